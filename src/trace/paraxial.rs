//! The paraxial design numbers of a bench (what `spibench check` prints and writes as
//! `check.json`), without tracing it: the elements, each lens's focal length and the conjugates
//! it forms, the chart → DMD magnification, what each arm lens does with the beam, the
//! numerical aperture of each diode and the size of the pattern area on the chart
//! ([`paraxial_report`] → [`ParaxialReport`]).
//!
//! **Which object each lens images.** The chief rays ([`chief_ray`]: the ray from the
//! filament centre along the lamp axis, refracted at every interface and reflected by the DMD in
//! either mirror state) pass the bench's elements in order. Each lens on them images the last
//! object that precedes it: the lamp filament (the collimator), a chart (the imaging lens), the
//! DMD's pattern area (the arm lenses), or the image formed by an earlier lens when two lenses
//! follow each other. Distances are measured along the lens axis from the object point (where
//! the chief ray meets it) to the front principal plane, and from the back principal plane to
//! the image (Gaussian lens equation 1/s + 1/s' = 1/f; thick-lens f and principal planes from
//! the lensmaker's equation, e.g. Hecht, *Optics*, §6.2).

use glam::DVec3;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::optics::bench::Interaction;
use crate::optics::dmd::MirrorState;
use crate::optics::lens::trace::Paraxial;
use crate::optics::outline::{LensPrescription, element_outlines, lenses};
use crate::trace::fan::{ChiefEnd, chief_ray, dmd_axes};

/// One element of the bench.
#[derive(Debug, Clone, Serialize)]
pub struct ElementEntry {
    pub name: String,
    pub kind: String,
    /// Centre of its outline (m, bench frame): the mean of the outline's points, which for a
    /// lens or a tilted part is not where the file places it.
    pub centre_m: [f64; 3],
    /// Its position as the bench file gives it (m, bench frame: a lens's first vertex, a
    /// mirror's or a diode's centre, the lamp's filament centre); null for the DMD, which
    /// defines the frame.
    pub position_m: Option<[f64; 3]>,
}

/// A lens's paraxial numbers at the design wavelength.
#[derive(Debug, Clone, Serialize)]
pub struct LensEntry {
    pub name: String,
    /// Refractive index of its glass at the design wavelength.
    pub index: f64,
    pub front_radius_m: Option<f64>,
    pub back_radius_m: Option<f64>,
    pub thickness_m: f64,
    /// Effective focal length and back focal length (from the back vertex).
    pub focal_length_m: f64,
    pub back_focal_length_m: f64,
    /// What it images (`lamp filament`, `chart NAME`, `DMD pattern centre`, `image by LENS`),
    /// or null when no chief ray passes it.
    pub object: Option<String>,
    /// Object distance, object point → front principal plane, along the axis (m).
    pub object_distance_m: Option<f64>,
    /// Image distance, back principal plane → image, along the axis (m; negative: virtual).
    pub image_distance_m: Option<f64>,
    /// Lateral magnification −s'/s.
    pub magnification: Option<f64>,
    /// For an arm lens (object: the DMD), what it does with the beam; null for other lenses.
    pub arm: Option<ArmLensEntry>,
}

/// What an arm lens does with the beam from the DMD (paraxial, unfolded along the chief ray,
/// no vignetting; see [`arm_beam`]).
#[derive(Debug, Clone, Serialize)]
pub struct ArmLensEntry {
    /// The pupil: the imaging lens's whole clear aperture (its back principal plane and
    /// semi-diameter), `pupil_to_dmd_m` before the DMD along the chief ray. The lit part of it
    /// (the filament's image in a Köhler-like bench) is smaller, so the beam and fill below are
    /// upper bounds: what the arm must accept if the imaging lens's aperture is filled.
    pub pupil: String,
    pub pupil_diameter_m: f64,
    pub pupil_to_dmd_m: f64,
    /// Where this lens images the pupil (from its back principal plane, along the light) and
    /// the pupil image's diameter.
    pub pupil_image_distance_m: f64,
    pub pupil_image_diameter_m: f64,
    /// Where it images the DMD's pattern area (= `image_distance_m`) and that image's diagonal.
    pub dmd_image_distance_m: f64,
    pub dmd_image_diagonal_m: f64,
    /// The lit pupil: the light that reaches the DMD from the illumination, as the cone each
    /// pattern point receives (see [`LitPupil`]): the half-angle of that cone, and where the
    /// cones' axes meet (the filament's image: its distance before the DMD, null when the
    /// illumination is telecentric) and its diameter there. `lit_by` says whether the
    /// filament's image or the pupil's aperture limits the cone.
    pub lit_half_angle_rad: f64,
    pub lit_pupil_to_dmd_m: Option<f64>,
    pub lit_pupil_diameter_m: Option<f64>,
    pub lit_by: String,
    /// The diode the arm's chief ray reaches, its distance from the back principal plane along
    /// the chief ray (fold mirrors included), the beam's diameter there (every point of the
    /// pattern area lit by the lit pupil's cone: the estimate) and its fill of the diode's
    /// diameter (> 1: the diode clips the beam).
    pub diode: Option<String>,
    pub diode_distance_m: Option<f64>,
    pub spot_diameter_m: Option<f64>,
    pub diode_fill: Option<f64>,
    /// The same with the pupil's whole aperture lit: the upper bound a filled aperture gives.
    pub spot_bound_diameter_m: Option<f64>,
    pub diode_fill_bound: Option<f64>,
}

/// The light a DMD point receives from the illumination, in paraxial optics along the lit
/// chief ray (lamp → lenses → DMD, unfolded). With the ray-transfer matrix [[A, B], [C, D]]
/// from the filament to the DMD (lenses as thin lenses at their principal planes, in air:
/// AD − BC = 1; e.g. Hecht, *Optics*, §6.2), a ray from filament height y₀ reaches the DMD at
/// height h with slope u = (D·h − y₀)/B. So every pattern point h receives a cone of half-angle
/// r/|B| (r: the filament's reach, the half-diagonal of a rectangular one), whose axis has
/// slope D·h/B: the axes meet at B/D before the DMD, where the filament is imaged (the lit
/// pupil of a Köhler bench), with diameter 2·(r/|B|)·|B/D| = 2r/|D|. Apertures on the way (the
/// collimator's, a field stop) are not applied: the cone is capped by the pupil's aperture only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LitPupil {
    /// Filament → DMD ray-transfer matrix so far: [A, B, C, D].
    m: [f64; 4],
    /// The plane the matrix ends at (the lamp, then each lens's back principal plane).
    from: DVec3,
    /// The filament's reach (m).
    reach: f64,
}

impl LitPupil {
    pub fn new(filament: DVec3, reach: f64) -> LitPupil {
        LitPupil {
            m: [1.0, 0.0, 0.0, 1.0],
            from: filament,
            reach,
        }
    }

    fn then(&mut self, [a2, b2, c2, d2]: [f64; 4]) {
        let [a, b, c, d] = self.m;
        self.m = [
            a2 * a + b2 * c,
            a2 * b + b2 * d,
            c2 * a + d2 * c,
            c2 * b + d2 * d,
        ];
    }

    /// A lens of focal length `f` with principal planes at `front` and `back` on `axis`.
    pub fn lens(&mut self, f: f64, front: DVec3, back: DVec3, axis: DVec3) {
        self.then([1.0, (front - self.from).dot(axis), 0.0, 1.0]);
        self.then([1.0, 0.0, -1.0 / f, 1.0]);
        self.from = back;
    }

    /// Ends the matrix at the DMD point `p` (along the chief ray from the last plane).
    pub fn at(mut self, p: DVec3) -> LitPupil {
        self.then([1.0, (p - self.from).length(), 0.0, 1.0]);
        self.from = p;
        self
    }

    /// Half-angle of the cone each pattern point receives (∞ when the filament is imaged on
    /// the DMD: then the lenses' apertures set it).
    pub fn half_angle(&self) -> f64 {
        self.reach / self.m[1].abs()
    }

    /// Slope of the cone's axis per unit height on the DMD: D/B (0: telecentric).
    pub fn chief_per_height(&self) -> f64 {
        self.m[3] / self.m[1]
    }
}

/// The beam of an arm lens of focal length `f` at `s` from the DMD (object distance), for a
/// pupil of semi-diameter `a` at `l` before the DMD and a pattern area of half-diagonal `h`:
/// (pupil image distance, pupil magnification, beam diameter at `z` behind the lens). Paraxial
/// ray heights y and slopes u through a thin lens at the principal planes (u' = u − y/f; e.g.
/// Hecht, *Optics*, §6.1): the marginal ray leaves the DMD's centre with slope a/l, the chief
/// ray leaves the pattern's corner at height h with slope h/l (it comes through the pupil's
/// centre); the beam's radius at z is |y_marginal| + |y_chief|.
pub fn arm_beam(f: f64, s: f64, a: f64, l: f64, h: f64, z: Option<f64>) -> (f64, f64, Option<f64>) {
    let sp = l + s;
    let sp_img = 1.0 / (1.0 / f - 1.0 / sp);
    let mp = -sp_img / sp;
    (sp_img, mp, z.map(|z| arm_spot(f, s, a / l, 1.0 / l, h, z)))
}

/// The beam diameter at `z` behind an arm lens (focal length `f`, `s` from the DMD) when each
/// pattern point receives a cone of half-angle `u_marginal` whose axis has slope
/// `chief_per_height`·height, over a pattern of half-diagonal `h`: |y_marginal| + |y_chief|
/// as in [`arm_beam`] (the marginal ray from the DMD's centre, the chief ray from the corner).
pub fn arm_spot(f: f64, s: f64, u_marginal: f64, chief_per_height: f64, h: f64, z: f64) -> f64 {
    let height = |y0: f64, u0: f64| {
        let y = y0 + u0 * s;
        let u = u0 - y / f;
        y + u * z
    };
    2.0 * (height(0.0, u_marginal).abs() + height(h, h * chief_per_height).abs())
}

/// Walks the chief ray of mirror state `state` from the lamp (objects, lens conjugates, the
/// chart → DMD chain, the lit pupil) and fills the lens entries it meets; sets `chart_to_dmd`
/// to the chart → DMD magnification when it is first found.
fn walk_chief_ray(
    bench: &Bench,
    prescriptions: &[LensPrescription],
    entries: &mut [LensEntry],
    state: MirrorState,
    wl: f64,
    half_diagonal: f64,
    chart_to_dmd: &mut Option<f64>,
) {
    let lamp = &bench.lamp().frame;
    let ray = chief_ray(bench, lamp.origin, lamp.w, wl, state);
    let mut object: (DVec3, String) = (lamp.origin, "lamp filament".into());
    // Magnification accumulated since the last chart.
    let mut since_chart: Option<f64> = None;
    let mut last: Option<usize> = None;
    // The pupil (name, semi-diameter) and the path from it; the arm lens (entry, its back
    // principal plane's path) and the path from it to the ray's end.
    let mut pupil: Option<(String, f64, f64)> = None;
    let mut pupil_to_dmd: Option<(String, f64, f64)> = None;
    let mut arm_lens: Option<(usize, f64)> = None;
    // The illumination's matrix up to the DMD, then the lit cone there.
    let mut illum = Some(LitPupil::new(lamp.origin, bench.lamp().shape.reach()));
    let mut lit: Option<LitPupil> = None;
    let mut trail = ray.points[0];
    for (k, el) in ray.elements.iter().enumerate() {
        let p = ray.points[k + 1];
        let step = (p - trail).length();
        trail = p;
        if let Some(pp) = &mut pupil {
            pp.2 += step;
        }
        if let Some(a) = &mut arm_lens {
            a.1 += step;
        }
        match el {
            None => {
                pupil_to_dmd = pupil.take();
                lit = illum.take().map(|x| x.at(p));
                if chart_to_dmd.is_none() {
                    *chart_to_dmd = since_chart;
                }
                since_chart = None;
                object = (p, "DMD pattern centre".into());
                last = None;
            }
            Some(id) => {
                let name = &bench.elements()[*id];
                // The chart's object plane is its chrome face, whichever way it faces.
                if ray.surfaces[k].is_some_and(|i| {
                    matches!(bench.surfaces()[i].interaction, Interaction::Chart { .. })
                }) {
                    object = (p, format!("chart `{name}`"));
                    since_chart = Some(1.0);
                    last = Some(*id);
                    continue;
                }
                if last == Some(*id) {
                    continue;
                }
                last = Some(*id);
                let Some(i) = prescriptions.iter().position(|l| &l.name == name) else {
                    continue;
                };
                let l = &prescriptions[i];
                let (f, _, h1, h2) = cardinal(l, wl);
                let front_h = l.vertex + h1 * l.axis;
                let back_h = l.vertex + (l.thickness + h2) * l.axis;
                let s = (front_h - object.0).dot(l.axis);
                let s_img = 1.0 / (1.0 / f - 1.0 / s);
                let m = -s_img / s;
                if let Some(il) = &mut illum {
                    il.lens(f, front_h, back_h, l.axis);
                }
                let is_dmd_object = object.1 == "DMD pattern centre";
                let images_chart = object.1.starts_with("chart");
                let e = &mut entries[i];
                if e.object.is_none() {
                    e.object = Some(object.1.clone());
                    e.object_distance_m = Some(s);
                    e.image_distance_m = Some(s_img);
                    e.magnification = Some(m);
                    if let (true, Some((name, a, l))) = (is_dmd_object, &pupil_to_dmd) {
                        let (pupil_img, pupil_m, _) = arm_beam(f, s, *a, *l, half_diagonal, None);
                        let (u, c, lit_by) = lit_cone(lit, *a / *l, 1.0 / *l);
                        e.arm = Some(ArmLensEntry {
                            pupil: format!("aperture of `{name}`"),
                            pupil_diameter_m: 2.0 * a,
                            pupil_to_dmd_m: *l,
                            pupil_image_distance_m: pupil_img,
                            pupil_image_diameter_m: 2.0 * a * pupil_m.abs(),
                            dmd_image_distance_m: s_img,
                            dmd_image_diagonal_m: 2.0 * half_diagonal * m.abs(),
                            lit_half_angle_rad: u,
                            lit_pupil_to_dmd_m: (c != 0.0).then(|| 1.0 / c),
                            lit_pupil_diameter_m: (c != 0.0).then(|| 2.0 * u / c.abs()),
                            lit_by: lit_by.to_string(),
                            diode: None,
                            diode_distance_m: None,
                            spot_diameter_m: None,
                            diode_fill: None,
                            spot_bound_diameter_m: None,
                            diode_fill_bound: None,
                        });
                        // The path from the back principal plane to this surface point.
                        arm_lens = Some((i, -(back_h - p).length()));
                    }
                }
                if images_chart {
                    // The pupil of the light on the DMD: this lens's aperture, from its
                    // back principal plane (the path from there to the surface point).
                    pupil = Some((l.name.clone(), l.semi_diameter, -(p - back_h).length()));
                }
                since_chart = since_chart.map(|x| x * m);
                object = (back_h + s_img * l.axis, format!("image by `{name}`"));
            }
        }
    }
    if let (Some(a), Some(end)) = (&mut arm_lens, ray.points.last()) {
        // The ray's last point (on the diode) if the walk above did not reach it.
        a.1 += (*end - trail).length();
    }
    if let (Some((i, z)), ChiefEnd::Detector(d)) = (arm_lens, ray.end) {
        let det = &bench.detectors()[d];
        let l = &prescriptions[i];
        let (f, ..) = cardinal(l, wl);
        let e = &mut entries[i];
        if let (Some(arm), Some(s), Some((_, a, pl))) =
            (&mut e.arm, e.object_distance_m, &pupil_to_dmd)
        {
            let (_, _, bound) = arm_beam(f, s, *a, *pl, half_diagonal, Some(z));
            let (u, c, _) = lit_cone(lit, *a / *pl, 1.0 / *pl);
            let spot = arm_spot(f, s, u, c, half_diagonal, z);
            arm.diode = Some(["pd_plus", "pd_minus"][d].to_string());
            arm.diode_distance_m = Some(z);
            arm.spot_diameter_m = Some(spot);
            arm.diode_fill = Some(spot / (2.0 * det.radius));
            arm.spot_bound_diameter_m = bound;
            arm.diode_fill_bound = bound.map(|v| v / (2.0 * det.radius));
        }
    }
}

/// The cone each pattern point receives: the lit pupil's (the filament's image) where it is
/// narrower than the aperture's (half-angle `aperture_u`, axis slope `aperture_chief` per unit
/// height), else the aperture's: (half-angle, axis slope per height, which one).
fn lit_cone(
    lit: Option<LitPupil>,
    aperture_u: f64,
    aperture_chief: f64,
) -> (f64, f64, &'static str) {
    match lit {
        Some(p) if p.half_angle() < aperture_u => {
            (p.half_angle(), p.chief_per_height(), "filament image")
        }
        _ => (aperture_u, aperture_chief, "aperture"),
    }
}

/// A photodiode's numerical aperture.
#[derive(Debug, Clone, Serialize)]
pub struct DiodeEntry {
    pub name: String,
    pub diameter_m: f64,
    /// The element whose surface the arm's chief ray leaves last before the diode.
    pub last_optic: Option<String>,
    /// Distance from that surface (where the chief ray leaves it) to the diode centre (m).
    pub distance_m: Option<f64>,
    /// sin of the half-angle the diode disk subtends from there: r / √(r² + d²).
    pub numerical_aperture: Option<f64>,
    /// Where the arm's chief ray from the pattern centre ends.
    pub chief_ray_end: String,
    /// Where it meets the diode, in the diode's (u, v) axes from the active area's centre (the
    /// axes of the irradiance maps; m), when it ends there.
    pub chief_ray_on_diode_m: Option<[f64; 2]>,
    /// The angular acceptance at the DMD: the smallest angle, over eight directions around the
    /// arm's chief ray at the pattern centre, by which a ray must turn before it no longer
    /// reaches the diode (rad; up to [`ACCEPTANCE_MAX_RAD`]).
    pub acceptance_rad: Option<f64>,
    /// The DMD's order spacing λ/p at the design wavelength (rad; the spacing along a mirror
    /// axis, the closest orders; docs/dmd_diffraction.md).
    pub order_spacing_rad: Option<f64>,
}

/// The largest angle the acceptance search turns a ray by (rad): beyond it no arm's optics
/// matter for the orders (the envelope of a mirror is a few λ/p wide).
pub const ACCEPTANCE_MAX_RAD: f64 = 0.5;

impl DiodeEntry {
    /// The diode accepts less than one order spacing: with the diffractive DMD it collects only
    /// the orders that happen to fall on it (docs/guide/05-dmd-diffraction.md).
    pub fn acceptance_below_order_spacing(&self) -> bool {
        matches!((self.acceptance_rad, self.order_spacing_rad), (Some(a), Some(s)) if a < s)
    }
}

/// The angular acceptance of arm k's diode (see [`DiodeEntry::acceptance_rad`]): along each of
/// eight directions around the chief ray, the turn at which the ray first misses the diode, by
/// bisection to 0.1 mrad after a scan in 5 mrad steps (a diode accepts a range of angles about
/// its chief ray, not a scattered set, for any arm of lenses and mirrors).
fn acceptance(bench: &Bench, axes: &crate::trace::fan::DmdAxes, k: usize, wl: f64) -> f64 {
    let state = crate::optics::Arm::from_index(k).state();
    let d = axes.outgoing[crate::optics::dmd::state_index(state)];
    let a = d.any_orthonormal_vector();
    let b = d.cross(a);
    let reaches = |t: f64, phi: f64| {
        let dir = (d * t.cos() + (a * phi.cos() + b * phi.sin()) * t.sin()).normalize();
        axes.arm_ray(bench, k, dir, wl).end == ChiefEnd::Detector(k)
    };
    let mut least = ACCEPTANCE_MAX_RAD;
    for j in 0..8 {
        let phi = std::f64::consts::TAU * j as f64 / 8.0;
        let step = 5e-3;
        let mut t = step;
        while t <= least && reaches(t, phi) {
            t += step;
        }
        if t > least {
            continue;
        }
        let (mut lo, mut hi) = (t - step, t);
        while hi - lo > 1e-4 {
            let mid = 0.5 * (lo + hi);
            if reaches(mid, phi) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        least = least.min(lo);
    }
    least
}

/// The paraxial numbers of a bench (`check.json`).
#[derive(Debug, Clone, Serialize)]
pub struct ParaxialReport {
    pub scene: String,
    pub design_wavelength_m: f64,
    pub elements: Vec<ElementEntry>,
    pub lenses: Vec<LensEntry>,
    /// The glasses modelled from a prescription's nd and Vd (filled by `outputs::check`, which
    /// has the bench file).
    pub glass_substitutions: Vec<String>,
    /// Lateral magnification from the chart to the DMD (product over the lenses between).
    pub chart_to_dmd_magnification: Option<f64>,
    /// The pattern area on the DMD (width, height; m).
    pub pattern_on_dmd_m: Option<[f64; 2]>,
    /// The pattern area seen on the chart: the DMD size / |m| (m).
    pub pattern_on_chart_m: Option<[f64; 2]>,
    pub diodes: Vec<DiodeEntry>,
}

/// Paraxial data of a lens at `wl` from every surface of its prescription (a y–nu trace,
/// `Prescription::paraxial`): (f, BFL, front principal plane offset h1 from the first vertex,
/// back principal plane offset h2 from the last vertex), offsets along the light: h1 = f − FFL,
/// h2 = BFL − f (for a singlet h1 = −f(n − 1)t/(n R2), h2 = −f(n − 1)t/(n R1), Hecht §6.2). An
/// afocal lens has f = BFL = ∞ and its principal planes at the vertices.
fn cardinal(lens: &LensPrescription, wl: f64) -> (f64, f64, f64, f64) {
    match lens.prescription.paraxial(wl) {
        Ok(Paraxial {
            efl_m: Some(f),
            bfl_m: Some(bfl),
            ffl_m: Some(ffl),
        }) => (f, bfl, f - ffl, bfl - f),
        _ => (f64::INFINITY, f64::INFINITY, 0.0, 0.0),
    }
}

/// Computes the report at the design wavelength `wl` (m; see the module notes). The elements'
/// positions as the bench file gives them (`ElementEntry::position_m`) are left to the caller,
/// which has the file.
pub fn paraxial_report(scene: &str, bench: &Bench, wl: f64) -> Result<ParaxialReport> {
    let (lo, hi) = bench.band();
    if !(wl.is_finite() && wl >= lo && wl <= hi) {
        return Err(Error::field(
            "wavelength_nm",
            format!(
                "the design wavelength must lie in the traced band {:.0}–{:.0} nm, got {:.1} nm",
                lo * 1e9,
                hi * 1e9,
                wl * 1e9
            ),
        ));
    }
    let elements = element_outlines(bench)
        .into_iter()
        .map(|o| {
            let pts: Vec<DVec3> = o.polylines.iter().flatten().copied().collect();
            let c = pts.iter().copied().sum::<DVec3>() / pts.len().max(1) as f64;
            ElementEntry {
                name: o.name,
                kind: o.kind.name().into(),
                centre_m: c.to_array(),
                position_m: None,
            }
        })
        .collect();
    let prescriptions = lenses(bench);
    let mut entries: Vec<LensEntry> = prescriptions
        .iter()
        .map(|l| {
            let n = l.glass.index(wl);
            let (f, bfl, _, _) = cardinal(l, wl);
            LensEntry {
                name: l.name.clone(),
                index: n,
                front_radius_m: l.front_radius,
                back_radius_m: l.back_radius,
                thickness_m: l.thickness,
                focal_length_m: f,
                back_focal_length_m: bfl,
                object: None,
                object_distance_m: None,
                image_distance_m: None,
                magnification: None,
                arm: None,
            }
        })
        .collect();

    let pattern_on_dmd = bench.dmd().map(|s| {
        let d = &s.dmd;
        let p = d.pattern;
        let side = p.mirrors_per_unit as f64 * d.pitch;
        [p.units_across as f64 * side, p.units_down as f64 * side]
    });
    let half_diagonal = pattern_on_dmd.map_or(0.0, |[w, h]| 0.5 * w.hypot(h));
    // Walk the two chief rays from the lamp: objects, lens conjugates, the chart → DMD chain.
    let mut chart_to_dmd = None;
    for state in [MirrorState::Plus, MirrorState::Minus] {
        walk_chief_ray(
            bench,
            &prescriptions,
            &mut entries,
            state,
            wl,
            half_diagonal,
            &mut chart_to_dmd,
        );
    }

    let pattern_on_chart = match (pattern_on_dmd, chart_to_dmd) {
        (Some([w, h]), Some(m)) if m != 0.0 => Some([w / m.abs(), h / m.abs()]),
        _ => None,
    };

    let diodes = diode_entries(bench, wl);

    Ok(ParaxialReport {
        scene: scene.to_string(),
        design_wavelength_m: wl,
        elements,
        lenses: entries,
        glass_substitutions: Vec::new(),
        chart_to_dmd_magnification: chart_to_dmd,
        pattern_on_dmd_m: pattern_on_dmd,
        pattern_on_chart_m: pattern_on_chart,
        diodes,
    })
}

/// Each diode's numerical aperture along its arm's chief ray. The geometric NA of the diode
/// disk seen from the last optic before it is chosen over an NA "seen from the DMD through
/// the arm": it needs no paraxial model of a folded, tilted arm, and it is the number to set
/// against the convergence of the beam arriving from that optic (a diode whose NA exceeds
/// the beam's can catch all of it, whatever the arm does before).
fn diode_entries(bench: &Bench, wl: f64) -> Vec<DiodeEntry> {
    let mut diodes = Vec::new();
    let axes = dmd_axes(bench, wl).ok();
    for (k, det) in bench.detectors().iter().enumerate() {
        let name = ["pd_plus", "pd_minus"][k].to_string();
        let mut entry = DiodeEntry {
            name,
            diameter_m: 2.0 * det.radius,
            last_optic: None,
            distance_m: None,
            numerical_aperture: None,
            chief_ray_end: "no DMD".into(),
            chief_ray_on_diode_m: None,
            acceptance_rad: None,
            order_spacing_rad: bench.dmd().map(|s| wl / s.dmd.pitch),
        };
        if let Some(axes) = &axes {
            let ray = axes.arm_chief_ray(bench, k, wl);
            entry.chief_ray_end = match ray.end {
                ChiefEnd::Detector(i) => format!("photodiode {}", ["+", "−"][i]),
                ChiefEnd::Blocked(id) => format!("blocked by {}", bench.elements()[id]),
                ChiefEnd::Escaped => "leaves the bench".into(),
                ChiefEnd::Steps => "too many interactions".into(),
            };
            if ray.end == ChiefEnd::Detector(k) && ray.points.len() >= 3 {
                let n = ray.points.len();
                let from = ray.points[n - 2];
                let optic = match ray.elements.get(n - 3) {
                    Some(Some(id)) => bench.elements()[*id].clone(),
                    _ => "dmd".into(),
                };
                let d = (det.frame.origin - from).length();
                entry.last_optic = Some(optic);
                entry.distance_m = Some(d);
                entry.numerical_aperture = Some(det.radius / det.radius.hypot(d));
                let l = det.frame.to_local(ray.points[n - 1]);
                entry.chief_ray_on_diode_m = Some([l.x, l.y]);
                entry.acceptance_rad = Some(acceptance(bench, axes, k, wl));
            }
        }
        diodes.push(entry);
    }
    diodes
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Principal planes of a plano-convex lens used curved side first: H at the curved vertex,
    /// H' at t/n inside the flat vertex (so BFL = f − t/n); flat side first, the mirror image.
    #[test]
    fn principal_planes_of_a_plano_convex_lens() {
        use crate::optics::lens::{LensSurface, Medium, Prescription, Shape};
        let glass = crate::optics::glass::Glass::Constant(1.5);
        let lens = |front: Shape, back: Shape| {
            let medium = Medium {
                name: "1.5".into(),
                glass: glass.clone(),
                range_nm: None,
                source: "test".into(),
            };
            let surface = |shape, thickness_m, medium_after| LensSurface {
                shape,
                semi_diameter_m: 0.02,
                thickness_m,
                medium_after,
            };
            LensPrescription {
                name: "l".into(),
                vertex: DVec3::ZERO,
                axis: DVec3::Z,
                front_radius: None,
                back_radius: None,
                thickness: 0.01,
                semi_diameter: 0.02,
                glass: glass.clone(),
                prescription: Prescription {
                    name: "l".into(),
                    surfaces: vec![
                        surface(front, 0.01, medium),
                        surface(back, 0.0, Medium::air()),
                    ],
                    image_distance_m: None,
                },
            }
        };
        let l = lens(Shape::Sphere { c: 20.0 }, Shape::Flat);
        let (f, bfl, h1, h2) = cardinal(&l, 850e-9);
        assert!((f - 0.1).abs() < 1e-15);
        assert!(h1.abs() < 1e-15 && (h2 + 0.01 / 1.5).abs() < 1e-15);
        assert!((bfl - (f + h2)).abs() < 1e-15);
        let l = lens(Shape::Flat, Shape::Sphere { c: -20.0 });
        let (_, bfl, h1, h2) = cardinal(&l, 850e-9);
        assert!((h1 - 0.01 / 1.5).abs() < 1e-15 && h2.abs() < 1e-15 && (bfl - 0.1).abs() < 1e-15);
        // A flat plate is afocal: no focal length, the principal planes at the vertices.
        let l = lens(Shape::Flat, Shape::Flat);
        assert_eq!(
            cardinal(&l, 850e-9),
            (f64::INFINITY, f64::INFINITY, 0.0, 0.0)
        );
    }

    /// The paper bench at 850 nm: the imaging lens at 2f–2f images the chart at −1 (the scene
    /// places the chart at 2f for n = 1.50984), the collimator images the filament near infinity.
    #[test]
    fn paper_bench_numbers() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let r = paraxial_report("paper", &bench, 850e-9).unwrap();
        let img = r.lenses.iter().find(|l| l.name == "imaging_lens").unwrap();
        assert!(img.object.as_deref().unwrap().starts_with("chart"));
        let m = r.chart_to_dmd_magnification.unwrap();
        assert!((m + 1.0).abs() < 1e-3, "{m}");
        let arm = r.lenses.iter().find(|l| l.name == "arm_plus_lens").unwrap();
        assert_eq!(arm.object.as_deref(), Some("DMD pattern centre"));
        let col = r.lenses.iter().find(|l| l.name == "collimator").unwrap();
        assert_eq!(col.object.as_deref(), Some("lamp filament"));
        assert!(col.image_distance_m.unwrap().abs() > 10.0);
        for d in &r.diodes {
            let na = d.numerical_aperture.unwrap();
            // 2.5 mm at ~136 mm from the fold mirror.
            assert!((na - 0.0184).abs() < 0.001, "{d:?}");
            assert!(d.last_optic.as_deref().unwrap().ends_with("_fold"));
        }
        assert!(paraxial_report("paper", &bench, 200e-9).is_err());
    }

    /// The arm lenses of the paper bench: the pupil (the imaging lens's aperture, 2f = 202 mm
    /// before the DMD) and the DMD imaged by each arm lens, and the beam on the 5 mm diode
    /// against the paraxial formula by hand.
    #[test]
    fn arm_lens_pupil_dmd_image_and_diode_fill() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let r = paraxial_report("paper", &bench, 850e-9).unwrap();
        for name in ["arm_plus_lens", "arm_minus_lens"] {
            let l = r.lenses.iter().find(|l| l.name == name).unwrap();
            let a = l.arm.as_ref().unwrap_or_else(|| panic!("{name}: {l:?}"));
            eprintln!("{name}: {a:?}");
            assert!(a.pupil.contains("imaging_lens"), "{a:?}");
            assert!((a.pupil_to_dmd_m - 0.202).abs() < 0.01, "{a:?}");
            assert_eq!(a.dmd_image_distance_m, l.image_distance_m.unwrap());
            let (f, s) = (l.focal_length_m, l.object_distance_m.unwrap());
            // Gaussian conjugate of the pupil at l + s.
            let sp = a.pupil_to_dmd_m + s;
            let expect = sp * f / (sp - f);
            assert!((a.pupil_image_distance_m - expect).abs() < 1e-9, "{a:?}");
            let d = a.diode.as_deref().unwrap();
            assert!(name.contains(if d == "pd_plus" { "plus" } else { "minus" }));
            let (z, spot, fill) = (
                a.diode_distance_m.unwrap(),
                a.spot_diameter_m.unwrap(),
                a.diode_fill.unwrap(),
            );
            assert!(z > 0.0 && spot > 0.0);
            assert!((fill - spot / 5e-3).abs() < 1e-12, "{a:?}");
        }
        // By hand: f = 100 mm, DMD at 150 mm, pupil Ø 20 mm at 200 mm, pattern half-diagonal
        // 5 mm, diode 300 mm behind: marginal ray y = 0.05·150 = 7.5 mm, slope 0.05 − 0.075,
        // at 300 mm −0.0 mm; chief ray y = 5 + 0.025·150 = 8.75 mm, slope 0.025 − 0.0875, at
        // 300 mm −10 mm; beam Ø 2·(0 + 10) = 20 mm. The pupil (350 mm) is imaged at 140 mm.
        let (sp, mp, d) = arm_beam(0.1, 0.15, 0.01, 0.2, 0.005, Some(0.3));
        assert!(
            (sp - 0.14).abs() < 1e-12 && (mp + 0.4).abs() < 1e-12,
            "{sp} {mp}"
        );
        assert!((d.unwrap() - 0.02).abs() < 1e-12, "{d:?}");
    }

    /// The lit pupil of a Köhler train by hand: filament at a thin collimator's focus
    /// (f = 100 mm), a thin lens f = 100 mm 200 mm further on, the DMD 200 mm behind it. The
    /// matrix is B = −f, D = −1 whatever the gap: each DMD point receives a cone of r/f, the
    /// cones' axes meet f before the DMD (the filament's image, of diameter 2r).
    #[test]
    fn lit_pupil_of_a_koehler_train() {
        let r = 1e-3;
        let mut p = LitPupil::new(DVec3::ZERO, r);
        let at = |z: f64| DVec3::new(0.0, 0.0, z);
        p.lens(0.1, at(0.1), at(0.1), DVec3::Z);
        p.lens(0.1, at(0.3), at(0.3), DVec3::Z);
        let p = p.at(at(0.5));
        assert!(
            (p.m[1] + 0.1).abs() < 1e-12 && (p.m[3] + 1.0).abs() < 1e-12,
            "{p:?}"
        );
        assert!((p.half_angle() - 0.01).abs() < 1e-12);
        assert!((1.0 / p.chief_per_height() - 0.1).abs() < 1e-12);
        // The narrower cone wins; a wider lit cone leaves the aperture's.
        assert_eq!(lit_cone(Some(p), 0.05, 1.0 / 0.2).2, "filament image");
        assert_eq!(
            lit_cone(Some(p), 0.005, 1.0 / 0.2),
            (0.005, 5.0, "aperture")
        );
        // The DMD at an arm lens's focal plane: each point's beam leaves collimated, 2·u·s
        // wide; with telecentric light the corner's chief ray crosses the axis at f.
        let spot = arm_spot(0.1, 0.1, 0.01, 0.0, 0.005, 0.1);
        assert!((spot - 0.002).abs() < 1e-15, "{spot}");
    }

    /// On the paper bench the filament (2.0 × 1.2 mm, reach 1.166 mm) at the collimator's
    /// focus is imaged by the imaging lens about f = 101 mm before the DMD at its own size, so
    /// each pattern point receives ± r/f ≈ 11.5 mrad, not the ± 126 mrad of the imaging lens's
    /// whole aperture: the estimated beam on the diode is a fraction of the bound and fits
    /// the 5 mm diode.
    #[test]
    fn arm_lens_spot_from_the_lit_pupil() {
        let bench = crate::trace::testing::paper_bench_with_mask();
        let r = paraxial_report("paper", &bench, 850e-9).unwrap();
        let f_img = r
            .lenses
            .iter()
            .find(|l| l.name == "imaging_lens")
            .unwrap()
            .focal_length_m;
        let reach = 1e-3_f64.hypot(0.6e-3);
        for name in ["arm_plus_lens", "arm_minus_lens"] {
            let l = r.lenses.iter().find(|l| l.name == name).unwrap();
            let a = l.arm.as_ref().unwrap();
            assert_eq!(a.lit_by, "filament image", "{a:?}");
            let pl = a.lit_pupil_to_dmd_m.unwrap();
            assert!((pl - f_img).abs() < 2e-3, "{a:?}");
            assert!((a.lit_pupil_diameter_m.unwrap() / (2.0 * reach) - 1.0).abs() < 0.03);
            assert!(
                (a.lit_half_angle_rad * f_img / reach - 1.0).abs() < 0.03,
                "{a:?}"
            );
            let (spot, bound) = (a.spot_diameter_m.unwrap(), a.spot_bound_diameter_m.unwrap());
            let (f, s, z) = (
                l.focal_length_m,
                l.object_distance_m.unwrap(),
                a.diode_distance_m.unwrap(),
            );
            let h = 0.5 * 48.0 * 12.0 * 13.68e-6 * 2f64.sqrt();
            let by_hand = arm_spot(f, s, reach / f_img, 1.0 / f_img, h, z);
            assert!((spot / by_hand - 1.0).abs() < 0.05, "{spot} {by_hand}");
            assert!(spot < 0.25 * bound, "{a:?}");
            assert!(
                a.diode_fill.unwrap() < 1.0 && a.diode_fill_bound.unwrap() > 1.0,
                "{a:?}"
            );
        }
    }
}

#[cfg(test)]
mod lens_system_tests {
    use super::*;
    use crate::lens::{GlassOptions, read_zmx};
    use crate::scene::doc::BenchDoc;
    use std::path::Path;

    /// The paper bench's text with the `Lens` element `name` replaced by `with`.
    fn replaced(text: &str, name: &str, with: &str) -> String {
        let start = text
            .find(&format!("        Lens(\n            name: \"{name}\""))
            .unwrap();
        let end = start + text[start..].find("        ),\n").unwrap() + "        ),\n".len();
        format!("{}{with}{}", &text[..start], &text[end..])
    }

    /// `check`'s lens table covers `LensSystem` elements: the AC254-100-B doublet as the
    /// imaging lens and the AL1815 even asphere in the + arm get the EFL and BFL of their
    /// prescriptions (all surfaces, the asphere's paraxial curvature), and the doublet still
    /// images the chart.
    #[test]
    fn doublets_and_aspheres_are_in_the_lens_table() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let path = root.join("scenes/paper_bench.ron");
        let text = std::fs::read_to_string(&path).unwrap();
        let doublet = "        LensSystem(\n            name: \"imaging_lens\",\n            zmx: \"parts/thorlabs_ac254-100-b.zmx\",\n            position_mm: (0.0, 0.0, 205.668),\n            axis: Vector((0.0, 0.0, -1.0)),\n        ),\n";
        let asphere = "        LensSystem(\n            name: \"arm_plus_lens\",\n            zmx: \"parts/thorlabs_al1815.zmx\",\n            position_mm: (28.7606, -28.7606, 91.3545),\n            axis: Polar(theta_deg: 24.0, phi_deg: -45.0),\n        ),\n";
        let text = replaced(
            &replaced(&text, "imaging_lens", doublet),
            "arm_plus_lens",
            asphere,
        );
        let doc = BenchDoc::parse(&text, &path).unwrap();
        let bench = doc.build().unwrap();
        let r = paraxial_report("paper", &bench, 850e-9).unwrap();
        for (name, part, surfaces) in [
            ("imaging_lens", "thorlabs_ac254-100-b.zmx", 3),
            ("arm_plus_lens", "thorlabs_al1815.zmx", 2),
        ] {
            let p = read_zmx(
                &root.join("scenes/parts").join(part),
                &GlassOptions::default(),
            )
            .unwrap()
            .prescription;
            assert_eq!(p.surfaces.len(), surfaces);
            let want = p.paraxial(850e-9).unwrap();
            let l = r.lenses.iter().find(|l| l.name == name).unwrap();
            let rel = |a: f64, b: f64| ((a - b) / b).abs();
            assert!(
                rel(l.focal_length_m, want.efl_m.unwrap()) < 1e-9,
                "{name}: {l:?}"
            );
            assert!(
                rel(l.back_focal_length_m, want.bfl_m.unwrap()) < 1e-9,
                "{name}: {l:?}"
            );
            assert!((l.thickness_m - p.length_m()).abs() < 1e-12, "{name}");
        }
        let img = r.lenses.iter().find(|l| l.name == "imaging_lens").unwrap();
        assert!(
            img.object.as_deref().unwrap().starts_with("chart"),
            "{img:?}"
        );
        // The shipped doublet is the f = 100 mm achromat, the asphere the f = 15 mm collector.
        assert!(
            (img.focal_length_m - 0.1).abs() < 1e-3,
            "{}",
            img.focal_length_m
        );
        let arm = r.lenses.iter().find(|l| l.name == "arm_plus_lens").unwrap();
        assert!(
            (arm.focal_length_m - 0.015).abs() < 1e-3,
            "{}",
            arm.focal_length_m
        );
        assert_eq!(r.lenses.len(), 4);
    }

    /// A diode's angular acceptance against the DMD's order spacing. The paper's arms relay the
    /// lit pupil (101.4 mm behind the array) about 1:1 onto the diode, so a ray turned by θ at
    /// the pattern centre moves about 101 mm × θ on it: what the chief ray leaves of the 2.5 mm
    /// radius, over 101 mm, within 20 % (~25 mrad on the + arm), below λ/p = 62 mrad at 850 nm, and `check` warns. The
    /// condenser bench images the DMD onto its diodes, so the turn moves the ray through the
    /// arm's apertures instead: its arm lens's 22.9 mm clear radius at 100 mm, less the field,
    /// accepts at least 0.15 rad, more than two order spacings, and nothing is warned; its
    /// chief rays land within 1 mm of their diodes' centres.
    #[test]
    fn acceptance_against_the_order_spacing() {
        let wl = crate::trace::fan::DESIGN_WAVELENGTH_M;
        let paper = crate::trace::testing::bench_with("paper_bench.ron", &[]);
        let condenser = crate::trace::testing::bench_with("paper_bench_condenser.ron", &[]);
        for d in diode_entries(&paper, wl) {
            let (a, s) = (d.acceptance_rad.unwrap(), d.order_spacing_rad.unwrap());
            assert!((s - wl / 13.68e-6).abs() < 1e-12);
            assert!(d.acceptance_below_order_spacing());
            let [u, v] = d.chief_ray_on_diode_m.unwrap();
            // The − arm's built-in errors (its fold tilted by (0.2, −0.1)°, its diode 0.3 mm
            // off) put its chief ray ~1.2 mm from the centre; the + arm's lands near it.
            let off = u.hypot(v);
            assert!(
                off < [0.5e-3, 1.5e-3][d.name.ends_with("minus") as usize],
                "{}: {off}",
                d.name
            );
            // What is left of the radius, over the ~101 mm per radian of the 1:1 relay.
            let want = (2.5e-3 - off) / 0.1014;
            assert!(
                (a / want - 1.0).abs() < 0.2,
                "{}: {a} against {want}",
                d.name
            );
        }
        for d in diode_entries(&condenser, wl) {
            let a = d.acceptance_rad.unwrap();
            assert!(
                a > 0.15 && a > 2.0 * d.order_spacing_rad.unwrap(),
                "{}: {a}",
                d.name
            );
            assert!(!d.acceptance_below_order_spacing());
            let [u, v] = d.chief_ray_on_diode_m.unwrap();
            assert!(u.hypot(v) < 1e-3, "{}: ({u}, {v})", d.name);
        }
    }
}
