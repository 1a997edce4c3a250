//! `spibench align BENCH --free PATH=LO:HI [--free …] --objective balance|power|weighted
//! [--weight METRIC=W …] [--rays N] [--start-rays N] [--seed S] [--out DIR]`: the free bench
//! variables that optimise an objective (crate::align: Nelder–Mead on common-random-number
//! traces, the ray count raised as it converges).
//!
//! Output (DIR): `aligned.ron` (the aligned bench, which every command reads), `summary.json`
//! (the free variables at the start and at the optimum, every metric of both benches with its
//! standard error and the paired standard error of the change), `history.csv` and
//! `history.svg/png` (the convergence), `layout_before.svg`, `layout_after.svg` and
//! `report.html`.

use anyhow::Result;
use clap::{Args, ValueEnum};
use serde::Serialize;

use crate::align::{AlignOptions, Alignment, Free, Objective, align};
use crate::report::csv::write_csv;
use crate::report::html::{Block, Page, write_page};
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, Series, write_plot};
use crate::scene::doc::BenchDoc;
use crate::transport::metrics::{METRICS, MetricRow};

use super::rows::Row;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObjectiveArg {
    /// Minimise |imbalance| (plus --offset-weight × |b₋ − b₊|/(b₊ + b₋) when given) with k±
    /// held at --min-fraction of their best.
    Balance,
    /// Maximise k₊ + k₋.
    Power,
    /// Minimise Σ W·METRIC over the --weight flags.
    Weighted,
}

/// Arguments of `spibench align`.
#[derive(Debug, Clone, Args)]
#[command(
    mut_arg("rays", |a| a.default_value("200000")
        .help("Lamp rays of the last stage (and of the reported benches)")),
    mut_arg("seed", |a| a.default_value("1")),
    mut_arg("set", |a| a.help("Set a bench variable of the starting bench first (repeatable)")),
    mut_arg("out", |a| a.default_value("out/align")),
)]
pub struct AlignArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    /// A free variable and its bounds, PATH=LO:HI (the variable's values; a rigid-body move
    /// such as `detectors.minus.decenter_mm.x` starts at 0).
    #[arg(long, value_name = "PATH=LO:HI", required = true)]
    pub free: Vec<String>,
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

/// `align`'s default ray count of the last stage (also set on the flag, for `--help`).
const DEFAULT_RAYS: u64 = 200_000;

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
    files: &'a [String],
}

#[derive(Serialize)]
struct FreeSummary<'a> {
    path: &'a str,
    lo: f64,
    hi: f64,
    start: f64,
    aligned: f64,
    /// The start and the result counted from the bench file: a rigid-body move includes the
    /// `--set` moves of the same path (for a field, the same as `start`, `aligned`).
    start_from_file: f64,
    aligned_from_file: f64,
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

/// Whether `path` names a rigid-body move (src/scene/variables.rs: `ELEMENT.decenter_mm.x|y`,
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
/// move, the `--set` moves of the same path (applied in order, they add up along one axis).
fn from_file(path: &str, start: f64, set: &[String]) -> crate::Result<f64> {
    if !is_move(path) {
        return Ok(start);
    }
    let mut total = start;
    for text in set {
        let (p, v) = super::parse_assignment(text, "--set")?;
        if p == path {
            total += v;
        }
    }
    Ok(total)
}

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
fn check_weights(objective: &Objective) -> crate::Result<()> {
    let max = crate::checked::MAX_SCALAR;
    let weights: Vec<(&str, f64)> = match objective {
        Objective::Balance { offset_weight, .. } => vec![("--offset-weight", *offset_weight)],
        Objective::Power => Vec::new(),
        Objective::Weighted(w) => w.iter().map(|(_, v)| ("--weight", *v)).collect(),
    };
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
    let (name, doc) = args.bench.load()?;
    let free: Vec<Free> = args
        .free
        .iter()
        .map(|f| Free::parse(f))
        .collect::<crate::Result<_>>()?;
    for f in &free {
        doc.get(&f.path)?;
    }
    let objective = objective(args)?;
    check_weights(&objective)?;
    crate::align::check_objective(&objective)?;
    let opts = &args.bench.opts;
    let rays = opts.rays_or(DEFAULT_RAYS, super::args::MIN_RAYS_WITH_STDERR)?;
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
    let aligned = doc.with(&a.settings())?;
    let mut files: Vec<String> = [
        "aligned.ron",
        "summary.json",
        "history.csv",
        "history.svg",
        "history.png",
        "layout_before.svg",
        "layout_after.svg",
        "report.html",
    ]
    .map(String::from)
    .to_vec();
    let path = out.path("aligned.ron");
    std::fs::write(&path, aligned.to_ron()?).map_err(|e| crate::Error::write(&path, e))?;

    write_history(&a, &free, &out)?;

    report_page(
        &out,
        &name,
        args,
        (&free, &o, &a),
        (&doc, &aligned),
        t0.elapsed().as_secs_f64(),
    )?;
    let summary = AlignSummary {
        command: "align",
        spibench_version: env!("CARGO_PKG_VERSION"),
        scene: &name,
        objective: format!("{objective:?}"),
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
        free: free_summaries(&free, &a, &args.bench.set)?,
        start: Row::metrics(&a.start, &a.start),
        aligned: Row::metrics(&a.best, &a.start),
        files: &files,
    };
    let provenance = super::run::bench_provenance(&name, &doc, &[o.seed])?;
    super::provenance::write_summary(&out, &summary, &provenance)?;
    files.sort();
    let dir = out.commit()?;
    let imb = a.best.metrics.get("imbalance").map(|m| m.estimate());
    for w in &a.warnings {
        eprintln!("warning: {w}");
    }
    // One line per variable, so that the output fits a terminal whatever the paths.
    println!("aligned; the search stopped because {}", a.stop.describe());
    for f in free_summaries(&free, &a, &args.bench.set)? {
        println!(
            "  {} = {:.5}{} (start {:.5}; counted from the bench file)",
            f.path,
            f.aligned_from_file,
            match (f.half_width, f.flat_toward) {
                (Some(h), _) => format!(" ± {h:.2e}"),
                (None, Some(side)) => format!(" (plateau edge, flat toward {side})"),
                (None, None) => " (flat)".to_string(),
            },
            f.start_from_file
        );
    }
    println!(
        "imbalance {}; wrote {}",
        imb.map_or_else(String::new, |e| format!(
            "{:.3e} ± {:.1e}",
            e.value, e.stderr
        )),
        dir.display()
    );
    Ok(())
}

/// The command's parsed objective.
fn objective(args: &AlignArgs) -> crate::Result<Objective> {
    Ok(match args.objective {
        ObjectiveArg::Balance => Objective::Balance {
            min_fraction: args.min_fraction,
            offset_weight: args.offset_weight,
        },
        ObjectiveArg::Power => Objective::Power,
        ObjectiveArg::Weighted => Objective::Weighted(
            args.weight
                .iter()
                .map(|w| super::parse_assignment(w, "--weight"))
                .collect::<crate::Result<_>>()?,
        ),
    })
}

/// report.html: what was searched and why it stopped, the warnings, the tables, the
/// convergence plot and the layouts before and after (`layout_before.svg`, `layout_after.svg`
/// written beside it).
fn report_page(
    out: &OutputDir,
    name: &str,
    args: &AlignArgs,
    (free, o, a): (&[Free], &AlignOptions, &Alignment),
    (doc, aligned): (&BenchDoc, &BenchDoc),
    seconds: f64,
) -> crate::Result<()> {
    let mut blocks = vec![Block::Paragraph(format!(
        "{name}: {} free variable(s), objective {:?}; {} evaluations in {:.1} s (Nelder–Mead on \
         common-random-number traces, {} → {} rays), stopped because {}. The returned point is \
         the best of {} candidates traced again with {} rays on a fresh seed ({}). The start \
         and the aligned bench are traced with {} rays and seed {}; their difference carries a \
         paired standard error.",
        free.len(),
        args.objective,
        a.history.len(),
        seconds,
        o.start_rays,
        o.max_rays,
        a.stop.describe(),
        a.candidates.len(),
        a.compare_rays,
        a.compare_seed,
        o.max_rays,
        o.seed
    ))];
    for w in &a.warnings {
        blocks.push(Block::Paragraph(format!("Warning: {w}.")));
    }
    blocks.extend(tables(free, a));
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
    set: &[String],
) -> crate::Result<Vec<FreeSummary<'a>>> {
    let finite = |v: f64| v.is_finite().then_some(v);
    free.iter()
        .enumerate()
        .map(|(i, f)| {
            let (start, aligned) = (a.start_values[i], a.best_values[i]);
            let start_from_file = from_file(&f.path, start, set)?;
            let u = &a.uncertainty[i];
            Ok(FreeSummary {
                path: &f.path,
                lo: f.lo,
                hi: f.hi,
                start,
                aligned,
                start_from_file,
                aligned_from_file: start_from_file + (aligned - start),
                half_width: finite(u.half_width),
                rise_minus: finite(u.rise_minus),
                rise_plus: finite(u.rise_plus),
                flat_toward: u.flat_toward.map(|k| if k < 0 { "-" } else { "+" }),
                at_bound: u.at_bound,
            })
        })
        .collect()
}

/// `history.csv` and the convergence plot `history.svg`/`.png`: every evaluation's stage,
/// rays, free values, objective with its standard error, imbalance and k±.
fn write_history(a: &Alignment, free: &[Free], out: &OutputDir) -> crate::Result<()> {
    let mut header: Vec<String> = vec!["evaluation".into(), "stage".into(), "rays".into()];
    header.extend(free.iter().map(|f| f.path.clone()));
    header.extend(
        [
            "objective",
            "objective_stderr",
            "imbalance",
            "imbalance_stderr",
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
fn tables(free: &[Free], a: &Alignment) -> Vec<Block> {
    let mut blocks = Vec::new();
    let var_rows: Vec<Vec<String>> = free
        .iter()
        .zip(a.start_values.iter().zip(&a.best_values))
        .zip(&a.uncertainty)
        .map(|((f, (s, b)), u)| {
            vec![
                f.path.clone(),
                format!("{} … {}", f.lo, f.hi),
                format!("{s:.6}"),
                format!("{b:.6}"),
                match (u.half_width.is_finite(), u.flat_toward) {
                    (true, _) => format!("{:.2e}", u.half_width),
                    (false, Some(k)) => format!(
                        "edge of a plateau: flat toward {}",
                        if k < 0 { "−" } else { "+" }
                    ),
                    (false, None) => "flat within the noise".into(),
                },
            ]
        })
        .collect();
    blocks.push(Block::Table {
        caption: Some(
            "Free variables (values on the starting bench; ± where the objective rises by its \
             paired standard error, from its curvature)"
                .into(),
        ),
        header: ["variable", "bounds", "start", "aligned", "±"]
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
    for (i, (m, unit, _)) in METRICS.iter().enumerate() {
        let (s, b) = (&a.start.metrics.values[i], &a.best.metrics.values[i]);
        let r = MetricRow::new(b, s);
        mrows.push(vec![
            format!("{m} ({unit})"),
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
            "detectors.minus.decenter_mm.x=1.0".to_string(),
            "detectors.minus.decenter_mm.y=0.5".to_string(),
        ];
        assert_eq!(
            from_file("detectors.minus.decenter_mm.x", 0.0, &set).unwrap(),
            1.0
        );
        assert_eq!(
            from_file("detectors.minus.diameter_mm", 5.0, &set).unwrap(),
            5.0
        );
    }

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
