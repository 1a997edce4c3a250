//! Reflection and refraction at dielectric interfaces: Fresnel's equations for unpolarised light
//! (the average of s and p, appropriate for a thermal source) and a single thin-film layer
//! (quarter-wave AR coatings), plus the reflection and refraction of direction vectors.

use glam::DVec3;

/// Fresnel amplitude coefficients for s and p polarisation (Born & Wolf §1.5.2), from medium 1
/// (index n1, cosine of the angle of incidence `cos_i` ≥ 0) into medium 2. `None` means total
/// internal reflection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Amplitudes {
    pub rs: f64,
    pub rp: f64,
    pub ts: f64,
    pub tp: f64,
    /// Cosine of the refraction angle.
    pub cos_t: f64,
}

pub fn amplitudes(n1: f64, n2: f64, cos_i: f64) -> Option<Amplitudes> {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t2 = (n1 / n2).powi(2) * (1.0 - cos_i * cos_i);
    if sin_t2 >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin_t2).sqrt();
    let (a, b) = (n1 * cos_i, n2 * cos_t);
    let (c, d) = (n2 * cos_i, n1 * cos_t);
    Some(Amplitudes {
        rs: (a - b) / (a + b),
        rp: (c - d) / (c + d),
        ts: 2.0 * a / (a + b),
        tp: 2.0 * n1 * cos_i / (c + d),
        cos_t,
    })
}

/// Power reflectance for unpolarised light, ½(|rs|² + |rp|²); 1 under total internal reflection.
#[inline]
pub fn reflectance(n1: f64, n2: f64, cos_i: f64) -> f64 {
    match amplitudes(n1, n2, cos_i) {
        None => 1.0,
        Some(a) => 0.5 * (a.rs * a.rs + a.rp * a.rp),
    }
}

/// Power transmittance for unpolarised light computed from the transmitted amplitudes,
/// ½(|ts|² + |tp|²)·(n2 cos θt)/(n1 cos θi). Independent of [`reflectance`], so R + T = 1 is a
/// real check of the formulas.
pub fn transmittance(n1: f64, n2: f64, cos_i: f64) -> f64 {
    match amplitudes(n1, n2, cos_i) {
        None => 0.0,
        Some(a) => {
            0.5 * (a.ts * a.ts + a.tp * a.tp) * (n2 * a.cos_t) / (n1 * cos_i.clamp(1e-300, 1.0))
        }
    }
}

/// A minimal complex number for the thin-film formula (evanescent waves need complex cosines).
#[derive(Debug, Clone, Copy, PartialEq)]
struct C {
    re: f64,
    im: f64,
}

impl C {
    fn new(re: f64, im: f64) -> C {
        C { re, im }
    }
    fn real(re: f64) -> C {
        C { re, im: 0.0 }
    }
    fn add(self, o: C) -> C {
        C::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: C) -> C {
        C::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: C) -> C {
        C::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn div(self, o: C) -> C {
        let d = o.re * o.re + o.im * o.im;
        C::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
    fn scale(self, s: f64) -> C {
        C::new(self.re * s, self.im * s)
    }
    fn norm2(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    /// Principal square root (non-negative imaginary part for negative reals), which makes an
    /// evanescent wave decay into the layer.
    fn sqrt(self) -> C {
        let r = self.norm2().sqrt();
        let re = ((r + self.re) * 0.5).max(0.0).sqrt();
        let im = ((r - self.re) * 0.5).max(0.0).sqrt();
        C::new(re, if self.im < 0.0 { -im } else { im })
    }
    fn exp_i(phase: C) -> C {
        // e^{i z} = e^{-Im z} (cos Re z + i sin Re z)
        let m = (-phase.im).exp();
        C::new(m * phase.re.cos(), m * phase.re.sin())
    }
}

/// Unpolarised reflectance of a single homogeneous layer (index `n_layer`, thickness
/// `thickness_m`) between an incident medium `n0` and an exit medium `n2`, for light arriving at
/// `cos0` in medium 0 (Born & Wolf §1.6.4, Airy summation):
/// r = (r01 + r12 e^{2iβ}) / (1 + r01 r12 e^{2iβ}), β = 2π n1 d cos θ1 / λ.
/// Total reflection (n0 sin θ0 > n2) gives 1.
pub fn single_layer_reflectance(
    n0: f64,
    n_layer: f64,
    n2: f64,
    thickness_m: f64,
    wavelength_m: f64,
    cos0: f64,
) -> f64 {
    let cos0 = cos0.clamp(0.0, 1.0);
    let s0 = n0 * (1.0 - cos0 * cos0).sqrt(); // the invariant n sin θ
    if s0 >= n2 {
        return 1.0;
    }
    // The layer's phase thickness at normal incidence, 2π n1 d / λ: β = k cos θ1.
    let k = 2.0 * std::f64::consts::PI * n_layer * thickness_m / wavelength_m;
    let n = [n0, n_layer, n2];
    if s0 < n_layer {
        return single_layer_propagating(n, k, cos0, s0);
    }
    single_layer_evanescent(n, k, cos0, s0)
}

/// [`single_layer_reflectance`] when the wave propagates in the layer (n sin θ below the
/// layer's index, and below the exit medium's: checked by the caller). Every cosine and every
/// r_ij is then real, and |(r01 + r12 e^{iφ}) / (1 + r01 r12 e^{iφ})|² with φ = 2β reduces to
/// (r01² + r12² + 2 r01 r12 cos φ) / (1 + r01² r12² + 2 r01 r12 cos φ): one cosine, no complex
/// division. This is the tracer's case at every coated lens face, so it is most of the cost of
/// a coating (the complex form, [`single_layer_evanescent`], agrees with it to rounding: unit test
/// `propagating_layer_equals_the_complex_form`).
#[inline]
fn single_layer_propagating([n0, n1, n2]: [f64; 3], k: f64, cos0: f64, s0: f64) -> f64 {
    let cos_in = |n: f64| (1.0 - (s0 / n) * (s0 / n)).max(0.0).sqrt();
    let (c1, c2) = (cos_in(n1), cos_in(n2));
    let cos_phi = (2.0 * k * c1).cos();
    let airy = |r01: f64, r12: f64| {
        let cross = 2.0 * r01 * r12 * cos_phi;
        (r01 * r01 + r12 * r12 + cross) / (1.0 + r01 * r01 * r12 * r12 + cross)
    };
    let ratio = |a: f64, b: f64| (a - b) / (a + b);
    let r_s = airy(ratio(n0 * cos0, n1 * c1), ratio(n1 * c1, n2 * c2));
    let r_p = airy(ratio(n1 * cos0, n0 * c1), ratio(n2 * c1, n1 * c2));
    (0.5 * (r_s + r_p)).clamp(0.0, 1.0)
}

/// [`single_layer_reflectance`] in complex arithmetic, for any n sin θ below the exit medium's
/// index: above the layer's the wave is evanescent in the layer (complex cosine, decaying phase).
fn single_layer_evanescent([n0, n_layer, n2]: [f64; 3], k: f64, cos0: f64, s0: f64) -> f64 {
    let cos_in = |n: f64| C::real(1.0 - (s0 / n).powi(2)).sqrt();
    let c0 = C::real(cos0);
    let c1 = cos_in(n_layer);
    let c2 = cos_in(n2);
    let beta = c1.scale(k);
    let phase = C::exp_i(beta.scale(2.0));
    let airy = |r01: C, r12: C| {
        let num = r01.add(r12.mul(phase));
        let den = C::real(1.0).add(r01.mul(r12).mul(phase));
        num.div(den).norm2()
    };
    // s: r_ij = (n_i cos_i − n_j cos_j)/(n_i cos_i + n_j cos_j); p: (n_j cos_i − n_i cos_j)/(…).
    let rs = |na: f64, ca: C, nb: f64, cb: C| {
        let a = ca.scale(na);
        let b = cb.scale(nb);
        a.sub(b).div(a.add(b))
    };
    let rp = |na: f64, ca: C, nb: f64, cb: C| {
        let a = ca.scale(nb);
        let b = cb.scale(na);
        a.sub(b).div(a.add(b))
    };
    let r_s = airy(rs(n0, c0, n_layer, c1), rs(n_layer, c1, n2, c2));
    let r_p = airy(rp(n0, c0, n_layer, c1), rp(n_layer, c1, n2, c2));
    (0.5 * (r_s + r_p)).clamp(0.0, 1.0)
}

/// Mirror reflection of direction `d` about the unit normal `n` (either orientation).
#[inline]
pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// Snell refraction of the unit direction `d` through a surface with unit normal `n` (either
/// orientation) from index `n1` into `n2`; `None` under total internal reflection.
#[inline]
pub fn refract(d: DVec3, n: DVec3, n1: f64, n2: f64) -> Option<DVec3> {
    // Orient the normal against the incoming direction.
    let (n, cos_i) = {
        let c = -d.dot(n);
        if c >= 0.0 { (n, c) } else { (-n, -c) }
    };
    let eta = n1 / n2;
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return None;
    }
    Some((eta * d + (eta * cos_i - k.sqrt()) * n).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn energy_is_conserved_at_every_angle() {
        // R is computed from the reflected amplitudes, T from the transmitted ones with the
        // beam-area and index factor: they must add to 1 up to rounding.
        for &(n1, n2) in &[(1.0, 1.5168), (1.5168, 1.0), (1.0, 1.78), (1.33, 1.46)] {
            for k in 0..=89 {
                let cos_i = (k as f64).to_radians().cos();
                let r = reflectance(n1, n2, cos_i);
                let t = transmittance(n1, n2, cos_i);
                if amplitudes(n1, n2, cos_i).is_some() {
                    assert!((r + t - 1.0).abs() < 1e-12, "{n1}->{n2} at {k}°: {r}+{t}");
                } else {
                    assert_eq!(r, 1.0);
                }
            }
        }
    }

    #[test]
    fn brewster_angle_has_no_p_reflection() {
        for &(n1, n2) in &[(1.0f64, 1.5168f64), (1.5168, 1.0), (1.0, 1.78)] {
            let theta_b = (n2 / n1).atan();
            let a = amplitudes(n1, n2, theta_b.cos()).unwrap();
            assert!(a.rp.abs() < 1e-12, "rp = {}", a.rp);
            assert!(a.rs.abs() > 0.1);
        }
        // Normal incidence: ((n1 − n2)/(n1 + n2))², 4.21 % for n = 1.5168.
        let r0 = reflectance(1.0, 1.5168, 1.0);
        assert!((r0 - (0.5168f64 / 2.5168).powi(2)).abs() < 1e-15);
    }

    #[test]
    fn quarter_wave_layer_matches_closed_form() {
        // At the design wavelength and normal incidence a quarter-wave layer gives
        // R = ((n0 n2 − n1²)/(n0 n2 + n1²))² (Hecht §9.9); a zero-thickness layer gives the bare
        // interface, and a half-wave layer is "absent" (R of the bare interface again).
        let (n0, n1, n2, l) = (1.0, 1.38, 1.52, 550e-9);
        let q = l / (4.0 * n1);
        let r = single_layer_reflectance(n0, n1, n2, q, l, 1.0);
        let expect = ((n0 * n2 - n1 * n1) / (n0 * n2 + n1 * n1)).powi(2);
        assert!((r - expect).abs() < 1e-14, "{r} vs {expect}");
        let bare = reflectance(n0, n2, 1.0);
        assert!((single_layer_reflectance(n0, n1, n2, 0.0, l, 1.0) - bare).abs() < 1e-14);
        assert!((single_layer_reflectance(n0, n1, n2, 2.0 * q, l, 1.0) - bare).abs() < 1e-14);
        // Oblique bare-layer limit equals the plain Fresnel result at every angle.
        for k in 0..80 {
            let c = (k as f64).to_radians().cos();
            let a = single_layer_reflectance(n0, n1, n2, 0.0, l, c);
            assert!((a - reflectance(n0, n2, c)).abs() < 1e-12);
        }
        // Reciprocity: the same layer seen from the glass side at the matching angle.
        let c0: f64 = 30f64.to_radians().cos();
        let s = (1.0 - c0 * c0).sqrt() * n0 / n2;
        let c2 = (1.0 - s * s).sqrt();
        let from_air = single_layer_reflectance(n0, n1, n2, q, 700e-9, c0);
        let from_glass = single_layer_reflectance(n2, n1, n0, q, 700e-9, c2);
        assert!((from_air - from_glass).abs() < 1e-12);
        // Beyond the critical angle from the glass side: total reflection.
        assert_eq!(single_layer_reflectance(n2, n1, n0, q, l, 0.5), 1.0);
    }

    #[test]
    fn propagating_layer_equals_the_complex_form() {
        // The real-arithmetic path against the complex one over indices, thicknesses,
        // wavelengths and angles where the wave propagates in the layer (both sides of it).
        let mut worst = 0.0f64;
        for &(n0, n1, n2) in &[
            (1.0, 1.38, 1.52),
            (1.52, 1.38, 1.0),
            (1.0, 2.1, 1.7),
            (1.8, 1.38, 1.5),
        ] {
            for degrees in 0..=89 {
                let cos0 = (degrees as f64).to_radians().cos();
                let s0 = n0 * (1.0 - cos0 * cos0).sqrt();
                if s0 >= n1 || s0 >= n2 {
                    continue;
                }
                for &d in &[0.0, 37e-9, 99.6e-9, 250e-9, 1.3e-6] {
                    for &l in &[400e-9, 633e-9, 1064e-9] {
                        let k = 2.0 * std::f64::consts::PI * n1 * d / l;
                        let a = single_layer_propagating([n0, n1, n2], k, cos0, s0);
                        let b = single_layer_evanescent([n0, n1, n2], k, cos0, s0);
                        worst = worst.max((a - b).abs());
                    }
                }
            }
        }
        assert!(worst < 1e-14, "largest difference {worst:e}");
        // The evanescent case (from glass beyond the layer's critical angle, below the exit
        // medium's) still goes through the complex form: n0 = 1.8, MgF2 1.38, exit 1.5,
        // sin θ0 = 0.8, n sin θ = 1.44.
        let cos0 = 0.6;
        let r = single_layer_reflectance(1.8, 1.38, 1.5, 100e-9, 600e-9, cos0);
        let s0 = 1.8 * (1.0f64 - cos0 * cos0).sqrt();
        assert!(s0 > 1.38);
        let k = 2.0 * std::f64::consts::PI * 1.38 * 100e-9 / 600e-9;
        assert_eq!(r, single_layer_evanescent([1.8, 1.38, 1.5], k, cos0, s0));
        assert!(r > 0.0 && r < 1.0, "{r}");
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = DVec3::Z;
        let d = DVec3::new(30f64.to_radians().sin(), 0.0, -30f64.to_radians().cos());
        let t = refract(d, n, 1.0, 1.5).unwrap();
        let sin_t = (t.x * t.x + t.y * t.y).sqrt();
        assert!((sin_t - 0.5 / 1.5).abs() < 1e-14);
        assert!(t.z < 0.0);
        assert!(refract(-t, n, 1.5, 1.0).unwrap().abs_diff_eq(-d, 1e-14));
        let grazing = DVec3::new(0.9, 0.0, -(1.0f64 - 0.81).sqrt());
        assert!(refract(grazing, n, 1.5, 1.0).is_none());
    }
}
