//! The paper's idealised simulations: an [`Experiment`] in, scored reconstructions out.
//!
//! Every cell of objects × sampling ratios × cases is acquired with the scalar-gain model of the
//! paper's Eqs. (6)–(11), reconstructed by the experiment's [`Solver`] (TVAL3 and its 0/1 handling), brought to the ground truth's scale by the
//! one normalisation rule of [`crate::metrics::normalize_to_truth`], and scored with PSNR and
//! MSSIM. No files are touched here; `cli::simulate` writes the outputs.
//!
//! Determinism: the patterns of a cell depend only on the experiment's pattern seed and the
//! ratio (the set for a lower ratio is a prefix of the set for a higher one, as in the TVAL3
//! reference problems), and the noise of cell c comes from stream c of the experiment seed, so
//! cells can run in parallel and the results do not depend on the number of threads.

use rayon::prelude::*;
use serde::Serialize;

use crate::acquisition::{self, NoiseDistribution, PatternSet, Scheme, patterns_for_ratio};
use crate::error::Result;
use crate::metrics;
use crate::objects;
use crate::raster::Raster;
use crate::reconstruction::tval3::StopReason;
use crate::reconstruction::{PatternForm, Solver, ZeroOneHandling};
use crate::scene::experiment::{CurveSpec, CurveX, Experiment, Metric, PatternsSpec};

/// One simulated, reconstructed and scored cell. Keys are documented for summary.json.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// Object name from the experiment file.
    pub object: String,
    /// Case label from the experiment file.
    pub case: String,
    /// Acquisition scheme.
    pub scheme: Scheme,
    /// Sampling ratio M/N.
    pub ratio: f64,
    /// Base patterns M.
    pub measurements: usize,
    /// Arm gains (dimensionless) and offsets (object units). In summary.json they are
    /// `gain_plus`, `gain_minus`, `offset_plus_object`, `offset_minus_object`: the traced
    /// commands' `k_plus` is in A/W and `b_plus` in A, and one key never carries two units
    /// (docs/outputs.md).
    #[serde(rename = "gain_plus")]
    pub k_plus: f64,
    #[serde(rename = "gain_minus")]
    pub k_minus: f64,
    #[serde(rename = "offset_plus_object")]
    pub b_plus: f64,
    #[serde(rename = "offset_minus_object")]
    pub b_minus: f64,
    /// k' = k₊ + k₋ (`gain_prime`).
    #[serde(rename = "gain_prime")]
    pub k_prime: f64,
    /// Additive noise distribution, if any.
    pub noise: Option<NoiseDistribution>,
    /// Standard deviation of one noise draw (object units), 0 without noise.
    #[serde(rename = "noise_std_object")]
    pub noise_std: f64,
    /// PSNR after normalisation, dB (peak 255).
    pub psnr_db: f64,
    /// Mean SSIM (Wang et al. 2004) after normalisation.
    pub mssim: f64,
    /// Gain and offset of the normalisation (reconstruction → truth).
    pub normalization_gain: f64,
    pub normalization_offset: f64,
    /// Solver iterations and operator applications (forward + adjoint).
    pub iterations: usize,
    pub operator_applications: usize,
    /// How the 0/1 system was solved (traditional cells only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub zero_one_handling: Option<ZeroOneHandling>,
    /// Whether TVAL3 met its outer tolerance (`stop` is `Tolerance`).
    pub converged: bool,
    /// Why TVAL3 stopped: `Tolerance`, `MaxOuter` (inner-loop cap) or `MaxIterations`.
    pub stop: StopReason,
    /// ‖A u − y‖ / ‖y‖ of the raw reconstruction.
    pub relative_residual: f64,
    /// Solver CPU time, s: a timing, written to timings.json and kept out of the deterministic
    /// outputs.
    #[serde(skip)]
    pub solver_time_s: f64,
    /// DMD frames shown, detector samples recorded, and acquisition time at the DMD rate, s.
    pub dmd_frames: usize,
    pub detector_samples: usize,
    pub acquisition_time_s: f64,
}

/// The result of an experiment: the cells in a fixed order (object, ratio, case — case
/// fastest), the normalised reconstruction of each cell, and the ground truth of each object.
#[derive(Debug, Clone)]
pub struct SimulationOutput {
    pub cells: Vec<Cell>,
    pub reconstructions: Vec<Raster>,
    pub truths: Vec<Raster>,
}

/// Runs every cell. `progress(done, total)` is called as cells finish (from any thread).
pub fn run(exp: &Experiment, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<SimulationOutput> {
    let n = exp.width * exp.height;
    let truths: Vec<Raster> = exp
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| {
            objects::render_object(&o.object, exp.width, exp.height, &exp.base_dir)
                .map_err(|e| e.within(&format!("objects[{i}].object")))
        })
        .collect::<Result<_>>()?;

    // One pattern set at the largest ratio; smaller ratios use its first rows.
    let max_m = exp
        .sampling_ratios
        .iter()
        .map(|&r| patterns_for_ratio(r, n))
        .max()
        .unwrap_or(1);
    let full: PatternSet = match &exp.patterns {
        PatternsSpec::Random { seed } => {
            acquisition::random_set(exp.width, exp.height, max_m, *seed)?
        }
        PatternsSpec::Hadamard { ordering } => {
            acquisition::hadamard_set(exp.width, *ordering, max_m)?
        }
    };
    let sets: Vec<PatternSet> = exp
        .sampling_ratios
        .iter()
        .map(|&r| full.head(patterns_for_ratio(r, n)))
        .collect::<Result<_>>()?;

    let (n_obj, n_ratio, n_case) = (
        exp.objects.len(),
        exp.sampling_ratios.len(),
        exp.cases.len(),
    );
    let total = n_obj * n_ratio * n_case;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<Result<(Cell, Raster)>> = (0..total)
        .into_par_iter()
        .map(|idx| {
            let (o, rest) = (idx / (n_ratio * n_case), idx % (n_ratio * n_case));
            let (r, c) = (rest / n_case, rest % n_case);
            let out = run_cell(exp, &truths[o], &sets[r], o, r, c, idx as u64);
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(d, total);
            out
        })
        .collect();
    let (cells, reconstructions) = crate::error::in_order(results)?.into_iter().unzip();
    Ok(SimulationOutput {
        cells,
        reconstructions,
        truths,
    })
}

fn run_cell(
    exp: &Experiment,
    truth: &Raster,
    patterns: &PatternSet,
    o: usize,
    r: usize,
    c: usize,
    cell_index: u64,
) -> Result<(Cell, Raster)> {
    let case = &exp.cases[c];
    let seed = crate::rng::mix64(exp.seed ^ crate::rng::mix64(cell_index));
    let acq = acquisition::acquire(
        case.scheme,
        &truth.data,
        patterns,
        &case.arms,
        case.noise.as_ref(),
        seed,
        exp.dmd_rate_hz,
    )?;
    let zero_one = case.scheme.zero_one().unwrap_or(exp.zero_one);
    let solver = Solver::new(exp.solver.clone(), zero_one);
    let form = case.scheme.form();
    let sol = solver.solve(acq.operator.as_ref(), &acq.y, exp.width, exp.height, form)?;
    let norm = metrics::normalize_to_truth(&sol.image, truth)?;
    let psnr_db = metrics::psnr(truth, &norm.image, metrics::PEAK_255);
    let mssim = metrics::mssim(truth, &norm.image)?;
    let a = case.arms;
    let cell = Cell {
        object: exp.objects[o].name.clone(),
        case: case.label.clone(),
        scheme: case.scheme,
        ratio: exp.sampling_ratios[r],
        measurements: acq.measurements,
        k_plus: a.k_plus,
        k_minus: a.k_minus,
        b_plus: a.b_plus,
        b_minus: a.b_minus,
        k_prime: a.k_plus + a.k_minus,
        noise: case.noise.map(|n| n.distribution),
        noise_std: case.noise.map_or(0.0, |n| n.std),
        psnr_db,
        mssim,
        normalization_gain: norm.gain,
        normalization_offset: norm.offset,
        iterations: sol.iterations,
        operator_applications: sol.forward_applications + sol.adjoint_applications,
        zero_one_handling: (form == PatternForm::ZeroOne).then_some(zero_one),
        converged: sol.converged,
        stop: sol.stop,
        relative_residual: sol.relative_residual,
        solver_time_s: sol.cpu_time_s,
        dmd_frames: acq.dmd_frames,
        detector_samples: acq.detector_samples,
        acquisition_time_s: acq.acquisition_time_s,
    };
    Ok((cell, norm.image))
}

/// One point of a curve: mean and sample standard deviation over the objects.
#[derive(Debug, Clone, Serialize)]
pub struct CurvePoint {
    pub x: f64,
    pub mean: f64,
    pub std: f64,
    pub count: usize,
}

/// One series of a curve (one scheme).
#[derive(Debug, Clone, Serialize)]
pub struct CurveSeries {
    pub scheme: Scheme,
    pub points: Vec<CurvePoint>,
}

/// Tolerance when matching a curve filter (`at_ratio`, `at_k_prime`) to a cell's value.
const MATCH_TOL: f64 = 1e-9;

/// The series of a curve: cells filtered by the spec, grouped by scheme and x, in the order in
/// which schemes and x values first appear among the cells.
pub fn curve(spec: &CurveSpec, cells: &[Cell]) -> Vec<CurveSeries> {
    let keep = |c: &&Cell| {
        spec.at_ratio
            .is_none_or(|r| (c.ratio - r).abs() < MATCH_TOL)
            && spec
                .at_k_prime
                .is_none_or(|k| (c.k_prime - k).abs() < MATCH_TOL)
    };
    let x_of = |c: &Cell| match spec.x {
        CurveX::Ratio => c.ratio,
        CurveX::KPrime => c.k_prime,
    };
    let y_of = |c: &Cell| match spec.metric {
        Metric::Psnr => c.psnr_db,
        Metric::Mssim => c.mssim,
    };
    // Per scheme, the metric values collected at each x.
    type Samples = Vec<(f64, Vec<f64>)>;
    let mut series: Vec<(Scheme, Samples)> = Vec::new();
    for c in cells.iter().filter(keep) {
        let s = match series.iter_mut().position(|(s, _)| *s == c.scheme) {
            Some(i) => &mut series[i].1,
            None => {
                series.push((c.scheme, Vec::new()));
                &mut series.last_mut().expect("just pushed").1
            }
        };
        let x = x_of(c);
        match s.iter_mut().find(|(px, _)| (*px - x).abs() < MATCH_TOL) {
            Some((_, ys)) => ys.push(y_of(c)),
            None => s.push((x, vec![y_of(c)])),
        }
    }
    series
        .into_iter()
        .map(|(scheme, pts)| {
            let mut points: Vec<CurvePoint> = pts
                .into_iter()
                .map(|(x, ys)| {
                    let n = ys.len() as f64;
                    let mean = ys.iter().sum::<f64>() / n;
                    let var = if ys.len() > 1 {
                        ys.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / (n - 1.0)
                    } else {
                        0.0
                    };
                    CurvePoint {
                        x,
                        mean,
                        std: var.sqrt(),
                        count: ys.len(),
                    }
                })
                .collect();
            points.sort_by(|a, b| a.x.total_cmp(&b.x));
            CurveSeries { scheme, points }
        })
        .collect()
}
