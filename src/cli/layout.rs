//! `spibench layout [SCENE] [--set PATH=VALUE …] [--rays N] [--irradiance-rays N] [--seed S]
//! [--out DIR]`: draws the bench as a lens designer's 2-D layout (top view, side view, the plane
//! of the two arms) with a fan of traced rays coloured by fate (with `--irradiance-rays`, and
//! under the views each diode's traced irradiance map as an inset), and writes `DIR/layout.svg`, `DIR/layout.png` (the same
//! drawing, rendered by resvg at 288 dpi) and `DIR/layout.pdf`, 7.2 in wide (a double-column
//! figure), through a staged output directory (crate::outputs::layout).

use crate::error::Error;
use crate::outputs::layout::{Insets, figure, printed, write_figure};
use crate::report::output::OutputDir;
use crate::trace::fan::{DEFAULT_FAN_RAYS, ray_fan};

/// Arguments of `spibench layout`.
///
/// `--rays` counts the rays of the drawn fan (1 to 10⁶, checked by `trace::fan::ray_fan`),
/// not of a trace, so the bench file's `run.rays` does not set it.
#[derive(Debug, Clone, clap::Args)]
#[command(
    mut_arg("rays", |a| a.default_value("400").help(
        "Lamp rays in the fan (half traced with every pattern unit in state +, half in state −)"
    )),
    mut_arg("seed", |a| a.default_value("1").help("Seed of the fan's random streams")),
    mut_arg("out", |a| a.default_value("out/layout").help("Output directory")),
)]
pub struct LayoutArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
    /// Lamp rays of a trace that maps the light on the two diodes, drawn as insets under the
    /// views (each diode's map with every unit in its own arm's state, its spill and centroid
    /// with standard errors); 0: no insets. 200000 gives a map worth reading (a few seconds on
    /// two cores); at least 2048, two batches
    #[arg(long = "irradiance-rays", value_name = "N", default_value_t = 0)]
    pub irradiance_rays: u64,
}

// The fan's default as `--help` shows it.
const _: () = assert!(DEFAULT_FAN_RAYS == 400);

/// Runs `spibench layout`.
pub fn run(args: &LayoutArgs) -> anyhow::Result<()> {
    let doc = args.bench.load()?;
    let bench = doc.build()?;
    if bench.dmd().is_none() {
        return Err(Error::field("dmd", "`layout` needs a bench with a DMD")
            .in_file(doc.path())
            .into());
    }
    let rays = args.opts.rays.map_or(DEFAULT_FAN_RAYS, |r| {
        usize::try_from(r).unwrap_or(usize::MAX)
    });
    let out = args.opts.out_or("out/layout");
    let fan = ray_fan(&bench, rays, args.opts.seed())?;
    // The maps' trace is checked (and traced) before anything is written.
    let insets = match args.irradiance_rays {
        0 => None,
        n => Some(Insets::trace(&bench, n, args.opts.seed())?),
    };
    // The file's name as the drawing's title; the built-in bench by its name.
    let title = match doc.path().file_name() {
        Some(n) if !doc.is_built_in() => n.to_string_lossy().into_owned(),
        _ => doc.name(),
    };
    let svg = figure(&bench, &fan, &title, insets.as_ref()).map_err(|e| e.in_file(doc.path()))?;
    let dir = OutputDir::create(&out)?;
    write_figure(&svg, &dir)?;
    dir.commit()?;
    println!("{}", printed(&doc.name(), &fan, insets.as_ref(), &out));
    Ok(())
}
