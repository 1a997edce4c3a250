//! Provenance: what made a `summary.json`. Every command's summary carries a `provenance`
//! block (docs/outputs.md): the spibench version and the git commit it was built from (when
//! known), the command line, the seeds, and the SHA-256 and size of every input file.
//!
//! Nothing in it changes between two runs of the same command on the same inputs, so summaries
//! stay byte-identical; the date of a run is a timing and lives with the timings.

use std::path::Path;

use serde::Serialize;
use sha2::{Digest, Sha256};

use crate::report::output::OutputDir;

/// One input file.
#[derive(Debug, Clone, Serialize)]
pub struct InputFile {
    /// As given on the command line (or a built-in name in angle brackets).
    pub path: String,
    pub sha256: String,
    pub bytes: u64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Provenance {
    pub spibench_version: &'static str,
    /// The commit spibench was built from, with "-modified" when the tree had changes; None
    /// when it was not built from a git checkout.
    pub git_commit: Option<&'static str>,
    /// The command line as given (program name first).
    pub command: Vec<String>,
    pub seeds: Vec<u64>,
    pub inputs: Vec<InputFile>,
}

pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

impl Provenance {
    /// The provenance of this process with its `seeds` and no inputs yet.
    pub fn new(seeds: &[u64]) -> Provenance {
        Provenance {
            spibench_version: env!("CARGO_PKG_VERSION"),
            git_commit: option_env!("SPIBENCH_GIT_COMMIT"),
            command: std::env::args().collect(),
            seeds: seeds.to_vec(),
            inputs: Vec::new(),
        }
    }

    /// Adds an input file, hashed as it is on disk now (streamed; the command has already
    /// read and validated it, so only a file that grew meanwhile meets the 4 GiB cap).
    pub fn file(mut self, path: &Path) -> crate::Result<Provenance> {
        use std::io::Read;
        const CAP: u64 = 4 << 30;
        let file = std::fs::File::open(path).map_err(|e| crate::Error::read(path, e))?;
        let mut reader = file.take(CAP + 1);
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
        if total > CAP {
            return Err(
                crate::Error::input("larger than 4 GiB: not a spibench input").in_file(path),
            );
        }
        self.inputs.push(InputFile {
            path: path.display().to_string(),
            sha256: hasher
                .finalize()
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect(),
            bytes: total,
        });
        Ok(self)
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

/// The current time in UTC as ISO 8601 (`2026-11-24T01:15:00Z`), for timings files. Civil
/// date from days since 1970-01-01 by Hinnant's algorithm ("chrono-compatible low-level date
/// algorithms", 2013), which holds for the proleptic Gregorian calendar.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    utc_from_unix(secs)
}

fn utc_from_unix(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// A summary with the provenance block as its first key (the summary's own keys follow in
/// their order).
#[derive(Serialize)]
struct WithProvenance<'a, T: Serialize> {
    provenance: &'a Provenance,
    #[serde(flatten)]
    summary: &'a T,
}

/// Writes `summary` (a struct) as `summary.json` with the `provenance` block first.
pub fn write_summary<T: Serialize>(
    out: &OutputDir,
    summary: &T,
    provenance: &Provenance,
) -> crate::Result<()> {
    crate::report::json::write_json(
        &out.path("summary.json"),
        &WithProvenance {
            provenance,
            summary,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates() {
        assert_eq!(utc_from_unix(0), "1970-01-01T00:00:00Z");
        // 2000-02-29 (a leap day of a century leap year) and 2026-11-24 01:15:00.
        assert_eq!(utc_from_unix(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc_from_unix(1_795_482_900), "2026-11-24T01:15:00Z");
    }

    #[test]
    fn provenance_comes_first_and_hashes_inputs() {
        #[derive(Serialize)]
        struct S {
            b: u32,
            a: u32,
        }
        let p = Provenance::new(&[3]).text("<built-in>", "abc");
        // SHA-256("abc"), FIPS 180-2 appendix B.1.
        assert_eq!(
            p.inputs[0].sha256,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let text = serde_json::to_string(&WithProvenance {
            provenance: &p,
            summary: &S { b: 1, a: 2 },
        })
        .unwrap();
        assert!(
            text.starts_with("{\"provenance\":{\"spibench_version\""),
            "{text}"
        );
        assert!(text.ends_with("\"b\":1,\"a\":2}"), "{text}");
    }
}
