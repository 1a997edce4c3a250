//! `Kernel`: a traced object kernel, its sparse matrices and its product.

use std::sync::Arc;

use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use spibench::optics::Arm;
use spibench::optics::dmd::MirrorState;
use spibench::pipeline::operator::{self, KernelMatrices};
use spibench::scene::run::RunScene;
use spibench::trace::BatchTally;
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

    /// Lamp rays traced for the kernel.
    #[getter]
    fn rays(&self) -> u64 {
        self.kernel.rays
    }

    /// Seed of the kernel trace.
    #[getter]
    fn seed(&self) -> u64 {
        self.kernel.seed
    }

    /// Batches the rays were traced in (the standard errors' samples).
    #[getter]
    fn batches(&self) -> u64 {
        self.kernel.batches
    }

    /// The fraction of the chart's detected current carried by paths that met the chart twice or
    /// more.
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

    /// The detected current (A) of paths that met the chart twice or more.
    #[getter]
    fn multi_crossing_current_a(&self) -> f64 {
        self.kernel.multi_crossing_current_a
    }

    /// T[arm][state] (units × pixels, A per unit transmittance).
    fn t(&self, py: Python<'_>, arm: PyArm, state: PyMirrorState) -> PyResult<Csr> {
        Csr::new(py, &self.matrices.t[block(arm, state)])
    }

    /// The object-independent T[arm][state] (A, per unit).
    fn t0<'py>(
        &self,
        py: Python<'py>,
        arm: PyArm,
        state: PyMirrorState,
    ) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.matrices.t0[block(arm, state)].clone())
    }

    /// The gain matrix G of `arm` (units × pixels, A per unit transmittance).
    fn g(&self, py: Python<'_>, arm: PyArm) -> PyResult<Csr> {
        Csr::new(py, &self.matrices.g[Arm::from(arm)])
    }

    /// The standard error of each entry of G of `arm` (A), G's sparsity.
    fn g_stderr(&self, py: Python<'_>, arm: PyArm) -> PyResult<Csr> {
        Csr::new(py, &self.matrices.g_stderr[Arm::from(arm)])
    }

    /// The object-independent gains of `arm` (A, per unit).
    fn g0<'py>(&self, py: Python<'py>, arm: PyArm) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.matrices.g0[Arm::from(arm)].clone())
    }

    /// The power on the units X (units × pixels, W per unit transmittance).
    fn x(&self, py: Python<'_>) -> PyResult<Csr> {
        Csr::new(py, &self.matrices.x)
    }

    /// The object-independent power on the units (W).
    fn x0<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.matrices.x0.clone())
    }

    /// The pattern-independent traced current of `arm`'s diode per pixel (A).
    fn c<'py>(&self, py: Python<'py>, arm: PyArm) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.matrices.c[Arm::from(arm)].clone())
    }

    /// Its object-independent part (A).
    fn c0(&self, arm: PyArm) -> f64 {
        self.matrices.c0[Arm::from(arm)]
    }

    /// The transport of one object through the kernel (`Transport::from_kernel`): its scalars
    /// with standard errors by name, the names as a trace's metrics.
    fn transport_metrics(
        &self,
        object: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Vec<(&'static str, Estimate)>> {
        let o = object.as_slice().map_err(PyErr::from)?;
        let t = Transport::from_kernel(&self.scene.bench, &self.kernel, o).map_err(to_py)?;
        let e = |v: &spibench::transport::Estimate| Estimate {
            value: v.value,
            stderr: v.stderr,
        };
        Ok(vec![
            ("x_total_w", e(&t.x_total)),
            ("k_plus", e(&t.k[0])),
            ("k_minus", e(&t.k[1])),
            ("k_prime", e(&t.k_prime)),
            ("imbalance", e(&t.imbalance)),
            ("b_plus", e(&t.b[0])),
            ("b_minus", e(&t.b[1])),
        ])
    }

    /// The library's kernel product of each object (rows of `objects`): the power on each
    /// unit x_j (W), and the four T blocks (A), as `Kernel::apply` computes them; with `linear`
    /// its linear part (`Kernel::apply_linear`: light that meets the chart more than once
    /// weighted by its first pixel only), which the sparse matrices hold.
    #[pyo3(signature = (objects, threads=None, linear=false))]
    fn product<'py>(
        &self,
        py: Python<'py>,
        objects: PyReadonlyArray2<'py, f64>,
        threads: Option<usize>,
        linear: bool,
    ) -> PyResult<Product> {
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
        Ok(Product {
            x_w: vec2(py, x, n, units)?.unbind(),
            t_a: vec2(py, t, n, 4 * units)?.unbind(),
        })
    }
}

/// A detection arm (its photodiode): + or −, as `spibench::optics::Arm`.
#[pyclass(
    name = "Arm",
    eq,
    eq_int,
    frozen,
    from_py_object,
    module = "spibench._spibench"
)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PyArm {
    Plus = 0,
    Minus = 1,
}

impl From<PyArm> for Arm {
    fn from(a: PyArm) -> Arm {
        match a {
            PyArm::Plus => Arm::Plus,
            PyArm::Minus => Arm::Minus,
        }
    }
}

/// A powered mirror's state, + or − (the states of T).
#[pyclass(
    name = "MirrorState",
    eq,
    eq_int,
    frozen,
    from_py_object,
    module = "spibench._spibench"
)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PyMirrorState {
    Plus = 0,
    Minus = 1,
}

impl From<PyMirrorState> for MirrorState {
    fn from(s: PyMirrorState) -> MirrorState {
        match s {
            PyMirrorState::Plus => MirrorState::Plus,
            PyMirrorState::Minus => MirrorState::Minus,
        }
    }
}

/// The kernel matrices' block of T[arm][state].
fn block(arm: PyArm, state: PyMirrorState) -> usize {
    BatchTally::t_block(arm.into(), state.into())
}

/// A sparse matrix in compressed rows, as `scipy.sparse.csr_matrix` takes it.
#[pyclass(frozen, get_all, module = "spibench._spibench")]
pub(crate) struct Csr {
    data: Py<PyArray1<f64>>,
    indices: Py<PyArray1<u32>>,
    indptr: Py<PyArray1<u64>>,
    /// (rows, columns).
    shape: (usize, usize),
}

impl Csr {
    fn new(py: Python<'_>, m: &operator::Csr) -> PyResult<Csr> {
        let indptr: Vec<u64> = m.indptr.iter().map(|&v| v as u64).collect();
        Ok(Csr {
            data: m.data.clone().into_pyarray(py).unbind(),
            indices: m.indices.clone().into_pyarray(py).unbind(),
            indptr: indptr.into_pyarray(py).unbind(),
            shape: (m.rows, m.cols),
        })
    }
}

/// A traced number with its standard error.
#[pyclass(frozen, get_all, module = "spibench._spibench")]
pub(crate) struct Estimate {
    value: f64,
    stderr: f64,
}

/// The kernel product of a batch of objects: the power on each unit x_j (W), (N, units), and
/// the four T blocks (A), (N, 4·units), in `BatchTally::t_block` order.
#[pyclass(frozen, get_all, module = "spibench._spibench")]
pub(crate) struct Product {
    x_w: Py<PyArray2<f64>>,
    t_a: Py<PyArray2<f64>>,
}
