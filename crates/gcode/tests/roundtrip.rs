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

/// The streamed rewrite is the in-memory one: same bytes, or the same error at the same place,
/// however the text is split into pushes.
fn same_as_in_memory(
    s: &str,
    cuts: &[usize],
    t: &Transform3,
    opts: &TransformOptions,
) -> Result<(), TestCaseError> {
    let want = Program::parse(s).transform(t, opts);
    let mut st = truepos_gcode::StreamTransform::new(t, opts);
    let mut out = String::new();
    let mut at = 0;
    let mut got = Ok(());
    for &c in cuts.iter().chain(std::iter::once(&s.len())) {
        let mut c = c.clamp(at, s.len());
        while !s.is_char_boundary(c) {
            c += 1;
        }
        got = st.push(&s[at..c], &mut out);
        at = c;
        if got.is_err() {
            break;
        }
    }
    let got = got.and_then(|()| st.finish(&mut out).map(|_| out));
    match (want, got) {
        (Ok(w), Ok(g)) => prop_assert_eq!(w, g),
        (Err(w), Err(g)) => {
            prop_assert_eq!((w.line(), w.column(), w.to_string()), (g.line(), g.column(), g.to_string()))
        }
        (w, g) => prop_assert!(false, "in memory {:?}, streamed {:?}", w, g),
    }
    Ok(())
}

proptest! {
    #[test]
    fn streamed_rewrite_equals_in_memory(s in gcode_text(), cuts in prop::collection::vec(0usize..400, 0..6),
                                         angle in -0.5f64..0.5, tilt in prop::bool::ANY) {
        let mut cuts = cuts;
        cuts.sort_unstable();
        let rot = if tilt { truepos_math::types::rx(angle) } else { truepos_math::types::rz(angle) };
        let t = Transform3::new(1.0002, rot, truepos_math::Vector3::new(1.5, -0.7, 0.2));
        for opts in [
            TransformOptions::default(),
            TransformOptions { start_mm: Some([1.0, 2.0, 3.0]), arc_policy: truepos_gcode::ArcPolicy::Linearize { tolerance_mm: 0.01 }, decimals: Some(3) },
        ] {
            same_as_in_memory(&s, &cuts, &t, &opts)?;
        }
    }
}
