//! The outputs of `spibench check` (docs/outputs.md, "check"): `check.json` ([`CheckJson`]),
//! the paraxial numbers of crate::trace::paraxial in SI with unit-suffixed keys, each element
//! with its position as the bench file gives it, the DMD model they were computed for and, beside
//! the paraxial beam on each diode, the short traced footprint of [`footprint`]; and the report
//! `check` prints.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::report::output::OutputDir;
use crate::scene::doc::{BenchDoc, DmdModel};
use crate::trace::irradiance::{IrradianceMaps, MapStats, STATES};
use crate::trace::paraxial::{ParaxialReport, paraxial_report};

/// `check.json`: the paraxial report with its keys unchanged (flattened), the DMD model and the
/// traced footprint.
#[derive(Debug, Clone, Serialize)]
pub struct CheckJson {
    #[serde(flatten)]
    pub paraxial: ParaxialReport,
    /// The model of the bench's DMD as built, `geometric` or `diffractive` (the bench's
    /// `dmd.model` or the model chosen over it); null for a bench without a DMD.
    pub dmd_model: Option<String>,
    /// The traced footprint on each diode; null when none was traced (no rays asked, or no DMD).
    pub footprint: Option<Footprint>,
}

impl CheckJson {
    /// The report of `doc` with its paraxial numbers and footprint.
    pub fn new(doc: &BenchDoc, paraxial: ParaxialReport, footprint: Option<Footprint>) -> Self {
        CheckJson {
            paraxial,
            dmd_model: doc.dmd_model().map(|m: DmdModel| m.name().to_string()),
            footprint,
        }
    }
}

/// The paraxial report of the bench `doc` at `wl` (m), each element with its position from
/// the file.
pub fn report(doc: &BenchDoc, bench: &crate::optics::Bench, wl: f64) -> Result<ParaxialReport> {
    let mut report = paraxial_report(&doc.name(), bench, wl)?;
    report.glass_substitutions = doc.glass_substitutions();
    let poses = file_positions(&doc.file);
    for e in &mut report.elements {
        e.position_m = poses.iter().find(|(n, _)| *n == e.name).map(|p| p.1);
    }
    Ok(report)
}

/// Writes `check.json` into `dir` (a staging folder).
pub fn write(dir: &OutputDir, report: &CheckJson) -> Result<()> {
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::Numerical(format!("cannot encode check.json: {e}")))?;
    let path = dir.path("check.json");
    std::fs::write(&path, json + "\n").map_err(|e| Error::write(&path, e))
}

/// `check`'s traced rays when none are asked for: a fraction of a second on two cores for the
/// paper bench, enough for its centroids to a few per cent of the spot's RMS radius.
pub const DEFAULT_FOOTPRINT_RAYS: u64 = 20_480;

/// The independent traces the footprint's rays are split into: each number is that of their
/// pooled maps, its standard error the replicas' spread / √K (K − 1 = 7 degrees of freedom, so
/// a standard error is itself uncertain by about a quarter: 1/√(2·7)).
pub const FOOTPRINT_REPLICAS: u64 = 8;

/// Bins across each diode's map: twice `trace`'s, so that the centroid's and RMS radius's
/// binning (at most half a bin; the RMS radius's square grows by bin²/6, Sheppard's
/// correction) stays small beside a millimetre spot on a diode's map.
pub const FOOTPRINT_BINS: usize = 128;

/// The fewest footprint rays (other than none): two batches, as every traced number with a
/// standard error (`trace::RAYS_PER_BATCH`).
pub const MIN_FOOTPRINT_RAYS: u64 = 2 * crate::trace::RAYS_PER_BATCH;

/// The traced footprint of `check`: where the light of each arm lands on its diode's plane
/// (`trace::irradiance`'s maps of the arm's own state: every pattern unit in the arm's mirror
/// state), beside the paraxial estimate.
#[derive(Debug, Clone, Serialize)]
pub struct Footprint {
    /// Lamp rays traced in all ([`FOOTPRINT_REPLICAS`] × the rays of one replica).
    pub rays: u64,
    pub seed: u64,
    pub replicas: u64,
    pub bins: usize,
    /// `pd_plus`, then `pd_minus`.
    pub diodes: Vec<DiodeFootprint>,
}

/// One diode's traced footprint: the numbers of its map (positions in the map's (u, v) axes
/// from the active area's centre, those of `chief_ray_on_diode_m`), each with its standard
/// error; null where a replica mapped no light on it.
#[derive(Debug, Clone, Serialize)]
pub struct DiodeFootprint {
    pub name: String,
    /// The mirror state of the map (`all_plus` for `pd_plus`, `all_minus` for `pd_minus`).
    pub state: String,
    /// The width of a map bin (m).
    pub bin_m: f64,
    /// Whether the diode has a housing: its front plate is what catches, and so measures, the
    /// light beside the active area. Without one only the active area is mapped (the spill is
    /// null, and a beam the diode clips looks smaller and more central than it is).
    pub housing: bool,
    /// Centroid of the mapped light (active area and plate).
    pub centroid_m: Option<[f64; 2]>,
    pub centroid_stderr_m: Option<[f64; 2]>,
    /// RMS radius about the centroid.
    pub rms_radius_m: Option<f64>,
    pub rms_radius_stderr_m: Option<f64>,
    /// 2√2 × the RMS radius: the diameter of the uniformly lit disk with this RMS radius, the
    /// measure comparable with the paraxial beam diameter (a spot brighter at its centre than
    /// at its edge has a smaller one than its edge-to-edge diameter).
    pub rms_diameter_m: Option<f64>,
    pub rms_diameter_stderr_m: Option<f64>,
    /// The share of the mapped light on the housing's plate rather than the active area.
    pub spill: Option<f64>,
    pub spill_stderr: Option<f64>,
    /// The paraxial numbers beside them (copies): where the arm's chief ray meets the diode,
    /// and the estimated beam diameter of the arm lens that sends its light there.
    pub chief_ray_on_diode_m: Option<[f64; 2]>,
    pub paraxial_spot_diameter_m: Option<f64>,
}

/// The standard error of a pooled value from its K replicas' values: their standard deviation
/// / √K (None unless every replica has a value).
fn spread_se(values: &[Option<f64>]) -> Option<f64> {
    let v: Vec<f64> = values.iter().copied().collect::<Option<Vec<f64>>>()?;
    let n = v.len() as f64;
    if v.len() < 2 {
        return None;
    }
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    Some((var / n).sqrt())
}

/// Traces the footprint of `bench` ([`Footprint`]) with `rays` lamp rays in
/// [`FOOTPRINT_REPLICAS`] replicas from `seed`: None for `rays` = 0 or a bench without a DMD
/// (nothing to trace). `rays` must be 0 or lie between [`MIN_FOOTPRINT_RAYS`] and the one
/// trace cap (field `footprint_rays`). Identical on any number of threads (each replica is).
pub fn footprint(
    bench: &crate::optics::Bench,
    paraxial: &ParaxialReport,
    rays: u64,
    seed: u64,
) -> Result<Option<Footprint>> {
    let max = crate::scene::run::MAX_RAYS;
    if rays != 0 && !(MIN_FOOTPRINT_RAYS..=max).contains(&rays) {
        return Err(Error::field(
            "footprint_rays",
            format!(
                "must be 0 (no footprint) or lie between {MIN_FOOTPRINT_RAYS} (two batches) \
                 and {max}, got {rays}"
            ),
        ));
    }
    if rays == 0 || bench.dmd().is_none() {
        return Ok(None);
    }
    let per = rays.div_ceil(FOOTPRINT_REPLICAS);
    let r = crate::trace::irradiance::trace_replicas(
        bench,
        per,
        seed,
        FOOTPRINT_REPLICAS,
        FOOTPRINT_BINS,
    )?;
    let diodes = (0..2)
        .map(|d| diode_footprint(&r.pooled, d, &r.each[d], paraxial))
        .collect();
    Ok(Some(Footprint {
        rays: per * FOOTPRINT_REPLICAS,
        seed,
        replicas: FOOTPRINT_REPLICAS,
        bins: FOOTPRINT_BINS,
        diodes,
    }))
}

/// Diode d's footprint: the pooled map's numbers, the replicas' spread for their errors.
fn diode_footprint(
    pooled: &IrradianceMaps,
    d: usize,
    each: &[Option<MapStats>],
    paraxial: &ParaxialReport,
) -> DiodeFootprint {
    let name = ["pd_plus", "pd_minus"][d].to_string();
    let window = &pooled.windows[d];
    let housing = window.housing.is_some();
    let lit = each.iter().all(Option::is_some);
    let st = pooled.stats(d, d);
    let of = |f: &dyn Fn(&MapStats) -> f64| -> (Option<f64>, Option<f64>) {
        if !lit {
            return (None, None);
        }
        let values: Vec<Option<f64>> = each.iter().map(|s| s.as_ref().map(f)).collect();
        (Some(f(&st)), spread_se(&values))
    };
    let (cx, cx_se) = of(&|s| s.centroid_m[0]);
    let (cy, cy_se) = of(&|s| s.centroid_m[1]);
    let (r, r_se) = of(&|s| s.rms_radius_m);
    let (spill, spill_se) = if housing {
        of(&|s| s.spill)
    } else {
        (None, None)
    };
    let both = |a: Option<f64>, b: Option<f64>| a.zip(b).map(|(a, b)| [a, b]);
    let diameter = 2.0 * std::f64::consts::SQRT_2;
    let diode = paraxial.diodes.iter().find(|e| e.name == name);
    let spot = paraxial.lenses.iter().find_map(|l| {
        l.arm
            .as_ref()
            .filter(|a| a.diode.as_deref() == Some(name.as_str()))
            .and_then(|a| a.spot_diameter_m)
    });
    DiodeFootprint {
        state: STATES[d].to_string(),
        bin_m: 2.0 * window.half_width_m / pooled.bins as f64,
        housing,
        centroid_m: both(cx, cy),
        centroid_stderr_m: both(cx_se, cy_se),
        rms_radius_m: r,
        rms_radius_stderr_m: r_se,
        rms_diameter_m: r.map(|r| diameter * r),
        rms_diameter_stderr_m: r_se.map(|s| diameter * s),
        spill,
        spill_stderr: spill_se,
        chief_ray_on_diode_m: diode.and_then(|e| e.chief_ray_on_diode_m),
        paraxial_spot_diameter_m: spot,
        name,
    }
}

fn mm(x: f64) -> String {
    format!("{:.3}", x * 1e3)
}

fn opt_mm(x: Option<f64>) -> String {
    x.map_or("—".into(), mm)
}

/// Every part's position as the file writes it (mm → m), by the name the outlines use: the
/// elements by their names, `lamp`, and the detectors as `pd_plus` and `pd_minus`. Read from
/// the file's serialised form, so every element kind with a `position_mm` is covered.
fn file_positions(file: &crate::scene::bench::BenchFile) -> Vec<(String, [f64; 3])> {
    let Ok(v) = serde_json::to_value(file) else {
        return Vec::new();
    };
    let pos = |o: &serde_json::Value| -> Option<[f64; 3]> {
        let p = o.get("position_mm")?;
        let c: Vec<f64> = p.as_array()?.iter().filter_map(|x| x.as_f64()).collect();
        (c.len() == 3).then(|| [c[0] / 1e3, c[1] / 1e3, c[2] / 1e3])
    };
    let mut out = Vec::new();
    for e in v["elements"].as_array().into_iter().flatten() {
        // Externally tagged: {"Lens": {...}}.
        let inner = e.as_object().and_then(|o| o.values().next()).unwrap_or(e);
        if let (Some(name), Some(p)) = (inner.get("name").and_then(|n| n.as_str()), pos(inner)) {
            out.push((name.to_string(), p));
        }
    }
    for (key, name) in [("plus", "pd_plus"), ("minus", "pd_minus")] {
        if let Some(p) = pos(&v["detectors"][key]) {
            out.push((name.to_string(), p));
        }
    }
    if let Some(p) = pos(&v["lamp"]) {
        out.push(("lamp".to_string(), p));
    }
    out
}

/// The report `check` prints, line by line.
pub fn printed(c: &CheckJson) -> Vec<String> {
    let r = &c.paraxial;
    let mut out = Vec::new();
    out.push(format!(
        "{}: valid bench; paraxial numbers at {:.1} nm",
        r.scene,
        r.design_wavelength_m * 1e9
    ));
    // Its own line: the first names the scene, whose path may be long.
    out.push(format!(
        "DMD model: {}",
        c.dmd_model.as_deref().unwrap_or("— (no DMD)")
    ));
    out.push("elements:".to_string());
    for e in &r.elements {
        // The pose from the file where it gives one (the outline's centroid is not the pose).
        let (what, p) = match e.position_m {
            Some(p) => ("position", p),
            None => ("outline centre", e.centre_m),
        };
        out.push(format!(
            "  {:<22} {:<11} {what} ({}, {}, {}) mm",
            e.name,
            e.kind,
            mm(p[0]),
            mm(p[1]),
            mm(p[2])
        ));
    }
    out.push("lenses (distances along each lens axis, from/to its principal planes):".to_string());
    for l in &r.lenses {
        out.push(format!(
            "  {:<22} n = {:.5}, f = {} mm, BFL = {} mm",
            l.name,
            l.index,
            mm(l.focal_length_m),
            mm(l.back_focal_length_m)
        ));
        match &l.object {
            // An image more than 1000 f away is a collimated beam for any bench.
            Some(o) if l.magnification.is_some_and(|m| m.abs() > 1e3) => out.push(format!(
                "  {:<22} object: {o}, s = {} mm\n  {:<22} image at infinity (collimated, s' = {:.3} m)",
                "",
                opt_mm(l.object_distance_m),
                "",
                l.image_distance_m.unwrap_or(f64::INFINITY)
            )),
            Some(o) => out.push(format!(
                "  {:<22} object: {o}, s = {} mm\n  {:<22} image s' = {} mm; m = {}",
                "",
                opt_mm(l.object_distance_m),
                "",
                opt_mm(l.image_distance_m),
                l.magnification.map_or("—".into(), |m| format!("{m:.4}"))
            )),
            None => out.push(format!("  {:<22} on no chief ray: no conjugates", "")),
        }
        if let Some(a) = &l.arm {
            arm_lines(a, &mut out);
        }
    }
    for s in &r.glass_substitutions {
        out.push(format!("  glass substituted: {s}"));
    }
    match r.chart_to_dmd_magnification {
        Some(m) => out.push(format!("chart → DMD magnification: {m:.4}")),
        None => out.push("chart → DMD magnification: — (no chart before the DMD)".to_string()),
    }
    if let Some([w, h]) = r.pattern_on_dmd_m {
        out.push(format!("pattern area on the DMD: {} × {} mm", mm(w), mm(h)));
    }
    if let Some([w, h]) = r.pattern_on_chart_m {
        out.push(format!(
            "pattern area on the chart: {} × {} mm",
            mm(w),
            mm(h)
        ));
    }
    out.push(
        "photodiodes (geometric NA of the disk seen from the last optic on the arm's chief ray):"
            .to_string(),
    );
    for d in &r.diodes {
        out.push(format!(
            "  {:<9} Ø {} mm, chief ray ends on {}\n            last optic {}, {} mm away, NA = {}",
            d.name,
            mm(d.diameter_m),
            d.chief_ray_end,
            d.last_optic.as_deref().unwrap_or("—"),
            opt_mm(d.distance_m),
            d.numerical_aperture
                .map_or("—".into(), |v| format!("{v:.4}"))
        ));
        if let Some([u, v]) = d.chief_ray_on_diode_m {
            out.push(format!(
                "            chief ray at (u, v) = ({}, {}) mm from the active area's centre",
                mm(u),
                mm(v)
            ));
        }
        if let (Some(a), Some(s)) = (d.acceptance_rad, d.order_spacing_rad) {
            out.push(format!(
                "            accepts ± {:.1} mrad at the DMD; order spacing λ/p = {:.1} mrad",
                1e3 * a,
                1e3 * s
            ));
        }
        if d.acceptance_below_order_spacing() {
            // Three lines: the tables fit 100 columns.
            out.push(format!(
                "warning: {} accepts less than one order spacing of the DMD: with the \
                 diffractive model",
                d.name
            ));
            out.push(
                "  it collects only the orders that fall on it (k′ can drop by half;".to_string(),
            );
            out.push("  docs/guide/12-designing-for-diffraction.md)".to_string());
        }
    }
    footprint_lines(c, &mut out);
    out
}

/// The traced footprint's lines, each diode's beside its paraxial estimate.
fn footprint_lines(c: &CheckJson, out: &mut Vec<String>) {
    let Some(f) = &c.footprint else {
        let why = if c.dmd_model.is_some() {
            "not traced (0 rays asked)"
        } else {
            "not traced (no DMD)"
        };
        out.push(format!("traced footprint: {why}"));
        return;
    };
    out.push(format!(
        "traced footprint ({} rays, seed {}; ± one standard error, from {} replicas),",
        f.rays, f.seed, f.replicas
    ));
    out.push(
        "  the arm's own state on its diode's plane (u, v from the active area's centre):"
            .to_string(),
    );
    let pm = |x: Option<f64>, se: Option<f64>| match (x, se) {
        (Some(x), Some(se)) => format!("{} ± {}", mm(x), mm(se)),
        (Some(x), None) => mm(x),
        _ => "—".to_string(),
    };
    for d in &f.diodes {
        let (c0, c1) = (d.centroid_m.map(|v| v[0]), d.centroid_m.map(|v| v[1]));
        let (s0, s1) = (
            d.centroid_stderr_m.map(|v| v[0]),
            d.centroid_stderr_m.map(|v| v[1]),
        );
        out.push(format!(
            "  {:<9} centroid ({}, {}) mm",
            d.name,
            pm(c0, s0),
            pm(c1, s1)
        ));
        if let Some([u, v]) = d.chief_ray_on_diode_m {
            out.push(format!(
                "            paraxial chief ray ({}, {}) mm",
                mm(u),
                mm(v)
            ));
        }
        out.push(format!(
            "            2√2·RMS radius Ø {} mm; paraxial beam Ø ≈ {} mm",
            pm(d.rms_diameter_m, d.rms_diameter_stderr_m),
            opt_mm(d.paraxial_spot_diameter_m)
        ));
        match (d.spill, d.spill_stderr) {
            (Some(s), se) => out.push(format!(
                "            spill: {:.2} ± {:.2} % of it on the housing, off the active area",
                100.0 * s,
                100.0 * se.unwrap_or(0.0)
            )),
            (None, _) if !d.housing => out.push(
                "            spill: — (no housing: only the active area is mapped)".to_string(),
            ),
            (None, _) => out.push("            spill: — (no light mapped)".to_string()),
        }
    }
}

/// The lines of an arm lens: where it images the pupil and the DMD, the lit pupil and the beam
/// on the arm's diode.
fn arm_lines(a: &crate::trace::paraxial::ArmLensEntry, out: &mut Vec<String>) {
    // One short line per item: the tables fit 100 columns.
    out.push(format!(
        "  {:<22} pupil: {} (Ø {} mm,",
        "",
        a.pupil,
        mm(a.pupil_diameter_m)
    ));
    out.push(format!(
        "  {:<22}   {} mm before the DMD)",
        "",
        mm(a.pupil_to_dmd_m)
    ));
    out.push(format!(
        "  {:<22} pupil image s' = {} mm, Ø {} mm",
        "",
        mm(a.pupil_image_distance_m),
        mm(a.pupil_image_diameter_m)
    ));
    out.push(format!(
        "  {:<22} DMD image s' = {} mm, diagonal {} mm",
        "",
        mm(a.dmd_image_distance_m),
        mm(a.dmd_image_diagonal_m)
    ));
    // The lit pupil: where the light on the DMD comes from (filament image or aperture).
    match (a.lit_pupil_diameter_m, a.lit_pupil_to_dmd_m) {
        (Some(d), Some(l)) => out.push(format!(
            "  {:<22} lit pupil: {} (Ø {} mm, {} mm before the DMD),",
            "",
            a.lit_by,
            mm(d),
            mm(l)
        )),
        _ => out.push(format!(
            "  {:<22} lit pupil: {} at infinity (telecentric),",
            "", a.lit_by
        )),
    }
    out.push(format!(
        "  {:<22}   a cone of ± {:.2} mrad on each pattern point",
        "",
        1e3 * a.lit_half_angle_rad
    ));
    match (
        &a.diode,
        a.diode_distance_m,
        a.spot_diameter_m,
        a.diode_fill,
    ) {
        (Some(d), Some(z), Some(spot), Some(fill)) => {
            out.push(format!(
                "  {:<22} {d} at {} mm: beam Ø ≈ {} mm, fill ≈ {:.0} % (lit pupil)",
                "",
                mm(z),
                mm(spot),
                100.0 * fill
            ));
            if let (Some(b), Some(fb)) = (a.spot_bound_diameter_m, a.diode_fill_bound) {
                out.push(format!(
                    "  {:<22}   aperture filled: beam Ø ≤ {} mm, fill ≤ {:.0} %",
                    "",
                    mm(b),
                    100.0 * fb
                ));
            }
        }
        _ => out.push(format!("  {:<22} the arm's chief ray reaches no diode", "")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn symmetric() -> BenchDoc {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes/tests/symmetric_arms.ron");
        BenchDoc::open(Some(&p)).unwrap()
    }

    /// `check.json` keeps every key of the paraxial report as it was (flattened, the same
    /// values) and adds only `dmd_model` and `footprint`.
    #[test]
    fn the_wrapper_keeps_the_paraxial_keys_and_adds_the_dmd_model() {
        let doc = symmetric();
        let bench = doc.build().unwrap();
        let paraxial = report(&doc, &bench, 850e-9).unwrap();
        let plain = serde_json::to_value(&paraxial).unwrap();
        let wrapped = serde_json::to_value(CheckJson::new(&doc, paraxial, None)).unwrap();
        let (plain, wrapped) = (plain.as_object().unwrap(), wrapped.as_object().unwrap());
        for (k, v) in plain {
            assert_eq!(wrapped.get(k), Some(v), "key `{k}`");
        }
        let mut extra: Vec<&str> = wrapped
            .keys()
            .filter(|k| !plain.contains_key(*k))
            .map(String::as_str)
            .collect();
        extra.sort_unstable();
        assert_eq!(extra, ["dmd_model", "footprint"]);
        assert_eq!(wrapped["dmd_model"], "geometric");
        assert!(wrapped["footprint"].is_null());
        // The model chosen over the file's is the one named.
        let mut d = symmetric();
        d.set_dmd_model(DmdModel::Diffractive).unwrap();
        let b = d.build().unwrap();
        let c = CheckJson::new(&d, report(&d, &b, 850e-9).unwrap(), None);
        assert_eq!(c.dmd_model.as_deref(), Some("diffractive"));
        assert_eq!(printed(&c)[1], "DMD model: diffractive");
    }

    /// The footprint is bit-identical on one and two threads, names its replicas' rays, and
    /// refuses a ray count below two batches by its field (no flag).
    #[test]
    fn the_footprint_is_identical_on_one_and_two_threads() {
        let doc = symmetric();
        let bench = doc.build().unwrap();
        let paraxial = report(&doc, &bench, 850e-9).unwrap();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| footprint(&bench, &paraxial, 4096, 7).unwrap().unwrap())
        };
        let (a, b) = (run(1), run(2));
        let (a, b) = (
            serde_json::to_string(&a).unwrap(),
            serde_json::to_string(&b).unwrap(),
        );
        assert_eq!(a, b);
        let f = run(1);
        assert_eq!(f.rays, 4096);
        assert!(
            f.diodes
                .iter()
                .all(|d| d.centroid_m.is_some() && !d.housing)
        );
        assert!(footprint(&bench, &paraxial, 0, 7).unwrap().is_none());
        let e = footprint(&bench, &paraxial, 100, 7)
            .unwrap_err()
            .to_string();
        assert!(e.contains("footprint_rays") && e.contains("2048"), "{e}");
    }

    /// The standard error from the replicas: the spread / √K, none unless every replica has a
    /// value.
    #[test]
    fn the_spread_gives_the_standard_error() {
        let v = [Some(1.0), Some(3.0)];
        // sd = √2, /√2 = 1.
        assert!((spread_se(&v).unwrap() - 1.0).abs() < 1e-15);
        assert!(spread_se(&[Some(1.0), None]).is_none());
        use crate::trace::irradiance::replica_seed;
        assert_ne!(replica_seed(1, 0), replica_seed(1, 1));
    }
}
