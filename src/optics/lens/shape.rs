//! The rotationally symmetric surface shapes of a lens prescription, in a surface's own frame
//! (vertex at the origin, axis +z): their sag, analytic normal and exact ray intersection.
//!
//! The sag convention is Zemax's and ISO 10110's (and optiland's and rayoptics'), with
//! s = x² + y², curvature c = 1/R and conic constant k:
//!
//! z(s) = c s / (1 + √(1 − (1 + k) c² s)) + Σᵢ₌₁⁸ aᵢ sⁱ
//!
//! (a₁ the r² coefficient, a₂ = A₄ … a₈ = A₁₆). The conic term is defined where
//! (1 + k) c² s ≤ 1; paraboloids and hyperboloids (k ≤ −1) everywhere.

use glam::DVec3;

/// A surface shape. Lengths in metres; `a[i]` multiplies s^(i+1) = r^(2i+2), unit m^(−1−2i).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    Flat,
    /// A sphere of curvature `c` (1/m, positive when the centre lies at +z).
    Sphere {
        c: f64,
    },
    /// A conic of curvature `c` and conic constant `k` (k = 0 a sphere, −1 a paraboloid).
    Conic {
        c: f64,
        k: f64,
    },
    /// An even asphere: the conic plus the polynomial Σ aᵢ r^(2i).
    EvenAsphere {
        c: f64,
        k: f64,
        a: [f64; 8],
    },
}

/// Newton iterations allowed on an asphere before the ray counts as a miss. The iteration
/// starts on the conic's exact intersection, so it needs 3–6 steps on the shipped parts.
const NEWTON_STEPS: usize = 60;

impl Shape {
    /// Curvature and conic constant of the base conic.
    fn base(&self) -> (f64, f64) {
        match *self {
            Shape::Flat => (0.0, 0.0),
            Shape::Sphere { c } => (c, 0.0),
            Shape::Conic { c, k } | Shape::EvenAsphere { c, k, .. } => (c, k),
        }
    }

    fn poly(&self) -> Option<&[f64; 8]> {
        match self {
            Shape::EvenAsphere { a, .. } => Some(a),
            _ => None,
        }
    }

    /// The paraxial curvature (1/m): the base curvature plus twice the r² coefficient, since
    /// z ≈ (c/2 + a₁) r² near the axis.
    pub fn paraxial_curvature(&self) -> f64 {
        self.base().0 + self.poly().map_or(0.0, |a| 2.0 * a[0])
    }

    /// The largest s = r² at which the sag is defined (∞ where it is everywhere).
    pub fn s_max(&self) -> f64 {
        let (c, k) = self.base();
        let kc2 = (1.0 + k) * c * c;
        if kc2 > 0.0 { 1.0 / kc2 } else { f64::INFINITY }
    }

    /// The sag z(s) at s = r² (m), `None` outside the conic's domain.
    pub fn sag(&self, s: f64) -> Option<f64> {
        let (c, k) = self.base();
        let root = 1.0 - (1.0 + k) * c * c * s;
        if root < 0.0 {
            return None;
        }
        let mut z = c * s / (1.0 + root.sqrt());
        if let Some(a) = self.poly() {
            // Horner in s: Σ aᵢ sⁱ = s(a₁ + s(a₂ + …)).
            let mut p = 0.0;
            for ai in a.iter().rev() {
                p = p * s + ai;
            }
            z += p * s;
        }
        Some(z)
    }

    /// dz/ds at s = r², `None` outside the domain or on its edge (where the slope is vertical).
    pub fn dsag_ds(&self, s: f64) -> Option<f64> {
        let (c, k) = self.base();
        let root = 1.0 - (1.0 + k) * c * c * s;
        if root <= 0.0 && c != 0.0 {
            return None;
        }
        // d/ds [c s / (1 + √(1 − K s))] = c / (2 √(1 − K s)), K = (1 + k) c².
        let mut d = if c == 0.0 {
            0.0
        } else {
            c / (2.0 * root.sqrt())
        };
        if let Some(a) = self.poly() {
            let mut p = 0.0;
            for (i, ai) in a.iter().enumerate().rev() {
                p = p * s + (i + 1) as f64 * ai;
            }
            d += p;
        }
        Some(d)
    }

    /// The unit normal at the local point `p` (on the surface), pointing to +z (toward the
    /// side after the surface): ∇(z − sag) = (−2x z′, −2y z′, 1) normalised.
    pub fn normal(&self, p: DVec3) -> Option<DVec3> {
        let d = self.dsag_ds(p.x * p.x + p.y * p.y)?;
        Some(DVec3::new(-2.0 * p.x * d, -2.0 * p.y * d, 1.0).normalize())
    }

    /// The ray parameter t > `t_min` where the ray `o + t·d` (local frame) meets the surface
    /// within the semi-diameter `r_max`, or `None` (a miss: outside the aperture, outside the
    /// sag's domain, only the far branch of a sphere, or no convergence).
    pub fn intersect(&self, o: DVec3, d: DVec3, r_max: f64, t_min: f64) -> Option<f64> {
        self.intersect_between(o, d, r_max, t_min, f64::INFINITY)
    }

    /// The nearest t in (`t_min`, `t_max`) on the surface within `r_max`, as [`Shape::intersect`].
    pub fn intersect_between(
        &self,
        o: DVec3,
        d: DVec3,
        r_max: f64,
        t_min: f64,
        t_max: f64,
    ) -> Option<f64> {
        let roots = self.conic_roots(o, d);
        let valid = |t: f64| {
            if !(t > t_min && t < t_max && t.is_finite()) {
                return false;
            }
            let p = o + t * d;
            let s = p.x * p.x + p.y * p.y;
            if s > r_max * r_max || s > self.s_max() {
                return false;
            }
            // The quadratic also solves the far branch of a closed conic (the other side of a
            // sphere): keep only points on the sag's own branch.
            let scale = 1.0 + p.z.abs().max(r_max);
            self.sag(s).is_some_and(|z| (p.z - z).abs() <= 1e-9 * scale)
        };
        let mut best: Option<f64> = None;
        let mut consider = |t: f64| {
            if valid(t) && best.is_none_or(|b| t < b) {
                best = Some(t);
            }
        };
        match self.poly() {
            None => roots.into_iter().flatten().for_each(&mut consider),
            // Newton from each root of the base conic, and from the vertex plane (where the
            // conic misses or its roots lie outside the aperture).
            Some(_) => {
                let plane = (d.z != 0.0).then(|| -o.z / d.z);
                for t0 in roots.into_iter().chain([plane]).flatten() {
                    if let Some(t) = self.newton(o, d, t0, r_max) {
                        consider(t);
                    }
                }
            }
        }
        best
    }

    /// Both roots of the base conic c s − 2z + (1 + k) c z² = 0 along the ray, in the stable
    /// form (one tends to the plane's −o_z/d_z as c → 0, so flats and weak curves lose no
    /// digits); `None` for a missing root.
    fn conic_roots(&self, o: DVec3, d: DVec3) -> [Option<f64>; 2] {
        let (c, k) = self.base();
        let e = 1.0 + k;
        let a = c * (d.x * d.x + d.y * d.y + e * d.z * d.z);
        let b = 2.0 * (c * (o.x * d.x + o.y * d.y + e * o.z * d.z) - d.z);
        let cc = c * (o.x * o.x + o.y * o.y + e * o.z * o.z) - 2.0 * o.z;
        let disc = b * b - 4.0 * a * cc;
        if disc < 0.0 {
            return [None, None];
        }
        let sign = if b >= 0.0 { 1.0 } else { -1.0 };
        let q = -0.5 * (b + sign * disc.sqrt());
        let finite = |t: f64| t.is_finite().then_some(t);
        let near = if q != 0.0 { finite(cc / q) } else { None };
        let far = if a != 0.0 { finite(q / a) } else { None };
        [near, far]
    }

    /// Newton's method on g(t) = z(t) − sag(s(t)), from the base conic's intersection `t0`,
    /// safeguarded: a step that leaves the sag's domain or the aperture (with a 10 % margin) is
    /// halved until it does not, and a stalled or non-converging iteration is a miss.
    fn newton(&self, o: DVec3, d: DVec3, t0: f64, r_max: f64) -> Option<f64> {
        let s_lim = (1.21 * r_max * r_max).min(self.s_max());
        let g = |t: f64| -> Option<(f64, f64)> {
            let p = o + t * d;
            let s = p.x * p.x + p.y * p.y;
            if s > s_lim {
                return None;
            }
            let z = self.sag(s)?;
            let dz = self.dsag_ds(s)?;
            Some((p.z - z, d.z - 2.0 * (p.x * d.x + p.y * d.y) * dz))
        };
        let mut t = t0;
        let (mut gv, mut dg) = g(t)?;
        let tol = 1e-15 * (1.0 + o.length() + r_max);
        for _ in 0..NEWTON_STEPS {
            if dg == 0.0 || !dg.is_finite() {
                return None;
            }
            let mut step = gv / dg;
            let mut next = None;
            for _ in 0..40 {
                if let Some(v) = g(t - step) {
                    next = Some(v);
                    break;
                }
                step *= 0.5;
            }
            let (ng, ndg) = next?;
            t -= step;
            (gv, dg) = (ng, ndg);
            if step.abs() <= tol || gv == 0.0 {
                return Some(t);
            }
        }
        None
    }
}

/// Refraction of the unit direction `d` at a surface of unit normal `n` from index `n1` into
/// `n2` (Snell's law in vector form); `None` on total internal reflection.
pub fn refract(d: DVec3, n: DVec3, n1: f64, n2: f64) -> Option<DVec3> {
    // Orient the normal against the ray.
    let (n, cos_i) = {
        let c = -d.dot(n);
        if c < 0.0 { (-n, -c) } else { (n, c) }
    };
    let mu = n1 / n2;
    let k = 1.0 - mu * mu * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return None;
    }
    Some((mu * d + (mu * cos_i - k.sqrt()) * n).normalize())
}
