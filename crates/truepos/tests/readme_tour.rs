//! The README's five-minute tour quotes what its commands print: this test runs the same
//! commands (the same seeds, in a temporary directory) and fails when a quoted figure and the
//! output disagree by more than half a unit of the README's last printed digit (the README is
//! right to the digits it shows). Regenerate the figures with `scripts/readme_figures.sh`.

mod common;

use serde_json::Value;
use std::path::Path;

/// The tour's code block.
fn tour() -> String {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md")).unwrap();
    let start = readme.find("## Five-minute tour").expect("README has the tour");
    let block = &readme[start..];
    let open = block.find("```sh").expect("tour code block") + 5;
    let close = block[open..].find("```").expect("end of the tour block");
    block[open..open + close].to_string()
}

/// The numbers of the comment on the tour line that contains `key` (or the comment line right
/// after it, for a command split over two lines), with their decimals.
fn quoted(tour: &str, key: &str) -> Vec<(f64, usize)> {
    let lines: Vec<&str> = tour.lines().collect();
    let i = lines.iter().position(|l| l.contains(key)).unwrap_or_else(|| panic!("no tour line has {key:?}"));
    let mut comment = lines[i].rsplit_once("# ").map(|(_, c)| c.to_string()).unwrap_or_default();
    if comment.trim().is_empty() {
        comment = lines
            .get(i + 1)
            .and_then(|l| l.rsplit_once("# "))
            .map(|(_, c)| c.to_string())
            .unwrap_or_default();
    }
    let mut out = Vec::new();
    let mut cur = String::new();
    for ch in comment.chars().chain(std::iter::once(' ')) {
        if ch.is_ascii_digit() || ch == '.' || ((ch == '-' || ch == '+') && cur.is_empty()) {
            cur.push(ch);
        } else {
            let t = cur.trim_end_matches('.');
            if let Ok(v) = t.parse::<f64>() {
                if t.bytes().any(|b| b.is_ascii_digit()) {
                    out.push((v, t.split_once('.').map_or(0, |(_, d)| d.len())));
                }
            }
            cur.clear();
        }
    }
    assert!(!out.is_empty(), "no number quoted on the tour line of {key:?}: {comment}");
    out
}

/// `value` agrees with the quoted `(q, decimals)` to the quoted digits.
fn agrees(what: &str, value: f64, (q, d): (f64, usize)) -> Option<String> {
    let half = 0.5 * 10f64.powi(-(d as i32)) * 1.0001;
    ((value - q).abs() > half)
        .then(|| format!("{what}: README says {q} ({d} decimals), the command gives {value}"))
}

fn run(dir: &Path, args: &str) -> String {
    let out = common::bin().args(args.split_whitespace()).current_dir(dir).output().unwrap();
    assert!(
        matches!(out.status.code(), Some(0) | Some(1)),
        "{args}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn json(dir: &Path, args: &str) -> Value {
    serde_json::from_str(&run(dir, args)).unwrap()
}

fn file_json(dir: &Path, f: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join(f)).unwrap()).unwrap()
}

/// The second line (first data row) of a CSV written by the tour, comments skipped, as numbers.
fn first_row(dir: &Path, f: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(dir.join(f)).unwrap();
    let row = text.lines().filter(|l| !l.starts_with('#')).nth(1).unwrap().to_string();
    row.split(',').skip(1).take(3).map(|v| v.parse().unwrap()).collect()
}

#[test]
fn readme_tour_figures_match_the_commands() {
    let t = tour();
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let mut bad: Vec<String> = Vec::new();
    let mut check = |what: &str, v: f64, q: (f64, usize)| bad.extend(agrees(what, v, q));

    run(d, "simulate latency --out tour/latency");
    let v = json(d, "latency --machine tour/latency/machine.csv --probe tour/latency/probe.csv --sphere-diameter-mm 25 --tip-radius-mm 2 --json");
    let q = quoted(&t, "--sphere-diameter-mm 25 --tip-radius-mm 2");
    check("latency delay (µs)", v["delay_s"].as_f64().unwrap() * 1e6, q[0]);
    check("latency U (µs)", v["uncertainty_s"].as_f64().unwrap() * 1e6, q[1]);

    run(d, "simulate head-offset --out tour/head");
    let v = json(
        d,
        "head-offset --points tour/head/points.csv --table-center-mm 500,250,0 --tip-radius-mm 1.5 --json",
    );
    let truth = file_json(d, "tour/head/truth.json");
    let q = quoted(&t, "jq -c .offset_mm tour/head/truth.json");
    let worst = (0..3)
        .map(|i| (v["offset_mm"][i].as_f64().unwrap() - truth["offset_mm"][i].as_f64().unwrap()).abs())
        .fold(0.0, f64::max);
    for i in 0..3 {
        check("head truth offset (mm)", truth["offset_mm"][i].as_f64().unwrap(), q[i]);
    }
    check("head offset error (µm)", worst * 1e3, q[3]);

    run(d, "simulate comp --out tour/comp");
    run(d, "comp correct --map tour/comp/map.csv --squareness tour/comp/squareness.toml --points tour/comp/points.csv --output tour/comp/corrected.csv --probe-offset-mm 0,0,-150");
    let row = first_row(d, "tour/comp/corrected.csv");
    let q = quoted(&t, "tour/comp/corrected.csv | sed");
    let truth = file_json(d, "tour/comp/truth.json");
    let qt = quoted(&t, "tour/comp/truth.json");
    for i in 0..3 {
        check("comp corrected P1 (mm)", row[i], q[i + 1]);
        check("comp truth P1 (mm)", truth["true_points_mm"][0][i].as_f64().unwrap(), qt[i]);
    }

    run(d, "simulate load --out tour/load");
    run(d, "load map --bed tour/load/bed.toml --output tour/load/map.csv");
    run(d, "load correct --map tour/load/map.csv --load tour/load/load.toml --bed tour/load/bed.toml --points tour/load/points.csv --output tour/load/corrected.csv");
    let row = first_row(d, "tour/load/corrected.csv");
    let q = quoted(&t, "tour/load/corrected.csv | sed");
    let truth = file_json(d, "tour/load/truth.json");
    let qt = quoted(&t, "tour/load/truth.json");
    for i in 0..3 {
        check("load corrected P1 (mm)", row[i], q[i + 1]);
        check("load truth P1 (mm)", truth["true_points_mm"][0][i].as_f64().unwrap(), qt[i]);
    }

    run(d, "simulate scan --out tour/scan");
    let v = json(d, "scan run --features tour/scan/features.toml --part tour/scan/truth.json --output tour/scan/points.csv --json");
    let q = quoted(&t, "--output tour/scan/points.csv --json");
    check("scan cycle time (s)", v["cycle_time_s"].as_f64().unwrap(), q[0]);
    check("scan stops", v["stops"].as_f64().unwrap(), q[1]);
    // bore0's scan points, as the README's awk line selects them.
    let text = std::fs::read_to_string(d.join("tour/scan/points.csv")).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let mut bore = String::from(lines.next().unwrap());
    bore.push('\n');
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        if f.get(5) == Some(&"bore0") && f.get(4) == Some(&"scan") {
            bore.push_str(l);
            bore.push('\n');
        }
    }
    std::fs::write(d.join("tour/scan/bore0.csv"), bore).unwrap();
    let v = json(d, "fit circle tour/scan/bore0.csv --json");
    let q = quoted(&t, "truepos fit circle tour/scan/bore0.csv");
    check("bore0 radius (mm)", v["radius_mm"].as_f64().unwrap(), q[0]);
    let truth = file_json(d, "tour/scan/truth.json");
    let q = quoted(&t, "jq '.features[0].actual.radius_mm'");
    check("bore0 true radius (mm)", truth["features"][0]["actual"]["radius_mm"].as_f64().unwrap(), q[0]);

    run(d, "simulate somac --out tour/somac");
    let v = json(d, "somac run --program tour/somac/program.nc --cell tour/somac/cell.toml --db tour/somac/audit.sqlite --json");
    let q = quoted(&t, "--db tour/somac/audit.sqlite --json");
    check("somac true mean error (mm)", v["true_mean_error_mm"].as_f64().unwrap(), q[0]);
    check("somac true max error (mm)", v["true_max_error_mm"].as_f64().unwrap(), q[1]);
    let truth = file_json(d, "tour/somac/truth.json");
    let q = quoted(&t, "truepos simulate somac --out tour/somac");
    check("somac native mean error (mm)", truth["native_mean_error_mm"].as_f64().unwrap(), q[0]);

    assert!(
        bad.is_empty(),
        "README tour figures drifted (scripts/readme_figures.sh regenerates them):\n  {}",
        bad.join("\n  ")
    );
}

/// The comparison itself: a figure off by more than half its last digit is found.
#[test]
fn a_drifted_figure_is_found() {
    let t = "x\ntruepos a --json | jq   # 29.2 s, 0 stops\n";
    let q = quoted(t, "truepos a");
    assert_eq!(q, vec![(29.2, 1), (0.0, 0)]);
    assert!(agrees("cycle", 30.34, q[0]).is_some());
    assert!(agrees("cycle", 29.24, q[0]).is_none());
}
