//! Tolerance analysis of the shipped file on the paper bench: the sensitivity table at a ray
//! count that resolves each imbalance change to 1e-4 (paired standard error), and a 100-trial
//! Monte Carlo without `--quality`, with the time split between compensators and traces.
//!
//!     cargo bench --bench tolerance [-- TRIALS]
//!
//! A pilot sensitivity table at 50 000 rays measures the worst paired standard error of an
//! imbalance change; it falls as 1/√rays, so the pilot predicts the rays for 1e-4. The Monte
//! Carlo is run twice: with the file as shipped (no compensators) and with the − diode's
//! decentre as a Balance compensator, to measure what compensators cost. The baseline for the
//! compensated trials is the uncompensated trial (the same trace after the compensators).
//!
//! It also measures how the time of one trace splits before and after the DMD: a trial that
//! perturbs only parts after the DMD could re-trace only the light leaving the DMD (a stored
//! ray bundle), which pays only if most of the time is spent after the DMD.

use std::path::Path;
use std::time::Instant;

use spibench::scene::doc::BenchDoc;
use spibench::scene::tolerance::ToleranceSet;
use spibench::tolerance::{ToleranceOptions, is_metric, nominal, sensitivity, trial};

fn main() {
    let trials: u64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(100);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = BenchDoc::read(&root.join("scenes/paper_bench.ron")).expect("the paper bench");
    let set = ToleranceSet::read(
        &root.join("scenes/tolerances/paper_bench.ron"),
        &doc,
        &is_metric,
    )
    .expect("the shipped tolerance file");
    let threads = rayon::current_num_threads();
    println!(
        "paper bench, {} tolerances, {threads} thread(s)",
        set.tolerances.len()
    );

    // Pilot: the worst paired SE of an imbalance change.
    let pilot = 50_000;
    let o = |rays| ToleranceOptions {
        rays,
        seed: 1,
        quality: false,
    };
    let t = Instant::now();
    let nom = nominal(&doc, &o(pilot)).unwrap();
    let rows = sensitivity(&doc, &set, &nom, &o(pilot), &|_, _| {}).unwrap();
    let pilot_s = t.elapsed().as_secs_f64();
    let worst = rows
        .iter()
        .flat_map(|r| {
            [
                r.at(false, "imbalance_diff_stderr"),
                r.at(true, "imbalance_diff_stderr"),
            ]
        })
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let rays = ((pilot as f64) * (worst / 1e-4).powi(2)).ceil() as u64;
    // Capped at 1e6 rays per trace so that the benchmark stays within minutes on 2 cores; the
    // worst standard error reached is printed.
    let rays = rays.clamp(pilot, 1_000_000);
    println!(
        "pilot: {} traces at {pilot} rays in {pilot_s:.1} s; worst paired SE of Δimbalance \
         {worst:.2e} → {rays} rays for 1e-4",
        2 * rows.len() + 1
    );

    let t = Instant::now();
    let nom = nominal(&doc, &o(rays)).unwrap();
    let rows = sensitivity(&doc, &set, &nom, &o(rays), &|_, _| {}).unwrap();
    let sens_s = t.elapsed().as_secs_f64();
    let worst = rows
        .iter()
        .flat_map(|r| {
            [
                r.at(false, "imbalance_diff_stderr"),
                r.at(true, "imbalance_diff_stderr"),
            ]
        })
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    println!(
        "sensitivity: {} traces at {rays} rays in {sens_s:.1} s (target < 300 s); worst paired \
         SE {worst:.2e}",
        2 * rows.len() + 1
    );
    for r in rows.iter().take(5) {
        println!(
            "  {:<40} Δimbalance {:+.2e} / {:+.2e}",
            r.path,
            r.at(false, "imbalance_diff"),
            r.at(true, "imbalance_diff")
        );
    }

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
    let cset = ToleranceSet::parse(&text, Path::new("compensated.ron"), &doc, &is_metric).unwrap();
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
}
