//! Staged trials for a budget's confirmations: a confirmation only asks whether each trial meets
//! the file's limits, and most trials are far from every limit compared with the Monte Carlo
//! error of a short trace. So each trial is first traced at [`FIRST_STAGE_DIVISOR`] times fewer
//! rays; where every limit's verdict stands at [`DECISION_Z`] of that trace's standard errors
//! on either side, it is kept, and only the rest are traced again at the run's rays (the same
//! trace as an unstaged confirmation's, bit for bit: a trial is a function of the seed, its
//! index and its budget). This is sequential sampling in two stages (Wald 1947): the verdict of
//! a kept trial differs from the full trace's only where the full trace lands more than four of
//! the short trace's standard errors from it (one-sided normal tail 3·10⁻⁵, an error of that
//! size per trial on a yield).
//!
//! A verdict on a limit stands when the whole interval value ± z·se lies on one side of it: in
//! the pass set (an interval of the value: min, max, |·| ≤ abs_max together), or beyond one of
//! its ends. With a variable attenuator the judged electrical imbalance is the residual after
//! it was set, a non-decreasing function of the imbalance before it
//! ([`crate::pipeline::perturb::attenuated_imbalance`]), so the interval is taken on the
//! imbalance before (its standard error is recorded for that, [`IMBALANCE_UNATTENUATED_STDERR`])
//! and mapped through the attenuator: the pass set stays an interval and the same rule holds.
//!
//! Staging applies only where a verdict rests on traced values with standard errors: no
//! geometric compensator (its search would re-trace at the first stage's rays and could settle
//! elsewhere), no `--quality` (image scores carry none), and with an attenuator no limit on a
//! metric other than the imbalance (the attenuator's setting moves those too).

use crate::error::Result;
use crate::pipeline::evaluate::Evaluation;
use crate::scene::doc::BenchDoc;
use crate::scene::tolerance::{IMBALANCE_ELECTRICAL, ToleranceLimit, ToleranceSet, TrialRecord};

use super::ToleranceOptions;

/// The first stage traces the run's rays divided by this.
pub const FIRST_STAGE_DIVISOR: u64 = 8;
/// A first-stage verdict stands when the limit is at least this many of its standard errors
/// away.
pub const DECISION_Z: f64 = 4.0;
/// The fewest batches a first stage traces: its standard errors come from batch means, whose
/// own relative error is about 1/√(2·batches) (16 batches: 18 %, so z = 4 is at worst 3.4).
pub const MIN_FIRST_STAGE_BATCHES: u64 = 16;

/// The standard error of the electrical imbalance before the attenuator was set, recorded by a
/// trial with an attenuator beside [`crate::scene::tolerance::ATTENUATOR_VALUES`].
pub const IMBALANCE_UNATTENUATED_STDERR: &str = "imbalance_electrical_unattenuated_stderr";

/// The first stage of a run: its rays and the nominal bench traced at them (the trials' changes
/// are taken against it, with common random numbers).
pub struct FirstStage {
    pub rays: u64,
    pub nominal: Evaluation,
}

/// The first stage's rays for a run at `rays`: `rays` / [`FIRST_STAGE_DIVISOR`] in whole
/// batches, `None` when that is under [`MIN_FIRST_STAGE_BATCHES`] batches.
pub fn first_stage_rays(rays: u64) -> Option<u64> {
    let batch = crate::trace::RAYS_PER_BATCH;
    let r = rays / FIRST_STAGE_DIVISOR / batch * batch;
    (r >= MIN_FIRST_STAGE_BATCHES * batch).then_some(r)
}

/// Whether the trials of `set` may be staged (module docs).
pub fn applies(set: &ToleranceSet, quality: bool) -> bool {
    !quality
        && set.compensators.is_empty()
        && !set.limits.is_empty()
        && (set.attenuator.is_none() || set.limits.iter().all(ToleranceLimit::is_on_imbalance))
}

/// The first stage of a run with options `o`, or `None` where staging does not apply.
pub fn first_stage(
    doc: &BenchDoc,
    set: &ToleranceSet,
    o: &ToleranceOptions,
) -> Result<Option<FirstStage>> {
    let Some(rays) = first_stage_rays(o.rays).filter(|_| applies(set, o.quality)) else {
        return Ok(None);
    };
    let at = ToleranceOptions { rays, ..*o };
    Ok(Some(FirstStage {
        rays,
        nominal: super::nominal(doc, &at)?,
    }))
}

/// Trial `i` of `set`, staged: at the first stage's rays, kept where its verdict stands
/// ([`verdict`]), else traced at `o.rays` against `nominal`. The record of a kept trial names
/// its rays.
pub fn trial(
    doc: &BenchDoc,
    set: &ToleranceSet,
    (nominal, stage): (&Evaluation, &FirstStage),
    o: &ToleranceOptions,
    i: u64,
) -> Result<TrialRecord> {
    let at = ToleranceOptions {
        rays: stage.rays,
        ..*o
    };
    let (mut first, _) = super::trial(doc, set, &stage.nominal, &at, i)?;
    if first.error.is_some() || verdict(set, &first).is_some() {
        if first.error.is_none() {
            first.rays = Some(stage.rays);
        }
        return Ok(first);
    }
    Ok(super::trial(doc, set, nominal, o, i)?.0)
}

/// The interval of a limit's pass set: [lo, hi] from its min, max and abs_max together.
fn pass_interval(l: &ToleranceLimit) -> (f64, f64) {
    let a = l.abs_max.unwrap_or(f64::INFINITY);
    (
        l.min.unwrap_or(f64::NEG_INFINITY).max(-a),
        l.max.unwrap_or(f64::INFINITY).min(a),
    )
}

/// Where the interval `ends` (its lower and upper end mapped to the judged value) lies against
/// the pass set (lo, hi): `Some(true)` inside, `Some(false)` beyond one end, `None` across.
fn side(ends: (f64, f64), (lo, hi): (f64, f64)) -> Option<bool> {
    let (a, b) = ends;
    if !(a.is_finite() && b.is_finite()) {
        return None;
    }
    if a >= lo && b <= hi {
        Some(true)
    } else if b < lo || a > hi {
        Some(false)
    } else {
        None
    }
}

/// The verdict of a first-stage record, where it stands (module docs): `Some(false)` when a
/// limit fails beyond its error, `Some(true)` when every limit holds beyond it, `None` else.
pub fn verdict(set: &ToleranceSet, r: &TrialRecord) -> Option<bool> {
    if r.error.is_some() {
        return Some(false);
    }
    let mut all = Some(true);
    for l in &set.limits {
        let v = match (&set.attenuator, l.is_on_imbalance()) {
            (Some(a), true) => {
                let (u, se) = (
                    r.value(crate::scene::tolerance::ATTENUATOR_VALUES[2])?,
                    r.value(IMBALANCE_UNATTENUATED_STDERR)?,
                );
                let after = |x: f64| {
                    let x = x.clamp(-1.0 + 1e-12, 1.0 - 1e-12);
                    let t = crate::pipeline::perturb::attenuator_transmissions(x, a);
                    crate::pipeline::perturb::attenuated_imbalance(x, t)
                };
                let h = DECISION_Z * se;
                side((after(u - h), after(u + h)), pass_interval(l))
            }
            _ => {
                let name = if l.is_on_imbalance() {
                    IMBALANCE_ELECTRICAL.to_string()
                } else {
                    l.metric.to_string()
                };
                let (u, se) = (
                    l.value_in(r)?,
                    r.value(&format!("{name}_stderr"))
                        .filter(|s| s.is_finite())?,
                );
                let h = DECISION_Z * se;
                side((u - h, u + h), pass_interval(l))
            }
        };
        match v {
            Some(false) => return Some(false),
            Some(true) => {}
            None => all = None,
        }
    }
    all
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limit(min: Option<f64>, max: Option<f64>, abs_max: Option<f64>) -> ToleranceLimit {
        ToleranceLimit {
            metric: "imbalance".parse().unwrap(),
            min,
            max,
            abs_max,
        }
    }

    #[test]
    fn a_verdict_stands_only_when_the_whole_interval_is_on_one_side() {
        let l = limit(None, None, Some(0.01));
        assert_eq!(pass_interval(&l), (-0.01, 0.01));
        assert_eq!(side((-0.005, 0.009), pass_interval(&l)), Some(true));
        assert_eq!(side((0.011, 0.05), pass_interval(&l)), Some(false));
        assert_eq!(side((-0.05, -0.0101), pass_interval(&l)), Some(false));
        // Across an end, or across the whole pass set (a short trace whose error is wider
        // than the limit): no verdict.
        assert_eq!(side((0.005, 0.02), pass_interval(&l)), None);
        assert_eq!(side((-0.03, 0.03), pass_interval(&l)), None);
        assert_eq!(side((f64::NAN, 0.0), pass_interval(&l)), None);
        let k = limit(Some(0.2), Some(0.5), Some(0.4));
        assert_eq!(pass_interval(&k), (0.2, 0.4));
    }

    fn record(values: &[(&str, f64)]) -> TrialRecord {
        TrialRecord {
            index: 0,
            deviations: Vec::new(),
            compensators: Vec::new(),
            values: values.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
            error: None,
            needed_travel: Vec::new(),
            rays: None,
        }
    }

    fn set_with(attenuator: Option<f64>) -> ToleranceSet {
        let mut s = ToleranceSet {
            path: "t.ron".into(),
            tolerances: Vec::new(),
            compensators: Vec::new(),
            limits: vec![limit(None, None, Some(0.01))],
            quality: None,
            attenuator: None,
        };
        s.attenuator = attenuator.map(|t| crate::scene::tolerance::Attenuator {
            arm: crate::scene::tolerance::AttenuatorArm::Stronger,
            min_transmission: t,
        });
        s
    }

    /// Without an attenuator the electrical imbalance's own interval decides; with one at
    /// T ≥ 0.5 every |ι′| ≤ 1/3 is nulled, and the residual at T = 0.5,
    /// (0.5(1 + x) − (1 − x))/(0.5(1 + x) + (1 − x)), reaches 0.01 at x = 0.515/1.505 =
    /// 0.3422, so a trial decides by where ι′ ± 4σ lies against ±0.3422.
    #[test]
    fn the_attenuator_maps_the_interval_of_the_imbalance_before_it() {
        let plain = set_with(None);
        let r = |v: f64, se: f64| {
            record(&[
                ("imbalance_electrical", v),
                ("imbalance_electrical_stderr", se),
            ])
        };
        assert_eq!(verdict(&plain, &r(0.002, 0.001)), Some(true));
        assert_eq!(verdict(&plain, &r(0.002, 0.003)), None);
        assert_eq!(verdict(&plain, &r(0.03, 0.004)), Some(false));
        // No standard error: no verdict.
        assert_eq!(
            verdict(&plain, &record(&[("imbalance_electrical", 0.0)])),
            None
        );

        let att = set_with(Some(0.5));
        let x = 0.515 / 1.505;
        let t =
            crate::pipeline::perturb::attenuator_transmissions(x, att.attenuator.as_ref().unwrap());
        let res = crate::pipeline::perturb::attenuated_imbalance(x, t);
        assert!((res - 0.01).abs() < 1e-12, "{res}");
        let a = |before: f64, se: f64| {
            record(&[
                ("imbalance_electrical", 0.0),
                ("imbalance_electrical_stderr", 0.004),
                ("imbalance_electrical_unattenuated", before),
                (IMBALANCE_UNATTENUATED_STDERR, se),
            ])
        };
        // Nulled well inside the attenuator's reach, though the recorded ι′ = 0 ± 0.004 alone
        // would not decide.
        assert_eq!(verdict(&att, &a(0.1, 0.005)), Some(true));
        assert_eq!(verdict(&att, &a(-0.3, 0.005)), Some(true));
        assert_eq!(verdict(&att, &a(0.33, 0.005)), None);
        assert_eq!(verdict(&att, &a(0.3422 - 0.021, 0.005)), Some(true));
        assert_eq!(verdict(&att, &a(0.3422 + 0.021, 0.005)), Some(false));
        assert_eq!(verdict(&att, &a(0.40, 0.005)), Some(false));
        assert_eq!(verdict(&att, &a(-0.40, 0.005)), Some(false));
    }

    #[test]
    fn the_first_stage_is_whole_batches_and_not_too_short() {
        let b = crate::trace::RAYS_PER_BATCH;
        assert_eq!(first_stage_rays(200_000), Some(24 * b));
        assert_eq!(first_stage_rays(16 * 8 * b), Some(16 * b));
        assert_eq!(first_stage_rays(16 * 8 * b - 1), None);
        assert_eq!(first_stage_rays(20_000), None);
    }
}
