//! `spibench fit [BENCH] --measured DIR --free PATH=LO:HI [--free …] [--adjust PATH=LO:HI …]
//! [--imbalance-limit L] [--gain-tolerance T|free] [--rays N] [--seed S] [--out DIR]`: the bench as built, the free
//! variables fitted to an `intake` folder's frames (crate::fit: Levenberg–Marquardt on
//! common-random-number traces, the nuisances profiled out), their uncertainty and
//! identifiability, and the compensators that rebalance it. The files are
//! crate::outputs::fit's.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::fit::{FitRequest, MAX_ITERATIONS, fit, identify::SCAN_POINTS, read_measured};
use crate::pipeline::optimise::Free;
use crate::report::output::OutputDir;

/// Arguments of `spibench fit`.
#[derive(Debug, Clone, Args)]
#[command(
    mut_arg("rays", |a| a.help(super::args::rays_help(
        "Lamp rays of the last stage (the first traces a quarter)", DEFAULT_RAYS))),
    mut_arg("seed", |a| a.default_value("1")),
    mut_arg("set", |a| a.help("Set a variable of the nominal bench first (repeatable)")),
    mut_arg("out", |a| a.default_value("out/fit")),
)]
pub struct FitArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    /// The measurements: an `intake` output folder (its `summary.json` and `frames.csv`,
    /// the calibrated sequence among its records).
    #[arg(long, value_name = "DIR", required = true)]
    pub measured: PathBuf,
    /// A variable to fit and its bounds, PATH=LO:HI; the nominal bench's value must lie within
    /// (a rigid-body move such as `arm_plus_lens.decenter_mm.x` starts at 0).
    #[arg(long, value_name = "PATH=LO:HI", required = true)]
    pub free: Vec<String>,
    /// A compensator the user can turn, PATH=LO:HI: the fitted bench is rebalanced with these.
    #[arg(long, value_name = "PATH=LO:HI")]
    pub adjust: Vec<String>,
    /// The |electrical imbalance| ι′ (the diodes' responsivity scales included, as the tolerance
    /// yield judges it) the adjustment must bring the fitted bench under.
    #[arg(long, default_value_t = 0.01, value_name = "L")]
    pub imbalance_limit: f64,
    /// How well the detector's four channel gains (RF on each diode, each monitor) are known
    /// about the lamp's unknown power: a relative standard deviation, or `free` to fit each
    /// channel's scale without a prior (the frames then fix only the shape of each arm's
    /// collection, not the arms' ratio).
    #[arg(long, default_value = "0.05", value_name = "FRACTION|free")]
    pub gain_tolerance: String,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// `fit`'s ray count when neither `--rays` nor the bench file's `run.rays` gives one.
pub const DEFAULT_RAYS: u64 = 200_000;

/// fit's total work, bounded above: two stages of at most [`MAX_ITERATIONS`] iterations, each a
/// Jacobian (one trace per variable) and up to six trial steps, the final Jacobian, a scan of
/// every direction, and the adjustment's search (40 per compensator) with two evaluations.
fn work(free: usize, adjust: usize, rays: u64) -> super::args::Work {
    let traces = 3
        + 2 * (1 + MAX_ITERATIONS * (free + 6))
        + free
        + SCAN_POINTS * free
        + if adjust > 0 { 40 * adjust + 2 } else { 0 };
    super::args::Work {
        rays: traces as f64 * rays as f64,
        what: format!("up to {traces} traces × {rays} rays"),
        ..Default::default()
    }
}

fn parse_free(v: &[String], flag: &str) -> crate::Result<Vec<Free>> {
    v.iter()
        .map(|f| Free::parse(f).map_err(|e| e.at_field(flag)))
        .collect()
}

/// `--gain-tolerance`: a relative standard deviation in (0, 1], or `free`.
fn parse_gain_tolerance(v: &str) -> crate::Result<Option<f64>> {
    if v.trim() == "free" {
        return Ok(None);
    }
    match v.trim().parse::<f64>() {
        Ok(t) if t.is_finite() && t > 0.0 && t <= 1.0 => Ok(Some(t)),
        _ => Err(crate::Error::field(
            "--gain-tolerance",
            format!("must be a relative standard deviation in (0, 1] or `free`, got `{v}`"),
        )),
    }
}

/// Runs `spibench fit`.
pub fn run(args: &FitArgs) -> Result<()> {
    let doc = args.bench.load()?;
    let free = parse_free(&args.free, "--free")?;
    let adjust = parse_free(&args.adjust, "--adjust")?;
    for f in free.iter().chain(&adjust) {
        doc.get(&f.path)?;
    }
    let limit = args.imbalance_limit;
    if !(limit.is_finite() && limit > 0.0) {
        return Err(crate::Error::field(
            "--imbalance-limit",
            format!("must be a positive number, got {limit}"),
        )
        .into());
    }
    let gain_tolerance = parse_gain_tolerance(&args.gain_tolerance)?;
    let rays = args.opts.rays(&doc, DEFAULT_RAYS)?;
    crate::pipeline::optimise::check_start(&doc, &free, true)?;
    if !adjust.is_empty() {
        crate::pipeline::optimise::check_start(&doc, &adjust, true)?;
    }
    let measured = read_measured(&args.measured)?;
    crate::fit::check_measured(&doc, &measured)?;
    args.work.check(&work(free.len(), adjust.len(), rays))?;
    let req = FitRequest {
        free,
        adjust,
        imbalance_limit: limit,
        gain_tolerance,
        rays,
        seed: args.opts.seed(),
    };
    let out = OutputDir::create(&args.opts.out_or("out/fit"))?;
    let bar = super::progress::bar(
        (3 + 2 * (1 + MAX_ITERATIONS * (req.free.len() + 6))) as u64,
        "traces",
    );
    let f = fit(&doc, &measured, &req, &|n| bar.set_position(n as u64))?;
    bar.finish_and_clear();
    let mut provenance = crate::provenance::Provenance::of_bench(&doc, &[req.seed])?;
    for name in ["summary.json", "frames.csv"] {
        provenance = provenance.file(&args.measured.join(name))?;
    }
    let files = crate::outputs::fit::write(&f, &doc, &measured, &provenance, &out)?;
    let dir = out.commit()?;
    for line in crate::outputs::fit::printed(&f, &doc, &measured) {
        println!("{line}");
    }
    println!("wrote {} ({} files)", dir.display(), files.len());
    Ok(())
}
