//! The command line: subcommands over the library. `anyhow` lives only here.

/// Runs the command line and returns the process exit status.
pub fn main() -> i32 {
    0
}
