//! Every bitmap figure is a rendering of its SVG: plots, heatmaps, per-unit maps and the
//! bench layout are drawn once as SVG and rasterised here by resvg, with text set in the
//! embedded DejaVu Sans (`fonts/DejaVuSans.ttf`) by usvg's text layout (HarfBuzz-style shaping
//! through rustybuzz, with the font's own advances and kerning). The PNG therefore shows the
//! same glyphs, at the same places, as the SVG does in a browser with that font, and no system
//! font is ever consulted.
//!
//! Why not plotters' bitmap backend: it positions glyphs one by one from rounded pixel boxes,
//! which breaks words apart ("bal ancing") and lifts the decimal point; resvg lays out text
//! as a browser does.

use std::sync::{Arc, OnceLock};

use crate::error::{Error, Result};

static DEJAVU_SANS: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

/// The family name the embedded font registers under.
pub const FONT_FAMILY: &str = "DejaVu Sans";

/// The font database holding only the embedded font, mapped to every generic family, built
/// once per process.
fn fontdb() -> Arc<resvg::usvg::fontdb::Database> {
    static DB: OnceLock<Arc<resvg::usvg::fontdb::Database>> = OnceLock::new();
    DB.get_or_init(|| {
        let mut db = resvg::usvg::fontdb::Database::new();
        db.load_font_data(DEJAVU_SANS.to_vec());
        db.set_sans_serif_family(FONT_FAMILY);
        db.set_serif_family(FONT_FAMILY);
        db.set_monospace_family(FONT_FAMILY);
        Arc::new(db)
    })
    .clone()
}

/// usvg options that resolve every font family to the embedded DejaVu Sans.
pub fn options() -> resvg::usvg::Options<'static> {
    resvg::usvg::Options {
        font_family: FONT_FAMILY.into(),
        fontdb: fontdb(),
        ..Default::default()
    }
}

/// Parses SVG text into a usvg tree (text laid out with the embedded font).
pub fn parse(svg: &str) -> Result<resvg::usvg::Tree> {
    resvg::usvg::Tree::from_str(svg, &options())
        .map_err(|e| Error::Numerical(format!("cannot parse a figure's SVG: {e}")))
}

/// Renders SVG text at its own size (1 px per SVG user unit) on a white background: the
/// width, the height and the RGB bytes (row-major).
pub fn svg_to_rgb(svg: &str) -> Result<(u32, u32, Vec<u8>)> {
    let tree = parse(svg)?;
    let size = tree.size().to_int_size();
    let mut pixmap = resvg::tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or_else(|| Error::Numerical("a figure's SVG has no area".into()))?;
    pixmap.fill(resvg::tiny_skia::Color::WHITE);
    resvg::render(
        &tree,
        resvg::tiny_skia::Transform::default(),
        &mut pixmap.as_mut(),
    );
    let (w, h) = (pixmap.width(), pixmap.height());
    // Opaque after the white fill, so premultiplied and straight RGBA agree.
    let rgb = pixmap
        .data()
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    Ok((w, h, rgb))
}

/// Renders SVG text over an existing RGB image of `width × height` (the SVG's own size), in
/// place: a transparent SVG holding only text labels over a montage's tiles, for example.
pub fn render_over(svg: &str, width: u32, height: u32, rgb: &mut [u8]) -> Result<()> {
    let tree = parse(svg)?;
    if rgb.len() != width as usize * height as usize * 3 {
        return Err(Error::Numerical(
            "the image under a figure's text has the wrong size".into(),
        ));
    }
    let rgba: Vec<u8> = rgb
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    let size = resvg::tiny_skia::IntSize::from_wh(width, height)
        .ok_or_else(|| Error::Numerical("a figure has no area".into()))?;
    let mut pixmap = resvg::tiny_skia::Pixmap::from_vec(rgba, size)
        .ok_or_else(|| Error::Numerical("a figure has no area".into()))?;
    resvg::render(
        &tree,
        resvg::tiny_skia::Transform::default(),
        &mut pixmap.as_mut(),
    );
    for (out, p) in rgb.chunks_exact_mut(3).zip(pixmap.data().chunks_exact(4)) {
        out.copy_from_slice(&p[..3]);
    }
    Ok(())
}

/// Renders SVG text to PNG bytes (RGB, white background) at its own size.
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>> {
    let (w, h, rgb) = svg_to_rgb(svg)?;
    super::png::encode_rgb8(w, h, &rgb)
}

/// The embedded font in a database of svg2pdf's usvg version (svg2pdf 0.13 parses with usvg
/// 0.45, resvg here uses 0.49; both trees are built from the same SVG text and font).
fn pdf_fontdb() -> Arc<svg2pdf::usvg::fontdb::Database> {
    static DB: OnceLock<Arc<svg2pdf::usvg::fontdb::Database>> = OnceLock::new();
    DB.get_or_init(|| {
        let mut db = svg2pdf::usvg::fontdb::Database::new();
        db.load_font_data(DEJAVU_SANS.to_vec());
        db.set_sans_serif_family(FONT_FAMILY);
        db.set_serif_family(FONT_FAMILY);
        db.set_monospace_family(FONT_FAMILY);
        Arc::new(db)
    })
    .clone()
}

/// A one-page PDF of SVG text, one PDF point per SVG user unit (so a 960 × 600 figure is
/// 13.3 × 8.3 in, to be scaled by `\includegraphics[width=…]`). Text stays text: the glyphs
/// used are embedded as a subset of DejaVu Sans, so it can be searched and copied. The file
/// holds no date, so the same figure gives the same bytes.
pub fn svg_to_pdf(svg: &str) -> Result<Vec<u8>> {
    let opt = svg2pdf::usvg::Options {
        font_family: FONT_FAMILY.into(),
        fontdb: pdf_fontdb(),
        ..Default::default()
    };
    let tree = svg2pdf::usvg::Tree::from_str(svg, &opt)
        .map_err(|e| Error::Numerical(format!("cannot parse a figure's SVG: {e}")))?;
    svg2pdf::to_pdf(
        &tree,
        svg2pdf::ConversionOptions::default(),
        svg2pdf::PageOptions { dpi: 72.0 },
    )
    .map_err(|e| Error::Numerical(format!("cannot convert a figure to PDF: {e}")))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The horizontal ink extent of each column of an RGB image: true where a column holds a
    /// pixel darker than mid-grey.
    pub(crate) fn ink_columns(w: u32, h: u32, rgb: &[u8]) -> Vec<bool> {
        (0..w as usize)
            .map(|x| {
                (0..h as usize).any(|y| {
                    let p = &rgb[(y * w as usize + x) * 3..][..3];
                    p.iter().map(|&v| v as u32).sum::<u32>() < 3 * 128
                })
            })
            .collect()
    }

    /// The sum of the glyph advances of `text` in the embedded font at `size` px: the advance
    /// widths of the font's `hmtx` table for the glyphs its `cmap` (format 4) gives, read from
    /// DejaVuSans.ttf with a few lines of Python (`struct`) outside spibench, in font units of
    /// 1/2048 em. Kerning is not included.
    pub(crate) fn advance_px(text: &str, size: f64) -> f64 {
        let units = match text {
            "balancing" => 9970.0,
            "imbalanced" => 11927.0,
            "Single" => 6296.0,
            "0.385" => 5863.0,
            other => panic!("no reference advance for {other:?}"),
        };
        units * size / 2048.0
    }

    /// The widest run of blank columns between the first and last inked column.
    pub(crate) fn widest_inner_gap(cols: &[bool]) -> usize {
        let first = cols.iter().position(|&c| c).unwrap_or(0);
        let last = cols.iter().rposition(|&c| c).unwrap_or(0);
        let (mut best, mut run) = (0, 0);
        for &c in &cols[first..=last] {
            run = if c { 0 } else { run + 1 };
            best = best.max(run);
        }
        best
    }

    /// A word set by resvg with the embedded font is as wide as the font's advances say and
    /// has no gap inside it wider than a thin stroke (the bitmap backend's "bal ancing").
    #[test]
    fn text_is_set_with_the_fonts_own_advances() {
        for word in ["balancing", "imbalanced", "Single", "0.385"] {
            let size = 40.0;
            let svg = format!(
                r#"<svg xmlns="http://www.w3.org/2000/svg" width="400" height="80"><text x="10" y="55" font-family="sans-serif" font-size="{size}">{word}</text></svg>"#
            );
            let (w, h, rgb) = svg_to_rgb(&svg).unwrap();
            let cols = ink_columns(w, h, &rgb);
            let first = cols.iter().position(|&c| c).unwrap();
            let last = cols.iter().rposition(|&c| c).unwrap();
            let ink = (last - first + 1) as f64;
            let advance = advance_px(word, size);
            // Ink is the advance minus the side bearings of the first and last glyph (a few
            // px at 40 px), never more than the advance.
            assert!(
                ink <= advance + 1.0 && ink > advance - 0.2 * size,
                "{word}: ink {ink} px, advances {advance:.1} px"
            );
            // Letter gaps inside a word stay below 0.3 em: the widest in these words is about
            // 0.2 em (the side bearings around "l" and "."), while a broken layout adds at
            // least a space (0.32 em) to a normal gap.
            let gap = widest_inner_gap(&cols) as f64;
            assert!(gap < 0.3 * size, "{word}: a {gap} px gap");
        }
    }
}
