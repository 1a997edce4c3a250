//! How every command writes its `summary.json`: with its `provenance` block first
//! (crate::provenance holds the block itself), and `timings.json` beside it with the date.

use serde::Serialize;

use crate::provenance::Provenance;
use crate::report::output::OutputDir;

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

/// Writes `summary.json` (provenance first) and, when the command has timings, `timings.json`
/// beside it: the one file whose figures differ between two identical runs.
pub fn write_summary_and_timings<T: Serialize, U: Serialize>(
    out: &OutputDir,
    summary: &T,
    provenance: &Provenance,
    timings: Option<&U>,
) -> crate::Result<()> {
    write_summary(out, summary, provenance)?;
    if let Some(t) = timings {
        crate::report::json::write_json(&out.path("timings.json"), t)?;
    }
    Ok(())
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
    fn provenance_comes_first() {
        #[derive(Serialize)]
        struct S {
            b: u32,
            a: u32,
        }
        let p = Provenance::new(&[3]).text("<built-in>", "abc");
        // SHA-256("abc"), FIPS 180-2 appendix B.1.
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
