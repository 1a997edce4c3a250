//! The bad-input catalogue: one case per class of failure seen when bad input got through
//! (panics, NaN results, wrong exit codes, wrong locations, files left behind). Each case asserts
//! exit status 2, the file, the line and the field's full path in the message, and no output
//! or staging folder left.

use std::path::{Path, PathBuf};

use crate::common::{TempDir, assert_input_error, spibench, stderr};

const BENCH: &str = "scenes/tests/symmetric_arms.ron";
const EXPERIMENT: &str = "scenes/fig1.ron";

fn shipped(rel: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
}

/// Writes `rel` with one edit into `dir` and returns the path and the 1-based line of `marker`.
fn edited(dir: &TempDir, rel: &str, from: &str, to: &str, marker: &str) -> (PathBuf, usize) {
    let text = shipped(rel);
    assert_eq!(text.matches(from).count(), 1, "edit {from:?} of {rel}");
    let text = text.replacen(from, to, 1);
    let line = text[..text.find(marker).expect("marker")]
        .matches('\n')
        .count()
        + 1;
    let name = Path::new(rel).file_name().unwrap();
    let p = dir.0.join(name);
    std::fs::write(&p, text).unwrap();
    (p, line)
}

/// A bench edit through `spibench trace`: exit 2 naming file, line and field path.
fn bench_case(tag: &str, from: &str, to: &str, marker: &str, field: &str) {
    let dir = TempDir::new(&format!("bad-bench-{tag}"));
    let (scene, line) = edited(&dir, BENCH, from, to, marker);
    let out = dir.join("out");
    let o = spibench(
        &[
            "trace",
            scene.to_str().unwrap(),
            "--rays",
            "2048",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let located = format!("line {line},");
    let field = format!("field `{field}`");
    assert_input_error(&o, &["symmetric_arms.ron", &located, &field], &out);
}

/// An experiment edit through `spibench simulate`.
fn experiment_case(tag: &str, from: &str, to: &str, marker: &str, field: &str) {
    let dir = TempDir::new(&format!("bad-exp-{tag}"));
    let (exp, line) = edited(&dir, EXPERIMENT, from, to, marker);
    let out = dir.join("out");
    let o = spibench(
        &[
            "simulate",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let located = format!("line {line},");
    let field = format!("field `{field}`");
    assert_input_error(&o, &["fig1.ron", &located, &field], &out);
}

#[test]
fn non_finite_and_huge_positions_are_refused_at_their_element() {
    bench_case(
        "nan-element",
        "position_mm: (17.2564, -17.2564, 54.8127),",
        "position_mm: (NaN, -17.2564, 54.8127),",
        "position_mm: (NaN",
        "elements[0].position_mm",
    );
    bench_case(
        "huge-lamp",
        "position_mm: (0.0, 0.0, 100.0),",
        "position_mm: (0.0, 0.0, 1e308),",
        "1e308",
        "lamp.position_mm",
    );
    bench_case(
        "inf-detector",
        "position_mm: (39.0011, -39.0011, 123.8823),",
        "position_mm: (39.0011, -inf, 123.8823),",
        "-inf, 123",
        "detectors.plus.position_mm",
    );
    bench_case(
        "huge-axis",
        "axis: Vector((0.0, 0.0, -1.0)),",
        "axis: Vector((0.0, 0.0, -1e300)),",
        "-1e300",
        "lamp.axis",
    );
}

#[test]
fn lengths_temperatures_and_kinds_are_refused_at_their_own_field() {
    bench_case(
        "thickness",
        "-45.0),\n            front_radius_mm: 25.75,\n            thickness_mm: 5.34,",
        "-45.0),\n            front_radius_mm: 25.75,\n            thickness_mm: 1e308,",
        "1e308",
        "elements[0].thickness_mm",
    );
    bench_case(
        "temperature",
        "temperature_k: 2800.0",
        "temperature_k: 1e9",
        "1e9",
        "lamp.spectrum.temperature_k",
    );
    bench_case(
        "kind",
        "        Lens(\n            name: \"arm_plus_lens\"",
        "        Bogus(\n            name: \"arm_plus_lens\"",
        "Bogus",
        "elements[0]",
    );
    bench_case(
        "wrapping",
        "mirrors_per_unit: 8",
        "mirrors_per_unit: 4611686018427387904",
        "pattern: (origin",
        "dmd.pattern",
    );
}

#[test]
fn simulate_errors_name_file_line_and_the_full_field_path() {
    experiment_case(
        "bias",
        "b_plus: 1.0, b_minus: 5.0)),\n    ],",
        "b_plus: -1e308, b_minus: 5.0)),\n    ],",
        "-1e308",
        "cases[4].arms.b_plus",
    );
    experiment_case("tol", "tol: 1e-4", "tol: NaN", "tol: NaN", "solver.tol");
    experiment_case(
        "maxit",
        "maxit: 300",
        "maxit: 0",
        "maxit: 0",
        "solver.maxit",
    );
    experiment_case("mu", "mu: 256.0,", "mu: -1.0,", "mu: -1.0", "solver.mu");
    experiment_case(
        "image",
        "object: Phantom",
        "object: TestImage(\"nope\")",
        "TestImage",
        "objects[0].object.TestImage",
    );
    experiment_case(
        "size",
        "width: 128,\n    height: 128,",
        "width: 5000,\n    height: 5000,",
        "width: 5000",
        "width",
    );
}

#[test]
fn command_line_limits_and_unreadable_files_are_input_errors() {
    let dir = TempDir::new("bad-cli");
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join(BENCH);
    let out = dir.join("out");
    let o = spibench(
        &[
            "trace",
            bench.to_str().unwrap(),
            "--rays",
            "18446744073709551615",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_input_error(&o, &["--rays", "18446744073709551615"], &out);

    // A device read as a scene stops at the size limit.
    let o = spibench(
        &[
            "trace",
            "/dev/zero",
            "--rays",
            "2048",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_input_error(&o, &["/dev/zero", "MiB"], &out);

    let o = spibench(
        &[
            "export-mitsuba",
            bench.to_str().unwrap(),
            "--wavelength-nm",
            "5000",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_input_error(&o, &["--wavelength-nm", "outside the traced band"], &out);
}

#[test]
fn a_file_in_the_way_of_the_output_folder_is_an_input_error() {
    let dir = TempDir::new("bad-out");
    let out = dir.join("out");
    std::fs::write(&out, b"a file").unwrap();
    let o = spibench(&["simulate", "fig1", "--out", out.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("not a directory") && err.contains("out"),
        "{err}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"a file");
}

#[test]
fn a_two_column_measurement_array_is_not_read_as_one_vector() {
    let dir = TempDir::new("bad-npy");
    let (pp, yp) = (dir.join("p.npy"), dir.join("y.npy"));
    // 128 patterns of 16 units, and measurements shaped (64, 2): 128 values, but not a vector.
    spibench::report::npy::write_u8(&pp, &[128, 16], &vec![1u8; 128 * 16]).unwrap();
    spibench::report::npy::write_f64(&yp, &[64, 2], &[1.0; 128]).unwrap();
    let out = dir.join("out");
    let o = spibench(
        &[
            "reconstruct",
            "--patterns",
            pp.to_str().unwrap(),
            "--measurements",
            yp.to_str().unwrap(),
            "--size",
            "4x4",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_input_error(&o, &["y.npy", "1-D", "[64, 2]"], &out);
}
