//! The numbers a bench is judged by, each with its Monte Carlo standard error, in a form that
//! also gives the standard error of the *difference* between two benches traced with common
//! random numbers.
//!
//! Every metric here is a smooth function of batch totals (a total, or a ratio of totals). Its
//! batch-means standard error is that of its linearisation: the metric's *influence* ψ_b of
//! batch b (for a total S = Σ s_b over batches of n_b of the N rays, ψ_b = s_b − (n_b/N)·S; for
//! a ratio R = ΣA_b/ΣD_b, ψ_b = (A_b − R·D_b)/ΣD_b, the delta method), and
//! SE² = n_B/(n_B − 1)·Σ_b ψ_b². These are exactly the formulas of
//! [`crate::transport::total_estimate`] and [`crate::transport::ratio_estimate`].
//!
//! Two benches traced with the same seed draw the same random numbers batch by batch (common
//! random numbers: crate::trace keys batch b's stream by (seed, b)), so their batch estimates
//! are strongly correlated when the benches differ a little. The difference of a metric between
//! them is then resolved by the paired batch differences:
//! SE²(M_a − M_b) = n_B/(n_B − 1)·Σ_b (ψ_{a,b} − ψ_{b,b})², far below SE_a² + SE_b² (Glasserman,
//! *Monte Carlo Methods in Financial Engineering*, 2003, §4.1: common random numbers).

use std::ops::Index;

use serde::Serialize;

use crate::optics::Arm;
use crate::optics::dmd::{MirrorState, state_index};
pub use crate::quantities::{BENCH_METRICS, BenchMetric};
use crate::trace::Tallies;
use crate::transport::{Estimate, Transport};

/// A traced number (a bench metric, a CMRR) with its per-batch influence (see the module notes).
#[derive(Debug, Clone, PartialEq)]
pub struct TracedValue {
    pub value: f64,
    psi: Vec<f64>,
}

impl TracedValue {
    /// An exact number (no Monte Carlo error), e.g. an electronics setting.
    pub fn exact(value: f64, batches: usize) -> TracedValue {
        TracedValue {
            value,
            psi: vec![0.0; batches],
        }
    }

    /// The total Σ_b s_b of per-batch sums `s` over batches of `n` rays.
    pub fn total(n: &[u64], s: &[f64]) -> TracedValue {
        let big_n: u64 = n.iter().sum();
        let total: f64 = s.iter().sum();
        let psi = n
            .iter()
            .zip(s)
            .map(|(&k, &v)| v - (k as f64 / big_n.max(1) as f64) * total)
            .collect();
        TracedValue { value: total, psi }
    }

    /// The ratio ΣA_b / ΣD_b.
    pub fn ratio(a: &[f64], d: &[f64]) -> TracedValue {
        let sa: f64 = a.iter().sum();
        let sd: f64 = d.iter().sum();
        let r = sa / sd;
        let psi = a.iter().zip(d).map(|(x, y)| (x - r * y) / sd).collect();
        TracedValue { value: r, psi }
    }

    /// f(self) by the delta method: value f(v), influence f'(v)·ψ, so standard errors and
    /// paired differences carry over to any smooth function of a metric.
    pub fn map(&self, f: impl Fn(f64) -> f64, df: impl Fn(f64) -> f64) -> TracedValue {
        let slope = df(self.value);
        TracedValue {
            value: f(self.value),
            psi: self.psi.iter().map(|p| slope * p).collect(),
        }
    }

    /// c·self for an exact factor c (an attenuator's transmission): value and influence scale
    /// alike.
    pub fn scaled(&self, c: f64) -> TracedValue {
        TracedValue {
            value: c * self.value,
            psi: self.psi.iter().map(|p| c * p).collect(),
        }
    }

    /// f(a, b) of two metrics of one trace by the delta method: value `f`, influence
    /// ∂f/∂a·ψ_a + ∂f/∂b·ψ_b (`dfa`, `dfb` at the traced values), batch by batch. A linear
    /// combination (such as k′ = k₊ + k₋) is exact; a ratio is linearised as
    /// [`TracedValue::ratio`] is, so a function of k± gives the imbalance's own influence.
    pub fn map2(a: &TracedValue, b: &TracedValue, f: f64, dfa: f64, dfb: f64) -> TracedValue {
        TracedValue {
            value: f,
            psi: a
                .psi
                .iter()
                .zip(&b.psi)
                .map(|(x, y)| dfa * x + dfb * y)
                .collect(),
        }
    }

    /// This metric plus a constant.
    pub fn plus(mut self, c: f64) -> TracedValue {
        self.value += c;
        self
    }

    /// The batch-means standard error (NaN with fewer than two batches).
    pub fn stderr(&self) -> f64 {
        se(self.psi.iter().copied())
    }

    pub fn estimate(&self) -> Estimate {
        Estimate {
            value: self.value,
            stderr: self.stderr(),
        }
    }

    /// `self − other` with the paired (common-random-numbers) standard error. NaN when the two
    /// were not traced with the same batches.
    pub fn diff(&self, other: &TracedValue) -> Estimate {
        let stderr = if self.psi.len() == other.psi.len() {
            se(self.psi.iter().zip(&other.psi).map(|(a, b)| a - b))
        } else {
            f64::NAN
        };
        Estimate {
            value: self.value - other.value,
            stderr,
        }
    }
}

fn se(psi: impl ExactSizeIterator<Item = f64>) -> f64 {
    let nb = psi.len();
    if nb < 2 {
        return f64::NAN;
    }
    let q: f64 = psi.map(|p| p * p).sum();
    (q * nb as f64 / (nb as f64 - 1.0)).sqrt()
}

/// The bench's common-mode rejection (dB) from the traced imbalance ι = (k₊ − k₋)/(k₊ + k₋)
/// and the diodes' responsivity scales s± (the electronics): the RF output's response to light
/// sent into one arm divided by its response to the same light sent into each arm, the
/// Thorlabs definition of a balanced detector's CMRR (docs/bench-facts.md §1.2) with the arms'
/// gains k± in front of the diodes.
///
/// Light W per arm gives the currents s₊k₊W and s₋k₋W; the RF output amplifies their
/// difference. With a = s₊k₊, b = s₋k₋, CMRR = 20·log₁₀(½(a + b)/|a − b|) =
/// −20·log₁₀(2|ι'|), ι' = (a − b)/(a + b): the effective imbalance, which is ι for matched
/// diodes and (s₊ − s₋)/(s₊ + s₋) for matched arms (then this is
/// [`crate::detector::Bap::cmrr_db`], the electronics alone). With r = s₊/s₋,
/// ι' = (r(1 + ι) − (1 − ι))/(r(1 + ι) + (1 − ι)) and dι'/dι = 4r/(r(1 + ι) + (1 − ι))², so
/// the standard errors follow from ι's by the delta method ([`TracedValue::map`]). +∞ (with a NaN
/// standard error) where ι' = 0.
pub fn cmrr_db(imbalance: &TracedValue, responsivity_scale: [f64; 2]) -> TracedValue {
    electrical_imbalance(imbalance, responsivity_scale).map(
        |e| -20.0 * (2.0 * e.abs()).log10(),
        |e| -20.0 / std::f64::consts::LN_10 / e,
    )
}

/// The electrical imbalance ι' = (s₊k₊ − s₋k₋)/(s₊k₊ + s₋k₋): the optical imbalance ι =
/// (k₊ − k₋)/(k₊ + k₋) as the balanced detector's difference output sees it, through the
/// diodes' responsivity factors s± (their mismatch). With r = s₊/s₋,
/// ι' = (r(1 + ι) − (1 − ι))/(r(1 + ι) + (1 − ι)), which is ι for matched diodes (r = 1) and
/// (s₊ − s₋)/(s₊ + s₋) for matched arms (ι = 0); dι'/dι = 4r/(r(1 + ι) + (1 − ι))², so the
/// standard error follows from ι's by the delta method. (The RF output's gain multiplies
/// both arms' currents alike and leaves ι' as it is.)
pub fn electrical_imbalance(imbalance: &TracedValue, responsivity_scale: [f64; 2]) -> TracedValue {
    let r = responsivity_scale[0] / responsivity_scale[1];
    imbalance.map(
        move |i| (r * (1.0 + i) - (1.0 - i)) / (r * (1.0 + i) + (1.0 - i)),
        move |i| {
            let denom = r * (1.0 + i) + (1.0 - i);
            4.0 * r / (denom * denom)
        },
    )
}

/// The traced metrics of one bench, indexed by [`BenchMetric`].
#[derive(Debug, Clone, PartialEq)]
pub struct BenchMetrics {
    pub values: [TracedValue; BENCH_METRICS],
}

impl BenchMetrics {
    /// From a trace's batches and its transport (for the ambient and dark currents).
    pub fn new(t: &Tallies, transport: &Transport) -> BenchMetrics {
        let bs = &t.batches;
        let col = |f: &dyn Fn(&crate::trace::BatchScalars) -> f64| -> Vec<f64> {
            bs.iter().map(f).collect()
        };
        let n: Vec<u64> = bs.iter().map(|b| b.rays).collect();
        let x = col(&|b| b.x);
        let (plus, minus) = (Arm::Plus, Arm::Minus);
        let g = Arm::ALL.map(|arm| col(&|b| b.g[arm]));
        let gsum: Vec<f64> = g[plus].iter().zip(&g[minus]).map(|(a, b)| a + b).collect();
        let gdiff: Vec<f64> = g[plus].iter().zip(&g[minus]).map(|(a, b)| a - b).collect();
        let constant = |arm: Arm| transport.ambient_a[arm] + transport.dark_a[arm];
        let b = Arm::ALL.map(|arm| TracedValue::total(&n, &col(&|s| s.c[arm])).plus(constant(arm)));
        // detected_w[world][diode]: world 0 = every unit in state +, 1 = every unit in state −.
        let det = |w: MirrorState, d: Arm| col(&|s| s.detected_w[state_index(w)][d]);
        let (all_plus, all_minus) = (MirrorState::Plus, MirrorState::Minus);
        let values = BenchMetric::ALL.map(|m| match m {
            BenchMetric::KPlus => TracedValue::ratio(&g[plus], &x),
            BenchMetric::KMinus => TracedValue::ratio(&g[minus], &x),
            BenchMetric::KPrime => TracedValue::ratio(&gsum, &x),
            BenchMetric::Imbalance => TracedValue::ratio(&gdiff, &gsum),
            BenchMetric::BPlus => b[plus].clone(),
            BenchMetric::BMinus => b[minus].clone(),
            BenchMetric::BMinusMinusBPlus => {
                TracedValue::total(&n, &col(&|s| s.c[minus] - s.c[plus]))
                    .plus(constant(minus) - constant(plus))
            }
            BenchMetric::PowerPlusW => TracedValue::total(&n, &det(all_plus, plus)),
            BenchMetric::PowerMinusW => TracedValue::total(&n, &det(all_minus, minus)),
            BenchMetric::LeakPlus => {
                TracedValue::ratio(&det(all_plus, minus), &det(all_plus, plus))
            }
            BenchMetric::LeakMinus => {
                TracedValue::ratio(&det(all_minus, plus), &det(all_minus, minus))
            }
            BenchMetric::XTotalW => TracedValue::total(&n, &x),
        });
        BenchMetrics { values }
    }

    /// Every metric with its value, in table order.
    pub fn iter(&self) -> impl Iterator<Item = (BenchMetric, &TracedValue)> {
        BenchMetric::ALL.into_iter().zip(&self.values)
    }
}

impl Index<BenchMetric> for BenchMetrics {
    type Output = TracedValue;
    #[inline]
    fn index(&self, m: BenchMetric) -> &TracedValue {
        &self.values[m]
    }
}

/// One metric in a summary row: value, standard error and, against a reference bench traced
/// with the same random numbers, the difference with its paired standard error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MetricRow {
    pub value: f64,
    pub stderr: f64,
    pub diff: f64,
    pub diff_stderr: f64,
}

impl MetricRow {
    pub fn new(m: &TracedValue, reference: &TracedValue) -> MetricRow {
        let d = m.diff(reference);
        MetricRow {
            value: m.value,
            stderr: m.stderr(),
            diff: d.value,
            diff_stderr: d.stderr,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::{ratio_estimate, total_estimate};

    #[test]
    fn influence_errors_equal_the_batch_means_formulas() {
        let n = [10u64, 10, 12, 8];
        let s = [1.0, 2.5, 3.0, 1.5];
        let t = TracedValue::total(&n, &s);
        let e = total_estimate(&n.iter().copied().zip(s).collect::<Vec<_>>());
        assert_eq!(t.value, e.value);
        assert!((t.stderr() - e.stderr).abs() < 1e-14);
        let a = [2.0, 4.1, 0.9, 3.3];
        let r = TracedValue::ratio(&a, &s);
        let e = ratio_estimate(&a.iter().copied().zip(s).collect::<Vec<_>>());
        assert_eq!(r.value, e.value);
        assert!((r.stderr() - e.stderr).abs() < 1e-14);
    }

    #[test]
    fn cmrr_includes_the_arms_and_reduces_to_the_electronics() {
        let n = [10u64; 4];
        let (a, d) = ([1.0, 1.1, 0.9, 1.0], [1.05, 1.0, 1.1, 0.95]);
        // Matched arms: the electronics' CMRR, 20·log₁₀(s̄/|s₊ − s₋|).
        let zero = TracedValue::total(&n, &[0.0; 4]);
        let bap_like = 20.0 * (0.5 * (1.0 + 0.97) / 0.03f64).log10();
        assert!((cmrr_db(&zero, [1.0, 0.97]).value - bap_like).abs() < 1e-9);
        // An arm that is blind (ι → 1) leaves no rejection: about −6 dB, whatever the diodes.
        let blind = TracedValue::ratio(&[0.9996; 4], &[1.0; 4]);
        assert!((cmrr_db(&blind, [1.0, 1.0]).value + 6.02).abs() < 0.01);
        // The delta-method slope matches a finite difference.
        let i = TracedValue::ratio(&a, &d);
        let c = cmrr_db(&i, [1.0, 0.98]);
        let h = 1e-7;
        let shifted = TracedValue::exact(i.value + h, 4);
        let fd = (cmrr_db(&shifted, [1.0, 0.98]).value - c.value) / h;
        assert!(
            (c.stderr() - fd.abs() * i.stderr()).abs() < 1e-5 * c.stderr(),
            "{fd}"
        );
    }

    /// The electrical imbalance is the optical one with matched diodes and moves by the
    /// responsivity mismatch otherwise, in closed form: with ι = 0.01 and s = (1.02, 0.98),
    /// r = 1.02/0.98 and ι' = (r·1.01 − 0.99)/(r·1.01 + 0.99) = 0.029988…; with matched arms,
    /// ι' = (s₊ − s₋)/(s₊ + s₋) = 0.02.
    #[test]
    fn electrical_imbalance_moves_by_the_responsivity_mismatch() {
        let i = TracedValue::ratio(&[1.01, 1.02, 1.0, 1.01], &[101.0, 101.0, 101.0, 101.0]);
        let matched = electrical_imbalance(&i, [1.0, 1.0]);
        assert!((matched.value - i.value).abs() < 1e-15);
        assert!((matched.stderr() - i.stderr()).abs() < 1e-15);
        let optical = TracedValue::exact(0.01, 4);
        let e = electrical_imbalance(&optical, [1.02, 0.98]).value;
        let r = 1.02 / 0.98;
        let closed = (r * 1.01 - 0.99) / (r * 1.01 + 0.99);
        assert!((e - closed).abs() < 1e-15, "{e} vs {closed}");
        // To first order ι' ≈ ι + (s₊ − s₋)/(s₊ + s₋) = 0.03.
        assert!((e - 0.03).abs() < 1e-3, "{e}");
        let zero = TracedValue::exact(0.0, 4);
        assert!((electrical_imbalance(&zero, [1.02, 0.98]).value - 0.02).abs() < 1e-15);
        // A mismatch can cancel the arms' imbalance: s₊/s₋ = (1 − ι)/(1 + ι) gives ι' = 0.
        let cancel = electrical_imbalance(&optical, [0.99, 1.01]).value;
        assert!(cancel.abs() < 1e-15, "{cancel}");
    }

    #[test]
    fn paired_difference_cancels_common_noise() {
        // Two "benches" whose batch sums share the same noise: the difference is exact.
        let n = [10u64; 5];
        let s = [1.0, 1.3, 0.8, 1.1, 0.9];
        let s2: Vec<f64> = s.iter().map(|v| v * 1.01).collect();
        let a = TracedValue::total(&n, &s);
        let b = TracedValue::total(&n, &s2);
        let d = b.diff(&a);
        assert!((d.value - 0.01 * a.value).abs() < 1e-12);
        assert!(
            d.stderr < 0.02 * a.stderr(),
            "{} vs {}",
            d.stderr,
            a.stderr()
        );
        // Different batch structures cannot be paired.
        assert!(
            TracedValue::total(&n[..4], &s[..4])
                .diff(&a)
                .stderr
                .is_nan()
        );
    }
}
