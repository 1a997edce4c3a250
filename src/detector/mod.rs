//! Detector electronics in time: the balanced amplified photodetector ([`bap`]), the
//! oscilloscope ([`scope`]), lamp and ambient drift ([`drift`]) and the frame-by-frame
//! recording that turns traced photocurrents into the per-frame values the acquisition schemes
//! use ([`record`]).
//!
//! Pure functions over data in SI units (amperes, volts, seconds, hertz). Randomness comes from
//! [`crate::rng::stream`] keyed by (seed, frame batch) or a fixed stream index, drawn in time
//! order, so a record does not depend on the number of threads.

pub mod bap;
pub mod drift;
pub mod frames;
pub mod record;
pub mod scope;

pub use bap::{Bap, Load, MONITOR_MINUS, MONITOR_PLUS, OUTPUT_NAMES, OutputStage, RF};
pub use drift::{Drift, DriftPath};
pub use frames::{BOUNDARY_EPS, FrameMeans, SettleRule};
pub use record::{
    FrameTiming, Illumination, Record, RecordModel, SignalTrace, frame_start_sample, ideal_frames,
    record, record_frames, record_observed, record_with,
};
pub use scope::{Channel, ChannelRange, Scope, ScopeNoise, auto_range};
