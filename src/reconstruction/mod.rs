//! Linear operators and the TVAL3-class total-variation solver. Knows nothing of optics.

pub mod bitmatrix;

pub use bitmatrix::BitMatrix;
