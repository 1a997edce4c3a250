//! The outputs of `spibench run` (docs/outputs.md, "run"), from the outcome of the traced
//! experiment (crate::run), written into a staging folder that is moved into place only when
//! complete:
//!
//! - `summary.json`: the transport (as `spibench trace`), the electronics and oscilloscope
//!   settings, the run settings, the recorded sequences, saturation findings, and for every
//!   scheme × ratio PSNR, MSSIM, frames, acquisition time, solver iterations (keys on
//!   [`summary::RunSummary`]). Byte-identical for the same scene and seed on any number of threads.
//! - `timings.json`: wall-clock times of the trace, record and solve stages and each solve's
//!   CPU time: the only output figures that differ between two identical runs.
//! - `results.csv`: the results table, one row per scheme × ratio, in the schema `simulate`'s
//!   `cells.csv` shares (`report::csv::ResultRow`), LF line ends; byte-identical for a seed,
//!   like summary.json.
//! - `repeats.json`, `repeats.csv`, `mssim_vs_frames.*`, `psnr_vs_frames.*`: the statistics of
//!   `--repeats N` and the scores against the frames shown ([`repeats`]).
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
//!
//! The modules: [`summary`] (`summary.json`), [`report`] (`report.html`), [`repeats`] (the files
//! of `--repeats N`), [`arrays`] (`arrays/*.npy`); the figures are `figures.rs`'s.

use crate::report::csv::ResultRow;
use crate::run::findings::{self, pct};
use crate::run::{RunOutcome, SchemeResult};

pub mod arrays;
pub mod card;
#[cfg(feature = "figures")]
mod figures;
pub mod repeats;
#[cfg(feature = "figures")]
pub mod report;
pub mod scope;
pub mod summary;

/// The file of a reconstruction.
pub fn result_file(r: &SchemeResult) -> String {
    format!("images/{}__r{:.3}.png", r.scheme.key(), r.ratio)
}

/// What the outputs of a run are drawn from besides the outcome of repeat 0.
pub struct RunPage<'a> {
    pub name: &'a str,
    pub bench: &'a crate::optics::Bench,
    /// The effective bench as RON ([`effective_ron`]).
    pub settings_ron: &'a str,
    pub findings: &'a findings::Findings,
    /// The repeat statistics (N ≥ 2 only: a plain run writes none).
    pub repeats: Option<&'a crate::run::repeats::Repeats>,
}

/// The effective bench of a run as canonical RON (every default written out), with the ray
/// count the run traced, which `spibench run` reads back.
pub fn effective_ron(doc: &crate::scene::doc::BenchDoc, rays: u64) -> crate::Result<String> {
    let mut doc = doc.clone();
    doc.file.run.rays = rays;
    doc.to_ron()
}

/// Writes every output of a run into `out` (a staging folder): the repeat files first (with
/// N ≥ 2 repeats), so that the report embeds their error-bar figures, then the summary, the
/// images, `results.csv`, the figures, `report.html` and the arrays. Returns the count of
/// files the run reports (the arrays and `timings.json` are written beside them, not counted)
/// and the summary card (from summary.json's values) that the report and the terminal open
/// with.
#[cfg(feature = "figures")]
pub fn write(
    page: &RunPage<'_>,
    o: &RunOutcome,
    provenance: &crate::provenance::Provenance,
    out: &crate::report::output::OutputDir,
) -> crate::Result<(usize, crate::outputs::card::Card)> {
    let repeat_files = match page.repeats {
        Some(r) => repeats::write(r, &o.settings, out)?.len(),
        None => 0,
    };
    let (name, bench, settings_ron) = (page.name, page.bench, page.settings_ron);
    let mut files = Vec::new();
    let bench_path = out.path("bench.ron");
    std::fs::write(&bench_path, settings_ron).map_err(|e| crate::Error::write(&bench_path, e))?;
    files.push("bench.ron".to_string());
    crate::report::png::write_gray8(&out.path("images/x.png"), &o.truth, 0.0, 255.0)?;
    files.push("images/x.png".to_string());
    for r in &o.results {
        let f = result_file(r);
        crate::report::png::write_gray8(&out.path(&f), &r.reconstruction, 0.0, 255.0)?;
        files.push(f);
    }

    let rows = result_rows(name, o);
    crate::report::csv::write_results(&out.path("results.csv"), &rows)?;
    files.push("results.csv".to_string());

    figures::write_fig6_montage(o, out, &mut files)?;
    figures::write_fig7_curves(o, out, &mut files)?;
    figures::write_signal_traces(o, out, &mut files)?;

    files.push("report.html".to_string());
    files.push("summary.json".to_string());
    // timings.json is written beside them but not listed, so that summary.json stays the same
    // for the same seed whatever the timings file holds.
    let count = files.len() + 1;
    let mut summary = summary::summarize_run(name, bench, o, files);
    // The standings over every repeat (summarize_run sees repeat 0 only).
    summary.findings.standings = page.findings.record();
    super::summary::write_summary_and_timings(out, &summary, provenance, Some(&run_timings(o)))?;
    let json = serde_json::to_value(&summary)
        .map_err(|e| crate::Error::Numerical(format!("the run summary as JSON: {e}")))?;
    let card = card::card(&json);
    report::write_report(page, o, &summary, &card, out)?;
    arrays::write_arrays(o, out)?;
    Ok((count + repeat_files, card))
}

/// The rows of `results.csv`, one per scheme × ratio.
pub fn result_rows(name: &str, o: &RunOutcome) -> Vec<ResultRow> {
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

/// timings.json of `run`: the wall-clock times of the stages and each solve's CPU time, the
/// only figures that differ between two runs with one seed (summary.json and results.csv are
/// byte-identical).
pub fn run_timings(o: &RunOutcome) -> serde_json::Value {
    serde_json::json!({
        "date_utc": super::summary::utc_now(),
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

/// The printed CMRR: the bench's (with the arms' k±) and the electronics' alone, in dB. The
/// model's RF output is G·(I₊ − I₋), an ideal subtraction (src/detector/bap.rs), so its only
/// common-mode leak is the imbalance: with none (diodes' flat responsivity scales equal, or an
/// electrical imbalance of exactly zero) the ratio is unbounded, which a line of its own says
/// rather than "inf dB" (summary.json writes null).
fn cmrr_lines(bench_db: f64, electronics_db: f64) -> Vec<String> {
    let db = |v: f64| {
        if v.is_finite() {
            format!("{v:.1} dB")
        } else if v == f64::INFINITY {
            "unbounded".to_string()
        } else {
            "undefined".to_string()
        }
    };
    let mut lines = vec![format!(
        "  CMRR: bench {} (with the arms' k±), electronics alone {}",
        db(bench_db),
        db(electronics_db)
    )];
    let reason = match (bench_db == f64::INFINITY, electronics_db == f64::INFINITY) {
        (true, true) => "the diodes' responsivity scales match exactly, and so do the arms' k±",
        (false, true) => "the diodes' responsivity scales match exactly",
        (true, false) => "the electrical imbalance is exactly zero",
        (false, false) => return lines,
    };
    lines.push(format!("    unbounded: {reason};"));
    lines.push(
        "    the model's RF output subtracts the diodes' currents ideally: the amplifier's own"
            .into(),
    );
    lines.push("    finite CMRR is not modelled".into());
    lines
}

/// What `spibench run` prints (stdout): the findings first, then the stage times, the traced
/// gains and offsets, the electronics and a table of the scores; saturation is warned about
/// apart (`RunOutcome::saturation`).
pub fn printed(
    name: &str,
    o: &RunOutcome,
    found: &findings::Findings,
    repeats: Option<&crate::run::repeats::Repeats>,
) -> Vec<String> {
    let mut out = Vec::new();
    let t = &o.transport;
    let pm = |e: crate::transport::Estimate| format!("{:.4e} ± {:.1e}", e.value, e.stderr);
    out.push(format!(
        "{name}: {}×{} units, {} rays (seed {})",
        t.units_across, t.units_down, t.rays, o.seed
    ));
    // The result first: which scheme wins where, and whether the lead is tested.
    out.extend(found.printed());
    out.push(format!(
        "  trace {:.1} s, record {:.1} s, solve {:.1} s",
        o.timings.trace_s, o.timings.record_s, o.timings.solve_s
    ));
    out.push(format!(
        "  k+ = {} A/W, k- = {} A/W, k' = {} A/W",
        pm(t.k[0]),
        pm(t.k[1]),
        pm(t.k_prime)
    ));
    out.push(format!(
        "  imbalance = {}, b+ = {} A, b- = {} A",
        pm(t.imbalance),
        pm(t.b[0]),
        pm(t.b[1])
    ));
    let ch = &o.channels;
    out.push(format!(
        "  detector: RF {:.0} V/A (±{} V), monitors {:.0}/{:.0} V/A",
        o.detector.rf.gain_v_per_a,
        o.detector.rf.swing_v,
        o.detector.monitors[0].gain_v_per_a,
        o.detector.monitors[1].gain_v_per_a,
    ));
    out.extend(cmrr_lines(o.cmrr().value, o.detector.cmrr_db()));
    out.push(format!(
        "  scope: {:.3e} S/s, RF {:.0e} V/div, MON+ {:.0e} V/div, MON- {:.0e} V/div",
        o.scope.sample_rate_hz, ch[0].volts_per_div, ch[1].volts_per_div, ch[2].volts_per_div
    ));
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
                out.extend(table_blocks(&title, &columns, &rows));
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
            out.extend(table_blocks("MSSIM (PSNR dB), one run", &columns, &scores));
        }
    }
    if let Some(c) = &o.resolution {
        out.push(format!(
            "  finest USAF element resolved (group/element; x itself: {}; registration r = {:.3})",
            element_text(c.ideal_finest_resolved),
            c.registration_correlation
        ));
        let finest = cells(&|res| element_text(res.finest_resolved));
        out.extend(table_blocks("", &columns, &finest));
    }
    out
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

    /// "Settings that reproduce this page" is RON that `run` reads back into the same bench
    /// and run settings.
    #[test]
    fn effective_bench_reads_back() {
        let doc = crate::scene::doc::BenchDoc::paper().unwrap();
        let text = effective_ron(&doc, 12_345).unwrap();
        let back =
            crate::scene::doc::BenchDoc::parse(&text, std::path::Path::new("bench.ron")).unwrap();
        assert_eq!(back.to_ron().unwrap(), text);
        let scene = back.run_scene().unwrap();
        assert_eq!(scene.settings.rays, 12_345);
        let mut original = doc.clone();
        original.file.run.rays = 12_345;
        assert_eq!(back.file, original.file);
    }

    /// A finite CMRR prints in dB on one line; an unbounded one says so and why, never "inf",
    /// and every line fits the 100 columns of the terminal.
    #[test]
    fn cmrr_lines_say_unbounded_not_inf() {
        assert_eq!(
            cmrr_lines(41.04, 30.5),
            ["  CMRR: bench 41.0 dB (with the arms' k±), electronics alone 30.5 dB"]
        );
        for (bench, electronics, why) in [
            (41.0, f64::INFINITY, "responsivity scales match exactly;"),
            (f64::INFINITY, 30.5, "electrical imbalance is exactly zero"),
            (f64::INFINITY, f64::INFINITY, "and so do the arms' k±"),
        ] {
            let lines = cmrr_lines(bench, electronics);
            let text = lines.join("\n");
            assert!(text.contains("unbounded") && text.contains(why), "{text}");
            assert!(text.contains("finite CMRR is not modelled"), "{text}");
            assert!(!text.to_lowercase().contains("inf"), "{text}");
            assert!(lines.iter().all(|l| l.chars().count() <= 100), "{text}");
        }
        assert!(cmrr_lines(f64::NAN, 30.5)[0].contains("bench undefined"));
    }
}
