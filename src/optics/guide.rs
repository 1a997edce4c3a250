//! Chart-guided field sampling: aiming lamp rays at the clear areas of a chart.
//!
//! On a negative chart most of the lit field is chrome (OD ≈ 3): a ray aimed uniformly over the
//! field target lands on chrome about two times in three and then carries nothing to the DMD,
//! so the object x_j and the gains k± rest on the minority of rays that meet clear glass. This
//! module builds a third strategy for the lamp's direction mixture (see `optics::lamp`): aim at
//! points of the field target that the optics carry onto clear glass.
//!
//! The optics between the field target (a plane just in front of the collimator) and the chart
//! are summarised by a *proxy map*: for each of `WAVELENGTH_NODES` wavelength bands an affine map
//!
//! s = A·q + B·d + c,
//!
//! from the target point q and the filament point d (both as (u, v) offsets in the lamp frame, m)
//! to the point s where the ray meets the chart's chrome face (chart coordinates, m). It is
//! fitted by least squares to design rays traced through the real surfaces (refraction at the
//! band's centre wavelength, no Fresnel reflection, no absorption): in a Köhler-style bench A is
//! about the identity and B·d the shift due to the filament's angular size. The strategy draws s
//! from a piecewise-constant density over the chart proportional to the clear fraction of each
//! cell, and aims at q = A⁻¹(s − B·d − c).
//!
//! Unbiasedness does not depend on how good the map is. The density of q given d and λ is
//! exactly p_s(A·q + B·d + c)·|det A| for the map as fitted, which the lamp evaluates for every
//! ray whatever strategy drew it (one-sample multiple importance sampling, Veach 1997 §9.2), and
//! the other strategies keep the mixture positive wherever light can go. An imperfect map (lens
//! aberrations, the ND filters' tilt, dispersion within a band) only aims a little off the bars.

use glam::DVec3;
use rayon::prelude::*;

use super::bench::{Bench, ChartPlate, Interaction, Target};
use super::fresnel::{reflect, refract};
use super::geometry::Frame;
use super::lamp::{CdfIndex, EmitterShape, FieldTarget};

/// Wavelength bands of the proxy map. Dispersion moves the collimated beam's scale by ~3 % over
/// 350–1150 nm in N-BK7 (docs/bench-facts.md §3.4); 16 bands leave ≤ 0.2 % per band, a few µm at the
/// field's edge.
pub const WAVELENGTH_NODES: usize = 16;

/// Cells across the longer side of the density's window on the chart. 256 cells over a ~11 mm
/// window are ~45 µm: a tenth of the bar width in the paper's region (Group −1, ~0.6 mm), so few
/// rays are aimed at cells that are part chrome.
pub const GRID_CELLS: usize = 256;

/// Relative density of the one-cell rim around clear glass (see `ChartGuide::fit`).
const RIM_WEIGHT: f64 = 0.25;
const RIM: usize = 1;

/// Clear-fraction samples per cell side (the mask is evaluated on a 3×3 grid in each cell).
const SUPERSAMPLE: usize = 3;

/// Design rays per wavelength band: a 3×3 grid over the filament times a 5×5 grid over the
/// field target.
const FILAMENT_GRID: usize = 3;
const TARGET_GRID: usize = 5;

/// Step off a surface when following a design ray (m), as the tracer does (1 nm).
const STEP_OFF: f64 = 1e-9;

/// The affine proxy map of one wavelength band.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Affine {
    /// s = a·q + b·d + c (row-major 2×2 matrices).
    a: [[f64; 2]; 2],
    b: [[f64; 2]; 2],
    c: [f64; 2],
    a_inv: [[f64; 2]; 2],
    /// |det a|: the area scale from the target plane to the chart.
    det_abs: f64,
}

impl Affine {
    /// The map with its inverse, or `None` if it folds the plane (|det A| ≤ 1e-6: the chart
    /// would see the target's points nearly on top of each other).
    #[inline]
    fn new(a: [[f64; 2]; 2], b: [[f64; 2]; 2], c: [f64; 2]) -> Option<Affine> {
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        if det.abs().partial_cmp(&1e-6) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let a_inv = [
            [a[1][1] / det, -a[0][1] / det],
            [-a[1][0] / det, a[0][0] / det],
        ];
        Some(Affine {
            a,
            b,
            c,
            a_inv,
            det_abs: det.abs(),
        })
    }

    #[inline]
    fn apply(&self, q: (f64, f64), d: (f64, f64)) -> (f64, f64) {
        let (a, b, c) = (&self.a, &self.b, &self.c);
        (
            a[0][0] * q.0 + a[0][1] * q.1 + b[0][0] * d.0 + b[0][1] * d.1 + c[0],
            a[1][0] * q.0 + a[1][1] * q.1 + b[1][0] * d.0 + b[1][1] * d.1 + c[1],
        )
    }

    #[inline]
    fn invert(&self, s: (f64, f64), d: (f64, f64)) -> (f64, f64) {
        let (b, c, m) = (&self.b, &self.c, &self.a_inv);
        let r0 = s.0 - b[0][0] * d.0 - b[0][1] * d.1 - c[0];
        let r1 = s.1 - b[1][0] * d.0 - b[1][1] * d.1 - c[1];
        (m[0][0] * r0 + m[0][1] * r1, m[1][0] * r0 + m[1][1] * r1)
    }
}

/// The fitted strategy: proxy maps per wavelength band and the clear-area density on the chart.
#[derive(Debug, Clone)]
pub struct ChartGuide {
    /// Share of the field-aimed rays that this strategy draws (the rest are uniform over the
    /// field target).
    pub share: f64,
    /// Index of the chart in `Bench::charts`.
    pub chart: usize,
    band: (f64, f64),
    maps: Vec<Affine>,
    /// Window on the chart: lower-left corner (m), square cell side (m), cells across and down.
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    /// Cumulative distribution over rows (ny + 1 entries) and, per row, over its cells
    /// (nx + 1 entries each).
    row_cdf: Vec<f64>,
    col_cdf: Vec<f64>,
    /// Guide tables of `row_cdf` and of each row's CDF in `col_cdf` (exactly `pick`, faster).
    row_index: CdfIndex,
    col_index: Vec<CdfIndex>,
    /// Density of s per cell (1/m²).
    density: Vec<f64>,
    /// The largest RMS residual of the design rays about the fitted maps (m): how well the proxy
    /// map follows the optics (efficiency only).
    pub fit_rms_m: f64,
    /// Fraction of the window's area that is clear glass (before the rim is added).
    pub clear_fraction: f64,
}

impl ChartGuide {
    /// Fits the strategy for chart `chart` of `bench`, whose lamp must have a field target,
    /// over a `region` of the chart (width, height in m) centred on the image of the target's
    /// centre.
    /// Fails with a sentence when the design rays from the field target do not reach the chart
    /// or no clear glass lies in the part of the chart they reach.
    pub fn fit(
        bench: &Bench,
        chart: usize,
        share: f64,
        region: (f64, f64),
    ) -> Result<ChartGuide, String> {
        let lamp = &bench.lamp();
        let field = lamp
            .field
            .ok_or("chart guidance needs a field target (`field_sampling`)")?;
        if !(0.0..=1.0).contains(&share) {
            return Err(format!("the share must be in [0, 1], got {share}"));
        }
        let plate = bench
            .charts()
            .get(chart)
            .ok_or_else(|| format!("no chart {chart}"))?;
        let fr = &lamp.frame;
        let (du, dv) = match lamp.shape {
            EmitterShape::Rect { half_u, half_v } => (half_u, half_v),
            // The square inscribed in the disk.
            EmitterShape::Disk { radius } => (radius * 0.707, radius * 0.707),
        };
        // Design rays aim over the target plane within half the region's size around the
        // target's centre: the part that feeds the region if the optics image the target plane
        // near 1:1 onto the chart (a collimator; others still fit if most rays arrive).
        let (qu, qv) = (0.5 * region.0, 0.5 * region.1);
        if !(qu > 0.0 && qv > 0.0 && qu.is_finite() && qv.is_finite()) {
            return Err(format!(
                "the region must be positive, got {} × {} m",
                region.0, region.1
            ));
        }
        let (maps, fit_rms) = fit_maps(bench, chart, (&field, fr), (du, dv), (qu, qv))?;

        // The window: `region` (width, height in m) centred where the target's centre sends the
        // light from the filament's centre at the band's middle.
        let centre = maps[maps.len() / 2].apply((0.0, 0.0), (0.0, 0.0));
        let (w, h) = region;
        let cell = w.max(h) / GRID_CELLS as f64;
        let nx = ((w / cell).round() as usize).max(1);
        let ny = ((h / cell).round() as usize).max(1);
        let (x0, y0) = (
            centre.0 - 0.5 * nx as f64 * cell,
            centre.1 - 0.5 * ny as f64 * cell,
        );

        let (clear, glass) = clear_cells(plate, (x0, y0, cell), (nx, ny));
        let total: f64 = clear.iter().sum();
        if total <= 0.0 {
            return Err(
                "no clear glass of the chart lies in the part of it that the field target \
                 reaches"
                    .into(),
            );
        }
        let mut row_cdf = Vec::with_capacity(ny + 1);
        let mut col_cdf = Vec::with_capacity(ny * (nx + 1));
        let mut acc = 0.0;
        row_cdf.push(0.0);
        for i in 0..ny {
            let row = &clear[i * nx..(i + 1) * nx];
            let sum: f64 = row.iter().sum();
            acc += sum;
            row_cdf.push(acc / total);
            let mut c = 0.0;
            col_cdf.push(0.0);
            for &v in row {
                // A row without clear glass is never chosen; a uniform CDF keeps it finite.
                c += if sum > 0.0 { v / sum } else { 1.0 / nx as f64 };
                col_cdf.push(c);
            }
            col_cdf[i * (nx + 1) + nx] = 1.0;
        }
        row_cdf[ny] = 1.0;
        let density = clear.iter().map(|v| v / (total * cell * cell)).collect();
        let row_index = CdfIndex::new(&row_cdf);
        let col_index = col_cdf.par_chunks(nx + 1).map(CdfIndex::new).collect();
        Ok(ChartGuide {
            share,
            chart,
            band: bench.band(),
            maps,
            row_index,
            col_index,
            x0,
            y0,
            cell,
            nx,
            ny,
            row_cdf,
            col_cdf,
            density,
            fit_rms_m: fit_rms,
            clear_fraction: glass,
        })
    }

    /// The proxy map at λ: linear interpolation between the fitted band centres (constant
    /// beyond the outer ones). A deterministic function of λ, so sampling and density agree.
    #[inline]
    fn map(&self, wavelength_m: f64) -> Affine {
        let f = (wavelength_m - self.band.0) / (self.band.1 - self.band.0) * self.maps.len() as f64
            - 0.5;
        let last = self.maps.len() - 1;
        if f <= 0.0 {
            return self.maps[0];
        }
        if f >= last as f64 {
            return self.maps[last];
        }
        let k = f as usize;
        let t = f - k as f64;
        let (m0, m1) = (&self.maps[k], &self.maps[k + 1]);
        let mix = |x: f64, y: f64| x + t * (y - x);
        let a = [
            [mix(m0.a[0][0], m1.a[0][0]), mix(m0.a[0][1], m1.a[0][1])],
            [mix(m0.a[1][0], m1.a[1][0]), mix(m0.a[1][1], m1.a[1][1])],
        ];
        let b = [
            [mix(m0.b[0][0], m1.b[0][0]), mix(m0.b[0][1], m1.b[0][1])],
            [mix(m0.b[1][0], m1.b[1][0]), mix(m0.b[1][1], m1.b[1][1])],
        ];
        let c = [mix(m0.c[0], m1.c[0]), mix(m0.c[1], m1.c[1])];
        Affine::new(a, b, c).unwrap_or(*m0)
    }

    /// A target point q ((u, v) offset on the field plane, m) for the filament point d, from
    /// two uniforms.
    #[inline]
    pub fn sample(&self, a: f64, b: f64, d: (f64, f64), wavelength_m: f64) -> (f64, f64) {
        let (i, fa) = self.row_index.pick(&self.row_cdf, a);
        let row = &self.col_cdf[i * (self.nx + 1)..(i + 1) * (self.nx + 1)];
        let (j, fb) = self.col_index[i].pick(row, b);
        let s = (
            self.x0 + (j as f64 + fb) * self.cell,
            self.y0 + (i as f64 + fa) * self.cell,
        );
        self.map(wavelength_m).invert(s, d)
    }

    /// The density of target point q (per m² of the field plane) for the filament point d.
    #[inline]
    pub fn pdf(&self, q: (f64, f64), d: (f64, f64), wavelength_m: f64) -> f64 {
        let m = self.map(wavelength_m);
        let s = m.apply(q, d);
        let fx = (s.0 - self.x0) / self.cell;
        let fy = (s.1 - self.y0) / self.cell;
        if !(fx >= 0.0 && fy >= 0.0 && fx < self.nx as f64 && fy < self.ny as f64) {
            return 0.0;
        }
        self.density[fy as usize * self.nx + fx as usize] * m.det_abs
    }
}

/// The proxy maps of the `WAVELENGTH_NODES` bands, each fitted by least squares to the design
/// rays from a grid over the filament (half-sizes `d`) to a grid over the field target
/// (half-sizes `q`), and the largest RMS residual (m).
fn fit_maps(
    bench: &Bench,
    chart: usize,
    (field, fr): (&FieldTarget, &Frame),
    (du, dv): (f64, f64),
    (qu, qv): (f64, f64),
) -> Result<(Vec<Affine>, f64), String> {
    let grid = |n: usize| -> Vec<f64> {
        (0..n)
            .map(|k| 0.8 * (2.0 * k as f64 / (n - 1) as f64 - 1.0))
            .collect()
    };
    let (gf, gt) = (grid(FILAMENT_GRID), grid(TARGET_GRID));
    // One map per wavelength node, the nodes in parallel (each alone: the same maps on any
    // thread count). The design rays are the serial part of every bench's construction: 3 600
    // traced through the optics, about 4 ms for the paper bench on one thread, which the tolerance
    // and sweep jobs pay for every bench they build between parallel traces.
    let fitted: Vec<Result<(Affine, f64), String>> = (0..WAVELENGTH_NODES)
        .into_par_iter()
        .map(|k| {
            let wl = bench.band().0
                + (k as f64 + 0.5) * (bench.band().1 - bench.band().0) / WAVELENGTH_NODES as f64;
            fit_map(
                bench,
                chart,
                (field, fr),
                (du, dv),
                (qu, qv),
                (&gf, &gt),
                wl,
            )
        })
        .collect();
    // The first failing node's error, as the sequential fit reported it.
    let mut maps = Vec::with_capacity(WAVELENGTH_NODES);
    let mut fit_rms = 0.0f64;
    for f in fitted {
        let (map, rms) = f?;
        fit_rms = fit_rms.max(rms);
        maps.push(map);
    }
    Ok((maps, fit_rms))
}

/// The affine map from (target point, filament point) to the chart at wavelength `wl`, fitted
/// by least squares to the design rays of the grids `gf` (filament) and `gt` (target), and the
/// fit's RMS residual.
fn fit_map(
    bench: &Bench,
    chart: usize,
    (field, fr): (&FieldTarget, &Frame),
    (du, dv): (f64, f64),
    (qu, qv): (f64, f64),
    (gf, gt): (&[f64], &[f64]),
    wl: f64,
) -> Result<(Affine, f64), String> {
    let wanted = gf.len() * gf.len() * gt.len() * gt.len();
    // Features scaled to O(1) for a well-conditioned normal matrix.
    let mut rows: Vec<([f64; 5], [f64; 2])> = Vec::with_capacity(wanted);
    for &fa in gf {
        for &fb in gf {
            let d = (fa * du, fb * dv);
            let p = fr.origin + d.0 * fr.u + d.1 * fr.v;
            for &ta in gt {
                for &tb in gt {
                    let q = (ta * qu, tb * qv);
                    let aim = field.center + q.0 * fr.u + q.1 * fr.v;
                    if let Some(s) = follow_to_chart(bench, chart, p, (aim - p).normalize(), wl) {
                        rows.push(([ta, tb, fa, fb, 1.0], [s.0, s.1]));
                    }
                }
            }
        }
    }
    if rows.len() * 10 < wanted * 6 {
        return Err(format!(
            "only {} of {wanted} design rays from the field target reach the chart at \
             {:.0} nm: the field target must feed the chart through the optics",
            rows.len(),
            wl * 1e9
        ));
    }
    let (coef, rms) = least_squares(&rows)
        .ok_or("the design rays do not determine the map from the field target to the chart")?;
    // Undo the feature scaling: s = Σ coef·(q/qu, q/qv, d/du, d/dv, 1).
    let a = [
        [coef[0][0] / qu, coef[0][1] / qv],
        [coef[1][0] / qu, coef[1][1] / qv],
    ];
    let b = [
        [coef[0][2] / du, coef[0][3] / dv],
        [coef[1][2] / du, coef[1][3] / dv],
    ];
    let c = [coef[0][4], coef[1][4]];
    let map = Affine::new(a, b, c).ok_or(
        "the optics fold the field target onto a line on the chart: cannot aim through them",
    )?;
    Ok((map, rms))
}

/// The clear fraction of each of the `nx × ny` cells of side `cell` from (x0, y0) on the chart
/// (3 × 3 samples a cell), raised to a rim around the clear glass (below), and the mean clear
/// fraction before the rim.
fn clear_cells(
    plate: &ChartPlate,
    (x0, y0, cell): (f64, f64, f64),
    (nx, ny): (usize, usize),
) -> (Vec<f64>, f64) {
    let mut clear = vec![0.0; nx * ny];
    let sub = cell / SUPERSAMPLE as f64;
    // Rows in parallel: the 590 000 mask look-ups of the paper bench are ~40 ms on one thread,
    // a serial part of every bench's construction (each cell is computed alone, so the result
    // does not depend on the pool).
    clear.par_chunks_mut(nx).enumerate().for_each(|(i, row)| {
        for (j, c) in row.iter_mut().enumerate() {
            let mut acc = 0.0;
            for a in 0..SUPERSAMPLE {
                for b in 0..SUPERSAMPLE {
                    let x = x0 + j as f64 * cell + (b as f64 + 0.5) * sub;
                    let y = y0 + i as f64 * cell + (a as f64 + 0.5) * sub;
                    acc += plate.mask.clear_fraction(x, y).clamp(0.0, 1.0);
                }
            }
            *c = acc / (SUPERSAMPLE * SUPERSAMPLE) as f64;
        }
    });
    // A rim of one cell around the clear glass at a quarter of the density: rays that the
    // proxy map misplaces by up to a cell (its error is ~10 µm RMS, ~70 µm at worst on the
    // paper bench) still find a density no more than 4× below that of the glass they reach,
    // which bounds their weight; the rim costs ~5 % of the rays on 0.6 mm bars.
    let glass = clear.iter().sum::<f64>() / (nx * ny) as f64;
    let clear: Vec<f64> = (0..ny)
        .flat_map(|i| (0..nx).map(move |j| (i, j)))
        .map(|(i, j)| {
            let mut m = 0.0f64;
            for ii in i.saturating_sub(RIM)..(i + RIM + 1).min(ny) {
                for jj in j.saturating_sub(RIM)..(j + RIM + 1).min(nx) {
                    m = m.max(clear[ii * nx + jj]);
                }
            }
            clear[i * nx + j].max(RIM_WEIGHT * m)
        })
        .collect();
    (clear, glass)
}

/// Follows a design ray from `o` along the unit `d` at `wl` through refracting and reflecting
/// surfaces (no Fresnel reflection, no absorption) to the chrome face of chart `chart`; its point
/// there in chart coordinates, or `None` if the ray is stopped first.
fn follow_to_chart(
    bench: &Bench,
    chart: usize,
    mut o: DVec3,
    mut d: DVec3,
    wl: f64,
) -> Option<(f64, f64)> {
    for _ in 0..64 {
        let (t, target) = bench.nearest(o, d);
        let Some(Target::Surface(i, n)) = target else {
            return None;
        };
        let s = &bench.surfaces()[i];
        let hit = o + t * d;
        if s.clear.is_some_and(|c| c.blocks(hit)) {
            return None;
        }
        let cos_signed = -d.dot(n);
        let (front, back) = match &s.interaction {
            Interaction::Chart { chart: c, .. } if *c == chart => {
                let l = bench.charts()[chart].frame.to_local(hit);
                return Some((l.x, l.y));
            }
            Interaction::Interface { front, back, .. } | Interaction::Chart { front, back, .. } => {
                (*front, *back)
            }
            Interaction::Mirror { .. } if cos_signed > 0.0 => {
                d = reflect(d, n);
                o = hit + STEP_OFF * n;
                continue;
            }
            _ => return None,
        };
        let (m_in, m_out, nn) = if cos_signed >= 0.0 {
            (front, back, n)
        } else {
            (back, front, -n)
        };
        d = refract(
            d,
            nn,
            bench.media()[m_in].glass.index(wl),
            bench.media()[m_out].glass.index(wl),
        )?;
        o = hit - STEP_OFF * nn;
    }
    None
}

/// Least squares s ≈ coef·x for both coordinates of s, by the normal equations (5 unknowns,
/// O(1) features); the coefficients and the RMS residual length, or `None` if singular.
fn least_squares(rows: &[([f64; 5], [f64; 2])]) -> Option<([[f64; 5]; 2], f64)> {
    let mut m = [[0.0; 5]; 5];
    let mut r = [[0.0; 5]; 2];
    for (x, s) in rows {
        for i in 0..5 {
            for j in 0..5 {
                m[i][j] += x[i] * x[j];
            }
            r[0][i] += x[i] * s[0];
            r[1][i] += x[i] * s[1];
        }
    }
    let coef = [solve5(m, r[0])?, solve5(m, r[1])?];
    let mut sq = 0.0;
    for (x, s) in rows {
        for k in 0..2 {
            let e: f64 = (0..5).map(|i| coef[k][i] * x[i]).sum::<f64>() - s[k];
            sq += e * e;
        }
    }
    Some((coef, (sq / rows.len() as f64).sqrt()))
}

/// Gaussian elimination with partial pivoting.
fn solve5(mut m: [[f64; 5]; 5], mut b: [f64; 5]) -> Option<[f64; 5]> {
    let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    for col in 0..5 {
        let piv = (col..5).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[piv][col].abs().partial_cmp(&(1e-12 * scale)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        m.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..5 {
            let f = m[row][col] / m[col][col];
            let pivot_row = m[col];
            for (a, p) in m[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *a -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 5];
    for row in (0..5).rev() {
        let s: f64 = (row + 1..5).map(|k| m[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / m[row][row];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::lamp::{Emission, factor_stats};
    use crate::rng::{self, uniform};

    fn paper_bench() -> Bench {
        crate::scene::bench::read_bench(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/paper_bench.ron"
        )))
        .unwrap()
    }

    /// The proxy map predicts where fresh design rays (random filament point, target point and
    /// wavelength, not the fitting grid) meet the chart to a fraction of a density cell, and
    /// the paper bench's collimator images the target near 1:1 (scale 1.01–1.07 over the band,
    /// the flip of the chart's frame aside).
    #[test]
    fn proxy_map_follows_the_optics() {
        let bench = paper_bench();
        let g = bench
            .lamp()
            .guide
            .as_ref()
            .expect("the paper bench is chart-guided");
        let f = bench.lamp().field.unwrap();
        let fr = bench.lamp().frame;
        let mut r = rng::stream(3, 0);
        let (mut worst, mut sq, mut n) = (0.0f64, 0.0, 0);
        for _ in 0..2000 {
            let mut u = || 2.0 * uniform(&mut r) - 1.0;
            let d = (u() * 1e-3, u() * 0.6e-3);
            let q = (u() * 5e-3, u() * 5e-3);
            let wl = bench.band().0 + 0.5 * (u() + 1.0) * (bench.band().1 - bench.band().0);
            let p = fr.origin + d.0 * fr.u + d.1 * fr.v;
            let aim = f.center + q.0 * fr.u + q.1 * fr.v;
            let s = follow_to_chart(&bench, g.chart, p, (aim - p).normalize(), wl)
                .expect("the design ray reaches the chart");
            let e = g.map(wl).apply(q, d);
            let err = (e.0 - s.0).hypot(e.1 - s.1);
            worst = worst.max(err);
            sq += err * err;
            n += 1;
        }
        let rms = (sq / n as f64).sqrt();
        // Bounds from what the guide needs: an RMS error below half a density cell keeps most
        // misplaced rays within the one-cell rim, and no error above a quarter of the region's
        // narrowest bar (Group −1 element 6: 0.561 mm) aims a ray at the wrong bar. Measured:
        // 9 µm RMS and 72 µm at worst (aberrations at the field's corners), cells of 43 µm.
        let bar = 0.5e-3 / 2f64.powf(-1.0 + 5.0 / 6.0);
        assert!(
            rms < 0.5 * g.cell && worst < 0.25 * bar,
            "rms {rms:e}, worst {worst:e}, cell {:e}",
            g.cell
        );
        assert!(g.fit_rms_m < 0.5 * g.cell, "fit rms {:e}", g.fit_rms_m);
        for m in &g.maps {
            assert!(m.det_abs > 1.0 && m.det_abs < 1.2, "{m:?}");
        }
        // Group −1 elements 5–6 and their neighbours: a minority of the region is clear glass.
        assert!(
            g.clear_fraction > 0.05 && g.clear_fraction < 0.5,
            "{}",
            g.clear_fraction
        );
    }

    /// Sampling and density agree: the density integrates to 1 over the target plane, every
    /// draw has a positive density, and the share of draws in three test boxes matches the
    /// density's integral over the box within 4 binomial standard errors.
    #[test]
    fn draws_follow_the_density() {
        let bench = paper_bench();
        let g = bench.lamp().guide.as_ref().unwrap();
        let (d, wl) = ((0.4e-3, -0.3e-3), 633e-9);
        // The density is piecewise constant on cells of ~43 µm; the midpoint rule on a 5 µm grid
        // integrates it to 0.1 % over the plane and 0.3 % over a box (measured against a
        // 2.5 µm grid). The total's tolerance, 0.5 %, lies between that and the ≥ 1 % error a
        // wrong Jacobian would make (|det A| = 1.01–1.15 on this bench).
        let step = 5e-6;
        let half = 7e-3;
        let k = (2.0 * half / step) as usize;
        let boxes = [
            ((-1.0e-3, -1.0e-3), (1.0e-3, 1.0e-3)),
            ((2.0e-3, 0.5e-3), (3.0e-3, 2.5e-3)),
            ((-5.0e-3, -5.0e-3), (0.0, 5.0e-3)),
        ];
        let mut total = 0.0;
        let mut in_box = [0.0; 3];
        for i in 0..k {
            for j in 0..k {
                let q = (
                    -half + (j as f64 + 0.5) * step,
                    -half + (i as f64 + 0.5) * step,
                );
                let v = g.pdf(q, d, wl) * step * step;
                total += v;
                for (b, acc) in boxes.iter().zip(in_box.iter_mut()) {
                    if q.0 >= b.0.0 && q.0 < b.1.0 && q.1 >= b.0.1 && q.1 < b.1.1 {
                        *acc += v;
                    }
                }
            }
        }
        assert!((total - 1.0).abs() < 5e-3, "integral {total}");
        let n = 200_000;
        let mut counts = [0usize; 3];
        let mut r = rng::stream(11, 0);
        for _ in 0..n {
            let q = g.sample(uniform(&mut r), uniform(&mut r), d, wl);
            assert!(g.pdf(q, d, wl) > 0.0, "draw {q:?} has no density");
            for (b, c) in boxes.iter().zip(counts.iter_mut()) {
                if q.0 >= b.0.0 && q.0 < b.1.0 && q.1 >= b.0.1 && q.1 < b.1.1 {
                    *c += 1;
                }
            }
        }
        for (p, c) in in_box.iter().zip(counts) {
            let f = c as f64 / n as f64;
            let se = (p * (1.0 - p) / n as f64).sqrt().max(1.0 / n as f64);
            assert!(
                // 4 binomial standard errors plus the quadrature's 0.3 %.
                (f - p).abs() < 4.0 * se + 3e-3 * p,
                "frequency {f} vs integral {p}"
            );
        }
        // The boxes are not trivial (measured: 2.6 %, 4.7 % and 41 % of the draws).
        assert!(in_box.iter().all(|&p| p > 0.01), "{in_box:?}");
    }

    /// With the guide in the lamp's mixture, every emission weight stays unbiased: the mean
    /// factor is the traced cone's share sin²θmax of the Lambertian power, and the mean factor
    /// of rays through a small disk on the field plane equals the plain cone's (4 standard
    /// errors). (Whether the guide lowers the disk's error depends on what glass the disk
    /// sends light to; the traced bench shows the gain, see trace/tests.rs.)
    #[test]
    fn guided_mixture_is_unbiased() {
        let bench = paper_bench();
        let guided = bench.lamp().clone();
        let mut plain = guided.clone();
        plain.field = None;
        plain.guide = None;
        let f = guided.field.unwrap();
        let fr = guided.frame;
        // A 1 mm disk on the field plane, 1.5 mm off the target's centre.
        let in_disk = |e: &Emission| {
            let t = (f.center - e.origin).dot(fr.w) / e.direction.dot(fr.w);
            let q = e.origin + t * e.direction - f.center;
            (q.dot(fr.u) - 1.5e-3).hypot(q.dot(fr.v)) < 0.5e-3
        };
        let n = 400_000;
        let band = bench.band();
        let draw = |seed: u64| {
            let mut r = rng::stream(seed, 0);
            move || {
                let u = [(); 5].map(|_| uniform(&mut r));
                let wl = band.0 + uniform(&mut r) * (band.1 - band.0);
                (u, wl)
            }
        };
        let ((a, sa), (b, sb)) = factor_stats(&guided, n, draw(1), in_disk);
        let (_, (c, sc)) = factor_stats(&plain, n, draw(2), in_disk);
        let sin2 = guided.sin2_max;
        assert!((a - sin2).abs() < 4.0 * sa, "{a} ± {sa} vs {sin2}");
        assert!(
            (b - c).abs() < 4.0 * (sb * sb + sc * sc).sqrt(),
            "{b} ± {sb} vs {c} ± {sc}"
        );
    }
}
