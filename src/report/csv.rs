//! CSV tables as RFC 4180 describes them: records end with CRLF, and a field is enclosed in
//! double quotes (with inner quotes doubled) exactly when it contains a comma, a double quote,
//! a carriage return or a line feed. Python's `csv` module and pandas read this back unchanged.

use std::path::Path;

use super::npy::write_atomic;
use crate::error::{Error, Result};

/// One field, quoted if RFC 4180 requires it.
pub fn quote_field(field: &str) -> String {
    if field.contains([',', '"', '\r', '\n']) {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_string()
    }
}

/// The text of a table: a header record, then one record per row.
pub fn encode_csv(header: &[&str], rows: &[Vec<String>]) -> std::result::Result<String, String> {
    if header.is_empty() {
        return Err("a CSV table needs at least one column".into());
    }
    let mut out = String::new();
    let mut push = |fields: &mut dyn Iterator<Item = &str>| {
        let line: Vec<String> = fields.map(quote_field).collect();
        out.push_str(&line.join(","));
        out.push_str("\r\n");
    };
    push(&mut header.iter().copied());
    for (i, row) in rows.iter().enumerate() {
        if row.len() != header.len() {
            return Err(format!(
                "CSV row {} has {} fields but the header has {}",
                i + 1,
                row.len(),
                header.len()
            ));
        }
        push(&mut row.iter().map(String::as_str));
    }
    Ok(out)
}

/// Writes a CSV table (RFC 4180 quoting, CRLF record ends) through a temporary name.
pub fn write_csv(path: &Path, header: &[&str], rows: &[Vec<String>]) -> Result<()> {
    let text = encode_csv(header, rows).map_err(|m| Error::input(m).in_file(path))?;
    write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_commas_quotes_and_newlines() {
        assert_eq!(quote_field("plain text"), "plain text");
        assert_eq!(quote_field("a,b"), "\"a,b\"");
        assert_eq!(quote_field("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(quote_field("two\nlines"), "\"two\nlines\"");
        assert_eq!(quote_field("cr\rhere"), "\"cr\rhere\"");
        assert_eq!(quote_field(""), "");
        let text = encode_csv(
            &["scheme", "psnr_db"],
            &[
                vec!["SCB, balanced".into(), "24.1".into()],
                vec!["\"quoted\"\nname".into(), "NaN".into()],
            ],
        )
        .unwrap();
        assert_eq!(
            text,
            "scheme,psnr_db\r\n\"SCB, balanced\",24.1\r\n\"\"\"quoted\"\"\nname\",NaN\r\n"
        );
    }

    #[test]
    fn writes_file_and_rejects_ragged_rows() {
        let dir = std::env::temp_dir().join(format!("spibench-csv-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        write_csv(&path, &["a", "b"], &[vec!["1".into(), "x,y".into()]]).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "a,b\r\n1,\"x,y\"\r\n"
        );
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
