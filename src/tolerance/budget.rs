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
//! 2. **Allocation** ([`allocate`]): from the loosest scales, the tolerance whose tightening
//!    (× [`TIGHTEN_STEP`]) buys the most surface yield per unit of cost is tightened until the
//!    surface yield reaches the surface target; then every tolerance that can be loosened
//!    (× [`LOOSEN_STEP`]) without losing the target is (marginal analysis, the classic greedy
//!    allocation of tolerance costs: Chase and Parkinson 1991). Scales are rounded down to 3
//!    significant digits.
//! 3. **Confirmation.** `trials` Monte Carlo trials of real traced benches drawn from the
//!    budget, compensators adjusted in each ([`super::trial`]), judged by every limit of the
//!    file; the one-sided Wilson lower bound of their yield at confidence C must reach Y. Each
//!    round's trials are fresh (round r traces trials r·n … r·n + n − 1), so the bound of the
//!    round that stops is not biased by the rounds before.
//! 4. **Iteration.** A round that falls short refits the surface on every trial so far (cross
//!    terms and the compensators' corrections, [`budget_surface::Surface::refit`]) and raises the
//!    surface target by the gap between surface and trials, and at least half-way to 1.
//!
//! The baseline is the one-at-a-time inverse limit of lens-design tools (OpticStudio's Inverse
//! Limit): each tolerance alone set, on the surface, to the largest scale at which its limits
//! still hold at both ends of its range, then the Monte Carlo yield of that budget.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::pipeline::evaluate::Evaluation;
use crate::scene::budget_costs::ToleranceCost;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{SensitivityRecord, ToleranceSet, TrialRecord};

use super::ToleranceOptions;
use super::budget_surface::{Samples, Surface, fraction_needed, soft_widths, wilson_lower};

/// The factor a tightening step scales a tolerance by.
pub const TIGHTEN_STEP: f64 = 0.8;
/// The factor a loosening step scales a tolerance by.
pub const LOOSEN_STEP: f64 = 1.05;
/// The tolerances (largest share of the surface's variance first) whose pairs get cross terms
/// in a refit.
pub const REFIT_TOP: usize = 5;
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
    pub fraction: f64,
    /// The one-sided Wilson lower bound at the run's confidence.
    pub lower_bound: f64,
}

/// One round of the search.
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
    pub rows: Vec<BudgetRow>,
    /// The joint budget: the last round's (met the bound, or the best found).
    pub joint: BudgetFigures,
    pub baseline: BudgetFigures,
    pub rounds: Vec<Round>,
    /// The surface yield with every tolerance at one common scale λ: (λ, Ŷ).
    pub common_scale: Vec<(f64, f64)>,
    /// The limits no surface models (judged by the confirmations only).
    pub unmodelled_limits: Vec<String>,
    /// The trials of the confirmations, joint rounds then the baseline.
    #[serde(skip)]
    pub records: Vec<TrialRecord>,
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

fn total_cost(costs: &[ToleranceCost], scales: &[f64]) -> f64 {
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
fn round_down(v: f64) -> f64 {
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

/// Traces the confirmation trials `first … first + n − 1` of the budget `scales` and judges
/// them by every limit of the file.
fn confirm(
    job: &Job,
    scales: &[f64],
    first: u64,
    records: &mut Vec<TrialRecord>,
) -> Result<Confirmation> {
    let b = scaled_set(job.set, scales);
    let n = job.b.trials as usize;
    let mut passed = 0;
    let mut failed = 0;
    for i in first..first + n as u64 {
        let (r, _) = super::trial(job.doc, &b, job.nominal, job.o, i)?;
        if r.error.is_some() {
            failed += 1;
        } else if job
            .set
            .limits
            .iter()
            .all(|l| r.value(&l.metric.to_string()).is_some_and(|v| l.holds(v)))
        {
            passed += 1;
        }
        records.push(r);
    }
    (job.progress)(&format!("trials {first}…: {passed} of {n} pass"));
    Ok(Confirmation {
        first_index: first,
        trials: n,
        passed,
        failed_trials: failed,
        fraction: passed as f64 / n.max(1) as f64,
        lower_bound: wilson_lower(passed, n, job.b.confidence),
    })
}

struct Job<'a> {
    doc: &'a BenchDoc,
    set: &'a ToleranceSet,
    nominal: &'a Evaluation,
    o: &'a ToleranceOptions,
    b: &'a BudgetOptions,
    progress: &'a (dyn Fn(&str) + Sync),
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

/// Searches the budget for `set`'s limits (module docs). `sens` is the sensitivity table at
/// the file's ranges, `costs` one rule per tolerance; `progress` reports what runs.
#[allow(clippy::too_many_arguments)]
pub fn budget(
    doc: &BenchDoc,
    set: &ToleranceSet,
    costs: &[ToleranceCost],
    nominal: &Evaluation,
    sens: &[SensitivityRecord],
    o: &ToleranceOptions,
    b: &BudgetOptions,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<BudgetOutcome> {
    check_options(b)?;
    let costs = &set.pin_fixed(costs);
    let job = Job {
        doc,
        set,
        nominal,
        o,
        b,
        progress,
    };
    let nominal_values = super::values(nominal, nominal);
    let mut surface = Surface::from_sensitivity(set, sens, &nominal_values);
    let samples = Samples::draw(set, o.seed, b.samples);
    let lo: Vec<f64> = costs.iter().map(|c| c.min_scale).collect();
    let hi: Vec<f64> = costs
        .iter()
        .enumerate()
        .map(|(i, c)| valid_hi(doc, set, i, c.max_scale).max(c.min_scale))
        .collect();
    let fraction = fraction_needed(b.target_yield, b.confidence, b.trials as usize);
    let needed = fraction.unwrap_or(1.0);
    let mut records = Vec::new();
    let mut rounds: Vec<Round> = Vec::new();
    let mut target = needed;
    // Too few trials to show the target even if all pass: reported, not refused, so that a
    // small trial run still writes its baseline and surface.
    let mut reason = fraction.is_none().then(|| {
        let n = (1..=10_000_000usize)
            .find(|n| wilson_lower(*n, *n, b.confidence) >= b.target_yield)
            .unwrap_or(10_000_000);
        format!(
            "{} trials cannot show a yield of {} at confidence {} even if every one passes: give \
             `trials` {n} or more",
            b.trials, b.target_yield, b.confidence
        )
    });
    let rounds_allowed = if fraction.is_some() { b.max_rounds } else { 0 };
    for r in 0..rounds_allowed {
        let Some((scales, y)) = allocate(&surface, &samples, costs, (&lo, &hi), target) else {
            let y = samples.yield_at(&surface, &lo);
            reason = Some(format!(
                "on the response surface the tightest scales the bounds allow give a yield of \
                 {y:.4}, below the {target:.4} this round needs"
            ));
            break;
        };
        progress(&format!(
            "round {}: surface yield {y:.4} (target {target:.4}), confirming",
            r + 1
        ));
        let first = r as u64 * b.trials;
        let c = confirm(&job, &scales, first, &mut records)?;
        let met = c.lower_bound >= b.target_yield;
        rounds.push(Round {
            surface_target: target,
            surface_yield: y,
            total_cost: total_cost(costs, &scales),
            geometric_mean_scale: geometric_mean(&scales),
            cross_terms: surface.metrics.iter().map(|m| m.cross.len()).sum(),
            scales: scales.clone(),
            confirmation: c.clone(),
        });
        if met {
            break;
        }
        // Refit on every trial so far, weighting tolerances by their share of the surface's
        // spread at the file's ranges.
        let weight = spread_weights(&surface, set);
        if surface.metrics.iter().all(|m| m.cross.is_empty()) {
            surface.refit(set, &records, &weight, REFIT_TOP);
        } else {
            surface.refit(set, &records, &weight, 0);
        }
        let y_now = samples.yield_at(&surface, &scales);
        let gap = (y_now - c.fraction).max(0.0);
        target = (needed + gap).max(target + 0.5 * (1.0 - target)).min(1.0);
    }
    let reached = rounds
        .last()
        .is_some_and(|r| r.confirmation.lower_bound >= b.target_yield);
    if !reached && reason.is_none() {
        reason = Some(match rounds.last() {
            Some(last) => format!(
                "{} rounds did not confirm the target: the last budget's yield was {:.4} \
                 (lower bound {:.4} at confidence {})",
                rounds.len(),
                last.confirmation.fraction,
                last.confirmation.lower_bound,
                b.confidence
            ),
            None => "no round ran".into(),
        });
    }
    // The budget reported: the last round's when it met the bound, else the round with the
    // best confirmed yield.
    let chosen = if reached {
        rounds.last()
    } else {
        rounds
            .iter()
            .max_by(|a, b| a.confirmation.fraction.total_cmp(&b.confirmation.fraction))
    };
    let scales = chosen.map_or_else(|| lo.clone(), |r| r.scales.clone());
    let joint = BudgetFigures {
        total_cost: total_cost(costs, &scales),
        geometric_mean_scale: geometric_mean(&scales),
        surface_yield: samples.yield_at(&surface, &scales),
        confirmation: chosen.map(|r| r.confirmation.clone()),
        scales: scales.clone(),
    };
    let base: Vec<f64> = (0..set.tolerances.len())
        .map(|i| inverse_limit(&surface, set, i, lo[i], hi[i]))
        .collect();
    progress("baseline (one at a time): confirming");
    let bc = confirm(&job, &base, BASELINE_INDEX_BASE, &mut records)?;
    let baseline = BudgetFigures {
        total_cost: total_cost(costs, &base),
        geometric_mean_scale: geometric_mean(&base),
        surface_yield: samples.yield_at(&surface, &base),
        confirmation: Some(bc),
        scales: base.clone(),
    };
    let shares = loss_shares(&surface, &samples, &scales);
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
            baseline_scale: base[i],
            baseline_cost: costs[i].cost(base[i]),
        })
        .collect();
    let top = hi.iter().copied().fold(1.0, f64::max);
    let common_scale = (0..=40)
        .map(|k| {
            let l = 0.01 * (top / 0.01f64).powf(k as f64 / 40.0);
            (
                l,
                samples.yield_at(&surface, &vec![l; set.tolerances.len()]),
            )
        })
        .collect();
    Ok(BudgetOutcome {
        target_yield: b.target_yield,
        confidence: b.confidence,
        fraction_needed: needed,
        surface_samples: b.samples,
        reached,
        reason,
        rows,
        joint,
        baseline,
        rounds,
        common_scale,
        unmodelled_limits: surface.unmodelled.clone(),
        records,
    })
}

/// Each tolerance's weight in the surface at the file's ranges: Σ over the metrics of
/// (|p|·w + |q|·w²)² with w the half width, normalised by the metric's limit scale.
fn spread_weights(surface: &Surface, set: &ToleranceSet) -> Vec<f64> {
    set.tolerances
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let w = t.min.abs().max(t.max.abs());
            surface
                .metrics
                .iter()
                .map(|m| (m.lin[i].abs() * w + m.quad[i].abs() * w * w).powi(2))
                .sum()
        })
        .collect()
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
            if l.holds(m.at(&x)) {
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
mod tests {
    use super::*;
    use crate::quantities::BenchMetric;
    use crate::scene::tolerance::{Distribution, Tolerance, ToleranceLimit};
    use crate::tolerance::budget_surface::MetricSurface;

    /// Two tolerances on a linear imbalance, one 4× as sensitive: the surface yield is met,
    /// the dear-to-tighten one stays looser, and the inverse limits put each alone at the
    /// limit.
    fn toy() -> (ToleranceSet, Surface) {
        let t = |p: &str| Tolerance {
            path: p.into(),
            min: -1.0,
            max: 1.0,
            distribution: Distribution::Uniform,
            nominal: 0.0,
            fixed: false,
        };
        let limit = ToleranceLimit {
            metric: BenchMetric::Imbalance.into(),
            min: None,
            max: None,
            abs_max: Some(0.01),
        };
        let set = ToleranceSet {
            path: "t.ron".into(),
            tolerances: vec![t("a.despace_mm"), t("b.despace_mm")],
            compensators: Vec::new(),
            limits: vec![limit.clone()],
            quality: None,
        };
        let surface = Surface {
            metrics: vec![MetricSurface {
                metric: BenchMetric::Imbalance.into(),
                m0: 0.0,
                lin: vec![0.04, 0.01],
                quad: vec![0.0, 0.0],
                cross: Vec::new(),
            }],
            limits: vec![(0, limit)],
            unmodelled: Vec::new(),
        };
        (set, surface)
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
