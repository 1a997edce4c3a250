//! Output files: JSON summaries, images (PNG, EXR), arrays (.npy), plots and HTML reports.
//! Together with `scene` and `cli`, the only module that touches files.

pub mod csv;
pub mod exr;
mod font;
pub mod heatmap;
pub mod html;
pub mod json;
pub mod layout;
pub mod montage;
pub mod npy;
pub mod output;
pub mod plot;
pub mod png;
pub mod svg;
