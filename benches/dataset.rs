//! Dataset throughput: 10 000 samples of 48 × 48 random crops of the shipped images through the
//! paper bench (secondary complementary balancing and double-arm at 25 %, the electronics noise
//! of the bench, no reconstructions), made from one traced object kernel; against the baseline
//! of tracing each object directly (the object as the chart's image mask), measured on a few
//! objects in the same run.
//!
//!     cargo bench --bench dataset            (SPIBENCH_DATASET_SAMPLES, _RAYS override)
//!     SPIBENCH_DATASET_THREADS="1 2 4 8 16" cargo bench --bench dataset   (thread scaling too)
//!
//! Targets on a 2-core machine: ≥ 200 samples/s after the kernel trace, kernel trace < 2 min.
//! The samples are recorded frame by frame (the dataset default); a subset is also recorded
//! sample by sample in time, as `spibench run` does, to show what that costs.

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;
use spibench::dataset::{Prepared, generate, shard_range};
use spibench::detector::RecordModel;
use spibench::scene::bench::{
    ChartPatternSpec, ChartSpec, ElementSpec, Finite, LengthMm, SpectrumSpec,
};
use spibench::scene::dataset::parse_dataset;
use spibench::scene::doc::BenchDoc;
use spibench::trace::{TraceOptions, trace};
use spibench::transport::Transport;

fn env(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// With SPIBENCH_DATASET_THREADS (say "1 2 4 8 16"), the same dataset written again at each
/// thread count (a pool of that many threads): samples/s, the speed-up against the first count,
/// and the share of the time outside the parallel sample loops (the serial part).
fn scaling(prep: &Prepared, samples: u64) {
    let Ok(list) = std::env::var("SPIBENCH_DATASET_THREADS") else {
        return;
    };
    let mut base = None;
    for t in list
        .split([' ', ','])
        .filter_map(|w| w.parse::<usize>().ok())
    {
        let out =
            std::env::temp_dir().join(format!("spibench-bench-dataset-{}-{t}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .expect("pool");
        let g = pool.install(|| {
            let lock = spibench::report::output::FolderLock::acquire(&out).expect("lock");
            let range = shard_range(prep.shards_total(), None);
            generate(prep, &lock, range, false, &["bench".into()], &|_, _| {}).expect("dataset")
        });
        let _ = std::fs::remove_dir_all(&out);
        let rate = samples as f64 / g.seconds;
        let base = *base.get_or_insert(rate);
        println!(
            "threads {t:3}: {rate:8.1} samples/s, speed-up {:5.2}, {:4.1} % outside the sample loops",
            rate / base,
            100.0 * (1.0 - g.sample_seconds / g.seconds)
        );
    }
}

fn main() {
    let samples = env("SPIBENCH_DATASET_SAMPLES", 10_000);
    let rays = env("SPIBENCH_DATASET_RAYS", 2_000_000);
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let spec_path = scenes.join("bench_dataset.ron");
    let text = format!(
        "Dataset(\n    bench: \"paper_bench.ron\",\n    kernel: (rays: {rays}, seed: 1, grid_px: (48, 48), field_mm: (7.88, 7.88)),\n    objects: TestImages(names: [\"astronaut\", \"chelsea\", \"coffee\", \"rocket\", \"hubble_deep_field\"], rule: RandomCrop),\n    acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm], ratios: [0.25]),\n    seed: 3,\n    samples: {samples},\n    shard_samples: 500,\n)\n"
    );
    let spec = parse_dataset(&text, &spec_path).expect("spec");
    let prep = Prepared::new(spec).expect("kernel");
    println!(
        "kernel trace: {rays} rays, {:.1} s ({} entries; multi-crossing share {:.2e}) [target < 120 s]",
        prep.kernel_seconds,
        prep.kernel.entries.len(),
        prep.kernel.multi_crossing_current_fraction()
    );
    let out = std::env::temp_dir().join(format!("spibench-bench-dataset-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let lock = spibench::report::output::FolderLock::acquire(&out).expect("lock");
    let g = generate(
        &prep,
        &lock,
        shard_range(prep.shards_total(), None),
        false,
        &["bench".into()],
        &|_, _| {},
    )
    .expect("dataset");
    let per_s = samples as f64 / g.seconds;
    println!(
        "dataset: {samples} samples in {:.1} s: {per_s:.0} samples/s (written to disk) [target ≥ 200]; \
         {:.1} % of the time outside the parallel sample loops",
        g.seconds,
        100.0 * (1.0 - g.sample_seconds / g.seconds)
    );
    let _ = std::fs::remove_dir_all(&out);
    drop(lock);
    scaling(&prep, samples);

    // The same samples recorded sample by sample in time (the model of `spibench run`), on a
    // subset, without writing: what the frame-level record saves.
    let subset = env("SPIBENCH_DATASET_SAMPLE_MODEL", 200).min(samples);
    let mut prep = prep;
    let timed = |prep: &Prepared| {
        let t = Instant::now();
        (0..subset).into_par_iter().for_each(|s| {
            prep.sample(s).expect("sample");
        });
        subset as f64 / t.elapsed().as_secs_f64()
    };
    let frames_rate = timed(&prep);
    prep.scene.settings.record = RecordModel::Samples;
    let samples_rate = timed(&prep);
    prep.scene.settings.record = RecordModel::Frames;
    println!(
        "record model on {subset} samples (no writing): frames {frames_rate:.0} samples/s, \
         samples (time domain) {samples_rate:.1} samples/s: {:.0}× faster",
        frames_rate / samples_rate
    );

    // Baseline: each object traced directly at the kernel's ray count, then recorded the same
    // way (so the comparison is per sample, end to end).
    let direct_objects = env("SPIBENCH_DATASET_DIRECT", 2);
    let tmp = std::env::temp_dir().join(format!("spibench-bench-direct-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let doc = BenchDoc::read(&scenes.join("paper_bench.ron")).unwrap();
    let start = Instant::now();
    for s in 0..direct_objects {
        let object = prep.object(s).unwrap();
        let png = tmp.join(format!("object{s}.png"));
        spibench::report::png::write_gray16(&png, &object, 0.0, 1.0).unwrap();
        let mut d = doc.clone();
        for el in d.file.elements.iter_mut() {
            if let ElementSpec::Chart(ChartSpec {
                pattern,
                center_on,
                chrome_od,
                chrome_reflectance,
                ..
            }) = el
            {
                *pattern = ChartPatternSpec::Image {
                    path: png.display().to_string(),
                    width_mm: LengthMm(7.88),
                    height_mm: LengthMm(7.88),
                };
                *center_on = None;
                *chrome_od = SpectrumSpec::Constant(Finite(10.0));
                *chrome_reflectance = SpectrumSpec::Constant(Finite(0.0));
            }
        }
        let bench = d.build().unwrap();
        let t = trace(&bench, &TraceOptions::new(rays, 1)).unwrap();
        let transport = Transport::from_tallies(&bench, &t);
        let _ = spibench::pipeline::record_transport(
            &transport,
            &prep.scene.detector,
            &prep.scene.scope,
            &prep.scene.settings,
            &prep.patterns,
            s,
            &|_, _, _| {},
        )
        .unwrap();
    }
    let direct_s = start.elapsed().as_secs_f64() / direct_objects as f64;
    let _ = std::fs::remove_dir_all(&tmp);
    println!(
        "direct tracing: {direct_s:.1} s per object ({direct_objects} objects, {rays} rays each); \
         speed-up of the kernel {:.0}× per sample ({:.0}× including the kernel trace over {samples} samples)",
        direct_s * per_s,
        direct_s * samples as f64 / (g.seconds + prep.kernel_seconds)
    );
}
