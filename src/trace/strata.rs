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
    /// As `Independent`, except at dielectric interfaces: the path refracts with weight
    /// w·(1 − R) and the reflected part is followed with probability R at weight w (see
    /// `path::cross_interface`). The default: about half the rays of `Independent` for the same
    /// error on k±, at about 1.3 times the time per ray (docs/tracer_sampling.md;
    /// `benches/trace.rs` compares the three).
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
/// (empty with [`Sampling::Independent`]).
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
            for (i, &p) in perm.iter().enumerate() {
                values[i * dims + d] = (p as f64 + uniform(&mut rng)) * inv_n;
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

/// A uniformly random permutation of 0..n (Fisher–Yates).
pub fn permutation(n: usize, rng: &mut StreamRng) -> Vec<u32> {
    let mut p = Vec::with_capacity(n);
    permutation_into(n, rng, &mut p);
    p
}

/// [`permutation`] into `p` (cleared first), reusing its allocation.
fn permutation_into(n: usize, rng: &mut StreamRng, p: &mut Vec<u32>) {
    p.clear();
    p.extend(0..n as u32);
    for i in (1..n).rev() {
        let j = ((uniform(rng) * (i + 1) as f64) as usize).min(i);
        p.swap(i, j);
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
