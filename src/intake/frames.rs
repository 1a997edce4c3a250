//! Frames found in a record: from the DMD controller's trigger edges, or without a trigger
//! from the frame rate and the calibration preamble's all-on/all-off steps; then each frame's
//! value by the record stage's own settle-window rule (crate::detector::frames).
//!
//! Edges are assigned to frames walking from the first: an edge one period (±25 %) after the
//! last assigned one starts the next frame, an edge k periods after it means k − 1 pulses
//! were missed (those frames start on the period grid, reported by index and time), and an
//! edge that falls between frames is an extra pulse (reported, not a frame). A frame starts on
//! the regular grid from frame 0 when its edge is the grid's first sample there (the sampled
//! edge only places the start within a sample), else at its edge; a period more than 1 % off
//! the nominal is flagged irregular.

use serde::Serialize;

use super::record::ScopeRecord;
use crate::detector::{FrameMeans, SettleRule};
use crate::error::{Error, Result};

/// Tolerance of an edge's place, as a share of the frame period.
pub const EDGE_TOLERANCE: f64 = 0.25;
/// A period further than this share from the nominal is irregular.
pub const IRREGULAR_PERIOD: f64 = 0.01;
/// A sample within this share of the screen's span from its edge is clipped.
pub const CLIP_MARGIN: f64 = 1e-3;

/// Flags of a found frame.
pub const FLAG_CLIPPED: u8 = 1;
pub const FLAG_IRREGULAR: u8 = 2;
pub const FLAG_NO_PULSE: u8 = 4;

/// A trigger anomaly: a pulse missing or extra, at a frame and a time.
#[derive(Debug, Clone, Serialize)]
pub struct TriggerAnomaly {
    /// `missing_pulse` or `extra_pulse`.
    pub kind: &'static str,
    /// The frame without its pulse, or the frame the extra pulse fell in.
    pub frame: usize,
    pub time_s: f64,
    pub sample: u64,
}

/// One found frame.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FoundFrame {
    /// Start (samples from the record's first, fractional on the grid).
    pub start: f64,
    pub first_sample: u64,
    pub end_sample: u64,
    pub settled_samples: usize,
    /// [RF, MONITOR+, MONITOR−] means over the settled window (V).
    pub values: [f64; 3],
    /// Bit o: channel o clipped at its screen in a settled sample (see `flags`).
    pub clipped: u8,
    pub flags: u8,
}

/// The frames of one record.
#[derive(Debug, Clone)]
pub struct FoundFrames {
    pub frames: Vec<FoundFrame>,
    pub anomalies: Vec<TriggerAnomaly>,
    /// `trigger` or `preamble`.
    pub method: &'static str,
    pub edges: usize,
}

/// The three signal channels and the trigger of a record, as indices into its columns.
#[derive(Debug, Clone, Copy)]
pub struct ChannelMap {
    pub signals: [usize; 3],
    pub trigger: Option<usize>,
}

fn time_of(rec: &ScopeRecord, n: f64) -> f64 {
    (n - rec.trigger_index.unwrap_or(0) as f64) * rec.sample_interval_s
}

/// Rising edges of a trigger channel: samples at or above the midpoint of its range after one
/// below it (the first sample counts when it is high).
pub fn rising_edges(trig: &[f64]) -> Vec<u64> {
    let (lo, hi) = trig
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Vec::new();
    }
    let mid = 0.5 * (lo + hi);
    let mut edges = Vec::new();
    let mut was_high = false;
    for (n, &v) in trig.iter().enumerate() {
        let high = v >= mid;
        if high && !was_high {
            edges.push(n as u64);
        }
        was_high = high;
    }
    edges
}

/// Frame starts from trigger edges (the module notes): the starts, each frame's flags, and the
/// anomalies. `expected` frames; more edges are a refusal naming the first frame too many.
pub fn starts_from_edges(
    rec: &ScopeRecord,
    edges: &[u64],
    rule: &SettleRule,
    expected: usize,
) -> Result<(Vec<f64>, Vec<u8>, Vec<TriggerAnomaly>)> {
    let p = rule.per_frame;
    let Some(&e0) = edges.first() else {
        return Err(Error::input("the trigger channel has no rising edge").in_file(&rec.path));
    };
    let anchor = e0 as f64;
    let mut starts = vec![anchor];
    let mut flags = vec![0u8];
    let mut anomalies = Vec::new();
    let (mut prev_e, mut prev_k) = (e0 as f64, 0usize);
    let start_of = |k: usize, e: u64| -> f64 {
        let grid = anchor + rule.grid_start(k);
        if SettleRule::first_sample(grid) == e {
            grid
        } else {
            e as f64
        }
    };
    for &e in &edges[1..] {
        let d = (e as f64 - prev_e) / p;
        let k_rel = d.round();
        let dev = (d - k_rel).abs();
        if k_rel < 1.0 || dev > EDGE_TOLERANCE {
            anomalies.push(TriggerAnomaly {
                kind: "extra_pulse",
                frame: prev_k + d.floor().max(0.0) as usize,
                time_s: time_of(rec, e as f64),
                sample: e,
            });
            continue;
        }
        let k = prev_k + k_rel as usize;
        if k >= expected {
            return Err(Error::input(format!(
                "frame {k} (a trigger edge at t = {:.6e} s, sample {e}) lies beyond the \
                 sequence's {expected} frames: the record holds more frames than the patterns",
                time_of(rec, e as f64)
            ))
            .in_file(&rec.path));
        }
        for j in prev_k + 1..k {
            let s = prev_e + (j - prev_k) as f64 * p;
            anomalies.push(TriggerAnomaly {
                kind: "missing_pulse",
                frame: j,
                time_s: time_of(rec, s),
                sample: SettleRule::first_sample(s),
            });
            starts.push(s);
            flags.push(FLAG_NO_PULSE);
        }
        let s = start_of(k, e);
        let period = (s - starts[starts.len() - 1]) / p;
        let irregular = (period - 1.0).abs() > IRREGULAR_PERIOD;
        starts.push(s);
        flags.push(if irregular { FLAG_IRREGULAR } else { 0 });
        (prev_e, prev_k) = (e as f64, k);
    }
    Ok((starts, flags, anomalies))
}

/// Frame starts without a trigger: the calibration preamble's (all on, all off) frames make
/// MONITOR+ step down and up at every frame boundary of the first `2·pairs` frames; each
/// crossing of the midpoint between its high and low levels places the grid, and the grid is
/// the mean of those placements.
pub fn starts_from_preamble(
    rec: &ScopeRecord,
    map: &ChannelMap,
    rule: &SettleRule,
    expected: usize,
    pairs: usize,
) -> Result<Vec<f64>> {
    let p = rule.per_frame;
    let mon = &rec.data[map.signals[1]];
    let span = ((2 * pairs) as f64 * p).ceil() as usize;
    if pairs == 0 || mon.len() < span {
        return Err(Error::input(
            "without a trigger channel, frames are found from the calibration preamble's all-on \
             and all-off frames, and this sequence has none (or the record is shorter than it): \
             record the DMD controller's trigger",
        )
        .in_file(&rec.path));
    }
    let head = &mon[..span];
    let (lo, hi) = head
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let mid = 0.5 * (lo + hi);
    // Crossings into frames 1, 2, …: down into an all-off frame, up into an all-on one. The
    // record may start early, before frame 0: the first crossing down is frame 1's start.
    let mut placements = Vec::new();
    let mut high = head[0] >= mid;
    let mut next_frame = 1usize;
    for (n, &v) in head.iter().enumerate() {
        let now = v >= mid;
        if now != high {
            if next_frame == 1 && now {
                // A rise before the first fall: the record starts in an all-off frame before
                // the preamble; wait for the first fall.
                high = now;
                continue;
            }
            placements.push(n as f64 - 0.5 - rule.grid_start(next_frame));
            next_frame += 1;
            high = now;
        }
    }
    if placements.len() < 3 {
        return Err(Error::input(
            "the calibration preamble's steps are not found in MONITOR+ (fewer than three \
             crossings in its frames): record the DMD controller's trigger",
        )
        .in_file(&rec.path));
    }
    // Rounded to whole samples, so that the grid's frames start where the crossings say.
    let anchor = (placements.iter().sum::<f64>() / placements.len() as f64).round();
    Ok((0..expected).map(|k| anchor + rule.grid_start(k)).collect())
}

/// Each frame's settled-window means and flags by the settle-window rule, from its start.
pub fn cut_frames(
    rec: &ScopeRecord,
    map: &ChannelMap,
    rule: &SettleRule,
    starts: &[f64],
    flags: &[u8],
) -> Result<Vec<FoundFrame>> {
    let samples = rec.samples() as u64;
    let n_frames = starts.len();
    let firsts: Vec<u64> = starts
        .iter()
        .map(|&s| SettleRule::first_sample(s))
        .collect();
    let mut ends: Vec<u64> = firsts[1..].to_vec();
    if let Some(&last) = starts.last() {
        let end = SettleRule::first_sample(last + rule.per_frame);
        // A record that ends within a sample of the last frame's end ends it.
        ends.push(if end.abs_diff(samples) <= 1 {
            samples
        } else {
            end
        });
    }
    if let Some(f) = ends.iter().position(|&e| e > samples) {
        return Err(Error::input(format!(
            "the record ends at t = {:.6e} s, within frame {f} of the sequence's {n_frames}: \
             the record is shorter than the sequence",
            time_of(rec, samples as f64)
        ))
        .in_file(&rec.path));
    }
    let windows: Vec<Option<(f64, f64)>> = map
        .signals
        .iter()
        .map(|&c| {
            rec.screens[c].map(|s| {
                let (lo, hi) = s.window();
                let m = CLIP_MARGIN * (hi - lo);
                (lo + m, hi - m)
            })
        })
        .collect();
    let cols = map.signals.map(|c| &rec.data[c]);
    let mut means = FrameMeans::<3>::new(n_frames);
    let mut clipped = vec![0u8; n_frames];
    for f in 0..n_frames {
        for n in firsts[f]..ends[f] {
            if !rule.settled(n, starts[f]) {
                continue;
            }
            for o in 0..3 {
                let v = cols[o][n as usize];
                means.add(f, o, v);
                if let Some((lo, hi)) = windows[o]
                    && (v <= lo || v >= hi)
                {
                    clipped[f] |= 1 << o;
                }
            }
            means.count(f);
        }
    }
    let (values, counts) = means.means();
    Ok((0..n_frames)
        .map(|f| FoundFrame {
            start: starts[f],
            first_sample: firsts[f],
            end_sample: ends[f],
            settled_samples: counts[f],
            values: values[f],
            clipped: clipped[f],
            flags: flags.get(f).copied().unwrap_or(0) | (u8::from(clipped[f] != 0) * FLAG_CLIPPED),
        })
        .collect())
}

/// The frames of a record of `expected` frames: from its trigger when it has one, else from
/// the preamble of `pairs` calibration pairs. Refused, naming the frame, when the record holds
/// fewer or more frames than the sequence.
pub fn find_frames(
    rec: &ScopeRecord,
    map: &ChannelMap,
    rule: &SettleRule,
    expected: usize,
    pairs: usize,
) -> Result<FoundFrames> {
    let (starts, flags, anomalies, method, edges) = match map.trigger {
        Some(t) => {
            let edges = rising_edges(&rec.data[t]);
            let (s, f, a) = starts_from_edges(rec, &edges, rule, expected)?;
            (s, f, a, "trigger", edges.len())
        }
        None => {
            let s = starts_from_preamble(rec, map, rule, expected, pairs)?;
            let n = s.len();
            (s, vec![0; n], Vec::new(), "preamble", 0)
        }
    };
    if starts.len() < expected {
        let f = starts.len();
        let last = starts[f - 1] + rule.per_frame;
        let beyond = last + rule.per_frame <= rec.samples() as f64;
        return Err(Error::input(if beyond {
            format!(
                "frame {f} of the sequence's {expected} has no trigger pulse (none after \
                 t = {:.6e} s, where it was due): the record holds fewer frames than the \
                 patterns",
                time_of(rec, last)
            )
        } else {
            format!(
                "the record ends at t = {:.6e} s, before frame {f} of the sequence's \
                 {expected}: the record is shorter than the sequence",
                time_of(rec, rec.samples() as f64)
            )
        })
        .in_file(&rec.path));
    }
    let frames = cut_frames(rec, map, rule, &starts, &flags)?;
    Ok(FoundFrames {
        frames,
        anomalies,
        method,
        edges,
    })
}

/// The time (s) of a frame's start from the record's trigger.
pub fn frame_time(rec: &ScopeRecord, f: &FoundFrame) -> f64 {
    time_of(rec, f.start)
}

#[cfg(test)]
mod tests;
