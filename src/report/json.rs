//! JSON output (`summary.json` and friends): pretty-printed, ending with a newline, written
//! through a temporary name.
//!
//! Non-finite numbers: JSON has no NaN or infinity. serde_json writes a non-finite `f64`/`f32`
//! as `null`, which keeps every file valid JSON; a reader sees "no value". We rely on that and
//! test it, and [`finite_or_null`] makes the choice explicit in a summary struct's type
//! (`Option<f64>` serialises `None` as `null` too), so readers of the code see it. A quantity
//! that is legitimately infinite should be reported under a separate flag, not as a number.

use std::path::Path;

use serde::Serialize;

use super::npy::write_atomic;
use crate::error::{Error, Result};

/// `Some(v)` for a finite value, `None` (written as JSON `null`) for NaN and ±∞.
pub fn finite_or_null(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// The pretty JSON text of `value`, with a trailing newline.
pub fn to_json_string<T: Serialize>(value: &T) -> std::result::Result<String, serde_json::Error> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    Ok(text)
}

/// Writes `value` as pretty JSON; NaN and ±∞ become `null` (see the module notes).
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = to_json_string(value).map_err(|e| {
        Error::write(
            path,
            std::io::Error::other(format!("cannot encode as JSON: {e}")),
        )
    })?;
    write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    #[derive(Serialize)]
    struct Summary {
        psnr_db: f64,
        gain: f32,
        ratio: Option<f64>,
        values: Vec<f64>,
        name: String,
    }

    #[test]
    fn non_finite_numbers_give_valid_json_with_nulls() {
        let dir = std::env::temp_dir().join(format!("spibench-json-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("summary.json");
        let s = Summary {
            psnr_db: f64::INFINITY,
            gain: f32::NAN,
            ratio: finite_or_null(f64::NAN),
            values: vec![1.5, f64::NEG_INFINITY, f64::NAN, -0.25],
            name: "quote \" and \n newline".into(),
        };
        write_json(&path, &s).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.ends_with("}\n"));
        let v: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
        assert!(v["psnr_db"].is_null());
        assert!(v["gain"].is_null());
        assert!(v["ratio"].is_null());
        assert_eq!(v["values"], serde_json::json!([1.5, null, null, -0.25]));
        assert_eq!(v["name"], "quote \" and \n newline");
        assert_eq!(finite_or_null(2.5), Some(2.5));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn unencodable_value_is_a_write_error() {
        // JSON object keys must be strings; a map keyed by a tuple cannot be encoded.
        let mut m = HashMap::new();
        m.insert((1, 2), 3);
        let path = std::env::temp_dir().join("spibench-json-never-written.json");
        let e = write_json(&path, &m).unwrap_err();
        assert!(
            e.to_string().contains("spibench-json-never-written.json"),
            "{e}"
        );
        assert!(!path.exists());
    }
}
