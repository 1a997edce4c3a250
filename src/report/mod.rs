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

/// An integer exponent in Unicode superscript digits ("−3" → "⁻³"), for 10ⁿ in labels.
pub(crate) fn superscript(e: i32) -> String {
    e.to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}
