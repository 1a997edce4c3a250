//! Dataset specs (`spibench dataset SPEC`): RON, parsed and validated here, with located errors.
//!
//! ```ron
//! Dataset(
//!     bench: "paper_bench.ron",          // relative to the spec; its electronics: and run:
//!                                        // sections give the detector, noise and patterns
//!     kernel: (rays: 300000, seed: 1, grid_px: (96, 96), field_mm: (7.88, 7.88)),
//!     objects: TestImages(names: ["astronaut", "coffee"], rule: RandomCrop),
//!     // Optional in acquisition: the pattern family and ordering (default: the bench's run:
//!     // section).
//!     acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm], ratios: [0.25],
//!                   patterns: Hadamard(ordering: CakeCutting)),
//!     seed: 7,
//!     samples: 64,
//!     shard_samples: 16,
//!     // Optional: benches drawn from a tolerance file, a new one every 16 samples (default
//!     // Nominal); what else to write; how the outputs are recorded (default Frames).
//!     benches: Tolerance(file: "tolerances/paper_bench.ron", samples_per_bench: 16),
//!     write: (patterns: false, scope_frames: 0, reconstructions: false),
//!     record: Frames,
//!     // Optional: the detector and oscilloscope in place of the bench's electronics: section.
//!     electronics: (detector: (load: FiftyOhm)),
//!     // Optional: the DMD's model in place of the bench's (Geometric or Diffractive).
//!     dmd_model: Geometric,
//! )
//! ```

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::acquisition::Scheme;
use crate::error::{Error, Result};
use crate::provenance::sha256_hex;
use crate::raster::Raster;
use crate::scene::locate;
use crate::scene::numbers::{Count, Positive, Ratio, checked, via};

/// The largest object grid side (pixels).
pub const MAX_GRID_SIDE: usize = 1024;
/// The largest kernel trace (rays).
pub const MAX_KERNEL_RAYS: u64 = 10_000_000_000;
/// The smallest kernel trace (rays): two batches of the trace (`trace::RAYS_PER_BATCH` = 1024
/// rays each), so that every kernel entry has a standard error. With one batch the standard
/// errors are 0/0: a kernel of 1 ray wrote NaN into its manifest.
pub const MIN_KERNEL_RAYS: u64 = 2048;

/// The kernel trace's rays, as read.
pub type KernelRays = Count<MIN_KERNEL_RAYS, MAX_KERNEL_RAYS>;
/// A sample count (of a dataset, a shard or a bench), as read: at most 10⁹.
pub type SampleCount = Count<1, 1_000_000_000>;
/// An object grid side (pixels), as read.
pub type GridSide = Count<1, { MAX_GRID_SIDE as u64 }>;

checked!(
    /// The chart field (mm) a kernel grid covers, one side: in (0, 1000] mm.
    FieldMm,
    above 0.0,
    at_most 1000.0,
    |v| format!("the field needs a positive size of at most 1000 mm, got {v:e}")
);

checked!(
    /// A USAF field width (mm) of random USAF objects: in (0, 100] mm.
    UsafFieldMm,
    above 0.0,
    at_most 100.0,
    |v| format!("a USAF field must lie in (0, 100] mm, got {v:e}")
);

/// A dataset spec as written.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, rename = "Dataset")]
pub struct DatasetFile {
    /// The bench file, relative to the spec. Its `electronics:` section is the detector and
    /// oscilloscope, its `run:` section the pattern family, DMD rate, drift and noise.
    pub bench: String,
    /// Which benches the samples see.
    #[serde(default)]
    pub benches: BenchesSpec,
    /// The object-kernel trace: rays, seed, object grid and the chart field it covers.
    pub kernel: KernelSpec,
    /// Where the objects come from.
    pub objects: ObjectsSpec,
    /// Schemes and sampling ratios (default: the bench's `run:` section).
    #[serde(default)]
    pub acquisition: Option<AcquisitionSpec>,
    /// Seed of the objects and the noise: sample s depends on (seed, s) alone.
    pub seed: u64,
    /// Samples in the dataset (one object each, measured by every scheme and ratio).
    #[serde(deserialize_with = "via::<SampleCount, _, _>")]
    pub samples: u64,
    /// Samples per shard (a shard's arrays are `.npy` files of this many rows).
    #[serde(deserialize_with = "via::<SampleCount, _, _>")]
    pub shard_samples: u64,
    /// What is written besides the measurements, objects, k± and b±.
    #[serde(default)]
    pub write: WriteSpec,
    /// The most the dataset may occupy on disk (GB, default 100): a larger request is an input
    /// error before anything is written.
    #[serde(default, deserialize_with = "via::<Option<Positive>, _, _>")]
    pub max_disk_gb: Option<f64>,
    /// How the detector outputs are recorded (default `Frames`).
    #[serde(default)]
    pub record: RecordSpec,
    /// The detector and oscilloscope, in the form of a bench's `electronics:` section, in place
    /// of the bench's (default: the bench's own).
    #[serde(default)]
    pub electronics: Option<crate::scene::run::ElectronicsSpec>,
    /// The DMD's model, in place of the bench file's `dmd.model`: `Geometric` (plane mirrors)
    /// or `Diffractive` (the array as a blazed grating; docs/dmd_diffraction.md); default: the
    /// bench's own. The manifest's `dmd_model` names the model the kernels were traced with.
    #[serde(default)]
    pub dmd_model: Option<crate::scene::doc::DmdModel>,
}

/// How the detector outputs of each sample are recorded.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
pub enum RecordSpec {
    /// Each frame's settled-window mean drawn from its exact distribution
    /// (`detector::record_frames`): the same electronics, noise, drift and clipping as `run`,
    /// without simulating every oscilloscope sample. The default.
    #[default]
    Frames,
    /// Sample by sample in time, as `spibench run` records (`detector::record`): the
    /// reference, about a hundred times slower.
    Samples,
}

impl RecordSpec {
    pub fn model(self) -> crate::detector::RecordModel {
        match self {
            RecordSpec::Frames => crate::detector::RecordModel::Frames,
            RecordSpec::Samples => crate::detector::RecordModel::Samples,
        }
    }
}

/// Which benches the samples are measured through.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum BenchesSpec {
    /// The bench file as it is.
    #[default]
    Nominal,
    /// Benches drawn from a tolerance file (relative to the spec), a new one every
    /// `samples_per_bench` samples: samples s with the same ⌊s / samples_per_bench⌋ = t see
    /// the bench of tolerance trial t (its draws keyed by the dataset's seed and t, its
    /// compensators adjusted as `spibench tolerance` adjusts them), each traced as a kernel of
    /// its own.
    Tolerance {
        /// The tolerance file, relative to the spec.
        file: String,
        /// Samples measured through each drawn bench.
        #[serde(deserialize_with = "via::<SampleCount, _, _>")]
        samples_per_bench: u64,
    },
}

/// The object-kernel trace.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct KernelSpec {
    /// Lamp rays of the kernel trace.
    #[serde(deserialize_with = "via::<KernelRays, _, _>")]
    pub rays: u64,
    /// Seed of the kernel trace.
    pub seed: u64,
    /// Object grid (pixels across, down): may be finer than the DMD units.
    #[serde(deserialize_with = "via::<(GridSide, GridSide), _, _>")]
    pub grid_px: (usize, usize),
    /// The chart field the grid covers (mm), centred on the chart's `position_mm`.
    #[serde(deserialize_with = "via::<(FieldMm, FieldMm), _, _>")]
    pub field_mm: (f64, f64),
    /// The chart element (default: the bench's only chart).
    #[serde(default)]
    pub chart: Option<String>,
}

impl KernelSpec {
    /// Checks the numbers as a spec's `kernel:` section reads them (for a kernel spec made in
    /// code: the Python package's `Bench.kernel`); each error names its field (`grid_px`,
    /// `field_mm`, `rays`) and nothing else, for the caller to locate.
    pub fn check(&self) -> Result<()> {
        for side in [self.grid_px.0, self.grid_px.1] {
            GridSide::try_from(side as u64).map_err(|m| Error::field("grid_px", m))?;
        }
        for side in [self.field_mm.0, self.field_mm.1] {
            FieldMm::try_from(side).map_err(|m| Error::field("field_mm", m))?;
        }
        KernelRays::try_from(self.rays).map_err(|m| Error::field("rays", m))?;
        Ok(())
    }
}

/// How an image larger than the grid becomes an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
pub enum FitRule {
    /// A grid-sized window at a random position (the image must be at least the grid's size).
    RandomCrop,
    /// The whole image resampled to the grid by area averaging.
    Resize,
}

/// Where the objects come from.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub enum ObjectsSpec {
    /// Every PNG, JPEG, EXR or 2-D `.npy` image of a folder (relative to the spec), in name order;
    /// sample s uses image s mod count.
    Folder {
        /// The folder, relative to the spec.
        path: String,
        /// How an image larger than the grid becomes an object.
        rule: FitRule,
    },
    /// Shipped test images by name.
    TestImages {
        /// Their names (`astronaut`, `chelsea`, `coffee`, `rocket`, `hubble_deep_field`).
        names: Vec<String>,
        /// How an image larger than the grid becomes an object.
        rule: FitRule,
    },
    /// The 1951 USAF chart at a random scale (field widths from `min_field_mm` to
    /// `max_field_mm`) and a random offset (up to half the field).
    Usaf {
        /// The smallest field width (mm).
        #[serde(deserialize_with = "via::<UsafFieldMm, _, _>")]
        min_field_mm: f64,
        /// The largest field width (mm).
        #[serde(deserialize_with = "via::<UsafFieldMm, _, _>")]
        max_field_mm: f64,
    },
    /// The modified Shepp–Logan phantom.
    Phantom,
    /// 1 to `max_count` random rectangles of random transmittance on black.
    Rectangles {
        /// The most rectangles an object has.
        #[serde(deserialize_with = "via::<Count<1, 1000>, _, _>")]
        max_count: usize,
    },
}

/// The acquisitions of every sample.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AcquisitionSpec {
    /// The schemes each sample is measured with.
    pub schemes: Vec<Scheme>,
    /// The sampling ratios M/N, each in (0, 1].
    #[serde(deserialize_with = "via::<Vec<Ratio>, _, _>")]
    pub ratios: Vec<f64>,
    /// The pattern family and ordering, `Random(seed: S)` or `Hadamard(ordering: O)` (default:
    /// the bench's `run:` section).
    #[serde(default)]
    pub patterns: Option<crate::scene::experiment::PatternsSpec>,
}

/// What a dataset writes besides the measurements, objects, k± and b±.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WriteSpec {
    /// Also write the packed base patterns (once per dataset).
    #[serde(default)]
    pub patterns: bool,
    /// Also write, per sample, the oscilloscope's record of the first `scope_frames` frames of
    /// each sequence, sample by sample (at most 100 frames).
    #[serde(
        default,
        deserialize_with = "via::<Count<0, { MAX_SCOPE_FRAMES as u64 }>, _, _>"
    )]
    pub scope_frames: usize,
    /// Also reconstruct every (scheme, ratio) with the bench's TVAL3 settings, and write the
    /// reconstructions, the object's image on the DMD units they are scored against, and their
    /// PSNR and MSSIM.
    #[serde(default)]
    pub reconstructions: bool,
}

/// The most frames of oscilloscope record a dataset sample may carry.
pub const MAX_SCOPE_FRAMES: usize = 100;

/// Objects, validated and loaded.
#[derive(Debug, Clone)]
pub enum ObjectSource {
    /// Images in [0, 1] with the rule that fits them to the grid.
    Images {
        names: Vec<String>,
        images: Vec<Raster>,
        rule: FitRule,
    },
    Usaf {
        min_field_mm: f64,
        max_field_mm: f64,
    },
    Phantom,
    Rectangles {
        max_count: usize,
    },
}

/// An object image a dataset reads (a file of an image folder, or a shipped test image), named
/// as the spec finds it and hashed as read: a dataset's manifest lists them
/// (`provenance.objects`), so that a merge or a resume sees an image that changed between jobs.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ObjectFile {
    /// The file's name in the image folder, or the test image's name.
    pub name: String,
    /// The SHA-256 of the bytes decoded (the file's, or the shipped image's).
    pub sha256: String,
}

/// A validated dataset spec.
#[derive(Debug, Clone)]
pub struct DatasetSpec {
    pub file: DatasetFile,
    pub path: PathBuf,
    /// The spec's text (hashed and copied into the manifest).
    pub text: String,
    pub bench_path: PathBuf,
    /// The tolerance file of `benches: Tolerance(..)`, resolved against the spec's folder.
    pub tolerance_path: Option<PathBuf>,
    pub objects: ObjectSource,
    /// The object images read, in the order samples use them (none for drawn objects).
    pub object_files: Vec<ObjectFile>,
}

/// Reads and validates a dataset spec; images are loaded (and checked against the grid) here.
/// `bytes_per_sample` gives the disk a sample needs, to check `max_disk_gb` (the caller knows
/// the acquisition; pass 0 to skip).
pub fn read_dataset(path: &Path) -> Result<DatasetSpec> {
    let text = crate::scene::read_text(path)?;
    parse_dataset(&text, path)
}

pub fn parse_dataset(text: &str, path: &Path) -> Result<DatasetSpec> {
    let file: DatasetFile = crate::scene::parse_ron(text, path)?;
    let err = |field: &str, msg: String| {
        let e = Error::field(field, msg).in_file(path);
        locate::at(e, text, locate::first_key(text, field))
    };
    let base = path.parent().unwrap_or(Path::new("."));
    if let Some(e) = &file.electronics {
        crate::scene::run::electronics_si(e, Some(text), path)?;
    }
    let tolerance_path = match &file.benches {
        BenchesSpec::Nominal => None,
        BenchesSpec::Tolerance { file: tol, .. } => {
            let p = base.join(tol);
            if !p.is_file() {
                return Err(err(
                    "file",
                    format!("the tolerance file {} does not exist", p.display()),
                ));
            }
            Some(p)
        }
    };
    let (gw, gh) = file.kernel.grid_px;
    if let Some(a) = &file.acquisition {
        if a.schemes.is_empty() {
            return Err(err("schemes", "name at least one scheme".into()));
        }
        if a.ratios.is_empty() {
            return Err(err("ratios", "name at least one sampling ratio".into()));
        }
    }
    let fit = |img: &Raster, name: &str, rule: FitRule| -> Result<()> {
        if rule == FitRule::RandomCrop && (img.width < gw || img.height < gh) {
            return Err(err(
                "objects",
                format!(
                    "image {name} ({}×{}) is smaller than the {gw}×{gh} object grid: a random \
                     crop needs a larger image (or use rule: Resize)",
                    img.width, img.height
                ),
            ));
        }
        Ok(())
    };
    let mut object_files = Vec::new();
    let objects = match &file.objects {
        ObjectsSpec::Folder { path: folder, rule } => {
            folder_objects(&base.join(folder), *rule, &err, &fit, &mut object_files)?
        }
        ObjectsSpec::TestImages { names, rule } => {
            if names.is_empty() {
                return Err(err("names", "name at least one test image".into()));
            }
            let mut images = Vec::new();
            for n in names {
                let bytes =
                    crate::objects::test_image(n).map_err(|e| err("names", e.to_string()))?;
                let img = crate::objects::image_file::decode_gray(bytes)
                    .map_err(|e| err("names", e.to_string()))?;
                fit(&img, n, *rule)?;
                object_files.push(ObjectFile {
                    name: n.clone(),
                    sha256: sha256_hex(bytes),
                });
                images.push(img.map(|v| v / 255.0));
            }
            ObjectSource::Images {
                names: names.clone(),
                images,
                rule: *rule,
            }
        }
        ObjectsSpec::Usaf {
            min_field_mm,
            max_field_mm,
        } => {
            if max_field_mm < min_field_mm {
                return Err(err(
                    "min_field_mm",
                    "USAF fields need min_field_mm ≤ max_field_mm".into(),
                ));
            }
            ObjectSource::Usaf {
                min_field_mm: *min_field_mm,
                max_field_mm: *max_field_mm,
            }
        }
        ObjectsSpec::Phantom => ObjectSource::Phantom,
        ObjectsSpec::Rectangles { max_count } => ObjectSource::Rectangles {
            max_count: *max_count,
        },
    };
    Ok(DatasetSpec {
        bench_path: base.join(&file.bench),
        tolerance_path,
        file,
        path: path.to_path_buf(),
        text: text.to_string(),
        objects,
        object_files,
    })
}

/// The objects of an image folder: its PNG, JPEG, EXR and .npy files in name order, read,
/// hashed and decoded in parallel (a folder may hold thousands of images; the first bad file in
/// name order is the one reported), each checked against the grid by `fit` and listed with its
/// SHA-256 in `object_files`.
fn folder_objects(
    dir: &Path,
    rule: FitRule,
    err: &(dyn Fn(&str, String) -> Error + Sync),
    fit: &dyn Fn(&Raster, &str, FitRule) -> Result<()>,
    object_files: &mut Vec<ObjectFile>,
) -> Result<ObjectSource> {
    let entries = std::fs::read_dir(dir).map_err(|e| {
        err(
            "objects",
            format!("cannot read the image folder {}: {e}", dir.display()),
        )
    })?;
    let mut files: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension().and_then(|x| x.to_str()).is_some_and(|x| {
                matches!(
                    x.to_ascii_lowercase().as_str(),
                    "png" | "jpg" | "jpeg" | "exr" | "npy"
                )
            })
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(err(
            "objects",
            format!(
                "the image folder {} holds no PNG, JPEG, EXR or .npy image",
                dir.display()
            ),
        ));
    }
    let read: Vec<Result<(Raster, String)>> = files
        .par_iter()
        .map(|f| {
            let unreadable =
                |e: String| err("objects", format!("unreadable image {}: {e}", f.display()));
            let bytes = std::fs::read(f).map_err(|e| unreadable(e.to_string()))?;
            let img = crate::objects::image_file::decode_gray(&bytes)
                .map_err(|e| unreadable(e.to_string()))?;
            Ok((img, sha256_hex(&bytes)))
        })
        .collect();
    let mut names = Vec::new();
    let mut images = Vec::new();
    for (f, r) in files.iter().zip(read) {
        let (img, sha256) = r?;
        let name = f.file_name().map(|n| n.to_string_lossy().to_string());
        let name = name.unwrap_or_default();
        fit(&img, &name, rule)?;
        object_files.push(ObjectFile {
            name: name.clone(),
            sha256,
        });
        names.push(name);
        images.push(img.map(|v| v / 255.0));
    }
    Ok(ObjectSource::Images {
        names,
        images,
        rule,
    })
}

impl DatasetSpec {
    /// The pattern family the spec's acquisition names, if it names one.
    pub fn patterns(&self) -> Option<&crate::scene::experiment::PatternsSpec> {
        self.file
            .acquisition
            .as_ref()
            .and_then(|a| a.patterns.as_ref())
    }

    /// An error of the spec's `kernel:` section found by code that took the section as a value
    /// (the kernel builder, `pipeline::operator::ClearChart`), located in the spec at its field,
    /// or at `kernel:` when the field is not written (a default chart). Other errors (the
    /// bench's own, located in the bench file) are returned as they are.
    pub fn kernel_error(&self, e: Error) -> Error {
        match e {
            Error::Input { location, message } if location.file.is_none() => {
                let field = location.field.unwrap_or_else(|| "kernel".to_string());
                let pos = locate::key_after(&self.text, "kernel", &field);
                locate::at(
                    Error::field(field, message).in_file(&self.path),
                    &self.text,
                    pos,
                )
            }
            e => e,
        }
    }

    /// An input error located at `field` of the spec.
    pub fn error(&self, field: &str, message: impl Into<String>) -> Error {
        let e = Error::field(field, message).in_file(&self.path);
        locate::at(e, &self.text, locate::first_key(&self.text, field))
    }
}
