//! Traced object kernels: one trace of a bench whose chart is clear glass gives the transport of
//! every object on a grid of the chart plane.
//!
//! Light reaches the detectors through the chart linearly in the object's transmittance: a path
//! that meets the chart face at object pixel i goes on (reflected or transmitted, as at clear
//! glass) with probability t_i and is absorbed otherwise. For a clear chart the trace therefore
//! tallies, for each object pixel i, DMD unit j (the unit under the path's first crossing of the
//! pattern area), mirror state s and photodiode d, the kernel K[d][s][i][j] (A per unit
//! transmittance), and the transport of an object t is
//!
//!   T[d][s][j](t) = K0[d][s][j] + Σ_i t_i·K[d][s][i][j],   B_d(t) = B0_d + Σ_i t_i·Bk[d][i],
//!
//! where K0 and B0 are the light that never met the chart (object-independent: light bypassing
//! the object) and Bk the chart light that never met the pattern area. The power on the units,
//! x_j, is split the same way. Ambient light and dark current are object-independent too; they
//! stay in the bench's detectors and enter the transport as always
//! (`transport::Transport::from_kernel`).
//!
//! The object model is the one of a chart whose opaque parts are black (no reflectance, no
//! leak): the mask's clear fraction t_i. Outside the grid the chart plane is opaque and black:
//! a path that meets it there is absorbed. A chrome chart with a reflective face and a finite
//! optical density is not linear in this sense (chrome reflects ~10 % back towards the lamp);
//! the kernel describes the ideal transmittance object that datasets need.
//!
//! What the kernel neglects: a path that meets the chart face more than once (a ghost between
//! the chart and the lamp-side or imaging optics) is attributed to the pixel of its first
//! meeting, weighted t_i instead of t_i·t_i'. The trace measures that share
//! ([`Kernel::multi_crossing_current_fraction`]).
//!
//! Determinism and errors: the batches of `trace::trace` (same streams, same batch size), merged
//! in batch order. Each kernel entry keeps the sums over batches of its per-batch values and of
//! their squares and cross products; a product Σ_i t_i·K_i takes the variance
//! Σ_i t_i²·var(K_i), which neglects the (small, negative) covariance between pixels of one
//! batch that the Latin hypercube introduces.

use std::collections::HashMap;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::optics::dmd::MirrorState;
use crate::optics::{Arm, Bench};

use super::path::{self, ChartCrossing, Detection, NO_PIXEL, PatternMode, Recorder};
use super::tally::{BatchTally, Tallies, branch_state};
use super::{BATCHES_PER_CHUNK, RAYS_PER_BATCH, TraceOptions};

/// The object grid on a chart face: `width_px` × `height_px` pixels covering `width_m` ×
/// `height_m`, centred on the plate centre, row 0 at the top (largest local y) — the mapping
/// of an image mask (`optics::chart::ChartMask::Image`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectGrid {
    /// Index of the chart plate in the bench (`Bench::charts`).
    pub chart: usize,
    pub width_px: usize,
    pub height_px: usize,
    pub width_m: f64,
    pub height_m: f64,
}

impl ObjectGrid {
    pub fn pixels(&self) -> usize {
        self.width_px * self.height_px
    }

    /// The pixel at chart coordinates (m from the plate centre), as `ChartMask::Image` maps it.
    #[inline]
    pub fn pixel_at(&self, x_m: f64, y_m: f64) -> Option<u32> {
        let fx = x_m / self.width_m + 0.5;
        let fy = 0.5 - y_m / self.height_m;
        if !(0.0..1.0).contains(&fx) || !(0.0..1.0).contains(&fy) {
            return None;
        }
        let c = ((fx * self.width_px as f64) as usize).min(self.width_px - 1);
        let r = ((fy * self.height_px as f64) as usize).min(self.height_px - 1);
        Some((r * self.width_px + c) as u32)
    }
}

/// Per-pixel batch vector: (g₊, g₋, x, c₊, c₋) summed over units. The same length holds a
/// kernel entry's batch values: T[d][s] at [`BatchTally::t_block`], then x at [`ENTRY_X`].
const PV: usize = 5;

/// Index of g of `arm` in the per-pixel vector.
pub const fn pv_g(arm: Arm) -> usize {
    arm.index()
}

/// Index of x in the per-pixel vector.
pub const PV_X: usize = 2;

/// Index of c of `arm` in the per-pixel vector.
pub const fn pv_c(arm: Arm) -> usize {
    3 + arm.index()
}

/// Index of x in a kernel entry's batch values (after the four T[d][s]).
const ENTRY_X: usize = 4;

/// A kernel entry's accumulator: the sums of its batch values ([`PV`] of them), then the raw
/// batch second moments Σ g² (per arm, from [`ACC_G2`]), Σ g·x (per arm, from [`ACC_GX`]) and
/// Σ x² ([`ACC_X2`]).
const ACC: usize = 10;
const ACC_G2: usize = 5;
const ACC_GX: usize = 7;
const ACC_X2: usize = 9;

/// The gain g_d = T[d][on] − T[d][off] of `arm` from the four T[d][s] of `t` (blocks of
/// [`BatchTally::t_block`]).
#[inline]
fn gain(t: &[f64], arm: Arm) -> f64 {
    t[BatchTally::t_block(arm, arm.state())] - t[off_block(arm)]
}

/// The block T[d][off] of `arm`: the current of arm d from units in the other state, part of c_d.
#[inline]
fn off_block(arm: Arm) -> usize {
    BatchTally::t_block(arm, arm.other().state())
}
/// Its second moments (upper triangle, row-major).
const PQ: usize = 15;

#[inline]
fn tri(a: usize, b: usize) -> usize {
    let (a, b) = if a <= b { (a, b) } else { (b, a) };
    // Rows of lengths 5, 4, 3, 2, 1.
    a * PV - a * (a + 1) / 2 + b
}

/// One kernel entry (object pixel i, unit j): sums over the trace.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KernelEntry {
    /// T[d][s] for this (i, j), index d·2 + s (A per unit transmittance).
    pub t: [f64; 4],
    /// Power on unit j's mirrors from pixel i (W per unit transmittance).
    pub x: f64,
    /// Centred batch second moments: Σ_b (g_b − ḡ)² per arm, Σ_b (g_b − ḡ)(x_b − x̄) per arm,
    /// Σ_b (x_b − x̄)².
    pub g2: [f64; 2],
    pub gx: [f64; 2],
    pub x2: f64,
}

impl KernelEntry {
    /// From an entry's accumulator over `nb` batches (see [`ACC`]): the sums, and the second
    /// moments centred on the batch means.
    fn from_sums(a: &[f64; ACC], nb: f64) -> KernelEntry {
        let g = Arm::ALL.map(|arm| gain(a, arm));
        let x = a[ENTRY_X];
        KernelEntry {
            t: [a[0], a[1], a[2], a[3]],
            x,
            g2: Arm::ALL.map(|arm| a[ACC_G2 + arm.index()] - g[arm] * g[arm] / nb),
            gx: Arm::ALL.map(|arm| a[ACC_GX + arm.index()] - g[arm] * x / nb),
            x2: a[ACC_X2] - x * x / nb,
        }
    }
}

/// A traced object kernel (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Kernel {
    pub grid: ObjectGrid,
    pub rays: u64,
    pub seed: u64,
    pub batches: u64,
    pub units_across: usize,
    pub units_down: usize,
    /// Non-zero entries sorted by (pixel, unit); pixel `grid.pixels()` is the object-independent
    /// light (never met the chart).
    pub entries: Vec<(u32, u32, KernelEntry)>,
    /// Bk[d] per pixel (index `grid.pixels()`: B0): current of light that never met the pattern.
    pub b: Vec<[f64; 2]>,
    /// Per pixel (same indexing), centred batch second moments of (g₊, g₋, x, c₊, c₋).
    pub pixel_q: Vec<[f64; PQ]>,
    /// The clear-chart trace's own tallies (its ledger is that of the clear chart).
    pub tallies: Tallies,
    /// Detected current (summed over detectors and worlds) of paths that met the chart face
    /// once or more, and of those that met it twice or more (A).
    pub chart_current_a: f64,
    pub multi_crossing_current_a: f64,
    /// Detection events of paths that met the chart face once or more, and twice or more.
    pub chart_detections: u64,
    pub multi_crossing_detections: u64,
}

/// What one batch records.
struct KernelBatch {
    /// Key pixel·units + unit → index into `values`.
    index: HashMap<u64, usize>,
    values: Vec<(u64, [f64; PV])>,
    b: HashMap<u32, [f64; 2]>,
    grid: ObjectGrid,
    units: usize,
    bypass: u32,
    chart_current: f64,
    multi_current: f64,
    chart_n: u64,
    multi_n: u64,
}

impl KernelBatch {
    fn new(grid: ObjectGrid, units: usize) -> KernelBatch {
        KernelBatch {
            index: HashMap::new(),
            values: Vec::new(),
            b: HashMap::new(),
            grid,
            units,
            bypass: grid.pixels() as u32,
            chart_current: 0.0,
            multi_current: 0.0,
            chart_n: 0,
            multi_n: 0,
        }
    }

    fn pixel(&self, p: u32) -> u32 {
        if p == NO_PIXEL { self.bypass } else { p }
    }

    fn slot(&mut self, pixel: u32, unit: usize) -> &mut [f64; PV] {
        let key = pixel as u64 * self.units as u64 + unit as u64;
        let n = self.values.len();
        let k = *self.index.entry(key).or_insert(n);
        if k == n {
            self.values.push((key, [0.0; PV]));
        }
        &mut self.values[k].1
    }
}

impl Recorder for KernelBatch {
    #[inline(always)]
    fn segment(&mut self, _: glam::DVec3, _: glam::DVec3, _: f64) {}
    #[inline(always)]
    fn ray_done(&mut self, _: &BatchTally) {}

    fn chart_crossing(&mut self, chart: usize, x_m: f64, y_m: f64) -> ChartCrossing {
        if chart != self.grid.chart {
            return ChartCrossing::Untracked;
        }
        match self.grid.pixel_at(x_m, y_m) {
            Some(i) => ChartCrossing::Pixel(i),
            None => ChartCrossing::Outside,
        }
    }

    fn detected(&mut self, hit: Detection) {
        if hit.chart_hits >= 1 {
            self.chart_current += hit.current_a;
            self.chart_n += 1;
        }
        if hit.chart_hits >= 2 {
            self.multi_current += hit.current_a;
            self.multi_n += 1;
        }
        let i = self.pixel(hit.pixel);
        match branch_state(hit.world) {
            None => self.b.entry(i).or_insert([0.0; 2])[hit.detector] += hit.current_a,
            Some(state) => {
                self.slot(i, hit.unit)[BatchTally::t_block(hit.detector, state)] += hit.current_a
            }
        }
    }

    fn incident(&mut self, unit: usize, pixel: u32, w: f64) {
        let i = self.pixel(pixel);
        self.slot(i, unit)[ENTRY_X] += w;
    }
}

/// The errors of [`trace_kernel`]'s input, each at its field.
fn check_kernel_options(bench: &Bench, grid: ObjectGrid, options: &TraceOptions) -> Result<()> {
    if options.rays == 0 {
        return Err(Error::field(
            "rays",
            "the number of rays must be at least 1",
        ));
    }
    if !matches!(options.mode, PatternMode::Branch) {
        return Err(Error::field(
            "mode",
            "an object kernel is traced with both mirror states (Branch)",
        ));
    }
    if grid.chart >= bench.charts().len() {
        return Err(Error::field("chart", "the bench has no such chart"));
    }
    if grid.pixels() == 0
        || grid.pixels() >= u32::MAX as usize
        || !(grid.width_m > 0.0 && grid.height_m > 0.0)
    {
        return Err(Error::field(
            "grid",
            "the object grid needs at least one pixel and a positive size",
        ));
    }
    Ok(())
}

/// Traces the object kernel of `bench` (whose chart `grid.chart` should be clear glass: any
/// mask it carries multiplies the kernel) on the current rayon pool. `options.mode` must be
/// `PatternMode::Branch`.
pub fn trace_kernel(bench: &Bench, grid: ObjectGrid, options: &TraceOptions) -> Result<Kernel> {
    check_kernel_options(bench, grid, options)?;
    let (across, down) = bench.units_shape();
    let units = across * down;
    let npix = grid.pixels();
    let mut tallies = Tallies::new(
        across,
        down,
        bench.elements().len(),
        options.seed,
        bench.lamp().power_outside_cone(),
    );
    let mut acc: HashMap<u64, [f64; ACC]> = HashMap::new();
    let mut b = vec![[0.0; 2]; npix + 1];
    let mut psum = vec![[0.0; PV]; npix + 1];
    let mut pq = vec![[0.0; PQ]; npix + 1];
    let (mut chart_current, mut multi_current, mut chart_n, mut multi_n) = (0.0, 0.0, 0, 0);
    let n = options.rays;
    let n_batches = n.div_ceil(RAYS_PER_BATCH);
    let inv = 1.0 / n as f64;
    let mut start = 0;
    let mut touched: Vec<[f64; PV]> = vec![[0.0; PV]; npix + 1];
    let mut touched_list: Vec<usize> = Vec::new();
    while start < n_batches {
        let end = (start + BATCHES_PER_CHUNK).min(n_batches);
        let chunk: Vec<(BatchTally, KernelBatch)> = (start..end)
            .into_par_iter()
            .map(|bi| {
                let rays = RAYS_PER_BATCH.min(n - bi * RAYS_PER_BATCH);
                let mut rec = KernelBatch::new(grid, units);
                let t = path::run_batch_recorded(
                    bench,
                    PatternMode::Branch,
                    options.seed,
                    bi,
                    rays,
                    inv,
                    &mut rec,
                );
                rec.values.sort_unstable_by_key(|v| v.0);
                rec.index = HashMap::new();
                (t, rec)
            })
            .collect();
        for (t, kb) in &chunk {
            tallies.absorb(t);
            chart_current += kb.chart_current;
            multi_current += kb.multi_current;
            chart_n += kb.chart_n;
            multi_n += kb.multi_n;
            // Per-entry sums and raw second moments (centred at the end).
            for (key, v) in &kb.values {
                let a = acc.entry(*key).or_insert([0.0; ACC]);
                let g = Arm::ALL.map(|arm| gain(v, arm));
                let x = v[ENTRY_X];
                for k in 0..PV {
                    a[k] += v[k];
                }
                for arm in Arm::ALL {
                    a[ACC_G2 + arm.index()] += g[arm] * g[arm];
                    a[ACC_GX + arm.index()] += g[arm] * x;
                }
                a[ACC_X2] += x * x;
                let i = (*key / units as u64) as usize;
                let pv = &mut touched[i];
                if pv.iter().all(|&z| z == 0.0) {
                    touched_list.push(i);
                }
                // (g₊, g₋, x, c₊, c₋): c₊ gets T[+][−], c₋ gets T[−][+].
                for arm in Arm::ALL {
                    pv[pv_g(arm)] += g[arm];
                    pv[pv_c(arm)] += v[off_block(arm)];
                }
                pv[PV_X] += x;
            }
            let mut bkeys: Vec<(&u32, &[f64; 2])> = kb.b.iter().collect();
            bkeys.sort_unstable_by_key(|e| *e.0);
            for (&i, v) in bkeys {
                let i = i as usize;
                for arm in Arm::ALL {
                    b[i][arm] += v[arm];
                }
                let pv = &mut touched[i];
                if pv.iter().all(|&z| z == 0.0) {
                    touched_list.push(i);
                }
                for arm in Arm::ALL {
                    pv[pv_c(arm)] += v[arm];
                }
            }
            // Sorted so that the floating-point sums per pixel are made in a fixed order.
            touched_list.sort_unstable();
            touched_list.dedup();
            for &i in &touched_list {
                let v = touched[i];
                for a in 0..PV {
                    psum[i][a] += v[a];
                    for c in a..PV {
                        pq[i][tri(a, c)] += v[a] * v[c];
                    }
                }
                touched[i] = [0.0; PV];
            }
            touched_list.clear();
        }
        start = end;
    }
    let nb = n_batches as f64;
    let mut entries: Vec<(u32, u32, KernelEntry)> = acc
        .into_iter()
        .map(|(key, a)| {
            let (i, j) = ((key / units as u64) as u32, (key % units as u64) as u32);
            (i, j, KernelEntry::from_sums(&a, nb))
        })
        .collect();
    entries.sort_unstable_by_key(|e| (e.0, e.1));
    for (q, s) in pq.iter_mut().zip(&psum) {
        for a in 0..PV {
            for c in a..PV {
                q[tri(a, c)] -= s[a] * s[c] / nb;
            }
        }
    }
    Ok(Kernel {
        grid,
        rays: n,
        seed: options.seed,
        batches: n_batches,
        units_across: across,
        units_down: down,
        entries,
        b,
        pixel_q: pq,
        tallies,
        chart_current_a: chart_current,
        multi_crossing_current_a: multi_current,
        chart_detections: chart_n,
        multi_crossing_detections: multi_n,
    })
}

/// The transport of one object through a kernel: per-unit sums and variances.
#[derive(Debug, Clone, PartialEq)]
pub struct KernelProduct {
    /// T[d][s][j], index (d·2 + s)·units + j (A).
    pub t: Vec<f64>,
    pub x: Vec<f64>,
    pub b: [f64; 2],
    /// Per unit: Σ_i t_i²·(centred g2[2], gx[2], x2) (for the k maps' standard errors).
    pub g2: [Vec<f64>; 2],
    pub gx: [Vec<f64>; 2],
    pub x2: Vec<f64>,
    /// Σ_i t_i²·(centred second moments of (g₊, g₋, x, c₊, c₋)).
    pub q: [f64; PQ],
    /// Sums of (g₊, g₋, x, c₊, c₋).
    pub sums: [f64; PV],
    pub batches: u64,
}

impl KernelProduct {
    /// The covariance (batch means, times B/(B − 1)) of components a and c of
    /// (g₊, g₋, x, c₊, c₋).
    pub fn cov(&self, a: usize, c: usize) -> f64 {
        let nb = self.batches as f64;
        self.q[tri(a, c)] * nb / (nb - 1.0)
    }
}

impl Kernel {
    pub fn units(&self) -> usize {
        self.units_across * self.units_down
    }

    /// The share of the detected current carried by paths that met the chart face more than
    /// once, among paths that met it at all: what the kernel mis-weights (t_i instead of
    /// t_i·t_i').
    pub fn multi_crossing_current_fraction(&self) -> f64 {
        self.multi_crossing_current_a / self.chart_current_a
    }

    /// The products T(t), x(t), B(t) for the object `t` (row-major on the grid, transmittance
    /// in [0, 1]; values outside are used as given). Panics if `t` has the wrong length:
    /// callers check it.
    pub fn apply(&self, object: &[f64]) -> KernelProduct {
        let units = self.units();
        let npix = self.grid.pixels();
        assert_eq!(object.len(), npix, "object size");
        let w = |i: u32| {
            if i as usize == npix {
                1.0
            } else {
                object[i as usize]
            }
        };
        let mut p = KernelProduct {
            t: vec![0.0; 4 * units],
            x: vec![0.0; units],
            b: [0.0; 2],
            g2: [vec![0.0; units], vec![0.0; units]],
            gx: [vec![0.0; units], vec![0.0; units]],
            x2: vec![0.0; units],
            q: [0.0; PQ],
            sums: [0.0; PV],
            batches: self.batches,
        };
        for (i, j, e) in &self.entries {
            let ti = w(*i);
            if ti == 0.0 {
                continue;
            }
            let j = *j as usize;
            let t2 = ti * ti;
            for ds in 0..4 {
                p.t[ds * units + j] += ti * e.t[ds];
            }
            p.x[j] += ti * e.x;
            for arm in Arm::ALL {
                p.g2[arm][j] += t2 * e.g2[arm];
                p.gx[arm][j] += t2 * e.gx[arm];
            }
            p.x2[j] += t2 * e.x2;
        }
        for (i, (bi, qi)) in self.b.iter().zip(&self.pixel_q).enumerate() {
            let ti = w(i as u32);
            if ti == 0.0 {
                continue;
            }
            for arm in Arm::ALL {
                p.b[arm] += ti * bi[arm];
            }
            for (a, v) in p.q.iter_mut().zip(qi) {
                *a += ti * ti * v;
            }
        }
        let t_at =
            |arm: Arm, state: MirrorState, j: usize| p.t[BatchTally::t_index(units, arm, state, j)];
        let mut sums = [0.0; PV];
        for j in 0..units {
            for arm in Arm::ALL {
                let (on, off) = (arm.state(), arm.other().state());
                sums[pv_g(arm)] += t_at(arm, on, j) - t_at(arm, off, j);
            }
            sums[PV_X] += p.x[j];
            for arm in Arm::ALL {
                sums[pv_c(arm)] += t_at(arm, arm.other().state(), j);
            }
        }
        for arm in Arm::ALL {
            sums[pv_c(arm)] += p.b[arm];
        }
        p.sums = sums;
        p
    }
}

#[cfg(test)]
mod tests;
