//! Irradiance maps on the photodiodes, from the same trace as the tallies
//! ([`trace_with_maps`]; no second pass): for each diode, the power per square bin of its plane
//! over the active area and the front plate of its housing around it, per mirror state (every
//! pattern unit +, every unit −, and the pattern-independent part: light that never met the
//! pattern area), with the standard error of every bin from the batch totals.
//!
//! A path reaching the active area is binned where it lands (the same path, the same weight,
//! as the detected power of the ledger), a path absorbed by the housing's front plate likewise
//! (the plate is the annulus of `housing_diameter_mm` in the diode's plane); light beyond the
//! map's square, or on a bench without a housing beyond the active area, is not mapped. So the
//! map's active-area layer sums to the ledger's detected power of each state to rounding.
//!
//! Each batch keeps its hits as a short list (a few hundred for 1024 rays), so a batch waiting
//! for the merge costs little memory; the merge bins them in batch order, so the maps are
//! bit-identical on any number of threads.

use glam::DVec3;

use super::path::{Detection, Recorder};
use super::tally::{BRANCH_MINUS, BRANCH_PLUS, BatchTally, COMMON, Tallies};
use super::{RAYS_PER_BATCH, TraceOptions, batches_in_order, path};
use crate::error::Result;
use crate::optics::Bench;
use crate::optics::geometry::Frame;

/// Bins across each map (square bins, the same count along both axes).
pub const DEFAULT_BINS: usize = 64;

/// The map's half-width as a multiple of the active radius when a diode has no housing.
const BARE_HALF_WIDTH: f64 = 2.0;

/// The mirror states of the maps, in array order: every unit +, every unit −, and the
/// pattern-independent part.
pub const STATES: [&str; 3] = ["all_plus", "all_minus", "pattern_independent"];

/// Layers of a map: what reached the active area, what the front plate absorbed.
const LAYERS: usize = 2;

/// One diode's map window: its frame (centre of the active area, w its normal, u and v the
/// map's x and y axes), active radius, half-width of the square and the housing's element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    pub frame: Frame,
    pub radius_m: f64,
    pub half_width_m: f64,
    pub housing: Option<usize>,
}

impl Window {
    /// The bin of a point of the diode's plane, if inside the square.
    fn bin(&self, bins: usize, hit: DVec3) -> Option<usize> {
        let l = self.frame.to_local(hit);
        let k = |x: f64| {
            let f = (x + self.half_width_m) / (2.0 * self.half_width_m);
            (0.0..1.0)
                .contains(&f)
                .then_some((f * bins as f64) as usize)
        };
        // Row 0 at +v (the top of an image), column 0 at −u.
        Some((bins - 1 - k(l.y)?) * bins + k(l.x)?)
    }

    /// The centre of bin (row, col) in the map's (u, v) coordinates (m).
    pub fn bin_centre(&self, bins: usize, row: usize, col: usize) -> (f64, f64) {
        let s = 2.0 * self.half_width_m / bins as f64;
        (
            -self.half_width_m + (col as f64 + 0.5) * s,
            self.half_width_m - (row as f64 + 0.5) * s,
        )
    }
}

/// The map windows of a bench's two diodes.
pub fn windows(bench: &Bench) -> [Window; 2] {
    let names = ["pd_plus_housing", "pd_minus_housing"];
    std::array::from_fn(|d| {
        let det = &bench.detectors()[d];
        let housing = bench.elements().iter().position(|e| e == names[d]);
        let outer = housing.and_then(|id| {
            bench.surfaces().iter().find_map(|s| match s.geometry {
                crate::optics::geometry::Geometry::Plane {
                    shape: crate::optics::geometry::Shape2D::Annulus { outer, .. },
                    ..
                } if s.element == id => Some(outer),
                _ => None,
            })
        });
        Window {
            frame: det.frame,
            radius_m: det.radius,
            half_width_m: outer.unwrap_or(BARE_HALF_WIDTH * det.radius),
            housing,
        }
    })
}

/// The map of a named surface (baffles, stray light): the power crossing the element's first
/// surface, binned in that surface's plane (its frame's u, v; a curved surface is projected
/// along its axis), over a square 10 % wider than the surface's outline.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceMap {
    pub name: String,
    /// The index of the mapped surface in `Bench::surfaces`.
    pub surface: usize,
    pub window: Window,
}

/// The map windows of the named elements, in the order given. An unknown name is an error of
/// the field `irradiance_at` naming it and listing the bench's element names.
pub fn surface_maps(bench: &Bench, names: &[String]) -> Result<Vec<SurfaceMap>> {
    use crate::optics::geometry::Geometry;
    // A hit stores its map's index in a u8 (`Hit`), the diodes taking 0 and 1; a name given
    // twice would only duplicate a map.
    for (k, name) in names.iter().enumerate() {
        if names[..k].contains(name) {
            return Err(crate::error::Error::field(
                "irradiance_at",
                format!("`{name}` is named twice"),
            ));
        }
    }
    if names.len() > usize::from(u8::MAX) - 2 {
        return Err(crate::error::Error::field(
            "irradiance_at",
            format!(
                "{} surfaces named; at most {} can be mapped",
                names.len(),
                u8::MAX - 2
            ),
        ));
    }
    names
        .iter()
        .map(|name| {
            let element = bench.elements().iter().position(|e| e == name);
            let found = element.and_then(|id| {
                bench
                    .surfaces()
                    .iter()
                    .position(|s| s.element == id)
                    .map(|i| (i, &bench.surfaces()[i]))
            });
            let Some((surface, s)) = found else {
                return Err(crate::error::Error::field(
                    "irradiance_at",
                    format!(
                        "no element named `{name}` in the bench; its elements: {}",
                        bench.elements().join(", ")
                    ),
                ));
            };
            let (frame, radius) = match &s.geometry {
                Geometry::Plane { frame, shape } => (*frame, shape.bounding_radius()),
                Geometry::SphereCap {
                    vertex,
                    axis,
                    aperture,
                    ..
                } => (Frame::new(*vertex, *axis, None), *aperture),
                Geometry::Asphere {
                    frame, aperture, ..
                } => (*frame, *aperture),
                Geometry::Cylinder {
                    base, axis, radius, ..
                } => (Frame::new(*base, *axis, None), *radius),
            };
            Ok(SurfaceMap {
                name: name.clone(),
                surface,
                window: Window {
                    frame,
                    radius_m: radius,
                    half_width_m: 1.1 * radius,
                    housing: None,
                },
            })
        })
        .collect()
}

/// Map d's window: the two diodes (0, 1), then the named surfaces (2 + k).
fn map_window<'a>(windows: &'a [Window; 2], surfaces: &'a [SurfaceMap], d: usize) -> &'a Window {
    match d {
        0 | 1 => &windows[d],
        _ => &surfaces[d - 2].window,
    }
}

/// One mapped hit of a batch: (diode, ledger world, layer, bin) and its power (W).
type Hit = (u8, u8, u8, u32, f64);

/// The recorder of a mapped trace: every hit on a diode's map, in the order traced.
pub(super) struct MapRecorder<'a> {
    windows: &'a [Window; 2],
    surfaces: &'a [SurfaceMap],
    bins: usize,
    hits: Vec<Hit>,
}

impl MapRecorder<'_> {
    fn add(&mut self, d: usize, world: usize, layer: u8, hit: DVec3, w: f64) {
        if let Some(b) = map_window(self.windows, self.surfaces, d).bin(self.bins, hit) {
            self.hits.push((d as u8, world as u8, layer, b as u32, w));
        }
    }
}

impl Recorder for MapRecorder<'_> {
    #[inline(always)]
    fn segment(&mut self, _: DVec3, _: DVec3, _: f64) {}
    #[inline(always)]
    fn ray_done(&mut self, _: &BatchTally) {}
    fn detected(&mut self, h: Detection) {
        self.add(h.detector.index(), h.world, 0, h.hit, h.power_w);
    }
    fn absorbed(&mut self, world: usize, element: usize, hit: DVec3, w: f64) {
        for d in 0..2 {
            if self.windows[d].housing == Some(element) {
                self.add(d, world, 1, hit, w);
            }
        }
    }
    fn met(&mut self, world: usize, surface: usize, hit: DVec3, w: f64) {
        for k in 0..self.surfaces.len() {
            if self.surfaces[k].surface == surface {
                self.add(2 + k, world, 0, hit, w);
            }
        }
    }
}

/// The maps of a trace: for diode d, state s and layer l, bin i (row-major, row 0 at +v) at
/// index ((d·3 + s)·2 + l)·bins² + i, the power (W) summed over batches and the sum of squares
/// of the batch totals.
#[derive(Debug, Clone, PartialEq)]
pub struct IrradianceMaps {
    pub bins: usize,
    pub windows: [Window; 2],
    /// The named surfaces' maps: map 2 + k is `surfaces[k]` (one layer: the power crossing).
    pub surfaces: Vec<SurfaceMap>,
    pub batches: u64,
    pub power_w: Vec<f64>,
    pub sum_sq: Vec<f64>,
    /// The pattern light alone (the branch worlds, without the pattern-independent part): for
    /// map d, branch b (0: the units in state +, 1: in −), layer l and bin i at
    /// [`branch_index`], the power summed over batches and the sum of squares of the batch
    /// totals. A state's map less the pattern-independent one is this sum to rounding, but its
    /// error is not that of either (the two share their batches), hence its own sums.
    pub branch_w: Vec<f64>,
    pub branch_sum_sq: Vec<f64>,
    /// The merge's scratch: one batch's bins per diode, world and layer, and the bins touched.
    scratch: Vec<f64>,
    touched: Vec<u32>,
}

/// The index of (diode, state, layer, bin).
#[inline]
pub fn index(bins: usize, d: usize, s: usize, l: usize, i: usize) -> usize {
    ((d * 3 + s) * LAYERS + l) * bins * bins + i
}

/// The index of (map, branch, layer, bin) in the branch sums.
#[inline]
pub fn branch_index(bins: usize, d: usize, b: usize, l: usize, i: usize) -> usize {
    ((d * 2 + b) * LAYERS + l) * bins * bins + i
}

impl IrradianceMaps {
    pub fn new(windows: [Window; 2], surfaces: Vec<SurfaceMap>, bins: usize) -> IrradianceMaps {
        let maps = 2 + surfaces.len();
        let n = maps * 3 * LAYERS * bins * bins;
        let nb = maps * 2 * LAYERS * bins * bins;
        IrradianceMaps {
            bins,
            windows,
            surfaces,
            batches: 0,
            power_w: vec![0.0; n],
            sum_sq: vec![0.0; n],
            branch_w: vec![0.0; nb],
            branch_sum_sq: vec![0.0; nb],
            scratch: vec![0.0; n],
            touched: Vec::new(),
        }
    }

    /// Adds the maps of another trace of the same bench and windows over independent batches
    /// (another seed): the sums and sums of squares add, and so do the batches, so that every
    /// bin's error is that of the pooled batches. Refused (an error naming what differs) when
    /// the two do not have the same bins, windows and surfaces.
    pub fn merge(&mut self, other: &IrradianceMaps) -> Result<()> {
        if self.bins != other.bins
            || self.windows != other.windows
            || self.surfaces != other.surfaces
        {
            return Err(crate::Error::Numerical(
                "irradiance maps of different windows cannot be pooled".into(),
            ));
        }
        for (a, b) in [
            (&mut self.power_w, &other.power_w),
            (&mut self.sum_sq, &other.sum_sq),
            (&mut self.branch_w, &other.branch_w),
            (&mut self.branch_sum_sq, &other.branch_sum_sq),
        ] {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
        self.batches += other.batches;
        Ok(())
    }

    /// Adds one batch's hits (called in batch order).
    fn absorb(&mut self, hits: &[Hit]) {
        let bins = self.bins;
        // scratch holds worlds (COMMON, BRANCH_PLUS, BRANCH_MINUS) in the state slots.
        for &(d, world, l, b, w) in hits {
            let k = index(bins, d as usize, world as usize, l as usize, b as usize);
            if self.scratch[k] == 0.0 {
                self.touched
                    .push(index(bins, d as usize, 0, l as usize, b as usize) as u32);
            }
            self.scratch[k] += w;
        }
        self.touched.sort_unstable();
        self.touched.dedup();
        let stride = LAYERS * bins * bins;
        for &k0 in &self.touched {
            let k0 = k0 as usize;
            let (c, p, m) = (
                self.scratch[k0 + COMMON * stride],
                self.scratch[k0 + BRANCH_PLUS * stride],
                self.scratch[k0 + BRANCH_MINUS * stride],
            );
            for (s, v) in [c + p, c + m, c].into_iter().enumerate() {
                self.power_w[k0 + s * stride] += v;
                self.sum_sq[k0 + s * stride] += v * v;
            }
            // k0 = index(d, 0, l, i) = (d·3·LAYERS + l)·bins² + i: its map d and layer l.
            let area = bins * bins;
            let (d, rest) = (k0 / (3 * stride), k0 % (3 * stride));
            let (l, i) = (rest / area, rest % area);
            for (b, v) in [p, m].into_iter().enumerate() {
                let kb = branch_index(bins, d, b, l, i);
                self.branch_w[kb] += v;
                self.branch_sum_sq[kb] += v * v;
            }
            for world in 0..3 {
                self.scratch[k0 + world * stride] = 0.0;
            }
        }
        self.touched.clear();
        self.batches += 1;
    }

    /// The standard error (W) of the power in entry `k` (batch means: the total is a sum of
    /// `batches` independent batch totals).
    pub fn stderr_w(&self, k: usize) -> f64 {
        batch_stderr(self.batches, self.power_w[k], self.sum_sq[k])
    }

    /// The signal spill of map d, branch b (0: every unit +, 1: every unit −): of the pattern
    /// light alone (the state's map less its pattern-independent part, which no pattern moves
    /// and a balanced detector's offset calibration removes), the share on the housing's
    /// plate, with its standard error by first-order propagation, the bins independent (as
    /// for the centroid): with A and P the signal on the active area and the plate and
    /// T = A + P, ∂(P/T)/∂P_i = A/T² and ∂(P/T)/∂A_i = −P/T². (0, 0) when no pattern light
    /// was mapped.
    pub fn signal_spill(&self, d: usize, b: usize) -> (f64, f64) {
        let bins = self.bins;
        let n = bins * bins;
        let sum = |l: usize| -> f64 {
            (0..n)
                .map(|i| self.branch_w[branch_index(bins, d, b, l, i)])
                .sum()
        };
        let (a, p) = (sum(0), sum(1));
        let t = a + p;
        if t <= 0.0 {
            return (0.0, 0.0);
        }
        let se = |l: usize, i: usize| {
            let k = branch_index(bins, d, b, l, i);
            batch_stderr(self.batches, self.branch_w[k], self.branch_sum_sq[k])
        };
        let var: f64 = (0..n)
            .map(|i| (a * se(1, i)).powi(2) + (p * se(0, i)).powi(2))
            .sum();
        (p / t, var.sqrt() / (t * t))
    }

    /// Map d's window: the diodes (0, 1), then the named surfaces.
    pub fn window(&self, d: usize) -> &Window {
        map_window(&self.windows, &self.surfaces, d)
    }

    /// The area of one bin (m²).
    pub fn bin_area_m2(&self, d: usize) -> f64 {
        (2.0 * self.window(d).half_width_m / self.bins as f64).powi(2)
    }

    /// Diode d's map in state s, both layers: irradiance (W/m²) and its standard error, row-major.
    pub fn irradiance(&self, d: usize, s: usize) -> (Vec<f64>, Vec<f64>) {
        let (n, a) = (self.bins * self.bins, self.bin_area_m2(d));
        let mut e = vec![0.0; n];
        let mut se = vec![0.0; n];
        for i in 0..n {
            let (k0, k1) = (index(self.bins, d, s, 0, i), index(self.bins, d, s, 1, i));
            e[i] = (self.power_w[k0] + self.power_w[k1]) / a;
            // Active area and plate are disjoint in a bin only at the edge; a bin's error is
            // that of the sum of its two layers, bounded by the sum of their errors.
            se[i] = (self.stderr_w(k0) + self.stderr_w(k1)) / a;
        }
        (e, se)
    }

    /// The standard error (W) of bin i of map d in state s, both layers (as in `irradiance`).
    pub fn bin_stderr_w(&self, d: usize, s: usize, i: usize) -> f64 {
        let bins = self.bins;
        self.stderr_w(index(bins, d, s, 0, i)) + self.stderr_w(index(bins, d, s, 1, i))
    }

    /// The summary numbers of diode d in state s.
    pub fn stats(&self, d: usize, s: usize) -> MapStats {
        let bins = self.bins;
        let n = bins * bins;
        let layer =
            |l: usize| -> f64 { (0..n).map(|i| self.power_w[index(bins, d, s, l, i)]).sum() };
        let (active, plate) = (layer(0), layer(1));
        let layer_se = |l: usize| -> f64 {
            // The batch totals' error of a layer: from the per-bin sums it is not available,
            // so the quadrature sum of the bins' errors is given (bins are correlated only
            // through the batches they share).
            (0..n)
                .map(|i| self.stderr_w(index(bins, d, s, l, i)).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let total = active + plate;
        let (mut cx, mut cy) = (0.0, 0.0);
        let w = self.window(d);
        let weight = |i: usize| {
            self.power_w[index(bins, d, s, 0, i)] + self.power_w[index(bins, d, s, 1, i)]
        };
        for i in 0..n {
            let (x, y) = w.bin_centre(bins, i / bins, i % bins);
            cx += weight(i) * x;
            cy += weight(i) * y;
        }
        let (cx, cy) = if total > 0.0 {
            (cx / total, cy / total)
        } else {
            (0.0, 0.0)
        };
        let mut r2 = 0.0;
        // The centroid's variance by the delta method, bins independent: ∂c_x/∂w_i =
        // (x_i − c_x)/W, so var c_x ≈ Σ (x_i − c_x)² se_i² / W² (se_i as in `irradiance`).
        let (mut vx, mut vy) = (0.0, 0.0);
        for i in 0..n {
            let (x, y) = w.bin_centre(bins, i / bins, i % bins);
            r2 += weight(i) * ((x - cx).powi(2) + (y - cy).powi(2));
            let se = self.bin_stderr_w(d, s, i);
            vx += ((x - cx) * se).powi(2);
            vy += ((y - cy) * se).powi(2);
        }
        let centroid_stderr_m = if total > 0.0 {
            [vx.sqrt() / total, vy.sqrt() / total]
        } else {
            [0.0, 0.0]
        };
        MapStats {
            active_w: active,
            active_stderr_w: layer_se(0),
            plate_w: plate,
            centroid_m: [cx, cy],
            centroid_stderr_m,
            rms_radius_m: if total > 0.0 {
                (r2 / total).sqrt()
            } else {
                0.0
            },
            spill: if total > 0.0 { plate / total } else { 0.0 },
        }
    }
}

/// Replica k's seed: the trace streams hash it again (`rng::stream`), so neighbouring values
/// are unrelated; xor with k on the hashed seed keeps the replicas of one seed distinct.
pub fn replica_seed(seed: u64, k: u64) -> u64 {
    crate::rng::mix64(seed) ^ k
}

/// The maps of independent replicas of one trace ([`trace_replicas`]).
pub struct Replicas {
    /// Their sum, the batches pooled (each bin's error is the pooled batches').
    pub pooled: IrradianceMaps,
    /// Per diode and replica, the diode's numbers in its own state; None where it mapped no
    /// light.
    pub each: [Vec<Option<MapStats>>; 2],
}

/// `replicas` traces (at least one) of `bench` with `rays` lamp rays each on the seeds [`replica_seed`] of
/// `seed`, mapped with `bins` bins, so that a ratio's error can be read from the replicas'
/// spread as well as from the bins (each replica is identical on any number of threads, and
/// so is the whole).
pub fn trace_replicas(
    bench: &Bench,
    rays: u64,
    seed: u64,
    replicas: u64,
    bins: usize,
) -> Result<Replicas> {
    let mut each: [Vec<Option<MapStats>>; 2] = [Vec::new(), Vec::new()];
    let mut replica = |k: u64| -> Result<IrradianceMaps> {
        let options = TraceOptions::new(rays, replica_seed(seed, k));
        let (_, maps) = trace_with_maps(bench, &options, bins)?;
        for (d, e) in each.iter_mut().enumerate() {
            let st = maps.stats(d, d);
            e.push((st.active_w + st.plate_w > 0.0).then_some(st));
        }
        Ok(maps)
    };
    let mut pooled = replica(0)?;
    for k in 1..replicas {
        pooled.merge(&replica(k)?)?;
    }
    Ok(Replicas { pooled, each })
}

/// The standard error of a sum of `batches` independent batch totals whose sum is `s` and sum
/// of squares `q` (batch means).
fn batch_stderr(batches: u64, s: f64, q: f64) -> f64 {
    let n = batches as f64;
    if n < 2.0 {
        return 0.0;
    }
    (n / (n - 1.0) * (q - s * s / n).max(0.0)).sqrt()
}

/// A map's summary numbers (positions in the map's (u, v) axes from the active area's centre).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapStats {
    /// Power on the active area (W): the ledger's detected power of the state.
    pub active_w: f64,
    pub active_stderr_w: f64,
    /// Power on the front plate around it (W).
    pub plate_w: f64,
    /// The centre of the light (m).
    pub centroid_m: [f64; 2],
    /// Its standard error along each axis (m), from the bins' errors taken as independent (0
    /// when nothing was mapped).
    pub centroid_stderr_m: [f64; 2],
    /// The RMS radius about it (m).
    pub rms_radius_m: f64,
    /// The share of the mapped light outside the active area: plate ÷ (active + plate).
    pub spill: f64,
}

/// Traces as [`super::trace`] does and maps the light on the diodes from the same paths, with
/// `bins` bins across each map.
pub fn trace_with_maps(
    bench: &Bench,
    options: &TraceOptions,
    bins: usize,
) -> Result<(Tallies, IrradianceMaps)> {
    trace_with_surface_maps(bench, options, bins, &[])
}

/// [`trace_with_maps`] that also maps the power crossing each named element's first surface
/// (maps 2, 3, … in the order named), from the same paths.
pub fn trace_with_surface_maps(
    bench: &Bench,
    options: &TraceOptions,
    bins: usize,
    names: &[String],
) -> Result<(Tallies, IrradianceMaps)> {
    super::check_options(bench, options)?;
    let surfaces = surface_maps(bench, names)?;
    let (across, down) = bench.units_shape();
    let mut tallies = Tallies::new(
        across,
        down,
        bench.elements().len(),
        options.seed,
        bench.lamp().power_outside_cone(),
    );
    let windows = windows(bench);
    let mut maps = IrradianceMaps::new(windows, surfaces.clone(), bins);
    let n = options.rays;
    let inv = 1.0 / n as f64;
    batches_in_order(
        n.div_ceil(RAYS_PER_BATCH),
        |b| {
            let rays = RAYS_PER_BATCH.min(n - b * RAYS_PER_BATCH);
            let mut rec = MapRecorder {
                windows: &windows,
                surfaces: &surfaces,
                bins,
                hits: Vec::new(),
            };
            let t = path::run_batch_sampled(
                bench,
                options.mode,
                options.sampling,
                options.seed,
                b,
                rays,
                inv,
                &mut rec,
            );
            (t, rec.hits)
        },
        |_, (t, hits)| {
            tallies.absorb(&t);
            maps.absorb(&hits);
        },
        |batches| {
            if let Some(report) = options.progress {
                report((batches * RAYS_PER_BATCH).min(n), n);
            }
        },
    );
    Ok((tallies, maps))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::Arm;
    use crate::trace::tally::{EXTRA_SLOTS, slot_detected};

    /// A named surface must exist and be named once; the error names the field, not a flag.
    #[test]
    fn unknown_or_repeated_surface_names_are_refused() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let first = bench.elements()[bench.surfaces()[0].element].clone();
        assert_eq!(
            surface_maps(&bench, std::slice::from_ref(&first))
                .unwrap()
                .len(),
            1
        );
        let e = surface_maps(&bench, &["no_such".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("no_such") && e.contains(&first), "{e}");
        let e = surface_maps(&bench, &[first.clone(), first])
            .unwrap_err()
            .to_string();
        assert!(e.contains("twice"), "{e}");
    }

    /// The map summed over each diode's active area is the ledger's detected power of each
    /// mirror state (the same paths: equal to rounding, far inside the standard error), the
    /// tallies are those of the plain trace, and the light lands near the diode's centre.
    #[test]
    fn the_active_area_sums_to_the_detected_power() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let o = TraceOptions::new(20_000, 3);
        let (t, maps) = trace_with_maps(&bench, &o, DEFAULT_BINS).unwrap();
        let plain = super::super::trace(&bench, &o).unwrap();
        assert_eq!(t, plain);
        let n_el = bench.elements().len();
        for arm in Arm::ALL {
            let slot = n_el + slot_detected(arm);
            let common = t.ledger[COMMON][slot];
            let want = [
                common + t.ledger[BRANCH_PLUS][slot],
                common + t.ledger[BRANCH_MINUS][slot],
                common,
            ];
            for (s, w) in want.into_iter().enumerate() {
                let st = maps.stats(arm.index(), s);
                assert!(
                    (st.active_w - w).abs() <= 1e-12 * w.abs().max(1e-30),
                    "{arm:?} {}: {} vs {w}",
                    STATES[s],
                    st.active_w
                );
                assert!((st.active_w - w).abs() <= st.active_stderr_w.max(1e-300));
                assert!((0.0..=1.0).contains(&st.spill));
            }
            let own = maps.stats(arm.index(), arm.index());
            assert!(own.active_w > 0.0);
            assert!(
                own.centroid_m[0].hypot(own.centroid_m[1]) < maps.windows[arm.index()].half_width_m
            );
        }
        assert_eq!(EXTRA_SLOTS, t.ledger[COMMON].len() - n_el);
    }

    /// The signal spill: its active-area sums are the ledger's branch detected powers (the
    /// same paths), it equals the plate's share of the state's map less the
    /// pattern-independent one to rounding, and its standard error agrees with the scatter of
    /// 8 independent traces: the sample standard deviation over the mean reported error lies
    /// within the 99 % band of a χ² with 7 degrees of freedom, √(0.99/7) … √(20.3/7) =
    /// 0.38 … 1.70. Pooling the 8 (`merge`) divides the error by about √8.
    #[test]
    fn the_signal_spill_and_its_error_match_the_scatter_of_seeds() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let n_el = bench.elements().len();
        let mut spills = [Vec::new(), Vec::new()];
        let mut errors = [Vec::new(), Vec::new()];
        let mut pooled: Option<IrradianceMaps> = None;
        for seed in 0..8 {
            let (t, maps) =
                trace_with_maps(&bench, &TraceOptions::new(8192, 40 + seed), 32).unwrap();
            for arm in Arm::ALL {
                let (d, b) = (arm.index(), arm.index());
                let slot = n_el + slot_detected(arm);
                let world = [BRANCH_PLUS, BRANCH_MINUS][b];
                let active: f64 = (0..32 * 32)
                    .map(|i| maps.branch_w[branch_index(32, d, b, 0, i)])
                    .sum();
                let want = t.ledger[world][slot];
                assert!(
                    (active - want).abs() <= 1e-12 * want.abs(),
                    "{active} vs {want}"
                );
                let (own, common) = (maps.stats(d, b), maps.stats(d, 2));
                let (pa, pp) = (own.active_w - common.active_w, own.plate_w - common.plate_w);
                let (spill, se) = maps.signal_spill(d, b);
                assert!(
                    (spill - pp / (pa + pp)).abs() < 1e-9,
                    "{spill} vs {}",
                    pp / (pa + pp)
                );
                assert!(se > 0.0 && spill > 0.0 && spill < 1.0, "{spill} ± {se}");
                spills[d].push(spill);
                errors[d].push(se);
            }
            match &mut pooled {
                None => pooled = Some(maps),
                Some(p) => p.merge(&maps).unwrap(),
            }
        }
        let pooled = pooled.unwrap();
        for d in 0..2 {
            let n = spills[d].len() as f64;
            let mean = spills[d].iter().sum::<f64>() / n;
            let sd = (spills[d].iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let se = errors[d].iter().sum::<f64>() / n;
            assert!(
                (0.38..=1.70).contains(&(sd / se)),
                "diode {d}: sd {sd:e}, se {se:e}"
            );
            let (p, pse) = pooled.signal_spill(d, d);
            assert!((p - mean).abs() < 4.0 * pse, "{p} vs {mean}");
            // Each replica's error is estimated from its 8 batches (relative scatter about
            // 1/√(2·7) ≈ 0.27), their mean to ≈ 0.1 and the pooled one's from 64 batches to
            // ≈ 0.09: 0.3 is about 2.2 standard deviations of the ratio.
            assert!(
                (pse * 8f64.sqrt() / se - 1.0).abs() < 0.3,
                "{pse:e} vs {se:e}"
            );
        }
    }

    /// The centroid's standard error in closed form: two bins of powers w₁, w₂ at x₁, x₂ with
    /// errors s₁, s₂ put the centroid at (w₁x₁ + w₂x₂)/W, and ∂c/∂w₁ = w₂(x₁ − x₂)/W²,
    /// ∂c/∂w₂ = w₁(x₂ − x₁)/W², so var c = (x₁ − x₂)²(w₂²s₁² + w₁²s₂²)/W⁴. Two batches of
    /// totals a, b give a bin the error |a − b| (batch means, n/(n − 1) = 2).
    #[test]
    fn the_centroid_error_of_two_bins_is_the_closed_form() {
        let window = Window {
            frame: Frame::new(DVec3::ZERO, DVec3::Z, None),
            radius_m: 1e-3,
            half_width_m: 2e-3,
            housing: None,
        };
        let bins = 4;
        let mut maps = IrradianceMaps::new([window; 2], Vec::new(), bins);
        maps.batches = 2;
        // Bin (row 0, col 0) in the active layer with batch totals 3 and 1 (w₁ = 4, s₁ = 2);
        // bin (row 2, col 3) on the plate with 0.5 and 1.5 (w₂ = 2, s₂ = 1); diode 1, state 1.
        let (b1, b2) = (0, 2 * bins + 3);
        for (l, i, a, b) in [(0, b1, 3.0, 1.0), (1, b2, 0.5, 1.5)] {
            let k = index(bins, 1, 1, l, i);
            maps.power_w[k] = a + b;
            maps.sum_sq[k] = a * a + b * b;
        }
        let st = maps.stats(1, 1);
        let (w1, s1, w2, s2, total) = (4.0, 2.0, 2.0, 1.0, 6.0);
        let (x1, y1) = window.bin_centre(bins, 0, 0);
        let (x2, y2) = window.bin_centre(bins, 2, 3);
        let want = |p1: f64, p2: f64| {
            ((p1 - p2).powi(2) * (w2 * w2 * s1 * s1 + w1 * w1 * s2 * s2)).sqrt() / (total * total)
        };
        assert!((st.centroid_m[0] - (w1 * x1 + w2 * x2) / total).abs() < 1e-18);
        for (got, want) in st
            .centroid_stderr_m
            .iter()
            .zip([want(x1, x2), want(y1, y2)])
        {
            assert!((got - want).abs() <= 1e-12 * want, "{got:e} vs {want:e}");
        }
        // Nothing mapped: no centroid and no error.
        assert_eq!(maps.stats(0, 0).centroid_stderr_m, [0.0, 0.0]);
    }

    /// The maps are bit-identical on one and two threads.
    #[test]
    fn maps_are_identical_on_one_and_two_threads() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let o = TraceOptions::new(6_000, 11);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| trace_with_maps(&bench, &o, 32).unwrap())
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a.1.power_w, b.1.power_w);
        assert_eq!(a.1.sum_sq, b.1.sum_sq);
        assert_eq!(a.0, b.0);
    }

    /// A bench that images a uniformly lit Lambertian disk 1:1 through a stop and a weak
    /// symmetric lens of constant index (no dispersion, no reflections) onto a diode: the
    /// image is a disk of the same radius, uniformly lit (the view factor of the stop varies by
    /// (ρ/s)² ~ 1e-5 over the source), and every bin's expected power is the image's irradiance
    /// times the bin's overlap with the disk. Returns the bench, the image radius (m) and the mean view
    /// factor of the stop from the source.
    fn imaged_disk() -> (Bench, f64, f64) {
        // Thick-lens numbers (n = 1.5, R₁ = −R₂ = 200 mm, t = 2 mm): power, principal planes
        // (inside the lens, δ = f(n−1)t/(nR) from each vertex) and the 2f–2f conjugates.
        let (n, r, t) = (1.5f64, 200.0f64, 2.0f64);
        let phi = (n - 1.0) * (2.0 / r - (n - 1.0) * t / (n * r * r));
        let f = 1.0 / phi;
        let delta = f * (n - 1.0) * t / (n * r);
        let front = 2.0 * f - delta;
        let image = front + t - delta + 2.0 * f;
        let stop = front - 1.0;
        let text = format!(
            r#"(
    lamp: (
        position_mm: (0.0, 0.0, 0.0),
        axis: Vector((0.0, 0.0, 1.0)),
        filament: Disk(diameter_mm: 2.0),
        spectrum: Table([(350.0, 1.0), (1150.0, 1.0)]),
        power: InBand(watts: 2.0),
        emission: Cone(half_angle_deg: 1.0),
    ),
    elements: [
        Aperture(name: "stop", position_mm: (0.0, 0.0, {stop}), axis: Vector((0.0, 0.0, 1.0)),
            inner_diameter_mm: 10.0, outer_diameter_mm: 40.0),
        Lens(name: "lens", position_mm: (0.0, 0.0, {front}), axis: Vector((0.0, 0.0, 1.0)),
            front_radius_mm: Some({r}), back_radius_mm: Some(-{r}), thickness_mm: {t},
            diameter_mm: 20.0, glass: "1.5", coating: Reflectance(Constant(0.0))),
    ],
    detectors: (
        plus: (position_mm: (0.0, 0.0, {image}), normal: Vector((0.0, 0.0, -1.0)),
            diameter_mm: 2.4, responsivity: Constant(0.5), housing_diameter_mm: Some(4.0)),
        minus: (position_mm: (0.0, 0.0, -100.0), normal: Vector((0.0, 0.0, -1.0)),
            diameter_mm: 5.0, responsivity: Constant(0.5)),
    ),
)"#
        );
        let bench =
            crate::scene::bench::parse_bench(&text, std::path::Path::new("disk.ron")).unwrap();
        // The power through the stop: the view factor of a disk of radius a at distance s from
        // a point at ρ on a parallel plane (F = ½[1 − (s² + ρ² − a²)/√((s² + ρ² + a²)² −
        // 4a²ρ²)]), averaged over the uniformly emitting source disk (radius 1 mm).
        let (a, s_stop, rs) = (5e-3, stop * 1e-3, 1e-3);
        let view = |rho: f64| {
            let q = s_stop * s_stop + rho * rho;
            0.5 * (1.0 - (q - a * a) / ((q + a * a).powi(2) - 4.0 * a * a * rho * rho).sqrt())
        };
        let k = 2000;
        let mean = (0..k)
            .map(|i| {
                let rho = rs * (i as f64 + 0.5) / k as f64;
                view(rho) * 2.0 * rho / (rs * rs) * rs / k as f64
            })
            .sum::<f64>();
        (bench, rs, mean)
    }

    /// The area (m²) of the square [x0, x1] × [y0, y1] inside the disk of radius r at the
    /// origin, by the chord integral (midpoint rule, 400 steps: exact to ~1e-6 of a bin).
    fn overlap(x0: f64, x1: f64, y0: f64, y1: f64, r: f64) -> f64 {
        let k = 400;
        let dx = (x1 - x0) / k as f64;
        (0..k)
            .map(|i| {
                let x = x0 + (i as f64 + 0.5) * dx;
                let h = (r * r - x * x).max(0.0).sqrt();
                (y1.min(h) - y0.max(-h)).max(0.0) * dx
            })
            .sum()
    }

    /// The closed-form case: a uniformly lit disk imaged 1:1 by a thin lens. Every bin of the
    /// map holds the analytic irradiance × its overlap with the image disk (χ² with each bin's
    /// batch standard error, over the bins at least half inside the image, within 5 standard
    /// deviations of its degrees of freedom; the emission is stratified, so the binomial
    /// variance of a count would overstate the noise), the total is the power through the stop
    /// (within 4 binomial standard errors of a count of equal-weight rays, an upper bound on the
    /// stratified error), and no light lands farther than 10 µm
    /// beyond the image's edge (the lens's transverse spherical aberration at NA 0.0125 is
    /// h·LSA/s' = 1.75 µm, LSA = h²n²/(8f(n−1)²) for a symmetric lens at unit magnification).
    #[test]
    fn a_uniformly_lit_disk_images_to_its_analytic_irradiance() {
        let (bench, r_img, through) = imaged_disk();
        let o = TraceOptions::new(400_000, 5);
        let (t, maps) = trace_with_maps(&bench, &o, DEFAULT_BINS).unwrap();
        let n_el = bench.elements().len();
        let traced = t.ledger[COMMON][n_el + crate::trace::tally::SLOT_EMITTED];
        // Every ray starts with the same weight: the cone's power over the rays.
        let w0 = traced / o.rays as f64;
        // The power into the stop: the lamp's 2 W times the view factor (the traced cone holds
        // all of it: the stop subtends 0.72° of the cone's 1°).
        let expected_total = 2.0 * through;
        let e0 = expected_total / (std::f64::consts::PI * r_img * r_img);
        let bins = maps.bins;
        let w = &maps.windows[0];
        let step = 2.0 * w.half_width_m / bins as f64;
        let (mut chi2, mut dof, mut outside) = (0.0, 0usize, 0.0);
        for row in 0..bins {
            for col in 0..bins {
                let (x, y) = w.bin_centre(bins, row, col);
                let (x0, y0) = (x - 0.5 * step, y - 0.5 * step);
                let got = maps.power_w[index(bins, 0, 2, 0, row * bins + col)]
                    + maps.power_w[index(bins, 0, 2, 1, row * bins + col)];
                let nearest = (x.abs() - 0.5 * step)
                    .max(0.0)
                    .hypot((y.abs() - 0.5 * step).max(0.0));
                if nearest > r_img + 10e-6 {
                    outside += got;
                    continue;
                }
                let mu = e0 * overlap(x0, x0 + step, y0, y0 + step, r_img);
                // Bins at least half inside the image: their batch standard error is well
                // determined (~250 rays each); the thin slivers at the edge are left to the
                // total and to the zero outside.
                if mu >= 0.5 * e0 * step * step {
                    let k = index(bins, 0, 2, 0, row * bins + col);
                    let se = maps.stderr_w(k);
                    chi2 += ((got - mu) / se).powi(2);
                    dof += 1;
                }
            }
        }
        let dof_f = dof as f64;
        assert!(dof > 700, "{dof} bins inside the image");
        assert!(
            (chi2 - dof_f).abs() < 5.0 * (2.0 * dof_f).sqrt(),
            "χ² {chi2:.1} over {dof} bins"
        );
        assert_eq!(outside, 0.0, "light beyond the image's edge");
        let st = maps.stats(0, 2);
        let se = (expected_total * w0).sqrt();
        assert!(
            (st.active_w - expected_total).abs() < 4.0 * se,
            "{} W on the diode against {expected_total} ± {se}",
            st.active_w
        );
        assert_eq!(st.plate_w, 0.0);
        assert!(st.centroid_m[0].abs() < 4.0 * r_img / (st.active_w / w0).sqrt());
        // A uniform disk's RMS radius is r/√2; binning at the bin centres adds step²/6 to its
        // square (0.13 % of the radius here) and the noise is ~0.2 %.
        assert!((st.rms_radius_m - r_img / 2f64.sqrt()).abs() < 0.01 * r_img);
    }
}
