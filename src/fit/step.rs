//! Finite-difference slopes of a Monte Carlo model, with their noise, and the step that keeps
//! that noise small.
//!
//! Every evaluation of the fit traces with the same rays (common random numbers), so the
//! difference of two evaluations does not carry the full noise of either. It is not free of
//! noise either: where a variable moves light across a diode's or a pupil's edge, the rays that
//! cross the edge between the two points jump from one side to the other, and their number is
//! a Poisson count. For a step h its variance grows as h, so the slope's variance falls only as
//! 1/h; with a step of 1 % of the range the slope is mostly that count. The noise does not
//! average out in JᵀJ: E[ŝ²] = s² + var ŝ, so a noisy column overstates the curvature of χ²
//! and the standard errors that come from it are too small.
//!
//! The classic optimum for a central difference balances the noise σ/h against the truncation
//! error h²·|f'''|/6: h = (3σ/|f'''|)^(1/3) (P. E. Gill, W. Murray and M. H. Wright, *Practical
//! Optimization*, Academic Press 1981, §8.6). Here σ itself depends on h (the crossing count),
//! and what matters is the noise's share of the column's squared norm, so the rule is the
//! practical variant: the slope's noise is measured at the trial step from the trace's own
//! batches (each batch's difference at the two points, the same rays at both, less its share
//! of the total: batch means), and when its share of Σŝ² exceeds [`Rule::noise_share`] the step
//! is widened by that share's excess (the 1/h law of the crossing count), within
//! [`Rule::floor`] and [`Rule::ceiling`] of the unit box. The ceiling bounds the truncation
//! error: a central difference of half-width 0.15 of the box is exact for a quadratic and off
//! by h²·f'''/6 for a cubic. At a bound the difference is one-sided (the point and one step
//! inward).

use crate::error::Result;

/// One evaluation of a vector of model outputs with its Monte Carlo batches: each batch's value
/// of every output less its share of the total (batch means), and the batch-means factor
/// B/(B − 1) (the variance of an output is factor·Σ_b deviation²).
#[derive(Debug, Clone)]
pub struct Sampled {
    pub values: Vec<f64>,
    /// [batch][output].
    pub deviations: Vec<Vec<f64>>,
    pub factor: f64,
}

/// How the step is chosen (unit box).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rule {
    /// The step tried first.
    pub first: f64,
    /// The smallest step: below it the crossing count of a trace is a few rays.
    pub floor: f64,
    /// The largest: the truncation error stays small beside the slope.
    pub ceiling: f64,
    /// The largest share of Σŝ² that noise may take before the step is widened.
    pub noise_share: f64,
}

/// The fit's rule: a 3 % step first, 3 % to 15 % of the box, noise at most 5 % of Σŝ² (the
/// standard errors then come out at most ≈ 2.5 % small from the noise).
pub const RULE: Rule = Rule {
    first: 0.03,
    floor: 0.03,
    ceiling: 0.15,
    noise_share: 0.05,
};

/// One column of the Jacobian.
#[derive(Debug, Clone)]
pub struct Column {
    /// ŝ_k for every output.
    pub slope: Vec<f64>,
    /// var ŝ_k, from the batches.
    pub variance: Vec<f64>,
    /// The step's half-width (central) or width (one-sided).
    pub step: f64,
    /// Σ var ŝ / Σ ŝ²: the noise's share of the column's squared norm.
    pub noise_share: f64,
}

/// The two points of the difference at `u` with step `h` in the unit box: central where both
/// lie inside, else the point and one step inward (one-sided).
pub fn stencil(u: f64, h: f64) -> (f64, f64) {
    if u - h >= 0.0 && u + h <= 1.0 {
        (u - h, u + h)
    } else if u + h <= 1.0 {
        (u, u + h)
    } else {
        (u - h, u)
    }
}

/// The slope between two evaluations `a` at `ta` and `b` at `tb` (same rays), with each
/// output's variance from the batches of the difference.
pub fn difference(a: &Sampled, ta: f64, b: &Sampled, tb: f64) -> Column {
    let dt = tb - ta;
    let slope: Vec<f64> = b
        .values
        .iter()
        .zip(&a.values)
        .map(|(y, x)| (y - x) / dt)
        .collect();
    let mut variance = vec![0.0; slope.len()];
    for (db, da) in b.deviations.iter().zip(&a.deviations) {
        for (v, (y, x)) in variance.iter_mut().zip(db.iter().zip(da)) {
            let d = (y - x) / dt;
            *v += d * d;
        }
    }
    let factor = 0.5 * (a.factor + b.factor);
    for v in &mut variance {
        *v *= factor;
    }
    let s2: f64 = slope.iter().map(|s| s * s).sum();
    let n2: f64 = variance.iter().sum();
    let noise_share = if s2 > 0.0 { n2 / s2 } else { f64::INFINITY };
    Column {
        slope,
        variance,
        step: dt.abs(),
        noise_share,
    }
}

/// The step to use after one at `h` left `share` of Σŝ² to noise: widened by the share's
/// excess over the rule's (the slope's noise variance falls as 1/h where rays cross edges),
/// narrowed likewise when the noise is far below it (a smaller truncation error), within the
/// rule's floor and ceiling. A column without signal (share ≥ 1 or not finite) gets the
/// ceiling.
pub fn next_step(h: f64, share: f64, rule: &Rule) -> f64 {
    if !share.is_finite() || share >= 1.0 {
        return rule.ceiling;
    }
    (h * share / rule.noise_share).clamp(rule.floor, rule.ceiling)
}

/// The slope of `f` (evaluated at points of the unit box) at `u`: a first difference at step
/// `h`; when its noise share exceeds the rule's and the step can widen, a second at the wider
/// step ([`next_step`]). Returns the column and the step the next call should try.
pub fn column(
    f: &mut dyn FnMut(f64) -> Result<Sampled>,
    u: f64,
    h: f64,
    rule: &Rule,
) -> Result<(Column, f64)> {
    let eval = |f: &mut dyn FnMut(f64) -> Result<Sampled>, h: f64| -> Result<Column> {
        let (ta, tb) = stencil(u, h);
        let (a, b) = (f(ta)?, f(tb)?);
        Ok(difference(&a, ta, &b, tb))
    };
    let h = h.clamp(rule.floor, rule.ceiling);
    let mut c = eval(f, h)?;
    let mut next = next_step(h, c.noise_share, rule);
    if c.noise_share > rule.noise_share && next > h * 1.25 {
        c = eval(f, next)?;
        next = next_step(next, c.noise_share, rule).max(next);
    }
    Ok((c, next))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model whose outputs count rays past an edge, as a diode edge does: output k at t is the
    /// share of its own N rays with s_j < t + a_k, s_j drawn with cumulative t³ on [0, 1]
    /// (s = v^(1/3), v uniform), so its mean is (t + a_k)³ (slope 3(t + a_k)², f‴ = 6), and
    /// every evaluation uses the same rays (common random numbers), in batches of 10.
    struct EdgeModel {
        rays: Vec<Vec<f64>>,
        offsets: Vec<f64>,
    }

    const N: usize = 200;
    const OUTPUTS: usize = 40;
    const BATCH: usize = 10;

    impl EdgeModel {
        fn new() -> Self {
            let mut state = 0x2545_f491_4f6c_dd1du64;
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ((state >> 11) as f64 / (1u64 << 53) as f64).cbrt()
            };
            let rays = (0..OUTPUTS)
                .map(|_| (0..N).map(|_| next()).collect())
                .collect();
            // Offsets keep t + a_k inside (0.3, 0.8) at t = 0.5.
            let offsets = (0..OUTPUTS)
                .map(|k| -0.2 + 0.5 * k as f64 / OUTPUTS as f64)
                .collect();
            EdgeModel { rays, offsets }
        }

        fn eval(&self, t: f64) -> Sampled {
            let n = N as f64;
            let nb = N / BATCH;
            // [output][batch]
            let per: Vec<Vec<f64>> = self
                .rays
                .iter()
                .zip(&self.offsets)
                .map(|(r, a)| {
                    r.chunks(BATCH)
                        .map(|c| c.iter().filter(|&&s| s < t + a).count() as f64 / n)
                        .collect()
                })
                .collect();
            let values: Vec<f64> = per.iter().map(|b| b.iter().sum()).collect();
            let deviations = (0..nb)
                .map(|b| {
                    per.iter()
                        .zip(&values)
                        .map(|(p, v)| p[b] - v / nb as f64)
                        .collect()
                })
                .collect();
            Sampled {
                values,
                deviations,
                factor: nb as f64 / (nb as f64 - 1.0),
            }
        }

        fn slope(&self, t: f64) -> Vec<f64> {
            self.offsets
                .iter()
                .map(|a| 3.0 * (t + a) * (t + a))
                .collect()
        }
    }

    fn norm2(v: &[f64]) -> f64 {
        v.iter().map(|x| x * x).sum()
    }

    #[test]
    fn a_small_forward_step_overstates_the_slopes_and_the_rule_does_not() {
        let m = EdgeModel::new();
        let t = 0.5;
        let truth = m.slope(t);
        // Forward difference at 0.2 % of the box: E[Σŝ²] = Σs² + Σ var ŝ with var ŝ_k ≈
        // s_k/(N·h) (a Poisson count of N·s_k·h crossings), so E[Σŝ²]/Σs² − 1 =
        // Σ s_k/(N·h·Σ s_k²) ≈ 2.1 here: the squared norm is tripled, and a standard error
        // from it ≈ 40 % small.
        let h = 0.002;
        let expect: f64 = truth.iter().sum::<f64>() / (N as f64 * h) / norm2(&truth);
        assert!(expect > 2.0, "{expect}");
        let fwd = difference(&m.eval(t), t, &m.eval(t + h), t + h);
        let ratio = norm2(&fwd.slope) / norm2(&truth);
        assert!(ratio > 1.5, "forward Σŝ²/Σs² {ratio}");
        // Its own batches see the noise.
        assert!(fwd.noise_share > 0.3, "{}", fwd.noise_share);

        let mut f = |x: f64| Ok(m.eval(x));
        let (c, next) = column(&mut f, t, RULE.first, &RULE).unwrap();
        assert!(c.step >= RULE.floor && next <= RULE.ceiling);
        // Central difference of a cubic: truncation h²·f‴/6 = h² ≤ 0.02 at these steps, a
        // tenth of the slopes' noise (√(s/(2Nh)) ≈ 0.2). The slopes are within their stated
        // errors: Σ z² over 40 independent outputs, each z a t-variable with 19 degrees of
        // freedom (20 batches), has mean 44.7 and standard deviation 11; 90 is above its
        // 1-in-1000 point.
        let z2: f64 = c
            .slope
            .iter()
            .zip(&truth)
            .zip(&c.variance)
            .map(|((s, t), v)| (s - t) * (s - t) / v)
            .sum();
        assert!(z2 < 90.0, "Σz² {z2} at step {}", c.step);
        // The squared norm is no longer inflated: the rule holds the noise near 5 % of Σŝ²,
        // and the sampling error of Σŝ²/Σs² is 2·√(share/40) ≈ 7 %: within 0.3 of 1 (four of
        // those), where the forward difference's is 3.
        let r = norm2(&c.slope) / norm2(&truth);
        assert!((r - 1.0).abs() < 0.3, "Σŝ²/Σs² {r} at step {}", c.step);
        assert!(
            c.noise_share < 2.0 * RULE.noise_share,
            "share {} step {}",
            c.noise_share,
            c.step
        );
    }

    #[test]
    fn the_stencil_is_central_inside_and_one_sided_at_a_bound() {
        assert_eq!(stencil(0.5, 0.1), (0.4, 0.6));
        assert_eq!(stencil(0.0, 0.1), (0.0, 0.1));
        assert_eq!(stencil(1.0, 0.1), (0.9, 1.0));
        assert_eq!(next_step(0.03, 0.2, &RULE), 0.12);
        assert_eq!(next_step(0.03, 0.9, &RULE), RULE.ceiling);
        assert_eq!(next_step(0.05, 0.001, &RULE), RULE.floor);
        assert_eq!(next_step(0.05, f64::NAN, &RULE), RULE.ceiling);
    }
}
