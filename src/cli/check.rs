//! `spibench check [SCENE] [--set PATH=VALUE …] [--wavelength-nm L] [--out DIR]`: reads and
//! validates a bench without tracing it and prints its paraxial design numbers
//! (crate::trace::paraxial). With `--out`, the same numbers go to `DIR/check.json` (SI,
//! unit-suffixed keys; crate::outputs::check); without it nothing is written.

use std::path::PathBuf;

use crate::outputs::check::{printed, report, write};
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
    let report = report(&doc, &bench, args.wavelength_nm * 1e-9)?;
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
