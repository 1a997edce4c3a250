//! CSV tables written by the `csv` crate: records end with LF (as pandas, R and Python's `csv`
//! module write and read by default), a field is quoted exactly when it must be (a comma, a
//! double quote, CR or LF inside), and numbers are written in their shortest form that reads
//! back to the same `f64` (Ryū). Missing values are empty fields, so a column keeps one type.
//!
//! `results.csv` of `run` and `cells.csv` of `simulate` share one schema, [`ResultRow`], so
//! tables of many runs and simulations can be concatenated and still say where each row came
//! from.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::npy::write_atomic;
use crate::error::{Error, Result};

/// One reconstruction, the row of `results.csv` (`run`) and `cells.csv` (`simulate`).
///
/// Gains and offsets are in the units the command works in: `run` traces a bench, so k± and k′
/// are in A/W and b± in A (`gain_units` = "A/W", `offset_units` = "A"); `simulate` uses the
/// paper's idealised model in object units (`gain_units` = "1", `offset_units` = "object").
/// Empty fields: a value the command does not have (`noise` in `run`, `saturated` and the
/// resolution read-out in `simulate`, an element when none is resolved).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResultRow {
    /// `run` or `simulate`.
    pub command: String,
    /// The bench or experiment file.
    pub scene: String,
    pub seed: u64,
    /// The object reconstructed (a name from the experiment, or the chart of a bench).
    pub object: String,
    /// The case (simulate) or the run's title (run).
    pub case: String,
    /// Scheme key (`traditional`, `single_arm_complementary`, `double_arm`,
    /// `secondary_complementary_balancing`).
    pub scheme: String,
    pub ratio: f64,
    pub measurements: u64,
    pub dmd_frames: u64,
    pub detector_samples: u64,
    /// The DMD's display time for the frames (s): a physical time, not a computing time.
    pub acquisition_time_s: f64,
    pub k_plus: f64,
    pub k_minus: f64,
    pub k_prime: f64,
    pub gain_units: String,
    pub b_plus: f64,
    pub b_minus: f64,
    pub offset_units: String,
    pub noise: Option<String>,
    pub noise_std: Option<f64>,
    pub psnr_db: f64,
    pub mssim: f64,
    pub iterations: u64,
    pub converged: bool,
    pub stop: String,
    pub saturated: Option<bool>,
    pub finest_group: Option<i32>,
    pub finest_element: Option<u32>,
    pub finest_lp_per_mm: Option<f64>,
}

fn writer() -> csv::WriterBuilder {
    let mut b = csv::WriterBuilder::new();
    b.terminator(csv::Terminator::Any(b'\n'))
        .quote_style(csv::QuoteStyle::Necessary);
    b
}

fn finish(w: csv::Writer<Vec<u8>>) -> std::result::Result<Vec<u8>, String> {
    w.into_inner().map_err(|e| e.to_string())
}

/// The text of a table of serde rows (header from the field names); `header` is written
/// when there is no row, so an empty table still names its columns.
pub fn encode_rows<T: Serialize>(
    header: &[&str],
    rows: &[T],
) -> std::result::Result<Vec<u8>, String> {
    let mut w = writer()
        .has_headers(!rows.is_empty())
        .from_writer(Vec::new());
    if rows.is_empty() {
        w.write_record(header).map_err(|e| e.to_string())?;
    }
    for r in rows {
        w.serialize(r).map_err(|e| e.to_string())?;
    }
    finish(w)
}

/// The columns of [`ResultRow`], in order.
pub const RESULT_COLUMNS: [&str; 29] = [
    "command",
    "scene",
    "seed",
    "object",
    "case",
    "scheme",
    "ratio",
    "measurements",
    "dmd_frames",
    "detector_samples",
    "acquisition_time_s",
    "k_plus",
    "k_minus",
    "k_prime",
    "gain_units",
    "b_plus",
    "b_minus",
    "offset_units",
    "noise",
    "noise_std",
    "psnr_db",
    "mssim",
    "iterations",
    "converged",
    "stop",
    "saturated",
    "finest_group",
    "finest_element",
    "finest_lp_per_mm",
];

/// Writes `results.csv` / `cells.csv` rows through a temporary name.
pub fn write_results(path: &Path, rows: &[ResultRow]) -> Result<()> {
    let bytes = encode_rows(&RESULT_COLUMNS, rows).map_err(|m| Error::input(m).in_file(path))?;
    write_atomic(path, &bytes)
}

/// Reads a `results.csv` / `cells.csv` back into rows.
pub fn read_results(path: &Path) -> Result<Vec<ResultRow>> {
    let mut r = csv::ReaderBuilder::new()
        .from_path(path)
        .map_err(|e| Error::read(path, std::io::Error::other(e.to_string())))?;
    r.deserialize()
        .map(|row| row.map_err(|e| Error::input(format!("bad CSV row: {e}")).in_file(path)))
        .collect()
}

/// The text of a table of string fields: a header record, then one record per row.
pub fn encode_csv(header: &[&str], rows: &[Vec<String>]) -> std::result::Result<String, String> {
    if header.is_empty() {
        return Err("a CSV table needs at least one column".into());
    }
    let mut w = writer().from_writer(Vec::new());
    w.write_record(header).map_err(|e| e.to_string())?;
    for (i, row) in rows.iter().enumerate() {
        if row.len() != header.len() {
            return Err(format!(
                "CSV row {} has {} fields but the header has {}",
                i + 1,
                row.len(),
                header.len()
            ));
        }
        w.write_record(row).map_err(|e| e.to_string())?;
    }
    String::from_utf8(finish(w)?).map_err(|e| e.to_string())
}

/// Writes a CSV table of string fields (LF record ends) through a temporary name.
pub fn write_csv(path: &Path, header: &[&str], rows: &[Vec<String>]) -> Result<()> {
    let text = encode_csv(header, rows).map_err(|m| Error::input(m).in_file(path))?;
    write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_commas_quotes_and_newlines() {
        let text = encode_csv(
            &["scheme", "psnr_db"],
            &[
                vec!["SCB, balanced".into(), "24.1".into()],
                vec!["\"quoted\"\nname".into(), "NaN".into()],
                vec!["".into(), "cr\rhere".into()],
            ],
        )
        .unwrap();
        assert_eq!(
            text,
            "scheme,psnr_db\n\"SCB, balanced\",24.1\n\"\"\"quoted\"\"\nname\",NaN\n,\"cr\rhere\"\n"
        );
    }

    fn row(i: u32) -> ResultRow {
        ResultRow {
            command: "run".into(),
            scene: "scenes/paper, \"bench\".ron".into(),
            seed: 7,
            object: "USAF 1951".into(),
            case: "spibench run".into(),
            scheme: "double_arm".into(),
            ratio: 0.1 * i as f64,
            measurements: 230,
            dmd_frames: 460,
            detector_samples: 920,
            acquisition_time_s: 0.02024,
            k_plus: 0.35313,
            k_minus: 0.3312e-1,
            k_prime: 1.0 / 3.0,
            gain_units: "A/W".into(),
            b_plus: 4.2e-9,
            b_minus: -0.0,
            offset_units: "A".into(),
            noise: if i == 0 {
                None
            } else {
                Some("Gaussian".into())
            },
            noise_std: if i == 0 { None } else { Some(0.5) },
            psnr_db: f64::NAN,
            mssim: 0.812345678901,
            iterations: 31,
            converged: i == 0,
            stop: "Tolerance".into(),
            saturated: if i == 0 { None } else { Some(false) },
            finest_group: if i == 0 { None } else { Some(-1) },
            finest_element: Some(3),
            finest_lp_per_mm: if i == 0 { None } else { Some(0.561231) },
        }
    }

    /// The results table uses LF only and parses back to the same values (NaN as NaN, empty
    /// fields as missing), with every column's type the same in every row.
    #[test]
    fn results_are_lf_and_parse_back() {
        let dir = std::env::temp_dir().join(format!("spibench-csv-rows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("results.csv");
        let rows = vec![row(0), row(1), row(2)];
        write_results(&path, &rows).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(!bytes.contains(&b'\r'), "CR in the file");
        assert_eq!(bytes.iter().filter(|&&b| b == b'\n').count(), 4);
        let text = String::from_utf8(bytes).unwrap();
        assert_eq!(text.lines().next().unwrap(), RESULT_COLUMNS.join(","));
        let back = read_results(&path).unwrap();
        assert_eq!(back.len(), rows.len());
        for (a, b) in back.iter().zip(&rows) {
            assert!(a.psnr_db.is_nan());
            let (mut a, mut b) = (a.clone(), b.clone());
            a.psnr_db = 0.0;
            b.psnr_db = 0.0;
            assert_eq!(a, b);
        }
        // An empty table still names its columns.
        write_results(&path, &[]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, RESULT_COLUMNS.join(",") + "\n");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn writes_file_and_rejects_ragged_rows() {
        let dir = std::env::temp_dir().join(format!("spibench-csv-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        write_csv(&path, &["a", "b"], &[vec!["1".into(), "x,y".into()]]).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n1,\"x,y\"\n");
        let bad = dir.join("ragged.csv");
        let e = write_csv(&bad, &["a", "b"], &[vec!["1".into()]]).unwrap_err();
        assert!(e.is_user_error());
        assert!(
            e.to_string().contains("ragged.csv") && e.to_string().contains("row 1"),
            "{e}"
        );
        assert!(!bad.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
