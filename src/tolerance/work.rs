//! The work of a tolerance run, estimated before it starts: every traced bench costs its rays
//! and, before them, the bench's build and chart-guide fit, which at a few thousand rays cost
//! more than the rays do. Both are counted in traced lamp rays (the fixed cost as the rays
//! traced in the same time), and the total is also stated as a rough time.

use crate::scene::tolerance::{CompensatorObjective, ToleranceSet};

use super::Resolve;

/// The fixed cost of one traced bench of a tolerance run, in the lamp rays traced in the same
/// time: drawing its deviations, building it twice (the validity check of a trial and the
/// evaluation) with its BVH, spectral sampler and chart-guide fit, and reducing its tallies to
/// metrics. From the per-trial times of `tolerance` on the paper bench, a + b·rays fitted over
/// three ray counts, as a/b (docs/performance.md, "The fixed cost of a tolerance trial"). A
/// compensator's evaluation builds its bench once, so counting it at this cost errs high.
pub const BENCH_OVERHEAD_RAYS: f64 = 12_000.0;

/// Lamp rays traced per second on two cores, for the rough time of an estimate: the same
/// fit's b, on two threads (a bench with more surfaces or a diffractive DMD traces more
/// slowly, a release build a little faster).
pub const RAYS_PER_SECOND_TWO_CORES: f64 = 3.8e5;

/// Each compensator group (balance, power) of a trial is searched with at most 60 evaluations
/// at up to a quarter of the trial's rays (`pipeline::perturb`): 60 benches, the rays of 15
/// traces.
const BENCHES_PER_COMPENSATOR_GROUP: f64 = 60.0;
const TRACES_PER_COMPENSATOR_GROUP: f64 = 15.0;

/// A tolerance run's estimated work.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkEstimate {
    /// Benches built and traced (the nominal bench, the sensitivity ends, every trial and its
    /// compensators' evaluations).
    pub benches: f64,
    /// Lamp rays traced in all.
    pub rays: f64,
    /// `rays` plus [`BENCH_OVERHEAD_RAYS`] per bench: the work, in traced rays.
    pub equivalent_rays: f64,
    /// The rough time of `equivalent_rays` on two cores (s).
    pub seconds: f64,
    /// The counts that make it, for a message.
    pub what: String,
}

/// The work of `trials` trials (those this run holds), with the sensitivity table when
/// `sensitivity` (with `resolve`, each end traced again up to its `max_rays`), every trace at
/// `rays`, and each trial with up to 60 evaluations per compensator group at a quarter of the
/// rays.
pub fn estimate(
    set: &ToleranceSet,
    trials: u64,
    sensitivity: bool,
    rays: u64,
    resolve: Option<&Resolve>,
) -> WorkEstimate {
    let r = rays as f64;
    let ends = 2.0 * set.tolerances.len() as f64;
    // With `resolve`, an end is traced again at 2ᵏ× the rays up to max_rays: at most twice
    // max_rays in all, over at most log₂(max_rays / rays) traces.
    let (sens_traces, sens_rays) = match (sensitivity, resolve) {
        (false, _) => (0.0, 0.0),
        (true, None) => (ends, ends * r),
        (true, Some(v)) => {
            let again = (v.max_rays as f64 / r).log2().ceil().max(0.0);
            (ends * (1.0 + again), ends * (r + 2.0 * v.max_rays as f64))
        }
    };
    let groups = [CompensatorObjective::Balance, CompensatorObjective::Power]
        .iter()
        .filter(|o| set.compensators.iter().any(|c| c.objective == **o))
        .count() as f64;
    let per_trial = 1.0 + TRACES_PER_COMPENSATOR_GROUP * groups;
    let benches_per_trial = 1.0 + BENCHES_PER_COMPENSATOR_GROUP * groups;
    let n = trials as f64;
    let benches = 1.0 + sens_traces + n * benches_per_trial;
    let rays_total = r + sens_rays + n * per_trial * r;
    let equivalent_rays = rays_total + benches * BENCH_OVERHEAD_RAYS;
    let seconds = equivalent_rays / RAYS_PER_SECOND_TWO_CORES;
    let what = format!(
        "{trials} trials × up to {per_trial} traces × {rays} rays and {sens_traces} sensitivity \
         traces{}, and {benches:.0} benches built at {BENCH_OVERHEAD_RAYS:.0} rays' time each \
         for the build and chart-guide fit: {}",
        if resolve.is_some() && sensitivity {
            " (resolved)"
        } else {
            ""
        },
        rough_time(seconds)
    );
    WorkEstimate {
        benches,
        rays: rays_total,
        equivalent_rays,
        seconds,
        what,
    }
}

/// A duration as a message states an estimate: "about 40 s", "about 12 min", "about 15 h",
/// "about 3.2 days" (two significant figures at most; an estimate is no more precise).
pub fn rough_time(seconds: f64) -> String {
    let on = "on two cores";
    if !seconds.is_finite() {
        return format!("an unbounded time {on}");
    }
    let (v, unit) = if seconds < 120.0 {
        (seconds, "s")
    } else if seconds < 7_200.0 {
        (seconds / 60.0, "min")
    } else if seconds < 172_800.0 {
        (seconds / 3_600.0, "h")
    } else {
        (seconds / 86_400.0, "days")
    };
    if v < 10.0 {
        format!("about {v:.1} {unit} {on}")
    } else {
        format!("about {v:.0} {unit} {on}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::doc::BenchDoc;
    use std::path::Path;

    fn paper_set() -> ToleranceSet {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let doc = BenchDoc::read(&root.join("scenes/paper_bench.ron")).unwrap();
        let path = root.join("scenes/tolerances/paper_bench.ron");
        let text = std::fs::read_to_string(&path).unwrap();
        ToleranceSet::parse(&text, &path, &doc).unwrap()
    }

    /// A million trials at 4096 rays trace only 4·10⁹ rays, but their benches' builds make it
    /// over 10¹⁰ rays' work (about 12 h); a hundred trials stay small.
    #[test]
    fn the_fixed_cost_of_each_bench_is_counted() {
        let set = paper_set();
        assert!(set.compensators.is_empty());
        let big = estimate(&set, 1_000_000, true, 4096, None);
        assert!(big.rays < 5e9, "{big:?}");
        assert!(big.equivalent_rays > 1e10, "{big:?}");
        assert_eq!(big.benches, 1.0 + 2.0 * set.tolerances.len() as f64 + 1e6);
        assert!(big.seconds > 10.0 * 3600.0, "{big:?}");
        assert!(big.what.contains("about 12 h on two cores"), "{}", big.what);
        let small = estimate(&set, 100, true, 4096, None);
        assert!(small.equivalent_rays < 1e7, "{small:?}");
        // A shard without the sensitivity table traces the nominal bench and its trials only.
        let shard = estimate(&set, 100, false, 4096, None);
        assert_eq!(shard.benches, 101.0);
    }

    #[test]
    fn rough_times_round_to_their_unit() {
        assert_eq!(rough_time(42.0), "about 42 s on two cores");
        assert_eq!(rough_time(600.0), "about 10 min on two cores");
        assert_eq!(rough_time(54_000.0), "about 15 h on two cores");
        assert_eq!(rough_time(280_000.0), "about 3.2 days on two cores");
    }

    /// Per-trial cost against rays, for docs/performance.md: `cargo test --lib
    /// tolerance::work::tests::measure_trial_cost -- --ignored --nocapture`, on one thread
    /// (process CPU time, which other processes on a shared machine do not inflate).
    #[test]
    #[ignore]
    fn measure_trial_cost() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let doc = BenchDoc::read(&root.join("scenes/paper_bench.ron")).unwrap();
        let set = paper_set();
        let cpu = || {
            let stat = std::fs::read_to_string("/proc/self/stat").unwrap();
            let f: Vec<&str> = stat
                .rsplit(')')
                .next()
                .unwrap()
                .split_whitespace()
                .collect();
            (f[11].parse::<f64>().unwrap() + f[12].parse::<f64>().unwrap()) / 100.0
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        pool.install(|| {
            let n = 40;
            for rays in [4096u64, 16_384, 65_536] {
                let o = super::super::ToleranceOptions {
                    rays,
                    seed: 1,
                    quality: false,
                };
                let nom = super::super::nominal(&doc, &o).unwrap();
                let (c0, w0) = (cpu(), std::time::Instant::now());
                for i in 0..n {
                    super::super::trial(&doc, &set, &nom, &o, i).unwrap();
                }
                let (c1, w1) = (cpu(), std::time::Instant::now());
                for i in 0..n {
                    let (d, _, _) = super::super::trial_doc(&doc, &set, &o, i).unwrap();
                    d.build().unwrap();
                }
                let c2 = cpu();
                let bench = doc.build().unwrap();
                for i in 0..n {
                    crate::pipeline::trace_stage(
                        &bench,
                        &crate::pipeline::TraceRequest::new(rays, i),
                    )
                    .unwrap();
                }
                let c3 = cpu();
                eprintln!(
                    "rays {rays}: trial {:.1} ms CPU ({:.1} ms wall), draw+build {:.1} ms, \
                     trace_stage {:.1} ms",
                    (c1 - c0) / n as f64 * 1e3,
                    (w1 - w0).as_secs_f64() / n as f64 * 1e3,
                    (c2 - c1) / n as f64 * 1e3,
                    (c3 - c2) / n as f64 * 1e3
                );
            }
        });
    }
}
