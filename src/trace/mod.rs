//! The Monte Carlo engine: forward from the lamp, one wavelength per ray, in parallel over
//! fixed-size batches (the only module that traces in parallel).
//!
//! Use: `let tallies = trace(&bench, &TraceOptions::new(rays, seed))?;` then
//! `crate::transport::Transport::from_tallies(&bench, &tallies)`. `PatternMode::Fixed(&bits)`
//! traces the bench with one DMD pattern instead (a direct check of the linear model).
//!
//! Determinism: batch b (of [`RAYS_PER_BATCH`] rays, the last one shorter) always draws its
//! stratification from `rng::stream(seed, b)`, and every ray its interactions from streams keyed
//! by (seed, ray index, part of the path) (path.rs, `RayKey`); batches run in parallel in chunks
//! (at least [`BATCHES_PER_CHUNK`]) and their tallies are merged in batch order, so the result is
//! bit-identical for any number of threads. Because each ray has its own streams, two benches
//! that differ a little are traced with common random numbers ray by ray. Within a batch the
//! rays' emission and wavelength coordinates form a Latin hypercube (path.rs); the physics of
//! each interaction is documented in path.rs.

pub mod collection;
pub mod fan;
pub mod kernel;
pub mod path;
pub mod split;
pub mod strata;
pub mod tally;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::optics::Bench;

pub use path::PatternMode;
pub use strata::Sampling;
pub use tally::{BatchScalars, BatchTally, Tallies};

/// Rays per batch. Fixed (never derived from the thread count). 1024 rays are a few
/// milliseconds of work — far above the cost of merging a batch — and give enough batches for
/// batch-means standard errors even in short test traces.
pub const RAYS_PER_BATCH: u64 = 1024;

/// Batches traced in parallel before their tallies are merged, at least (bounds memory to ~25 MB
/// of per-batch tallies for the paper bench per chunk; any value gives the same result). With
/// many threads a chunk holds [`BATCHES_PER_THREAD`] per thread, up to [`MAX_BATCHES_PER_CHUNK`]:
/// the threads wait for the slowest at the end of each chunk, about one batch in every
/// batches-per-thread, 6 % at 16 threads with 256.
pub const BATCHES_PER_CHUNK: u64 = 256;
/// See [`BATCHES_PER_CHUNK`].
pub const BATCHES_PER_THREAD: u64 = 32;
/// See [`BATCHES_PER_CHUNK`] (two chunks of the paper bench's tallies: ~190 MB).
pub const MAX_BATCHES_PER_CHUNK: u64 = 1024;

/// The batches of one chunk on the current pool ([`BATCHES_PER_CHUNK`]).
fn chunk_batches() -> u64 {
    (BATCHES_PER_THREAD * rayon::current_num_threads() as u64)
        .clamp(BATCHES_PER_CHUNK, MAX_BATCHES_PER_CHUNK)
}

/// A progress callback of the tracer: (rays traced, rays to trace), called after every chunk
/// of batches has been merged (from a thread of the pool). The library draws nothing; the command line turns this
/// into a bar or a log line.
pub type RayProgress<'a> = &'a (dyn Fn(u64, u64) + Sync);

/// What to trace.
#[derive(Clone, Copy)]
pub struct TraceOptions<'a> {
    pub rays: u64,
    pub seed: u64,
    pub mode: PatternMode<'a>,
    /// How the rays draw their random numbers (`strata.rs`).
    pub sampling: Sampling,
    /// Told how far the trace has come.
    pub progress: Option<RayProgress<'a>>,
}

impl std::fmt::Debug for TraceOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceOptions")
            .field("rays", &self.rays)
            .field("seed", &self.seed)
            .field("mode", &self.mode)
            .field("sampling", &self.sampling)
            .field("progress", &self.progress.is_some())
            .finish()
    }
}

impl TraceOptions<'_> {
    pub fn new(rays: u64, seed: u64) -> TraceOptions<'static> {
        TraceOptions {
            rays,
            seed,
            mode: PatternMode::Branch,
            sampling: Sampling::default(),
            progress: None,
        }
    }
}

/// Traces `options.rays` lamp rays through `bench` on the current rayon pool.
pub fn trace(bench: &Bench, options: &TraceOptions) -> Result<Tallies> {
    if options.rays == 0 {
        return Err(Error::field(
            "rays",
            "the number of rays must be at least 1",
        ));
    }
    if let PatternMode::Fixed(bits) = options.mode
        && bits.len() != bench.units()
    {
        return Err(Error::field(
            "pattern",
            format!(
                "a pattern of {} units for a DMD pattern area of {} units",
                bits.len(),
                bench.units()
            ),
        ));
    }
    let (across, down) = bench.units_shape();
    let mut tallies = Tallies::new(
        across,
        down,
        bench.elements().len(),
        options.seed,
        bench.lamp().power_outside_cone(),
    );
    let n = options.rays;
    let n_batches = n.div_ceil(RAYS_PER_BATCH);
    let inv = 1.0 / n as f64;
    batches_in_order(
        n_batches,
        |b| {
            let rays = RAYS_PER_BATCH.min(n - b * RAYS_PER_BATCH);
            path::run_batch(
                bench,
                options.mode,
                options.sampling,
                options.seed,
                b,
                rays,
                inv,
            )
        },
        |_, t| tallies.absorb(&t),
        |batches| {
            if let Some(report) = options.progress {
                report((batches * RAYS_PER_BATCH).min(n), n);
            }
        },
    );
    Ok(tallies)
}

/// Computes `make(b)` for the batches `0..n_batches` on the current rayon pool and hands every
/// result to `absorb` in batch order, calling `chunk_done` with the number of batches absorbed
/// so far after each chunk of batches ([`BATCHES_PER_CHUNK`]).
///
/// The serial merge of one chunk runs beside the parallel computation of the next (one
/// `rayon::join`), so the other threads never wait for it; before, every chunk's merge was a
/// serial pause of all threads, a share that grows with the thread count (Amdahl). The order of
/// the merge, and so every floating-point sum, is the same for any number of threads. At most
/// two chunks of results are held at once.
pub(crate) fn batches_in_order<T, M, A, C>(
    n_batches: u64,
    make: M,
    mut absorb: A,
    mut chunk_done: C,
) where
    T: Send,
    M: Fn(u64) -> T + Sync,
    A: FnMut(u64, T) + Send,
    C: FnMut(u64) + Send,
{
    let mut pending: Option<(u64, Vec<T>)> = None;
    let mut start = 0;
    let chunk = chunk_batches();
    loop {
        let end = (start + chunk).min(n_batches);
        let mut merge = |done: Option<(u64, Vec<T>)>| {
            if let Some((first, chunk)) = done {
                let len = chunk.len() as u64;
                for (b, r) in (first..).zip(chunk) {
                    absorb(b, r);
                }
                chunk_done(first + len);
            }
        };
        let compute =
            || (start < end).then(|| (start, (start..end).into_par_iter().map(&make).collect()));
        let ((), next) = rayon::join(|| merge(pending.take()), compute);
        if next.is_none() {
            return;
        }
        pending = next;
        start = end;
    }
}

#[cfg(test)]
pub(crate) mod testing {
    //! Benches for tests.
    use crate::optics::Bench;
    use std::path::{Path, PathBuf};

    pub fn scene_path(rel: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(rel)
    }

    /// A bench file with text replacements applied (each must match exactly once).
    pub fn bench_with(rel: &str, edits: &[(&str, &str)]) -> Bench {
        let path = scene_path(rel);
        let mut text = std::fs::read_to_string(&path).unwrap();
        for (from, to) in edits {
            assert_eq!(
                text.matches(from).count(),
                1,
                "edit `{from}` must match once"
            );
            text = text.replace(from, to);
        }
        crate::scene::bench::parse_bench(&text, &path).unwrap()
    }

    /// The paper bench with its USAF chart replaced by an image mask of the same region size
    /// (the USAF geometry lives in crate::objects::usaf and is tested there).
    pub fn paper_bench_with_mask() -> Bench {
        bench_with(
            "paper_bench.ron",
            &[
                (
                    "pattern: Usaf(min_group: -2, max_group: 7),",
                    "pattern: Image(path: \"images/astronaut.png\", width_mm: 20.0, height_mm: 20.0),",
                ),
                (
                    "center_on: Elements(group: -1, first: 5, last: 6),",
                    "center_on: Point((0.0, 0.0)),",
                ),
            ],
        )
    }
}

#[cfg(test)]
mod tests;
