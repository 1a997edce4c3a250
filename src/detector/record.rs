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

use rand::Rng;
use serde::Serialize;

use super::bap::Bap;
use super::drift::DriftPath;
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

/// A pair of standard normal deviates (Box–Muller, both values used).
#[inline]
fn normal_pair<R: Rng + ?Sized>(r: &mut R) -> (f64, f64) {
    let u1 = rng::uniform_open0(r);
    let u2 = rng::uniform(r);
    let rad = (-2.0 * u1.ln()).sqrt();
    let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
    (rad * c, rad * s)
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
    let n_frames = light.light_a.len();
    let dt = 1.0 / timing.sample_rate_hz;
    let total_s = n_frames as f64 * timing.frame_s;
    let n_samples = (total_s * timing.sample_rate_hz).ceil() as u64;
    let stages = [0, 1, 2].map(|o| *bap.stage(o));
    let a = stages.map(|s| s.pole_factor(dt));
    // Per-output factor turning √S (A/√Hz) into the standard deviation of one OU increment (V).
    let inc = [0, 1, 2].map(|o| {
        stages[o].gain_v_per_a * (stages[o].noise_bandwidth_hz() * (1.0 - a[o] * a[o])).sqrt()
    });
    let shot_on = noisy && bap.shot_noise;

    let mut frames = vec![[0.0; 3]; n_frames];
    let mut counts = vec![0usize; n_frames];
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

    // Frame membership in units of samples, with a tolerance of 10⁻⁶ sample so that a sample
    // that falls exactly on a frame or settling boundary (440 samples per 44 µs frame) is not
    // moved by the rounding of t/T.
    let per_frame = timing.frame_s * timing.sample_rate_hz;
    let settle_samples = timing.settling_s * timing.sample_rate_hz;
    const EPS: f64 = 1e-6;
    for n in 0..n_samples {
        let t = n as f64 * dt;
        let f = (((n as f64 + EPS) / per_frame) as usize).min(n_frames - 1);
        let in_frame = n as f64 - f as f64 * per_frame;
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
            let (xp, xm) = normal_pair(&mut r);
            let (e0, e1) = normal_pair(&mut r);
            let (e2, s0) = normal_pair(&mut r);
            let (s1, s2) = normal_pair(&mut r);
            noise = [
                inc[0] * (shot[0] * xp - shot[1] * xm + amp[0] * e0),
                inc[1] * (shot[0] * xp + amp[1] * e1),
                inc[2] * (shot[1] * xm + amp[2] * e2),
            ];
            // Oscilloscope input noise, added below.
            scope_draws = [s0, s1, s2];
        }
        let settled = in_frame + EPS >= settle_samples;
        let keep_trace = f < trace.frames;
        if keep_trace {
            trace.t_s.push(t);
        }
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
            if settled {
                frames[f][o] += rec;
                if over {
                    over_range[f] |= 1 << o;
                }
            }
        }
        if settled {
            counts[f] += 1;
        }
    }
    for (fr, &c) in frames.iter_mut().zip(&counts) {
        let k = c.max(1) as f64;
        for v in fr.iter_mut() {
            *v /= k;
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detector::bap::tests::bap;
    use crate::detector::bap::{MONITOR_MINUS, MONITOR_PLUS, RF};

    fn channel(noise: f64, offset: f64) -> Channel {
        Channel {
            volts_per_div: 1.0,
            offset_v: offset,
            noise_v_rms: noise,
            lsb_v: 0.0,
            bits: 0,
        }
    }

    const TIMING: FrameTiming = FrameTiming {
        frame_s: 44e-6,
        settling_s: 13e-6,
        sample_rate_hz: 10e6,
    };

    /// The frame means' variance matches the model: per output an AR(1) sequence of
    /// coefficient a and stationary variance G²·S·πB/2, averaged over K samples, plus the
    /// oscilloscope's white noise σ_s²/K:
    /// var = σ²/K²·[K + 2·Σ_{k=1}^{K−1} (K − k)·a^k] + σ_s²/K.
    /// With F = 3000 nearly independent frames (the pole forgets in 0.16 µs, the frames are
    /// 13 µs apart), the sample variance has a relative standard error √(2/(F − 1)) = 2.6 %;
    /// the test allows 5 of them.
    #[test]
    fn frame_noise_matches_the_model() {
        let b = bap();
        let frames = 3000;
        let light = vec![[10e-6, 5e-6]; frames];
        let il = Illumination {
            light_a: &light,
            ambient_a: [0.0; 2],
            dark_a: [1e-9; 2],
        };
        let ideal = ideal_frames(&b, &il)[0];
        let sigma_s = 2e-5;
        let ch = [0, 1, 2].map(|o| channel(sigma_s, ideal[o]));
        let rec = record(
            &b,
            &ch,
            TIMING,
            &il,
            &DriftPath::flat(frames, TIMING.frame_s),
            9,
            true,
            2,
        );
        let i = b.diode_currents(light[0], [0.0; 2], [1e-9; 2]);
        let rms = b.output_noise_v_rms(i);
        let k = 0.5 * (rec.settled_samples.0 + rec.settled_samples.1) as f64;
        for o in [RF, MONITOR_PLUS, MONITOR_MINUS] {
            let a = b.stage(o).pole_factor(1.0 / TIMING.sample_rate_hz);
            let kk = k.round() as usize;
            let mut sum = kk as f64;
            for lag in 1..kk {
                sum += 2.0 * (kk - lag) as f64 * a.powi(lag as i32);
            }
            let want = rms[o].powi(2) * sum / (k * k) + sigma_s * sigma_s / k;
            let vals: Vec<f64> = rec.frames.iter().map(|f| f[o]).collect();
            let n = vals.len() as f64;
            let mean = vals.iter().sum::<f64>() / n;
            let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
            let tol = 5.0 * (2.0 / (n - 1.0)).sqrt();
            assert!(
                (var / want - 1.0).abs() < tol,
                "output {o}: variance {var:e} vs model {want:e}"
            );
            // The mean is the noise-free output: within 5 standard errors.
            assert!(
                (mean - ideal[o]).abs() < 5.0 * (want / n).sqrt(),
                "output {o}: mean {mean} vs {}",
                ideal[o]
            );
        }
        // The trace holds the first two frames, sample by sample.
        assert_eq!(rec.trace.frames, 2);
        assert_eq!(rec.trace.t_s.len(), 880);
        assert!(rec.clipped.iter().all(|&c| c == 0));
    }

    /// Noise off and a frame longer than the filter's memory: every frame's mean is its ideal
    /// output; the settled window holds (T − t_s)·fs samples.
    #[test]
    fn noise_free_frames_are_the_ideal_outputs() {
        let b = bap();
        let light: Vec<[f64; 2]> = (0..50)
            .map(|f| [1e-6 * (1.0 + (f % 7) as f64), 2e-6 + 1e-7 * (f % 3) as f64])
            .collect();
        let il = Illumination {
            light_a: &light,
            ambient_a: [1e-11; 2],
            dark_a: [1e-9; 2],
        };
        let ideal = ideal_frames(&b, &il);
        let ch = [channel(0.0, 0.0); 3];
        let rec = record(
            &b,
            &ch,
            TIMING,
            &il,
            &DriftPath::flat(50, TIMING.frame_s),
            1,
            false,
            0,
        );
        for (f, (got, want)) in rec.frames.iter().zip(&ideal).enumerate() {
            for o in 0..3 {
                assert!(
                    (got[o] - want[o]).abs() <= 1e-14 * want[o].abs().max(1e-3),
                    "frame {f} output {o}: {} vs {}",
                    got[o],
                    want[o]
                );
            }
        }
        // 31 µs at 10 MS/s: 310 or 311 samples.
        assert!(rec.settled_samples.0 >= 310 && rec.settled_samples.1 <= 311);
        // Clipping is flagged: a tiny swing clips the RF output in every frame.
        let mut small = b.clone();
        small.rf.swing_v = 1e-3;
        let rec = record(
            &small,
            &ch,
            TIMING,
            &il,
            &DriftPath::flat(50, TIMING.frame_s),
            1,
            false,
            0,
        );
        assert_eq!(rec.clipped_frames(RF, 50), 50);
        assert_eq!(rec.clipped_frames(MONITOR_PLUS, 50), 0);
        assert!(
            rec.frames
                .iter()
                .all(|f| f[RF].abs() <= 1e-3 * (1.0 + 1e-12))
        );
    }
}
