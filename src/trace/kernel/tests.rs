//! The object kernel against direct traces of the same objects.

use super::{Kernel, ObjectGrid, trace_kernel};
use crate::objects::usaf::{Polarity, UsafChart};
use crate::optics::Arm;
use crate::raster::Raster;
use crate::trace::testing::bench_with;
use crate::trace::{TraceOptions, trace};
use crate::transport::Transport;

/// The chart field the paper bench images onto its 48 × 48 units (mm).
const FIELD_MM: f64 = 7.88;
/// Object pixels per side: twice the units per axis.
const GRID: usize = 96;

const CHART_EDITS_COMMON: [(&str, &str); 3] = [
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
];

fn kernel_bench() -> crate::optics::Bench {
    let mut edits = CHART_EDITS_COMMON.to_vec();
    edits.push((
        "pattern: Usaf(min_group: -2, max_group: 7),",
        "pattern: Clear,",
    ));
    bench_with("paper_bench.ron", &edits)
}

/// The paper bench with `object` (values in [0, 1]) as an image mask of the kernel's field, on
/// black chrome (OD 10, no reflectance): the object the kernel describes. Returns the bench and
/// the object as the mask reads it (16-bit levels).
fn direct_bench(
    object: &Raster,
    dir: &std::path::Path,
    name: &str,
) -> (crate::optics::Bench, Vec<f64>) {
    let file = dir.join(format!("{name}.png"));
    crate::report::png::write_gray16(&file, object, 0.0, 1.0).unwrap();
    let pattern = format!(
        "pattern: Image(path: {:?}, width_mm: {FIELD_MM}, height_mm: {FIELD_MM}),",
        file.display().to_string()
    );
    let mut edits = CHART_EDITS_COMMON.to_vec();
    edits.push((
        "pattern: Usaf(min_group: -2, max_group: 7),",
        pattern.as_str(),
    ));
    let quantised = object
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 65535.0).round() / 65535.0)
        .collect();
    (bench_with("paper_bench.ron", &edits), quantised)
}

fn objects() -> Vec<(&'static str, Raster)> {
    // The USAF chart rendered on the grid (pixel clear fractions), group −1 elements 5–6 region
    // centred as the paper bench centres it: a 7.88 mm square around the region's centre.
    let chart = UsafChart::new(-2, 7, Polarity::Negative).unwrap();
    let b5 = crate::objects::usaf::element_box(-1, 5).unwrap();
    let b6 = crate::objects::usaf::element_box(-1, 6).unwrap();
    let u = b5.union(&b6);
    let (cx, cy) = (0.5 * (u.x0_mm() + u.x1_mm()), 0.5 * (u.y0_mm() + u.y1_mm()));
    let h = 0.5 * FIELD_MM;
    let region = crate::objects::usaf::Region::from_corners(cx - h, cy - h, cx + h, cy + h);
    let usaf = chart.render(&region, GRID, GRID);
    let natural = |name: &str| {
        let src =
            crate::objects::image_file::decode_gray(crate::objects::test_image(name).unwrap())
                .unwrap();
        crate::objects::image_file::resize_area(&src, GRID, GRID)
            .unwrap()
            .map(|v| v / 255.0)
    };
    vec![
        ("usaf", usaf),
        ("astronaut", natural("astronaut")),
        ("coffee", natural("coffee")),
    ]
}

/// Per-unit gains g±_j with their standard errors from a direct trace (batch means).
fn direct_gains(t: &crate::trace::Tallies) -> ([Vec<f64>; 2], [Vec<f64>; 2]) {
    let units = t.units();
    let nb = t.batches.len() as f64;
    let g: [Vec<f64>; 2] = Arm::ALL.map(|d| {
        let (on, off) = (d.state(), d.other().state());
        (0..units)
            .map(|j| {
                t.t[crate::trace::BatchTally::t_index(units, d, on, j)]
                    - t.t[crate::trace::BatchTally::t_index(units, d, off, j)]
            })
            .collect()
    });
    let se = Arm::ALL.map(|d| {
        (0..units)
            .map(|j| ((t.g2[d][j] - g[d][j] * g[d][j] / nb).max(0.0) * nb / (nb - 1.0)).sqrt())
            .collect()
    });
    (g, se)
}

/// An object traced directly and the same object through the kernel agree within their
/// combined standard errors: per unit (mean squared z over the 2 × 2304 gains near 1, no bias)
/// and for k±, c± and the power on the pattern; on the USAF chart and two natural images. Also
/// measures what the kernel neglects (paths meeting the chart twice).
#[test]
fn kernel_matches_direct_traces() {
    let rays = 300 * crate::trace::RAYS_PER_BATCH;
    let bench = kernel_bench();
    let grid = ObjectGrid {
        chart: 0,
        width_px: GRID,
        height_px: GRID,
        width_m: FIELD_MM * 1e-3,
        height_m: FIELD_MM * 1e-3,
    };
    let kernel: Kernel = trace_kernel(&bench, grid, &TraceOptions::new(rays, 11)).unwrap();
    let ghost = kernel.multi_crossing_current_fraction();
    eprintln!(
        "kernel: {} entries; multi-crossing share of chart current {:.3e} ({} of {} detections)",
        kernel.entries.len(),
        ghost,
        kernel.multi_crossing_detections,
        kernel.chart_detections
    );
    assert!(ghost < 1e-2, "ghost share {ghost}");
    let dir = std::env::temp_dir().join(format!("spibench-kernel-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, object) in objects() {
        let (direct, x) = direct_bench(&object, &dir, name);
        let tk = Transport::from_kernel(&bench, &kernel, &x).unwrap();
        let gk_se = Transport::kernel_gain_stderr(&kernel, &x);
        let tallies = trace(&direct, &TraceOptions::new(rays, 12)).unwrap();
        let td = Transport::from_tallies(&direct, &tallies);
        let (gd, gd_se) = direct_gains(&tallies);
        // Gains summed over blocks of 6 × 6 units (64 blocks per arm), so that each compared
        // number rests on many rays and its batch-means error is close to normal.
        const BLOCK: usize = 6;
        let (across, down) = (tk.units_across, tk.units_down);
        let (mut z2, mut zsum, mut n) = (0.0, 0.0, 0usize);
        for d in Arm::ALL {
            for by in 0..down / BLOCK {
                for bx in 0..across / BLOCK {
                    let (mut a, mut b, mut s2) = (0.0, 0.0, 0.0);
                    for y in 0..BLOCK {
                        for x in 0..BLOCK {
                            let j = (by * BLOCK + y) * across + bx * BLOCK + x;
                            a += tk.g_a[d][j];
                            b += gd[d][j];
                            s2 += gk_se[d][j].powi(2) + gd_se[d][j].powi(2);
                        }
                    }
                    if s2 > 0.0 {
                        let z = (a - b) / s2.sqrt();
                        z2 += z * z;
                        zsum += z;
                        n += 1;
                    }
                }
            }
        }
        let (mz2, mz) = (z2 / n as f64, zsum / n as f64);
        eprintln!(
            "{name}: block mean z² {mz2:.3}, mean z {mz:.3} over {n}; k+ {:?} vs {:?}; x {:?} vs {:?}",
            tk.k[Arm::Plus],
            td.k[Arm::Plus],
            tk.x_total,
            td.x_total
        );
        assert!(n > 60, "{name}: {n} blocks compared");
        assert!((0.4..1.8).contains(&mz2), "{name}: mean z² {mz2}");
        assert!(mz.abs() < 0.5, "{name}: mean z {mz}");
        let close = |a: crate::transport::Estimate, b: crate::transport::Estimate, what: &str| {
            let s = (a.stderr.powi(2) + b.stderr.powi(2)).sqrt();
            assert!(
                (a.value - b.value).abs() < 4.0 * s,
                "{name} {what}: kernel {a:?} vs direct {b:?}"
            );
        };
        for d in Arm::ALL {
            close(tk.k[d], td.k[d], "k");
            close(tk.c_traced[d], td.c_traced[d], "c");
        }
        close(tk.x_total, td.x_total, "x");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The paper bench's lamp without chart guiding (its field sampling aims at the chart's clear
/// areas, so it differs between a clear chart and an object), for traces with common random
/// numbers.
const UNGUIDED: (&str, &str) = (
    "chart_guided: (chart: \"chart\", share: 0.6, region_mm: (11.0, 11.0)),",
    "",
);

/// The kernel's product is the direct trace of the same object, path by path: with the lamp
/// unguided, the same seed and a binary object on chrome that passes nothing (OD 10, no
/// reflectance), every path that survives the object in the direct trace is the kernel path of
/// the same random numbers, with weight Π tᵢ = 1, and every other kernel path has a pixel of
/// t = 0 among those it met (weight 0). So the products agree to rounding (and the 10⁻¹⁰ leak
/// of the chrome), with structure at the field's edge (bars to the border) and for paths that
/// meet the chart more than once. The first meeting's weight alone (the kernel before it kept
/// ghosts apart) over-counts the light of paths that met a clear pixel, then an opaque one.
#[test]
fn kernel_product_is_the_direct_trace_path_by_path() {
    let rays = 160 * crate::trace::RAYS_PER_BATCH;
    let mut edits = CHART_EDITS_COMMON.to_vec();
    edits.push(UNGUIDED);
    edits.push((
        "pattern: Usaf(min_group: -2, max_group: 7),",
        "pattern: Clear,",
    ));
    let bench = bench_with("paper_bench.ron", &edits);
    let grid = ObjectGrid {
        chart: 0,
        width_px: GRID,
        height_px: GRID,
        width_m: FIELD_MM * 1e-3,
        height_m: FIELD_MM * 1e-3,
    };
    let kernel = trace_kernel(&bench, grid, &TraceOptions::new(rays, 5)).unwrap();
    assert!(!kernel.ghosts.is_empty());
    let dir = std::env::temp_dir().join(format!("spibench-kernel-crn-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A checkerboard of single pixels: structure everywhere, the field's edges included, so
    // that a path meeting the chart again at another pixel likely meets the other colour.
    let object = Raster::from_fn(GRID, GRID, |r, c| ((r + c) % 2) as f64);
    let file = dir.join("checker.png");
    crate::report::png::write_gray16(&file, &object, 0.0, 1.0).unwrap();
    let pattern = format!(
        "pattern: Image(path: {:?}, width_mm: {FIELD_MM}, height_mm: {FIELD_MM}),",
        file.display().to_string()
    );
    let mut edits = CHART_EDITS_COMMON.to_vec();
    edits.push(UNGUIDED);
    edits.push(("pattern: Usaf(min_group: -2, max_group: 7),", &pattern));
    let direct = bench_with("paper_bench.ron", &edits);
    // Path by path only against the analogue tracer, which the kernel trace follows.
    let options = TraceOptions {
        sampling: crate::trace::Sampling::Independent,
        ..TraceOptions::new(rays, 5)
    };
    let tallies = trace(&direct, &options).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let td = Transport::from_tallies(&direct, &tallies);
    let x = &object.data;
    let tk = Transport::from_kernel(&bench, &kernel, x).unwrap();
    let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-7 * scale;
    let scale_t = td.t_a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (j, (a, b)) in tk.t_a.iter().zip(&td.t_a).enumerate() {
        assert!(
            close(*a, *b, scale_t),
            "T entry {j}: kernel {a:e}, direct {b:e}"
        );
    }
    let scale_x = td.x_w.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in tk.x_w.iter().zip(&td.x_w) {
        assert!(close(*a, *b, scale_x), "x: kernel {a:e}, direct {b:e}");
    }
    for arm in Arm::ALL {
        let (a, b) = (tk.c_traced[arm].value, td.c_traced[arm].value);
        eprintln!("c{arm:?}: kernel {a:.6e}, direct {b:.6e}");
        assert!(
            close(a, b, b.abs()),
            "c {arm:?}: kernel {a:e}, direct {b:e}"
        );
    }
    // The first meeting's weight alone over-counts: more light than the direct trace in T
    // (the currents per unit and state) and in c₋.
    let first = kernel.apply_linear(x);
    let excess_t: f64 = first.t.iter().zip(&td.t_a).map(|(a, b)| a - b).sum();
    let c_minus = first.sums[super::pv_c(Arm::Minus)];
    let direct_c = td.c_traced[Arm::Minus].value;
    eprintln!(
        "first-meeting weighting: Σ T {excess_t:+.3e} A over the direct trace's {:.3e}; c- {c_minus:.6e} ({:+.4} %); {} ghosts",
        td.t_a.iter().sum::<f64>(),
        100.0 * (c_minus / direct_c - 1.0),
        kernel.ghosts.len()
    );
    assert!(excess_t > 1e-6 * scale_t, "{excess_t:e}");
    assert!(
        c_minus >= direct_c * (1.0 - 1e-9),
        "{c_minus:e} vs {direct_c:e}"
    );
    values_only_products_equal_the_full_ones(&bench, &kernel, x);
}

/// The products without the totals' error sums (`Kernel::apply_values`,
/// `Transport::from_kernel_values`) give every value bit for bit as the full ones, ghosts
/// included, and unknown (NaN) errors for the totals only.
fn values_only_products_equal_the_full_ones(
    bench: &crate::optics::Bench,
    kernel: &Kernel,
    x: &[f64],
) {
    for linear in [false, true] {
        let full = if linear {
            kernel.apply_linear(x)
        } else {
            kernel.apply(x)
        };
        let values = kernel.apply_values(x, linear);
        assert_eq!(values.t, full.t, "linear {linear}");
        assert_eq!(
            (&values.x, values.b, values.sums),
            (&full.x, full.b, full.sums)
        );
        assert_eq!(
            (&values.g2, &values.gx, &values.x2),
            (&full.g2, &full.gx, &full.x2)
        );
        assert!(values.group_sums.is_empty() && values.q == [0.0; super::PQ]);
        assert!(values.cov(0, 0).is_nan());
        let tf = if linear {
            Transport::from_kernel_linear(bench, kernel, x).unwrap()
        } else {
            Transport::from_kernel(bench, kernel, x).unwrap()
        };
        let tv = Transport::from_kernel_values(bench, kernel, x, linear).unwrap();
        assert_eq!(
            (&tv.t_a, &tv.x_w, &tv.g_a, &tv.k_map),
            (&tf.t_a, &tf.x_w, &tf.g_a, &tf.k_map)
        );
        for arm in Arm::ALL {
            assert_eq!(tv.k[arm].value, tf.k[arm].value);
            assert_eq!(tv.c_traced[arm].value, tf.c_traced[arm].value);
            assert!(tf.k[arm].stderr.is_finite() && tv.k[arm].stderr.is_nan());
        }
        assert_eq!(tv.x_total.value, tf.x_total.value);
        assert!(tv.x_total.stderr.is_nan() && tv.imbalance.stderr.is_nan());
    }
}
