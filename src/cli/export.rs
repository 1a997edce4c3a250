//! `spibench export-mitsuba [SCENE] [--set PATH=VALUE …] --out DIR [--pattern SPEC]
//! [--wavelength-nm NM] [--as-is]`: the bench as a Mitsuba 3 scene (mitsuba==3.9.1).
//!
//! By default the monochromatic, constant-index substitute at `--wavelength-nm` (850 nm) is
//! exported (crate::optics::monochromatic): every change it makes is printed and written to
//! `substitutions.txt`. `--as-is` exports the bench unchanged and fails, naming the element, if
//! Mitsuba cannot represent it. Output (DIR): `scene.xml`, `meshes/*.ply`, `charts/*.pfm`,
//! `manifest.json`, `substitutions.txt` and `summary.json` (crate::outputs::export), written
//! into a staging directory and moved into place only when everything succeeded. Mitsuba cannot model the DMD's diffraction:
//! a bench with `model: Diffractive` is exported with geometric mirrors and a note saying so
//! (`--as-is` refuses it).

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::export::{DmdPattern, ExportOptions, export_mitsuba};
use crate::optics::monochromatic::{MonochromaticOptions, monochromatic};
use crate::outputs::export::{DIFFRACTION_NOTE, ExportSummary, write};
use crate::report::output::OutputDir;

/// Arguments of `spibench export-mitsuba`.
#[derive(Debug, Clone, clap::Args)]
pub struct ExportArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// DMD pattern: all-plus, all-minus, random:SEED, complement-random:SEED, or a .npy file of
    /// 0/1 unit states (row-major).
    #[arg(long, default_value = "all-plus")]
    pub pattern: String,
    /// Wavelength of the monochromatic, constant-index substitute (nm).
    #[arg(long, default_value_t = 850.0)]
    pub wavelength_nm: f64,
    /// Export the bench unchanged (fails if Mitsuba cannot represent it).
    #[arg(long)]
    pub as_is: bool,
    /// Keep the lamp's graybody spectrum and the responsivity tables (for a spectral render;
    /// implies --as-is).
    #[arg(long)]
    pub spectral: bool,
    /// Samples per irradiancemeter for Mitsuba's own `path` integrator.
    #[arg(long, default_value_t = 1_000_000)]
    pub sensor_samples: u32,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

pub fn run(args: &ExportArgs) -> anyhow::Result<()> {
    let summary = export(args)?;
    for n in &summary.substitutions {
        println!("substitute: {n}");
    }
    println!(
        "exported {} ({} files, pattern {}) to {}",
        summary.scene,
        summary.files.len(),
        summary.pattern,
        args.out.display()
    );
    Ok(())
}

fn export(args: &ExportArgs) -> Result<ExportSummary> {
    let doc = args.bench.load()?;
    let bench = doc.build()?;
    let diffractive = bench.dmd().is_some_and(|s| s.dmd.diffraction().is_some());
    if diffractive && args.as_is {
        return Err(Error::field(
            "dmd.model",
            "Mitsuba cannot model the DMD's diffraction: export without --as-is (the scene's \
             mirrors then reflect geometrically) or set `model: Geometric`",
        )
        .in_file(doc.path()));
    }
    let spec = args
        .pattern
        .parse::<DmdPattern>()
        .map_err(|e| e.at_field("--pattern"))?;
    let base = std::env::current_dir().unwrap_or_default();
    let bits = spec.bits(bench.units(), &base)?;
    let (bench, notes, wl) = if args.as_is || args.spectral {
        (bench, Vec::new(), None)
    } else {
        // The substitute stands for the traced bench at one wavelength: outside the band the
        // bench traces, its indices and spectra are extrapolations nobody asked for.
        let (lo, hi) = bench.band();
        let (lo_nm, hi_nm) = (lo * 1e9, hi * 1e9);
        let nm = args.wavelength_nm;
        if !(nm.is_finite() && nm >= lo_nm - 1e-9 && nm <= hi_nm + 1e-9) {
            return Err(Error::field(
                "--wavelength-nm",
                format!(
                    "{nm} nm is outside the traced band of {} ({lo_nm:.0}–{hi_nm:.0} nm)",
                    doc.name()
                ),
            ));
        }
        let m = monochromatic(&bench, &MonochromaticOptions::at_nm(args.wavelength_nm))
            .map_err(|m| Error::field("--wavelength-nm", m))?;
        (m.bench, m.notes, Some(m.wavelength_m))
    };
    if args.sensor_samples == 0 {
        return Err(Error::field("--sensor-samples", "must be at least 1"));
    }
    let scene = export_mitsuba(
        &bench,
        &ExportOptions {
            pattern: bits,
            pattern_label: spec.label(),
            wavelength_m: wl,
            sensor_samples: args.sensor_samples,
            spectral: args.spectral,
        },
    )
    .map_err(|e| e.in_file(doc.path()))?;
    let mut substitutions = notes;
    if diffractive {
        substitutions.insert(0, DIFFRACTION_NOTE.to_string());
    }
    substitutions.extend(scene.notes.iter().cloned());
    let summary = ExportSummary {
        scene: doc.name(),
        pattern: spec.label(),
        wavelength_nm: wl.map(|w| w * 1e9),
        substitutions,
        files: Vec::new(),
    };
    let provenance = crate::provenance::Provenance::of_bench(&doc, &[])?;
    let dir = OutputDir::create(&args.out)?;
    let summary = write(&dir, &scene, summary, &provenance)?;
    dir.commit()?;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("spibench-export-{}-{name}", std::process::id()))
    }

    fn args(scene: PathBuf, out: PathBuf, pattern: &str) -> ExportArgs {
        ExportArgs {
            bench: crate::cli::args::BenchArgs {
                scene: Some(scene),
                set: Vec::new(),
                dmd_model: None,
            },
            out,
            pattern: pattern.into(),
            wavelength_nm: 850.0,
            as_is: false,
            spectral: false,
            sensor_samples: 1000,
            work: Default::default(),
        }
    }

    /// Mitsuba cannot model the DMD's diffraction: the export says so, and `--as-is` refuses.
    #[test]
    fn diffractive_benches_are_exported_geometric_with_a_note() {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(root.join("scenes/tests/symmetric_arms.ron"))
            .unwrap()
            .replace("model: Geometric,", "model: Diffractive(),");
        let dir = tmp("diffractive");
        std::fs::create_dir_all(&dir).unwrap();
        let scene = dir.join("bench.ron");
        std::fs::write(&scene, text).unwrap();
        let out = dir.join("out");
        let s = export(&args(scene.clone(), out.clone(), "all-plus")).unwrap();
        assert!(
            s.substitutions[0].contains("Mitsuba cannot model the DMD's diffraction"),
            "{:?}",
            s.substitutions
        );
        let mut a = args(scene, dir.join("as-is"), "all-plus");
        a.as_is = true;
        let e = export(&a).unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("dmd.model"),
            "{e}"
        );
        assert!(!dir.join("as-is").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn exports_a_bench_and_refuses_bad_input_without_output() {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let out = tmp("ok");
        let s = export(&args(
            root.join("scenes/tests/symmetric_arms.ron"),
            out.clone(),
            "random:3",
        ))
        .unwrap();
        assert!(out.join("scene.xml").exists() && out.join("manifest.json").exists());
        assert!(s.files.iter().any(|f| f.contains("dmd_mirrors")));
        // Tungsten lamp, N-BK7 and the Si table are substituted and said so.
        assert!(s.substitutions.iter().any(|n| n.contains("arm_plus_lens")));
        let _ = std::fs::remove_dir_all(&out);
        // A bad pattern and --as-is on a dispersive bench: input errors, no output directory.
        let bad = tmp("bad");
        let e = export(&args(
            root.join("scenes/tests/symmetric_arms.ron"),
            bad.clone(),
            "stripes",
        ))
        .unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("pattern"),
            "{e}"
        );
        let mut a = args(
            root.join("scenes/tests/symmetric_arms.ron"),
            bad.clone(),
            "all-plus",
        );
        a.as_is = true;
        let e = export(&a).unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("dispersive"),
            "{e}"
        );
        assert!(!bad.exists());
    }
}
