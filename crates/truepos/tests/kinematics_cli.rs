//! `truepos kinematics calibrate`: on the virtual xyzbc-trt machine (against its truth), the
//! refusals before any motion (orientations that cannot determine a pin, maxkins, bad options),
//! and, `#[ignore]`d (≈ 2.5 min), through a real LinuxCNC five-axis controller started by the
//! test (skipped loudly without LinuxCNC or its sphere5 truth component).

mod common;

use common::bin;
use std::time::Instant;
use truepos_linuxcnc::harness::{FiveAxisTruth, SimLinuxCnc};

const SET: [&str; 6] = ["0,0", "0,120", "0,240", "45,0", "90,120", "90,240"];

fn orientation_args(set: &[&str]) -> Vec<String> {
    set.iter().flat_map(|o| ["--orientation".to_string(), o.to_string()]).collect()
}

fn json(out: &std::process::Output) -> serde_json::Value {
    assert_eq!(out.status.code(), Some(0), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// (name → identified, true) of the four observable axes, in µm of error.
fn axis_errors_um(j: &serde_json::Value, truth: &[f64; 5]) -> [f64; 4] {
    let p = |n: &str| {
        j["parameters"].as_array().unwrap().iter().find(|q| q["name"] == n).unwrap()["identified"]
            .as_f64()
            .unwrap()
    };
    // z-rot-point is not written: the B axis's Z is z-rot-point (configured) + z-offset.
    let zr = j["unchanged"][0]["configured"].as_f64().unwrap();
    [
        (p("x-rot-point") - truth[0]) * 1e3,
        (p("y-rot-point") - truth[1]) * 1e3,
        (p("x-rot-point") + p("x-offset") - truth[0] - truth[3]) * 1e3,
        (zr + p("z-offset") - truth[2] - truth[4]) * 1e3,
    ]
}

#[test]
fn virtual_calibration_finds_the_true_axes_and_the_write_back_removes_the_spread() {
    let out = bin()
        .args(["kinematics", "calibrate", "--model", "xyzbc-trt", "--near=60,25,15", "--diameter-mm", "25"])
        .args(["--tip-diameter-mm", "2", "--clearance-mm", "1", "--apply", "--verify", "--json"])
        .args(orientation_args(&SET))
        .output()
        .unwrap();
    let j = json(&out);
    let truth: Vec<f64> = j["virtual_truth"]["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["value"].as_f64().unwrap())
        .collect();
    let e = axis_errors_um(&j, &[truth[0], truth[1], truth[2], truth[3], truth[4]]);
    for v in e {
        assert!(v.abs() < 2.0, "{e:?}");
    }
    assert_eq!(j["model"], "xyzbc-trt");
    assert_eq!(j["applied"], true);
    assert_eq!(j["centres_mm"].as_array().unwrap().len(), 6);
    assert_eq!(j["coverage_factor"], 2.0);
    assert!(j["spread_before_mm"].as_f64().unwrap() > 0.01);
    assert!(j["spread_after_predicted_mm"].as_f64().unwrap() < 0.002);
    assert!(j["verify"]["spread_mm"].as_f64().unwrap() < 0.002, "{}", j["verify"]);
    assert_eq!(j["verify"]["centres_mm"].as_array().unwrap().len(), 5);
    assert!(j["ini_lines"][0] == "[KINS]" && j["hal_lines"].as_array().unwrap().len() == 4);
    for p in j["parameters"].as_array().unwrap() {
        let u = p["uncertainty"].as_f64().unwrap();
        assert!(u > 0.0 && u < 0.002, "{p}");
    }
    // Human text: the dry run says nothing was written.
    let out = bin()
        .args(["kinematics", "calibrate", "--model", "xyzbc-trt", "--near=60,25,15", "--diameter-mm", "25"])
        .args(orientation_args(&SET[..4]))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("dry run") && text.contains("X_ROT_POINT = "), "{text}");
}

#[test]
fn refusals_are_exit_2_before_any_motion() {
    let base = ["kinematics", "calibrate", "--near=60,25,15", "--diameter-mm", "25", "--json"];
    let cases: Vec<(Vec<String>, &str)> = vec![
        // No two B angles: the B axis (x-offset, z-offset) is not determined.
        (
            [vec!["--model".to_string(), "xyzbc-trt".into()], orientation_args(&["0,0", "0,120", "0,240"])]
                .concat(),
            "x-offset, z-offset",
        ),
        // No two C angles: the C axis.
        (
            [vec!["--model".to_string(), "xyzbc-trt".into()], orientation_args(&["0,0", "45,0", "90,0"])]
                .concat(),
            "x-rot-point, y-rot-point",
        ),
        (
            [vec!["--model".to_string(), "maxkins".into()], orientation_args(&SET)].concat(),
            "forward and inverse",
        ),
        (
            [vec!["--model".to_string(), "xyzbc-trt".into()], orientation_args(&["0,0", "0,120", "120,0"])]
                .concat(),
            "90°",
        ),
        (
            [vec!["--model".to_string(), "xyzbc-trt".into(), "--verify".into()], orientation_args(&SET)]
                .concat(),
            "--apply",
        ),
        // Refused before the controller is even contacted (nothing listens there).
        (
            [
                vec![
                    "--model".to_string(),
                    "xyzbc-trt".into(),
                    "--controller".into(),
                    "linuxcncrsh://127.0.0.1:9".into(),
                ],
                orientation_args(&["0,0", "0,90"]),
            ]
            .concat(),
            "x-offset",
        ),
    ];
    for (args, expect) in cases {
        let out = bin().args(base).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(out.stdout.is_empty());
        assert!(err.contains(expect), "{args:?}: {err}");
    }
    // A controller that is not there: exit 3 naming it.
    let out = bin()
        .args(base)
        .args(["--model", "xyzbc-trt", "--controller", "linuxcncrsh://127.0.0.1:9"])
        .args(orientation_args(&SET))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("127.0.0.1:9"));
}

/// The whole command on a real LinuxCNC five-axis controller: the geometry configured tens of µm
/// off the truth; calibrate, apply, verify at five other orientations.
#[test]
#[ignore]
fn linuxcnc_five_axis_calibrate_apply_verify_through_the_cli() {
    let five = FiveAxisTruth::default();
    let sim = match SimLinuxCnc::start_five_axis(five) {
        Ok(s) => s,
        Err(why) => {
            eprintln!("SKIPPED: LinuxCNC five-axis CLI test: {why}");
            return;
        }
    };
    sim.arm().expect("arming");
    let c = five.sphere_center_mm;
    let near = format!("--near={},{},{}", c.x + 0.031, c.y - 0.022, c.z + 0.027);
    let t0 = Instant::now();
    let out = bin()
        .args(["kinematics", "calibrate", "--controller", &sim.url(), "--model", "xyzbc-trt", &near])
        .args(["--diameter-mm", "25", "--tip-diameter-mm", "2", "--clearance-mm", "0.5", "--points", "9"])
        .args(["--apply", "--verify", "--json"])
        .args(orientation_args(&SET))
        .output()
        .unwrap();
    let secs = t0.elapsed().as_secs_f64();
    let j = json(&out);
    let e = axis_errors_um(&j, &five.truth);
    let spread = j["verify"]["spread_mm"].as_f64().unwrap() * 1e3;
    eprintln!(
        "CLI on LinuxCNC: {secs:.0} s; {:.1} s per orientation; axes error {e:.2?} µm; spread {:.1} µm before, {:.2} µm predicted, {spread:.2} µm verified",
        j["time_per_orientation_s"].as_f64().unwrap(),
        j["spread_before_mm"].as_f64().unwrap() * 1e3,
        j["spread_after_predicted_mm"].as_f64().unwrap() * 1e3
    );
    for v in e {
        assert!(v.abs() < 3.0, "{e:?}");
    }
    assert!(spread < 3.0);
    assert_eq!(j["applied"], true);
    // The configured values were read from the running controller.
    let conf = |n: &str| {
        j["parameters"].as_array().unwrap().iter().find(|q| q["name"] == n).unwrap()["configured"]
            .as_f64()
            .unwrap()
    };
    assert_eq!(
        [conf("x-rot-point"), conf("y-rot-point"), conf("x-offset"), conf("z-offset")],
        [five.configured[0], five.configured[1], five.configured[3], five.configured[4]]
    );
}

/// `--db`: the calibration is one audit-trail run with each parameter before and after, and the
/// trail's chain verifies.
#[test]
fn the_calibration_is_recorded_in_the_audit_trail() {
    let d = tempfile::tempdir().unwrap();
    let db = d.path().join("trail.sqlite");
    let out = bin()
        .args(["kinematics", "calibrate", "--model", "xyzbc-trt", "--near=60,25,15", "--diameter-mm", "25"])
        .args(["--tip-diameter-mm", "2", "--clearance-mm", "1", "--apply", "--json", "--db"])
        .arg(&db)
        .args(orientation_args(&SET))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let c = rusqlite::Connection::open(&db).unwrap();
    let (status, message): (String, String) = c
        .query_row("SELECT status, message FROM runs ORDER BY id DESC LIMIT 1", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
        .unwrap();
    assert_eq!(status, "SUCCESS");
    assert!(message.starts_with("applied"), "{message}");
    // Each parameter before and after, as the JSON reports it, in the trail's results.
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let show = bin().args(["audit", "show", "1", "--json", "--db"]).arg(&db).output().unwrap();
    let s: serde_json::Value = serde_json::from_slice(&show.stdout).unwrap();
    let results = s["results"].as_array().unwrap();
    let params = j["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 4);
    for p in params {
        let row = |q: &str| {
            results
                .iter()
                .find(|r| r["fields"]["label"] == p["name"] && r["fields"]["quantity"] == q)
                .unwrap_or_else(|| panic!("{} {q} not recorded", p["name"]))["fields"]
                .clone()
        };
        assert_eq!(row("configured")["value"], p["configured"]);
        assert_eq!(row("identified")["value"], p["identified"]);
        assert_eq!(row("identified")["expanded_uncertainty"], p["expanded_uncertainty"]);
        assert_eq!(row("identified")["verdict"], "written");
    }
    let v = bin().args(["audit", "verify", "--db"]).arg(&db).output().unwrap();
    assert_eq!(v.status.code(), Some(0), "{}", String::from_utf8_lossy(&v.stderr));
}

/// `--machine-model`: the parameters' uncertainties are task-specific (the calibration simulated
/// on machines drawn from the model), at least the fit's own, the JSON says so, and a bad model
/// is refused before anything moves.
#[test]
fn machine_model_gives_task_specific_uncertainties() {
    let d = tempfile::tempdir().unwrap();
    let model = d.path().join("model.toml");
    std::fs::write(&model, "[ippdme.model]\n").unwrap();
    let run = |extra: &[&str]| {
        bin()
            .args([
                "kinematics",
                "calibrate",
                "--model",
                "xyzbc-trt",
                "--near=60,25,15",
                "--diameter-mm",
                "25",
            ])
            .args(["--tip-diameter-mm", "2", "--clearance-mm", "1", "--json"])
            .args(orientation_args(&SET))
            .args(extra)
            .output()
            .unwrap()
    };
    let fit = run(&[]);
    assert_eq!(fit.status.code(), Some(0), "{}", String::from_utf8_lossy(&fit.stderr));
    assert!(String::from_utf8_lossy(&fit.stderr).contains("no --machine-model"));
    let fit: serde_json::Value = serde_json::from_slice(&fit.stdout).unwrap();
    assert_eq!(fit["uncertainty_method"], "fit-residuals");
    let o = run(&["--machine-model", model.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["uncertainty_method"], "task-specific");
    assert_eq!(j["monte_carlo_runs"], 200);
    for (p, f) in j["parameters"].as_array().unwrap().iter().zip(fit["parameters"].as_array().unwrap()) {
        let (u, big_u) = (p["uncertainty"].as_f64().unwrap(), p["expanded_uncertainty"].as_f64().unwrap());
        assert!(u >= f["uncertainty"].as_f64().unwrap() && big_u >= u, "{p}");
        assert!(big_u < 0.02, "U of a few µm, not tens: {p}");
    }
    std::fs::write(&model, "[ippdme.model]\nnoise = 1\n").unwrap();
    let o = run(&["--machine-model", model.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!String::from_utf8_lossy(&o.stderr).contains("orientation 1/"), "nothing moved");
}
