//! `spibench layout BENCH [--rays N] [--seed S] [--out DIR]`: draws the bench as a lens
//! designer's 2-D layout (top view, side view, the plane of the two arms) with a fan of traced
//! rays coloured by fate, and writes `DIR/layout.svg`, `DIR/layout.png` (the same drawing,
//! rendered by resvg at 288 dpi) and `DIR/layout.pdf`, 7.2 in wide (a double-column figure),
//! through a staged output directory.

use std::path::PathBuf;

use crate::error::Error;
use crate::report::layout::layout_svg;
use crate::report::outline::outline_text;
use crate::report::output::OutputDir;
use crate::report::svg::{at_print_size, write_figure};
use crate::scene::bench::read_bench;
use crate::trace::fan::{DEFAULT_FAN_RAYS, Fate, ray_fan};

/// Arguments of `spibench layout`.
///
/// `--rays` counts the rays of the drawn fan (1 to 10⁶, checked by `trace::fan::ray_fan`),
/// not of a trace.
#[derive(Debug, Clone, clap::Args)]
#[command(
    mut_arg("rays", |a| a.default_value("400").help(
        "Lamp rays in the fan (half traced with every pattern unit in state +, half in state −)"
    )),
    mut_arg("seed", |a| a.default_value("1").help("Seed of the fan's random streams")),
    mut_arg("out", |a| a.default_value("out/layout").help("Output directory")),
)]
pub struct LayoutArgs {
    /// Bench file (RON).
    pub scene: PathBuf,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

// The fan's default as `--help` shows it.
const _: () = assert!(DEFAULT_FAN_RAYS == 400);

/// Runs `spibench layout`.
pub fn run(args: &LayoutArgs) -> anyhow::Result<()> {
    let bench = read_bench(&args.scene)?;
    if bench.dmd().is_none() {
        return Err(Error::field("dmd", "`layout` needs a bench with a DMD")
            .in_file(&args.scene)
            .into());
    }
    let rays = args.opts.rays.map_or(DEFAULT_FAN_RAYS, |r| {
        usize::try_from(r).unwrap_or(usize::MAX)
    });
    let out = args.opts.out_or("out/layout");
    let fan = ray_fan(&bench, rays, args.opts.seed())?;
    let title = args.scene.file_name().map_or_else(
        || args.scene.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let svg = layout_svg(&bench, &fan, &title)
        .and_then(|svg| outline_text(&svg))
        .map_err(|e| e.in_file(&args.scene))?;
    let dir = OutputDir::create(&out)?;
    write_figure(&svg, &dir.path("layout.svg"), &dir.path("layout.png"), true)?;
    dir.commit()?;
    let counts = fan.counts();
    let fates: Vec<String> = Fate::ALL
        .iter()
        .zip(counts)
        .filter(|(_, n)| *n > 0)
        .map(|(f, n)| format!("{} {n}", f.label()))
        .collect();
    println!(
        "{}: {} rays ({}); wrote {}/layout.svg, layout.png and layout.pdf",
        args.scene.display(),
        fan.rays.len(),
        fates.join(", "),
        out.display()
    );
    Ok(())
}

/// The bench's layout (three views with a ray fan of [`DEFAULT_FAN_RAYS`] rays, seed 1) as a
/// report block, and the SVG text to write beside the report.
pub(super) fn layout_block(
    bench: &crate::optics::Bench,
    title: &str,
) -> crate::Result<(crate::report::html::Block, String)> {
    let fan = ray_fan(bench, DEFAULT_FAN_RAYS, 1)?;
    let svg = at_print_size(&outline_text(&layout_svg(bench, &fan, title)?)?)?;
    Ok((
        crate::report::html::Block::Svg {
            caption: format!(
                "The bench: top view, side view and the plane of the two arms, with {} lamp rays \
                 coloured by fate (layout.svg).",
                fan.rays.len()
            ),
            svg: svg.clone(),
        },
        svg,
    ))
}
