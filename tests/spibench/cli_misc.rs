//! The command line's own conveniences: completions, man pages, --threads, --quiet.

use crate::common::{TempDir, spibench, stderr, stdout};

/// `completions bash` prints a script bash accepts (`bash -n`); zsh and fish produce text.
#[test]
fn completions_are_valid_bash() {
    let o = spibench(&["completions", "bash"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let script = stdout(&o);
    assert!(script.contains("spibench"), "{script}");
    let dir = TempDir::new("completions");
    let path = dir.join("spibench.bash");
    std::fs::write(&path, &script).unwrap();
    let check = std::process::Command::new("bash")
        .arg("-n")
        .arg(&path)
        .output()
        .expect("bash runs");
    assert!(
        check.status.success(),
        "bash -n: {}",
        String::from_utf8_lossy(&check.stderr)
    );
    for shell in ["zsh", "fish"] {
        let o = spibench(&["completions", shell], &[]);
        assert!(o.status.success() && !o.stdout.is_empty(), "{shell}");
    }
}

/// `man` writes one page per command, in roff.
#[test]
fn man_pages_are_written() {
    let dir = TempDir::new("man");
    let out = dir.join("man");
    let o = spibench(&["man", "--out", out.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let page = std::fs::read_to_string(out.join("spibench-run.1")).unwrap();
    assert!(page.starts_with(".ie") || page.contains(".TH"), "{page}");
    assert!(page.contains("repeats"), "the run page documents --repeats");
    assert!(out.join("spibench.1").exists());
}

/// `--quiet` leaves stderr empty on success; `--threads 0` is a usage error (exit 2).
#[test]
fn quiet_and_threads() {
    let bench = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper_bench.ron");
    let o = spibench(&["--quiet", "--threads", "1", "check", bench], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
    assert!(!stdout(&o).is_empty());
    let o = spibench(&["--threads", "0", "check", bench], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--threads"));
}

/// `run --repeats 0` is a usage error naming the flag, before any trace, and leaves nothing.
#[test]
fn repeats_must_be_positive() {
    let dir = TempDir::new("repeats0");
    let out = dir.join("run");
    let o = spibench(
        &["run", "--repeats", "0", "--out", out.to_str().unwrap()],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--repeats"), "{}", stderr(&o));
    assert!(!out.exists());
}
