//! Uncertainty and identifiability at the fit's optimum.
//!
//! With J the Jacobian of the whitened residuals in the unit box, JᵀJ = V·diag(s²)·Vᵀ; s are
//! J's singular values and V's columns the directions they belong to. Along direction k one
//! standard deviation is σ_k = √(max(1, χ²/dof)·v_kᵀ·M·v_k) / s_k² (box units, M below; with
//! noise independent from frame to frame and of the weights' size M = A and σ_k = 1/s_k; the
//! factor inflates the errors when the model explains the frames less well than the noise
//! allows). The curvature sees the noise the optimum's neighbours share; a trace noise they do
//! not share (below: rays that take other paths) moves χ² by up to the equally good Δχ²
//! between them, so the optimum is known only to where the curvature alone adds that much:
//! σ_k is raised to at least √Δχ² / (2·s_k) ([`unshared_sigma`]; the factor 2 makes that
//! half-width the 95 % one), the same rule as the equally good ranges, and the covariance
//! gains the difference along each identified direction. A direction
//! whose σ_k exceeds [`UNIDENTIFIED_SIGMA`] of the box is *unidentified*: the frames do not pin
//! it, and it is scanned instead (the misfit traced at [`SCAN_POINTS`] points across the box
//! along it, common random numbers); its range of equally good values holds every scanned point
//! whose χ² is within Δχ² = 4·max(1, χ²/dof) + 2√2·sd(χ²) of the lowest χ² seen (the optimum's,
//! or a scan point's where that is lower). The first term is the ≈ 95 % limit for one parameter
//! where the noise is the same at both points; the second is the noise of a χ² difference
//! between points whose traces do not share it (sd(χ²) is [`super::chi2::Expected::sd`], √2 for
//! two independent draws, 2 of them for ≈ 95 %): common random numbers cancel the trace's noise
//! between neighbouring benches, not between a lens decentred by +d and by −d, whose rays take
//! other paths, and where the model's rays are few that noise (hundreds on a few thousand frame
//! values) swamps the first term, so a valley found at one trace's noise is not a valley the
//! data prefer. The limit is conservative for near points (their noise is partly shared). The
//! range spans the whole box and not only
//! around the optimum, so that another valley as good (a lens decentre's mirror image) is
//! inside it; it runs from the first such point to the last, extended one point beyond each
//! (or to the bound). A valley narrower than the scan's spacing can still fall between points.
//!
//! A is JᵀJ less the differences' own noise on its diagonal (Σ var Ĵ of each column, from the
//! trace's batches: [`super::step`]), so that a column no larger than its noise adds no
//! curvature. The covariance of the variables is the sandwich C = max(1, χ²/dof)·A⁺·M·A⁺ with A,
//! A⁺ its pseudo-inverse over the identified directions and M the covariance of Jᵀ·δr
//! ([`noise_moment`]: the measurement noise, independent from frame to frame, and the model
//! trace's, which every frame shares), in the variables' units; a variable with a share above
//! [`LOADING`] in an unidentified direction is reported unidentified (no standard error) with
//! its range from the scan. Each identified variable's axis is scanned too (the same
//! [`SCAN_POINTS`] across its bounds, the others held): a scanned point within Δχ² of the
//! optimum but beyond the 95 % half-width its curvature gives is another valley as good (the
//! mirror image −d of a lens decentre d), which the local curvature cannot see, and the
//! variable is then reported unidentified with the scan's range. Where any variable is
//! unidentified and there are two to four, all of them are also scanned jointly on a grid
//! across their bounds ([`GridScan`]; with more, the two to four unidentified ones): each
//! unidentified variable's range is the union of the line scans' and the grid's, and an
//! identified one with an equally good grid point beyond its 95 % half-width and a grid step
//! is another valley's too (a mirror image can be joint: both lenses' decentres flipped
//! together, which no axis through the optimum reaches), reported unidentified. Where χ² lies
//! above its band, every free variable is scanned so ([`joint_grid`]) if it was not, for a
//! better start and failing one for the ranges.

// Dense matrices indexed both ways: index loops read as the formulas do.
#![allow(clippy::needless_range_loop)]

use crate::error::Result;

use super::{Problem, dot, linalg};

/// σ along a direction (unit box) above which it is unidentified.
pub const UNIDENTIFIED_SIGMA: f64 = 0.25;
/// Points of a scan along an unidentified direction.
pub const SCAN_POINTS: usize = 13;
/// A variable's component in an unidentified direction above which it is unidentified.
pub const LOADING: f64 = 0.5;

/// One direction the data do not constrain.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Unidentified {
    /// Its singular value (whitened residuals per unit box).
    pub singular_value: f64,
    /// The direction, one component per free variable (unit box, unit length).
    pub direction: Vec<f64>,
    /// Each variable's range of equally good values along it (its units).
    pub range_lo: Vec<f64>,
    pub range_hi: Vec<f64>,
    /// The scan: each point's values and χ² − χ²_best.
    pub scan_values: Vec<Vec<f64>>,
    pub scan_delta_chi2: Vec<f64>,
    /// The Δχ² that bounds the range.
    pub delta_chi2_limit: f64,
}

/// Grid points per variable of the joint scan of k variables ([`grid_scan`]):
/// 7² = 49 traces for two, 5³ = 125 for three, 4⁴ = 256 for four; none beyond four (the line
/// scans alone). Four came from the coverage benches: a bench with four unidentified variables
/// ended with narrow ranges beside the truth when only the line scans covered it
/// (docs/guide/11-fitting.md).
pub fn grid_points(k: usize) -> Option<usize> {
    match k {
        2 => Some(7),
        3 => Some(5),
        4 => Some(4),
        _ => None,
    }
}

/// The joint scan of two to four variables (module notes): a line scan follows one direction
/// through the optimum, and where two directions are both free the equally good region is a
/// patch of their plane that a true bench can lie in off both lines (a lens decentred in x and
/// in y). Each scanned variable takes [`grid_points`] values across its bounds, the others
/// held at the optimum, every combination traced (common random numbers, the fit's rays); a
/// variable's range holds every grid point within the same Δχ² as the line scans', one grid
/// step beyond each end.
#[derive(Debug, Clone, serde::Serialize)]
pub struct GridScan {
    /// The variables scanned (indices into the free variables).
    pub variables: Vec<usize>,
    /// Each grid point: the free variables' values, and χ² − χ²_best (null where the bench
    /// does not build).
    pub scan_values: Vec<Vec<f64>>,
    pub scan_delta_chi2: Vec<f64>,
    pub delta_chi2_limit: f64,
    /// Per scanned variable (in `variables`' order), its range of equally good values.
    pub range_lo: Vec<f64>,
    pub range_hi: Vec<f64>,
}

/// The uncertainty of a fit.
#[derive(Debug, Clone)]
pub struct Identification {
    /// Standard error of each variable (its units); NaN where unidentified.
    pub stderr: Vec<f64>,
    pub correlation: Vec<Vec<f64>>,
    /// Descending.
    pub singular_values: Vec<f64>,
    pub identified: Vec<bool>,
    pub unidentified: Vec<Unidentified>,
    /// The joint scan (module notes): of every free variable where one is unidentified and
    /// there are two to four, or where χ² ended above its band ([`joint_grid`]); else of the
    /// two to four unidentified ones.
    pub grid: Option<GridScan>,
    /// The equally good Δχ² at the optimum ([`At::limit`]).
    pub limit: f64,
}

impl Identification {
    /// A scanned point clearly better than the optimum (by more than the equally good Δχ²):
    /// the optimum was a local one.
    pub fn better_point(&self) -> Option<Vec<f64>> {
        lowest_where(self.scanned(), |d| d < -self.limit)
    }

    /// The lowest point below the optimum (Δχ² < 0) among the scans made at it and `extra`,
    /// another grid traced about the same optimum ([`joint_grid`]).
    pub fn lowest_below(&self, extra: Option<&GridScan>) -> Option<Vec<f64>> {
        let extra = extra
            .into_iter()
            .flat_map(|g| g.scan_values.iter().zip(&g.scan_delta_chi2));
        lowest_where(self.scanned().chain(extra), |d| d < 0.0)
    }

    /// Every point scanned at the optimum (line scans and the joint grid), with its Δχ².
    fn scanned(&self) -> impl Iterator<Item = (&Vec<f64>, &f64)> {
        let lines = self
            .unidentified
            .iter()
            .flat_map(|u| u.scan_values.iter().zip(&u.scan_delta_chi2));
        let grid = self
            .grid
            .iter()
            .flat_map(|g| g.scan_values.iter().zip(&g.scan_delta_chi2));
        lines.chain(grid)
    }

    /// Variable i's range of equally good values (its units) about the fitted value `x`: the
    /// union of the line scans along the directions it loads and of the joint scan; None for
    /// an identified variable.
    pub fn range(&self, i: usize, x: f64) -> Option<(f64, f64)> {
        if self.identified[i] {
            return None;
        }
        let lines = self
            .unidentified
            .iter()
            .filter(|u| u.direction[i].abs() > LOADING)
            .map(|u| (u.range_lo[i], u.range_hi[i]));
        let grid = self.grid.iter().filter_map(|g| {
            let k = g.variables.iter().position(|&v| v == i)?;
            Some((g.range_lo[k], g.range_hi[k]))
        });
        Some(
            lines
                .chain(grid)
                .fold((x, x), |(a, b), (lo, hi)| (a.min(lo), b.max(hi))),
        )
    }
}

/// The misfit at the optimum: χ², χ²/dof and the standard deviation of χ² a correct model
/// gives ([`super::chi2::Expected::sd`]).
#[derive(Debug, Clone, Copy)]
pub struct At {
    pub chi2: f64,
    pub chi2_dof: f64,
    pub chi2_sd: f64,
}

impl At {
    /// The Δχ² within which a scanned point is as good as the optimum (module notes).
    pub fn limit(&self) -> f64 {
        4.0 * self.chi2_dof.max(1.0) + 2.0 * std::f64::consts::SQRT_2 * self.chi2_sd
    }
}

/// One standard deviation along a direction of singular value `s` (unit box) from the trace
/// noise the optimum's neighbours do not share (module notes): the half-width √limit / s at
/// which the curvature alone raises χ² by the equally good Δχ², over 2 (the 95 % half-width
/// of one standard deviation). Where sd(χ²) is negligible it is √max(1, χ²/dof) / s, the
/// inflated σ of independent noise.
pub fn unshared_sigma(at: At, s: f64) -> f64 {
    if s > 0.0 {
        at.limit().sqrt() / (2.0 * s)
    } else {
        f64::INFINITY
    }
}

/// Identifies the fit at `u` (unit box) from its Jacobian's columns (module notes).
#[allow(clippy::too_many_arguments)]
pub fn identify(
    p: &Problem,
    u: &[f64],
    jacobian: &super::Jacobian,
    prof: &super::Profiled,
    batches: &super::model::BatchFrames,
    at: At,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<Identification> {
    let chi2_dof = at.chi2_dof;
    let n = u.len();
    let jac = &jacobian.cols;
    // A = JᵀJ less the differences' own noise on its diagonal (E[ŝ²] = s² + var ŝ, module
    // notes): a column whose slopes are no larger than their noise then has no curvature and
    // is reported unidentified rather than pinned by its noise.
    let a: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    let noise: f64 = if i == j {
                        jacobian.variance[i].iter().sum()
                    } else {
                        0.0
                    };
                    dot(&jac[i], &jac[j]) - noise
                })
                .collect()
        })
        .collect();
    let (eig, vecs) = linalg::symmetric_eigen(&a);
    let s: Vec<f64> = eig.iter().map(|e| e.max(0.0).sqrt()).collect();
    let inflate2 = chi2_dof.max(1.0);
    let range: Vec<f64> = p.free.iter().map(|f| f.hi - f.lo).collect();
    let m = noise_moment(p, jac, prof, batches);
    let mut pinv = vec![vec![0.0; n]; n];
    // The unshared trace noise's variance along each identified direction, beyond the
    // sandwich's (module notes), added to the covariance below.
    let mut unshared = vec![vec![0.0; n]; n];
    let mut identified = vec![true; n];
    let mut unidentified = Vec::new();
    for k in 0..n {
        let v: Vec<f64> = (0..n).map(|i| vecs[i][k]).collect();
        // Along v: δt = vᵀ·Jᵀ·δr / s², variance vᵀ·M·v / s⁴.
        let vmv: f64 = (0..n)
            .map(|i| (0..n).map(|j| v[i] * m[i][j] * v[j]).sum::<f64>())
            .sum();
        let sigma = if s[k] > 0.0 {
            (inflate2 * vmv.max(0.0)).sqrt() / (s[k] * s[k])
        } else {
            f64::INFINITY
        };
        let sigma_eff = sigma.max(unshared_sigma(at, s[k]));
        if sigma_eff <= UNIDENTIFIED_SIGMA {
            let extra = sigma_eff * sigma_eff - sigma * sigma;
            for i in 0..n {
                for j in 0..n {
                    pinv[i][j] += v[i] * v[j] / (s[k] * s[k]);
                    unshared[i][j] += v[i] * v[j] * extra;
                }
            }
            continue;
        }
        for i in 0..n {
            if v[i].abs() > LOADING {
                identified[i] = false;
            }
        }
        unidentified.push(scan(p, u, &v, s[k], at, rays, seed, count)?);
    }
    // C = A⁺·M·A⁺ over the identified directions, in the variables' units.
    let mut cov = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..n {
            let mut c = 0.0;
            for k in 0..n {
                for l in 0..n {
                    c += pinv[i][k] * m[k][l] * pinv[l][j];
                }
            }
            cov[i][j] = (inflate2 * c + unshared[i][j]) * range[i] * range[j];
        }
    }
    // An identified variable's curvature is local: a second valley as good (a lens decentre's
    // mirror image) is found only by scanning its axis across the box (module notes).
    for i in 0..n {
        if !identified[i] {
            continue;
        }
        let half = 2.0 * cov[i][i].max(0.0).sqrt() / range[i];
        let axis: Vec<f64> = (0..n).map(|j| if j == i { 1.0 } else { 0.0 }).collect();
        let line = scan(p, u, &axis, a[i][i].max(0.0).sqrt(), at, rays, seed, count)?;
        if second_valley(&line, u[i], half, i, p.free[i].lo, range[i]) {
            identified[i] = false;
            unidentified.push(line);
        }
    }
    let stderr: Vec<f64> = (0..n)
        .map(|i| {
            if identified[i] {
                cov[i][i].sqrt()
            } else {
                f64::NAN
            }
        })
        .collect();
    let correlation = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    let d = (cov[i][i] * cov[j][j]).sqrt();
                    if i == j {
                        1.0
                    } else if d > 0.0 {
                        cov[i][j] / d
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        })
        .collect();
    let mut stderr = stderr;
    let grid = joint_scan(p, u, &mut identified, &mut stderr, at, rays, seed, count)?;
    Ok(Identification {
        stderr,
        correlation,
        singular_values: s,
        identified,
        unidentified,
        grid,
        limit: at.limit(),
    })
}

/// The identification's joint scan (module notes): every free variable where one is
/// unidentified and there are two to four (a mirror valley can be joint: each lens decentre
/// flipped together, no axis through the optimum reaching it), else the unidentified ones
/// where there are two to four; None otherwise. An identified variable with a joint second
/// valley ([`joint_second_valleys`]) is marked unidentified, its standard error NaN.
#[allow(clippy::too_many_arguments)]
fn joint_scan(
    p: &Problem,
    u: &[f64],
    identified: &mut [bool],
    stderr: &mut [f64],
    at: At,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<Option<GridScan>> {
    let n = u.len();
    let unknown: Vec<usize> = (0..n).filter(|&i| !identified[i]).collect();
    let scanned: Vec<usize> = match grid_points(n) {
        Some(_) if !unknown.is_empty() => (0..n).collect(),
        _ => unknown,
    };
    let Some(points) = grid_points(scanned.len()) else {
        return Ok(None);
    };
    let g = grid_scan(p, u, &scanned, points, at, rays, seed, count)?;
    for i in joint_second_valleys(p.free, u, &g, points, identified, stderr) {
        identified[i] = false;
        stderr[i] = f64::NAN;
    }
    Ok(Some(g))
}

/// The joint scan of every free variable about an optimum whose χ² lies above its sampling
/// band (`at.chi2` above [`super::chi2::Expected::upper`]): the fit is then in a valley the
/// frames do not prefer, and a line scan follows one direction while the true bench can lie
/// off it (a lens tilt and a decentre of the same lens, one identified and one not). Each
/// variable at [`grid_points`] levels across its bounds (13, the line scans' density, for one
/// variable); None where the identification's own grid already covers them all, or beyond four.
#[allow(clippy::too_many_arguments)]
pub fn joint_grid(
    p: &Problem,
    u: &[f64],
    id: &Identification,
    at: At,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<Option<GridScan>> {
    let n = u.len();
    if id.grid.as_ref().is_some_and(|g| g.variables.len() == n) {
        return Ok(None);
    }
    let points = if n == 1 {
        Some(SCAN_POINTS)
    } else {
        grid_points(n)
    };
    let Some(points) = points else {
        return Ok(None);
    };
    let all: Vec<usize> = (0..n).collect();
    Ok(Some(grid_scan(p, u, &all, points, at, rays, seed, count)?))
}

/// The scanned point of lowest Δχ² among those whose Δχ² passes `keep`.
fn lowest_where<'a>(
    points: impl Iterator<Item = (&'a Vec<f64>, &'a f64)>,
    keep: impl Fn(f64) -> bool,
) -> Option<Vec<f64>> {
    points
        .filter(|(_, d)| keep(**d))
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(x, _)| x.clone())
}

/// Per scanned variable, the levels (0 … `points` − 1) its equally good grid points span: the
/// points whose Δχ² (`d`, each point's levels in `levels`) is within `limit` of the lowest
/// seen (0, the optimum's, or a grid point's below it), from the lowest level among them to
/// the highest, one level further each way within the grid; None where no point is.
pub fn grid_ranges(
    levels: &[Vec<usize>],
    d: &[f64],
    points: usize,
    limit: f64,
) -> Vec<Option<(usize, usize)>> {
    let floor = d.iter().copied().fold(0.0, f64::min);
    let vars = levels.first().map_or(0, Vec::len);
    (0..vars)
        .map(|k| {
            levels
                .iter()
                .zip(d)
                .filter(|(_, dd)| **dd - floor <= limit)
                .map(|(ks, _)| ks[k])
                .fold(None, |r: Option<(usize, usize)>, l| {
                    Some(r.map_or((l, l), |(a, b)| (a.min(l), b.max(l))))
                })
                .map(|(a, b)| (a.saturating_sub(1), (b + 1).min(points - 1)))
        })
        .collect()
}

/// The joint scan of the variables `free` at `points` values each ([`GridScan`]).
#[allow(clippy::too_many_arguments)]
fn grid_scan(
    p: &Problem,
    u: &[f64],
    free: &[usize],
    points: usize,
    at: At,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<GridScan> {
    let level = |k: usize| k as f64 / (points - 1) as f64;
    let total = points.pow(free.len() as u32);
    let (mut values, mut d, mut levels) = (Vec::new(), Vec::new(), Vec::new());
    for flat in 0..total {
        let mut w = u.to_vec();
        let mut rest = flat;
        let mut ks = Vec::with_capacity(free.len());
        for &i in free {
            ks.push(rest % points);
            w[i] = level(rest % points);
            rest /= points;
        }
        let x = p.to_values(&w);
        let c = p.chi2_at(&x, rays, seed, count)?;
        d.push(c - at.chi2);
        values.push(x);
        levels.push(ks);
    }
    let limit = at.limit();
    let (mut range_lo, mut range_hi) = (Vec::new(), Vec::new());
    for (&i, span) in free.iter().zip(grid_ranges(&levels, &d, points, limit)) {
        let f = &p.free[i];
        // The optimum's own value is in the range, as for the line scans.
        let here = f.lo + u[i] * (f.hi - f.lo);
        let to_value = |l: usize| f.lo + level(l) * (f.hi - f.lo);
        let (lo, hi) = span.map_or((here, here), |(a, b)| {
            (to_value(a).min(here), to_value(b).max(here))
        });
        range_lo.push(lo);
        range_hi.push(hi);
    }
    Ok(GridScan {
        variables: free.to_vec(),
        scan_values: values,
        scan_delta_chi2: d,
        delta_chi2_limit: limit,
        range_lo,
        range_hi,
    })
}

/// The identified variables of the joint scan `g` (`points` levels a variable) that have an
/// equally good grid point (Δχ² within the limit of the lowest seen) farther from the optimum
/// `u` than their 95 % half-width (2 standard errors) and one grid step: another valley, joint
/// with the other variables' (both lens decentres flipped), which neither the curvature nor an
/// axis scan sees.
pub fn joint_second_valleys(
    free: &[crate::pipeline::optimise::Free],
    u: &[f64],
    g: &GridScan,
    points: usize,
    identified: &[bool],
    stderr: &[f64],
) -> Vec<usize> {
    let floor = g.scan_delta_chi2.iter().copied().fold(0.0, f64::min);
    g.variables
        .iter()
        .copied()
        .filter(|&i| identified[i])
        .filter(|&i| {
            let f = &free[i];
            let here = f.lo + u[i] * (f.hi - f.lo);
            let reach = 2.0 * stderr[i] + (f.hi - f.lo) / (points - 1) as f64;
            g.scan_values
                .iter()
                .zip(&g.scan_delta_chi2)
                .any(|(x, d)| d - floor <= g.delta_chi2_limit && (x[i] - here).abs() > reach)
        })
        .collect()
}

/// Whether the scan along variable `i`'s axis has an equally good point (Δχ² within the
/// limit) farther from the optimum `ui` (unit box) than `half`, the 95 % half-width its
/// curvature gives: another valley the local curvature cannot see.
fn second_valley(line: &Unidentified, ui: f64, half: f64, i: usize, lo: f64, width: f64) -> bool {
    line.scan_values
        .iter()
        .zip(&line.scan_delta_chi2)
        .any(|(x, d)| *d <= line.delta_chi2_limit && ((x[i] - lo) / width - ui).abs() > half)
}

/// The scan along direction `v` from `u` (module notes).
#[allow(clippy::too_many_arguments)]
fn scan(
    p: &Problem,
    u: &[f64],
    v: &[f64],
    singular_value: f64,
    at: At,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<Unidentified> {
    // The stretch of t for which u + t·v stays in the box.
    let (mut t_lo, mut t_hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for (ui, vi) in u.iter().zip(v) {
        if vi.abs() < 1e-12 {
            continue;
        }
        let (a, b) = ((0.0 - ui) / vi, (1.0 - ui) / vi);
        t_lo = t_lo.max(a.min(b));
        t_hi = t_hi.min(a.max(b));
    }
    let ts: Vec<f64> = (0..SCAN_POINTS)
        .map(|k| t_lo + (t_hi - t_lo) * k as f64 / (SCAN_POINTS - 1) as f64)
        .collect();
    let (chi2, limit) = (at.chi2, at.limit());
    let mut d = Vec::with_capacity(ts.len());
    let mut values = Vec::with_capacity(ts.len());
    for &t in &ts {
        let w: Vec<f64> = u.iter().zip(v).map(|(a, b)| a + t * b).collect();
        let x = p.to_values(&w);
        let c = p.chi2_at(&x, rays, seed, count)?;
        d.push(c - chi2);
        values.push(x);
    }
    let (lo, hi) = equally_good(&ts, &d, limit);
    let (tl, th) = (ts[lo].min(0.0), ts[hi].max(0.0));
    let ends = |t: f64| p.to_values(&u.iter().zip(v).map(|(a, b)| a + t * b).collect::<Vec<_>>());
    let (xa, xb) = (ends(tl), ends(th));
    Ok(Unidentified {
        singular_value,
        direction: v.to_vec(),
        range_lo: xa.iter().zip(&xb).map(|(a, b)| a.min(*b)).collect(),
        range_hi: xa.iter().zip(&xb).map(|(a, b)| a.max(*b)).collect(),
        scan_values: values,
        scan_delta_chi2: d,
        delta_chi2_limit: limit,
    })
}

/// The scan points' stretch of equally good values (module notes): from the first to the last
/// point whose χ² is within `limit` of the lowest seen (the optimum's, `d` = 0, or a scan
/// point's below it), the point nearest the optimum included, one point further each way
/// (within the scan). Across the whole scan, not only the stretch around the optimum: a second
/// valley as good within Δχ² (the mirror of a lens decentre) widens the range to hold it.
pub fn equally_good(ts: &[f64], d: &[f64], limit: f64) -> (usize, usize) {
    let zero = ts
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map_or(0, |(k, _)| k);
    let floor = d.iter().copied().fold(0.0, f64::min);
    let within = (0..d.len()).filter(|&k| d[k] - floor <= limit);
    let (lo, hi) = within.fold((zero, zero), |(a, b), k| (a.min(k), b.max(k)));
    (
        lo.saturating_sub(1),
        (hi + 1).min(ts.len().saturating_sub(1)),
    )
}

/// M = Cov(Jᵀ·δr), the noise moment of the whitened residuals' projection on the Jacobian
/// (unit box), from the two noises the residuals carry:
///
/// - the measurement's, independent from frame to frame: δr_i = ε_i/σ_i with var ε_i = σ_o²
///   (the channel's frame noise), so M_meas = Σ_i J_i·J_iᵀ·σ_o²/σ_i²;
/// - the model trace's, shared by the frames: every frame sums the same traced per-unit gains,
///   so batch b of the trace moves residual i by d_b,i = Σ_arm c_o,arm·δu_b,arm(f)/σ_i (c the
///   fitted scales of the channel on each arm's light, δu_b the batch's frame light less the
///   batch mean), and M_trace = B/(B − 1)·Σ_b (Jᵀ·d_b)(Jᵀ·d_b)ᵀ (batch means).
///
/// The weights 1/σ_i² count both variances frame by frame, so that χ² measures the misfit
/// against both; the covariance A⁺·M·A⁺ counts the trace's once, with its correlations.
pub fn noise_moment(
    p: &Problem,
    jac: &[Vec<f64>],
    prof: &super::Profiled,
    batches: &super::model::BatchFrames,
) -> Vec<Vec<f64>> {
    let n = jac.len();
    let nu = &prof.nuisances;
    // Scales per channel [RF, MON+, MON−] on [u₊, u₋].
    let scale = [[nu[0], -nu[1]], [nu[3], 0.0], [0.0, nu[5]]];
    let noise2 = p.measured.noise_v.map(|s| s * s);
    let mut m = vec![vec![0.0; n]; n];
    let nb = batches.deviations.len();
    let mut jd = vec![vec![0.0; n]; nb];
    let (mut idx, mut flat) = (0, 0);
    for (s, q) in p.measured.sequences.iter().enumerate() {
        for f in 0..q.values.len() {
            if q.flagged[f] {
                flat += 1;
                continue;
            }
            for o in 0..3 {
                let sg = prof.sigma_v[s][f][o];
                let share = noise2[o] / (sg * sg);
                for i in 0..n {
                    for j in 0..n {
                        m[i][j] += jac[i][idx] * jac[j][idx] * share;
                    }
                }
                for (b, dev) in batches.deviations.iter().enumerate() {
                    let d = (scale[o][0] * dev[flat][0] + scale[o][1] * dev[flat][1]) / sg;
                    for i in 0..n {
                        jd[b][i] += jac[i][idx] * d;
                    }
                }
                idx += 1;
            }
            flat += 1;
        }
    }
    // The gain prior's rows at the end: unit variance ([`super::gains`]).
    for r in idx..idx + prof.prior_rows {
        for i in 0..n {
            for j in 0..n {
                m[i][j] += jac[i][r] * jac[j][r];
            }
        }
    }
    for v in &jd {
        for i in 0..n {
            for j in 0..n {
                m[i][j] += batches.factor * v[i] * v[j];
            }
        }
    }
    m
}
