//! The loosening pass after the rounds of a tolerance budget (crate::tolerance::budget, step 6; a
//! sibling of `budget`, declared in `tolerance`).
//!
//! The rounds' allocation ([`crate::tolerance::budget::allocate`]) minimises the total cost on the surface,
//! and the joint budget is the cheapest round that passed. Cost and looseness are not the same
//! measure: with per-tolerance weights (by default 1/sᵢ, so the tightest tolerance is by far the
//! dearest) the cheapest budget can be tighter, by its geometric-mean scale, than the
//! one-at-a-time inverse limits. The one-at-a-time budget, though, puts each tolerance alone at
//! its limit, so the limits add up and its yield falls short; scaled down uniformly it is
//! over-tight everywhere. This pass starts from each of two budgets the surface holds feasible:
//!
//! - (a) the cheapest passing round's, and
//! - (b) the one-at-a-time budget scaled down uniformly (÷ [`LOOSEN_STEP`] at a time) until the
//!   surface yield reaches the pass's target,
//!
//! and loosens each greedily: of the tolerances whose step (× [`LOOSEN_STEP`]) keeps the surface
//! yield at the target, the one saving the most cost per step, one at a time, until none can
//! move (marginal analysis in the loosening direction, as in Chase and Parkinson 1991). The
//! result with the larger geometric-mean scale (on a tie the cheaper) is confirmed by traced
//! trials from [`LOOSEN_INDEX_BASE`], a block no round, the baseline or the surface draws use,
//! so its bound is from fresh trials; it becomes the joint budget only if that one-sided lower
//! bound reaches Y. Otherwise, or when its geometric-mean scale is no larger than the cheapest
//! passing round's (then it is not traced), the joint budget stays the rounds' choice.
//!
//! The pass's surface target is the rounds': the pass fraction the bound needs, plus one
//! binomial standard error, plus the final surface's bias (its yield less the confirmed
//! fraction) at the budget the pass tries to beat, the cheapest passing round (else the last
//! confirmation).

use crate::error::Result;
use crate::scene::budget_costs::ToleranceCost;

use crate::tolerance::budget::{
    Confirmation, LOOSEN_STEP, Round, geometric_mean, round_down, total_cost,
};
use crate::tolerance::budget_search::{
    Aim, Job, Rounds, TracedConfirmation, cheapest_pass, confirm,
};
use crate::tolerance::budget_surface::{Samples, Surface};

/// The first trial index of the loosening pass's confirmation: above every round's (round r
/// traces r·n …, at most 50 rounds of at most 10⁶ trials) and the baseline's (2⁴⁰ …), below the
/// surface draws' (2⁴⁸ …).
pub const LOOSEN_INDEX_BASE: u64 = 1 << 44;

/// Which start a loosened budget came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// The cheapest passing round's budget.
    CheapestPass,
    /// The one-at-a-time budget, scaled down uniformly to surface feasibility.
    OneAtATime,
}

impl Start {
    fn describe(self) -> &'static str {
        match self {
            Start::CheapestPass => "the cheapest passing round",
            Start::OneAtATime => "the one-at-a-time budget scaled down",
        }
    }
}

/// A loosened budget, before its confirmation.
#[derive(Debug, Clone, PartialEq)]
pub struct Proposal {
    pub scales: Vec<f64>,
    pub surface_yield: f64,
    pub start: Start,
    /// The uniform factor the start was scaled down by to reach the target (1: none).
    pub scaled_by: f64,
}

/// `start` (clamped to `lo … hi`) scaled down uniformly, ÷ [`LOOSEN_STEP`] at a time, until its
/// surface yield reaches `target`, with the factor; `None` when it does not before every scale
/// sits at its lower bound.
pub fn scaled_to_target(
    surface: &Surface,
    samples: &Samples,
    (lo, hi): (&[f64], &[f64]),
    target: f64,
    start: &[f64],
) -> Option<(Vec<f64>, f64)> {
    let mut factor = 1.0;
    loop {
        let s: Vec<f64> = start
            .iter()
            .zip(lo.iter().zip(hi))
            .map(|(v, (l, h))| (v * factor).min(*h).max(*l))
            .collect();
        if samples.yield_at(surface, &s) >= target {
            return Some((s, factor));
        }
        if s.iter().zip(lo).all(|(v, l)| v <= l) {
            return None;
        }
        factor /= LOOSEN_STEP;
    }
}

/// Loosens `start` one tolerance at a time: of those below their upper bound whose step
/// (× [`LOOSEN_STEP`], capped at the bound) keeps the surface yield at `target`, the one whose
/// step saves the most cost (the first on ties), until none can move; then every scale rounded
/// down to 3 significant digits (within its lower bound), as the rounds' budgets are.
pub fn loosen(
    surface: &Surface,
    samples: &Samples,
    costs: &[ToleranceCost],
    (lo, hi): (&[f64], &[f64]),
    target: f64,
    start: &[f64],
) -> Vec<f64> {
    let n = start.len();
    let mut s = start.to_vec();
    let step = |s: &[f64], i: usize| (s[i] * LOOSEN_STEP).min(hi[i]);
    // Each step moves one scale 5 % towards its bound (0.01 to 1 takes 95 steps), so the cap
    // is never reached with any bounds a costs file gives; it only guards the loop.
    for _ in 0..100_000 {
        let mut order: Vec<usize> = (0..n).filter(|i| s[*i] < hi[*i]).collect();
        let saving = |i: usize| costs[i].cost(s[i]) - costs[i].cost(step(&s, i));
        order.sort_by(|a, b| saving(*b).total_cmp(&saving(*a)));
        let moved = order.into_iter().find_map(|i| {
            let mut t = s.clone();
            t[i] = step(&s, i);
            (samples.yield_at(surface, &t) >= target).then_some(t)
        });
        match moved {
            Some(t) => s = t,
            None => break,
        }
    }
    for (v, l) in s.iter_mut().zip(lo) {
        *v = round_down(*v).max(*l);
    }
    s
}

/// The pass's budget (module docs): both starts made feasible and loosened, the larger
/// geometric-mean scale kept (on a tie the cheaper, then the cheapest pass's); `None` when no
/// start reaches the target.
pub fn propose(
    surface: &Surface,
    samples: &Samples,
    costs: &[ToleranceCost],
    bounds: (&[f64], &[f64]),
    target: f64,
    (cheapest, one_at_a_time): (Option<&[f64]>, &[f64]),
) -> Option<Proposal> {
    let starts = cheapest
        .map(|c| (Start::CheapestPass, c))
        .into_iter()
        .chain([(Start::OneAtATime, one_at_a_time)]);
    let mut best: Option<Proposal> = None;
    for (start, scales) in starts {
        let Some((feasible, scaled_by)) =
            scaled_to_target(surface, samples, bounds, target, scales)
        else {
            continue;
        };
        let s = loosen(surface, samples, costs, bounds, target, &feasible);
        let p = Proposal {
            surface_yield: samples.yield_at(surface, &s),
            scales: s,
            start,
            scaled_by,
        };
        let better = best.as_ref().is_none_or(|b| {
            let (g, gb) = (geometric_mean(&p.scales), geometric_mean(&b.scales));
            g > gb || (g == gb && total_cost(costs, &p.scales) < total_cost(costs, &b.scales))
        });
        if better {
            best = Some(p);
        }
    }
    best
}

/// What the pass did.
#[derive(Debug, Clone, PartialEq)]
pub enum PassResult {
    /// Nothing to confirm, and why.
    Skipped(String),
    /// A shard traced its part of the confirmation; the other shards' are missing.
    Incomplete,
    /// Confirmed: the pass's round, whether its bound reached Y, and where it started.
    Confirmed {
        round: Round,
        accepted: bool,
        from: String,
    },
}

/// What the pass works from: the final surface, its draws, the costs and bounds, the rounds'
/// aim, the one-at-a-time budget and the rounds run.
pub struct PassInputs<'a> {
    pub surface: &'a Surface,
    pub samples: &'a Samples,
    pub costs: &'a [ToleranceCost],
    pub bounds: (&'a [f64], &'a [f64]),
    pub aim: &'a Aim,
    pub target_yield: f64,
    pub one_at_a_time: &'a [f64],
    /// The confirmed pass fraction of the baseline (the bias's reference when no round ran).
    pub baseline_fraction: Option<f64>,
    pub rounds: &'a [Round],
}

/// The pass (module docs) with `confirm` tracing (or modelling) the trials of a budget.
pub fn pass_with(
    p: &PassInputs,
    confirm: &mut dyn FnMut(&[f64]) -> Result<Option<Confirmation>>,
) -> Result<PassResult> {
    let cheapest = cheapest_pass(p.rounds, p.target_yield);
    // The surface's bias where the budget to beat was confirmed.
    let reference = cheapest
        .or_else(|| p.rounds.len().checked_sub(1))
        .map(|k| {
            (
                p.rounds[k].scales.as_slice(),
                p.rounds[k].confirmation.fraction,
            )
        })
        .or_else(|| p.baseline_fraction.map(|f| (p.one_at_a_time, f)));
    let gap = reference.map_or(0.0, |(s, f)| p.samples.yield_at(p.surface, s) - f);
    let target = (p.aim.needed + p.aim.margin + gap).clamp(0.5, 1.0);
    let starts = (
        cheapest.map(|k| p.rounds[k].scales.as_slice()),
        p.one_at_a_time,
    );
    let Some(prop) = propose(p.surface, p.samples, p.costs, p.bounds, target, starts) else {
        return Ok(PassResult::Skipped(format!(
            "no start reaches the surface target {target:.4}"
        )));
    };
    // Keep the rounds' choice unless the pass is looser by the geometric mean: the pass aims
    // at that measure, and the cheapest pass already wins on cost.
    if let Some(k) = cheapest {
        let (g, g0) = (
            geometric_mean(&prop.scales),
            p.rounds[k].geometric_mean_scale,
        );
        if g <= g0 {
            return Ok(PassResult::Skipped(format!(
                "its budget (geometric-mean scale {g:.4}) is no looser than round {}'s ({g0:.4})",
                k + 1
            )));
        }
    }
    if let Some(k) = p.rounds.iter().position(|r| r.scales == prop.scales) {
        return Ok(PassResult::Skipped(format!(
            "it found round {}'s budget again",
            k + 1
        )));
    }
    let Some(c) = confirm(&prop.scales)? else {
        return Ok(PassResult::Incomplete);
    };
    let accepted = c.lower_bound >= p.target_yield;
    Ok(PassResult::Confirmed {
        accepted,
        round: Round {
            surface_target: target,
            surface_yield: prop.surface_yield,
            total_cost: total_cost(p.costs, &prop.scales),
            geometric_mean_scale: geometric_mean(&prop.scales),
            cross_terms: p.surface.metrics.iter().map(|m| m.cross.len()).sum(),
            scales: prop.scales.clone(),
            confirmation: c,
        },
        from: format!(
            "from {}{}",
            prop.start.describe(),
            if prop.scaled_by < 1.0 {
                format!(" (× {:.3})", prop.scaled_by)
            } else {
                String::new()
            }
        ),
    })
}

/// The pass after the rounds of a search: confirmed by traced trials (with the job's
/// compensators) from [`LOOSEN_INDEX_BASE`]; its round is appended to `search.rounds` and
/// marked `search.loosened`, and `search.stop` says what it did.
#[allow(clippy::too_many_arguments)]
pub fn after_rounds(
    job: &Job,
    samples: &Samples,
    costs: &[ToleranceCost],
    bounds: (&[f64], &[f64]),
    aim: &Aim,
    (one_at_a_time, baseline_fraction): (&[f64], Option<f64>),
    search: &mut Rounds,
    traced: &mut Vec<TracedConfirmation>,
) -> Result<()> {
    let y = job.b.target_yield;
    let inputs = PassInputs {
        surface: &search.surface,
        samples,
        costs,
        bounds,
        aim,
        target_yield: y,
        one_at_a_time,
        baseline_fraction,
        rounds: &search.rounds,
    };
    (job.progress)("loosening pass: searching on the surface");
    let result = pass_with(&inputs, &mut |s| {
        (job.progress)(&format!(
            "loosening pass: geometric-mean scale {:.4}, confirming on fresh trials",
            geometric_mean(s)
        ));
        confirm(job, s, LOOSEN_INDEX_BASE, traced)
    })?;
    match result {
        PassResult::Skipped(why) => search.stop += &format!("; loosening pass skipped: {why}"),
        PassResult::Incomplete => {
            search.incomplete = true;
            search.stop = format!(
                "shard {}/{} stopped at the loosening pass",
                job.shard.0, job.shard.1
            );
        }
        PassResult::Confirmed {
            round,
            accepted,
            from,
        } => {
            let c = &round.confirmation;
            search.stop += &format!(
                "; loosening pass (round {}, {from}, geometric-mean scale {:.4}): {} of {} pass, \
                 lower bound {:.4}, {}",
                search.rounds.len() + 1,
                round.geometric_mean_scale,
                c.passed,
                c.trials,
                c.lower_bound,
                if accepted {
                    "accepted as the joint budget"
                } else {
                    "below the target, not used"
                }
            );
            if accepted {
                search.reason = None;
            }
            search.loosened = Some(search.rounds.len());
            search.rounds.push(round);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::tolerance::{Distribution, ToleranceSet};
    use crate::tolerance::budget::{allocate, inverse_limit, synthetic_confirm};
    use crate::tolerance::budget_surface::fraction_needed;

    const LIMIT: f64 = 0.01;

    type Confirmer = Box<dyn FnMut(&[f64]) -> Result<Option<Confirmation>>>;

    /// One tolerance drawn uniformly over ±1 and three drawn from a normal truncated at ±8σ,
    /// all acting linearly on the imbalance (0.02, 0.04, 0.04, 0.04 per unit), |imbalance| ≤
    /// 0.01. Each alone reaches the limit at the end of its range at scale 0.5 or 0.25, so the
    /// one-at-a-time limits are 0.5, 0.25, 0.25, 0.25; the ends, though, are where the truncated
    /// normals almost never draw (σ = 1/8 of the range), so those limits are tight for what
    /// they cost, while together at their limits the four add up and miss a 93 % surface yield.
    fn model(lin: [f64; 4]) -> (ToleranceSet, Surface) {
        let narrow = Distribution::TruncatedNormal { sigmas: 8.0 };
        crate::tolerance::budget::linear_model(
            &[
                ("a.despace_mm", Distribution::Uniform),
                ("b.despace_mm", narrow),
                ("c.despace_mm", narrow),
                ("d.despace_mm", narrow),
            ],
            &lin,
            LIMIT,
        )
    }

    fn round_of(scales: Vec<f64>, costs: &[ToleranceCost], c: Confirmation) -> Round {
        Round {
            surface_target: 0.0,
            surface_yield: 0.0,
            total_cost: total_cost(costs, &scales),
            geometric_mean_scale: geometric_mean(&scales),
            cross_terms: 0,
            scales,
            confirmation: c,
        }
    }

    /// The one-at-a-time limits add up and miss the target; scaled down to the target they are
    /// over-tight; the pass loosens them to a budget whose geometric-mean scale is at least the
    /// one-at-a-time one's (and the rounds' cheapest pass's), at a lower cost than either, and
    /// its confirmation on a fresh block of trials holds the yield. With a truth the surface
    /// underestimates, the confirmation falls short and the pass's budget is not accepted.
    #[test]
    fn the_pass_loosens_past_the_one_at_a_time_limits_and_confirms() {
        let lin = [0.02, 0.04, 0.04, 0.04];
        let (set, surface) = model(lin);
        let samples = Samples::draw(&set, 5, 4000);
        let costs = vec![ToleranceCost::default(); 4];
        let (lo, hi) = (vec![0.01; 4], vec![1.0; 4]);
        let (y, conf, n) = (0.9, 0.95, 2000usize);
        let needed = fraction_needed(y, conf, n).unwrap();
        // Three binomial SEs above the fraction needed (the rounds use one): the surface is
        // the truth here, so the fresh confirmation then misses the bound with probability
        // about 0.1 %, not 16 %.
        let se = (needed * (1.0 - needed) / n as f64).sqrt();
        let aim = Aim {
            needed,
            margin: 3.0 * se,
        };
        let target = needed + aim.margin;
        let oat: Vec<f64> = (0..4)
            .map(|i| inverse_limit(&surface, &set, i, lo[i], hi[i]))
            .collect();
        for (s, want) in oat.iter().zip([0.5, 0.25, 0.25, 0.25]) {
            assert!((s - want).abs() <= 0.002, "{oat:?}");
        }
        let y_oat = samples.yield_at(&surface, &oat);
        assert!(y_oat < target, "the limits should add: {y_oat} vs {target}");
        let (scaled, factor) =
            scaled_to_target(&surface, &samples, (&lo, &hi), target, &oat).unwrap();
        assert!(factor < 1.0 && geometric_mean(&scaled) < geometric_mean(&oat));
        // A round that passed by holding everything tight (scale 0.2, confirmed on its own
        // block of trials): the cheapest pass the rounds found.
        let s1 = vec![0.2; 4];
        let c1 = synthetic_confirm(&set, &surface, (0, n, conf), &s1);
        assert!(c1.lower_bound >= y, "{c1:?}");
        let rounds = vec![round_of(s1.clone(), &costs, c1)];
        let inputs = PassInputs {
            surface: &surface,
            samples: &samples,
            costs: &costs,
            bounds: (&lo, &hi),
            aim: &aim,
            target_yield: y,
            one_at_a_time: &oat,
            baseline_fraction: None,
            rounds: &rounds,
        };
        let confirmer = |truth: &Surface| -> Confirmer {
            let (set, truth) = (set.clone(), truth.clone());
            Box::new(move |s: &[f64]| {
                Ok(Some(synthetic_confirm(
                    &set,
                    &truth,
                    (LOOSEN_INDEX_BASE, n, conf),
                    s,
                )))
            })
        };
        let result = pass_with(&inputs, &mut *confirmer(&surface)).unwrap();
        let PassResult::Confirmed {
            round, accepted, ..
        } = result.clone()
        else {
            panic!("{result:?}");
        };
        let (gm, gm_oat, gm_1) = (
            round.geometric_mean_scale,
            geometric_mean(&oat),
            geometric_mean(&s1),
        );
        eprintln!(
            "one at a time {oat:?} (GM {gm_oat:.4}, cost {:.3}, surface yield {y_oat:.4}); \
             scaled ×{factor:.3}; round {s1:?} (GM {gm_1:.4}, cost {:.3}); pass {:?} (GM {gm:.4}, \
             cost {:.3}, surface {:.4}, confirmed {}/{n}, bound {:.4})",
            total_cost(&costs, &oat),
            total_cost(&costs, &s1),
            round.scales,
            round.total_cost,
            round.surface_yield,
            round.confirmation.passed,
            round.confirmation.lower_bound
        );
        assert!(accepted && round.confirmation.lower_bound >= y, "{round:?}");
        assert!(gm >= gm_oat && gm >= gm_1, "{gm} vs {gm_oat}, {gm_1}");
        assert!(round.total_cost < total_cost(&costs, &oat));
        assert!(round.surface_yield >= round.surface_target);
        // A fresh block: not the rounds' (0, n, 2n, …), the baseline's or the surface draws'.
        assert_eq!(round.confirmation.first_index, LOOSEN_INDEX_BASE);
        const {
            assert!(LOOSEN_INDEX_BASE > crate::tolerance::budget::BASELINE_INDEX_BASE + 1_000_000);
            assert!(
                LOOSEN_INDEX_BASE + 1_000_000 < crate::tolerance::budget_surface::SAMPLE_INDEX_BASE
            );
        }
        // Deterministic.
        let again = pass_with(&inputs, &mut *confirmer(&surface)).unwrap();
        assert!(matches!(&again, PassResult::Confirmed { round: r, .. } if *r == round));
        // After a round the allocation made at the same target, the pass is traced only if it
        // is looser than that round by the geometric mean.
        let (s2, _) = allocate(&surface, &samples, &costs, (&lo, &hi), target).unwrap();
        let c2 = synthetic_confirm(&set, &surface, (n as u64, n, conf), &s2);
        let allocated = vec![round_of(s2.clone(), &costs, c2)];
        let after = PassInputs {
            rounds: &allocated,
            ..inputs
        };
        let result = pass_with(&after, &mut *confirmer(&surface)).unwrap();
        eprintln!("after the allocation's round {s2:?}: {result:?}");
        match &result {
            PassResult::Skipped(why) => assert!(why.contains("no looser"), "{why}"),
            PassResult::Confirmed { round, .. } => {
                assert!(
                    round.geometric_mean_scale > geometric_mean(&s2),
                    "{result:?}"
                )
            }
            PassResult::Incomplete => panic!("{result:?}"),
        }
        // The built benches are 30 % more sensitive than the surface says: the pass's budget
        // fails its confirmation and is not accepted.
        let (_, harsher) = model(lin.map(|p| 1.3 * p));
        let result = pass_with(&inputs, &mut *confirmer(&harsher)).unwrap();
        assert!(
            matches!(&result, PassResult::Confirmed { accepted: false, round, .. }
                if round.confirmation.lower_bound < y),
            "{result:?}"
        );
    }
}
