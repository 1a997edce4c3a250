//! `spibench check [SCENE] [--set PATH=VALUE …] [--wavelength-nm L] [--footprint-rays N]
//! [--seed S] [--out DIR]`: reads and validates a bench, prints its paraxial design numbers
//! (crate::trace::paraxial), the DMD model they are for, and beside the paraxial beam on each
//! diode a short traced footprint (crate::outputs::check::footprint; `--footprint-rays 0`
//! traces nothing). With `--out`, the same numbers go to `DIR/check.json` (SI, unit-suffixed
//! keys; crate::outputs::check); without it nothing is written.

use std::path::PathBuf;

use crate::outputs::check::{CheckJson, DEFAULT_FOOTPRINT_RAYS, footprint, printed, report, write};
use crate::report::output::OutputDir;
use crate::trace::fan::DESIGN_WAVELENGTH_M;

/// Arguments of `spibench check`.
#[derive(Debug, Clone, clap::Args)]
pub struct CheckArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    /// Design wavelength of the paraxial numbers (nm); default 850 nm, the photocurrent's
    /// spectral centroid for a tungsten lamp on silicon without ND filters. On the paper bench,
    /// whose ND filters pass the near infrared, the centroid is about 947 nm (near the DMD's
    /// 984 nm blaze; docs/dmd_diffraction.md): pass --wavelength-nm 947 for those numbers.
    #[arg(long, default_value_t = DESIGN_WAVELENGTH_M * 1e9)]
    pub wavelength_nm: f64,
    /// Lamp rays of the traced footprint on each diode (centroid, RMS radius, spill, each with
    /// its standard error from 8 replicas), printed beside the paraxial beam; 0 traces
    /// nothing; otherwise at least 2048 (two batches).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_FOOTPRINT_RAYS)]
    pub footprint_rays: u64,
    /// Seed of the footprint's random streams (same seed, same footprint, on any number of
    /// threads).
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// Write `check.json` into this directory (nothing is written without it).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// Runs `spibench check`.
pub fn run(args: &CheckArgs) -> anyhow::Result<()> {
    let doc = args.bench.load()?;
    let bench = doc.build()?;
    let paraxial = report(&doc, &bench, args.wavelength_nm * 1e-9)?;
    let rays = args.footprint_rays;
    args.work.check(&super::args::Work {
        rays: rays as f64,
        what: format!("{rays} footprint rays"),
        ..Default::default()
    })?;
    let traced = footprint(&bench, &paraxial, rays, args.seed)?;
    let report = CheckJson::new(&doc, paraxial, traced);
    if let Some(out) = &args.out {
        let dir = OutputDir::create(out)?;
        write(&dir, &report)?;
        dir.commit()?;
    }
    for line in printed(&report) {
        println!("{line}");
    }
    Ok(())
}
