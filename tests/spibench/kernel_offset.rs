//! The object kernel's offsets b± (and k±) against direct traces of the same object, for an
//! object of bars across the whole field and a disk (mean transmittance about 0.22: structure at
//! the pattern's edge), on the paper bench. A measurement, not run by default (minutes of
//! tracing):
//!
//! ```text
//! cargo test --test spibench kernel_offset -- --ignored --nocapture
//! ```
//!
//! `SPIBENCH_KO_SEEDS` (default 8) kernel seeds and as many direct seeds,
//! `SPIBENCH_KO_RAYS` (default 400 000) rays each. Each quantity is compared by its mean over
//! the seeds; its standard error is the spread of the seeds (s/√n, independent seeds), and z is
//! the difference over the combined standard error. docs/object_kernels.md quotes the result.

use spibench::optics::Arm;
use spibench::raster::Raster;
use spibench::trace::kernel::{ObjectGrid, trace_kernel};
use spibench::trace::{TraceOptions, trace};
use spibench::transport::Transport;

use super::common::TempDir;
use super::kernel_se::bench_with_pattern;

/// The chart field the paper bench images onto its 48 × 48 units (mm); the object grid is
/// 2 × finer per axis, as in the dataset example.
const FIELD_MM: f64 = 7.88;
const GRID: usize = 96;

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Bars 3 px wide every 16 px over the whole field (the first at the field's left edge) and a
/// disk of radius 11 px below the centre: mean transmittance 0.22.
fn bars_and_disk() -> Raster {
    let half = 0.5 * GRID as f64;
    Raster::from_fn(GRID, GRID, |y, x| {
        let (u, v) = (x as f64 + 0.5 - half, y as f64 + 0.5 - half);
        let clear = (u + half).rem_euclid(16.0) < 3.0 || u * u + (v - 16.0).powi(2) < 121.0;
        if clear { 1.0 } else { 0.0 }
    })
}

/// Mean and standard error of the mean (s/√n) over seeds.
fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let s2 = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (s2 / n).sqrt())
}

/// The compared quantities of one transport.
fn quantities(t: &Transport) -> Vec<(&'static str, f64)> {
    let (bp, bm) = (t.b[Arm::Plus].value, t.b[Arm::Minus].value);
    let (cp, cm) = (t.c_traced[Arm::Plus].value, t.c_traced[Arm::Minus].value);
    vec![
        ("b+ (A)", bp),
        ("b- (A)", bm),
        ("b- - b+ (A)", bm - bp),
        ("b+ traced (A)", cp),
        ("b- traced (A)", cm),
        ("k+ (A/W)", t.k[Arm::Plus].value),
        ("k- (A/W)", t.k[Arm::Minus].value),
    ]
}

#[test]
#[ignore = "a measurement of minutes; see the module docs"]
fn kernel_offsets_against_direct_traces() {
    let seeds = env_u64("SPIBENCH_KO_SEEDS", 8).max(2);
    let rays = env_u64("SPIBENCH_KO_RAYS", 400_000);
    let dir = TempDir::new("kernel-offset");
    let object = bars_and_disk();
    let mean_t = object.data.iter().sum::<f64>() / object.data.len() as f64;
    let file = dir.join("bars_and_disk.png");
    spibench::report::png::write_gray16(&file, &object, 0.0, 1.0).unwrap();
    let direct_bench = bench_with_pattern(&format!(
        "pattern: Image(path: {:?}, width_mm: {FIELD_MM}, height_mm: {FIELD_MM}),",
        file.display().to_string()
    ));
    let kernel_bench = bench_with_pattern("pattern: Clear,");
    let grid = ObjectGrid {
        chart: 0,
        width_px: GRID,
        height_px: GRID,
        width_m: FIELD_MM * 1e-3,
        height_m: FIELD_MM * 1e-3,
    };
    // [product, first-pixel (linear) weighting, direct] × quantity × seed.
    let mut rows: Vec<[Vec<f64>; 3]> = Vec::new();
    let mut push = |which: usize, t: &Transport| {
        for (q, (_, v)) in quantities(t).into_iter().enumerate() {
            if rows.len() <= q {
                rows.push(Default::default());
            }
            rows[q][which].push(v);
        }
    };
    for seed in 0..seeds {
        let kernel =
            trace_kernel(&kernel_bench, grid, &TraceOptions::new(rays, 1000 + seed)).unwrap();
        push(
            0,
            &Transport::from_kernel(&kernel_bench, &kernel, &object.data).unwrap(),
        );
        push(
            1,
            &Transport::from_kernel_linear(&kernel_bench, &kernel, &object.data).unwrap(),
        );
        let tallies = trace(&direct_bench, &TraceOptions::new(rays, 2000 + seed)).unwrap();
        push(2, &Transport::from_tallies(&direct_bench, &tallies));
    }
    let names: Vec<&str> = quantities(&Transport::from_tallies(
        &direct_bench,
        &trace(&direct_bench, &TraceOptions::new(1024, 1)).unwrap(),
    ))
    .into_iter()
    .map(|(n, _)| n)
    .collect();
    eprintln!(
        "object: {GRID}×{GRID} bars and disk, mean transmittance {mean_t:.4}; {seeds} kernel and {seeds} direct seeds of {rays} rays"
    );
    eprintln!(
        "{:14} {:>12} {:>10} {:>12} {:>10} {:>8} {:>7} | {:>8} {:>7}",
        "quantity", "kernel", "±", "direct", "±", "diff %", "z", "lin. %", "lin. z"
    );
    for (name, [prod, lin, direct]) in names.iter().zip(&rows) {
        let (mk, sk) = mean_se(prod);
        let (ml, sl) = mean_se(lin);
        let (md, sd) = mean_se(direct);
        let z = (mk - md) / (sk * sk + sd * sd).sqrt();
        let zl = (ml - md) / (sl * sl + sd * sd).sqrt();
        eprintln!(
            "{name:14} {mk:12.5e} {sk:10.2e} {md:12.5e} {sd:10.2e} {:8.2} {z:7.2} | {:8.2} {zl:7.2}",
            100.0 * (mk / md - 1.0),
            100.0 * (ml / md - 1.0)
        );
    }
}
