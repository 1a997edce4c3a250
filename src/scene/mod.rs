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
    options
        .from_str::<T>(text)
        .map_err(|e| ron_error(text, path, e))
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
    let field = match &e.code {
        R::NoSuchStructField { found, .. } => Some(found.clone()),
        R::MissingStructField { field, .. } | R::DuplicateStructField { field, .. } => {
            Some(field.to_string())
        }
        _ => field_before(text, line, col),
    };
    let message = match &e.code {
        R::Message(m) => m.clone(),
        other => {
            let mut m = other.to_string();
            if let Some(first) = m.get(..1) {
                m = first.to_lowercase() + &m[1..];
            }
            m
        }
    };
    let mut err = Error::input(message).in_file(path).at_line(line, col);
    if let Some(f) = field {
        err = err.at_field(f);
    }
    err
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
    fn missing_file_is_a_read_error() {
        let e = read_ron::<Lens>(Path::new("/nonexistent/x.ron")).unwrap_err();
        assert!(e.is_user_error());
        assert!(e.to_string().contains("/nonexistent/x.ron"));
    }
}
