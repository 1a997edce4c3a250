//! Records the git commit spibench is built from (when the source is a git checkout and git is
//! installed) for the provenance block of every summary.json. Without git the commit is
//! reported as unknown; the build never fails for it.

use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| s.len() == 40 && s.bytes().all(|b| b.is_ascii_hexdigit()));
    let dirty = Command::new("git")
        .args(["status", "--porcelain", "--untracked-files=no"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| !o.stdout.is_empty());
    if let Some(c) = commit {
        let suffix = if dirty == Some(true) { "-modified" } else { "" };
        println!("cargo:rustc-env=SPIBENCH_GIT_COMMIT={c}{suffix}");
    }
    // Rebuild when HEAD moves (a commit or a checkout); source edits rebuild anyway.
    for f in [".git/HEAD", ".git/index"] {
        if std::path::Path::new(f).exists() {
            println!("cargo:rerun-if-changed={f}");
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
}
