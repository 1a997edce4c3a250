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

use crate::optics::Bench;
use crate::reconstruction::{BitMatrix, LinearOperator, PackedOperator, PatternForm};
use crate::trace::tally::{
    BRANCH_MINUS, BRANCH_PLUS, COMMON, SLOT_DETECTED_MINUS, SLOT_DETECTED_PLUS, SLOT_EMITTED,
    SLOT_ESCAPED, SLOT_PATH_CAP,
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
    /// emitted − (absorbed + escaped + path cap + detected): zero up to rounding.
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
            let det = [
                get(n_el + SLOT_DETECTED_PLUS),
                get(n_el + SLOT_DETECTED_MINUS),
            ];
            let out: f64 =
                absorbed.iter().map(|a| a.1).sum::<f64>() + escaped + cap + det[0] + det[1];
            LedgerWorld {
                absorbed_w: absorbed,
                escaped_w: escaped,
                path_cap_w: cap,
                detected_w: det,
                residual_w: emitted - out,
            }
        };
        Ledger {
            emitted_w: emitted,
            emitted_nominal_w: bench.lamp().band_power_w,
            outside_cone_w: t.outside_cone_w,
            worlds: [world(BRANCH_PLUS), world(BRANCH_MINUS)],
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
    /// two identical transports compare equal.
    pub k_map_stderr: [Vec<f64>; 2],
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

impl Transport {
    pub fn from_tallies(bench: &Bench, t: &Tallies) -> Transport {
        let units = t.units();
        let idx = |d: usize, s: usize, j: usize| BatchTally::t_index(units, d, s, j);
        let g_a: [Vec<f64>; 2] = [0, 1].map(|d| {
            (0..units)
                .map(|j| t.t[idx(d, d, j)] - t.t[idx(d, 1 - d, j)])
                .collect()
        });
        let nb = t.batches.len() as f64;
        let bfac = if nb >= 2.0 { nb / (nb - 1.0) } else { f64::NAN };
        let mut k_map = [vec![0.0; units], vec![0.0; units]];
        let mut k_map_stderr = [vec![0.0; units], vec![0.0; units]];
        for d in 0..2 {
            for j in 0..units {
                let x = t.x[j];
                if x > 0.0 {
                    let k = g_a[d][j] / x;
                    k_map[d][j] = k;
                    // Σ_b x_bj² = (Σ_b x_bj)² exactly when one batch holds all of x_j (the
                    // batch ratio estimator's residuals then vanish identically), and is below
                    // it by at least 2·x_min·x_max otherwise; 1e-9 separates the two cases far
                    // above rounding.
                    if x * x - t.x2[j] <= 1e-9 * x * x {
                        k_map_stderr[d][j] = f64::INFINITY;
                        continue;
                    }
                    let q = t.g2[d][j] - 2.0 * k * t.gx[d][j] + k * k * t.x2[j];
                    k_map_stderr[d][j] = (q.max(0.0) * bfac).sqrt() / x;
                }
            }
        }
        let ambient_a = [0, 1].map(|d| bench.detectors()[d].ambient_current_a);
        let dark_a = [0, 1].map(|d| bench.detectors()[d].dark_current_a);
        let c_traced = [0, 1].map(|d| {
            let v: Vec<(u64, f64)> = t.batches.iter().map(|b| (b.rays, b.c[d])).collect();
            total_estimate(&v)
        });
        let c_a = [0, 1].map(|d| c_traced[d].value + ambient_a[d] + dark_a[d]);
        let b = [0, 1].map(|d| Estimate {
            value: c_a[d],
            stderr: c_traced[d].stderr,
        });
        let k = [0, 1].map(|d| {
            let v: Vec<(f64, f64)> = t.batches.iter().map(|b| (b.g[d], b.x)).collect();
            ratio_estimate(&v)
        });
        let k_prime = ratio_estimate(
            &t.batches
                .iter()
                .map(|b| (b.g[0] + b.g[1], b.x))
                .collect::<Vec<_>>(),
        );
        let imbalance = ratio_estimate(
            &t.batches
                .iter()
                .map(|b| (b.g[0] - b.g[1], b.g[0] + b.g[1]))
                .collect::<Vec<_>>(),
        );
        let x_total = total_estimate(&t.batches.iter().map(|b| (b.rays, b.x)).collect::<Vec<_>>());
        Transport {
            rays: t.rays,
            seed: t.seed,
            units_across: t.units_across,
            units_down: t.units_down,
            x_w: t.x.clone(),
            t_a: t.t.clone(),
            g_a,
            k_map,
            k_map_stderr,
            c_a,
            c_traced,
            ambient_a,
            dark_a,
            x_total,
            k,
            b,
            k_prime,
            imbalance,
            ledger: Ledger::from_tallies(bench, t),
        }
    }

    pub fn units(&self) -> usize {
        self.x_w.len()
    }

    /// T[d][s][j] (A).
    pub fn t(&self, d: usize, s: usize, j: usize) -> f64 {
        self.t_a[BatchTally::t_index(self.units(), d, s, j)]
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
        let op = PackedOperator::new(patterns.head(m), PatternForm::ZeroOne);
        let mut pg = [vec![0.0; m], vec![0.0; m]];
        for (g, out) in self.g_a.iter().zip(pg.iter_mut()) {
            op.apply(g, out);
        }
        let total = [0, 1].map(|d| self.g_a[d].iter().sum::<f64>());
        let c = [0, 1].map(|d| self.c_traced[d].value);
        let mut out = Vec::with_capacity(if complementary { 2 * m } else { m });
        for (p_plus, p_minus) in pg[0].iter().zip(&pg[1]) {
            out.push([p_plus + c[0], (total[1] - p_minus) + c[1]]);
            if complementary {
                out.push([(total[0] - p_plus) + c[0], p_minus + c[1]]);
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
        [0, 1].map(|d| light[d] + self.ambient_a[d] + self.dark_a[d])
    }
}

/// The photocurrents of a fixed-pattern trace ([`crate::trace::PatternMode::Fixed`]):
/// y± = traced current + ambient + dark (A), with the traced part's standard error.
pub fn fixed_pattern_currents(bench: &Bench, t: &Tallies) -> [Estimate; 2] {
    [0, 1].map(|d| {
        let v: Vec<(u64, f64)> = t.batches.iter().map(|b| (b.rays, b.b[d])).collect();
        let e = total_estimate(&v);
        Estimate {
            value: e.value
                + bench.detectors()[d].ambient_current_a
                + bench.detectors()[d].dark_current_a,
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
