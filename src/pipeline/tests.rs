//! Tests of the stages on benches as values: a written bench traces as the one it was written
//! from, a part moved in code traces as the same edit made in the file, and a cached trace gives
//! the same downstream results.

use std::path::{Path, PathBuf};

use super::cache::{CacheKey, TraceCache};
use super::*;
use crate::quantities::BenchMetric;
use crate::scene::doc::BenchDoc;

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

fn paper() -> BenchDoc {
    BenchDoc::read(&scene_path("paper_bench.ron")).unwrap()
}

fn tallies(doc: &BenchDoc, rays: u64, seed: u64) -> Tallies {
    let bench = doc.build().unwrap();
    trace_stage(&bench, &TraceRequest::new(rays, seed))
        .unwrap()
        .tallies
}

#[test]
fn a_bench_written_out_and_read_back_traces_bit_identically() {
    let doc = paper();
    let back = BenchDoc::parse(&doc.to_ron().unwrap(), doc.path()).unwrap();
    assert_eq!(tallies(&doc, 20_000, 3), tallies(&back, 20_000, 3));
}

#[test]
fn moving_a_part_in_code_equals_editing_the_file() {
    let path = scene_path("paper_bench.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    // The − diode as written in the file.
    let doc = paper();
    let old = doc.file.detectors.minus.position_mm;
    let written = format!("position_mm: ({}, {}, {})", old.0, old.1, old.2);
    let edited_text = format!("position_mm: ({}, {}, {})", old.0 + 0.75, old.1, old.2);
    assert_eq!(
        text.matches(&written).count(),
        1,
        "the diode position must be written as `{written}`"
    );
    let edited = BenchDoc::parse(&text.replace(&written, &edited_text), &path).unwrap();
    let mut moved = doc.clone();
    moved
        .set("detectors.minus.position_mm.x", old.0 + 0.75)
        .unwrap();
    assert_eq!(moved.file, edited.file);
    assert_eq!(tallies(&moved, 20_000, 4), tallies(&edited, 20_000, 4));
    // And the move changed something: the bench is rebuilt, not reused.
    assert_ne!(tallies(&moved, 20_000, 4), tallies(&doc, 20_000, 4));
}

#[test]
fn a_cached_trace_gives_identical_downstream_results() {
    // A quick bench: 16 × 16 units, a few ratios and two schemes.
    let mut doc = paper();
    doc.set("dmd.pattern.units_across", 16.0).unwrap();
    doc.set("dmd.pattern.units_down", 16.0).unwrap();
    doc.set("dmd.pattern.mirrors_per_unit", 36.0).unwrap();
    let mut scene = doc.run_scene().unwrap();
    scene.settings.sampling_ratios = vec![0.25, 1.0];
    scene.settings.schemes = vec![
        crate::acquisition::Scheme::DoubleArm,
        crate::acquisition::Scheme::SecondaryComplementaryBalancing,
    ];
    let dir = std::env::temp_dir().join(format!("spibench-cache-run-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let cache = TraceCache::new(&dir);
    let key = CacheKey::new(&doc, 40_000, 9).unwrap();
    let req = TraceRequest {
        cache: Some((&cache, &key)),
        ..TraceRequest::new(40_000, 9)
    };
    let quiet: Progress = &|_, _, _| {};
    let first = crate::run::run(&scene, &req, quiet).unwrap();
    let second = crate::run::run(&scene, &req, quiet).unwrap();
    assert_eq!(first.cache, CacheStatus::Miss);
    assert_eq!(second.cache, CacheStatus::Hit);
    assert_eq!(first.transport, second.transport);
    for (a, b) in first.results.iter().zip(&second.results) {
        assert_eq!(a.reconstruction, b.reconstruction);
        assert_eq!(
            (a.psnr_db, a.mssim, a.iterations),
            (b.psnr_db, b.mssim, b.iterations)
        );
    }
    // A damaged entry is rebuilt, and the results stay the same.
    let entry = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .find(|e| e.path().extension().is_some_and(|x| x == "trace"))
        .unwrap()
        .path();
    let mut bytes = std::fs::read(&entry).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 1;
    std::fs::write(&entry, &bytes).unwrap();
    let third = crate::run::run(&scene, &req, quiet).unwrap();
    assert!(
        matches!(third.cache, CacheStatus::Rebuilt(_)),
        "{:?}",
        third.cache
    );
    assert_eq!(third.transport, first.transport);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bench_metrics_agree_with_the_transport() {
    let doc = paper();
    let bench = doc.build().unwrap();
    let t = trace_stage(&bench, &TraceRequest::new(30_000, 2)).unwrap();
    let m = &t.metrics;
    let tr = &t.transport;
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1e-30);
    for (name, e) in [
        (BenchMetric::KPlus, tr.k[0]),
        (BenchMetric::KMinus, tr.k[1]),
        (BenchMetric::KPrime, tr.k_prime),
        (BenchMetric::Imbalance, tr.imbalance),
        (BenchMetric::BPlus, tr.b[0]),
        (BenchMetric::BMinus, tr.b[1]),
        (BenchMetric::XTotalW, tr.x_total),
    ] {
        let v = m[name].estimate();
        assert!(close(v.value, e.value), "{name}: {v:?} vs {e:?}");
        assert!(close(v.stderr, e.stderr), "{name}: {v:?} vs {e:?}");
    }
    // The detected powers are the ledger's.
    let l = &tr.ledger;
    assert!(close(
        m[BenchMetric::PowerPlusW].value,
        l.worlds[0].detected_w[0]
    ));
    assert!(close(
        m[BenchMetric::PowerMinusW].value,
        l.worlds[1].detected_w[1]
    ));
    assert!(close(
        m[BenchMetric::LeakPlus].value,
        l.worlds[0].detected_w[1] / l.worlds[0].detected_w[0]
    ));
}

/// The paper bench with its four LA1050 singlets as `LensSystem(zmx: "parts/…")` elements
/// (the shipped prescription, turned round where the bench uses the lens flat side first)
/// traces the same k±, b± within their standard errors: the same surfaces, built from a file.
#[test]
fn the_paper_bench_with_its_lenses_as_lens_systems_traces_the_same() {
    use crate::scene::bench::{ElementSpec, LensSystemSpec};
    let doc = paper();
    let mut file = doc.file.clone();
    let mut replaced = 0;
    for el in &mut file.elements {
        if let ElementSpec::Lens(l) = el
            && l.part.as_deref() == Some("LA1050")
        {
            *el = ElementSpec::LensSystem(LensSystemSpec {
                name: l.name.clone(),
                part: l.part.clone(),
                zmx: Some("parts/thorlabs_la1050.zmx".into()),
                surfaces: None,
                reversed: l.front_radius_mm.is_none(),
                position_mm: l.position_mm,
                axis: l.axis,
                diameter_mm: Some(l.diameter_mm),
                clear_diameter_mm: l.clear_diameter_mm,
                glass_catalogues: Vec::new(),
                allow_glass_substitution: false,
                coating: l.coating.clone(),
                tilt_deg: l.tilt_deg,
            });
            replaced += 1;
        }
    }
    assert_eq!(replaced, 4);
    let systems = BenchDoc::from_file(file, doc.path());
    let rays = 100_000;
    let a = trace_stage(&doc.build().unwrap(), &TraceRequest::new(rays, 5)).unwrap();
    let b = trace_stage(&systems.build().unwrap(), &TraceRequest::new(rays, 5)).unwrap();
    for m in [
        BenchMetric::KPlus,
        BenchMetric::KMinus,
        BenchMetric::BPlus,
        BenchMetric::BMinus,
    ] {
        let (x, y) = (&a.metrics[m], &b.metrics[m]);
        let se = x.stderr().hypot(y.stderr());
        assert!(
            (x.value - y.value).abs() <= 3.0 * se + 1e-12 * x.value.abs(),
            "{m:?}: {} vs {} (se {se})",
            x.value,
            y.value
        );
    }
    // The same surfaces to rounding: the trace agrees far inside its errors.
    let k = (
        &a.metrics[BenchMetric::KPlus],
        &b.metrics[BenchMetric::KPlus],
    );
    assert!(
        (k.0.value - k.1.value).abs() <= 1e-6 * k.0.value.abs(),
        "{} vs {}",
        k.0.value,
        k.1.value
    );
}

/// An even-asphere `LensSystem` (the shipped AL1815 collector) in an arm of the paper bench:
/// it builds, traces without a NaN, draws, and exports to Mitsuba as a mesh; a bad
/// prescription inside a bench is an error located in the prescription file.
#[test]
fn an_asphere_lens_system_builds_traces_draws_and_exports() {
    let path = scene_path("paper_bench.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text
        .find("        Lens(\n            name: \"arm_plus_lens\"")
        .unwrap();
    let end = start + text[start..].find("        ),\n").unwrap() + "        ),\n".len();
    let system = "        LensSystem(\n            name: \"arm_plus_lens\",\n            zmx: \"parts/thorlabs_al1815.zmx\",\n            position_mm: (28.7606, -28.7606, 91.3545),\n            axis: Polar(theta_deg: 24.0, phi_deg: -45.0),\n            coating: MgF2(design_nm: 550.0),\n        ),\n";
    let edited = format!("{}{system}{}", &text[..start], &text[end..]);
    let doc = BenchDoc::parse(&edited, &path).unwrap();
    let bench = doc.build().unwrap();
    assert!(bench.surfaces().iter().any(|s| matches!(
        s.geometry,
        crate::optics::geometry::Geometry::Asphere { .. }
    )));
    let t = trace_stage(&bench, &TraceRequest::new(20_000, 1)).unwrap();
    // f = 15 mm where the bench's design has 100 mm: the + arm's beam has spread far beyond
    // its 5 mm diode when it gets there, so k₊ is about 0; the − arm is untouched. (The
    // asphere itself traces like the sphere it approximates: benches/lens.rs.)
    for m in [BenchMetric::KPlus, BenchMetric::KMinus, BenchMetric::BPlus] {
        let v = t.metrics[m].value;
        assert!(v.is_finite() && v >= 0.0, "{m:?}: {v}");
    }
    assert!(t.metrics[BenchMetric::KMinus].value > 0.0);
    assert!(!crate::optics::outline::element_outlines(&bench).is_empty());
    crate::trace::fan::ray_fan(&bench, 50, 1).unwrap();
    let mono = crate::optics::monochromatic::monochromatic(
        &bench,
        &crate::optics::monochromatic::MonochromaticOptions::at_nm(850.0),
    )
    .unwrap();
    let scene = crate::export::export_mitsuba(
        &mono.bench,
        &crate::export::ExportOptions {
            pattern: vec![true; mono.bench.units()],
            pattern_label: "all-plus".into(),
            wavelength_m: Some(850e-9),
            sensor_samples: 16,
            spectral: false,
        },
    )
    .unwrap();
    assert!(scene.files.iter().any(|(n, _)| n.contains("arm_plus_lens")));
    // The prescription's own errors keep its file and line; a missing file is named.
    let bad = edited.replace("parts/thorlabs_al1815.zmx", "parts/missing.zmx");
    let e = BenchDoc::parse(&bad, &path)
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.zmx"), "{e}");
    let neither = edited.replace("            zmx: \"parts/thorlabs_al1815.zmx\",\n", "");
    let e = BenchDoc::parse(&neither, &path)
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("arm_plus_lens") && e.contains("either"), "{e}");
}

/// Inline surfaces: a doublet written in the bench equals the same prescription read from the
/// shipped file (the same bench surfaces), and crossing faces are located in the surface list.
#[test]
fn inline_lens_system_surfaces_match_the_file_and_are_checked() {
    let path = scene_path("paper_bench.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text
        .find("        Lens(\n            name: \"arm_plus_lens\"")
        .unwrap();
    let end = start + text[start..].find("        ),\n").unwrap() + "        ),\n".len();
    let head = "        LensSystem(\n            name: \"arm_plus_lens\",\n            position_mm: (28.7606, -28.7606, 91.3545),\n            axis: Polar(theta_deg: 24.0, phi_deg: -45.0),\n";
    let from_file =
        format!("{head}            zmx: \"parts/thorlabs_ac254-100-b.zmx\",\n        ),\n");
    let inline = format!(
        "{head}            surfaces: [\n                (radius_mm: 66.68, semi_diameter_mm: 12.7, thickness_mm: 4.0, glass: \"N-LAK22\"),\n                (radius_mm: -53.7, semi_diameter_mm: 12.7, thickness_mm: 1.5, glass: \"N-SF6HT\"),\n                (radius_mm: -259.41, semi_diameter_mm: 12.7),\n            ],\n        ),\n"
    );
    let build = |el: &str| {
        BenchDoc::parse(&format!("{}{el}{}", &text[..start], &text[end..]), &path)
            .unwrap()
            .build()
    };
    let (a, b) = (build(&from_file).unwrap(), build(&inline).unwrap());
    assert_eq!(a.surfaces().len(), b.surfaces().len());
    // The file's curvatures are 1/R to 10 digits: the radii agree to 1e-9 relative.
    let k = (
        trace_stage(&a, &TraceRequest::new(20_000, 2)).unwrap(),
        trace_stage(&b, &TraceRequest::new(20_000, 2)).unwrap(),
    );
    let (x, y) = (
        &k.0.metrics[BenchMetric::KPlus],
        &k.1.metrics[BenchMetric::KPlus],
    );
    assert!(
        (x.value - y.value).abs() <= 1e-6 * x.value,
        "{} vs {}",
        x.value,
        y.value
    );
    // Bench variables move and tilt it as they do a Lens.
    let mut doc = BenchDoc::parse(
        &format!("{}{inline}{}", &text[..start], &text[end..]),
        &path,
    )
    .unwrap();
    doc.set("arm_plus_lens.position_mm.x", 29.0).unwrap();
    assert_eq!(doc.get("arm_plus_lens.position_mm.x").unwrap(), 29.0);
    doc.set("arm_plus_lens.tilt_deg.x", 0.5).unwrap();
    doc.set("arm_plus_lens.despace_mm", 0.2).unwrap();
    doc.build().unwrap();
    let crossing = inline.replace("thickness_mm: 4.0", "thickness_mm: 0.5");
    let e = build(&crossing).unwrap_err().to_string();
    assert!(
        e.contains("surfaces[0].thickness_mm") && e.contains("cross"),
        "{e}"
    );
}
