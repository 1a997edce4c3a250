//! The outputs of `spibench check` (docs/outputs.md, "check"): `check.json`, the paraxial
//! numbers of crate::trace::paraxial in SI with unit-suffixed keys, each element with its
//! position as the bench file gives it, and the report `check` prints.

use crate::error::{Error, Result};
use crate::report::output::OutputDir;
use crate::scene::doc::BenchDoc;
use crate::trace::paraxial::{ParaxialReport, paraxial_report};

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
pub fn write(dir: &OutputDir, report: &ParaxialReport) -> Result<()> {
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::Numerical(format!("cannot encode check.json: {e}")))?;
    let path = dir.path("check.json");
    std::fs::write(&path, json + "\n").map_err(|e| Error::write(&path, e))
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
pub fn printed(r: &ParaxialReport) -> Vec<String> {
    let mut out = Vec::new();
    out.push(format!(
        "{}: valid bench; paraxial numbers at {:.1} nm",
        r.scene,
        r.design_wavelength_m * 1e9
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
    out
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
