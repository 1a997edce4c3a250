//! `spibench trace [SCENE] [--set PATH=VALUE …] [--rays N] [--seed S] [--out DIR]
//! [--irradiance-at NAME …]`: transport only — k±, b±, the per-unit maps and the flux ledger of
//! a traced bench, the irradiance maps on the diodes and at any named surface (outputs:
//! crate::outputs::trace, crate::outputs::irradiance). Everything is computed in memory and written into a staging folder
//! that is renamed into place at the end, so bad input or a failed write leaves no partial
//! output.

use crate::error::Error;
use crate::outputs::irradiance::IrradianceSummary;
use crate::outputs::trace::{DiffractionSummary, printed, summarize, write};
use crate::pipeline::{CacheStatus, Traced};
use crate::report::output::OutputDir;
use crate::trace::TraceOptions;
use crate::trace::collection::diffraction_pair;
use crate::trace::irradiance::{DEFAULT_BINS, trace_with_maps, trace_with_surface_maps};

/// Arguments of `spibench trace`.
#[derive(Debug, Clone, clap::Args)]
#[command(
    mut_arg("rays", |a| a.help(super::args::rays_help("Lamp rays to trace", DEFAULT_RAYS))),
    mut_arg("seed", |a| a.default_value("1")),
    mut_arg("out", |a| a.default_value("out/trace")),
)]
pub struct TraceArgs {
    #[command(flatten)]
    pub bench: super::args::BenchArgs,
    #[command(flatten)]
    pub opts: super::args::RunOpts,
    #[command(flatten)]
    pub work: super::args::WorkArgs,
    /// Also map the power meeting this element's first surface (a baffle's or an aperture's
    /// plate, a filter's or a lens's front face): irradiance_at_NAME.npy, its
    /// standard errors, a figure and summary.json's `irradiance_at`, from the same trace. A path
    /// is booked each time it meets the surface, in either direction
    #[arg(long = "irradiance-at", value_name = "NAME")]
    pub irradiance_at: Vec<String>,
}

/// `trace`'s ray count when neither `--rays` nor the bench file's `run.rays` gives one.
pub const DEFAULT_RAYS: u64 = 2_000_000;

/// Runs `spibench trace`.
pub fn run(args: &TraceArgs) -> anyhow::Result<()> {
    let doc = args.bench.load()?;
    let bench = doc.build()?;
    if bench.dmd().is_none() {
        return Err(Error::field("dmd", "`trace` needs a bench with a DMD")
            .in_file(doc.path())
            .into());
    }
    let rays = args.opts.rays(&doc, DEFAULT_RAYS)?;
    // The file names of the named surfaces' maps, checked before the trace.
    crate::outputs::irradiance::file_stems(&args.irradiance_at)?;
    let seed = args.opts.seed();
    let out = args.opts.out_or("out/trace");
    let start = std::time::Instant::now();
    let bar = super::progress::bar(rays, "rays");
    let report = |done: u64, _: u64| bar.set_position(done);
    // The irradiance maps on the diodes and at the named surfaces come from the same paths
    // (no second pass); an unknown name is refused before a ray is traced.
    let options = TraceOptions {
        progress: Some(&report),
        ..TraceOptions::new(rays, seed)
    };
    let (tallies, irradiance) = if args.irradiance_at.is_empty() {
        trace_with_maps(&bench, &options, DEFAULT_BINS)?
    } else {
        trace_with_surface_maps(&bench, &options, DEFAULT_BINS, &args.irradiance_at)?
    };
    let traced = Traced::from_tallies(&bench, tallies, CacheStatus::Off);
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    // No light on the pattern area is the bench's fault, not a result: exit 2, naming the cause.
    traced.truth().map_err(|e| e.in_file(doc.path()))?;
    let t = &traced.transport;
    let mut summary = summarize(&doc.name(), &bench, t, &traced.metrics, traced.arrivals());
    summary.irradiance = Some(IrradianceSummary::of(&irradiance));
    summary.irradiance_at = crate::outputs::irradiance::surfaces_of(&irradiance);
    let provenance = crate::provenance::Provenance::of_bench(&doc, &[seed])?;
    let collections = match bench.dmd().and_then(|s| s.dmd.diffraction()) {
        Some(_) => {
            let (n, c) = diffraction_pair(&bench, rays, seed)?;
            summary.dmd_diffraction = Some(DiffractionSummary::of(n, &c));
            Some(c)
        }
        None => None,
    };
    let dir = OutputDir::create(&out)?;
    write(
        &dir,
        t,
        &mut summary,
        &provenance,
        collections.as_ref(),
        &bench,
    )?;
    let mut mapped = crate::outputs::irradiance::write(&dir, &irradiance)?;
    summary.files.append(&mut mapped);
    crate::outputs::summary::write_summary(&dir, &summary, &provenance)?;
    dir.commit()?;
    let json = serde_json::to_value(&summary)?;
    for line in crate::outputs::trace::card(&json).printed() {
        println!("{line}");
    }
    for line in printed(&summary, seconds) {
        println!("{line}");
    }
    // The folder and a count: the file list is in summary.json (`files`), and a line per file
    // would not fit a terminal.
    println!(
        "wrote {} ({} files: summary.json, maps.exr and the per-unit maps x, g±, k± as SVG, PNG and PDF)",
        out.display(),
        summary.files.len() + 1
    );
    Ok(())
}
