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
        let n = rec.frames.len() as f64;
        let (mean, var) = stats(&rec, o);
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
fn stats(rec: &Record, o: usize) -> (f64, f64) {
    let vals: Vec<f64> = rec.frames.iter().map(|f| f[o]).collect();
    let n = vals.len() as f64;
    let mean = vals.iter().sum::<f64>() / n;
    let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var)
}

fn correlation(rec: &Record, o1: usize, o2: usize) -> f64 {
    let (m1, v1) = stats(rec, o1);
    let (m2, v2) = stats(rec, o2);
    let n = rec.frames.len() as f64;
    let c = rec
        .frames
        .iter()
        .map(|f| (f[o1] - m1) * (f[o2] - m2))
        .sum::<f64>()
        / (n - 1.0);
    c / (v1 * v2).sqrt()
}

/// Without noise the frame model is the sample model's exact closed form, also with a pole
/// slow enough that the transient reaches into the settled window (30 kHz: a^131 = 0.08),
/// and, with a lamp drift and ripple, the drift taken at the window's centre.
#[test]
fn frame_record_is_the_closed_form_of_the_sample_record() {
    let mut b = bap();
    for o in 0..3 {
        let st = match o {
            0 => &mut b.rf,
            1 => &mut b.monitors[0],
            _ => &mut b.monitors[1],
        };
        st.bandwidth_hz = 3e4;
    }
    let light: Vec<[f64; 2]> = (0..80)
        .map(|f| [1e-6 * (1.0 + (f % 5) as f64), 3e-6 - 2e-7 * (f % 3) as f64])
        .collect();
    let il = Illumination {
        light_a: &light,
        ambient_a: [1e-11; 2],
        dark_a: [1e-9; 2],
    };
    let ch = [channel(0.0, 0.0); 3];
    let flat = DriftPath::flat(80, TIMING.frame_s);
    let s = record(&b, &ch, TIMING, &il, &flat, 1, false, 0);
    let f = record_frames(&b, &ch, TIMING, &il, &flat, 1, false, 0);
    assert_eq!(s.settled_samples, f.settled_samples);
    assert_eq!(s.samples, f.samples);
    for (k, (a, c)) in s.frames.iter().zip(&f.frames).enumerate() {
        for o in 0..3 {
            assert!(
                (a[o] - c[o]).abs() <= 1e-9 * a[o].abs().max(1e-3),
                "frame {k} output {o}: samples {} vs frames {}",
                a[o],
                c[o]
            );
        }
    }
    // The transient matters here: frame 1 differs from its steady output by far more than
    // the agreement above.
    let ideal = ideal_frames(&b, &il);
    assert!((f.frames[1][MONITOR_PLUS] - ideal[1][MONITOR_PLUS]).abs() > 1e-4);
    // Drift and ripple: the lamp factor at the window's centre. The frame model holds the
    // input constant over a frame, so the output's lag behind a drifting input (the pole's
    // time constant 1/(2πB), 0.16 µs at 1 MHz, times the drift's slope) is what it
    // neglects. The OU drift changes by σ·√(2T/τ) (rms) per frame of T, so the relative
    // error is that step times (1/(2πB))/T, allowed 5 rms steps (the ripple's slope,
    // 2π·120 Hz·0.005, adds 10⁻¹⁰ over the lag).
    let b = bap();
    let drift = crate::detector::Drift {
        lamp_drift_rms: 0.01,
        lamp_drift_time_s: 1e-2,
        lamp_ripple_amplitude: 0.005,
        lamp_ripple_hz: 120.0,
        ..crate::detector::Drift::none()
    };
    let path = DriftPath::draw(&drift, 80, TIMING.frame_s, 4);
    let s = record(&b, &ch, TIMING, &il, &path, 1, false, 0);
    let f = record_frames(&b, &ch, TIMING, &il, &path, 1, false, 0);
    let step = drift.lamp_drift_rms * (2.0 * TIMING.frame_s / drift.lamp_drift_time_s).sqrt();
    let lag = 1.0 / (std::f64::consts::TAU * b.rf.bandwidth_hz);
    let tol = 5.0 * step * lag / TIMING.frame_s;
    for (k, (a, c)) in s.frames.iter().zip(&f.frames).enumerate() {
        for o in 0..3 {
            assert!(
                (a[o] - c[o]).abs() <= tol * a[o].abs().max(1e-3),
                "frame {k} output {o} with drift: {} vs {}",
                a[o],
                c[o]
            );
        }
    }
    // Clipping is flagged in the same frames.
    let mut small = b.clone();
    small.monitors[0].swing_v = 0.05;
    let s = record(&small, &ch, TIMING, &il, &flat, 1, false, 0);
    let f = record_frames(&small, &ch, TIMING, &il, &flat, 1, false, 0);
    assert_eq!(s.clipped, f.clipped);
    assert!(f.clipped_frames(MONITOR_PLUS, 80) > 0);
    assert!(f.clipped_frames(MONITOR_PLUS, 80) < 80);
}

/// With noise, the frame means of both models have the same mean, variance and
/// correlation between outputs, with the oscilloscope's noise and a coarse ADC (a step of
/// about a third of a sample's noise, so the error acts as noise). 4000 frames: a sample
/// variance has a relative standard error of √(2/3999) = 2.2 %, the ratio of two of them
/// 3.2 %, allowed five times; a correlation ρ has a standard error (1 − ρ²)/√n.
#[test]
fn frame_record_noise_matches_the_sample_record() {
    let b = bap();
    let frames = 4000;
    let light = vec![[10e-6, 5e-6]; frames];
    let il = Illumination {
        light_a: &light,
        ambient_a: [0.0; 2],
        dark_a: [1e-9; 2],
    };
    let ideal = ideal_frames(&b, &il)[0];
    let flat = DriftPath::flat(frames, TIMING.frame_s);
    let rms = b.output_noise_v_rms(b.diode_currents(light[0], [0.0; 2], [1e-9; 2]));
    for quantised in [false, true] {
        let ch = [0, 1, 2].map(|o| {
            let mut c = channel(2e-5, ideal[o]);
            if quantised {
                c.lsb_v = 0.3 * rms[o];
                c.bits = 16;
            }
            c
        });
        let s = record(&b, &ch, TIMING, &il, &flat, 9, true, 0);
        let f = record_frames(&b, &ch, TIMING, &il, &flat, 9, true, 0);
        let n = frames as f64;
        for o in [RF, MONITOR_PLUS, MONITOR_MINUS] {
            let (ms, vs) = stats(&s, o);
            let (mf, vf) = stats(&f, o);
            let tol = 5.0 * (4.0 / (n - 1.0)).sqrt();
            assert!(
                (vf / vs - 1.0).abs() < tol,
                "output {o} (quantised {quantised}): variance frames {vf:e} vs samples {vs:e}"
            );
            assert!(
                (mf - ms).abs() < 5.0 * ((vs + vf) / n).sqrt(),
                "output {o}: mean frames {mf} vs samples {ms}"
            );
        }
        for (o1, o2) in [
            (RF, MONITOR_PLUS),
            (RF, MONITOR_MINUS),
            (MONITOR_PLUS, MONITOR_MINUS),
        ] {
            let (rs, rf) = (correlation(&s, o1, o2), correlation(&f, o1, o2));
            let se = (1.0 - rs * rs) / n.sqrt();
            assert!(
                (rs - rf).abs() < 5.0 * std::f64::consts::SQRT_2 * se,
                "outputs {o1}, {o2}: correlation frames {rf} vs samples {rs}"
            );
        }
        // The oscilloscope's trace is the sample model's.
        assert!(f.trace.t_s.is_empty());
    }
    // A trace of the first frames, sample by sample.
    let ch = [0, 1, 2].map(|o| channel(2e-5, ideal[o]));
    let f = record_frames(&b, &ch, TIMING, &il, &flat, 9, true, 3);
    assert_eq!(f.trace.frames, 3);
    assert_eq!(f.trace.t_s.len(), 3 * 440);
}

#[test]
fn ar1_sum_variance_is_the_double_sum() {
    for (a, k) in [(0.0, 5), (0.5, 1), (0.53, 310), (0.98, 40), (0.999, 7)] {
        let mut want = 0.0;
        for i in 0..k {
            for j in 0..k {
                want += f64::powi(a, (i as i32 - j as i32).abs());
            }
        }
        let got = ar1_sum_variance(a, k);
        assert!(
            (got / want - 1.0).abs() < 1e-10,
            "a {a} k {k}: {got} vs {want}"
        );
    }
}
