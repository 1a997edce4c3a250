//! Tolerance analysis of a bench: what imbalance, offset and image quality to expect when its
//! parts are made and placed within stated tolerances, and which tolerance dominates.
//!
//! - **Sensitivity** ([`sensitivity`]): each tolerance alone at its min and at its max, traced
//!   with the nominal bench's seed (common random numbers), so that each change from the
//!   nominal bench carries its paired standard error (crate::transport::metrics). Rows are
//!   sorted by their largest change of the imbalance.
//! - **Monte Carlo** ([`trial`]): trial i draws every tolerance from the stream keyed by
//!   (seed, i) of [`crate::rng`] (a salted seed, so the draws are unrelated to the rays' streams),
//!   applies the compensators with the alignment optimiser ([`crate::align`]), and traces the
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

use crate::align::{AlignOptions, Free, Objective, align};
use crate::error::{Error, Result};
use crate::rng;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{
    CompensatorObjective, Distribution, SensitivityRecord, ToleranceSet, TrialRecord, value_of,
};
use crate::sweep::{SweepOptions, SweepPoint, point};
use crate::transport::metrics::{METRICS, MetricRow};

/// The metrics of the sensitivity table, in its column order.
pub const SENSITIVITY_METRICS: [&str; 6] = [
    "imbalance",
    "k_prime",
    "b_minus_minus_b_plus",
    "leak_plus",
    "leak_minus",
    "cmrr_db",
];

/// A salt that separates the tolerance draws' streams from the rays' streams of the same seed.
const DRAW_SALT: u64 = 0x70_1e_7a_4c_e5_d7_a3_11;

/// How to analyse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToleranceOptions {
    pub rays: u64,
    pub seed: u64,
    /// Run the whole pipeline on every trial (image scores).
    pub quality: bool,
}

impl ToleranceOptions {
    fn sweep(&self, quality: bool) -> SweepOptions {
        SweepOptions {
            rays: self.rays,
            seed: self.seed,
            quality,
        }
    }
}

/// Whether `name` is a metric recorded for every trial (quality scores are checked when the
/// trials exist).
pub fn is_metric(name: &str) -> bool {
    METRICS.iter().any(|m| m.0 == name)
        || name == "cmrr_db"
        || name.ends_with("_mssim")
        || name.ends_with("_psnr_db")
        || name.ends_with("_finest_lp_per_mm")
}

/// The recorded numbers of a traced bench against the nominal one: each metric, its standard
/// error, its difference from the nominal bench and the paired standard error of that
/// difference; the CMRR; with `quality`, each scheme × ratio's MSSIM, PSNR and finest resolved
/// USAF element (lp/mm; NaN when none is resolved).
pub fn values(p: &SweepPoint, nominal: &SweepPoint) -> Vec<(String, f64)> {
    let mut v = Vec::new();
    for (i, (name, _, _)) in METRICS.iter().enumerate() {
        let r = MetricRow::new(&p.metrics.values[i], &nominal.metrics.values[i]);
        v.push((name.to_string(), r.value));
        v.push((format!("{name}_stderr"), r.stderr));
        v.push((format!("{name}_diff"), r.diff));
        v.push((format!("{name}_diff_stderr"), r.diff_stderr));
    }
    let cmrr = p.cmrr_db.unwrap_or(f64::NAN);
    v.push(("cmrr_db".into(), cmrr));
    let c0 = nominal.cmrr_db.unwrap_or(f64::NAN);
    v.push((
        "cmrr_db_diff".into(),
        if cmrr == c0 { 0.0 } else { cmrr - c0 },
    ));
    v.push(("cmrr_db_diff_stderr".into(), 0.0));
    v.push(("arrivals".into(), p.arrivals as f64));
    if let Some(q) = &p.quality {
        for r in q {
            let key = quality_key(r.scheme.key(), r.ratio);
            v.push((format!("{key}_mssim"), r.mssim));
            v.push((format!("{key}_psnr_db"), r.psnr_db));
            v.push((
                format!("{key}_finest_lp_per_mm"),
                r.finest_resolved.as_ref().map_or(f64::NAN, |e| e.lp_per_mm),
            ));
        }
    }
    v
}

/// `SCHEME_PERCENT`, e.g. `secondary_complementary_balancing_40`.
pub fn quality_key(scheme: &str, ratio: f64) -> String {
    format!("{scheme}_{}", (ratio * 100.0).round() as u32)
}

/// The nominal bench, traced (with `quality`, through the whole pipeline).
pub fn nominal(doc: &BenchDoc, o: &ToleranceOptions) -> Result<SweepPoint> {
    point(doc, Vec::new(), &o.sweep(o.quality))
}

/// The settings (absolute values of each variable) for deviations from the nominal bench. A
/// zero deviation sets nothing: a rigid-body move by 0 would still rewrite the part's axis as
/// a vector, which need not be bit-identical to the file's form.
fn settings(set: &ToleranceSet, deviations: &[(String, f64)]) -> Vec<(String, f64)> {
    set.tolerances
        .iter()
        .zip(deviations)
        .filter(|(_, (_, d))| *d != 0.0)
        .map(|(t, (_, d))| (t.path.clone(), t.nominal + d))
        .collect()
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
    nominal: &SweepPoint,
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
                    Entry::Vacant(e) => e.insert(point(doc, Vec::new(), &at.sweep(false))?),
                };
                let p = point(&d, s.clone(), &at.sweep(false))?;
                let end: Vec<(String, f64)> = values(&p, nom)
                    .into_iter()
                    .filter(|(k, _)| {
                        SENSITIVITY_METRICS
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

/// Trial i's deviations, drawn from the stream keyed by (seed, i).
pub fn draw(set: &ToleranceSet, seed: u64, i: u64) -> Vec<(String, f64)> {
    let mut r = rng::stream(rng::mix64(seed ^ DRAW_SALT), i);
    set.tolerances
        .iter()
        .map(|t| {
            let (lo, hi) = (t.min, t.max);
            let mid = 0.5 * (lo + hi);
            let half = 0.5 * (hi - lo);
            let v = match t.distribution {
                Distribution::Uniform => lo + rng::uniform(&mut r) * (hi - lo),
                Distribution::Normal { sigmas } => mid + half / sigmas * rng::normal(&mut r),
                Distribution::TruncatedNormal { sigmas } => {
                    // Rejection: with the range at ±kσ, k ≥ 0.1, fewer than 13 draws on average.
                    let mut v = mid;
                    for _ in 0..10_000 {
                        let z = rng::normal(&mut r);
                        if z.abs() <= sigmas {
                            v = mid + half / sigmas * z;
                            break;
                        }
                    }
                    v
                }
            };
            // A zero range draws exactly zero, so that zero tolerances give the nominal bench.
            (t.path.clone(), if half == 0.0 { lo } else { v })
        })
        .collect()
}

/// The alignment options of the compensators: a quarter of the trial's rays at most, starting
/// at a sixteenth.
fn compensator_options(o: &ToleranceOptions) -> AlignOptions {
    AlignOptions {
        start_rays: o.rays / 16,
        max_rays: (o.rays / 4).max(2 * crate::trace::RAYS_PER_BATCH),
        seed: o.seed,
        max_evaluations: 60,
    }
}

/// A trial's bench, its tolerances' deviations and its compensators' deviations.
pub type TrialBench = (BenchDoc, Vec<(String, f64)>, Vec<(String, f64)>);

/// The perturbed bench of trial i, with its compensators applied, and the compensators'
/// deviations.
pub fn trial_doc(
    doc: &BenchDoc,
    set: &ToleranceSet,
    o: &ToleranceOptions,
    i: u64,
) -> Result<TrialBench> {
    let deviations = draw(set, o.seed, i);
    let mut d = doc.with(&settings(set, &deviations))?;
    let mut comp = Vec::new();
    // Compensators that share an objective are adjusted together, in file order of their
    // objectives.
    for objective in [CompensatorObjective::Balance, CompensatorObjective::Power] {
        let group: Vec<_> = set
            .compensators
            .iter()
            .filter(|c| c.objective == objective)
            .collect();
        if group.is_empty() {
            continue;
        }
        let free: Vec<Free> = group
            .iter()
            .map(|c| {
                let v = d.get(&c.path)?;
                Ok(Free {
                    path: c.path.clone(),
                    lo: v + c.min,
                    hi: v + c.max,
                })
            })
            .collect::<Result<_>>()?;
        let base: Vec<f64> = group
            .iter()
            .map(|c| d.get(&c.path))
            .collect::<Result<_>>()?;
        let obj = match objective {
            CompensatorObjective::Balance => Objective::Balance { min_fraction: 0.9 },
            CompensatorObjective::Power => Objective::Power,
        };
        let a = align(&d, &free, &obj, &compensator_options(o), &|_| {})?;
        for ((c, b), v) in group.iter().zip(&base).zip(&a.best_values) {
            comp.push((c.path.clone(), v - b));
        }
        d = d.with(&a.settings())?;
    }
    Ok((d, deviations, comp))
}

/// Runs trial i: draws, compensates, traces, records. A perturbed bench that is not valid (e.g.
/// two parts overlapping) is recorded with its error and no values.
pub fn trial(
    doc: &BenchDoc,
    set: &ToleranceSet,
    nominal: &SweepPoint,
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
                },
                TrialTiming {
                    compensators_s: (t1 - t0).as_secs_f64(),
                    trace_s: 0.0,
                },
            ));
        }
        Err(e) => return Err(e),
    };
    let p = point(&d, Vec::new(), &o.sweep(o.quality))?;
    let rec = TrialRecord {
        index: i,
        deviations,
        compensators,
        values: values(&p, nominal),
        error: None,
    };
    Ok((
        rec,
        TrialTiming {
            compensators_s: (t1 - t0).as_secs_f64(),
            trace_s: t1.elapsed().as_secs_f64(),
        },
    ))
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
}

/// Everything computed from the records.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    pub percentiles: Vec<PercentileRow>,
    pub yields: Vec<YieldRow>,
    /// With `--quality` and a `quality` limit: per scheme, the fraction meeting it.
    pub quality_yields: Vec<(String, YieldRow)>,
    pub rss: Vec<RssRow>,
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
fn reported(records: &[TrialRecord]) -> Vec<String> {
    let mut names: Vec<String> = METRICS.iter().map(|m| m.0.to_string()).collect();
    names.push("cmrr_db".into());
    if let Some(r) = records.iter().find(|r| r.error.is_none()) {
        for (k, _) in &r.values {
            if k.ends_with("_mssim") || k.ends_with("_psnr_db") || k.ends_with("_finest_lp_per_mm")
            {
                names.push(k.clone());
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
    let column = |name: &str| -> Vec<f64> {
        ok.iter()
            .filter_map(|r| r.value(name))
            .filter(|v| !v.is_nan())
            .collect()
    };
    let mut percentiles = Vec::new();
    for name in reported(records) {
        let mut v = column(&name);
        if v.is_empty() {
            continue;
        }
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        v.sort_by(f64::total_cmp);
        let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
        a.sort_by(f64::total_cmp);
        percentiles.push(PercentileRow {
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
    let n = records.len();
    let mut yields: Vec<YieldRow> = set
        .limits
        .iter()
        .map(|l| {
            let passed = ok
                .iter()
                .filter(|r| r.value(&l.metric).is_some_and(|v| l.holds(v)))
                .count();
            yield_row(l.describe(), passed, n)
        })
        .collect();
    if set.limits.len() > 1 {
        let passed = ok
            .iter()
            .filter(|r| {
                set.limits
                    .iter()
                    .all(|l| r.value(&l.metric).is_some_and(|v| l.holds(v)))
            })
            .count();
        yields.push(yield_row("all limits".into(), passed, n));
    }
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
    let mut rss = Vec::new();
    if let Some(sens) = sensitivity {
        for m in SENSITIVITY_METRICS {
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
                let slope =
                    (r.at(true, &format!("{m}_diff")) - r.at(false, &format!("{m}_diff"))) / width;
                let c = (slope * t.distribution.std_dev(width)).powi(2);
                if c.is_finite() {
                    total += c;
                    if c > dominant.1 {
                        dominant = (r.path.clone(), c);
                    }
                }
            }
            let mc = column(m);
            let mean = mc.iter().sum::<f64>() / mc.len().max(1) as f64;
            let sd = (mc.iter().map(|x| (x - mean).powi(2)).sum::<f64>()
                / (mc.len() as f64 - 1.0).max(1.0))
            .sqrt();
            rss.push(RssRow {
                metric: m.to_string(),
                rss_std_dev: total.sqrt(),
                monte_carlo_std_dev: if mc.len() >= 2 { sd } else { f64::NAN },
                dominant: dominant.0,
                dominant_share: if total > 0.0 { dominant.1 / total } else { 0.0 },
            });
        }
    }
    Analysis {
        percentiles,
        yields,
        quality_yields,
        rss,
        failed_trials: records.len() - ok.len(),
    }
}

/// Checks that shards of one run fit together and returns their records in index order:
/// the same bench, tolerances, rays, seed, trial count and mode, and every trial exactly once.
pub fn merge(
    shards: &[crate::scene::tolerance::ShardFile],
) -> Result<crate::scene::tolerance::ShardFile> {
    let Some(first) = shards.first() else {
        return Err(Error::field("--merge", "give the shard folders to merge"));
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
                "--merge",
                format!(
                    "shard {}/{} was not made by the same run as shard {}/{} (bench, tolerance \
                     file, rays, seed, trials, --quality and the shard count must agree)",
                    s.shard.0, s.shard.1, first.shard.0, first.shard.1
                ),
            ));
        }
    }
    let mut records: Vec<TrialRecord> = shards.iter().flat_map(|s| s.records.clone()).collect();
    records.sort_by_key(|r| r.index);
    let complete = records.len() as u64 == first.trials
        && records.iter().enumerate().all(|(k, r)| r.index == k as u64);
    if !complete {
        return Err(Error::field(
            "--merge",
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

#[cfg(test)]
mod tests;
