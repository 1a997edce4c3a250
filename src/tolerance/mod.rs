//! Tolerance analysis of a bench: what imbalance, offset and image quality to expect when its
//! parts are made and placed within stated tolerances, and which tolerance dominates.
//!
//! - **Sensitivity** ([`sensitivity`]): each tolerance alone at its min and at its max, traced
//!   with the nominal bench's seed (common random numbers), so that each change from the
//!   nominal bench carries its paired standard error (crate::transport::metrics). Rows are
//!   sorted by their largest change of the imbalance.
//! - **Monte Carlo** ([`trial`]): trial i draws every tolerance from the stream keyed by
//!   (seed, i) of [`crate::rng`] (a salted seed, so the draws are unrelated to the rays' streams),
//!   applies the compensators with the optimiser ([`crate::pipeline::perturb`]), and traces the
//!   perturbed bench with the nominal bench's seed and ray count, so that the spread over
//!   trials is the tolerances' and not the ray noise's. Trials are independent of each other:
//!   any subset (a shard) gives the same records as the full run.
//! - **Statistics** ([`analyse`]): percentiles, yields against the file's limits, image-quality
//!   yields per scheme, and the root-sum-square (RSS) spread predicted from the sensitivity
//!   table against the Monte Carlo spread. The RSS assumes each metric linear in each tolerance
//!   and the tolerances independent: σ_m² ≈ Σ_t (∂m/∂t)²·σ_t², with ∂m/∂t the secant slope
//!   between the tolerance's min and max and σ_t its distribution's standard deviation. A Monte
//!   Carlo spread far from the RSS shows interactions or nonlinearity (e.g. a diode at the edge
//!   of its spot).

use std::collections::btree_map::Entry;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::pipeline::evaluate::{EvaluateOptions, Evaluation, evaluate};
use crate::quantities::{BenchMetric, ImageScore, Quantity};
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{
    ATTENUATOR_VALUES, IMBALANCE_ELECTRICAL, SensitivityRecord, ToleranceLimit, ToleranceSet,
    TrialRecord, value_of,
};

pub use crate::pipeline::evaluate::{quality_key, values};

pub mod budget;
pub mod budget_baseline;
pub mod budget_loosen;
pub mod budget_search;
pub mod budget_surface;
pub mod staged;
pub mod summaries;
pub mod work;
pub use crate::pipeline::perturb::{TrialBench, draw, trial_doc};

/// The metrics of the sensitivity table, in its column order.
pub const SENSITIVITY_METRICS: [Quantity; 6] = [
    Quantity::Metric(BenchMetric::Imbalance),
    Quantity::Metric(BenchMetric::KPrime),
    Quantity::Metric(BenchMetric::BMinusMinusBPlus),
    Quantity::Metric(BenchMetric::LeakPlus),
    Quantity::Metric(BenchMetric::LeakMinus),
    Quantity::Cmrr,
];

/// How to analyse: the rays and seed of every traced bench, and whether every trial runs the
/// whole pipeline (image scores).
pub type ToleranceOptions = EvaluateOptions;

/// Every value a tolerance run records for bench `p` (evaluated from `doc`) against the
/// nominal bench `nominal` (from `nominal_doc`): [`values`], then the electrical imbalance ι′
/// ([`IMBALANCE_ELECTRICAL`]), its standard error, its change from the nominal bench's and
/// that change's paired standard error: the optical imbalance through the diodes'
/// responsivity scales of each bench's electronics
/// ([`crate::transport::metrics::electrical_imbalance`]; the RF stage's one gain multiplies
/// both arms' currents alike, so only the responsivity mismatch moves ι′ away from ι). NaN
/// where the electronics are not valid.
pub fn recorded(
    (doc, p): (&BenchDoc, &Evaluation),
    (nominal_doc, nominal): (&BenchDoc, &Evaluation),
) -> Vec<(String, f64)> {
    let mut v = values(p, nominal);
    let e = electrical(doc, p);
    let e0 = electrical(nominal_doc, nominal);
    let d = e.as_ref().zip(e0.as_ref()).map(|(a, b)| {
        let mut d = a.diff(b);
        if a.value == b.value {
            // The same bench: no change (and no standard error of one).
            d.stderr = 0.0;
        }
        d
    });
    let name = IMBALANCE_ELECTRICAL;
    v.push((name.to_string(), e.as_ref().map_or(f64::NAN, |e| e.value)));
    v.push((
        format!("{name}_stderr"),
        e.as_ref().map_or(f64::NAN, |e| e.stderr()),
    ));
    v.push((format!("{name}_diff"), d.map_or(f64::NAN, |d| d.value)));
    v.push((
        format!("{name}_diff_stderr"),
        d.map_or(f64::NAN, |d| d.stderr),
    ));
    v
}

/// The electrical imbalance of bench `p` of `doc` (None for electronics that are not valid).
fn electrical(doc: &BenchDoc, p: &Evaluation) -> Option<crate::transport::metrics::TracedValue> {
    let d = crate::scene::run::detector_si(&doc.file.electronics.detector).ok()?;
    Some(crate::transport::metrics::electrical_imbalance(
        &p.metrics[BenchMetric::Imbalance],
        d.responsivity_scale,
    ))
}

/// The nominal bench, traced (with `quality`, through the whole pipeline).
pub fn nominal(doc: &BenchDoc, o: &ToleranceOptions) -> Result<Evaluation> {
    evaluate(doc, Vec::new(), o)
}

/// How far each row of the sensitivity table is resolved: each end of a row (the tolerance at
/// its min, at its max) is traced again, with the nominal bench, at more rays until the paired
/// standard error of its imbalance change is at most max(`stderr`, `relative`·|Δ imbalance|),
/// or the next step would pass `max_rays`. The ray counts are the run's rays times powers of 2
/// (so the nominal bench is traced at few counts); from the standard error at one count, which
/// falls as 1/√rays, the next count is the first that should meet the target.
///
/// A large change needs only a relative resolution: the paired standard error of a change that
/// moves light across an edge (a spot leaving a diode) falls only as 1/√rays, since common
/// random numbers pair nothing of the rays that switch between detected and lost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resolve {
    pub stderr: f64,
    pub relative: f64,
    pub max_rays: u64,
}

impl Resolve {
    /// The standard error a change `d` must reach.
    pub fn target(&self, d: f64) -> f64 {
        let rel = self.relative * d.abs();
        if rel.is_finite() {
            self.stderr.max(rel)
        } else {
            self.stderr
        }
    }

    /// Whether a change `d` ± `se` is resolved (a change without a standard error cannot be
    /// resolved further).
    pub fn holds(&self, d: f64, se: f64) -> bool {
        !se.is_finite() || se <= self.target(d)
    }

    /// The ray count after `rays` for a change `d` ± `se`: `rays`·2ᵏ, the smallest k ≥ 1 whose
    /// predicted standard error se·2^(−k/2) meets the target, or the largest within
    /// `max_rays`. `None` when no step is allowed.
    pub fn next_rays(&self, rays: u64, d: f64, se: f64) -> Option<u64> {
        let mut next = rays.checked_mul(2).filter(|n| *n <= self.max_rays)?;
        let need = rays as f64 * (se / self.target(d)).powi(2);
        while (next as f64) < need {
            match next.checked_mul(2).filter(|n| *n <= self.max_rays) {
                Some(n) => next = n,
                None => break,
            }
        }
        Some(next)
    }
}

/// The sensitivity table: each tolerance alone at its min and max (tolerances with a zero
/// range are traced too, and show no change), sorted by the largest |Δ imbalance|, largest
/// first. `nominal` is the nominal bench at `o.rays`; with `resolve`, ends that are not yet
/// resolved are traced again with more rays. `progress(done, total)` counts ends.
pub fn sensitivity(
    doc: &BenchDoc,
    set: &ToleranceSet,
    nominal: &Evaluation,
    o: &ToleranceOptions,
    resolve: Option<Resolve>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<SensitivityRecord>> {
    let total = 2 * set.tolerances.len();
    let mut rows = Vec::with_capacity(set.tolerances.len());
    // The nominal bench at every ray count used, traced once each.
    let mut nominals = std::collections::BTreeMap::from([(o.rays, nominal.clone())]);
    for (i, t) in set.tolerances.iter().enumerate() {
        let mut ends = Vec::with_capacity(2);
        let mut end_rays = [o.rays; 2];
        for (k, dev) in [t.min, t.max].into_iter().enumerate() {
            let s = vec![(t.path.clone(), t.nominal + dev)];
            let d = doc.with(&s)?;
            let mut rays = o.rays;
            let end = loop {
                let at = ToleranceOptions { rays, ..*o };
                let nom = match nominals.entry(rays) {
                    Entry::Occupied(e) => e.into_mut(),
                    Entry::Vacant(e) => {
                        e.insert(evaluate(doc, Vec::new(), &at.with_quality(false))?)
                    }
                };
                let p = evaluate(&d, s.clone(), &at.with_quality(false))?;
                let names: Vec<String> = SENSITIVITY_METRICS
                    .iter()
                    .map(|m| m.to_string())
                    .chain([IMBALANCE_ELECTRICAL.to_string()])
                    .collect();
                let end: Vec<(String, f64)> = recorded((&d, &p), (doc, nom))
                    .into_iter()
                    .filter(|(k, _)| {
                        names
                            .iter()
                            .any(|m| k == &format!("{m}_diff") || k == &format!("{m}_diff_stderr"))
                    })
                    .collect();
                let (dv, se) = (
                    value_of(&end, "imbalance_diff"),
                    value_of(&end, "imbalance_diff_stderr"),
                );
                match resolve {
                    Some(r) if !r.holds(dv, se) => match r.next_rays(rays, dv, se) {
                        Some(next) => rays = next,
                        None => break end,
                    },
                    _ => break end,
                }
            };
            end_rays[k] = rays;
            ends.push(end);
            progress(2 * i + k + 1, total);
        }
        let at_max = ends.pop().unwrap_or_default();
        let at_min = ends.pop().unwrap_or_default();
        rows.push(SensitivityRecord {
            path: t.path.clone(),
            min: t.min,
            max: t.max,
            rays: end_rays,
            at_min,
            at_max,
        });
    }
    let impact = |r: &SensitivityRecord| {
        let a = r.at(false, "imbalance_diff").abs();
        let b = r.at(true, "imbalance_diff").abs();
        let m = a.max(b);
        if m.is_nan() { 0.0 } else { m }
    };
    // Stable: equal impacts keep file order.
    rows.sort_by(|a, b| impact(b).total_cmp(&impact(a)));
    Ok(rows)
}

/// Runs trial i: draws, compensates, traces, records. A perturbed bench that is not valid (e.g.
/// two parts overlapping) is recorded with its error and no values.
pub fn trial(
    doc: &BenchDoc,
    set: &ToleranceSet,
    nominal: &Evaluation,
    o: &ToleranceOptions,
    i: u64,
) -> Result<(TrialRecord, TrialTiming)> {
    let t0 = std::time::Instant::now();
    let built = trial_doc(doc, set, o, i).and_then(|(d, dev, comp)| {
        d.build()?;
        Ok((d, dev, comp))
    });
    let t1 = std::time::Instant::now();
    let (d, deviations, compensators) = match built {
        Ok(x) => x,
        Err(e) if e.is_user_error() => {
            return Ok((
                TrialRecord {
                    index: i,
                    deviations: draw(set, o.seed, i),
                    compensators: Vec::new(),
                    values: Vec::new(),
                    error: Some(e.to_string()),
                    needed_travel: Vec::new(),
                    rays: None,
                },
                TrialTiming {
                    compensators_s: (t1 - t0).as_secs_f64(),
                    trace_s: 0.0,
                },
            ));
        }
        Err(e) => return Err(e),
    };
    let needed_travel = needed_travel(doc, set, o, i, &compensators);
    let t1 = std::time::Instant::now();
    let p = evaluate(&d, Vec::new(), o)?;
    let values = match &set.attenuator {
        None => recorded((&d, &p), (doc, nominal)),
        Some(a) => attenuated_values(&d, &p, (doc, nominal), a),
    };
    let rec = TrialRecord {
        index: i,
        deviations,
        compensators,
        values,
        error: None,
        needed_travel,
        rays: None,
    };
    Ok((
        rec,
        TrialTiming {
            compensators_s: (t1 - t0).as_secs_f64(),
            trace_s: t1.elapsed().as_secs_f64(),
        },
    ))
}

/// The recorded values of trial bench `p` (traced from `d`) with the attenuator `a` set on it
/// ([`crate::pipeline::perturb::attenuator_transmissions`] of its electrical imbalance; no
/// trace): [`recorded`] of the attenuated bench, then the transmissions set and the electrical
/// imbalance and k′ before they were ([`ATTENUATOR_VALUES`]), and that imbalance's standard error
/// ([`staged::IMBALANCE_UNATTENUATED_STDERR`]). Electronics that are not valid (no electrical
/// imbalance) leave the attenuator open.
fn attenuated_values(
    d: &BenchDoc,
    p: &Evaluation,
    nominal: (&BenchDoc, &Evaluation),
    a: &crate::scene::tolerance::Attenuator,
) -> Vec<(String, f64)> {
    use crate::pipeline::perturb::{attenuated, attenuator_transmissions};
    let e = p.electrical_imbalance();
    let before = e.as_ref().map_or(f64::NAN, |e| e.value);
    let t = attenuator_transmissions(before, a);
    let q = attenuated(d, p, t);
    let mut v = recorded((d, &q), nominal);
    let k_prime = p.metrics[BenchMetric::KPrime].value;
    for (name, x) in ATTENUATOR_VALUES.iter().zip([t[0], t[1], before, k_prime]) {
        v.push((name.to_string(), x));
    }
    v.push((
        staged::IMBALANCE_UNATTENUATED_STDERR.to_string(),
        e.map_or(f64::NAN, |e| e.stderr()),
    ));
    v
}

/// How much wider a compensator's range is made, about its centre, to find the travel a trial
/// that ran out of it would need.
pub const WIDER_TRAVEL: f64 = 4.0;

/// The compensators of trial `i` that settled at a bound of their range (`comp`: each one's
/// settled deviation), with the deviation the same adjustment reaches when every one of them
/// may move [`WIDER_TRAVEL`] times as far about its range's centre. Empty when none is at a
/// bound (no extra trace). A wider range that gives no valid bench, or whose adjustment fails,
/// gives NaN.
fn needed_travel(
    doc: &BenchDoc,
    set: &ToleranceSet,
    o: &ToleranceOptions,
    i: u64,
    comp: &[(String, f64)],
) -> Vec<crate::scene::tolerance::NeededTravel> {
    let settled = |path: &str| comp.iter().find(|(p, _)| p == path).map(|(_, v)| *v);
    let short: Vec<&crate::scene::tolerance::Compensator> = set
        .compensators
        .iter()
        .filter(|c| settled(&c.path).is_some_and(|v| summaries::at_bound(c, v)))
        .collect();
    if short.is_empty() {
        return Vec::new();
    }
    let mut wide = set.clone();
    for c in &mut wide.compensators {
        if short.iter().any(|s| s.path == c.path) {
            let (mid, half) = (0.5 * (c.min + c.max), 0.5 * (c.max - c.min));
            (c.min, c.max) = (mid - WIDER_TRAVEL * half, mid + WIDER_TRAVEL * half);
        }
    }
    let moved = trial_doc(doc, &wide, o, i)
        .and_then(|(d, _, comp)| d.build().map(|_| comp))
        .ok();
    short
        .iter()
        .map(|c| {
            let w = wide.compensators.iter().find(|w| w.path == c.path);
            let needed = moved
                .as_ref()
                .and_then(|m| m.iter().find(|(p, _)| *p == c.path))
                .map_or(f64::NAN, |(_, v)| *v);
            crate::scene::tolerance::NeededTravel {
                path: c.path.clone(),
                settled: settled(&c.path).unwrap_or(f64::NAN),
                needed,
                beyond: w.is_some_and(|w| needed.is_finite() && summaries::at_bound(w, needed)),
            }
        })
        .collect()
}

/// Where a trial's time went (s).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct TrialTiming {
    pub compensators_s: f64,
    pub trace_s: f64,
}

/// The trial indices of shard (I, N): i ≡ I (mod N).
pub fn shard_indices(trials: u64, shard: (u64, u64)) -> impl Iterator<Item = u64> {
    (shard.0..trials).step_by(shard.1.max(1) as usize)
}

/// Percentiles of one recorded metric over the trials.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PercentileRow {
    pub metric: String,
    pub trials: usize,
    pub mean: f64,
    pub std_dev: f64,
    pub p50: f64,
    pub p90: f64,
    pub p97_7: f64,
    /// The same percentiles of |value| (for signed metrics such as the imbalance).
    pub abs_p50: f64,
    pub abs_p90: f64,
    pub abs_p97_7: f64,
}

/// A yield: the fraction of trials that meet a limit (failed trials count as not meeting it).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct YieldRow {
    pub limit: String,
    pub passed: usize,
    pub trials: usize,
    pub fraction: f64,
    /// The binomial standard error of the fraction, √(p(1 − p)/n).
    pub stderr: f64,
    /// The Wilson score interval of the fraction at 95 % (Wilson 1927): unlike p ± 1.96·SE it
    /// keeps a width when every trial passes or none does.
    pub ci95: [f64; 2],
    /// For a limit on the imbalance (judged on the electrical imbalance, what the balanced
    /// detector's output sees): the same limit judged on the optical imbalance, beside it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optical: Option<Box<YieldRow>>,
}

/// The two-sided 95 % Wilson score interval of `passed` successes in `trials` (NaN for none):
/// (p + z²/2n ± z·√(p(1 − p)/n + z²/4n²)) / (1 + z²/n), z = 1.959964.
pub fn wilson95(passed: usize, trials: usize) -> [f64; 2] {
    if trials == 0 {
        return [f64::NAN; 2];
    }
    let (n, z) = (trials as f64, 1.959_964);
    let p = passed as f64 / n;
    let centre = p + z * z / (2.0 * n);
    let half = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
    let d = 1.0 + z * z / n;
    [
        ((centre - half) / d).max(0.0),
        ((centre + half) / d).min(1.0),
    ]
}

fn yield_row(limit: String, passed: usize, trials: usize) -> YieldRow {
    let p = if trials > 0 {
        passed as f64 / trials as f64
    } else {
        f64::NAN
    };
    YieldRow {
        limit,
        passed,
        trials,
        fraction: p,
        stderr: (p * (1.0 - p) / trials.max(1) as f64).sqrt(),
        ci95: wilson95(passed, trials),
        optical: None,
    }
}

/// The RSS spread of one metric predicted from the sensitivity table, against the Monte Carlo
/// spread.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RssRow {
    pub metric: String,
    pub rss_std_dev: f64,
    pub monte_carlo_std_dev: f64,
    /// The tolerance contributing most to the RSS, and its share of the RSS variance.
    pub dominant: String,
    pub dominant_share: f64,
    /// Why the RSS's linear, two-sided model may not hold for this metric (one reason per
    /// relevant tolerance: `summaries::linearity_flags`); empty when every relevant response
    /// is linear within the stated threshold.
    pub linearity_flags: Vec<String>,
}

/// Everything computed from the records.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    pub percentiles: Vec<PercentileRow>,
    pub yields: Vec<YieldRow>,
    /// With `--quality` and a `quality` limit: per scheme, the fraction meeting it.
    pub quality_yields: Vec<(String, YieldRow)>,
    pub rss: Vec<RssRow>,
    /// The tail that matters of each reported metric (the lower tail for k', the upper tail
    /// of |imbalance|, …).
    pub tails: Vec<summaries::TailRow>,
    /// Each compensator's settled moves: mean, SD, extremes, how often at a bound.
    pub compensators: Vec<summaries::CompensatorRow>,
    /// The variable attenuator's settings and the signal they cost (None without one).
    pub attenuator: Option<summaries::AttenuatorRow>,
    /// The tolerances that cause the failing trials, most first (`summaries::failure_causes`;
    /// empty without the sensitivity table).
    pub failure_causes: Vec<summaries::FailureCause>,
    /// The failing good trials (beyond some limit, judged as the yields are).
    pub failing_trials: usize,
    pub failed_trials: usize,
}

/// The p-th percentile (0–100) of sorted values, linearly interpolated (Hyndman and Fan 1996,
/// definition 7, the default of R and NumPy).
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = (sorted.len() - 1) as f64 * p / 100.0;
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// The metrics percentiles are reported for (and the quality scores present in the records).
fn reported(records: &[TrialRecord]) -> Vec<Quantity> {
    let mut names: Vec<Quantity> = BenchMetric::ALL.map(Quantity::Metric).to_vec();
    names.push(Quantity::Cmrr);
    if let Some(r) = records.iter().find(|r| r.error.is_none()) {
        for (k, _) in &r.values {
            if let Some((key, score)) = ImageScore::split(k) {
                names.push(Quantity::Score {
                    key: key.to_string(),
                    score,
                });
            }
        }
    }
    names
}

/// Percentiles, yields and the RSS comparison from the trial records (in index order) and the
/// sensitivity table.
pub fn analyse(
    set: &ToleranceSet,
    records: &[TrialRecord],
    sensitivity: Option<&[SensitivityRecord]>,
) -> Analysis {
    let ok: Vec<&TrialRecord> = records.iter().filter(|r| r.error.is_none()).collect();
    let names = reported(records);
    let tails = summaries::tails(&names, &ok, &set.limits);
    let n = records.len();
    Analysis {
        percentiles: percentile_rows(names, &ok),
        yields: limit_yields(&set.limits, &ok, n),
        quality_yields: quality_yields(set, &ok, n),
        rss: sensitivity.map_or_else(Vec::new, |sens| rss_rows(set, &ok, sens)),
        tails,
        compensators: summaries::compensators(&set.compensators, &ok),
        attenuator: summaries::attenuator(set.attenuator.as_ref(), &ok),
        failure_causes: sensitivity.map_or_else(Vec::new, |sens| {
            summaries::failure_causes(&set.tolerances, &set.limits, &ok, sens)
        }),
        failing_trials: ok
            .iter()
            .filter(|r| !set.limits.iter().all(|l| judged(r, l)))
            .count(),
        failed_trials: records.len() - ok.len(),
    }
}

/// The values of `name` over the good trials, in trial order, NaNs left out.
fn column(ok: &[&TrialRecord], name: &str) -> Vec<f64> {
    ok.iter()
        .filter_map(|r| r.value(name))
        .filter(|v| !v.is_nan())
        .collect()
}

/// One percentile row per reported metric that some good trial recorded.
fn percentile_rows(names: Vec<Quantity>, ok: &[&TrialRecord]) -> Vec<PercentileRow> {
    let mut rows = Vec::new();
    for q in names {
        let name = q.to_string();
        let mut v = column(ok, &name);
        if v.is_empty() {
            continue;
        }
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        v.sort_by(f64::total_cmp);
        let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
        a.sort_by(f64::total_cmp);
        rows.push(PercentileRow {
            metric: name,
            trials: v.len(),
            mean,
            std_dev: var.sqrt(),
            p50: percentile(&v, 50.0),
            p90: percentile(&v, 90.0),
            p97_7: percentile(&v, 97.7),
            abs_p50: percentile(&a, 50.0),
            abs_p90: percentile(&a, 90.0),
            abs_p97_7: percentile(&a, 97.7),
        });
    }
    rows
}

/// Whether trial `r` meets limit `l` as the yields judge it: a limit on the imbalance on the
/// electrical imbalance (ToleranceLimit::value_in).
fn judged(r: &TrialRecord, l: &ToleranceLimit) -> bool {
    l.value_in(r).is_some_and(|v| l.holds(v))
}

/// Whether trial `r` meets limit `l` on the metric it names: for a limit on the imbalance, the
/// optical imbalance reported beside the judged (electrical) one.
fn optical(r: &TrialRecord, l: &ToleranceLimit) -> bool {
    r.value(&l.metric.to_string()).is_some_and(|v| l.holds(v))
}

/// The yield of each limit over the `n` trials, then of all of them together when there are
/// several; a row on the imbalance carries the optical imbalance's yield beside it.
fn limit_yields(limits: &[ToleranceLimit], ok: &[&TrialRecord], n: usize) -> Vec<YieldRow> {
    let row = |label: String,
               holds: &dyn Fn(&TrialRecord) -> bool,
               opt: &dyn Fn(&TrialRecord) -> bool,
               on_imbalance: bool| {
        let mut y = yield_row(label.clone(), ok.iter().filter(|r| holds(r)).count(), n);
        if on_imbalance {
            let o = ok.iter().filter(|r| opt(r)).count();
            y.optical = Some(Box::new(yield_row(format!("{label}, optical"), o, n)));
        }
        y
    };
    let mut yields: Vec<YieldRow> = limits
        .iter()
        .map(|l| {
            row(
                l.describe(),
                &|r| judged(r, l),
                &|r| optical(r, l),
                l.is_on_imbalance(),
            )
        })
        .collect();
    if limits.len() > 1 {
        yields.push(row(
            "all limits".into(),
            &|r| limits.iter().all(|l| judged(r, l)),
            &|r| limits.iter().all(|l| optical(r, l)),
            limits.iter().any(|l| l.is_on_imbalance()),
        ));
    }
    yields
}

/// With a `quality` limit: per scheme in the first good trial's records, the fraction of the
/// `n` trials whose MSSIM at the limit's ratio meets it.
fn quality_yields(set: &ToleranceSet, ok: &[&TrialRecord], n: usize) -> Vec<(String, YieldRow)> {
    let mut quality_yields = Vec::new();
    if let (Some(q), Some(first)) = (set.quality, ok.first()) {
        let suffix = format!("_{}_mssim", q.ratio_percent);
        for (k, _) in &first.values {
            if let Some(scheme) = k.strip_suffix(&suffix) {
                let passed = ok
                    .iter()
                    .filter(|r| r.value(k).is_some_and(|v| v >= q.min_mssim))
                    .count();
                quality_yields.push((
                    scheme.to_string(),
                    yield_row(
                        format!("MSSIM ≥ {} at {} %", q.min_mssim, q.ratio_percent),
                        passed,
                        n,
                    ),
                ));
            }
        }
    }
    quality_yields
}

/// The RSS spread of each sensitivity metric predicted from the table against the Monte Carlo
/// spread over the good trials (the module's **Statistics**).
fn rss_rows(set: &ToleranceSet, ok: &[&TrialRecord], sens: &[SensitivityRecord]) -> Vec<RssRow> {
    SENSITIVITY_METRICS
        .iter()
        .map(|m| {
            let (total, dominant) = rss_sum(set, m, sens);
            let mc = column(ok, &m.to_string());
            let mean = mc.iter().sum::<f64>() / mc.len().max(1) as f64;
            let sd = (mc.iter().map(|x| (x - mean).powi(2)).sum::<f64>()
                / (mc.len() as f64 - 1.0).max(1.0))
            .sqrt();
            RssRow {
                metric: m.to_string(),
                rss_std_dev: total.sqrt(),
                monte_carlo_std_dev: if mc.len() >= 2 { sd } else { f64::NAN },
                dominant: dominant.0,
                dominant_share: if total > 0.0 { dominant.1 / total } else { 0.0 },
                linearity_flags: summaries::linearity_flags(m, sens),
            }
        })
        .collect()
}

/// Σ_t (∂m/∂t)²·σ_t² over the tolerances of the sensitivity table (secant slopes between each
/// tolerance's min and max; non-finite terms left out), with the tolerance whose term is the
/// largest and that term.
fn rss_sum(set: &ToleranceSet, m: &Quantity, sens: &[SensitivityRecord]) -> (f64, (String, f64)) {
    let mut total = 0.0;
    let mut dominant = (String::new(), 0.0);
    for r in sens {
        let Some(t) = set.tolerances.iter().find(|t| t.path == r.path) else {
            continue;
        };
        let width = r.max - r.min;
        if width <= 0.0 {
            continue;
        }
        let slope = (r.at(true, &format!("{m}_diff")) - r.at(false, &format!("{m}_diff"))) / width;
        let c = (slope * t.distribution.std_dev(width)).powi(2);
        if c.is_finite() {
            total += c;
            if c > dominant.1 {
                dominant = (r.path.clone(), c);
            }
        }
    }
    (total, dominant)
}

/// Checks that shards of one run fit together and returns their records in index order:
/// the same bench, tolerances, rays, seed, trial count and mode, every shard I/N of the run
/// exactly once (shard 0 with the sensitivity table, the others without), each holding only
/// its own trials, and every trial exactly once.
pub fn merge(
    shards: &[crate::scene::tolerance::ShardFile],
) -> Result<crate::scene::tolerance::ShardFile> {
    let Some(first) = shards.first() else {
        return Err(Error::field("merge", "give the shard folders to merge"));
    };
    for s in shards {
        if s.bench_ron != first.bench_ron
            || s.tolerances_text != first.tolerances_text
            || (s.rays, s.seed, s.trials, s.quality)
                != (first.rays, first.seed, first.trials, first.quality)
            || s.nominal.len() != first.nominal.len()
            || s.shard.1 != first.shard.1
        {
            return Err(Error::field(
                "merge",
                format!(
                    "shard {}/{} was not made by the same run as shard {}/{} (bench, tolerance \
                     file, rays, seed, trials, `quality` and the shard count must agree)",
                    s.shard.0, s.shard.1, first.shard.0, first.shard.1
                ),
            ));
        }
    }
    check_shard_set(shards)?;
    let mut records: Vec<TrialRecord> = shards.iter().flat_map(|s| s.records.clone()).collect();
    records.sort_by_key(|r| r.index);
    let complete = records.len() as u64 == first.trials
        && records.iter().enumerate().all(|(k, r)| r.index == k as u64);
    if !complete {
        return Err(Error::field(
            "merge",
            format!(
                "the shards hold {} trial records, not each of the {} trials exactly once: \
                 merge every shard of the run, once",
                records.len(),
                first.trials
            ),
        ));
    }
    let sensitivity = shards.iter().find_map(|s| s.sensitivity.clone());
    let mut merged = first.clone();
    merged.shard = (0, 1);
    merged.records = records;
    merged.sensitivity = sensitivity;
    merged.nominal = shards
        .iter()
        .find(|s| s.shard.0 == 0)
        .map_or_else(|| first.nominal.clone(), |s| s.nominal.clone());
    Ok(merged)
}

/// Every shard I/N of the run exactly once; shard 0 (which runs the sensitivity table, so a
/// run of `--trials 0` still has a shard to merge) with its table, the others without; each
/// shard's records its own trials i ≡ I (mod N), i < trials.
fn check_shard_set(shards: &[crate::scene::tolerance::ShardFile]) -> Result<()> {
    let n = shards[0].shard.1;
    let mut seen = std::collections::BTreeSet::new();
    for s in shards {
        let (i, _) = s.shard;
        if n == 0 || i >= n || !seen.insert(i) {
            return Err(Error::field(
                "merge",
                format!(
                    "shard {i}/{n} is given twice or is not a shard of the run: give every \
                     shard of the run exactly once"
                ),
            ));
        }
        if (i == 0) != s.sensitivity.is_some() {
            return Err(Error::field(
                "merge",
                format!(
                    "shard {i}/{n} {} the sensitivity table, which shard 0 and only shard 0 \
                     holds: was its trials.ron edited?",
                    if i == 0 { "lacks" } else { "holds" }
                ),
            ));
        }
        if let Some(r) = s
            .records
            .iter()
            .find(|r| r.index >= s.trials || r.index % n != i)
        {
            return Err(Error::field(
                "merge",
                format!(
                    "shard {i}/{n} holds trial {}, which is not one of its trials (i ≡ {i} \
                     mod {n}, i < {})",
                    r.index, s.trials
                ),
            ));
        }
    }
    if (seen.len() as u64) < n {
        let missing = (0..n).find(|i| !seen.contains(i)).unwrap_or(0);
        return Err(Error::field(
            "merge",
            format!(
                "shard {missing}/{n} of the run is missing{}: give every shard of the run \
                 exactly once",
                if missing == 0 {
                    " (it holds the sensitivity table)"
                } else {
                    ""
                }
            ),
        ));
    }
    Ok(())
}

/// True for the name of a value a trial records ([`values`]): a metric, its standard error,
/// its difference from the nominal bench and that difference's standard error; the CMRR; the
/// arrivals; and with `--quality`, `SCHEME_PERCENT_mssim`, `_psnr_db`, `_finest_lp_per_mm`.
pub fn is_value_name(name: &str) -> bool {
    let base = ["_diff_stderr", "_stderr", "_diff"]
        .iter()
        .find_map(|s| name.strip_suffix(s))
        .unwrap_or(name);
    if base.parse::<Quantity>().is_ok_and(|q| q.is_traced())
        || name == "arrivals"
        || base == IMBALANCE_ELECTRICAL
        || ATTENUATOR_VALUES.contains(&name)
        || name == staged::IMBALANCE_UNATTENUATED_STDERR
    {
        return true;
    }
    ImageScore::split(name)
        .and_then(|(key, _)| key.rsplit_once('_'))
        .is_some_and(|(scheme, pct)| {
            !pct.is_empty()
                && pct.len() <= 3
                && pct.bytes().all(|b| b.is_ascii_digit())
                && scheme.parse::<crate::acquisition::Scheme>().is_ok()
        })
}

/// Checks the names a shard record read back from `file` holds (it is untrusted: see
/// crate::report::untrusted): the deviations of each trial are the tolerance file's, in its
/// order; its compensators the file's; every recorded value, nominal value and sensitivity
/// entry a name [`values`] writes; every sensitivity row a tolerance of the file. These names
/// become columns, figure file names and report text.
pub fn check_shard_names(
    s: &crate::scene::tolerance::ShardFile,
    set: &ToleranceSet,
    file: &std::path::Path,
) -> Result<()> {
    let bad = |field: String, msg: String| Error::input(msg).in_file(file).at_field(field);
    let values = |v: &[(String, f64)], field: String| -> Result<()> {
        match v.iter().position(|(k, _)| !is_value_name(k)) {
            Some(k) => Err(bad(
                format!("{field}[{k}]"),
                format!("{:?} is not a value spibench records", v[k].0),
            )),
            None => Ok(()),
        }
    };
    values(&s.nominal, "nominal".into())?;
    for (n, r) in s.records.iter().enumerate() {
        let at = |f: &str| format!("records[{n}].{f}");
        let names: Vec<&str> = r.deviations.iter().map(|(p, _)| p.as_str()).collect();
        let want: Vec<&str> = set.tolerances.iter().map(|t| t.path.as_str()).collect();
        if names != want {
            return Err(bad(
                at("deviations"),
                format!(
                    "trial {} deviates {names:?}, not the tolerance file's {want:?}",
                    r.index
                ),
            ));
        }
        if let Some((p, _)) = r
            .compensators
            .iter()
            .find(|(p, _)| !set.compensators.iter().any(|c| &c.path == p))
        {
            return Err(bad(
                at("compensators"),
                format!("{p:?} is not a compensator of the tolerance file"),
            ));
        }
        values(&r.values, at("values"))?;
    }
    for (n, row) in s.sensitivity.iter().flatten().enumerate() {
        let at = |f: &str| format!("sensitivity[{n}].{f}");
        if !set.tolerances.iter().any(|t| t.path == row.path) {
            return Err(bad(
                at("path"),
                format!("{:?} is not a tolerance of the tolerance file", row.path),
            ));
        }
        values(&row.at_min, at("at_min"))?;
        values(&row.at_max, at("at_max"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
