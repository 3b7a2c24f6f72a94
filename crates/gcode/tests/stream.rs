//! The streamed rewrite (`transform_stream`, many pieces, a reader thread) gives byte for byte
//! what the in-memory `Program::transform` gives, on a varied program of several pieces: mm and
//! inch, absolute and incremental moves, arcs (kept, swapped, linearised), canned cycles, G53,
//! parameters set in one piece and used in later ones, comments of both kinds, CRLF.

use truepos_gcode::{transform_stream, ArcPolicy, Program, StreamError, TransformOptions};
use truepos_math::types::{rx, ry, rz};
use truepos_math::{Transform3, Vector3};

fn varied_program(blocks: usize) -> String {
    let mut s = String::from("%\nO1000 (VARIED)\n#<depth> = 2.5\n#1=10\nG21 G90 G17\nG0 X0 Y0 Z50\n");
    for i in 0..blocks {
        let x = (i % 97) as f64 * 1.25;
        let y = (i % 89) as f64 * 0.5;
        match i % 12 {
            0 => s.push_str(&format!("N{i} G1 X{x:.3} Y{y:.3} F2000 (MSG,Measure SOMaC (nested) X9)\n")),
            1 => s.push_str(&format!("G1 X[{x} + #1] Y-#<depth> ; semicolon X1 Y2\r\n")),
            2 => s.push_str(&format!("G2 X{:.3} Y{y:.3} I5 J0\n", x + 10.0)),
            3 => s.push_str(&format!("G1 X{x:.3} Y{y:.3}\nG3 X{:.3} Y{:.3} R7.5\n", x + 5.0, y + 5.0)),
            4 => s.push_str("G91 G1 X0.1 Y-0.05 Z0.01\nG90\n"),
            5 => s.push_str(&format!("G20 G1 X{:.4} Y{:.4}\nG21\n", x / 25.4, y / 25.4)),
            6 => s.push_str(&format!("G81 X{x:.3} Y{y:.3} Z-5 R2 F100\nG80\n")),
            7 => s.push_str("#1=[#1+1] G1 Z#1\n\n"),
            8 => s.push_str("G53 G0 Z0\nG0 X0 Y0 Z40\n"),
            9 => s.push_str(&format!("G18 G2 X{x:.3} Z10 I2 K0\nG17\n")),
            10 => s.push_str("(comment only (nested))\n"),
            _ => s.push_str(&format!("g1x{x:.2}y{y:.2}\n")),
        }
    }
    s.push_str("M30\n%");
    s
}

fn streamed(src: &str, t: &Transform3, opts: &TransformOptions) -> Result<String, StreamError> {
    let mut out = Vec::new();
    let sum = transform_stream(std::io::Cursor::new(src.as_bytes().to_vec()), &mut out, t, opts)?;
    assert_eq!(sum.lines, Program::parse(src).lines.len());
    Ok(String::from_utf8(out).expect("the rewrite writes UTF-8"))
}

#[test]
fn streamed_output_is_byte_identical_to_the_in_memory_result() {
    let src = varied_program(150_000);
    assert!(src.len() > 3 * truepos_gcode::PIECE_BYTES, "several pieces");
    let keep_plane = Transform3::new(1.0001, rz(0.3), Vector3::new(5.0, -2.0, 1.0));
    // Turns the XY and ZX planes over (G2 <-> G3) and Z upside down (canned cycles refused).
    let flip = Transform3::new(1.0, rx(std::f64::consts::PI), Vector3::new(0.0, 0.0, 100.0));
    let lin =
        TransformOptions { arc_policy: ArcPolicy::Linearize { tolerance_mm: 0.005 }, ..Default::default() };
    let mut ok = 0;
    for (t, opts) in [
        (Transform3::identity(), TransformOptions::default()),
        // The G18 arcs' plane is tilted by a turn about Z: linearised.
        (keep_plane, lin.clone()),
        (keep_plane, TransformOptions { decimals: Some(6), start_mm: Some([1.0, 2.0, 3.0]), ..lin.clone() }),
        // Refused at the first G18 arc (tilted) and at the first canned cycle (Z turned over).
        (keep_plane, TransformOptions::default()),
        (flip, TransformOptions::default()),
        (Transform3::new(1.0, ry(0.2), Vector3::zeros()), lin.clone()),
    ] {
        let want = Program::parse(&src).transform(&t, &opts);
        let got = streamed(&src, &t, &opts);
        match (want, got) {
            (Ok(w), Ok(g)) => {
                assert!(w == g, "streamed output differs");
                ok += 1;
            }
            (Err(w), Err(StreamError::Gcode(g))) => assert_eq!(w, g),
            (w, g) => panic!("in memory {:?}, streamed {:?}", w.map(|_| ()), g.map(|_| ())),
        }
    }
    assert_eq!(ok, 3, "the first three transforms rewrite the whole program");
}
