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

/// The tables and notes that `check`, `trace`, `sweep` (two variables), `tolerance`, `align`
/// and `run --repeats` (its findings and paired differences) print fit a terminal of 100 columns (`simulate`'s are checked in cli_simulate); a line that
/// names the output folder may be longer by the folder's own length.
#[test]
fn printed_tables_fit_100_columns() {
    let dir = TempDir::new("width");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let bench = root.join("scenes/tests/symmetric_arms.ron");
    let bench = bench.to_str().unwrap();
    let paper = root.join("scenes/paper_bench.ron");
    let tol = root.join("scenes/tolerances/symmetric_arms.ron");
    let out = |n: &str| dir.join(n).to_str().unwrap().to_string();
    let (o1, o2, o3, o4, o5) = (out("t"), out("s"), out("tol"), out("a"), out("r"));
    // `run --repeats` prints the paired differences SCB − each baseline; single-arm and
    // offset-aware double-arm have the longest names (that table printed 101 columns).
    let small = crate::findings::small_run_scene_of(
        &dir,
        "SecondaryComplementaryBalancing, SingleArmComplementary, DoubleArmOffset",
        "0.125, 1.0",
    );
    let runs: Vec<Vec<&str>> = vec![
        vec!["check", paper.to_str().unwrap()],
        vec!["trace", bench, "--rays", "8192", "--out", &o1],
        vec![
            "sweep",
            bench,
            "--vary",
            "detectors.minus.decenter_mm.x=-0.5:0.5:2",
            "--vary",
            "arm_minus_lens.despace_mm=-0.2:0.2:2",
            "--rays",
            "4096",
            "--out",
            &o2,
        ],
        vec![
            "tolerance",
            bench,
            "--tolerances",
            tol.to_str().unwrap(),
            "--trials",
            "2",
            "--rays",
            "4096",
            "--out",
            &o3,
        ],
        vec![
            "align",
            bench,
            "--free",
            "detectors.minus.decenter_mm.x=-2:2",
            "--rays",
            "4096",
            "--max-evaluations",
            "8",
            "--out",
            &o4,
        ],
        vec![
            "run",
            small.to_str().unwrap(),
            "--repeats",
            "2",
            "--out",
            &o5,
        ],
    ];
    for args in runs {
        let o = spibench(&args, &[]);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        let text = stdout(&o);
        let dir_len = dir.0.to_str().unwrap().chars().count() + 4;
        for l in text.lines() {
            let n = l.chars().count();
            let allowed = if l.contains(dir.0.to_str().unwrap()) {
                100 + dir_len
            } else {
                100
            };
            assert!(n <= allowed, "{} ({n} columns): {l}", args[0]);
        }
        // Align's summary card opens its output, its numbers summary.json's, each variable
        // as the bench file counts it with the move made.
        if args[0] == "align" {
            assert_card_opens(&text, &o4, spibench::outputs::align::card);
            assert!(text.contains(", moved "), "{text}");
        }
        // Tolerance's card too: its yields, causes and compensators are summary.json's.
        if args[0] == "tolerance" {
            assert_card_opens(&text, &o3, spibench::outputs::tolerance::card);
            assert!(text.contains("95 % interval"), "{text}");
        }
    }
}

/// Asserts that `text`, a command's output, opens with the summary card `card` makes of the
/// summary.json in folder `out`, and that every number of the card is that file's.
fn assert_card_opens(
    text: &str,
    out: &str,
    card: impl Fn(&serde_json::Value) -> spibench::outputs::card::Card,
) {
    let s = crate::common::read_json(&std::path::Path::new(out).join("summary.json"));
    let card = card(&s);
    card.check_against(&s).unwrap();
    assert!(text.starts_with(&card.printed().join("\n")), "{text}");
}
