//! `Kernel`: a traced object kernel, its sparse matrices and its product.

use std::sync::Arc;

use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use spibench::error::Error;
use spibench::pipeline::operator::{self, KernelMatrices};
use spibench::scene::run::RunScene;
use spibench::trace::kernel::Kernel as LibKernel;
use spibench::transport::Transport;

use crate::{rows_of, run, to_py, vec1, vec2};

/// A traced object kernel with the bench it was traced for (see `spibench.Kernel`).
#[pyclass(frozen, module = "spibench._spibench")]
pub(crate) struct Kernel {
    pub(crate) scene: Arc<RunScene>,
    pub(crate) kernel: Arc<LibKernel>,
    pub(crate) matrices: Arc<KernelMatrices>,
}

impl Kernel {
    pub(crate) fn new(scene: RunScene, kernel: LibKernel) -> Kernel {
        let matrices = KernelMatrices::new(&kernel);
        Kernel {
            scene: Arc::new(scene),
            kernel: Arc::new(kernel),
            matrices: Arc::new(matrices),
        }
    }

    #[allow(clippy::type_complexity)]
    fn csr_parts<'py>(
        py: Python<'py>,
        m: &operator::Csr,
    ) -> (
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<u32>>,
        Bound<'py, PyArray1<u64>>,
        (usize, usize),
    ) {
        (
            m.data.clone().into_pyarray(py),
            m.indices.clone().into_pyarray(py),
            m.indptr
                .iter()
                .map(|&v| v as u64)
                .collect::<Vec<_>>()
                .into_pyarray(py),
            (m.rows, m.cols),
        )
    }
}

#[pymethods]
impl Kernel {
    /// (height, width) of the object grid.
    #[getter]
    fn grid(&self) -> (usize, usize) {
        (self.kernel.grid.height_px, self.kernel.grid.width_px)
    }

    /// (height, width) of the field (mm).
    #[getter]
    fn field_mm(&self) -> (f64, f64) {
        (
            self.kernel.grid.height_m * 1e3,
            self.kernel.grid.width_m * 1e3,
        )
    }

    /// (down, across) DMD units.
    #[getter]
    fn units(&self) -> (usize, usize) {
        (self.kernel.units_down, self.kernel.units_across)
    }

    #[getter]
    fn rays(&self) -> u64 {
        self.kernel.rays
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.kernel.seed
    }

    #[getter]
    fn batches(&self) -> u64 {
        self.kernel.batches
    }

    #[getter]
    fn multi_crossing_current_fraction(&self) -> f64 {
        self.kernel.multi_crossing_current_fraction()
    }

    /// The clear chart's detected current (A, summed over the diodes and both mirror-state
    /// worlds) of paths that met the chart once or more, and twice or more.
    #[getter]
    fn chart_current_a(&self) -> f64 {
        self.kernel.chart_current_a
    }

    #[getter]
    fn multi_crossing_current_a(&self) -> f64 {
        self.kernel.multi_crossing_current_a
    }

    /// A sparse matrix (data, indices, indptr, shape): kind "t" (block 0–3), "g", "g_stderr"
    /// (arm 0–1) or "x".
    #[allow(clippy::type_complexity)]
    fn csr<'py>(
        &self,
        py: Python<'py>,
        kind: &str,
        index: usize,
    ) -> PyResult<(
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<u32>>,
        Bound<'py, PyArray1<u64>>,
        (usize, usize),
    )> {
        let m = &self.matrices;
        let mat = match (kind, index) {
            ("t", 0..4) => &m.t[index],
            ("g", 0..2) => &m.g[index],
            ("g_stderr", 0..2) => &m.g_stderr[index],
            ("x", 0) => &m.x,
            _ => {
                return Err(to_py(Error::field(
                    "kind",
                    format!("no matrix {kind:?}[{index}]"),
                )));
            }
        };
        Ok(Self::csr_parts(py, mat))
    }

    /// An object-independent column or per-pixel vector: "t0" (block 0–3), "g0" (arm), "x0",
    /// "c" (arm, per pixel), "c0" (arm, one value).
    fn vector<'py>(
        &self,
        py: Python<'py>,
        kind: &str,
        index: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let m = &self.matrices;
        let v = match (kind, index) {
            ("t0", 0..4) => m.t0[index].clone(),
            ("g0", 0..2) => m.g0[index].clone(),
            ("x0", 0) => m.x0.clone(),
            ("c", 0..2) => m.c[index].clone(),
            ("c0", 0..2) => vec![m.c0[index]],
            _ => {
                return Err(to_py(Error::field(
                    "kind",
                    format!("no vector {kind:?}[{index}]"),
                )));
            }
        };
        Ok(vec1(py, v))
    }

    /// The transport of one object through the kernel (`Transport::from_kernel`): its scalars
    /// with standard errors, (name, value, stderr), names as a trace's metrics.
    fn transport_metrics(
        &self,
        object: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Vec<(&'static str, f64, f64)>> {
        let o = object.as_slice().map_err(PyErr::from)?;
        let t = Transport::from_kernel(&self.scene.bench, &self.kernel, o).map_err(to_py)?;
        Ok(vec![
            ("x_total_w", t.x_total.value, t.x_total.stderr),
            ("k_plus", t.k[0].value, t.k[0].stderr),
            ("k_minus", t.k[1].value, t.k[1].stderr),
            ("k_prime", t.k_prime.value, t.k_prime.stderr),
            ("imbalance", t.imbalance.value, t.imbalance.stderr),
            ("b_plus", t.b[0].value, t.b[0].stderr),
            ("b_minus", t.b[1].value, t.b[1].stderr),
        ])
    }

    /// The library's kernel product of each object (rows of `objects`): the power on each
    /// unit x_j (W), and the four T blocks (A), as `Kernel::apply` computes them; with `linear`
    /// its linear part (`Kernel::apply_linear`: light that meets the chart more than once
    /// weighted by its first pixel only), which the sparse matrices hold.
    #[pyo3(signature = (objects, threads=None, linear=false))]
    #[allow(clippy::type_complexity)]
    fn product<'py>(
        &self,
        py: Python<'py>,
        objects: PyReadonlyArray2<'py, f64>,
        threads: Option<usize>,
        linear: bool,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>)> {
        use rayon::prelude::*;
        let pixels = self.kernel.grid.pixels();
        let units = self.kernel.units();
        let data = rows_of(&objects, "objects", pixels)
            .map_err(to_py)?
            .to_vec();
        let n = data.len() / pixels;
        let kernel = &self.kernel;
        let (x, t) = run(py, threads, || {
            let parts: Vec<(Vec<f64>, Vec<f64>)> = data
                .par_chunks(pixels)
                .map(|o| {
                    let p = if linear {
                        kernel.apply_linear(o)
                    } else {
                        kernel.apply(o)
                    };
                    (p.x, p.t)
                })
                .collect();
            let (x, t): (Vec<Vec<f64>>, Vec<Vec<f64>>) = parts.into_iter().unzip();
            Ok((x.concat(), t.concat()))
        })?;
        Ok((vec2(py, x, n, units)?, vec2(py, t, n, 4 * units)?))
    }
}
