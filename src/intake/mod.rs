//! Measurements from a built bench (`spibench intake`): oscilloscope records in ([`record`]),
//! frames found and cut by the record stage's own settle-window rule ([`frames`]), each arm
//! calibrated from the all-on/all-off frames ([`calibrate`]), every scheme's measurement
//! vector formed from the frames the sequences support and reconstructed with `run`'s solver
//! through the same solve stage (crate::pipeline::solve_stage), scored against a truth when
//! one is given. No files are written here: crate::outputs::intake writes them.
//!
//! Simulated and measured data go through one pipeline: a record that `run --scope-record`
//! wrote gives, here, the frame values, measurements, reconstructions and scores of the run
//! itself, bit for bit.

pub mod calibrate;
pub mod frames;
pub mod record;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::acquisition::{
    PatternFamily, PatternSet, Scheme, Sequence, patterns_for_ratio, schemes::CALIBRATION_PAIRS,
};
use crate::detector::{Channel, FrameTiming, Record, SettleRule, SignalTrace};
use crate::error::{Error, Result};
use crate::pipeline::{Recorded, SchemeResult};
use crate::raster::Raster;
use crate::reconstruction::BitMatrix;
use crate::scene::run::RunSettings;

pub use calibrate::ArmCalibration;
pub use frames::{ChannelMap, FoundFrames, TriggerAnomaly};
pub use record::{Layout, ScopeRecord};

/// The four channel roles of `--channels`, in the order [RF, MON+, MON−, TRIG].
pub const ROLES: [&str; 4] = ["RF", "MON+", "MON-", "TRIG"];

/// Which record channel plays each role (None: the default, by label, then CH1…CH4).
#[derive(Debug, Clone, Default)]
pub struct ChannelNames(pub [Option<String>; 4]);

impl std::str::FromStr for ChannelNames {
    type Err = Error;

    /// `RF=CH1,MON+=CH2,MON-=CH3,TRIG=CH4` (any subset; `TRIG=none` for no trigger).
    fn from_str(s: &str) -> Result<ChannelNames> {
        let mut names: [Option<String>; 4] = Default::default();
        for part in s.split(',').filter(|p| !p.trim().is_empty()) {
            let (role, name) = part.split_once('=').ok_or_else(|| {
                Error::field("channels", format!("expected ROLE=NAME, got {part:?}"))
            })?;
            let role = role.trim().to_ascii_uppercase().replace('−', "-");
            let Some(i) = ROLES.iter().position(|r| *r == role) else {
                return Err(Error::field(
                    "channels",
                    format!("unknown role {role:?}; one of {}", ROLES.join(", ")),
                ));
            };
            names[i] = Some(name.trim().to_string());
        }
        Ok(ChannelNames(names))
    }
}

/// What to take in.
#[derive(Debug, Clone)]
pub struct IntakeRequest {
    /// Record files, or folders holding `record.csv`/`record.npy` (or one such folder per
    /// sequence, as `run --scope-record` writes `scope/`).
    pub inputs: Vec<PathBuf>,
    /// The patterns' folder (`patterns.npy`, `patterns.json`); default: each record's own.
    pub patterns: Option<PathBuf>,
    pub channels: ChannelNames,
    /// The DMD's frame rate when the record has no sidecar saying it (default: the settings').
    pub frame_rate_hz: Option<f64>,
    /// The ideal object (`.npy` of x, shown as 255·x/max x, or an 8-bit PNG).
    pub truth: Option<PathBuf>,
    /// The schemes, ratios, solver and settling time (a bench's `run` settings).
    pub settings: RunSettings,
}

/// One record taken in.
#[derive(Debug, Clone)]
pub struct IntakeRecord {
    pub path: PathBuf,
    pub layout: Layout,
    pub sequence: Sequence,
    pub timing: FrameTiming,
    /// Where the timing came from: `sidecar` or `settings`.
    pub timing_from: &'static str,
    pub channels: ChannelMap,
    pub channel_names: [String; 4],
    pub samples: usize,
    pub found: FoundFrames,
    /// The record's first samples of RF, MONITOR+, MONITOR− and TRIG, for the report.
    pub head: Vec<[f64; 4]>,
    pub sample_interval_s: f64,
    /// SHA-256 of the frames the DMD showed: the packed rows of `patterns.npy` (frames ×
    /// ⌈units/8⌉ bytes, most significant bit first), which `fit` compares with its bench's.
    pub patterns_sha256: String,
}

/// Everything intake found.
#[derive(Debug, Clone)]
pub struct Intake {
    pub records: Vec<IntakeRecord>,
    /// Per arm [+, −], from the calibrated sequence's preamble (None without one).
    pub calibration: Option<[ArmCalibration; 2]>,
    pub units: (usize, usize),
    pub base_patterns: usize,
    /// Scheme-major, ratio-minor; scores NaN without a truth.
    pub results: Vec<SchemeResult>,
    /// Frames clipped, per result (among those its scheme used).
    pub flagged: Vec<usize>,
    pub truth: Option<Raster>,
}

/// The sequence a pattern file describes.
#[derive(Debug, Clone, serde::Deserialize)]
struct PatternsFile {
    units_across: usize,
    units_down: usize,
    base_patterns: usize,
    frames: usize,
    #[serde(default)]
    family: Option<String>,
    #[serde(default)]
    ordering: Option<String>,
    #[serde(default)]
    seed: Option<u64>,
    #[serde(default)]
    sequence: Option<String>,
}

/// The base patterns and the sequence of a patterns folder, and the SHA-256 of its frames'
/// packed rows ([`IntakeRecord::patterns_sha256`]).
fn read_patterns(dir: &Path) -> Result<(PatternSet, Sequence, String)> {
    let json = dir.join("patterns.json");
    let text = std::fs::read_to_string(&json).map_err(|e| Error::read(&json, e))?;
    let meta: PatternsFile = serde_json::from_str(&text).map_err(|e| {
        Error::input(format!("not a patterns.json: {e}"))
            .in_file(&json)
            .at_line(e.line(), e.column())
    })?;
    let m = meta.base_patterns;
    let named = meta
        .sequence
        .as_deref()
        .and_then(|k| Sequence::all().into_iter().find(|q| q.key() == k));
    let sequence = named.unwrap_or(if meta.frames == 2 * m {
        Sequence::Complementary
    } else if meta.frames == m + 2 * CALIBRATION_PAIRS {
        Sequence::CalibratedBase
    } else {
        Sequence::Base
    });
    if sequence.frames(m) != meta.frames || m == 0 {
        return Err(Error::input(format!(
            "{} frames for {m} base patterns is not the {} sequence",
            meta.frames,
            sequence.key()
        ))
        .in_file(&json));
    }
    let npy = dir.join("patterns.npy");
    let a = crate::report::npy::read_bounded(&npy, "patterns", |_| (0.0, String::new()))?;
    let (w, h) = (meta.units_across, meta.units_down);
    let units = w * h;
    let row_bytes = units.div_ceil(8);
    let bytes = match &a.data {
        crate::npy::NpyData::U8(b) if a.shape == [meta.frames, row_bytes] => b,
        _ => {
            return Err(Error::input(format!(
                "expected uint8 of shape [{}, {row_bytes}], got {} {:?}",
                meta.frames,
                a.dtype(),
                a.shape
            ))
            .in_file(&npy));
        }
    };
    let sha = crate::provenance::sha256_hex(bytes);
    // The base patterns' rows in the sequence's frames.
    let row_of = |i: usize| match sequence {
        Sequence::Base => i,
        Sequence::Complementary => 2 * i,
        Sequence::CalibratedBase => 2 * CALIBRATION_PAIRS + i,
    };
    let bits = BitMatrix::from_fn(m, units, |i, j| {
        bytes[row_of(i) * row_bytes + j / 8] & (0x80 >> (j % 8)) != 0
    });
    // The family's own set when the file names one and its bits agree (a Hadamard set then
    // solves through the fast transform, as in `run`); the bits as given otherwise.
    let family = match (meta.family.as_deref(), meta.ordering.as_deref(), meta.seed) {
        (Some("random"), _, Some(seed)) => Some(PatternFamily::Random { seed }),
        (Some("hadamard"), Some(o), _) => crate::acquisition::HadamardOrdering::all()
            .into_iter()
            .find(|h| h.label() == o)
            .map(|ordering| PatternFamily::Hadamard { ordering }),
        _ => None,
    };
    if let Some(f) = family
        && let Ok(set) = f.build(w, h, m)
        && *set.base_patterns() == bits
    {
        return Ok((set, sequence, sha));
    }
    Ok((
        PatternSet::Random {
            width: w,
            height: h,
            seed: 0,
            patterns: bits,
        },
        sequence,
        sha,
    ))
}

/// The record files named by the inputs: files as given; a folder's `record.csv` (or
/// `record.npy`), or those of its sub-folders in name order.
pub fn record_files(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let own = |d: &Path| -> Option<PathBuf> {
        ["record.csv", "record.npy"]
            .iter()
            .map(|f| d.join(f))
            .find(|p| p.is_file())
    };
    let mut files = Vec::new();
    for p in inputs {
        if !p.is_dir() {
            files.push(p.clone());
            continue;
        }
        if let Some(f) = own(p) {
            files.push(f);
            continue;
        }
        let mut subs: Vec<PathBuf> = std::fs::read_dir(p)
            .map_err(|e| Error::read(p, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|d| d.is_dir())
            .collect();
        subs.sort();
        let found: Vec<PathBuf> = subs.iter().filter_map(|d| own(d)).collect();
        if found.is_empty() {
            return Err(Error::input(
                "no record here: a record file, or a folder holding record.csv or record.npy \
                 (or sub-folders that do)",
            )
            .in_file(p));
        }
        files.extend(found);
    }
    Ok(files)
}

/// The channel of each role: as named, else by the role's label, else CH1…CH4 in turn.
fn map_channels(rec: &ScopeRecord, names: &ChannelNames) -> Result<(ChannelMap, [String; 4])> {
    let mut idx = [None; 4];
    for (i, role) in ROLES.iter().enumerate() {
        idx[i] = match &names.0[i] {
            Some(n) if i == 3 && n.eq_ignore_ascii_case("none") => None,
            Some(n) => Some(rec.channel(n).ok_or_else(|| {
                Error::input(format!(
                    "no channel {n:?} (given for {role}) in the record; its channels: {}",
                    rec.names()
                ))
                .in_file(&rec.path)
            })?),
            None => rec.channel(role).or_else(|| {
                let by_column = rec.channel(&format!("CH{}", i + 1));
                // Without labels, CH1…CH4 in role order; TRIG only when a fourth exists.
                by_column.filter(|_| rec.labels.iter().all(Option::is_none))
            }),
        };
    }
    let mut signals = [0; 3];
    for i in 0..3 {
        signals[i] = idx[i].ok_or_else(|| {
            Error::input(format!(
                "no channel for {}: map one to it ({}=NAME); the record's channels: {}",
                ROLES[i],
                ROLES[i],
                rec.names()
            ))
            .in_file(&rec.path)
        })?;
    }
    let names = [0, 1, 2, 3].map(|i| idx[i].map_or("none".to_string(), |c| rec.columns[c].clone()));
    Ok((
        ChannelMap {
            signals,
            trigger: idx[3],
        },
        names,
    ))
}

/// The frame timing a record was made with: its sidecar's (`record.json` beside it), else the
/// frame rate given or the settings', the record's sample interval and the settings' settling.
fn record_timing(
    path: &Path,
    rec: &ScopeRecord,
    req: &IntakeRequest,
) -> Result<(FrameTiming, &'static str)> {
    #[derive(serde::Deserialize)]
    struct Side {
        frame_timing: FrameTimingFile,
    }
    #[derive(serde::Deserialize)]
    struct FrameTimingFile {
        frame_s: f64,
        settling_s: f64,
        sample_rate_hz: f64,
    }
    let side = path.with_extension("json");
    if req.frame_rate_hz.is_none()
        && let Ok(text) = std::fs::read_to_string(&side)
        && let Ok(s) = serde_json::from_str::<Side>(&text)
    {
        let t = s.frame_timing;
        return Ok((
            FrameTiming {
                frame_s: t.frame_s,
                settling_s: t.settling_s,
                sample_rate_hz: t.sample_rate_hz,
            },
            "sidecar",
        ));
    }
    let rate = req.frame_rate_hz.unwrap_or(req.settings.dmd_rate_hz);
    if !(rate.is_finite() && rate > 0.0) {
        return Err(Error::field(
            "frame_rate_hz",
            format!("must be positive, got {rate}"),
        ));
    }
    Ok((
        FrameTiming {
            frame_s: 1.0 / rate,
            settling_s: req.settings.settling_time_s,
            sample_rate_hz: 1.0 / rec.sample_interval_s,
        },
        "settings",
    ))
}

/// Reads the truth: a `.npy` of the object (shown as 255·x / max x, as `run` scores) or an
/// 8-bit PNG (0–255 as it is).
fn read_truth(path: &Path, (w, h): (usize, usize)) -> Result<Raster> {
    let is_npy = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    let r = if is_npy {
        let a = crate::report::npy::read_bounded(path, "the truth", |_| (0.0, String::new()))?;
        if a.shape != [h, w] {
            return Err(Error::input(format!(
                "the truth is {:?}, the patterns' units {h} × {w}",
                a.shape
            ))
            .in_file(path));
        }
        let x = Raster {
            width: w,
            height: h,
            data: a.to_f64(),
        };
        crate::pipeline::evaluate::truth_view(&x)
            .ok_or_else(|| Error::input("the truth has no positive value").in_file(path))?
    } else {
        crate::objects::image_file::load_image(path, w, h)?
    };
    Ok(r)
}

/// Takes one record in: read, channels mapped, timing, frames found and cut.
fn take_record(
    path: &Path,
    req: &IntakeRequest,
    expected: usize,
    pairs: usize,
    sequence: Sequence,
) -> Result<IntakeRecord> {
    let rec = record::read(path)?;
    let (map, names) = map_channels(&rec, &req.channels)?;
    let (timing, timing_from) = record_timing(path, &rec, req)?;
    let rule = SettleRule::of(timing);
    let found = frames::find_frames(&rec, &map, &rule, expected, pairs)?;
    let head_len = rec.samples().min((8.0 * rule.per_frame).ceil() as usize);
    let head = (0..head_len)
        .map(|n| {
            let s = map.signals.map(|c| rec.data[c][n]);
            let t = map.trigger.map_or(f64::NAN, |c| rec.data[c][n]);
            [s[0], s[1], s[2], t]
        })
        .collect();
    Ok(IntakeRecord {
        path: path.to_path_buf(),
        layout: rec.layout,
        sequence,
        timing,
        timing_from,
        channels: map,
        channel_names: names,
        samples: rec.samples(),
        found,
        head,
        sample_interval_s: rec.sample_interval_s,
        patterns_sha256: String::new(),
    })
}

/// A found record as the solve stage reads it.
fn as_record(r: &IntakeRecord) -> Record {
    let f = &r.found.frames;
    let counts: Vec<usize> = f.iter().map(|x| x.settled_samples).collect();
    Record {
        frames: f.iter().map(|x| x.values).collect(),
        clipped: f.iter().map(|x| x.clipped).collect(),
        over_range: vec![0; f.len()],
        settled_samples: (
            counts.iter().copied().min().unwrap_or(0),
            counts.iter().copied().max().unwrap_or(0),
        ),
        samples: r.samples as u64,
        trace: SignalTrace {
            t_s: Vec::new(),
            v: [Vec::new(), Vec::new(), Vec::new()],
            frames: 0,
        },
    }
}

/// Takes the records in, calibrates, forms every scheme's measurements, reconstructs and
/// scores.
pub fn intake(req: &IntakeRequest) -> Result<Intake> {
    let files = record_files(&req.inputs)?;
    let mut records: Vec<IntakeRecord> = Vec::new();
    let mut set: Option<PatternSet> = None;
    for path in &files {
        let dir = req
            .patterns
            .clone()
            .unwrap_or_else(|| path.parent().unwrap_or(Path::new(".")).to_path_buf());
        let (s, sequence, sha) = read_patterns(&dir)?;
        if records.iter().any(|r| r.sequence == sequence) {
            return Err(Error::input(format!(
                "a second record of the {} sequence",
                sequence.key()
            ))
            .in_file(path));
        }
        let m = s.measurements();
        match &set {
            Some(first) if first.measurements() != m || first.units() != s.units() => {
                return Err(Error::input(
                    "the records' patterns differ from the first record's (base patterns or units)",
                )
                .in_file(&dir.join("patterns.json")));
            }
            Some(_) => {}
            None => set = Some(s),
        }
        let pairs = if sequence == Sequence::CalibratedBase {
            CALIBRATION_PAIRS
        } else {
            0
        };
        let mut taken = take_record(path, req, sequence.frames(m), pairs, sequence)?;
        taken.patterns_sha256 = sha;
        records.push(taken);
    }
    let set = set.ok_or_else(|| Error::input("no record to take in"))?;
    let (w, h) = (set.width(), set.height());
    let m_max = set.measurements();
    let calibration = records
        .iter()
        .find(|r| r.sequence == Sequence::CalibratedBase)
        .map(|r| calibrate::calibrate(&r.found.frames));
    let truth = req
        .truth
        .as_deref()
        .map(|p| read_truth(p, (w, h)))
        .transpose()?;
    let schemes: Vec<Scheme> = req
        .settings
        .schemes
        .iter()
        .copied()
        .filter(|s| records.iter().any(|r| r.sequence == s.sequence()))
        .collect();
    let ratios: Vec<f64> = req
        .settings
        .sampling_ratios
        .iter()
        .copied()
        .filter(|&r| patterns_for_ratio(r, w * h) <= m_max)
        .collect();
    let recorded = Recorded {
        patterns: Arc::new(set),
        timing: records[0].timing,
        channels: [Channel {
            volts_per_div: 0.0,
            offset_v: 0.0,
            noise_v_rms: 0.0,
            lsb_v: 0.0,
            bits: 0,
        }; 3],
        records: records.iter().map(|r| (r.sequence, as_record(r))).collect(),
        sequences: Vec::new(),
        saturation: Vec::new(),
    };
    let zero = Raster {
        width: w,
        height: h,
        data: vec![0.0; w * h],
    };
    let quiet: crate::pipeline::Progress = &|_, _, _| {};
    let mut results = crate::pipeline::solve_stage(
        &recorded,
        &schemes,
        &ratios,
        truth.as_ref().unwrap_or(&zero),
        &crate::pipeline::evaluate::run_solver(&req.settings),
        None,
        quiet,
    )?;
    if truth.is_none() {
        for r in &mut results {
            (r.psnr_db, r.mssim) = (f64::NAN, f64::NAN);
        }
    }
    let flagged = results
        .iter()
        .map(|r| {
            let rec = recorded.record(r.scheme.sequence());
            rec.map_or(0, |rec| {
                let n = r.dmd_frames.min(rec.clipped.len());
                rec.clipped[..n]
                    .iter()
                    .filter(|&&b| r.scheme.outputs().iter().any(|o| b & (1 << o.index()) != 0))
                    .count()
            })
        })
        .collect();
    Ok(Intake {
        records,
        calibration,
        units: (w, h),
        base_patterns: m_max,
        results,
        flagged,
        truth,
    })
}

/// The settings' solver key, for the summary.
pub fn settings_of(doc: &crate::scene::doc::BenchDoc) -> Result<RunSettings> {
    Ok(doc.run_scene()?.settings)
}

#[cfg(test)]
mod tests;
