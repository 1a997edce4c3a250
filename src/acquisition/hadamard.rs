//! Two-dimensional Sylvester–Hadamard patterns and their measurement orderings.
//!
//! # Patterns
//!
//! An s×s pattern set (s = 2^m) uses the rows of the Sylvester matrix H_N of order N = s²,
//! `H[h][c] = (−1)^popcount(h & c)`. Natural row h = i·s + j, reshaped row-major to s×s, is the
//! outer product of the 1-D rows H_s[i] (down the image) and H_s[j] (across it)
//! (docs/bench-facts.md §10.1). A DMD shows the 0/1 pattern P⁺ = (1 + H)/2 (mirror ON where H = +1) and
//! the other arm sees its complement P⁻ = (1 − H)/2 = 1 − P⁺ at the same instant.
//!
//! Only powers of two have a Sylvester basis. In particular the paper's experimental sizes 48×48
//! and 96×96 have none (48 and 96 are not powers of two; MATLAB `hadamard` refuses them too,
//! docs/bench-facts.md §0.2), so those sizes need random patterns.
//!
//! # Orderings
//!
//! Every ordering is a permutation of the natural indices 0..s², returned in measurement order by
//! [`hadamard_order`]. With sequency seq(r) = number of sign changes of 1-D row r, the natural
//! row of sequency k is bitrev(gray(k)) with gray(k) = k ⊕ (k >> 1) (docs/bench-facts.md §10.2; the
//! gray-*decode* mapping used by some public code is wrong for n ≥ 8).
//!
//! - [`HadamardOrdering::Natural`]: Sylvester order.
//! - [`HadamardOrdering::Walsh`]: the 1-D sequency (Walsh) order of H_N, each row reshaped to
//!   s×s, i.e. measurement k uses natural row bitrev_{2m}(gray(k)). We take this convention
//!   rather than a walk over the 2-D sequency pairs (u, v) because it is fully determined by the
//!   1-D definition (no free choice of walk), it is what reshaping a Walsh-ordered H_N (the
//!   usual MATLAB practice) gives, and its defining property, non-decreasing sign changes of the
//!   flattened rows, can be checked directly. In 2-D terms it is a boustrophedon walk: with
//!   u = seq(i) and v = seq(j), measurement k has v = k / s as the major key and u = k mod s
//!   (v even) or s − 1 − k mod s (v odd) as the minor one (derived in the tests). Its first s
//!   patterns therefore vary along one axis only, which is why it is a poor compressive order.
//! - [`HadamardOrdering::RussianDolls`] (Sun et al., Sci. Rep. 7:3464, 2017): doll k is the set
//!   of 2-D sequency pairs with max(u, v) < 2^k, the 4^k patterns that are constant on dyadic
//!   blocks of s/2^k × s/2^k units, so the first 4^k measurements are a complete basis of a
//!   2^k × 2^k image (docs/bench-facts.md §10.3). **Within a doll the order is this project's choice**,
//!   because the paper's is not confirmed: patterns are sorted by (max(u, v), u + v, u), i.e.
//!   coarsest first, then by total sequency, then by vertical sequency.
//! - [`HadamardOrdering::CakeCutting`] (W.-K. Yu, Sensors 19:4122, 2019): ascending number of
//!   4-connected same-sign regions ("pieces") of the reshaped pattern, with a **stable** sort so
//!   that ties keep natural order (as MATLAB's stable `sort` does; docs/bench-facts.md §10.4). Because
//!   neighbouring blocks of an outer-product ±1 pattern always differ in sign, the piece count
//!   has the closed form (seq(i) + 1)·(seq(j) + 1), which the tests check against a flood fill.
//!
//! # Origami: deliberately absent
//!
//! The origami ordering (Yu & Liu, Sensors 19:5135, 2019; arXiv 1903.11432) is **not**
//! implemented. The stored copies of the paper that could be searched (the MDPI article page and
//! the ar5iv rendering of arXiv 1903.11432) yielded only the abstract and introduction: a
//! deterministic "origami pattern construction" that reorders the Hadamard basis and reaches
//! sampling ratios down to 0.5 %. The folding rule itself (the paper's method section and
//! Fig. 1) could not be read, and no public implementation was found in the code index. An
//! ordering invented from the name would be mislabelled, so there is no `Origami` variant and an
//! experiment file that asks for one is rejected by the parser as an unknown variant.

use serde::{Deserialize, Serialize};

use super::patterns::MAX_UNITS;
use crate::error::{Error, Result};
use crate::reconstruction::BitMatrix;

/// The order in which Hadamard patterns are measured (see the module documentation).
///
/// Experiment files spell the variants in snake_case: `natural`, `walsh`, `russian_dolls`,
/// `cake_cutting`. There is no `origami` (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
// Files spell variants as Rust does (`CakeCutting`), the RON convention, or in snake_case
// (`cake_cutting`), which is what JSON output and benches written by spibench use.
#[serde(rename_all(serialize = "snake_case"))]
pub enum HadamardOrdering {
    /// Sylvester (natural) order.
    #[serde(alias = "natural")]
    Natural,
    /// 1-D sequency order of H_{s²}, rows reshaped to s×s.
    #[serde(alias = "walsh")]
    Walsh,
    /// Russian dolls (Sun et al. 2017); within-doll order is this project's choice.
    #[serde(alias = "russian_dolls")]
    RussianDolls,
    /// Cake-cutting (Yu 2019): ascending piece count, ties in natural order.
    #[serde(alias = "cake_cutting")]
    CakeCutting,
}

impl HadamardOrdering {
    pub fn all() -> [HadamardOrdering; 4] {
        [
            HadamardOrdering::Natural,
            HadamardOrdering::Walsh,
            HadamardOrdering::RussianDolls,
            HadamardOrdering::CakeCutting,
        ]
    }

    /// Human-readable name for plots and summaries.
    pub fn label(self) -> &'static str {
        match self {
            HadamardOrdering::Natural => "natural",
            HadamardOrdering::Walsh => "Walsh (sequency)",
            HadamardOrdering::RussianDolls => "Russian dolls",
            HadamardOrdering::CakeCutting => "cake-cutting",
        }
    }
}

/// Checks that `side` has a Sylvester basis and returns m = log2(side). Errors name the field
/// `patterns` (the pattern family the user chose), not the side, which no file or flag spells
/// so; a caller whose grid comes from a flag renames it (`--units`).
pub fn check_side(side: usize) -> Result<u32> {
    if side == 0 {
        return Err(Error::field(
            "patterns",
            "a Hadamard pattern set needs at least 1×1 units, got a grid side of 0",
        ));
    }
    if !side.is_power_of_two() {
        return Err(Error::field(
            "patterns",
            format!(
                "Hadamard patterns exist only for power-of-two sides (Sylvester construction), \
                 got a {side}×{side} unit grid; sizes such as 48 and 96 have no Sylvester Hadamard basis, so use \
                 random patterns for them or pick a side such as {} or {}",
                side.next_power_of_two() / 2,
                side.next_power_of_two()
            ),
        ));
    }
    match side.checked_mul(side) {
        Some(n) if n <= MAX_UNITS => Ok(side.trailing_zeros()),
        _ => Err(Error::field(
            "patterns",
            format!(
                "a {side}×{side} Hadamard pattern set is absurdly large (more than {MAX_UNITS} \
                 units); the largest supported side is {}",
                1usize << (MAX_UNITS.trailing_zeros() / 2)
            ),
        )),
    }
}

/// `h` with its lowest `bits` bits reversed (higher bits must be zero).
#[inline]
fn bitrev(h: usize, bits: u32) -> usize {
    if bits == 0 {
        0
    } else {
        h.reverse_bits() >> (usize::BITS - bits)
    }
}

#[inline]
fn gray(k: usize) -> usize {
    k ^ (k >> 1)
}

#[inline]
fn gray_decode(mut g: usize) -> usize {
    let mut k = g;
    while g > 1 {
        g >>= 1;
        k ^= g;
    }
    k
}

/// The natural (Sylvester) row of H_{2^bits} whose sequency (number of sign changes) is `k`:
/// bitrev(gray(k)).
#[inline]
pub fn sequency_to_natural(k: usize, bits: u32) -> usize {
    bitrev(gray(k), bits)
}

/// The sequency (number of sign changes) of natural row `h` of H_{2^bits}:
/// gray_decode(bitrev(h)), the inverse of [`sequency_to_natural`].
#[inline]
pub fn natural_to_sequency(h: usize, bits: u32) -> usize {
    gray_decode(bitrev(h, bits))
}

/// The number of 4-connected same-sign regions of 2-D pattern `h` on an s×s grid (s = 2^bits):
/// (seq(i) + 1)·(seq(j) + 1) with h = i·s + j.
pub fn cake_cutting_pieces(h: usize, bits: u32) -> usize {
    let side = 1usize << bits;
    let (i, j) = (h / side, h % side);
    (natural_to_sequency(i, bits) + 1) * (natural_to_sequency(j, bits) + 1)
}

/// Natural row indices h = i·s + j of all s² patterns of an s×s grid, in measurement order.
pub fn hadamard_order(side: usize, ordering: HadamardOrdering) -> Result<Vec<usize>> {
    let m = check_side(side)?;
    let n = side * side;
    let order = match ordering {
        HadamardOrdering::Natural => (0..n).collect(),
        HadamardOrdering::Walsh => (0..n).map(|k| sequency_to_natural(k, 2 * m)).collect(),
        HadamardOrdering::RussianDolls => {
            // 2-D sequency pairs (u down, v across); the doll of (u, v) is fixed by max(u, v),
            // so sorting by max(u, v) first measures whole dolls in turn.
            let mut pairs: Vec<(usize, usize)> = (0..n).map(|k| (k / side, k % side)).collect();
            pairs.sort_by_key(|&(u, v)| (u.max(v), u + v, u));
            pairs
                .into_iter()
                .map(|(u, v)| sequency_to_natural(u, m) * side + sequency_to_natural(v, m))
                .collect()
        }
        HadamardOrdering::CakeCutting => {
            let mut order: Vec<usize> = (0..n).collect();
            // `sort_by_key` is stable, so equal piece counts stay in natural order.
            order.sort_by_key(|&h| cake_cutting_pieces(h, m));
            order
        }
    };
    Ok(order)
}

/// The 0/1 DMD patterns P⁺ = (1 + H)/2 of natural rows `rows` on an s×s grid: one row per
/// pattern, unit c = r·s + col row-major, bit set where H = +1.
pub fn hadamard_patterns(side: usize, rows: &[usize]) -> Result<BitMatrix> {
    check_side(side)?;
    let n = side * side;
    if let Some(&bad) = rows.iter().find(|&&h| h >= n) {
        return Err(Error::field(
            "rows",
            format!("Hadamard row {bad} does not exist for a {side}×{side} grid (rows 0..{n})"),
        ));
    }
    let mut p = BitMatrix::zeros(rows.len(), n);
    for (r, &h) in rows.iter().enumerate() {
        for (wi, word) in p.row_words_mut(r).iter_mut().enumerate() {
            let base = wi * 64;
            let mut w = 0u64;
            for b in 0..64.min(n - base) {
                // H[h][c] = +1 when popcount(h & c) is even.
                if (h & (base + b)).count_ones() & 1 == 0 {
                    w |= 1 << b;
                }
            }
            *word = w;
        }
    }
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruction::{HadamardOperator, LinearOperator, PackedOperator, PatternForm};

    /// Entry c of natural row h of H_n as ±1.
    fn h_entry(h: usize, c: usize) -> i32 {
        if (h & c).count_ones().is_multiple_of(2) {
            1
        } else {
            -1
        }
    }

    fn sign_changes(v: &[i32]) -> usize {
        v.windows(2).filter(|w| w[0] != w[1]).count()
    }

    /// The ±1 s×s pattern of natural row h, row-major.
    fn pattern_pm(side: usize, h: usize) -> Vec<i32> {
        (0..side * side).map(|c| h_entry(h, c)).collect()
    }

    /// Number of 4-connected same-sign regions, by flood fill.
    fn flood_fill_pieces(side: usize, p: &[i32]) -> usize {
        let mut seen = vec![false; p.len()];
        let mut pieces = 0;
        for start in 0..p.len() {
            if seen[start] {
                continue;
            }
            pieces += 1;
            seen[start] = true;
            let mut stack = vec![start];
            while let Some(c) = stack.pop() {
                let (r, col) = (c / side, c % side);
                let mut nbrs = Vec::with_capacity(4);
                if r > 0 {
                    nbrs.push(c - side);
                }
                if r + 1 < side {
                    nbrs.push(c + side);
                }
                if col > 0 {
                    nbrs.push(c - 1);
                }
                if col + 1 < side {
                    nbrs.push(c + 1);
                }
                for d in nbrs {
                    if !seen[d] && p[d] == p[c] {
                        seen[d] = true;
                        stack.push(d);
                    }
                }
            }
        }
        pieces
    }

    #[test]
    fn every_ordering_is_a_permutation() {
        for side in [1, 2, 4, 8, 16, 32] {
            for ordering in HadamardOrdering::all() {
                let order = hadamard_order(side, ordering).unwrap();
                let mut seen = vec![false; side * side];
                assert_eq!(order.len(), side * side);
                for &h in &order {
                    assert!(!seen[h], "{ordering:?} repeats {h} at side {side}");
                    seen[h] = true;
                }
            }
        }
    }

    #[test]
    fn one_d_sequency_mapping_counts_sign_changes() {
        // The published sequencies of natural H16 rows (docs/bench-facts.md §10.2).
        let h16: Vec<usize> = (0..16).map(|h| natural_to_sequency(h, 4)).collect();
        assert_eq!(h16, [0, 15, 7, 8, 3, 12, 4, 11, 1, 14, 6, 9, 2, 13, 5, 10]);
        for bits in 1..=7 {
            let n = 1usize << bits;
            for k in 0..n {
                let h = sequency_to_natural(k, bits);
                let row: Vec<i32> = (0..n).map(|c| h_entry(h, c)).collect();
                assert_eq!(sign_changes(&row), k, "n = {n}, sequency {k}");
                assert_eq!(natural_to_sequency(h, bits), k);
            }
        }
        // The widely copied bitrev(gray_decode(k)) mapping fails this count at n = 8, so the
        // check above can tell the two apart.
        let wrong = |k: usize| bitrev(gray_decode(k), 3);
        let bad = (0..8).any(|k| {
            let row: Vec<i32> = (0..8).map(|c| h_entry(wrong(k), c)).collect();
            sign_changes(&row) != k
        });
        assert!(bad);
    }

    #[test]
    fn walsh_order_has_non_decreasing_sequency_and_is_a_boustrophedon() {
        for side in [2usize, 4, 8, 16, 32] {
            let m = side.trailing_zeros();
            let n = side * side;
            let order = hadamard_order(side, HadamardOrdering::Walsh).unwrap();
            let mut last = 0;
            for (k, &h) in order.iter().enumerate() {
                // Sign changes of the flattened (1-D, length s²) row, counted explicitly.
                let seq = sign_changes(&pattern_pm(side, h));
                assert!(seq >= last, "side {side}: sequency falls at {k}");
                assert_eq!(seq, k);
                last = seq;
                // The 2-D reading stated in the module documentation.
                let (u, v) = (
                    natural_to_sequency(h / side, m),
                    natural_to_sequency(h % side, m),
                );
                assert_eq!(v, k / side);
                let minor = if v % 2 == 0 {
                    k % side
                } else {
                    side - 1 - k % side
                };
                assert_eq!(u, minor, "side {side}, k {k}");
            }
            assert_eq!(order.len(), n);
        }
    }

    #[test]
    fn russian_dolls_span_block_constant_patterns() {
        for side in [8usize, 16] {
            let m = side.trailing_zeros();
            let order = hadamard_order(side, HadamardOrdering::RussianDolls).unwrap();
            for k in 0..=m {
                let count = 1usize << (2 * k);
                let block = side >> k;
                let block_constant = |h: usize| {
                    let p = pattern_pm(side, h);
                    (0..side * side).all(|c| {
                        let (r, col) = (c / side, c % side);
                        p[c] == p[(r / block * block) * side + col / block * block]
                    })
                };
                // The first 4^k patterns are distinct (permutation) and orthogonal, and the
                // block-constant patterns at 2^k × 2^k form a space of dimension exactly 4^k,
                // so being block-constant means spanning it.
                for &h in &order[..count] {
                    assert!(block_constant(h), "side {side}, doll {k}: {h}");
                    // In natural indices: both 1-D rows are multiples of 2^(m-k).
                    assert_eq!((h / side) % block, 0);
                    assert_eq!((h % side) % block, 0);
                }
                if count < side * side {
                    assert!(
                        !block_constant(order[count]),
                        "side {side}, doll {k} overflows"
                    );
                }
            }
            // The documented within-doll key is non-decreasing.
            let key = |h: usize| {
                let (u, v) = (
                    natural_to_sequency(h / side, m),
                    natural_to_sequency(h % side, m),
                );
                (u.max(v), u + v, u)
            };
            assert!(order.windows(2).all(|w| key(w[0]) < key(w[1])));
        }
    }

    #[test]
    fn cake_cutting_matches_flood_fill_and_is_stable() {
        for side in [4usize, 8, 16] {
            let m = side.trailing_zeros();
            for h in 0..side * side {
                let p = pattern_pm(side, h);
                assert_eq!(
                    cake_cutting_pieces(h, m),
                    flood_fill_pieces(side, &p),
                    "side {side}, row {h}"
                );
            }
            let order = hadamard_order(side, HadamardOrdering::CakeCutting).unwrap();
            for w in order.windows(2) {
                let (a, b) = (cake_cutting_pieces(w[0], m), cake_cutting_pieces(w[1], m));
                assert!(a <= b, "pieces fall");
                if a == b {
                    assert!(w[0] < w[1], "tie not in natural order");
                }
            }
            assert_eq!(order[0], 0);
            assert_eq!(cake_cutting_pieces(*order.last().unwrap(), m), side * side);
        }
    }

    #[test]
    fn flood_fill_counts_known_shapes() {
        // A check of the checker: a 4×4 with one island of − inside + has 2 pieces, a
        // checkerboard 16.
        let mut p = vec![1; 16];
        p[5] = -1;
        p[6] = -1;
        assert_eq!(flood_fill_pieces(4, &p), 2);
        let board: Vec<i32> = (0..16)
            .map(|c| if (c / 4 + c % 4) % 2 == 0 { 1 } else { -1 })
            .collect();
        assert_eq!(flood_fill_pieces(4, &board), 16);
    }

    #[test]
    fn non_power_of_two_sides_are_input_errors() {
        for side in [0usize, 3, 48, 96, 100] {
            let e = hadamard_order(side, HadamardOrdering::Walsh).unwrap_err();
            assert!(e.is_user_error());
            let s = e.to_string();
            assert!(s.contains("field `patterns`"), "{s}");
            if side != 0 {
                assert!(s.contains("power-of-two") && s.contains("random"), "{s}");
            }
            assert!(hadamard_patterns(side, &[0]).is_err());
        }
        let e = hadamard_order(1 << 14, HadamardOrdering::Natural).unwrap_err();
        assert!(e.to_string().contains("absurdly large"), "{e}");
        assert!(hadamard_order(1 << 13, HadamardOrdering::Natural).is_ok());
        assert!(hadamard_patterns(4, &[16]).is_err());
    }

    #[test]
    fn patterns_are_plus_one_positions_and_complement_round_trips() {
        let side = 8;
        let rows = hadamard_order(side, HadamardOrdering::CakeCutting).unwrap();
        let p = hadamard_patterns(side, &rows).unwrap();
        let c = p.complement();
        for (r, &h) in rows.iter().enumerate() {
            for u in 0..side * side {
                assert_eq!(p.get(r, u), h_entry(h, u) == 1);
                assert_eq!(c.get(r, u), h_entry(h, u) == -1);
            }
        }
        assert_eq!(c.complement(), p);
    }

    #[test]
    fn packed_patterns_agree_with_the_fast_operator() {
        // 2-D side 16 gives 256 units (four whole words); side 4 gives 16 (a partial word).
        for side in [4usize, 16] {
            let n = side * side;
            let rows = hadamard_order(side, HadamardOrdering::RussianDolls).unwrap();
            let rows = &rows[..n / 2 + 1];
            let x: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 3.5).collect();
            for form in [PatternForm::ZeroOne, PatternForm::PlusMinusOne] {
                let packed = PackedOperator::new(hadamard_patterns(side, rows).unwrap(), form);
                let fast = HadamardOperator::new(n, rows.to_vec(), form);
                let (mut a, mut b) = (vec![0.0; rows.len()], vec![0.0; rows.len()]);
                packed.apply(&x, &mut a);
                fast.apply(&x, &mut b);
                for (u, v) in a.iter().zip(&b) {
                    assert!((u - v).abs() < 1e-9, "{form:?}: {u} vs {v}");
                }
            }
        }
    }

    #[test]
    fn experiment_files_name_orderings_and_reject_origami() {
        use crate::scene::parse_ron;
        use std::path::Path;
        let p = Path::new("e.ron");
        assert_eq!(
            parse_ron::<HadamardOrdering>("CakeCutting", p).unwrap(),
            HadamardOrdering::CakeCutting
        );
        assert_eq!(
            parse_ron::<HadamardOrdering>("RussianDolls", p).unwrap(),
            HadamardOrdering::RussianDolls
        );
        for name in ["origami", "Origami"] {
            let e = parse_ron::<HadamardOrdering>(name, p).unwrap_err();
            assert!(e.is_user_error());
            let s = e.to_string();
            assert!(s.contains(name) && s.contains("CakeCutting"), "{s}");
        }
    }
}
