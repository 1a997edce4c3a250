//! Tolerance files: parsing, located errors, the attenuator kind, and the trial records.

use super::*;

fn doc() -> BenchDoc {
    BenchDoc::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron")).unwrap()
}

fn parse(text: &str) -> Result<ToleranceSet> {
    ToleranceSet::parse(text, Path::new("t.ron"), &doc())
}

#[test]
fn shipped_file_reads() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tolerances/paper_bench.ron");
    let s = ToleranceSet::read(&p, &doc()).unwrap();
    assert!(s.tolerances.len() >= 10);
    // The DMD's tilt is a device specification, marked fixed; nothing else is.
    let fixed: Vec<&str> = s
        .tolerances
        .iter()
        .filter(|t| t.is_fixed())
        .map(|t| t.path.as_str())
        .collect();
    assert_eq!(fixed, ["dmd.tilt_deg"]);
    // A budget keeps a fixed tolerance at scale 1, the others within their bounds.
    let costs = crate::scene::budget_costs::default_costs(&s);
    let pinned = s.pin_fixed(&costs);
    for (t, c) in s.tolerances.iter().zip(&pinned) {
        let want = if t.is_fixed() {
            (1.0, 1.0)
        } else {
            (costs[0].min_scale, costs[0].max_scale)
        };
        assert_eq!((c.min_scale, c.max_scale), want, "{}", t.path);
    }
}

#[test]
fn ranges_and_distributions() {
    let s = parse(
        "(tolerances: [\n (path: \"dmd.tilt_deg\", range: Between(-1.0, 0.5), distribution: \
         TruncatedNormal(sigmas: 2.0)),\n (path: \"chart.despace_mm\", range: PlusMinus(0.2)),\n],\
         limits: [(metric: \"imbalance\", abs_max: 0.01)])",
    )
    .unwrap();
    assert_eq!(s.tolerances[0].min, -1.0);
    assert_eq!(s.tolerances[0].nominal, 12.0);
    assert_eq!((s.tolerances[1].min, s.tolerances[1].max), (-0.2, 0.2));
    assert!((Distribution::Uniform.std_dev(1.0) - 0.288_675).abs() < 1e-6);
    assert_eq!(Distribution::Normal { sigmas: 2.0 }.std_dev(4.0), 1.0);
    // Truncation at ±1σ: σ_t = 0.5396σ.
    let t = Distribution::TruncatedNormal { sigmas: 1.0 }.std_dev(2.0);
    assert!((t - 0.5396).abs() < 1e-3, "{t}");
    assert!(s.limits[0].holds(0.005) && !s.limits[0].holds(-0.02));
}

#[test]
fn bad_files_are_located_input_errors() {
    for (text, frags) in [
        (
            "(tolerances: [\n(path: \"no_such.despace_mm\", range: PlusMinus(1.0))])",
            &["t.ron, line 2", "no_such"][..],
        ),
        (
            "(tolerances: [\n\n(path: \"chart.despace_mm\", range: Between(1.0, -1.0))])",
            &["line 3", "empty"][..],
        ),
        (
            "(tolerances: [(path: \"dmd.tilt_deg\", range: PlusMinus(20.0))])",
            &["line 1", "dmd.tilt_deg", "cannot deviate"][..],
        ),
        (
            "(tolerances: [(path: \"chart.despace_mm\", rnage: PlusMinus(1.0))])",
            &["line 1", "rnage"][..],
        ),
        (
            "(tolerances: [], limits: [(metric: \"imbalanse\", abs_max: 0.1)])",
            &["imbalanse"][..],
        ),
        (
            "(tolerances: [(path: \"chart.despace_mm\", range: PlusMinus(1.0), \
             distribution: Normal(sigmas: 0.0))])",
            &["sigmas"][..],
        ),
        (
            "(tolerances: [(path: \"chart.despace_mm\", range: PlusMinus(1.0), \
             fixed: 1)])",
            &["fixed"][..],
        ),
        (
            "(tolerances: [], compensators: [\n\n(kind: Attenuator(min_transmission: 1.5))])",
            &[
                "line 3",
                "compensators[0].kind",
                "min_transmission",
                "(0, 1)",
            ][..],
        ),
        (
            "(tolerances: [], compensators: [\n(kind: Attenuator(min_transmission: 0.5), \
             objective: Power)])",
            &["line 2", "only balance"][..],
        ),
        (
            "(tolerances: [], compensators: [(kind: Attenuator(min_transmission: 0.5)),\n\
             (kind: Attenuator(arm: Plus, min_transmission: 0.5))])",
            &["line 2", "compensators[1].kind", "one attenuator"][..],
        ),
        (
            "(tolerances: [], compensators: [(kind: Attenuator(arm: Both, \
             min_transmission: 0.5))])",
            &["Both"][..],
        ),
        (
            "(tolerances: [], compensators: [(kind: Attenuator(min_transmission: 0.5), \
             path: \"chart.despace_mm\", range: PlusMinus(1.0))])",
            &["compensators[0]", "either a bench variable"][..],
        ),
    ] {
        let e = parse(text).unwrap_err();
        assert!(e.is_user_error(), "{e}");
        let s = e.to_string();
        for f in frags {
            assert!(s.contains(f), "{text}: {s} lacks {f}");
        }
    }
}

/// The attenuator is a compensator of its own kind: the stronger arm by default, counted
/// among the compensators, and refused where a bench document must hold it.
#[test]
fn an_attenuator_reads_as_a_compensator_kind() {
    let text = "(tolerances: [],\n compensators: [\n  (kind: Attenuator(min_transmission: \
                0.5), objective: Balance),\n  (path: \"chart.despace_mm\", range: \
                PlusMinus(0.5))])";
    let s = parse(text).unwrap();
    assert_eq!(
        s.attenuator,
        Some(Attenuator {
            arm: AttenuatorArm::Stronger,
            min_transmission: 0.5
        })
    );
    assert_eq!((s.compensators.len(), s.compensator_count()), (1, 2));
    let e = s
        .refuse_attenuator(text, "a dataset's benches")
        .unwrap_err();
    assert!(e.is_user_error());
    let m = e.to_string();
    assert!(
        m.contains("line 3") && m.contains("a dataset's benches"),
        "{m}"
    );
    let plain = parse("(tolerances: [])").unwrap();
    assert!(plain.refuse_attenuator("", "x").is_ok() && plain.attenuator.is_none());
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tolerances/paper_bench_balanced.ron");
    let b = ToleranceSet::read(&p, &doc()).unwrap();
    let plain = ToleranceSet::read(&p.with_file_name("paper_bench.ron"), &doc()).unwrap();
    // The same 27 tolerances and limits as the compensator-free file, and the attenuator.
    assert_eq!(
        (b.tolerances.len(), &b.tolerances, &b.limits),
        (27, &plain.tolerances, &plain.limits)
    );
    assert_eq!(b.attenuator.map(|a| a.min_transmission), Some(0.5));
    assert!(b.compensators.is_empty());
}

#[test]
fn shard_files_read_back_bit_for_bit() {
    let s = ShardFile {
        spibench_version: "x".into(),
        scene: "s".into(),
        bench_ron: "()".into(),
        tolerances_path: "t.ron".into(),
        tolerances_text: "t".into(),
        rays: 10,
        seed: 1,
        trials: 2,
        quality: false,
        shard: (0, 1),
        nominal: vec![("a".into(), 0.1 + 0.2)],
        sensitivity: None,
        records: vec![TrialRecord {
            index: 0,
            deviations: vec![("p".into(), -1.234_567_890_123_456_7e-5)],
            compensators: vec![],
            values: vec![
                ("k".into(), std::f64::consts::PI / 3.0),
                ("n".into(), 1e300),
            ],
            error: None,
            needed_travel: vec![NeededTravel {
                path: "d.x".into(),
                settled: 1.5,
                needed: 2.25,
                beyond: false,
            }],
            rays: Some(3072),
        }],
    };
    let text = shard_to_ron(&s).unwrap();
    let back: ShardFile = crate::scene::parse_ron(&text, Path::new("s.ron")).unwrap();
    assert_eq!(back, s);
}
