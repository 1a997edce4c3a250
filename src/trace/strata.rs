//! How a batch's rays draw their random numbers: the Latin hypercube of the emission and the
//! wavelength, and, with [`Sampling::Stratified`], Latin-hypercube prefixes of every ray's
//! interaction streams.
//!
//! A ray's interactions draw from three streams (path.rs, `RayKey`): before the pattern area,
//! then one per mirror-state branch. Most rays meet the same surfaces in the same order (the
//! collimator's faces, the filters, the chart, the imaging lens, the DMD window; after the split
//! the window again and the arm lens), so the k-th draw of a stream is, for most rays of a batch,
//! the Fresnel choice of the same interface. Independent draws make the number of rays of a batch
//! that reflect there binomial, and that count is most of the noise of the detected currents:
//! a reflection after the DMD (window, arm lens: 1–5 % each) removes a ray from g± but not from
//! x. [`Sampling::Stratified`] takes the first draws of each stream from a Latin hypercube over
//! the batch instead (McKay, Beckman & Conover 1979, as the emission already does), so a batch
//! has within one ray the expected number of reflections at each of those interfaces.
//!
//! Unbiased for any bench: in a Latin hypercube each point, taken alone, is uniform on the unit
//! cube, so every ray's draws are independent uniforms exactly as before, whatever surfaces they
//! end up deciding; only the rays of one batch are made to cover each dimension evenly. Batches
//! are independent (each has its own permutations), so batch means still give honest standard
//! errors. The strata of a ray depend on (seed, batch, ray), never on the bench, so two benches
//! traced with the same seed still share their random numbers ray by ray (common random
//! numbers), and on any number of threads.

use crate::rng::{StreamRng, uniform};

/// How the rays of a batch draw their random numbers, and how a path crosses an interface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sampling {
    /// The emission and wavelength from the batch's Latin hypercube, every interaction from the
    /// ray's independent streams, and the analogue choice at every interface: reflect with
    /// probability R, refract otherwise (the tracer before issue 26's splitting).
    Independent,
    /// As `Independent`, and the first [`PREFIX`] draws of each of the ray's three streams from
    /// a Latin hypercube over the batch as well.
    Stratified,
    /// The default. At dielectric interfaces the path refracts with weight w·(1 − R) and the
    /// reflected part is followed with probability R at weight w (see `path::cross_interface`),
    /// and the emission and wavelength come from a scrambled Sobol' sequence over the batch
    /// ([`EmissionPoints`]) instead of the Latin hypercube; the first [`PREFIX`] draws of each
    /// interaction stream come from the batch's Latin hypercube, as with `Stratified`. The
    /// crossings halve the rays needed for a given error on k±, the Sobol' points take 1.4
    /// times less variance again (docs/tracer_sampling.md; `benches/trace.rs` compares the
    /// three samplings). The stratified prefixes change nothing measurable on the paper bench
    /// and cost 4 % of its time, but they make the reflected light of the validation's
    /// ghost_plate case twelve times more precise (docs/tracer_sampling.md, "The default
    /// tracer's profile"), so they stay.
    #[default]
    Split,
}

/// Stratified draws at the head of each interaction stream (before the DMD, + branch,
/// − branch). The paper bench's paths draw about ten times before the pattern area and four
/// after it; draws beyond the prefix come from the stream itself.
pub const PREFIX: usize = 12;

/// Interaction streams per ray (see path.rs, `STREAM_COMMON`, `STREAM_PLUS`, `STREAM_MINUS`).
pub const STREAMS: usize = 3;

/// The stratified prefixes of one batch: for ray i, `STREAMS × PREFIX` uniforms, ray-major
/// (empty with [`Sampling::Independent`]; both `Stratified` and `Split` use them).
#[derive(Debug, Clone, Default)]
pub struct BatchStrata {
    values: Vec<f64>,
}

impl BatchStrata {
    /// The prefixes of `n` rays of batch `batch`, from a stream of the batch of their own (the
    /// emission's hypercube draws from `rng::stream(seed, batch)` and is unchanged by them).
    pub fn new(sampling: Sampling, seed: u64, batch: u64, n: usize) -> BatchStrata {
        if sampling == Sampling::Independent || n == 0 {
            return BatchStrata::default();
        }
        let dims = STREAMS * PREFIX;
        let mut rng = crate::rng::stream(crate::rng::mix64(seed ^ 0x5354_5241_5441_0000), batch);
        let mut values = vec![0.0; n * dims];
        let inv_n = 1.0 / n as f64;
        let mut perm = Vec::with_capacity(n);
        for d in 0..dims {
            permutation_into(n, &mut rng, &mut perm);
            // Index loops here and below, not iterator adapters: see `permutation_into`.
            let mut i = 0;
            while i < n {
                values[i * dims + d] = (perm[i] as f64 + uniform(&mut rng)) * inv_n;
                i += 1;
            }
        }
        BatchStrata { values }
    }

    /// Ray i's prefix of stream `part` (empty when not stratified).
    #[inline]
    pub fn prefix(&self, i: usize, part: usize) -> &[f64] {
        if self.values.is_empty() {
            return &[];
        }
        let start = (i * STREAMS + part) * PREFIX;
        &self.values[start..start + PREFIX]
    }
}

/// Emission coordinates per ray: filament point (2), strategy (1), direction (2), wavelength
/// bin and offset (2).
pub const EMISSION_DIMS: usize = 7;

/// The emission and wavelength coordinates of a batch's rays: a Latin hypercube for the
/// analogue samplings (as before `Split`), a scrambled Sobol' sequence for [`Sampling::Split`].
#[derive(Debug, Clone)]
pub enum EmissionPoints {
    /// One random permutation of the n strata per dimension (McKay, Beckman & Conover 1979).
    LatinHypercube { perms: Vec<Vec<u32>>, inv_n: f64 },
    /// Per dimension the scramble seed and the digital shift of the batch (see [`Self::point`]).
    Sobol {
        scramble: [(u32, u32); EMISSION_DIMS],
    },
}

/// Which emission coordinate each Sobol' dimension drives: the first two (a (0, 2)-sequence in
/// two dimensions) the direction, which decides where on the chart and the DMD a ray lands; then
/// the wavelength bin, the mixture strategy, the offset within the bin and the filament point.
/// Measured on the paper bench (10⁶ rays, four seeds): this order gave 1.42× less variance on
/// k± than the Latin hypercube, the wavelength first 1.27× (docs/tracer_sampling.md).
const SOBOL_ORDER: [usize; EMISSION_DIMS] = [3, 4, 5, 2, 6, 0, 1];

impl EmissionPoints {
    /// The points of a batch of `n` rays, drawing their randomisation from the batch's stream
    /// `rng` (the Latin hypercube draws its permutations here and one jitter per coordinate in
    /// [`Self::point`], exactly as the tracer did before `Split`).
    pub fn new(sampling: Sampling, n: usize, rng: &mut StreamRng) -> EmissionPoints {
        if sampling == Sampling::Split {
            let mut scramble = [(0, 0); EMISSION_DIMS];
            for s in &mut scramble {
                *s = (bits32(rng), bits32(rng));
            }
            EmissionPoints::Sobol { scramble }
        } else {
            EmissionPoints::LatinHypercube {
                perms: (0..EMISSION_DIMS).map(|_| permutation(n, rng)).collect(),
                inv_n: 1.0 / n as f64,
            }
        }
    }

    /// Ray i's coordinates, each uniform on [0, 1) taken alone, with the jitter drawn from `rng`.
    ///
    /// Sobol': point i of the sequence (Joe & Kuo's direction numbers), its bits reversed, put
    /// through the hash-based nested scramble of Laine & Karras (Burley, *J. Computer Graphics
    /// Techniques* 9(4), 2020), reversed back, XORed with the batch's random shift and jittered
    /// below 2⁻³². The scramble permutes each bit according to the bits above it, which keeps
    /// the sequence's stratification (every 1-D projection of 2ᵐ points stratified, the first
    /// two dimensions a (0, m, 2)-net; unit tests below); the random shift makes each coordinate
    /// exactly uniform whatever the hash does, so every tally stays unbiased, and batches,
    /// scrambled independently, keep honest batch-means errors (randomised quasi-Monte Carlo,
    /// Owen 1997).
    #[inline]
    pub fn point(&self, i: usize, rng: &mut StreamRng) -> [f64; EMISSION_DIMS] {
        let mut u = [0.0; EMISSION_DIMS];
        match self {
            EmissionPoints::LatinHypercube { perms, inv_n } => {
                let mut d = 0;
                while d < perms.len() {
                    u[d] = (perms[d][i] as f64 + uniform(rng)) * inv_n;
                    d += 1;
                }
            }
            EmissionPoints::Sobol { scramble } => {
                let mut k = 0;
                while k < EMISSION_DIMS {
                    let (seed, shift) = scramble[k];
                    let x = nested_scramble(sobol(i as u32, k), seed) ^ shift;
                    u[SOBOL_ORDER[k]] = (x as f64 + uniform(rng)) * (1.0 / 4_294_967_296.0);
                    k += 1;
                }
            }
        }
        u
    }
}

/// 32 random bits from the stream.
fn bits32(rng: &mut StreamRng) -> u32 {
    (uniform(rng) * 4_294_967_296.0) as u32
}

/// Primitive polynomials (degree s, coefficients a) and initial direction numbers m of Sobol'
/// dimensions 2–7, from Joe & Kuo's table new-joe-kuo-6.21201 (S. Joe and F. Y. Kuo,
/// *SIAM J. Sci. Comput.* 30, 2008); dimension 1 is van der Corput's.
const SOBOL_POLY: [(u32, &[u32]); EMISSION_DIMS - 1] = [
    (0, &[1]),
    (1, &[1, 3]),
    (1, &[1, 3, 1]),
    (2, &[1, 1, 1]),
    (1, &[1, 1, 3, 3]),
    (4, &[1, 3, 5, 13]),
];

/// The direction numbers v_k (as 32-bit fractions) of every dimension.
const SOBOL_V: [[u32; 32]; EMISSION_DIMS] = sobol_directions();

const fn sobol_directions() -> [[u32; 32]; EMISSION_DIMS] {
    let mut v = [[0u32; 32]; EMISSION_DIMS];
    let mut k = 0;
    while k < 32 {
        v[0][k] = 1 << (31 - k);
        k += 1;
    }
    let mut d = 1;
    while d < EMISSION_DIMS {
        let (a, m) = SOBOL_POLY[d - 1];
        let s = m.len();
        let mut k = 0;
        while k < 32 {
            v[d][k] = if k < s {
                m[k] << (31 - k)
            } else {
                // v_k = a₁v_{k−1} ⊕ … ⊕ a_{s−1}v_{k−s+1} ⊕ v_{k−s} ⊕ (v_{k−s} >> s)
                let mut x = v[d][k - s] ^ (v[d][k - s] >> s);
                let mut j = 1;
                while j < s {
                    if (a >> (s - 1 - j)) & 1 == 1 {
                        x ^= v[d][k - j];
                    }
                    j += 1;
                }
                x
            };
            k += 1;
        }
        d += 1;
    }
    v
}

/// Point `i` of Sobol' dimension `d`, as a 32-bit fraction.
#[inline]
fn sobol(mut i: u32, d: usize) -> u32 {
    let v = &SOBOL_V[d];
    let (mut x, mut k) = (0u32, 0);
    while i != 0 {
        if i & 1 == 1 {
            x ^= v[k];
        }
        i >>= 1;
        k += 1;
    }
    x
}

/// Burley's (2020) hash-based nested uniform scramble of a 32-bit fraction: the Laine–Karras
/// permutation on the reversed bits, so that each output bit depends only on the bits above it.
#[inline]
fn nested_scramble(x: u32, seed: u32) -> u32 {
    let mut y = x.reverse_bits().wrapping_add(seed);
    y ^= y.wrapping_mul(0x6c50_b47c);
    y ^= y.wrapping_mul(0xb82f_1e52);
    y ^= y.wrapping_mul(0xc7af_e638);
    y ^= y.wrapping_mul(0x8d22_f6e6);
    y.reverse_bits()
}

/// A uniformly random permutation of 0..n (Fisher–Yates).
pub fn permutation(n: usize, rng: &mut StreamRng) -> Vec<u32> {
    let mut p = Vec::with_capacity(n);
    permutation_into(n, rng, &mut p);
    p
}

/// [`permutation`] into `p` (cleared first), reusing its allocation.
///
/// Written with index loops and slice indexing, not a reversed range and `min`: the test
/// profile builds this crate at opt-level 1, which calls those small functions instead of
/// inlining them (a tenth of the Mitsuba comparison test's time went to such calls; with this
/// loop and the two in `BatchStrata::new` and `EmissionPoints::point` it takes 41 s instead of
/// 44.5 s). The release build makes the same code of either form; the draws and swaps are the
/// same.
fn permutation_into(n: usize, rng: &mut StreamRng, p: &mut Vec<u32>) {
    p.clear();
    p.resize(n, 0);
    let s = p.as_mut_slice();
    let mut k = 0;
    while k < n {
        s[k] = k as u32;
        k += 1;
    }
    // Fisher–Yates from the top: i = n − 1, …, 1, each swapped with j uniform on 0..=i.
    let mut i = n;
    while i > 1 {
        i -= 1;
        let j = (uniform(rng) * (i + 1) as f64) as usize;
        let j = if j < i { j } else { i };
        s.swap(i, j);
    }
}

/// The random numbers of one path: its stratified prefix, then its stream.
#[derive(Debug, Clone)]
pub struct PathRng {
    prefix: [f64; PREFIX],
    len: usize,
    next: usize,
    tail: StreamRng,
}

impl PathRng {
    /// Draws `prefix` (at most [`PREFIX`] values) first, then from `tail`.
    #[inline]
    pub fn new(prefix: &[f64], tail: StreamRng) -> PathRng {
        let mut p = [0.0; PREFIX];
        let len = prefix.len().min(PREFIX);
        p[..len].copy_from_slice(&prefix[..len]);
        PathRng {
            prefix: p,
            len,
            next: 0,
            tail,
        }
    }

    /// The next uniform in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        if self.next < self.len {
            let u = self.prefix[self.next];
            self.next += 1;
            u
        } else {
            uniform(&mut self.tail)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scrambled Sobol' points of a batch of 1024 rays: every coordinate holds exactly one
    /// ray in each of the 1024 strata of [0, 1), the direction's two coordinates are a
    /// (0, 10, 2)-net (every box of 2ᵃ × 2¹⁰⁻ᵃ strata holds exactly one ray), and the values stay
    /// in [0, 1). Wrong direction numbers or a scramble that mixed bits across levels would break
    /// the first or the second.
    #[test]
    fn sobol_points_are_stratified_and_a_net() {
        let n = 1024;
        for batch in 0..4 {
            let mut rng = crate::rng::stream(11, batch);
            let points = EmissionPoints::new(Sampling::Split, n, &mut rng);
            let u: Vec<[f64; EMISSION_DIMS]> = (0..n).map(|i| points.point(i, &mut rng)).collect();
            for d in 0..EMISSION_DIMS {
                let mut seen = vec![false; n];
                for p in &u {
                    assert!((0.0..1.0).contains(&p[d]));
                    let k = (p[d] * n as f64) as usize;
                    assert!(!seen[k], "dimension {d}: stratum {k} twice");
                    seen[k] = true;
                }
            }
            let (da, db) = (SOBOL_ORDER[0], SOBOL_ORDER[1]);
            for a in 0..=10 {
                let (na, nb) = (1usize << a, 1usize << (10 - a));
                let mut seen = vec![false; n];
                for p in &u {
                    let cell = (p[da] * na as f64) as usize * nb + (p[db] * nb as f64) as usize;
                    assert!(!seen[cell], "box {cell} of {na} × {nb} twice");
                    seen[cell] = true;
                }
            }
        }
    }

    /// The unscrambled sequence is Sobol's: the first points of dimensions 1–3 as tabulated in
    /// Gray-code order (Joe & Kuo: 0, 1/2, 3/4, 1/4, 3/8, 7/8, … in dimension 1); `sobol` takes
    /// the points in their natural order, point i of the table being natural point i ⊕ (i >> 1).
    #[test]
    fn sobol_sequence_starts_as_tabulated() {
        let f = |i: u32, d: usize| sobol(i ^ (i >> 1), d) as f64 / 4_294_967_296.0;
        let first: Vec<[f64; 3]> = (0..6).map(|i| [f(i, 0), f(i, 1), f(i, 2)]).collect();
        let expected = [
            [0.0, 0.0, 0.0],
            [0.5, 0.5, 0.5],
            [0.75, 0.25, 0.25],
            [0.25, 0.75, 0.75],
            [0.375, 0.375, 0.625],
            [0.875, 0.875, 0.125],
        ];
        assert_eq!(first, expected);
    }

    /// Each coordinate of a scrambled point is uniform taken alone (the random digital shift):
    /// over 20 000 batches, point 0's coordinates have mean 1/2 and variance 1/12 within five
    /// standard errors, and fall into each tenth of [0, 1) about equally (χ² with 9 degrees of
    /// freedom below 40, p ≈ 10⁻⁵).
    #[test]
    fn scrambled_points_are_uniform() {
        let batches = 20_000;
        for i in [0usize, 1, 777] {
            let mut sums = [[0.0f64; 2]; EMISSION_DIMS];
            let mut bins = [[0u32; 10]; EMISSION_DIMS];
            for b in 0..batches {
                let mut rng = crate::rng::stream(5, b);
                let points = EmissionPoints::new(Sampling::Split, 1024, &mut rng);
                let u = points.point(i, &mut rng);
                for d in 0..EMISSION_DIMS {
                    sums[d][0] += u[d];
                    sums[d][1] += u[d] * u[d];
                    bins[d][(u[d] * 10.0) as usize] += 1;
                }
            }
            let m = batches as f64;
            for d in 0..EMISSION_DIMS {
                let mean = sums[d][0] / m;
                let var = sums[d][1] / m - mean * mean;
                assert!(
                    (mean - 0.5).abs() < 5.0 * (1.0f64 / 12.0 / m).sqrt(),
                    "{i} {d}: {mean}"
                );
                assert!(
                    (var - 1.0 / 12.0).abs() < 5.0 * (1.0f64 / 180.0 / m).sqrt(),
                    "{var}"
                );
                let e = m / 10.0;
                let chi2: f64 = bins[d].iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
                assert!(chi2 < 40.0, "point {i}, dimension {d}: χ² {chi2}");
            }
        }
    }

    /// Every stratified dimension holds exactly one ray per stratum of the batch, and the
    /// values stay in [0, 1).
    #[test]
    fn each_dimension_is_a_latin_hypercube() {
        let n = 1000;
        let s = BatchStrata::new(Sampling::Stratified, 3, 7, n);
        for part in 0..STREAMS {
            for k in 0..PREFIX {
                let mut seen = vec![false; n];
                for i in 0..n {
                    let u = s.prefix(i, part)[k];
                    assert!((0.0..1.0).contains(&u));
                    let cell = (u * n as f64) as usize;
                    assert!(!seen[cell], "stratum {cell} twice (part {part}, draw {k})");
                    seen[cell] = true;
                }
            }
        }
        assert!(
            BatchStrata::new(Sampling::Independent, 3, 7, n)
                .prefix(0, 0)
                .is_empty()
        );
    }

    /// Each ray's draw k is uniform on its own (the property that keeps every tally unbiased):
    /// over many batches, the mean and variance of one ray's draw match U(0, 1), and two
    /// dimensions of one ray are uncorrelated.
    #[test]
    fn one_rays_draws_are_independent_uniforms() {
        let batches = 4000;
        let (mut s, mut s2, mut c) = (0.0, 0.0, 0.0);
        for b in 0..batches {
            let st = BatchStrata::new(Sampling::Stratified, 11, b, 64);
            let u = st.prefix(5, 1);
            s += u[0];
            s2 += u[0] * u[0];
            c += (u[0] - 0.5) * (st.prefix(5, 2)[3] - 0.5);
        }
        let n = batches as f64;
        let mean = s / n;
        let var = s2 / n - mean * mean;
        // SE of the mean: sqrt(1/12/n) = 0.0046; of the variance ≈ 0.0013; of the covariance
        // sqrt(1/144/n) = 0.0013.
        assert!((mean - 0.5).abs() < 5.0 * 0.0046, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 5.0 * 0.0013, "var {var}");
        assert!((c / n).abs() < 5.0 * 0.0013, "cov {}", c / n);
    }

    #[test]
    fn path_rng_draws_the_prefix_then_the_stream() {
        let tail = crate::rng::stream(1, 2);
        let mut r = PathRng::new(&[0.25, 0.75], tail.clone());
        assert_eq!(r.uniform(), 0.25);
        assert_eq!(r.uniform(), 0.75);
        let mut t = tail;
        assert_eq!(r.uniform(), uniform(&mut t));
        // An empty prefix is the stream itself.
        let mut r = PathRng::new(&[], crate::rng::stream(1, 2));
        let mut t = crate::rng::stream(1, 2);
        assert_eq!(r.uniform(), uniform(&mut t));
    }
}
