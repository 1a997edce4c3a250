//! Deterministic random streams.
//!
//! Every random quantity in spibench comes from a stream keyed by (seed, stream index), never from
//! a thread-local generator, so that results are bit-identical on any number of threads: work is
//! cut into fixed-size batches, batch `b` draws from `stream(seed, b)`, and partial results are
//! merged in batch order.

use rand::Rng;
use rand_pcg::Pcg64Mcg;

/// The generator behind every stream (PCG-64 MCG: 16 bytes of state, period 2^126).
pub type StreamRng = Pcg64Mcg;

/// One SplitMix64 finalisation step (Steele, Lea and Flood 2014), used to hash seeds.
#[inline]
pub fn mix64(z: u64) -> u64 {
    let mut z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The independent stream for batch `index` of a computation seeded with `seed`.
/// The whole 128-bit state comes from the hash, so neighbouring indices are unrelated.
pub fn stream(seed: u64, index: u64) -> StreamRng {
    let hi = mix64(seed);
    let lo = mix64(index ^ mix64(seed ^ 0xD1B5_4A32_D192_ED03));
    Pcg64Mcg::new(((hi as u128) << 64) | lo as u128)
}

/// A uniform double in [0, 1) from the top 53 bits of one 64-bit draw. Written here rather than
/// taken from `rand` so that golden values do not change with the `rand` version.
#[inline]
pub fn uniform<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A uniform double in (0, 1], safe as the argument of a logarithm.
#[inline]
pub fn uniform_open0<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    ((rng.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A standard normal deviate by the ziggurat method of Marsaglia and Tsang (2000), exact: one
/// 64-bit draw and a table lookup for about 99 % of deviates, against a logarithm and a sine for
/// Box–Muller, which took a quarter of a dataset sample's time in the detector's noise. Written
/// here, as [`uniform`], so that golden values do not change with a crate's version. Bits 0–7 of
/// the draw pick the layer and bits 11–63 the position in it, so the two are independent.
#[inline]
pub fn normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    let z = ziggurat();
    loop {
        let bits = rng.next_u64();
        let i = (bits & 0xff) as usize;
        let u = 2.0 * ((bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)) - 1.0;
        let x = u * z.x[i];
        if x.abs() < z.x[i + 1] {
            return x;
        }
        if i == 0 {
            return normal_tail(rng, u);
        }
        // The wedge between the layer's rectangle and the curve: uniform height in the layer.
        if z.f[i] + (z.f[i + 1] - z.f[i]) * uniform(rng) < (-0.5 * x * x).exp() {
            return x;
        }
    }
}

/// A deviate beyond the ziggurat's base radius R, on the side of `u`'s sign (Marsaglia 1964:
/// x = −ln U₁ / R accepted when −2 ln U₂ > x²).
#[cold]
fn normal_tail<R: Rng + ?Sized>(rng: &mut R, u: f64) -> f64 {
    loop {
        let x = -uniform_open0(rng).ln() / ZIGGURAT_R;
        let y = -uniform_open0(rng).ln();
        if 2.0 * y > x * x {
            return if u < 0.0 {
                -(ZIGGURAT_R + x)
            } else {
                ZIGGURAT_R + x
            };
        }
    }
}

/// The ziggurat of 256 layers of equal area V under exp(−x²/2) (Marsaglia and Tsang 2000,
/// J. Stat. Softw. 5(8), table for n = 256): R is the base layer's right edge.
const ZIGGURAT_R: f64 = 3.654_152_885_361_009;
const ZIGGURAT_V: f64 = 4.928_673_233_99e-3;

/// Layer edges x[i] (x[0] = V/f(R), the base rectangle's width; x[1] = R; x[256] = 0) and the
/// curve's heights f[i] = exp(−x[i]²/2) there.
struct Ziggurat {
    x: [f64; 257],
    f: [f64; 257],
}

fn ziggurat() -> &'static Ziggurat {
    static TABLE: std::sync::LazyLock<Ziggurat> = std::sync::LazyLock::new(|| {
        let pdf = |x: f64| (-0.5 * x * x).exp();
        let mut x = [0.0; 257];
        x[0] = ZIGGURAT_V / pdf(ZIGGURAT_R);
        x[1] = ZIGGURAT_R;
        // Each layer's area x[i]·(f(x[i+1]) − f(x[i])) is V; the top one ends at 0.
        for i in 1..255 {
            x[i + 1] = (-2.0 * (ZIGGURAT_V / x[i] + pdf(x[i])).ln()).sqrt();
        }
        Ziggurat { x, f: x.map(pdf) }
    });
    &TABLE
}

/// The SplitMix64 sequence: output k is `mix64(seed + k·γ)` with γ = 0x9E3779B97F4A7C15.
/// It is random access, which lets pattern bits be generated in parallel, and it is the generator
/// of the TVAL3 reference problems (seed 0x5EED0001), so spibench reproduces their patterns.
#[derive(Debug, Clone)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The generator positioned so that its next output is output number `k`.
    pub fn at(seed: u64, k: u64) -> Self {
        SplitMix64 {
            state: seed.wrapping_add(k.wrapping_mul(0x9E37_79B9_7F4A_7C15)),
        }
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let out = mix64(self.state);
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_matches_published_first_output() {
        // The check value quoted with the TVAL3 reference problems.
        assert_eq!(SplitMix64::new(0).next_u64(), 0xE220_A839_7B1D_CDAF);
        let mut a = SplitMix64::new(42);
        a.next_u64();
        a.next_u64();
        assert_eq!(a.next_u64(), SplitMix64::at(42, 2).next_u64());
    }

    #[test]
    fn streams_differ_and_repeat() {
        let x: Vec<u64> = (0..4).map(|_| stream(7, 0).next_u64()).collect();
        assert!(x.iter().all(|&v| v == x[0]));
        assert_ne!(stream(7, 0).next_u64(), stream(7, 1).next_u64());
        assert_ne!(stream(7, 0).next_u64(), stream(8, 0).next_u64());
    }

    #[test]
    fn normal_has_unit_variance() {
        let mut r = stream(1, 0);
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let v = normal(&mut r);
            s += v;
            s2 += v * v;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        // Standard errors: 1/sqrt(n) = 0.0022 for the mean, sqrt(2/n) = 0.0032 for the variance.
        assert!(mean.abs() < 5.0 * 0.0023, "mean {mean}");
        assert!((var - 1.0).abs() < 5.0 * 0.0032, "var {var}");
    }

    #[test]
    fn ziggurat_layers_have_equal_areas_and_close_at_zero() {
        // R and V are published to 12 significant digits, which limits how exactly the
        // ziggurat closes: evaluated in mpmath with these two values, the base's area is V to
        // −3.1·10⁻¹², and the recurrence reaches the curve's peak to 2.3·10⁻¹¹. Each layer
        // below the top has area V by construction, to f64 rounding (≤ 4·10⁻¹⁴ measured; the
        // difference of two heights loses at most a factor 1/Δf ≈ 200 of ε); the top layer
        // inherits the closure's error times x[255]/V ≈ 44 (9.9·10⁻¹⁰).
        let z = ziggurat();
        for i in 1..255 {
            let area = z.x[i] * (z.f[i + 1] - z.f[i]);
            assert!((area / ZIGGURAT_V - 1.0).abs() < 1e-12, "layer {i}: {area}");
        }
        let top = ZIGGURAT_V / z.x[255] + z.f[255];
        assert!((top - 1.0).abs() < 1e-10, "top {top}");
        let area = z.x[255] * (1.0 - z.f[255]);
        let bound = 1e-10 * z.x[255] / ZIGGURAT_V;
        assert!((area / ZIGGURAT_V - 1.0).abs() < bound, "top layer: {area}");
        // The base: R·f(R) plus the tail ∫_R^∞ f = √(π/2)·erfc(R/√2), together V
        // (erfc(R/√2) = 2.580 324 876 539e-4 from mpmath).
        let tail = (std::f64::consts::PI / 2.0).sqrt() * 2.580_324_876_539e-4;
        let base = ZIGGURAT_R * z.f[1] + tail;
        assert!((base / ZIGGURAT_V - 1.0).abs() < 1e-10, "base {base}");
    }

    #[test]
    fn normal_matches_the_normal_distribution_in_bulk_and_tails() {
        // 2·10⁶ deviates binned at the normal's quantiles, the tails beyond R (the ziggurat's
        // base edge, reached only through its tail algorithm) and beyond 4.5 included. Each
        // bin's count is binomial: within 5 standard deviations of n·p.
        let mut r = stream(3, 0);
        let n = 2_000_000usize;
        // Edges and the normal's CDF there (Φ, from mpmath's ncdf).
        let edges = [
            -4.5,
            -3.654_152_885_361_009,
            -2.0,
            -1.0,
            0.0,
            0.5,
            1.5,
            3.0,
            4.5,
        ];
        let cdf = [
            3.397_673_124_730e-6,
            1.290_162_438_270e-4,
            0.022_750_131_948_179,
            0.158_655_253_931_457,
            0.5,
            0.691_462_461_274_013,
            0.933_192_798_731_142,
            0.998_650_101_968_370,
            0.999_996_602_326_875,
        ];
        let mut counts = [0usize; 10];
        let (mut s3, mut s4) = (0.0, 0.0);
        for _ in 0..n {
            let v = normal(&mut r);
            counts[edges.partition_point(|&e| e <= v)] += 1;
            s3 += v * v * v;
            s4 += v * v * v * v;
        }
        for (b, &c) in counts.iter().enumerate() {
            let lo = if b == 0 { 0.0 } else { cdf[b - 1] };
            let hi = if b == edges.len() { 1.0 } else { cdf[b] };
            let p = hi - lo;
            let sd = (n as f64 * p * (1.0 - p)).sqrt();
            let dev = (c as f64 - n as f64 * p).abs();
            assert!(
                dev < 5.0 * sd.max(1.0),
                "bin {b}: {c} against {}",
                n as f64 * p
            );
        }
        // Skewness 0 and kurtosis 3: standard errors √(6/n) = 0.0017, √(24/n) = 0.0035.
        let (skew, kurt) = (s3 / n as f64, s4 / n as f64);
        assert!(skew.abs() < 5.0 * 0.0018, "skewness {skew}");
        assert!((kurt - 3.0).abs() < 5.0 * 0.0035, "kurtosis {kurt}");
    }
}
