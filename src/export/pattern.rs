//! DMD pattern specifications for exports and validation traces: `all-plus`, `all-minus`,
//! `random:SEED`, `complement-random:SEED`, or a `.npy` file of 0/1 values (one per unit,
//! row-major, any shape with that many elements).

use std::path::Path;

use crate::error::{Error, Result};

/// A DMD pattern over the pattern area's units (true = state +).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DmdPattern {
    AllPlus,
    AllMinus,
    /// `crate::acquisition::patterns::random(1, units, seed)`: SplitMix64 bits.
    Random(u64),
    /// The complement of `Random(seed)`.
    ComplementRandom(u64),
    /// A .npy file of 0/1 values.
    Npy(String),
}

impl std::str::FromStr for DmdPattern {
    type Err = Error;

    /// Parses `all-plus`, `all-minus`, `random:SEED`, `complement-random:SEED` or a path ending
    /// in `.npy`.
    fn from_str(s: &str) -> Result<DmdPattern> {
        let t = s.trim();
        let seed = |v: &str| {
            v.trim().parse::<u64>().map_err(|_| {
                Error::field(
                    "pattern",
                    format!("`{v}` is not a seed (an unsigned integer)"),
                )
            })
        };
        Ok(match t {
            "all-plus" => DmdPattern::AllPlus,
            "all-minus" => DmdPattern::AllMinus,
            _ if t.starts_with("random:") => DmdPattern::Random(seed(&t[7..])?),
            _ if t.starts_with("complement-random:") => {
                DmdPattern::ComplementRandom(seed(&t[18..])?)
            }
            _ if t.ends_with(".npy") => DmdPattern::Npy(t.to_string()),
            _ => {
                return Err(Error::field(
                    "pattern",
                    format!(
                        "unknown pattern `{t}`: use all-plus, all-minus, random:SEED, \
                         complement-random:SEED or a .npy file"
                    ),
                ));
            }
        })
    }
}

impl DmdPattern {
    /// The label used in manifests and reference files.
    pub fn label(&self) -> String {
        match self {
            DmdPattern::AllPlus => "all-plus".into(),
            DmdPattern::AllMinus => "all-minus".into(),
            DmdPattern::Random(s) => format!("random:{s}"),
            DmdPattern::ComplementRandom(s) => format!("complement-random:{s}"),
            DmdPattern::Npy(p) => p.clone(),
        }
    }

    /// The unit states for a pattern area of `units` units. A .npy path is resolved against
    /// `base` when relative.
    pub fn bits(&self, units: usize, base: &Path) -> Result<Vec<bool>> {
        let random = |seed: u64| {
            let m = crate::acquisition::patterns::random(1, units, seed);
            (0..units).map(|j| m.get(0, j)).collect::<Vec<bool>>()
        };
        Ok(match self {
            DmdPattern::AllPlus => vec![true; units],
            DmdPattern::AllMinus => vec![false; units],
            DmdPattern::Random(s) => random(*s),
            DmdPattern::ComplementRandom(s) => random(*s).into_iter().map(|b| !b).collect(),
            DmdPattern::Npy(p) => {
                let path = base.join(p);
                let a = crate::report::npy::read(&path)?;
                let v = a.to_f64();
                if v.len() != units {
                    return Err(Error::field(
                        "pattern",
                        format!("{} values for a pattern area of {units} units", v.len()),
                    )
                    .in_file(&path));
                }
                let mut out = Vec::with_capacity(units);
                for x in v {
                    if x == 0.0 || x == 1.0 {
                        out.push(x == 1.0);
                    } else {
                        return Err(Error::field(
                            "pattern",
                            format!("pattern values must be 0 or 1, got {x}"),
                        )
                        .in_file(&path));
                    }
                }
                out
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_complements_complement() {
        let base = Path::new(".");
        assert_eq!(
            "all-plus".parse::<DmdPattern>().unwrap(),
            DmdPattern::AllPlus
        );
        assert_eq!(
            "random:7".parse::<DmdPattern>().unwrap(),
            DmdPattern::Random(7)
        );
        assert!("random:x".parse::<DmdPattern>().is_err());
        assert!("stripes".parse::<DmdPattern>().is_err());
        let a = DmdPattern::Random(7).bits(16, base).unwrap();
        let b = DmdPattern::ComplementRandom(7).bits(16, base).unwrap();
        assert!(a.iter().zip(&b).all(|(x, y)| x != y));
        assert!(a.iter().any(|&x| x) && a.iter().any(|&x| !x));
        assert_eq!(DmdPattern::AllMinus.bits(3, base).unwrap(), vec![false; 3]);
    }
}
