//! `truepos somac inspect` and `truepos head-offset acquire` on the virtual controller: results
//! against the virtual machine's truth, human output, and bad input (exit 2, nothing moved).

mod common;

use common::write;

/// `truepos` in cargo's scratch directory: `somac inspect` appends to `./somac-audit.sqlite`.
fn bin() -> std::process::Command {
    let mut c = common::bin();
    c.current_dir(env!("CARGO_TARGET_TMPDIR"));
    c
}

fn json(out: &std::process::Output) -> serde_json::Value {
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn somac_inspect_finds_the_virtual_holes_of_a_program() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let out =
        bin().args(["simulate", "somac", "--out"]).arg(dir).args(["--holes-per-row", "4"]).output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    let j = json(
        &bin()
            .args(["somac", "inspect", "--program"])
            .arg(dir.join("program.nc"))
            .args(["--diameter-mm", "8", "--tip-diameter-mm", "3", "--feed-mm-min", "50", "--json"])
            .output()
            .unwrap(),
    );
    let holes = j["holes"].as_array().unwrap();
    let truth = j["virtual_truth"].as_array().unwrap();
    assert_eq!(holes.len(), 8);
    assert_eq!(j["n_holes"], 8);
    for (h, t) in holes.iter().zip(truth) {
        let m: Vec<f64> = serde_json::from_value(h["measured_mm"].clone()).unwrap();
        let n: Vec<f64> = serde_json::from_value(h["nominal_mm"].clone()).unwrap();
        let tt: Vec<f64> = serde_json::from_value(t["top_mm"].clone()).unwrap();
        let ce = (m[0] - tt[0]).hypot(m[1] - tt[1]);
        // One servo step at F50 (0.83 µm) plus 4σ of the axes' 0.1 µm noise.
        assert!(ce < 1.3e-3, "{}: centre {ce} mm from the truth", h["id"]);
        let pe = h["position_error_mm"].as_f64().unwrap();
        assert!((pe - (tt[0] - n[0]).hypot(tt[1] - n[1])).abs() < 1.3e-3);
        assert!((h["true_position_mm"].as_f64().unwrap() - 2.0 * pe).abs() < 1e-12);
        // Diameter: + 2 × 0.5 µm pre-travel + 0 … 2 steps.
        let de = h["diameter_mm"].as_f64().unwrap() - t["diameter_mm"].as_f64().unwrap();
        assert!(de > 0.6e-3 && de < 3.1e-3, "{}: diameter error {de}", h["id"]);
        assert!(h["line"].as_u64().is_some() && h["n_points"] == 8);
    }
    assert_eq!(j["controller"]["address"], "virtual");
    // The same in human text, with a tolerance every hole exceeds: exit 1, named.
    let out = bin()
        .args(["somac", "inspect", "--program"])
        .arg(dir.join("program.nc"))
        .args(["--diameter-mm", "8", "--tip-diameter-mm", "3", "--tolerance-mm", "0.000001"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("pos µm") && text.contains("position error: mean"), "{text}");
    assert!(text.contains("8 of 8 holes beyond the position tolerance"), "{text}");
}

#[test]
fn somac_inspect_reads_a_hole_list_with_diameters_and_refuses_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let holes = write(tmp.path(), "holes.csv", "id,x_mm,y_mm,z_mm,diameter_mm\nA,10,20,0,6\nB,40,20,0,12\n");
    let j = json(
        &bin()
            .args(["somac", "inspect", "--holes"])
            .arg(&holes)
            .args(["--tip-diameter-mm", "2", "--points", "6", "--json"])
            .output()
            .unwrap(),
    );
    let d: Vec<f64> =
        j["holes"].as_array().unwrap().iter().map(|h| h["diameter_mm"].as_f64().unwrap()).collect();
    // σ = 5 µm on the true diameter: 6 and 12 mm within 30 µm.
    assert!((d[0] - 6.0).abs() < 0.03 && (d[1] - 12.0).abs() < 0.03, "{d:?}");
    // A non-positive diameter: exit 2 at its line and column.
    let bad = write(tmp.path(), "bad.csv", "id,x_mm,y_mm,z_mm,diameter_mm\nA,10,20,0,6\nB,40,20,0,-1\n");
    let out = bin().args(["somac", "inspect", "--holes"]).arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("bad.csv:3:5"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // No diameter anywhere; a tip that does not fit; neither --program nor --holes.
    let nod = write(tmp.path(), "nod.csv", "id,x_mm,y_mm,z_mm\nA,10,20,0\n");
    let out = bin().args(["somac", "inspect", "--holes"]).arg(&nod).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = bin()
        .args(["somac", "inspect", "--holes"])
        .arg(&nod)
        .args(["--diameter-mm", "3", "--tip-diameter-mm", "2.5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no room"));
    assert_eq!(
        bin().args(["somac", "inspect", "--diameter-mm", "3"]).output().unwrap().status.code(),
        Some(2)
    );
}

#[test]
fn head_offset_acquire_on_the_virtual_machine_then_head_offset_recovers_its_offset() {
    let tmp = tempfile::tempdir().unwrap();
    let pts = tmp.path().join("points.csv");
    let mut cmd = bin();
    cmd.args([
        "head-offset",
        "acquire",
        "--near=600,250,30",
        "--diameter-mm",
        "25",
        "--tip-diameter-mm",
        "3",
    ]);
    for o in ["0,0", "0,120", "0,240", "90,0", "90,120", "90,240"] {
        cmd.args(["--orientation", o]);
    }
    cmd.args([
        "--nominal-offset-mm=42,-18,-165",
        "--table-center-mm",
        "500,250,0",
        "--seed",
        "4",
        "--json",
        "--output",
    ]);
    let acq = json(&cmd.arg(&pts).output().unwrap());
    assert_eq!(acq["n_points"], 72);
    let truth: Vec<f64> = serde_json::from_value(acq["virtual_truth"]["head_offset_mm"].clone()).unwrap();
    let r = json(
        &bin()
            .args(["head-offset", "--points"])
            .arg(&pts)
            .args(["--table-center-mm", "500,250,0", "--json"])
            .output()
            .unwrap(),
    );
    let off: Vec<f64> = serde_json::from_value(r["offset_mm"].clone()).unwrap();
    let u: Vec<f64> = serde_json::from_value(r["uncertainty_mm"].clone()).unwrap();
    for i in 0..3 {
        let e = off[i] - truth[i];
        eprintln!(
            "CLI head offset [{i}]: {:.6} mm, truth {:.6}, error {:.3} µm, u {:.3} µm",
            off[i],
            truth[i],
            e * 1e3,
            u[i] * 1e3
        );
        // k = 2 plus 0.5 µm for the servo latch's bias (0 … 0.83 µm into the sphere at F50).
        assert!(e.abs() <= 2.0 * u[i] + 5e-4, "component {i}: error {e}, u {}", u[i]);
    }
    // C ≠ 0 without the table centre: exit 2 before anything moves, no file.
    let out = bin()
        .args([
            "head-offset",
            "acquire",
            "--near=600,250,30",
            "--diameter-mm",
            "25",
            "--orientation",
            "0,90",
            "--output",
        ])
        .arg(tmp.path().join("x.csv"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(!tmp.path().join("x.csv").exists());
}
