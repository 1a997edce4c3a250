//! Experiment files for `spibench simulate` (the paper's idealised simulations).
