//! The measurements a fit reads: an `intake` output folder (docs/outputs.md, "intake"): its
//! `summary.json` (units, base patterns, each record's sequence and the SHA-256 of the frames
//! its DMD showed) and `frames.csv` (every frame's [RF, MONITOR+, MONITOR−] values and flags).
//!
//! The frame-to-frame noise of each channel is measured on the calibrated sequence's preamble:
//! its all-on and all-off frames repeat one pattern each, so their scatter about each level's
//! mean is the noise of one frame value (the pooled sample variance of the two levels, 2·(n − 1)
//! degrees of freedom). A fit therefore needs that sequence among the records.

use std::path::{Path, PathBuf};

use crate::acquisition::Sequence;
use crate::acquisition::schemes::CALIBRATION_PAIRS;
use crate::error::{Error, Result};

/// One recorded sequence of the measured folder.
#[derive(Debug, Clone)]
pub struct MeasuredSequence {
    pub sequence: Sequence,
    /// [RF, MONITOR+, MONITOR−] of every frame (V).
    pub values: Vec<[f64; 3]>,
    /// Each frame's start in its record (s, from the trigger): where the slow processes of
    /// the record (the room light's flicker) are in their cycle.
    pub start_s: Vec<f64>,
    /// A frame intake flagged (clipped, irregular period, missing pulse): left out of the fit.
    pub flagged: Vec<bool>,
    pub patterns_sha256: String,
}

/// An intake folder read for a fit.
#[derive(Debug, Clone)]
pub struct Measured {
    pub dir: PathBuf,
    pub units: (usize, usize),
    pub base_patterns: usize,
    pub sequences: Vec<MeasuredSequence>,
    /// Each channel's frame-to-frame standard deviation [RF, MONITOR+, MONITOR−] (V).
    pub noise_v: [f64; 3],
    /// Its degrees of freedom.
    pub noise_dof: usize,
}

impl Measured {
    /// Frames the fit uses (not flagged).
    pub fn used_frames(&self) -> usize {
        self.sequences
            .iter()
            .map(|s| s.flagged.iter().filter(|f| !**f).count())
            .sum()
    }
}

#[derive(serde::Deserialize)]
struct SummaryFile {
    command: String,
    units_across: usize,
    units_down: usize,
    base_patterns: usize,
    records: Vec<RecordFile>,
}

#[derive(serde::Deserialize)]
struct RecordFile {
    sequence: String,
    #[serde(default)]
    patterns_sha256: Option<String>,
}

/// Reads an intake folder.
pub fn read_measured(dir: &Path) -> Result<Measured> {
    let sp = dir.join("summary.json");
    let text = std::fs::read_to_string(&sp).map_err(|e| Error::read(&sp, e))?;
    let s: SummaryFile = serde_json::from_str(&text).map_err(|e| {
        Error::input(format!("not an intake summary.json: {e}"))
            .in_file(&sp)
            .at_line(e.line(), e.column())
    })?;
    if s.command != "intake" {
        return Err(Error::input(format!(
            "written by `{}`, not `intake`: give an intake output folder",
            s.command
        ))
        .in_file(&sp));
    }
    let mut sequences = Vec::new();
    for r in &s.records {
        let sequence = Sequence::all()
            .into_iter()
            .find(|q| q.key() == r.sequence)
            .ok_or_else(|| {
                Error::input(format!("unknown sequence {:?}", r.sequence)).in_file(&sp)
            })?;
        let sha = r.patterns_sha256.clone().ok_or_else(|| {
            Error::input(
                "the records carry no patterns_sha256 (an intake from before it was recorded): \
                 take the records in again",
            )
            .in_file(&sp)
        })?;
        sequences.push(MeasuredSequence {
            sequence,
            values: Vec::new(),
            start_s: Vec::new(),
            flagged: Vec::new(),
            patterns_sha256: sha,
        });
    }
    read_frames(&dir.join("frames.csv"), &mut sequences)?;
    for q in &sequences {
        let want = q.sequence.frames(s.base_patterns);
        if q.values.len() != want {
            return Err(Error::input(format!(
                "{} frames of the {} sequence, expected {want}",
                q.values.len(),
                q.sequence.key()
            ))
            .in_file(&dir.join("frames.csv")));
        }
    }
    if sequences.iter().all(|q| q.flagged.iter().all(|f| *f)) {
        return Err(Error::input(
            "every frame is flagged (clipped, irregular or without its pulse): nothing to fit",
        )
        .in_file(&dir.join("frames.csv")));
    }
    let (noise_v, noise_dof) = noise_of(&sequences).ok_or_else(|| {
        Error::input(
            "no calibrated_base record: its all-on/all-off frames give the frame-to-frame \
             noise the fit weighs by (record the calibrated sequence too)",
        )
        .in_file(&sp)
    })?;
    Ok(Measured {
        dir: dir.to_path_buf(),
        units: (s.units_across, s.units_down),
        base_patterns: s.base_patterns,
        sequences,
        noise_v,
        noise_dof,
    })
}

/// Fills each sequence's values and flags from `frames.csv`.
fn read_frames(path: &Path, sequences: &mut [MeasuredSequence]) -> Result<()> {
    let mut rd = csv::Reader::from_path(path)
        .map_err(|e| Error::input(format!("cannot read: {e}")).in_file(path))?;
    for (n, row) in rd.records().enumerate() {
        let line = n + 2;
        let row = row.map_err(|e| Error::input(format!("{e}")).in_file(path).at_line(line, 1))?;
        let bad = |why: String| Error::input(why).in_file(path).at_line(line, 1);
        if row.len() < 8 {
            return Err(bad(format!("{} cells, expected 8", row.len())));
        }
        let Some(q) = sequences.iter_mut().find(|q| q.sequence.key() == &row[0]) else {
            return Err(bad(format!(
                "sequence {:?} is not in summary.json",
                &row[0]
            )));
        };
        let frame: usize = row[1]
            .parse()
            .map_err(|_| bad(format!("frame {:?} is not a whole number", &row[1])))?;
        if frame != q.values.len() {
            return Err(bad(format!("frame {frame} out of order")));
        }
        let mut v = [0.0; 3];
        for (k, cell) in v.iter_mut().enumerate() {
            *cell = row[4 + k]
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(format!("value {:?} is not a finite number", &row[4 + k])))?;
        }
        let start = row[2]
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| bad(format!("start_s {:?} is not a finite number", &row[2])))?;
        q.values.push(v);
        q.start_s.push(start);
        q.flagged.push(!row[7].trim().is_empty());
    }
    Ok(())
}

/// The pooled within-level standard deviation of each channel over the calibration
/// preamble's unflagged frames (module notes), and its degrees of freedom.
fn noise_of(sequences: &[MeasuredSequence]) -> Option<([f64; 3], usize)> {
    let q = sequences
        .iter()
        .find(|q| q.sequence == Sequence::CalibratedBase)?;
    let mut out = [0.0; 3];
    let mut dof = 0;
    for (o, slot) in out.iter_mut().enumerate() {
        let (mut ss, mut df) = (0.0, 0usize);
        for parity in 0..2 {
            let v: Vec<f64> = (0..CALIBRATION_PAIRS)
                .map(|k| 2 * k + parity)
                .filter(|&f| f < q.values.len() && !q.flagged[f])
                .map(|f| q.values[f][o])
                .collect();
            if v.len() < 2 {
                continue;
            }
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            ss += v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>();
            df += v.len() - 1;
        }
        if df == 0 {
            return None;
        }
        *slot = (ss / df as f64).sqrt();
        dof = df;
    }
    Some((out, dof))
}
