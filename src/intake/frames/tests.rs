//! Frame finding on synthetic records: a regular trigger, ±5 % jitter, a missing and an extra
//! pulse, a clipped channel, a short record and too many frames; and without a trigger, the
//! calibration preamble.

// Samples are built by index, as the record's columns are read.
#![allow(clippy::needless_range_loop)]

use super::*;
use crate::detector::FrameTiming;
use crate::intake::record::{Layout, ScopeRecord, Screen};

const P: usize = 40;

fn rule() -> SettleRule {
    SettleRule::of(FrameTiming {
        frame_s: 40e-6,
        settling_s: 10e-6,
        sample_rate_hz: 1e6,
    })
}

/// Frame k shows MONITOR+ = k (RF = −k, MONITOR− = 2k); the trigger rises at `edges` (10
/// samples high each); `extra` samples after the frames.
fn synthetic(n_frames: usize, edges: &[usize], extra: usize) -> ScopeRecord {
    let n = n_frames * P + extra;
    let mut data = vec![vec![0.0; n]; 4];
    for s in 0..n {
        let k = (s / P).min(n_frames - 1) as f64;
        data[0][s] = -k;
        data[1][s] = k;
        data[2][s] = 2.0 * k;
    }
    for &e in edges {
        for s in e..(e + 10).min(n) {
            data[3][s] = 3.3;
        }
    }
    ScopeRecord {
        path: "synthetic.csv".into(),
        layout: Layout::Tektronix,
        sample_interval_s: 1e-6,
        columns: ["CH1", "CH2", "CH3", "CH4"].map(String::from).to_vec(),
        labels: vec![None; 4],
        screens: vec![None; 4],
        data,
        trigger_index: Some(0),
    }
}

fn map() -> ChannelMap {
    ChannelMap {
        signals: [0, 1, 2],
        trigger: Some(3),
    }
}

#[test]
fn a_regular_trigger_gives_every_frame_its_value() {
    let edges: Vec<usize> = (0..20).map(|k| k * P).collect();
    let rec = synthetic(20, &edges, 0);
    let f = find_frames(&rec, &map(), &rule(), 20, 0).unwrap();
    assert_eq!(f.frames.len(), 20);
    assert!(f.anomalies.is_empty());
    for (k, fr) in f.frames.iter().enumerate() {
        assert_eq!(fr.values, [-(k as f64), k as f64, 2.0 * k as f64]);
        // 40 samples, the first 10 settling.
        assert_eq!(fr.settled_samples, 30, "{k}");
        assert_eq!(fr.flags, 0);
    }
}

#[test]
fn jitter_of_five_percent_still_assigns_every_frame() {
    // Edges ±2 samples (5 % of 40) about the frame starts; the frames are the same.
    let edges: Vec<usize> = (0..30)
        .map(|k| (k * P) as i64 + [0, 2, -2, 1, -1][k % 5])
        .map(|e| e.max(0) as usize)
        .collect();
    let rec = synthetic(30, &edges, 0);
    let f = find_frames(&rec, &map(), &rule(), 30, 0).unwrap();
    assert!(f.anomalies.is_empty(), "{:?}", f.anomalies);
    for (k, fr) in f.frames.iter().enumerate() {
        // Each frame still reads its own value: the settled window (≥ 8 samples in, 2 at most
        // into the next frame's start) holds frame k's samples only, or nearly.
        assert_eq!(fr.first_sample as i64, edges[k] as i64, "{k}");
        assert!(
            (fr.values[1] - k as f64).abs() < 0.1,
            "{k}: {:?}",
            fr.values
        );
    }
    assert!(f.frames.iter().any(|x| x.flags & FLAG_IRREGULAR != 0));
}

#[test]
fn a_missing_pulse_is_found_by_frame_and_time() {
    let edges: Vec<usize> = (0..20).filter(|&k| k != 7).map(|k| k * P).collect();
    let rec = synthetic(20, &edges, 0);
    let f = find_frames(&rec, &map(), &rule(), 20, 0).unwrap();
    assert_eq!(f.anomalies.len(), 1);
    let a = &f.anomalies[0];
    assert_eq!(
        (a.kind, a.frame, a.sample),
        ("missing_pulse", 7, (7 * P) as u64)
    );
    assert!((a.time_s - 7.0 * 40e-6).abs() < 1e-12);
    // No shift: every frame keeps its value, the pulseless one flagged.
    for (k, fr) in f.frames.iter().enumerate() {
        assert_eq!(fr.values[1], k as f64);
    }
    assert_eq!(f.frames[7].flags, FLAG_NO_PULSE);
}

#[test]
fn an_extra_pulse_is_found_and_not_taken_for_a_frame() {
    let mut edges: Vec<usize> = (0..20).map(|k| k * P).collect();
    edges.insert(13, 12 * P + P / 2);
    let rec = synthetic(20, &edges, 0);
    let f = find_frames(&rec, &map(), &rule(), 20, 0).unwrap();
    assert_eq!(f.anomalies.len(), 1);
    let a = &f.anomalies[0];
    assert_eq!((a.kind, a.frame), ("extra_pulse", 12));
    assert_eq!(a.sample, (12 * P + P / 2) as u64);
    assert_eq!(f.frames.len(), 20);
    for (k, fr) in f.frames.iter().enumerate() {
        assert_eq!(fr.values[1], k as f64);
    }
}

#[test]
fn a_clipped_channel_flags_its_frames() {
    let edges: Vec<usize> = (0..10).map(|k| k * P).collect();
    let mut rec = synthetic(10, &edges, 0);
    // MONITOR+'s screen tops out at 5 V: frames 5 … 9 sit at or beyond it.
    rec.screens[1] = Some(Screen {
        volts_per_div: 0.5,
        offset_v: 2.5,
    });
    let f = find_frames(&rec, &map(), &rule(), 10, 0).unwrap();
    let clipped: Vec<usize> = (0..10)
        .filter(|&k| f.frames[k].flags & FLAG_CLIPPED != 0)
        .collect();
    // Frame 0 sits at the screen's bottom (0 V), frames 5 … 9 at or above its top.
    assert_eq!(clipped, vec![0, 5, 6, 7, 8, 9]);
    assert_eq!(f.frames[6].clipped, 0b010);
}

#[test]
fn a_short_record_and_too_many_frames_are_refused_naming_the_frame() {
    let edges: Vec<usize> = (0..10).map(|k| k * P).collect();
    let rec = synthetic(10, &edges, 0);
    let e = find_frames(&rec, &map(), &rule(), 12, 0).unwrap_err();
    let m = e.to_string();
    assert!(
        e.is_user_error() && m.contains("frame 10") && m.contains("shorter"),
        "{m}"
    );
    assert!(m.contains("synthetic.csv"), "{m}");
    let e = find_frames(&rec, &map(), &rule(), 8, 0).unwrap_err();
    let m = e.to_string();
    assert!(m.contains("frame 8") && m.contains("more frames"), "{m}");
    // The last frame cut short by the record's end.
    let mut rec = synthetic(10, &edges, 0);
    for c in &mut rec.data {
        c.truncate(9 * P + 20);
    }
    let m = find_frames(&rec, &map(), &rule(), 10, 0)
        .unwrap_err()
        .to_string();
    assert!(m.contains("frame 9") && m.contains("shorter"), "{m}");
}

#[test]
fn without_a_trigger_the_preamble_places_the_frames() {
    // 4 pairs of (all on, all off) on MONITOR+, then patterns; the record starts 13 samples
    // before frame 0.
    let lead = 13;
    let n_frames = 8 + 6;
    let n = lead + n_frames * P;
    let mut rec = synthetic(n_frames, &[], 0);
    let value = |k: usize| {
        if k < 8 {
            [1.0, 0.0][k % 2]
        } else {
            0.3 + 0.05 * k as f64
        }
    };
    for c in &mut rec.data {
        c.resize(n, 0.0);
    }
    for s in 0..n {
        let k = s.saturating_sub(lead) / P;
        let v = if s < lead {
            0.0
        } else {
            value(k.min(n_frames - 1))
        };
        rec.data[1][s] = v;
    }
    let m = ChannelMap {
        signals: [0, 1, 2],
        trigger: None,
    };
    let f = find_frames(&rec, &m, &rule(), n_frames, 4).unwrap();
    assert_eq!(f.method, "preamble");
    assert_eq!(f.frames[0].first_sample, lead as u64);
    for k in 0..n_frames {
        assert!((f.frames[k].values[1] - value(k)).abs() < 1e-12, "{k}");
    }
    // A sequence without a preamble cannot be found without a trigger.
    let e = find_frames(&rec, &m, &rule(), n_frames, 0).unwrap_err();
    assert!(e.to_string().contains("trigger"), "{e}");
}
