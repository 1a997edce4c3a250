//! Linear operators and the TVAL3-class total-variation solver. Knows nothing of optics.

pub mod bitmatrix;
pub mod operator;

pub use bitmatrix::BitMatrix;
pub use operator::{HadamardOperator, LinearOperator, PackedOperator, PatternForm, fwht};
