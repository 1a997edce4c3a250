//! The memory limit: every allocation whose size follows from the input (the diffractive DMD's
//! tail tables, an array read from a `.npy` file) is estimated before it is made, and an
//! estimate above [`MAX_MEMORY_BYTES`] is refused as bad input naming the estimate and the
//! settings that make it, instead of the process aborting part-way (an allocation failure
//! cannot be caught) or swapping for minutes. `--allow-large`, the switch that lifts the limits
//! on a command's total work, lifts this one too ([`allow_large`]); the library never lifts it
//! itself.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::Error;

/// The most memory one estimated table or array may take without `--allow-large`: 2 GB, a
/// quarter of a small machine's memory and far above what the shipped benches and datasets
/// need (the paper bench's tables are absent, a diffractive bench at the default 10 nm bins
/// needs tens of megabytes, a dataset shard's arrays a few tens).
pub const MAX_MEMORY_BYTES: f64 = 2e9;

static LIFTED: AtomicBool = AtomicBool::new(false);

/// Lifts the limit for the rest of the process (the command line's `--allow-large`).
pub fn allow_large() {
    LIFTED.store(true, Ordering::Relaxed);
}

/// The limit now in force: None once lifted.
pub fn limit() -> Option<f64> {
    (!LIFTED.load(Ordering::Relaxed)).then_some(MAX_MEMORY_BYTES)
}

/// A size in words: "3.84 GB" (decimal units, two decimals).
pub fn bytes_text(bytes: f64) -> String {
    let (v, unit) = if bytes >= 1e9 {
        (bytes / 1e9, "GB")
    } else if bytes >= 1e6 {
        (bytes / 1e6, "MB")
    } else if bytes >= 1e3 {
        (bytes / 1e3, "kB")
    } else {
        (bytes, "bytes")
    };
    if unit == "bytes" {
        format!("{v:.0} {unit}")
    } else {
        format!("{v:.2} {unit}")
    }
}

/// Refuses `bytes` of `what` (made by `settings`) above the limit now in force ([`limit`]): an
/// input error without a location, for the caller to place (the field or file whose settings
/// make the estimate). `remedy` says how to bring it under the limit.
pub fn check(bytes: f64, what: &str, settings: &str, remedy: &str) -> Result<(), Error> {
    check_within(limit(), bytes, what, settings, remedy)
}

/// [`check`] against an explicit limit (None: no limit).
pub fn check_within(
    limit: Option<f64>,
    bytes: f64,
    what: &str,
    settings: &str,
    remedy: &str,
) -> Result<(), Error> {
    let Some(max) = limit else { return Ok(()) };
    // NaN counts as over the limit.
    if bytes <= max {
        return Ok(());
    }
    Err(Error::input(format!(
        "{what} would take about {} of memory ({settings}), above the limit of {}: {remedy}, \
         or pass `allow_large` to proceed anyway",
        bytes_text(bytes),
        bytes_text(max)
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimates_above_the_limit_are_refused_with_their_settings() {
        assert!(check_within(Some(1e9), 9.9e8, "x", "y", "z").is_ok());
        assert!(check_within(None, 1e30, "x", "y", "z").is_ok());
        let e =
            check_within(Some(1e9), 3.84e9, "the tables", "5400 bins", "widen them").unwrap_err();
        let s = e.to_string();
        assert!(e.is_user_error());
        assert!(
            s.contains("3.84 GB") && s.contains("5400 bins") && s.contains("1.00 GB"),
            "{s}"
        );
        assert!(
            s.contains("widen them") && s.contains("`allow_large`"),
            "{s}"
        );
        assert!(check_within(Some(1e9), f64::NAN, "x", "y", "z").is_err());
        assert_eq!(bytes_text(512.0), "512 bytes");
        assert_eq!(bytes_text(MAX_MEMORY_BYTES), "2.00 GB");
        assert_eq!(bytes_text(37_249.0 * 8.0), "297.99 kB");
    }
}
