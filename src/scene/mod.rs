//! Input files: the only module that knows RON and serde.
//!
//! Scene and experiment files carry their units in field names (`focal_length_mm`,
//! `wavelength_nm`); this module validates them and converts to SI once, so that everything
//! downstream holds valid, SI-valued data. Every error names the file, the line and column, and
//! the field; [`locate`] finds
//! where a field is written, [`numbers`] holds the checked number types.

pub mod bench;
pub mod budget_costs;
pub mod dataset;
pub mod doc;
pub mod experiment;
pub mod locate;
pub mod numbers;
pub mod run;
pub mod tolerance;
pub mod variables;

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{Error, Result};

pub(crate) use locate::line_col;
pub use locate::{field_before, find_path, path_at};
use locate::{last_key_before, offset_of};

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

    /// Every number of every input file is read through a checked type: a field of a
    /// `Deserialize` type in `scene` (or of the solver options, the additive noise and the objects
    /// below it) may not hold a bare `f64` or integer unless it is read
    /// `via` a checked type (`deserialize_with = "via::<…>"`), is a seed (any value is valid), or
    /// its whole type is built by `try_from` a checked form. The records spibench writes for its
    /// own merges (tolerance shards) hold results, not input, and are listed here by name.
    #[test]
    fn input_files_hold_no_bare_numbers() {
        const RECORDS: [&str; 4] = [
            "ShardFile",
            "TrialRecord",
            "SensitivityRecord",
            "NeededTravel",
        ];
        const BARE: [&str; 14] = [
            "f32", "f64", "u8", "u16", "u32", "u64", "u128", "usize", "i8", "i16", "i32", "i64",
            "i128", "isize",
        ];
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        // The input types below `scene` that the files hold: the TVAL3 options, the additive
        // noise and the objects (with their USAF regions).
        let mut files: Vec<std::path::PathBuf> = [
            "reconstruction/tval3/options.rs",
            "acquisition/noise.rs",
            "objects/mod.rs",
        ]
        .iter()
        .map(|f| src.join(f))
        .collect();
        let mut dirs = vec![src.join("scene")];
        while let Some(d) = dirs.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    dirs.push(p);
                } else if p.extension().is_some_and(|x| x == "rs") {
                    files.push(p);
                }
            }
        }
        files.sort();
        let mut bad = Vec::new();
        let mut scanned = 0;
        for f in &files {
            let text = std::fs::read_to_string(f).unwrap();
            // Unit tests below `#[cfg(test)]` declare types of their own.
            let lines: Vec<&str> = text
                .lines()
                .take_while(|l| l.trim() != "#[cfg(test)]")
                .collect();
            let mut i = 0;
            while i < lines.len() {
                let l = lines[i].trim();
                if !(l.starts_with("#[derive(") && l.contains("Deserialize")) {
                    i += 1;
                    continue;
                }
                // The item's attributes, then its head line.
                let mut whole_checked = false;
                i += 1;
                while i < lines.len()
                    && !lines[i].contains("struct ")
                    && !lines[i].contains("enum ")
                {
                    whole_checked |= lines[i].contains("try_from");
                    i += 1;
                }
                let Some(head) = lines.get(i) else { break };
                let name = head
                    .split_whitespace()
                    .skip_while(|w| *w != "struct" && *w != "enum")
                    .nth(1)
                    .unwrap_or("")
                    .trim_end_matches(['{', '(', ';'])
                    .split('<')
                    .next()
                    .unwrap_or("")
                    .to_string();
                if whole_checked || RECORDS.contains(&name.as_str()) || !head.contains('{') {
                    i += 1;
                    continue;
                }
                scanned += 1;
                // The body: up to the brace that closes the head's.
                let mut depth = 0i32;
                let mut attrs = String::new();
                loop {
                    let line = lines[i];
                    let code = line.split("//").next().unwrap_or("");
                    let body_line = depth > 0 || !code.contains('{');
                    let t = code.trim();
                    // Depth 1: a struct's fields or an enum's variants; depth 2: the fields of
                    // a struct variant (`Usaf { min_group: … }`).
                    if body_line && (depth == 1 || depth == 2) {
                        if t.starts_with("#[") || (!attrs.is_empty() && !attrs.ends_with(']')) {
                            attrs.push_str(t);
                        } else if !t.is_empty() {
                            // A field `name: Type,` or a tuple variant `Name(Type, …),`.
                            let (field, ty) = match t.split_once(':') {
                                Some((n, ty)) if !n.contains('(') => (n.trim(), ty),
                                _ => (t.split('(').next().unwrap_or(t), t),
                            };
                            // Const-generic bounds (`{ MAX as u64 }`) are not field types.
                            let mut ty_clean = String::new();
                            let mut braces = 0;
                            for c in ty.chars() {
                                match c {
                                    '{' => braces += 1,
                                    '}' => braces -= 1,
                                    _ if braces == 0 => ty_clean.push(c),
                                    _ => {}
                                }
                            }
                            let holds_bare = ty_clean
                                .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                                .any(|w| BARE.contains(&w));
                            // `Variant { name: Type }` on one line: the field is the last word.
                            let field = field.rsplit(['{', ' ']).next().unwrap_or(field).trim();
                            let ok = !holds_bare
                                || attrs.contains("deserialize_with = \"via::<")
                                || field == "seed";
                            if !ok {
                                let rel = f.strip_prefix(env!("CARGO_MANIFEST_DIR")).unwrap();
                                bad.push(format!(
                                    "{}:{}: `{name}.{field}` holds a bare number ({})",
                                    rel.display(),
                                    i + 1,
                                    ty.trim()
                                ));
                            }
                            attrs.clear();
                        }
                    }
                    depth += code.matches('{').count() as i32 - code.matches('}').count() as i32;
                    i += 1;
                    if depth <= 0 || i >= lines.len() {
                        break;
                    }
                }
            }
        }
        assert!(
            scanned > 30,
            "only {scanned} input types found: is the scan broken?"
        );
        assert!(
            bad.is_empty(),
            "read these through a checked type of crate::checked or scene::numbers (or `via` \
             one):\n{}",
            bad.join("\n")
        );
    }

    #[test]
    fn missing_file_is_a_read_error() {
        let e = read_ron::<Lens>(Path::new("/nonexistent/x.ron")).unwrap_err();
        assert!(e.is_user_error());
        assert!(e.to_string().contains("/nonexistent/x.ron"));
    }
}
