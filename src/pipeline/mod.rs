//! The stages every command composes: trace → record → solve (with scores). Each is a plain
//! function over data, so that `run`, `sweep` and the commands built on them reuse one pipeline
//! instead of copying it.
//!
//! - [`trace_stage`]: a bench → its transport (T maps, k±, b±, the ledger) and its metrics with
//!   standard errors ([`Traced`]); optionally through an on-disk cache ([`cache`]);
//! - [`record_stage`]: the transport, the electronics and the acquisition settings → the
//!   detector outputs recorded in time for the DMD's frame sequences ([`Recorded`]);
//! - [`solve_stage`]: the records → each scheme's measurements, reconstructed and scored
//!   ([`SchemeResult`]).
//!
//! # Sequences and schemes
//!
//! Two acquisitions are recorded, each with all three outputs on the oscilloscope: the base
//! sequence P₁, P₂, …, P_M and the complementary sequence P₁, 1 − P₁, P₂, 1 − P₂, …. Which
//! sequence and outputs a scheme reads and how its measurements are formed belong to the scheme
//! ([`crate::acquisition::Scheme::sequence`], `outputs`, `measurements`). A lower sampling ratio
//! uses the first M patterns of the set for the highest ratio and the first M (or 2M) frames of
//! each record, exactly what an acquisition stopped after M patterns would have recorded.
//!
//! # Scores
//!
//! The ideal object is x_j, the power incident on unit j (W, from the trace), shown on 0–255 as
//! 255·x_j / max x. Every reconstruction is brought to that scale by the one rule of
//! [`crate::metrics::score`] and scored with PSNR and MSSIM.
//!
//! # Determinism
//!
//! The trace is deterministic for a seed (crate::trace); the records run in parallel with each
//! other but each in time order with streams keyed by (seed, frame batch); the reconstructions
//! run in parallel and are collected in cell order.

pub mod cache;
pub mod evaluate;
pub mod operator;
pub mod optimise;
pub mod perturb;
mod record;
mod solve;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::raster::Raster;
use crate::trace::{Tallies, TraceOptions, trace};
use crate::transport::Transport;
use crate::transport::metrics::BenchMetrics;

pub use record::{
    Recorded, ReplaySetup, SampleSink, Saturation, SequenceSummary, record_stage, record_transport,
    replay_sequence,
};
pub use solve::{
    MIN_REGISTRATION_CORRELATION, ResolutionContext, Resolved, SchemeResult, resolution_context,
    solve_stage,
};

/// Stage of a pipeline, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Record,
    Solve,
}

/// A progress callback: (stage, done, total). Called from any thread; no terminal code lives
/// in the library.
pub type Progress<'a> = &'a (dyn Fn(Stage, u64, u64) + Sync);

/// A traced bench: everything downstream stages need from the optics.
#[derive(Debug, Clone)]
pub struct Traced {
    pub rays: u64,
    pub seed: u64,
    /// The merged tallies (kept for the metrics' paired standard errors and for the cache).
    pub tallies: Tallies,
    pub transport: Transport,
    pub metrics: BenchMetrics,
    /// Whether the tallies came from the trace cache.
    pub cache: CacheStatus,
}

/// What the trace cache did for a trace.
#[derive(Debug, Clone, PartialEq)]
pub enum CacheStatus {
    /// No cache was used.
    Off,
    /// Read from the cache.
    Hit,
    /// Not in the cache: traced and stored.
    Miss,
    /// The entry was damaged (the reason): traced again and stored.
    Rebuilt(String),
}

impl Traced {
    /// From tallies (traced now or read from the cache).
    pub fn from_tallies(bench: &Bench, tallies: Tallies, cache: CacheStatus) -> Traced {
        let transport = Transport::from_tallies(bench, &tallies);
        let metrics = BenchMetrics::new(&tallies, &transport);
        Traced {
            rays: tallies.rays,
            seed: tallies.seed,
            transport,
            metrics,
            tallies,
            cache,
        }
    }

    /// Lamp rays whose path reached the pattern area.
    pub fn arrivals(&self) -> u64 {
        self.tallies.arrivals
    }

    /// The ideal object x_j (W) as an image of the pattern area.
    pub fn x(&self) -> Result<Raster> {
        let t = &self.transport;
        Raster::new(t.units_across, t.units_down, t.x_w.clone())
    }

    /// The ideal object on 0–255 (255·x / max x). No light on the pattern area is an input
    /// error: the bench, not the code, is at fault.
    pub fn truth(&self) -> Result<Raster> {
        let x = self.x()?;
        let Some(truth) = evaluate::truth_view(&x) else {
            return Err(Error::input(format!(
                "no traced light reached the DMD's pattern area ({} rays, {} arrivals): the lamp, \
                 the chart and the imaging lens do not send light onto it; check their \
                 positions and axes (`spibench layout` draws the bench), or trace more rays",
                self.rays,
                self.arrivals()
            ))
            .at_field("rays"));
        };
        // An arm that detects nothing leaves its leak ratios 0/0: a blocked or misplaced
        // photodiode is the bench's fault, reported like no light at all.
        for (arm, k) in ["+", "−"].iter().zip(&self.transport.k) {
            if !(k.value.is_finite() && k.value > 0.0) {
                return Err(Error::input(format!(
                    "no traced light reached the photodiode of arm {arm} ({} rays): check the \
                     positions and axes of the arm's lens and photodiode (`spibench layout` \
                     draws the bench), or trace more rays",
                    self.rays
                ))
                .at_field("detectors"));
            }
        }
        Ok(truth)
    }
}

/// What to trace, and where to cache it.
#[derive(Clone, Copy)]
pub struct TraceRequest<'a> {
    pub rays: u64,
    pub seed: u64,
    /// Told how far the trace has come (rays traced, rays to trace).
    pub progress: Option<crate::trace::RayProgress<'a>>,
    /// The trace cache and this bench's key in it.
    pub cache: Option<(&'a cache::TraceCache, &'a cache::CacheKey)>,
}

impl TraceRequest<'_> {
    pub fn new(rays: u64, seed: u64) -> TraceRequest<'static> {
        TraceRequest {
            rays,
            seed,
            progress: None,
            cache: None,
        }
    }
}

impl std::fmt::Debug for TraceRequest<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceRequest")
            .field("rays", &self.rays)
            .field("seed", &self.seed)
            .field("progress", &self.progress.is_some())
            .field("cache", &self.cache.map(|(_, k)| k.as_str()))
            .finish()
    }
}

/// The trace stage: traces `bench` (or reads the same trace from the cache) and derives its
/// transport and metrics.
pub fn trace_stage(bench: &Bench, req: &TraceRequest) -> Result<Traced> {
    let status = match req.cache {
        None => CacheStatus::Off,
        Some((c, key)) => match c.lookup(key) {
            cache::Lookup::Hit(t) if t.rays == req.rays && t.seed == req.seed => {
                return Ok(Traced::from_tallies(bench, *t, CacheStatus::Hit));
            }
            cache::Lookup::Hit(_) => CacheStatus::Rebuilt("rays or seed differ".into()),
            cache::Lookup::Miss => CacheStatus::Miss,
            cache::Lookup::Corrupt(why) => CacheStatus::Rebuilt(why),
        },
    };
    let tallies = trace(
        bench,
        &TraceOptions {
            progress: req.progress,
            ..TraceOptions::new(req.rays, req.seed)
        },
    )?;
    if let Some((c, key)) = req.cache {
        c.store(key, &tallies)?;
    }
    Ok(Traced::from_tallies(bench, tallies, status))
}

/// Wall-clock timings (s); the only part of a run that changes between identical runs.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Timings {
    pub trace_s: f64,
    pub record_s: f64,
    pub solve_s: f64,
    pub total_s: f64,
}
#[cfg(test)]
mod tests;
