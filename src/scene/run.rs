//! The two optional sections of a bench file that `spibench run` reads: `electronics` (the
//! balanced amplified photodetector and the oscilloscope) and `run` (what to acquire and how to
//! reconstruct it). Both may be omitted, wholly or field by field: every field has a default,
//! documented below with its source and confidence (H: manufacturer or computed, M: secondary
//! source, L: estimate; see docs/bench-facts.md).
//!
//! ```ron
//! (
//!     lamp: (...), elements: [...], dmd: (...), detectors: (...),
//!     electronics: (
//!         detector: (load: FiftyOhm, responsivity_scale_minus: 0.99),
//!         oscilloscope: (sample_rate_hz: 5e6, rf: Fixed(volts_per_div: 0.01, offset_v: 0.0)),
//!     ),
//!     run: (sampling_ratios: [0.25, 1.0], schemes: [SecondaryComplementaryBalancing]),
//! )
//! ```
//!
//! Units are in the field names (`_hz`, `_v`, `_us`, `_a_per_rthz`); [`RunScene`] holds the
//! same values in SI after validation. Single values are checked while reading (the error has
//! the line and column); relations between values (a settling time longer than the frame, a
//! sample rate that leaves no sample in the settled window) are checked after reading and the
//! error names the field and the line where it is written (or the section, when the field was
//! left at its default).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::acquisition::{AdditiveNoise, DEFAULT_DMD_RATE_HZ, PatternFamily, Scheme};
use crate::detector::{
    Bap, ChannelRange, Drift, Load, OutputStage, RecordModel, Scope, ScopeNoise,
};
use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::reconstruction::tval3::Tval3Options;
use crate::scene::bench::{BenchFile, NonNegative, Positive, build_bench};
use crate::scene::experiment::{NoiseSpec, PatternsSpec, Ratio};
use crate::scene::locate;
use crate::scene::numbers::{Count, OffsetV, via};

/// Everything `spibench run` needs, validated and in SI.
#[derive(Debug, Clone)]
pub struct RunScene {
    pub bench: Bench,
    pub detector: Bap,
    pub scope: Scope,
    pub settings: RunSettings,
}

/// The largest number of oscilloscope samples one run may simulate (both sequences, all
/// frames): 2·10⁹ samples is hours of work, almost certainly a typing error in a rate.
pub const MAX_SCOPE_SAMPLES: f64 = 2e9;

/// The largest number of rays a run may trace (10¹⁰ rays is about a day on two cores).
pub const MAX_RAYS: u64 = 10_000_000_000;

/// The fewest rays a traced number's standard error needs: the trace's standard errors are batch
/// means over batches of `trace::RAYS_PER_BATCH` (1024) rays, and two full batches are the
/// fewest that give a spread (one batch gave NaN standard errors; `cli::args` ties the two
/// constants by a test).
pub const MIN_RAYS: u64 = 2048;

/// The largest output or oscilloscope offset (V): far beyond any amplifier or scope input.
pub const MAX_OFFSET_V: f64 = 1e3;

/// The run settings in SI (the `run` section of a bench file, validated).
#[derive(Debug, Clone, Serialize)]
pub struct RunSettings {
    pub title: String,
    pub rays: u64,
    pub sampling_ratios: Vec<f64>,
    pub schemes: Vec<Scheme>,
    pub patterns: PatternFamily,
    pub dmd_rate_hz: f64,
    pub settling_time_s: f64,
    pub drift: Drift,
    pub noise: bool,
    pub additive_noise: Option<AdditiveNoise>,
    pub solver: Tval3Options,
    pub signal_trace_frames: usize,
    /// How the detector outputs are recorded: sample by sample (`spibench run`, the reference)
    /// or frame by frame (datasets choose it in their spec). Not a field of the bench file.
    #[serde(skip)]
    pub record: RecordModel,
}

// ---------------------------------------------------------------------------------------------
// electronics

/// The `electronics` section.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ElectronicsSpec {
    /// The balanced amplified photodetector (Thorlabs PDB210A/M class).
    pub detector: DetectorSpec,
    /// The oscilloscope (Tektronix MSO64 class) that records the three outputs.
    pub oscilloscope: ScopeSpec,
}

/// What the detector's outputs drive (the oscilloscope's input termination). Thorlabs
/// amplified detectors drive their BNC outputs through a 50 Ω series resistor, so the gain and
/// swing into a 50 Ω load are half those into a high impedance (docs/bench-facts.md §1.1, L).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
pub enum LoadSpec {
    /// 1 MΩ oscilloscope input (the usual choice for a 1 MHz detector).
    HighImpedance,
    /// 50 Ω termination.
    FiftyOhm,
}

/// The balanced detector: two diodes, an RF (difference) output and two monitor outputs.
///
/// The diodes' spectral responsivity tables are the bench's `detectors.plus.responsivity` and
/// `detectors.minus.responsivity` (applied wavelength by wavelength during the trace). The two
/// `responsivity_scale_*` factors multiply each diode's photocurrent on top of its table: a
/// flat (grey) mismatch between the two diodes of one device. A mismatch δ between the two
/// diodes makes a common-mode input appear at the RF output with relative size δ, so the
/// common-mode rejection ratio is CMRR = 20·log₁₀(1/δ) dB.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectorSpec {
    /// Load on every output. Default `HighImpedance`.
    pub load: LoadSpec,
    /// The RF (difference) output, V = G·(I₊ − I₋) + offset.
    pub rf: RfSpec,
    /// MONITOR+ (diode +), V = G·I₊ + offset.
    pub monitor_plus: MonitorSpec,
    /// MONITOR− (diode −), V = G·I₋ + offset.
    pub monitor_minus: MonitorSpec,
    /// Photocurrent scale of diode + relative to its table. Default 1.
    pub responsivity_scale_plus: Positive,
    /// Photocurrent scale of diode − relative to its table. Default 0.97: a 3 % mismatch, i.e.
    /// a CMRR of 30.5 dB, within the "≥ 25–30 dB" estimate for the PDB210A (docs/bench-facts.md §1.1,
    /// L; the PDB4xx family is specified > 20 dB, H).
    pub responsivity_scale_minus: Positive,
    /// Shot noise 2qI of each diode's total current (signal, ambient and dark). Default true.
    pub shot_noise: bool,
}

impl Default for DetectorSpec {
    fn default() -> Self {
        DetectorSpec {
            load: LoadSpec::HighImpedance,
            rf: RfSpec::default(),
            monitor_plus: MonitorSpec::default(),
            monitor_minus: MonitorSpec::default(),
            responsivity_scale_plus: Positive(1.0),
            responsivity_scale_minus: Positive(0.97),
            shot_noise: true,
        }
    }
}

/// Frequency response of an output.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum BandwidthSpec {
    /// A single real pole at `bandwidth_hz` (−3 dB), the usual transimpedance response.
    OnePole {
        /// The −3 dB bandwidth (Hz).
        bandwidth_hz: Positive,
    },
}

/// Amplifier noise referred to the input.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum AmplifierNoiseSpec {
    /// Input current noise density (A/√Hz).
    InputCurrent {
        /// Input current noise density (A/√Hz).
        a_per_rthz: NonNegative,
    },
    /// Noise-equivalent power (W/√Hz) at a wavelength where the diode's responsivity is
    /// `responsivity_a_per_w`; the input current noise is their product.
    Nep {
        /// Noise-equivalent power (W/√Hz).
        w_per_rthz: NonNegative,
        /// The diode's responsivity at the NEP's wavelength (A/W).
        responsivity_a_per_w: Positive,
    },
}

impl AmplifierNoiseSpec {
    fn a_per_rthz(self) -> f64 {
        match self {
            AmplifierNoiseSpec::InputCurrent { a_per_rthz } => a_per_rthz.0,
            AmplifierNoiseSpec::Nep {
                w_per_rthz,
                responsivity_a_per_w,
            } => w_per_rthz.0 * responsivity_a_per_w.0,
        }
    }
}

/// The RF output.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RfSpec {
    /// Transimpedance into a high impedance (V/A). Default 350 × 10³: twice the 50 Ω value
    /// (docs/bench-facts.md §1.1, L).
    pub gain_high_z_v_per_a: Positive,
    /// Transimpedance into 50 Ω (V/A). Default 175 × 10³ (docs/bench-facts.md §1.1, M). A real unit
    /// can differ by tens of per cent (a measured unit gave 258 kV/W at 795 nm, M).
    pub gain_50_ohm_v_per_a: Positive,
    /// Output swing ±V into a high impedance. Default 10 V (docs/bench-facts.md §1.1, L: the manual's
    /// value was not found).
    pub swing_high_z_v: Positive,
    /// Output swing ±V into 50 Ω. Default 3.6 V (docs/bench-facts.md §1.1, L).
    pub swing_50_ohm_v: Positive,
    /// Output offset with no light (V). Default 2 mV ("< ± a few mV", docs/bench-facts.md §1.1, L).
    #[serde(deserialize_with = "via::<OffsetV, _, _>")]
    pub offset_v: f64,
    /// Default `OnePole(bandwidth_hz: 1e6)`: DC–1 MHz (docs/bench-facts.md §1.1, M).
    pub bandwidth: BandwidthSpec,
    /// Default `InputCurrent(a_per_rthz: 2.3e-12)`: ≈ 1 mV rms at 350 kV/A over a 1 MHz
    /// one-pole bandwidth, i.e. an NEP of ≈ 3.5 pW/√Hz at 0.65 A/W (docs/bench-facts.md §1.1, L).
    pub noise: AmplifierNoiseSpec,
}

impl Default for RfSpec {
    fn default() -> Self {
        RfSpec {
            gain_high_z_v_per_a: Positive(350e3),
            gain_50_ohm_v_per_a: Positive(175e3),
            swing_high_z_v: Positive(10.0),
            swing_50_ohm_v: Positive(3.6),
            offset_v: 2e-3,
            bandwidth: BandwidthSpec::OnePole {
                bandwidth_hz: Positive(1e6),
            },
            noise: AmplifierNoiseSpec::InputCurrent {
                a_per_rthz: NonNegative(2.3e-12),
            },
        }
    }
}

/// A monitor output (MONITOR+ or MONITOR−).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MonitorSpec {
    /// Transimpedance into a high impedance (V/A). Default 17.5 × 10³: the manual's monitor
    /// calibration of 10 V/mW at 795 nm divided by 0.57 A/W (docs/bench-facts.md §1.1, L).
    pub gain_high_z_v_per_a: Positive,
    /// Transimpedance into 50 Ω (V/A). Default 8.75 × 10³ (half, as for the RF output, L).
    pub gain_50_ohm_v_per_a: Positive,
    /// Output swing ±V into a high impedance. Default 10 V (PDB44x monitor, docs/bench-facts.md §1.2,
    /// H for that family, L here).
    pub swing_high_z_v: Positive,
    /// Output swing ±V into 50 Ω. Default 1.5 V (PDB44x monitor, docs/bench-facts.md §1.2, L here).
    pub swing_50_ohm_v: Positive,
    /// Output offset with no light (V). Default 1 mV (L).
    #[serde(deserialize_with = "via::<OffsetV, _, _>")]
    pub offset_v: f64,
    /// Default `OnePole(bandwidth_hz: 1e6)`: the PDB4xx fast monitors are DC–1 MHz
    /// (docs/bench-facts.md §1.2, L for the PDB210A).
    pub bandwidth: BandwidthSpec,
    /// Default `InputCurrent(a_per_rthz: 2.3e-12)`, as the RF amplifier (L).
    pub noise: AmplifierNoiseSpec,
}

impl Default for MonitorSpec {
    fn default() -> Self {
        MonitorSpec {
            gain_high_z_v_per_a: Positive(17.5e3),
            gain_50_ohm_v_per_a: Positive(8.75e3),
            swing_high_z_v: Positive(10.0),
            swing_50_ohm_v: Positive(1.5),
            offset_v: 1e-3,
            bandwidth: BandwidthSpec::OnePole {
                bandwidth_hz: Positive(1e6),
            },
            noise: AmplifierNoiseSpec::InputCurrent {
                a_per_rthz: NonNegative(2.3e-12),
            },
        }
    }
}

/// The vertical setting of one oscilloscope channel.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum ChannelSpec {
    /// As an operator would set it: the smallest 1-2-5 volts/division that holds the
    /// noise-free signal of the whole acquisition in 8 of the 10 divisions, centred by the
    /// vertical offset.
    Auto,
    /// 10 divisions of `volts_per_div` centred on `offset_v`.
    Fixed {
        /// Vertical scale (V per division).
        volts_per_div: Positive,
        /// Vertical offset (V): the voltage at the screen's centre.
        #[serde(deserialize_with = "via::<OffsetV, _, _>")]
        offset_v: f64,
    },
}

/// The oscilloscope.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScopeSpec {
    /// Recorded sample rate (Hz). Default 10 MS/s: High Res mode decimates the 25 GS/s ADC
    /// stream to the record rate (docs/bench-facts.md §8, M); 10 MS/s oversamples the 1 MHz detector
    /// tenfold and keeps a 0.2 s acquisition within the standard 62.5 Mpts record (L: a setting,
    /// not a fact).
    pub sample_rate_hz: Positive,
    /// ADC bits of the recorded samples. Default 16: High Res at ≤ 625 MS/s (docs/bench-facts.md §8,
    /// M/L).
    #[serde(deserialize_with = "via::<Count<1, 24>, _, _>")]
    pub bits: u32,
    /// Analog bandwidth (Hz). Default 4 GHz (option 6-BW-4000, docs/bench-facts.md §8, M).
    pub analog_bandwidth_hz: Positive,
    /// High Res acquisition: the noise bandwidth shrinks to 0.44 × the sample rate (boxcar rule,
    /// docs/bench-facts.md §8, H). Without it the full analog bandwidth's noise aliases into every
    /// sample. Default true.
    pub high_res: bool,
    /// Input noise floor at full bandwidth (V rms). Default 50 µV (docs/bench-facts.md §8: "order
    /// 50–100 µV rms at 1 mV/div", L).
    pub noise_floor_v_rms: NonNegative,
    /// Input noise that grows with the vertical scale, as a fraction of one division (rms, at
    /// full bandwidth). Default 0.006 (L: typical of 12-bit scopes at 4 GHz).
    pub noise_fraction_of_div: NonNegative,
    /// Channel of the RF output. Default `Auto`.
    pub rf: ChannelSpec,
    /// Channel of MONITOR+. Default `Auto`.
    pub monitor_plus: ChannelSpec,
    /// Channel of MONITOR−. Default `Auto`.
    pub monitor_minus: ChannelSpec,
}

impl Default for ScopeSpec {
    fn default() -> Self {
        ScopeSpec {
            sample_rate_hz: Positive(10e6),
            bits: 16,
            analog_bandwidth_hz: Positive(4e9),
            high_res: true,
            noise_floor_v_rms: NonNegative(50e-6),
            noise_fraction_of_div: NonNegative(0.006),
            rf: ChannelSpec::Auto,
            monitor_plus: ChannelSpec::Auto,
            monitor_minus: ChannelSpec::Auto,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// run

/// The `run` section.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunSpec {
    /// Title of montages and plots. Default "spibench run".
    pub title: String,
    /// Lamp rays to trace for the transport. Default 2 × 10⁶ (about 7 s on two cores for the
    /// paper bench, which gives k± to about 0.09 % relative standard error).
    #[serde(deserialize_with = "via::<Count<MIN_RAYS, MAX_RAYS>, _, _>")]
    pub rays: u64,
    /// Sampling ratios M/N, each in (0, 1]. Default the paper's Fig. 6: 5, 10, 15, 20, 40, 60,
    /// 80 and 100 %.
    pub sampling_ratios: Vec<Ratio>,
    /// Schemes to run. Default the paper's four in its order, then the two fairer baselines
    /// (traditional CS solved zero-mean, calibrated double-arm).
    pub schemes: Vec<Scheme>,
    /// Base patterns: `Random(seed: S)` (default, seed 1) or `Hadamard(ordering: O)`
    /// (2^m × 2^m units only).
    pub patterns: PatternsSpec,
    /// DMD binary pattern rate (Hz). Default 22 727 Hz: one global reset per 44 µs, the
    /// paper's "up to 22 kHz" (docs/bench-facts.md §2.4, M/H).
    pub dmd_rate_hz: Positive,
    /// Mirror settling time at the start of each frame (µs), excluded from the frame's mean.
    /// Default 13 µs (DLP7000 settling after a global reset, docs/bench-facts.md §2.4, H).
    pub settling_time_us: NonNegative,
    /// Lamp and ambient drift.
    pub drift: DriftSpec,
    /// `false` switches off every random process (shot, amplifier and oscilloscope noise, drift,
    /// ripple, flicker) and the quantisation: the noise-free limit of the same bench. Clipping
    /// stays. Default true.
    pub noise: bool,
    /// The paper's idealised additive noise (§3), in volts, added to every recorded frame value
    /// of every output on top of the physical noise. Default none.
    pub additive_noise: Option<NoiseSpec>,
    /// TVAL3 options. Default: the settings of the TVAL3 reference runs (mu 2⁸, beta 2⁵ without
    /// continuation, tol 10⁻⁴, maxit 300, isotropic TV, u ≥ 0); when given, unset fields take
    /// TVAL3's own defaults.
    pub solver: Option<Tval3Options>,
    /// Frames of each output kept as sampled signal traces (for plots). Default 6.
    #[serde(deserialize_with = "via::<Count<0, 1000>, _, _>")]
    pub signal_trace_frames: usize,
}

impl Default for RunSpec {
    fn default() -> Self {
        RunSpec {
            title: "spibench run".to_string(),
            rays: 2_000_000,
            sampling_ratios: [0.05, 0.1, 0.15, 0.2, 0.4, 0.6, 0.8, 1.0]
                .into_iter()
                .map(Ratio)
                .collect(),
            schemes: Scheme::all().to_vec(),
            patterns: PatternsSpec::default(),
            dmd_rate_hz: Positive(DEFAULT_DMD_RATE_HZ),
            settling_time_us: NonNegative(13.0),
            drift: DriftSpec::default(),
            noise: true,
            additive_noise: None,
            solver: None,
            signal_trace_frames: 6,
        }
    }
}

/// Slow multiplicative processes. The lamp's factor 1 + d(t) + r(t) multiplies all traced
/// light (both arms: common mode); the ambient factor multiplies the ambient current of both
/// diodes. d(t) is an Ornstein–Uhlenbeck process (stationary rms, correlation time), r(t) a
/// sinusoid of random phase.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DriftSpec {
    /// Relative rms of the lamp's intensity drift. Default 10⁻³ (L: a stabilised QTH source
    /// such as the SLS201L; no datasheet value in docs/bench-facts.md).
    pub lamp_drift_rms: NonNegative,
    /// Correlation time of the lamp drift (s). Default 10 s (L: thermal time scales of a bulb
    /// and its housing).
    pub lamp_drift_time_s: Positive,
    /// Relative amplitude of the lamp's ripple. Default 2 × 10⁻⁴ (L: a regulated DC supply).
    pub lamp_ripple_amplitude: NonNegative,
    /// Ripple frequency (Hz). Default 100 Hz (twice the 50 Hz mains, L).
    pub lamp_ripple_hz: Positive,
    /// Relative rms of the ambient light's slow drift. Default 0.05 (L).
    pub ambient_drift_rms: NonNegative,
    /// Correlation time of the ambient drift (s). Default 10 s (L).
    pub ambient_drift_time_s: Positive,
    /// Relative modulation depth of room-light flicker. Default 0.1 (L: lamps on 50 Hz mains
    /// flicker at 100 Hz by several to tens of per cent).
    pub ambient_flicker_depth: NonNegative,
    /// Flicker frequency (Hz). Default 100 Hz (L).
    pub ambient_flicker_hz: Positive,
}

impl Default for DriftSpec {
    fn default() -> Self {
        DriftSpec {
            lamp_drift_rms: NonNegative(1e-3),
            lamp_drift_time_s: Positive(10.0),
            lamp_ripple_amplitude: NonNegative(2e-4),
            lamp_ripple_hz: Positive(100.0),
            ambient_drift_rms: NonNegative(0.05),
            ambient_drift_time_s: Positive(10.0),
            ambient_flicker_depth: NonNegative(0.1),
            ambient_flicker_hz: Positive(100.0),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Reading and conversion.

/// Parses and validates a run scene; `path` names the file in errors and anchors relative
/// paths.
pub fn parse_run_scene(text: &str, path: &Path) -> Result<RunScene> {
    let file: BenchFile = crate::scene::parse_ron(text, path)?;
    run_scene(&file, Some(text), path)
}

/// Converts a parsed bench file into a run scene; `text` is its source when it has one (for
/// error lines), as in [`build_bench`].
pub fn run_scene(file: &BenchFile, text: Option<&str>, path: &Path) -> Result<RunScene> {
    let bench = build_bench(file, text, path)?;
    let locate = |e: Error, section: &str, field: &str| locate_error(e, text, path, section, field);
    let (detector, scope) = electronics_si(&file.electronics, text, path)?;
    let settings = settings_si(&file.run).map_err(|(f, e)| locate(e, "run", f))?;
    if bench.dmd().is_none() {
        return Err(Error::field("dmd", "`run` needs a bench with a DMD").in_file(path));
    }
    check_relations(&bench, &scope, &settings).map_err(|(f, e)| {
        let section = if f.starts_with("sample_rate") {
            "electronics"
        } else {
            "run"
        };
        locate(e, section, f)
    })?;
    Ok(RunScene {
        bench,
        detector,
        scope,
        settings,
    })
}

/// The `electronics:` section of a file (`text` at `path`, a bench or a dataset spec) in SI:
/// the detector and the oscilloscope, errors located in that file.
pub fn electronics_si(
    e: &ElectronicsSpec,
    text: Option<&str>,
    path: &Path,
) -> Result<(Bap, Scope)> {
    let locate = |er: Error, field: &str| locate_error(er, text, path, "electronics", field);
    let detector = detector_si(&e.detector).map_err(|(f, er)| locate(er, f))?;
    let scope = scope_si(&e.oscilloscope).map_err(|(f, er)| locate(er, f))?;
    Ok((detector, scope))
}

/// Adds the file, the field and (when the field is written in the file) its line: the first
/// `field:` after the top-level `section:`, or the section itself when the field is not written.
fn locate_error(e: Error, text: Option<&str>, path: &Path, section: &str, field: &str) -> Error {
    let e = e.in_file(path).at_field(field);
    match text {
        Some(t) => locate::at(e, t, locate::key_after(t, section, field)),
        None => e,
    }
}

type FieldResult<T> = std::result::Result<T, (&'static str, Error)>;

fn stage(
    load: LoadSpec,
    gains: (f64, f64),
    swings: (f64, f64),
    offset_v: f64,
    bandwidth: BandwidthSpec,
    noise: AmplifierNoiseSpec,
) -> OutputStage {
    let (gain, swing) = match load {
        LoadSpec::HighImpedance => (gains.0, swings.0),
        LoadSpec::FiftyOhm => (gains.1, swings.1),
    };
    let BandwidthSpec::OnePole { bandwidth_hz } = bandwidth;
    OutputStage {
        gain_v_per_a: gain,
        swing_v: swing,
        offset_v,
        bandwidth_hz: bandwidth_hz.0,
        input_noise_a_per_rthz: noise.a_per_rthz(),
    }
}

/// The detector section in SI.
pub fn detector_si(d: &DetectorSpec) -> FieldResult<Bap> {
    let rf = stage(
        d.load,
        (d.rf.gain_high_z_v_per_a.0, d.rf.gain_50_ohm_v_per_a.0),
        (d.rf.swing_high_z_v.0, d.rf.swing_50_ohm_v.0),
        d.rf.offset_v,
        d.rf.bandwidth,
        d.rf.noise,
    );
    let mon = |m: &MonitorSpec| {
        stage(
            d.load,
            (m.gain_high_z_v_per_a.0, m.gain_50_ohm_v_per_a.0),
            (m.swing_high_z_v.0, m.swing_50_ohm_v.0),
            m.offset_v,
            m.bandwidth,
            m.noise,
        )
    };
    let monitors = [mon(&d.monitor_plus), mon(&d.monitor_minus)];
    for (v, f) in [
        (d.responsivity_scale_plus.0, "responsivity_scale_plus"),
        (d.responsivity_scale_minus.0, "responsivity_scale_minus"),
    ] {
        if v > 2.0 {
            return Err((
                f,
                Error::input(format!(
                    "a responsivity scale of {v} is not a small mismatch (expected 0 < s ≤ 2)"
                )),
            ));
        }
    }
    Ok(Bap {
        load: match d.load {
            LoadSpec::HighImpedance => Load::HighImpedance,
            LoadSpec::FiftyOhm => Load::FiftyOhm,
        },
        rf,
        monitors,
        responsivity_scale: [d.responsivity_scale_plus.0, d.responsivity_scale_minus.0],
        shot_noise: d.shot_noise,
    })
}

/// The oscilloscope section in SI.
pub fn scope_si(s: &ScopeSpec) -> FieldResult<Scope> {
    let channel = |c: ChannelSpec| match c {
        ChannelSpec::Auto => ChannelRange::Auto,
        ChannelSpec::Fixed {
            volts_per_div,
            offset_v,
        } => ChannelRange::Fixed {
            volts_per_div: volts_per_div.0,
            offset_v,
        },
    };
    Ok(Scope {
        sample_rate_hz: s.sample_rate_hz.0,
        bits: s.bits,
        noise: ScopeNoise {
            floor_v_rms: s.noise_floor_v_rms.0,
            fraction_of_div: s.noise_fraction_of_div.0,
            analog_bandwidth_hz: s.analog_bandwidth_hz.0,
            high_res: s.high_res,
        },
        channels: [
            channel(s.rf),
            channel(s.monitor_plus),
            channel(s.monitor_minus),
        ],
    })
}

/// The run section in SI.
pub fn settings_si(r: &RunSpec) -> FieldResult<RunSettings> {
    if r.sampling_ratios.is_empty() {
        return Err((
            "sampling_ratios",
            Error::input("at least one sampling ratio is needed"),
        ));
    }
    if r.schemes.is_empty() {
        return Err(("schemes", Error::input("at least one scheme is needed")));
    }
    for (i, s) in r.schemes.iter().enumerate() {
        if r.schemes[..i].contains(s) {
            return Err((
                "schemes",
                Error::input(format!("scheme {s:?} is listed twice")),
            ));
        }
    }
    let solver = r.solver.clone().unwrap_or_else(|| Tval3Options {
        mu0: Some(256.0),
        beta0: Some(32.0),
        ..Tval3Options::reference()
    });
    solver.validate().map_err(|e| ("solver", e))?;
    let d = &r.drift;
    Ok(RunSettings {
        title: r.title.clone(),
        rays: r.rays,
        sampling_ratios: r.sampling_ratios.iter().map(|x| x.0).collect(),
        schemes: r.schemes.clone(),
        patterns: r.patterns.family(),
        dmd_rate_hz: r.dmd_rate_hz.0,
        settling_time_s: r.settling_time_us.0 * 1e-6,
        drift: Drift {
            lamp_drift_rms: d.lamp_drift_rms.0,
            lamp_drift_time_s: d.lamp_drift_time_s.0,
            lamp_ripple_amplitude: d.lamp_ripple_amplitude.0,
            lamp_ripple_hz: d.lamp_ripple_hz.0,
            ambient_drift_rms: d.ambient_drift_rms.0,
            ambient_drift_time_s: d.ambient_drift_time_s.0,
            ambient_flicker_depth: d.ambient_flicker_depth.0,
            ambient_flicker_hz: d.ambient_flicker_hz.0,
        },
        noise: r.noise,
        additive_noise: r
            .additive_noise
            .map(|n: NoiseSpec| -> AdditiveNoise { n.0 }),
        solver,
        signal_trace_frames: r.signal_trace_frames,
        record: RecordModel::Samples,
    })
}

/// Checks between sections: the frame timing against the sample rate, the pattern kind against
/// the pattern area, and the amount of work.
fn check_relations(bench: &Bench, scope: &Scope, s: &RunSettings) -> FieldResult<()> {
    let frame_s = 1.0 / s.dmd_rate_hz;
    if s.settling_time_s >= frame_s {
        return Err((
            "settling_time_us",
            Error::input(format!(
                "the settling time ({:.3} µs) must be shorter than the frame (1/dmd_rate_hz = \
                 {:.3} µs)",
                s.settling_time_s * 1e6,
                frame_s * 1e6
            )),
        ));
    }
    let settled = (frame_s - s.settling_time_s) * scope.sample_rate_hz;
    if settled < 2.0 {
        return Err((
            "sample_rate_hz",
            Error::input(format!(
                "{} S/s leaves {settled:.2} samples in each frame's settled window of {:.3} µs; \
                 at least 2 are needed",
                scope.sample_rate_hz,
                (frame_s - s.settling_time_s) * 1e6
            )),
        ));
    }
    let (across, down) = bench.units_shape();
    let n = across * down;
    let max_m = s
        .sampling_ratios
        .iter()
        .map(|&r| crate::acquisition::patterns_for_ratio(r, n))
        .max()
        .unwrap_or(1);
    // Both sequences: M frames of P alone and 2M frames of P, 1 − P.
    let samples = 3.0 * max_m as f64 * frame_s * scope.sample_rate_hz;
    if samples > MAX_SCOPE_SAMPLES {
        return Err((
            "sample_rate_hz",
            Error::input(format!(
                "{samples:.3e} oscilloscope samples per channel (3·M frames at {} S/s) is absurd \
                 (more than {MAX_SCOPE_SAMPLES:e})",
                scope.sample_rate_hz
            )),
        ));
    }
    // Checked here, where the bench file's `run.patterns` is located, and not first when the
    // patterns are built (a field `patterns` of no file).
    if let PatternFamily::Hadamard { .. } = s.patterns
        && (across != down || !across.is_power_of_two())
    {
        return Err((
            "patterns",
            Error::input(format!(
                "Hadamard patterns need a square pattern area of 2^m × 2^m units (Sylvester \
                 construction), got {across}×{down} units: use Random patterns, or a side such \
                 as {} or {}",
                across.next_power_of_two() / 2,
                across.next_power_of_two()
            )),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper_text() -> String {
        std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/paper_bench.ron"
        ))
        .unwrap()
    }

    fn with_sections(extra: &str) -> String {
        let t = paper_text();
        let end = t.rfind(')').unwrap();
        format!("{}{}\n)\n", &t[..end], extra)
    }

    #[test]
    fn defaults_apply_without_sections() {
        let s = parse_run_scene(&paper_text(), Path::new("paper_bench.ron")).unwrap();
        assert_eq!(s.detector.rf.gain_v_per_a, 350e3);
        assert_eq!(s.detector.rf.swing_v, 10.0);
        assert_eq!(s.detector.monitors[0].gain_v_per_a, 17.5e3);
        assert_eq!(s.detector.responsivity_scale, [1.0, 0.97]);
        assert_eq!(s.scope.sample_rate_hz, 10e6);
        assert_eq!(s.settings.sampling_ratios.len(), 8);
        assert_eq!(
            s.settings.schemes,
            crate::acquisition::Scheme::all().to_vec()
        );
        assert!((s.settings.settling_time_s - 13e-6).abs() < 1e-18);
        assert_eq!(s.settings.solver.maxit, 300);
        assert!(s.settings.solver.nonneg);
    }

    #[test]
    fn fifty_ohm_load_halves_the_gain() {
        let text = with_sections("electronics: (detector: (load: FiftyOhm)),");
        let s = parse_run_scene(&text, Path::new("b.ron")).unwrap();
        assert_eq!(s.detector.rf.gain_v_per_a, 175e3);
        assert_eq!(s.detector.rf.swing_v, 3.6);
        assert_eq!(s.detector.monitors[1].swing_v, 1.5);
    }

    #[test]
    fn nep_is_converted_to_input_current() {
        let text = with_sections(
            "electronics: (detector: (rf: (noise: Nep(w_per_rthz: 2e-12, responsivity_a_per_w: 0.5)))),",
        );
        let s = parse_run_scene(&text, Path::new("b.ron")).unwrap();
        assert!((s.detector.rf.input_noise_a_per_rthz - 1e-12).abs() < 1e-27);
    }

    #[test]
    fn unknown_field_names_line_and_field() {
        let text = with_sections("run: (sampling_ratio: [0.5]),");
        let e = parse_run_scene(&text, Path::new("b.ron")).unwrap_err();
        let s = e.to_string();
        assert!(e.is_user_error());
        assert!(s.contains("sampling_ratio"), "{s}");
        assert!(s.contains("line"), "{s}");
    }

    #[test]
    fn bad_values_are_input_errors_with_field() {
        for (extra, field) in [
            ("run: (sampling_ratios: [1.5]),", "sampling_ratios"),
            ("run: (settling_time_us: 50.0),", "settling_time_us"),
            (
                "electronics: (oscilloscope: (sample_rate_hz: 30000.0)),",
                "sample_rate_hz",
            ),
            (
                "electronics: (detector: (rf: (offset_v: -1.0, gain_high_z_v_per_a: -3.0))),",
                "gain_high_z_v_per_a",
            ),
            ("run: (schemes: []),", "schemes"),
            ("run: (rays: 0),", "rays"),
            ("electronics: (oscilloscope: (bits: 0)),", "bits"),
        ] {
            let text = with_sections(extra);
            let e = parse_run_scene(&text, Path::new("b.ron")).unwrap_err();
            let s = e.to_string();
            assert!(e.is_user_error(), "{extra}: {s}");
            assert!(s.contains(field), "{extra}: {s}");
            assert!(s.contains("b.ron"), "{extra}: {s}");
            assert!(s.contains("line"), "{extra}: {s}");
        }
    }
}
