//! `spibench sweep [SCENE] --vary PATH=START:STOP:N [--vary …] [--set PATH=VALUE …] [--rays N]
//! [--seed S] [--quality] [--limit METRIC=VALUE …] [--out DIR]`: one bench over a 1-D or 2-D
//! grid of bench variables, every point traced with the same seed (common random numbers), so
//! that each point's difference from the nominal bench carries a paired standard error far
//! below that of independent runs (crate::sweep). The files are crate::outputs::sweep's.

use anyhow::Result;
use clap::Args;

use crate::outputs::sweep::{printed, write};
use crate::report::output::OutputDir;
use crate::sweep::limits::{MetricLimit, report};
use crate::sweep::{SweepOptions, Vary, sweep};

/// Arguments of `spibench sweep`.
#[derive(Debug, Clone, Args)]
#[command(
    mut_arg("rays", |a| a.help(super::args::rays_help("Lamp rays per grid point", DEFAULT_RAYS))),
    mut_arg("seed", |a| a.default_value("1")
        .help("Seed of every point's trace (the same for all: common random numbers)")),
    mut_arg("set", |a| a.help("Set a bench variable of the nominal bench first (repeatable)")),
    mut_arg("out", |a| a.default_value("out/sweep")),
)]
pub struct SweepArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    /// A variable and its grid, PATH=START:STOP:N (N values, both ends included); once for a
    /// 1-D sweep, twice for a 2-D grid. PATH is a bench variable such as
    /// `detectors.minus.position_mm.x`, `arm_minus_lens.despace_mm` or `dmd.tilt_deg`.
    #[arg(long, value_name = "PATH=START:STOP:N", required = true)]
    pub vary: Vec<String>,
    // The whole pipeline on every point; the help counts the schemes from their table.
    #[arg(long, help = super::help::sweep_quality_help())]
    pub quality: bool,
    /// A limit on |METRIC| (e.g. `imbalance=0.01`; repeatable, 1-D sweeps): where along the
    /// variable the metric crosses it, with a 95 % interval from the points' standard errors
    /// (printed, in the report and in summary.json's `limits`).
    #[arg(long, value_name = "METRIC=VALUE")]
    pub limit: Vec<String>,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// `sweep`'s ray count per point when neither `--rays` nor the bench file's `run.rays` gives
/// one.
pub const DEFAULT_RAYS: u64 = 500_000;

/// Runs `spibench sweep`.
pub fn run(args: &SweepArgs) -> Result<()> {
    let doc = args.bench.load()?;
    let name = doc.name();
    let vary: Vec<Vary> = args
        .vary
        .iter()
        .map(|v| Vary::parse(v))
        .collect::<crate::Result<_>>()?;
    let opts = &args.opts;
    let (rays, seed) = (opts.rays(&doc, DEFAULT_RAYS)?, opts.seed());
    let limits: Vec<MetricLimit> = args
        .limit
        .iter()
        .map(|l| MetricLimit::parse(l, args.quality))
        .collect::<crate::Result<_>>()?;
    if !limits.is_empty() && vary.len() != 1 {
        return Err(crate::Error::field(
            "--limit",
            "a crossing is found along one variable: give one --vary",
        )
        .into());
    }
    // Unknown paths fail here, before anything is traced.
    let nominal_values: Vec<f64> = vary
        .iter()
        .map(|v| doc.get(&v.path))
        .collect::<crate::Result<_>>()?;
    let grid: Vec<String> = vary.iter().map(|v| v.n.to_string()).collect();
    let traces = vary.iter().map(|v| v.n as f64).product::<f64>() + 1.0;
    args.work.check(&super::args::Work {
        rays: traces * rays as f64,
        what: format!(
            "{} points and the nominal bench × {rays} rays",
            grid.join(" × ")
        ),
        ..Default::default()
    })?;
    let out = OutputDir::create(&opts.out_or("out/sweep"))?;
    let options = SweepOptions {
        rays,
        seed,
        quality: args.quality,
    };
    let points: usize = vary.iter().map(|v| v.n).product();
    eprintln!(
        "{name}: sweep of {points} point(s) + the nominal bench, {} rays each (seed {}){}",
        rays,
        seed,
        if args.quality { ", full pipeline" } else { "" }
    );
    let bar = super::progress::bar(points as u64 + 1, "points");
    let start = std::time::Instant::now();
    let s = sweep(&doc, &vary, &options, &|done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let bench = doc.build()?;
    let provenance = crate::provenance::Provenance::of_bench(&doc, &[seed])?;
    let crossed = limits
        .iter()
        .map(|l| report(l, &s))
        .collect::<crate::Result<Vec<_>>>()?;
    let (files, card) = write(
        &name,
        &bench,
        &s,
        &nominal_values,
        &crossed,
        &provenance,
        &out,
    )?;
    let dir = out.commit()?;
    for line in card.printed() {
        println!("{line}");
    }
    for line in printed(&s, &crossed) {
        println!("{line}");
    }
    println!(
        "wrote {} ({} files, {:.1} s)",
        dir.display(),
        files,
        seconds
    );
    Ok(())
}
