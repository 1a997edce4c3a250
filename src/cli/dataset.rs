//! `spibench dataset`: synthetic datasets through a traced bench (crate::dataset).

use std::path::PathBuf;

use crate::dataset::{Prepared, generate, merge, read_manifest};
use crate::error::Error;
use crate::report::output::FolderLock;
use crate::scene::dataset::read_dataset;

#[derive(Debug, Clone, clap::Args)]
pub struct DatasetArgs {
    /// The dataset spec (RON; see scenes/dataset_example.ron). Not needed with --merge.
    pub spec: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/dataset")]
    pub out: PathBuf,
    /// Make only job I of N (0-based) of the dataset's shards, e.g. `--shard 2/8`: a contiguous
    /// block of shard folders, from ⌊I·T/N⌋ to ⌊(I+1)·T/N⌋ of the T shards.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Continue an interrupted run in --out from its last committed shard.
    #[arg(long)]
    pub resume: bool,
    /// Merge these dataset folders (the jobs of a sharded run) into --out.
    #[arg(long, num_args = 1..)]
    pub merge: Vec<PathBuf>,
    #[command(flatten)]
    pub work: crate::cli::args::WorkArgs,
}

/// A work-limit refusal ([`crate::cli::args::WorkArgs::check`]) located in the spec: at its
/// `samples` when the samples are over their limit, else at the kernel's `rays` (the traced
/// rays), with the message (and its `--allow-large`) kept.
fn work_error(
    spec: &crate::scene::dataset::DatasetSpec,
    w: &crate::cli::args::Work,
    e: Error,
) -> Error {
    match e {
        Error::Input { message, .. } if w.samples >= crate::cli::args::MAX_WORK_SAMPLES => {
            spec.error("samples", message)
        }
        Error::Input { message, .. } => spec.kernel_error(Error::field("rays", message)),
        e => e,
    }
}

/// The work of this job of the dataset: its samples, and the kernels it traces (one for a
/// nominal dataset; one per drawn bench of its samples, besides their compensators' traces).
fn work(
    spec: &crate::scene::dataset::DatasetSpec,
    job: Option<crate::cli::args::Shard>,
) -> crate::cli::args::Work {
    let f = &spec.file;
    let shards = f.samples.div_ceil(f.shard_samples);
    let (a, b) = job.map_or((0, shards), |j| j.block(shards));
    let (first, end) = (a * f.shard_samples, (b * f.shard_samples).min(f.samples));
    let samples = end.saturating_sub(first);
    let kernels = match &f.benches {
        crate::scene::dataset::BenchesSpec::Tolerance {
            samples_per_bench, ..
        } if samples > 0 => (end - 1) / samples_per_bench - first / samples_per_bench + 1,
        _ => 1,
    };
    crate::cli::args::Work {
        rays: kernels as f64 * f.kernel.rays as f64,
        samples: samples as f64,
        bytes: 0.0,
        what: format!(
            "{samples} samples through {kernels} kernel(s) of {} rays",
            f.kernel.rays
        ),
    }
}

pub fn run(args: &DatasetArgs) -> anyhow::Result<()> {
    let command: Vec<String> = std::env::args().collect();
    if !args.merge.is_empty() {
        if let Some(spec) = &args.spec {
            return Err(Error::field(
                "SPEC",
                format!(
                    "--merge makes a dataset from the folders it names, not from a spec: drop \
                     {} (the folders' manifests name their spec)",
                    spec.display()
                ),
            )
            .into());
        }
        for (flag, given) in [("--shard", args.shard.is_some()), ("--resume", args.resume)] {
            if given {
                return Err(Error::field(flag, "is not an option of --merge").into());
            }
        }
        // The job's fields in its errors (`merge`, `out`, `resume`) are shown as the flags when the
        // error is printed (super::flags).
        let m = merge(&args.merge, &args.out, &command)?;
        println!(
            "merged {} folders: {} shards, {} samples → {}",
            args.merge.len(),
            m.shards.len(),
            m.samples,
            args.out.display()
        );
        return Ok(());
    }
    let Some(spec_path) = &args.spec else {
        return Err(Error::field("SPEC", "name a dataset spec (or --merge folders)").into());
    };
    let job = crate::cli::args::Shard::parse_opt(args.shard.as_deref())?;
    let spec = read_dataset(spec_path)?;
    // Above the limits, refused before the kernel is traced (the disk a dataset needs is
    // checked against its spec's `max_disk_gb` when it is prepared).
    let w = work(&spec, job);
    args.work.check(&w).map_err(|e| work_error(&spec, &w, e))?;
    // The folder is locked before the kernel is traced, so that a second run into it (a
    // `--resume` while the first still writes) stops at once.
    let lock = FolderLock::acquire(&args.out)?;
    let prep = Prepared::new(spec)?;
    let range = job.map_or((0, prep.shards_total()), |j| j.block(prep.shards_total()));
    crate::note!(
        "kernel: {} rays, {} entries, traced in {:.1} s; multi-crossing share {:.2e}",
        prep.kernel.rays,
        prep.kernel.entries.len(),
        prep.kernel_seconds,
        prep.kernel.multi_crossing_current_fraction()
    );
    if let Some(d) = &prep.drawn {
        crate::note!(
            "benches: drawn from {} ({} tolerance(s), {} compensator(s)), a new one every {} \
             samples, each traced as its own kernel",
            d.set.path.display(),
            d.set.tolerances.len(),
            d.set.compensators.len(),
            d.samples_per_bench
        );
    }
    let g = generate(
        &prep,
        &lock,
        range,
        args.resume,
        &command,
        &|done, total| crate::note!("shard {done}/{total} committed"),
    )?;
    let m = read_manifest(&args.out)?;
    let samples: u64 = m.shards.iter().map(|s| s.samples).sum();
    println!(
        "{} shards written ({} already there), {} samples in {} ({:.1} samples/s; {:.1} % of \
         the {:.2} s outside the sample loops)",
        g.shards_written,
        g.shards_resumed,
        samples,
        args.out.display(),
        g.samples_written as f64 / g.seconds.max(1e-9),
        100.0 * (1.0 - g.sample_seconds / g.seconds.max(1e-9)),
        g.seconds
    );
    let c = &g.commits;
    crate::note!(
        "shard writing: arrays {:.2} s (encoded, hashed and written), manifest {:.2} s; the \
         sample loops waited {:.2} s for it, and outlasted their last samples by {:.3} s",
        c.arrays,
        c.manifest,
        c.waited,
        c.held
    );
    // Reference values for readers (the CI's numpy check reads this line).
    if range.0 < range.1 {
        let first = range.0 * prep.spec.file.shard_samples;
        let s = prep.sample(first)?;
        let object_sum: f64 = s.object.iter().sum();
        let (name, _, _) = &prep.measurement_names()[0];
        println!(
            "check: sample {first} object_sum {object_sum:.17e} {name}[0] {:.17e} k+ {:.17e}",
            s.measurements[0][0], s.k_a_per_w[0]
        );
    }
    Ok(())
}
