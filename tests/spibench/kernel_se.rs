//! Reported standard errors against the spread of replicate traces: `trace` (k±, b±) and the
//! object kernel (k±, b±, the power on the pattern), on the paper bench, for a full object and a
//! small one.
//!
//! For each quantity the test runs R independent replicates (seeds), takes the sample standard
//! deviation s of the R estimates and the root mean square m of the R reported standard errors,
//! and asks that s/m lie in the sampling band of a correct standard error: for normal estimates
//! (R − 1)·s²/σ² is chi-square with R − 1 degrees of freedom, so with R = 24 the ratio s/σ lies
//! in [0.545, 1.506] with probability 0.999 (two-sided; Wilson–Hilferty's approximation of the
//! 0.05 % and 99.95 % points of χ²₂₃). m estimates σ with a few per cent of error at these batch
//! counts, well inside the band. A wrong estimator (the object kernel's Σ tᵢ²·var(Kᵢ), which
//! ignores the Latin hypercube's negative covariance between the pixels of a batch, or batch
//! means on too few batches) shows as a ratio well outside it.

use std::path::Path;

use spibench::optics::{Arm, Bench};
use spibench::raster::Raster;
use spibench::trace::kernel::{ObjectGrid, trace_kernel};
use spibench::trace::{TraceOptions, trace};
use spibench::transport::{Estimate, Transport};

use super::common::TempDir;

/// Replicates per quantity.
const REPLICATES: u64 = 24;
/// The 0.999 sampling band of s/σ for 24 replicates (see the module docs).
const BAND: (f64, f64) = (0.545, 1.506);
/// Rays per replicate: 24 batches of 1024.
const RAYS: u64 = 24 * 1024;
/// The chart field the paper bench images onto its 48 × 48 units (mm), and the object grid.
const FIELD_MM: f64 = 7.88;
const GRID: usize = 48;

fn scene_text() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    std::fs::read_to_string(path).unwrap()
}

/// The paper bench with its chart's pattern replaced (`pattern` is a RON `pattern:` line), on
/// black chrome of OD 10 without reflectance (the object the kernel describes), centred.
pub(super) fn bench_with_pattern(pattern: &str) -> Bench {
    let mut text = scene_text();
    for (from, to) in [
        (
            "center_on: Elements(group: -1, first: 5, last: 6),",
            "center_on: Point((0.0, 0.0)),",
        ),
        (
            "chrome_od: Table([(350.0, 3.2), (430.0, 3.0), (700.0, 2.8), (1150.0, 2.5)]),",
            "chrome_od: Constant(10.0),",
        ),
        (
            "chrome_reflectance: Constant(0.10),",
            "chrome_reflectance: Constant(0.0),",
        ),
        ("pattern: Usaf(min_group: -2, max_group: 7),", pattern),
    ] {
        assert_eq!(text.matches(from).count(), 1, "{from}");
        text = text.replace(from, to);
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron");
    spibench::scene::bench::parse_bench(&text, &path).unwrap()
}

/// A disk of `radius_px` at the grid's centre (clear inside), and bars over the whole field with
/// a disk (structure at the field's edge): the small and the full object.
fn objects() -> [(&'static str, Raster); 2] {
    let make = |f: &dyn Fn(f64, f64) -> bool| {
        let mut data = vec![0.0; GRID * GRID];
        for y in 0..GRID {
            for x in 0..GRID {
                let (u, v) = (
                    x as f64 + 0.5 - 0.5 * GRID as f64,
                    y as f64 + 0.5 - 0.5 * GRID as f64,
                );
                if f(u, v) {
                    data[y * GRID + x] = 1.0;
                }
            }
        }
        Raster::new(GRID, GRID, data).unwrap()
    };
    [
        ("small disk", make(&|u, v| u * u + v * v < 16.0)),
        (
            "bars and disk",
            make(&|u, v| (u + 24.0).rem_euclid(8.0) < 2.0 || u * u + (v - 8.0).powi(2) < 36.0),
        ),
    ]
}

/// s/m over the replicates (see the module docs), with s and m.
fn spread_ratio(v: &[Estimate]) -> (f64, f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().map(|e| e.value).sum::<f64>() / n;
    let s = (v.iter().map(|e| (e.value - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let m = (v.iter().map(|e| e.stderr * e.stderr).sum::<f64>() / n).sqrt();
    (s / m, s, m)
}

/// The quantities compared: k±, b± (traced part), Σx.
fn quantities(t: &Transport) -> [(&'static str, Estimate); 5] {
    [
        ("k+", t.k[Arm::Plus]),
        ("k-", t.k[Arm::Minus]),
        ("b+", t.c_traced[Arm::Plus]),
        ("b-", t.c_traced[Arm::Minus]),
        ("x", t.x_total),
    ]
}

/// Checks every quantity's ratio against the band; prints the table either way.
fn check(rows: &[(String, Vec<Estimate>)]) {
    let mut bad = Vec::new();
    for (name, v) in rows {
        let (r, s, m) = spread_ratio(v);
        eprintln!("{name:32} spread {s:.3e}  reported {m:.3e}  ratio {r:.3}");
        if !(BAND.0..=BAND.1).contains(&r) {
            bad.push(format!("{name}: ratio {r:.3}"));
        }
    }
    assert!(bad.is_empty(), "outside the band {BAND:?}: {bad:?}");
}

#[test]
fn reported_standard_errors_match_the_replicate_spread() {
    let dir = TempDir::new("kernel-se");
    let kernel_bench = bench_with_pattern("pattern: Clear,");
    let grid = ObjectGrid {
        chart: 0,
        width_px: GRID,
        height_px: GRID,
        width_m: FIELD_MM * 1e-3,
        height_m: FIELD_MM * 1e-3,
    };
    let objects = objects();
    let mut direct = Vec::new();
    for (name, object) in &objects {
        let file = dir.join(&format!("{}.png", name.replace(' ', "_")));
        spibench::report::png::write_gray16(&file, object, 0.0, 1.0).unwrap();
        let pattern = format!(
            "pattern: Image(path: {:?}, width_mm: {FIELD_MM}, height_mm: {FIELD_MM}),",
            file.display().to_string()
        );
        direct.push(bench_with_pattern(&pattern));
    }
    let mut rows: Vec<(String, Vec<Estimate>)> = Vec::new();
    let mut push = |label: String, e: Estimate| match rows.iter_mut().find(|r| r.0 == label) {
        Some(r) => r.1.push(e),
        None => rows.push((label, vec![e])),
    };
    for seed in 0..REPLICATES {
        let kernel =
            trace_kernel(&kernel_bench, grid, &TraceOptions::new(RAYS, 1000 + seed)).unwrap();
        for ((name, object), bench) in objects.iter().zip(&direct) {
            let tk = Transport::from_kernel(&kernel_bench, &kernel, &object.data).unwrap();
            for (q, e) in quantities(&tk) {
                push(format!("kernel {name} {q}"), e);
            }
            let tallies = trace(bench, &TraceOptions::new(RAYS, 2000 + seed)).unwrap();
            let td = Transport::from_tallies(bench, &tallies);
            for (q, e) in quantities(&td) {
                push(format!("trace {name} {q}"), e);
            }
        }
    }
    check(&rows);
}
