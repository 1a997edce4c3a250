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
