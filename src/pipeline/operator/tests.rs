//! The traced operator against the record stage, and its adjoint.

use super::*;
use crate::acquisition::Scheme;
use crate::detector::RecordModel;
use crate::pipeline::evaluate;
use crate::rng::{self, uniform};
use crate::transport::Transport;

/// The kernel spec of `rays` rays (seed 3) on a `grid` of pixels over `field_mm`.
fn spec(chart: Option<&str>, grid: (usize, usize), field_mm: (f64, f64), rays: u64) -> KernelSpec {
    KernelSpec {
        rays,
        seed: 3,
        grid_px: grid,
        field_mm,
        chart: chart.map(String::from),
    }
}

fn paper_doc() -> BenchDoc {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    BenchDoc::read(&path).unwrap()
}

/// A small kernel of the paper bench (12 × 12 pixels over its 7.88 mm field) and the bench's
/// run scene, noise off, recorded frame by frame.
fn setup() -> (RunScene, Kernel) {
    let doc = paper_doc();
    let rays = 8 * crate::trace::RAYS_PER_BATCH;
    let kernel = clear_chart_kernel(&doc, &spec(None, (12, 12), (7.88, 7.88), rays)).unwrap();
    let mut scene = doc.run_scene().unwrap();
    scene.settings.noise = false;
    scene.settings.additive_noise = None;
    scene.settings.record = RecordModel::Frames;
    scene.settings.schemes = Scheme::all().to_vec();
    (scene, kernel)
}

fn random(n: usize, seed: u64) -> Vec<f64> {
    let mut r = rng::stream(seed, 0);
    (0..n).map(|_| uniform(&mut r)).collect()
}

#[test]
fn adjoint_is_exact_for_every_scheme() {
    let (scene, kernel) = setup();
    let mats = KernelMatrices::new(&kernel);
    let (patterns, m) = patterns_for(&scene, 0.1).unwrap();
    for scheme in Scheme::all() {
        let op = TracedOperator::new(&scene, &mats, &patterns, scheme, m).unwrap();
        let t = random(op.pixels, 1);
        let y: Vec<f64> = random(m, 2).iter().map(|v| v - 0.5).collect();
        let at = op.apply(&t).unwrap();
        let lhs = dot(&at, &y);
        let rhs = dot(&t, &op.apply_adjoint(&y).unwrap());
        // Relative to the Cauchy–Schwarz bound ‖At‖‖y‖ (⟨At, y⟩ itself sums cancelling terms).
        let scale = dot(&at, &at).sqrt() * dot(&y, &y).sqrt();
        assert!(
            (lhs - rhs).abs() <= 1e-12 * scale,
            "{scheme:?}: {lhs} vs {rhs}"
        );
    }
}

/// A t + y₀ is the noise-free record's measurement (frames, ideal channels) to rounding, for
/// every scheme; the calibrated scheme on the clear object, whose swings it divides by.
#[test]
fn operator_matches_the_noise_free_record() {
    let (scene, kernel) = setup();
    let mats = KernelMatrices::new(&kernel);
    let (patterns, m) = patterns_for(&scene, 0.1).unwrap();
    let object = random(kernel.grid.pixels(), 5);
    let ones = vec![1.0; kernel.grid.pixels()];
    let packed = crate::acquisition::PackedPatterns::new(patterns.clone());
    for scheme in Scheme::all() {
        let op = TracedOperator::new(&scene, &mats, &patterns, scheme, m).unwrap();
        let t = if scheme == Scheme::DoubleArmCalibrated {
            &ones
        } else {
            &object
        };
        let transport = Transport::from_kernel_linear(&scene.bench, &kernel, t).unwrap();
        let rec = evaluate::acquire(&scene, &transport, &packed, 9, &|_, _, _| {}).unwrap();
        let frames = &rec.record(scheme.sequence()).unwrap().frames;
        let y = scheme.measurements(frames, m);
        let lin = op.apply(t).unwrap();
        let scale = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for (i, ((l, o), yi)) in lin.iter().zip(&op.offset).zip(&y).enumerate() {
            let model = l + o;
            assert!(
                (model - yi).abs() <= 1e-9 * scale,
                "{scheme:?} row {i}: {model} vs {yi}"
            );
        }
    }
}

#[test]
fn kernel_matrices_give_the_kernel_product_exactly() {
    let (_, kernel) = setup();
    let mats = KernelMatrices::new(&kernel);
    let t = random(kernel.grid.pixels(), 7);
    let p = kernel.apply_linear(&t);
    let units = kernel.units();
    let bits = |v: &[f64], v0: &[f64]| -> Vec<u64> {
        v.iter().zip(v0).map(|(a, b)| (a + b).to_bits()).collect()
    };
    let exact = |v: &[f64]| -> Vec<u64> { v.iter().map(|a| a.to_bits()).collect() };
    let mut x = vec![0.0; units];
    mats.x.apply(&t, &mut x);
    assert_eq!(bits(&x, &mats.x0), exact(&p.x));
    for (b, (m, m0)) in mats.t.iter().zip(&mats.t0).enumerate() {
        m.apply(&t, &mut x);
        assert_eq!(bits(&x, m0), exact(&p.t[b * units..(b + 1) * units]));
    }
}

#[test]
fn bad_sizes_and_values_are_named() {
    let (scene, kernel) = setup();
    let mats = KernelMatrices::new(&kernel);
    let (patterns, m) = patterns_for(&scene, 0.1).unwrap();
    let op = TracedOperator::new(&scene, &mats, &patterns, Scheme::DoubleArm, m).unwrap();
    let e = op.apply(&[1.0; 3]).unwrap_err().to_string();
    assert!(e.contains("`x`"), "{e}");
    let mut y = vec![0.0; m];
    y[2] = f64::NAN;
    let e = op.apply_adjoint(&y).unwrap_err().to_string();
    assert!(e.contains("`y`") && e.contains("value 2"), "{e}");
    assert!(patterns_for(&scene, 1.5).is_err());
}

/// The kernel builder's checks, each naming its field of the kernel spec and nothing traced:
/// the bounds of a dataset spec's `kernel:` section, and the chart.
#[test]
fn a_kernel_spec_is_checked_before_anything_is_traced() {
    use crate::scene::bench::{ChartSpec, ElementSpec};
    let refused = |doc: &BenchDoc, s: KernelSpec, field: &str, words: &[&str]| {
        let e = ClearChart::new(doc, &s).err().expect("refused");
        let text = e.to_string();
        assert!(e.is_user_error(), "{text}");
        assert!(text.starts_with(&format!("field `{field}`: ")), "{text}");
        for w in words {
            assert!(text.contains(w), "{text} lacks {w:?}");
        }
    };
    let doc = paper_doc();
    assert!(ClearChart::new(&doc, &spec(None, (4, 4), (1.0, 1.0), 2048)).is_ok());
    let cases = [
        (
            spec(Some("nope"), (4, 4), (1.0, 1.0), 2048),
            "chart",
            "its charts: \"chart\"",
        ),
        (
            spec(None, (0, 4), (1.0, 1.0), 2048),
            "grid_px",
            "from 1 to 1024, got 0",
        ),
        (
            spec(None, (4, 2000), (1.0, 1.0), 2048),
            "grid_px",
            "got 2000",
        ),
        (
            spec(None, (4, 4), (f64::NAN, 1.0), 2048),
            "field_mm",
            "positive",
        ),
        (
            spec(None, (4, 4), (1.0, -1.0), 2048),
            "field_mm",
            "positive",
        ),
        (spec(None, (4, 4), (1.0, 1.0), 1024), "rays", "from 2048"),
    ];
    for (s, field, words) in cases {
        refused(&doc, s, field, &[words]);
    }
    // Two charts, none named.
    let mut two = doc.clone();
    let mut second = two
        .file
        .elements
        .iter()
        .find(|e| matches!(e, ElementSpec::Chart(_)))
        .cloned()
        .unwrap();
    if let ElementSpec::Chart(ChartSpec { name, .. }) = &mut second {
        *name = "second".into();
    }
    two.file.elements.push(second);
    let words = ["2 charts", "\"second\"", "name one"];
    refused(&two, spec(None, (4, 4), (1.0, 1.0), 2048), "chart", &words);
    assert!(ClearChart::new(&two, &spec(Some("second"), (4, 4), (1.0, 1.0), 2048)).is_ok());
}

#[test]
fn a_batch_reports_its_first_failing_item_on_any_thread_count() {
    // Items 2 and 5 of 8 fail; item 5 fails at once and item 2 late, so a collect that keeps
    // whichever error a thread meets first would often report item 5 on four threads.
    let v: Vec<f64> = (0..8).map(f64::from).collect();
    let f = |x: &[f64]| -> Result<Vec<f64>> {
        match x[0] as usize {
            2 => {
                std::thread::sleep(std::time::Duration::from_millis(20));
                Err(Error::input("item 2"))
            }
            5 => Err(Error::input("item 5")),
            _ => Ok(x.to_vec()),
        }
    };
    for threads in [1, 4] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        for _ in 0..5 {
            let e = pool.install(|| batch(&v, 1, f)).unwrap_err();
            assert!(e.to_string().contains("item 2"), "{threads} threads: {e}");
        }
    }
    assert_eq!(batch(&v[..2], 1, f).unwrap(), [0.0, 1.0]);
}
