//! Irradiance-map benchmark (harness = false, std::time only): `cargo bench --bench irradiance
//! [-- SCENE …]`.
//!
//! Traces each bench (default: scenes/paper_bench.ron and scenes/paper_bench_condenser.ron)
//! with the diodes' irradiance maps (`trace::irradiance::trace_with_maps`, 64 × 64 bins) and
//! without them (`trace::trace`), same rays and seed, alternating five times on two threads so
//! that the machine's drift falls on both, and prints the throughput of each and the maps'
//! extra time, with the load average beside it. The maps are recorded from the same paths
//! (a short list of hits per batch, binned in the merge), so the target is under 10 % more
//! time; the tallies of the two traces are checked to be identical.

use std::path::PathBuf;
use std::time::Instant;

use spibench::scene::doc::BenchDoc;
use spibench::trace::irradiance::{DEFAULT_BINS, trace_with_maps};
use spibench::trace::{TraceOptions, trace};

const RAYS: u64 = 200_000;
const ROUNDS: usize = 5;

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
        let (mut off, mut on) = (0.0, 0.0);
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
        }
        let n = (ROUNDS as u64 * RAYS) as f64;
        println!(
            "{}: maps off {:.0} rays/s, on {:.0} rays/s on 2 threads ({:+.1} % time with the \
             maps; {ROUNDS} alternating rounds of {RAYS} rays; {})",
            path.display(),
            n / off,
            n / on,
            100.0 * (on / off - 1.0),
            load()
        );
    }
}
