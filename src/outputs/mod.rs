//! The outputs of every command, one module per command as docs/outputs.md has one section per
//! command: each holds that command's `summary.json` type, its CSV rows, its figures, the blocks
//! of its `report.html` and the lines it prints, written from what the command's job returned.
//! The command line (`cli`) parses arguments, runs the job and calls the module here; nothing
//! here parses arguments or names a flag, so another caller (the Python package) can write a
//! command's folder the same way.
//!
//! Shared by all: [`summary`] (`summary.json` with its provenance first, `timings.json`),
//! [`rows`] (the metric row of `sweep`, `tolerance` and `align`) and [`layout`] (the bench
//! drawing of `layout` and of the reports). The figure writers need the `figures` feature, as
//! the `report` modules they call.

pub mod card;
pub mod check;
pub mod export;
pub mod fit;
pub mod intake;
pub mod irradiance;
pub mod labels;
pub mod layout;
pub mod lens;
pub mod reconstruct;
pub mod rows;
pub mod run;
pub mod summary;
pub mod trace;

#[cfg(feature = "figures")]
pub mod align;
#[cfg(feature = "figures")]
pub mod simulate;
#[cfg(feature = "figures")]
pub mod sweep;
#[cfg(feature = "figures")]
pub mod tolerance;
