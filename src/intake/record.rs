//! Oscilloscope records read from files: the CSV exports of the common bench scopes, streamed
//! line by line into one float64 column per channel (a 10⁷-sample, 4-channel CSV is never held
//! as text: memory is the record's binary size), and `.npy` with its JSON sidecar.
//!
//! The header tells the layout (docs/scope-records.md):
//!
//! - **Tektronix** (MSO 4/5/6, MDO, TBS): `key,value…` lines (`Sample Interval`, `Record Length`,
//!   `Zero Index`, `Vertical Scale`, `Vertical Offset`, `Label`), then `TIME,CH1,…` and rows of
//!   time and values;
//! - **Keysight** (InfiniiVision): `x-axis,1,2,…`, then `second,Volt,…`, then rows;
//! - **Rigol** (DS1000Z, MSO5000 memory): `X,CH1,…,Start,Increment,`, then
//!   `Sequence,Volt,…,START,INCREMENT`, then rows of index and values; or `Time(s),CH1(V),…`
//!   (a screen export), rows of time and values.
//!
//! A UTF-8 byte-order mark and CRLF line ends are read as plain text. An empty cell, a value
//! that is not a finite number, a row with too few cells, and a last line cut short are input
//! errors naming the file and the line.

use std::io::BufRead;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// A record's CSV layout, told by its header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    Tektronix,
    Keysight,
    Rigol,
    Npy,
}

/// One channel's screen: the volts that the ADC's codes span (from the header, when it says).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Screen {
    pub volts_per_div: f64,
    pub offset_v: f64,
}

impl Screen {
    /// [low, high] of the 10 divisions.
    pub fn window(&self) -> (f64, f64) {
        let half = 5.0 * self.volts_per_div;
        (self.offset_v - half, self.offset_v + half)
    }
}

/// A record read from a file: one column of samples per channel.
#[derive(Debug, Clone)]
pub struct ScopeRecord {
    pub path: PathBuf,
    pub layout: Layout,
    pub sample_interval_s: f64,
    /// Column names as the file gives them (`CH1`, `1` → `CH1`).
    pub columns: Vec<String>,
    /// Channel labels (Tektronix `Label` line, `.npy` sidecar), when given.
    pub labels: Vec<Option<String>>,
    /// Each channel's screen, when the header gives it.
    pub screens: Vec<Option<Screen>>,
    pub data: Vec<Vec<f64>>,
    /// The sample at the trigger (time 0), when the header says.
    pub trigger_index: Option<u64>,
}

impl ScopeRecord {
    pub fn samples(&self) -> usize {
        self.data.first().map_or(0, Vec::len)
    }

    /// The index of the channel called `name` (a column name or a label, case-insensitive).
    pub fn channel(&self, name: &str) -> Option<usize> {
        let is = |s: &str| s.eq_ignore_ascii_case(name);
        self.labels
            .iter()
            .position(|l| l.as_deref().is_some_and(is))
            .or_else(|| self.columns.iter().position(|c| is(c)))
    }

    /// The channels' names for a message: `CH1 (RF), CH2, …`.
    pub fn names(&self) -> String {
        self.columns
            .iter()
            .zip(&self.labels)
            .map(|(c, l)| match l {
                Some(l) if !l.is_empty() => format!("{c} ({l})"),
                _ => c.clone(),
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A column name as the layouts spell channels: Keysight's `1` is `CH1`; Rigol's `CH1(V)`
/// loses its unit.
fn column_name(cell: &str) -> String {
    let c = cell.trim();
    let c = c.split_once('(').map_or(c, |(name, _)| name).trim();
    if !c.is_empty() && c.bytes().all(|b| b.is_ascii_digit()) {
        format!("CH{c}")
    } else {
        c.to_string()
    }
}

fn located(path: &Path, line: usize, message: impl Into<String>) -> Error {
    Error::input(message).in_file(path).at_line(line, 1)
}

/// The lines of a file, one at a time in one buffer: the line's text without its line end
/// (and without a leading byte-order mark), its 1-based number, and whether it ended in a
/// line feed.
struct Lines<R> {
    reader: R,
    buf: String,
    number: usize,
    path: PathBuf,
}

impl<R: BufRead> Lines<R> {
    fn next(&mut self) -> Result<Option<(&str, usize, bool)>> {
        self.buf.clear();
        let n = self
            .reader
            .read_line(&mut self.buf)
            .map_err(|e| match e.kind() {
                std::io::ErrorKind::InvalidData => located(
                    &self.path,
                    self.number + 1,
                    "not UTF-8 text: a CSV export is expected",
                ),
                _ => Error::read(&self.path, e),
            })?;
        if n == 0 {
            return Ok(None);
        }
        self.number += 1;
        let ended = self.buf.ends_with('\n');
        let mut s = self.buf.trim_end_matches(['\n', '\r']);
        if self.number == 1 {
            s = s.trim_start_matches('\u{feff}');
        }
        Ok(Some((s, self.number, ended)))
    }
}

/// How a layout's data rows read: the cells that hold time or index, the channels after them.
#[derive(Debug, Clone)]
struct RowShape {
    lead: usize,
    channels: usize,
    /// Rigol's rows may end in an empty cell (the header's trailing comma).
    trailing_empty: bool,
}

/// What the header said.
#[derive(Debug, Clone, Default)]
struct HeaderInfo {
    sample_interval_s: Option<f64>,
    record_length: Option<u64>,
    trigger_index: Option<u64>,
    columns: Vec<String>,
    labels: Vec<Option<String>>,
    screens: Vec<Option<Screen>>,
    /// Rigol's start time and increment.
    start_s: Option<f64>,
}

fn cells(line: &str) -> Vec<&str> {
    line.split(',').map(str::trim).collect()
}

fn number(path: &Path, line: usize, cell: &str, what: &str) -> Result<f64> {
    match cell.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(located(
            path,
            line,
            format!("{what} {cell:?} is not a finite number"),
        )),
    }
}

/// Reads the header of a CSV export up to its column line; returns the layout, what it said
/// and the shape of its rows.
fn read_header<R: BufRead>(lines: &mut Lines<R>) -> Result<(Layout, HeaderInfo, RowShape)> {
    let path = lines.path.clone();
    let mut info = HeaderInfo::default();
    let mut keys: Vec<(String, Vec<String>)> = Vec::new();
    let mut layout = None;
    while let Some((text, no, _)) = lines.next()? {
        let c = cells(text);
        let first = c[0].to_ascii_lowercase();
        if no == 1 && first == "x-axis" {
            // Keysight: channel names, then units.
            info.columns = c[1..].iter().map(|s| column_name(s)).collect();
            if lines.next()?.is_none() {
                return Err(located(
                    &path,
                    2,
                    "a Keysight export ends after its first line",
                ));
            }
            layout = Some(Layout::Keysight);
            break;
        }
        if no == 1 && first == "x" && c.iter().any(|s| s.eq_ignore_ascii_case("increment")) {
            // Rigol: X,CH1,…,Start,Increment, then Sequence,Volt,…,start,increment.
            let start = c
                .iter()
                .position(|s| s.eq_ignore_ascii_case("start"))
                .unwrap_or(c.len());
            info.columns = c[1..start].iter().map(|s| column_name(s)).collect();
            let Some((units, no2, _)) = lines.next()? else {
                return Err(located(
                    &path,
                    2,
                    "a Rigol export ends after its first line",
                ));
            };
            let u = cells(units);
            let (s, i) = (u.get(start), u.get(start + 1));
            let (Some(s), Some(i)) = (s, i) else {
                return Err(located(
                    &path,
                    no2,
                    "the Rigol start and increment are missing",
                ));
            };
            info.start_s = Some(number(&path, no2, s, "the start time")?);
            info.sample_interval_s = Some(number(&path, no2, i, "the increment")?);
            layout = Some(Layout::Rigol);
            break;
        }
        if no == 1 && first.starts_with("time(") {
            // Rigol screen export.
            info.columns = c[1..].iter().map(|s| column_name(s)).collect();
            layout = Some(Layout::Rigol);
            break;
        }
        if first == "time" {
            info.columns = c[1..].iter().map(|s| column_name(s)).collect();
            layout = Some(Layout::Tektronix);
            break;
        }
        if no == 1 && first != "model" && !first.is_empty() && !text.contains(',') {
            break;
        }
        keys.push((
            c[0].to_string(),
            c[1..].iter().map(|s| s.to_string()).collect(),
        ));
        if no > 64 {
            break;
        }
    }
    let Some(layout) = layout else {
        return Err(located(
            &path,
            1,
            "unknown CSV layout: the header is neither a Tektronix export (Model,… then \
             TIME,CH1,…), a Keysight one (x-axis,1,…), nor a Rigol one (X,CH1,…,Start,Increment \
             or Time(s),CH1(V),…)",
        ));
    };
    let n = info.columns.len();
    for (key, values) in &keys {
        let first = values.first().map(String::as_str).unwrap_or("");
        let per_channel = |f: &dyn Fn(&str) -> Option<f64>| -> Vec<Option<f64>> {
            (0..n).map(|o| values.get(o).and_then(|v| f(v))).collect()
        };
        match key.to_ascii_lowercase().as_str() {
            "sample interval" => info.sample_interval_s = first.parse().ok(),
            "record length" => info.record_length = first.parse::<f64>().ok().map(|v| v as u64),
            "zero index" => info.trigger_index = first.parse::<f64>().ok().map(|v| v as u64),
            "label" => {
                info.labels = (0..n)
                    .map(|o| values.get(o).filter(|v| !v.is_empty()).cloned())
                    .collect()
            }
            "vertical scale" => {
                let scale = per_channel(&|v| v.parse().ok());
                info.screens = scale
                    .into_iter()
                    .map(|s| {
                        s.map(|volts_per_div| Screen {
                            volts_per_div,
                            offset_v: 0.0,
                        })
                    })
                    .collect();
            }
            _ => {}
        }
    }
    // Offsets after scales, whatever the order of the lines.
    for (key, values) in &keys {
        if key.eq_ignore_ascii_case("vertical offset") {
            for (o, s) in info.screens.iter_mut().enumerate() {
                if let (Some(s), Some(v)) = (s, values.get(o).and_then(|v| v.parse().ok())) {
                    s.offset_v = v;
                }
            }
        }
    }
    if n == 0 {
        return Err(located(
            &path,
            lines.number,
            "the column line names no channel",
        ));
    }
    let shape = RowShape {
        lead: 1,
        channels: n,
        trailing_empty: layout == Layout::Rigol,
    };
    Ok((layout, info, shape))
}

/// Reads a CSV export (streamed: one line in memory at a time).
pub fn read_csv(path: &Path) -> Result<ScopeRecord> {
    let file = std::fs::File::open(path).map_err(|e| Error::read(path, e))?;
    let mut lines = Lines {
        reader: std::io::BufReader::with_capacity(1 << 20, file),
        buf: String::with_capacity(256),
        number: 0,
        path: path.to_path_buf(),
    };
    let (layout, info, shape) = read_header(&mut lines)?;
    let n = shape.channels;
    // The columns' memory, estimated from the header's record length when it gives one.
    let expected = info.record_length.unwrap_or(0) as usize;
    crate::memory::check(
        expected as f64 * n as f64 * 8.0,
        "a scope record's samples",
        &format!("{expected} samples × {n} channels"),
        "a shorter record",
    )?;
    let mut data: Vec<Vec<f64>> = (0..n).map(|_| Vec::with_capacity(expected)).collect();
    let (mut t_first, mut t_last) = (None, 0.0);
    while let Some((text, no, ended)) = lines.next()? {
        if text.is_empty() {
            if ended {
                continue;
            }
            break;
        }
        let mut it = text.split(',');
        let lead = it.next().unwrap_or("").trim();
        let mut got = 0;
        for (o, column) in data.iter_mut().enumerate() {
            let Some(cell) = it.next() else { break };
            let cell = cell.trim();
            if cell.is_empty() && !ended {
                return Err(located(path, no, "the last line is cut short"));
            }
            if cell.is_empty() {
                return Err(located(
                    path,
                    no,
                    format!("empty cell in column {} ({})", o + 2, info.columns[o]),
                ));
            }
            match cell.parse::<f64>() {
                Ok(v) if v.is_finite() => column.push(v),
                _ if !ended => {
                    return Err(located(path, no, "the last line is cut short"));
                }
                _ => {
                    return Err(located(
                        path,
                        no,
                        format!(
                            "{cell:?} in column {} ({}) is not a finite number",
                            o + 2,
                            info.columns[o]
                        ),
                    ));
                }
            }
            got += 1;
        }
        if got < n {
            for c in data.iter_mut().take(got) {
                c.pop();
            }
            let why = if ended {
                format!(
                    "{} cells where the header names {}",
                    got + 1,
                    n + shape.lead
                )
            } else {
                "the last line is cut short".to_string()
            };
            return Err(located(path, no, why));
        }
        if let Some(extra) = it.next()
            && !(shape.trailing_empty && extra.trim().is_empty())
        {
            return Err(located(
                path,
                no,
                format!("more cells than the {} the header names", n + shape.lead),
            ));
        }
        if !ended {
            // A complete row without its line end: a record saved whole ends in one, so the
            // file was cut here.
            return Err(located(
                path,
                no,
                "the last line is cut short (no line end)",
            ));
        }
        if layout != Layout::Rigol || info.start_s.is_none() {
            let t = number(path, no, lead, "the time")?;
            t_first.get_or_insert(t);
            t_last = t;
        }
    }
    let samples = data[0].len();
    if samples == 0 {
        return Err(located(path, lines.number, "the record holds no sample"));
    }
    if let Some(len) = info.record_length
        && len != samples as u64
    {
        return Err(located(
            path,
            lines.number,
            format!("the header's Record Length is {len}, but the file holds {samples} samples"),
        ));
    }
    let dt = match (info.sample_interval_s, t_first) {
        (Some(dt), _) => dt,
        (None, Some(t0)) if samples > 1 => (t_last - t0) / (samples - 1) as f64,
        _ => 0.0,
    };
    if !(dt.is_finite() && dt > 0.0) {
        return Err(located(
            path,
            1,
            "the record does not say its sample interval",
        ));
    }
    let trigger_index = info.trigger_index.or_else(|| {
        // Time zero from the first time (or Rigol's start), when it lies in the record.
        let t0 = info.start_s.or(t_first)?;
        let i = (-t0 / dt).round();
        (i >= 0.0 && (i as usize) < samples).then_some(i as u64)
    });
    let mut labels = info.labels;
    labels.resize(n, None);
    let mut screens = info.screens;
    screens.resize(n, None);
    Ok(ScopeRecord {
        path: path.to_path_buf(),
        layout,
        sample_interval_s: dt,
        columns: info.columns,
        labels,
        screens,
        data,
        trigger_index,
    })
}

/// The sidecar of a `.npy` record (`record.json` as `run --scope-record` writes it).
#[derive(Debug, Clone, serde::Deserialize)]
pub struct NpySidecar {
    pub sample_interval_s: f64,
    #[serde(default)]
    pub trigger_index: Option<u64>,
    pub channels: Vec<SidecarChannel>,
}

#[derive(Debug, Clone, serde::Deserialize)]
pub struct SidecarChannel {
    pub name: String,
    #[serde(default)]
    pub column: Option<String>,
    #[serde(default)]
    pub volts_per_div: Option<f64>,
    #[serde(default)]
    pub offset_v: Option<f64>,
}

/// Reads a `.npy` record (float64 or float32, samples × channels) with its JSON sidecar (the
/// same name with `.json`).
pub fn read_npy(path: &Path) -> Result<ScopeRecord> {
    let side_path = path.with_extension("json");
    let text = std::fs::read_to_string(&side_path).map_err(|e| Error::read(&side_path, e))?;
    let side: NpySidecar = serde_json::from_str(&text).map_err(|e| {
        Error::input(format!("not a scope record's sidecar: {e}"))
            .in_file(&side_path)
            .at_line(e.line(), e.column())
    })?;
    let a = crate::report::npy::read_bounded(path, "a scope record", |_| (0.0, String::new()))?;
    let (samples, n) = match a.shape.as_slice() {
        [s, c] => (*s, *c),
        _ => {
            return Err(Error::input(format!(
                "a record is samples × channels, got shape {:?}",
                a.shape
            ))
            .in_file(path));
        }
    };
    if n != side.channels.len() {
        return Err(Error::input(format!(
            "{} channels in the array, {} in {}",
            n,
            side.channels.len(),
            side_path.display()
        ))
        .in_file(path));
    }
    let flat = a.to_f64();
    let mut data: Vec<Vec<f64>> = (0..n).map(|_| Vec::with_capacity(samples)).collect();
    for (i, v) in flat.iter().enumerate() {
        if !v.is_finite() {
            return Err(Error::input(format!(
                "sample {} of channel {} is not a finite number",
                i / n,
                side.channels[i % n].name
            ))
            .in_file(path));
        }
        data[i % n].push(*v);
    }
    Ok(ScopeRecord {
        path: path.to_path_buf(),
        layout: Layout::Npy,
        sample_interval_s: side.sample_interval_s,
        columns: side
            .channels
            .iter()
            .enumerate()
            .map(|(o, c)| c.column.clone().unwrap_or(format!("CH{}", o + 1)))
            .collect(),
        labels: side.channels.iter().map(|c| Some(c.name.clone())).collect(),
        screens: side
            .channels
            .iter()
            .map(|c| {
                c.volts_per_div.map(|volts_per_div| Screen {
                    volts_per_div,
                    offset_v: c.offset_v.unwrap_or(0.0),
                })
            })
            .collect(),
        data,
        trigger_index: side.trigger_index,
    })
}

/// Reads a record by its extension: `.npy` or a CSV export.
pub fn read(path: &Path) -> Result<ScopeRecord> {
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("npy") => read_npy(path),
        _ => read_csv(path),
    }
}

#[cfg(test)]
mod tests;
