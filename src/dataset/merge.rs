//! Merging dataset folders (the jobs of a sharded run) into one.

use std::path::{Path, PathBuf};

use super::contract::MANIFEST;
use super::manifest::{objects_differ, verified, write_manifest};
use super::{Manifest, MergedInput, read_manifest};
use crate::error::{Error, Result};
use crate::report::untrusted::bad_field;

/// Merges dataset folders (each one job's shards) into `out`: the same spec, bench and seed in
/// every folder, no shard twice and none missing. Every manifest is checked before any other
/// file is opened ([`read_manifest`]); every file copied (each shard's arrays, the copies of
/// the inputs) is checked against the SHA-256 of the manifest it came from, in the bytes that
/// are written; the merged manifest names only what the output holds and keeps each input's
/// command (`provenance.merged_from`). A merge of one folder is a complete copy of it.
pub fn merge(inputs: &[PathBuf], out: &Path, command: &[String]) -> Result<Manifest> {
    if inputs.is_empty() {
        return Err(Error::field("merge", "name the folders to merge"));
    }
    crate::report::output::refuse_overlap(out, inputs, "out")?;
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
                &d.join(MANIFEST),
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
        return Err(Error::field(
            "merge",
            format!(
                "cannot merge: {} shard(s) missing, first shard {first} (samples from {}); the \
                 folders give no sample there (an unfinished job? resume it)",
                m0.shards_total - listed,
                first * m0.shard_samples
            ),
        ));
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
