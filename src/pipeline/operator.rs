//! The traced acquisition as a linear operator on objects: the measurements of one scheme,
//! noise-free and unclipped, written y = A t + y₀ for an object t on an object kernel's grid
//! (transmittance per pixel), with A matrix-free and its exact adjoint Aᵀ. This is what
//! programs that solve for the object (Python's `spibench.Acquisition`, deepinv) need beside
//! the measurement itself, which [`crate::pipeline::evaluate::acquire`] simulates with the
//! electronics in time and their noise.
//!
//! The model is the record stage's, term by term (`Transport::frame_currents`,
//! `Bap::diode_currents`, `OutputStage::ideal_v`, `Scheme::measurements`):
//!
//! - the kernel gives, for arm d, the per-unit gains g_d = G_d t + g⁰_d (G_d[j][i] =
//!   K[d][on][i][j] − K[d][off][i][j]) and the pattern-independent traced light
//!   c_d = C_d·t + c⁰_d (the off-state light and the light that never met the pattern), both
//!   linear in t with the object-independent light (⁰) apart;
//! - a frame showing P gives the light L₊ = P·g₊ + c₊, L₋ = Σg₋ − P·g₋ + c₋ (its complement
//!   swaps the roles of P and 1 − P), the diode currents s_d·(L_d + ambient_d) + dark_d, and the
//!   outputs gain·current + offset (RF: I₊ − I₋; monitors: I₊, I₋);
//! - each scheme's y_i is then, with a_i = P_i·g₊, b_i = P_i·g₋ and S_d = Σg_d, one affine
//!   function of (a_i, b_i, S₊, S₋, c₊, c₋) with the same coefficients for every i
//!   ([`Coefficients`]). The constants (ambient, dark, output offsets) enter y₀ only.
//!
//! The calibrated double-arm scheme divides by each arm's full-scale swing measured on the
//! object itself, which is not linear in the object; its linear part divides by the swings of
//! the clear object (t = 1) instead, so that A t + y₀ equals its measurement for objects of the
//! clear object's totals and scales with them otherwise.
//!
//! What the operator leaves out, and the simulated measurement keeps: the light of paths that
//! met the chart more than once, weighted here by the first pixel they met instead of the
//! product of every pixel met (`Kernel::apply_linear` against `Kernel::apply`; about 1 % of
//! the offset c₋ on the paper bench, trace::kernel), the single pole's
//! transient from the previous frame (e^{−2πB·t_settle}, below 10⁻³⁰ at the paper's settings),
//! clipping at the output swing and the oscilloscope's window, lamp and ambient drift, and the
//! noise.

use std::sync::Arc;

use rayon::prelude::*;

use crate::acquisition::{PatternSet, Scheme, patterns_for_ratio};
use crate::detector::Bap;
use crate::error::{Error, Result};
use crate::optics::Arm;
use crate::reconstruction::{LinearOperator, PatternForm};
use crate::scene::dataset::KernelSpec;
use crate::scene::doc::BenchDoc;
use crate::scene::run::RunScene;
use crate::trace::kernel::{Kernel, ObjectGrid, trace_kernel};
use crate::trace::{BatchTally, TraceOptions};

/// A sparse matrix in compressed rows (rows × cols), column indices ascending in each row.
#[derive(Debug, Clone, PartialEq)]
pub struct Csr {
    pub rows: usize,
    pub cols: usize,
    pub indptr: Vec<usize>,
    pub indices: Vec<u32>,
    pub data: Vec<f64>,
}

impl Csr {
    /// From (row, col, value) triplets sorted by (col, row), as a kernel's entries are sorted
    /// by (pixel, unit): a counting sort by row keeps the columns ascending in each row.
    fn from_col_major(rows: usize, cols: usize, triplets: &[(u32, u32, f64)]) -> Csr {
        let mut indptr = vec![0usize; rows + 1];
        for &(r, _, _) in triplets {
            indptr[r as usize + 1] += 1;
        }
        for r in 0..rows {
            indptr[r + 1] += indptr[r];
        }
        let mut next = indptr.clone();
        let mut indices = vec![0u32; triplets.len()];
        let mut data = vec![0.0; triplets.len()];
        for &(r, c, v) in triplets {
            let k = &mut next[r as usize];
            indices[*k] = c;
            data[*k] = v;
            *k += 1;
        }
        Csr {
            rows,
            cols,
            indptr,
            indices,
            data,
        }
    }

    /// y = M x (each row summed in column order, from 0).
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        for (r, out) in y.iter_mut().enumerate().take(self.rows) {
            let mut s = 0.0;
            for k in self.indptr[r]..self.indptr[r + 1] {
                s += self.data[k] * x[self.indices[k] as usize];
            }
            *out = s;
        }
    }

    /// x += Mᵀ y.
    pub fn apply_adjoint_add(&self, y: &[f64], x: &mut [f64]) {
        for (r, &yr) in y.iter().enumerate().take(self.rows) {
            if yr == 0.0 {
                continue;
            }
            for k in self.indptr[r]..self.indptr[r + 1] {
                x[self.indices[k] as usize] += self.data[k] * yr;
            }
        }
    }
}

/// The block of T[arm][state] in a kernel entry's `t`.
fn block(arm: Arm, on: bool) -> usize {
    let state = if on { arm.state() } else { arm.other().state() };
    BatchTally::t_block(arm, state)
}

/// A kernel's per-arm matrices: K[d][s] (units × pixels) for each block d·2 + s, the power on
/// the units X (units × pixels), and the object-independent columns (light that never met the
/// chart), all in the kernel's units (A, W per unit transmittance).
#[derive(Debug, Clone, PartialEq)]
pub struct KernelMatrices {
    /// Indexed by [`BatchTally::t_block`].
    pub t: [Csr; 4],
    pub t0: [Vec<f64>; 4],
    pub x: Csr,
    pub x0: Vec<f64>,
    /// Per arm, the gain matrix G_d = K[d][on] − K[d][off] and its per-entry standard error
    /// (batch means).
    pub g: [Csr; 2],
    pub g_stderr: [Csr; 2],
    pub g0: [Vec<f64>; 2],
    /// Per arm, the pattern-independent traced light per pixel C_d (off-state light and light
    /// that never met the pattern area) and its object-independent part c⁰_d (A).
    pub c: [Vec<f64>; 2],
    pub c0: [f64; 2],
}

impl KernelMatrices {
    pub fn new(kernel: &Kernel) -> KernelMatrices {
        let (units, npix) = (kernel.units(), kernel.grid.pixels());
        let bypass = npix as u32;
        let nb = kernel.batches as f64;
        let mut t: [Vec<(u32, u32, f64)>; 4] = Default::default();
        let mut t0 = [0, 1, 2, 3].map(|_| vec![0.0; units]);
        let (mut x, mut x0) = (Vec::new(), vec![0.0; units]);
        let mut g: [Vec<(u32, u32, f64)>; 2] = Default::default();
        let mut gse: [Vec<(u32, u32, f64)>; 2] = Default::default();
        let mut g0 = [vec![0.0; units], vec![0.0; units]];
        let mut c = [vec![0.0; npix], vec![0.0; npix]];
        let mut c0 = [0.0; 2];
        for (i, j, e) in &kernel.entries {
            let (i, j) = (*i, *j);
            for arm in Arm::ALL {
                let (on, off) = (e.t[block(arm, true)], e.t[block(arm, false)]);
                if i == bypass {
                    g0[arm][j as usize] += on - off;
                    c0[arm] += off;
                } else {
                    g[arm.index()].push((j, i, on - off));
                    let v = if nb > 1.0 {
                        (e.g2[arm].max(0.0) * nb / (nb - 1.0)).sqrt()
                    } else {
                        f64::INFINITY
                    };
                    gse[arm.index()].push((j, i, v));
                    c[arm][i as usize] += off;
                }
            }
            for (b, tb) in t.iter_mut().enumerate() {
                if i == bypass {
                    t0[b][j as usize] = e.t[b];
                } else {
                    tb.push((j, i, e.t[b]));
                }
            }
            if i == bypass {
                x0[j as usize] = e.x;
            } else {
                x.push((j, i, e.x));
            }
        }
        for (i, bi) in kernel.b.iter().enumerate() {
            for arm in Arm::ALL {
                if i == npix {
                    c0[arm] += bi[arm];
                } else {
                    c[arm][i] += bi[arm];
                }
            }
        }
        let csr = |v: &[(u32, u32, f64)]| Csr::from_col_major(units, npix, v);
        KernelMatrices {
            t: [0, 1, 2, 3].map(|b| csr(&t[b])),
            t0,
            x: csr(&x),
            x0,
            g: [csr(&g[0]), csr(&g[1])],
            g_stderr: [csr(&gse[0]), csr(&gse[1])],
            g0,
            c,
            c0,
        }
    }
}

/// The coefficients of y_i = ka·a_i + kb·b_i + ks₊·S₊ + ks₋·S₋ + kc₊·c₊ + kc₋·c₋ (module
/// documentation), per scheme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coefficients {
    pub ka: f64,
    pub kb: f64,
    pub ks: [f64; 2],
    pub kc: [f64; 2],
}

impl Coefficients {
    /// The coefficients of `scheme` for detector `bap`; `clear_totals` are S₊, S₋ of the clear
    /// object (the calibrated scheme's reference swings).
    pub fn new(scheme: Scheme, bap: &Bap, clear_totals: [f64; 2]) -> Coefficients {
        let s = bap.responsivity_scale;
        // Volts per ampere of light on each arm, through its monitor and through the RF output.
        let alpha = bap.monitors[0].gain_v_per_a * s[0];
        let beta = bap.monitors[1].gain_v_per_a * s[1];
        let rf = [bap.rf.gain_v_per_a * s[0], bap.rf.gain_v_per_a * s[1]];
        let zero = Coefficients {
            ka: 0.0,
            kb: 0.0,
            ks: [0.0; 2],
            kc: [0.0; 2],
        };
        match scheme {
            // V₊(P) = α(a + c₊) + const.
            Scheme::Traditional | Scheme::TraditionalZeroMean => Coefficients {
                ka: alpha,
                kc: [alpha, 0.0],
                ..zero
            },
            // V₊(P) − V₊(1 − P) = α(2a − S₊).
            Scheme::SingleArmComplementary => Coefficients {
                ka: 2.0 * alpha,
                ks: [-alpha, 0.0],
                ..zero
            },
            // V₊(P) − V₋(P) = α(a + c₊) − β(S₋ − b + c₋) + const.
            Scheme::DoubleArm | Scheme::DoubleArmOffset => Coefficients {
                ka: alpha,
                kb: beta,
                ks: [0.0, -beta],
                kc: [alpha, -beta],
            },
            // V_rf(P) − V_rf(1 − P) = γs₊(2a − S₊) − γs₋(S₋ − 2b).
            Scheme::SecondaryComplementaryBalancing => Coefficients {
                ka: 2.0 * rf[0],
                kb: 2.0 * rf[1],
                ks: [-rf[0], -rf[1]],
                kc: [0.0; 2],
            },
            // a/S₊ − (S₋ − b)/S₋ with the clear object's swings.
            Scheme::DoubleArmCalibrated => Coefficients {
                ka: 1.0 / clear_totals[0],
                kb: 1.0 / clear_totals[1],
                ks: [0.0, -1.0 / clear_totals[1]],
                kc: [0.0; 2],
            },
        }
    }
}

/// One scheme's traced acquisition through an object kernel as y = A t + y₀ (module
/// documentation).
pub struct TracedOperator {
    pub scheme: Scheme,
    /// Measurements M (base patterns used).
    pub measurements: usize,
    pub pixels: usize,
    pub units: usize,
    pub coefficients: Coefficients,
    /// y₀, the measurements of the black object (t = 0).
    pub offset: Vec<f64>,
    patterns: Arc<dyn LinearOperator>,
    g: [Csr; 2],
    c: [Vec<f64>; 2],
}

impl TracedOperator {
    /// The operator of `scheme` with the first `m` patterns of `patterns`, for the bench of
    /// `scene` whose kernel gave `matrices`.
    pub fn new(
        scene: &RunScene,
        matrices: &KernelMatrices,
        patterns: &PatternSet,
        scheme: Scheme,
        m: usize,
    ) -> Result<TracedOperator> {
        let units = matrices.x.rows;
        if patterns.units() != units {
            return Err(Error::field(
                "patterns",
                format!(
                    "patterns of {} units for a kernel of {units} units",
                    patterns.units()
                ),
            ));
        }
        let head = patterns.head(m)?;
        let op = head.operator(PatternForm::ZeroOne);
        let pixels = matrices.x.cols;
        // S± of the clear object: G·1 + g⁰ summed.
        let clear = Arm::ALL.map(|arm| {
            let mut g = vec![0.0; units];
            matrices.g[arm.index()].apply(&vec![1.0; pixels], &mut g);
            g.iter().zip(&matrices.g0[arm]).map(|(a, b)| a + b).sum()
        });
        let coefficients = Coefficients::new(scheme, &scene.detector, clear);
        let mut me = TracedOperator {
            scheme,
            measurements: m,
            pixels,
            units,
            coefficients,
            offset: Vec::new(),
            patterns: op,
            g: matrices.g.clone(),
            c: matrices.c.clone(),
        };
        // y₀: the object-independent light through the same coefficients, plus the constants
        // (ambient, dark, output offsets) as the scheme forms them from equal frames.
        let mut offset = me.combine(&matrices.g0, matrices.c0);
        let bap = &scene.detector;
        let amb = Arm::ALL.map(|arm| scene.bench.detectors()[arm].ambient_current_a);
        let dark = Arm::ALL.map(|arm| scene.bench.detectors()[arm].dark_current_a);
        let dark_frame = bap.ideal_outputs_v(bap.diode_currents([0.0; 2], amb, dark));
        if scheme != Scheme::DoubleArmCalibrated {
            let frames = vec![dark_frame; scheme.dmd_frames(1).max(2)];
            let k = scheme.measurements(&frames, 1)[0];
            offset.iter_mut().for_each(|y| *y += k);
        }
        me.offset = offset;
        Ok(me)
    }

    /// y = coefficients applied to per-unit gains `g` and pattern-independent light `c`.
    fn combine(&self, g: &[Vec<f64>; 2], c: [f64; 2]) -> Vec<f64> {
        let k = &self.coefficients;
        let m = self.measurements;
        let (mut a, mut b) = (vec![0.0; m], vec![0.0; m]);
        if k.ka != 0.0 {
            self.patterns.apply(&g[0], &mut a);
        }
        if k.kb != 0.0 {
            self.patterns.apply(&g[1], &mut b);
        }
        let s = [g[0].iter().sum::<f64>(), g[1].iter().sum::<f64>()];
        let common = k.ks[0] * s[0] + k.ks[1] * s[1] + k.kc[0] * c[0] + k.kc[1] * c[1];
        a.iter()
            .zip(&b)
            .map(|(a, b)| k.ka * a + k.kb * b + common)
            .collect()
    }

    fn check(&self, what: &str, v: &[f64], n: usize) -> Result<()> {
        if v.len() != n {
            return Err(Error::field(
                what,
                format!("has {} values, the operator needs {n}", v.len()),
            ));
        }
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::field(
                what,
                format!("value {i} is not finite ({})", v[i]),
            ));
        }
        Ok(())
    }

    /// A t (the linear part; V, or 1 for the calibrated scheme).
    pub fn apply(&self, t: &[f64]) -> Result<Vec<f64>> {
        self.check("x", t, self.pixels)?;
        let g = [0, 1].map(|d| {
            let mut v = vec![0.0; self.units];
            self.g[d].apply(t, &mut v);
            v
        });
        let c = [0, 1].map(|d| dot(&self.c[d], t));
        Ok(self.combine(&g, c))
    }

    /// Aᵀ y, the exact adjoint of [`TracedOperator::apply`].
    pub fn apply_adjoint(&self, y: &[f64]) -> Result<Vec<f64>> {
        self.check("y", y, self.measurements)?;
        let k = &self.coefficients;
        let sum_y: f64 = y.iter().sum();
        let mut t = vec![0.0; self.pixels];
        let kd = [k.ka, k.kb];
        for (d, (g, c)) in self.g.iter().zip(&self.c).enumerate() {
            let mut u = vec![0.0; self.units];
            if kd[d] != 0.0 {
                let w: Vec<f64> = y.iter().map(|v| kd[d] * v).collect();
                self.patterns.apply_adjoint(&w, &mut u);
            }
            let s = k.ks[d] * sum_y;
            u.iter_mut().for_each(|v| *v += s);
            g.apply_adjoint_add(&u, &mut t);
            let cd = k.kc[d] * sum_y;
            if cd != 0.0 {
                for (ti, ci) in t.iter_mut().zip(c) {
                    *ti += cd * ci;
                }
            }
        }
        Ok(t)
    }

    /// [`TracedOperator::apply`] on each object of a batch (row-major, `pixels` per object),
    /// in parallel; the result does not depend on the thread count.
    pub fn apply_batch(&self, t: &[f64]) -> Result<Vec<f64>> {
        batch(t, self.pixels, |x| self.apply(x))
    }

    /// [`TracedOperator::apply_adjoint`] on each of a batch of measurement vectors.
    pub fn apply_adjoint_batch(&self, y: &[f64]) -> Result<Vec<f64>> {
        batch(y, self.measurements, |v| self.apply_adjoint(v))
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `f` on each chunk of `n` values of `v`, in parallel, concatenated in order; the error of the
/// first failing chunk in order ([`crate::error::in_order`]).
fn batch(
    v: &[f64],
    n: usize,
    f: impl Fn(&[f64]) -> Result<Vec<f64>> + Sync + Send,
) -> Result<Vec<f64>> {
    if n == 0 || !v.len().is_multiple_of(n) {
        return Err(Error::field(
            "batch",
            format!("{} values are not a whole number of items of {n}", v.len()),
        ));
    }
    let parts = crate::error::in_order(v.par_chunks(n).map(f).collect())?;
    Ok(parts.concat())
}

/// A bench made ready for its clear-chart object kernel, the one way `spibench dataset` and the
/// Python package's `Bench.kernel` trace one: the chart the kernel spec names (or the bench's
/// only chart) made clear glass centred on its `position_mm` (where the bench puts the chart
/// point it images), and the spec's object grid on it.
pub struct ClearChart {
    doc: BenchDoc,
    grid: ObjectGrid,
    rays: u64,
    seed: u64,
}

impl ClearChart {
    /// Checks `spec` ([`KernelSpec::check`]) and picks its chart in `doc`; nothing is built or
    /// traced. Every error names its field of `spec` (`grid_px`, `field_mm`, `rays`, `chart`)
    /// and no file, for the caller to locate (a dataset spec, a Python argument).
    pub fn new(doc: &BenchDoc, spec: &KernelSpec) -> Result<ClearChart> {
        use crate::scene::bench::{ChartPatternSpec, ChartSpec, ElementSpec};
        spec.check()?;
        let mut doc = doc.clone();
        let (mut found, mut names) = (None, Vec::new());
        for el in doc.file.elements.iter_mut() {
            if let ElementSpec::Chart(ChartSpec {
                name,
                pattern,
                center_on,
                ..
            }) = el
            {
                if found.is_none() && spec.chart.as_ref().is_none_or(|want| want == name) {
                    *pattern = ChartPatternSpec::Clear;
                    *center_on = None;
                    found = Some(names.len());
                }
                names.push(format!("{name:?}"));
            }
        }
        let chart = match (found, &spec.chart) {
            (Some(i), Some(_)) => i,
            (Some(i), None) if names.len() == 1 => i,
            (_, Some(want)) => {
                return Err(Error::field(
                    "chart",
                    format!(
                        "the bench has no chart named {want:?} (its charts: {})",
                        if names.is_empty() {
                            "none".to_string()
                        } else {
                            names.join(", ")
                        }
                    ),
                ));
            }
            (_, None) => {
                return Err(Error::field(
                    "chart",
                    match names.len() {
                        0 => "the bench has no chart: an object kernel needs one".to_string(),
                        n => format!("the bench has {n} charts ({}): name one", names.join(", ")),
                    },
                ));
            }
        };
        let (w, h) = spec.grid_px;
        let grid = ObjectGrid {
            chart,
            width_px: w,
            height_px: h,
            width_m: spec.field_mm.0 * 1e-3,
            height_m: spec.field_mm.1 * 1e-3,
        };
        Ok(ClearChart {
            doc,
            grid,
            rays: spec.rays,
            seed: spec.seed,
        })
    }

    /// Builds the bench with its chart clear and traces the kernel.
    pub fn trace(&self) -> Result<Kernel> {
        let options = TraceOptions::new(self.rays, self.seed);
        trace_kernel(&self.doc.build()?, self.grid, &options)
    }
}

/// The clear-chart object kernel of `doc` that `spec` describes ([`ClearChart`]).
pub fn clear_chart_kernel(doc: &BenchDoc, spec: &KernelSpec) -> Result<Kernel> {
    ClearChart::new(doc, spec)?.trace()
}

/// The patterns `scene`'s settings name, enough for sampling ratio `ratio`, and M.
pub fn patterns_for(scene: &RunScene, ratio: f64) -> Result<(PatternSet, usize)> {
    if !(ratio.is_finite() && ratio > 0.0 && ratio <= 1.0) {
        return Err(Error::field(
            "ratio",
            format!("a sampling ratio lies in (0, 1], got {ratio}"),
        ));
    }
    let (w, h) = scene.bench.units_shape();
    let m = patterns_for_ratio(ratio, w * h);
    Ok((scene.settings.patterns.build(w, h, m)?, m))
}

#[cfg(test)]
mod tests;
