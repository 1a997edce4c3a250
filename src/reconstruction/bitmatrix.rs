//! A bit-packed 0/1 matrix: the storage of every pattern set.
//!
//! Row i, column j is bit `j % 64` of word `i * words_per_row + j / 64` (least significant bit
//! first). Padding bits past `cols` in the last word of a row are always zero, so word-wise
//! operations (complement, popcount) need only mask the last word.

use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BitMatrix {
    rows: usize,
    cols: usize,
    words_per_row: usize,
    words: Vec<u64>,
}

impl BitMatrix {
    pub fn zeros(rows: usize, cols: usize) -> Self {
        let words_per_row = cols.div_ceil(64);
        BitMatrix {
            rows,
            cols,
            words_per_row,
            words: vec![0; rows * words_per_row],
        }
    }

    /// Builds from packed words; padding bits are cleared.
    pub fn from_words(rows: usize, cols: usize, mut words: Vec<u64>) -> Result<Self> {
        let words_per_row = cols.div_ceil(64);
        if words.len() != rows * words_per_row {
            return Err(Error::input(format!(
                "{} words cannot hold a {rows}×{cols} bit matrix ({} expected)",
                words.len(),
                rows * words_per_row
            )));
        }
        let mask = Self::last_word_mask(cols);
        if words_per_row > 0 {
            for r in 0..rows {
                words[r * words_per_row + words_per_row - 1] &= mask;
            }
        }
        Ok(BitMatrix {
            rows,
            cols,
            words_per_row,
            words,
        })
    }

    pub fn from_fn(rows: usize, cols: usize, f: impl Fn(usize, usize) -> bool) -> Self {
        let mut m = BitMatrix::zeros(rows, cols);
        for r in 0..rows {
            for c in 0..cols {
                if f(r, c) {
                    m.set(r, c, true);
                }
            }
        }
        m
    }

    /// From a row-major array of 0/1 bytes (any non-zero byte is 1).
    pub fn from_bytes01(rows: usize, cols: usize, bytes: &[u8]) -> Result<Self> {
        if bytes.len() != rows * cols {
            return Err(Error::input(format!(
                "{} values cannot form a {rows}×{cols} pattern matrix",
                bytes.len()
            )));
        }
        let mut m = BitMatrix::zeros(rows, cols);
        for r in 0..rows {
            let row = &bytes[r * cols..(r + 1) * cols];
            let words = m.row_words_mut(r);
            for (c, &b) in row.iter().enumerate() {
                if b != 0 {
                    words[c / 64] |= 1 << (c % 64);
                }
            }
        }
        Ok(m)
    }

    /// From `numpy.packbits(P, axis=1)`: each row is `ceil(cols / 8)` bytes, most significant
    /// bit first within a byte.
    pub fn from_packbits(rows: usize, cols: usize, bytes: &[u8]) -> Result<Self> {
        let bytes_per_row = cols.div_ceil(8);
        if bytes.len() != rows * bytes_per_row {
            return Err(Error::input(format!(
                "{} packed bytes cannot form a {rows}×{cols} pattern matrix ({} expected)",
                bytes.len(),
                rows * bytes_per_row
            )));
        }
        let mut m = BitMatrix::zeros(rows, cols);
        for r in 0..rows {
            let row = &bytes[r * bytes_per_row..(r + 1) * bytes_per_row];
            let words = m.row_words_mut(r);
            for c in 0..cols {
                if (row[c / 8] >> (7 - c % 8)) & 1 == 1 {
                    words[c / 64] |= 1 << (c % 64);
                }
            }
        }
        Ok(m)
    }

    #[inline]
    fn last_word_mask(cols: usize) -> u64 {
        match cols % 64 {
            0 => u64::MAX,
            r => (1u64 << r) - 1,
        }
    }

    pub fn rows(&self) -> usize {
        self.rows
    }

    pub fn cols(&self) -> usize {
        self.cols
    }

    pub fn words_per_row(&self) -> usize {
        self.words_per_row
    }

    pub fn words(&self) -> &[u64] {
        &self.words
    }

    #[inline]
    pub fn get(&self, r: usize, c: usize) -> bool {
        debug_assert!(r < self.rows && c < self.cols);
        (self.words[r * self.words_per_row + c / 64] >> (c % 64)) & 1 == 1
    }

    #[inline]
    pub fn set(&mut self, r: usize, c: usize, v: bool) {
        debug_assert!(r < self.rows && c < self.cols);
        let w = &mut self.words[r * self.words_per_row + c / 64];
        if v {
            *w |= 1 << (c % 64);
        } else {
            *w &= !(1 << (c % 64));
        }
    }

    #[inline]
    pub fn row_words(&self, r: usize) -> &[u64] {
        &self.words[r * self.words_per_row..(r + 1) * self.words_per_row]
    }

    #[inline]
    pub fn row_words_mut(&mut self, r: usize) -> &mut [u64] {
        &mut self.words[r * self.words_per_row..(r + 1) * self.words_per_row]
    }

    /// Number of ones in row r.
    pub fn row_count(&self, r: usize) -> usize {
        self.row_words(r)
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum()
    }

    /// The complementary pattern set 1 − P (what the other DMD arm sees).
    pub fn complement(&self) -> BitMatrix {
        let mask = Self::last_word_mask(self.cols);
        let mut words: Vec<u64> = self.words.iter().map(|w| !w).collect();
        if self.words_per_row > 0 {
            for r in 0..self.rows {
                words[r * self.words_per_row + self.words_per_row - 1] &= mask;
            }
        }
        BitMatrix {
            rows: self.rows,
            cols: self.cols,
            words_per_row: self.words_per_row,
            words,
        }
    }

    /// The first `m` rows.
    pub fn head(&self, m: usize) -> BitMatrix {
        let m = m.min(self.rows);
        BitMatrix {
            rows: m,
            cols: self.cols,
            words_per_row: self.words_per_row,
            words: self.words[..m * self.words_per_row].to_vec(),
        }
    }

    /// The transpose, also bit-packed (used for fast adjoint products).
    pub fn transpose(&self) -> BitMatrix {
        let mut t = BitMatrix::zeros(self.cols, self.rows);
        for r in 0..self.rows {
            let words = self.row_words(r);
            for (wi, &w) in words.iter().enumerate() {
                let mut bits = w;
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    let c = wi * 64 + b;
                    t.words[c * t.words_per_row + r / 64] |= 1 << (r % 64);
                    bits &= bits - 1;
                }
            }
        }
        t
    }

    /// Row r as 0/1 bytes.
    pub fn row_bytes01(&self, r: usize) -> Vec<u8> {
        (0..self.cols).map(|c| self.get(r, c) as u8).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(rows: usize, cols: usize) -> BitMatrix {
        BitMatrix::from_fn(rows, cols, |r, c| (r * 7 + c * 13 + r * c) % 3 == 0)
    }

    #[test]
    fn complement_of_complement_is_the_pattern() {
        for cols in [1, 63, 64, 65, 130] {
            let m = sample(5, cols);
            let c = m.complement();
            for r in 0..5 {
                assert_eq!(m.row_count(r) + c.row_count(r), cols);
                for j in 0..cols {
                    assert_ne!(m.get(r, j), c.get(r, j));
                }
            }
            assert_eq!(c.complement(), m);
        }
    }

    #[test]
    fn packbits_and_bytes_agree() {
        let m = sample(3, 21);
        let bytes: Vec<u8> = (0..3).flat_map(|r| m.row_bytes01(r)).collect();
        assert_eq!(BitMatrix::from_bytes01(3, 21, &bytes).unwrap(), m);
        // numpy.packbits: most significant bit first, rows padded to whole bytes.
        let mut packed = Vec::new();
        for r in 0..3 {
            for b in 0..21usize.div_ceil(8) {
                let mut byte = 0u8;
                for k in 0..8 {
                    let c = b * 8 + k;
                    if c < 21 && m.get(r, c) {
                        byte |= 0x80 >> k;
                    }
                }
                packed.push(byte);
            }
        }
        assert_eq!(BitMatrix::from_packbits(3, 21, &packed).unwrap(), m);
        assert!(BitMatrix::from_packbits(3, 21, &packed[1..]).is_err());
    }

    #[test]
    fn transpose_twice_is_identity() {
        let m = sample(70, 131);
        let t = m.transpose();
        assert_eq!(t.rows(), 131);
        for r in 0..70 {
            for c in 0..131 {
                assert_eq!(m.get(r, c), t.get(c, r));
            }
        }
        assert_eq!(t.transpose(), m);
    }
}
