//! The `LensSystem` element: a prescription from a Zemax file (through `crate::lens`) or from
//! inline surfaces, checked, converted to SI and added as bench surfaces
//! (`optics::lens::parts`).

use std::path::Path;

use crate::error::{Error, Result};
use crate::lens::{GlassOptions, Substitution, agf::Catalogue, read_zmx};
use crate::optics::bench::{ElementId, Solid};
use crate::optics::geometry::Frame;
use crate::optics::lens::parts::add_lens_system;
use crate::optics::lens::{Defect, LensSurface, Medium, Prescription, Shape};

use super::build::{Builder, Ctx, mm};
use super::schema::{BenchFile, ElementSpec, LensSpec, LensSurfaceSpec, LensSystemSpec};
use crate::optics::bench::BenchParts;
use crate::scene::locate::Locator;
use crate::scene::numbers::RadiusMm;

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
        let (p, _) = self.prescription(el, n)?;
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

    /// The element's prescription as the light meets it (turned round when `reversed`), with
    /// the glasses modelled from a file's nd and Vd (only where `allow_glass_substitution`).
    pub(super) fn prescription(
        &self,
        el: &LensSystemSpec,
        n: &str,
    ) -> Result<(Prescription, Vec<Substitution>)> {
        let e = |f: &str, m: String| self.ctx.err_el(n, f, m);
        let base = self.ctx.path.parent().unwrap_or(Path::new(""));
        let (p, subs) = match (&el.zmx, &el.surfaces) {
            (Some(file), None) => {
                let catalogues = el
                    .glass_catalogues
                    .iter()
                    .map(|c| Catalogue::read(&base.join(c)))
                    .collect::<Result<Vec<_>>>()
                    .map_err(|err| relocated(err, || e("glass_catalogues", String::new())))?;
                // A substitution is never silent: the bench states its permission, and every
                // command reports what was substituted (`lens_substitutions`).
                let glasses = GlassOptions {
                    catalogues,
                    allow_substitution: el.allow_glass_substitution,
                };
                let loaded = read_zmx(&base.join(file), &glasses)?;
                (loaded.prescription, loaded.substitutions)
            }
            (None, Some(surfaces)) => (self.inline(n, surfaces)?, Vec::new()),
            _ => {
                return Err(e(
                    "zmx",
                    "a LensSystem takes either `zmx` (a prescription file) or `surfaces`".into(),
                ));
            }
        };
        Ok((if el.reversed { p.reversed() } else { p }, subs))
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

/// A `Builder` for reading the lens elements of `file` alone (its own glasses checked), without
/// building the bench.
fn lens_reader<'a>(file: &BenchFile, text: Option<&'a str>, path: &'a Path) -> Result<Builder<'a>> {
    let mut b = Builder {
        ctx: Ctx {
            loc: text.map(|text| Locator { text }),
            path,
            glasses: Vec::new(),
        },
        parts: BenchParts::new(),
        solids: Vec::new(),
        throughput: Vec::new(),
    };
    let band = (file.band_nm.0.0 * 1e-9, file.band_nm.1.0 * 1e-9);
    b.ctx.glasses = b.user_glasses(file, band)?;
    Ok(b)
}

/// The prescription of the bench element `name` (a `Lens` or a `LensSystem`) as the bench
/// builds it, in the light's direction, with the substitutions its glasses needed.
pub fn element_prescription(
    file: &BenchFile,
    text: Option<&str>,
    path: &Path,
    name: &str,
) -> Result<(Prescription, Vec<Substitution>)> {
    let b = lens_reader(file, text, path)?;
    let lenses: Vec<&str> = file
        .elements
        .iter()
        .filter(|el| matches!(el, ElementSpec::Lens(_) | ElementSpec::LensSystem(_)))
        .map(|el| el.name())
        .collect();
    let el = file.elements.iter().find(|el| el.name() == name);
    match el {
        Some(ElementSpec::LensSystem(l)) => b.prescription(l, name),
        Some(ElementSpec::Lens(l)) => Ok((b.singlet(l, name)?, Vec::new())),
        _ => Err(Error::field(
            "element",
            format!(
                "the bench has no lens named `{name}`{}; its lenses: {}",
                if el.is_some() {
                    " (that element is no lens)"
                } else {
                    ""
                },
                if lenses.is_empty() {
                    "none".into()
                } else {
                    lenses.join(", ")
                }
            ),
        )
        .in_file(path)),
    }
}

/// Every glass the bench's `LensSystem` elements model from a file's nd and Vd (each allowed
/// by its element's `allow_glass_substitution`), in element order.
pub fn lens_substitutions(file: &BenchFile, path: &Path) -> Result<Vec<Substitution>> {
    let b = lens_reader(file, None, path)?;
    let mut out = Vec::new();
    for el in &file.elements {
        if let ElementSpec::LensSystem(l) = el
            && l.allow_glass_substitution
        {
            out.extend(b.prescription(l, &l.name)?.1);
        }
    }
    Ok(out)
}

impl Builder<'_> {
    /// A `Lens` element as a two-surface prescription (its clear aperture on both faces).
    fn singlet(&self, el: &LensSpec, n: &str) -> Result<Prescription> {
        let glass = self
            .ctx
            .glass(&el.glass, |m| self.ctx.err_el(n, "glass", m))?;
        let sd = 0.5e-3 * el.clear_diameter_mm.unwrap_or(el.diameter_mm).0;
        let shape = |r: Option<RadiusMm>| r.map_or(Shape::Flat, |r| Shape::Sphere { c: 1e3 / r.0 });
        let p = Prescription {
            name: n.to_string(),
            surfaces: vec![
                LensSurface {
                    shape: shape(el.front_radius_mm),
                    semi_diameter_m: sd,
                    thickness_m: el.thickness_mm.0 * 1e-3,
                    medium_after: Medium {
                        name: el.glass.clone(),
                        glass,
                        range_nm: None,
                        source: "bench".into(),
                    },
                },
                LensSurface {
                    shape: shape(el.back_radius_mm),
                    semi_diameter_m: sd,
                    thickness_m: 0.0,
                    medium_after: Medium::air(),
                },
            ],
            image_distance_m: None,
        };
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::doc::BenchDoc;

    /// The paper bench with its four LA1050 singlets as `LensSystem(zmx: "parts/…")`.
    fn lens_system_paper() -> BenchDoc {
        let doc =
            BenchDoc::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron"))
                .unwrap();
        let mut file = doc.file.clone();
        for el in &mut file.elements {
            if let ElementSpec::Lens(l) = el {
                *el = ElementSpec::LensSystem(LensSystemSpec {
                    name: l.name.clone(),
                    part: l.part.clone(),
                    zmx: Some("parts/thorlabs_la1050.zmx".into()),
                    surfaces: None,
                    reversed: l.front_radius_mm.is_none(),
                    position_mm: l.position_mm,
                    axis: l.axis,
                    diameter_mm: Some(l.diameter_mm),
                    clear_diameter_mm: l.clear_diameter_mm,
                    glass_catalogues: Vec::new(),
                    allow_glass_substitution: false,
                    coating: l.coating.clone(),
                    tilt_deg: l.tilt_deg,
                });
            }
        }
        BenchDoc::from_file(file, doc.path())
    }

    /// The shipped tolerance file of the paper bench reads against the bench rebuilt with
    /// `LensSystem` elements, and each of its lens tolerances, at either end of its range,
    /// builds a bench whose lens moved: decentred across the axis, despaced along it, tilted.
    #[test]
    fn the_paper_tolerances_move_lens_systems() {
        let doc = lens_system_paper();
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let set = crate::scene::tolerance::ToleranceSet::read(
            &root.join("scenes/tolerances/paper_bench.ron"),
            &doc,
        )
        .unwrap();
        let nominal = crate::optics::outline::lenses(&doc.build().unwrap());
        let mut moved = 0;
        for t in set.tolerances.iter().filter(|t| t.path.contains("_lens.")) {
            let name = t.path.split('.').next().unwrap();
            let before = nominal.iter().find(|l| l.name == name).unwrap();
            for end in [t.min, t.max] {
                let edited = doc.with(&[(t.path.clone(), t.nominal + end)]).unwrap();
                let bench = edited.build().unwrap();
                let after = crate::optics::outline::lenses(&bench)
                    .into_iter()
                    .find(|l| l.name == name)
                    .unwrap();
                let shift = after.vertex - before.vertex;
                let along = shift.dot(before.axis);
                if t.path.ends_with("despace_mm") {
                    // Along the part's axis, which the lens's own tilt turns a little from its optics.
                    assert!(
                        (shift.length() - end.abs() * 1e-3).abs() < 1e-9,
                        "{}",
                        t.path
                    );
                    assert!(
                        (along - end * 1e-3).abs() < 1e-2 * end.abs() * 1e-3,
                        "{}: {shift}",
                        t.path
                    );
                } else if t.path.contains("decenter_mm") {
                    // Across the part's axis (the file's own tilt of a lens, a fraction of a
                    // degree, turns its optical axis a little from the part frame's).
                    assert!(
                        along.abs() < 1e-2 * end.abs() * 1e-3,
                        "{}: {along} m",
                        t.path
                    );
                    assert!(
                        (shift.length() - end.abs() * 1e-3).abs() < 1e-9,
                        "{}",
                        t.path
                    );
                } else {
                    let turn = after.axis.angle_between(before.axis).to_degrees();
                    // Composed with the lens's own tilt in the file: the same turn to 1 %.
                    assert!(
                        (turn - end.abs()).abs() < 1e-2 * end.abs(),
                        "{}: {turn}°",
                        t.path
                    );
                }
                moved += 1;
            }
        }
        assert_eq!(moved, 2 * 10);
    }
}
