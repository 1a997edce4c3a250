//! Benches drawn from a tolerance file: trial i's deviations from the stream keyed by
//! (seed, i), applied to the nominal bench, with the file's compensators adjusted by the
//! optimiser ([`crate::pipeline::optimise`]). The `tolerance` job traces such benches for its
//! Monte Carlo; the `dataset` job measures objects through them. Trials are independent of each
//! other: any subset (a shard) draws the same benches as the full run.

use crate::error::Result;
use crate::pipeline::evaluate::EvaluateOptions;
use crate::pipeline::optimise::{AlignOptions, Free, Objective, search, settings as free_settings};
use crate::rng;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{CompensatorObjective, Distribution, ToleranceSet};

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
