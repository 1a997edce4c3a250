//! `Acquisition`: one scheme's traced acquisition, its simulated measurement, the linear
//! operator with its adjoint, and TVAL3.

use std::sync::Arc;

use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use spibench::acquisition::{PackedPatterns, Scheme};
use spibench::detector::RecordModel;
use spibench::error::{Error, Result};
use spibench::pipeline::evaluate;
use spibench::pipeline::operator::{self, KernelMatrices, TracedOperator};
use spibench::scene::run::RunScene;
use spibench::trace::kernel::Kernel as LibKernel;
use spibench::transport::Transport;

use crate::kernel::Kernel;
use crate::{rows_of, run, scheme_named, to_py, vec1, vec2};

/// One scheme's traced acquisition through an object kernel (see `spibench.Acquisition`).
#[pyclass(frozen, module = "spibench._spibench")]
pub(crate) struct Acquisition {
    /// The scene recorded: its electronics, settings and the schemes whose sequences are
    /// recorded together (they share the oscilloscope's ranges).
    scene: Arc<RunScene>,
    kernel: Arc<LibKernel>,
    /// The patterns recorded (at least `m`), with their operator built once.
    patterns: PackedPatterns,
    op: Arc<TracedOperator>,
}

impl Acquisition {
    pub(crate) fn build(
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

    /// The scheme's key (`scb`, `double_arm`, …), as the command line names it.
    #[getter]
    fn scheme(&self) -> &'static str {
        self.op.scheme.key()
    }

    /// M, the number of measurements.
    #[getter]
    fn measurements(&self) -> usize {
        self.op.measurements
    }

    /// The number of object pixels (H·W of the kernel's grid).
    #[getter]
    fn pixels(&self) -> usize {
        self.op.pixels
    }

    /// (down, across) DMD units.
    #[getter]
    fn units(&self) -> (usize, usize) {
        (self.kernel.units_down, self.kernel.units_across)
    }

    /// (H, W) of the objects.
    #[getter]
    fn grid(&self) -> (usize, usize) {
        (self.kernel.grid.height_px, self.kernel.grid.width_px)
    }

    /// Whether the bench's run settings switch the noise on.
    #[getter]
    fn noise_default(&self) -> bool {
        self.scene.settings.noise
    }

    /// The schemes recorded together with this one (its own first), whose sequences share the
    /// record.
    #[getter]
    fn recorded(&self) -> Vec<&'static str> {
        self.scene
            .settings
            .schemes
            .iter()
            .map(|s| s.key())
            .collect()
    }

    /// y₀ (M,), the measurement of the black object: the affine part (V).
    #[getter]
    fn offset<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec1(py, self.op.offset.clone())
    }

    /// The coefficients of the operator's measurement model.
    #[getter]
    fn coefficients(&self) -> Coefficients {
        let k = &self.op.coefficients;
        Coefficients {
            ka: k.ka,
            kb: k.kb,
            ks: (k.ks[0], k.ks[1]),
            kc: (k.kc[0], k.kc[1]),
        }
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

    /// TVAL3 on the DMD units, as `spibench run` solves this scheme.
    #[pyo3(signature = (y, threads=None))]
    fn reconstruct<'py>(
        &self,
        py: Python<'py>,
        y: PyReadonlyArray1<'py, f64>,
        threads: Option<usize>,
    ) -> PyResult<Solution> {
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
        Ok(Solution {
            image: vec2(py, sol.image.data, down, across)?.unbind(),
            iterations: sol.iterations,
            stop: format!("{:?}", sol.stop),
            converged: sol.converged,
            relative_residual: sol.relative_residual,
            seconds,
        })
    }
}

/// The coefficients of y_i = ka·a_i + kb·b_i + ks₊·S₊ + ks₋·S₋ + kc₊·c₊ + kc₋·c₋ + const
/// (`pipeline::operator::Coefficients`), in V/A (the calibrated scheme: 1/A); `ks` and `kc`
/// per arm (+, −).
#[pyclass(frozen, get_all, module = "spibench._spibench")]
pub(crate) struct Coefficients {
    ka: f64,
    kb: f64,
    ks: (f64, f64),
    kc: (f64, f64),
}

/// A TVAL3 reconstruction: the image (down × across), the iterations, why it stopped
/// (`Tolerance`, `MaxOuter`, `MaxIterations`), whether it converged, its relative residual and
/// the seconds it took.
#[pyclass(frozen, get_all, module = "spibench._spibench")]
pub(crate) struct Solution {
    image: Py<PyArray2<f64>>,
    iterations: usize,
    stop: String,
    converged: bool,
    relative_residual: f64,
    seconds: f64,
}
