//! The solve stage: each scheme's measurements from the records, reconstructed, scored, and read
//! for USAF resolution.

use rayon::prelude::*;
use serde::Serialize;

use super::{Progress, Recorded, Stage};
use crate::acquisition::{PatternSet, Scheme, patterns_for_ratio};
use crate::error::Result;
use crate::metrics;
use crate::metrics::resolution::{
    ChartToImage, ResolutionOptions, read_resolution, read_resolution_against,
};
use crate::objects::usaf::UsafChart;
use crate::raster::Raster;
use crate::reconstruction::Solver;

/// A resolved USAF element and its spatial frequency on the chart.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Resolved {
    pub group: i32,
    pub element: u8,
    pub lp_per_mm: f64,
}

/// How reconstructions of a USAF chart are read for resolution: the chart, the map from chart
/// millimetres to unit coordinates found by registering the ideal object x against the chart,
/// and what x itself resolves (the limit set by the optics and the unit size).
#[derive(Debug, Clone, Serialize)]
pub struct ResolutionContext {
    #[serde(skip)]
    pub chart: UsafChart,
    #[serde(skip)]
    pub map: ChartToImage,
    /// Chart mm → unit pixel coordinates: (col, row) = m·(x, y) + t, with m in pixels per mm
    /// (summary key `chart_to_pixel_matrix_px_per_mm`, rows of m) and t in pixels
    /// (`chart_to_pixel_offset_px`). The keys say the units: `map_m` read as metres.
    #[serde(rename = "chart_to_pixel_matrix_px_per_mm")]
    pub map_m: [[f64; 2]; 2],
    #[serde(rename = "chart_to_pixel_offset_px")]
    pub map_t: [f64; 2],
    /// Pearson correlation of x with the chart through `map` (the read-out is skipped below
    /// [`MIN_REGISTRATION_CORRELATION`]).
    pub registration_correlation: f64,
    pub criterion: &'static str,
    pub threshold: f64,
    /// What the ideal object x resolves.
    pub ideal_finest_resolved: Option<Resolved>,
}

/// Below this correlation the registration is not trusted and no resolution is reported.
pub const MIN_REGISTRATION_CORRELATION: f64 = 0.8;

/// Registers x against the bench's USAF chart (if it has one) for the resolution read-out.
///
/// Geometric guess: the chart point that the imaging lens puts on the pattern centre, taking
/// the paper's 1:1 imaging (m = −1) about the optical axis (the bench z axis), and one unit =
/// pitch · mirrors per unit on the chart. The registration then refines orientation, scale
/// (±12 %) and offset (±4 units) against x itself.
pub fn resolution_context(
    bench: &crate::optics::Bench,
    x: &Raster,
) -> Result<Option<ResolutionContext>> {
    let (Some(plate), Some(dmd)) = (bench.charts().first(), bench.dmd()) else {
        return Ok(None);
    };
    let crate::optics::chart::ChartMask::Usaf(chart) = &plate.mask else {
        return Ok(None);
    };
    let d = &dmd.dmd;
    let pa = &d.pattern;
    let mpu = pa.mirrors_per_unit as f64;
    // Pattern centre on the DMD (m, bench frame: columns along +x, rows along −y).
    let dx =
        (pa.col0 as f64 + pa.units_across as f64 * mpu / 2.0 - d.columns as f64 / 2.0) * d.pitch;
    let dy = -(pa.row0 as f64 + pa.units_down as f64 * mpu / 2.0 - d.rows as f64 / 2.0) * d.pitch;
    let f = &plate.frame;
    if f.w.z.abs() < 1e-6 {
        return Ok(None);
    }
    // The chart point on the line through (−dx, −dy) parallel to the axis.
    let base = glam::DVec3::new(-dx, -dy, 0.0);
    let t = (f.origin - base).dot(f.w) / f.w.z;
    let local = f.to_local(base + glam::DVec3::new(0.0, 0.0, t));
    let center_mm = [local.x * 1e3, local.y * 1e3];
    let pixels_per_mm = 1.0 / (d.pitch * mpu * 1e3);
    let reg = metrics::registration::register_chart(x, chart, center_mm, pixels_per_mm, 4.0)?;
    if reg.correlation.is_nan() || reg.correlation < MIN_REGISTRATION_CORRELATION {
        return Ok(None);
    }
    let options = ResolutionOptions::default();
    let ideal = finest(x, chart, &reg.map, &options)?;
    Ok(Some(ResolutionContext {
        chart: chart.clone(),
        map: reg.map,
        map_m: reg.map.m,
        map_t: reg.map.t,
        registration_correlation: reg.correlation,
        criterion: metrics::resolution::CRITERION,
        threshold: options.threshold,
        ideal_finest_resolved: ideal,
    }))
}

/// The finest element resolved in `image`.
fn finest(
    image: &Raster,
    chart: &UsafChart,
    map: &ChartToImage,
    options: &ResolutionOptions,
) -> Result<Option<Resolved>> {
    let r = read_resolution(image, chart, map, options)?;
    Ok(resolved_of(&r))
}

/// The finest element resolved in `image` with its noise known from `residual`.
fn finest_against(
    image: &Raster,
    residual: Option<&Raster>,
    chart: &UsafChart,
    map: &ChartToImage,
) -> Result<Option<Resolved>> {
    let options = ResolutionOptions::default();
    let r = read_resolution_against(image, residual, chart, map, &options)?;
    Ok(resolved_of(&r))
}

fn resolved_of(r: &metrics::resolution::ResolutionReadout) -> Option<Resolved> {
    r.finest_resolved.map(|e| Resolved {
        group: e.group,
        element: e.element,
        lp_per_mm: metrics::resolution::usaf_lp_per_mm(e.group, e.element),
    })
}

/// One scheme at one sampling ratio.
#[derive(Debug, Clone, Serialize)]
pub struct SchemeResult {
    pub scheme: Scheme,
    /// Sampling ratio M/N as asked for, and M.
    pub ratio: f64,
    pub measurements: usize,
    /// DMD frames shown, values used for reconstruction (frames × outputs read), acquisition
    /// time at the DMD rate (s).
    pub dmd_frames: usize,
    pub detector_samples: usize,
    pub acquisition_time_s: f64,
    pub psnr_db: f64,
    pub mssim: f64,
    /// The normalisation (reconstruction → 0–255 truth scale).
    pub normalization_gain: f64,
    pub normalization_offset: f64,
    pub iterations: usize,
    /// True only when the solver met its tolerance (see `stop`).
    pub converged: bool,
    /// Why the solver stopped: its tolerance, or an iteration cap.
    pub stop: crate::reconstruction::StopReason,
    pub relative_residual: f64,
    /// True when an output this scheme read was clipped at its swing, or its oscilloscope
    /// channel over range, in a frame it used: the result is not trustworthy.
    pub saturated: bool,
    /// Solver CPU time (s): a timing, different from run to run, so written to timings.json
    /// rather than to the deterministic outputs.
    #[serde(skip)]
    pub solver_time_s: f64,
    /// The finest USAF element resolved in the reconstruction (metrics::resolution, both bar
    /// orientations above the Michelson-contrast threshold); None when the chart is not a USAF
    /// chart, could not be registered, or nothing is resolved.
    pub finest_resolved: Option<Resolved>,
    /// The reconstruction after normalisation, on the truth's 0–255 scale.
    #[serde(skip)]
    pub reconstruction: Raster,
    /// The measurements y_i the solver was given (V).
    #[serde(skip)]
    pub y: Vec<f64>,
    /// The solver's image before the scoring normalisation.
    #[serde(skip)]
    pub solution: Raster,
}

/// The solve stage: for every scheme × sampling ratio of `schemes` and `ratios` (scheme-major),
/// forms the scheme's measurements from its record, reconstructs them with `solver` and scores
/// the reconstruction against `truth` (and reads its USAF resolution when `resolution` is
/// given). Cells run in parallel and are collected in order.
pub fn solve_stage(
    recorded: &Recorded,
    schemes: &[Scheme],
    ratios: &[f64],
    truth: &Raster,
    solver: &Solver,
    resolution: Option<&ResolutionContext>,
    progress: Progress,
) -> Result<Vec<SchemeResult>> {
    let (across, down) = (truth.width, truth.height);
    let n = across * down;
    let sets: Vec<PatternSet> = ratios
        .iter()
        .map(|&r| recorded.patterns.head(patterns_for_ratio(r, n)))
        .collect::<Result<_>>()?;
    let n_ratio = ratios.len();
    let total = schemes.len() * n_ratio;
    let done = std::sync::atomic::AtomicU64::new(0);
    progress(Stage::Solve, 0, total as u64);
    let cells: Vec<Result<SchemeResult>> = (0..total)
        .into_par_iter()
        .map(|idx| {
            let scheme = schemes[idx / n_ratio];
            let r = idx % n_ratio;
            let set = &sets[r];
            let m = set.measurements();
            let rec = recorded.record(scheme.sequence()).ok_or_else(|| {
                crate::Error::Numerical(format!("no record for {}", scheme.label()))
            })?;
            let y = scheme.measurements(&rec.frames, m);
            let frames = scheme.dmd_frames(m);
            let saturated = scheme.outputs().iter().any(|o| {
                rec.clipped_frames(o.index(), frames) + rec.over_range_frames(o.index(), frames) > 0
            });
            let op = set.operator(scheme.form());
            let sol = match scheme.zero_one() {
                Some(zero_one) => Solver {
                    zero_one,
                    ..solver.clone()
                }
                .solve(op.as_ref(), &y, across, down, scheme.form())?,
                None => solver.solve(op.as_ref(), &y, across, down, scheme.form())?,
            };
            let scores = metrics::score(truth, &sol.image)?;
            let finest_resolved = match resolution {
                Some(c) => {
                    // The image's noise from its residual against the truth (the resolution
                    // read-out's null, metrics::resolution).
                    let residual = Raster::from_fn(across, down, |r, col| {
                        scores.image.get(r, col) - truth.get(r, col)
                    });
                    finest_against(&scores.image, Some(&residual), &c.chart, &c.map)?
                }
                None => None,
            };
            let out = SchemeResult {
                scheme,
                ratio: ratios[r],
                measurements: m,
                dmd_frames: frames,
                detector_samples: frames * scheme.outputs().len(),
                acquisition_time_s: frames as f64 * recorded.timing.frame_s,
                psnr_db: scores.psnr_db,
                mssim: scores.mssim,
                normalization_gain: scores.gain,
                normalization_offset: scores.offset,
                iterations: sol.iterations,
                converged: sol.converged,
                stop: sol.stop,
                relative_residual: sol.relative_residual,
                saturated,
                solver_time_s: sol.cpu_time_s,
                finest_resolved,
                reconstruction: scores.image,
                y,
                solution: sol.image,
            };
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(Stage::Solve, d, total as u64);
            Ok(out)
        })
        .collect();
    // The first failing cell's error in index order, on any thread count.
    crate::error::in_order(cells)
}
