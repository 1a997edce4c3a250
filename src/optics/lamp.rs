//! The lamp: a Lambertian emitting filament, its spectrum, and the importance sampling of where
//! rays start, where they go and at which wavelength.
//!
//! Emission is one-sided Lambertian from a flat filament (rectangle or disk) facing the
//! collimator: radiance is uniform over the filament and over directions, so the power into solid
//! angle dω at angle θ from the filament normal is Φ·cos θ dω / π. A coiled filament is not flat,
//! but only the part of its emission that reaches the collimator matters and, seen from there, it
//! is a bright patch of about the coil's outline (confidence L; a measured radiance map would
//! replace the flat patch).
//!
//! Sampling (all exact, so every traced number is unbiased):
//! - position: uniform over the filament;
//! - direction: a mixture of (1 − α) cosine-weighted directions inside a cone of half-angle
//!   θmax around the filament normal and α directions toward a "field" target (the part of the
//!   collimator whose light reaches the imaged region of the chart), of which a share β may be
//!   aimed at the chart's clear glass (`optics::guide`), with weight (cos θ/π)/pdf_mixture(ω)
//!   (one-sample multiple importance sampling, balance heuristic); a direction drawn outside
//!   the cone carries nothing;
//! - power outside the cone, Φ·cos²θmax, is never traced: it goes straight into the ledger as
//!   absorbed by the lamp housing (the cone is chosen to contain the collimator's aperture, so
//!   none of that light could reach the bench);
//! - wavelength: from a tabulated density ∝ S(λ)·τ(λ)·(ℜ̄(λ) + f·max ℜ̄) over the traced band,
//!   where S is the lamp's spectral power, τ the bench's expected spectral throughput (the
//!   product of its absorbing filters' internal transmittances at normal incidence: an ND stack
//!   passes 100× more at 1000 nm than at 400 nm) and ℜ̄ the mean responsivity of the two
//!   photodiodes, with weight (S(λ)/∫S)/pdf(λ). The weight after the filters is then ∝
//!   1/(ℜ̄ + f·max ℜ̄): photocurrent tallies are nearly constant per ray, and the floor f keeps
//!   the power tallies (the object x_j) from blowing up where ℜ is small.

use std::f64::consts::PI;

use glam::DVec3;

use super::geometry::Frame;
use super::guide::ChartGuide;
use super::spectrum::{Spectrum, integrate, planck_radiance, tungsten_emissivity};

/// The outline of the emitting filament in the lamp frame's (u, v) plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EmitterShape {
    Rect { half_u: f64, half_v: f64 },
    Disk { radius: f64 },
}

impl EmitterShape {
    pub fn area(&self) -> f64 {
        match *self {
            EmitterShape::Rect { half_u, half_v } => 4.0 * half_u * half_v,
            EmitterShape::Disk { radius } => PI * radius * radius,
        }
    }

    /// Distance from the centre to the farthest point of the outline.
    pub fn reach(&self) -> f64 {
        match *self {
            EmitterShape::Rect { half_u, half_v } => half_u.hypot(half_v),
            EmitterShape::Disk { radius } => radius,
        }
    }
}

/// The relative spectral shape of the emitted power (arbitrary units; only the shape matters).
#[derive(Debug, Clone, PartialEq)]
pub enum LampSpectrum {
    /// Planck × tungsten emissivity (Larrabee fit, docs/bench-facts.md §3.2).
    Tungsten { temperature_k: f64 },
    /// Planck × a constant emissivity.
    Graybody { temperature_k: f64, emissivity: f64 },
    /// A measured relative spectrum.
    Table(Spectrum),
}

impl LampSpectrum {
    /// Relative spectral power at λ. For the thermal forms this is the spectral radiant
    /// exitance ε(λ)·π·B_λ(T) in W/(m² m), so that it also gives absolute power per filament area.
    #[inline]
    pub fn at(&self, wavelength_m: f64) -> f64 {
        match self {
            LampSpectrum::Tungsten { temperature_k } => {
                PI * tungsten_emissivity(wavelength_m, *temperature_k)
                    * planck_radiance(wavelength_m, *temperature_k)
            }
            LampSpectrum::Graybody {
                temperature_k,
                emissivity,
            } => PI * emissivity * planck_radiance(wavelength_m, *temperature_k),
            LampSpectrum::Table(s) => s.at(wavelength_m),
        }
    }

    /// ∫ S dλ over the band.
    pub fn integral(&self, band: (f64, f64)) -> f64 {
        // 1 nm panels of Simpson's rule resolve Planck's curve to ~1e-12 and a tabulated
        // spectrum's kinks (1 nm grids are the finest vendor tables) to far better than the
        // Monte Carlo noise.
        let n = (((band.1 - band.0) / 0.25e-9).ceil() as usize).max(64);
        integrate(|l| self.at(l), band.0, band.1, n)
    }
}

/// Emission toward a field target: an outline (disk or rectangle in the lamp frame's u, v
/// axes) centred at `center` in a plane perpendicular to the lamp axis, chosen with
/// probability `probability`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldTarget {
    pub center: DVec3,
    pub outline: FieldOutline,
    pub probability: f64,
}

/// The outline of a field target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FieldOutline {
    Disk { radius: f64 },
    Rect { half_u: f64, half_v: f64 },
}

impl FieldOutline {
    fn area(&self) -> f64 {
        match *self {
            FieldOutline::Disk { radius } => PI * radius * radius,
            FieldOutline::Rect { half_u, half_v } => 4.0 * half_u * half_v,
        }
    }

    fn reach(&self) -> f64 {
        match *self {
            FieldOutline::Disk { radius } => radius,
            FieldOutline::Rect { half_u, half_v } => half_u.hypot(half_v),
        }
    }

    /// A uniform point from two uniforms, in (u, v) offsets.
    fn sample(&self, a: f64, b: f64) -> (f64, f64) {
        match *self {
            FieldOutline::Disk { radius } => {
                let r = radius * a.sqrt();
                let phi = 2.0 * PI * b;
                (r * phi.cos(), r * phi.sin())
            }
            FieldOutline::Rect { half_u, half_v } => {
                ((2.0 * a - 1.0) * half_u, (2.0 * b - 1.0) * half_v)
            }
        }
    }

    fn contains(&self, x: f64, y: f64) -> bool {
        match *self {
            FieldOutline::Disk { radius } => x * x + y * y <= radius * radius,
            FieldOutline::Rect { half_u, half_v } => x.abs() <= half_u && y.abs() <= half_v,
        }
    }
}

#[derive(Debug, Clone)]
pub struct Lamp {
    /// Origin at the filament centre, w = the filament normal (emission axis).
    pub frame: Frame,
    pub shape: EmitterShape,
    pub spectrum: LampSpectrum,
    /// Radiant power emitted in the traced band (W), one-sided Lambertian.
    pub band_power_w: f64,
    /// sin² of the emission cone's half-angle.
    pub sin2_max: f64,
    pub field: Option<FieldTarget>,
    /// Of the rays aimed at the field target, a share aimed at a chart's clear areas instead of
    /// uniformly over the target (fitted to the assembled bench, see `optics::guide`).
    pub guide: Option<ChartGuide>,
}

/// A sampled emission: start point, unit direction, and the ray's share of the band power as a
/// fraction of `band_power_w` (to be multiplied by the spectral factor and divided by the number
/// of rays).
#[derive(Debug, Clone, Copy)]
pub struct Emission {
    pub origin: DVec3,
    pub direction: DVec3,
    pub factor: f64,
}

impl Lamp {
    /// Power that leaves the filament outside the traced cone (W), analytically:
    /// Φ·(1 − sin²θmax) for a Lambertian emitter.
    pub fn power_outside_cone(&self) -> f64 {
        self.band_power_w * (1.0 - self.sin2_max)
    }

    /// Checks that the field disk lies inside the emission cone as seen from every filament
    /// point and in front of the filament (so the mixture density covers only the cone and the
    /// analytic outside-cone power stays exact). Returns a message on failure.
    pub fn check_field(&self) -> Result<(), String> {
        let Some(f) = self.field else { return Ok(()) };
        let dist = (f.center - self.frame.origin).dot(self.frame.w);
        if dist <= 0.0 {
            return Err("the field disk must lie in front of the filament".into());
        }
        let lateral = (f.center - self.frame.origin - dist * self.frame.w).length();
        let worst = (lateral + f.outline.reach() + self.shape.reach()) / dist;
        let tan_max = (self.sin2_max / (1.0 - self.sin2_max).max(1e-300)).sqrt();
        if self.sin2_max < 1.0 && worst > tan_max {
            return Err(format!(
                "the field disk reaches {:.2}° from the lamp axis, outside the emission cone \
                 ({:.2}°)",
                worst.atan().to_degrees(),
                tan_max.atan().to_degrees()
            ));
        }
        if !(f.probability >= 0.0 && f.probability < 1.0) {
            return Err("the field sampling probability must be in [0, 1)".into());
        }
        Ok(())
    }

    /// Samples an emission at `wavelength_m` from five uniform numbers in [0, 1): two for the
    /// point on the filament, one for the choice of strategy, two for the direction. (The
    /// wavelength matters only to the chart-guided strategy, whose aim follows the dispersion.)
    #[inline]
    pub fn sample(&self, u: [f64; 5], wavelength_m: f64) -> Emission {
        let fr = &self.frame;
        let (x, y) = match self.shape {
            EmitterShape::Rect { half_u, half_v } => {
                ((2.0 * u[0] - 1.0) * half_u, (2.0 * u[1] - 1.0) * half_v)
            }
            EmitterShape::Disk { radius } => {
                let r = radius * u[0].sqrt();
                let a = 2.0 * PI * u[1];
                (r * a.cos(), r * a.sin())
            }
        };
        let p = fr.origin + x * fr.u + y * fr.v;
        let (alpha, beta) = self.shares();
        let (a, b) = (u[3], u[4]);
        let dir = match (self.field, &self.guide) {
            (Some(f), Some(g)) if u[2] < alpha * beta => {
                let (qx, qy) = g.sample(a, b, (x, y), wavelength_m);
                (f.center + qx * fr.u + qy * fr.v - p).normalize()
            }
            (Some(f), _) if u[2] < alpha => {
                let (x, y) = f.outline.sample(a, b);
                let q = f.center + x * fr.u + y * fr.v;
                (q - p).normalize()
            }
            _ => {
                let s2 = a * self.sin2_max;
                let c = (1.0 - s2).max(0.0).sqrt();
                let s = s2.sqrt();
                let phi = 2.0 * PI * b;
                s * phi.cos() * fr.u + s * phi.sin() * fr.v + c * fr.w
            }
        };
        let cos_t = dir.dot(fr.w);
        // Only the cone is traced (the power outside it is booked analytically), so a guided
        // direction outside it carries nothing; its density still counts in the mixture.
        let in_cone = self.pdf_cone(cos_t) > 0.0;
        let pdf = self.pdf(p, (x, y), dir, wavelength_m);
        let factor = if in_cone && pdf > 0.0 {
            cos_t / PI / pdf
        } else {
            0.0
        };
        Emission {
            origin: p,
            direction: dir,
            factor,
        }
    }

    /// (α, β): the probability of aiming at the field target and, of those, the share aimed by
    /// the chart guide.
    #[inline]
    pub(crate) fn shares(&self) -> (f64, f64) {
        let alpha = self.field.map_or(0.0, |f| f.probability);
        let beta = self.guide.as_ref().map_or(0.0, |g| g.share);
        (alpha, beta)
    }

    /// The mixture's solid-angle density of `dir` from filament point p (offset d in the lamp
    /// frame): (1 − α)·cone + α·(1 − β)·uniform target + α·β·chart-guided target.
    #[inline]
    fn pdf(&self, p: DVec3, d: (f64, f64), dir: DVec3, wavelength_m: f64) -> f64 {
        let (alpha, beta) = self.shares();
        let cos_t = dir.dot(self.frame.w);
        let mut pdf = (1.0 - alpha) * self.pdf_cone(cos_t);
        if let Some(f) = self.field
            && alpha > 0.0
            && let Some((q, jacobian)) = self.field_point(p, dir)
        {
            if beta < 1.0 && f.outline.contains(q.0, q.1) {
                pdf += alpha * (1.0 - beta) * jacobian / f.outline.area();
            }
            if let Some(g) = &self.guide
                && beta > 0.0
            {
                pdf += alpha * beta * jacobian * g.pdf(q, d, wavelength_m);
            }
        }
        pdf
    }

    /// Solid-angle density of the cosine-weighted cone.
    #[inline]
    fn pdf_cone(&self, cos_t: f64) -> f64 {
        if cos_t <= 0.0 || 1.0 - cos_t * cos_t > self.sin2_max * (1.0 + 1e-12) {
            0.0
        } else {
            cos_t / (PI * self.sin2_max)
        }
    }

    /// Where the ray from `p` along `dir` crosses the field plane, as (u, v) offsets from the
    /// target's centre, and the Jacobian t²/cos θ from area on that plane to solid angle at p.
    #[inline]
    fn field_point(&self, p: DVec3, dir: DVec3) -> Option<((f64, f64), f64)> {
        let f = self.field?;
        let w = self.frame.w;
        let cos_t = dir.dot(w);
        if cos_t <= 0.0 {
            return None;
        }
        let t = (f.center - p).dot(w) / cos_t;
        if t <= 0.0 {
            return None;
        }
        let q = p + t * dir - f.center;
        Some(((q.dot(self.frame.u), q.dot(self.frame.v)), t * t / cos_t))
    }
}

/// The floor f of the wavelength density S·τ·(ℜ̄ + f·max ℜ̄), as a fraction of the peak mean
/// responsivity. Measured on the paper bench, the error of k± hardly depends on it between 0.25
/// and 3 (the spectral part of that error comes from ℜ varying across the band, which no
/// choice of density removes for one wavelength per ray); f = 1 keeps every power weight within
/// a factor of 2 of the others, which keeps the rare heavy stray-light paths light.
pub const SPECTRAL_FLOOR: f64 = 1.0;

/// Tabulated wavelength sampling over the traced band (see the module notes).
#[derive(Debug, Clone)]
pub struct SpectralSampler {
    pub band: (f64, f64),
    bin: f64,
    cdf: Vec<f64>,
    cdf_index: CdfIndex,
    density: Vec<f64>,
    spectrum: LampSpectrum,
    spectrum_integral: f64,
}

impl SpectralSampler {
    /// `responsivity(λ)` is the mean responsivity of the detectors (A/W) and `throughput(λ)`
    /// the bench's expected spectral transmittance (1 if unknown); neither changes the mean of
    /// any tally, only its noise.
    pub fn new(
        spectrum: &LampSpectrum,
        band: (f64, f64),
        responsivity: impl Fn(f64) -> f64,
        throughput: impl Fn(f64) -> f64,
    ) -> SpectralSampler {
        let n = (((band.1 - band.0) / 1e-9).ceil() as usize).max(1);
        let bin = (band.1 - band.0) / n as f64;
        let mids: Vec<f64> = (0..n).map(|i| band.0 + (i as f64 + 0.5) * bin).collect();
        let r_max = mids
            .iter()
            .map(|&l| responsivity(l))
            .fold(0.0f64, f64::max)
            .max(1e-300);
        let f: Vec<f64> = mids
            .iter()
            .map(|&l| {
                spectrum.at(l).max(0.0)
                    * throughput(l).max(1e-300)
                    * (responsivity(l).max(0.0) + SPECTRAL_FLOOR * r_max)
            })
            .collect();
        let total: f64 = f.iter().sum();
        let mut cdf = Vec::with_capacity(n + 1);
        let mut acc = 0.0;
        cdf.push(0.0);
        for v in &f {
            acc += v;
            cdf.push(acc / total);
        }
        let density = f.iter().map(|v| v / (total * bin)).collect();
        SpectralSampler {
            band,
            bin,
            cdf_index: CdfIndex::new(&cdf),
            cdf,
            density,
            spectrum: spectrum.clone(),
            spectrum_integral: spectrum.integral(band),
        }
    }

    /// A wavelength from two uniforms and its weight (S(λ)/∫S)/pdf(λ) (mean 1 over the band).
    #[inline]
    pub fn sample(&self, u_bin: f64, u_in: f64) -> (f64, f64) {
        let (i, _) = self.cdf_index.pick(&self.cdf, u_bin);
        let l = self.band.0 + (i as f64 + u_in) * self.bin;
        let w = self.spectrum.at(l) / self.spectrum_integral / self.density[i];
        (l, w)
    }
}

/// The interval of a CDF (c[0] = 0 ≤ … ≤ c[last] ≈ 1) that holds u, and u's position within
/// it in [0, 1) (a second uniform for a piecewise-constant draw, made of u's remaining bits).
/// The plain binary search, the reference that [`CdfIndex::pick`] must equal.
#[cfg(test)]
pub(crate) fn pick(cdf: &[f64], u: f64) -> (usize, f64) {
    let i = cdf.partition_point(|&c| c <= u);
    within(cdf, i, u)
}

/// The interval and position of [`pick`] from the count i of CDF entries ≤ u.
#[inline]
fn within(cdf: &[f64], i: usize, u: f64) -> (usize, f64) {
    let n = cdf.len() - 1;
    let i = (i.max(1) - 1).min(n - 1);
    let width = cdf[i + 1] - cdf[i];
    let f = if width > 0.0 {
        ((u - cdf[i]) / width).clamp(0.0, 1.0 - f64::EPSILON)
    } else {
        0.5
    };
    (i, f)
}

/// A guide table for [`pick`] over one CDF (the "indexed search" of Chen & Asau 1974): for u in
/// the k-th of n equal buckets of [0, 1), the entries ≤ u start at or after `first[k]` and
/// those > u at or before `first[k + 3]`, so a pick searches a few entries instead of the whole
/// table (the chart guide's 256 × 257 CDF is larger than a core's L2 cache, and its binary
/// searches were 7 % of the paper bench's trace). The answer is exactly [`pick`]'s.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CdfIndex {
    /// first[j]: the number of CDF entries ≤ (j − 1)/n, for j = 0 ..= n + 3.
    first: Vec<u32>,
}

impl CdfIndex {
    pub(crate) fn new(cdf: &[f64]) -> CdfIndex {
        let n = cdf.len() - 1;
        let first = (0..n + 4)
            .map(|j| cdf.partition_point(|&c| c <= (j as f64 - 1.0) / n as f64) as u32)
            .collect();
        CdfIndex { first }
    }

    /// [`pick`] over `cdf` (the CDF this index was made from).
    #[inline]
    pub(crate) fn pick(&self, cdf: &[f64], u: f64) -> (usize, f64) {
        let n = cdf.len() - 1;
        // u·n may round up to the next integer, or u be ≥ 1: the three buckets around k
        // (thresholds (k − 1)/n and (k + 2)/n) hold u with margins of a whole bucket.
        let k = ((u * n as f64).max(0.0) as usize).min(n);
        let (lo, hi) = (self.first[k] as usize, self.first[k + 3] as usize);
        let i = lo + cdf[lo..hi].partition_point(|&c| c <= u);
        within(cdf, i, u)
    }
}

/// Mean and standard error of the emission factor over `n` draws of `lamp`, over all rays and
/// over the rays that `inside` accepts: the unbiasedness tests of the direction mixture.
#[cfg(test)]
pub(crate) fn factor_stats(
    lamp: &Lamp,
    n: usize,
    mut draw: impl FnMut() -> ([f64; 5], f64),
    inside: impl Fn(&Emission) -> bool,
) -> ((f64, f64), (f64, f64)) {
    let (mut s, mut s2, mut d, mut d2) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..n {
        let (u, wl) = draw();
        let e = lamp.sample(u, wl);
        s += e.factor;
        s2 += e.factor * e.factor;
        let v = if inside(&e) { e.factor } else { 0.0 };
        d += v;
        d2 += v * v;
    }
    let nf = n as f64;
    let m = |s: f64, s2: f64| (s / nf, ((s2 / nf - (s / nf).powi(2)) / nf).sqrt());
    (m(s, s2), m(d, d2))
}

/// In-band radiant power of a flat one-sided Lambertian filament of `area` (m²) at its
/// temperature: area·∫ ε(λ)·π·B_λ(T) dλ over the band (W). Only for thermal spectra.
pub fn band_power_from_filament(area: f64, spectrum: &LampSpectrum, band: (f64, f64)) -> f64 {
    area * spectrum.integral(band)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng;

    fn lamp(field: Option<FieldTarget>, sin2: f64) -> Lamp {
        Lamp {
            frame: Frame::new(DVec3::ZERO, DVec3::Z, None),
            shape: EmitterShape::Rect {
                half_u: 1e-3,
                half_v: 0.5e-3,
            },
            spectrum: LampSpectrum::Tungsten {
                temperature_k: 2796.0,
            },
            band_power_w: 1.0,
            sin2_max: sin2,
            field,
            guide: None,
        }
    }

    #[test]
    fn cone_weights_are_constant_and_mixture_is_unbiased() {
        let sin2 = 0.2f64;
        let plain = lamp(None, sin2);
        let mut r = rng::stream(5, 0);
        let u = |r: &mut rng::StreamRng| {
            [
                rng::uniform(r),
                rng::uniform(r),
                rng::uniform(r),
                rng::uniform(r),
                rng::uniform(r),
            ]
        };
        for _ in 0..100 {
            let e = plain.sample(u(&mut r), 850e-9);
            assert!((e.factor - sin2).abs() < 1e-12);
        }
        // With a field disk, the mean weight of rays landing on a test disk (here: the whole
        // cone) must still be sin²θmax, and the mean weight landing inside a small disk must be
        // the same as without importance sampling. Estimate both with n rays; the standard errors
        // are computed from the samples and the tolerance is 4 of them.
        let field = FieldTarget {
            center: DVec3::new(0.002, 0.0, 0.05),
            outline: FieldOutline::Rect {
                half_u: 0.004,
                half_v: 0.003,
            },
            probability: 0.6,
        };
        let mixed = lamp(Some(field), sin2);
        assert!(mixed.check_field().is_ok());
        let n = 200_000;
        let in_small = |e: &Emission| {
            let t = 0.05 / e.direction.z;
            let q = e.origin + t * e.direction;
            (q.x - 0.003).hypot(q.y) < 0.002
        };
        let ((a, sa), (b, sb)) = factor_stats(&mixed, n, || (u(&mut r), 850e-9), in_small);
        let (_, (c, sc)) = factor_stats(&plain, n, || (u(&mut r), 850e-9), in_small);
        assert!((a - sin2).abs() < 4.0 * sa, "{a} ± {sa}");
        assert!(
            (b - c).abs() < 4.0 * (sb * sb + sc * sc).sqrt(),
            "{b}±{sb} vs {c}±{sc}"
        );
        // The mixture concentrates samples in the field: smaller error for the same n.
        assert!(sb < sc);
    }

    #[test]
    fn field_outside_cone_is_rejected() {
        let l = lamp(
            Some(FieldTarget {
                center: DVec3::new(0.05, 0.0, 0.05),
                outline: FieldOutline::Disk { radius: 0.01 },
                probability: 0.5,
            }),
            0.1,
        );
        assert!(l.check_field().is_err());
    }

    #[test]
    fn spectral_weights_integrate_to_one() {
        // E[w] = 1 and E[w·g(λ)] = ∫ S g / ∫ S for any g: check g = 1 and g = ℜ with 4 standard
        // errors from the sample variance.
        let spec = LampSpectrum::Tungsten {
            temperature_k: 2796.0,
        };
        let resp = Spectrum::from_static(&crate::optics::spectrum::SILICON_PIN_RESPONSIVITY);
        let band = (350e-9, 1150e-9);
        let s = SpectralSampler::new(&spec, band, |l| resp.at(l), |l| 1.0 / (1.0 + 1e6 * l));
        let mut r = rng::stream(9, 0);
        let n = 200_000;
        let (mut m1, mut q1, mut m2, mut q2) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let (l, w) = s.sample(rng::uniform(&mut r), rng::uniform(&mut r));
            assert!(l >= band.0 && l <= band.1);
            m1 += w;
            q1 += w * w;
            let v = w * resp.at(l);
            m2 += v;
            q2 += v * v;
        }
        let nf = n as f64;
        let se = |m: f64, q: f64| ((q / nf - (m / nf).powi(2)) / nf).sqrt();
        let exact_r =
            integrate(|l| spec.at(l) * resp.at(l), band.0, band.1, 32_000) / spec.integral(band);
        assert!((m1 / nf - 1.0).abs() < 4.0 * se(m1, q1));
        assert!((m2 / nf - exact_r).abs() < 4.0 * se(m2, q2));
        // docs/bench-facts.md §3.4: at 2796 K (pure Planck) 86 % of the photocurrent comes from > 700 nm.
        let planck = LampSpectrum::Graybody {
            temperature_k: 2796.0,
            emissivity: 1.0,
        };
        let num = integrate(|l| planck.at(l) * resp.at(l), 700e-9, 1150e-9, 20_000);
        let den = integrate(|l| planck.at(l) * resp.at(l), 350e-9, 1150e-9, 20_000);
        assert!((num / den - 0.86).abs() < 0.006, "{}", num / den);
    }

    /// The indexed pick returns exactly the binary search's interval and position, for CDFs
    /// with flat stretches (empty cells), a steep step, and u on and around every entry.
    #[test]
    fn indexed_pick_equals_binary_search() {
        let mut r = rng::stream(5, 0);
        let cdfs: Vec<Vec<f64>> = vec![
            vec![0.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0],
            vec![0.0, 1e-9, 0.999_999_999, 1.0],
            {
                let w: Vec<f64> = (0..300)
                    .map(|k| if k % 7 < 3 { 0.0 } else { rng::uniform(&mut r) })
                    .collect();
                let total: f64 = w.iter().sum();
                let mut c = vec![0.0];
                let mut acc = 0.0;
                for v in &w {
                    acc += v;
                    c.push(acc / total);
                }
                *c.last_mut().unwrap() = 1.0;
                c
            },
        ];
        for cdf in &cdfs {
            let index = CdfIndex::new(cdf);
            let mut us: Vec<f64> = (0..20_000).map(|_| rng::uniform(&mut r)).collect();
            for &c in cdf {
                us.extend([c, c.next_down(), c.next_up()]);
            }
            us.extend([0.0, 1.0 - f64::EPSILON / 2.0]);
            for u in us.into_iter().filter(|u| (0.0..1.0).contains(u)) {
                assert_eq!(index.pick(cdf, u), pick(cdf, u), "u = {u:e}");
            }
        }
    }
}
