//! The `fit` job: the bench as built. The free bench variables (misalignments) whose traced
//! model reproduces what a built bench recorded, every frame value of every channel of an
//! `intake` folder ([`measured`]), with the nuisances a lab does not know profiled out
//! ([`model`]); then each variable's standard error, the correlations and the singular values
//! of the Jacobian, the directions the data do not constrain with the range of equally good
//! values along each ([`identify`]), and optionally the compensator moves that rebalance the
//! fitted bench.
//!
//! # Method
//!
//! Levenberg–Marquardt (K. Levenberg, *Q. Appl. Math.* 2, 164–168, 1944; D. W. Marquardt,
//! *J. SIAM* 11, 431–441, 1963) on the whitened residuals, in the free variables scaled to the
//! unit box (a step is projected onto it, so the bounds hold). Every evaluation of one stage
//! traces with the same rays and seed (common random numbers): the misfit is one fixed sample
//! path, and the differences of the Jacobian are paired, their trace noise cancelling ray by
//! ray, except for the rays that cross an edge (a diode's, a pupil's) between the two points.
//! Those make a small step's slope mostly noise, and that noise inflates JᵀJ and shrinks the
//! standard errors; the differences are therefore central, one-sided at a bound, with a step
//! per variable chosen from the trace's own batches so that noise is a small share of each
//! column ([`step`]). The first stage traces a quarter of the rays, from each of up to three
//! coarse starts in distinct valleys ([`start`]); the second, from the lowest first-stage
//! optimum, all of them.
//!
//! At the optimum the fit is identified ([`identify`]), and χ² is set against what a correct
//! model gives ([`chi2`]: the mean from the noise, the spread from the batches and from
//! [`chi2::REPLICAS`] traces on seeds of their own, the larger kept). It goes on from a scanned
//! point (at most [`MAX_RESTARTS`] times) that is clearly better (below by more than the
//! equally good Δχ²) or, when χ² lies above its band's upper edge, from any lower one, all the
//! free variables then scanned on one grid as well ([`identify::joint_grid`]): a χ² the
//! noise does not explain says the optimum is in a valley the frames do not prefer.

pub mod chi2;
pub mod gains;
pub mod identify;
pub mod linalg;
pub mod measured;
pub mod model;
pub mod start;
pub mod step;

use crate::acquisition::{Sequence, patterns_for_ratio};
use crate::error::{Error, Result};
use crate::pipeline::evaluate::{EvaluateOptions, evaluate};
use crate::pipeline::optimise::{AlignOptions, Free, Objective, check_start, search, settings};
use crate::pipeline::{TraceRequest, trace_stage};
use crate::quantities::BenchMetric;
use crate::reconstruction::BitMatrix;
use crate::scene::doc::BenchDoc;

pub use identify::{Identification, Unidentified};
pub use measured::{Measured, read_measured};
pub use model::{NUISANCES, Profiled};

/// The most Levenberg–Marquardt iterations per stage.
pub const MAX_ITERATIONS: usize = 12;

/// What to fit.
#[derive(Debug, Clone)]
pub struct FitRequest {
    pub free: Vec<Free>,
    /// Compensators for the adjustment (empty: none).
    pub adjust: Vec<Free>,
    /// The limit the adjustment must bring |imbalance| under (the electrical imbalance, the
    /// detector's, as the adjustment balances it and as tolerance limits are judged).
    pub imbalance_limit: f64,
    /// The relative tolerance (one standard deviation) to which the lab knows its detector's
    /// channel gains about the common lamp power ([`gains`]); None: the gains are free.
    pub gain_tolerance: Option<f64>,
    pub rays: u64,
    pub seed: u64,
}

/// One evaluated point.
#[derive(Debug, Clone)]
pub struct Point {
    pub values: Vec<f64>,
    pub profiled: Profiled,
}

/// One accepted Levenberg–Marquardt step.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FitStep {
    pub stage: usize,
    pub rays: u64,
    pub values: Vec<f64>,
    pub chi2: f64,
    pub lambda: f64,
}

/// The adjustment of the fitted bench.
#[derive(Debug, Clone)]
pub struct Adjustment {
    pub adjust: Vec<Free>,
    pub values: Vec<f64>,
    /// [before, after]: k₊, k₋ (A/W), the optical imbalance (k₊ − k₋)/(k₊ + k₋) and the
    /// electrical one (s₊k₊ − s₋k₋)/(s₊k₊ + s₋k₋) (NaN for invalid electronics), each with its
    /// standard error.
    pub k_plus: [(f64, f64); 2],
    pub k_minus: [(f64, f64); 2],
    pub imbalance: [(f64, f64); 2],
    pub imbalance_electrical: [(f64, f64); 2],
    pub limit: f64,
    /// |electrical imbalance| after the adjustment is under `limit`.
    pub under_limit: bool,
}

/// A finished fit.
#[derive(Debug, Clone)]
pub struct Fit {
    pub free: Vec<Free>,
    pub rays: u64,
    pub seed: u64,
    pub best: Point,
    pub nominal_chi2: f64,
    /// Rows (the used frame values and the gain prior's) minus free variables minus the linear
    /// parameters.
    pub dof: usize,
    pub values_used: usize,
    pub history: Vec<FitStep>,
    pub identification: Identification,
    /// The nominal scales (V/A) the nuisance scales are relative to.
    pub nominal_scales: [f64; 4],
    /// The gains' prior tolerance ([`FitRequest::gain_tolerance`]).
    pub gain_tolerance: Option<f64>,
    pub adjustment: Option<Adjustment>,
    pub evaluations: usize,
    /// What a correct model's χ² should be at these rays ([`chi2`]).
    pub chi2_expected: chi2::Expected,
    /// The records' slow terms fitted with the nuisances.
    pub slow: model::SlowTerms,
    /// The Monte Carlo variance scale at the optimum ([`model::VarianceScale`]).
    pub variance_scale: model::VarianceScale,
    /// The starts Levenberg–Marquardt ran from ([`start`]), in the order run.
    pub starts: Vec<StartRun>,
}

/// One start of the fit ([`start::coarse_starts`]) and where its first stage ended.
#[derive(Debug, Clone)]
pub struct StartRun {
    /// The start (the variables' values) and its χ² at the first stage's rays.
    pub from: Vec<f64>,
    pub coarse_chi2: f64,
    /// The first stage's optimum from it and its χ² there (the variance scale calibrated at
    /// that point, as every start's is: they compare on one footing).
    pub values: Vec<f64>,
    pub chi2: f64,
    /// Whether the second stage and the fit went on from it (the lowest χ²).
    pub chosen: bool,
}

impl Fit {
    pub fn chi2_per_dof(&self) -> f64 {
        self.best.profiled.chi2 / self.dof.max(1) as f64
    }

    /// The nuisances as reported: scales relative to the nominal electronics, offsets in V.
    pub fn nuisances(&self) -> Vec<(&'static str, f64)> {
        let n = &self.best.profiled.nuisances;
        let s = &self.nominal_scales;
        let rel = [
            n[0] / s[0],
            n[1] / s[1],
            n[2],
            n[3] / s[2],
            n[4],
            n[5] / s[3],
            n[6],
        ];
        NUISANCES.iter().copied().zip(rel).collect()
    }

    pub fn settings(&self) -> Vec<(String, f64)> {
        settings(&self.free, &self.best.values)
    }
}

/// What every evaluation shares: the bench, the measured frames and their patterns.
pub struct Problem<'a> {
    pub doc: &'a BenchDoc,
    pub free: &'a [Free],
    pub measured: &'a Measured,
    pub bits: BitMatrix,
    /// The Monte Carlo variance scale the evaluations use ([`Problem::calibrate`] sets it).
    pub scale: std::cell::Cell<model::VarianceScale>,
    /// Each variable's difference step to try next (unit box, [`step::Rule`]).
    pub steps: std::cell::RefCell<Vec<f64>>,
    /// The detector gains' prior ([`gains`]), or None where they are free.
    pub prior: Option<gains::GainPrior>,
    /// The records' slow terms, fitted with the offsets ([`model::SlowTerms`]).
    pub slow: model::SlowTerms,
}

impl Problem<'_> {
    /// The misfit at `x` (the variables' values) traced with (rays, seed); None when the bench
    /// at `x` does not build.
    pub fn at(&self, x: &[f64], rays: u64, seed: u64) -> Result<Option<Profiled>> {
        let Some(bench) = self.bench_at(x) else {
            return Ok(None);
        };
        let traced = trace_stage(&bench, &TraceRequest::new(rays, seed))?;
        let frames = model::model_frames(
            &traced.transport,
            &self.bits,
            self.measured,
            &self.scale.get(),
        );
        // A bench whose arm sees no light at all cannot be profiled: no better than a bench
        // that does not build.
        Ok(model::profile(&frames, self.measured, self.prior.as_ref(), &self.slow).ok())
    }

    /// The χ² at `x` traced with (rays, seed), infinite where the bench does not build or
    /// cannot be profiled (a scan or a start's comparison then passes over it); `count` after
    /// the trace.
    pub fn chi2_at(
        &self,
        x: &[f64],
        rays: u64,
        seed: u64,
        count: &(dyn Fn() + Sync),
    ) -> Result<f64> {
        let c = self.at(x, rays, seed)?.map_or(f64::INFINITY, |q| q.chi2);
        count();
        Ok(c)
    }

    /// The bench at `x` built, or None.
    fn bench_at(&self, x: &[f64]) -> Option<crate::optics::bench::Bench> {
        self.doc.with(&settings(self.free, x)).ok()?.build().ok()
    }

    /// Traces `x` keeping each batch's frames, sets the Monte Carlo variance scale from them
    /// ([`model::VarianceScale`]: every later evaluation uses it) and returns the misfit at `x`
    /// with that scale and the batches; None when the bench at `x` does not build.
    pub fn calibrate(
        &self,
        x: &[f64],
        rays: u64,
        seed: u64,
    ) -> Result<Option<(Profiled, model::BatchFrames)>> {
        let Some(bench) = self.bench_at(x) else {
            return Ok(None);
        };
        let (traced, batches) = model::batch_frames(&bench, rays, seed, &self.bits, self.measured)?;
        let t = &traced.transport;
        let unit = model::model_frames(
            t,
            &self.bits,
            self.measured,
            &model::VarianceScale::default(),
        );
        let scale = batches.scale(&unit, self.measured);
        self.scale.set(scale);
        let frames = model::model_frames(t, &self.bits, self.measured, &scale);
        Ok(
            model::profile(&frames, self.measured, self.prior.as_ref(), &self.slow)
                .ok()
                .map(|p| (p, batches)),
        )
    }

    pub fn to_values(&self, u: &[f64]) -> Vec<f64> {
        self.free
            .iter()
            .zip(u)
            .map(|(f, t)| f.lo + t.clamp(0.0, 1.0) * (f.hi - f.lo))
            .collect()
    }

    pub fn to_unit(&self, x: &[f64]) -> Vec<f64> {
        self.free
            .iter()
            .zip(x)
            .map(|(f, v)| (v - f.lo) / (f.hi - f.lo))
            .collect()
    }

    /// The misfit at `x` traced with (rays, seed) keeping each batch's frames, and its
    /// residuals' batch deviations ([`step::Sampled`]); None when the bench at `x` does not
    /// build or cannot be profiled.
    pub fn sampled(&self, x: &[f64], rays: u64, seed: u64) -> Result<Option<step::Sampled>> {
        let Some(bench) = self.bench_at(x) else {
            return Ok(None);
        };
        let (traced, batches) = model::batch_frames(&bench, rays, seed, &self.bits, self.measured)?;
        let frames = model::model_frames(
            &traced.transport,
            &self.bits,
            self.measured,
            &self.scale.get(),
        );
        let Ok(prof) = model::profile(&frames, self.measured, self.prior.as_ref(), &self.slow)
        else {
            return Ok(None);
        };
        Ok(Some(step::Sampled {
            deviations: residual_deviations(self.measured, &prof, &batches),
            values: prof.residuals,
            factor: batches.factor,
        }))
    }

    /// The Jacobian of the whitened residuals in the unit box at `u` (columns: one per free
    /// variable, rows: residuals), by paired central differences whose step each variable's
    /// rule chooses from the trace's own batches ([`step`]; one-sided at a bound). The steps
    /// carry over to the next call. `count` after each trace.
    pub fn jacobian(
        &self,
        u: &[f64],
        rays: u64,
        seed: u64,
        count: &(dyn Fn() + Sync),
    ) -> Result<Jacobian> {
        let mut cols = Vec::with_capacity(u.len());
        let mut variance = Vec::with_capacity(u.len());
        let mut steps = Vec::with_capacity(u.len());
        let mut shares = Vec::with_capacity(u.len());
        for i in 0..u.len() {
            let mut f = |t: f64| -> Result<step::Sampled> {
                let mut v = u.to_vec();
                v[i] = t;
                let x = self.to_values(&v);
                let s = self.sampled(&x, rays, seed)?;
                count();
                s.ok_or_else(|| {
                    Error::input(format!(
                        "the bench does not build at {} = {} (a difference step of the fit): \
                         narrow its bounds",
                        self.free[i].path, x[i]
                    ))
                })
            };
            let h = self.steps.borrow()[i];
            let (c, next) = step::column(&mut f, u[i], h, &step::RULE)?;
            self.steps.borrow_mut()[i] = next;
            steps.push(c.step);
            shares.push(c.noise_share);
            variance.push(c.variance);
            cols.push(c.slope);
        }
        Ok(Jacobian {
            cols,
            variance,
            steps,
            noise_share: shares,
        })
    }
}

/// The Jacobian of the whitened residuals (unit box) and what its differences measured.
#[derive(Debug, Clone)]
pub struct Jacobian {
    /// One column per free variable.
    pub cols: Vec<Vec<f64>>,
    /// Each entry's variance from the trace's batches.
    pub variance: Vec<Vec<f64>>,
    /// Each column's step (unit box) and the noise's share of its squared norm.
    pub steps: Vec<f64>,
    pub noise_share: Vec<f64>,
}

/// Each batch's deviation of the whitened residuals: the batch's frame light less its share,
/// through the channel's fitted scales, over the residual's σ (the sign of −model dropped: only
/// differences and squares of these are used), in the residuals' order.
pub fn residual_deviations(
    measured: &Measured,
    prof: &Profiled,
    batches: &model::BatchFrames,
) -> Vec<Vec<f64>> {
    let nu = &prof.nuisances;
    // Scales per channel [RF, MON+, MON−] on [u₊, u₋].
    let scale = [[nu[0], -nu[1]], [nu[3], 0.0], [0.0, nu[5]]];
    batches
        .deviations
        .iter()
        .map(|dev| {
            let mut out = Vec::with_capacity(prof.residuals.len());
            let mut flat = 0;
            for (s, q) in measured.sequences.iter().enumerate() {
                for f in 0..q.values.len() {
                    if !q.flagged[f] {
                        for (o, sc) in scale.iter().enumerate() {
                            let d = sc[0] * dev[flat][0] + sc[1] * dev[flat][1];
                            out.push(d / prof.sigma_v[s][f][o]);
                        }
                    }
                    flat += 1;
                }
            }
            // The prior's rows carry no trace noise before the profiling.
            out.extend(std::iter::repeat_n(0.0, prof.prior_rows));
            out
        })
        .collect()
}

/// The measured folder against the bench: units, base patterns and each sequence's frames
/// (their SHA-256); the base patterns the bench shows.
pub fn check_measured(doc: &BenchDoc, measured: &Measured) -> Result<BitMatrix> {
    let scene = doc.run_scene()?;
    let (w, h) = scene.bench.units_shape();
    let m_max = scene
        .settings
        .sampling_ratios
        .iter()
        .map(|&r| patterns_for_ratio(r, w * h))
        .max()
        .unwrap_or(1);
    let sp = measured.dir.join("summary.json");
    if (w, h) != measured.units || m_max != measured.base_patterns {
        return Err(Error::input(format!(
            "measured with {} × {} units and {} base patterns, the bench shows {w} × {h} and \
             {m_max}: a measured folder from another bench or sequence",
            measured.units.0, measured.units.1, measured.base_patterns
        ))
        .in_file(&sp));
    }
    let set = scene.settings.patterns.build(w, h, m_max)?;
    let bits = set.base_patterns().into_owned();
    for q in &measured.sequences {
        let sha = crate::provenance::sha256_hex(&model::packed_rows(&bits, q.sequence));
        if sha != q.patterns_sha256 {
            return Err(Error::input(format!(
                "the {} record's patterns (SHA-256 {}…) are not the frames this bench shows \
                 ({}…): a measured folder from another sequence or bench",
                q.sequence.key(),
                &q.patterns_sha256[..q.patterns_sha256.len().min(12)],
                &sha[..12]
            ))
            .in_file(&sp));
        }
    }
    if !measured
        .sequences
        .iter()
        .any(|q| q.sequence == Sequence::CalibratedBase)
    {
        return Err(Error::input("no calibrated_base record").in_file(&sp));
    }
    Ok(bits)
}

/// Fits the free variables to the measured frames (module notes), identifies them, and with
/// compensators adjusts the fitted bench. `progress(evaluations)` after each trace.
pub fn fit(
    doc: &BenchDoc,
    measured: &Measured,
    req: &FitRequest,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Fit> {
    if req.free.is_empty() {
        return Err(Error::field("free", "give at least one free variable"));
    }
    let start = check_start(doc, &req.free, true)?;
    if !req.adjust.is_empty() {
        check_start(doc, &req.adjust, true)
            .map_err(|e| e.with_note("the adjustment's compensators"))?;
    }
    let bits = check_measured(doc, measured)?;
    let scene = doc.run_scene()?;
    let nominal_scales = model::nominal_scales(&scene.detector);
    let p = Problem {
        doc,
        free: &req.free,
        measured,
        bits,
        scale: std::cell::Cell::new(model::VarianceScale::default()),
        steps: std::cell::RefCell::new(vec![step::RULE.first; req.free.len()]),
        prior: req.gain_tolerance.map(|tolerance| gains::GainPrior {
            nominal: nominal_scales,
            tolerance,
        }),
        slow: model::SlowTerms::of(&scene.settings.drift),
    };
    let rays = req.rays.max(2 * crate::trace::RAYS_PER_BATCH);
    let stages = [(rays / 4).max(2 * crate::trace::RAYS_PER_BATCH), rays];
    let evals = std::sync::atomic::AtomicUsize::new(0);
    let count = || {
        let n = evals.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(n);
    };
    let (nominal, _) = p.calibrate(&start, rays, req.seed)?.ok_or_else(|| {
        Error::input(
            "the nominal bench does not build, or its frames do not separate the light from \
                 the offsets (an arm without light)",
        )
    })?;
    count();
    let (mut u, mut history, starts) =
        multi_start(&p, p.to_unit(&start), stages, req.seed, &count)?;
    let mut restarts = 0;
    let (u, best_prof, identification, chi2_expected) = loop {
        let x = p.to_values(&u);
        let (prof, batches) = p
            .calibrate(&x, rays, req.seed)?
            .ok_or_else(|| Error::input("the fitted bench does not build"))?;
        count();
        let dof = prof.dof(req.free.len());
        let jacobian = p.jacobian(&u, rays, req.seed, &count)?;
        let jac = &jacobian.cols;
        let chi2_dof = prof.chi2 / dof.max(1) as f64;
        let replicas = replica_chi2(&p, &x, rays, req.seed, &count)?;
        let expected = chi2::expected(&p, &prof, jac, &batches).with_replicas(&replicas);
        let at = identify::At {
            chi2: prof.chi2,
            chi2_dof,
            chi2_sd: expected.sd,
        };
        let mut id = identify::identify(
            &p, &u, &jacobian, &prof, &batches, at, rays, req.seed, &count,
        )?;
        let above = prof.chi2 > expected.upper();
        let (next, joint) = go_on_from(&p, &u, &id, at, above, rays, req.seed, &count)?;
        match next {
            Some(x) if restarts < MAX_RESTARTS => {
                restarts += 1;
                let stage = stages.len();
                u = levenberg_marquardt(
                    &p,
                    p.to_unit(&x),
                    rays,
                    req.seed,
                    stage,
                    &mut history,
                    &count,
                )?;
            }
            _ => {
                if joint.is_some() {
                    id.grid = joint;
                }
                break (u, prof, id, expected);
            }
        }
    };
    let x = p.to_values(&u);
    let n_used = best_prof.residuals.len() - best_prof.prior_rows;
    let dof = best_prof.dof(req.free.len());
    let best = Point {
        values: x,
        profiled: best_prof,
    };
    let fitted_doc = doc.with(&settings(&req.free, &best.values))?;
    let adjustment = if req.adjust.is_empty() {
        None
    } else {
        Some(adjust(&fitted_doc, req, &count)?)
    };
    Ok(Fit {
        free: req.free.clone(),
        rays,
        seed: req.seed,
        nominal_chi2: nominal.chi2,
        dof,
        values_used: n_used,
        history,
        identification,
        nominal_scales,
        gain_tolerance: req.gain_tolerance,
        adjustment,
        best,
        evaluations: evals.load(std::sync::atomic::Ordering::Relaxed),
        chi2_expected,
        slow: p.slow.clone(),
        variance_scale: p.scale.get(),
        starts,
    })
}

pub use start::COARSE_POINTS;

/// The coarse starts from `u` ([`start`]) at (rays, seed), best first.
fn coarse_start(
    p: &Problem,
    u: Vec<f64>,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<Vec<start::Scored>> {
    let mut chi2 = |v: &[f64]| p.chi2_at(&p.to_values(v), rays, seed, count);
    start::coarse_starts(&mut chi2, u, start::MAX_STARTS)
}

/// The first stage of Levenberg–Marquardt (`stages[0]` rays) from each coarse start
/// ([`start::best_of_starts`]), each with its own difference steps from the rule's first; the
/// second stage (all the rays) from the lowest first-stage optimum. Returns that optimum, the
/// chosen start's accepted steps and every start's record.
fn multi_start(
    p: &Problem,
    u0: Vec<f64>,
    stages: [u64; 2],
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<(Vec<f64>, Vec<FitStep>, Vec<StartRun>)> {
    // The variance scale of the nominal bench's calibration (the caller's): the starts' ends
    // are compared under it, not each under its own, whose batch estimate differs by noise.
    let scale = p.scale.get();
    let starts = coarse_start(p, u0, stages[0], seed, count)?;
    let mut runs: Vec<(Vec<FitStep>, Vec<f64>)> = Vec::with_capacity(starts.len());
    let mut local = |u: Vec<f64>| -> Result<start::Scored> {
        *p.steps.borrow_mut() = vec![step::RULE.first; u.len()];
        let mut history = Vec::new();
        p.calibrate(&p.to_values(&u), stages[0], seed)?;
        count();
        let u = levenberg_marquardt(p, u, stages[0], seed, 0, &mut history, count)?;
        p.scale.set(scale);
        let c = selection_chi2(p, &u, stages[0], seed, count)?;
        runs.push((history, p.steps.borrow().clone()));
        Ok((u, c))
    };
    let (best, ends) = start::best_of_starts(&starts, &mut local)?;
    let (mut history, steps) = runs.swap_remove(best);
    *p.steps.borrow_mut() = steps;
    let mut u = ends[best].0.clone();
    p.calibrate(&p.to_values(&u), stages[1], seed)?;
    count();
    u = levenberg_marquardt(p, u, stages[1], seed, 1, &mut history, count)?;
    let record = starts
        .iter()
        .zip(&ends)
        .enumerate()
        .map(|(k, (s, e))| StartRun {
            from: p.to_values(&s.0),
            coarse_chi2: s.1,
            values: p.to_values(&e.0),
            chi2: e.1,
            chosen: k == best,
        })
        .collect();
    Ok((u, history, record))
}

/// Where the fit goes on from after identifying the optimum `u`, and the joint grid it traced
/// to decide. A scan that found a clearly better point: the optimum was local. A χ² above its
/// sampling band (`above`) says the same of any lower point, every free variable then scanned
/// jointly too ([`identify::joint_grid`]); where none is lower, or no restart is left, that
/// grid gives the ranges.
#[allow(clippy::too_many_arguments)]
fn go_on_from(
    p: &Problem,
    u: &[f64],
    id: &Identification,
    at: identify::At,
    above: bool,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<(Option<Vec<f64>>, Option<identify::GridScan>)> {
    if let Some(x) = id.better_point() {
        return Ok((Some(x), None));
    }
    if !above {
        return Ok((None, None));
    }
    let joint = identify::joint_grid(p, u, id, at, rays, seed, count)?;
    Ok((id.lowest_below(joint.as_ref()), joint))
}

/// χ² at `x` on [`chi2::REPLICAS`] traces of seeds of their own, each as the fit computes its
/// own: the variance scale calibrated on that trace ([`Problem::calibrate`]), so that their
/// spread is the sampling spread of the χ² the fit reports, weights' estimate included. The
/// fit's own scale is kept.
fn replica_chi2(
    p: &Problem,
    x: &[f64],
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<Vec<f64>> {
    let kept = p.scale.get();
    let out = (0..chi2::REPLICAS)
        .map(|k| {
            let s = seed.wrapping_add(chi2::REPLICA_SEED_BASE + k);
            let c = p
                .calibrate(x, rays, s)?
                .map_or(f64::INFINITY, |(q, _)| q.chi2);
            count();
            Ok(c)
        })
        .collect();
    p.scale.set(kept);
    out
}

/// The most times the fit goes on from a better scanned point than its optimum
/// ([`identify::Identification::better_point`], [`identify::joint_grid`]).
pub const MAX_RESTARTS: usize = 2;

/// Independent traces a start's end is judged by ([`selection_chi2`]).
pub const SELECTION_SEEDS: u64 = 3;

/// The mean χ² at `u` over [`SELECTION_SEEDS`] traces on seeds of their own (infinite where
/// the bench does not build). Each start's optimum was found on the fit's common random
/// numbers, whose noise has one realisation at each point: a valley whose realisation happens
/// to lie low would win against a deeper one by the noise of one trace (the χ² of one trace
/// scatters by hundreds on a frame set of a few thousand values where the rays are few), so
/// the valleys are compared on fresh traces, their mean's scatter smaller by √3.
fn selection_chi2(
    p: &Problem,
    u: &[f64],
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<f64> {
    let x = p.to_values(u);
    let mut sum = 0.0;
    for k in 0..SELECTION_SEEDS {
        let s = seed.wrapping_add(SELECTION_SEED_BASE + k);
        sum += p.chi2_at(&x, rays, s, count)?;
    }
    Ok(sum / SELECTION_SEEDS as f64)
}

/// Added to the fit's seed for the selection traces: far from any seed a user counts through.
const SELECTION_SEED_BASE: u64 = 0x5e1e_c700_0000;

/// One stage of Levenberg–Marquardt from `u` (module notes); returns the stage's optimum.
fn levenberg_marquardt(
    p: &Problem,
    mut u: Vec<f64>,
    rays: u64,
    seed: u64,
    stage: usize,
    history: &mut Vec<FitStep>,
    count: &(dyn Fn() + Sync),
) -> Result<Vec<f64>> {
    let n = u.len();
    let mut cur = p
        .at(&p.to_values(&u), rays, seed)?
        .ok_or_else(|| Error::input("the fit's starting bench does not build"))?;
    count();
    let mut lambda = 1e-3;
    for _ in 0..MAX_ITERATIONS {
        let jac = p.jacobian(&u, rays, seed, count)?.cols;
        let a: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| dot(&jac[i], &jac[j])).collect())
            .collect();
        let g: Vec<f64> = (0..n).map(|i| -dot(&jac[i], &cur.residuals)).collect();
        let mut improved = false;
        for _try in 0..6 {
            let mut m = a.clone();
            for (i, row) in m.iter_mut().enumerate() {
                row[i] += lambda * a[i][i].max(1e-12) + 1e-12;
            }
            let Some(delta) = linalg::solve(m, g.clone()) else {
                lambda *= 10.0;
                continue;
            };
            let trial: Vec<f64> = u
                .iter()
                .zip(&delta)
                .map(|(a, d)| (a + d).clamp(0.0, 1.0))
                .collect();
            let step: f64 = trial.iter().zip(&u).map(|(a, b)| (a - b).abs()).sum();
            if step < 1e-6 {
                break;
            }
            let next = p.at(&p.to_values(&trial), rays, seed)?;
            count();
            match next {
                Some(q) if q.chi2 < cur.chi2 => {
                    let gain = (cur.chi2 - q.chi2) / cur.chi2.max(f64::MIN_POSITIVE);
                    u = trial;
                    cur = q;
                    lambda = (lambda / 3.0).max(1e-7);
                    history.push(FitStep {
                        stage,
                        rays,
                        values: p.to_values(&u),
                        chi2: cur.chi2,
                        lambda,
                    });
                    improved = gain > 1e-4 && step > 1e-4;
                    break;
                }
                _ => lambda *= 4.0,
            }
        }
        if !improved {
            break;
        }
    }
    Ok(u)
}

pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The compensators that rebalance the fitted bench (the optimiser's balance objective: the
/// detector's electrical imbalance, the diodes' responsivity scales included), and its k±,
/// optical and electrical imbalance before and after on one seed.
fn adjust(fitted: &BenchDoc, req: &FitRequest, count: &(dyn Fn() + Sync)) -> Result<Adjustment> {
    let o = AlignOptions {
        start_rays: (req.rays / 4).max(2 * crate::trace::RAYS_PER_BATCH),
        max_rays: req.rays,
        seed: req.seed,
        max_evaluations: 40 * req.adjust.len().max(1),
    };
    let s = search(fitted, &req.adjust, &Objective::BALANCE, &o, &|_| count())?;
    let eo = EvaluateOptions {
        rays: req.rays,
        seed: req.seed,
        quality: false,
    };
    let before = evaluate(fitted, Vec::new(), &eo)?;
    let set = settings(&req.adjust, &s.best_values);
    let after = evaluate(&fitted.with(&set)?, set, &eo)?;
    let pick =
        |m: BenchMetric| [&before, &after].map(|e| (e.metrics[m].value, e.metrics[m].stderr()));
    let electrical = [&before, &after].map(|e| {
        e.electrical_imbalance()
            .map_or((f64::NAN, f64::NAN), |i| (i.value, i.stderr()))
    });
    Ok(Adjustment {
        adjust: req.adjust.clone(),
        values: s.best_values,
        k_plus: pick(BenchMetric::KPlus),
        k_minus: pick(BenchMetric::KMinus),
        imbalance: pick(BenchMetric::Imbalance),
        imbalance_electrical: electrical,
        limit: req.imbalance_limit,
        under_limit: electrical[1].0.abs() < req.imbalance_limit,
    })
}

#[cfg(test)]
mod tests;
