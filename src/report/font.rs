//! The one font every figure uses, embedded so that plots and montages render text without any
//! system font (plotters' `ab_glyph` backend resolves only registered family names; see
//! docs/rust-notes.md §7). DejaVu Sans ships under the Bitstream Vera licence, which allows embedding;
//! the licence text sits beside the font file.

use std::sync::OnceLock;

use plotters::style::{FontDesc, FontFamily, FontStyle, register_font};

static DEJAVU_SANS: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

/// The family name figures ask for; plotters uses it for captions and axes by default.
pub(crate) const FAMILY: &str = "sans-serif";

static REGISTERED: OnceLock<bool> = OnceLock::new();

/// Registers the embedded font for `"sans-serif"` once per process. Returns false when the font
/// data cannot be parsed, which only a corrupted build could cause.
pub(crate) fn ensure_registered() -> bool {
    *REGISTERED.get_or_init(|| register_font(FAMILY, FontStyle::Normal, DEJAVU_SANS).is_ok())
}

/// An I/O error describing a missing font, for `Error::write(path, ..)`.
pub(crate) fn unavailable() -> std::io::Error {
    std::io::Error::other("the embedded DejaVu Sans font could not be loaded")
}

/// The width in pixels plotters will give `text` at `size` (its size unit, about 1.24 px per
/// point of em height), or an estimate from the character count if measuring fails.
pub(crate) fn text_width(text: &str, size: f64) -> u32 {
    ensure_registered();
    FontDesc::new(FontFamily::Name(FAMILY), size, FontStyle::Normal)
        .box_size(text)
        .map(|(w, _)| w)
        .unwrap_or_else(|_| (text.chars().count() as f64 * size * 0.6).ceil() as u32)
}

/// `text`, shortened with an ellipsis if needed so that it is at most `max_px` wide at `size`.
pub(crate) fn fit_text(text: &str, size: f64, max_px: u32) -> String {
    if text_width(text, size) <= max_px {
        return text.to_string();
    }
    let chars: Vec<char> = text.chars().collect();
    for keep in (0..chars.len()).rev() {
        let candidate: String = chars[..keep]
            .iter()
            .collect::<String>()
            .trim_end()
            .to_string()
            + "…";
        if text_width(&candidate, size) <= max_px {
            return candidate;
        }
    }
    String::new()
}

/// Splits `text` at spaces into at most `max_lines` lines no wider than `max_px` at `size`,
/// greedily; the last line is shortened with an ellipsis if the words do not fit.
pub(crate) fn wrap_text(text: &str, size: f64, max_px: u32, max_lines: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut current = String::new();
    let words: Vec<&str> = text.split_whitespace().collect();
    let mut i = 0;
    while i < words.len() {
        let candidate = if current.is_empty() {
            words[i].to_string()
        } else {
            format!("{current} {}", words[i])
        };
        if text_width(&candidate, size) <= max_px || current.is_empty() {
            current = candidate;
            i += 1;
        } else if lines.len() + 1 >= max_lines {
            // `current` is the last line allowed: the remaining words join it below.
            break;
        } else {
            lines.push(std::mem::take(&mut current));
        }
    }
    if i < words.len() {
        // Out of lines: the rest of the words go on the last line, shortened to fit.
        let rest = words[i..].join(" ");
        current = if current.is_empty() {
            rest
        } else {
            format!("{current} {rest}")
        };
    }
    if !current.is_empty() || lines.is_empty() {
        lines.push(current);
    }
    lines
        .into_iter()
        .take(max_lines.max(1))
        .map(|l| fit_text(&l, size, max_px))
        .collect()
}

/// Greedy line breaking of `pieces` joined by `sep`; None if a piece alone is too wide or more
/// than `max_lines` lines are needed.
fn greedy(
    pieces: &[&str],
    sep: &str,
    size: f64,
    max_px: u32,
    max_lines: usize,
) -> Option<Vec<String>> {
    let mut lines: Vec<String> = Vec::new();
    let mut current = String::new();
    for piece in pieces {
        if text_width(piece, size) > max_px {
            return None;
        }
        let candidate = if current.is_empty() {
            piece.to_string()
        } else {
            format!("{current}{sep}{piece}")
        };
        if text_width(&candidate, size) <= max_px {
            current = candidate;
        } else {
            lines.push(std::mem::replace(&mut current, piece.to_string()));
        }
    }
    lines.push(current);
    (lines.len() <= max_lines).then_some(lines)
}

/// `text` on at most `max_lines` lines no wider than `max_px` at `size`, without shortening
/// anything, or None. Breaks at " / " first (so "PSNR 24.1 dB / MSSIM 0.81" splits between
/// the two scores, dropping the slash), then at spaces.
pub(crate) fn wrap_exact(
    text: &str,
    size: f64,
    max_px: u32,
    max_lines: usize,
) -> Option<Vec<String>> {
    let text = text.trim();
    if text_width(text, size) <= max_px {
        return Some(vec![text.to_string()]);
    }
    if max_lines < 2 {
        return None;
    }
    if text.contains(" / ") {
        let parts: Vec<&str> = text.split(" / ").map(str::trim).collect();
        if let Some(lines) = greedy(&parts, " / ", size, max_px, max_lines) {
            return Some(lines);
        }
    }
    let words: Vec<&str> = text.split_whitespace().collect();
    greedy(&words, " ", size, max_px, max_lines)
}

/// The lines and text size for a label in a box `max_px` wide and `max_lines` lines high: the
/// largest size from `size` down to `min_size` (1-unit steps) at which it fits whole, or
/// `min_size` with the last line shortened by an ellipsis.
pub(crate) fn fit_lines(
    text: &str,
    size: f64,
    min_size: f64,
    max_px: u32,
    max_lines: usize,
) -> (Vec<String>, f64) {
    let mut s = size;
    while s >= min_size {
        if let Some(lines) = wrap_exact(text, s, max_px, max_lines) {
            return (lines, s);
        }
        s -= 1.0;
    }
    (wrap_text(text, min_size, max_px, max_lines), min_size)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measures_wraps_and_shortens() {
        assert!(ensure_registered());
        let w1 = text_width("MSSIM", 20.0);
        let w2 = text_width("MSSIM 0.81", 20.0);
        assert!(w1 > 20 && w2 > w1 && w2 < 200, "{w1} {w2}");
        // Widths scale with the size (to rounding of each glyph advance).
        let w40 = text_width("MSSIM", 40.0);
        assert!((w40 as i64 - 2 * w1 as i64).abs() <= 5, "{w40} vs 2 × {w1}");
        let cap = "PSNR 24.1 dB / MSSIM 0.81";
        let narrow = text_width("PSNR 24.1 dB", 14.0) + 2;
        assert_eq!(
            wrap_exact(cap, 14.0, narrow, 2).unwrap(),
            vec!["PSNR 24.1 dB".to_string(), "MSSIM 0.81".to_string()]
        );
        assert_eq!(
            wrap_exact(cap, 14.0, 10_000, 2).unwrap(),
            vec![cap.to_string()]
        );
        assert!(wrap_exact(cap, 14.0, narrow, 1).is_none());
        let (lines, size) = fit_lines(cap, 14.0, 8.0, narrow, 1);
        assert_eq!(lines.len(), 1);
        assert!(size < 14.0 && text_width(&lines[0], size) <= narrow);
        // Too narrow even at the smallest size: shortened with an ellipsis, within the width.
        let lines = wrap_text("Secondary complementary balancing", 14.0, 60, 2);
        assert_eq!(lines.len(), 2);
        assert!(lines[1].ends_with('…'), "{lines:?}");
        assert!(lines.iter().all(|l| text_width(l, 14.0) <= 60), "{lines:?}");
        assert_eq!(fit_text("abc", 14.0, 1000), "abc");
    }
}
