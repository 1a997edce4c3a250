//! Turns of the illumination about the DMD's centre (docs/dmd_diffraction.md, "Blaze matching").

use glam::{DMat3, DVec3};

use super::moves::{pose, unit};
use crate::error::{Error, Result};
use crate::optics::geometry::Frame;
use crate::scene::bench::{
    ApertureSpec, BaffleSpec, BenchFile, ChartSpec, Direction, ElementSpec, FilterSpec, LensSpec,
    LensSystemSpec, MirrorSpec, Mm3, TubeSpec,
};

/// How far (mm) a part's position may lie from a chief line and still count as on it.
pub(super) const ON_LINE_MM: f64 = 5.0;

/// The most fold mirrors an arm's chief line follows.
pub(super) const MAX_FOLDS: usize = 4;

/// A turn of the illumination: about the mirrors' hinge or about the in-plane axis across it,
/// with the arms left in place or following their states' specular directions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Turn {
    pub(super) across: bool,
    pub(super) tracked: bool,
}

/// `illumination.turn_deg.hinge|across`, `illumination.tracked_turn_deg.hinge|across`; None
/// for any other path (an unknown `illumination.…` path then fails as an unknown part, with
/// these paths among the suggestions, since [`list`] holds them).
pub(super) fn parse_turn(path: &str) -> Option<Turn> {
    let segs: Vec<&str> = path.split('.').collect();
    let (kind, axis) = match segs.as_slice() {
        ["illumination", kind, axis] => (*kind, *axis),
        _ => return None,
    };
    let tracked = match kind {
        "turn_deg" => false,
        "tracked_turn_deg" => true,
        _ => return None,
    };
    let across = match axis {
        "hinge" => false,
        "across" => true,
        _ => return None,
    };
    Some(Turn { across, tracked })
}

pub(super) fn v3(p: Mm3) -> DVec3 {
    DVec3::new(p.0, p.1, p.2)
}

pub(super) fn mm3(v: DVec3) -> Mm3 {
    Mm3(v.x, v.y, v.z)
}

/// The mirror reflection of direction `d` off a surface of unit normal `n`.
pub(super) fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// The distance along `dir` from `o` of the point of the line nearest `p`, when `p` lies ahead
/// of `o` and within [`ON_LINE_MM`] of the line.
pub(super) fn along_line(p: DVec3, o: DVec3, dir: DVec3) -> Option<f64> {
    let s = (p - o).dot(dir);
    let off = (p - o - s * dir).length();
    (s > 1e-6 && off <= ON_LINE_MM).then_some(s)
}

/// The parts a turn moves: the illumination's elements (on the half-line from the DMD's centre
/// through the lamp) and each arm's (on its chief line: from the DMD's centre along its state's
/// specular reflection of the incoming chief direction `d`, folded by each mirror met on it).
pub(super) struct Groups {
    pub(super) illumination: Vec<String>,
    pub(super) arms: [Vec<String>; 2],
    /// Each arm's last fold mirror met by its chief line, with the chief direction arriving
    /// there and the fold's unit normal.
    pub(super) last_folds: [Option<Fold>; 2],
}

/// A fold mirror on an arm's chief line.
pub(super) struct Fold {
    pub(super) name: String,
    pub(super) position: DVec3,
    pub(super) incoming: DVec3,
    pub(super) normal: DVec3,
}

pub(super) fn groups(
    file: &BenchFile,
    d: DVec3,
    normals: [DVec3; 2],
    path: &str,
) -> Result<Groups> {
    let place: Vec<(String, DVec3, Option<Direction>)> = file
        .elements
        .iter()
        .map(|el| {
            let (position, mirror) = match el {
                ElementSpec::Lens(LensSpec { position_mm, .. })
                | ElementSpec::LensSystem(LensSystemSpec { position_mm, .. })
                | ElementSpec::Filter(FilterSpec { position_mm, .. })
                | ElementSpec::Aperture(ApertureSpec { position_mm, .. })
                | ElementSpec::Tube(TubeSpec { position_mm, .. })
                | ElementSpec::Baffle(BaffleSpec { position_mm, .. })
                | ElementSpec::Chart(ChartSpec { position_mm, .. }) => (*position_mm, None),
                ElementSpec::Mirror(MirrorSpec {
                    position_mm,
                    normal,
                    ..
                }) => (*position_mm, Some(*normal)),
            };
            (el.name().to_string(), v3(position), mirror)
        })
        .collect();
    let illumination: Vec<String> = place
        .iter()
        .filter(|(_, p, _)| along_line(*p, DVec3::ZERO, -d).is_some())
        .map(|(n, _, _)| n.clone())
        .collect();
    let mut arms: [Vec<String>; 2] = [Vec::new(), Vec::new()];
    let mut last_folds: [Option<Fold>; 2] = [None, None];
    for (k, arm) in arms.iter_mut().enumerate() {
        let (mut o, mut dir) = (DVec3::ZERO, reflect(d, normals[k]));
        for _ in 0..=MAX_FOLDS {
            let mut on: Vec<(f64, usize)> = place
                .iter()
                .enumerate()
                .filter(|(_, (n, _, _))| !arm.contains(n))
                .filter_map(|(i, (_, p, _))| along_line(*p, o, dir).map(|s| (s, i)))
                .collect();
            on.sort_by(|a, b| a.0.total_cmp(&b.0));
            let fold = on.iter().find(|(_, i)| place[*i].2.is_some()).copied();
            let end = fold.map_or(f64::INFINITY, |f| f.0);
            arm.extend(
                on.iter()
                    .filter(|(s, _)| *s <= end)
                    .map(|(_, i)| place[*i].0.clone()),
            );
            let Some((_, i)) = fold else { break };
            let normal = place[i].2.map(|n| unit(n, path)).transpose()?;
            let normal = normal.unwrap_or(DVec3::Z);
            last_folds[k] = Some(Fold {
                name: place[i].0.clone(),
                position: place[i].1,
                incoming: dir,
                normal,
            });
            (o, dir) = (place[i].1, reflect(dir, normal));
        }
    }
    for (name, _, _) in &place {
        let on = usize::from(illumination.contains(name))
            + arms.iter().filter(|a| a.contains(name)).count();
        if on > 1 {
            return Err(Error::field(
                path,
                format!(
                    "`{name}` lies on more than one chief line (the illumination's, the arms'): \
                     this bench cannot be turned as a whole; move its parts one by one"
                ),
            ));
        }
    }
    Ok(Groups {
        illumination,
        arms,
        last_folds,
    })
}

/// Turns the illumination by `deg` about the DMD's centre: the lamp (its field-sampling target
/// with it) and the illumination's elements rigidly, about the mirrors' hinge or the in-plane
/// axis across it; a tracked turn also turns each arm by the smallest rotation that carries its
/// state's specular direction to the new one, so the arms stay on the geometric reflection of
/// the incoming chief ray (the diodes as one mount where both arms are folded: [`track_arms`]).
pub(super) fn apply_turn(file: &mut BenchFile, turn: Turn, deg: f64, path: &str) -> Result<()> {
    // The range of every orientation angle of a bench file (±360°).
    crate::scene::numbers::DirectionDeg::try_from(deg).map_err(|m| Error::field(path, m))?;
    let Some(dmd) = file.dmd.as_ref() else {
        return Err(Error::field(
            path,
            "turns the illumination about the DMD's centre: this bench has no `dmd`",
        ));
    };
    let (tilt, a) = (
        dmd.tilt_deg.0.to_radians(),
        dmd.tilt_axis_deg.0.to_radians(),
    );
    // The hinge as in optics::dmd: state + is a right-handed turn by the tilt about it.
    let hinge = DVec3::new(a.cos(), a.sin(), 0.0);
    let axis = if turn.across {
        hinge.cross(DVec3::Z)
    } else {
        hinge
    };
    let normals = [1.0, -1.0].map(|s| DMat3::from_axis_angle(hinge, s * tilt) * DVec3::Z);
    let lamp = v3(file.lamp.position_mm);
    if lamp.z <= 0.0 {
        return Err(Error::field(
            path,
            "turns the illumination about the DMD's centre: the lamp must stand in front of \
             the array (z > 0)",
        ));
    }
    let d = -lamp.normalize();
    let g = groups(file, d, normals, path)?;
    let q = DMat3::from_axis_angle(axis, deg.to_radians());
    turn_part(file, "lamp", q, path)?;
    if let Some(fs) = file.lamp.field_sampling.as_mut() {
        fs.center_mm = mm3(q * v3(fs.center_mm));
    }
    for name in &g.illumination {
        turn_part(file, name, q, path)?;
    }
    if turn.tracked {
        track_arms(file, &g, [d, q * d], normals, path)?;
    }
    Ok(())
}

/// The arms' part of a tracked turn (`d` the incoming chief direction before and after): each
/// arm's elements turn about the DMD's centre by the smallest rotation carrying its state's
/// specular direction to the new one. The two diodes are one instrument (a balanced detector,
/// its inputs side by side): when both arms end in a fold mirror, the pair moves as one rigid
/// mount, turned by the rotation half-way between the arms' (on a bench symmetric under the
/// exchange of the arms, a turn about the turn's own axis) and slid along its beams to keep the
/// diodes in focus, and each arm's last fold is re-aimed so its chief ray meets its diode as
/// before. An arm without a fold has nothing to
/// steer its beam with: then each diode turns with its own arm.
pub(super) fn track_arms(
    file: &mut BenchFile,
    g: &Groups,
    d: [DVec3; 2],
    normals: [DVec3; 2],
    path: &str,
) -> Result<()> {
    let r = [0, 1].map(|k| {
        glam::DQuat::from_rotation_arc(reflect(d[0], normals[k]), reflect(d[1], normals[k]))
    });
    for (k, names) in g.arms.iter().enumerate() {
        for name in names {
            turn_part(file, name, DMat3::from_quat(r[k]), path)?;
        }
    }
    let detectors = ["detectors.plus", "detectors.minus"];
    let [Some(fold_plus), Some(fold_minus)] = &g.last_folds else {
        for (k, detector) in detectors.iter().enumerate() {
            turn_part(file, detector, DMat3::from_quat(r[k]), path)?;
        }
        return Ok(());
    };
    let diodes = [
        v3(file.detectors.plus.position_mm),
        v3(file.detectors.minus.position_mm),
    ];
    let mount = r[0].slerp(r[1], 0.5);
    let folds = [fold_plus, fold_minus];
    let at = [0, 1].map(|k| r[k] * folds[k].position);
    // Refocus: the turned mount brings the diodes nearer the folds (by 9 mm at a 17.6° turn
    // across the hinge on the paper bench), so slide the pair along its beams' mean direction
    // until the folds' distances to the diodes are on average what they were: each diode stays
    // in its arm's image plane, as on a bench where the detector is moved, not only turned.
    let length = |a: DVec3, b: DVec3| (a - b).length();
    let before = [0, 1].map(|k| length(diodes[k], folds[k].position));
    let mut placed = diodes.map(|p| mount * p);
    let beam = [0, 1].map(|k| (placed[k] - at[k]).normalize());
    let slide = (beam[0] + beam[1]).normalize();
    for _ in 0..4 {
        let s = (0..2)
            .map(|k| {
                let b = (placed[k] - at[k]).normalize();
                (before[k] - length(placed[k], at[k])) / b.dot(slide)
            })
            .sum::<f64>()
            / 2.0;
        placed = placed.map(|p| p + s * slide);
    }
    let shift = placed[0] - mount * diodes[0];
    for detector in detectors {
        turn_part(file, detector, DMat3::from_quat(mount), path)?;
        let p = pose(file, detector, path)?;
        *p.position = mm3(v3(*p.position) + shift);
    }
    for (k, fold) in folds.into_iter().enumerate() {
        // The chief ray turned with the arm leaves the fold towards where the diode would be,
        // turned with the arm; turn it further, about the fold, by the rotation that carries
        // that point onto where the mount put the diode: any offset from the diode's centre
        // (a built-in misalignment) is kept, to first order.
        let (incoming, normal) = (r[k] * fold.incoming, r[k] * fold.normal);
        let steer = glam::DQuat::from_rotation_arc(
            (r[k] * diodes[k] - at[k]).normalize(),
            (placed[k] - at[k]).normalize(),
        );
        let outgoing = steer * reflect(incoming, normal);
        let mut aimed = (incoming - outgoing).normalize();
        if aimed.dot(normal) < 0.0 {
            aimed = -aimed;
        }
        let tilt = DMat3::from_quat(glam::DQuat::from_rotation_arc(normal, aimed));
        rotate_part(file, &fold.name, tilt, false, path)?;
    }
    Ok(())
}

/// Turns a part rigidly by `q` about the DMD's centre (the origin): its position, its axis and
/// its in-plane orientation.
pub(super) fn turn_part(file: &mut BenchFile, target: &str, q: DMat3, path: &str) -> Result<()> {
    rotate_part(file, target, q, true, path)
}

/// Turns a part's orientation (its axis and in-plane orientation) by `q`, and its position
/// about the DMD's centre too when `about_centre` (else about the part's own position).
pub(super) fn rotate_part(
    file: &mut BenchFile,
    target: &str,
    q: DMat3,
    about_centre: bool,
    path: &str,
) -> Result<()> {
    let p = pose(file, target, path)?;
    let w = unit(*p.axis, path)?;
    let hint = match p.x_axis.as_deref() {
        Some(Some(d)) => Some(unit(*d, path)?),
        _ => None,
    };
    let f = Frame::new(DVec3::ZERO, w, hint);
    let vec = |v: DVec3| Direction::Vector(mm3(v));
    if about_centre {
        *p.position = mm3(q * v3(*p.position));
    }
    *p.axis = vec(q * f.w);
    if let Some(x) = p.x_axis {
        *x = Some(vec(q * f.u));
    }
    Ok(())
}
