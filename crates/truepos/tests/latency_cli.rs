//! `truepos latency`, `latency apply` and `simulate latency` through the command line: results
//! against the virtual cell's truth.json, and bad input → exit 2 with file and line.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run truepos")
}

fn simulate(dir: &Path, variant: &str, extra: &[&str]) -> serde_json::Value {
    let out = dir.to_str().unwrap();
    let mut args = vec!["simulate", "latency", "--out", out, "--seed", "3", "--variant", variant];
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(o.status.success(), "simulate failed: {}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&std::fs::read(dir.join("truth.json")).unwrap()).unwrap()
}

/// The data set's two stream files, with the `#` comment lines `simulate` writes taken out so
/// that the tests below can edit rows by line number (header = line 1). Reading the commented
/// files is tested in `simulate_cli.rs`.
fn files(dir: &Path) -> (String, String) {
    let strip = |name: &str| {
        let path = dir.join(name);
        let text = std::fs::read_to_string(&path).unwrap();
        let kept: String = text.lines().filter(|l| !l.starts_with('#')).map(|l| format!("{l}\n")).collect();
        std::fs::write(&path, kept).unwrap();
        path.to_str().unwrap().to_string()
    };
    (strip("machine.csv"), strip("probe.csv"))
}

fn json_of(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "exit {:?}: {}", o.status.code(), String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("one JSON object on stdout")
}

#[test]
fn sphere_artefact_from_files_matches_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = simulate(tmp.path(), "sphere", &["--repeats", "48", "--delay-s", "-0.002"]);
    let (m, p) = files(tmp.path());
    let d = truth["artefact"]["diameter_mm"].as_f64().unwrap().to_string();
    let r = truth["tip_radius_mm"].as_f64().unwrap().to_string();
    let j = json_of(&run(&[
        "latency",
        "--machine",
        &m,
        "--probe",
        &p,
        "--sphere-diameter-mm",
        &d,
        "--tip-radius-mm",
        &r,
        "--json",
    ]));
    assert_eq!(j["method"], "artefact");
    // 240 touches; a touch may be left out (with a warning) when its retract is too short.
    assert!(j["n_contacts"].as_u64().unwrap() >= 235, "{}", j["n_contacts"]);
    let got = j["delay_s"].as_f64().unwrap();
    let u = j["uncertainty_s"].as_f64().unwrap();
    let want = truth["delay_s"].as_f64().unwrap();
    assert!((want + 0.002).abs() < 1e-12);
    // Contract: within 10 µs and within 3 stated standard uncertainties.
    assert!((got - want).abs() < 10e-6 && (got - want).abs() < 3.0 * u, "{got} vs {want} (u {u})");
    assert!(j["rms_mm"].as_f64().unwrap() < 0.01);
}

#[test]
fn speeds_report_per_speed_and_static_size() {
    let tmp = tempfile::tempdir().unwrap();
    // 2 kHz streams: at 1 kHz the 40 mm/s contacts are under-sampled (see virtual_cell.rs).
    let truth = simulate(
        tmp.path(),
        "speeds",
        &["--repeats", "32", "--machine-rate-hz", "2000", "--probe-rate-hz", "2000"],
    );
    let (m, p) = files(tmp.path());
    let j = json_of(&run(&["latency", "--machine", &m, "--probe", &p, "--tip-radius-mm", "2", "--json"]));
    assert_eq!(j["method"], "speeds");
    let want = truth["delay_s"].as_f64().unwrap();
    let got = j["delay_s"].as_f64().unwrap();
    let u = j["uncertainty_s"].as_f64().unwrap();
    assert!((got - want).abs() < 10e-6 && (got - want).abs() < 3.0 * u, "{got} vs {want} (u {u})");
    let ps = j["per_speed"].as_array().unwrap();
    assert!(ps.len() >= 4);
    assert!(ps[0]["speed_mm_s"].as_f64().unwrap() > 0.0 && ps[0]["size_mm"].as_f64().unwrap() > 24.0);
    // Static size: the 25 mm sphere within a few µm (intercept u ≈ 1 µm).
    assert!((j["static_size_mm"].as_f64().unwrap() - 25.0).abs() < 5e-3);
}

#[test]
fn apply_puts_stylus_centres_on_the_sphere() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = simulate(tmp.path(), "sphere", &["--repeats", "1"]);
    let (m, p) = files(tmp.path());
    let out = tmp.path().join("centres.csv");
    let delay = truth["delay_s"].as_f64().unwrap().to_string();
    let apply = |out: &std::path::Path| {
        let args = ["latency", "apply", "--delay-s", &delay, "--machine", &m, "--probe", &p, "--output"];
        let o = run(&[&args[..], &[out.to_str().unwrap()]].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    apply(&out);
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    assert_eq!(lines.next().unwrap(), "t_s,x_mm,y_mm,z_mm");
    let c = &truth["artefact"]["centre_mm"];
    let c = [c[0].as_f64().unwrap(), c[1].as_f64().unwrap(), c[2].as_f64().unwrap()];
    let rc = truth["stylus_centre_size_mm"].as_f64().unwrap() / 2.0;
    // Compare only samples in firm contact: deflection over 50 µm.
    let probe = std::fs::read_to_string(&p).unwrap();
    let ns = |t: &str| (t.parse::<f64>().unwrap() * 1e9).round() as i64;
    let defl: std::collections::HashMap<i64, f64> = probe
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v: Vec<f64> = f[1..4].iter().map(|s| s.parse().unwrap()).collect();
            // Keyed by the time in ns: the files write times with different numbers of digits.
            (ns(f[0]), (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        })
        .collect();
    let mut n = 0;
    for l in lines {
        let f: Vec<f64> = l.split(',').map(|s| s.parse().unwrap()).collect();
        let key = ns(l.split(',').next().unwrap());
        if defl.get(&key).copied().unwrap_or(0.0) > 0.05 {
            let r = ((f[1] - c[0]).powi(2) + (f[2] - c[1]).powi(2) + (f[3] - c[2]).powi(2)).sqrt();
            // Encoder 1 µm + probe 0.3 µm noise, stylus dynamics: within 6 µm of the surface.
            assert!((r - rc).abs() < 6e-3, "stylus centre {r} vs {rc} at t = {}", f[0]);
            n += 1;
        }
    }
    assert!(n > 50, "{n} points in contact");
    // The same as Parquet (by the extension): the same doubles as the CSV's shortest text.
    let pq = tmp.path().join("centres.parquet");
    apply(&pq);
    let cols = truepos_io::parquet_file::read_columns(&pq).unwrap();
    let csv = truepos_io::csv::Table::read(&out).unwrap();
    assert_eq!(cols.names, csv.header);
    for name in ["t_s", "x_mm", "y_mm", "z_mm"] {
        assert_eq!(cols.f64(&pq, name).unwrap(), csv.f64_column(name).unwrap(), "{name}");
    }
}

#[test]
fn residual_of_already_corrected_data() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = simulate(tmp.path(), "inout", &["--repeats", "48"]);
    let (m, p) = files(tmp.path());
    // Correct the machine stamps by D0 = 2 ms: t ← t − D0.
    let d0 = 0.002;
    let text = std::fs::read_to_string(&m).unwrap();
    let mut fixed = String::new();
    for (i, l) in text.lines().enumerate() {
        if i == 0 {
            fixed.push_str(l);
        } else {
            let (t, rest) = l.split_once(',').unwrap();
            fixed.push_str(&format!("{},{}", t.parse::<f64>().unwrap() - d0, rest));
        }
        fixed.push('\n');
    }
    let m2 = tmp.path().join("machine_corrected.csv");
    std::fs::write(&m2, fixed).unwrap();
    let j = json_of(&run(&[
        "latency",
        "--machine",
        m2.to_str().unwrap(),
        "--probe",
        &p,
        "--already-corrected-s",
        "0.002",
        "--json",
    ]));
    let want = truth["delay_s"].as_f64().unwrap();
    let u = j["uncertainty_s"].as_f64().unwrap();
    let res = j["residual_delay_s"].as_f64().unwrap();
    assert!((res - (want - d0)).abs() < 10e-6 && (res - (want - d0)).abs() < 3.0 * u, "{res}");
    assert!((j["delay_s"].as_f64().unwrap() - want).abs() < 10e-6);
}

fn expect_exit2(o: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    for n in needles {
        assert!(err.contains(n), "'{n}' not in: {err}");
    }
    assert!(o.stdout.is_empty(), "nothing on stdout on error");
}

#[test]
fn bad_input_exits_2_with_file_and_line() {
    let tmp = tempfile::tempdir().unwrap();
    simulate(tmp.path(), "sphere", &["--repeats", "1"]);
    let (m, p) = files(tmp.path());
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    // Unsorted machine stamps: rows 2 and 3 swapped → line 4 of the file (header is line 1).
    let text = std::fs::read_to_string(&m).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines.swap(2, 3);
    let unsorted = write(tmp.path(), "unsorted.csv", &(lines.join("\n") + "\n"));
    expect_exit2(
        &run(&["latency", "--machine", &s(&unsorted), "--probe", &p]),
        &["unsorted.csv:4", "increase"],
    );
    // Duplicate probe stamp on line 6.
    let text = std::fs::read_to_string(&p).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let t4 = lines[4].split(',').next().unwrap().to_string();
    let rest = lines[5].split_once(',').unwrap().1.to_string();
    lines[5] = format!("{t4},{rest}");
    let dup = write(tmp.path(), "dup.csv", &(lines.join("\n") + "\n"));
    expect_exit2(&run(&["latency", "--machine", &m, "--probe", &s(&dup)]), &["dup.csv:6", "duplicate"]);
    // Streams that do not overlap in time.
    let far = write(tmp.path(), "far.csv", "t_s,x_mm,y_mm,z_mm\n1000,0,0,0\n1001,0,0,0\n");
    expect_exit2(&run(&["latency", "--machine", &s(&far), "--probe", &p]), &["do not overlap"]);
    // No contact above the threshold.
    expect_exit2(&run(&["latency", "--machine", &m, "--probe", &p, "--threshold-mm", "5"]), &["no contact"]);
    // One speed with --method speeds.
    expect_exit2(&run(&["latency", "--machine", &m, "--probe", &p, "--method", "speeds"]), &["one speed"]);
    // A value that is not a number: file, line and column.
    let bad = write(tmp.path(), "bad.csv", "t_s,a_mm,b_mm,c_mm\n0,0,0,0\n0.001,x,0,0\n");
    expect_exit2(&run(&["latency", "--machine", &m, "--probe", &s(&bad)]), &["bad.csv:3"]);
    // Apply: no partial output on bad input.
    let out = tmp.path().join("out.csv");
    expect_exit2(
        &run(&[
            "latency",
            "apply",
            "--delay-s",
            "0.001",
            "--machine",
            &s(&unsorted),
            "--probe",
            &p,
            "--output",
            &s(&out),
        ]),
        &["unsorted.csv:4"],
    );
    assert!(!out.exists());
    // Missing files option.
    expect_exit2(&run(&["latency", "--machine", &m]), &["--probe"]);
}

#[test]
fn scan_variant_via_auto() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = simulate(tmp.path(), "scan", &["--repeats", "6"]);
    let (m, p) = files(tmp.path());
    let j = json_of(&run(&["latency", "--machine", &m, "--probe", &p, "--json"]));
    assert_eq!(j["method"], "scan");
    let want = truth["delay_s"].as_f64().unwrap();
    let got = j["delay_s"].as_f64().unwrap();
    let u = j["uncertainty_s"].as_f64().unwrap();
    // Contract: the scan method within 20 µs and 3 u.
    assert!((got - want).abs() < 20e-6 && (got - want).abs() < 3.0 * u, "{got} vs {want} (u {u})");
    assert!(j["scan_rms_after_mm"].as_f64().unwrap() < j["scan_rms_before_mm"].as_f64().unwrap());
}

/// Known weakness: on 1 kHz streams the scan method's error depends on the fractional part of
/// the delay in machine samples (seed 3: 0 µs at 3.0 ms, −27 µs at 3.1 ms, −12 µs at 3.5 ms),
/// beyond the stated uncertainty (6 µs). Not yet explained.
#[test]
#[ignore]
fn scan_fractional_sample_delay() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = simulate(tmp.path(), "scan", &["--repeats", "6", "--delay-s", "0.0031"]);
    let (m, p) = files(tmp.path());
    let j = json_of(&run(&["latency", "--machine", &m, "--probe", &p, "--json"]));
    assert_eq!(j["method"], "scan");
    let want = truth["delay_s"].as_f64().unwrap();
    let got = j["delay_s"].as_f64().unwrap();
    let u = j["uncertainty_s"].as_f64().unwrap();
    // Contract: the scan method within 20 µs and 3 u.
    assert!((got - want).abs() < 20e-6 && (got - want).abs() < 3.0 * u, "{got} vs {want} (u {u})");
    assert!(j["scan_rms_after_mm"].as_f64().unwrap() < j["scan_rms_before_mm"].as_f64().unwrap());
}

/// A size given for the artefact while the tip radius is left at 0 (sizes then mean the
/// stylus-centre surface) yields an absurd delay: the result carries a warning naming the cause.
#[test]
fn implausible_delay_is_flagged() {
    let tmp = tempfile::tempdir().unwrap();
    simulate(tmp.path(), "sphere", &[]);
    let (m, p) = files(tmp.path());
    let o = run(&["latency", "--machine", &m, "--probe", &p, "--sphere-diameter-mm", "25", "--json"]);
    let v = json_of(&o);
    let w = v["warnings"].to_string();
    assert!(w.contains("implausible") && w.contains("--tip-radius-mm"), "{w}");
    // With the tip radius the same data give the true 2.5 ms and no such warning.
    let o = run(&[
        "latency",
        "--machine",
        &m,
        "--probe",
        &p,
        "--sphere-diameter-mm",
        "25",
        "--tip-radius-mm",
        "2",
        "--json",
    ]);
    let v = json_of(&o);
    assert!(!v["warnings"].to_string().contains("implausible"));
    assert!((v["delay_s"].as_f64().unwrap() - 0.0025).abs() < 0.0001, "{v}");
}

/// `latency probe` on the virtual machine tool: it latches at the first 1 ms servo sample after
/// the trigger, at a random phase, so its true mean delay is 0.5 ms. The sphere probed at four
/// feeds gives the delay as minus the slope of radius against feed; the estimate must agree with
/// 0.5 ms within three of its own standard uncertainties (plus 20 µs for the finite sample of
/// phases), and its uncertainty must be a real one (neither zero nor larger than the delay).
#[test]
fn latency_probe_finds_the_virtual_latch_delay() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_truepos"))
        .args(["latency", "probe", "--near=120,45,30", "--diameter-mm", "25", "--tip-diameter-mm", "3"])
        .args(["--feeds-mm-min", "60,240,960,1920", "--points", "50", "--json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let (d, u) = (j["delay_s"].as_f64().unwrap(), j["uncertainty_s"].as_f64().unwrap());
    let truth = j["virtual_truth_delay_s"].as_f64().unwrap();
    assert_eq!(truth, 0.0005);
    assert!(u > 1e-6 && u < truth, "u = {u} s: {j}");
    assert!((d - truth).abs() < 3.0 * u + 20e-6, "delay {d} s ± {u} against {truth} s: {j}");
    // One feed cannot give a slope: refused before any motion.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_truepos"))
        .args(["latency", "probe", "--near=120,45,30", "--diameter-mm", "25", "--feeds-mm-min", "60"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
}
