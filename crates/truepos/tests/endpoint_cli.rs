//! CLI tests of the end-point control commands: `air`, `autoscale`, `orient`, `align`,
//! `simulate somac` + `somac run`.

use std::path::Path;
use std::process::Command;

fn truepos(args: &[&str], dir: &Path) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_truepos")).args(args).current_dir(dir).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json(s: &str) -> serde_json::Value {
    serde_json::from_str(s).unwrap_or_else(|e| panic!("not one JSON object ({e}): {s}"))
}

#[test]
fn air_reproduces_the_nist_equations() {
    let d = tempfile::tempdir().unwrap();
    let (code, out, _) = truepos(
        &["air", "--temperature-c", "20", "--pressure-pa", "101325", "--humidity-pct", "50", "--json"],
        d.path(),
    );
    assert_eq!(code, 0);
    let v = json(&out);
    // NIST calculator output for these conditions at 633 nm: 1.000271373 (printed to 1e-9).
    assert!((v["n"].as_f64().unwrap() - 1.000271373).abs() < 5e-10);
    assert_eq!(v["formula"], "ciddor");
    let (code, out, _) = truepos(
        &[
            "air",
            "--temperature-c",
            "20",
            "--pressure-pa",
            "101325",
            "--humidity-pct",
            "20",
            "--formula",
            "edlen",
            "--json",
        ],
        d.path(),
    );
    assert_eq!(code, 0);
    assert!((json(&out)["n"].as_f64().unwrap() - 1.000_271_629_169_165).abs() < 1e-11);
    let (code, _, err) = truepos(
        &["air", "--temperature-c", "20", "--pressure-pa", "101325", "--humidity-pct", "120"],
        d.path(),
    );
    assert_eq!(code, 2, "{err}");
}

#[test]
fn autoscale_gives_1_001_for_the_product_example() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(
        d.path().join("ref.csv"),
        "id,x_mm,y_mm,z_mm\nA,0,0,0\nB,100,0,0\nC,0,100,0\nD,100,100,10\n",
    )
    .unwrap();
    std::fs::write(
        d.path().join("meas.csv"),
        "# measured now\nid,x_mm,y_mm,z_mm\nD,100.1,100.1,10.01\nC,0,100.1,0\nB,100.1,0,0\nA,0,0,0\n",
    )
    .unwrap();
    let (code, out, err) = truepos(
        &[
            "autoscale",
            "--reference",
            "ref.csv",
            "--measured",
            "meas.csv",
            "--cte-ppm-per-c",
            "23",
            "--temperature-c",
            "63.4783",
            "--json",
        ],
        d.path(),
    );
    assert_eq!(code, 0, "{err}");
    let v = json(&out);
    assert!((v["scale"].as_f64().unwrap() - 1.001).abs() < 1e-12, "{v}");
    // expected 1 + 23e-6 · 43.4783 = 1.00100000: discrepancy below 0.01 ppm.
    assert!(v["discrepancy_ppm"].as_f64().unwrap().abs() < 0.01, "{v}");
    // Two features are enough: their distance ratio (1 mm measured for 100 mm: 0.01).
    std::fs::write(d.path().join("two.csv"), "id,x_mm,y_mm,z_mm\nA,0,0,0\nB,1,0,0\n").unwrap();
    let (code, out, err) =
        truepos(&["autoscale", "--reference", "ref.csv", "--measured", "two.csv", "--json"], d.path());
    assert_eq!(code, 0, "{err}");
    assert!((json(&out)["scale"].as_f64().unwrap() - 0.01).abs() < 1e-12);
    std::fs::write(d.path().join("one.csv"), "id,x_mm,y_mm,z_mm\nA,0,0,0\n").unwrap();
    let (code, _, err) = truepos(&["autoscale", "--reference", "ref.csv", "--measured", "one.csv"], d.path());
    assert_eq!(code, 2);
    assert!(err.contains("one.csv") && err.contains("at least 2"), "{err}");
}

const PROGRAM: &str = "%\r\nO1000 (SPAR)\r\nN10 G21 G90 G17\r\n\r\nN20 G0 X0 Y0 Z50 ; start\r\nN30 G1 X100.5 Y20 Z5 F1500 (MSG,Measure SOMaC)\r\nN40 M98 P9001 (DRILL)\r\nN50 G0 Z50\r\nM30\r\n%";

#[test]
fn orient_keeps_everything_but_the_transformed_coordinates() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("spar.nc"), PROGRAM).unwrap();
    std::fs::write(
        d.path().join("nom.csv"),
        "id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1000,0,0\nT3,0,500,0\nT4,1000,500,20\n",
    )
    .unwrap();
    // Identity: byte for byte.
    let (code, _, err) = truepos(
        &[
            "orient",
            "--reference",
            "nom.csv",
            "--measured",
            "nom.csv",
            "--program",
            "spar.nc",
            "--output",
            "same.nc",
        ],
        d.path(),
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read_to_string(d.path().join("same.nc")).unwrap(), PROGRAM);
    // A pure translation by (2, -1, 0.5) mm.
    std::fs::write(
        d.path().join("meas.csv"),
        "id,x_mm,y_mm,z_mm\nT1,2,-1,0.5\nT2,1002,-1,0.5\nT3,2,499,0.5\nT4,1002,499,20.5\n",
    )
    .unwrap();
    let (code, out, err) = truepos(
        &[
            "orient",
            "--reference",
            "nom.csv",
            "--measured",
            "meas.csv",
            "--program",
            "spar.nc",
            "--output",
            "moved.nc",
            "--json",
        ],
        d.path(),
    );
    assert_eq!(code, 0, "{err}");
    assert!(json(&out)["rms_mm"].as_f64().unwrap() < 1e-9);
    let moved = std::fs::read_to_string(d.path().join("moved.nc")).unwrap();
    let expect = PROGRAM
        .replace("N20 G0 X0 Y0 Z50 ; start", "N20 G0 X2.0000 Y-1.0000 Z50.5000 ; start")
        .replace("N30 G1 X100.5 Y20 Z5 F1500", "N30 G1 X102.5000 Y19.0000 Z5.5000 F1500")
        .replace("N50 G0 Z50\r", "N50 G0 Z50.5000\r");
    assert_eq!(moved, expect);
    // Malformed number: exit 2, line and column, no output file.
    std::fs::write(d.path().join("bad.nc"), "G0 X0 Y0 Z0\nG1 X1.2.3 Y0\n").unwrap();
    let (code, _, err) = truepos(
        &[
            "orient",
            "--reference",
            "nom.csv",
            "--measured",
            "meas.csv",
            "--program",
            "bad.nc",
            "--output",
            "bad_out.nc",
        ],
        d.path(),
    );
    assert_eq!(code, 2);
    assert!(err.contains("bad.nc:2:4"), "{err}");
    assert!(!d.path().join("bad_out.nc").exists());
    // Fewer than three targets.
    std::fs::write(d.path().join("few.csv"), "id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1,0,0\n").unwrap();
    let (code, _, err) = truepos(
        &[
            "orient",
            "--reference",
            "nom.csv",
            "--measured",
            "few.csv",
            "--program",
            "spar.nc",
            "--output",
            "x.nc",
        ],
        d.path(),
    );
    assert_eq!(code, 2);
    assert!(err.contains("at least 3"), "{err}");
    assert!(!d.path().join("x.nc").exists());
}

#[test]
fn align_recovers_a_known_transform_and_rejects_bad_files() {
    let d = tempfile::tempdir().unwrap();
    // machine = Rz(90°)·tracker + (10, 20, 30)
    std::fs::write(
        d.path().join("tracker.csv"),
        "id,x_mm,y_mm,z_mm,w\nA,1,0,0,1\nB,0,2,0,1\nC,0,0,3,2\nD,4,5,6,1\n",
    )
    .unwrap();
    std::fs::write(
        d.path().join("machine.csv"),
        "x_mm,id,y_mm,z_mm\n10,A,21,30\n8,B,20,30\n10,C,20,33\n5,D,24,36\n",
    )
    .unwrap();
    let (code, out, err) = truepos(
        &["align", "--from", "tracker.csv", "--to", "machine.csv", "--weights", "w", "--json"],
        d.path(),
    );
    assert_eq!(code, 0, "{err}");
    let v = json(&out);
    let t: Vec<f64> = v["translation_mm"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert!((t[0] - 10.0).abs() < 1e-9 && (t[1] - 20.0).abs() < 1e-9 && (t[2] - 30.0).abs() < 1e-9, "{v}");
    assert!((v["rotation"][0][1].as_f64().unwrap() + 1.0).abs() < 1e-12);
    assert!(v["rms_mm"].as_f64().unwrap() < 1e-9);
    let (code, out, _) = truepos(
        &["align", "--from", "tracker.csv", "--to", "machine.csv", "--method", "three-point", "--json"],
        d.path(),
    );
    assert_eq!(code, 0);
    assert!(json(&out)["residuals"][3]["residual_mm"].as_f64().unwrap() < 1e-9);
    std::fs::write(d.path().join("nan.csv"), "id,x_mm,y_mm,z_mm\nA,1,0,0\nB,0,NaN,0\nC,0,0,3\n").unwrap();
    let (code, _, err) = truepos(&["align", "--from", "nan.csv", "--to", "machine.csv"], d.path());
    assert_eq!(code, 2);
    assert!(err.contains("nan.csv:3:3"), "{err}");
}

#[test]
fn somac_run_on_the_virtual_gantry() {
    let d = tempfile::tempdir().unwrap();
    let (code, _, err) =
        truepos(&["simulate", "somac", "--out", "cell", "--seed", "2", "--holes-per-row", "12"], d.path());
    assert_eq!(code, 0, "{err}");
    for f in ["program.nc", "cell.toml", "truth.json"] {
        assert!(d.path().join("cell").join(f).exists(), "{f}");
    }
    let (code, out, err) = truepos(
        &[
            "somac",
            "run",
            "--program",
            "cell/program.nc",
            "--cell",
            "cell/cell.toml",
            "--db",
            "audit.sqlite",
            "--json",
        ],
        d.path(),
    );
    assert!(code == 0 || code == 1, "{err}");
    let v = json(&out);
    let stops = v["stops"].as_array().unwrap();
    assert_eq!(stops.len(), 24);
    for s in stops {
        assert!(["SUCCESS", "PARTIAL", "FAILURE"].contains(&s["status"].as_str().unwrap()));
        for k in ["line", "commanded_mm", "measured_mm", "corrections", "iterations", "final_error_mm"] {
            assert!(s.get(k).is_some(), "{k} missing");
        }
    }
    assert!(v["true_max_error_mm"].as_f64().unwrap() <= 0.050, "{v}");
    for k in ["alarms", "mean_error_mm", "std_error_mm", "max_error_mm"] {
        assert!(v.get(k).is_some(), "{k} missing");
    }
    assert!(d.path().join("audit.sqlite").exists());
    // A cell file with a bad value: exit 2 naming the file and line.
    let cell = std::fs::read_to_string(d.path().join("cell/cell.toml"))
        .unwrap()
        .replace("error_scale = 3.0", "error_scale = \"big\"");
    std::fs::write(d.path().join("bad.toml"), cell).unwrap();
    let (code, _, err) =
        truepos(&["somac", "run", "--program", "cell/program.nc", "--cell", "bad.toml"], d.path());
    assert_eq!(code, 2);
    // The line of the key (cell.toml is commented, so not a fixed number).
    let text = std::fs::read_to_string(d.path().join("bad.toml")).unwrap();
    let line = text.lines().position(|l| l.starts_with("error_scale")).unwrap() + 1;
    assert!(err.contains(&format!("bad.toml:{line}")), "{err}");
}
