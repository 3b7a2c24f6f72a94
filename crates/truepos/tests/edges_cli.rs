//! Issue 14 through the built binary: G-code words without a valid number, expressions,
//! comments, the start position and tilted arcs (`orient`, `somac run`); degenerate `align` and
//! `autoscale` input and autoscale from two features; `air` outside the equations' range; count
//! limits; the audit trail shared by concurrent runs and refusing foreign databases.

mod common;
use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn json(o: &Output) -> Value {
    assert_eq!(o.status.code(), Some(0), "stderr: {}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Reference and measured targets: measured = reference shifted by (1, 2, 3) (no rotation), or
/// `tilt` rad about X first.
fn targets(d: &Path, tilt: f64) -> (PathBuf, PathBuf) {
    let pts = [
        ("A", [0.0, 0.0, 0.0]),
        ("B", [500.0, 0.0, 0.0]),
        ("C", [0.0, 400.0, 0.0]),
        ("D", [500.0, 400.0, 50.0]),
    ];
    let mut r = String::from("id,x_mm,y_mm,z_mm\n");
    let mut m = r.clone();
    for (id, p) in pts {
        r.push_str(&format!("{id},{},{},{}\n", p[0], p[1], p[2]));
        let (c, sn) = (tilt.cos(), tilt.sin());
        let q = [p[0] + 1.0, c * p[1] - sn * p[2] + 2.0, sn * p[1] + c * p[2] + 3.0];
        m.push_str(&format!("{id},{},{},{}\n", q[0], q[1], q[2]));
    }
    (write(d, "ref.csv", r), write(d, "meas.csv", m))
}

fn orient(d: &Path, tilt: f64, program: &str, extra: &[&str]) -> (Output, PathBuf) {
    let (r, m) = targets(d, tilt);
    let prog = write(d, "prog.nc", program);
    let out = d.join("out.nc");
    let o = bin()
        .args([
            "orient",
            "--reference",
            s(&r),
            "--measured",
            s(&m),
            "--program",
            s(&prog),
            "--output",
            s(&out),
        ])
        .args(extra)
        .output()
        .unwrap();
    (o, out)
}

#[test]
fn orient_refuses_words_without_a_valid_number_with_line_and_column() {
    for bad in ["Xabc", "X", "XNaN", "X1,5", "X1e999", "X#100", "X[1/0]"] {
        let d = tempfile::tempdir().unwrap();
        let (o, out) = orient(d.path(), 0.0, &format!("G0 X0 Y0 Z0\nN20 G1 {bad} Y5 F100\n"), &[]);
        expect_input_error(&o, &["prog.nc:2:8"]);
        assert!(!out.exists(), "{bad}: no output on bad input");
    }
}

#[test]
fn orient_evaluates_expressions_and_keeps_comments_byte_for_byte() {
    let d = tempfile::tempdir().unwrap();
    let prog = "#1=2\nG0 X[#1+8] Y0 Z#1 (a (b) X99) ; c X98\nG1 X#1 F100\n";
    let (o, out) = orient(d.path(), 0.0, prog, &["--json"]);
    json(&o);
    // Shift (1, 2, 3): X 10 → 11, Y 0 → 2, Z 2 → 5; X#1 = 2 → 3; comments untouched.
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "#1=2\nG0 X11.0000 Y2.0000 Z5.0000 (a (b) X99) ; c X98\nG1 X3.0000 F100\n"
    );
}

#[test]
fn orient_needs_the_start_position_for_a_partial_first_motion() {
    let d = tempfile::tempdir().unwrap();
    let prog = "N10 G21 G90\nN20 G0 Z50.\nN30 G1 X10 Y20 F100\n";
    let (o, out) = orient(d.path(), 0.0, prog, &[]);
    expect_input_error(&o, &["prog.nc:2:8", "--start-mm"]);
    assert!(!out.exists());
    let (o, out) = orient(d.path(), 0.0, prog, &["--start-mm=-5,6,100", "--json"]);
    json(&o);
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text, "N10 G21 G90\nN20 G0 Z53.0000\nN30 G1 X11.0000 Y22.0000 F100\n");
}

#[test]
fn orient_linearises_tilted_arcs_only_when_asked() {
    let d = tempfile::tempdir().unwrap();
    let prog = "G17 G0 X10 Y0 Z0\nG2 X0 Y-10 I-10 J0 F200\n";
    let (o, _) = orient(d.path(), 0.2, prog, &[]);
    expect_input_error(&o, &["prog.nc:2", "tilts"]);
    let (o, out) = orient(d.path(), 0.2, prog, &["--arc-tolerance-mm", "0.005", "--json"]);
    json(&o);
    let text = std::fs::read_to_string(&out).unwrap();
    // A quarter of radius 10 within 5 µm: ≥ 18 chords (2·acos(1 − 0.005/10) ≈ 0.063 rad each).
    assert!(text.lines().count() >= 19, "{text}");
    assert!(!text.contains('I'), "{text}");
}

#[test]
fn somac_run_refuses_a_malformed_program_before_any_motion() {
    let d = tempfile::tempdir().unwrap();
    let o = bin()
        .args(["simulate", "somac", "--out", s(d.path()), "--holes-per-row", "2", "--seed", "3"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let prog = std::fs::read_to_string(d.path().join("program.nc")).unwrap();
    // Corrupt the X word of the first measurement block's line.
    let (k, line) = prog.lines().enumerate().find(|(_, l)| l.contains(" X") && l.contains("G0")).unwrap();
    let col = line.find(" X").unwrap() + 2;
    let bad: String = prog
        .lines()
        .enumerate()
        .map(|(i, l)| if i == k { l.replacen(" X", " Xabc X", 1) } else { l.to_string() } + "\n")
        .collect();
    let p = write(d.path(), "bad.nc", bad);
    let db = d.path().join("audit.sqlite");
    let o = bin()
        .args([
            "somac",
            "run",
            "--program",
            s(&p),
            "--cell",
            s(&d.path().join("cell.toml")),
            "--db",
            s(&db),
            "--json",
        ])
        .output()
        .unwrap();
    expect_input_error(&o, &[&format!("bad.nc:{}:{col}", k + 1), "Xabc"]);
}

#[test]
fn somac_run_shares_one_audit_database_between_eight_runs_and_refuses_foreign_files() {
    let d = tempfile::tempdir().unwrap();
    let o = bin()
        .args(["simulate", "somac", "--out", s(d.path()), "--holes-per-row", "2", "--seed", "5"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let db = d.path().join("audit.sqlite");
    let run = |db: &Path| {
        bin()
            .args(["somac", "run", "--program", s(&d.path().join("program.nc"))])
            .args(["--cell", s(&d.path().join("cell.toml")), "--db", s(db), "--json"])
            .spawn()
            .unwrap()
    };
    let children: Vec<_> = (0..8).map(|_| run(&db)).collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(matches!(o.status.code(), Some(0) | Some(1)), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let c = rusqlite::Connection::open(&db).unwrap();
    let q = |sql: &str| -> i64 { c.query_row(sql, [], |r| r.get(0)).unwrap() };
    assert_eq!(q("SELECT COUNT(*) FROM runs"), 8);
    assert_eq!(
        q("SELECT COUNT(*) FROM runs WHERE ended_at IS NOT NULL AND status IN ('SUCCESS', 'ALARM', 'FAILURE')"),
        8
    );
    assert_eq!(q("SELECT COUNT(DISTINCT run_id) FROM stops"), 8);
    let started: String = c.query_row("SELECT started_at FROM runs LIMIT 1", [], |r| r.get(0)).unwrap();
    assert!(started.ends_with('Z') && started.as_bytes()[10] == b'T', "{started}");
    // A foreign file is refused and left as it was.
    let foreign = write(d.path(), "notes.sqlite", "just text\n");
    let o = bin()
        .args(["somac", "run", "--program", s(&d.path().join("program.nc"))])
        .args(["--cell", s(&d.path().join("cell.toml")), "--db", s(&foreign), "--json"])
        .output()
        .unwrap();
    expect_input_error(&o, &["notes.sqlite", "not an SQLite"]);
    assert_eq!(std::fs::read(&foreign).unwrap(), b"just text\n");
}

#[test]
fn autoscale_from_two_features_and_degenerate_sets() {
    let d = tempfile::tempdir().unwrap();
    let r = write(d.path(), "r.csv", "id,x_mm,y_mm,z_mm\nA,0,0,0\nB,100,0,0\n");
    let m = write(d.path(), "m.csv", "id,x_mm,y_mm,z_mm\nA,10,20,5\nB,10,120.1,5\n");
    let j = json(
        &bin().args(["autoscale", "--reference", s(&r), "--measured", s(&m), "--json"]).output().unwrap(),
    );
    // 100.1 / 100.0, rotated by 90° and shifted: exactly the distance ratio.
    assert!((j["scale"].as_f64().unwrap() - 1.001).abs() < 1e-12, "{j}");
    let same = write(d.path(), "same.csv", "id,x_mm,y_mm,z_mm\nA,5,5,5\nB,5,5,5\nC,5,5,5\n");
    let r3 = write(d.path(), "r3.csv", "id,x_mm,y_mm,z_mm\nA,0,0,0\nB,100,0,0\nC,0,100,0\n");
    let o =
        bin().args(["autoscale", "--reference", s(&r3), "--measured", s(&same), "--json"]).output().unwrap();
    expect_input_error(&o, &["same.csv", "coincide"]);
    let o =
        bin().args(["autoscale", "--reference", s(&same), "--measured", s(&r3), "--json"]).output().unwrap();
    expect_input_error(&o, &["coincide"]);
}

#[test]
fn align_names_degenerate_input() {
    let d = tempfile::tempdir().unwrap();
    let good = write(d.path(), "g.csv", "id,x_mm,y_mm,z_mm,w\nA,0,0,0,0\nB,100,0,0,0\nC,0,100,0,0\n");
    let o = bin()
        .args(["align", "--from", s(&good), "--to", s(&good), "--weights", "w", "--json"])
        .output()
        .unwrap();
    expect_input_error(&o, &["weights"]);
    let same = write(d.path(), "same.csv", "id,x_mm,y_mm,z_mm\nA,5,5,5\nB,5,5,5\nC,5,5,5\n");
    let o = bin().args(["align", "--from", s(&same), "--to", s(&good), "--json"]).output().unwrap();
    expect_input_error(&o, &["coincide"]);
    let empty = write(d.path(), "empty.csv", "id,x_mm,y_mm,z_mm\nA,0,0,0\n,100,0,0\nC,0,100,0\n");
    let o = bin().args(["align", "--from", s(&empty), "--to", s(&good), "--json"]).output().unwrap();
    expect_input_error(&o, &["empty.csv:3:1", "empty id"]);
    let dup = write(d.path(), "dup.csv", "id,x_mm,y_mm,z_mm\nA,0,0,0\nA,100,0,0\nC,0,100,0\n");
    let o = bin().args(["align", "--from", s(&dup), "--to", s(&good), "--json"]).output().unwrap();
    expect_input_error(&o, &["dup.csv:3", "duplicate"]);
}

#[test]
fn air_outside_the_equations_range_is_refused() {
    for (args, needle) in [
        (&["--wavelength-nm", "0.633"][..], "wavelength"),
        (&["--pressure-pa", "1e12"][..], "pressure"),
        (&["--humidity-pct", "150"][..], "humidity"),
        (&["--temperature-c=-300"][..], "temperature"),
        (&["--co2-ppm", "5000"][..], "CO2"),
    ] {
        let mut a =
            vec!["air", "--temperature-c", "20", "--pressure-pa", "101325", "--humidity-pct", "50", "--json"];
        // Later options of the same name win in clap only when allowed; replace instead.
        for pair in args.iter() {
            let key = pair.split('=').next().unwrap();
            if let Some(i) = a.iter().position(|x| *x == key) {
                a.drain(i..i + 2);
            }
        }
        a.extend_from_slice(args);
        let o = bin().args(&a).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{a:?}: {err}");
        assert!(err.contains(needle), "{err}");
        assert!(o.stdout.is_empty());
    }
}

#[test]
fn count_options_have_limits() {
    let d = tempfile::tempdir().unwrap();
    for v in ["1e9", "1000000000", "0"] {
        let o =
            bin().args(["simulate", "somac", "--out", s(d.path()), "--holes-per-row", v]).output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{v}: {}", String::from_utf8_lossy(&o.stderr));
    }
    let o = bin().args(["simulate", "scan", "--out", s(d.path()), "--features", "100000"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
}

/// A program of several pieces streamed through orient: the output is what the library's
/// in-memory transform gives; an error far down keeps its line and column in the whole file and
/// leaves no output (not even the pieces before it).
#[test]
fn orient_streams_long_programs_and_locates_late_errors() {
    let d = tempfile::tempdir().unwrap();
    let mut prog = String::from("G21 G90\nG0 X0 Y0 Z0\n");
    for i in 0..120_000 {
        prog.push_str(&format!("N{i} G1 X{}.25 Y{} (c {i})\n", i % 500, i % 300));
    }
    assert!(prog.len() > 3 * truepos_gcode::PIECE_BYTES);
    let (o, out) = orient(d.path(), 0.1, &prog, &["--json"]);
    let v = json(&o);
    assert_eq!(v["lines"], 120_002);
    let (r, m) = targets(d.path(), 0.1);
    let (r, m) =
        (truepos_io::points::read_id_points(&r).unwrap(), truepos_io::points::read_id_points(&m).unwrap());
    let mt = truepos_io::points::match_by_id(&r, &m);
    let opts = truepos_math::bestfit::BestFitOptions { with_scale: false };
    let t = truepos_math::bestfit::best_fit(&mt.from, &mt.to, None, opts).unwrap();
    let want = truepos_gcode::Program::parse(&prog).transform(&t, &Default::default()).unwrap();
    assert!(
        std::fs::read_to_string(&out).unwrap() == want,
        "streamed orient differs from the in-memory rewrite"
    );
    std::fs::remove_file(&out).unwrap();
    prog.push_str("G1 X1 Y2\nG1 X1..5\n");
    let (o, out) = orient(d.path(), 0.1, &prog, &[]);
    expect_input_error(&o, &["prog.nc:120004:4"]);
    assert!(!out.exists(), "no output on bad input");
}
