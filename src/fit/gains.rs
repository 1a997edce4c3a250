//! The detector's gains within their tolerance: a prior on the four channel scales.
//!
//! Without a prior the fit profiles each channel's scale on the light freely ([`super::model`]),
//! so a change that scales one arm's light (a lens decentre that loses a share of the spot,
//! the DMD's tilt moving the blaze away from one arm) is taken up by that arm's scale: the
//! frames keep only the shape of each arm's per-unit map. A lab does know its detector, to a
//! tolerance: the RF transimpedance G_rf, each monitor's G±, and each diode's responsivity
//! ℜ± (the PDB2xx family's CMRR of > 20 dB bounds the two diodes' mismatch to about 10 %). What
//! it does not know is the lamp's absolute power L at the diodes. So the four scales are
//!
//! c_k = n_k·(L + δ_k),  k ∈ {RF on u₊, RF on u₋, MONITOR+, MONITOR−},
//!
//! with n_k the nominal electronics' scales (V/A, [`super::model::nominal_scales`]), L free
//! (relative to the nominal bench) and δ_k ~ N(0, (τ·L)²): each scale known to the relative
//! tolerance τ (one standard deviation) about a common unknown power. With L's prior flat,
//! integrating it out leaves a Gaussian on the relative scales ρ_k = c_k/n_k about their mean,
//! exp(−Σ_k (ρ_k − ρ̄)²/(2τ²L²)): three rows of the least squares, one per Helmert contrast
//! h_j of the four ρ_k (orthonormal, orthogonal to their sum), (0 − h_j·ρ)/(τ·L₀) with L₀
//! the free fit's mean ρ (so the system stays linear and as well conditioned as the free
//! one), and L reported as the fitted ρ̄. A correct bench has χ² ≈ rows − parameters as
//! before, and the rows carry unit variance in the noise moment
//! ([`super::identify::noise_moment`]) and in the expected χ² ([`super::chi2`]): the lab's
//! detector differs from its nominal by about τ. This is the Gaussian prior of a maximum a
//! posteriori fit (J. Kaipio and E. Somersalo, *Statistical and Computational Inverse
//! Problems*, Springer 2005, §3.3), with the gains' ratios, not their product with the power,
//! constrained.

use crate::error::{Error, Result};

use super::model::{Flat, free_columns, wls};

/// How well the lab knows its detector's four channel scales (module notes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainPrior {
    /// The nominal scales (V/A): RF on u₊, RF on u₋, MONITOR+, MONITOR−.
    pub nominal: [f64; 4],
    /// Each scale's relative standard deviation about the common lamp scale.
    pub tolerance: f64,
}

/// The fit under the prior: the free nuisances' columns over all rows (the data's, then the
/// prior's), the observations, the weights and the coefficients ([`super::NUISANCES`] order).
pub(super) struct PriorFit {
    pub cols: Vec<Vec<f64>>,
    pub y: Vec<f64>,
    pub w: Vec<f64>,
    pub coef: Vec<f64>,
    /// ρ̄, the mean of the four scales relative to the nominal.
    pub lamp_scale: f64,
    pub prior_rows: usize,
}

/// The prior's rows: the contrasts of four scales.
pub const PRIOR_ROWS: usize = 3;

/// The Helmert contrasts of four values: orthonormal rows orthogonal to (1, 1, 1, 1).
fn helmert() -> [[f64; 4]; PRIOR_ROWS] {
    let (a, b, c) = (0.5f64.sqrt(), 6f64.sqrt().recip(), 12f64.sqrt().recip());
    [
        [a, -a, 0.0, 0.0],
        [b, b, -2.0 * b, 0.0],
        [c, c, c, -3.0 * c],
    ]
}

/// Where the four scales sit among the seven nuisances.
const SCALE_AT: [usize; 4] = [0, 1, 3, 5];

/// Fits the nuisances under `prior` from the free fit's coefficients `free` (module notes),
/// in two passes (the second's weights carry the first's scales).
pub(super) fn fit_under_prior(
    flat: &Flat,
    floor: [f64; 3],
    free: &[f64],
    prior: &GainPrior,
) -> Result<PriorFit> {
    let nom = prior.nominal;
    let rho = |c: &[f64]| [0, 1, 2, 3].map(|k| c[SCALE_AT[k]] / nom[k]);
    let l0 = rho(free).iter().sum::<f64>() / 4.0;
    if !(l0.is_finite() && l0 > 0.0) {
        return Err(Error::input(
            "the frames' fitted gains are not positive: no common lamp power fits them",
        ));
    }
    let h = helmert();
    let mut cols = free_columns(flat);
    for (k, &at) in SCALE_AT.iter().enumerate() {
        cols[at].extend(h.iter().map(|hj| hj[k] / nom[k]));
    }
    for (p, col) in cols.iter_mut().enumerate() {
        if !SCALE_AT.contains(&p) {
            col.extend([0.0; PRIOR_ROWS]);
        }
    }
    let mut y = flat.rows();
    y.extend([0.0; PRIOR_ROWS]);
    let prior_w = 1.0 / (prior.tolerance * l0).powi(2);
    let weights = |c: &[f64]| {
        let mut w = flat.weights(floor, SCALE_AT.map(|at| c[at]));
        w.extend([prior_w; PRIOR_ROWS]);
        w
    };
    let mut w = weights(free);
    let mut coef = wls(&cols, &y, &w)?;
    w = weights(&coef);
    coef = wls(&cols, &y, &w)?;
    Ok(PriorFit {
        lamp_scale: rho(&coef).iter().sum::<f64>() / 4.0,
        cols,
        y,
        w,
        coef,
        prior_rows: PRIOR_ROWS,
    })
}
