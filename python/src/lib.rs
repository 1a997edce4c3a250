//! `spibench._spibench`: the extension module under the `spibench` Python package.
//!
//! A thin layer over the library: every computation is the library's own function (the
//! evaluate step's trace, the object kernel, `Transport::from_kernel` with the record stage,
//! `pipeline::operator::TracedOperator`, the TVAL3 solver, `dataset::generate`). Arrays cross as
//! contiguous float64 numpy arrays, already checked for shape and dtype by the Python layer
//! (`spibench/__init__.py`), and checked again here for length and finiteness. Errors become
//! `InputError` (a `ValueError`) for input a user can fix, `OSError` for files, `RuntimeError`
//! otherwise, each with the library's located message. Long calls release the GIL and run on
//! the library's threads (`threads=`, default the global pool); results do not depend on the
//! thread count.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use spibench::acquisition::{PackedPatterns, Scheme};
use spibench::dataset::{self, Prepared};
use spibench::detector::RecordModel;
use spibench::error::{Error, Result};
use spibench::pipeline::evaluate::{self, Evaluation, evaluation_of};
use spibench::pipeline::operator::{self, KernelMatrices, TracedOperator};
use spibench::pipeline::{TraceRequest, Traced, trace_stage};
use spibench::scene::dataset::KernelSpec;
use spibench::scene::doc::BenchDoc;
use spibench::scene::run::RunScene;
use spibench::trace::kernel::Kernel as LibKernel;
use spibench::transport::Transport;

create_exception!(
    _spibench,
    InputError,
    PyValueError,
    "Input a user can fix (a bench file, a variable path, an argument); the message names the \
     file, line and field or the argument, as the command line prints it."
);

/// The paper's bench, as the command line builds it in.
const PAPER_BENCH: &str = include_str!("../../scenes/paper_bench.ron");
const PAPER_BENCH_NAME: &str = "<built-in scenes/paper_bench.ron>";

fn to_py(e: Error) -> PyErr {
    let text = e.to_string();
    match e {
        Error::Input { .. } => InputError::new_err(text),
        Error::Io { .. } => PyOSError::new_err(text),
        Error::Numerical(_) => PyRuntimeError::new_err(text),
    }
}

/// Runs `f` without the GIL, on a pool of `threads` threads (the global pool when None).
fn run<T: Send>(
    py: Python<'_>,
    threads: Option<usize>,
    f: impl FnOnce() -> Result<T> + Send,
) -> PyResult<T> {
    py.detach(|| match threads {
        None => f(),
        Some(0) => Err(Error::field("threads", "at least one thread is needed")),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| Error::Numerical(format!("cannot start {n} threads: {e}")))?
            .install(f),
    })
    .map_err(to_py)
}

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

fn scheme_named(name: &str) -> Result<Scheme> {
    Scheme::all()
        .into_iter()
        .find(|s| s.key() == name)
        .ok_or_else(|| {
            let names: Vec<&str> = Scheme::all().iter().map(|s| s.key()).collect();
            Error::field(
                "scheme",
                format!("unknown scheme {name:?}; one of {}", names.join(", ")),
            )
        })
}

fn vec1<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    v.into_pyarray(py)
}

fn vec2<'py>(
    py: Python<'py>,
    v: Vec<f64>,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    v.into_pyarray(py).reshape([rows, cols])
}

/// The rows of a C-contiguous 2-D float64 array, named `what` in errors.
fn rows_of<'a>(a: &'a PyReadonlyArray2<'_, f64>, what: &str, cols: usize) -> Result<&'a [f64]> {
    let shape = a.as_array().shape().to_vec();
    if shape[1] != cols {
        return Err(Error::field(
            what,
            format!("has {} values per item, {cols} are needed", shape[1]),
        ));
    }
    a.as_slice()
        .map_err(|_| Error::field(what, "must be a C-contiguous array"))
}

// ---------------------------------------------------------------------------------------------
// benches and traces

/// A bench document (see `spibench.Bench`).
#[pyclass(frozen, module = "spibench._spibench")]
struct Bench {
    doc: BenchDoc,
}

#[pymethods]
impl Bench {
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Bench> {
        Ok(Bench {
            doc: BenchDoc::read(&path).map_err(to_py)?,
        })
    }

    #[staticmethod]
    fn paper() -> PyResult<Bench> {
        Ok(Bench {
            doc: BenchDoc::parse(PAPER_BENCH, Path::new(PAPER_BENCH_NAME)).map_err(to_py)?,
        })
    }

    #[staticmethod]
    fn parse(text: &str, path: PathBuf) -> PyResult<Bench> {
        Ok(Bench {
            doc: BenchDoc::parse(text, &path).map_err(to_py)?,
        })
    }

    fn set(&self, settings: Vec<(String, f64)>) -> PyResult<Bench> {
        Ok(Bench {
            doc: self.doc.with(&settings).map_err(to_py)?,
        })
    }

    fn get(&self, path: &str) -> PyResult<f64> {
        self.doc.get(path).map_err(to_py)
    }

    fn variables(&self) -> Vec<String> {
        spibench::scene::variables::list(&self.doc.file)
    }

    fn edits(&self) -> Vec<(String, f64)> {
        self.doc.edits().to_vec()
    }

    fn path(&self) -> PathBuf {
        self.doc.path().to_path_buf()
    }

    fn to_ron(&self) -> PyResult<String> {
        self.doc.to_ron().map_err(to_py)
    }

    /// Builds the bench and its electronics; returns the DMD units (across, down).
    fn check(&self) -> PyResult<(usize, usize)> {
        let scene = self.doc.run_scene().map_err(to_py)?;
        Ok(scene.bench.units_shape())
    }

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

/// A traced bench (see `spibench.Trace`).
#[pyclass(frozen, module = "spibench._spibench")]
struct Trace {
    traced: Traced,
    evaluation: Evaluation,
}

#[pymethods]
impl Trace {
    /// The recorded numbers of `sweep` against `reference` (itself when None).
    #[pyo3(signature = (reference=None))]
    fn values(&self, reference: Option<&Trace>) -> Vec<(String, f64)> {
        let r = reference.map_or(&self.evaluation, |r| &r.evaluation);
        evaluate::values(&self.evaluation, r)
    }

    #[getter]
    fn rays(&self) -> u64 {
        self.traced.rays
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.traced.seed
    }

    #[getter]
    fn units(&self) -> (usize, usize) {
        let t = &self.traced.transport;
        (t.units_down, t.units_across)
    }

    /// The per-unit maps by name: x_w, g_plus_a, g_minus_a, k_plus_a_per_w, …, t_a (4 blocks).
    fn map<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let t = &self.traced.transport;
        let v = match name {
            "x_w" => t.x_w.clone(),
            "g_plus_a" => t.g_a[0].clone(),
            "g_minus_a" => t.g_a[1].clone(),
            "k_plus_a_per_w" => t.k_map[0].clone(),
            "k_minus_a_per_w" => t.k_map[1].clone(),
            "k_plus_stderr_a_per_w" => t.k_map_stderr[0].clone(),
            "k_minus_stderr_a_per_w" => t.k_map_stderr[1].clone(),
            "t_a" => t.t_a.clone(),
            _ => return Err(to_py(Error::field("name", format!("no map {name:?}")))),
        };
        Ok(vec1(py, v))
    }

    /// The flux ledger: per world (+, −) absorbed per element, escaped, path cap, detected.
    fn ledger<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let l = &self.traced.transport.ledger;
        let d = PyDict::new(py);
        d.set_item("emitted_w", l.emitted_w)?;
        d.set_item("emitted_nominal_w", l.emitted_nominal_w)?;
        d.set_item("outside_cone_w", l.outside_cone_w)?;
        for (name, w) in ["plus", "minus"].iter().zip(&l.worlds) {
            let wd = PyDict::new(py);
            wd.set_item("absorbed_w", w.absorbed_w.clone())?;
            wd.set_item("escaped_w", w.escaped_w)?;
            wd.set_item("path_cap_w", w.path_cap_w)?;
            wd.set_item("detected_w", w.detected_w.to_vec())?;
            wd.set_item("sampled_w", w.sampled_w)?;
            wd.set_item("residual_w", w.residual_w)?;
            d.set_item(format!("world_{name}"), wd)?;
        }
        Ok(d)
    }
}

// ---------------------------------------------------------------------------------------------
// object kernels

/// A traced object kernel with the bench it was traced for (see `spibench.Kernel`).
#[pyclass(frozen, module = "spibench._spibench")]
struct Kernel {
    scene: Arc<RunScene>,
    kernel: Arc<LibKernel>,
    matrices: Arc<KernelMatrices>,
}

impl Kernel {
    fn new(scene: RunScene, kernel: LibKernel) -> Kernel {
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

// ---------------------------------------------------------------------------------------------
// the acquisition operator

/// One scheme's traced acquisition through an object kernel (see `spibench.Acquisition`).
#[pyclass(frozen, module = "spibench._spibench")]
struct Acquisition {
    /// The scene recorded: its electronics, settings and the schemes whose sequences are
    /// recorded together (they share the oscilloscope's ranges).
    scene: Arc<RunScene>,
    kernel: Arc<LibKernel>,
    /// The patterns recorded (at least `m`), with their operator built once.
    patterns: PackedPatterns,
    op: Arc<TracedOperator>,
}

impl Acquisition {
    fn build(
        scene: &RunScene,
        kernel: Arc<LibKernel>,
        matrices: &KernelMatrices,
        patterns: PackedPatterns,
        scheme: Scheme,
        m: usize,
        recorded: Vec<Scheme>,
    ) -> Result<Acquisition> {
        let mut scene = scene.clone();
        scene.settings.schemes = recorded;
        scene.settings.signal_trace_frames = 0;
        let op = TracedOperator::new(&scene, matrices, patterns.set(), scheme, m)?;
        Ok(Acquisition {
            scene: Arc::new(scene),
            kernel,
            patterns,
            op: Arc::new(op),
        })
    }

    /// The simulated measurement of one object with record seed `seed`.
    /// With `linear`, through the kernel's linear part (`Transport::from_kernel_linear`), the
    /// part that `A x + y₀` describes exactly.
    fn measure(
        &self,
        scene: &RunScene,
        object: &[f64],
        seed: u64,
        linear: bool,
    ) -> Result<Vec<f64>> {
        // Values only: a measurement reports no standard errors (Transport::from_kernel_values).
        let transport = Transport::from_kernel_values(&scene.bench, &self.kernel, object, linear)?;
        let rec = evaluate::acquire(scene, &transport, &self.patterns, seed, &|_, _, _| {})?;
        let scheme = self.op.scheme;
        let r = rec.record(scheme.sequence()).ok_or_else(|| {
            Error::Numerical(format!("no record for the {} sequence", scheme.label()))
        })?;
        Ok(scheme.measurements(&r.frames, self.op.measurements))
    }
}

#[pymethods]
impl Acquisition {
    #[new]
    #[pyo3(signature = (kernel, scheme, ratio, record="frames", recorded=None))]
    fn new(
        kernel: &Kernel,
        scheme: &str,
        ratio: f64,
        record: &str,
        recorded: Option<Vec<String>>,
    ) -> PyResult<Acquisition> {
        let make = || -> Result<Acquisition> {
            let scheme = scheme_named(scheme)?;
            let mut scene = (*kernel.scene).clone();
            scene.settings.record = match record {
                "frames" => RecordModel::Frames,
                "samples" => RecordModel::Samples,
                _ => {
                    return Err(Error::field(
                        "record",
                        format!("{record:?} is neither \"frames\" nor \"samples\""),
                    ));
                }
            };
            let mut schemes = vec![scheme];
            for s in recorded.iter().flatten() {
                let s = scheme_named(s).map_err(|e| e.at_field("recorded"))?;
                if !schemes.contains(&s) {
                    schemes.push(s);
                }
            }
            let (patterns, m) = operator::patterns_for(&scene, ratio)?;
            Acquisition::build(
                &scene,
                kernel.kernel.clone(),
                &kernel.matrices,
                PackedPatterns::new(patterns),
                scheme,
                m,
                schemes,
            )
        };
        make().map_err(to_py)
    }

    #[getter]
    fn scheme(&self) -> &'static str {
        self.op.scheme.key()
    }

    #[getter]
    fn measurements(&self) -> usize {
        self.op.measurements
    }

    #[getter]
    fn pixels(&self) -> usize {
        self.op.pixels
    }

    #[getter]
    fn units(&self) -> (usize, usize) {
        (self.kernel.units_down, self.kernel.units_across)
    }

    #[getter]
    fn grid(&self) -> (usize, usize) {
        (self.kernel.grid.height_px, self.kernel.grid.width_px)
    }

    #[getter]
    fn noise_default(&self) -> bool {
        self.scene.settings.noise
    }

    #[getter]
    fn recorded(&self) -> Vec<&'static str> {
        self.scene
            .settings
            .schemes
            .iter()
            .map(|s| s.key())
            .collect()
    }

    #[getter]
    fn offset<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.op.offset.clone())
    }

    /// The coefficients (ka, kb, ks₊, ks₋, kc₊, kc₋) of the operator's measurement model.
    #[getter]
    fn coefficients(&self) -> [f64; 6] {
        let k = &self.op.coefficients;
        [k.ka, k.kb, k.ks[0], k.ks[1], k.kc[0], k.kc[1]]
    }

    /// The first M base patterns, one row of units (row-major) per pattern, as 0/1 bytes.
    fn patterns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u8>>> {
        let bits = self.patterns.set().base_patterns();
        let (m, n) = (self.op.measurements, bits.cols());
        let mut v = Vec::with_capacity(m * n);
        for i in 0..m {
            for j in 0..n {
                v.push(bits.get(i, j) as u8);
            }
        }
        v.into_pyarray(py).reshape([m, n])
    }

    /// The simulated measurements (V) of each object, as `spibench dataset` forms them:
    /// `seeds[n]` is object n's record seed; with `linear`, through the kernel's linear part.
    #[pyo3(signature = (objects, noise, seeds, threads=None, linear=false))]
    fn forward<'py>(
        &self,
        py: Python<'py>,
        objects: PyReadonlyArray2<'py, f64>,
        noise: bool,
        seeds: PyReadonlyArray1<'py, u64>,
        threads: Option<usize>,
        linear: bool,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        use rayon::prelude::*;
        let pixels = self.op.pixels;
        let data = rows_of(&objects, "x", pixels).map_err(to_py)?.to_vec();
        let n = data.len() / pixels;
        let seeds = seeds.as_slice().map_err(PyErr::from)?.to_vec();
        if seeds.len() != n {
            return Err(to_py(Error::field(
                "seed",
                format!("{} seeds for {n} objects", seeds.len()),
            )));
        }
        let mut scene = (*self.scene).clone();
        scene.settings.noise = noise;
        if !noise {
            scene.settings.additive_noise = None;
        }
        let m = self.op.measurements;
        let y = run(py, threads, || {
            let parts: Vec<Vec<f64>> = data
                .par_chunks(pixels)
                .zip(seeds.par_iter())
                .map(|(o, &s)| self.measure(&scene, o, s, linear))
                .collect::<Result<_>>()?;
            Ok(parts.concat())
        })?;
        vec2(py, y, n, m)
    }

    /// A x for each object (the linear part).
    #[pyo3(signature = (objects, threads=None))]
    fn apply<'py>(
        &self,
        py: Python<'py>,
        objects: PyReadonlyArray2<'py, f64>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let data = rows_of(&objects, "x", self.op.pixels).map_err(to_py)?;
        let n = data.len() / self.op.pixels;
        let op = &self.op;
        let y = run(py, threads, || op.apply_batch(data))?;
        vec2(py, y, n, op.measurements)
    }

    /// Aᵀ y for each measurement vector.
    #[pyo3(signature = (y, threads=None))]
    fn adjoint<'py>(
        &self,
        py: Python<'py>,
        y: PyReadonlyArray2<'py, f64>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let data = rows_of(&y, "y", self.op.measurements).map_err(to_py)?;
        let n = data.len() / self.op.measurements;
        let op = &self.op;
        let x = run(py, threads, || op.apply_adjoint_batch(data))?;
        vec2(py, x, n, op.pixels)
    }

    /// The best of `repeats` runs of the library's batch product (A, or Aᵀ with `adjoint`) on
    /// `objects` (or measurement rows), timed inside Rust: the work `apply`/`adjoint` do
    /// without the Python layer (for the benchmark of that layer's overhead).
    #[pyo3(signature = (objects, adjoint, repeats, threads=None))]
    fn time_rust(
        &self,
        py: Python<'_>,
        objects: PyReadonlyArray2<'_, f64>,
        adjoint: bool,
        repeats: usize,
        threads: Option<usize>,
    ) -> PyResult<f64> {
        let n = if adjoint {
            self.op.measurements
        } else {
            self.op.pixels
        };
        let data = rows_of(&objects, "objects", n).map_err(to_py)?;
        let op = &self.op;
        run(py, threads, || {
            let mut best = f64::INFINITY;
            for _ in 0..repeats.max(1) {
                let start = std::time::Instant::now();
                let out = if adjoint {
                    op.apply_adjoint_batch(data)?
                } else {
                    op.apply_batch(data)?
                };
                std::hint::black_box(out);
                best = best.min(start.elapsed().as_secs_f64());
            }
            Ok(best)
        })
    }

    /// TVAL3 on the DMD units, as `spibench run` solves this scheme: (image (down × across),
    /// iterations, stop reason, converged, relative residual, seconds).
    #[pyo3(signature = (y, threads=None))]
    #[allow(clippy::type_complexity)]
    fn reconstruct<'py>(
        &self,
        py: Python<'py>,
        y: PyReadonlyArray1<'py, f64>,
        threads: Option<usize>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, usize, String, bool, f64, f64)> {
        let y = y.as_slice().map_err(PyErr::from)?.to_vec();
        let scheme = self.op.scheme;
        let m = self.op.measurements;
        if y.len() != m {
            return Err(to_py(Error::field(
                "y",
                format!("has {} measurements, the acquisition has {m}", y.len()),
            )));
        }
        let (across, down) = (self.kernel.units_across, self.kernel.units_down);
        let settings = &self.scene.settings;
        let patterns = self.patterns.set();
        let (sol, seconds) = run(py, threads, || {
            let start = std::time::Instant::now();
            let op = patterns.head(m)?.operator(scheme.form());
            let mut solver = evaluate::run_solver(settings);
            if let Some(z) = scheme.zero_one() {
                solver.zero_one = z;
            }
            let sol = solver.solve(op.as_ref(), &y, across, down, scheme.form())?;
            Ok((sol, start.elapsed().as_secs_f64()))
        })?;
        Ok((
            vec2(py, sol.image.data, down, across)?,
            sol.iterations,
            format!("{:?}", sol.stop),
            sol.converged,
            sol.relative_residual,
            seconds,
        ))
    }
}

// ---------------------------------------------------------------------------------------------
// datasets

/// A dataset's inputs rebuilt from its folder (see `spibench.open_dataset`).
#[pyclass(frozen, module = "spibench._spibench")]
struct Dataset {
    prep: Arc<Prepared>,
    matrices: Arc<KernelMatrices>,
    kernel: Arc<LibKernel>,
}

/// The spec of the dataset in `dir`, read from its copy, its bench the folder's copy unless the
/// original (same SHA-256) is still in place (relative paths in it then resolve as before).
fn dataset_spec(dir: &Path) -> Result<spibench::scene::dataset::DatasetSpec> {
    let manifest = dataset::read_manifest(dir)?;
    let copy = dir.join("spec.ron");
    let text = std::fs::read_to_string(&copy).map_err(|e| Error::read(&copy, e))?;
    let original = PathBuf::from(&manifest.provenance.spec_file);
    let mut spec = spibench::scene::dataset::parse_dataset(&text, &original)?;
    let same = std::fs::read(&spec.bench_path)
        .is_ok_and(|b| dataset::sha256_hex(&b) == manifest.provenance.bench_sha256);
    if !same {
        spec.bench_path = dir.join("bench.ron");
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
fn make_dataset(
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
fn dataset_noise_seed(seed: u64, s: u64) -> u64 {
    dataset::noise_seed(seed, s)
}

/// The library's version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _spibench(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("InputError", m.py().get_type::<InputError>())?;
    m.add_class::<Bench>()?;
    m.add_class::<Trace>()?;
    m.add_class::<Kernel>()?;
    m.add_class::<Acquisition>()?;
    m.add_class::<Dataset>()?;
    m.add_function(wrap_pyfunction!(make_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(dataset_noise_seed, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
