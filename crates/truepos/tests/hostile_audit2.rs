//! Findings of the second hostile audit of issue 31 (`scripts/hostile_round3.sh`, report in
//! docs/hardening.md), through the binary: G-code expressions that overflowed the stack, CR-only
//! line ends that made a program one block, guarded verdicts without a known uncertainty, and
//! QIF plans with a second block of definitions, nominals or units. Every case: exit 2, the
//! file and place named, no output left behind.

mod common;

use common::{bin, expect_input_error, write};
use std::path::Path;

const TREF: &str = "id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1000,0,0\nT3,0,1000,0\n";
const TMEAS: &str = "id,x_mm,y_mm,z_mm\nT1,1,0,0\nT2,1001,0,0\nT3,1,1000,0\n";

/// Nothing but `keep` in `dir` (no output, no temporary file).
fn only(dir: &Path, keep: &[&str]) {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut want: Vec<String> = keep.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(names, want);
}

/// F1: a 10,000-term expression, 7,000 nested brackets or 20,000 signs in one word overflowed
/// the reader thread's stack (exit 134, a temporary file left); now exit 2 at the word's place
/// with the limit, and nothing written.
#[test]
fn huge_gcode_expressions_are_refused_not_crashed() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "tref.csv", TREF);
    write(d.path(), "tmeas.csv", TMEAS);
    let cases = [
        ("flat.nc", format!("X[{}1]", "1+".repeat(10_000))),
        ("deep.nc", format!("X{}1{}", "[".repeat(7000), "]".repeat(7000))),
        ("signs.nc", format!("X[{}1]", "-".repeat(20_000))),
    ];
    for (name, word) in &cases {
        write(d.path(), name, format!("G90\nG0 {word} Y0 Z0\n"));
    }
    for (name, _) in &cases {
        let out = bin()
            .current_dir(d.path())
            .args(["orient", "--reference", "tref.csv", "--measured", "tmeas.csv", "--program", name])
            .args(["--output", "o.nc"])
            .output()
            .unwrap();
        expect_input_error(&out, &[&format!("{name}:2:4"), "more than 1000 values and operators"]);
        assert!(String::from_utf8_lossy(&out.stderr).len() < 2000, "the message quotes all of it");
        only(d.path(), &["tref.csv", "tmeas.csv", "flat.nc", "deep.nc", "signs.nc"]);
    }
    // The same in a parameter setting of a somac program (the main thread's parser).
    let prog = write(d.path(), "set.nc", format!("#1=[{}1]\nG0 X#1 Y0 Z0\n", "1+".repeat(200_000)));
    let out = bin()
        .args(["somac", "inspect", "--diameter-mm", "6", "--program"])
        .arg(&prog)
        .arg("--db")
        .arg(d.path().join("s.sqlite"))
        .output()
        .unwrap();
    expect_input_error(&out, &["set.nc:1:", "more than 1000 values and operators"]);
}

/// F19, F20: lines ending in a carriage return alone (classic Mac OS) read as one block: orient
/// wrote a wrong program with exit 0 (the first motion took the last X), somac inspect found
/// one hole of four. Now exit 2 naming CR-only line ends at the first one, nothing written.
#[test]
fn cr_only_gcode_is_refused_at_its_first_carriage_return() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "tref.csv", TREF);
    write(d.path(), "tmeas.csv", TMEAS);
    write(d.path(), "mac.nc", "G90\rG0 X1 Y2 Z3\rG1 X10 Y10 Z0 F100\r");
    let out = bin()
        .current_dir(d.path())
        .args(["orient", "--reference", "tref.csv", "--measured", "tmeas.csv", "--program", "mac.nc"])
        .args(["--output", "o.nc"])
        .output()
        .unwrap();
    expect_input_error(&out, &["mac.nc:1:4", "CR-only line ends", "LF or CRLF"]);
    only(d.path(), &["tref.csv", "tmeas.csv", "mac.nc"]);
    // A comment swallowing the rest of a CR-only program is caught too.
    write(d.path(), "macc.nc", "G90 ; set up\rG0 X1 Y2 Z3\r");
    let out = bin()
        .current_dir(d.path())
        .args(["orient", "--reference", "tref.csv", "--measured", "tmeas.csv", "--program", "macc.nc"])
        .args(["--output", "o.nc"])
        .output()
        .unwrap();
    expect_input_error(&out, &["macc.nc:1:", "CR-only line ends"]);
    // somac inspect on a simulated cell's program with its LF turned into CR.
    let out = bin().args(["simulate", "somac", "--out"]).arg(d.path().join("cell")).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let prog = std::fs::read(d.path().join("cell/program.nc")).unwrap();
    let mac: Vec<u8> = prog.iter().map(|&c| if c == b'\n' { b'\r' } else { c }).collect();
    let macp = write(d.path(), "macsomac.nc", mac);
    let out = bin()
        .args(["somac", "inspect", "--diameter-mm", "6", "--program"])
        .arg(&macp)
        .arg("--db")
        .arg(d.path().join("m.sqlite"))
        .output()
        .unwrap();
    expect_input_error(&out, &["macsomac.nc:1:", "CR-only line ends"]);
}
