//! `spibench tolerance --budget` end to end on the small symmetric test bench.

use std::path::Path;

use crate::common::{TempDir, assert_input_error, read_json, spibench, stderr};

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .display()
        .to_string()
}

fn budget(extra: &[&str], out: &Path) -> std::process::Output {
    let bench = scene("tests/symmetric_arms.ron");
    let tol = scene("tolerances/symmetric_arms_budget.ron");
    let mut a = vec![
        "tolerance",
        bench.as_str(),
        "--tolerances",
        tol.as_str(),
        "--rays",
        "4096",
        "--seed",
        "3",
        "--budget",
    ];
    a.extend_from_slice(extra);
    a.extend(["--out", out.to_str().unwrap()]);
    spibench(&a, &[])
}

/// The one-sided Wilson lower bound at 95 % (z = 1.6449).
fn wilson_95(passed: f64, n: f64) -> f64 {
    let (z, p) = (1.644_853_6_f64, passed / n);
    let z2 = z * z;
    (p + z2 / (2.0 * n) - z * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt()) / (1.0 + z2 / n)
}

/// The budget for Y = 0.9 (100 trials per confirmation), read back by `spibench tolerance`
/// with another seed and 300 trials: the one-sided 95 % Wilson lower bound of that yield is at
/// least Y − 0.02. The joint budget's geometric-mean scale is at least the one-at-a-time one's.
#[test]
fn a_budget_reads_back_and_holds_its_yield_under_another_seed() {
    let dir = TempDir::new("budget");
    let out = dir.join("budget");
    let o = budget(&["--target-yield", "0.9", "--trials", "100"], &out);
    assert!(o.status.success(), "{}", stderr(&o));
    crate::outputs_schema::check_file(&out.join("summary.json"), "BudgetSummary");
    let s = read_json(&out.join("summary.json"));
    assert_eq!(s["reached"], true, "{s}");
    let (joint, base) = (&s["joint"], &s["baseline"]);
    assert!(joint["confirmation"]["lower_bound"].as_f64().unwrap() >= 0.9);
    assert!(
        joint["geometric_mean_scale"].as_f64().unwrap()
            >= base["geometric_mean_scale"].as_f64().unwrap() - 1e-12,
        "{s}"
    );
    // The one-at-a-time budget is scaled to the target only where it missed it.
    let base_met = base["confirmation"]["lower_bound"].as_f64().unwrap() >= 0.9;
    assert_eq!(s["baseline_at_target"].is_null(), base_met, "{s}");
    for f in [
        "budget.ron",
        "budget.csv",
        "report.html",
        "yield_vs_scale.svg",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let text = std::fs::read_to_string(out.join("budget.ron")).unwrap();
    assert!(
        text.contains("// scale ") && text.contains("% of the yield loss"),
        "{text}"
    );
    // The command that made it names the DMD's model, whatever the file's default.
    let made_by = text.lines().find(|l| l.starts_with("// Made by")).unwrap();
    assert!(made_by.contains("--dmd-model geometric"), "{made_by}");
    // Independently verified: the budget file, another seed, 300 trials.
    let check = dir.join("check");
    let b = out.join("budget.ron");
    let o = spibench(
        &[
            "tolerance",
            &scene("tests/symmetric_arms.ron"),
            "--tolerances",
            b.to_str().unwrap(),
            "--rays",
            "4096",
            "--seed",
            "11",
            "--trials",
            "300",
            "--out",
            check.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v = read_json(&check.join("summary.json"));
    let y = &v["analysis"]["yields"][0];
    let lb = wilson_95(y["passed"].as_f64().unwrap(), y["trials"].as_f64().unwrap());
    assert!(lb >= 0.9 - 0.02, "lower bound {lb}: {y}");
}

/// Bad targets, confidences and costs files exit 2 with nothing written; a target the bounds
/// cannot reach is reported with its reason, exit 0.
#[test]
fn bad_budget_input_is_refused_and_an_unreachable_target_reported() {
    let dir = TempDir::new("budget-bad");
    for (args, frags) in [
        (
            &["--target-yield", "1.0"][..],
            &["--target-yield", "between 0 and 1"][..],
        ),
        (&["--target-yield", "0"][..], &["--target-yield"][..]),
        (
            &["--target-yield", "0.9", "--confidence", "1.5"][..],
            &["--confidence"][..],
        ),
    ] {
        let out = dir.join("bad");
        assert_input_error(&budget(args, &out), frags, &out);
    }
    let costs = dir.join("costs.ron");
    std::fs::write(
        &costs,
        "(tolerances: [\n (path: \"detectors.plus.decenter_mm.x\"),\n (path: \"chart.despace_mm\", weight: 2.0),\n])",
    )
    .unwrap();
    let out = dir.join("bad");
    let o = budget(
        &["--target-yield", "0.9", "--costs", costs.to_str().unwrap()],
        &out,
    );
    assert_input_error(
        &o,
        &["costs.ron, line 3", "chart.despace_mm", "not a tolerance"],
        &out,
    );
    // No scale may go below the file's: the spot leaves the diode in too many benches.
    std::fs::write(&costs, "(default: (min_scale: 1.0))").unwrap();
    let out = dir.join("unreachable");
    let o = budget(
        &[
            "--target-yield",
            "0.9",
            "--trials",
            "40",
            "--costs",
            costs.to_str().unwrap(),
        ],
        &out,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let s = read_json(&out.join("summary.json"));
    assert_eq!(s["reached"], false, "{s}");
    assert!(
        s["reason"].as_str().unwrap().contains("tightest scales"),
        "{s}"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("UNREACHABLE"));
    crate::outputs_schema::check_file(&out.join("summary.json"), "BudgetSummary");
}

/// summary.json without what a resume changes by design (its provenance names the resumed
/// records it read).
fn outcome_of(dir: &Path) -> serde_json::Value {
    let mut s = read_json(&dir.join("summary.json"));
    s.as_object_mut().unwrap().remove("provenance");
    s
}

/// A search stopped after its first round and resumed, and one whose baseline was traced by two
/// shards and then resumed from both, give exactly the uninterrupted search's outputs (every
/// trial is a function of the seed, its index and its budget).
#[test]
fn a_resumed_or_sharded_budget_equals_the_uninterrupted_one() {
    let dir = TempDir::new("budget-resume");
    let args = |rounds: &'static str| {
        [
            "--target-yield",
            "0.9",
            "--trials",
            "60",
            "--budget-rounds",
            rounds,
        ]
    };
    let whole = dir.join("whole");
    let o = budget(&args("3"), &whole);
    assert!(o.status.success(), "{}", stderr(&o));
    let first = dir.join("first");
    let o = budget(&args("1"), &first);
    assert!(o.status.success(), "{}", stderr(&o));
    let resumed = dir.join("resumed");
    let mut a = args("3").to_vec();
    a.extend(["--resume", first.to_str().unwrap()]);
    let o = budget(&a, &resumed);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("from the resumed records"),
        "{}",
        stderr(&o)
    );
    assert_eq!(outcome_of(&resumed), outcome_of(&whole));
    let text = |d: &Path| std::fs::read_to_string(d.join("budget.ron")).unwrap();
    assert_eq!(text(&resumed), text(&whole));
    // Two shards trace the baseline's trials between them and stop; a resume from both goes on.
    let mut shards = Vec::new();
    for k in ["0/2", "1/2"] {
        let out = dir.join(&format!("shard{}", &k[..1]));
        let mut a = args("3").to_vec();
        a.extend(["--shard", k]);
        let o = budget(&a, &out);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(!out.join("summary.json").exists());
        shards.push(out);
    }
    let merged = dir.join("merged");
    let mut a = args("3").to_vec();
    a.push("--resume");
    a.extend(shards.iter().map(|p| p.to_str().unwrap()));
    let o = budget(&a, &merged);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(outcome_of(&merged), outcome_of(&whole));
    // Records of another run are refused at the field.
    let mut a = vec!["--target-yield", "0.8", "--trials", "60", "--resume"];
    a.push(first.to_str().unwrap());
    let bad = dir.join("bad");
    assert_input_error(
        &budget(&a, &bad),
        &["--resume", "target_yield differs"],
        &bad,
    );
}

/// A variable attenuator in the stronger arm (`kind: Attenuator`) on the small bench: the
/// diodes' responsivity mismatch, 8–10 % here and fixed (no budget can remove it), keeps ι′
/// beyond 1 % before it, and it nulls ι′ in every trial at a cost
/// in k′ the summary states. The budget reaches the target with it, writes it into
/// budget.ron, and the file reads back. A dataset, a trial's bench file and the image-quality
/// stages, which cannot carry it, refuse it at its line.
#[test]
fn an_attenuator_balances_every_trial_and_travels_with_the_budget() {
    let dir = TempDir::new("budget-attenuator");
    let tol = dir.join("attenuated.ron");
    std::fs::write(
        &tol,
        "(\n    tolerances: [\n        (path: \"electronics.detector.responsivity_scale_minus\", \
         range: Between(-0.1, -0.08), fixed: true),\n        (path: \"detectors.plus.decenter_mm.x\", \
         range: PlusMinus(0.5)),\n        (path: \"lamp.decenter_mm.x\", range: \
         PlusMinus(0.5)),\n    ],\n    compensators: [\n        (kind: \
         Attenuator(arm: Stronger, min_transmission: 0.5), objective: Balance),\n    ],\n    \
         limits: [(metric: \"imbalance\", abs_max: 0.01)],\n)\n",
    )
    .unwrap();
    let bench = scene("tests/symmetric_arms.ron");
    let run = |extra: &[&str], out: &Path| {
        let mut a = vec![
            "tolerance",
            bench.as_str(),
            "--tolerances",
            tol.to_str().unwrap(),
            "--rays",
            "4096",
            "--seed",
            "3",
        ];
        a.extend_from_slice(extra);
        a.extend(["--out", out.to_str().unwrap()]);
        spibench(&a, &[])
    };
    let mc = dir.join("mc");
    let o = run(&["--trials", "20"], &mc);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        crate::common::stdout(&o).contains("attenuator"),
        "{}",
        crate::common::stdout(&o)
    );
    crate::outputs_schema::check_file(&mc.join("summary.json"), "ToleranceSummary");
    let s = read_json(&mc.join("summary.json"));
    assert_eq!(s["attenuator"]["arm"], "Stronger", "{}", s["attenuator"]);
    let a = &s["analysis"]["attenuator"];
    assert_eq!(a["trials"], 20, "{a}");
    assert!(
        a["k_prime_mean_after"].as_f64() < a["k_prime_mean_before"].as_f64(),
        "{a}"
    );
    for r in s["trial_rows"].as_array().unwrap() {
        let v = &r["values"];
        let before = v["imbalance_electrical_unattenuated"].as_f64().unwrap();
        let t = v["attenuator_transmission_plus"]
            .as_f64()
            .unwrap()
            .min(v["attenuator_transmission_minus"].as_f64().unwrap());
        assert!(before.abs() > 0.01 && t < 1.0, "{v}");
        assert!(
            v["imbalance_electrical"].as_f64().unwrap().abs() < 1e-9,
            "{v}"
        );
    }
    assert_eq!(s["analysis"]["yields"][0]["passed"], 20);

    let out = dir.join("budget");
    let o = run(
        &["--budget", "--target-yield", "0.9", "--trials", "40"],
        &out,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let b = read_json(&out.join("summary.json"));
    assert_eq!(b["reached"], true, "{b}");
    let text = std::fs::read_to_string(out.join("budget.ron")).unwrap();
    assert!(
        text.contains(
            "(kind: Attenuator(arm: Stronger, min_transmission: 0.5), objective: Balance)"
        ),
        "{text}"
    );
    let back = dir.join("back");
    let budget = out.join("budget.ron");
    let o = spibench(
        &[
            "tolerance",
            &bench,
            "--tolerances",
            budget.to_str().unwrap(),
            "--rays",
            "4096",
            "--seed",
            "11",
            "--trials",
            "10",
            "--out",
            back.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        read_json(&back.join("summary.json"))["analysis"]["attenuator"]["trials"],
        10
    );

    for (extra, frag) in [
        (&["--quality"][..], "recorded and solved"),
        (&["--trial", "2"][..], "a trial's bench file"),
    ] {
        let o = run(extra, &dir.join("refused"));
        crate::common::assert_input_error(
            &o,
            &["attenuated.ron", "line 8", frag],
            &dir.join("refused"),
        );
    }
}
