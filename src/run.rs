//! The whole traced experiment of the paper's §4 as one library function ([`run`]): the stages
//! of [`crate::pipeline`] composed — trace the bench, record the detector outputs in time for
//! the DMD's frame sequences, form the four schemes' measurements, reconstruct with TVAL3 and
//! score against the ideal object. No files are touched here; `cli::run` writes the outputs and
//! the report reads [`RunOutcome`]. See crate::pipeline for the sequences, the scores and
//! determinism.

use std::time::Instant;

use crate::acquisition::{Scheme, patterns_for_ratio};
use crate::detector::{Bap, Channel, FrameTiming, Scope, SignalTrace};
use crate::error::Result;
use crate::pipeline::{self, CacheStatus, TraceRequest, Traced};
use crate::raster::Raster;
use crate::reconstruction::{Solver, ZeroOneHandling};
use crate::scene::run::RunScene;
use crate::transport::Transport;

pub use crate::acquisition::Sequence;
pub use crate::pipeline::{
    MIN_REGISTRATION_CORRELATION, Progress, ResolutionContext, Resolved, Saturation, SchemeResult,
    SequenceSummary, Stage, Timings,
};
pub use crate::scene::run::RunSettings;

/// Everything a report needs from a run.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    pub seed: u64,
    pub settings: RunSettings,
    pub transport: Transport,
    /// Lamp rays whose path reached the pattern area.
    pub trace_arrivals: u64,
    pub detector: Bap,
    pub scope: Scope,
    /// The oscilloscope channels as set for the run [RF, MONITOR+, MONITOR−].
    pub channels: [Channel; 3],
    pub timing: FrameTiming,
    /// Ideal object: x_j (W) and its 0–255 view (255·x / max x), units_across × units_down.
    pub x: Raster,
    pub truth: Raster,
    /// Scheme-major, ratio-minor, in the settings' order.
    pub results: Vec<SchemeResult>,
    /// The USAF resolution read-out's registration (None without a registrable USAF chart).
    pub resolution: Option<ResolutionContext>,
    /// The recorded sequences (those some scheme needed).
    pub sequences: Vec<SequenceSummary>,
    /// The first frames of each recorded sequence, sample by sample.
    pub traces: Vec<(Sequence, SignalTrace)>,
    pub saturation: Vec<Saturation>,
    pub timings: Timings,
    /// What the trace cache did.
    pub cache: CacheStatus,
    /// The bench's metrics with standard errors (crate::transport::metrics).
    pub metrics: crate::transport::metrics::BenchMetrics,
}

impl RunOutcome {
    /// The result of `scheme` at ratio index `r`.
    pub fn result(&self, scheme: Scheme, r: usize) -> Option<&SchemeResult> {
        let s = self.settings.schemes.iter().position(|&x| x == scheme)?;
        self.results
            .get(s * self.settings.sampling_ratios.len() + r)
    }
}

/// Runs the pipeline on a scene with `seed` (the trace, the noise and the drift; the patterns
/// have their own seed in the scene). `trace` is how to trace (rays, progress bar, cache; its
/// seed is `seed`); `progress` reports the later stages.
pub fn run(
    scene: &RunScene,
    seed: u64,
    trace: &TraceRequest,
    progress: Progress,
) -> Result<RunOutcome> {
    let t_all = Instant::now();
    let s = &scene.settings;
    let (across, down) = scene.bench.units_shape();
    let n = across * down;
    // Patterns first: a bad pattern setting should fail before the long trace.
    let max_m = s
        .sampling_ratios
        .iter()
        .map(|&r| patterns_for_ratio(r, n))
        .max()
        .unwrap_or(1);
    let patterns = s.patterns.build(across, down, max_m)?;

    let t0 = Instant::now();
    let traced = pipeline::trace_stage(&scene.bench, &TraceRequest { seed, ..*trace })?;
    let trace_s = t0.elapsed().as_secs_f64();
    let mut outcome = downstream(scene, &traced, &patterns, seed, progress)?;
    outcome.timings.trace_s = trace_s;
    outcome.timings.total_s = t_all.elapsed().as_secs_f64();
    Ok(outcome)
}

/// Everything after the trace: record, solve and score a traced bench (a cached trace, or one
/// point of a sweep). `patterns` holds the base patterns for the highest ratio.
pub fn downstream(
    scene: &RunScene,
    traced: &Traced,
    patterns: &crate::acquisition::PatternSet,
    seed: u64,
    progress: Progress,
) -> Result<RunOutcome> {
    let s = &scene.settings;
    let x = traced.x()?;
    let truth = traced.truth()?;
    let t1 = Instant::now();
    let recorded = pipeline::record_stage(
        traced,
        &scene.detector,
        &scene.scope,
        s,
        patterns,
        seed,
        progress,
    )?;
    let record_s = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let resolution = pipeline::resolution_context(&scene.bench, &x)?;
    let results = pipeline::solve_stage(
        &recorded,
        &s.schemes,
        &s.sampling_ratios,
        &truth,
        // The paper's plain handling of traditional CS's 0/1 patterns: `run` reproduces the
        // paper's set-up (the zero-mean remedy is `simulate`'s and `reconstruct`'s option).
        &Solver::new(s.solver.clone(), ZeroOneHandling::Plain),
        resolution.as_ref(),
        progress,
    )?;
    let solve_s = t2.elapsed().as_secs_f64();
    Ok(RunOutcome {
        seed,
        settings: s.clone(),
        trace_arrivals: traced.arrivals(),
        transport: traced.transport.clone(),
        detector: scene.detector.clone(),
        scope: scene.scope.clone(),
        channels: recorded.channels,
        timing: recorded.timing,
        x,
        truth,
        results,
        resolution,
        traces: recorded.traces(),
        sequences: recorded.sequences,
        saturation: recorded.saturation,
        timings: Timings {
            trace_s: 0.0,
            record_s,
            solve_s,
            total_s: record_s + solve_s,
        },
        cache: traced.cache.clone(),
        metrics: traced.metrics.clone(),
    })
}

pub mod repeats;
pub mod summary;

#[cfg(test)]
mod tests;
