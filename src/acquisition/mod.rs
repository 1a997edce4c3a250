//! Patterns (random, Hadamard with orderings) and the four acquisition schemes.

pub mod patterns;
