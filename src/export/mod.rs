//! Export of a bench as a Mitsuba 3 scene (mitsuba==3.9.1), built in memory: `scene.xml`, one
//! binary PLY per optical surface (plus one for every black absorber and one for the DMD), a
//! float bitmap (PFM) per chart mask, and `manifest.json` with what an external forward tracer
//! needs (lamp frame, emission cone, power, the photodiodes). Pure: no file IO; the CLI writes
//! the files (src/cli/export.rs).
//!
//! The exporter writes exactly the surfaces spibench traces: it walks [`Bench::surfaces`],
//! [`Bench::meshes`] and the DMD and maps each interaction onto one Mitsuba BSDF:
//!
//! | spibench | Mitsuba |
//! |---|---|
//! | interface between media n₁ (normal side) and n₂ | `dielectric`, `ext_ior` n₁, `int_ior` n₂ (none when n₁ = n₂) |
//! | black surface, lens rim, mount, housing, DMD gaps | `diffuse` of reflectance 0 |
//! | mirror (front surface) and DMD facets | `conductor`, `material: none`, `specular_reflectance` R |
//! | chart mask | `mask` with opacity 1 − T from a bitmap (nearest, raw), black behind |
//! | photodiode | `disk` with a black BSDF and an `irradiancemeter` |
//! | lamp filament | `rectangle`/`disk` with an `area` emitter of radiance Φ/(π·A), black BSDF |
//!
//! One difference is left: spibench's filament is transparent to light coming back to it, the
//! exported one absorbs it (Mitsuba's `path` integrator finds no emission on an emitter with a
//! `null` BSDF). Light that returns onto the 2 mm filament and would then still reach a
//! photodiode is far below the validation's resolution.
//!
//! Only a monochromatic, constant-index bench can be exported (Mitsuba has no dispersion, no
//! thin films, no absorbing dielectric, no refracting mask): pass a bench through
//! [`crate::optics::monochromatic::monochromatic`] first; [`export_mitsuba`] refuses anything
//! else with a message that names the element.
//!
//! Geometry (docs/mitsuba.md): scene units are millimetres (Mitsuba offsets every spawned ray by
//! about (1 + max|p|)·8.9e-5 scene units, 0.09 µm near the DMD at the origin); spherical caps are
//! meshes of [`CAP_RINGS`] rings × [`SEGMENTS`] segments with exact vertex normals (chord sag
//! error below 0.5 µm for the benches here), circles are polygons of [`SEGMENTS`] sides whose
//! radius is scaled to keep the circle's area; the DMD is one mesh of two triangles per facet,
//! each facet in its pattern state, over a black substrate below the tilted mirrors.

mod mesh;
pub mod pattern;
mod scene;

use serde_json::json;

use crate::error::{Error, Result};
use crate::optics::Bench;

use scene::{BLACK, SceneWriter};

pub use pattern::DmdPattern;

/// Sides of every circle polygon and azimuthal segments of every cap.
pub const SEGMENTS: usize = 256;
/// Radial rings of a spherical cap.
pub const CAP_RINGS: usize = 48;

/// Metres to scene millimetres.
const MM: f64 = 1e3;

/// An exported scene: files (relative path, bytes) and notes for the user.
#[derive(Debug, Clone)]
pub struct MitsubaScene {
    pub files: Vec<(String, Vec<u8>)>,
    /// What the export could not represent exactly, one sentence each.
    pub notes: Vec<String>,
}

/// Export options.
#[derive(Debug, Clone)]
pub struct ExportOptions {
    /// State of every pattern unit (true = +), row-major; must have `bench.units()` entries.
    pub pattern: Vec<bool>,
    /// A label for the pattern (written to the manifest).
    pub pattern_label: String,
    /// The monochromatic wavelength of the substitute (m), for the manifest; None if the bench
    /// was exported as it is.
    pub wavelength_m: Option<f64>,
    /// Samples per pixel of the two irradiancemeters (for Mitsuba's own `path` integrator).
    pub sensor_samples: u32,
    /// Keep the lamp's thermal spectrum and the diodes' responsivity tables (written to the
    /// manifest for a spectral render: Mitsuba's `blackbody` emitter and a `specfilm` with the
    /// responsivity as its response). Glasses must still have constant indices.
    pub spectral: bool,
}

/// A refusal: the bench has something Mitsuba cannot represent.
fn unrepresentable(what: String) -> Error {
    Error::input(format!(
        "{what}; Mitsuba 3 cannot represent it: export the monochromatic substitute \
         (`wavelength_nm`)"
    ))
}

/// Exports a monochromatic, constant-index bench (see the module notes).
pub fn export_mitsuba(bench: &Bench, opts: &ExportOptions) -> Result<MitsubaScene> {
    if bench.dmd().is_some() && opts.pattern.len() != bench.units() {
        return Err(Error::field(
            "pattern",
            format!(
                "a pattern of {} units for a DMD pattern area of {} units",
                opts.pattern.len(),
                bench.units()
            ),
        ));
    }
    let notes: Vec<String> = Vec::new();
    let depth = bench.max_interactions() + 1;
    let mut w = SceneWriter::new(depth);
    for s in bench.surfaces() {
        w.surface(bench, opts, s)?;
    }
    w.meshes(bench);
    if let Some(setup) = &bench.dmd() {
        w.dmd(setup, opts)?;
    }
    if !w.black.is_empty() {
        let black = std::mem::take(&mut w.black);
        w.add_mesh("absorbers", &black, BLACK);
    }
    let lamp_json = w.lamp(bench, opts)?;
    let manifest = json!({
        "generator": format!("spibench {} export-mitsuba", env!("CARGO_PKG_VERSION")),
        "mitsuba_version": "3.9.1",
        "units": "millimetres; powers in W",
        "wavelength_nm": opts.wavelength_m.map(|w| w * 1e9),
        "pattern": opts.pattern_label,
        "pattern_units": opts.pattern.len(),
        "max_depth": depth,
        "lamp": lamp_json,
        "band_nm": [bench.band().0 * 1e9, bench.band().1 * 1e9],
        "detectors": w.detectors_json,
    });
    let mut files = w.files;
    files.push(("scene.xml".into(), w.xml.into_bytes()));
    files.push((
        "manifest.json".into(),
        serde_json::to_string_pretty(&manifest)
            .map_err(|e| Error::Numerical(e.to_string()))?
            .into_bytes(),
    ));
    Ok(MitsubaScene { files, notes })
}
