//! The digital micromirror device as an analytic grid of tilted square mirrors.
//!
//! Frame: the bench frame itself. The array lies in z = 0 centred on the origin, +z is the array
//! normal, column index grows along +x and row index grows along −y (row 0 at the top, +y), so
//! per-unit maps are row-major images as seen from the front of the DMD.
//!
//! Each mirror is a square of side `side` = pitch·√fill centred on its cell, with edges along x
//! and y when flat, rotated by ±tilt about the hinge axis (the mirror diagonal by default,
//! docs/bench-facts.md §2.1). A ray reaching the array is tested against the facets of the 3×3 cells
//! around where it enters and leaves the slab |z| ≤ h (h = highest corner of a tilted mirror);
//! the tilted corners move by at most h·tan θ ≪ pitch sideways for incidence angles θ below ~70°,
//! which covers every ray of the bench (docs/rust-notes.md §4: this analytic grid agrees with a triangle
//! BVH of the mirrors on 99.985 % of rays, the rest within f32 rounding of an edge).

use std::sync::Arc;

use glam::{DMat3, DVec3};

use super::arm::Arm;
use super::diffraction::{Diffraction, Facet, Grating, Order, TableSize};
use super::fresnel::reflect;
use super::geometry::SURFACE_OFFSET;
use super::spectrum::Spectrum;

/// A mirror's state. Powered mirrors are only ever at ±tilt; `Flat` is the unpowered (parked)
/// position (docs/bench-facts.md §2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MirrorState {
    Plus,
    Minus,
    Flat,
}

impl MirrorState {
    /// The state of a unit that a pattern bit sets: + for a set bit, − otherwise.
    #[inline]
    pub const fn from_bit(bit: bool) -> MirrorState {
        if bit {
            MirrorState::Plus
        } else {
            MirrorState::Minus
        }
    }

    /// The arm this state sends light into (state + into arm +); `Flat` sends it into neither.
    #[inline]
    pub const fn arm(self) -> Option<Arm> {
        match self {
            MirrorState::Plus => Some(Arm::Plus),
            MirrorState::Minus => Some(Arm::Minus),
            MirrorState::Flat => None,
        }
    }
}

/// The block of mirrors that carries the pattern: `units_across` × `units_down` units of
/// `mirrors_per_unit` × `mirrors_per_unit` mirrors, starting at mirror (`col0`, `row0`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatternArea {
    pub col0: usize,
    pub row0: usize,
    pub units_across: usize,
    pub units_down: usize,
    pub mirrors_per_unit: usize,
}

impl PatternArea {
    pub fn units(&self) -> usize {
        self.units_across * self.units_down
    }

    /// The unit (row-major index) of mirror (col, row), or None outside the pattern area.
    #[inline]
    pub fn unit_of(&self, col: usize, row: usize) -> Option<usize> {
        let m = self.mirrors_per_unit;
        if col < self.col0 || row < self.row0 {
            return None;
        }
        let (uc, ur) = ((col - self.col0) / m, (row - self.row0) / m);
        if uc < self.units_across && ur < self.units_down {
            Some(ur * self.units_across + uc)
        } else {
            None
        }
    }
}

#[derive(Debug, Clone)]
pub struct Dmd {
    pub columns: usize,
    pub rows: usize,
    pub pitch: f64,
    /// Side of one mirror (m): pitch·√fill_factor.
    pub side: f64,
    /// Tilt angle (rad) and hinge axis (unit vector in the array plane).
    pub tilt: f64,
    pub hinge: DVec3,
    pub pattern: PatternArea,
    pub outside: MirrorState,
    pub reflectance: Spectrum,
    /// Rotation of a flat mirror into each state (index by `state_index`) and its normal.
    rot: [DMat3; 3],
    rot_t: [DMat3; 3],
    normal: [DVec3; 3],
    /// Highest |z| reached by a tilted mirror's corner.
    h: f64,
    /// The diffractive model (docs/dmd_diffraction.md), None for geometric reflection.
    diffraction: Option<Arc<Diffraction>>,
    x0: f64,
    y0: f64,
}

/// What a ray meets at the array.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DmdHit {
    /// The front of mirror (col, row) in `state`: hit distance and the mirror's normal.
    Mirror {
        t: f64,
        col: usize,
        row: usize,
        normal: DVec3,
    },
    /// The ray went down between mirrors (into the gaps or onto the back of a mirror): absorbed
    /// by the CMOS substrate and hinges. `t` is where it crossed z = 0.
    Gap { t: f64 },
}

/// The mirror states of the pattern area as one path sees them; mirrors outside the pattern area
/// are always in the array's `outside` state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PatternStates<'a> {
    /// Every pattern mirror in one state.
    Uniform(MirrorState),
    /// Unit j's mirrors in state + when `bits[j]`, − otherwise (row-major units).
    Bits(&'a [bool]),
}

/// What the array does to a ray that meets it ([`Dmd::interact`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DmdOutcome {
    /// Reflected by the front of a mirror: the ray leaves from `origin` (just off the facet)
    /// along `direction`, its weight multiplied by the aluminium's `reflectance` (the rest is
    /// absorbed by the mirrors). `unit`: the pattern unit the mirror belongs to, None for a
    /// mirror outside the pattern area.
    Reflected {
        origin: DVec3,
        direction: DVec3,
        reflectance: f64,
        unit: Option<usize>,
    },
    /// Diffractive model only: the mirror front was met but the drawn order is evanescent (or
    /// would leave below the facet), so no power leaves; the aluminium absorbs it all. `unit` as
    /// for `Reflected`.
    Evanescent { unit: Option<usize> },
    /// The ray went down between the mirrors (into the gaps or onto the back of a mirror): the
    /// CMOS substrate and hinges absorb it.
    Absorbed,
    /// The ray came from behind the array: the silicon chip and the ceramic package it is
    /// bonded to are opaque, so it ends on the package's back (on the real device no light
    /// reaches the mirrors, or passes the array, from behind).
    Behind,
    /// An upward ray that met no neighbouring mirror: it carries on in its direction from
    /// `origin`, just above the slab that holds the mirrors.
    Left { origin: DVec3 },
}

#[inline]
pub fn state_index(s: MirrorState) -> usize {
    match s {
        MirrorState::Plus => 0,
        MirrorState::Minus => 1,
        MirrorState::Flat => 2,
    }
}

impl Dmd {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        columns: usize,
        rows: usize,
        pitch: f64,
        fill_factor: f64,
        tilt: f64,
        hinge_angle: f64,
        pattern: PatternArea,
        outside: MirrorState,
        reflectance: Spectrum,
    ) -> Dmd {
        let hinge = DVec3::new(hinge_angle.cos(), hinge_angle.sin(), 0.0);
        let rot = [
            DMat3::from_axis_angle(hinge, tilt),
            DMat3::from_axis_angle(hinge, -tilt),
            DMat3::IDENTITY,
        ];
        let side = pitch * fill_factor.sqrt();
        // The corner farthest from the hinge line is at side/√2 (diagonal hinge) or side/2
        // (edge hinge); side/√2 bounds both.
        let h = side / std::f64::consts::SQRT_2 * tilt.abs().sin() + 1e-12;
        Dmd {
            columns,
            rows,
            pitch,
            side,
            tilt,
            hinge,
            pattern,
            outside,
            reflectance,
            rot,
            rot_t: [rot[0].transpose(), rot[1].transpose(), rot[2].transpose()],
            normal: [rot[0] * DVec3::Z, rot[1] * DVec3::Z, DVec3::Z],
            h,
            diffraction: None,
            x0: -(columns as f64) * pitch / 2.0,
            y0: (rows as f64) * pitch / 2.0,
        }
    }

    /// The same array reflecting as a diffractive grating (docs/dmd_diffraction.md): tail tables
    /// for the traced `band` (m) in bins of `bin` (m), for the states the mirrors take (+, −
    /// and the outside state).
    pub fn with_diffraction(mut self, band: (f64, f64), bin: f64) -> Dmd {
        let facets = [0, 1, 2].map(|s| Facet::rotated(self.rot[s]));
        let (grating, used) = (self.grating(), self.states_used());
        self.diffraction = Some(Arc::new(Diffraction::new(grating, facets, band, bin, used)));
        self
    }

    /// The memory [`Dmd::with_diffraction`] would take for its tables, estimated without
    /// building them.
    pub fn diffraction_size(&self, band: (f64, f64), bin: f64) -> TableSize {
        TableSize::new(self.grating(), band, bin, self.states_used())
    }

    fn grating(&self) -> Grating {
        Grating {
            pitch: self.pitch,
            side: self.side,
        }
    }

    /// The states the mirrors take: +, − and the outside state.
    fn states_used(&self) -> [bool; 3] {
        let mut used = [true, true, false];
        used[state_index(self.outside)] = true;
        used
    }

    /// The same array reflecting geometrically.
    pub fn geometric(&self) -> Dmd {
        Dmd {
            diffraction: None,
            ..self.clone()
        }
    }

    /// The diffractive model, None when the array reflects geometrically.
    pub fn diffraction(&self) -> Option<&Diffraction> {
        self.diffraction.as_deref()
    }

    /// The unit normal of a mirror in `state`.
    pub fn normal(&self, state: MirrorState) -> DVec3 {
        self.normal[state_index(state)]
    }

    /// Half width and half height of the array (m).
    pub fn half_size(&self) -> (f64, f64) {
        (-self.x0, self.y0)
    }

    /// Half thickness of the slab that contains every tilted mirror.
    pub fn slab_half_height(&self) -> f64 {
        self.h
    }

    /// Centre of mirror (col, row).
    #[inline]
    pub fn mirror_center(&self, col: usize, row: usize) -> DVec3 {
        DVec3::new(
            self.x0 + (col as f64 + 0.5) * self.pitch,
            self.y0 - (row as f64 + 0.5) * self.pitch,
            0.0,
        )
    }

    /// The cell (col, row) containing (x, y) on the array plane, if inside the array.
    #[inline]
    pub fn cell_at(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let c = ((x - self.x0) / self.pitch).floor();
        let r = ((self.y0 - y) / self.pitch).floor();
        if c >= 0.0 && r >= 0.0 && (c as usize) < self.columns && (r as usize) < self.rows {
            Some((c as usize, r as usize))
        } else {
            None
        }
    }

    /// Where a ray starts interacting with the array, if it does: for a downward ray that
    /// crosses z = 0 inside the array, the parameter where it enters the slab |z| ≤ h; for an
    /// upward ray that starts inside the slab over the array (just reflected by a mirror), `t_min`
    /// (it may still meet a neighbouring mirror); for an upward ray from behind the array, where
    /// it meets the slab's back face inside the array's outline (the chip and its package are
    /// opaque: [`Dmd::interact`] absorbs it there). Otherwise None: the ray misses the array (the
    /// package around it is an ordinary surface).
    #[inline]
    pub fn slab_entry(&self, o: DVec3, d: DVec3, t_min: f64) -> Option<f64> {
        let (hx, hy) = self.half_size();
        if d.z < 0.0 {
            let t0 = -o.z / d.z;
            if t0 <= t_min {
                return None;
            }
            let p = o + t0 * d;
            if p.x.abs() <= hx && p.y.abs() <= hy {
                Some(((self.h - o.z) / d.z).max(t_min))
            } else {
                None
            }
        } else if o.z < -self.h {
            if d.z <= 0.0 {
                return None;
            }
            let t0 = (-self.h - o.z) / d.z;
            let p = o + t0 * d;
            (t0 > t_min && p.x.abs() <= hx && p.y.abs() <= hy).then_some(t0)
        } else if o.z <= self.h && o.z >= -self.h && o.x.abs() <= hx && o.y.abs() <= hy {
            Some(t_min)
        } else {
            None
        }
    }

    /// Where a downward ray crosses the array plane z = 0 (for the footprint of a pattern unit).
    #[inline]
    pub fn plane_crossing(&self, o: DVec3, d: DVec3) -> Option<DVec3> {
        if d.z < 0.0 {
            Some(o - (o.z / d.z) * d)
        } else {
            None
        }
    }

    /// Intersects the mirror grid with mirror states given by `state_of(col, row)`. Only facet
    /// fronts count as mirror hits; a downward ray that meets no facet front is a [`DmdHit::Gap`];
    /// an upward ray that meets no facet returns None (it has left the array).
    pub fn intersect(
        &self,
        o: DVec3,
        d: DVec3,
        t_min: f64,
        state_of: impl Fn(usize, usize) -> MirrorState,
    ) -> Option<DmdHit> {
        let h = self.h;
        // Where the ray is inside the slab.
        let (ta, tb) = if d.z != 0.0 {
            let a = (h - o.z) / d.z;
            let b = (-h - o.z) / d.z;
            (a.min(b).max(t_min), a.max(b))
        } else {
            (t_min, t_min + 4.0 * self.pitch)
        };
        if tb <= ta {
            return None;
        }
        let pa = o + ta * d;
        let pb = o + tb * d;
        let mut best: Option<(f64, usize, usize, usize)> = None; // (t, col, row, state)
        let test_around = |p: DVec3, best: &mut Option<(f64, usize, usize, usize)>| {
            let c = ((p.x - self.x0) / self.pitch).floor() as i64;
            let r = ((self.y0 - p.y) / self.pitch).floor() as i64;
            for rr in r - 1..=r + 1 {
                for cc in c - 1..=c + 1 {
                    if cc < 0 || rr < 0 || cc >= self.columns as i64 || rr >= self.rows as i64 {
                        continue;
                    }
                    let (col, row) = (cc as usize, rr as usize);
                    let s = state_index(state_of(col, row));
                    let n = self.normal[s];
                    let den = d.dot(n);
                    if den == 0.0 {
                        continue;
                    }
                    let c0 = self.mirror_center(col, row);
                    let t = (c0 - o).dot(n) / den;
                    if t <= t_min || best.is_some_and(|b| b.0 <= t) {
                        continue;
                    }
                    let local = self.rot_t[s] * (o + t * d - c0);
                    let half = 0.5 * self.side;
                    if local.x.abs() <= half && local.y.abs() <= half {
                        *best = Some((t, col, row, s));
                    }
                }
            }
        };
        test_around(pa, &mut best);
        if (pb - pa).length() > 0.5 * self.pitch {
            test_around(pb, &mut best);
        }
        match best {
            Some((t, col, row, s)) => {
                let n = self.normal[s];
                if d.dot(n) < 0.0 {
                    Some(DmdHit::Mirror {
                        t,
                        col,
                        row,
                        normal: n,
                    })
                } else {
                    // The back of a mirror: only reachable through a gap.
                    Some(DmdHit::Gap { t })
                }
            }
            None if d.z < 0.0 => Some(DmdHit::Gap {
                t: if d.z != 0.0 { -o.z / d.z } else { ta },
            }),
            None => None,
        }
    }

    /// The pattern unit whose footprint a downward ray crosses on the array plane z = 0, if any:
    /// where a trace attributes a path to a unit (and splits it into its mirror-state branches).
    #[inline]
    pub fn unit_crossed(&self, o: DVec3, d: DVec3) -> Option<usize> {
        let q = self.plane_crossing(o, d)?;
        self.cell_at(q.x, q.y)
            .and_then(|(c, r)| self.pattern.unit_of(c, r))
    }

    /// A ray (origin `o`, unit direction `d`, wavelength `wavelength_m`) that has reached the
    /// array ([`Dmd::slab_entry`]) meets the actual tilted facets, with the pattern mirrors in
    /// `states` and all others in the `outside` state: reflection on the front of a facet with
    /// the aluminium's reflectance R(λ) (docs/bench-facts.md §2.2–2.3), absorption in the gaps,
    /// or, for an upward ray that meets no neighbouring facet, a way out of the slab. The one
    /// place where the DMD acts on a ray. Reflection is geometric, or, with the diffractive
    /// model, into the diffraction order that `order_u` (one uniform in [0, 1), unused by the
    /// geometric model) draws (docs/dmd_diffraction.md).
    pub fn interact(
        &self,
        o: DVec3,
        d: DVec3,
        wavelength_m: f64,
        states: PatternStates,
        order_u: f64,
    ) -> DmdOutcome {
        if d.z > 0.0 && o.z < -self.h {
            return DmdOutcome::Behind;
        }
        let pattern = self.pattern;
        let outside = self.outside;
        let state_of = |c: usize, r: usize| -> MirrorState {
            match pattern.unit_of(c, r) {
                None => outside,
                Some(j) => match states {
                    PatternStates::Uniform(s) => s,
                    PatternStates::Bits(bits) => MirrorState::from_bit(bits[j]),
                },
            }
        };
        match self.intersect(o, d, 0.0, state_of) {
            Some(DmdHit::Mirror {
                t,
                col,
                row,
                normal,
            }) => {
                let hit = o + t * d;
                let unit = pattern.unit_of(col, row);
                let direction = match &self.diffraction {
                    None => reflect(d, normal),
                    Some(diff) => {
                        let s = state_index(state_of(col, row));
                        match diff.draw(s, d, wavelength_m, order_u) {
                            Order::Propagating { direction, .. } => direction,
                            Order::Specular => reflect(d, normal),
                            Order::Evanescent => return DmdOutcome::Evanescent { unit },
                        }
                    }
                };
                DmdOutcome::Reflected {
                    origin: hit + SURFACE_OFFSET * normal,
                    direction,
                    reflectance: self.reflectance.at(wavelength_m).clamp(0.0, 1.0),
                    unit,
                }
            }
            Some(DmdHit::Gap { .. }) => DmdOutcome::Absorbed,
            None => {
                // An upward ray that met no neighbouring mirror: move it just above the slab.
                let t_exit = (self.h - o.z) / d.z;
                DmdOutcome::Left {
                    origin: o + (t_exit + SURFACE_OFFSET / d.z) * d,
                }
            }
        }
    }

    /// The rotation that takes a flat mirror into `state` (for tests and exporters).
    pub fn rotation(&self, state: MirrorState) -> DMat3 {
        self.rot[state_index(state)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dlp7000() -> Dmd {
        Dmd::new(
            1024,
            768,
            13.68e-6,
            0.92,
            12f64.to_radians(),
            45f64.to_radians(),
            PatternArea {
                col0: 224,
                row0: 96,
                units_across: 48,
                units_down: 48,
                mirrors_per_unit: 12,
            },
            MirrorState::Minus,
            Spectrum::Constant(1.0),
        )
    }

    #[test]
    fn normal_incidence_leaves_at_24_degrees_in_the_45_degree_plane() {
        // docs/bench-facts.md §2.3: r = (±sin 2θ/√2, ∓sin 2θ/√2, cos 2θ) = (±0.2876, ∓0.2876, 0.9135).
        let dmd = dlp7000();
        let mut rng = crate::rng::stream(3, 0);
        for (state, sign) in [(MirrorState::Plus, 1.0), (MirrorState::Minus, -1.0)] {
            let mut hits = 0;
            for _ in 0..1000 {
                let x = (crate::rng::uniform(&mut rng) - 0.5) * 0.014;
                let y = (crate::rng::uniform(&mut rng) - 0.5) * 0.0105;
                let o = DVec3::new(x, y, 1e-3);
                let d = DVec3::new(0.0, 0.0, -1.0);
                match dmd.intersect(o, d, 0.0, |_, _| state) {
                    Some(DmdHit::Mirror { normal, .. }) => {
                        hits += 1;
                        let r = reflect(d, normal);
                        let expect = DVec3::new(
                            sign * (24f64.to_radians().sin() / 2f64.sqrt()),
                            -sign * (24f64.to_radians().sin() / 2f64.sqrt()),
                            24f64.to_radians().cos(),
                        );
                        assert!(r.abs_diff_eq(expect, 1e-12), "{r:?}");
                        assert!((r.x - sign * 0.2876).abs() < 5e-5);
                        assert!((r.z - 0.9135).abs() < 5e-5);
                        assert!((r.z.acos().to_degrees() - 24.0).abs() < 1e-9);
                    }
                    Some(DmdHit::Gap { .. }) => {}
                    None => panic!("a downward ray over the array must meet it"),
                }
            }
            // The fraction that meets a mirror is the projected fill factor: a mirror tilted by
            // 12° projects onto the array plane with area side²·cos 12°, so 0.92·cos 12° = 0.900.
            // Binomial standard error √(0.9·0.1/1000) = 0.0095; allow 4 standard errors.
            let frac = hits as f64 / 1000.0;
            let proj = 0.92 * 12f64.to_radians().cos();
            assert!((frac - proj).abs() < 4.0 * 0.0095, "{frac} vs {proj}");
        }
    }

    #[test]
    fn pattern_units_are_row_major() {
        let dmd = dlp7000();
        let p = dmd.pattern;
        assert_eq!(p.unit_of(224, 96), Some(0));
        assert_eq!(p.unit_of(224 + 12, 96), Some(1));
        assert_eq!(p.unit_of(224, 96 + 12), Some(48));
        assert_eq!(p.unit_of(224 + 575, 96 + 575), Some(48 * 48 - 1));
        assert_eq!(p.unit_of(224 + 576, 96), None);
        assert_eq!(p.unit_of(223, 100), None);
        // Mirror (0, 0) is at the top left: −x, +y.
        let c = dmd.mirror_center(0, 0);
        assert!(c.x < 0.0 && c.y > 0.0);
        assert_eq!(dmd.cell_at(c.x, c.y), Some((0, 0)));
    }
}
