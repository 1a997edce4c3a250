//! `spibench align [SCENE] --free PATH=LO:HI [--free …] --objective balance|power|weighted|centre
//! [--weight METRIC=W …] [--rays N] [--start-rays N] [--seed S] [--out DIR]`: the free bench
//! variables that optimise an objective (crate::align: Nelder–Mead on common-random-number
//! traces, the ray count raised as it converges).
//!
//! The files (`aligned.ron`, `summary.json`, the convergence history, the layouts before and
//! after, `report.html`) are crate::outputs::align's.

use anyhow::Result;
use clap::{Args, ValueEnum};

use crate::align::{AlignOptions, Free, Objective, align};
use crate::outputs::align::{AlignRun, printed, write};
use crate::quantities::BenchMetric;
use crate::report::output::OutputDir;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObjectiveArg {
    /// Minimise the detector's |imbalance| (electrical: the diodes' responsivity scales
    /// included; plus --offset-weight × |b₋ − b₊|/(b₊ + b₋) when given) with k± held at
    /// --min-fraction of their best.
    Balance,
    /// Maximise k₊ + k₋.
    Power,
    /// Minimise Σ W·METRIC over the --weight flags.
    Weighted,
    /// Centre each diode on its arm's spot: maximise the two margins, active radius −
    /// (centroid offset + 2 RMS radii) of the pattern light on the active area (the light
    /// collected; not the housing plate's, where the diffractive DMD's other orders land), from
    /// the irradiance maps, the smaller weighted 3 times the larger. The robust choice where the imbalance is flat (the whole spot on the diode
    /// over a range of positions).
    Centre,
}

/// Arguments of `spibench align`.
#[derive(Debug, Clone, Args)]
#[command(
    mut_arg("rays", |a| a.help(super::args::rays_help(
        "Lamp rays of the last stage (and of the reported benches)", DEFAULT_RAYS))),
    mut_arg("seed", |a| a.default_value("1")),
    mut_arg("set", |a| a.help("Set a bench variable of the starting bench first (repeatable)")),
    mut_arg("out", |a| a.default_value("out/align")),
)]
pub struct AlignArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    /// A free variable and its bounds, PATH=LO:HI (the variable's values; a rigid-body move
    /// such as `detectors.minus.decenter_mm.x` starts at 0).
    #[arg(long, value_name = "PATH=LO:HI", required = true)]
    pub free: Vec<String>,
    /// What the free variables optimise.
    #[arg(long, value_enum, default_value = "balance")]
    pub objective: ObjectiveArg,
    /// For `balance`: the fraction of their best that k₊ and k₋ must keep.
    #[arg(long, default_value_t = 0.9)]
    pub min_fraction: f64,
    /// For `balance`: the weight of the offset term |b₋ − b₊|/(b₊ + b₋) (default 0: balance
    /// is the imbalance alone; the offset is usually out of reach of the arm knobs).
    #[arg(long, default_value_t = 0.0, value_name = "W")]
    pub offset_weight: f64,
    /// For `weighted`: METRIC=W (repeatable), e.g. `imbalance=1`, `k_prime=-1`.
    #[arg(long, value_name = "METRIC=W")]
    pub weight: Vec<String>,
    /// Lamp rays of the first stage (default: --rays / 16).
    #[arg(long)]
    pub start_rays: Option<u64>,
    /// The most traced evaluations of the search (at least the free variables + 2; the final
    /// comparison and the uncertainty probes add up to 4 + 2 × free variables).
    #[arg(long, default_value_t = 200)]
    pub max_evaluations: usize,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// `align`'s ray count of the last stage when neither `--rays` nor the bench file's `run.rays`
/// gives one.
pub const DEFAULT_RAYS: u64 = 200_000;

/// The first stage's rays (`--start-rays`, default --rays / 16 but at least two batches),
/// with `--start-rays` and `--max-evaluations` checked: a value the search cannot use is an
/// input error, not silently changed.
fn check_counts(args: &AlignArgs, free: usize, rays: u64) -> crate::Result<u64> {
    let min_rays = 2 * crate::trace::RAYS_PER_BATCH;
    if args.max_evaluations < free + 2 {
        return Err(crate::Error::field(
            "--max-evaluations",
            format!(
                "{} is too few: a simplex of {free} free variable(s) and one step need at least {}",
                args.max_evaluations,
                free + 2
            ),
        ));
    }
    match args.start_rays {
        Some(r) if r < min_rays || r > rays => Err(crate::Error::field(
            "--start-rays",
            format!(
                "{r} must lie between {min_rays} (two batches, for a standard error) and --rays \
                 ({rays})"
            ),
        )),
        Some(r) => Ok(r),
        None => Ok((rays / 16).clamp(min_rays.min(rays), rays)),
    }
}

/// The objective's weights within ±[`crate::checked::MAX_SCALAR`] (10¹⁵), as every weight of an
/// input file: a weight of 10³⁰⁸ is finite, but its squared standard errors overflow.
fn check_weights(weights: impl IntoIterator<Item = (&'static str, f64)>) -> crate::Result<()> {
    let max = crate::checked::MAX_SCALAR;
    match weights
        .into_iter()
        .find(|(_, w)| !(w.is_finite() && w.abs() <= max))
    {
        Some((flag, w)) => Err(crate::Error::field(
            flag,
            format!("a weight must be a finite number within ±{max:e}, got {w:e}"),
        )),
        None => Ok(()),
    }
}

/// align's total work, bounded above: the search's first trace and each of its evaluations at
/// up to the last stage's rays, the final comparison ([`crate::align::CANDIDATES`] points) and
/// the uncertainty probes (two per free variable) at twice those rays, and the start and the
/// result at the last stage's rays.
fn work(free: usize, o: &AlignOptions) -> super::args::Work {
    let rays = o.max_rays as f64;
    let search = o.max_evaluations as f64 + 1.0;
    let checks = (crate::align::CANDIDATES + 2 * free) as f64;
    super::args::Work {
        rays: (search + 2.0) * rays + checks * 2.0 * rays,
        what: format!(
            "up to {} evaluations and the start and result × {} rays, {} comparison and probe \
             traces × {} rays",
            o.max_evaluations + 1,
            o.max_rays,
            crate::align::CANDIDATES + 2 * free,
            2 * o.max_rays
        ),
        ..Default::default()
    }
}

/// Runs `spibench align`.
pub fn run(args: &AlignArgs) -> Result<()> {
    let doc = args.bench.load()?;
    let name = doc.name();
    let free: Vec<Free> = args
        .free
        .iter()
        .map(|f| Free::parse(f))
        .collect::<crate::Result<_>>()?;
    for f in &free {
        doc.get(&f.path)?;
    }
    let objective = objective(args)?;
    crate::align::check_objective(&objective)?;
    let opts = &args.opts;
    let rays = opts.rays(&doc, DEFAULT_RAYS)?;
    let o = AlignOptions {
        start_rays: check_counts(args, free.len(), rays)?,
        max_rays: rays,
        seed: opts.seed(),
        max_evaluations: args.max_evaluations,
    };
    // Bounds, start, starting bench and total work checked before the output folder or any
    // trace.
    crate::align::check_start(&doc, &free, true)?;
    args.work.check(&work(free.len(), &o))?;
    let out = OutputDir::create(&opts.out_or("out/align"))?;
    let bar = super::progress::bar(o.max_evaluations as u64, "evals");
    let t0 = std::time::Instant::now();
    let a = align(&doc, &free, &objective, &o, &|n| bar.set_position(n as u64))?;
    bar.finish_and_clear();
    let r = AlignRun {
        name: &name,
        doc: &doc,
        free: &free,
        objective: &objective,
        options: &o,
        alignment: &a,
        seconds: t0.elapsed().as_secs_f64(),
    };
    let provenance = crate::provenance::Provenance::of_bench(&doc, &[o.seed])?;
    let (_, card) = write(&r, &provenance, &out)?;
    let dir = out.commit()?;
    for w in &a.warnings {
        eprintln!("warning: {w}");
    }
    for line in card.printed() {
        println!("{line}");
    }
    for line in printed(&r, &dir) {
        println!("{line}");
    }
    Ok(())
}

/// The command's parsed objective.
fn objective(args: &AlignArgs) -> crate::Result<Objective> {
    Ok(match args.objective {
        ObjectiveArg::Balance => {
            check_weights([("--offset-weight", args.offset_weight)])?;
            Objective::Balance {
                min_fraction: args.min_fraction,
                offset_weight: args.offset_weight,
            }
        }
        ObjectiveArg::Power => Objective::Power,
        ObjectiveArg::Centre => Objective::Centre,
        ObjectiveArg::Weighted => {
            let w: Vec<(String, f64)> = args
                .weight
                .iter()
                .map(|w| super::parse_assignment(w, "--weight"))
                .collect::<crate::Result<_>>()?;
            check_weights(w.iter().map(|(_, v)| ("--weight", *v)))?;
            let metric = |(name, wt): (String, f64)| match name.parse::<BenchMetric>() {
                Ok(m) => Ok((m, wt)),
                Err(_) => Err(crate::Error::field(
                    "--weight",
                    format!("`{name}={wt}`: the metrics are {}", BenchMetric::keys()),
                )),
            };
            Objective::Weighted(w.into_iter().map(metric).collect::<crate::Result<_>>()?)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_counts_every_trace_and_refuses_a_huge_search() {
        let o = AlignOptions {
            start_rays: 12_500,
            max_rays: 200_000,
            seed: 1,
            max_evaluations: 200,
        };
        // 201 search traces, start and result, 4 candidates and 2 probes at twice the rays.
        let w = work(1, &o);
        assert_eq!(w.rays, 203.0 * 2e5 + 6.0 * 4e5);
        assert!(super::super::args::WorkArgs::default().check(&w).is_ok());
        let huge = AlignOptions {
            max_rays: 1_000_000_000,
            max_evaluations: 1000,
            ..o
        };
        let e = super::super::args::WorkArgs::default()
            .check(&work(2, &huge))
            .unwrap_err();
        let m = e.to_string();
        assert!(e.is_user_error() && m.contains("--allow-large"), "{m}");
        assert!(
            m.contains("1001 evaluations") && m.contains("traced rays"),
            "{m}"
        );
    }
}
