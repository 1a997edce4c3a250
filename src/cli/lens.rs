//! `spibench lens FILE [--wavelength-nm L] [--heights-mm H,…] [--catalogue AGF …]
//! [--allow-glass-substitution] [--out DIR]`: a Zemax prescription's surface table, paraxial
//! EFL, BFL and FFL, and a meridional fan of real rays to the file's image surface
//! (crate::lens::report); with `--out`, `summary.json` and the drawing (crate::outputs::lens).
//!
//! `spibench lens [SCENE] --element NAME [--set PATH=VALUE …]`: the same report of a bench's
//! `Lens` or `LensSystem` element as the bench builds it (its glasses, its substitutions,
//! turned round where the bench turns it), SCENE being a bench file as for every bench
//! command (default: the built-in paper bench).

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::lens::{GlassOptions, LoadedLens, agf::Catalogue, read_zmx, report::report};
use crate::outputs::lens::{LensSummary, printed, write};
use crate::provenance::Provenance;
use crate::report::output::OutputDir;

/// Arguments of `spibench lens`.
#[derive(Debug, Clone, clap::Args)]
pub struct LensArgs {
    /// A sequential Zemax prescription (.zmx); with `--element`, a bench file (default: the
    /// paper's bench built into the binary).
    pub file: Option<PathBuf>,
    /// Report the bench's lens element of this name (a `Lens` or a `LensSystem`) instead of a
    /// prescription file.
    #[arg(long, value_name = "NAME")]
    pub element: Option<String>,
    /// With `--element`: set a bench variable first, e.g. `--set imaging_lens.position_mm.z=200`
    /// (repeatable; paths as in `spibench sweep`).
    #[arg(long = "set", value_name = "PATH=VALUE", requires = "element")]
    pub set: Vec<String>,
    /// Wavelength of the indices (nm).
    #[arg(long, default_value_t = 850.0)]
    pub wavelength_nm: f64,
    /// Heights of the fan's rays (mm), comma-separated (default 0.1, 0.3, 0.5, 0.7 and 0.9 of
    /// the first surface's semi-diameter).
    #[arg(long, value_delimiter = ',', value_name = "H,H,…")]
    pub heights_mm: Option<Vec<f64>>,
    /// A Zemax glass catalogue (.agf) to resolve glass names through, before the built-in
    /// catalogue (repeatable; the file's GCAT order ranks them). A bench element uses the
    /// bench's own `glass_catalogues`.
    #[arg(long = "catalogue", value_name = "AGF", conflicts_with = "element")]
    pub catalogues: Vec<PathBuf>,
    /// Model a glass that no catalogue has from its GLAS line's nd and Vd (always reported). A
    /// bench element follows its own `allow_glass_substitution`.
    #[arg(long, conflicts_with = "element")]
    pub allow_glass_substitution: bool,
    /// Output directory for summary.json and the drawing (lens.svg, lens.png, lens.pdf).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: &LensArgs) -> anyhow::Result<()> {
    let summary = lens(args)?;
    // A bench's substitutions were reported when it was read (`BenchArgs::load`).
    if args.element.is_none() {
        for s in &summary.substitutions {
            eprintln!("warning: {s}");
        }
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

/// The prescription to report, what to call it, and the provenance of its inputs.
fn load(args: &LensArgs) -> Result<(LoadedLens, String, Provenance)> {
    if let Some(name) = &args.element {
        let bench = super::args::BenchArgs {
            scene: args.file.clone(),
            set: args.set.clone(),
            dmd_model: None,
        };
        let doc = bench.load()?;
        let (prescription, substitutions) =
            crate::scene::bench::element_prescription(&doc.file, doc.text(), doc.path(), name)?;
        let loaded = LoadedLens {
            path: doc.path().to_path_buf(),
            prescription,
            substitutions,
            ignored: Vec::new(),
        };
        let label = format!("{}, element {name}", doc.name());
        return Ok((loaded, label, Provenance::of_bench(&doc, &[])?));
    }
    let Some(file) = &args.file else {
        return Err(Error::field(
            "FILE",
            "name a prescription (.zmx), or a bench element with --element NAME",
        ));
    };
    let catalogues = args
        .catalogues
        .iter()
        .map(|p| Catalogue::read(p))
        .collect::<Result<Vec<_>>>()?;
    let glasses = GlassOptions {
        catalogues,
        allow_substitution: args.allow_glass_substitution,
    };
    let loaded = read_zmx(file, &glasses)?;
    let mut inputs = vec![file.clone()];
    inputs.extend(args.catalogues.iter().cloned());
    let provenance = Provenance::new(&[]).files(&inputs)?;
    Ok((loaded, file.display().to_string(), provenance))
}

fn lens(args: &LensArgs) -> Result<LensSummary> {
    let (loaded, label, provenance) = load(args)?;
    let r = report(&loaded, args.wavelength_nm, args.heights_mm.as_deref())?;
    let summary = LensSummary::new(&label, &r);
    let Some(out) = &args.out else {
        return Ok(summary);
    };
    let dir = OutputDir::create(out)?;
    let summary = write(&dir, summary, &loaded.prescription, &provenance)?;
    dir.commit()?;
    Ok(summary)
}
