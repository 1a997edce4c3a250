//! `spibench layout` and `spibench check` end to end: every shipped bench draws, its SVG is
//! well-formed XML with three views and the rays of every fate its fan has; `check` of the paper
//! bench gives the closed-form focal length, the 1:1 chart → DMD magnification and the pattern
//! size on the chart; a broken bench is located.

use std::path::{Path, PathBuf};

use spibench::optics::glass::N_BK7;
use spibench::trace::fan::{Fate, ray_fan};

use crate::common::{TempDir, assert_input_error, read_json, spibench, stderr, stdout};

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// The `*.ron` files of `scenes/` that parse as benches (the rest are experiment files).
fn shipped_benches() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(scenes())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .filter(|p| spibench::scene::bench::read_bench(p).is_ok())
        .collect();
    v.sort();
    v
}

#[test]
fn the_shipped_benches_are_the_paper_benches_and_fig8() {
    let names: Vec<String> = shipped_benches()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "fig8_region_b_48.ron",
            "fig8_region_b_96.ron",
            "fig8_region_c_96.ron",
            "paper_bench.ron",
            "paper_bench_condenser.ron"
        ]
    );
}

/// Every shipped bench draws; the SVG parses as XML, has the three views, and in each view one
/// path per fan ray of every fate that occurs (the fan is recomputed here with the same seed:
/// it is deterministic); the paper bench's fan lights both arms. The PNG has the SVG's size.
#[test]
fn layout_of_every_shipped_bench() {
    let tmp = TempDir::new("cli-layout");
    let rays = 160;
    for (k, scene) in shipped_benches().iter().enumerate() {
        let out = tmp.join(&format!("layout-{k}"));
        let o = spibench(
            &[
                "layout",
                scene.to_str().unwrap(),
                "--rays",
                &rays.to_string(),
                "--seed",
                "3",
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(stdout(&o).contains("layout.svg"));
        let text = std::fs::read_to_string(out.join("layout.svg")).unwrap();
        let doc = roxmltree::Document::parse(&text).expect("well-formed SVG");
        let class = |n: &roxmltree::Node| n.attribute("class").unwrap_or("").to_string();
        let views: Vec<_> = doc
            .descendants()
            .filter(|n| n.has_tag_name("g") && class(n) == "view")
            .collect();
        let ids: Vec<&str> = views.iter().filter_map(|v| v.attribute("id")).collect();
        assert_eq!(ids, ["view-top", "view-side", "view-arms"]);

        let bench = spibench::scene::bench::read_bench(scene).unwrap();
        let fan = ray_fan(&bench, rays, 3).unwrap();
        let counts = fan.counts();
        for v in &views {
            for (i, fate) in Fate::ALL.iter().enumerate() {
                let drawn = v
                    .descendants()
                    .filter(|n| n.has_tag_name("path") && class(n) == format!("ray {}", fate.key()))
                    .count();
                assert_eq!(drawn, counts[i], "{} {:?}", scene.display(), fate);
            }
            let outlines = v
                .descendants()
                .filter(|n| class(n).starts_with("element "))
                .count();
            assert!(outlines >= 10, "{outlines} outlines");
        }
        assert!(counts[0] > 0 && counts[1] > 0, "both arms lit: {counts:?}");
        // The PNG is the SVG at 288 dpi: 2 px per unit of its viewBox (half points).
        let png = image::open(out.join("layout.png")).unwrap();
        let svg = doc.root_element();
        let vb_w: f64 = svg
            .attribute("viewBox")
            .unwrap()
            .split(' ')
            .nth(2)
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(f64::from(png.width()), 2.0 * vb_w, "PNG size");
        assert_eq!(svg.attribute("width"), Some("7.2014in"));
        assert!(out.join("layout.pdf").is_file());
    }
}

/// `check` of the paper bench: the imaging lens (LA1050, R = 51.5 mm plano-convex, N-BK7)
/// has f = R/(n − 1) at 850 nm (the thick-lens formula for a flat back face, exact), the
/// chart → DMD magnification is −1 to 0.1 % (the scene places the chart at 2f for
/// n(850 nm) = 1.50984, given to 5 decimals: the residual is ~1e-5), and the pattern on the
/// chart is the 576 × 13.68 µm pattern on the DMD divided by |m|. Without `--out` nothing is
/// written; the printed f matches.
#[test]
fn check_of_the_paper_bench() {
    let tmp = TempDir::new("cli-check");
    let scene = scenes().join("paper_bench.ron");
    let out = tmp.join("check");
    let o = spibench(
        &[
            "check",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    crate::outputs_schema::check_file(&out.join("check.json"), "CheckJson");
    let v = read_json(&out.join("check.json"));
    assert_eq!(v["design_wavelength_m"].as_f64().unwrap(), 850e-9);
    let n = N_BK7.index(850e-9);
    let f = 0.0515 / (n - 1.0);
    let lens = v["lenses"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l["name"] == "imaging_lens")
        .unwrap();
    let got = lens["focal_length_m"].as_f64().unwrap();
    assert!((got - f).abs() < 1e-12 * f, "{got} vs {f}");
    assert!(lens["object"].as_str().unwrap().contains("chart"));
    assert!(
        stdout(&o).contains(&format!("f = {:.3} mm", f * 1e3)),
        "{}",
        stdout(&o)
    );
    let m = v["chart_to_dmd_magnification"].as_f64().unwrap();
    assert!((m + 1.0).abs() < 1e-3, "m = {m}");
    let dmd = v["pattern_on_dmd_m"].as_array().unwrap();
    let chart = v["pattern_on_chart_m"].as_array().unwrap();
    for k in 0..2 {
        let d = dmd[k].as_f64().unwrap();
        assert!((d - 576.0 * 13.68e-6).abs() < 1e-15);
        assert!((chart[k].as_f64().unwrap() - d / m.abs()).abs() < 1e-15);
    }
    for d in v["diodes"].as_array().unwrap() {
        assert!(d["numerical_aperture"].as_f64().unwrap() > 0.0, "{d}");
    }
    // The pose is the file's (the collimator's vertex at (0, 0, 520) mm), not the mean of its
    // outline points (which sat at x = 0.272, z = 517.34 mm).
    let c = v["elements"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == "collimator")
        .unwrap();
    assert_eq!(c["position_m"], serde_json::json!([0.0, 0.0, 0.52]), "{c}");
    let line = stdout(&o)
        .lines()
        .find(|l| l.trim_start().starts_with("collimator"))
        .unwrap()
        .to_string();
    assert!(
        line.contains("position (0.000, 0.000, 520.000) mm"),
        "{line}"
    );
    // Without --out: the same report, no files.
    let before: Vec<_> = std::fs::read_dir(&tmp.0).unwrap().flatten().collect();
    let o = spibench(&["check", scene.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(0));
    let after: Vec<_> = std::fs::read_dir(&tmp.0).unwrap().flatten().collect();
    assert_eq!(before.len(), after.len());
}

/// A broken bench (a lens with a negative diameter on a known line): `check` and `layout` exit
/// with status 2, name the file, the line and the field, and write nothing.
#[test]
fn check_and_layout_of_a_broken_bench() {
    let tmp = TempDir::new("cli-check-bad");
    let text = std::fs::read_to_string(scenes().join("paper_bench.ron")).unwrap();
    let from = "            clear_diameter_mm: 45.72,\n            glass: \"N-BK7\",\n            // -A coating";
    assert_eq!(text.matches(from).count(), 1);
    let bad = text.replacen(from, &from.replace("45.72", "-45.72"), 1);
    let line = bad[..bad.find("-45.72").unwrap()].matches('\n').count() + 1;
    let scene = tmp.join("broken_bench.ron");
    std::fs::write(&scene, bad).unwrap();
    let out = tmp.join("out");
    for cmd in ["check", "layout"] {
        let o = spibench(
            &[cmd, scene.to_str().unwrap(), "--out", out.to_str().unwrap()],
            &[],
        );
        assert_input_error(
            &o,
            &[
                "broken_bench.ron",
                &format!("line {line}"),
                "clear_diameter_mm",
            ],
            &out,
        );
    }
}

/// The + diode of scenes/tests/check_footprint.ron moved 0.8 mm along its own x, so that its
/// chief ray and its light land off the active area's centre.
const MOVED: &str = "detectors.plus.decenter_mm.x=0.8";

/// Standard errors a centroid may lie from the chief ray: the replicas' standard error has 7
/// degrees of freedom, and |t₇| > 5 has probability 0.0016 per coordinate.
const CENTROID_SE: f64 = 5.0;

/// What the paraxial chief ray leaves out (m): the arm lens's aberrations with the DMD's
/// keystoned aperture (the DMD lies tilted to the arm). They widen the 2√2·RMS diameter of
/// the image from the paraxial 0.922 mm (m = −0.461 of the 2 mm disk) to 0.931 mm, 4 µm of it
/// the binning's bin²/6; at 819 200 rays the centroids sit 1.4 ± 0.2 µm from the chief ray, in
/// the plane of the arm. 10 µm holds that blur's scale with margin, a hundredth of the 0.8 mm
/// move.
const ABERRATION_M: f64 = 10e-6;

/// `check`'s traced footprint on scenes/tests/check_footprint.ron (each LA1131 images the
/// lamp's 2 mm disk onto its diode; 12 mm housings), with the + diode moved off the beam:
/// `check.json` names the DMD model, is the same on one and two threads, and each diode's
/// traced centroid lies inside the active area and on the paraxial chief ray, within
/// `CENTROID_SE` of its standard errors plus half a map bin (the binning) plus `ABERRATION_M`
/// (see there). The moved diode's footprint moves with it. `--footprint-rays 0` traces
/// nothing; too few rays are refused by the flag.
#[test]
fn check_traces_the_footprint_beside_the_paraxial_beam() {
    let tmp = TempDir::new("cli-check-footprint");
    let scene = scenes().join("tests/check_footprint.ron");
    let scene = scene.to_str().unwrap();
    let run = |threads: &str, out: &Path, rays: &str| {
        spibench(
            &[
                "--threads",
                threads,
                "check",
                scene,
                "--set",
                MOVED,
                "--footprint-rays",
                rays,
                "--seed",
                "3",
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        )
    };
    let (one, two) = (tmp.join("one"), tmp.join("two"));
    let o = run("1", &one, "16384");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o2 = run("2", &two, "16384");
    assert_eq!(o2.status.code(), Some(0), "{}", stderr(&o2));
    let text = std::fs::read_to_string(one.join("check.json")).unwrap();
    assert_eq!(
        text,
        std::fs::read_to_string(two.join("check.json")).unwrap()
    );
    assert_eq!(stdout(&o), stdout(&o2));
    crate::outputs_schema::check_file(&one.join("check.json"), "CheckJson");
    let v = read_json(&one.join("check.json"));
    assert_eq!(v["dmd_model"], "geometric");
    assert_eq!(stdout(&o).lines().nth(1), Some("DMD model: geometric"));
    let f = &v["footprint"];
    assert_eq!(f["rays"], 16384);
    assert_eq!(f["seed"], 3);
    let radius = v["diodes"][0]["diameter_m"].as_f64().unwrap() / 2.0;
    for (k, d) in f["diodes"].as_array().unwrap().iter().enumerate() {
        let num = |key: &str, i: usize| d[key][i].as_f64().unwrap();
        let (c, chief) = (
            [num("centroid_m", 0), num("centroid_m", 1)],
            [
                num("chief_ray_on_diode_m", 0),
                num("chief_ray_on_diode_m", 1),
            ],
        );
        assert!(c[0].hypot(c[1]) < radius, "{d}");
        let bin = d["bin_m"].as_f64().unwrap();
        for i in 0..2 {
            let se = num("centroid_stderr_m", i);
            assert!(se > 0.0, "{d}");
            let tol = CENTROID_SE * se + 0.5 * bin + ABERRATION_M;
            assert!(
                (c[i] - chief[i]).abs() < tol,
                "{}: centroid {} against the chief ray {} ± {tol} m",
                d["name"],
                c[i],
                chief[i]
            );
        }
        // The moved diode: its chief ray (and so the light) 0.8 mm off the centre.
        let off = chief[0].hypot(chief[1]);
        if k == 0 {
            assert!((off - 0.8e-3).abs() < 1e-5, "{d}");
        } else {
            assert!(off < 1e-5, "{d}");
        }
        // The image lies 1.6 mm inside the active edge: what reaches the plate is stray light
        // (lens ghosts; 1e-4 at 819 200 rays).
        let spill = d["spill"].as_f64().unwrap();
        assert!((0.0..0.01).contains(&spill), "{d}");
    }
    assert!(stdout(&o).contains("paraxial chief ray"), "{}", stdout(&o));
    // No footprint: nothing traced, said so.
    let none = tmp.join("none");
    let o = run("1", &none, "0");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(read_json(&none.join("check.json"))["footprint"].is_null());
    assert!(
        stdout(&o).contains("traced footprint: not traced"),
        "{}",
        stdout(&o)
    );
    // Too few rays: refused by the flag, nothing written.
    let bad = tmp.join("bad");
    let o = run("1", &bad, "100");
    assert_input_error(&o, &["--footprint-rays", "2048"], &bad);
}

/// `layout --irradiance-rays N` draws the two diodes' maps as insets under the views (one
/// group each, a heatmap inside, a caption naming the spill and centroid with their errors),
/// bit-identically on one and two threads; without the flag the drawing has none. The printed
/// lines give each diode's spill and centroid.
#[test]
fn layout_with_irradiance_insets() {
    let tmp = TempDir::new("cli-layout-insets");
    let draw = |threads: &str, extra: &[&str], name: &str| {
        let out = tmp.join(name);
        let mut args = vec!["layout", "--rays", "40", "--seed", "5"];
        args.extend(extra);
        args.extend(["--out", out.to_str().unwrap()]);
        let o = spibench(&args, &[("RAYON_NUM_THREADS", threads)]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        (
            std::fs::read_to_string(out.join("layout.svg")).unwrap(),
            stdout(&o),
        )
    };
    let flag = ["--irradiance-rays", "8192"];
    let (one, printed) = draw("1", &flag, "one");
    let (two, _) = draw("2", &flag, "two");
    assert!(one == two, "the insets differ between one and two threads");
    let doc = roxmltree::Document::parse(&one).expect("well-formed SVG");
    let insets: Vec<_> = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("irradiance-inset"))
        .collect();
    let ids: Vec<&str> = insets.iter().filter_map(|n| n.attribute("id")).collect();
    assert_eq!(ids, ["inset-minus", "inset-plus"]);
    for g in &insets {
        // The heatmap is embedded as its own <svg>; the caption's text is kept as aria-label.
        assert!(g.descendants().any(|n| n.has_tag_name("svg")));
        let text: Vec<&str> = g
            .descendants()
            .filter_map(|n| n.attribute("aria-label"))
            .collect();
        let all = text.join("\n");
        for f in [
            "W/m²",
            "spill (front plate ÷ map)",
            "centroid (u, v)",
            " ± ",
            "mm",
        ] {
            assert!(all.contains(f), "{f:?} missing from {all}");
        }
    }
    // The three views are still the only views.
    let views = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("view"))
        .count();
    assert_eq!(views, 3);
    for d in [
        "pd_plus, all units +: spill",
        "pd_minus, all units −: spill",
    ] {
        assert!(printed.contains(d), "{printed}");
    }
    let (plain, _) = draw("2", &[], "plain");
    assert!(!plain.contains("irradiance-inset"));
}

/// A ray count below two batches or above the trace's limit is refused with exit status 2,
/// naming the flag, and nothing is written.
#[test]
fn layout_refuses_absurd_irradiance_rays() {
    let tmp = TempDir::new("cli-layout-insets-bad");
    for n in ["5", "100000000000"] {
        let out = tmp.join("out");
        let o = out.to_str().unwrap();
        let args = ["layout", "--irradiance-rays", n, "--out", o];
        assert_input_error(&spibench(&args, &[]), &["--irradiance-rays", n], &out);
    }
}
