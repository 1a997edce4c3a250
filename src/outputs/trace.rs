//! The outputs of `spibench trace` (docs/outputs.md, "trace"): `summary.json` ([`TraceSummary`],
//! also the transport block of `run`'s summary, so that every command that reports a traced
//! bench writes the same keys with the same units), `maps.exr` (one multi-channel EXR of the
//! per-unit maps, f32, row-major, row 0 = the top row of the pattern area, [`maps`]) and one
//! figure per map (`NAME.svg`, its rendering `NAME.png` and `NAME.pdf`: one square per unit,
//! axes of unit indices, a colour bar in the map's unit, dark units hatched,
//! `report::heatmap::UnitMap`). With the diffractive DMD model (docs/dmd_diffraction.md) the
//! collection of the DMD's reflected light with and without diffraction: `summary.json` gains
//! `dmd_diffraction`, and `collection.svg`/`.png`/`.pdf` plot each arm's collection against
//! wavelength, the lamp's light and the diodes' responsivity shaded behind.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::optics::Bench;
use crate::quantities::BenchMetric;
use crate::trace::collection::Collection;
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
    /// The metrics of [`crate::quantities::BenchMetric`] not given above, each with its
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
    /// The irradiance maps on the diodes (`trace`; crate::outputs::irradiance).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub irradiance: Option<super::irradiance::IrradianceSummary>,
    /// The maps at the named surfaces (`trace --irradiance-at`), in the order named.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub irradiance_at: Vec<super::irradiance::SurfaceIrradiance>,
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

impl DiffractionSummary {
    /// The shares of the two collections of `trace::collection::diffraction_pair` (geometric,
    /// diffractive), each traced with `rays`.
    pub fn of(rays: u64, [geometric, diffractive]: &[Collection; 2]) -> DiffractionSummary {
        DiffractionSummary {
            rays,
            geometric: CollectionShares::of(geometric),
            diffractive: CollectionShares::of(diffractive),
        }
    }
}

impl CollectionShares {
    /// From a traced collection.
    pub fn of(c: &Collection) -> CollectionShares {
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
        BenchMetric::PowerPlusW,
        BenchMetric::PowerMinusW,
        BenchMetric::LeakPlus,
        BenchMetric::LeakMinus,
        BenchMetric::BMinusMinusBPlus,
    ] {
        let m = &metrics[name];
        extra.insert(name.to_string(), m.value);
        extra.insert(format!("{name}_stderr"), m.stderr());
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
        irradiance: None,
        irradiance_at: Vec::new(),
        files: Vec::new(),
    }
}

/// Metres to nanometres, rounded to 1e-6 nm (undoing the nm → m conversion's rounding).
fn round_nm(m: f64) -> f64 {
    (m * 1e15).round() / 1e6
}

/// The per-unit maps written to the EXR (channel name, values).
pub fn maps(t: &Transport) -> Vec<(&'static str, Vec<f64>)> {
    vec![
        ("x_w", t.x_w.clone()),
        ("g_plus_a", t.g_a[0].clone()),
        ("g_minus_a", t.g_a[1].clone()),
        ("k_plus_a_per_w", t.k_map[0].clone()),
        ("k_minus_a_per_w", t.k_map[1].clone()),
        ("k_plus_stderr", t.k_map_stderr[0].clone()),
        ("k_minus_stderr", t.k_map_stderr[1].clone()),
        ("x_stderr_w", t.x_map_stderr.clone()),
        ("g_plus_stderr_a", t.g_map_stderr[0].clone()),
        ("g_minus_stderr_a", t.g_map_stderr[1].clone()),
    ]
}

/// Writes every output of a trace into `dir` (a staging folder): the EXR, the five map figures
/// and, with `collections`, the collection figure; `summary.files` is set to what was written
/// and `summary.json` written last, with its provenance first.
#[cfg(feature = "figures")]
pub fn write(
    dir: &crate::report::output::OutputDir,
    t: &Transport,
    summary: &mut TraceSummary,
    provenance: &crate::provenance::Provenance,
    collections: Option<&[Collection; 2]>,
    bench: &Bench,
) -> crate::Result<()> {
    use crate::report::exr::write_channels;
    use crate::report::heatmap::{UnitMap, write_unit_map};
    use rayon::prelude::*;
    let mut files = Vec::new();
    let (w, h) = (t.units_across, t.units_down);
    let maps = maps(t);
    let f32s: Vec<Vec<f32>> = maps
        .iter()
        .map(|(_, v)| v.iter().map(|&x| x as f32).collect())
        .collect();
    let channels: Vec<(&str, &[f32])> = maps
        .iter()
        .zip(&f32s)
        .map(|((n, _), v)| (*n, v.as_slice()))
        .collect();
    let unit_maps = [
        ("x", "x_j", "W", &t.x_w, true),
        ("g_plus", "g₊_j", "A", &t.g_a[0], false),
        ("g_minus", "g₋_j", "A", &t.g_a[1], false),
        ("k_plus", "k₊_j", "A/W", &t.k_map[0], true),
        ("k_minus", "k₋_j", "A/W", &t.k_map[1], true),
    ];
    // The EXR and the five maps (SVG, PNG and PDF each; the PNG and PDF compression is most of
    // the time) are independent files, written side by side: serial, they were the largest
    // serial part of `trace` on many threads.
    let (exr, written) = rayon::join(
        || write_channels(&dir.path("maps.exr"), w, h, &channels),
        || {
            unit_maps
                .par_iter()
                .map(|&(stem, label, unit, values, from_zero)| {
                    let map = UnitMap {
                        label: label.into(),
                        unit: unit.into(),
                        width: w,
                        height: h,
                        values: values.clone(),
                        light_w: t.x_w.clone(),
                        from_zero,
                    };
                    let (svg, png) = (format!("{stem}.svg"), format!("{stem}.png"));
                    write_unit_map(&map, &dir.path(&svg), &dir.path(&png))?;
                    Ok([svg, png, format!("{stem}.pdf")])
                })
                .collect::<Vec<crate::Result<_>>>()
        },
    );
    exr?;
    files.push("maps.exr".to_string());
    // The first failing map's error in order, on any thread count.
    files.extend(crate::error::in_order(written)?.into_iter().flatten());
    if let Some(c) = collections {
        let (plot, opts) = collection_plot(c, bench);
        crate::report::plot::write_plot_with(
            &plot,
            &opts,
            &dir.path("collection.svg"),
            &dir.path("collection.png"),
        )?;
        for ext in ["svg", "png", "pdf"] {
            files.push(format!("collection.{ext}"));
        }
    }
    summary.files = files;
    super::summary::write_summary(dir, &*summary, provenance)
}

/// The figure of each arm's collection against wavelength, both models, with the spectrum of
/// the light on the pattern (the lamp's, after the optics before the DMD) and each diode's
/// responsivity shaded behind the curves, each normalised to a peak of 1 on the right-hand
/// scale. Diodes with one responsivity curve share one shaded area.
#[cfg(feature = "figures")]
fn collection_plot(
    c: &[Collection; 2],
    bench: &Bench,
) -> (
    crate::report::plot::LinePlot,
    crate::report::plot::PlotOptions,
) {
    use crate::optics::Arm;
    use crate::report::plot::{Area, LinePlot, PlotOptions, Series};
    let [geometric, diffractive] = c;
    let x: Vec<f64> = (0..geometric.bins)
        .map(|b| geometric.wavelength_m(b) * 1e9)
        .collect();
    let mut series = Vec::new();
    for arm in Arm::ALL {
        for (name, col) in [("geometric", geometric), ("diffractive", diffractive)] {
            series.push(Series {
                label: format!("arm {} ({name})", arm.label()),
                x: x.clone(),
                y: (0..col.bins).map(|b| col.share_in(b, arm, arm)).collect(),
                y_err: None,
            });
        }
    }
    let scaled = |v: Vec<f64>| {
        let peak = v.iter().cloned().fold(0.0, f64::max);
        v.into_iter()
            .map(|y| if peak > 0.0 { y / peak } else { 0.0 })
            .collect::<Vec<f64>>()
    };
    // The shaded curves on a finer grid than the bins, so that their shapes show.
    let fine: Vec<f64> = {
        let (lo, hi) = (geometric.band_m.0 * 1e9, geometric.band_m.1 * 1e9);
        (0..=200)
            .map(|k| lo + (hi - lo) * f64::from(k) / 200.0)
            .collect()
    };
    let mut areas = vec![Area {
        label: "lamp light on the pattern".into(),
        x: x.clone(),
        y: scaled(diffractive.incident_w.clone()),
    }];
    let resp: Vec<Vec<f64>> = Arm::ALL
        .iter()
        .map(|&arm| {
            let r = &bench.detectors()[arm].responsivity;
            scaled(fine.iter().map(|nm| r.at(nm * 1e-9)).collect())
        })
        .collect();
    if resp[0] == resp[1] {
        areas.push(Area {
            label: "diode responsivity".into(),
            x: fine.clone(),
            y: resp[0].clone(),
        });
    } else {
        for (arm, y) in Arm::ALL.iter().zip(resp) {
            areas.push(Area {
                label: format!("diode {} responsivity", arm.label()),
                x: fine.clone(),
                y,
            });
        }
    }
    let plot = LinePlot {
        title: "Each arm's collection of the DMD-reflected light against wavelength".into(),
        x_label: "wavelength (nm)".into(),
        y_label: "share on the arm's diode".into(),
        series,
        log_x: false,
    };
    let opts = PlotOptions {
        size: None,
        areas,
        area_label: "relative (peak = 1)".into(),
        ..PlotOptions::default()
    };
    (plot, opts)
}

/// The summary card of `spibench trace` (from its summary.json as a value): k±, k′, the
/// imbalance, b±, the off-arm leaks and the light on the pattern, with their standard errors.
pub fn card(summary: &serde_json::Value) -> crate::outputs::card::Card {
    use crate::outputs::card::{Card, num, pm};
    let mut c = Card::new("summary");
    let pmv = |v: &[serde_json::Value], unit: &str| pm(num(&v[0]), num(&v[1]), unit);
    for (label, keys, unit) in [
        ("k₊, k₋", ["k_plus", "k_minus"], "A/W"),
        ("b₊, b₋", ["b_plus", "b_minus"], "A"),
        ("off-arm leak +, −", ["leak_plus", "leak_minus"], ""),
    ] {
        let p: Vec<String> = keys
            .iter()
            .flat_map(|k| [format!("/{k}"), format!("/{k}_stderr")])
            .collect();
        c.line(summary, label, &p, |v| {
            format!("{}, {}", pmv(&v[..2], unit), pmv(&v[2..], unit))
        });
    }
    c.line(
        summary,
        "k′ = k₊ + k₋",
        &["/k_prime", "/k_prime_stderr"],
        |v| pmv(v, "A/W"),
    );
    c.line(
        summary,
        "imbalance, optical",
        &["/imbalance", "/imbalance_stderr"],
        |v| format!("{} ((k₊ − k₋)/(k₊ + k₋))", pmv(v, "")),
    );
    c.line(
        summary,
        "light on the pattern",
        &["/x_total_w", "/x_total_w_stderr"],
        |v| pmv(v, "W"),
    );
    c
}

/// What `spibench trace` prints: the gains and offsets of each arm, k', the imbalance, the
/// light on the pattern and the ledger's residual, and with the diffractive model each diode's
/// share of the pattern mirrors' reflected power under both models.
pub fn printed(s: &TraceSummary, seconds: f64) -> Vec<String> {
    let pm = |v: f64, e: f64| format!("{v:.6e} ± {e:.1e}");
    let mut out = vec![
        format!(
            "{}: {} rays (seed {}) in {seconds:.1} s",
            s.scene, s.rays, s.seed
        ),
        format!("  {:<10} {:>28} {:>28}", "", "arm +", "arm −"),
        format!(
            "  {:<10} {:>28} {:>28}",
            "k (A/W)",
            pm(s.k_plus, s.k_plus_stderr),
            pm(s.k_minus, s.k_minus_stderr)
        ),
        format!(
            "  {:<10} {:>28} {:>28}",
            "b (A)",
            pm(s.b_plus, s.b_plus_stderr),
            pm(s.b_minus, s.b_minus_stderr)
        ),
        format!(
            "  k' = {} A/W, imbalance = {}",
            pm(s.k_prime, s.k_prime_stderr),
            pm(s.imbalance, s.imbalance_stderr)
        ),
        format!(
            "  x total = {} W on the pattern; ledger residual {:.1e} / {:.1e} W",
            pm(s.x_total_w, s.x_total_w_stderr),
            s.ledger
                .all_plus
                .residual_w
                .abs()
                .max(s.ledger.all_minus.residual_w.abs()),
            s.ledger.emitted_w
        ),
    ];
    if let Some(d) = &s.dmd_diffraction {
        out.push(format!(
            "  DMD diffraction: share of the pattern mirrors' reflected power on each diode ({} rays per model)",
            d.rays
        ));
        out.push(format!(
            "  {:<22} {:>12} {:>12}",
            "", "geometric", "diffractive"
        ));
        let (g, f) = (&d.geometric, &d.diffractive);
        for (label, a, b) in [
            ("diode + from state +", g.plus_from_plus, f.plus_from_plus),
            ("diode − from state +", g.minus_from_plus, f.minus_from_plus),
            ("diode + from state −", g.plus_from_minus, f.plus_from_minus),
            (
                "diode − from state −",
                g.minus_from_minus,
                f.minus_from_minus,
            ),
        ] {
            out.push(format!("  {label:<22} {a:>12.4} {b:>12.4}"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    /// The numbers behind the per-unit standard errors on the paper bench (run by hand:
    /// `cargo test --lib outputs::trace::tests::paper_bench_unresolved_units -- --ignored
    /// --nocapture`; SPIBENCH_RAYS sets the ray count, default 2 × 10⁶ as `trace`).
    #[test]
    #[ignore]
    fn paper_bench_unresolved_units() {
        let rays = std::env::var("SPIBENCH_RAYS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(2_000_000);
        let doc = crate::scene::doc::BenchDoc::paper().unwrap();
        let bench = doc.build().unwrap();
        let traced =
            crate::pipeline::trace_stage(&bench, &crate::pipeline::TraceRequest::new(rays, 1))
                .unwrap();
        let t = &traced.transport;
        let lit = crate::report::heatmap::lit_units(&t.x_w, crate::report::heatmap::DARK_FRACTION);
        for d in 0..2 {
            let nonzero = t.k_map[d].iter().filter(|k| **k != 0.0).count();
            let unresolved: Vec<usize> = (0..t.k_map[d].len())
                .filter(|&j| t.k_map[d][j] != 0.0 && t.k_map_stderr[d][j].is_infinite())
                .collect();
            let zero_se = (0..t.k_map[d].len())
                .filter(|&j| t.k_map[d][j] != 0.0 && t.k_map_stderr[d][j] == 0.0)
                .count();
            let max_x = unresolved.iter().map(|&j| t.x_w[j]).fold(0.0, f64::max);
            let max_k = unresolved
                .iter()
                .map(|&j| t.k_map[d][j])
                .fold(0.0, f64::max);
            let mean_x = t.x_w.iter().sum::<f64>() / t.x_w.len() as f64;
            println!(
                "arm {d}: {rays} rays, {} units, {nonzero} with k != 0, {} unresolved (light in \
                 one batch only), {zero_se} with SE exactly 0 otherwise; unresolved units: x_j \
                 <= {max_x:.3e} W (mean x_j {mean_x:.3e} W), k_j <= {max_k:.3} A/W, {} of them lit",
                t.k_map[d].len(),
                unresolved.len(),
                unresolved.iter().filter(|&&j| lit[j]).count()
            );
        }
    }
}
