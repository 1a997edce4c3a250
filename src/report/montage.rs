//! Image montages laid out like a paper figure: a title, column labels above, row labels
//! (rotated) at the left, one tile per cell with an optional caption underneath (for example
//! "PSNR 24.1 dB / MSSIM 0.81"), written as one RGB PNG and as an SVG of the same size
//! ([`montage_svg`]: each tile embedded as a lossless PNG of its own pixels, the text as glyph
//! outlines). No PDF: the montage is neither a curve nor a map.
//!
//! Every tile shows its raster on the 0–255 gray scale of the scores (values clipped to
//! [0, 255], rounded; NaN shows black), scaled by nearest neighbour so that its longer side is
//! `tile_px`, centred in its cell. All reconstructions thus share one gray scale and compare
//! fairly; normalise a raster to 0–255 before adding it if it lives on another scale.
//!
//! The layout depends only on the grid, `tile_px` and which kinds of text are present (never on
//! the text itself): a label or caption that is wider than its tile wraps onto two lines
//! (captions break at " / " first, so the two scores sit on separate lines), then shrinks to
//! 3/4 of the text size (at least 9), and only then is shortened with an ellipsis; the title
//! shrinks likewise to fit the figure width. With `f = clamp(round(tile_px / 10), 12, 24)`, `line = f + f / 3`,
//! `gap = max(4, tile_px / 20)` and margin `f`:
//!
//! - width  = 2f + [2·line if any row label] + cols·tile_px + (cols − 1)·gap
//! - height = 2f + [2·line if a title] + [2·line if any column label]
//!   + rows·(tile_px + [2·line if any caption]) + (rows − 1)·gap

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::font::{self, FAMILY};
use crate::error::{Error, Result};
use crate::raster::Raster;

#[derive(Debug, Clone, PartialEq)]
pub struct Montage {
    pub title: String,
    /// One label per row (left), or empty for none.
    pub row_labels: Vec<String>,
    /// One label per column (top), or empty for none.
    pub col_labels: Vec<String>,
    /// `tiles[row][col]`; `None` leaves the cell gray (for example a scheme not run).
    pub tiles: Vec<Vec<Option<Raster>>>,
    /// `captions[row][col]` under each tile; empty (or empty rows/strings) for none.
    pub captions: Vec<Vec<String>>,
    /// How a cell without a tile is shown.
    pub empty: EmptyCell,
}

/// How a montage shows a cell without a tile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EmptyCell {
    /// A gray square: a tile that could have been there (a scheme not run, for example).
    #[default]
    Gray,
    /// Nothing (the background): a cell the layout leaves free, such as the object's column
    /// below the one tile that shows it.
    Blank,
}

impl EmptyCell {
    /// The gray level of an empty cell.
    fn gray(self) -> u8 {
        match self {
            EmptyCell::Gray => EMPTY_GRAY,
            EmptyCell::Blank => 255,
        }
    }
}

/// Where everything goes, in pixels from the top-left corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MontageLayout {
    pub width: u32,
    pub height: u32,
    pub rows: usize,
    pub cols: usize,
    pub tile_px: u32,
    /// Text size for labels and captions (plotters' size unit, about the em height in pixels).
    pub font_px: u32,
    pub line_px: u32,
    pub gap_px: u32,
    pub margin_px: u32,
    pub title_h: u32,
    pub header_h: u32,
    pub left_w: u32,
    pub caption_h: u32,
}

impl MontageLayout {
    /// The top-left pixel of cell `(row, col)`.
    pub fn cell_origin(&self, row: usize, col: usize) -> (u32, u32) {
        let x = self.margin_px + self.left_w + col as u32 * (self.tile_px + self.gap_px);
        let y = self.margin_px
            + self.title_h
            + self.header_h
            + row as u32 * (self.tile_px + self.caption_h + self.gap_px);
        (x, y)
    }
}

/// Largest montage accepted, in pixels (3 bytes each in memory).
const MAX_PIXELS: u64 = 1 << 26;

/// Background of an empty cell and of the unused part of a non-square tile's cell.
const EMPTY_GRAY: u8 = 225;

/// Checks the grid and computes the layout.
pub fn montage_layout(m: &Montage, tile_px: u32) -> Result<MontageLayout> {
    if !(8..=4096).contains(&tile_px) {
        return Err(Error::field(
            "tile_px",
            format!("tile size must be 8 to 4096 pixels, got {tile_px}"),
        ));
    }
    let rows = m.tiles.len();
    let cols = m.tiles.first().map_or(0, Vec::len);
    if rows == 0 || cols == 0 {
        return Err(Error::field("tiles", "a montage needs at least one tile"));
    }
    if let Some((r, row)) = m.tiles.iter().enumerate().find(|(_, t)| t.len() != cols) {
        return Err(Error::field(
            format!("tiles[{r}]"),
            format!("row {r} has {} tiles but row 0 has {cols}", row.len()),
        ));
    }
    for (r, row) in m.tiles.iter().enumerate() {
        for (c, tile) in row.iter().enumerate() {
            if let Some(t) = tile
                && (t.width == 0 || t.height == 0 || t.data.len() != t.width * t.height)
            {
                return Err(Error::field(
                    format!("tiles[{r}][{c}]"),
                    format!(
                        "the raster claims {}×{} pixels but holds {} values",
                        t.width,
                        t.height,
                        t.data.len()
                    ),
                ));
            }
        }
    }
    if !m.row_labels.is_empty() && m.row_labels.len() != rows {
        return Err(Error::field(
            "row_labels",
            format!("{} row labels for {rows} rows", m.row_labels.len()),
        ));
    }
    if !m.col_labels.is_empty() && m.col_labels.len() != cols {
        return Err(Error::field(
            "col_labels",
            format!("{} column labels for {cols} columns", m.col_labels.len()),
        ));
    }
    if !m.captions.is_empty() {
        if m.captions.len() != rows {
            return Err(Error::field(
                "captions",
                format!("{} caption rows for {rows} rows", m.captions.len()),
            ));
        }
        if let Some((r, row)) = m
            .captions
            .iter()
            .enumerate()
            .find(|(_, c)| !c.is_empty() && c.len() != cols)
        {
            return Err(Error::field(
                format!("captions[{r}]"),
                format!("{} captions for {cols} columns", row.len()),
            ));
        }
    }
    let font_px = ((tile_px as f64 / 10.0).round() as u32).clamp(12, 24);
    let line_px = font_px + font_px / 3;
    let gap_px = (tile_px / 20).max(4);
    let margin_px = font_px;
    let title_h = if m.title.trim().is_empty() {
        0
    } else {
        2 * line_px
    };
    let header_h = if any_text(m.col_labels.iter()) {
        2 * line_px
    } else {
        0
    };
    let left_w = if any_text(m.row_labels.iter()) {
        2 * line_px
    } else {
        0
    };
    let caption_h = if any_text(m.captions.iter().flatten()) {
        2 * line_px
    } else {
        0
    };
    let width = 2 * margin_px as u64
        + left_w as u64
        + cols as u64 * tile_px as u64
        + (cols as u64 - 1) * gap_px as u64;
    let height = 2 * margin_px as u64
        + title_h as u64
        + header_h as u64
        + rows as u64 * (tile_px + caption_h) as u64
        + (rows as u64 - 1) * gap_px as u64;
    if width * height > MAX_PIXELS {
        return Err(Error::field(
            "tiles",
            format!(
                "a {rows}×{cols} montage of {tile_px}-pixel tiles would be {width}×{height} pixels, \
                 more than the {MAX_PIXELS} allowed"
            ),
        ));
    }
    Ok(MontageLayout {
        width: width as u32,
        height: height as u32,
        rows,
        cols,
        tile_px,
        font_px,
        line_px,
        gap_px,
        margin_px,
        title_h,
        header_h,
        left_w,
        caption_h,
    })
}

fn any_text<'a>(mut texts: impl Iterator<Item = &'a String>) -> bool {
    texts.any(|s| !s.trim().is_empty())
}

/// The gray level a tile shows for `v`: clipped to [0, 255] and rounded; NaN is 0.
fn gray(v: f64) -> u8 {
    if v.is_nan() {
        0
    } else {
        v.clamp(0.0, 255.0).round() as u8
    }
}

/// Where `tile` is drawn in the `size × size` cell at `(x0, y0)`: scaled so its longer side is
/// `size` (each side at least one pixel), centred. Returns `(x, y, width, height)` in pixels.
fn drawn_box(x0: u32, y0: u32, size: u32, tile: &Raster) -> (u32, u32, u32, u32) {
    let (w, h) = (tile.width as u64, tile.height as u64);
    let long = w.max(h);
    let dw = ((w * size as u64 + long / 2) / long).max(1) as u32;
    let dh = ((h * size as u64 + long / 2) / long).max(1) as u32;
    (x0 + (size - dw) / 2, y0 + (size - dh) / 2, dw, dh)
}

/// Copies `tile` into `rgb` (an image `stride` pixels wide) at `(x0, y0)`, scaled by nearest
/// neighbour so its longer side is `size`, centred in the `size × size` cell.
fn blit(rgb: &mut [u8], stride: u32, x0: u32, y0: u32, size: u32, tile: &Raster) {
    let (w, h) = (tile.width as u64, tile.height as u64);
    let (ox, oy, dw, dh) = drawn_box(x0, y0, size, tile);
    for py in 0..dh {
        // Source row of this pixel centre: floor((py + ½)·h / dh), in integers.
        let sy = (((2 * py as u64 + 1) * h) / (2 * dh as u64)).min(h - 1) as usize;
        for px in 0..dw {
            let sx = (((2 * px as u64 + 1) * w) / (2 * dw as u64)).min(w - 1) as usize;
            let g = gray(tile.data[sy * tile.width + sx]);
            let i = (((oy + py) as usize) * stride as usize + (ox + px) as usize) * 3;
            rgb[i..i + 3].copy_from_slice(&[g, g, g]);
        }
    }
}

fn fill(rgb: &mut [u8], stride: u32, x0: u32, y0: u32, w: u32, h: u32, g: u8) {
    for y in y0..y0 + h {
        let start = (y as usize * stride as usize + x0 as usize) * 3;
        rgb[start..start + w as usize * 3].fill(g);
    }
}

/// The montage as RGB pixels (row-major, 3 bytes each) with its layout.
pub fn render_montage(m: &Montage, tile_px: u32) -> Result<(MontageLayout, Vec<u8>)> {
    let lay = montage_layout(m, tile_px)?;
    if !font::ensure_registered() {
        return Err(Error::Numerical(font::unavailable().to_string()));
    }
    let mut rgb = vec![255u8; lay.width as usize * lay.height as usize * 3];
    for (r, row) in m.tiles.iter().enumerate() {
        for (c, tile) in row.iter().enumerate() {
            let (x0, y0) = lay.cell_origin(r, c);
            let g = if tile.is_some() {
                EMPTY_GRAY
            } else {
                m.empty.gray()
            };
            fill(&mut rgb, lay.width, x0, y0, tile_px, tile_px, g);
            if let Some(t) = tile {
                blit(&mut rgb, lay.width, x0, y0, tile_px, t);
            }
        }
    }
    draw_text(m, &lay, &mut rgb).map_err(Error::Numerical)?;
    Ok((lay, rgb))
}

/// Draws the title, labels and captions over the tiles' white surroundings.
fn draw_text(m: &Montage, lay: &MontageLayout, rgb: &mut [u8]) -> std::result::Result<(), String> {
    // The text is drawn as SVG and rendered by resvg over the tiles (report::svg), so glyphs
    // are spaced by the font's own advances, as in every other figure.
    let svg = labels_svg(m, lay)?;
    super::svg::render_over(&svg, lay.width, lay.height, rgb).map_err(|e| e.to_string())
}

/// The title, labels and captions as a transparent SVG of the montage's size (text elements).
fn labels_svg(m: &Montage, lay: &MontageLayout) -> std::result::Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (lay.width, lay.height)).into_drawing_area();
        draw_labels(m, lay, &root)?;
    }
    Ok(svg)
}

/// The pixels a tile's raster shows (row-major, [`gray`] of each value), before any scaling.
pub fn tile_gray(tile: &Raster) -> Vec<u8> {
    tile.data.iter().map(|&v| gray(v)).collect()
}

/// The montage as SVG, `width × height` user units for the PNG's `width × height` pixels: the
/// same layout, each tile embedded at its own resolution as a lossless 8-bit gray PNG (a
/// `data:` URI) stretched over the box the PNG draws it in, with `image-rendering` asking for
/// square pixels (nearest neighbour) as in the PNG; the text set as glyph outlines
/// (`report::outline`), so no viewer needs the font.
pub fn montage_svg(m: &Montage, tile_px: u32) -> Result<String> {
    let lay = montage_layout(m, tile_px)?;
    if !font::ensure_registered() {
        return Err(Error::Numerical(font::unavailable().to_string()));
    }
    let (w, h) = (lay.width, lay.height);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" \
         viewBox=\"0 0 {w} {h}\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"#FFFFFF\"/>\n"
    );
    for (r, row) in m.tiles.iter().enumerate() {
        for (c, tile) in row.iter().enumerate() {
            let (x0, y0) = lay.cell_origin(r, c);
            let g = if tile.is_some() {
                EMPTY_GRAY
            } else {
                m.empty.gray()
            };
            svg.push_str(&format!(
                "<rect x=\"{x0}\" y=\"{y0}\" width=\"{tile_px}\" height=\"{tile_px}\" \
                 fill=\"#{g:02X}{g:02X}{g:02X}\"/>\n"
            ));
            if let Some(t) = tile {
                let png = encode_tile(t)?;
                let (x, y, dw, dh) = drawn_box(x0, y0, tile_px, t);
                svg.push_str(&format!(
                    "<image x=\"{x}\" y=\"{y}\" width=\"{dw}\" height=\"{dh}\" \
                     preserveAspectRatio=\"none\" image-rendering=\"optimizeSpeed\" \
                     style=\"image-rendering:pixelated\" href=\"data:image/png;base64,{}\"/>\n",
                    super::html::base64(&png)
                ));
            }
        }
    }
    let labels = labels_svg(m, &lay).map_err(Error::Numerical)?;
    svg.push_str(svg_body(&labels));
    svg.push_str("</svg>\n");
    super::outline::outline_text(&svg)
}

/// The content of an SVG document's root element.
fn svg_body(svg: &str) -> &str {
    let open = svg
        .find("<svg")
        .and_then(|s| svg[s..].find('>').map(|e| s + e + 1));
    match (open, svg.rfind("</svg>")) {
        (Some(a), Some(b)) if a <= b => &svg[a..b],
        _ => "",
    }
}

/// A tile's raster as an 8-bit gray PNG of its own size ([`tile_gray`]).
fn encode_tile(tile: &Raster) -> Result<Vec<u8>> {
    let buf: image::GrayImage =
        image::ImageBuffer::from_raw(tile.width as u32, tile.height as u32, tile_gray(tile))
            .ok_or_else(|| Error::Numerical("a montage tile's buffer has the wrong size".into()))?;
    let mut out = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| Error::Numerical(format!("cannot encode a montage tile as PNG: {e}")))?;
    Ok(out.into_inner())
}

fn draw_labels<DB: DrawingBackend>(
    m: &Montage,
    lay: &MontageLayout,
    root: &DrawingArea<DB, plotters::coord::Shift>,
) -> std::result::Result<(), String> {
    let size = lay.font_px as f64;
    // Labels that do not fit on two lines shrink down to this before being shortened.
    let min_size = (size * 0.75).round().max(9.0);
    let centred = |s: f64| {
        TextStyle::from((FAMILY, s).into_font())
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Center))
    };
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let line = lay.line_px as i32;
    if lay.title_h > 0 {
        let (lines, ts) = font::fit_lines(
            &m.title,
            size * 4.0 / 3.0,
            size,
            lay.width.saturating_sub(2 * lay.margin_px),
            1,
        );
        let y = lay.margin_px as i32 + lay.title_h as i32 / 2;
        for l in lines {
            root.draw(&Text::new(l, (lay.width as i32 / 2, y), centred(ts)))
                .map_err(err)?;
        }
    }
    // Lines of a wrapped label, centred as a block on `centre` along the stacking direction.
    let offsets = |n: usize| (0..n).map(move |k| (2 * k as i32 - (n as i32 - 1)) * line / 2);
    let tile = lay.tile_px as i32;
    if lay.header_h > 0 {
        for (c, label) in m.col_labels.iter().enumerate() {
            let (x0, _) = lay.cell_origin(0, c);
            let (lines, s) = font::fit_lines(label, size, min_size, lay.tile_px, 2);
            let n = lines.len();
            let yc = (lay.margin_px + lay.title_h) as i32 + lay.header_h as i32 / 2;
            for (l, dy) in lines.into_iter().zip(offsets(n)) {
                root.draw(&Text::new(l, (x0 as i32 + tile / 2, yc + dy), centred(s)))
                    .map_err(err)?;
            }
        }
    }
    if lay.left_w > 0 {
        for (r, label) in m.row_labels.iter().enumerate() {
            let (_, y0) = lay.cell_origin(r, 0);
            let (lines, s) = font::fit_lines(label, size, min_size, lay.tile_px, 2);
            let rotated = centred(s).transform(FontTransform::Rotate270);
            let n = lines.len();
            let xc = lay.margin_px as i32 + lay.left_w as i32 / 2;
            for (l, dx) in lines.into_iter().zip(offsets(n)) {
                root.draw(&Text::new(
                    l,
                    (xc + dx, y0 as i32 + tile / 2),
                    rotated.clone(),
                ))
                .map_err(err)?;
            }
        }
    }
    if lay.caption_h > 0 {
        for (r, row) in m.captions.iter().enumerate() {
            for (c, caption) in row.iter().enumerate() {
                let (x0, y0) = lay.cell_origin(r, c);
                if caption.trim().is_empty() {
                    continue;
                }
                let (lines, s) = font::fit_lines(caption, size, min_size, lay.tile_px, 2);
                let n = lines.len();
                let yc = (y0 + lay.tile_px) as i32 + lay.caption_h as i32 / 2;
                for (l, dy) in lines.into_iter().zip(offsets(n)) {
                    root.draw(&Text::new(l, (x0 as i32 + tile / 2, yc + dy), centred(s)))
                        .map_err(err)?;
                }
            }
        }
    }
    root.present().map_err(err)
}

/// Writes the montage as an RGB PNG (see the module notes for the layout).
pub fn write_montage(m: &Montage, tile_px: u32, path: &Path) -> Result<()> {
    let (lay, rgb) = render_montage(m, tile_px).map_err(|e| match e {
        Error::Numerical(msg) => Error::write(path, std::io::Error::other(msg)),
        other => other.in_file(path),
    })?;
    let png = super::png::encode_rgb8_at_dpi(lay.width, lay.height, &rgb, montage_dpi(&lay))
        .map_err(|e| e.in_file(path))?;
    super::npy::write_atomic(path, &png)
}

/// The resolution a montage's PNG states (`pHYs`): the montage is drawn in pixels of its tiles,
/// not at a print size, so it states the resolution at which it fills the width of a
/// two-column page (`FigureSize::DOUBLE_COLUMN_IN`), never below 96 dpi (a small montage is
/// then narrower than the page).
pub fn montage_dpi(lay: &MontageLayout) -> f64 {
    (f64::from(lay.width) / super::svg::FigureSize::DOUBLE_COLUMN_IN).max(96.0)
}

/// Writes the montage as SVG ([`montage_svg`]) and as an RGB PNG of the same size. Both are
/// made in memory before either is written, so a failure writes neither.
pub fn write_montage_figure(
    m: &Montage,
    tile_px: u32,
    svg_path: &Path,
    png_path: &Path,
) -> Result<()> {
    let fail = |path: &Path, e: Error| match e {
        Error::Numerical(msg) => Error::write(path, std::io::Error::other(msg)),
        other => other.in_file(path),
    };
    let svg = montage_svg(m, tile_px).map_err(|e| fail(svg_path, e))?;
    let (lay, rgb) = render_montage(m, tile_px).map_err(|e| fail(png_path, e))?;
    let png = super::png::encode_rgb8_at_dpi(lay.width, lay.height, &rgb, montage_dpi(&lay))
        .map_err(|e| fail(png_path, e))?;
    super::npy::write_atomic(svg_path, svg.as_bytes())?;
    super::npy::write_atomic(png_path, &png)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(w: usize, h: usize, seed: usize) -> Raster {
        Raster::from_fn(w, h, |r, c| ((r * 37 + c * 11 + seed * 53) % 256) as f64)
    }

    fn example() -> Montage {
        let mut clipped = pattern(8, 8, 3);
        clipped.set(0, 0, 300.0);
        clipped.set(0, 1, -5.0);
        clipped.set(0, 2, f64::NAN);
        clipped.set(0, 3, 127.5);
        Montage {
            title: "Reconstructions at 25 % sampling".into(),
            row_labels: vec![
                "Single detector".into(),
                "Secondary complementary balancing".into(),
            ],
            col_labels: vec!["Cameraman".into(), "Peppers".into(), "USAF chart".into()],
            tiles: vec![
                vec![Some(pattern(8, 8, 0)), Some(pattern(16, 16, 1)), None],
                vec![
                    Some(pattern(5, 5, 2)),
                    Some(pattern(8, 4, 4)),
                    Some(clipped),
                ],
            ],
            captions: vec![
                vec![
                    "PSNR 24.1 dB / MSSIM 0.81".into(),
                    "PSNR 22.0 dB".into(),
                    "".into(),
                ],
                vec![],
            ],
            empty: EmptyCell::Gray,
        }
    }

    fn px(img: &image::RgbImage, x: u32, y: u32) -> u8 {
        let p = img.get_pixel(x, y).0;
        assert!(
            p[0] == p[1] && p[1] == p[2],
            "tile pixel ({x}, {y}) is not gray: {p:?}"
        );
        p[0]
    }

    #[test]
    fn layout_sizes_follow_the_documented_formula() {
        // tile 64: f = 12, line = 16, gap = 4, margin = 12.
        let lay = montage_layout(&example(), 64).unwrap();
        assert_eq!(
            (lay.width, lay.height),
            (
                12 + 32 + 3 * 64 + 2 * 4 + 12,
                12 + 32 + 32 + 2 * (64 + 32) + 4 + 12
            )
        );
        assert_eq!((lay.width, lay.height), (256, 284));
        // No text at all: only margins, tiles and gaps. tile 200: f = 20, gap = 10.
        let bare = Montage {
            title: String::new(),
            row_labels: vec![],
            col_labels: vec![],
            tiles: vec![vec![None, None]],
            captions: vec![],
            empty: EmptyCell::Gray,
        };
        let lay = montage_layout(&bare, 200).unwrap();
        assert_eq!(
            (lay.width, lay.height),
            (2 * 20 + 2 * 200 + 10, 2 * 20 + 200)
        );
    }

    #[test]
    fn png_has_expected_size_and_tile_pixels() {
        let m = example();
        let dir =
            std::env::temp_dir().join(format!("spibench-montage-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.png");
        write_montage(&m, 64, &path).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(img.dimensions(), (256, 284));
        let lay = montage_layout(&m, 64).unwrap();

        // (0, 0): 8×8 scaled by exactly 8; the centre of block (i, j) shows raster (row j, col i).
        let t = m.tiles[0][0].as_ref().unwrap();
        let (x0, y0) = lay.cell_origin(0, 0);
        for (i, j) in [(0, 0), (7, 0), (3, 5), (7, 7)] {
            let want = t.get(j, i) as u8;
            assert_eq!(px(&img, x0 + i as u32 * 8 + 4, y0 + j as u32 * 8 + 4), want);
            // Nearest neighbour: the block's corners carry the same value.
            assert_eq!(px(&img, x0 + i as u32 * 8, y0 + j as u32 * 8 + 7), want);
        }
        // (0, 1): 16×16 scaled by 4.
        let t = m.tiles[0][1].as_ref().unwrap();
        let (x0, y0) = lay.cell_origin(0, 1);
        assert_eq!(
            px(&img, x0 + 13 * 4 + 1, y0 + 2 * 4 + 2),
            t.get(2, 13) as u8
        );
        // (0, 2): no raster, an empty gray cell.
        let (x0, y0) = lay.cell_origin(0, 2);
        assert_eq!(px(&img, x0 + 32, y0 + 32), EMPTY_GRAY);
        // (1, 0): 5×5 to 64 (factor 12.8): pixel 0 → source 0, pixel 63 → source 4,
        // pixel 13 → floor(27·5/128) = 1.
        let t = m.tiles[1][0].as_ref().unwrap();
        let (x0, y0) = lay.cell_origin(1, 0);
        assert_eq!(px(&img, x0, y0), t.get(0, 0) as u8);
        assert_eq!(px(&img, x0 + 63, y0 + 63), t.get(4, 4) as u8);
        assert_eq!(px(&img, x0 + 13, y0 + 12), t.get(0, 1) as u8);
        // (1, 1): 8 wide × 4 tall → 64 × 32, centred vertically (16 rows of gray above).
        let t = m.tiles[1][1].as_ref().unwrap();
        let (x0, y0) = lay.cell_origin(1, 1);
        assert_eq!(px(&img, x0 + 4, y0 + 8), EMPTY_GRAY);
        assert_eq!(px(&img, x0 + 4, y0 + 16 + 4), t.get(0, 0) as u8);
        assert_eq!(px(&img, x0 + 60, y0 + 16 + 28), t.get(3, 7) as u8);
        // (1, 2): clipping and rounding: 300 → 255, −5 → 0, NaN → 0, 127.5 → 128.
        let (x0, y0) = lay.cell_origin(1, 2);
        let row0: Vec<u8> = (0..4).map(|i| px(&img, x0 + i * 8 + 4, y0 + 4)).collect();
        assert_eq!(row0, vec![255, 0, 0, 128]);

        // Text was drawn: dark pixels in the title band, the column-label band, the row-label
        // strip and under the first tile (its caption), and none under the empty caption.
        let dark = |x0: u32, y0: u32, w: u32, h: u32| {
            (x0..x0 + w)
                .flat_map(|x| (y0..y0 + h).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 128)
                .count()
        };
        let (gx, gy) = lay.cell_origin(0, 0);
        assert!(dark(0, lay.margin_px, lay.width, lay.title_h) > 50);
        assert!(dark(gx, gy - lay.header_h, 3 * 64, lay.header_h) > 50);
        assert!(dark(lay.margin_px, gy, lay.left_w, lay.height - gy) > 50);
        assert!(dark(gx, gy + 64, 64, lay.caption_h) > 30);
        let (cx, cy) = lay.cell_origin(0, 2);
        assert_eq!(dark(cx, cy + 64, 64, lay.caption_h), 0);
    }

    #[test]
    fn svg_embeds_each_tile_losslessly_at_the_png_layout() {
        let m = example();
        let dir = std::env::temp_dir().join(format!("spibench-montage-svg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (svg_path, png_path) = (dir.join("m.svg"), dir.join("m.png"));
        write_montage_figure(&m, 64, &svg_path, &png_path).unwrap();
        let text = std::fs::read_to_string(&svg_path).unwrap();
        let img = image::open(&png_path).unwrap().to_rgb8();
        let _ = std::fs::remove_dir_all(&dir);

        let doc = roxmltree::Document::parse(&text).unwrap();
        let root = doc.root_element();
        let num = |n: roxmltree::Node, a: &str| -> u32 {
            n.attribute(a)
                .unwrap_or_else(|| panic!("no {a}"))
                .parse()
                .unwrap()
        };
        assert_eq!((num(root, "width"), num(root, "height")), img.dimensions());
        assert_eq!(root.attribute("viewBox"), Some("0 0 256 284"));
        // Text is outlines (labelled for search and screen readers), never <text>.
        assert!(!doc.descendants().any(|n| n.has_tag_name("text")));
        let labels: Vec<&str> = doc
            .descendants()
            .filter_map(|n| n.attribute("aria-label"))
            .collect();
        assert!(
            labels.contains(&"Reconstructions at 25 % sampling"),
            "{labels:?}"
        );
        assert!(labels.contains(&"USAF chart"), "{labels:?}");

        // One image per tile present, in row-major order, holding the tile's own pixels.
        let images: Vec<roxmltree::Node> = doc
            .descendants()
            .filter(|n| n.has_tag_name("image"))
            .collect();
        let tiles: Vec<&Raster> = m.tiles.iter().flatten().flatten().collect();
        assert_eq!(images.len(), tiles.len());
        for (node, tile) in images.iter().zip(&tiles) {
            let href = node.attribute("href").unwrap();
            let coded = href.strip_prefix("data:image/png;base64,").unwrap();
            let png = image::load_from_memory_with_format(
                &crate::report::html::tests::decode64(coded),
                image::ImageFormat::Png,
            )
            .unwrap();
            assert_eq!(png.color(), image::ColorType::L8);
            let png = png.to_luma8();
            assert_eq!(png.dimensions(), (tile.width as u32, tile.height as u32));
            assert_eq!(png.into_raw(), tile_gray(tile));
            assert!(
                node.attribute("style")
                    .unwrap()
                    .contains("image-rendering:pixelated")
            );
            assert_eq!(node.attribute("preserveAspectRatio"), Some("none"));
            // The box is where the PNG draws the tile: its corners show the raster's corners.
            let (x, y, w, h) = (
                num(*node, "x"),
                num(*node, "y"),
                num(*node, "width"),
                num(*node, "height"),
            );
            let last = tile_gray(tile)[tile.data.len() - 1];
            assert_eq!(px(&img, x, y), tile_gray(tile)[0]);
            assert_eq!(px(&img, x + w - 1, y + h - 1), last);
        }
        // The 8 × 4 tile at (1, 1) sits 16 pixels down its cell, as in the PNG.
        let (x0, y0) = montage_layout(&m, 64).unwrap().cell_origin(1, 1);
        assert_eq!((num(images[3], "x"), num(images[3], "y")), (x0, y0 + 16));
        assert_eq!(
            (num(images[3], "width"), num(images[3], "height")),
            (64, 32)
        );
        // The clipped tile's pixels: 300 → 255, −5 → 0, NaN → 0, 127.5 → 128.
        assert_eq!(tile_gray(tiles[4])[..4], [255, 0, 0, 128]);
    }

    #[test]
    fn inconsistent_grids_are_input_errors() {
        let path = std::env::temp_dir().join("spibench-montage-never.png");
        let mut m = example();
        m.tiles[1].pop();
        assert!(
            write_montage(&m, 64, &path)
                .unwrap_err()
                .to_string()
                .contains("tiles[1]")
        );
        let mut m = example();
        m.row_labels.pop();
        assert!(write_montage(&m, 64, &path).unwrap_err().is_user_error());
        let mut m = example();
        m.captions = vec![vec![]];
        assert!(write_montage(&m, 64, &path).unwrap_err().is_user_error());
        let mut m = example();
        m.tiles[0][0] = Some(Raster {
            width: 3,
            height: 3,
            data: vec![0.0; 8],
        });
        assert!(write_montage(&m, 64, &path).unwrap_err().is_user_error());
        assert!(
            write_montage(&example(), 4, &path)
                .unwrap_err()
                .is_user_error()
        );
        assert!(
            write_montage(&example(), 4096, &path)
                .unwrap_err()
                .is_user_error()
        );
        assert!(!path.exists());
    }
}
