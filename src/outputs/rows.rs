//! One row of a traced bench's metrics, with one key naming scheme for `sweep` (its rows and
//! `sweep.csv`), `tolerance` (its nominal bench, trial rows, `trials.csv`) and `align` (its
//! start and aligned benches); docs/outputs.md, "Metric rows".
//!
//! For each metric M of `quantities::BenchMetric` (unit: `BenchMetric::unit`): `M`,
//! `M_stderr`, `M_diff` (against the reference bench: the nominal bench, or align's start),
//! `M_diff_stderr` (paired: common random numbers) and `M_diff_stderr_independent` (what two
//! independent traces would give); then the same five for `cmrr_db` (the bench's, with the
//! optics), `cmrr_electronics_db`, `arrivals` and, with the whole pipeline, `SCHEME_PCT_mssim`, `SCHEME_PCT_psnr_db` and
//! `SCHEME_PCT_finest_lp_per_mm`. The numbers are those of `crate::tolerance::values` (which
//! the tolerance records store), so every command computes them one way.

use serde::ser::{Serialize, SerializeMap, Serializer};

use crate::pipeline::evaluate::Evaluation;

/// Named numbers in their order; serialised as a JSON object (NaN and ±∞ as null).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Row(pub Vec<(String, f64)>);

impl Row {
    /// The metrics of `p` against `reference` (traced with the same seed).
    pub fn metrics(p: &Evaluation, reference: &Evaluation) -> Row {
        Row::from_values(
            &crate::tolerance::values(p, reference),
            &crate::tolerance::values(reference, reference),
        )
    }

    /// A row from recorded `values` (as `crate::tolerance::values` makes them) and those of the
    /// reference bench, which give each metric's independent standard error of the difference.
    pub fn from_values(values: &[(String, f64)], reference: &[(String, f64)]) -> Row {
        let get = |v: &[(String, f64)], k: &str| v.iter().find(|(n, _)| n == k).map(|e| e.1);
        let mut row = Vec::with_capacity(values.len() * 5 / 4);
        for (k, v) in values {
            row.push((k.clone(), *v));
            let Some(m) = k.strip_suffix("_diff_stderr") else {
                continue;
            };
            let stderr = format!("{m}_stderr");
            if let (Some(a), Some(b)) = (get(values, &stderr), get(reference, &stderr)) {
                row.push((format!("{m}_diff_stderr_independent"), a.hypot(b)));
            }
        }
        Row(row)
    }

    /// Prepends named values (a sweep point's varied variables).
    pub fn with_settings(mut self, settings: &[(String, f64)]) -> Row {
        let mut v = settings.to_vec();
        v.append(&mut self.0);
        self.0 = v;
        self
    }

    pub fn keys(&self) -> impl Iterator<Item = &str> {
        self.0.iter().map(|(k, _)| k.as_str())
    }

    pub fn get(&self, key: &str) -> Option<f64> {
        self.0.iter().find(|(k, _)| k == key).map(|e| e.1)
    }

    /// The CSV cells under `header`: each number as JSON writes it, empty where the row has no
    /// such key or the number is not finite.
    pub fn csv_cells(&self, header: &[String]) -> Vec<String> {
        header
            .iter()
            .map(|k| match self.get(k) {
                Some(v) if is_count(k, v) => format!("{}", v as u64),
                Some(v) => csv_number(v),
                None => String::new(),
            })
            .collect()
    }
}

/// Whether `key` holds a count (written as a whole number, not as a float).
fn is_count(key: &str, v: f64) -> bool {
    key == "arrivals" && v >= 0.0 && v.fract() == 0.0 && v < 2f64.powi(53)
}

/// A number as JSON writes it (shortest round-trip form); empty for NaN and ±∞.
pub fn csv_number(v: f64) -> String {
    serde_json::Number::from_f64(v).map_or_else(String::new, |n| n.to_string())
}

impl Serialize for Row {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            if is_count(k, *v) {
                m.serialize_entry(k, &(*v as u64))?;
                continue;
            }
            match serde_json::Number::from_f64(*v) {
                Some(n) => m.serialize_entry(k, &n)?,
                None => m.serialize_entry(k, &Option::<f64>::None)?,
            }
        }
        m.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn independent_errors_follow_each_paired_one() {
        let v = |pairs: &[(&str, f64)]| -> Vec<(String, f64)> {
            pairs.iter().map(|(k, x)| (k.to_string(), *x)).collect()
        };
        let point = v(&[
            ("k_plus", 1.0),
            ("k_plus_stderr", 3.0),
            ("k_plus_diff", 0.5),
            ("k_plus_diff_stderr", 0.1),
            ("cmrr_db", f64::NAN),
            ("cmrr_db_diff_stderr", 0.0),
        ]);
        let nominal = v(&[("k_plus_stderr", 4.0)]);
        let row = Row::from_values(&point, &nominal).with_settings(&v(&[("a.b_mm", 2.0)]));
        let keys: Vec<&str> = row.keys().collect();
        assert_eq!(
            keys,
            [
                "a.b_mm",
                "k_plus",
                "k_plus_stderr",
                "k_plus_diff",
                "k_plus_diff_stderr",
                "k_plus_diff_stderr_independent",
                "cmrr_db",
                "cmrr_db_diff_stderr"
            ]
        );
        assert_eq!(row.get("k_plus_diff_stderr_independent"), Some(5.0));
        let text = serde_json::to_string(&row).unwrap();
        assert!(
            text.contains("\"cmrr_db\":null") && text.starts_with("{\"a.b_mm\":2.0"),
            "{text}"
        );
        assert_eq!(
            row.csv_cells(&["cmrr_db".into(), "k_plus".into(), "x".into()]),
            ["", "1.0", ""]
        );
    }
}
