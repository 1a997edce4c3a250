//! The repeat statistics of `spibench run` (crate::run::repeats): `repeats.json`,
//! `repeats.csv`, the scores against the frames shown (equal-cost comparison) with error bars,
//! and a printed table of the paired differences.
//!
//! Files (with `--repeats 1` the standard deviations are 0 and no intervals are given):
//! - `repeats.json`: [`Repeats`] (per scheme × ratio: frames, acquisition time, mean and
//!   sample SD of PSNR and MSSIM; paired differences with 95 % intervals; the seeds);
//! - `repeats.csv`: the per scheme × ratio rows;
//! - `mssim_vs_frames.{svg,png}`, `psnr_vs_frames.{svg,png}`: each scheme's mean score against
//!   the DMD frames it showed (calibration frames included), ± one SD, so schemes that show a
//!   pattern and its complement are compared with those that show it once at equal cost.

use crate::report::csv::write_csv;
use crate::report::json::write_json;
use crate::report::output::OutputDir;
use crate::report::plot::{LinePlot, Series, write_plot};
use crate::run::RunSettings;
use crate::run::repeats::{RepeatStats, Repeats};

/// Writes the repeat files into `out` and returns their names.
pub fn write(r: &Repeats, s: &RunSettings, out: &OutputDir) -> crate::Result<Vec<String>> {
    let mut files = Vec::new();
    write_json(&out.path("repeats.json"), r)?;
    files.push("repeats.json".to_string());
    let header = [
        "scheme",
        "ratio",
        "repeats",
        "dmd_frames",
        "acquisition_time_s",
        "psnr_db_mean",
        "psnr_db_sd",
        "mssim_mean",
        "mssim_sd",
        "saturated_repeats",
    ];
    let rows: Vec<Vec<String>> = r
        .stats
        .iter()
        .map(|x| {
            vec![
                x.scheme.key().to_string(),
                format!("{}", x.ratio),
                x.repeats.to_string(),
                x.dmd_frames.to_string(),
                format!("{:.6}", x.acquisition_time_s),
                format!("{:.4}", x.psnr_db_mean),
                format!("{:.4}", x.psnr_db_sd),
                format!("{:.6}", x.mssim_mean),
                format!("{:.6}", x.mssim_sd),
                x.saturated_repeats.to_string(),
            ]
        })
        .collect();
    write_csv(&out.path("repeats.csv"), &header, &rows)?;
    files.push("repeats.csv".to_string());

    let n_ratio = s.sampling_ratios.len();
    for (stem, label, pick) in [
        (
            "mssim_vs_frames",
            "MSSIM",
            (|x: &RepeatStats| (x.mssim_mean, x.mssim_sd)) as fn(&RepeatStats) -> (f64, f64),
        ),
        ("psnr_vs_frames", "PSNR (dB)", |x: &RepeatStats| {
            (x.psnr_db_mean, x.psnr_db_sd)
        }),
    ] {
        let series = s
            .schemes
            .iter()
            .enumerate()
            .map(|(k, scheme)| {
                let rows = &r.stats[k * n_ratio..(k + 1) * n_ratio];
                Series {
                    label: scheme.label().to_string(),
                    x: rows.iter().map(|x| x.dmd_frames as f64).collect(),
                    y: rows.iter().map(|x| pick(x).0).collect(),
                    y_err: (r.repeats > 1).then(|| rows.iter().map(|x| pick(x).1).collect()),
                }
            })
            .collect();
        let plot = LinePlot {
            title: format!(
                "{}: {label} against DMD frames shown (mean ± SD of {} repeats)",
                s.title, r.repeats
            ),
            x_label: "DMD frames shown (calibration included)".to_string(),
            y_label: label.to_string(),
            series,
            log_x: true,
        };
        write_plot(
            &plot,
            &out.path(&format!("{stem}.svg")),
            &out.path(&format!("{stem}.png")),
        )?;
        files.push(format!("{stem}.svg"));
        files.push(format!("{stem}.png"));
    }
    Ok(files)
}

/// A short name for the terminal table.
fn short(s: crate::acquisition::Scheme) -> &'static str {
    use crate::acquisition::Scheme::*;
    match s {
        Traditional => "traditional",
        SingleArmComplementary => "single-arm",
        DoubleArm => "double-arm",
        SecondaryComplementaryBalancing => "SCB",
        TraditionalZeroMean => "trad. zero-mean",
        DoubleArmCalibrated => "calibrated double-arm",
        DoubleArmOffset => "offset-aware double-arm",
    }
}

/// The paired differences as a table under 100 columns (nothing for one repeat): one line per
/// comparison and ratio, MSSIM and PSNR side by side, each with its 95 % interval.
pub fn print(r: &Repeats) {
    if r.repeats < 2 {
        return;
    }
    println!(
        "paired differences over {} repeats: mean [95 % interval]",
        r.repeats
    );
    for pair in r.paired.chunks(2) {
        let [m, p] = pair else { continue };
        let ci = |x: &crate::run::repeats::PairedDifference, d: usize| {
            let [lo, hi] = x.ci95.unwrap_or([f64::NAN; 2]);
            format!("{:+.d$} [{:+.d$}, {:+.d$}]", x.mean, lo, hi, d = d)
        };
        println!(
            "  {:<29} {:>5}  MSSIM {:<27} PSNR {} dB",
            format!("{} − {}", short(m.a), short(m.b)),
            super::run::pct(m.ratio),
            ci(m, 4),
            ci(p, 2)
        );
    }
}
