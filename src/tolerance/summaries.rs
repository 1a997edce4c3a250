//! Summaries of a tolerance run that say what the distributions mean for a builder: the tail of
//! each metric that matters, the compensators' moves, histogram bins, and whether the RSS
//! estimate can be trusted (a linear, two-sided response) for each metric.

use serde::Serialize;

use crate::quantities::{BenchMetric, Quantity};
use crate::scene::tolerance::{Compensator, SensitivityRecord, ToleranceLimit, TrialRecord};

/// Which end of a metric's distribution hurts a bench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Tail {
    /// Low values hurt (a weak signal: k', k±, powers, CMRR, image scores).
    Lower,
    /// Large |values| hurt (imbalance, offsets, leaks).
    UpperAbs,
}

/// The tail that matters for `q`.
pub fn tail(q: &Quantity) -> Tail {
    match q {
        Quantity::Metric(
            BenchMetric::KPrime
            | BenchMetric::KPlus
            | BenchMetric::KMinus
            | BenchMetric::PowerPlusW
            | BenchMetric::PowerMinusW
            | BenchMetric::XTotalW,
        )
        | Quantity::Cmrr
        | Quantity::CmrrElectronics
        | Quantity::Score { .. } => Tail::Lower,
        Quantity::Metric(_) => Tail::UpperAbs,
    }
}

/// The tail that matters for the quantity named `metric` (the upper tail of |value| for a
/// name that is none).
pub fn tail_of(metric: &str) -> Tail {
    metric.parse().map_or(Tail::UpperAbs, |q| tail(&q))
}

/// Whether the quantity named `metric` is an off-arm leak. Recorded as the ratio
/// r = P_wrong/P_own of the two diodes' powers (crate::transport::metrics), it is unbounded: a
/// part that blinds the own arm sends r far above 1 (41 in a trial of the paper bench's
/// tolerances). The tails and figures therefore show the bounded fraction [`leak_fraction`].
pub fn is_fraction(metric: &str) -> bool {
    metric
        .parse::<Quantity>()
        .ok()
        .and_then(|q| q.metric())
        .is_some_and(BenchMetric::is_leak)
}

/// A leak ratio r = P_wrong/P_own as the bounded fraction P_wrong/(P_own + P_wrong) = r/(1 + r):
/// the share of the light of one world that reaches the wrong diode, 0 … 1 (≈ r for small
/// leaks; ½ where both diodes see the same power).
pub fn leak_fraction(r: f64) -> f64 {
    if r.is_infinite() && r > 0.0 {
        1.0
    } else {
        r / (1.0 + r)
    }
}

/// The value of `metric` as the summaries read it: a leak as its bounded fraction, any other
/// metric as recorded.
pub fn shown(metric: &str, v: f64) -> f64 {
    if is_fraction(metric) {
        leak_fraction(v)
    } else {
        v
    }
}

/// One metric's tail over the trials.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TailRow {
    pub metric: String,
    pub tail: Tail,
    /// The 90th and 97.7th percentiles of |value| (upper tail), or the 10th and 2.3rd of the
    /// value (lower tail): the values 10 % and 2.3 % of built benches are worse than. Leaks as
    /// their bounded fraction ([`leak_fraction`]).
    pub worst_10_percent: f64,
    pub worst_2_3_percent: f64,
    /// The worst trial.
    pub worst: f64,
    /// The fraction of trials beyond the file's limits on this metric (null without one).
    pub beyond_limits: Option<f64>,
}

/// The tail rows of `metrics` (each metric's finite values over the good trials).
pub fn tails(metrics: &[Quantity], ok: &[&TrialRecord], limits: &[ToleranceLimit]) -> Vec<TailRow> {
    let mut rows = Vec::new();
    for q in metrics {
        let tail = tail(q);
        let m = &q.to_string();
        let mut v: Vec<f64> = ok
            .iter()
            .filter_map(|r| r.value(m))
            .map(|v| shown(m, v))
            .filter(|v| v.is_finite())
            .map(|v| if tail == Tail::UpperAbs { v.abs() } else { v })
            .collect();
        if v.is_empty() {
            continue;
        }
        v.sort_by(f64::total_cmp);
        let (p10, p2, worst) = match tail {
            Tail::UpperAbs => (
                super::percentile(&v, 90.0),
                super::percentile(&v, 97.7),
                v[v.len() - 1],
            ),
            Tail::Lower => (
                super::percentile(&v, 10.0),
                super::percentile(&v, 2.3),
                v[0],
            ),
        };
        let mine: Vec<&ToleranceLimit> = limits.iter().filter(|l| &l.metric == q).collect();
        let beyond_limits = (!mine.is_empty()).then(|| {
            let bad = ok
                .iter()
                .filter(|r| !r.value(m).is_some_and(|x| mine.iter().all(|l| l.holds(x))))
                .count();
            bad as f64 / ok.len().max(1) as f64
        });
        rows.push(TailRow {
            metric: m.clone(),
            tail,
            worst_10_percent: p10,
            worst_2_3_percent: p2,
            worst,
            beyond_limits,
        });
    }
    rows
}

/// A compensator at its bound: within this fraction of its range of min or max. The compensator
/// search (crate::pipeline::optimise) ends within its last step of a bound it presses against,
/// 1/128 of the range in a trial traced here (−0.0196875 of ±0.02), so a tighter fraction
/// would miss most compensators that ran out of travel.
pub const AT_BOUND_FRACTION: f64 = 0.02;

/// One compensator's settled moves over the trials.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompensatorRow {
    pub path: String,
    /// Its allowed moves.
    pub min: f64,
    pub max: f64,
    pub trials: usize,
    pub mean: f64,
    pub std_dev: f64,
    /// The smallest and largest move.
    pub lowest: f64,
    pub highest: f64,
    /// Trials that ended within [`AT_BOUND_FRACTION`] of the range at min, at max.
    pub at_min: usize,
    pub at_max: usize,
    /// (at_min + at_max) / trials: how often the compensator ran out of range.
    pub at_bound_fraction: f64,
    /// Each trial that ended at a bound, with the travel it would need (trial order).
    pub short: Vec<ShortTravel>,
}

/// One trial whose compensator ran out of travel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShortTravel {
    pub trial: u64,
    /// The deviation it settled at, at a bound.
    pub settled: f64,
    /// The deviation a wider range settles at (NaN where that adjustment failed).
    pub needed: f64,
    /// The wider range was not enough either: `needed` is a lower bound.
    pub beyond: bool,
}

/// Whether a compensator's settled deviation `v` lies at a bound of its range.
pub fn at_bound(c: &Compensator, v: f64) -> bool {
    let tol = AT_BOUND_FRACTION * (c.max - c.min).abs();
    v <= c.min + tol || v >= c.max - tol
}

/// The compensators' moves over the good trials.
pub fn compensators(set: &[Compensator], ok: &[&TrialRecord]) -> Vec<CompensatorRow> {
    set.iter()
        .filter_map(|c| {
            let v: Vec<f64> = ok
                .iter()
                .filter_map(|r| r.compensators.iter().find(|(p, _)| *p == c.path))
                .map(|(_, v)| *v)
                .filter(|v| v.is_finite())
                .collect();
            if v.is_empty() {
                return None;
            }
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
            let tol = AT_BOUND_FRACTION * (c.max - c.min).abs();
            let at_min = v.iter().filter(|&&x| x <= c.min + tol).count();
            let at_max = v.iter().filter(|&&x| x >= c.max - tol).count();
            let short = ok
                .iter()
                .flat_map(|r| {
                    r.needed_travel
                        .iter()
                        .filter(|t| t.path == c.path)
                        .map(|t| ShortTravel {
                            trial: r.index,
                            settled: t.settled,
                            needed: t.needed,
                            beyond: t.beyond,
                        })
                })
                .collect();
            Some(CompensatorRow {
                path: c.path.clone(),
                min: c.min,
                max: c.max,
                trials: v.len(),
                mean,
                std_dev: if v.len() > 1 { var.sqrt() } else { 0.0 },
                lowest: v.iter().copied().fold(f64::INFINITY, f64::min),
                highest: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                at_min,
                at_max,
                at_bound_fraction: (at_min + at_max) as f64 / n,
                short,
            })
        })
        .collect()
}

/// How many failing trials one tolerance is the leading cause of.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailureCause {
    pub path: String,
    /// Failing trials (good trials beyond a limit) in which this tolerance's predicted share of
    /// the failing metric's change is the largest.
    pub failures: usize,
    /// A device specification (`fixed: true`): it cannot be tightened.
    pub fixed: bool,
}

/// The recorded name whose change the sensitivity table holds for a limit: the electrical
/// imbalance for a limit on the imbalance (the yield judges it so), else the limit's metric.
fn change_name(l: &ToleranceLimit) -> String {
    if l.is_on_imbalance() {
        crate::scene::tolerance::IMBALANCE_ELECTRICAL.to_string()
    } else {
        l.metric.to_string()
    }
}

/// Which tolerances cause the failures: in each good trial that fails a limit, every
/// tolerance's predicted change of the failing metric is its secant slope across the
/// sensitivity table's row times the trial's deviation ((m(max) − m(min))/(max − min) · δ, the
/// RSS's linear model), and the tolerance with the largest |change| is that failure's cause.
/// Tolerances causing at least one failure, most failures first (ties in file order). Limits on
/// a metric the sensitivity table does not hold (image scores) attribute nothing.
pub fn failure_causes(
    tolerances: &[crate::scene::tolerance::Tolerance],
    limits: &[ToleranceLimit],
    ok: &[&TrialRecord],
    sens: &[SensitivityRecord],
) -> Vec<FailureCause> {
    let mut counts = vec![0usize; tolerances.len()];
    for r in ok {
        for l in limits {
            if l.value_in(r).is_some_and(|v| l.holds(v)) {
                continue;
            }
            let d = format!("{}_diff", change_name(l));
            let change = |i: usize| -> f64 {
                let t = &tolerances[i];
                let Some(row) = sens.iter().find(|s| s.path == t.path) else {
                    return 0.0;
                };
                let width = row.max - row.min;
                let dev = r.deviations.get(i).map_or(0.0, |(_, v)| *v);
                let c = (row.at(true, &d) - row.at(false, &d)) / width * dev;
                if c.is_finite() { c.abs() } else { 0.0 }
            };
            let lead = (0..tolerances.len())
                .map(|i| (i, change(i)))
                .filter(|(_, c)| *c > 0.0)
                .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
            if let Some((i, _)) = lead {
                counts[i] += 1;
            }
            // One cause per failing trial: its first failing limit.
            break;
        }
    }
    let mut out: Vec<FailureCause> = tolerances
        .iter()
        .zip(counts)
        .filter(|(_, n)| *n > 0)
        .map(|(t, failures)| FailureCause {
            path: t.path.clone(),
            failures,
            fixed: t.is_fixed(),
        })
        .collect();
    out.sort_by_key(|c| std::cmp::Reverse(c.failures));
    out
}

/// Histogram bins for `n` sorted values: the Freedman–Diaconis width 2·IQR·n^(−1/3) (Freedman
/// and Diaconis 1981), but never more bins than the square-root rule's ⌈√n⌉, which a long tail
/// (one far trial stretches the range, not the IQR) would otherwise exceed, leaving most bins
/// empty; ⌈√n⌉ when the IQR is 0; at least 3 bins (fewer values: one bin each).
pub fn histogram_bins(sorted: &[f64]) -> usize {
    let n = sorted.len();
    let root = ((n as f64).sqrt().ceil() as usize).max(1);
    let floor = 3.min(n.max(1));
    if n < 2 {
        return 1;
    }
    let range = sorted[n - 1] - sorted[0];
    let iqr = super::percentile(sorted, 75.0) - super::percentile(sorted, 25.0);
    let fd = if iqr > 0.0 && range > 0.0 {
        (range / (2.0 * iqr * (n as f64).powf(-1.0 / 3.0))).ceil() as usize
    } else {
        root
    };
    fd.min(root).max(floor)
}

/// A tolerance's response is called curved when, fitted as m = s·t + c·t² through the nominal
/// bench and both ends, its quadratic term at the range's wider end exceeds this fraction of
/// the linear term (and c is beyond 2 standard errors).
pub const CURVATURE_LIMIT: f64 = 0.25;

/// A tolerance is checked for a metric when its change at either end is at least this
/// fraction of the largest change any tolerance makes.
pub const RELEVANT_FRACTION: f64 = 0.1;

/// Why the RSS's linear model may not hold for `metric`: one reason per relevant tolerance
/// whose response is one-sided (range on one side of nominal, or both ends moving the metric
/// the same way) or curved beyond [`CURVATURE_LIMIT`].
pub fn linearity_flags(metric: &Quantity, sens: &[SensitivityRecord]) -> Vec<String> {
    let d = format!("{metric}_diff");
    let se = format!("{metric}_diff_stderr");
    let largest = sens
        .iter()
        .flat_map(|r| [r.at(false, &d).abs(), r.at(true, &d).abs()])
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut flags = Vec::new();
    if largest <= 0.0 {
        return flags;
    }
    for r in sens {
        let (da, db) = (r.at(false, &d), r.at(true, &d));
        let (sa, sb) = (r.at(false, &se), r.at(true, &se));
        if !(da.is_finite() && db.is_finite())
            || da.abs().max(db.abs()) < RELEVANT_FRACTION * largest
        {
            continue;
        }
        let (a, b) = (r.min, r.max);
        if a >= 0.0 || b <= 0.0 {
            flags.push(format!(
                "{}: one-sided range {a} … {b}: the response is seen on one side of the nominal \
                 bench only, so its curvature is untested and the mean shift it causes is not \
                 in the RSS σ",
                r.path
            ));
            continue;
        }
        let significant = |v: f64, s: f64| !s.is_finite() || v.abs() > 2.0 * s;
        if da.signum() == db.signum() && significant(da, sa) && significant(db, sb) {
            flags.push(format!(
                "{}: both ends move {metric} the same way ({da:+.3e} at {a}, {db:+.3e} at {b}): \
                 a one-sided response the secant slope of the RSS misses",
                r.path
            ));
            continue;
        }
        let c = (db / b - da / a) / (b - a);
        let s = db / b - c * b;
        let c_se = ((sb / b).powi(2) + (sa / a).powi(2)).sqrt() / (b - a);
        let w = a.abs().max(b.abs());
        let ratio = (c * w).abs() / s.abs();
        if ratio > CURVATURE_LIMIT && (!c_se.is_finite() || c.abs() > 2.0 * c_se) {
            flags.push(format!(
                "{}: curved response (quadratic term {:.0} % of the linear at ±{w}; \
                 {da:+.3e} at {a}, {db:+.3e} at {b})",
                r.path,
                100.0 * ratio.min(1e4)
            ));
        }
    }
    flags
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sens(path: &str, min: f64, max: f64, at_min: f64, at_max: f64) -> SensitivityRecord {
        let row = |v: f64| {
            vec![
                ("imbalance_diff".to_string(), v),
                ("imbalance_diff_stderr".to_string(), 1e-5),
            ]
        };
        SensitivityRecord {
            path: path.into(),
            min,
            max,
            rays: [1000, 1000],
            at_min: row(at_min),
            at_max: row(at_max),
        }
    }

    /// A linear response is not flagged; an even one (both ends the same way), a curved one and
    /// a one-sided range are; a tolerance too small to matter is skipped.
    #[test]
    fn rss_flags_one_sided_and_curved_responses() {
        let linear = sens("a", -1.0, 1.0, -0.01, 0.01);
        let even = sens("b", -1.0, 1.0, 0.008, 0.009);
        let curved = sens("c", -1.0, 1.0, -0.002, 0.01);
        let one_sided = sens("d", 0.0, 0.2, 0.0, 0.009);
        let tiny = sens("e", -1.0, 1.0, 1e-4, 1e-4);
        let flags = linearity_flags(
            &BenchMetric::Imbalance.into(),
            &[linear, even, curved, one_sided, tiny],
        );
        let paths: Vec<&str> = flags.iter().map(|f| &f[..1]).collect();
        assert_eq!(paths, ["b", "c", "d"], "{flags:#?}");
        assert!(flags[0].contains("same way"));
        assert!(flags[1].contains("curved"));
        assert!(flags[2].contains("one-sided range"));
    }

    #[test]
    fn bins_follow_freedman_diaconis_up_to_the_square_root_rule() {
        // 10 000 uniform values: IQR = 0.5, width 2·0.5·10000^(−1/3) = 0.0464: 22 bins.
        let v: Vec<f64> = (0..10_000).map(|i| i as f64 / 9_999.0).collect();
        assert_eq!(histogram_bins(&v), 22);
        // 100 values with one far outlier: Freedman–Diaconis asks for hundreds of narrow bins;
        // the square-root rule's 10 win.
        let mut v: Vec<f64> = (0..99).map(|i| i as f64 / 98.0).collect();
        v.push(50.0);
        assert_eq!(histogram_bins(&v), 10);
        // 20 trials with a tail: never more than ⌈√20⌉ = 5 bins (not 200).
        let mut v: Vec<f64> = (0..19).map(|i| f64::from(i) * 1e-4).collect();
        v.push(1.0);
        assert_eq!(histogram_bins(&v), 5);
        assert_eq!(histogram_bins(&[1.0; 30]), 6);
        assert_eq!(histogram_bins(&[1.0, 2.0]), 2);
    }

    #[test]
    fn compensator_moves_count_their_bounds() {
        let rec = |v: f64| TrialRecord {
            index: 0,
            deviations: Vec::new(),
            compensators: vec![("d.x".into(), v)],
            values: Vec::new(),
            error: None,
            needed_travel: Vec::new(),
            rays: None,
        };
        let recs = [rec(-1.0), rec(0.2), rec(1.0), rec(0.9)];
        let ok: Vec<&TrialRecord> = recs.iter().collect();
        let c = Compensator {
            path: "d.x".into(),
            min: -1.0,
            max: 1.0,
            objective: crate::scene::tolerance::CompensatorObjective::Balance,
        };
        let rows = compensators(&[c], &ok);
        assert_eq!((rows[0].at_min, rows[0].at_max), (1, 1));
        assert_eq!(rows[0].at_bound_fraction, 0.5);
        assert_eq!((rows[0].lowest, rows[0].highest), (-1.0, 1.0));
    }

    /// A leak ratio of 41 (an arm blinded) is the fraction 41/42; small leaks stay as they are.
    #[test]
    fn leaks_are_bounded_fractions() {
        assert!((leak_fraction(41.0) - 41.0 / 42.0).abs() < 1e-15);
        assert!((leak_fraction(1e-4) - 1e-4).abs() < 1e-8);
        assert_eq!(leak_fraction(f64::INFINITY), 1.0);
        assert_eq!(shown("leak_plus", 1.0), 0.5);
        assert_eq!(shown("imbalance", 1.0), 1.0);
    }

    #[test]
    fn tails_read_the_end_that_matters() {
        assert_eq!(tail_of("k_prime"), Tail::Lower);
        assert_eq!(tail_of("scb_40_mssim"), Tail::Lower);
        assert_eq!(tail_of("imbalance"), Tail::UpperAbs);
        let rec = |v: f64| TrialRecord {
            index: 0,
            deviations: Vec::new(),
            compensators: Vec::new(),
            values: vec![("imbalance".into(), v), ("k_prime".into(), 1.0 + v)],
            error: None,
            needed_travel: Vec::new(),
            rays: None,
        };
        let recs: Vec<TrialRecord> = (0..101).map(|i| rec((i as f64 - 50.0) / 1000.0)).collect();
        let ok: Vec<&TrialRecord> = recs.iter().collect();
        let limit = ToleranceLimit {
            metric: BenchMetric::Imbalance.into(),
            min: None,
            max: None,
            abs_max: Some(0.04),
        };
        let rows = tails(
            &[BenchMetric::Imbalance.into(), BenchMetric::KPrime.into()],
            &ok,
            &[limit],
        );
        // |imbalance| runs 0 … 0.05, two values per step: worst 10 % beyond 0.045.
        assert!((rows[0].worst_10_percent - 0.045).abs() < 1e-12);
        assert_eq!(rows[0].worst, 0.05);
        // 20 of 101 beyond 0.04.
        assert!((rows[0].beyond_limits.unwrap() - 20.0 / 101.0).abs() < 1e-12);
        assert!((rows[1].worst_10_percent - 0.96).abs() < 1e-12);
        assert_eq!(rows[1].worst, 0.95);
        assert_eq!(rows[1].beyond_limits, None);
    }
}

/// The variable attenuator over the good trials: where it was set, how far, how often it ran
/// out of range (its darkest setting, the balance not reached), and the signal it cost.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AttenuatorRow {
    pub arm: crate::scene::tolerance::AttenuatorArm,
    pub min_transmission: f64,
    /// Good trials that record the attenuator.
    pub trials: usize,
    /// Trials in which it was set in front of the + diode, and of the − diode (T < 1).
    pub in_plus: usize,
    pub in_minus: usize,
    /// Trials in which it stopped at `min_transmission`: the arms could not be balanced.
    pub at_min: usize,
    /// The transmission set (T of the attenuated arm, 1 where neither was): mean and least.
    pub transmission_mean: f64,
    pub transmission_min: f64,
    /// Mean k′ over the trials before the attenuator was set and after.
    pub k_prime_mean_before: f64,
    pub k_prime_mean_after: f64,
}

/// The attenuator's row (None without one, or without a good trial that records it).
pub fn attenuator(
    a: Option<&crate::scene::tolerance::Attenuator>,
    ok: &[&TrialRecord],
) -> Option<AttenuatorRow> {
    let a = a?;
    let [tp, tm, _, kp0] = crate::scene::tolerance::ATTENUATOR_VALUES;
    let rows: Vec<(f64, f64, f64, f64)> = ok
        .iter()
        .filter_map(|r| {
            Some((
                r.value(tp)?,
                r.value(tm)?,
                r.value(kp0)?,
                r.value("k_prime")?,
            ))
        })
        .collect();
    if rows.is_empty() {
        return None;
    }
    let n = rows.len() as f64;
    let t: Vec<f64> = rows.iter().map(|r| r.0.min(r.1)).collect();
    let k_before = rows.iter().map(|r| r.2).sum::<f64>() / n;
    let k_after = rows.iter().map(|r| r.3).sum::<f64>() / n;
    Some(AttenuatorRow {
        arm: a.arm,
        min_transmission: a.min_transmission,
        trials: rows.len(),
        in_plus: rows.iter().filter(|r| r.0 < 1.0).count(),
        in_minus: rows.iter().filter(|r| r.1 < 1.0).count(),
        at_min: t.iter().filter(|&&x| x <= a.min_transmission).count(),
        transmission_mean: t.iter().sum::<f64>() / n,
        transmission_min: t.iter().copied().fold(f64::INFINITY, f64::min),
        k_prime_mean_before: k_before,
        k_prime_mean_after: k_after,
    })
}
