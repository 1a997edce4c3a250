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
//!
//! The module's files: `paths.rs` (field paths), `moves.rs` (rigid-body moves), `turns.rs`
//! (turns of the illumination).

mod moves;
mod paths;
#[cfg(test)]
mod tests;
mod turns;

use serde_json::Value;

use crate::checked::shown;
use crate::error::{Error, Result};
use crate::scene::bench::BenchFile;

use moves::{apply_move, moves_of, parse_move, pose};
use paths::{bad_path, clean_serde, element_parts, leaves, to_value, walk_mut, walk_ref};
use turns::{apply_turn, parse_turn};

/// The top-level sections that a path may start with (besides element names).
const SECTIONS: [&str; 5] = ["lamp", "dmd", "detectors", "electronics", "run"];

/// Top-level scalar fields that a path may name alone.
const TOP_FIELDS: [&str; 2] = ["band_nm", "max_interactions"];

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
