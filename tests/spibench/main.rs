//! The integration tests: the command line end to end, bad input, determinism across thread
//! counts, and the paper's claims on small problems. One binary, so CI links once.

mod cli_dataset;
mod cli_layout;
mod cli_reconstruct;
mod cli_run;
mod cli_simulate;
mod cli_sweep;
mod common;
mod layering;
mod paper;
mod validation;
