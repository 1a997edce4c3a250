//! Matrix-free measurement operators.
//!
//! No operator stores a dense float matrix: pattern sets are bit-packed ([`BitMatrix`]) and
//! Hadamard sets are rows of a Sylvester matrix applied with the fast Walsh–Hadamard transform.
//!
//! # The packed kernels
//!
//! A product with a 0/1 matrix is a sum of subsets of the input. The "Four Russians" lookup-table
//! method groups the input in runs of 8 elements and tabulates, per run, all 256 subset sums; one
//! byte of a pattern row then selects its partial sum with a single load, replacing 8 masked
//! additions (docs/rust-notes.md §9 measured 8.3 ms against 33.6 ms for iterating set bits on a
//! 4096 × 16384 matrix). The adjoint uses the same kernel on a transposed copy of the bits that is
//! built once, at construction.
//!
//! Three further choices bring the 4096 × 16384 product to about 2.3 ms on one thread and 1.2 ms
//! on two (benches/tval3.rs; a dense f64 product takes about 45 ms):
//! - Cache blocking. The tables of all groups together are 2 KiB × cols/8 (4 MiB for 16384
//!   columns), far more than the L1 cache, and a row visits one random line of every table. The
//!   pattern bytes are therefore stored in blocks of `BLOCK_GROUPS` consecutive groups (row by
//!   row inside a block), and a task builds the tables of one block (32 KiB), sweeps all its rows
//!   through that block and only then moves on. The lookups then stay in L1, and the pattern
//!   bytes stream through memory in storage order. Building the tables costs about 5 % of a
//!   product.
//! - Balanced byte extraction in the inner loop (see `sweep_block`).
//! - For `PlusMinusOne` the tables hold signed subset sums Σ ±x directly, which is the
//!   measurement 2·P·x − Σx evaluated group by group: the same number of lookups as the 0/1
//!   product, no final correction, and no cancellation between two large sums.
//!
//! Entries stay f64: the result equals the bit-by-bit sum to rounding (about 1e-15 relative),
//! and the kernel is bound by the number of lookups, not by the size of an entry.
//!
//! # Determinism
//!
//! Output elements are split into contiguous chunks (one per thread, at least `MIN_CHUNK_ROWS`
//! rows each), one rayon task each; every output element is
//! written by exactly one task, and the order of its floating-point operations (block by block,
//! group by group, each table built by the same recurrence) does not depend on how the outputs are
//! chunked. Results are therefore bit-identical for any number of threads, which the tests check.

use rayon::prelude::*;

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

/// Number of 8-element groups whose tables are built and used together (16 × 2 KiB = 32 KiB of
/// f64 tables, the L1 data cache of common x86-64 cores). Measured on the 4096 × 16384 product
/// (AMD Zen 3): 8 and 16 groups are equal within noise, 32 and 64 were about 50 % slower as the
/// tables spill out of L1.
const BLOCK_GROUPS: usize = 16;

/// The fewest output rows a product gives one chunk (one rayon task), so that building the
/// chunk's tables (the work of sweeping ~256 rows) stays at most a quarter of it. One chunk per
/// thread built the tables once per thread: a dataset sample, whose products (about a thousand
/// rows) run inside the parallel sample loop, cost 16.5 % more CPU on 16 threads than on one
/// (measured as 16 threads on one core, where nothing runs in parallel; 3.6 % with this bound).
const MIN_CHUNK_ROWS: usize = 1024;

/// The bytes of a 0/1 matrix (8 input elements per byte, bit b of byte g = input 8g + b),
/// stored block by block for the cache-blocked lookup kernel.
///
/// Layout: for block k (groups `k·BLOCK_GROUPS ..`, `w_k` groups wide, the last block possibly
/// narrower), the `out_len × w_k` bytes of that block, row-major. So the bytes a row needs from
/// one block are contiguous, and a range of rows of one block is contiguous too.
#[derive(Debug, Clone)]
struct ByteBlocks {
    out_len: usize,
    in_len: usize,
    groups: usize,
    bytes: Vec<u8>,
}

impl ByteBlocks {
    fn zeros(out_len: usize, in_len: usize) -> Self {
        let groups = in_len.div_ceil(8);
        ByteBlocks {
            out_len,
            in_len,
            groups,
            bytes: vec![0u8; out_len * groups],
        }
    }

    /// Position of byte (row, group): every block before the one holding `group` is full width.
    #[inline]
    fn index(&self, row: usize, group: usize) -> usize {
        let g0 = group - group % BLOCK_GROUPS;
        let w = BLOCK_GROUPS.min(self.groups - g0);
        g0 * self.out_len + row * w + (group - g0)
    }

    /// The rows of a row-major bit matrix, 8 columns per byte (byte k of a little-endian word is
    /// columns 8k .. 8k + 7, least significant bit first, which is exactly a group).
    fn from_rows(m: &BitMatrix) -> Self {
        let mut out = ByteBlocks::zeros(m.rows(), m.cols());
        // A row's bytes within one block are contiguous in the layout: one copy per row and
        // block (this runs for every record's frame currents, so it is kept at memcpy speed).
        let mut row = Vec::with_capacity(8 * m.words_per_row());
        for r in 0..m.rows() {
            row.clear();
            row.extend(m.row_words(r).iter().flat_map(|w| w.to_le_bytes()));
            for g0 in (0..out.groups).step_by(BLOCK_GROUPS) {
                let w = BLOCK_GROUPS.min(out.groups - g0);
                let at = out.index(r, g0);
                out.bytes[at..at + w].copy_from_slice(&row[g0..g0 + w]);
            }
        }
        out
    }

    /// The columns of a row-major bit matrix (that is, the rows of its transpose), 8 rows of the
    /// original per byte, built 8×8 bits at a time: byte k of the words of rows 8g .. 8g + 7 at
    /// one word index form an 8×8 block whose transpose holds, in byte j, column 8k + j of those
    /// rows.
    fn from_columns(m: &BitMatrix) -> Self {
        let rows = m.rows();
        let cols = m.cols();
        let mut out = ByteBlocks::zeros(cols, rows);
        for g in 0..out.groups {
            for wi in 0..m.words_per_row() {
                let mut words = [0u64; 8];
                for (i, w) in words.iter_mut().enumerate() {
                    if 8 * g + i < rows {
                        *w = m.row_words(8 * g + i)[wi];
                    }
                }
                for k in 0..8 {
                    let block = words.iter().enumerate().fold(0u64, |acc, (i, &w)| {
                        acc | (((w >> (8 * k)) & 0xFF) << (8 * i))
                    });
                    let t = transpose8(block).to_le_bytes();
                    for (j, &byte) in t.iter().enumerate() {
                        let c = 64 * wi + 8 * k + j;
                        if c < cols {
                            let i = out.index(c, g);
                            out.bytes[i] = byte;
                        }
                    }
                }
            }
        }
        out
    }
}

/// Transposes an 8×8 bit matrix held in a u64 (byte i = row i, bit j of it = column j) in three
/// rounds of masked swaps (Warren, Hacker's Delight §7-3): 2×2 blocks, then 4×4, then 8×8.
#[inline]
fn transpose8(mut x: u64) -> u64 {
    let t = (x ^ (x >> 7)) & 0x00AA_00AA_00AA_00AA;
    x ^= t ^ (t << 7);
    let t = (x ^ (x >> 14)) & 0x0000_CCCC_0000_CCCC;
    x ^= t ^ (t << 14);
    let t = (x ^ (x >> 28)) & 0x0000_0000_F0F0_F0F0;
    x ^= t ^ (t << 28);
    x
}

/// Fills `table` with the 256 subset sums of the (up to) 8 values in `xs`: entry k is
/// Σ_b [bit b of k] x_b for `ZeroOne` and Σ_b ±x_b (+ where bit b is set) for `PlusMinusOne`.
/// Missing values (a short last group) count as zero.
///
/// Built as the sum of two 16-entry tables, one per half byte: entry 16h + l = lo[l] + hi[h].
/// The 256 additions are then 16 runs of 16 independent additions, which vectorise fully.
#[inline]
fn build_table(table: &mut [f64; 256], xs: &[f64], form: PatternForm) {
    let mut v = [0.0f64; 8];
    v[..xs.len()].copy_from_slice(xs);
    let lo = nibble_table(&[v[0], v[1], v[2], v[3]], form);
    let hi = nibble_table(&[v[4], v[5], v[6], v[7]], form);
    for (row, &h) in table.chunks_exact_mut(16).zip(hi.iter()) {
        for (t, &l) in row.iter_mut().zip(lo.iter()) {
            *t = l + h;
        }
    }
}

/// The 16 subset sums of 4 values (signed sums for `PlusMinusOne`).
#[inline]
fn nibble_table(v: &[f64; 4], form: PatternForm) -> [f64; 16] {
    let (base, scale) = match form {
        PatternForm::ZeroOne => (0.0, 1.0),
        PatternForm::PlusMinusOne => (-((v[0] + v[1]) + (v[2] + v[3])), 2.0),
    };
    let mut t = [0.0f64; 16];
    t[0] = base;
    for (b, &vb) in v.iter().enumerate() {
        let step = scale * vb;
        let half = 1usize << b;
        for k in 0..half {
            t[half + k] = t[k] + step;
        }
    }
    t
}

/// One block of the kernel: adds to every element of `out` the sum of its `W` table lookups.
/// `W` is a compile-time width (a multiple of 8) so the loop is fully unrolled.
///
/// Each lookup needs its byte in a register. Loading every byte separately makes the loads the
/// bottleneck, extracting every byte from 64-bit words by shifts makes the integer units the
/// bottleneck; loading the first 4 bytes one by one and shifting the other 12 out of a 32-bit
/// and a 64-bit word balances the two and measured about 12 % faster than either (Zen 3).
///
/// The loops are `while` loops over indices, not ranges: the test profile builds this crate at
/// opt-level 1, which does not inline a range's `next`, and with ranges this kernel spent half
/// its time in those calls there (the paper's Fig. 1 test took 48 s); the release build unrolls
/// either form into the same code.
#[inline]
fn sweep_block<const W: usize>(tables: &[[f64; 256]], data: &[u8], out: &mut [f64]) {
    const { assert!(W.is_multiple_of(8) && W >= 8) };
    let tables: &[[f64; 256]; W] = tables[..W]
        .try_into()
        .expect("table count equals block width");
    assert_eq!(data.len(), out.len() * W, "a row of W bytes per output");
    let mut r = 0;
    while r < out.len() {
        let row: &[u8; W] = data[r * W..(r + 1) * W].try_into().expect("row width");
        // Four partial sums shorten the dependency chain of the additions. Lookup j always goes
        // to sum j % 4, so the order of operations is fixed.
        let mut acc = [0.0f64; 4];
        let mut j = 0;
        while j < 4 {
            acc[j] += tables[j][row[j] as usize];
            j += 1;
        }
        let w = u32::from_le_bytes([row[4], row[5], row[6], row[7]]);
        while j < 8 {
            acc[j % 4] += tables[j][(w >> (8 * (j - 4))) as u8 as usize];
            j += 1;
        }
        while j < W {
            let w = u64::from_le_bytes(row[j..j + 8].try_into().expect("8 bytes"));
            let mut k = 0;
            while k < 8 {
                acc[(j + k) % 4] += tables[j + k][(w >> (8 * k)) as u8 as usize];
                k += 1;
            }
            j += 8;
        }
        out[r] += (acc[0] + acc[1]) + (acc[2] + acc[3]);
        r += 1;
    }
}

/// The same for a block narrower than [`BLOCK_GROUPS`] (only the last block of a matrix).
fn sweep_block_dyn(tables: &[[f64; 256]], w: usize, data: &[u8], out: &mut [f64]) {
    for (o, row) in out.iter_mut().zip(data.chunks_exact(w)) {
        let mut acc = [0.0f64; 4];
        for (j, (t, &b)) in tables.iter().zip(row).enumerate() {
            acc[j % 4] += t[b as usize];
        }
        *o += (acc[0] + acc[1]) + (acc[2] + acc[3]);
    }
}

/// `out = M x` for the stored 0/1 matrix M used in `form`, with the cache-blocked LUT kernel.
fn lut_product(m: &ByteBlocks, x: &[f64], out: &mut [f64], form: PatternForm) {
    assert_eq!(x.len(), m.in_len, "input length");
    assert_eq!(out.len(), m.out_len, "output length");
    if m.out_len == 0 {
        return;
    }
    // At most one chunk of outputs per thread, and at least MIN_CHUNK_ROWS rows a chunk: every
    // chunk builds all tables (as much work as sweeping ~256 rows), so more chunks only repeat
    // that work. The chunking does not change any output bit (see the module documentation).
    let tasks = m
        .out_len
        .div_ceil(MIN_CHUNK_ROWS)
        .clamp(1, rayon::current_num_threads().max(1));
    let chunk = m.out_len.div_ceil(tasks).max(1);
    out.par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(ci, out_chunk)| {
            let r0 = ci * chunk;
            let rows = out_chunk.len();
            let mut tables = vec![[0.0f64; 256]; BLOCK_GROUPS];
            out_chunk.iter_mut().for_each(|v| *v = 0.0);
            let mut offset = 0;
            for g0 in (0..m.groups).step_by(BLOCK_GROUPS) {
                let w = BLOCK_GROUPS.min(m.groups - g0);
                for (j, t) in tables[..w].iter_mut().enumerate() {
                    let c0 = 8 * (g0 + j);
                    build_table(t, &x[c0..(c0 + 8).min(m.in_len)], form);
                }
                let data = &m.bytes[offset + r0 * w..offset + (r0 + rows) * w];
                if w == BLOCK_GROUPS {
                    sweep_block::<BLOCK_GROUPS>(&tables, data, out_chunk);
                } else {
                    sweep_block_dyn(&tables, w, data, out_chunk);
                }
                offset += m.out_len * w;
            }
        });
}

/// A bit-packed pattern set used as `P` or as `2P − 1`.
///
/// Construction lays the patterns out row-wise for the lookup kernel of `A x`; the column-wise
/// layout for `Aᵀ y` (the bit matrix's transpose) is made on the first adjoint product, since
/// many users never need one (the frame currents of every dataset sample and every record, where
/// the transpose was most of the time). 1 bit per entry each, so with the bit matrix itself at
/// most 3 bits per entry: 24 MiB for 4096 × 16384.
#[derive(Debug, Clone)]
pub struct PackedOperator {
    patterns: BitMatrix,
    form: PatternForm,
    forward: ByteBlocks,
    adjoint: std::sync::OnceLock<ByteBlocks>,
}

impl PackedOperator {
    pub fn new(patterns: BitMatrix, form: PatternForm) -> Self {
        let forward = ByteBlocks::from_rows(&patterns);
        PackedOperator {
            patterns,
            form,
            forward,
            adjoint: std::sync::OnceLock::new(),
        }
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
        lut_product(&self.forward, x, y, self.form);
    }

    fn apply_adjoint(&self, y: &[f64], x: &mut [f64]) {
        // (2P − 1)ᵀ y = 2 Pᵀ y − Σy: the same signed tables, now over groups of 8 measurements.
        let adjoint = self
            .adjoint
            .get_or_init(|| ByteBlocks::from_columns(&self.patterns));
        lut_product(adjoint, y, x, self.form);
    }
}

/// Selected rows of the Sylvester Hadamard matrix of order `n` (a power of two), given by their
/// natural indices, used as `(1 + H)/2` (ZeroOne) or `H` (PlusMinusOne).
///
/// For 2-D patterns on an s×s grid with s a power of two, n = s² and natural row h = i·s + j,
/// reshaped row-major, is the outer product of 1-D rows i and j (docs/bench-facts.md §10.1).
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
        // All N rows of H x cost O(N log N) with the FWHT; the selected rows are then read off.
        let mut t = x.to_vec();
        fwht(&mut t);
        // Row 0 of H is all ones, so (1 + H)/2 needs Σx = (H x)[0] and no separate sum.
        let total = t[0];
        for (yi, &h) in y.iter_mut().zip(&self.rows) {
            *yi = match self.form {
                PatternForm::PlusMinusOne => t[h],
                PatternForm::ZeroOne => 0.5 * (total + t[h]),
            };
        }
    }

    fn apply_adjoint(&self, y: &[f64], x: &mut [f64]) {
        // H is symmetric, so Hᵀ scatters y into the selected rows and transforms back; the
        // all-ones part of (1 + H)/2 adds Σy/2 to every element, which is the same as adding
        // Σy/2 to row 0 before the transform.
        x.iter_mut().for_each(|v| *v = 0.0);
        let mut ysum = 0.0;
        for (&yi, &h) in y.iter().zip(&self.rows) {
            x[h] += match self.form {
                PatternForm::PlusMinusOne => yi,
                PatternForm::ZeroOne => 0.5 * yi,
            };
            ysum += yi;
        }
        if self.form == PatternForm::ZeroOne {
            x[0] += 0.5 * ysum;
        }
        fwht(x);
    }
}

/// In-place unnormalised fast Walsh–Hadamard transform in natural (Sylvester) order:
/// `x ← H x` with `H[i][j] = (−1)^popcount(i & j)`. The length must be a power of two.
pub fn fwht(x: &mut [f64]) {
    let n = x.len();
    assert!(n.is_power_of_two(), "FWHT length {n} is not a power of two");
    let mut h = 1;
    while h < n {
        for block in x.chunks_exact_mut(2 * h) {
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

#[cfg(test)]
mod tests;
