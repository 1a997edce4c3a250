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

    /// The standard error (W) of entry `k` of the branch sums ([`branch_index`]).
    pub fn branch_stderr_w(&self, k: usize) -> f64 {
        batch_stderr(self.batches, self.branch_w[k], self.branch_sum_sq[k])
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
        let se = |l: usize, i: usize| self.branch_stderr_w(branch_index(bins, d, b, l, i));
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

    /// The summary numbers of diode d in state s: the centroid and RMS radius of all the light
    /// mapped, active area and plate together.
    pub fn stats(&self, d: usize, s: usize) -> MapStats {
        let bins = self.bins;
        let n = bins * bins;
        let layer =
            |l: usize| -> f64 { (0..n).map(|i| self.power_w[index(bins, d, s, l, i)]).sum() };
        // The batch totals' error of a layer: from the per-bin sums it is not available, so
        // the quadrature sum of the bins' errors is given (bins are correlated only through
        // the batches they share).
        let active_se = (0..n)
            .map(|i| self.stderr_w(index(bins, d, s, 0, i)).powi(2))
            .sum::<f64>()
            .sqrt();
        let weight = |i: usize| {
            self.power_w[index(bins, d, s, 0, i)] + self.power_w[index(bins, d, s, 1, i)]
        };
        let layers = [layer(0), active_se, layer(1)];
        self.summarise(d, layers, weight, |i| self.bin_stderr_w(d, s, i))
    }

    /// The collected spot of diode d, branch b (0: every unit +, 1: every unit −): the
    /// summary numbers of the pattern light that reaches the active area, the light the diode
    /// turns into its signal. The centroid and RMS radius are those of the active-area layer
    /// of the branch map alone: neither the light on the housing's plate (with the diffractive
    /// DMD chiefly the orders the diode does not collect, several millimetres off) nor the
    /// pattern-independent light (no pattern moves it) enter them. `plate_w` and `spill` are
    /// the branch's plate light and [`IrradianceMaps::signal_spill`]'s share.
    pub fn collected(&self, d: usize, b: usize) -> MapStats {
        let bins = self.bins;
        let n = bins * bins;
        let k = |l: usize, i: usize| branch_index(bins, d, b, l, i);
        let layer = |l: usize| -> f64 { (0..n).map(|i| self.branch_w[k(l, i)]).sum() };
        let se = |i: usize| self.branch_stderr_w(k(0, i));
        let active_se = (0..n).map(|i| se(i).powi(2)).sum::<f64>().sqrt();
        let mut st = self.summarise(
            d,
            [layer(0), active_se, layer(1)],
            |i| self.branch_w[k(0, i)],
            se,
        );
        st.spill = self.signal_spill(d, b).0;
        st
    }

    /// The summary numbers of map d's light of per-bin power `weight` and error `se`, with
    /// [active power, its error, plate power]; the spill is plate ÷ (active + plate).
    fn summarise(
        &self,
        d: usize,
        [active, active_stderr_w, plate]: [f64; 3],
        weight: impl Fn(usize) -> f64,
        se: impl Fn(usize) -> f64,
    ) -> MapStats {
        let bins = self.bins;
        let n = bins * bins;
        let w = self.window(d);
        let total: f64 = (0..n).map(&weight).sum();
        let (mut cx, mut cy) = (0.0, 0.0);
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
            let se = se(i);
            vx += ((x - cx) * se).powi(2);
            vy += ((y - cy) * se).powi(2);
        }
        let centroid_stderr_m = if total > 0.0 {
            [vx.sqrt() / total, vy.sqrt() / total]
        } else {
            [0.0, 0.0]
        };
        let mapped = active + plate;
        MapStats {
            active_w: active,
            active_stderr_w,
            plate_w: plate,
            centroid_m: [cx, cy],
            centroid_stderr_m,
            rms_radius_m: if total > 0.0 {
                (r2 / total).sqrt()
            } else {
                0.0
            },
            spill: if mapped > 0.0 { plate / mapped } else { 0.0 },
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

/// A map's summary numbers (positions in the map's (u, v) axes from the active area's centre):
/// of a state's light ([`IrradianceMaps::stats`]) or of a branch's collected spot
/// ([`IrradianceMaps::collected`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapStats {
    /// Power on the active area (W): the ledger's detected power of the state (of the branch,
    /// for a collected spot).
    pub active_w: f64,
    pub active_stderr_w: f64,
    /// Power on the front plate around it (W).
    pub plate_w: f64,
    /// The centre of the light summarised (m): all the mapped light for a state, the light on
    /// the active area for a collected spot.
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
mod tests;
