//! `spibench run [SCENE] [--out DIR] [--seed S] [--rays N]`: the whole traced experiment
//! (crate::run). Without SCENE, the paper's bench built into the binary
//! (scenes/paper_bench.ron with the default `electronics` and `run` sections).
//!
//! Output (DIR), written into a staging folder and moved into place only when complete:
//!
//! - `summary.json`: the transport (as `spibench trace`), the electronics and oscilloscope
//!   settings, the run settings, the recorded sequences, saturation findings, and for every
//!   scheme × ratio PSNR, MSSIM, frames, acquisition time, solver iterations (keys on
//!   [`RunSummary`]). Byte-identical for the same scene and seed on any number of threads.
//! - `timings.json`: wall-clock times of the trace, record and solve stages and each solve's
//!   CPU time: the only output figures that differ between two identical runs.
//! - `results.csv`: the results table, one row per scheme × ratio, in the schema `simulate`'s
//!   `cells.csv` shares (`report::csv::ResultRow`), LF line ends; byte-identical for a seed,
//!   like summary.json.
//! - `repeats.json`, `repeats.csv`, `mssim_vs_frames.*`, `psnr_vs_frames.*`: the statistics of
//!   `--repeats N` and the scores against the frames shown (cli::run_repeats).
//! - `bench.ron`: the effective bench (every default written out, the traced ray count), which
//!   `spibench run bench.ron --seed S` reads back to reproduce the run.
//! - `images/x.png` (the ideal object, 255·x / max x) and `images/<scheme>__r<ratio>.png` (each
//!   normalised reconstruction on the same 0–255 scale).
//! - `montage.{svg,png}`: laid out like the paper's Fig. 6 (one row per scheme, the object x at
//!   the head of each row, then one column per ratio, PSNR / MSSIM under each tile); the SVG
//!   embeds each tile as a lossless PNG of its pixels.
//! - `mssim_vs_ratio.{svg,png,pdf}` (the paper's Fig. 7) and `psnr_vs_ratio.{svg,png,pdf}`;
//!   the PNG and the PDF are renderings of the SVG.
//! - `signals_<sequence>.{svg,png,pdf}`: the first frames of each recorded sequence as the
//!   oscilloscope sampled them, one panel per output on a shared time axis, with the frame
//!   boundaries and the averaged settled windows marked.
//! - `report.html`: one self-contained page (images embedded as data: URIs, no network) with the
//!   bench summary, the per-unit efficiency maps, the ledger, the signal traces, the montage,
//!   the curves, the resolution read-out and the settings that reproduce the run.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::Result;
use clap::Args;

use crate::pipeline::TraceRequest;
use crate::pipeline::cache::{CacheKey, TraceCache};
use crate::report::csv::{ResultRow, write_results};
use crate::report::montage::{Montage, write_montage_figure};
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, ScopePlot, Series, write_plot, write_scope};
use crate::report::png::write_gray8;
use crate::run::summary::summarize_run;
use crate::run::{RunOutcome, SchemeResult, Stage};
use crate::scene::doc::BenchDoc;
use crate::scene::run::RunScene;

/// The findings (computed in the library, so that summary.json carries them too).
pub use crate::run::findings;

/// The paper's bench, built into the binary.
pub const PAPER_BENCH: &str = include_str!("../../scenes/paper_bench.ron");

/// The name the built-in bench has in messages and summaries.
pub const PAPER_BENCH_NAME: &str = "<built-in scenes/paper_bench.ron>";

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
    mut_arg("rays", |a| a.help("Lamp rays to trace, overriding the scene's `run.rays`")),
)]
pub struct RunArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    /// Keep traces in this folder and reuse them: a later run of the same bench, rays and seed
    /// (whatever its electronics, noise or solver settings) skips the trace.
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// Repeat every random process after the trace N times (noise, drift, random patterns):
    /// mean ± SD per scheme and ratio, paired differences (`repeats.json`, `repeats.csv`,
    /// `*_vs_frames` plots; written only for N ≥ 2). The other outputs are those of repeat 1,
    /// the plain run.
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub repeats: usize,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// Reads the bench named on the command line (or the built-in bench) and applies `--set`.
pub fn load_doc(scene: Option<&Path>, set: &[String]) -> crate::Result<(String, BenchDoc)> {
    let (name, mut doc) = match scene {
        Some(p) => (p.display().to_string(), BenchDoc::read(p)?),
        None => (
            PAPER_BENCH_NAME.to_string(),
            BenchDoc::parse(PAPER_BENCH, Path::new(PAPER_BENCH_NAME))?,
        ),
    };
    for a in set {
        let (path, value) = super::parse_assignment(a, "--set")?;
        doc.set(&path, value)?;
    }
    Ok((name, doc))
}

/// Loads the scene named by the arguments (or the built-in bench) with the `--set` and
/// `--rays` overrides.
pub fn load_scene(args: &RunArgs) -> crate::Result<(String, BenchDoc, RunScene)> {
    let (name, doc) = args.bench.load()?;
    let mut scene = doc.run_scene()?;
    if let Some(r) = args.bench.opts.rays {
        scene.settings.rays = super::args::check_rays(r, super::args::MIN_RAYS_WITH_STDERR)?;
    }
    Ok((name, doc, scene))
}

/// Runs `spibench run`.
pub fn run(args: &RunArgs) -> Result<()> {
    let (name, doc, scene) = load_scene(args)?;
    let seed = args.bench.opts.seed();
    let out = OutputDir::create(&args.bench.opts.out_or("out/run"))?;
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
        crate::run::repeats::run_repeats(&scene, seed, &request, args.repeats, &progress)?;
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
    let provenance = bench_provenance(&name, &doc, &[seed])?;
    let settings_ron = super::run_report::effective_ron(&doc, outcome.transport.rays)?;
    let findings = findings::Findings::of(&outcomes);
    // Statistics need two repeats or more: a plain run writes none (as documented). They are
    // written first, so that the report embeds their error-bar figures.
    let (repeat_files, stats) = if repeats.repeats > 1 {
        (
            super::run_repeats::write(&repeats, &scene.settings, &out)?.len(),
            Some(&repeats),
        )
    } else {
        (0, None)
    };
    let summary_files = write_outputs(
        &RunPage {
            name: &name,
            bench: &scene.bench,
            settings_ron: &settings_ron,
            findings: &findings,
            repeats: stats,
        },
        outcome,
        &provenance,
        &out,
    )? + repeat_files;
    super::run_arrays::write_arrays(outcome, &out)?;
    let dir = out.commit()?;
    print_report(&name, outcome, &findings, stats);
    super::run_repeats::print(&repeats);
    println!(
        "wrote {} ({} files, {:.1} s)",
        dir.display(),
        summary_files,
        outcome.timings.total_s
    );
    Ok(())
}

pub(super) use crate::run::findings::pct;

/// The file of a reconstruction.
pub fn result_file(r: &SchemeResult) -> String {
    format!("images/{}__r{:.3}.png", r.scheme.key(), r.ratio)
}

/// Writes a plot as `STEM.svg`, `STEM.png` and `STEM.pdf` and lists the files.
fn write_plot_pair(
    plot: &LinePlot,
    stem: &str,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<()> {
    write_plot(
        plot,
        &out.path(&format!("{stem}.svg")),
        &out.path(&format!("{stem}.png")),
    )?;
    files.push(format!("{stem}.svg"));
    files.push(format!("{stem}.png"));
    files.push(format!("{stem}.pdf"));
    Ok(())
}

/// The provenance of a command that reads a bench: the bench file (or the built-in text) and
/// every image it loads.
pub(super) fn bench_provenance(
    name: &str,
    doc: &BenchDoc,
    seeds: &[u64],
) -> crate::Result<crate::provenance::Provenance> {
    let p = crate::provenance::Provenance::new(seeds);
    let mut p = if name == PAPER_BENCH_NAME {
        p.text(PAPER_BENCH_NAME, PAPER_BENCH)
    } else {
        p.file(doc.path())?
    };
    for f in doc.input_files() {
        p = p.file(&f)?;
    }
    Ok(p)
}

/// What the report of a run is drawn from besides the outcome of repeat 0.
pub struct RunPage<'a> {
    pub name: &'a str,
    pub bench: &'a crate::optics::Bench,
    /// The effective bench as RON.
    pub settings_ron: &'a str,
    pub findings: &'a findings::Findings,
    /// The repeat statistics (N ≥ 2 only).
    pub repeats: Option<&'a crate::run::repeats::Repeats>,
}

fn write_outputs(
    page: &RunPage<'_>,
    o: &RunOutcome,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<usize> {
    let (name, bench, settings_ron) = (page.name, page.bench, page.settings_ron);
    let mut files = Vec::new();
    let bench_path = out.path("bench.ron");
    std::fs::write(&bench_path, settings_ron).map_err(|e| crate::Error::write(&bench_path, e))?;
    files.push("bench.ron".to_string());
    write_gray8(&out.path("images/x.png"), &o.truth, 0.0, 255.0)?;
    files.push("images/x.png".to_string());
    for r in &o.results {
        let f = result_file(r);
        write_gray8(&out.path(&f), &r.reconstruction, 0.0, 255.0)?;
        files.push(f);
    }

    let rows = result_rows(name, o);
    write_results(&out.path("results.csv"), &rows)?;
    files.push("results.csv".to_string());

    write_fig6_montage(o, out, &mut files)?;
    write_fig7_curves(o, out, &mut files)?;
    write_signal_traces(o, out, &mut files)?;

    files.push("report.html".to_string());
    files.push("summary.json".to_string());
    // timings.json is written beside them but not listed, so that summary.json stays the same
    // for the same seed whatever the timings file holds.
    let count = files.len() + 1;
    let mut summary = summarize_run(name, bench, o, files);
    // The standings over every repeat (summarize_run sees repeat 0 only).
    summary.findings.standings = page.findings.record();
    super::provenance::write_summary_and_timings(out, &summary, provenance, Some(&run_timings(o)))?;
    super::run_report::write_report(page, o, &summary, out)?;
    Ok(count)
}

/// The rows of `results.csv`, one per scheme × ratio.
fn result_rows(name: &str, o: &RunOutcome) -> Vec<ResultRow> {
    let s = &o.settings;
    let t = &o.transport;
    o.results
        .iter()
        .map(|r| ResultRow {
            command: "run".into(),
            scene: name.to_string(),
            seed: o.seed,
            object: "chart".into(),
            case: s.title.clone(),
            scheme: r.scheme.key().to_string(),
            ratio: r.ratio,
            measurements: r.measurements as u64,
            dmd_frames: r.dmd_frames as u64,
            detector_samples: r.detector_samples as u64,
            acquisition_time_s: r.acquisition_time_s,
            k_plus: t.k[0].value,
            k_minus: t.k[1].value,
            k_prime: t.k_prime.value,
            gain_units: "A/W".into(),
            b_plus: t.b[0].value,
            b_minus: t.b[1].value,
            offset_units: "A".into(),
            noise: None,
            noise_std: None,
            psnr_db: r.psnr_db,
            mssim: r.mssim,
            iterations: r.iterations as u64,
            converged: r.converged,
            stop: format!("{:?}", r.stop),
            saturated: Some(r.saturated),
            finest_group: r.finest_resolved.map(|e| e.group),
            finest_element: r.finest_resolved.map(|e| u32::from(e.element)),
            finest_lp_per_mm: r.finest_resolved.map(|e| e.lp_per_mm),
        })
        .collect()
}

/// Fig. 6: one row per scheme, the object x at the head of every row.
fn write_fig6_montage(
    o: &RunOutcome,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<()> {
    let s = &o.settings;
    let n_ratio = s.sampling_ratios.len();
    let mut tiles = Vec::new();
    let mut captions = Vec::new();
    let mut row_labels = Vec::new();
    for (k, scheme) in s.schemes.iter().enumerate() {
        let letter = (b'a' + k as u8) as char;
        row_labels.push(format!("({letter}) {}", scheme.label()));
        let mut trow = vec![Some(o.truth.clone())];
        let mut crow = vec!["ideal object x".to_string()];
        for r in 0..n_ratio {
            let res = &o.results[k * n_ratio + r];
            trow.push(Some(res.reconstruction.clone()));
            crow.push(format!(
                "{:.2} dB / {:.3}{}",
                res.psnr_db,
                res.mssim,
                if res.saturated { " SAT" } else { "" }
            ));
        }
        tiles.push(trow);
        captions.push(crow);
    }
    let montage = Montage {
        title: format!("{}: reconstructions against sampling ratio", s.title),
        row_labels,
        col_labels: std::iter::once("object".to_string())
            .chain(s.sampling_ratios.iter().map(|&r| pct(r)))
            .collect(),
        tiles,
        captions,
    };
    write_montage_figure(
        &montage,
        160,
        &out.path("montage.svg"),
        &out.path("montage.png"),
    )?;
    files.push("montage.svg".to_string());
    files.push("montage.png".to_string());

    Ok(())
}

/// Fig. 7 (MSSIM against sampling ratio) and its PSNR twin.
fn write_fig7_curves(
    o: &RunOutcome,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<()> {
    let s = &o.settings;
    let n_ratio = s.sampling_ratios.len();
    for (stem, label, pick) in [
        (
            "mssim_vs_ratio",
            "MSSIM",
            (|r: &SchemeResult| r.mssim) as fn(&SchemeResult) -> f64,
        ),
        ("psnr_vs_ratio", "PSNR (dB)", |r: &SchemeResult| r.psnr_db),
    ] {
        let plot = LinePlot {
            title: format!("{}: {label} against sampling ratio", s.title),
            x_label: "sampling ratio M/N".to_string(),
            y_label: label.to_string(),
            series: s
                .schemes
                .iter()
                .enumerate()
                .map(|(k, scheme)| Series {
                    label: scheme.label().to_string(),
                    x: s.sampling_ratios.clone(),
                    y: (0..n_ratio)
                        .map(|r| pick(&o.results[k * n_ratio + r]))
                        .collect(),
                    y_err: None,
                })
                .collect(),
            log_x: false,
        };
        write_plot_pair(&plot, stem, out, files)?;
    }

    Ok(())
}

/// The signal traces: one panel per output on a shared time axis, every sample on the line.
fn write_signal_traces(
    o: &RunOutcome,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<()> {
    for (q, tr) in &o.traces {
        if tr.t_s.is_empty() {
            continue;
        }
        let scope = ScopePlot {
            t_us: tr.t_s.iter().map(|t| t * 1e6).collect(),
            channels: (0..3)
                .map(|k| {
                    (
                        ["RF", "MONITOR+", "MONITOR−"][k].to_string(),
                        tr.v[k].clone(),
                    )
                })
                .collect(),
            frame_us: o.timing.frame_s * 1e6,
            settling_us: o.timing.settling_s * 1e6,
        };
        let stem = format!("signals_{}", q.key());
        write_scope(
            &scope,
            &out.path(&format!("{stem}.svg")),
            &out.path(&format!("{stem}.png")),
        )?;
        for ext in ["svg", "png", "pdf"] {
            files.push(format!("{stem}.{ext}"));
        }
    }

    Ok(())
}

/// timings.json of `run`: the wall-clock times of the stages and each solve's CPU time, the
/// only figures that differ between two runs with one seed (summary.json and results.csv are
/// byte-identical).
fn run_timings(o: &RunOutcome) -> serde_json::Value {
    serde_json::json!({
        "date_utc": super::provenance::utc_now(),
        "trace_s": o.timings.trace_s,
        "record_s": o.timings.record_s,
        "solve_s": o.timings.solve_s,
        "total_s": o.timings.total_s,
        "results": o.results.iter().map(|r| serde_json::json!({
            "scheme": r.scheme.key(),
            "ratio": r.ratio,
            "solver_time_s": r.solver_time_s,
        })).collect::<Vec<_>>(),
    })
}

/// "g/e" of a resolved element, or "none".
pub fn element_text(e: Option<crate::run::Resolved>) -> String {
    match e {
        Some(e) => format!("{}/{}", e.group, e.element),
        None => "none".to_string(),
    }
}

/// The widest line the printed report may take (terminals of 100 columns).
const REPORT_WIDTH: usize = 100;

/// A table of `rows` (label, one cell per column) under `columns`, split into blocks of columns
/// so that no line is wider than [`REPORT_WIDTH`]; each block repeats the labels.
fn table_blocks(title: &str, columns: &[String], rows: &[(String, Vec<String>)]) -> Vec<String> {
    const LABEL: usize = 34;
    const CELL: usize = 14;
    let per_block = ((REPORT_WIDTH - 2 - LABEL) / (CELL + 1)).max(1);
    let mut lines = Vec::new();
    for first in (0..columns.len()).step_by(per_block) {
        let last = (first + per_block).min(columns.len());
        let mut head = format!("  {title:<LABEL$}");
        for c in &columns[first..last] {
            head.push_str(&format!(" {c:>CELL$}"));
        }
        lines.push(head);
        for (label, cells) in rows {
            let label: String = label.chars().take(LABEL).collect();
            let mut line = format!("  {label:<LABEL$}");
            for c in &cells[first..last] {
                line.push_str(&format!(" {c:>CELL$}"));
            }
            lines.push(line);
        }
    }
    lines
}

fn print_report(
    name: &str,
    o: &RunOutcome,
    found: &findings::Findings,
    repeats: Option<&crate::run::repeats::Repeats>,
) {
    let t = &o.transport;
    let pm = |e: crate::transport::Estimate| format!("{:.4e} ± {:.1e}", e.value, e.stderr);
    println!(
        "{name}: {}×{} units, {} rays (seed {})",
        t.units_across, t.units_down, t.rays, o.seed
    );
    // The result first: which scheme wins where, and whether the lead is tested.
    for line in found.printed() {
        println!("{line}");
    }
    println!(
        "  trace {:.1} s, record {:.1} s, solve {:.1} s",
        o.timings.trace_s, o.timings.record_s, o.timings.solve_s
    );
    println!(
        "  k+ = {} A/W, k- = {} A/W, k' = {} A/W",
        pm(t.k[0]),
        pm(t.k[1]),
        pm(t.k_prime)
    );
    println!(
        "  imbalance = {}, b+ = {} A, b- = {} A",
        pm(t.imbalance),
        pm(t.b[0]),
        pm(t.b[1])
    );
    let ch = &o.channels;
    println!(
        "  detector: RF {:.0} V/A (±{} V), monitors {:.0}/{:.0} V/A",
        o.detector.rf.gain_v_per_a,
        o.detector.rf.swing_v,
        o.detector.monitors[0].gain_v_per_a,
        o.detector.monitors[1].gain_v_per_a,
    );
    println!(
        "  CMRR: bench {:.1} dB (with the arms' k±), electronics alone {:.1} dB",
        o.cmrr().value,
        o.detector.cmrr_db(),
    );
    println!(
        "  scope: {:.3e} S/s, RF {:.0e} V/div, MON+ {:.0e} V/div, MON- {:.0e} V/div",
        o.scope.sample_rate_hz, ch[0].volts_per_div, ch[1].volts_per_div, ch[2].volts_per_div
    );
    let s = &o.settings;
    let n_ratio = s.sampling_ratios.len();
    let columns: Vec<String> = s.sampling_ratios.iter().map(|&r| pct(r)).collect();
    let cells = |f: &dyn Fn(&SchemeResult) -> String| -> Vec<(String, Vec<String>)> {
        s.schemes
            .iter()
            .enumerate()
            .map(|(k, scheme)| {
                let row = (0..n_ratio)
                    .map(|r| f(&o.results[k * n_ratio + r]))
                    .collect();
                (scheme.label().to_string(), row)
            })
            .collect()
    };
    match repeats {
        Some(rp) => {
            // Means and SDs over the repeats, as repeats.csv holds them, labelled as such.
            let stat = |res: &SchemeResult| {
                rp.stats
                    .iter()
                    .find(|x| x.scheme == res.scheme && x.ratio == res.ratio)
            };
            for (title, f) in [
                (
                    format!("MSSIM mean ± SD, {} repeats", rp.repeats),
                    (|x: &crate::run::repeats::RepeatStats| {
                        format!("{:.3}±{:.3}", x.mssim_mean, x.mssim_sd)
                    }) as fn(&crate::run::repeats::RepeatStats) -> String,
                ),
                (format!("PSNR dB mean ± SD, {} repeats", rp.repeats), |x| {
                    format!("{:.2}±{:.2}", x.psnr_db_mean, x.psnr_db_sd)
                }),
            ] {
                let rows = cells(&|res| stat(res).map_or_else(String::new, f));
                for line in table_blocks(&title, &columns, &rows) {
                    println!("{line}");
                }
            }
        }
        None => {
            let scores = cells(&|res| {
                format!(
                    "{:.3} ({:.1}){}",
                    res.mssim,
                    res.psnr_db,
                    if res.saturated { "!" } else { "" }
                )
            });
            for line in table_blocks("MSSIM (PSNR dB), one run", &columns, &scores) {
                println!("{line}");
            }
        }
    }
    if let Some(c) = &o.resolution {
        println!(
            "  finest USAF element resolved (group/element; x itself: {}; registration r = {:.3})",
            element_text(c.ideal_finest_resolved),
            c.registration_correlation
        );
        let finest = cells(&|res| element_text(res.finest_resolved));
        for line in table_blocks("", &columns, &finest) {
            println!("{line}");
        }
    }
    for sat in &o.saturation {
        eprintln!("warning: SATURATION: {}", sat.message);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eight ratios and every scheme fit in 100 columns: two blocks of four ratios.
    #[test]
    fn tables_fit_100_columns() {
        let columns: Vec<String> = [0.05, 0.1, 0.15, 0.2, 0.4, 0.6, 0.8, 1.0]
            .iter()
            .map(|&r| pct(r))
            .collect();
        let rows: Vec<(String, Vec<String>)> = crate::acquisition::Scheme::all()
            .iter()
            .map(|s| (s.label().to_string(), vec!["0.997 (34.1)!".to_string(); 8]))
            .collect();
        let lines = table_blocks("MSSIM (PSNR dB)", &columns, &rows);
        assert_eq!(
            lines.len(),
            2 * (1 + crate::acquisition::Scheme::all().len())
        );
        for l in &lines {
            assert!(
                l.chars().count() <= REPORT_WIDTH,
                "{} columns: {l}",
                l.chars().count()
            );
        }
        assert!(lines[0].contains("20 %") && lines[lines.len() / 2].contains("100 %"));
    }

    #[test]
    fn built_in_bench_parses_with_defaults() {
        let args = RunArgs {
            bench: crate::cli::args::BenchArgs {
                opts: crate::cli::args::RunOpts {
                    rays: Some(2048),
                    ..Default::default()
                },
                ..Default::default()
            },
            cache: None,
            repeats: 1,
            work: Default::default(),
        };
        let (name, _, scene) = load_scene(&args).unwrap();
        assert_eq!(name, PAPER_BENCH_NAME);
        assert_eq!(scene.settings.rays, 2048);
        assert_eq!(scene.bench.units_shape(), (48, 48));
        assert_eq!(
            scene.settings.sampling_ratios,
            vec![0.05, 0.1, 0.15, 0.2, 0.4, 0.6, 0.8, 1.0]
        );
        // One batch has no standard error: fewer than two are refused, naming `--rays`.
        for rays in [0, 1, 2047] {
            let mut bad = args.clone();
            bad.bench.opts.rays = Some(rays);
            let e = load_scene(&bad).unwrap_err();
            assert!(e.is_user_error() && e.to_string().contains("--rays"), "{e}");
        }
    }
}
