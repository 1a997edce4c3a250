//! `spibench run` end to end on a small variant of the paper's bench (16 × 16 units, few rays):
//! every output, determinism across thread counts, saturation reporting, bad input.

use std::path::{Path, PathBuf};

use crate::common::*;

/// The paper bench as 16 × 16 units of 36 × 36 mirrors with a short run section, plus edits.
fn small_scene(dir: &TempDir, name: &str, run: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut t = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/paper_bench.ron"
    ))
    .unwrap();
    let mut all = vec![(
        "units_across: 48, units_down: 48, mirrors_per_unit: 12",
        "units_across: 16, units_down: 16, mirrors_per_unit: 36",
    )];
    all.extend_from_slice(edits);
    for (a, b) in all {
        assert_eq!(t.matches(a).count(), 1, "{a}");
        t = t.replace(a, b);
    }
    let end = t.rfind(')').unwrap();
    let t = format!("{}    run: ({run}),\n)\n", &t[..end]);
    let p = dir.join(name);
    std::fs::write(&p, t).unwrap();
    p
}

const RUN: &str = "rays: 30000, sampling_ratios: [0.25, 1.0], signal_trace_frames: 3";

fn run_to(scene: &Path, out: &Path, threads: &str) -> std::process::Output {
    spibench(
        &[
            "run",
            "--repeats",
            "1",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--seed",
            "4",
        ],
        &[("RAYON_NUM_THREADS", threads)],
    )
}

/// summary.json without its timings and the command line of its provenance (the two runs
/// compared here write to different folders; a rerun of one command is byte-identical, see
/// output_dirs).
fn without_timings(mut v: serde_json::Value) -> serde_json::Value {
    v.as_object_mut().unwrap().remove("timings");
    if let Some(p) = v.get_mut("provenance").and_then(|p| p.as_object_mut()) {
        p.remove("command");
    }
    for r in v["results"].as_array_mut().unwrap() {
        r.as_object_mut().unwrap().remove("solver_time_s");
    }
    v
}

#[test]
fn run_writes_every_output_identically_on_one_and_two_threads() {
    let dir = TempDir::new("run-ok");
    let scene = small_scene(&dir, "small.ron", RUN, &[]);
    let (a, b) = (dir.join("one"), dir.join("two"));
    let oa = run_to(&scene, &a, "1");
    assert!(oa.status.success(), "{}", stderr(&oa));
    let ob = run_to(&scene, &b, "2");
    assert!(ob.status.success(), "{}", stderr(&ob));
    let files = expected_run_files();
    for f in &files {
        assert!(a.join(f).is_file(), "missing {f}");
    }
    // With --repeats 1, no repeat statistics (one repeat has no spread).
    for f in ["repeats.json", "repeats.csv", "mssim_vs_frames.svg"] {
        assert!(!a.join(f).exists(), "{f} written with --repeats 1");
    }
    assert_report_page(&a.join("report.html"));
    let sa = read_json(&a.join("summary.json"));
    let e = &sa["electronics"];
    assert!(
        e["cmrr_db"].is_number() && e["cmrr_electronics_db"].is_number(),
        "{e}"
    );
    assert_ne!(e["cmrr_db"], e["cmrr_electronics_db"], "{e}");
    let sb = read_json(&b.join("summary.json"));
    assert_eq!(without_timings(sa.clone()), without_timings(sb));
    // Same seed: results.csv byte-identical (summary.json too but for the command line, above);
    // the timings are in timings.json.
    let same = std::fs::read(a.join("results.csv")).unwrap()
        == std::fs::read(b.join("results.csv")).unwrap();
    assert!(same, "results.csv differs between two runs with one seed");
    assert!(read_json(&a.join("timings.json"))["total_s"].is_number());
    // The same command again (on two threads) replaces the folder with a byte-identical
    // summary.json and results.csv: provenance included, timings apart.
    let kept: Vec<Vec<u8>> = ["summary.json", "results.csv"]
        .iter()
        .map(|f| std::fs::read(a.join(f)).unwrap())
        .collect();
    let again = run_to(&scene, &a, "2");
    assert!(again.status.success(), "{}", stderr(&again));
    for (f, before) in ["summary.json", "results.csv"].iter().zip(&kept) {
        assert!(
            &std::fs::read(a.join(f)).unwrap() == before,
            "{f} differs between two runs of one command"
        );
    }
    assert_documented_keys(&sa);
    let out = stdout(&oa);
    // The summary card opens the terminal output and the report, and its numbers are
    // summary.json's.
    let card = spibench::outputs::run::card::card(&sa);
    card.check_against(&sa).unwrap();
    let printed = card.printed();
    assert!(out.starts_with(&printed.join("\n")), "{out}");
    assert!(printed.iter().any(|l| l.contains("imbalance, electrical")));
    assert!(printed.iter().any(|l| l.contains("MSSIM at 25 %")));
    let html = std::fs::read_to_string(a.join("report.html")).unwrap();
    let first_card = html
        .find("<section class=\"card\">")
        .expect("a card in the report");
    assert!(first_card < html.find("<h2 id=").unwrap_or(usize::MAX));
    for line in &card.lines {
        let v = line.sources[0].1.as_f64();
        if let Some(v) = v.filter(|v| v.is_finite()) {
            assert!(v == sa.pointer(&line.sources[0].0).unwrap().as_f64().unwrap());
        }
    }
    assert!(html.contains("<details>"), "long explanations are folded");
    assert!(out.contains("Secondary complementary balancing"), "{out}");
    // The report's table and notes fit a terminal of 100 columns (paths aside).
    for l in out.lines().filter(|l| l.starts_with("  ")) {
        assert!(
            l.chars().count() <= 100,
            "{} columns: {l}",
            l.chars().count()
        );
    }
    let sa = without_timings(sa);
    assert_other_seed_and_settings(&scene, &dir, &a, &sa);
    // results.csv: LF only, one row per result, the run-identifying columns filled in.
    let csv = std::fs::read_to_string(a.join("results.csv")).unwrap();
    assert!(!csv.contains('\r'));
    assert_eq!(csv.lines().count(), 15, "a header and 14 rows");
    assert!(csv.starts_with("command,scene,seed,"), "{csv}");
}

/// Every file `spibench run` writes for the small scene (schemes at 25 and 100 %).
fn expected_run_files() -> Vec<String> {
    let mut files = vec![
        "summary.json".to_string(),
        "report.html".to_string(),
        "results.csv".to_string(),
        "montage.png".to_string(),
        "montage.svg".to_string(),
        "images/x.png".to_string(),
        "bench.ron".to_string(),
    ];
    for stem in [
        "mssim_vs_ratio",
        "psnr_vs_ratio",
        "signals_base",
        "signals_complementary",
    ] {
        files.push(format!("{stem}.svg"));
        files.push(format!("{stem}.png"));
        files.push(format!("{stem}.pdf"));
    }
    for scheme in [
        "traditional",
        "single_arm_complementary",
        "double_arm",
        "secondary_complementary_balancing",
    ] {
        for r in ["0.250", "1.000"] {
            files.push(format!("images/{scheme}__r{r}.png"));
        }
    }
    // The raw arrays (src/outputs/run/arrays.rs).
    for f in [
        "transport_x_w",
        "patterns_packed",
        "measurements_double_arm_r0.2500_v",
        "reconstruction_double_arm_r0.2500",
    ] {
        files.push(format!("arrays/{f}.npy"));
    }
    files
}

/// report.html: one self-contained page whose images are all embedded, with its sections, the
/// solver's stops and both CMRRs.
fn assert_report_page(page: &Path) {
    let html = std::fs::read_to_string(page).expect("report.html");
    assert!(
        html.starts_with("<!DOCTYPE html>"),
        "report.html is not an HTML page"
    );
    for absent in ["http://", "https://", "<script", "<link"] {
        assert!(!html.contains(absent), "report.html contains {absent}");
    }
    assert!(
        html.matches("src=\"data:image/").count() >= 6,
        "embedded images missing"
    );
    for section in ["Flux ledger", "Signals", "Reconstructions", "Settings"] {
        assert!(html.contains(section), "report.html lacks {section}");
    }
    // Each solve says what stopped it (not a bare "(cap)" after fewer iterations than the cap),
    // and the bench's CMRR with the arms stands beside the electronics' alone.
    assert!(!html.contains("(cap)"), "report.html still says (cap)");
    assert!(html.contains("TVAL3&#39;s stops:"));
    assert!(html.contains("CMRR of the bench") && html.contains("CMRR of the electronics alone"));
}

/// The documented keys of summary.json and the frame counts at 100 %.
fn assert_documented_keys(sa: &serde_json::Value) {
    assert_eq!(sa["command"], "run");
    for key in [
        "k_plus",
        "k_minus",
        "b_plus",
        "b_minus",
        "k_prime",
        "imbalance",
        "ledger",
    ] {
        assert!(sa["transport"].get(key).is_some(), "transport.{key}");
    }
    assert!(sa["transport"].get("k_plus_stderr").is_some());
    assert_eq!(sa["electronics"]["detector"]["rf"]["gain_v_per_a"], 350e3);
    assert_eq!(sa["saturated"], false);
    let results = sa["results"].as_array().unwrap();
    assert_eq!(results.len(), 14, "seven schemes × two ratios");
    for r in results {
        for key in [
            "scheme",
            "ratio",
            "psnr_db",
            "mssim",
            "dmd_frames",
            "acquisition_time_s",
            "iterations",
        ] {
            assert!(r.get(key).is_some(), "results[].{key}");
        }
    }
    // 100 % of 256 units: SCB shows 512 frames, double-arm 256.
    let frames = |scheme: &str| {
        results
            .iter()
            .find(|r| r["scheme"] == scheme && r["ratio"] == 1.0)
            .unwrap()["dmd_frames"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(frames("secondary_complementary_balancing"), 512);
    assert_eq!(frames("double_arm"), 256);
}

/// Another seed gives other noise; the folder's bench.ron reproduces the run (seed 4, like
/// `run_to`) on one thread: the same transport and results. `sa` is the first run's summary
/// without timings.
fn assert_other_seed_and_settings(scene: &Path, dir: &TempDir, a: &Path, sa: &serde_json::Value) {
    // A different seed gives different noise.
    let c = dir.join("three");
    let oc = spibench(
        &[
            "run",
            "--repeats",
            "1",
            scene.to_str().unwrap(),
            "--out",
            c.to_str().unwrap(),
            "--seed",
            "5",
        ],
        &[],
    );
    assert!(oc.status.success(), "{}", stderr(&oc));
    assert_ne!(
        without_timings(read_json(&c.join("summary.json")))["results"],
        sa["results"]
    );
    // The page's settings (bench.ron) reproduce the run: the same transport and results.
    let d = dir.join("again");
    let od = spibench(
        &[
            "run",
            "--repeats",
            "1",
            a.join("bench.ron").to_str().unwrap(),
            "--out",
            d.to_str().unwrap(),
            "--seed",
            "4",
        ],
        &[("RAYON_NUM_THREADS", "1")],
    );
    assert!(od.status.success(), "{}", stderr(&od));
    let sd = without_timings(read_json(&d.join("summary.json")));
    assert_eq!(sd["results"], sa["results"]);
    assert_eq!(sd["transport"]["k_plus"], sa["transport"]["k_plus"]);
}

#[test]
fn run_reports_saturation() {
    let dir = TempDir::new("run-sat");
    // A 1 kW lamp: about a thousand times the default light.
    let scene = small_scene(
        &dir,
        "bright.ron",
        "rays: 30000, sampling_ratios: [0.5], schemes: [SecondaryComplementaryBalancing]",
        &[("power: FromFilament,", "power: InBand(watts: 1000.0),")],
    );
    let out = dir.join("out");
    let o = run_to(&scene, &out, "2");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("SATURATION"), "{}", stderr(&o));
    let s = read_json(&out.join("summary.json"));
    assert_eq!(s["saturated"], true);
    let sat = s["saturation"].as_array().unwrap();
    assert!(
        sat.iter()
            .any(|x| x["output"] == "rf" && x["kind"] == "detector_swing")
    );
    assert_eq!(s["results"][0]["saturated"], true);
}

#[test]
fn run_rejects_bad_input_with_file_line_and_field() {
    let dir = TempDir::new("run-bad");
    let scene = small_scene(&dir, "typo.ron", "rays: 2048, sampling_ratio: [0.5]", &[]);
    let out = dir.join("out");
    let o = run_to(&scene, &out, "2");
    assert_input_error(&o, &["typo.ron", "line", "sampling_ratio"], &out);

    let scene = small_scene(&dir, "slow.ron", "rays: 2048, settling_time_us: 60.0", &[]);
    let o = run_to(&scene, &out, "2");
    assert_input_error(&o, &["slow.ron", "line", "settling_time_us"], &out);

    let o = run_to(&dir.join("missing.ron"), &out, "2");
    assert_input_error(&o, &["missing.ron"], &out);
}

/// With exactly matched diodes (the symmetric test bench's − diode at 1.0) the electronics'
/// CMRR is unbounded: the terminal says so in words, never "inf", and summary.json writes null
/// for it, while the bench's CMRR (the traced arms' imbalance is not exactly zero) stays a
/// number.
#[test]
fn run_says_an_unbounded_cmrr_in_words() {
    let dir = TempDir::new("run-cmrr");
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/tests/symmetric_arms.ron"
    ))
    .unwrap();
    let mismatched = "responsivity_scale_minus: 0.999";
    assert_eq!(text.matches(mismatched).count(), 1, "{mismatched}");
    // 16 × 16 units of 2 × 2 mirrors: SSIM's window needs 11 × 11 pixels at the least.
    let units = "units_across: 4, units_down: 4, mirrors_per_unit: 8";
    assert_eq!(text.matches(units).count(), 1, "{units}");
    let text = text
        .replace(mismatched, "responsivity_scale_minus: 1.0")
        .replace(
            units,
            "units_across: 16, units_down: 16, mirrors_per_unit: 2",
        );
    let end = text.rfind(')').unwrap();
    let text = format!(
        "{}    run: (rays: 30000, sampling_ratios: [0.5], schemes: \
         [SecondaryComplementaryBalancing], signal_trace_frames: 3),\n)\n",
        &text[..end]
    );
    let scene = dir.join("matched.ron");
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out");
    let o = run_to(&scene, &out, "2");
    assert!(o.status.success(), "{}", stderr(&o));
    let printed = stdout(&o);
    // No "inf", "-inf", "infinite" or "infinity" as a word (words such as "information" may
    // appear in the findings).
    let infinite = printed
        .split(|c: char| !c.is_alphanumeric())
        .any(|w| ["inf", "infinite", "infinity"].contains(&w.to_lowercase().as_str()));
    assert!(!infinite, "{printed}");
    assert!(
        printed.contains("electronics alone unbounded")
            && printed.contains("finite CMRR is not modelled"),
        "{printed}"
    );
    let s = read_json(&out.join("summary.json"));
    assert!(
        s["electronics"]["cmrr_electronics_db"].is_null(),
        "{}",
        s["electronics"]
    );
    assert!(s["electronics"]["cmrr_db"].is_f64(), "{}", s["electronics"]);
}
