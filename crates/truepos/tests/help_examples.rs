//! Every example of every `--help` runs: the command tree is walked (`truepos __cli-tree`),
//! each command's `--help` is read as a user sees it, the lines of its `Example(s):` block are
//! taken verbatim and run, in one working directory, after the `truepos simulate …` examples
//! have written the data sets the others read, and with a few small files named as the
//! examples name them (points.csv, hole.csv, tracker.csv, …). An example must be one command
//! (no pipes, quotes or `&&`), printed unwrapped, and end with exit code 0 or 1 (1: a verdict
//! out of tolerance, a legitimate answer). `ippdme serve` runs until stopped: it is started on a
//! free port (`--port 0` for the example's 1294, which another program may hold) and stopped
//! with SIGTERM after it listens. `truepos demo --out demo` (every capability, 10–20 s) runs in
//! the `#[ignore]`d `demo_example_runs`; the always-on test runs every other example (≈ 25 s).

mod common;

use serde_json::Value;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

fn paths(cmd: &Value, prefix: &[String], out: &mut Vec<Vec<String>>) {
    out.push(prefix.to_vec());
    for s in cmd["subcommands"].as_array().into_iter().flatten() {
        if s["hidden"].as_bool().unwrap_or(false) {
            continue;
        }
        let mut p = prefix.to_vec();
        p.push(s["name"].as_str().unwrap().to_string());
        paths(s, &p, out);
    }
}

/// The example lines of `truepos <path> --help`.
fn help_examples(path: &[String]) -> Vec<String> {
    let out = common::bin().args(path).arg("--help").env("COLUMNS", "60").output().unwrap();
    assert!(out.status.success(), "{path:?} --help");
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines().skip_while(|l| *l != "Example:" && *l != "Examples:");
    lines.next();
    lines.take_while(|l| !l.trim().is_empty()).map(|l| l.trim().to_string()).collect()
}

fn write_points(dir: &Path, name: &str, rows: &[[f64; 3]], ids: bool) {
    let mut s = String::from(if ids { "id,x_mm,y_mm,z_mm\n" } else { "x_mm,y_mm,z_mm\n" });
    for (i, p) in rows.iter().enumerate() {
        if ids {
            s.push_str(&format!("T{},", i + 1));
        }
        s.push_str(&format!("{:.6},{:.6},{:.6}\n", p[0], p[1], p[2]));
    }
    std::fs::write(dir.join(name), s).unwrap();
}

/// The small files the examples name that no `simulate` writes.
fn fixtures(dir: &Path) {
    let tau = std::f64::consts::TAU;
    // A Ø 25 sphere's upper half, a Ø 20 hole (±1 µm lobing), a Ø 16 bore 20 deep.
    let sphere: Vec<[f64; 3]> = (0..40)
        .map(|i| {
            let (a, e) = (i as f64 * 0.7, 0.2 + 1.2 * (i % 7) as f64 / 7.0);
            [100.0 + 12.5 * e.cos() * a.cos(), 50.0 + 12.5 * e.cos() * a.sin(), 20.0 + 12.5 * e.sin()]
        })
        .collect();
    write_points(dir, "points.csv", &sphere, false);
    let hole: Vec<[f64; 3]> = (0..48)
        .map(|i| {
            let a = i as f64 * tau / 48.0;
            let r = 10.001 + 0.001 * (3.0 * a).sin();
            [3.0 + r * a.cos(), -2.0 + r * a.sin(), 5.0]
        })
        .collect();
    write_points(dir, "hole.csv", &hole, false);
    let mut ds = String::from("60\n");
    for i in 0..60 {
        let a = i as f64 * tau / 12.0;
        let r = 8.0 + 0.0005 * (2.0 * a).cos();
        ds.push_str(&format!("{:.6}\t{:.6}\t{:.6}\n", r * a.cos(), r * a.sin(), -4.0 * (i / 12) as f64));
    }
    std::fs::write(dir.join("bore.ds"), ds).unwrap();
    // Matched point sets: a rotation of 0.01 rad about Z and a shift (align), a 40 ppm scale
    // (autoscale, a part 4.1 °C warm with 23.6 ppm/°C would be 96.8 ppm), targets moved 0.3 mm.
    let base = [
        [0.0, 0.0, 0.0],
        [1000.0, 0.0, 0.0],
        [1000.0, 800.0, 10.0],
        [0.0, 800.0, 5.0],
        [500.0, 400.0, 300.0],
    ];
    let (c, s) = (0.01f64.cos(), 0.01f64.sin());
    let moved: Vec<[f64; 3]> =
        base.iter().map(|p| [c * p[0] - s * p[1] + 12.0, s * p[0] + c * p[1] - 3.0, p[2] + 1.5]).collect();
    write_points(dir, "tracker.csv", &base, true);
    write_points(dir, "machine.csv", &moved, true);
    write_points(dir, "balls_20C.csv", &base, true);
    let scaled: Vec<[f64; 3]> = base.iter().map(|p| p.map(|v| v * (1.0 + 96.8e-6))).collect();
    write_points(dir, "balls_now.csv", &scaled, true);
    write_points(dir, "targets_nominal.csv", &base, true);
    let shifted: Vec<[f64; 3]> = base.iter().map(|p| [p[0] + 0.3, p[1] - 0.2, p[2] + 0.1]).collect();
    write_points(dir, "targets_now.csv", &shifted, true);
    // The NIST DMIS example and the part modelled for it (the repository's data).
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/dmis");
    for f in ["simple_in.dms", "simple_part.toml"] {
        std::fs::copy(data.join(f), dir.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
    }
}

/// Examples shown in `--help` but not run here, with the reason: they need a state this test
/// cannot make (each is run by its own command's tests).
const SHOWN_NOT_RUN: &[(&str, &str)] = &[(
    "truepos audit push ",
    "needs a spool left by a run whose database went away (crates/truepos/tests/audit_cli.rs makes one)",
)];

/// Run one example in `dir`; `Err` with what went wrong.
fn run(dir: &Path, example: &str) -> Result<Duration, String> {
    let words: Vec<&str> = example.split_whitespace().collect();
    if words.first() != Some(&"truepos") {
        return Err("does not start with `truepos`".into());
    }
    if example.contains(['|', '&', ';', '#', '\'', '"', '\\', '>', '<']) {
        return Err("is not one plain command (pipe, quote, comment or continuation)".into());
    }
    let t0 = Instant::now();
    if words.get(1..3) == Some(&["ippdme", "serve"]) {
        let args: Vec<&str> = words[1..].iter().map(|w| if *w == "1294" { "0" } else { w }).collect();
        let mut child = common::bin().args(&args).current_dir(dir).stderr(Stdio::piped()).spawn().unwrap();
        let mut err = child.stderr.take().unwrap();
        let mut seen = String::new();
        let mut buf = [0u8; 256];
        while !seen.contains("listening") {
            use std::io::Read;
            match err.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => seen.push_str(&String::from_utf8_lossy(&buf[..n])),
            }
        }
        let _ = std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
        let status = child.wait().unwrap();
        return if seen.contains("listening") && status.code() == Some(0) {
            Ok(t0.elapsed())
        } else {
            Err(format!("exit {:?}; stderr: {seen}", status.code()))
        };
    }
    let out = common::bin().args(&words[1..]).current_dir(dir).output().unwrap();
    match out.status.code() {
        Some(0) | Some(1) => Ok(t0.elapsed()),
        c => Err(format!("exit {c:?}; stderr: {}", String::from_utf8_lossy(&out.stderr))),
    }
}

#[test]
fn every_help_example_runs() {
    let out = common::bin().arg("__cli-tree").output().unwrap();
    let tree: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut all = Vec::new();
    paths(&tree, &[], &mut all);
    let mut examples: Vec<String> = Vec::new();
    let mut without = Vec::new();
    for p in &all {
        let ex = help_examples(p);
        if ex.is_empty() {
            without.push(p.join(" "));
        }
        for e in ex {
            if !examples.contains(&e) {
                examples.push(e);
            }
        }
    }
    assert!(without.is_empty(), "commands without an example in --help: {without:?}");
    assert!(examples.len() >= 40, "only {} examples", examples.len());
    // The data sets first (stable order otherwise: load map before load correct, …).
    examples.sort_by_key(|e| !e.starts_with("truepos simulate"));
    let dir = tempfile::tempdir().unwrap();
    fixtures(dir.path());
    let mut failed = Vec::new();
    let mut times = Vec::new();
    for (prefix, why) in SHOWN_NOT_RUN {
        eprintln!("not run here: {prefix}… ({why})");
    }
    for e in examples
        .iter()
        .filter(|e| !e.starts_with("truepos demo") && !SHOWN_NOT_RUN.iter().any(|(p, _)| e.starts_with(p)))
    {
        match run(dir.path(), e) {
            Ok(t) => times.push((t, e.clone())),
            Err(why) => failed.push(format!("{e}\n    {why}")),
        }
    }
    times.sort();
    for (t, e) in times.iter().rev().take(5) {
        eprintln!("{:6.2} s  {e}", t.as_secs_f64());
    }
    assert!(failed.is_empty(), "{} example(s) failed:\n  {}", failed.len(), failed.join("\n  "));
}

/// Examples are printed verbatim: a long one stays on one line at any terminal width.
#[test]
fn examples_are_not_wrapped() {
    for cols in ["40", "200"] {
        let out = common::bin().args(["fit", "--help"]).env("COLUMNS", cols).output().unwrap();
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(
            text.lines().any(|l| l.trim()
                == "truepos fit circle hole.csv --nominal-diameter-mm 20 --tolerance-mm=-0.001,0.006 --decision-rule guarded --qif hole.qif"),
            "{text}"
        );
    }
    // `truepos help load map` shows the same examples as `truepos load map --help`.
    let a = common::bin().args(["help", "load", "map"]).output().unwrap();
    let b = common::bin().args(["load", "map", "--help"]).output().unwrap();
    assert_eq!(a.stdout, b.stdout);
    assert!(String::from_utf8_lossy(&a.stdout)
        .contains("truepos load map --bed load/bed.toml --output load/map.csv"));
}

/// The demo's example (slow: every capability end to end).
#[test]
#[ignore]
fn demo_example_runs() {
    let ex = help_examples(&["demo".to_string()]);
    assert_eq!(ex, vec!["truepos demo --out demo".to_string()]);
    let dir = tempfile::tempdir().unwrap();
    run(dir.path(), &ex[0]).unwrap();
    assert!(dir.path().join("demo/index.html").is_file());
}
