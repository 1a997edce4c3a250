//! The coarse start of the fit, before Levenberg–Marquardt.
//!
//! A misalignment often leaves the light unchanged near the nominal bench (a spot inside its
//! diode, a lens whose pupil is not yet clipped), where the gradient is zero and
//! Levenberg–Marquardt would not move: each variable in turn is set to the best of
//! [`COARSE_POINTS`] evenly spaced values across its bounds, the others held, twice over (a
//! coordinate scan). Alone, that scan follows the axes: two variables that trade off (the two
//! arms' lens decentres move the same frames) can leave it in a valley on the wrong side, which
//! the first axis it scans happens to see first. So every pair of variables is also tried on a
//! [`PAIR_LEVELS`]² grid (the others at the start).
//!
//! A lens decentred by +d and by −d clips its pupil alike, so the misfit has a valley on each
//! side, and the grid point with the lowest χ² need not lie in the deeper one's basin (a broad
//! shallow valley wins at the grid's coarse levels over a narrow deep one). So the start is not
//! one point but several ([`coarse_starts`]): every *local* minimum of a pair's grid (a point
//! below each of its grid neighbours) is refined by the coordinate scan, as is the start
//! itself; the refined points are ordered by χ², those within a coordinate scan's grid step
//! ([`DISTINCT`]) of a better one dropped, and Levenberg–Marquardt runs from the best
//! [`MAX_STARTS`] ([`best_of_starts`]), the lowest optimum kept. Everything is in a fixed
//! order (pairs, levels, a stable sort), so the starts are deterministic in the seed.

use crate::error::Result;

/// Points per variable of the coordinate scan.
pub const COARSE_POINTS: usize = 9;
/// The levels of each pair's grid (unit box): the centres of the thirds.
pub const PAIR_LEVELS: [f64; 3] = [1.0 / 6.0, 0.5, 5.0 / 6.0];
/// The most starts Levenberg–Marquardt runs from.
pub const MAX_STARTS: usize = 3;
/// Two starts closer than this in every variable (unit box) are one: the coordinate scan's
/// grid step, below which the scan cannot tell them apart.
pub const DISTINCT: f64 = 1.0 / (COARSE_POINTS - 1) as f64;

/// A point of the unit box and its χ².
pub type Scored = (Vec<f64>, f64);

/// The coordinate scan from `u` (χ² there `best`): the point and its χ².
fn coordinate_scan(
    chi2: &mut dyn FnMut(&[f64]) -> Result<f64>,
    mut u: Vec<f64>,
    mut best: f64,
) -> Result<Scored> {
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

/// A descent from `u` (χ² there `best`) that stays in its basin: each variable in turn moves
/// one coordinate-scan step ([`DISTINCT`]) either way while that lowers χ², until no move does
/// (at most `COARSE_POINTS` passes). [`coordinate_scan`] looks along each whole axis and can
/// leave a narrow valley for a broad one that its axis crosses; a pair grid's local minimum is
/// refined by this instead, so that its valley is kept for Levenberg–Marquardt.
fn local_scan(
    chi2: &mut dyn FnMut(&[f64]) -> Result<f64>,
    mut u: Vec<f64>,
    mut best: f64,
) -> Result<Scored> {
    for _pass in 0..COARSE_POINTS {
        let mut moved = false;
        for i in 0..u.len() {
            for dir in [-1.0, 1.0] {
                let mut v = u.clone();
                v[i] = (v[i] + dir * DISTINCT).clamp(0.0, 1.0);
                if v == u {
                    continue;
                }
                let c = chi2(&v)?;
                if c < best {
                    (best, u, moved) = (c, v, true);
                }
            }
        }
        if !moved {
            break;
        }
    }
    Ok((u, best))
}

/// The local minima of every pair's grid around `u` (the others held): the grid points whose
/// χ² is finite and below that of each neighbour along a level, in the order found.
fn pair_minima(chi2: &mut dyn FnMut(&[f64]) -> Result<f64>, u: &[f64]) -> Result<Vec<Scored>> {
    let n = PAIR_LEVELS.len();
    let mut found = Vec::new();
    for i in 0..u.len() {
        for j in i + 1..u.len() {
            let mut grid = [[0.0; 3]; 3];
            let mut points = Vec::with_capacity(n * n);
            for (a, &x) in PAIR_LEVELS.iter().enumerate() {
                for (b, &y) in PAIR_LEVELS.iter().enumerate() {
                    let mut v = u.to_vec();
                    (v[i], v[j]) = (x, y);
                    grid[a][b] = chi2(&v)?;
                    points.push(v);
                }
            }
            for a in 0..n {
                for b in 0..n {
                    let c = grid[a][b];
                    let below = |a2: usize, b2: usize| c < grid[a2][b2];
                    let local = c.is_finite()
                        && (a == 0 || below(a - 1, b))
                        && (a + 1 == n || below(a + 1, b))
                        && (b == 0 || below(a, b - 1))
                        && (b + 1 == n || below(a, b + 1));
                    if local {
                        found.push((points[a * n + b].clone(), c));
                    }
                }
            }
        }
    }
    Ok(found)
}

/// Orders `points` by χ² (stable: ties keep their order) and keeps at most `max`, each more
/// than [`DISTINCT`] from every better one kept in some variable.
fn distinct_best(mut points: Vec<Scored>, max: usize) -> Vec<Scored> {
    points.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut kept: Vec<Scored> = Vec::new();
    for p in points {
        if kept.len() == max {
            break;
        }
        let near = kept.iter().any(|k| {
            k.0.iter()
                .zip(&p.0)
                .all(|(a, b)| (a - b).abs() <= DISTINCT + 1e-12)
        });
        if !near {
            kept.push(p);
        }
    }
    kept
}

/// The starts from `u` (module notes): at most `max` distinct points, best first, each with its
/// χ²; `chi2` the misfit at a point of the unit box (infinite where the bench does not build).
/// Never empty: the coordinate scan from `u` is always a candidate.
pub fn coarse_starts(
    chi2: &mut dyn FnMut(&[f64]) -> Result<f64>,
    u: Vec<f64>,
    max: usize,
) -> Result<Vec<Scored>> {
    let c0 = chi2(&u)?;
    let minima = distinct_best(pair_minima(chi2, &u)?, max.max(1));
    let mut candidates = vec![coordinate_scan(chi2, u, c0)?];
    for (g, cg) in minima {
        candidates.push(local_scan(chi2, g, cg)?);
    }
    Ok(distinct_best(candidates, max.max(1)))
}

/// The single best coarse start from `u` ([`coarse_starts`] with one start).
pub fn coarse_search(chi2: &mut dyn FnMut(&[f64]) -> Result<f64>, u: Vec<f64>) -> Result<Vec<f64>> {
    let mut s = coarse_starts(chi2, u, 1)?;
    Ok(s.swap_remove(0).0)
}

/// Runs `local` (Levenberg–Marquardt in the fit) from each start in order and returns every
/// start's optimum with its χ² and the index of the lowest (the first of equals).
pub fn best_of_starts(
    starts: &[Scored],
    local: &mut dyn FnMut(Vec<f64>) -> Result<Scored>,
) -> Result<(usize, Vec<Scored>)> {
    let mut ends = Vec::with_capacity(starts.len());
    for (u, _) in starts {
        ends.push(local(u.clone())?);
    }
    let best = ends
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.1.total_cmp(&b.1.1))
        .map_or(0, |(k, _)| k);
    Ok((best, ends))
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
    /// A broad shallow valley at (0.2, 0.5), floor χ² = 1, and a narrow deep one at (0.8, 0.7),
    /// floor 0. On the pair grid the shallow valley's point (1/6, 1/2) is the best (χ² 1.04)
    /// and the deep valley's (5/6, 5/6) only a local minimum (7.6, its neighbours 9.0 and 16.4);
    /// the coordinate scan from it reaches (5/6, 3/4) at 1.44, still above the shallow floor.
    fn shallow_and_deep(v: &[f64]) -> f64 {
        let (x, y) = (v[0], v[1]);
        let deep = 400.0 * ((x - 0.8).powi(2) + (y - 0.7).powi(2));
        let shallow = 1.0 + 40.0 * ((x - 0.2).powi(2) + (y - 0.5).powi(2));
        deep.min(shallow)
    }

    /// A local descent standing in for Levenberg–Marquardt: steepest descent with backtracking,
    /// central-difference gradient, projected onto the box; it stays in its start's basin.
    fn descend(f: fn(&[f64]) -> f64, mut u: Vec<f64>) -> Scored {
        let mut c = f(&u);
        let mut step = 0.1;
        for _ in 0..2000 {
            let g: Vec<f64> = (0..u.len())
                .map(|i| {
                    let (mut a, mut b) = (u.clone(), u.clone());
                    a[i] -= 1e-7;
                    b[i] += 1e-7;
                    (f(&b) - f(&a)) / 2e-7
                })
                .collect();
            let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm < 1e-9 || step < 1e-12 {
                break;
            }
            let t: Vec<f64> = u
                .iter()
                .zip(&g)
                .map(|(a, d)| (a - step * d / norm).clamp(0.0, 1.0))
                .collect();
            let ct = f(&t);
            if ct < c {
                (u, c) = (t, ct);
                step *= 1.5;
            } else {
                step *= 0.5;
            }
        }
        (u, c)
    }

    #[test]
    fn a_second_start_reaches_the_deeper_valley_the_best_grid_point_misses() {
        let mut f = |v: &[f64]| Ok(shallow_and_deep(v));
        let mut local = |u: Vec<f64>| Ok(descend(shallow_and_deep, u));
        // One start: the best grid point, in the shallow valley's basin; descent ends on its
        // floor, χ² 1.
        let one = coarse_starts(&mut f, vec![0.5, 0.5], 1).unwrap();
        assert_eq!(one.len(), 1);
        assert!((one[0].0[0] - 1.0 / 6.0).abs() < 1e-12, "{one:?}");
        let (k, ends) = best_of_starts(&one, &mut local).unwrap();
        assert!((ends[k].1 - 1.0).abs() < 1e-6, "{ends:?}");
        // Several: the start's own scan ends at (1/4, 1/2), within a grid step of the shallow
        // valley's grid point, so it is dropped; the deep valley's local minimum, refined in its
        // basin, is the first start, the shallow one the second, and the deep one's descent
        // reaches the true floor, χ² 0 at (0.8, 0.7).
        let starts = coarse_starts(&mut f, vec![0.5, 0.5], MAX_STARTS).unwrap();
        assert_eq!(starts.len(), 2, "{starts:?}");
        assert!(starts[0].1 <= starts[1].1);
        assert!((starts[0].0[0] - 5.0 / 6.0).abs() < 1e-12, "{starts:?}");
        assert!((starts[1].0[0] - 1.0 / 6.0).abs() < 1e-12, "{starts:?}");
        let (k, ends) = best_of_starts(&starts, &mut local).unwrap();
        assert_eq!(k, 0, "{ends:?}");
        assert!(ends[k].1 < 1e-6, "{ends:?}");
        assert!(
            (ends[k].0[0] - 0.8).abs() < 1e-3 && (ends[k].0[1] - 0.7).abs() < 1e-3,
            "{ends:?}"
        );
        assert!((ends[1].1 - 1.0).abs() < 1e-6, "{ends:?}");
    }

    #[test]
    fn starts_closer_than_a_grid_step_are_one() {
        let pts = vec![
            (vec![0.5, 0.5], 2.0),
            (vec![0.4, 0.55], 1.0),
            (vec![0.9, 0.5], 3.0),
            (vec![0.1, 0.1], 4.0),
        ];
        let kept = distinct_best(pts, 2);
        assert_eq!(kept, vec![(vec![0.4, 0.55], 1.0), (vec![0.9, 0.5], 3.0)]);
    }
}
