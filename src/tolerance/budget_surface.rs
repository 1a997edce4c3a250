//! The response surface of a tolerance budget and the yield estimated on it.
//!
//! Each limited metric m is modelled as a function of the deviations x (absolute, one per
//! tolerance): m(x) ≈ m₀ + Σᵢ (pᵢxᵢ + qᵢxᵢ²) + Σ_{(i,j)} cᵢⱼxᵢxⱼ. The per-tolerance terms are
//! the parabola through the nominal bench and the two ends of the sensitivity table (paired
//! traces, so the differences carry little ray noise); the cross terms, and corrections of the
//! per-tolerance terms that compensators make, come from the Monte Carlo trials of the budget's
//! confirmations ([`Surface::refit`]). A tolerance scaled by s draws s times its deviation at
//! scale 1 for every distribution of the file (each is a location–scale family about the
//! middle of its range, and the range scales about 0), so the yield of a budget is estimated
//! on fixed draws at scale 1 ([`Samples`]), scaled per tolerance: common random numbers over
//! every candidate budget.

use crate::quantities::Quantity;
use crate::scene::tolerance::{
    IMBALANCE_ELECTRICAL, SensitivityRecord, ToleranceLimit, ToleranceSet, TrialRecord,
};

/// The name of the recorded value limit `l` judges ([`ToleranceLimit::value_in`]): the
/// electrical imbalance for a limit on the imbalance where the nominal bench records a finite
/// one, else the metric's own name.
fn recorded_name(l: &ToleranceLimit, nominal: &[(String, f64)]) -> String {
    if l.is_on_imbalance()
        && crate::scene::tolerance::value_of(nominal, IMBALANCE_ELECTRICAL).is_finite()
    {
        IMBALANCE_ELECTRICAL.to_string()
    } else {
        l.metric.to_string()
    }
}

/// One limited metric's surface.
#[derive(Debug, Clone, PartialEq)]
pub struct MetricSurface {
    pub metric: Quantity,
    /// The recorded value the surface models: for a limit on the imbalance the electrical
    /// imbalance ι′ where the records hold it (what `spibench tolerance` judges, so that the
    /// budget and its read-back check judge one quantity), else the metric itself.
    pub recorded: String,
    pub m0: f64,
    /// Per tolerance (file order): linear and quadratic coefficients in the deviation.
    pub lin: Vec<f64>,
    pub quad: Vec<f64>,
    /// Cross terms cᵢⱼ·xᵢxⱼ.
    pub cross: Vec<(usize, usize, f64)>,
    /// For the electrical imbalance of a file with a variable attenuator: the attenuator, set
    /// on each sample as on each traced trial. The surface then models ι′ before it
    /// ([`MetricSurface::judged`] applies it), and is refitted on the trials' values before it.
    pub attenuator: Option<crate::scene::tolerance::Attenuator>,
}

impl MetricSurface {
    fn term(&self, i: usize, x: f64) -> f64 {
        self.lin[i] * x + self.quad[i] * x * x
    }

    /// The value a limit judges at deviations `x`: the surface, with the attenuator set on it
    /// where there is one (`crate::pipeline::perturb::attenuator_transmissions`, in closed
    /// form as in every trial).
    pub fn judged(&self, x: &[f64]) -> f64 {
        let v = self.at(x);
        match &self.attenuator {
            None => v,
            Some(a) => {
                use crate::pipeline::perturb::{attenuated_imbalance, attenuator_transmissions};
                attenuated_imbalance(v, attenuator_transmissions(v, a))
            }
        }
    }

    /// The recorded value the surface is refitted on: with an attenuator, the one before it.
    fn refit_name(&self) -> String {
        if self.attenuator.is_some() {
            format!("{}_unattenuated", self.recorded)
        } else {
            self.recorded.clone()
        }
    }

    /// The surface at deviations `x`.
    pub fn at(&self, x: &[f64]) -> f64 {
        let mut v = self.m0;
        for (i, xi) in x.iter().enumerate() {
            v += self.term(i, *xi);
        }
        for &(i, j, c) in &self.cross {
            v += c * x[i] * x[j];
        }
        v
    }
}

/// The response surface: one [`MetricSurface`] per limit on a metric of the sensitivity table,
/// the limits it is judged by.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    pub metrics: Vec<MetricSurface>,
    /// The limits, each with the index of its metric's surface.
    pub limits: Vec<(usize, ToleranceLimit)>,
    /// The limits of the file no surface models (judged in the confirmations only).
    pub unmodelled: Vec<String>,
}

/// The parabola p·x + q·x² through (0, 0), (a, da), (b, db); a line through the one nonzero
/// end when the other end is 0; nothing for a zero range or a change that is not a number.
fn parabola(a: f64, b: f64, da: f64, db: f64) -> (f64, f64) {
    let (da, db) = (
        if da.is_finite() { da } else { 0.0 },
        if db.is_finite() { db } else { 0.0 },
    );
    match (a == 0.0, b == 0.0) {
        _ if a == b => (0.0, 0.0),
        (true, _) => (db / b, 0.0),
        (_, true) => (da / a, 0.0),
        _ => {
            let q = (db / b - da / a) / (b - a);
            (db / b - q * b, q)
        }
    }
}

/// A change of the sensitivity table within [`NOISE_Z`] of its paired standard errors of zero
/// is not told from ray noise, and is taken as none: summed over the many tolerances that barely
/// act on a metric, such noise would read as a spread the built benches do not have (at 20 000
/// rays the paper bench's lens and chart moves change the imbalance by about 10⁻³ ± 10⁻³, a
/// tenth of its limit), and the budget would tighten them for nothing. A change that is real
/// but this small still shows in the confirmations, and through their pass fractions in the
/// surface targets of the rounds (`budget_search::rounds`).
fn denoised(d: f64, se: f64) -> f64 {
    if se.is_finite() && d.abs() < NOISE_Z * se {
        0.0
    } else {
        d
    }
}

/// How many standard errors from zero a change of the sensitivity table must lie to count.
pub const NOISE_Z: f64 = 2.0;

impl Surface {
    /// The surface from the sensitivity table and the nominal bench's values, for the file's
    /// limits on metrics the table records.
    pub fn from_sensitivity(
        set: &ToleranceSet,
        sens: &[SensitivityRecord],
        nominal: &[(String, f64)],
    ) -> Surface {
        let mut metrics: Vec<MetricSurface> = Vec::new();
        let mut limits = Vec::new();
        let mut unmodelled = Vec::new();
        for l in &set.limits {
            let name = recorded_name(l, nominal);
            let diff = format!("{name}_diff");
            let recorded = sens
                .iter()
                .any(|r| r.at_min.iter().any(|(k, _)| *k == diff));
            let m0 = crate::scene::tolerance::value_of(nominal, &name);
            if !recorded || !m0.is_finite() {
                unmodelled.push(l.describe());
                continue;
            }
            let k = match metrics.iter().position(|m| m.metric == l.metric) {
                Some(k) => k,
                None => {
                    let mut lin = vec![0.0; set.tolerances.len()];
                    let mut quad = vec![0.0; set.tolerances.len()];
                    let se = format!("{diff}_stderr");
                    for r in sens {
                        if let Some(i) = set.tolerances.iter().position(|t| t.path == r.path) {
                            let end = |high: bool| denoised(r.at(high, &diff), r.at(high, &se));
                            (lin[i], quad[i]) = parabola(r.min, r.max, end(false), end(true));
                        }
                    }
                    metrics.push(MetricSurface {
                        metric: l.metric.clone(),
                        recorded: name.clone(),
                        m0,
                        lin,
                        quad,
                        cross: Vec::new(),
                        attenuator: set.attenuator.filter(|_| name == IMBALANCE_ELECTRICAL),
                    });
                    metrics.len() - 1
                }
            };
            limits.push((k, l.clone()));
        }
        Surface {
            metrics,
            limits,
            unmodelled,
        }
    }

    /// Whether deviations `x` meet every modelled limit.
    pub fn passes(&self, x: &[f64]) -> bool {
        let v: Vec<f64> = self.metrics.iter().map(|m| m.judged(x)).collect();
        self.limits.iter().all(|(k, l)| l.holds(v[*k]))
    }

    /// Refits each metric's surface on the trials' measured values (the confirmations'
    /// benches, with their compensators): a ridge least-squares correction of the residual
    /// m_trial − m_surface over an intercept, xᵢ and xᵢ² of every tolerance with a positive `weight`
    /// (one the surface sees acting: a fit over every tolerance would read the trials' noise
    /// as effects of those that do nothing), and xᵢxⱼ among the `top` of them (by `weight`, largest first), in units of each
    /// tolerance's half range. The ridge ([`REFIT_RIDGE`]) shrinks what the trials barely
    /// explore (a tolerance the budget holds tight), so the correction does not extrapolate
    /// noise to scales no trial drew. The correction is kept when it removes at least
    /// [`REFIT_GAIN`] of the residual sum of squares. Returns the number of cross terms added.
    pub fn refit(
        &mut self,
        set: &ToleranceSet,
        trials: &[TrialRecord],
        weight: &[f64],
        top: usize,
    ) -> usize {
        let mut order: Vec<usize> = (0..set.tolerances.len()).collect();
        order.sort_by(|a, b| weight[*b].total_cmp(&weight[*a]));
        order.retain(|i| weight[*i] > 0.0);
        let paired = &order[..top.min(order.len())];
        let half: Vec<f64> = set
            .tolerances
            .iter()
            .map(|t| 0.5 * (t.max - t.min).abs().max(t.max.abs().max(t.min.abs())))
            .collect();
        let mut added = 0;
        for m in &mut self.metrics {
            let name = m.refit_name();
            let data: Vec<(Vec<f64>, f64)> = trials
                .iter()
                .filter(|r| r.error.is_none())
                .filter_map(|r| {
                    let v = r.value(&name).filter(|v| v.is_finite())?;
                    let x: Vec<f64> = r.deviations.iter().map(|(_, d)| *d).collect();
                    Some((x.clone(), v - m.at(&x)))
                })
                .collect();
            let mut feats: Vec<Feature> = vec![Feature::One];
            for &i in &order {
                feats.extend([Feature::Lin(i), Feature::Quad(i)]);
            }
            for (a, &i) in paired.iter().enumerate() {
                for &j in &paired[a + 1..] {
                    feats.push(Feature::Cross(i, j));
                }
            }
            if data.len() < 2 * feats.len() {
                continue;
            }
            let rows: Vec<Vec<f64>> = data
                .iter()
                .map(|(x, _)| feats.iter().map(|f| f.value(x, &half)).collect())
                .collect();
            let y: Vec<f64> = data.iter().map(|(_, r)| *r).collect();
            let Some(beta) = ridge(&rows, &y, REFIT_RIDGE * data.len() as f64) else {
                continue;
            };
            let ss0: f64 = y.iter().map(|r| r * r).sum();
            let ss1: f64 = rows
                .iter()
                .zip(&y)
                .map(|(row, r)| (r - dot(row, &beta)).powi(2))
                .sum();
            if !(ss1.is_finite() && ss1 <= (1.0 - REFIT_GAIN) * ss0) {
                continue;
            }
            for (f, b) in feats.iter().zip(&beta) {
                match *f {
                    Feature::One => m.m0 += b,
                    Feature::Lin(i) => m.lin[i] += b / half[i],
                    Feature::Quad(i) => m.quad[i] += b / (half[i] * half[i]),
                    Feature::Cross(i, j) => {
                        m.cross.push((i, j, b / (half[i] * half[j])));
                        added += 1;
                    }
                }
            }
        }
        added
    }
}

/// The share of the residual sum of squares a refit must remove to be kept.
pub const REFIT_GAIN: f64 = 0.1;

/// The ridge of a refit per trial, λ/n: a feature whose mean square over the trials is below it
/// (a tolerance drawn uniformly within about ±0.05 of its file's half range) has its
/// correction shrunk by half or more.
pub const REFIT_RIDGE: f64 = 1e-3;

#[derive(Debug, Clone, Copy)]
enum Feature {
    One,
    Lin(usize),
    Quad(usize),
    Cross(usize, usize),
}

impl Feature {
    fn value(&self, x: &[f64], half: &[f64]) -> f64 {
        let u = |i: usize| if half[i] > 0.0 { x[i] / half[i] } else { 0.0 };
        match *self {
            Feature::One => 1.0,
            Feature::Lin(i) => u(i),
            Feature::Quad(i) => u(i) * u(i),
            Feature::Cross(i, j) => u(i) * u(j),
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Ridge least squares: β = (XᵀX + λI)⁻¹Xᵀy by Cholesky; `None` when it is not positive
/// definite or not finite.
fn ridge(rows: &[Vec<f64>], y: &[f64], lambda: f64) -> Option<Vec<f64>> {
    let p = rows.first()?.len();
    let mut a = vec![0.0; p * p];
    let mut b = vec![0.0; p];
    for (row, yi) in rows.iter().zip(y) {
        for i in 0..p {
            b[i] += row[i] * yi;
            for j in 0..=i {
                a[i * p + j] += row[i] * row[j];
            }
        }
    }
    for i in 0..p {
        a[i * p + i] += lambda;
    }
    // Cholesky A = LLᵀ in the lower triangle.
    for j in 0..p {
        let mut d = a[j * p + j];
        for k in 0..j {
            d -= a[j * p + k] * a[j * p + k];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        a[j * p + j] = d;
        for i in j + 1..p {
            let mut s = a[i * p + j];
            for k in 0..j {
                s -= a[i * p + k] * a[j * p + k];
            }
            a[i * p + j] = s / d;
        }
    }
    let mut z = b;
    for i in 0..p {
        for k in 0..i {
            z[i] -= a[i * p + k] * z[k];
        }
        z[i] /= a[i * p + i];
    }
    for i in (0..p).rev() {
        for k in i + 1..p {
            z[i] -= a[k * p + i] * z[k];
        }
        z[i] /= a[i * p + i];
    }
    z.iter().all(|v| v.is_finite()).then_some(z)
}

/// Fixed draws of the deviations at scale 1, one row per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Samples {
    pub rows: Vec<Vec<f64>>,
}

/// The trial index of the first surface sample: far above any trial a run traces, so the
/// surface's draws are not the confirmations'.
pub const SAMPLE_INDEX_BASE: u64 = 1 << 48;

impl Samples {
    /// `n` draws from the tolerance file's distributions (the trial draws of
    /// `pipeline::perturb::draw`, at indices from [`SAMPLE_INDEX_BASE`]).
    pub fn draw(set: &ToleranceSet, seed: u64, n: usize) -> Samples {
        Samples {
            rows: (0..n as u64)
                .map(|k| {
                    crate::pipeline::perturb::draw(set, seed, SAMPLE_INDEX_BASE + k)
                        .into_iter()
                        .map(|(_, d)| d)
                        .collect()
                })
                .collect(),
        }
    }

    /// The fraction of samples that pass on the surface with the deviations scaled by
    /// `scales`.
    pub fn yield_at(&self, surface: &Surface, scales: &[f64]) -> f64 {
        if self.rows.is_empty() {
            return f64::NAN;
        }
        let mut x = vec![0.0; scales.len()];
        let passed = self
            .rows
            .iter()
            .filter(|row| {
                for ((xi, u), s) in x.iter_mut().zip(row.iter()).zip(scales) {
                    *xi = u * s;
                }
                surface.passes(&x)
            })
            .count();
        passed as f64 / self.rows.len() as f64
    }

    /// A smooth version of [`Samples::yield_at`] for ranking moves where the count does not
    /// change: each limit's pass replaced by a logistic of its margin over `width` (per
    /// limit), multiplied over the limits.
    pub fn soft_yield_at(&self, surface: &Surface, scales: &[f64], width: &[f64]) -> f64 {
        let mut x = vec![0.0; scales.len()];
        let mut total = 0.0;
        for row in &self.rows {
            for ((xi, u), s) in x.iter_mut().zip(row.iter()).zip(scales) {
                *xi = u * s;
            }
            let v: Vec<f64> = surface.metrics.iter().map(|m| m.judged(&x)).collect();
            let mut p = 1.0;
            for ((k, l), w) in surface.limits.iter().zip(width) {
                let margin = margin(l, v[*k]);
                p *= 1.0 / (1.0 + (-margin / w).exp());
            }
            total += p;
        }
        total / self.rows.len().max(1) as f64
    }
}

/// How far inside a limit a value lies (negative outside; −∞ for NaN).
pub fn margin(l: &ToleranceLimit, v: f64) -> f64 {
    if v.is_nan() {
        return f64::NEG_INFINITY;
    }
    let mut m = f64::INFINITY;
    if let Some(a) = l.abs_max {
        m = m.min(a - v.abs());
    }
    if let Some(a) = l.min {
        m = m.min(v - a);
    }
    if let Some(a) = l.max {
        m = m.min(a - v);
    }
    m
}

/// The logistic width of each limit's soft pass: 2 % of its scale (the largest |bound|), or
/// 10⁻⁶ for a limit at 0.
pub fn soft_widths(surface: &Surface) -> Vec<f64> {
    surface
        .limits
        .iter()
        .map(|(_, l)| {
            let s = [l.abs_max, l.min, l.max]
                .into_iter()
                .flatten()
                .map(f64::abs)
                .fold(0.0, f64::max);
            if s > 0.0 { 0.02 * s } else { 1e-6 }
        })
        .collect()
}

/// The quantile of the standard normal distribution at `p` in (0, 1) (Acklam's rational
/// approximation, relative error below 1.2·10⁻⁹).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// The one-sided Wilson score lower bound of a binomial proportion at confidence `c`
/// (Wilson 1927): `passed` of `n`.
pub fn wilson_lower(passed: usize, n: usize, c: f64) -> f64 {
    if n == 0 {
        return 0.0;
    }
    let z = normal_quantile(c);
    let (n, p) = (n as f64, passed as f64 / n as f64);
    let z2 = z * z;
    let centre = p + z2 / (2.0 * n);
    let spread = z * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    ((centre - spread) / (1.0 + z2 / n)).max(0.0)
}

/// The smallest pass fraction of `n` trials whose Wilson lower bound at `c` reaches `y`, or
/// `None` when even n of n does not.
pub fn fraction_needed(y: f64, c: f64, n: usize) -> Option<f64> {
    (0..=n)
        .find(|k| wilson_lower(*k, n, c) >= y)
        .map(|k| k as f64 / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_quantiles_and_wilson_bounds() {
        assert!((normal_quantile(0.95) - 1.644_853_6).abs() < 1e-6);
        assert!((normal_quantile(0.5)).abs() < 1e-12);
        assert!((normal_quantile(0.001) + 3.090_232_3).abs() < 1e-6);
        // 290 of 300 at 95 %: p̂ = 0.9667, Wilson lower bound 0.9448 (Wilson 1927, by hand:
        // (p̂ + z²/2n − z√(p̂q̂/n + z²/4n²))/(1 + z²/n)).
        let lb = wilson_lower(290, 300, 0.95);
        assert!((lb - 0.944_8).abs() < 5e-4, "{lb}");
        assert!(wilson_lower(300, 300, 0.95) < 1.0);
        let f = fraction_needed(0.95, 0.95, 300).unwrap();
        assert!(wilson_lower((f * 300.0).round() as usize, 300, 0.95) >= 0.95);
        assert!(wilson_lower((f * 300.0).round() as usize - 1, 300, 0.95) < 0.95);
        assert_eq!(fraction_needed(0.999, 0.95, 10), None);
    }

    #[test]
    fn parabolas_pass_through_both_ends() {
        let (p, q) = parabola(-1.0, 2.0, 3.0, 5.0);
        assert!((q - p - 3.0).abs() < 1e-12);
        assert!((p * 2.0 + q * 4.0 - 5.0).abs() < 1e-12);
        assert_eq!(parabola(0.0, 2.0, 0.0, 4.0), (2.0, 0.0));
        assert_eq!(parabola(0.0, 0.0, 0.0, 0.0), (0.0, 0.0));
    }

    /// A ridge fit recovers a known cross term from noiseless data.
    #[test]
    fn ridge_recovers_coefficients() {
        let rows: Vec<Vec<f64>> = (0..50)
            .map(|k| {
                let (a, b) = ((k as f64 * 0.37).sin(), (k as f64 * 0.73).cos());
                vec![1.0, a, b, a * b]
            })
            .collect();
        let y: Vec<f64> = rows
            .iter()
            .map(|r| 0.5 + 2.0 * r[1] - r[2] + 3.0 * r[3])
            .collect();
        let beta = ridge(&rows, &y, 1e-12).unwrap();
        for (b, want) in beta.iter().zip([0.5, 2.0, -1.0, 3.0]) {
            assert!((b - want).abs() < 1e-6, "{beta:?}");
        }
    }
}
