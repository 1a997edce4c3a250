//! The whole traced experiment of the paper's §4 as one library function ([`run`]): trace the
//! bench, record the detector outputs in time for the DMD's frame sequences, form the four
//! schemes' measurements from the outputs the paper used, reconstruct with TVAL3 and score
//! against the ideal object. No files are touched here; `cli::run` writes the outputs and the
//! report integration reads [`RunOutcome`].
//!
//! # Sequences and schemes
//!
//! Two acquisitions are recorded, each with all three outputs on the oscilloscope:
//!
//! - the base sequence shows P₁, P₂, …, P_M (one frame per pattern);
//! - the complementary sequence shows P₁, 1 − P₁, P₂, 1 − P₂, … (a complementary pair back to
//!   back).
//!
//! | scheme | sequence | output | y_i |
//! |---|---|---|---|
//! | traditional CS | base | MONITOR+ | V₊(P_i), A = P |
//! | single-arm complementary | complementary | MONITOR+ | V₊(P_i) − V₊(1 − P_i), Â = 2P − 1 |
//! | double-arm dual-pixel | base | MONITOR+, MONITOR− | V₊(P_i) − V₋(P_i), Â |
//! | secondary complementary balancing | complementary | RF | V_rf(P_i) − V_rf(1 − P_i), Â |
//!
//! A lower sampling ratio uses the first M patterns of the set for the highest ratio and the
//! first M (or 2M) frames of each record, exactly what an acquisition stopped after M patterns
//! would have recorded. Frames and acquisition times are reported per scheme (M or 2M frames at
//! the DMD rate).
//!
//! # Light per frame
//!
//! From the transport (crate::transport): a frame showing pattern F gives the diodes the traced
//! light currents I₊ = Σ_j F_j·g₊_j + c₊ and I₋ = Σ_j (1 − F_j)·g₋_j + c₋, with c± the traced
//! pattern-independent light (ambient and dark currents are added by the detector, so that the
//! ambient drift and the responsivity mismatch act on the right terms).
//!
//! # Scores
//!
//! The ideal object is x_j, the power incident on unit j (W, from the trace), shown on 0–255 as
//! 255·x_j / max x. Every reconstruction is brought to that scale by the one rule of
//! [`crate::metrics`] (least-squares gain and offset, then a clip to [0, 255]) and scored with
//! PSNR and MSSIM.
//!
//! # Determinism
//!
//! The trace is deterministic for a seed (crate::trace); the two records run in parallel with
//! each other but each in time order with streams keyed by (seed, frame batch); the
//! reconstructions run in parallel and are collected in cell order. Only the timings differ
//! between runs.

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::acquisition::{self, AdditiveNoise, PatternSet, Scheme};
use crate::detector::{
    self, Bap, Channel, DriftPath, FrameTiming, Illumination, MONITOR_MINUS, MONITOR_PLUS,
    OUTPUT_NAMES, RF, Record, Scope, SignalTrace,
};
use crate::error::{Error, Result};
use crate::metrics;
use crate::metrics::resolution::{ChartToImage, ResolutionOptions, read_resolution};
use crate::objects::usaf::UsafChart;
use crate::raster::Raster;
use crate::reconstruction::{BitMatrix, PatternForm, tval3};
use crate::rng;
use crate::scene::experiment::PatternsSpec;
use crate::scene::run::RunScene;
use crate::simulation::patterns_for_ratio;
use crate::trace::{TraceOptions, trace};
use crate::transport::Transport;

/// The run settings in SI (from the `run` section of a scene, crate::scene::run).
#[derive(Debug, Clone, Serialize)]
pub struct RunSettings {
    pub title: String,
    pub rays: u64,
    pub sampling_ratios: Vec<f64>,
    pub schemes: Vec<Scheme>,
    #[serde(serialize_with = "patterns_text")]
    pub patterns: PatternsSpec,
    pub dmd_rate_hz: f64,
    pub settling_time_s: f64,
    pub drift: detector::Drift,
    pub noise: bool,
    pub additive_noise: Option<AdditiveNoise>,
    pub solver: tval3::Tval3Options,
    pub signal_trace_frames: usize,
}

fn patterns_text<S: serde::Serializer>(
    p: &PatternsSpec,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(&match p {
        PatternsSpec::Random { seed } => format!("random (seed {seed})"),
        PatternsSpec::Hadamard { ordering } => format!("hadamard ({})", ordering.label()),
    })
}

/// The two recorded frame sequences.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sequence {
    /// P₁, P₂, …
    Base,
    /// P₁, 1 − P₁, P₂, 1 − P₂, …
    Complementary,
}

impl Sequence {
    pub fn key(self) -> &'static str {
        match self {
            Sequence::Base => "base",
            Sequence::Complementary => "complementary",
        }
    }

    /// The sequence a scheme reads.
    pub fn of(scheme: Scheme) -> Sequence {
        match scheme {
            Scheme::Traditional | Scheme::DoubleArm => Sequence::Base,
            Scheme::SingleArmComplementary | Scheme::SecondaryComplementaryBalancing => {
                Sequence::Complementary
            }
        }
    }

    fn index(self) -> usize {
        match self {
            Sequence::Base => 0,
            Sequence::Complementary => 1,
        }
    }
}

/// The outputs a scheme reads (indices into [RF, MONITOR+, MONITOR−]).
pub fn outputs_of(scheme: Scheme) -> &'static [usize] {
    match scheme {
        Scheme::Traditional | Scheme::SingleArmComplementary => &[MONITOR_PLUS],
        Scheme::DoubleArm => &[MONITOR_PLUS, MONITOR_MINUS],
        Scheme::SecondaryComplementaryBalancing => &[RF],
    }
}

/// Stage of a run, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Record,
    Solve,
}

/// A resolved USAF element and its spatial frequency on the chart.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Resolved {
    pub group: i32,
    pub element: u8,
    pub lp_per_mm: f64,
}

/// How reconstructions of a USAF chart are read for resolution: the chart, the map from chart
/// millimetres to unit coordinates found by registering the ideal object x against the chart,
/// and what x itself resolves (the limit set by the optics and the unit size).
#[derive(Debug, Clone, Serialize)]
pub struct ResolutionContext {
    #[serde(skip)]
    pub chart: UsafChart,
    #[serde(skip)]
    pub map: ChartToImage,
    /// Chart mm → unit pixel coordinates: (col, row) = m·(x, y) + t.
    pub map_m: [[f64; 2]; 2],
    pub map_t: [f64; 2],
    /// Pearson correlation of x with the chart through `map` (the read-out is skipped below
    /// [`MIN_REGISTRATION_CORRELATION`]).
    pub registration_correlation: f64,
    pub criterion: &'static str,
    pub threshold: f64,
    /// What the ideal object x resolves.
    pub ideal_finest_resolved: Option<Resolved>,
}

/// Below this correlation the registration is not trusted and no resolution is reported.
pub const MIN_REGISTRATION_CORRELATION: f64 = 0.8;

/// Registers x against the bench's USAF chart (if it has one) for the resolution read-out.
///
/// Geometric guess: the chart point that the imaging lens puts on the pattern centre, taking
/// the paper's 1:1 imaging (m = −1) about the optical axis (the bench z axis), and one unit =
/// pitch · mirrors per unit on the chart. The registration then refines orientation, scale
/// (±12 %) and offset (±4 units) against x itself.
fn resolution_context(
    bench: &crate::optics::Bench,
    x: &Raster,
) -> Result<Option<ResolutionContext>> {
    let (Some(plate), Some(dmd)) = (bench.charts.first(), bench.dmd.as_ref()) else {
        return Ok(None);
    };
    let crate::optics::chart::ChartMask::Usaf(chart) = &plate.mask else {
        return Ok(None);
    };
    let d = &dmd.dmd;
    let pa = &d.pattern;
    let mpu = pa.mirrors_per_unit as f64;
    // Pattern centre on the DMD (m, bench frame: columns along +x, rows along −y).
    let dx =
        (pa.col0 as f64 + pa.units_across as f64 * mpu / 2.0 - d.columns as f64 / 2.0) * d.pitch;
    let dy = -(pa.row0 as f64 + pa.units_down as f64 * mpu / 2.0 - d.rows as f64 / 2.0) * d.pitch;
    let f = &plate.frame;
    if f.w.z.abs() < 1e-6 {
        return Ok(None);
    }
    // The chart point on the line through (−dx, −dy) parallel to the axis.
    let base = glam::DVec3::new(-dx, -dy, 0.0);
    let t = (f.origin - base).dot(f.w) / f.w.z;
    let local = f.to_local(base + glam::DVec3::new(0.0, 0.0, t));
    let center_mm = [local.x * 1e3, local.y * 1e3];
    let pixels_per_mm = 1.0 / (d.pitch * mpu * 1e3);
    let reg = metrics::registration::register_chart(x, chart, center_mm, pixels_per_mm, 4.0)?;
    if reg.correlation.is_nan() || reg.correlation < MIN_REGISTRATION_CORRELATION {
        return Ok(None);
    }
    let options = ResolutionOptions::default();
    let ideal = finest(x, chart, &reg.map, &options)?;
    Ok(Some(ResolutionContext {
        chart: chart.clone(),
        map: reg.map,
        map_m: reg.map.m,
        map_t: reg.map.t,
        registration_correlation: reg.correlation,
        criterion: metrics::resolution::CRITERION,
        threshold: options.threshold,
        ideal_finest_resolved: ideal,
    }))
}

/// The finest element resolved in `image`.
fn finest(
    image: &Raster,
    chart: &UsafChart,
    map: &ChartToImage,
    options: &ResolutionOptions,
) -> Result<Option<Resolved>> {
    let r = read_resolution(image, chart, map, options)?;
    Ok(r.finest_resolved.map(|e| Resolved {
        group: e.group,
        element: e.element,
        lp_per_mm: metrics::resolution::usaf_lp_per_mm(e.group, e.element),
    }))
}

/// One scheme at one sampling ratio.
#[derive(Debug, Clone, Serialize)]
pub struct SchemeResult {
    pub scheme: Scheme,
    /// Sampling ratio M/N as asked for, and M.
    pub ratio: f64,
    pub measurements: usize,
    /// DMD frames shown, values used for reconstruction (frames × outputs read), acquisition
    /// time at the DMD rate (s).
    pub dmd_frames: usize,
    pub detector_samples: usize,
    pub acquisition_time_s: f64,
    pub psnr_db: f64,
    pub mssim: f64,
    /// The normalisation (reconstruction → 0–255 truth scale).
    pub normalization_gain: f64,
    pub normalization_offset: f64,
    pub iterations: usize,
    pub converged: bool,
    pub relative_residual: f64,
    /// True when an output this scheme read was clipped at its swing, or its oscilloscope
    /// channel over range, in a frame it used: the result is not trustworthy.
    pub saturated: bool,
    /// Solver CPU time (s): a timing, different from run to run.
    pub solver_time_s: f64,
    /// The finest USAF element resolved in the reconstruction (metrics::resolution, both bar
    /// orientations above the Michelson-contrast threshold); None when the chart is not a USAF
    /// chart, could not be registered, or nothing is resolved.
    pub finest_resolved: Option<Resolved>,
    /// The reconstruction after normalisation, on the truth's 0–255 scale.
    #[serde(skip)]
    pub reconstruction: Raster,
}

/// What was recorded in one sequence.
#[derive(Debug, Clone, Serialize)]
pub struct SequenceSummary {
    pub sequence: Sequence,
    pub frames: usize,
    pub duration_s: f64,
    /// Oscilloscope samples per channel.
    pub scope_samples: u64,
    /// Samples averaged per frame (min, max).
    pub settled_samples_per_frame: (usize, usize),
    /// Per output [RF, MONITOR+, MONITOR−]: frames with a clipped output, frames over the
    /// oscilloscope range, and the largest |V| of the noise-free unclipped output.
    pub clipped_frames: [usize; 3],
    pub over_range_frames: [usize; 3],
    pub peak_abs_ideal_v: [f64; 3],
}

/// A saturation or over-range finding, also printed as a warning.
#[derive(Debug, Clone, Serialize)]
pub struct Saturation {
    pub sequence: Sequence,
    /// "rf", "monitor_plus" or "monitor_minus".
    pub output: &'static str,
    /// "detector_swing" (the output clipped) or "oscilloscope_range".
    pub kind: &'static str,
    pub frames: usize,
    pub of_frames: usize,
    pub limit_v: f64,
    pub peak_abs_ideal_v: f64,
    pub message: String,
}

/// Wall-clock timings (s); the only part of a run that changes between identical runs.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Timings {
    pub trace_s: f64,
    pub record_s: f64,
    pub solve_s: f64,
    pub total_s: f64,
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
    pub timings: Timings,
}

impl RunOutcome {
    /// The result of `scheme` at ratio index `r`.
    pub fn result(&self, scheme: Scheme, r: usize) -> Option<&SchemeResult> {
        let s = self.settings.schemes.iter().position(|&x| x == scheme)?;
        self.results
            .get(s * self.settings.sampling_ratios.len() + r)
    }
}

/// The traced light currents [I₊, I₋] (A, without ambient and dark) of the frames of a sequence
/// for the first `m` base patterns.
pub fn frame_light(
    transport: &Transport,
    patterns: &BitMatrix,
    m: usize,
    sequence: Sequence,
) -> Vec<[f64; 2]> {
    let op = crate::reconstruction::PackedOperator::new(patterns.head(m), PatternForm::ZeroOne);
    use crate::reconstruction::LinearOperator;
    let mut pg = [vec![0.0; m], vec![0.0; m]];
    for (g, out) in transport.g_a.iter().zip(pg.iter_mut()) {
        op.apply(g, out);
    }
    let total = [0, 1].map(|d| transport.g_a[d].iter().sum::<f64>());
    let c = [0, 1].map(|d| transport.c_traced[d].value);
    let mut out = Vec::with_capacity(match sequence {
        Sequence::Base => m,
        Sequence::Complementary => 2 * m,
    });
    for (p_plus, p_minus) in pg[0].iter().zip(&pg[1]) {
        // Pattern P_i: arm + sees P, arm − sees 1 − P.
        out.push([p_plus + c[0], (total[1] - p_minus) + c[1]]);
        if sequence == Sequence::Complementary {
            out.push([(total[0] - p_plus) + c[0], p_minus + c[1]]);
        }
    }
    out
}

/// The measurements of `scheme` for the first `m` patterns from the recorded frame values.
pub fn measurements(scheme: Scheme, frames: &[[f64; 3]], m: usize) -> Vec<f64> {
    (0..m)
        .map(|i| match scheme {
            Scheme::Traditional => frames[i][MONITOR_PLUS],
            Scheme::DoubleArm => frames[i][MONITOR_PLUS] - frames[i][MONITOR_MINUS],
            Scheme::SingleArmComplementary => {
                frames[2 * i][MONITOR_PLUS] - frames[2 * i + 1][MONITOR_PLUS]
            }
            Scheme::SecondaryComplementaryBalancing => frames[2 * i][RF] - frames[2 * i + 1][RF],
        })
        .collect()
}

fn sequence_seed(seed: u64, s: Sequence) -> u64 {
    rng::mix64(seed ^ rng::mix64(0x5EC0_0000 + s.index() as u64))
}

/// Runs the pipeline on a scene with `seed` (the trace, the noise and the drift; the patterns
/// have their own seed in the scene). `trace_progress` shows the tracer's bar on a terminal;
/// `progress(stage, done, total)` reports the later stages.
pub fn run(
    scene: &RunScene,
    seed: u64,
    trace_progress: bool,
    progress: &(dyn Fn(Stage, u64, u64) + Sync),
) -> Result<RunOutcome> {
    let t_all = Instant::now();
    let s = &scene.settings;
    let bench = &scene.bench;
    let (across, down) = bench.units_shape();
    let n = across * down;

    // Patterns first: a bad pattern setting should fail before the long trace.
    let max_m = s
        .sampling_ratios
        .iter()
        .map(|&r| patterns_for_ratio(r, n))
        .max()
        .unwrap_or(1);
    let full: PatternSet = match &s.patterns {
        PatternsSpec::Random { seed } => acquisition::random_set(across, down, max_m, *seed)?,
        PatternsSpec::Hadamard { ordering } => acquisition::hadamard_set(across, *ordering, max_m)?,
    };
    let bits = full.base_patterns().into_owned();

    let t0 = Instant::now();
    let tallies = trace(
        bench,
        &TraceOptions {
            progress: trace_progress,
            ..TraceOptions::new(s.rays, seed)
        },
    )?;
    let transport = Transport::from_tallies(bench, &tallies);
    let trace_s = t0.elapsed().as_secs_f64();
    let x = Raster::new(across, down, transport.x_w.clone())?;
    let x_max = x.max();
    if x_max.is_nan() || x_max <= 0.0 {
        return Err(Error::Numerical(format!(
            "no traced light reached the pattern area ({} rays): trace more rays or check the \
             bench's alignment",
            s.rays
        )));
    }
    let truth = x.map(|v| 255.0 * v / x_max);

    // ---- Record.
    let t1 = Instant::now();
    let timing = FrameTiming {
        frame_s: 1.0 / s.dmd_rate_hz,
        settling_s: s.settling_time_s,
        sample_rate_hz: scene.scope.sample_rate_hz,
    };
    let needed: Vec<Sequence> = [Sequence::Base, Sequence::Complementary]
        .into_iter()
        .filter(|q| s.schemes.iter().any(|&k| Sequence::of(k) == *q))
        .collect();
    let lights: Vec<Vec<[f64; 2]>> = needed
        .iter()
        .map(|&q| frame_light(&transport, &bits, max_m, q))
        .collect();
    let ambient_a = transport.ambient_a;
    let dark_a = transport.dark_a;
    let illum: Vec<Illumination> = lights
        .iter()
        .map(|l| Illumination {
            light_a: l,
            ambient_a,
            dark_a,
        })
        .collect();
    let ideal: Vec<Vec<[f64; 3]>> = illum
        .iter()
        .map(|il| detector::ideal_frames(&scene.detector, il))
        .collect();
    // Channel ranges from the clipped noise-free outputs of every recorded frame.
    let channels: [Channel; 3] = [0, 1, 2].map(|o| {
        let st = scene.detector.stage(o);
        let (lo, hi) = ideal
            .iter()
            .flatten()
            .map(|v| st.clip(v[o]))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        scene.scope.channel(o, lo, hi, !s.noise)
    });
    let total_frames: u64 = lights.iter().map(|l| l.len() as u64).sum();
    progress(Stage::Record, 0, total_frames);
    let records: Vec<Record> = needed
        .par_iter()
        .zip(illum.par_iter())
        .map(|(&q, il)| {
            let q_seed = sequence_seed(seed, q);
            let drift = if s.noise {
                DriftPath::draw(&s.drift, il.light_a.len(), timing.frame_s, q_seed)
            } else {
                DriftPath::flat(il.light_a.len(), timing.frame_s)
            };
            let mut r = detector::record(
                &scene.detector,
                &channels,
                timing,
                il,
                &drift,
                q_seed,
                s.noise,
                s.signal_trace_frames,
            );
            if let Some(noise) = &s.additive_noise {
                add_paper_noise(&mut r, noise, q_seed);
            }
            r
        })
        .collect();
    progress(Stage::Record, total_frames, total_frames);
    let record_s = t1.elapsed().as_secs_f64();

    let mut sequences = Vec::new();
    let mut saturation = Vec::new();
    for ((&q, r), id) in needed.iter().zip(&records).zip(&ideal) {
        let frames = r.frames.len();
        let peak = [0, 1, 2].map(|o| id.iter().map(|v| v[o].abs()).fold(0.0, f64::max));
        let clipped = [0, 1, 2].map(|o| r.clipped_frames(o, frames));
        let over = [0, 1, 2].map(|o| r.over_range_frames(o, frames));
        for o in 0..3 {
            let swing = scene.detector.stage(o).swing_v;
            if clipped[o] > 0 {
                saturation.push(Saturation {
                    sequence: q,
                    output: OUTPUT_NAMES[o],
                    kind: "detector_swing",
                    frames: clipped[o],
                    of_frames: frames,
                    limit_v: swing,
                    peak_abs_ideal_v: peak[o],
                    message: format!(
                        "{} output clipped at ±{swing} V in {} of {frames} frames of the {} \
                         sequence (noise-free peak |V| = {:.4} V): the light saturates the \
                         detector; results that read it are marked saturated",
                        OUTPUT_NAMES[o],
                        clipped[o],
                        q.key(),
                        peak[o]
                    ),
                });
            }
            if over[o] > 0 {
                let (lo, hi) = channels[o].window();
                saturation.push(Saturation {
                    sequence: q,
                    output: OUTPUT_NAMES[o],
                    kind: "oscilloscope_range",
                    frames: over[o],
                    of_frames: frames,
                    limit_v: hi.abs().max(lo.abs()),
                    peak_abs_ideal_v: peak[o],
                    message: format!(
                        "{} channel over the oscilloscope's range [{lo:.4}, {hi:.4}] V in {} of \
                         {frames} frames of the {} sequence; results that read it are marked \
                         saturated",
                        OUTPUT_NAMES[o],
                        over[o],
                        q.key()
                    ),
                });
            }
        }
        sequences.push(SequenceSummary {
            sequence: q,
            frames,
            duration_s: frames as f64 * timing.frame_s,
            scope_samples: r.samples,
            settled_samples_per_frame: r.settled_samples,
            clipped_frames: clipped,
            over_range_frames: over,
            peak_abs_ideal_v: peak,
        });
    }

    // ---- Reconstruct and score.
    let t2 = Instant::now();
    let resolution = resolution_context(&scene.bench, &x)?;
    let sets: Vec<PatternSet> = s
        .sampling_ratios
        .iter()
        .map(|&r| full.head(patterns_for_ratio(r, n)))
        .collect::<Result<_>>()?;
    let n_ratio = s.sampling_ratios.len();
    let total = s.schemes.len() * n_ratio;
    let done = std::sync::atomic::AtomicU64::new(0);
    progress(Stage::Solve, 0, total as u64);
    let results: Vec<SchemeResult> = (0..total)
        .into_par_iter()
        .map(|idx| {
            let scheme = s.schemes[idx / n_ratio];
            let r = idx % n_ratio;
            let set = &sets[r];
            let m = set.measurements();
            let q = Sequence::of(scheme);
            let k = needed.iter().position(|&x| x == q).expect("recorded");
            let rec = &records[k];
            let y = measurements(scheme, &rec.frames, m);
            let frames = scheme.dmd_frames(m);
            let saturated = outputs_of(scheme)
                .iter()
                .any(|&o| rec.clipped_frames(o, frames) + rec.over_range_frames(o, frames) > 0);
            let op = set.operator(scheme.form());
            let sol = tval3::tval3(op.as_ref(), &y, across, down, &s.solver)?;
            let norm = metrics::normalize_to_truth(&sol.image, &truth)?;
            let finest_resolved = match &resolution {
                Some(c) => finest(&norm.image, &c.chart, &c.map, &ResolutionOptions::default())?,
                None => None,
            };
            let out = SchemeResult {
                scheme,
                ratio: s.sampling_ratios[r],
                measurements: m,
                dmd_frames: frames,
                detector_samples: frames * outputs_of(scheme).len(),
                acquisition_time_s: frames as f64 * timing.frame_s,
                psnr_db: metrics::psnr(&truth, &norm.image, metrics::PEAK_255),
                mssim: metrics::mssim(&truth, &norm.image)?,
                normalization_gain: norm.gain,
                normalization_offset: norm.offset,
                iterations: sol.iterations,
                converged: sol.converged,
                relative_residual: sol.relative_residual,
                saturated,
                solver_time_s: sol.cpu_time_s,
                finest_resolved,
                reconstruction: norm.image,
            };
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(Stage::Solve, d, total as u64);
            Ok(out)
        })
        .collect::<Result<_>>()?;
    let solve_s = t2.elapsed().as_secs_f64();

    let traces = needed
        .iter()
        .zip(&records)
        .map(|(&q, r)| (q, r.trace.clone()))
        .collect();
    Ok(RunOutcome {
        seed,
        settings: s.clone(),
        trace_arrivals: tallies.arrivals,
        transport,
        detector: scene.detector.clone(),
        scope: scene.scope.clone(),
        channels,
        timing,
        x,
        truth,
        results,
        resolution,
        sequences,
        traces,
        saturation,
        timings: Timings {
            trace_s,
            record_s,
            solve_s,
            total_s: t_all.elapsed().as_secs_f64(),
        },
    })
}

/// The paper's idealised additive noise on every recorded frame value of every output: output
/// o of a sequence draws from the noise streams of seed mix64(sequence seed ⊕ o).
fn add_paper_noise(r: &mut Record, noise: &AdditiveNoise, seed: u64) {
    for o in 0..3 {
        let e = noise.samples(rng::mix64(seed ^ (0xADD0 + o as u64)), r.frames.len());
        for (f, e) in r.frames.iter_mut().zip(e) {
            f[o] += e;
        }
    }
}

#[cfg(test)]
mod tests;
