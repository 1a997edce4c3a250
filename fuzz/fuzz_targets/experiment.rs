//! Any text as an experiment file: parsing and validation never panic, and every error is an
//! input error.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = spibench::scene::experiment::parse(text, Path::new("fuzz.ron"), Path::new(".")) {
        assert!(e.is_user_error(), "not an input error: {e}");
    }
});
