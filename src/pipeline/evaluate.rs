//! The evaluate step: one bench (or one traced transport, or one object through an object
//! kernel) in, its metrics, recorded measurements and, when asked, its solved and scored images
//! out. Every job composes it — `run` (one repeat or many), `sweep` (every grid point), `align`
//! (every simplex vertex), `tolerance` (the nominal bench, every sensitivity end and trial) and
//! `dataset` (every sample) — so the stages of [`crate::pipeline`] are chained in one place.
//!
//! - [`evaluate`]: a bench document → [`Evaluation`] (metrics with standard errors, the
//!   bench's CMRR with the optics and the detector's alone, arrivals; with `quality`, every scheme × ratio of the bench's `run:`
//!   settings recorded, solved and scored); [`evaluate_mapped`] the same trace with the diodes'
//!   irradiance maps, for where each arm's spot lands ([`Spot`], `align`'s centre objective);
//! - [`evaluate_traced`]: a traced bench of a [`RunScene`] → [`RunOutcome`], everything a run
//!   reports (records, solutions, scores, the USAF read-out);
//! - [`acquire`] and [`solve_scored`]: a transport made any way (an object kernel's product for
//!   a dataset sample) → its records, then its reconstructions scored against the ideal object.
//!
//! The ideal object's 0–255 view ([`truth_view`]) and the solver of the traced experiment
//! ([`run_solver`]) are defined here once.

use crate::acquisition::{PackedPatterns, PatternSet, Scheme, patterns_for_ratio};
use crate::detector::{Bap, Channel, FrameTiming, Scope, SignalTrace};
use crate::error::Result;
use crate::pipeline::{
    self, CacheStatus, Progress, Recorded, ResolutionContext, Saturation, SchemeResult,
    SequenceSummary, TraceRequest, Traced,
};
use crate::quantities::{BenchMetric, ImageScore, Quantity};
use crate::raster::Raster;
use crate::reconstruction::{Solver, ZeroOneHandling};
use crate::scene::doc::BenchDoc;
use crate::scene::run::{RunScene, RunSettings};
use crate::transport::Transport;
use crate::transport::metrics::{BenchMetrics, MetricRow, TracedValue};

pub use crate::acquisition::Sequence;

/// How to evaluate a bench.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvaluateOptions {
    pub rays: u64,
    pub seed: u64,
    /// Run the whole pipeline (record, solve, score) on the bench.
    pub quality: bool,
}

impl EvaluateOptions {
    /// The same rays and seed, with or without the image-quality stages.
    pub fn with_quality(&self, quality: bool) -> EvaluateOptions {
        EvaluateOptions { quality, ..*self }
    }
}

/// One evaluated bench: a point of a sweep, a vertex of an alignment, a trial of a tolerance
/// analysis.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// The variables set on the nominal bench (empty for the nominal bench itself).
    pub settings: Vec<(String, f64)>,
    pub metrics: BenchMetrics,
    /// The bench's common-mode rejection (dB) with the arms' k± in it
    /// ([`crate::transport::metrics::cmrr_db`]), with its Monte Carlo influence; None when the
    /// electronics are invalid.
    pub cmrr: Option<TracedValue>,
    /// The detector's common-mode rejection from its electronics alone (dB, not traced;
    /// infinite for matched diodes); None when the electronics are invalid.
    pub cmrr_electronics_db: Option<f64>,
    /// The diodes' responsivity scales s± of the bench's electronics [+, −]; None when the
    /// electronics are invalid.
    pub responsivity_scale: Option<[f64; 2]>,
    pub arrivals: u64,
    /// With `quality`: every scheme × ratio of the bench's `run` settings.
    pub quality: Option<Vec<SchemeResult>>,
    /// From [`evaluate_mapped`]: where the light lands on each diode (+, −), from the
    /// irradiance maps of the same trace; None from [`evaluate`].
    pub spots: Option<[Spot; 2]>,
}

impl Evaluation {
    /// The electrical imbalance ι′ = (s₊k₊ − s₋k₋)/(s₊k₊ + s₋k₋), the optical imbalance as the
    /// balanced detector's difference output sees it through the bench's own responsivity
    /// scales ([`crate::transport::metrics::electrical_imbalance`], its influence carried by
    /// the delta method); None when the electronics are invalid.
    pub fn electrical_imbalance(&self) -> Option<TracedValue> {
        self.responsivity_scale.map(|s| {
            crate::transport::metrics::electrical_imbalance(
                &self.metrics[BenchMetric::Imbalance],
                s,
            )
        })
    }
}

/// Where the light of one diode's own arm lands on it: its collected spot, the pattern light
/// on its active area with every unit in its state (+ for the + diode, − for the − diode;
/// [`crate::pipeline::optimise::spot`]), and its centre margin
/// ([`crate::pipeline::optimise::centre_margin_m`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spot {
    /// Centroid (with its standard error) and RMS radius of the light on the active area, and
    /// the share of the state's pattern light on the housing's plate, in the diode's (u, v)
    /// axes from the active area's centre.
    pub stats: crate::trace::irradiance::MapStats,
    pub active_radius_m: f64,
    /// The centroid's distance from the active area's centre (m) and its standard error.
    pub offset_m: f64,
    pub offset_stderr_m: f64,
    /// Active radius − (offset + k·RMS radius) (m; −∞ when no light was mapped) and its
    /// standard error.
    pub margin_m: f64,
    pub margin_stderr_m: f64,
}

/// Traces one bench (and with `quality` runs the whole pipeline on it). `settings` are only
/// recorded in the result: `doc` already has them applied.
pub fn evaluate(
    doc: &BenchDoc,
    settings: Vec<(String, f64)>,
    o: &EvaluateOptions,
) -> Result<Evaluation> {
    let req = TraceRequest::new(o.rays, o.seed);
    let quiet: Progress = &|_, _, _| {};
    let (traced, quality) = if o.quality {
        let scene = doc.run_scene()?;
        let traced = pipeline::trace_stage(&scene.bench, &req)?;
        let patterns = base_patterns(&scene.settings.patterns, &scene)?;
        let outcome = evaluate_traced(&scene, &traced, &patterns, o.seed, quiet)?;
        (traced, Some(outcome.results))
    } else {
        let bench = doc.build()?;
        (pipeline::trace_stage(&bench, &req)?, None)
    };
    Ok(evaluation_of(doc, settings, &traced, quality))
}

/// [`evaluate`] without the quality stages, traced with the diodes' irradiance maps
/// ([`crate::trace::irradiance::trace_with_maps`], the same paths and tallies as the plain
/// trace): the evaluation carries each diode's [`Spot`].
pub fn evaluate_mapped(
    doc: &BenchDoc,
    settings: Vec<(String, f64)>,
    o: &EvaluateOptions,
) -> Result<Evaluation> {
    use crate::trace::irradiance::{DEFAULT_BINS, trace_with_maps};
    let bench = doc.build()?;
    let options = crate::trace::TraceOptions::new(o.rays, o.seed);
    let (tallies, maps) = trace_with_maps(&bench, &options, DEFAULT_BINS)?;
    let traced = Traced::from_tallies(&bench, tallies, CacheStatus::Off);
    let mut e = evaluation_of(doc, settings, &traced, None);
    e.spots = Some(std::array::from_fn(|d| {
        crate::pipeline::optimise::spot(&maps, d, crate::pipeline::optimise::CENTRE_RMS_RADII)
    }));
    Ok(e)
}

/// The evaluation of a bench already traced (`traced` from `doc`): its metrics, the bench's
/// CMRR with the arms' k± in it, the electronics' CMRR alone, the arrivals and the given
/// quality scores. [`evaluate`] is this after its trace; a caller that keeps the trace (the
/// Python package, for its maps) calls it directly.
pub fn evaluation_of(
    doc: &BenchDoc,
    settings: Vec<(String, f64)>,
    traced: &Traced,
    quality: Option<Vec<SchemeResult>>,
) -> Evaluation {
    // The electronics alone (no bench build): the diodes' responsivity scales.
    let detector = crate::scene::run::detector_si(&doc.file.electronics.detector).ok();
    let cmrr = detector.as_ref().map(|d| {
        crate::transport::metrics::cmrr_db(
            &traced.metrics[BenchMetric::Imbalance],
            d.responsivity_scale,
        )
    });
    Evaluation {
        settings,
        cmrr,
        responsivity_scale: detector.as_ref().map(|d| d.responsivity_scale),
        cmrr_electronics_db: detector.map(|d| d.cmrr_db()),
        arrivals: traced.arrivals(),
        metrics: traced.metrics.clone(),
        quality,
        spots: None,
    }
}

/// `SCHEME_PERCENT`, e.g. `secondary_complementary_balancing_40`.
pub fn quality_key(scheme: &str, ratio: f64) -> String {
    format!("{scheme}_{}", (ratio * 100.0).round() as u32)
}

/// The recorded numbers of an evaluated bench against the nominal one: each metric, its
/// standard error, its difference from the nominal bench and the paired standard error of that
/// difference; the CMRR; with `quality`, each scheme × ratio's MSSIM, PSNR and finest resolved
/// USAF element (lp/mm; NaN when none is resolved).
pub fn values(p: &Evaluation, nominal: &Evaluation) -> Vec<(String, f64)> {
    let mut v = Vec::new();
    for (m, value) in p.metrics.iter() {
        let name = m.key();
        let r = MetricRow::new(value, &nominal.metrics[m]);
        v.push((name.to_string(), r.value));
        v.push((format!("{name}_stderr"), r.stderr));
        v.push((format!("{name}_diff"), r.diff));
        v.push((format!("{name}_diff_stderr"), r.diff_stderr));
    }
    let nan = MetricRow {
        value: f64::NAN,
        stderr: f64::NAN,
        diff: f64::NAN,
        diff_stderr: f64::NAN,
    };
    let c = match (&p.cmrr, &nominal.cmrr) {
        (Some(c), Some(c0)) => {
            let mut r = MetricRow::new(c, c0);
            if c.value == c0.value {
                // Both infinite (matched arms and diodes) or the same bench: no change.
                (r.diff, r.diff_stderr) = (0.0, 0.0);
            }
            r
        }
        (Some(c), None) => MetricRow {
            value: c.value,
            stderr: c.stderr(),
            ..nan
        },
        _ => nan,
    };
    let cmrr = Quantity::Cmrr;
    v.push((cmrr.to_string(), c.value));
    v.push((format!("{cmrr}_stderr"), c.stderr));
    v.push((format!("{cmrr}_diff"), c.diff));
    v.push((format!("{cmrr}_diff_stderr"), c.diff_stderr));
    v.push((
        Quantity::CmrrElectronics.to_string(),
        p.cmrr_electronics_db.unwrap_or(f64::NAN),
    ));
    v.push(("arrivals".into(), p.arrivals as f64));
    if let Some(q) = &p.quality {
        for r in q {
            let key = quality_key(r.scheme.key(), r.ratio);
            for score in ImageScore::ALL {
                let x = match score {
                    ImageScore::Mssim => r.mssim,
                    ImageScore::PsnrDb => r.psnr_db,
                    ImageScore::FinestLpPerMm => {
                        r.finest_resolved.as_ref().map_or(f64::NAN, |e| e.lp_per_mm)
                    }
                };
                let q = Quantity::Score {
                    key: key.clone(),
                    score,
                };
                v.push((q.to_string(), x));
            }
        }
    }
    v
}

/// The base patterns of `family` for the highest sampling ratio of the scene's settings (a lower
/// ratio uses their first rows). Built before any trace, so a bad pattern setting fails first.
pub fn base_patterns(
    family: &crate::acquisition::PatternFamily,
    scene: &RunScene,
) -> Result<PatternSet> {
    let (across, down) = scene.bench.units_shape();
    let max_m = scene
        .settings
        .sampling_ratios
        .iter()
        .map(|&r| patterns_for_ratio(r, across * down))
        .max()
        .unwrap_or(1);
    family.build(across, down, max_m)
}

/// The solver of the traced experiment: the scene's TVAL3 settings with the paper's plain
/// handling of traditional CS's 0/1 patterns (`run` reproduces the paper's set-up; the
/// zero-mean remedy is `simulate`'s and `reconstruct`'s option).
pub fn run_solver(settings: &RunSettings) -> Solver {
    Solver::new(settings.solver.clone(), ZeroOneHandling::Plain)
}

/// The ideal object x (W per unit) shown on 0–255 as 255·x / max x, the scale every
/// reconstruction is scored on; None when no light reached the pattern area.
pub fn truth_view(x: &Raster) -> Option<Raster> {
    let x_max = x.max();
    if x_max.is_nan() || x_max <= 0.0 {
        return None;
    }
    Some(x.map(|v| 255.0 * v / x_max))
}

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
    pub timings: pipeline::Timings,
    /// What the trace cache did.
    pub cache: CacheStatus,
    /// The bench's metrics with standard errors (crate::transport::metrics).
    pub metrics: BenchMetrics,
}

impl RunOutcome {
    /// The bench's common-mode rejection with the arms' k± in it (dB, with its influence):
    /// [`crate::transport::metrics::cmrr_db`] of the traced imbalance and the diodes' mismatch.
    pub fn cmrr(&self) -> TracedValue {
        crate::transport::metrics::cmrr_db(
            &self.metrics[BenchMetric::Imbalance],
            self.detector.responsivity_scale,
        )
    }

    /// The result of `scheme` at ratio index `r`.
    pub fn result(&self, scheme: Scheme, r: usize) -> Option<&SchemeResult> {
        let s = self.settings.schemes.iter().position(|&x| x == scheme)?;
        self.results
            .get(s * self.settings.sampling_ratios.len() + r)
    }
}

/// What every acquisition of one traced bench shares, whatever its noise: the ideal object,
/// its 0–255 view and the USAF chart's registration (a search over the chart's placement that
/// costs as much as a record stage). Made once per trace ([`Shared::of`]), so that the repeats
/// of a run pay only for their own record and solve.
#[derive(Debug, Clone)]
pub struct Shared {
    pub x: Raster,
    pub truth: Raster,
    pub resolution: Option<ResolutionContext>,
}

impl Shared {
    /// The shared inputs of a traced bench of `scene`.
    pub fn of(scene: &RunScene, traced: &Traced) -> Result<Shared> {
        let x = traced.x()?;
        let truth = traced.truth()?;
        let resolution = pipeline::resolution_context(&scene.bench, &x)?;
        Ok(Shared {
            x,
            truth,
            resolution,
        })
    }
}

/// Everything after the trace: record, solve and score a traced bench (a fresh or cached trace,
/// one point of a sweep, one repeat of a run). `patterns` holds the base patterns for the
/// highest ratio ([`base_patterns`]).
pub fn evaluate_traced(
    scene: &RunScene,
    traced: &Traced,
    patterns: &PatternSet,
    seed: u64,
    progress: Progress,
) -> Result<RunOutcome> {
    let t0 = std::time::Instant::now();
    let shared = Shared::of(scene, traced)?;
    let shared_s = t0.elapsed().as_secs_f64();
    let packed = PackedPatterns::new(patterns.clone());
    let mut o = evaluate_shared(scene, traced, &shared, &packed, seed, progress)?;
    o.timings.solve_s += shared_s;
    o.timings.total_s += shared_s;
    Ok(o)
}

/// [`evaluate_traced`] with the trace's [`Shared`] inputs and the packed patterns made by the
/// caller (once for every repeat that reads the same patterns).
pub fn evaluate_shared(
    scene: &RunScene,
    traced: &Traced,
    shared: &Shared,
    packed: &PackedPatterns,
    seed: u64,
    progress: Progress,
) -> Result<RunOutcome> {
    let s = &scene.settings;
    let t1 = std::time::Instant::now();
    let recorded = acquire(scene, &traced.transport, packed, seed, progress)?;
    let record_s = t1.elapsed().as_secs_f64();
    let t2 = std::time::Instant::now();
    let results = solve_scored(
        s,
        &recorded,
        &s.schemes,
        &s.sampling_ratios,
        &shared.truth,
        shared.resolution.as_ref(),
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
        x: shared.x.clone(),
        truth: shared.truth.clone(),
        results,
        resolution: shared.resolution.clone(),
        traces: recorded.traces(),
        sequences: recorded.sequences,
        saturation: recorded.saturation,
        timings: pipeline::Timings {
            trace_s: 0.0,
            record_s,
            solve_s,
            total_s: record_s + solve_s,
        },
        cache: traced.cache.clone(),
        metrics: traced.metrics.clone(),
    })
}

/// The record stage for a transport made any way (a trace, or an object kernel's product): the
/// scene's electronics and acquisition settings, the noise and drift keyed by `seed`.
pub fn acquire(
    scene: &RunScene,
    transport: &Transport,
    patterns: &PackedPatterns,
    seed: u64,
    progress: Progress,
) -> Result<Recorded> {
    pipeline::record_transport(
        transport,
        &scene.detector,
        &scene.scope,
        &scene.settings,
        patterns,
        seed,
        progress,
    )
}

/// Each scheme × ratio (scheme-major) of a record solved with the traced experiment's solver
/// ([`run_solver`]) and scored against `truth` (the ideal object's [`truth_view`]); the USAF
/// read-out when `resolution` is given.
pub fn solve_scored(
    settings: &RunSettings,
    recorded: &Recorded,
    schemes: &[Scheme],
    ratios: &[f64],
    truth: &Raster,
    resolution: Option<&ResolutionContext>,
    progress: Progress,
) -> Result<Vec<SchemeResult>> {
    pipeline::solve_stage(
        recorded,
        schemes,
        ratios,
        truth,
        &run_solver(settings),
        resolution,
        progress,
    )
}
