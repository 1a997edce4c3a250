//! Slow multiplicative processes in time: lamp intensity drift and ripple (common to both arms,
//! they multiply all traced light) and ambient-light drift and flicker (they multiply the
//! ambient current of both diodes).
//!
//! Each factor is 1 + d(t) + a·sin(2πft + φ), with d an Ornstein–Uhlenbeck process of
//! stationary rms σ and correlation time τ, sampled exactly at every frame start,
//! d_{k+1} = d_k·e^{−Δ/τ} + σ·√(1 − e^{−2Δ/τ})·ξ_k (Gillespie, Phys. Rev. E 54:2084, 1996),
//! and linearly interpolated within a frame (Δ = 44 µs ≪ τ), and φ a uniform random phase.
//! One stream per acquisition ([`crate::rng::stream`] keyed by the acquisition's seed and
//! [`DRIFT_STREAM`]), drawn in frame order: the path does not depend on the thread count.

use serde::Serialize;

use crate::rng;

/// Stream index of the drift path within an acquisition's seed (the frame batches of
/// [`super::record`] use indices from 0 upward, far below this).
pub const DRIFT_STREAM: u64 = 1 << 40;

/// The drift settings (SI; relative quantities are fractions of the mean).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Drift {
    pub lamp_drift_rms: f64,
    pub lamp_drift_time_s: f64,
    pub lamp_ripple_amplitude: f64,
    pub lamp_ripple_hz: f64,
    pub ambient_drift_rms: f64,
    pub ambient_drift_time_s: f64,
    pub ambient_flicker_depth: f64,
    pub ambient_flicker_hz: f64,
}

impl Drift {
    /// No drift at all.
    pub fn none() -> Drift {
        Drift {
            lamp_drift_rms: 0.0,
            lamp_drift_time_s: 1.0,
            lamp_ripple_amplitude: 0.0,
            lamp_ripple_hz: 100.0,
            ambient_drift_rms: 0.0,
            ambient_drift_time_s: 1.0,
            ambient_flicker_depth: 0.0,
            ambient_flicker_hz: 100.0,
        }
    }
}

/// One realisation of the drift over an acquisition of `frames` frames.
#[derive(Debug, Clone)]
pub struct DriftPath {
    frame_s: f64,
    /// d(t) of the lamp and of the ambient light at every frame start (frames + 1 values).
    lamp: Vec<f64>,
    ambient: Vec<f64>,
    lamp_ripple: (f64, f64, f64),
    ambient_flicker: (f64, f64, f64),
}

/// Exact OU path at `n` equally spaced times.
fn ou_path<R: rand::Rng + ?Sized>(n: usize, dt: f64, rms: f64, tau: f64, r: &mut R) -> Vec<f64> {
    let mut out = Vec::with_capacity(n);
    if rms == 0.0 {
        out.resize(n, 0.0);
        return out;
    }
    let a = (-dt / tau).exp();
    let step = rms * (1.0 - a * a).max(0.0).sqrt();
    let mut d = rms * rng::normal(r);
    for _ in 0..n {
        out.push(d);
        d = a * d + step * rng::normal(r);
    }
    out
}

impl DriftPath {
    /// Draws the path for `frames` frames of `frame_s` seconds from `rng::stream(seed,
    /// DRIFT_STREAM)`.
    pub fn draw(drift: &Drift, frames: usize, frame_s: f64, seed: u64) -> DriftPath {
        let mut r = rng::stream(seed, DRIFT_STREAM);
        let lamp = ou_path(
            frames + 1,
            frame_s,
            drift.lamp_drift_rms,
            drift.lamp_drift_time_s,
            &mut r,
        );
        let ambient = ou_path(
            frames + 1,
            frame_s,
            drift.ambient_drift_rms,
            drift.ambient_drift_time_s,
            &mut r,
        );
        let phase1 = std::f64::consts::TAU * rng::uniform(&mut r);
        let phase2 = std::f64::consts::TAU * rng::uniform(&mut r);
        DriftPath {
            frame_s,
            lamp,
            ambient,
            lamp_ripple: (drift.lamp_ripple_amplitude, drift.lamp_ripple_hz, phase1),
            ambient_flicker: (
                drift.ambient_flicker_depth,
                drift.ambient_flicker_hz,
                phase2,
            ),
        }
    }

    /// The constant path: both factors are 1 at all times.
    pub fn flat(frames: usize, frame_s: f64) -> DriftPath {
        DriftPath {
            frame_s,
            lamp: vec![0.0; frames + 1],
            ambient: vec![0.0; frames + 1],
            lamp_ripple: (0.0, 0.0, 0.0),
            ambient_flicker: (0.0, 0.0, 0.0),
        }
    }

    fn factor(path: &[f64], wave: (f64, f64, f64), frame: usize, t: f64, frame_s: f64) -> f64 {
        let u = (t / frame_s - frame as f64).clamp(0.0, 1.0);
        let k = frame.min(path.len().saturating_sub(2));
        let d = path[k] + u * (path[k + 1] - path[k]);
        let (amp, f, phase) = wave;
        let w = if amp == 0.0 {
            0.0
        } else {
            amp * (std::f64::consts::TAU * f * t + phase).sin()
        };
        1.0 + d + w
    }

    /// The lamp factor at time `t` (s) within frame `frame`.
    pub fn lamp(&self, frame: usize, t: f64) -> f64 {
        Self::factor(&self.lamp, self.lamp_ripple, frame, t, self.frame_s)
    }

    /// The ambient factor at time `t` (s) within frame `frame`.
    pub fn ambient(&self, frame: usize, t: f64) -> f64 {
        Self::factor(&self.ambient, self.ambient_flicker, frame, t, self.frame_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ou_path_has_the_stated_rms_and_correlation() {
        // 20 000 steps of dt = τ/10: the lag-1 correlation is e^{−0.1} = 0.905; the rms is σ.
        // The path has ≈ n·dt/(2τ) = 1000 independent stretches, so the sample variance has a
        // relative standard error of about √(2/1000) = 4.5 %: test the rms to 5 × 2.2 %.
        let mut r = rng::stream(7, 0);
        let p = ou_path(20_000, 0.1, 0.01, 1.0, &mut r);
        let n = p.len() as f64;
        let mean = p.iter().sum::<f64>() / n;
        let var = p.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        assert!((var.sqrt() / 0.01 - 1.0).abs() < 0.11, "rms {}", var.sqrt());
        let c1 = p
            .windows(2)
            .map(|w| (w[0] - mean) * (w[1] - mean))
            .sum::<f64>()
            / (n - 1.0);
        assert!(
            (c1 / var - (-0.1f64).exp()).abs() < 0.05,
            "lag-1 {}",
            c1 / var
        );
    }

    #[test]
    fn flat_path_is_one_and_ripple_has_its_amplitude() {
        let f = DriftPath::flat(10, 44e-6);
        assert_eq!(f.lamp(3, 3.5 * 44e-6), 1.0);
        assert_eq!(f.ambient(9, 9.9 * 44e-6), 1.0);
        let d = Drift {
            lamp_ripple_amplitude: 0.01,
            ..Drift::none()
        };
        let p = DriftPath::draw(&d, 1000, 44e-6, 3);
        // Over one 10 ms period (227 frames) the factor spans 1 ± 0.01.
        let v: Vec<f64> = (0..228).map(|k| p.lamp(k, k as f64 * 44e-6)).collect();
        let (lo, hi) = v
            .iter()
            .fold((2.0f64, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        assert!(
            (hi - 1.01).abs() < 1e-4 && (lo - 0.99).abs() < 1e-4,
            "{lo} {hi}"
        );
        // Same seed, same path.
        let q = DriftPath::draw(&d, 1000, 44e-6, 3);
        assert_eq!(p.lamp(5, 5.2 * 44e-6), q.lamp(5, 5.2 * 44e-6));
    }
}
