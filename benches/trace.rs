//! Tracer benchmark (harness = false, std::time only): `cargo bench --bench trace [-- SCENE]`.
//!
//! Traces a bench (default scenes/paper_bench.ron) and prints
//! - rays per second per core on 1 and 2 threads, and that the two give bit-identical tallies;
//!   with more cores (or SPIBENCH_TRACE_THREADS="4 8 16") the scaling to each thread count,
//! - the relative standard errors of k₊ and k₋, the number of rays and the time needed for
//!   0.1 % (extrapolated with SE ∝ 1/√N from a pilot run, then confirmed by one run at that N),
//!   with the default sampling, `Sampling::Split` (the refracted part of every interface
//!   crossing carried as weight, the reflected part followed with probability R),
//! - the same in the same run for the tracer's earlier sampling, `Sampling::Independent`
//!   (the analogue choice at every interface; the emission's Latin hypercube is the same), the
//!   baseline of the split crossings, and for `Sampling::Stratified`,
//! - and two baselines of the lamp's importance sampling: the field target without the chart
//!   guidance, and the bench without any field importance sampling (rays over the whole cone),
//! - the throughput of the diffractive DMD model against the geometric one (same rays, same
//!   run, three alternating pilot runs each).
//!
//! Timings are wall-clock and depend on what else the machine is doing (the load average is
//! printed beside them); the ratio to the baseline, measured in the same run, is the meaningful
//! comparison.

use std::path::PathBuf;
use std::time::Instant;

use spibench::optics::Bench;
use spibench::trace::{Sampling, Tallies, TraceOptions, trace};
use spibench::transport::Transport;

struct Run {
    seconds: f64,
    rel_se: [f64; 2],
    k: [f64; 2],
    tallies: Tallies,
}

fn run(bench: &Bench, rays: u64, seed: u64, threads: usize, sampling: Sampling) -> Run {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    let options = TraceOptions {
        sampling,
        ..TraceOptions::new(rays, seed)
    };
    let start = Instant::now();
    let tallies = pool.install(|| trace(bench, &options)).expect("trace");
    let seconds = start.elapsed().as_secs_f64();
    let t = Transport::from_tallies(bench, &tallies);
    Run {
        seconds,
        rel_se: [t.k[0].relative_stderr(), t.k[1].relative_stderr()],
        k: [t.k[0].value, t.k[1].value],
        tallies,
    }
}

/// Rays needed for 0.1 % on both k₊ and k₋, from a pilot run of `rays`.
fn rays_for_target(pilot: &Run, rays: u64) -> u64 {
    let worst = pilot.rel_se[0].max(pilot.rel_se[1]);
    ((rays as f64) * (worst / 1e-3).powi(2)).ceil() as u64
}

/// The 1-minute load average, to print beside a timing (the machine may be shared).
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(|l| format!("load {l}")))
        .unwrap_or_else(|| "load ?".into())
}

/// Thread counts of the scaling table: SPIBENCH_TRACE_THREADS ("1 2 4 8 16"), else the powers
/// of two above 2 up to the machine's cores, and the core count itself.
fn thread_counts() -> Vec<usize> {
    if let Ok(list) = std::env::var("SPIBENCH_TRACE_THREADS") {
        return list
            .split([' ', ','])
            .filter_map(|w| w.parse().ok())
            .filter(|&t| t > 2)
            .collect();
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut counts: Vec<usize> = (2..)
        .map(|k| 1usize << k)
        .take_while(|&t| t <= cores)
        .collect();
    if cores > 2 && counts.last() != Some(&cores) {
        counts.push(cores);
    }
    counts
}

/// The trace's thread scaling beyond 2 threads (rays/s, speed-up against `one`, the 1-thread
/// run, and that every count gives bit-identical tallies). Prints nothing on a 2-core machine.
fn scaling(bench: &Bench, rays: u64, sampling: Sampling, one: &Run) {
    for t in thread_counts() {
        let r = run(bench, rays, 1, t, sampling);
        println!(
            "{t:>3} threads: {:.0} rays/s, {:.2}x the 1-thread rate ({:.0} % of linear; {}); \
             bit-identical to 1 thread: {}",
            rays as f64 / r.seconds,
            one.seconds / r.seconds,
            100.0 * one.seconds / r.seconds / t as f64,
            load(),
            r.tallies == one.tallies
        );
    }
}

fn main() {
    let scene = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/scenes/paper_bench.ron"
            ))
        });
    let doc = match spibench::scene::doc::BenchDoc::read(&scene) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let build = |file: spibench::scene::bench::BenchFile| {
        spibench::scene::doc::BenchDoc::from_file(file, doc.path())
            .build()
            .unwrap_or_else(|e| {
                eprintln!("{e}");
                std::process::exit(2);
            })
    };
    let bench = build(doc.file.clone());
    println!("bench: {}", scene.display());

    let pilot_rays = 1_000_000;
    let new = Sampling::default();
    let one = run(&bench, pilot_rays, 1, 1, new);
    let two = run(&bench, pilot_rays, 1, 2, new);
    println!(
        "rays/s per core: {:.0} (1 thread), {:.0} (2 threads: {:.0} in total; {}); \
         1 and 2 threads bit-identical: {}",
        pilot_rays as f64 / one.seconds,
        pilot_rays as f64 / two.seconds / 2.0,
        pilot_rays as f64 / two.seconds,
        load(),
        one.tallies == two.tallies
    );
    scaling(&bench, pilot_rays, new, &one);
    println!(
        "pilot {pilot_rays} rays: k+ = {:.5} (rel. SE {:.2e}), k- = {:.5} (rel. SE {:.2e})",
        two.k[0], two.rel_se[0], two.k[1], two.rel_se[1]
    );
    let n = rays_for_target(&two, pilot_rays);
    let predicted = two.seconds * n as f64 / pilot_rays as f64;
    println!("0.1 % on k+ and k-: {n} rays, predicted {predicted:.2} s on 2 threads");
    let confirm = run(&bench, n, 2, 2, new);
    println!(
        "confirmed at {n} rays: {:.2} s on 2 threads ({}), rel. SE k+ {:.2e}, k- {:.2e}",
        confirm.seconds,
        load(),
        confirm.rel_se[0],
        confirm.rel_se[1]
    );

    // The baselines in the same run, same emission, same seed: the analogue tracer (the default
    // before the split crossings) and its stratified interaction streams.
    for (name, sampling) in [
        ("independent (analogue)", Sampling::Independent),
        ("stratified (analogue)", Sampling::Stratified),
    ] {
        let base = run(&bench, pilot_rays, 1, 2, sampling);
        let nb = rays_for_target(&base, pilot_rays);
        let tb = base.seconds * nb as f64 / pilot_rays as f64;
        println!(
            "baseline {name}: {:.0} rays/s on 2 threads ({}), k+ = {:.5} (rel. SE {:.2e}), \
             k- = {:.5} (rel. SE {:.2e}) -> 0.1 % needs {nb} rays, ~{tb:.2} s (extrapolated)",
            pilot_rays as f64 / base.seconds,
            load(),
            base.k[0],
            base.rel_se[0],
            base.k[1],
            base.rel_se[1],
        );
        println!(
            "{new:?} against {name}: {:.2}x the time per ray, {:.2}x fewer rays to 0.1 %, \
             {:.2}x less time to 0.1 % (pilot extrapolations, same run)",
            two.seconds / base.seconds,
            nb as f64 / n as f64,
            tb / predicted.max(1e-9)
        );
    }

    // The diffractive DMD model against the geometric one (docs/dmd_diffraction.md), same run,
    // same rays, alternating to spread the machine's drift over both: throughput ratio.
    let mut file = doc.file.clone();
    let geometric = build(file.clone());
    if let Some(d) = file.dmd.as_mut() {
        d.model = spibench::scene::bench::DmdModelSpec::Diffractive {
            tail_bin_nm: spibench::scene::numbers::Positive(10.0),
        };
    }
    let build_start = Instant::now();
    let diffractive = build(file);
    let build_s = build_start.elapsed().as_secs_f64();
    let (mut tg, mut td) = (0.0, 0.0);
    let mut kd = [0.0; 2];
    for _ in 0..3 {
        tg += run(&geometric, pilot_rays, 1, 2, new).seconds;
        let r = run(&diffractive, pilot_rays, 1, 2, new);
        td += r.seconds;
        kd = r.k;
    }
    println!(
        "DMD model: geometric {:.0} rays/s, diffractive {:.0} rays/s on 2 threads \
         ({:+.1} % time; tables built in {build_s:.2} s); diffractive k+ = {:.5}, k- = {:.5}",
        3.0 * pilot_rays as f64 / tg,
        3.0 * pilot_rays as f64 / td,
        100.0 * (td / tg - 1.0),
        kd[0],
        kd[1]
    );

    // Comparisons in the same run: the field target without the chart guidance, and no field
    // importance sampling at all (rays over the whole emission cone only).
    // Each variant is a bench of its own, built from an edited file.
    let mut file = doc.file.clone();
    if let Some(f) = file.lamp.field_sampling.as_mut() {
        f.chart_guided = None;
    }
    let unguided = build(file.clone());
    file.lamp.field_sampling = None;
    let plain = build(file);
    for (name, b) in [
        ("field target without chart guidance", &unguided),
        ("baseline without field sampling", &plain),
    ] {
        let base = run(b, pilot_rays, 1, 2, new);
        let nb = rays_for_target(&base, pilot_rays);
        let tb = base.seconds * nb as f64 / pilot_rays as f64;
        println!(
            "{name}: {:.0} rays/s, rel. SE k+ {:.2e}, k- {:.2e} at {pilot_rays} rays \
             -> 0.1 % needs {nb} rays, ~{tb:.1} s (extrapolated): {:.1}x slower to the target",
            pilot_rays as f64 / base.seconds,
            base.rel_se[0],
            base.rel_se[1],
            tb / confirm.seconds.max(1e-9)
        );
    }
}
