//! Triangle soups in scene millimetres: plane shapes (discs, rings, rectangles, with holes),
//! spherical caps with exact vertex normals, cylinders, the clear strips between a chart's
//! chrome, and their binary PLY form.

use std::fmt::Write as _;

use glam::DVec3;

use super::{CAP_RINGS, MM, SEGMENTS};
use crate::optics::geometry::{Frame, Geometry, Shape2D, sag};
use crate::optics::lens::Shape as LensShape;

/// A triangle soup in scene millimetres, optionally with vertex normals.
#[derive(Debug, Default, Clone)]
pub(super) struct Soup {
    v: Vec<[f32; 3]>,
    n: Vec<[f32; 3]>,
    f: Vec<[u32; 3]>,
}

impl Soup {
    pub(super) fn vertex(&mut self, p: DVec3, normal: Option<DVec3>) -> u32 {
        let q = p * MM;
        self.v.push([q.x as f32, q.y as f32, q.z as f32]);
        if let Some(n) = normal {
            let n = n.normalize();
            self.n.push([n.x as f32, n.y as f32, n.z as f32]);
        }
        (self.v.len() - 1) as u32
    }

    pub(super) fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.f.push([a, b, c]);
    }

    /// A planar quadrilateral (corners in order around it) as two triangles, without normals.
    pub(super) fn quad(&mut self, corners: [DVec3; 4]) {
        let [a, b, c, d] = corners.map(|p| self.vertex(p, None));
        self.tri(a, b, c);
        self.tri(a, c, d);
    }

    pub(super) fn append(&mut self, other: &Soup) {
        let base = self.v.len() as u32;
        self.v.extend_from_slice(&other.v);
        self.f.extend(
            other
                .f
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    pub(super) fn is_empty(&self) -> bool {
        self.f.is_empty()
    }

    /// Binary little-endian PLY (normals only if every vertex has one).
    pub(super) fn ply(&self) -> Vec<u8> {
        let normals = !self.n.is_empty() && self.n.len() == self.v.len();
        let mut h = String::from("ply\nformat binary_little_endian 1.0\n");
        let _ = writeln!(h, "element vertex {}", self.v.len());
        h.push_str("property float x\nproperty float y\nproperty float z\n");
        if normals {
            h.push_str("property float nx\nproperty float ny\nproperty float nz\n");
        }
        let _ = writeln!(h, "element face {}", self.f.len());
        h.push_str("property list uchar int vertex_indices\nend_header\n");
        let mut out = h.into_bytes();
        for (i, v) in self.v.iter().enumerate() {
            for c in v {
                out.extend_from_slice(&c.to_le_bytes());
            }
            if normals {
                for c in &self.n[i] {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
        for t in &self.f {
            out.push(3);
            for &i in t {
                out.extend_from_slice(&(i as i32).to_le_bytes());
            }
        }
        out
    }
}

/// The radius of a regular polygon of `n` sides with the area of the circle of radius `r`.
pub(super) fn area_preserving(r: f64, n: usize) -> f64 {
    let a = std::f64::consts::TAU / n as f64;
    r * (a / a.sin()).sqrt()
}

/// A planar outline triangulated counter-clockwise in (u, v), so the normal is `frame.w`.
pub(super) fn plane_soup(frame: &Frame, shape: Shape2D) -> Soup {
    let mut s = Soup::default();
    let at = |x: f64, y: f64| frame.origin + x * frame.u + y * frame.v;
    let n = SEGMENTS;
    let ring = |r: f64, k: usize| {
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        (r * a.cos(), r * a.sin())
    };
    match shape {
        Shape2D::Disk { radius } => {
            let r = area_preserving(radius, n);
            let c = s.vertex(at(0.0, 0.0), None);
            let first = s.v.len() as u32;
            for k in 0..n {
                let (x, y) = ring(r, k);
                s.vertex(at(x, y), None);
            }
            for k in 0..n as u32 {
                s.tri(c, first + k, first + (k + 1) % n as u32);
            }
        }
        Shape2D::Annulus { inner, outer } => {
            let (ri, ro) = (area_preserving(inner, n), area_preserving(outer, n));
            strip(
                &mut s,
                n,
                |k| at(ring(ri, k).0, ring(ri, k).1),
                |k| at(ring(ro, k).0, ring(ro, k).1),
            );
        }
        Shape2D::Rect { half_u, half_v } => {
            s.quad([
                at(-half_u, -half_v),
                at(half_u, -half_v),
                at(half_u, half_v),
                at(-half_u, half_v),
            ]);
        }
        Shape2D::RectWithRectHole {
            half_u,
            half_v,
            hole_u,
            hole_v,
        } => {
            let outer = [
                (-half_u, -half_v),
                (half_u, -half_v),
                (half_u, half_v),
                (-half_u, half_v),
            ];
            let inner = [
                (-hole_u, -hole_v),
                (hole_u, -hole_v),
                (hole_u, hole_v),
                (-hole_u, hole_v),
            ];
            strip(
                &mut s,
                4,
                |k| at(inner[k].0, inner[k].1),
                |k| at(outer[k].0, outer[k].1),
            );
        }
        Shape2D::RectWithHole {
            half_u,
            half_v,
            hole,
        } => {
            // Wedges from the hole polygon out to the rectangle, with the rectangle's corners
            // inserted in the wedges that contain them.
            let r = area_preserving(hole, n);
            let to_rect = |k: usize| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                let (c, si) = (a.cos(), a.sin());
                let t = (half_u / c.abs().max(1e-300)).min(half_v / si.abs().max(1e-300));
                (t * c, t * si)
            };
            let corners = [
                (half_u, half_v),
                (-half_u, half_v),
                (-half_u, -half_v),
                (half_u, -half_v),
            ];
            for k in 0..n {
                let a0 = std::f64::consts::TAU * k as f64 / n as f64;
                let a1 = std::f64::consts::TAU * (k + 1) as f64 / n as f64;
                let (i0, i1) = (ring(r, k), ring(r, k + 1));
                let (o0, o1) = (to_rect(k), to_rect(k + 1));
                let ia = s.vertex(at(i0.0, i0.1), None);
                let ib = s.vertex(at(i1.0, i1.1), None);
                let oa = s.vertex(at(o0.0, o0.1), None);
                let ob = s.vertex(at(o1.0, o1.1), None);
                let corner = corners.iter().find(|c| {
                    let a = c.1.atan2(c.0).rem_euclid(std::f64::consts::TAU);
                    a > a0 && a < a1
                });
                match corner {
                    Some(c) => {
                        let cv = s.vertex(at(c.0, c.1), None);
                        s.tri(ia, oa, cv);
                        s.tri(ia, cv, ob);
                    }
                    None => s.tri(ia, oa, ob),
                }
                s.tri(ia, ob, ib);
            }
        }
    }
    s
}

/// Quads between an inner and an outer closed chain of `n` points (counter-clockwise).
pub(super) fn strip(
    s: &mut Soup,
    n: usize,
    inner: impl Fn(usize) -> DVec3,
    outer: impl Fn(usize) -> DVec3,
) {
    let first = s.v.len() as u32;
    for k in 0..n {
        s.vertex(inner(k), None);
        s.vertex(outer(k), None);
    }
    for k in 0..n as u32 {
        let (i0, o0) = (first + 2 * k, first + 2 * k + 1);
        let k1 = (k + 1) % n as u32;
        let (i1, o1) = (first + 2 * k1, first + 2 * k1 + 1);
        s.tri(i0, o0, o1);
        s.tri(i0, o1, i1);
    }
}

/// A spherical cap between `rho0` and `rho1` from the axis, with exact vertex normals
/// (p − centre)/R and the winding that agrees with them.
pub(super) fn cap_soup(vertex: DVec3, axis: DVec3, radius: f64, rho0: f64, rho1: f64) -> Soup {
    let centre = vertex + radius * axis;
    let limit = radius.abs() * (1.0 - 1e-12);
    revolved_soup(
        vertex,
        axis,
        rho0,
        rho1,
        limit,
        |rho| sag(radius, rho),
        |p| (p - centre) / radius,
    )
}

/// A lens surface of any `optics::lens::Shape` (`Geometry::Asphere`) between `rho0` and
/// `rho1` from its axis, with the analytic normals (−w at the vertex).
pub(super) fn asphere_soup(frame: &Frame, shape: &LensShape, rho0: f64, rho1: f64) -> Soup {
    let f = *frame;
    let limit = shape.s_max().sqrt() * (1.0 - 1e-12);
    revolved_soup(
        f.origin,
        f.w,
        rho0,
        rho1,
        limit,
        |rho| shape.sag(rho * rho).unwrap_or(0.0),
        move |p| {
            let l = f.to_local(p);
            let n = shape.normal(l).unwrap_or(DVec3::Z);
            -(n.x * f.u + n.y * f.v + n.z * f.w)
        },
    )
}

/// A surface of revolution z = sag(ρ) about `axis` from `vertex`, rings from `rho0` to `rho1`
/// (area-preserving radii, at most `rho_max`), with per-vertex normals.
fn revolved_soup(
    vertex: DVec3,
    axis: DVec3,
    rho0: f64,
    rho1: f64,
    rho_max: f64,
    sag_of: impl Fn(f64) -> f64,
    normal: impl Fn(DVec3) -> DVec3,
) -> Soup {
    let mut s = Soup::default();
    // e1 × e2 = −axis: counter-clockwise in (e1, e2) faces −axis, the normal at the vertex.
    let f = Frame::new(vertex, -axis, None);
    let (e1, e2) = (f.u, f.v);
    let n = SEGMENTS;
    let scale = area_preserving(1.0, n);
    let point = |rho: f64, k: usize| {
        let rho = (rho * scale).min(rho_max);
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        vertex + sag_of(rho) * axis + rho * (a.cos() * e1 + a.sin() * e2)
    };
    let rings = ((CAP_RINGS as f64 * (rho1 - rho0) / rho1).ceil() as usize).max(2);
    let mut prev: Option<u32> = None;
    let mut start = 0;
    if rho0 <= 0.0 {
        let c = s.vertex(vertex, Some(normal(vertex)));
        prev = Some(c);
        start = 1;
    }
    let mut prev_ring: Option<u32> = None;
    for i in start..=rings {
        let rho = rho0 + (rho1 - rho0) * i as f64 / rings as f64;
        let first = s.v.len() as u32;
        for k in 0..n {
            let p = point(rho, k);
            s.vertex(p, Some(normal(p)));
        }
        let nn = n as u32;
        match (prev_ring, prev) {
            (Some(pr), _) => {
                for k in 0..nn {
                    let k1 = (k + 1) % nn;
                    s.tri(pr + k, first + k, first + k1);
                    s.tri(pr + k, first + k1, pr + k1);
                }
            }
            (None, Some(c)) => {
                for k in 0..nn {
                    s.tri(c, first + k, first + (k + 1) % nn);
                }
            }
            (None, None) => {}
        }
        prev_ring = Some(first);
    }
    s
}

/// The side of a cylinder (black: its winding does not matter).
pub(super) fn cylinder_soup(base: DVec3, axis: DVec3, radius: f64, length: f64) -> Soup {
    let f = Frame::new(base, axis, None);
    let r = area_preserving(radius, SEGMENTS);
    let ring = |k: usize, h: f64| {
        let a = std::f64::consts::TAU * k as f64 / SEGMENTS as f64;
        base + h * axis + r * (a.cos() * f.u + a.sin() * f.v)
    };
    let mut s = Soup::default();
    strip(&mut s, SEGMENTS, |k| ring(k, 0.0), |k| ring(k, length));
    s
}

pub(super) fn geometry_soup(g: &Geometry, rho_range: Option<(f64, f64)>) -> Soup {
    match g {
        Geometry::Plane { frame, shape } => plane_soup(frame, *shape),
        Geometry::SphereCap {
            vertex,
            axis,
            radius,
            aperture,
            inner,
        } => {
            let (a, b) = rho_range.unwrap_or((*inner, *aperture));
            cap_soup(*vertex, *axis, *radius, a, b)
        }
        Geometry::Asphere {
            frame,
            shape,
            aperture,
        } => {
            let (a, b) = rho_range.unwrap_or((0.0, *aperture));
            asphere_soup(frame, shape, a, b)
        }
        Geometry::Cylinder {
            base,
            axis,
            radius,
            length,
        } => cylinder_soup(*base, *axis, *radius, *length),
    }
}

/// The chrome of a chart face outside its image: up to four rectangles (below, above, left and
/// right of the image) of the plate `(half_u, half_v)`, the image spanning `(x0, x1, y0, y1)`
/// in face coordinates.
pub(super) fn chrome_strips(
    face: &Frame,
    (half_u, half_v): (f64, f64),
    bounds: (f64, f64, f64, f64),
) -> Soup {
    let (x0, x1, y0, y1) = bounds;
    let mut rest = Soup::default();
    let at = |x: f64, y: f64| face.origin + x * face.u + y * face.v;
    for (a, b, cc, d) in [
        (
            (-half_u, -half_v),
            (half_u, -half_v),
            (half_u, y0),
            (-half_u, y0),
        ),
        (
            (-half_u, y1),
            (half_u, y1),
            (half_u, half_v),
            (-half_u, half_v),
        ),
        ((-half_u, y0), (x0, y0), (x0, y1), (-half_u, y1)),
        ((x1, y0), (half_u, y0), (half_u, y1), (x1, y1)),
    ] {
        if (b.0 - a.0) <= 0.0 || (cc.1 - b.1) <= 0.0 {
            continue;
        }
        let i = rest.vertex(at(a.0, a.1), None);
        let j = rest.vertex(at(b.0, b.1), None);
        let l = rest.vertex(at(cc.0, cc.1), None);
        let m = rest.vertex(at(d.0, d.1), None);
        rest.tri(i, j, l);
        rest.tri(i, l, m);
    }
    rest
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed area of a triangle soup projected on the xy plane (positive counter-clockwise).
    fn signed_area_z(s: &Soup) -> f64 {
        let p = |i: u32| {
            let v = s.v[i as usize];
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        s.f.iter()
            .map(|t| 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).z)
            .sum()
    }

    #[test]
    fn polygons_keep_the_circle_area() {
        let f = Frame::new(DVec3::ZERO, DVec3::Z, None);
        let s = plane_soup(&f, Shape2D::Disk { radius: 1.0 });
        let area = signed_area_z(&s);
        // Counter-clockwise (normal +z) and the area of the unit circle in mm² (1 m = 1000 mm),
        // to f32 rounding of the vertices.
        let exact = std::f64::consts::PI * 1e6;
        assert!((area - exact).abs() < 1e-5 * exact, "{area}");
    }

    #[test]
    fn rect_with_hole_covers_the_rect_minus_the_hole() {
        let f = Frame::new(DVec3::ZERO, DVec3::Z, None);
        let s = plane_soup(
            &f,
            Shape2D::RectWithHole {
                half_u: 0.04,
                half_v: 0.03,
                hole: 0.01,
            },
        );
        let area = signed_area_z(&s);
        let exact = (0.08 * 0.06 - std::f64::consts::PI * 1e-4) * 1e6;
        assert!((area - exact).abs() < 1e-5 * exact, "{area} vs {exact}");
    }

    #[test]
    fn cap_normals_agree_with_the_winding() {
        for r in [0.05, -0.05] {
            let s = cap_soup(DVec3::new(0.0, 0.0, 0.1), DVec3::Z, r, 0.0, 0.02);
            for t in &s.f {
                let p = |i: u32| {
                    let v = s.v[i as usize];
                    DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
                };
                let geo = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
                let n = s.n[t[0] as usize];
                let n = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
                assert!(geo.dot(n) > 0.0);
            }
        }
    }
}
