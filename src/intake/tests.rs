//! The frames intake cuts from a replayed record are the record stage's own, bit for bit, for
//! every sequence with the default noise and drift; and the calibration's standard errors are
//! honest: over records of one bench with known arm
//! gains and offsets (the noise-free record's), recorded with noise under 24 seeds, the
//! z-scores of each arm's gain and offset fall within Student's 95 % interval (7 degrees of
//! freedom: 8 frames per level) in the expected share of cases.

use std::path::Path;

use super::calibrate::calibrate_values;
use crate::acquisition::{PackedPatterns, Sequence};
use crate::scene::run::parse_run_scene;

fn scene() -> crate::scene::run::RunScene {
    // No drift: the frame-to-frame scatter is the noise alone (a lamp or ambient drift moves
    // every frame of a record together, which no scatter within the record can show).
    scene_with(
        "run: (rays: 20000, schemes: [double_arm_calibrated], sampling_ratios: [0.05], \
         drift: (lamp_drift_rms: 0, lamp_ripple_amplitude: 0, ambient_drift_rms: 0, \
         ambient_flicker_depth: 0)),",
    )
}

fn scene_with(run: &str) -> crate::scene::run::RunScene {
    let t = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/paper_bench.ron"
    ))
    .unwrap();
    let t = t.replace(
        "units_across: 48, units_down: 48, mirrors_per_unit: 12",
        "units_across: 16, units_down: 16, mirrors_per_unit: 36",
    );
    let end = t.rfind(')').unwrap();
    parse_run_scene(&format!("{}{run}\n)\n", &t[..end]), Path::new("small.ron")).unwrap()
}

#[test]
fn calibration_z_scores_over_24_records_follow_their_standard_errors() {
    let s = scene();
    let traced = crate::pipeline::trace_stage(
        &s.bench,
        &crate::pipeline::TraceRequest::new(s.settings.rays, 3),
    )
    .unwrap();
    let patterns = crate::pipeline::evaluate::base_patterns(&s.settings.patterns, &s).unwrap();
    let packed = PackedPatterns::new(patterns);
    let quiet: crate::pipeline::Progress = &|_, _, _| {};
    let record = |settings: &crate::scene::run::RunSettings, seed: u64| -> Vec<[f64; 3]> {
        let r = crate::pipeline::record_transport(
            &traced.transport,
            &s.detector,
            &s.scope,
            settings,
            &packed,
            seed,
            quiet,
        )
        .unwrap();
        r.record(Sequence::CalibratedBase).unwrap().frames.clone()
    };
    let mut quiet_settings = s.settings.clone();
    quiet_settings.noise = false;
    let truth = calibrate_values(&record(&quiet_settings, 1));
    let mut z = Vec::new();
    for seed in 1..=24 {
        let c = calibrate_values(&record(&s.settings, seed));
        for a in 0..2 {
            z.push((c[a].gain_v - truth[a].gain_v) / c[a].gain_stderr_v);
            z.push((c[a].offset_v - truth[a].offset_v) / c[a].offset_stderr_v);
        }
    }
    let t95 = 2.365;
    let inside = z.iter().filter(|v| v.abs() <= t95).count() as f64 / z.len() as f64;
    let mean_sq = z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64;
    let line: Vec<String> = z.iter().map(|v| format!("{v:.2}")).collect();
    eprintln!(
        "z-scores (gain+, offset+, gain−, offset− per record): {}",
        line.join(" ")
    );
    eprintln!("share within ±{t95}: {inside:.3}; mean z² {mean_sq:.3} (t₇: 1.4)");
    // 96 z-scores, pairs sharing their dark frames: the share's standard deviation is about
    // √(0.95·0.05/48) = 0.031, so 0.85 is three of them below 0.95; mean z² of t₇ is 1.4
    // with a standard deviation of about 0.4 over 48 independent pairs.
    assert!(inside >= 0.85, "share {inside}");
    assert!((0.5..=2.6).contains(&mean_sq), "mean z² {mean_sq}");
}

/// A replayed record as a file holds it: the samples of [RF, MON+, MON−] and TRIG as
/// `run --scope-record` writes it.
struct Columns {
    rule: crate::detector::SettleRule,
    data: Vec<Vec<f64>>,
}

impl crate::pipeline::SampleSink for Columns {
    fn sample(&mut self, n: u64, f: usize, v: &[f64; 3]) {
        let in_frame = n as f64 - self.rule.grid_start(f);
        let high = in_frame < crate::outputs::run::scope::TRIGGER_DUTY * self.rule.per_frame;
        for (o, &x) in v.iter().enumerate() {
            self.data[o].push(x);
        }
        self.data[3].push(if high { 3.3 } else { 0.0 });
    }
}

#[test]
fn frames_cut_from_a_replayed_record_are_the_record_stages_bit_for_bit() {
    // Every scheme (all three sequences), the default noise and drift.
    let s = scene_with("run: (rays: 20000, sampling_ratios: [0.1]),");
    let traced = crate::pipeline::trace_stage(
        &s.bench,
        &crate::pipeline::TraceRequest::new(s.settings.rays, 3),
    )
    .unwrap();
    let patterns = crate::pipeline::evaluate::base_patterns(&s.settings.patterns, &s).unwrap();
    let packed = PackedPatterns::new(patterns);
    let quiet: crate::pipeline::Progress = &|_, _, _| {};
    let seed = 9;
    let recorded = crate::pipeline::record_transport(
        &traced.transport,
        &s.detector,
        &s.scope,
        &s.settings,
        &packed,
        seed,
        quiet,
    )
    .unwrap();
    for q in Sequence::all() {
        let (_, cols) = crate::pipeline::replay_sequence(
            &traced.transport,
            &s.detector,
            &s.scope,
            &s.settings,
            &packed,
            seed,
            q,
            |setup| {
                Ok(Columns {
                    rule: crate::detector::SettleRule::of(setup.timing),
                    data: vec![Vec::new(); 4],
                })
            },
        )
        .unwrap()
        .unwrap();
        let rec = super::ScopeRecord {
            path: "replayed.csv".into(),
            layout: super::Layout::Npy,
            sample_interval_s: 1.0 / s.scope.sample_rate_hz,
            columns: ["CH1", "CH2", "CH3", "CH4"].map(String::from).to_vec(),
            labels: vec![None; 4],
            screens: vec![None; 4],
            data: cols.data,
            trigger_index: Some(0),
        };
        let want = &recorded.record(q).unwrap().frames;
        let map = super::ChannelMap {
            signals: [0, 1, 2],
            trigger: Some(3),
        };
        let found = super::frames::find_frames(&rec, &map, &cols.rule, want.len(), 0).unwrap();
        let got: Vec<[f64; 3]> = found.frames.iter().map(|f| f.values).collect();
        assert!(found.anomalies.is_empty());
        // Bit for bit: every frame value of every output.
        assert_eq!(
            got.iter().map(|v| v.map(f64::to_bits)).collect::<Vec<_>>(),
            want.iter().map(|v| v.map(f64::to_bits)).collect::<Vec<_>>(),
            "{}",
            q.key()
        );
    }
}
