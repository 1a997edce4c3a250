//! A bench as a value that code can change and rebuild.
//!
//! A [`BenchDoc`] is the parsed bench file ([`BenchFile`]) together with where it came from: the
//! path (which names it in errors and anchors relative image paths) and, when it was read from
//! text, that text (which gives errors their line and column). Code edits the file — through
//! bench variables ([`crate::scene::variables`]) or directly — and builds a fresh
//! [`crate::optics::Bench`] from it with [`BenchDoc::build`]; a `Bench` has no setters, so its
//! derived state (the BVH, the spectral sampler, the chart guide, the emission cone) is always
//! the one its parts imply.
//!
//! [`BenchDoc::to_ron`] writes the bench back as RON that every command accepts; reading it
//! again gives the identical file, and so the identical bench.
//!
//! Every command that reads a bench enters here, once: [`BenchDoc::open`] reads the named file
//! or, without one, the paper's bench built into the program ([`BenchDoc::paper`]); the
//! document's own text then gives the provenance of its outputs ([`BenchDoc::provenance`]).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::scene::bench::{BenchFile, DmdModelSpec, build_bench};
use crate::scene::run::{RunScene, run_scene};

/// The paper's bench, built into the program (`scenes/paper_bench.ron`).
pub const PAPER_BENCH: &str = include_str!("../../scenes/paper_bench.ron");

/// The name the built-in bench has in messages and summaries.
pub const PAPER_BENCH_NAME: &str = "<built-in scenes/paper_bench.ron>";

/// The DMD model a caller selects over the bench file's `dmd.model` ([`BenchDoc::set_dmd_model`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
pub enum DmdModel {
    /// Plane mirrors: each mirror reflects specularly.
    Geometric,
    /// The array as a blazed two-dimensional grating (docs/dmd_diffraction.md).
    Diffractive,
}

impl DmdModel {
    /// The model's name in summaries and manifests: `geometric` or `diffractive`.
    pub fn name(self) -> &'static str {
        match self {
            DmdModel::Geometric => "geometric",
            DmdModel::Diffractive => "diffractive",
        }
    }
}

/// A bench file with its origin, and the variables set on it since it was read.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchDoc {
    /// The bench as data.
    pub file: BenchFile,
    path: PathBuf,
    /// The source text the file was read from. Field positions stay valid after variables are
    /// set (only values change), so errors keep their lines.
    text: Option<String>,
    /// Variables set since reading, in order, for error messages.
    edits: Vec<(String, f64)>,
}

impl BenchDoc {
    /// Reads a bench file (not yet built: see [`BenchDoc::build`]).
    pub fn read(path: &Path) -> Result<BenchDoc> {
        let text = crate::scene::read_text(path)?;
        BenchDoc::parse(&text, path)
    }

    /// The paper's bench built into the program ([`PAPER_BENCH`], named [`PAPER_BENCH_NAME`]).
    pub fn paper() -> Result<BenchDoc> {
        BenchDoc::parse(PAPER_BENCH, Path::new(PAPER_BENCH_NAME))
    }

    /// The bench file at `path`, or without one the built-in paper bench.
    pub fn open(path: Option<&Path>) -> Result<BenchDoc> {
        match path {
            Some(p) => BenchDoc::read(p),
            None => BenchDoc::paper(),
        }
    }

    /// Parses bench text; `path` names it in errors and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<BenchDoc> {
        let file: BenchFile = crate::scene::parse_ron(text, path)?;
        Ok(BenchDoc {
            file,
            path: path.to_path_buf(),
            text: Some(text.to_string()),
            edits: Vec::new(),
        })
    }

    /// A bench made in code: errors name the field but no line; relative image paths are
    /// taken relative to `path`'s folder.
    pub fn from_file(file: BenchFile, path: &Path) -> BenchDoc {
        BenchDoc {
            file,
            path: path.to_path_buf(),
            text: None,
            edits: Vec::new(),
        }
    }

    /// The path that names this bench.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The name of the bench in messages and summaries: its path as given, or
    /// [`PAPER_BENCH_NAME`] for the built-in bench.
    pub fn name(&self) -> String {
        self.path.display().to_string()
    }

    /// Whether this is the built-in paper bench ([`BenchDoc::paper`]).
    pub fn is_built_in(&self) -> bool {
        self.path == Path::new(PAPER_BENCH_NAME)
    }

    /// The text the bench was read from (none for a bench made in code).
    pub fn text(&self) -> Option<&str> {
        self.text.as_deref()
    }

    /// The `run.rays` the bench file states, if it states one (a bench made in code states
    /// none): the ray count every command that traces takes unless told otherwise.
    pub fn stated_rays(&self) -> Option<u64> {
        let text = self.text.as_deref()?;
        crate::scene::locate::find_path(text, "run.rays").map(|_| self.file.run.rays)
    }

    /// The variables set since reading, in order.
    pub fn edits(&self) -> &[(String, f64)] {
        &self.edits
    }

    /// Builds and validates the bench.
    pub fn build(&self) -> Result<Bench> {
        build_bench(&self.file, self.text.as_deref(), &self.path).map_err(|e| self.context(e))
    }

    /// Builds the bench with its electronics and run settings, for `spibench run`.
    pub fn run_scene(&self) -> Result<RunScene> {
        run_scene(&self.file, self.text.as_deref(), &self.path).map_err(|e| self.context(e))
    }

    /// Sets a bench variable (a field path or a rigid-body move, see
    /// [`crate::scene::variables`]).
    pub fn set(&mut self, path: &str, value: f64) -> Result<()> {
        crate::scene::variables::set(&mut self.file, path, value)
            .map_err(|e| e.in_file(&self.path))?;
        self.edits.push((path.to_string(), value));
        Ok(())
    }

    /// Selects the DMD's model over the file's `dmd.model`: plane mirrors, or the diffractive
    /// model with the file's own `tail_bin_nm` when the file states one (else its default).
    /// The bench is built from the edited file, so its diffraction tables always follow the
    /// model and every other field. An error names the field `dmd_model`.
    pub fn set_dmd_model(&mut self, model: DmdModel) -> Result<()> {
        let Some(dmd) = self.file.dmd.as_mut() else {
            return Err(Error::field(
                "dmd_model",
                format!("`{}` has no DMD whose model could be chosen", self.name()),
            ));
        };
        dmd.model = match (model, dmd.model) {
            (DmdModel::Geometric, _) => DmdModelSpec::Geometric,
            (DmdModel::Diffractive, m @ DmdModelSpec::Diffractive { .. }) => m,
            (DmdModel::Diffractive, DmdModelSpec::Geometric) => DmdModelSpec::diffractive(),
        };
        Ok(())
    }

    /// The DMD's model as this document builds it; None for a bench without a DMD.
    pub fn dmd_model(&self) -> Option<DmdModel> {
        self.file.dmd.as_ref().map(|d| match d.model {
            DmdModelSpec::Geometric => DmdModel::Geometric,
            DmdModelSpec::Diffractive { .. } => DmdModel::Diffractive,
        })
    }

    /// A copy with the variables set (in order).
    pub fn with(&self, settings: &[(String, f64)]) -> Result<BenchDoc> {
        let mut d = self.clone();
        for (p, v) in settings {
            d.set(p, *v)?;
        }
        Ok(d)
    }

    /// The files this bench reads besides itself (chart mask images, lens prescriptions and
    /// their glass catalogues), as paths resolved against the bench file's folder, in element
    /// order.
    pub fn input_files(&self) -> Vec<PathBuf> {
        use crate::scene::bench::{ChartPatternSpec, ChartSpec, ElementSpec, LensSystemSpec};
        let base = self.path.parent().unwrap_or(Path::new("."));
        self.file
            .elements
            .iter()
            .flat_map(|el| match el {
                ElementSpec::Chart(ChartSpec {
                    pattern: ChartPatternSpec::Image { path, .. },
                    ..
                }) => vec![base.join(path)],
                ElementSpec::LensSystem(LensSystemSpec {
                    zmx,
                    glass_catalogues,
                    ..
                }) => zmx
                    .iter()
                    .chain(glass_catalogues)
                    .map(|p| base.join(p))
                    .collect(),
                _ => Vec::new(),
            })
            .collect()
    }

    /// The glasses this bench's `LensSystem` elements model from their prescriptions' nd and Vd
    /// (allowed by `allow_glass_substitution`), as sentences naming the file and line. Empty
    /// when the lenses cannot be read: building the bench then reports why.
    pub fn glass_substitutions(&self) -> Vec<String> {
        crate::scene::bench::lens_substitutions(&self.file, &self.path)
            .map(|s| s.iter().map(|s| s.to_string()).collect())
            .unwrap_or_default()
    }

    /// The value of a bench variable.
    pub fn get(&self, path: &str) -> Result<f64> {
        crate::scene::variables::get(&self.file, path).map_err(|e| e.in_file(&self.path))
    }

    /// The bench as RON text (every field written, defaults filled in), which every command
    /// reads back into the identical bench.
    pub fn to_ron(&self) -> Result<String> {
        to_ron(&self.file)
    }

    /// Says which variables were set when the error arose, since the file's text no longer
    /// shows the values that were built.
    fn context(&self, e: Error) -> Error {
        if self.edits.is_empty() {
            return e;
        }
        let set: Vec<String> = self
            .edits
            .iter()
            .map(|(p, v)| format!("{p} = {v}"))
            .collect();
        e.with_note(format!("with the bench variables {}", set.join(", ")))
    }
}

impl crate::provenance::Provenance {
    /// The provenance of an output made from the bench `doc` with `seeds`: the bench as the
    /// text it was read from, under its name (so a file's entry is the file's own hash and
    /// size, and the built-in bench's is its text's), and every image it loads, hashed as they
    /// are on disk now. Defined here, beside the document, because `provenance` sits below
    /// `scene` in the module graph.
    pub fn of_bench(doc: &BenchDoc, seeds: &[u64]) -> Result<Self> {
        let p = Self::new(seeds);
        let p = match &doc.text {
            Some(t) => p.text(&doc.name(), t),
            None => p.file(&doc.path)?,
        };
        let mut p = p.files(&doc.input_files())?;
        p.glass_substitutions = doc.glass_substitutions();
        p.dmd_model = doc.dmd_model().map(DmdModel::name);
        Ok(p)
    }
}

/// The canonical RON text of a bench file: every field written, in declaration order.
pub fn to_ron(file: &BenchFile) -> Result<String> {
    let config = ron::ser::PrettyConfig::new()
        .struct_names(false)
        .indentor("    ".to_string())
        .separate_tuple_members(false)
        .enumerate_arrays(false);
    let body = ron::ser::to_string_pretty(file, config)
        .map_err(|e| Error::Numerical(format!("the bench cannot be written as RON: {e}")))?;
    Ok(format!(
        "// A spibench bench file (millimetres and degrees), written by spibench.\n{body}\n"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper_path() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron")
    }

    #[test]
    fn written_bench_reads_back_identically() {
        for name in [
            "paper_bench.ron",
            "fig8_region_b_48.ron",
            "fig8_region_b_96.ron",
            "fig8_region_c_96.ron",
        ] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("scenes")
                .join(name);
            let doc = BenchDoc::read(&path).unwrap();
            let text = doc.to_ron().unwrap();
            let back = BenchDoc::parse(&text, &path).unwrap();
            assert_eq!(back.file, doc.file, "{name}");
            // Written twice, the text is the same: the form is canonical.
            assert_eq!(back.to_ron().unwrap(), text, "{name}");
        }
    }

    #[test]
    fn errors_of_an_edited_bench_name_the_variables() {
        let mut doc = BenchDoc::read(&paper_path()).unwrap();
        doc.build().unwrap();
        // A biconvex lens 10 µm thick: its faces cross, and the build must refuse it.
        doc.set("imaging_lens.thickness_mm", 0.01).unwrap();
        let Err(e) = doc.build() else {
            panic!("a lens whose faces cross was accepted")
        };
        assert!(e.is_user_error());
        let s = e.to_string();
        assert!(s.contains("imaging_lens.thickness_mm = 0.01"), "{s}");
        // The text of the file still locates the field.
        assert!(s.contains("line "), "{s}");
    }
}
