//! Datasets: `Dataset` (a dataset's inputs rebuilt from its folder), `make_dataset` and the
//! record seed of a sample.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use pyo3::prelude::*;

use spibench::dataset::{self, Prepared, contract};
use spibench::error::{Error, Result};
use spibench::pipeline::operator::KernelMatrices;
use spibench::trace::kernel::Kernel as LibKernel;

use crate::acquisition::Acquisition;
use crate::kernel::Kernel;
use crate::{run, scheme_named, to_py};

/// A dataset's inputs rebuilt from its folder (see `spibench.open_dataset`).
#[pyclass(frozen, module = "spibench._spibench")]
pub(crate) struct Dataset {
    prep: Arc<Prepared>,
    matrices: Arc<KernelMatrices>,
    kernel: Arc<LibKernel>,
}

/// The spec of the dataset in `dir`, read from its copy, its bench the folder's copy unless the
/// original (same SHA-256) is still in place (relative paths in it then resolve as before).
fn dataset_spec(dir: &Path) -> Result<spibench::scene::dataset::DatasetSpec> {
    let manifest = dataset::read_manifest(dir)?;
    let copy = dir.join(contract::SPEC_COPY);
    let text = std::fs::read_to_string(&copy).map_err(|e| Error::read(&copy, e))?;
    let original = PathBuf::from(&manifest.provenance.spec_file);
    let mut spec = spibench::scene::dataset::parse_dataset(&text, &original)?;
    let same = std::fs::read(&spec.bench_path)
        .is_ok_and(|b| dataset::sha256_hex(&b) == manifest.provenance.bench_sha256);
    if !same {
        spec.bench_path = dir.join(contract::BENCH_COPY);
    }
    Ok(spec)
}

#[pymethods]
impl Dataset {
    #[new]
    #[pyo3(signature = (path, threads=None))]
    fn new(py: Python<'_>, path: PathBuf, threads: Option<usize>) -> PyResult<Dataset> {
        run(py, threads, || {
            let spec = dataset_spec(&path)?;
            // A dataset over benches drawn from a tolerance file opens with its nominal
            // bench's kernel; `drawn_bench` rebuilds each drawn one.
            let prep = Prepared::new(spec)?;
            let matrices = KernelMatrices::new(&prep.kernel);
            let kernel = Arc::new(prep.kernel.clone());
            Ok(Dataset {
                prep: Arc::new(prep),
                matrices: Arc::new(matrices),
                kernel,
            })
        })
    }

    /// The spec's seed.
    #[getter]
    fn seed(&self) -> u64 {
        self.prep.spec.file.seed
    }

    /// The acquisition of `scheme` at `ratio` exactly as the dataset recorded it (every scheme
    /// of the dataset recorded together, its patterns, electronics and record model).
    fn acquisition(&self, scheme: &str, ratio: f64) -> PyResult<Acquisition> {
        self.cell(&self.kernel(), scheme, ratio).map_err(to_py)
    }

    /// The benches the dataset's samples were measured through: 1 for a nominal dataset,
    /// ⌈samples / samples_per_bench⌉ for benches drawn from a tolerance file.
    #[getter]
    fn benches(&self) -> u64 {
        let p = &self.prep;
        match &p.drawn {
            None => 1,
            Some(d) => p.spec.file.samples.div_ceil(d.samples_per_bench),
        }
    }

    /// The names of a drawn bench's deviations (tolerances, then compensators); empty for a
    /// nominal dataset.
    fn deviation_names(&self) -> Vec<String> {
        self.prep.deviation_names()
    }

    /// Drawn bench `t` of a dataset over benches drawn from a tolerance file, as the dataset
    /// measured its samples: its kernel (traced again with the spec's rays and seed, bit for
    /// bit the dataset's) and its deviations.
    fn drawn_bench(&self, py: Python<'_>, t: u64) -> PyResult<(Kernel, Vec<f64>)> {
        let Some(d) = &self.prep.drawn else {
            return Err(to_py(Error::field(
                "t",
                "the dataset's samples were measured through its nominal bench alone",
            )));
        };
        let n = self.benches();
        if t >= n {
            return Err(to_py(Error::field(
                "t",
                format!("bench {t} of a dataset with {n} benches"),
            )));
        }
        let b = run(py, None, || self.prep.drawn_bench(d, t))?;
        Ok((Kernel::new(b.scene, b.kernel), b.deviations))
    }

    /// The acquisition of `scheme` at `ratio` through `kernel` (a drawn bench's, from
    /// `drawn_bench`), recorded as the dataset records (every scheme of the dataset together,
    /// its patterns).
    fn acquisition_on(&self, kernel: &Kernel, scheme: &str, ratio: f64) -> PyResult<Acquisition> {
        self.cell(kernel, scheme, ratio).map_err(to_py)
    }

    /// The dataset's kernel (with its bench's scene).
    fn kernel(&self) -> Kernel {
        Kernel {
            scene: Arc::new(self.prep.scene.clone()),
            kernel: self.kernel.clone(),
            matrices: self.matrices.clone(),
        }
    }
}

impl Dataset {
    /// The acquisition of `scheme` at `ratio` through `kernel` with the dataset's patterns and
    /// recorded schemes.
    fn cell(&self, kernel: &Kernel, scheme: &str, ratio: f64) -> Result<Acquisition> {
        let scheme = scheme_named(scheme)?;
        let p = &self.prep;
        if !p.schemes.contains(&scheme) {
            return Err(Error::field(
                "scheme",
                format!("the dataset has no {} measurements", scheme.key()),
            ));
        }
        if !p.ratios.contains(&ratio) {
            return Err(Error::field(
                "ratio",
                format!("the dataset's ratios are {:?}", p.ratios),
            ));
        }
        let m = spibench::acquisition::patterns_for_ratio(ratio, p.units());
        Acquisition::build(
            &kernel.scene,
            kernel.kernel.clone(),
            &kernel.matrices,
            p.patterns.clone(),
            scheme,
            m,
            p.schemes.clone(),
        )
    }
}

/// Makes the dataset of `spec` in `out` as `spibench dataset SPEC --out OUT` does.
#[pyfunction]
#[pyo3(signature = (spec, out, threads=None))]
pub(crate) fn make_dataset(
    py: Python<'_>,
    spec: PathBuf,
    out: PathBuf,
    threads: Option<usize>,
) -> PyResult<u64> {
    run(py, threads, || {
        let spec = spibench::scene::dataset::read_dataset(&spec)?;
        let prep = Prepared::new(spec)?;
        let range = (0, prep.shards_total());
        let command = vec!["spibench".to_string(), "dataset (python)".to_string()];
        // The same folder lock as the command line: a second writer stops at once.
        let lock = spibench::report::output::FolderLock::acquire(&out)?;
        let g = dataset::generate(&prep, &lock, range, false, &command, &|_, _| {})?;
        Ok(g.shards_written)
    })
}

/// The record seed of sample `s` of a dataset of seed `seed`.
#[pyfunction]
pub(crate) fn dataset_noise_seed(seed: u64, s: u64) -> u64 {
    dataset::noise_seed(seed, s)
}
