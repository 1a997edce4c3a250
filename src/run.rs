//! The whole traced experiment of the paper's §4 as one library function ([`run`]): the bench
//! traced once, then the evaluate step ([`crate::pipeline::evaluate::evaluate_traced`]): the
//! detector outputs recorded in time for the DMD's frame sequences, the schemes' measurements,
//! TVAL3 and the scores against the ideal object. [`run`] is the one-repeat case of
//! [`repeats::run_repeats`]. No files are touched here: crate::outputs::run writes the outputs
//! from [`RunOutcome`]. See crate::pipeline for the sequences, the scores and
//! determinism.

use crate::error::Result;
use crate::pipeline::TraceRequest;
use crate::scene::run::RunScene;

pub use crate::acquisition::Sequence;
pub use crate::pipeline::evaluate::RunOutcome;
pub use crate::pipeline::{
    MIN_REGISTRATION_CORRELATION, Progress, ResolutionContext, Resolved, Saturation, SchemeResult,
    SequenceSummary, Stage, Timings,
};
pub use crate::scene::run::RunSettings;

/// Runs the pipeline on a scene. `trace` is how to trace (rays, seed, progress bar, cache); its
/// seed is the run's, of the trace, the noise and the drift (the patterns have their own seed
/// in the scene); `progress` reports the later stages.
pub fn run(scene: &RunScene, trace: &TraceRequest, progress: Progress) -> Result<RunOutcome> {
    let (mut outcomes, _) = repeats::run_repeats(scene, trace, 1, progress)?;
    Ok(outcomes.swap_remove(0))
}

pub mod findings;
pub mod repeats;

#[cfg(test)]
mod tests;
