//! DMD pattern sets, always bit-packed, each with its complement.

use crate::reconstruction::BitMatrix;
use crate::rng::SplitMix64;

/// `rows` random 0/1 patterns of `cols` units each, every bit equally likely.
///
/// Bits come from the SplitMix64 sequence seeded with `seed`, read least significant bit first
/// and row-major over the whole matrix: bit t of the flattened matrix is bit `t % 64` of output
/// `t / 64`. This is the convention of the TVAL3 reference problems, so seed 0x5EED0001
/// reproduces their pattern matrix exactly.
pub fn random(rows: usize, cols: usize, seed: u64) -> BitMatrix {
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
            if word & 1 == 1 {
                m.set(r, c, true);
            }
            word >>= 1;
            avail -= 1;
        }
    }
    m
}
