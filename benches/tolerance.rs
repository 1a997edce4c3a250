//! Tolerance analysis of the shipped file on the paper bench: the sensitivity table resolved
//! end by end (`tolerance --resolve 1e-4`: each end's paired standard error of Δimbalance at
//! most max(10⁻⁴, 1 % of |Δ|), from 102 400 rays, 2ᵏ times that, up to 6.6·10⁶), against
//! the baseline of one ray count for every row (10⁶, the previous method), and a 100-trial
//! Monte Carlo without `--quality`, with the time split between compensators and traces.
//!
//!     cargo bench --bench tolerance [-- TRIALS]
//!
//! The Monte Carlo is run twice: with the file as shipped (no compensators) and with the −
//! diode's decentre as a Balance compensator, to measure what compensators cost.
//!
//! It also counts where a trace's work goes, before and after the DMD (`trace::split`): a trial
//! that perturbs only parts after the DMD could re-trace only the light leaving the DMD (a
//! stored ray bundle), which pays only in proportion to the work done after the DMD.

use std::path::Path;
use std::time::Instant;

use spibench::scene::doc::BenchDoc;
use spibench::scene::tolerance::{SensitivityRecord, ToleranceSet};
use spibench::tolerance::{Resolve, ToleranceOptions, nominal, sensitivity, trial};

fn worst(rows: &[SensitivityRecord], rule: &Resolve) -> (f64, usize) {
    let mut worst = 0.0f64;
    let mut unresolved = 0;
    for r in rows {
        let mut ok = true;
        for high in [false, true] {
            let (d, se) = (
                r.at(high, "imbalance_diff"),
                r.at(high, "imbalance_diff_stderr"),
            );
            if se.is_finite() {
                worst = worst.max(se);
            }
            ok &= rule.holds(d, se);
        }
        unresolved += usize::from(!ok);
    }
    (worst, unresolved)
}

fn main() {
    let trials: u64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(100);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = BenchDoc::read(&root.join("scenes/paper_bench.ron")).expect("the paper bench");
    let set = ToleranceSet::read(&root.join("scenes/tolerances/paper_bench.ron"), &doc)
        .expect("the shipped tolerance file");
    let threads = rayon::current_num_threads();
    println!(
        "paper bench, {} tolerances, {threads} thread(s)",
        set.tolerances.len()
    );
    let o = |rays| ToleranceOptions {
        rays,
        seed: 1,
        quality: false,
    };

    // Resolved end by end.
    let start = 100 * spibench::trace::RAYS_PER_BATCH;
    let rule = Resolve {
        stderr: 1e-4,
        relative: 0.01,
        max_rays: 64 * start,
    };
    let t = Instant::now();
    let nom = nominal(&doc, &o(start)).unwrap();
    let rows = sensitivity(&doc, &set, &nom, &o(start), Some(rule), &|_, _| {}).unwrap();
    let sens_s = t.elapsed().as_secs_f64();
    let ends: Vec<u64> = rows.iter().flat_map(|r| r.rays).collect();
    let mut ray_counts = ends.clone();
    ray_counts.sort();
    ray_counts.dedup();
    let (w, unresolved) = worst(&rows, &rule);
    println!(
        "sensitivity resolved to max(1e-4, 1 % of |Δ|): {} rows in {sens_s:.1} s (target < \
         300 s); worst paired SE {w:.2e}; {unresolved} row(s) unresolved at the cap",
        rows.len()
    );
    for rc in &ray_counts {
        let n = ends.iter().filter(|r| *r == rc).count();
        println!("  {n:>2} end(s) at {rc} rays");
    }
    for r in rows.iter().take(5) {
        println!(
            "  {:<34} Δimbalance {:+.3e} ± {:.1e} / {:+.3e} ± {:.1e} (rays {:?})",
            r.path,
            r.at(false, "imbalance_diff"),
            r.at(false, "imbalance_diff_stderr"),
            r.at(true, "imbalance_diff"),
            r.at(true, "imbalance_diff_stderr"),
            r.rays
        );
    }

    // Baseline: every row at one ray count.
    let fixed = 1_000_000;
    let t = Instant::now();
    let nom = nominal(&doc, &o(fixed)).unwrap();
    let base = sensitivity(&doc, &set, &nom, &o(fixed), None, &|_, _| {}).unwrap();
    let base_s = t.elapsed().as_secs_f64();
    let (w, unresolved) = worst(&base, &rule);
    println!(
        "baseline, every row at {fixed} rays: {} traces in {base_s:.1} s; worst paired SE \
         {w:.2e}; {unresolved} row(s) unresolved by the same rule",
        2 * base.len() + 1
    );

    // Monte Carlo at the ray count of the shipped default (200 000).
    let mc_rays = 200_000;
    let nom = nominal(&doc, &o(mc_rays)).unwrap();
    let t = Instant::now();
    let (mut comp, mut tr) = (0.0, 0.0);
    for i in 0..trials {
        let (_, timing) = trial(&doc, &set, &nom, &o(mc_rays), i).unwrap();
        comp += timing.compensators_s;
        tr += timing.trace_s;
    }
    let mc_s = t.elapsed().as_secs_f64();
    println!(
        "Monte Carlo: {trials} trials at {mc_rays} rays in {mc_s:.1} s (target < 600 s for 100): \
         draws and builds {comp:.1} s, traces {tr:.1} s"
    );

    // With one compensator: the − diode re-centred for balance.
    let mut text = std::fs::read_to_string(root.join("scenes/tolerances/paper_bench.ron")).unwrap();
    text = text.replacen(
        "compensators: [],",
        "compensators: [(path: \"detectors.minus.decenter_mm.x\", range: PlusMinus(1.0), \
         objective: Balance)],",
        1,
    );
    let cset = ToleranceSet::parse(&text, Path::new("compensated.ron"), &doc).unwrap();
    let n_comp = trials.min(10);
    let t = Instant::now();
    let (mut comp, mut tr) = (0.0, 0.0);
    for i in 0..n_comp {
        let (_, timing) = trial(&doc, &cset, &nom, &o(mc_rays), i).unwrap();
        comp += timing.compensators_s;
        tr += timing.trace_s;
    }
    println!(
        "compensated Monte Carlo: {n_comp} trials in {:.1} s: compensators {comp:.1} s ({:.0} %), \
         traces {tr:.1} s",
        t.elapsed().as_secs_f64(),
        100.0 * comp / (comp + tr)
    );

    // Where a trace's work goes: segments before and after the DMD, and one trace's time.
    let bench = doc.build().unwrap();
    let split = spibench::trace::split::segment_split(&bench, 200_000, 1);
    let t = Instant::now();
    spibench::trace::trace(&bench, &spibench::trace::TraceOptions::new(1_000_000, 1)).unwrap();
    let trace_s = t.elapsed().as_secs_f64();
    println!(
        "one trace of 10⁶ rays: {trace_s:.2} s; of 2·10⁵ rays, {} reach the pattern area; \
         segments before the DMD {}, after it (both branches) {}, of rays that never reach it \
         {}: {:.0} % of the work is after the DMD",
        split.arrived,
        split.before_dmd,
        split.after_dmd,
        split.never_arrived,
        100.0 * split.after_share()
    );
}
