//! Fuzz target: the G-code layer never panics on any text; printing a parsed program gives the
//! text back byte for byte; the identity transform either refuses (with a location) or returns
//! the program unchanged; a small rotation + translation never panics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use truepos_gcode::{Program, TransformOptions};
use truepos_math::types::rz;
use truepos_math::{Transform3, Vector3};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let p = Program::parse(text);
    assert_eq!(p.to_string(), text);
    let _ = p.check();
    let _ = p.blocks();
    match p.transform(&Transform3::identity(), &TransformOptions::default()) {
        Ok(out) => assert_eq!(out, text),
        Err(e) => assert!(e.line() >= 1 && e.column() >= 1),
    }
    let t = Transform3::new(1.0001, rz(0.01), Vector3::new(1.0, -2.0, 0.5));
    if let Ok(out) = p.transform(&t, &TransformOptions::default()) {
        // The rewritten program parses, and has as many lines.
        assert_eq!(Program::parse(&out).lines.len(), p.lines.len());
    }
});
