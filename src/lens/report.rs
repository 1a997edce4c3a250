//! The `spibench lens` job: a prescription's surface table, paraxial focal lengths and a
//! meridional fan of real rays, in millimetres (the unit of lens catalogues).

use super::LoadedLens;
use crate::error::{Error, Result};
use crate::optics::lens::{Prescription, Shape};

/// Fractions of the first surface's semi-diameter at which the default fan is traced (those of
/// validation/lenses/reference.json).
pub const DEFAULT_FAN: [f64; 5] = [0.1, 0.3, 0.5, 0.7, 0.9];

/// One row of the surface table.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceRow {
    /// `flat`, `sphere`, `conic` or `even asphere`.
    pub kind: &'static str,
    /// Radius of curvature (mm), `None` for flat (infinite).
    pub radius_mm: Option<f64>,
    pub conic: f64,
    /// A₂ … A₁₆ (mm^(1−2i)), all zero for a non-asphere.
    pub asphere: [f64; 8],
    pub semi_diameter_mm: f64,
    pub thickness_mm: f64,
    pub medium_after: String,
    pub index_after: f64,
    pub medium_source: String,
}

/// One real ray of the fan.
#[derive(Debug, Clone, PartialEq)]
pub struct FanRay {
    pub height_mm: f64,
    /// The intercept on the image plane, `None` for a ray that missed an aperture or was
    /// totally internally reflected.
    pub y_mm: Option<f64>,
    pub direction: Option<[f64; 3]>,
}

/// What `spibench lens` computes.
#[derive(Debug, Clone)]
pub struct LensReport {
    pub name: String,
    pub wavelength_nm: f64,
    pub surfaces: Vec<SurfaceRow>,
    pub efl_mm: Option<f64>,
    pub bfl_mm: Option<f64>,
    pub ffl_mm: Option<f64>,
    /// The plane the fan is traced to, after the last vertex: the file's image surface, or the
    /// paraxial focus where the file has none.
    pub image_distance_mm: Option<f64>,
    pub rays: Vec<FanRay>,
    /// RMS of the fan's y intercepts at the paraxial focus (mm); `None` when afocal or no ray
    /// got through.
    pub rms_spot_mm: Option<f64>,
    pub substitutions: Vec<String>,
    pub ignored: Vec<(String, usize)>,
}

/// The report at `wavelength_nm`, with the fan at `heights_mm` (default: [`DEFAULT_FAN`] of the
/// first semi-diameter).
pub fn report(
    lens: &LoadedLens,
    wavelength_nm: f64,
    heights_mm: Option<&[f64]>,
) -> Result<LensReport> {
    if !(wavelength_nm.is_finite() && wavelength_nm > 0.0) {
        return Err(Error::field(
            "wavelength_nm",
            "must be a positive wavelength in nm",
        ));
    }
    let p = &lens.prescription;
    let wl = wavelength_nm * 1e-9;
    let n = p.indices(wl).map_err(|e| e.in_file(&lens.path))?;
    let par = p.paraxial(wl)?;
    let mm = |m: f64| m * 1e3;
    let sd0 = mm(p.surfaces[0].semi_diameter_m);
    let heights: Vec<f64> = match heights_mm {
        Some(h) => h.to_vec(),
        None => DEFAULT_FAN.iter().map(|f| f * sd0).collect(),
    };
    if let Some(h) = heights.iter().find(|h| !h.is_finite()) {
        return Err(Error::field("heights_mm", format!("{h} is not a height")));
    }
    let plane_m = p.image_distance_m.or(par.bfl_m);
    let rays: Vec<FanRay> = heights
        .iter()
        .map(|&h| {
            let hit = plane_m.and_then(|z| p.parallel_ray(h * 1e-3, z, &n));
            FanRay {
                height_mm: h,
                y_mm: hit.map(|(y, _)| mm(y)),
                direction: hit.map(|(_, d)| d.to_array()),
            }
        })
        .collect();
    let rms_spot_mm = par
        .bfl_m
        .and_then(|bfl| rms_at(p, &heights, bfl, &n))
        .map(mm);
    Ok(LensReport {
        name: p.name.clone(),
        wavelength_nm,
        surfaces: table(p, &n),
        efl_mm: par.efl_m.map(mm),
        bfl_mm: par.bfl_m.map(mm),
        ffl_mm: par.ffl_m.map(mm),
        image_distance_mm: plane_m.map(mm),
        rays,
        rms_spot_mm,
        substitutions: lens.substitutions.iter().map(|s| s.to_string()).collect(),
        ignored: lens.ignored.clone(),
    })
}

/// RMS of the fan's intercepts on the plane `plane_m` after the last vertex (m).
fn rms_at(p: &Prescription, heights_mm: &[f64], plane_m: f64, n: &[f64]) -> Option<f64> {
    let ys: Vec<f64> = heights_mm
        .iter()
        .filter_map(|&h| p.parallel_ray(h * 1e-3, plane_m, n).map(|(y, _)| y))
        .collect();
    if ys.is_empty() {
        return None;
    }
    Some((ys.iter().map(|y| y * y).sum::<f64>() / ys.len() as f64).sqrt())
}

fn table(p: &Prescription, n: &[f64]) -> Vec<SurfaceRow> {
    p.surfaces
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let (kind, c, k, a) = match s.shape {
                Shape::Flat => ("flat", 0.0, 0.0, [0.0; 8]),
                Shape::Sphere { c } => ("sphere", c, 0.0, [0.0; 8]),
                Shape::Conic { c, k } => ("conic", c, k, [0.0; 8]),
                Shape::EvenAsphere { c, k, a } => ("even asphere", c, k, a),
            };
            SurfaceRow {
                kind,
                radius_mm: (c != 0.0).then(|| 1e3 / c),
                conic: k,
                asphere: std::array::from_fn(|j| a[j] * 1e-3_f64.powi(2 * j as i32 + 1)),
                semi_diameter_mm: s.semi_diameter_m * 1e3,
                thickness_mm: s.thickness_m * 1e3,
                medium_after: s.medium_after.name.clone(),
                index_after: n[i + 1],
                medium_source: s.medium_after.source.clone(),
            }
        })
        .collect()
}
