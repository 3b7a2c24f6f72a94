//! Fuzz target: the NIST `.ds` parser never panics; accepted files have exactly the announced
//! number of finite points.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    match truepos_io::points::parse_ds(Path::new("fuzz.ds"), data) {
        Ok(pts) => assert!(pts.iter().all(|p| p.x.is_finite() && p.y.is_finite() && p.z.is_finite())),
        Err(e) => assert!(e.file.is_some()),
    }
});
