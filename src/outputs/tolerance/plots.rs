//! The figures of `tolerance`: histograms and empirical CDFs of the main metrics over the
//! trials, with the file's limits drawn.

use crate::report::html::Block;
use crate::report::output::OutputDir;
use crate::report::plot::{
    Band, BandAxis, LinePlot, Markers, PlotOptions, Series, write_plot_with,
};
use crate::scene::tolerance::{SensitivityRecord, ShardFile, ToleranceSet};
use crate::tolerance::Analysis;

/// The limits of the file (and the quality limit) on `metric` as shaded bands of the values
/// they allow, on a plot of |value| (`abs`) or of the value, each end mapped by `shown` (the
/// leaks' bounded fractions).
fn limit_bands(
    set: &ToleranceSet,
    metric: &str,
    abs: bool,
    shown: impl Fn(f64) -> f64,
) -> Vec<Band> {
    let band = |label: String, lo: f64, hi: f64| Band {
        label,
        axis: BandAxis::X,
        lo: if lo.is_finite() { shown(lo) } else { lo },
        hi: if hi.is_finite() { shown(hi) } else { hi },
    };
    let mut out = Vec::new();
    for l in set.limits.iter().filter(|l| l.metric.to_string() == metric) {
        if let Some(m) = l.abs_max {
            let lo = if abs { f64::NEG_INFINITY } else { -m };
            out.push(band(format!("|{metric}| ≤ {m}"), lo, m));
        }
        if let Some(v) = l.min
            && (!abs || v > 0.0)
        {
            out.push(band(format!("{metric} ≥ {v}"), v, f64::INFINITY));
        }
        if let Some(v) = l.max
            && (!abs || v > 0.0)
        {
            out.push(band(format!("{metric} ≤ {v}"), f64::NEG_INFINITY, v));
        }
    }
    if let Some(q) = set.quality
        && metric.ends_with(&format!("_{}_mssim", q.ratio_percent))
    {
        out.push(band(
            format!("MSSIM ≥ {}", q.min_mssim),
            q.min_mssim,
            f64::INFINITY,
        ));
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

/// Histograms (outlines, Freedman–Diaconis bins up to ⌈√n⌉) and empirical CDFs (steps) of the main
/// metrics over the trials, with the file's limits drawn, written as figures and returned as
/// report blocks. The CDF is of |value| on a log axis for the metrics whose upper |·| tail
/// matters (imbalance, offsets, leaks), of the value for those whose lower tail matters (k',
/// MSSIM).
pub(super) fn distribution_plots(
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
        // The empirical CDF as steps: each trial raises it by 1/n at its value, where its
        // marker sits.
        let cdf_series = vec![Series {
            label: String::new(),
            y: (0..cx.len())
                .map(|i| (zeros + i + 1) as f64 / n as f64)
                .collect(),
            x: cx,
            y_err: None,
        }];
        let bands = |abs: bool| limit_bands(set, &metric, abs, |x| shown(&metric, x));
        let cdf_opts = PlotOptions {
            bands: bands(upper),
            steps: true,
            ..PlotOptions::default()
        };
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
        let (steps, _) = histogram_series(&v, bins);
        let hist_series = vec![steps];
        let hist_opts = PlotOptions {
            bands: bands(false),
            markers: Markers::None,
            ..PlotOptions::default()
        };
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
            vec![("hist", hist, hist_opts)]
        } else {
            vec![("hist", hist, hist_opts), ("cdf", cdf, cdf_opts)]
        };
        for (kind, plot, opts) in plots {
            let (svg, png) = (
                format!("{kind}_{metric}.svg"),
                format!("{kind}_{metric}.png"),
            );
            write_plot_with(&plot, &opts, &out.path(&svg), &out.path(&png))?;
            let text = std::fs::read_to_string(out.path(&svg))
                .map_err(|e| crate::Error::read(&out.path(&svg), e))?;
            figs.push(Block::Svg {
                caption: if kind == "hist" {
                    format!(
                        "Histogram of {label} over {n} trials ({bins} bins: Freedman–Diaconis, \
                         at most ⌈√n⌉); shaded: the values the file's limits allow"
                    )
                } else {
                    format!(
                        "Empirical CDF of {}{label} over {n} trials, as steps, a marker at each \
                         trial ({tail}){}; shaded: the values the file's limits allow",
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

/// The tornado chart of the sensitivity table (`tornado.svg`, `.png`, `.pdf`): each tolerance's
/// change of the electrical imbalance ι′ and of k′ at its min and at its max, with ±1 paired
/// standard error, the tolerances ordered by their largest |Δι′|, largest at the top; fixed
/// tolerances (device specifications) marked. None for an empty table.
pub(super) fn tornado_plot(
    sens: &[SensitivityRecord],
    set: &ToleranceSet,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<Option<Block>> {
    use crate::report::plot::{Tornado, TornadoPanel, write_tornado};
    if sens.is_empty() {
        return Ok(None);
    }
    let e = crate::scene::tolerance::IMBALANCE_ELECTRICAL;
    let bar = |r: &SensitivityRecord, m: &str| {
        [false, true].map(|high| {
            [
                r.at(high, &format!("{m}_diff")),
                r.at(high, &format!("{m}_diff_stderr")),
            ]
        })
    };
    let size = |r: &SensitivityRecord| {
        let b = bar(r, e);
        let m = b[0][0].abs().max(b[1][0].abs());
        if m.is_nan() { 0.0 } else { m }
    };
    let mut rows: Vec<&SensitivityRecord> = sens.iter().collect();
    // Stable: equal changes keep the table's order.
    rows.sort_by(|a, b| size(b).total_cmp(&size(a)));
    let tornado = Tornado {
        rows: rows
            .iter()
            .map(|r| {
                let fixed = set
                    .tolerances
                    .iter()
                    .any(|t| t.path == r.path && t.is_fixed());
                format!("{}{}", r.path, if fixed { " (fixed)" } else { "" })
            })
            .collect(),
        panels: vec![
            TornadoPanel {
                x_label: "Δ imbalance ι′ (electrical)".into(),
                bars: rows.iter().map(|r| bar(r, e)).collect(),
            },
            TornadoPanel {
                x_label: "Δ k′ (A/W)".into(),
                bars: rows.iter().map(|r| bar(r, "k_prime")).collect(),
            },
        ],
        ends: ["tolerance at its min".into(), "at its max".into()],
    };
    let (svg, png) = ("tornado.svg".to_string(), "tornado.png".to_string());
    write_tornado(&tornado, &out.path(&svg), &out.path(&png))?;
    let text = std::fs::read_to_string(out.path(&svg))
        .map_err(|e| crate::Error::read(&out.path(&svg), e))?;
    files.extend([svg, png]);
    Ok(Some(Block::Svg {
        caption: "Tornado chart of the sensitivity table: the change of the electrical \
                  imbalance ι′ (left) and of k′ (right) with each tolerance alone at its min and \
                  at its max, whiskers ±1 paired standard error; largest |Δι′| at the top; \
                  (fixed): a device specification, which cannot be tightened"
            .into(),
        svg: text,
    }))
}
