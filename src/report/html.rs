//! One self-contained HTML page per report: text, tables, key–value lists and images, all in
//! a single file that needs no network, no script and no external style sheet or font.
//!
//! A report is plain data ([`Page`] holding [`Block`]s) turned into a string by [`render`] (or
//! written atomically by [`write_page`]). Everything that is text is HTML-escaped ([`escape`]),
//! so a caption or table cell holding `<script>` shows those characters and runs nothing.
//!
//! # Images
//!
//! PNG bytes are embedded as `data:image/png;base64,…` URIs (base64 of RFC 4648 §4, written
//! here: [`base64`]). An image narrower than [`MIN_DISPLAY_PX`] is shown enlarged by the
//! smallest whole factor that brings it to that width (a 48×48 reconstruction at 6×, 288 px),
//! and every enlarged image is drawn with `image-rendering: pixelated`, so each pixel stays a
//! crisp square instead of being smoothed: a reconstruction's pixels are its data.
//! [`png_bytes_gray8`] encodes a [`Raster`] in memory with the same code as the PNG files.
//!
//! SVG (for example a plot from `plotters`) is embedded as a `data:image/svg+xml;base64,…`
//! URI in an `<img>`, not inline. Why: an SVG referenced by `<img>` is rendered by browsers in
//! their "secure static mode" (no script runs, no external resource is fetched, no event
//! handler fires; W3C SVG 2 §"Processing modes", HTML's rule for images), and its markup is
//! base64 text that cannot close or open a tag of the page. Inline SVG would share the page's
//! DOM, so any `<script>`, `<foreignObject>` or `on…` attribute in it would run or break the
//! page unless the SVG were fully parsed and sanitised. Before embedding, the text is checked
//! to be an SVG document (optional BOM, XML declaration, comments and a DOCTYPE without an
//! internal subset, then an `<svg` root element); anything else is shown as a visible
//! placeholder. A root element without an `xmlns` gets the SVG namespace added, since an
//! `<img>` renders nothing without it.
//!
//! A Content-Security-Policy meta element (`default-src 'none'; img-src data:; style-src
//! 'unsafe-inline'`) makes the browser itself refuse any script and any fetch, so the page
//! stays self-contained even if a future block type made a mistake.
//!
//! # Checking the look in a browser
//!
//! The Rust tests need no browser. To look at a sample page (Debian's `chromium` package):
//!
//! ```text
//! SPIBENCH_HTML_SAMPLE=/tmp/page.html cargo test --lib report::html::tests::sample_page
//! chromium --headless --no-sandbox --disable-gpu --hide-scrollbars \
//!     --screenshot=/tmp/page.png --window-size=1200,1600 file:///tmp/page.html
//! chromium --headless --no-sandbox --disable-gpu --no-pdf-header-footer \
//!     --print-to-pdf=/tmp/page.pdf file:///tmp/page.html
//! ```

use std::fmt::Write as _;
use std::path::Path;

use super::npy::write_atomic;
use crate::error::Result;
use crate::raster::Raster;

/// Images narrower than this (CSS px) are shown enlarged by a whole factor (see module docs).
pub const MIN_DISPLAY_PX: u32 = 256;

/// One HTML page: a title (shown as the top heading) and its blocks, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct Page {
    pub title: String,
    pub blocks: Vec<Block>,
}

/// The parts a page is built from. All strings are plain text (escaped when rendered).
#[derive(Debug, Clone, PartialEq)]
pub enum Block {
    /// A section heading; `level` 1..=6 (values outside are clamped). Level-2 headings get a
    /// table of contents under the title when there are at least three of them.
    Heading {
        level: u8,
        text: String,
    },
    Paragraph(String),
    /// A table; cells that read as numbers (optionally with `%`) are right-aligned.
    Table {
        caption: Option<String>,
        header: Vec<String>,
        rows: Vec<Vec<String>>,
    },
    /// A PNG file's bytes, embedded. `width_px`: the display width in CSS pixels; `None`
    /// shows the natural width, enlarged by a whole factor when below [`MIN_DISPLAY_PX`].
    Image {
        caption: String,
        png: Vec<u8>,
        alt: String,
        width_px: Option<u32>,
    },
    /// An SVG document (text), embedded as an image (see the module docs for why).
    Svg {
        caption: String,
        svg: String,
    },
    /// Blocks side by side (wrapping on narrow pages), typically images of the same size.
    Figures(Vec<Block>),
    /// Monospaced text, whitespace kept.
    Preformatted(String),
    /// A two-column list of names and values.
    KeyValues(Vec<(String, String)>),
    /// The summary card a page opens with: a framed two-column list of the few numbers a reader
    /// looks for first, under its title.
    Card {
        title: String,
        rows: Vec<(String, String)>,
    },
    /// A collapsible section (`<details>`), closed until opened: long explanations, kept out of
    /// the reader's way.
    Details {
        summary: String,
        blocks: Vec<Block>,
    },
}

/// `blocks` with every paragraph longer than `max_chars` characters folded into a collapsible
/// section whose summary is the paragraph's first sentence (up to its first ". ", at most
/// about 160 characters) and whose body is the whole paragraph.
pub fn fold_long_paragraphs(blocks: Vec<Block>, max_chars: usize) -> Vec<Block> {
    blocks
        .into_iter()
        .map(|b| match b {
            Block::Paragraph(text) if text.chars().count() > max_chars => {
                let first = text.split(". ").next().unwrap_or(&text);
                let mut summary: String = first.chars().take(160).collect();
                if summary.chars().count() < text.chars().count() {
                    summary.push_str(" …");
                }
                Block::Details {
                    summary,
                    blocks: vec![Block::Paragraph(text)],
                }
            }
            Block::Figures(inner) => Block::Figures(fold_long_paragraphs(inner, max_chars)),
            other => other,
        })
        .collect()
}

impl Block {
    /// A grayscale image of `image`, mapped linearly from `[lo, hi]` to black..white (as
    /// [`png_bytes_gray8`]); the caption doubles as the alternative text.
    pub fn gray_image(
        caption: impl Into<String>,
        image: &Raster,
        lo: f64,
        hi: f64,
    ) -> Result<Block> {
        let caption = caption.into();
        Ok(Block::Image {
            alt: caption.clone(),
            caption,
            png: png_bytes_gray8(image, lo, hi)?,
            width_px: None,
        })
    }
}

/// An 8-bit gray PNG of `image` in memory: `[lo, hi]` maps linearly to `[0, 255]`, clipped,
/// rounded, NaN to 0 (the encoder of `report::png::write_gray8`). Bad input (a non-finite or
/// empty range, an inconsistent raster) is `Error::Input`.
pub fn png_bytes_gray8(image: &Raster, lo: f64, hi: f64) -> Result<Vec<u8>> {
    super::png::encode_gray8(image, lo, hi)
}

/// A value with its standard error in concise (parenthesis) notation, as metrology writes it
/// (JCGM 100:2008, the GUM, §7.2.2): `0.3531(3)` is 0.3531 ± 0.0003. The uncertainty keeps two
/// significant digits when its first digit is 1 or 2 (so rounding it costs at most ~25 %) and
/// one otherwise, and the value is rounded to the same decimal place. Magnitudes outside
/// 10⁻³…10⁵ get a power of ten: `1.2345(12)×10⁻⁶`. A zero standard error shows the value alone
/// (six significant digits); a NaN one appends "(unresolved)".
pub fn concise(v: f64, se: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    let exp = |m: f64| -> i32 {
        if m != 0.0 && !(1e-3..1e5).contains(&m.abs()) {
            m.abs().log10().floor() as i32
        } else {
            0
        }
    };
    if se.is_nan() || se == 0.0 || se.is_infinite() {
        let e = exp(v);
        let m = v / 10f64.powi(e);
        let text = if v == 0.0 {
            "0".to_string()
        } else {
            let digits = (5 - m.abs().log10().floor() as i32).clamp(0, 12) as usize;
            trim_zeros(format!("{m:.digits$}"))
        };
        let text = text + &times_ten(e);
        return if se.is_nan() {
            format!("{text} (unresolved)")
        } else {
            text
        };
    }
    let se = se.abs();
    let e = if v != 0.0 { exp(v) } else { exp(se) };
    let scale = 10f64.powi(e);
    let (m, s) = (v / scale, se / scale);
    let mut lead = s.log10().floor() as i32;
    // The first digit after rounding to two significant digits (9.96 → 10 moves up a decade).
    let first = (s / 10f64.powi(lead - 1)).round() / 10.0;
    if first >= 10.0 {
        lead += 1;
    }
    let first = (s / 10f64.powi(lead)).floor().max(1.0);
    let digits = if first < 3.0 { 2 } else { 1 };
    let place = lead - (digits - 1);
    let unc = (s / 10f64.powi(place)).round() as u64;
    let body = if place >= 0 {
        let q = 10f64.powi(place);
        format!(
            "{:.0}({})",
            (m / q).round() * q,
            unc * 10u64.pow(place as u32)
        )
    } else {
        let decimals = (-place) as usize;
        format!("{m:.decimals$}({unc})")
    };
    body.replace('-', "−") + &times_ten(e)
}

fn trim_zeros(s: String) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn times_ten(e: i32) -> String {
    if e == 0 {
        return String::new();
    }
    let sup = super::superscript(e);
    format!("×10{sup}")
}

/// `concise(v, se)` followed by the unit (none when `unit` is empty).
pub fn concise_unit(v: f64, se: f64, unit: &str) -> String {
    if unit.is_empty() {
        concise(v, se)
    } else {
        format!("{} {unit}", concise(v, se))
    }
}

/// A value in engineering notation with an SI prefix and five significant digits
/// (`1.2346 mW`, `−48.000 nA`); an exact zero is `0 W`.
pub fn eng(v: f64, unit: &str) -> String {
    if v == 0.0 {
        return format!("0 {unit}");
    }
    if !v.is_finite() {
        return format!("{v} {unit}");
    }
    const PREFIXES: [(i32, &str); 11] = [
        (-24, "y"),
        (-21, "z"),
        (-18, "a"),
        (-15, "f"),
        (-12, "p"),
        (-9, "n"),
        (-6, "µ"),
        (-3, "m"),
        (0, ""),
        (3, "k"),
        (6, "M"),
    ];
    let mut e3 = (v.abs().log10().floor() as i32).div_euclid(3) * 3;
    // Rounding to five significant digits may carry into the next group (999.996 → 1000.0).
    let mut m = v / 10f64.powi(e3);
    let decimals = |m: f64| (4 - m.abs().log10().floor() as i32).clamp(0, 4) as usize;
    let rounded: f64 = format!("{m:.*}", decimals(m)).parse().unwrap_or(m);
    if rounded.abs() >= 1000.0 {
        e3 += 3;
        m = v / 10f64.powi(e3);
    }
    match PREFIXES.iter().find(|(p, _)| *p == e3) {
        Some((_, prefix)) => format!("{:.*} {prefix}{unit}", decimals(m), m).replace('-', "−"),
        None => format!("{v:.4e} {unit}").replace('-', "−"),
    }
}

/// Base64 of `bytes` with the standard alphabet and `=` padding (RFC 4648 §4), no line breaks.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        // Three bytes make a 24-bit group, read as four 6-bit indices from the most
        // significant end; a short final chunk is padded with zero bits and `=` (RFC 4648 §4).
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let group = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                let index = (group >> (18 - 6 * i)) & 0x3f;
                out.push(char::from(ALPHABET[index as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Escapes text for HTML element content and quoted attribute values: `& < > " '` become
/// character references, and control characters other than tab, line feed and carriage return
/// (which HTML does not allow) become U+FFFD.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + text.len() / 8);
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            '\t' | '\n' | '\r' => out.push(c),
            c if c.is_control() => out.push('\u{FFFD}'),
            c => out.push(c),
        }
    }
    out
}

/// The style sheet: readable on screen, clean on paper, no external resources.
const STYLE: &str = r#"
:root { color-scheme: light; }
body { font-family: system-ui, -apple-system, "Segoe UI", "DejaVu Sans", Helvetica, Arial, sans-serif;
  color: #1a1a1a; background: #fff; line-height: 1.45; max-width: 72rem; margin: 1.5rem auto;
  padding: 0 1.5rem; font-size: 15px; }
h1 { font-size: 1.7em; margin: 0.2em 0 0.6em; border-bottom: 2px solid #333; padding-bottom: 0.2em; }
h2 { font-size: 1.35em; margin: 1.6em 0 0.5em; border-bottom: 1px solid #bbb; padding-bottom: 0.15em; }
h3 { font-size: 1.15em; margin: 1.3em 0 0.4em; }
h4, h5, h6 { font-size: 1em; margin: 1.1em 0 0.3em; }
p { margin: 0.5em 0 0.8em; }
nav.toc { font-size: 0.92em; margin: 0 0 1em; }
nav.toc ol { margin: 0.2em 0; padding-left: 1.6em; }
nav.toc a { color: #1a4f8a; text-decoration: none; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.93em; }
caption { caption-side: top; text-align: left; font-weight: 600; padding-bottom: 0.3em; }
th, td { border: 1px solid #c8c8c8; padding: 0.25em 0.6em; vertical-align: top; text-align: left; }
thead th { background: #eef0f3; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
table.kv th { background: #f6f7f9; font-weight: 600; white-space: nowrap; }
pre { background: #f6f7f9; border: 1px solid #ddd; padding: 0.6em 0.8em; overflow-x: auto;
  font-size: 0.88em; line-height: 1.3; white-space: pre-wrap; word-break: break-word; }
figure { margin: 0.6em 0 1.2em; display: inline-block; vertical-align: top; max-width: 100%; }
figure img { display: block; max-width: 100%; height: auto; border: 1px solid #ccc; background: #fff; }
figure img.px { image-rendering: crisp-edges; image-rendering: pixelated; }
figcaption { font-size: 0.9em; color: #333; margin-top: 0.3em; max-width: 100%; }
.figures { display: flex; flex-wrap: wrap; gap: 1rem 1.4rem; align-items: flex-start; margin: 0.6em 0 1.2em; }
.figures > figure { margin: 0; }
.missing { border: 1px dashed #b00; color: #b00; padding: 0.6em; font-size: 0.9em; }
section.card { border: 2px solid #1a4f8a; border-radius: 6px; padding: 0.4em 1em 0.2em;
  margin: 0.6em 0 1.4em; background: #f7f9fc; }
h2.card { border: none; margin: 0.3em 0 0.2em; font-size: 1.15em; }
section.card table.kv { margin: 0.3em 0 0.6em; }
section.card table.kv th, section.card table.kv td { white-space: normal; }
details { margin: 0.3em 0 0.8em; }
details > summary { cursor: pointer; color: #1a4f8a; }
footer { margin-top: 2.5em; font-size: 0.8em; color: #666; border-top: 1px solid #ddd; padding-top: 0.4em; }
@page { margin: 15mm; }
@media print {
  body { max-width: none; margin: 0; padding: 0; font-size: 10pt; }
  nav.toc { display: none; }
  figure, table, pre, .figures { break-inside: avoid; }
  h1, h2, h3, h4 { break-after: avoid; }
  thead th, table.kv th, pre { background: none; }
}
"#;

/// The policy that keeps the page self-contained: no script, no fetch, inline style and
/// data: images only.
const CSP: &str = "default-src 'none'; img-src data:; style-src 'unsafe-inline'";

/// The page as one HTML5 document.
pub fn render(page: &Page) -> String {
    let mut out = String::new();
    out.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    let _ = writeln!(
        out,
        "<meta http-equiv=\"Content-Security-Policy\" content=\"{CSP}\">"
    );
    out.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    let _ = writeln!(out, "<title>{}</title>", escape(&page.title));
    let _ = writeln!(out, "<style>{STYLE}</style>\n</head>\n<body>");
    let _ = writeln!(out, "<h1>{}</h1>", escape(&page.title));

    // Every heading gets an id in document order (nested ones too), so the contents can link.
    let mut headings = Vec::new();
    collect_headings(&page.blocks, &mut headings);
    let sections: Vec<(usize, &str)> = headings
        .iter()
        .enumerate()
        .filter(|(_, (level, _))| *level == 2)
        .map(|(i, (_, text))| (i, *text))
        .collect();
    if sections.len() >= 3 {
        out.push_str("<nav class=\"toc\"><ol>\n");
        for (i, text) in sections {
            let _ = writeln!(out, "<li><a href=\"#s{}\">{}</a></li>", i + 1, escape(text));
        }
        out.push_str("</ol></nav>\n");
    }
    let mut next_heading = 0;
    for block in &page.blocks {
        render_block(&mut out, block, &mut next_heading);
    }
    let _ = writeln!(
        out,
        "<footer>Generated by spibench {}.</footer>\n</body>\n</html>",
        env!("CARGO_PKG_VERSION")
    );
    out
}

/// Writes the rendered page to `path` atomically (temporary name, then rename).
pub fn write_page(path: &Path, page: &Page) -> Result<()> {
    write_atomic(path, render(page).as_bytes())
}

fn clamp_level(level: u8) -> u8 {
    level.clamp(1, 6)
}

fn collect_headings<'a>(blocks: &'a [Block], out: &mut Vec<(u8, &'a str)>) {
    for b in blocks {
        match b {
            Block::Heading { level, text } => out.push((clamp_level(*level), text)),
            Block::Figures(inner) => collect_headings(inner, out),
            _ => {}
        }
    }
}

/// True for a table cell that reads as a number: optional sign (ASCII or U+2212 minus), digits,
/// decimal point, exponent, optional trailing `%`.
fn is_numeric(cell: &str) -> bool {
    let t = cell.trim();
    let t = t.strip_suffix('%').unwrap_or(t).trim_end();
    let t = t.replace('\u{2212}', "-");
    !t.is_empty()
        && t.chars().any(|c| c.is_ascii_digit())
        && t.chars()
            .all(|c| c.is_ascii_digit() || matches!(c, '+' | '-' | '.' | 'e' | 'E'))
        && t.parse::<f64>().is_ok()
}

/// Width and height from a PNG's IHDR chunk, or `None` if the bytes are not a PNG file.
fn png_size(png: &[u8]) -> Option<(u32, u32)> {
    const SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
    if png.len() < 24 || &png[..8] != SIGNATURE || &png[12..16] != b"IHDR" {
        return None;
    }
    let w = u32::from_be_bytes(png[16..20].try_into().ok()?);
    let h = u32::from_be_bytes(png[20..24].try_into().ok()?);
    (w > 0 && h > 0).then_some((w, h))
}

/// The display width of an image of natural width `natural` (see [`Block::Image`]).
fn display_width(natural: u32, requested: Option<u32>) -> u32 {
    match requested {
        Some(w) if w > 0 => w,
        _ if natural < MIN_DISPLAY_PX => natural * MIN_DISPLAY_PX.div_ceil(natural),
        _ => natural,
    }
}

/// The SVG text ready for embedding, or `None` if it is not an SVG document (module docs).
fn checked_svg(svg: &str) -> Option<String> {
    let mut rest = svg.strip_prefix('\u{FEFF}').unwrap_or(svg).trim_start();
    loop {
        if let Some(r) = rest.strip_prefix("<?") {
            rest = r.split_once("?>")?.1.trim_start();
        } else if let Some(r) = rest.strip_prefix("<!--") {
            rest = r.split_once("-->")?.1.trim_start();
        } else if rest
            .get(..9)
            .is_some_and(|p| p.eq_ignore_ascii_case("<!DOCTYPE"))
        {
            let (decl, r) = rest.split_once('>')?;
            // An internal subset can define entities; refuse it rather than reason about it.
            if decl.contains('[') {
                return None;
            }
            rest = r.trim_start();
        } else {
            break;
        }
    }
    let after = rest.strip_prefix("<svg")?;
    if !after.starts_with(|c: char| c.is_ascii_whitespace() || c == '>' || c == '/') {
        return None;
    }
    let root_tag = &after[..after.find('>')?];
    if root_tag.contains("xmlns=") {
        Some(svg.to_string())
    } else {
        // Insert the namespace right after `<svg` of the root element.
        let at = svg.len() - after.len();
        Some(format!(
            "{} xmlns=\"http://www.w3.org/2000/svg\"{}",
            &svg[..at],
            &svg[at..]
        ))
    }
}

fn figcaption(out: &mut String, caption: &str) {
    if !caption.is_empty() {
        let _ = write!(out, "<figcaption>{}</figcaption>", escape(caption));
    }
}

fn render_block(out: &mut String, block: &Block, next_heading: &mut usize) {
    match block {
        Block::Heading { level, text } => {
            *next_heading += 1;
            let l = clamp_level(*level);
            let _ = writeln!(
                out,
                "<h{l} id=\"s{}\">{}</h{l}>",
                *next_heading,
                escape(text)
            );
        }
        Block::Paragraph(text) => {
            let _ = writeln!(out, "<p>{}</p>", escape(text));
        }
        Block::Table {
            caption,
            header,
            rows,
        } => {
            out.push_str("<table>\n");
            if let Some(c) = caption {
                let _ = writeln!(out, "<caption>{}</caption>", escape(c));
            }
            if !header.is_empty() {
                out.push_str("<thead><tr>");
                for h in header {
                    let _ = write!(out, "<th scope=\"col\">{}</th>", escape(h));
                }
                out.push_str("</tr></thead>\n");
            }
            out.push_str("<tbody>\n");
            for row in rows {
                out.push_str("<tr>");
                for cell in row {
                    if is_numeric(cell) {
                        let _ = write!(out, "<td class=\"num\">{}</td>", escape(cell));
                    } else {
                        let _ = write!(out, "<td>{}</td>", escape(cell));
                    }
                }
                out.push_str("</tr>\n");
            }
            out.push_str("</tbody>\n</table>\n");
        }
        Block::Image {
            caption,
            png,
            alt,
            width_px,
        } => {
            out.push_str("<figure>");
            match png_size(png) {
                Some((w, _)) => {
                    let shown = display_width(w, *width_px);
                    let class = if shown > w { " class=\"px\"" } else { "" };
                    let _ = write!(
                        out,
                        "<img{class} width=\"{shown}\" alt=\"{}\" src=\"data:image/png;base64,{}\">",
                        escape(alt),
                        base64(png)
                    );
                }
                None => {
                    let _ = write!(
                        out,
                        "<div class=\"missing\">Image not shown: the data is not a PNG file ({} bytes).</div>",
                        png.len()
                    );
                }
            }
            figcaption(out, caption);
            out.push_str("</figure>\n");
        }
        Block::Svg { caption, svg } => {
            out.push_str("<figure>");
            match checked_svg(svg) {
                Some(doc) => {
                    let _ = write!(
                        out,
                        "<img alt=\"{}\" src=\"data:image/svg+xml;base64,{}\">",
                        escape(caption),
                        base64(doc.as_bytes())
                    );
                }
                None => {
                    out.push_str(
                        "<div class=\"missing\">Image not shown: the text is not an SVG document.</div>",
                    );
                }
            }
            figcaption(out, caption);
            out.push_str("</figure>\n");
        }
        Block::Figures(blocks) => {
            out.push_str("<div class=\"figures\">\n");
            for b in blocks {
                render_block(out, b, next_heading);
            }
            out.push_str("</div>\n");
        }
        Block::Preformatted(text) => {
            // The HTML parser drops one newline right after <pre>, so one is added to keep a
            // leading newline of the text.
            let _ = writeln!(out, "<pre>\n{}</pre>", escape(text));
        }
        Block::Card { title, rows } => {
            let _ = writeln!(
                out,
                "<section class=\"card\">\n<h2 class=\"card\">{}</h2>",
                escape(title)
            );
            render_block(out, &Block::KeyValues(rows.clone()), next_heading);
            out.push_str("</section>\n");
        }
        Block::Details { summary, blocks } => {
            let _ = writeln!(out, "<details>\n<summary>{}</summary>", escape(summary));
            for b in blocks {
                render_block(out, b, next_heading);
            }
            out.push_str("</details>\n");
        }
        Block::KeyValues(pairs) => {
            out.push_str("<table class=\"kv\">\n<tbody>\n");
            for (k, v) in pairs {
                let cls = if is_numeric(v) { " class=\"num\"" } else { "" };
                let _ = writeln!(
                    out,
                    "<tr><th scope=\"row\">{}</th><td{cls}>{}</td></tr>",
                    escape(k),
                    escape(v)
                );
            }
            out.push_str("</tbody>\n</table>\n");
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
