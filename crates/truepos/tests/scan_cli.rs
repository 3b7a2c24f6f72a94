//! `truepos scan` and `truepos simulate scan` through the command line.

use std::path::Path;
use std::process::Command;

fn truepos(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_truepos")).args(args).output().expect("runs")
}

fn json(out: &std::process::Output) -> serde_json::Value {
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("one JSON object on stdout")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn simulate_plan_and_run_both_styles() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = truepos(&["simulate", "scan", "--out", s(&d.join("sc")), "--seed", "3", "--features", "5"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let features = d.join("sc/features.toml");
    let truth = d.join("sc/truth.json");
    let t: serde_json::Value = serde_json::from_slice(&std::fs::read(&truth).unwrap()).unwrap();
    assert_eq!(t["features"].as_array().unwrap().len(), 5);
    // the fifth feature is displaced by 1.2–1.8 mm (scenario definition)
    assert!(t["features"][4]["normal_offset_mm"].as_f64().unwrap().abs() > 1.19);

    let path = d.join("path.csv");
    let p = json(&truepos(&["scan", "plan", "--features", s(&features), "--output", s(&path), "--json"]));
    assert_eq!(p["stops"], 0);
    let text = std::fs::read_to_string(&path).unwrap();
    let header = text.lines().find(|l| !l.starts_with('#')).unwrap();
    assert!(header.starts_with("t_s,x_mm,y_mm,z_mm,segment,feature"));
    for seg in ["transfer", "approach", "settle", "scan", "release"] {
        assert!(text.contains(&format!(",{seg},")), "no {seg} rows");
    }

    let pts_b = d.join("b.csv");
    let pts_c = d.join("c.csv");
    let part = s(&truth);
    let b = json(&truepos(&[
        "scan",
        "run",
        "--features",
        s(&features),
        "--part",
        part,
        "--output",
        s(&pts_b),
        "--json",
    ]));
    let c = json(&truepos(&[
        "scan",
        "run",
        "--features",
        s(&features),
        "--part",
        part,
        "--output",
        s(&pts_c),
        "--style",
        "classic",
        "--json",
    ]));
    assert_eq!(b["stops"], 0);
    assert_eq!(c["stops"], 20, "classic: four stops per feature");
    let (tb, tc) = (b["cycle_time_s"].as_f64().unwrap(), c["cycle_time_s"].as_f64().unwrap());
    assert!(tb < 0.7 * tc, "blended {tb} s vs classic {tc} s");
    for r in [&b, &c] {
        let fs = r["features"].as_array().unwrap();
        assert_eq!(fs.len(), 5);
        for f in fs {
            // perfect true geometry: the form error is noise and dynamics, a few µm at most
            let fe = f["form_error_mm"].as_f64().unwrap();
            assert!(fe > 0.0 && fe < 0.004, "{f}");
            assert!(f["time_s"].as_f64().unwrap() > 0.0);
        }
    }
    // the displaced feature's path was shifted by its true offset (within 0.1 mm)
    let off = t["features"][4]["normal_offset_mm"].as_f64().unwrap();
    let shift = b["features"][4]["contact_shift_mm"].as_f64().unwrap();
    assert!((shift - off).abs() < 0.1, "shift {shift} offset {off}");
    let pts = std::fs::read_to_string(&pts_b).unwrap();
    let header = pts.lines().find(|l| !l.starts_with('#')).unwrap();
    assert!(header.starts_with("t_s,x_mm,y_mm,z_mm,segment,feature,deflection_mm,quality"));
    let scan_rows: Vec<&str> = pts.lines().filter(|l| l.contains(",scan,")).collect();
    assert!(scan_rows.len() > 1000);
    assert!(scan_rows.iter().all(|l| [",0,", ",5,", ",9,"].iter().any(|q| l.contains(q))));
}

const GOOD: &str = r#"
scan_speed_mm_s = 30
[[feature]]
id = "b1"
kind = "circle"
center_mm = [0, 0, -5]
axis = [0, 0, 1]
radius_mm = 10
side = "inside"
start_deg = 0
sweep_deg = 360

[[feature]]
id = "l1"
kind = "line"
start_mm = [30, 0, 0]
end_mm = [60, 0, 0]
normal = [0, 0, 1]
"#;

fn expect_usage_error(d: &Path, name: &str, toml: &str, extra: &[&str], needles: &[&str]) {
    let f = d.join(format!("{name}.toml"));
    std::fs::write(&f, toml).unwrap();
    let out_path = d.join(format!("{name}.csv"));
    let mut args = vec!["scan", "plan", "--features", s(&f), "--output", s(&out_path)];
    args.extend_from_slice(extra);
    let out = truepos(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{name}: {err}");
    for n in needles {
        assert!(err.contains(n), "{name}: '{n}' not in: {err}");
    }
    assert!(!out_path.exists(), "{name}: output written despite bad input");
}

#[test]
fn bad_input_exits_2_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // the good file plans
    let f = d.join("good.toml");
    std::fs::write(&f, GOOD).unwrap();
    let out = truepos(&["scan", "plan", "--features", s(&f), "--output", s(&d.join("good.csv"))]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    expect_usage_error(
        d,
        "angle_cli_high",
        GOOD,
        &["--approach-angle-deg", "61"],
        &["approach_angle_deg", "20 and 60"],
    );
    expect_usage_error(d, "angle_cli_low", GOOD, &["--approach-angle-deg", "19.5"], &["approach_angle_deg"]);
    expect_usage_error(
        d,
        "angle_file",
        &format!("approach_angle_deg = 70\n{GOOD}"),
        &[],
        &["approach_angle_deg", "70"],
    );
    expect_usage_error(
        d,
        "zero_line",
        &GOOD.replace("end_mm = [60, 0, 0]", "end_mm = [30, 0, 0]"),
        &[],
        &["zero_line.toml", "l1", "length"],
    );
    expect_usage_error(
        d,
        "zero_radius",
        &GOOD.replace("radius_mm = 10", "radius_mm = 0"),
        &[],
        &["zero_radius.toml", "b1", "radius"],
    );
    expect_usage_error(
        d,
        "axis",
        &GOOD.replace("axis = [0, 0, 1]", "axis = [0, 0.6, 0.9]"),
        &[],
        &["axis.toml", "b1", "unit vector"],
    );
    expect_usage_error(d, "side", &GOOD.replace("side = \"inside\"", "side = \"up\""), &[], &["b1", "side"]);
    expect_usage_error(
        d,
        "syntax",
        &GOOD.replace("radius_mm = 10", "radius_mm = ten"),
        &[],
        &["syntax.toml"],
    );
    expect_usage_error(d, "bands", GOOD, &["--quality-bands-mm", "0.05,0.02"], &["quality_bands_mm"]);
    // the message names the line of the feature
    let f = d.join("line_no.toml");
    std::fs::write(&f, GOOD.replace("radius_mm = 10", "radius_mm = -1")).unwrap();
    let out = truepos(&["scan", "plan", "--features", s(&f), "--output", s(&d.join("x.csv"))]);
    let err = String::from_utf8_lossy(&out.stderr);
    let line = GOOD.lines().position(|l| l.contains("id = \"b1\"")).unwrap() + 1;
    assert!(err.contains(&format!("{line}")), "{err}");
}

#[test]
fn machine_file_is_read_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let f = d.join("f.toml");
    std::fs::write(&f, GOOD).unwrap();
    let m = d.join("cmm.toml");
    std::fs::write(&m, "probe_noise_um = 0.1\n[servo]\nbandwidth_hz = 25\n[stylus]\nfriction = 0.1\nnatural_freq_hz = [120, 120, 180]\n").unwrap();
    let out = d.join("p.csv");
    let r = json(&truepos(&[
        "scan",
        "run",
        "--features",
        s(&f),
        "--machine",
        s(&m),
        "--output",
        s(&out),
        "--json",
    ]));
    assert_eq!(r["stops"], 0);
    assert_eq!(r["features"].as_array().unwrap().len(), 2);
    // an unknown key and an impossible value are input errors (exit 2), naming the file
    for (name, text) in
        [("unknown", "[servo]\nbandwith_hz = 25\n"), ("negative", "[servo]\nbandwidth_hz = -3\n")]
    {
        let m = d.join(format!("{name}.toml"));
        std::fs::write(&m, text).unwrap();
        let o = d.join(format!("{name}.csv"));
        let out = truepos(&["scan", "run", "--features", s(&f), "--machine", s(&m), "--output", s(&o)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(&format!("{name}.toml")), "{err}");
        assert!(!o.exists());
    }
}

#[test]
fn a_scan_too_short_for_a_form_error_reports_null_not_a_number() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // a 0.1 mm line at 30 mm/s: 3 ms of scan, fewer points than a form evaluation needs
    let f = d.join("short.toml");
    std::fs::write(&f, GOOD.replace("end_mm = [60, 0, 0]", "end_mm = [30.1, 0, 0]")).unwrap();
    let r = json(&truepos(&["scan", "run", "--features", s(&f), "--output", s(&d.join("p.csv")), "--json"]));
    let l1 = &r["features"][1];
    assert!(l1["form_error_mm"].is_null(), "{l1}");
    assert!(l1["form_error_note"].as_str().unwrap().contains("too few"), "{l1}");
    assert!(r["features"][0]["form_error_mm"].as_f64().is_some());
}

/// `scan plan` and `scan run` write Parquet for a `.parquet` output: the CSV's columns, the
/// numbers bit for bit (the CSV's are shortest round-trip), `segment` and `feature` as text.
#[test]
fn plan_and_run_write_parquet_by_extension() {
    use truepos_io::parquet_file::{read_columns, ColumnData};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = truepos(&["simulate", "scan", "--out", s(&d.join("sc")), "--seed", "4", "--features", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let features = d.join("sc/features.toml");
    let truth = d.join("sc/truth.json");
    for (cmd, extra) in [("plan", vec![]), ("run", vec!["--part", s(&truth)])] {
        let csv = d.join(format!("{cmd}.csv"));
        let pq = d.join(format!("{cmd}.parquet"));
        for o in [&csv, &pq] {
            let mut args = vec!["scan", cmd, "--features", s(&features), "--output", s(o)];
            args.extend(extra.iter().copied());
            let out = truepos(&args);
            assert!(out.status.success(), "{cmd}: {}", String::from_utf8_lossy(&out.stderr));
        }
        let want = truepos_io::csv::Table::read(&csv).unwrap();
        let got = read_columns(&pq).unwrap();
        assert_eq!(got.names, want.header, "{cmd}");
        assert!(want.n_rows() > 100, "{cmd}: {} rows", want.n_rows());
        assert_eq!(got.n_rows(), want.n_rows(), "{cmd}");
        for (name, data) in got.names.iter().zip(&got.data) {
            match data {
                ColumnData::Str(v) => {
                    assert!(name == "segment" || name == "feature", "{cmd}: {name} is text");
                    assert!(*v == want.str_column(name).unwrap(), "{cmd}: {name} differs");
                }
                ColumnData::F64(v) => {
                    let a = want.f64_column(name).unwrap();
                    assert!(
                        a.iter().zip(v).all(|(a, b)| a.to_bits() == b.to_bits()),
                        "{cmd}: {name} differs"
                    );
                }
            }
        }
    }
}
