//! `spibench trace` end to end (its summary, maps and figures, the collection of a diffractive
//! bench), the one entrance for a bench (every command that reads one runs on the built-in
//! paper bench without SCENE and takes `--set`) and the one rule for the ray count.

use std::path::{Path, PathBuf};

use crate::common::{TempDir, read_json, spibench, stderr, stdout};

fn symmetric_arms() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron")
}

/// `trace` writes the summary, the EXR of ten channels and the map figures, and replaces them
/// when run again, leaving no staging folder.
#[test]
fn trace_writes_summary_maps_and_images() {
    let tmp = TempDir::new("cli-trace-ok");
    let out = tmp.join("out");
    let scene = symmetric_arms();
    let args = [
        "trace",
        scene.to_str().unwrap(),
        "--rays",
        "20000",
        "--seed",
        "3",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = spibench(&args, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = read_json(&out.join("summary.json"));
    // The summary card opens the terminal output, its numbers summary.json's.
    let card = spibench::outputs::trace::card(&v);
    card.check_against(&v).unwrap();
    assert!(
        stdout(&o).starts_with(&card.printed().join("\n")),
        "{}",
        stdout(&o)
    );
    for key in [
        "k_plus",
        "k_minus",
        "b_plus",
        "b_minus",
        "k_plus_stderr",
        "k_minus_stderr",
        "b_plus_stderr",
        "b_minus_stderr",
        "k_prime",
        "imbalance",
        "rays",
        "ledger",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["rays"], 20_000);
    assert!(v["k_plus"].as_f64().unwrap() > 0.0);
    assert!(
        v["ledger"]["all_plus"]["absorbed_w"]["dmd_gaps"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    for f in [
        "maps.exr",
        "x.png",
        "g_plus.png",
        "g_minus.png",
        "k_plus.png",
        "k_minus.png",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // The map is enlarged to a readable size, with its SVG beside it.
    let img = image::open(out.join("k_plus.png")).unwrap();
    assert!(img.width() >= 480 && img.height() >= 480);
    assert!(out.join("k_plus.svg").is_file());
    // The EXR holds the ten channels at 4 × 4: the maps and their standard errors.
    let exr = exr::prelude::read_all_data_from_file(out.join("maps.exr")).unwrap();
    let layer = &exr.layer_data[0];
    assert_eq!(layer.size, exr::prelude::Vec2(4, 4));
    assert_eq!(layer.channel_data.list.len(), 10);
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    for n in ["x_stderr_w", "g_plus_stderr_a", "g_minus_stderr_a"] {
        assert!(names.iter().any(|c| c == n), "{n} in {names:?}");
    }
    // Running again over an existing folder replaces the files and leaves no staging.
    let o = spibench(&args, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let leftovers: Vec<_> = std::fs::read_dir(&tmp.0)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(leftovers.is_empty());
}

/// A bench with the diffractive DMD model: `summary.json` gains `dmd_diffraction` (shares in
/// [0, 1], each arm collecting most of its own light with geometric mirrors) and the
/// collection figure is written.
#[test]
fn a_diffractive_bench_reports_the_collection() {
    let tmp = TempDir::new("cli-trace-diffractive");
    let text = std::fs::read_to_string(symmetric_arms())
        .unwrap()
        .replace("model: Geometric,", "model: Diffractive(),");
    let scene = tmp.join("bench.ron");
    std::fs::write(&scene, text).unwrap();
    let out = tmp.join("out");
    let o = spibench(
        &[
            "trace",
            scene.to_str().unwrap(),
            "--rays",
            "20000",
            "--seed",
            "3",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = read_json(&out.join("summary.json"));
    let d = &v["dmd_diffraction"];
    for model in ["geometric", "diffractive"] {
        for key in [
            "plus_from_plus",
            "minus_from_plus",
            "plus_from_minus",
            "minus_from_minus",
        ] {
            let s = d[model][key].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&s), "{model} {key}: {s}");
        }
    }
    assert!(d["geometric"]["plus_from_plus"].as_f64().unwrap() > 0.5);
    assert!(out.join("collection.png").is_file() && out.join("collection.pdf").is_file());
    assert!(stdout(&o).contains("DMD diffraction"), "{}", stdout(&o));
    // The lamp's light and the responsivity are shaded, with their scale on the right.
    let svg = std::fs::read_to_string(out.join("collection.svg")).unwrap();
    for label in [
        "lamp light on the pattern",
        "diode responsivity",
        "relative (peak = 1)",
        "arm + (diffractive)",
    ] {
        assert!(svg.contains(&format!(r#"aria-label="{label}""#)), "{label}");
    }
    assert!(svg.contains("<polygon"), "no filled area");
}

const BUILT_IN: &str = "<built-in scenes/paper_bench.ron>";
const MOVE: &str = "detectors.minus.decenter_mm.x=1.5";

/// `trace`, `check`, `layout` and `export-mitsuba` run without SCENE on the built-in paper
/// bench, name it, record its text in the provenance, and take `--set` as every other bench
/// command does.
#[test]
fn bench_commands_take_the_built_in_bench_and_set() {
    let tmp = TempDir::new("cli-built-in");
    let dir = |n: &str| tmp.join(n).to_str().unwrap().to_string();
    // check: the moved diode is where --set put it, 1.5 mm along x.
    let checks: Vec<serde_json::Value> = [None, Some(MOVE)]
        .iter()
        .enumerate()
        .map(|(k, set)| {
            let out = dir(&format!("check{k}"));
            let mut a = vec!["check", "--out", &out];
            if let Some(s) = set {
                a.extend(["--set", s]);
            }
            let o = spibench(&a, &[]);
            assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
            assert!(stdout(&o).starts_with(BUILT_IN), "{}", stdout(&o));
            read_json(&Path::new(&out).join("check.json"))
        })
        .collect();
    let pd_minus = |v: &serde_json::Value| {
        v["elements"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["name"] == "pd_minus")
            .map(|e| e["centre_m"][0].as_f64().unwrap())
            .unwrap()
    };
    let moved = pd_minus(&checks[1]) - pd_minus(&checks[0]);
    assert!(moved.abs() > 1e-4, "--set moved pd_minus by {moved} m");
    assert_eq!(checks[0]["scene"], BUILT_IN);
    // trace: the built-in bench in the summary and its provenance.
    let out = dir("trace");
    let o = spibench(
        &["trace", "--set", MOVE, "--rays", "4096", "--out", &out],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = read_json(&Path::new(&out).join("summary.json"));
    assert_eq!(v["scene"], BUILT_IN);
    assert_eq!(v["rays"], 4096);
    assert_eq!(v["provenance"]["inputs"][0]["path"], BUILT_IN);
    // layout and export-mitsuba.
    let out = dir("layout");
    let o = spibench(
        &["layout", "--set", MOVE, "--rays", "20", "--out", &out],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(Path::new(&out).join("layout.svg").is_file());
    let out = dir("export");
    let o = spibench(&["export-mitsuba", "--set", MOVE, "--out", &out], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = read_json(&Path::new(&out).join("summary.json"));
    assert_eq!(v["scene"], BUILT_IN);
    assert_eq!(v["provenance"]["inputs"][0]["path"], BUILT_IN);
    // A --set of a path the bench does not have is located as in every other command.
    for cmd in ["trace", "check", "layout", "export-mitsuba"] {
        let out = dir(&format!("bad-{cmd}"));
        let o = spibench(&[cmd, "--set", "nowhere.x_mm=1", "--out", &out], &[]);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {}", stderr(&o));
        assert!(stderr(&o).contains("nowhere"), "{cmd}: {}", stderr(&o));
        assert!(!Path::new(&out).exists());
    }
}

/// One rule for the ray count: `--rays`, else the bench file's `run.rays`, else the command's
/// default; `--help` says so.
#[test]
fn the_ray_count_is_the_flag_else_the_bench_file_s() {
    let tmp = TempDir::new("cli-rays-rule");
    let text = std::fs::read_to_string(symmetric_arms()).unwrap();
    let end = text.rfind(')').unwrap();
    let stated = format!("{}    run: (rays: 6144),\n)\n", &text[..end]);
    let scene = tmp.join("stated.ron");
    std::fs::write(&scene, stated).unwrap();
    let traced = |extra: &[&str], tag: &str| {
        let out = tmp.join(tag);
        let mut a = vec![
            "trace",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        let o = spibench(&a, &[]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        read_json(&out.join("summary.json"))["rays"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(traced(&[], "file"), 6144);
    assert_eq!(traced(&["--rays", "4096"], "flag"), 4096);
    for cmd in ["run", "trace", "sweep", "tolerance", "align"] {
        let o = spibench(&[cmd, "--help"], &[]);
        let help = stdout(&o);
        assert!(
            help.contains("default: the bench file's `run.rays`"),
            "{cmd} --help: {help}"
        );
    }
}
