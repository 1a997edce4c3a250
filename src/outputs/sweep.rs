//! The outputs of `spibench sweep` (docs/outputs.md, "sweep"): `summary.json` (`rows`: one per
//! grid point, the varied values and every metric with `_stderr`, `_diff` from the nominal
//! bench and `_diff_stderr`; `limits`: where each limit is crossed), `sweep.csv` (the same
//! columns), plots (1-D: each metric against the variable with ±1 standard-error bars; 2-D:
//! heatmaps with a colour bar and the nominal bench marked), `layout.svg` and `report.html`.

use serde::Serialize;

use crate::pipeline::evaluate::Evaluation;
use crate::quantities::BenchMetric;
use crate::report::csv::write_csv;
use crate::report::heatmap::{Heatmap, write_heatmap};
use crate::report::html::{Block, Page, write_page};
use crate::report::output::OutputDir;
use crate::report::plot::{
    Band, BandAxis, LinePlot, Mark, PlotOptions, Series, write_plot, write_plot_with,
};
use crate::sweep::limits::LimitReport;
use crate::sweep::{Sweep, Vary};

use super::labels::variable_label;
use super::rows::Row;

/// The metrics plotted, with their axis labels.
const PLOTTED: [(BenchMetric, &str); 6] = [
    (BenchMetric::Imbalance, "imbalance (k₊ − k₋)/(k₊ + k₋)"),
    (BenchMetric::KPlus, "k₊ (A/W)"),
    (BenchMetric::KMinus, "k₋ (A/W)"),
    (BenchMetric::BMinusMinusBPlus, "b₋ − b₊ (A)"),
    (BenchMetric::LeakPlus, "off-arm leak, all units + (ratio)"),
    (
        BenchMetric::PowerMinusW,
        "power on diode −, all units − (W)",
    ),
];

/// `summary.json` of `sweep`.
#[derive(Serialize)]
struct SweepSummary<'a> {
    command: &'static str,
    spibench_version: &'static str,
    scene: &'a str,
    rays: u64,
    seed: u64,
    quality: bool,
    vary: Vec<VarySummary<'a>>,
    /// Metric names, units and meanings (every row has the keys of [`Row::metrics`]: `NAME`,
    /// `NAME_stderr`, `NAME_diff`, `NAME_diff_stderr`, and `NAME_diff_stderr_independent`: the
    /// standard error the difference would have between independent runs; `cmrr_db`, the
    /// bench's common-mode rejection with the arms' k± in it (the same five keys),
    /// `cmrr_electronics_db`, the detector's alone (exact; null when infinite), and
    /// `arrivals` (lamp rays that reached the pattern area)).
    metrics: Vec<MetricDoc>,
    /// Where each limit is crossed (1-D sweeps; empty without limits).
    limits: &'a [LimitReport],
    nominal: Row,
    rows: Vec<Row>,
    files: Vec<String>,
}

#[derive(Serialize)]
struct VarySummary<'a> {
    path: &'a str,
    start: f64,
    stop: f64,
    n: usize,
    /// The variable's value in the nominal bench (0 for a rigid-body move).
    nominal: f64,
}

#[derive(Serialize)]
struct MetricDoc {
    name: &'static str,
    unit: &'static str,
    meaning: &'static str,
}

/// One row: the varied values, then the point's metrics against the nominal bench
/// ([`Row::metrics`]: the keys `tolerance` and `align` write too).
fn row(p: &Evaluation, nominal: &Evaluation) -> Row {
    Row::metrics(p, nominal).with_settings(&p.settings)
}

/// The sweep as a table under 100 columns for up to two varied variables: the variables, the
/// imbalance, its paired change from the nominal bench and k'; every other metric, with its
/// standard errors, is in `sweep.csv` and `summary.json`; then where each limit is crossed.
pub fn printed(s: &Sweep, crossed: &[LimitReport]) -> Vec<String> {
    let mut out = Vec::new();
    let mut line = String::from(" ");
    for v in &s.vary {
        line += &format!(" {:>13}", short(&v.path));
    }
    for h in ["imbalance", "Δ imbalance", "k' (A/W)"] {
        line += &format!(" {h:>20}");
    }
    out.push(line);
    for p in &s.points {
        let mut line = String::from(" ");
        for (_, v) in &p.settings {
            line += &format!(" {v:>13.6}");
        }
        for (n, diff) in [
            (BenchMetric::Imbalance, false),
            (BenchMetric::Imbalance, true),
            (BenchMetric::KPrime, false),
        ] {
            let (a, b) = (&p.metrics[n], &s.nominal.metrics[n]);
            let e = if diff { a.diff(b) } else { a.estimate() };
            line += &format!(" {:>20}", format!("{:.4e} ± {:.1e}", e.value, e.stderr));
        }
        out.push(line);
    }
    out.push("  (k±, b±, b₋ − b₊, powers and leaks with their standard errors: sweep.csv)".into());
    for c in crossed {
        out.extend(c.lines().into_iter().map(|l| format!("  {l}")));
    }
    out
}

/// The rows as CSV: the columns of the first row, in its order.
fn write_rows_csv(path: &std::path::Path, rows: &[Row]) -> crate::Result<()> {
    let header: Vec<String> = rows
        .first()
        .map_or_else(Vec::new, |r| r.keys().map(String::from).collect());
    let cells: Vec<Vec<String>> = rows.iter().map(|r| r.csv_cells(&header)).collect();
    let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(path, &header_refs, &cells)
}

/// The last two segments of a path, for table headings.
fn short(path: &str) -> String {
    let segs: Vec<&str> = path.split('.').collect();
    let k = segs.len().saturating_sub(2);
    let s = segs[k..].join(".");
    if s.chars().count() > 13 {
        s.chars().take(12).collect::<String>() + "…"
    } else {
        s
    }
}

/// Writes every output of a sweep of the bench `name` into `out` (a staging folder); returns
/// the count of files and the summary card. `nominal_values` are the swept variables' values in the nominal bench.
pub fn write(
    name: &str,
    bench: &crate::optics::Bench,
    s: &Sweep,
    nominal_values: &[f64],
    crossed: &[LimitReport],
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<(usize, crate::outputs::card::Card)> {
    let mut files = vec![
        "summary.json".to_string(),
        "sweep.csv".to_string(),
        "report.html".to_string(),
    ];
    let rows: Vec<Row> = s.points.iter().map(|p| row(p, &s.nominal)).collect();
    write_rows_csv(&out.path("sweep.csv"), &rows)?;
    let mut blocks = vec![Block::Paragraph(format!(
        "{} grid point(s) of {name}, each traced with {} rays and seed {} (common random numbers: \
         every point draws the same random numbers, so a difference from the nominal bench is \
         resolved by its paired standard error, given beside the standard error independent \
         runs would have). Error bars and ± are one standard error.",
        s.points.len(),
        s.options.rays,
        s.options.seed
    ))];
    let (layout, svg) = super::layout::layout_block(bench, name)?;
    let path = out.path("layout.svg");
    std::fs::write(&path, &svg).map_err(|e| crate::Error::write(&path, e))?;
    files.push("layout.svg".into());
    blocks.push(layout);
    if !crossed.is_empty() {
        blocks.push(limits_block(crossed));
    }
    let figures = match s.vary.as_slice() {
        [v] => line_plots(s, v, crossed, out, &mut files)?,
        [a, b] => heatmaps(s, [a, b], nominal_values, out, &mut files)?,
        _ => Vec::new(),
    };
    for (svg, caption) in figures {
        let text = std::fs::read_to_string(out.path(&svg))
            .map_err(|e| crate::Error::read(&out.path(&svg), e))?;
        blocks.push(Block::Svg { caption, svg: text });
    }
    blocks.push(points_table(s));
    let nominal = row(&s.nominal, &s.nominal);
    let summary = SweepSummary {
        command: "sweep",
        spibench_version: env!("CARGO_PKG_VERSION"),
        scene: name,
        rays: s.options.rays,
        seed: s.options.seed,
        quality: s.options.quality,
        vary: s
            .vary
            .iter()
            .zip(nominal_values)
            .map(|(v, &n)| VarySummary {
                path: &v.path,
                start: v.start,
                stop: v.stop,
                n: v.n,
                nominal: n,
            })
            .collect(),
        metrics: BenchMetric::ALL
            .iter()
            .map(|m| MetricDoc {
                name: m.key(),
                unit: m.unit(),
                meaning: m.meaning(),
            })
            .collect(),
        limits: crossed,
        nominal,
        rows,
        files: files.clone(),
    };
    let json = serde_json::to_value(&summary)
        .map_err(|e| crate::Error::Numerical(format!("the sweep summary as JSON: {e}")))?;
    let card = card(&json);
    blocks.insert(0, card.block());
    let blocks = crate::report::html::fold_long_paragraphs(blocks, 320);
    write_page(
        &out.path("report.html"),
        &Page {
            title: format!("spibench sweep of {name}"),
            blocks,
        },
    )?;
    super::summary::write_summary(out, &summary, provenance)?;
    Ok((files.len(), card))
}

/// The summary card of a sweep (from its summary.json as a value): what was swept, the nominal
/// bench's imbalance and k′, the range of the imbalance over the grid, and each limit's
/// crossings.
pub fn card(summary: &serde_json::Value) -> crate::outputs::card::Card {
    use crate::outputs::card::{Card, num, pm, sig};
    let mut c = Card::new("summary");
    for i in 0..crate::outputs::card::array_len(summary, "/vary") {
        let v = format!("/vary/{i}");
        let keys = ["path", "start", "stop", "n", "nominal"].map(|k| format!("{v}/{k}"));
        c.line(summary, "swept", &keys, |v| {
            format!(
                "{} from {} to {} ({} points; nominal {})",
                v[0].as_str().unwrap_or(""),
                sig(num(&v[1]), 4),
                sig(num(&v[2]), 4),
                v[3],
                sig(num(&v[4]), 4)
            )
        });
    }
    c.line(
        summary,
        "nominal imbalance, k′",
        &[
            "/nominal/imbalance",
            "/nominal/imbalance_stderr",
            "/nominal/k_prime",
            "/nominal/k_prime_stderr",
        ],
        |v| {
            format!(
                "{}, {}",
                pm(num(&v[0]), num(&v[1]), ""),
                pm(num(&v[2]), num(&v[3]), "A/W")
            )
        },
    );
    // The grid points with the lowest and the highest imbalance.
    let rows = crate::outputs::card::array_len(summary, "/rows");
    let at = |i: usize| {
        summary
            .pointer(&format!("/rows/{i}/imbalance"))
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(f64::NAN)
    };
    let finite: Vec<usize> = (0..rows).filter(|&i| at(i).is_finite()).collect();
    if let (Some(&lo), Some(&hi)) = (
        finite.iter().min_by(|&&a, &&b| at(a).total_cmp(&at(b))),
        finite.iter().max_by(|&&a, &&b| at(a).total_cmp(&at(b))),
    ) {
        c.line(
            summary,
            "imbalance over the grid",
            &[
                &format!("/rows/{lo}/imbalance"),
                &format!("/rows/{hi}/imbalance"),
            ],
            |v| format!("{:.3e} to {:.3e}", num(&v[0]), num(&v[1])),
        );
    }
    for j in 0..crate::outputs::card::array_len(summary, "/limits") {
        let l = format!("/limits/{j}");
        let mut keys: Vec<String> = ["metric", "limit", "points_within", "points"]
            .map(|k| format!("{l}/{k}"))
            .to_vec();
        for k in 0..crate::outputs::card::array_len(summary, &format!("{l}/crossings")) {
            keys.push(format!("{l}/crossings/{k}/at"));
            keys.push(format!("{l}/crossings/{k}/stderr"));
        }
        c.line(summary, "limit", &keys, |v| {
            let mut text = format!(
                "|{}| ≤ {}: met at {} of {} points",
                v[0].as_str().unwrap_or(""),
                v[1],
                v[2],
                v[3]
            );
            let crossings: Vec<String> = v[4..]
                .chunks(2)
                .map(|x| pm(num(&x[0]), num(&x[1]), ""))
                .collect();
            if !crossings.is_empty() {
                text += &format!("; crossed at {}", crossings.join(", "));
            }
            text
        });
    }
    c
}

/// 1-D: each plotted metric against the variable with ±1 standard-error bars, and with the
/// whole pipeline the MSSIM of each scheme; the figures (file, caption) written.
fn line_plots(
    s: &Sweep,
    v: &Vary,
    crossed: &[LimitReport],
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<Vec<(String, String)>> {
    let mut figures = Vec::new();
    let xs: Vec<f64> = s.points.iter().map(|p| p.settings[0].1).collect();
    for (metric, label) in PLOTTED {
        let ys: Vec<f64> = s.points.iter().map(|p| p.metrics[metric].value).collect();
        crate::sweep::require_finite(&s.vary, &format!("{label} (`{metric}`)"), ys.len(), &ys)?;
        let series = vec![Series {
            label: String::new(),
            x: xs.clone(),
            y: ys.clone(),
            y_err: Some(
                s.points
                    .iter()
                    .map(|p| {
                        let e = p.metrics[metric].stderr();
                        if e.is_finite() { e } else { 0.0 }
                    })
                    .collect(),
            ),
        }];
        let plot = LinePlot {
            title: String::new(),
            x_label: variable_label(&v.path),
            y_label: label.to_string(),
            series,
            log_x: false,
        };
        let opts = limit_band(crossed, metric.key(), &xs, &ys);
        let (svg, png) = (format!("{metric}.svg"), format!("{metric}.png"));
        write_plot_with(&plot, &opts, &out.path(&svg), &out.path(&png))?;
        figures.push((svg.clone(), label.to_string()));
        files.extend([svg, png]);
    }
    if let Some((y_label, series)) = mssim_series(s, &xs)? {
        let plot = LinePlot {
            title: String::new(),
            x_label: variable_label(&v.path),
            y_label,
            series,
            log_x: false,
        };
        write_plot(&plot, &out.path("mssim.svg"), &out.path("mssim.png"))?;
        figures.push(("mssim.svg".into(), "MSSIM of each scheme".into()));
        files.extend(["mssim.svg".to_string(), "mssim.png".to_string()]);
    }
    Ok(figures)
}

/// With the whole pipeline, the MSSIM of each scheme at the largest sampling ratio against the
/// variable at `xs` (the axis label and one series per scheme); refused when no point of any
/// scheme has a finite MSSIM ([`crate::sweep::require_finite`]). None without `quality`.
fn mssim_series(s: &Sweep, xs: &[f64]) -> crate::Result<Option<(String, Vec<Series>)>> {
    let Some(q) = s.points.first().and_then(|p| p.quality.as_ref()) else {
        return Ok(None);
    };
    let last_ratio = q.iter().map(|r| r.ratio).fold(0.0, f64::max);
    let schemes: Vec<_> = q
        .iter()
        .filter(|r| r.ratio == last_ratio)
        .map(|r| r.scheme)
        .collect();
    let series: Vec<Series> = schemes
        .iter()
        .map(|&k| Series {
            label: k.label().to_string(),
            x: xs.to_vec(),
            y: s.points
                .iter()
                .map(|p| {
                    p.quality
                        .as_ref()
                        .and_then(|q| q.iter().find(|r| r.scheme == k && r.ratio == last_ratio))
                        .map_or(f64::NAN, |r| r.mssim)
                })
                .collect(),
            y_err: None,
        })
        .collect();
    let y_label = format!("MSSIM at {:.0} % sampling", last_ratio * 100.0);
    let all: Vec<f64> = series.iter().flat_map(|k| k.y.iter().copied()).collect();
    crate::sweep::require_finite(
        &s.vary,
        &format!("{y_label} (`mssim`) for any scheme"),
        s.points.len(),
        &all,
    )?;
    Ok(Some((y_label, series)))
}

/// The limits on `metric` as one shaded band of the values they allow (|metric| ≤ L: from −L
/// to L, open towards a sign the metric never takes, so that the axis is not stretched to it)
/// and their crossings marked at ±L, each with its 95 % interval along the variable.
fn limit_band(crossed: &[LimitReport], metric: &str, xs: &[f64], ys: &[f64]) -> PlotOptions {
    let negative = ys.iter().any(|&y| y < 0.0);
    let positive = ys.iter().any(|&y| y > 0.0) || !negative;
    let mut opts = PlotOptions::default();
    for c in crossed.iter().filter(|c| c.metric == metric) {
        opts.bands.push(Band {
            label: format!("|{metric}| ≤ {}", c.limit),
            axis: BandAxis::Y,
            lo: if negative {
                -c.limit
            } else {
                f64::NEG_INFINITY
            },
            hi: if positive { c.limit } else { f64::INFINITY },
        });
        for k in &c.crossings {
            // The crossing's side: the sign of the metric at the two grid points around it.
            let near: f64 = xs
                .iter()
                .zip(ys)
                .filter(|(x, _)| k.between.contains(x))
                .map(|(_, y)| *y)
                .sum();
            opts.marks.push(Mark {
                x: k.at,
                y: if near < 0.0 { -c.limit } else { c.limit },
                x_interval: k.ci95,
            });
        }
    }
    if !opts.marks.is_empty() {
        opts.mark_label = "crossing (95 % interval)".into();
    }
    opts
}

/// The report's table of limit crossings.
fn limits_block(crossed: &[LimitReport]) -> Block {
    let mut rows = Vec::new();
    for c in crossed {
        let head = vec![
            format!("|{}| ≤ {}", c.metric, c.limit),
            format!("{} of {}", c.points_within, c.points),
        ];
        if c.crossings.is_empty() {
            let mut r = head.clone();
            r.extend([
                if c.points_within == c.points {
                    "met at every point".to_string()
                } else {
                    "exceeded at every point".to_string()
                },
                String::new(),
                String::new(),
                String::new(),
            ]);
            rows.push(r);
        }
        for x in &c.crossings {
            let mut r = head.clone();
            r.extend([
                x.direction.to_string(),
                format!("{:.6} ± {:.2e}", x.at, x.stderr),
                x.ci95
                    .map_or_else(|| "–".into(), |[lo, hi]| format!("[{lo:.6}, {hi:.6}]")),
                format!("{} … {}", x.between[0], x.between[1]),
            ]);
            rows.push(r);
        }
    }
    Block::Table {
        caption: Some(format!(
            "Where each limit is crossed along {}: linear interpolation between the grid points \
             on either side; ± the standard error from the two points' standard errors (added \
             linearly: the points share their random numbers), 95 % interval ± 1.96 σ; the \
             interpolation's own error is not included",
            crossed.first().map_or("", |c| c.variable.as_str())
        )),
        header: [
            "limit",
            "points within",
            "crossing",
            "at ± SE",
            "95 % interval",
            "between grid points",
        ]
        .map(String::from)
        .to_vec(),
        rows,
    }
}

/// 2-D: heatmaps of the first four plotted metrics with the nominal bench marked.
fn heatmaps(
    s: &Sweep,
    [a, b]: [&Vary; 2],
    nominal_values: &[f64],
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<Vec<(String, String)>> {
    let mut figures = Vec::new();
    for &(metric, label) in PLOTTED.iter().take(4) {
        let values: Vec<f64> = s.points.iter().map(|p| p.metrics[metric].value).collect();
        crate::sweep::require_finite(
            &s.vary,
            &format!("{label} (`{metric}`)"),
            values.len(),
            &values,
        )?;
        let h = Heatmap {
            x_label: variable_label(&a.path),
            y_label: variable_label(&b.path),
            value_label: label.to_string(),
            xs: a.values(),
            ys: b.values(),
            values,
            mark: Some((nominal_values[0], nominal_values[1])),
        };
        let (svg, png) = (format!("{metric}.svg"), format!("{metric}.png"));
        write_heatmap(&h, &out.path(&svg), &out.path(&png))?;
        figures.push((svg.clone(), format!("{label}; + marks the nominal bench")));
        files.extend([svg, png]);
    }
    Ok(figures)
}

/// The report's table of grid points: the variables, the imbalance and its change, k± and
/// b₋ − b₊, each ± its standard error.
fn points_table(s: &Sweep) -> Block {
    let mut header_html: Vec<String> = s.vary.iter().map(|v| v.path.clone()).collect();
    header_html.extend(
        [
            "imbalance",
            "Δ imbalance",
            "k₊ (A/W)",
            "k₋ (A/W)",
            "b₋ − b₊ (A)",
        ]
        .map(String::from),
    );
    let pm = |m: &crate::transport::Estimate| format!("{:.4e} ± {:.1e}", m.value, m.stderr);
    let table_rows = s
        .points
        .iter()
        .map(|p| {
            let mut r: Vec<String> = p.settings.iter().map(|(_, v)| format!("{v}")).collect();
            let g = |m: BenchMetric| p.metrics[m].estimate();
            let d = |m: BenchMetric| p.metrics[m].diff(&s.nominal.metrics[m]);
            for e in [
                g(BenchMetric::Imbalance),
                d(BenchMetric::Imbalance),
                g(BenchMetric::KPlus),
                g(BenchMetric::KMinus),
                g(BenchMetric::BMinusMinusBPlus),
            ] {
                r.push(pm(&e));
            }
            r
        })
        .collect();
    Block::Table {
        caption: Some("Grid points (value ± standard error; Δ against the nominal bench ± its paired standard error)".into()),
        header: header_html,
        rows: table_rows,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acquisition::Scheme;
    use crate::pipeline::SchemeResult;
    use crate::raster::Raster;

    fn scored(scheme: Scheme, mssim: f64) -> SchemeResult {
        SchemeResult {
            scheme,
            ratio: 0.4,
            measurements: 1,
            dmd_frames: 1,
            detector_samples: 1,
            acquisition_time_s: 1e-3,
            psnr_db: 20.0,
            mssim,
            normalization_gain: 1.0,
            normalization_offset: 0.0,
            iterations: 1,
            converged: true,
            stop: crate::reconstruction::StopReason::Tolerance,
            relative_residual: 0.0,
            saturated: false,
            solver_time_s: 0.0,
            finest_resolved: None,
            reconstruction: Raster::zeros(1, 1),
            y: Vec::new(),
            solution: Raster::zeros(1, 1),
        }
    }

    /// The MSSIM plot of a sweep with the whole pipeline is refused, naming the variable, when
    /// no scheme has a finite MSSIM at any point, and drawn when one point of one scheme has.
    #[test]
    fn an_mssim_plot_with_no_finite_point_is_refused_naming_the_variable() {
        let doc = crate::scene::doc::BenchDoc::read(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron"),
        )
        .unwrap();
        let o = crate::sweep::SweepOptions {
            rays: 4096,
            seed: 1,
            quality: false,
        };
        let v = Vary::parse("dmd.tilt_deg=11:13:2").unwrap();
        let mut s = crate::sweep::sweep(&doc, &[v], &o, &|_, _| {}).unwrap();
        let xs: Vec<f64> = s.points.iter().map(|p| p.settings[0].1).collect();
        assert!(mssim_series(&s, &xs).unwrap().is_none());
        let schemes = [Scheme::DoubleArm, Scheme::Traditional];
        for p in &mut s.points {
            p.quality = Some(schemes.iter().map(|&k| scored(k, f64::NAN)).collect());
        }
        let e = mssim_series(&s, &xs).unwrap_err();
        let text = e.to_string();
        for part in [
            "field `vary`",
            "dmd.tilt_deg",
            "none of the 2 point(s)",
            "MSSIM",
        ] {
            assert!(e.is_user_error() && text.contains(part), "{part}: {text}");
        }
        s.points[1].quality.as_mut().unwrap()[1].mssim = 0.5;
        let (_, series) = mssim_series(&s, &xs).unwrap().unwrap();
        assert_eq!(series.len(), 2);
    }
}
