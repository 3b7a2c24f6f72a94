//! `truepos somac run --controller linuxcncrsh://…` against a real LinuxCNC started by the test:
//! a 20-hole spar program with and without correction (LinuxCNC moves the axes, the virtual
//! cell's trackers observe its actual position), and an e-stop pressed during a run. Skipped
//! loudly when LinuxCNC is not installed.

mod common;

use common::bin;
use std::path::Path;
use std::time::{Duration, Instant};
use truepos_linuxcnc::harness::{SimLinuxCnc, SphereTruth};

fn run(dir: &Path, url: &str, db: &str, extra: &[&str]) -> std::process::Output {
    bin()
        .args(["somac", "run", "--program"])
        .arg(dir.join("program.nc"))
        .arg("--cell")
        .arg(dir.join("cell.toml"))
        .arg("--db")
        .arg(dir.join(db))
        .args(["--controller", url, "--json"])
        .args(extra)
        .output()
        .unwrap()
}

fn report(label: &str, j: &serde_json::Value) {
    let stops = j["stops"].as_array().unwrap();
    let true_errs: Vec<f64> = stops.iter().filter_map(|s| s["true_error_mm"].as_f64()).collect();
    let walls: Vec<f64> =
        j["stop_wall_s"].as_array().unwrap().iter().map(|w| w["wall_s"].as_f64().unwrap()).collect();
    let statuses: Vec<&str> = stops.iter().map(|s| s["status"].as_str().unwrap()).collect();
    eprintln!(
        "somac on LinuxCNC ({label}): {} stops, true hole error mean {:.4} max {:.4} mm; measured mean {:.4} max {:.4} mm; \
         wall {:.1} s, per stop {:.2}–{:.2} s (mean {:.2}); statuses {:?}",
        stops.len(),
        j["true_mean_error_mm"].as_f64().unwrap(),
        j["true_max_error_mm"].as_f64().unwrap(),
        j["mean_error_mm"].as_f64().unwrap(),
        j["max_error_mm"].as_f64().unwrap(),
        j["wall_s"].as_f64().unwrap(),
        walls.iter().cloned().fold(f64::MAX, f64::min),
        walls.iter().cloned().fold(0.0, f64::max),
        walls.iter().sum::<f64>() / walls.len() as f64,
        statuses
    );
    eprintln!(
        "  true errors (mm): {:?}",
        true_errs.iter().map(|e| (e * 1e4).round() / 1e4).collect::<Vec<_>>()
    );
}

#[test]
fn somac_on_linuxcnc_corrects_and_stops_on_estop() {
    let sim = match SimLinuxCnc::start(SphereTruth::default()) {
        Ok(s) => s,
        Err(why) => {
            eprintln!("SKIPPED: somac on LinuxCNC: {why}");
            return;
        }
    };
    sim.arm().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let out = bin()
        .args(["simulate", "somac", "--out"])
        .arg(dir)
        .args(["--seed", "3", "--holes-per-row", "10"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let url = sim.url();

    // Native: measure only.
    let out = run(dir, &url, "native.sqlite", &["--no-correct"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(matches!(out.status.code(), Some(0) | Some(1)), "{err}");
    let native: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    report("no correction", &native);
    assert_eq!(native["stops"].as_array().unwrap().len(), 20);
    assert!(native["controller"]["version"].as_str().unwrap().starts_with("LinuxCNC 2.9"));

    // With correction.
    let out = run(dir, &url, "corrected.sqlite", &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(matches!(out.status.code(), Some(0) | Some(1)), "{err}");
    let corr: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    report("corrected", &corr);
    let stops = corr["stops"].as_array().unwrap();
    assert_eq!(stops.len(), 20);
    // The correction loop closes on the tracker through LinuxCNC: the true error drops well
    // below the native one (the virtual gantry's structural error is ~0.1–0.5 mm; the corrected
    // error is the trackers' uncertainty and the threshold, tens of µm).
    let before = native["true_mean_error_mm"].as_f64().unwrap();
    let after = corr["true_mean_error_mm"].as_f64().unwrap();
    assert!(after < 0.5 * before && after < 0.08, "before {before} after {after}");
    assert!(stops.iter().filter(|s| s["status"] == "SUCCESS").count() >= 18, "{stops:?}");
    // The audit trail names the controller.
    let db = rusqlite::Connection::open(dir.join("corrected.sqlite")).unwrap();
    let (c, v): (String, String) = db
        .query_row("SELECT controller, controller_version FROM runs ORDER BY id DESC LIMIT 1", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
        .unwrap();
    assert_eq!(c, url);
    assert!(v.starts_with("LinuxCNC 2.9"), "{v}");

    // E-stop pressed during a run: exit 3 naming the address, no further motion, the audit
    // records the abort and the stop in progress as FAILURE.
    let child = bin()
        .args(["somac", "run", "--program"])
        .arg(dir.join("program.nc"))
        .arg("--cell")
        .arg(dir.join("cell.toml"))
        .arg("--db")
        .arg(dir.join("estop.sqlite"))
        .args(["--controller", &url, "--json"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(2500));
    sim.press_estop().unwrap();
    let t = Instant::now();
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("e-stop during somac ({:.1} s after the press): {err}", t.elapsed().as_secs_f64());
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains(&url) && err.contains("e-stop"), "{err}");
    assert!(t.elapsed() < Duration::from_secs(10));
    let db = rusqlite::Connection::open(dir.join("estop.sqlite")).unwrap();
    let run_id: i64 = db.query_row("SELECT max(id) FROM runs", [], |r| r.get(0)).unwrap();
    let aborted: i64 = db
        .query_row(
            "SELECT count(*) FROM alarms WHERE run_id = ?1 AND kind = 'controller_fault'",
            [run_id],
            |r| r.get(0),
        )
        .unwrap();
    let failed: i64 = db
        .query_row("SELECT count(*) FROM stops WHERE run_id = ?1 AND status = 'FAILURE'", [run_id], |r| {
            r.get(0)
        })
        .unwrap();
    let stops: i64 =
        db.query_row("SELECT count(*) FROM stops WHERE run_id = ?1", [run_id], |r| r.get(0)).unwrap();
    eprintln!("e-stop audit: {stops} stop results, {failed} FAILURE, {aborted} controller_fault alarm");
    assert_eq!(aborted, 1);
    assert!(failed >= 1);
    assert!(stops < 20);
}

/// `truepos somac inspect --controller linuxcncrsh://…` on the HAL plate's four bores (listed at
/// their round nominal positions), and `truepos head-offset acquire` on a machine without rotary
/// axes: refused before it moves, or one orientation that head-offset then refuses.
#[test]
fn somac_inspect_and_head_offset_acquire_on_linuxcnc() {
    let sim = match SimLinuxCnc::start(SphereTruth::default()) {
        Ok(s) => s,
        Err(why) => {
            eprintln!("SKIPPED: somac inspect on LinuxCNC: {why}");
            return;
        }
    };
    sim.arm().unwrap();
    let url = sim.url();
    let plate = sim.plate();
    let tip = sim.sphere().tip_radius_mm;
    let tmp = tempfile::tempdir().unwrap();
    let mut csv = String::from("id,x_mm,y_mm,z_mm\n");
    for (i, b) in plate.bores.iter().enumerate() {
        csv +=
            &format!("B{i},{},{},{}\n", b.center_xy_mm[0].round(), b.center_xy_mm[1].round(), plate.z_mm[1]);
    }
    let holes = common::write(tmp.path(), "holes.csv", csv);
    let t = Instant::now();
    let out = bin()
        .current_dir(tmp.path())
        .args(["somac", "inspect", "--controller", &url, "--holes"])
        .arg(&holes)
        .args([
            "--diameter-mm",
            "10",
            "--tip-diameter-mm",
            &format!("{}", 2.0 * tip),
            "--feed-mm-min",
            "50",
            "--json",
        ])
        .output()
        .unwrap();
    let secs = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(j["controller"]["version"].as_str().unwrap().starts_with("LinuxCNC 2.9"));
    let step = 50.0 / 60.0 * 1e-3;
    for (h, b) in j["holes"].as_array().unwrap().iter().zip(&plate.bores) {
        let m: Vec<f64> = serde_json::from_value(h["measured_mm"].clone()).unwrap();
        let ce = (m[0] - b.center_xy_mm[0]).hypot(m[1] - b.center_xy_mm[1]);
        let de = h["diameter_mm"].as_f64().unwrap() - b.diameter_mm;
        eprintln!(
            "somac inspect on LinuxCNC {}: position error {:.1} µm; vs HAL truth centre {:.3} µm, diameter {:.3} µm; {:.1} s",
            h["id"],
            h["position_error_mm"].as_f64().unwrap() * 1e3,
            ce * 1e3,
            de * 1e3,
            h["elapsed_s"].as_f64().unwrap()
        );
        // One servo step (F50 × 1 ms) on the centre and 0 … 2 steps on the diameter, + 2 nm read-back.
        assert!(ce <= step + 2e-6, "{ce}");
        assert!(de >= -2e-6 && de <= 2.0 * step + 2e-6, "{de}");
    }
    eprintln!("somac inspect on LinuxCNC: 4 holes in {secs:.1} s (process wall time)");

    // Head-offset acquisition needs B/C: refused at once, naming the address, nothing moved.
    let before = sim_position(&url);
    let t = Instant::now();
    let out = bin()
        .args(["head-offset", "acquire", "--controller", &url, "--near=120,45,30", "--diameter-mm", "25"])
        .args(["--tip-diameter-mm", "3", "--orientation", "0,0", "--orientation", "90,0", "--output"])
        .arg(tmp.path().join("h.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("head-offset acquire with B on LinuxCNC ({:.1} s): {err}", t.elapsed().as_secs_f64());
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains(&url) && err.contains("B (head swivel)") && err.contains("no rotary axes"), "{err}");
    assert!(!tmp.path().join("h.csv").exists());
    assert_eq!(sim_position(&url), before);
    // The one orientation it has: acquired, and head-offset says what that cannot determine.
    let out = bin()
        .args(["head-offset", "acquire", "--controller", &url, "--near=120,45,30", "--diameter-mm", "25"])
        .args([
            "--tip-diameter-mm",
            "3",
            "--points",
            "8",
            "--feed-mm-min",
            "200",
            "--orientation",
            "0,0",
            "--output",
        ])
        .arg(tmp.path().join("h.csv"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let out = bin().args(["head-offset", "--points"]).arg(tmp.path().join("h.csv")).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("head-offset on one LinuxCNC orientation: {err}");
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("one orientation"), "{err}");
}

/// The machine's position through a fresh linuxcncrsh session (the CLI's sessions have ended).
fn sim_position(url: &str) -> [f64; 3] {
    use truepos_device::ProbingMachine;
    let mut m = truepos_linuxcnc::LinuxCnc::open(url).unwrap();
    let p = m.position().unwrap();
    [p.x, p.y, p.z]
}
