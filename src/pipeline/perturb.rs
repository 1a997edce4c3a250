//! Benches drawn from a tolerance file: trial i's deviations from the stream keyed by
//! (seed, i), applied to the nominal bench, with the file's compensators adjusted by the
//! optimiser ([`crate::pipeline::optimise`]). The `tolerance` job traces such benches for its
//! Monte Carlo; the `dataset` job measures objects through them. Trials are independent of each
//! other: any subset (a shard) draws the same benches as the full run.
//!
//! A variable attenuator ([`Attenuator`]) is the one compensator that is not a bench variable:
//! it scales the light reaching one diode, so it is set in closed form from the trial's traced
//! imbalance ([`attenuator_transmissions`]) and applied to that trace's metrics
//! ([`attenuated`]) without a trace of its own.

use crate::error::Result;
use crate::pipeline::evaluate::{EvaluateOptions, Evaluation};
use crate::pipeline::optimise::{AlignOptions, Free, Objective, search, settings as free_settings};
use crate::rng;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{
    Attenuator, AttenuatorArm, CompensatorObjective, Distribution, ToleranceSet,
};
use crate::transport::metrics::TracedValue;

/// A salt that separates the tolerance draws' streams from the rays' streams of the same seed.
const DRAW_SALT: u64 = 0x70_1e_7a_4c_e5_d7_a3_11;

/// The settings (absolute values of each variable) for deviations from the nominal bench. A
/// zero deviation sets nothing: a rigid-body move by 0 would still rewrite the part's axis as
/// a vector, which need not be bit-identical to the file's form.
pub fn settings(set: &ToleranceSet, deviations: &[(String, f64)]) -> Vec<(String, f64)> {
    set.tolerances
        .iter()
        .zip(deviations)
        .filter(|(_, (_, d))| *d != 0.0)
        .map(|(t, (_, d))| (t.path.clone(), t.nominal + d))
        .collect()
}

/// Trial i's deviations, drawn from the stream keyed by (seed, i).
pub fn draw(set: &ToleranceSet, seed: u64, i: u64) -> Vec<(String, f64)> {
    let mut r = rng::stream(rng::mix64(seed ^ DRAW_SALT), i);
    set.tolerances
        .iter()
        .map(|t| {
            let (lo, hi) = (t.min, t.max);
            let mid = 0.5 * (lo + hi);
            let half = 0.5 * (hi - lo);
            let v = match t.distribution {
                Distribution::Uniform => lo + rng::uniform(&mut r) * (hi - lo),
                Distribution::Normal { sigmas } => mid + half / sigmas * rng::normal(&mut r),
                Distribution::TruncatedNormal { sigmas } => {
                    // Rejection: with the range at ±kσ, k ≥ 0.1, fewer than 13 draws on average.
                    let mut v = mid;
                    for _ in 0..10_000 {
                        let z = rng::normal(&mut r);
                        if z.abs() <= sigmas {
                            v = mid + half / sigmas * z;
                            break;
                        }
                    }
                    v
                }
            };
            // A zero range draws exactly zero, so that zero tolerances give the nominal bench.
            (t.path.clone(), if half == 0.0 { lo } else { v })
        })
        .collect()
}

/// The alignment options of the compensators: a quarter of the trial's rays at most, starting
/// at a sixteenth.
fn compensator_options(o: &EvaluateOptions) -> AlignOptions {
    AlignOptions {
        start_rays: o.rays / 16,
        max_rays: (o.rays / 4).max(2 * crate::trace::RAYS_PER_BATCH),
        seed: o.seed,
        max_evaluations: 60,
    }
}

/// A trial's bench, its tolerances' deviations and its compensators' deviations.
pub type TrialBench = (BenchDoc, Vec<(String, f64)>, Vec<(String, f64)>);

/// The perturbed bench of trial i, with its compensators applied, and the compensators'
/// deviations.
pub fn trial_doc(
    doc: &BenchDoc,
    set: &ToleranceSet,
    o: &EvaluateOptions,
    i: u64,
) -> Result<TrialBench> {
    let deviations = draw(set, o.seed, i);
    let mut d = doc.with(&settings(set, &deviations))?;
    let mut comp = Vec::new();
    // Compensators that share an objective are adjusted together, in file order of their
    // objectives.
    for objective in [CompensatorObjective::Balance, CompensatorObjective::Power] {
        let group: Vec<_> = set
            .compensators
            .iter()
            .filter(|c| c.objective == objective)
            .collect();
        if group.is_empty() {
            continue;
        }
        let free: Vec<Free> = group
            .iter()
            .map(|c| {
                let v = d.get(&c.path)?;
                Ok(Free {
                    path: c.path.clone(),
                    lo: v + c.min,
                    hi: v + c.max,
                })
            })
            .collect::<Result<_>>()?;
        let base: Vec<f64> = group
            .iter()
            .map(|c| d.get(&c.path))
            .collect::<Result<_>>()?;
        let obj = match objective {
            CompensatorObjective::Balance => Objective::BALANCE,
            CompensatorObjective::Power => Objective::Power,
        };
        // The search alone: its best values are what the trial needs (the `align` job's final
        // traces of the start and the result would be thrown away).
        let a = search(&d, &free, &obj, &compensator_options(o), &|_| {})?;
        for ((c, b), v) in group.iter().zip(&base).zip(&a.best_values) {
            comp.push((c.path.clone(), v - b));
        }
        d = d.with(&free_settings(&free, &a.best_values))?;
    }
    Ok((d, deviations, comp))
}

/// The transmissions [T₊, T₋] a variable attenuator ([`Attenuator`]) is set to on a bench whose
/// electrical imbalance is `imbalance` (ι′ = (a − b)/(a + b), a = s₊k₊ and b = s₋k₋ the arms'
/// photocurrents per unit of light): the stronger arm's current is brought down to the
/// weaker's, T = b/a (or a/b), which nulls ι′, and where that would take T below
/// `min_transmission` the attenuator stops there. An attenuator in one named arm does nothing
/// when that arm is the weaker (it cannot add light). A ι′ that is not a number, or at ±1 (one
/// arm dark), leaves both at 1.
pub fn attenuator_transmissions(imbalance: f64, a: &Attenuator) -> [f64; 2] {
    if !(imbalance.is_finite() && imbalance.abs() < 1.0) || imbalance == 0.0 {
        return [1.0; 2];
    }
    let plus_stronger = imbalance > 0.0;
    let acts = match a.arm {
        AttenuatorArm::Stronger => true,
        AttenuatorArm::Plus => plus_stronger,
        AttenuatorArm::Minus => !plus_stronger,
    };
    if !acts {
        return [1.0; 2];
    }
    // weaker / stronger = (1 − |ι′|)/(1 + |ι′|).
    let i = imbalance.abs();
    let t = ((1.0 - i) / (1.0 + i)).max(a.min_transmission);
    if plus_stronger { [t, 1.0] } else { [1.0, t] }
}

/// The electrical imbalance after the transmissions `t` = [T₊, T₋]:
/// (T₊(1 + ι′) − T₋(1 − ι′))/(T₊(1 + ι′) + T₋(1 − ι′)); 0 where the attenuator could reach the
/// balance, else the residual at its darkest setting (smaller than |ι′|).
pub fn attenuated_imbalance(imbalance: f64, t: [f64; 2]) -> f64 {
    let (a, b) = (t[0] * (1.0 + imbalance), t[1] * (1.0 - imbalance));
    if t == [1.0; 2] {
        return imbalance;
    }
    (a - b) / (a + b)
}

/// Bench `e` (traced from `doc`) with the transmissions `t` = [T₊, T₋] in front of its
/// diodes: every metric as the same trace gives it with all light reaching diode ± scaled by
/// T± — k±, k′, the imbalance, the detected powers, the cross-talk ratios, and the offsets b±
/// less the diodes' dark currents (the filter covers the diode, so the ambient light on it is
/// attenuated too; the dark current is not light) — each with its Monte Carlo influence
/// carried through ([`TracedValue::scaled`], [`TracedValue::map2`]), and the bench's CMRR
/// from the new imbalance. The light at the pattern (x) and the arrivals do not change. With
/// t = [1, 1], `e` itself, bit for bit.
pub fn attenuated(doc: &BenchDoc, e: &Evaluation, t: [f64; 2]) -> Evaluation {
    if t == [1.0; 2] {
        return e.clone();
    }
    use crate::quantities::BenchMetric as M;
    let dark = [
        doc.file.detectors.plus.dark_current_a.0,
        doc.file.detectors.minus.dark_current_a.0,
    ];
    let m = &e.metrics;
    let mut out = e.metrics.clone();
    let [tp, tm] = t;
    out.values[M::KPlus] = m[M::KPlus].scaled(tp);
    out.values[M::KMinus] = m[M::KMinus].scaled(tm);
    let (kp, km) = (&m[M::KPlus], &m[M::KMinus]);
    out.values[M::KPrime] = TracedValue::map2(kp, km, tp * kp.value + tm * km.value, tp, tm);
    // ι = (u − v)/(u + v), u = T₊k₊, v = T₋k₋: ∂ι/∂k₊ = 2T₊v/(u + v)², ∂ι/∂k₋ = −2T₋u/(u + v)².
    let (u, v) = (tp * kp.value, tm * km.value);
    let d2 = (u + v) * (u + v);
    out.values[M::Imbalance] = TracedValue::map2(
        kp,
        km,
        (u - v) / (u + v),
        2.0 * tp * v / d2,
        -2.0 * tm * u / d2,
    );
    out.values[M::BPlus] = m[M::BPlus].scaled(tp).plus((1.0 - tp) * dark[0]);
    out.values[M::BMinus] = m[M::BMinus].scaled(tm).plus((1.0 - tm) * dark[1]);
    let (bp, bm) = (&m[M::BPlus], &m[M::BMinus]);
    out.values[M::BMinusMinusBPlus] = TracedValue::map2(
        bm,
        bp,
        tm * bm.value + (1.0 - tm) * dark[1] - tp * bp.value - (1.0 - tp) * dark[0],
        tm,
        -tp,
    );
    out.values[M::PowerPlusW] = m[M::PowerPlusW].scaled(tp);
    out.values[M::PowerMinusW] = m[M::PowerMinusW].scaled(tm);
    // Light of state + that reaches diode −, over what reaches diode +; and the reverse.
    out.values[M::LeakPlus] = m[M::LeakPlus].scaled(tm / tp);
    out.values[M::LeakMinus] = m[M::LeakMinus].scaled(tp / tm);
    let cmrr = e
        .responsivity_scale
        .map(|s| crate::transport::metrics::cmrr_db(&out[M::Imbalance], s));
    Evaluation {
        metrics: out,
        cmrr,
        ..e.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn att(arm: AttenuatorArm, min_transmission: f64) -> Attenuator {
        Attenuator {
            arm,
            min_transmission,
        }
    }

    /// Within its range the attenuator nulls ι′ on either side (in the stronger arm); beyond it
    /// it stops at its darkest setting and leaves the residual of that setting,
    /// (T(1 + ι′) − (1 − ι′))/(T(1 + ι′) + (1 − ι′)) for a stronger + arm.
    #[test]
    fn the_attenuator_nulls_the_imbalance_within_its_range_and_leaves_the_bound_beyond() {
        let a = att(AttenuatorArm::Stronger, 0.5);
        // (1 − 1/3)/(1 + 1/3) = 0.5: the widest ι′ it balances.
        for i in [-0.333, -0.2, -0.01, 1e-9, 0.05, 0.2, 0.333] {
            let t = attenuator_transmissions(i, &a);
            assert!(t.iter().all(|x| (0.5..=1.0).contains(x)), "{i}: {t:?}");
            assert_eq!(t.iter().filter(|x| **x < 1.0).count(), 1, "{i}: {t:?}");
            assert!(attenuated_imbalance(i, t).abs() < 1e-15, "{i}: {t:?}");
        }
        assert_eq!(attenuator_transmissions(0.2, &a)[1], 1.0);
        assert_eq!(attenuator_transmissions(-0.2, &a)[0], 1.0);
        for i in [0.5f64, -0.5, 0.9] {
            let t = attenuator_transmissions(i, &a);
            assert_eq!(t.iter().copied().fold(1.0, f64::min), 0.5, "{i}");
            let bound = (0.5 * (1.0 + i.abs()) - (1.0 - i.abs()))
                / (0.5 * (1.0 + i.abs()) + (1.0 - i.abs()));
            let after = attenuated_imbalance(i, t);
            assert!(
                (after.abs() - bound).abs() < 1e-15 && after.signum() == i.signum(),
                "{i}"
            );
            assert!(after.abs() < i.abs());
        }
        // 0.5 at ι′ = 0.5: (0.75 − 0.5)/(0.75 + 0.5) = 0.2.
        assert!((attenuated_imbalance(0.5, attenuator_transmissions(0.5, &a)) - 0.2).abs() < 1e-15);
        // Balanced, not a number, or one arm dark: nothing to do.
        for i in [0.0, f64::NAN, 1.0, -1.0] {
            assert_eq!(attenuator_transmissions(i, &a), [1.0; 2], "{i}");
        }
    }

    /// An attenuator in one named arm acts only when that arm is the stronger: it cannot add
    /// light to the weaker one.
    #[test]
    fn an_attenuator_in_one_arm_cannot_help_the_other() {
        let plus = att(AttenuatorArm::Plus, 0.2);
        let minus = att(AttenuatorArm::Minus, 0.2);
        assert_eq!(attenuator_transmissions(-0.1, &plus), [1.0; 2]);
        assert_eq!(attenuated_imbalance(-0.1, [1.0; 2]), -0.1);
        assert_eq!(attenuator_transmissions(0.1, &minus), [1.0; 2]);
        let t = attenuator_transmissions(0.1, &plus);
        assert!((t[0] - 0.9 / 1.1).abs() < 1e-15 && t[1] == 1.0);
        let t = attenuator_transmissions(-0.1, &minus);
        assert!(t[0] == 1.0 && (t[1] - 0.9 / 1.1).abs() < 1e-15);
    }
}
