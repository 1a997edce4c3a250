//! Progress for every command, in one style: a bar on a terminal, a log line every few seconds
//! when stderr is a file or a pipe (so batch logs are not silent for a whole run), nothing with
//! `--quiet`. The library never draws: it reports (done, total) through callbacks, and this is
//! where they become bars.
//!
//! The bar stays under 80 columns: `   rays [=========>          ] 1.20 M/2.00 M 190 k/s eta 4s`.

use std::io::{IsTerminal, Write as _};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU8, Ordering};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle, TermLike};

/// How much a command says on stderr: set once from `--quiet` / `--verbose`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verbosity {
    /// Errors and warnings only.
    Quiet = 0,
    /// Progress and the short notes of each command.
    Normal = 1,
    /// Also stage timings and settings.
    Verbose = 2,
}

static VERBOSITY: AtomicU8 = AtomicU8::new(Verbosity::Normal as u8);

pub fn set_verbosity(v: Verbosity) {
    VERBOSITY.store(v as u8, Ordering::Relaxed);
}

pub fn verbosity() -> Verbosity {
    match VERBOSITY.load(Ordering::Relaxed) {
        0 => Verbosity::Quiet,
        1 => Verbosity::Normal,
        _ => Verbosity::Verbose,
    }
}

/// Seconds between log lines when stderr is not a terminal.
const LOG_INTERVAL: Duration = Duration::from_secs(5);

/// A number with an SI prefix and three significant digits: 950, 1.20 k, 2.00 M.
pub fn si(v: f64) -> String {
    let a = v.abs();
    let (scaled, prefix) = if a >= 1e9 {
        (v / 1e9, " G")
    } else if a >= 1e6 {
        (v / 1e6, " M")
    } else if a >= 1e3 {
        (v / 1e3, " k")
    } else {
        return format!("{v:.0}");
    };
    let digits = if scaled.abs() >= 100.0 {
        0
    } else if scaled.abs() >= 10.0 {
        1
    } else {
        2
    };
    format!("{scaled:.digits$}{prefix}")
}

fn style(with_bar: bool) -> ProgressStyle {
    let template = if with_bar {
        "{msg:>8} [{bar:20}] {pos_si}/{len_si} {rate_si} eta {eta}"
    } else {
        "{msg:>8} {pos_si}/{len_si} ({percent} %) {rate_si}, {elapsed} elapsed, eta {eta}"
    };
    ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .with_key(
            "pos_si",
            |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{}", si(s.pos() as f64));
            },
        )
        .with_key(
            "len_si",
            |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{}", si(s.len().unwrap_or(0) as f64));
            },
        )
        .with_key(
            "rate_si",
            |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{}/s", si(s.per_sec()));
            },
        )
        .progress_chars("=> ")
}

/// A progress reporter for `total` steps of `what` (a short noun: "rays", "frames", "cells").
/// Drawn as a bar on a terminal, as a log line every few seconds otherwise, never with
/// `--quiet`.
pub fn bar(total: u64, what: &str) -> ProgressBar {
    if verbosity() == Verbosity::Quiet {
        return ProgressBar::hidden();
    }
    let terminal = std::io::stderr().is_terminal();
    let target = if terminal {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::term_like_with_hz(Box::new(LogLines::default()), 1)
    };
    let pb = ProgressBar::with_draw_target(Some(total), target);
    pb.set_style(style(terminal));
    pb.set_message(what.to_string());
    pb
}

/// A "terminal" that writes a drawn progress line to stderr at most every [`LOG_INTERVAL`],
/// as a plain line (no cursor movement): progress for logs.
#[derive(Debug, Default)]
struct LogLines {
    last: Mutex<Option<Instant>>,
}

impl LogLines {
    fn emit(&self, s: &str) -> std::io::Result<()> {
        let line = s.trim();
        if line.is_empty() {
            return Ok(());
        }
        let Ok(mut last) = self.last.lock() else {
            return Ok(());
        };
        let now = Instant::now();
        // The first draw is at start (nothing to report yet); then one line per interval.
        match *last {
            None => *last = Some(now),
            Some(t) if now.duration_since(t) >= LOG_INTERVAL => {
                *last = Some(now);
                writeln!(std::io::stderr(), "{line}")?;
            }
            Some(_) => {}
        }
        Ok(())
    }
}

impl TermLike for LogLines {
    fn width(&self) -> u16 {
        100
    }
    fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.emit(s)
    }
    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.emit(s)
    }
    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

/// A note on stderr (what a command is doing), unless `--quiet`.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {
        if $crate::cli::progress::verbosity() != $crate::cli::progress::Verbosity::Quiet {
            eprintln!($($arg)*);
        }
    };
}

/// A detail on stderr, only with `--verbose`.
#[macro_export]
macro_rules! detail {
    ($($arg:tt)*) => {
        if $crate::cli::progress::verbosity() == $crate::cli::progress::Verbosity::Verbose {
            eprintln!($($arg)*);
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn si_prefixes() {
        assert_eq!(si(950.0), "950");
        assert_eq!(si(1200.0), "1.20 k");
        assert_eq!(si(2_000_000.0), "2.00 M");
        assert_eq!(si(190_400.0), "190 k");
        assert_eq!(si(12_345_678.0), "12.3 M");
    }

    /// The widest bar line stays under 80 columns.
    #[test]
    fn bar_fits_80_columns() {
        let line = format!(
            "{:>8} [{}] {}/{} {}/s eta {}",
            "frames",
            " ".repeat(20),
            si(999_999_999.0),
            si(999_999_999.0),
            si(999_999.0),
            "59m 59s"
        );
        assert!(line.chars().count() < 80, "{} columns: {line}", line.len());
    }
}
