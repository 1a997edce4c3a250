//! Checked numbers of the input files: newtypes validated while deserialising, so that a value
//! out of range is refused where it is written and the error carries its line and column.
//!
//! Every bounded scalar is declared through [`checked!`], so that a new field of that kind
//! cannot forget its check; whole numbers are [`Count`] and [`Whole`], whose bounds are part of
//! the type (`Count<1, 100_000>`); the two checked tuples ([`Mm3`], [`TableNm`]) are written by
//! hand. No field of an input file holds a bare `f64` or integer: the test
//! `input_files_hold_no_bare_numbers` (in `scene`) reads the sources and fails on one, so a new
//! field cannot skip validation by accident.

use serde::{Deserialize, Serialize};

use crate::optics::spectrum::Table;

/// Other modules of `scene` declare their own checked scalars with it (`scene::dataset`).
pub(crate) use crate::checked::checked;
pub use crate::checked::{
    Count, Finite, MAX_SCALAR, NonNegative, Plain, Positive, UnitFraction, Whole, via,
};

/// The largest optical density accepted (transmittance 1e-10: far beyond any filter or chrome).
pub const MAX_OD: f64 = 10.0;

/// The largest distance from the bench origin a position may have (mm): 100 m, far beyond any
/// table, yet small enough that every product of positions stays finite.
pub const MAX_POSITION_MM: f64 = 1e5;

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

checked!(
    /// An angle (degrees) that is an orientation (a polar or azimuth angle, a hinge angle):
    /// finite and within ±360°.
    DirectionDeg,
    |v| v.abs() <= 360.0,
    |v| format!("must be a finite angle within ±360 degrees, got {v:e}")
);

checked!(
    /// An alignment tilt (degrees) of a part about one of its own axes: below 90° in magnitude
    /// (at 90° the part would lie along its own axis).
    TiltDeg,
    |v| v.abs() < 90.0,
    |v| format!("a tilt must be finite and below 90 degrees in magnitude, got {v:e}")
);

checked!(
    /// A signed radius of curvature (mm): non-zero and at most [`MAX_POSITION_MM`] in
    /// magnitude (a longer radius is flat for any bench: omit it). A radius of 1e308 mm made
    /// every sag overflow.
    RadiusMm,
    |v| v != 0.0 && v.abs() <= MAX_POSITION_MM,
    |v| format!(
        "a radius of curvature must be non-zero and at most {MAX_POSITION_MM} mm in magnitude \
         (omit it for a flat surface), got {v:e}"
    )
);

checked!(
    /// A signed coordinate (mm) within ±[`MAX_POSITION_MM`] (a point on a chart).
    CoordMm,
    |v| v.abs() <= MAX_POSITION_MM,
    |v| format!("must be a finite coordinate within ±{MAX_POSITION_MM} mm, got {v:e}")
);

checked!(
    /// An optical density in [0, [`MAX_OD`]]. NaN fails here: it passed a range check on the
    /// built spectrum (whose minimum and maximum skip NaN) and absorbed every ray.
    OpticalDensity,
    from 0.0,
    at_most MAX_OD,
    |v| format!("an optical density must lie in [0, {MAX_OD}], got {v:e}")
);

checked!(
    /// A wavelength (nm) of the traced band: above 100 nm and at most 20 000 nm.
    WavelengthNm,
    above 100.0,
    at_most 20_000.0,
    |v| format!("a wavelength must lie in (100, 20000] nm, got {v:e}")
);

checked!(
    /// The design wavelength (nm) of a quarter-wave AR coating: in (100, 5000) nm.
    DesignNm,
    |v| v > 100.0 && v < 5000.0,
    |v| format!("the AR design wavelength must be in (100, 5000) nm, got {v:e}")
);

checked!(
    /// A probability that leaves some rays to the other strategy: in [0, 1).
    Probability,
    |v| (0.0..1.0).contains(&v),
    |v| format!("must lie in [0, 1), got {v}")
);

checked!(
    /// A voltage offset (V) of an output or an oscilloscope channel: within ±1 kV, far beyond
    /// any amplifier or scope input.
    OffsetV,
    |v| v.abs() <= 1e3,
    |v| format!("offset_v must be a finite number within ±1000 V, got {v:e}")
);

checked!(
    /// A number of standard deviations at which a range ends: in (0, 10].
    Sigmas,
    above 0.0,
    at_most 10.0,
    |v| format!("sigmas (the range's ends in standard deviations) must lie in (0, 10], got {v}")
);

checked!(
    /// An MSSIM threshold: in [−1, 1], the range of the index (Wang et al. 2004).
    Mssim,
    from -1.0,
    at_most 1.0,
    |v| format!("an MSSIM lies in [-1, 1], got {v}")
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
