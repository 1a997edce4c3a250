//! First-order (paraxial) focal lengths and exact real rays through a [`Prescription`].
//!
//! Conventions (the catalogues', and validation/lenses/README.md): the EFL is 1/Φ in air,
//! positive for a converging lens; the BFL runs from the last vertex to the rear focus, positive
//! when the focus lies after it; the FFL from the first vertex to the front focus, positive when
//! the focus lies before it. So a positive lens has positive EFL, BFL and FFL.

use glam::DVec3;

use super::{Prescription, shape::refract};
use crate::error::Result;

/// The paraxial focal lengths (m); all `None` for an afocal element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Paraxial {
    pub efl_m: Option<f64>,
    pub bfl_m: Option<f64>,
    pub ffl_m: Option<f64>,
}

/// A power below this (1/m) counts as afocal: a focal length above 10⁹ m.
const AFOCAL_POWER: f64 = 1e-9;

/// A y–nu trace of the marginal ray y = 1, u = 0 through curvatures `c` (each surface's
/// paraxial curvature), gaps `t` and indices `n` (n₀ before the first surface): the final
/// height and reduced angle.
fn ynu(c: &[f64], t: &[f64], n: &[f64]) -> (f64, f64) {
    let (mut y, mut u) = (1.0, 0.0);
    for k in 0..c.len() {
        // n′u′ = nu − yφ with φ = c (n′ − n).
        u = (n[k] * u - y * c[k] * (n[k + 1] - n[k])) / n[k + 1];
        if k + 1 < c.len() {
            y += u * t[k];
        }
    }
    (y, u)
}

impl Prescription {
    /// The paraxial EFL, BFL and FFL at `wavelength_m`. The paraxial curvature of an even
    /// asphere includes its r² term (c + 2a₁).
    pub fn paraxial(&self, wavelength_m: f64) -> Result<Paraxial> {
        let n = self.indices(wavelength_m)?;
        let c: Vec<f64> = self
            .surfaces
            .iter()
            .map(|s| s.shape.paraxial_curvature())
            .collect();
        let t: Vec<f64> = self.surfaces.iter().map(|s| s.thickness_m).collect();
        let (y, u) = ynu(&c, &t, &n);
        if u.abs() < AFOCAL_POWER {
            return Ok(Paraxial {
                efl_m: None,
                bfl_m: None,
                ffl_m: None,
            });
        }
        // Reversed: the last surface first, each curvature negated, the gaps in reverse.
        let cr: Vec<f64> = c.iter().rev().map(|c| -c).collect();
        let mut tr: Vec<f64> = t[..t.len().saturating_sub(1)].to_vec();
        tr.reverse();
        let nr: Vec<f64> = n.iter().rev().copied().collect();
        let (yr, ur) = ynu(&cr, &tr, &nr);
        Ok(Paraxial {
            efl_m: Some(-1.0 / u),
            bfl_m: Some(-y / u),
            ffl_m: Some(-yr / ur),
        })
    }

    /// Traces the ray `o + t·d` (o, d in the element's frame: first vertex at the origin, axis
    /// +z) through every surface; the point on the last surface and the direction after it, in
    /// air, or `None` if it misses an aperture or is totally internally reflected.
    pub fn trace_ray(&self, o: DVec3, d: DVec3, n: &[f64]) -> Option<(DVec3, DVec3)> {
        let (mut p, mut d) = (o, d.normalize());
        let mut z = 0.0;
        for (k, s) in self.surfaces.iter().enumerate() {
            let local = p - DVec3::new(0.0, 0.0, z);
            let t = s.shape.intersect(local, d, s.semi_diameter_m, 0.0)?;
            let hit = local + t * d;
            let normal = s.shape.normal(hit)?;
            d = refract(d, normal, n[k], n[k + 1])?;
            p = hit + DVec3::new(0.0, 0.0, z);
            z += s.thickness_m;
        }
        Some((p, d))
    }

    /// A ray parallel to the axis at height `height_m` in the meridional (y–z) plane, traced
    /// to the plane `plane_m` after the last vertex: (y there, direction after the last
    /// surface), or `None` on a miss or total internal reflection.
    pub fn parallel_ray(&self, height_m: f64, plane_m: f64, n: &[f64]) -> Option<(f64, DVec3)> {
        // Any start before the first surface's sag will do for a parallel ray.
        let start = -(self.surfaces.first()?.semi_diameter_m + 1e-3);
        let o = DVec3::new(0.0, height_m, start);
        let (p, d) = self.trace_ray(o, DVec3::Z, n)?;
        let z_plane = self.length_m() + plane_m;
        if d.z <= 0.0 {
            return None;
        }
        let y = p.y + (z_plane - p.z) * d.y / d.z;
        Some((y, d))
    }
}
