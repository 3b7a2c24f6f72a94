//! The usual first-hour mistakes get an answer that says what to fix: negative sizes in both
//! option forms, a `demo --out` that is a file (refused at once, one error line), a bed TOML
//! value that is wrong (its line and column), a `;`-separated points file.

mod common;

use std::time::{Duration, Instant};

#[test]
fn negative_sizes_are_refused_as_not_positive_in_both_forms() {
    for args in [
        &["probe", "sphere", "--near=120,45,30", "--diameter-mm", "-25"][..],
        &["probe", "sphere", "--near=120,45,30", "--diameter-mm=-25"][..],
        &["probe", "sphere", "--near=120,45,30", "--diameter-mm", "0"][..],
        &["latency", "--machine", "m.csv", "--probe", "p.csv", "--sphere-diameter-mm", "-25"][..],
    ] {
        let out = common::bin().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("must be positive"), "{args:?}: {err}");
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
    }
}

#[test]
fn demo_out_that_is_a_file_fails_at_once_with_one_error() {
    let d = tempfile::tempdir().unwrap();
    let f = common::write(d.path(), "FILE", "x");
    let t0 = Instant::now();
    let out = common::bin().args(["demo", "--out"]).arg(&f).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(t0.elapsed() < Duration::from_secs(3), "took {:?}", t0.elapsed());
    assert_eq!(err.matches("error:").count(), 1, "{err}");
    assert!(err.contains("not a directory"), "{err}");
}

#[test]
fn a_wrong_bed_value_is_named_at_its_line() {
    let d = tempfile::tempdir().unwrap();
    let bed = common::write(
        d.path(),
        "bed.toml",
        "# granite\n[bed]\nsize_x_mm = 2000\nsize_y_mm = 1500\nthickness_mm = -250\nyoungs_modulus_mpa = 50000\npoisson = 0.25\nsupports = \"simply-supported-edges\"\n",
    );
    let out = common::bin()
        .args(["load", "map", "--bed"])
        .arg(&bed)
        .args(["--output", "m.csv"])
        .current_dir(d.path())
        .output()
        .unwrap();
    common::expect_input_error(&out, &["bed.toml:5:16:", "thickness_mm = -250: must be positive"]);
}

#[test]
fn a_semicolon_separated_points_file_is_named() {
    let d = tempfile::tempdir().unwrap();
    let p = common::write(d.path(), "p.csv", "x_mm;y_mm;z_mm\n102,996060;1,5;2\n");
    let out = common::bin().args(["fit", "sphere"]).arg(&p).output().unwrap();
    common::expect_input_error(&out, &["separated by ';'", "decimal point"]);
}
