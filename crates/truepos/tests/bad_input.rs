//! Bad input through the built binary: every case must exit with code 2 (never 101, a panic),
//! with a message naming the file and, where there is one, the line and column; commands that
//! write an output file must leave none behind.

mod common;
use common::*;
use std::path::Path;
use std::process::Output;

fn fit(kind: &str, file: &Path) -> Output {
    bin().args(["fit", kind]).arg(file).arg("--json").output().unwrap()
}

#[test]
fn malformed_csv_values_name_file_line_and_column() {
    let d = tempfile::tempdir().unwrap();
    let cases: [(&str, &[u8], &[&str]); 6] = [
        ("nan.csv", b"x_mm,y_mm,z_mm\n1,2,3\n4,5,NaN\n7,8,9\n0,1,1\n", &["nan.csv:3:3", "z_mm", "finite"]),
        ("inf.csv", b"x_mm,y_mm,z_mm\n1,2,3\ninf,5,6\n7,8,9\n0,1,1\n", &["inf.csv:3:1", "x_mm"]),
        ("text.csv", b"x_mm,y_mm,z_mm\n1,2,3\n4,five,6\n7,8,9\n0,1,1\n", &["text.csv:3:2", "y_mm", "five"]),
        (
            "empty_value.csv",
            b"x_mm,y_mm,z_mm\n1,2,3\n4,,6\n7,8,9\n0,1,1\n",
            &["empty_value.csv:3:2", "empty"],
        ),
        ("ragged.csv", b"x_mm,y_mm,z_mm\n1,2,3\n4,5\n7,8,9\n0,1,1\n", &["ragged.csv:3", "ragged"]),
        ("long_row.csv", b"x_mm,y_mm,z_mm\n1,2,3\n4,5,6\n7,8,9,10\n0,1,1\n", &["long_row.csv:4", "ragged"]),
    ];
    for (name, bytes, needles) in cases {
        let f = write(d.path(), name, bytes);
        expect_input_error(&fit("sphere", &f), needles);
    }
}

#[test]
fn missing_columns_empty_and_binary_files() {
    let d = tempfile::tempdir().unwrap();
    let f = write(d.path(), "nocol.csv", b"# comment\nx_mm,y_mm\n1,2\n3,4\n5,6\n");
    expect_input_error(&fit("plane", &f), &["nocol.csv:2", "z_mm"]);
    let f = write(d.path(), "empty.csv", b"");
    expect_input_error(&fit("plane", &f), &["empty.csv", "empty"]);
    let f = write(d.path(), "header_only.csv", b"x_mm,y_mm,z_mm\n");
    expect_input_error(&fit("plane", &f), &["header_only.csv", "3 points"]);
    let f =
        write(d.path(), "elf.csv", b"\x7fELF\x02\x01\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\x03\x00>\x00");
    expect_input_error(&fit("plane", &f), &["elf.csv:1", "binary"]);
    let f = write(d.path(), "latin1.csv", b"x_mm,y_mm,z_mm\n1,2,3\n\xe9,2,3\n");
    expect_input_error(&fit("plane", &f), &["latin1.csv:3", "UTF-8"]);
    let missing = d.path().join("does_not_exist.csv");
    expect_input_error(&fit("plane", &missing), &["does_not_exist.csv", "cannot read"]);
}

#[test]
fn malformed_ds_files() {
    let d = tempfile::tempdir().unwrap();
    let cases: [(&str, &[u8], &[&str]); 6] = [
        ("count.ds", b"3\n1 2 3\n4 5 6\n", &["count.ds", "3 points"]),
        ("nocount.ds", b"1 2 3\n4 5 6\n", &["nocount.ds:1:1", "count"]),
        ("text.ds", b"4\n1 2 3\n4 x 6\n7 8 9\n1 1 0\n", &["text.ds:3:2", "'x'"]),
        ("two.ds", b"4\n1 2 3\n4 5\n7 8 9\n1 1 0\n", &["two.ds:3", "x y z"]),
        ("nan.ds", b"4\n1 2 3\n4 5 nan\n7 8 9\n1 1 0\n", &["nan.ds:3:3", "finite"]),
        ("empty.ds", b"", &["empty.ds", "empty"]),
    ];
    for (name, bytes, needles) in cases {
        let f = write(d.path(), name, bytes);
        expect_input_error(&fit("sphere", &f), needles);
    }
}

#[test]
fn degenerate_geometry_is_named() {
    let d = tempfile::tempdir().unwrap();
    let csv = |pts: &[[f64; 3]]| {
        let mut s = String::from("x_mm,y_mm,z_mm\n");
        for p in pts {
            s.push_str(&format!("{},{},{}\n", p[0], p[1], p[2]));
        }
        s.into_bytes()
    };
    // Too few points for each element.
    let two = csv(&[[0., 0., 0.], [1., 0., 0.]]);
    let f = write(d.path(), "two.csv", &two);
    for kind in ["plane", "circle", "sphere", "cylinder", "cone"] {
        expect_input_error(&fit(kind, &f), &["two.csv", kind, "at least"]);
    }
    // Coincident points.
    let f = write(d.path(), "same.csv", csv(&[[1., 2., 3.]; 6]));
    expect_input_error(&fit("line", &f), &["same.csv", "coincide"]);
    // Collinear points: a plane and a circle are not determined.
    let line: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, 2.0 * i as f64, -(i as f64)]).collect();
    let f = write(d.path(), "collinear.csv", csv(&line));
    expect_input_error(&fit("plane", &f), &["collinear.csv", "collinear"]);
    expect_input_error(&fit("circle", &f), &["collinear.csv", "collinear"]);
    // Coplanar points (a circle): a sphere, cylinder and cone are not determined.
    let circ: Vec<[f64; 3]> = (0..12)
        .map(|i| {
            let a = i as f64 * 0.5;
            [10.0 * a.cos(), 10.0 * a.sin(), 4.0]
        })
        .collect();
    let f = write(d.path(), "coplanar.csv", csv(&circ));
    for kind in ["sphere", "cylinder", "cone"] {
        expect_input_error(&fit(kind, &f), &["coplanar.csv", "coplanar"]);
    }
    // A cylinder fitted with a cone: the apex is at infinity.
    let cyl: Vec<[f64; 3]> = (0..40)
        .map(|i| {
            let a = i as f64 * 0.7;
            [5.0 * a.cos(), 5.0 * a.sin(), (i % 5) as f64 * 3.0]
        })
        .collect();
    let f = write(d.path(), "cylinder.csv", csv(&cyl));
    expect_input_error(&fit("cone", &f), &["cylinder.csv", "cylinder"]);
    // A cylinder fitted to noisy-free flat data spread in two directions plus a small
    // deterministic bump pattern (not coplanar, but flat: no significant curvature).
    let flat: Vec<[f64; 3]> = (0..100)
        .map(|i| {
            let (x, y) = ((i % 10) as f64, (i / 10) as f64);
            [x, y, 1e-3 * (((i * 7919) % 13) as f64 - 6.0) / 6.0]
        })
        .collect();
    let f = write(d.path(), "flat.csv", csv(&flat));
    expect_input_error(&fit("cylinder", &f), &["flat.csv", "flat"]);
}

#[test]
fn usage_errors_exit_2() {
    let out = bin().args(["fit", "torus", "x.csv"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = bin().args(["fit", "sphere"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn no_output_file_left_on_bad_input() {
    // `truepos comp correct` writes --output: a malformed map must stop it before any file exists.
    let d = tempfile::tempdir().unwrap();
    let map = write(d.path(), "map.csv", b"axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad\nx,0,0,0,0,0,0,0\nx,100,abc,0,0,0,0,0\n");
    let pts = write(d.path(), "pts.csv", b"x_mm,y_mm,z_mm\n1,2,3\n");
    let out_path = d.path().join("corrected.csv");
    let out = bin()
        .args(["comp", "correct", "--map"])
        .arg(&map)
        .arg("--points")
        .arg(&pts)
        .arg("--output")
        .arg(&out_path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("map.csv:3"), "{err}");
    assert!(!out_path.exists(), "a failed run left {}", out_path.display());
    let leftovers: Vec<_> = std::fs::read_dir(d.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(leftovers.len(), 2, "temporary files left behind: {leftovers:?}");
}
