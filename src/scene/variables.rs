//! Bench variables: any numeric field of a bench file named by a path, and the rigid-body moves
//! a tolerance table speaks in.
//!
//! **Field paths** are `ELEMENT.FIELD[.COMPONENT]`, in the field's own units as written in the
//! file (millimetres, degrees, nanometres, …):
//! - ELEMENT is an element's `name`, or a section: `lamp`, `dmd`, `detectors.plus`,
//!   `detectors.minus`, `electronics`, `run`;
//! - FIELD is a field of it, nested as deep as the file nests (`lamp.field_sampling.probability`,
//!   `dmd.pattern.units_across`); an enum's variant is passed through (`lamp.filament.width_mm`
//!   reaches the `Rect` filament's width; `lamp.axis.theta_deg` a polar direction's angle);
//! - COMPONENT is `x|y|z` (or `0|1|2`) for a vector and `0|1` for a pair.
//!
//! Examples: `detectors.minus.position_mm.x`, `arm_minus_lens.tilt_deg.0`, `dmd.tilt_deg`.
//!
//! **Rigid-body moves** are relative to the bench they are applied to, in the part's own frame
//! (the frame its axis or normal and its `x_axis` define, before its alignment `tilt_deg`):
//! - `ELEMENT.decenter_mm.x|y`: along the part's own x or y axis (perpendicular to its axis or
//!   normal);
//! - `ELEMENT.despace_mm`: along its axis or normal, in the direction written in the file (a
//!   lens's axis is the direction of light travel; a mirror's or a diode's normal points out of
//!   its face, toward the light);
//! - `ELEMENT.tilt_deg.x|y`: a rotation about its own x or y axis through its position.
//!
//! Every element, the lamp and both detectors accept moves. The DMD defines the bench frame and
//! does not move: tilt its mirrors with `dmd.tilt_deg` instead.
//!
//! Setting goes through the bench file's own deserialiser, so a value outside a field's valid
//! range is refused with the same rule as in a file, and the bench built from the result is
//! validated as a whole like any other.

use glam::{DMat3, DVec3};
use serde_json::Value;

use crate::checked::shown;
use crate::error::{Error, Result};
use crate::optics::geometry::Frame;
use crate::scene::bench::{
    ApertureSpec, BaffleSpec, BenchFile, ChartSpec, Direction, ElementSpec, FilterSpec, LensSpec,
    MirrorSpec, Mm3, TubeSpec,
};

/// The top-level sections that a path may start with (besides element names).
const SECTIONS: [&str; 5] = ["lamp", "dmd", "detectors", "electronics", "run"];

/// Top-level scalar fields that a path may name alone.
const TOP_FIELDS: [&str; 2] = ["band_nm", "max_interactions"];

/// A rigid-body move of a part, in its own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Move {
    /// Along the part's own x (0) or y (1) axis (mm).
    Decenter(usize),
    /// Along its axis or normal (mm).
    Despace,
    /// About its own x (0) or y (1) axis (degrees).
    Tilt(usize),
}

/// The value of a numeric bench variable (a field path; a rigid-body move reads 0, since moves
/// are relative to the bench they are applied to).
pub fn get(file: &BenchFile, path: &str) -> Result<f64> {
    if let Some(turn) = parse_turn(path) {
        // Check that the bench can be turned (a DMD, parts on one chief line only).
        apply_turn(&mut file.clone(), turn, 0.0, path)?;
        return Ok(0.0);
    }
    if let Some((target, mv)) = parse_move(path)? {
        // Check that the part exists and can move.
        let _ = (pose(&mut file.clone(), &target, path)?, mv);
        return Ok(0.0);
    }
    let root = to_value(file)?;
    let leaf = walk_ref(&root, path).map_err(|m| bad_path(file, path, m))?;
    leaf.as_f64()
        .ok_or_else(|| bad_path(file, path, "names a field that is not a number".into()))
}

/// Sets a numeric bench variable: a field path to `value` in the field's units, or a rigid-body
/// move by `value` (mm or degrees). Errors (an unknown path, a value outside the field's valid
/// range) are input errors that name the path and list the valid paths near it.
pub fn set(file: &mut BenchFile, path: &str, value: f64) -> Result<()> {
    if !value.is_finite() {
        return Err(Error::field(
            path,
            format!(
                "a bench variable must be a finite number, got {}",
                shown(value)
            ),
        ));
    }
    if let Some(turn) = parse_turn(path) {
        return apply_turn(file, turn, value, path);
    }
    if let Some((target, mv)) = parse_move(path)? {
        return apply_move(file, &target, mv, value, path);
    }
    let mut root = to_value(file)?;
    let leaf = walk_mut(&mut root, path).map_err(|m| bad_path(file, path, m))?;
    *leaf = match &*leaf {
        Value::Number(n) if n.is_u64() || n.is_i64() => {
            if value.fract() != 0.0 {
                return Err(Error::field(
                    path,
                    format!("this field is a whole number, got {}", shown(value)),
                ));
            }
            if n.is_u64() && value < 0.0 {
                return Err(Error::field(
                    path,
                    format!("this field is a count (≥ 0), got {}", shown(value)),
                ));
            }
            if value.abs() > 9.0e15 {
                return Err(Error::field(
                    path,
                    format!("{} is too large for a whole-number field", shown(value)),
                ));
            }
            if n.is_u64() {
                Value::from(value as u64)
            } else {
                Value::from(value as i64)
            }
        }
        Value::Number(_) => Value::from(value),
        Value::Null => {
            return Err(bad_path(
                file,
                path,
                "names a field that is not set in this bench: write it in the bench file first"
                    .into(),
            ));
        }
        _ => {
            return Err(bad_path(
                file,
                path,
                "names a field that is not a number".into(),
            ));
        }
    };
    *file = serde_json::from_value::<BenchFile>(root).map_err(|e| {
        Error::field(
            path,
            format!("value {} refused: {}", shown(value), clean_serde(&e)),
        )
    })?;
    Ok(())
}

/// Every numeric field path of the bench, plus the rigid-body moves of its movable parts, in
/// file order.
pub fn list(file: &BenchFile) -> Vec<String> {
    let Ok(root) = to_value(file) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    if let Value::Object(top) = &root {
        for f in TOP_FIELDS {
            if let Some(v) = top.get(f) {
                leaves(v, f, &mut out);
            }
        }
        for s in SECTIONS {
            if s == "detectors" {
                for d in ["plus", "minus"] {
                    let base = format!("detectors.{d}");
                    if let Some(v) = top.get("detectors").and_then(|v| v.get(d)) {
                        leaves(v, &base, &mut out);
                        moves_of(&base, &mut out);
                    }
                }
            } else if let Some(v) = top.get(s) {
                leaves(v, s, &mut out);
                if s == "lamp" {
                    moves_of(s, &mut out);
                }
            }
        }
        if let Some(Value::Array(els)) = top.get("elements") {
            for el in els {
                if let Some((name, inner)) = element_parts(el) {
                    leaves(inner, &name, &mut out);
                    moves_of(&name, &mut out);
                }
            }
        }
    }
    if file.dmd.is_some() {
        for kind in ["turn_deg", "tracked_turn_deg"] {
            for axis in ["hinge", "across"] {
                out.push(format!("illumination.{kind}.{axis}"));
            }
        }
    }
    out
}

fn moves_of(base: &str, out: &mut Vec<String>) {
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

/// Numeric leaves under `v`, named from `base` (variant wrappers passed through, `name` and
/// strings skipped).
fn leaves(v: &Value, base: &str, out: &mut Vec<String>) {
    match v {
        Value::Number(_) => out.push(base.to_string()),
        Value::Array(a) => {
            let names: &[&str] = if a.len() == 3 { &["x", "y", "z"] } else { &[] };
            for (i, x) in a.iter().enumerate() {
                let c = names
                    .get(i)
                    .map_or_else(|| i.to_string(), |s| s.to_string());
                leaves(x, &format!("{base}.{c}"), out);
            }
        }
        Value::Object(m) => {
            if let Some(inner) = variant_inner(v) {
                leaves(inner, base, out);
                return;
            }
            for (k, x) in m {
                leaves(x, &format!("{base}.{k}"), out);
            }
        }
        _ => {}
    }
}

fn to_value(file: &BenchFile) -> Result<Value> {
    serde_json::to_value(file)
        .map_err(|e| Error::Numerical(format!("a bench could not be represented: {e}")))
}

fn clean_serde(e: &serde_json::Error) -> String {
    let s = e.to_string();
    // serde_json appends "at line 0 column 0" for values: meaningless here.
    match s.find(" at line ") {
        Some(k) => s[..k].to_string(),
        None => s,
    }
}

/// An externally tagged enum variant `{"Name": inner}`: its inner value.
fn variant_inner(v: &Value) -> Option<&Value> {
    match v {
        Value::Object(m) if m.len() == 1 => {
            let (k, inner) = m.iter().next()?;
            k.chars()
                .next()
                .is_some_and(|c| c.is_ascii_uppercase())
                .then_some(inner)
        }
        _ => None,
    }
}

fn variant_inner_mut(v: &mut Value) -> Option<&mut Value> {
    let is_variant = variant_inner(v).is_some();
    match v {
        Value::Object(m) if is_variant => m.values_mut().next(),
        _ => None,
    }
}

/// An element's name and its fields.
fn element_parts(el: &Value) -> Option<(String, &Value)> {
    let inner = variant_inner(el)?;
    let name = inner.get("name")?.as_str()?.to_string();
    Some((name, inner))
}

/// Splits a path into the part it addresses (a section, `detectors.plus|minus` or an element
/// name) and the rest.
fn split_target(path: &str) -> (String, Vec<&str>) {
    let segs: Vec<&str> = path.split('.').collect();
    if segs.len() >= 2 && segs[0] == "detectors" {
        return (format!("detectors.{}", segs[1]), segs[2..].to_vec());
    }
    (segs[0].to_string(), segs[1..].to_vec())
}

fn walk_ref<'v>(root: &'v Value, path: &str) -> std::result::Result<&'v Value, String> {
    let (target, rest) = split_target(path);
    let mut cur = find_target(root, &target)?;
    for seg in rest {
        if let Some(inner) = variant_inner(cur) {
            cur = inner;
        }
        cur = step(cur, seg)?;
    }
    if let Some(inner) = variant_inner(cur) {
        cur = inner;
    }
    Ok(cur)
}

fn walk_mut<'v>(root: &'v mut Value, path: &str) -> std::result::Result<&'v mut Value, String> {
    // Resolve with the immutable walk first (good messages), then follow the same steps.
    walk_ref(root, path)?;
    let (target, rest) = split_target(path);
    let mut cur = find_target_mut(root, &target).ok_or("unknown part")?;
    for seg in rest {
        if variant_inner(cur).is_some() {
            cur = variant_inner_mut(cur).ok_or("unreachable")?;
        }
        let idx = index_of(cur, seg)?;
        cur = match (cur, idx) {
            (Value::Object(m), Key::Field) => m.get_mut(seg).ok_or("unknown field")?,
            (Value::Array(a), Key::Index(i)) => a.get_mut(i).ok_or("no such component")?,
            _ => return Err("unreachable".into()),
        };
    }
    if variant_inner(cur).is_some() {
        cur = variant_inner_mut(cur).ok_or("unreachable")?;
    }
    Ok(cur)
}

enum Key {
    Field,
    Index(usize),
}

fn index_of(cur: &Value, seg: &str) -> std::result::Result<Key, String> {
    match cur {
        Value::Object(m) => {
            if m.contains_key(seg) {
                Ok(Key::Field)
            } else {
                Err(format!("has no field `{seg}`"))
            }
        }
        Value::Array(a) => {
            let i = match seg {
                "x" => 0,
                "y" => 1,
                "z" => 2,
                s => s
                    .parse::<usize>()
                    .map_err(|_| format!("`{seg}` is not a component (x, y, z or an index)"))?,
            };
            if i < a.len() {
                Ok(Key::Index(i))
            } else {
                Err(format!(
                    "component `{seg}` is out of range: the value has {} components",
                    a.len()
                ))
            }
        }
        Value::Null => Err(format!(
            "reaches a field that is not set in this bench before `{seg}`: write it in the \
             bench file first"
        )),
        _ => Err(format!("reaches a plain value before `{seg}`")),
    }
}

fn step<'v>(cur: &'v Value, seg: &str) -> std::result::Result<&'v Value, String> {
    match (cur, index_of(cur, seg)?) {
        (Value::Object(m), Key::Field) => m.get(seg).ok_or_else(|| "unknown field".into()),
        (Value::Array(a), Key::Index(i)) => a.get(i).ok_or_else(|| "no such component".into()),
        _ => Err("unreachable".into()),
    }
}

fn find_target<'v>(root: &'v Value, target: &str) -> std::result::Result<&'v Value, String> {
    if let Some(rest) = target.strip_prefix("detectors.") {
        return root
            .get("detectors")
            .and_then(|d| d.get(rest))
            .ok_or_else(|| format!("`{target}`: the detectors are `plus` and `minus`"));
    }
    if SECTIONS.contains(&target) || TOP_FIELDS.contains(&target) {
        return match root.get(target) {
            Some(Value::Null) | None => Err(format!("this bench has no `{target}` section")),
            Some(v) => Ok(v),
        };
    }
    if let Some(Value::Array(els)) = root.get("elements") {
        for el in els {
            if let Some((name, inner)) = element_parts(el)
                && name == target
            {
                return Ok(inner);
            }
        }
    }
    Err(format!("no element or section named `{target}`"))
}

fn find_target_mut<'v>(root: &'v mut Value, target: &str) -> Option<&'v mut Value> {
    if let Some(rest) = target.strip_prefix("detectors.") {
        return root.get_mut("detectors")?.get_mut(rest);
    }
    if SECTIONS.contains(&target) || TOP_FIELDS.contains(&target) {
        return root.get_mut(target);
    }
    let Some(Value::Array(els)) = root.get_mut("elements") else {
        return None;
    };
    els.iter_mut()
        .filter_map(variant_inner_mut)
        .find(|inner| inner.get("name").and_then(Value::as_str) == Some(target))
}

/// An input error for a bad path: the reason and the valid paths nearest to it.
fn bad_path(file: &BenchFile, path: &str, why: String) -> Error {
    let all = list(file);
    let (target, _) = split_target(path);
    let mut near: Vec<&String> = all
        .iter()
        .filter(|p| p.starts_with(&format!("{target}.")) || p.as_str() == target)
        .collect();
    let hint = if near.is_empty() {
        let mut parts: Vec<String> = SECTIONS
            .iter()
            .filter(|s| **s != "detectors")
            .map(|s| s.to_string())
            .collect();
        parts.extend(["detectors.plus".to_string(), "detectors.minus".to_string()]);
        if let Ok(Value::Array(els)) = to_value(file).map(|v| v["elements"].clone()) {
            parts.extend(els.iter().filter_map(|e| element_parts(e).map(|p| p.0)));
        }
        format!("the parts of this bench are {}", parts.join(", "))
    } else {
        near.sort_by_key(|p| distance(p, path));
        near.truncate(12);
        format!(
            "valid paths near it: {}",
            near.iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    Error::field(path, format!("bench variable `{path}` {why}; {hint}"))
}

/// Levenshtein distance, for ordering suggestions.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

// ---------------------------------------------------------------------------------------------
// Rigid-body moves.

/// `ELEMENT.decenter_mm.x` → (ELEMENT, Decenter(0)); field paths → None.
fn parse_move(path: &str) -> Result<Option<(String, Move)>> {
    let (target, rest) = split_target(path);
    let mv = match rest.as_slice() {
        ["decenter_mm", c] => Move::Decenter(axis_index(c, path)?),
        ["despace_mm"] => Move::Despace,
        ["tilt_deg", c @ ("x" | "y")] => Move::Tilt(axis_index(c, path)?),
        _ => return Ok(None),
    };
    Ok(Some((target, mv)))
}

fn axis_index(c: &str, path: &str) -> Result<usize> {
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
struct Pose<'a> {
    position: &'a mut Mm3,
    axis: &'a mut Direction,
    x_axis: Option<&'a mut Option<Direction>>,
}

fn pose<'a>(file: &'a mut BenchFile, target: &str, path: &str) -> Result<Pose<'a>> {
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

fn unit(d: Direction, path: &str) -> Result<DVec3> {
    d.to_unit().map_err(|m| Error::field(path, m))
}

fn apply_move(file: &mut BenchFile, target: &str, mv: Move, value: f64, path: &str) -> Result<()> {
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

// ---------------------------------------------------------------------------------------------
// Turns of the illumination about the DMD's centre (docs/dmd_diffraction.md, "Blaze matching").

/// How far (mm) a part's position may lie from a chief line and still count as on it.
const ON_LINE_MM: f64 = 5.0;

/// The most fold mirrors an arm's chief line follows.
const MAX_FOLDS: usize = 4;

/// A turn of the illumination: about the mirrors' hinge or about the in-plane axis across it,
/// with the arms left in place or following their states' specular directions.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Turn {
    across: bool,
    tracked: bool,
}

/// `illumination.turn_deg.hinge|across`, `illumination.tracked_turn_deg.hinge|across`; None
/// for any other path (an unknown `illumination.…` path then fails as an unknown part, with
/// these paths among the suggestions, since [`list`] holds them).
fn parse_turn(path: &str) -> Option<Turn> {
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

fn v3(p: Mm3) -> DVec3 {
    DVec3::new(p.0, p.1, p.2)
}

fn mm3(v: DVec3) -> Mm3 {
    Mm3(v.x, v.y, v.z)
}

/// The mirror reflection of direction `d` off a surface of unit normal `n`.
fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// The distance along `dir` from `o` of the point of the line nearest `p`, when `p` lies ahead
/// of `o` and within [`ON_LINE_MM`] of the line.
fn along_line(p: DVec3, o: DVec3, dir: DVec3) -> Option<f64> {
    let s = (p - o).dot(dir);
    let off = (p - o - s * dir).length();
    (s > 1e-6 && off <= ON_LINE_MM).then_some(s)
}

/// The parts a turn moves: the illumination's elements (on the half-line from the DMD's centre
/// through the lamp) and each arm's (on its chief line: from the DMD's centre along its state's
/// specular reflection of the incoming chief direction `d`, folded by each mirror met on it).
struct Groups {
    illumination: Vec<String>,
    arms: [Vec<String>; 2],
    /// Each arm's last fold mirror met by its chief line, with the chief direction arriving
    /// there and the fold's unit normal.
    last_folds: [Option<Fold>; 2],
}

/// A fold mirror on an arm's chief line.
struct Fold {
    name: String,
    position: DVec3,
    incoming: DVec3,
    normal: DVec3,
}

fn groups(file: &BenchFile, d: DVec3, normals: [DVec3; 2], path: &str) -> Result<Groups> {
    let place: Vec<(String, DVec3, Option<Direction>)> = file
        .elements
        .iter()
        .map(|el| {
            let (position, mirror) = match el {
                ElementSpec::Lens(LensSpec { position_mm, .. })
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
fn apply_turn(file: &mut BenchFile, turn: Turn, deg: f64, path: &str) -> Result<()> {
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
fn track_arms(
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
fn turn_part(file: &mut BenchFile, target: &str, q: DMat3, path: &str) -> Result<()> {
    rotate_part(file, target, q, true, path)
}

/// Turns a part's orientation (its axis and in-plane orientation) by `q`, and its position
/// about the DMD's centre too when `about_centre` (else about the part's own position).
fn rotate_part(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::bench::BenchFile;
    use std::path::Path;

    fn paper() -> BenchFile {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
        let text = std::fs::read_to_string(&path).unwrap();
        crate::scene::parse_ron(&text, &path).unwrap()
    }

    #[test]
    fn field_paths_get_and_set() {
        let mut f = paper();
        let x = get(&f, "detectors.minus.position_mm.x").unwrap();
        set(&mut f, "detectors.minus.position_mm.x", x + 1.5).unwrap();
        assert_eq!(f.detectors.minus.position_mm.0, x + 1.5);
        assert_eq!(get(&f, "detectors.minus.position_mm.x").unwrap(), x + 1.5);
        set(&mut f, "dmd.tilt_deg", 11.0).unwrap();
        assert_eq!(f.dmd.as_ref().unwrap().tilt_deg.0, 11.0);
        // An integer field takes whole numbers only.
        set(&mut f, "dmd.pattern.units_across", 32.0).unwrap();
        assert_eq!(f.dmd.as_ref().unwrap().pattern.units_across.get(), 32);
        assert!(set(&mut f, "dmd.pattern.units_across", 32.5).is_err());
    }

    #[test]
    fn every_listed_path_reads() {
        let f = paper();
        let all = list(&f);
        assert!(all.len() > 50, "{}", all.len());
        for p in &all {
            get(&f, p).unwrap_or_else(|e| panic!("{p}: {e}"));
        }
        assert!(all.iter().any(|p| p == "detectors.minus.despace_mm"));
    }

    #[test]
    fn bad_paths_and_values_are_input_errors_naming_the_path() {
        let mut f = paper();
        let e = set(&mut f, "detectors.minus.positon_mm.x", 1.0).unwrap_err();
        let s = e.to_string();
        assert!(e.is_user_error());
        assert!(
            s.contains("positon_mm") && s.contains("detectors.minus.position_mm.x"),
            "{s}"
        );
        let e = set(&mut f, "no_such_lens.position_mm.x", 1.0).unwrap_err();
        assert!(e.to_string().contains("detectors.plus"), "{e}");
        // Outside the field's valid range: refused by the file's own rule.
        let e = set(&mut f, "dmd.tilt_deg", -3.0).unwrap_err();
        assert!(e.to_string().contains("positive"), "{e}");
        assert!(set(&mut f, "dmd.tilt_deg", f64::NAN).is_err());
        assert!(set(&mut f, "dmd.decenter_mm.x", 1.0).is_err());
    }

    #[test]
    fn moves_are_rigid_and_in_the_parts_frame() {
        let f0 = paper();
        let mut f = f0.clone();
        let d0 = f0.detectors.minus.clone();
        set(&mut f, "detectors.minus.despace_mm", 2.0).unwrap();
        let n = d0.normal.to_unit().unwrap();
        let p = f.detectors.minus.position_mm;
        let moved = DVec3::new(
            p.0 - d0.position_mm.0,
            p.1 - d0.position_mm.1,
            p.2 - d0.position_mm.2,
        );
        assert!((moved - 2.0 * n).length() < 1e-12, "{moved:?}");
        // A decentre is perpendicular to the normal and 1 mm long.
        let mut g = f0.clone();
        set(&mut g, "detectors.minus.decenter_mm.y", 1.0).unwrap();
        let p = g.detectors.minus.position_mm;
        let moved = DVec3::new(
            p.0 - d0.position_mm.0,
            p.1 - d0.position_mm.1,
            p.2 - d0.position_mm.2,
        );
        assert!((moved.length() - 1.0).abs() < 1e-12 && moved.dot(n).abs() < 1e-12);
        // A tilt turns the normal by the angle, about an axis perpendicular to it.
        let mut h = f0.clone();
        set(&mut h, "detectors.minus.tilt_deg.x", 3.0).unwrap();
        let n2 = h.detectors.minus.normal.to_unit().unwrap();
        assert!((n.dot(n2).acos().to_degrees() - 3.0).abs() < 1e-9);
        assert_eq!(h.detectors.minus.position_mm, d0.position_mm);
        // Moves read as 0 and zero moves change nothing.
        assert_eq!(get(&h, "detectors.minus.tilt_deg.x").unwrap(), 0.0);
        let mut z = f0.clone();
        set(&mut z, "detectors.minus.decenter_mm.x", 0.0).unwrap();
        assert_eq!(z.detectors.minus.position_mm, d0.position_mm);
    }

    fn element_position(f: &BenchFile, name: &str) -> DVec3 {
        let el = f.elements.iter().find(|e| e.name() == name).unwrap();
        match el {
            ElementSpec::Lens(LensSpec { position_mm, .. })
            | ElementSpec::Mirror(MirrorSpec { position_mm, .. })
            | ElementSpec::Chart(ChartSpec { position_mm, .. }) => v3(*position_mm),
            _ => panic!("{name}"),
        }
    }

    #[test]
    fn turns_find_the_illumination_and_the_arms_of_the_paper_bench() {
        let f = paper();
        let g = groups(
            &f,
            DVec3::NEG_Z,
            [1.0, -1.0].map(|s| {
                DMat3::from_axis_angle(
                    DVec3::new(1.0, 1.0, 0.0).normalize(),
                    s * 12f64.to_radians(),
                ) * DVec3::Z
            }),
            "t",
        )
        .unwrap();
        let mut ill = g.illumination.clone();
        ill.sort();
        assert_eq!(
            ill,
            [
                "chart",
                "collimator",
                "field_stop",
                "imaging_iris",
                "imaging_lens",
                "imaging_lens_tube",
                "lamp_tube",
                "nd_od1",
                "nd_od2"
            ]
        );
        assert_eq!(g.arms[0], ["arm_plus_lens", "arm_plus_fold"]);
        assert_eq!(g.arms[1], ["arm_minus_lens", "arm_minus_fold"]);
        let all = list(&f);
        for p in [
            "illumination.turn_deg.hinge",
            "illumination.tracked_turn_deg.across",
        ] {
            assert!(all.iter().any(|x| x == p), "{p}");
            assert_eq!(get(&f, p).unwrap(), 0.0);
        }
        let mut no_dmd = f.clone();
        no_dmd.dmd = None;
        let e = set(&mut no_dmd, "illumination.turn_deg.across", 3.0).unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("no `dmd`"),
            "{e}"
        );
        let e = set(&mut f.clone(), "illumination.turn_deg.sideways", 3.0).unwrap_err();
        assert!(
            e.to_string().contains("illumination.turn_deg.across"),
            "{e}"
        );
    }

    /// A tracked turn keeps each arm on its state's specular reflection of the incoming chief
    /// direction; a plain turn leaves the arms where they were. Both turn the illumination
    /// rigidly by the angle.
    #[test]
    fn tracked_turns_keep_the_arms_on_the_specular_directions() {
        let f0 = paper();
        let hinge = DVec3::new(1.0, 1.0, 0.0).normalize();
        let n =
            [1.0, -1.0].map(|s| DMat3::from_axis_angle(hinge, s * 12f64.to_radians()) * DVec3::Z);
        let off = |f: &BenchFile, k: usize, name: &str| {
            let d = -v3(f.lamp.position_mm).normalize();
            let u = reflect(d, n[k]);
            // sin of the angle (acos near 1 would lose the small offsets)
            element_position(f, name).normalize().cross(u).length()
        };
        let names = ["arm_plus_lens", "arm_minus_lens"];
        for across in ["across", "hinge"] {
            let mut f = f0.clone();
            set(
                &mut f,
                &format!("illumination.tracked_turn_deg.{across}"),
                10.0,
            )
            .unwrap();
            let (a, b) = (v3(f0.lamp.position_mm), v3(f.lamp.position_mm));
            assert!((a.angle_between(b).to_degrees() - 10.0).abs() < 1e-9);
            assert!((a.length() - b.length()).abs() < 1e-9);
            let (c0, c1) = (
                element_position(&f0, "chart"),
                element_position(&f, "chart"),
            );
            assert!(
                (c0.angle_between(c1).to_degrees() - 10.0).abs() < 1e-9,
                "{across}"
            );
            for (k, name) in names.iter().enumerate() {
                // The − arm lens sits 0.3 mm off its line by design: the offset is kept.
                assert!(
                    (off(&f, k, name) - off(&f0, k, name)).abs() < 1e-9,
                    "{across} {name}"
                );
            }
            let mut g = f0.clone();
            set(&mut g, &format!("illumination.turn_deg.{across}"), 10.0).unwrap();
            for name in names {
                assert_eq!(element_position(&g, name), element_position(&f0, name));
            }
            assert_eq!(g.lamp.position_mm, f.lamp.position_mm);
        }
        // Across the hinge the incidence on both facets stays the same (the blaze is symmetric).
        let mut f = f0.clone();
        set(&mut f, "illumination.turn_deg.across", 10.0).unwrap();
        let d = -v3(f.lamp.position_mm).normalize();
        assert!((d.dot(n[0]) - d.dot(n[1])).abs() < 1e-12);
        assert!(
            (d.dot(n[0]).abs() - 10f64.to_radians().cos() * 12f64.to_radians().cos()).abs() < 1e-12
        );
    }

    /// Where an arm's chief line (from the DMD's centre along its state's specular direction,
    /// folded by the arm's fold mirror as written in the file) meets its diode's plane, from
    /// the diode's centre (mm).
    fn chief_ray_offset(f: &BenchFile, k: usize) -> DVec3 {
        let hinge = DVec3::new(1.0, 1.0, 0.0).normalize();
        let s = [1.0, -1.0][k];
        let n = DMat3::from_axis_angle(hinge, s * 12f64.to_radians()) * DVec3::Z;
        let u = reflect(-v3(f.lamp.position_mm).normalize(), n);
        let fold = ["arm_plus_fold", "arm_minus_fold"][k];
        let Some(ElementSpec::Mirror(MirrorSpec {
            position_mm,
            normal,
            ..
        })) = f.elements.iter().find(|e| e.name() == fold)
        else {
            panic!("{fold}")
        };
        let (p, m) = (v3(*position_mm), unit(*normal, "t").unwrap());
        let hit = u * (p.dot(m) / u.dot(m));
        let out = reflect(u, m);
        let det = [&f.detectors.plus, &f.detectors.minus][k];
        let (c, w) = (v3(det.position_mm), unit(det.normal, "t").unwrap());
        hit + out * ((c - hit).dot(w) / out.dot(w)) - c
    }

    /// The balanced detector's two diodes move as one rigid mount under a tracked turn, and
    /// each arm's re-aimed fold still brings its chief ray onto its diode (the − arm's built-in
    /// offset kept): at 18° across the hinge, where turning each diode with its own arm would
    /// make them overlap.
    #[test]
    fn tracked_turns_move_the_detector_pair_as_one_mount() {
        let f0 = paper();
        let pair = |f: &BenchFile| {
            let (a, b) = (&f.detectors.plus, &f.detectors.minus);
            let (na, nb) = (unit(a.normal, "t").unwrap(), unit(b.normal, "t").unwrap());
            (
                v3(a.position_mm).distance(v3(b.position_mm)),
                na.angle_between(nb),
            )
        };
        for across in ["across", "hinge"] {
            let mut f = f0.clone();
            let turn = if across == "across" { 18.0 } else { 2.0 };
            set(
                &mut f,
                &format!("illumination.tracked_turn_deg.{across}"),
                turn,
            )
            .unwrap();
            let (s0, s1) = (pair(&f0), pair(&f));
            assert!((s0.0 - s1.0).abs() < 1e-9 && (s0.1 - s1.1).abs() < 1e-12);
            for k in 0..2 {
                let (o0, o1) = (chief_ray_offset(&f0, k), chief_ray_offset(&f, k));
                assert!(
                    (o0.length() - o1.length()).abs() < 0.05,
                    "{across} {k}: {o0} {o1}"
                );
            }
            assert!(chief_ray_offset(&f, 0).length() < 0.05);
            // In focus: each fold's distance to its diode kept (to 0.2 mm: the pair is rigid,
            // the two distances are matched on average).
            for (fold, det) in [
                ("arm_plus_fold", [&f0.detectors.plus, &f.detectors.plus]),
                ("arm_minus_fold", [&f0.detectors.minus, &f.detectors.minus]),
            ] {
                let l0 = element_position(&f0, fold).distance(v3(det[0].position_mm));
                let l1 = element_position(&f, fold).distance(v3(det[1].position_mm));
                assert!((l0 - l1).abs() < 0.2, "{across} {fold}: {l0} {l1}");
            }
        }
        // Across the hinge the pair turns about the turn's own axis (the bench is symmetric
        // under the exchange of the arms; the refocusing slide stays in the symmetry plane), by
        // about the turn (0.915 of it, and the slide moves the pair's midpoint a little further).
        let mut f = f0.clone();
        set(&mut f, "illumination.tracked_turn_deg.across", 18.0).unwrap();
        let mid =
            |f: &BenchFile| v3(f.detectors.plus.position_mm) + v3(f.detectors.minus.position_mm);
        let (m0, m1) = (mid(&f0), mid(&f));
        let axis = m0.cross(m1).normalize();
        assert!(
            axis.dot(DVec3::new(1.0, -1.0, 0.0).normalize()).abs() > 0.999,
            "{axis}"
        );
        let angle = m0.angle_between(m1).to_degrees();
        assert!(angle > 15.0 && angle < 20.0, "{angle}");
    }
}
