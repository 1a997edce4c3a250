//! Provenance: what made an output file. Every command's `summary.json` carries a `provenance`
//! block (docs/outputs.md): the spibench version and the git commit it was built from (when
//! known), the command line, the seeds, and the SHA-256 and size of every input file.
//!
//! Nothing in it changes between two runs of the same command on the same inputs, so summaries
//! stay byte-identical; the date of a run is a timing and lives with the timings. It is not
//! tied to the command line: a caller that is not the `spibench` binary (a dataset manifest,
//! the Python package) names its own command words with [`Provenance::with_command`]. A bench's
//! provenance is `Provenance::of_bench` (in `scene::doc`, above this module in the module
//! graph): the bench document's text and the images it loads.

use std::path::Path;

use serde::Serialize;
use sha2::{Digest, Sha256};

/// One input file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct InputFile {
    /// As given on the command line (or a built-in name in angle brackets).
    pub path: String,
    pub sha256: String,
    pub bytes: u64,
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Provenance {
    pub spibench_version: &'static str,
    /// The commit spibench was built from, with "-modified" when the tree had changes; None
    /// when it was not built from a git checkout.
    pub git_commit: Option<&'static str>,
    /// The command line as given (program name first).
    pub command: Vec<String>,
    pub seeds: Vec<u64>,
    pub inputs: Vec<InputFile>,
    /// The glasses a bench's lens prescriptions modelled from their files' nd and Vd (each
    /// allowed by its element); absent when none was.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub glass_substitutions: Vec<String>,
    /// The model the bench's DMD was traced with, `geometric` or `diffractive`, after any
    /// override of the file's (docs/dmd_diffraction.md); absent for an output of no bench with
    /// a DMD.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dmd_model: Option<&'static str>,
}

/// The SHA-256 of `bytes` as lower-case hex (FIPS 180-4).
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// Bytes (a digest) as lower-case hex.
pub fn hex(digest: &[u8]) -> String {
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// The most bytes an input file may have: no spibench input comes near it, and hashing stops
/// there rather than reading a wrong path (a disk image, a device) to its end.
const INPUT_CAP: u64 = 4 << 30;

impl Provenance {
    /// The provenance of this process (its command line from `std::env::args()`) with its
    /// `seeds` and no inputs yet.
    pub fn new(seeds: &[u64]) -> Provenance {
        Provenance::with_command(std::env::args().collect(), seeds)
    }

    /// The provenance of the command `command` (program name first) with its `seeds` and no
    /// inputs yet.
    pub fn with_command(command: Vec<String>, seeds: &[u64]) -> Provenance {
        Provenance {
            spibench_version: env!("CARGO_PKG_VERSION"),
            git_commit: option_env!("SPIBENCH_GIT_COMMIT"),
            command,
            seeds: seeds.to_vec(),
            inputs: Vec::new(),
            glass_substitutions: Vec::new(),
            dmd_model: None,
        }
    }

    /// Adds an input file, hashed as it is on disk now (streamed; the command has already
    /// read and validated it, so only a file that grew meanwhile meets the 4 GiB cap).
    pub fn file(mut self, path: &Path) -> crate::Result<Provenance> {
        self.inputs.push(hash_file(path)?);
        Ok(self)
    }

    /// Adds input files in order ([`Provenance::file`] each).
    pub fn files(self, paths: &[std::path::PathBuf]) -> crate::Result<Provenance> {
        paths.iter().try_fold(self, |p, f| p.file(f))
    }

    /// Adds an input held in memory (a built-in bench or experiment).
    pub fn text(mut self, name: &str, text: &str) -> Provenance {
        self.inputs.push(InputFile {
            path: name.to_string(),
            sha256: sha256_hex(text.as_bytes()),
            bytes: text.len() as u64,
        });
        self
    }
}

/// The SHA-256 and size of a file on disk, read in 64 KiB blocks.
pub fn hash_file(path: &Path) -> crate::Result<InputFile> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| crate::Error::read(path, e))?;
    let mut reader = file.take(INPUT_CAP + 1);
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut total = 0u64;
    loop {
        let n = reader
            .read(&mut buf)
            .map_err(|e| crate::Error::read(path, e))?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        total += n as u64;
    }
    if total > INPUT_CAP {
        return Err(crate::Error::input("larger than 4 GiB: not a spibench input").in_file(path));
    }
    Ok(InputFile {
        path: path.display().to_string(),
        sha256: hex(&hasher.finalize()),
        bytes: total,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hashes_text_and_files_alike() {
        let p = Provenance::with_command(vec!["spibench".into(), "run".into()], &[3])
            .text("<built-in>", "abc");
        assert_eq!(p.command, ["spibench", "run"]);
        assert_eq!(p.seeds, [3]);
        // SHA-256("abc"), FIPS 180-2 appendix B.1.
        assert_eq!(
            p.inputs[0].sha256,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert_eq!(p.inputs[0].bytes, 3);
        let path = std::env::temp_dir().join(format!("spibench-prov-{}", std::process::id()));
        std::fs::write(&path, "abc").unwrap();
        let f = hash_file(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert_eq!(f.sha256, p.inputs[0].sha256);
        assert_eq!(f.bytes, 3);
    }
}
