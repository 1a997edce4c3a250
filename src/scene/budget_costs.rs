//! Costs files of `spibench tolerance --budget --costs FILE`: what tightening each tolerance
//! costs, and how far its range may be scaled.
//!
//! ```ron
//! (
//!     // For every tolerance the file does not name (each field optional).
//!     default: (weight: 1.0, exponent: 1.0, min_scale: 0.01, max_scale: 1.0),
//!     tolerances: [
//!         // A precision mount: three times as dear to tighten, never looser than listed.
//!         (path: "detectors.minus.decenter_mm.x", weight: 3.0, max_scale: 1.0),
//!         (path: "lamp.despace_mm", max_scale: 2.0),
//!     ],
//! )
//! ```
//!
//! Tolerance i scaled by sᵢ (its range sᵢ × the tolerance file's) costs
//! `weight · sᵢ^(−exponent)`: the usual "tighter is dearer" rule (cost ∝ 1/s by default). The
//! search keeps sᵢ within `min_scale … max_scale`.

use std::path::Path;

use serde::Deserialize;

use crate::error::{Error, Result};
use crate::scene::numbers::{Positive, via};
use crate::scene::tolerance::ToleranceSet;

/// The cost rule and scale bounds of one tolerance.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ToleranceCost {
    pub weight: f64,
    pub exponent: f64,
    pub min_scale: f64,
    pub max_scale: f64,
}

impl Default for ToleranceCost {
    /// Cost 1/s, scales 0.01 … 1 (the file's ranges are the loosest the search tries).
    fn default() -> Self {
        ToleranceCost {
            weight: 1.0,
            exponent: 1.0,
            min_scale: 0.01,
            max_scale: 1.0,
        }
    }
}

impl ToleranceCost {
    /// The cost at scale `s`.
    pub fn cost(&self, s: f64) -> f64 {
        self.weight * s.powf(-self.exponent)
    }
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct CostSpec {
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    weight: Option<f64>,
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    exponent: Option<f64>,
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    min_scale: Option<f64>,
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    max_scale: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct EntrySpec {
    path: String,
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    weight: Option<f64>,
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    exponent: Option<f64>,
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    min_scale: Option<f64>,
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    max_scale: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct CostsFileSpec {
    #[serde(default)]
    default: CostSpec,
    #[serde(default)]
    tolerances: Vec<EntrySpec>,
}

/// The largest scale a costs file may allow (a range 100 × the tolerance file's).
pub const MAX_SCALE: f64 = 100.0;

/// One cost rule per tolerance of `set`, in its order: the defaults without a costs file.
pub fn default_costs(set: &ToleranceSet) -> Vec<ToleranceCost> {
    vec![ToleranceCost::default(); set.tolerances.len()]
}

/// Parses a costs file (`path` names it in errors) against the tolerance file: every path
/// must be one of its tolerances, named once, and every bound pair ordered.
pub fn parse_costs(text: &str, path: &Path, set: &ToleranceSet) -> Result<Vec<ToleranceCost>> {
    use crate::scene::locate;
    let spec: CostsFileSpec = crate::scene::parse_ron(text, path)?;
    let base = ToleranceCost::default();
    let d = ToleranceCost {
        weight: spec.default.weight.unwrap_or(base.weight),
        exponent: spec.default.exponent.unwrap_or(base.exponent),
        min_scale: spec.default.min_scale.unwrap_or(base.min_scale),
        max_scale: spec.default.max_scale.unwrap_or(base.max_scale),
    };
    let check = |c: &ToleranceCost, needle: Option<&str>, what: &str| -> Result<()> {
        if c.min_scale > c.max_scale || c.max_scale > MAX_SCALE {
            let e = Error::field(
                "max_scale",
                format!(
                    "{what}: the scales {} … {} are not an ordered range within (0, {MAX_SCALE}]",
                    c.min_scale, c.max_scale
                ),
            )
            .in_file(path);
            let pos = match needle {
                Some(n) => locate::string_literal(text, n),
                None => locate::first_key(text, "default"),
            };
            return Err(locate::at(e, text, pos));
        }
        Ok(())
    };
    check(&d, None, "the default")?;
    let mut out = vec![d; set.tolerances.len()];
    let mut seen = vec![false; set.tolerances.len()];
    for t in &spec.tolerances {
        let located = |msg: String| {
            let e = Error::field("path", msg).in_file(path);
            locate::at(e, text, locate::string_literal(text, &t.path))
        };
        let Some(i) = set.tolerances.iter().position(|u| u.path == t.path) else {
            return Err(located(format!(
                "`{}` is not a tolerance of {}",
                t.path,
                set.path.display()
            )));
        };
        if std::mem::replace(&mut seen[i], true) {
            return Err(located(format!("`{}` is listed twice", t.path)));
        }
        let c = ToleranceCost {
            weight: t.weight.unwrap_or(d.weight),
            exponent: t.exponent.unwrap_or(d.exponent),
            min_scale: t.min_scale.unwrap_or(d.min_scale),
            max_scale: t.max_scale.unwrap_or(d.max_scale),
        };
        check(&c, Some(&t.path), &format!("`{}`", t.path))?;
        out[i] = c;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set() -> ToleranceSet {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let doc = crate::scene::doc::BenchDoc::read(&root.join("scenes/paper_bench.ron")).unwrap();
        ToleranceSet::read(&root.join("scenes/tolerances/paper_bench.ron"), &doc).unwrap()
    }

    #[test]
    fn costs_default_and_override_per_tolerance() {
        let s = set();
        let c = parse_costs(
            "(default: (max_scale: 2.0),\n tolerances: [(path: \"dmd.tilt_deg\", weight: 3.0)])",
            Path::new("c.ron"),
            &s,
        )
        .unwrap();
        let i = s
            .tolerances
            .iter()
            .position(|t| t.path == "dmd.tilt_deg")
            .unwrap();
        assert_eq!(c[i].weight, 3.0);
        assert_eq!(c[i].max_scale, 2.0);
        assert_eq!(c[0].weight, 1.0);
        assert!((c[i].cost(0.5) - 6.0).abs() < 1e-12);
    }

    #[test]
    fn bad_costs_files_are_located() {
        let s = set();
        for (text, frags) in [
            (
                "(tolerances: [\n(path: \"no_such.despace_mm\", weight: 2.0)])",
                &["c.ron, line 2", "no_such.despace_mm", "not a tolerance"][..],
            ),
            (
                "(tolerances: [(path: \"dmd.tilt_deg\"),\n (path: \"dmd.tilt_deg\")])",
                &["listed twice"][..],
            ),
            (
                "(tolerances: [(path: \"dmd.tilt_deg\", min_scale: 0.5, max_scale: 0.2)])",
                &["line 1", "ordered"][..],
            ),
            (
                "(tolerances: [(path: \"dmd.tilt_deg\", wieght: 2.0)])",
                &["wieght"][..],
            ),
            (
                "(tolerances: [(path: \"dmd.tilt_deg\", weight: -1.0)])",
                &["weight"][..],
            ),
        ] {
            let e = parse_costs(text, Path::new("c.ron"), &s).unwrap_err();
            assert!(e.is_user_error(), "{e}");
            let m = e.to_string();
            for f in frags {
                assert!(m.contains(f), "{text}: {m} lacks {f}");
            }
        }
    }
}
