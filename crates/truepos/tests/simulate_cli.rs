//! `truepos simulate X` for a new user: every scenario prints the command to run next and its
//! key facts, every CSV and TOML it writes is commented (and still reads back), the default
//! latency data set meets the 10 µs goal through the printed command, `simulate comp` gives a
//! map the printed `comp correct` command uses to recover the truth, and a map without its Y or
//! Z table is refused by name.

mod common;

use common::{bin, expect_input_error};
use serde_json::Value;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Run `truepos simulate <args> --out dir`; return stderr.
fn simulate(dir: &Path, args: &[&str]) -> String {
    let o = bin().arg("simulate").args(args).args(["--out", s(dir)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "simulate {args:?}: {err}");
    assert!(o.stdout.is_empty(), "simulate writes nothing on stdout");
    err
}

/// The first printed `truepos …` command after `prefix` (e.g. "next: "), split into arguments.
fn printed_command(stderr: &str, prefix: &str) -> Vec<String> {
    let line = stderr
        .lines()
        .find_map(|l| l.strip_prefix(prefix))
        .unwrap_or_else(|| panic!("no '{prefix}' line in: {stderr}"));
    let mut words: Vec<String> = line.split_whitespace().map(String::from).collect();
    assert_eq!(words[0], "truepos", "{line}");
    words.remove(0);
    words
}

fn truth(dir: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(dir.join("truth.json")).unwrap()).unwrap()
}

/// Every CSV written starts with `#` comment lines; every TOML has a comment line.
fn assert_commented(dir: &Path) -> usize {
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
        let text = std::fs::read_to_string(&p).unwrap();
        match ext {
            "csv" => assert!(text.starts_with('#'), "{} has no comment lines", p.display()),
            "toml" => assert!(
                text.lines().any(|l| l.trim_start().starts_with('#')),
                "{} is not commented",
                p.display()
            ),
            _ => continue,
        }
        n += 1;
    }
    n
}

#[test]
fn default_latency_scenario_meets_the_10_us_goal_through_the_printed_command() {
    let d = tempfile::tempdir().unwrap();
    let err = simulate(d.path(), &["latency"]);
    // Key facts: the artefact and its size, the contacts.
    assert!(err.contains("sphere Ø 25 mm") && err.contains("120 contacts"), "{err}");
    assert_eq!(assert_commented(d.path()), 2);
    let mut cmd = printed_command(&err, "next: ");
    cmd.push("--json".into());
    let o = bin().args(&cmd).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    let want = truth(d.path())["delay_s"].as_f64().unwrap();
    let got = j["delay_s"].as_f64().unwrap();
    let u = j["uncertainty_s"].as_f64().unwrap();
    // The product goal (10 µs), and the stated U (k = 2) below it so the goal is met by design.
    assert!((got - want).abs() <= 10e-6, "delay {got} s vs true {want} s");
    assert!(2.0 * u < 10e-6, "U = {} µs", 2e6 * u);
}

#[test]
fn per_axis_output_explains_itself() {
    let d = tempfile::tempdir().unwrap();
    let err = simulate(d.path(), &["latency", "--variant", "per-axis", "--repeats", "4"]);
    let cmd = printed_command(&err, "next: ");
    assert!(cmd.iter().any(|w| w == "--per-axis"), "{cmd:?}");
    let o = bin().args(&cmd).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // X and Y differ by 1.5 ms in the simulator: said to differ, and the single delay not
    // read as an error; Z is touched from one side only: not determined.
    assert!(out.contains("the axes differ") && out.contains("not an error of the method"), "{out}");
    assert!(out.contains("delay Z       not determined"), "{out}");
}

#[test]
fn comp_scenario_round_trip_and_missing_tables() {
    let d = tempfile::tempdir().unwrap();
    let err = simulate(d.path(), &["comp"]);
    assert!(err.contains("400 points") && err.contains("201 x, 301 y and 161 z rows"), "{err}");
    assert_eq!(assert_commented(d.path()), 3);
    let cmd = printed_command(&err, "next: ");
    let o = bin().args(&cmd).arg("--json").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["uncertainty_method"], "map-propagation");
    assert_eq!(j["coverage_factor"], 2.0);
    let t = truth(d.path());
    let text = std::fs::read_to_string(d.path().join("corrected.csv")).unwrap();
    let mut rows = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (cx, cy, cz) = (col("x_mm"), col("y_mm"), col("z_mm"));
    let (ux, uy, uz) = (col("u_x_um"), col("u_y_um"), col("u_z_um"));
    let (mut worst, mut n, mut inside, mut big_u) = (0.0_f64, 0, 0, 0.0_f64);
    for (r, tp) in rows.zip(t["true_points_mm"].as_array().unwrap()) {
        let v: Vec<&str> = r.split(',').collect();
        let p: Vec<f64> = [cx, cy, cz].iter().map(|&c| v[c].parse().unwrap()).collect();
        let u: Vec<f64> = [ux, uy, uz].iter().map(|&c| v[c].parse().unwrap()).collect();
        for k in 0..3 {
            let e = (p[k] - tp[k].as_f64().unwrap()) * 1e3;
            worst = worst.max(e.abs());
            // The stated U (k = 2) of the corrected coordinate.
            inside += usize::from(e.abs() <= 2.0 * u[k]);
            big_u = big_u.max(2.0 * u[k]);
        }
        n += 1;
    }
    assert_eq!(n, 400);
    // The map carries its calibration's error: every corrected coordinate within 1 µm (the
    // demo's tolerance), and most within the printed ±U. One map's 400 points share its
    // calibration's systematic part, so they are not independent comparisons: the 90–99 % bar is
    // tested over 100 maps (crates/cell/tests/comp_coverage.rs).
    assert!(worst < 1.0, "worst corrected coordinate {worst} µm from the truth");
    let cov = inside as f64 / 1200.0;
    assert!(cov > 0.75, "coverage {cov}");
    assert!(
        (big_u
            - j["max_expanded_uncertainty_um"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .fold(0.0, f64::max))
        .abs()
            < 1e-3
    );
    assert!(t["uncorrected_max_error_um"].as_f64().unwrap() > 2.0);
    // Without its Y (or Z) table the map is refused, naming the table.
    let map = std::fs::read_to_string(d.path().join("map.csv")).unwrap();
    for axis in ["y", "z"] {
        let cut: String =
            map.lines().filter(|l| !l.starts_with(&format!("{axis},"))).map(|l| format!("{l}\n")).collect();
        let p = d.path().join(format!("map_no_{axis}.csv"));
        std::fs::write(&p, cut).unwrap();
        let o = bin()
            .args(["comp", "correct", "--map", s(&p), "--points", s(&d.path().join("points.csv"))])
            .args(["--output", s(&d.path().join("x.csv"))])
            .output()
            .unwrap();
        expect_input_error(&o, &[&format!("map_no_{axis}.csv"), &format!("the {axis} table is missing")]);
        assert!(!d.path().join("x.csv").exists());
    }
}

#[test]
fn every_scenario_prints_the_next_command_and_comments_its_files() {
    let cases: [(&[&str], &str); 4] = [
        (&["head-offset"], "calibrate with: "),
        (&["load"], "next: "),
        (&["scan", "--features", "3"], "scan with: "),
        (&["somac", "--holes-per-row", "2"], "next: "),
    ];
    for (args, prefix) in cases {
        let d = tempfile::tempdir().unwrap();
        let err = simulate(d.path(), args);
        let cmd = printed_command(&err, prefix);
        assert!(!cmd.is_empty());
        assert!(assert_commented(d.path()) >= 1, "{args:?}");
    }
}

/// `simulate somac` prints both figures without end-point control, and `somac run` with the
/// matching options reproduces them; the audit database is where --db says and is printed.
#[test]
fn somac_figures_agree_with_somac_run() {
    let d = tempfile::tempdir().unwrap();
    let err = simulate(d.path(), &["somac", "--holes-per-row", "2"]);
    assert!(err.contains("as written (native)") && err.contains("oriented on the part targets"), "{err}");
    let t = truth(d.path());
    let cell = std::fs::read_to_string(d.path().join("cell.toml")).unwrap();
    assert!(cell.contains("# air pressure (Pa)"), "{cell}");
    let db = d.path().join("audit.sqlite");
    for (flags, key) in [
        (&["--no-correct", "--no-orient"][..], "native_mean_error_mm"),
        (&["--no-correct"][..], "oriented_only_mean_error_mm"),
    ] {
        let o = bin()
            .args(["somac", "run", "--program", s(&d.path().join("program.nc")), "--cell"])
            .args([s(&d.path().join("cell.toml")), "--db", s(&db), "--json"])
            .args(flags)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(stderr.contains(&format!("audit trail appended to {}", db.display())), "{stderr}");
        let j: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {stderr}"));
        let (got, want) = (j["true_mean_error_mm"].as_f64().unwrap(), t[key].as_f64().unwrap());
        // The same cell, seed and program: the same run, to rounding.
        assert!((got - want).abs() < 1e-9, "{flags:?}: {got} vs {key} {want}");
    }
    assert!(db.exists());
}
