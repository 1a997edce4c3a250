//! The outputs of `spibench fit` (docs/outputs.md, "fit"), from crate::fit's result:
//!
//! - `summary.json` ([`FitSummary`]): each free variable's fitted value with its standard error
//!   (or, unidentified, its range of equally good values), χ²/dof, the nuisances, the singular
//!   values and correlations, the unidentified directions with their scans, the adjustment;
//! - `fitted.ron`: the nominal bench with the fitted values set, which `run` reads;
//! - `residuals.csv`: every frame's residual (V) and its σ per channel;
//! - `residuals.svg`: the whitened residuals per channel and sequence;
//! - `report.html`: the tables and the residual figure.

use std::fmt::Write as _;

use serde::Serialize;

use crate::fit::{Fit, FitStep, Measured, Unidentified};
use crate::report::json::finite_or_null;
use crate::report::output::OutputDir;
use crate::scene::doc::BenchDoc;

/// One free variable in `summary.json`.
#[derive(Debug, Serialize)]
pub struct FittedVariable {
    pub path: String,
    pub lo: f64,
    pub hi: f64,
    pub value: f64,
    /// Null where unidentified.
    pub stderr: Option<f64>,
    pub identified: bool,
    /// The range of equally good values (the 95 % interval where identified).
    pub range_lo: f64,
    pub range_hi: f64,
}

/// One nuisance.
#[derive(Debug, Serialize)]
pub struct Nuisance {
    pub name: &'static str,
    pub value: f64,
}

/// The adjustment in `summary.json`.
#[derive(Debug, Serialize)]
pub struct AdjustmentSummary {
    pub paths: Vec<String>,
    pub values: Vec<f64>,
    pub imbalance_limit: f64,
    pub under_limit: bool,
    pub k_plus_before: f64,
    pub k_plus_before_stderr: f64,
    pub k_plus_after: f64,
    pub k_plus_after_stderr: f64,
    pub k_minus_before: f64,
    pub k_minus_before_stderr: f64,
    pub k_minus_after: f64,
    pub k_minus_after_stderr: f64,
    pub imbalance_before: f64,
    pub imbalance_before_stderr: f64,
    pub imbalance_after: f64,
    pub imbalance_after_stderr: f64,
    pub imbalance_electrical_before: f64,
    pub imbalance_electrical_before_stderr: f64,
    pub imbalance_electrical_after: f64,
    pub imbalance_electrical_after_stderr: f64,
}

/// `summary.json` of `fit`.
#[derive(Debug, Serialize)]
pub struct FitSummary {
    pub command: &'static str,
    pub spibench_version: &'static str,
    pub bench: String,
    pub measured: String,
    pub rays: u64,
    pub seed: u64,
    pub evaluations: usize,
    pub values_used: usize,
    pub dof: usize,
    pub chi2: f64,
    pub chi2_per_dof: f64,
    pub chi2_nominal: f64,
    /// What a correct model's χ² should be: its mean from each noise and its standard deviation.
    pub chi2_expected: crate::fit::chi2::Expected,
    pub chi2_expected_per_dof: f64,
    pub chi2_band_per_dof: [f64; 2],
    /// The Monte Carlo variance scale [[calibration +, −], [patterns +, −]].
    pub mc_variance_scale: [[f64; 2]; 2],
    pub noise_v: [f64; 3],
    /// The gains' prior tolerance (null: free gains).
    pub gain_tolerance: Option<f64>,
    /// Under a gain prior, the four gains' mean scale relative to the nominal electronics.
    pub lamp_scale: Option<f64>,
    /// The gain prior's rows among the residuals (0 without a prior).
    pub prior_rows: usize,
    pub variables: Vec<FittedVariable>,
    pub nuisances: Vec<Nuisance>,
    /// Each record's slow terms (the ambient light's drift between records, the room light's
    /// flicker), fitted with the nuisances.
    pub slow_terms: SlowTermsSummary,
    pub singular_values: Vec<f64>,
    pub correlation: Vec<Vec<Option<f64>>>,
    pub unidentified: Vec<Unidentified>,
    /// The joint scan of two to four unidentified variables.
    pub unidentified_grid: Option<crate::fit::identify::GridScan>,
    pub history: Vec<FitStep>,
    /// How many starts Levenberg–Marquardt ran from, and each.
    pub starts_run: usize,
    pub starts: Vec<StartSummary>,
    pub adjustment: Option<AdjustmentSummary>,
}

/// The records' slow terms in `summary.json`.
#[derive(Debug, Serialize)]
pub struct SlowTermsSummary {
    /// The hum frequencies fitted (Hz): the bench's flicker and ripple.
    pub hum_hz: Vec<f64>,
    /// Per record (in `records`' order), its offset shift per channel [RF, MONITOR+,
    /// MONITOR−] against the first record's (V).
    pub offset_shift_v: Vec<[f64; 3]>,
    /// Per record, per hum frequency, each channel's amplitude (V).
    pub hum_amplitude_v: Vec<Vec<[f64; 3]>>,
    /// The records' sequences.
    pub records: Vec<String>,
}

/// One start of the fit in `summary.json`.
#[derive(Debug, Serialize)]
pub struct StartSummary {
    pub from: Vec<f64>,
    pub coarse_chi2: Option<f64>,
    pub values: Vec<f64>,
    pub chi2: Option<f64>,
    pub chosen: bool,
}

/// The summary of a fit.
pub fn summarize(f: &Fit, doc: &BenchDoc, measured: &Measured) -> FitSummary {
    let id = &f.identification;
    let variables = f
        .free
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let x = f.best.values[i];
            let h = 1.96 * id.stderr[i];
            let (lo, hi) = id.range(i, x).unwrap_or((x - h, x + h));
            FittedVariable {
                path: v.path.clone(),
                lo: v.lo,
                hi: v.hi,
                value: x,
                stderr: finite_or_null(id.stderr[i]),
                identified: id.identified[i],
                range_lo: lo,
                range_hi: hi,
            }
        })
        .collect();
    let adjustment = f.adjustment.as_ref().map(|a| AdjustmentSummary {
        paths: a.adjust.iter().map(|x| x.path.clone()).collect(),
        values: a.values.clone(),
        imbalance_limit: a.limit,
        under_limit: a.under_limit,
        k_plus_before: a.k_plus[0].0,
        k_plus_before_stderr: a.k_plus[0].1,
        k_plus_after: a.k_plus[1].0,
        k_plus_after_stderr: a.k_plus[1].1,
        k_minus_before: a.k_minus[0].0,
        k_minus_before_stderr: a.k_minus[0].1,
        k_minus_after: a.k_minus[1].0,
        k_minus_after_stderr: a.k_minus[1].1,
        imbalance_before: a.imbalance[0].0,
        imbalance_before_stderr: a.imbalance[0].1,
        imbalance_after: a.imbalance[1].0,
        imbalance_after_stderr: a.imbalance[1].1,
        imbalance_electrical_before: a.imbalance_electrical[0].0,
        imbalance_electrical_before_stderr: a.imbalance_electrical[0].1,
        imbalance_electrical_after: a.imbalance_electrical[1].0,
        imbalance_electrical_after_stderr: a.imbalance_electrical[1].1,
    });
    FitSummary {
        command: "fit",
        spibench_version: env!("CARGO_PKG_VERSION"),
        bench: doc.name(),
        measured: measured.dir.display().to_string(),
        rays: f.rays,
        seed: f.seed,
        evaluations: f.evaluations,
        values_used: f.values_used,
        dof: f.dof,
        chi2: f.best.profiled.chi2,
        chi2_per_dof: f.chi2_per_dof(),
        chi2_nominal: f.nominal_chi2,
        chi2_expected: f.chi2_expected,
        chi2_expected_per_dof: f.chi2_expected.mean() / f.dof.max(1) as f64,
        chi2_band_per_dof: [-2.0, 2.0]
            .map(|k| (f.chi2_expected.mean() + k * f.chi2_expected.sd) / f.dof.max(1) as f64),
        mc_variance_scale: f.variance_scale.0,
        noise_v: measured.noise_v,
        gain_tolerance: f.gain_tolerance,
        lamp_scale: f.best.profiled.lamp_scale,
        prior_rows: f.best.profiled.prior_rows,
        variables,
        nuisances: f
            .nuisances()
            .into_iter()
            .map(|(name, value)| Nuisance { name, value })
            .collect(),
        slow_terms: slow_terms(f, measured),
        singular_values: id.singular_values.clone(),
        correlation: id
            .correlation
            .iter()
            .map(|r| r.iter().map(|&c| finite_or_null(c)).collect())
            .collect(),
        unidentified: id.unidentified.clone(),
        unidentified_grid: id.grid.clone(),
        history: f.history.clone(),
        starts_run: f.starts.len(),
        starts: f
            .starts
            .iter()
            .map(|r| StartSummary {
                from: r.from.clone(),
                coarse_chi2: finite_or_null(r.coarse_chi2),
                values: r.values.clone(),
                chi2: finite_or_null(r.chi2),
                chosen: r.chosen,
            })
            .collect(),
        adjustment,
    }
}

const CHANNELS: [&str; 3] = ["RF", "MONITOR+", "MONITOR−"];

/// `residuals.csv`.
fn residuals_csv(f: &Fit, m: &Measured) -> String {
    let mut s = String::from(
        "sequence,frame,rf_residual_v,rf_sigma_v,monitor_plus_residual_v,monitor_plus_sigma_v,\
         monitor_minus_residual_v,monitor_minus_sigma_v\n",
    );
    let p = &f.best.profiled;
    for (k, q) in m.sequences.iter().enumerate() {
        for (i, (r, sg)) in p.residual_v[k].iter().zip(&p.sigma_v[k]).enumerate() {
            let _ = write!(s, "{},{i}", q.sequence.key());
            for o in 0..3 {
                let cell = |v: f64| {
                    if v.is_finite() {
                        format!("{v:e}")
                    } else {
                        String::new()
                    }
                };
                let _ = write!(s, ",{},{}", cell(r[o]), cell(sg[o]));
            }
            s.push('\n');
        }
    }
    s
}

/// The whitened residuals as one SVG: a row per channel, the sequences side by side.
fn residuals_svg(f: &Fit, m: &Measured) -> String {
    let p = &f.best.profiled;
    let total: usize = p.residual_v.iter().map(Vec::len).sum::<usize>().max(2);
    let (w, ph) = (900.0, 110.0);
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{}' font-size='11'>",
        3.0 * (ph + 16.0) + 16.0
    );
    let x_of = |k: usize| 70.0 + (w - 80.0) * k as f64 / (total - 1) as f64;
    for (o, name) in CHANNELS.iter().enumerate() {
        let y0 = o as f64 * (ph + 16.0) + 8.0;
        let y_of = |z: f64| y0 + ph / 2.0 - (ph / 2.0) * (z / 4.0).clamp(-1.0, 1.0);
        let _ = write!(
            s,
            "<rect x='70' y='{y0}' width='{}' height='{ph}' fill='none' stroke='#999'/>\
             <line x1='70' x2='{}' y1='{:.1}' y2='{:.1}' stroke='#bbb'/>\
             <text x='2' y='{:.1}'>{name}</text><text x='40' y='{:.1}'>+4σ</text>\
             <text x='40' y='{:.1}'>−4σ</text>",
            w - 80.0,
            w - 10.0,
            y_of(0.0),
            y_of(0.0),
            y0 + ph / 2.0,
            y0 + 10.0,
            y0 + ph
        );
        let mut k = 0;
        for (seq, q) in m.sequences.iter().enumerate() {
            for (r, sg) in p.residual_v[seq].iter().zip(&p.sigma_v[seq]) {
                if r[o].is_finite() {
                    let _ = write!(
                        s,
                        "<circle cx='{:.1}' cy='{:.1}' r='1.2' fill='#124'/>",
                        x_of(k),
                        y_of(r[o] / sg[o])
                    );
                }
                k += 1;
            }
            if o == 2 {
                let _ = write!(
                    s,
                    "<text x='{:.1}' y='{:.1}'>{}</text>",
                    x_of(k.saturating_sub(p.residual_v[seq].len())),
                    3.0 * (ph + 16.0) + 12.0,
                    q.sequence.key()
                );
            }
        }
    }
    s.push_str("</svg>");
    s
}

fn report_html(summary: &FitSummary, svg: &str) -> String {
    let mut h = String::from(
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>spibench fit</title>\
         <style>body{font-family:sans-serif;max-width:960px;margin:auto}table{border-collapse:\
         collapse}td,th{border:1px solid #bbb;padding:2px 6px;text-align:right}</style></head>\
         <body><h1>The bench as built</h1>",
    );
    let _ = write!(
        h,
        "<p>{} frame values fitted, {} degrees of freedom: χ² = {:.1} (χ²/dof = {:.3}; the \
         nominal bench {:.1}), {} rays, seed {}, {} traces.</p>",
        summary.values_used,
        summary.dof,
        summary.chi2,
        summary.chi2_per_dof,
        summary.chi2_nominal,
        summary.rays,
        summary.seed,
        summary.evaluations
    );
    if let Some(w) = band_warning(summary) {
        let _ = write!(h, "<p><strong>{w}.</strong></p>");
    }
    h.push_str(
        "<h2>Fitted variables</h2><table><tr><th>variable</th><th>value</th><th>± SE</th>\
         <th>range (95 % or equally good)</th><th>identified</th></tr>",
    );
    for v in &summary.variables {
        let se = v.stderr.map_or("–".to_string(), |s| format!("{s:.4}"));
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{:.4}</td><td>{se}</td><td>{:.4} … {:.4}</td><td>{}</td></tr>",
            v.path, v.value, v.range_lo, v.range_hi, v.identified
        );
    }
    h.push_str("</table><h2>Nuisances</h2><table>");
    for n in &summary.nuisances {
        let _ = write!(h, "<tr><td>{}</td><td>{:.6}</td></tr>", n.name, n.value);
    }
    let _ = write!(
        h,
        "</table><p>Singular values: {:?}</p><h2>Residuals</h2><p>Whitened residuals (measured \
         − model) / σ of every frame value, per channel.</p>{svg}",
        summary.singular_values
    );
    if let Some(a) = &summary.adjustment {
        let _ = write!(
            h,
            "<h2>Adjustment</h2><p>{} = {:?}: electrical imbalance {:.5} ± {:.5} → {:.5} ± \
             {:.5} (limit {}: {}); optical imbalance {:.5} ± {:.5} → {:.5} ± {:.5}; k₊ {:.4e} → \
             {:.4e} A/W, k₋ {:.4e} → {:.4e} A/W.</p>",
            a.paths.join(", "),
            a.values,
            a.imbalance_electrical_before,
            a.imbalance_electrical_before_stderr,
            a.imbalance_electrical_after,
            a.imbalance_electrical_after_stderr,
            a.imbalance_limit,
            if a.under_limit { "under" } else { "not under" },
            a.imbalance_before,
            a.imbalance_before_stderr,
            a.imbalance_after,
            a.imbalance_after_stderr,
            a.k_plus_before,
            a.k_plus_after,
            a.k_minus_before,
            a.k_minus_after
        );
    }
    h.push_str("</body></html>\n");
    h
}

/// Writes every output of a fit into `out` (a staging folder); returns the files.
pub fn write(
    f: &Fit,
    doc: &BenchDoc,
    measured: &Measured,
    provenance: &crate::provenance::Provenance,
    out: &OutputDir,
) -> crate::Result<Vec<String>> {
    let summary = summarize(f, doc, measured);
    super::summary::write_summary(out, &summary, provenance)?;
    let ron = doc.with(&f.settings())?.to_ron()?;
    let text = [
        ("fitted.ron", ron),
        ("residuals.csv", residuals_csv(f, measured)),
        ("residuals.svg", residuals_svg(f, measured)),
    ];
    let svg = text[2].1.clone();
    for (name, body) in text {
        let p = out.path(name);
        std::fs::write(&p, body).map_err(|e| crate::Error::write(&p, e))?;
    }
    let p = out.path("report.html");
    std::fs::write(&p, report_html(&summary, &svg)).map_err(|e| crate::Error::write(&p, e))?;
    Ok([
        "summary.json",
        "fitted.ron",
        "residuals.csv",
        "residuals.svg",
        "report.html",
    ]
    .map(String::from)
    .to_vec())
}

fn slow_terms(f: &Fit, measured: &Measured) -> SlowTermsSummary {
    let records = measured.sequences.len();
    let (offset_shift_v, hum_amplitude_v) = f.slow.split(records, &f.best.profiled.slow);
    SlowTermsSummary {
        hum_hz: f.slow.hum_hz.clone(),
        offset_shift_v,
        hum_amplitude_v,
        records: measured
            .sequences
            .iter()
            .map(|q| q.sequence.key().to_string())
            .collect(),
    }
}

/// What a χ²/dof outside its sampling band says, or None inside it.
fn band_warning(s: &FitSummary) -> Option<String> {
    let [lo, hi] = s.chi2_band_per_dof;
    let why = if s.chi2_per_dof > hi {
        "the fit stopped in a valley the frames do not prefer, or the bench lacks what made \
         them (another --seed or more --rays tells which)"
    } else if s.chi2_per_dof < lo {
        "the frames' noise is overstated (noise_v), or the model's traces share more than \
         their batches say"
    } else {
        return None;
    };
    Some(format!(
        "χ²/dof outside its sampling band [{lo:.3}, {hi:.3}]: {why}"
    ))
}

/// The lines `fit` prints.
pub fn printed(f: &Fit, doc: &BenchDoc, measured: &Measured) -> Vec<String> {
    let s = summarize(f, doc, measured);
    let mut lines = vec![format!(
        "χ²/dof = {:.3} ({} values, {} dof; nominal bench χ² {:.1})",
        s.chi2_per_dof, s.values_used, s.dof, s.chi2_nominal
    )];
    if let Some(w) = band_warning(&s) {
        lines.push(w);
    }
    for v in &s.variables {
        lines.push(match v.stderr {
            Some(se) if v.identified => format!("{:<36} {:>10.4} ± {:.4}", v.path, v.value, se),
            _ => format!(
                "{:<36} unidentified: equally good from {:.4} to {:.4}",
                v.path, v.range_lo, v.range_hi
            ),
        });
    }
    if let Some(a) = &s.adjustment {
        lines.push(format!(
            "adjustment {}: electrical imbalance {:.5} → {:.5} ({} the limit {}), optical \
             {:.5} → {:.5}",
            a.paths
                .iter()
                .zip(&a.values)
                .map(|(p, v)| format!("{p} = {v:.4}"))
                .collect::<Vec<_>>()
                .join(", "),
            a.imbalance_electrical_before,
            a.imbalance_electrical_after,
            if a.under_limit { "under" } else { "not under" },
            a.imbalance_limit,
            a.imbalance_before,
            a.imbalance_after
        ));
    }
    lines
}
