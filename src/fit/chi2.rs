//! The χ² a correct model should give, and its sampling band.
//!
//! The whitened residuals r_i = (y_i − model_i)/σ_i carry two noises ([`super::identify`]'s
//! noise moment): the measurement's, independent from frame to frame with variance share
//! s_i = σ_o²/σ_i², and the model trace's, which every frame shares (batch b moves the
//! residuals by d_b). Fitting the nuisances and the variables projects r onto the complement Q
//! of their columns, so for a correct model
//!
//! E[χ²] = Σ_i s_i·(1 − h_i) + B/(B − 1)·Σ_b ‖Q·d_b‖²,
//!
//! with h_i ≈ (nuisances + variables)/rows the hat matrix's diagonal taken as flat (a gain
//! prior's rows, [`super::gains`], count with s_i = 1). Because
//! the trace's share is correlated over the frames, the nuisances remove more than one unit of
//! it each (a trace error common to all units is one arm's scale): E[χ²] falls below the
//! degrees of freedom, and the spread of χ² exceeds √(2·dof). For Gaussian noise
//! var χ² = 2·tr((QΣQ)²) (Σ the residuals' covariance), here
//! 2·[Σ_i s_i² + 2·Σ_i s_i·(QSQ)_ii + tr((QSQ)²)] with S the batch-means covariance of the
//! trace part; tr((QSQ)²) from the batch-means estimate is corrected for its own sampling
//! (with ν = B − 1: ν²/((ν − 1)(ν + 2))·(tr Ŝ² − (tr Ŝ)²/ν), the unbiased estimate of tr Σ² of a
//! Wishart matrix; D. J. Srivastava, *J. Japan Statist. Soc.* 35, 251–272, 2005).

use super::model::{BatchFrames, Profiled};
use super::{Problem, dot, linalg};

/// What a correct model's χ² should be.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Expected {
    /// E[χ²] from the measurement noise.
    pub measurement: f64,
    /// E[χ²] from the model trace's noise.
    pub trace: f64,
    /// The standard deviation of χ²: the larger of the two estimates below.
    pub sd: f64,
    /// sd(χ²) from the trace's batches (module notes): exact for Gaussian batch means.
    pub sd_batches: f64,
    /// The sample standard deviation of χ² at the optimum over [`REPLICAS`] traces on seeds
    /// of their own, each computed as the fit computes its own (the variance scale calibrated
    /// on it, the nuisances profiled): the spread itself, where the batches' formula misses
    /// part of it (0 until measured).
    pub sd_replicas: f64,
}

/// Independent traces at the optimum whose χ² spread measures sd(χ²) ([`Expected::sd_replicas`]).
pub const REPLICAS: u64 = 8;

/// Added to the fit's seed for the replica traces (far from the selection traces' and from
/// any seed a user counts through).
pub const REPLICA_SEED_BASE: u64 = 0x4e91_1ca0_0000;

impl Expected {
    pub fn mean(&self) -> f64 {
        self.measurement + self.trace
    }

    /// The upper edge of the sampling band, mean + 2 sd: a χ² above it was not explained
    /// within the noise, so the fit is in a valley the frames do not prefer (or the model
    /// lacks something).
    pub fn upper(&self) -> f64 {
        self.mean() + 2.0 * self.sd
    }

    /// With the spread measured on independent traces at the optimum (`chi2`: their χ²
    /// values): `sd` becomes the larger of the two estimates. The batches' formula holds the
    /// weights fixed, while each trace's weights come from its own estimate of the variance
    /// scale (about a hundred batches at 10⁵ rays: some 14 % of error), which moves χ² too; on one
    /// coverage bench the formula gave half the spread measured (docs/guide/11-fitting.md).
    pub fn with_replicas(self, chi2: &[f64]) -> Expected {
        let n = chi2.len();
        if n < 2 || chi2.iter().any(|c| !c.is_finite()) {
            return self;
        }
        let mean = chi2.iter().sum::<f64>() / n as f64;
        let var = chi2.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let sd_replicas = var.sqrt();
        Expected {
            sd: self.sd_batches.max(sd_replicas),
            sd_replicas,
            ..self
        }
    }
}

/// Projects `d` (the residuals' rows) off the linear model's whitened columns, then off the
/// Jacobian's.
fn project(d: &mut [f64], prof: &Profiled, jac: &[Vec<f64>]) {
    for cols in [&prof.basis_w[..], jac] {
        if let Some(c) = least_squares(cols, d) {
            for (k, col) in cols.iter().enumerate() {
                for (di, ji) in d.iter_mut().zip(col) {
                    *di -= c[k] * ji;
                }
            }
        }
    }
}

/// The least-squares coefficients of `y` on `cols` (normal equations, columns scaled).
fn least_squares(cols: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
    let k = cols.len();
    let norm: Vec<f64> = cols.iter().map(|c| dot(c, c).sqrt().max(1e-300)).collect();
    let a: Vec<Vec<f64>> = (0..k)
        .map(|i| {
            (0..k)
                .map(|j| dot(&cols[i], &cols[j]) / (norm[i] * norm[j]))
                .collect()
        })
        .collect();
    let b: Vec<f64> = (0..k).map(|i| dot(&cols[i], y) / norm[i]).collect();
    linalg::solve(a, b).map(|c| c.iter().zip(&norm).map(|(c, s)| c / s).collect())
}

/// The expected χ² of the fit at its optimum (module notes).
pub fn expected(p: &Problem, prof: &Profiled, jac: &[Vec<f64>], batches: &BatchFrames) -> Expected {
    let nu = &prof.nuisances;
    let scale = [[nu[0], -nu[1]], [nu[3], 0.0], [0.0, nu[5]]];
    let noise2 = p.measured.noise_v.map(|s| s * s);
    let mut share = Vec::with_capacity(prof.residuals.len());
    let mut ds: Vec<Vec<f64>> =
        vec![Vec::with_capacity(prof.residuals.len()); batches.deviations.len()];
    let mut flat = 0;
    for (s, q) in p.measured.sequences.iter().enumerate() {
        for f in 0..q.values.len() {
            if !q.flagged[f] {
                for o in 0..3 {
                    let sg = prof.sigma_v[s][f][o];
                    share.push(noise2[o] / (sg * sg));
                    for (b, dev) in batches.deviations.iter().enumerate() {
                        ds[b].push((scale[o][0] * dev[flat][0] + scale[o][1] * dev[flat][1]) / sg);
                    }
                }
            }
            flat += 1;
        }
    }
    // The gain prior's rows: unit variance, the lab's detector off its nominal by its
    // tolerance ([`super::gains`]); no trace noise before the profiling.
    share.extend(std::iter::repeat_n(1.0, prof.prior_rows));
    for d in &mut ds {
        d.extend(std::iter::repeat_n(0.0, prof.prior_rows));
    }
    let n = share.len().max(1) as f64;
    let fitted = (jac.len() + prof.linear_parameters()) as f64;
    let total_share: f64 = share.iter().sum();
    let measurement = total_share * (1.0 - fitted / n).max(0.0);
    for d in &mut ds {
        project(d, prof, jac);
    }
    let f = batches.factor;
    let trace: f64 = f * ds.iter().map(|d| dot(d, d)).sum::<f64>();
    let share2: f64 = share.iter().map(|s| s * s).sum();
    let cross: f64 = f * ds
        .iter()
        .map(|d| d.iter().zip(&share).map(|(di, s)| s * di * di).sum::<f64>())
        .sum::<f64>();
    let nb = ds.len();
    let mut tr_s2 = 0.0;
    for a in 0..nb {
        for b in 0..nb {
            let g = dot(&ds[a], &ds[b]);
            tr_s2 += f * f * g * g;
        }
    }
    let nu_b = nb.saturating_sub(1) as f64;
    let tr_sigma2 = if nu_b > 1.0 {
        (nu_b * nu_b / ((nu_b - 1.0) * (nu_b + 2.0)) * (tr_s2 - trace * trace / nu_b)).max(0.0)
    } else {
        tr_s2
    };
    let sd = (2.0 * (share2 + 2.0 * cross + tr_sigma2)).sqrt();
    Expected {
        measurement,
        trace,
        sd,
        sd_batches: sd,
        sd_replicas: 0.0,
    }
}
