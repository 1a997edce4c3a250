//! The library's error type.
//!
//! Errors split into two kinds that the command line treats differently: input a user can fix
//! (a malformed file, an unknown field, impossible geometry, a missing file), which ends with exit
//! status 2, and everything else (a failed write, a numerical breakdown), which ends with 1.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where in an input a problem sits: the file, the 1-based line and column, and the field.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Location {
    pub file: Option<PathBuf>,
    pub line: Option<usize>,
    pub column: Option<usize>,
    pub field: Option<String>,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts = Vec::new();
        if let Some(file) = &self.file {
            parts.push(file.display().to_string());
        }
        match (self.line, self.column) {
            (Some(l), Some(c)) => parts.push(format!("line {l}, column {c}")),
            (Some(l), None) => parts.push(format!("line {l}")),
            _ => {}
        }
        if let Some(field) = &self.field {
            parts.push(format!("field `{field}`"));
        }
        write!(f, "{}", parts.join(", "))
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Input a user can fix. The message is one sentence or paragraph without the location.
    #[error("{}{message}", if .location == &Location::default() { String::new() } else { format!("{location}: ") })]
    Input { location: Location, message: String },

    /// A file that could not be read or written. The message names the path and says what
    /// went wrong in words (with the system's text after it), and what a user can do.
    #[error("cannot {action} {}: {}", .path.display(), describe_io(.source))]
    Io {
        action: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// A computation that cannot go on (for example a singular system); never bad input.
    #[error("{0}")]
    Numerical(String),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The results of a parallel loop that can fail (collected into a `Vec` in index order), as
/// the items, or the first failing item's error in index order, as a sequential loop reports
/// it. rayon's own `collect::<Result<_>>` keeps whichever error a thread met first, so with two
/// failing items its message could change with the thread count.
pub fn in_order<T, E>(results: Vec<std::result::Result<T, E>>) -> std::result::Result<Vec<T>, E> {
    results.into_iter().collect()
}

impl Error {
    /// Bad input with no location yet; add it with [`Error::in_file`] and [`Error::at_field`].
    pub fn input(message: impl Into<String>) -> Self {
        Error::Input {
            location: Location::default(),
            message: message.into(),
        }
    }

    /// Bad input in a named field.
    pub fn field(field: impl Into<String>, message: impl Into<String>) -> Self {
        Error::input(message).at_field(field)
    }

    /// The message alone, without its location (another error's text when this one is not an
    /// input error): for an error that a caller relocates to a field of its own.
    pub fn message(&self) -> String {
        match self {
            Error::Input { message, .. } => message.clone(),
            other => other.to_string(),
        }
    }

    pub fn in_file(mut self, path: &Path) -> Self {
        if let Error::Input { location, .. } = &mut self
            && location.file.is_none()
        {
            location.file = Some(path.to_path_buf());
        }
        self
    }

    pub fn at_field(mut self, name: impl Into<String>) -> Self {
        if let Error::Input { location, .. } = &mut self
            && location.field.is_none()
        {
            location.field = Some(name.into());
        }
        self
    }

    /// Puts the field of an input error inside `parent` (`tol` → `solver.tol`); an error
    /// without a field gets `parent` as its field.
    pub fn within(mut self, parent: &str) -> Self {
        if let Error::Input { location, .. } = &mut self {
            location.field = Some(match location.field.take() {
                Some(f) if !parent.is_empty() => format!("{parent}.{f}"),
                Some(f) => f,
                None => parent.to_string(),
            });
        }
        self
    }

    pub fn at_line(mut self, line: usize, column: usize) -> Self {
        if let Error::Input { location, .. } = &mut self {
            location.line = Some(line);
            location.column = Some(column);
        }
        self
    }

    /// Appends a sentence to an input error's message (other errors are returned unchanged).
    pub fn with_note(mut self, note: impl AsRef<str>) -> Self {
        if let Error::Input { message, .. } = &mut self {
            let m = message.trim_end_matches('.');
            *message = format!("{m} ({})", note.as_ref());
        }
        self
    }

    pub fn read(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            action: "read",
            path: path.to_path_buf(),
            source,
        }
    }

    pub fn write(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            action: "write",
            path: path.to_path_buf(),
            source,
        }
    }

    /// True for problems the user caused and can fix (exit status 2 at the command line):
    /// bad input, a file that cannot be read, and a write refused for a reason a user can
    /// remove (permissions, a read-only or full filesystem, a file or folder in the way).
    pub fn is_user_error(&self) -> bool {
        match self {
            Error::Input { .. } | Error::Io { action: "read", .. } => true,
            Error::Io { source, .. } => user_fixable(source.kind()),
            Error::Numerical(_) => false,
        }
    }
}

fn user_fixable(kind: std::io::ErrorKind) -> bool {
    use std::io::ErrorKind as K;
    matches!(
        kind,
        K::PermissionDenied
            | K::ReadOnlyFilesystem
            | K::AlreadyExists
            | K::NotADirectory
            | K::IsADirectory
            | K::DirectoryNotEmpty
            | K::StorageFull
            | K::QuotaExceeded
            | K::NotFound
    )
}

/// An I/O error in words a user can act on, followed by the system's own text.
fn describe_io(e: &std::io::Error) -> String {
    use std::io::ErrorKind as K;
    let hint = match e.kind() {
        K::PermissionDenied => {
            "permission denied (check the folder's permissions or choose another path)"
        }
        K::ReadOnlyFilesystem => "the filesystem is read-only (choose another path)",
        K::AlreadyExists => {
            "something is already in the way at this path (remove it or choose another path)"
        }
        K::NotADirectory => {
            "a file is in the way where a folder is needed (remove it or choose another path)"
        }
        K::IsADirectory => {
            "a folder is in the way where a file is needed (remove it or choose another path)"
        }
        K::DirectoryNotEmpty => {
            "a folder that is not empty is in the way (remove it or choose another path)"
        }
        K::StorageFull | K::QuotaExceeded => {
            "no space left (free some space or choose another path)"
        }
        K::NotFound => "no such file or folder",
        _ => return e.to_string(),
    };
    format!("{hint}; {e}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn input_error_names_file_line_and_field() {
        let e = Error::field("ratio", "must be in (0, 1], got 0")
            .in_file(Path::new("fig1.ron"))
            .at_line(4, 12);
        assert_eq!(
            e.to_string(),
            "fig1.ron, line 4, column 12, field `ratio`: must be in (0, 1], got 0"
        );
        assert!(e.is_user_error());
        assert!(!Error::Numerical("x".into()).is_user_error());
    }
}
