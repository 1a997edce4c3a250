//! The dataset folder's contract, in one place: the names of its files, folders and arrays,
//! and the rules a manifest read back from a folder must follow. The writer (`dataset`), the
//! Python package (through its extension) and the readers' tests take the names from here;
//! `examples/dataset_numpy.py`, which must run with numpy alone, keeps its own copy of these
//! tables, and a Python test compares it with this module's.
//!
//! A dataset folder holds
//! - [`MANIFEST`], the manifest ([`super::Manifest`], format [`FORMAT`]);
//! - the copies of its inputs, [`COPIES`] (`spec.ron`, `bench.ron` and, for benches drawn from a
//!   tolerance file, `tolerances.ron`), and optionally [`PATTERNS`], the packed base patterns;
//! - one folder per shard, [`shard_dir`] (`shard_NNNNNN`), holding one [`array_file`]
//!   (`NAME.npy`) per array of the manifest's schema.
//!
//! The arrays are the per-sample [`SampleArray`]s (`sample`, `object`, `k`, …), one
//! [`CellArray`] of each kind per scheme and ratio (`meas_SCHEME_rRATIO`, the ratio with four
//! decimals), and one oscilloscope record per sequence ([`scope_array`], `scope_SEQUENCE`).
//! While a run writes, a shard is staged as [`shard_staging`] (`.shard_NNNNNN.partial`) and a
//! setup file or the manifest as [`temporary`] (`NAME.partial`).
//!
//! A manifest read back from a folder is untrusted (crate::report::untrusted): before any file
//! it names is opened, every name in it is checked against what `spibench dataset` writes, and
//! every path it names must stay inside the folder ([`check_manifest`], [`check_paths`]):
//!
//! - a shard folder is exactly `shard_NNNNNN` of its own index, its samples those of that index;
//! - an array name is one of the names the manifest's schemes, ratios and sequences allow
//!   ([`array_names`]), its file exactly `NAME.npy`, and every shard holds exactly the schema's
//!   arrays in the schema's order;
//! - the copies of the inputs are exactly the names of [`COPIES`] and [`PATTERNS`], each with a
//!   SHA-256; every object image listed has a name and a SHA-256;
//! - none of these resolves, through a symbolic link, outside the folder.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use super::Manifest;
use crate::acquisition::{Scheme, Sequence};
use crate::error::Result;
use crate::report::untrusted::{Folder, PlainName, bad_field, is_sha256_hex};

/// The manifest's format name.
pub const FORMAT: &str = "spibench-dataset-1";
/// The manifest's file.
pub const MANIFEST: &str = "manifest.json";
/// The copy of the dataset spec.
pub const SPEC_COPY: &str = "spec.ron";
/// The copy of the bench file.
pub const BENCH_COPY: &str = "bench.ron";
/// The copy of the tolerance file the benches were drawn from.
pub const TOLERANCE_COPY: &str = "tolerances.ron";
/// The packed base patterns (`write: (patterns: true)`).
pub const PATTERNS: &str = "patterns.npy";
/// The copies of the inputs, each with the field of the manifest's `provenance` that names it.
pub const COPIES: [(&str, &str); 3] = [
    ("spec_file", SPEC_COPY),
    ("bench_file", BENCH_COPY),
    ("tolerance_file", TOLERANCE_COPY),
];
/// The files a dataset folder gets before its first shard, in the order they are written.
pub const SETUP_FILES: [&str; 5] = [SPEC_COPY, BENCH_COPY, TOLERANCE_COPY, PATTERNS, MANIFEST];
/// The suffix of what a run is still writing: a staged shard, a file's temporary copy.
pub const PARTIAL: &str = ".partial";

/// The temporary copy of the folder's file `name` while it is written (as
/// `report::npy::atomic_temp` names it).
pub fn temporary(name: &str) -> String {
    format!("{name}{PARTIAL}")
}

/// The folder of shard `b`: `shard_NNNNNN`, the index with at least six digits.
pub fn shard_dir(b: u64) -> String {
    format!("shard_{b:06}")
}

/// The staging folder of shard `b` while its files are written: `.shard_NNNNNN.partial`.
pub fn shard_staging(b: u64) -> String {
    format!(".{}{PARTIAL}", shard_dir(b))
}

/// Whether `name` has the form of a shard folder (`shard_` and six or more digits).
pub fn is_shard_dir(name: &str) -> bool {
    name.strip_prefix("shard_")
        .is_some_and(|d| d.len() >= 6 && d.bytes().all(|b| b.is_ascii_digit()))
}

/// Whether `name` has the form of a shard's staging folder.
pub fn is_shard_staging(name: &str) -> bool {
    name.strip_prefix('.')
        .and_then(|n| n.strip_suffix(PARTIAL))
        .is_some_and(is_shard_dir)
}

/// The file of array `name` in a shard folder: `NAME.npy`.
pub fn array_file(name: &str) -> String {
    format!("{name}.npy")
}

/// The arrays of a sample whatever its schemes and ratios (each optional but `sample`,
/// `object`, `k` and `b`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleArray {
    /// The sample index s.
    Sample,
    /// The ideal object on the kernel grid.
    Object,
    /// k± of the sample's transport.
    K,
    /// b± of the sample's transport.
    B,
    /// The index of the drawn bench (benches drawn from a tolerance file).
    Bench,
    /// The drawn bench's deviations (benches drawn from a tolerance file).
    Deviations,
    /// The object's light on the DMD units (with the reconstructions).
    DmdImage,
}

impl SampleArray {
    pub const ALL: [SampleArray; 7] = [
        SampleArray::Sample,
        SampleArray::Object,
        SampleArray::K,
        SampleArray::B,
        SampleArray::Bench,
        SampleArray::Deviations,
        SampleArray::DmdImage,
    ];

    /// The array's name in a manifest and its file's stem.
    pub fn name(self) -> &'static str {
        match self {
            SampleArray::Sample => "sample",
            SampleArray::Object => "object",
            SampleArray::K => "k",
            SampleArray::B => "b",
            SampleArray::Bench => "bench",
            SampleArray::Deviations => "deviations",
            SampleArray::DmdImage => "dmd_image",
        }
    }

    /// The array named `name`, if it is one of these.
    pub fn parse(name: &str) -> Option<SampleArray> {
        SampleArray::ALL.into_iter().find(|a| a.name() == name)
    }
}

/// The arrays a sample holds per (scheme, ratio): `KIND_SCHEME_rRATIO`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellArray {
    /// The scheme's measurements (`meas`).
    Measurements,
    /// The scheme's TVAL3 reconstruction (`recon`).
    Reconstruction,
    /// Its PSNR and MSSIM (`score`).
    Score,
}

impl CellArray {
    pub const ALL: [CellArray; 3] = [
        CellArray::Measurements,
        CellArray::Reconstruction,
        CellArray::Score,
    ];

    /// The kind's prefix in an array name.
    pub fn prefix(self) -> &'static str {
        match self {
            CellArray::Measurements => "meas",
            CellArray::Reconstruction => "recon",
            CellArray::Score => "score",
        }
    }

    /// The kind with prefix `prefix`, if there is one.
    pub fn parse(prefix: &str) -> Option<CellArray> {
        CellArray::ALL.into_iter().find(|c| c.prefix() == prefix)
    }

    /// The array of scheme `scheme` (its key, as a manifest's `schemes` list it) at sampling
    /// ratio `ratio`, the ratio written with four decimals.
    pub fn name(self, scheme: &str, ratio: f64) -> String {
        format!("{}_{scheme}_r{ratio:.4}", self.prefix())
    }
}

/// The oscilloscope record of sequence `q`: `scope_SEQUENCE`.
pub fn scope_array(q: Sequence) -> String {
    format!("scope_{}", q.key())
}

/// Every array name a dataset of these schemes (their keys) and ratios may hold.
pub fn array_names(schemes: &[String], ratios: &[f64]) -> BTreeSet<String> {
    let mut names: BTreeSet<String> = SampleArray::ALL
        .iter()
        .map(|a| a.name().to_string())
        .collect();
    for s in schemes {
        for r in ratios {
            names.extend(CellArray::ALL.iter().map(|c| c.name(s, *r)));
        }
    }
    names.extend(Sequence::all().map(scope_array));
    names
}

/// The array names a manifest with these schemes and ratios may hold, each scheme checked, and
/// the ratios with the first.
fn allowed_names(m: &Manifest, file: &Path) -> Result<BTreeSet<String>> {
    for (i, s) in m.schemes.iter().enumerate() {
        if s.parse::<Scheme>().is_err() {
            return Err(bad_field(
                file,
                &format!("schemes[{i}]"),
                format!("{s:?} is not a scheme of spibench"),
            ));
        }
        if i > 0 {
            continue;
        }
        for (j, r) in m.ratios.iter().enumerate() {
            if !(r.is_finite() && *r > 0.0 && *r <= 1.0) {
                return Err(bad_field(
                    file,
                    &format!("ratios[{j}]"),
                    format!("a sampling ratio in (0, 1], got {r}"),
                ));
            }
        }
    }
    Ok(array_names(&m.schemes, &m.ratios))
}

/// The fixed file names of a dataset folder and their checksums.
fn check_copies(m: &Manifest, file: &Path) -> Result<()> {
    let p = &m.provenance;
    let fixed = [
        ("provenance.spec_file", Some(&p.spec_file), SPEC_COPY),
        ("provenance.bench_file", Some(&p.bench_file), BENCH_COPY),
        (
            "provenance.tolerance_file",
            p.tolerance_file.as_ref(),
            TOLERANCE_COPY,
        ),
        ("patterns_file", m.patterns_file.as_ref(), PATTERNS),
    ];
    for (field, got, want) in fixed {
        if let Some(got) = got
            && got != want
        {
            return Err(bad_field(
                file,
                field,
                format!("a dataset folder names this copy {want:?}, not {got:?}"),
            ));
        }
    }
    let sums = [
        ("provenance.spec_sha256", true, Some(&p.spec_sha256)),
        ("provenance.bench_sha256", true, Some(&p.bench_sha256)),
        (
            "provenance.tolerance_sha256",
            p.tolerance_file.is_some(),
            p.tolerance_sha256.as_ref(),
        ),
        (
            "patterns_sha256",
            m.patterns_file.is_some(),
            m.patterns_sha256.as_ref(),
        ),
    ];
    for (field, needed, sum) in sums {
        match sum {
            Some(s) if !is_sha256_hex(s) => {
                return Err(bad_field(
                    file,
                    field,
                    format!("a SHA-256 is 64 lowercase hexadecimal digits, not {s:?}"),
                ));
            }
            None if needed => {
                return Err(bad_field(
                    file,
                    field,
                    "missing: every file of a dataset folder has its SHA-256 in the manifest \
                     (a folder made by an older spibench? make it again)",
                ));
            }
            _ => {}
        }
    }
    // The object names are only compared and printed (never opened), so any file name will do,
    // but not one that could forge lines of a message.
    for (i, o) in p.objects.iter().enumerate() {
        let at = |f: &str| format!("provenance.objects[{i}].{f}");
        if o.name.is_empty() || o.name.chars().any(char::is_control) {
            return Err(bad_field(
                file,
                &at("name"),
                format!(
                    "an object is named by a non-empty file name, not {:?}",
                    o.name
                ),
            ));
        }
        if !is_sha256_hex(&o.sha256) {
            return Err(bad_field(
                file,
                &at("sha256"),
                format!(
                    "a SHA-256 is 64 lowercase hexadecimal digits, not {:?}",
                    o.sha256
                ),
            ));
        }
    }
    Ok(())
}

/// Checks every name, count and checksum of a manifest read from `file` (no file is opened).
pub fn check_manifest(m: &Manifest, file: &Path) -> Result<()> {
    if m.format != FORMAT {
        return Err(bad_field(
            file,
            "format",
            format!("{:?} is not {FORMAT:?}", m.format),
        ));
    }
    check_copies(m, file)?;
    if m.samples == 0 || m.shard_samples == 0 {
        return Err(bad_field(
            file,
            "shard_samples",
            "samples and shard_samples must be at least 1",
        ));
    }
    if m.shards_total != m.samples.div_ceil(m.shard_samples) {
        return Err(bad_field(
            file,
            "shards_total",
            format!(
                "{} samples in shards of {} make {} shards, not {}",
                m.samples,
                m.shard_samples,
                m.samples.div_ceil(m.shard_samples),
                m.shards_total
            ),
        ));
    }
    let (lo, hi) = m.shard_range;
    if lo > hi || hi > m.shards_total {
        return Err(bad_field(
            file,
            "shard_range",
            format!(
                "[{lo}, {hi}) is not a range of the {} shards",
                m.shards_total
            ),
        ));
    }
    let allowed = allowed_names(m, file)?;
    let mut seen = BTreeSet::new();
    for (i, a) in m.schema.iter().enumerate() {
        let field = format!("schema[{i}].name");
        PlainName::parse(&a.name, file, &field)?;
        if !allowed.contains(&a.name) || !seen.insert(a.name.as_str()) {
            return Err(bad_field(
                file,
                &field,
                format!(
                    "{:?} is not an array a dataset of these schemes and ratios holds (or it \
                     is listed twice)",
                    a.name
                ),
            ));
        }
    }
    let mut indices = BTreeSet::new();
    for i in 0..m.shards.len() {
        check_shard(m, i, file, &mut indices)?;
    }
    Ok(())
}

/// Checks shard entry `i` of the manifest: its index, folder, samples and files.
fn check_shard(m: &Manifest, i: usize, file: &Path, indices: &mut BTreeSet<u64>) -> Result<()> {
    let s = &m.shards[i];
    let at = |f: &str| format!("shards[{i}].{f}");
    if s.index < m.shard_range.0 || s.index >= m.shard_range.1 || !indices.insert(s.index) {
        return Err(bad_field(
            file,
            &at("index"),
            format!(
                "shard {} is not in this folder's range [{}, {}) (or is listed twice)",
                s.index, m.shard_range.0, m.shard_range.1
            ),
        ));
    }
    let want = shard_dir(s.index);
    if s.dir != want {
        PlainName::parse(&s.dir, file, &at("dir"))?;
        return Err(bad_field(
            file,
            &at("dir"),
            format!(
                "the folder of shard {} is {want:?}, not {:?}",
                s.index, s.dir
            ),
        ));
    }
    let first = s.index * m.shard_samples;
    let samples = first.saturating_add(m.shard_samples).min(m.samples) - first;
    if s.first_sample != first || s.samples != samples {
        return Err(bad_field(
            file,
            &at("first_sample"),
            format!(
                "shard {} holds samples {first} to {} ({samples} samples), not {} from {}",
                s.index,
                first + samples - 1,
                s.samples,
                s.first_sample
            ),
        ));
    }
    if s.files.len() != m.schema.len() {
        return Err(bad_field(
            file,
            &at("files"),
            format!(
                "a shard holds one file per array of the schema ({}), not {}",
                m.schema.len(),
                s.files.len()
            ),
        ));
    }
    for (k, (f, a)) in s.files.iter().zip(&m.schema).enumerate() {
        let field = |g: &str| at(&format!("files[{k}].{g}"));
        PlainName::parse(&f.file, file, &field("file"))?;
        if f.name != a.name {
            return Err(bad_field(
                file,
                &field("name"),
                format!("array {k} of the schema is {:?}, not {:?}", a.name, f.name),
            ));
        }
        if f.file != array_file(&a.name) {
            return Err(bad_field(
                file,
                &field("file"),
                format!(
                    "the file of array {:?} is \"{}.npy\", not {:?}",
                    a.name, a.name, f.file
                ),
            ));
        }
        if !is_sha256_hex(&f.sha256) {
            return Err(bad_field(
                file,
                &field("sha256"),
                format!(
                    "a SHA-256 is 64 lowercase hexadecimal digits, not {:?}",
                    f.sha256
                ),
            ));
        }
    }
    Ok(())
}

/// Every path a checked manifest names, relative to its folder, with the field that names it.
pub fn named_paths(m: &Manifest) -> Vec<(PathBuf, String)> {
    let mut v = vec![
        (
            PathBuf::from(&m.provenance.spec_file),
            "provenance.spec_file".into(),
        ),
        (
            PathBuf::from(&m.provenance.bench_file),
            "provenance.bench_file".into(),
        ),
    ];
    if let Some(t) = &m.provenance.tolerance_file {
        v.push((PathBuf::from(t), "provenance.tolerance_file".into()));
    }
    if let Some(p) = &m.patterns_file {
        v.push((PathBuf::from(p), "patterns_file".into()));
    }
    for (i, s) in m.shards.iter().enumerate() {
        v.push((PathBuf::from(&s.dir), format!("shards[{i}].dir")));
        for (k, f) in s.files.iter().enumerate() {
            v.push((
                Path::new(&s.dir).join(&f.file),
                format!("shards[{i}].files[{k}].file"),
            ));
        }
    }
    v
}

/// Checks that no path the manifest names leads out of `folder` (nothing is opened).
pub fn check_paths(folder: &Folder, m: &Manifest, file: &Path) -> Result<()> {
    for (rel, field) in named_paths(m) {
        folder.inside(&rel, file, &field)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::{
        ArraySchema, FileHash, KernelInfo, ManifestProvenance, ShardEntry, sha256_hex,
    };

    fn sum(s: &str) -> String {
        sha256_hex(s.as_bytes())
    }

    /// A manifest of 5 samples in shards of 2, shards 1 and 2 of it committed.
    fn manifest() -> Manifest {
        let names = ["sample", "object", "meas_double_arm_r0.0500", "k", "b"];
        let schema: Vec<ArraySchema> = names
            .iter()
            .map(|n| ArraySchema {
                name: n.to_string(),
                dtype: "<f8".into(),
                sample_shape: vec![],
                units: "1".into(),
                description: String::new(),
            })
            .collect();
        let shard = |index: u64, first: u64, samples: u64| ShardEntry {
            index,
            first_sample: first,
            samples,
            dir: format!("shard_{index:06}"),
            files: names
                .iter()
                .map(|n| FileHash {
                    name: n.to_string(),
                    file: format!("{n}.npy"),
                    sha256: sum(n),
                })
                .collect(),
        };
        Manifest {
            format: FORMAT.into(),
            provenance: ManifestProvenance {
                spibench_version: "0".into(),
                command: vec!["spibench".into()],
                spec_file: "spec.ron".into(),
                spec_sha256: sum("spec"),
                bench_file: "bench.ron".into(),
                bench_sha256: sum("bench"),
                tolerance_file: None,
                tolerance_sha256: None,
                objects: vec![crate::dataset::ObjectFile {
                    name: "a.png".into(),
                    sha256: sum("a.png"),
                }],
                merged_from: Vec::new(),
            },
            seed: 1,
            samples: 5,
            shard_samples: 2,
            shards_total: 3,
            shard_range: (1, 3),
            kernel: KernelInfo {
                rays: 1,
                seed: 1,
                grid_px: (1, 1),
                field_mm: (1.0, 1.0),
                entries: 1,
                multi_crossing_current_fraction: 0.0,
            },
            pattern_family: "random".into(),
            record: "frames".into(),
            dmd_model: "diffractive".into(),
            measurements_max: 1,
            schemes: vec!["double_arm".into()],
            ratios: vec![0.05],
            schema,
            patterns_file: None,
            patterns_sha256: None,
            shards: vec![shard(1, 2, 2), shard(2, 4, 1)],
        }
    }

    /// The error of a manifest edited by `edit`: it must name the file and `field`.
    fn refused(edit: impl Fn(&mut Manifest), field: &str) {
        let mut m = manifest();
        edit(&mut m);
        let e = check_manifest(&m, Path::new("d/manifest.json")).unwrap_err();
        assert!(e.is_user_error(), "{e}");
        let s = e.to_string();
        assert!(
            s.contains("d/manifest.json") && s.contains(&format!("field `{field}`")),
            "{field}: {s}"
        );
    }

    #[test]
    fn the_names_are_the_folder_layout() {
        assert_eq!(
            CellArray::Measurements.name("double_arm", 0.05),
            "meas_double_arm_r0.0500"
        );
        assert_eq!(
            CellArray::Score.name("traditional", 1.0),
            "score_traditional_r1.0000"
        );
        assert_eq!(scope_array(Sequence::Complementary), "scope_complementary");
        assert_eq!(array_file("k"), "k.npy");
        assert_eq!(shard_dir(12), "shard_000012");
        assert_eq!(shard_dir(1_234_567), "shard_1234567");
        assert_eq!(shard_staging(12), ".shard_000012.partial");
        assert!(is_shard_dir(&shard_dir(3)) && is_shard_staging(&shard_staging(3)));
        for bad in ["shard_12", "shard_00001x", "xshard_000001", ".shard_000001"] {
            assert!(!is_shard_dir(bad), "{bad}");
        }
        assert!(!is_shard_staging("shard_000001.partial"));
        // A setup file's temporary copy is named as `write_atomic` names it.
        for f in SETUP_FILES {
            let tmp = crate::report::npy::atomic_temp(Path::new(f));
            assert_eq!(tmp, Path::new(&temporary(f)), "{f}");
        }
        for a in SampleArray::ALL {
            assert_eq!(SampleArray::parse(a.name()), Some(a));
        }
        for c in CellArray::ALL {
            assert_eq!(CellArray::parse(c.prefix()), Some(c));
        }
        let names = array_names(&["double_arm".into()], &[0.05, 0.1]);
        assert_eq!(
            names.len(),
            SampleArray::ALL.len() + 2 * 3 + Sequence::all().len()
        );
        assert!(names.contains("recon_double_arm_r0.1000") && names.contains("scope_base"));
    }

    #[test]
    fn a_written_manifest_passes_and_every_tampering_is_named() {
        check_manifest(&manifest(), Path::new("m.json")).unwrap();
        refused(
            |m| m.shards[1].dir = "../outside/evil".into(),
            "shards[1].dir",
        );
        refused(|m| m.shards[0].dir = "/etc".into(), "shards[0].dir");
        refused(|m| m.shards[0].dir = "shard_000002".into(), "shards[0].dir");
        refused(|m| m.shards[0].dir = "shard_1".into(), "shards[0].dir");
        refused(
            |m| m.schema[0].name = "../../../outside/evil/sample".into(),
            "schema[0].name",
        );
        refused(
            |m| m.schema[2].name = "meas_double_arm_r0.2500".into(),
            "schema[2].name",
        );
        refused(|m| m.schema[1].name = "sample".into(), "schema[1].name");
        refused(
            |m| m.shards[1].files[1].file = "../object.npy".into(),
            "shards[1].files[1].file",
        );
        refused(
            |m| m.shards[1].files[1].file = "sample.npy".into(),
            "shards[1].files[1].file",
        );
        refused(
            |m| m.shards[0].files[0].name = "k".into(),
            "shards[0].files[0].name",
        );
        refused(
            |m| m.shards[0].files.pop().map(|_| ()).unwrap(),
            "shards[0].files",
        );
        refused(
            |m| m.shards[0].files[0].sha256 = "../x".into(),
            "shards[0].files[0].sha256",
        );
        refused(|m| m.shards[0].index = 0, "shards[0].index");
        refused(|m| m.shards[1].index = 1, "shards[1].index");
        refused(|m| m.shards[0].first_sample = 3, "shards[0].first_sample");
        refused(|m| m.shard_range = (0, 4), "shard_range");
        refused(|m| m.samples = u64::MAX, "shards_total");
        refused(|m| m.shard_samples = 0, "shard_samples");
        refused(|m| m.schemes[0] = "../evil".into(), "schemes[0]");
        refused(|m| m.ratios[0] = f64::NAN, "ratios[0]");
        refused(
            |m| m.provenance.spec_file = "/etc/passwd".into(),
            "provenance.spec_file",
        );
        refused(
            |m| m.provenance.tolerance_file = Some("../t.ron".into()),
            "provenance.tolerance_file",
        );
        refused(
            |m| m.provenance.tolerance_file = Some("tolerances.ron".into()),
            "provenance.tolerance_sha256",
        );
        refused(
            |m| m.patterns_file = Some("patterns.npy".into()),
            "patterns_sha256",
        );
        refused(|m| m.format = "other".into(), "format");
        refused(
            |m| m.provenance.objects[0].sha256 = "A".repeat(64),
            "provenance.objects[0].sha256",
        );
        refused(
            |m| m.provenance.objects[0].name = "a\nb".into(),
            "provenance.objects[0].name",
        );
        refused(
            |m| m.provenance.objects[0].name = String::new(),
            "provenance.objects[0].name",
        );
    }

    #[cfg(unix)]
    #[test]
    fn paths_that_lead_out_through_links_are_named() {
        let root =
            std::env::temp_dir().join(format!("spibench-dataset-check-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let dir = root.join("data");
        std::fs::create_dir_all(dir.join("shard_000002")).unwrap();
        std::fs::create_dir_all(root.join("outside")).unwrap();
        std::os::unix::fs::symlink(root.join("outside"), dir.join("shard_000001")).unwrap();
        let folder = Folder::new(&dir).unwrap();
        let file = dir.join("manifest.json");
        let e = check_paths(&folder, &manifest(), &file).unwrap_err();
        assert!(e.to_string().contains("field `shards[0].dir`"), "{e}");
        std::fs::remove_file(dir.join("shard_000001")).unwrap();
        std::fs::create_dir_all(dir.join("shard_000001")).unwrap();
        std::os::unix::fs::symlink(root.join("outside/k.npy"), dir.join("shard_000002/k.npy"))
            .unwrap();
        let e = check_paths(&folder, &manifest(), &file).unwrap_err();
        assert!(
            e.to_string().contains("field `shards[1].files[3].file`"),
            "{e}"
        );
        std::fs::remove_file(dir.join("shard_000002/k.npy")).unwrap();
        check_paths(&folder, &manifest(), &file).unwrap();
        let _ = std::fs::remove_dir_all(&root);
    }
}
