//! `spibench tolerance BENCH --tolerances FILE [--trials N] [--rays N] [--seed S] [--quality]
//! [--out DIR] [--trial K] [--shard I/N] [--merge DIR…]`: the sensitivity table, a Monte Carlo
//! of built benches with their compensators, yields against the file's limits and per scheme,
//! and the RSS estimate against the Monte Carlo spread (crate::tolerance).
//!
//! Output (DIR): `summary.json` (nominal metrics, sensitivity rows, RSS, percentiles, yields,
//! one row per trial), `sensitivity.csv`, `trials.csv`, `trials.ron` (the records, from which
//! `--merge` rebuilds the outputs), histogram and CDF plots, `report.html`. With `--shard I/N`
//! the run holds the trials i ≡ I (mod N) (shard 0 also the sensitivity table); `--merge`
//! over the N shard folders writes exactly the outputs of the unsharded run. `--trial K` writes
//! only `trial_K.ron`, the perturbed (and compensated) bench of trial K, which `run`, `trace`
//! and `export-mitsuba` read.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use serde::Serialize;

use crate::report::csv::write_csv;
use crate::report::html::{Block, Page, write_page};
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, Series, write_plot};
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{
    Compensator, Limit, QualityLimit, SensitivityRecord, ShardFile, Tolerance, ToleranceSet,
    shard_to_ron,
};

use super::rows::Row;
use crate::tolerance::{
    Analysis, SENSITIVITY_METRICS, ToleranceOptions, analyse, is_metric, merge, nominal,
    sensitivity, trial, trial_doc,
};

/// Arguments of `spibench tolerance`.
#[derive(Debug, Clone, Args)]
#[command(
    mut_arg("rays", |a| a.default_value("200000").help("Lamp rays per traced bench")),
    mut_arg("seed", |a| a.default_value("1").help(
        "Seed: of every trace (common random numbers) and, salted, of the tolerance draws"
    )),
    mut_arg("set", |a| a.help("Set a bench variable of the nominal bench first (repeatable)")),
    mut_arg("out", |a| a.default_value("out/tolerance")),
)]
pub struct ToleranceArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
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
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// The most trials one run may have.
const MAX_TRIALS: u64 = 1_000_000;

/// `tolerance`'s default ray count per trace (also set on the flag, for `--help`).
const DEFAULT_RAYS: u64 = 200_000;

/// Runs `spibench tolerance`.
pub fn run(args: &ToleranceArgs) -> Result<()> {
    if !args.merge.is_empty() {
        return run_merge(args);
    }
    let (name, doc) = args.bench.load()?;
    let opts = &args.bench.opts;
    let tol_path = args
        .tolerances
        .as_deref()
        .ok_or_else(|| crate::Error::field("--tolerances", "give the tolerance file"))?;
    let tol_text = crate::scene::read_text(tol_path)?;
    let set = ToleranceSet::parse(&tol_text, tol_path, &doc, &is_metric)?;
    let (rays, seed) = (
        opts.rays_or(DEFAULT_RAYS, super::args::MIN_RAYS_WITH_STDERR)?,
        opts.seed(),
    );
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
        check_quality_names(&doc, &set, &tol_text)?;
    }
    if let Some(k) = args.trial {
        let out = OutputDir::create(&opts.out_or("out/tolerance"))?;
        let (d, dev, comp) = trial_doc(&doc, &set, &o, k)?;
        d.build()?;
        let file = format!("trial_{k}.ron");
        let mut text = String::from("// ");
        text += &format!(
            "Trial {k} of `spibench tolerance {name} --tolerances {} --seed {} --rays {}`.\n",
            tol_path.display(),
            seed,
            rays
        );
        for (p, v) in dev.iter().chain(&comp) {
            text += &format!("//   {p}: {v:+.6e}\n");
        }
        text += &d.to_ron()?;
        let path = out.path(&file);
        std::fs::write(&path, text).map_err(|e| crate::Error::write(&path, e))?;
        let dir = out.commit()?;
        println!("wrote {}", dir.join(file).display());
        return Ok(());
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
        set.compensators.len(),
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
        nominal: crate::tolerance::values(&nom, &nom),
        sensitivity: sens,
        records,
    };
    let provenance =
        super::run::bench_provenance(&name, &doc, &[seed])?.file(Path::new(tol_path))?;
    let files = write_outputs(&shard_file, &set, &provenance, &out)?;
    let dir = out.commit()?;
    println!(
        "wrote {} ({files} files, {:.1} s: {})",
        dir.display(),
        start.elapsed().as_secs_f64(),
        time_split(set.compensators.len(), comp_s, trace_s)
    );
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
fn check_quality_names(
    doc: &crate::scene::doc::BenchDoc,
    set: &ToleranceSet,
    tol_text: &str,
) -> crate::Result<()> {
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

/// The shard record's checksum file beside `trials.ron` (`sha256sum` format).
const CHECKSUM_FILE: &str = "trials.ron.sha256";

/// `trials.ron.sha256`: the SHA-256 of `trials.ron`, as `sha256sum` writes it.
fn checksum_line(trials_ron: &str) -> String {
    format!(
        "{}  trials.ron\n",
        crate::provenance::sha256_hex(trials_ron.as_bytes())
    )
}

/// Reads the shard record of the tolerance output folder `dir` (named on the command line, so
/// trusted; what it holds is not): `trials.ron` and its checksum file, inside the folder (no
/// symbolic link out), the record matching its SHA-256. Returns the record's path and text.
fn read_shard_record(dir: &Path) -> crate::Result<(PathBuf, String)> {
    use crate::report::untrusted::{Folder, bad_field, is_sha256_hex};
    let folder = Folder::new(dir)?;
    let sum_path = dir.join(CHECKSUM_FILE);
    let (_, sum) = folder.read(Path::new(CHECKSUM_FILE), &sum_path, CHECKSUM_FILE)?;
    let sum = String::from_utf8_lossy(&sum);
    let want = match sum.trim_end().split_once("  ") {
        Some((h, "trials.ron")) if is_sha256_hex(h) => h.to_string(),
        _ => {
            return Err(bad_field(
                &sum_path,
                "sha256",
                "not a checksum line `SHA256  trials.ron` (a folder made by an older spibench? \
                 run the shard again)",
            ));
        }
    };
    let rec = dir.join("trials.ron");
    let (_, bytes) = folder.read(Path::new("trials.ron"), &rec, "trials.ron")?;
    if crate::provenance::sha256_hex(&bytes) != want {
        return Err(crate::Error::input(format!(
            "the record was edited or is damaged: its SHA-256 differs from the one in \
             {CHECKSUM_FILE}; run the shard again"
        ))
        .in_file(&rec));
    }
    let text = String::from_utf8(bytes)
        .map_err(|_| crate::Error::input("the record is not UTF-8 text").in_file(&rec))?;
    Ok((rec, text))
}

/// The rays a tolerance run may trace at most: the nominal bench; on shard 0 the sensitivity
/// table (each tolerance at both ends, and with `--resolve` each end and the nominal bench again
/// at up to `--max-rays`); and each trial of this shard, once and through its compensators
/// (each objective's group adjusted by at most 60 evaluations at up to a quarter of the rays:
/// `pipeline::perturb`).
fn work(
    set: &ToleranceSet,
    trials: u64,
    shard: super::args::Shard,
    rays: u64,
    resolve: Option<&crate::tolerance::Resolve>,
) -> super::args::Work {
    let r = rays as f64;
    let ends = 2.0 * set.tolerances.len() as f64;
    let sensitivity = if shard.index == 0 {
        ends * r + resolve.map_or(0.0, |v| 2.0 * ends * v.max_rays as f64)
    } else {
        0.0
    };
    let groups = [
        crate::scene::tolerance::CompensatorObjective::Balance,
        crate::scene::tolerance::CompensatorObjective::Power,
    ]
    .iter()
    .filter(|o| set.compensators.iter().any(|c| c.objective == **o))
    .count() as f64;
    let per_trial = 1.0 + 15.0 * groups;
    // The trials i ≡ I (mod N) below `trials`.
    let mine = trials.saturating_sub(shard.index).div_ceil(shard.count) as f64;
    super::args::Work {
        rays: r + sensitivity + mine * per_trial * r,
        what: format!(
            "{mine} trials × up to {per_trial} traces × {rays} rays, and {ends} sensitivity \
             traces{}",
            if resolve.is_some() {
                " with --resolve"
            } else {
                ""
            }
        ),
        ..Default::default()
    }
}

fn run_merge(args: &ToleranceArgs) -> Result<()> {
    let out_dir = args.bench.opts.out_or("out/tolerance");
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
        &is_metric,
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
    let files = write_outputs(&merged, &set, &provenance, &out)?;
    let dir = out.commit()?;
    println!(
        "merged {} shard(s), {} trials: wrote {} ({files} files)",
        shards.len(),
        merged.records.len(),
        dir.display()
    );
    Ok(())
}

fn pm(v: f64, se: f64) -> String {
    format!("{v:+.3e} ± {se:.1e}")
}

/// Writes every output of a run from its records; the same records give the same files.
fn write_outputs(
    s: &ShardFile,
    set: &ToleranceSet,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<usize> {
    let analysis = analyse(set, &s.records, s.sensitivity.as_deref());
    let mut files: Vec<String> = [
        "summary.json",
        "trials.ron",
        CHECKSUM_FILE,
        "trials.csv",
        "report.html",
    ]
    .map(String::from)
    .to_vec();
    let path = out.path("trials.ron");
    let record = shard_to_ron(s)?;
    std::fs::write(&path, &record).map_err(|e| crate::Error::write(&path, e))?;
    let path = out.path(CHECKSUM_FILE);
    std::fs::write(&path, checksum_line(&record)).map_err(|e| crate::Error::write(&path, e))?;
    // Every trial's numbers in the metric rows sweep and align write too.
    let values: Vec<Row> = s
        .records
        .iter()
        .map(|r| Row::from_values(&r.values, &s.nominal))
        .collect();
    write_trials_csv(s, set, &values, out)?;
    let mut blocks = vec![intro_block(s, set, &analysis)];
    if let Some(sens) = &s.sensitivity {
        files.push("sensitivity.csv".into());
        write_sensitivity_csv(sens, out)?;
        blocks.extend(sensitivity_blocks(sens));
    }
    if !s.records.is_empty() {
        blocks.extend(monte_carlo_blocks(&analysis));
        blocks.extend(distribution_plots(s, set, &analysis, out, &mut files)?);
    }
    write_page(
        &out.path("report.html"),
        &Page {
            title: format!("spibench tolerance of {}", s.scene),
            blocks,
        },
    )?;
    let summary = ToleranceSummary {
        command: "tolerance",
        spibench_version: env!("CARGO_PKG_VERSION"),
        scene: &s.scene,
        tolerances_file: &s.tolerances_path,
        rays: s.rays,
        seed: s.seed,
        trials: s.trials,
        shard: [s.shard.0, s.shard.1],
        quality: s.quality,
        tolerances: &set.tolerances,
        compensators: &set.compensators,
        limits: &set.limits,
        quality_limit: &set.quality,
        nominal: Row::from_values(&s.nominal, &s.nominal),
        sensitivity: s
            .sensitivity
            .iter()
            .flatten()
            .map(|r| SensitivitySummary {
                path: &r.path,
                min: r.min,
                max: r.max,
                rays: r.rays,
                at_min: Row(r.at_min.clone()),
                at_max: Row(r.at_max.clone()),
            })
            .collect(),
        analysis: &analysis,
        trial_rows: s
            .records
            .iter()
            .zip(values)
            .map(|(r, values)| TrialSummary {
                index: r.index,
                deviations: Row(r.deviations.clone()),
                compensators: Row(r.compensators.clone()),
                values,
                error: r.error.as_deref(),
            })
            .collect(),
        files: &files,
    };
    super::provenance::write_summary(out, &summary, provenance)?;
    Ok(files.len())
}

/// Where a run's time went; the compensators' share only for a file that has some.
fn time_split(compensators: usize, comp_s: f64, trace_s: f64) -> String {
    if compensators == 0 {
        format!("trial traces {trace_s:.1} s")
    } else {
        format!("compensators {comp_s:.1} s, trial traces {trace_s:.1} s")
    }
}

/// `trials.csv`: index, deviations, compensators, each trial's metric row, error.
fn write_trials_csv(
    s: &ShardFile,
    set: &ToleranceSet,
    values: &[Row],
    out: &OutputDir,
) -> crate::Result<()> {
    let mut header: Vec<String> = vec!["index".into()];
    header.extend(set.tolerances.iter().map(|t| t.path.clone()));
    header.extend(
        set.compensators
            .iter()
            .map(|c| format!("compensator:{}", c.path)),
    );
    let value_names: Vec<String> = s
        .records
        .iter()
        .zip(values)
        .find(|(r, _)| r.error.is_none())
        .map_or_else(Vec::new, |(_, v)| v.keys().map(String::from).collect());
    header.extend(value_names.iter().cloned());
    header.push("error".into());
    let rows: Vec<Vec<String>> = s
        .records
        .iter()
        .zip(values)
        .map(|(r, v)| {
            let mut row = vec![r.index.to_string()];
            row.extend(r.deviations.iter().map(|(_, v)| format!("{v:e}")));
            for c in &set.compensators {
                row.push(
                    r.compensators
                        .iter()
                        .find(|(p, _)| *p == c.path)
                        .map_or_else(String::new, |(_, v)| format!("{v:e}")),
                );
            }
            for n in &value_names {
                row.push(v.get(n).map_or_else(String::new, |v| format!("{v:e}")));
            }
            row.push(r.error.clone().unwrap_or_default());
            row
        })
        .collect();
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(&out.path("trials.csv"), &h, &rows)?;
    Ok(())
}

/// The report's opening paragraph: what was traced, how often, and how many trials failed.
fn intro_block(s: &ShardFile, set: &ToleranceSet, analysis: &Analysis) -> Block {
    Block::Paragraph(format!(
        "{}: {} tolerance(s) from {}, {} compensator(s); every bench traced with {} rays and \
         seed {} (common random numbers: differences from the nominal bench carry paired \
         standard errors); {} Monte Carlo trial(s){}{}.",
        s.scene,
        set.tolerances.len(),
        s.tolerances_path,
        set.compensators.len(),
        s.rays,
        s.seed,
        s.records.len(),
        if s.quality {
            ", each through the whole pipeline"
        } else {
            ""
        },
        if analysis.failed_trials > 0 {
            format!(
                " ({} gave a bench that is not valid and count as failures)",
                analysis.failed_trials
            )
        } else {
            String::new()
        }
    ))
}

/// `sensitivity.csv`: each tolerance alone at its min and max, the change of every
/// sensitivity metric with its paired standard error.
fn write_sensitivity_csv(sens: &[SensitivityRecord], out: &OutputDir) -> crate::Result<()> {
    let mut header = vec![
        "path".to_string(),
        "min".into(),
        "max".into(),
        "rays_at_min".into(),
        "rays_at_max".into(),
    ];
    for end in ["min", "max"] {
        for m in SENSITIVITY_METRICS {
            header.push(format!("{m}_diff_at_{end}"));
            header.push(format!("{m}_diff_stderr_at_{end}"));
        }
    }
    let rows: Vec<Vec<String>> = sens
        .iter()
        .map(|r| {
            let mut row = vec![
                r.path.clone(),
                format!("{}", r.min),
                format!("{}", r.max),
                format!("{}", r.rays[0]),
                format!("{}", r.rays[1]),
            ];
            for high in [false, true] {
                for m in SENSITIVITY_METRICS {
                    row.push(format!("{:e}", r.at(high, &format!("{m}_diff"))));
                    row.push(format!("{:e}", r.at(high, &format!("{m}_diff_stderr"))));
                }
            }
            row
        })
        .collect();
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(&out.path("sensitivity.csv"), &h, &rows)?;
    Ok(())
}

/// The sensitivity table of the report.
fn sensitivity_blocks(sens: &[SensitivityRecord]) -> Vec<Block> {
    let mut blocks = Vec::new();
    blocks.push(Block::Heading {
        level: 2,
        text: "Sensitivity".into(),
    });
    blocks.push(Block::Table {
        caption: Some(
            "Each tolerance alone at its min / max: change from the nominal bench ± its \
             paired standard error, sorted by the largest |Δ imbalance|; the rays of the \
             row's traces (more than the run's where --resolve asked for them)"
                .into(),
        ),
        header: [
            "tolerance",
            "range",
            "rays",
            "Δ imbalance",
            "Δ k' (A/W)",
            "Δ(b₋ − b₊) (A)",
            "Δ leak +",
            "Δ leak −",
            "Δ CMRR (dB)",
        ]
        .map(String::from)
        .to_vec(),
        rows: sens
            .iter()
            .flat_map(|r| {
                [false, true].map(|high| {
                    let mut row = vec![
                        if high { String::new() } else { r.path.clone() },
                        format!("{}", if high { r.max } else { r.min }),
                        r.rays[usize::from(high)].to_string(),
                    ];
                    for m in SENSITIVITY_METRICS {
                        row.push(pm(
                            r.at(high, &format!("{m}_diff")),
                            r.at(high, &format!("{m}_diff_stderr")),
                        ));
                    }
                    row
                })
            })
            .collect(),
    });
    blocks
}

/// The Monte Carlo tables of the report: percentiles, yields, RSS against Monte Carlo.
fn monte_carlo_blocks(analysis: &Analysis) -> Vec<Block> {
    let mut blocks = Vec::new();
    blocks.push(Block::Heading {
        level: 2,
        text: "Monte Carlo".into(),
    });
    blocks.push(Block::Table {
        caption: Some(
            "Distribution over the trials (percentiles of the value and of its magnitude). \
             The leaks here are the recorded ratios P_wrong/P_own, unbounded where a part \
             blinds the own arm; the tails table and the figures show them as the bounded \
             fraction P_wrong/(P_own + P_wrong), 0 … 1"
                .into(),
        ),
        header: [
            "metric",
            "unit",
            "mean",
            "std dev",
            "median",
            "90 %",
            "97.7 %",
            "|·| median",
            "|·| 90 %",
            "|·| 97.7 %",
        ]
        .map(String::from)
        .to_vec(),
        rows: analysis
            .percentiles
            .iter()
            .map(|p| {
                let mut r = vec![p.metric.clone(), unit_of(&p.metric)];
                r.extend(
                    [
                        p.mean,
                        p.std_dev,
                        p.p50,
                        p.p90,
                        p.p97_7,
                        p.abs_p50,
                        p.abs_p90,
                        p.abs_p97_7,
                    ]
                    .map(|v| format!("{v:.4e}")),
                );
                r
            })
            .collect(),
    });
    let mut yrows: Vec<Vec<String>> = analysis
        .yields
        .iter()
        .map(|y| {
            vec![
                y.limit.clone(),
                format!("{}/{}", y.passed, y.trials),
                format!("{:.1} % ± {:.1} %", 100.0 * y.fraction, 100.0 * y.stderr),
            ]
        })
        .collect();
    yrows.extend(analysis.quality_yields.iter().map(|(scheme, y)| {
        vec![
            format!("{scheme}: {}", y.limit),
            format!("{}/{}", y.passed, y.trials),
            format!("{:.1} % ± {:.1} %", 100.0 * y.fraction, 100.0 * y.stderr),
        ]
    }));
    if !yrows.is_empty() {
        blocks.push(Block::Table {
            caption: Some(
                "Yield: the fraction of trials meeting each limit (± binomial standard \
                 error); image quality per scheme side by side"
                    .into(),
            ),
            header: ["limit", "trials passing", "yield"]
                .map(String::from)
                .to_vec(),
            rows: yrows,
        });
    }
    blocks.extend(tail_block(analysis));
    blocks.extend(compensator_block(analysis));
    if !analysis.rss.is_empty() {
        blocks.push(Block::Table {
            caption: Some(format!(
                "Root-sum-square spread from the sensitivity table (linear, independent \
                 tolerances) against the Monte Carlo spread: a large gap means the \
                 tolerances interact or act nonlinearly. The RSS is flagged where a tolerance \
                 whose change reaches {:.0} % of the largest has a one-sided range, moves the \
                 metric the same way at both ends, or has a quadratic term above {:.0} % of its \
                 linear term at the range end (fitted through the nominal bench and both ends, \
                 beyond 2 standard errors): there an agreement with the Monte Carlo σ can be a \
                 coincidence",
                100.0 * crate::tolerance::summaries::RELEVANT_FRACTION,
                100.0 * crate::tolerance::summaries::CURVATURE_LIMIT
            )),
            header: [
                "metric",
                "RSS σ",
                "Monte Carlo σ",
                "dominant tolerance",
                "its share",
                "RSS model",
            ]
            .map(String::from)
            .to_vec(),
            rows: analysis
                .rss
                .iter()
                .map(|r| {
                    vec![
                        r.metric.clone(),
                        format!("{:.3e}", r.rss_std_dev),
                        format!("{:.3e}", r.monte_carlo_std_dev),
                        r.dominant.clone(),
                        format!("{:.0} %", 100.0 * r.dominant_share),
                        if r.linearity_flags.is_empty() {
                            "linear, two-sided".into()
                        } else {
                            format!("FLAGGED: {}", r.linearity_flags.join("; "))
                        },
                    ]
                })
                .collect(),
        });
    }
    blocks
}

/// A metric's unit for the report (the leaks as bounded fractions).
fn unit_of(metric: &str) -> String {
    if crate::tolerance::summaries::is_fraction(metric) {
        return "ratio P_wrong/P_own".into();
    }
    crate::transport::metrics::METRICS
        .iter()
        .find(|m| m.0 == metric)
        .map_or_else(
            || {
                if metric.ends_with("_db") {
                    "dB".into()
                } else {
                    String::new()
                }
            },
            |m| m.1.to_string(),
        )
}

/// The tail that matters of each metric: where the worst 10 % and 2.3 % of built benches lie.
fn tail_block(analysis: &Analysis) -> Option<Block> {
    use crate::tolerance::summaries::Tail;
    if analysis.tails.is_empty() {
        return None;
    }
    Some(Block::Table {
        caption: Some(
            "The tail that matters: for k', k±, powers, CMRR and image scores the low values \
             (10th and 2.3rd percentiles, the lowest trial), for the imbalance, offsets and \
             leaks the large |values| (90th and 97.7th percentiles of |·|, the largest); the \
             leaks as the bounded fraction P_wrong/(P_own + P_wrong), 0 … 1; the fraction of \
             trials beyond the file's limits on the metric"
                .into(),
        ),
        header: [
            "metric",
            "unit",
            "tail",
            "worst 10 % beyond",
            "worst 2.3 % beyond",
            "worst trial",
            "beyond the limits",
        ]
        .map(String::from)
        .to_vec(),
        rows: analysis
            .tails
            .iter()
            .map(|t| {
                vec![
                    t.metric.clone(),
                    if crate::tolerance::summaries::is_fraction(&t.metric) {
                        "fraction, 0–1".into()
                    } else {
                        unit_of(&t.metric)
                    },
                    match t.tail {
                        Tail::Lower => "lower".into(),
                        Tail::UpperAbs => "upper of |·|".into(),
                    },
                    format!("{:.4e}", t.worst_10_percent),
                    format!("{:.4e}", t.worst_2_3_percent),
                    format!("{:.4e}", t.worst),
                    t.beyond_limits
                        .map_or_else(|| "–".into(), |f| format!("{:.1} %", 100.0 * f)),
                ]
            })
            .collect(),
    })
}

/// The compensators' settled moves.
fn compensator_block(analysis: &Analysis) -> Option<Block> {
    if analysis.compensators.is_empty() {
        return None;
    }
    Some(Block::Table {
        caption: Some(format!(
            "Compensator moves over the trials (from the value after the tolerances are \
             applied); at a bound: within {} of the range of min or max, where the compensator \
             ran out of travel",
            crate::tolerance::summaries::AT_BOUND_FRACTION
        )),
        header: [
            "compensator",
            "range",
            "mean",
            "SD",
            "lowest",
            "highest",
            "at min / at max",
            "at a bound",
        ]
        .map(String::from)
        .to_vec(),
        rows: analysis
            .compensators
            .iter()
            .map(|c| {
                vec![
                    c.path.clone(),
                    format!("{} … {}", c.min, c.max),
                    format!("{:+.4e}", c.mean),
                    format!("{:.4e}", c.std_dev),
                    format!("{:+.4e}", c.lowest),
                    format!("{:+.4e}", c.highest),
                    format!("{} / {}", c.at_min, c.at_max),
                    format!("{:.1} % of {}", 100.0 * c.at_bound_fraction, c.trials),
                ]
            })
            .collect(),
    })
}

/// The file's limits on `metric` as vertical lines from 0 to `top`: on a plot of |value|
/// (`abs`) the `abs_max` limits, on a plot of the value the `min` and `max` ones and ±`abs_max`.
fn limit_lines(limits: &[(String, f64)], top: f64) -> Vec<Series> {
    limits
        .iter()
        .map(|(label, x)| Series {
            label: label.clone(),
            x: vec![*x, *x],
            y: vec![0.0, top],
            y_err: None,
        })
        .collect()
}

/// The limits of the file (and the quality limit) on `metric`, as (label, x) on a plot of
/// |value| (`abs`) or of the value.
fn limits_on(set: &ToleranceSet, metric: &str, abs: bool) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for l in set.limits.iter().filter(|l| l.metric == metric) {
        if let Some(m) = l.abs_max {
            out.push((format!("limit |{metric}| ≤ {m}"), m));
            if !abs {
                out.push((format!("limit |{metric}| ≥ −{m}"), -m));
            }
        }
        for (v, op) in [(l.min, "≥"), (l.max, "≤")] {
            if let Some(v) = v
                && (!abs || v > 0.0)
            {
                out.push((format!("limit {metric} {op} {v}"), v));
            }
        }
    }
    if let Some(q) = set.quality
        && metric.ends_with(&format!("_{}_mssim", q.ratio_percent))
    {
        out.push((format!("limit MSSIM ≥ {}", q.min_mssim), q.min_mssim));
    }
    out
}

/// The metrics plotted (key, axis label).
fn plotted_metrics(set: &ToleranceSet, analysis: &Analysis) -> Vec<(String, String)> {
    let mut plotted: Vec<(String, String)> = [
        ("imbalance", "imbalance (k₊ − k₋)/(k₊ + k₋)"),
        ("k_prime", "k' = k₊ + k₋ (A/W)"),
        ("b_minus_minus_b_plus", "b₋ − b₊ (A)"),
        (
            "leak_plus",
            "off-arm leak, all units +: P₋/(P₊ + P₋) (fraction, 0–1)",
        ),
        (
            "leak_minus",
            "off-arm leak, all units −: P₊/(P₊ + P₋) (fraction, 0–1)",
        ),
    ]
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .to_vec();
    for (scheme, _) in &analysis.quality_yields {
        if let Some(q) = set.quality {
            plotted.push((
                format!("{scheme}_{}_mssim", q.ratio_percent),
                format!("MSSIM at {} %, {scheme}", q.ratio_percent),
            ));
        }
    }
    plotted
}

/// A histogram as steps: `bins` equal bins over the values' range.
fn histogram_series(v: &[f64], bins: usize) -> (Series, f64) {
    let n = v.len();
    let (lo, hi) = (v[0], v[n - 1]);
    let w = if hi > lo {
        (hi - lo) / bins as f64
    } else {
        1.0
    };
    let mut counts = vec![0usize; bins];
    for x in v {
        counts[(((x - lo) / w) as usize).min(bins - 1)] += 1;
    }
    let (mut hx, mut hy) = (vec![lo], vec![0.0]);
    for (b, c) in counts.iter().enumerate() {
        let (a, z) = (lo + b as f64 * w, lo + (b + 1) as f64 * w);
        hx.extend([a, z]);
        hy.extend([*c as f64, *c as f64]);
    }
    hx.push(lo + bins as f64 * w);
    hy.push(0.0);
    let top = counts.iter().copied().max().unwrap_or(1) as f64;
    (
        Series {
            label: String::new(),
            x: hx,
            y: hy,
            y_err: None,
        },
        top,
    )
}

/// Histograms (as steps, Freedman–Diaconis bins with a floor) and empirical CDFs of the main
/// metrics over the trials, with the file's limits drawn, written as figures and returned as
/// report blocks. The CDF is of |value| on a log axis for the metrics whose upper |·| tail
/// matters (imbalance, offsets, leaks), of the value for those whose lower tail matters (k',
/// MSSIM).
fn distribution_plots(
    s: &ShardFile,
    set: &ToleranceSet,
    analysis: &Analysis,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<Vec<Block>> {
    use crate::tolerance::summaries::{Tail, histogram_bins, shown, tail_of};
    let mut figs = Vec::new();
    for (metric, label) in plotted_metrics(set, analysis) {
        // Leaks as bounded fractions (summaries::leak_fraction), their limits too.
        let mut v: Vec<f64> = s
            .records
            .iter()
            .filter_map(|r| r.value(&metric))
            .map(|v| shown(&metric, v))
            .filter(|v| v.is_finite())
            .collect();
        if v.len() < 2 {
            continue;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let upper = tail_of(&metric) == Tail::UpperAbs;
        // |value| on a log axis: zeros cannot be drawn and are counted in the caption.
        let mut cx: Vec<f64> = if upper {
            v.iter().map(|x| x.abs()).filter(|x| *x > 0.0).collect()
        } else {
            v.clone()
        };
        cx.sort_by(f64::total_cmp);
        let zeros = n - cx.len();
        // Large magnitudes on a log axis; the lower tail of a value on a linear one.
        let log_x = upper;
        let mut cdf_series = vec![Series {
            label: String::new(),
            y: (0..cx.len())
                .map(|i| (zeros + i + 1) as f64 / n as f64)
                .collect(),
            x: cx,
            y_err: None,
        }];
        let limit_at = |abs: bool| -> Vec<(String, f64)> {
            limits_on(set, &metric, abs)
                .into_iter()
                .map(|(l, x)| (l, shown(&metric, x)))
                .collect()
        };
        cdf_series.extend(limit_lines(&limit_at(upper), 1.0));
        let cdf = LinePlot {
            title: String::new(),
            x_label: if upper {
                format!("|{label}| (log scale)")
            } else {
                label.clone()
            },
            y_label: "fraction of trials ≤ x".into(),
            series: cdf_series,
            log_x,
        };
        let bins = histogram_bins(&v);
        let (steps, top) = histogram_series(&v, bins);
        let mut hist_series = vec![steps];
        hist_series.extend(limit_lines(&limit_at(false), top));
        let hist = LinePlot {
            title: String::new(),
            x_label: label.clone(),
            y_label: "trials".into(),
            series: hist_series,
            log_x: false,
        };
        let tail = if upper {
            "the upper tail of |value| matters"
        } else {
            "the lower tail matters"
        };
        // Every trial at exactly 0 (a metric a symmetric bench holds at 0): no CDF on a log axis.
        let plots = if cdf.series[0].x.is_empty() {
            vec![("hist", hist)]
        } else {
            vec![("hist", hist), ("cdf", cdf)]
        };
        for (kind, plot) in plots {
            let (svg, png) = (
                format!("{kind}_{metric}.svg"),
                format!("{kind}_{metric}.png"),
            );
            write_plot(&plot, &out.path(&svg), &out.path(&png))?;
            let text = std::fs::read_to_string(out.path(&svg))
                .map_err(|e| crate::Error::read(&out.path(&svg), e))?;
            figs.push(Block::Svg {
                caption: if kind == "hist" {
                    format!(
                        "Histogram of {label} over {n} trials ({bins} bins: Freedman–Diaconis, \
                         at least max(10, √n)); vertical lines: the file's limits"
                    )
                } else {
                    format!(
                        "Empirical CDF of {}{label} over {n} trials ({tail}){}; vertical lines: \
                         the file's limits",
                        if upper { "|·| of " } else { "" },
                        if zeros > 0 {
                            format!("; {zeros} trial(s) at exactly 0 are counted but not drawn")
                        } else {
                            String::new()
                        }
                    )
                },
                svg: text,
            });
            files.extend([svg, png]);
        }
    }
    Ok(figs)
}

/// `summary.json` of `tolerance`.
#[derive(Serialize)]
struct ToleranceSummary<'a> {
    command: &'static str,
    spibench_version: &'static str,
    scene: &'a str,
    tolerances_file: &'a str,
    rays: u64,
    seed: u64,
    trials: u64,
    /// [I, N] of `--shard I/N` ([0, 1] unsharded).
    shard: [u64; 2],
    quality: bool,
    tolerances: &'a [Tolerance],
    compensators: &'a [Compensator],
    limits: &'a [Limit],
    quality_limit: &'a Option<QualityLimit>,
    /// The nominal bench's metric row (differences against itself).
    nominal: Row,
    sensitivity: Vec<SensitivitySummary<'a>>,
    /// NaN written as null.
    analysis: &'a Analysis,
    trial_rows: Vec<TrialSummary<'a>>,
    files: &'a [String],
}

#[derive(Serialize)]
struct SensitivitySummary<'a> {
    path: &'a str,
    min: f64,
    max: f64,
    rays: [u64; 2],
    at_min: Row,
    at_max: Row,
}

#[derive(Serialize)]
struct TrialSummary<'a> {
    index: u64,
    deviations: Row,
    compensators: Row,
    values: Row,
    error: Option<&'a str>,
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
