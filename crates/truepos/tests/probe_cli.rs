//! `truepos probe sphere`: on the virtual machine tool (against its truth), bad usage, an
//! unreachable controller, and through a real LinuxCNC started by the test (skipped loudly when
//! LinuxCNC is not installed).

mod common;

use common::bin;
use std::net::TcpListener;
use std::time::{Duration, Instant};
use truepos_linuxcnc::harness::{SimLinuxCnc, SphereTruth};

fn json(out: &std::process::Output) -> serde_json::Value {
    assert_eq!(out.status.code(), Some(0), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn v3(j: &serde_json::Value) -> [f64; 3] {
    let a = j.as_array().unwrap();
    [a[0].as_f64().unwrap(), a[1].as_f64().unwrap(), a[2].as_f64().unwrap()]
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn virtual_sphere_is_found_within_the_latch_error() {
    let out = bin()
        .args(["probe", "sphere", "--near=-10.5,20,-3", "--diameter-mm", "25", "--tip-diameter-mm", "3"])
        .args(["--points", "15", "--json"])
        .output()
        .unwrap();
    let j = json(&out);
    assert_eq!(j["n_points"], 15);
    assert_eq!(j["points"].as_array().unwrap().len(), 15);
    assert_eq!(j["controller"]["address"], "virtual");
    let truth = &j["virtual_truth"];
    // Default feed 50 mm/min: the 1 ms servo latch puts each point up to 0.83 µm inside, plus
    // 0.5 µm pre-travel and 0.1 µm noise: the radius reads low by ≈ 0.5 + 0.42 µm, the centre
    // within about one servo step.
    let ce = dist(v3(&j["center_mm"]), v3(&truth["center_mm"]));
    assert!(ce < 0.0015, "centre error {ce}");
    let re = j["radius_mm"].as_f64().unwrap() - truth["radius_mm"].as_f64().unwrap();
    assert!(re < 0.0 && re > -0.0015, "radius error {re}");
    // The virtual setup puts the sphere a few tenths off the nominal centre (seeded).
    assert!(dist(v3(&truth["center_mm"]), [-10.5, 20.0, -3.0]) < 0.5);
}

#[test]
fn bad_usage_is_exit_2() {
    for args in [
        vec!["--near", "1,2", "--diameter-mm", "25"],
        vec!["--near=1,2,3", "--diameter-mm", "-25"],
        vec!["--near=1,2,3", "--diameter-mm", "25", "--points", "4"],
        vec!["--near=1,2,3", "--diameter-mm", "25", "--controller", "ftp://host:21"],
        vec!["--near=1,2,3", "--diameter-mm", "25", "--controller", "linuxcncrsh://host"],
    ] {
        let out = bin().args(["probe", "sphere"]).args(&args).arg("--json").output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(out.stdout.is_empty());
    }
}

#[test]
fn an_unreachable_controller_is_exit_3_naming_the_address_within_ten_seconds() {
    let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let url = format!("linuxcncrsh://127.0.0.1:{port}");
    let t = Instant::now();
    let out = bin()
        .args(["probe", "sphere", "--controller", &url, "--near=0,0,0", "--diameter-mm", "25", "--json"])
        .output()
        .unwrap();
    assert!(t.elapsed() < Duration::from_secs(10));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains(&url), "{err}");
    assert!(out.stdout.is_empty());
}

#[test]
fn probe_sphere_through_linuxcnc() {
    let sim = match SimLinuxCnc::start(SphereTruth::default()) {
        Ok(s) => s,
        Err(why) => {
            eprintln!("SKIPPED: probe sphere through LinuxCNC: {why}");
            return;
        }
    };
    // Not armed: in e-stop → exit 3, saying so.
    let base =
        ["probe", "sphere", "--controller", &sim.url(), "--diameter-mm", "25", "--tip-diameter-mm", "3"];
    let out = bin().args(base).args(["--near=120,45,30", "--json"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains("e-stop") && err.contains(&sim.url()), "{err}");
    sim.arm().unwrap();
    let truth = sim.sphere();
    let out = bin()
        .args(base)
        .args([
            "--near=120.1,44.9,30.1",
            "--points",
            "6",
            "--feed-mm-min",
            "200",
            "--clearance-mm",
            "0.5",
            "--json",
        ])
        .output()
        .unwrap();
    let j = json(&out);
    assert!(j["controller"]["version"].as_str().unwrap().starts_with("LinuxCNC 2.9"), "{j}");
    let c = truth.center_mm;
    // 200 mm/min: each point latches up to 3.3 µm inside (1 ms servo): the radius reads low by
    // about half that, the centre moves by up to about a step; 5 µm as in the verified recipe.
    let ce = dist(v3(&j["center_mm"]), [c.x, c.y, c.z]);
    let re = j["radius_mm"].as_f64().unwrap() - truth.radius_mm;
    eprintln!(
        "CLI through LinuxCNC F200, 6 points: centre error {:.2} µm, radius error {:.2} µm",
        ce * 1e3,
        re * 1e3
    );
    assert!(ce < 0.005, "centre error {ce}");
    assert!(re <= 1e-6 && re > -0.005, "radius error {re}");
    // The sphere is 3 mm lower than said: the first probing move ends without contact.
    let out = bin()
        .args(base)
        .args(["--near=120,45,33", "--clearance-mm", "0.5", "--feed-mm-min", "200", "--json"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains("G38.2") && err.contains("without contact") && err.contains(&sim.url()), "{err}");
    assert!(out.stdout.is_empty());
    // The delay of LinuxCNC's probe latch by the feeds method (`latency probe`): its probe input
    // is sampled in the 1 ms servo thread, so a latch is 0…1 period late at a random phase:
    // 0.5 ms on average (one run measured 500.7 ± 2.2 µs). Allowed: 5 u plus 50 µs for the
    // finite sample of phases.
    let out = bin()
        .args(["latency", "probe", "--controller", &sim.url(), "--near=120,45,30", "--diameter-mm", "25"])
        .args(["--tip-diameter-mm", "3", "--feeds-mm-min", "50,100,200,400", "--points", "12"])
        .args(["--clearance-mm", "0.5", "--json"])
        .output()
        .unwrap();
    let j = json(&out);
    let (d, u) = (j["delay_s"].as_f64().unwrap(), j["uncertainty_s"].as_f64().unwrap());
    eprintln!(
        "latency probe through LinuxCNC (F50…F400, 12 points each): delay {:.1} µs ± {:.1} µs",
        d * 1e6,
        u * 1e6
    );
    assert!(u > 1e-7 && u < 1e-4, "u {u} s: {j}");
    assert!((d - 0.0005).abs() < 5.0 * u + 50e-6, "delay {d} s ± {u}: {j}");
}
