//! Symbolic links planted where spibench keeps its own entries (a stale swap folder inside or
//! beside an output folder, the lock file beside it): no command follows them, so the files they
//! lead to are neither moved, deleted nor created; each such link is an input error that names
//! it (exit 2), and the output folder is left as it was.

use std::path::{Path, PathBuf};

use crate::common::{TempDir, spibench, stderr};
use crate::untrusted::{merge_tolerance, ok, s, tolerance, tree, write_spec};

/// A process id that runs nowhere (Linux has no such pid), so that its swap folders count as
/// stale and are swept.
const DEAD_PID: u32 = u32::MAX - 7;

/// A folder of files that a command following a planted link would move or delete.
fn victim(t: &TempDir) -> PathBuf {
    let v = t.join("victim");
    std::fs::create_dir_all(v.join("sub")).unwrap();
    std::fs::write(v.join("thesis.tex"), b"years of work").unwrap();
    std::fs::write(v.join("sub/data.csv"), b"1,2,3\n").unwrap();
    v
}

/// Asserts a refusal with exit status 2 that names the link `link`.
fn refused_naming(o: &std::process::Output, link: &Path, what: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{what}: {err}");
    let name = link.file_name().unwrap().to_str().unwrap();
    assert!(
        err.contains(name) && err.contains("symbolic link"),
        "{what}: the message must name the link {name}: {err}"
    );
    assert!(!err.contains("panicked"), "{what}: {err}");
}

/// Plants `link` → `to`, runs `run`, and checks that it is refused naming the link, that the
/// victim folder and `out` are as they were, and removes the link again.
fn planted(
    link: &Path,
    to: &Path,
    out: &Path,
    victim: &Path,
    what: &str,
    run: impl Fn() -> std::process::Output,
) {
    let snap = |d: &Path| d.exists().then(|| tree(d));
    let (victim_before, out_before) = (tree(victim), snap(out));
    std::os::unix::fs::symlink(to, link).unwrap();
    refused_naming(&run(), link, what);
    assert_eq!(
        tree(victim),
        victim_before,
        "{what}: the victim's files changed"
    );
    std::fs::remove_file(link).unwrap();
    assert_eq!(snap(out), out_before, "{what}: the output folder changed");
}

#[cfg(target_os = "linux")]
#[test]
fn links_named_like_stale_swap_folders_are_refused_not_followed() {
    let t = TempDir::new("planted-swap");
    let v = victim(&t);
    let stale = format!(".spibench-old-{DEAD_PID}-0");
    // Tolerance: two shards, merged once into an existing output folder.
    let shards: Vec<PathBuf> = (0..2).map(|i| t.join(&format!("s{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        ok(&tolerance(
            &["--trials", "3", "--shard", &format!("{i}/2")],
            d,
        ));
    }
    let out = t.join("out");
    ok(&merge_tolerance(&[&shards[0], &shards[1]], &out));
    let merge = || merge_tolerance(&[&shards[0], &shards[1]], &out);
    planted(&out.join(&stale), &v, &out, &v, "tolerance --merge", merge);
    // Beside the folder, named like its replaced copy.
    let beside = t.join(&format!(".out.spibench-old-{DEAD_PID}-0"));
    planted(&beside, &v, &out, &v, "tolerance --merge, beside", merge);
    // A staging folder's name, inside.
    let partial = out.join(format!(".spibench-partial-{DEAD_PID}-0"));
    planted(&partial, &v, &out, &v, "tolerance --merge, staging", merge);
    // A rerun of a shard into its own folder.
    planted(
        &shards[0].join(&stale),
        &v,
        &shards[0],
        &v,
        "tolerance shard rerun",
        || tolerance(&["--trials", "3", "--shard", "0/2"], &shards[0]),
    );
    // Dataset: a folder merged into an existing output folder.
    let spec = write_spec(&t.0);
    let one = t.join("one");
    ok(&spibench(&["dataset", s(&spec), "--out", s(&one)], &[]));
    let m = t.join("m");
    let dmerge = || spibench(&["dataset", "--merge", s(&one), "--out", s(&m)], &[]);
    ok(&dmerge());
    planted(&m.join(&stale), &v, &m, &v, "dataset --merge", dmerge);
    // With every link gone, the same commands succeed.
    ok(&merge());
    ok(&dmerge());
    assert!(v.join("thesis.tex").is_file() && v.join("sub/data.csv").is_file());
}

#[cfg(unix)]
#[test]
fn a_dangling_link_named_like_the_lock_file_creates_nothing() {
    let t = TempDir::new("planted-lock");
    let v = victim(&t);
    let target = v.join("created-by-spibench");
    let spec = write_spec(&t.0);
    let one = t.join("one");
    ok(&spibench(&["dataset", s(&spec), "--out", s(&one)], &[]));
    // dataset --merge into a new folder.
    let m = t.join("m");
    let lock = t.join(".m.spibench-lock");
    planted(&lock, &target, &m, &v, "dataset --merge", || {
        spibench(&["dataset", "--merge", s(&one), "--out", s(&m)], &[])
    });
    assert!(!target.exists() && !m.exists());
    // dataset --resume of an existing folder.
    let lock = t.join(".one.spibench-lock");
    planted(&lock, &target, &one, &v, "dataset --resume", || {
        spibench(&["dataset", s(&spec), "--out", s(&one), "--resume"], &[])
    });
    assert!(!target.exists());
    // tolerance --merge.
    let shards: Vec<PathBuf> = (0..2).map(|i| t.join(&format!("s{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        ok(&tolerance(
            &["--trials", "2", "--shard", &format!("{i}/2")],
            d,
        ));
    }
    let out = t.join("out");
    let lock = t.join(".out.spibench-lock");
    planted(&lock, &target, &out, &v, "tolerance --merge", || {
        merge_tolerance(&[&shards[0], &shards[1]], &out)
    });
    assert!(!target.exists() && !out.exists());
    // A lock file left by a run that was killed (a plain file) is taken over as before.
    std::fs::write(&lock, b"").unwrap();
    ok(&merge_tolerance(&[&shards[0], &shards[1]], &out));
    assert!(!lock.exists());
}
