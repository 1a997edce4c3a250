//! Tolerance files: how well each part of a bench is made and placed, what the builder adjusts
//! after assembly (compensators), and the limits a built bench must meet.
//!
//! ```ron
//! (
//!     tolerances: [
//!         // A rigid-body move (relative) or a field (a deviation from its nominal value).
//!         (path: "arm_minus_lens.decenter_mm.x", range: PlusMinus(0.1)),
//!         (path: "dmd.tilt_deg", range: Between(-1.0, 1.0), distribution: Normal(sigmas: 3.0),
//!          fixed: true),
//!     ],
//!     compensators: [
//!         (path: "detectors.minus.decenter_mm.x", range: PlusMinus(1.0), objective: Balance),
//!     ],
//!     limits: [(metric: "imbalance", abs_max: 0.01)],
//!     quality: (ratio_percent: 40, min_mssim: 0.95),
//! )
//! ```
//!
//! Every value of a tolerance or a compensator is a **deviation** from the bench it is applied
//! to: a field path is set to its nominal value plus the deviation, a rigid-body move
//! (`NAME.decenter_mm.x`, `NAME.despace_mm`, `NAME.tilt_deg.x`) moves the part by it (see
//! [`crate::scene::variables`]). A range is `PlusMinus(h)` (−h … +h) or `Between(min, max)`.
//! A distribution is `Uniform` (default), `Normal(sigmas: k)` (centred on the middle of the
//! range, with the range's ends at ±kσ, not truncated), or `TruncatedNormal(sigmas: k)` (the
//! same normal, redrawn until it falls inside the range). `fixed: true` marks a device
//! specification (a data sheet's spread, such as the DMD's micromirror tilt): it is drawn like
//! any tolerance, but the reports flag it as one that cannot be tightened and a tolerance
//! budget keeps it at its file's range ([`Tolerance::scale_bounds`]).
//!
//! This module also reads and writes the trial records of a sharded `spibench tolerance` run
//! ([`ShardFile`]), since it is the one module that parses files.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::quantities::Quantity;
use crate::scene::doc::BenchDoc;
use crate::scene::numbers::{Count, Finite, Mssim, NonNegative, Sigmas, via};

/// A range of deviations as written in a file.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub enum RangeSpec {
    /// −h … +h.
    PlusMinus(NonNegative),
    /// min … max.
    Between(Finite, Finite),
}

/// How a tolerance is distributed over its range.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize, Serialize)]
pub enum Distribution {
    /// Uniform over the range.
    #[default]
    Uniform,
    /// Normal, centred on the middle of the range, the range's ends at ±`sigmas`·σ.
    Normal {
        /// The range's ends in standard deviations.
        #[serde(deserialize_with = "via::<Sigmas, _, _>")]
        sigmas: f64,
    },
    /// The same normal, truncated to the range.
    TruncatedNormal {
        /// The range's ends in standard deviations.
        #[serde(deserialize_with = "via::<Sigmas, _, _>")]
        sigmas: f64,
    },
}

impl Distribution {
    /// The standard deviation of a deviation drawn over a range of width `width`.
    pub fn std_dev(&self, width: f64) -> f64 {
        match *self {
            Distribution::Uniform => width / 12f64.sqrt(),
            Distribution::Normal { sigmas } => width / (2.0 * sigmas),
            Distribution::TruncatedNormal { sigmas } => {
                // Variance of a standard normal truncated to [−k, k]: 1 − 2kφ(k)/(2Φ(k) − 1).
                let k = sigmas;
                let phi = (-0.5 * k * k).exp() / (2.0 * std::f64::consts::PI).sqrt();
                let mass = erf(k / std::f64::consts::SQRT_2);
                let var = 1.0 - 2.0 * k * phi / mass;
                width / (2.0 * k) * var.max(0.0).sqrt()
            }
        }
    }
}

/// The error function (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7): enough for a standard
/// deviation used in a root-sum-square estimate.
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    if x >= 0.0 { y } else { -y }
}

/// What a compensator is adjusted to optimise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
pub enum CompensatorObjective {
    /// Balance the arms: minimise |imbalance| and |b₋ − b₊| with both k± held near their best.
    #[default]
    Balance,
    /// Collect the most light: maximise k₊ + k₋.
    Power,
}

/// One tolerance as written: a bench variable and the deviations it may take.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToleranceSpec {
    /// A bench variable: a field path or a rigid-body move (docs/reference/bench.md).
    path: String,
    /// The deviations from the nominal value (a field) or the move's extent.
    range: RangeSpec,
    /// How the Monte Carlo draws a deviation over the range.
    #[serde(default)]
    distribution: Distribution,
    /// A device specification (a data sheet's spread, such as the DMD's micromirror tilt):
    /// drawn like any tolerance, but nobody building the bench can tighten it.
    #[serde(default)]
    fixed: bool,
}

/// One compensator as written: a bench variable the builder adjusts after assembly (`path`
/// and `range`), or a compensator of another kind (`kind`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct CompensatorSpec {
    /// A bench variable: a field path or a rigid-body move.
    #[serde(default)]
    path: Option<String>,
    /// The adjustment range, as a deviation from the nominal value.
    #[serde(default)]
    range: Option<RangeSpec>,
    /// A compensator that is not a bench variable (a variable attenuator).
    #[serde(default)]
    kind: Option<CompensatorKind>,
    /// What the adjustment optimises.
    #[serde(default)]
    objective: CompensatorObjective,
}

impl CompensatorSpec {
    /// Entry `n` as a bench variable (its path and range), or None where it is the variable
    /// attenuator, which is validated into `attenuator` (at most one); either is a located
    /// error in `text` (the file `path`'s) otherwise.
    fn variable_or_attenuator(
        &self,
        n: usize,
        attenuator: &mut Option<Attenuator>,
        text: &str,
        path: &Path,
    ) -> Result<Option<(&str, RangeSpec)>> {
        use crate::scene::locate::{at, find_path, first_key, string_literal};
        match (&self.kind, &self.path, self.range) {
            (
                Some(CompensatorKind::Attenuator {
                    arm,
                    min_transmission,
                }),
                None,
                None,
            ) => {
                let field = format!("compensators[{n}].kind");
                let a = check_attenuator(
                    (*arm, *min_transmission),
                    self.objective,
                    attenuator.is_some(),
                )
                .map_err(|m| {
                    let pos = find_path(text, &field).or_else(|| first_key(text, "kind"));
                    at(Error::field(field.clone(), m).in_file(path), text, pos)
                })?;
                *attenuator = Some(a);
                Ok(None)
            }
            (None, Some(p), Some(r)) => Ok(Some((p.as_str(), r))),
            _ => {
                let e = Error::field(
                    format!("compensators[{n}]"),
                    "a compensator is either a bench variable (`path` and `range`) or \
                     `kind: Attenuator(..)` alone",
                )
                .in_file(path);
                let pos = self
                    .path
                    .as_deref()
                    .and_then(|p| string_literal(text, p))
                    .or_else(|| first_key(text, "compensators"));
                Err(at(e, text, pos))
            }
        }
    }
}

/// A compensator that is not a bench variable.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum CompensatorKind {
    /// A continuously variable neutral attenuator (an ND wheel) in front of one diode
    /// ([`Attenuator`]).
    Attenuator {
        /// The arm it sits in (default: the stronger one of each built bench).
        #[serde(default)]
        arm: AttenuatorArm,
        /// The least transmission it can be set to, in (0, 1).
        #[serde(deserialize_with = "via::<Finite, _, _>")]
        min_transmission: f64,
    },
}

/// The arm of a variable attenuator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
pub enum AttenuatorArm {
    /// In front of the + diode.
    Plus,
    /// In front of the − diode.
    Minus,
    /// In front of whichever diode gives the larger current in the built bench (the lab puts
    /// the filter where it is needed after assembly).
    #[default]
    Stronger,
}

/// A validated variable neutral attenuator: transmission T ∈ [`min_transmission`, 1] in front
/// of a diode, set after assembly in closed form to null the electrical imbalance
/// ([`crate::pipeline::perturb::attenuator_transmissions`]). It scales all light reaching that
/// diode (not its dark current), so it needs no trace of its own.
///
/// [`min_transmission`]: Attenuator::min_transmission
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Attenuator {
    pub arm: AttenuatorArm,
    pub min_transmission: f64,
}

/// The recorded values of a trial with an attenuator: the transmission set in front of each
/// diode (1 where there is none), and the electrical imbalance and k′ before it was set.
pub const ATTENUATOR_VALUES: [&str; 4] = [
    "attenuator_transmission_plus",
    "attenuator_transmission_minus",
    "imbalance_electrical_unattenuated",
    "k_prime_unattenuated",
];

/// A limit as written in a file (the name `Limit` is the one a file may write before it).
#[derive(Debug, Clone, Deserialize)]
#[serde(rename = "Limit", deny_unknown_fields)]
struct LimitSpec {
    /// A metric name of the trial rows (`imbalance`, `k_prime`, `leak_plus`, …, or with
    /// `--quality` `SCHEME_RATIO_mssim` such as `scb_40_mssim`).
    metric: String,
    /// value ≥ min.
    #[serde(default, deserialize_with = "via::<Option<Finite>, _, _>")]
    min: Option<f64>,
    /// value ≤ max.
    #[serde(default, deserialize_with = "via::<Option<Finite>, _, _>")]
    max: Option<f64>,
    /// |value| ≤ abs_max.
    #[serde(default, deserialize_with = "via::<Option<NonNegative>, _, _>")]
    abs_max: Option<f64>,
}

/// A limit a built bench must meet, on one recorded quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ToleranceLimit {
    pub metric: Quantity,
    pub min: Option<f64>,
    pub max: Option<f64>,
    /// |value| ≤ abs_max.
    pub abs_max: Option<f64>,
}

impl ToleranceLimit {
    /// Whether a value meets the limit (NaN never does).
    pub fn holds(&self, v: f64) -> bool {
        !v.is_nan()
            && self.min.is_none_or(|m| v >= m)
            && self.max.is_none_or(|m| v <= m)
            && self.abs_max.is_none_or(|m| v.abs() <= m)
    }

    /// The recorded value of a trial this limit judges: for a limit on the imbalance, the
    /// electrical imbalance ι′ ([`IMBALANCE_ELECTRICAL`], what the balanced detector's
    /// difference output sees, the diodes' responsivity mismatch included) where the record
    /// holds it, else (records of an older spibench) the optical one; any other metric as
    /// recorded.
    pub fn value_in(&self, r: &TrialRecord) -> Option<f64> {
        if self.is_on_imbalance()
            && let Some(v) = r.value(IMBALANCE_ELECTRICAL)
        {
            return Some(v);
        }
        r.value(&self.metric.to_string())
    }

    /// Whether the limit is on the imbalance (judged electrically, [`Self::value_in`]).
    pub fn is_on_imbalance(&self) -> bool {
        self.metric == Quantity::Metric(crate::quantities::BenchMetric::Imbalance)
    }

    /// The limit as text, e.g. `|imbalance| ≤ 0.01`.
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some(m) = self.abs_max {
            parts.push(format!("|{}| ≤ {m}", self.metric));
        }
        if let Some(m) = self.min {
            parts.push(format!("{} ≥ {m}", self.metric));
        }
        if let Some(m) = self.max {
            parts.push(format!("{} ≤ {m}", self.metric));
        }
        parts.join(" and ")
    }
}

/// The name under which a tolerance run records each bench's electrical imbalance
/// ι′ = (s₊k₊ − s₋k₋)/(s₊k₊ + s₋k₋) (`crate::transport::metrics::electrical_imbalance`),
/// beside the optical `imbalance`; its standard error is `imbalance_electrical_stderr`.
pub const IMBALANCE_ELECTRICAL: &str = "imbalance_electrical";

/// The image-quality limit applied to every scheme alike (with `--quality`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct QualityLimit {
    /// The sampling ratio (%) it applies at; one of the bench's `run` ratios.
    #[serde(deserialize_with = "via::<Count<1, 100>, _, _>")]
    pub ratio_percent: u32,
    /// The least MSSIM a scheme's reconstruction may score at that ratio.
    #[serde(deserialize_with = "via::<Mssim, _, _>")]
    pub min_mssim: f64,
}

/// A tolerance file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToleranceFileSpec {
    /// The toleranced variables, each drawn independently in every Monte Carlo trial.
    tolerances: Vec<ToleranceSpec>,
    /// The variables adjusted after assembly, in every trial, in order.
    #[serde(default)]
    compensators: Vec<CompensatorSpec>,
    /// The limits a built bench must meet to count in the yield.
    #[serde(default)]
    limits: Vec<LimitSpec>,
    /// The image-quality limit for every scheme (used with `--quality`).
    #[serde(default)]
    quality: Option<QualityLimit>,
}

/// One validated tolerance: deviations `min ..= max` from the nominal bench.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tolerance {
    pub path: String,
    pub min: f64,
    pub max: f64,
    pub distribution: Distribution,
    /// The variable's nominal value (0 for a rigid-body move).
    pub nominal: f64,
    /// A device specification that cannot be tightened (`fixed: true` in the file).
    pub fixed: bool,
}

impl Tolerance {
    /// Whether the tolerance is a device specification that cannot be tightened: a budget
    /// keeps it at scale 1, and reports flag it instead of asking for it to be held closer.
    pub fn is_fixed(&self) -> bool {
        self.fixed
    }

    /// The scale bounds a budget may give this tolerance: `min … max` as asked, or exactly 1
    /// for a fixed one (a device specification is neither tightened nor loosened).
    pub fn scale_bounds(&self, min: f64, max: f64) -> (f64, f64) {
        if self.fixed { (1.0, 1.0) } else { (min, max) }
    }
}

/// One validated compensator: adjusted within `min ..= max` of the value it has after the
/// tolerances are applied.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Compensator {
    pub path: String,
    pub min: f64,
    pub max: f64,
    pub objective: CompensatorObjective,
}

/// A validated tolerance file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ToleranceSet {
    pub path: PathBuf,
    pub tolerances: Vec<Tolerance>,
    pub compensators: Vec<Compensator>,
    /// The variable attenuator among the compensators, if the file has one.
    pub attenuator: Option<Attenuator>,
    pub limits: Vec<ToleranceLimit>,
    pub quality: Option<QualityLimit>,
}

/// The largest number of tolerances or compensators a file may list.
pub const MAX_ENTRIES: usize = 1000;

impl ToleranceSet {
    /// Reads a tolerance file and checks it against the bench: every path must name a bench
    /// variable, every range must be finite and ordered, and the bench must accept both ends
    /// (a field set outside its valid range is refused); every limit must name a [`Quantity`].
    pub fn read(path: &Path, doc: &BenchDoc) -> Result<Self> {
        let text = crate::scene::read_text(path)?;
        Self::parse(&text, path, doc)
    }

    /// Parses tolerance text; `path` names it in errors.
    pub fn parse(text: &str, path: &Path, doc: &BenchDoc) -> Result<Self> {
        let spec: ToleranceFileSpec = crate::scene::parse_ron(text, path)?;
        // An error at the line where `needle` (a path or a metric, a string) is first written.
        let locate = |needle: &str, field: &str, msg: String| -> Error {
            let e = Error::field(field, msg).in_file(path);
            crate::scene::locate::at(e, text, crate::scene::locate::string_literal(text, needle))
        };
        if spec.tolerances.len() > MAX_ENTRIES || spec.compensators.len() > MAX_ENTRIES {
            return Err(Error::field(
                "tolerances",
                format!("a file may list at most {MAX_ENTRIES} tolerances and compensators"),
            )
            .in_file(path));
        }
        let range = |p: &str, r: RangeSpec| -> Result<(f64, f64)> {
            let (lo, hi) = match r {
                RangeSpec::PlusMinus(h) => (-h.0, h.0),
                RangeSpec::Between(a, b) => (a.0, b.0),
            };
            if lo > hi {
                return Err(locate(
                    p,
                    "range",
                    format!(
                        "`{p}`: the range {lo} … {hi} is empty (PlusMinus takes h ≥ 0, Between \
                         takes min ≤ max)"
                    ),
                ));
            }
            // Both ends must give a valid bench variable.
            let nominal = crate::scene::variables::get(&doc.file, p)
                .map_err(|e| locate(p, "path", e.to_string()))?;
            for end in [lo, hi] {
                let mut f = doc.file.clone();
                crate::scene::variables::set(&mut f, p, nominal + end).map_err(|e| {
                    locate(
                        p,
                        "range",
                        format!("`{p}` cannot deviate by {end} from {nominal}: {e}"),
                    )
                })?;
            }
            Ok((lo, hi))
        };
        let mut tolerances: Vec<Tolerance> = Vec::new();
        for t in &spec.tolerances {
            if tolerances.iter().any(|u| u.path == t.path) {
                return Err(locate(
                    &t.path,
                    "path",
                    format!("`{}` is listed twice among the tolerances", t.path),
                ));
            }
            let (min, max) = range(&t.path, t.range)?;
            tolerances.push(Tolerance {
                path: t.path.clone(),
                min,
                max,
                distribution: t.distribution,
                nominal: crate::scene::variables::get(&doc.file, &t.path)
                    .map_err(|e| locate(&t.path, "path", e.to_string()))?,
                fixed: t.fixed,
            });
        }
        let mut compensators: Vec<Compensator> = Vec::new();
        let mut attenuator = None;
        for (n, c) in spec.compensators.iter().enumerate() {
            let Some((c_path, c_range)) =
                c.variable_or_attenuator(n, &mut attenuator, text, path)?
            else {
                continue;
            };
            let c_path = c_path.to_string();
            if compensators.iter().any(|u| u.path == c_path) {
                return Err(locate(
                    &c_path,
                    "path",
                    format!("`{c_path}` is listed twice among the compensators"),
                ));
            }
            let (min, max) = range(&c_path, c_range)?;
            if min == max {
                return Err(locate(
                    &c_path,
                    "range",
                    format!("`{c_path}`: a compensator needs a range of nonzero width"),
                ));
            }
            compensators.push(Compensator {
                path: c_path,
                min,
                max,
                objective: c.objective,
            });
        }
        let mut limits = Vec::with_capacity(spec.limits.len());
        for l in &spec.limits {
            let Ok(metric) = l.metric.parse::<Quantity>() else {
                return Err(locate(
                    &l.metric,
                    "metric",
                    format!(
                        "`{}` is not a recorded metric (for example `imbalance`, `k_prime`, \
                         `b_minus_minus_b_plus`, `leak_plus`, `scb_40_mssim`)",
                        l.metric
                    ),
                ));
            };
            if l.min.is_none() && l.max.is_none() && l.abs_max.is_none() {
                return Err(locate(
                    &l.metric,
                    "limits",
                    format!("the limit on `{}` sets none of min, max, abs_max", l.metric),
                ));
            }
            if let (Some(lo), Some(hi)) = (l.min, l.max)
                && lo > hi
            {
                return Err(locate(
                    &l.metric,
                    "limits",
                    format!(
                        "the limit on `{}` has min {lo} > max {hi}: no value can meet it",
                        l.metric
                    ),
                ));
            }
            limits.push(ToleranceLimit {
                metric,
                min: l.min,
                max: l.max,
                abs_max: l.abs_max,
            });
        }
        Ok(ToleranceSet {
            path: path.to_path_buf(),
            tolerances,
            compensators,
            attenuator,
            limits,
            quality: spec.quality,
        })
    }

    /// Checks the file's image-quality limits against the run that will score them (`--quality`):
    /// `quality.ratio_percent` must be one of the run's sampling ratios (in per cent), and a limit
    /// on an image score (`SCHEME_PERCENT_mssim`, `…_psnr_db`, `…_finest_lp_per_mm`) must name a
    /// score the run records (`is_score`). Either mistake gave an empty yield. `text` is the
    /// file's text, for the line of the error.
    pub fn check_quality(
        &self,
        text: &str,
        ratios_percent: &[u32],
        is_score: &dyn Fn(&str) -> bool,
    ) -> Result<()> {
        use crate::scene::locate;
        if let Some(q) = self.quality
            && !ratios_percent.contains(&q.ratio_percent)
        {
            let list: Vec<String> = ratios_percent.iter().map(|r| r.to_string()).collect();
            let e = Error::field(
                "quality.ratio_percent",
                format!(
                    "{} % is not one of the run's sampling ratios ({} %, the bench's \
                     `run.sampling_ratios`): no trial would be scored there",
                    q.ratio_percent,
                    list.join(", ")
                ),
            )
            .in_file(&self.path);
            return Err(locate::at(
                e,
                text,
                locate::first_key(text, "ratio_percent"),
            ));
        }
        for l in &self.limits {
            let name = l.metric.to_string();
            if !l.metric.is_traced() && !is_score(&name) {
                let example = ratios_percent.first().map_or(String::new(), |r| {
                    format!(", e.g. `secondary_complementary_balancing_{r}_mssim`")
                });
                let e = Error::field(
                    "limits.metric",
                    format!(
                        "`{}` is not an image score this run records (SCHEME_PERCENT_mssim with \
                         one of the run's schemes and sampling ratios{example})",
                        l.metric
                    ),
                )
                .in_file(&self.path);
                return Err(locate::at(e, text, locate::string_literal(text, &name)));
            }
        }
        Ok(())
    }

    /// The compensators of the file, the attenuator included.
    pub fn compensator_count(&self) -> usize {
        self.compensators.len() + usize::from(self.attenuator.is_some())
    }

    /// An error, at the attenuator's line of `text` (the file's text), for a use that cannot
    /// hold the attenuator, which is set on a trial's traced metrics and is no part of its
    /// bench document: `what` says which (a dataset's benches, a trial's bench file, the
    /// image-quality stages). Ok where the file has none.
    pub fn refuse_attenuator(&self, text: &str, what: &str) -> Result<()> {
        if self.attenuator.is_none() {
            return Ok(());
        }
        let e = Error::field(
            "compensators.kind",
            format!(
                "the attenuator is set on each trial's traced metrics and is not a part of the \
                 bench, so {what} cannot have it: use a tolerance file without it"
            ),
        )
        .in_file(&self.path);
        Err(crate::scene::locate::at(
            e,
            text,
            crate::scene::locate::first_key(text, "kind"),
        ))
    }

    /// The budget's cost rules with every fixed tolerance's scale bounds pinned to 1
    /// ([`Tolerance::scale_bounds`]); `costs` holds one rule per tolerance, in file order.
    pub fn pin_fixed(
        &self,
        costs: &[crate::scene::budget_costs::ToleranceCost],
    ) -> Vec<crate::scene::budget_costs::ToleranceCost> {
        costs
            .iter()
            .zip(&self.tolerances)
            .map(|(c, t)| {
                let (min_scale, max_scale) = t.scale_bounds(c.min_scale, c.max_scale);
                crate::scene::budget_costs::ToleranceCost {
                    min_scale,
                    max_scale,
                    ..*c
                }
            })
            .collect()
    }

    /// A set with every tolerance range scaled by `factor` (0 gives the nominal bench).
    pub fn scaled(&self, factor: f64) -> ToleranceSet {
        let mut s = self.clone();
        for t in &mut s.tolerances {
            t.min *= factor;
            t.max *= factor;
        }
        s
    }
}

/// The attenuator as validated: `min_transmission` in (0, 1), the objective `Balance` (a
/// neutral attenuator can only lose light), at most one (`seen`: one came before).
fn check_attenuator(
    (arm, t): (AttenuatorArm, f64),
    objective: CompensatorObjective,
    seen: bool,
) -> std::result::Result<Attenuator, String> {
    if seen {
        return Err(
            "a tolerance file may have one attenuator: it balances the arms alone, on \
                    whichever arm it sits"
                .into(),
        );
    }
    if objective != CompensatorObjective::Balance {
        return Err(
            "an attenuator can only balance the arms (`objective: Balance`): it takes \
                    light away, never adds it"
                .into(),
        );
    }
    if !(t > 0.0 && t < 1.0) {
        return Err(format!(
            "`min_transmission` must lie in (0, 1) (the attenuator's darkest setting), got {t}"
        ));
    }
    Ok(Attenuator {
        arm,
        min_transmission: t,
    })
}

/// One Monte Carlo trial as recorded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialRecord {
    pub index: u64,
    /// The drawn deviation of each tolerance, in file order.
    pub deviations: Vec<(String, f64)>,
    /// The deviation each compensator settled at.
    pub compensators: Vec<(String, f64)>,
    /// Every recorded number, by name (metrics, their standard errors and differences from
    /// the nominal bench, CMRR, image scores).
    pub values: Vec<(String, f64)>,
    /// Why the trial could not be traced (a perturbed bench that is not valid), if so.
    pub error: Option<String>,
    /// The compensators that ended this trial at a limit of their travel, each with the
    /// travel the same adjustment needs when allowed more (`crate::tolerance::trial`).
    #[serde(default)]
    pub needed_travel: Vec<NeededTravel>,
    /// The rays it was traced with, where fewer than the run's: a budget confirmation's trial
    /// kept at its first stage (`crate::tolerance::staged`); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rays: Option<u64>,
}

/// A compensator that ended a trial at a limit of its travel, and the travel it would need.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NeededTravel {
    pub path: String,
    /// The deviation it settled at (at a limit of the file's range).
    pub settled: f64,
    /// The deviation the same adjustment settles at with its range widened about its centre
    /// (`crate::tolerance::WIDER_TRAVEL` times); NaN where that adjustment failed.
    pub needed: f64,
    /// True when the wider range was not enough either: `needed` is then a lower bound on
    /// the travel.
    pub beyond: bool,
}

impl TrialRecord {
    pub fn value(&self, name: &str) -> Option<f64> {
        self.values.iter().find(|(k, _)| k == name).map(|(_, v)| *v)
    }
}

/// One row of a sensitivity table: a tolerance alone at its min and at its max.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensitivityRecord {
    pub path: String,
    pub min: f64,
    pub max: f64,
    /// Lamp rays of the traces at [min, max] (each compared with the nominal bench traced with
    /// as many): the run's rays, or more where `tolerance --resolve` asked for them.
    #[serde(default)]
    pub rays: [u64; 2],
    /// Changes from the nominal bench at the min (`NAME_diff`, `NAME_diff_stderr`, …).
    pub at_min: Vec<(String, f64)>,
    pub at_max: Vec<(String, f64)>,
}

impl SensitivityRecord {
    pub fn at(&self, high: bool, name: &str) -> f64 {
        value_of(if high { &self.at_max } else { &self.at_min }, name)
    }
}

/// The value named `name` in a list of named values (NaN when it is not there).
pub fn value_of(v: &[(String, f64)], name: &str) -> f64 {
    v.iter()
        .find(|(k, _)| k == name)
        .map_or(f64::NAN, |(_, x)| *x)
}

/// The records a (sharded) tolerance run writes, from which its outputs are made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardFile {
    pub spibench_version: String,
    pub scene: String,
    /// The canonical RON of the nominal bench and the tolerance file's text, which shards
    /// must share to be merged.
    pub bench_ron: String,
    /// The tolerance file as named on the command line, and its text.
    pub tolerances_path: String,
    pub tolerances_text: String,
    pub rays: u64,
    pub seed: u64,
    pub trials: u64,
    pub quality: bool,
    /// (I, N): this shard holds the trials i ≡ I (mod N).
    pub shard: (u64, u64),
    pub nominal: Vec<(String, f64)>,
    /// The sensitivity table (written by shard 0 only).
    pub sensitivity: Option<Vec<SensitivityRecord>>,
    pub records: Vec<TrialRecord>,
}

/// The shard file as RON text (floats written so that they read back bit for bit).
pub fn shard_to_ron(s: &ShardFile) -> Result<String> {
    let config = ron::ser::PrettyConfig::new()
        .struct_names(false)
        .indentor(" ".to_string());
    ron::ser::to_string_pretty(s, config)
        .map_err(|e| Error::Numerical(format!("the trial records cannot be written: {e}")))
}

/// Reads a shard file written by `spibench tolerance`.
pub fn read_shard(path: &Path) -> Result<ShardFile> {
    crate::scene::read_ron(path)
}

#[cfg(test)]
mod tests;
