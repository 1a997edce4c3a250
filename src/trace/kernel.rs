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
//! Paths that meet the chart face more than once (a ghost between the chart and the lamp-side
//! or imaging optics, light reflected back through the chart) are kept apart: each is named by
//! the pixels it met, in order ([`Ghost`]), and weighted by the product of their
//! transmittances, Π_k t_{i_k}, as the direct trace of the object weights it (each meeting
//! passes with its pixel's clear fraction). Attributing such a path to its first pixel alone
//! over-counts the light of paths that met a clear pixel and then an opaque one: on the paper
//! bench about 1 % of the offset c₋ of an object of bars and a disk (docs/object_kernels.md).
//! [`Kernel::multi_crossing_current_fraction`] measures their share of the current.
//!
//! Determinism and errors: the batches of `trace::trace` (same streams, same batch size), merged
//! in batch order. Each kernel entry keeps the sums over batches of its per-batch values and of
//! their squares and cross products, for the per-unit maps' errors (Σ_i t_i²·var(K_i), which
//! neglects the covariance between the pixels of one batch). The object's totals (k±, c±, the
//! power on the pattern) take their errors from batch groups instead ([`Kernel::group_sums`]):
//! the batches are dealt into G = 32 groups, each pixel keeps its sums per group, and the
//! object's group totals are independent replicates of the product, so their spread includes
//! the Latin hypercube's (negative) covariance between the pixels of a batch, which the
//! per-pixel variances miss.

use std::collections::HashMap;

use crate::error::{Error, Result};
use crate::optics::dmd::MirrorState;
use crate::optics::{Arm, Bench};

use super::path::{self, ChartCrossing, Detection, NO_PIXEL, PatternMode, Recorder};
use super::tally::{BatchTally, Tallies, branch_state};
use super::{RAYS_PER_BATCH, TraceOptions};

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
    /// Paths that met the chart face more than once, grouped by the pixels they met (see
    /// [`Ghost`]; `entries`, `b`, `pixel_q` and `group_sums` hold their light at the first
    /// pixel met); `ghost_entries` holds their (ghost, unit) entries sorted, as `entries`.
    pub ghosts: Vec<Ghost>,
    pub ghost_entries: Vec<(u32, u32, KernelEntry)>,
    /// The clear-chart trace's own tallies (its ledger is that of the clear chart).
    pub tallies: Tallies,
    /// Detected current (summed over detectors and worlds) of paths that met the chart face
    /// once or more, and of those that met it twice or more (A).
    pub chart_current_a: f64,
    pub multi_crossing_current_a: f64,
    /// Detection events of paths that met the chart face once or more, and twice or more.
    pub chart_detections: u64,
    pub multi_crossing_detections: u64,
    /// The standard errors' batch groups: per pixel (index `grid.pixels()`: the light that
    /// never met the chart) and group g, the sums of (g₊, g₋, x, c₊, c₋) over the group's
    /// batches (index pixel·G + g, G = `group_rays.len()`), and each group's rays. For an
    /// object, the group totals Σ_i t_i·v_ig are independent replicates of the whole product
    /// (each group a sample of independent batches), so their spread gives its error with the
    /// Latin hypercube's covariance between pixels included.
    pub group_sums: Vec<[f64; PV]>,
    pub group_rays: Vec<u64>,
}

/// The light of paths that met the chart face at more than one point: for an object t it is
/// weighted by the product of the transmittances met, Π_k t_{i_k}. The kernel's pixel entries
/// hold it too, at the first pixel met (the linear part, [`Kernel::apply_linear`]); the ghost's
/// own values correct that by Π_k t_{i_k} − t_{i_1} ([`Kernel::apply`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Ghost {
    /// The pixels met, in the order met (a pixel met twice appears twice).
    pub pixels: Vec<u32>,
    /// Current that never met the pattern area, per detector (as [`Kernel::b`]).
    pub b: [f64; 2],
    /// Centred batch second moments of (g₊, g₋, x, c₊, c₋) (as [`Kernel::pixel_q`]).
    pub q: [f64; PQ],
    /// Per batch group, the sums of (g₊, g₋, x, c₊, c₋) (as [`Kernel::group_sums`]).
    pub group_sums: Vec<[f64; PV]>,
}

impl Ghost {
    /// The weight of this light for `object`: the product of the transmittances met.
    fn weight(&self, object: &[f64]) -> f64 {
        self.pixels.iter().map(|&i| object[i as usize]).product()
    }
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
    /// Keys above `bypass` name paths that met the chart again: node k (key bypass + 1 + k) is
    /// (the key before this meeting, the pixel met).
    nodes: Vec<(u32, u32)>,
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
            nodes: Vec::new(),
            chart_current: 0.0,
            multi_current: 0.0,
            chart_n: 0,
            multi_n: 0,
        }
    }

    fn pixel(&self, p: u32) -> u32 {
        if p == NO_PIXEL { self.bypass } else { p }
    }

    /// The pixels met by the path of `key` (a node key), in the order met.
    fn pixels_of(&self, mut key: u32) -> Vec<u32> {
        let mut v = Vec::new();
        while key > self.bypass {
            let (parent, pixel) = self.nodes[(key - self.bypass - 1) as usize];
            v.push(pixel);
            key = parent;
        }
        v.push(key);
        v.reverse();
        v
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

    fn chart_crossing(&mut self, chart: usize, x_m: f64, y_m: f64, pixel: u32) -> ChartCrossing {
        if chart != self.grid.chart {
            return ChartCrossing::Untracked;
        }
        match self.grid.pixel_at(x_m, y_m) {
            Some(i) if pixel == NO_PIXEL => ChartCrossing::Pixel(i),
            Some(i) => {
                // A further meeting: the path's light is weighted by every transmittance it
                // met, so it gets a key of its own (a node naming its earlier key and this pixel).
                self.nodes.push((pixel, i));
                ChartCrossing::Pixel(self.bypass + self.nodes.len() as u32)
            }
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
    let mut tallies = Tallies::new(
        across,
        down,
        bench.elements().len(),
        options.seed,
        bench.lamp().power_outside_cone(),
    );
    let mut merge = Merge::new(grid.pixels(), units, n_batches_of(options.rays));
    let n = options.rays;
    let n_batches = n_batches_of(n);
    let inv = 1.0 / n as f64;
    super::batches_in_order(
        n_batches,
        |bi| {
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
        },
        |bi, (t, kb)| {
            tallies.absorb(&t);
            merge.absorb(&kb, bi, t.rays);
        },
        |_| {},
    );
    Ok(merge.finish(grid, options, n_batches, across, down, tallies))
}

fn n_batches_of(rays: u64) -> u64 {
    rays.div_ceil(RAYS_PER_BATCH)
}

/// Batch groups of the kernel's standard errors (see [`Kernel::group_sums`]): batch b belongs
/// to group b mod G, G = min(batches, 32).
pub const ERROR_GROUPS: u64 = 32;

/// The kernel trace's accumulators, fed batch by batch in batch order. Keys: pixels 0..npix,
/// `npix` the light that never met the chart, `npix + 1 + g` ghost g (`ghost_pixels[g]`).
struct Merge {
    npix: usize,
    units: usize,
    /// Per (key, unit): sums of the batch values and raw second moments (see [`ACC`]).
    acc: HashMap<u64, [f64; ACC]>,
    /// Per key: Bk, sums and raw second moments of the batch's (g₊, g₋, x, c₊, c₋).
    b: Vec<[f64; 2]>,
    psum: Vec<[f64; PV]>,
    pq: Vec<[f64; PQ]>,
    /// This batch's (g₊, g₋, x, c₊, c₋) per key, and the keys it touched.
    touched: Vec<[f64; PV]>,
    touched_list: Vec<usize>,
    ghost_ids: HashMap<Vec<u32>, u32>,
    ghost_pixels: Vec<Vec<u32>>,
    /// Per key and batch group, the sums of (g₊, g₋, x, c₊, c₋) (index key·groups + group),
    /// and the rays of each group.
    groups: usize,
    group_sums: Vec<[f64; PV]>,
    group_rays: Vec<u64>,
    chart_current: f64,
    multi_current: f64,
    chart_n: u64,
    multi_n: u64,
}

impl Merge {
    fn new(npix: usize, units: usize, batches: u64) -> Merge {
        let groups = batches.clamp(1, ERROR_GROUPS) as usize;
        Merge {
            groups,
            group_sums: vec![[0.0; PV]; (npix + 1) * groups],
            group_rays: vec![0; groups],
            npix,
            units,
            acc: HashMap::new(),
            b: vec![[0.0; 2]; npix + 1],
            psum: vec![[0.0; PV]; npix + 1],
            pq: vec![[0.0; PQ]; npix + 1],
            touched: vec![[0.0; PV]; npix + 1],
            touched_list: Vec::new(),
            ghost_ids: HashMap::new(),
            ghost_pixels: Vec::new(),
            chart_current: 0.0,
            multi_current: 0.0,
            chart_n: 0,
            multi_n: 0,
        }
    }

    /// The trace-wide key of a batch's key: ghosts are named by the pixels they met, so that
    /// every batch's paths through the same pixels share one entry.
    fn global_key(&mut self, kb: &KernelBatch, key: u32) -> u64 {
        if key <= kb.bypass {
            return key as u64;
        }
        let pixels = kb.pixels_of(key);
        let next = self.ghost_pixels.len() as u32;
        let id = *self.ghost_ids.entry(pixels.clone()).or_insert(next);
        if id == next {
            self.ghost_pixels.push(pixels);
            self.b.push([0.0; 2]);
            self.psum.push([0.0; PV]);
            self.pq.push([0.0; PQ]);
            self.touched.push([0.0; PV]);
            self.group_sums
                .extend(std::iter::repeat_n([0.0; PV], self.groups));
        }
        (self.npix + 1) as u64 + id as u64
    }

    /// The first pixel met by ghost key `key`; None for a pixel or the light that never met the
    /// chart.
    fn first_pixel(&self, key: u64) -> Option<u64> {
        let first_ghost = (self.npix + 1) as u64;
        (key >= first_ghost).then(|| self.ghost_pixels[(key - first_ghost) as usize][0] as u64)
    }

    /// Marks key `i` as touched by this batch and returns its batch vector.
    fn touch(&mut self, i: usize) -> &mut [f64; PV] {
        if self.touched[i].iter().all(|&z| z == 0.0) {
            self.touched_list.push(i);
        }
        &mut self.touched[i]
    }

    fn absorb(&mut self, kb: &KernelBatch, batch: u64, rays: u64) {
        let group = (batch % self.groups as u64) as usize;
        self.group_rays[group] += rays;
        self.chart_current += kb.chart_current;
        self.multi_current += kb.multi_current;
        self.chart_n += kb.chart_n;
        self.multi_n += kb.multi_n;
        let units = self.units as u64;
        let mut values: Vec<(u64, [f64; PV])> = Vec::with_capacity(kb.values.len());
        for (key, v) in &kb.values {
            let (g, j) = (self.global_key(kb, (key / units) as u32), key % units);
            values.push((g * units + j, *v));
            // A ghost's light also stays with its first pixel: the linear part of the kernel
            // (see [`Kernel::apply_linear`]); the ghost entry carries the correction.
            if let Some(first) = self.first_pixel(g) {
                values.push((first * units + j, *v));
            }
        }
        // Two paths of one batch may meet the same pixels: one batch value per entry. Stable
        // sorts keep the sums in a fixed order.
        values.sort_by_key(|v| v.0);
        values.dedup_by(|later, kept| {
            if later.0 != kept.0 {
                return false;
            }
            for k in 0..PV {
                kept.1[k] += later.1[k];
            }
            true
        });
        for (key, v) in &values {
            let a = self.acc.entry(*key).or_insert([0.0; ACC]);
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
            let pv = self.touch((*key / units) as usize);
            // (g₊, g₋, x, c₊, c₋): c₊ gets T[+][−], c₋ gets T[−][+].
            for arm in Arm::ALL {
                pv[pv_g(arm)] += g[arm];
                pv[pv_c(arm)] += v[off_block(arm)];
            }
            pv[PV_X] += x;
        }
        let mut bkeys: Vec<(u32, [f64; 2])> = kb.b.iter().map(|(&i, v)| (i, *v)).collect();
        bkeys.sort_unstable_by_key(|e| e.0);
        for (i, v) in bkeys {
            let g = self.global_key(kb, i);
            for i in std::iter::once(g).chain(self.first_pixel(g)) {
                let i = i as usize;
                for arm in Arm::ALL {
                    self.b[i][arm] += v[arm];
                }
                let pv = self.touch(i);
                for arm in Arm::ALL {
                    pv[pv_c(arm)] += v[arm];
                }
            }
        }
        // Sorted so that the floating-point sums per key are made in a fixed order.
        self.touched_list.sort_unstable();
        self.touched_list.dedup();
        for &i in &self.touched_list {
            let v = self.touched[i];
            let gs = &mut self.group_sums[i * self.groups + group];
            for a in 0..PV {
                gs[a] += v[a];
            }
            for a in 0..PV {
                self.psum[i][a] += v[a];
                for c in a..PV {
                    self.pq[i][tri(a, c)] += v[a] * v[c];
                }
            }
            self.touched[i] = [0.0; PV];
        }
        self.touched_list.clear();
    }

    /// The kernel: moments centred on the batch means, entries split into pixels and ghosts.
    fn finish(
        mut self,
        grid: ObjectGrid,
        options: &TraceOptions,
        n_batches: u64,
        across: usize,
        down: usize,
        tallies: Tallies,
    ) -> Kernel {
        let nb = n_batches as f64;
        let units = self.units as u64;
        let first_ghost = (self.npix + 1) as u64;
        let mut entries: Vec<(u32, u32, KernelEntry)> = Vec::new();
        let mut ghost_entries: Vec<(u32, u32, KernelEntry)> = Vec::new();
        for (key, a) in &self.acc {
            let (i, j) = (key / units, (key % units) as u32);
            let e = KernelEntry::from_sums(a, nb);
            if i < first_ghost {
                entries.push((i as u32, j, e));
            } else {
                ghost_entries.push(((i - first_ghost) as u32, j, e));
            }
        }
        entries.sort_unstable_by_key(|e| (e.0, e.1));
        ghost_entries.sort_unstable_by_key(|e| (e.0, e.1));
        for (q, s) in self.pq.iter_mut().zip(&self.psum) {
            for a in 0..PV {
                for c in a..PV {
                    q[tri(a, c)] -= s[a] * s[c] / nb;
                }
            }
        }
        let split = self.npix + 1;
        let ghost_groups = self.group_sums.split_off(split * self.groups);
        let ghost_q = self.pq.split_off(split);
        let ghost_b = self.b.split_off(split);
        let ghosts = self
            .ghost_pixels
            .into_iter()
            .zip(ghost_b)
            .zip(ghost_q)
            .zip(ghost_groups.chunks(self.groups))
            .map(|(((pixels, b), q), g)| Ghost {
                pixels,
                b,
                q,
                group_sums: g.to_vec(),
            })
            .collect();
        Kernel {
            grid,
            rays: options.rays,
            seed: options.seed,
            batches: n_batches,
            units_across: across,
            units_down: down,
            entries,
            b: self.b,
            pixel_q: self.pq,
            ghosts,
            ghost_entries,
            tallies,
            chart_current_a: self.chart_current,
            multi_crossing_current_a: self.multi_current,
            chart_detections: self.chart_n,
            multi_crossing_detections: self.multi_n,
            group_sums: self.group_sums,
            group_rays: self.group_rays,
        }
    }
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
    /// Per batch group, the object's sums of (g₊, g₋, x, c₊, c₋), and the group's rays.
    pub group_sums: Vec<[f64; PV]>,
    pub group_rays: Vec<u64>,
    pub batches: u64,
}

impl KernelProduct {
    /// Adds kernel entry `e` of unit `j` weighted `ti`.
    fn add_entry(&mut self, ti: f64, j: usize, e: &KernelEntry) {
        if ti == 0.0 {
            return;
        }
        let units = self.x.len();
        let t2 = ti * ti;
        for ds in 0..4 {
            self.t[ds * units + j] += ti * e.t[ds];
        }
        self.x[j] += ti * e.x;
        for arm in Arm::ALL {
            self.g2[arm][j] += t2 * e.g2[arm];
            self.gx[arm][j] += t2 * e.gx[arm];
        }
        self.x2[j] += t2 * e.x2;
    }

    /// Adds a key's Bk weighted `ti`.
    #[inline]
    fn add_b(&mut self, ti: f64, b: &[f64; 2]) {
        if ti == 0.0 {
            return;
        }
        for arm in Arm::ALL {
            self.b[arm] += ti * b[arm];
        }
    }

    /// Adds a key's Bk, second moments and group sums weighted `ti`.
    fn add_pixel(&mut self, ti: f64, b: &[f64; 2], q: &[f64; PQ], groups: &[[f64; PV]]) {
        if ti == 0.0 {
            return;
        }
        self.add_b(ti, b);
        for (a, v) in self.q.iter_mut().zip(q) {
            *a += ti * ti * v;
        }
        for (s, v) in self.group_sums.iter_mut().zip(groups) {
            for k in 0..PV {
                s[k] += ti * v[k];
            }
        }
    }

    /// The covariance of the estimates of components a and c of (g₊, g₋, x, c₊, c₋): batch
    /// means over the batch groups, G/(G − 1)·Σ_g (S_ga − f_g·S_a)(S_gc − f_g·S_c) with f_g
    /// the group's share of the rays (see [`Kernel::group_sums`]). NaN for fewer than two
    /// groups.
    pub fn cov(&self, a: usize, c: usize) -> f64 {
        let groups = self.group_sums.len();
        if groups < 2 {
            return f64::NAN;
        }
        let n: u64 = self.group_rays.iter().sum();
        let total = |k: usize| self.group_sums.iter().map(|s| s[k]).sum::<f64>();
        let (sa, sc) = (total(a), total(c));
        let mut q = 0.0;
        for (s, &r) in self.group_sums.iter().zip(&self.group_rays) {
            let f = r as f64 / n as f64;
            q += (s[a] - f * sa) * (s[c] - f * sc);
        }
        let g = groups as f64;
        q * g / (g - 1.0)
    }

    /// [`KernelProduct::cov`] with the pixels of a batch taken as independent:
    /// Σ_i t_i²·cov_i (batch means, times B/(B − 1)). It misses the Latin hypercube's
    /// covariance between the pixels of a batch; kept to measure that.
    pub fn cov_independent_pixels(&self, a: usize, c: usize) -> f64 {
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
        self.apply_with(object, |g| g.weight(object), true)
    }

    /// [`Kernel::apply`] (`linear`: [`Kernel::apply_linear`]) without the batch-group sums and
    /// second moments of the totals: `group_sums` and `q` stay zero, so the totals' standard
    /// errors are unknown. Those sums stream 32 × 5 numbers per pixel (12 MB for 96 × 96
    /// pixels), most of the product's memory traffic, and a dataset sample or a Python
    /// measurement never reports them.
    pub fn apply_values(&self, object: &[f64], linear: bool) -> KernelProduct {
        if linear {
            self.apply_with(object, |g| object[g.pixels[0] as usize], false)
        } else {
            self.apply_with(object, |g| g.weight(object), false)
        }
    }

    /// The kernel's linear part: every path weighted by the first pixel it met (the ghosts'
    /// light attributed to their first pixel, as `entries`, `b` and `group_sums` hold it).
    /// The linear operator of `pipeline::operator` is this; [`Kernel::apply`] adds the ghosts'
    /// corrections Π_k t_{i_k} − t_{i_1}.
    pub fn apply_linear(&self, object: &[f64]) -> KernelProduct {
        self.apply_with(object, |g| object[g.pixels[0] as usize], true)
    }

    /// The product with the ghosts weighted by `ghost_weight` instead of t of their first pixel;
    /// the totals' error sums only with `errors`.
    fn apply_with(
        &self,
        object: &[f64],
        ghost_weight: impl Fn(&Ghost) -> f64,
        errors: bool,
    ) -> KernelProduct {
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
            group_sums: vec![[0.0; PV]; if errors { self.group_rays.len() } else { 0 }],
            group_rays: self.group_rays.clone(),
            batches: self.batches,
        };
        for (i, j, e) in &self.entries {
            p.add_entry(w(*i), *j as usize, e);
        }
        let groups = self.group_rays.len();
        for (i, (bi, qi)) in self.b.iter().zip(&self.pixel_q).enumerate() {
            if errors {
                let gs = &self.group_sums[i * groups..(i + 1) * groups];
                p.add_pixel(w(i as u32), bi, qi, gs);
            } else {
                p.add_b(w(i as u32), bi);
            }
        }
        // The ghosts' light is in the entries at its first pixel already: the correction.
        let ghost_w: Vec<f64> = self
            .ghosts
            .iter()
            .map(|g| ghost_weight(g) - object[g.pixels[0] as usize])
            .collect();
        for (g, j, e) in &self.ghost_entries {
            p.add_entry(ghost_w[*g as usize], *j as usize, e);
        }
        for (g, wg) in self.ghosts.iter().zip(&ghost_w) {
            if errors {
                p.add_pixel(*wg, &g.b, &g.q, &g.group_sums);
            } else {
                p.add_b(*wg, &g.b);
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
