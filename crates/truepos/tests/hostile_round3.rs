//! Hostile inputs of the third hardening round (issue 31), through the binary: QIF plans that
//! are too deep, too large or ambiguous; probing requests that would measure nothing; outputs
//! that would destroy what they replace; unclear refusals. Every case: exit 2 (or 3 for a
//! device), the file, line or field and the limit named, nothing written.

mod common;

use common::{bin, expect_input_error, write};

const CIRCLE: &str =
    "x_mm,y_mm,z_mm\n1,0,0\n0,1,0\n-1,0,0\n0,-1,0\n0.7071067811865476,0.7071067811865476,0\n";

#[test]
fn qif_plans_are_bounded_and_depth_limited() {
    let d = tempfile::tempdir().unwrap();
    let pts = write(d.path(), "c.csv", CIRCLE);
    let n = 50_000;
    let deep = write(
        d.path(),
        "deep.qif",
        format!(
            "<QIFDocument xmlns=\"http://qifstandards.org/xsd/qif3\">\n{}{}</QIFDocument>",
            "<a>".repeat(n),
            "</a>".repeat(n)
        ),
    );
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif-plan").arg(&deep).output().unwrap();
    expect_input_error(&out, &["deep.qif:2:", "nested more than 256"]);
    if std::path::Path::new("/dev/zero").exists() {
        let t = std::time::Instant::now();
        let out = bin().args(["fit", "circle"]).arg(&pts).args(["--qif-plan", "/dev/zero"]).output().unwrap();
        expect_input_error(&out, &["/dev/zero", "binary data"]);
        assert!(t.elapsed().as_secs_f64() < 10.0);
    } else {
        eprintln!("SKIPPED: no /dev/zero on this system");
    }
    let qif2 = write(
        d.path(),
        "old.qif",
        "<QIFDocument xmlns=\"http://qifstandards.org/xsd/qif2\"><Characteristics/></QIFDocument>",
    );
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif-plan").arg(&qif2).output().unwrap();
    expect_input_error(&out, &["old.qif", "QIF 2", "qif2"]);
}

#[test]
fn probing_feeds_and_counts_have_physical_limits() {
    let out = bin()
        .args(["probe", "sphere", "--near=0,0,0", "--diameter-mm", "25", "--feed-mm-min", "1e9"])
        .output()
        .unwrap();
    expect_input_error(&out, &["1000000000 mm/min", "5000 mm/min", "overtravel"]);
    let d = tempfile::tempdir().unwrap();
    let holes = write(d.path(), "holes.csv", "id,x_mm,y_mm,z_mm\nA,10,20,0\n");
    for (opt, val, needle) in
        [("--feed-mm-min", "1e9", "5000 mm/min"), ("--points", "1000000000", "between 4 and 10000")]
    {
        let out = bin()
            .args(["somac", "inspect", "--diameter-mm", "6", "--holes"])
            .arg(&holes)
            .args([opt, val, "--db"])
            .arg(d.path().join("a.sqlite"))
            .output()
            .unwrap();
        expect_input_error(&out, &[needle]);
    }
    // The limit itself is accepted.
    let out = bin()
        .args([
            "probe",
            "sphere",
            "--near=0,0,0",
            "--diameter-mm",
            "25",
            "--feed-mm-min",
            "5000",
            "--points",
            "6",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
}

/// Outputs replace only regular files that are not the command's own inputs: the input named
/// as the output, a symlink, a FIFO, a character device are refused (exit 2), left as they were.
#[cfg(unix)]
#[test]
fn outputs_never_destroy_what_they_replace() {
    let d = tempfile::tempdir().unwrap();
    let pts = write(d.path(), "c.csv", CIRCLE);
    // The input as its own output, named another way.
    let same = d.path().join(".").join("c.csv");
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif").arg(&same).output().unwrap();
    expect_input_error(&out, &["same file as the input", "c.csv"]);
    assert_eq!(std::fs::read_to_string(&pts).unwrap(), CIRCLE);
    let target = write(d.path(), "t.qif", "keep");
    let link = d.path().join("l.qif");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif").arg(&link).output().unwrap();
    expect_input_error(&out, &["l.qif", "symbolic link"]);
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    let fifo = d.path().join("f.qif");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()));
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif").arg(&fifo).output().unwrap();
    expect_input_error(&out, &["f.qif", "FIFO"]);
    let out = bin().args(["fit", "circle"]).arg(&pts).args(["--qif", "/dev/null"]).output().unwrap();
    expect_input_error(&out, &["/dev/null", "character device"]);
    // ippdme serve --log onto its own part file, or onto a full device: refused before serving.
    let part = write(d.path(), "part.toml", "# part\n");
    let out = bin()
        .args(["ippdme", "serve", "--port", "0", "--part"])
        .arg(&part)
        .arg("--log")
        .arg(d.path().join(".").join("part.toml"))
        .output()
        .unwrap();
    expect_input_error(&out, &["--log", "same file as the input", "part.toml"]);
    assert_eq!(std::fs::read_to_string(&part).unwrap(), "# part\n");
    let out = bin().args(["ippdme", "serve", "--port", "0", "--log", "/dev/full"]).output().unwrap();
    expect_input_error(&out, &["--log", "/dev/full", "character device"]);
}
