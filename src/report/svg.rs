//! Every bitmap figure is a rendering of its SVG: plots, heatmaps, per-unit maps and the
//! bench layout are drawn once as SVG and rasterised here by resvg, or converted to PDF by
//! svg2pdf. Text is set before either sees it: `report::outline` replaces each `<text>` with the
//! outlines of its glyphs in the embedded DejaVu Sans (the font's own advances and kerning), so
//! the PNG and the PDF show the same glyphs, at the same places, as the SVG file does in any
//! viewer, no system font is ever consulted, and the build needs no text-shaping stack.
//!
//! Why not plotters' bitmap backend: it positions glyphs one by one from rounded pixel boxes,
//! which breaks words apart ("bal ancing") and lifts the decimal point.

use std::path::Path;

use crate::error::{Error, Result};

/// SVG user units per inch of the figures drawn at print size: one unit is half a point, so
/// whole-unit stroke widths and marker sizes step in half points, and text of 16–18 units is
/// 8–9 pt on paper.
pub const UNITS_PER_IN: f64 = 144.0;

/// Resolution of the PNG rendering of a print-size figure (2 pixels per SVG unit): a
/// single-column figure is 1008 pixels wide.
pub const PNG_DPI: f64 = 288.0;

/// CSS pixels per inch: usvg, svg2pdf and browsers read an SVG's `in` lengths at this rate.
const CSS_PX_PER_IN: f64 = 96.0;

/// A figure's printed size in inches. Figures are drawn for the column widths of two-column
/// journals: [`FigureSize::SINGLE`] (3.5 in) and [`FigureSize::DOUBLE`] (7.2 in), with 8–9 pt
/// text at that size, so `\includegraphics` without a `width=` prints them as drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FigureSize {
    pub width_in: f64,
    pub height_in: f64,
}

impl FigureSize {
    /// One column of a two-column journal page.
    pub const SINGLE_COLUMN_IN: f64 = 3.5;
    /// The full text width of a two-column page.
    pub const DOUBLE_COLUMN_IN: f64 = 7.2;
    pub const SINGLE: FigureSize = FigureSize {
        width_in: Self::SINGLE_COLUMN_IN,
        height_in: 2.6,
    };
    pub const DOUBLE: FigureSize = FigureSize {
        width_in: Self::DOUBLE_COLUMN_IN,
        height_in: 3.4,
    };

    /// A checked size: each side from 1 to 40 inches.
    pub fn new(width_in: f64, height_in: f64) -> Result<FigureSize> {
        for (name, v) in [("width_in", width_in), ("height_in", height_in)] {
            if !(1.0..=40.0).contains(&v) {
                return Err(Error::field(
                    name,
                    format!("a figure side must be 1 to 40 inches, got {v}"),
                ));
            }
        }
        Ok(FigureSize {
            width_in,
            height_in,
        })
    }

    /// The size of a drawing of `width × height` SVG units ([`UNITS_PER_IN`]).
    pub fn of_units(width: u32, height: u32) -> FigureSize {
        FigureSize {
            width_in: f64::from(width) / UNITS_PER_IN,
            height_in: f64::from(height) / UNITS_PER_IN,
        }
    }

    /// The drawing's width and height in SVG user units.
    pub fn units(self) -> (u32, u32) {
        (
            (self.width_in * UNITS_PER_IN).round() as u32,
            (self.height_in * UNITS_PER_IN).round() as u32,
        )
    }

    /// The same width with `extra_in` inches added to the height.
    pub fn taller(self, extra_in: f64) -> FigureSize {
        FigureSize {
            height_in: self.height_in + extra_in,
            ..self
        }
    }
}

/// `svg` with its root element's `width` and `height` stated in inches, from its `viewBox` at
/// [`UNITS_PER_IN`]: the drawing is unchanged, and viewers, svg2pdf and LaTeX (via the PDF) show
/// it at its print size.
pub fn at_print_size(svg: &str) -> Result<String> {
    let start = svg
        .find("<svg")
        .ok_or_else(|| Error::Numerical("a figure's SVG has no <svg> element".into()))?;
    let end = start
        + svg[start..]
            .find('>')
            .ok_or_else(|| Error::Numerical("a figure's <svg> tag is not closed".into()))?;
    let tag = &svg[start..end];
    let attr = |name: &str| -> Option<(usize, usize)> {
        let key = format!(" {name}=\"");
        let at = tag.find(&key)? + key.len();
        let len = tag[at..].find('"')?;
        Some((at, at + len))
    };
    let (vb0, vb1) =
        attr("viewBox").ok_or_else(|| Error::Numerical("a figure's SVG has no viewBox".into()))?;
    let vb: Vec<f64> = tag[vb0..vb1]
        .split([' ', ','])
        .filter(|t| !t.is_empty())
        .filter_map(|t| t.parse().ok())
        .collect();
    if vb.len() != 4 || !(vb[2] > 0.0 && vb[3] > 0.0) {
        return Err(Error::Numerical("a figure's viewBox is malformed".into()));
    }
    let mut new_tag = tag.to_string();
    // Replace from the right so that earlier offsets stay valid.
    let mut edits: Vec<((usize, usize), String)> = Vec::new();
    let mut missing = String::new();
    for (name, units) in [("width", vb[2]), ("height", vb[3])] {
        let value = format!("{}in", trim_float(units / UNITS_PER_IN));
        match attr(name) {
            Some(span) => edits.push((span, value)),
            None => missing.push_str(&format!(" {name}=\"{value}\"")),
        }
    }
    // Missing attributes go right after `<svg`, before every other edit's offset.
    edits.push((("<svg".len(), "<svg".len()), missing));
    edits.sort_by_key(|((a, _), _)| std::cmp::Reverse(*a));
    for ((a, b), v) in edits {
        new_tag.replace_range(a..b, &v);
    }
    Ok(format!("{}{new_tag}{}", &svg[..start], &svg[end..]))
}

/// A length with at most four decimals and no trailing zeros.
fn trim_float(v: f64) -> String {
    let s = format!("{v:.4}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Renders a print-size SVG ([`at_print_size`]) at [`PNG_DPI`]: the width, the height and the
/// RGB bytes. Other SVG renders at its own size ([`svg_to_rgb`]).
pub fn print_to_rgb(svg: &str) -> Result<(u32, u32, Vec<u8>)> {
    render_scaled(svg, PNG_DPI / CSS_PX_PER_IN)
}

/// Writes a figure: its SVG, its PNG rendering at [`PNG_DPI`] and, when `pdf`, its PDF beside
/// the SVG (extension `.pdf`). `svg` is a drawing in [`UNITS_PER_IN`] units; its text is set as
/// outlines and its size stated in inches first. Everything is rendered in memory before the
/// first file is written, so a drawing failure writes nothing.
pub fn write_figure(svg: &str, svg_path: &Path, png_path: &Path, pdf: bool) -> Result<()> {
    let fail = |e: Error| match e {
        Error::Numerical(msg) => Error::write(svg_path, std::io::Error::other(msg)),
        other => other.in_file(svg_path),
    };
    let svg = at_print_size(&super::outline::outline_text(svg).map_err(fail)?).map_err(fail)?;
    // The PNG (render and deflate) and the PDF (conversion and deflate) side by side: they are
    // most of a figure's time, and a command writes its figures while nothing else runs.
    let (png, pdf) = rayon::join(
        || {
            let (w, h, rgb) = print_to_rgb(&svg)?;
            super::png::encode_rgb8_at_dpi(w, h, &rgb, PNG_DPI)
        },
        || pdf.then(|| svg_to_pdf(&svg)).transpose(),
    );
    let (png, pdf) = (png.map_err(fail)?, pdf.map_err(fail)?);
    super::npy::write_atomic(svg_path, svg.as_bytes())?;
    if let Some(pdf) = pdf {
        super::npy::write_atomic(&svg_path.with_extension("pdf"), &pdf)?;
    }
    super::npy::write_atomic(png_path, &png)
}

/// Parses SVG text into a usvg tree, its text set as glyph outlines first.
pub fn parse(svg: &str) -> Result<resvg::usvg::Tree> {
    let svg = super::outline::outline_text(svg)?;
    resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default())
        .map_err(|e| Error::Numerical(format!("cannot parse a figure's SVG: {e}")))
}

/// Renders SVG text at its own size (1 px per SVG user unit) on a white background: the
/// width, the height and the RGB bytes (row-major).
pub fn svg_to_rgb(svg: &str) -> Result<(u32, u32, Vec<u8>)> {
    render_scaled(svg, 1.0)
}

/// Renders SVG text at `scale` pixels per CSS pixel of its size on a white background.
fn render_scaled(svg: &str, scale: f64) -> Result<(u32, u32, Vec<u8>)> {
    let tree = parse(svg)?;
    let size = tree.size();
    let (w, h) = (
        (f64::from(size.width()) * scale).round() as u32,
        (f64::from(size.height()) * scale).round() as u32,
    );
    let mut pixmap = resvg::tiny_skia::Pixmap::new(w, h)
        .ok_or_else(|| Error::Numerical("a figure's SVG has no area".into()))?;
    pixmap.fill(resvg::tiny_skia::Color::WHITE);
    let (sx, sy) = (
        w as f32 / size.width().max(f32::MIN_POSITIVE),
        h as f32 / size.height().max(f32::MIN_POSITIVE),
    );
    resvg::render(
        &tree,
        resvg::tiny_skia::Transform::from_scale(sx, sy),
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

/// A one-page PDF of SVG text, the page of the size the SVG states (CSS units: 96 px per inch,
/// so a figure whose width is "3.5in" gives a 252 pt page, and a unitless 960 × 600 one
/// 10 × 6.25 in). Text is drawn as the glyph
/// outlines of the SVG ([`parse`]), so the PDF needs no embedded font. The file holds no date,
/// so the same figure gives the same bytes.
pub fn svg_to_pdf(svg: &str) -> Result<Vec<u8>> {
    // resvg and svg2pdf share one usvg version, so the tree parsed for the PNG serves here.
    let tree = parse(svg)?;
    svg2pdf::to_pdf(
        &tree,
        svg2pdf::ConversionOptions::default(),
        svg2pdf::PageOptions {
            dpi: CSS_PX_PER_IN as f32,
        },
    )
    .map(canonical_resource_order)
    .map_err(|e| Error::Numerical(format!("cannot convert a figure to PDF: {e}")))
}

/// The PDF with the entries of each resource dictionary in name order. svg2pdf keeps a page's
/// resources in a hash map, so the same figure lists them in a different order on each run;
/// the order carries no meaning in PDF (a dictionary is unordered, ISO 32000-1 §7.3.7), and
/// each entry is one line of its own (`/xo12 31 0 R`), so sorting the lines of each run of
/// entries leaves every byte count, and so every cross-reference offset, as it was. Lines
/// inside streams are never touched.
fn canonical_resource_order(pdf: Vec<u8>) -> Vec<u8> {
    fn entry_key(line: &[u8]) -> Option<(usize, &[u8], u64)> {
        let indent = line.iter().take_while(|&&b| b == b' ').count();
        let rest = line[indent..].strip_prefix(b"/")?;
        let name_end = rest.iter().position(|&b| b == b' ')?;
        let name = &rest[..name_end];
        let digits = name.iter().rev().take_while(|b| b.is_ascii_digit()).count();
        let (prefix, number) = name.split_at(name.len() - digits);
        let reference = std::str::from_utf8(&rest[name_end + 1..]).ok()?;
        let mut parts = reference.split(' ');
        let well_formed = prefix.iter().all(u8::is_ascii_alphabetic)
            && digits > 0
            && parts.next()?.bytes().all(|b| b.is_ascii_digit())
            && parts.next()? == "0"
            && parts.next()? == "R"
            && parts.next().is_none();
        let number: u64 = std::str::from_utf8(number).ok()?.parse().ok()?;
        well_formed.then_some((indent, prefix, number))
    }
    let lines: Vec<&[u8]> = pdf.split(|&b| b == b'\n').collect();
    let mut out: Vec<&[u8]> = Vec::with_capacity(lines.len());
    let (mut i, mut in_stream) = (0, false);
    while i < lines.len() {
        let line = lines[i];
        if in_stream {
            in_stream = line != b"endstream";
        } else if line == b"stream" {
            in_stream = true;
        } else if let Some((indent, prefix, _)) = entry_key(line) {
            let run_end = (i..lines.len())
                .find(|&j| entry_key(lines[j]).is_none_or(|(d, p, _)| d != indent || p != prefix))
                .unwrap_or(lines.len());
            let mut run = lines[i..run_end].to_vec();
            run.sort_by_key(|l| entry_key(l).map(|(_, _, n)| n));
            out.extend(run);
            i = run_end;
            continue;
        }
        out.push(line);
        i += 1;
    }
    out.join(&b'\n')
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

    /// The page size (width, height in points) of a one-page PDF: its `/MediaBox`.
    pub(crate) fn pdf_page_pt(pdf: &[u8]) -> (f64, f64) {
        let text = String::from_utf8_lossy(pdf);
        let at = text.find("/MediaBox").expect("a MediaBox") + "/MediaBox".len();
        let inside = &text[at..];
        let (open, close) = (inside.find('[').unwrap(), inside.find(']').unwrap());
        let v: Vec<f64> = inside[open + 1..close]
            .split_whitespace()
            .map(|t| t.parse().unwrap())
            .collect();
        (v[2] - v[0], v[3] - v[1])
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

    /// The same figure gives the same PDF bytes, whatever order svg2pdf's hash maps visit its
    /// resources in (many translucent shapes make many resources).
    #[test]
    fn pdf_bytes_are_deterministic() {
        let mut svg =
            String::from(r#"<svg xmlns="http://www.w3.org/2000/svg" width="200" height="100">"#);
        for k in 0..12 {
            svg.push_str(&format!(
                r##"<rect x="{}" y="10" width="10" height="50" fill="#1f77b4" opacity="0.{}"/>"##,
                10 * k,
                k + 1
            ));
        }
        svg.push_str(r#"<text x="5" y="90" font-size="12">k₊ (A/W)</text></svg>"#);
        let first = svg_to_pdf(&svg).unwrap();
        for _ in 0..6 {
            assert!(svg_to_pdf(&svg).unwrap() == first, "the PDF bytes changed");
        }
        assert!(first.starts_with(b"%PDF-"));
    }

    /// A figure states its size in inches from its viewBox (half points), its PNG has 288 dpi
    /// and its PDF page that size in points.
    #[test]
    fn print_size_from_the_view_box() {
        let svg = r#"<svg width="504" height="288" viewBox="0 0 504 288" xmlns="http://www.w3.org/2000/svg"><rect x="10" y="10" width="20" height="20"/></svg>"#;
        let out = at_print_size(svg).unwrap();
        assert!(
            out.starts_with(r#"<svg width="3.5in" height="2in" viewBox="0 0 504 288""#),
            "{out}"
        );
        assert_eq!(at_print_size(&out).unwrap(), out);
        let (w, h, _) = print_to_rgb(&out).unwrap();
        assert_eq!((w, h), (1008, 576));
        assert_eq!(pdf_page_pt(&svg_to_pdf(&out).unwrap()), (252.0, 144.0));
        let bare = r#"<svg viewBox="0 0 1037 144" xmlns="http://www.w3.org/2000/svg"/>"#;
        assert!(
            at_print_size(bare)
                .unwrap()
                .starts_with(r#"<svg width="7.2014in" height="1in""#)
        );
        assert!(at_print_size("<svg width=\"3\">").is_err());
        assert!(FigureSize::new(0.5, 2.0).is_err());
        assert_eq!(FigureSize::SINGLE.units(), (504, 374));
    }

    #[test]
    fn resource_entries_are_sorted_in_place() {
        let pdf = b"%PDF-1.7\n  /Resources <<\n      /xo12 31 0 R\n      /xo2 9 0 R\n      /gs1 4 0 R\n      /gs0 3 0 R\n  >>\nstream\n  /b2 1 0 R\n  /b1 1 0 R\nendstream\n".to_vec();
        let out = canonical_resource_order(pdf.clone());
        assert_eq!(out.len(), pdf.len());
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "%PDF-1.7\n  /Resources <<\n      /xo2 9 0 R\n      /xo12 31 0 R\n      /gs0 3 0 R\n      /gs1 4 0 R\n  >>\nstream\n  /b2 1 0 R\n  /b1 1 0 R\nendstream\n"
        );
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
