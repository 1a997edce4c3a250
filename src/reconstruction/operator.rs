//! Matrix-free measurement operators.
//!
//! No operator stores a dense float matrix: pattern sets are bit-packed ([`BitMatrix`]) and
//! Hadamard sets are rows of a Sylvester matrix applied with the fast Walsh–Hadamard transform.

use super::bitmatrix::BitMatrix;

/// A linear map from images (length `cols`, row-major) to measurements (length `rows`).
pub trait LinearOperator: Send + Sync {
    fn rows(&self) -> usize;
    fn cols(&self) -> usize;
    /// `y = A x`; `y` has length `rows()`, `x` length `cols()`.
    fn apply(&self, x: &[f64], y: &mut [f64]);
    /// `x = Aᵀ y`; overwrites `x`.
    fn apply_adjoint(&self, y: &[f64], x: &mut [f64]);
}

/// How a 0/1 pattern enters the measurement: as itself (one detector, one frame) or as
/// `2P − 1` (a complementary difference, P minus its complement).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum PatternForm {
    /// A = P, entries 0 and 1.
    ZeroOne,
    /// Â = 2P − 1, entries −1 and +1.
    PlusMinusOne,
}

/// A bit-packed pattern set used as `P` or as `2P − 1`.
#[derive(Debug, Clone)]
pub struct PackedOperator {
    patterns: BitMatrix,
    form: PatternForm,
}

impl PackedOperator {
    pub fn new(patterns: BitMatrix, form: PatternForm) -> Self {
        PackedOperator { patterns, form }
    }

    pub fn patterns(&self) -> &BitMatrix {
        &self.patterns
    }

    pub fn form(&self) -> PatternForm {
        self.form
    }
}

impl LinearOperator for PackedOperator {
    fn rows(&self) -> usize {
        self.patterns.rows()
    }

    fn cols(&self) -> usize {
        self.patterns.cols()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let total: f64 = x.iter().sum();
        for (r, yr) in y.iter_mut().enumerate() {
            let mut s = 0.0;
            for (wi, &w) in self.patterns.row_words(r).iter().enumerate() {
                let mut bits = w;
                while bits != 0 {
                    s += x[wi * 64 + bits.trailing_zeros() as usize];
                    bits &= bits - 1;
                }
            }
            *yr = match self.form {
                PatternForm::ZeroOne => s,
                PatternForm::PlusMinusOne => 2.0 * s - total,
            };
        }
    }

    fn apply_adjoint(&self, y: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        let mut ysum = 0.0;
        for (r, &yr) in y.iter().enumerate() {
            ysum += yr;
            let scale = match self.form {
                PatternForm::ZeroOne => yr,
                PatternForm::PlusMinusOne => 2.0 * yr,
            };
            for (wi, &w) in self.patterns.row_words(r).iter().enumerate() {
                let mut bits = w;
                while bits != 0 {
                    x[wi * 64 + bits.trailing_zeros() as usize] += scale;
                    bits &= bits - 1;
                }
            }
        }
        if self.form == PatternForm::PlusMinusOne {
            x.iter_mut().for_each(|v| *v -= ysum);
        }
    }
}

/// Selected rows of the Sylvester Hadamard matrix of order `n` (a power of two), given by their
/// natural indices, used as `(1 + H)/2` (ZeroOne) or `H` (PlusMinusOne).
///
/// For 2-D patterns on an s×s grid with s a power of two, n = s² and natural row h = i·s + j,
/// reshaped row-major, is the outer product of 1-D rows i and j (bench-facts §10.1).
#[derive(Debug, Clone)]
pub struct HadamardOperator {
    order: usize,
    rows: Vec<usize>,
    form: PatternForm,
}

impl HadamardOperator {
    /// Panics if `order` is not a power of two or a row index is out of range; callers validate
    /// user sizes first and report them as input errors.
    pub fn new(order: usize, rows: Vec<usize>, form: PatternForm) -> Self {
        assert!(
            order.is_power_of_two(),
            "Hadamard order {order} is not a power of two"
        );
        assert!(
            rows.iter().all(|&r| r < order),
            "Hadamard row index out of range"
        );
        HadamardOperator { order, rows, form }
    }

    pub fn order(&self) -> usize {
        self.order
    }

    /// Natural (Sylvester) indices of the rows, in measurement order.
    pub fn row_indices(&self) -> &[usize] {
        &self.rows
    }

    pub fn form(&self) -> PatternForm {
        self.form
    }
}

impl LinearOperator for HadamardOperator {
    fn rows(&self) -> usize {
        self.rows.len()
    }

    fn cols(&self) -> usize {
        self.order
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let mut t = x.to_vec();
        fwht(&mut t);
        let total: f64 = x.iter().sum();
        for (yi, &h) in y.iter_mut().zip(&self.rows) {
            *yi = match self.form {
                PatternForm::PlusMinusOne => t[h],
                PatternForm::ZeroOne => 0.5 * (total + t[h]),
            };
        }
    }

    fn apply_adjoint(&self, y: &[f64], x: &mut [f64]) {
        // H is symmetric, so Hᵀ scatters y into the selected rows and transforms back.
        let mut t = vec![0.0; self.order];
        let mut ysum = 0.0;
        for (&yi, &h) in y.iter().zip(&self.rows) {
            t[h] += match self.form {
                PatternForm::PlusMinusOne => yi,
                PatternForm::ZeroOne => 0.5 * yi,
            };
            ysum += yi;
        }
        fwht(&mut t);
        x.copy_from_slice(&t);
        if self.form == PatternForm::ZeroOne {
            x.iter_mut().for_each(|v| *v += 0.5 * ysum);
        }
    }
}

/// In-place unnormalised fast Walsh–Hadamard transform in natural (Sylvester) order:
/// `x ← H x` with `H[i][j] = (−1)^popcount(i & j)`. The length must be a power of two.
pub fn fwht(x: &mut [f64]) {
    let n = x.len();
    assert!(n.is_power_of_two(), "FWHT length {n} is not a power of two");
    let mut h = 1;
    while h < n {
        for block in x.chunks_mut(2 * h) {
            let (a, b) = block.split_at_mut(h);
            for (u, v) in a.iter_mut().zip(b.iter_mut()) {
                let (s, d) = (*u + *v, *u - *v);
                *u = s;
                *v = d;
            }
        }
        h *= 2;
    }
}
