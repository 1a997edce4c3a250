//! The walk of one lamp ray (and its DMD branches) through the bench.
//!
//! Physics per interaction (f64 throughout):
//! - interfaces: Fresnel (or coating) reflectance R for unpolarised light, refraction by Snell's
//!   law with the glass's dispersion at the ray's wavelength. With the default
//!   [`Sampling::Split`] the path refracts carrying w·(1 − R), and the reflected part is
//!   followed as a path of its own with probability R at weight w (`cross_interface`); with the
//!   analogue tracer (`Sampling::Independent`, `Stratified`) the ray reflects with probability R
//!   and refracts otherwise, its weight unchanged. Either way ghosts and stray light are traced
//!   with the right expectation.
//! - absorption (ND glass bulk, mirror and DMD aluminium 1 − R, chrome 1 − R − T): the weight
//!   is multiplied by the surviving fraction and the absorbed power is booked to the element.
//!   The one exception is chart chrome, where the absorption is drawn (see `chrome_event`) but no
//!   ray ever gains weight: paths end by absorption, escape, detection or the interaction cap.
//!   The ledger balances exactly, ray by ray: with the analogue tracer as it stands, with
//!   `Split` once the weight its followed reflections add or drop (`SLOT_SAMPLED`, zero in
//!   expectation) is counted.
//! - black surfaces (lens rims, mount lips, meshes, DMD gaps, housings): the ray ends and its
//!   power is booked to the element.
//! - photodiodes: the ray ends; its power is "detected" and its photocurrent w·ℜ(λ) is tallied.
//! - chart: where the mask is clear, a bare glass interface; on chrome (reflectance R_c,
//!   transmittance T_c = 10^−OD) the ray reflects, is transmitted (refracted into the substrate)
//!   or is absorbed, the absorption sampled rather than weighted (`chrome_event`). Image masks
//!   with grey levels choose clear or chrome with the pixel's clear fraction.
//! - geometric optics, except at the DMD with the bench's diffractive model: there a ray that
//!   meets a mirror front leaves in one diffraction order drawn from the order efficiencies
//!   (`optics::diffraction`, docs/dmd_diffraction.md); an evanescent draw is absorbed by the
//!   aluminium. With the default geometric model the mirrors reflect specularly.
//!
//! The nearest hit of every segment comes from the bench's BVH (`optics::bench::Accel`), checked
//! against brute force in the tests below.
//!
//! The DMD: a path that has not met the pattern area yet and crosses the array plane inside it
//! (downward) is split into two copies of the same weight, one per mirror state (`BRANCH_PLUS`,
//! `BRANCH_MINUS`), both attributed to the unit j under the crossing point (its footprint). Each
//! copy then meets the actual tilted facets of its state; the power that lands on pattern
//! mirrors is x_j (half from each copy, since the two states' facets differ at the edges), and
//! the power that falls into the gaps is absorbed there. On any later DMD interaction the copy
//! sees every pattern mirror in its own state (the world "all units in
//! state s"): exact for the uniform patterns and a second-order error otherwise, since light
//! returning to the array (via window or chart reflections, ~1 %) would meet a mix of states.
//! Mirrors outside the pattern area are always in the bench's outside state; for an unsplit path
//! the pattern mirrors adjacent to its crossing cell (only rays within ~2 µm of the pattern
//! border) are also taken in the outside state. What the array does to a ray (the facets of each
//! state, reflection, the gaps) is `optics::dmd::Dmd::interact`; `meet_dmd` here splits the path,
//! books x_j and the absorbed power.

use std::cell::Cell;

use glam::DVec3;

use crate::optics::Arm;
use crate::optics::bench::{Bench, Interaction, Target};
use crate::optics::dmd::{DmdOutcome, MirrorState, PatternStates};
use crate::optics::fresnel::reflect;
pub use crate::optics::geometry::SURFACE_OFFSET;

use super::strata::{BatchStrata, EMISSION_DIMS, EmissionPoints, PathRng, STREAMS, Sampling};

use super::tally::{
    BatchTally, COMMON, SLOT_EMITTED, SLOT_ESCAPED, SLOT_PATH_CAP, branch, branch_state,
    slot_detected,
};

/// How the pattern area is set during a trace.
#[derive(Debug, Clone, Copy)]
pub enum PatternMode<'a> {
    /// Split at the pattern area and follow both states (transport maps).
    Branch,
    /// A fixed pattern: unit j in state + when `pattern[j]`, − otherwise; no splitting.
    Fixed(&'a [bool]),
}

#[derive(Debug, Clone, Copy)]
struct Path {
    o: DVec3,
    d: DVec3,
    w: f64,
    world: usize,
    unit: usize,
    interactions: u32,
    arrived: bool,
    /// Set on arrival: the next mirror hit books the incident power to x of `unit`.
    x_pending: bool,
    /// The object pixels the path has met on the chart face, as the key a recorder that
    /// tracks an object grid gave at the last meeting ([`NO_PIXEL`] otherwise or before the
    /// chart).
    pixel: u32,
    /// How many times the path has met a chart face (reflections included).
    chart_hits: u16,
    /// The stream a path pushed on the stack starts when it is popped ([`RayKey::stream`]'s
    /// part): the − copy of a split starts its branch's stream, a reflected path of
    /// [`Sampling::Split`] one of its own (`STREAM_SPAWNED` + its ordinal in the ray), so that no
    /// path's draws depend on how many another path took (common random numbers).
    fresh_stream: Option<u64>,
}

/// `Path::pixel` of a path that has not met the tracked chart (or of an untracked trace).
pub const NO_PIXEL: u32 = u32::MAX;

/// What a recorder says about a path meeting a chart face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ChartCrossing {
    /// Not tracked: the chart's own mask decides, as in an ordinary trace.
    Untracked,
    /// Inside the object grid: the path's new key (the pixel, row-major, at a first meeting;
    /// the recorder's key for the pixels met so far after that), given back at the next
    /// meeting and in every detection and incidence.
    Pixel(u32),
    /// Outside the object grid, which is opaque and black: the path is absorbed.
    Outside,
}

/// Traces `rays` lamp rays of batch `batch`: the batch's Latin hypercube draws from
/// `rng::stream(seed, batch)`, and each ray's interactions from streams of its own (see
/// [`RayKey`]). `inv_rays` is 1/N for the whole trace: each ray carries 1/N of the sampled power.
pub fn run_batch(
    bench: &Bench,
    mode: PatternMode,
    sampling: Sampling,
    seed: u64,
    batch: u64,
    rays: u64,
    inv_rays: f64,
) -> BatchTally {
    run_batch_sampled(bench, mode, sampling, seed, batch, rays, inv_rays, &mut ())
}

/// [`run_batch`] with a [`Recorder`] that sees every path segment and the end of every ray (the
/// ray fan of `trace::fan`). `run_batch` passes `()`, whose empty inlined methods make this the
/// same machine code as a loop without the hooks.
///
/// Recorded traces (ray fans, object kernels, the spectral collection) follow the analogue
/// tracer, [`Sampling::Independent`]: a drawing shows one path per choice, and an object
/// kernel's identity with a direct trace, path by path, is stated and tested for it
/// (`trace::kernel`). Their estimates are unbiased either way.
pub(super) fn run_batch_recorded<R: Recorder>(
    bench: &Bench,
    mode: PatternMode,
    seed: u64,
    batch: u64,
    rays: u64,
    inv_rays: f64,
    rec: &mut R,
) -> BatchTally {
    run_batch_sampled(
        bench,
        mode,
        Sampling::Independent,
        seed,
        batch,
        rays,
        inv_rays,
        rec,
    )
}

/// [`run_batch_recorded`] with the choice of [`Sampling`].
#[allow(clippy::too_many_arguments)]
pub(super) fn run_batch_sampled<R: Recorder>(
    bench: &Bench,
    mode: PatternMode,
    sampling: Sampling,
    seed: u64,
    batch: u64,
    rays: u64,
    inv_rays: f64,
    rec: &mut R,
) -> BatchTally {
    let mut rng = crate::rng::stream(seed, batch);
    let mut tally = BatchTally::new(bench.units(), bench.elements().len());
    let mut stack = Vec::with_capacity(8);
    let mut index = vec![1.0; bench.media().len()];
    let n = rays as usize;
    // The emission's five coordinates and the wavelength's two, for every ray of the batch from
    // one low-discrepancy design: a scrambled Sobol' sequence with `Sampling::Split`, a Latin
    // hypercube (McKay, Beckman & Conover 1979) with the analogue samplings (strata.rs). Every ray
    // is still uniformly distributed, so every tally stays unbiased; the batch's rays cover the
    // filament, the directions and the spectrum evenly, which removes most of the spectral and
    // geometric noise from the per-batch sums. Batches remain independent, so batch means give
    // the errors.
    let points = EmissionPoints::new(sampling, n, &mut rng);
    let strata = BatchStrata::new(sampling, seed, batch, n);
    for i in 0..n {
        let u = points.point(i, &mut rng);
        let key = RayKey {
            seed,
            index: batch * crate::trace::RAYS_PER_BATCH + i as u64,
            strata: &strata,
            slot: i,
        };
        let mut ray_rng = key.stream(STREAM_COMMON);
        trace_ray(
            bench,
            mode,
            inv_rays,
            u,
            key,
            sampling,
            &mut ray_rng,
            &mut tally,
            &mut stack,
            &mut index,
            rec,
        );
        rec.ray_done(&tally);
    }
    tally
}

/// Sees what a trace does, for drawings: `segment(o, d, t)` for every straight piece of a path
/// (start, unit direction, length; t = ∞ when the ray leaves the bench), `ray_done` after every
/// lamp ray with the batch's tally so far.
///
/// The object-kernel trace (`trace::kernel`) also uses `chart_crossing` (where a path meets a
/// chart face, in the face's local coordinates, with the path's key so far), `detected` (every
/// photocurrent tallied, with the path's mirror-state world, unit, pixel key and number of chart
/// meetings) and
/// `incident` (every booking of x_j); the spectral collection (`trace::collection`) uses
/// `wavelength`. The defaults do nothing.
pub(super) trait Recorder {
    fn segment(&mut self, o: DVec3, d: DVec3, t: f64);
    fn ray_done(&mut self, tally: &BatchTally);
    #[inline(always)]
    fn chart_crossing(
        &mut self,
        _chart: usize,
        _x_m: f64,
        _y_m: f64,
        _pixel: u32,
    ) -> ChartCrossing {
        ChartCrossing::Untracked
    }
    #[inline(always)]
    fn detected(&mut self, _hit: Detection) {}
    #[inline(always)]
    fn incident(&mut self, _unit: usize, _pixel: u32, _w: f64) {}
    /// The wavelength (m) of the lamp ray about to be traced.
    #[inline(always)]
    fn wavelength(&mut self, _wl: f64) {}
    /// The lamp ray's emission draws (filament x, y; strategy; direction a, b; wavelength bin,
    /// offset) and its starting weight (W), before it is traced.
    #[inline(always)]
    fn emission(&mut self, _u: &[f64; EMISSION_DIMS], _w: f64) {}
    /// A path of power `w` (W) in ledger world `world` absorbed by a black surface of
    /// `element` at `hit` (the irradiance maps of `trace::irradiance` see the diodes' front
    /// plates this way).
    #[inline(always)]
    fn absorbed(&mut self, _world: usize, _element: usize, _hit: DVec3, _w: f64) {}
    /// A path of power `w` (W) in ledger world `world` meeting surface `surface` at `hit`,
    /// before anything happens there (the irradiance maps at named surfaces see the power
    /// crossing a surface this way).
    #[inline(always)]
    fn met(&mut self, _world: usize, _surface: usize, _hit: DVec3, _w: f64) {}
}

/// One photocurrent tallied by a path, for [`Recorder::detected`].
#[derive(Debug, Clone, Copy)]
pub(super) struct Detection {
    /// [`COMMON`] (never met the pattern area), or the branch of a mirror state
    /// ([`super::tally::BRANCH_PLUS`], [`super::tally::BRANCH_MINUS`]).
    pub world: usize,
    pub unit: usize,
    pub pixel: u32,
    pub chart_hits: u16,
    /// The arm whose photodiode the path reached.
    pub detector: Arm,
    pub current_a: f64,
    /// The power the path brought to the diode (W).
    pub power_w: f64,
    /// Where it met the diode (m, bench frame).
    pub hit: DVec3,
}

/// The recorder of an ordinary trace: records nothing.
impl Recorder for () {
    #[inline(always)]
    fn segment(&mut self, _: DVec3, _: DVec3, _: f64) {}
    #[inline(always)]
    fn ray_done(&mut self, _: &BatchTally) {}
}

/// Identifies one lamp ray of a trace, for its random streams.
///
/// Every ray draws its interactions from streams of its own, one for the path before the DMD
/// and one for each mirror-state branch after it, keyed by (seed, ray index, part). A change to
/// one part of the bench then changes the random numbers only of the rays, and of the branches,
/// whose paths it changes: two benches that differ a little are traced with common random
/// numbers ray by ray, so their difference is resolved far better than their values
/// (crate::transport::metrics). A single stream per batch would let one ray that takes another
/// path shift the draws of every later ray of its batch.
///
/// With [`Sampling::Stratified`] the first draws of each stream come from the batch's Latin
/// hypercube (`strata.rs`); they too depend on (seed, ray index) alone.
#[derive(Debug, Clone, Copy)]
struct RayKey<'a> {
    seed: u64,
    index: u64,
    /// The batch's stratified prefixes and the ray's place in its batch.
    strata: &'a BatchStrata,
    slot: usize,
}

/// The streams of a ray: before the DMD split, then the + and − branches.
const STREAM_COMMON: u64 = 0;
const STREAM_PLUS: u64 = 1;
const STREAM_MINUS: u64 = 2;
/// The first stream of the reflected paths of [`Sampling::Split`] (above every split's).
const STREAM_SPAWNED: u64 = 1 << 32;

impl RayKey<'_> {
    /// The uniform in [0, 1) that draws the diffraction order of the DMD hit of branch `world` at
    /// interaction `interactions` (SplitMix64 finalisations of the key: deterministic and
    /// independent of the threads, and of every stream of the ray).
    fn order_uniform(self, world: usize, interactions: u32) -> f64 {
        use crate::rng::mix64;
        let h = mix64(
            mix64(mix64(self.seed ^ 0x4F52_4445_5253_0000) ^ self.index)
                ^ ((world as u64) << 32 | interactions as u64),
        );
        (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Stream `part` of the ray: `STREAM_COMMON`, `STREAM_PLUS`, `STREAM_MINUS` for its first
    /// split at the pattern area, the same plus `STREAMS`·s for its split s (a reflected path of
    /// [`Sampling::Split`] may reach the pattern area after the first split), and
    /// `STREAM_SPAWNED` + n for its n-th reflected path.
    fn stream(self, part: u64) -> PathRng {
        let tail = crate::rng::stream(
            crate::rng::mix64(self.seed ^ crate::rng::mix64(0x5241_5953_0000_0000 + part)),
            self.index,
        );
        let prefix = if part < STREAMS as u64 {
            self.strata.prefix(self.slot, part as usize)
        } else {
            &[]
        };
        PathRng::new(prefix, tail)
    }
}

/// Traces one lamp ray with all its branches, adding to `tally`. `index` is scratch space for
/// the refractive index of every medium at the ray's wavelength (computed once per ray).
#[allow(clippy::too_many_arguments)]
fn trace_ray<R: Recorder>(
    bench: &Bench,
    mode: PatternMode,
    inv_rays: f64,
    u: [f64; EMISSION_DIMS],
    key: RayKey,
    sampling: Sampling,
    rng: &mut PathRng,
    tally: &mut BatchTally,
    stack: &mut Vec<Path>,
    index: &mut [f64],
    rec: &mut R,
) {
    let lamp = &bench.lamp();
    let (wl, spectral) = bench.sampler().sample(u[5], u[6]);
    rec.wavelength(wl);
    let e = lamp.sample([u[0], u[1], u[2], u[3], u[4]], wl);
    let w = lamp.band_power_w * e.factor * spectral * inv_rays;
    rec.emission(&u, w);
    let n_el = bench.elements().len();
    tally.ledger[COMMON][n_el + SLOT_EMITTED] += w;
    tally.rays += 1;
    if w <= 0.0 {
        return;
    }
    for (n, m) in index.iter_mut().zip(bench.media()) {
        *n = m.glass.index(wl);
    }
    stack.clear();
    stack.push(Path {
        o: e.origin,
        d: e.direction,
        w,
        world: COMMON,
        unit: 0,
        interactions: 0,
        arrived: false,
        x_pending: false,
        pixel: NO_PIXEL,
        chart_hits: 0,
        fresh_stream: None,
    });
    let ctx = Walk {
        bench,
        mode,
        wl,
        index,
        split_reflections: sampling == Sampling::Split,
        splits: Cell::new(0),
        spawned: Cell::new(0),
        arrived: Cell::new(false),
    };
    while let Some(mut p) = stack.pop() {
        if let Some(part) = p.fresh_stream.take() {
            // The − branch of a split (pushed by `meet_dmd`), or a reflected path of
            // `Sampling::Split`, draws from a stream of its own.
            *rng = key.stream(part);
        }
        walk(&ctx, p, key, rng, tally, stack, rec);
    }
}

#[inline]
fn book(tally: &mut BatchTally, world: usize, slot: usize, w: f64) {
    tally.ledger[world][slot] += w;
}

/// What every path of one lamp ray walks through: the bench, how its pattern area is set, the
/// ray's wavelength and the refractive index of every medium at that wavelength.
#[derive(Clone)]
struct Walk<'a> {
    bench: &'a Bench,
    mode: PatternMode<'a>,
    wl: f64,
    index: &'a [f64],
    /// [`Sampling::Split`]: interfaces pass the refracted part on as weight (see
    /// [`cross_interface`]).
    split_reflections: bool,
    /// Splits of the ray at the pattern area so far.
    splits: Cell<u64>,
    /// Reflected paths of [`Sampling::Split`] followed so far.
    spawned: Cell<u64>,
    /// Whether any path of the ray has reached the pattern area.
    arrived: Cell<bool>,
}

/// Whether a path goes on after an interaction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    Go,
    End,
}

/// Walks one path (the lamp ray or one of its branches) to its end (escape, absorption,
/// detection or the interaction cap): finds each next hit, hands it to the physics of the target
/// and books what ends the path.
fn walk<R: Recorder>(
    ctx: &Walk,
    mut p: Path,
    key: RayKey,
    rng: &mut PathRng,
    tally: &mut BatchTally,
    stack: &mut Vec<Path>,
    rec: &mut R,
) {
    let bench = ctx.bench;
    let n_el = bench.elements().len();
    loop {
        if p.interactions >= bench.max_interactions() {
            book(tally, p.world, n_el + SLOT_PATH_CAP, p.w);
            return;
        }
        p.interactions += 1;
        let (t, target) = bench.nearest(p.o, p.d);
        rec.segment(p.o, p.d, t);
        let flow = match target {
            None => {
                book(tally, p.world, n_el + SLOT_ESCAPED, p.w);
                Flow::End
            }
            Some(Target::Mesh(k)) => {
                book(tally, p.world, bench.meshes()[k].1, p.w);
                Flow::End
            }
            Some(Target::Surface(i, n)) => surface(ctx, &mut p, t, i, n, rng, tally, stack, rec),
            Some(Target::Dmd) => meet_dmd(ctx, &mut p, key, rng, tally, stack, rec),
        };
        if flow == Flow::End {
            return;
        }
    }
}

/// The sides of an interface that a ray crosses: the medium it comes from and the one beyond,
/// the normal facing the ray and the cosine of incidence.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    m_in: usize,
    m_out: usize,
    nn: DVec3,
    cos_i: f64,
}

impl Crossing {
    /// For an interface with media `front` (the side `n` points to) and `back`, met with
    /// cos_signed = −d·n.
    #[inline]
    fn new(front: usize, back: usize, n: DVec3, cos_signed: f64) -> Crossing {
        let (m_in, m_out, nn, cos_i) = if cos_signed >= 0.0 {
            (front, back, n, cos_signed)
        } else {
            (back, front, -n, -cos_signed)
        };
        Crossing {
            m_in,
            m_out,
            nn,
            cos_i,
        }
    }
}

/// A path meeting surface `i` (normal `n`) after a segment of length `t`.
#[allow(clippy::too_many_arguments)]
fn surface<R: Recorder>(
    ctx: &Walk,
    p: &mut Path,
    t: f64,
    i: usize,
    n: DVec3,
    rng: &mut PathRng,
    tally: &mut BatchTally,
    stack: &mut Vec<Path>,
    rec: &mut R,
) -> Flow {
    let (bench, wl) = (ctx.bench, ctx.wl);
    let s = &bench.surfaces()[i];
    let hit = p.o + t * p.d;
    let cos_signed = -p.d.dot(n);
    rec.met(p.world, i, hit, p.w);
    if s.clear.is_some_and(|c| c.blocks(hit)) {
        book(tally, p.world, s.element, p.w);
        return Flow::End;
    }
    match &s.interaction {
        Interaction::Absorber => {
            rec.absorbed(p.world, s.element, hit, p.w);
            book(tally, p.world, s.element, p.w);
            Flow::End
        }
        Interaction::Mirror { reflectance } => {
            if cos_signed <= 0.0 {
                book(tally, p.world, s.element, p.w);
                return Flow::End;
            }
            let r = reflectance.at(wl).clamp(0.0, 1.0);
            let kept = p.w * r;
            book(tally, p.world, s.element, p.w - kept);
            p.w = kept;
            p.d = reflect(p.d, n);
            p.o = hit + SURFACE_OFFSET * n;
            Flow::Go
        }
        Interaction::Detector { arm } => {
            if cos_signed <= 0.0 {
                book(tally, p.world, s.element, p.w);
            } else {
                detect(ctx, p, *arm, hit, tally, rec);
            }
            Flow::End
        }
        Interaction::Interface {
            front,
            back,
            coating,
        } => {
            let x = Crossing::new(*front, *back, n, cos_signed);
            attenuate(bench, x.m_in, t, wl, p, tally);
            let (n1, n2) = (ctx.index[x.m_in], ctx.index[x.m_out]);
            let r = coating.reflectance(n1, n2, x.cos_i, wl);
            cross_interface(ctx, p, hit, x.nn, (n1, n2, r), rng, tally, stack);
            Flow::Go
        }
        Interaction::Chart { chart, front, back } => {
            let x = Crossing::new(*front, *back, n, cos_signed);
            attenuate(bench, x.m_in, t, wl, p, tally);
            cross_chart(ctx, p, hit, x, s.element, *chart, rng, tally, stack, rec)
        }
    }
}

/// A path reaching the photodiode of `arm`: its photocurrent w·ℜ(λ) is tallied (to B± before
/// the pattern area, to T[arm][state][unit] in a branch) and its power booked as detected.
fn detect<R: Recorder>(
    ctx: &Walk,
    p: &Path,
    arm: Arm,
    hit: DVec3,
    tally: &mut BatchTally,
    rec: &mut R,
) {
    let det = &ctx.bench.detectors()[arm];
    let current = p.w * det.responsivity.at(ctx.wl);
    rec.detected(Detection {
        world: p.world,
        unit: p.unit,
        pixel: p.pixel,
        chart_hits: p.chart_hits,
        detector: arm,
        current_a: current,
        power_w: p.w,
        hit,
    });
    match branch_state(p.world) {
        None => tally.b[arm] += current,
        Some(state) => {
            let units = tally.x.len();
            tally.t[BatchTally::t_index(units, arm, state, p.unit)] += current;
        }
    }
    let n_el = ctx.bench.elements().len();
    book(tally, p.world, n_el + slot_detected(arm), p.w);
}

/// A path crossing the face of chart `chart` at `hit` (after the bulk absorption of the
/// segment): clear glass or chrome by the mask, or the recorder's object grid.
#[allow(clippy::too_many_arguments)]
fn cross_chart<R: Recorder>(
    ctx: &Walk,
    p: &mut Path,
    hit: DVec3,
    x: Crossing,
    element: usize,
    chart: usize,
    rng: &mut PathRng,
    tally: &mut BatchTally,
    stack: &mut Vec<Path>,
    rec: &mut R,
) -> Flow {
    let plate = &ctx.bench.charts()[chart];
    let local = plate.frame.to_local(hit);
    p.chart_hits = p.chart_hits.saturating_add(1);
    match rec.chart_crossing(chart, local.x, local.y, p.pixel) {
        ChartCrossing::Untracked => {}
        // The recorder names the path's meetings so far (its pixel, or for a path that meets
        // the chart again, a key of its own for the list of pixels met).
        ChartCrossing::Pixel(i) => p.pixel = i,
        ChartCrossing::Outside => {
            book(tally, p.world, element, p.w);
            return Flow::End;
        }
    }
    let clear = plate.mask.clear_fraction(local.x, local.y);
    let (n1, n2) = (ctx.index[x.m_in], ctx.index[x.m_out]);
    if clear >= 1.0 || (clear > 0.0 && rng.uniform() < clear) {
        let r = crate::optics::fresnel::reflectance(n1, n2, x.cos_i);
        cross_interface(ctx, p, hit, x.nn, (n1, n2, r), rng, tally, stack);
        return Flow::Go;
    }
    // Chrome: reflect R_c, transmit T_c = 10^−OD, absorb the rest, with the event drawn (see
    // `chrome_event`).
    let wl = ctx.wl;
    let rc = plate.chrome_reflectance.at(wl).clamp(0.0, 1.0);
    let tc = 10f64.powf(-plate.chrome_od.at(wl)).min(1.0 - rc);
    let (event, kept) = chrome_event(rc, tc, rng.uniform());
    let kept = p.w * kept;
    book(tally, p.world, element, p.w - kept);
    p.w = kept;
    match event {
        ChromeEvent::Absorbed => return Flow::End,
        ChromeEvent::Reflected => {
            p.d = reflect(p.d, x.nn);
            p.o = hit + SURFACE_OFFSET * x.nn;
        }
        // Into the substrate (or out of it), as at clear glass but without the bare-glass
        // Fresnel split: R_c and T_c are the chrome film's own reflectance and transmittance.
        ChromeEvent::Transmitted => scatter(p, hit, x.nn, n1, n2, 0.0, rng),
    }
    Flow::Go
}

/// A path reaching the DMD: split at its first crossing of the pattern area (see the module
/// docs), x_j booked on its first mirror hit after that, and what the array does to it
/// (`Dmd::interact`, the one place of the DMD's physics) applied and booked.
fn meet_dmd<R: Recorder>(
    ctx: &Walk,
    p: &mut Path,
    key: RayKey,
    rng: &mut PathRng,
    tally: &mut BatchTally,
    stack: &mut Vec<Path>,
    rec: &mut R,
) -> Flow {
    let setup = ctx.bench.dmd().expect("DMD target implies a DMD");
    let dmd = &setup.dmd;
    // Split an unsplit path at its first crossing of the pattern area.
    if !p.arrived
        && let Some(j) = dmd.unit_crossed(p.o, p.d)
    {
        p.arrived = true;
        p.x_pending = true;
        p.unit = j;
        // Lamp rays that reach the pattern area, once per ray (a reflected path of
        // `Sampling::Split` may arrive as well).
        if !ctx.arrived.replace(true) {
            tally.arrivals += 1;
        }
        if matches!(ctx.mode, PatternMode::Branch) && p.world == COMMON {
            let split = ctx.splits.get();
            ctx.splits.set(split + 1);
            let mut other = *p;
            other.world = branch(MirrorState::Minus);
            other.fresh_stream = Some(STREAM_MINUS + STREAMS as u64 * split);
            p.world = branch(MirrorState::Plus);
            // The minus copy is walked after this one finishes; each branch draws from its own
            // stream (see RayKey).
            other.interactions -= 1;
            stack.push(other);
            *rng = key.stream(STREAM_PLUS + STREAMS as u64 * split);
        }
    }
    // A branch sees every pattern mirror in its own state; an unsplit path (before the pattern
    // area, or only grazing its border) sees them in the outside state.
    let states = match ctx.mode {
        PatternMode::Fixed(bits) => PatternStates::Bits(bits),
        PatternMode::Branch => PatternStates::Uniform(branch_state(p.world).unwrap_or(dmd.outside)),
    };
    // The diffractive model's order draw: one uniform per mirror hit, hashed from the ray, its
    // branch and its interaction count rather than drawn from the path's stream, so that the
    // rest of the path sees the same random numbers under both models (common random numbers
    // for the comparison `trace` reports).
    let order_u = if dmd.diffraction().is_some() {
        key.order_uniform(p.world, p.interactions)
    } else {
        0.0
    };
    let outcome = dmd.interact(p.o, p.d, ctx.wl, states, order_u);
    if p.x_pending {
        // x_j: the power incident on pattern mirrors in unit j's footprint. The two branches see
        // slightly different facets (they differ only at the edges), so each books half of what
        // it meets: x_j is the mean over the two states.
        p.x_pending = false;
        if let DmdOutcome::Reflected { unit: Some(_), .. }
        | DmdOutcome::Evanescent { unit: Some(_) } = outcome
        {
            let share = if p.world == COMMON { 1.0 } else { 0.5 };
            tally.x[p.unit] += share * p.w;
            rec.incident(p.unit, p.pixel, share * p.w);
        }
    }
    match outcome {
        DmdOutcome::Reflected {
            origin,
            direction,
            reflectance,
            ..
        } => {
            let kept = p.w * reflectance;
            book(tally, p.world, setup.mirrors_element, p.w - kept);
            p.w = kept;
            p.d = direction;
            p.o = origin;
            Flow::Go
        }
        DmdOutcome::Evanescent { .. } => {
            // The drawn order carries no power away: the aluminium absorbs it.
            book(tally, p.world, setup.mirrors_element, p.w);
            Flow::End
        }
        DmdOutcome::Absorbed => {
            book(tally, p.world, setup.gaps_element, p.w);
            Flow::End
        }
        DmdOutcome::Behind => {
            book(tally, p.world, setup.package_element, p.w);
            Flow::End
        }
        DmdOutcome::Left { origin } => {
            p.o = origin;
            Flow::Go
        }
    }
}

mod interface;
use interface::{ChromeEvent, attenuate, chrome_event, cross_interface, scatter};

#[cfg(test)]
mod tests {
    use super::interface::CHROME_TRANSMIT_FLOOR;
    use super::*;
    use crate::rng::{StreamRng, uniform};

    /// Drawing the chrome's absorption keeps the expected reflected and transmitted power
    /// (midpoint rule over u: exact up to the grid's 1e-6 resolution) and never raises a ray's
    /// weight, for OD 3 chrome, a transparent "chrome", a black one and a mirror.
    #[test]
    fn chrome_event_is_unbiased_and_never_gains_weight() {
        for (rc, tc) in [(0.1, 1e-3), (0.0, 0.6), (0.05, 0.0), (0.9, 0.1), (0.0, 0.0)] {
            let n = 1_000_000;
            let (mut refl, mut trans, mut absorbed) = (0.0, 0.0, 0.0);
            for k in 0..n {
                let (event, kept) = chrome_event(rc, tc, (k as f64 + 0.5) / n as f64);
                assert!((0.0..=1.0).contains(&kept), "kept {kept} for ({rc}, {tc})");
                match event {
                    ChromeEvent::Reflected => refl += kept,
                    ChromeEvent::Transmitted => trans += kept,
                    ChromeEvent::Absorbed => absorbed += 1.0,
                }
            }
            let n = n as f64;
            assert!((refl / n - rc).abs() < 2e-6, "R {} vs {rc}", refl / n);
            assert!((trans / n - tc).abs() < 2e-6, "T {} vs {tc}", trans / n);
            if tc > 0.0 && tc < CHROME_TRANSMIT_FLOOR {
                // Most chrome hits end there: the point of drawing the absorption.
                assert!(absorbed / n > 1.0 - rc - CHROME_TRANSMIT_FLOOR - 1e-6);
            }
        }
    }

    /// Brute force over every primitive: the oracle for the BVH search.
    fn nearest_brute(bench: &Bench, o: DVec3, d: DVec3) -> (f64, Option<Target>) {
        let mut best = f64::INFINITY;
        let mut target = None;
        for (i, s) in bench.surfaces().iter().enumerate() {
            if let Some(h) = s.geometry.intersect(o, d, 0.0, best) {
                best = h.t;
                target = Some(Target::Surface(i, h.normal));
            }
        }
        for (k, (m, _)) in bench.meshes().iter().enumerate() {
            if let Some(t) = m.intersect(o, d, 0.0, best)
                && t < best
            {
                best = t;
                target = Some(Target::Mesh(k));
            }
        }
        if let Some(dmd) = &bench.dmd()
            && let Some(t) = dmd.dmd.slab_entry(o, d, 0.0)
            && t < best
        {
            best = t;
            target = Some(Target::Dmd);
        }
        (best, target)
    }

    /// The BVH search must find exactly the nearest primitive that brute force finds, for random
    /// rays and for rays leaving surfaces as path segments do (in both directions).
    #[test]
    fn bvh_search_matches_brute_force() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let mut rng = crate::rng::stream(99, 0);
        let mut mismatches = Vec::new();
        let u = |r: &mut StreamRng| uniform(r) * 2.0 - 1.0;
        for k in 0..200_000 {
            let mut o = DVec3::new(
                0.15 * u(&mut rng),
                0.15 * u(&mut rng),
                0.35 + 0.35 * u(&mut rng),
            );
            let mut d = DVec3::new(u(&mut rng), u(&mut rng), u(&mut rng)).normalize();
            if k % 2 == 1 {
                // Like a path segment: start 1 nm off a surface that the random ray meets.
                let (t, hit) = nearest_brute(&bench, o, d);
                if let Some(Target::Surface(_, n)) = hit {
                    let side = if uniform(&mut rng) < 0.5 { 1.0 } else { -1.0 };
                    o += t * d + side * SURFACE_OFFSET * n;
                    d = DVec3::new(u(&mut rng), u(&mut rng), u(&mut rng)).normalize();
                    if d.dot(n) * side < 0.0 {
                        d = -d;
                    }
                }
            }
            let (t1, a) = bench.nearest(o, d);
            let (t2, b) = nearest_brute(&bench, o, d);
            let same = match (&a, &b) {
                (None, None) => true,
                (Some(Target::Surface(i, _)), Some(Target::Surface(j, _))) => i == j,
                (Some(Target::Mesh(i)), Some(Target::Mesh(j))) => i == j,
                (Some(Target::Dmd), Some(Target::Dmd)) => true,
                _ => false,
            };
            if !same || (t1.is_finite() && (t1 - t2).abs() > 1e-12) {
                mismatches.push((o, d, t1, t2));
            }
        }
        assert!(
            mismatches.is_empty(),
            "{} mismatches, first {:?}",
            mismatches.len(),
            mismatches.first()
        );
    }
}
