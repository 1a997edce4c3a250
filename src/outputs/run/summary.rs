//! The schema of `spibench run`'s `summary.json` (the transport block is `trace`'s,
//! crate::outputs::trace).

use serde::Serialize;

use crate::acquisition::Scheme;
use crate::detector::{Bap, Channel, FrameTiming, Scope};
use crate::metrics::NORMALIZATION_RULE;
use crate::outputs::trace::{TraceSummary, summarize};
use crate::run::{
    ResolutionContext, RunOutcome, RunSettings, Saturation, SchemeResult, SequenceSummary, Timings,
};

/// `summary.json` of `run`. SI units unless the key says otherwise; NaN and ∞ are null.
#[derive(Serialize)]
pub struct RunSummary<'a> {
    /// Always "run".
    pub command: &'static str,
    pub spibench_version: &'static str,
    /// The scene path, or the built-in bench's name.
    pub scene: String,
    pub title: &'a str,
    pub seed: u64,
    pub units_across: usize,
    pub units_down: usize,
    /// The traced transport: k±, b±, k', imbalance, standard errors, ledger (keys as in
    /// `spibench trace`'s summary.json).
    pub transport: TraceSummary,
    /// The balanced detector and the oscilloscope as used.
    pub electronics: ElectronicsSummary<'a>,
    /// DMD frame time, settling time, oscilloscope sample rate.
    pub frame_timing: FrameTiming,
    /// The run settings (sampling ratios, schemes, patterns, drift, noise, solver).
    pub settings: &'a RunSettings,
    /// How reconstructions are brought to the ideal object's scale before scoring.
    pub normalization: &'static str,
    /// The ideal object: 255·x_j / max x, with max x (W).
    pub truth: &'static str,
    pub x_max_w: f64,
    /// The recorded frame sequences.
    pub sequences: &'a [SequenceSummary],
    /// True when any output was clipped or any channel over range; see `saturation`.
    pub saturated: bool,
    pub saturation: &'a [Saturation],
    /// Scheme-major, ratio-minor.
    pub results: &'a [SchemeResult],
    /// The USAF resolution read-out: the registration of x against the chart, the criterion,
    /// and what x itself resolves (null without a registrable USAF chart). Each result carries
    /// its `finest_resolved`.
    pub resolution: Option<&'a ResolutionContext>,
    /// Observations computed from the results (never tuned).
    pub findings: FindingsBlock,
    /// Output files, relative to the output folder.
    pub files: Vec<String>,
    /// Wall-clock timings (s): differ between identical runs, so they are not serialised here
    /// (summary.json is byte-identical for a seed); the CLI writes them to timings.json.
    #[serde(skip)]
    pub timings: Timings,
}

/// The electronics in summary.json.
#[derive(Serialize)]
pub struct ElectronicsSummary<'a> {
    pub detector: &'a Bap,
    /// The bench's common-mode rejection with the arms' k± in it (dB; null when infinite):
    /// crate::transport::metrics::cmrr_db of the traced imbalance and the diodes' mismatch.
    pub cmrr_db: Option<f64>,
    /// Its Monte Carlo standard error (dB).
    pub cmrr_db_stderr: Option<f64>,
    /// The detector's CMRR from the diodes' flat responsivity mismatch alone (dB; null when
    /// infinite, i.e. for exactly matched diodes: the model subtracts their currents ideally and
    /// has no amplifier CMRR of its own): what the bench would reject with perfectly matched arms.
    pub cmrr_electronics_db: Option<f64>,
    /// The electrical imbalance (s₊k₊ − s₋k₋)/(s₊k₊ + s₋k₋): the traced (optical) imbalance as
    /// the difference output sees it through the diodes' responsivity factors
    /// (crate::transport::metrics::electrical_imbalance).
    pub imbalance_electrical: f64,
    /// Its Monte Carlo standard error.
    pub imbalance_electrical_stderr: f64,
    /// Optical power difference that drives the RF output to its swing at 0.65 A/W (W).
    pub rf_saturation_power_w_at_0_65_a_per_w: f64,
    pub oscilloscope: &'a Scope,
    /// The channels as set: [rf, monitor_plus, monitor_minus].
    pub channels: ChannelsSummary,
    /// Rms output noise of each output at the mean currents of the recorded frames (V):
    /// shot and amplifier noise over the one-pole noise bandwidth.
    pub output_noise_v_rms: NamedOutputs,
}

#[derive(Serialize)]
pub struct ChannelsSummary {
    pub rf: Channel,
    pub monitor_plus: Channel,
    pub monitor_minus: Channel,
}

#[derive(Serialize)]
pub struct NamedOutputs {
    pub rf: f64,
    pub monitor_plus: f64,
    pub monitor_minus: f64,
}

/// The `findings` block of `summary.json`: comparisons the paper draws, computed from this run.
#[derive(Serialize)]
pub struct FindingsBlock {
    /// Ratios at which secondary complementary balancing has a higher MSSIM than double-arm
    /// dual-pixel, and at which it does not (both schemes run).
    pub scb_beats_double_arm_at: Vec<f64>,
    pub scb_not_above_double_arm_at: Vec<f64>,
    /// MSSIM of secondary complementary balancing minus that of traditional CS at the highest
    /// ratio (both schemes run).
    pub scb_minus_traditional_mssim_at_max_ratio: Option<f64>,
    /// Solves (scheme × ratio) of the plain run that TVAL3 ended on a cap (`maxcnt` outer loops
    /// or `maxit` iterations) rather than on its tolerance, and all the solves.
    pub solves_at_cap: usize,
    pub solves: usize,
    /// The standings the report and the printed summary open with (crate::run::findings):
    /// `repeats`, `basis`, `mssim` and `psnr_db`, each at every ratio and at equal frames.
    /// summarize_run fills them from its one outcome; `spibench run --repeats N` from all N.
    #[serde(flatten)]
    pub standings: crate::run::findings::Record,
}

fn findings(o: &RunOutcome) -> FindingsBlock {
    let s = &o.settings;
    let mut beats = Vec::new();
    let mut not = Vec::new();
    for (r, &ratio) in s.sampling_ratios.iter().enumerate() {
        if let (Some(scb), Some(dbl)) = (
            o.result(Scheme::SecondaryComplementaryBalancing, r),
            o.result(Scheme::DoubleArm, r),
        ) {
            if scb.mssim > dbl.mssim {
                beats.push(ratio);
            } else {
                not.push(ratio);
            }
        }
    }
    let last = s
        .sampling_ratios
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i);
    let scb_trad = last.and_then(|r| {
        Some(
            o.result(Scheme::SecondaryComplementaryBalancing, r)?.mssim
                - o.result(Scheme::Traditional, r)?.mssim,
        )
    });
    FindingsBlock {
        scb_beats_double_arm_at: beats,
        scb_not_above_double_arm_at: not,
        scb_minus_traditional_mssim_at_max_ratio: scb_trad,
        solves_at_cap: o
            .results
            .iter()
            .filter(|r| r.stop != crate::reconstruction::tval3::StopReason::Tolerance)
            .count(),
        solves: o.results.len(),
        standings: crate::run::findings::Findings::of(std::slice::from_ref(o)).record(),
    }
}

/// Builds the summary of an outcome.
pub fn summarize_run<'a>(
    name: &str,
    bench: &crate::optics::Bench,
    o: &'a RunOutcome,
    files: Vec<String>,
) -> RunSummary<'a> {
    let mut transport = summarize(name, bench, &o.transport, &o.metrics, o.trace_arrivals);
    transport.files = Vec::new();
    let mean_i = mean_currents(o);
    let noise = o.detector.output_noise_v_rms(mean_i);
    let cmrr = o.cmrr();
    let electronics_only = o.detector.cmrr_db();
    let electrical = crate::transport::metrics::electrical_imbalance(
        &o.metrics[crate::quantities::BenchMetric::Imbalance],
        o.detector.responsivity_scale,
    );
    RunSummary {
        command: "run",
        spibench_version: env!("CARGO_PKG_VERSION"),
        scene: name.to_string(),
        title: &o.settings.title,
        seed: o.seed,
        units_across: o.transport.units_across,
        units_down: o.transport.units_down,
        transport,
        electronics: ElectronicsSummary {
            detector: &o.detector,
            cmrr_db: cmrr.value.is_finite().then_some(cmrr.value),
            cmrr_db_stderr: cmrr.stderr().is_finite().then_some(cmrr.stderr()),
            cmrr_electronics_db: electronics_only.is_finite().then_some(electronics_only),
            imbalance_electrical: electrical.value,
            imbalance_electrical_stderr: electrical.stderr(),
            rf_saturation_power_w_at_0_65_a_per_w: o.detector.rf_saturation_power_w(0.65),
            oscilloscope: &o.scope,
            channels: ChannelsSummary {
                rf: o.channels[0],
                monitor_plus: o.channels[1],
                monitor_minus: o.channels[2],
            },
            output_noise_v_rms: NamedOutputs {
                rf: noise[0],
                monitor_plus: noise[1],
                monitor_minus: noise[2],
            },
        },
        frame_timing: o.timing,
        settings: &o.settings,
        normalization: NORMALIZATION_RULE,
        truth: "255 * x_j / max(x): x_j the traced power incident on unit j's mirrors",
        x_max_w: o.x.max(),
        sequences: &o.sequences,
        saturated: !o.saturation.is_empty(),
        saturation: &o.saturation,
        results: &o.results,
        resolution: o.resolution.as_ref(),
        findings: findings(o),
        files,
        timings: o.timings,
    }
}

/// Mean diode currents over a random pattern: half of each arm's pattern light plus the rest.
fn mean_currents(o: &RunOutcome) -> [f64; 2] {
    let t = &o.transport;
    let light = [0, 1].map(|d| 0.5 * t.g_a[d].iter().sum::<f64>() + t.c_traced[d].value);
    o.detector.diode_currents(light, t.ambient_a, t.dark_a)
}
