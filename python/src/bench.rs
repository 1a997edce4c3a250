//! `Bench`: a bench document, its checks, traces and object kernels.

use std::path::{Path, PathBuf};

use pyo3::prelude::*;

use spibench::error::Error;
use spibench::pipeline::evaluate::evaluation_of;
use spibench::pipeline::operator;
use spibench::pipeline::{TraceRequest, trace_stage};
use spibench::scene::dataset::KernelSpec;
use spibench::scene::doc::BenchDoc;

use crate::kernel::Kernel;
use crate::trace::Trace;
use crate::{run, to_py};

/// The paper's bench, as the command line builds it in.
const PAPER_BENCH: &str = include_str!("../../scenes/paper_bench.ron");
const PAPER_BENCH_NAME: &str = "<built-in scenes/paper_bench.ron>";

/// A kernel spec's error as the error of `Bench.kernel`'s argument: `grid_px` is `grid` there.
fn kernel_argument(e: Error) -> Error {
    match e {
        Error::Input {
            mut location,
            message,
        } if location.file.is_none() => {
            if location.field.as_deref() == Some("grid_px") {
                location.field = Some("grid".into());
            }
            Error::Input { location, message }
        }
        e => e,
    }
}

/// A bench document (see `spibench.Bench`).
#[pyclass(frozen, module = "spibench._spibench")]
pub(crate) struct Bench {
    doc: BenchDoc,
}

#[pymethods]
impl Bench {
    /// Reads and checks a bench file (RON).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Bench> {
        Ok(Bench {
            doc: BenchDoc::read(&path).map_err(to_py)?,
        })
    }

    /// The paper's bench, built into the library.
    #[staticmethod]
    fn paper() -> PyResult<Bench> {
        Ok(Bench {
            doc: BenchDoc::parse(PAPER_BENCH, Path::new(PAPER_BENCH_NAME)).map_err(to_py)?,
        })
    }

    /// A bench from RON text; `path` names it in errors and resolves relative files.
    #[staticmethod]
    fn parse(text: &str, path: PathBuf) -> PyResult<Bench> {
        Ok(Bench {
            doc: BenchDoc::parse(text, &path).map_err(to_py)?,
        })
    }

    /// A new bench with the (path, value) variables set, in order.
    fn set(&self, settings: Vec<(String, f64)>) -> PyResult<Bench> {
        Ok(Bench {
            doc: self.doc.with(&settings).map_err(to_py)?,
        })
    }

    /// The value of a bench variable.
    fn get(&self, path: &str) -> PyResult<f64> {
        self.doc.get(path).map_err(to_py)
    }

    /// Every variable path of the bench, in file order.
    fn variables(&self) -> Vec<String> {
        spibench::scene::variables::list(&self.doc.file)
    }

    /// The variables set since the file was read, in order.
    fn edits(&self) -> Vec<(String, f64)> {
        self.doc.edits().to_vec()
    }

    /// The file the bench was read from (or the name it was given).
    fn path(&self) -> PathBuf {
        self.doc.path().to_path_buf()
    }

    /// The bench as canonical RON text, which reads back as the same bench.
    fn to_ron(&self) -> PyResult<String> {
        self.doc.to_ron().map_err(to_py)
    }

    /// Builds the bench and its electronics; returns the DMD units (down, across).
    fn check(&self) -> PyResult<(usize, usize)> {
        let scene = self.doc.run_scene().map_err(to_py)?;
        let (across, down) = scene.bench.units_shape();
        Ok((down, across))
    }

    /// Traces `rays` lamp rays with `seed` on `threads` threads (default: all cores).
    #[pyo3(signature = (rays, seed, threads=None))]
    fn trace(
        &self,
        py: Python<'_>,
        rays: u64,
        seed: u64,
        threads: Option<usize>,
    ) -> PyResult<Trace> {
        let doc = &self.doc;
        run(py, threads, || {
            if rays == 0 {
                return Err(Error::field("rays", "at least one ray is needed"));
            }
            // As `pipeline::evaluate` (what `sweep` runs at every point), keeping the traced
            // transport for its maps.
            let bench = doc.build()?;
            let traced = trace_stage(&bench, &TraceRequest::new(rays, seed))?;
            let evaluation = evaluation_of(doc, doc.edits().to_vec(), &traced, None);
            Ok(Trace { traced, evaluation })
        })
    }

    /// The object kernel on `grid` = (height, width) pixels over `field_mm` = (height, width).
    #[pyo3(signature = (grid, field_mm, rays, seed, chart=None, threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn kernel(
        &self,
        py: Python<'_>,
        grid: (usize, usize),
        field_mm: (f64, f64),
        rays: u64,
        seed: u64,
        chart: Option<String>,
        threads: Option<usize>,
    ) -> PyResult<Kernel> {
        let doc = &self.doc;
        run(py, threads, || {
            let scene = doc.run_scene()?;
            // The spec of a dataset's `kernel:` section, which writes (across, down).
            let spec = KernelSpec {
                rays,
                seed,
                grid_px: (grid.1, grid.0),
                field_mm: (field_mm.1, field_mm.0),
                chart,
            };
            let kernel = operator::clear_chart_kernel(doc, &spec).map_err(kernel_argument)?;
            Ok(Kernel::new(scene, kernel))
        })
    }
}
