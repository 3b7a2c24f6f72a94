//! `somac run` says one verdict everywhere: the JSON `verdict`, `reasons` and `status`, the exit
//! code, and the audit trail's run row (status and a non-empty message) agree — on the README
//! tour's cell, where a tracker is bumped mid-run and the loop recovers with an inclination
//! alarm (verdict `alarm`, exit 1), and on a run without alarms.

mod common;
use common::bin;
use serde_json::Value;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run(dir: &Path, db: &Path) -> (Option<i32>, Value) {
    let o = bin()
        .args(["somac", "run", "--program", s(&dir.join("program.nc")), "--cell", s(&dir.join("cell.toml"))])
        .args(["--db", s(db), "--json"])
        .output()
        .unwrap();
    let j: Value = serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&o.stderr)));
    (o.status.code(), j)
}

fn last_run_row(db: &Path) -> (String, String, Option<String>) {
    let c = rusqlite::Connection::open(db).unwrap();
    c.query_row(
        "SELECT status, COALESCE(message, ''), ended_at FROM runs ORDER BY id DESC LIMIT 1",
        [],
        |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
    )
    .unwrap()
}

fn check_agreement(code: Option<i32>, j: &Value, db: &Path) {
    let verdict = j["verdict"].as_str().unwrap();
    let reasons: Vec<&str> = j["reasons"].as_array().unwrap().iter().map(|r| r.as_str().unwrap()).collect();
    assert!(!reasons.is_empty());
    let status = j["status"].as_str().unwrap();
    let want = match verdict {
        "pass" => (Some(0), "SUCCESS"),
        "alarm" => (Some(1), "ALARM"),
        "fail" => (Some(1), "FAILURE"),
        other => panic!("verdict {other}"),
    };
    assert_eq!((code, status), want, "{j}");
    let (db_status, message, ended) = last_run_row(db);
    assert_eq!(db_status, status);
    assert!(message.starts_with(verdict) && message.len() > verdict.len() + 2, "{message}");
    assert!(ended.is_some());
    // Every alarm is a reason, recovered or not.
    for a in j["alarms"].as_array().unwrap() {
        let kind = a["kind"].as_str().unwrap();
        let line = a["line"].as_u64().unwrap();
        assert!(
            reasons.iter().any(|r| r.contains(kind) && r.starts_with(&format!("line {line}:"))),
            "{kind} at {line}: {reasons:?}"
        );
    }
}

#[test]
fn the_tour_cell_with_a_bumped_tracker_ends_with_verdict_alarm_everywhere() {
    let d = tempfile::tempdir().unwrap();
    let o = bin().args(["simulate", "somac", "--out", s(d.path())]).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let db = d.path().join("audit.sqlite");
    let (code, j) = run(d.path(), &db);
    check_agreement(code, &j, &db);
    let stops = j["stops"].as_array().unwrap();
    if stops.iter().all(|s| s["status"] == "SUCCESS")
        && j["alarms"].as_array().unwrap().iter().any(|a| a["kind"] == "inclination")
    {
        assert_eq!(j["verdict"], "alarm", "{}", j["reasons"]);
    }
}

#[test]
fn a_small_run_agrees_too() {
    let d = tempfile::tempdir().unwrap();
    let o = bin()
        .args(["simulate", "somac", "--out", s(d.path()), "--holes-per-row", "2", "--seed", "5"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let db = d.path().join("audit.sqlite");
    let (code, j) = run(d.path(), &db);
    check_agreement(code, &j, &db);
}

/// A run ended by SIGINT is closed in the audit trail as ABORTED with its end time (not left
/// `running`), and the process reports the signal (exit status 130).
#[test]
fn a_run_interrupted_by_sigint_is_closed_as_aborted() {
    let d = tempfile::tempdir().unwrap();
    let o = bin().args(["simulate", "somac", "--out", s(d.path())]).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let db = d.path().join("audit.sqlite");
    let child = bin()
        .args([
            "somac",
            "run",
            "--program",
            s(&d.path().join("program.nc")),
            "--cell",
            s(&d.path().join("cell.toml")),
        ])
        .args(["--db", s(&db), "--json"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the run row exists, then interrupt.
    let t0 = std::time::Instant::now();
    while !db.exists() && t0.elapsed().as_secs() < 20 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    std::thread::sleep(std::time::Duration::from_millis(30));
    let _ = std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status();
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let (status, message, ended) = last_run_row(&db);
    if out.status.code() == Some(0) || out.status.code() == Some(1) {
        // The run finished before the signal arrived: then it is closed with its verdict.
        eprintln!("note: the run ended before SIGINT arrived ({status})");
        assert!(ended.is_some());
        return;
    }
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert_eq!(status, "ABORTED", "{err}");
    assert!(message.contains("SIGINT"), "{message}");
    assert!(ended.is_some());
    assert!(err.contains("ABORTED"), "{err}");
}
