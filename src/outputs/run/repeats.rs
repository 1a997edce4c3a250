//! The repeat statistics of `spibench run --repeats N` (crate::run::repeats): `repeats.json`,
//! `repeats.csv`, the scores against the frames shown (equal-cost comparison) with error bars,
//! and the printed table of the paired differences ([`lines`]).
//!
//! Files (with `--repeats 1` the standard deviations are 0 and no intervals are given):
//! - `repeats.json`: [`Repeats`] (per scheme × ratio: frames, acquisition time, mean and
//!   sample SD of PSNR and MSSIM; paired differences with 95 % intervals; the seeds);
//! - `repeats.csv`: the per scheme × ratio rows;
//! - `mssim_vs_frames.{svg,png}`, `psnr_vs_frames.{svg,png}`: each scheme's mean score against
//!   the DMD frames it showed (calibration frames included), ± one SD, so schemes that show a
//!   pattern and its complement are compared with those that show it once at equal cost.

use crate::run::findings::{pct, short};
use crate::run::repeats::Repeats;

/// Writes the repeat files into `out` and returns their names.
#[cfg(feature = "figures")]
pub fn write(
    r: &Repeats,
    s: &crate::run::RunSettings,
    out: &crate::report::output::OutputDir,
) -> crate::Result<Vec<String>> {
    use crate::report::csv::write_csv;
    use crate::report::json::write_json;
    use crate::report::plot::{LinePlot, Series, write_plot};
    use crate::run::repeats::RepeatStats;
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

/// The paired differences as printed lines under 100 columns (nothing for one repeat): one
/// line per comparison and ratio, MSSIM and PSNR side by side, each with its 95 % interval.
/// Scheme names are the findings' short ones, the columns as wide
/// as their widest entry; a row that would still pass 100 columns (PSNR differences of tens of
/// dB) puts its PSNR on a line of its own.
pub fn lines(r: &Repeats) -> Vec<String> {
    if r.repeats < 2 {
        return Vec::new();
    }
    let ci = |x: &crate::run::repeats::PairedDifference, d: usize| {
        let [lo, hi] = x.ci95.unwrap_or([f64::NAN; 2]);
        format!("{:+.d$} [{:+.d$}, {:+.d$}]", x.mean, lo, hi, d = d)
    };
    let rows: Vec<[String; 4]> = r
        .paired
        .chunks(2)
        .filter_map(|pair| {
            let [m, p] = pair else { return None };
            Some([
                format!("{} − {}", short(m.a), short(m.b)),
                pct(m.ratio),
                ci(m, 4),
                ci(p, 2),
            ])
        })
        .collect();
    let width = |c: usize| rows.iter().map(|x| x[c].chars().count()).max().unwrap_or(0);
    let (wl, wr, wm) = (width(0), width(1), width(2));
    let mut out = vec![format!(
        "paired differences over {} repeats: mean [95 % interval]",
        r.repeats
    )];
    for [label, ratio, mssim, psnr] in rows {
        let head = format!("  {label:<wl$} {ratio:>wr$}  MSSIM {mssim:<wm$}");
        let line = format!("{head}  PSNR {psnr} dB");
        if line.chars().count() <= 100 {
            out.push(line);
        } else {
            out.push(head.trim_end().to_string());
            out.push(format!("  {:wl$} {:wr$}  PSNR  {psnr} dB", "", ""));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acquisition::Scheme;
    use crate::run::repeats::PairedDifference;

    fn pair(b: Scheme, ratio: f64, metric: &'static str, mean: f64) -> PairedDifference {
        PairedDifference {
            a: Scheme::SecondaryComplementaryBalancing,
            b,
            ratio,
            metric,
            repeats: 3,
            mean,
            sd: mean.abs(),
            ci95: Some([mean - 2.0 * mean.abs(), mean + 2.0 * mean.abs()]),
        }
    }

    /// Every line fits 100 columns, for the longest baseline names (offset-aware double-arm
    /// printed 101 columns before), a ratio of one decimal and PSNR differences of tens of dB;
    /// every comparison is still printed.
    #[test]
    fn paired_table_fits_100_columns() {
        let mut paired = Vec::new();
        for b in [
            Scheme::SingleArmComplementary,
            Scheme::DoubleArmCalibrated,
            Scheme::DoubleArmOffset,
            Scheme::TraditionalZeroMean,
        ] {
            for (ratio, dm, dp) in [(0.125, -0.0012, -0.31), (1.0, 0.1234, -123.45)] {
                paired.push(pair(b, ratio, "mssim", dm));
                paired.push(pair(b, ratio, "psnr_db", dp));
            }
        }
        let r = Repeats {
            repeats: 3,
            seeds: vec![1, 2, 3],
            stats: Vec::new(),
            paired,
        };
        let lines = lines(&r);
        for l in &lines {
            assert!(
                l.chars().count() <= 100,
                "{} columns: {l}",
                l.chars().count()
            );
        }
        assert_eq!(lines.iter().filter(|l| l.contains("MSSIM")).count(), 8);
        assert_eq!(lines.iter().filter(|l| l.contains("PSNR")).count(), 8);
        assert!(lines.iter().any(|l| l.contains("SCB − offset dbl-arm")));
        assert!(lines.iter().any(|l| l.contains("12.5 %")));
        // One repeat: nothing to print.
        let one = Repeats { repeats: 1, ..r };
        assert!(super::lines(&one).is_empty());
    }
}
