//! The summary card every command's report and terminal output opens with: the few numbers a
//! reader looks for first, each line built from the values of the command's `summary.json`
//! and naming them (JSON pointers), so that a test can check that the card shows what the file
//! holds.

use serde_json::Value;

use crate::report::html::Block;

/// One line of a card: what it shows, its text, and the `summary.json` values it is made from
/// (a JSON pointer and the value found there).
#[derive(Debug, Clone, PartialEq)]
pub struct CardLine {
    pub label: String,
    pub text: String,
    pub sources: Vec<(String, Value)>,
}

/// A summary card: a title and its lines.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Card {
    pub title: String,
    pub lines: Vec<CardLine>,
}

impl Card {
    /// A card titled `title` that reads its values from `summary` (a command's summary.json as
    /// a value).
    pub fn new(title: impl Into<String>) -> Card {
        Card {
            title: title.into(),
            lines: Vec::new(),
        }
    }

    /// Adds a line whose text `text` makes from the values at `pointers` in `summary` (null
    /// where a pointer finds nothing).
    pub fn line(
        &mut self,
        summary: &Value,
        label: impl Into<String>,
        pointers: &[impl AsRef<str>],
        text: impl FnOnce(&[Value]) -> String,
    ) {
        let values: Vec<Value> = pointers
            .iter()
            .map(|p| summary.pointer(p.as_ref()).cloned().unwrap_or(Value::Null))
            .collect();
        self.lines.push(CardLine {
            label: label.into(),
            text: text(&values),
            sources: pointers
                .iter()
                .map(|p| p.as_ref().to_string())
                .zip(values)
                .collect(),
        });
    }

    /// The card as printed lines: its title, then one "label: text" line each, aligned.
    pub fn printed(&self) -> Vec<String> {
        let w = self
            .lines
            .iter()
            .map(|l| l.label.chars().count())
            .max()
            .unwrap_or(0);
        let mut out = vec![format!("{}:", self.title)];
        for l in &self.lines {
            let pad = w - l.label.chars().count();
            let head = format!("  {}{} ", l.label, " ".repeat(pad));
            let indent = " ".repeat(head.chars().count());
            let mut first = true;
            for part in wrap(&l.text, PRINTED_WIDTH.saturating_sub(w + 3).max(40)) {
                out.push(format!("{}{part}", if first { &head } else { &indent }));
                first = false;
            }
        }
        out
    }

    /// The card as the report's first block.
    pub fn block(&self) -> Block {
        Block::Card {
            title: self.title.clone(),
            rows: self
                .lines
                .iter()
                .map(|l| (l.label.clone(), l.text.clone()))
                .collect(),
        }
    }

    /// Checks every line's sources against `file` (the summary.json written): the first
    /// difference, as text.
    pub fn check_against(&self, file: &Value) -> std::result::Result<(), String> {
        for l in &self.lines {
            for (p, v) in &l.sources {
                let got = file.pointer(p).cloned().unwrap_or(Value::Null);
                if &got != v {
                    return Err(format!(
                        "{}: {p} is {got} in the file, {v} on the card",
                        l.label
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The widest printed line of a card (terminals of 100 columns).
pub const PRINTED_WIDTH: usize = 100;

/// `text` in lines of at most `width` characters, broken at spaces (a word longer than the
/// width stands alone on its line).
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split(' ') {
        let len = line.chars().count();
        if len > 0 && len + 1 + word.chars().count() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    lines.push(line);
    lines
}

/// The length of the array at `pointer` in `summary` (0 where there is none).
pub fn array_len(summary: &Value, pointer: &str) -> usize {
    summary
        .pointer(pointer)
        .and_then(Value::as_array)
        .map_or(0, Vec::len)
}

/// A number of a card from a JSON value (NaN for null or a non-number).
pub fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// `value ± stderr` with the standard error to two significant digits and the value to the
/// same place: decimals for magnitudes from 10⁻³ to 10⁴, else in scientific notation; the
/// value alone without a finite standard error; "–" for a missing value.
pub fn pm(value: f64, stderr: f64, unit: &str) -> String {
    if !value.is_finite() {
        return "–".into();
    }
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    let plain = value == 0.0 || (1e-3..1e4).contains(&value.abs());
    if !(stderr.is_finite() && stderr > 0.0) {
        return if plain {
            format!("{}{unit}", sig(value, 4))
        } else {
            format!("{value:.4e}{unit}")
        };
    }
    let place = stderr.log10().floor() as i32 - 1;
    if plain && place < 0 {
        let d = (-place) as usize;
        format!("{value:.d$} ± {stderr:.d$}{unit}")
    } else if plain {
        format!("{value:.0} ± {stderr:.0}{unit}")
    } else {
        let e = value.abs().log10().floor() as i32;
        let d = (e - place).clamp(0, 12) as usize;
        format!("{value:.d$e} ± {stderr:.1e}{unit}")
    }
}

/// `v` to `digits` significant digits in decimals (for magnitudes from 10⁻³ to 10⁴).
pub fn sig(v: f64, digits: i32) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let d = (digits - 1 - v.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let s = format!("{v:.d$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_with_their_errors() {
        assert_eq!(pm(0.3536124, 0.000132, "A/W"), "0.35361 ± 0.00013 A/W");
        assert_eq!(pm(7.7047e-9, 1.248e-11, "A"), "7.705e-9 ± 1.2e-11 A");
        assert_eq!(pm(30.11, 0.57, "dB"), "30.11 ± 0.57 dB");
        assert_eq!(pm(f64::NAN, 1.0, ""), "–");
        assert_eq!(pm(4.1465e-4, 7.29e-5, ""), "4.15e-4 ± 7.3e-5");
    }

    #[test]
    fn lines_name_the_values_they_show() {
        let summary = serde_json::json!({"a": {"k": 0.5, "k_stderr": 0.01}, "n": 3});
        let mut c = Card::new("summary");
        c.line(&summary, "k", &["/a/k", "/a/k_stderr"], |v| {
            pm(num(&v[0]), num(&v[1]), "A/W")
        });
        c.line(&summary, "count", &["/n"], |v| format!("{}", v[0]));
        assert_eq!(
            c.printed(),
            vec!["summary:", "  k     0.500 ± 0.010 A/W", "  count 3"]
        );
        assert!(c.check_against(&summary).is_ok());
        // A long text wraps under itself within 100 columns.
        let mut long = Card::new("summary");
        long.line(&summary, "k", &[] as &[&str], |_| {
            "word ".repeat(40).trim().to_string()
        });
        let lines = long.printed();
        assert!(lines.len() > 2 && lines.iter().all(|l| l.chars().count() <= PRINTED_WIDTH));
        assert!(lines[2].starts_with("    word"), "{lines:?}");
        let other = serde_json::json!({"a": {"k": 0.6, "k_stderr": 0.01}, "n": 3});
        assert!(c.check_against(&other).unwrap_err().contains("/a/k"));
    }
}
