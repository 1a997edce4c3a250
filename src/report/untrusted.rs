//! Names and paths read back from files that this process did not write: a dataset's
//! `manifest.json`, a tolerance shard's `trials.ron`, a trace-cache folder. Such a file may have
//! been edited by hand, by another tool or by someone else on a shared filesystem, so what it
//! names is checked before anything it names is opened:
//!
//! - a name ([`PlainName`]) is one plain path component: not empty, not `.` or `..`, without a
//!   separator (`/`, `\`, `:`) or a NUL, so it can neither be absolute nor climb out;
//! - a path inside a folder ([`Folder::inside`]) must not lead out of the folder through a
//!   symbolic link (its real path, links resolved, lies inside the folder's real path).
//!
//! Anything else is an input error (exit 2) naming the file and the field. What a user names
//! on the command line or in a spec is trusted; everything read back is checked (README,
//! "What spibench trusts").

use std::path::{Component, Path, PathBuf};

use crate::error::{Error, Result};

/// An input error about `field` of the record `file`.
pub fn bad_field(file: &Path, field: &str, message: impl Into<String>) -> Error {
    Error::input(message).in_file(file).at_field(field)
}

/// One plain path component, read from a file this process did not write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlainName(String);

impl PlainName {
    /// Checks `name`, the value of `field` in the record `file`.
    pub fn parse(name: &str, file: &Path, field: &str) -> Result<PlainName> {
        let why = if name.is_empty() {
            Some("is empty")
        } else if name == "." || name == ".." {
            Some("names a folder above or at the record's own folder")
        } else if name.contains(['/', '\\', ':']) {
            Some("holds a path separator (it must be a plain name inside the folder)")
        } else if name.contains('\0') {
            Some("holds a NUL character")
        } else if name.len() > 255 {
            Some("is longer than a file name may be (255 bytes)")
        } else {
            None
        };
        match why {
            Some(w) => Err(bad_field(
                file,
                field,
                format!(
                    "the name {name:?} {w}; spibench reads only files inside the folders it \
                     is given, so a name read back from a file must be a plain name"
                ),
            )),
            None => Ok(PlainName(name.to_string())),
        }
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl AsRef<Path> for PlainName {
    fn as_ref(&self) -> &Path {
        Path::new(&self.0)
    }
}

/// True for a SHA-256 written as 64 lowercase hexadecimal digits.
pub fn is_sha256_hex(s: &str) -> bool {
    s.len() == 64
        && s.bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

/// A folder named on the command line (trusted), whose contents are read back.
#[derive(Debug, Clone)]
pub struct Folder {
    /// As the user named it (for messages and for opening).
    given: PathBuf,
    /// Its real path, symbolic links resolved.
    real: PathBuf,
}

impl Folder {
    /// The folder `dir`, which must exist and be a folder.
    pub fn new(dir: &Path) -> Result<Folder> {
        let real = std::fs::canonicalize(dir).map_err(|e| Error::read(dir, e))?;
        if !real.is_dir() {
            return Err(Error::input("not a folder").in_file(dir));
        }
        Ok(Folder {
            given: dir.to_path_buf(),
            real,
        })
    }

    pub fn path(&self) -> &Path {
        &self.given
    }

    /// The real path of the folder.
    pub fn real(&self) -> &Path {
        &self.real
    }

    /// `rel` (plain components, checked by the caller) below this folder, named by `field`
    /// of the record `file`: what exists there must lie inside the folder once symbolic links
    /// are resolved. Nothing is opened (the path is only looked up); a missing path is returned
    /// as it is, for the read that follows to report.
    pub fn inside(&self, rel: &Path, file: &Path, field: &str) -> Result<PathBuf> {
        if !rel.components().all(|c| matches!(c, Component::Normal(_))) {
            return Err(bad_field(
                file,
                field,
                format!(
                    "{} is not a path of plain names inside the folder",
                    rel.display()
                ),
            ));
        }
        let full = self.real.join(rel);
        let out_of = |to: &Path| {
            bad_field(
                file,
                field,
                format!(
                    "{} leads out of the folder {} through a symbolic link (to {}); spibench \
                     reads only files inside the folders it is given",
                    rel.display(),
                    self.given.display(),
                    to.display()
                ),
            )
        };
        match std::fs::canonicalize(&full) {
            Ok(real) if real.starts_with(&self.real) => Ok(self.given.join(rel)),
            Ok(real) => Err(out_of(&real)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // Missing, or a link that dangles: a dangling link is refused too, since what
                // it would lead to cannot be checked.
                let mut p = self.real.clone();
                for c in rel.components() {
                    p.push(c);
                    if let Ok(m) = std::fs::symlink_metadata(&p)
                        && m.file_type().is_symlink()
                    {
                        let to = std::fs::read_link(&p).unwrap_or_default();
                        return Err(out_of(&to));
                    }
                }
                Ok(self.given.join(rel))
            }
            Err(e) => Err(Error::read(&full, e)),
        }
    }

    /// Reads the file `rel` below this folder after [`Folder::inside`] has checked it.
    pub fn read(&self, rel: &Path, file: &Path, field: &str) -> Result<(PathBuf, Vec<u8>)> {
        let p = self.inside(rel, file, field)?;
        let bytes = std::fs::read(&p).map_err(|e| Error::read(&p, e))?;
        Ok((p, bytes))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "spibench-untrusted-test-{}-{name}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn plain_names_only() {
        let f = Path::new("manifest.json");
        for ok in [
            "object",
            "meas_double_arm_r0.0500",
            "shard_000001",
            ".hidden",
        ] {
            assert_eq!(PlainName::parse(ok, f, "x").unwrap().as_str(), ok);
        }
        for bad in [
            "",
            ".",
            "..",
            "../outside/evil",
            "/etc",
            "a/b",
            "a\\b",
            "C:evil",
            "nul\0",
        ] {
            let e = PlainName::parse(bad, f, "shards[1].dir").unwrap_err();
            assert!(e.is_user_error());
            let s = e.to_string();
            assert!(
                s.contains("manifest.json") && s.contains("shards[1].dir"),
                "{s}"
            );
        }
        assert!(PlainName::parse(&"x".repeat(256), f, "x").is_err());
        assert!(is_sha256_hex(&"0a".repeat(32)));
        assert!(!is_sha256_hex(&"0A".repeat(32)) && !is_sha256_hex("abc"));
    }

    #[cfg(unix)]
    #[test]
    fn links_out_of_the_folder_are_refused() {
        let root = scratch("links");
        let dir = root.join("data");
        let outside = root.join("outside");
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::create_dir_all(&outside).unwrap();
        std::fs::write(outside.join("secret.npy"), b"decoy").unwrap();
        std::fs::write(dir.join("sub/a.npy"), b"a").unwrap();
        std::os::unix::fs::symlink(&outside, dir.join("out_link")).unwrap();
        std::os::unix::fs::symlink(dir.join("sub"), dir.join("in_link")).unwrap();
        std::os::unix::fs::symlink(root.join("nowhere"), dir.join("dangling")).unwrap();
        let folder = Folder::new(&dir).unwrap();
        let rec = dir.join("manifest.json");
        assert_eq!(
            folder.inside(Path::new("sub/a.npy"), &rec, "f").unwrap(),
            dir.join("sub/a.npy")
        );
        // A link that stays inside is followed; a missing file is left to the read.
        assert!(folder.inside(Path::new("in_link/a.npy"), &rec, "f").is_ok());
        assert!(folder.inside(Path::new("sub/missing"), &rec, "f").is_ok());
        for bad in ["out_link/secret.npy", "out_link", "dangling", "dangling/x"] {
            let e = folder
                .inside(Path::new(bad), &rec, "shards[0].dir")
                .unwrap_err();
            assert!(e.is_user_error());
            let s = e.to_string();
            assert!(
                s.contains("symbolic link") && s.contains("shards[0].dir"),
                "{s}"
            );
        }
        for bad in ["../outside/secret.npy", "/etc/passwd"] {
            assert!(folder.inside(Path::new(bad), &rec, "f").is_err(), "{bad}");
        }
        let _ = std::fs::remove_dir_all(&root);
    }
}
