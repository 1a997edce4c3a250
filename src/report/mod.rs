//! Output files: JSON summaries, images (PNG, EXR), arrays (.npy), plots and HTML reports.
//! Together with `scene` and `cli`, the only module that touches files.

pub mod npy;
