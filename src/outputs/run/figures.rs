//! The figures of `spibench run`: the montage (the paper's Fig. 6), the scores against the
//! sampling ratio (Fig. 7) and the oscilloscope panels of each recorded sequence.

use crate::report::montage::{Montage, write_montage_figure};
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, PlotOptions, ScopePlot, Series, write_plot_with, write_scope};
use crate::run::findings::pct;
use crate::run::{RunOutcome, SchemeResult};

/// Writes a plot as `STEM.svg`, `STEM.png` and `STEM.pdf` and lists the files.
fn write_plot_pair(
    plot: &LinePlot,
    opts: &PlotOptions,
    stem: &str,
    out: &OutputDir,
    files: &mut Vec<String>,
) -> crate::Result<()> {
    write_plot_with(
        plot,
        opts,
        &out.path(&format!("{stem}.svg")),
        &out.path(&format!("{stem}.png")),
    )?;
    files.push(format!("{stem}.svg"));
    files.push(format!("{stem}.png"));
    files.push(format!("{stem}.pdf"));
    Ok(())
}

/// Fig. 6: one row per scheme, one column per ratio, the object x once at the head of the
/// first row.
pub(super) fn write_fig6_montage(
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
        // The object once, at the head of the first row; the column stays blank below it.
        let mut trow = vec![(k == 0).then(|| o.truth.clone())];
        let mut crow = vec![if k == 0 { "ideal object x" } else { "" }.to_string()];
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
        // No title in the figure: the caption belongs to the page or paper that shows it.
        title: String::new(),
        row_labels,
        col_labels: std::iter::once("object".to_string())
            .chain(s.sampling_ratios.iter().map(|&r| pct(r)))
            .collect(),
        tiles,
        captions,
        empty: crate::report::montage::EmptyCell::Blank,
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

/// Fig. 7 (MSSIM against sampling ratio) and its PSNR twin, each with a lower panel of every
/// scheme's difference to the best scheme at each ratio: on a balanced bench several schemes
/// score alike and their curves lie on one line in the upper panel, while the lower one spreads
/// them apart on the scale of their differences.
pub(super) fn write_fig7_curves(
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
        let values: Vec<Vec<f64>> = (0..s.schemes.len())
            .map(|k| {
                (0..n_ratio)
                    .map(|r| pick(&o.results[k * n_ratio + r]))
                    .collect()
            })
            .collect();
        let best: Vec<f64> = (0..n_ratio)
            .map(|r| {
                values
                    .iter()
                    .map(|v| v[r])
                    .filter(|v| v.is_finite())
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .collect();
        let series = |diff: bool| -> Vec<Series> {
            s.schemes
                .iter()
                .zip(&values)
                .map(|(scheme, v)| Series {
                    label: scheme.label().to_string(),
                    x: s.sampling_ratios.clone(),
                    y: v.iter()
                        .zip(&best)
                        .map(|(y, b)| if diff { y - b } else { *y })
                        .collect(),
                    y_err: None,
                })
                .collect()
        };
        let unit = label.strip_prefix("PSNR").map_or("", |_| " (dB)");
        let plot = LinePlot {
            title: format!("{}: {label} against sampling ratio", s.title),
            x_label: "sampling ratio M/N".to_string(),
            y_label: label.to_string(),
            series: series(false),
            log_x: false,
        };
        let lower = LinePlot {
            title: String::new(),
            x_label: plot.x_label.clone(),
            y_label: format!("Δ to best{unit}"),
            series: series(true),
            log_x: false,
        };
        let opts = PlotOptions {
            lower: Some(Box::new(lower)),
            ..PlotOptions::default()
        };
        write_plot_pair(&plot, &opts, stem, out, files)?;
    }

    Ok(())
}

/// The signal traces: one panel per output on a shared time axis, every sample on the line.
pub(super) fn write_signal_traces(
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
