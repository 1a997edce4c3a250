//! Ray fans for drawings: a few hundred lamp rays traced with the tracer's own physics
//! (`path.rs`, through its [`Recorder`] hook), each path's vertices and fate kept, and the
//! deterministic chief rays that place the bench's axes.
//!
//! **Mirror states.** The fan is traced in two halves, each with a fixed pattern: the first half
//! with every pattern unit in state + and the second with every unit in state −, so both arms
//! are lit over the whole pattern area (a random pattern would light both arms too, but each
//! with only half the field, which hides where each arm's beam runs). Mirrors outside the
//! pattern keep the bench's outside state, as in every trace. In fixed-pattern mode a path is
//! never split, so one lamp ray is one polyline.
//!
//! **Determinism.** Half h draws from `rng::stream(seed, h)`; the rays within a half form the
//! tracer's Latin hypercube over emission and wavelength. The same seed gives the same fan.

use glam::DVec3;

use crate::error::{Error, Result};
use crate::optics::bench::{Interaction, Target};
use crate::optics::dmd::{MirrorState, state_index};
use crate::optics::fresnel::{reflect, refract};
use crate::optics::{Arm, Bench};

use super::path::{PatternMode, Recorder, SURFACE_OFFSET, run_batch_recorded};
use super::tally::{
    BatchTally, COMMON, SLOT_DETECTED_MINUS, SLOT_DETECTED_PLUS, SLOT_ESCAPED, SLOT_PATH_CAP,
};

/// How far (m) a ray that leaves the bench is drawn past its last interaction: 50 mm, long
/// enough to show its direction at the scale of a bench (~0.1–1 m) without stretching the
/// drawing.
pub const ESCAPE_LENGTH_M: f64 = 0.05;

/// Default number of rays of a fan: enough to show every beam and the stray light around it
/// without hiding the outlines.
pub const DEFAULT_FAN_RAYS: usize = 400;

/// The design wavelength of the paraxial numbers and the chief rays: 850 nm, the centroid of the
/// photocurrent of a tungsten lamp on silicon photodiodes without ND filters (docs/bench-facts.md
/// §3.4; on the paper bench, whose ND filters pass the near infrared far more than the visible,
/// the centroid is about 947 nm, docs/dmd_diffraction.md). The paper bench's lenses are laid out
/// for N-BK7 at 850 nm, n = 1.50984.
pub const DESIGN_WAVELENGTH_M: f64 = 850e-9;

/// How a fan ray ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Fate {
    /// Reached photodiode + (arm +).
    DetectedPlus,
    /// Reached photodiode − (arm −).
    DetectedMinus,
    /// Absorbed by an element (black surfaces, chrome, mirror or DMD aluminium...).
    Absorbed,
    /// Left the bench without meeting anything more.
    Escaped,
    /// Abandoned at the bench's interaction cap.
    PathCap,
}

impl Fate {
    pub const ALL: [Fate; 5] = [
        Fate::DetectedPlus,
        Fate::DetectedMinus,
        Fate::Absorbed,
        Fate::Escaped,
        Fate::PathCap,
    ];

    /// A short key (`detected-plus`, ...), used as a CSS class and a JSON key.
    pub fn key(self) -> &'static str {
        match self {
            Fate::DetectedPlus => "detected-plus",
            Fate::DetectedMinus => "detected-minus",
            Fate::Absorbed => "absorbed",
            Fate::Escaped => "escaped",
            Fate::PathCap => "path-cap",
        }
    }

    /// The label of a legend.
    pub fn label(self) -> &'static str {
        match self {
            Fate::DetectedPlus => "detected +",
            Fate::DetectedMinus => "detected −",
            Fate::Absorbed => "absorbed",
            Fate::Escaped => "escaped",
            Fate::PathCap => "interaction cap",
        }
    }
}

/// One traced lamp ray: the vertices of its path (bench frame, m) and how it ended.
#[derive(Debug, Clone, PartialEq)]
pub struct FanRay {
    pub points: Vec<DVec3>,
    pub fate: Fate,
    /// The state every pattern unit was in while this ray was traced.
    pub pattern_state: MirrorState,
}

/// A traced ray fan.
#[derive(Debug, Clone, PartialEq)]
pub struct RayFan {
    pub rays: Vec<FanRay>,
    pub seed: u64,
}

impl RayFan {
    /// Number of rays of each fate, in [`Fate::ALL`] order.
    pub fn counts(&self) -> [usize; 5] {
        let mut c = [0; 5];
        for r in &self.rays {
            c[Fate::ALL.iter().position(|f| *f == r.fate).unwrap_or(0)] += 1;
        }
        c
    }
}

/// Collects the segments of each ray and reads its fate from the tally.
struct FanRecorder {
    n_elements: usize,
    state: MirrorState,
    points: Vec<DVec3>,
    last_end: Option<DVec3>,
    /// The terminal ledger slots (escaped, cap, detected +, detected −) after the previous ray.
    before: [f64; 4],
    rays: Vec<FanRay>,
}

impl FanRecorder {
    fn terminal(&self, tally: &BatchTally) -> [f64; 4] {
        let l = &tally.ledger[COMMON];
        let n = self.n_elements;
        [
            l[n + SLOT_ESCAPED],
            l[n + SLOT_PATH_CAP],
            l[n + SLOT_DETECTED_PLUS],
            l[n + SLOT_DETECTED_MINUS],
        ]
    }
}

impl Recorder for FanRecorder {
    fn segment(&mut self, o: DVec3, d: DVec3, t: f64) {
        self.points.push(o);
        let t = if t.is_finite() { t } else { ESCAPE_LENGTH_M };
        self.last_end = Some(o + t * d);
    }

    fn ray_done(&mut self, tally: &BatchTally) {
        // In fixed-pattern mode a ray is one unsplit path, so exactly one terminal slot grows
        // unless the ray was absorbed (every ray weight is > 0, ~1/N of the band power, far
        // above the rounding of the running sums).
        let now = self.terminal(tally);
        let grew = |k: usize| now[k] > self.before[k];
        let fate = if grew(2) {
            Fate::DetectedPlus
        } else if grew(3) {
            Fate::DetectedMinus
        } else if grew(0) {
            Fate::Escaped
        } else if grew(1) {
            Fate::PathCap
        } else {
            Fate::Absorbed
        };
        self.before = now;
        let mut points = std::mem::take(&mut self.points);
        if let Some(end) = self.last_end.take() {
            points.push(end);
        }
        // A ray emitted with zero weight (outside the lamp's spectrum) has no path to draw.
        if points.len() >= 2 {
            self.rays.push(FanRay {
                points,
                fate,
                pattern_state: self.state,
            });
        }
    }
}

/// Traces a fan of `rays` lamp rays through `bench` (see the module notes): the first half with
/// every pattern unit in state +, the rest in state −.
pub fn ray_fan(bench: &Bench, rays: usize, seed: u64) -> Result<RayFan> {
    if rays == 0 || rays > 1_000_000 {
        return Err(Error::field(
            "rays",
            format!("a ray fan needs 1 to 1000000 rays, got {rays}"),
        ));
    }
    let units = bench.units();
    let plus = vec![true; units];
    let minus = vec![false; units];
    let halves = [
        (MirrorState::Plus, &plus, rays.div_ceil(2)),
        (MirrorState::Minus, &minus, rays / 2),
    ];
    let mut out = Vec::with_capacity(rays);
    for (h, (state, bits, n)) in halves.into_iter().enumerate() {
        if n == 0 {
            continue;
        }
        let mut rec = FanRecorder {
            n_elements: bench.elements().len(),
            state,
            points: Vec::new(),
            last_end: None,
            before: [0.0; 4],
            rays: Vec::with_capacity(n),
        };
        run_batch_recorded(
            bench,
            PatternMode::Fixed(bits),
            seed,
            h as u64,
            n as u64,
            1.0 / rays as f64,
            &mut rec,
        );
        out.append(&mut rec.rays);
    }
    Ok(RayFan { rays: out, seed })
}

/// Where a chief ray ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ChiefEnd {
    /// On photodiode `index`.
    Detector(usize),
    /// On a black surface, a mesh, a DMD gap or outside a clear aperture of element `id`.
    Blocked(usize),
    /// Left the bench.
    Escaped,
    /// Stopped after the step limit.
    Steps,
}

/// A deterministic chief ray: its vertices, the element and the surface met at each vertex
/// after the first (`None` for the DMD; no surface for a mesh), the point and direction in which
/// it met the DMD (if it did) and where it ended.
#[derive(Debug, Clone, PartialEq)]
pub struct ChiefRay {
    pub points: Vec<DVec3>,
    pub elements: Vec<Option<usize>>,
    pub surfaces: Vec<Option<usize>>,
    pub dmd_arrival: Option<(DVec3, DVec3)>,
    pub end: ChiefEnd,
}

/// Follows one ray from `origin` along `dir` at wavelength `wl`, deterministically: refraction
/// at every interface (no Fresnel reflection; total internal reflection reflects), chart plates
/// as clear glass, mirrors reflect, and the DMD reflects about the nominal normal of mirrors in
/// `state` where the ray crosses the array plane (the mirror facets and gaps are ignored: this
/// is the axis of the beam, not a sample of it). Used to place the chief rays of the layout and
/// of `spibench check`.
pub fn chief_ray(
    bench: &Bench,
    origin: DVec3,
    dir: DVec3,
    wl: f64,
    state: MirrorState,
) -> ChiefRay {
    let mut o = origin;
    let mut d = dir.normalize();
    let mut ray = ChiefRay {
        points: vec![o],
        elements: Vec::new(),
        surfaces: Vec::new(),
        dmd_arrival: None,
        end: ChiefEnd::Steps,
    };
    for _ in 0..bench.max_interactions().min(400) {
        let (t, target) = bench.nearest(o, d);
        let Some(target) = target else {
            ray.points.push(o + ESCAPE_LENGTH_M * d);
            ray.end = ChiefEnd::Escaped;
            return ray;
        };
        match target {
            Target::Mesh(k) => {
                ray.points.push(o + t * d);
                ray.elements.push(Some(bench.meshes()[k].1));
                ray.surfaces.push(None);
                ray.end = ChiefEnd::Blocked(bench.meshes()[k].1);
                return ray;
            }
            Target::Surface(i, n) => {
                let s = &bench.surfaces()[i];
                let hit = o + t * d;
                ray.points.push(hit);
                ray.elements.push(Some(s.element));
                ray.surfaces.push(Some(i));
                let cos = -d.dot(n);
                if s.clear.is_some_and(|c| c.blocks(hit)) {
                    ray.end = ChiefEnd::Blocked(s.element);
                    return ray;
                }
                let media = match &s.interaction {
                    Interaction::Absorber => {
                        ray.end = ChiefEnd::Blocked(s.element);
                        return ray;
                    }
                    Interaction::Detector { arm } => {
                        ray.end = if cos > 0.0 {
                            ChiefEnd::Detector(arm.index())
                        } else {
                            ChiefEnd::Blocked(s.element)
                        };
                        return ray;
                    }
                    Interaction::Mirror { .. } => {
                        if cos <= 0.0 {
                            ray.end = ChiefEnd::Blocked(s.element);
                            return ray;
                        }
                        d = reflect(d, n);
                        o = hit + SURFACE_OFFSET * n;
                        continue;
                    }
                    Interaction::Interface { front, back, .. }
                    | Interaction::Chart { front, back, .. } => (*front, *back),
                };
                let (m_in, m_out, nn) = if cos >= 0.0 {
                    (media.0, media.1, n)
                } else {
                    (media.1, media.0, -n)
                };
                let (n1, n2) = (
                    bench.media()[m_in].glass.index(wl),
                    bench.media()[m_out].glass.index(wl),
                );
                match refract(d, nn, n1, n2) {
                    Some(r) => {
                        d = r;
                        o = hit - SURFACE_OFFSET * nn;
                    }
                    None => {
                        d = reflect(d, nn);
                        o = hit + SURFACE_OFFSET * nn;
                    }
                }
            }
            Target::Dmd => {
                let setup = bench.dmd().expect("DMD target implies a DMD");
                let dmd = &setup.dmd;
                let h = dmd.slab_half_height();
                if d.z > 0.0 && o.z < -h {
                    // From behind: the chip and its package block it (`Dmd::interact`).
                    ray.points.push(o + ((-h - o.z) / d.z) * d);
                    ray.elements.push(Some(setup.package_element));
                    ray.surfaces.push(None);
                    ray.end = ChiefEnd::Blocked(setup.package_element);
                    return ray;
                }
                let Some(q) = dmd.plane_crossing(o, d).filter(|q| {
                    let (hx, hy) = dmd.half_size();
                    q.x.abs() <= hx && q.y.abs() <= hy
                }) else {
                    // Through the slab without crossing the array: step past it.
                    let h = dmd.slab_half_height();
                    let t_exit = if d.z > 0.0 {
                        (h - o.z) / d.z
                    } else {
                        (-h - o.z) / d.z
                    };
                    o += (t_exit.max(t) + SURFACE_OFFSET) * d;
                    continue;
                };
                ray.points.push(q);
                ray.elements.push(None);
                ray.surfaces.push(None);
                ray.dmd_arrival = Some((q, d));
                d = reflect(d, dmd.normal(state));
                if d.z <= 0.0 {
                    ray.end = ChiefEnd::Blocked(bench.dmd().map_or(0, |s| s.gaps_element));
                    return ray;
                }
                // Leave the slab that holds the tilted mirrors.
                let h = dmd.slab_half_height();
                o = q + ((h - q.z) / d.z + SURFACE_OFFSET) * d;
            }
        }
    }
    ray
}

/// The centre of the DMD's pattern area (on the array plane), if the bench has a DMD.
pub fn pattern_centre(bench: &Bench) -> Option<DVec3> {
    let dmd = &bench.dmd()?.dmd;
    let p = dmd.pattern;
    let last_c = p.col0 + p.units_across * p.mirrors_per_unit - 1;
    let last_r = p.row0 + p.units_down * p.mirrors_per_unit - 1;
    Some(0.5 * (dmd.mirror_center(p.col0, p.row0) + dmd.mirror_center(last_c, last_r)))
}

/// The bench's axes at the DMD: the incoming chief ray (from the centre of the filament along
/// the lamp axis) and its reflections for mirrors in state + and −.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DmdAxes {
    /// Where the incoming chief ray meets the array plane.
    pub arrival: DVec3,
    /// Unit direction of the incoming chief ray.
    pub incoming: DVec3,
    /// Unit directions of the outgoing chief rays, [state +, state −].
    pub outgoing: [DVec3; 2],
    /// The centre of the pattern area.
    pub pattern_centre: DVec3,
}

/// Traces the incoming chief ray to the DMD and reflects it for both mirror states. Fails when
/// the bench has no DMD or the chief ray does not reach it.
pub fn dmd_axes(bench: &Bench, wl: f64) -> std::result::Result<DmdAxes, String> {
    let dmd = &bench
        .dmd()
        .ok_or_else(|| "the bench has no DMD".to_string())?
        .dmd;
    let lamp = &bench.lamp().frame;
    let chief = chief_ray(bench, lamp.origin, lamp.w, wl, MirrorState::Plus);
    let (arrival, incoming) = chief.dmd_arrival.ok_or_else(|| {
        "the chief ray from the filament centre along the lamp axis does not reach the DMD"
            .to_string()
    })?;
    Ok(DmdAxes {
        arrival,
        incoming,
        outgoing: [
            reflect(incoming, dmd.normal(MirrorState::Plus)),
            reflect(incoming, dmd.normal(MirrorState::Minus)),
        ],
        pattern_centre: pattern_centre(bench).unwrap_or(arrival),
    })
}

impl DmdAxes {
    /// The chief ray of arm k (0 = +, 1 = −, [`Arm::index`]) from the arrival point, started
    /// just above the slab that holds the tilted mirrors: the reflection by mirrors in the state
    /// that sends light into the arm.
    pub fn arm_chief_ray(&self, bench: &Bench, k: usize, wl: f64) -> ChiefRay {
        let state = Arm::from_index(k).state();
        self.arm_ray(bench, k, self.outgoing[state_index(state)], wl)
    }

    /// A ray of arm k leaving the arrival point along `d` (unit; the chief ray's direction
    /// turned, for an arm's angular acceptance), started as [`DmdAxes::arm_chief_ray`] is.
    pub fn arm_ray(&self, bench: &Bench, k: usize, d: DVec3, wl: f64) -> ChiefRay {
        let state = Arm::from_index(k).state();
        let h = bench.dmd().map_or(0.0, |s| s.dmd.slab_half_height());
        let start = self.arrival + ((h - self.arrival.z) / d.z.max(1e-9) + SURFACE_OFFSET) * d;
        let mut ray = chief_ray(bench, start, d, wl, state);
        ray.points[0] = self.arrival;
        ray
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn symmetric() -> Bench {
        crate::trace::testing::bench_with("tests/symmetric_arms.ron", &[])
    }

    /// The fan is deterministic, lights both arms, and each ray's fate agrees with where its
    /// path ends: a detected ray ends on the active area of its photodiode.
    #[test]
    fn fan_is_deterministic_and_fates_match_the_paths() {
        let bench = symmetric();
        let a = ray_fan(&bench, 300, 7).unwrap();
        let b = ray_fan(&bench, 300, 7).unwrap();
        assert_eq!(a, b);
        assert!(a.rays.len() <= 300 && a.rays.len() > 250);
        let c = a.counts();
        let detected = |f: Fate| c[Fate::ALL.iter().position(|g| *g == f).unwrap()];
        assert!(
            detected(Fate::DetectedPlus) > 0 && detected(Fate::DetectedMinus) > 0,
            "both arms detected: {c:?}"
        );
        for r in &a.rays {
            let end = *r.points.last().unwrap();
            if let Some(arm) = match r.fate {
                Fate::DetectedPlus => Some(Arm::Plus),
                Fate::DetectedMinus => Some(Arm::Minus),
                _ => None,
            } {
                let det = &bench.detectors()[arm];
                let l = det.frame.to_local(end);
                assert!(l.z.abs() < 1e-6, "{l:?}");
                assert!(l.x.hypot(l.y) <= det.radius * (1.0 + 1e-9));
            }
            // Detected + only with every unit in state + (the outside state of this bench
            // sends no light to a diode that the pattern area does not).
            if r.fate == Fate::DetectedPlus {
                assert_eq!(r.pattern_state, MirrorState::Plus);
            }
        }
        assert!(ray_fan(&bench, 0, 1).is_err());
    }

    /// The chief ray of the paper bench runs down the axis onto the pattern centre and leaves
    /// at 2 × 12° = 24° from the normal for either state, in the 45° plane of the hinge.
    #[test]
    fn paper_bench_axes() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let axes = dmd_axes(&bench, DESIGN_WAVELENGTH_M).unwrap();
        assert!(
            axes.arrival.truncate().length() < 0.2e-3,
            "{:?}",
            axes.arrival
        );
        assert!((axes.incoming - DVec3::NEG_Z).length() < 1e-3);
        for (k, phi) in [(0, -45f64), (1, 135f64)] {
            let o = axes.outgoing[k];
            assert!((o.z.acos().to_degrees() - 24.0).abs() < 0.1, "{o:?}");
            assert!((o.y.atan2(o.x).to_degrees() - phi).abs() < 0.5, "{o:?}");
        }
        // The + chief ray reaches photodiode + through its lens and fold mirror.
        let ray = axes.arm_chief_ray(&bench, 0, DESIGN_WAVELENGTH_M);
        assert_eq!(ray.end, ChiefEnd::Detector(0), "{ray:?}");
    }
}
