//! Triangle meshes for mounts, tubes and baffles, intersected through an obvhs BVH.
//!
//! obvhs works in f32 with glam `Vec3A`. Meshes here are black absorbers (anodised mounts), so
//! only the hit distance matters: f32 in metres resolves ~0.1 µm at the bench's scale, far
//! below any mount tolerance. The optical surfaces themselves are analytic f64 (geometry.rs).
//!
//! obvhs 0.4 `CwBvh` misses every hit when a direction component is −0.0 (docs/rust-notes.md §4): every
//! ray is built by [`bvh_ray`], which adds +0.0 to turn −0.0 into +0.0.

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;

use super::geometry::Frame;

/// A triangle mesh with its BVH. Triangles are reordered into BVH order once, so the closure
/// receives the triangle directly.
pub struct Mesh {
    tris: Vec<Triangle>,
    bvh: CwBvh,
    lo: DVec3,
    hi: DVec3,
}

impl std::fmt::Debug for Mesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Mesh({} triangles)", self.tris.len())
    }
}

impl Clone for Mesh {
    fn clone(&self) -> Self {
        Mesh::new(self.tris.clone())
    }
}

/// The one way to make an obvhs ray: `+ Vec3A::ZERO` turns a −0.0 component into +0.0
/// (the CwBvh −0.0 traversal bug, docs/rust-notes.md §4).
#[inline]
pub fn bvh_ray(o: DVec3, d: DVec3, t_max: f64) -> Ray {
    let o = Vec3A::new(o.x as f32, o.y as f32, o.z as f32);
    let d = Vec3A::new(d.x as f32, d.y as f32, d.z as f32) + Vec3A::ZERO;
    Ray::new(o, d, 0.0, t_max.min(f32::MAX as f64) as f32)
}

impl Mesh {
    pub fn new(tris: Vec<Triangle>) -> Mesh {
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        // Reorder the triangles so that BVH slot i is triangle i.
        let ordered: Vec<Triangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for t in &tris {
            for v in [t.v0, t.v1, t.v2] {
                let p = DVec3::new(v.x as f64, v.y as f64, v.z as f64);
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        // Pad the box by 1 µm: f32 vertices and f64 rays must not disagree at its faces.
        let pad = DVec3::splat(1e-6);
        Mesh {
            tris: ordered,
            bvh,
            lo: lo - pad,
            hi: hi + pad,
        }
    }

    pub fn triangles(&self) -> &[Triangle] {
        &self.tris
    }

    /// The bounding box (lo, hi), padded by 1 µm.
    pub fn aabb(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// Distance to the nearest triangle along the unit direction `d`, if below `t_max`. Hits
    /// closer than `t_min` (the ray's own starting surface) are ignored.
    pub fn intersect(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
        let mut ray = bvh_ray(o, d, t_max);
        ray.tmin = t_min as f32;
        let mut hit = RayHit::none();
        let tris = &self.tris;
        if self
            .bvh
            .ray_traverse(ray, &mut hit, |r, id| tris[id].intersect(r))
        {
            Some(hit.t as f64)
        } else {
            None
        }
    }

    /// A closed tube (the side of a cylinder) of `radius` along the frame's w axis from the frame
    /// origin to `length`, as `segments` flat facets (2 triangles each).
    pub fn tube(frame: &Frame, radius: f64, length: f64, segments: usize) -> Mesh {
        let n = segments.max(3);
        let ring = |k: usize, h: f64| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            frame.to_world(DVec3::new(radius * a.cos(), radius * a.sin(), h))
        };
        let mut tris = Vec::with_capacity(2 * n);
        for k in 0..n {
            let (a0, a1) = (ring(k, 0.0), ring(k + 1, 0.0));
            let (b0, b1) = (ring(k, length), ring(k + 1, length));
            tris.push(tri(a0, a1, b1));
            tris.push(tri(a0, b1, b0));
        }
        Mesh::new(tris)
    }

    /// A flat rectangular plate (half sizes `half_u`, `half_v` in the frame's plane) with a
    /// centred circular hole of radius `hole`, triangulated as a fan between the hole's polygon
    /// (`segments` sides) and the rectangle's outline.
    pub fn plate_with_hole(
        frame: &Frame,
        half_u: f64,
        half_v: f64,
        hole: f64,
        segments: usize,
    ) -> Mesh {
        let n = segments.max(8).next_multiple_of(4);
        let mut tris = Vec::with_capacity(2 * n);
        // Each hole vertex pairs with the point where its ray from the centre meets the
        // rectangle; the rectangle corners are added where the ray sweeps past them.
        let outer = |a: f64| {
            let (c, s) = (a.cos(), a.sin());
            let k = (half_u / c.abs().max(1e-300)).min(half_v / s.abs().max(1e-300));
            DVec3::new(k * c, k * s, 0.0)
        };
        let corner_between = |a0: f64, a1: f64| {
            let corners = [
                (half_v.atan2(half_u), DVec3::new(half_u, half_v, 0.0)),
                (half_v.atan2(-half_u), DVec3::new(-half_u, half_v, 0.0)),
                (
                    (-half_v).atan2(-half_u) + std::f64::consts::TAU,
                    DVec3::new(-half_u, -half_v, 0.0),
                ),
                (
                    (-half_v).atan2(half_u) + std::f64::consts::TAU,
                    DVec3::new(half_u, -half_v, 0.0),
                ),
            ];
            corners
                .iter()
                .find(|(a, _)| *a > a0 && *a < a1)
                .map(|&(_, p)| p)
        };
        let w = |p: DVec3| frame.to_world(p);
        for k in 0..n {
            let a0 = std::f64::consts::TAU * k as f64 / n as f64;
            let a1 = std::f64::consts::TAU * (k + 1) as f64 / n as f64;
            let h0 = DVec3::new(hole * a0.cos(), hole * a0.sin(), 0.0);
            let h1 = DVec3::new(hole * a1.cos(), hole * a1.sin(), 0.0);
            let (o0, o1) = (outer(a0), outer(a1));
            match corner_between(a0, a1) {
                None => {
                    tris.push(tri(w(h0), w(o0), w(o1)));
                    tris.push(tri(w(h0), w(o1), w(h1)));
                }
                Some(c) => {
                    tris.push(tri(w(h0), w(o0), w(c)));
                    tris.push(tri(w(h0), w(c), w(h1)));
                    tris.push(tri(w(h1), w(c), w(o1)));
                }
            }
        }
        Mesh::new(tris)
    }
}

fn tri(a: DVec3, b: DVec3, c: DVec3) -> Triangle {
    let f = |p: DVec3| Vec3A::new(p.x as f32, p.y as f32, p.z as f32);
    Triangle {
        v0: f(a),
        v1: f(b),
        v2: f(c),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minus_z_direction_hits_plate() {
        // Regression for the obvhs CwBvh −0.0 bug (docs/rust-notes.md §4): a ray straight down −Z, whose
        // x and y components are −0.0 after negation, must still hit the plate.
        let frame = Frame::new(DVec3::new(0.0, 0.0, 0.1), DVec3::Z, None);
        let plate = Mesh::plate_with_hole(&frame, 0.05, 0.04, 0.01, 32);
        let d = -DVec3::new(0.0, 0.0, 1.0); // (−0.0, −0.0, −1.0)
        assert!(d.x.is_sign_negative() && d.y.is_sign_negative());
        let t = plate
            .intersect(DVec3::new(0.02, 0.0, 0.5), d, 0.0, 10.0)
            .unwrap();
        assert!((t - 0.4).abs() < 1e-6, "t = {t}");
        // Through the hole: no hit.
        assert!(
            plate
                .intersect(DVec3::new(0.0, 0.0, 0.5), d, 0.0, 10.0)
                .is_none()
        );
        // Outside the plate: no hit; in a corner: hit.
        assert!(
            plate
                .intersect(DVec3::new(0.06, 0.0, 0.5), d, 0.0, 10.0)
                .is_none()
        );
        assert!(
            plate
                .intersect(DVec3::new(0.049, 0.039, 0.5), d, 0.0, 10.0)
                .is_some()
        );
    }

    #[test]
    fn plate_area_is_rectangle_minus_polygon() {
        let frame = Frame::new(DVec3::ZERO, DVec3::Z, None);
        let (hu, hv, r, n) = (0.03, 0.02, 0.01, 64);
        let plate = Mesh::plate_with_hole(&frame, hu, hv, r, n);
        let area: f64 = plate
            .triangles()
            .iter()
            .map(|t| 0.5 * (t.v1 - t.v0).cross(t.v2 - t.v0).length() as f64)
            .sum();
        let polygon = 0.5 * n as f64 * r * r * (std::f64::consts::TAU / n as f64).sin();
        let expect = 4.0 * hu * hv - polygon;
        assert!((area / expect - 1.0).abs() < 1e-5, "{area} vs {expect}");
    }

    #[test]
    fn tube_blocks_oblique_rays() {
        let frame = Frame::new(DVec3::ZERO, -DVec3::Z, None);
        let tube = Mesh::tube(&frame, 0.02, 0.1, 64);
        // From the axis, sideways and down: hits the wall at ~0.02/sinθ.
        let d = DVec3::new(0.0, -1.0, -1.0).normalize();
        let t = tube
            .intersect(DVec3::new(0.0, 0.0, -0.001), d, 0.0, 1.0)
            .unwrap();
        let r = 0.02 * (std::f64::consts::PI / 64.0).cos(); // inscribed facet distance
        assert!(
            t >= r * 2f64.sqrt() - 1e-6 && t <= 0.02 * 2f64.sqrt() + 1e-6,
            "{t}"
        );
        // Straight along the axis: never hits.
        assert!(tube.intersect(DVec3::ZERO, -DVec3::Z, 0.0, 1.0).is_none());
    }
}
