//! TVAL3's view of the operator: A divided by sqrt(s2) with its products counted (ScaleA), and
//! the largest eigenvalue of AᵀA that sets s2.

use super::solver::norm_sq;
use crate::reconstruction::operator::LinearOperator;

/// The operator divided by sqrt(s2) (ScaleA: TVAL3 wraps A as `A(x, mode)/sqrt(s2)`), counting
/// the products made.
pub(super) struct Counted<'a> {
    pub(super) op: &'a dyn LinearOperator,
    /// sqrt(s2), or 1 without scaling.
    pub(super) divisor: f64,
    pub(super) forward: usize,
    pub(super) adjoint: usize,
}

impl Counted<'_> {
    pub(super) fn apply(&mut self, x: &[f64], y: &mut [f64]) {
        self.op.apply(x, y);
        self.forward += 1;
        if self.divisor != 1.0 {
            y.iter_mut().for_each(|v| *v /= self.divisor);
        }
    }

    pub(super) fn adjoint(&mut self, y: &[f64], x: &mut [f64]) {
        self.op.apply_adjoint(y, x);
        self.adjoint += 1;
        if self.divisor != 1.0 {
            x.iter_mut().for_each(|v| *v /= self.divisor);
        }
    }
}

/// The largest eigenvalue of AᵀA for ScaleA, or None when A Aᵀ = I already, which TVAL3 tests
/// first (||A Aᵀ t − t||₁ / ||t||₁ < 1e-3 for a random t) and then skips the scaling.
///
/// TVAL3 calls `eigs(AᵀA, 1, 'lm')` with tol 0.05, a Lanczos method (ARPACK). This is a plain
/// Lanczos iteration started from Aᵀt, so the two products of the AAᵀ test also make its first
/// step, stopped by ARPACK's own convergence test at the same tolerance: the Ritz residual
/// β_k |s_k| at most 0.05 θ. The Ritz value then lies within a few per cent below λ_max (the
/// spectrum of a random ±1 matrix has a soft edge, so the last digits converge slowly), which
/// docs/tval3.md accepts ("the result only sets the scale"); ARPACK always builds
/// a 20-vector basis first and so returns a value closer to λ_max at about three times the cost.
pub(super) fn largest_eigenvalue(a: &mut Counted<'_>) -> Option<f64> {
    let m = a.op.rows();
    let n = a.op.cols();
    // A fixed stream stands in for MATLAB's rand(m, 1), so the result is reproducible.
    let mut rng = crate::rng::stream(SCALE_A_SEED, 0);
    let t: Vec<f64> = (0..m).map(|_| crate::rng::uniform(&mut rng)).collect();
    let mut q = vec![0.0; n];
    a.adjoint(&t, &mut q);
    let mut aq = vec![0.0; m];
    a.apply(&q, &mut aq);
    let l1_t: f64 = t.iter().map(|v| v.abs()).sum();
    let l1_r: f64 = aq.iter().zip(&t).map(|(x, y)| (x - y).abs()).sum();
    if l1_r / l1_t < 1e-3 {
        return None;
    }
    let nq = norm_sq(&q).sqrt();
    if nq == 0.0 {
        // Aᵀ t = 0 for a positive t: A has no usable range; leave it unscaled.
        return Some(0.0);
    }
    q.iter_mut().for_each(|v| *v /= nq);
    aq.iter_mut().for_each(|v| *v /= nq);

    let mut q_prev = vec![0.0; n];
    let mut w = vec![0.0; n];
    let mut alphas = Vec::with_capacity(LANCZOS_MAX_STEPS);
    let mut betas: Vec<f64> = Vec::with_capacity(LANCZOS_MAX_STEPS);
    let mut theta = 0.0;
    for step in 0..LANCZOS_MAX_STEPS {
        if step > 0 {
            a.apply(&q, &mut aq);
        }
        a.adjoint(&aq, &mut w);
        // α = qᵀAᵀAq = ||Aq||², then w ← AᵀAq − α q − β q_prev.
        let alpha = norm_sq(&aq);
        let beta_prev = betas.last().copied().unwrap_or(0.0);
        for ((wi, &qi), &pi) in w.iter_mut().zip(&q).zip(&q_prev) {
            *wi -= alpha * qi + beta_prev * pi;
        }
        alphas.push(alpha);
        let beta = norm_sq(&w).sqrt();
        let (top, last) = tridiagonal_top_eigenpair(&alphas, &betas);
        theta = top;
        if beta * last.abs() <= SCALE_A_TOL * theta || beta == 0.0 {
            break;
        }
        betas.push(beta);
        std::mem::swap(&mut q_prev, &mut q);
        for (qi, &wi) in q.iter_mut().zip(&w) {
            *qi = wi / beta;
        }
    }
    Some(theta)
}

/// `eopts.tol` of TVAL3's ScaleA.
const SCALE_A_TOL: f64 = 0.05;
/// ARPACK's default basis size for one eigenvalue; never reached on the reference problems.
const LANCZOS_MAX_STEPS: usize = 20;
const SCALE_A_SEED: u64 = 0x7A13_5CA1;

/// The largest eigenvalue θ of the symmetric tridiagonal matrix with diagonal `a` and
/// off-diagonal `b` (`b.len() == a.len() − 1`), and the last component of its unit eigenvector.
///
/// θ comes from bisection on the Sturm count (the number of negative pivots of T − x I equals the
/// number of eigenvalues below x); the eigenvector from two steps of inverse iteration with a
/// shift just above θ, where T − σI is negative definite and elimination without pivoting is
/// stable.
pub(super) fn tridiagonal_top_eigenpair(a: &[f64], b: &[f64]) -> (f64, f64) {
    let k = a.len();
    let off = |i: usize| if i < b.len() { b[i].abs() } else { 0.0 };
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for (i, &ai) in a.iter().enumerate() {
        let r = off(i) + if i > 0 { off(i - 1) } else { 0.0 };
        lo = lo.min(ai - r);
        hi = hi.max(ai + r);
    }
    let below = |x: f64| {
        let mut count = 0;
        let mut d = 1.0;
        for (i, &ai) in a.iter().enumerate() {
            d = (ai - x) - if i > 0 { b[i - 1] * b[i - 1] / d } else { 0.0 };
            if d == 0.0 {
                d = -f64::MIN_POSITIVE;
            }
            if d < 0.0 {
                count += 1;
            }
        }
        count
    };
    // Invariant: fewer than k eigenvalues below lo, all k below hi (Gershgorin: hi ≥ λ_max,
    // and a slightly raised hi is strictly above).
    hi += f64::EPSILON * hi.abs().max(1.0);
    lo -= f64::EPSILON * lo.abs().max(1.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if below(mid) == k {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let theta = 0.5 * (lo + hi);
    if k == 1 {
        return (theta, 1.0);
    }
    let sigma = hi + 1e-10 * hi.abs().max(f64::MIN_POSITIVE);
    // A start with no special symmetry: a constant or alternating vector can be orthogonal to
    // the wanted eigenvector of a symmetric (Toeplitz) T.
    let mut x: Vec<f64> = (0..k)
        .map(|i| 1.0 + 0.5 * (0.618_034 * i as f64).fract())
        .collect();
    let mut c = vec![0.0; k];
    let mut d = vec![0.0; k];
    for _ in 0..2 {
        // Thomas algorithm for (T − σI) y = x.
        for i in 0..k {
            let sub = if i > 0 { b[i - 1] } else { 0.0 };
            let sup = if i + 1 < k { b[i] } else { 0.0 };
            let piv = (a[i] - sigma) - if i > 0 { sub * c[i - 1] } else { 0.0 };
            c[i] = sup / piv;
            d[i] = (x[i] - if i > 0 { sub * d[i - 1] } else { 0.0 }) / piv;
        }
        for i in (0..k).rev() {
            x[i] = d[i] - if i + 1 < k { c[i] * x[i + 1] } else { 0.0 };
        }
        let nx = norm_sq(&x).sqrt();
        x.iter_mut().for_each(|v| *v /= nx);
    }
    (theta, x[k - 1])
}
