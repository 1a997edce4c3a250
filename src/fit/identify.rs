//! Uncertainty and identifiability at the fit's optimum.
//!
//! With J the Jacobian of the whitened residuals in the unit box, JᵀJ = V·diag(s²)·Vᵀ; s are
//! J's singular values and V's columns the directions they belong to. Along direction k one
//! standard deviation is σ_k = √max(1, χ²/dof) / s_k (box units; the factor inflates the
//! errors when the model explains the frames less well than the noise allows). A direction
//! whose σ_k exceeds [`UNIDENTIFIED_SIGMA`] of the box is *unidentified*: the frames do not pin
//! it, and it is scanned instead (the misfit traced at [`SCAN_POINTS`] points across the box
//! along it, common random numbers); its range of equally good values is the stretch around the
//! optimum where χ² stays within Δχ² = 4·max(1, χ²/dof) of the optimum (≈ 95 % for one
//! parameter), extended to the first point beyond it on each side (or the bound).
//!
//! The covariance of the variables is the pseudo-inverse over the identified directions,
//! C = Σ_k v_k v_kᵀ σ_k², plus the covariance the model's own trace noise gives them
//! ([`trace_covariance`]: its errors are shared by every frame), in the variables' units; a variable with a share above
//! [`LOADING`] in an unidentified direction is reported unidentified (no standard error) with
//! its range from the scan.

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
}

impl Identification {
    /// A scanned point clearly better than the optimum (by more than a scan's Δχ² limit): the
    /// optimum was a local one.
    pub fn better_point(&self) -> Option<Vec<f64>> {
        self.unidentified
            .iter()
            .flat_map(|u| {
                u.scan_values
                    .iter()
                    .zip(&u.scan_delta_chi2)
                    .filter(|(_, d)| **d < -u.delta_chi2_limit)
            })
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map(|(x, _)| x.clone())
    }
}

/// Identifies the fit at `u` (unit box) from its Jacobian's columns (module notes).
#[allow(clippy::too_many_arguments)]
pub fn identify(
    p: &Problem,
    u: &[f64],
    jac: &[Vec<f64>],
    prof: &super::Profiled,
    g_stderr: &[Vec<f64>; 2],
    chi2: f64,
    chi2_dof: f64,
    rays: u64,
    seed: u64,
    count: &(dyn Fn() + Sync),
) -> Result<Identification> {
    let n = u.len();
    let a: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| dot(&jac[i], &jac[j])).collect())
        .collect();
    let (eig, vecs) = linalg::symmetric_eigen(&a);
    let s: Vec<f64> = eig.iter().map(|e| e.max(0.0).sqrt()).collect();
    let inflate = chi2_dof.max(1.0).sqrt();
    let range: Vec<f64> = p.free.iter().map(|f| f.hi - f.lo).collect();
    let mut cov = vec![vec![0.0; n]; n];
    let mut pinv = vec![vec![0.0; n]; n];
    let mut identified = vec![true; n];
    let mut unidentified = Vec::new();
    for k in 0..n {
        let sigma = if s[k] > 0.0 {
            inflate / s[k]
        } else {
            f64::INFINITY
        };
        let v: Vec<f64> = (0..n).map(|i| vecs[i][k]).collect();
        if sigma <= UNIDENTIFIED_SIGMA {
            for i in 0..n {
                for j in 0..n {
                    cov[i][j] += v[i] * v[j] * sigma * sigma * range[i] * range[j];
                    pinv[i][j] += v[i] * v[j] / (s[k] * s[k]);
                }
            }
            continue;
        }
        for i in 0..n {
            if v[i].abs() > LOADING {
                identified[i] = false;
            }
        }
        unidentified.push(scan(p, u, &v, s[k], chi2, chi2_dof, rays, seed, count)?);
    }
    let trace = trace_covariance(p, jac, &pinv, prof, g_stderr);
    for i in 0..n {
        for j in 0..n {
            cov[i][j] += trace[i][j] * range[i] * range[j];
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
    Ok(Identification {
        stderr,
        correlation,
        singular_values: s,
        identified,
        unidentified,
    })
}

/// The scan along direction `v` from `u` (module notes).
#[allow(clippy::too_many_arguments)]
fn scan(
    p: &Problem,
    u: &[f64],
    v: &[f64],
    singular_value: f64,
    chi2: f64,
    chi2_dof: f64,
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
    let limit = 4.0 * chi2_dof.max(1.0);
    let mut d = Vec::with_capacity(ts.len());
    let mut values = Vec::with_capacity(ts.len());
    for &t in &ts {
        let w: Vec<f64> = u.iter().zip(v).map(|(a, b)| a + t * b).collect();
        let x = p.to_values(&w);
        let c = p.at(&x, rays, seed)?.map_or(f64::INFINITY, |q| q.chi2);
        count();
        d.push(c - chi2);
        values.push(x);
    }
    // The contiguous stretch around t = 0 within the limit, one point further each way.
    let zero = ts
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map_or(0, |(k, _)| k);
    let (mut lo, mut hi) = (zero, zero);
    while lo > 0 && d[lo - 1] <= limit {
        lo -= 1;
    }
    while hi + 1 < ts.len() && d[hi + 1] <= limit {
        hi += 1;
    }
    let (lo, hi) = (lo.saturating_sub(1), (hi + 1).min(ts.len() - 1));
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

/// The covariance (unit box) that the model's own trace noise gives the fitted variables.
///
/// The per-frame weights count each frame's Monte Carlo variance, but a trace's errors are
/// shared by the frames: every frame sums the same per-unit gains g±_j, so their errors move
/// the optimum together. To first order the optimum moves by δθ = A⁺·Jᵀ·(δmodel/σ), with
/// δmodel(f, o) = Σ_arms c_o,arm·Σ_j P^arm_fj·δg^arm_j (c the fitted scales, P^+ the frame's
/// pattern and P^− its complement); so cov = Σ_arms Σ_j h_i,j·h_k,j·se(g_j)² with
/// h_i = (P^arm)ᵀ·(c·z_i/σ) and z_i = J·A⁺·e_i.
pub fn trace_covariance(
    p: &Problem,
    jac: &[Vec<f64>],
    pinv: &[Vec<f64>],
    prof: &super::Profiled,
    g_stderr: &[Vec<f64>; 2],
) -> Vec<Vec<f64>> {
    use crate::acquisition::Sequence;
    use crate::acquisition::schemes::CALIBRATION_PAIRS;
    let n = jac.len();
    let units = p.bits.cols();
    let nu = &prof.nuisances;
    // Scales per channel [RF, MON+, MON−] on [u₊, u₋].
    let scale = [[nu[0], -nu[1]], [nu[3], 0.0], [0.0, nu[5]]];
    let mut h = vec![[vec![0.0; units], vec![0.0; units]]; n];
    let mut idx = 0;
    for (s, q) in p.measured.sequences.iter().enumerate() {
        for f in 0..q.values.len() {
            if q.flagged[f] {
                continue;
            }
            // The frame's pattern as (row of the base patterns, inverted), or all on / all off.
            let pattern: (Option<usize>, bool) = match q.sequence {
                Sequence::Base => (Some(f), false),
                Sequence::Complementary => (Some(f / 2), f % 2 == 1),
                Sequence::CalibratedBase if f < 2 * CALIBRATION_PAIRS => (None, f % 2 == 1),
                Sequence::CalibratedBase => (Some(f - 2 * CALIBRATION_PAIRS), false),
            };
            let mut w = vec![[0.0; 2]; n];
            for o in 0..3 {
                let sg = prof.sigma_v[s][f][o];
                for (i, wi) in w.iter_mut().enumerate() {
                    let z: f64 = (0..n).map(|m| jac[m][idx] * pinv[m][i]).sum();
                    wi[0] += z / sg * scale[o][0];
                    wi[1] += z / sg * scale[o][1];
                }
                idx += 1;
            }
            for j in 0..units {
                let on = match pattern {
                    (Some(r), inv) => p.bits.get(r, j) != inv,
                    (None, inv) => !inv,
                };
                for (i, wi) in w.iter().enumerate() {
                    if on {
                        h[i][0][j] += wi[0];
                    } else {
                        h[i][1][j] += wi[1];
                    }
                }
            }
        }
    }
    let se2 = |a: usize, j: usize| {
        let s = g_stderr[a][j];
        if s.is_finite() { s * s } else { 0.0 }
    };
    (0..n)
        .map(|i| {
            (0..n)
                .map(|k| {
                    (0..2)
                        .map(|a| {
                            (0..units)
                                .map(|j| h[i][a][j] * h[k][a][j] * se2(a, j))
                                .sum::<f64>()
                        })
                        .sum()
                })
                .collect()
        })
        .collect()
}
