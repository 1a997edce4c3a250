//! Every bitmap figure is a rendering of its SVG: plots, heatmaps, per-unit maps and the
//! bench layout are drawn once as SVG and rasterised here by resvg, or converted to PDF by
//! svg2pdf. Text is set before either sees it: `report::outline` replaces each `<text>` with the
//! outlines of its glyphs in the embedded DejaVu Sans (the font's own advances and kerning), so
//! the PNG and the PDF show the same glyphs, at the same places, as the SVG file does in any
//! viewer, no system font is ever consulted, and the build needs no text-shaping stack.
//!
//! Why not plotters' bitmap backend: it positions glyphs one by one from rounded pixel boxes,
//! which breaks words apart ("bal ancing") and lifts the decimal point.

use crate::error::{Error, Result};

/// Parses SVG text into a usvg tree, its text set as glyph outlines first.
pub fn parse(svg: &str) -> Result<resvg::usvg::Tree> {
    let svg = super::outline::outline_text(svg)?;
    resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default())
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

/// A one-page PDF of SVG text, one PDF point per SVG user unit (so a 960 × 600 figure is
/// 13.3 × 8.3 in, to be scaled by `\includegraphics[width=…]`). Text is drawn as the glyph
/// outlines of the SVG ([`parse`]), so the PDF needs no embedded font. The file holds no date,
/// so the same figure gives the same bytes.
pub fn svg_to_pdf(svg: &str) -> Result<Vec<u8>> {
    // resvg and svg2pdf share one usvg version, so the tree parsed for the PNG serves here.
    let tree = parse(svg)?;
    svg2pdf::to_pdf(
        &tree,
        svg2pdf::ConversionOptions::default(),
        svg2pdf::PageOptions { dpi: 72.0 },
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
