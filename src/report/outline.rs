//! Figure text set as glyph outlines. Every `<text>` element of a figure's SVG becomes one
//! `<path>` holding the outlines of its glyphs in the embedded DejaVu Sans, placed with the
//! font's own advances and kerning (the `kern` table, read by `ab_glyph`, the same reader
//! plotters measures its labels with). The SVG written to disk, its PNG (resvg) and its PDF
//! (svg2pdf) are then drawn from the same paths: the figure looks the same in every viewer,
//! whatever fonts it has, and neither the rasteriser nor the PDF writer needs a text-shaping
//! stack (the build carries no font database, shaper or font subsetter).
//!
//! The text stays in the file: each path carries it as `aria-label`, read by screen readers and
//! found by a search of the file.
//!
//! Scope: the attributes our figure writers emit (`x`, `y`, `dy` in `em`, `ex` or user units,
//! `text-anchor`, `font-size`, `fill`, `opacity`, `transform`) and character content without
//! child elements. `1ex` is taken as half an em, as usvg (and so the earlier PNGs) did.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, GlyphId, OutlineCurve};

use crate::error::{Error, Result};

static DEJAVU_SANS: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

/// The embedded font, parsed once per process.
fn font() -> Result<&'static FontRef<'static>> {
    static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(DEJAVU_SANS).ok())
        .as_ref()
        .ok_or_else(|| Error::Numerical("the embedded DejaVu Sans font cannot be read".into()))
}

/// `svg` with every `<text …>…</text>` element replaced by the outlines of its glyphs. SVG
/// without text comes back unchanged.
pub fn outline_text(svg: &str) -> Result<String> {
    if !svg.contains("<text") {
        return Ok(svg.to_string());
    }
    let mut out = String::with_capacity(svg.len() * 2);
    let mut rest = svg;
    while let Some(start) = find_text_open(rest) {
        out.push_str(&rest[..start]);
        let element = &rest[start..];
        let tag_end = element
            .find('>')
            .ok_or_else(|| malformed("a <text> tag is not closed"))?;
        let tag = &element[..tag_end];
        let (content, after) = if tag.ends_with('/') {
            ("", &element[tag_end + 1..])
        } else {
            let body = &element[tag_end + 1..];
            let close = body
                .find("</text>")
                .ok_or_else(|| malformed("a <text> element has no </text>"))?;
            (&body[..close], &body[close + "</text>".len()..])
        };
        if content.contains('<') {
            return Err(malformed("a <text> element holds child elements"));
        }
        out.push_str(&text_path(&attributes(&tag["<text".len()..])?, content)?);
        rest = after;
    }
    out.push_str(rest);
    Ok(out)
}

/// The byte offset of the next `<text` start tag (not `<textPath` or another name).
fn find_text_open(s: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(i) = s[from..].find("<text") {
        let at = from + i;
        match s[at + 5..].chars().next() {
            Some(c) if c.is_whitespace() || c == '>' || c == '/' => return Some(at),
            _ => from = at + 5,
        }
    }
    None
}

fn malformed(what: &str) -> Error {
    Error::Numerical(format!("a figure's SVG is malformed: {what}"))
}

/// The `name="value"` pairs of a start tag (values unescaped).
fn attributes(s: &str) -> Result<Vec<(&str, String)>> {
    let mut attrs = Vec::new();
    let mut rest = s.trim_start().trim_end_matches('/');
    while !rest.trim().is_empty() {
        let eq = rest
            .find('=')
            .ok_or_else(|| malformed("an attribute without a value"))?;
        let name = rest[..eq].trim();
        let after = rest[eq + 1..].trim_start();
        let quote = after
            .chars()
            .next()
            .filter(|&q| q == '"' || q == '\'')
            .ok_or_else(|| malformed("an unquoted attribute"))?;
        let end = after[1..]
            .find(quote)
            .ok_or_else(|| malformed("an unterminated attribute"))?;
        attrs.push((name, unescape(&after[1..1 + end])));
        rest = after[end + 2..].trim_start();
    }
    Ok(attrs)
}

/// XML character references and the five predefined entities resolved.
fn unescape(s: &str) -> String {
    if !s.contains('&') {
        return s.to_string();
    }
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find('&') {
        out.push_str(&rest[..i]);
        let tail = &rest[i..];
        let Some(semi) = tail.find(';') else {
            out.push_str(tail);
            return out;
        };
        let entity = &tail[1..semi];
        let c = match entity {
            "lt" => Some('<'),
            "gt" => Some('>'),
            "amp" => Some('&'),
            "quot" => Some('"'),
            "apos" => Some('\''),
            _ => entity
                .strip_prefix("#x")
                .and_then(|h| u32::from_str_radix(h, 16).ok())
                .or_else(|| entity.strip_prefix('#').and_then(|d| d.parse().ok()))
                .and_then(char::from_u32),
        };
        match c {
            Some(c) => {
                out.push(c);
                rest = &tail[semi + 1..];
            }
            None => {
                out.push('&');
                rest = &tail[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

/// Character content as SVG shows it by default (`xml:space="default"`): newlines removed, tabs
/// as spaces, leading and trailing spaces dropped and runs of spaces made one.
fn collapse_space(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars().filter(|&c| c != '\n' && c != '\r') {
        let c = if c == '\t' { ' ' } else { c };
        if !(c == ' ' && (out.is_empty() || out.ends_with(' '))) {
            out.push(c);
        }
    }
    out.trim_end().to_string()
}

/// Text safe inside an attribute value or element content.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A length in user units: a number, or `em`/`ex` relative to the font size.
fn length(value: &str, font_size: f64) -> Result<f64> {
    let v = value.trim();
    let (number, scale) = if let Some(n) = v.strip_suffix("em") {
        (n, font_size)
    } else if let Some(n) = v.strip_suffix("ex") {
        (n, font_size / 2.0)
    } else {
        (v.strip_suffix("px").unwrap_or(v), 1.0)
    };
    number
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
        .map(|x| x * scale)
        .ok_or_else(|| malformed("a text position is not a number"))
}

/// One `<path>` drawing `content` as the element with `attrs` would show it.
fn text_path(attrs: &[(&str, String)], content: &str) -> Result<String> {
    let get = |name: &str| attrs.iter().find(|(n, _)| *n == name).map(|(_, v)| v);
    let font_size = match get("font-size") {
        Some(v) => length(v, 16.0)?,
        None => 16.0,
    };
    let pos = |name: &str| get(name).map_or(Ok(0.0), |v| length(v, font_size));
    let (x, y, dy) = (pos("x")?, pos("y")?, pos("dy")?);
    let text = collapse_space(&unescape(content));
    let font = font()?;
    let scale = font_size / f64::from(font.units_per_em().unwrap_or(2048.0));
    let glyphs: Vec<GlyphId> = text.chars().map(|c| font.glyph_id(c)).collect();
    // Pen positions in font units, kerned pair by pair.
    let mut pens = Vec::with_capacity(glyphs.len());
    let mut pen = 0.0f64;
    for (i, &g) in glyphs.iter().enumerate() {
        if i > 0 {
            pen += f64::from(font.kern_unscaled(glyphs[i - 1], g));
        }
        pens.push(pen);
        pen += f64::from(font.h_advance_unscaled(g));
    }
    let width = pen * scale;
    let x0 = x - match get("text-anchor").map(String::as_str) {
        Some("middle") => width / 2.0,
        Some("end") => width,
        _ => 0.0,
    };
    let y0 = y + dy;
    let mut d = String::new();
    for (&g, &p) in glyphs.iter().zip(&pens) {
        if let Some(outline) = font.outline(g) {
            let at = |q: ab_glyph::Point| {
                (
                    x0 + (p + f64::from(q.x)) * scale,
                    y0 - f64::from(q.y) * scale,
                )
            };
            append_outline(&mut d, &outline.curves, at);
        }
    }
    // The size stays on the path (no effect on its drawing) so that a reader of the file can
    // tell the text size at print size.
    let mut path = format!(
        r#"<path aria-label="{}" font-size="{}" d="{d}""#,
        escape(&text),
        (font_size * 1000.0).round() / 1000.0
    );
    path.push_str(&format!(
        r#" fill="{}""#,
        escape(get("fill").map_or("#000000", String::as_str))
    ));
    for name in ["opacity", "fill-opacity", "transform"] {
        if let Some(v) = get(name) {
            path.push_str(&format!(r#" {name}="{}""#, escape(v)));
        }
    }
    path.push_str("></path>");
    Ok(path)
}

/// Appends the contours of one glyph to path data: a new subpath wherever a curve does not
/// start where the previous one ended, each closed.
fn append_outline(
    d: &mut String,
    curves: &[OutlineCurve],
    at: impl Fn(ab_glyph::Point) -> (f64, f64),
) {
    use std::fmt::Write;
    let mut last: Option<ab_glyph::Point> = None;
    for curve in curves {
        let start = match curve {
            OutlineCurve::Line(a, _) | OutlineCurve::Quad(a, _, _) | OutlineCurve::Cubic(a, ..) => {
                *a
            }
        };
        if last != Some(start) {
            if last.is_some() {
                d.push('Z');
            }
            let (sx, sy) = at(start);
            let _ = write!(d, "M{sx:.2} {sy:.2}");
        }
        last = Some(match curve {
            OutlineCurve::Line(_, b) => {
                let (bx, by) = at(*b);
                let _ = write!(d, "L{bx:.2} {by:.2}");
                *b
            }
            OutlineCurve::Quad(_, c, b) => {
                let ((cx, cy), (bx, by)) = (at(*c), at(*b));
                let _ = write!(d, "Q{cx:.2} {cy:.2} {bx:.2} {by:.2}");
                *b
            }
            OutlineCurve::Cubic(_, c1, c2, b) => {
                let ((c1x, c1y), (c2x, c2y), (bx, by)) = (at(*c1), at(*c2), at(*b));
                let _ = write!(d, "C{c1x:.2} {c1y:.2} {c2x:.2} {c2y:.2} {bx:.2} {by:.2}");
                *b
            }
        });
    }
    if last.is_some() {
        d.push('Z');
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_becomes_one_labelled_path_per_element() {
        let svg = r##"<svg xmlns="http://www.w3.org/2000/svg" width="200" height="50"><rect x="0" y="0" width="5" height="5"/><text x="10" y="30" font-size="20" fill="#123456" transform="rotate(270, 10, 30)">
  A  &lt;b&gt;
</text><text x="1" y="2"/></svg>"##;
        let out = outline_text(svg).unwrap();
        assert!(!out.contains("<text"), "{out}");
        assert_eq!(out.matches("<path").count(), 2);
        assert!(out.contains(r#"aria-label="A &lt;b&gt;""#), "{out}");
        assert!(out.contains(r##"fill="#123456""##));
        assert!(out.contains(r#"transform="rotate(270, 10, 30)""#));
        assert!(out.starts_with(
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="200" height="50"><rect"#
        ));
        // Idempotent: outlined SVG has no text left to outline.
        assert_eq!(outline_text(&out).unwrap(), out);
    }

    /// The outline spans the font's advances: "balancing" at 40 px, set from x = 10 with the
    /// middle anchor, is centred on x = 10 within the side bearings.
    #[test]
    fn anchors_and_advances_place_the_glyphs() {
        let font = font().unwrap();
        let size = 40.0;
        let text = "balancing";
        let advance: f64 = text
            .chars()
            .map(|c| f64::from(font.h_advance_unscaled(font.glyph_id(c))))
            .sum::<f64>()
            * size
            / 2048.0;
        // The same advance the hand-read hmtx table gives (report::svg::tests).
        assert!((advance - 9970.0 * size / 2048.0).abs() < 1.0, "{advance}");
        let xs = |svg: &str| -> (f64, f64) {
            let d = svg
                .split(r#" d=""#)
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap();
            let nums: Vec<f64> = d
                .split(|c: char| c.is_ascii_alphabetic() || c == ' ')
                .filter_map(|t| t.parse().ok())
                .collect();
            let xs = nums.iter().step_by(2);
            (
                xs.clone().cloned().fold(f64::INFINITY, f64::min),
                xs.cloned().fold(f64::NEG_INFINITY, f64::max),
            )
        };
        let start = outline_text(&format!(
            r#"<text x="10" y="50" font-size="{size}">{text}</text>"#
        ))
        .unwrap();
        let (lo, hi) = xs(&start);
        assert!(lo >= 10.0 && lo < 10.0 + 0.1 * size, "{lo}");
        assert!(
            hi <= 10.0 + advance && hi > 10.0 + advance - 0.1 * size,
            "{hi}"
        );
        let end = outline_text(&format!(
            r#"<text x="10" y="50" font-size="{size}" text-anchor="end">{text}</text>"#
        ))
        .unwrap();
        let (lo_end, hi_end) = xs(&end);
        assert!((lo_end - (lo - advance)).abs() < 0.02 && (hi_end - (hi - advance)).abs() < 0.02);
    }

    #[test]
    fn dy_in_em_and_ex_moves_the_baseline() {
        let ys = |dy: &str| -> f64 {
            let svg = format!(r#"<text x="0" y="100" dy="{dy}" font-size="20">_</text>"#);
            let out = outline_text(&svg).unwrap();
            let d = out
                .split(r#" d=""#)
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap();
            d.split(|c: char| c.is_ascii_alphabetic() || c == ' ')
                .filter_map(|t| t.parse::<f64>().ok())
                .skip(1)
                .step_by(2)
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let base = ys("0");
        assert!((ys("0.5em") - base - 10.0).abs() < 0.02);
        assert!((ys("-0.5ex") - base + 5.0).abs() < 0.02);
    }

    #[test]
    fn malformed_text_is_an_error() {
        assert!(outline_text("<text x=\"1\">open").is_err());
        assert!(outline_text("<text x=1>a</text>").is_err());
        assert!(outline_text("<text x=\"a\">a</text>").is_err());
        assert!(outline_text("<text><tspan>a</tspan></text>").is_err());
    }
}
