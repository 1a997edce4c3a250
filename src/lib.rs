//! spibench: a physically based optical-bench simulator for DMD single-pixel imaging with
//! complementary and balanced detection.
//!
//! The pipeline is a chain of plain functions over data:
//! scene (RON) → bench → trace → transport (T maps, k±, b±) → detector → acquisition (schemes)
//! → reconstruction → metrics → report. See ARCHITECTURE.md for the code map and invariants.

pub mod acquisition;
pub mod align;
pub mod checked;
#[cfg(feature = "cli")]
pub mod cli;
pub mod dataset;
pub mod detector;
pub mod error;
pub mod export;
pub mod fit;
pub mod intake;
pub mod lens;
pub mod memory;
pub mod metrics;
pub mod npy;
pub mod objects;
pub mod optics;
pub mod outputs;
pub mod pipeline;
pub mod provenance;
pub mod quantities;
pub mod raster;
pub mod reconstruction;
pub mod report;
pub mod rng;
pub mod run;
pub mod scene;
pub mod simulation;
pub mod sweep;
pub mod tolerance;
pub mod trace;
pub mod transport;

pub use error::{Error, Result};
pub use raster::Raster;
