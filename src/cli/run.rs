//! `spibench run [SCENE] [--set PATH=VALUE …] [--out DIR] [--seed S] [--rays N] [--repeats N]
//! [--cache DIR]`: the whole traced experiment (crate::run), by default with
//! [`DEFAULT_REPEATS`] acquisitions of its one trace so that its standings are tested.
//! Without SCENE, the paper's bench built into the binary (scenes/paper_bench.ron with the
//! default `electronics` and `run` sections). The files it writes are crate::outputs::run's.

use std::path::PathBuf;
use std::sync::Mutex;

use anyhow::Result;
use clap::Args;

use crate::outputs::run::{RunPage, effective_ron, printed, write};
use crate::pipeline::TraceRequest;
use crate::pipeline::cache::{CacheKey, TraceCache};
use crate::report::output::OutputDir;
use crate::run::Stage;
use crate::run::findings::Findings;
use crate::scene::doc::BenchDoc;
use crate::scene::run::RunScene;

#[derive(Debug, Clone, Args)]
#[command(
    mut_arg("scene", |a| a.help(
        "A bench file (RON) with optional `electronics` and `run` sections; default: the \
         paper's bench built into the binary"
    )),
    mut_arg("out", |a| a.default_value("out/run")),
    mut_arg("seed", |a| a.default_value("1").help(
        "Seed of the trace, the noise and the drift (the patterns' seed is in the scene)"
    )),
    mut_arg("rays", |a| a.help(super::args::rays_help("Lamp rays to trace", DEFAULT_RAYS))),
)]
pub struct RunArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    /// Keep traces in this folder and reuse them: a later run of the same bench, rays and seed
    /// (whatever its electronics, noise or solver settings) skips the trace.
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// Repeat every random process after the trace N times (noise, drift, random patterns):
    /// mean ± SD per scheme and ratio, paired differences with 95 % intervals (`repeats.json`,
    /// `repeats.csv`, `*_vs_frames` plots; written only for N ≥ 2). The trace, the ideal object
    /// and the chart's registration are shared: only the record and the solve repeat. By
    /// default 3, so that the standings between schemes are tested; `--repeats 1` is one
    /// acquisition. The other outputs are those of repeat 1.
    #[arg(long, default_value_t = DEFAULT_REPEATS, value_name = "N")]
    pub repeats: usize,
    /// Also write every recorded sequence as an oscilloscope saves it, in `scope/`: the raw
    /// record of RF, MONITOR+, MONITOR− and the DMD's frame trigger as a Tektronix-layout CSV
    /// and `.npy` with a JSON sidecar, and the frames shown (`patterns.npy`, `patterns.json`),
    /// which `spibench intake` reads back (docs/scope-records.md).
    #[arg(long)]
    pub scope_record: bool,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// `run`'s repeats without `--repeats`: three acquisitions of the one trace, so that every
/// paired difference between schemes has a 95 % interval (Student's t with 2 degrees of
/// freedom: ±4.30 standard errors; two repeats would give ±12.7) and the standings are tested.
pub const DEFAULT_REPEATS: usize = 3;

/// `run`'s ray count when neither `--rays` nor the bench file's `run.rays` gives one: the
/// `run` section's own default.
pub const DEFAULT_RAYS: u64 = 2_000_000;

/// Loads the scene named by the arguments (or the built-in bench) with the `--set` edits and
/// the ray count of the one rule ([`super::args::RunOpts::rays`]).
pub fn load_scene(args: &RunArgs) -> crate::Result<(BenchDoc, RunScene)> {
    let doc = args.bench.load()?;
    let mut scene = doc.run_scene()?;
    scene.settings.rays = args.opts.rays(&doc, DEFAULT_RAYS)?;
    Ok((doc, scene))
}

/// Runs `spibench run`.
pub fn run(args: &RunArgs) -> Result<()> {
    let (doc, scene) = load_scene(args)?;
    let name = doc.name();
    let seed = args.opts.seed();
    let out = OutputDir::create(&args.opts.out_or("out/run"))?;
    let cache = args.cache.as_deref().map(TraceCache::new);
    let key = match &cache {
        Some(_) => Some(CacheKey::new(&doc, scene.settings.rays, seed)?),
        None => None,
    };
    eprintln!(
        "{}: {}×{} units, {} rays, {} scheme(s) × {} ratio(s), seed {}",
        name,
        scene.bench.units_shape().0,
        scene.bench.units_shape().1,
        scene.settings.rays,
        scene.settings.schemes.len(),
        scene.settings.sampling_ratios.len(),
        seed
    );
    let bars: Mutex<Option<(Stage, indicatif::ProgressBar)>> = Mutex::new(None);
    let progress = |stage: Stage, done: u64, total: u64| {
        if let Ok(mut g) = bars.lock() {
            let fresh = !matches!(&*g, Some((s, _)) if *s == stage);
            if fresh {
                if let Some((_, b)) = g.take() {
                    b.finish_and_clear();
                }
                let what = match stage {
                    Stage::Record => "frames",
                    Stage::Solve => "solves",
                };
                *g = Some((stage, super::progress::bar(total, what)));
            }
            if let Some((_, b)) = &*g {
                b.set_position(done);
            }
        }
    };
    let trace_bar = super::progress::bar(scene.settings.rays, "rays");
    let trace_report = |done: u64, _: u64| {
        trace_bar.set_position(done);
        if done >= scene.settings.rays {
            trace_bar.finish_and_clear();
        }
    };
    let request = TraceRequest {
        progress: Some(&trace_report),
        cache: cache.as_ref().zip(key.as_ref()),
        ..TraceRequest::new(scene.settings.rays, seed)
    };
    let (outcomes, repeats) =
        crate::run::repeats::run_repeats(&scene, &request, args.repeats, &progress)?;
    let outcome = &outcomes[0];
    if let (Some(c), Some(k)) = (&cache, &key) {
        match &outcome.cache {
            crate::pipeline::CacheStatus::Hit => {
                eprintln!(
                    "trace read from the cache ({}/{}.trace)",
                    c.dir().display(),
                    k.as_str()
                )
            }
            crate::pipeline::CacheStatus::Rebuilt(why) => {
                eprintln!("warning: damaged cache entry rebuilt ({why})")
            }
            _ => eprintln!("trace stored in the cache ({})", c.dir().display()),
        }
    }
    if let Ok(mut g) = bars.lock()
        && let Some((_, b)) = g.take()
    {
        b.finish_and_clear();
    }
    let provenance = crate::provenance::Provenance::of_bench(&doc, &[seed])?;
    let settings_ron = effective_ron(&doc, outcome.transport.rays)?;
    let findings = Findings::of(&outcomes);
    // Statistics need two repeats or more: a plain run writes none (as documented).
    let stats = (repeats.repeats > 1).then_some(&repeats);
    let page = RunPage {
        name: &name,
        bench: &scene.bench,
        settings_ron: &settings_ron,
        findings: &findings,
        repeats: stats,
    };
    let (mut files, card) = write(&page, outcome, &provenance, &out)?;
    if args.scope_record {
        let (written, bytes) = crate::outputs::run::scope::write_scope_records(outcome, &out)?;
        files += written.len();
        eprintln!(
            "scope records: {} sequence(s), {:.1} MB in scope/",
            written.len() / crate::outputs::run::scope::FILES_PER_SEQUENCE,
            bytes as f64 / 1e6
        );
    }
    let dir = out.commit()?;
    for line in card.printed() {
        println!("{line}");
    }
    for line in printed(&name, outcome, &findings, stats) {
        println!("{line}");
    }
    for sat in &outcome.saturation {
        eprintln!("warning: SATURATION: {}", sat.message);
    }
    for line in crate::outputs::run::repeats::lines(&repeats) {
        println!("{line}");
    }
    println!(
        "wrote {} ({} files, {:.1} s)",
        dir.display(),
        files,
        outcome.timings.total_s
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_in_bench_parses_with_defaults() {
        let args = RunArgs {
            bench: Default::default(),
            opts: crate::cli::args::RunOpts {
                rays: Some(2048),
                ..Default::default()
            },
            cache: None,
            repeats: 1,
            scope_record: false,
            work: Default::default(),
        };
        let (doc, scene) = load_scene(&args).unwrap();
        assert_eq!(doc.name(), crate::scene::doc::PAPER_BENCH_NAME);
        assert_eq!(scene.settings.rays, 2048);
        assert_eq!(scene.bench.units_shape(), (48, 48));
        assert_eq!(
            scene.settings.sampling_ratios,
            vec![0.05, 0.1, 0.15, 0.2, 0.4, 0.6, 0.8, 1.0]
        );
        // Without --rays, the `run` section's default: the command's default is the same.
        let plain = RunArgs {
            opts: Default::default(),
            ..args.clone()
        };
        assert_eq!(load_scene(&plain).unwrap().1.settings.rays, DEFAULT_RAYS);
        assert_eq!(crate::scene::run::RunSpec::default().rays, DEFAULT_RAYS);
        // One batch has no standard error: fewer than two are refused, naming `--rays`.
        for rays in [0, 1, 2047] {
            let mut bad = args.clone();
            bad.opts.rays = Some(rays);
            let e = load_scene(&bad).unwrap_err();
            assert!(e.is_user_error() && e.to_string().contains("--rays"), "{e}");
        }
    }
}
