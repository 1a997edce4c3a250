//! The TVAL3 iteration: the periodic differences, the shrinkage w-step, and the solver that
//! runs the inner and outer loops of `ftvcs_alp.m` step by step (docs/tval3.md).

use super::operator::{Counted, largest_eigenvalue};
use super::{Init, StopReason, TvNorm, Tval3Options};
use crate::reconstruction::operator::LinearOperator;

/// Periodic forward differences on a width × height row-major grid (TVAL3 `defDDt.m`): `x` along
/// a row (to the next column), `y` along a column (to the next row), both wrapping around.
#[derive(Clone, Copy)]
pub(super) struct Grid {
    pub(super) width: usize,
    pub(super) height: usize,
}

impl Grid {
    /// (Ux, Uy) = D U.
    pub(super) fn d(&self, u: &[f64], ux: &mut [f64], uy: &mut [f64]) {
        let (w, h) = (self.width, self.height);
        for r in 0..h {
            let row = &u[r * w..(r + 1) * w];
            let next = if r + 1 < h { r + 1 } else { 0 };
            let below = &u[next * w..(next + 1) * w];
            let ux_row = &mut ux[r * w..(r + 1) * w];
            for c in 0..w - 1 {
                ux_row[c] = row[c + 1] - row[c];
            }
            ux_row[w - 1] = row[0] - row[w - 1];
            for ((o, &a), &b) in uy[r * w..(r + 1) * w].iter_mut().zip(row).zip(below) {
                *o = b - a;
            }
        }
    }

    /// out = Dᵀ (X, Y), the exact adjoint of [`Grid::d`].
    pub(super) fn dt(&self, x: &[f64], y: &[f64], out: &mut [f64]) {
        let (w, h) = (self.width, self.height);
        for r in 0..h {
            let prev = if r > 0 { r - 1 } else { h - 1 };
            let xr = &x[r * w..(r + 1) * w];
            let yr = &y[r * w..(r + 1) * w];
            let yp = &y[prev * w..(prev + 1) * w];
            let o = &mut out[r * w..(r + 1) * w];
            o[0] = xr[w - 1] - xr[0];
            for c in 1..w {
                o[c] = xr[c - 1] - xr[c];
            }
            for ((oc, &a), &b) in o.iter_mut().zip(yp).zip(yr) {
                *oc += a - b;
            }
        }
    }
}

/// Two sums over i in 0..n of the pairs `f(i)`, each kept in four interleaved partial sums
/// (term i goes to lane i % 4) and combined as (s0 + s1) + (s2 + s3). The order is fixed, so the
/// result is reproducible, and four independent chains of additions run about four times faster
/// than one; every reduction of the solver goes through here. `f` may also write element i of
/// other vectors, which fuses passes over memory.
#[inline(always)]
pub(super) fn sum2(n: usize, mut f: impl FnMut(usize) -> (f64, f64)) -> (f64, f64) {
    let mut a = [0.0f64; 4];
    let mut b = [0.0f64; 4];
    let mut i = 0;
    while i + 4 <= n {
        for k in 0..4 {
            let (x, y) = f(i + k);
            a[k] += x;
            b[k] += y;
        }
        i += 4;
    }
    for k in 0..n - i {
        let (x, y) = f(i + k);
        a[k] += x;
        b[k] += y;
    }
    ((a[0] + a[1]) + (a[2] + a[3]), (b[0] + b[1]) + (b[2] + b[3]))
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    sum2(n, |i| (a[i] * b[i], 0.0)).0
}

pub(super) fn norm_sq(a: &[f64]) -> f64 {
    dot(a, a)
}

/// W = shrink(Ubar, 1/beta) with Ubar = DU − sigma/beta, in place of (wx, wy); returns
/// lam1 = Σ ||W_i||. (At the start sigma = 0, and then Ubar = DU exactly.)
///
/// Isotropic: W = max(|Ubar| − 1/β, 0) · Ubar/|Ubar| with |Ubar| = 0 read as 1 (TVAL3's guard
/// against 0/0); anisotropic: componentwise soft thresholding. For the isotropic λ1, ||W_i|| is
/// taken as max(|Ubar_i| − 1/β, 0) (0 where Ubar_i = 0), which equals TVAL3's
/// sqrt(Wx² + Wy²) in exact arithmetic and saves a square root per pixel.
///
/// The element-wise pass writes ||W_i|| to `scratch` and is free of branches so that it
/// vectorises; the sum is then taken in the fixed order of [`sum2`].
#[allow(clippy::too_many_arguments)]
pub(super) fn shrink(
    norm: TvNorm,
    beta: f64,
    ux: &[f64],
    uy: &[f64],
    sigx: &[f64],
    sigy: &[f64],
    wx: &mut [f64],
    wy: &mut [f64],
    scratch: &mut [f64],
) -> f64 {
    let thr = 1.0 / beta;
    let n = ux.len();
    let (uy, sigx, sigy) = (&uy[..n], &sigx[..n], &sigy[..n]);
    let (wx, wy, scratch) = (&mut wx[..n], &mut wy[..n], &mut scratch[..n]);
    match norm {
        TvNorm::Isotropic => {
            for i in 0..n {
                let a = ux[i] - sigx[i] / beta;
                let b = uy[i] - sigy[i] / beta;
                let v0 = (a * a + b * b).sqrt();
                let v = if v0 == 0.0 { 1.0 } else { v0 };
                let t = if v - thr > 0.0 { v - thr } else { 0.0 };
                let s = t / v;
                wx[i] = s * a;
                wy[i] = s * b;
                scratch[i] = if v0 == 0.0 { 0.0 } else { t };
            }
        }
        TvNorm::Anisotropic => {
            for i in 0..n {
                let a = ux[i] - sigx[i] / beta;
                let b = uy[i] - sigy[i] / beta;
                let ta = a.abs() - thr;
                let tb = b.abs() - thr;
                let ox = if ta > 0.0 { ta.copysign(a) } else { 0.0 };
                let oy = if tb > 0.0 { tb.copysign(b) } else { 0.0 };
                wx[i] = ox;
                wy[i] = oy;
                scratch[i] = ox.abs() + oy.abs();
            }
        }
    }
    sum2(n, |i| (scratch[i], 0.0)).0
}

/// The solver state (TVAL3 variable names; `p` suffixes are the previous iterate).
pub(super) struct Tval3Solver<'a> {
    pub(super) a: Counted<'a>,
    grid: Grid,
    opts: &'a Tval3Options,
    pub(super) iterations: usize,
    pub(super) outer: usize,
    pub(super) failures: usize,
    pub(super) relative_residual: f64,
}

/// The parts of the augmented Lagrangian that the line search and the w-step update.
#[derive(Clone, Copy, Default)]
struct Lagrangian {
    lam1: f64,
    lam2: f64,
    lam3: f64,
    lam4: f64,
    lam5: f64,
}

impl Lagrangian {
    fn f(&self, beta: f64, mu: f64) -> f64 {
        self.lam1 + beta / 2.0 * self.lam2 + mu / 2.0 * self.lam3 - self.lam4 - self.lam5
    }
}

impl<'a> Tval3Solver<'a> {
    pub(super) fn new(
        op: &'a dyn LinearOperator,
        width: usize,
        height: usize,
        opts: &'a Tval3Options,
    ) -> Self {
        Tval3Solver {
            a: Counted {
                op,
                divisor: 1.0,
                forward: 0,
                adjoint: 0,
            },
            grid: Grid { width, height },
            opts,
            iterations: 0,
            outer: 0,
            failures: 0,
            relative_residual: 0.0,
        }
    }

    /// ScaleA and Scaleb; returns the working b and `scl`.
    fn preprocess(&mut self, b: &[f64]) -> (Vec<f64>, f64) {
        let mut b = b.to_vec();
        if self.opts.scale_a
            && let Some(s2) = largest_eigenvalue(&mut self.a)
            && s2 > 1.0 + 1e-10
        {
            let s = s2.sqrt();
            self.a.divisor = s;
            b.iter_mut().for_each(|v| *v /= s);
        }
        let mut scl = 1.0;
        if self.opts.scale_b {
            let max = b.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let min = b.iter().copied().fold(f64::INFINITY, f64::min);
            let dif = (max - min).abs();
            // TVAL3 divides by the range unconditionally; a constant b (range 0) would make
            // scl infinite, so it is left unscaled instead.
            if dif > 0.0 && dif < 0.5 {
                scl = 0.5 / dif;
            } else if dif > 1.5 {
                scl = 1.5 / dif;
            }
            if scl != 1.0 {
                b.iter_mut().for_each(|v| *v *= scl);
            }
        }
        (b, scl)
    }

    /// Steepest-descent step length for the quadratic part along d (1 forward product):
    /// |d'd / (||D d||² + (mu/beta) ||A d||²)|.
    fn sd_step(&mut self, d: &[f64], mu_d_beta: f64, ws: &mut Work) -> f64 {
        self.grid.d(d, &mut ws.dx, &mut ws.dy);
        let d_dd = norm_sq(&ws.dx) + norm_sq(&ws.dy);
        self.a.apply(d, &mut ws.ad);
        let dd = dot(d, d);
        if dd == 0.0 {
            // d = 0: U is stationary. TVAL3 would form 0/0; no step is the same limit.
            return 0.0;
        }
        (dd / (d_dd + mu_d_beta * norm_sq(&ws.ad))).abs()
    }

    pub(super) fn run(&mut self, b_user: &[f64]) -> (Vec<f64>, StopReason) {
        let n = self.grid.width * self.grid.height;
        if b_user.iter().all(|&v| v == 0.0) {
            // A u = 0 is solved by u = 0 with zero total variation; the iteration itself would
            // divide 0 by 0 (||Up|| = 0 and d = 0).
            self.relative_residual = 0.0;
            return (vec![0.0; n], StopReason::Tolerance);
        }
        let mut s = self.start(b_user);
        let mut stop = StopReason::MaxIterations;
        for ii in 1..=self.opts.maxit {
            self.iterations = ii;
            // (a) Step length: BB1 within an inner loop, exact steepest descent at its start.
            let fst_itr = !s.have_prev;
            let tau = self.step_length(&mut s);
            // (b) Keep the previous values. Swapping buffers is enough: every current-iterate
            // vector is overwritten in full below before it is read.
            std::mem::swap(&mut s.cur, &mut s.prev);
            // (c) One projected gradient step; (d) D U and the gradients with the old W (2
            // products).
            self.project_step(&mut s, tau);
            self.grid.d(&s.cur.u, &mut s.cur.ux, &mut s.cur.uy);
            self.gradients(&mut s);
            s.f = s.lag.f(s.beta, s.mu);
            // (e) Non-monotone line search; (f) w-step (shrinkage) after a successful one.
            if self.line_search(&mut s, tau) {
                let tmpf = s.f - s.lag.lam1 - s.beta / 2.0 * s.lag.lam2 + s.lag.lam4;
                s.lag.lam1 = self.shrink_w(&mut s);
                self.tv_gradient(&mut s);
                s.f = tmpf + s.lag.lam1 + s.beta / 2.0 * s.lag.lam2 - s.lag.lam4;
            }
            // (g) Non-monotone reference value.
            let qp = s.q;
            s.q = s.gam * qp + 1.0;
            s.c_ref = (s.gam * qp * s.c_ref + s.f) / s.q;
            // (h) New direction and the inner stopping test; (i) the end of an inner loop.
            let (rel_chg, nrm_up) = s.new_direction();
            s.have_prev = true;
            if rel_chg < self.opts.tol_inn
                && !fst_itr
                && let Some(reason) = self.end_inner_loop(&mut s, nrm_up)
            {
                stop = reason;
                break;
            }
        }
        self.relative_residual = s.lag.lam3.sqrt() / s.nrm_b;
        let scl = s.scl;
        let mut u = s.cur.u;
        u.iter_mut().for_each(|v| *v /= scl);
        (u, stop)
    }

    /// Pre-processing, the first iterate and its gradients, and the first direction.
    fn start(&mut self, b_user: &[f64]) -> State {
        let opts = self.opts;
        let n = self.grid.width * self.grid.height;
        let m = b_user.len();
        let (b, scl) = self.preprocess(b_user);
        let nrm_b = norm_sq(&b).sqrt();
        let mut atb = vec![0.0; n];
        self.a.adjoint(&b, &mut atb);
        let mu = opts.mu0.unwrap_or(opts.mu).min(opts.mu);
        let beta = opts.beta0.unwrap_or(opts.beta).min(opts.beta);
        let mut cur = Iterate::zeros(n, m);
        if opts.init == Init::AdjointOfData {
            cur.u.copy_from_slice(&atb);
        }
        let mut s = State {
            rcd_u: cur.u.clone(),
            cur,
            prev: Iterate::zeros(n, m),
            step: Iterate::zeros(n, m),
            b,
            atb,
            scl,
            nrm_b,
            wx: vec![0.0; n],
            wy: vec![0.0; n],
            sigx: vec![0.0; n],
            sigy: vec![0.0; n],
            delta: vec![0.0; m],
            dts_atd: vec![0.0; n],
            d: Vec::new(),
            ws: Work::new(n, m),
            lag: Lagrangian::default(),
            mu,
            beta,
            f: 0.0,
            c_ref: 0.0,
            q: 1.0,
            gam: opts.gam,
            have_prev: false,
            count: 1,
        };
        self.grid.d(&s.cur.u, &mut s.cur.ux, &mut s.cur.uy);
        s.lag.lam1 = self.shrink_w(&mut s);
        self.gradients(&mut s);
        s.f = s.lag.f(beta, mu);
        s.c_ref = s.f;
        // d = g2 + (mu/beta) g − DtsAtd: the gradient of the augmented Lagrangian in u over beta.
        let mu_d_beta = s.mu_d_beta();
        s.d = (0..n)
            .map(|i| s.cur.g2[i] + mu_d_beta * s.cur.g[i] - s.dts_atd[i])
            .collect();
        s
    }

    /// The step length: BB1 from the last step within an inner loop, exact steepest descent
    /// at its start.
    fn step_length(&mut self, s: &mut State) -> f64 {
        if s.have_prev {
            // s = U − Up (= du of the previous iteration), yv = (g2 − g2p) + (mu/β)(g − gp).
            let (c, p, mu_d_beta) = (&s.cur, &s.prev, s.mu_d_beta());
            let (ss, sy) = sum2(c.u.len(), |i| {
                let s = c.u[i] - p.u[i];
                (
                    s * s,
                    s * ((c.g2[i] - p.g2[i]) + mu_d_beta * (c.g[i] - p.g[i])),
                )
            });
            (ss / sy.max(f64::EPSILON)).abs()
        } else {
            self.sd_step(&s.d, s.mu_d_beta(), &mut s.ws)
        }
    }

    /// U = max(Up − tau d, 0) (without the bound when `nonneg` is off).
    fn project_step(&self, s: &mut State, tau: f64) {
        for ((ui, &upi), &di) in s.cur.u.iter_mut().zip(&s.prev.u).zip(&s.d) {
            *ui = upi - tau * di;
            if self.opts.nonneg {
                *ui = ui.max(0.0);
            }
        }
    }

    /// The W-step's shrinkage of the current DU; returns lam1.
    fn shrink_w(&self, s: &mut State) -> f64 {
        shrink(
            self.opts.tv_norm,
            s.beta,
            &s.cur.ux,
            &s.cur.uy,
            &s.sigx,
            &s.sigy,
            &mut s.wx,
            &mut s.wy,
            &mut s.ws.dx,
        )
    }

    /// g2, lam2 and lam4 of the current iterate with the current W ([`Tval3Solver::update_w`]).
    fn tv_gradient(&self, s: &mut State) {
        self.update_w(
            &s.cur.ux,
            &s.cur.uy,
            &s.wx,
            &s.wy,
            &s.sigx,
            &s.sigy,
            &mut s.cur.g2,
            &mut s.lag,
            &mut s.ws,
        );
    }

    /// AU, g and g2 of the current iterate with the current W ([`Tval3Solver::get_g`]).
    fn gradients(&mut self, s: &mut State) {
        self.get_g(
            &s.cur.u,
            &s.cur.ux,
            &s.cur.uy,
            &s.wx,
            &s.wy,
            &s.b,
            &s.atb,
            &s.sigx,
            &s.sigy,
            &s.delta,
            &mut s.cur.au,
            &mut s.cur.g,
            &mut s.cur.g2,
            &mut s.lag,
            &mut s.ws,
        );
    }

    /// The non-monotone line search (Zhang & Hager 2004) by interpolation between Up and the
    /// full step. False when it gave up after 5 cuts and took the projected steepest-descent
    /// step with its own w-step instead (TVAL3's alpha = 0).
    fn line_search(&mut self, s: &mut State, tau: f64) -> bool {
        for i in 0..s.cur.u.len() {
            s.step.u[i] = s.cur.u[i] - s.prev.u[i];
        }
        let armijo = self.opts.c * s.beta * tau * dot(&s.d, &s.d);
        let mut alpha = 1.0;
        let mut cnt = 0;
        while s.f > s.c_ref - alpha * armijo {
            if cnt == 5 {
                self.give_up_line_search(s);
                return false;
            }
            if cnt == 0 {
                s.step_differences();
            }
            alpha *= self.opts.gamma;
            s.chord_point(alpha);
            cnt += 1;
        }
        true
    }

    /// The line search's way out: the projected steepest-descent step from Up, and the w-step
    /// with it.
    fn give_up_line_search(&mut self, s: &mut State) {
        s.gam *= self.opts.rate_gam;
        self.failures += 1;
        let tau_sd = self.sd_step(&s.d, s.mu_d_beta(), &mut s.ws);
        self.project_step(s, tau_sd);
        self.grid.d(&s.cur.u, &mut s.cur.ux, &mut s.cur.uy);
        s.lag.lam1 = self.shrink_w(s);
        self.gradients(s);
        s.f = s.lag.f(s.beta, s.mu);
    }

    /// The end of an inner loop: the outer stopping tests, then the multipliers' update and
    /// the continuation of mu and beta. Some(reason) when the solver stops.
    fn end_inner_loop(&mut self, s: &mut State, nrm_up: f64) -> Option<StopReason> {
        let opts = self.opts;
        s.count += 1;
        self.outer = s.count - 1;
        let (u, rcd_u) = (&s.cur.u, &s.rcd_u);
        let rel_chg_out = sum2(u.len(), |i| ((u[i] - rcd_u[i]).powi(2), 0.0)).0.sqrt() / nrm_up;
        s.rcd_u.copy_from_slice(&s.cur.u);
        if rel_chg_out < opts.tol {
            return Some(StopReason::Tolerance);
        }
        if s.count > opts.maxcnt {
            return Some(StopReason::MaxOuter);
        }
        let (c, beta, mu) = (&s.cur, s.beta, s.mu);
        // Multipliers: sigma −= beta (DU − W), delta −= mu (AU − b).
        for i in 0..c.u.len() {
            s.sigx[i] -= beta * (c.ux[i] - s.wx[i]);
            s.sigy[i] -= beta * (c.uy[i] - s.wy[i]);
        }
        for i in 0..s.delta.len() {
            s.delta[i] -= mu * (c.au[i] - s.b[i]);
        }
        let (_, lam4) = v_terms(&c.ux, &c.uy, &s.wx, &s.wy, &s.sigx, &s.sigy);
        let (_, lam5) = r_terms(&c.au, &s.b, &s.delta);
        s.lag.lam4 = lam4;
        s.lag.lam5 = lam5;
        // Continuation.
        let beta_old = s.beta;
        s.beta = (s.beta * opts.rate_ctn).min(opts.beta);
        s.mu = (s.mu * opts.rate_ctn).min(opts.mu);
        s.f = s.lag.f(s.beta, s.mu);
        // d (from h) equals −(Dᵀσ_new + Aᵀδ_new)/β_old plus the gradient terms; TVAL3 keeps
        // DtsAtd = −(β_old/β) d and rebuilds d with it.
        let mu_d_beta = s.mu_d_beta();
        for i in 0..s.d.len() {
            s.dts_atd[i] = -(beta_old / s.beta) * s.d[i];
            s.d[i] = s.cur.g2[i] + mu_d_beta * s.cur.g[i] - s.dts_atd[i];
        }
        s.have_prev = false;
        s.gam = opts.gam;
        s.q = 1.0;
        s.c_ref = s.f;
        None
    }

    /// `get_g`: Au = A U, g = Aᵀ(Au) − Aᵀb (2 products), then the W-dependent terms.
    #[allow(clippy::too_many_arguments)]
    fn get_g(
        &mut self,
        u: &[f64],
        ux: &[f64],
        uy: &[f64],
        wx: &[f64],
        wy: &[f64],
        b: &[f64],
        atb: &[f64],
        sigx: &[f64],
        sigy: &[f64],
        delta: &[f64],
        au: &mut [f64],
        g: &mut [f64],
        g2: &mut [f64],
        lag: &mut Lagrangian,
        ws: &mut Work,
    ) {
        self.a.apply(u, au);
        self.a.adjoint(au, g);
        for (gi, &ai) in g.iter_mut().zip(atb) {
            *gi -= ai;
        }
        self.update_w(ux, uy, wx, wy, sigx, sigy, g2, lag, ws);
        let (lam3, lam5) = r_terms(au, b, delta);
        lag.lam3 = lam3;
        lag.lam5 = lam5;
    }

    /// V = DU − W, g2 = Dᵀ V, lam2 = ||V||², lam4 = <sigma, V>.
    #[allow(clippy::too_many_arguments)]
    fn update_w(
        &self,
        ux: &[f64],
        uy: &[f64],
        wx: &[f64],
        wy: &[f64],
        sigx: &[f64],
        sigy: &[f64],
        g2: &mut [f64],
        lag: &mut Lagrangian,
        ws: &mut Work,
    ) {
        let (vxs, vys) = (&mut ws.vx, &mut ws.vy);
        let (lam2, lam4) = sum2(ux.len(), |i| {
            let vx = ux[i] - wx[i];
            let vy = uy[i] - wy[i];
            vxs[i] = vx;
            vys[i] = vy;
            (vx * vx + vy * vy, sigx[i] * vx + sigy[i] * vy)
        });
        self.grid.dt(&ws.vx, &ws.vy, g2);
        lag.lam2 = lam2;
        lag.lam4 = lam4;
    }
}

/// (lam2, lam4) = (||DU − W||², <sigma, DU − W>).
fn v_terms(ux: &[f64], uy: &[f64], wx: &[f64], wy: &[f64], sx: &[f64], sy: &[f64]) -> (f64, f64) {
    sum2(ux.len(), |i| {
        let vx = ux[i] - wx[i];
        let vy = uy[i] - wy[i];
        (vx * vx + vy * vy, sx[i] * vx + sy[i] * vy)
    })
}

/// (lam3, lam5) = (||AU − b||², <delta, AU − b>).
fn r_terms(au: &[f64], b: &[f64], delta: &[f64]) -> (f64, f64) {
    sum2(au.len(), |i| {
        let r = au[i] - b[i];
        (r * r, delta[i] * r)
    })
}

/// An iterate U and what TVAL3 derives from it: DU (ux, uy), AU, the data term's gradient g
/// and the TV term's g2. As `State::step`, the differences between two iterates.
struct Iterate {
    u: Vec<f64>,
    ux: Vec<f64>,
    uy: Vec<f64>,
    au: Vec<f64>,
    g: Vec<f64>,
    g2: Vec<f64>,
}

impl Iterate {
    fn zeros(n: usize, m: usize) -> Self {
        Iterate {
            u: vec![0.0; n],
            ux: vec![0.0; n],
            uy: vec![0.0; n],
            au: vec![0.0; m],
            g: vec![0.0; n],
            g2: vec![0.0; n],
        }
    }
}

/// Everything the iterations change (TVAL3 names; `prev` is the previous iterate, TVAL3's
/// `p` suffixes).
struct State {
    cur: Iterate,
    prev: Iterate,
    step: Iterate,
    /// The pre-processed data, Aᵀb, the scaling of b and ||b||.
    b: Vec<f64>,
    atb: Vec<f64>,
    scl: f64,
    nrm_b: f64,
    wx: Vec<f64>,
    wy: Vec<f64>,
    sigx: Vec<f64>,
    sigy: Vec<f64>,
    delta: Vec<f64>,
    dts_atd: Vec<f64>,
    /// The search direction.
    d: Vec<f64>,
    /// U at the end of the last inner loop.
    rcd_u: Vec<f64>,
    ws: Work,
    lag: Lagrangian,
    mu: f64,
    beta: f64,
    /// The augmented Lagrangian at U, its non-monotone reference and weight.
    f: f64,
    c_ref: f64,
    q: f64,
    gam: f64,
    /// Whether U and `prev` are two steps of the same inner loop (BB step possible).
    have_prev: bool,
    /// Inner loops begun (TVAL3's `count`).
    count: usize,
}

impl State {
    /// mu/beta, the weight of the data term's gradient in the direction.
    #[inline]
    fn mu_d_beta(&self) -> f64 {
        self.mu / self.beta
    }

    /// The differences between the full step and Up, once per line search (the step in u is
    /// already there).
    fn step_differences(&mut self) {
        let (c, p, d) = (&self.cur, &self.prev, &mut self.step);
        for i in 0..c.u.len() {
            d.g[i] = c.g[i] - p.g[i];
            d.g2[i] = c.g2[i] - p.g2[i];
            d.ux[i] = c.ux[i] - p.ux[i];
            d.uy[i] = c.uy[i] - p.uy[i];
        }
        for i in 0..c.au.len() {
            d.au[i] = c.au[i] - p.au[i];
        }
    }

    /// The iterate at Up + alpha (U − Up) and the Lagrangian there. Everything is affine in U
    /// with W fixed, so the chord point needs no product.
    fn chord_point(&mut self, alpha: f64) {
        let (c, p, d) = (&mut self.cur, &self.prev, &self.step);
        for i in 0..c.u.len() {
            c.g[i] = p.g[i] + alpha * d.g[i];
            c.g2[i] = p.g2[i] + alpha * d.g2[i];
            c.u[i] = p.u[i] + alpha * d.u[i];
            c.ux[i] = p.ux[i] + alpha * d.ux[i];
            c.uy[i] = p.uy[i] + alpha * d.uy[i];
        }
        for i in 0..c.au.len() {
            c.au[i] = p.au[i] + alpha * d.au[i];
        }
        let (lam2, lam4) = v_terms(&c.ux, &c.uy, &self.wx, &self.wy, &self.sigx, &self.sigy);
        self.lag.lam2 = lam2;
        self.lag.lam4 = lam4;
        let (lam3, lam5) = r_terms(&c.au, &self.b, &self.delta);
        self.lag.lam3 = lam3;
        self.lag.lam5 = lam5;
        self.f = self.lag.f(self.beta, self.mu);
    }

    /// The new direction d and (||U − Up||², ||Up||) for the inner stopping test.
    fn new_direction(&mut self) -> (f64, f64) {
        let mu_d_beta = self.mu_d_beta();
        let (c, p, d, dts_atd) = (&self.cur, &self.prev, &mut self.d, &self.dts_atd);
        let (nrm_uup, nrm_up) = sum2(c.u.len(), |i| {
            d[i] = c.g2[i] + mu_d_beta * c.g[i] - dts_atd[i];
            let s = c.u[i] - p.u[i];
            (s * s, p.u[i] * p.u[i])
        });
        let nrm_up = nrm_up.sqrt();
        (nrm_uup.sqrt() / nrm_up, nrm_up)
    }
}

/// Scratch vectors.
struct Work {
    dx: Vec<f64>,
    dy: Vec<f64>,
    ad: Vec<f64>,
    vx: Vec<f64>,
    vy: Vec<f64>,
}

impl Work {
    fn new(n: usize, m: usize) -> Self {
        Work {
            dx: vec![0.0; n],
            dy: vec![0.0; n],
            ad: vec![0.0; m],
            vx: vec![0.0; n],
            vy: vec![0.0; n],
        }
    }
}
