//! Rigid-body moves of a part in its own frame: `ELEMENT.decenter_mm.x|y`, `ELEMENT.despace_mm`
//! and `ELEMENT.tilt_deg.x|y`.

use glam::{DMat3, DVec3};

use super::paths::{bad_path, split_target};
use crate::error::{Error, Result};
use crate::optics::geometry::Frame;
use crate::scene::bench::{
    ApertureSpec, BaffleSpec, BenchFile, ChartSpec, Direction, ElementSpec, FilterSpec, LensSpec,
    LensSystemSpec, MirrorSpec, Mm3, TubeSpec,
};

/// A rigid-body move of a part, in its own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Move {
    /// Along the part's own x (0) or y (1) axis (mm).
    Decenter(usize),
    /// Along its axis or normal (mm).
    Despace,
    /// About its own x (0) or y (1) axis (degrees).
    Tilt(usize),
}

pub(super) fn moves_of(base: &str, out: &mut Vec<String>) {
    for m in [
        "decenter_mm.x",
        "decenter_mm.y",
        "despace_mm",
        "tilt_deg.x",
        "tilt_deg.y",
    ] {
        out.push(format!("{base}.{m}"));
    }
}

/// `ELEMENT.decenter_mm.x` → (ELEMENT, Decenter(0)); field paths → None.
pub(super) fn parse_move(path: &str) -> Result<Option<(String, Move)>> {
    let (target, rest) = split_target(path);
    let mv = match rest.as_slice() {
        ["decenter_mm", c] => Move::Decenter(axis_index(c, path)?),
        ["despace_mm"] => Move::Despace,
        ["tilt_deg", c @ ("x" | "y")] => Move::Tilt(axis_index(c, path)?),
        _ => return Ok(None),
    };
    Ok(Some((target, mv)))
}

pub(super) fn axis_index(c: &str, path: &str) -> Result<usize> {
    match c {
        "x" => Ok(0),
        "y" => Ok(1),
        _ => Err(Error::field(
            path,
            format!("a move's component is x or y (in the part's own frame), got `{c}`"),
        )),
    }
}

/// The pose fields of a movable part.
pub(super) struct Pose<'a> {
    pub(super) position: &'a mut Mm3,
    pub(super) axis: &'a mut Direction,
    pub(super) x_axis: Option<&'a mut Option<Direction>>,
}

pub(super) fn pose<'a>(file: &'a mut BenchFile, target: &str, path: &str) -> Result<Pose<'a>> {
    let p = match target {
        "lamp" => Pose {
            position: &mut file.lamp.position_mm,
            axis: &mut file.lamp.axis,
            x_axis: Some(&mut file.lamp.x_axis),
        },
        "detectors.plus" | "detectors.minus" => {
            let d = if target.ends_with("plus") {
                &mut file.detectors.plus
            } else {
                &mut file.detectors.minus
            };
            Pose {
                position: &mut d.position_mm,
                axis: &mut d.normal,
                x_axis: None,
            }
        }
        "dmd" => {
            return Err(Error::field(
                path,
                "the DMD defines the bench frame and does not move: tilt its mirrors with \
                 `dmd.tilt_deg`, or move the other parts",
            ));
        }
        name => {
            let Some(i) = file.elements.iter().position(|e| e.name() == name) else {
                return Err(bad_path(
                    file,
                    path,
                    format!("names no element or section `{name}`"),
                ));
            };
            let el = &mut file.elements[i];
            match el {
                ElementSpec::Lens(LensSpec {
                    position_mm, axis, ..
                })
                | ElementSpec::LensSystem(LensSystemSpec {
                    position_mm, axis, ..
                })
                | ElementSpec::Aperture(ApertureSpec {
                    position_mm, axis, ..
                })
                | ElementSpec::Tube(TubeSpec {
                    position_mm, axis, ..
                }) => Pose {
                    position: position_mm,
                    axis,
                    x_axis: None,
                },
                ElementSpec::Filter(FilterSpec {
                    position_mm,
                    axis,
                    x_axis,
                    ..
                })
                | ElementSpec::Baffle(BaffleSpec {
                    position_mm,
                    axis,
                    x_axis,
                    ..
                }) => Pose {
                    position: position_mm,
                    axis,
                    x_axis: Some(x_axis),
                },
                ElementSpec::Mirror(MirrorSpec {
                    position_mm,
                    normal,
                    x_axis,
                    ..
                })
                | ElementSpec::Chart(ChartSpec {
                    position_mm,
                    normal,
                    x_axis,
                    ..
                }) => Pose {
                    position: position_mm,
                    axis: normal,
                    x_axis: Some(x_axis),
                },
            }
        }
    };
    Ok(p)
}

pub(super) fn unit(d: Direction, path: &str) -> Result<DVec3> {
    d.to_unit().map_err(|m| Error::field(path, m))
}

pub(super) fn apply_move(
    file: &mut BenchFile,
    target: &str,
    mv: Move,
    value: f64,
    path: &str,
) -> Result<()> {
    let p = pose(file, target, path)?;
    let w = unit(*p.axis, path)?;
    let hint = match p.x_axis.as_deref() {
        Some(Some(d)) => Some(unit(*d, path)?),
        _ => None,
    };
    let f = Frame::new(DVec3::ZERO, w, hint);
    let along = |dir: DVec3, mm: f64, pos: &mut Mm3| {
        pos.0 += dir.x * mm;
        pos.1 += dir.y * mm;
        pos.2 += dir.z * mm;
    };
    match mv {
        Move::Decenter(i) => along(if i == 0 { f.u } else { f.v }, value, p.position),
        Move::Despace => along(f.w, value, p.position),
        Move::Tilt(i) => {
            // About the part's own x (u) or y (v) axis through its position: the axis turns,
            // and so does an explicit x_axis, so the part moves as a rigid body.
            let r = DMat3::from_axis_angle(if i == 0 { f.u } else { f.v }, value.to_radians());
            let vec = |v: DVec3| Direction::Vector(Mm3(v.x, v.y, v.z));
            *p.axis = vec(r * f.w);
            if let Some(x) = p.x_axis {
                // Keep the part's in-plane orientation: the turned u is the new x hint.
                *x = Some(vec(r * f.u));
            }
        }
    }
    Ok(())
}
