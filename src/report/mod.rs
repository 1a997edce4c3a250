//! Output files: JSON summaries, images (PNG, EXR), arrays (.npy), plots and HTML reports: the
//! writers that each command's outputs (crate::outputs) are made with.
//!
//! The figure modules (plot, heatmap, montage, svg, outline, font: plotters, resvg, svg2pdf,
//! ab_glyph and the embedded font) are built with the `figures` feature only; the plain writers are always there.

pub mod csv;
pub mod exr;
#[cfg(all(test, feature = "figures"))]
mod figure_tests;
#[cfg(feature = "figures")]
pub(crate) mod font;
#[cfg(feature = "figures")]
pub mod heatmap;
pub mod html;
pub mod json;
#[cfg(feature = "figures")]
pub mod montage;
pub mod npy;
#[cfg(feature = "figures")]
pub mod outline;
pub mod output;
#[cfg(feature = "figures")]
pub mod plot;
pub mod png;
#[cfg(feature = "figures")]
pub mod svg;
pub mod untrusted;

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
