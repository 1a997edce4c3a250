//! Bench files: the optical bench in RON, in millimetres and degrees, converted once into a
//! validated SI [`crate::optics::Bench`].
//!
//! **The bench frame.** One right-handed frame for every position and direction. Its origin is
//! the centre of the DMD's mirror array, +z is the array normal (toward the illumination), mirror
//! columns count along +x and rows along −y (row 0 at the top, +y), so per-unit maps read as
//! images of the array seen from the front. A bench without a DMD uses the same frame.
//!
//! **Directions** are written `Vector((x, y, z))` (any length, normalised on reading) or
//! `Polar(theta_deg: θ, phi_deg: φ)` = (sin θ cos φ, sin θ sin φ, cos θ): θ from +z, φ from +x
//! toward +y. The DMD's arms at ±24° in the 45° plane are `Polar(theta_deg: 24.0, phi_deg: -45.0)`
//! (arm +) and `Polar(theta_deg: 24.0, phi_deg: 135.0)` (arm −).
//!
//! **Validation.** Single values are checked while the file is read (a negative length, an empty
//! or unsorted table), so the error carries the line and column; relations between values (a
//! lens whose faces cross, overlapping elements, a pattern area outside the array) are checked
//! after reading and the error is located by looking the field up in the text. A `Bench` that
//! exists is valid.
//!
//! The module's files: `schema.rs` (the serde types of the file; `element_serde.rs` reads and
//! writes its elements as the struct variants a file writes), `build.rs` (the builder and
//! its checks), `elements.rs` (one function per element kind), `devices.rs` (the DMD, the
//! photodiodes and the lamp). The checked numbers are [`crate::scene::numbers`], the field
//! locator [`crate::scene::locate`].

mod build;
mod devices;
mod element_serde;
mod elements;
mod lens_system;
mod schema;
#[cfg(test)]
mod tests;

use std::path::Path;

use crate::error::Result;
use crate::optics::bench::{Bench, BenchParts};
use crate::scene::locate::Locator;

use build::{Builder, Ctx};

pub use crate::scene::numbers::{
    AngleDeg, CoordMm, Count, DesignNm, DirectionDeg, Finite, Irradiance, LengthMm, MAX_OD,
    MAX_POSITION_MM, MAX_SCALAR, Mm3, NonNegative, OpticalDensity, Positive, PowerW, Probability,
    RadiusMm, TableNm, Temperature, TiltDeg, UnitFraction, WavelengthNm, Whole,
};
pub use lens_system::{element_prescription, lens_substitutions};
pub use schema::{
    ApertureSpec, BaffleSpec, BenchFile, CenterOnSpec, ChartGuidedSpec, ChartPatternSpec,
    ChartSpec, CoatingSpec, DetectorsSpec, Direction, DmdModelSpec, DmdSpec, ElementSpec,
    EmissionSpec, FieldSamplingSpec, FilamentSpec, FilterSpec, GlassSpec, Interactions,
    LampPowerSpec, LampSpec, LampSpectrumSpec, LensSpec, LensSurfaceSpec, LensSystemSpec,
    MirrorCount, MirrorIndex, MirrorSpec, Outline, PatternSpec, PhotodiodeSpec, Segments,
    SpectrumSpec, StateSpec, TubeSpec, UsafElement, UsafGroup, WindowSpec,
};

// Conversion.

/// Reads and validates a bench file.
pub fn read_bench(path: &Path) -> Result<Bench> {
    let text = crate::scene::read_text(path)?;
    parse_bench(&text, path)
}

/// Parses and validates bench text; `path` names the file in errors and anchors relative image
/// paths.
pub fn parse_bench(text: &str, path: &Path) -> Result<Bench> {
    let file: BenchFile = crate::scene::parse_ron(text, path)?;
    build_bench(&file, Some(text), path)
}

/// Converts a parsed bench file into a validated bench. `text` is the file's source when there
/// is one: errors then carry the line and column of the field they name; a bench made in code
/// has none, and its errors name the field alone. `path` names the file in errors and anchors
/// relative image paths.
pub fn build_bench(file: &BenchFile, text: Option<&str>, path: &Path) -> Result<Bench> {
    Builder {
        ctx: Ctx {
            loc: text.map(|text| Locator { text }),
            path,
            glasses: Vec::new(),
        },
        parts: BenchParts::new(),
        solids: Vec::new(),
        throughput: Vec::new(),
    }
    .build(file)
}
