//! The integration tests: the command line end to end, bad input, determinism across thread
//! counts, and the paper's claims on small problems. One binary, so CI links once.

mod bad_input;
mod cli_budget;
mod cli_dataset;
mod cli_fit;
mod cli_intake;
mod cli_layout;
mod cli_lens;
mod cli_misc;
mod cli_reconstruct;
mod cli_run;
mod cli_simulate;
mod cli_sweep;
mod cli_tolerance;
mod cli_trace;
mod common;
mod condenser;
mod dataset_provenance;
mod dmd;
mod figures;
mod findings;
mod fuzz;
mod kernel_offset;
mod kernel_se;
mod layering;
mod memory;
mod output_dirs;
mod outputs_schema;
mod paper;
mod planted_links;
mod reference_docs;
mod untrusted;
mod validation;
