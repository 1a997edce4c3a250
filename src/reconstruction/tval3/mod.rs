//! Total-variation minimisation by augmented Lagrangian and alternating direction, after TVAL3
//! beta2.4 (`ftvcs_alp.m`; C. Li, W. Yin, Y. Zhang, "An efficient augmented Lagrangian method with
//! applications to total variation minimization", Comput. Optim. Appl. 56:507 (2013)).
//!
//! The solver reproduces the reference implementation step by step (docs/tval3.md):
//! its pre-processing (A scaled to unit spectral norm, b to a range of 0.5–1.5), which fixes what
//! `mu` means; the initial guess Aᵀb; one projected gradient step per iteration with
//! Barzilai–Borwein step lengths and the exact steepest-descent step at the start of every inner
//! loop; the non-monotone Zhang–Hager line search, which backtracks by interpolation without new
//! operator products and falls back to a steepest-descent step after 5 failures; the shrinkage
//! w-step; multiplier and continuation updates when an inner loop ends; and the stopping rules
//! (outer tolerance, `maxcnt` inner loops, `maxit` iterations). The result is `U/scl`.
//!
//! Problem: min Σ_i ||D_i u|| subject to A u = b (and u ≥ 0 with `nonneg`), with D the periodic
//! forward differences of a width × height row-major image.

//!
//! The module's files: `options.rs` (the options and their checks), `solver.rs` (the
//! iteration), `operator.rs` (the scaled, counted operator and the eigenvalue that scales it).

mod operator;
mod options;
mod solver;
#[cfg(test)]
mod tests;

use std::time::Instant;

use super::operator::LinearOperator;
use crate::error::{Error, Result};
use crate::raster::Raster;

pub use options::{Init, MAX_ITERATIONS, TvNorm, Tval3Options};
use solver::Tval3Solver;

/// Why the iteration ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum StopReason {
    /// The outer relative change fell below `tol`.
    Tolerance,
    /// `maxcnt` inner loops were completed before the outer tolerance was met (the usual end
    /// of the reference runs: a cap, not convergence).
    MaxOuter,
    /// `maxit` iterations ran out before either of the above.
    MaxIterations,
}

impl StopReason {
    /// The test that ended the solve, in a few words, for a table cell.
    pub fn short(&self) -> &'static str {
        match self {
            StopReason::Tolerance => "outer tol met",
            StopReason::MaxOuter => "maxcnt loops",
            StopReason::MaxIterations => "maxit cap",
        }
    }

    /// What ended the solve, with the settings of `o` that decided it. `MaxOuter` is the
    /// usual end of TVAL3's reference runs: every inner loop ended on its own tolerance
    /// `tol_inn` and the multipliers were updated `maxcnt` times, but the change between
    /// outer loops stayed above `tol`; it is neither the iteration cap nor convergence.
    pub fn describe(&self, o: &Tval3Options) -> String {
        match self {
            StopReason::Tolerance => format!("the outer tolerance tol = {:e} was met", o.tol),
            StopReason::MaxOuter => format!(
                "{} inner loops ended on the inner tolerance tol_inn = {:e} (maxcnt = {}); the \
                 outer tolerance tol = {:e} was not met",
                o.maxcnt + 1,
                o.tol_inn,
                o.maxcnt,
                o.tol
            ),
            StopReason::MaxIterations => format!(
                "the iteration cap maxit = {} was reached before either tolerance test ended \
                 the solve",
                o.maxit
            ),
        }
    }
}

/// A reconstruction and how it was reached.
#[derive(Debug, Clone)]
pub struct Tval3Output {
    /// The image on the caller's scale (`U/scl`), width × height, row-major.
    pub image: Raster,
    /// Iterations run (TVAL3 `numel(out.res)`).
    pub iterations: usize,
    /// Inner loops completed (each ends with a multiplier update or the stop).
    pub outer_iterations: usize,
    /// Products `A x` made, including the pre-processing.
    pub forward_applications: usize,
    /// Products `Aᵀ y` made, including the pre-processing.
    pub adjoint_applications: usize,
    /// True only when the outer tolerance was met (`stop` is [`StopReason::Tolerance`]). Both
    /// caps, `maxcnt` inner loops and `maxit` iterations, end the iteration without meeting
    /// `tol`, so neither counts as convergence (before, `maxcnt` did, and summaries printed
    /// `"converged": true` beside `"stop": "MaxOuter"`).
    pub converged: bool,
    pub stop: StopReason,
    /// ||A u − b|| / ||b|| on the caller's (unscaled) A and b, from the tracked A·U (so without
    /// an extra product; the ratio does not depend on the pre-processing scales).
    pub relative_residual: f64,
    /// Line searches that gave up after 5 backtracks and took the steepest-descent step
    /// (3 extra products each).
    pub line_search_failures: usize,
    /// CPU time of the whole process during the call (all threads), in seconds; wall-clock time
    /// on platforms where the process CPU clock is not available.
    pub cpu_time_s: f64,
}

/// Reconstructs a width × height image from `b ≈ A u` by TVAL3.
///
/// Errors: `b` of the wrong length or with non-finite values, `width · height ≠ op.cols()`, or
/// invalid options. Running out of iterations is not an error: see [`Tval3Output::stop`].
pub fn tval3(
    op: &dyn LinearOperator,
    b: &[f64],
    width: usize,
    height: usize,
    opts: &Tval3Options,
) -> Result<Tval3Output> {
    opts.validate()?;
    if width == 0 || height == 0 {
        return Err(Error::input(format!(
            "a {width}×{height} image has no pixels"
        )));
    }
    if width.checked_mul(height) != Some(op.cols()) {
        return Err(Error::input(format!(
            "a {width}×{height} image has {} pixels but the operator has {} columns",
            width.saturating_mul(height),
            op.cols()
        )));
    }
    if b.len() != op.rows() {
        return Err(Error::field(
            "b",
            format!(
                "has {} measurements but the operator has {} rows",
                b.len(),
                op.rows()
            ),
        ));
    }
    if let Some(i) = b.iter().position(|v| !v.is_finite()) {
        return Err(Error::field(
            "b",
            format!("measurement {i} is not finite ({})", b[i]),
        ));
    }

    let wall = Instant::now();
    let cpu0 = process_cpu_seconds();
    let mut solver = Tval3Solver::new(op, width, height, opts);
    let (u, stop) = solver.run(b);
    if u.iter().any(|v| !v.is_finite()) {
        // The data and the options were checked finite above; what is left to overflow are
        // the weights, so this is the input's fault (exit status 2), named as such.
        return Err(Error::field(
            "solver",
            format!(
                "TVAL3 produced non-finite values with mu = {:e}, beta = {:e} (mu0 = {:e}, \
                 beta0 = {:e}): the weights are outside the range the solver can use; TVAL3's \
                 defaults are mu = 2^8, beta = 2^5",
                opts.mu,
                opts.beta,
                opts.mu0.unwrap_or(opts.mu),
                opts.beta0.unwrap_or(opts.beta)
            ),
        ));
    }
    let cpu_time_s = match (cpu0, process_cpu_seconds()) {
        (Some(a), Some(z)) => z - a,
        _ => wall.elapsed().as_secs_f64(),
    };
    Ok(Tval3Output {
        image: Raster {
            width,
            height,
            data: u,
        },
        iterations: solver.iterations,
        outer_iterations: solver.outer,
        forward_applications: solver.a.forward,
        adjoint_applications: solver.a.adjoint,
        converged: stop == StopReason::Tolerance,
        stop,
        relative_residual: solver.relative_residual,
        line_search_failures: solver.failures,
        cpu_time_s,
    })
}

/// CPU time of the process (all threads) in seconds, from `clock_gettime`.
#[cfg(all(target_os = "linux", target_pointer_width = "64"))]
fn process_cpu_seconds() -> Option<f64> {
    #[repr(C)]
    struct Timespec {
        tv_sec: i64,
        tv_nsec: i64,
    }
    unsafe extern "C" {
        fn clock_gettime(clock: i32, tp: *mut Timespec) -> i32;
    }
    const CLOCK_PROCESS_CPUTIME_ID: i32 = 2;
    let mut ts = Timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec (two 64-bit fields on 64-bit Linux) to a valid,
    // exclusively borrowed pointer and reads nothing else.
    let rc = unsafe { clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    (rc == 0).then_some(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
}

#[cfg(not(all(target_os = "linux", target_pointer_width = "64")))]
fn process_cpu_seconds() -> Option<f64> {
    None
}
