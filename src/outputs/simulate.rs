//! The outputs of `spibench simulate` (docs/outputs.md, "simulate"): `summary.json`
//! (`SimulateSummary`), `timings.json`, `cells.csv` (the CSV row `run` shares), one figure and
//! CSV per curve of the experiment, the montages and `images/` (each object's truth and every
//! cell's reconstruction).

use serde::Serialize;

use crate::metrics::NORMALIZATION_RULE;
use crate::reconstruction::ZeroOneHandling;
use crate::reconstruction::tval3::StopReason;
use crate::report::csv::{ResultRow, write_csv, write_results};
use crate::report::montage::{Montage, write_montage_figure};
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, Series, write_plot};
use crate::report::png::write_gray8;
use crate::scene::experiment::{Axis, CurveX, Experiment, Metric};
use crate::simulation::{self, Cell, CurveSeries, SimulationOutput};

/// summary.json of `simulate`. Units: PSNR in dB, times in s, k± dimensionless, b± and noise
/// standard deviations in object units (grey levels summed over units).
#[derive(Serialize)]
struct Summary<'a> {
    /// Always "simulate".
    command: &'static str,
    spibench_version: &'static str,
    /// Experiment title and source (a path or `<built-in NAME>`).
    title: &'a str,
    source: &'a str,
    width: usize,
    height: usize,
    /// Units N = width × height.
    units: usize,
    sampling_ratios: &'a [f64],
    dmd_rate_hz: f64,
    seed: u64,
    /// How traditional (0/1) measurements were solved: "ZeroMean" or "Plain".
    zero_one: ZeroOneHandling,
    /// How reconstructions were brought to the truth's scale before scoring.
    normalization: &'static str,
    /// Every cell: object × ratio × case.
    cells: &'a [Cell],
    /// Curves by name: one series per scheme, mean and standard deviation over objects.
    curves: Vec<NamedCurve<'a>>,
}

/// timings.json of `simulate`: the only output that differs between two runs of one
/// experiment (summary.json and cells.csv are byte-identical for a seed).
#[derive(Serialize)]
struct SimulateTimings {
    /// Wall time of the whole run, s.
    wall_time_s: f64,
    /// Solver CPU time of every cell, in the order of summary.json's `cells`.
    cells: Vec<CellTiming>,
}

#[derive(Serialize)]
struct CellTiming {
    object: String,
    case: String,
    ratio: f64,
    solver_time_s: f64,
}

#[derive(Serialize)]
struct NamedCurve<'a> {
    name: &'a str,
    x: CurveX,
    metric: Metric,
    series: Vec<CurveSeries>,
}

fn cell_file(c: &Cell) -> String {
    format!(
        "images/{}__{}__r{:.3}.png",
        c.object,
        sanitize(&c.case),
        c.ratio
    )
}

/// A case label as a file-name fragment.
fn sanitize(s: &str) -> String {
    s.chars()
        .map(|ch| {
            if ch.is_ascii_alphanumeric() || ch == '-' || ch == '.' {
                ch
            } else {
                '_'
            }
        })
        .collect()
}

/// Writes every output of the experiment `exp` (named `source`: its path or built-in name)
/// into `out` (a staging folder); `wall` is the run's wall time (s), for `timings.json`.
pub fn write(
    exp: &Experiment,
    source: &str,
    res: &SimulationOutput,
    out: &OutputDir,
    wall: f64,
    provenance: &crate::provenance::Provenance,
) -> crate::Result<()> {
    for (o, truth) in exp.objects.iter().zip(&res.truths) {
        write_gray8(
            &out.path(&format!("images/{}__truth.png", o.name)),
            truth,
            0.0,
            255.0,
        )?;
    }
    for (c, img) in res.cells.iter().zip(&res.reconstructions) {
        write_gray8(&out.path(&cell_file(c)), img, 0.0, 255.0)?;
    }

    let rows: Vec<ResultRow> = res
        .cells
        .iter()
        .map(|c| ResultRow {
            command: "simulate".into(),
            scene: source.to_string(),
            seed: exp.seed,
            object: c.object.clone(),
            case: c.case.clone(),
            scheme: c.scheme.key().to_string(),
            ratio: c.ratio,
            measurements: c.measurements as u64,
            dmd_frames: c.dmd_frames as u64,
            detector_samples: c.detector_samples as u64,
            acquisition_time_s: c.acquisition_time_s,
            k_plus: c.k_plus,
            k_minus: c.k_minus,
            k_prime: c.k_prime,
            gain_units: "1".into(),
            b_plus: c.b_plus,
            b_minus: c.b_minus,
            offset_units: "object".into(),
            noise: c.noise.map(|n| format!("{n:?}")),
            noise_std: Some(c.noise_std),
            psnr_db: c.psnr_db,
            mssim: c.mssim,
            iterations: c.iterations as u64,
            converged: c.converged,
            stop: format!("{:?}", c.stop),
            saturated: None,
            finest_group: None,
            finest_element: None,
            finest_lp_per_mm: None,
        })
        .collect();
    write_results(&out.path("cells.csv"), &rows)?;

    let curves = write_curves(exp, res, out)?;

    if let Some(m) = &exp.montage {
        for (suffix, montage) in montages(exp, res, m.rows, m.columns) {
            write_montage_figure(
                &montage,
                m.tile_px,
                &out.path(&format!("montage{suffix}.svg")),
                &out.path(&format!("montage{suffix}.png")),
            )?;
        }
    }

    let summary = Summary {
        command: "simulate",
        spibench_version: env!("CARGO_PKG_VERSION"),
        title: &exp.title,
        source,
        width: exp.width,
        height: exp.height,
        units: exp.width * exp.height,
        sampling_ratios: &exp.sampling_ratios,
        dmd_rate_hz: exp.dmd_rate_hz,
        seed: exp.seed,
        zero_one: exp.zero_one,
        normalization: NORMALIZATION_RULE,
        cells: &res.cells,
        curves,
    };
    let timings = SimulateTimings {
        wall_time_s: wall,
        cells: res
            .cells
            .iter()
            .map(|c| CellTiming {
                object: c.object.clone(),
                case: c.case.clone(),
                ratio: c.ratio,
                solver_time_s: c.solver_time_s,
            })
            .collect(),
    };
    super::summary::write_summary_and_timings(out, &summary, provenance, Some(&timings))?;
    Ok(())
}

/// Each curve of the experiment: its CSV and its figure; returns the curves for the summary.
fn write_curves<'a>(
    exp: &'a Experiment,
    res: &SimulationOutput,
    out: &OutputDir,
) -> crate::Result<Vec<NamedCurve<'a>>> {
    let mut curves = Vec::new();
    for spec in &exp.curves {
        let series = simulation::curve(spec, &res.cells);
        let mut rows = Vec::new();
        for s in &series {
            for p in &s.points {
                rows.push(vec![
                    s.scheme.label().to_string(),
                    format!("{}", p.x),
                    format!("{:.6}", p.mean),
                    format!("{:.6}", p.std),
                    p.count.to_string(),
                ]);
            }
        }
        let (x_label, metric_label) = axis_labels(spec.x, spec.metric);
        write_csv(
            &out.path(&format!("{}.csv", spec.name)),
            &["scheme", "x", "mean", "std", "objects"],
            &rows,
        )?;
        let plot = LinePlot {
            title: format!("{}: {} against {}", exp.title, metric_label, x_label),
            x_label: x_label.to_string(),
            y_label: metric_label.to_string(),
            series: series
                .iter()
                .map(|s| Series {
                    label: s.scheme.label().to_string(),
                    x: s.points.iter().map(|p| p.x).collect(),
                    y: s.points.iter().map(|p| p.mean).collect(),
                    y_err: Some(s.points.iter().map(|p| p.std).collect()),
                })
                .collect(),
            log_x: spec.log_x,
        };
        write_plot(
            &plot,
            &out.path(&format!("{}.svg", spec.name)),
            &out.path(&format!("{}.png", spec.name)),
        )?;
        curves.push(NamedCurve {
            name: &spec.name,
            x: spec.x,
            metric: spec.metric,
            series,
        });
    }
    Ok(curves)
}

fn axis_labels(x: CurveX, metric: Metric) -> (&'static str, &'static str) {
    (
        match x {
            CurveX::Ratio => "sampling ratio M/N",
            CurveX::KPrime => "imbalance coefficient k' = k+ + k-",
        },
        match metric {
            Metric::Psnr => "PSNR (dB)",
            Metric::Mssim => "MSSIM",
        },
    )
}

/// Montages laid out with `rows` × `cols` axes; one montage per value of the third axis when it
/// has more than one value (file suffix `_<value>`).
fn montages(
    exp: &Experiment,
    res: &SimulationOutput,
    rows: Axis,
    cols: Axis,
) -> Vec<(String, Montage)> {
    let (n_obj, n_ratio, n_case) = (
        exp.objects.len(),
        exp.sampling_ratios.len(),
        exp.cases.len(),
    );
    let count = |a: Axis| match a {
        Axis::Object => n_obj,
        Axis::Ratio => n_ratio,
        Axis::Case => n_case,
    };
    let label = |a: Axis, i: usize| match a {
        Axis::Object => exp.objects[i].name.clone(),
        Axis::Ratio => format!("{:.0} %", exp.sampling_ratios[i] * 100.0),
        Axis::Case => exp.cases[i].label.clone(),
    };
    let third = [Axis::Object, Axis::Ratio, Axis::Case]
        .into_iter()
        .find(|a| *a != rows && *a != cols)
        .expect("three axes, two used");
    let mut out = Vec::new();
    for t in 0..count(third) {
        let mut tiles = Vec::new();
        let mut captions = Vec::new();
        for r in 0..count(rows) {
            let mut trow = Vec::new();
            let mut crow = Vec::new();
            for c in 0..count(cols) {
                let mut idx = [0usize; 3]; // object, ratio, case
                for (axis, i) in [(rows, r), (cols, c), (third, t)] {
                    match axis {
                        Axis::Object => idx[0] = i,
                        Axis::Ratio => idx[1] = i,
                        Axis::Case => idx[2] = i,
                    }
                }
                let k = (idx[0] * n_ratio + idx[1]) * n_case + idx[2];
                let cell = &res.cells[k];
                trow.push(Some(res.reconstructions[k].clone()));
                crow.push(format!("{:.2} dB / {:.3}", cell.psnr_db, cell.mssim));
            }
            tiles.push(trow);
            captions.push(crow);
        }
        let suffix = if count(third) > 1 {
            format!("_{}", sanitize(&label(third, t)))
        } else {
            String::new()
        };
        let title = if count(third) > 1 {
            format!("{} ({})", exp.title, label(third, t))
        } else {
            exp.title.clone()
        };
        let mut row_labels: Vec<String> = (0..count(rows)).map(|i| label(rows, i)).collect();
        let mut col_labels: Vec<String> = (0..count(cols)).map(|i| label(cols, i)).collect();
        // The ground truth beside the reconstructions: a leading row when objects run along
        // the columns, otherwise a leading column (each row's object, or this montage's).
        const TRUTH: &str = "ground truth";
        if cols == Axis::Object {
            row_labels.insert(0, TRUTH.into());
            tiles.insert(0, res.truths.iter().cloned().map(Some).collect());
            captions.insert(0, vec![String::new(); n_obj]);
        } else {
            col_labels.insert(0, TRUTH.into());
            for (r, (trow, crow)) in tiles.iter_mut().zip(captions.iter_mut()).enumerate() {
                // One object for every row: shown once, at the head of the first.
                let tile = match rows {
                    Axis::Object => Some(res.truths[r].clone()),
                    _ if r == 0 => Some(res.truths[t].clone()),
                    _ => None,
                };
                trow.insert(0, tile);
                crow.insert(0, String::new());
            }
        }
        out.push((
            suffix,
            Montage {
                title,
                row_labels,
                col_labels,
                tiles,
                captions,
                empty: crate::report::montage::EmptyCell::Blank,
            },
        ));
    }
    out
}

/// What `spibench simulate` prints: every cell's scores.
pub fn printed(exp: &Experiment, cells: &[Cell]) -> Vec<String> {
    let mut out = vec![
        format!(
            "{} — {}×{} units, PSNR (dB) / MSSIM after normalisation",
            exp.title, exp.width, exp.height
        ),
        format!(
            "{:<16} {:<28} {:>6} {:>9} {:>8} {:>6}",
            "object", "case", "ratio", "PSNR", "MSSIM", "iter"
        ),
    ];
    for c in cells {
        out.push(format!(
            "{:<16} {:<28} {:>5.0}% {:>9.2} {:>8.4} {:>6}{}",
            c.object,
            c.case,
            c.ratio * 100.0,
            c.psnr_db,
            c.mssim,
            c.iterations,
            match c.stop {
                StopReason::Tolerance => "",
                StopReason::MaxOuter => " (inner-loop cap)",
                StopReason::MaxIterations => " (iteration cap)",
            }
        ));
    }
    out
}
