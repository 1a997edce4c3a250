//! `spibench tolerance [SCENE] --tolerances FILE [--set PATH=VALUE …] [--trials N] [--rays N]
//! [--seed S] [--quality] [--out DIR] [--trial K] [--shard I/N] [--merge DIR…]`: the
//! sensitivity table, a Monte Carlo of built benches with their compensators, yields against
//! the file's limits and per scheme, and the RSS estimate against the Monte Carlo spread
//! (crate::tolerance; the files are crate::outputs::tolerance's). With `--shard I/N` the run
//! holds the trials i ≡ I (mod N) (shard 0 also the sensitivity table); `--merge` over the N
//! shard folders writes exactly the outputs of the unsharded run. `--trial K` writes only
//! `trial_K.ron`, the perturbed (and compensated) bench of trial K, which every command reads.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;

use crate::outputs::tolerance::{read_shard_record, trial_ron, write};
use crate::report::output::OutputDir;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{ShardFile, ToleranceSet};
use crate::tolerance::budget_search::BudgetTrialsFile;
use crate::tolerance::{ToleranceOptions, merge, nominal, sensitivity, trial, trial_doc};

/// Arguments of `spibench tolerance`.
#[derive(Debug, Clone, Args)]
#[command(
    mut_arg("rays", |a| a.help(super::args::rays_help("Lamp rays per traced bench", DEFAULT_RAYS))),
    mut_arg("seed", |a| a.default_value("1").help(
        "Seed: of every trace (common random numbers) and, salted, of the tolerance draws"
    )),
    mut_arg("set", |a| a.help("Set a bench variable of the nominal bench first (repeatable)")),
    mut_arg("out", |a| a.default_value("out/tolerance")),
)]
pub struct ToleranceArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    /// Tolerance file (RON; see `scenes/tolerances/paper_bench.ron`).
    #[arg(long, required_unless_present = "merge")]
    pub tolerances: Option<PathBuf>,
    /// Monte Carlo trials (0: the sensitivity table only).
    #[arg(long, default_value_t = 100)]
    pub trials: u64,
    /// Resolve every sensitivity row to this paired standard error of its imbalance change
    /// (or 1 % of the change, whichever is larger), tracing each end of the row again with
    /// 2ᵏ× the rays (k predicted from its standard error) until it is, up to --max-rays.
    #[arg(long, value_name = "SE")]
    pub resolve: Option<f64>,
    /// The most rays per trace of a row being resolved (default 64 × --rays).
    #[arg(long, value_name = "N", requires = "resolve")]
    pub max_rays: Option<u64>,
    /// Run the whole pipeline on every trial and the nominal bench (image scores per scheme).
    #[arg(long)]
    pub quality: bool,
    /// Write only the bench of trial K (as RON) and stop.
    #[arg(long, value_name = "K")]
    pub trial: Option<u64>,
    /// Run part I of N of the trials, strided: the trials i ≡ I (mod N) (shard 0 also runs
    /// the sensitivity table); `--merge` over the N folders gives the unsharded run's outputs.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Merge the output folders of the shards of one run into DIR (no tracing).
    #[arg(long, value_name = "DIR", num_args = 1..)]
    pub merge: Vec<PathBuf>,
    /// Search a tolerance budget: the loosest tolerances, at the least total cost, whose
    /// yield against the file's limits is at least --target-yield at --confidence, confirmed
    /// by --trials traced trials per round (docs/guide/10-tolerance-budget.md). Writes
    /// budget.ron, a tolerance file of the budget.
    #[arg(long, requires = "target_yield", conflicts_with_all = ["merge", "trial"])]
    pub budget: bool,
    /// With --budget: the yield to reach, in (0, 1).
    #[arg(long, value_name = "Y", requires = "budget")]
    pub target_yield: Option<f64>,
    /// With --budget: the confidence of the yield's lower bound, in (0, 1) (default 0.95).
    #[arg(long, value_name = "C", requires = "budget")]
    pub confidence: Option<f64>,
    /// With --budget: the cost of tightening each tolerance and its scale bounds (RON; by
    /// default cost 1/s, scales 0.01 … 1).
    #[arg(long, value_name = "FILE", requires = "budget")]
    pub costs: Option<PathBuf>,
    /// With --budget: draws of the response surface's yield estimate.
    #[arg(long, value_name = "N", default_value_t = 4000, requires = "budget")]
    pub surface_samples: usize,
    /// With --budget: continue from the budget runs in these folders (their
    /// budget_trials.ron): the search replays, reusing every trial they traced, and goes on.
    /// With --shard I/N, a run traces its part of the first confirmation they do not complete
    /// and stops; a resume with every shard's folder goes on from there.
    #[arg(long, value_name = "DIR", num_args = 1.., requires = "budget")]
    pub resume: Vec<PathBuf>,
    /// With --budget: the most confirmation rounds.
    #[arg(long, value_name = "N", default_value_t = 6, requires = "budget")]
    pub budget_rounds: usize,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// The most trials one run may have.
const MAX_TRIALS: u64 = 1_000_000;

/// `tolerance`'s ray count per trace when neither `--rays` nor the bench file's `run.rays`
/// gives one.
pub const DEFAULT_RAYS: u64 = 200_000;

/// Runs `spibench tolerance`.
pub fn run(args: &ToleranceArgs) -> Result<()> {
    if !args.merge.is_empty() {
        return run_merge(args);
    }
    let doc = args.bench.load()?;
    let name = doc.name();
    let opts = &args.opts;
    let tol_path = args
        .tolerances
        .as_deref()
        .ok_or_else(|| crate::Error::field("--tolerances", "give the tolerance file"))?;
    let tol_text = crate::scene::read_text(tol_path)?;
    let set = ToleranceSet::parse(&tol_text, tol_path, &doc)?;
    let (rays, seed) = (opts.rays(&doc, DEFAULT_RAYS)?, opts.seed());
    let resolve = resolve_option(args, rays)?;
    if args.trials > MAX_TRIALS {
        return Err(crate::Error::field("--trials", format!("at most {MAX_TRIALS}")).into());
    }
    let shard =
        super::args::Shard::parse_opt(args.shard.as_deref())?.unwrap_or(super::args::Shard::WHOLE);
    let o = ToleranceOptions {
        rays,
        seed,
        quality: args.quality,
    };
    if o.quality {
        set.refuse_attenuator(&tol_text, "a trial recorded and solved through its bench")?;
        check_quality_names(&doc, &set, &tol_text)?;
    }
    if args.budget {
        return run_budget(args, (&doc, &set, &o), tol_path, resolve);
    }
    if let Some(k) = args.trial {
        set.refuse_attenuator(&tol_text, "a trial's bench file")?;
        let run = format!(
            "spibench tolerance {name} --tolerances {} --seed {seed} --rays {rays}",
            tol_path.display()
        );
        return write_trial(args, (&doc, &set, &o), k, &run);
    }
    args.work
        .check(&work(&set, args.trials, shard, rays, resolve.as_ref()))?;
    let out = OutputDir::create(&opts.out_or("out/tolerance"))?;
    // A trial whose perturbed bench is not valid is not an input error: it is recorded as a
    // failed trial (a built bench that does not work).
    let start = std::time::Instant::now();
    eprintln!(
        "{name}: {} tolerance(s), {} compensator(s); {} rays per trace (seed {}){}",
        set.tolerances.len(),
        set.compensator_count(),
        rays,
        seed,
        if args.quality { ", full pipeline" } else { "" }
    );
    let nom = nominal(&doc, &o)?;
    let sens = if shard.index == 0 {
        let bar = super::progress::bar(2 * set.tolerances.len() as u64, "settings");
        let rows = sensitivity(&doc, &set, &nom, &o, resolve, &|d, _| {
            bar.set_position(d as u64)
        })?;
        bar.finish_and_clear();
        Some(rows)
    } else {
        None
    };
    let indices: Vec<u64> = shard.strided(args.trials).collect();
    let bar = super::progress::bar(indices.len() as u64, "trials");
    let mut records = Vec::with_capacity(indices.len());
    let (mut comp_s, mut trace_s) = (0.0, 0.0);
    for (k, &i) in indices.iter().enumerate() {
        let (r, t) = trial(&doc, &set, &nom, &o, i)?;
        comp_s += t.compensators_s;
        trace_s += t.trace_s;
        bar.set_position(k as u64 + 1);
        bar.set_message(format!(
            "trial {i}: imbalance {:+.3e}",
            r.value("imbalance").unwrap_or(f64::NAN)
        ));
        records.push(r);
    }
    bar.finish_and_clear();
    let shard_file = ShardFile {
        spibench_version: env!("CARGO_PKG_VERSION").into(),
        scene: name.clone(),
        bench_ron: doc.to_ron()?,
        tolerances_path: tol_path.display().to_string(),
        tolerances_text: tol_text,
        rays,
        seed,
        trials: args.trials,
        quality: args.quality,
        shard: shard.pair(),
        nominal: crate::tolerance::recorded((&doc, &nom), (&doc, &nom)),
        sensitivity: sens,
        records,
    };
    let provenance = crate::provenance::Provenance::of_bench(&doc, &[seed])?.file(tol_path)?;
    let (files, card) = write(&shard_file, &set, &provenance, &out)?;
    let dir = out.commit()?;
    for line in card.printed() {
        println!("{line}");
    }
    println!(
        "wrote {} ({files} files, {:.1} s: {})",
        dir.display(),
        start.elapsed().as_secs_f64(),
        time_split(set.compensators.len(), comp_s, trace_s)
    );
    Ok(())
}

/// `--trial K`: writes `trial_K.ron`, the bench of trial `k` (`run`: the command that draws
/// it, for the file's heading), and stops.
fn write_trial(
    args: &ToleranceArgs,
    (doc, set, o): (&BenchDoc, &ToleranceSet, &ToleranceOptions),
    k: u64,
    run: &str,
) -> Result<()> {
    let out = OutputDir::create(&args.opts.out_or("out/tolerance"))?;
    let (d, dev, comp) = trial_doc(doc, set, o, k)?;
    d.build()?;
    let file = format!("trial_{k}.ron");
    let moves: Vec<(String, f64)> = dev.into_iter().chain(comp).collect();
    let text = trial_ron(k, run, &d, &moves)?;
    let path = out.path(&file);
    std::fs::write(&path, text).map_err(|e| crate::Error::write(&path, e))?;
    let dir = out.commit()?;
    println!("wrote {}", dir.join(file).display());
    Ok(())
}

/// `--resolve` and `--max-rays` checked: the sensitivity's stopping rule, if asked for.
fn resolve_option(
    args: &ToleranceArgs,
    rays: u64,
) -> crate::Result<Option<crate::tolerance::Resolve>> {
    Ok(match args.resolve {
        None => None,
        Some(se) => {
            if !(se.is_finite() && se > 0.0 && se < 1.0) {
                return Err(crate::Error::field(
                    "--resolve",
                    format!("a paired standard error of the imbalance in (0, 1), got {se}"),
                ));
            }
            let max_rays = args
                .max_rays
                .unwrap_or(rays.saturating_mul(64))
                .min(crate::scene::run::MAX_RAYS);
            if max_rays < rays {
                return Err(crate::Error::field(
                    "--max-rays",
                    format!("must be at least --rays ({rays})"),
                ));
            }
            Some(crate::tolerance::Resolve {
                stderr: se,
                relative: 0.01,
                max_rays,
            })
        }
    })
}

/// With `--quality`: the run settings valid before the first trace, and the tolerance file's
/// quality limits naming scores this run records (else their yields would be empty).
fn check_quality_names(doc: &BenchDoc, set: &ToleranceSet, tol_text: &str) -> crate::Result<()> {
    let settings = doc.run_scene()?.settings;
    let percents: Vec<u32> = settings
        .sampling_ratios
        .iter()
        .map(|r| (r * 100.0).round() as u32)
        .collect();
    let keys: Vec<String> = settings
        .schemes
        .iter()
        .flat_map(|s| {
            settings
                .sampling_ratios
                .iter()
                .map(|r| crate::pipeline::evaluate::quality_key(s.key(), *r))
        })
        .collect();
    let is_score = |m: &str| {
        keys.iter().any(|k| {
            m.strip_prefix(k.as_str())
                .is_some_and(|rest| ["_mssim", "_psnr_db", "_finest_lp_per_mm"].contains(&rest))
        })
    };
    set.check_quality(tol_text, &percents, &is_score)
}

/// The run's work for the limits of `--allow-large`: the tolerance job's estimate
/// ([`crate::tolerance::work::estimate`]: each traced bench's rays and fixed cost), for the
/// trials i ≡ I (mod N) below `trials` this shard holds, with the sensitivity table on shard 0.
fn work(
    set: &ToleranceSet,
    trials: u64,
    shard: super::args::Shard,
    rays: u64,
    resolve: Option<&crate::tolerance::Resolve>,
) -> super::args::Work {
    let mine = trials.saturating_sub(shard.index).div_ceil(shard.count);
    let e = crate::tolerance::work::estimate(set, mine, shard.index == 0, rays, resolve);
    super::args::Work {
        rays: e.equivalent_rays,
        what: e.what,
        ..Default::default()
    }
}

fn run_merge(args: &ToleranceArgs) -> Result<()> {
    let out_dir = args.opts.out_or("out/tolerance");
    for (flag, given) in [
        ("--tolerances", args.tolerances.is_some()),
        ("SCENE", args.bench.scene.is_some()),
        ("--shard", args.shard.is_some()),
        ("--trial", args.trial.is_some()),
    ] {
        if given {
            return Err(crate::Error::field(
                flag,
                "is not an option of --merge (the shard records hold the bench, the \
                 tolerance file and the run's settings)",
            )
            .into());
        }
    }
    crate::report::output::refuse_overlap(&out_dir, &args.merge, "--out")?;
    let read: Vec<(PathBuf, String)> = args
        .merge
        .iter()
        .map(|d| read_shard_record(d))
        .collect::<crate::Result<_>>()?;
    let shards: Vec<ShardFile> = read
        .iter()
        .map(|(p, text)| crate::scene::parse_ron(text, p))
        .collect::<crate::Result<_>>()?;
    let merged = merge(&shards)?;
    let doc = BenchDoc::parse(&merged.bench_ron, Path::new(&merged.scene))?;
    let set = ToleranceSet::parse(
        &merged.tolerances_text,
        Path::new(&merged.tolerances_path),
        &doc,
    )?;
    for ((p, _), s) in read.iter().zip(&shards) {
        crate::tolerance::check_shard_names(s, &set, p)?;
    }
    let out = OutputDir::create(&out_dir)?;
    // The merge's provenance is its own command and the shard records it read; the bench and
    // tolerance files are inside those records (docs/outputs.md). Everything but this block
    // equals the unsharded run's summary.
    let mut provenance = crate::provenance::Provenance::new(&[merged.seed]);
    for (p, text) in &read {
        provenance = provenance.text(&p.display().to_string(), text);
    }
    // The shards' bench as they traced it (their records hold it with any `--dmd-model`).
    provenance.dmd_model = doc.dmd_model().map(|m| m.name());
    let (files, card) = write(&merged, &set, &provenance, &out)?;
    let dir = out.commit()?;
    for line in card.printed() {
        println!("{line}");
    }
    println!(
        "merged {} shard(s), {} trials: wrote {} ({files} files)",
        shards.len(),
        merged.records.len(),
        dir.display()
    );
    Ok(())
}
/// `--budget`: the budget search (crate::tolerance::budget) and its outputs. Everything that
/// can be refused (target, confidence, costs file, resumed records, work) is checked before any
/// output.
fn run_budget(
    args: &ToleranceArgs,
    (doc, set, o): (&BenchDoc, &ToleranceSet, &ToleranceOptions),
    tol_path: &Path,
    resolve: Option<crate::tolerance::Resolve>,
) -> Result<()> {
    use crate::outputs::tolerance::budget::write_budget_trials;
    use crate::tolerance::budget::{
        BudgetInputs, BudgetOptions, BudgetRunOptions, budget, check_options,
    };
    let b = BudgetOptions {
        target_yield: args.target_yield.unwrap_or(f64::NAN),
        confidence: args.confidence.unwrap_or(0.95),
        trials: args.trials,
        samples: args.surface_samples.clamp(100, 1_000_000),
        max_rounds: args.budget_rounds.clamp(1, 50),
    };
    check_options(&b)?;
    let costs = match &args.costs {
        Some(p) => crate::scene::budget_costs::parse_costs(&crate::scene::read_text(p)?, p, set)?,
        None => crate::scene::budget_costs::default_costs(set),
    };
    let shard =
        super::args::Shard::parse_opt(args.shard.as_deref())?.unwrap_or(super::args::Shard::WHOLE);
    let mut trials_file = BudgetTrialsFile {
        spibench_version: env!("CARGO_PKG_VERSION").into(),
        scene: doc.name(),
        bench_ron: doc.to_ron()?,
        tolerances_text: crate::scene::read_text(tol_path)?,
        costs: costs
            .iter()
            .map(|c| [c.weight, c.exponent, c.min_scale, c.max_scale])
            .collect(),
        rays: o.rays,
        seed: o.seed,
        trials: b.trials,
        quality: o.quality,
        target_yield: b.target_yield,
        confidence: b.confidence,
        surface_samples: b.samples,
        shard: shard.pair(),
        sensitivity: Vec::new(),
        confirmations: Vec::new(),
    };
    let prior = read_resumed(&args.resume, &trials_file, set)?;
    // The rounds, the baseline's confirmation, the loosening pass's and up to three of the
    // baseline scaled to the target, each `--trials` trials, each at the full rays (a resume's
    // traced ones not counted apart, staged trials counted whole: an estimate errs high).
    let all_trials = args.trials.saturating_mul(
        b.max_rounds as u64
            + 2
            + crate::tolerance::budget_baseline::SCALED_BASELINE_ATTEMPTS as u64,
    );
    args.work
        .check(&work(set, all_trials, shard, o.rays, resolve.as_ref()))?;
    let out = OutputDir::create(&args.opts.out_or("out/tolerance"))?;
    let start = std::time::Instant::now();
    eprintln!(
        "{}: budget of {} tolerance(s) for a yield ≥ {} at confidence {}; {} rays per trace, {} \
         trials per confirmation (seed {}){}",
        trials_file.scene,
        set.tolerances.len(),
        b.target_yield,
        b.confidence,
        o.rays,
        b.trials,
        o.seed,
        if o.quality { ", full pipeline" } else { "" }
    );
    let nom = nominal(doc, o)?;
    let sens = match prior.iter().find(|p| !p.sensitivity.is_empty()) {
        Some(p) => p.sensitivity.clone(),
        None => {
            let bar = super::progress::bar(2 * set.tolerances.len() as u64, "settings");
            let rows = sensitivity(doc, set, &nom, o, resolve, &|d, _| {
                bar.set_position(d as u64)
            })?;
            bar.finish_and_clear();
            rows
        }
    };
    let inputs = BudgetInputs {
        doc,
        set,
        costs: &costs,
        nominal: &nom,
        sens: &sens,
    };
    let confirmations: Vec<_> = prior.into_iter().flat_map(|p| p.confirmations).collect();
    let run_opts = BudgetRunOptions {
        o,
        b: &b,
        prior: &confirmations,
        shard: shard.pair(),
    };
    let outcome = budget(&inputs, &run_opts, &|m| eprintln!("  {m}"))?;
    trials_file.sensitivity = sens;
    trials_file.confirmations = outcome.traced.clone();
    write_budget_trials(&trials_file, &out)?;
    if outcome.incomplete {
        let dir = out.commit()?;
        println!(
            "shard {}/{}: traced its part of the next confirmation; resume with every shard's \
             folder (--resume) to go on; wrote {} ({:.1} s)",
            shard.index,
            shard.count,
            dir.join(crate::outputs::tolerance::budget::BUDGET_TRIALS)
                .display(),
            start.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    finish_budget(args, (doc, set, o), tol_path, &b, &outcome, out, start)
}

/// The records of the budget runs `--resume` names (each folder's `budget_trials.ron`),
/// checked to be of this run.
fn read_resumed(
    dirs: &[PathBuf],
    this: &BudgetTrialsFile,
    set: &ToleranceSet,
) -> crate::Result<Vec<BudgetTrialsFile>> {
    dirs.iter()
        .map(|d| {
            let p = d.join(crate::outputs::tolerance::budget::BUDGET_TRIALS);
            let text = crate::scene::read_text(&p)?;
            let f: BudgetTrialsFile = crate::scene::parse_ron(&text, &p)?;
            match this.mismatch(&f, set) {
                Some(why) => Err(crate::Error::field(
                    "resume",
                    format!(
                        "{} is not of this budget run: {why} (resume with the same bench, \
                         tolerance file, costs, rays, seed, trials, quality, target, confidence \
                         and surface samples)",
                        p.display()
                    ),
                )),
                None => Ok(f),
            }
        })
        .collect()
}

/// Writes a finished budget's outputs and prints its outcome.
#[allow(clippy::too_many_arguments)]
fn finish_budget(
    args: &ToleranceArgs,
    (doc, set, o): (&BenchDoc, &ToleranceSet, &ToleranceOptions),
    tol_path: &Path,
    b: &crate::tolerance::budget::BudgetOptions,
    outcome: &crate::tolerance::budget::BudgetOutcome,
    out: OutputDir,
    start: std::time::Instant,
) -> Result<()> {
    use crate::outputs::tolerance::budget::{BudgetRun, write_budget};
    let name = doc.name();
    // The DMD's model is written out whether or not it was chosen on the command line, so
    // that the command repeats the budget whatever the bench file's default.
    let command = format!(
        "spibench tolerance {name} --tolerances {} --budget --target-yield {} --confidence {} \
         --trials {} --rays {} --seed {}{}{}{}",
        tol_path.display(),
        b.target_yield,
        b.confidence,
        b.trials,
        o.rays,
        o.seed,
        doc.dmd_model()
            .map_or(String::new(), |m| format!(" --dmd-model {}", m.name())),
        args.costs
            .as_ref()
            .map_or(String::new(), |p| format!(" --costs {}", p.display())),
        if o.quality { " --quality" } else { "" }
    );
    let costs_name = args.costs.as_ref().map(|p| p.display().to_string());
    let tol_name = tol_path.display().to_string();
    let run = BudgetRun {
        scene: &name,
        tolerances_file: &tol_name,
        costs_file: costs_name.as_deref(),
        rays: o.rays,
        seed: o.seed,
        trials: b.trials,
        quality: o.quality,
        command: &command,
    };
    let mut provenance = crate::provenance::Provenance::of_bench(doc, &[o.seed])?.file(tol_path)?;
    if let Some(p) = &args.costs {
        provenance = provenance.file(p)?;
    }
    let files = write_budget(outcome, set, &run, &provenance, &out)?;
    let dir = out.commit()?;
    let j = &outcome.joint;
    let status = match (&j.confirmation, outcome.reached) {
        (Some(c), true) => format!(
            "reached: {} of {} trials pass, lower bound {:.4} ≥ {}",
            c.passed, c.trials, c.lower_bound, b.target_yield
        ),
        _ => format!(
            "UNREACHABLE: {}",
            outcome.reason.as_deref().unwrap_or("unknown")
        ),
    };
    let scaled = outcome
        .baseline_at_target
        .as_ref()
        .map_or(String::new(), |s| {
            format!(
                "; scaled × {:.3} to the target {:.4}, yield {:.4}",
                s.factor,
                s.budget.geometric_mean_scale,
                s.budget
                    .confirmation
                    .as_ref()
                    .map_or(f64::NAN, |c| c.fraction)
            )
        });
    println!(
        "budget {status}; geometric-mean scale {:.4} (one at a time {:.4}, yield {:.4}{scaled}); \
         wrote {} ({files} files, {:.1} s)",
        j.geometric_mean_scale,
        outcome.baseline.geometric_mean_scale,
        outcome
            .baseline
            .confirmation
            .as_ref()
            .map_or(f64::NAN, |c| c.fraction),
        dir.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Where a run's time went; the compensators' share only for a file that has some.
fn time_split(compensators: usize, comp_s: f64, trace_s: f64) -> String {
    if compensators == 0 {
        format!("trial traces {trace_s:.1} s")
    } else {
        format!("compensators {comp_s:.1} s, trial traces {trace_s:.1} s")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_split_names_compensators_only_when_there_are_some() {
        assert_eq!(time_split(0, 2.3, 4.0), "trial traces 4.0 s");
        assert!(time_split(1, 2.3, 4.0).starts_with("compensators 2.3 s"));
    }
}
