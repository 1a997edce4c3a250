//! The outputs of `spibench tolerance --budget` (docs/outputs.md, "tolerance --budget"):
//! `budget.ron`, the budget as a tolerance file that `spibench tolerance` reads back (each
//! tolerance's scale and share of the yield loss in comments), `summary.json`
//! (`BudgetSummary`), `budget.csv`, the figure of the surface yield against a common scale of
//! every tolerance with the target marked (`yield_vs_scale.svg`, `.png`), `report.html` and
//! `budget_trials.ron` (what `--resume` continues from).

use serde::Serialize;

use crate::report::csv::write_csv;
use crate::report::html::{Block, Page, write_page};
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, Series, write_plot};
use crate::scene::tolerance::{CompensatorObjective, Distribution, ToleranceSet};
use crate::tolerance::budget::{BudgetFigures, BudgetOutcome, BudgetRow, Round};
use crate::tolerance::budget_search::BudgetTrialsFile;

/// What the run was, for the summary and the file's heading.
#[derive(Debug, Clone)]
pub struct BudgetRun<'a> {
    pub scene: &'a str,
    pub tolerances_file: &'a str,
    pub costs_file: Option<&'a str>,
    pub rays: u64,
    pub seed: u64,
    pub trials: u64,
    /// Whether every trial ran the whole pipeline and the image-quality limit took part.
    pub quality: bool,
    /// The command words that made the budget.
    pub command: &'a str,
}

/// A number as RON text that reads back bit for bit.
fn num(v: f64) -> String {
    format!("{v:?}")
}

fn range_ron(min: f64, max: f64) -> String {
    if min == -max && max >= 0.0 {
        format!("PlusMinus({})", num(max))
    } else {
        format!("Between({}, {})", num(min), num(max))
    }
}

fn distribution_ron(d: &Distribution) -> String {
    match d {
        Distribution::Uniform => String::new(),
        Distribution::Normal { sigmas } => {
            format!(", distribution: Normal(sigmas: {})", num(*sigmas))
        }
        Distribution::TruncatedNormal { sigmas } => {
            format!(", distribution: TruncatedNormal(sigmas: {})", num(*sigmas))
        }
    }
}

/// The attenuator's entry among the compensators, as a tolerance file writes it.
pub fn attenuator_ron(a: &crate::scene::tolerance::Attenuator) -> String {
    use crate::scene::tolerance::AttenuatorArm;
    let arm = match a.arm {
        AttenuatorArm::Plus => "Plus",
        AttenuatorArm::Minus => "Minus",
        AttenuatorArm::Stronger => "Stronger",
    };
    format!(
        "        (kind: Attenuator(arm: {arm}, min_transmission: {}), objective: Balance),\n",
        num(a.min_transmission)
    )
}

/// `budget.ron`: the file's tolerances with the budget's ranges, its compensators, limits and
/// quality limit as they were; comments give the outcome and, per tolerance, its scale and its
/// share of the yield loss.
pub fn budget_ron(set: &ToleranceSet, b: &BudgetOutcome, run: &BudgetRun) -> String {
    let mut t = format!(
        "// Tolerance budget of {} for a yield of at least {} at confidence {}, from {}.\n\
         // Made by `{}`.\n",
        run.scene, b.target_yield, b.confidence, run.tolerances_file, run.command
    );
    t += &match (&b.joint.confirmation, b.reached) {
        (Some(c), true) => format!(
            "// Confirmed: {} of {} traced trials pass (yield {:.4}, one-sided Wilson lower \
             bound {:.4}).\n",
            c.passed, c.trials, c.fraction, c.lower_bound
        ),
        (c, _) => format!(
            "// NOT REACHED: {}{}.\n",
            b.reason.as_deref().unwrap_or("unknown"),
            c.as_ref().map_or(String::new(), |c| format!(
                "; this is the best budget found, {} of {} trials passing",
                c.passed, c.trials
            ))
        ),
    };
    t += &format!(
        "// Geometric-mean scale {:.4} (the one-at-a-time inverse limits: {:.4}{}).\n(\n    \
         tolerances: [\n",
        b.joint.geometric_mean_scale,
        b.baseline.geometric_mean_scale,
        scaled_note(b)
    );
    for (tol, r) in set.tolerances.iter().zip(&b.rows) {
        t += &format!(
            "        // scale {} of {}; {:.1} % of the yield loss\n        (path: {:?}, range: \
             {}{}{}),\n",
            r.scale,
            range_ron(tol.min, tol.max),
            100.0 * r.loss_share,
            tol.path,
            range_ron(r.min, r.max),
            distribution_ron(&tol.distribution),
            // A device specification stays one in the budget (it kept scale 1).
            if tol.is_fixed() { ", fixed: true" } else { "" }
        );
    }
    t += "    ],\n    compensators: [\n";
    for c in &set.compensators {
        let obj = match c.objective {
            CompensatorObjective::Balance => "Balance",
            CompensatorObjective::Power => "Power",
        };
        t += &format!(
            "        (path: {:?}, range: {}, objective: {obj}),\n",
            c.path,
            range_ron(c.min, c.max)
        );
    }
    if let Some(a) = &set.attenuator {
        t += &attenuator_ron(a);
    }
    t += "    ],\n    limits: [\n";
    for l in &set.limits {
        let mut parts = vec![format!("metric: {:?}", l.metric.to_string())];
        for (k, v) in [("min", l.min), ("max", l.max), ("abs_max", l.abs_max)] {
            if let Some(v) = v {
                parts.push(format!("{k}: {}", num(v)));
            }
        }
        t += &format!("        ({}),\n", parts.join(", "));
    }
    t += "    ],\n";
    if let Some(q) = set.quality {
        t += &format!(
            "    quality: (ratio_percent: {}, min_mssim: {}),\n",
            q.ratio_percent,
            num(q.min_mssim)
        );
    }
    t += ")\n";
    t
}

/// The one-at-a-time budget scaled to the target, for a line of text ("" where it was not).
fn scaled_note(b: &BudgetOutcome) -> String {
    b.baseline_at_target.as_ref().map_or(String::new(), |s| {
        format!(
            "; scaled × {:.3} to the target: {:.4}, {}",
            s.factor,
            s.budget.geometric_mean_scale,
            s.budget
                .confirmation
                .as_ref()
                .map_or("not confirmed".into(), |c| format!(
                    "{} of {} pass, lower bound {:.4}",
                    c.passed, c.trials, c.lower_bound
                ))
        )
    })
}

/// One point of the common-scale curve.
#[derive(Serialize)]
struct ScalePoint {
    scale: f64,
    surface_yield: f64,
}

/// `summary.json` of `tolerance --budget`.
#[derive(Serialize)]
struct BudgetSummary<'a> {
    command: &'static str,
    mode: &'static str,
    spibench_version: &'static str,
    scene: &'a str,
    tolerances_file: &'a str,
    costs_file: Option<&'a str>,
    rays: u64,
    seed: u64,
    trials: u64,
    target_yield: f64,
    confidence: f64,
    fraction_needed: f64,
    surface_samples: usize,
    quality: bool,
    lower_bound_method: &'static str,
    reached: bool,
    reason: Option<&'a str>,
    chosen_round: Option<usize>,
    stop: &'a str,
    unmodelled_limits: &'a [String],
    tolerances: &'a [BudgetRow],
    joint: &'a BudgetFigures,
    baseline: &'a BudgetFigures,
    baseline_at_target: Option<&'a crate::tolerance::budget_baseline::ScaledBaseline>,
    rounds: &'a [Round],
    common_scale: Vec<ScalePoint>,
    files: &'a [String],
}

/// `budget_trials.ron`: the run's identity, sensitivity table and every confirmation's trials,
/// from which `--resume` continues (floats written so that they read back bit for bit).
pub fn write_budget_trials(file: &BudgetTrialsFile, out: &OutputDir) -> crate::Result<()> {
    let config = ron::ser::PrettyConfig::new()
        .struct_names(false)
        .indentor(" ".to_string());
    let text = ron::ser::to_string_pretty(file, config).map_err(|e| {
        crate::Error::Numerical(format!("the trial records cannot be written: {e}"))
    })?;
    let path = out.path(BUDGET_TRIALS);
    std::fs::write(&path, text).map_err(|e| crate::Error::write(&path, e))
}

/// The file of a budget run's trials.
pub const BUDGET_TRIALS: &str = "budget_trials.ron";

/// Writes every output of a budget into `out` (a staging folder); returns the count of files.
pub fn write_budget(
    b: &BudgetOutcome,
    set: &ToleranceSet,
    run: &BudgetRun,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<usize> {
    let mut files: Vec<String> = [
        "summary.json",
        "budget.ron",
        "budget.csv",
        "report.html",
        BUDGET_TRIALS,
    ]
    .map(String::from)
    .to_vec();
    let path = out.path("budget.ron");
    std::fs::write(&path, budget_ron(set, b, run)).map_err(|e| crate::Error::write(&path, e))?;
    write_budget_csv(b, set, out)?;
    let fig = yield_figure(b, out, &mut files)?;
    write_page(
        &out.path("report.html"),
        &Page {
            title: format!("spibench tolerance budget of {}", run.scene),
            blocks: report_blocks(b, set, fig),
        },
    )?;
    let summary = BudgetSummary {
        command: "tolerance",
        mode: "budget",
        spibench_version: env!("CARGO_PKG_VERSION"),
        scene: run.scene,
        tolerances_file: run.tolerances_file,
        costs_file: run.costs_file,
        rays: run.rays,
        seed: run.seed,
        trials: run.trials,
        target_yield: b.target_yield,
        confidence: b.confidence,
        fraction_needed: b.fraction_needed,
        surface_samples: b.surface_samples,
        quality: run.quality,
        lower_bound_method: crate::tolerance::budget::LOWER_BOUND_METHOD,
        reached: b.reached,
        reason: b.reason.as_deref(),
        chosen_round: b.chosen_round,
        stop: &b.stop,
        unmodelled_limits: &b.unmodelled_limits,
        tolerances: &b.rows,
        joint: &b.joint,
        baseline: &b.baseline,
        baseline_at_target: b.baseline_at_target.as_ref(),
        rounds: &b.rounds,
        common_scale: b
            .common_scale
            .iter()
            .map(|&(scale, surface_yield)| ScalePoint {
                scale,
                surface_yield,
            })
            .collect(),
        files: &files,
    };
    super::super::summary::write_summary(out, &summary, provenance)?;
    Ok(files.len())
}

/// `budget.csv`: one row per tolerance, ranked by its share of the yield loss.
fn write_budget_csv(b: &BudgetOutcome, set: &ToleranceSet, out: &OutputDir) -> crate::Result<()> {
    let header = [
        "path",
        "file_min",
        "file_max",
        "scale",
        "budget_min",
        "budget_max",
        "cost",
        "loss_share",
        "baseline_scale",
        "baseline_cost",
    ];
    let rows: Vec<Vec<String>> = ranked(b)
        .into_iter()
        .map(|i| {
            let (r, t) = (&b.rows[i], &set.tolerances[i]);
            vec![
                r.path.clone(),
                format!("{:e}", t.min),
                format!("{:e}", t.max),
                format!("{}", r.scale),
                format!("{:e}", r.min),
                format!("{:e}", r.max),
                format!("{:e}", r.cost),
                format!("{:e}", r.loss_share),
                format!("{}", r.baseline_scale),
                format!("{:e}", r.baseline_cost),
            ]
        })
        .collect();
    write_csv(&out.path("budget.csv"), &header, &rows)
}

/// The tolerances' indices, largest share of the yield loss first (file order on ties).
fn ranked(b: &BudgetOutcome) -> Vec<usize> {
    let mut order: Vec<usize> = (0..b.rows.len()).collect();
    order.sort_by(|x, y| b.rows[*y].loss_share.total_cmp(&b.rows[*x].loss_share));
    order
}

/// The surface yield against a common scale of every tolerance, the target as a horizontal
/// line, the joint and one-at-a-time budgets' confirmed yields at their geometric-mean scales.
fn yield_figure(
    b: &BudgetOutcome,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<Block> {
    let (x, y): (Vec<f64>, Vec<f64>) = b.common_scale.iter().copied().unzip();
    let (x0, x1) = (
        x.first().copied().unwrap_or(0.01),
        x.last().copied().unwrap_or(1.0),
    );
    let point = |label: &str, f: &BudgetFigures| {
        f.confirmation.as_ref().map(|c| Series {
            label: format!("{label} (confirmed, geometric-mean scale)"),
            x: vec![f.geometric_mean_scale],
            y: vec![c.fraction],
            y_err: Some(vec![c.fraction - c.lower_bound]),
        })
    };
    let mut series = vec![
        Series {
            label: "surface yield, all tolerances at one scale".into(),
            x,
            y,
            y_err: None,
        },
        Series {
            label: format!("target {}", b.target_yield),
            x: vec![x0, x1],
            y: vec![b.target_yield; 2],
            y_err: None,
        },
    ];
    series.extend(point("joint budget", &b.joint));
    series.extend(point("one at a time", &b.baseline));
    if let Some(sb) = &b.baseline_at_target {
        series.extend(point("one at a time, scaled to the target", &sb.budget));
    }
    let plot = LinePlot {
        title: String::new(),
        x_label: "common scale of every tolerance's range (log scale)".into(),
        y_label: "yield".into(),
        series,
        log_x: true,
    };
    let (svg, png) = ("yield_vs_scale.svg", "yield_vs_scale.png");
    write_plot(&plot, &out.path(svg), &out.path(png))?;
    let text = std::fs::read_to_string(out.path(svg))
        .map_err(|e| crate::Error::read(&out.path(svg), e))?;
    files.extend([svg.to_string(), png.to_string()]);
    Ok(Block::Svg {
        caption: format!(
            "Yield on the response surface ({} draws) with every tolerance scaled alike, the \
             target {} marked; points: the confirmed yields of the joint and one-at-a-time \
             budgets at their geometric-mean scales, bars down to the Wilson lower bound at \
             confidence {}",
            b.surface_samples, b.target_yield, b.confidence
        ),
        svg: text,
    })
}

fn confirmed(f: &BudgetFigures) -> String {
    f.confirmation.as_ref().map_or("–".into(), |c| {
        format!(
            "{:.4} ({} of {}; lower bound {:.4})",
            c.fraction, c.passed, c.trials, c.lower_bound
        )
    })
}

/// The budget's section of `report.html`.
fn report_blocks(b: &BudgetOutcome, set: &ToleranceSet, fig: Block) -> Vec<Block> {
    let mut blocks = vec![Block::Heading {
        level: 2,
        text: "Tolerance budget".into(),
    }];
    blocks.push(Block::Paragraph(if b.reached {
        format!(
            "The joint budget reaches a yield of at least {} at confidence {}: its confirmation \
             by traced trials (compensators adjusted in each) gives {}.",
            b.target_yield,
            b.confidence,
            confirmed(&b.joint)
        )
    } else {
        format!(
            "The target yield {} at confidence {} was not reached: {}. The best budget found \
             is shown.",
            b.target_yield,
            b.confidence,
            b.reason.as_deref().unwrap_or("unknown")
        )
    }));
    blocks.push(Block::Table {
        caption: Some(
            "The joint budget against the one-at-a-time inverse limits (each tolerance alone \
             at the scale where its limit is reached)"
                .into(),
        ),
        header: [
            "budget",
            "total cost",
            "geometric-mean scale",
            "surface yield",
            "confirmed yield",
        ]
        .map(String::from)
        .to_vec(),
        rows: [("joint", &b.joint), ("one at a time", &b.baseline)]
            .into_iter()
            .chain(
                b.baseline_at_target
                    .as_ref()
                    .map(|s| ("one at a time, scaled to the target", &s.budget)),
            )
            .map(|(name, f)| {
                vec![
                    name.to_string(),
                    format!("{:.4}", f.total_cost),
                    format!("{:.4}", f.geometric_mean_scale),
                    format!("{:.4}", f.surface_yield),
                    confirmed(f),
                ]
            })
            .collect(),
    });
    blocks.push(Block::Table {
        caption: Some(
            "Each tolerance, largest share of the budget's yield loss first (on the surface, \
             each failing draw shared in proportion to |its term| of the failing metrics)"
                .into(),
        ),
        header: [
            "tolerance",
            "file range",
            "scale",
            "budget range",
            "share of loss",
            "one-at-a-time scale",
        ]
        .map(String::from)
        .to_vec(),
        rows: ranked(b)
            .into_iter()
            .map(|i| {
                let (r, t) = (&b.rows[i], &set.tolerances[i]);
                vec![
                    r.path.clone(),
                    format!("{} … {}", t.min, t.max),
                    format!("{}", r.scale),
                    format!("{:.4e} … {:.4e}", r.min, r.max),
                    format!("{:.1} %", 100.0 * r.loss_share),
                    format!("{}", r.baseline_scale),
                ]
            })
            .collect(),
    });
    blocks.push(Block::Table {
        caption: Some("The search's rounds: each allocated on the surface, then confirmed".into()),
        header: [
            "round",
            "surface target",
            "surface yield",
            "cross terms",
            "confirmed yield",
        ]
        .map(String::from)
        .to_vec(),
        rows: b
            .rounds
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let c = &r.confirmation;
                vec![
                    (k + 1).to_string(),
                    format!("{:.4}", r.surface_target),
                    format!("{:.4}", r.surface_yield),
                    r.cross_terms.to_string(),
                    format!("{:.4} (lower bound {:.4})", c.fraction, c.lower_bound),
                ]
            })
            .collect(),
    });
    blocks.push(fig);
    blocks
}
