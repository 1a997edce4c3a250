//! TVAL3's options, their defaults (`ftvcs_al_opts.m`) and their checks.

use crate::checked::{Count, MAX_SCALAR, Positive, UnitFraction, checked, via};
use crate::error::{Error, Result};

/// The norm of the discrete gradient in the TV term (TVAL3 `TVnorm`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum TvNorm {
    /// Σ sqrt(Ux² + Uy²) (`TVnorm = 2`, the default).
    Isotropic,
    /// Σ |Ux| + |Uy| (`TVnorm = 1`).
    Anisotropic,
}

/// The starting image (TVAL3 `init`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Init {
    /// U0 = Aᵀb on the pre-processed data (`init = 1`, the default; not projected to ≥ 0).
    AdjointOfData,
    /// U0 = 0 (`init = 0`).
    Zeros,
}

/// Solver options; the defaults are those of TVAL3 beta2.4 (`ftvcs_al_opts.m`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Tval3Options {
    /// Weight of ||Au − b||² after pre-processing (2^8). Large for noise-free data.
    #[serde(deserialize_with = "via::<Weight, _, _>")]
    pub mu: f64,
    /// Weight of ||Du − w||² (2^5).
    #[serde(deserialize_with = "via::<Weight, _, _>")]
    pub beta: f64,
    /// Starting mu; continuation multiplies by `rate_ctn` per inner loop up to `mu`. Unset means
    /// `mu` (TVAL3 fills `mu0 = mu` when it is not given), so a file that sets only `mu` gets no
    /// continuation, as in TVAL3.
    #[serde(deserialize_with = "via::<Option<Weight>, _, _>")]
    pub mu0: Option<f64>,
    /// Starting beta, as `mu0` (unset means `beta`).
    #[serde(deserialize_with = "via::<Option<Weight>, _, _>")]
    pub beta0: Option<f64>,
    /// Continuation factor (2).
    #[serde(deserialize_with = "via::<ContinuationRate, _, _>")]
    pub rate_ctn: f64,
    /// Outer tolerance on ||U − U_prev_outer|| / ||Up|| (1e-6).
    #[serde(deserialize_with = "via::<Positive, _, _>")]
    pub tol: f64,
    /// Inner tolerance on ||U − Up|| / ||Up|| (1e-3).
    #[serde(deserialize_with = "via::<Positive, _, _>")]
    pub tol_inn: f64,
    /// Maximum number of inner loops (10).
    #[serde(deserialize_with = "via::<Count<1, MAX_ITERATIONS>, _, _>")]
    pub maxcnt: usize,
    /// Maximum number of iterations in total (1025).
    #[serde(deserialize_with = "via::<Count<1, MAX_ITERATIONS>, _, _>")]
    pub maxit: usize,
    /// The starting image (`AdjointOfData`).
    pub init: Init,
    /// The norm of the gradient in the TV term (`Isotropic`).
    pub tv_norm: TvNorm,
    /// Project every iterate onto u ≥ 0 (false).
    pub nonneg: bool,
    /// Scale A to unit spectral norm (true).
    pub scale_a: bool,
    /// Scale b to a range between 0.5 and 1.5 (true).
    pub scale_b: bool,
    /// Armijo constant of the line search (1e-5).
    #[serde(deserialize_with = "via::<UnitFraction, _, _>")]
    pub c: f64,
    /// Backtracking factor (0.6).
    #[serde(deserialize_with = "via::<UnitFraction, _, _>")]
    pub gamma: f64,
    /// Non-monotone averaging weight, Zhang–Hager η (0.9995).
    #[serde(deserialize_with = "via::<UnitFraction, _, _>")]
    pub gam: f64,
    /// Factor applied to `gam` after a line-search failure (0.9).
    #[serde(deserialize_with = "via::<UnitFraction, _, _>")]
    pub rate_gam: f64,
}

/// The most iterations (and inner loops) a file may ask for: 10⁶, about a thousand times the
/// reference runs' 300, so that a typing error cannot start a run of days.
pub const MAX_ITERATIONS: u64 = 1_000_000;

checked!(
    /// A weight of the augmented Lagrangian (`mu`, `beta`, `mu0`, `beta0`): a positive normal
    /// number of at most [`MAX_SCALAR`]. The solver divides one weight by the other (mu/beta in
    /// the step and the w-update, beta/mu in the multipliers), so a subnormal weight made the
    /// iterates non-finite (a beta of 5e-324 beside mu = 256 did).
    Weight,
    |v| v.is_normal() && v > 0.0 && v <= MAX_SCALAR,
    |v| format!(
        "a TVAL3 weight must be a positive normal number of at most {MAX_SCALAR:e} (TVAL3 \
         divides by it; typical weights are 2^4 to 2^13), got {v:e}"
    )
);

checked!(
    /// The continuation factor: above 1 (continuation raises mu0 toward mu) and at most
    /// [`MAX_SCALAR`].
    ContinuationRate,
    |v| v > 1.0 && v <= MAX_SCALAR,
    |v| format!("must be a finite number above 1, got {v:e}")
);

impl Default for Tval3Options {
    fn default() -> Self {
        Tval3Options {
            mu: 256.0,
            beta: 32.0,
            mu0: None,
            beta0: None,
            rate_ctn: 2.0,
            tol: 1e-6,
            tol_inn: 1e-3,
            maxcnt: 10,
            maxit: 1025,
            init: Init::AdjointOfData,
            tv_norm: TvNorm::Isotropic,
            nonneg: false,
            scale_a: true,
            scale_b: true,
            c: 1e-5,
            gamma: 0.6,
            gam: 0.9995,
            rate_gam: 0.9,
        }
    }
}

impl Tval3Options {
    /// The settings of the TVAL3 reference runs (validation/tval3-phantom/README.md):
    /// mu 2^8, beta 2^5, tol 1e-4, maxit 300, isotropic TV, u ≥ 0, the rest at the defaults.
    pub fn reference() -> Self {
        Tval3Options {
            mu: 256.0,
            beta: 32.0,
            tol: 1e-4,
            maxit: 300,
            tv_norm: TvNorm::Isotropic,
            nonneg: true,
            ..Tval3Options::default()
        }
    }

    /// Checks every option against the ranges `ftvcs_al_opts.m` accepts.
    pub fn validate(&self) -> Result<()> {
        let positive = [
            ("mu", self.mu),
            ("beta", self.beta),
            ("mu0", self.mu0.unwrap_or(self.mu)),
            ("beta0", self.beta0.unwrap_or(self.beta)),
            ("tol", self.tol),
            ("tol_inn", self.tol_inn),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::field(
                    name,
                    format!("must be a positive finite number, got {v}"),
                ));
            }
        }
        // The solver divides one weight by the other (mu/beta in the step and the w-update,
        // beta/mu in the multipliers): a subnormal weight, or a pair whose ratio overflows,
        // makes the iterates non-finite (a beta of 5e-324 beside mu = 256 did). Name the weight
        // farther from its default in orders of magnitude.
        for (name, v) in positive.iter().take(4) {
            if !v.is_normal() {
                return Err(Error::field(
                    *name,
                    format!(
                        "{v:e} is below the smallest normal number {:e}: TVAL3 divides by it",
                        f64::MIN_POSITIVE
                    ),
                ));
            }
        }
        for (m, b) in [(positive[0], positive[1]), (positive[2], positive[3])] {
            if !((m.1 / b.1).is_normal() && (b.1 / m.1).is_normal()) {
                let off = |v: f64, default: f64| (v / default).log10().abs();
                let name = if off(m.1, 256.0) >= off(b.1, 32.0) {
                    m.0
                } else {
                    b.0
                };
                return Err(Error::field(
                    name,
                    format!(
                        "{} = {:e} and {} = {:e} differ by more than f64 can hold: TVAL3 uses \
                         their ratio (typical weights are 2^4 to 2^13)",
                        m.0, m.1, b.0, b.1
                    ),
                ));
            }
        }
        if !(self.rate_ctn.is_finite() && self.rate_ctn > 1.0) {
            return Err(Error::field(
                "rate_ctn",
                format!("must be a finite number above 1, got {}", self.rate_ctn),
            ));
        }
        let unit = [
            ("c", self.c),
            ("gamma", self.gamma),
            ("gam", self.gam),
            ("rate_gam", self.rate_gam),
        ];
        for (name, v) in unit {
            if !(v > 0.0 && v <= 1.0) {
                return Err(Error::field(name, format!("must be in (0, 1], got {v}")));
            }
        }
        if self.maxcnt == 0 {
            return Err(Error::field("maxcnt", "must be at least 1"));
        }
        if self.maxit == 0 {
            return Err(Error::field("maxit", "must be at least 1"));
        }
        Ok(())
    }
}
