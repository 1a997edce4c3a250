//! `run --scope-record`: every recorded sequence as a bench oscilloscope saves it, in the run's
//! `scope/<sequence>/` (docs/scope-records.md):
//!
//! - `record.csv`: the Tektronix MSO 4/5/6 CSV layout (key, value header lines, `Label`, then
//!   `TIME,CH1,CH2,CH3,CH4` and one row per sample), channels CH1 = RF, CH2 = MONITOR+,
//!   CH3 = MONITOR−, CH4 = TRIG, each value in full (shortest round-trip) precision;
//! - `record.npy`: the same samples, float64, samples × 4 in that channel order (V), and
//!   `record.json`, its sidecar (sample interval, length, trigger index, channels, units, the
//!   frame timing of the DMD controller);
//! - `patterns.npy`, `patterns.json`: the frames the DMD showed, calibration frames included,
//!   as `spibench patterns` writes them (packed rows, most significant bit first).
//!
//! The records are recorded again sample by sample (crate::pipeline::replay_sequence, the
//! record stage's own record, bit for bit) and streamed to disk as they come: memory stays at
//! one row. TRIG is the DMD controller's frame sync, a TTL-like pulse (3.3 V) over the first
//! quarter of every frame, rising at the frame's first sample.

use std::io::Write;

use serde::Serialize;

use crate::acquisition::{
    PackedPatterns, Sequence, patterns_for_ratio, schemes::CALIBRATION_PAIRS,
};
use crate::detector::{Channel, FrameTiming, SettleRule};
use crate::error::{Error, Result};
use crate::pipeline::ReplaySetup;
use crate::report::npy::F64FileWriter;
use crate::report::output::OutputDir;
use crate::run::RunOutcome;

/// Files written per sequence.
pub const FILES_PER_SEQUENCE: usize = 5;
/// TRIG's high level (V): a 3.3 V logic output.
pub const TRIGGER_HIGH_V: f64 = 3.3;
/// TRIG's pulse: this share of a frame from its start.
pub const TRIGGER_DUTY: f64 = 0.25;
/// The channels of a record, in column order, with their Tektronix column names.
pub const CHANNELS: [(&str, &str); 4] = [
    ("RF", "CH1"),
    ("MON+", "CH2"),
    ("MON-", "CH3"),
    ("TRIG", "CH4"),
];

/// One channel of `record.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelMeta {
    pub name: &'static str,
    pub column: &'static str,
    pub units: &'static str,
    /// The oscilloscope's setting (TRIG: a 1 V/div logic view).
    pub volts_per_div: f64,
    pub offset_v: f64,
    /// ADC bits (0: unquantised, the noise-free limit).
    pub bits: u32,
}

/// The frame timing the DMD controller used.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FrameTimingMeta {
    pub frames: usize,
    pub frame_s: f64,
    pub frame_rate_hz: f64,
    pub settling_s: f64,
    pub sample_rate_hz: f64,
    /// Frame 0 starts at this sample (the trigger index).
    pub first_frame_sample: u64,
    pub trigger_high_v: f64,
    pub trigger_width_s: f64,
}

/// `record.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RecordMeta {
    pub format: &'static str,
    /// The CSV layout of `record.csv`.
    pub csv_layout: &'static str,
    pub sequence: Sequence,
    pub sample_interval_s: f64,
    pub record_length: u64,
    /// The sample at the trigger (time 0).
    pub trigger_index: u64,
    pub channels: Vec<ChannelMeta>,
    /// `record.npy`'s layout.
    pub npy_layout: &'static str,
    pub frame_timing: FrameTimingMeta,
    /// The record's files and their sizes.
    pub csv_bytes: u64,
    pub npy_bytes: u64,
}

/// `patterns.json` of a sequence: the keys of `spibench patterns`' file, and the sequence.
#[derive(Debug, Clone, Serialize)]
pub struct SequencePatternsMeta {
    pub command: &'static str,
    pub spibench_version: &'static str,
    pub family: String,
    pub ordering: Option<&'static str>,
    pub seed: Option<u64>,
    pub units_across: usize,
    pub units_down: usize,
    pub unit_order: &'static str,
    pub ratio: f64,
    pub base_patterns: usize,
    pub frames: usize,
    pub frame_order: &'static str,
    pub sequence: Sequence,
    /// Frames before the first pattern: (all on, all off) pairs.
    pub calibration_frames: usize,
    pub value_meaning: &'static str,
    pub files: Vec<String>,
}

/// Writes every recorded sequence of `o` into `out/scope/`; returns the files written and the
/// bytes of the records.
pub fn write_scope_records(o: &RunOutcome, out: &OutputDir) -> Result<(Vec<String>, u64)> {
    let t = &o.transport;
    let (w, h) = (t.units_across, t.units_down);
    let m_max = o
        .settings
        .sampling_ratios
        .iter()
        .map(|&r| patterns_for_ratio(r, w * h))
        .max()
        .unwrap_or(1);
    let set = o.settings.patterns.build(w, h, m_max)?;
    let packed = PackedPatterns::new(set);
    let mut files = Vec::new();
    let mut bytes = 0;
    for summary in &o.sequences {
        let q = summary.sequence;
        let dir = format!("scope/{}", q.key());
        let (csv_path, npy_path) = (
            out.try_path(&format!("{dir}/record.csv"))?,
            out.try_path(&format!("{dir}/record.npy"))?,
        );
        let replayed = crate::pipeline::replay_sequence(
            t,
            &o.detector,
            &o.scope,
            &o.settings,
            &packed,
            o.seed,
            q,
            |setup| RecordWriter::create(&csv_path, &npy_path, setup),
        )?;
        let Some((_, writer)) = replayed else {
            continue;
        };
        let (setup, csv_bytes, npy_bytes) = writer.finish()?;
        bytes += csv_bytes + npy_bytes;
        let meta = record_meta(q, &setup, csv_bytes, npy_bytes);
        crate::report::json::write_json(&out.try_path(&format!("{dir}/record.json"))?, &meta)?;
        write_patterns(o, &packed, q, out, &dir)?;
        for f in [
            "record.csv",
            "record.npy",
            "record.json",
            "patterns.npy",
            "patterns.json",
        ] {
            files.push(format!("{dir}/{f}"));
        }
    }
    Ok((files, bytes))
}

fn record_meta(q: Sequence, s: &ReplaySetup, csv_bytes: u64, npy_bytes: u64) -> RecordMeta {
    let mut channels: Vec<ChannelMeta> = (0..3)
        .map(|o| ChannelMeta {
            name: CHANNELS[o].0,
            column: CHANNELS[o].1,
            units: "V",
            volts_per_div: s.channels[o].volts_per_div,
            offset_v: s.channels[o].offset_v,
            bits: s.channels[o].bits,
        })
        .collect();
    channels.push(ChannelMeta {
        name: CHANNELS[3].0,
        column: CHANNELS[3].1,
        units: "V",
        volts_per_div: 1.0,
        offset_v: 0.0,
        bits: 0,
    });
    RecordMeta {
        format: "spibench scope record",
        csv_layout: "tektronix",
        sequence: q,
        sample_interval_s: 1.0 / s.timing.sample_rate_hz,
        record_length: s.samples,
        trigger_index: 0,
        channels,
        npy_layout: "float64, samples × 4, columns RF, MON+, MON-, TRIG (V)",
        frame_timing: frame_timing_meta(s.timing, s.frames),
        csv_bytes,
        npy_bytes,
    }
}

fn frame_timing_meta(timing: FrameTiming, frames: usize) -> FrameTimingMeta {
    FrameTimingMeta {
        frames,
        frame_s: timing.frame_s,
        frame_rate_hz: 1.0 / timing.frame_s,
        settling_s: timing.settling_s,
        sample_rate_hz: timing.sample_rate_hz,
        first_frame_sample: 0,
        trigger_high_v: TRIGGER_HIGH_V,
        trigger_width_s: TRIGGER_DUTY * timing.frame_s,
    }
}

/// The frames of sequence `q`, as packed rows (frames × ⌈units/8⌉), and their description.
fn write_patterns(
    o: &RunOutcome,
    packed: &PackedPatterns,
    q: Sequence,
    out: &OutputDir,
    dir: &str,
) -> Result<()> {
    let set = packed.set();
    let units = set.units();
    let m = set.measurements();
    let bits = set.base_patterns();
    let lead = q.lead_frames();
    let frames = q.frames(m);
    let frame_bit = |f: usize, j: usize| -> bool {
        match q {
            Sequence::Base => bits.get(f, j),
            Sequence::Complementary => bits.get(f / 2, j) != (f % 2 == 1),
            Sequence::CalibratedBase if f < lead => f.is_multiple_of(2),
            Sequence::CalibratedBase => bits.get(f - lead, j),
        }
    };
    let row_bytes = units.div_ceil(8);
    let mut data = vec![0u8; frames * row_bytes];
    for f in 0..frames {
        for j in 0..units {
            if frame_bit(f, j) {
                data[f * row_bytes + j / 8] |= 0x80 >> (j % 8);
            }
        }
    }
    crate::report::npy::write_u8(
        &out.try_path(&format!("{dir}/patterns.npy"))?,
        &[frames, row_bytes],
        &data,
    )?;
    let (family, ordering, seed) = match o.settings.patterns {
        crate::acquisition::PatternFamily::Random { seed } => ("random", None, Some(seed)),
        crate::acquisition::PatternFamily::Hadamard { ordering } => {
            ("hadamard", Some(ordering.label()), None)
        }
    };
    let meta = SequencePatternsMeta {
        command: "run --scope-record",
        spibench_version: env!("CARGO_PKG_VERSION"),
        family: family.into(),
        ordering,
        seed,
        units_across: o.transport.units_across,
        units_down: o.transport.units_down,
        unit_order: "row-major: unit j = row · units_across + column, row 0 at the top",
        ratio: m as f64 / units as f64,
        base_patterns: m,
        frames,
        frame_order: match q {
            Sequence::Base => "base patterns i = 0, 1, …",
            Sequence::Complementary => "base pattern i, then its complement, for i = 0, 1, …",
            Sequence::CalibratedBase => "8 × (all on, all off), then base patterns i = 0, 1, …",
        },
        sequence: q,
        calibration_frames: 2 * CALIBRATION_PAIRS * usize::from(q == Sequence::CalibratedBase),
        value_meaning: "1 = state + (toward arm +), 0 = state −",
        files: vec!["patterns.npy".into()],
    };
    crate::report::json::write_json(&out.try_path(&format!("{dir}/patterns.json"))?, &meta)
}

/// The CSV and `.npy` of one record, written as the samples come.
struct RecordWriter {
    setup: ReplaySetup,
    rule: SettleRule,
    csv: std::io::BufWriter<std::fs::File>,
    csv_path: std::path::PathBuf,
    csv_bytes: u64,
    npy: F64FileWriter,
    line: String,
    /// The first write error, reported when the record is finished.
    error: Option<Error>,
}

impl RecordWriter {
    fn create(
        csv_path: &std::path::Path,
        npy_path: &std::path::Path,
        setup: &ReplaySetup,
    ) -> Result<RecordWriter> {
        let file = std::fs::File::create(csv_path).map_err(|e| Error::write(csv_path, e))?;
        let mut csv = std::io::BufWriter::with_capacity(1 << 20, file);
        let header = tektronix_header(setup);
        csv.write_all(header.as_bytes())
            .map_err(|e| Error::write(csv_path, e))?;
        Ok(RecordWriter {
            setup: *setup,
            rule: SettleRule::of(setup.timing),
            csv,
            csv_path: csv_path.to_path_buf(),
            csv_bytes: header.len() as u64,
            npy: F64FileWriter::create(npy_path, &[setup.samples as usize, 4])?,
            line: String::with_capacity(128),
            error: None,
        })
    }

    fn finish(mut self) -> Result<(ReplaySetup, u64, u64)> {
        if let Some(e) = self.error {
            return Err(e);
        }
        self.csv
            .flush()
            .map_err(|e| Error::write(&self.csv_path, e))?;
        self.npy.finish()?;
        let npy_bytes = 128 + 32 * self.setup.samples;
        Ok((self.setup, self.csv_bytes, npy_bytes))
    }
}

impl crate::pipeline::SampleSink for RecordWriter {
    fn sample(&mut self, n: u64, f: usize, v: &[f64; 3]) {
        if self.error.is_some() {
            return;
        }
        let in_frame = n as f64 - self.rule.grid_start(f);
        let trig = if in_frame < TRIGGER_DUTY * self.rule.per_frame {
            TRIGGER_HIGH_V
        } else {
            0.0
        };
        let t = n as f64 / self.setup.timing.sample_rate_hz;
        self.line.clear();
        use std::fmt::Write as _;
        let _ = writeln!(self.line, "{t:e},{},{},{},{trig}", v[0], v[1], v[2]);
        self.csv_bytes += self.line.len() as u64;
        if let Err(e) = self.csv.write_all(self.line.as_bytes()) {
            self.error = Some(Error::write(&self.csv_path, e));
            return;
        }
        if let Err(e) = self.npy.extend(&[v[0], v[1], v[2], trig]) {
            self.error = Some(e);
        }
    }
}

/// The header of `record.csv`: the lines a Tektronix MSO 4/5/6 writes before its samples.
fn tektronix_header(s: &ReplaySetup) -> String {
    let ch: Vec<Channel> = s.channels.to_vec();
    let dt = 1.0 / s.timing.sample_rate_hz;
    let join = |f: &dyn Fn(usize) -> String| (0..4).map(f).collect::<Vec<_>>().join(",");
    let scale = join(&|o| {
        if o < 3 {
            format!("{}", ch[o].volts_per_div)
        } else {
            "1".into()
        }
    });
    let offset = join(&|o| {
        if o < 3 {
            format!("{}", ch[o].offset_v)
        } else {
            "0".into()
        }
    });
    let labels = join(&|o| CHANNELS[o].0.to_string());
    let columns = join(&|o| CHANNELS[o].1.to_string());
    format!(
        "Model,spibench {version} simulated oscilloscope\n\
         Firmware Version,{version}\n\
         \n\
         Waveform Type,ANALOG\n\
         Point Format,Y\n\
         Horizontal Units,s\n\
         Horizontal Scale,{hscale}\n\
         Horizontal Delay,0\n\
         Sample Interval,{dt}\n\
         Record Length,{n}\n\
         Gating,0.0% to 100.0%\n\
         Probe Attenuation,1,1,1,1\n\
         Vertical Units,V,V,V,V\n\
         Vertical Offset,{offset}\n\
         Vertical Scale,{scale}\n\
         Vertical Position,0,0,0,0\n\
         Zero Index,0\n\
         Label,{labels}\n\
         TIME,{columns}\n",
        version = env!("CARGO_PKG_VERSION"),
        hscale = s.samples as f64 * dt / 10.0,
        n = s.samples,
    )
}
