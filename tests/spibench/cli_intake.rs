//! `spibench run --scope-record` and `spibench intake` end to end: the records of a run taken
//! back in give the run's own measurement vectors, reconstructions and scores, bit for bit,
//! for every scheme and ratio, from the CSV and from the `.npy`; damaged records and channel
//! names that do not match are located input errors.

use std::path::Path;

use crate::common::*;

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn intake(args: &[&str]) -> std::process::Output {
    spibench(&[&["intake"], args].concat(), &[])
}

/// Every result of `intake` equals the run's: scores in summary.json, measurement vectors and
/// reconstructions byte for byte.
fn assert_same_as_run(run: &Path, taken: &Path) {
    let r = read_json(&run.join("summary.json"));
    let i = read_json(&taken.join("summary.json"));
    let results = i["results"].as_array().unwrap();
    assert_eq!(results.len(), r["results"].as_array().unwrap().len());
    for x in results {
        let (scheme, ratio) = (x["scheme"].as_str().unwrap(), x["ratio"].as_f64().unwrap());
        let y = r["results"]
            .as_array()
            .unwrap()
            .iter()
            .find(|y| y["scheme"] == scheme && y["ratio"].as_f64() == Some(ratio))
            .unwrap();
        for k in [
            "psnr_db",
            "mssim",
            "iterations",
            "relative_residual",
            "measurements",
        ] {
            assert_eq!(x[k], y[k], "{scheme} {ratio} {k}");
        }
        let tag = format!("{scheme}_r{ratio:.4}");
        assert_eq!(
            bytes(&run.join(format!("arrays/measurements_{tag}_v.npy"))),
            bytes(&taken.join(format!("measurements/{tag}_v.npy"))),
            "{tag}"
        );
        assert_eq!(
            bytes(&run.join(format!("arrays/reconstruction_{tag}.npy"))),
            bytes(&taken.join(format!("reconstructions/{tag}.npy"))),
            "{tag}"
        );
    }
}

#[test]
fn intake_of_a_runs_scope_records_gives_the_run_bit_for_bit() {
    let dir = TempDir::new("intake-round-trip");
    let scene = small_paper_scene(&dir);
    let run = dir.join("run");
    let o = spibench(
        &[
            "run",
            "--repeats",
            "1",
            scene.to_str().unwrap(),
            "--out",
            run.to_str().unwrap(),
            "--seed",
            "4",
            "--scope-record",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for q in ["base", "complementary", "calibrated_base"] {
        let d = run.join("scope").join(q);
        crate::outputs_schema::check_file(&d.join("record.json"), "ScopeRecordMeta");
        crate::outputs_schema::check_file(&d.join("patterns.json"), "ScopePatterns");
        let meta = read_json(&d.join("record.json"));
        assert_eq!(meta["sequence"], q);
        let csv = std::fs::read_to_string(d.join("record.csv")).unwrap();
        assert!(csv.starts_with("Model,"), "{q}");
        assert!(csv.contains("\nLabel,RF,MON+,MON-,TRIG\nTIME,CH1,CH2,CH3,CH4\n"));
    }
    let truth = run.join("arrays/transport_x_w.npy");
    let bench = run.join("bench.ron");
    let common = [
        "--bench",
        bench.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
    ];
    // The CSV records, from the scope folder.
    let a = dir.join("intake-csv");
    let scope = run.join("scope");
    let o = intake(
        &[
            &[scope.to_str().unwrap(), "--out", a.to_str().unwrap()],
            &common[..],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    crate::outputs_schema::check_file(&a.join("summary.json"), "IntakeSummary");
    assert_same_as_run(&run, &a);
    let s = read_json(&a.join("summary.json"));
    for r in s["records"].as_array().unwrap() {
        assert_eq!(r["layout"], "tektronix");
        assert_eq!(r["frame_method"], "trigger");
        assert_eq!(r["timing_from"], "sidecar");
        assert_eq!(r["anomalies"].as_array().unwrap().len(), 0);
    }
    assert_eq!(s["calibration"].as_array().unwrap().len(), 2);
    let frames = std::fs::read_to_string(a.join("frames.csv")).unwrap();
    assert_eq!(frames.lines().count(), 1 + 256 + 512 + 272);
    assert!(a.join("report.html").is_file());
    // The .npy records, named one by one, with the patterns of each folder.
    let b = dir.join("intake-npy");
    let npys: Vec<String> = ["base", "complementary", "calibrated_base"]
        .iter()
        .map(|q| {
            scope
                .join(q)
                .join("record.npy")
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let npy_args: Vec<&str> = npys.iter().map(String::as_str).collect();
    let o = intake(&[&npy_args[..], &["--out", b.to_str().unwrap()], &common[..]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_as_run(&run, &b);

    // Channel names that the record does not have: refused, naming the record's channels.
    let c = dir.join("intake-bad-channels");
    let base = scope.join("base");
    let o = intake(&[
        base.to_str().unwrap(),
        "--channels",
        "RF=CH7",
        "--out",
        c.to_str().unwrap(),
    ]);
    assert_input_error(&o, &["CH7", "CH1 (RF)", "record.csv"], &c);
    // A clipped channel: MONITOR+'s screen narrowed (its header's Vertical Scale) so that its
    // samples sit at the screen's edge. Every frame is flagged, and the schemes that read
    // MONITOR+ are marked saturated with the count; SCB (RF) is not.
    let clipped = dir.join("clipped");
    std::fs::create_dir_all(&clipped).unwrap();
    for f in ["patterns.json", "patterns.npy"] {
        std::fs::copy(base.join(f), clipped.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(base.join("record.csv")).unwrap();
    let scale = text
        .lines()
        .find(|l| l.starts_with("Vertical Scale,"))
        .unwrap();
    let mut cells: Vec<&str> = scale.split(',').collect();
    cells[2] = "1e-9";
    let narrowed = cells.join(",");
    std::fs::write(
        clipped.join("record.csv"),
        text.replacen(scale, &narrowed, 1),
    )
    .unwrap();
    let e = dir.join("intake-clipped");
    let o = intake(&[clipped.to_str().unwrap(), "--out", e.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = read_json(&e.join("summary.json"));
    assert_eq!(s["records"][0]["clipped_frames"], 256);
    for r in s["results"].as_array().unwrap() {
        assert_eq!(r["saturated"], true, "{r}");
        assert_eq!(r["flagged_frames"], r["dmd_frames"], "{r}");
    }
    assert!(
        stdout(&o).contains("clipped frames: saturated"),
        "{}",
        stdout(&o)
    );
    // A damaged copy of a record: a located error (file, line).
    let damaged = dir.join("damaged");
    std::fs::create_dir_all(&damaged).unwrap();
    for f in ["patterns.json", "patterns.npy"] {
        std::fs::copy(base.join(f), damaged.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(base.join("record.csv")).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines[99] = "9.9e-6,NaN,0.1,0.1,0";
    std::fs::write(damaged.join("record.csv"), lines.join("\n") + "\n").unwrap();
    let d = dir.join("intake-damaged");
    let o = intake(&[damaged.to_str().unwrap(), "--out", d.to_str().unwrap()]);
    assert_input_error(&o, &["record.csv", "line 100", "not a finite number"], &d);
}
