//! A dataset folder's manifest: its types (the `manifest.json` format), the schema of a
//! sample's arrays, the manifest a run starts with, and the manifest read back (checked by
//! `check` before any file it names is opened) with the files it lists verified against their
//! SHA-256.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::contract::{
    self, BENCH_COPY, CellArray, FORMAT, MANIFEST, PATTERNS, SPEC_COPY, SampleArray,
    TOLERANCE_COPY, scope_array,
};
use super::{ObjectFile, Prepared, sha256_hex};
use crate::acquisition::{Scheme, patterns_for_ratio};
use crate::error::{Error, Result};

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
    /// The model the bench's DMD was traced with: `geometric` or `diffractive`
    /// (docs/dmd_diffraction.md). Empty in a manifest written before this field.
    #[serde(default)]
    pub dmd_model: String,
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

impl Prepared {
    /// `meas_SCHEME_rRATIO` per scheme and ratio, in sample order.
    pub fn measurement_names(&self) -> Vec<(String, Scheme, usize)> {
        let mut v = Vec::new();
        for s in &self.schemes {
            for r in &self.ratios {
                let m = patterns_for_ratio(*r, self.units());
                v.push((CellArray::Measurements.name(s.key(), *r), *s, m));
            }
        }
        v
    }

    /// The arrays of a sample, with their schema.
    pub fn schema(&self) -> Vec<ArraySchema> {
        let g = self.spec.file.kernel.grid_px;
        let mut v = vec![
            ArraySchema {
                name: SampleArray::Sample.name().into(),
                dtype: "<f8".into(),
                sample_shape: vec![],
                units: "1".into(),
                description: "the sample index s".into(),
            },
            ArraySchema {
                name: SampleArray::Object.name().into(),
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
            name: SampleArray::K.name().into(),
            dtype: "<f8".into(),
            sample_shape: vec![2],
            units: "A/W".into(),
            description: "k+ and k- of the sample's transport".into(),
        });
        v.push(ArraySchema {
            name: SampleArray::B.name().into(),
            dtype: "<f8".into(),
            sample_shape: vec![2],
            units: "A".into(),
            description: "b+ and b- of the sample's transport (traced offsets, ambient, dark)"
                .into(),
        });
        v.extend(self.optional_arrays());
        if self.drawn.is_some() {
            v.push(ArraySchema {
                name: SampleArray::Bench.name().into(),
                dtype: "<f8".into(),
                sample_shape: vec![],
                units: "1".into(),
                description: "the index t of the drawn bench the sample was measured through"
                    .into(),
            });
            let names = self.deviation_names();
            v.push(ArraySchema {
                name: SampleArray::Deviations.name().into(),
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

    /// The schema of the optional arrays (`write:` of the spec), in [`Sample::optional`](super::Sample::optional) order.
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
                name: SampleArray::DmdImage.name().into(),
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
                    name: CellArray::Reconstruction.name(sch.key(), *r),
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
                    name: CellArray::Score.name(sch.key(), *r),
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
                    name: scope_array(q),
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

    pub(super) fn manifest(&self, command: &[String], range: (u64, u64)) -> Manifest {
        let k = &self.spec.file.kernel;
        Manifest {
            format: FORMAT.into(),
            provenance: ManifestProvenance {
                spibench_version: env!("CARGO_PKG_VERSION").into(),
                command: command.to_vec(),
                spec_file: SPEC_COPY.into(),
                spec_sha256: sha256_hex(self.spec.text.as_bytes()),
                bench_file: BENCH_COPY.into(),
                bench_sha256: sha256_hex(self.bench_text.as_bytes()),
                tolerance_file: self.drawn.as_ref().map(|_| TOLERANCE_COPY.into()),
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
            // From the bench as built, which every kernel's bench shares.
            dmd_model: match self.scene.bench.dmd() {
                Some(s) if s.dmd.diffraction().is_some() => "diffractive".into(),
                _ => "geometric".into(),
            },
            measurements_max: self.patterns.set().measurements(),
            schemes: self.schemes.iter().map(|s| s.key().to_string()).collect(),
            ratios: self.ratios.clone(),
            schema: self.schema(),
            patterns_file: self.spec.file.write.patterns.then(|| PATTERNS.into()),
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

pub(super) fn write_manifest(dir: &Path, m: &Manifest) -> Result<()> {
    crate::report::npy::write_atomic(&dir.join(MANIFEST), manifest_text(m)?.as_bytes())
}

pub fn manifest_text(m: &Manifest) -> Result<String> {
    serde_json::to_string_pretty(m)
        .map_err(|e| Error::input(format!("cannot write the manifest: {e}")))
}

/// Reads a dataset folder's manifest. It is untrusted (another tool or person may have edited
/// it): every name in it is checked, and every path it names must stay inside `dir`, before
/// any file but the manifest is opened ([`contract::check_manifest`]).
pub fn read_manifest(dir: &Path) -> Result<Manifest> {
    let folder = crate::report::untrusted::Folder::new(dir)?;
    let p = dir.join(MANIFEST);
    let (_, bytes) = folder.read(Path::new(MANIFEST), &p, MANIFEST)?;
    let m: Manifest = serde_json::from_slice(&bytes)
        .map_err(|e| Error::input(format!("not a spibench dataset manifest: {e}")).in_file(&p))?;
    contract::check_manifest(&m, &p)?;
    contract::check_paths(&folder, &m, &p)?;
    Ok(m)
}

/// Reads the file `rel` of dataset folder `dir` (whose manifest [`read_manifest`] checked) and
/// checks it against its SHA-256 `sha256`; `what` names it in the message.
pub(super) fn verified(dir: &Path, rel: &Path, sha256: &str, what: &str) -> Result<Vec<u8>> {
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

/// The first difference between the object images `want` and those `got` lists, as its index
/// in `got` (or where `got` ends) and a sentence naming the object; `None` when they agree.
pub(super) fn objects_differ(want: &[ObjectFile], got: &[ObjectFile]) -> Option<(usize, String)> {
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
