//! The command line: subcommands over the library. `anyhow` lives only here.
//!
//! Exit status: 0 on success, 2 for input a user can fix (a malformed file, an unknown field,
//! impossible values, a missing file; also clap's usage errors), 1 for anything else.

mod align;
mod args;
mod check;
mod completions;
mod dataset;
mod export;
mod fit;
pub mod flags;
mod help;
mod intake;
mod layout;
mod lens;
mod patterns;
pub(crate) mod progress;
mod reconstruct;
mod run;
mod simulate;
mod sweep;
mod tolerance;
mod trace;

use clap::{CommandFactory, Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(
    name = "spibench",
    version,
    about = "Optical-bench simulator for DMD single-pixel imaging with complementary and balanced detection"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Worker threads (default: all cores; RAYON_NUM_THREADS also works). Results are
    /// identical for any count.
    #[arg(long, global = true, value_name = "N")]
    threads: Option<usize>,
    /// Errors and warnings only: no progress and no notes on stderr.
    #[arg(long, short, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Also print stage timings and settings on stderr.
    #[arg(long, short, global = true)]
    verbose: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    // The whole traced experiment; its description counts the schemes from their table.
    #[command(about = help::run_about(), long_about = None)]
    Run(run::RunArgs),
    /// Trace one bench over a 1-D or 2-D grid of bench variables with common random numbers:
    /// k±, b±, imbalance, leak and power at every point, with standard errors of each point and
    /// of its difference from the nominal bench.
    Sweep(sweep::SweepArgs),
    /// Tolerance analysis: sensitivity table, Monte Carlo of built benches with compensators,
    /// yields (metrics and image quality per scheme), RSS against Monte Carlo.
    Tolerance(tolerance::ToleranceArgs),
    /// Find the free bench variables that balance the arms, maximise the light, or minimise a
    /// weighted sum of metrics (Nelder–Mead on common-random-number traces).
    Align(align::AlignArgs),
    /// Run one of the paper's idealised simulations (scalar k±, b±, additive noise, no optics).
    Simulate(simulate::SimulateArgs),
    /// Reconstruct measurements that came from elsewhere (a real bench or another simulator).
    Reconstruct(reconstruct::ReconstructArgs),
    /// Trace a bench: k±, b±, the per-unit transport maps and the flux ledger.
    Trace(trace::TraceArgs),
    /// Export a bench as a Mitsuba 3 scene (the monochromatic, constant-index substitute unless --as-is).
    ExportMitsuba(export::ExportArgs),
    /// Draw a bench (top view, side view, the plane of the arms) with a fan of traced rays, as
    /// SVG and PNG.
    Layout(layout::LayoutArgs),
    /// Read and validate a bench; print its paraxial design numbers and a short traced footprint
    /// on each diode beside them.
    Check(check::CheckArgs),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell) to stdout.
    Completions(completions::CompletionsArgs),
    /// Write the man pages (spibench.1 and one per command) into a folder.
    Man(completions::ManArgs),
    /// Make a synthetic dataset: many objects measured through one traced bench (an object
    /// kernel), sharded, resumable, as .npy arrays with a manifest.
    Dataset(dataset::DatasetArgs),
    /// Export a pattern set as packed .npy and 1-bit PNG frames at the DMD's mirror resolution.
    Patterns(patterns::PatternsArgs),
    /// A lens prescription (.zmx): surface table, paraxial EFL, BFL and FFL, and a fan of real
    /// rays with their intercepts and the RMS spot.
    Lens(lens::LensArgs),
    /// Take in oscilloscope records of a built bench: frames found, arms calibrated, every
    /// scheme reconstructed with `run`'s solver and scored (the records of `run --scope-record`
    /// give back the run's own results).
    Intake(intake::IntakeArgs),
    /// Fit the bench as built: free misalignments fitted to an intake folder's frames, with
    /// standard errors, the directions the data do not fix, and the compensators that
    /// rebalance it.
    Fit(fit::FitArgs),
}

impl Command {
    /// `--allow-large`, which lifts the memory limit (`crate::memory`) as well as the work limits.
    fn allow_large(&self) -> bool {
        let work = match self {
            Command::Run(a) => a.work,
            Command::Sweep(a) => a.work,
            Command::Tolerance(a) => a.work,
            Command::Align(a) => a.work,
            Command::Reconstruct(a) => a.work,
            Command::Trace(a) => a.work,
            Command::ExportMitsuba(a) => a.work,
            Command::Layout(a) => a.work,
            Command::Check(a) => a.work,
            Command::Dataset(a) => a.work,
            Command::Patterns(a) => a.work,
            Command::Intake(a) => a.work,
            Command::Fit(a) => a.work,
            Command::Simulate(_) | Command::Completions(_) | Command::Man(_) | Command::Lens(_) => {
                return false;
            }
        };
        work.allow_large
    }
}

/// The command line's definition (every command, argument, default and help text), for the
/// generated reference (docs/reference/commands.md) and tools that describe it.
pub fn command() -> clap::Command {
    Cli::command()
}

/// Runs the command line and returns the process exit status.
pub fn main() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    progress::set_verbosity(if cli.quiet {
        progress::Verbosity::Quiet
    } else if cli.verbose {
        progress::Verbosity::Verbose
    } else {
        progress::Verbosity::Normal
    });
    if let Some(n) = cli.threads {
        if n == 0 || n > 4096 {
            eprintln!("error: --threads must lie between 1 and 4096, got {n}");
            return 2;
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: cannot start {n} threads: {e}");
            return 1;
        }
    }
    // SIGINT and SIGTERM remove the staging folders of a run in progress (exit 130, 143).
    crate::report::output::install_signal_cleanup();
    if cli.command.allow_large() {
        crate::memory::allow_large();
    }
    let result = match &cli.command {
        Command::Simulate(a) => simulate::run(a),
        Command::Reconstruct(a) => reconstruct::run(a),
        Command::Trace(a) => trace::run(a),
        Command::ExportMitsuba(a) => export::run(a),
        Command::Run(a) => run::run(a),
        Command::Sweep(a) => sweep::run(a),
        Command::Tolerance(a) => tolerance::run(a),
        Command::Align(a) => align::run(a),
        Command::Layout(a) => layout::run(a),
        Command::Check(a) => check::run(a),
        Command::Completions(a) => completions::completions(a, Cli::command()),
        Command::Man(a) => completions::man(a, Cli::command()),
        Command::Dataset(a) => dataset::run(a),
        Command::Patterns(a) => patterns::run(a),
        Command::Lens(a) => lens::run(a),
        Command::Intake(a) => intake::run(a),
        Command::Fit(a) => fit::run(a),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            let e = flags::relocate_any(e);
            eprintln!("error: {}", render_error(&e));
            exit_status(&e)
        }
    }
}

/// How 0/1 (traditional CS) measurements are solved, as `reconstruct` and `simulate` spell it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ZeroOneArg {
    /// Solve the exactly equivalent zero-mean system with the DC row down-weighted (converges
    /// like the ±1 schemes).
    #[value(name = "zero-mean")]
    ZeroMean,
    /// The zero-mean system without the DC row: for data with an unknown constant offset
    /// (detector bias, dark current, ambient light).
    #[value(name = "zero-mean-offset")]
    ZeroMeanOffset,
    /// Solve A = P as measured (the paper's handling; slow: the DC singular value).
    #[value(name = "plain")]
    Plain,
}

impl From<ZeroOneArg> for crate::reconstruction::ZeroOneHandling {
    fn from(a: ZeroOneArg) -> Self {
        match a {
            ZeroOneArg::ZeroMean => Self::ZeroMean,
            ZeroOneArg::ZeroMeanOffset => Self::ZeroMeanOffset,
            ZeroOneArg::Plain => Self::Plain,
        }
    }
}

/// Parses `PATH=VALUE` (a bench variable and a number) from the command line.
pub(crate) fn parse_assignment(text: &str, flag: &str) -> crate::Result<(String, f64)> {
    let bad = |why: &str| crate::Error::field(flag, format!("`{text}`: {why}"));
    let (path, value) = text
        .split_once('=')
        .ok_or_else(|| bad("expected PATH=VALUE"))?;
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|_| bad("the value is not a number"))?;
    if !value.is_finite() {
        return Err(bad("the value must be finite"));
    }
    Ok((path.trim().to_string(), value))
}

/// One paragraph: the error and its causes.
fn render_error(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = vec![e.to_string()];
    for cause in e.chain().skip(1) {
        let s = cause.to_string();
        if !parts.iter().any(|p| p.contains(&s)) {
            parts.push(s);
        }
    }
    parts.join(": ")
}

fn exit_status(e: &anyhow::Error) -> i32 {
    match e.chain().find_map(|c| c.downcast_ref::<crate::Error>()) {
        Some(err) if err.is_user_error() => 2,
        _ => 1,
    }
}
