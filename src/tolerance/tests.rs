use std::path::Path;

use super::*;
use crate::quantities::BenchMetric;
use crate::scene::tolerance::ToleranceSet;

fn symmetric() -> BenchDoc {
    BenchDoc::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron"))
        .unwrap()
}

fn set(doc: &BenchDoc, text: &str) -> ToleranceSet {
    ToleranceSet::parse(text, Path::new("t.ron"), doc).unwrap()
}

/// Tolerances that swap into each other under the symmetry of the bench's arms: each part of
/// arm + has its mirror image in arm −, with the same distribution.
const SYMMETRIC: &str = "(tolerances: [
    (path: \"detectors.plus.decenter_mm.x\", range: PlusMinus(0.6)),
    (path: \"detectors.minus.decenter_mm.x\", range: PlusMinus(0.6)),
    (path: \"arm_plus_lens.despace_mm\", range: PlusMinus(2.0)),
    (path: \"arm_minus_lens.despace_mm\", range: PlusMinus(2.0)),
], limits: [(metric: \"imbalance\", abs_max: 0.01)])";

const RAYS: u64 = 16_384;

fn opts(seed: u64) -> ToleranceOptions {
    ToleranceOptions {
        rays: RAYS,
        seed,
        quality: false,
    }
}

#[test]
fn zero_tolerances_reproduce_the_nominal_bench_exactly() {
    let doc = symmetric();
    let s = set(&doc, SYMMETRIC).scaled(0.0);
    let o = opts(3);
    let nominal = nominal(&doc, &o).unwrap();
    let (d, dev, _) = trial_doc(&doc, &s, &o, 5).unwrap();
    assert!(dev.iter().all(|(_, v)| *v == 0.0));
    assert_eq!(d.file, doc.file);
    let (r, _) = trial(&doc, &s, &nominal, &o, 5).unwrap();
    assert_eq!(r.values, recorded((&doc, &nominal), (&doc, &nominal)));
    for name in [
        "imbalance_diff",
        "k_prime_diff",
        "b_minus_minus_b_plus_diff",
    ] {
        assert_eq!(r.value(name), Some(0.0), "{name}");
    }
}

/// With arm-symmetric tolerances, the imbalance over the trials is centred on the nominal
/// bench's (0 up to its ray noise): |mean| < 3·√(s²/n + SE_nominal²).
#[test]
fn symmetric_tolerances_centre_the_imbalance_on_zero() {
    let doc = symmetric();
    let s = set(&doc, SYMMETRIC);
    let o = opts(4);
    let nom = nominal(&doc, &o).unwrap();
    let n = 24;
    let recs: Vec<TrialRecord> = (0..n)
        .map(|i| trial(&doc, &s, &nom, &o, i).unwrap().0)
        .collect();
    let a = analyse(&s, &recs, None);
    let imb = a
        .percentiles
        .iter()
        .find(|p| p.metric == "imbalance")
        .unwrap();
    let se_nom = nom.metrics[BenchMetric::Imbalance].stderr();
    let bound = 3.0 * ((imb.std_dev.powi(2) / n as f64) + se_nom.powi(2)).sqrt();
    eprintln!(
        "mean imbalance {:.3e}, spread {:.3e}, bound {bound:.3e}",
        imb.mean, imb.std_dev
    );
    assert!(imb.std_dev > 0.0, "the tolerances moved nothing");
    assert!(imb.mean.abs() < bound, "{} vs {bound}", imb.mean);
}

/// The symmetric bench with a baffle far outside every beam.
fn with_far_baffle() -> BenchDoc {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tests/symmetric_arms.ron");
    let text = std::fs::read_to_string(&path).unwrap().replacen(
        "elements: [",
        "elements: [ Baffle(name: \"far_baffle\", position_mm: (300.0, 300.0, -200.0), \
         axis: Vector((0.0, 0.0, 1.0)), width_mm: 20.0, height_mm: 20.0, hole_diameter_mm: 5.0),",
        1,
    );
    BenchDoc::parse(&text, &path).unwrap()
}

/// A baffle far outside every beam: its sensitivity is zero within the paired standard error.
#[test]
fn a_tolerance_that_cannot_matter_has_no_sensitivity() {
    let doc = with_far_baffle();
    let s = set(
        &doc,
        "(tolerances: [(path: \"far_baffle.decenter_mm.x\", range: PlusMinus(5.0)), \
         (path: \"far_baffle.tilt_deg.y\", range: PlusMinus(10.0))])",
    );
    let o = opts(5);
    let nom = nominal(&doc, &o).unwrap();
    let rows = sensitivity(&doc, &s, &nom, &o, None, &|_, _| {}).unwrap();
    for r in &rows {
        for high in [false, true] {
            for m in ["imbalance", "k_prime", "b_minus_minus_b_plus", "leak_plus"] {
                let d = r.at(high, &format!("{m}_diff"));
                let se = r.at(high, &format!("{m}_diff_stderr"));
                assert!(
                    d.abs() <= 3.0 * se || d == 0.0,
                    "{} {m}: {d} ± {se}",
                    r.path
                );
            }
        }
    }
}

/// The bench of trial K, written as RON and read back, traces to the trial's recorded metrics
/// bit for bit.
#[test]
fn a_trial_rebuilt_from_ron_traces_identically() {
    let doc = symmetric();
    let s = set(&doc, SYMMETRIC);
    let o = opts(6);
    let nom = nominal(&doc, &o).unwrap();
    let (rec, _) = trial(&doc, &s, &nom, &o, 3).unwrap();
    let (d, _, _) = trial_doc(&doc, &s, &o, 3).unwrap();
    let text = d.to_ron().unwrap();
    let back = BenchDoc::parse(&text, Path::new("trial_3.ron")).unwrap();
    let p = evaluate(&back, Vec::new(), &o.with_quality(false)).unwrap();
    assert_eq!(recorded((&back, &p), (&doc, &nom)), rec.values);
}

#[test]
fn draws_are_keyed_by_seed_and_index_and_respect_ranges() {
    let doc = symmetric();
    let s = set(
        &doc,
        "(tolerances: [(path: \"arm_plus_lens.despace_mm\", range: Between(-0.5, 1.0), \
         distribution: TruncatedNormal(sigmas: 1.0)), (path: \"arm_minus_lens.despace_mm\", \
         range: PlusMinus(1.0), distribution: Normal(sigmas: 2.0))])",
    );
    assert_eq!(draw(&s, 1, 7), draw(&s, 1, 7));
    assert_ne!(draw(&s, 1, 7), draw(&s, 1, 8));
    assert_ne!(draw(&s, 2, 7), draw(&s, 1, 7));
    let mut normals = Vec::new();
    for i in 0..2000 {
        let d = draw(&s, 9, i);
        assert!((-0.5..=1.0).contains(&d[0].1));
        normals.push(d[1].1);
    }
    let sd = (normals.iter().map(|x| x * x).sum::<f64>() / normals.len() as f64).sqrt();
    // σ = 0.5; the standard error of a sample standard deviation of 2000 is 1.6 %.
    assert!((sd - 0.5).abs() < 0.05 * 0.5, "{sd}");
}

#[test]
fn percentiles_and_yields() {
    let v: Vec<f64> = (0..=100).map(|i| i as f64).collect();
    assert_eq!(percentile(&v, 50.0), 50.0);
    assert_eq!(percentile(&v, 97.7), 97.7);
    assert!(percentile(&[], 50.0).is_nan());
    let y = yield_row("x".into(), 3, 4);
    assert_eq!(y.fraction, 0.75);
    assert!((y.stderr - (0.75f64 * 0.25 / 4.0).sqrt()).abs() < 1e-15);
    // Wilson 95 % interval of 3 of 4: 0.3006 … 0.9544 (Newcombe 1998, method 3); of 20 of
    // 20: 0.8389 … 1, where p ± 1.96·SE would have no width.
    let [lo, hi] = y.ci95;
    assert!(
        (lo - 0.3006).abs() < 1e-4 && (hi - 0.9544).abs() < 1e-4,
        "{lo} {hi}"
    );
    let [lo, hi] = wilson95(20, 20);
    assert!((lo - 0.8389).abs() < 1e-4 && hi == 1.0, "{lo} {hi}");
}

/// The electrical imbalance a trial records equals the optical one when the diodes are
/// matched, and moves by their responsivity mismatch otherwise, in closed form: with
/// r = s₊/s₋, ι′ = (r(1 + ι) − (1 − ι))/(r(1 + ι) + (1 − ι)). The responsivity does not
/// enter the trace, so both benches have the same optical ι (common random numbers).
#[test]
fn the_electrical_imbalance_moves_by_the_responsivity_mismatch() {
    let doc = symmetric();
    let o = opts(7);
    let path = "electronics.detector.responsivity_scale_minus";
    let plus = doc
        .get("electronics.detector.responsivity_scale_plus")
        .unwrap();
    // Matched diodes first.
    let doc = doc.with(&[(path.to_string(), plus)]).unwrap();
    let nom = nominal(&doc, &o).unwrap();
    let v = recorded((&doc, &nom), (&doc, &nom));
    let get = |v: &[(String, f64)], k: &str| value_of(v, k);
    let iota = get(&v, "imbalance");
    assert!(iota != 0.0);
    let s = crate::scene::run::detector_si(&doc.file.electronics.detector)
        .unwrap()
        .responsivity_scale;
    assert_eq!(s[0], s[1]);
    // Matched diodes: ι′ = ((1 + ι) − (1 − ι))/2 = ι, to the rounding of terms near 1.
    let e0 = get(&v, IMBALANCE_ELECTRICAL);
    assert!((e0 - iota).abs() <= 4.0 * f64::EPSILON, "{e0} vs {iota}");
    assert_eq!(get(&v, &format!("{IMBALANCE_ELECTRICAL}_diff")), 0.0);
    let s_minus = 0.98 * plus;
    let mismatched = doc.with(&[(path.to_string(), s_minus)]).unwrap();
    let p = evaluate(&mismatched, Vec::new(), &o).unwrap();
    let w = recorded((&mismatched, &p), (&doc, &nom));
    assert_eq!(get(&w, "imbalance"), iota, "the optical imbalance moved");
    let r = s[0] / s_minus;
    let closed = (r * (1.0 + iota) - (1.0 - iota)) / (r * (1.0 + iota) + (1.0 - iota));
    let e = get(&w, IMBALANCE_ELECTRICAL);
    assert!((e - closed).abs() <= 1e-15, "{e} vs {closed}");
    // To first order the mismatch (s₊ − s₋)/(s₊ + s₋) = 0.02/1.98 adds to ι.
    assert!((e - iota - 0.02 / 1.98).abs() < 1e-3, "{e} {iota}");
    // The yield judges a limit on the imbalance electrically, the optical one beside it: a
    // limit between the two passes optically and fails electrically.
    let limit = (iota.abs() + e.abs()) / 2.0;
    let set = set(
        &doc,
        &format!(
            "(tolerances: [(path: \"{path}\", range: PlusMinus(0.05))], \
             limits: [(metric: \"imbalance\", abs_max: {limit})])"
        ),
    );
    let rec = TrialRecord {
        index: 0,
        deviations: vec![(path.into(), s_minus - s[1])],
        compensators: Vec::new(),
        values: w,
        error: None,
        needed_travel: Vec::new(),
        rays: None,
    };
    let a = analyse(&set, &[rec], None);
    assert_eq!(a.yields[0].passed, 0);
    assert_eq!(a.yields[0].optical.as_ref().unwrap().passed, 1);
    assert_eq!(a.failing_trials, 1);
}

/// A compensator with too little travel ends a trial at its limit; the trial records the
/// travel a wider range settles at, beyond the file's. On the paper's bench the DMD's tilt
/// moves the imbalance by about 0.8 per degree (docs/guide/03-tolerances.md), so a tilt
/// error of 0.3° is far more than a ±0.02° adjustment can take back. That figure is the plane
/// mirrors' (with the diffractive DMD the tilt moves the blaze instead), so the test reads the
/// paper bench with the geometric DMD model (the Mitsuba case, equal to the shipped bench but
/// for the model).
#[test]
fn a_compensator_out_of_travel_records_the_travel_it_would_need() {
    let doc = BenchDoc::read(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/mitsuba/cases/paper_bench.ron"),
    )
    .unwrap();
    let s = set(
        &doc,
        "(tolerances: [(path: \"dmd.tilt_deg\", range: Between(0.3, 0.35))], \
         compensators: [(path: \"dmd.tilt_deg\", range: PlusMinus(0.02), \
         objective: Balance)], limits: [(metric: \"imbalance\", abs_max: 0.01)])",
    );
    let o = ToleranceOptions {
        rays: 8192,
        seed: 8,
        quality: false,
    };
    let nom = nominal(&doc, &o).unwrap();
    let (rec, _) = trial(&doc, &s, &nom, &o, 0).unwrap();
    let (_, settled) = &rec.compensators[0];
    assert!(
        summaries::at_bound(&s.compensators[0], *settled),
        "not at its limit: {settled}"
    );
    let t = &rec.needed_travel[0];
    assert_eq!(t.settled, *settled);
    assert!(
        t.needed.abs() > settled.abs() && t.needed.signum() == settled.signum(),
        "{t:?}"
    );
    let a = analyse(&s, std::slice::from_ref(&rec), None);
    assert_eq!(a.compensators[0].short.len(), 1);
    assert_eq!(a.compensators[0].short[0].needed, t.needed);
}

/// The attenuator on a traced bench: in front of a diode it acts on the current as that
/// diode's responsivity scale does on the light (ι′ of the attenuated bench with scales s
/// equals ι′ of the plain bench with s₊T₊, its standard error too, by the delta method on
/// either side), k± and the powers scale by T±, k′ is their sum, b± keep their dark current,
/// and the trial's record holds ι′ = 0 with the transmissions set and the values before.
#[test]
fn the_attenuator_acts_on_the_traced_metrics_as_a_scale_on_the_diodes_light() {
    use crate::pipeline::perturb::attenuated;
    use crate::scene::tolerance::ATTENUATOR_VALUES;
    let doc = symmetric();
    let o = opts(2);
    let d = doc
        .with(&[
            ("detectors.plus.decenter_mm.x".into(), 0.45),
            (
                "electronics.detector.responsivity_scale_minus".into(),
                0.899,
            ),
        ])
        .unwrap();
    let p = evaluate(&d, Vec::new(), &o).unwrap();
    let s = p.responsivity_scale.unwrap();
    let t = [0.8, 1.0];
    let q = attenuated(&d, &p, t);
    let (e_att, e_scaled) = (
        q.electrical_imbalance().unwrap(),
        crate::transport::metrics::electrical_imbalance(
            &p.metrics[BenchMetric::Imbalance],
            [s[0] * t[0], s[1] * t[1]],
        ),
    );
    assert!(
        (e_att.value - e_scaled.value).abs() < 1e-12,
        "{e_att:?} {e_scaled:?}"
    );
    assert!((e_att.stderr() / e_scaled.stderr() - 1.0).abs() < 1e-9);
    let m = |e: &crate::pipeline::evaluate::Evaluation, k: BenchMetric| e.metrics[k].value;
    assert!((m(&q, BenchMetric::KPlus) - 0.8 * m(&p, BenchMetric::KPlus)).abs() < 1e-15);
    assert_eq!(m(&q, BenchMetric::KMinus), m(&p, BenchMetric::KMinus));
    let kp = m(&q, BenchMetric::KPlus) + m(&q, BenchMetric::KMinus);
    assert!((m(&q, BenchMetric::KPrime) / kp - 1.0).abs() < 1e-12);
    assert!(q.metrics[BenchMetric::KPrime].stderr() <= p.metrics[BenchMetric::KPrime].stderr());
    let dark = d.file.detectors.plus.dark_current_a.0;
    let b = |e: &crate::pipeline::evaluate::Evaluation| e.metrics[BenchMetric::BPlus].value;
    assert!((b(&q) - dark - 0.8 * (b(&p) - dark)).abs() <= 1e-12 * b(&p).abs());
    // [1, 1] is the bench itself, bit for bit.
    assert_eq!(attenuated(&d, &p, [1.0; 2]).metrics, p.metrics);

    // A trial with the attenuator: the file's tolerances set to this bench (the − diode 10 %
    // less responsive than its nominal 0.999).
    let text = "(tolerances: [(path: \"detectors.plus.decenter_mm.x\", range: Between(0.45, 0.45)),\n\
                (path: \"electronics.detector.responsivity_scale_minus\", range: Between(-0.1, -0.1))],\n\
                compensators: [(kind: Attenuator(min_transmission: 0.5), objective: Balance)],\n\
                limits: [(metric: \"imbalance\", abs_max: 0.01)])";
    let s = set(&doc, text);
    let nom = nominal(&doc, &o).unwrap();
    let (r, _) = trial(&doc, &s, &nom, &o, 0).unwrap();
    let before = p.electrical_imbalance().unwrap().value;
    assert!(before.abs() > 0.01, "{before}");
    assert!(
        r.value("imbalance_electrical").unwrap().abs() < 1e-12,
        "{r:?}"
    );
    let v: Vec<f64> = ATTENUATOR_VALUES
        .iter()
        .map(|k| r.value(k).unwrap())
        .collect();
    let want =
        crate::pipeline::perturb::attenuator_transmissions(before, s.attenuator.as_ref().unwrap());
    assert_eq!(v[..2], want);
    assert_eq!(v[2], before);
    assert_eq!(v[3], m(&p, BenchMetric::KPrime));
    assert!(r.value("k_prime").unwrap() < v[3]);
    let a = analyse(&s, &[r], None);
    let row = a.attenuator.unwrap();
    assert_eq!(
        (row.trials, row.at_min, row.in_plus + row.in_minus),
        (1, 0, 1)
    );
}

/// A staged trial (`staged::trial`) reaches the verdict of the trial traced at the run's rays:
/// kept at its first stage only where that verdict stands at four standard errors, and
/// otherwise the full trace itself, bit for bit. The symmetric bench, twice: with the + diode up
/// to 2.5 mm off (its spot leaves the diode) and the − diode's responsivity ±0.7 behind a
/// variable attenuator at T ≥ 0.5 (|ι′| ≤ 0.342 is brought within 0.01: trials on both sides
/// of its reach, far from it), and with no attenuator and the responsivity ±0.03, whose ι′ of
/// about ±0.015 falls near the limit (trials the first stage cannot decide).
#[test]
fn a_staged_trial_keeps_the_verdict_of_the_full_trace() {
    use crate::tolerance::budget_search::passes;
    let doc = symmetric();
    let files = [
        "(tolerances: [(path: \"detectors.plus.decenter_mm.x\", range: PlusMinus(2.5)),\n\
         (path: \"electronics.detector.responsivity_scale_minus\", range: PlusMinus(0.7))],\n\
         compensators: [(kind: Attenuator(min_transmission: 0.5), objective: Balance)],\n\
         limits: [(metric: \"imbalance\", abs_max: 0.01)])",
        "(tolerances: [(path: \"electronics.detector.responsivity_scale_minus\", range: PlusMinus(0.03))],\n\
         limits: [(metric: \"imbalance\", abs_max: 0.01)])",
    ];
    let rays = staged::MIN_FIRST_STAGE_BATCHES * staged::FIRST_STAGE_DIVISOR * 1024;
    let o = ToleranceOptions {
        rays,
        seed: 3,
        quality: false,
    };
    let nom = nominal(&doc, &o).unwrap();
    let (mut kept, mut retraced, mut verdicts) = (0, 0, [0, 0]);
    for text in files {
        let s = set(&doc, text);
        let stage = staged::first_stage(&doc, &s, &o).unwrap().unwrap();
        assert_eq!(stage.rays, rays / staged::FIRST_STAGE_DIVISOR);
        for i in 0..8 {
            let st = staged::trial(&doc, &s, (&nom, &stage), &o, i).unwrap();
            let (full, _) = trial(&doc, &s, &nom, &o, i).unwrap();
            let v = passes(&s, false, &full);
            assert_eq!(passes(&s, false, &st), v, "trial {i}: {st:?} {full:?}");
            verdicts[v as usize] += 1;
            match st.rays {
                Some(r) => {
                    assert_eq!(r, stage.rays);
                    kept += 1;
                }
                None => {
                    assert_eq!(st, full);
                    retraced += 1;
                }
            }
        }
        // With --quality a trial is not staged.
        assert!(!staged::applies(&s, true));
    }
    assert!(
        kept >= 6 && retraced >= 1,
        "{kept} kept, {retraced} traced again"
    );
    assert!(verdicts[0] > 0 && verdicts[1] > 0, "{verdicts:?}");
}
