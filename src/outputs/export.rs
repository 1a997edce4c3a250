//! The outputs of `spibench export-mitsuba` (docs/outputs.md, "export-mitsuba"): the Mitsuba 3
//! scene's files as crate::export made them (`scene.xml`, `meshes/*.ply`, `charts/*.pfm`,
//! `manifest.json`), `substitutions.txt` (every change the monochromatic substitute made, one
//! per line) and `summary.json` ([`ExportSummary`]).

use serde::Serialize;

use crate::error::{Error, Result};
use crate::export::MitsubaScene;
use crate::provenance::Provenance;
use crate::report::output::OutputDir;

/// `summary.json` of an export.
#[derive(Debug, Clone, Serialize)]
pub struct ExportSummary {
    pub scene: String,
    pub pattern: String,
    /// The substitute's wavelength (nm), null with --as-is.
    pub wavelength_nm: Option<f64>,
    /// Every change the substitution made (empty for a bench Mitsuba represents as it is).
    pub substitutions: Vec<String>,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
}

/// What the export says of a bench whose DMD diffracts (docs/dmd_diffraction.md).
pub const DIFFRACTION_NOTE: &str = "dmd: Mitsuba cannot model the DMD's diffraction (a ray \
     tracer has no grating orders): the scene's mirrors reflect geometrically, as with `model: \
     Geometric`; compare Mitsuba with spibench's geometric model only";

/// Writes the scene's files, `substitutions.txt` and `summary.json` into `dir` (a staging
/// folder); `summary.files` is set to what was written.
pub fn write(
    dir: &OutputDir,
    scene: &MitsubaScene,
    mut summary: ExportSummary,
    provenance: &Provenance,
) -> Result<ExportSummary> {
    let mut files = Vec::new();
    for (name, bytes) in &scene.files {
        let p = dir.try_path(name)?;
        std::fs::write(&p, bytes).map_err(|e| Error::write(&p, e))?;
        files.push(name.clone());
    }
    let p = dir.try_path("substitutions.txt")?;
    let mut text = summary.substitutions.join("\n");
    text.push('\n');
    std::fs::write(&p, text).map_err(|e| Error::write(&p, e))?;
    files.push("substitutions.txt".into());
    summary.files = files;
    super::summary::write_summary(dir, &summary, provenance)?;
    Ok(summary)
}
