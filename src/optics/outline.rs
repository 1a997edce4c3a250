//! What each element of a bench looks like and what its lenses are, recovered from the bench's
//! surfaces: 3-D outline polylines for drawings (`spibench layout`) and the lens prescriptions
//! for the paraxial numbers of `spibench check`.
//!
//! A `Bench` keeps every element as the surfaces the builder made for it (`BenchParts`), tagged
//! with the element id, so nothing new needs storing: an element's kind follows from its
//! surfaces (a chart surface makes a chart, a mirror surface a mirror, a mesh a baffle, two
//! glass interfaces of a non-absorbing medium a lens, of an absorbing one a filter; black planes
//! and cylinders alone are apertures and tubes; the DMD and photodiode entries carry their
//! reserved ledger names).

use glam::DVec3;

use super::bench::{AIR_MEDIUM, Bench, Interaction};
use super::geometry::{Frame, Geometry, Shape2D, sag};
use super::glass::Glass;
use super::lamp::EmitterShape;
use super::lens::{LensSurface, Medium, Prescription, Shape};

/// Points per full circle of an outline.
const CIRCLE_POINTS: usize = 72;

/// What an element is, for drawing and for `check`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ElementKind {
    Lamp,
    Lens,
    Filter,
    Aperture,
    Tube,
    Baffle,
    Mirror,
    Chart,
    /// The DMD: its package, window and mirror array with the pattern area.
    Dmd,
    Photodiode,
}

impl ElementKind {
    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Lamp => "lamp",
            ElementKind::Lens => "lens",
            ElementKind::Filter => "filter",
            ElementKind::Aperture => "aperture",
            ElementKind::Tube => "tube",
            ElementKind::Baffle => "baffle",
            ElementKind::Mirror => "mirror",
            ElementKind::Chart => "chart",
            ElementKind::Dmd => "DMD",
            ElementKind::Photodiode => "photodiode",
        }
    }
}

/// One element's outline: 3-D polylines in the bench frame (m).
#[derive(Debug, Clone, PartialEq)]
pub struct ElementOutline {
    pub name: String,
    pub kind: ElementKind,
    pub polylines: Vec<Vec<DVec3>>,
}

/// A lens as built (a `Lens` or a `LensSystem`): the first vertex, the axis (direction of light
/// travel), the first and last surfaces' signed paraxial radii (positive: centre of curvature
/// after the surface; `None`: flat), the first-to-last vertex thickness, the first surface's
/// semi-diameter and the first glass; and every surface as a [`Prescription`] in the light's
/// direction, for its paraxial numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct LensPrescription {
    pub name: String,
    pub vertex: DVec3,
    pub axis: DVec3,
    pub front_radius: Option<f64>,
    pub back_radius: Option<f64>,
    pub thickness: f64,
    pub semi_diameter: f64,
    pub glass: Glass,
    pub prescription: Prescription,
}

/// The kind of ledger element `id` from its surfaces and meshes (None: an element with no
/// geometry of its own, such as the lamp housing, or one that belongs to the DMD or a diode).
fn kind_of(bench: &Bench, id: usize) -> Option<ElementKind> {
    let name = bench.elements()[id].as_str();
    if name.starts_with("dmd_") {
        return Some(ElementKind::Dmd);
    }
    if name.starts_with("pd_") {
        return Some(ElementKind::Photodiode);
    }
    let surfaces: Vec<_> = bench
        .surfaces()
        .iter()
        .filter(|s| s.element == id)
        .collect();
    if bench.meshes().iter().any(|(_, e)| *e == id) {
        return Some(ElementKind::Baffle);
    }
    let mut interfaces = 0;
    let mut absorbing = false;
    for s in &surfaces {
        match &s.interaction {
            Interaction::Chart { .. } => return Some(ElementKind::Chart),
            Interaction::Mirror { .. } => return Some(ElementKind::Mirror),
            Interaction::Detector { .. } => return Some(ElementKind::Photodiode),
            Interaction::Interface { back, .. } => {
                interfaces += 1;
                absorbing |= bench.media()[*back].absorption.is_some();
            }
            Interaction::Absorber => {}
        }
    }
    if interfaces > 0 {
        return Some(if absorbing {
            ElementKind::Filter
        } else {
            ElementKind::Lens
        });
    }
    match surfaces.first().map(|s| &s.geometry) {
        Some(Geometry::Cylinder { .. }) => Some(ElementKind::Tube),
        Some(Geometry::Plane { .. })
        | Some(Geometry::SphereCap { .. })
        | Some(Geometry::Asphere { .. }) => Some(ElementKind::Aperture),
        None => None,
    }
}

fn circle(frame: &Frame, r: f64, z: f64) -> Vec<DVec3> {
    (0..=CIRCLE_POINTS)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / CIRCLE_POINTS as f64;
            frame.to_world(DVec3::new(r * a.cos(), r * a.sin(), z))
        })
        .collect()
}

fn rect(frame: &Frame, hu: f64, hv: f64) -> Vec<DVec3> {
    [
        (-1.0, -1.0),
        (1.0, -1.0),
        (1.0, 1.0),
        (-1.0, 1.0),
        (-1.0, -1.0),
    ]
    .iter()
    .map(|(a, b)| frame.to_world(DVec3::new(a * hu, b * hv, 0.0)))
    .collect()
}

fn shape_lines(frame: &Frame, shape: Shape2D) -> Vec<Vec<DVec3>> {
    match shape {
        Shape2D::Disk { radius } => vec![circle(frame, radius, 0.0)],
        Shape2D::Rect { half_u, half_v } => vec![rect(frame, half_u, half_v)],
        Shape2D::Annulus { inner, outer } => {
            vec![circle(frame, inner, 0.0), circle(frame, outer, 0.0)]
        }
        Shape2D::RectWithHole {
            half_u,
            half_v,
            hole,
        } => vec![rect(frame, half_u, half_v), circle(frame, hole, 0.0)],
        Shape2D::RectWithRectHole {
            half_u,
            half_v,
            hole_u,
            hole_v,
        } => vec![rect(frame, half_u, half_v), rect(frame, hole_u, hole_v)],
    }
}

/// Outline polylines of one surface: plane outlines, the rim and two meridian profiles of a
/// spherical cap, the end circles and four generators of a cylinder.
fn geometry_lines(g: &Geometry) -> Vec<Vec<DVec3>> {
    match g {
        Geometry::Plane { frame, shape } => shape_lines(frame, *shape),
        Geometry::SphereCap {
            vertex,
            axis,
            radius,
            aperture,
            inner,
        } => {
            let frame = Frame::new(*vertex, *axis, None);
            let mut lines = vec![circle(&frame, *aperture, sag(*radius, *aperture))];
            let n = CIRCLE_POINTS / 2;
            for dir in [frame.u, frame.v] {
                let profile: Vec<DVec3> = (0..=n)
                    .map(|k| -aperture + 2.0 * aperture * k as f64 / n as f64)
                    .filter(|r| r.abs() >= *inner)
                    .map(|r| *vertex + sag(*radius, r.abs()) * *axis + r * dir)
                    .collect();
                lines.push(profile);
            }
            lines
        }
        Geometry::Asphere {
            frame,
            shape,
            aperture,
        } => {
            let z = |r: f64| shape.sag(r * r).unwrap_or(0.0);
            let mut lines = vec![circle(frame, *aperture, z(*aperture))];
            let n = CIRCLE_POINTS / 2;
            for dir in [frame.u, frame.v] {
                let profile: Vec<DVec3> = (0..=n)
                    .map(|k| -aperture + 2.0 * aperture * k as f64 / n as f64)
                    .map(|r| frame.origin + z(r) * frame.w + r * dir)
                    .collect();
                lines.push(profile);
            }
            lines
        }
        Geometry::Cylinder {
            base,
            axis,
            radius,
            length,
        } => {
            let frame = Frame::new(*base, *axis, None);
            let mut lines = vec![
                circle(&frame, *radius, 0.0),
                circle(&frame, *radius, *length),
            ];
            for k in 0..4 {
                let a = std::f64::consts::FRAC_PI_2 * k as f64;
                let (x, y) = (radius * a.cos(), radius * a.sin());
                lines.push(vec![
                    frame.to_world(DVec3::new(x, y, 0.0)),
                    frame.to_world(DVec3::new(x, y, *length)),
                ]);
            }
            lines
        }
    }
}

/// The boundary edges of a triangle mesh (edges used by one triangle only): the outer edge and
/// the hole of a baffle plate.
fn mesh_boundary(tris: &[obvhs::triangle::Triangle]) -> Vec<Vec<DVec3>> {
    use std::collections::BTreeMap;
    let key = |v: glam::Vec3A| {
        (
            (v.x as f64 * 1e7).round() as i64,
            (v.y as f64 * 1e7).round() as i64,
            (v.z as f64 * 1e7).round() as i64,
        )
    };
    let mut edges: BTreeMap<_, (usize, DVec3, DVec3)> = BTreeMap::new();
    for t in tris {
        for (a, b) in [(t.v0, t.v1), (t.v1, t.v2), (t.v2, t.v0)] {
            let (ka, kb) = (key(a), key(b));
            let k = if ka < kb { (ka, kb) } else { (kb, ka) };
            let e = edges.entry(k).or_insert((0, a.as_dvec3(), b.as_dvec3()));
            e.0 += 1;
        }
    }
    edges
        .into_values()
        .filter(|(n, _, _)| *n == 1)
        .map(|(_, a, b)| vec![a, b])
        .collect()
}

/// Every element's outline: the lamp's filament, each named element, the DMD (package, window,
/// the mirror array and the pattern area) and the two photodiodes with their housings.
pub fn element_outlines(bench: &Bench) -> Vec<ElementOutline> {
    let mut out = Vec::new();
    let lamp = &bench.lamp();
    out.push(ElementOutline {
        name: "lamp".into(),
        kind: ElementKind::Lamp,
        polylines: match lamp.shape {
            EmitterShape::Rect { half_u, half_v } => vec![rect(&lamp.frame, half_u, half_v)],
            EmitterShape::Disk { radius } => vec![circle(&lamp.frame, radius, 0.0)],
        },
    });
    let mut dmd_lines = Vec::new();
    let mut diode_lines: [Vec<Vec<DVec3>>; 2] = [Vec::new(), Vec::new()];
    for (id, name) in bench.elements().iter().enumerate() {
        let Some(kind) = kind_of(bench, id) else {
            continue;
        };
        let mut lines = Vec::new();
        for s in bench.surfaces().iter().filter(|s| s.element == id) {
            lines.extend(geometry_lines(&s.geometry));
        }
        for (m, _) in bench.meshes().iter().filter(|(_, e)| *e == id) {
            lines.extend(mesh_boundary(m.triangles()));
        }
        match kind {
            ElementKind::Dmd => dmd_lines.extend(lines),
            ElementKind::Photodiode => {
                let k = usize::from(name.starts_with("pd_minus"));
                diode_lines[k].extend(lines);
            }
            _ => out.push(ElementOutline {
                name: name.clone(),
                kind,
                polylines: lines,
            }),
        }
    }
    if let Some(setup) = &bench.dmd() {
        let d = &setup.dmd;
        let array = Frame::new(DVec3::ZERO, DVec3::Z, Some(DVec3::X));
        let (hx, hy) = d.half_size();
        dmd_lines.push(rect(&array, hx, hy));
        let p = d.pattern;
        let n = p.mirrors_per_unit;
        let a = d.mirror_center(p.col0, p.row0);
        let b = d.mirror_center(
            p.col0 + p.units_across * n - 1,
            p.row0 + p.units_down * n - 1,
        );
        let half = 0.5 * d.pitch;
        let c = Frame {
            origin: 0.5 * (a + b),
            ..array
        };
        dmd_lines.push(rect(
            &c,
            0.5 * (b.x - a.x).abs() + half,
            0.5 * (b.y - a.y).abs() + half,
        ));
        out.push(ElementOutline {
            name: "dmd".into(),
            kind: ElementKind::Dmd,
            polylines: dmd_lines,
        });
    }
    for (k, lines) in diode_lines.into_iter().enumerate() {
        if !lines.is_empty() {
            out.push(ElementOutline {
                name: ["pd_plus", "pd_minus"][k].into(),
                kind: ElementKind::Photodiode,
                polylines: lines,
            });
        }
    }
    out
}

/// The lenses of a bench, in the order of its elements: each lens element's glass interfaces,
/// front to back (`BenchParts::lens` and `add_lens_system` make them in that order), as flats,
/// spheres and aspheres on one axis.
pub fn lenses(bench: &Bench) -> Vec<LensPrescription> {
    let mut out = Vec::new();
    for (id, name) in bench.elements().iter().enumerate() {
        if kind_of(bench, id) != Some(ElementKind::Lens) {
            continue;
        }
        // (vertex, axis along the light, shape, semi-diameter, medium after)
        let mut faces = Vec::new();
        for s in bench.surfaces().iter().filter(|s| s.element == id) {
            let Interaction::Interface { back, .. } = s.interaction else {
                continue;
            };
            let face = match s.geometry {
                Geometry::SphereCap {
                    vertex,
                    axis,
                    radius,
                    aperture,
                    ..
                } => (vertex, axis, Shape::Sphere { c: 1.0 / radius }, aperture),
                // A flat lens face's frame looks back against the light (normal −axis).
                Geometry::Plane {
                    frame,
                    shape: Shape2D::Disk { radius },
                } => (frame.origin, -frame.w, Shape::Flat, radius),
                Geometry::Asphere {
                    frame,
                    shape,
                    aperture,
                } => (frame.origin, frame.w, shape, aperture),
                _ => {
                    faces.clear();
                    break;
                }
            };
            faces.push((face, back));
        }
        if faces.len() < 2 {
            continue;
        }
        let (v0, axis) = (faces[0].0.0, faces[0].0.1);
        let surfaces: Vec<LensSurface> = faces
            .iter()
            .enumerate()
            .map(|(k, ((v, _, shape, sd), back))| LensSurface {
                shape: *shape,
                semi_diameter_m: *sd,
                thickness_m: faces.get(k + 1).map_or(0.0, |f| (f.0.0 - *v).dot(axis)),
                medium_after: if *back == AIR_MEDIUM {
                    Medium::air()
                } else {
                    Medium {
                        name: format!("medium {back}"),
                        glass: bench.media()[*back].glass.clone(),
                        range_nm: None,
                        source: "bench".into(),
                    }
                },
            })
            .collect();
        let radius = |s: &Shape| {
            let c = s.paraxial_curvature();
            (c != 0.0).then(|| 1.0 / c)
        };
        let last = faces.len() - 1;
        out.push(LensPrescription {
            name: name.clone(),
            vertex: v0,
            axis,
            front_radius: radius(&faces[0].0.2),
            back_radius: radius(&faces[last].0.2),
            thickness: (faces[last].0.0 - v0).dot(axis),
            semi_diameter: faces[0].0.3,
            glass: bench.media()[faces[0].1].glass.clone(),
            prescription: Prescription {
                name: name.clone(),
                surfaces,
                image_distance_m: None,
            },
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper bench's lenses come back as built: four LA1050 (R 51.5 mm, 9.69 mm, Ø50.8,
    /// N-BK7), the collimator flat side first, the others curved side first.
    #[test]
    fn paper_bench_lenses_and_outlines() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let l = lenses(&bench);
        let names: Vec<_> = l.iter().map(|l| l.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "collimator",
                "imaging_lens",
                "arm_plus_lens",
                "arm_minus_lens"
            ]
        );
        for lens in &l {
            assert!((lens.thickness - 9.69e-3).abs() < 1e-12, "{lens:?}");
            assert!((lens.semi_diameter - 25.4e-3).abs() < 1e-12);
            assert_eq!(lens.glass, super::super::glass::N_BK7);
        }
        assert_eq!(
            (l[0].front_radius, l[0].back_radius),
            (None, Some(-51.5 * 1e-3))
        );
        assert_eq!(
            (l[1].front_radius, l[1].back_radius),
            (Some(51.5 * 1e-3), None)
        );
        assert!((l[1].vertex - DVec3::new(0.0, 0.0, 0.205668)).length() < 1e-12);
        assert!((l[1].axis - DVec3::NEG_Z).length() < 1e-12);

        let o = element_outlines(&bench);
        let kind = |n: &str| o.iter().find(|e| e.name == n).map(|e| e.kind);
        assert_eq!(kind("lamp"), Some(ElementKind::Lamp));
        assert_eq!(kind("nd_od2"), Some(ElementKind::Filter));
        assert_eq!(kind("field_stop"), Some(ElementKind::Baffle));
        assert_eq!(kind("chart"), Some(ElementKind::Chart));
        assert_eq!(kind("imaging_iris"), Some(ElementKind::Aperture));
        assert_eq!(kind("lamp_tube"), Some(ElementKind::Tube));
        assert_eq!(kind("arm_plus_fold"), Some(ElementKind::Mirror));
        assert_eq!(kind("dmd"), Some(ElementKind::Dmd));
        assert_eq!(kind("pd_minus"), Some(ElementKind::Photodiode));
        assert!(o.iter().all(|e| !e.polylines.is_empty()));
        // The baffle's boundary: its outer edge (80 mm square) and its 20 mm hole.
        let stop = o.iter().find(|e| e.name == "field_stop").unwrap();
        let r: Vec<f64> = stop
            .polylines
            .iter()
            .flatten()
            .map(|p| p.truncate().length())
            .collect();
        let (lo, hi) = r
            .iter()
            .fold((f64::MAX, 0.0f64), |a, &x| (a.0.min(x), a.1.max(x)));
        assert!((lo - 0.010).abs() < 1e-6 && (hi - 0.040 * 2f64.sqrt()).abs() < 1e-6);
    }
}
