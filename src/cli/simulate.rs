//! `spibench simulate EXPERIMENT [--out DIR] [--zero-one HANDLING]`: one of the paper's idealised
//! simulations (crate::simulation); the files are crate::outputs::simulate's.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;

use crate::outputs::simulate::{printed, write};
use crate::report::output::OutputDir;
use crate::scene::experiment;
use crate::simulation;

#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// An experiment file (RON), or a built-in experiment: fig1, fig2, fig3, fig4.
    pub experiment: String,
    /// Output folder (created; files of the same name are replaced). Default: out/<experiment>.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// How traditional (0/1) measurements are solved, overriding the experiment's `zero_one`:
    /// zero-mean (the exactly equivalent zero-mean system) or plain (A = P, the paper's).
    #[arg(long, value_enum)]
    pub zero_one: Option<super::ZeroOneArg>,
}

pub fn run(args: &SimulateArgs) -> Result<()> {
    let mut exp = experiment::load(&args.experiment)?;
    if let Some(z) = args.zero_one {
        exp.zero_one = z.into();
    }
    let stem = std::path::Path::new(&args.experiment)
        .file_stem()
        .map_or_else(
            || "experiment".to_string(),
            |s| s.to_string_lossy().into_owned(),
        );
    let out_dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(&stem));
    let out = OutputDir::create(&out_dir)?;

    let start = Instant::now();
    let total = exp.objects.len() * exp.sampling_ratios.len() * exp.cases.len();
    let pb = super::progress::bar(total as u64, "cells");
    let result = simulation::run(&exp, &|done, _| pb.set_position(done as u64))
        .map_err(|e| exp.locate(e))?;
    pb.finish_and_clear();
    let wall = start.elapsed().as_secs_f64();

    let provenance = crate::provenance::Provenance::new(&[exp.seed]);
    let provenance = if std::path::Path::new(&args.experiment).is_file() {
        provenance.file(std::path::Path::new(&args.experiment))?
    } else {
        provenance // a built-in experiment: named on the command line, built into the binary
    };
    write(&exp, &args.experiment, &result, &out, wall, &provenance)?;
    let dir = out.commit()?;
    for line in printed(&exp, &result.cells) {
        println!("{line}");
    }
    println!(
        "wrote {} ({} cells, {:.1} s)",
        dir.display(),
        result.cells.len(),
        wall
    );
    Ok(())
}
