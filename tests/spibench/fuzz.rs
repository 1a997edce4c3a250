//! A deterministic mutation fuzzer over the shipped scenes and experiments: deleted and
//! duplicated lines, numbers replaced by NaN, ±inf, ±1e308, wrapping integers or random
//! magnitudes, swapped tokens and truncation, every mutant keyed by (scene, index) through
//! SplitMix64 so a failure names a mutant that can be rebuilt exactly.
//!
//! Every mutant goes through parsing and validation and, when it is accepted, a tiny trace
//! (two batches of rays), in-process and with panics caught; a few dozen also go through the
//! `spibench trace` binary. What must hold: no panic, every error an input error (exit 2), and
//! every accepted bench traced to finite numbers or refused as an input error (no light on the
//! pattern area), never NaN or infinity in a summary. For longer runs, see `fuzz/` (cargo-fuzz).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use spibench::pipeline::{TraceRequest, trace_stage};
use spibench::scene::doc::BenchDoc;

use crate::common::{TempDir, spibench};

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny keyed generator, enough for mutations.
struct Mix(u64);

impl Mix {
    fn new(a: u64, b: u64) -> Mix {
        Mix(a.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ b.wrapping_add(0x632B_E59B_D9B4_E019))
    }
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Byte ranges of the number literals of a RON text (outside comments and strings).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += 1;
            }
            i += 1;
            continue;
        }
        let ident_before = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        if !ident_before
            && (b[i].is_ascii_digit()
                || (b[i] == b'-' && b.get(i + 1).is_some_and(|c| c.is_ascii_digit())))
        {
            let start = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_alphanumeric()
                    || b[i] == b'.'
                    || ((b[i] == b'-' || b[i] == b'+') && matches!(b[i - 1], b'e' | b'E')))
            {
                i += 1;
            }
            out.push((start, i));
            continue;
        }
        i += 1;
    }
    out
}

/// Word-like tokens (identifiers and numbers) for swapping.
fn tokens(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'.' || b[i] == b'-' {
            let s = i;
            while i < b.len()
                && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'.' || b[i] == b'-')
            {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

const SPECIAL: [&str; 10] = [
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "18446744073709551615",
    "4611686018427387904",
    "0",
    "-1",
    "1e-308",
];

/// One mutation of `text`, chosen by `rng`.
fn mutate_once(text: &str, rng: &mut Mix) -> String {
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    match rng.below(8) {
        0 if !lines.is_empty() => {
            let k = rng.below(lines.len());
            lines
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, l)| *l)
                .collect()
        }
        1 if !lines.is_empty() => {
            let k = rng.below(lines.len());
            let mut out = String::new();
            for (i, l) in lines.iter().enumerate() {
                out.push_str(l);
                if i == k {
                    out.push_str(l);
                }
            }
            out
        }
        2..=4 => {
            let nums = numbers(text);
            if nums.is_empty() {
                return text.to_string();
            }
            let (s, e) = nums[rng.below(nums.len())];
            let with = if rng.below(3) == 0 {
                // A random magnitude: ±m × 10^k, k anywhere in the f64 range.
                let sign = if rng.below(2) == 0 { "" } else { "-" };
                let k = rng.below(617) as i32 - 308;
                format!("{sign}{}.{}e{k}", 1 + rng.below(9), rng.below(1000))
            } else {
                SPECIAL[rng.below(SPECIAL.len())].to_string()
            };
            format!("{}{with}{}", &text[..s], &text[e..])
        }
        5 | 6 => {
            let t = tokens(text);
            if t.len() < 2 {
                return text.to_string();
            }
            let (mut a, mut b) = (t[rng.below(t.len())], t[rng.below(t.len())]);
            if a.0 > b.0 {
                std::mem::swap(&mut a, &mut b);
            }
            if a.1 > b.0 {
                return text.to_string();
            }
            format!(
                "{}{}{}{}{}",
                &text[..a.0],
                &text[b.0..b.1],
                &text[a.1..b.0],
                &text[a.0..a.1],
                &text[b.1..]
            )
        }
        _ => {
            let mut cut = rng.below(text.len());
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            text[..cut].to_string()
        }
    }
}

/// Mutant `index` of `text`: one to three mutations.
fn mutant(text: &str, scene_key: u64, index: u64) -> String {
    let mut rng = Mix::new(scene_key, index);
    let mut t = text.to_string();
    for _ in 0..1 + rng.below(3) {
        t = mutate_once(&t, &mut rng);
    }
    t
}

fn shipped(rel: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
}

/// What happened to one mutant, for the tally and for naming failures.
#[derive(Debug, PartialEq, Eq, Clone, Copy)]
enum Fate {
    Refused,
    Traced,
    NoLight,
}

/// Parses, validates and (when accepted) traces one bench mutant in-process with a tiny ray
/// count. Returns its fate, or a description of what broke the rules.
fn check_bench(text: &str, path: &Path, seed: u64) -> Result<Fate, String> {
    let parsed = catch_unwind(AssertUnwindSafe(|| {
        BenchDoc::parse(text, path).and_then(|d| d.run_scene())
    }))
    .map_err(|_| "panicked while parsing".to_string())?;
    let scene = match parsed {
        Ok(s) => s,
        Err(e) if e.is_user_error() => {
            let msg = e.to_string();
            if !msg.contains(&path.display().to_string()) {
                return Err(format!("an input error that names no file: {msg}"));
            }
            return Ok(Fate::Refused);
        }
        Err(e) => return Err(format!("not an input error: {e}")),
    };
    if scene.bench.dmd().is_none() {
        return Ok(Fate::Refused);
    }
    let rays = 2 * spibench::trace::RAYS_PER_BATCH;
    let traced = catch_unwind(AssertUnwindSafe(|| {
        trace_stage(&scene.bench, &TraceRequest::new(rays, seed))
    }))
    .map_err(|_| "panicked while tracing".to_string())?;
    let traced = match traced {
        Ok(t) => t,
        Err(e) if e.is_user_error() => return Ok(Fate::Refused),
        Err(e) => return Err(format!("trace failed with a non-input error: {e}")),
    };
    match traced.truth() {
        Err(e) if e.is_user_error() => return Ok(Fate::NoLight),
        Err(e) => return Err(format!("truth failed with a non-input error: {e}")),
        Ok(_) => {}
    }
    let metrics = format!("{:?} {:?}", traced.metrics, traced.transport.k);
    if metrics.contains("NaN") || metrics.contains("inf") {
        let at = metrics
            .find("NaN")
            .or_else(|| metrics.find("inf"))
            .unwrap_or(0);
        let from = at.saturating_sub(200);
        let to = (at + 40).min(metrics.len());
        return Err(format!(
            "non-finite numbers in an accepted trace: …{}",
            metrics.get(from..to).unwrap_or(&metrics)
        ));
    }
    Ok(Fate::Traced)
}

/// 2 000 bench mutants and 600 experiment mutants, in-process.
#[test]
fn mutants_of_the_shipped_scenes_end_in_an_input_error_or_finite_numbers() {
    let benches = [
        ("scenes/paper_bench.ron", 900u64),
        ("scenes/fig8_region_b_48.ron", 300),
        ("scenes/tests/symmetric_arms.ron", 500),
        ("scenes/tests/disk_to_disk.ron", 300),
    ];
    let mut failures = Vec::new();
    let mut tally = [0usize; 3];
    for (k, (rel, count)) in benches.iter().enumerate() {
        let text = shipped(rel);
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
        for i in 0..*count {
            let m = mutant(&text, k as u64, i);
            match check_bench(&m, &path, i) {
                Ok(f) => tally[f as usize] += 1,
                Err(why) => failures.push(format!("{rel} mutant {i}: {why}")),
            }
        }
    }
    let experiments = [
        "scenes/fig1.ron",
        "scenes/fig2.ron",
        "scenes/fig3.ron",
        "scenes/fig4.ron",
    ];
    for (k, rel) in experiments.iter().enumerate() {
        let text = shipped(rel);
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
        for i in 0..150u64 {
            let m = mutant(&text, 100 + k as u64, i);
            let r = catch_unwind(AssertUnwindSafe(|| {
                spibench::scene::experiment::parse(&m, &path, Path::new("scenes"))
            }));
            match r {
                Err(_) => failures.push(format!("{rel} mutant {i}: panicked while parsing")),
                Ok(Err(e)) if !e.is_user_error() => {
                    failures.push(format!("{rel} mutant {i}: not an input error: {e}"))
                }
                Ok(Err(e)) if !e.to_string().contains(&path.display().to_string()) => {
                    failures.push(format!("{rel} mutant {i}: no file named: {e}"))
                }
                Ok(Ok(exp)) => {
                    let finite = exp.sampling_ratios.iter().all(|r| r.is_finite())
                        && exp.dmd_rate_hz.is_finite()
                        && exp.cases.iter().all(|c| {
                            [c.arms.k_plus, c.arms.k_minus, c.arms.b_plus, c.arms.b_minus]
                                .iter()
                                .all(|v| v.is_finite())
                        })
                        && exp.solver.validate().is_ok();
                    if !finite {
                        failures.push(format!("{rel} mutant {i}: accepted non-finite values"));
                    }
                }
                Ok(Err(_)) => {}
            }
        }
    }
    eprintln!(
        "fuzz: {} refused, {} traced, {} without light on the pattern",
        tally[0], tally[1], tally[2]
    );
    assert!(
        failures.is_empty(),
        "{} of the mutants broke the rules:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// A few dozen mutants through the binary: exit 0 or 2 only, and a summary without NaN.
#[test]
fn mutants_through_the_cli_exit_0_or_2_with_finite_summaries() {
    let dir = TempDir::new("fuzz-cli");
    let text = shipped("scenes/tests/symmetric_arms.ron");
    let mut failures = Vec::new();
    for i in 0..30u64 {
        let m = mutant(&text, 7, i);
        let scene = dir.join(&format!("m{i}.ron"));
        std::fs::write(&scene, &m).unwrap();
        let out = dir.join(&format!("out{i}"));
        let o = spibench(
            &[
                "trace",
                scene.to_str().unwrap(),
                "--rays",
                "2048",
                "--out",
                out.to_str().unwrap(),
            ],
            &[("RAYON_NUM_THREADS", "1")],
        );
        match o.status.code() {
            Some(0) => {
                let s = std::fs::read_to_string(out.join("summary.json")).unwrap_or_default();
                if s.contains("NaN") || s.contains("null") && s.contains("\"k_plus\": null") {
                    failures.push(format!("mutant {i}: NaN in summary.json"));
                }
            }
            Some(2) => {
                let err = String::from_utf8_lossy(&o.stderr);
                if !err.contains(&format!("m{i}.ron")) && !err.contains("--rays") {
                    failures.push(format!("mutant {i}: exit 2 without the file: {err}"));
                }
                if out.exists() {
                    failures.push(format!("mutant {i}: output left after exit 2"));
                }
            }
            other => failures.push(format!(
                "mutant {i}: exit {other:?}: {}",
                String::from_utf8_lossy(&o.stderr)
            )),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// 1000 mutants of the shipped tolerance file (checked against the paper bench) and 600 of the
/// shipped dataset spec, in-process: no panic, every error an input error naming the file, and
/// every accepted file holding finite, ordered values only.
#[test]
fn mutants_of_tolerance_files_and_dataset_specs_end_in_input_errors() {
    use spibench::scene::dataset::parse_dataset;
    use spibench::scene::tolerance::ToleranceSet;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = BenchDoc::read(&root.join("scenes/paper_bench.ron")).unwrap();
    let mut failures = Vec::new();
    let rel = "scenes/tolerances/paper_bench.ron";
    let (text, path) = (shipped(rel), root.join(rel));
    let mut accepted = [0usize; 2];
    for i in 0..1000u64 {
        let m = mutant(&text, 200, i);
        let r = catch_unwind(AssertUnwindSafe(|| ToleranceSet::parse(&m, &path, &doc)));
        match r {
            Err(_) => failures.push(format!("{rel} mutant {i}: panicked")),
            Ok(Err(e)) if !e.is_user_error() || !e.to_string().contains(rel) => {
                failures.push(format!("{rel} mutant {i}: {e}"))
            }
            Ok(Err(_)) => {}
            Ok(Ok(set)) => {
                accepted[0] += 1;
                let ranges_ok = set.tolerances.iter().all(|t| {
                    t.min.is_finite()
                        && t.max.is_finite()
                        && t.min <= t.max
                        && t.nominal.is_finite()
                });
                let limits_ok = set.limits.iter().all(|l| {
                    [l.min, l.max, l.abs_max]
                        .iter()
                        .flatten()
                        .all(|v| v.is_finite())
                        && !matches!((l.min, l.max), (Some(a), Some(b)) if a > b)
                });
                let quality_ok = set.quality.is_none_or(|q| {
                    (1..=100).contains(&q.ratio_percent) && q.min_mssim.is_finite()
                });
                if !(ranges_ok && limits_ok && quality_ok) {
                    failures.push(format!("{rel} mutant {i}: accepted a bad value: {set:?}"));
                }
            }
        }
    }
    let rel = "scenes/dataset_example.ron";
    let (text, path) = (shipped(rel), root.join(rel));
    for i in 0..600u64 {
        let m = mutant(&text, 300, i);
        let r = catch_unwind(AssertUnwindSafe(|| parse_dataset(&m, &path)));
        match r {
            Err(_) => failures.push(format!("{rel} mutant {i}: panicked")),
            Ok(Err(e)) if !e.is_user_error() || !e.to_string().contains(rel) => {
                failures.push(format!("{rel} mutant {i}: {e}"))
            }
            Ok(Err(_)) => {}
            Ok(Ok(spec)) => {
                accepted[1] += 1;
                let f = &spec.file;
                let ok = f.samples >= 1
                    && f.shard_samples >= 1
                    && f.kernel.rays >= spibench::scene::dataset::MIN_KERNEL_RAYS
                    && [f.kernel.field_mm.0, f.kernel.field_mm.1]
                        .iter()
                        .all(|v| v.is_finite() && *v > 0.0)
                    && f.acquisition.as_ref().is_none_or(|a| {
                        a.ratios.iter().all(|r| *r > 0.0 && *r <= 1.0) && !a.ratios.is_empty()
                    })
                    && f.max_disk_gb.is_none_or(|g| g.is_finite() && g > 0.0);
                if !ok {
                    failures.push(format!("{rel} mutant {i}: accepted a bad value: {f:?}"));
                }
            }
        }
    }
    eprintln!(
        "fuzz: {} of 1000 tolerance files and {} of 600 dataset specs accepted",
        accepted[0], accepted[1]
    );
    // Some mutants (a changed comment, a valid new number) must get through, or the test checks
    // nothing but the parser.
    assert!(accepted[0] > 0 && accepted[1] > 0, "{accepted:?}");
    assert!(
        failures.is_empty(),
        "{} of the mutants broke the rules:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Values tried in place of a command-line argument: non-numbers, non-finite and huge numbers,
/// integers at 2⁶³ and past 2⁶⁴, zero and negatives, and malformed sizes and ranges. (Valid but
/// slow values, such as 4·10⁹ rays for `trace`, are left out: the test must stay short.)
const ARG_VALUES: [&str; 18] = [
    "NaN",
    "inf",
    "-1",
    "0",
    "1e308",
    "9223372036854775808",
    "18446744073709551616",
    "",
    "abc",
    "0x0",
    "1x4294967297",
    "-0.5",
    "0/0",
    "dmd.tilt_deg=NaN:1:2",
    "dmd.tilt_deg=0:1:18446744073709551615",
    "detectors.minus.decenter_mm.x=-1e308:1e308",
    "imbalance=1e308",
    "1",
];

/// A small experiment for `spibench simulate` (8 × 8 units, two cases, a few iterations).
const SMALL_EXPERIMENT: &str = r#"Experiment(
    title: "fuzz",
    width: 8,
    height: 8,
    objects: [(name: "phantom", object: Phantom), (name: "usaf", object: Usaf(region: Elements(group: 0, first: 4, last: 6)))],
    sampling_ratios: [0.5],
    cases: [
        (label: "scb", scheme: SecondaryComplementaryBalancing,
         arms: (k_plus: 1.01, k_minus: 1.02, b_plus: 1.0, b_minus: 5.0),
         noise: (distribution: Gaussian, std: 2.0)),
    ],
    solver: (mu: 256.0, beta: 32.0, tol: 1e-3, maxit: 30, nonneg: true),
    seed: 5,
)
"#;

/// The non-finite numbers of a run's outputs (exit 0): `NaN` or an infinity in `summary.json`
/// (which JSON cannot hold: a number written as `NaN` or `inf`) or in a CSV table.
fn non_finite_outputs(out: &Path, what: &str) -> Vec<String> {
    let mut bad = Vec::new();
    let Ok(entries) = std::fs::read_dir(out) else {
        return bad;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !(name == "summary.json" || name.ends_with(".csv")) {
            continue;
        }
        let text = std::fs::read_to_string(e.path()).unwrap_or_default();
        let cells = text.split([',', '\n', ':', ' ']);
        if let Some(c) = cells
            .map(str::trim)
            .find(|c| ["NaN", "inf", "-inf"].contains(c))
        {
            bad.push(format!("{what}: {c} in {name}"));
        }
    }
    bad
}

/// Every command's arguments mutated one at a time through the binary (six mutants of each
/// value-taking argument of a cheap valid command line, `align` and `simulate` included), then
/// 24 mutants of a small experiment file through `simulate`: exit 0 or 2 only, never a panic or
/// an abort, an exit-2 message that names an argument or a file, nothing left behind after
/// exit 2 (no output, staging folder or lock), and no NaN or infinity in a summary or CSV table
/// after exit 0.
#[test]
fn mutated_command_line_arguments_exit_0_or_2() {
    let dir = TempDir::new("fuzz-args");
    let files = ArgFiles::new(&dir);
    let mut failures = Vec::new();
    let mut n = 0;
    let mut exits = [0usize; 2];
    for (c, (line, slots)) in command_lines(&files).iter().enumerate() {
        for &slot in slots {
            let mut rng = Mix::new(400 + c as u64, slot as u64);
            for _ in 0..6 {
                let value = ARG_VALUES[rng.below(ARG_VALUES.len())];
                let mut args = line.clone();
                args[slot] = value;
                let out = dir.join(&format!("out{n}"));
                n += 1;
                let mut a = args.clone();
                a.extend(["--out", out.to_str().unwrap()]);
                let o = spibench(&a, &[("RAYON_NUM_THREADS", "1")]);
                let what = format!("`spibench {}`", args.join(" "));
                judge_exit(&o, &out, &what, None, &mut exits, &mut failures);
            }
        }
    }
    // Mutated experiment files through `spibench simulate`: the same rules, and an exit-2
    // message that names the file.
    for i in 0..24u64 {
        let m = mutant(SMALL_EXPERIMENT, 900, i);
        let name = format!("exp{i}.ron");
        let file = dir.join(&name);
        std::fs::write(&file, &m).unwrap();
        let out = dir.join(&format!("out{n}"));
        n += 1;
        let o = spibench(
            &[
                "simulate",
                file.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[("RAYON_NUM_THREADS", "1")],
        );
        let what = format!("experiment mutant {i}");
        judge_exit(&o, &out, &what, Some(&name), &mut exits, &mut failures);
    }
    for e in std::fs::read_dir(&dir.0).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.contains("partial") || name.contains("spibench-lock") {
            failures.push(format!("{name} left behind"));
        }
    }
    eprintln!(
        "fuzz: {n} command lines, {} exit 0, {} exit 2",
        exits[0], exits[1]
    );
    assert!(exits[0] > 0 && exits[1] > 0, "{exits:?}");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Exit 0 with finite outputs, or exit 2 with a message (that names `names`, when given), no
/// panic and no output folder; anything else is a failure. Counts the exits 0 and 2.
fn judge_exit(
    o: &std::process::Output,
    out: &Path,
    what: &str,
    names: Option<&str>,
    exits: &mut [usize; 2],
    failures: &mut Vec<String>,
) {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    if let Some(c @ (0 | 2)) = o.status.code() {
        exits[c as usize / 2] += 1;
    }
    match o.status.code() {
        Some(0) => failures.extend(non_finite_outputs(out, what)),
        Some(2) => {
            let unnamed = names.is_some_and(|name| !err.contains(name));
            if err.contains("panicked") || err.trim().is_empty() || unnamed {
                failures.push(format!("{what}: exit 2 with {err:?}"));
            }
            if out.exists() {
                failures.push(format!("{what}: output left after exit 2"));
            }
        }
        other => failures.push(format!("{what}: exit {other:?}: {err}")),
    }
}

/// The input files of the mutated command lines, written in the test's folder.
struct ArgFiles {
    sym: String,
    tol: String,
    spec: String,
    patterns: String,
    measurements: String,
    experiment: String,
}

impl ArgFiles {
    fn new(dir: &TempDir) -> ArgFiles {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let sym = root.join("scenes/tests/symmetric_arms.ron");
        let sym = sym.to_str().unwrap();
        let paper = root.join("scenes/paper_bench.ron");
        std::fs::copy(&paper, dir.join("paper_bench.ron")).unwrap();
        let tol = dir.join("tol.ron");
        std::fs::write(
            &tol,
            "(tolerances: [(path: \"dmd.tilt_deg\", range: PlusMinus(0.5))])",
        )
        .unwrap();
        let spec = dir.join("spec.ron");
        std::fs::write(
            &spec,
            "Dataset(bench: \"paper_bench.ron\", kernel: (rays: 4096, seed: 1, grid_px: (8, 8), \
             field_mm: (7.88, 7.88)), objects: Phantom, seed: 7, samples: 2, shard_samples: 2)",
        )
        .unwrap();
        let (pp, yp) = (dir.join("p.npy"), dir.join("y.npy"));
        spibench::report::npy::write_u8(&pp, &[8, 16], &[1u8; 128]).unwrap();
        spibench::report::npy::write_f64(&yp, &[8], &[1.0; 8]).unwrap();
        let exp = dir.join("exp.ron");
        std::fs::write(&exp, SMALL_EXPERIMENT).unwrap();
        let path = |p: &Path| p.to_str().unwrap().to_string();
        ArgFiles {
            sym: sym.to_string(),
            tol: path(&tol),
            spec: path(&spec),
            patterns: path(&pp),
            measurements: path(&yp),
            experiment: path(&exp),
        }
    }
}

/// The command lines, each with the indices of its values that are mutated.
fn command_lines(f: &ArgFiles) -> Vec<(Vec<&str>, Vec<usize>)> {
    let (sym, tol, spec, pp, yp, exp) = (
        f.sym.as_str(),
        f.tol.as_str(),
        f.spec.as_str(),
        f.patterns.as_str(),
        f.measurements.as_str(),
        f.experiment.as_str(),
    );
    let free = "detectors.minus.decenter_mm.x=-2:2";
    vec![
        (
            vec!["trace", sym, "--rays", "2048", "--seed", "3"],
            vec![3, 5],
        ),
        (
            vec!["run", sym, "--rays", "2048", "--repeats", "1"],
            vec![3, 5],
        ),
        (
            vec![
                "sweep",
                sym,
                "--vary",
                "dmd.tilt_deg=11:12:2",
                "--rays",
                "2048",
            ],
            vec![3, 5],
        ),
        (
            vec![
                "tolerance",
                sym,
                "--tolerances",
                tol,
                "--trials",
                "1",
                "--rays",
                "2048",
                "--shard",
                "0/1",
            ],
            vec![5, 7, 9],
        ),
        (
            vec![
                "patterns",
                "--family",
                "random",
                "--units",
                "8x8",
                "--ratio",
                "0.5",
                "--mirrors-per-unit",
                "2",
                "--dmd",
                "64x64",
            ],
            vec![4, 6, 8, 10],
        ),
        (vec!["check", sym, "--wavelength-nm", "850"], vec![3]),
        (
            vec!["layout", sym, "--rays", "40", "--seed", "2"],
            vec![3, 5],
        ),
        (
            vec!["export-mitsuba", sym, "--wavelength-nm", "850"],
            vec![3],
        ),
        (vec!["dataset", spec, "--shard", "0/1"], vec![3]),
        (
            vec![
                "reconstruct",
                "--patterns",
                pp,
                "--measurements",
                yp,
                "--size",
                "4x4",
            ],
            vec![6],
        ),
        (vec!["--threads", "1", "check", sym], vec![1]),
        (
            vec![
                "align",
                sym,
                "--free",
                free,
                "--rays",
                "2048",
                "--start-rays",
                "2048",
                "--max-evaluations",
                "4",
                "--min-fraction",
                "0.9",
                "--offset-weight",
                "0.1",
                "--seed",
                "1",
            ],
            vec![3, 5, 7, 9, 11, 13, 15],
        ),
        (
            vec![
                "align",
                sym,
                "--free",
                free,
                "--objective",
                "weighted",
                "--weight",
                "imbalance=1",
                "--rays",
                "2048",
                "--max-evaluations",
                "4",
                "--set",
                "detectors.minus.decenter_mm.x=0.5",
            ],
            vec![5, 7, 13],
        ),
        (vec!["simulate", exp, "--zero-one", "plain"], vec![1, 3]),
    ]
}
