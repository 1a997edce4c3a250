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
    experiment_fragments(tag, from, to, marker, &[&format!("field `{field}`")]);
}

/// An experiment edit through `spibench simulate`: exit 2 naming the file, the line and
/// `fragments`.
fn experiment_fragments(tag: &str, from: &str, to: &str, marker: &str, fragments: &[&str]) {
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
    let mut all = vec!["fig1.ron", located.as_str()];
    all.extend_from_slice(fragments);
    assert_input_error(&o, &all, &out);
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
        "4611686018427387904",
        "dmd.pattern.mirrors_per_unit",
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
    // Too many random pattern bits: named at the image size that makes them (lines 7–8), not
    // at line 1 as a field `measurements` that no file has, nor at the ratios.
    experiment_case(
        "pattern-bits",
        "width: 128,\n    height: 128,",
        "width: 1024,\n    height: 1024,",
        "width: 1024",
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

// The classes of bad input to the newer commands (sweep, tolerance, dataset, patterns, check,
// simulate): each case asserts exit 2, the file and line or the argument named, and that no
// output folder, staging folder or lock is left.

const PAPER: &str = "scenes/paper_bench.ron";

/// `spibench ARGS… --out DIR/out` for a case: the output must not appear.
fn run_case(dir: &TempDir, args: &[&str], fragments: &[&str]) {
    let out = dir.join("out");
    let mut a: Vec<&str> = args.to_vec();
    a.extend(["--out", out.to_str().unwrap()]);
    let o = spibench(&a, &[("RAYON_NUM_THREADS", "1")]);
    assert_input_error(&o, fragments, &out);
}

/// A bench file edited once, through `spibench trace`, naming the file, the line and a part of
/// the field's path.
fn traced_edit(tag: &str, rel: &str, from: &str, to: &str, marker: &str, field: &str) {
    let dir = TempDir::new(&format!("bad-new-{tag}"));
    let (scene, line) = edited(&dir, rel, from, to, marker);
    let name = Path::new(rel).file_name().unwrap().to_str().unwrap();
    run_case(
        &dir,
        &["trace", scene.to_str().unwrap(), "--rays", "2048"],
        &[name, &format!("line {line},"), field],
    );
}

/// A dataset spec of a few phantom samples through `bench` (a file name in `dir`).
fn small_spec(dir: &TempDir, bench: &str, kernel_rays: &str, samples: &str) -> PathBuf {
    let text = format!(
        "Dataset(\n    bench: \"{bench}\",\n    kernel: (rays: {kernel_rays}, seed: 1, grid_px: (8, 8), \
         field_mm: (7.88, 7.88)),\n    objects: Phantom,\n    seed: 7,\n    samples: {samples},\n    \
         shard_samples: 4,\n)\n"
    );
    let p = dir.join("spec.ron");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn panics_of_the_newer_inputs_are_located_input_errors() {
    // An azimuth checked like its polar angle.
    for (tag, bad) in [("phi-nan", "NaN"), ("phi-inf", "-inf")] {
        traced_edit(
            tag,
            BENCH,
            "theta_deg: 24.0, phi_deg: -45.0",
            &format!("theta_deg: 24.0, phi_deg: {bad}"),
            &format!("phi_deg: {bad}"),
            "phi_deg`",
        );
    }
    traced_edit(
        "radius",
        BENCH,
        "-45.0),\n            front_radius_mm: 25.75,",
        "-45.0),\n            front_radius_mm: 1e308,",
        "1e308",
        "front_radius_mm`",
    );
    // A NaN optical density in the bench a dataset spec names.
    let dir = TempDir::new("bad-new-dataset-od");
    let (_, line) = edited(&dir, PAPER, "od: NgGlass(2.0)", "od: NgGlass(NaN)", "NaN");
    let spec = small_spec(&dir, "paper_bench.ron", "4096", "4");
    run_case(
        &dir,
        &["dataset", spec.to_str().unwrap()],
        &["paper_bench.ron", &format!("line {line},"), ".od`"],
    );
}

#[test]
fn bad_input_that_was_accepted_is_refused() {
    // `check` and `trace` refused a NaN optical density nowhere.
    let dir = TempDir::new("bad-new-od-check");
    let (bench, line) = edited(&dir, PAPER, "od: NgGlass(1.0)", "od: NgGlass(NaN)", "NaN");
    run_case(
        &dir,
        &["check", bench.to_str().unwrap()],
        &[
            "paper_bench.ron",
            &format!("line {line},"),
            ".od`",
            "optical density",
        ],
    );
    // A mirror count whose product with the units wrapped.
    let dir = TempDir::new("bad-new-mirrors");
    run_case(
        &dir,
        &[
            "patterns",
            "--family",
            "random",
            "--units",
            "48x48",
            "--ratio",
            "0.1",
            "--mirrors-per-unit",
            "9223372036854775808",
        ],
        &["--mirrors-per-unit", "do not fit"],
    );
    // A limit no value can meet, and a quality ratio the run does not score.
    let dir = TempDir::new("bad-new-limits");
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join(PAPER);
    let tol = dir.join("tol.ron");
    std::fs::write(
        &tol,
        "(\n    tolerances: [(path: \"chart.despace_mm\", range: PlusMinus(0.1))],\n    limits: [\n        \
         (metric: \"imbalance\", min: 0.1, max: -0.1),\n    ],\n)\n",
    )
    .unwrap();
    run_case(
        &dir,
        &[
            "tolerance",
            bench.to_str().unwrap(),
            "--tolerances",
            tol.to_str().unwrap(),
            "--trials",
            "0",
        ],
        &["tol.ron", "line 4,", "field `limits`", "min 0.1 > max -0.1"],
    );
    std::fs::write(
        &tol,
        "(\n    tolerances: [(path: \"chart.despace_mm\", range: PlusMinus(0.1))],\n    \
         quality: (ratio_percent: 33, min_mssim: 0.9),\n)\n",
    )
    .unwrap();
    run_case(
        &dir,
        &[
            "tolerance",
            bench.to_str().unwrap(),
            "--tolerances",
            tol.to_str().unwrap(),
            "--trials",
            "0",
            "--quality",
        ],
        &["tol.ron", "line 3,", "quality.ratio_percent", "33 %"],
    );
}

#[test]
fn errors_point_at_the_field_that_is_wrong() {
    // A NaN optical density is the filter's, not `--rays`' or the swept variable's.
    let dir = TempDir::new("bad-new-od-sweep");
    let (bench, line) = edited(&dir, PAPER, "od: NgGlass(2.0)", "od: NgGlass(NaN)", "NaN");
    let located = format!("line {line},");
    run_case(
        &dir,
        &["trace", bench.to_str().unwrap(), "--rays", "2048"],
        &["paper_bench.ron", &located, ".od`"],
    );
    run_case(
        &dir,
        &[
            "sweep",
            bench.to_str().unwrap(),
            "--vary",
            "dmd.tilt_deg=11:12:2",
            "--rays",
            "2048",
        ],
        &["paper_bench.ron", &located, ".od`"],
    );
    // A Hadamard size error names the flag that set the size.
    let dir = TempDir::new("bad-new-hadamard");
    run_case(
        &dir,
        &[
            "patterns",
            "--family",
            "hadamard",
            "--units",
            "48x48",
            "--ratio",
            "0.1",
            "--mirrors-per-unit",
            "4",
        ],
        &["--units", "power-of-two"],
    );
    // A kernel of one ray is refused where it is written (it gave NaN standard errors).
    let dir = TempDir::new("bad-new-kernel");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join(PAPER),
        dir.join("paper_bench.ron"),
    )
    .unwrap();
    let spec = small_spec(&dir, "paper_bench.ron", "1", "4");
    run_case(
        &dir,
        &["dataset", spec.to_str().unwrap()],
        &["spec.ron", "line 3,", "kernel.rays`", "2048"],
    );
    assert_eq!(
        spibench::scene::dataset::MIN_KERNEL_RAYS,
        2 * spibench::trace::RAYS_PER_BATCH,
        "a kernel's minimum is two batches"
    );
}

#[test]
fn sizes_are_checked_before_anything_is_allocated() {
    // 65 536 × 65 536 mirrors: refused with its size, not aborted with a staging folder left.
    let dir = TempDir::new("bad-new-huge-dmd");
    run_case(
        &dir,
        &[
            "patterns",
            "--family",
            "random",
            "--units",
            "4096x4096",
            "--ratio",
            "0.01",
            "--mirrors-per-unit",
            "16",
            "--dmd",
            "65536x65536",
        ],
        &["bytes written", "--allow-large"],
    );
}

#[test]
fn total_work_above_the_limits_is_refused_with_its_estimate() {
    let dir = TempDir::new("bad-new-work");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bench = root.join(PAPER);
    let tol = root.join("scenes/tolerances/paper_bench.ron");
    run_case(
        &dir,
        &[
            "tolerance",
            bench.to_str().unwrap(),
            "--tolerances",
            tol.to_str().unwrap(),
            "--trials",
            "1000000",
        ],
        &["1000000 trials", "traced rays", "--allow-large"],
    );
    // Few rays per trace: 4·10⁹ rays, but a million benches to build (about 15 h).
    run_case(
        &dir,
        &[
            "tolerance",
            bench.to_str().unwrap(),
            "--tolerances",
            tol.to_str().unwrap(),
            "--trials",
            "1000000",
            "--rays",
            "4096",
        ],
        &[
            "1000000 trials",
            "1000055 benches built at 12000 rays' time each",
            "about 12 h on two cores",
            "--allow-large",
        ],
    );
    run_case(
        &dir,
        &[
            "sweep",
            bench.to_str().unwrap(),
            "--vary",
            "dmd.tilt_deg=11:13:100",
            "--vary",
            "chart.despace_mm=-1:1:100",
            "--rays",
            "10000000000",
        ],
        &["100 × 100 points", "traced rays", "--allow-large"],
    );
    std::fs::copy(&bench, dir.join("paper_bench.ron")).unwrap();
    let spec = small_spec(&dir, "paper_bench.ron", "4096", "100000000");
    run_case(
        &dir,
        &["dataset", spec.to_str().unwrap()],
        &["100000000 samples", "--allow-large"],
    );
}

#[test]
fn a_sweep_set_that_loses_the_dmd_names_the_edit() {
    let dir = TempDir::new("bad-sweep-set-dmd");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bench = root.join(PAPER);
    run_case(
        &dir,
        &[
            "sweep",
            bench.to_str().unwrap(),
            "--set",
            "illumination.turn_deg.across=180",
            "--vary",
            "dmd.tilt_deg=11:13:3",
            "--rays",
            "4096",
        ],
        &["--set", "illumination.turn_deg.across=180"],
    );
}

#[test]
fn a_sweep_with_no_finite_point_names_the_variable() {
    let dir = TempDir::new("bad-sweep-no-finite");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bench = root.join(PAPER);
    run_case(
        &dir,
        &[
            "sweep",
            bench.to_str().unwrap(),
            // Plane mirrors: turned 10° about the hinge the arms see no light at all; the
            // diffractive DMD still sends a few orders onto the diodes.
            "--dmd-model",
            "geometric",
            "--set",
            "illumination.turn_deg.hinge=10",
            "--vary",
            "dmd.tilt_deg=11:13:3",
            "--rays",
            "4096",
        ],
        &["--vary", "dmd.tilt_deg", "none of the 3 point(s)"],
    );
}

/// A 2-D sweep is refused the same way before its heatmaps, which would otherwise be drawn
/// empty.
#[test]
fn a_2d_sweep_with_no_finite_point_names_the_variables() {
    let dir = TempDir::new("bad-sweep-no-finite-2d");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bench = root.join(PAPER);
    run_case(
        &dir,
        &[
            "sweep",
            bench.to_str().unwrap(),
            // Plane mirrors: turned 10° about the hinge the arms see no light at all; the
            // diffractive DMD still sends a few orders onto the diodes.
            "--dmd-model",
            "geometric",
            "--set",
            "illumination.turn_deg.hinge=10",
            "--vary",
            "dmd.tilt_deg=11:13:2",
            "--vary",
            "arm_minus_lens.despace_mm=0:1:2",
            "--rays",
            "4096",
        ],
        &[
            "--vary",
            "dmd.tilt_deg × arm_minus_lens.despace_mm",
            "none of the 4 point(s)",
        ],
    );
}

#[test]
fn a_dataset_over_the_sample_limit_is_refused_at_its_spec_line() {
    // Located at the spec's `samples` (line 6), not at the flag alone.
    let dir = TempDir::new("bad-new-work-located");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(root.join(PAPER), dir.join("paper_bench.ron")).unwrap();
    let spec = small_spec(&dir, "paper_bench.ron", "4096", "1000000000");
    run_case(
        &dir,
        &["dataset", spec.to_str().unwrap()],
        &[
            "spec.ron",
            "line 6,",
            "samples`",
            "1.00e9 samples",
            "--allow-large",
        ],
    );
}

// The rest of the catalogue of the newer commands' classes, and where the other cases live:
// merges (`untrusted::a_merge_copies_what_it_checked_and_never_its_inputs`,
// `untrusted::tolerance_shard_records_are_checked`), the dataset lock and `--quiet`
// (`untrusted::a_dataset_folder_is_locked_and_quiet_means_quiet`), align's counts, bounds and
// start (`cli_tolerance::align_checks_its_arguments_before_tracing`), TVAL3's weight in an
// experiment (`cli_simulate::a_weight_the_solver_cannot_use_is_an_input_error`).

/// Fewer rays than two batches of 1024 give no standard error: `run --rays 1` and a bench's
/// `run.rays` are refused, naming the flag or the field (both were accepted).
#[test]
fn ray_counts_below_two_batches_are_refused() {
    let dir = TempDir::new("bad-new-run-rays");
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join(BENCH);
    for rays in ["1", "2047"] {
        run_case(
            &dir,
            &["run", bench.to_str().unwrap(), "--rays", rays],
            &["--rays", "2048", "two batches"],
        );
    }
    let (scene, line) = edited(
        &dir,
        BENCH,
        "\n)",
        "\n    run: (sampling_ratios: [0.5], rays: 1),\n)",
        "rays: 1)",
    );
    run_case(
        &dir,
        &["run", scene.to_str().unwrap()],
        &[
            "symmetric_arms.ron",
            &format!("line {line},"),
            "field `run.rays`",
            "2048",
        ],
    );
}

/// The numbers of the solver options, the additive noise and the objects go through checked
/// types like the bench's: each error names the file, the line and the full field path.
#[test]
fn solver_noise_and_object_numbers_are_located() {
    let dir = TempDir::new("bad-new-solver");
    let (scene, line) = edited(
        &dir,
        BENCH,
        "\n)",
        "\n    run: (sampling_ratios: [0.5], solver: (beta: 5e-324)),\n)",
        "beta: 5e-324",
    );
    run_case(
        &dir,
        &["run", scene.to_str().unwrap()],
        &[
            "symmetric_arms.ron",
            &format!("line {line},"),
            "field `run.solver.beta`",
            "5e-324",
        ],
    );
    experiment_case(
        "noise-std",
        "scheme: Traditional),",
        "scheme: Traditional, noise: (distribution: Gaussian, std: -inf)),",
        "std: -inf",
        "cases[0].noise.std",
    );
    experiment_fragments(
        "usaf-group",
        "object: Phantom",
        "object: Usaf(region: Elements(group: 12, first: 1, last: 2))",
        "group: 12",
        &["field `objects[0].object", "group`", "from -2 to 9"],
    );
    experiment_fragments(
        "usaf-window",
        "object: Phantom",
        "object: Usaf(region: Window(center_x_mm: 0.0, center_y_mm: NaN, width_mm: 1.0, \
         height_mm: 1.0))",
        "center_y_mm",
        &["field `objects[0].object", "center_y_mm`"],
    );
}

/// align estimates its total work before the first trace and refuses a search above the limit
/// with the estimate; a starting bench outside a field's range names the field.
#[test]
fn align_work_and_start_are_checked_before_tracing() {
    let dir = TempDir::new("bad-new-align");
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join(BENCH);
    let bench = bench.to_str().unwrap();
    let free = "detectors.minus.decenter_mm.x=-2:2";
    run_case(
        &dir,
        &[
            "align",
            bench,
            "--free",
            free,
            "--max-evaluations",
            "100000000",
            "--rays",
            "1000000",
        ],
        &["100000001 evaluations", "traced rays", "--allow-large"],
    );
    run_case(
        &dir,
        &[
            "align",
            bench,
            "--free",
            free,
            "--set",
            "dmd.fill_factor=1.5",
        ],
        &["dmd.fill_factor", "value 1.5 refused", "(0, 1]"],
    );
    run_case(
        &dir,
        &["align", bench, "--free", free, "--offset-weight", "1e308"],
        &["--offset-weight", "1e15"],
    );
}

/// The tolerance command's PDFs are the same bytes in two identical runs (their object order
/// once followed a hash map's).
#[test]
fn tolerance_pdfs_are_byte_identical_between_runs() {
    let dir = TempDir::new("bad-new-pdf");
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let bench = scenes.join("tests/symmetric_arms.ron");
    let tol = scenes.join("tolerances/symmetric_arms.ron");
    let pdfs = |out: &Path| -> Vec<(String, Vec<u8>)> {
        let o = spibench(
            &[
                "tolerance",
                bench.to_str().unwrap(),
                "--tolerances",
                tol.to_str().unwrap(),
                "--trials",
                "3",
                "--rays",
                "4096",
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(out)
            .unwrap()
            .flatten()
            .filter(|e| e.path().extension().is_some_and(|x| x == "pdf"))
            .map(|e| {
                (
                    e.file_name().to_string_lossy().into_owned(),
                    std::fs::read(e.path()).unwrap(),
                )
            })
            .collect();
        files.sort();
        files
    };
    let (a, b) = (pdfs(&dir.join("a")), pdfs(&dir.join("b")));
    assert!(!a.is_empty(), "tolerance wrote no PDF");
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{name} differs between two identical runs");
    }
    assert_eq!(a.len(), b.len());
}

/// A refused value is printed as it was given (1e308, not a 309-digit integer), and a corrupt
/// object image is reported at the experiment's file, line and field, the image named after
/// them (not the experiment's line after the image's name, as if it were the image's).
#[test]
fn values_and_images_are_reported_as_given_and_where_given() {
    let dir = TempDir::new("bad-as-given");
    let out = dir.join("out");
    let o = out.to_str().unwrap();
    for (args, field) in [
        (
            vec!["run", "--set", "dmd.pattern.units_across=1e308", "--out", o],
            "dmd.pattern.units_across",
        ),
        (
            vec!["sweep", "--vary", "dmd.tilt_deg=1:1e308:2", "--out", o],
            "dmd.tilt_deg",
        ),
    ] {
        let r = spibench(&args, &[]);
        assert_input_error(&r, &[&format!("field `{field}`"), "1e308"], &out);
        assert!(!stderr(&r).contains("0000000000"), "{}", stderr(&r));
    }
    let (exp, line) = edited(
        &dir,
        EXPERIMENT,
        "(name: \"phantom\", object: Phantom)",
        "(name: \"phantom\", object: File(path: \"broken.png\"))",
        "File(path",
    );
    std::fs::write(dir.join("broken.png"), b"\x89PNG\r\n\x1a\nnot really a png").unwrap();
    let r = spibench(&["simulate", exp.to_str().unwrap(), "--out", o], &[]);
    let err = stderr(&r);
    let at = format!("fig1.ron, line {line}, column ");
    assert_input_error(
        &r,
        &[&at, "field `objects[0].object`: ", "broken.png: "],
        &out,
    );
    assert!(
        err.find(&at) < err.find("broken.png"),
        "the experiment's location comes first: {err}"
    );
    assert!(!err.contains("broken.png, line"), "{err}");
}

/// Hadamard patterns on the paper bench's 48 × 48 units are refused at the bench file's
/// `run: (patterns: …)`, with its line (they were refused when the patterns were built, as a field
/// `patterns` of no file).
#[test]
fn hadamard_patterns_on_a_side_of_48_units_are_located_in_the_bench_file() {
    let dir = TempDir::new("bad-hadamard-48");
    let (scene, line) = edited(
        &dir,
        PAPER,
        "    detectors: (",
        "    run: (patterns: Hadamard(ordering: Natural)),\n    detectors: (",
        "run: (patterns",
    );
    run_case(
        &dir,
        &["run", scene.to_str().unwrap(), "--rays", "2048"],
        &[
            "paper_bench.ron",
            &format!("line {line},"),
            "field `patterns`",
            "48×48",
            "32 or 64",
        ],
    );
}
