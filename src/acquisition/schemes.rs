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
mod tests;
