//! The reports state their result: `run` opens with its findings (the best scheme at each ratio
//! and at equal frames, its margin over every other scheme with paired 95 % intervals, ties
//! called ties), `sweep --limit` says where a metric crosses a limit with an interval, and
//! `tolerance` reads the tail that matters, the compensators' moves and whether its RSS holds.

use std::path::{Path, PathBuf};

use crate::common::*;

fn paper() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper_bench.ron").to_string()
}

/// The paper bench as 16 × 16 units with a run section of three schemes and three ratios.
fn small_run_scene(dir: &TempDir) -> PathBuf {
    small_run_scene_of(
        dir,
        "SecondaryComplementaryBalancing, DoubleArmCalibrated, Traditional",
        "0.25, 0.5, 1.0",
    )
}

/// The paper bench as 16 × 16 units, 30 000 rays, with the schemes and ratios given (RON lists
/// without their brackets).
pub(crate) fn small_run_scene_of(dir: &TempDir, schemes: &str, ratios: &str) -> PathBuf {
    let t = std::fs::read_to_string(paper()).unwrap();
    let a = "units_across: 48, units_down: 48, mirrors_per_unit: 12";
    assert_eq!(t.matches(a).count(), 1);
    let t = t.replace(a, "units_across: 16, units_down: 16, mirrors_per_unit: 36");
    let end = t.trim_end().rfind(')').unwrap();
    let run = format!(
        "rays: 30000, sampling_ratios: [{ratios}], signal_trace_frames: 2, \
         schemes: [{schemes}]"
    );
    let p = dir.join("small.ron");
    std::fs::write(
        &p,
        format!(
            "{},\n    run: ({run}),\n)\n",
            t[..end].trim_end().trim_end_matches(',')
        ),
    )
    .unwrap();
    p
}

/// The mean MSSIM of each (scheme, ratio) in repeats.json.
fn means(repeats: &serde_json::Value) -> Vec<(String, f64, f64)> {
    repeats["stats"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            (
                s["scheme"].as_str().unwrap().to_string(),
                s["ratio"].as_f64().unwrap(),
                s["mssim_mean"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// `run --repeats 3`: the printed summary and report.html open with the findings; the best
/// scheme they name at each ratio is the one with the highest mean MSSIM in repeats.json; a
/// lead over the calibrated baseline whose paired interval contains 0 is called "not
/// distinguished"; the scores table is labelled mean ± SD and the error-bar figures are in the
/// page.
#[test]
fn run_opens_with_findings_that_match_the_repeats() {
    let dir = TempDir::new("findings-run");
    let scene = small_run_scene(&dir);
    let out = dir.join("out");
    let o = spibench(
        &[
            "run",
            scene.to_str().unwrap(),
            "--repeats",
            "3",
            "--seed",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    let pos = |s: &str| {
        text.find(s)
            .unwrap_or_else(|| panic!("stdout lacks {s:?}:\n{text}"))
    };
    assert!(
        pos("findings (MSSIM; means of 3 repeats") < pos("k+ ="),
        "{text}"
    );
    assert!(
        pos("at each ratio:") < pos("MSSIM mean ± SD, 3 repeats"),
        "{text}"
    );
    assert!(text.contains("at equal DMD frames:"), "{text}");
    assert!(text.contains("PSNR dB mean ± SD, 3 repeats"), "{text}");
    // Every printed line fits 100 columns (the paired-differences table with the longest
    // baseline names is checked in cli_misc::printed_tables_fit_100_columns).
    for l in text.lines().filter(|l| !l.contains(out.to_str().unwrap())) {
        assert!(
            l.chars().count() <= 100,
            "{} columns: {l}",
            l.chars().count()
        );
    }

    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let at = |s: &str| html.find(s).unwrap_or_else(|| panic!("report lacks {s:?}"));
    assert!(at(">Findings<") < at("Bench: gains and offsets"));
    assert!(html.contains("mean ± sample SD over 3 repeats"));
    assert!(html.contains("MSSIM, mean ± SD"));
    assert!(html.contains("best − Double-arm, calibrated"));
    assert!(html.contains("MSSIM against DMD frames, mean ± SD over the repeats"));
    assert!(html.contains("at equal DMD frames"));

    let repeats = read_json(&out.join("repeats.json"));
    let m = means(&repeats);
    // summary.json carries the same findings, over all three repeats.
    crate::outputs_schema::check_file(&out.join("summary.json"), "RunSummary");
    let summary = read_json(&out.join("summary.json"));
    let found = &summary["findings"];
    assert_eq!(found["repeats"], 3, "{found}");
    let standings = found["mssim"]["at_ratios"].as_array().unwrap();
    assert_eq!(standings.len(), 3);
    assert_eq!(found["psnr_db"]["at_ratios"].as_array().unwrap().len(), 3);
    assert!(
        !found["mssim"]["at_equal_frames"]
            .as_array()
            .unwrap()
            .is_empty()
    );
    for st in standings {
        let ratio = st["ratio"].as_f64().unwrap();
        let best = m
            .iter()
            .filter(|x| x.1 == ratio)
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .unwrap();
        assert_eq!(st["best"], best.0.as_str(), "{st}");
        assert!(
            (st["best_mean"].as_f64().unwrap() - best.2).abs() < 1e-12,
            "{st}"
        );
        let margins = st["margins"].as_array().unwrap();
        assert_eq!(margins.len(), 2, "{st}");
        for mg in margins {
            let ci = mg["ci95"].as_array().unwrap();
            let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
            let verdict = if lo > 0.0 || hi < 0.0 {
                "ahead"
            } else {
                "not_distinguished"
            };
            assert_eq!(mg["verdict"], verdict, "{mg}");
            // The best's mean minus the other's mean over the same repeats.
            let other = m
                .iter()
                .find(|x| x.1 == ratio && x.0 == mg["scheme"].as_str().unwrap())
                .unwrap();
            assert!((mg["mean"].as_f64().unwrap() - (best.2 - other.2)).abs() < 1e-12);
        }
    }
    let label = |key: &str| match key {
        "secondary_complementary_balancing" => "Secondary complementary balancing",
        "double_arm_calibrated" => "Double-arm, calibrated",
        "traditional" => "Traditional CS",
        other => panic!("{other}"),
    };
    for (ratio, pct) in [(0.25, "25 %"), (0.5, "50 %"), (1.0, "100 %")] {
        let best = m
            .iter()
            .filter(|x| x.1 == ratio)
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .unwrap();
        let head = format!("At {pct}, {} has the highest mean MSSIM", label(&best.0));
        let i = at(&head);
        let sentence = &html[i..i + html[i..].find(").").unwrap()];
        // SCB − calibrated double-arm, paired over the repeats.
        let pair = repeats["paired"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| {
                p["b"] == "double_arm_calibrated"
                    && p["metric"] == "mssim"
                    && p["ratio"].as_f64() == Some(ratio)
            })
            .unwrap();
        let ci = pair["ci95"].as_array().unwrap();
        let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
        let between = ["secondary_complementary_balancing", "double_arm_calibrated"];
        if between.contains(&best.0.as_str()) && lo <= 0.0 && hi >= 0.0 {
            assert!(
                sentence.contains("not distinguished from"),
                "a tie called a win: {sentence} (interval [{lo}, {hi}])"
            );
        }
        if between.contains(&best.0.as_str()) && (lo > 0.0 || hi < 0.0) {
            assert!(
                !sentence.contains("not distinguished from Double-arm, calibrated")
                    && !sentence.contains("not distinguished from Secondary"),
                "a tested lead called a tie: {sentence} (interval [{lo}, {hi}])"
            );
        }
    }
}

/// `sweep --limit imbalance=…` reports where |imbalance| crosses the limit, between the two
/// grid points that straddle it, with a 95 % interval around it, in summary.json, on stdout and
/// in the report; sweep.csv starts with the swept variable. A limit on a 2-D sweep or on an
/// unknown metric is an input error before any trace.
#[test]
fn sweep_reports_where_a_limit_is_crossed() {
    let dir = TempDir::new("findings-sweep");
    let out = dir.join("out");
    let path = "detectors.minus.decenter_mm.x";
    let o = spibench(
        &[
            "sweep",
            &paper(),
            // Plane mirrors: the crossing this test finds is the geometric bench's (with the
            // diffractive DMD the imbalance starts at 0.07 and the crossing moves).
            "--dmd-model",
            "geometric",
            "--vary",
            &format!("{path}=-2.5:0:6"),
            "--rays",
            "6000",
            "--seed",
            "3",
            "--limit",
            "imbalance=0.05",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let s = read_json(&out.join("summary.json"));
    let rows = s["rows"].as_array().unwrap();
    let lim = &s["limits"][0];
    assert_eq!(lim["metric"], "imbalance");
    assert_eq!(lim["limit"], 0.05);
    // The crossings are exactly where neighbouring points straddle the limit.
    let y: Vec<f64> = rows
        .iter()
        .map(|r| r["imbalance"].as_f64().unwrap().abs())
        .collect();
    let x: Vec<f64> = rows.iter().map(|r| r[path].as_f64().unwrap()).collect();
    let straddles: Vec<usize> = (0..y.len() - 1)
        .filter(|&i| (y[i] > 0.05) != (y[i + 1] > 0.05))
        .collect();
    let crossings = lim["crossings"].as_array().unwrap();
    assert_eq!(crossings.len(), straddles.len(), "{lim}\n{y:?}");
    assert!(
        !crossings.is_empty(),
        "the − diode decentred by 2.5 mm should push |imbalance| past 0.05: {y:?}"
    );
    for (c, &i) in crossings.iter().zip(&straddles) {
        let at = c["at"].as_f64().unwrap();
        assert!((x[i]..=x[i + 1]).contains(&at), "{c}");
        let ci = c["ci95"].as_array().unwrap();
        let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
        assert!(lo < at, "{c}");
        assert!(at < hi && c["stderr"].as_f64().unwrap() > 0.0, "{c}");
    }
    let text = stdout(&o);
    assert!(
        text.contains(&format!("|imbalance| ≤ 0.05 along {path}:\n")),
        "{text}"
    );
    assert!(text.contains("(95 %: ["), "{text}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("Where each limit is crossed"));
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    assert!(csv.starts_with(&format!("{path},")), "{csv}");

    for (args, fragment) in [
        (
            vec![
                "--vary",
                "dmd.tilt_deg=11:13:2",
                "--limit",
                "imbalance=0.01",
            ],
            "one --vary",
        ),
        (vec!["--limit", "imbalnce=0.01"], "unknown metric"),
        (vec!["--limit", "imbalance=-1"], "--limit"),
    ] {
        let bad = dir.join("bad");
        let mut a = vec![
            "sweep".to_string(),
            paper(),
            "--vary".into(),
            format!("{path}=-1:0:2"),
            "--out".into(),
            bad.to_str().unwrap().into(),
        ];
        a.extend(args.iter().map(|s| s.to_string()));
        let refs: Vec<&str> = a.iter().map(String::as_str).collect();
        let o = spibench(&refs, &[]);
        assert_input_error(&o, &["--limit", fragment], &bad);
    }
}

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .display()
        .to_string()
}

/// `tolerance` with a compensator: the summary reads the tail that matters for each metric
/// (lower for k', upper |·| for the imbalance), the compensator's moves (mean, SD, extremes,
/// how often at a bound), flags or clears the RSS of every metric, and the report draws CDFs of
/// |imbalance| on a log axis with the limit and states the leaks as bounded fractions.
#[test]
fn tolerance_reads_tails_compensators_and_the_rss_model() {
    let dir = TempDir::new("findings-tolerance");
    let tol = dir.join("tol.ron");
    let text = std::fs::read_to_string(scene("tolerances/symmetric_arms.ron")).unwrap();
    let text = text.replace(
        "    limits: [",
        "    compensators: [\n        (path: \"detectors.minus.decenter_mm.x\", range: \
         PlusMinus(0.2), objective: Balance),\n    ],\n    limits: [",
    );
    std::fs::write(&tol, text).unwrap();
    let out = dir.join("out");
    let o = spibench(
        &[
            "tolerance",
            &scene("tests/symmetric_arms.ron"),
            "--tolerances",
            tol.to_str().unwrap(),
            "--trials",
            "6",
            "--rays",
            "8192",
            "--seed",
            "3",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let s = read_json(&out.join("summary.json"));
    // The summary card opens the terminal output and the report, its numbers summary.json's:
    // each yield, the tolerances that move the imbalance most, the compensators' travel.
    let card = spibench::outputs::tolerance::card(&s);
    card.check_against(&s).unwrap();
    assert!(
        stdout(&o).starts_with(&card.printed().join("\n")),
        "{}",
        stdout(&o)
    );
    assert!(card.printed().iter().any(|l| l.contains("yield")));
    assert!(
        card.printed()
            .iter()
            .any(|l| l.contains("at its travel limit"))
    );
    let a = &s["analysis"];
    let tail = |m: &str| {
        a["tails"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["metric"] == m)
            .unwrap_or_else(|| panic!("no tail row for {m}"))
            .clone()
    };
    assert_eq!(tail("k_prime")["tail"], "lower");
    assert_eq!(tail("imbalance")["tail"], "upper_abs");
    let worst = tail("imbalance")["worst"].as_f64().unwrap();
    let largest = s["trial_rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|r| r["values"]["imbalance"].as_f64())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    assert_eq!(worst, largest);
    assert!(tail("imbalance")["beyond_limits"].is_number());
    let c = &a["compensators"][0];
    assert_eq!(c["path"], "detectors.minus.decenter_mm.x");
    assert_eq!(c["trials"], 6);
    let (lo, hi) = (
        c["lowest"].as_f64().unwrap(),
        c["highest"].as_f64().unwrap(),
    );
    assert!(lo <= hi, "{c}");
    assert!(
        (-0.2..=0.2).contains(&lo) && (-0.2..=0.2).contains(&hi),
        "{c}"
    );
    assert!(c["at_bound_fraction"].as_f64().unwrap() <= 1.0);
    for r in a["rss"].as_array().unwrap() {
        assert!(r["linearity_flags"].is_array(), "{r}");
    }
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    for s in [
        "The tail that matters",
        "Compensator moves",
        "fraction, 0–1",
        "RSS model",
        "|·| of imbalance",
        "Freedman–Diaconis",
    ] {
        assert!(html.contains(s), "report lacks {s:?}");
    }
    let cdf = std::fs::read_to_string(out.join("cdf_imbalance.svg")).unwrap();
    assert!(
        cdf.contains("log scale"),
        "the CDF of |imbalance| is not on a log axis"
    );
    assert!(cdf.contains("|imbalance| ≤ 0.01"), "the limit is not drawn");
    crate::outputs_schema::check_file(&out.join("summary.json"), "ToleranceSummary");
}
