//! Staged output directories: a command writes every file into a fresh hidden staging directory
//! on the destination's own filesystem and swaps it into place only when the whole run has
//! succeeded, so that a failed or interrupted run leaves nothing half written, and a folder that
//! existed before is either replaced as a whole or left exactly as it was.
//!
//! The contract, in order of the steps of a run:
//!
//! - **Lock.** `create` takes an advisory lock (`flock`) on `.NAME.spibench-lock` beside the
//!   destination `NAME`, so a second run into the same folder fails at once with an input error
//!   (exit 2) instead of silently overwriting the first. The kernel drops the lock when a
//!   process dies, however it dies.
//! - **Sweep.** With the lock held, hidden staging (`.NAME.spibench-partial-PID-N`) and
//!   replaced (`.NAME.spibench-old-PID-N`) folders of processes that no longer run (Linux:
//!   no `/proc/PID`) are removed; a replaced folder whose swap was cut short (the destination
//!   is missing) is put back first.
//! - **Stage.** Files are written into a hidden sibling of the destination, or inside the
//!   destination (`NAME/.spibench-partial-PID-N`) when the destination is a mount point (a
//!   container volume) or its parent is not writable: a rename never crosses filesystems.
//! - **Commit.** A new destination is the staging folder renamed. An existing one is replaced:
//!   `NAME → .NAME.spibench-old-PID-N`, staging → `NAME`, then the old folder is removed; if the
//!   second rename fails the first is undone. When renaming the destination fails because it is
//!   a mount point (`EXDEV`, `EBUSY`), the staged files are moved (copied when they sit on
//!   another device) into the destination and swapped entry by entry, the old entries kept
//!   aside until the new ones are all in place.
//! - **Signals.** SIGINT and SIGTERM (after [`install_signal_cleanup`]) remove every live
//!   staging folder and lock file and end the process with status 130 or 143. A commit in
//!   progress finishes first, so the destination is never left between two states.

use std::collections::BTreeSet;
use std::ffi::OsString;
use std::fs::File;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

use crate::error::{Error, Result};

/// Distinguishes several staging directories of one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Staging folders and lock files of this process that are live now, removed by the signal
/// handler. Commits hold this lock while they swap folders, so a signal never interrupts a swap.
static LIVE: Mutex<Vec<Live>> = Mutex::new(Vec::new());

#[derive(Debug)]
struct Live {
    id: u64,
    /// The staging folders (one for an [`OutputDir`]; a [`FolderLock`]'s shards being written,
    /// none between them).
    staging: Vec<PathBuf>,
    lock_file: PathBuf,
}

fn live() -> MutexGuard<'static, Vec<Live>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Test hook: when this environment variable is set, renaming an existing destination fails
/// with `EXDEV`, as it does when the destination is a mount point, so that the fallback can be
/// tested on machines where no second filesystem can be mounted.
pub const TEST_EXDEV_ENV: &str = "SPIBENCH_TEST_OUTPUT_EXDEV";

/// Installs handlers for SIGINT and SIGTERM that remove every live staging folder and lock file
/// of this process and then exit with status 128 + signal (130, 143). Called once by the command
/// line; a second call does nothing.
pub fn install_signal_cleanup() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        #[cfg(unix)]
        {
            use signal_hook::consts::{SIGINT, SIGTERM};
            // The handler itself only writes to a pipe (signal-hook's iterator); the cleanup runs
            // on an ordinary thread, where removing folders is allowed.
            if let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) {
                std::thread::spawn(move || {
                    if let Some(sig) = signals.forever().next() {
                        // Held until the exit: nothing is staged and created meanwhile
                        // (`FolderLock::stage_created`).
                        let entries = live();
                        for e in entries.iter() {
                            for s in &e.staging {
                                remove_staged(s);
                            }
                            let _ = std::fs::remove_file(&e.lock_file);
                        }
                        std::process::exit(128 + sig);
                    }
                });
            }
        }
    });
}

/// Removes a staged folder or file. Other threads may still be writing files into a staged
/// folder (a dataset's shard), so a removal can meet a file created after it listed the folder
/// and fail; it is tried again until the path is gone (a file cannot be created in a folder
/// that no longer exists), a few hundred milliseconds at most.
#[cfg(unix)]
fn remove_staged(s: &Path) {
    for _ in 0..200 {
        let _ = std::fs::remove_dir_all(s).or_else(|_| std::fs::remove_file(s));
        if std::fs::symlink_metadata(s).is_err() {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

/// Where the staging folder lives relative to the destination.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// A hidden sibling `.NAME.spibench-partial-PID-N`, swapped in by renames.
    Sibling,
    /// Inside the destination (a mount point), swapped in entry by entry.
    Inside,
}

/// An output directory being written. Files go to [`OutputDir::path`] (inside the staging
/// directory) and appear in the final directory only at [`OutputDir::commit`], which replaces
/// the final directory as a whole; dropping an uncommitted `OutputDir` removes the staging
/// directory and leaves the final one untouched.
#[derive(Debug)]
pub struct OutputDir {
    /// The destination as the caller named it (returned by `commit`).
    final_dir: PathBuf,
    /// The destination with a name of its own (`dir/.` resolved), used for renames.
    target: PathBuf,
    staging: PathBuf,
    mode: Mode,
    id: u64,
    /// Ancestors of the destination that `create` made, deepest first, removed again (when
    /// empty) if the run is abandoned.
    created_parents: Vec<PathBuf>,
    lock: Option<DirLock>,
    committed: bool,
}

impl OutputDir {
    /// Locks `final_dir` against other runs, sweeps stale staging folders of dead processes and
    /// starts staging output in a new hidden directory (see the module docs for where). Missing
    /// parent directories are created. A destination locked by another run, a file in the way
    /// or a destination that contains the current directory are input errors.
    pub fn create(final_dir: &Path) -> Result<OutputDir> {
        let Destination {
            target,
            name,
            parent,
            existing,
        } = Destination::of(final_dir)?;
        let created_parents = create_missing(&parent).map_err(|e| Error::write(&parent, e))?;
        let abandon = |e: Error| {
            remove_empty(&created_parents);
            e
        };

        // A destination on another device than its parent is a mount point: it cannot be
        // renamed, so stage inside it.
        let mount_point = existing.is_some() && is_mount_point(&target, &parent);
        let mut mode = if mount_point {
            Mode::Inside
        } else {
            Mode::Sibling
        };
        let lock = match mode {
            Mode::Sibling => {
                match DirLock::acquire(&parent.join(format!(".{name}.spibench-lock")), final_dir) {
                    Ok(l) => l,
                    // A parent we may not write into, around a destination we may: stage inside.
                    Err(e) if existing.is_some() && is_permission(&e) => {
                        mode = Mode::Inside;
                        DirLock::acquire(&target.join(".spibench-lock"), final_dir)
                            .map_err(abandon)?
                    }
                    Err(e) => return Err(abandon(e)),
                }
            }
            Mode::Inside => DirLock::acquire(&target.join(".spibench-lock"), final_dir)?,
        };
        if let Err(e) = sweep_stale(&parent, &name, &target) {
            drop(lock);
            return Err(abandon(e));
        }

        let pid = std::process::id();
        let mut live_entries = live();
        loop {
            let id = COUNTER.fetch_add(1, Ordering::Relaxed);
            let staging = match mode {
                Mode::Sibling => parent.join(format!(".{name}.spibench-partial-{pid}-{id}")),
                Mode::Inside => target.join(format!(".spibench-partial-{pid}-{id}")),
            };
            match std::fs::create_dir(&staging) {
                Ok(()) => {
                    live_entries.push(Live {
                        id,
                        staging: vec![staging.clone()],
                        lock_file: lock.path.clone(),
                    });
                    return Ok(OutputDir {
                        final_dir: final_dir.to_path_buf(),
                        target,
                        staging,
                        mode,
                        id,
                        created_parents,
                        lock: Some(lock),
                        committed: false,
                    });
                }
                // A stale directory from an earlier process with the same id: try the next name.
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => {
                    drop(live_entries);
                    drop(lock);
                    return Err(abandon(Error::write(&staging, e)));
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

    /// Replaces the final directory by the staged one (see the module docs) and releases the
    /// lock. On failure the final directory is as it was before and the staging is removed.
    /// Returns the final directory.
    pub fn commit(self) -> Result<PathBuf> {
        let exdev = std::env::var_os(TEST_EXDEV_ENV).is_some();
        self.finish(exdev)
    }

    /// [`OutputDir::commit`], with renaming an existing destination failing as on a mount
    /// point when `exdev` is set.
    fn finish(mut self, exdev: bool) -> Result<PathBuf> {
        self.committed = true;
        let result = {
            // Hold the registry while swapping so that a signal waits for the swap to finish.
            let mut entries = live();
            let result = self.swap_into_place(exdev);
            let _ = std::fs::remove_dir_all(&self.staging);
            entries.retain(|e| e.id != self.id);
            result
        };
        self.lock.take();
        result.map(|()| self.final_dir.clone())
    }

    fn swap_into_place(&mut self, exdev: bool) -> Result<()> {
        match self.mode {
            Mode::Inside => replace_entries(&self.staging, &self.target),
            Mode::Sibling => {
                match std::fs::symlink_metadata(&self.target) {
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                        // Nothing to replace: the whole tree appears at once.
                        return std::fs::rename(&self.staging, &self.target)
                            .map_err(|e| Error::write(&self.target, e));
                    }
                    Err(e) => return Err(Error::write(&self.target, e)),
                    Ok(_) => {}
                }
                let parent = self.staging.parent().unwrap_or(Path::new("."));
                let name = self
                    .target
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy();
                let old = parent.join(format!(
                    ".{name}.spibench-old-{}-{}",
                    std::process::id(),
                    self.id
                ));
                let moved = if exdev {
                    Err(std::io::Error::from_raw_os_error(EXDEV))
                } else {
                    std::fs::rename(&self.target, &old)
                };
                match moved {
                    Ok(()) => {}
                    Err(e) if is_cross_device(&e) => {
                        // The destination is a mount point after all: bring the staged files
                        // onto its filesystem and swap entry by entry there.
                        let inner = self.target.join(format!(
                            ".spibench-partial-{}-{}",
                            std::process::id(),
                            self.id
                        ));
                        let copied = move_tree(&self.staging, &inner)
                            .and_then(|()| replace_entries(&inner, &self.target));
                        let _ = std::fs::remove_dir_all(&inner);
                        return copied;
                    }
                    Err(e) => return Err(Error::write(&self.target, e)),
                }
                if let Err(e) = std::fs::rename(&self.staging, &self.target) {
                    // Undo the first rename: the old folder comes back unchanged.
                    let _ = std::fs::rename(&old, &self.target);
                    return Err(Error::write(&self.target, e));
                }
                // A failure here leaves a hidden folder that the next run's sweep removes.
                let _ = std::fs::remove_dir_all(&old);
                Ok(())
            }
        }
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.committed {
            let mut entries = live();
            let _ = std::fs::remove_dir_all(&self.staging);
            entries.retain(|e| e.id != self.id);
            drop(entries);
            self.lock.take();
            remove_empty(&self.created_parents);
        }
    }
}

const EXDEV: i32 = 18;
const EBUSY: i32 = 16;

/// True for the errors a rename gives when source and destination are on different mounts, or
/// when the directory renamed is a mount point.
fn is_cross_device(e: &std::io::Error) -> bool {
    e.kind() == std::io::ErrorKind::CrossesDevices
        || e.kind() == std::io::ErrorKind::ResourceBusy
        || matches!(e.raw_os_error(), Some(EXDEV | EBUSY))
}

fn is_permission(e: &Error) -> bool {
    matches!(e, Error::Io { source, .. }
        if matches!(source.kind(), std::io::ErrorKind::PermissionDenied
            | std::io::ErrorKind::ReadOnlyFilesystem))
}

#[cfg(unix)]
fn is_mount_point(dir: &Path, parent: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(dir), std::fs::metadata(parent)) {
        (Ok(a), Ok(b)) => a.dev() != b.dev(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn is_mount_point(_dir: &Path, _parent: &Path) -> bool {
    false
}

/// A destination folder as the locks and staging see it.
struct Destination {
    /// The destination with a name of its own (`dir/.` resolved).
    target: PathBuf,
    name: String,
    parent: PathBuf,
    existing: Option<std::fs::Metadata>,
}

impl Destination {
    /// Resolves `final_dir`; a file in the way, the root or a folder holding the current
    /// directory are input errors.
    fn of(final_dir: &Path) -> Result<Destination> {
        // `.` or `run/..` have no name of their own: resolve them to the directory they name.
        let target = match final_dir.file_name() {
            Some(_) => final_dir.to_path_buf(),
            None => std::fs::canonicalize(final_dir).unwrap_or_else(|_| final_dir.to_path_buf()),
        };
        let name = target
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|n| !n.is_empty())
            .ok_or_else(|| {
                Error::input("the output directory needs a name (it cannot be the root `/`)")
                    .in_file(final_dir)
            })?
            .to_string();
        let existing = std::fs::metadata(&target).ok();
        if let Some(meta) = &existing
            && !meta.is_dir()
        {
            return Err(Error::input(
                "the output path exists and is not a directory: remove the file or choose \
                 another output folder",
            )
            .in_file(final_dir));
        }
        if existing.is_some() {
            refuse_current_dir(&target, final_dir)?;
        }
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        Ok(Destination {
            target,
            name,
            parent,
            existing,
        })
    }
}

/// The lock of an output folder that a command writes in place rather than staged as a whole
/// (a dataset, which is resumable shard by shard): the same lock file as
/// [`OutputDir::create`] takes, so that no two runs of any command write one folder at once.
/// The folder's parents are created; the folder itself is left to the caller. While a piece
/// of the folder is staged ([`FolderLock::stage_created`]), SIGINT and SIGTERM remove that piece
/// and the lock file; dropping the lock removes the lock file.
#[derive(Debug)]
pub struct FolderLock {
    dir: PathBuf,
    id: u64,
    lock: Option<DirLock>,
    /// Ancestors `acquire` made, deepest first, removed again on release when still empty.
    created_parents: Vec<PathBuf>,
}

impl FolderLock {
    /// Locks `dir` against every other spibench run, or reports the run that holds it (an
    /// input error about `dir`).
    pub fn acquire(dir: &Path) -> Result<FolderLock> {
        let d = Destination::of(dir)?;
        let created_parents = create_missing(&d.parent).map_err(|e| Error::write(&d.parent, e))?;
        let sibling = d.parent.join(format!(".{}.spibench-lock", d.name));
        let inside = d.target.join(".spibench-lock");
        // A mount point is locked inside, where `OutputDir::create` locks it.
        let mount_point = d.existing.is_some() && is_mount_point(&d.target, &d.parent);
        let first = if mount_point { &inside } else { &sibling };
        let lock = match DirLock::acquire(first, dir) {
            Ok(l) => Ok(l),
            // A parent we may not write into, around a folder we may: lock inside, as
            // `OutputDir::create` does.
            Err(e) if !mount_point && d.existing.is_some() && is_permission(&e) => {
                DirLock::acquire(&inside, dir)
            }
            Err(e) => Err(e),
        };
        let lock = lock.inspect_err(|_| remove_empty(&created_parents))?;
        let id = COUNTER.fetch_add(1, Ordering::Relaxed);
        live().push(Live {
            id,
            staging: Vec::new(),
            lock_file: lock.path.clone(),
        });
        Ok(FolderLock {
            dir: dir.to_path_buf(),
            id,
            lock: Some(lock),
            created_parents,
        })
    }

    /// The locked folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Creates `path` with `create` (a folder being filled, or a temporary file being written,
    /// to be renamed into place) and marks it as a piece a signal removes; several may be staged
    /// at once. Both happen while holding the registry that a signal's cleanup holds until the
    /// process exits: the cleanup either finds the piece created and staged, and removes it, or
    /// comes first, and then nothing is created after it (marking first and creating after, a
    /// signal between the two left the piece behind).
    pub fn stage_created<T>(
        &self,
        path: &Path,
        create: impl FnOnce(&Path) -> std::io::Result<T>,
    ) -> std::io::Result<T> {
        let mut entries = live();
        let made = create(path)?;
        for e in entries.iter_mut().filter(|e| e.id == self.id) {
            e.staging.push(path.to_path_buf());
        }
        Ok(made)
    }

    /// Unmarks `staging` (renamed into place, or removed).
    pub fn unstage(&self, staging: &Path) {
        for e in live().iter_mut().filter(|e| e.id == self.id) {
            e.staging.retain(|s| s != staging);
        }
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        let mut entries = live();
        entries.retain(|e| e.id != self.id);
        drop(entries);
        self.lock.take();
        remove_empty(&self.created_parents);
    }
}

/// Refuses an output folder that is one of the `inputs`, lies inside one or holds one (after
/// resolving `.`, `..` and symbolic links): a merge replaces its output folder as a whole, so
/// it would destroy the input it reads.
pub fn refuse_overlap(out: &Path, inputs: &[PathBuf], flag: &str) -> Result<()> {
    let o = resolved(out);
    for i in inputs {
        let r = resolved(i);
        if o.starts_with(&r) || r.starts_with(&o) {
            let how = if o == r {
                "is"
            } else if o.starts_with(&r) {
                "lies inside"
            } else {
                "holds"
            };
            return Err(Error::field(
                flag,
                format!(
                    "the output folder {} {how} the input {}: a merge replaces its output \
                     folder as a whole, so write it to a folder of its own",
                    out.display(),
                    i.display()
                ),
            ));
        }
    }
    Ok(())
}

/// `p` with symbolic links resolved as far as it exists (relative to the current directory); of
/// a path that does not exist, `.` and `..` are taken as written and the deepest part that
/// exists is resolved.
fn resolved(p: &Path) -> PathBuf {
    let abs = if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(p)
    };
    if let Ok(r) = std::fs::canonicalize(&abs) {
        return r;
    }
    let mut lexical = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::ParentDir => {
                lexical.pop();
            }
            Component::CurDir => {}
            other => lexical.push(other),
        }
    }
    let mut base = lexical.clone();
    let mut rest = Vec::new();
    loop {
        if let Ok(mut r) = std::fs::canonicalize(&base) {
            for n in rest.iter().rev() {
                r.push(n);
            }
            return r;
        }
        match (base.file_name(), base.parent()) {
            (Some(n), Some(parent)) => {
                rest.push(n.to_os_string());
                base = parent.to_path_buf();
            }
            _ => return lexical,
        }
    }
}

/// A run replaces its output folder: refuse a destination that holds the current directory, so
/// that `--out .` cannot wipe a working tree.
fn refuse_current_dir(target: &Path, given: &Path) -> Result<()> {
    if let (Ok(t), Ok(cwd)) = (
        std::fs::canonicalize(target),
        std::env::current_dir().and_then(std::fs::canonicalize),
    ) && cwd.starts_with(&t)
    {
        return Err(Error::input(
            "the output folder contains the current directory; a run replaces its output \
             folder as a whole, so choose a folder of its own (for example `out/run`)",
        )
        .in_file(given));
    }
    Ok(())
}

/// An advisory lock on a lock file, removed again when released.
#[derive(Debug)]
struct DirLock {
    path: PathBuf,
    _file: File,
}

impl DirLock {
    /// Takes the lock or reports the run that holds it as an input error about `dest`.
    fn acquire(path: &Path, dest: &Path) -> Result<DirLock> {
        loop {
            let file = open_lock_file(path)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    return Err(Error::input(format!(
                        "another spibench run is writing into this output folder (it holds {}); \
                         wait for it to finish or choose another output folder",
                        path.display()
                    ))
                    .in_file(dest));
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(Error::write(path, e)),
            }
            // A run that finished between our open and our lock removed the file it locked;
            // then the lock we hold is on a file nobody else sees: take it again on the new one.
            if same_file(&file, path) {
                return Ok(DirLock {
                    path: path.to_path_buf(),
                    _file: file,
                });
            }
        }
    }
}

/// Opens the lock file `path` without ever following a symbolic link: a new one is created
/// exclusively (`create_new`, which fails on any entry there, a dangling link included, instead
/// of creating the file the link names), an existing one (left by a run that was killed) is
/// opened, without creating anything, only after its entry showed a plain file; `same_file`
/// then checks that the file locked is the entry at `path` still.
fn open_lock_file(path: &Path) -> Result<File> {
    loop {
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
        {
            Ok(f) => return Ok(f),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(Error::write(path, e)),
        }
        refuse_link(path, "lock file")?;
        match std::fs::OpenOptions::new().write(true).open(path) {
            Ok(f) => return Ok(f),
            // Removed meanwhile by the run that held it: create it again.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => return Err(Error::write(path, e)),
        }
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        // Removed while still locked (the file closes after this), so a waiting run re-checks.
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    // The entry itself: a link put in the file's place is not the file.
    match (file.metadata(), std::fs::symlink_metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &File, path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file())
}

/// The process id in a name `PREFIX{pid}-{n}`, if it has that shape.
fn pid_in(name: &str, prefix: &str) -> Option<u32> {
    let rest = name.strip_prefix(prefix)?;
    let (pid, n) = rest.split_once('-')?;
    n.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// True when process `pid` is known not to run any more. Only Linux's `/proc` is consulted;
/// elsewhere nothing is taken for dead. A staging folder of this very process that is not live
/// is stale too (left by an earlier process with the same id).
fn is_dead(pid: u32, path: &Path) -> bool {
    if pid == std::process::id() {
        return !live().iter().any(|e| e.staging.iter().any(|s| s == path));
    }
    Path::new("/proc/self").exists() && !Path::new("/proc").join(pid.to_string()).exists()
}

/// Removes what dead runs left for destination `target` (named `name`, in `parent`): staging
/// folders, and replaced folders (put back first when the destination is missing). Called with
/// the destination's lock held. An entry with such a name that is a symbolic link was not made
/// by spibench: it is neither followed nor removed, and the run stops with an input error naming
/// it (following it would move or delete the files it leads to).
fn sweep_stale(parent: &Path, name: &str, target: &Path) -> Result<()> {
    let partial = format!(".{name}.spibench-partial-");
    let old = format!(".{name}.spibench-old-");
    for entry in sorted_names(parent) {
        let Some(s) = entry.to_str() else { continue };
        let path = parent.join(&entry);
        if let Some(pid) = pid_in(s, &partial) {
            if is_dead(pid, &path) {
                refuse_link(&path, "staging folder")?;
                let _ = std::fs::remove_dir_all(&path);
            }
        } else if let Some(pid) = pid_in(s, &old)
            && is_dead(pid, &path)
        {
            refuse_link(&path, "replaced output folder")?;
            if std::fs::symlink_metadata(target).is_err() {
                let _ = std::fs::rename(&path, target);
            } else {
                let _ = std::fs::remove_dir_all(&path);
            }
        }
    }
    // The destination itself as the user named it may be a link (trusted); its entries are not.
    if target.is_dir() {
        for entry in sorted_names(target) {
            let Some(s) = entry.to_str() else { continue };
            let path = target.join(&entry);
            if let Some(pid) = pid_in(s, ".spibench-partial-") {
                if is_dead(pid, &path) {
                    refuse_link(&path, "staging folder")?;
                    let _ = std::fs::remove_dir_all(&path);
                }
            } else if let Some(pid) = pid_in(s, ".spibench-old-")
                && is_dead(pid, &path)
            {
                refuse_link(&path, "folder of replaced entries")?;
                // An entry-by-entry swap cut short: the old entries go back where they were.
                for e in sorted_names(&path) {
                    let back = target.join(&e);
                    remove_any(&back);
                    let _ = std::fs::rename(path.join(&e), &back);
                }
                let _ = std::fs::remove_dir_all(&path);
            }
        }
    }
    Ok(())
}

/// The input error for a symbolic link found where spibench keeps an entry of its own (`what`:
/// a lock file, a staging or swap folder, a temporary file). spibench makes no links there, so
/// someone else did: it is neither followed (it may lead anywhere, and what spibench does to its
/// own entries is move, write and delete) nor removed.
pub fn planted_link(path: &Path, what: &str) -> Error {
    let to = std::fs::read_link(path).unwrap_or_default();
    Error::input(format!(
        "a symbolic link (to {}) stands where spibench keeps its own {what}; spibench never \
         follows a link there, since it would write, move or delete what the link leads to: \
         remove the link (or choose another output folder)",
        to.display()
    ))
    .in_file(path)
}

/// Refuses a symbolic link at `path` ([`planted_link`]); anything else, or nothing, passes.
/// Looks at the entry itself (`symlink_metadata`), never at what it leads to.
pub fn refuse_link(path: &Path, what: &str) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Err(planted_link(path, what)),
        _ => Ok(()),
    }
}

/// Creates a fresh file at `path` to write, without following a symbolic link: a plain file
/// left there (a temporary copy of a run that was killed) is removed first, and the new file is
/// created exclusively (`create_new`: an entry that appears meanwhile, a link included, makes it
/// fail instead of being written through). Callers refuse a link first ([`refuse_link`]).
pub fn create_fresh(path: &Path) -> std::io::Result<File> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_file() => std::fs::remove_file(path)?,
        _ => {}
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
}

fn sorted_names(dir: &Path) -> Vec<OsString> {
    let mut v: Vec<OsString> = std::fs::read_dir(dir)
        .map(|it| it.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

fn remove_any(path: &Path) {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => {
            let _ = std::fs::remove_dir_all(path);
        }
        Ok(_) => {
            let _ = std::fs::remove_file(path);
        }
        Err(_) => {}
    }
}

/// True for the hidden bookkeeping entries of a destination used in place.
fn is_bookkeeping(name: &OsString) -> bool {
    name.to_str().is_some_and(|s| s.starts_with(".spibench-"))
}

/// Replaces the entries of `dest` by those of `staging` (a folder inside `dest`): the current
/// entries move aside into `dest/.spibench-old-PID-N`, the staged ones move in, and the old ones
/// are removed; if a move in fails, the moved-in entries are removed and the old ones put back.
fn replace_entries(staging: &Path, dest: &Path) -> Result<()> {
    let id = COUNTER.fetch_add(1, Ordering::Relaxed);
    let aside = dest.join(format!(".spibench-old-{}-{id}", std::process::id()));
    std::fs::create_dir(&aside).map_err(|e| Error::write(&aside, e))?;
    let current: Vec<OsString> = sorted_names(dest)
        .into_iter()
        .filter(|n| !is_bookkeeping(n))
        .collect();
    let mut set_aside = Vec::new();
    let mut moved_in = BTreeSet::new();
    let mut failure = None;
    for n in &current {
        match std::fs::rename(dest.join(n), aside.join(n)) {
            Ok(()) => set_aside.push(n.clone()),
            Err(e) => {
                failure = Some(Error::write(&dest.join(n), e));
                break;
            }
        }
    }
    if failure.is_none() {
        for n in sorted_names(staging) {
            match std::fs::rename(staging.join(&n), dest.join(&n)) {
                Ok(()) => {
                    moved_in.insert(n);
                }
                Err(e) => {
                    failure = Some(Error::write(&dest.join(&n), e));
                    break;
                }
            }
        }
    }
    if let Some(e) = failure {
        for n in &moved_in {
            remove_any(&dest.join(n));
        }
        for n in &set_aside {
            let _ = std::fs::rename(aside.join(n), dest.join(n));
        }
        let _ = std::fs::remove_dir_all(&aside);
        return Err(e);
    }
    let _ = std::fs::remove_dir_all(&aside);
    Ok(())
}

/// Moves the tree `from` to `to` (which must not exist): a rename when both are on one
/// filesystem, else a copy followed by removing `from`.
fn move_tree(from: &Path, to: &Path) -> Result<()> {
    match std::fs::rename(from, to) {
        Ok(()) => Ok(()),
        Err(e) if is_cross_device(&e) => {
            copy_tree(from, to)?;
            let _ = std::fs::remove_dir_all(from);
            Ok(())
        }
        Err(e) => Err(Error::write(to, e)),
    }
}

fn copy_tree(from: &Path, to: &Path) -> Result<()> {
    std::fs::create_dir(to).map_err(|e| Error::write(to, e))?;
    for n in sorted_names(from) {
        let (s, d) = (from.join(&n), to.join(&n));
        let meta = std::fs::symlink_metadata(&s).map_err(|e| Error::read(&s, e))?;
        if meta.is_dir() {
            copy_tree(&s, &d)?;
        } else {
            std::fs::copy(&s, &d).map_err(|e| Error::write(&d, e))?;
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
mod tests;
