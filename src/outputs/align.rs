//! The outputs of `spibench align` (docs/outputs.md, "align"): `aligned.ron` (the aligned bench,
//! which every command reads), `summary.json` (the free variables at the start and at the
//! optimum, every metric of both benches with its standard error and the paired standard error
//! of the change), `history.csv` and `history.svg/png` (the convergence), `layout_before.svg`,
//! `layout_after.svg` and `report.html`.

use serde::Serialize;

use crate::align::{AlignOptions, Alignment, Free, Objective};
use crate::quantities::BenchMetric;
use crate::report::csv::write_csv;
use crate::report::html::{Block, Page, write_page};
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, Series, write_plot};
use crate::scene::doc::BenchDoc;
use crate::transport::metrics::MetricRow;

use super::rows::Row;

/// The files `align` writes, in its summary's order.
pub const FILES: [&str; 8] = [
    "aligned.ron",
    "summary.json",
    "history.csv",
    "history.svg",
    "history.png",
    "layout_before.svg",
    "layout_after.svg",
    "report.html",
];

/// What an alignment's outputs are drawn from.
pub struct AlignRun<'a> {
    /// The bench's name, and the starting bench (the bench file with its `--set` edits).
    pub name: &'a str,
    pub doc: &'a BenchDoc,
    pub free: &'a [Free],
    pub objective: &'a Objective,
    pub options: &'a AlignOptions,
    pub alignment: &'a Alignment,
    /// The search's wall-clock time (s), for the report.
    pub seconds: f64,
}

/// The objective's kind as the report names it: `Balance`, `Power`, `Weighted` or `Centre`.
fn kind(o: &Objective) -> &'static str {
    match o {
        Objective::Balance { .. } => "Balance",
        Objective::Power => "Power",
        Objective::Weighted(_) => "Weighted",
        Objective::Centre => "Centre",
    }
}

/// Writes every output of an alignment into `out` (a staging folder) and returns the files
/// written, sorted.
pub fn write(
    r: &AlignRun<'_>,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<(Vec<String>, crate::outputs::card::Card)> {
    let (a, o) = (r.alignment, r.options);
    let aligned = r.doc.with(&a.settings())?;
    let mut files: Vec<String> = FILES.map(String::from).to_vec();
    let path = out.path("aligned.ron");
    std::fs::write(&path, aligned.to_ron()?).map_err(|e| crate::Error::write(&path, e))?;
    write_history(a, r.free, out)?;
    let summary = AlignSummary {
        command: "align",
        spibench_version: env!("CARGO_PKG_VERSION"),
        scene: r.name,
        objective: format!("{:?}", r.objective),
        objective_terms: &a.terms,
        stop: a.stop,
        stop_reason: a.stop.describe(),
        compare_rays: a.compare_rays,
        compare_seed: a.compare_seed,
        candidates: &a.candidates,
        warnings: &a.warnings,
        rays: o.max_rays,
        start_rays: o.start_rays,
        seed: o.seed,
        evaluations: a.history.len(),
        free: free_summaries(r.free, a, r.doc.edits()),
        start: row(&a.start, &a.start),
        aligned: row(&a.best, &a.start),
        centre: centre_summary(a),
        files: &files,
    };
    let json = serde_json::to_value(&summary)
        .map_err(|e| crate::Error::Numerical(format!("the align summary as JSON: {e}")))?;
    let card = card(&json);
    report_page(out, r, &aligned, &card)?;
    super::summary::write_summary(out, &summary, provenance)?;
    files.sort();
    Ok((files, card))
}

/// The metric row of `p` against `reference` ([`Row::metrics`]), ending, as a tolerance row
/// does, with the electrical imbalance ι′ (`imbalance_electrical`, the balance objective's),
/// its standard error, its change and that change's paired and independent standard errors
/// (NaN, written null, where the electronics are not valid).
fn row(
    p: &crate::pipeline::evaluate::Evaluation,
    reference: &crate::pipeline::evaluate::Evaluation,
) -> Row {
    let electrical = |e: &crate::pipeline::evaluate::Evaluation| {
        let mut v = crate::tolerance::values(e, reference);
        let (i, i0) = (e.electrical_imbalance(), reference.electrical_imbalance());
        let d = i.as_ref().zip(i0.as_ref()).map(|(a, b)| {
            let mut d = a.diff(b);
            if a.value == b.value {
                // The same bench: no change (and no standard error of one).
                d.stderr = 0.0;
            }
            d
        });
        let name = crate::scene::tolerance::IMBALANCE_ELECTRICAL;
        let nan = f64::NAN;
        v.push((name.to_string(), i.as_ref().map_or(nan, |i| i.value)));
        v.push((
            format!("{name}_stderr"),
            i.as_ref().map_or(nan, |i| i.stderr()),
        ));
        v.push((format!("{name}_diff"), d.map_or(nan, |d| d.value)));
        v.push((format!("{name}_diff_stderr"), d.map_or(nan, |d| d.stderr)));
        v
    };
    Row::from_values(&electrical(p), &electrical(reference))
}

/// The summary card of `align` (from its summary.json as a value): why the search stopped,
/// each free variable as the bench file counts it with the move made, and the electrical
/// imbalance (the detector's, which the balance objective minimises), the optical one and k′
/// at the start and after.
pub fn card(summary: &serde_json::Value) -> crate::outputs::card::Card {
    use crate::outputs::card::{Card, num, pm};
    let mut c = Card::new("summary");
    c.line(summary, "stopped", &["/stop_reason", "/evaluations"], |v| {
        format!("{} ({} evaluations)", v[0].as_str().unwrap_or(""), v[1])
    });
    for i in 0..crate::outputs::card::array_len(summary, "/free") {
        let f = format!("/free/{i}");
        let keys = [
            "path",
            "aligned_from_file",
            "half_width",
            "moved",
            "start_from_file",
        ]
        .map(|k| format!("{f}/{k}"));
        c.line(summary, format!("free {}", i + 1), &keys, |v| {
            format!(
                "{} = {}, moved {:+.5} from {:.5}",
                v[0].as_str().unwrap_or(""),
                pm(num(&v[1]), num(&v[2]), ""),
                num(&v[3]),
                num(&v[4])
            )
        });
    }
    for (label, key, unit) in [
        ("electrical imbalance", "imbalance_electrical", ""),
        ("optical imbalance", "imbalance", ""),
        ("k′", "k_prime", "A/W"),
    ] {
        let keys = [
            format!("/start/{key}"),
            format!("/start/{key}_stderr"),
            format!("/aligned/{key}"),
            format!("/aligned/{key}_stderr"),
            format!("/aligned/{key}_diff"),
            format!("/aligned/{key}_diff_stderr"),
        ];
        c.line(summary, label, &keys, |v| {
            format!(
                "{} → {} (change {})",
                pm(num(&v[0]), num(&v[1]), unit),
                pm(num(&v[2]), num(&v[3]), unit),
                pm(num(&v[4]), num(&v[5]), unit)
            )
        });
    }
    // With the centre objective: each spot's offset from its diode's centre and the margin
    // (mm, the bench file's unit), before → after.
    for (i, sign) in ["+", "−"].into_iter().enumerate() {
        let d = format!("/centre/diodes/{i}");
        if summary.pointer(&d).is_none() {
            continue;
        }
        let keys = [
            "start/centroid_offset_m",
            "start/centroid_offset_stderr_m",
            "aligned/centroid_offset_m",
            "aligned/centroid_offset_stderr_m",
            "aligned/centre_margin_m",
            "aligned/centre_margin_stderr_m",
        ]
        .map(|k| format!("{d}/{k}"));
        c.line(summary, format!("{sign} spot offset"), &keys, |v| {
            let mm = |k: usize| num(&v[k]) * 1e3;
            format!(
                "{} → {} (margin {})",
                pm(mm(0), mm(1), "mm"),
                pm(mm(2), mm(3), "mm"),
                pm(mm(4), mm(5), "mm")
            )
        });
    }
    c
}

/// What `spibench align` prints: why the search stopped, each free variable (counted from the
/// bench file) with its ± or why it has none, and the imbalance reached (electrical and
/// optical); warnings are printed
/// apart (`Alignment::warnings`).
pub fn printed(r: &AlignRun<'_>, dir: &std::path::Path) -> Vec<String> {
    let a = r.alignment;
    let imb = a.best.metrics[BenchMetric::Imbalance].estimate();
    let electrical = a.best.electrical_imbalance().map_or(f64::NAN, |e| e.value);
    let electrical_se = a
        .best
        .electrical_imbalance()
        .map_or(f64::NAN, |e| e.stderr());
    // One line per variable, so that the output fits a terminal whatever the paths.
    let mut out = vec![format!(
        "aligned; the search stopped because {}",
        a.stop.describe()
    )];
    out.push("  (each variable as the bench file counts it, and the move from the start)".into());
    for f in free_summaries(r.free, a, r.doc.edits()) {
        out.push(format!(
            "  {} = {:.5}{}, moved {:+.5} from {:.5}",
            f.path,
            f.aligned_from_file,
            uncertainty_text(&f),
            f.moved,
            f.start_from_file
        ));
    }
    out.push(format!(
        "imbalance {electrical:.3e} ± {electrical_se:.1e} electrical (the detector's), \
         {:.3e} ± {:.1e} optical; wrote {}",
        imb.value,
        imb.stderr,
        dir.display()
    ));
    out
}

/// A free variable's ± or why it has none, as the terminal and the report say it.
fn uncertainty_text(f: &FreeSummary<'_>) -> String {
    match (f.half_width, f.flat_toward) {
        (Some(h), _) => format!(" ± {h:.2e}"),
        (None, Some(side)) => format!(" (plateau edge, flat toward {side})"),
        (None, None) => " (flat within the noise)".to_string(),
    }
}

/// `summary.json` of `align`.
#[derive(Serialize)]
struct AlignSummary<'a> {
    command: &'static str,
    spibench_version: &'static str,
    scene: &'a str,
    /// `Balance`, `Power` or the weighted sum, as Rust's `Debug` writes it.
    objective: String,
    /// The objective's terms at the aligned bench (standard errors paired with the start).
    objective_terms: &'a [crate::pipeline::optimise::Term],
    /// Why the search's last stage ended (`NoiseFloor`, `SimplexSize`, `Budget`) and in words.
    stop: crate::pipeline::optimise::SearchStop,
    stop_reason: &'static str,
    /// The final paired comparison: its rays and seed, and each candidate (the returned point
    /// first) with its objective and paired difference from the returned point.
    compare_rays: u64,
    compare_seed: u64,
    candidates: &'a [crate::align::Candidate],
    /// The result on a bound, an objective flat within its noise.
    warnings: &'a [String],
    rays: u64,
    start_rays: u64,
    seed: u64,
    evaluations: usize,
    free: Vec<FreeSummary<'a>>,
    /// The metrics of the starting bench ([`Row::metrics`] against itself: zero differences).
    start: Row,
    /// The metrics of the aligned bench against the start: `M_diff` is the change, with its
    /// paired standard error `M_diff_stderr`.
    aligned: Row,
    /// With the centre objective: where each diode's spot lands, at the start and aligned.
    centre: Option<CentreSummary>,
    files: &'a [String],
}

/// The centre objective's numbers: each diode's spot at the start and at the aligned bench
/// (the same traces as `start` and `aligned`).
#[derive(Serialize)]
struct CentreSummary {
    /// k of the margin: active radius − (centroid offset + k·RMS radius).
    rms_radii: f64,
    diodes: Vec<CentreDiode>,
}

#[derive(Serialize)]
struct CentreDiode {
    diode: &'static str,
    active_radius_m: f64,
    start: SpotSummary,
    aligned: SpotSummary,
    /// aligned − start of the centroid's offset, and the standard error of that difference
    /// from the two traces' own errors (unpaired: the maps keep no per-batch totals).
    centroid_offset_change_m: Option<f64>,
    centroid_offset_change_stderr_m: Option<f64>,
}

#[derive(Serialize)]
struct SpotSummary {
    /// Null where no light was mapped.
    centre_margin_m: Option<f64>,
    centre_margin_stderr_m: f64,
    /// The centroid in the diode's (u, v) axes from the active area's centre, its error.
    centroid_m: [f64; 2],
    centroid_stderr_m: [f64; 2],
    /// Its distance from the centre, and the error of that.
    centroid_offset_m: f64,
    centroid_offset_stderr_m: f64,
    rms_radius_m: f64,
    spill: f64,
}

/// The centre summary, when the start and the result carry their spots (the centre
/// objective).
fn centre_summary(a: &Alignment) -> Option<CentreSummary> {
    let (s, b) = (a.start.spots?, a.best.spots?);
    let finite = |v: f64| v.is_finite().then_some(v);
    let spot = |p: &crate::pipeline::evaluate::Spot| SpotSummary {
        centre_margin_m: finite(p.margin_m),
        centre_margin_stderr_m: p.margin_stderr_m,
        centroid_m: p.stats.centroid_m,
        centroid_stderr_m: p.stats.centroid_stderr_m,
        centroid_offset_m: p.offset_m,
        centroid_offset_stderr_m: p.offset_stderr_m,
        rms_radius_m: p.stats.rms_radius_m,
        spill: p.stats.spill,
    };
    let mapped = |p: &crate::pipeline::evaluate::Spot| p.stats.active_w > 0.0;
    Some(CentreSummary {
        rms_radii: crate::pipeline::optimise::CENTRE_RMS_RADII,
        diodes: (0..2)
            .map(|d| {
                let both = mapped(&s[d]) && mapped(&b[d]);
                CentreDiode {
                    diode: ["pd_plus", "pd_minus"][d],
                    active_radius_m: s[d].active_radius_m,
                    start: spot(&s[d]),
                    aligned: spot(&b[d]),
                    centroid_offset_change_m: both.then(|| b[d].offset_m - s[d].offset_m),
                    centroid_offset_change_stderr_m: both
                        .then(|| b[d].offset_stderr_m.hypot(s[d].offset_stderr_m)),
                }
            })
            .collect(),
    })
}

#[derive(Serialize)]
struct FreeSummary<'a> {
    path: &'a str,
    lo: f64,
    hi: f64,
    start: f64,
    aligned: f64,
    /// The start and the result counted from the bench file: a rigid-body move includes the
    /// moves of the same path set before the search (for a field, the same as `start`, `aligned`).
    start_from_file: f64,
    aligned_from_file: f64,
    /// The move the alignment made, aligned − start (the same in either frame).
    moved: f64,
    /// ± this much raises the objective by its paired standard error (null: flat).
    half_width: Option<f64>,
    /// The objective's rises at the probes − and + (null where not probed).
    rise_minus: Option<f64>,
    rise_plus: Option<f64>,
    /// `-` or `+`: the objective stays flat within its noise toward that side and rises
    /// toward the other (the result is at the edge of a plateau); null otherwise.
    flat_toward: Option<&'static str>,
    at_bound: bool,
}

/// Whether `path` names a rigid-body move (src/scene/variables/moves.rs: `ELEMENT.decenter_mm.x|y`,
/// `ELEMENT.despace_mm`, `ELEMENT.tilt_deg.x|y`), whose value counts from the starting bench.
fn is_move(path: &str) -> bool {
    let parts: Vec<&str> = path.split('.').collect();
    match parts.as_slice() {
        [.., "despace_mm"] => parts.len() >= 2,
        [.., "decenter_mm" | "tilt_deg", "x" | "y"] => parts.len() >= 3 && parts[0] != "dmd",
        _ => false,
    }
}

/// The value of a free variable at the start counted from the bench file: for a rigid-body
/// move, the edits of the same path set on the bench before the search (`--set`; applied in
/// order, they add up along one axis).
fn from_file(path: &str, start: f64, edits: &[(String, f64)]) -> f64 {
    if !is_move(path) {
        return start;
    }
    start
        + edits
            .iter()
            .filter(|(p, _)| p == path)
            .map(|(_, v)| v)
            .sum::<f64>()
}

/// report.html: what was searched and why it stopped, the warnings, the tables, the
/// convergence plot and the layouts before and after (`layout_before.svg`, `layout_after.svg`
/// written beside it).
fn report_page(
    out: &OutputDir,
    r: &AlignRun<'_>,
    aligned: &BenchDoc,
    card: &crate::outputs::card::Card,
) -> crate::Result<()> {
    let (name, free, o, a, doc) = (r.name, r.free, r.options, r.alignment, r.doc);
    let mut blocks = vec![
        card.block(),
        Block::Paragraph(format!(
            "{name}: {} free variable(s), objective {:?}; {} evaluations in {:.1} s (Nelder–Mead on \
         common-random-number traces, {} → {} rays), stopped because {}. The returned point is \
         the best of {} candidates traced again with {} rays on a fresh seed ({}). The start \
         and the aligned bench are traced with {} rays and seed {}; their difference carries a \
         paired standard error.",
            free.len(),
            kind(r.objective),
            a.history.len(),
            r.seconds,
            o.start_rays,
            o.max_rays,
            a.stop.describe(),
            a.candidates.len(),
            a.compare_rays,
            a.compare_seed,
            o.max_rays,
            o.seed
        )),
    ];
    for w in &a.warnings {
        blocks.push(Block::Paragraph(format!("Warning: {w}.")));
    }
    blocks.extend(tables(&free_summaries(free, a, doc.edits()), a));
    let svg = std::fs::read_to_string(out.path("history.svg"))
        .map_err(|e| crate::Error::read(&out.path("history.svg"), e))?;
    blocks.push(Block::Svg {
        caption: "Convergence: the objective at each evaluation (stages trace more rays)".into(),
        svg,
    });
    for (file, d, title) in [
        ("layout_before.svg", doc, "before"),
        ("layout_after.svg", aligned, "after"),
    ] {
        let (block, svg) =
            super::layout::layout_block(&d.build()?, &format!("{name}, {title} alignment"))?;
        let path = out.path(file);
        std::fs::write(&path, &svg).map_err(|e| crate::Error::write(&path, e))?;
        blocks.push(Block::Heading {
            level: 2,
            text: format!("Layout {title}"),
        });
        blocks.push(block);
    }
    let blocks = crate::report::html::fold_long_paragraphs(blocks, 320);
    write_page(
        &out.path("report.html"),
        &Page {
            title: format!("spibench align of {name}"),
            blocks,
        },
    )?;
    Ok(())
}

/// The free variables' summaries: bounds, start and result (also counted from the file) and
/// their uncertainty.
fn free_summaries<'a>(
    free: &'a [Free],
    a: &Alignment,
    edits: &[(String, f64)],
) -> Vec<FreeSummary<'a>> {
    let finite = |v: f64| v.is_finite().then_some(v);
    free.iter()
        .enumerate()
        .map(|(i, f)| {
            let (start, aligned) = (a.start_values[i], a.best_values[i]);
            let start_from_file = from_file(&f.path, start, edits);
            let u = &a.uncertainty[i];
            FreeSummary {
                path: &f.path,
                lo: f.lo,
                hi: f.hi,
                start,
                aligned,
                start_from_file,
                aligned_from_file: start_from_file + (aligned - start),
                moved: aligned - start,
                half_width: finite(u.half_width),
                rise_minus: finite(u.rise_minus),
                rise_plus: finite(u.rise_plus),
                flat_toward: u.flat_toward.map(|k| if k < 0 { "-" } else { "+" }),
                at_bound: u.at_bound,
            }
        })
        .collect()
}

/// `history.csv` and the convergence plot `history.svg`/`.png`: every evaluation's stage,
/// rays, free values, objective with its standard error, the optical and the electrical
/// imbalance with theirs, and k±.
fn write_history(a: &Alignment, free: &[Free], out: &OutputDir) -> crate::Result<()> {
    let mut header: Vec<String> = vec!["evaluation".into(), "stage".into(), "rays".into()];
    header.extend(free.iter().map(|f| f.path.clone()));
    header.extend(
        [
            "objective",
            "objective_stderr",
            "imbalance",
            "imbalance_stderr",
            "imbalance_electrical",
            "imbalance_electrical_stderr",
            "k_plus",
            "k_minus",
        ]
        .map(String::from),
    );
    let rows: Vec<Vec<String>> = a
        .history
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let mut r = vec![i.to_string(), e.stage.to_string(), e.rays.to_string()];
            r.extend(e.values.iter().map(|v| format!("{v:e}")));
            r.extend(
                [
                    e.objective,
                    e.objective_stderr,
                    e.imbalance,
                    e.imbalance_stderr,
                    e.imbalance_electrical,
                    e.imbalance_electrical_stderr,
                    e.k_plus,
                    e.k_minus,
                ]
                .map(|v| format!("{v:e}")),
            );
            r
        })
        .collect();
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(&out.path("history.csv"), &h, &rows)?;
    let finite: Vec<(f64, f64, f64)> = a
        .history
        .iter()
        .enumerate()
        .filter(|(_, e)| e.objective.is_finite())
        .map(|(i, e)| (i as f64, e.objective, e.objective_stderr))
        .collect();
    let mut best = f64::INFINITY;
    let plot = LinePlot {
        title: String::new(),
        x_label: "evaluation".into(),
        y_label: "objective (lower is better)".into(),
        series: vec![
            Series {
                label: "evaluated (± 1 SE)".into(),
                x: finite.iter().map(|p| p.0).collect(),
                y: finite.iter().map(|p| p.1).collect(),
                y_err: Some(
                    finite
                        .iter()
                        .map(|p| if p.2.is_finite() { p.2 } else { 0.0 })
                        .collect(),
                ),
            },
            Series {
                label: "best so far".into(),
                x: finite.iter().map(|p| p.0).collect(),
                y: finite
                    .iter()
                    .map(|p| {
                        best = best.min(p.1);
                        best
                    })
                    .collect(),
                y_err: None,
            },
        ],
        log_x: false,
    };
    write_plot(&plot, &out.path("history.svg"), &out.path("history.png"))?;
    Ok(())
}

/// The report's tables: the free variables (bounds, start, aligned) and every metric of the
/// start and the aligned bench with the change and its paired standard error.
fn tables(free: &[FreeSummary<'_>], a: &Alignment) -> Vec<Block> {
    let mut blocks = Vec::new();
    let var_rows: Vec<Vec<String>> = free
        .iter()
        .map(|f| {
            // The bounds in the bench file's frame too (a move's bounds count from the start).
            let off = f.start_from_file - f.start;
            vec![
                f.path.to_string(),
                format!("{} … {}", f.lo + off, f.hi + off),
                format!("{:.6}", f.start_from_file),
                format!("{:.6}", f.aligned_from_file),
                format!("{:+.6}", f.moved),
                uncertainty_text(f)
                    .trim_start_matches(" ± ")
                    .trim()
                    .to_string(),
            ]
        })
        .collect();
    blocks.push(Block::Table {
        caption: Some(
            "Free variables as the bench file counts them (bounds, start and aligned, as the \
             terminal and summary.json's `*_from_file` give them), the move the alignment made, \
             and ± where the objective rises by its paired standard error, from its curvature"
                .into(),
        ),
        header: ["variable", "bounds", "start", "aligned", "move", "±"]
            .map(String::from)
            .to_vec(),
        rows: var_rows,
    });
    blocks.push(Block::Table {
        caption: Some(
            "The objective's terms at the aligned bench (± paired standard error against the \
             start)"
                .into(),
        ),
        header: ["term", "value"].map(String::from).to_vec(),
        rows: a
            .terms
            .iter()
            .map(|t| {
                vec![
                    t.name.clone(),
                    format!("{:.4e} ± {:.1e}", t.value, t.stderr),
                ]
            })
            .collect(),
    });
    blocks.push(Block::Table {
        caption: Some(format!(
            "The final comparison ({} rays, seed {}): the returned point first",
            a.compare_rays, a.compare_seed
        )),
        header: ["values", "objective", "difference from the returned point"]
            .map(String::from)
            .to_vec(),
        rows: a
            .candidates
            .iter()
            .map(|c| {
                vec![
                    format!("{:?}", c.values),
                    format!("{:.4e}", c.objective),
                    format!("{:+.3e} ± {:.1e}", c.diff, c.diff_stderr),
                ]
            })
            .collect(),
    });
    let mut mrows = Vec::new();
    for m in BenchMetric::ALL {
        let (s, b) = (&a.start.metrics[m], &a.best.metrics[m]);
        let r = MetricRow::new(b, s);
        mrows.push(vec![
            format!("{m} ({})", m.unit()),
            format!("{:.4e} ± {:.1e}", s.value, s.stderr()),
            format!("{:.4e} ± {:.1e}", r.value, r.stderr),
            format!("{:+.4e} ± {:.1e}", r.diff, r.diff_stderr),
        ]);
    }
    if let (Some(s), Some(b)) = (
        a.start.electrical_imbalance(),
        a.best.electrical_imbalance(),
    ) {
        let r = MetricRow::new(&b, &s);
        mrows.push(vec![
            format!("{} (–)", crate::scene::tolerance::IMBALANCE_ELECTRICAL),
            format!("{:.4e} ± {:.1e}", s.value, s.stderr()),
            format!("{:.4e} ± {:.1e}", r.value, r.stderr),
            format!("{:+.4e} ± {:.1e}", r.diff, r.diff_stderr),
        ]);
    }
    blocks.push(Block::Table {
        caption: Some("Metrics of the start and the aligned bench (± standard error; the change ± its paired standard error)".into()),
        header: ["metric", "start", "aligned", "change"].map(String::from).to_vec(),
        rows: mrows,
    });
    blocks
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_count_from_the_file_after_set() {
        assert!(is_move("detectors.minus.decenter_mm.x"));
        assert!(is_move("arm_minus_lens.despace_mm"));
        assert!(is_move("arm_minus_lens.tilt_deg.y"));
        assert!(!is_move("arm_minus_lens.tilt_deg.0"));
        assert!(!is_move("dmd.tilt_deg"));
        assert!(!is_move("detectors.minus.diameter_mm"));
        let set = [
            ("detectors.minus.decenter_mm.x".to_string(), 1.0),
            ("detectors.minus.decenter_mm.y".to_string(), 0.5),
        ];
        assert_eq!(from_file("detectors.minus.decenter_mm.x", 0.0, &set), 1.0);
        assert_eq!(from_file("detectors.minus.diameter_mm", 5.0, &set), 5.0);
    }
}
