//! A dataset folder written in place: its setup files, a resume's checks and clean-up, the
//! shards' arrays (`shards` makes and commits them), and `generate`, which puts these together.

use std::path::Path;

use super::contract::{
    BENCH_COPY, MANIFEST, PATTERNS, SETUP_FILES, SPEC_COPY, SampleArray, TOLERANCE_COPY,
    is_shard_dir, is_shard_staging, temporary,
};
use super::manifest::{manifest_text, objects_differ};
use super::{ArraySchema, Manifest, Prepared, Sample, read_manifest, shards, verify_shard};
use crate::error::{Error, Result};
use crate::report::npy::F64FileWriter;
use crate::report::output::FolderLock;
use crate::report::untrusted::bad_field;

impl Prepared {
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
        match SampleArray::parse(name) {
            Some(SampleArray::Sample) => index(put, &|s| s),
            Some(SampleArray::Object) => rows(put, &|s| &s.object),
            Some(SampleArray::K) => rows(put, &|s| &s.k_a_per_w),
            Some(SampleArray::B) => rows(put, &|s| &s.b_a),
            Some(SampleArray::Bench) => index(put, &|s| self.bench_index(s)),
            Some(SampleArray::Deviations) => rows(put, &|s| &s.deviations),
            // The reconstructions' DMD image is one of the optional arrays.
            Some(SampleArray::DmdImage) | None => {
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
    pub(super) fn write_array(
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
    pub(super) fn packed_patterns(&self) -> Vec<u8> {
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
}

/// Writes `name` in the dataset folder `lock` holds, atomically, its temporary copy staged so
/// that SIGINT or SIGTERM removes it.
pub(super) fn write_locked(lock: &FolderLock, name: &str, bytes: &[u8]) -> Result<()> {
    let path = lock.dir().join(name);
    let tmp = crate::report::npy::atomic_temp(&path);
    crate::report::output::refuse_link(&tmp, "temporary copy")?;
    let written = crate::report::npy::write_atomic_with(&path, bytes, |t| {
        lock.stage_created(t, crate::report::output::create_fresh)
    });
    lock.unstage(&tmp);
    written
}

/// True when the folder `dir` holds nothing but a fresh run's setup files (complete or
/// temporary) and lock files: a run stopped before its first manifest, which a resume starts
/// afresh.
fn only_setup_files(dir: &Path) -> bool {
    let setup = |n: &str| SETUP_FILES.iter().any(|f| n == *f || n == temporary(f));
    dir.read_dir().is_ok_and(|d| {
        d.flatten().all(|e| {
            let n = e.file_name().to_string_lossy().to_string();
            n.starts_with(".spibench-") || (setup(&n) && e.file_type().is_ok_and(|t| t.is_file()))
        })
    })
}

/// Removes what an interrupted run left in a dataset folder: staging folders
/// (`.shard_NNNNNN.partial`) and shard folders committed after the manifest's last update. Only
/// entries with exactly these names go; a symbolic link among them is removed itself, never
/// followed.
fn remove_leftovers(dir: &Path, manifest: &Manifest) -> Result<()> {
    for e in std::fs::read_dir(dir)
        .map_err(|e| Error::read(dir, e))?
        .flatten()
    {
        let name = e.file_name().to_string_lossy().to_string();
        let staging = is_shard_staging(&name);
        let unlisted = is_shard_dir(&name) && !manifest.shards.iter().any(|s| s.dir == name);
        // `write_atomic`'s temporary copies of the folder's own files.
        let partial = SETUP_FILES.iter().any(|f| name == temporary(f));
        if !(staging || unlisted || partial) {
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
    let exists = dir.join(MANIFEST).exists();
    if resume && exists {
        manifest = read_manifest(dir)?;
        let fresh = prep.manifest(command, range);
        if manifest.provenance.spec_sha256 != fresh.provenance.spec_sha256
            || manifest.provenance.bench_sha256 != fresh.provenance.bench_sha256
            || manifest.provenance.tolerance_sha256 != fresh.provenance.tolerance_sha256
            || manifest.shard_range != range
        {
            return Err(Error::field(
                "resume",
                "the folder holds another dataset (its spec, bench or shard range differ): \
                 resume it with the same spec and shard range",
            )
            .in_file(dir));
        }
        if let Some((i, why)) =
            objects_differ(&fresh.provenance.objects, &manifest.provenance.objects)
        {
            return Err(bad_field(
                &dir.join(MANIFEST),
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
                .flat_map(|f| [f.to_string(), temporary(f)])
            {
                match std::fs::remove_file(dir.join(&f)) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                        return Err(Error::write(&dir.join(&f), e));
                    }
                    _ => {}
                }
            }
        } else if exists || dir.read_dir().is_ok_and(content) {
            return Err(Error::field(
                "out",
                "the output folder exists and is not empty: choose another, or resume the \
                 dataset it holds",
            )
            .in_file(dir));
        }
        std::fs::create_dir_all(dir).map_err(|e| Error::write(dir, e))?;
        manifest = prep.manifest(command, range);
        write_locked(lock, SPEC_COPY, prep.spec.text.as_bytes())?;
        write_locked(lock, BENCH_COPY, prep.bench_text.as_bytes())?;
        if let Some(d) = &prep.drawn {
            write_locked(lock, TOLERANCE_COPY, d.text.as_bytes())?;
        }
        if prep.spec.file.write.patterns {
            write_locked(lock, PATTERNS, &prep.packed_patterns())?;
        }
        write_locked(lock, MANIFEST, manifest_text(&manifest)?.as_bytes())?;
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
