use crate::common::*;

const SMALL: &str = r#"
Experiment(
    title: "small",
    width: 32,
    height: 32,
    objects: [(name: "phantom", object: Phantom)],
    sampling_ratios: [0.3, 0.6],
    cases: [
        (label: "traditional", scheme: Traditional),
        (label: "scb", scheme: SecondaryComplementaryBalancing,
         arms: (k_plus: 1.01, k_minus: 1.02, b_plus: 1.0, b_minus: 5.0),
         noise: (distribution: Gaussian, std: 20.0)),
    ],
    solver: (tol: 1e-4, maxit: 200, nonneg: true),
    seed: 5,
    montage: (rows: Ratio, columns: Case, tile_px: 32),
    curves: [(name: "psnr", x: Ratio, metric: Psnr)],
)
"#;

/// Runs `spibench simulate FILE --out OUT` with extra environment variables.
fn simulate(
    file: &std::path::Path,
    out: &std::path::Path,
    env: &[(&str, &str)],
) -> std::process::Output {
    spibench(
        &[
            "simulate",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        env,
    )
}

#[test]
fn simulate_writes_every_output() {
    let dir = TempDir::new("sim-ok");
    let file = dir.join("small.ron");
    std::fs::write(&file, SMALL).unwrap();
    let out = dir.join("out");
    let o = simulate(&file, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The printed table fits 100 columns (the line naming the output folder aside).
    for l in crate::common::stdout(&o)
        .lines()
        .filter(|l| !l.starts_with("wrote "))
    {
        assert!(
            l.chars().count() <= 100,
            "{} columns: {l}",
            l.chars().count()
        );
    }
    for f in [
        "summary.json",
        "cells.csv",
        "psnr.svg",
        "psnr.png",
        "psnr.csv",
        "montage.png",
        "montage.svg",
        "images/phantom__truth.png",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    crate::outputs_schema::check_file(&out.join("summary.json"), "SimulateSummary");
    crate::outputs_schema::check_file(&out.join("timings.json"), "SimulateTimings");
    let s = read_json(&out.join("summary.json"));
    assert_eq!(s["provenance"]["command"][1], "simulate");
    assert!(s["provenance"]["seeds"].is_array());
    let cells = s["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 4);
    for c in cells {
        for key in [
            "scheme",
            "object",
            "ratio",
            "gain_plus",
            "gain_minus",
            "offset_plus_object",
            "offset_minus_object",
            "psnr_db",
            "mssim",
            "iterations",
            "dmd_frames",
            "acquisition_time_s",
        ] {
            assert!(!c[key].is_null(), "cell lacks {key}: {c}");
        }
        let psnr = c["psnr_db"].as_f64().unwrap();
        assert!(
            psnr > 15.0,
            "a 32×32 phantom at 30–60 % should reconstruct: {psnr} dB"
        );
    }
    // Complementary schemes show two DMD frames per base pattern.
    let scb = cells.iter().find(|c| c["case"] == "scb").unwrap();
    assert_eq!(
        scb["dmd_frames"].as_u64().unwrap(),
        2 * scb["measurements"].as_u64().unwrap()
    );
    assert!(stdout(&o).contains("PSNR"));
}

#[test]
fn simulate_is_identical_on_one_and_two_threads() {
    let dir = TempDir::new("sim-threads");
    let file = dir.join("small.ron");
    std::fs::write(&file, SMALL).unwrap();
    let mut results = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.join(&format!("out{threads}"));
        let o = simulate(&file, &out, &[("RAYON_NUM_THREADS", threads)]);
        assert!(o.status.success(), "{}", stderr(&o));
        let mut s = read_json(&out.join("summary.json"));
        // Timings differ between runs, and the command lines name other folders; everything
        // else must be bit-identical.
        s["wall_time_s"] = serde_json::Value::Null;
        s["provenance"]["command"] = serde_json::Value::Null;
        for c in s["cells"].as_array_mut().unwrap() {
            c["solver_time_s"] = serde_json::Value::Null;
        }
        results.push(s.to_string());
    }
    assert_eq!(results[0], results[1]);
}

#[test]
fn unknown_field_names_file_line_and_field() {
    let dir = TempDir::new("sim-unknown");
    let file = dir.join("bad.ron");
    std::fs::write(&file, SMALL.replace("seed: 5,", "seed: 5,\n    sead: 6,")).unwrap();
    let out = dir.join("out");
    let o = simulate(&file, &out, &[]);
    assert_input_error(&o, &["bad.ron", "line 16", "sead"], &out);
}

#[test]
fn sampling_ratio_out_of_range_is_rejected() {
    let dir = TempDir::new("sim-ratio");
    for bad in ["0.0", "1.5"] {
        let file = dir.join("bad.ron");
        std::fs::write(&file, SMALL.replace("[0.3, 0.6]", &format!("[0.3, {bad}]"))).unwrap();
        let out = dir.join("out");
        let o = simulate(&file, &out, &[]);
        assert_input_error(
            &o,
            &["bad.ron", "line 7", "sampling_ratios", "(0, 1]"],
            &out,
        );
    }
}

/// A regularisation weight TVAL3 cannot use is an input error naming the field (before, a
/// beta of 5e-324 ran to non-finite iterates and exited 1).
#[test]
fn a_weight_the_solver_cannot_use_is_an_input_error() {
    let dir = TempDir::new("sim-weight");
    let file = dir.join("bad.ron");
    std::fs::write(
        &file,
        SMALL.replace("solver: (tol: 1e-4,", "solver: (beta: 5e-324, tol: 1e-4,"),
    )
    .unwrap();
    let out = dir.join("out");
    let o = simulate(&file, &out, &[]);
    assert_input_error(&o, &["bad.ron", "solver.beta", "5e-324"], &out);
}

#[test]
fn missing_experiment_and_missing_object_file() {
    let dir = TempDir::new("sim-missing");
    let out = dir.join("out");
    let o = simulate(&dir.join("nope.ron"), &out, &[]);
    assert_input_error(&o, &["nope.ron"], &out);

    let file = dir.join("obj.ron");
    std::fs::write(
        &file,
        SMALL.replace("object: Phantom", "object: File(path: \"missing.png\")"),
    )
    .unwrap();
    let o = simulate(&file, &out, &[]);
    assert_input_error(&o, &["missing.png"], &out);
}

#[test]
fn hadamard_needs_a_power_of_two() {
    let dir = TempDir::new("sim-hadamard");
    let file = dir.join("h.ron");
    let text = SMALL
        .replace("width: 32", "width: 48")
        .replace("height: 32", "height: 48")
        .replace(
            "seed: 5,",
            "seed: 5,\n    patterns: Hadamard(ordering: CakeCutting),",
        );
    std::fs::write(&file, text).unwrap();
    let out = dir.join("out");
    let o = simulate(&file, &out, &[]);
    assert_input_error(&o, &["h.ron", "patterns", "48"], &out);
}

#[test]
fn built_in_experiments_parse() {
    for name in ["fig1", "fig2", "fig3", "fig4"] {
        spibench::scene::experiment::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

/// `simulate` runs traditional cells with either handling of the 0/1 system: the experiment's
/// default (zero-mean) and `--zero-one plain`; the ±1 cells are the same either way, and each
/// cell reports its stop reason consistently with `converged`.
#[test]
fn simulate_runs_both_zero_one_handlings() {
    let dir = TempDir::new("sim-01");
    let file = dir.join("small.ron");
    std::fs::write(&file, SMALL).unwrap();
    let mut summaries = Vec::new();
    for (name, extra) in [("zero-mean", None), ("plain", Some("plain"))] {
        let out = dir.join(name);
        let mut args = vec![
            "simulate",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        if let Some(z) = extra {
            args.extend(["--zero-one", z]);
        }
        let o = spibench(&args, &[]);
        assert!(o.status.success(), "{}", stderr(&o));
        let s = read_json(&out.join("summary.json"));
        let want = if name == "plain" { "Plain" } else { "ZeroMean" };
        assert_eq!(s["zero_one"], want, "{s}");
        for c in s["cells"].as_array().unwrap() {
            let traditional = c["scheme"] == "traditional";
            assert_eq!(c["zero_one_handling"].is_null(), !traditional, "{c}");
            if traditional {
                assert_eq!(c["zero_one_handling"], want);
            }
            assert_eq!(
                c["converged"].as_bool().unwrap(),
                c["stop"] == "Tolerance",
                "{c}"
            );
        }
        summaries.push(s);
    }
    let (a, b) = (&summaries[0]["cells"], &summaries[1]["cells"]);
    for i in 0..a.as_array().unwrap().len() {
        if a[i]["scheme"] != "traditional" {
            assert_eq!(a[i]["psnr_db"], b[i]["psnr_db"], "cell {i}");
        }
    }
}
