//! Summary schemas shared by every command that reports a traced bench: the transport block
//! (`trace`'s `summary.json`, `run`'s `transport` key, each `sweep` point), so that every
//! command writes the same keys with the same units.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::optics::Bench;
use crate::transport::metrics::BenchMetrics;
use crate::transport::{LedgerWorld, Transport};

/// `summary.json`. Currents in A, powers in W, efficiencies in A/W; every estimate has a
/// `_stderr` twin (Monte Carlo standard error, batch means); NaN is written as null.
#[derive(Debug, Clone, Serialize)]
pub struct TraceSummary {
    /// The bench file as given on the command line.
    pub scene: String,
    /// Lamp rays traced and the seed of the random streams.
    pub rays: u64,
    pub seed: u64,
    /// Traced wavelength band [min, max] (nm); every power here is within it.
    pub band_nm: [f64; 2],
    /// Pattern units across and down (the maps' width and height).
    pub units_across: usize,
    pub units_down: usize,
    /// Lamp rays whose path reached the pattern area (sampling diagnostic).
    pub arrivals: u64,
    /// Lamp power emitted in the traced band (W).
    pub lamp_band_power_w: f64,
    /// Σ_j x_j: power incident on the pattern-area mirrors (W).
    pub x_total_w: f64,
    pub x_total_w_stderr: f64,
    /// k± = Σ_j g±_j / Σ_j x_j (A/W).
    pub k_plus: f64,
    pub k_plus_stderr: f64,
    pub k_minus: f64,
    pub k_minus_stderr: f64,
    /// b± = c±: pattern-independent current of each arm (A), traced light + ambient + dark.
    pub b_plus: f64,
    pub b_plus_stderr: f64,
    pub b_minus: f64,
    pub b_minus_stderr: f64,
    /// k' = k₊ + k₋ (A/W), the SCB image scale.
    pub k_prime: f64,
    pub k_prime_stderr: f64,
    /// (k₊ − k₋)/(k₊ + k₋).
    pub imbalance: f64,
    pub imbalance_stderr: f64,
    /// Parts of b±: traced light (A), ambient (A, from the irradiance on the diode, its area
    /// and the mean 400–700 nm responsivity), dark current (A).
    pub b_traced_plus: f64,
    pub b_traced_minus: f64,
    pub b_ambient_plus: f64,
    pub b_ambient_minus: f64,
    pub b_dark_plus: f64,
    pub b_dark_minus: f64,
    /// The metrics of [`crate::transport::metrics::METRICS`] not given above, each with its
    /// `_stderr`: the detected powers `power_plus_w`, `power_minus_w` (W), the off-arm leaks
    /// `leak_plus`, `leak_minus` and the offset `b_minus_minus_b_plus` (A).
    #[serde(flatten)]
    pub metrics: BTreeMap<String, f64>,
    /// The flux ledger.
    pub ledger: LedgerSummary,
    /// With the diffractive DMD model only (`trace`): the collection with and without
    /// diffraction (docs/dmd_diffraction.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dmd_diffraction: Option<DiffractionSummary>,
    /// Output files (relative to the output directory).
    pub files: Vec<String>,
}

/// What `trace` reports on a bench whose DMD diffracts: the share of the power the pattern
/// mirrors reflect that reaches each diode (over the traced band), with geometric mirrors and
/// with the diffractive model, from two traces of the same rays (common random numbers).
#[derive(Debug, Clone, Serialize)]
pub struct DiffractionSummary {
    /// Lamp rays of each of the two collection traces.
    pub rays: u64,
    pub geometric: CollectionShares,
    pub diffractive: CollectionShares,
}

/// Shares of the reflected power of the mirrors in one state reaching one diode.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct CollectionShares {
    pub plus_from_plus: f64,
    pub minus_from_plus: f64,
    pub plus_from_minus: f64,
    pub minus_from_minus: f64,
}

impl CollectionShares {
    /// From a traced collection.
    pub fn of(c: &crate::trace::collection::Collection) -> CollectionShares {
        use crate::optics::Arm::{Minus, Plus};
        CollectionShares {
            plus_from_plus: c.share(Plus, Plus),
            minus_from_plus: c.share(Minus, Plus),
            plus_from_minus: c.share(Plus, Minus),
            minus_from_minus: c.share(Minus, Minus),
        }
    }
}

/// The flux ledger in `summary.json` (W).
#[derive(Debug, Clone, Serialize)]
pub struct LedgerSummary {
    /// Emitted in the band: the sampled ray weights plus the analytic power outside the traced
    /// emission cone (an unbiased estimate of `emitted_nominal_w`).
    pub emitted_w: f64,
    /// The lamp's band power.
    pub emitted_nominal_w: f64,
    /// Emitted outside the traced cone (booked to `lamp_housing`).
    pub outside_cone_w: f64,
    /// The bench with every pattern unit in state + ...
    pub all_plus: LedgerWorldSummary,
    /// ... and in state −.
    pub all_minus: LedgerWorldSummary,
}

/// Where the power went in one mirror-state world (W).
#[derive(Debug, Clone, Serialize)]
pub struct LedgerWorldSummary {
    /// Absorbed per bench element (element names as in the bench file, plus lamp_housing,
    /// dmd_mirrors, dmd_gaps, dmd_package, dmd_window, pd_*_housing).
    pub absorbed_w: BTreeMap<String, f64>,
    /// Left the bench without meeting anything.
    pub escaped_w: f64,
    /// Abandoned at the interaction cap.
    pub path_cap_w: f64,
    /// Reached photodiode + and −.
    pub detected_plus_w: f64,
    pub detected_minus_w: f64,
    /// Weight added by the tracer's sampled reflections (signed, zero in expectation).
    pub sampled_w: f64,
    /// emitted + sampled − (absorbed + escaped + path cap + detected): zero up to rounding.
    pub residual_w: f64,
}

fn world_summary(w: &LedgerWorld) -> LedgerWorldSummary {
    LedgerWorldSummary {
        absorbed_w: w.absorbed_w.iter().cloned().collect(),
        escaped_w: w.escaped_w,
        path_cap_w: w.path_cap_w,
        detected_plus_w: w.detected_w[0],
        detected_minus_w: w.detected_w[1],
        sampled_w: w.sampled_w,
        residual_w: w.residual_w,
    }
}

/// Builds the summary of a transport.
pub fn summarize(
    scene: &str,
    bench: &Bench,
    t: &Transport,
    metrics: &BenchMetrics,
    arrivals: u64,
) -> TraceSummary {
    let mut extra = BTreeMap::new();
    for name in [
        "power_plus_w",
        "power_minus_w",
        "leak_plus",
        "leak_minus",
        "b_minus_minus_b_plus",
    ] {
        if let Some(m) = metrics.get(name) {
            extra.insert(name.to_string(), m.value);
            extra.insert(format!("{name}_stderr"), m.stderr());
        }
    }
    TraceSummary {
        scene: scene.to_string(),
        rays: t.rays,
        seed: t.seed,
        band_nm: [round_nm(bench.band().0), round_nm(bench.band().1)],
        units_across: t.units_across,
        units_down: t.units_down,
        arrivals,
        lamp_band_power_w: bench.lamp().band_power_w,
        x_total_w: t.x_total.value,
        x_total_w_stderr: t.x_total.stderr,
        k_plus: t.k[0].value,
        k_plus_stderr: t.k[0].stderr,
        k_minus: t.k[1].value,
        k_minus_stderr: t.k[1].stderr,
        b_plus: t.b[0].value,
        b_plus_stderr: t.b[0].stderr,
        b_minus: t.b[1].value,
        b_minus_stderr: t.b[1].stderr,
        k_prime: t.k_prime.value,
        k_prime_stderr: t.k_prime.stderr,
        imbalance: t.imbalance.value,
        imbalance_stderr: t.imbalance.stderr,
        b_traced_plus: t.c_traced[0].value,
        b_traced_minus: t.c_traced[1].value,
        b_ambient_plus: t.ambient_a[0],
        b_ambient_minus: t.ambient_a[1],
        b_dark_plus: t.dark_a[0],
        b_dark_minus: t.dark_a[1],
        metrics: extra,
        ledger: LedgerSummary {
            emitted_w: t.ledger.emitted_w,
            emitted_nominal_w: t.ledger.emitted_nominal_w,
            outside_cone_w: t.ledger.outside_cone_w,
            all_plus: world_summary(&t.ledger.worlds[0]),
            all_minus: world_summary(&t.ledger.worlds[1]),
        },
        dmd_diffraction: None,
        files: Vec::new(),
    }
}

/// Metres to nanometres, rounded to 1e-6 nm (undoing the nm → m conversion's rounding).
fn round_nm(m: f64) -> f64 {
    (m * 1e15).round() / 1e6
}
