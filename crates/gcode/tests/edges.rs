//! Hostile and odd programs: every word's value is known exactly or the program is refused with
//! the line and column of the first thing that cannot be executed; comments come back byte for
//! byte; parameters and expressions evaluate as LinuxCNC's RS274NGC interpreter does.

use truepos_gcode::{GcodeError, Program, TransformOptions};
use truepos_math::types::rz;
use truepos_math::{Point3, Transform3, Vector3};

fn loc(e: &GcodeError) -> (usize, usize) {
    (e.line(), e.column())
}

#[test]
fn words_without_a_valid_number_are_refused_with_line_and_column() {
    for (bad, col) in [
        ("Xabc", 8),
        ("X", 8),
        ("XNaN", 8),
        ("X1,5", 8),
        ("X1e999", 8),
        ("X1e3", 8),
        ("X-", 8),
        ("X.", 8),
        ("X1.2.3", 8),
        ("X+inf", 8),
    ] {
        let src = format!("G0 X0 Y0 Z0\nN20 G1 {bad} Y5 F100\nG1 X100\n");
        let p = Program::parse(&src);
        let e = p.check().expect_err(bad);
        assert_eq!(loc(&e), (2, col), "{bad}: {e}");
        // The transform refuses it too (nothing written), even the identity.
        let e = p.transform(&Transform3::identity(), &TransformOptions::default()).expect_err(bad);
        assert_eq!(loc(&e), (2, col), "{bad}");
    }
}

#[test]
fn text_that_is_not_gcode_is_refused() {
    for (src, at) in [
        ("G1 X1 = 2\n", (1, 7)),
        ("G1 X1 , Y2\n", (1, 7)),
        ("G1 X1 (open comment\n", (1, 7)),
        ("#1\n", (1, 1)),
        ("o100 sub\nG1 X1\no100 endsub\n", (1, 6)),
        ("o<probe> call [1]\n", (1, 1)),
        ("G1 X#1\n", (1, 4)),
        ("#1=2 #2=[#1+1]\n", (1, 6)),
        ("G1 X#<_x>\n", (1, 4)),
        ("G1 X[SQRT[-1]]\n", (1, 4)),
        ("G1 X[1/0]\n", (1, 4)),
        ("G1 X[10**400]\n", (1, 4)),
        ("G1 X[1e3]\n", (1, 4)),
    ] {
        let e = Program::parse(src).check().expect_err(src);
        assert_eq!(loc(&e), at, "{src}: {e}");
    }
    // Block delete at the start of a line and a byte-order mark are fine.
    Program::parse("\u{feff}G0 X1 Y1 Z1\n/G1 X2\n").check().unwrap();
}

#[test]
fn parameters_and_expressions_give_the_positions_linuxcnc_would() {
    // Hand-evaluated: #1 = 2, #<d> = 2*3 = 6 (on the next line: a setting takes effect only
    // after its line), X[#1+2] = 4, Y#<d> = 6,
    // Z-[#1*0.5] = -1; on the line `#1=10 X#1`, X reads the old #1 (2) and #1 becomes 10 after.
    let src = "#1=2\n#<d> = [#1 * 3]\nG0 X[#1+2] Y#<d> Z-[#1*0.5]\n#1=10 G1 X#1 F100\nG1 Y#1\nG1 XSIN[30] YATAN[1]/[1] Z[7 MOD 3 + 2**3]\n";
    let p = Program::parse(src);
    p.check().unwrap();
    assert_eq!(p.to_string(), src);
    let b = p.blocks();
    assert_eq!(b[2].target_mm, Some(Point3::new(4.0, 6.0, -1.0)));
    assert_eq!(b[3].target_mm, Some(Point3::new(2.0, 6.0, -1.0)));
    assert_eq!(b[4].target_mm, Some(Point3::new(2.0, 10.0, -1.0)));
    let t = b[5].target_mm.unwrap();
    assert!((t - Point3::new(0.5, 45.0, 9.0)).norm() < 1e-12, "{t}");
}

#[test]
fn expression_words_are_rewritten_to_their_transformed_value() {
    let src = "#1=2\nG0 X[#1+8] Y0 Z#1 (keep (this) X99) ; and X98 this\nG1 X#1 F100\n";
    let p = Program::parse(src);
    // A translation by (1, 0, 0): X[#1+8] = 10 -> 11; Z#1 = 2 unchanged (kept verbatim).
    let t = Transform3::rigid(truepos_math::Matrix3::identity(), Vector3::new(1.0, 0.0, 0.0));
    let out = p.transform(&t, &TransformOptions::default()).unwrap();
    assert_eq!(out, "#1=2\nG0 X11.0000 Y0 Z#1 (keep (this) X99) ; and X98 this\nG1 X3.0000 F100\n");
    // The identity keeps every byte, nested comments included.
    assert_eq!(p.transform(&Transform3::identity(), &TransformOptions::default()).unwrap(), src);
    // A rotation: the output, interpreted, is the transformed input.
    let t = Transform3::new(1.0, rz(0.3), Vector3::new(5.0, -2.0, 1.0));
    let out = p.transform(&t, &TransformOptions::default()).unwrap();
    let q = Program::parse(&out);
    q.check().unwrap();
    for (a, b) in p.blocks().iter().zip(q.blocks().iter()) {
        if let (Some(x), Some(y)) = (a.target_mm, b.target_mm) {
            assert!((t.apply(&x) - y).norm() < 1e-4, "{x} -> {y}");
        }
    }
}

#[test]
fn comments_come_back_byte_identical_under_a_transform() {
    let src = "G0 X0 Y0 Z0\nG1 X10 (a (b) X99) Y5 ; c (d) X98 Y97\n(only (nested) comment X1)\n";
    let t = Transform3::rigid(truepos_math::Matrix3::identity(), Vector3::new(1.0, 2.0, 3.0));
    let out = Program::parse(src).transform(&t, &TransformOptions::default()).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    // Z stays at the 3.0000 the first line now writes, so it is not repeated.
    assert_eq!(lines[1], "G1 X11.0000 (a (b) X99) Y7.0000 ; c (d) X98 Y97");
    assert_eq!(lines[2], "(only (nested) comment X1)");
}

/// An arc whose plane a rotation tilts, linearised: every output point lies on the exactly
/// transformed arc (to the output rounding), and every chord's sagitta (the distance of its
/// midpoint from the circle, measured back in the program's frame on the circle's own
/// definition) is within the tolerance.
#[test]
fn tilted_arcs_are_linearised_within_the_tolerance() {
    use truepos_gcode::ArcPolicy;
    use truepos_math::types::rx;
    let src = "G21 G90 G17\nG0 X10 Y0 Z5\nG2 X0 Y-10 I-10 J0 F300 (quarter, centre form)\nG2 X-10 Y0 R10\nG1 X0 Y0\n";
    let t = Transform3::new(1.0, rx(0.3) * rz(0.2), Vector3::new(100.0, -50.0, 20.0));
    // Without the policy: refused, naming the line.
    let e = Program::parse(src).transform(&t, &TransformOptions::default()).unwrap_err();
    assert_eq!(e.line(), 3);
    for tol in [0.01, 0.001] {
        let opts =
            TransformOptions { arc_policy: ArcPolicy::Linearize { tolerance_mm: tol }, ..Default::default() };
        let out = Program::parse(src).transform(&t, &opts).unwrap();
        let q = Program::parse(&out);
        q.check().unwrap();
        assert!(out.contains("(quarter, centre form)"), "comment kept");
        assert!(!out.contains('I') && !out.contains('R'), "centre words removed:\n{out}");
        // Every G1 move's end point, back in the program frame.
        let inv = |p: Point3| (t.rotation.transpose() * (p - t.translation).coords) / t.scale;
        let pts: Vec<Vector3> = q.blocks().iter().filter_map(|b| b.target_mm).map(inv).collect();
        // pts[0] is the G0 start; then the two arcs (radius 10 about the origin in z = 5) and the final G1.
        let arc = &pts[..pts.len() - 1];
        let mut worst = 0.0f64;
        for w in arc.windows(2) {
            for p in w {
                assert!((p.xy().norm() - 10.0).abs() < 2e-4 && (p.z - 5.0).abs() < 2e-4, "{p}");
            }
            let mid = 0.5 * (w[0] + w[1]);
            worst = worst.max(10.0 - mid.xy().norm());
        }
        assert!(worst <= tol, "sagitta {worst} > {tol}");
        assert!(worst > 0.5 * tol, "not needlessly fine: {worst} vs {tol}");
        // The arcs end where the transformed program ends them: (0, −10, 5) then (−10, 0, 5).
        assert!(arc.iter().any(|p| (p - Vector3::new(0.0, -10.0, 5.0)).norm() < 2e-4));
        assert!((arc[arc.len() - 1] - Vector3::new(-10.0, 0.0, 5.0)).norm() < 2e-4);
        // The clockwise quarter goes through (7.07, −7.07), not the long way round.
        assert!(arc.iter().all(|p| !(p.x > 1.0 && p.y > 1.0)));
        // The feed of the arc line applies from the first chord on.
        let first_chord = out.lines().nth(2).unwrap();
        assert!(first_chord.starts_with("G1 ") && first_chord.ends_with("F300"), "{first_chord}");
    }
}
