//! Irradiance-map benchmark (harness = false, std::time only): `cargo bench --bench irradiance
//! [-- SCENE …]`.
//!
//! Traces each bench (default: scenes/paper_bench.ron and scenes/paper_bench_condenser.ron)
//! with the diodes' irradiance maps (`trace::irradiance::trace_with_maps`, 64 × 64 bins),
//! with those and the maps at three named surfaces as well (`trace_with_surface_maps`: the
//! imaging iris and the two arm lenses, `trace --irradiance-at`), and without maps
//! (`trace::trace`), same rays and seed, in rotation nine times on two threads so that the
//! machine's drift falls on all three, and prints the throughput of each and the maps' extra
//! time (the median over the rounds of each round's ratio of times, and its range), with the
//! load average beside it. The maps are recorded from the same paths (a short
//! list of hits per batch, binned in the merge), so the target is under 10 % more time; the
//! tallies of the traces are checked to be identical.

use std::path::PathBuf;
use std::time::Instant;

use spibench::scene::doc::BenchDoc;
use spibench::trace::irradiance::{DEFAULT_BINS, trace_with_maps, trace_with_surface_maps};
use spibench::trace::{TraceOptions, trace};

const RAYS: u64 = 200_000;
const ROUNDS: usize = 9;

/// The named surfaces mapped in the third case (those of them the bench has).
const SURFACES: [&str; 3] = ["imaging_iris", "arm_plus_lens", "arm_minus_lens"];

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(|l| format!("load {l}")))
        .unwrap_or_else(|| "load ?".into())
}

/// The CPU time (s) the process's threads have run, from the kernel's per-thread
/// `schedstat` (nanoseconds on a CPU): on a machine that other jobs load, a case's CPU time
/// moves less than its wall time (time spent waiting for a core is not counted), so the ratio
/// of CPU times is the steadier measure of the maps' extra work. The pool's threads live for
/// the whole run, so no thread's time is lost between two readings.
fn cpu_s() -> f64 {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return f64::NAN;
    };
    tasks
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .sum::<f64>()
        * 1e-9
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let args: Vec<PathBuf> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .map(PathBuf::from)
        .collect();
    let scenes = if args.is_empty() {
        vec![
            root.join("scenes/paper_bench.ron"),
            root.join("scenes/paper_bench_condenser.ron"),
        ]
    } else {
        args
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    for path in scenes {
        let bench = BenchDoc::read(&path)
            .and_then(|d| d.build())
            .expect("bench");
        let o = TraceOptions::new(RAYS, 1);
        let mut plain = None;
        let names: Vec<String> = SURFACES
            .iter()
            .filter(|n| bench.elements().iter().any(|e| e == *n))
            .map(|n| n.to_string())
            .collect();
        // Per round, each case's time; the order rotates from round to round so that no case
        // always runs first (a warm cache, a neighbour's build starting).
        let mut times = [[0.0f64; 3]; ROUNDS];
        let mut cpu = [[0.0f64; 3]; ROUNDS];
        for r in 0..ROUNDS {
            for c in (0..3).map(|k| (k + r) % 3) {
                let c0 = cpu_s();
                let t0 = Instant::now();
                let tallies = match c {
                    0 => pool.install(|| trace(&bench, &o)).expect("trace"),
                    1 => {
                        pool.install(|| trace_with_maps(&bench, &o, DEFAULT_BINS))
                            .expect("trace with maps")
                            .0
                    }
                    _ => {
                        pool.install(|| trace_with_surface_maps(&bench, &o, DEFAULT_BINS, &names))
                            .expect("trace with surface maps")
                            .0
                    }
                };
                times[r][c] = t0.elapsed().as_secs_f64();
                cpu[r][c] = cpu_s() - c0;
                let plain = plain.get_or_insert_with(|| tallies.clone());
                assert_eq!(*plain, tallies, "the maps must not change the tallies");
            }
        }
        let total = |c: usize| times.iter().map(|t| t[c]).sum::<f64>();
        let n = (ROUNDS as u64 * RAYS) as f64;
        // The figure that survives a loaded machine: each round's ratio of times (the cases of
        // one round ran within seconds of each other), its median and range over the rounds.
        let ratios = |times: &[[f64; 3]; ROUNDS], c: usize| {
            let mut r: Vec<f64> = times.iter().map(|t| t[c] / t[0]).collect();
            r.sort_by(f64::total_cmp);
            (r[ROUNDS / 2], r[0], r[ROUNDS - 1])
        };
        let pct = |(m, lo, hi): (f64, f64, f64)| {
            format!(
                "{:+.1} % (rounds {:+.1} to {:+.1} %)",
                100.0 * (m - 1.0),
                100.0 * (lo - 1.0),
                100.0 * (hi - 1.0)
            )
        };
        println!(
            "{}: maps off {:.0} rays/s, on {:.0} rays/s, with {} named surfaces ({}) {:.0} rays/s \
             on 2 threads, {DEFAULT_BINS} x {DEFAULT_BINS} bins; median time per round with the \
             diodes' maps {}, with the surfaces' too {}; median CPU time per round with the \
             diodes' maps {}, with the surfaces' too {}; {ROUNDS} rounds of {RAYS} rays; {}",
            path.display(),
            n / total(0),
            n / total(1),
            names.len(),
            names.join(", "),
            n / total(2),
            pct(ratios(&times, 1)),
            pct(ratios(&times, 2)),
            pct(ratios(&cpu, 1)),
            pct(ratios(&cpu, 2)),
            load()
        );
    }
}
