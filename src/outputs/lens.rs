//! The outputs of `spibench lens` (docs/outputs.md, "lens"): `summary.json` ([`LensSummary`]),
//! the drawing of the lens with its fan (`lens.svg`, `lens.png`, `lens.pdf`; `figures` feature) and the
//! printed surface table.

use std::fmt::Write as _;

use serde::Serialize;

use crate::error::Result;
use crate::lens::report::{FanRay, LensReport};
use crate::optics::lens::Prescription;
use crate::provenance::Provenance;
use crate::report::output::OutputDir;

/// One surface in `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct SurfaceEntry {
    pub kind: String,
    pub radius_mm: Option<f64>,
    pub conic: f64,
    pub asphere_mm: Vec<f64>,
    pub semi_diameter_mm: f64,
    pub thickness_mm: f64,
    pub medium_after: String,
    pub index_after: f64,
    pub medium_source: String,
}

/// One ray of the fan in `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RayEntry {
    pub height_mm: f64,
    pub y_mm: Option<f64>,
    pub direction: Option<[f64; 3]>,
}

/// `summary.json` of `spibench lens`.
#[derive(Debug, Clone, Serialize)]
pub struct LensSummary {
    pub file: String,
    pub name: String,
    pub wavelength_nm: f64,
    pub efl_mm: Option<f64>,
    pub bfl_mm: Option<f64>,
    pub ffl_mm: Option<f64>,
    pub image_distance_mm: Option<f64>,
    pub rays: Vec<RayEntry>,
    pub rms_spot_mm: Option<f64>,
    pub surfaces: Vec<SurfaceEntry>,
    pub substitutions: Vec<String>,
    pub ignored_operands: Vec<String>,
    pub files: Vec<String>,
}

impl LensSummary {
    pub fn new(file: &str, r: &LensReport) -> LensSummary {
        LensSummary {
            file: file.to_string(),
            name: r.name.clone(),
            wavelength_nm: r.wavelength_nm,
            efl_mm: r.efl_mm,
            bfl_mm: r.bfl_mm,
            ffl_mm: r.ffl_mm,
            image_distance_mm: r.image_distance_mm,
            rays: r
                .rays
                .iter()
                .map(
                    |FanRay {
                         height_mm,
                         y_mm,
                         direction,
                     }| RayEntry {
                        height_mm: *height_mm,
                        y_mm: *y_mm,
                        direction: *direction,
                    },
                )
                .collect(),
            rms_spot_mm: r.rms_spot_mm,
            surfaces: r
                .surfaces
                .iter()
                .map(|s| SurfaceEntry {
                    kind: s.kind.to_string(),
                    radius_mm: s.radius_mm,
                    conic: s.conic,
                    asphere_mm: s.asphere.to_vec(),
                    semi_diameter_mm: s.semi_diameter_mm,
                    thickness_mm: s.thickness_mm,
                    medium_after: s.medium_after.clone(),
                    index_after: s.index_after,
                    medium_source: s.medium_source.clone(),
                })
                .collect(),
            substitutions: r.substitutions.clone(),
            ignored_operands: r
                .ignored
                .iter()
                .map(|(op, n)| format!("{op} ×{n}"))
                .collect(),
            files: Vec::new(),
        }
    }
}

/// Writes `summary.json` and, with the `figures` feature, the drawing into `dir`.
pub fn write(
    dir: &OutputDir,
    mut summary: LensSummary,
    prescription: &Prescription,
    provenance: &Provenance,
) -> Result<LensSummary> {
    #[cfg(feature = "figures")]
    let files = {
        let mut files = vec!["summary.json".to_string()];
        let svg = drawing(prescription, &summary);
        crate::report::svg::write_figure(&svg, &dir.path("lens.svg"), &dir.path("lens.png"), true)?;
        for f in ["lens.svg", "lens.png", "lens.pdf"] {
            files.push(f.into());
        }
        files
    };
    #[cfg(not(feature = "figures"))]
    let files = {
        let _ = prescription;
        vec!["summary.json".to_string()]
    };
    summary.files = files;
    super::summary::write_summary(dir, &summary, provenance)?;
    Ok(summary)
}

fn opt(v: Option<f64>) -> String {
    v.map_or("—".into(), |v| format!("{v:.6} mm"))
}

/// What `spibench lens` prints: the surface table, the focal lengths and the fan.
pub fn printed(s: &LensSummary) -> String {
    let mut t = String::new();
    let _ = writeln!(t, "{} ({}) at {} nm", s.name, s.file, s.wavelength_nm);
    let _ = writeln!(
        t,
        "  #  {:<13} {:>12} {:>9} {:>9} {:>9}  medium after (n)",
        "shape", "R (mm)", "k", "semi-Ø", "t (mm)"
    );
    for (i, x) in s.surfaces.iter().enumerate() {
        let r = x.radius_mm.map_or("∞".into(), |r| format!("{r:.4}"));
        let _ = writeln!(
            t,
            "  {}  {:<13} {:>12} {:>9.4} {:>9.4} {:>9.4}  {} ({:.6}; {})",
            i + 1,
            x.kind,
            r,
            x.conic,
            x.semi_diameter_mm,
            x.thickness_mm,
            x.medium_after,
            x.index_after,
            x.medium_source
        );
    }
    let _ = writeln!(
        t,
        "EFL {}, BFL {}, FFL {}",
        opt(s.efl_mm),
        opt(s.bfl_mm),
        opt(s.ffl_mm)
    );
    let _ = writeln!(
        t,
        "real rays to the image plane {} after the last vertex:",
        opt(s.image_distance_mm)
    );
    for r in &s.rays {
        match (r.y_mm, r.direction) {
            (Some(y), Some(d)) => {
                let _ = writeln!(
                    t,
                    "  h {:>9.4} mm → y {:>+13.6e} mm, direction ({:.9}, {:.9}, {:.9})",
                    r.height_mm, y, d[0], d[1], d[2]
                );
            }
            _ => {
                let _ = writeln!(t, "  h {:>9.4} mm → missed (aperture or TIR)", r.height_mm);
            }
        }
    }
    let _ = write!(t, "RMS spot at the paraxial focus: {}", opt(s.rms_spot_mm));
    for sub in &s.substitutions {
        let _ = write!(t, "\nsubstituted: {sub}");
    }
    t
}

/// The lens in section (y–z) with its fan, in print units (144 per inch), 5 in wide.
#[cfg(feature = "figures")]
pub fn drawing(p: &Prescription, s: &LensSummary) -> String {
    use glam::DVec3;
    let (w, h) = (720.0, 360.0);
    let length = p.length_m() * 1e3;
    let plane = s.image_distance_mm.unwrap_or(0.0).max(0.0);
    let z0 = -0.15 * (length + plane).max(1.0);
    let z1 = length + plane;
    let y_max = p
        .surfaces
        .iter()
        .map(|x| x.semi_diameter_m * 1e3)
        .fold(0.0, f64::max)
        * 1.15;
    let sx = (w - 60.0) / (z1 - z0).max(1e-9);
    let sy = (h - 90.0) / (2.0 * y_max).max(1e-9);
    let scale = sx.min(sy * 4.0);
    let sy = sy.min(scale * 4.0);
    let px = |z: f64| 30.0 + (z - z0) * scale;
    let py = |y: f64| h / 2.0 - y * sy;
    let mut svg = format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="DejaVu Sans, sans-serif"><rect width="{w}" height="{h}" fill="white"/>"##
    );
    let _ = write!(
        svg,
        r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="#888" stroke-dasharray="4 3" stroke-width="0.7"/>"##,
        px(z0),
        py(0.0),
        px(z1),
        py(0.0)
    );
    // Each surface as its sag profile across its clear aperture.
    let vz = p.vertex_z();
    for (x, z) in p.surfaces.iter().zip(&vz) {
        let sd = x.semi_diameter_m;
        let pts: Vec<String> = (0..=64)
            .map(|i| {
                let r = -sd + 2.0 * sd * i as f64 / 64.0;
                let zz = z + x.shape.sag(r * r).unwrap_or(0.0);
                format!("{:.2},{:.2}", px(zz * 1e3), py(r * 1e3))
            })
            .collect();
        let _ = write!(
            svg,
            r##"<polyline points="{}" fill="none" stroke="#1f4e99" stroke-width="1.4"/>"##,
            pts.join(" ")
        );
    }
    // The fan, in the meridional plane, traced again for its vertices.
    let n = p.indices(s.wavelength_nm * 1e-9).unwrap_or_default();
    for r in &s.rays {
        let mut pts = vec![(z0, r.height_mm)];
        let mut o = DVec3::new(0.0, r.height_mm * 1e-3, z0 * 1e-3);
        let mut d = DVec3::Z;
        let mut ok = !n.is_empty();
        for (k, (x, z)) in p.surfaces.iter().zip(&vz).enumerate() {
            if !ok {
                break;
            }
            let local = o - DVec3::new(0.0, 0.0, *z);
            let hit = x
                .shape
                .intersect(local, d, x.semi_diameter_m, 0.0)
                .map(|t| local + t * d);
            let next = hit.and_then(|q| {
                let nn = x.shape.normal(q)?;
                crate::optics::lens::shape::refract(d, nn, n[k], n[k + 1]).map(|d2| (q, d2))
            });
            match next {
                Some((q, d2)) => {
                    o = q + DVec3::new(0.0, 0.0, *z);
                    d = d2;
                    pts.push((o.z * 1e3, o.y * 1e3));
                }
                None => ok = false,
            }
        }
        if ok && d.z > 0.0 {
            let zend = z1 * 1e-3;
            let y = o.y + (zend - o.z) * d.y / d.z;
            pts.push((z1, y * 1e3));
        }
        for sign in [1.0, -1.0] {
            let line: Vec<String> = pts
                .iter()
                .map(|(z, y)| format!("{:.2},{:.2}", px(*z), py(sign * y)))
                .collect();
            let _ = write!(
                svg,
                r##"<polyline points="{}" fill="none" stroke="#c0392b" stroke-width="0.6"/>"##,
                line.join(" ")
            );
        }
    }
    let _ = write!(
        svg,
        r##"<text x="30" y="20" font-size="12">{}</text><text x="30" y="36" font-size="11">{} nm: EFL {}, BFL {}, RMS spot {}</text><text x="30" y="{}" font-size="10">transverse scale {:.2} × the axial; the image plane at the right edge</text></svg>"##,
        xml(&s.name),
        s.wavelength_nm,
        opt(s.efl_mm),
        opt(s.bfl_mm),
        opt(s.rms_spot_mm),
        h - 12.0,
        sy / scale
    );
    svg
}

#[cfg(feature = "figures")]
fn xml(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
