//! The record stage: the detector outputs in time for the DMD's frame sequences.

use rayon::prelude::*;
use serde::Serialize;

use super::{Progress, Stage, Traced};
use crate::acquisition::{
    AdditiveNoise, PackedPatterns, PatternSet, Sequence, schemes::CALIBRATION_PAIRS,
};
use crate::detector::{
    self, Bap, Channel, DriftPath, FrameTiming, Illumination, OUTPUT_NAMES, Record, Scope,
    SignalTrace,
};
use crate::error::Result;
use crate::rng;
use crate::scene::run::RunSettings;

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

/// The recorded sequences of an acquisition.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// The base patterns for the highest sampling ratio (lower ratios use their first rows).
    pub patterns: std::sync::Arc<PatternSet>,
    pub timing: FrameTiming,
    /// The oscilloscope channels as set for the pattern sequences [RF, MONITOR+, MONITOR−] (the
    /// calibrated acquisition, when there are others, is auto-ranged on its own).
    pub channels: [Channel; 3],
    /// One record per sequence that some scheme needs, in [`Sequence`] order.
    pub records: Vec<(Sequence, Record)>,
    pub sequences: Vec<SequenceSummary>,
    pub saturation: Vec<Saturation>,
}

impl Recorded {
    /// The record of a sequence.
    pub fn record(&self, q: Sequence) -> Option<&Record> {
        self.records.iter().find(|(s, _)| *s == q).map(|(_, r)| r)
    }

    /// The first frames of each record, sample by sample.
    pub fn traces(&self) -> Vec<(Sequence, SignalTrace)> {
        self.records
            .iter()
            .map(|(q, r)| (*q, r.trace.clone()))
            .collect()
    }
}

fn sequence_seed(seed: u64, s: Sequence) -> u64 {
    let index = match s {
        Sequence::Base => 0,
        Sequence::Complementary => 1,
        Sequence::CalibratedBase => 2,
    };
    rng::mix64(seed ^ rng::mix64(0x5EC0_0000 + index))
}

/// The record stage: records every sequence that `settings.schemes` read, for the patterns of
/// `patterns`, through the detector and oscilloscope, with the noise and drift drawn from
/// streams keyed by `seed`.
pub fn record_stage(
    traced: &Traced,
    detector: &Bap,
    scope: &Scope,
    settings: &RunSettings,
    patterns: &PackedPatterns,
    seed: u64,
    progress: Progress,
) -> Result<Recorded> {
    record_transport(
        &traced.transport,
        detector,
        scope,
        settings,
        patterns,
        seed,
        progress,
    )
}

/// [`record_stage`] for a transport made any way (a trace, or an object kernel's product).
pub fn record_transport(
    transport: &crate::transport::Transport,
    detector: &Bap,
    scope: &Scope,
    settings: &RunSettings,
    patterns: &PackedPatterns,
    seed: u64,
    progress: Progress,
) -> Result<Recorded> {
    let s = settings;
    let prep = prepare(transport, detector, scope, s, patterns);
    let Prepared {
        timing,
        needed,
        lights,
        ideal,
        channels,
        seq_channels,
    } = &prep;
    let (timing, channels) = (*timing, *channels);
    let illum = illuminations(transport, lights);
    let total_frames: u64 = lights.iter().map(|l| l.len() as u64).sum();
    progress(Stage::Record, 0, total_frames);
    let records: Vec<Record> = needed
        .par_iter()
        .zip(illum.par_iter())
        .zip(seq_channels.par_iter())
        .map(|((&q, il), channels)| record_sequence(s, detector, channels, timing, il, seed, q))
        .collect();
    progress(Stage::Record, total_frames, total_frames);

    let mut sequences = Vec::new();
    let mut saturation = Vec::new();
    for (((&q, r), id), channels) in needed.iter().zip(&records).zip(ideal).zip(seq_channels) {
        let (summary, found) = summarize_sequence(detector, channels, timing, q, r, id);
        sequences.push(summary);
        saturation.extend(found);
    }
    Ok(Recorded {
        patterns: patterns.shared_set(),
        timing,
        channels,
        records: needed.iter().copied().zip(records).collect(),
        sequences,
        saturation,
    })
}

/// What every record of an acquisition is made from: the timing, the sequences some scheme
/// reads, the light of each frame, the noise-free outputs and the oscilloscope's channels.
struct Prepared {
    timing: FrameTiming,
    needed: Vec<Sequence>,
    lights: Vec<Vec<[f64; 2]>>,
    ideal: Vec<Vec<[f64; 3]>>,
    channels: [Channel; 3],
    seq_channels: Vec<[Channel; 3]>,
}

fn prepare(
    transport: &crate::transport::Transport,
    detector: &Bap,
    scope: &Scope,
    s: &RunSettings,
    patterns: &PackedPatterns,
) -> Prepared {
    let timing = FrameTiming {
        frame_s: 1.0 / s.dmd_rate_hz,
        settling_s: s.settling_time_s,
        sample_rate_hz: scope.sample_rate_hz,
    };
    let needed: Vec<Sequence> = Sequence::all()
        .into_iter()
        .filter(|q| s.schemes.iter().any(|k| k.sequence() == *q))
        .collect();
    let lights = frame_lights(transport, patterns, &needed);
    let ideal: Vec<Vec<[f64; 3]>> = illuminations(transport, &lights)
        .iter()
        .map(|il| detector::ideal_frames(detector, il))
        .collect();
    let (channels, seq_channels) = channel_settings(detector, scope, s.noise, &needed, &ideal);
    Prepared {
        timing,
        needed,
        lights,
        ideal,
        channels,
        seq_channels,
    }
}

fn illuminations<'a>(
    transport: &crate::transport::Transport,
    lights: &'a [Vec<[f64; 2]>],
) -> Vec<Illumination<'a>> {
    lights
        .iter()
        .map(|l| Illumination {
            light_a: l,
            ambient_a: transport.ambient_a,
            dark_a: transport.dark_a,
        })
        .collect()
}

/// Where a replayed record's samples go ([`replay_sequence`]).
pub trait SampleSink {
    /// Sample `n` (from the start of the sequence) of frame `frame`: the recorded volts of
    /// [RF, MONITOR+, MONITOR−].
    fn sample(&mut self, n: u64, frame: usize, v: &[f64; 3]);
}

/// What a replayed sequence is recorded with, known before its first sample.
#[derive(Debug, Clone, Copy)]
pub struct ReplaySetup {
    pub timing: FrameTiming,
    /// The sequence's oscilloscope channels [RF, MONITOR+, MONITOR−].
    pub channels: [Channel; 3],
    pub frames: usize,
    /// Samples per channel.
    pub samples: u64,
}

/// One sequence of [`record_transport`] recorded again, sample by sample, every recorded sample
/// handed in time order (its index, its frame, the volts of [RF, MONITOR+, MONITOR−]) to the
/// sink that `open` makes from the sequence's setup: the same record, bit for bit, as the record
/// stage made with the same arguments. Returns the record and the sink; None when no scheme of
/// `settings` reads `q`. Only the sample-by-sample model has samples to hand over, and the
/// paper's additive noise is added to frame values, not to samples: both are refused.
#[allow(clippy::too_many_arguments)]
pub fn replay_sequence<S, O>(
    transport: &crate::transport::Transport,
    detector: &Bap,
    scope: &Scope,
    settings: &RunSettings,
    patterns: &PackedPatterns,
    seed: u64,
    q: Sequence,
    open: O,
) -> Result<Option<(Record, S)>>
where
    S: SampleSink,
    O: FnOnce(&ReplaySetup) -> Result<S>,
{
    if settings.record != detector::RecordModel::Samples {
        return Err(crate::Error::field(
            "run.record",
            "a scope record needs the sample-by-sample record model",
        ));
    }
    if settings.additive_noise.is_some() {
        return Err(crate::Error::field(
            "run.additive_noise",
            "a scope record holds samples, and the paper's additive noise is added to frame \
             values: leave it out to write one",
        ));
    }
    let prep = prepare(transport, detector, scope, settings, patterns);
    let Some(i) = prep.needed.iter().position(|&n| n == q) else {
        return Ok(None);
    };
    let il = &illuminations(transport, &prep.lights)[i];
    let channels = prep.seq_channels[i];
    let frames = il.light_a.len();
    let mut sink = open(&ReplaySetup {
        timing: prep.timing,
        channels,
        frames,
        samples: detector::frame_start_sample(prep.timing, frames, frames),
    })?;
    let q_seed = sequence_seed(seed, q);
    let drift = sequence_drift(settings, il, prep.timing, q_seed);
    let r = detector::record_observed(
        detector,
        &channels,
        prep.timing,
        il,
        &drift,
        q_seed,
        settings.noise,
        settings.signal_trace_frames,
        |n, f, v: &[f64; 3]| sink.sample(n, f, v),
    );
    Ok(Some((r, sink)))
}

fn sequence_drift(
    s: &RunSettings,
    il: &Illumination,
    timing: FrameTiming,
    q_seed: u64,
) -> DriftPath {
    if s.noise {
        DriftPath::draw(&s.drift, il.light_a.len(), timing.frame_s, q_seed)
    } else {
        DriftPath::flat(il.light_a.len(), timing.frame_s)
    }
}

/// The light on each diode, frame by frame, of each sequence in `needed`.
fn frame_lights(
    transport: &crate::transport::Transport,
    patterns: &PackedPatterns,
    needed: &[Sequence],
) -> Vec<Vec<[f64; 2]>> {
    // The pattern products are shared by every sequence (one packed product per record, with
    // the operator built once per pattern set).
    let products = transport.pattern_products_of(patterns.product());
    let units = patterns.set().units();
    needed
        .iter()
        .map(|&q| match q {
            Sequence::Base => transport.frame_currents_of(&products, false),
            Sequence::Complementary => transport.frame_currents_of(&products, true),
            Sequence::CalibratedBase => {
                // All-on frames shown as complementary pairs give (all on, all off).
                let on =
                    crate::reconstruction::BitMatrix::from_fn(CALIBRATION_PAIRS, units, |_, _| {
                        true
                    });
                let mut l = transport.frame_currents(&on, CALIBRATION_PAIRS, true);
                l.extend(transport.frame_currents_of(&products, false));
                l
            }
        })
        .collect()
}

/// The oscilloscope's channels: those shared by the pattern sequences, and each sequence's.
///
/// Channel ranges come from the clipped noise-free outputs of the recorded frames. The pattern
/// sequences share one setting of the oscilloscope; the calibrated acquisition is set up on its
/// own (its all-on frames need a wider range than any pattern), so adding it changes nothing
/// for the others.
fn channel_settings(
    detector: &Bap,
    scope: &Scope,
    noise: bool,
    needed: &[Sequence],
    ideal: &[Vec<[f64; 3]>],
) -> ([Channel; 3], Vec<[Channel; 3]>) {
    let range = |frames: &mut dyn Iterator<Item = &[f64; 3]>| -> [Channel; 3] {
        let frames: Vec<&[f64; 3]> = frames.collect();
        [0, 1, 2].map(|o| {
            let st = detector.stage(o);
            let (lo, hi) = frames
                .iter()
                .map(|v| st.clip(v[o]))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                });
            scope.channel(o, lo, hi, !noise)
        })
    };
    let patterns_only = needed.iter().any(|&q| q != Sequence::CalibratedBase);
    let shared = range(
        &mut needed
            .iter()
            .zip(ideal)
            .filter(|(q, _)| !patterns_only || **q != Sequence::CalibratedBase)
            .flat_map(|(_, f)| f.iter()),
    );
    let per_sequence = needed
        .iter()
        .zip(ideal)
        .map(|(&q, f)| match q {
            Sequence::CalibratedBase if patterns_only => range(&mut f.iter()),
            _ => shared,
        })
        .collect();
    (shared, per_sequence)
}

/// One sequence recorded through the detector and oscilloscope, with its drift and noise drawn
/// from the streams of the sequence's seed.
fn record_sequence(
    s: &RunSettings,
    detector: &Bap,
    channels: &[Channel; 3],
    timing: FrameTiming,
    il: &Illumination,
    seed: u64,
    q: Sequence,
) -> Record {
    let q_seed = sequence_seed(seed, q);
    let drift = sequence_drift(s, il, timing, q_seed);
    let mut r = detector::record_with(
        s.record,
        detector,
        channels,
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
}

/// What one recorded sequence holds, and its clipping and over-range findings.
fn summarize_sequence(
    detector: &Bap,
    channels: &[Channel; 3],
    timing: FrameTiming,
    q: Sequence,
    r: &Record,
    ideal: &[[f64; 3]],
) -> (SequenceSummary, Vec<Saturation>) {
    let frames = r.frames.len();
    let peak = [0, 1, 2].map(|o| ideal.iter().map(|v| v[o].abs()).fold(0.0, f64::max));
    let clipped = [0, 1, 2].map(|o| r.clipped_frames(o, frames));
    let over = [0, 1, 2].map(|o| r.over_range_frames(o, frames));
    let mut saturation = Vec::new();
    for o in 0..3 {
        let swing = detector.stage(o).swing_v;
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
    let summary = SequenceSummary {
        sequence: q,
        frames,
        duration_s: frames as f64 * timing.frame_s,
        scope_samples: r.samples,
        settled_samples_per_frame: r.settled_samples,
        clipped_frames: clipped,
        over_range_frames: over,
        peak_abs_ideal_v: peak,
    };
    (summary, saturation)
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
