//! Tolerance budgets: the loosest tolerances, at the least total cost, that still give a
//! target yield at a stated confidence.
//!
//! Tolerance i gets a scale sᵢ on the file's range (its range becomes sᵢ × the file's), within
//! the bounds of its cost rule (`scene::budget_costs`), costing cᵢ(sᵢ) = wᵢ·sᵢ^(−eᵢ) (by
//! default 1/sᵢ). The search:
//!
//! 1. **Surface.** The sensitivity table gives each limited metric as a sum of parabolas, one
//!    per tolerance ([`budget_surface::Surface`]); the yield of a budget is estimated on it over
//!    fixed draws at scale 1, scaled (common random numbers: deterministic in the seed).
//! 2. **Baseline.** The one-at-a-time inverse limit of lens-design tools (OpticStudio's Inverse
//!    Limit): each tolerance alone set, on that surface, to the largest scale at which its
//!    limits still hold at both ends of its range; then the Monte Carlo yield of that budget
//!    (`budget_search::baseline`). Its trials are the first data the surface is recalibrated
//!    on.
//! 3. **Allocation** ([`allocate`]): from the loosest scales, the tolerance whose tightening
//!    (× [`TIGHTEN_STEP`]) buys the most surface yield per unit of cost is tightened until the
//!    surface yield reaches the round's surface target; then every tolerance that can be
//!    loosened (× [`LOOSEN_STEP`]) without losing the target is (marginal analysis, the classic
//!    greedy allocation of tolerance costs: Chase and Parkinson 1991). Scales are rounded down
//!    to 3 significant digits.
//! 4. **Confirmation.** `trials` Monte Carlo trials of real traced benches drawn from the
//!    budget, compensators adjusted in each ([`super::trial`]), judged by every limit of the
//!    file (with `quality`, the image-quality limit too); the one-sided Wilson score lower
//!    bound of their yield at confidence C must reach Y. Each round's trials are fresh (round r
//!    traces trials r·n … r·n + n − 1), so a round's bound is not biased by the rounds before.
//! 5. **Rounds** (`budget_search::rounds`). After each confirmation the surface is
//!    recalibrated on every trial so far ([`budget_surface::Surface::refit`]: per-tolerance
//!    corrections, cross terms, what the compensators change), and the next surface target is
//!    the pass fraction the bound needs, plus one binomial standard error, plus the recalibrated
//!    surface's bias at the budget just confirmed (its yield there less the confirmed one). So
//!    a budget confirmed with room to spare (the surface pessimistic) is loosened, one that fell
//!    short tightened. The search stops when the next budget would save less than
//!    `budget_search::MIN_SAVING` of the cheapest passing budget's cost, repeats a round, or the
//!    rounds run out; the joint budget is the cheapest round that met the bound.
//! 6. **Loosening pass** ([`super::budget_loosen`]). The cheapest budget need not be the
//!    loosest (the cost weights differ by tolerance), and the one-at-a-time budget is over-tight
//!    once scaled down to the target. From each (the cheapest passing round, and the
//!    one-at-a-time budget scaled down uniformly until the surface holds it feasible), the
//!    tolerance whose loosening step saves the most cost is loosened while the surface yield
//!    holds; the result with the larger geometric-mean scale is confirmed on a fresh block of
//!    trials ([`super::budget_loosen::LOOSEN_INDEX_BASE`]) and becomes the joint budget only if
//!    its lower bound reaches Y. Its round is the last of `rounds` (`Rounds::loosened`).
//!
//! 7. **The one-at-a-time budget at the target** ([`super::budget_baseline`]): where the
//!    baseline missed Y, it is scaled down uniformly until a confirmation on fresh trials meets
//!    it, so that the joint budget's looseness is compared with a baseline that also reaches
//!    the target.
//!
//! Where a run's trials can be judged from a shorter trace (no geometric compensator, no
//! `--quality`), every confirmation's trial is staged ([`super::staged`]): traced first at an
//! eighth of the rays and kept where its verdict stands at four standard errors.
//!
//! A round that passes after several were tried is the cheapest of the passing rounds: each
//! bound is its own round's, from fresh trials, but choosing among passing rounds is a mild
//! selection the independent check (`spibench tolerance` on the budget file, another seed)
//! guards against.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::pipeline::evaluate::Evaluation;
use crate::scene::budget_costs::ToleranceCost;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{SensitivityRecord, ToleranceSet};

use super::ToleranceOptions;
use super::budget_search::{
    Aim, Job, Rounds, TracedConfirmation, baseline, calibrated, cheapest_pass, rounds,
};
use super::budget_surface::{Samples, Surface, fraction_needed, soft_widths, wilson_lower};

use super::budget_baseline::{self, Scaled, ScaledBaseline};
use super::budget_loosen;

/// How the lower bound of a confirmation's yield is computed (named in `summary.json`).
pub const LOWER_BOUND_METHOD: &str = "Wilson score, one-sided";

/// The factor a tightening step scales a tolerance by.
pub const TIGHTEN_STEP: f64 = 0.8;
/// The factor a loosening step scales a tolerance by.
pub const LOOSEN_STEP: f64 = 1.05;
/// The first trial index of the baseline's confirmation (the joint rounds use 0, n, 2n, …).
pub const BASELINE_INDEX_BASE: u64 = 1 << 40;

/// What the search aims at and how hard it works.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BudgetOptions {
    /// Y: the yield to reach, in (0, 1).
    pub target_yield: f64,
    /// C: the confidence of the lower bound, in (0, 1).
    pub confidence: f64,
    /// Trials per confirmation.
    pub trials: u64,
    /// Draws of the surface's yield estimate.
    pub samples: usize,
    /// The most confirmation rounds.
    pub max_rounds: usize,
}

/// Checks Y and C (each in the open interval (0, 1)); the errors name the field.
pub fn check_options(b: &BudgetOptions) -> Result<()> {
    let open = |v: f64| v.is_finite() && v > 0.0 && v < 1.0;
    if !open(b.target_yield) {
        return Err(Error::field(
            "target_yield",
            format!("a yield strictly between 0 and 1, got {}", b.target_yield),
        ));
    }
    if !open(b.confidence) {
        return Err(Error::field(
            "confidence",
            format!(
                "a confidence strictly between 0 and 1, got {}",
                b.confidence
            ),
        ));
    }
    Ok(())
}

/// A confirmation: real traced trials of a budget.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Confirmation {
    pub first_index: u64,
    pub trials: usize,
    pub passed: usize,
    pub failed_trials: usize,
    /// Trials whose verdict stood at the first stage's rays (`super::staged`; 0 unstaged).
    pub first_stage_trials: usize,
    pub fraction: f64,
    /// The one-sided Wilson lower bound at the run's confidence.
    pub lower_bound: f64,
}

/// One round of the search (the last may be the loosening pass's, `chosen_round` then naming
/// it when it was accepted).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Round {
    pub surface_target: f64,
    pub surface_yield: f64,
    pub scales: Vec<f64>,
    pub total_cost: f64,
    pub geometric_mean_scale: f64,
    /// Cross terms the surface held when this round's budget was allocated.
    pub cross_terms: usize,
    pub confirmation: Confirmation,
}

/// One tolerance of the budget.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetRow {
    pub path: String,
    pub scale: f64,
    /// The budget's range (deviations).
    pub min: f64,
    pub max: f64,
    pub cost: f64,
    pub bounds: [f64; 2],
    /// Its share of the budget's yield loss on the surface: each failing draw shared in
    /// proportion to |its term| of the failing metrics, averaged over the failing draws.
    pub loss_share: f64,
    pub baseline_scale: f64,
    pub baseline_cost: f64,
}

/// A budget as summarised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetFigures {
    pub scales: Vec<f64>,
    pub total_cost: f64,
    pub geometric_mean_scale: f64,
    pub surface_yield: f64,
    pub confirmation: Option<Confirmation>,
}

/// The whole search.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetOutcome {
    pub target_yield: f64,
    pub confidence: f64,
    /// The pass fraction of `trials` trials whose lower bound reaches Y.
    pub fraction_needed: f64,
    pub surface_samples: usize,
    /// Whether a budget's confirmation met the bound.
    pub reached: bool,
    /// Why not, when not.
    pub reason: Option<String>,
    /// The round whose budget is the joint one (0-based; none when no round ran).
    pub chosen_round: Option<usize>,
    /// Why the rounds stopped where they did.
    pub stop: String,
    /// A shard's run that stopped at a confirmation the other shards complete: only
    /// `traced` is meaningful.
    #[serde(skip)]
    pub incomplete: bool,
    pub rows: Vec<BudgetRow>,
    /// The joint budget: the loosening pass's when it met the bound, else the cheapest round
    /// that did, or the best found.
    pub joint: BudgetFigures,
    pub baseline: BudgetFigures,
    /// The baseline scaled down uniformly until its confirmation meets the target, where it
    /// missed (`super::budget_baseline`): the fair comparison for the joint budget.
    pub baseline_at_target: Option<ScaledBaseline>,
    pub rounds: Vec<Round>,
    /// The surface yield with every tolerance at one common scale λ: (λ, Ŷ).
    pub common_scale: Vec<(f64, f64)>,
    /// The limits no surface models (judged by the confirmations only).
    pub unmodelled_limits: Vec<String>,
    /// The confirmations' trials, the baseline's then the rounds'.
    #[serde(skip)]
    pub traced: Vec<TracedConfirmation>,
}

/// The tolerance file with each range scaled by its scale.
pub fn scaled_set(set: &ToleranceSet, scales: &[f64]) -> ToleranceSet {
    let mut s = set.clone();
    for (t, k) in s.tolerances.iter_mut().zip(scales) {
        t.min *= k;
        t.max *= k;
    }
    s
}

pub fn total_cost(costs: &[ToleranceCost], scales: &[f64]) -> f64 {
    costs.iter().zip(scales).map(|(c, s)| c.cost(*s)).sum()
}

/// The geometric mean of the scales.
pub fn geometric_mean(scales: &[f64]) -> f64 {
    if scales.is_empty() {
        return f64::NAN;
    }
    (scales.iter().map(|s| s.ln()).sum::<f64>() / scales.len() as f64).exp()
}

/// `v` to 12 significant digits: the product of a 3-digit scale and a file's range without its
/// last bits of rounding noise (0.46, not 0.45999999999999996), for the budget file.
fn decimal(v: f64) -> f64 {
    format!("{v:.11e}").parse().unwrap_or(v)
}

/// `v` rounded down to 3 significant digits.
pub(super) fn round_down(v: f64) -> f64 {
    if !(v > 0.0 && v.is_finite()) {
        return v;
    }
    // v = d·10^(−k) with d of 3 digits; dividing by the exact power 10^k gives the nearest
    // double to the decimal (a product with 10^(−k), not exact, would not).
    let k = 2 - v.log10().floor() as i32;
    let scaled = if k >= 0 {
        v * 10f64.powi(k)
    } else {
        v / 10f64.powi(-k)
    };
    // A 3-digit value may land a hair below its integer.
    let d = if (scaled - scaled.round()).abs() <= 1e-9 * scaled {
        scaled.round()
    } else {
        scaled.floor()
    };
    if k >= 0 {
        d / 10f64.powi(k)
    } else {
        d * 10f64.powi(-k)
    }
}

/// The scales minimising the total cost whose surface yield reaches `target`, within
/// `lo … hi`, and their surface yield; `None` when even the tightest scales fall short.
pub fn allocate(
    surface: &Surface,
    samples: &Samples,
    costs: &[ToleranceCost],
    (lo, hi): (&[f64], &[f64]),
    target: f64,
) -> Option<(Vec<f64>, f64)> {
    let n = costs.len();
    let widths = soft_widths(surface);
    let mut s = hi.to_vec();
    let mut y = samples.yield_at(surface, &s);
    for _ in 0..100_000 {
        if y >= target {
            break;
        }
        let soft = samples.soft_yield_at(surface, &s, &widths);
        let mut best: Option<(usize, f64)> = None;
        for i in (0..n).filter(|i| s[*i] > lo[*i]) {
            let mut t = s.clone();
            t[i] = (s[i] * TIGHTEN_STEP).max(lo[i]);
            let gain = samples.soft_yield_at(surface, &t, &widths) - soft;
            let dcost = (costs[i].cost(t[i]) - costs[i].cost(s[i])).max(1e-300);
            let ratio = gain / dcost;
            if best.is_none_or(|(_, r)| ratio > r) {
                best = Some((i, ratio));
            }
        }
        let (i, _) = best?;
        s[i] = (s[i] * TIGHTEN_STEP).max(lo[i]);
        y = samples.yield_at(surface, &s);
    }
    if y < target {
        return None;
    }
    // Loosen what the target allows, the largest saving first.
    for _ in 0..200 {
        let mut order: Vec<usize> = (0..n).filter(|i| s[*i] < hi[*i]).collect();
        let saving =
            |i: usize| costs[i].cost(s[i]) - costs[i].cost((s[i] * LOOSEN_STEP).min(hi[i]));
        order.sort_by(|a, b| saving(*b).total_cmp(&saving(*a)));
        let mut moved = false;
        for i in order {
            let mut t = s.clone();
            t[i] = (s[i] * LOOSEN_STEP).min(hi[i]);
            if samples.yield_at(surface, &t) >= target {
                s = t;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    for (v, l) in s.iter_mut().zip(lo) {
        *v = round_down(*v).max(*l);
    }
    let y = samples.yield_at(surface, &s);
    Some((s, y))
}

/// The one-at-a-time inverse limit of tolerance `i`: the largest scale in `lo … hi` at which
/// the surface, with this tolerance alone deviating, meets every limit over its whole range
/// (both ends, and the parabola's turning point where it lies inside).
pub fn inverse_limit(surface: &Surface, set: &ToleranceSet, i: usize, lo: f64, hi: f64) -> f64 {
    let t = &set.tolerances[i];
    let mut x = vec![0.0; set.tolerances.len()];
    let mut holds = |s: f64| {
        let mut points = vec![s * t.min, s * t.max];
        for m in &surface.metrics {
            if m.quad[i] != 0.0 {
                let v = -m.lin[i] / (2.0 * m.quad[i]);
                if v > s * t.min && v < s * t.max {
                    points.push(v);
                }
            }
        }
        points.into_iter().all(|p| {
            x[i] = p;
            surface.passes(&x)
        })
    };
    if holds(hi) {
        return hi;
    }
    if !holds(lo) {
        return lo;
    }
    let (mut a, mut b) = (lo.ln(), hi.ln());
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if holds(m.exp()) {
            a = m;
        } else {
            b = m;
        }
    }
    round_down(a.exp()).max(lo)
}

/// The largest scale ≤ `hi` (halving from `hi`, never below 1) at which both ends of
/// tolerance `i`'s range are a valid bench.
fn valid_hi(doc: &BenchDoc, set: &ToleranceSet, i: usize, hi: f64) -> f64 {
    let t = &set.tolerances[i];
    let ok = |s: f64| {
        [t.min, t.max]
            .iter()
            .all(|d| doc.with(&[(t.path.clone(), t.nominal + s * d)]).is_ok())
    };
    let mut s = hi;
    while s > 1.0 && !ok(s) {
        s = (s / 2.0).max(1.0);
    }
    s
}

/// The inputs of a budget search beside the bench: the tolerance file, one cost rule per
/// tolerance, the nominal bench, the sensitivity table at the file's ranges.
pub struct BudgetInputs<'a> {
    pub doc: &'a BenchDoc,
    pub set: &'a ToleranceSet,
    pub costs: &'a [ToleranceCost],
    pub nominal: &'a Evaluation,
    pub sens: &'a [SensitivityRecord],
}

/// How a run traces: the options of every trace, the search's, the confirmations of a run
/// before (reused where they agree: a resume, or the shards of one), and the shard (I, N) this
/// run traces of a confirmation they do not complete ((0, 1): all of it).
pub struct BudgetRunOptions<'a> {
    pub o: &'a ToleranceOptions,
    pub b: &'a BudgetOptions,
    pub prior: &'a [TracedConfirmation],
    pub shard: (u64, u64),
}

/// Searches the budget for the file's limits (module docs); `progress` reports what runs.
pub fn budget(
    inputs: &BudgetInputs,
    run: &BudgetRunOptions,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<BudgetOutcome> {
    let (set, costs, b) = (inputs.set, inputs.costs, run.b);
    check_options(b)?;
    let costs = &set.pin_fixed(costs);
    let stage = super::staged::first_stage(inputs.doc, set, run.o)?;
    let job = Job {
        doc: inputs.doc,
        set,
        nominal: inputs.nominal,
        o: run.o,
        b,
        progress,
        prior: run.prior,
        shard: run.shard,
        stage: stage.as_ref(),
    };
    // Every value a trial records, the electrical imbalance ι′ included: the surface models ι′
    // only where the nominal bench records it, and the confirmations judge ι′ (with `values`
    // alone the surface modelled the optical imbalance and was blind to the diodes'
    // responsivity mismatch, which moves ι′ only).
    let nominal_values =
        super::recorded((inputs.doc, inputs.nominal), (inputs.doc, inputs.nominal));
    let base = Surface::from_sensitivity(set, inputs.sens, &nominal_values);
    let samples = Samples::draw(set, run.o.seed, b.samples);
    let lo: Vec<f64> = costs.iter().map(|c| c.min_scale).collect();
    let hi: Vec<f64> = costs
        .iter()
        .enumerate()
        .map(|(i, c)| valid_hi(inputs.doc, set, i, c.max_scale).max(c.min_scale))
        .collect();
    let fraction = fraction_needed(b.target_yield, b.confidence, b.trials as usize);
    let needed = fraction.unwrap_or(1.0);
    let mut traced = Vec::new();
    // The baseline first: its trials are the first calibration of the joint search's surface.
    let (base_scales, base_c) = baseline(&job, &base, (&lo, &hi), &mut traced)?;
    let mut scaled = None;
    let search = match (fraction, &base_c) {
        (Some(_), Some(_)) => {
            let aim = Aim {
                needed,
                margin: (needed * (1.0 - needed) / b.trials as f64).sqrt(),
            };
            let mut search = rounds(&job, &base, &samples, costs, (&lo, &hi), &aim, &mut traced)?;
            if !search.incomplete {
                let base_fraction = base_c.as_ref().map(|c| c.fraction);
                budget_loosen::after_rounds(
                    &job,
                    &samples,
                    costs,
                    (&lo, &hi),
                    &aim,
                    (&base_scales, base_fraction),
                    &mut search,
                    &mut traced,
                )?;
            }
            if !search.incomplete {
                let r = budget_baseline::after_search(
                    &job,
                    &search.surface,
                    &samples,
                    costs,
                    (&lo, &hi),
                    &aim,
                    (&base_scales, base_c.as_ref()),
                    &mut traced,
                )?;
                match r {
                    Scaled::Incomplete => {
                        search.incomplete = true;
                        search.stop = format!(
                            "shard {}/{} stopped at the one-at-a-time budget scaled to the target",
                            run.shard.0, run.shard.1
                        );
                    }
                    Scaled::Skipped(why) => {
                        search.stop += &format!("; one-at-a-time budget not scaled: {why}")
                    }
                    Scaled::Done(b) => scaled = Some(b),
                }
            }
            search
        }
        _ => Rounds {
            rounds: Vec::new(),
            surface: calibrated(&base, set, &traced),
            reason: fraction.is_none().then(|| too_few_trials(b)),
            stop: "no round ran".into(),
            incomplete: base_c.is_none(),
            loosened: None,
        },
    };
    let baseline = BudgetFigures {
        total_cost: total_cost(costs, &base_scales),
        geometric_mean_scale: geometric_mean(&base_scales),
        surface_yield: samples.yield_at(&search.surface, &base_scales),
        confirmation: base_c,
        scales: base_scales,
    };
    Ok(outcome(
        inputs,
        b,
        &samples,
        (lo, hi),
        needed,
        (search, baseline, scaled),
        traced,
    ))
}

/// Too few trials to show the target even if all pass: reported, not refused, so that a small
/// trial run still writes its baseline and surface.
fn too_few_trials(b: &BudgetOptions) -> String {
    let n = (1..=10_000_000usize)
        .find(|n| wilson_lower(*n, *n, b.confidence) >= b.target_yield)
        .unwrap_or(10_000_000);
    format!(
        "{} trials cannot show a yield of {} at confidence {} even if every one passes: give \
         `trials` {n} or more",
        b.trials, b.target_yield, b.confidence
    )
}

/// The outcome of a search: the joint budget (the loosening pass's when it met the bound, else
/// the cheapest round that did, else the round with the best confirmed yield), its rows beside the baseline's, the common-scale
/// curve on the final surface.
fn outcome(
    inputs: &BudgetInputs,
    b: &BudgetOptions,
    samples: &Samples,
    (lo, hi): (Vec<f64>, Vec<f64>),
    needed: f64,
    (search, baseline, baseline_at_target): (Rounds, BudgetFigures, Option<ScaledBaseline>),
    traced: Vec<TracedConfirmation>,
) -> BudgetOutcome {
    let (set, costs, surface) = (inputs.set, inputs.costs, &search.surface);
    let passing = search
        .loosened
        .filter(|k| search.rounds[*k].confirmation.lower_bound >= b.target_yield)
        .or_else(|| cheapest_pass(&search.rounds, b.target_yield));
    let chosen = passing.or_else(|| {
        (0..search.rounds.len()).max_by(|x, y| {
            let f = |k: usize| search.rounds[k].confirmation.fraction;
            f(*x).total_cmp(&f(*y))
        })
    });
    let scales = chosen.map_or_else(|| lo.clone(), |k| search.rounds[k].scales.clone());
    let joint = BudgetFigures {
        total_cost: total_cost(costs, &scales),
        geometric_mean_scale: geometric_mean(&scales),
        surface_yield: samples.yield_at(surface, &scales),
        confirmation: chosen.map(|k| search.rounds[k].confirmation.clone()),
        scales: scales.clone(),
    };
    let shares = loss_shares(surface, samples, &scales);
    let rows = set
        .tolerances
        .iter()
        .enumerate()
        .map(|(i, t)| BudgetRow {
            path: t.path.clone(),
            scale: scales[i],
            min: decimal(t.min * scales[i]),
            max: decimal(t.max * scales[i]),
            cost: costs[i].cost(scales[i]),
            bounds: [lo[i], hi[i]],
            loss_share: shares[i],
            baseline_scale: baseline.scales[i],
            baseline_cost: costs[i].cost(baseline.scales[i]),
        })
        .collect();
    let top = hi.iter().copied().fold(1.0, f64::max);
    let common_scale = (0..=40)
        .map(|k| {
            let l = 0.01 * (top / 0.01f64).powf(k as f64 / 40.0);
            (l, samples.yield_at(surface, &vec![l; set.tolerances.len()]))
        })
        .collect();
    BudgetOutcome {
        target_yield: b.target_yield,
        confidence: b.confidence,
        fraction_needed: needed,
        surface_samples: b.samples,
        reached: passing.is_some(),
        reason: if passing.is_some() {
            None
        } else {
            search.reason
        },
        chosen_round: chosen,
        stop: search.stop,
        incomplete: search.incomplete,
        rows,
        joint,
        baseline,
        baseline_at_target,
        rounds: search.rounds,
        common_scale,
        unmodelled_limits: surface.unmodelled.clone(),
        traced,
    }
}

/// Each tolerance's share of the yield loss at `scales` on the surface: every sample that
/// fails is shared among the tolerances in proportion to |their term| of the failing metrics
/// (a cross term half to each), and the shares averaged over the failing samples (zeros when
/// none fails). Removing a tolerance is no measure here: two that cancel (the two diodes'
/// decentres) would each seem to cost nothing.
fn loss_shares(surface: &Surface, samples: &Samples, scales: &[f64]) -> Vec<f64> {
    let n = scales.len();
    let mut total = vec![0.0; n];
    let mut failing = 0usize;
    let mut x = vec![0.0; n];
    for row in &samples.rows {
        for ((xi, u), s) in x.iter_mut().zip(row).zip(scales) {
            *xi = u * s;
        }
        if surface.passes(&x) {
            continue;
        }
        let mut part = vec![0.0; n];
        for (k, l) in &surface.limits {
            let m = &surface.metrics[*k];
            if l.holds(m.judged(&x)) {
                continue;
            }
            for (i, p) in part.iter_mut().enumerate() {
                *p += (m.lin[i] * x[i] + m.quad[i] * x[i] * x[i]).abs();
            }
            for &(i, j, c) in &m.cross {
                let v = 0.5 * (c * x[i] * x[j]).abs();
                part[i] += v;
                part[j] += v;
            }
        }
        let sum: f64 = part.iter().sum();
        if sum > 0.0 && sum.is_finite() {
            failing += 1;
            for (t, p) in total.iter_mut().zip(&part) {
                *t += p / sum;
            }
        }
    }
    total
        .iter()
        .map(|t| if failing > 0 { t / failing as f64 } else { 0.0 })
        .collect()
}

#[cfg(test)]
/// A test fixture shared by `budget_loosen`'s and `budget_baseline`'s tests: a synthetic
/// confirmation: `n` trials drawn as traced trials are (`perturb::draw` at the
/// indices from `first`), judged on the `truth` model, with the one-sided Wilson bound.
pub(crate) fn synthetic_confirm(
    set: &ToleranceSet,
    truth: &Surface,
    (first, n, c): (u64, usize, f64),
    scales: &[f64],
) -> Confirmation {
    let passed = (first..first + n as u64)
        .filter(|i| {
            let x: Vec<f64> = crate::pipeline::perturb::draw(set, 5, *i)
                .iter()
                .zip(scales)
                .map(|((_, d), s)| d * s)
                .collect();
            truth.passes(&x)
        })
        .count();
    Confirmation {
        first_index: first,
        trials: n,
        passed,
        failed_trials: 0,
        first_stage_trials: 0,
        fraction: passed as f64 / n as f64,
        lower_bound: wilson_lower(passed, n, c),
    }
}

/// A test fixture shared by this module's and `budget_loosen`'s tests: tolerances over ±1
/// (nominal 0, none fixed, no compensators) acting linearly on the imbalance with slopes
/// `lin`, and the one limit |imbalance| ≤ `abs_max`.
#[cfg(test)]
pub(crate) fn linear_model(
    tolerances: &[(&str, crate::scene::tolerance::Distribution)],
    lin: &[f64],
    abs_max: f64,
) -> (ToleranceSet, Surface) {
    use crate::quantities::BenchMetric;
    use crate::scene::tolerance::{Tolerance, ToleranceLimit};
    use crate::tolerance::budget_surface::MetricSurface;
    let limit = ToleranceLimit {
        metric: BenchMetric::Imbalance.into(),
        min: None,
        max: None,
        abs_max: Some(abs_max),
    };
    let set = ToleranceSet {
        path: "t.ron".into(),
        tolerances: tolerances
            .iter()
            .map(|(p, distribution)| Tolerance {
                path: (*p).into(),
                min: -1.0,
                max: 1.0,
                distribution: *distribution,
                nominal: 0.0,
                fixed: false,
            })
            .collect(),
        compensators: Vec::new(),
        attenuator: None,
        limits: vec![limit.clone()],
        quality: None,
    };
    let surface = Surface {
        metrics: vec![MetricSurface {
            metric: BenchMetric::Imbalance.into(),
            recorded: "imbalance".into(),
            m0: 0.0,
            lin: lin.to_vec(),
            quad: vec![0.0; lin.len()],
            cross: Vec::new(),
            attenuator: None,
        }],
        limits: vec![(0, limit)],
        unmodelled: Vec::new(),
    };
    (set, surface)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::tolerance::Distribution;

    /// Two tolerances on a linear imbalance, one 4× as sensitive: the surface yield is met,
    /// the dear-to-tighten one stays looser, and the inverse limits put each alone at the
    /// limit.
    fn toy() -> (ToleranceSet, Surface) {
        linear_model(
            &[
                ("a.despace_mm", Distribution::Uniform),
                ("b.despace_mm", Distribution::Uniform),
            ],
            &[0.04, 0.01],
            0.01,
        )
    }

    #[test]
    fn allocation_meets_the_surface_target_at_low_cost() {
        let (set, surface) = toy();
        let samples = Samples::draw(&set, 7, 4000);
        let costs = vec![ToleranceCost::default(); 2];
        let (lo, hi) = (vec![0.01; 2], vec![1.0; 2]);
        let (s, y) = allocate(&surface, &samples, &costs, (&lo, &hi), 0.95).unwrap();
        assert!(y >= 0.95, "{s:?} {y}");
        assert!(s[0] < s[1], "{s:?}");
        // Deterministic in the seed.
        let again = allocate(
            &surface,
            &Samples::draw(&set, 7, 4000),
            &costs,
            (&lo, &hi),
            0.95,
        );
        assert_eq!(again, Some((s.clone(), y)));
        // The inverse limits: 0.04·s = 0.01 → s = 0.25; b alone never reaches the limit.
        let a = inverse_limit(&surface, &set, 0, 0.01, 1.0);
        assert!((a - 0.25).abs() < 0.002, "{a}");
        assert_eq!(inverse_limit(&surface, &set, 1, 0.01, 1.0), 1.0);
        // The one-at-a-time budget (0.25, 1) misses 95 %: both at their limits together.
        let y_base = samples.yield_at(&surface, &[0.25, 1.0]);
        assert!(y_base < 0.95, "{y_base}");
        // Shares of the loss sum to 1.
        let shares = loss_shares(&surface, &samples, &s);
        assert!(
            (shares.iter().sum::<f64>() - 1.0).abs() < 1e-12,
            "{shares:?}"
        );
        // A target the bounds cannot reach.
        let tight = vec![0.9; 2];
        assert_eq!(
            allocate(&surface, &samples, &costs, (&tight, &hi), 0.99),
            None
        );
    }

    #[test]
    fn targets_and_confidences_are_checked() {
        let b = |y: f64, c: f64, n: u64| BudgetOptions {
            target_yield: y,
            confidence: c,
            trials: n,
            samples: 100,
            max_rounds: 3,
        };
        assert!(check_options(&b(0.95, 0.95, 300)).is_ok());
        for (opt, flag) in [
            (b(0.0, 0.95, 300), "target_yield"),
            (b(1.0, 0.95, 300), "target_yield"),
            (b(f64::NAN, 0.95, 300), "target_yield"),
            (b(0.9, 1.0, 300), "confidence"),
            (b(0.9, 0.0, 300), "confidence"),
        ] {
            let e = check_options(&opt).unwrap_err();
            assert!(e.is_user_error() && e.to_string().contains(flag), "{e}");
        }
    }

    #[test]
    fn rounding_goes_down_to_three_digits() {
        assert_eq!(round_down(0.123_456), 0.123);
        assert_eq!(round_down(0.25), 0.25);
        assert_eq!(round_down(1.0), 1.0);
        assert_eq!(round_down(0.019_99), 0.0199);
        assert_eq!(round_down(0.175_000_000_1), 0.175);
        assert!((geometric_mean(&[0.25, 1.0]) - 0.5).abs() < 1e-12);
    }
}
