//! `spibench lens` end to end: the shipped parts' summaries (schema of docs/outputs.md, the
//! reference EFL of validation/lenses/), the drawing, and every bad prescription an input error
//! with exit status 2 and nothing written.

use std::path::{Path, PathBuf};

use crate::common::{TempDir, assert_input_error, read_json, spibench, stderr, stdout};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

#[test]
fn lens_reports_a_shipped_part_with_its_fan_and_drawing() {
    let tmp = TempDir::new("cli-lens");
    let out = tmp.join("ac254");
    let file = root().join("scenes/parts/thorlabs_ac254-100-b.zmx");
    let o = spibench(
        &[
            "lens",
            file.to_str().unwrap(),
            "--wavelength-nm",
            "587.5618",
            "--heights-mm",
            "1.27,3.81,11.43",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("EFL 100.233958 mm"), "{text}");
    crate::outputs_schema::check_file(&out.join("summary.json"), "LensSummary");
    let s = read_json(&out.join("summary.json"));
    // rayoptics and optiland (validation/lenses/reference.json): EFL 100.23395751877341 mm, the
    // ray at 1.27 mm meets the image plane at y = 0.0024241943402976904 mm.
    assert!((s["efl_mm"].as_f64().unwrap() - 100.233_957_518_773_41).abs() < 1e-6);
    assert!((s["rays"][0]["y_mm"].as_f64().unwrap() - 0.002_424_194_340_297_690_4).abs() < 1e-9);
    assert_eq!(s["rays"].as_array().unwrap().len(), 3);
    assert_eq!(s["surfaces"].as_array().unwrap().len(), 3);
    let svg = std::fs::read_to_string(out.join("lens.svg")).unwrap();
    assert!(svg.contains("<polyline"));
    assert!(out.join("lens.png").exists());
    // Without --out nothing is written, and the default fan has five rays.
    let o = spibench(&["lens", file.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(stdout(&o).matches("→ y").count(), 5);
}

#[test]
fn bad_prescriptions_exit_2_and_write_nothing() {
    let tmp = TempDir::new("cli-lens-bad");
    let bad = root().join("validation/lenses/test_prescriptions/bad");
    for (file, fragments) in [
        (
            "missing_disz.zmx",
            &["missing_disz.zmx, line 15", "DISZ"][..],
        ),
        ("curv_nan.zmx", &["line 18", "CURV"]),
        ("crossing_surfaces.zmx", &["line 19", "cross"]),
        ("aperture_beyond_conic.zmx", &["line 22", "DIAM"]),
        (
            "unknown_glass_no_ndvd.zmx",
            &["line 20", "GLAS", "NOT-A-GLASS"],
        ),
        ("parm9.zmx", &["line 27", "PARM"]),
        ("toroidal.zmx", &["line 17", "TOROIDAL"]),
        (
            "utf16_odd_length.zmx",
            &["utf16_odd_length.zmx", "odd length"],
        ),
    ] {
        let out = tmp.join(file);
        let path = bad.join(file);
        let o = spibench(
            &[
                "lens",
                path.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert_input_error(&o, fragments, &out);
    }
    // A glass range the wavelength leaves: located in the catalogue.
    let out = tmp.join("range");
    let cat = root().join("validation/lenses/test_catalogue.agf");
    let zmx = tmp.join("narrow.zmx");
    let text = std::fs::read_to_string(
        root().join("validation/lenses/test_prescriptions/sphere_biconvex.zmx"),
    )
    .unwrap()
    .replace("GLAS N-BK7", "GLAS NARROW-BK7");
    std::fs::write(&zmx, text).unwrap();
    let args = [
        "lens",
        zmx.to_str().unwrap(),
        "--catalogue",
        cat.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    assert_input_error(&spibench(&args, &[]), &["NARROW-BK7", "outside"], &out);
    // Substitution allowed: done, and said on stderr and in summary.json.
    let out = tmp.join("sub");
    let path = bad.join("unknown_glass_with_ndvd.zmx");
    let o = spibench(
        &[
            "lens",
            path.to_str().unwrap(),
            "--allow-glass-substitution",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("NOT-A-GLASS is in no catalogue"));
    let s = read_json(&out.join("summary.json"));
    assert_eq!(s["substitutions"].as_array().unwrap().len(), 1);
}

/// The paper bench's text with the `Lens` element `name` replaced by `with`.
fn replaced(text: &str, name: &str, with: &str) -> String {
    let start = text
        .find(&format!("        Lens(\n            name: \"{name}\""))
        .unwrap();
    let end = start + text[start..].find("        ),\n").unwrap() + "        ),\n".len();
    format!("{}{with}{}", &text[..start], &text[end..])
}

/// `spibench lens BENCH --element NAME` reports a bench's `Lens` (the built-in bench's imaging
/// lens, the same numbers as the shipped LA1050 prescription) and `LensSystem` (the AC254-100-B
/// doublet) elements; a glass the bench allows to be modelled from nd/Vd is reported on
/// stderr, by `check` (printed and check.json) and in `trace`'s summary.json, and without the
/// permission the bench is refused naming the glass.
#[test]
fn lens_reports_bench_elements_and_bench_substitutions() {
    let tmp = TempDir::new("cli-lens-bench");
    // A Lens element of the built-in bench against the part's own file.
    let o = spibench(&["lens", "--element", "imaging_lens"], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let part = root().join("scenes/parts/thorlabs_la1050.zmx");
    let p = spibench(&["lens", part.to_str().unwrap()], &[]);
    let efl = |t: &str| {
        t.lines()
            .find(|l| l.starts_with("EFL"))
            .unwrap()
            .to_string()
    };
    assert_eq!(efl(&stdout(&o)), efl(&stdout(&p)));
    // A bench whose imaging lens is the doublet and whose + arm lens is an LA1050 whose glass
    // no catalogue has (its nd and Vd are N-BK7's).
    let zmx = tmp.join("la1050_unknown.zmx");
    let text = std::fs::read_to_string(&part)
        .unwrap()
        .replace("GLAS N-BK7", "GLAS NOT-A-GLASS");
    std::fs::write(&zmx, text).unwrap();
    let doublet = format!(
        "        LensSystem(\n            name: \"imaging_lens\",\n            zmx: \"{}\",\n            position_mm: (0.0, 0.0, 205.668),\n            axis: Vector((0.0, 0.0, -1.0)),\n        ),\n",
        root()
            .join("scenes/parts/thorlabs_ac254-100-b.zmx")
            .display()
    );
    let arm = |allow: bool| {
        format!(
            "        LensSystem(\n            name: \"arm_plus_lens\",\n            zmx: \"{}\",\n            allow_glass_substitution: {allow},\n            position_mm: (28.7606, -28.7606, 91.3545),\n            axis: Polar(theta_deg: 24.0, phi_deg: -45.0),\n        ),\n",
            zmx.display()
        )
    };
    let paper = std::fs::read_to_string(root().join("scenes/paper_bench.ron")).unwrap();
    let with_doublet = replaced(&paper, "imaging_lens", &doublet);
    let bench = tmp.join("bench.ron");
    std::fs::write(&bench, replaced(&with_doublet, "arm_plus_lens", &arm(true))).unwrap();
    let b = bench.to_str().unwrap();
    let out = tmp.join("doublet");
    let o = spibench(
        &[
            "lens",
            b,
            "--element",
            "imaging_lens",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    crate::outputs_schema::check_file(&out.join("summary.json"), "LensSummary");
    let s = read_json(&out.join("summary.json"));
    assert_eq!(s["surfaces"].as_array().unwrap().len(), 3);
    // The doublet's EFL at 850 nm, near its nominal 100 mm.
    assert!((s["efl_mm"].as_f64().unwrap() - 100.0).abs() < 1.0, "{s}");
    // The substituted element: reported by `lens`, `check` and `trace`.
    let o = spibench(&["lens", b, "--element", "arm_plus_lens"], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("NOT-A-GLASS is in no catalogue"),
        "{}",
        stderr(&o)
    );
    assert!(stdout(&o).contains("substituted: "), "{}", stdout(&o));
    let out = tmp.join("check");
    let o = spibench(&["check", b, "--out", out.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("NOT-A-GLASS"), "{}", stderr(&o));
    assert!(stdout(&o).contains("glass substituted: "), "{}", stdout(&o));
    crate::outputs_schema::check_file(&out.join("check.json"), "CheckJson");
    let c = read_json(&out.join("check.json"));
    assert_eq!(c["glass_substitutions"].as_array().unwrap().len(), 1);
    let lenses = c["lenses"].as_array().unwrap();
    assert!(lenses.iter().any(|l| l["name"] == "imaging_lens"), "{c}");
    let out = tmp.join("trace");
    let o = spibench(
        &["trace", b, "--rays", "4096", "--out", out.to_str().unwrap()],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    crate::outputs_schema::check_file(&out.join("summary.json"), "TraceSummary");
    let t = read_json(&out.join("summary.json"));
    let subs = t["provenance"]["glass_substitutions"].as_array().unwrap();
    assert_eq!(subs.len(), 1);
    assert!(subs[0].as_str().unwrap().contains("NOT-A-GLASS"));
    // Without the permission: refused, naming the glass; and no such element is located.
    std::fs::write(
        &bench,
        replaced(&with_doublet, "arm_plus_lens", &arm(false)),
    )
    .unwrap();
    let out = tmp.join("refused");
    let o = spibench(&["check", b, "--out", out.to_str().unwrap()], &[]);
    assert_input_error(&o, &["NOT-A-GLASS", "substitution"], &out);
    let o = spibench(
        &[
            "lens",
            "--element",
            "no_such_lens",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_input_error(&o, &["no_such_lens", "imaging_lens"], &out);
}
