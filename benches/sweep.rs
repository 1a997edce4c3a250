//! A 1-D sweep of 11 points on the paper bench, at the ray count that resolves each point's
//! difference from the nominal bench to 0.1 % (of k₋ for k₋'s difference, and 1e-3 absolute
//! for the imbalance's), against independent runs at the same precision.
//!
//!     cargo bench --bench sweep [-- PATH=START:STOP:N]
//!
//! A pilot sweep measures, at every point, the paired (common-random-number) standard error of
//! the difference and the standard error independent runs would have (√(SE_a² + SE_b²)). Both
//! fall as 1/√rays, so the pilot predicts the rays each needs for the target; the sweep is then
//! run and timed at the common-random-number count, and the effective speed-up is the ratio of
//! the two ray counts (the time per ray is the same).

use std::path::Path;
use std::time::Instant;

use spibench::quantities::BenchMetric;
use spibench::scene::doc::BenchDoc;
use spibench::sweep::{Sweep, SweepOptions, Vary, sweep};

/// The worst, over the points, of (paired SE, independent SE) of the difference from the
/// nominal bench, in target units: Δk₋ / k₋ / 1e-3 and Δimbalance / 1e-3.
fn worst(s: &Sweep) -> (f64, f64) {
    let k0 = s.nominal.metrics[BenchMetric::KMinus].value;
    let mut out = (0.0f64, 0.0f64);
    for p in &s.points {
        for (name, scale) in [
            (BenchMetric::KMinus, k0 * 1e-3),
            (BenchMetric::Imbalance, 1e-3),
        ] {
            let (a, b) = (&p.metrics[name], &s.nominal.metrics[name]);
            out.0 = out.0.max(a.diff(b).stderr / scale);
            out.1 = out.1.max(a.stderr().hypot(b.stderr()) / scale);
        }
    }
    out
}

fn main() {
    let vary = std::env::args()
        .skip(1)
        .find(|a| a.contains('='))
        .unwrap_or_else(|| "arm_minus_lens.despace_mm=-5:5:11".to_string());
    let vary = Vary::parse(&vary).expect("PATH=START:STOP:N");
    let doc = BenchDoc::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron"))
        .expect("the paper bench");
    let pilot_rays = 100_000;
    let opts = |rays| SweepOptions {
        rays,
        seed: 1,
        quality: false,
    };
    let t = Instant::now();
    let pilot = sweep(
        &doc,
        std::slice::from_ref(&vary),
        &opts(pilot_rays),
        &|_, _| {},
    )
    .unwrap();
    let pilot_s = t.elapsed().as_secs_f64();
    let (paired, independent) = worst(&pilot);
    // SE ∝ 1/√rays: rays to bring the worst point to the target (ratio 1), with 10 % to spare.
    // At least 50 batches, so that the batch-means errors themselves are reliable.
    let need = |r: f64, base: u64| ((base as f64) * 1.1 * r * r).ceil().max(51_200.0) as u64;
    let (mut n_crn, n_ind) = (need(paired, pilot_rays), need(independent, pilot_rays));
    println!(
        "sweep of {} = {}..{} ({} points + nominal), paper bench",
        vary.path, vary.start, vary.stop, vary.n
    );
    println!(
        "pilot at {pilot_rays} rays/point: {pilot_s:.1} s; worst SE of a difference / target: \
         {paired:.2} paired, {independent:.2} independent"
    );
    // Confirm, raising the ray count while the worst point misses the target (the paired
    // error's estimate is heavy-tailed: a few rays whose path the change alters dominate it).
    let (seconds, achieved) = loop {
        let t = Instant::now();
        let s = sweep(&doc, std::slice::from_ref(&vary), &opts(n_crn), &|_, _| {}).unwrap();
        let seconds = t.elapsed().as_secs_f64();
        let (achieved, _) = worst(&s);
        if achieved <= 1.0 || n_crn > 50 * pilot_rays {
            break (seconds, achieved);
        }
        println!("  {n_crn} rays/point: worst SE / target {achieved:.2}, raising the ray count");
        n_crn = need(achieved, n_crn);
    };
    let per_ray = seconds / (n_crn as f64 * (vary.n + 1) as f64);
    let independent_s = per_ray * n_ind as f64 * (vary.n + 1) as f64;
    println!(
        "common random numbers: {n_crn} rays/point, {seconds:.1} s for the sweep, worst SE / \
         target {achieved:.2}"
    );
    println!(
        "independent runs at the same precision: {n_ind} rays/point, ~{independent_s:.0} s \
         (extrapolated at the same time per ray)"
    );
    println!(
        "effective speed-up of common random numbers: {:.0}x",
        n_ind as f64 / n_crn as f64
    );
}
