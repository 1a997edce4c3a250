//! Multi-surface lenses: a prescription of rotationally symmetric surfaces front to back (flat,
//! sphere, conic, even asphere), each with its clear aperture, the thickness to the next surface
//! and the medium after it, so that cemented doublets and triplets are one element. Exact ray
//! intersection ([`shape`]), the paraxial focal lengths and meridional real rays ([`trace`]).
//! Lengths in metres, wavelengths in metres; the readers of prescriptions (`crate::lens`) convert.

pub mod parts;
pub mod shape;
pub mod trace;

pub use shape::Shape;

use crate::error::{Error, Result};
use crate::optics::glass::Glass;

/// The medium after a surface: a glass (with where it came from) or air.
#[derive(Debug, Clone, PartialEq)]
pub struct Medium {
    /// The glass's name as the prescription gives it (`air` for air).
    pub name: String,
    pub glass: Glass,
    /// The wavelength range (nm) of the glass's formula, if its source states one.
    pub range_nm: Option<(f64, f64)>,
    /// Where the model came from, for reports: `built-in catalogue`, a catalogue file and line,
    /// or a substitution from nd and Vd.
    pub source: String,
}

impl Medium {
    pub fn air() -> Medium {
        Medium {
            name: "air".into(),
            glass: crate::optics::glass::AIR,
            range_nm: None,
            source: "air (n = 1)".into(),
        }
    }

    pub fn is_air(&self) -> bool {
        self.name == "air"
    }

    /// The refractive index at `wavelength_m`; a wavelength outside the formula's stated range is
    /// an error naming the glass and its source, never a silent extrapolation.
    pub fn index(&self, wavelength_m: f64) -> Result<f64> {
        let nm = wavelength_m * 1e9;
        if let Some((lo, hi)) = self.range_nm
            && !(lo - 1e-9..=hi + 1e-9).contains(&nm)
        {
            return Err(Error::input(format!(
                "glass {} ({}) is defined from {lo} nm to {hi} nm; {nm} nm is outside that range",
                self.name, self.source
            )));
        }
        Ok(self.glass.index(wavelength_m))
    }
}

/// One surface of a prescription.
#[derive(Debug, Clone, PartialEq)]
pub struct LensSurface {
    pub shape: Shape,
    /// The clear semi-diameter (m): rays outside it are stopped (the edge and mount are black).
    pub semi_diameter_m: f64,
    /// The axial distance from this vertex to the next (m); 0 on the last surface.
    pub thickness_m: f64,
    /// The medium after this surface (air after the last).
    pub medium_after: Medium,
}

/// A lens element: surfaces front to back, the medium before the first being air.
#[derive(Debug, Clone, PartialEq)]
pub struct Prescription {
    pub name: String,
    pub surfaces: Vec<LensSurface>,
    /// The distance from the last vertex to the prescription's image plane, where it has one.
    pub image_distance_m: Option<f64>,
}

/// What makes a prescription's geometry impossible, with the index of the surface at fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Defect {
    /// The semi-diameter exceeds the radius at which the sag is defined (r ≤ 1/(|c|√(1 + k))).
    ApertureBeyondSag { surface: usize, r_max_m: f64 },
    /// Surface `surface` and the next one meet inside their common aperture (the thickness is
    /// too small), with the smallest axial gap found.
    Crossing { surface: usize, gap_m: f64 },
    /// A non-positive or non-finite semi-diameter or thickness.
    BadDimension { surface: usize },
}

/// Points of the common aperture at which two neighbouring surfaces' gap is checked.
const GAP_SAMPLES: usize = 256;

impl Prescription {
    /// The axial position of each vertex from the first (m).
    pub fn vertex_z(&self) -> Vec<f64> {
        let mut z = 0.0;
        self.surfaces
            .iter()
            .map(|s| {
                let here = z;
                z += s.thickness_m;
                here
            })
            .collect()
    }

    /// The same element turned round (light meeting the last surface first): the surfaces in
    /// reverse order, each shape mirrored (every coefficient negated), the gaps and media
    /// shifted. The image distance is dropped (the file's image plane belongs to the other way).
    pub fn reversed(&self) -> Prescription {
        let n = self.surfaces.len();
        let surfaces = (0..n)
            .rev()
            .map(|k| {
                let s = &self.surfaces[k];
                let shape = match s.shape {
                    Shape::Flat => Shape::Flat,
                    Shape::Sphere { c } => Shape::Sphere { c: -c },
                    Shape::Conic { c, k } => Shape::Conic { c: -c, k },
                    Shape::EvenAsphere { c, k, a } => Shape::EvenAsphere {
                        c: -c,
                        k,
                        a: a.map(|x| -x),
                    },
                };
                let (thickness_m, medium_after) = if k > 0 {
                    let prev = &self.surfaces[k - 1];
                    (prev.thickness_m, prev.medium_after.clone())
                } else {
                    (0.0, Medium::air())
                };
                LensSurface {
                    shape,
                    semi_diameter_m: s.semi_diameter_m,
                    thickness_m,
                    medium_after,
                }
            })
            .collect();
        Prescription {
            name: self.name.clone(),
            surfaces,
            image_distance_m: None,
        }
    }

    /// The element's axial length, first vertex to last.
    pub fn length_m(&self) -> f64 {
        self.vertex_z().last().copied().unwrap_or(0.0)
    }

    /// The refractive indices before the first surface and after each: n₀ = 1 (air), nᵢ₊₁.
    pub fn indices(&self, wavelength_m: f64) -> Result<Vec<f64>> {
        let mut n = vec![1.0];
        for s in &self.surfaces {
            n.push(s.medium_after.index(wavelength_m)?);
        }
        Ok(n)
    }

    /// The first geometric defect, if any: apertures within each sag's domain, and each glass
    /// (or air gap) of non-negative thickness everywhere across the smaller aperture.
    pub fn defect(&self) -> Option<Defect> {
        for (i, s) in self.surfaces.iter().enumerate() {
            let thick_ok = s.thickness_m.is_finite() && s.thickness_m >= 0.0;
            if !(s.semi_diameter_m.is_finite() && s.semi_diameter_m > 0.0 && thick_ok) {
                return Some(Defect::BadDimension { surface: i });
            }
            let s_max = s.shape.s_max();
            if s.semi_diameter_m * s.semi_diameter_m > s_max {
                return Some(Defect::ApertureBeyondSag {
                    surface: i,
                    r_max_m: s_max.sqrt(),
                });
            }
        }
        for (i, pair) in self.surfaces.windows(2).enumerate() {
            let (a, b) = (&pair[0], &pair[1]);
            let r = a.semi_diameter_m.min(b.semi_diameter_m);
            let mut gap_min = f64::INFINITY;
            for j in 0..=GAP_SAMPLES {
                let s = (r * j as f64 / GAP_SAMPLES as f64).powi(2);
                let (Some(za), Some(zb)) = (a.shape.sag(s), b.shape.sag(s)) else {
                    continue;
                };
                gap_min = gap_min.min(a.thickness_m + zb - za);
            }
            if gap_min < 0.0 {
                return Some(Defect::Crossing {
                    surface: i,
                    gap_m: gap_min,
                });
            }
        }
        None
    }
}

#[cfg(test)]
mod tests;
