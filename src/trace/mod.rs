//! The Monte Carlo engine: forward from the lamp, one wavelength per ray, in parallel over
//! fixed-size batches (the only module that traces in parallel).
//!
//! Use: `let tallies = trace(&bench, &TraceOptions::new(rays, seed))?;` then
//! `crate::transport::Transport::from_tallies(&bench, &tallies)`. `PatternMode::Fixed(&bits)`
//! traces the bench with one DMD pattern instead (a direct check of the linear model).
//!
//! Determinism: batch b (of [`RAYS_PER_BATCH`] rays, the last one shorter) always draws its
//! stratification from `rng::stream(seed, b)`, and every ray its interactions from streams keyed
//! by (seed, ray index, part of the path) (path.rs, `RayKey`); batches run in parallel
//! and their tallies are merged in batch order (`batches_in_order`), so the result is
//! bit-identical for any number of threads. Because each ray has its own streams, two benches
//! that differ a little are traced with common random numbers ray by ray. Within a batch the
//! rays' emission and wavelength coordinates form a Latin hypercube (path.rs); the physics of
//! each interaction is documented in path.rs.

pub mod collection;
pub mod fan;
pub mod irradiance;
pub mod kernel;
pub mod paraxial;
pub mod path;
pub mod split;
pub mod strata;
pub mod tally;

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

use crate::error::{Error, Result};
use crate::optics::Bench;

pub use path::PatternMode;
pub use strata::Sampling;
pub use tally::{BatchScalars, BatchTally, Tallies};

/// Rays per batch. Fixed (never derived from the thread count). 1024 rays are a few
/// milliseconds of work — far above the cost of merging a batch — and give enough batches for
/// batch-means standard errors even in short test traces.
pub const RAYS_PER_BATCH: u64 = 1024;

/// Batches whose results may wait for the merge at once, per thread of the pool (at least
/// [`MIN_PENDING_BATCHES`], at most [`MAX_PENDING_BATCHES`]): a thread that would start a batch
/// further ahead of the merge than that waits until the merge catches up, which bounds the
/// memory held by finished batches (~100 kB of tallies each for the paper bench) whatever the
/// scheduling. Any value gives the same result.
pub const PENDING_BATCHES_PER_THREAD: u64 = 32;
/// See [`PENDING_BATCHES_PER_THREAD`].
pub const MIN_PENDING_BATCHES: u64 = 256;
/// See [`PENDING_BATCHES_PER_THREAD`] (about 100 MB of the paper bench's tallies).
pub const MAX_PENDING_BATCHES: u64 = 1024;
/// The progress callback is called after every this many batches merged (and after the last).
pub const BATCHES_PER_REPORT: u64 = 256;

/// The bound on finished batches waiting for the merge, on the current pool.
fn pending_limit() -> u64 {
    (PENDING_BATCHES_PER_THREAD * rayon::current_num_threads() as u64)
        .clamp(MIN_PENDING_BATCHES, MAX_PENDING_BATCHES)
}

/// A progress callback of the tracer: (rays traced, rays to trace), called after every
/// [`BATCHES_PER_REPORT`] batches merged (from a thread of the pool). The library draws
/// nothing; the command line turns this into a bar or a log line.
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
    check_options(bench, options)?;
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

/// The options' rays and pattern, checked against the bench.
fn check_options(bench: &Bench, options: &TraceOptions) -> Result<()> {
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
    Ok(())
}

/// Computes `make(b)` for the batches `0..n_batches` on the current rayon pool and hands every
/// result to `absorb` in batch order, calling `progress` with the number of batches absorbed so
/// far after every [`BATCHES_PER_REPORT`] of them and after the last.
///
/// No thread waits for another at a chunk's end: one worker per thread claims batch indices
/// in order, one at a time, and the thread that finishes a batch merges every finished batch
/// that is next in order, unless another thread is merging already (which then takes it).
/// Before, the batches ran in chunks of a few hundred and every thread waited at each chunk's
/// end for the slowest, about half a batch per thread per chunk, a loss that grows with the
/// thread count. The order of the merge, and so every floating-point sum, is the same for any
/// number of threads. A worker does not start a batch more than [`pending_limit`] ahead of the
/// merge: it waits, so at most that many results are held at once.
///
/// Contract: `make`, `absorb` and `progress` never wait for the pool (no rayon call inside).
/// Then every batch before a waiting worker's is being computed by a running thread, or done,
/// and the merge goes on; a rayon call inside could put a worker that waits on top of the
/// batch the merge needs, on one thread's stack. (The tracer's batches and merges are serial.)
pub(crate) fn batches_in_order<T, M, A, C>(n_batches: u64, make: M, absorb: A, progress: C)
where
    T: Send,
    M: Fn(u64) -> T + Sync,
    A: FnMut(u64, T) + Send,
    C: FnMut(u64) + Send,
{
    let order = InOrder {
        n_batches,
        limit: pending_limit(),
        claimed: AtomicU64::new(0),
        queue: Mutex::new(Queue {
            merged: 0,
            failed: false,
            ready: BTreeMap::new(),
        }),
        room: Condvar::new(),
        sink: Mutex::new((absorb, progress)),
    };
    // One worker per thread of the pool, each taking batches until none is left (a task per
    // batch would queue 10⁷ tasks for the largest traces allowed).
    let workers = (rayon::current_num_threads() as u64).min(n_batches);
    rayon::scope_fifo(|s| {
        for _ in 0..workers {
            s.spawn_fifo(|_| order.work(&make));
        }
    });
}

/// The shared state of [`batches_in_order`].
struct InOrder<T, A, C> {
    n_batches: u64,
    limit: u64,
    /// The next batch index to hand out.
    claimed: AtomicU64,
    queue: Mutex<Queue<T>>,
    /// Signalled when the merge advances (or a batch failed).
    room: Condvar,
    /// The merge: held by the one thread merging.
    sink: Mutex<(A, C)>,
}

/// Finished batches waiting for the merge.
struct Queue<T> {
    /// Batches absorbed so far (the next one to absorb).
    merged: u64,
    /// A batch panicked: nobody waits any longer (the scope rethrows the panic).
    failed: bool,
    ready: BTreeMap<u64, T>,
}

impl<T, A, C> InOrder<T, A, C>
where
    T: Send,
    A: FnMut(u64, T) + Send,
    C: FnMut(u64) + Send,
{
    /// One worker: claims the next batch, waits for room, computes it, queues it and merges
    /// what is in order, until every batch is claimed (or one failed).
    fn work(&self, make: &(impl Fn(u64) -> T + Sync)) {
        let guard = FailOnPanic(self);
        loop {
            let b = self.claimed.fetch_add(1, Ordering::Relaxed);
            if b >= self.n_batches {
                break;
            }
            {
                let mut q = lock(&self.queue);
                while b >= q.merged + self.limit && !q.failed {
                    q = self.room.wait(q).unwrap_or_else(PoisonError::into_inner);
                }
                if q.failed {
                    return;
                }
            }
            let result = make(b);
            lock(&self.queue).ready.insert(b, result);
            self.merge();
        }
        std::mem::forget(guard);
    }

    /// Absorbs the queued batches that are next in order, unless another thread is doing so.
    /// After letting go of the merge it looks again: a batch queued while it held the merge by
    /// a thread that then found the merge taken would otherwise wait for the next batch.
    fn merge(&self) {
        loop {
            let Ok(mut sink) = self.sink.try_lock() else {
                return;
            };
            let (absorb, progress) = &mut *sink;
            let mut next = lock(&self.queue).merged;
            loop {
                let Some(result) = lock(&self.queue).ready.remove(&next) else {
                    break;
                };
                absorb(next, result);
                next += 1;
                lock(&self.queue).merged = next;
                self.room.notify_all();
                if next.is_multiple_of(BATCHES_PER_REPORT) || next == self.n_batches {
                    progress(next);
                }
            }
            drop(sink);
            if !lock(&self.queue).ready.contains_key(&next) {
                return;
            }
        }
    }
}

/// Wakes every waiting worker if a batch (or the merge) panics, so that the scope can end and
/// rethrow the panic instead of waiting for a batch that never comes.
struct FailOnPanic<'a, T, A, C>(&'a InOrder<T, A, C>);

impl<T, A, C> Drop for FailOnPanic<'_, T, A, C> {
    fn drop(&mut self) {
        lock(&self.0.queue).failed = true;
        self.0.room.notify_all();
    }
}

/// A lock that survives a panic elsewhere (the data it guards stays consistent: every update
/// under it is a single insert, remove or store).
fn lock<U>(m: &Mutex<U>) -> MutexGuard<'_, U> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
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
