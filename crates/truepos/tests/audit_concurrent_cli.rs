//! Eight `truepos somac run` processes on one fresh audit database at the same time (issue 14):
//! every process succeeds, and the database holds eight complete runs — each with its end time,
//! final status, and one `stops` row per stop of the program — and no empty run rows.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

fn truepos(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_truepos"));
    c.current_dir(dir);
    c
}

#[test]
fn eight_concurrent_somac_processes_on_one_database_all_complete() {
    let d = tempfile::tempdir().unwrap();
    let s = truepos(d.path())
        .args(["simulate", "somac", "--out", "cell", "--seed", "5", "--holes-per-row", "25"])
        .output()
        .unwrap();
    assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
    let t0 = Instant::now();
    let children: Vec<_> = (0..8)
        .map(|_| {
            truepos(d.path())
                .args(["somac", "run", "--program", "cell/program.nc", "--cell", "cell/cell.toml"])
                .args(["--db", "shared.sqlite", "--json"])
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let mut stop_counts = Vec::new();
    for (k, c) in children.into_iter().enumerate() {
        let out = c.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        // Exit 1 is a metrological verdict (a stop not SUCCESS), never an audit failure.
        assert!(matches!(out.status.code(), Some(0 | 1)), "process {k}: {:?} {err}", out.status);
        assert!(!err.contains("locked") && !err.contains("already exists"), "process {k}: {err}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        stop_counts.push(v["stops"].as_array().unwrap().len() as i64);
    }
    eprintln!("8 concurrent somac runs on one database: {:.2} s", t0.elapsed().as_secs_f64());

    let db = rusqlite::Connection::open(d.path().join("shared.sqlite")).unwrap();
    let runs: Vec<(i64, Option<String>, Option<String>, String)> = db
        .prepare("SELECT id, ended_at, status, started_at FROM runs ORDER BY id")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(runs.len(), 8, "{runs:?}");
    for (id, ended, status, started) in &runs {
        let ended = ended.as_deref().unwrap_or_else(|| panic!("run {id} has no end time"));
        assert!(status.is_some(), "run {id} has no final status");
        for ts in [started.as_str(), ended] {
            // ISO 8601 UTC: 2026-11-24T03:44:10Z (optionally with fractional seconds).
            assert!(ts.len() >= 20 && ts.ends_with('Z') && ts.as_bytes()[10] == b'T', "run {id}: {ts}");
        }
        assert!(ended >= started.as_str(), "run {id}: ended {ended} before started {started}");
        let stops: i64 =
            db.query_row("SELECT COUNT(*) FROM stops WHERE run_id = ?1", [id], |r| r.get(0)).unwrap();
        assert_eq!(stops, stop_counts[0], "run {id}: {stops} stop rows");
    }
    assert!(stop_counts.iter().all(|&n| n == stop_counts[0] && n > 0), "{stop_counts:?}");
}
