//! The optics of the bench, pure and in SI units (metres, watts, amperes): spectra, glasses,
//! Fresnel and thin-film coatings, analytic surfaces, meshes (obvhs), the DMD and the two
//! detection arms it serves, the chart masks, the lamp and the assembled [`bench::Bench`]. Knows
//! nothing of files, threads or serde.

pub mod arm;
pub mod bench;
pub mod chart;
pub mod diffraction;
pub mod dmd;
pub mod fresnel;
pub mod geometry;
pub mod glass;
pub mod guide;
pub mod lamp;
pub mod lens;
pub mod mesh;
pub mod monochromatic;
pub mod outline;
pub mod spectrum;

pub use arm::Arm;
pub use bench::Bench;
