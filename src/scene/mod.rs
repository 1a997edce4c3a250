//! Input files: the only module that knows RON and serde.
//!
//! Scene and experiment files carry their units in field names (`focal_length_mm`,
//! `wavelength_nm`); this module validates them and converts to SI once, so that everything
//! downstream holds valid, SI-valued data. Every error names the file, the line and column, and
//! the field.

pub mod bench;
pub mod dataset;
pub mod doc;
pub mod experiment;
pub mod run;
pub mod tolerance;
pub mod variables;

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{Error, Result};

/// Parses RON text into `T`, mapping every parse or validation error to an [`Error::Input`]
/// that names `path`, the line and column, and the field.
///
/// Files may write `Option` fields without `Some(..)` (the `implicit_some` extension is on).
pub fn parse_ron<T: DeserializeOwned>(text: &str, path: &Path) -> Result<T> {
    let options =
        ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    options.from_str::<T>(text).map_err(|e| {
        let err = ron_error(text, path, e);
        match other_kind_of_file::<T>(text) {
            Some(hint) => Error::input(hint).in_file(path),
            None => err,
        }
    })
}

/// When a file of another kind is given where `T` is expected (an experiment where a bench
/// belongs), the sentence that says so; the parser alone would only report a type mismatch.
fn other_kind_of_file<T>(text: &str) -> Option<String> {
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with("//") && !l.starts_with("#!"))?;
    let name: String = first
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    let wanted = std::any::type_name::<T>();
    let (kind, command) = match name.as_str() {
        "Experiment" => ("an experiment file", "spibench simulate"),
        "Dataset" => ("a dataset spec", "spibench dataset"),
        _ => return None,
    };
    // The file is what `T` is: the error is elsewhere.
    let own = wanted.ends_with(&format!("::{name}File")) || wanted.ends_with(&format!("::{name}"));
    (!own).then(|| {
        let expected = if wanted.contains("BenchFile") {
            "a bench file (the top level is `(lamp: …, elements: […], …)`)"
        } else {
            "another kind of file"
        };
        format!("this is {kind}, which `{command}` reads, but this command expects {expected}")
    })
}

/// Reads and parses a RON file.
pub fn read_ron<T: DeserializeOwned>(path: &Path) -> Result<T> {
    parse_ron(&read_text(path)?, path)
}

/// The largest input text file spibench reads (bench, experiment and settings files are a few
/// kilobytes; a larger one is a wrong path, such as a device or a data file).
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// Reads a UTF-8 input file of at most [`MAX_TEXT_BYTES`], without reading past the limit (so
/// that `/dev/zero` or a huge file fails at once).
pub fn read_text(path: &Path) -> Result<String> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| Error::read(path, e))?;
    let mut bytes = Vec::new();
    file.take(MAX_TEXT_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::read(path, e))?;
    if bytes.len() as u64 > MAX_TEXT_BYTES {
        return Err(Error::input(format!(
            "the file is larger than {} MiB: not a spibench input file",
            MAX_TEXT_BYTES >> 20
        ))
        .in_file(path));
    }
    String::from_utf8(bytes).map_err(|_| Error::input("the file is not UTF-8 text").in_file(path))
}

fn ron_error(text: &str, path: &Path, e: ron::error::SpannedError) -> Error {
    use ron::Error as R;
    let (line, col) = (e.span.start.line, e.span.start.col);
    let offset = offset_of(text, line, col);
    let enclosing = path_at(text, offset);
    let mut message = match &e.code {
        R::Message(m) => m.clone(),
        other => {
            let mut m = other.to_string();
            if let Some(first) = m.get(..1) {
                m = first.to_lowercase() + &m[1..];
            }
            m
        }
    };
    // A value checked while parsing (a `try_from` type) may name its own field inside the
    // value just read: "field `k_plus`: must be …". That field, within the enclosing one, is
    // the one to report, at its own line (the last `k_plus:` before the error).
    let inner = message
        .strip_prefix("field `")
        .and_then(|m| m.split_once("`: "))
        .map(|(f, rest)| (f.to_string(), rest.to_string()));
    let mut at = (line, col);
    let field = match (&e.code, inner) {
        (R::NoSuchStructField { found, .. }, _) => Some(join_path(enclosing.as_deref(), found)),
        (R::MissingStructField { field, .. } | R::DuplicateStructField { field, .. }, _) => {
            Some(join_path(enclosing.as_deref(), field))
        }
        (_, Some((f, rest))) => {
            message = rest;
            match last_key_before(text, &f, offset) {
                Some(p) => {
                    at = line_col(text, p);
                    path_at(text, p + f.len() + 1).or(Some(f))
                }
                None => Some(join_path(enclosing.as_deref(), &f)),
            }
        }
        _ => enclosing.or_else(|| field_before(text, line, col)),
    };
    let mut err = Error::input(message).in_file(path).at_line(at.0, at.1);
    if let Some(f) = field {
        err = err.at_field(f);
    }
    err
}

fn join_path(base: Option<&str>, field: &str) -> String {
    match base {
        Some(b) if !b.is_empty() && !b.ends_with(field) => format!("{b}.{field}"),
        Some(b) if !b.is_empty() => b.to_string(),
        _ => field.to_string(),
    }
}

/// Byte offset of a 1-based line and column.
fn offset_of(text: &str, line: usize, col: usize) -> usize {
    let mut offset = 0;
    for (i, l) in text.split_inclusive('\n').enumerate() {
        if i + 1 == line {
            return offset
                + l.char_indices()
                    .nth(col.saturating_sub(1))
                    .map_or(l.len(), |(b, _)| b);
        }
        offset += l.len();
    }
    text.len()
}

/// 1-based line and column of a byte offset.
pub(crate) fn line_col(text: &str, pos: usize) -> (usize, usize) {
    let mut pos = pos.min(text.len());
    while !text.is_char_boundary(pos) {
        pos -= 1;
    }
    let before = &text[..pos];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Offset of the last `key:` (as a whole word, outside comments and strings) before `pos`.
fn last_key_before(text: &str, key: &str, pos: usize) -> Option<usize> {
    keys(text)
        .into_iter()
        .filter(|&(p, k)| k == key && p < pos)
        .map(|(p, _)| p)
        .next_back()
}

/// Every `identifier:` of the text outside comments and strings: (offset, identifier).
fn keys(text: &str) -> Vec<(usize, &str)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if let Some(next) = bench::skip_trivia(b, i) {
            i = next;
            continue;
        }
        if b[i].is_ascii_alphabetic() || b[i] == b'_' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            let mut j = i;
            while j < b.len() && b[j].is_ascii_whitespace() {
                j += 1;
            }
            if j < b.len() && b[j] == b':' && b.get(j + 1) != Some(&b':') {
                out.push((start, &text[start..i]));
            }
            continue;
        }
        i += 1;
    }
    out
}

/// The full path (`cases[1].arms.b_minus`) of the field whose value holds byte offset `pos`:
/// struct fields joined by `.`, list items by their index. None outside every field.
pub fn path_at(text: &str, pos: usize) -> Option<String> {
    enum Frame {
        Struct(Option<String>),
        List(usize),
    }
    let b = text.as_bytes();
    let end = pos.min(b.len());
    let mut stack: Vec<Frame> = Vec::new();
    let mut i = 0;
    while i < end {
        if let Some(next) = bench::skip_trivia(b, i) {
            i = next;
            continue;
        }
        match b[i] {
            b'(' | b'{' => stack.push(Frame::Struct(None)),
            b'[' => stack.push(Frame::List(0)),
            b')' | b']' | b'}' => {
                stack.pop();
            }
            b',' => match stack.last_mut() {
                Some(Frame::List(n)) => *n += 1,
                Some(Frame::Struct(f)) => *f = None,
                None => {}
            },
            c if c.is_ascii_alphabetic() || c == b'_' => {
                let start = i;
                while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                    i += 1;
                }
                let mut j = i;
                while j < b.len() && b[j].is_ascii_whitespace() {
                    j += 1;
                }
                if j < b.len()
                    && b[j] == b':'
                    && b.get(j + 1) != Some(&b':')
                    && let Some(Frame::Struct(f)) = stack.last_mut()
                {
                    *f = Some(text[start..i].to_string());
                }
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    let mut path = String::new();
    for f in &stack {
        match f {
            Frame::Struct(Some(name)) => {
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(name);
            }
            Frame::Struct(None) => {}
            Frame::List(n) => path.push_str(&format!("[{n}]")),
        }
    }
    (!path.is_empty()).then_some(path)
}

/// Offset of the field at a full path (`cases[1].label`, as [`path_at`] writes it): the
/// first `key:` whose path is that one. None when the field is not written in the text.
pub fn find_path(text: &str, path: &str) -> Option<usize> {
    let last = path.rsplit('.').next().unwrap_or(path);
    let last = last.split('[').next().unwrap_or(last);
    keys(text)
        .into_iter()
        .filter(|&(_, k)| k == last)
        .map(|(p, k)| (p, p + k.len() + 1))
        .find(|&(_, after)| {
            path_at(text, after + 1).is_some_and(|found| {
                found == path || found.strip_prefix(path).is_some_and(|r| r.starts_with('['))
            })
        })
        .map(|(p, _)| p)
}

/// The name of the field whose value contains the position (1-based line and column): the last
/// `identifier:` at or before it. Used to name the field of a value that failed validation.
pub fn field_before(text: &str, line: usize, col: usize) -> Option<String> {
    let mut offset = 0;
    for (i, l) in text.split_inclusive('\n').enumerate() {
        if i + 1 == line {
            offset += l
                .char_indices()
                .nth(col.saturating_sub(1))
                .map_or(l.len(), |(b, _)| b);
            break;
        }
        offset += l.len();
    }
    let before = &text[..offset.min(text.len())];
    let bytes = before.as_bytes();
    let mut i = bytes.len();
    while i > 0 {
        i -= 1;
        if bytes[i] == b':'
            && !(i + 1 < bytes.len() && bytes[i + 1] == b':')
            && !(i > 0 && bytes[i - 1] == b':')
        {
            let mut j = i;
            while j > 0 && bytes[j - 1] == b' ' {
                j -= 1;
            }
            let end = j;
            while j > 0 && (bytes[j - 1].is_ascii_alphanumeric() || bytes[j - 1] == b'_') {
                j -= 1;
            }
            if j < end {
                return Some(before[j..end].to_string());
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Lens {
        focal_length_mm: f64,
        diameter_mm: f64,
    }

    /// An experiment or dataset file where a bench is expected says what it is.
    #[test]
    fn a_file_of_another_kind_is_named() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        for (f, words) in [
            (
                "fig1.ron",
                "experiment file, which `spibench simulate` reads",
            ),
            (
                "dataset_example.ron",
                "dataset spec, which `spibench dataset` reads",
            ),
        ] {
            let p = root.join(f);
            let e = crate::scene::bench::read_bench(&p).unwrap_err();
            let m = e.to_string();
            assert!(e.is_user_error() && m.contains(words), "{m}");
            assert!(m.contains(f), "{m}");
        }
        // A bench still parses, and a broken bench keeps its own message.
        assert!(crate::scene::bench::read_bench(&root.join("paper_bench.ron")).is_ok());
    }

    #[test]
    fn unknown_field_is_named_with_line() {
        let text = "(\n  focal_length_mm: 50.0,\n  diamter_mm: 25.4,\n)\n";
        let e = parse_ron::<Lens>(text, Path::new("lens.ron")).unwrap_err();
        let s = e.to_string();
        assert!(s.starts_with("lens.ron, line 3"), "{s}");
        assert!(s.contains("field `diamter_mm`"), "{s}");
        assert!(e.is_user_error());
    }

    #[test]
    fn type_error_names_enclosing_field() {
        let text = "(\n  focal_length_mm: \"fifty\",\n  diameter_mm: 25.4,\n)\n";
        let s = parse_ron::<Lens>(text, Path::new("l.ron"))
            .unwrap_err()
            .to_string();
        assert!(
            s.contains("line 2") && s.contains("field `focal_length_mm`"),
            "{s}"
        );
    }

    #[test]
    fn paths_name_list_items_and_nested_fields() {
        let text = "Experiment(\n  cases: [\n    (label: \"a\", arms: (k_plus: 1)),\n    (label: \"b\", // x: y\n     arms: (k_plus: 1, b_minus: NaN)),\n  ],\n)\n";
        let pos = text.find("NaN").unwrap();
        assert_eq!(path_at(text, pos).as_deref(), Some("cases[1].arms.b_minus"));
        let at = find_path(text, "cases[1].label").unwrap();
        assert_eq!(line_col(text, at), (4, 6));
        let at = find_path(text, "cases[0].arms.k_plus").unwrap();
        assert_eq!(line_col(text, at).0, 3);
        assert!(find_path(text, "cases[2].label").is_none());
    }

    #[test]
    fn missing_file_is_a_read_error() {
        let e = read_ron::<Lens>(Path::new("/nonexistent/x.ron")).unwrap_err();
        assert!(e.is_user_error());
        assert!(e.to_string().contains("/nonexistent/x.ron"));
    }
}
