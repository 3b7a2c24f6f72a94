//! `truepos ippdme serve` as a process: listening line, a full session with the log, SIGTERM →
//! exit 0, bad part file → exit 2 naming file and line, port in use → exit 3.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::process::Command;
use std::time::{Duration, Instant};

fn truepos() -> Command {
    Command::new(env!("CARGO_BIN_EXE_truepos"))
}

/// Start `truepos ippdme serve` on a free loopback port with `part` (and `extra` options);
/// returns the child and the address it printed.
fn spawn_server(part: &std::path::Path, extra: &[&std::ffi::OsStr]) -> (std::process::Child, String) {
    common::ippdme_server(part.parent().unwrap_or(std::path::Path::new(".")), part, extra)
}

#[test]
fn serve_runs_a_session_logs_it_and_ends_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [0, 0, 0]\ndiameter_mm = 20\n").unwrap();
    let log = dir.path().join("ippdme.log");
    // The ideal machine (every error model off) answers exactly.
    let machine = ideal_machine(dir.path());
    let (mut child, addr) =
        spawn_server(&part, &["--log".as_ref(), log.as_os_str(), "--machine".as_ref(), machine.as_os_str()]);
    let s = TcpStream::connect(&addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    w.write_all(b"00001 StartSession()\r\n00002 Home()\r\n00003 ChangeTool(\"Probe1\")\r\n00004 PtMeas(X(0), Y(0), Z(10), IJK(0,0,1))\r\n00005 EndSession()\r\n").unwrap();
    let mut lines = Vec::new();
    while lines.last().is_none_or(|l: &String| l != "00005 %") {
        let mut l = String::new();
        assert!(r.read_line(&mut l).unwrap() > 0, "{lines:?}");
        lines.push(l.trim_end().to_string());
    }
    assert!(lines.contains(&"00004 # X(0.000000), Y(0.000000), Z(11.500000)".to_string()), "{lines:?}");
    drop((w, r));
    // SIGTERM: exit 0.
    unsafe_kill(child.id());
    let t0 = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "no exit after SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(status.code(), Some(0));
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.contains(" < 00004 PtMeas(X(0), Y(0), Z(10), IJK(0,0,1))"), "{text}");
    assert!(text.contains(" > 00004 # X(0.000000), Y(0.000000), Z(11.500000)"), "{text}");
}

#[test]
fn serve_plans_an_unknown_contour_scan_and_logs_how() {
    // The default (realistic) machine, a table plane Z = 0: a ScanIn… line on it is planned.
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[plane]]\nid = \"table\"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n").unwrap();
    let log = dir.path().join("ippdme.log");
    let (mut child, addr) = spawn_server(&part, &["--log".as_ref(), log.as_os_str()]);
    let s = TcpStream::connect(&addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    w.write_all(
        b"00001 StartSession()\r\n00002 Home()\r\n00003 ChangeTool(\"Probe1\")\r\n00004 GoTo(X(0), Y(0), Z(50))\r\n\
          00005 ScanInPlaneEndIsSphere(0, 0, 0, 0, 0, 1, 10, 0, 0, 0.5, 40, 0, 0, 2, 0, 0, 1)\r\n00006 EndSession()\r\n",
    )
    .unwrap();
    let mut lines = Vec::new();
    while lines.last().is_none_or(|l: &String| l != "00006 %") {
        let mut l = String::new();
        assert!(r.read_line(&mut l).unwrap() > 0, "{lines:?}");
        lines.push(l.trim_end().to_string());
    }
    drop((w, r));
    // X, Y, Z, Q per point (the default OnScanReport): 0 to 40 mm in 0.5 mm steps.
    let values: Vec<f64> = lines
        .iter()
        .filter_map(|l| l.strip_prefix("00005 # "))
        .flat_map(|d| d.split(',').map(|v| v.trim().parse::<f64>().unwrap()).collect::<Vec<_>>())
        .collect();
    assert_eq!(values.len(), 81 * 4, "{lines:?}");
    for p in values.chunks(4) {
        // The realistic machine's geometric map and noise: a few µm off the true Z = r, < 10 µm.
        assert!((p[2] - 1.5).abs() < 10e-3 && p[1].abs() < 10e-3, "{p:?}");
    }
    assert!((values[80 * 4] - 40.0).abs() < 10e-3, "end at X = {}", values[80 * 4]);
    unsafe_kill(child.id());
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        assert!(t0.elapsed() < Duration::from_secs(10), "no exit after SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    }
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(
        text.contains(
            "# 00005: unknown contour planned as a line on the plane face `table` (blended planner"
        ),
        "{text}"
    );
}

/// The operator's side: home the machine and pick the probe (both persist across sessions;
/// truepos itself never homes a machine).
fn home_with_probe1(addr: &str) {
    let s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    w.write_all(
        b"00001 StartSession()\r\n00002 Home()\r\n00003 ChangeTool(\"Probe1\")\r\n00004 EndSession()\r\n",
    )
    .unwrap();
    let mut last = String::new();
    while last.trim_end() != "00004 %" {
        last.clear();
        assert!(r.read_line(&mut last).unwrap() > 0);
    }
}

/// A machine file with every error model off: the virtual CMM then answers exactly.
fn ideal_machine(dir: &std::path::Path) -> std::path::PathBuf {
    let machine = dir.join("cmm.toml");
    std::fs::write(
        &machine,
        "[ippdme.model]\ngeometric_errors = \"none\"\npretravel_um = 0\nlobing_um = 0\nprobe_noise_um = 0\n",
    )
    .unwrap();
    machine
}

fn unsafe_kill(pid: u32) {
    let st = Command::new("kill").args(["-TERM", &pid.to_string()]).status().unwrap();
    assert!(st.success());
}

#[test]
fn bad_part_file_is_exit_2_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [0, 0, 0]\ndiameter_mm = 20\nradius = 3\n").unwrap();
    let out = truepos().args(["ippdme", "serve", "--port", "0", "--part"]).arg(&part).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("part.toml:4:"), "{err}");
}

#[test]
fn bad_machine_model_is_exit_2_naming_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let machine = dir.path().join("cmm.toml");
    std::fs::write(&machine, "[ippdme.model]\nseed = 3\nprobe_noize_um = 0.2\n").unwrap();
    let out = truepos().args(["ippdme", "serve", "--port", "0", "--machine"]).arg(&machine).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cmm.toml:3:") && err.contains("probe_noize_um"), "{err}");
    std::fs::write(&machine, "[ippdme.model]\npretravel_um = -4\n").unwrap();
    let out = truepos().args(["ippdme", "serve", "--port", "0", "--machine"]).arg(&machine).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("ippdme.model.pretravel_um"), "{err}");
}

#[test]
fn port_in_use_is_exit_3() {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = l.local_addr().unwrap().port().to_string();
    let out = truepos().args(["ippdme", "serve", "--port", &port]).output().unwrap();
    assert_eq!(out.status.code(), Some(3), "{}", String::from_utf8_lossy(&out.stderr));
}

/// `probe sphere --controller ippdme://…` against our own server: the client opens the session,
/// probes the upper hemisphere with PtMeas and fits; the part file's sphere is the truth.
#[test]
fn probe_sphere_through_ippdme_finds_the_part_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    // Truth: centre (10, -5, 20), Ø25 mm; the probe's ball is Probe1's 3 mm.
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [10, -5, 20]\ndiameter_mm = 25\n").unwrap();
    let (mut child, addr) = spawn_server(&part, &[]);
    home_with_probe1(&addr);
    let out = truepos()
        .args(["probe", "sphere", "--controller", &format!("ippdme://{addr}")])
        .args([
            "--near=10.2,-5.1,20.1",
            "--diameter-mm",
            "25",
            "--tip-diameter-mm",
            "3",
            "--points",
            "12",
            "--json",
        ])
        .output()
        .unwrap();
    unsafe_kill(child.id());
    let _ = child.wait();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let c: Vec<f64> = j["center_mm"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let r = j["radius_mm"].as_f64().unwrap();
    // The default virtual CMM is a realistic one (geometric errors of a few µm, compensated
    // pre-travel with 0.5 µm lobing, 0.25 µm touch noise): the fit of 12 points agrees with the
    // part file within 5 µm (a bridge CMM's MPE class), and is not exact.
    let e = ((c[0] - 10.0).powi(2) + (c[1] + 5.0).powi(2) + (c[2] - 20.0).powi(2)).sqrt();
    eprintln!(
        "probe sphere through ippdme://, realistic CMM: centre error {:.3} µm, radius error {:+.3} µm",
        e * 1e3,
        (r - 12.5) * 1e3
    );
    assert!(e < 5e-3, "centre {c:?}");
    assert!((r - 12.5).abs() < 5e-3, "radius {r}");
    assert!(e > 1e-6 || (r - 12.5).abs() > 1e-6, "an exact answer from a machine with error models");
    assert_eq!(j["n_points"].as_u64(), Some(12));
}

/// Head-offset acquisition on a CMM through `ippdme://`: the rotary table turns the sphere (C =
/// 0, 90, 180, 270° through `AlignPart`), the points file calibrates. The CMM reports tip
/// centres, so the true offset is zero; a table turning about Z determines its X and Y and not
/// its Z, which head-offset must refuse to report as a number.
#[test]
fn head_offset_acquisition_through_ippdme_turns_the_rotary_table() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [200, 0, 50]\ndiameter_mm = 25\n").unwrap();
    let machine = ideal_machine(dir.path());
    let (mut child, addr) = spawn_server(&part, &["--machine".as_ref(), machine.as_os_str()]);
    home_with_probe1(&addr);
    let points = dir.path().join("points.csv");
    let url = format!("ippdme://{addr}");
    let mut args =
        vec!["head-offset", "acquire", "--controller", &url, "--near=200,0,50", "--diameter-mm", "25"];
    args.extend(["--tip-diameter-mm", "3", "--table-center-mm", "0,0,0", "--points", "8", "--json"]);
    for c in ["0,0", "0,90", "0,180", "0,270"] {
        args.extend(["--orientation", c]);
    }
    args.push("--output");
    let out = truepos().args(&args).arg(&points).output().unwrap();
    let _ = child.kill();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let cal = truepos()
        .args(["head-offset", "--table-center-mm", "0,0,0", "--tip-radius-mm", "1.5", "--json", "--points"])
        .arg(&points)
        .output()
        .unwrap();
    assert_eq!(cal.status.code(), Some(0), "{}", String::from_utf8_lossy(&cal.stderr));
    let j: serde_json::Value = serde_json::from_slice(&cal.stdout).unwrap();
    eprintln!(
        "head offset through ippdme: {} ± {} mm, observable {}",
        j["offset_mm"], j["uncertainty_mm"], j["observable"]
    );
    let observable: Vec<bool> =
        j["observable"].as_array().unwrap().iter().map(|v| v.as_bool().unwrap()).collect();
    assert_eq!(observable, [true, true, false], "{j}");
    // The ideal CMM latches exactly (to its 1e-6 mm report resolution and the 1 nm contact
    // search): the X and Y offset are zero to well under 0.1 µm.
    for k in 0..2 {
        let v = j["offset_mm"][k].as_f64().unwrap();
        assert!(v.abs() < 1e-4, "offset[{k}] = {v} mm: {j}");
    }
}

/// `latency probe` over `ippdme://`: the virtual CMM latches the contact itself (its reports carry
/// no delay, whatever the PtMeas speed), so the feeds method must find zero within three of its
/// standard uncertainties (plus 5 µs), on the realistic machine with its touch noise and errors.
#[test]
fn latency_probe_through_ippdme_finds_no_delay_on_a_cmm_that_latches_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [10, -5, 20]\ndiameter_mm = 25\n").unwrap();
    let (mut child, addr) = spawn_server(&part, &[]);
    home_with_probe1(&addr);
    let out = truepos()
        .args(["latency", "probe", "--controller", &format!("ippdme://{addr}"), "--near=10,-5,20"])
        .args(["--diameter-mm", "25", "--tip-diameter-mm", "3", "--feeds-mm-min", "60,240,960", "--json"])
        .output()
        .unwrap();
    let _ = child.kill();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let (d, u) = (j["delay_s"].as_f64().unwrap(), j["uncertainty_s"].as_f64().unwrap());
    eprintln!("latency probe through ippdme (realistic CMM): {:.2} µs ± {:.2} µs", d * 1e6, u * 1e6);
    assert!(u > 0.0 && d.abs() < 3.0 * u + 5e-6, "delay {d} s ± {u}: {j}");
}
