//! The outputs of `spibench intake` (docs/outputs.md, "intake"), from what crate::intake found:
//!
//! - `summary.json` ([`IntakeSummary`]): each record (layout, sequence, channels, timing, frame
//!   table statistics, trigger anomalies), each arm's calibration with standard errors, and
//!   every scheme × ratio's solve and scores (with the frames flagged among those it used);
//! - `frames.csv`: one row per frame of every record (sequence, index, start time, settled
//!   samples, the values of RF, MONITOR+, MONITOR−, flags);
//! - `measurements/<scheme>_r<ratio>_v.npy` and `reconstructions/<scheme>_r<ratio>.npy` (the
//!   solver's image, float64, row-major), `images/<scheme>__r<ratio>.png` (normalised to the
//!   truth's 0–255 when a truth is given, else over its own range);
//! - `report.html`: the record's first frames with the found frame boundaries and settled
//!   windows overlaid, the calibration and the scores' table.

use std::fmt::Write as _;
use std::io::Write as _;

use serde::Serialize;

use crate::intake::frames::{FLAG_CLIPPED, FLAG_IRREGULAR, FLAG_NO_PULSE};
use crate::intake::{ArmCalibration, Intake, IntakeRecord, Layout, TriggerAnomaly};
use crate::report::json::finite_or_null;
use crate::report::output::OutputDir;

/// One record in `summary.json`.
#[derive(Debug, Serialize)]
pub struct RecordSummary {
    pub file: String,
    pub layout: Layout,
    pub sequence: &'static str,
    pub samples: usize,
    pub sample_interval_s: f64,
    /// The record's columns for RF, MON+, MON−, TRIG (`none`: no trigger).
    pub channels: [String; 4],
    /// `trigger` (edges) or `preamble` (frame rate and the calibration steps).
    pub frame_method: &'static str,
    pub trigger_edges: usize,
    pub frame_s: f64,
    pub settling_s: f64,
    pub sample_rate_hz: f64,
    /// `sidecar` (the record's JSON) or `settings` (frame rate given or the bench's).
    pub timing_from: &'static str,
    pub frames: usize,
    pub settled_samples_min: usize,
    pub settled_samples_max: usize,
    pub clipped_frames: usize,
    pub irregular_frames: usize,
    pub anomalies: Vec<TriggerAnomaly>,
    /// SHA-256 of the frames' packed rows (crate::intake::IntakeRecord::patterns_sha256).
    pub patterns_sha256: String,
}

/// One scheme × ratio in `summary.json`.
#[derive(Debug, Serialize)]
pub struct IntakeResult {
    pub scheme: &'static str,
    pub ratio: f64,
    pub measurements: usize,
    pub dmd_frames: usize,
    pub psnr_db: Option<f64>,
    pub mssim: Option<f64>,
    pub iterations: usize,
    pub converged: bool,
    pub relative_residual: f64,
    /// A clipped frame among those the scheme read.
    pub saturated: bool,
    pub flagged_frames: usize,
    pub measurements_file: String,
    pub reconstruction_file: String,
}

/// `summary.json` of `intake`.
#[derive(Debug, Serialize)]
pub struct IntakeSummary {
    pub command: &'static str,
    pub spibench_version: &'static str,
    pub units_across: usize,
    pub units_down: usize,
    pub base_patterns: usize,
    pub records: Vec<RecordSummary>,
    pub calibration: Option<[ArmCalibration; 2]>,
    pub scored: bool,
    pub results: Vec<IntakeResult>,
}

fn tag(r: &crate::pipeline::SchemeResult) -> String {
    format!("{}_r{:.4}", r.scheme.key(), r.ratio)
}

/// The summary of what intake found.
pub fn summarize(i: &Intake) -> IntakeSummary {
    let records = i.records.iter().map(record_summary).collect();
    let results = i
        .results
        .iter()
        .zip(&i.flagged)
        .map(|(r, &flagged)| IntakeResult {
            scheme: r.scheme.key(),
            ratio: r.ratio,
            measurements: r.measurements,
            dmd_frames: r.dmd_frames,
            psnr_db: finite_or_null(r.psnr_db),
            mssim: finite_or_null(r.mssim),
            iterations: r.iterations,
            converged: r.converged,
            relative_residual: r.relative_residual,
            saturated: r.saturated,
            flagged_frames: flagged,
            measurements_file: format!("measurements/{}_v.npy", tag(r)),
            reconstruction_file: format!("reconstructions/{}.npy", tag(r)),
        })
        .collect();
    IntakeSummary {
        command: "intake",
        spibench_version: env!("CARGO_PKG_VERSION"),
        units_across: i.units.0,
        units_down: i.units.1,
        base_patterns: i.base_patterns,
        records,
        calibration: i.calibration,
        scored: i.truth.is_some(),
        results,
    }
}

fn record_summary(r: &IntakeRecord) -> RecordSummary {
    let f = &r.found.frames;
    let count = |flag: u8| f.iter().filter(|x| x.flags & flag != 0).count();
    RecordSummary {
        file: r.path.display().to_string(),
        layout: r.layout,
        sequence: r.sequence.key(),
        samples: r.samples,
        sample_interval_s: r.sample_interval_s,
        channels: r.channel_names.clone(),
        frame_method: r.found.method,
        trigger_edges: r.found.edges,
        frame_s: r.timing.frame_s,
        settling_s: r.timing.settling_s,
        sample_rate_hz: r.timing.sample_rate_hz,
        timing_from: r.timing_from,
        frames: f.len(),
        settled_samples_min: f.iter().map(|x| x.settled_samples).min().unwrap_or(0),
        settled_samples_max: f.iter().map(|x| x.settled_samples).max().unwrap_or(0),
        clipped_frames: count(FLAG_CLIPPED),
        irregular_frames: count(FLAG_IRREGULAR),
        anomalies: r.found.anomalies.clone(),
        patterns_sha256: r.patterns_sha256.clone(),
    }
}

fn flag_text(flags: u8) -> String {
    let mut v = Vec::new();
    if flags & FLAG_CLIPPED != 0 {
        v.push("clipped");
    }
    if flags & FLAG_IRREGULAR != 0 {
        v.push("irregular_period");
    }
    if flags & FLAG_NO_PULSE != 0 {
        v.push("missing_pulse");
    }
    v.join(";")
}

/// `frames.csv`: every frame of every record.
fn write_frames_csv(i: &Intake, out: &OutputDir) -> crate::Result<()> {
    let path = out.path("frames.csv");
    let file = std::fs::File::create(&path).map_err(|e| crate::Error::write(&path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let mut text = String::from(
        "sequence,frame,start_s,settled_samples,rf_v,monitor_plus_v,monitor_minus_v,flags\n",
    );
    for r in &i.records {
        for (k, f) in r.found.frames.iter().enumerate() {
            let _ = writeln!(
                text,
                "{},{k},{:e},{},{},{},{},{}",
                r.sequence.key(),
                frame_time_of(r, f),
                f.settled_samples,
                f.values[0],
                f.values[1],
                f.values[2],
                flag_text(f.flags)
            );
            if text.len() > 1 << 16 {
                w.write_all(text.as_bytes())
                    .map_err(|e| crate::Error::write(&path, e))?;
                text.clear();
            }
        }
    }
    w.write_all(text.as_bytes())
        .and_then(|_| w.flush())
        .map_err(|e| crate::Error::write(&path, e))
}

/// A frame's start from the record's first sample (s).
fn frame_time_of(r: &IntakeRecord, f: &crate::intake::frames::FoundFrame) -> f64 {
    f.start * r.sample_interval_s
}

/// Writes every output of an intake into `out` (a staging folder); returns the files.
pub fn write(
    i: &Intake,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<Vec<String>> {
    let mut files = vec!["summary.json".to_string(), "frames.csv".to_string()];
    let summary = summarize(i);
    super::summary::write_summary(out, &summary, provenance)?;
    write_frames_csv(i, out)?;
    for r in &i.results {
        let t = tag(r);
        let m = format!("measurements/{t}_v.npy");
        crate::report::npy::write_f64(&out.try_path(&m)?, &[r.y.len()], &r.y)?;
        let s = format!("reconstructions/{t}.npy");
        crate::report::npy::write_f64(
            &out.try_path(&s)?,
            &[r.solution.height, r.solution.width],
            &r.solution.data,
        )?;
        let png = format!("images/{}__r{:.3}.png", r.scheme.key(), r.ratio);
        let img = if i.truth.is_some() {
            r.reconstruction.clone()
        } else {
            let (lo, hi) = (r.solution.min(), r.solution.max());
            let span = if hi > lo { hi - lo } else { 1.0 };
            r.solution.map(|v| 255.0 * (v - lo) / span)
        };
        crate::report::png::write_gray8(&out.try_path(&png)?, &img, 0.0, 255.0)?;
        files.extend([m, s, png]);
    }
    let html = report_html(i, &summary);
    let path = out.path("report.html");
    std::fs::write(&path, html).map_err(|e| crate::Error::write(&path, e))?;
    files.push("report.html".into());
    Ok(files)
}

/// The lines `intake` prints.
pub fn printed(i: &Intake) -> Vec<String> {
    let mut lines = Vec::new();
    for r in &i.records {
        let f = &r.found.frames;
        lines.push(format!(
            "{}: {} frames of the {} sequence ({} layout, frames from the {}), {} clipped, {} \
             irregular, {} trigger anomalies",
            r.path.display(),
            f.len(),
            r.sequence.key(),
            format!("{:?}", r.layout).to_lowercase(),
            r.found.method,
            f.iter().filter(|x| x.flags & FLAG_CLIPPED != 0).count(),
            f.iter().filter(|x| x.flags & FLAG_IRREGULAR != 0).count(),
            r.found.anomalies.len()
        ));
        for a in &r.found.anomalies {
            lines.push(format!(
                "  warning: {} at frame {} (t = {:.6e} s, sample {})",
                a.kind.replace('_', " "),
                a.frame,
                a.time_s,
                a.sample
            ));
        }
    }
    if let Some(c) = &i.calibration {
        for a in c {
            lines.push(format!(
                "arm {}: gain {:.6e} ± {:.2e} V, offset {:.6e} ± {:.2e} V ({} frames per level)",
                a.arm, a.gain_v, a.gain_stderr_v, a.offset_v, a.offset_stderr_v, a.frames_per_level
            ));
        }
    }
    for (r, &fl) in i.results.iter().zip(&i.flagged) {
        lines.push(format!(
            "{:<36} r = {:.2}: PSNR {:>7.2} dB, MSSIM {:.4}{}",
            r.scheme.key(),
            r.ratio,
            r.psnr_db,
            r.mssim,
            if fl > 0 {
                format!(" ({fl} clipped frames: saturated)")
            } else {
                String::new()
            }
        ));
    }
    lines
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The first frames of a record as one SVG: a panel per channel, the found frame starts as
/// lines and the settled windows shaded.
fn record_svg(r: &IntakeRecord) -> String {
    let (w, ph) = (900.0, 90.0);
    let n = r.head.len();
    if n < 2 {
        return String::new();
    }
    let names = ["RF", "MONITOR+", "MONITOR−", "TRIG"];
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{}' font-size='11'>",
        4.0 * (ph + 12.0)
    );
    let x_of = |k: f64| 60.0 + (w - 70.0) * k / (n - 1) as f64;
    let rule = crate::detector::SettleRule::of(r.timing);
    for (c, name) in names.iter().enumerate() {
        let y0 = c as f64 * (ph + 12.0) + 6.0;
        let vals: Vec<f64> = r.head.iter().map(|v| v[c]).collect();
        if vals.iter().any(|v| v.is_nan()) {
            continue;
        }
        let (lo, hi) = vals
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let span = if hi > lo { hi - lo } else { 1.0 };
        for f in &r.found.frames {
            if f.first_sample as usize >= n {
                break;
            }
            let settled = f.start + rule.settle;
            let end = (f.end_sample as f64).min((n - 1) as f64);
            if settled < end {
                let _ = write!(
                    s,
                    "<rect x='{:.1}' y='{y0:.1}' width='{:.1}' height='{ph}' fill='#dde8f6'/>",
                    x_of(settled),
                    x_of(end) - x_of(settled)
                );
            }
            let _ = write!(
                s,
                "<line x1='{x:.1}' x2='{x:.1}' y1='{y0:.1}' y2='{:.1}' stroke='#c33'/>",
                y0 + ph,
                x = x_of(f.start)
            );
        }
        let mut pts = String::new();
        for (k, v) in vals.iter().enumerate() {
            let _ = write!(
                pts,
                "{:.1},{:.1} ",
                x_of(k as f64),
                y0 + ph * (1.0 - (v - lo) / span)
            );
        }
        let _ = write!(
            s,
            "<polyline fill='none' stroke='#124' stroke-width='0.8' points='{pts}'/>\
             <text x='2' y='{:.1}'>{name}</text>",
            y0 + ph / 2.0
        );
    }
    s.push_str("</svg>");
    s
}

fn report_html(i: &Intake, summary: &IntakeSummary) -> String {
    let mut h = String::from(
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>spibench intake</title>\
         <style>body{font-family:sans-serif;max-width:960px;margin:auto}table{border-collapse:\
         collapse}td,th{border:1px solid #bbb;padding:2px 6px;text-align:right}</style></head><body>\
         <h1>Measurements taken in</h1>",
    );
    for r in &i.records {
        let _ = write!(
            h,
            "<h2>{} sequence</h2><p>{} — {} samples, {} frames found from the {}; the red lines \
             are the frame starts found, the shaded spans the settled windows whose means are \
             the frame values.</p>{}",
            r.sequence.key(),
            esc(&r.path.display().to_string()),
            r.samples,
            r.found.frames.len(),
            r.found.method,
            record_svg(r)
        );
        if !r.found.anomalies.is_empty() {
            h.push_str("<p>Trigger anomalies:</p><ul>");
            for a in &r.found.anomalies {
                let _ = write!(
                    h,
                    "<li>{} at frame {} (t = {:.6e} s)</li>",
                    a.kind, a.frame, a.time_s
                );
            }
            h.push_str("</ul>");
        }
    }
    if let Some(c) = &i.calibration {
        h.push_str(
            "<h2>Calibration</h2><table><tr><th>arm</th><th>gain (V)</th><th>± (V)</th>\
             <th>offset (V)</th><th>± (V)</th></tr>",
        );
        for a in c {
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{:.6e}</td><td>{:.2e}</td><td>{:.6e}</td><td>{:.2e}</td></tr>",
                a.arm, a.gain_v, a.gain_stderr_v, a.offset_v, a.offset_stderr_v
            );
        }
        h.push_str("</table>");
    }
    h.push_str(
        "<h2>Schemes</h2><table><tr><th>scheme</th><th>ratio</th><th>PSNR (dB)</th>\
         <th>MSSIM</th><th>iterations</th><th>clipped frames</th></tr>",
    );
    for r in &summary.results {
        let num = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.4}"));
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{:.2}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            r.scheme,
            r.ratio,
            num(r.psnr_db),
            num(r.mssim),
            r.iterations,
            r.flagged_frames
        );
    }
    h.push_str("</table></body></html>\n");
    h
}
