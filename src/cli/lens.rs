//! `spibench lens FILE [--wavelength-nm L] [--heights-mm H,…] [--catalogue AGF …]
//! [--allow-glass-substitution] [--out DIR]`: a Zemax prescription's surface table, paraxial
//! EFL, BFL and FFL, and a meridional fan of real rays to the file's image surface
//! (crate::lens::report); with `--out`, `summary.json` and the drawing (crate::outputs::lens).

use std::path::PathBuf;

use crate::error::Result;
use crate::lens::{GlassOptions, agf::Catalogue, read_zmx, report::report};
use crate::outputs::lens::{LensSummary, printed, write};
use crate::report::output::OutputDir;

/// Arguments of `spibench lens`.
#[derive(Debug, Clone, clap::Args)]
pub struct LensArgs {
    /// A sequential Zemax prescription (.zmx).
    pub file: PathBuf,
    /// Wavelength of the indices (nm).
    #[arg(long, default_value_t = 850.0)]
    pub wavelength_nm: f64,
    /// Heights of the fan's rays (mm), comma-separated (default 0.1, 0.3, 0.5, 0.7 and 0.9 of
    /// the first surface's semi-diameter).
    #[arg(long, value_delimiter = ',', value_name = "H,H,…")]
    pub heights_mm: Option<Vec<f64>>,
    /// A Zemax glass catalogue (.agf) to resolve glass names through, before the built-in
    /// catalogue (repeatable; the file's GCAT order ranks them).
    #[arg(long = "catalogue", value_name = "AGF")]
    pub catalogues: Vec<PathBuf>,
    /// Model a glass that no catalogue has from its GLAS line's nd and Vd (always reported).
    #[arg(long)]
    pub allow_glass_substitution: bool,
    /// Output directory for summary.json and the drawing (lens.svg, lens.png, lens.pdf).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: &LensArgs) -> anyhow::Result<()> {
    let summary = lens(args)?;
    for s in &summary.substitutions {
        eprintln!("warning: {s}");
    }
    println!("{}", printed(&summary));
    if let Some(out) = &args.out {
        println!(
            "wrote {}/summary.json, lens.svg, lens.png and lens.pdf",
            out.display()
        );
    }
    Ok(())
}

fn lens(args: &LensArgs) -> Result<LensSummary> {
    let catalogues = args
        .catalogues
        .iter()
        .map(|p| Catalogue::read(p))
        .collect::<Result<Vec<_>>>()?;
    let glasses = GlassOptions {
        catalogues,
        allow_substitution: args.allow_glass_substitution,
    };
    let loaded = read_zmx(&args.file, &glasses)?;
    let r = report(&loaded, args.wavelength_nm, args.heights_mm.as_deref())?;
    let summary = LensSummary::new(&args.file.display().to_string(), &r);
    let Some(out) = &args.out else {
        return Ok(summary);
    };
    let mut inputs = vec![args.file.clone()];
    inputs.extend(args.catalogues.iter().cloned());
    let provenance = crate::provenance::Provenance::new(&[]).files(&inputs)?;
    let dir = OutputDir::create(out)?;
    let summary = write(&dir, summary, &loaded.prescription, &provenance)?;
    dir.commit()?;
    Ok(summary)
}
