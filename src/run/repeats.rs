//! Repeated acquisitions of one traced bench (`spibench run --repeats N`): every random process
//! after the trace is drawn again (detector and oscilloscope noise, drift, the paper's additive
//! noise, and the patterns when they are random), the trace is shared, and each scheme × ratio
//! is reported as a mean and a sample standard deviation over the repeats, with paired
//! differences between schemes.
//!
//! Within a repeat the schemes share what their hardware shares: schemes that read the same
//! frame sequence (traditional CS and double-arm, single-arm and SCB) read the same recorded
//! noise, so a paired difference between them is free of that noise's common part, and its
//! confidence interval comes from the spread of the per-repeat differences (Student's t with
//! N − 1 degrees of freedom).
//!
//! Repeat 0 uses the run's own seed and patterns, so `--repeats 1` is the plain run; repeat
//! r > 0 uses [`repeat_seed`] for the noise and drift and [`repeat_patterns`] for the patterns.

use serde::Serialize;

use super::RunOutcome;
use crate::acquisition::{PackedPatterns, PatternFamily, Scheme};
use crate::error::{Error, Result};
use crate::pipeline::evaluate::{Shared, base_patterns, evaluate_shared};
use crate::pipeline::{self, Progress, TraceRequest};
use crate::rng;
use crate::scene::run::RunScene;

/// At most this many repeats (each is a whole record and solve stage).
pub const MAX_REPEATS: usize = 1000;

/// The noise and drift seed of repeat `r` (repeat 0: the run's seed).
pub fn repeat_seed(seed: u64, r: usize) -> u64 {
    if r == 0 {
        seed
    } else {
        rng::mix64(seed ^ rng::mix64(0x4E9E_A700_0000 + r as u64))
    }
}

/// The pattern family of repeat `r`: random patterns are drawn again from a seed keyed by the
/// repeat; Hadamard patterns are fixed by their ordering and stay.
pub fn repeat_patterns(family: &PatternFamily, r: usize) -> PatternFamily {
    match *family {
        PatternFamily::Random { seed } if r > 0 => PatternFamily::Random {
            seed: rng::mix64(seed ^ rng::mix64(0x9A77_0000_0000 + r as u64)),
        },
        other => other,
    }
}

/// One scheme at one ratio over the repeats.
#[derive(Debug, Clone, Serialize)]
pub struct RepeatStats {
    pub scheme: Scheme,
    pub ratio: f64,
    pub repeats: usize,
    pub dmd_frames: usize,
    pub acquisition_time_s: f64,
    pub psnr_db_mean: f64,
    /// Sample standard deviation over the repeats (0 for one repeat).
    pub psnr_db_sd: f64,
    pub mssim_mean: f64,
    pub mssim_sd: f64,
    /// Repeats whose result read a clipped or over-range output.
    pub saturated_repeats: usize,
}

/// A paired difference `a − b` of one score at one ratio, over the repeats.
#[derive(Debug, Clone, Serialize)]
pub struct PairedDifference {
    pub a: Scheme,
    pub b: Scheme,
    pub ratio: f64,
    /// "mssim" or "psnr_db".
    pub metric: &'static str,
    pub repeats: usize,
    pub mean: f64,
    pub sd: f64,
    /// The 95 % confidence interval of the mean difference (Student's t, N − 1 degrees of
    /// freedom); None for a single repeat.
    pub ci95: Option<[f64; 2]>,
}

/// What `--repeats N` adds to a run.
#[derive(Debug, Clone, Serialize)]
pub struct Repeats {
    pub repeats: usize,
    /// The noise and drift seed of each repeat.
    pub seeds: Vec<u64>,
    /// Scheme-major, ratio-minor, as the run's results.
    pub stats: Vec<RepeatStats>,
    /// SCB − single-arm complementary and SCB − calibrated double-arm (when both schemes ran).
    pub paired: Vec<PairedDifference>,
}

/// Runs the scene's trace once and its downstream stages `n` times ([`repeat_seed`],
/// [`repeat_patterns`]), in repeat order. The run's seed is the trace's (`trace.seed`): it
/// keys the trace, and repeat 0's noise and drift. Returns the outcome of repeat 0 (the plain
/// run), every repeat's outcome and the statistics. A count out of range names the field
/// `repeats`.
pub fn run_repeats(
    scene: &RunScene,
    trace: &TraceRequest,
    n: usize,
    progress: Progress,
) -> Result<(Vec<RunOutcome>, Repeats)> {
    let seed = trace.seed;
    if n == 0 || n > MAX_REPEATS {
        return Err(Error::field(
            "repeats",
            format!("must lie between 1 and {MAX_REPEATS}, got {n}"),
        ));
    }
    // Every repeat's patterns first: a bad pattern setting fails before the trace. Repeats
    // that draw the same patterns (Hadamard orderings are fixed) share one packed set.
    let families: Vec<PatternFamily> = (0..n)
        .map(|r| repeat_patterns(&scene.settings.patterns, r))
        .collect();
    let mut packed: Vec<(PatternFamily, PackedPatterns)> = Vec::new();
    for f in &families {
        if !packed.iter().any(|(g, _)| g == f) {
            packed.push((*f, PackedPatterns::new(base_patterns(f, scene)?)));
        }
    }
    let t0 = std::time::Instant::now();
    let traced = pipeline::trace_stage(&scene.bench, trace)?;
    let trace_s = t0.elapsed().as_secs_f64();
    // What does not depend on the noise (the ideal object, the chart's registration) is made
    // once: only the record and the solve repeat.
    let t1 = std::time::Instant::now();
    let shared = Shared::of(scene, &traced)?;
    let shared_s = t1.elapsed().as_secs_f64();
    let mut outcomes = Vec::with_capacity(n);
    for (r, f) in families.iter().enumerate() {
        let p = packed
            .iter()
            .find(|(g, _)| g == f)
            .map(|(_, p)| p)
            .ok_or_else(|| Error::Numerical("a repeat's patterns were not built".into()))?;
        let mut o = evaluate_shared(scene, &traced, &shared, p, repeat_seed(seed, r), progress)?;
        if r == 0 {
            o.timings.trace_s = trace_s;
            o.timings.solve_s += shared_s;
        }
        o.timings.total_s = o.timings.trace_s + o.timings.record_s + o.timings.solve_s;
        outcomes.push(o);
    }
    let stats = statistics(&outcomes, seed);
    Ok((outcomes, stats))
}

/// Mean and sample standard deviation (0 for fewer than two values), summed in order.
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, 0.0);
    }
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// The two-sided 95 % quantile of Student's t with `df` degrees of freedom (tabulated to 30,
/// then the normal quantile with a first-order correction, within 0.2 % beyond 30).
pub fn t95(df: usize) -> f64 {
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match df {
        0 => f64::INFINITY,
        1..=30 => T[df - 1],
        _ => 1.959_964 + 2.37 / df as f64,
    }
}

/// The statistics of repeated outcomes of one scene (all with the same schemes and ratios).
pub fn statistics(outcomes: &[RunOutcome], seed: u64) -> Repeats {
    let n = outcomes.len();
    let first = &outcomes[0];
    let s = &first.settings;
    let n_ratio = s.sampling_ratios.len();
    let column = |i: usize, f: fn(&crate::pipeline::SchemeResult) -> f64| -> Vec<f64> {
        outcomes.iter().map(|o| f(&o.results[i])).collect()
    };
    let stats = first
        .results
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (psnr_db_mean, psnr_db_sd) = mean_sd(&column(i, |r| r.psnr_db));
            let (mssim_mean, mssim_sd) = mean_sd(&column(i, |r| r.mssim));
            RepeatStats {
                scheme: r.scheme,
                ratio: r.ratio,
                repeats: n,
                dmd_frames: r.dmd_frames,
                acquisition_time_s: r.acquisition_time_s,
                psnr_db_mean,
                psnr_db_sd,
                mssim_mean,
                mssim_sd,
                saturated_repeats: outcomes.iter().filter(|o| o.results[i].saturated).count(),
            }
        })
        .collect();
    let index = |k: Scheme| s.schemes.iter().position(|&x| x == k);
    let mut paired = Vec::new();
    let scb = Scheme::SecondaryComplementaryBalancing;
    for other in [
        Scheme::SingleArmComplementary,
        Scheme::DoubleArmCalibrated,
        Scheme::DoubleArmOffset,
    ] {
        let (Some(a), Some(b)) = (index(scb), index(other)) else {
            continue;
        };
        for (r, &ratio) in s.sampling_ratios.iter().enumerate() {
            let (ia, ib) = (a * n_ratio + r, b * n_ratio + r);
            for (metric, f) in [
                (
                    "mssim",
                    (|r: &crate::pipeline::SchemeResult| r.mssim)
                        as fn(&crate::pipeline::SchemeResult) -> f64,
                ),
                ("psnr_db", |r: &crate::pipeline::SchemeResult| r.psnr_db),
            ] {
                let d: Vec<f64> = column(ia, f)
                    .iter()
                    .zip(column(ib, f))
                    .map(|(x, y)| x - y)
                    .collect();
                let (mean, sd) = mean_sd(&d);
                let ci95 = (n > 1).then(|| {
                    let h = t95(n - 1) * sd / (n as f64).sqrt();
                    [mean - h, mean + h]
                });
                paired.push(PairedDifference {
                    a: scb,
                    b: other,
                    ratio,
                    metric,
                    repeats: n,
                    mean,
                    sd,
                    ci95,
                });
            }
        }
    }
    Repeats {
        repeats: n,
        seeds: (0..n).map(|r| repeat_seed(seed, r)).collect(),
        stats,
        paired,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_sd_and_t_quantiles() {
        assert_eq!(mean_sd(&[2.0]), (2.0, 0.0));
        let (m, s) = mean_sd(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, 2.5);
        assert!((s - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(t95(1), 12.706);
        assert_eq!(t95(30), 2.042);
        // t(60) = 2.000, t(120) = 1.980 (standard tables).
        assert!((t95(60) - 2.000).abs() < 0.004);
        assert!((t95(120) - 1.980).abs() < 0.004);
    }

    #[test]
    fn repeat_zero_is_the_run_itself() {
        assert_eq!(repeat_seed(7, 0), 7);
        assert_ne!(repeat_seed(7, 1), 7);
        assert_ne!(repeat_seed(7, 1), repeat_seed(7, 2));
        let f = PatternFamily::Random { seed: 3 };
        assert_eq!(repeat_patterns(&f, 0), f);
        assert_ne!(repeat_patterns(&f, 1), f);
    }
}
