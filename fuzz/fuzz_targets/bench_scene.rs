//! Any text as a bench file: parsing and validation never panic, and an accepted bench traces
//! (two batches of rays) to finite numbers or to an input error.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use spibench::pipeline::{TraceRequest, trace_stage};
use spibench::scene::doc::BenchDoc;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz.ron");
    let scene = match BenchDoc::parse(text, path).and_then(|d| d.run_scene()) {
        Ok(s) => s,
        Err(e) => {
            assert!(e.is_user_error(), "not an input error: {e}");
            return;
        }
    };
    if scene.bench.dmd().is_none() {
        return;
    }
    let rays = 2 * spibench::trace::RAYS_PER_BATCH;
    match trace_stage(&scene.bench, &TraceRequest::new(rays, 1)) {
        Ok(t) => {
            if t.truth().is_ok() {
                let m = format!("{:?}", t.metrics);
                assert!(!m.contains("NaN") && !m.contains("inf"), "{m}");
            }
        }
        Err(e) => assert!(e.is_user_error(), "not an input error: {e}"),
    }
});
