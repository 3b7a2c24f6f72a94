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
