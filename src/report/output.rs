//! Staged output directories: a command writes every file into a fresh hidden sibling of its
//! output directory and moves them into place only when the whole run has succeeded, so that a
//! failed or interrupted run leaves nothing half written in the output directory (DESIGN.md,
//! command-line contract: "no partial output left behind").

use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// Distinguishes several staging directories of one process for the same output directory.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// An output directory being written. Files go to [`OutputDir::path`] (inside the staging
/// directory) and appear in the final directory only at [`OutputDir::commit`]; dropping an
/// uncommitted `OutputDir` removes the staging directory and leaves the final one untouched.
#[derive(Debug)]
pub struct OutputDir {
    final_dir: PathBuf,
    staging: PathBuf,
    /// Ancestors of the staging directory that `create` made, deepest first, removed again
    /// (when empty) if the run is abandoned.
    created_parents: Vec<PathBuf>,
    committed: bool,
}

impl OutputDir {
    /// Starts staging output for `final_dir` in a new hidden sibling directory named
    /// `.NAME.spibench-partial-PID-N`. Missing parent directories are created.
    pub fn create(final_dir: &Path) -> Result<OutputDir> {
        // `.` or `run/..` have no name of their own: stage beside the directory they resolve to.
        let resolved = match final_dir.file_name() {
            Some(_) => final_dir.to_path_buf(),
            None => std::fs::canonicalize(final_dir).unwrap_or_else(|_| final_dir.to_path_buf()),
        };
        let name = resolved
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|n| !n.is_empty())
            .ok_or_else(|| {
                Error::input("the output directory needs a name (it cannot be the root `/`)")
                    .in_file(final_dir)
            })?
            .to_string();
        if let Ok(meta) = std::fs::metadata(final_dir)
            && !meta.is_dir()
        {
            return Err(
                Error::input("the output path exists and is not a directory").in_file(final_dir),
            );
        }
        let parent = match resolved.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let created_parents = create_missing(&parent).map_err(|e| Error::write(&parent, e))?;
        let pid = std::process::id();
        loop {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let staging = parent.join(format!(".{name}.spibench-partial-{pid}-{n}"));
            match std::fs::create_dir(&staging) {
                Ok(()) => {
                    return Ok(OutputDir {
                        final_dir: final_dir.to_path_buf(),
                        staging,
                        created_parents,
                        committed: false,
                    });
                }
                // A stale directory from an earlier process with the same id: try the next name.
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => {
                    remove_empty(&created_parents);
                    return Err(Error::write(&staging, e));
                }
            }
        }
    }

    /// The directory that [`OutputDir::commit`] fills.
    pub fn final_dir(&self) -> &Path {
        &self.final_dir
    }

    /// The staging directory files are written to now.
    pub fn staging_dir(&self) -> &Path {
        &self.staging
    }

    /// Where to write `file_name` now: a path inside the staging directory. The name may
    /// contain sub-folders (`"images/a.png"`), which are created here. Only plain components
    /// are kept (a leading `/`, `.` and `..` are dropped), so the path always stays inside the
    /// staging directory. Use [`OutputDir::try_path`] to have such names rejected instead.
    pub fn path(&self, file_name: &str) -> PathBuf {
        let rel: PathBuf = Path::new(file_name)
            .components()
            .filter_map(|c| match c {
                Component::Normal(s) => Some(s),
                _ => None,
            })
            .collect();
        let full = self.staging.join(rel);
        if let Some(dir) = full.parent() {
            // A failure here surfaces as a write error naming the file when the caller writes.
            let _ = std::fs::create_dir_all(dir);
        }
        full
    }

    /// Like [`OutputDir::path`], but a name that is empty, absolute or contains `.`/`..` is an
    /// input error, and failing to create its sub-folders is a write error.
    pub fn try_path(&self, file_name: &str) -> Result<PathBuf> {
        let p = Path::new(file_name);
        let plain =
            !file_name.is_empty() && p.components().all(|c| matches!(c, Component::Normal(_)));
        if !plain {
            return Err(Error::input(format!(
                "output file name {file_name:?} must be a relative path of plain names"
            ))
            .in_file(&self.final_dir));
        }
        let full = self.staging.join(p);
        if let Some(dir) = full.parent() {
            std::fs::create_dir_all(dir).map_err(|e| Error::write(dir, e))?;
        }
        Ok(full)
    }

    /// Moves every staged file into the final directory and removes the staging directory.
    /// The final directory is created if needed (then the staging directory is simply renamed,
    /// in one step); in an existing one, same-named files are replaced and other files are left
    /// alone. Returns the final directory.
    pub fn commit(mut self) -> Result<PathBuf> {
        self.committed = true;
        let result = self.move_into_place();
        if result.is_err() {
            // Leave no staging directory behind; whatever was moved stays moved.
            let _ = std::fs::remove_dir_all(&self.staging);
        }
        result.map(|()| self.final_dir.clone())
    }

    fn move_into_place(&self) -> Result<()> {
        match std::fs::symlink_metadata(&self.final_dir) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // Nothing to merge with: the whole tree appears at once.
                return std::fs::rename(&self.staging, &self.final_dir)
                    .map_err(|e| Error::write(&self.final_dir, e));
            }
            Err(e) => return Err(Error::write(&self.final_dir, e)),
            Ok(_) => {}
        }
        merge(&self.staging, &self.final_dir)?;
        std::fs::remove_dir_all(&self.staging).map_err(|e| Error::write(&self.staging, e))
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
            remove_empty(&self.created_parents);
        }
    }
}

/// Moves the entries of `from` into `to` (an existing directory), recursing into directories
/// that exist on both sides and replacing files.
fn merge(from: &Path, to: &Path) -> Result<()> {
    let entries = std::fs::read_dir(from).map_err(|e| Error::write(from, e))?;
    let mut names: Vec<_> = entries
        .map(|e| e.map(|e| e.file_name()))
        .collect::<std::io::Result<_>>()
        .map_err(|e| Error::write(from, e))?;
    names.sort();
    for name in names {
        let src = from.join(&name);
        let dst = to.join(&name);
        let src_is_dir = std::fs::symlink_metadata(&src)
            .map_err(|e| Error::write(&src, e))?
            .is_dir();
        let dst_meta = std::fs::symlink_metadata(&dst).ok();
        match (src_is_dir, dst_meta) {
            (true, Some(m)) if m.is_dir() => merge(&src, &dst)?,
            (_, Some(m)) if m.is_dir() => {
                return Err(Error::write(
                    &dst,
                    std::io::Error::other("a directory is in the way of an output file"),
                ));
            }
            // A file, or a directory with nothing in the way: rename replaces a file atomically.
            _ => std::fs::rename(&src, &dst).map_err(|e| Error::write(&dst, e))?,
        }
    }
    Ok(())
}

/// Creates `dir` and its missing ancestors; returns the ones it created, deepest first.
fn create_missing(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut missing = Vec::new();
    let mut cur = Some(dir);
    while let Some(d) = cur {
        if d.as_os_str().is_empty() || d.exists() {
            break;
        }
        missing.push(d.to_path_buf());
        cur = d.parent();
    }
    std::fs::create_dir_all(dir)?;
    Ok(missing)
}

/// Removes directories that are empty, deepest first; non-empty ones stay.
fn remove_empty(dirs: &[PathBuf]) {
    for d in dirs {
        let _ = std::fs::remove_dir(d);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "spibench-output-test-{}-{name}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn files_appear_only_after_commit() {
        let root = scratch("commit");
        let fin = root.join("run");
        let out = OutputDir::create(&fin).unwrap();
        let staging = out.staging_dir().to_path_buf();
        assert!(staging.is_dir());
        let name = staging.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with(".run.spibench-partial-"), "{name}");
        std::fs::write(out.path("summary.json"), b"{}").unwrap();
        std::fs::write(out.path("images/a.png"), b"png").unwrap();
        assert!(!fin.exists(), "nothing may appear before commit");
        let done = out.commit().unwrap();
        assert_eq!(done, fin);
        assert_eq!(std::fs::read(fin.join("summary.json")).unwrap(), b"{}");
        assert_eq!(std::fs::read(fin.join("images/a.png")).unwrap(), b"png");
        assert!(!staging.exists());
        assert_eq!(entries(&root), vec!["run".to_string()]);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn drop_without_commit_leaves_nothing() {
        let root = scratch("drop");
        let fin = root.join("deeper/run");
        {
            let out = OutputDir::create(&fin).unwrap();
            std::fs::write(out.path("images/b.png"), b"half").unwrap();
            assert!(out.staging_dir().exists());
        }
        assert!(!fin.exists());
        // The missing parent made for the staging directory is removed again, too.
        assert!(entries(&root).is_empty(), "{:?}", entries(&root));

        // An existing final directory is left exactly as it was.
        let fin = root.join("existing");
        std::fs::create_dir_all(&fin).unwrap();
        std::fs::write(fin.join("old.txt"), b"old").unwrap();
        let staging;
        {
            let out = OutputDir::create(&fin).unwrap();
            staging = out.staging_dir().to_path_buf();
            std::fs::write(out.path("old.txt"), b"new").unwrap();
        }
        assert!(!staging.exists());
        assert_eq!(entries(&fin), vec!["old.txt".to_string()]);
        assert_eq!(std::fs::read(fin.join("old.txt")).unwrap(), b"old");
        assert_eq!(entries(&root), vec!["existing".to_string()]);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn commit_into_existing_dir_keeps_unrelated_files() {
        let root = scratch("merge");
        let fin = root.join("run");
        std::fs::create_dir_all(fin.join("images")).unwrap();
        std::fs::write(fin.join("notes.txt"), b"keep me").unwrap();
        std::fs::write(fin.join("summary.json"), b"old").unwrap();
        std::fs::write(fin.join("images/old.png"), b"old png").unwrap();
        let out = OutputDir::create(&fin).unwrap();
        std::fs::write(out.path("summary.json"), b"new").unwrap();
        std::fs::write(out.path("images/new.png"), b"new png").unwrap();
        std::fs::write(out.path("plots/p.svg"), b"<svg/>").unwrap();
        out.commit().unwrap();
        assert_eq!(std::fs::read(fin.join("notes.txt")).unwrap(), b"keep me");
        assert_eq!(std::fs::read(fin.join("summary.json")).unwrap(), b"new");
        assert_eq!(
            std::fs::read(fin.join("images/old.png")).unwrap(),
            b"old png"
        );
        assert_eq!(
            std::fs::read(fin.join("images/new.png")).unwrap(),
            b"new png"
        );
        assert_eq!(std::fs::read(fin.join("plots/p.svg")).unwrap(), b"<svg/>");
        assert_eq!(entries(&root), vec!["run".to_string()]);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn names_stay_inside_the_staging_dir() {
        let root = scratch("names");
        let out = OutputDir::create(&root.join("run")).unwrap();
        let p = out.path("../../escape.txt");
        assert!(p.starts_with(out.staging_dir()), "{}", p.display());
        let p = out.path("/abs/x.txt");
        assert!(p.starts_with(out.staging_dir()), "{}", p.display());
        assert!(out.try_path("../x").unwrap_err().is_user_error());
        assert!(out.try_path("/x").is_err());
        assert!(out.try_path("").is_err());
        assert!(out.try_path("a/b.txt").unwrap().parent().unwrap().is_dir());
        // Two stagings for the same directory in one process do not collide.
        let other = OutputDir::create(&root.join("run")).unwrap();
        assert_ne!(other.staging_dir(), out.staging_dir());
        drop((out, other));
        assert!(entries(&root).is_empty(), "{:?}", entries(&root));
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn a_file_in_the_way_is_an_input_error() {
        let root = scratch("file");
        let fin = root.join("run");
        std::fs::write(&fin, b"i am a file").unwrap();
        let e = OutputDir::create(&fin).unwrap_err();
        assert!(e.is_user_error());
        assert!(e.to_string().contains("run"), "{e}");
        assert!(OutputDir::create(Path::new("/")).is_err());
        // A directory given as `dir/.` stages beside `dir` and commits into it.
        let dotted = root.join("dotted");
        std::fs::create_dir_all(&dotted).unwrap();
        let out = OutputDir::create(&dotted.join(".")).unwrap();
        assert_eq!(
            out.staging_dir().parent().unwrap(),
            root.canonicalize().unwrap()
        );
        std::fs::write(out.path("x.txt"), b"x").unwrap();
        out.commit().unwrap();
        assert_eq!(std::fs::read(dotted.join("x.txt")).unwrap(), b"x");
        let _ = std::fs::remove_dir_all(&root);
    }
}
