//! The four acquisition schemes with scalar arm gains (paper §2, Eqs. 6–12, and §3).
//!
//! # Model
//!
//! For an object x (N ideal per-unit values) and M base patterns P (0/1), each DMD arm is a
//! linear detector with gain k and bias b (paper Eqs. 6–9):
//!
//! ```text
//! monitor sample, arm +, frame F:  s₊ = k₊ (F·x + e) + b₊       (arm + sees F)
//! monitor sample, arm −, frame F:  s₋ = k₋ ((1 − F)·x + e) + b₋ (arm − sees the complement)
//! RF sample (balanced output), frame F:
//!                                 B = k₊ F·x + b₊ − k₋ (1 − F)·x − b₋ + e
//! ```
//!
//! where e is one independent draw of the additive noise per recorded sample
//! ([`super::noise`]). Monitor noise sits inside the gain, as in Eqs. (6)–(9). The RF output is
//! one measured value formed after the two arm gains, so there is no single arm gain to put its
//! draw inside: it is added to the recorded value itself ("directly onto the measured values",
//! paper §3). With the paper's Fig. 4 gains (k₊ = 1, k₋ = 1.01) the two placements differ by
//! at most 1 %.
//!
//! The schemes, for pattern i (frames shown in display order, samples in recording order):
//!
//! | scheme | frames | samples | y_i | operator |
//! |---|---|---|---|---|
//! | traditional CS | P_i | s₊(P_i) | s₊(P_i) | A = P |
//! | single-arm complementary | P_i, 1 − P_i | s₊(P_i), s₊(1 − P_i) | difference | Â = 2P − 1 |
//! | double-arm dual-pixel | P_i | s₊(P_i), s₋(P_i) | s₊ − s₋ | Â |
//! | secondary complementary balancing | P_i, 1 − P_i | B(P_i), B(1 − P_i) | B₁ − B₂ | Â |
//!
//! Noise-free, with Σx the object total and k' = k₊ + k₋ (see [`Scheme::model`]):
//! - traditional: y = k₊·Px + b₊;
//! - single-arm: y = k₊·Âx;
//! - double-arm: y = k₊Px + b₊ − k₋(Σx − Px) − b₋ = (k'/2)·Âx + ((k₊ − k₋)/2)·Σx + b₊ − b₋,
//!   using Px = (Âx + Σx)/2; the offset is as large as the signal at 1 % imbalance;
//! - SCB: B₁ − B₂ = k₊(Px − (Σx − Px)) + k₋(Px − (Σx − Px)) = k'·Âx exactly (Eq. 12).
//!
//! Frames are shown P_1, 1 − P_1, P_2, 1 − P_2, … (a complementary pair back to back, as the
//! paper's SCB needs), and recorded samples are numbered in that order: for the two-sample
//! schemes, sample 2i belongs to P_i (or arm + of frame i) and sample 2i + 1 to 1 − P_i (or
//! arm −). Noise draw t goes to sample t.
//!
//! # Two baselines a competent experimenter would use instead
//!
//! The paper compares SCB against traditional CS solved as measured and against uncalibrated
//! double-arm detection. Three fairer baselines are schemes of their own:
//!
//! - **traditional CS, zero-mean solve** ([`Scheme::TraditionalZeroMean`]): the same frames and
//!   samples as traditional CS, reconstructed through the zero-mean ±1 system
//!   ([`crate::reconstruction::ZeroOneHandling::ZeroMeanOffset`], which also ignores the
//!   constant offset b₊ of the monitor) instead of the 0/1 system whose DC singular value
//!   stalls TVAL3;
//! - **double-arm, calibrated** ([`Scheme::DoubleArmCalibrated`]): before the patterns the DMD
//!   shows [`CALIBRATION_PAIRS`] pairs of all-on and all-off frames (counted in its frame
//!   budget). Each arm's response is affine in the light it receives, V± = k±·(light) + b±,
//!   whatever its gain, bias, dark current, ambient light or off-arm leak (a leak proportional
//!   to the + light only changes the − arm's effective gain). Two points fix an affine map, so
//!   with the averaged calibration values V₊(1), V₊(0), V₋(1), V₋(0) each arm is normalised to
//!   the fraction of the object it sees, and
//!
//!   ```text
//!   y_i = (V₊(P_i) − V₊(0)) / (V₊(1) − V₊(0)) − (V₋(P_i) − V₋(1)) / (V₋(0) − V₋(1))
//!       = P_i·x/Σx − (Σx − P_i·x)/Σx = Â_i·x / Σx,
//!   ```
//!
//!   a ±1 system with neither imbalance nor offset. What remains is the calibration's own noise
//!   and any departure from an affine, uniform response (per-unit differences between the two
//!   arms' transport maps on a traced bench).
//! - **double-arm, offset-aware solve** ([`Scheme::DoubleArmOffset`]): double-arm's own frames
//!   and samples, no calibration. Written with the 0/1 operator, double-arm's measurement is
//!   y = k₊Px + b₊ − k₋(Σx − Px) − b₋ = k'·Px + c, with c = b₊ − b₋ − k₋Σx the same for every
//!   frame: imbalance and offset together are one unknown constant. Solving for x and c jointly
//!   is the zero-mean 0/1 system without its DC row
//!   ([`crate::reconstruction::ZeroOneHandling::ZeroMeanOffset`], the least-squares
//!   elimination of c), as for `TraditionalZeroMean`. What it cannot remove is a c that changes
//!   from frame to frame: lamp drift multiplies k₋Σx, about half the signal, and nothing
//!   cancels it, whereas SCB's back-to-back complementary pair does.

use std::fmt;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::noise::AdditiveNoise;
use super::patterns::PatternSet;
use crate::error::{Error, Result};
use crate::reconstruction::{LinearOperator, PatternForm, ZeroOneHandling};

/// The DMD pattern rate used for acquisition times unless told otherwise: one global reset per
/// 44 µs (DLP7000 through a ViALUX controller; the paper's "up to 22 kHz"; docs/bench-facts.md §0.6).
pub const DEFAULT_DMD_RATE_HZ: f64 = 22_727.0;

/// Pairs of all-on / all-off calibration frames the calibrated double-arm scheme shows before
/// its patterns. Eight pairs average each calibration value over eight frames, so the
/// calibration's noise is about a third of one frame's while costing 16 frames, under 14 % of
/// the 5 % sampling budget (115 frames) of a 48 × 48 pattern and under 1 % at 100 %.
pub const CALIBRATION_PAIRS: usize = 8;

/// The frame sequences a DMD shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sequence {
    /// P₁, P₂, …: one frame per pattern.
    Base,
    /// P₁, 1 − P₁, P₂, 1 − P₂, …: a complementary pair back to back.
    Complementary,
    /// [`CALIBRATION_PAIRS`] × (all on, all off), then P₁, P₂, …
    CalibratedBase,
}

impl Sequence {
    pub fn key(self) -> &'static str {
        match self {
            Sequence::Base => "base",
            Sequence::Complementary => "complementary",
            Sequence::CalibratedBase => "calibrated_base",
        }
    }

    /// Every sequence, in the order records are kept.
    pub fn all() -> [Sequence; 3] {
        [
            Sequence::Base,
            Sequence::Complementary,
            Sequence::CalibratedBase,
        ]
    }

    /// Frames shown for `m` base patterns.
    pub fn frames(self, m: usize) -> usize {
        match self {
            Sequence::Base => m,
            Sequence::Complementary => 2 * m,
            Sequence::CalibratedBase => m + 2 * CALIBRATION_PAIRS,
        }
    }

    /// Frames shown before the first pattern (calibration frames).
    pub fn lead_frames(self) -> usize {
        match self {
            Sequence::CalibratedBase => 2 * CALIBRATION_PAIRS,
            Sequence::Base | Sequence::Complementary => 0,
        }
    }
}

/// The balanced detector's outputs, in the order of its recorded frame values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Output {
    /// The balanced RF output, G·(I₊ − I₋).
    Rf,
    /// The monitor of the + diode.
    MonitorPlus,
    /// The monitor of the − diode.
    MonitorMinus,
}

impl Output {
    /// Index into a frame's [RF, MONITOR+, MONITOR−] values (crate::detector's order).
    pub fn index(self) -> usize {
        match self {
            Output::Rf => crate::detector::RF,
            Output::MonitorPlus => crate::detector::MONITOR_PLUS,
            Output::MonitorMinus => crate::detector::MONITOR_MINUS,
        }
    }
}

/// The four acquisition schemes of the paper (§2 and §3), and two fairer baselines (module
/// documentation).
///
/// Experiment files spell them in snake_case: `traditional`, `single_arm_complementary`,
/// `double_arm`, `secondary_complementary_balancing`, `traditional_zero_mean`,
/// `double_arm_calibrated`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
// Files spell variants as Rust does (`CakeCutting`), the RON convention, or in snake_case
// (`cake_cutting`), which is what JSON output and benches written by spibench use.
#[serde(rename_all(serialize = "snake_case"))]
pub enum Scheme {
    /// Traditional CS: one arm (MONITOR+), one frame and one sample per pattern, A = P.
    #[serde(alias = "traditional")]
    Traditional,
    /// Single-arm complementary: MONITOR+ over P then 1 − P, difference, Â = 2P − 1.
    #[serde(alias = "single_arm_complementary")]
    SingleArmComplementary,
    /// Double-arm dual-pixel: MONITOR+ minus MONITOR− on the same frame, Â.
    #[serde(alias = "double_arm")]
    DoubleArm,
    /// Secondary complementary balancing: RF output over P then 1 − P, difference, Â.
    #[serde(alias = "secondary_complementary_balancing")]
    SecondaryComplementaryBalancing,
    /// Traditional CS's frames and samples, solved through the zero-mean ±1 system.
    #[serde(alias = "traditional_zero_mean")]
    TraditionalZeroMean,
    /// Double-arm with a two-point calibration of each arm from all-on / all-off frames.
    #[serde(alias = "double_arm_calibrated")]
    DoubleArmCalibrated,
    /// Double-arm's frames and samples, solved with one unknown constant offset (the zero-mean
    /// 0/1 system without its DC row): no calibration frames.
    #[serde(alias = "double_arm_offset")]
    DoubleArmOffset,
}

impl std::str::FromStr for Scheme {
    type Err = Error;

    /// A scheme's [`Scheme::key`] (an input error naming the keys otherwise).
    fn from_str(name: &str) -> Result<Scheme> {
        Scheme::all()
            .into_iter()
            .find(|s| s.key() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = Scheme::all().iter().map(|s| s.key()).collect();
                Error::field(
                    "scheme",
                    format!("unknown scheme {name:?}; one of {}", names.join(", ")),
                )
            })
    }
}

/// The noise-free measurement as an affine function of the object:
/// y = gain·(A x) + sum_coefficient·Σx + constant, with A the scheme's operator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineModel {
    pub gain: f64,
    pub sum_coefficient: f64,
    pub constant: f64,
}

impl Scheme {
    /// The paper's four schemes followed by the three baselines.
    pub fn all() -> [Scheme; 7] {
        [
            Scheme::Traditional,
            Scheme::SingleArmComplementary,
            Scheme::DoubleArm,
            Scheme::SecondaryComplementaryBalancing,
            Scheme::TraditionalZeroMean,
            Scheme::DoubleArmCalibrated,
            Scheme::DoubleArmOffset,
        ]
    }

    /// The paper's four schemes.
    pub fn paper() -> [Scheme; 4] {
        [
            Scheme::Traditional,
            Scheme::SingleArmComplementary,
            Scheme::DoubleArm,
            Scheme::SecondaryComplementaryBalancing,
        ]
    }

    /// How this scheme's 0/1 measurements must be solved, when the scheme fixes it
    /// (`TraditionalZeroMean`, `DoubleArmOffset`); otherwise the solver's own setting applies.
    pub fn zero_one(self) -> Option<ZeroOneHandling> {
        match self {
            Scheme::TraditionalZeroMean | Scheme::DoubleArmOffset => {
                Some(ZeroOneHandling::ZeroMeanOffset)
            }
            _ => None,
        }
    }

    /// Name for plots and summaries.
    pub fn label(self) -> &'static str {
        match self {
            Scheme::Traditional => "Traditional CS",
            Scheme::SingleArmComplementary => "Single-arm complementary",
            Scheme::DoubleArm => "Double-arm dual-pixel",
            Scheme::SecondaryComplementaryBalancing => "Secondary complementary balancing",
            Scheme::TraditionalZeroMean => "Traditional CS, zero-mean solve",
            Scheme::DoubleArmCalibrated => "Double-arm, calibrated",
            Scheme::DoubleArmOffset => "Double-arm, offset-aware solve",
        }
    }

    /// The snake_case name used in files (identical to the serde name).
    pub fn key(self) -> &'static str {
        match self {
            Scheme::Traditional => "traditional",
            Scheme::SingleArmComplementary => "single_arm_complementary",
            Scheme::DoubleArm => "double_arm",
            Scheme::SecondaryComplementaryBalancing => "secondary_complementary_balancing",
            Scheme::TraditionalZeroMean => "traditional_zero_mean",
            Scheme::DoubleArmCalibrated => "double_arm_calibrated",
            Scheme::DoubleArmOffset => "double_arm_offset",
        }
    }

    /// How the base patterns enter the reconstruction operator.
    pub fn form(self) -> PatternForm {
        match self {
            Scheme::Traditional | Scheme::TraditionalZeroMean | Scheme::DoubleArmOffset => {
                PatternForm::ZeroOne
            }
            _ => PatternForm::PlusMinusOne,
        }
    }

    /// DMD frames shown for `m` base patterns.
    pub fn dmd_frames(self, m: usize) -> usize {
        self.sequence().frames(m)
    }

    /// Detector samples recorded for `m` base patterns.
    pub fn detector_samples(self, m: usize) -> usize {
        self.dmd_frames(m) * self.outputs().len()
    }

    /// The frame sequence the scheme's DMD shows.
    pub fn sequence(self) -> Sequence {
        match self {
            Scheme::Traditional
            | Scheme::TraditionalZeroMean
            | Scheme::DoubleArm
            | Scheme::DoubleArmOffset => Sequence::Base,
            Scheme::SingleArmComplementary | Scheme::SecondaryComplementaryBalancing => {
                Sequence::Complementary
            }
            Scheme::DoubleArmCalibrated => Sequence::CalibratedBase,
        }
    }

    /// The detector outputs the scheme reads (the paper's §4 set-up): MONITOR+ for the one-arm
    /// schemes, both monitors for double-arm, the balanced RF output for SCB.
    pub fn outputs(self) -> &'static [Output] {
        match self {
            Scheme::Traditional | Scheme::TraditionalZeroMean | Scheme::SingleArmComplementary => {
                &[Output::MonitorPlus]
            }
            Scheme::DoubleArm | Scheme::DoubleArmCalibrated | Scheme::DoubleArmOffset => {
                &[Output::MonitorPlus, Output::MonitorMinus]
            }
            Scheme::SecondaryComplementaryBalancing => &[Output::Rf],
        }
    }

    /// The scheme's measurements y_i for the first `m` patterns from the recorded frame values
    /// of its sequence (`frames[k][o]`: frame k, output o in [`Output`] order).
    ///
    /// | scheme | y_i |
    /// |---|---|
    /// | traditional CS | V₊(P_i) |
    /// | single-arm complementary | V₊(P_i) − V₊(1 − P_i) |
    /// | double-arm dual-pixel | V₊(P_i) − V₋(P_i) |
    /// | secondary complementary balancing | V_rf(P_i) − V_rf(1 − P_i) |
    /// | traditional CS, zero-mean solve | V₊(P_i) |
    /// | double-arm, calibrated | two-point normalised V₊(P_i) − V₋(P_i) (module documentation) |
    /// | double-arm, offset-aware solve | V₊(P_i) − V₋(P_i) |
    pub fn measurements(self, frames: &[[f64; 3]], m: usize) -> Vec<f64> {
        let (rf, mp, mm) = (
            Output::Rf.index(),
            Output::MonitorPlus.index(),
            Output::MonitorMinus.index(),
        );
        // The calibration frames open the calibrated record (read only for that scheme); the
        // patterns follow them.
        let calibration =
            (self == Scheme::DoubleArmCalibrated).then(|| Calibration::from_frames(frames));
        let lead = self.sequence().lead_frames();
        (0..m)
            .map(|i| match self {
                Scheme::Traditional | Scheme::TraditionalZeroMean => frames[i][mp],
                Scheme::DoubleArmCalibrated => calibration.map_or(f64::NAN, |c| {
                    c.normalise(frames[lead + i][mp], frames[lead + i][mm])
                }),
                Scheme::DoubleArm | Scheme::DoubleArmOffset => frames[i][mp] - frames[i][mm],
                Scheme::SingleArmComplementary => frames[2 * i][mp] - frames[2 * i + 1][mp],
                Scheme::SecondaryComplementaryBalancing => {
                    frames[2 * i][rf] - frames[2 * i + 1][rf]
                }
            })
            .collect()
    }

    /// The noise-free model of the scheme (module documentation) for an object of total
    /// `total` = Σx (only the calibrated scheme's gain depends on it).
    pub fn model(self, arms: &ScalarArms, total: f64) -> AffineModel {
        let (kp, km) = (arms.k_plus, arms.k_minus);
        match self {
            Scheme::DoubleArmCalibrated => AffineModel {
                gain: 1.0 / total,
                sum_coefficient: 0.0,
                constant: 0.0,
            },
            Scheme::Traditional | Scheme::TraditionalZeroMean => AffineModel {
                gain: kp,
                sum_coefficient: 0.0,
                constant: arms.b_plus,
            },
            Scheme::SingleArmComplementary => AffineModel {
                gain: kp,
                sum_coefficient: 0.0,
                constant: 0.0,
            },
            // With the 0/1 operator P: y = k₊Px + b₊ − k₋(Σx − Px) − b₋.
            Scheme::DoubleArmOffset => AffineModel {
                gain: kp + km,
                sum_coefficient: -km,
                constant: arms.b_plus - arms.b_minus,
            },
            Scheme::DoubleArm => AffineModel {
                gain: 0.5 * (kp + km),
                sum_coefficient: 0.5 * (kp - km),
                constant: arms.b_plus - arms.b_minus,
            },
            Scheme::SecondaryComplementaryBalancing => AffineModel {
                gain: kp + km,
                sum_coefficient: 0.0,
                constant: 0.0,
            },
        }
    }
}

/// The two-point calibration of the arms from the [`CALIBRATION_PAIRS`] (all on, all off)
/// frame pairs that open a [`Sequence::CalibratedBase`] record: each monitor's mean over the
/// all-on and over the all-off frames, summed in frame order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    pub plus_on: f64,
    pub plus_off: f64,
    pub minus_on: f64,
    pub minus_off: f64,
}

impl Calibration {
    /// The calibration read from the first 2 × [`CALIBRATION_PAIRS`] frames (fewer if the
    /// record is shorter; an empty record gives NaN values, which the solver rejects).
    pub fn from_frames(frames: &[[f64; 3]]) -> Calibration {
        let (mp, mm) = (Output::MonitorPlus.index(), Output::MonitorMinus.index());
        let pairs = (frames.len() / 2).min(CALIBRATION_PAIRS);
        let mean = |parity: usize, o: usize| {
            let sum: f64 = (0..pairs).map(|k| frames[2 * k + parity][o]).sum();
            sum / pairs as f64
        };
        Calibration {
            plus_on: mean(0, mp),
            plus_off: mean(1, mp),
            minus_on: mean(0, mm),
            minus_off: mean(1, mm),
        }
    }

    /// The calibrated double-arm measurement of a frame with monitor values `v_plus`, `v_minus`:
    /// the + arm's fraction of its full-scale light minus the − arm's (module documentation).
    pub fn normalise(&self, v_plus: f64, v_minus: f64) -> f64 {
        (v_plus - self.plus_off) / (self.plus_on - self.plus_off)
            - (v_minus - self.minus_on) / (self.minus_off - self.minus_on)
    }
}

/// Scalar gains and biases of the two arms (paper Eqs. 6–9).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScalarArms {
    pub k_plus: f64,
    pub k_minus: f64,
    pub b_plus: f64,
    pub b_minus: f64,
}

impl ScalarArms {
    /// Balanced, unbiased arms: k± = 1, b± = 0.
    pub fn ideal() -> Self {
        ScalarArms {
            k_plus: 1.0,
            k_minus: 1.0,
            b_plus: 0.0,
            b_minus: 0.0,
        }
    }

    /// The paper's imbalanced example (§3, Fig. 1d–e): k₊ = 1.01, k₋ = 1.02, b₊ = 1, b₋ = 5.
    pub fn paper_imbalanced() -> Self {
        ScalarArms {
            k_plus: 1.01,
            k_minus: 1.02,
            b_plus: 1.0,
            b_minus: 5.0,
        }
    }

    /// The paper's imbalance sweep (§3, Figs. 2–3): k₊ = 1 and k₋ = k' − 1, no bias.
    pub fn from_k_prime(k_prime: f64) -> Self {
        ScalarArms {
            k_plus: 1.0,
            k_minus: k_prime - 1.0,
            b_plus: 0.0,
            b_minus: 0.0,
        }
    }

    /// k' = k₊ + k₋, the SCB image gain.
    pub fn k_prime(&self) -> f64 {
        self.k_plus + self.k_minus
    }

    /// Gains must be finite and positive (a zero gain is a missing detector), biases finite.
    pub fn validate(&self) -> Result<()> {
        for (name, k) in [("k_plus", self.k_plus), ("k_minus", self.k_minus)] {
            if !k.is_finite() || k <= 0.0 {
                return Err(Error::field(
                    name,
                    format!("an arm gain must be finite and > 0, got {k}"),
                ));
            }
        }
        for (name, b) in [("b_plus", self.b_plus), ("b_minus", self.b_minus)] {
            if !b.is_finite() {
                return Err(Error::field(
                    name,
                    format!("an arm bias must be finite, got {b}"),
                ));
            }
        }
        Ok(())
    }
}

/// One simulated acquisition: the measurements and what it cost.
#[derive(Clone)]
pub struct Acquisition {
    pub scheme: Scheme,
    /// The measurements used for reconstruction, length M.
    pub y: Vec<f64>,
    /// The recorded detector samples in recording order (module documentation), with noise.
    pub samples: Vec<f64>,
    /// A = P (traditional) or Â = 2P − 1 (the others), M × N.
    pub operator: Arc<dyn LinearOperator>,
    /// M, the number of base patterns.
    pub measurements: usize,
    pub dmd_frames: usize,
    pub detector_samples: usize,
    /// DMD frames divided by the DMD pattern rate.
    pub acquisition_time_s: f64,
}

impl fmt::Debug for Acquisition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Acquisition")
            .field("scheme", &self.scheme)
            .field("measurements", &self.measurements)
            .field("dmd_frames", &self.dmd_frames)
            .field("detector_samples", &self.detector_samples)
            .field("acquisition_time_s", &self.acquisition_time_s)
            .field(
                "operator",
                &format_args!("{}×{}", self.operator.rows(), self.operator.cols()),
            )
            .finish_non_exhaustive()
    }
}

/// Simulates `scheme` on object `x` (length N, row-major units) with `patterns`, scalar `arms`,
/// optional additive `noise` seeded with `seed` (draw t from `rng::stream(seed, t / 4096)`),
/// and a DMD running at `dmd_rate_hz`.
pub fn acquire(
    scheme: Scheme,
    x: &[f64],
    patterns: &PatternSet,
    arms: &ScalarArms,
    noise: Option<&AdditiveNoise>,
    seed: u64,
    dmd_rate_hz: f64,
) -> Result<Acquisition> {
    let n = patterns.units();
    let m = patterns.measurements();
    if x.len() != n {
        return Err(Error::field(
            "object",
            format!(
                "the object has {} values but the patterns have {n} units ({}×{})",
                x.len(),
                patterns.width(),
                patterns.height()
            ),
        ));
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(Error::field(
            "object",
            format!("object value {i} is {}, not a finite number", x[i]),
        ));
    }
    if !dmd_rate_hz.is_finite() || dmd_rate_hz <= 0.0 {
        return Err(Error::field(
            "dmd_rate_hz",
            format!("the DMD pattern rate must be finite and > 0 Hz, got {dmd_rate_hz}"),
        ));
    }
    arms.validate()?;
    if let Some(noise) = noise {
        noise.validate()?;
    }

    // P·x for every base pattern, and the complement (1 − P)·x = Σx − P·x.
    let mut px = vec![0.0; m];
    patterns.operator(PatternForm::ZeroOne).apply(x, &mut px);
    let total: f64 = x.iter().sum();
    let cx: Vec<f64> = px.iter().map(|p| total - p).collect();

    let count = scheme.detector_samples(m);
    let e = match noise {
        Some(noise) => noise.samples(seed, count),
        None => vec![0.0; count],
    };
    let ScalarArms {
        k_plus: kp,
        k_minus: km,
        b_plus: bp,
        b_minus: bm,
    } = *arms;
    // Monitor of arm ± and the RF output, for a frame whose ON pattern gives `on`·x and OFF
    // pattern `off`·x.
    let monitor_plus = |on: f64, e: f64| kp * (on + e) + bp;
    let monitor_minus = |off: f64, e: f64| km * (off + e) + bm;
    let rf = |on: f64, off: f64, e: f64| kp * on + bp - (km * off + bm) + e;

    let mut samples = Vec::with_capacity(count);
    let mut y = Vec::with_capacity(m);
    if scheme == Scheme::DoubleArmCalibrated {
        // Both monitors on every frame of the calibrated sequence: (all on, all off) pairs,
        // then the patterns; sample 2t is MONITOR+ of frame t, sample 2t + 1 MONITOR−.
        let lead = scheme.sequence().lead_frames();
        let light = |t: usize| -> (f64, f64) {
            match t.checked_sub(lead) {
                Some(i) => (px[i], cx[i]),
                None if t.is_multiple_of(2) => (total, 0.0),
                None => (0.0, total),
            }
        };
        let mut frames = Vec::with_capacity(lead + m);
        for t in 0..lead + m {
            let (on, off) = light(t);
            let sp = monitor_plus(on, e[2 * t]);
            let sm = monitor_minus(off, e[2 * t + 1]);
            samples.extend([sp, sm]);
            let mut f = [0.0; 3];
            f[Output::MonitorPlus.index()] = sp;
            f[Output::MonitorMinus.index()] = sm;
            frames.push(f);
        }
        y = scheme.measurements(&frames, m);
    }
    for i in 0..m {
        match scheme {
            Scheme::DoubleArmCalibrated => break,
            Scheme::Traditional | Scheme::TraditionalZeroMean => {
                let s = monitor_plus(px[i], e[i]);
                samples.push(s);
                y.push(s);
            }
            Scheme::SingleArmComplementary => {
                let s1 = monitor_plus(px[i], e[2 * i]);
                let s2 = monitor_plus(cx[i], e[2 * i + 1]);
                samples.extend([s1, s2]);
                y.push(s1 - s2);
            }
            Scheme::DoubleArm | Scheme::DoubleArmOffset => {
                let sp = monitor_plus(px[i], e[2 * i]);
                let sm = monitor_minus(cx[i], e[2 * i + 1]);
                samples.extend([sp, sm]);
                y.push(sp - sm);
            }
            Scheme::SecondaryComplementaryBalancing => {
                let b1 = rf(px[i], cx[i], e[2 * i]);
                let b2 = rf(cx[i], px[i], e[2 * i + 1]);
                samples.extend([b1, b2]);
                y.push(b1 - b2);
            }
        }
    }

    let dmd_frames = scheme.dmd_frames(m);
    Ok(Acquisition {
        scheme,
        y,
        samples,
        operator: patterns.operator(scheme.form()),
        measurements: m,
        dmd_frames,
        detector_samples: count,
        acquisition_time_s: dmd_frames as f64 / dmd_rate_hz,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acquisition::hadamard::HadamardOrdering;
    use crate::acquisition::patterns::{hadamard_set, random_set};

    /// A deterministic non-trivial 0–255 object.
    fn object(n: usize) -> Vec<f64> {
        (0..n).map(|i| ((i * 97 + 13) % 256) as f64).collect()
    }

    /// The base patterns as dense 0/1 rows.
    fn dense(set: &PatternSet) -> Vec<Vec<f64>> {
        let p = set.base_patterns();
        (0..p.rows())
            .map(|r| (0..p.cols()).map(|c| p.get(r, c) as u8 as f64).collect())
            .collect()
    }

    fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(u, v)| u * v).sum()
    }

    fn close(a: f64, b: f64, scale: f64) -> bool {
        (a - b).abs() <= 1e-12 * scale.max(1.0)
    }

    /// Paper Eqs. (6)–(12) evaluated with dense patterns, their dense complements and the same
    /// noise draws, sample by sample.
    fn dense_equations(
        scheme: Scheme,
        x: &[f64],
        p: &[Vec<f64>],
        arms: &ScalarArms,
        e: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let ScalarArms {
            k_plus: kp,
            k_minus: km,
            b_plus: bp,
            b_minus: bm,
        } = *arms;
        let (mut y, mut s) = (Vec::new(), Vec::new());
        if scheme == Scheme::DoubleArmCalibrated {
            // Eqs. (6) and (7) on every frame: 8 × (all on, all off), then the patterns; the
            // calibration values averaged, each arm mapped to its fraction of the object.
            let total: f64 = x.iter().sum();
            let lead = 2 * CALIBRATION_PAIRS;
            let mut v = Vec::new();
            for t in 0..lead + p.len() {
                let (on, off) = if t < lead {
                    if t.is_multiple_of(2) {
                        (total, 0.0)
                    } else {
                        (0.0, total)
                    }
                } else {
                    let a = dot(&p[t - lead], x);
                    (a, total - a)
                };
                let yp = kp * (on + e[2 * t]) + bp;
                let ym = km * (off + e[2 * t + 1]) + bm;
                s.extend([yp, ym]);
                v.push((yp, ym));
            }
            let mean = |f: &dyn Fn(&(f64, f64)) -> f64, parity: usize| {
                (0..CALIBRATION_PAIRS)
                    .map(|k| f(&v[2 * k + parity]))
                    .sum::<f64>()
                    / CALIBRATION_PAIRS as f64
            };
            let (p1, p0) = (mean(&|a| a.0, 0), mean(&|a| a.0, 1));
            let (m1, m0) = (mean(&|a| a.1, 0), mean(&|a| a.1, 1));
            for &(yp, ym) in &v[lead..] {
                y.push((yp - p0) / (p1 - p0) - (ym - m1) / (m0 - m1));
            }
            return (y, s);
        }
        for (i, row) in p.iter().enumerate() {
            let a_plus = row.clone();
            let a_minus: Vec<f64> = row.iter().map(|v| 1.0 - v).collect();
            match scheme {
                Scheme::DoubleArmCalibrated => unreachable!("returned above"),
                Scheme::Traditional | Scheme::TraditionalZeroMean => {
                    let v = kp * (dot(&a_plus, x) + e[i]) + bp;
                    s.push(v);
                    y.push(v);
                }
                Scheme::SingleArmComplementary => {
                    let v1 = kp * (dot(&a_plus, x) + e[2 * i]) + bp;
                    let v2 = kp * (dot(&a_minus, x) + e[2 * i + 1]) + bp;
                    s.extend([v1, v2]);
                    y.push(v1 - v2);
                }
                Scheme::DoubleArm | Scheme::DoubleArmOffset => {
                    // Eqs. (6) and (7): y'⁺ − y'⁻ on one frame.
                    let yp = kp * (dot(&a_plus, x) + e[2 * i]) + bp;
                    let ym = km * (dot(&a_minus, x) + e[2 * i + 1]) + bm;
                    s.extend([yp, ym]);
                    y.push(yp - ym);
                }
                Scheme::SecondaryComplementaryBalancing => {
                    // Eqs. (10)–(12) with the noise on each RF sample.
                    let b1 = kp * dot(&a_plus, x) + bp - (km * dot(&a_minus, x) + bm) + e[2 * i];
                    let b2 =
                        kp * dot(&a_minus, x) + bp - (km * dot(&a_plus, x) + bm) + e[2 * i + 1];
                    s.extend([b1, b2]);
                    y.push(b1 - b2);
                }
            }
        }
        (y, s)
    }

    fn small_sets() -> Vec<PatternSet> {
        vec![
            random_set(8, 8, 20, 0x5EED_0001).unwrap(),
            hadamard_set(8, HadamardOrdering::CakeCutting, 20).unwrap(),
        ]
    }

    #[test]
    fn every_scheme_matches_the_dense_equations() {
        let x = object(64);
        let scale = x.iter().sum::<f64>() * 3.0;
        for set in small_sets() {
            let p = dense(&set);
            for noise in [
                None,
                Some(AdditiveNoise::gaussian(3.0)),
                Some(AdditiveNoise::exponential(2.0)),
                Some(AdditiveNoise::poisson(4.0)),
            ] {
                for arms in [
                    ScalarArms::paper_imbalanced(),
                    ScalarArms::from_k_prime(20.0),
                ] {
                    for scheme in Scheme::all() {
                        let a = acquire(scheme, &x, &set, &arms, noise.as_ref(), 9, 1e3).unwrap();
                        let e = match &noise {
                            Some(n) => n.samples(9, scheme.detector_samples(20)),
                            None => vec![0.0; scheme.detector_samples(20)],
                        };
                        let (y, s) = dense_equations(scheme, &x, &p, &arms, &e);
                        assert_eq!(a.y.len(), 20);
                        assert_eq!(a.samples.len(), scheme.detector_samples(20));
                        for (u, v) in a.y.iter().zip(&y).chain(a.samples.iter().zip(&s)) {
                            assert!(close(*u, *v, scale), "{scheme:?} {noise:?}: {u} vs {v}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn noise_free_schemes_follow_their_affine_models() {
        // SCB: B₁ − B₂ = k'·Âx; double-arm: (k'/2)·Âx + ((k₊ − k₋)/2)·Σx + b₊ − b₋; the
        // others as in the module documentation. Âx and Px are evaluated densely.
        let x = object(64);
        let sum: f64 = x.iter().sum();
        for set in small_sets() {
            let p = dense(&set);
            for arms in [
                ScalarArms::paper_imbalanced(),
                ScalarArms::from_k_prime(3.0),
                ScalarArms {
                    k_plus: 0.37,
                    k_minus: 2.9,
                    b_plus: -4.0,
                    b_minus: 11.0,
                },
            ] {
                for scheme in Scheme::all() {
                    let a = acquire(scheme, &x, &set, &arms, None, 0, 1e3).unwrap();
                    let model = scheme.model(&arms, sum);
                    for (row, &yi) in p.iter().zip(&a.y) {
                        let ax = match scheme.form() {
                            PatternForm::ZeroOne => dot(row, &x),
                            PatternForm::PlusMinusOne => {
                                row.iter().zip(&x).map(|(r, v)| (2.0 * r - 1.0) * v).sum()
                            }
                        };
                        let expect = model.gain * ax + model.sum_coefficient * sum + model.constant;
                        assert!(close(yi, expect, 4.0 * sum), "{scheme:?}: {yi} vs {expect}");
                    }
                }
                // The stated closed forms of the two paper identities.
                let scb = Scheme::SecondaryComplementaryBalancing.model(&arms, sum);
                assert_eq!(scb.gain, arms.k_prime());
                assert_eq!((scb.sum_coefficient, scb.constant), (0.0, 0.0));
                let da = Scheme::DoubleArm.model(&arms, sum);
                assert_eq!(da.gain, arms.k_prime() / 2.0);
                assert_eq!(da.sum_coefficient, (arms.k_plus - arms.k_minus) / 2.0);
                assert_eq!(da.constant, arms.b_plus - arms.b_minus);
            }
        }
    }

    #[test]
    fn scb_identity_holds_to_rounding_and_double_arm_offset_is_visible() {
        let x = object(64);
        let arms = ScalarArms::paper_imbalanced();
        for set in small_sets() {
            let scb = acquire(
                Scheme::SecondaryComplementaryBalancing,
                &x,
                &set,
                &arms,
                None,
                0,
                DEFAULT_DMD_RATE_HZ,
            )
            .unwrap();
            let mut ahat = vec![0.0; 20];
            scb.operator.apply(&x, &mut ahat);
            let sum: f64 = x.iter().sum();
            for (y, a) in scb.y.iter().zip(&ahat) {
                // A few roundings of values up to k'·Σx ≈ 3e4: 1e-12 relative of that.
                assert!((y - arms.k_prime() * a).abs() <= 1e-12 * arms.k_prime() * sum);
            }
            let da = acquire(Scheme::DoubleArm, &x, &set, &arms, None, 0, 1e3).unwrap();
            let offset = (arms.k_plus - arms.k_minus) / 2.0 * sum + arms.b_plus - arms.b_minus;
            // −0.005·Σx − 4 ≈ −45 here: far above rounding, so the check below sees it.
            assert!(offset < -40.0, "{offset}");
            for (y, a) in da.y.iter().zip(&ahat) {
                assert!((y - (arms.k_prime() / 2.0 * a + offset)).abs() <= 1e-12 * 3.0 * sum);
            }
        }
    }

    #[test]
    fn frames_samples_and_time_per_scheme() {
        let x = object(64);
        let set = random_set(8, 8, 20, 1).unwrap();
        let expect = [
            (Scheme::Traditional, 20, 20),
            (Scheme::SingleArmComplementary, 40, 40),
            (Scheme::DoubleArm, 20, 40),
            (Scheme::SecondaryComplementaryBalancing, 40, 40),
            (Scheme::TraditionalZeroMean, 20, 20),
            (Scheme::DoubleArmCalibrated, 36, 72),
            (Scheme::DoubleArmOffset, 20, 40),
        ];
        for (scheme, frames, samples) in expect {
            let a = acquire(
                scheme,
                &x,
                &set,
                &ScalarArms::ideal(),
                None,
                0,
                DEFAULT_DMD_RATE_HZ,
            )
            .unwrap();
            assert_eq!(a.measurements, 20);
            assert_eq!((a.dmd_frames, a.detector_samples), (frames, samples));
            assert_eq!(a.samples.len(), samples);
            assert_eq!(a.acquisition_time_s, frames as f64 / 22_727.0);
            assert_eq!(a.operator.rows(), 20);
            assert_eq!(a.operator.cols(), 64);
        }
    }

    #[test]
    fn seeds_repeat_and_differ() {
        let x = object(64);
        let set = random_set(8, 8, 20, 1).unwrap();
        let noise = AdditiveNoise::poisson(3.0);
        let arms = ScalarArms::paper_imbalanced();
        for scheme in Scheme::all() {
            let run = |seed| {
                acquire(scheme, &x, &set, &arms, Some(&noise), seed, 1e3)
                    .unwrap()
                    .y
            };
            let a = run(5);
            let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&a), bits(&run(5)));
            assert_ne!(a, run(6));
        }
    }

    #[test]
    fn noise_means_cancel_only_in_complementary_differences() {
        // Exponential noise with σ = 10 has mean 10. Over M = 4096 measurements the residual
        // y − (noise-free y) has mean k·10 for traditional and 0 for the differences. Standard
        // error of the residual mean: k·σ/√M (one draw) or σ·√(k₊² + k±²)/√M (two draws), at
        // most 0.32 here; tolerance 5 SE.
        let x = object(1024);
        let set = random_set(32, 32, 4096, 8).unwrap();
        let arms = ScalarArms::ideal();
        let noise = AdditiveNoise::exponential(10.0);
        for scheme in Scheme::all() {
            let clean = acquire(scheme, &x, &set, &arms, None, 0, 1e3).unwrap();
            let noisy = acquire(scheme, &x, &set, &arms, Some(&noise), 3, 1e3).unwrap();
            // The calibrated scheme's measurements are fractions of the object total: scale
            // them back. Its calibration means (8 frames each) are shared by every
            // measurement, so their error does not average out over M.
            let scale = match scheme {
                Scheme::DoubleArmCalibrated => x.iter().sum::<f64>(),
                _ => 1.0,
            };
            let mean = noisy
                .y
                .iter()
                .zip(&clean.y)
                .map(|(a, b)| (a - b) * scale)
                .sum::<f64>()
                / 4096.0;
            let expected = match scheme {
                Scheme::Traditional | Scheme::TraditionalZeroMean => 10.0,
                _ => 0.0,
            };
            let se = match scheme {
                Scheme::DoubleArmCalibrated => 10.0 * (2.0 / 8.0 + 2.0 / 4096f64).sqrt(),
                _ => 10.0 * 2f64.sqrt() / 64.0,
            };
            assert!((mean - expected).abs() < 5.0 * se, "{scheme:?}: {mean}");
        }
    }

    #[test]
    fn bad_inputs_name_their_fields() {
        let set = random_set(8, 8, 20, 1).unwrap();
        let x = object(64);
        let arms = ScalarArms::ideal();
        let t = Scheme::DoubleArm;
        let field = |r: Result<Acquisition>| {
            let e = r.unwrap_err();
            assert!(e.is_user_error());
            e.to_string()
        };
        assert!(field(acquire(t, &x[..63], &set, &arms, None, 0, 1e3)).contains("`object`"));
        let mut bad = x.clone();
        bad[7] = f64::NAN;
        assert!(field(acquire(t, &bad, &set, &arms, None, 0, 1e3)).contains("`object`"));
        for rate in [0.0, -1.0, f64::INFINITY, f64::NAN] {
            assert!(field(acquire(t, &x, &set, &arms, None, 0, rate)).contains("`dmd_rate_hz`"));
        }
        let noise = AdditiveNoise::gaussian(-1.0);
        assert!(field(acquire(t, &x, &set, &arms, Some(&noise), 0, 1e3)).contains("`noise.std`"));
        let arms_bad = ScalarArms {
            k_minus: 0.0,
            ..arms
        };
        assert!(field(acquire(t, &x, &set, &arms_bad, None, 0, 1e3)).contains("`k_minus`"));
        let arms_bad = ScalarArms {
            b_plus: f64::INFINITY,
            ..arms
        };
        assert!(field(acquire(t, &x, &set, &arms_bad, None, 0, 1e3)).contains("`b_plus`"));
    }

    #[test]
    fn reproduces_the_tval3_reference_measurements() {
        // validation/tval3-phantom (README there): 10 % random set (1638 patterns, seed
        // 0x5EED0001) on the 128×128 phantom. y = Âx (ideal single-arm), y_imb = the paper's
        // imbalanced double-arm case, y_bal = SCB with the same arms = 2.03·y.
        use crate::report::npy;
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/validation/tval3-phantom/");
        let load = |name: &str| {
            npy::read(std::path::Path::new(&format!("{dir}{name}")))
                .unwrap()
                .to_f64()
        };
        let x = load("phantom_x.npy");
        let set = random_set(128, 128, 1638, 0x5EED_0001).unwrap();
        let sum: f64 = x.iter().sum();
        for (scheme, arms, file) in [
            (
                Scheme::SingleArmComplementary,
                ScalarArms::ideal(),
                "phantom_r10_y.npy",
            ),
            (
                Scheme::DoubleArm,
                ScalarArms::paper_imbalanced(),
                "phantom_r10_y_imb.npy",
            ),
            (
                Scheme::SecondaryComplementaryBalancing,
                ScalarArms::paper_imbalanced(),
                "phantom_r10_y_bal.npy",
            ),
        ] {
            let reference = load(file);
            let a = acquire(scheme, &x, &set, &arms, None, 0, DEFAULT_DMD_RATE_HZ).unwrap();
            assert_eq!(a.y.len(), reference.len());
            for (u, v) in a.y.iter().zip(&reference) {
                // Sums of up to 16384 values of at most 255 in another order: 1e-12 of 3·Σx.
                assert!((u - v).abs() <= 1e-12 * 3.0 * sum, "{scheme:?}: {u} vs {v}");
            }
        }
    }

    #[test]
    fn experiment_files_spell_schemes_and_arms() {
        use crate::scene::parse_ron;
        use std::path::Path;
        let p = Path::new("e.ron");
        for s in Scheme::all() {
            assert_eq!(parse_ron::<Scheme>(&format!("{s:?}"), p).unwrap(), s);
        }
        let arms: ScalarArms = parse_ron(
            "(k_plus: 1.01, k_minus: 1.02, b_plus: 1.0, b_minus: 5.0)",
            p,
        )
        .unwrap();
        assert_eq!(arms, ScalarArms::paper_imbalanced());
        assert!(parse_ron::<Scheme>("scb", p).is_err());
    }
}
