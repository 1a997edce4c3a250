//! `spibench intake DIR|FILES [--patterns DIR] [--channels RF=…,MON+=…,MON-=…,TRIG=…]
//! [--frame-rate-hz F] [--truth FILE] [--bench FILE] [--out DIR]`: oscilloscope records of a
//! built bench in, frames found, arms calibrated, every scheme reconstructed (crate::intake);
//! the files it writes are crate::outputs::intake's.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::intake::{ChannelNames, IntakeRequest};
use crate::report::output::OutputDir;
use crate::scene::doc::BenchDoc;

#[derive(Debug, Clone, Args)]
pub struct IntakeArgs {
    /// Record files (CSV exports of Tektronix, Keysight or Rigol scopes, or `.npy` with its
    /// `.json` sidecar), or folders holding `record.csv`/`record.npy`, or a folder of such
    /// folders (a run's `scope/`).
    #[arg(required = true, value_name = "DIR|FILES")]
    pub inputs: Vec<PathBuf>,
    /// The patterns' folder (`patterns.npy`, `patterns.json` as `spibench patterns` writes
    /// them); default: each record's own folder.
    #[arg(long, value_name = "DIR")]
    pub patterns: Option<PathBuf>,
    /// Which record channel is which, e.g. `RF=CH1,MON+=CH2,MON-=CH3,TRIG=CH4` (`TRIG=none`:
    /// no trigger). Default: the channels labelled so, else CH1…CH4 in that order.
    #[arg(long, value_name = "ROLE=NAME,…")]
    pub channels: Option<String>,
    /// The DMD's frame rate when the record has no sidecar with its timing (default: the
    /// bench's `run.dmd_rate_hz`).
    #[arg(long, value_name = "F")]
    pub frame_rate_hz: Option<f64>,
    /// The ideal object to score against: a `.npy` of x (scored as 255·x/max x, as `run`
    /// scores; a run's `arrays/transport_x_w.npy`) or an 8-bit PNG.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// The bench whose `run` settings (schemes, ratios, solver, settling time) apply; default:
    /// the paper's bench built in (a run's `bench.ron` reproduces the run's settings).
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Output folder (created; files of the same names are replaced).
    #[arg(long, default_value = "out/intake", value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
}

/// Runs `spibench intake`.
pub fn run(args: &IntakeArgs) -> Result<()> {
    if let Some(f) = args.frame_rate_hz
        && !(f.is_finite() && f > 0.0)
    {
        return Err(crate::Error::field(
            "--frame-rate-hz",
            format!("must be a positive frame rate, got {f}"),
        )
        .into());
    }
    let doc = BenchDoc::open(args.bench.as_deref())?;
    let settings = crate::intake::settings_of(&doc)?;
    let channels: ChannelNames = match &args.channels {
        Some(c) => c
            .parse()
            .map_err(|e: crate::Error| e.at_field("--channels"))?,
        None => ChannelNames::default(),
    };
    let req = IntakeRequest {
        inputs: args.inputs.clone(),
        patterns: args.patterns.clone(),
        channels,
        frame_rate_hz: args.frame_rate_hz,
        truth: args.truth.clone(),
        settings,
    };
    let out = OutputDir::create(&args.out)?;
    let intake = crate::intake::intake(&req)?;
    let mut provenance = crate::provenance::Provenance::new(&[]);
    for r in &intake.records {
        provenance = provenance.file(&r.path)?;
    }
    if let Some(t) = &args.truth {
        provenance = provenance.file(t)?;
    }
    let files = crate::outputs::intake::write(&intake, &provenance, &out)?;
    let dir = out.commit()?;
    for line in crate::outputs::intake::printed(&intake) {
        println!("{line}");
    }
    println!("wrote {} ({} files)", dir.display(), files.len());
    Ok(())
}
