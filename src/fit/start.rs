//! The coarse start of the fit, before Levenberg–Marquardt.
//!
//! A misalignment often leaves the light unchanged near the nominal bench (a spot inside its
//! diode, a lens whose pupil is not yet clipped), where the gradient is zero and
//! Levenberg–Marquardt would not move: each variable in turn is set to the best of
//! [`COARSE_POINTS`] evenly spaced values across its bounds, the others held, twice over (a
//! coordinate scan). Alone, that scan follows the axes: two variables that trade off (the two
//! arms' lens decentres move the same frames) can leave it in a valley on the wrong side, which
//! the first axis it scans happens to see first. So every pair of variables is also tried on a
//! [`PAIR_LEVELS`]² grid (the others at the start), and the coordinate scan runs from the start
//! and from the best grid point; the lower χ² wins.

use crate::error::Result;

/// Points per variable of the coordinate scan.
pub const COARSE_POINTS: usize = 9;
/// The levels of each pair's grid (unit box): the centres of the thirds.
pub const PAIR_LEVELS: [f64; 3] = [1.0 / 6.0, 0.5, 5.0 / 6.0];

/// The coordinate scan from `u` (χ² there `best`): the point and its χ².
fn coordinate_scan(
    chi2: &mut dyn FnMut(&[f64]) -> Result<f64>,
    mut u: Vec<f64>,
    mut best: f64,
) -> Result<(Vec<f64>, f64)> {
    for _sweep in 0..2 {
        for i in 0..u.len() {
            for k in 0..COARSE_POINTS {
                let mut v = u.clone();
                v[i] = k as f64 / (COARSE_POINTS - 1) as f64;
                if v == u {
                    continue;
                }
                let c = chi2(&v)?;
                if c < best {
                    (best, u) = (c, v);
                }
            }
        }
    }
    Ok((u, best))
}

/// The best point of every pair's grid around `u` (the others held), if better than `best`.
fn pair_grid(
    chi2: &mut dyn FnMut(&[f64]) -> Result<f64>,
    u: &[f64],
    best: f64,
) -> Result<Option<(Vec<f64>, f64)>> {
    let mut found: Option<(Vec<f64>, f64)> = None;
    for i in 0..u.len() {
        for j in i + 1..u.len() {
            for a in PAIR_LEVELS {
                for b in PAIR_LEVELS {
                    let mut v = u.to_vec();
                    (v[i], v[j]) = (a, b);
                    let c = chi2(&v)?;
                    if c < found.as_ref().map_or(best, |f| f.1) {
                        found = Some((v, c));
                    }
                }
            }
        }
    }
    Ok(found)
}

/// The coarse start from `u` (module notes); `chi2` the misfit at a point of the unit box
/// (infinite where the bench does not build).
pub fn coarse_search(chi2: &mut dyn FnMut(&[f64]) -> Result<f64>, u: Vec<f64>) -> Result<Vec<f64>> {
    let c0 = chi2(&u)?;
    let grid = pair_grid(chi2, &u, c0)?;
    let axes = coordinate_scan(chi2, u, c0)?;
    let Some((g, cg)) = grid else {
        return Ok(axes.0);
    };
    let other = coordinate_scan(chi2, g, cg)?;
    Ok(if other.1 < axes.1 { other.0 } else { axes.0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two valleys: a broad shallow one at (0.25, 0.5), its floor at χ² = 1, which the axes
    /// through the centre cross, and the true one, narrow, at (0.8, 0.8), χ² = 0, which they
    /// miss (χ² ≥ 9 on them).
    fn two_valleys(v: &[f64]) -> f64 {
        let (x, y) = (v[0], v[1]);
        let a = 100.0 * ((x - 0.8).powi(2) + (y - 0.8).powi(2));
        let b = 1.0 + 10.0 * ((x - 0.25).powi(2) + (y - 0.5).powi(2));
        a.min(b)
    }

    #[test]
    fn the_pair_grid_finds_the_valley_the_axes_miss() {
        let mut evals = 0;
        let mut f = |v: &[f64]| {
            evals += 1;
            Ok(two_valleys(v))
        };
        // The coordinate scan alone stays in the shallow valley.
        let (axes, c) = coordinate_scan(&mut f, vec![0.5, 0.5], two_valleys(&[0.5, 0.5])).unwrap();
        assert!(c >= 1.0 && (axes[0] - 0.25).abs() < 0.1, "{axes:?} χ² {c}");
        // With the pair grid the start lands in the true one, within a grid spacing (1/8).
        let u = coarse_search(&mut f, vec![0.5, 0.5]).unwrap();
        assert!(
            (u[0] - 0.8).abs() <= 0.125 && (u[1] - 0.8).abs() <= 0.125,
            "{u:?}"
        );
        assert!(two_valleys(&u) < 1.0);
        // One variable: no pairs, the scan alone.
        evals = 0;
        let mut g = |v: &[f64]| {
            evals += 1;
            Ok((v[0] - 0.3).powi(2))
        };
        let u = coarse_search(&mut g, vec![0.5]).unwrap();
        assert!(
            (u[0] - 0.25).abs() < 1e-12 || (u[0] - 0.375).abs() < 1e-12,
            "{u:?}"
        );
        // At most 1 + 2 sweeps × 9 points (a sweep that moves early revisits the start).
        assert!(evals <= 1 + 2 * COARSE_POINTS, "{evals}");
    }
}
