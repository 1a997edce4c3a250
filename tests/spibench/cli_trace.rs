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

/// The symmetric-arms bench with a clear, unreflecting glass plate (`arm_plus_window`: index
/// 1.5, zero reflectance, no absorption) across the + arm 0.3 mm before its diode, as large
/// as the diode (Ø 5 mm), written as `window.ron` in `dir`. The + arm's light reaches the diode
/// through it once and nothing comes back (the diode ends every path it stops), so the plate's
/// map and the diode's map hold the same paths, bar a ray that crosses the plate's rim within
/// 0.3 mm·tan θ of the diode's edge.
fn windowed_arms(dir: &TempDir) -> PathBuf {
    // The + arm's axis (the lens's, θ 24°, φ −45°) and its diode's centre (mm).
    let (t, p) = (24f64.to_radians(), (-45f64).to_radians());
    let axis = [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
    let diode = [39.0011, -39.0011, 123.8823];
    let at = |s: f64| -> Vec<f64> { (0..3).map(|i| diode[i] - s * axis[i]).collect() };
    let front = at(0.3);
    let window = format!(
        r#"elements: [
        Filter(
            name: "arm_plus_window",
            position_mm: ({}, {}, {}),
            axis: Polar(theta_deg: 24.0, phi_deg: -45.0),
            outline: Round(diameter_mm: 5.0),
            thickness_mm: 0.1,
            glass: "1.5",
            od: Constant(0.0),
            coating: Reflectance(Constant(0.0)),
        ),"#,
        front[0], front[1], front[2]
    );
    let text = std::fs::read_to_string(symmetric_arms()).unwrap();
    assert!(text.contains("elements: ["));
    let scene = dir.join("window.ron");
    std::fs::write(&scene, text.replacen("elements: [", &window, 1)).unwrap();
    scene
}

/// `--irradiance-at NAME` maps the power crossing a named surface: a plate that the + arm's
/// light crosses once on its way to the diode holds the diode's detected power (the same
/// paths: equal to rounding, and in any case within 4 combined standard errors), in every
/// mirror state, with the files and summary keys of docs/outputs.md.
#[test]
fn a_surface_the_light_crosses_once_holds_the_diode_s_power() {
    let tmp = TempDir::new("cli-trace-irradiance-at");
    let scene = windowed_arms(&tmp);
    let out = tmp.join("out");
    let o = spibench(
        &[
            "trace",
            scene.to_str().unwrap(),
            "--rays",
            "20000",
            "--seed",
            "4",
            "--irradiance-at",
            "arm_plus_window",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    crate::outputs_schema::check_file(&out.join("summary.json"), "TraceSummary");
    let v = read_json(&out.join("summary.json"));
    let at = &v["irradiance_at"][0];
    assert_eq!(at["name"], "arm_plus_window");
    assert_eq!(v["irradiance_at"].as_array().unwrap().len(), 1);
    // The window: 10 % wider than the plate's 2.5 mm radius.
    let hw = at["half_width_m"].as_f64().unwrap();
    assert!((hw - 1.1 * 2.5e-3).abs() < 1e-12, "{hw}");
    for state in ["all_plus", "all_minus", "pattern_independent"] {
        let (a, b) = (&at[state], &v["irradiance"]["plus"][state]);
        let (pa, pb) = (
            a["power_w"].as_f64().unwrap(),
            b["active_w"].as_f64().unwrap(),
        );
        let (sa, sb) = (
            a["power_w_stderr"].as_f64().unwrap(),
            b["active_w_stderr"].as_f64().unwrap(),
        );
        assert!(
            (pa - pb).abs() <= 4.0 * sa.hypot(sb),
            "{state}: {pa} ± {sa} W at the plate, {pb} ± {sb} W on the diode"
        );
        // The same paths with the same weights: the sums differ by rounding only.
        assert!(
            (pa - pb).abs() <= 1e-9 * pb.abs(),
            "{state}: {pa} W at the plate, {pb} W on the diode"
        );
    }
    assert!(at["all_plus"]["power_w"].as_f64().unwrap() > 0.0);
    let listed: Vec<&str> = v["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    for f in [
        "irradiance_at_arm_plus_window.npy",
        "irradiance_at_arm_plus_window_stderr.npy",
        "irradiance_at_arm_plus_window.svg",
        "irradiance_at_arm_plus_window.png",
        "irradiance_at_arm_plus_window.pdf",
    ] {
        assert!(out.join(f).is_file(), "{f}");
        assert!(listed.contains(&f), "{f} not listed");
    }
    // The arrays have the diodes' layout: float64, (3, 64, 64).
    let npy = std::fs::read(out.join("irradiance_at_arm_plus_window.npy")).unwrap();
    let header = String::from_utf8_lossy(&npy[..128.min(npy.len())]).into_owned();
    assert!(
        header.contains("'<f8'") && header.contains("(3, 64, 64)"),
        "{header}"
    );
    assert_eq!(
        npy.len(),
        std::fs::read(out.join("irradiance_plus.npy"))
            .unwrap()
            .len()
    );
}

/// The named surfaces' maps are bit-identical on one and two threads.
#[test]
fn surface_maps_are_identical_on_one_and_two_threads() {
    let tmp = TempDir::new("cli-trace-irradiance-at-threads");
    let scene = symmetric_arms();
    let run = |threads: &str| {
        let out = tmp.join(&format!("t{threads}"));
        let o = spibench(
            &[
                "--threads",
                threads,
                "trace",
                scene.to_str().unwrap(),
                "--rays",
                "8192",
                "--seed",
                "5",
                "--irradiance-at",
                "arm_plus_lens",
                "--irradiance-at",
                "arm_minus_lens",
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        out
    };
    let (one, two) = (run("1"), run("2"));
    for stem in ["arm_plus_lens", "arm_minus_lens"] {
        for f in [
            format!("irradiance_at_{stem}.npy"),
            format!("irradiance_at_{stem}_stderr.npy"),
        ] {
            let a = std::fs::read(one.join(&f)).unwrap();
            assert!(a.len() > 128, "{f}");
            assert_eq!(a, std::fs::read(two.join(&f)).unwrap(), "{f}");
        }
    }
}

/// An unknown name, or two names written to one file, is refused before a ray is traced:
/// exit status 2, the flag and the bench's element names in the message, nothing written.
#[test]
fn an_unknown_surface_is_refused_naming_the_flag() {
    let tmp = TempDir::new("cli-trace-irradiance-at-bad");
    let scene = symmetric_arms();
    let out = tmp.join("out");
    let run = |names: &[&str]| {
        let mut a = vec!["trace", scene.to_str().unwrap(), "--rays", "4096"];
        for n in names {
            a.extend(["--irradiance-at", n]);
        }
        a.extend(["--out", out.to_str().unwrap()]);
        spibench(&a, &[])
    };
    let o = run(&["no_such_baffle"]);
    crate::common::assert_input_error(
        &o,
        &[
            "--irradiance-at",
            "no_such_baffle",
            "arm_plus_lens",
            "arm_minus_lens",
        ],
        &out,
    );
    let o = run(&["arm_plus_lens", "arm_plus lens"]);
    crate::common::assert_input_error(
        &o,
        &["--irradiance-at", "irradiance_at_arm_plus_lens.npy"],
        &out,
    );
    let o = run(&["arm_plus_lens", "arm_plus_lens"]);
    crate::common::assert_input_error(&o, &["--irradiance-at", "twice"], &out);
}
