//! Irradiance-map benchmark (harness = false, std::time only): `cargo bench --bench irradiance
//! [-- SCENE …]`.
//!
//! Traces each bench (default: scenes/paper_bench.ron and scenes/paper_bench_condenser.ron)
//! with the diodes' irradiance maps (`trace::irradiance::trace_with_maps`, 64 × 64 bins),
//! with those and the maps at three named surfaces as well (`trace_with_surface_maps`: the
//! imaging iris and the two arm lenses, `trace --irradiance-at`), and without maps
//! (`trace::trace`), same rays and seed, in rotation five times on two threads so that the
//! machine's drift falls on all three, and prints the throughput of each and the maps' extra
//! time, with the load average beside it. The maps are recorded from the same paths (a short
//! list of hits per batch, binned in the merge), so the target is under 10 % more time; the
//! tallies of the traces are checked to be identical.

use std::path::PathBuf;
use std::time::Instant;

use spibench::scene::doc::BenchDoc;
use spibench::trace::irradiance::{DEFAULT_BINS, trace_with_maps, trace_with_surface_maps};
use spibench::trace::{TraceOptions, trace};

const RAYS: u64 = 200_000;
const ROUNDS: usize = 5;

/// The named surfaces mapped in the third case (those of them the bench has).
const SURFACES: [&str; 3] = ["imaging_iris", "arm_plus_lens", "arm_minus_lens"];

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(|l| format!("load {l}")))
        .unwrap_or_else(|| "load ?".into())
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
        let names: Vec<String> = SURFACES
            .iter()
            .filter(|n| bench.elements().iter().any(|e| e == *n))
            .map(|n| n.to_string())
            .collect();
        let (mut off, mut on, mut at) = (0.0, 0.0, 0.0);
        for _ in 0..ROUNDS {
            let t0 = Instant::now();
            let plain = pool.install(|| trace(&bench, &o)).expect("trace");
            off += t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let (mapped, _) = pool
                .install(|| trace_with_maps(&bench, &o, DEFAULT_BINS))
                .expect("trace with maps");
            on += t1.elapsed().as_secs_f64();
            assert_eq!(plain, mapped, "the maps must not change the tallies");
            let t2 = Instant::now();
            let (surfaces, _) = pool
                .install(|| trace_with_surface_maps(&bench, &o, DEFAULT_BINS, &names))
                .expect("trace with surface maps");
            at += t2.elapsed().as_secs_f64();
            assert_eq!(plain, surfaces, "the maps must not change the tallies");
        }
        let n = (ROUNDS as u64 * RAYS) as f64;
        println!(
            "{}: maps off {:.0} rays/s, on {:.0} rays/s, with {} named surfaces ({}) {:.0} rays/s \
             on 2 threads ({:+.1} % time with the diodes' maps, {:+.1} % with the surfaces' too; \
             {ROUNDS} rounds of {RAYS} rays; {})",
            path.display(),
            n / off,
            n / on,
            names.len(),
            names.join(", "),
            n / at,
            100.0 * (on / off - 1.0),
            100.0 * (at / off - 1.0),
            load()
        );
    }
}
