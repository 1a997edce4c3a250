//! DMD pattern sets, always bit-packed (random) or implicit (Hadamard), each with its complement.
//!
//! A pattern set holds M base 0/1 patterns over N units (a unit is one block of DMD mirrors;
//! units are numbered row-major, `row * width + col`). What the ON arm sees is P, what the OFF
//! arm sees is 1 − P; the schemes in [`super::schemes`] decide which of the two a detector
//! records and whether the measurement is used as A = P or Â = 2P − 1.

use std::borrow::Cow;
use std::sync::Arc;

use super::hadamard::{HadamardOrdering, check_side, hadamard_order, hadamard_patterns};
use crate::error::{Error, Result};
use crate::reconstruction::{
    BitMatrix, HadamardOperator, LinearOperator, PackedOperator, PatternForm,
};
use crate::rng::SplitMix64;

/// The largest number of units a pattern set may have (2^26, e.g. 8192×8192). Anything larger
/// is a typing error rather than an experiment: one float image alone would take 512 MiB.
pub const MAX_UNITS: usize = 1 << 26;

/// The largest stored random pattern matrix, in bits (2^33 bits = 1 GiB).
pub const MAX_RANDOM_BITS: usize = 1 << 33;

/// Random sets may hold up to this many patterns per unit (oversampling beyond 4N is absurd
/// for compressive imaging and only costs memory).
pub const MAX_RANDOM_OVERSAMPLING: usize = 4;

/// `rows` random 0/1 patterns of `cols` units each, every bit equally likely.
///
/// Bits come from the SplitMix64 sequence seeded with `seed`, read least significant bit first
/// and row-major over the whole matrix: bit t of the flattened matrix is bit `t % 64` of output
/// `t / 64`. This is the convention of the TVAL3 reference problems, so seed 0x5EED0001
/// reproduces their pattern matrix exactly.
pub fn random(rows: usize, cols: usize, seed: u64) -> BitMatrix {
    let mut m = BitMatrix::zeros(rows, cols);
    if rows == 0 || cols == 0 {
        return m;
    }
    // The whole bit stream, one SplitMix64 output per 64 bits, plus one spare word so that a
    // row's last (shifted) word can always read its successor.
    let total_bits = rows * cols;
    let mut outputs = SplitMix64::new(seed);
    let stream: Vec<u64> = (0..total_bits.div_ceil(64) + 1)
        .map(|_| outputs.next_u64())
        .collect();
    let wpr = m.words_per_row();
    let tail = cols % 64;
    for r in 0..rows {
        let row = m.row_words_mut(r);
        for (q, word) in row.iter_mut().enumerate() {
            // Bits 64q.. of row r are bits r·cols + 64q.. of the stream.
            let t = r * cols + 64 * q;
            let (k, shift) = (t / 64, t % 64);
            let mut w = stream[k] >> shift;
            if shift != 0 {
                w |= stream[k + 1] << (64 - shift);
            }
            if q + 1 == wpr && tail != 0 {
                w &= (1u64 << tail) - 1;
            }
            *word = w;
        }
    }
    m
}

/// A set of M base patterns over N units.
///
/// Build it with [`random_set`] or [`hadamard_set`], which validate sizes; a variant built by
/// hand must keep their invariants (a power-of-two side and rows below side²).
#[derive(Debug, Clone)]
pub enum PatternSet {
    /// Random 0/1 patterns from [`random`] (any width × height).
    Random {
        width: usize,
        height: usize,
        seed: u64,
        patterns: BitMatrix,
    },
    /// Sylvester–Hadamard patterns P⁺ = (1 + H)/2 on a side × side grid (side = 2^m), given by
    /// their natural row indices in measurement order; never stored as bits.
    Hadamard {
        side: usize,
        ordering: HadamardOrdering,
        rows: Vec<usize>,
    },
}

fn check_grid(width: usize, height: usize) -> Result<usize> {
    if width == 0 || height == 0 {
        return Err(Error::field(
            "size",
            format!("a pattern grid needs at least one unit, got {width}×{height}"),
        ));
    }
    match width.checked_mul(height) {
        Some(n) if n <= MAX_UNITS => Ok(n),
        _ => Err(Error::field(
            "size",
            format!(
                "a {width}×{height} pattern grid is absurdly large (more than {MAX_UNITS} units)"
            ),
        )),
    }
}

/// Number of base patterns for a sampling ratio: the nearest integer to ratio·N, at least 1 and
/// at most N.
pub fn patterns_for_ratio(ratio: f64, units: usize) -> usize {
    ((ratio * units as f64).round() as usize).clamp(1, units)
}

/// Which base patterns an acquisition shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PatternFamily {
    /// Random 0/1 patterns from a seeded SplitMix64 sequence ([`random_set`]).
    Random { seed: u64 },
    /// Sylvester Hadamard patterns in an ordering (2^m × 2^m units only, [`hadamard_set`]).
    Hadamard { ordering: HadamardOrdering },
}

impl PatternFamily {
    /// The first `m` patterns of the family for a `width × height` unit grid.
    pub fn build(&self, width: usize, height: usize, m: usize) -> Result<PatternSet> {
        match *self {
            PatternFamily::Random { seed } => random_set(width, height, m, seed),
            PatternFamily::Hadamard { ordering } => {
                if width != height {
                    return Err(Error::field(
                        "patterns",
                        format!(
                            "Hadamard patterns need a square 2^m × 2^m unit grid, got {width}×{height}"
                        ),
                    ));
                }
                hadamard_set(width, ordering, m)
            }
        }
    }

    /// "random (seed 1)", "hadamard (cake-cutting)".
    pub fn label(&self) -> String {
        match self {
            PatternFamily::Random { seed } => format!("random (seed {seed})"),
            PatternFamily::Hadamard { ordering } => format!("hadamard ({})", ordering.label()),
        }
    }
}

impl serde::Serialize for PatternFamily {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.label())
    }
}

/// `m` random patterns on a `width` × `height` grid from [`random`] with `seed`.
///
/// Valid for 1 ≤ m ≤ 4N and at most [`MAX_RANDOM_BITS`] stored bits.
pub fn random_set(width: usize, height: usize, m: usize, seed: u64) -> Result<PatternSet> {
    let n = check_grid(width, height)?;
    if m == 0 {
        return Err(Error::field(
            "measurements",
            "at least one pattern is needed, got 0",
        ));
    }
    if m > MAX_RANDOM_OVERSAMPLING * n {
        return Err(Error::field(
            "measurements",
            format!(
                "{m} random patterns for {n} units is absurd (more than \
                 {MAX_RANDOM_OVERSAMPLING}·N = {})",
                MAX_RANDOM_OVERSAMPLING * n
            ),
        ));
    }
    if m.saturating_mul(n) > MAX_RANDOM_BITS {
        return Err(Error::field(
            "measurements",
            format!(
                "{m} random patterns of {n} units would take {:.1} GiB of bits (limit 1 GiB)",
                (m as f64) * (n as f64) / 8.0 / (1u64 << 30) as f64
            ),
        ));
    }
    Ok(PatternSet::Random {
        width,
        height,
        seed,
        patterns: random(m, n, seed),
    })
}

/// The first `m` Hadamard patterns of a `side` × `side` grid in `ordering`; 1 ≤ m ≤ side².
pub fn hadamard_set(side: usize, ordering: HadamardOrdering, m: usize) -> Result<PatternSet> {
    check_side(side)?;
    let n = side * side;
    if m == 0 || m > n {
        return Err(Error::field(
            "measurements",
            format!(
                "a {side}×{side} Hadamard set has {n} patterns, so 1 ≤ M ≤ {n}; got {m} \
                 (orthogonal patterns cannot oversample)"
            ),
        ));
    }
    let mut rows = hadamard_order(side, ordering)?;
    rows.truncate(m);
    Ok(PatternSet::Hadamard {
        side,
        ordering,
        rows,
    })
}

impl PatternSet {
    /// M, the number of base patterns.
    pub fn measurements(&self) -> usize {
        match self {
            PatternSet::Random { patterns, .. } => patterns.rows(),
            PatternSet::Hadamard { rows, .. } => rows.len(),
        }
    }

    /// N, the number of units per pattern.
    pub fn units(&self) -> usize {
        self.width() * self.height()
    }

    /// Units across.
    pub fn width(&self) -> usize {
        match self {
            PatternSet::Random { width, .. } => *width,
            PatternSet::Hadamard { side, .. } => *side,
        }
    }

    /// Units down.
    pub fn height(&self) -> usize {
        match self {
            PatternSet::Random { height, .. } => *height,
            PatternSet::Hadamard { side, .. } => *side,
        }
    }

    /// The sampling ratio M/N.
    pub fn ratio(&self) -> f64 {
        self.measurements() as f64 / self.units() as f64
    }

    /// The base 0/1 patterns P (M × N, bit-packed). Borrowed for random sets; built for
    /// Hadamard sets (M·N bits), so call it only when the bits themselves are needed.
    pub fn base_patterns(&self) -> Cow<'_, BitMatrix> {
        match self {
            PatternSet::Random { patterns, .. } => Cow::Borrowed(patterns),
            PatternSet::Hadamard { side, rows, .. } => Cow::Owned(
                hadamard_patterns(*side, rows)
                    .expect("a constructed Hadamard set has a valid side and rows"),
            ),
        }
    }

    /// The same set cut to its first `m` patterns (1 ≤ m ≤ M): a lower sampling ratio with the
    /// same seed or ordering.
    pub fn head(&self, m: usize) -> Result<PatternSet> {
        if m == 0 || m > self.measurements() {
            return Err(Error::field(
                "measurements",
                format!(
                    "cannot take {m} patterns from a set of {}",
                    self.measurements()
                ),
            ));
        }
        Ok(match self {
            PatternSet::Random {
                width,
                height,
                seed,
                patterns,
            } => PatternSet::Random {
                width: *width,
                height: *height,
                seed: *seed,
                patterns: patterns.head(m),
            },
            PatternSet::Hadamard {
                side,
                ordering,
                rows,
            } => PatternSet::Hadamard {
                side: *side,
                ordering: *ordering,
                rows: rows[..m].to_vec(),
            },
        })
    }

    /// The measurement operator A = P ([`PatternForm::ZeroOne`]) or Â = 2P − 1
    /// ([`PatternForm::PlusMinusOne`]): bit-packed for random sets, a fast Walsh–Hadamard
    /// transform for Hadamard sets; never a dense matrix.
    pub fn operator(&self, form: PatternForm) -> Arc<dyn LinearOperator> {
        match self {
            PatternSet::Random { patterns, .. } => {
                Arc::new(PackedOperator::new(patterns.clone(), form))
            }
            PatternSet::Hadamard { side, rows, .. } => {
                Arc::new(HadamardOperator::new(side * side, rows.clone(), form))
            }
        }
    }
}

/// A pattern set with the 0/1 bit-packed operator of its base patterns, built once. Every
/// record through the set needs the products Σ_j P_ij·g±_j of all its patterns with the
/// per-unit gains (`Transport::pattern_products_of`), and a dataset or a Python batch records
/// thousands of objects through one set: building the operator for each record (a copy and a
/// repacking of the bits) was ~5 % of a dataset sample's time, and each record's copy of the
/// set (for the solver) ~1 % more, now shared. The set can only be read, so the operator
/// always belongs to it.
#[derive(Debug, Clone)]
pub struct PackedPatterns {
    set: Arc<PatternSet>,
    product: PackedOperator,
}

impl PackedPatterns {
    pub fn new(set: PatternSet) -> PackedPatterns {
        let product = PackedOperator::new(set.base_patterns().into_owned(), PatternForm::ZeroOne);
        PackedPatterns {
            set: Arc::new(set),
            product,
        }
    }

    pub fn set(&self) -> &PatternSet {
        &self.set
    }

    /// The set, shared (a record keeps it for the solver without copying its bits).
    pub fn shared_set(&self) -> Arc<PatternSet> {
        self.set.clone()
    }

    /// The operator P of all M base patterns ([`PatternForm::ZeroOne`]), as the record's
    /// forward model uses it for Random and Hadamard sets alike.
    pub fn product(&self) -> &PackedOperator {
        &self.product
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The convention written out bit by bit, as in the TVAL3 reference README.
    fn random_bitwise(rows: usize, cols: usize, seed: u64) -> BitMatrix {
        let mut m = BitMatrix::zeros(rows, cols);
        let mut bits = SplitMix64::new(seed);
        let mut word = 0u64;
        let mut avail = 0u32;
        for r in 0..rows {
            for c in 0..cols {
                if avail == 0 {
                    word = bits.next_u64();
                    avail = 64;
                }
                m.set(r, c, word & 1 == 1);
                word >>= 1;
                avail -= 1;
            }
        }
        m
    }

    #[test]
    fn word_wise_random_matches_the_bit_convention() {
        for (rows, cols) in [
            (1, 1),
            (3, 63),
            (5, 64),
            (7, 65),
            (4, 100),
            (9, 130),
            (2, 4096),
        ] {
            for seed in [0u64, 0x5EED_0001] {
                assert_eq!(
                    random(rows, cols, seed),
                    random_bitwise(rows, cols, seed),
                    "{rows}×{cols}"
                );
            }
        }
        // First bits of the reference stream: SplitMix64(0) starts with 0xE220A8397B1DCDAF,
        // whose lowest byte 0xAF read least significant bit first is 1, 1, 1, 1, 0, 1, 0, 1.
        let p = random(1, 8, 0);
        let bits: Vec<bool> = (0..8).map(|c| p.get(0, c)).collect();
        assert_eq!(bits, [true, true, true, true, false, true, false, true]);
        assert_eq!(random(0, 5, 1).rows(), 0);
    }

    #[test]
    fn random_bits_are_balanced() {
        // 64 × 1024 bits: the count of ones is Binomial(65536, 1/2), standard deviation 128.
        let p = random(64, 1024, 99);
        let ones: usize = (0..64).map(|r| p.row_count(r)).sum();
        assert!((ones as f64 - 32768.0).abs() < 5.0 * 128.0, "{ones}");
    }

    #[test]
    fn sets_report_sizes_and_operators() {
        let r = random_set(12, 5, 30, 7).unwrap();
        assert_eq!(
            (r.measurements(), r.units(), r.width(), r.height()),
            (30, 60, 12, 5)
        );
        assert!((r.ratio() - 0.5).abs() < 1e-15);
        let op = r.operator(PatternForm::PlusMinusOne);
        assert_eq!((op.rows(), op.cols()), (30, 60));
        assert_eq!(*r.base_patterns(), random(30, 60, 7));

        let h = hadamard_set(8, HadamardOrdering::CakeCutting, 20).unwrap();
        assert_eq!((h.measurements(), h.units()), (20, 64));
        let op = h.operator(PatternForm::ZeroOne);
        assert_eq!((op.rows(), op.cols()), (20, 64));
        let order = hadamard_order(8, HadamardOrdering::CakeCutting).unwrap();
        assert_eq!(
            *h.base_patterns(),
            hadamard_patterns(8, &order[..20]).unwrap()
        );
        // Both operators apply their base patterns.
        for set in [&r, &h] {
            let n = set.units();
            let x: Vec<f64> = (0..n).map(|i| (i % 7) as f64).collect();
            let mut y = vec![0.0; set.measurements()];
            set.operator(PatternForm::ZeroOne).apply(&x, &mut y);
            let p = set.base_patterns();
            for (i, yi) in y.iter().enumerate() {
                let direct: f64 = (0..n).filter(|&c| p.get(i, c)).map(|c| x[c]).sum();
                assert!((yi - direct).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn head_keeps_the_leading_patterns() {
        let r = random_set(8, 8, 40, 3).unwrap();
        let r10 = r.head(10).unwrap();
        assert_eq!(*r10.base_patterns(), r.base_patterns().head(10));
        let h = hadamard_set(8, HadamardOrdering::Walsh, 64).unwrap();
        let h5 = h.head(5).unwrap();
        assert_eq!(
            *h5.base_patterns(),
            *hadamard_set(8, HadamardOrdering::Walsh, 5)
                .unwrap()
                .base_patterns()
        );
        assert!(r.head(0).is_err() && r.head(41).is_err());
    }

    #[test]
    fn bad_sizes_are_input_errors_naming_the_field() {
        let field = |e: Error| {
            assert!(e.is_user_error());
            e.to_string()
        };
        assert!(field(random_set(0, 8, 4, 1).unwrap_err()).contains("field `size`"));
        assert!(field(random_set(1 << 14, 1 << 13, 4, 1).unwrap_err()).contains("absurdly"));
        assert!(field(random_set(usize::MAX, 2, 4, 1).unwrap_err()).contains("absurdly"));
        assert!(field(random_set(8, 8, 0, 1).unwrap_err()).contains("field `measurements`"));
        assert!(random_set(8, 8, 256, 1).is_ok());
        assert!(field(random_set(8, 8, 257, 1).unwrap_err()).contains("absurd"));
        assert!(field(random_set(4096, 4096, 1024, 1).unwrap_err()).contains("GiB"));
        assert!(field(hadamard_set(48, HadamardOrdering::Natural, 10).unwrap_err()).contains("48"));
        assert!(hadamard_set(8, HadamardOrdering::Natural, 64).is_ok());
        assert!(
            field(hadamard_set(8, HadamardOrdering::Natural, 65).unwrap_err())
                .contains("field `measurements`")
        );
        assert!(hadamard_set(8, HadamardOrdering::Natural, 0).is_err());
    }

    /// The operator a `PackedPatterns` keeps is P of all M base patterns: bit for bit the set's
    /// own 0/1 operator for a random set, and the fast transform's values for a Hadamard set
    /// (another order of summation, so to rounding).
    #[test]
    fn packed_patterns_hold_the_operator_of_every_base_pattern() {
        let x: Vec<f64> = (0..64).map(|i| ((i * 37 % 64) as f64).sqrt()).collect();
        for (set, exact) in [
            (random_set(8, 8, 40, 3).unwrap(), true),
            (
                hadamard_set(8, HadamardOrdering::CakeCutting, 20).unwrap(),
                false,
            ),
        ] {
            let packed = PackedPatterns::new(set.clone());
            let (op, want) = (packed.product(), set.operator(PatternForm::ZeroOne));
            assert_eq!((op.rows(), op.cols()), (set.measurements(), set.units()));
            assert_eq!(op.form(), PatternForm::ZeroOne);
            let (mut got, mut expect) = (vec![0.0; op.rows()], vec![0.0; op.rows()]);
            op.apply(&x, &mut got);
            want.apply(&x, &mut expect);
            for (g, e) in got.iter().zip(&expect) {
                if exact {
                    assert_eq!(g, e);
                } else {
                    assert!((g - e).abs() <= 1e-12 * e.abs().max(1.0), "{g} vs {e}");
                }
            }
        }
    }
}
