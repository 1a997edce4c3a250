//! The paper's additive measurement noise (Gaussian, exponential, Poisson).
//!
//! # Semantics
//!
//! The paper adds noise "directly onto the measured values" and quotes the standard deviation σ
//! of the distribution (§3, Fig. 4). spibench draws **one independent value for every recorded
//! detector sample**: each MONITOR+ sample of traditional and single-arm acquisition, each of
//! the two monitor samples of a double-arm frame, each RF-output sample of secondary
//! complementary balancing. How a draw enters its sample is fixed in [`super::schemes`].
//!
//! The draws follow the named distribution with standard deviation σ and are **not centred**
//! unless [`AdditiveNoise::centred`] is set:
//! - Gaussian: N(0, σ²), mean 0;
//! - exponential: rate 1/σ, mean σ (an exponential's standard deviation equals its mean);
//! - Poisson: a count with λ = σ², so its standard deviation is σ and its mean σ².
//!
//! A non-zero mean acts like an extra constant offset on every sample, which a complementary
//! difference cancels in expectation; that is part of what the paper's Fig. 4 shows. With
//! `centred: true` the mean is subtracted from every draw.
//!
//! # Determinism
//!
//! Sample t takes its draw from stream `rng::stream(seed, t / NOISE_BATCH)`, drawn in sample
//! order within the batch. The values therefore depend only on the seed and the sample index,
//! never on the number of threads or on how many samples are requested in total.
//!
//! # Poisson sampling
//!
//! For λ < 30, inversion by sequential search of the cumulative distribution (exact up to
//! floating-point rounding of the cumulative sums). For λ ≥ 30, Hörmann's transformed rejection
//! with squeeze, PTRS (W. Hörmann, "The transformed rejection method for generating Poisson
//! random variables", Insurance: Mathematics and Economics 12:39–45, 1993), which is exact:
//! the rejection step compares against the true log-probability, λ^k e^−λ / k!, with ln k! from
//! a Stirling series accurate to better than 1e-15 relative for k ≥ 16 and an exact sum below.

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::checked::{NonNegative, via};
use crate::error::{Error, Result};
use crate::rng;

/// Samples per random stream: sample t uses stream `t / NOISE_BATCH`.
pub const NOISE_BATCH: usize = 4096;

/// The largest standard deviation allowed for Poisson noise (λ = σ² ≤ 2^52, where counts are
/// still exact integers in a double).
pub const MAX_POISSON_STD: f64 = (1u64 << 26) as f64;

/// The distribution of the additive noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
// Files spell variants as Rust does (`CakeCutting`), the RON convention, or in snake_case
// (`cake_cutting`), which is what JSON output and benches written by spibench use.
#[serde(rename_all(serialize = "snake_case"))]
pub enum NoiseDistribution {
    /// Normal with mean 0 and standard deviation σ.
    #[serde(alias = "gaussian")]
    Gaussian,
    /// Exponential with mean and standard deviation σ (non-negative draws).
    #[serde(alias = "exponential")]
    Exponential,
    /// Poisson with mean λ = σ² (σ at most 2²⁶, where counts stay exact).
    #[serde(alias = "poisson")]
    Poisson,
}

impl NoiseDistribution {
    pub fn all() -> [NoiseDistribution; 3] {
        [
            NoiseDistribution::Gaussian,
            NoiseDistribution::Exponential,
            NoiseDistribution::Poisson,
        ]
    }

    pub fn label(self) -> &'static str {
        match self {
            NoiseDistribution::Gaussian => "Gaussian",
            NoiseDistribution::Exponential => "exponential",
            NoiseDistribution::Poisson => "Poisson",
        }
    }
}

/// Additive noise on every recorded detector sample, in the units of the measured values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdditiveNoise {
    /// The distribution of one draw.
    pub distribution: NoiseDistribution,
    /// Standard deviation σ of one draw (σ ≥ 0).
    #[serde(deserialize_with = "via::<NonNegative, _, _>")]
    pub std: f64,
    /// Subtract the distribution's mean from every draw (default: no, as in the paper).
    #[serde(default)]
    pub centred: bool,
}

impl AdditiveNoise {
    /// Uncentred noise of the given distribution and standard deviation.
    pub fn new(distribution: NoiseDistribution, std: f64) -> Self {
        AdditiveNoise {
            distribution,
            std,
            centred: false,
        }
    }

    pub fn gaussian(std: f64) -> Self {
        Self::new(NoiseDistribution::Gaussian, std)
    }

    pub fn exponential(std: f64) -> Self {
        Self::new(NoiseDistribution::Exponential, std)
    }

    pub fn poisson(std: f64) -> Self {
        Self::new(NoiseDistribution::Poisson, std)
    }

    /// The same noise with its mean subtracted (or not).
    pub fn with_centring(mut self, centred: bool) -> Self {
        self.centred = centred;
        self
    }

    /// Checks σ; errors name the field `noise.std`.
    pub fn validate(&self) -> Result<()> {
        if !self.std.is_finite() || self.std < 0.0 {
            return Err(Error::field(
                "noise.std",
                format!(
                    "the noise standard deviation must be finite and ≥ 0, got {}",
                    self.std
                ),
            ));
        }
        if self.distribution == NoiseDistribution::Poisson && self.std > MAX_POISSON_STD {
            return Err(Error::field(
                "noise.std",
                format!(
                    "Poisson noise with std {} (λ = std²) is beyond exact integer counts; the \
                     largest allowed std is {MAX_POISSON_STD}",
                    self.std
                ),
            ));
        }
        Ok(())
    }

    /// The mean of the underlying (uncentred) distribution: 0, σ or σ².
    pub fn distribution_mean(&self) -> f64 {
        match self.distribution {
            NoiseDistribution::Gaussian => 0.0,
            NoiseDistribution::Exponential => self.std,
            NoiseDistribution::Poisson => self.std * self.std,
        }
    }

    /// The mean of one draw as added to a sample (0 when centred).
    pub fn mean(&self) -> f64 {
        if self.centred {
            0.0
        } else {
            self.distribution_mean()
        }
    }

    /// One draw.
    pub fn draw<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        let v = match self.distribution {
            NoiseDistribution::Gaussian => self.std * rng::normal(rng),
            NoiseDistribution::Exponential => -self.std * rng::uniform_open0(rng).ln(),
            NoiseDistribution::Poisson => poisson(self.std * self.std, rng),
        };
        if self.centred {
            v - self.distribution_mean()
        } else {
            v
        }
    }

    /// The draws for samples 0..count of a computation seeded with `seed` (see the module
    /// documentation for the stream layout). Call [`AdditiveNoise::validate`] first.
    pub fn samples(&self, seed: u64, count: usize) -> Vec<f64> {
        let mut out = vec![0.0; count];
        for (b, chunk) in out.chunks_mut(NOISE_BATCH).enumerate() {
            let mut r = rng::stream(seed, b as u64);
            for v in chunk {
                *v = self.draw(&mut r);
            }
        }
        out
    }
}

/// A Poisson count with mean `lambda` (≥ 0), as a double.
pub fn poisson<R: Rng + ?Sized>(lambda: f64, rng: &mut R) -> f64 {
    if lambda <= 0.0 {
        0.0
    } else if lambda < 30.0 {
        poisson_inversion(lambda, rng)
    } else {
        poisson_ptrs(lambda, rng)
    }
}

/// Inversion: the smallest k with F(k) ≥ u, searching upwards from 0.
fn poisson_inversion<R: Rng + ?Sized>(lambda: f64, rng: &mut R) -> f64 {
    let u = rng::uniform(rng);
    let mut k = 0u32;
    let mut p = (-lambda).exp();
    let mut cdf = p;
    // If rounding leaves the cumulative sum a hair below u near 1, the search stops once the
    // probabilities underflow; that tail is below 1e-300.
    while u >= cdf && p > 0.0 {
        k += 1;
        p *= lambda / k as f64;
        cdf += p;
    }
    k as f64
}

/// Hörmann's PTRS (1993), valid for λ ≥ 10; constants from the paper.
fn poisson_ptrs<R: Rng + ?Sized>(lambda: f64, rng: &mut R) -> f64 {
    let slam = lambda.sqrt();
    let loglam = lambda.ln();
    let b = 0.931 + 2.53 * slam;
    let a = -0.059 + 0.02483 * b;
    let inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
    let v_r = 0.9277 - 3.6224 / (b - 2.0);
    loop {
        let u = rng::uniform(rng) - 0.5;
        let v = rng::uniform(rng);
        let us = 0.5 - u.abs();
        let k = ((2.0 * a / us + b) * u + lambda + 0.43).floor();
        // Squeeze: inside this box the transformed hat lies under the density.
        if us >= 0.07 && v <= v_r {
            return k;
        }
        if k < 0.0 || (us < 0.013 && v > us) {
            continue;
        }
        let lhs = v.ln() + inv_alpha.ln() - (a / (us * us) + b).ln();
        let rhs = -lambda + k * loglam - ln_factorial(k);
        if lhs <= rhs {
            return k;
        }
    }
}

/// ln k! for a non-negative integer k given as a double: an exact sum below 16, otherwise the
/// Stirling series ln k! = k ln k − k + ½ ln(2πk) + 1/(12k) − 1/(360k³) + 1/(1260k⁵)
/// − 1/(1680k⁷), whose truncation error is below 1/(1188 k⁹) < 1e-13 absolute at k = 16.
pub fn ln_factorial(k: f64) -> f64 {
    if k < 16.0 {
        let mut s = 0.0;
        let mut i = 2.0;
        while i <= k {
            s += f64::ln(i);
            i += 1.0;
        }
        s
    } else {
        let r = 1.0 / k;
        let r2 = r * r;
        k * k.ln() - k
            + 0.5 * (std::f64::consts::TAU * k).ln()
            + r * (1.0 / 12.0 - r2 * (1.0 / 360.0 - r2 * (1.0 / 1260.0 - r2 / 1680.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sample mean and (population) variance.
    fn moments(v: &[f64]) -> (f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n;
        (mean, var)
    }

    #[test]
    fn ln_factorial_matches_direct_sums() {
        let mut exact = 0.0f64;
        for k in 0..400u32 {
            if k >= 2 {
                exact += (k as f64).ln();
            }
            let got = ln_factorial(k as f64);
            assert!(
                (got - exact).abs() <= 1e-12 * exact.max(1.0),
                "k = {k}: {got} vs {exact}"
            );
        }
    }

    #[test]
    fn moments_match_the_stated_distributions() {
        // n = 200 000 draws each. Standard errors: mean σ/√n; variance √((μ₄ − σ⁴)/n) with
        // μ₄ = 3σ⁴ (Gaussian), 9σ⁴ (exponential), λ(1 + 3λ) (Poisson). Tolerance 5 SE.
        let n = 200_000;
        let sigma = 2.5;
        for (noise, mu4) in [
            (AdditiveNoise::gaussian(sigma), 3.0 * sigma.powi(4)),
            (AdditiveNoise::exponential(sigma), 9.0 * sigma.powi(4)),
            (AdditiveNoise::poisson(sigma), {
                let l = sigma * sigma;
                l * (1.0 + 3.0 * l)
            }),
        ] {
            for centred in [false, true] {
                let noise = noise.with_centring(centred);
                let v = noise.samples(11, n);
                let (mean, var) = moments(&v);
                let se_mean = sigma / (n as f64).sqrt();
                let se_var = ((mu4 - sigma.powi(4)) / n as f64).sqrt();
                assert!(
                    (mean - noise.mean()).abs() < 5.0 * se_mean,
                    "{noise:?}: mean {mean}"
                );
                assert!(
                    (var - sigma * sigma).abs() < 5.0 * se_var,
                    "{noise:?}: var {var}"
                );
            }
        }
    }

    #[test]
    fn poisson_mean_and_variance_across_both_samplers() {
        // Mean SE √(λ/n); variance SE √((λ + 2λ²)/n) (μ₄ − σ⁴ for a Poisson); 5 SE.
        let n = 200_000;
        for (i, &lambda) in [0.3, 4.0, 29.5, 30.0, 57.0, 1.0e4, 1.0e9]
            .iter()
            .enumerate()
        {
            let mut r = rng::stream(5, i as u64);
            let v: Vec<f64> = (0..n).map(|_| poisson(lambda, &mut r)).collect();
            assert!(v.iter().all(|&k| k >= 0.0 && k.fract() == 0.0));
            let (mean, var) = moments(&v);
            let se_mean = (lambda / n as f64).sqrt();
            let se_var = ((lambda + 2.0 * lambda * lambda) / n as f64).sqrt();
            assert!(
                (mean - lambda).abs() < 5.0 * se_mean,
                "λ {lambda}: mean {mean}"
            );
            assert!((var - lambda).abs() < 5.0 * se_var, "λ {lambda}: var {var}");
        }
    }

    #[test]
    fn poisson_frequencies_match_the_pmf() {
        // Per-value check: the count of k in n draws is Binomial(n, p_k), SE √(n p (1 − p));
        // 5 SE for each k with n·p_k ≥ 50. One λ per sampler.
        let n = 400_000;
        for (i, &lambda) in [3.0f64, 45.0].iter().enumerate() {
            let mut r = rng::stream(6, i as u64);
            let mut counts = vec![0usize; 200];
            for _ in 0..n {
                let k = poisson(lambda, &mut r) as usize;
                if k < counts.len() {
                    counts[k] += 1;
                }
            }
            for (k, &c) in counts.iter().enumerate() {
                let p = (-lambda + k as f64 * lambda.ln() - ln_factorial(k as f64)).exp();
                let expected = n as f64 * p;
                if expected < 50.0 {
                    continue;
                }
                let se = (expected * (1.0 - p)).sqrt();
                assert!(
                    (c as f64 - expected).abs() < 5.0 * se,
                    "λ {lambda}, k {k}: {c} vs {expected:.1}"
                );
            }
        }
    }

    #[test]
    fn draws_depend_only_on_seed_and_index() {
        let noise = AdditiveNoise::poisson(7.0);
        let short = noise.samples(3, 100);
        let long = noise.samples(3, 3 * NOISE_BATCH + 17);
        assert_eq!(short[..], long[..100]);
        assert_eq!(long, noise.samples(3, 3 * NOISE_BATCH + 17));
        assert_ne!(short, noise.samples(4, 100));
        // Batches use different streams: batch 1 is not a copy of batch 0.
        assert_ne!(long[..16], long[NOISE_BATCH..NOISE_BATCH + 16]);
        assert!(
            AdditiveNoise::gaussian(0.0)
                .samples(1, 10)
                .iter()
                .all(|&v| v == 0.0)
        );
        assert!(
            AdditiveNoise::poisson(0.0)
                .samples(1, 10)
                .iter()
                .all(|&v| v == 0.0)
        );
    }

    #[test]
    fn invalid_std_names_the_field() {
        for s in [-1.0, f64::NAN, f64::INFINITY] {
            let e = AdditiveNoise::gaussian(s).validate().unwrap_err();
            assert!(
                e.is_user_error() && e.to_string().contains("field `noise.std`"),
                "{e}"
            );
        }
        assert!(AdditiveNoise::poisson(1e8).validate().is_err());
        assert!(AdditiveNoise::poisson(1e4).validate().is_ok());
    }

    #[test]
    fn experiment_files_spell_noise() {
        use crate::scene::parse_ron;
        use std::path::Path;
        let n: AdditiveNoise =
            parse_ron("(distribution: Poisson, std: 2.0)", Path::new("e.ron")).unwrap();
        assert_eq!(n, AdditiveNoise::poisson(2.0));
        let n: AdditiveNoise = parse_ron(
            "(distribution: Exponential, std: 1.5, centred: true)",
            Path::new("e.ron"),
        )
        .unwrap();
        assert!(n.centred && n.distribution == NoiseDistribution::Exponential);
        let e = parse_ron::<AdditiveNoise>("(distribution: Gaussian, sigma: 1.0)", Path::new("e"))
            .unwrap_err();
        assert!(e.to_string().contains("sigma"), "{e}");
    }
}
