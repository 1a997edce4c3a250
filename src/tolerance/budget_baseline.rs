//! The one-at-a-time budget brought to the target (crate::tolerance::budget, step 7; a sibling
//! of `budget`, declared in `tolerance`).
//!
//! The one-at-a-time inverse limits put every tolerance alone at its limit, so together they
//! usually miss the target, and a budget that misses cannot be compared with one that meets it
//! by looseness alone. What a lens designer does next (OpticStudio's inverse limits, then its
//! Monte Carlo, then tightening until the Monte Carlo passes) is to scale the whole budget down.
//! So when the baseline's confirmation misses Y, the baseline is scaled down uniformly (each
//! scale clamped to its bounds, ÷ [`crate::tolerance::budget::LOOSEN_STEP`] at a time) until the
//! final surface holds it at the rounds' surface target (the pass fraction the bound needs, one
//! binomial standard error, and the surface's bias at the baseline), and confirmed on fresh
//! trials from [`SCALED_BASELINE_INDEX_BASE`]; a confirmation that falls short raises the
//! surface target by its shortfall and the next attempt is scaled further, up to
//! [`SCALED_BASELINE_ATTEMPTS`]. Its geometric-mean scale is the fair baseline for the joint
//! budget's: both meet the target.

use serde::Serialize;

use crate::error::Result;
use crate::scene::budget_costs::ToleranceCost;

use crate::tolerance::budget::{
    BudgetFigures, Confirmation, LOOSEN_STEP, geometric_mean, round_down, total_cost,
};
use crate::tolerance::budget_loosen::scaled_to_target;
use crate::tolerance::budget_search::{Aim, Job, TracedConfirmation, confirm};
use crate::tolerance::budget_surface::{Samples, Surface};

/// The first trial index of the scaled baseline's confirmations (attempt k traces from here +
/// k·n): between the baseline's (2⁴⁰) and the loosening pass's (2⁴⁴) blocks.
pub const SCALED_BASELINE_INDEX_BASE: u64 = 1 << 42;
/// The most confirmations of the scaled baseline.
pub const SCALED_BASELINE_ATTEMPTS: usize = 3;

/// The one-at-a-time budget scaled down to the target.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScaledBaseline {
    /// The uniform factor on the one-at-a-time scales (each then clamped to its bounds).
    pub factor: f64,
    /// Confirmations traced (the last one's is `budget.confirmation`).
    pub attempts: usize,
    /// Whether its last confirmation's lower bound reached Y.
    pub reached: bool,
    pub budget: BudgetFigures,
}

/// What the scaling did.
#[derive(Debug, Clone, PartialEq)]
pub enum Scaled {
    /// Not needed (the baseline met the target, or it was not confirmed), or not possible on
    /// the surface, and why.
    Skipped(String),
    /// A shard traced its part of a confirmation; the other shards' are missing.
    Incomplete,
    Done(ScaledBaseline),
}

/// Traces (or models) the confirmation of budget `scales` at attempt k; `None` when a shard
/// traced only its part.
pub type ConfirmAt<'a> = dyn FnMut(usize, &[f64]) -> Result<Option<Confirmation>> + 'a;

/// The scaled baseline (module docs), with `confirm` tracing (or modelling) the trials of a
/// budget at attempt k.
#[allow(clippy::too_many_arguments)]
pub fn scale_with(
    surface: &Surface,
    samples: &Samples,
    costs: &[ToleranceCost],
    bounds: (&[f64], &[f64]),
    aim: &Aim,
    target_yield: f64,
    (one_at_a_time, baseline): (&[f64], Option<&Confirmation>),
    confirm: &mut ConfirmAt,
) -> Result<Scaled> {
    let Some(base) = baseline else {
        return Ok(Scaled::Skipped("the baseline was not confirmed".into()));
    };
    if base.lower_bound >= target_yield {
        return Ok(Scaled::Skipped(
            "the one-at-a-time budget itself meets the target".into(),
        ));
    }
    let gap = samples.yield_at(surface, one_at_a_time) - base.fraction;
    let mut target = (aim.needed + aim.margin + gap).clamp(0.5, 1.0);
    let mut last: Option<ScaledBaseline> = None;
    for k in 0..SCALED_BASELINE_ATTEMPTS {
        let Some((_, f)) = scaled_to_target(surface, samples, bounds, target, one_at_a_time) else {
            break;
        };
        // The factor to 3 significant digits, rounded down (tighter: the surface still holds
        // it), as the rounds' scales are.
        let mut factor = round_down(f);
        let scaled = |factor: f64| -> Vec<f64> {
            one_at_a_time
                .iter()
                .zip(bounds.0.iter().zip(bounds.1))
                .map(|(v, (l, h))| (v * factor).min(*h).max(*l))
                .collect()
        };
        let mut s = scaled(factor);
        // Each attempt is tighter than the one before, even where the surface is flat.
        if let Some(prev) = &last
            && factor >= prev.factor
        {
            factor = round_down(prev.factor / LOOSEN_STEP);
            s = scaled(factor);
            if last.as_ref().is_some_and(|p| p.budget.scales == s) {
                break;
            }
        }
        let Some(c) = confirm(k, &s)? else {
            return Ok(Scaled::Incomplete);
        };
        let reached = c.lower_bound >= target_yield;
        target = (target + (aim.needed + aim.margin - c.fraction).max(aim.margin)).min(1.0);
        last = Some(ScaledBaseline {
            factor,
            attempts: k + 1,
            reached,
            budget: BudgetFigures {
                total_cost: total_cost(costs, &s),
                geometric_mean_scale: geometric_mean(&s),
                surface_yield: samples.yield_at(surface, &s),
                confirmation: Some(c),
                scales: s,
            },
        });
        if reached {
            break;
        }
    }
    Ok(match last {
        Some(b) => Scaled::Done(b),
        None => Scaled::Skipped(format!(
            "no uniform scaling within the bounds reaches the surface target {target:.4}"
        )),
    })
}

/// The scaled baseline of a search, confirmed by traced trials (with the job's compensators).
#[allow(clippy::too_many_arguments)]
pub fn after_search(
    job: &Job,
    surface: &Surface,
    samples: &Samples,
    costs: &[ToleranceCost],
    bounds: (&[f64], &[f64]),
    aim: &Aim,
    baseline: (&[f64], Option<&Confirmation>),
    traced: &mut Vec<TracedConfirmation>,
) -> Result<Scaled> {
    let n = job.b.trials;
    scale_with(
        surface,
        samples,
        costs,
        bounds,
        aim,
        job.b.target_yield,
        baseline,
        &mut |k, s| {
            (job.progress)(&format!(
                "one at a time, scaled to the target: geometric-mean scale {:.4}, confirming",
                geometric_mean(s)
            ));
            confirm(job, s, SCALED_BASELINE_INDEX_BASE + k as u64 * n, traced)
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::tolerance::Distribution;
    use crate::tolerance::budget::synthetic_confirm;

    /// Four tolerances acting linearly (0.02, 0.04, 0.04, 0.04 per unit of the range) on a
    /// metric limited to ±0.01: alone each reaches the limit at scale 0.5 or 0.25, together at
    /// those scales they miss. Scaled down, the baseline must meet the target on the model's
    /// own confirmations, and each attempt is tighter than the one before.
    #[test]
    fn the_baseline_is_scaled_down_until_its_confirmation_meets_the_target() {
        let (set, surface) = crate::tolerance::budget::linear_model(
            &[
                ("a.despace_mm", Distribution::Uniform),
                ("b.despace_mm", Distribution::Uniform),
                ("c.despace_mm", Distribution::Uniform),
                ("d.despace_mm", Distribution::Uniform),
            ],
            &[0.02, 0.04, 0.04, 0.04],
            0.01,
        );
        let samples = Samples::draw(&set, 3, 4000);
        let n = 300usize;
        let base = [0.5, 0.25, 0.25, 0.25];
        let (lo, hi) = (vec![0.01; 4], vec![1.0; 4]);
        let costs = vec![ToleranceCost::default(); 4];
        let judge = |first: u64, s: &[f64]| synthetic_confirm(&set, &surface, (first, n, 0.95), s);
        let c0 = judge(1 << 40, &base);
        assert!(c0.lower_bound < 0.95, "{c0:?}");
        let needed = crate::tolerance::budget_surface::fraction_needed(0.95, 0.95, n).unwrap();
        let aim = Aim {
            needed,
            margin: (needed * (1.0 - needed) / n as f64).sqrt(),
        };
        let scale = |base_c: &Confirmation, confirm: &mut ConfirmAt| {
            scale_with(
                &surface,
                &samples,
                &costs,
                (&lo, &hi),
                &aim,
                0.95,
                (&base, Some(base_c)),
                confirm,
            )
            .unwrap()
        };
        let mut factors = Vec::new();
        let out = scale(&c0, &mut |k, s| {
            factors.push(s[0] / base[0]);
            Ok(Some(judge(
                SCALED_BASELINE_INDEX_BASE + k as u64 * n as u64,
                s,
            )))
        });
        let Scaled::Done(b) = out else {
            panic!("{out:?}")
        };
        assert!(b.reached, "{b:?}");
        assert!(b.factor < 1.0);
        let c = b.budget.confirmation.as_ref().unwrap();
        assert!(c.lower_bound >= 0.95, "{c:?}");
        assert!(factors.windows(2).all(|w| w[1] < w[0]), "{factors:?}");
        // Every scale is the baseline's times the one factor, of 3 significant digits.
        assert_eq!(b.factor, round_down(b.factor));
        for (s, b0) in b.budget.scales.iter().zip(base) {
            assert!((s / b0 - b.factor).abs() < 1e-12);
        }
        // A baseline that meets the target is not scaled.
        let pass = Confirmation {
            lower_bound: 0.96,
            ..c0.clone()
        };
        let skipped = scale(&pass, &mut |_, _| panic!("nothing to confirm"));
        assert!(matches!(skipped, Scaled::Skipped(_)));
    }
}
