//! Each arm's gain and offset from the calibration preamble's (all on, all off) frames, with
//! standard errors from the frame-to-frame scatter.
//!
//! All on sends the whole object to arm + and nothing to arm −; all off the reverse. So each
//! monitor has *lit* frames (the object's light k·Σx plus the offset) and *dark* frames (the
//! offset b alone: pattern-independent light, ambient, dark current, the amplifier's offset):
//! offset b̂ = mean of the dark frames, gain ĝ = mean(lit) − mean(dark) (V for the whole
//! object). Each mean's standard error is the sample standard deviation over its frames / √n;
//! the gain's adds the two in quadrature (the frames' noises are independent: the output's pole
//! forgets within the settling time).

use serde::Serialize;

use super::frames::FoundFrame;
use crate::acquisition::schemes::CALIBRATION_PAIRS;

/// One arm's two-point calibration.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ArmCalibration {
    /// `plus` or `minus`.
    pub arm: &'static str,
    /// The whole object's signal, mean(lit) − mean(dark) (V), and its standard error.
    pub gain_v: f64,
    pub gain_stderr_v: f64,
    /// The dark level (V), and its standard error.
    pub offset_v: f64,
    pub offset_stderr_v: f64,
    /// Frames in each mean.
    pub frames_per_level: usize,
}

/// Mean and standard error of the mean (sample SD / √n; NaN below two values).
pub fn mean_stderr(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, f64::NAN);
    }
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The calibration of arms [+, −] from the first 2·[`CALIBRATION_PAIRS`] frames of a
/// calibrated record (frame 2k all on, 2k + 1 all off).
pub fn calibrate(frames: &[FoundFrame]) -> [ArmCalibration; 2] {
    let values: Vec<[f64; 3]> = frames.iter().map(|f| f.values).collect();
    calibrate_values(&values)
}

/// [`calibrate`] from the frames' values [RF, MONITOR+, MONITOR−].
pub fn calibrate_values(frames: &[[f64; 3]]) -> [ArmCalibration; 2] {
    let pairs = (frames.len() / 2).min(CALIBRATION_PAIRS);
    let level = |parity: usize, o: usize| -> Vec<f64> {
        (0..pairs).map(|k| frames[2 * k + parity][o]).collect()
    };
    // MONITOR+ (output 1) is lit when all on; MONITOR− (output 2) when all off.
    [("plus", 1, 0), ("minus", 2, 1)].map(|(arm, o, lit)| {
        let (l, l_se) = mean_stderr(&level(lit, o));
        let (d, d_se) = mean_stderr(&level(1 - lit, o));
        ArmCalibration {
            arm,
            gain_v: l - d,
            gain_stderr_v: l_se.hypot(d_se),
            offset_v: d,
            offset_stderr_v: d_se,
            frames_per_level: pairs,
        }
    })
}
