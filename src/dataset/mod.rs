//! Synthetic datasets (`spibench dataset`): many objects measured through one traced bench.
//!
//! The bench is traced once as an object kernel (`trace::kernel`, chart clear); every sample is
//! then an object on the kernel's grid, its transport by the kernel's sparse product
//! (`Transport::from_kernel`), and the detector electronics in time with their noise
//! (`pipeline::record_transport`), read by each scheme as in `spibench run`.
//!
//! Determinism: sample s draws its object from `rng::stream(mix64(seed ⊕ OBJECTS), s)` and its
//! noise from the seed mix64(mix64(seed ⊕ NOISE) ⊕ s), so it is the same whatever the shard,
//! the thread count or a resume. Samples are grouped in shards of `shard_samples` consecutive
//! samples; shard b holds samples b·S … (b+1)·S − 1.
//!
//! On disk (a dataset folder; every name of it is defined in [`contract`], beside the rules a
//! manifest read back must follow):
//! - `manifest.json`: schema (array names, dtypes, per-sample shapes, units), provenance
//!   (spibench version, spec and bench SHA-256 and copies `spec.ron`, `bench.ron`, seeds, the
//!   command), the shard range this folder is responsible for, and every committed shard with
//!   the SHA-256 of each of its files;
//! - `shard_NNNNNN/NAME.npy`: one `.npy` per array, first axis the shard's samples (float64,
//!   little endian, 64-byte aligned headers: `np.load(..., mmap_mode="r")` maps them);
//! - `patterns.npy` (optional): the packed base patterns.
//!
//! A shard is written in a staging folder `.shard_NNNNNN.partial` and committed by rename; the
//! manifest is rewritten (through a temporary name and a rename) after each commit. Killed at
//! any point, a `--resume` finds the committed shards in the manifest, checks their checksums,
//! removes staging leftovers and shards the manifest does not list, and continues; a folder
//! stopped before its first manifest (only setup files in it) is started afresh. SIGINT and
//! SIGTERM remove the shards being written and any temporary copy of a setup file or manifest.
//!
//! Here: the setup of a dataset (its bench, schemes, patterns and kernel: [`Prepared::new`]);
//! `manifest` (the manifest's types, the arrays' schema, reading it back), `sampler` (the
//! samples), `folder` (the folder written in place: [`generate`]), `shards` (a shard's writing
//! and commit) and `merge`.

use crate::acquisition::{PackedPatterns, Scheme, patterns_for_ratio};
use crate::error::Result;
use crate::pipeline::operator::ClearChart;
use crate::rng;
pub use crate::scene::dataset::ObjectFile;
use crate::scene::dataset::{BenchesSpec, DatasetSpec};
use crate::scene::doc::BenchDoc;
use crate::scene::run::RunScene;
use crate::trace::kernel::Kernel;

pub mod contract;
mod folder;
mod manifest;
mod merge;
mod sampler;
mod shards;

pub use contract::FORMAT;
pub use folder::{CommitSeconds, Generated, generate};
pub use manifest::{
    ArraySchema, FileHash, KernelInfo, Manifest, ManifestProvenance, MergedInput, ShardEntry,
    manifest_text, read_manifest, verify_shard,
};
pub use merge::merge;
pub use sampler::{BenchKernel, Sample};
// The names the shard writer (`shards`) uses from its parent.
use contract::shard_dir as shard_dir_name;
use folder::write_locked;

/// Stream tags of the objects and of the noise.
const OBJECTS: u64 = 0x0B1E_C750_0000_0001;
const NOISE: u64 = 0x0015_E000_0000_0002;

/// The record seed (noise and drift) of sample `s` of a dataset of seed `seed`.
pub fn noise_seed(seed: u64, s: u64) -> u64 {
    rng::mix64(rng::mix64(seed ^ NOISE) ^ s)
}

/// Everything a sample needs, made once per process.
pub struct Prepared {
    pub spec: DatasetSpec,
    pub scene: RunScene,
    pub kernel: Kernel,
    /// The base patterns for the highest ratio, with their operator built once.
    pub patterns: PackedPatterns,
    pub schemes: Vec<Scheme>,
    pub ratios: Vec<f64>,
    pub bench_text: String,
    pub kernel_seconds: f64,
    /// The benches drawn from a tolerance file, when the spec asks for them.
    pub drawn: Option<DrawnBenches>,
}

/// The benches of `benches: Tolerance(..)`.
pub struct DrawnBenches {
    pub doc: BenchDoc,
    pub set: crate::scene::tolerance::ToleranceSet,
    pub text: String,
    pub samples_per_bench: u64,
}

/// The run scene of a dataset's bench `doc`, which must have a DMD.
fn checked_scene(doc: &BenchDoc, spec: &DatasetSpec) -> Result<RunScene> {
    let scene = doc.run_scene()?;
    if scene.bench.dmd().is_none() {
        return Err(spec.error("bench", "a dataset needs a bench with a DMD"));
    }
    Ok(scene)
}

/// A bench's run scene with the settings the spec asks for: its schemes, the pattern family it
/// names, its oscilloscope frames and its record model.
fn dataset_scene(mut scene: RunScene, spec: &DatasetSpec, schemes: &[Scheme]) -> RunScene {
    let settings = &mut scene.settings;
    settings.schemes = schemes.to_vec();
    settings.signal_trace_frames = spec.file.write.scope_frames;
    settings.record = spec.file.record.model();
    if let Some(p) = spec.patterns() {
        settings.patterns = p.family();
    }
    scene
}

/// The object kernel of a dataset's bench `doc` (the spec's `kernel:` section), its chart and
/// numbers checked by the one kernel builder and its errors located in the spec.
fn bench_kernel(doc: &BenchDoc, spec: &DatasetSpec) -> Result<Kernel> {
    ClearChart::new(doc, &spec.file.kernel)
        .map_err(|e| spec.kernel_error(e))?
        .trace()
}

impl Prepared {
    /// Reads the bench, traces the kernel and builds the patterns.
    pub fn new(spec: DatasetSpec) -> Result<Prepared> {
        let bench_text = crate::scene::read_text(&spec.bench_path)?;
        let mut doc = BenchDoc::parse(&bench_text, &spec.bench_path)?;
        if let Some(e) = &spec.file.electronics {
            // The spec's electronics replace the bench's (checked, with located errors, when
            // the spec was read).
            doc.file.electronics = e.clone();
        }
        // The spec's DMD model replaces the bench's (a bench without a DMD is refused below).
        if let Some(m) = spec.file.dmd_model
            && doc.file.dmd.is_some()
        {
            doc.set_dmd_model(m)?;
        }
        let scene = checked_scene(&doc, &spec)?;
        let (schemes, ratios) = match &spec.file.acquisition {
            Some(a) => (a.schemes.clone(), a.ratios.clone()),
            None => (
                scene.settings.schemes.clone(),
                scene.settings.sampling_ratios.clone(),
            ),
        };
        let scene = dataset_scene(scene, &spec, &schemes);
        let k = &spec.file.kernel;
        let (w, h) = scene.bench.units_shape();
        let units = w * h;
        let r_max = ratios.iter().copied().fold(0.0, f64::max);
        let patterns = scene
            .settings
            .patterns
            .build(w, h, patterns_for_ratio(r_max, units))
            .map_err(|e| match spec.patterns() {
                Some(_) => spec.error("patterns", e.message()),
                None => e,
            })?;
        let disk_gb = spec.file.max_disk_gb.unwrap_or(100.0);
        let per_sample = 8.0
            * (k.grid_px.0 * k.grid_px.1
                + 4
                + ratios
                    .iter()
                    .map(|r| patterns_for_ratio(*r, units))
                    .sum::<usize>()
                    * schemes.len()) as f64;
        // The optional arrays: reconstructions with their DMD image and scores, and about
        // P + 1 oscilloscope samples per recorded frame of each of at most three sequences.
        let w = &spec.file.write;
        let cells = (schemes.len() * ratios.len()) as f64;
        let optional = if w.reconstructions {
            8.0 * (units as f64 * (1.0 + cells) + 2.0 * cells)
        } else {
            0.0
        } + 8.0
            * 3.0
            * 3.0
            * w.scope_frames as f64
            * (scene.scope.sample_rate_hz / scene.settings.dmd_rate_hz + 1.0);
        let need_gb = (per_sample + optional) * spec.file.samples as f64 / 1e9;
        if need_gb > disk_gb {
            return Err(spec.error(
                "samples",
                format!(
                    "{} samples need {need_gb:.3} GB, more than the {disk_gb} GB allowed \
                     (max_disk_gb)",
                    spec.file.samples
                ),
            ));
        }
        let drawn = match (&spec.tolerance_path, &spec.file.benches) {
            (
                Some(path),
                BenchesSpec::Tolerance {
                    samples_per_bench, ..
                },
            ) => {
                let text = crate::scene::read_text(path)?;
                let set = crate::scene::tolerance::ToleranceSet::parse(&text, path, &doc)?;
                set.refuse_attenuator(&text, "a dataset's benches")?;
                Some(DrawnBenches {
                    doc: doc.clone(),
                    set,
                    text,
                    samples_per_bench: *samples_per_bench,
                })
            }
            _ => None,
        };
        let start = std::time::Instant::now();
        let kernel = bench_kernel(&doc, &spec)?;
        let kernel_seconds = start.elapsed().as_secs_f64();
        Ok(Prepared {
            spec,
            scene,
            kernel,
            patterns: PackedPatterns::new(patterns),
            schemes,
            ratios,
            bench_text,
            kernel_seconds,
            drawn,
        })
    }
}

pub use crate::provenance::sha256_hex;

/// `I/N` → the shard range of job I of N (contiguous blocks).
pub fn shard_range(total: u64, job: Option<(u64, u64)>) -> (u64, u64) {
    match job {
        None => (0, total),
        Some((i, n)) => (i * total / n, (i + 1) * total / n),
    }
}
