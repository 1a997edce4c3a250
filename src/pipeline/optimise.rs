//! The optimiser of bench variables: the values of free variables that optimise an objective,
//! found by a derivative-free search on traced benches. Used by the `align` job and by the
//! compensators of a tolerance trial ([`crate::pipeline::perturb`]).
//!
//! # Method
//!
//! The search is the Nelder–Mead simplex method (J. A. Nelder and R. Mead, "A simplex method for
//! function minimization", *Computer Journal* 7, 308–313, 1965), with the standard coefficients
//! (reflection 1, expansion 2, contraction ½, shrink ½) and the ordering and tie rules of
//! J. C. Lagarias, J. A. Reeds, M. H. Wright and P. E. Wright, "Convergence properties of the
//! Nelder–Mead simplex method in low dimensions", *SIAM J. Optim.* 9, 112–147 (1998). It works
//! on the free variables scaled to the unit box [0, 1]ⁿ; a trial point outside the box is
//! projected onto it.
//!
//! # Monte Carlo noise
//!
//! A traced objective is a random number. Two things keep the simplex from chasing noise:
//!
//! - **Common random numbers.** Every evaluation of one stage traces with the same seed and ray
//!   count, so the objective is one fixed, smooth *sample path* of the random function, and
//!   Nelder–Mead minimises that deterministic function. This is sample-path optimisation
//!   (S. M. Robinson, "Analysis of sample-path optimization", *Math. Oper. Res.* 21, 513–528,
//!   1996): its minimiser converges to the true one as the sample grows.
//! - **A growing sample.** A stage stops when the objective values across the simplex differ by
//!   less than the standard error of the objective's difference from the stage's first point
//!   (paired, with common random numbers; smaller differences would fit the sample path, not
//!   the bench) or when the simplex has shrunk below a set size; the next stage traces 4×
//!   the rays and restarts the simplex at the best point with half the step. Raising the sample
//!   size as the search converges is the variable-sample scheme of T. Homem-de-Mello,
//!   "Variable-sample methods for stochastic optimization", *ACM TOMACS* 13, 108–133 (2003).
//!
//! # Objectives
//!
//! Each objective is a sum of named terms ([`terms`]), reported one by one:
//!
//! - `Balance { min_fraction, offset_weight }`: minimise |ι′|, the electrical imbalance
//!   ι′ = (s₊k₊ − s₋k₋)/(s₊k₊ + s₋k₋) that the balanced detector's difference output sees
//!   ([`crate::transport::metrics::electrical_imbalance`], the evaluated bench's own diode
//!   responsivity scales s±, [`Evaluation::responsivity_scale`]), not the optical
//!   ι = (k₊ − k₋)/(k₊ + k₋): with r = s₊/s₋ ≠ 1 the arms balance the detector at
//!   ι = (1 − r)/(1 + r) (about −0.015 for the default 3 % mismatch), and the tolerance limits
//!   on the imbalance are judged on ι′ too. To it are added offset_weight·|b₋ − b₊|/(b₊ + b₋),
//!   only when the user gives the offset a weight, and a penalty 10·Σ max(0, f·k_ref − k±)/k_ref that holds each arm's k± at a fraction f of its
//!   best. The best is taken as the better arm of the starting bench (k_ref = max(k₊, k₋) at
//!   the start): balancing must not be bought by dimming the good arm. The offset term is off
//!   by default: on the paper bench it is about 0.84, out of reach of the arm knobs, and its
//!   ray noise, not the imbalance, then decided which point won.
//! - `Power`: maximise k₊ + k₋ (minimise −(k₊ + k₋)/(k₊ + k₋)_start).
//! - `Weighted`: minimise Σ w_m·m over named metrics (values in their SI units).
//! - `Centre`: maximise the diodes' centre margins ([`centre_margin_m`]: active radius −
//!   centroid offset − 2 RMS radii of the arm's collected spot, the pattern light of its state
//!   on its active area, from the irradiance maps of the same trace, [`spot`]), the smaller
//!   one weighted more ([`centre_value`]), in units of the smaller active radius: each diode
//!   centred on its spot.
//!   Where the imbalance is flat over a range of positions (the whole spot on the diode), this
//!   is the point in the middle of that range, the one that keeps the spot on the diode for the
//!   largest move either way. Its standard error is the margin's own (delta method over the
//!   map's bins, [`spot`]), not paired: the maps keep no per-batch totals to pair.
//!   The light on the housing's plate is not the spot (with the diffractive DMD it is chiefly
//!   the orders the diode does not collect), so a spot that crosses the rim is seen by its
//!   part inside: its margin bottoms out once the spot's centre reaches the rim ([`spot`]).

use crate::error::{Error, Result};
use crate::pipeline::evaluate::{EvaluateOptions, Evaluation, Spot, evaluate, evaluate_mapped};
use crate::quantities::BenchMetric;
use crate::scene::doc::BenchDoc;
use crate::transport::metrics::BenchMetrics;

/// A free variable and its bounds (values of the bench variable as `variables::get` reads
/// them: a field's value, or a rigid-body move relative to the starting bench).
#[derive(Debug, Clone, PartialEq)]
pub struct Free {
    pub path: String,
    pub lo: f64,
    pub hi: f64,
}

impl Free {
    /// Parses `PATH=LO:HI`.
    pub fn parse(text: &str) -> Result<Free> {
        let bad = |why: &str| Error::field("free", format!("`{text}`: {why}"));
        let (path, range) = text
            .split_once('=')
            .ok_or_else(|| bad("expected PATH=LO:HI"))?;
        let (a, b) = range
            .split_once(':')
            .ok_or_else(|| bad("expected PATH=LO:HI"))?;
        let num = |s: &str| -> Result<f64> {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad("LO and HI must be finite numbers"))
        };
        let (lo, hi) = (num(a)?, num(b)?);
        if lo >= hi {
            return Err(bad("LO must be below HI"));
        }
        Ok(Free {
            path: path.trim().to_string(),
            lo,
            hi,
        })
    }
}

/// What to optimise.
#[derive(Debug, Clone, PartialEq)]
pub enum Objective {
    /// |electrical imbalance| + offset_weight·|b₋ − b₊|/(b₊ + b₋), k± held at min_fraction of
    /// the best (module notes).
    Balance {
        min_fraction: f64,
        offset_weight: f64,
    },
    Power,
    Weighted(Vec<(BenchMetric, f64)>),
    /// −[min(m₊, m₋) + (m₊ + m₋)/2]/(2·min(R₊, R₋)) of the centre margins m±
    /// ([`centre_value`]): each diode centred on its arm's spot.
    Centre,
}

impl Objective {
    /// Balance of the arms alone (the offset unweighted), k± held at 90 % of the best.
    pub const BALANCE: Objective = Objective::Balance {
        min_fraction: 0.9,
        offset_weight: 0.0,
    };

    /// Whether the objective needs the diodes' irradiance maps ([`Evaluation::spots`]).
    pub fn needs_maps(&self) -> bool {
        matches!(self, Objective::Centre)
    }
}

/// Evaluates one bench for `obj`: with the diodes' irradiance maps when the objective needs
/// them ([`evaluate_mapped`]), the plain trace otherwise.
pub fn evaluate_for(
    obj: &Objective,
    doc: &BenchDoc,
    settings: Vec<(String, f64)>,
    o: &EvaluateOptions,
) -> Result<Evaluation> {
    if obj.needs_maps() && !o.quality {
        evaluate_mapped(doc, settings, o)
    } else {
        evaluate(doc, settings, o)
    }
}

/// The balance objective's first term: the electrical imbalance's magnitude.
pub const BALANCE_TERM: &str = "|electrical imbalance| |s₊k₊ − s₋k₋|/(s₊k₊ + s₋k₋)";

/// One named term of an objective at a point: its value and its standard error (paired where
/// the objective was evaluated against a reference bench).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Term {
    pub name: String,
    pub value: f64,
    pub stderr: f64,
}

/// Why a search ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum SearchStop {
    /// The objective's spread over the last simplex fell below its paired standard error.
    NoiseFloor,
    /// The last simplex shrank below 1e-3 of the box.
    SimplexSize,
    /// The evaluation budget ran out before either test ended the last stage.
    Budget,
}

impl SearchStop {
    pub fn describe(&self) -> &'static str {
        match self {
            SearchStop::NoiseFloor => {
                "the objective's spread over the simplex fell below its paired standard error"
            }
            SearchStop::SimplexSize => "the simplex shrank below 1e-3 of the box",
            SearchStop::Budget => "the evaluation budget (--max-evaluations) ran out",
        }
    }
}

/// How to search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignOptions {
    /// Rays of the first stage; each later stage traces 4× more, up to `max_rays`.
    pub start_rays: u64,
    pub max_rays: u64,
    pub seed: u64,
    /// The most traced evaluations in all.
    pub max_evaluations: usize,
}

impl AlignOptions {
    /// The rays of the first and of the last stage: at least two batches (a standard error
    /// needs two), and the last never below the first.
    pub fn stage_rays(&self) -> (u64, u64) {
        let start = self.start_rays.max(2 * crate::trace::RAYS_PER_BATCH);
        (start, self.max_rays.max(start))
    }
}

/// One traced evaluation of the objective.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    pub stage: usize,
    pub rays: u64,
    pub values: Vec<f64>,
    pub objective: f64,
    pub objective_stderr: f64,
    /// The optical imbalance (k₊ − k₋)/(k₊ + k₋) and the electrical one (the balance
    /// objective's), each with its standard error.
    pub imbalance: f64,
    pub imbalance_stderr: f64,
    pub imbalance_electrical: f64,
    pub imbalance_electrical_stderr: f64,
    pub k_plus: f64,
    pub k_minus: f64,
}

/// A finished search: where it started and the best point it found, in the variables' values.
#[derive(Debug, Clone)]
pub struct Search {
    pub start_values: Vec<f64>,
    pub best_values: Vec<f64>,
    pub history: Vec<Step>,
    /// Why the last stage ended.
    pub stop: SearchStop,
    /// The objective's reference k (see the module notes), from the start.
    pub k_ref: f64,
}

/// The settings (path, value) of the free variables at `x`.
pub fn settings(free: &[Free], x: &[f64]) -> Vec<(String, f64)> {
    free.iter()
        .zip(x)
        .map(|(f, &v)| (f.path.clone(), v))
        .collect()
}

/// An objective to minimise: the value and its standard error at a point of the unit box.
type ObjectiveFn<'a> = dyn FnMut(&[f64]) -> Result<(f64, f64)> + 'a;

fn value(m: &BenchMetrics, metric: BenchMetric) -> (f64, f64) {
    let x = &m[metric];
    (x.value, x.stderr())
}

/// The objective (to minimise) and its standard error, given the reference k (see the module
/// notes): the sum of its [`terms`]. With `paired`, the standard error is that of the
/// difference from the `paired` bench traced with the same random numbers: the noise that
/// matters when two nearby points are compared.
pub fn objective(
    obj: &Objective,
    e: &Evaluation,
    k_ref: f64,
    paired: Option<&Evaluation>,
) -> (f64, f64) {
    let t = terms(obj, e, k_ref, paired);
    let f = t.iter().map(|t| t.value).sum::<f64>();
    // The terms come from the same traces; their errors are added in quadrature as before (the
    // penalty is exact).
    let se = t.iter().map(|t| t.stderr * t.stderr).sum::<f64>().sqrt();
    (f, se)
}

/// The objective's terms at a point (see [`objective`]). The centre objective reads the
/// evaluation's spots; evaluated without them ([`evaluate`] rather than [`evaluate_for`]) its
/// value is NaN.
pub fn terms(
    obj: &Objective,
    e: &Evaluation,
    k_ref: f64,
    paired: Option<&Evaluation>,
) -> Vec<Term> {
    let m = &e.metrics;
    let value = |m: &BenchMetrics, metric: BenchMetric| -> (f64, f64) {
        let (v, se) = value(m, metric);
        match paired {
            Some(p) => (v, m[metric].diff(&p.metrics[metric]).stderr),
            None => (v, se),
        }
    };
    let term = |name: &str, value: f64, stderr: f64| Term {
        name: name.to_string(),
        value,
        stderr,
    };
    match obj {
        Objective::Balance {
            min_fraction,
            offset_weight,
        } => {
            // The electrical imbalance, each bench through its own responsivity scales, paired
            // like the metrics (its influence is the optical one's times dι′/dι). Invalid
            // electronics give NaN: no balance to reach.
            let (imb, imb_se) = match (e.electrical_imbalance(), paired) {
                (Some(i), Some(p)) => {
                    let se = p
                        .electrical_imbalance()
                        .map_or(f64::NAN, |p| i.diff(&p).stderr);
                    (i.value, se)
                }
                (Some(i), None) => (i.value, i.stderr()),
                (None, _) => (f64::NAN, f64::NAN),
            };
            let (kp, _) = value(m, BenchMetric::KPlus);
            let (km, _) = value(m, BenchMetric::KMinus);
            let short = |k: f64| (min_fraction * k_ref - k).max(0.0) / k_ref;
            let mut t = vec![term(
                BALANCE_TERM,
                if imb.is_nan() { 1.0 } else { imb.abs() },
                imb_se,
            )];
            if *offset_weight != 0.0 {
                let (bp, _) = value(m, BenchMetric::BPlus);
                let (bm, _) = value(m, BenchMetric::BMinus);
                let (db, db_se) = value(m, BenchMetric::BMinusMinusBPlus);
                let scale = (bp + bm).abs();
                let (off, off_se) = if scale > 0.0 {
                    (db.abs() / scale, db_se / scale)
                } else {
                    (0.0, 0.0)
                };
                t.push(term(
                    "offset_weight·|b₋ − b₊|/(b₊ + b₋)",
                    offset_weight * off,
                    offset_weight.abs() * off_se,
                ));
            }
            t.push(term(
                "k± penalty 10·Σ max(0, f·k_ref − k±)/k_ref",
                10.0 * (short(kp) + short(km)),
                0.0,
            ));
            t
        }
        Objective::Power => {
            let (k, se) = value(m, BenchMetric::KPrime);
            vec![term("−k'/k'_start", -k / k_ref, se / k_ref)]
        }
        Objective::Weighted(w) => w
            .iter()
            .map(|&(metric, wt)| {
                let (x, se) = value(m, metric);
                term(&format!("{wt}·{metric}"), wt * x, (wt * se).abs())
            })
            .collect(),
        Objective::Centre => {
            let name = "−[min(m₊, m₋) + (m₊ + m₋)/2]/(2·min(R₊, R₋)), m± the centre margins";
            let Some(s) = &e.spots else {
                return vec![term(name, f64::NAN, f64::NAN)];
            };
            let margins = [s[0].margin_m, s[1].margin_m];
            let radii = [s[0].active_radius_m, s[1].active_radius_m];
            vec![term(
                name,
                centre_value(margins, radii),
                centre_value_stderr(margins, [s[0].margin_stderr_m, s[1].margin_stderr_m], radii),
            )]
        }
    }
}

/// How many RMS radii of the light spot the centre margin keeps inside the active edge: for a
/// round Gaussian spot, 2σ_r (σ_r the RMS radius, √2 of the per-axis σ) holds about 86 % of the
/// power (1 − e⁻²), so a positive margin means the bulk of the spot clears the edge.
pub const CENTRE_RMS_RADII: f64 = 2.0;

/// The centre margin of one diode (m): active radius − (distance of the spot's centroid from
/// the diode's centre + k·RMS radius), from its collected spot's summary ([`spot`]). It is
/// largest where the spot sits at the diode's centre, and it falls through 0 as the spot's
/// footprint reaches the active edge. With no light on the active area it is −∞: a diode the
/// light misses is not centred.
pub fn centre_margin_m(
    stats: &crate::trace::irradiance::MapStats,
    active_radius_m: f64,
    k_rms: f64,
) -> f64 {
    if stats.active_w.is_nan() || stats.active_w <= 0.0 {
        return f64::NEG_INFINITY;
    }
    let [cx, cy] = stats.centroid_m;
    active_radius_m - (cx.hypot(cy) + k_rms * stats.rms_radius_m)
}

/// Diode d's [`Spot`] in its own arm's state (branch d: every unit + for the + diode, − for
/// the − diode), with the centre margin for `k_rms` RMS radii and its standard error.
///
/// The spot is the light the diode collects: the pattern light of its state on its active
/// area ([`crate::trace::irradiance::IrradianceMaps::collected`]). The housing's plate is left
/// out because with the diffractive DMD it holds chiefly the diffraction orders the diode does
/// not collect (filament images one order spacing, 2.6–8.5 mm on the paper bench, from the
/// collected one; docs/dmd_diffraction.md), whose centroid says nothing about where the
/// collected order sits; the pattern-independent light is left out because no pattern moves
/// it. The price: a spot crossing the rim is seen by its part inside, so its margin stops
/// falling once the spot's centre reaches the rim (about −0.6 spot radii for a uniform round
/// spot) and climbs back toward 0 as the last of it leaves: the margin pulls a diode toward its
/// spot from wherever the spot's centre lies on the active area, and peaks with it centred.
///
/// The errors are the delta method over the map's bins, taken as independent (as the
/// centroid's, [`crate::trace::irradiance::MapStats::centroid_stderr_m`]): with W the mapped
/// power, c the centroid, ρ = |c|, e = c/ρ and r² = Σ wᵢ|pᵢ − c|²/W, a bin's power moves
/// ρ by e·(pᵢ − c)/W and r by (|pᵢ − c|² − r²)/(2rW) (the centroid's own move changes r² only at
/// second order), and the margin by minus the first plus k times the second. Near the centre
/// (ρ within a few standard errors of 0) |c| is biased high by about its error, and the
/// direction e is that of the noise: the error given is that along it.
pub fn spot(maps: &crate::trace::irradiance::IrradianceMaps, d: usize, k_rms: f64) -> Spot {
    use crate::trace::irradiance::branch_index;
    let stats = maps.collected(d, d);
    let window = maps.window(d);
    let radius = window.radius_m;
    let total = stats.active_w;
    let [cx, cy] = stats.centroid_m;
    let rho = cx.hypot(cy);
    let (ex, ey) = if rho > 0.0 {
        (cx / rho, cy / rho)
    } else {
        (1.0, 0.0)
    };
    let r = stats.rms_radius_m;
    let bins = maps.bins;
    let (mut v_rho, mut v_margin) = (0.0, 0.0);
    if total > 0.0 {
        for i in 0..bins * bins {
            let se = maps.branch_stderr_w(branch_index(bins, d, d, 0, i));
            if se == 0.0 {
                continue;
            }
            let (x, y) = window.bin_centre(bins, i / bins, i % bins);
            let (dx, dy) = (x - cx, y - cy);
            let g_rho = (ex * dx + ey * dy) / total;
            let g_r = if r > 0.0 {
                (dx * dx + dy * dy - r * r) / (2.0 * r * total)
            } else {
                0.0
            };
            v_rho += (g_rho * se).powi(2);
            v_margin += ((g_rho + k_rms * g_r) * se).powi(2);
        }
    }
    Spot {
        stats,
        active_radius_m: radius,
        offset_m: rho,
        offset_stderr_m: v_rho.sqrt(),
        margin_m: centre_margin_m(&stats, radius, k_rms),
        margin_stderr_m: v_margin.sqrt(),
    }
}

/// The centre objective to minimise: minus the mean of the smaller of the two diodes' margins
/// and their average, in units of the smaller active radius (dimensionless like the other
/// objectives), −[min(m₊, m₋) + (m₊ + m₋)/2]/(2·min(R₊, R₋)).
///
/// The smaller margin alone (max-min) would stop pulling a diode toward its centre as soon as
/// its margin passed the other's: with only the − diode free and the + spot 0.3 mm off its own
/// centre, every − position within 0.3 mm of the − centre would score alike, and the search
/// would stop anywhere on that plateau. The average keeps each diode's margin in the objective
/// (where each diode's variables move only its own spot, the optimum centres both), and the
/// smaller margin's extra weight keeps a variable that moves both spots from buying one
/// diode's margin with the other's.
pub fn centre_value(margins_m: [f64; 2], radii_m: [f64; 2]) -> f64 {
    let [a, b] = margins_m;
    -(a.min(b) + 0.5 * (a + b)) / (2.0 * radii_m[0].min(radii_m[1]))
}

/// The standard error of [`centre_value`] from the margins' own (the two diodes' light is
/// mapped from different mirror states, taken as independent): the smaller margin enters with
/// weight 3/4, the larger with 1/4, over the smaller radius.
pub fn centre_value_stderr(margins_m: [f64; 2], stderr_m: [f64; 2], radii_m: [f64; 2]) -> f64 {
    let (low, high) = if margins_m[0] <= margins_m[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    (0.75 * stderr_m[low]).hypot(0.25 * stderr_m[high]) / radii_m[0].min(radii_m[1])
}

/// Checks an objective's metric names.
pub fn check_objective(obj: &Objective) -> Result<()> {
    match obj {
        Objective::Balance { min_fraction, .. }
            if !(*min_fraction >= 0.0 && *min_fraction <= 1.0) =>
        {
            Err(Error::field(
                "min_fraction",
                format!("must lie in [0, 1], got {min_fraction}"),
            ))
        }
        Objective::Balance { offset_weight, .. } if !offset_weight.is_finite() => {
            Err(Error::field(
                "offset_weight",
                format!("must be finite, got {offset_weight}"),
            ))
        }
        Objective::Weighted(w) if w.is_empty() => Err(Error::field(
            "weight",
            "the weighted objective needs at least one `weight` METRIC=W",
        )),
        Objective::Weighted(w) => {
            for (metric, wt) in w {
                if !wt.is_finite() {
                    return Err(Error::field(
                        "weight",
                        format!("`{metric}={wt}`: the metrics are {}", BenchMetric::keys()),
                    ));
                }
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// The balance objective balances the detector (the electrical imbalance), which needs the
/// bench's electronics valid: their error, with a note saying why, before anything is traced.
fn check_electronics_for(obj: &Objective, doc: &BenchDoc) -> Result<()> {
    if matches!(obj, Objective::Balance { .. }) {
        crate::scene::run::electronics_si(&doc.file.electronics, doc.text(), doc.path()).map_err(
            |e| {
                e.with_note(
                    "the balance objective balances the detector's output through its diodes' \
                     responsivity scales",
                )
            },
        )?;
    }
    Ok(())
}

/// Finds the free variables that minimise the objective (see the module notes).
/// `progress(evaluations done)` is called after each trace.
pub fn search(
    doc: &BenchDoc,
    free: &[Free],
    obj: &Objective,
    o: &AlignOptions,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Search> {
    check_objective(obj)?;
    if free.is_empty() {
        return Err(Error::field("free", "give at least one free variable"));
    }
    for (i, f) in free.iter().enumerate() {
        if f.lo.partial_cmp(&f.hi) != Some(std::cmp::Ordering::Less) {
            return Err(Error::field(
                "free",
                format!("`{}`: LO must be below HI", f.path),
            ));
        }
        if free[..i].iter().any(|g| g.path == f.path) {
            return Err(Error::field("free", format!("`{}` is free twice", f.path)));
        }
    }
    check_electronics_for(obj, doc)?;
    let n = free.len();
    let start_values = check_start(doc, free, false)?;
    let to_x = |u: &[f64]| -> Vec<f64> {
        free.iter()
            .zip(u)
            .map(|(f, &t)| f.lo + t.clamp(0.0, 1.0) * (f.hi - f.lo))
            .collect()
    };
    let u0: Vec<f64> = free
        .iter()
        .zip(&start_values)
        .map(|(f, &v)| (v - f.lo) / (f.hi - f.lo))
        .collect();
    let trace = |x: &[f64], rays: u64| -> Result<Option<Evaluation>> {
        let d = doc.with(&settings(free, x))?;
        // A point where the bench is not valid (e.g. two parts overlapping) is infeasible.
        if d.build().is_err() {
            return Ok(None);
        }
        let so = EvaluateOptions {
            rays,
            seed: o.seed,
            quality: false,
        };
        evaluate_for(obj, &d, settings(free, x), &so).map(Some)
    };
    let (start_rays, max_rays) = o.stage_rays();
    let first = trace(&start_values, start_rays)?
        .ok_or_else(|| Error::input("the starting bench is not valid"))?;
    let mut stop;
    let k_ref = match obj {
        Objective::Power => value(&first.metrics, BenchMetric::KPrime).0,
        _ => value(&first.metrics, BenchMetric::KPlus)
            .0
            .max(value(&first.metrics, BenchMetric::KMinus).0),
    };
    if k_ref.is_nan() || k_ref <= 0.0 {
        return Err(Error::input(
            "the starting bench sends no light to the diodes: align needs a start that detects \
             some light (check the free variables' start values, or trace more rays)",
        ));
    }
    let history: std::cell::RefCell<Vec<Step>> = std::cell::RefCell::new(Vec::new());
    let reference: std::cell::RefCell<Option<(usize, Evaluation)>> = Default::default();
    let evaluate = |u: &[f64], stage: usize, rays: u64| -> Result<(f64, f64)> {
        let x = to_x(u);
        let Some(p) = trace(&x, rays)? else {
            history.borrow_mut().push(Step {
                stage,
                rays,
                values: x,
                objective: f64::INFINITY,
                objective_stderr: f64::NAN,
                imbalance: f64::NAN,
                imbalance_stderr: f64::NAN,
                imbalance_electrical: f64::NAN,
                imbalance_electrical_stderr: f64::NAN,
                k_plus: f64::NAN,
                k_minus: f64::NAN,
            });
            progress(history.borrow().len());
            return Ok((f64::INFINITY, f64::NAN));
        };
        // The stage's first point is the reference of its paired standard errors.
        let mut r = reference.borrow_mut();
        if r.as_ref().is_none_or(|(s, _)| *s != stage) {
            *r = Some((stage, p.clone()));
        }
        let (f, se) = objective(obj, &p, k_ref, r.as_ref().map(|(_, e)| e));
        let (imb, imb_se) = value(&p.metrics, BenchMetric::Imbalance);
        let electrical = p.electrical_imbalance();
        history.borrow_mut().push(Step {
            stage,
            rays,
            values: x,
            objective: f,
            objective_stderr: se,
            imbalance: imb,
            imbalance_stderr: imb_se,
            imbalance_electrical: electrical.as_ref().map_or(f64::NAN, |e| e.value),
            imbalance_electrical_stderr: electrical.as_ref().map_or(f64::NAN, |e| e.stderr()),
            k_plus: value(&p.metrics, BenchMetric::KPlus).0,
            k_minus: value(&p.metrics, BenchMetric::KMinus).0,
        });
        progress(history.borrow().len());
        Ok((if f.is_nan() { f64::INFINITY } else { f }, se))
    };

    let mut best_u = u0.clone();
    let mut step = 0.25;
    let mut rays = start_rays;
    let mut stage = 0;
    loop {
        let stages_left = {
            let mut k = 1;
            let mut r = rays;
            while r < max_rays {
                r = (r * 4).min(max_rays);
                k += 1;
            }
            k
        };
        let used = history.borrow().len();
        let budget = (o.max_evaluations.saturating_sub(used) / stages_left).max(n + 2);
        (best_u, stop) = nelder_mead(&mut |u| evaluate(u, stage, rays), &best_u, step, budget)?;
        if rays >= max_rays || history.borrow().len() >= o.max_evaluations {
            break;
        }
        rays = (rays * 4).min(max_rays);
        step *= 0.5;
        stage += 1;
    }
    Ok(Search {
        start_values,
        best_values: to_x(&best_u),
        history: history.into_inner(),
        stop,
        k_ref,
    })
}

/// The start of a search, checked before anything is traced: both bounds of every free
/// variable must be values the bench accepts (a field's range, checked by the file's own
/// deserialiser), the start must lie within them (with `strict`; otherwise it is moved into
/// them, as a compensator's is), and the starting bench must build; each failure is an input
/// error that names the variable or the field.
pub fn check_start(doc: &BenchDoc, free: &[Free], strict: bool) -> Result<Vec<f64>> {
    let mut start = Vec::with_capacity(free.len());
    for f in free {
        for (end, v) in [("LO", f.lo), ("HI", f.hi)] {
            doc.with(&[(f.path.clone(), v)]).map_err(|e| {
                e.with_note(format!(
                    "`free` {}={}:{}: its {end} bound",
                    f.path, f.lo, f.hi
                ))
            })?;
        }
        let v = doc.get(&f.path)?;
        if strict && !(v >= f.lo && v <= f.hi) {
            return Err(Error::field(
                "free",
                format!(
                    "`{}`: the starting bench has {v}, outside the bounds {}:{} (a rigid-body \
                     move starts at 0)",
                    f.path, f.lo, f.hi
                ),
            ));
        }
        start.push(v.clamp(f.lo, f.hi));
    }
    doc.with(&settings(free, &start))?
        .build()
        .map_err(|e| e.with_note("the starting bench of align is not valid"))?;
    Ok(start)
}

/// Nelder–Mead on the unit box from `u0` with an initial step `step`, at most `budget`
/// evaluations. `f` returns the objective and its standard error; the stage stops when the
/// simplex is smaller than 1e-3 of the box or the objective's spread over the simplex is below
/// the best vertex's standard error (Lagarias et al. 1998 for the steps; the stopping rule is
/// the module's).
fn nelder_mead(
    f: &mut ObjectiveFn,
    u0: &[f64],
    step: f64,
    budget: usize,
) -> Result<(Vec<f64>, SearchStop)> {
    let mut stop = SearchStop::Budget;
    let n = u0.len();
    let clamp = |u: Vec<f64>| -> Vec<f64> { u.into_iter().map(|t| t.clamp(0.0, 1.0)).collect() };
    let mut simplex: Vec<(Vec<f64>, f64)> = Vec::with_capacity(n + 1);
    let mut evals = 0;
    // The standard error of each evaluated point's objective: the noise floor is the best
    // vertex's.
    let mut se_of: Vec<(Vec<f64>, f64)> = Vec::new();
    fn call(
        f: &mut ObjectiveFn,
        u: &[f64],
        evals: &mut usize,
        se_of: &mut Vec<(Vec<f64>, f64)>,
    ) -> Result<f64> {
        *evals += 1;
        let (v, se) = f(u)?;
        se_of.push((u.to_vec(), se));
        Ok(v)
    }
    simplex.push((u0.to_vec(), call(f, u0, &mut evals, &mut se_of)?));
    for i in 0..n {
        let mut u = u0.to_vec();
        // Step toward the interior when the start sits near an edge of the box.
        u[i] = if u[i] + step <= 1.0 {
            u[i] + step
        } else {
            u[i] - step
        };
        let u = clamp(u);
        let v = call(f, &u, &mut evals, &mut se_of)?;
        simplex.push((u, v));
    }
    let order = |s: &mut Vec<(Vec<f64>, f64)>| {
        // Stable: ties keep their order (Lagarias et al.'s rule).
        s.sort_by(|a, b| a.1.total_cmp(&b.1));
    };
    while evals < budget {
        order(&mut simplex);
        let size = simplex[1..]
            .iter()
            .map(|(u, _)| {
                u.iter()
                    .zip(&simplex[0].0)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        let best = simplex[0].1;
        let worst = simplex[n].1;
        let noise = se_of
            .iter()
            .rev()
            .find(|(u, _)| *u == simplex[0].0)
            .map_or(0.0, |(_, se)| if se.is_finite() { *se } else { 0.0 });
        if size < 1e-3 {
            stop = SearchStop::SimplexSize;
            break;
        }
        if worst.is_finite() && worst - best < noise {
            stop = SearchStop::NoiseFloor;
            break;
        }
        let second = simplex[n - 1].1;
        let centroid: Vec<f64> = (0..n)
            .map(|j| simplex[..n].iter().map(|(u, _)| u[j]).sum::<f64>() / n as f64)
            .collect();
        let along = |t: f64| -> Vec<f64> {
            clamp(
                centroid
                    .iter()
                    .zip(&simplex[n].0)
                    .map(|(c, w)| c + t * (c - w))
                    .collect(),
            )
        };
        let r = along(1.0);
        let fr = call(f, &r, &mut evals, &mut se_of)?;
        if fr < best {
            let e = along(2.0);
            let fe = call(f, &e, &mut evals, &mut se_of)?;
            simplex[n] = if fe < fr { (e, fe) } else { (r, fr) };
        } else if fr < second {
            simplex[n] = (r, fr);
        } else {
            let (c, fc) = if fr < worst {
                let c = along(0.5);
                let fc = call(f, &c, &mut evals, &mut se_of)?;
                (c, fc)
            } else {
                let c = along(-0.5);
                let fc = call(f, &c, &mut evals, &mut se_of)?;
                (c, fc)
            };
            if fc < fr.min(worst) {
                simplex[n] = (c, fc);
            } else {
                // Shrink toward the best vertex.
                let b = simplex[0].0.clone();
                for v in simplex.iter_mut().skip(1) {
                    let u: Vec<f64> = v.0.iter().zip(&b).map(|(x, y)| y + 0.5 * (x - y)).collect();
                    let fu = call(f, &u, &mut evals, &mut se_of)?;
                    *v = (u, fu);
                }
            }
        }
    }
    order(&mut simplex);
    Ok((simplex.swap_remove(0).0, stop))
}

#[cfg(test)]
mod tests;
