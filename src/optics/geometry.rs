//! Analytic surfaces in f64: planes with 2-D outlines, spherical caps and cylinders, their ray
//! intersections and bounding spheres.
//!
//! Convention: every surface has a geometric normal and therefore a *front* side (the side the
//! normal points to) and a *back* side. Interfaces store the medium on each side, so a ray's
//! incident medium follows from the sign of d·n at the hit and no per-ray medium state is needed.

use glam::{DMat3, DVec3};

/// Distance (m) by which a ray leaving a surface is moved off it, to the side it leaves on.
/// 1 nm: far below every feature of the bench (the thinnest gap is the DMD's ~1 µm) and far above
/// f64 rounding at bench scale (~1e-16 m).
pub const SURFACE_OFFSET: f64 = 1e-9;

/// An orthonormal frame: `origin`, in-plane axes `u`, `v` and normal `w` (u × v = w).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub origin: DVec3,
    pub u: DVec3,
    pub v: DVec3,
    pub w: DVec3,
}

impl Frame {
    /// A frame with normal `w` and in-plane `u` taken from the projection of `u_hint` onto the
    /// plane (or a fixed default when `u_hint` is absent or parallel to `w`).
    pub fn new(origin: DVec3, w: DVec3, u_hint: Option<DVec3>) -> Frame {
        let w = w.normalize();
        let u = match u_hint {
            Some(h) if (h - h.dot(w) * w).length() > 1e-9 => (h - h.dot(w) * w).normalize(),
            _ => default_u(w),
        };
        let v = w.cross(u);
        Frame { origin, u, v, w }
    }

    /// The frame rotated about its own `u` axis by `a` radians, then about the new `v` axis by
    /// `b` radians (small alignment tilts of an element about its centre).
    pub fn tilted(&self, a: f64, b: f64) -> Frame {
        let r1 = DMat3::from_axis_angle(self.u, a);
        let (u, v, w) = (self.u, r1 * self.v, r1 * self.w);
        let r2 = DMat3::from_axis_angle(v, b);
        Frame {
            origin: self.origin,
            u: (r2 * u).normalize(),
            v: v.normalize(),
            w: (r2 * w).normalize(),
        }
    }

    #[inline]
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        let q = p - self.origin;
        DVec3::new(q.dot(self.u), q.dot(self.v), q.dot(self.w))
    }

    #[inline]
    pub fn to_world(&self, l: DVec3) -> DVec3 {
        self.origin + l.x * self.u + l.y * self.v + l.z * self.w
    }
}

/// The default in-plane axis for a normal `w`: the projection of +x, or of +y when `w` is close
/// to ±x. For w = +z this gives u = +x, v = +y.
pub fn default_u(w: DVec3) -> DVec3 {
    let r = if w.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    (r - r.dot(w) * w).normalize()
}

/// A planar outline in the (u, v) coordinates of its frame (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape2D {
    Disk {
        radius: f64,
    },
    Rect {
        half_u: f64,
        half_v: f64,
    },
    Annulus {
        inner: f64,
        outer: f64,
    },
    /// A rectangle with a centred circular hole.
    RectWithHole {
        half_u: f64,
        half_v: f64,
        hole: f64,
    },
    /// A rectangle with a centred rectangular hole.
    RectWithRectHole {
        half_u: f64,
        half_v: f64,
        hole_u: f64,
        hole_v: f64,
    },
}

impl Shape2D {
    #[inline]
    pub fn contains(&self, x: f64, y: f64) -> bool {
        match *self {
            Shape2D::Disk { radius } => x * x + y * y <= radius * radius,
            Shape2D::Rect { half_u, half_v } => x.abs() <= half_u && y.abs() <= half_v,
            Shape2D::Annulus { inner, outer } => {
                let r2 = x * x + y * y;
                r2 >= inner * inner && r2 <= outer * outer
            }
            Shape2D::RectWithHole {
                half_u,
                half_v,
                hole,
            } => x.abs() <= half_u && y.abs() <= half_v && x * x + y * y >= hole * hole,
            Shape2D::RectWithRectHole {
                half_u,
                half_v,
                hole_u,
                hole_v,
            } => x.abs() <= half_u && y.abs() <= half_v && !(x.abs() < hole_u && y.abs() < hole_v),
        }
    }

    /// Radius of the smallest centred disk that contains the outline.
    pub fn bounding_radius(&self) -> f64 {
        match *self {
            Shape2D::Disk { radius } => radius,
            Shape2D::Annulus { outer, .. } => outer,
            Shape2D::Rect { half_u, half_v }
            | Shape2D::RectWithHole { half_u, half_v, .. }
            | Shape2D::RectWithRectHole { half_u, half_v, .. } => half_u.hypot(half_v),
        }
    }

    /// Area of the outline (m²).
    pub fn area(&self) -> f64 {
        use std::f64::consts::PI;
        match *self {
            Shape2D::Disk { radius } => PI * radius * radius,
            Shape2D::Rect { half_u, half_v } => 4.0 * half_u * half_v,
            Shape2D::Annulus { inner, outer } => PI * (outer * outer - inner * inner),
            Shape2D::RectWithHole {
                half_u,
                half_v,
                hole,
            } => 4.0 * half_u * half_v - PI * hole * hole,
            Shape2D::RectWithRectHole {
                half_u,
                half_v,
                hole_u,
                hole_v,
            } => 4.0 * (half_u * half_v - hole_u * hole_v),
        }
    }
}

/// A surface's shape in the bench.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// A planar piece: outline `shape` in the frame's (u, v) plane; normal = frame.w.
    Plane { frame: Frame, shape: Shape2D },
    /// A spherical cap: the part of the sphere of signed radius `radius` (centre at
    /// `vertex + radius·axis`) between `inner` and `aperture` from the axis, on the vertex side
    /// (`inner` = 0 for a full cap, > 0 for the ring outside a clear aperture). Normal =
    /// (p − centre)/radius, i.e. −axis at the vertex for either sign of the radius.
    SphereCap {
        vertex: DVec3,
        axis: DVec3,
        radius: f64,
        aperture: f64,
        inner: f64,
    },
    /// A rotationally symmetric lens surface of any shape (a conic or an even asphere,
    /// `optics::lens::Shape`) with its vertex at `frame.origin` and its axis `frame.w`, out to
    /// `aperture` from the axis. Normal: the analytic gradient, pointing against the axis
    /// (−w at the vertex), as a `SphereCap`'s.
    Asphere {
        frame: Frame,
        shape: super::lens::Shape,
        aperture: f64,
    },
    /// The side of a cylinder of `radius` around `axis` from `base` to `base + length·axis`;
    /// normal points outward.
    Cylinder {
        base: DVec3,
        axis: DVec3,
        radius: f64,
        length: f64,
    },
}

/// A ray–surface intersection: distance along the unit direction and the geometric normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub t: f64,
    pub normal: DVec3,
}

impl Geometry {
    /// The nearest intersection with t in (t_min, t_max) for a ray with unit direction `d`.
    #[inline]
    pub fn intersect(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<Hit> {
        match self {
            Geometry::Plane { frame, shape } => {
                let den = d.dot(frame.w);
                if den == 0.0 {
                    return None;
                }
                let t = (frame.origin - o).dot(frame.w) / den;
                if !(t > t_min && t < t_max) {
                    return None;
                }
                let q = o + t * d - frame.origin;
                if shape.contains(q.dot(frame.u), q.dot(frame.v)) {
                    Some(Hit { t, normal: frame.w })
                } else {
                    None
                }
            }
            Geometry::SphereCap {
                vertex,
                axis,
                radius,
                aperture,
                inner,
            } => {
                let c = *vertex + *radius * *axis;
                let oc = o - c;
                let b = oc.dot(d);
                let cc = oc.dot(oc) - radius * radius;
                let disc = b * b - cc;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                // Numerically stable pair of roots.
                let q = if b > 0.0 { -b - s } else { -b + s };
                let (mut t0, mut t1) = (q, if q != 0.0 { cc / q } else { -b });
                if t0 > t1 {
                    std::mem::swap(&mut t0, &mut t1);
                }
                let sign = radius.signum();
                for t in [t0, t1] {
                    if !(t > t_min && t < t_max) {
                        continue;
                    }
                    let p = o + t * d;
                    let pc = p - c;
                    // Vertex side of the sphere: (p − c)·axis has the sign of −radius.
                    if pc.dot(*axis) * sign > 0.0 {
                        continue;
                    }
                    let along = (p - *vertex).dot(*axis);
                    let radial2 = (p - *vertex).length_squared() - along * along;
                    if radial2 <= aperture * aperture && radial2 >= inner * inner {
                        return Some(Hit {
                            t,
                            normal: pc / *radius,
                        });
                    }
                }
                None
            }
            Geometry::Asphere {
                frame,
                shape,
                aperture,
            } => {
                let lo = frame.to_local(o);
                let ld = DVec3::new(d.dot(frame.u), d.dot(frame.v), d.dot(frame.w));
                let t = shape.intersect_between(lo, ld, *aperture, t_min, t_max)?;
                let n = shape.normal(lo + t * ld)?;
                let normal = -(n.x * frame.u + n.y * frame.v + n.z * frame.w);
                Some(Hit { t, normal })
            }
            Geometry::Cylinder {
                base,
                axis,
                radius,
                length,
            } => {
                let ob = o - *base;
                let dp = d - d.dot(*axis) * *axis;
                let op = ob - ob.dot(*axis) * *axis;
                let a = dp.length_squared();
                if a == 0.0 {
                    return None;
                }
                let b = op.dot(dp);
                let c = op.length_squared() - radius * radius;
                let disc = b * b - a * c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                for t in [(-b - s) / a, (-b + s) / a] {
                    if !(t > t_min && t < t_max) {
                        continue;
                    }
                    let p = ob + t * d;
                    let h = p.dot(*axis);
                    if h >= 0.0 && h <= *length {
                        let n = (p - h * *axis) / *radius;
                        return Some(Hit { t, normal: n });
                    }
                }
                None
            }
        }
    }

    /// An axis-aligned box (lo, hi) that contains the surface, for quick rejection.
    pub fn aabb(&self) -> (DVec3, DVec3) {
        // The box of a disk of radius r and unit normal n: centre ± r·√(1 − nᵢ²) per axis.
        let disk = |c: DVec3, n: DVec3, r: f64| {
            let e = DVec3::new(
                (1.0 - n.x * n.x).max(0.0).sqrt(),
                (1.0 - n.y * n.y).max(0.0).sqrt(),
                (1.0 - n.z * n.z).max(0.0).sqrt(),
            ) * r;
            (c - e, c + e)
        };
        let union = |a: (DVec3, DVec3), b: (DVec3, DVec3)| (a.0.min(b.0), a.1.max(b.1));
        match self {
            Geometry::Plane { frame, shape } => match *shape {
                Shape2D::Disk { radius } | Shape2D::Annulus { outer: radius, .. } => {
                    disk(frame.origin, frame.w, radius)
                }
                Shape2D::Rect { half_u, half_v }
                | Shape2D::RectWithHole { half_u, half_v, .. }
                | Shape2D::RectWithRectHole { half_u, half_v, .. } => {
                    let mut lo = DVec3::splat(f64::INFINITY);
                    let mut hi = DVec3::splat(f64::NEG_INFINITY);
                    for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                        let p = frame.origin + a * half_u * frame.u + b * half_v * frame.v;
                        lo = lo.min(p);
                        hi = hi.max(p);
                    }
                    (lo, hi)
                }
            },
            Geometry::SphereCap {
                vertex,
                axis,
                radius,
                aperture,
                ..
            } => {
                // The cap lies in the cylinder of radius `aperture` between the vertex plane and
                // the plane of its rim.
                let rim = *vertex + sag(*radius, *aperture) * *axis;
                union(disk(*vertex, *axis, *aperture), disk(rim, *axis, *aperture))
            }
            Geometry::Asphere {
                frame,
                shape,
                aperture,
            } => {
                // Between the vertex plane and the extremes of the sag over the aperture.
                let (mut z_lo, mut z_hi) = (0.0_f64, 0.0_f64);
                for k in 1..=64 {
                    let r = aperture * k as f64 / 64.0;
                    if let Some(z) = shape.sag(r * r) {
                        z_lo = z_lo.min(z);
                        z_hi = z_hi.max(z);
                    }
                }
                // A margin for the sag between the samples.
                let m = 0.02 * (z_hi - z_lo) + 1e-9;
                union(
                    disk(frame.origin + (z_lo - m) * frame.w, frame.w, *aperture),
                    disk(frame.origin + (z_hi + m) * frame.w, frame.w, *aperture),
                )
            }
            Geometry::Cylinder {
                base,
                axis,
                radius,
                length,
            } => union(
                disk(*base, *axis, *radius),
                disk(*base + *length * *axis, *axis, *radius),
            ),
        }
    }
}

/// The sag z(r) of a sphere of signed radius `radius` at height `r` from its axis, measured from
/// the vertex along the axis: z = R − sign(R)·√(R² − r²). Caller guarantees |R| ≥ r.
#[inline]
pub fn sag(radius: f64, r: f64) -> f64 {
    radius - radius.signum() * (radius * radius - r * r).max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_cap_hits_vertex_and_respects_aperture() {
        let cap = Geometry::SphereCap {
            vertex: DVec3::ZERO,
            axis: DVec3::Z,
            radius: 0.05,
            aperture: 0.02,
            inner: 0.0,
        };
        let h = cap
            .intersect(DVec3::new(0.0, 0.0, -1.0), DVec3::Z, 0.0, 10.0)
            .unwrap();
        assert!((h.t - 1.0).abs() < 1e-12);
        assert!(h.normal.abs_diff_eq(-DVec3::Z, 1e-12));
        // Off-axis at 0.01: hits at the sag.
        let h = cap
            .intersect(DVec3::new(0.01, 0.0, -1.0), DVec3::Z, 0.0, 10.0)
            .unwrap();
        assert!((h.t - 1.0 - sag(0.05, 0.01)).abs() < 1e-12);
        // Outside the aperture: no hit (and not the far side of the sphere).
        assert!(
            cap.intersect(DVec3::new(0.03, 0.0, -1.0), DVec3::Z, 0.0, 10.0)
                .is_none()
        );
        // Negative radius: the cap bulges the other way; the normal at the vertex is still −axis.
        let cap = Geometry::SphereCap {
            vertex: DVec3::ZERO,
            axis: DVec3::Z,
            radius: -0.05,
            aperture: 0.02,
            inner: 0.0,
        };
        let h = cap
            .intersect(DVec3::new(0.01, 0.0, -1.0), DVec3::Z, 0.0, 10.0)
            .unwrap();
        assert!((h.t - 1.0 - sag(-0.05, 0.01)).abs() < 1e-12);
        assert!(sag(-0.05, 0.01) < 0.0);
        let h0 = cap
            .intersect(DVec3::new(0.0, 0.0, -1.0), DVec3::Z, 0.0, 10.0)
            .unwrap();
        assert!(h0.normal.abs_diff_eq(-DVec3::Z, 1e-12));
    }

    #[test]
    fn cylinder_and_plane() {
        let cyl = Geometry::Cylinder {
            base: DVec3::ZERO,
            axis: DVec3::Z,
            radius: 1.0,
            length: 2.0,
        };
        let h = cyl
            .intersect(DVec3::new(-5.0, 0.0, 1.0), DVec3::X, 0.0, 100.0)
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-12 && h.normal.abs_diff_eq(-DVec3::X, 1e-12));
        assert!(
            cyl.intersect(DVec3::new(-5.0, 0.0, 3.0), DVec3::X, 0.0, 100.0)
                .is_none()
        );
        let f = Frame::new(DVec3::ZERO, DVec3::Z, None);
        assert!(f.u.abs_diff_eq(DVec3::X, 0.0) && f.v.abs_diff_eq(DVec3::Y, 0.0));
        let plane = Geometry::Plane {
            frame: f,
            shape: Shape2D::Annulus {
                inner: 1.0,
                outer: 2.0,
            },
        };
        assert!(
            plane
                .intersect(DVec3::new(0.5, 0.0, 1.0), -DVec3::Z, 0.0, 9.0)
                .is_none()
        );
        assert!(
            plane
                .intersect(DVec3::new(1.5, 0.0, 1.0), -DVec3::Z, 0.0, 9.0)
                .is_some()
        );
    }

    #[test]
    fn tilted_frame_stays_orthonormal() {
        let f = Frame::new(DVec3::ZERO, DVec3::new(0.3, -0.2, 0.9), None).tilted(0.01, -0.02);
        assert!((f.u.cross(f.v) - f.w).length() < 1e-12);
        assert!(f.u.dot(f.v).abs() < 1e-12);
    }
}
