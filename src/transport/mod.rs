//! From traced tallies to the linear transport model of docs/design.md ("Transport is linear"):
//! per-unit maps x_j, T[d][s][j], g±_j, k±_j, the scalars k±, b±, k', the imbalance, their
//! Monte Carlo standard errors, and the flux ledger.
//!
//! For a pattern P (P_j = 1: state +, 0: state −):
//!
//!   y₊(P) = Σ_j P_j·g₊_j + c₊,       g₊_j = T[+][+][j] − T[+][−][j],  c₊ = Σ_j T[+][−][j] + B₊
//!   y₋(P) = Σ_j (1 − P_j)·g₋_j + c₋, g₋_j = T[−][−][j] − T[−][+][j],  c₋ = Σ_j T[−][+][j] + B₋
//!
//! where B± is the pattern-independent current of arm ±: traced light that never met the pattern
//! area (mirrors outside it, window and package reflections, ghosts, chart leakage that lands
//! outside the pattern) plus the ambient and dark currents. k±_j = g±_j / x_j with x_j the power
//! incident on unit j's mirrors (the light that lands on the pattern mirrors within the unit's
//! footprint, averaged over the two mirror states, whose tilted facets differ only at their
//! edges; light falling into the gaps between mirrors is not part of x_j);
//! k± = Σ_j g±_j / Σ_j x_j (A/W), b± = c± (A), k' = k₊ + k₋, imbalance = (k₊ − k₋)/(k₊ + k₋).
//!
//! Standard errors use batch means over the trace's fixed batches: for a total S = Σ_b S_b,
//! var ≈ B/(B−1)·Σ_b (S_b − (n_b/N)·S)²; for a ratio R = ΣA_b/ΣD_b (delta method),
//! var ≈ B/(B−1)·Σ_b (A_b − R·D_b)² / (ΣD_b)².
//! A trace of a single batch has no spread to measure: its standard errors are NaN for the
//! scalars and +∞ for the per-unit maps ([`Transport::k_map_stderr`]), whether the transport
//! comes from a trace's tallies or from an object kernel.
//!
//! Per-arm arrays (`[T; 2]`) are indexed by [`Arm`]: + is 0, − is 1.

use crate::optics::dmd::MirrorState;
use crate::optics::{Arm, Bench};
use crate::reconstruction::{BitMatrix, LinearOperator, PackedOperator, PatternForm};
use crate::trace::tally::{
    COMMON, SLOT_EMITTED, SLOT_ESCAPED, SLOT_PATH_CAP, SLOT_SAMPLED, branch, slot_detected,
};
pub mod kernel;
pub mod metrics;

use crate::trace::{BatchTally, Tallies};

/// A Monte Carlo estimate and its standard error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub stderr: f64,
}

impl Estimate {
    pub fn exact(value: f64) -> Estimate {
        Estimate { value, stderr: 0.0 }
    }

    pub fn relative_stderr(&self) -> f64 {
        self.stderr / self.value.abs()
    }
}

/// Batch-means estimate of a total Σ_b s_b where batch b has n_b of the N rays.
pub fn total_estimate(batches: &[(u64, f64)]) -> Estimate {
    let n: u64 = batches.iter().map(|b| b.0).sum();
    let s: f64 = batches.iter().map(|b| b.1).sum();
    let nb = batches.len();
    if nb < 2 || n == 0 {
        return Estimate {
            value: s,
            stderr: f64::NAN,
        };
    }
    let mut q = 0.0;
    for &(k, v) in batches {
        let e = v - (k as f64 / n as f64) * s;
        q += e * e;
    }
    Estimate {
        value: s,
        stderr: (q * nb as f64 / (nb as f64 - 1.0)).sqrt(),
    }
}

/// Batch-means (delta-method) estimate of a ratio ΣA_b / ΣD_b.
pub fn ratio_estimate(pairs: &[(f64, f64)]) -> Estimate {
    let a: f64 = pairs.iter().map(|p| p.0).sum();
    let d: f64 = pairs.iter().map(|p| p.1).sum();
    let r = a / d;
    let nb = pairs.len();
    if nb < 2 || d == 0.0 {
        return Estimate {
            value: r,
            stderr: f64::NAN,
        };
    }
    let mut q = 0.0;
    for &(x, y) in pairs {
        let e = x - r * y;
        q += e * e;
    }
    Estimate {
        value: r,
        stderr: (q * nb as f64 / (nb as f64 - 1.0)).sqrt() / d.abs(),
    }
}

/// Where the traced power went in one mirror-state world (W).
#[derive(Debug, Clone, PartialEq)]
pub struct LedgerWorld {
    /// Absorbed power per bench element, in the bench's element order (the lamp housing includes
    /// the analytic emission outside the traced cone).
    pub absorbed_w: Vec<(String, f64)>,
    pub escaped_w: f64,
    pub path_cap_w: f64,
    /// Power reaching the photodiodes [arm +, arm −].
    pub detected_w: [f64; 2],
    /// Weight added by following sampled reflections at their path's full weight
    /// (`trace::Sampling::Split`): signed, zero in expectation (its batch spread is the
    /// sampling's own noise), exactly zero with the analogue tracer.
    pub sampled_w: f64,
    /// emitted + sampled − (absorbed + escaped + path cap + detected): zero up to rounding.
    pub residual_w: f64,
}

/// The flux ledger of a trace.
#[derive(Debug, Clone, PartialEq)]
pub struct Ledger {
    /// Emitted power in the traced band (W): the sampled ray weights plus the analytic power
    /// outside the emission cone. Its expectation is the lamp's band power.
    pub emitted_w: f64,
    /// The lamp's band power (W), for comparison with `emitted_w`.
    pub emitted_nominal_w: f64,
    /// Power emitted outside the traced cone (W), booked to the lamp housing.
    pub outside_cone_w: f64,
    /// [every pattern unit in state +, every pattern unit in state −].
    pub worlds: [LedgerWorld; 2],
}

impl Ledger {
    pub fn from_tallies(bench: &Bench, t: &Tallies) -> Ledger {
        let n_el = bench.elements().len();
        let emitted = t.ledger[COMMON][n_el + SLOT_EMITTED] + t.outside_cone_w;
        let world = |branch: usize| {
            let get = |slot: usize| t.ledger[COMMON][slot] + t.ledger[branch][slot];
            let absorbed: Vec<(String, f64)> = (0..n_el)
                .map(|e| {
                    let extra = if e == bench.lamp_housing() {
                        t.outside_cone_w
                    } else {
                        0.0
                    };
                    (bench.elements()[e].clone(), get(e) + extra)
                })
                .collect();
            let escaped = get(n_el + SLOT_ESCAPED);
            let cap = get(n_el + SLOT_PATH_CAP);
            let det = Arm::ALL.map(|arm| get(n_el + slot_detected(arm)));
            let sampled = get(n_el + SLOT_SAMPLED);
            let out: f64 = absorbed.iter().map(|a| a.1).sum::<f64>()
                + escaped
                + cap
                + det[Arm::Plus]
                + det[Arm::Minus];
            LedgerWorld {
                absorbed_w: absorbed,
                escaped_w: escaped,
                path_cap_w: cap,
                detected_w: det,
                sampled_w: sampled,
                residual_w: emitted + sampled - out,
            }
        };
        Ledger {
            emitted_w: emitted,
            emitted_nominal_w: bench.lamp().band_power_w,
            outside_cone_w: t.outside_cone_w,
            worlds: [MirrorState::Plus, MirrorState::Minus].map(|state| world(branch(state))),
        }
    }
}

/// The traced transport of a bench: everything the detector and acquisition stages need.
#[derive(Debug, Clone, PartialEq)]
pub struct Transport {
    pub rays: u64,
    pub seed: u64,
    pub units_across: usize,
    pub units_down: usize,
    /// Power incident on each unit's mirrors (W), row-major.
    pub x_w: Vec<f64>,
    /// T[d][s][j] (A): photocurrent of diode d from light first meeting unit j in state s;
    /// index (d·2 + s)·units + j, d and s 0 = +, 1 = −.
    pub t_a: Vec<f64>,
    /// g±_j (A) [arm +, arm −].
    pub g_a: [Vec<f64>; 2],
    /// k±_j = g±_j / x_j (A/W); 0 where no light reached the unit.
    pub k_map: [Vec<f64>; 2],
    /// Standard error of k±_j (A/W), from the spread of the batch ratios; +∞ where light reached
    /// the unit in fewer than two batches (unresolved: one batch's ratio has no spread to
    /// measure, and the batch formula would give exactly 0). Infinite rather than NaN so that
    /// two identical transports compare equal. A transport from an object kernel shows this only
    /// for a single-batch trace (its moments are centred and summed over pixels).
    pub k_map_stderr: [Vec<f64>; 2],
    /// Standard errors of g±_j (A) and of x_j (W), batch means (the spread of the unit's batch
    /// sums); +∞ for a single-batch trace, 0 where no light reached the unit.
    pub g_map_stderr: [Vec<f64>; 2],
    pub x_map_stderr: Vec<f64>,
    /// c± (A) = traced pattern-independent current + ambient + dark.
    pub c_a: [f64; 2],
    /// The traced part of c± (A) with its standard error.
    pub c_traced: [Estimate; 2],
    /// Ambient and dark currents (A) per arm.
    pub ambient_a: [f64; 2],
    pub dark_a: [f64; 2],
    /// Scalars.
    pub x_total: Estimate,
    pub k: [Estimate; 2],
    pub b: [Estimate; 2],
    pub k_prime: Estimate,
    pub imbalance: Estimate,
    pub ledger: Ledger,
}

/// The batch-means factor B/(B − 1) of B batches; None for fewer than two batches, which have no
/// spread to measure.
pub(crate) fn batch_factor(batches: u64) -> Option<f64> {
    let nb = batches as f64;
    (nb >= 2.0).then(|| nb / (nb - 1.0))
}

/// The batch second moments of the per-unit gains g±_j and powers x_j that the standard errors
/// of the k±_j maps come from.
pub(crate) struct UnitMoments<'a> {
    /// Σ_b g_bj² per arm.
    pub g2: &'a [Vec<f64>; 2],
    /// Σ_b g_bj·x_bj per arm.
    pub gx: &'a [Vec<f64>; 2],
    /// Σ_b x_bj².
    pub x2: &'a [f64],
    /// Raw sums over the batches (a trace's tallies) rather than sums centred on the batch mean
    /// (an object kernel's product, summed over pixels taken as independent). Only raw sums show
    /// a unit lit in one batch alone, whose k±_j is unresolved.
    pub raw: bool,
}

/// Everything a transport is made of besides the per-unit maps, which [`Transport::assemble`]
/// derives from the summed T and x and their batch moments.
pub(crate) struct TransportParts<'a> {
    pub rays: u64,
    pub seed: u64,
    pub units_across: usize,
    pub units_down: usize,
    pub batches: u64,
    /// T[d][s][j] (A), index [`BatchTally::t_index`].
    pub t_a: Vec<f64>,
    pub x_w: Vec<f64>,
    pub moments: UnitMoments<'a>,
    pub c_traced: [Estimate; 2],
    pub x_total: Estimate,
    pub k: [Estimate; 2],
    pub k_prime: Estimate,
    pub imbalance: Estimate,
    pub ledger: Ledger,
}

impl Transport {
    pub fn from_tallies(bench: &Bench, t: &Tallies) -> Transport {
        let c_traced = Arm::ALL.map(|arm| {
            let v: Vec<(u64, f64)> = t.batches.iter().map(|b| (b.rays, b.c[arm])).collect();
            total_estimate(&v)
        });
        let k = Arm::ALL.map(|arm| {
            let v: Vec<(f64, f64)> = t.batches.iter().map(|b| (b.g[arm], b.x)).collect();
            ratio_estimate(&v)
        });
        let (plus, minus) = (Arm::Plus, Arm::Minus);
        let k_prime = ratio_estimate(
            &t.batches
                .iter()
                .map(|b| (b.g[plus] + b.g[minus], b.x))
                .collect::<Vec<_>>(),
        );
        let imbalance = ratio_estimate(
            &t.batches
                .iter()
                .map(|b| (b.g[plus] - b.g[minus], b.g[plus] + b.g[minus]))
                .collect::<Vec<_>>(),
        );
        let x_total = total_estimate(&t.batches.iter().map(|b| (b.rays, b.x)).collect::<Vec<_>>());
        Transport::assemble(
            bench,
            TransportParts {
                rays: t.rays,
                seed: t.seed,
                units_across: t.units_across,
                units_down: t.units_down,
                batches: t.batches.len() as u64,
                t_a: t.t.clone(),
                x_w: t.x.clone(),
                moments: UnitMoments {
                    g2: &t.g2,
                    gx: &t.gx,
                    x2: &t.x2,
                    raw: true,
                },
                c_traced,
                x_total,
                k,
                k_prime,
                imbalance,
                ledger: Ledger::from_tallies(bench, t),
            },
        )
    }

    /// The one body of [`Transport::from_tallies`] and [`Transport::from_kernel`]: the gains
    /// g±_j, the maps k±_j with their standard errors (and the guards on them), and c± and b±
    /// with the ambient and dark currents of `bench`'s detectors.
    pub(crate) fn assemble(bench: &Bench, parts: TransportParts) -> Transport {
        let units = parts.x_w.len();
        let (t, m) = (&parts.t_a, &parts.moments);
        let idx =
            |arm: Arm, state: MirrorState, j: usize| BatchTally::t_index(units, arm, state, j);
        let g_a: [Vec<f64>; 2] = Arm::ALL.map(|arm| {
            let (on, off) = (arm.state(), arm.other().state());
            (0..units)
                .map(|j| t[idx(arm, on, j)] - t[idx(arm, off, j)])
                .collect()
        });
        let bfac = batch_factor(parts.batches);
        let mut k_map = [vec![0.0; units], vec![0.0; units]];
        let mut k_map_stderr = [vec![0.0; units], vec![0.0; units]];
        for arm in Arm::ALL {
            for j in 0..units {
                let x = parts.x_w[j];
                if x > 0.0 {
                    let k = g_a[arm][j] / x;
                    k_map[arm][j] = k;
                    // Σ_b x_bj² = (Σ_b x_bj)² exactly when one batch holds all of x_j (the
                    // batch ratio estimator's residuals then vanish identically), and is below
                    // it by at least 2·x_min·x_max otherwise; 1e-9 separates the two cases far
                    // above rounding. A single batch holds all of every x_j.
                    let Some(bfac) = bfac else {
                        k_map_stderr[arm][j] = f64::INFINITY;
                        continue;
                    };
                    if m.raw && x * x - m.x2[j] <= 1e-9 * x * x {
                        k_map_stderr[arm][j] = f64::INFINITY;
                        continue;
                    }
                    let q = m.g2[arm][j] - 2.0 * k * m.gx[arm][j] + k * k * m.x2[j];
                    k_map_stderr[arm][j] = (q.max(0.0) * bfac).sqrt() / x;
                }
            }
        }
        // Σ_b (v_b − v̄)² from the moments: raw sums less B·v̄², or already centred.
        let centred = |sq: f64, v: f64| {
            let nb = parts.batches as f64;
            if m.raw { sq - v * v / nb } else { sq }
        };
        let unit_se = |sq: f64, v: f64| match bfac {
            Some(f) => (centred(sq, v).max(0.0) * f).sqrt(),
            None => f64::INFINITY,
        };
        let g_map_stderr = Arm::ALL.map(|arm| {
            (0..units)
                .map(|j| unit_se(m.g2[arm][j], g_a[arm][j]))
                .collect()
        });
        let x_map_stderr = (0..units).map(|j| unit_se(m.x2[j], parts.x_w[j])).collect();
        let ambient_a = Arm::ALL.map(|arm| bench.detectors()[arm].ambient_current_a);
        let dark_a = Arm::ALL.map(|arm| bench.detectors()[arm].dark_current_a);
        let c_traced = parts.c_traced;
        let c_a = Arm::ALL.map(|arm| c_traced[arm].value + ambient_a[arm] + dark_a[arm]);
        let b = Arm::ALL.map(|arm| Estimate {
            value: c_a[arm],
            stderr: c_traced[arm].stderr,
        });
        Transport {
            rays: parts.rays,
            seed: parts.seed,
            units_across: parts.units_across,
            units_down: parts.units_down,
            x_w: parts.x_w,
            t_a: parts.t_a,
            g_a,
            k_map,
            k_map_stderr,
            g_map_stderr,
            x_map_stderr,
            c_a,
            c_traced,
            ambient_a,
            dark_a,
            x_total: parts.x_total,
            k: parts.k,
            b,
            k_prime: parts.k_prime,
            imbalance: parts.imbalance,
            ledger: parts.ledger,
        }
    }

    pub fn units(&self) -> usize {
        self.x_w.len()
    }

    /// T[d][s][j] (A): the current of arm d from light first meeting unit j in state s.
    pub fn t(&self, arm: Arm, state: MirrorState, j: usize) -> f64 {
        self.t_a[BatchTally::t_index(self.units(), arm, state, j)]
    }

    /// The forward model (the one place it is written): the traced light currents [I₊, I₋] (A)
    /// of the frames that show the first `m` rows of `patterns`, where a frame showing F gives
    /// I₊ = Σ_j F_j·g₊_j + c₊ and I₋ = Σ_j (1 − F_j)·g₋_j + c₋ (arm + sees the units in state +,
    /// arm − those in state −), with c± the traced pattern-independent light. Ambient light and
    /// dark current are not included: the detector adds them, so that ambient drift and the
    /// responsivity mismatch act on the right terms. With `complementary`, each pattern P_i is
    /// followed by its complement 1 − P_i (2m frames), as the complementary schemes show them.
    pub fn frame_currents(
        &self,
        patterns: &BitMatrix,
        m: usize,
        complementary: bool,
    ) -> Vec<[f64; 2]> {
        let products = self.pattern_products(patterns, m);
        self.frame_currents_of(&products, complementary)
    }

    /// Σ_j P_ij·g±_j for the first `m` rows of `patterns`: the pattern-dependent part of
    /// [`Transport::frame_currents`], the same for a sequence and its complementary form, so a
    /// record computes it once for all its sequences.
    pub fn pattern_products(&self, patterns: &BitMatrix, m: usize) -> [Vec<f64>; 2] {
        self.pattern_products_of(&PackedOperator::new(patterns.head(m), PatternForm::ZeroOne))
    }

    /// [`Transport::pattern_products`] for every row of a 0/1 operator built beforehand (a
    /// [`crate::acquisition::PackedPatterns`]'s, shared by all the records through its set).
    pub fn pattern_products_of(&self, op: &PackedOperator) -> [Vec<f64>; 2] {
        debug_assert_eq!(op.form(), PatternForm::ZeroOne, "0/1 patterns");
        let m = op.rows();
        let mut pg = [vec![0.0; m], vec![0.0; m]];
        for (g, out) in self.g_a.iter().zip(pg.iter_mut()) {
            op.apply(g, out);
        }
        pg
    }

    /// [`Transport::frame_currents`] from the [`Transport::pattern_products`] of its patterns.
    pub fn frame_currents_of(&self, pg: &[Vec<f64>; 2], complementary: bool) -> Vec<[f64; 2]> {
        let total = Arm::ALL.map(|arm| self.g_a[arm].iter().sum::<f64>());
        let c = Arm::ALL.map(|arm| self.c_traced[arm].value);
        let (plus, minus) = (Arm::Plus, Arm::Minus);
        let m = pg[plus].len();
        let mut out = Vec::with_capacity(if complementary { 2 * m } else { m });
        for (p_plus, p_minus) in pg[plus].iter().zip(&pg[minus]) {
            out.push([p_plus + c[plus], (total[minus] - p_minus) + c[minus]]);
            if complementary {
                out.push([(total[plus] - p_plus) + c[plus], p_minus + c[minus]]);
            }
        }
        out
    }

    /// The diode currents [y₊, y₋] (A) for one pattern, ambient and dark current included:
    /// y±(P) = [`Transport::frame_currents`] + ambient + dark. `pattern.len()` must equal the
    /// number of units.
    pub fn currents(&self, pattern: &[bool]) -> [f64; 2] {
        let units = self.units();
        let bits = BitMatrix::from_fn(1, units, |_, j| pattern.get(j).copied().unwrap_or(false));
        let [light] = self.frame_currents(&bits, 1, false)[..] else {
            return [f64::NAN; 2];
        };
        Arm::ALL.map(|arm| light[arm] + self.ambient_a[arm] + self.dark_a[arm])
    }
}

/// The photocurrents of a fixed-pattern trace ([`crate::trace::PatternMode::Fixed`]):
/// y± = traced current + ambient + dark (A), with the traced part's standard error.
pub fn fixed_pattern_currents(bench: &Bench, t: &Tallies) -> [Estimate; 2] {
    Arm::ALL.map(|arm| {
        let v: Vec<(u64, f64)> = t.batches.iter().map(|b| (b.rays, b.b[arm])).collect();
        let e = total_estimate(&v);
        let det = &bench.detectors()[arm];
        Estimate {
            value: e.value + det.ambient_current_a + det.dark_current_a,
            stderr: e.stderr,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batch_means_formulas() {
        // Equal batches 1, 2, 3: total 6; deviations −1, 0, 1 → q = 2, ×3/2 → var 3.
        let e = total_estimate(&[(10, 1.0), (10, 2.0), (10, 3.0)]);
        assert_eq!(e.value, 6.0);
        assert!((e.stderr - 3f64.sqrt()).abs() < 1e-12);
        // A ratio with A_b = 2 D_b exactly has zero error.
        let r = ratio_estimate(&[(2.0, 1.0), (4.0, 2.0), (1.0, 0.5)]);
        assert_eq!(r.value, 2.0);
        assert!(r.stderr.abs() < 1e-15);
        assert!(total_estimate(&[(1, 1.0)]).stderr.is_nan());
    }
}
