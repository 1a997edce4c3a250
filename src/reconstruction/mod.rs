//! Linear operators, the TVAL3-class total-variation solver, and [`Solver`], the one entry point
//! that says how measurements are reconstructed. Knows nothing of optics.

pub mod bitmatrix;
pub mod operator;
pub mod solver;
pub mod tval3;

pub use bitmatrix::BitMatrix;
pub use operator::{HadamardOperator, LinearOperator, PackedOperator, PatternForm, fwht};
pub use solver::{Solution, Solver, ZeroOneHandling};
pub use tval3::{Init, StopReason, TvNorm, Tval3Options, Tval3Output, tval3};
