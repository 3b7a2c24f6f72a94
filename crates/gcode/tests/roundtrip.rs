//! Lossless round trip: print(parse(s)) == s for any text, parse(print(p)) == p, and the
//! identity transform returns every program byte for byte.

use proptest::prelude::*;
use truepos_gcode::{Program, TransformOptions};
use truepos_math::Transform3;

/// G-code-like lines: words, comments, spacing, odd tokens, both line endings.
fn gcode_text() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        "[GMXYZIJKRFSTNOgxyz][+-]?[0-9]{0,4}(\\.[0-9]{0,4})?",
        "\\([^)\\n]{0,12}\\)?",
        ";[^\\n]{0,10}",
        "[ \\t]{1,3}",
        "%",
        "#[0-9]=[0-9.]{1,3}",
        "[A-Z]\\[[#0-9+*]{0,5}\\]",
        "\\([a-z ]{0,4}\\([a-z X9]{0,4}\\)[a-z X9]{0,4}\\)",
        "#<[a-z_]{1,4}> ?= ?[0-9.\\-]{1,3}",
        "[XYZ]-?#[0-9<>a-z]{1,3}",
        "[XYZ][A-Z]{1,4}\\[[0-9]{1,2}\\]",
        "[^\\n]{1,3}",
    ];
    let line = prop::collection::vec(token, 0..8).prop_map(|t| t.concat());
    (prop::collection::vec((line, prop_oneof!["\n", "\r\n"]), 0..20), any::<bool>()).prop_map(
        |(lines, last)| {
            let mut s: String = lines.iter().map(|(l, e)| format!("{l}{e}")).collect();
            if last {
                s.push_str("G1 X1");
            }
            s
        },
    )
}

proptest! {
    #[test]
    fn print_parse_is_identity_on_arbitrary_text(s in "\\PC{0,200}") {
        prop_assert_eq!(Program::parse(&s).to_string(), s);
    }

    #[test]
    fn print_parse_is_identity_on_gcode(s in gcode_text()) {
        let p = Program::parse(&s);
        prop_assert_eq!(p.to_string(), s.clone());
        // parse(print(p)) == p
        prop_assert_eq!(Program::parse(&p.to_string()), p);
    }

    #[test]
    fn identity_transform_keeps_bytes(s in gcode_text()) {
        let p = Program::parse(&s);
        // Programs the transform refuses (G92, unknown positions never occur for identity) are fine to skip.
        if let Ok(out) = p.transform(&Transform3::identity(), &TransformOptions::default()) {
            prop_assert_eq!(out, s);
        }
    }
}
