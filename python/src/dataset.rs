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
            if spec.tolerance_path.is_some() {
                return Err(Error::field(
                    "benches",
                    "a dataset over benches drawn from a tolerance file has one kernel per \
                     bench; open_dataset rebuilds nominal datasets only",
                )
                .in_file(&path));
            }
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
        let make = || -> Result<Acquisition> {
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
                &p.scene,
                self.kernel.clone(),
                &self.matrices,
                p.patterns.clone(),
                scheme,
                m,
                p.schemes.clone(),
            )
        };
        make().map_err(to_py)
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
