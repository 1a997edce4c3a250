//! Output folders under signals, reruns, concurrent runs and a second filesystem
//! (`report::output`): a run leaves either its complete result or, when interrupted or killed,
//! the folder exactly as it was before, and nothing hidden beside it once the next run has
//! swept what a killed one left.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{TempDir, spibench};

/// A small experiment that still takes long enough (a few hundred milliseconds) for a signal
/// to arrive while it runs.
const EXPERIMENT: &str = r#"Experiment(
    title: "output folders",
    width: 64, height: 64,
    objects: [(name: "phantom", object: Phantom), (name: "usaf", object: Usaf(region: Fig6))],
    sampling_ratios: [0.25, 0.5, 1.0],
    cases: [
        (label: "TCS", scheme: Traditional),
        (label: "SCB", scheme: SecondaryComplementaryBalancing,
         arms: (k_plus: 1.01, k_minus: 1.02, b_plus: 1.0, b_minus: 5.0)),
    ],
    solver: (maxit: 200),
)
"#;

fn experiment(dir: &TempDir) -> PathBuf {
    let p = dir.join("exp.ron");
    std::fs::write(&p, EXPERIMENT).unwrap();
    p
}

fn start(exp: &Path, out: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_spibench"))
        .args([
            "simulate",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Waits until the run's staging folder exists (the run has started writing).
fn wait_for_staging(parent: &Path) -> bool {
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(60) {
        if names(parent).iter().any(|n| n.contains("spibench-partial")) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    false
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill {sig}");
}

/// A folder that existed before, with one file only this test wrote.
fn existing(dir: &TempDir) -> PathBuf {
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("mine.txt"), b"keep").unwrap();
    out
}

fn assert_unchanged(out: &Path) {
    assert_eq!(names(out), vec!["mine.txt"]);
    assert_eq!(std::fs::read(out.join("mine.txt")).unwrap(), b"keep");
}

#[test]
fn sigint_and_sigterm_leave_the_folder_as_it_was_and_nothing_beside_it() {
    for (sig, code) in [("-INT", 130), ("-TERM", 143)] {
        let dir = TempDir::new(&format!("out-signal{sig}"));
        let exp = experiment(&dir);
        let out = existing(&dir);
        let mut child = start(&exp, &out);
        assert!(wait_for_staging(&dir.0), "the run never staged");
        signal(&child, sig);
        let status = child.wait().unwrap();
        if status.success() {
            // The run finished before the signal arrived: then it replaced the folder.
            assert!(out.join("summary.json").exists());
        } else {
            assert_eq!(status.code(), Some(code), "{sig}");
            assert_unchanged(&out);
        }
        assert_eq!(names(&dir.0), vec!["exp.ron", "out"], "{sig}");
    }
}

#[test]
fn sigkill_at_a_random_point_leaves_the_folder_unchanged_and_the_next_run_sweeps() {
    let dir = TempDir::new("out-kill");
    let exp = experiment(&dir);
    let out = existing(&dir);
    // A "random" point, fixed per process so a failure can be replayed: 0–150 ms after staging.
    let delay = Duration::from_millis(u64::from(std::process::id() % 150));
    let mut child = start(&exp, &out);
    assert!(wait_for_staging(&dir.0));
    std::thread::sleep(delay);
    signal(&child, "-KILL");
    let status = child.wait().unwrap();
    if !status.success() {
        assert_unchanged(&out);
    }
    // What the killed run left (staging, a lock file) goes at the next run.
    let o = spibench(
        &[
            "simulate",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", crate::common::stderr(&o));
    assert_eq!(names(&dir.0), vec!["exp.ron", "out"]);
    assert!(
        !out.join("mine.txt").exists(),
        "a rerun replaces the folder"
    );
}

#[test]
fn a_rerun_replaces_the_folder_with_byte_identical_results() {
    let dir = TempDir::new("out-rerun");
    let exp = experiment(&dir);
    let out = existing(&dir);
    let run = || {
        let o = spibench(
            &[
                "simulate",
                exp.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert_eq!(o.status.code(), Some(0), "{}", crate::common::stderr(&o));
        (
            std::fs::read(out.join("summary.json")).unwrap(),
            std::fs::read(out.join("cells.csv")).unwrap(),
        )
    };
    let first = run();
    assert!(!out.join("mine.txt").exists(), "stale files do not survive");
    assert!(out.join("timings.json").exists());
    let second = run();
    assert!(
        first == second,
        "summary.json and cells.csv differ between runs"
    );
    assert_eq!(names(&dir.0), vec!["exp.ron", "out"]);
}

#[test]
fn of_two_concurrent_runs_one_wins_and_the_other_exits_2() {
    let dir = TempDir::new("out-concurrent");
    let exp = experiment(&dir);
    let out = dir.join("out");
    let mut first = start(&exp, &out);
    assert!(wait_for_staging(&dir.0));
    let second = spibench(
        &[
            "simulate",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let status = first.wait().unwrap();
    assert!(status.success());
    if second.status.code() != Some(0) {
        assert_eq!(second.status.code(), Some(2));
        let err = crate::common::stderr(&second);
        assert!(err.contains("another spibench run"), "{err}");
        assert!(err.contains("out"), "{err}");
    }
    assert!(out.join("summary.json").exists());
    assert_eq!(names(&dir.0), vec!["exp.ron", "out"]);
}

#[test]
fn out_on_another_filesystem_and_a_failing_rename_both_work() {
    let dir = TempDir::new("out-exdev");
    let exp = experiment(&dir);
    // The rename of the destination fails as on a mount point: the files are swapped in place.
    let out = existing(&dir);
    let o = spibench(
        &[
            "simulate",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[("SPIBENCH_TEST_OUTPUT_EXDEV", "1")],
    );
    assert_eq!(o.status.code(), Some(0), "{}", crate::common::stderr(&o));
    assert!(!out.join("mine.txt").exists());
    assert!(out.join("summary.json").exists());
    assert!(
        !names(&out).iter().any(|n| n.starts_with('.')),
        "{:?}",
        names(&out)
    );
    assert_eq!(names(&dir.0), vec!["exp.ron", "out"]);

    // A tmpfs on another device, where the machine has one.
    let shm = Path::new("/dev/shm");
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let other_device = std::fs::metadata(shm)
            .ok()
            .zip(std::fs::metadata(&dir.0).ok())
            .is_some_and(|(a, b)| a.dev() != b.dev());
        if other_device {
            let base = shm.join(format!("spibench-out-{}", std::process::id()));
            let out = base.join("out");
            let o = spibench(
                &[
                    "simulate",
                    exp.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                ],
                &[],
            );
            let ok = o.status.code() == Some(0);
            let clean = ok && names(&base) == vec!["out"];
            let _ = std::fs::remove_dir_all(&base);
            assert!(ok, "{}", crate::common::stderr(&o));
            assert!(clean);
        }
    }
}
