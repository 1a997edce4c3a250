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
//! On disk (a dataset folder):
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

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::acquisition::{PackedPatterns, Scheme, patterns_for_ratio};
use crate::error::{Error, Result};
use crate::pipeline::evaluate;
use crate::raster::Raster;
use crate::report::npy::F64FileWriter;
use crate::report::output::FolderLock;
use crate::report::untrusted::bad_field;
use crate::rng::{self, uniform};
pub use crate::scene::dataset::ObjectFile;
use crate::scene::dataset::{BenchesSpec, DatasetSpec, FitRule, ObjectSource};
use crate::scene::doc::BenchDoc;
use crate::scene::run::RunScene;
use crate::trace::kernel::{Kernel, ObjectGrid, trace_kernel};
use crate::transport::Transport;

mod check;
mod shards;

/// Stream tags of the objects and of the noise.
const OBJECTS: u64 = 0x0B1E_C750_0000_0001;
const NOISE: u64 = 0x0015_E000_0000_0002;

/// The record seed (noise and drift) of sample `s` of a dataset of seed `seed`.
pub fn noise_seed(seed: u64, s: u64) -> u64 {
    rng::mix64(rng::mix64(seed ^ NOISE) ^ s)
}

/// The manifest's format name.
pub const FORMAT: &str = "spibench-dataset-1";

/// One array of a shard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArraySchema {
    pub name: String,
    pub dtype: String,
    /// Shape of one sample (the file's shape is [samples in shard] + this).
    pub sample_shape: Vec<usize>,
    pub units: String,
    pub description: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileHash {
    pub name: String,
    pub file: String,
    pub sha256: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardEntry {
    pub index: u64,
    pub first_sample: u64,
    pub samples: u64,
    pub dir: String,
    pub files: Vec<FileHash>,
}

/// The `provenance` block of a dataset manifest. Unlike the summaries' block
/// ([`crate::provenance::Provenance`], write-only), a manifest is read back: `--resume` and
/// `--merge` compare these inputs (spec, bench, tolerance file by name and SHA-256, hashed
/// with the one helper [`crate::provenance::sha256_hex`]) before they touch a shard, so it is
/// owned strings that deserialise, and its keys are the manifest format's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestProvenance {
    pub spibench_version: String,
    pub command: Vec<String>,
    pub spec_file: String,
    pub spec_sha256: String,
    pub bench_file: String,
    pub bench_sha256: String,
    /// The tolerance file of a dataset over drawn benches (copied as `tolerances.ron`).
    pub tolerance_file: Option<String>,
    pub tolerance_sha256: Option<String>,
    /// The object images the spec read (a folder's files in name order, or the shipped test
    /// images), each with the SHA-256 of its bytes; empty for drawn objects (USAF, phantom,
    /// rectangles). `--resume` and `--merge` compare them: a folder's images may change while
    /// the spec that names the folder does not. (A manifest written before this field reads
    /// as empty.)
    #[serde(default)]
    pub objects: Vec<ObjectFile>,
    /// For a merged dataset: the folders merged, each with the command that made it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub merged_from: Vec<MergedInput>,
}

/// A folder a merged dataset was made from (a folder that was itself merged lists its own
/// inputs after it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MergedInput {
    /// The folder as the merge's command line named it.
    pub folder: String,
    /// The command that made (or last resumed) it.
    pub command: Vec<String>,
    pub shard_range: (u64, u64),
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KernelInfo {
    pub rays: u64,
    pub seed: u64,
    pub grid_px: (usize, usize),
    pub field_mm: (f64, f64),
    pub entries: usize,
    /// Share of the chart light's detected current carried by paths that met the chart face
    /// more than once (what the kernel neglects).
    pub multi_crossing_current_fraction: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub provenance: ManifestProvenance,
    pub seed: u64,
    pub samples: u64,
    pub shard_samples: u64,
    pub shards_total: u64,
    /// Shards [first, end) this folder is responsible for.
    pub shard_range: (u64, u64),
    pub kernel: KernelInfo,
    pub pattern_family: String,
    /// How the detector outputs were recorded: `frames` or `samples`.
    pub record: String,
    pub measurements_max: usize,
    pub schemes: Vec<String>,
    pub ratios: Vec<f64>,
    pub schema: Vec<ArraySchema>,
    pub patterns_file: Option<String>,
    /// The SHA-256 of `patterns.npy`, when written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patterns_sha256: Option<String>,
    pub shards: Vec<ShardEntry>,
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

/// One bench of a dataset: its detector, electronics and settings, and its object kernel.
pub struct BenchKernel {
    pub scene: RunScene,
    pub kernel: Kernel,
    /// Deviations of the tolerances (file order) then of the compensators, from the nominal
    /// bench.
    pub deviations: Vec<f64>,
}

/// Invalid drawn benches tolerated in a row before a dataset gives up.
const MAX_REDRAWS: u64 = 64;

/// One sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub object: Vec<f64>,
    /// Per (scheme, ratio) in [`Prepared::measurement_names`] order.
    pub measurements: Vec<Vec<f64>>,
    pub k_a_per_w: [f64; 2],
    pub b_a: [f64; 2],
    /// The drawn bench's deviations (empty for the nominal bench).
    pub deviations: Vec<f64>,
    /// The optional arrays of [`Prepared::optional_arrays`], in that order.
    pub optional: Vec<Vec<f64>>,
}

/// The index of the chart `name` (or the only chart) among the bench file's charts, and the
/// bench with that chart made clear glass.
fn clear_chart(
    doc: &BenchDoc,
    name: Option<&str>,
    spec: &DatasetSpec,
) -> Result<(BenchDoc, usize)> {
    use crate::scene::bench::{ChartPatternSpec, ElementSpec};
    let mut doc = doc.clone();
    let mut found = None;
    let mut k = 0;
    let mut n_charts = 0;
    for el in doc.file.elements.iter_mut() {
        if let ElementSpec::Chart {
            name: n,
            pattern,
            center_on,
            ..
        } = el
        {
            n_charts += 1;
            if name.is_none_or(|want| want == n) && found.is_none() {
                // Clear glass, its centre at `position_mm` (where the bench puts the chart
                // point it images): the object grid is centred there.
                *pattern = ChartPatternSpec::Clear;
                *center_on = None;
                found = Some(k);
            }
            k += 1;
        }
    }
    match (found, name) {
        (Some(i), Some(_)) => Ok((doc, i)),
        (Some(i), None) if n_charts == 1 => Ok((doc, i)),
        (_, Some(n)) => Err(spec.error("chart", format!("the bench has no chart named {n:?}"))),
        _ => Err(spec.error(
            "bench",
            format!(
                "the bench needs exactly one chart (it has {n_charts}); name it in kernel.chart"
            ),
        )),
    }
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

/// The object kernel of a dataset's bench `doc`.
fn bench_kernel(doc: &BenchDoc, spec: &DatasetSpec) -> Result<Kernel> {
    let k = &spec.file.kernel;
    let (clear, chart) = clear_chart(doc, k.chart.as_deref(), spec)?;
    let kernel_bench = clear.build()?;
    let grid = ObjectGrid {
        chart,
        width_px: k.grid_px.0,
        height_px: k.grid_px.1,
        width_m: k.field_mm.0 * 1e-3,
        height_m: k.field_mm.1 * 1e-3,
    };
    trace_kernel(
        &kernel_bench,
        grid,
        &crate::trace::TraceOptions::new(k.rays, k.seed),
    )
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
                let set = crate::scene::tolerance::ToleranceSet::parse(
                    &text,
                    path,
                    &doc,
                    &crate::pipeline::evaluate::is_metric,
                )?;
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

    /// The bench index of sample s (0 for every sample of a nominal dataset).
    pub fn bench_index(&self, s: u64) -> u64 {
        self.drawn.as_ref().map_or(0, |d| s / d.samples_per_bench)
    }

    /// Bench t of the benches `d` (this dataset's): tolerance trial t with the dataset's seed,
    /// or the next valid draw when that one is not a valid bench. Its kernel is traced with the
    /// kernel spec's rays and seed.
    pub fn drawn_bench(&self, d: &DrawnBenches, t: u64) -> Result<BenchKernel> {
        let options = crate::pipeline::evaluate::EvaluateOptions {
            rays: self.spec.file.kernel.rays,
            seed: self.spec.file.seed,
            quality: false,
        };
        let mut last = None;
        for j in 0..MAX_REDRAWS {
            // Redraws use trial indices far beyond any bench index.
            let draw = t + (j << 40);
            let made = crate::pipeline::perturb::trial_doc(&d.doc, &d.set, &options, draw)
                .and_then(|(doc, dev, comp)| {
                    Ok(BenchKernel {
                        scene: dataset_scene(
                            checked_scene(&doc, &self.spec)?,
                            &self.spec,
                            &self.schemes,
                        ),
                        kernel: bench_kernel(&doc, &self.spec)?,
                        deviations: dev.iter().chain(&comp).map(|(_, v)| *v).collect(),
                    })
                });
            match made {
                Ok(b) => return Ok(b),
                Err(e) if e.is_user_error() => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(self.spec.error(
            "benches",
            format!(
                "{MAX_REDRAWS} draws in a row for bench {t} made no valid bench; the last: {}",
                last.map(|e| e.to_string()).unwrap_or_default()
            ),
        ))
    }

    /// Names of the deviations of a drawn bench (tolerances, then compensators).
    pub fn deviation_names(&self) -> Vec<String> {
        self.drawn.as_ref().map_or_else(Vec::new, |d| {
            d.set
                .tolerances
                .iter()
                .map(|t| t.path.clone())
                .chain(
                    d.set
                        .compensators
                        .iter()
                        .map(|c| format!("{} (compensator)", c.path)),
                )
                .collect()
        })
    }

    pub fn units(&self) -> usize {
        self.kernel.units()
    }

    /// `meas_SCHEME_rRATIO` per scheme and ratio, in sample order.
    pub fn measurement_names(&self) -> Vec<(String, Scheme, usize)> {
        let mut v = Vec::new();
        for s in &self.schemes {
            for r in &self.ratios {
                let m = patterns_for_ratio(*r, self.units());
                v.push((format!("meas_{}_r{:.4}", s.key(), r), *s, m));
            }
        }
        v
    }

    /// The arrays of a sample, with their schema.
    pub fn schema(&self) -> Vec<ArraySchema> {
        let g = self.spec.file.kernel.grid_px;
        let mut v = vec![
            ArraySchema {
                name: "sample".into(),
                dtype: "<f8".into(),
                sample_shape: vec![],
                units: "1".into(),
                description: "the sample index s".into(),
            },
            ArraySchema {
                name: "object".into(),
                dtype: "<f8".into(),
                sample_shape: vec![g.1, g.0],
                units: "transmittance".into(),
                description: "the ideal object on the kernel grid (rows top to bottom)".into(),
            },
        ];
        for (name, s, m) in self.measurement_names() {
            v.push(ArraySchema {
                name,
                dtype: "<f8".into(),
                sample_shape: vec![m],
                units: "V".into(),
                description: format!(
                    "{} measurements y_i for the first {m} base patterns",
                    s.label()
                ),
            });
        }
        v.push(ArraySchema {
            name: "k".into(),
            dtype: "<f8".into(),
            sample_shape: vec![2],
            units: "A/W".into(),
            description: "k+ and k- of the sample's transport".into(),
        });
        v.push(ArraySchema {
            name: "b".into(),
            dtype: "<f8".into(),
            sample_shape: vec![2],
            units: "A".into(),
            description: "b+ and b- of the sample's transport (traced offsets, ambient, dark)"
                .into(),
        });
        v.extend(self.optional_arrays());
        if self.drawn.is_some() {
            v.push(ArraySchema {
                name: "bench".into(),
                dtype: "<f8".into(),
                sample_shape: vec![],
                units: "1".into(),
                description: "the index t of the drawn bench the sample was measured through"
                    .into(),
            });
            let names = self.deviation_names();
            v.push(ArraySchema {
                name: "deviations".into(),
                dtype: "<f8".into(),
                sample_shape: vec![names.len()],
                units: "the unit of each variable (mm, degrees or 1)".into(),
                description: format!(
                    "the drawn bench's deviations from the nominal bench: {}",
                    names.join(", ")
                ),
            });
        }
        v
    }

    /// The object of sample s.
    pub fn object(&self, s: u64) -> Result<Raster> {
        let (gw, gh) = self.spec.file.kernel.grid_px;
        let mut r = rng::stream(rng::mix64(self.spec.file.seed ^ OBJECTS), s);
        let obj = match &self.spec.objects {
            ObjectSource::Images { images, rule, .. } => {
                let img = &images[(s % images.len() as u64) as usize];
                match rule {
                    FitRule::Resize => crate::objects::image_file::resize_area(img, gw, gh)?,
                    FitRule::RandomCrop => {
                        let c0 = ((uniform(&mut r) * (img.width - gw + 1) as f64) as usize)
                            .min(img.width - gw);
                        let r0 = ((uniform(&mut r) * (img.height - gh + 1) as f64) as usize)
                            .min(img.height - gh);
                        let mut d = Vec::with_capacity(gw * gh);
                        for row in 0..gh {
                            for col in 0..gw {
                                d.push(img.get(r0 + row, c0 + col));
                            }
                        }
                        Raster::new(gw, gh, d)?
                    }
                }
            }
            ObjectSource::Usaf {
                min_field_mm,
                max_field_mm,
            } => {
                let chart = crate::objects::usaf::UsafChart::new(
                    -2,
                    7,
                    crate::objects::usaf::Polarity::Negative,
                )?;
                let f = min_field_mm + uniform(&mut r) * (max_field_mm - min_field_mm);
                let fy = f * gh as f64 / gw as f64;
                let cx = (uniform(&mut r) - 0.5) * f;
                let cy = (uniform(&mut r) - 0.5) * fy;
                let region = crate::objects::usaf::Region::from_corners(
                    cx - 0.5 * f,
                    cy - 0.5 * fy,
                    cx + 0.5 * f,
                    cy + 0.5 * fy,
                );
                chart.render(&region, gw, gh)
            }
            ObjectSource::Phantom => crate::objects::phantom::phantom_sized(gw, gh, false)?,
            ObjectSource::Rectangles { max_count } => {
                let mut d = vec![0.0; gw * gh];
                let n = 1 + ((uniform(&mut r) * *max_count as f64) as usize).min(max_count - 1);
                for _ in 0..n {
                    let (a, b) = (uniform(&mut r) * gw as f64, uniform(&mut r) * gw as f64);
                    let (c, e) = (uniform(&mut r) * gh as f64, uniform(&mut r) * gh as f64);
                    let t = uniform(&mut r);
                    let (x0, x1) = (a.min(b) as usize, (a.max(b) as usize).min(gw - 1));
                    let (y0, y1) = (c.min(e) as usize, (c.max(e) as usize).min(gh - 1));
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            d[y * gw + x] = t;
                        }
                    }
                }
                Raster::new(gw, gh, d)?
            }
        };
        Ok(obj.map(|v| v.clamp(0.0, 1.0)))
    }

    /// Sample s: its object, transport, recorded frames and measurements (for a dataset over
    /// drawn benches its bench is traced first: [`Prepared::sample_on`] reuses one).
    pub fn sample(&self, s: u64) -> Result<Sample> {
        match &self.drawn {
            Some(d) => self.sample_on(s, Some(&self.drawn_bench(d, self.bench_index(s))?)),
            None => self.sample_on(s, None),
        }
    }

    /// Sample s measured through `bench` (which must be bench [`Prepared::bench_index`]`(s)`),
    /// or through the nominal bench.
    pub fn sample_on(&self, s: u64, bench: Option<&BenchKernel>) -> Result<Sample> {
        let (scene, kernel) = match bench {
            Some(b) => (&b.scene, &b.kernel),
            None => (&self.scene, &self.kernel),
        };
        let object = self.object(s)?.data;
        // Values only: a sample's arrays hold no standard errors (Transport::from_kernel_values).
        let transport = Transport::from_kernel_values(&scene.bench, kernel, &object, false)?;
        let seed = noise_seed(self.spec.file.seed, s);
        let rec = evaluate::acquire(scene, &transport, &self.patterns, seed, &|_, _, _| {})?;
        let mut measurements = Vec::new();
        for (_, scheme, m) in self.measurement_names() {
            let r = rec.record(scheme.sequence()).ok_or_else(|| {
                Error::input(format!("no record for the {} sequence", scheme.label()))
            })?;
            measurements.push(scheme.measurements(&r.frames, m));
        }
        let mut optional = Vec::new();
        let w = &self.spec.file.write;
        if w.reconstructions {
            let x = Raster::new(
                transport.units_across,
                transport.units_down,
                transport.x_w.clone(),
            )?;
            let truth = evaluate::truth_view(&x).ok_or_else(|| {
                Error::input(format!(
                    "sample {s}: no light of the object reached the DMD's pattern area"
                ))
            })?;
            let cells = evaluate::solve_scored(
                &scene.settings,
                &rec,
                &self.schemes,
                &self.ratios,
                &truth,
                None,
                &|_, _, _| {},
            )?;
            optional.push(x.data);
            let scores: Vec<Vec<f64>> = cells.iter().map(|c| vec![c.psnr_db, c.mssim]).collect();
            optional.extend(cells.into_iter().map(|c| c.solution.data));
            optional.extend(scores);
        }
        if w.scope_frames > 0 {
            for (q, len) in self.scope_sequences() {
                let r = rec.record(q).ok_or_else(|| {
                    Error::Numerical(format!("no record for the {} sequence", q.key()))
                })?;
                let v = &r.trace.v;
                if v.iter().any(|c| c.len() != len) {
                    return Err(Error::Numerical(format!(
                        "the {} sequence's oscilloscope record holds {} samples, not {len}",
                        q.key(),
                        v[0].len()
                    )));
                }
                optional.push(v.concat());
            }
        }
        Ok(Sample {
            object,
            measurements,
            k_a_per_w: [transport.k[0].value, transport.k[1].value],
            b_a: [transport.b[0].value, transport.b[1].value],
            deviations: bench.map_or_else(Vec::new, |b| b.deviations.clone()),
            optional,
        })
    }

    /// The sequences the schemes read, each with the length of its oscilloscope record of the
    /// first `scope_frames` frames (samples n whose frame ⌊(n + 10⁻⁶)/P⌋ is below that, P the
    /// samples per frame, as [`crate::detector::record`] assigns them).
    pub fn scope_sequences(&self) -> Vec<(crate::acquisition::Sequence, usize)> {
        let st = &self.scene.settings;
        let timing = crate::detector::FrameTiming {
            frame_s: 1.0 / st.dmd_rate_hz,
            settling_s: st.settling_time_s,
            sample_rate_hz: self.scene.scope.sample_rate_hz,
        };
        let m = self.patterns.set().measurements();
        crate::acquisition::Sequence::all()
            .into_iter()
            .filter(|q| self.schemes.iter().any(|k| k.sequence() == *q))
            .map(|q| {
                let frames = q.frames(m);
                let f = self.spec.file.write.scope_frames.min(frames);
                let len = crate::detector::frame_start_sample(timing, frames, f);
                (q, len as usize)
            })
            .collect()
    }

    /// The schema of the optional arrays (`write:` of the spec), in [`Sample::optional`] order.
    pub fn optional_arrays(&self) -> Vec<ArraySchema> {
        let mut v = Vec::new();
        let w = &self.spec.file.write;
        let (across, down) = self.scene.bench.units_shape();
        let cells: Vec<(Scheme, f64)> = self
            .schemes
            .iter()
            .flat_map(|s| self.ratios.iter().map(move |r| (*s, *r)))
            .collect();
        if w.reconstructions {
            v.push(ArraySchema {
                name: "dmd_image".into(),
                dtype: "<f8".into(),
                sample_shape: vec![down, across],
                units: "W".into(),
                description: "the object's light on each DMD unit (x_j, rows top to bottom); \
                              the reconstructions are scored against it scaled to 0–255 by \
                              its maximum"
                    .into(),
            });
            for (sch, r) in &cells {
                v.push(ArraySchema {
                    name: format!("recon_{}_r{r:.4}", sch.key()),
                    dtype: "<f8".into(),
                    sample_shape: vec![down, across],
                    units: "arbitrary (as TVAL3 returns it)".into(),
                    description: format!(
                        "{} reconstruction at {:.1} % sampling",
                        sch.label(),
                        100.0 * r
                    ),
                });
            }
            for (sch, r) in &cells {
                v.push(ArraySchema {
                    name: format!("score_{}_r{r:.4}", sch.key()),
                    dtype: "<f8".into(),
                    sample_shape: vec![2],
                    units: "dB, 1".into(),
                    description: format!(
                        "PSNR and MSSIM of the {} reconstruction at {:.1} % against dmd_image \
                         (after the least-squares gain and offset, as in spibench run)",
                        sch.label(),
                        100.0 * r
                    ),
                });
            }
        }
        if w.scope_frames > 0 {
            for (q, len) in self.scope_sequences() {
                v.push(ArraySchema {
                    name: format!("scope_{}", q.key()),
                    dtype: "<f8".into(),
                    sample_shape: vec![3, len],
                    units: "V".into(),
                    description: format!(
                        "the oscilloscope's record [RF, MONITOR+, MONITOR−] of the first {} \
                         frames of the {} sequence, sample n at n/{} s",
                        w.scope_frames,
                        q.key(),
                        self.scene.scope.sample_rate_hz
                    ),
                });
            }
        }
        v
    }

    pub fn shards_total(&self) -> u64 {
        self.spec
            .file
            .samples
            .div_ceil(self.spec.file.shard_samples)
    }

    /// The samples of shard b, computed in parallel (the drawn benches they see traced first,
    /// each once, in index order; a kernel trace is itself parallel).
    pub fn shard_samples(&self, b: u64) -> Result<Vec<Sample>> {
        self.shard_samples_timed(b).map(|(v, _)| v)
    }

    /// [`Prepared::shard_samples`], with the seconds by which the parallel loop outlasted its
    /// last sample. A thread of the pool that waits for its part of the loop runs any pending
    /// work of the pool meanwhile, a shard's file writing included, and the loop ends only
    /// when that thread is back: this measures what such work holds the loop up (the tail
    /// between its end and the end of its last sample).
    pub fn shard_samples_timed(&self, b: u64) -> Result<(Vec<Sample>, f64)> {
        let f = &self.spec.file;
        let first = b * f.shard_samples;
        let end = (first + f.shard_samples).min(f.samples);
        let t0 = self.bench_index(first);
        let benches: Vec<BenchKernel> = match &self.drawn {
            Some(d) => (t0..=self.bench_index(end - 1))
                .map(|t| self.drawn_bench(d, t))
                .collect::<Result<_>>()?,
            None => Vec::new(),
        };
        let start = std::time::Instant::now();
        // The latest end of a sample, in nanoseconds since `start` (one atomic store a sample).
        let last_end = std::sync::atomic::AtomicU64::new(0);
        let samples: Vec<Result<Sample>> = (first..end)
            .into_par_iter()
            .map(|s| {
                let bench = benches.get((self.bench_index(s) - t0) as usize);
                let v = self.sample_on(s, bench);
                let ns = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
                last_end.fetch_max(ns, std::sync::atomic::Ordering::Relaxed);
                v
            })
            .collect();
        let samples = crate::error::in_order(samples)?;
        let last = std::time::Duration::from_nanos(last_end.into_inner());
        Ok((samples, start.elapsed().saturating_sub(last).as_secs_f64()))
    }

    /// The values of array `name` of the shard whose first sample is `first`, made of its
    /// `samples` ([`Prepared::shard_samples`]), row by row in C order, given to `put`.
    fn array_rows(
        &self,
        name: &str,
        first: u64,
        samples: &[Sample],
        put: &mut dyn FnMut(&[f64]) -> Result<()>,
    ) -> Result<()> {
        let rows = |put: &mut dyn FnMut(&[f64]) -> Result<()>, row: &dyn Fn(&Sample) -> &[f64]| {
            samples.iter().try_for_each(|s| put(row(s)))
        };
        let index = |put: &mut dyn FnMut(&[f64]) -> Result<()>, f: &dyn Fn(u64) -> u64| {
            (first..first + samples.len() as u64).try_for_each(|s| put(&[f(s) as f64]))
        };
        match name {
            "sample" => index(put, &|s| s),
            "object" => rows(put, &|s| &s.object),
            "k" => rows(put, &|s| &s.k_a_per_w),
            "b" => rows(put, &|s| &s.b_a),
            "bench" => index(put, &|s| self.bench_index(s)),
            "deviations" => rows(put, &|s| &s.deviations),
            name => {
                if let Some(i) = self.measurement_names().iter().position(|m| m.0 == name) {
                    rows(put, &|s| &s.measurements[i])
                } else {
                    let i = self
                        .optional_arrays()
                        .iter()
                        .position(|a| a.name == name)
                        .expect("schema names");
                    rows(put, &|s| &s.optional[i])
                }
            }
        }
    }

    /// Writes array `a` of shard b, made of its `samples`, to `path`; returns the file's
    /// SHA-256. The values go from the samples through a cache-sized chunk into the file and
    /// the hash ([`F64FileWriter`]): the whole array never exists as bytes in memory.
    fn write_array(
        &self,
        path: &Path,
        a: &ArraySchema,
        b: u64,
        samples: &[Sample],
    ) -> Result<String> {
        let mut shape = vec![samples.len()];
        shape.extend(&a.sample_shape);
        let mut w = F64FileWriter::create(path, &shape)?;
        let first = b * self.spec.file.shard_samples;
        self.array_rows(&a.name, first, samples, &mut |v| w.extend(v))?;
        w.finish()
    }

    /// `patterns.npy`: the base patterns, each row packed 8 units to a byte (most
    /// significant bit first, as `numpy.packbits`).
    fn packed_patterns(&self) -> Vec<u8> {
        let bits = self.patterns.set().base_patterns();
        let (rows, cols) = (bits.rows(), bits.cols());
        let mut packed = Vec::with_capacity(rows * cols.div_ceil(8));
        for i in 0..rows {
            let mut byte = 0u8;
            for j in 0..cols {
                if bits.get(i, j) {
                    byte |= 0x80 >> (j % 8);
                }
                if j % 8 == 7 || j + 1 == cols {
                    packed.push(byte);
                    byte = 0;
                }
            }
        }
        crate::report::npy::encode_u8(&[rows, cols.div_ceil(8)], &packed)
    }

    fn manifest(&self, command: &[String], range: (u64, u64)) -> Manifest {
        let k = &self.spec.file.kernel;
        Manifest {
            format: FORMAT.into(),
            provenance: ManifestProvenance {
                spibench_version: env!("CARGO_PKG_VERSION").into(),
                command: command.to_vec(),
                spec_file: "spec.ron".into(),
                spec_sha256: sha256_hex(self.spec.text.as_bytes()),
                bench_file: "bench.ron".into(),
                bench_sha256: sha256_hex(self.bench_text.as_bytes()),
                tolerance_file: self.drawn.as_ref().map(|_| "tolerances.ron".into()),
                tolerance_sha256: self.drawn.as_ref().map(|d| sha256_hex(d.text.as_bytes())),
                objects: self.spec.object_files.clone(),
                merged_from: Vec::new(),
            },
            seed: self.spec.file.seed,
            samples: self.spec.file.samples,
            shard_samples: self.spec.file.shard_samples,
            shards_total: self.shards_total(),
            shard_range: range,
            kernel: KernelInfo {
                rays: k.rays,
                seed: k.seed,
                grid_px: k.grid_px,
                field_mm: k.field_mm,
                entries: self.kernel.entries.len(),
                multi_crossing_current_fraction: self.kernel.multi_crossing_current_fraction(),
            },
            pattern_family: self.scene.settings.patterns.label(),
            record: match self.scene.settings.record {
                crate::detector::RecordModel::Frames => "frames".into(),
                crate::detector::RecordModel::Samples => "samples".into(),
            },
            measurements_max: self.patterns.set().measurements(),
            schemes: self.schemes.iter().map(|s| s.key().to_string()).collect(),
            ratios: self.ratios.clone(),
            schema: self.schema(),
            patterns_file: self.spec.file.write.patterns.then(|| "patterns.npy".into()),
            patterns_sha256: self
                .spec
                .file
                .write
                .patterns
                .then(|| sha256_hex(&self.packed_patterns())),
            shards: Vec::new(),
        }
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

fn shard_dir_name(b: u64) -> String {
    format!("shard_{b:06}")
}

fn write_manifest(dir: &Path, m: &Manifest) -> Result<()> {
    crate::report::npy::write_atomic(&dir.join("manifest.json"), manifest_text(m)?.as_bytes())
}

fn manifest_text(m: &Manifest) -> Result<String> {
    serde_json::to_string_pretty(m)
        .map_err(|e| Error::input(format!("cannot write the manifest: {e}")))
}

/// Writes `name` in the dataset folder `lock` holds, atomically, its temporary copy staged so
/// that SIGINT or SIGTERM removes it.
fn write_locked(lock: &FolderLock, name: &str, bytes: &[u8]) -> Result<()> {
    let path = lock.dir().join(name);
    let tmp = crate::report::npy::atomic_temp(&path);
    let written = crate::report::npy::write_atomic_with(&path, bytes, |t| {
        lock.stage_created(t, |p| std::fs::File::create(p))
    });
    lock.unstage(&tmp);
    written
}

/// The files a dataset folder gets before its first manifest, in the order they are written.
const SETUP_FILES: [&str; 5] = [
    "spec.ron",
    "bench.ron",
    "tolerances.ron",
    "patterns.npy",
    "manifest.json",
];

/// True when the folder `dir` holds nothing but a fresh run's setup files (complete or
/// temporary) and lock files: a run stopped before its first manifest, which a resume starts
/// afresh.
fn only_setup_files(dir: &Path) -> bool {
    let setup = |n: &str| {
        SETUP_FILES
            .iter()
            .any(|f| n == *f || n == format!("{f}.partial"))
    };
    dir.read_dir().is_ok_and(|d| {
        d.flatten().all(|e| {
            let n = e.file_name().to_string_lossy().to_string();
            n.starts_with(".spibench-") || (setup(&n) && e.file_type().is_ok_and(|t| t.is_file()))
        })
    })
}

/// Reads a dataset folder's manifest. It is untrusted (another tool or person may have edited
/// it): every name in it is checked, and every path it names must stay inside `dir`, before
/// any file but the manifest is opened (`check`).
pub fn read_manifest(dir: &Path) -> Result<Manifest> {
    let folder = crate::report::untrusted::Folder::new(dir)?;
    let p = dir.join("manifest.json");
    let (_, bytes) = folder.read(Path::new("manifest.json"), &p, "manifest.json")?;
    let m: Manifest = serde_json::from_slice(&bytes)
        .map_err(|e| Error::input(format!("not a spibench dataset manifest: {e}")).in_file(&p))?;
    check::check_manifest(&m, &p)?;
    check::check_paths(&folder, &m, &p)?;
    Ok(m)
}

/// Reads the file `rel` of dataset folder `dir` (whose manifest [`read_manifest`] checked) and
/// checks it against its SHA-256 `sha256`; `what` names it in the message.
fn verified(dir: &Path, rel: &Path, sha256: &str, what: &str) -> Result<Vec<u8>> {
    let p = dir.join(rel);
    let bytes = std::fs::read(&p).map_err(|e| Error::read(&p, e))?;
    if sha256_hex(&bytes) != sha256 {
        return Err(Error::input(format!(
            "{what} is corrupted or was edited: the SHA-256 of {} differs from the manifest's; \
             delete the folder and make the dataset (or this shard's job) again",
            rel.display()
        ))
        .in_file(&p));
    }
    Ok(bytes)
}

/// Checks every file of a committed shard (of a manifest read by [`read_manifest`]) against
/// its checksum.
pub fn verify_shard(dir: &Path, shard: &ShardEntry) -> Result<()> {
    for f in &shard.files {
        let rel = Path::new(&shard.dir).join(&f.file);
        verified(dir, &rel, &f.sha256, &format!("shard {}", shard.index))?;
    }
    Ok(())
}

/// Removes what an interrupted run left in a dataset folder: staging folders
/// (`.shard_NNNNNN.partial`) and shard folders committed after the manifest's last update. Only
/// entries with exactly these names go; a symbolic link among them is removed itself, never
/// followed.
fn remove_leftovers(dir: &Path, manifest: &Manifest) -> Result<()> {
    let is_shard = |n: &str| {
        n.strip_prefix("shard_")
            .is_some_and(|d| d.len() >= 6 && d.bytes().all(|b| b.is_ascii_digit()))
    };
    for e in std::fs::read_dir(dir)
        .map_err(|e| Error::read(dir, e))?
        .flatten()
    {
        let name = e.file_name().to_string_lossy().to_string();
        let staging = name
            .strip_prefix('.')
            .and_then(|n| n.strip_suffix(".partial"))
            .is_some_and(is_shard);
        let unlisted = is_shard(&name) && !manifest.shards.iter().any(|s| s.dir == name);
        // `write_atomic`'s temporary copies of the folder's own files.
        let temporary = SETUP_FILES.iter().any(|f| name == format!("{f}.partial"));
        if !(staging || unlisted || temporary) {
            continue;
        }
        let path = e.path();
        let removed = match e.file_type() {
            Ok(t) if t.is_dir() => std::fs::remove_dir_all(&path),
            Ok(_) => std::fs::remove_file(&path),
            Err(err) => Err(err),
        };
        removed.map_err(|err| Error::write(&path, err))?;
    }
    Ok(())
}

/// What `generate` did.
#[derive(Debug, Clone)]
pub struct Generated {
    pub shards_written: u64,
    pub samples_written: u64,
    pub shards_resumed: u64,
    pub seconds: f64,
    /// The seconds spent computing samples (the parallel sample loops); the rest of `seconds`
    /// is spent outside them (setup, and the wait for the last shard's writing).
    pub sample_seconds: f64,
    /// Where the shards' writing went (it runs beside the next shard's samples).
    pub commits: CommitSeconds,
}

/// The seconds of the shards' commits, summed over the shards: making the arrays' files
/// (encoded, hashed and written as they go, side by side), rewriting the manifest (with its
/// fsync), and how long the job waited for shards' writing: between two shards' sample loops
/// while as many shards as may be written at once (three) were still being written, and after
/// the last loop, for the writes that nothing overlaps.
#[derive(Debug, Clone, Copy, Default)]
pub struct CommitSeconds {
    pub arrays: f64,
    pub manifest: f64,
    pub waited: f64,
    /// How long the sample loops outlasted their last samples, summed: a thread of the loop
    /// held by other work of the pool (a write) when the loop's samples were done
    /// ([`Prepared::shard_samples_timed`]).
    pub held: f64,
}

/// Makes (or, with `resume`, continues) the shards `range` of a dataset in the folder `lock`
/// holds (the lock every command takes on its output folder, so that no other run writes it
/// meanwhile).
pub fn generate(
    prep: &Prepared,
    lock: &FolderLock,
    range: (u64, u64),
    resume: bool,
    command: &[String],
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Generated> {
    let start = std::time::Instant::now();
    let dir = lock.dir();
    let mut manifest;
    let exists = dir.join("manifest.json").exists();
    if resume && exists {
        manifest = read_manifest(dir)?;
        let fresh = prep.manifest(command, range);
        if manifest.provenance.spec_sha256 != fresh.provenance.spec_sha256
            || manifest.provenance.bench_sha256 != fresh.provenance.bench_sha256
            || manifest.provenance.tolerance_sha256 != fresh.provenance.tolerance_sha256
            || manifest.shard_range != range
        {
            return Err(Error::input(
                "the folder holds another dataset (its spec, bench or shard range differ): \
                 resume it with the same spec and --shard",
            )
            .in_file(dir));
        }
        if let Some((i, why)) =
            objects_differ(&fresh.provenance.objects, &manifest.provenance.objects)
        {
            return Err(bad_field(
                &dir.join("manifest.json"),
                &format!("provenance.objects[{i}]"),
                format!(
                    "the folder's dataset was made from other object images than the spec reads \
                     now: {why}; resume with the images it was made from, or make the dataset \
                     again in a new folder"
                ),
            ));
        }
        for s in &manifest.shards {
            verify_shard(dir, s)?;
        }
        remove_leftovers(dir, &manifest)?;
        manifest.provenance.command = command.to_vec();
    } else {
        // The lock file of a folder locked in place (a mount point) is not content.
        let content = |d: std::fs::ReadDir| {
            d.flatten()
                .any(|e| !e.file_name().to_string_lossy().starts_with(".spibench-"))
        };
        let restart = resume && !exists && only_setup_files(dir);
        if restart {
            // Stopped before its first manifest: nothing of it to keep.
            for f in SETUP_FILES
                .iter()
                .flat_map(|f| [f.to_string(), format!("{f}.partial")])
            {
                match std::fs::remove_file(dir.join(&f)) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                        return Err(Error::write(&dir.join(&f), e));
                    }
                    _ => {}
                }
            }
        } else if exists || dir.read_dir().is_ok_and(content) {
            return Err(Error::input(
                "the output folder exists and is not empty: choose another, or continue it \
                 with --resume",
            )
            .in_file(dir));
        }
        std::fs::create_dir_all(dir).map_err(|e| Error::write(dir, e))?;
        manifest = prep.manifest(command, range);
        write_locked(lock, "spec.ron", prep.spec.text.as_bytes())?;
        write_locked(lock, "bench.ron", prep.bench_text.as_bytes())?;
        if let Some(d) = &prep.drawn {
            write_locked(lock, "tolerances.ron", d.text.as_bytes())?;
        }
        if prep.spec.file.write.patterns {
            write_locked(lock, "patterns.npy", &prep.packed_patterns())?;
        }
        write_locked(lock, "manifest.json", manifest_text(&manifest)?.as_bytes())?;
    }
    let done: Vec<u64> = manifest.shards.iter().map(|s| s.index).collect();
    let todo: Vec<u64> = (range.0..range.1).filter(|b| !done.contains(b)).collect();
    let (written, sample_seconds, commits) =
        shards::make_shards(prep, lock, &mut manifest, &todo, &|b| {
            progress(b + 1 - range.0, range.1 - range.0)
        })?;
    let samples_written = manifest
        .shards
        .iter()
        .filter(|s| todo.contains(&s.index))
        .map(|s| s.samples)
        .sum();
    Ok(Generated {
        shards_written: written,
        samples_written,
        shards_resumed: done.len() as u64,
        seconds: start.elapsed().as_secs_f64(),
        sample_seconds,
        commits,
    })
}

/// Merges dataset folders (each one job's shards) into `out`: the same spec, bench and seed in
/// every folder, no shard twice and none missing. Every manifest is checked before any other
/// file is opened ([`read_manifest`]); every file copied (each shard's arrays, the copies of
/// the inputs) is checked against the SHA-256 of the manifest it came from, in the bytes that
/// are written; the merged manifest names only what the output holds and keeps each input's
/// command (`provenance.merged_from`). A merge of one folder is a complete copy of it.
pub fn merge(inputs: &[PathBuf], out: &Path, command: &[String]) -> Result<Manifest> {
    if inputs.is_empty() {
        return Err(Error::field("--merge", "name the folders to merge"));
    }
    crate::report::output::refuse_overlap(out, inputs, "--out")?;
    let manifests: Vec<Manifest> = inputs
        .iter()
        .map(|d| read_manifest(d))
        .collect::<Result<_>>()?;
    let m0 = &manifests[0];
    for (d, m) in inputs.iter().zip(&manifests) {
        let same = m.provenance.spec_sha256 == m0.provenance.spec_sha256
            && m.provenance.bench_sha256 == m0.provenance.bench_sha256
            && m.provenance.tolerance_sha256 == m0.provenance.tolerance_sha256
            && m.seed == m0.seed
            && m.samples == m0.samples
            && m.shard_samples == m0.shard_samples
            && m.format == m0.format
            && m.schema == m0.schema
            && m.patterns_sha256 == m0.patterns_sha256;
        if !same {
            return Err(Error::input(format!(
                "cannot merge: {} was made from another spec, bench or seed than {}",
                d.display(),
                inputs[0].display()
            ))
            .in_file(d));
        }
    }
    for (d, m) in inputs.iter().zip(&manifests).skip(1) {
        if let Some((i, why)) = objects_differ(&m0.provenance.objects, &m.provenance.objects) {
            return Err(bad_field(
                &d.join("manifest.json"),
                &format!("provenance.objects[{i}]"),
                format!(
                    "cannot merge: {} was made from other object images than {}: {why}",
                    d.display(),
                    inputs[0].display()
                ),
            ));
        }
    }
    let owner = shard_owners(inputs, &manifests)?;
    let staging = crate::report::output::OutputDir::create(out)?;
    let sdir = staging.staging_dir().to_path_buf();
    let mut merged = m0.clone();
    merged.shards.clear();
    merged.shard_range = (0, m0.shards_total);
    merged.provenance.command = command.to_vec();
    merged.provenance.merged_from = inputs
        .iter()
        .zip(&manifests)
        .flat_map(|(d, m)| {
            std::iter::once(MergedInput {
                folder: d.display().to_string(),
                command: m.provenance.command.clone(),
                shard_range: m.shard_range,
            })
            .chain(m.provenance.merged_from.iter().cloned())
        })
        .collect();
    copy_inputs(inputs, &manifests, &sdir)?;
    for (&i, &k) in &owner {
        let s = manifests[k]
            .shards
            .iter()
            .find(|s| s.index == i)
            .ok_or_else(|| Error::Numerical(format!("shard {i} lost its entry")))?;
        let dst = sdir.join(&s.dir);
        std::fs::create_dir_all(&dst).map_err(|e| Error::write(&dst, e))?;
        for f in &s.files {
            let rel = Path::new(&s.dir).join(&f.file);
            let bytes = verified(&inputs[k], &rel, &f.sha256, &format!("shard {i}"))?;
            let p = dst.join(&f.file);
            std::fs::write(&p, bytes).map_err(|e| Error::write(&p, e))?;
        }
        merged.shards.push(s.clone());
    }
    write_manifest(&sdir, &merged)?;
    staging.commit()?;
    Ok(merged)
}

/// The first difference between the object images `want` and those `got` lists, as its index
/// in `got` (or where `got` ends) and a sentence naming the object; `None` when they agree.
fn objects_differ(want: &[ObjectFile], got: &[ObjectFile]) -> Option<(usize, String)> {
    let short = |h: &str| h.get(..16).unwrap_or(h).to_string();
    (0..want.len().max(got.len())).find_map(|i| match (want.get(i), got.get(i)) {
        (Some(a), Some(b)) if a == b => None,
        (Some(a), Some(b)) if a.name == b.name => Some((
            i,
            format!(
                "object {i}, {:?}, has SHA-256 {}… there, not {}…",
                b.name,
                short(&b.sha256),
                short(&a.sha256)
            ),
        )),
        (Some(a), Some(b)) => Some((
            i,
            format!("object {i} is {:?} there, not {:?}", b.name, a.name),
        )),
        (Some(a), None) => Some((
            i,
            format!(
                "it lists {} object(s), without {:?} (object {i})",
                got.len(),
                a.name
            ),
        )),
        (None, Some(b)) => Some((
            i,
            format!(
                "it lists {} object(s), {:?} (object {i}) besides the {} expected",
                got.len(),
                b.name,
                want.len()
            ),
        )),
        (None, None) => None,
    })
}

/// Which input holds each shard of the dataset (shard index → input), refusing a shard held
/// twice and a shard held by none.
fn shard_owners(
    inputs: &[PathBuf],
    manifests: &[Manifest],
) -> Result<std::collections::BTreeMap<u64, usize>> {
    let m0 = &manifests[0];
    let mut owner: std::collections::BTreeMap<u64, usize> = std::collections::BTreeMap::new();
    for (k, (d, m)) in inputs.iter().zip(manifests).enumerate() {
        for s in &m.shards {
            if let Some(&o) = owner.get(&s.index) {
                return Err(Error::input(format!(
                    "cannot merge: shard {} (samples {}–{}) is in both {} and {}",
                    s.index,
                    s.first_sample,
                    s.first_sample + s.samples - 1,
                    inputs[o].display(),
                    d.display()
                )));
            }
            owner.insert(s.index, k);
        }
    }
    let listed = owner.len() as u64;
    if listed < m0.shards_total {
        // Every index below the count is either listed or the first missing one.
        let first = (0..=listed).find(|i| !owner.contains_key(i)).unwrap_or(0);
        return Err(Error::input(format!(
            "cannot merge: {} shard(s) missing, first shard {first} (samples from {}); the \
             folders give no sample there (an unfinished job? resume it with --resume)",
            m0.shards_total - listed,
            first * m0.shard_samples
        )));
    }
    Ok(owner)
}

/// Checks every input's copies of the spec, bench, tolerance file and patterns against its
/// manifest, and writes the first input's into `sdir`.
fn copy_inputs(inputs: &[PathBuf], manifests: &[Manifest], sdir: &Path) -> Result<()> {
    for (k, (d, m)) in inputs.iter().zip(manifests).enumerate() {
        let p = &m.provenance;
        let files = [
            (Some(&p.spec_file), Some(&p.spec_sha256)),
            (Some(&p.bench_file), Some(&p.bench_sha256)),
            (p.tolerance_file.as_ref(), p.tolerance_sha256.as_ref()),
            (m.patterns_file.as_ref(), m.patterns_sha256.as_ref()),
        ];
        for (name, sum) in files {
            if let (Some(name), Some(sum)) = (name, sum) {
                let bytes = verified(d, Path::new(name), sum, name)?;
                if k == 0 {
                    crate::report::npy::write_atomic(&sdir.join(name), &bytes)?;
                }
            }
        }
    }
    Ok(())
}
