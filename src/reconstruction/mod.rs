//! Linear operators and the TVAL3-class total-variation solver. Knows nothing of optics.

pub mod bitmatrix;
pub mod operator;
pub mod tval3;

pub use bitmatrix::BitMatrix;
pub use operator::{HadamardOperator, LinearOperator, PackedOperator, PatternForm, fwht};
pub use tval3::{Init, StopReason, TvNorm, Tval3Options, Tval3Output, tval3};
