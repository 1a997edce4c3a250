//! One acquisition in time: the DMD shows a sequence of frames, the diodes' currents follow the
//! traced transport of each frame's pattern times the drift factors, the three outputs filter
//! and clip them, and the oscilloscope samples, adds its noise, digitises, and each frame's value
//! is the mean of the samples in its settled window.
//!
//! Timing. Frame f occupies [f·T, (f+1)·T), T = 1/rate. The oscilloscope samples freely at
//! t_n = n/fs (its clock is not locked to the DMD). The mirrors are taken to switch at the
//! frame start; the first `settling_s` of each frame are excluded from its mean (the mirrors
//! ring there; that motion is not modelled because those samples are discarded). Samples at
//! t ≥ f·T + settling_s belong to frame f's settled window.
//!
//! Outputs. Each output is a single pole of bandwidth B sampled every dt = 1/fs. The signal
//! part, piecewise constant over a sample interval, is filtered exactly (zero-order hold):
//! v ← a·v + (1 − a)·x with a = e^{−2πB·dt}. The noise part is white current noise of one-sided
//! density S (shot noise 2qI and amplifier i_n², [`super::Bap::input_noise_psd`]) through the
//! same pole: an Ornstein–Uhlenbeck process of stationary variance G²·S·πB/2, advanced exactly
//! with increments of variance G²·S·(πB/2)·(1 − a²). The shot noise of diode d is one draw per
//! sample shared by the RF output and MONITOR d (exact when their bandwidths are equal); each
//! amplifier adds its own independent draw. Then the output is clipped at its swing, the
//! oscilloscope adds its input noise and digitises ([`super::scope::Channel::digitise`]).
//!
//! Determinism: samples are produced in time order in one pass; frame f's draws come from
//! `rng::stream(seed, f / FRAMES_PER_BATCH)`, so the record is the same on any number of threads
//! (acquisitions run in parallel with each other, never split).

use serde::Serialize;

use super::bap::{Bap, MONITOR_PLUS, RF};
use super::drift::DriftPath;
use super::frames::{BOUNDARY_EPS, FrameMeans, SettleRule};
use super::scope::Channel;
use crate::rng;

/// Frames per random stream.
pub const FRAMES_PER_BATCH: usize = 64;

/// Stream index of the filters' initial noise (beyond any frame batch and the drift stream).
pub const INITIAL_STATE_STREAM: u64 = super::drift::DRIFT_STREAM + 1;

/// Frame timing of a sequence (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameTiming {
    /// 1 / DMD rate.
    pub frame_s: f64,
    /// Excluded start of each frame.
    pub settling_s: f64,
    /// Oscilloscope sample rate (Hz).
    pub sample_rate_hz: f64,
}

/// What the diodes see over a sequence.
#[derive(Debug, Clone, Copy)]
pub struct Illumination<'a> {
    /// Traced light current [diode +, diode −] of every frame (A): pattern-dependent light plus
    /// the traced pattern-independent light (c± without ambient and dark).
    pub light_a: &'a [[f64; 2]],
    /// Ambient current of each diode (A), multiplied by the ambient factor.
    pub ambient_a: [f64; 2],
    /// Dark current of each diode (A).
    pub dark_a: [f64; 2],
}

/// Sampled signals of the first frames of a sequence: what the oscilloscope recorded.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignalTrace {
    /// Sample times (s) from the start of the sequence.
    pub t_s: Vec<f64>,
    /// Recorded volts of [RF, MONITOR+, MONITOR−] at those times.
    pub v: [Vec<f64>; 3],
    /// Frames covered.
    pub frames: usize,
}

/// A recorded sequence.
#[derive(Debug, Clone)]
pub struct Record {
    /// Mean recorded volts over each frame's settled window, [RF, MONITOR+, MONITOR−].
    pub frames: Vec<[f64; 3]>,
    /// Bit o set when output o was clipped at its swing in some sample of the frame.
    pub clipped: Vec<u8>,
    /// Bit o set when channel o was over the oscilloscope's range in some settled sample.
    pub over_range: Vec<u8>,
    /// Samples averaged per frame (min, max over frames).
    pub settled_samples: (usize, usize),
    /// Samples recorded per channel in all.
    pub samples: u64,
    /// The first frames, sample by sample.
    pub trace: SignalTrace,
}

impl Record {
    /// Frames among the first `n` in which output `o` was clipped.
    pub fn clipped_frames(&self, o: usize, n: usize) -> usize {
        self.clipped[..n.min(self.clipped.len())]
            .iter()
            .filter(|&&b| b & (1 << o) != 0)
            .count()
    }

    /// Frames among the first `n` in which channel `o` was over range.
    pub fn over_range_frames(&self, o: usize, n: usize) -> usize {
        self.over_range[..n.min(self.over_range.len())]
            .iter()
            .filter(|&&b| b & (1 << o) != 0)
            .count()
    }
}

/// Fills `out` with standard normal deviates, in order. A plain loop: written with
/// `array::from_fn`, whether the draws were inlined into the frame loop changed with unrelated
/// edits elsewhere in the crate (5 % of a dataset sample when they were not).
#[inline(always)]
fn normals(r: &mut rng::StreamRng, out: &mut [f64]) {
    for v in out {
        *v = rng::normal(r);
    }
}

/// The steady, noise-free, unclipped outputs of every frame (V) with the lamp and ambient
/// factors at 1: what an operator sets the oscilloscope ranges from, and the frame values of an
/// ideal bench.
pub fn ideal_frames(bap: &Bap, light: &Illumination) -> Vec<[f64; 3]> {
    light
        .light_a
        .iter()
        .map(|l| bap.ideal_outputs_v(bap.diode_currents(*l, light.ambient_a, light.dark_a)))
        .collect()
}

/// Records a sequence. `noisy = false` draws nothing (no shot, amplifier or oscilloscope noise;
/// pass [`DriftPath::flat`] and ideal channels for the fully noise-free limit).
#[allow(clippy::too_many_arguments)]
pub fn record(
    bap: &Bap,
    channels: &[Channel; 3],
    timing: FrameTiming,
    light: &Illumination,
    drift: &DriftPath,
    seed: u64,
    noisy: bool,
    trace_frames: usize,
) -> Record {
    record_observed(
        bap,
        channels,
        timing,
        light,
        drift,
        seed,
        noisy,
        trace_frames,
        |_, _, _| {},
    )
}

/// [`record`], handing every recorded sample to `sink` in time order: its index n (from the
/// start of the sequence), its frame, and the recorded volts of [RF, MONITOR+, MONITOR−] (what
/// the oscilloscope stores; a record file holds these, so that the frames cut from it are the
/// record's own).
#[allow(clippy::too_many_arguments)]
pub fn record_observed<F: FnMut(u64, usize, &[f64; 3])>(
    bap: &Bap,
    channels: &[Channel; 3],
    timing: FrameTiming,
    light: &Illumination,
    drift: &DriftPath,
    seed: u64,
    noisy: bool,
    trace_frames: usize,
    mut sink: F,
) -> Record {
    let n_frames = light.light_a.len();
    let dt = 1.0 / timing.sample_rate_hz;
    let n_samples = frame_start_sample(timing, n_frames, n_frames);
    let stages = [0, 1, 2].map(|o| *bap.stage(o));
    let a = stages.map(|s| s.pole_factor(dt));
    // Per-output factor turning √S (A/√Hz) into the standard deviation of one OU increment (V).
    let inc = [0, 1, 2].map(|o| {
        stages[o].gain_v_per_a * (stages[o].noise_bandwidth_hz() * (1.0 - a[o] * a[o])).sqrt()
    });
    let shot_on = noisy && bap.shot_noise;

    let mut means = FrameMeans::<3>::new(n_frames);
    let mut clipped = vec![0u8; n_frames];
    let mut over_range = vec![0u8; n_frames];
    let mut trace = SignalTrace {
        t_s: Vec::new(),
        v: [Vec::new(), Vec::new(), Vec::new()],
        frames: trace_frames.min(n_frames),
    };

    let currents_at = |f: usize, t: f64| -> [f64; 2] {
        let lamp = drift.lamp(f, t);
        let amb = drift.ambient(f, t);
        let l = light.light_a[f];
        bap.diode_currents(
            [lamp * l[0], lamp * l[1]],
            [amb * light.ambient_a[0], amb * light.ambient_a[1]],
            light.dark_a,
        )
    };

    let mut rng_batch = usize::MAX;
    let mut r = rng::stream(seed, 0);
    // Filter states start in the steady state of the first sample, with stationary noise.
    let mut v = [0.0; 3];
    if n_frames > 0 {
        let i0 = currents_at(0, 0.0);
        v = bap.ideal_outputs_v(i0);
        if noisy {
            let rms = bap.output_noise_v_rms(i0);
            let mut r0 = rng::stream(seed, INITIAL_STATE_STREAM);
            for (o, vo) in v.iter_mut().enumerate() {
                *vo += rms[o] * rng::normal(&mut r0);
            }
        }
    }
    let sqrt_psd = |i: [f64; 2]| -> ([f64; 2], [f64; 3]) {
        let shot = if shot_on {
            [0, 1].map(|d| (2.0 * super::bap::ELEMENTARY_CHARGE_C * i[d].max(0.0)).sqrt())
        } else {
            [0.0; 2]
        };
        let amp = if noisy {
            stages.map(|s| s.input_noise_a_per_rthz)
        } else {
            [0.0; 3]
        };
        (shot, amp)
    };

    // Frame membership and settling: the one settle-window rule (super::frames).
    let rule = SettleRule::of(timing);
    for n in 0..n_samples {
        let t = n as f64 * dt;
        let f = rule.frame_of(n, n_frames);
        let i = currents_at(f, t);
        let x = bap.ideal_outputs_v(i);
        let mut noise = [0.0; 3];
        let mut scope_draws = [0.0; 3];
        if noisy {
            let batch = f / FRAMES_PER_BATCH;
            if batch != rng_batch {
                rng_batch = batch;
                r = rng::stream(seed, batch as u64);
            }
            let (shot, amp) = sqrt_psd(i);
            let mut d = [0.0; 8];
            normals(&mut r, &mut d);
            let [xp, xm, e0, e1, e2, s0, s1, s2] = d;
            noise = [
                inc[0] * (shot[0] * xp - shot[1] * xm + amp[0] * e0),
                inc[1] * (shot[0] * xp + amp[1] * e1),
                inc[2] * (shot[1] * xm + amp[2] * e2),
            ];
            // Oscilloscope input noise, added below.
            scope_draws = [s0, s1, s2];
        }
        let settled = rule.settled(n, rule.grid_start(f));
        let keep_trace = f < trace.frames;
        if keep_trace {
            trace.t_s.push(t);
        }
        let mut recorded = [0.0; 3];
        for o in 0..3 {
            v[o] = a[o] * v[o] + (1.0 - a[o]) * x[o] + noise[o];
            let out = stages[o].clip(v[o]);
            if out != v[o] {
                clipped[f] |= 1 << o;
            }
            let input = out + channels[o].noise_v_rms * scope_draws[o];
            let (rec, over) = channels[o].digitise(input);
            if keep_trace {
                trace.v[o].push(rec);
            }
            recorded[o] = rec;
            if settled {
                means.add(f, o, rec);
                if over {
                    over_range[f] |= 1 << o;
                }
            }
        }
        if settled {
            means.count(f);
        }
        sink(n, f, &recorded);
    }
    let (frames, counts) = means.means();
    let settled_samples = (
        counts.iter().copied().min().unwrap_or(0),
        counts.iter().copied().max().unwrap_or(0),
    );
    Record {
        frames,
        clipped,
        over_range,
        settled_samples,
        samples: n_samples,
        trace,
    }
}

/// How a sequence is recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RecordModel {
    /// Sample by sample in time ([`record`]): the reference model.
    #[default]
    Samples,
    /// Frame by frame ([`record_frames`]): each frame's settled-window mean drawn directly from
    /// its exact distribution, about a hundred times faster; for datasets of many objects.
    Frames,
}

/// Records a sequence with `model`.
#[allow(clippy::too_many_arguments)]
pub fn record_with(
    model: RecordModel,
    bap: &Bap,
    channels: &[Channel; 3],
    timing: FrameTiming,
    light: &Illumination,
    drift: &DriftPath,
    seed: u64,
    noisy: bool,
    trace_frames: usize,
) -> Record {
    let f = match model {
        RecordModel::Samples => record,
        RecordModel::Frames => record_frames,
    };
    f(
        bap,
        channels,
        timing,
        light,
        drift,
        seed,
        noisy,
        trace_frames,
    )
}

/// The first sample of frame `f` of a sequence of `n_frames` frames (the samples n with
/// ⌊(n + ε)/P⌋ ≥ f, P samples per frame, as [`record`] assigns them); `f = n_frames` gives the
/// number of samples of the whole sequence.
pub fn frame_start_sample(timing: FrameTiming, n_frames: usize, f: usize) -> u64 {
    let n_samples = (n_frames as f64 * timing.frame_s * timing.sample_rate_hz).ceil() as u64;
    if f == 0 {
        0
    } else if f >= n_frames {
        n_samples
    } else {
        let per_frame = timing.frame_s * timing.sample_rate_hz;
        ((f as f64 * per_frame - BOUNDARY_EPS).ceil().max(0.0) as u64).min(n_samples)
    }
}

/// Σ_{k=0}^{K−1} Σ_{l=0}^{K−1} a^{|k−l|} = K·(1 + a)/(1 − a) − 2a·(1 − a^K)/(1 − a)²: the
/// variance of the sum of K consecutive samples of a stationary AR(1) sequence of coefficient a
/// and unit variance (K when a = 0).
fn ar1_sum_variance(a: f64, k: usize) -> f64 {
    let kf = k as f64;
    if a <= 0.0 || k <= 1 {
        return kf;
    }
    let one = 1.0 - a;
    // Every term of the double sum is non-negative, so its diagonal, K, bounds it from below
    // (a guard against cancellation as a → 1).
    (kf * (1.0 + a) / one - 2.0 * a * (1.0 - a.powi(k as i32)) / (one * one)).max(kf)
}

/// Records a sequence frame by frame: the same model as [`record`] with each frame's
/// settled-window mean computed in closed form instead of sample by sample.
///
/// - **Samples and windows.** Frame f holds the samples n with ⌊(n + ε)/P⌋ = f (P samples per
///   frame), its settled window those with n ≥ f·P + S − ε (S settling samples), exactly as in
///   [`record`].
/// - **Signal.** The diode currents are taken constant over a frame at their value at the
///   settled window's centre (the drift is linear within a frame; the ripple's curvature over
///   31 µs is below 10⁻⁴ of its amplitude). Through the single pole the output after k + 1
///   samples of frame f is x + (v − x)·a^{k+1}, v the state at the end of frame f − 1, so the
///   window mean is x + (v − x)·a^{k₀+1}·(1 − a^K)/((1 − a)·K): the exact zero-order-hold
///   response that [`record`] computes sample by sample.
/// - **Noise.** Each noise source (the shot noise of each diode, each amplifier's current
///   noise) is an Ornstein–Uhlenbeck process through the output's pole, an AR(1) sequence of
///   coefficient a and stationary variance G²·S·πB/2 per sample; the mean of K consecutive
///   samples has variance σ²·[K(1 + a)/(1 − a) − 2a(1 − a^K)/(1 − a)²]/K² (Box, Jenkins and
///   Reinsel, *Time Series Analysis*, §2.1, the variance of a sum of AR(1) terms). One normal
///   draw per diode serves the RF output and its monitor, so their shot noise is as correlated
///   as in [`record`] (exactly when their bandwidths are equal). The oscilloscope's white input
///   noise adds σ_s²/K. Successive windows are treated as independent: the pole forgets over
///   the settling time (e^{−2πB·t_s} = e^{−82} at 1 MHz and 13 µs).
/// - **Quantisation.** When a sample's noise is at least half a step the ADC's error acts as
///   uniform noise of variance q²/12 per sample (q²/(12K) for the mean); with less noise than
///   that, the mean is digitised as every sample would be.
/// - **Clipping and range.** An output is clipped when its noise-free response leaves the swing
///   somewhere in the frame (the response is monotone between the previous state and x), and the
///   mean is clipped with it; a channel is flagged over range when the noise-free mean lies
///   within three sample standard deviations of the screen's edge, where some of ~300 settled
///   samples would fall outside it.
/// - **Signal trace.** The first `trace_frames` frames are recorded sample by sample by
///   [`record`] with the same seed, so plots of the oscilloscope look as in a full record.
///
/// The draws of frame f come from `rng::stream(seed, f / FRAMES_PER_BATCH)`: the record does
/// not depend on the number of threads.
#[allow(clippy::too_many_arguments)]
pub fn record_frames(
    bap: &Bap,
    channels: &[Channel; 3],
    timing: FrameTiming,
    light: &Illumination,
    drift: &DriftPath,
    seed: u64,
    noisy: bool,
    trace_frames: usize,
) -> Record {
    let n_frames = light.light_a.len();
    let fs = timing.sample_rate_hz;
    let dt = 1.0 / fs;
    let n_samples = frame_start_sample(timing, n_frames, n_frames);
    let stages = [0, 1, 2].map(|o| *bap.stage(o));
    let a = stages.map(|s| s.pole_factor(dt));
    let shot_on = noisy && bap.shot_noise;
    // The same frame membership as `record`, tolerance included.
    let per_frame = timing.frame_s * fs;
    let settle = timing.settling_s * fs;
    let start = |f: usize| frame_start_sample(timing, n_frames, f);

    let currents_at = |f: usize, t: f64| -> [f64; 2] {
        let lamp = drift.lamp(f, t);
        let amb = drift.ambient(f, t);
        let l = light.light_a[f];
        bap.diode_currents(
            [lamp * l[0], lamp * l[1]],
            [amb * light.ambient_a[0], amb * light.ambient_a[1]],
            light.dark_a,
        )
    };

    let mut frames = vec![[0.0; 3]; n_frames];
    let mut clipped = vec![0u8; n_frames];
    let mut over_range = vec![0u8; n_frames];
    let mut counts = vec![0usize; n_frames];
    let mut v = if n_frames > 0 {
        bap.ideal_outputs_v(currents_at(0, 0.0))
    } else {
        [0.0; 3]
    };
    let mut rng_batch = usize::MAX;
    let mut r = rng::stream(seed, 0);
    // Per-source variance of one unit-density white current through each stage's pole.
    let unit_var = stages.map(|st| st.gain_v_per_a.powi(2) * st.noise_bandwidth_hz());
    let mut terms: Option<((usize, i32, i32), [WindowTerms; 3])> = None;
    for f in 0..n_frames {
        let (k, k0, n, mid) = settled_window(f, start(f), start(f + 1), per_frame, settle, dt);
        counts[f] = k;
        // The frames of a sequence share one or two windows: their terms computed once each.
        let w = match terms {
            Some((key, w)) if key == (k, k0, n) => w,
            _ => {
                let w =
                    [0, 1, 2].map(|o| WindowTerms::new(a[o], unit_var[o], &channels[o], k, k0, n));
                terms = Some(((k, k0, n), w));
                w
            }
        };
        let i = currents_at(f, mid);
        let x = bap.ideal_outputs_v(i);
        // Noise draws: shot of each diode, each amplifier, the oscilloscope, the ADC.
        let mut z = [0.0; 11];
        if noisy && k > 0 {
            let batch = f / FRAMES_PER_BATCH;
            if batch != rng_batch {
                rng_batch = batch;
                r = rng::stream(seed, batch as u64);
            }
            normals(&mut r, &mut z);
        }
        let shot = if shot_on {
            [0, 1].map(|d| (2.0 * super::bap::ELEMENTARY_CHARGE_C * i[d].max(0.0)).sqrt())
        } else {
            [0.0; 2]
        };
        for o in 0..3 {
            let st = &stages[o];
            let (ao, w) = (a[o], &w[o]);
            let v_start = x[o] + (v[o] - x[o]) * ao;
            let v_end = x[o] + (v[o] - x[o]) * w.a_n;
            if st.clip(v_start) != v_start || st.clip(v_end) != v_end {
                clipped[f] |= 1 << o;
            }
            // Zero for an empty window (1 − a⁰ = 0) and for a pole too fast to remember (a = 0).
            let transient = (v[o] - x[o]) * w.a_k0 * w.one_minus_a_k / w.transient_den;
            let mean = st.clip(x[o] + transient);
            v[o] = v_end;
            if k == 0 {
                continue;
            }
            let ch = &channels[o];
            // Per-source white current densities (√(A²/Hz)) and their draws.
            let amp = if noisy {
                st.input_noise_a_per_rthz
            } else {
                0.0
            };
            let (sources, draws): ([f64; 3], [f64; 3]) = match o {
                RF => ([shot[0], -shot[1], amp], [z[0], z[1], z[2]]),
                MONITOR_PLUS => ([shot[0], 0.0, amp], [z[0], z[1], z[3]]),
                _ => ([0.0, shot[1], amp], [z[0], z[1], z[4]]),
            };
            let det_noise: f64 = (0..3).map(|s| sources[s] * draws[s]).sum::<f64>() * w.mean_scale;
            let sample_var =
                unit_var[o] * sources.iter().map(|s| s * s).sum::<f64>() + ch.noise_v_rms.powi(2);
            let mut value = mean + det_noise + w.scope_scale * z[5 + o];
            let (lo, hi) = ch.window();
            if ch.lsb_v > 0.0 {
                if sample_var.sqrt() >= 0.5 * ch.lsb_v {
                    value += w.adc_scale * z[8 + o];
                } else {
                    value = ch.digitise(value).0;
                }
            }
            let margin = 3.0 * sample_var.sqrt();
            if mean - margin < lo || mean + margin > hi {
                over_range[f] |= 1 << o;
            }
            frames[f][o] = value.clamp(lo, hi);
        }
    }
    let trace = head_trace(
        bap,
        channels,
        timing,
        light,
        drift,
        seed,
        noisy,
        trace_frames,
    );
    Record {
        frames,
        clipped,
        over_range,
        settled_samples: (
            counts.iter().copied().min().unwrap_or(0),
            counts.iter().copied().max().unwrap_or(0),
        ),
        samples: n_samples,
        trace,
    }
}

/// What a frame's settled window (k samples from offset k0 of the frame's n) makes of one
/// channel's pole (a per sample) and noise: the factors the frame loop of [`record_frames`]
/// multiplies by, each the expression it evaluated per frame before, so the record is the same
/// bit for bit. `unit_var` is the stationary per-sample variance of one unit-density source
/// through the pole (V² per A²/Hz).
#[derive(Debug, Clone, Copy)]
struct WindowTerms {
    /// a^n: the frame's end from its start.
    a_n: f64,
    /// a^(k0+1), 1 − a^k and (1 − a)·K (K = max(k, 1)): the settled mean's transient.
    a_k0: f64,
    one_minus_a_k: f64,
    transient_den: f64,
    /// √(unit_var·Σ a^|i−j|)/K: the detector noise of the window's mean per unit draw.
    mean_scale: f64,
    /// σ_scope/√K and LSB/√(12K): the oscilloscope's noise and the ADC's rounding in the mean.
    scope_scale: f64,
    adc_scale: f64,
}

impl WindowTerms {
    fn new(a: f64, unit_var: f64, ch: &Channel, k: usize, k0: i32, n: i32) -> WindowTerms {
        let kf = k.max(1) as f64;
        WindowTerms {
            a_n: a.powi(n.max(0)),
            a_k0: a.powi(k0 + 1),
            one_minus_a_k: 1.0 - a.powi(k as i32),
            transient_den: (1.0 - a) * kf,
            mean_scale: (unit_var * ar1_sum_variance(a, k)).sqrt() / kf,
            scope_scale: ch.noise_v_rms / kf.sqrt(),
            adc_scale: ch.lsb_v / (12.0 * kf).sqrt(),
        }
    }
}

/// The settled window of frame f, whose samples are n0..n1: the number of settled samples k,
/// the offset k0 of the first from n0, the frame's sample count n, and the time (s) at the
/// window's centre (the frame's centre when nothing settles), where drift is evaluated.
fn settled_window(
    f: usize,
    n0: u64,
    n1: u64,
    per_frame: f64,
    settle: f64,
    dt: f64,
) -> (usize, i32, i32, f64) {
    let settled_from = ((f as f64 * per_frame + settle - BOUNDARY_EPS)
        .ceil()
        .max(0.0) as u64)
        .max(n0);
    let k = n1.saturating_sub(settled_from) as usize;
    let k0 = (settled_from.min(n1) - n0) as i32;
    let n = (n1 - n0) as i32;
    let mid = if k > 0 {
        (settled_from as f64 + 0.5 * (k as f64 - 1.0)) * dt
    } else {
        (n0 as f64 + 0.5 * (n as f64 - 1.0).max(0.0)) * dt
    };
    (k, k0, n, mid)
}

/// The first `trace_frames` frames recorded sample by sample with [`record`] and the same seed
/// (what the oscilloscope plots show); an empty trace for none.
#[allow(clippy::too_many_arguments)]
fn head_trace(
    bap: &Bap,
    channels: &[Channel; 3],
    timing: FrameTiming,
    light: &Illumination,
    drift: &DriftPath,
    seed: u64,
    noisy: bool,
    trace_frames: usize,
) -> SignalTrace {
    let n_frames = light.light_a.len();
    if trace_frames == 0 || n_frames == 0 {
        return SignalTrace {
            t_s: Vec::new(),
            v: [Vec::new(), Vec::new(), Vec::new()],
            frames: 0,
        };
    }
    let m = trace_frames.min(n_frames);
    let head = Illumination {
        light_a: &light.light_a[..m],
        ..*light
    };
    record(bap, channels, timing, &head, drift, seed, noisy, m).trace
}

#[cfg(test)]
mod tests;
