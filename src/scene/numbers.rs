//! Checked numbers of the input files: newtypes validated while deserialising, so that a value
//! out of range is refused where it is written and the error carries its line and column.
//!
//! Every bounded scalar is declared through [`checked!`], so that a new field of that kind
//! cannot forget its check; the two checked tuples ([`Mm3`], [`TableNm`]) are written by hand.

use serde::{Deserialize, Serialize};

use crate::optics::spectrum::Table;

/// The largest plain positive or non-negative number a bench may hold (gains, bandwidths,
/// noise densities): far above any real one, and far from overflowing in products.
pub const MAX_SCALAR: f64 = 1e15;

/// The largest optical density accepted (transmittance 1e-10: far beyond any filter or chrome).
pub const MAX_OD: f64 = 10.0;

/// The largest distance from the bench origin a position may have (mm): 100 m, far beyond any
/// table, yet small enough that every product of positions stays finite.
pub const MAX_POSITION_MM: f64 = 1e5;

/// Declares a checked scalar newtype: finite, above (`above`) or at least (`from`) its lower
/// bound and at most its upper bound, with the message its error gives (`|v|` names the value
/// read). The `unit` form is a positive quantity whose message names the bounds and the unit.
macro_rules! checked {
    ($(#[$m:meta])* $name:ident, above $lo:expr, at_most $hi:expr, unit $unit:expr) => {
        checked!(
            $(#[$m])* $name,
            above $lo,
            at_most $hi,
            |v| format!(
                "must be a positive number (above {}) of at most {} {}, got {v:e}",
                $lo, $hi, $unit
            )
        );
    };
    ($(#[$m:meta])* $name:ident, above $lo:expr, at_most $hi:expr, |$v:ident| $msg:expr) => {
        checked!(@type $(#[$m])* $name, |v| v > $lo && v <= $hi, |$v| $msg);
    };
    ($(#[$m:meta])* $name:ident, from $lo:expr, at_most $hi:expr, |$v:ident| $msg:expr) => {
        checked!(@type $(#[$m])* $name, |v| ($lo..=$hi).contains(&v), |$v| $msg);
    };
    (@type $(#[$m:meta])* $name:ident, |$a:ident| $ok:expr, |$v:ident| $msg:expr) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
        #[serde(try_from = "f64", into = "f64")]
        pub struct $name(pub f64);

        impl From<$name> for f64 {
            fn from(v: $name) -> f64 {
                v.0
            }
        }

        impl TryFrom<f64> for $name {
            type Error = String;
            fn try_from($a: f64) -> std::result::Result<Self, String> {
                if $a.is_finite() && $ok {
                    Ok($name($a))
                } else {
                    let $v = $a;
                    Err($msg)
                }
            }
        }
    };
}

checked!(
    /// A finite number > 0.
    Positive,
    above 0.0,
    at_most MAX_SCALAR,
    |v| format!("must be a positive number of at most {MAX_SCALAR:e}, got {v:e}")
);

checked!(
    /// A finite number ≥ 0.
    NonNegative,
    from 0.0,
    at_most MAX_SCALAR,
    |v| format!("must be a non-negative number of at most {MAX_SCALAR:e}, got {v:e}")
);

checked!(
    /// A length (mm) of a part: positive and at most [`MAX_POSITION_MM`] (100 m).
    LengthMm,
    above 0.0,
    at_most MAX_POSITION_MM,
    unit "mm"
);

checked!(
    /// An angle (degrees) that is a size (a cone half-angle, a mirror tilt): in (0, 180].
    AngleDeg,
    above 0.0,
    at_most 180.0,
    unit "degrees"
);

checked!(
    /// A radiant power (W): positive and at most 1 MW (a lamp of a bench draws tens of watts).
    PowerW,
    above 0.0,
    at_most 1e6,
    unit "W"
);

checked!(
    /// A number in (0, 1].
    UnitFraction,
    above 0.0,
    at_most 1.0,
    |v| format!("must be in (0, 1], got {v}")
);

checked!(
    /// A sampling ratio in (0, 1] (experiment files).
    Ratio,
    above 0.0,
    at_most 1.0,
    |v| format!("a sampling ratio must lie in (0, 1], got {v}")
);

checked!(
    /// A colour temperature (K) of a thermal source: above 0 and at most 4000 K (tungsten melts
    /// at 3695 K; a quartz-halogen filament runs at 2800–3400 K).
    Temperature,
    above 0.0,
    at_most 4000.0,
    |v| format!("a filament temperature must lie in (0, 4000] K, got {v}")
);

checked!(
    /// An irradiance (W/m²) of ambient light: at least 0 and at most 2000 W/m² (direct sunlight
    /// is about 1000 W/m²; a lit laboratory gives well under 10 W/m²).
    Irradiance,
    from 0.0,
    at_most 2000.0,
    |v| format!("an ambient irradiance must lie in [0, 2000] W/m², got {v}")
);

/// A table of (wavelength_nm, value) pairs with strictly increasing wavelengths.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "Vec<(f64, f64)>", into = "Vec<(f64, f64)>")]
pub struct TableNm(pub Vec<(f64, f64)>);

impl From<TableNm> for Vec<(f64, f64)> {
    fn from(v: TableNm) -> Vec<(f64, f64)> {
        v.0
    }
}

impl TryFrom<Vec<(f64, f64)>> for TableNm {
    type Error = String;
    fn try_from(v: Vec<(f64, f64)>) -> std::result::Result<Self, String> {
        Table::from_nm(&v)?;
        Ok(TableNm(v))
    }
}

/// A point or vector in the bench frame (mm), each component finite and within
/// ±[`MAX_POSITION_MM`], checked while reading so that the error carries the line.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(try_from = "(f64, f64, f64)", into = "(f64, f64, f64)")]
pub struct Mm3(pub f64, pub f64, pub f64);

impl From<Mm3> for (f64, f64, f64) {
    fn from(v: Mm3) -> (f64, f64, f64) {
        (v.0, v.1, v.2)
    }
}

impl TryFrom<(f64, f64, f64)> for Mm3 {
    type Error = String;
    fn try_from(v: (f64, f64, f64)) -> std::result::Result<Self, String> {
        for c in [v.0, v.1, v.2] {
            if !(c.is_finite() && c.abs() <= MAX_POSITION_MM) {
                return Err(format!(
                    "components must be finite and within ±{MAX_POSITION_MM} mm, got {c:e}"
                ));
            }
        }
        Ok(Mm3(v.0, v.1, v.2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ranges and messages of the checked scalars, at and beyond their bounds.
    #[test]
    fn bounds_and_messages() {
        assert!(Positive::try_from(0.0).is_err() && Positive::try_from(1e15).is_ok());
        assert_eq!(
            Positive::try_from(-1.0).unwrap_err(),
            "must be a positive number of at most 1e15, got -1e0"
        );
        assert!(NonNegative::try_from(0.0).is_ok() && NonNegative::try_from(-0.5).is_err());
        assert_eq!(
            LengthMm::try_from(0.0).unwrap_err(),
            "must be a positive number (above 0) of at most 100000 mm, got 0e0"
        );
        assert!(AngleDeg::try_from(180.0).is_ok() && AngleDeg::try_from(180.5).is_err());
        assert!(UnitFraction::try_from(1.0).is_ok() && UnitFraction::try_from(f64::NAN).is_err());
        assert_eq!(
            Ratio::try_from(2.0).unwrap_err(),
            "a sampling ratio must lie in (0, 1], got 2"
        );
        assert_eq!(
            Temperature::try_from(5000.0).unwrap_err(),
            "a filament temperature must lie in (0, 4000] K, got 5000"
        );
        assert!(Irradiance::try_from(0.0).is_ok() && Irradiance::try_from(2000.5).is_err());
    }
}
