//! The `LensSystem` element: a prescription from a Zemax file (through `crate::lens`) or from
//! inline surfaces, checked, converted to SI and added as bench surfaces
//! (`optics::lens::parts`).

use std::path::Path;

use crate::error::{Error, Result};
use crate::lens::{GlassOptions, agf::Catalogue, read_zmx};
use crate::optics::bench::{ElementId, Solid};
use crate::optics::geometry::Frame;
use crate::optics::lens::parts::add_lens_system;
use crate::optics::lens::{Defect, LensSurface, Medium, Prescription, Shape};

use super::build::{Builder, mm};
use super::schema::{LensSurfaceSpec, LensSystemSpec};

impl Builder<'_> {
    /// A `LensSystem` element.
    pub(super) fn lens_system(
        &mut self,
        el: &LensSystemSpec,
        id: ElementId,
        name: String,
    ) -> Result<()> {
        let n = name.as_str();
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
        let frame = self
            .ctx
            .frame(mm(el.position_mm), el.axis, None, el.tilt_deg, &e)?;
        let coating = self.ctx.coating(&el.coating, |m| e("coating", m))?;
        let base = self.ctx.path.parent().unwrap_or(Path::new(""));
        let p = match (&el.zmx, &el.surfaces) {
            (Some(file), None) => {
                let catalogues = el
                    .glass_catalogues
                    .iter()
                    .map(|c| Catalogue::read(&base.join(c)))
                    .collect::<Result<Vec<_>>>()
                    .map_err(|err| relocated(err, || e("glass_catalogues", String::new())))?;
                // No nd/Vd substitution inside a bench: a bench has no report to state it in
                // yet, and a substitution is never silent (`spibench lens` allows it).
                let glasses = GlassOptions {
                    catalogues,
                    allow_substitution: false,
                };
                read_zmx(&base.join(file), &glasses)?.prescription
            }
            (None, Some(surfaces)) => self.inline(n, surfaces)?,
            _ => {
                return Err(e(
                    "zmx",
                    "a LensSystem takes either `zmx` (a prescription file) or `surfaces`".into(),
                ));
            }
        };
        let p = if el.reversed { p.reversed() } else { p };
        let widest = p
            .surfaces
            .iter()
            .map(|s| s.semi_diameter_m)
            .fold(0.0, f64::max);
        let radius = el.diameter_mm.map_or(widest, |d| 0.5e-3 * d.0);
        if radius < widest * (1.0 - 1e-12) {
            return Err(e(
                "diameter_mm",
                format!(
                    "the diameter ({} mm) is smaller than the largest surface ({} mm)",
                    2e3 * radius,
                    2e3 * widest
                ),
            ));
        }
        let clear = el.clear_diameter_mm.map(|c| 0.5e-3 * c.0);
        add_lens_system(&mut self.parts, id, &frame, &p, &coating, radius, clear);
        let (z1, z2) = extent(&p);
        let solid = Solid::Cylinder {
            frame: Frame {
                origin: frame.origin + z1 * frame.w,
                ..frame
            },
            radius,
            length: z2 - z1,
        };
        self.solids.push((name, solid));
        Ok(())
    }

    /// The prescription of inline surfaces, its geometry checked.
    fn inline(&self, n: &str, surfaces: &[LensSurfaceSpec]) -> Result<Prescription> {
        let e = |i: usize, f: &str, m: String| self.ctx.err_el(n, &format!("surfaces[{i}].{f}"), m);
        if surfaces.len() < 2 {
            return Err(self
                .ctx
                .err_el(n, "surfaces", "a lens needs at least two surfaces"));
        }
        let mut out = Vec::new();
        for (i, s) in surfaces.iter().enumerate() {
            let last = i + 1 == surfaces.len();
            if s.asphere.len() > 7 {
                return Err(e(
                    i,
                    "asphere",
                    "at most seven coefficients, A4 … A16".into(),
                ));
            }
            let c = s.radius_mm.map_or(0.0, |r| 1e3 / r.0);
            let k = s.conic.map_or(0.0, |k| k.0);
            let mut a = [0.0; 8];
            for (j, x) in s.asphere.iter().enumerate() {
                // A_{2j+4} in mm^(−2j−3) → m^(−2j−3).
                a[j + 1] = x.0 * 1e3_f64.powi(2 * j as i32 + 3);
            }
            let shape = match (c, k, a.iter().any(|&x| x != 0.0)) {
                (_, _, true) => Shape::EvenAsphere { c, k, a },
                (0.0, _, false) => Shape::Flat,
                (c, 0.0, false) => Shape::Sphere { c },
                (c, k, false) => Shape::Conic { c, k },
            };
            let thickness = match (s.thickness_mm, last) {
                (Some(t), false) => t.0 * 1e-3,
                (None, true) => 0.0,
                (None, false) => {
                    return Err(e(
                        i,
                        "thickness_mm",
                        "missing (the gap to the next surface)".into(),
                    ));
                }
                (Some(_), true) => {
                    return Err(e(
                        i,
                        "thickness_mm",
                        "the last surface has no thickness after it".into(),
                    ));
                }
            };
            let medium = match (&s.glass, last) {
                (Some(g), false) => Medium {
                    name: g.clone(),
                    glass: self.ctx.glass(g, |m| e(i, "glass", m))?,
                    range_nm: None,
                    source: "bench".into(),
                },
                (None, _) => Medium::air(),
                (Some(_), true) => {
                    return Err(e(i, "glass", "the last surface has air after it".into()));
                }
            };
            out.push(LensSurface {
                shape,
                semi_diameter_m: s.semi_diameter_mm.0 * 1e-3,
                thickness_m: thickness,
                medium_after: medium,
            });
        }
        let p = Prescription {
            name: n.to_string(),
            surfaces: out,
            image_distance_m: None,
        };
        match p.defect() {
            None => Ok(p),
            Some(Defect::ApertureBeyondSag { surface, r_max_m }) => Err(e(
                surface,
                "semi_diameter_mm",
                format!(
                    "larger than the surface allows: its sag is defined out to {} mm only",
                    r_max_m * 1e3
                ),
            )),
            Some(Defect::Crossing { surface, gap_m }) => Err(e(
                surface,
                "thickness_mm",
                format!(
                    "this surface and the next cross inside their common aperture (an axial gap \
                     of {} mm at worst)",
                    gap_m * 1e3
                ),
            )),
            Some(Defect::BadDimension { surface }) => Err(e(
                surface,
                "semi_diameter_mm",
                "not a positive length".into(),
            )),
        }
    }
}

/// The axial extent (m) of a prescription from its first vertex: the lowest and highest sag.
fn extent(p: &Prescription) -> (f64, f64) {
    let (mut lo, mut hi) = (0.0_f64, 0.0_f64);
    for (s, z) in p.surfaces.iter().zip(p.vertex_z()) {
        for k in 0..=16 {
            let r = s.semi_diameter_m * k as f64 / 16.0;
            let zz = z + s.shape.sag(r * r).unwrap_or(0.0);
            lo = lo.min(zz);
            hi = hi.max(zz);
        }
    }
    (lo, hi)
}

/// An error of a catalogue file keeps its own location; anything else is the element's.
fn relocated(err: Error, element: impl Fn() -> Error) -> Error {
    match &err {
        Error::Input { location, .. } if location.file.is_some() => err,
        Error::Io { .. } => err,
        _ => element(),
    }
}
