//! Checked numbers of the input files, the part every layer may use: the [`checked!`] macro
//! that declares a bounded scalar newtype, the whole numbers [`Count`] and [`Whole`] with their
//! bounds in the type, the plain scalars ([`Positive`], [`NonNegative`], [`UnitFraction`],
//! [`Finite`]) and [`via`], which reads a field through its checked type and keeps its plain
//! form. A value out of range is refused while the file is read, so the error carries its line,
//! column and field path.
//!
//! The bench's own quantities (lengths, angles, optical densities, …) are in `scene::numbers`,
//! which re-exports these; the solver options (`reconstruction::tval3`), the additive noise
//! (`acquisition::noise`) and the objects (`objects`) live below `scene` and read their numbers
//! through these types directly. The test `input_files_hold_no_bare_numbers` (in `scene`) reads
//! the sources of every such type and fails on a field that holds a bare number.

use serde::{Deserialize, Serialize};

/// The largest plain positive or non-negative number a bench may hold (gains, bandwidths,
/// noise densities): far above any real one, and far from overflowing in products.
pub const MAX_SCALAR: f64 = 1e15;

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
    ($(#[$m:meta])* $name:ident, |$a:ident| $ok:expr, |$v:ident| $msg:expr) => {
        checked!(@type $(#[$m])* $name, |$a| $ok, |$v| $msg);
    };
    ($(#[$m:meta])* $name:ident, from $lo:expr, at_most $hi:expr, |$v:ident| $msg:expr) => {
        checked!(@type $(#[$m])* $name, |v| ($lo..=$hi).contains(&v), |$v| $msg);
    };
    (@type $(#[$m:meta])* $name:ident, |$a:ident| $ok:expr, |$v:ident| $msg:expr) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, ::serde::Deserialize, ::serde::Serialize)]
        #[serde(try_from = "f64", into = "f64")]
        pub struct $name(pub f64);

        impl From<$name> for f64 {
            fn from(v: $name) -> f64 {
                v.0
            }
        }

        impl $crate::checked::Plain<f64> for $name {
            fn plain(self) -> f64 {
                self.0
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

/// A checked value's plain form: the field type a struct keeps when code outside `scene` reads
/// it as a plain number, while the file is read through the checked type ([`via`]).
pub trait Plain<T> {
    fn plain(self) -> T;
}

impl<A: Plain<X>, B: Plain<Y>, X, Y> Plain<(X, Y)> for (A, B) {
    fn plain(self) -> (X, Y) {
        (self.0.plain(), self.1.plain())
    }
}

impl<A: Plain<X>, X> Plain<Vec<X>> for Vec<A> {
    fn plain(self) -> Vec<X> {
        self.into_iter().map(Plain::plain).collect()
    }
}

impl<A: Plain<X>, X> Plain<Option<X>> for Option<A> {
    fn plain(self) -> Option<X> {
        self.map(Plain::plain)
    }
}

/// A number as a user writes it, for messages: the shortest text that reads back as the same
/// value, in exponent form where plain decimals would run long (`1e308`, not a 309-digit
/// integer; `2.5e-7`, not `0.00000025`).
pub fn shown(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && a != 0.0 && !(1e-4..1e16).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Reads a field through its checked type `C` and keeps its plain form `T`:
/// `#[serde(deserialize_with = "via::<Count<1, 1000>, _, _>")] max_count: usize`. The check
/// runs while the file is read, so its error carries the line and column like any other.
pub fn via<'de, C, T, D>(d: D) -> std::result::Result<T, D::Error>
where
    C: Deserialize<'de> + Plain<T>,
    D: serde::Deserializer<'de>,
{
    C::deserialize(d).map(Plain::plain)
}

/// Every module that reads an input file declares its own checked scalars with it
/// (`scene::dataset`, `reconstruction::tval3`).
pub(crate) use checked;

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
    /// A number in (0, 1].
    UnitFraction,
    above 0.0,
    at_most 1.0,
    |v| format!("must be in (0, 1], got {v}")
);

checked!(
    /// A finite number of at most [`MAX_SCALAR`] in magnitude, either sign (a constant of a
    /// spectrum, a deviation, a limit): the bound keeps every product of such numbers finite.
    Finite,
    |v| v.abs() <= MAX_SCALAR,
    |v| format!("must be a finite number within ±{MAX_SCALAR:e}, got {v:e}")
);

/// A whole number in `LO ..= HI` (a count, an index, a size), checked while reading like the
/// scalars above. The bounds are in the type, so a field states its range where it is declared
/// (`Count<1, 100_000>`), and no count can skip its check or wrap in a product later.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize, Serialize)]
#[serde(try_from = "u64", into = "u64")]
pub struct Count<const LO: u64, const HI: u64>(u64);

impl<const LO: u64, const HI: u64> Count<LO, HI> {
    /// The largest value the type holds.
    pub const MAX: u64 = HI;

    /// `v` when it is in range (for defaults and values made in code).
    pub const fn new(v: u64) -> Self {
        assert!(v >= LO && v <= HI, "a count out of its type's range");
        Count(v)
    }

    pub fn get(self) -> u64 {
        self.0
    }

    /// The value as an index or size (every bound here is far below `usize::MAX` on 64-bit).
    pub fn usize(self) -> usize {
        self.0 as usize
    }
}

impl<const LO: u64, const HI: u64> Plain<u64> for Count<LO, HI> {
    fn plain(self) -> u64 {
        self.0
    }
}

impl<const LO: u64, const HI: u64> Plain<usize> for Count<LO, HI> {
    fn plain(self) -> usize {
        self.usize()
    }
}

impl<const LO: u64, const HI: u64> Plain<u32> for Count<LO, HI> {
    fn plain(self) -> u32 {
        const {
            assert!(
                HI <= u32::MAX as u64,
                "a Count read as u32 needs bounds within u32"
            )
        };
        self.0 as u32
    }
}

impl<const LO: u64, const HI: u64> Plain<u8> for Count<LO, HI> {
    fn plain(self) -> u8 {
        const {
            assert!(
                HI <= u8::MAX as u64,
                "a Count read as u8 needs bounds within u8"
            )
        };
        self.0 as u8
    }
}

impl<const LO: u64, const HI: u64> From<Count<LO, HI>> for u64 {
    fn from(v: Count<LO, HI>) -> u64 {
        v.0
    }
}

impl<const LO: u64, const HI: u64> TryFrom<u64> for Count<LO, HI> {
    type Error = String;
    fn try_from(v: u64) -> std::result::Result<Self, String> {
        if (LO..=HI).contains(&v) {
            Ok(Count(v))
        } else {
            Err(format!("must be a whole number from {LO} to {HI}, got {v}"))
        }
    }
}

/// A signed whole number in `LO ..= HI` (a USAF group), checked while reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize, Serialize)]
#[serde(try_from = "i64", into = "i64")]
pub struct Whole<const LO: i64, const HI: i64>(i64);

impl<const LO: i64, const HI: i64> Whole<LO, HI> {
    pub fn get(self) -> i64 {
        self.0
    }
}

impl<const LO: i64, const HI: i64> Plain<i32> for Whole<LO, HI> {
    fn plain(self) -> i32 {
        const {
            assert!(
                LO >= i32::MIN as i64 && HI <= i32::MAX as i64,
                "a Whole read as i32 needs bounds within i32"
            )
        };
        self.0 as i32
    }
}

impl<const LO: i64, const HI: i64> From<Whole<LO, HI>> for i64 {
    fn from(v: Whole<LO, HI>) -> i64 {
        v.0
    }
}

impl<const LO: i64, const HI: i64> TryFrom<i64> for Whole<LO, HI> {
    type Error = String;
    fn try_from(v: i64) -> std::result::Result<Self, String> {
        if (LO..=HI).contains(&v) {
            Ok(Whole(v))
        } else {
            Err(format!("must be a whole number from {LO} to {HI}, got {v}"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::shown;

    #[test]
    fn numbers_are_shown_as_written() {
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-1.5e20), "-1.5e20");
        assert_eq!(shown(2.5e-7), "2.5e-7");
        assert_eq!(shown(12.25), "12.25");
        assert_eq!(shown(0.0), "0");
        assert_eq!(shown(1e15), "1000000000000000");
        assert_eq!(shown(f64::NAN), "NaN");
    }
}
