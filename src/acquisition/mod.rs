//! Patterns (random, Hadamard with orderings) and the four acquisition schemes.
//!
//! - [`patterns`]: pattern sets (random bit-packed, Hadamard implicit) and their operators;
//! - [`hadamard`]: Sylvester patterns and the natural, Walsh, Russian-dolls and cake-cutting
//!   orderings (origami is deliberately absent; see that module);
//! - [`schemes`]: traditional, single-arm complementary, double-arm and secondary complementary
//!   balancing acquisition with scalar arm gains (paper Eqs. 6–12);
//! - [`noise`]: the paper's additive Gaussian, exponential and Poisson noise.

pub mod hadamard;
pub mod noise;
pub mod patterns;
pub mod schemes;

pub use hadamard::{HadamardOrdering, hadamard_order, hadamard_patterns};
pub use noise::{AdditiveNoise, NoiseDistribution};
pub use patterns::{
    PackedPatterns, PatternFamily, PatternSet, hadamard_set, patterns_for_ratio, random_set,
};
pub use schemes::{
    Acquisition, DEFAULT_DMD_RATE_HZ, Output, ScalarArms, Scheme, Sequence, acquire,
};
