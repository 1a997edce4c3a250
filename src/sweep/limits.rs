//! A limit on a metric along a 1-D sweep (`spibench sweep --limit METRIC=VALUE`): where
//! |METRIC| crosses VALUE, with an interval.
//!
//! Between two neighbouring grid points on either side of the limit, the crossing is found by
//! linear interpolation of |m| against the swept variable:
//! x* = xᵢ + (L − yᵢ)·(xᵢ₊₁ − xᵢ)/(yᵢ₊₁ − yᵢ). Its standard error comes from the two points'
//! standard errors by the delta method, ∂x*/∂yᵢ = Δx·(L − yᵢ₊₁)/Δy² and
//! ∂x*/∂yᵢ₊₁ = −Δx·(L − yᵢ)/Δy². The points of a sweep share their random numbers, so their
//! errors are correlated (crate::sweep); the two terms are added linearly,
//! σ = |∂x*/∂yᵢ|·σᵢ + |∂x*/∂yᵢ₊₁|·σᵢ₊₁, the bound for any correlation (for both points
//! moving together it is exact: δ·Δx/Δy). The 95 % interval is x* ± 1.96σ. The linear
//! interpolation's own error (the curve's bend between the points) is not in it: a finer grid
//! near the crossing shrinks it.

use serde::Serialize;

use super::Sweep;
use crate::error::{Error, Result};
use crate::quantities::{BenchMetric, Quantity};

/// A limit on one metric: |metric| ≤ value.
#[derive(Debug, Clone, PartialEq)]
pub struct MetricLimit {
    pub metric: Quantity,
    pub value: f64,
}

impl MetricLimit {
    /// Parses `METRIC=VALUE` (VALUE finite and ≥ 0; METRIC a recorded metric, the image scores
    /// only with the whole pipeline, `quality`). Errors name the field `limit`.
    pub fn parse(text: &str, quality: bool) -> Result<MetricLimit> {
        let bad = |why: String| Error::field("limit", format!("`{text}`: {why}"));
        let (metric, value) = text
            .split_once('=')
            .ok_or_else(|| bad("expected METRIC=VALUE, e.g. imbalance=0.01".into()))?;
        let metric = metric.trim();
        let Some(known) = metric
            .parse::<Quantity>()
            .ok()
            .filter(|q| q.is_traced() || quality)
        else {
            let names: Vec<String> = BenchMetric::ALL
                .map(Quantity::Metric)
                .into_iter()
                .chain(Quantity::CMRRS)
                .map(|q| q.to_string())
                .collect();
            return Err(bad(format!(
                "unknown metric `{metric}` (one of {}; image scores with `quality`)",
                names.join(", ")
            )));
        };
        let value: f64 = value
            .trim()
            .parse()
            .map_err(|_| bad("VALUE must be a number".into()))?;
        if !(value.is_finite() && value >= 0.0) {
            return Err(bad(format!(
                "VALUE is a limit on |{metric}|: finite and ≥ 0"
            )));
        }
        Ok(MetricLimit {
            metric: known,
            value,
        })
    }
}

/// Where |metric| crosses the limit between two grid points.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Crossing {
    /// The crossing, in the swept variable's unit.
    pub at: f64,
    /// Its standard error from the two points' standard errors (null when they have none).
    pub stderr: f64,
    /// at ± 1.96 · stderr (null without standard errors).
    pub ci95: Option<[f64; 2]>,
    /// `leaves` (|metric| rises above the limit, in the direction of the sweep) or `enters`.
    pub direction: &'static str,
    /// The grid values on either side.
    pub between: [f64; 2],
}

/// One `--limit` over the sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LimitReport {
    pub metric: String,
    /// |metric| ≤ limit.
    pub limit: f64,
    /// The swept variable.
    pub variable: String,
    /// Grid points meeting the limit, of the points with a value.
    pub points_within: usize,
    pub points: usize,
    pub crossings: Vec<Crossing>,
}

impl LimitReport {
    /// The report as printed lines (under 100 columns for paths up to about 50 characters):
    /// the limit, then one line per crossing.
    pub fn lines(&self) -> Vec<String> {
        let text = self.sentence();
        match text.split_once(": ") {
            Some((head, rest)) if !self.crossings.is_empty() => std::iter::once(format!("{head}:"))
                .chain(rest.split("; ").map(|c| format!("  {c}")))
                .collect(),
            _ => vec![text],
        }
    }

    /// The report in one sentence.
    pub fn sentence(&self) -> String {
        let head = format!("|{}| ≤ {} along {}", self.metric, self.limit, self.variable);
        if self.crossings.is_empty() {
            return if self.points_within == self.points && self.points > 0 {
                format!(
                    "{head}: met at every point ({} of {})",
                    self.points, self.points
                )
            } else if self.points_within == 0 {
                format!("{head}: exceeded at every point ({})", self.points)
            } else {
                format!("{head}: no crossing")
            };
        }
        let parts: Vec<String> = self
            .crossings
            .iter()
            .map(|c| {
                let d = digits(c.stderr, c.between[1] - c.between[0]);
                match c.ci95 {
                    Some([lo, hi]) => format!(
                        "{} at {:.d$} ± {:.d$} (95 %: [{lo:.d$}, {hi:.d$}])",
                        c.direction, c.at, c.stderr
                    ),
                    None => format!("{} at {:.d$} (no standard error)", c.direction, c.at),
                }
            })
            .collect();
        format!("{head}: {}", parts.join("; "))
    }
}

/// Decimals that show a standard error to two significant figures (or the grid step's scale
/// without one).
fn digits(se: f64, step: f64) -> usize {
    let scale = if se.is_finite() && se > 0.0 {
        se
    } else {
        step.abs() / 100.0
    };
    if !(scale.is_finite() && scale > 0.0) {
        return 3;
    }
    (1.0 - scale.log10().floor()).clamp(0.0, 12.0) as usize
}

/// The crossings of |y| = limit along x (points with a non-finite value skipped), each with
/// its interval; `se` the points' standard errors (NaN: none).
pub fn crossings(x: &[f64], y: &[f64], se: &[f64], limit: f64) -> Vec<Crossing> {
    let pts: Vec<(f64, f64, f64)> = (0..x.len())
        .filter(|&i| y[i].is_finite())
        .map(|i| (x[i], y[i].abs(), se[i]))
        .collect();
    let mut out = Vec::new();
    for w in pts.windows(2) {
        let [(x0, y0, s0), (x1, y1, s1)] = [w[0], w[1]];
        let (above0, above1) = (y0 > limit, y1 > limit);
        if above0 == above1 {
            continue;
        }
        let (dx, dy) = (x1 - x0, y1 - y0);
        let at = x0 + (limit - y0) * dx / dy;
        let d0 = dx * (limit - y1) / (dy * dy);
        let d1 = -dx * (limit - y0) / (dy * dy);
        let stderr = d0.abs() * s0 + d1.abs() * s1;
        let h = 1.959_964 * stderr;
        out.push(Crossing {
            at,
            stderr,
            ci95: h.is_finite().then_some([at - h, at + h]),
            direction: if above1 { "leaves" } else { "enters" },
            between: [x0, x1],
        });
    }
    out
}

/// The report of one limit over a 1-D sweep: the metric at every grid point, as
/// [`crate::pipeline::evaluate::values`] records it against the nominal bench (the numbers of
/// the sweep's metric rows), with its standard error.
pub fn report(limit: &MetricLimit, s: &Sweep) -> Result<LimitReport> {
    let [v] = s.vary.as_slice() else {
        return Err(Error::field(
            "limit",
            "a crossing is found along one variable: sweep one",
        ));
    };
    let rows: Vec<Vec<(String, f64)>> = s
        .points
        .iter()
        .map(|p| crate::pipeline::evaluate::values(p, &s.nominal))
        .collect();
    let get = |r: &[(String, f64)], k: &str| r.iter().find(|(n, _)| n == k).map(|e| e.1);
    let metric = limit.metric.to_string();
    if rows.iter().all(|r| get(r, &metric).is_none()) {
        return Err(Error::field(
            "limit",
            format!("the sweep's rows have no `{metric}`"),
        ));
    }
    let col =
        |k: &str| -> Vec<f64> { rows.iter().map(|r| get(r, k).unwrap_or(f64::NAN)).collect() };
    let x: Vec<f64> = s
        .points
        .iter()
        .map(|p| {
            p.settings
                .iter()
                .find(|(k, _)| *k == v.path)
                .map_or(f64::NAN, |e| e.1)
        })
        .collect();
    let y = col(&metric);
    let se = col(&format!("{metric}_stderr"));
    let valid: Vec<f64> = y.iter().copied().filter(|v| v.is_finite()).collect();
    Ok(LimitReport {
        metric,
        limit: limit.value,
        variable: v.path.clone(),
        points_within: valid.iter().filter(|v| v.abs() <= limit.value).count(),
        points: valid.len(),
        crossings: crossings(&x, &y, &se, limit.value),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight line |y| = 0.02·x crosses 0.01 at x = 0.5; both points' errors move it by
    /// σ·Δx/Δy when they move together.
    #[test]
    fn crossing_by_interpolation_with_its_error() {
        let x = [0.0, 1.0, 2.0];
        let y = [0.0, -0.02, -0.04];
        let se = [1e-3, 1e-3, 1e-3];
        let c = crossings(&x, &y, &se, 0.01);
        assert_eq!(c.len(), 1);
        assert!((c[0].at - 0.5).abs() < 1e-12, "{:?}", c[0]);
        // Δx/Δy = 50: σ = 1e-3 · 50.
        assert!((c[0].stderr - 0.05).abs() < 1e-12, "{:?}", c[0]);
        assert_eq!(c[0].direction, "leaves");
        assert_eq!(c[0].between, [0.0, 1.0]);
        let [lo, hi] = c[0].ci95.unwrap();
        assert!((hi - lo - 2.0 * 1.959_964 * 0.05).abs() < 1e-12);
        // A valley: leaves, then enters; a NaN point is skipped.
        let c = crossings(
            &[0.0, 1.0, 2.0, 3.0],
            &[0.0, 0.03, f64::NAN, 0.0],
            &[0.0; 4],
            0.01,
        );
        assert_eq!(c.len(), 2);
        assert_eq!(c[1].direction, "enters");
        assert!((c[1].at - (1.0 + 2.0 * 2.0 / 3.0)).abs() < 1e-12);
        assert_eq!(c[1].stderr, 0.0);
    }

    #[test]
    fn limits_parse_and_reject() {
        let l = MetricLimit::parse("imbalance=0.01", false).unwrap();
        assert_eq!(
            (l.metric, l.value),
            (Quantity::Metric(BenchMetric::Imbalance), 0.01)
        );
        for bad in [
            "imbalance",
            "imbalance=x",
            "imbalance=-1",
            "imbalance=inf",
            "nonsense=1",
            "secondary_complementary_balancing_40_mssim=0.9",
        ] {
            let e = MetricLimit::parse(bad, false).unwrap_err();
            assert!(
                e.is_user_error() && e.to_string().contains("field `limit`"),
                "{e}"
            );
        }
        assert!(MetricLimit::parse("secondary_complementary_balancing_40_mssim=0.9", true).is_ok());
    }

    #[test]
    fn sentences_say_where_or_that_nothing_crosses() {
        let r = LimitReport {
            metric: "imbalance".into(),
            limit: 0.01,
            variable: "d.x".into(),
            points_within: 3,
            points: 3,
            crossings: Vec::new(),
        };
        assert!(r.sentence().contains("met at every point"));
        let c = crossings(&[0.0, 1.0], &[0.0, 0.02], &[1e-3, 1e-3], 0.01);
        let r = LimitReport {
            crossings: c,
            points_within: 1,
            points: 2,
            ..r
        };
        let s = r.sentence();
        assert!(s.contains("leaves at 0.500 ± 0.050"), "{s}");
        let lines = r.lines();
        assert_eq!(lines[0], "|imbalance| ≤ 0.01 along d.x:");
        assert!(lines[1].starts_with("  leaves at 0.500"), "{lines:?}");
    }
}
