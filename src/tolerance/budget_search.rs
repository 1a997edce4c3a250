//! The traced part of a tolerance budget's search (crate::tolerance::budget): confirmations by
//! Monte Carlo trials of real benches, the one-at-a-time baseline's, and the rounds that
//! allocate on the response surface, confirm, recalibrate the surface on every trial so far and
//! then loosen a budget that passed with room to spare or tighten one that fell short.
//!
//! Every trial is a pure function of (seed, index, budget): a confirmation traced before (a
//! resumed run's, or another shard's) is reused where its first index and scales agree bit for
//! bit, so a resumed or sharded search replays the uninterrupted one exactly.

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::pipeline::evaluate::Evaluation;
use crate::scene::budget_costs::ToleranceCost;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{QualityLimit, ToleranceSet, TrialRecord};

use super::ToleranceOptions;
use super::budget::{
    BASELINE_INDEX_BASE, BudgetOptions, Confirmation, Round, allocate, geometric_mean,
    inverse_limit, scaled_set, total_cost,
};
use super::budget_surface::{Samples, Surface, wilson_lower};

/// The tolerances (largest share of the surface's spread first) whose pairs get cross terms in
/// a recalibration.
pub const REFIT_TOP: usize = 5;
/// A loosening round must promise at least this fraction of the best passing budget's cost as
/// saving, else the search has converged.
pub const MIN_SAVING: f64 = 0.01;
/// After a round that falls short with no budget passed yet, the next surface target moves at
/// least this fraction of the way to 1 (so that the rounds cannot stall on a surface that keeps
/// predicting the same yield).
pub const MIN_TIGHTEN: f64 = 0.1;

/// One confirmation's trials as traced: its budget, its first index and its records (index
/// order). A shard's holds only its own trials.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TracedConfirmation {
    pub first_index: u64,
    pub scales: Vec<f64>,
    pub records: Vec<TrialRecord>,
}

/// `budget_trials.ron`: what a budget run traced, from which a later run resumes (`prior`):
/// the run's identity (bench, tolerance file, costs, rays, seed, trials, `quality`, target,
/// confidence, surface draws: a resume must agree on all of them to replay the search), the
/// sensitivity table (not traced again) and every confirmation's trials.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BudgetTrialsFile {
    pub spibench_version: String,
    pub scene: String,
    pub bench_ron: String,
    pub tolerances_text: String,
    /// Each tolerance's cost rule: [weight, exponent, min_scale, max_scale].
    pub costs: Vec<[f64; 4]>,
    pub rays: u64,
    pub seed: u64,
    pub trials: u64,
    pub quality: bool,
    pub target_yield: f64,
    pub confidence: f64,
    pub surface_samples: usize,
    /// (I, N) of the run that wrote it ((0, 1): not sharded).
    pub shard: (u64, u64),
    pub sensitivity: Vec<crate::scene::tolerance::SensitivityRecord>,
    pub confirmations: Vec<TracedConfirmation>,
}

impl BudgetTrialsFile {
    /// Why `other` (a file to resume from) is not of the same run as `self` (this run's
    /// identity, with no confirmations), if it is not; every trial's deviations must name the
    /// tolerance file's variables in its order.
    pub fn mismatch(&self, other: &BudgetTrialsFile, set: &ToleranceSet) -> Option<String> {
        let fields = [
            ("bench", self.bench_ron == other.bench_ron),
            (
                "tolerance file",
                self.tolerances_text == other.tolerances_text,
            ),
            ("costs", self.costs == other.costs),
            ("rays", self.rays == other.rays),
            ("seed", self.seed == other.seed),
            ("trials", self.trials == other.trials),
            ("quality", self.quality == other.quality),
            ("target_yield", self.target_yield == other.target_yield),
            ("confidence", self.confidence == other.confidence),
            (
                "surface_samples",
                self.surface_samples == other.surface_samples,
            ),
        ];
        if let Some((name, _)) = fields.iter().find(|(_, same)| !same) {
            return Some(format!("its {name} differs from this run's"));
        }
        let want: Vec<&str> = set.tolerances.iter().map(|t| t.path.as_str()).collect();
        other
            .confirmations
            .iter()
            .flat_map(|c| &c.records)
            .find(|r| {
                r.deviations
                    .iter()
                    .map(|(p, _)| p.as_str())
                    .ne(want.iter().copied())
            })
            .map(|r| {
                format!(
                    "trial {} does not deviate the tolerance file's variables",
                    r.index
                )
            })
    }
}

/// What a search traces with.
pub struct Job<'a> {
    pub doc: &'a BenchDoc,
    pub set: &'a ToleranceSet,
    pub nominal: &'a Evaluation,
    pub o: &'a ToleranceOptions,
    pub b: &'a BudgetOptions,
    pub progress: &'a (dyn Fn(&str) + Sync),
    /// Confirmations traced before (a resumed run's, the shards'), reused where they agree.
    pub prior: &'a [TracedConfirmation],
    /// (I, N): with N > 1, of a confirmation `prior` does not complete, only the trials whose
    /// offset k (index − first) has k ≡ I (mod N) are traced, and the search stops there.
    pub shard: (u64, u64),
    /// The trials' first stage, where they are staged (`super::staged`).
    pub stage: Option<&'a super::staged::FirstStage>,
}

/// Whether a trial meets every limit of the file: every metric limit, and with `quality` the
/// image-quality limit for every scheme the trial scored (a trial that scored none fails it).
pub fn passes(set: &ToleranceSet, quality: bool, r: &TrialRecord) -> bool {
    r.error.is_none()
        && set
            .limits
            .iter()
            .all(|l| l.value_in(r).is_some_and(|v| l.holds(v)))
        && (!quality || set.quality.is_none_or(|q| quality_holds(&q, r)))
}

fn quality_holds(q: &QualityLimit, r: &TrialRecord) -> bool {
    let suffix = format!("_{}_mssim", q.ratio_percent);
    let mut scores = r
        .values
        .iter()
        .filter(|(k, _)| k.ends_with(&suffix))
        .map(|(_, v)| *v)
        .peekable();
    scores.peek().is_some() && scores.all(|v| v >= q.min_mssim)
}

/// Traces (or takes from `job.prior`) the trials `first … first + n − 1` of the budget
/// `scales`, appends them to `traced`, and judges them; `None` when this shard traced its part
/// and the others' are missing.
pub fn confirm(
    job: &Job,
    scales: &[f64],
    first: u64,
    traced: &mut Vec<TracedConfirmation>,
) -> Result<Option<Confirmation>> {
    let n = job.b.trials;
    let b = scaled_set(job.set, scales);
    let prior: Vec<&TrialRecord> = job
        .prior
        .iter()
        .filter(|p| p.first_index == first && p.scales == scales)
        .flat_map(|p| &p.records)
        .collect();
    let (mut records, mut missing, mut reused) = (Vec::with_capacity(n as usize), false, 0);
    for i in first..first + n {
        if let Some(r) = prior.iter().find(|r| r.index == i) {
            records.push((*r).clone());
            reused += 1;
        } else if job.shard.1 > 1 && (i - first) % job.shard.1 != job.shard.0 {
            missing = true;
        } else {
            records.push(match job.stage {
                Some(st) => super::staged::trial(job.doc, &b, (job.nominal, st), job.o, i)?,
                None => super::trial(job.doc, &b, job.nominal, job.o, i)?.0,
            });
        }
    }
    let passed = records
        .iter()
        .filter(|r| passes(job.set, job.o.quality, r))
        .count();
    let failed = records.iter().filter(|r| r.error.is_some()).count();
    let first_stage = records.iter().filter(|r| r.rays.is_some()).count();
    traced.push(TracedConfirmation {
        first_index: first,
        scales: scales.to_vec(),
        records,
    });
    let from = if reused > 0 {
        format!(" ({reused} from the resumed records)")
    } else {
        String::new()
    };
    if missing {
        (job.progress)(&format!(
            "trials {first}…: shard {}/{} traced its part{from}; the other shards' are missing",
            job.shard.0, job.shard.1
        ));
        return Ok(None);
    }
    let staged = job.stage.map_or(String::new(), |st| {
        format!(" ({first_stage} decided at {} rays)", st.rays)
    });
    (job.progress)(&format!(
        "trials {first}…: {passed} of {n} pass{staged}{from}"
    ));
    Ok(Some(Confirmation {
        first_index: first,
        trials: n as usize,
        passed,
        failed_trials: failed,
        first_stage_trials: first_stage,
        fraction: passed as f64 / n.max(1) as f64,
        lower_bound: wilson_lower(passed, n as usize, job.b.confidence),
    }))
}

/// The one-at-a-time baseline: each tolerance alone at its inverse limit on the sensitivity
/// surface, then confirmed (trials from [`BASELINE_INDEX_BASE`]).
pub fn baseline(
    job: &Job,
    surface: &Surface,
    (lo, hi): (&[f64], &[f64]),
    traced: &mut Vec<TracedConfirmation>,
) -> Result<(Vec<f64>, Option<Confirmation>)> {
    let base: Vec<f64> = (0..job.set.tolerances.len())
        .map(|i| inverse_limit(surface, job.set, i, lo[i], hi[i]))
        .collect();
    (job.progress)("baseline (one at a time): confirming");
    let c = confirm(job, &base, BASELINE_INDEX_BASE, traced)?;
    Ok((base, c))
}

/// The surface from the sensitivity table, recalibrated on every trial traced so far
/// (`budget_surface::Surface::refit`: the per-tolerance terms of every tolerance, cross terms
/// among the [`REFIT_TOP`] with the largest spread). Always from `base`, so a recalibration does
/// not stack on the one before.
pub fn calibrated(base: &Surface, set: &ToleranceSet, traced: &[TracedConfirmation]) -> Surface {
    let records: Vec<TrialRecord> = traced.iter().flat_map(|t| t.records.clone()).collect();
    let mut s = base.clone();
    let weight = spread_weights(base, set);
    s.refit(set, &records, &weight, REFIT_TOP);
    s
}

/// Each tolerance's weight in the surface at the file's ranges: Σ over the metrics of
/// (|p|·w + |q|·w²)² with w the half width.
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

/// The joint rounds of a search.
pub struct Rounds {
    pub rounds: Vec<Round>,
    /// The surface after the last recalibration.
    pub surface: Surface,
    /// Why the search ended without a passing budget, when it did.
    pub reason: Option<String>,
    /// Why the search stopped where it did (converged, out of rounds, …).
    pub stop: String,
    /// A shard stopped at a confirmation the other shards must complete.
    pub incomplete: bool,
    /// The index in `rounds` of the loosening pass's round (crate::tolerance::budget_loosen),
    /// when it was confirmed.
    pub loosened: Option<usize>,
}

/// What the rounds aim at: the pass fraction `needed` of a confirmation for its lower bound to
/// reach Y, and `margin`, one binomial standard error at that fraction, added to the surface
/// target so that a budget whose surface yield is right passes its confirmation about 84 % of
/// the time rather than half.
pub struct Aim {
    pub needed: f64,
    pub margin: f64,
}

/// The rounds (module docs). `base` is the sensitivity surface, `traced` holds the baseline's
/// trials (the first calibration data) and gains every round's.
pub fn rounds(
    job: &Job,
    base: &Surface,
    samples: &Samples,
    costs: &[ToleranceCost],
    bounds: (&[f64], &[f64]),
    aim: &Aim,
    traced: &mut Vec<TracedConfirmation>,
) -> Result<Rounds> {
    let b = job.b;
    let mut surface = calibrated(base, job.set, traced);
    // The surface's bias at the last confirmed budget: its yield there less the confirmed one.
    let mut gap = last_gap(&surface, samples, traced, job);
    let mut out = Rounds {
        rounds: Vec::new(),
        surface: surface.clone(),
        reason: None,
        stop: format!("{} rounds ran (`max_rounds`)", b.max_rounds),
        incomplete: false,
        loosened: None,
    };
    let mut prev_fail: Option<f64> = None;
    for r in 0..b.max_rounds {
        let best = cheapest_pass(&out.rounds, b.target_yield);
        let mut target = (aim.needed + aim.margin + gap).clamp(0.5, 1.0);
        match (best, prev_fail) {
            // Tightening with nothing passed: at least a step beyond the last failing target.
            (None, Some(f)) => target = target.max(f + MIN_TIGHTEN * (1.0 - f)),
            // A looser budget failed after one passed: no looser than half-way back.
            (Some(k), Some(f)) => target = target.max(0.5 * (f + out.rounds[k].surface_target)),
            _ => {}
        }
        let Some((scales, y)) = allocate(&surface, samples, costs, bounds, target) else {
            let y = samples.yield_at(&surface, bounds.0);
            out.stop = format!(
                "on the response surface the tightest scales the bounds allow give a yield of \
                 {y:.4}, below the {target:.4} round {} needs",
                r + 1
            );
            if best.is_none() {
                out.reason = Some(out.stop.clone());
            }
            break;
        };
        if let Some(k) = best {
            let cost = total_cost(costs, &scales);
            if cost >= (1.0 - MIN_SAVING) * out.rounds[k].total_cost {
                out.stop = format!(
                    "converged: the next budget would save less than {} % of round {}'s cost",
                    100.0 * MIN_SAVING,
                    k + 1
                );
                break;
            }
        }
        if let Some(k) = out.rounds.iter().position(|q| q.scales == scales) {
            out.stop = format!("converged: the next budget repeats round {}'s", k + 1);
            break;
        }
        (job.progress)(&format!(
            "round {}: surface yield {y:.4} (target {target:.4}), confirming",
            r + 1
        ));
        let cross_terms = surface.metrics.iter().map(|m| m.cross.len()).sum();
        let first = r as u64 * b.trials;
        let Some(c) = confirm(job, &scales, first, traced)? else {
            out.incomplete = true;
            out.stop = format!(
                "shard {}/{} stopped at round {}",
                job.shard.0,
                job.shard.1,
                r + 1
            );
            break;
        };
        let met = c.lower_bound >= b.target_yield;
        prev_fail = (!met).then_some(target);
        surface = calibrated(base, job.set, traced);
        gap = samples.yield_at(&surface, &scales) - c.fraction;
        out.rounds.push(Round {
            surface_target: target,
            surface_yield: y,
            total_cost: total_cost(costs, &scales),
            geometric_mean_scale: geometric_mean(&scales),
            cross_terms,
            scales,
            confirmation: c,
        });
    }
    if cheapest_pass(&out.rounds, b.target_yield).is_none() && out.reason.is_none() {
        out.reason = Some(match out.rounds.last() {
            Some(last) => format!(
                "{} rounds did not confirm the target: the last budget's yield was {:.4} \
                 (lower bound {:.4} at confidence {})",
                out.rounds.len(),
                last.confirmation.fraction,
                last.confirmation.lower_bound,
                b.confidence
            ),
            None => "no round ran".into(),
        });
    }
    out.surface = surface;
    Ok(out)
}

/// The surface's yield at the last traced confirmation's budget less its confirmed fraction (0
/// when none is complete).
fn last_gap(surface: &Surface, samples: &Samples, traced: &[TracedConfirmation], job: &Job) -> f64 {
    traced
        .last()
        .filter(|t| t.records.len() as u64 == job.b.trials && !t.records.is_empty())
        .map_or(0.0, |t| {
            let passed = t
                .records
                .iter()
                .filter(|r| passes(job.set, job.o.quality, r))
                .count();
            samples.yield_at(surface, &t.scales) - passed as f64 / t.records.len() as f64
        })
}

/// The passing round of least total cost (the first on ties).
pub fn cheapest_pass(rounds: &[Round], y: f64) -> Option<usize> {
    rounds
        .iter()
        .enumerate()
        .filter(|(_, r)| r.confirmation.lower_bound >= y)
        .min_by(|a, b| a.1.total_cost.total_cmp(&b.1.total_cost))
        .map(|(k, _)| k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quantities::BenchMetric;
    use crate::scene::tolerance::ToleranceLimit;

    #[test]
    fn a_trial_passes_every_metric_limit_and_with_quality_every_scheme() {
        let set = ToleranceSet {
            path: "t.ron".into(),
            tolerances: Vec::new(),
            compensators: Vec::new(),
            attenuator: None,
            limits: vec![ToleranceLimit {
                metric: BenchMetric::Imbalance.into(),
                min: None,
                max: None,
                abs_max: Some(0.01),
            }],
            quality: Some(QualityLimit {
                ratio_percent: 40,
                min_mssim: 0.9,
            }),
        };
        let rec = |v: &[(&str, f64)]| TrialRecord {
            index: 0,
            deviations: Vec::new(),
            compensators: Vec::new(),
            values: v.iter().map(|(k, x)| (k.to_string(), *x)).collect(),
            needed_travel: Vec::new(),
            rays: None,
            error: None,
        };
        let good = rec(&[
            ("imbalance", 0.005),
            ("hadamard_40_mssim", 0.95),
            ("random_40_mssim", 0.92),
        ]);
        let blurred = rec(&[
            ("imbalance", 0.005),
            ("hadamard_40_mssim", 0.95),
            ("random_40_mssim", 0.85),
        ]);
        let unbalanced = rec(&[("imbalance", -0.02), ("hadamard_40_mssim", 0.95)]);
        assert!(passes(&set, true, &good) && passes(&set, false, &good));
        assert!(!passes(&set, true, &blurred) && passes(&set, false, &blurred));
        assert!(!passes(&set, true, &unbalanced) && !passes(&set, false, &unbalanced));
        // No score at the limit's ratio: the quality limit is not met.
        assert!(!passes(&set, true, &rec(&[("imbalance", 0.0)])));
        let mut failed = good.clone();
        failed.error = Some("overlap".into());
        assert!(!passes(&set, false, &failed));
    }
}
