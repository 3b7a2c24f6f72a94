//! `truepos audit list | show | export | verify | migrate | push` and `--db` on `somac run` and
//! `somac inspect` (issue 30): on SQLite (no server) and on a throw-away PostgreSQL
//! (`crates/audit/tests/pgcluster`; `SKIPPED: …` when it cannot start). Tampering makes
//! `verify` exit 1 naming the record; a password in the address is refused (exit 2) and never
//! printed; an unreachable database stops the run before any motion (exit 3).

mod common;
#[path = "../../audit/tests/pgcluster/mod.rs"]
mod pgcluster;

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn bin(dir: &Path) -> Command {
    let mut c = common::bin();
    c.current_dir(dir).env_remove("PGPASSWORD").env("HOME", dir);
    c
}

fn ok_json(o: &Output) -> Value {
    assert!(matches!(o.status.code(), Some(0 | 1)), "{:?}: {}", o.status, String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&o.stdout)))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn simulate(dir: &Path) {
    let o = bin(dir)
        .args(["simulate", "somac", "--out", "cell", "--seed", "3", "--holes-per-row", "4"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

fn somac_run(dir: &Path, db: &str) -> Command {
    let mut c = bin(dir);
    c.args([
        "somac",
        "run",
        "--program",
        "cell/program.nc",
        "--cell",
        "cell/cell.toml",
        "--db",
        db,
        "--json",
    ]);
    c
}

fn inspect(dir: &Path, db: &str) -> Command {
    let mut c = bin(dir);
    c.args([
        "somac",
        "inspect",
        "--program",
        "cell/program.nc",
        "--diameter-mm",
        "8",
        "--tip-diameter-mm",
        "3",
    ])
    .args(["--db", db, "--json"]);
    c
}

/// list, show, export (JSON, CSV) and verify agree with what the runs printed.
fn check_trail(dir: &Path, db: &str, env: &[(&str, &str)], stops: usize) {
    let audit = |args: &[&str]| {
        let mut c = bin(dir);
        c.arg("audit").args(args).args(["--db", db]).envs(env.iter().copied());
        c.output().unwrap()
    };
    let list = ok_json(&audit(&["list", "--json"]));
    let runs = list["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 3, "{list}");
    for r in &runs[..2] {
        assert!(matches!(r["status"].as_str(), Some("SUCCESS" | "FAILURE")), "{r}");
        assert_eq!(r["controller"], "virtual");
        assert!(r["ended_at"].as_str().unwrap().ends_with('Z'));
    }
    assert_eq!(runs[2]["note"], "somac inspect");
    let show = ok_json(&audit(&["show", "1", "--json"]));
    assert_eq!(show["counts"]["stops"], stops as i64, "{show}");
    assert_eq!(show["stops"].as_array().unwrap().len(), stops);
    let by_uid = ok_json(&audit(&["show", runs[0]["uid"].as_str().unwrap(), "--json"]));
    assert_eq!(by_uid["run"]["id"], 1);
    let insp = ok_json(&audit(&["show", "3", "--json"]));
    assert_eq!(insp["counts"]["inspections"], 8);
    let hole = &insp["inspections"][0]["fields"];
    assert!(hole["position_error_mm"].as_f64().unwrap() < 0.2 && hole["points"] == 8, "{hole}");
    let o = audit(&["export", "1", "--format", "json"]);
    let export = ok_json(&o);
    let records = export["records"].as_array().unwrap();
    let total: i64 = show["counts"].as_object().unwrap().values().map(|v| v.as_i64().unwrap()).sum();
    assert_eq!(records.len() as i64, total + 1, "every record of the run and its start");
    assert!(records.windows(2).all(|w| w[0]["seq"].as_i64() < w[1]["seq"].as_i64()));
    assert!(records.iter().all(|r| r["hash"].as_str().unwrap().len() == 64));
    let o = audit(&["export", "1", "--format", "csv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = String::from_utf8(o.stdout).unwrap();
    assert!(csv.starts_with("seq,table,record_id,prev_hash,hash,"), "{csv}");
    assert_eq!(csv.lines().count(), records.len() + 1);
    let v = ok_json(&audit(&["verify", "--json"]));
    assert_eq!(v["ok"], true, "{v}");
    assert_eq!(v["head"]["seq"], v["records"]);
    let o = audit(&["show", "99"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("no run '99'"));
}

#[test]
fn audit_commands_on_sqlite_and_tampering_named() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    simulate(dir);
    let mut stops = 0;
    for _ in 0..2 {
        let j = ok_json(&somac_run(dir, "a.sqlite").output().unwrap());
        stops = j["stops"].as_array().unwrap().len();
    }
    let o = inspect(dir, "a.sqlite").output().unwrap();
    ok_json(&o);
    assert!(stderr(&o).contains("audit trail appended to a.sqlite (run 3)"), "{}", stderr(&o));
    check_trail(dir, "a.sqlite", &[], stops);
    let v = ok_json(&bin(dir).args(["audit", "verify", "--db", "a.sqlite", "--json"]).output().unwrap());
    let head = format!("{}:{}", v["head"]["seq"], v["head"]["hash"].as_str().unwrap());
    let o = bin(dir).args(["audit", "verify", "--db", "a.sqlite", "--head", &head]).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = bin(dir).args(["audit", "verify", "--db", "a.sqlite", "--head", "12:abc"]).output().unwrap();
    common::expect_input_error(&o, &["is not SEQ:HASH"]);
    // The last record deleted: only the kept head tells.
    let c = rusqlite::Connection::open(dir.join("a.sqlite")).unwrap();
    c.execute("DELETE FROM run_ends WHERE run_id = 3", []).unwrap();
    let o = bin(dir).args(["audit", "verify", "--db", "a.sqlite"]).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = bin(dir).args(["audit", "verify", "--db", "a.sqlite", "--head", &head]).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("records at its end were deleted"));

    // An owner's change to one value: verify exits 1 naming that record.
    let seq: i64 = c.query_row("SELECT MIN(seq) FROM stops WHERE run_id = 2", [], |r| r.get(0)).unwrap();
    c.execute("UPDATE stops SET final_error_mm = 0.0001 WHERE seq = ?1", [seq]).unwrap();
    let o = bin(dir).args(["audit", "verify", "--db", "a.sqlite", "--json"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!((v["ok"].as_bool(), v["first_broken"]["seq"].as_i64()), (Some(false), Some(seq)), "{v}");
    assert_eq!(v["first_broken"]["table"], "stops");
    let o = bin(dir).args(["audit", "verify", "--db", "a.sqlite"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains(&format!("BROKEN at record seq {seq} (stops ")) && text.contains("changed"),
        "{text}"
    );
    // A deleted record: named by the one after it.
    c.execute("UPDATE stops SET final_error_mm = 0.0001 WHERE seq = ?1", [seq]).unwrap();
    let o = bin(dir).args(["audit", "verify", "--db", "a.sqlite", "--json"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));

    // Reading a trail that does not exist: exit 2, nothing created.
    let o = bin(dir).args(["audit", "list", "--db", "none.sqlite"]).output().unwrap();
    common::expect_input_error(&o, &["no audit trail at none.sqlite"]);
    assert!(!dir.join("none.sqlite").exists());

    // Addresses: a password is refused and never printed; a verifying TLS mode without a readable
    // authority file is named before anything runs; unreachable.
    for (db, what) in [
        ("postgresql://cell:hunter2@127.0.0.1:1/fleet", "password in the address is refused"),
        (
            "postgresql://cell@127.0.0.1:1/fleet?sslmode=verify-full&sslrootcert=nope/ca.pem",
            "sslrootcert nope/ca.pem",
        ),
        ("postgresql://cell@127.0.0.1:1/fleet?sslmode=on", "not one of disable"),
        ("mysql://cell@127.0.0.1/fleet", "not a supported database"),
    ] {
        let o = somac_run(dir, db).output().unwrap();
        common::expect_input_error(&o, &[what]);
        assert!(!stderr(&o).contains("hunter2"), "{}", stderr(&o));
        let o = bin(dir).args(["audit", "list", "--db", db]).output().unwrap();
        common::expect_input_error(&o, &[what]);
    }
    let o = somac_run(dir, "postgresql://cell@127.0.0.1:1/fleet?connect_timeout=2").output().unwrap();
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    assert!(stderr(&o).contains("audit trail postgresql://cell@127.0.0.1:1/fleet"), "{}", stderr(&o));
}

#[test]
fn audit_commands_on_postgres() {
    let Some(pg) = pgcluster::Cluster::start() else { return };
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    simulate(dir);
    let owner = pg.url("owner", "fleet");
    let cell = pg.url("cell", "fleet");
    // The cell role cannot create the schema; the owner does, once.
    let o = somac_run(dir, &cell).env("PGPASSWORD", pgcluster::CELL_PW).output().unwrap();
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("truepos audit migrate"), "{}", stderr(&o));
    let o = bin(dir)
        .args(["audit", "migrate", "--db", &owner])
        .env("PGPASSWORD", pgcluster::OWNER_PW)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("audit schema version 5"));
    // Runs as the insert-and-read role: password from PGPASSWORD, then from ~/.pgpass.
    let j = ok_json(&somac_run(dir, &cell).env("PGPASSWORD", pgcluster::CELL_PW).output().unwrap());
    let stops = j["stops"].as_array().unwrap().len();
    assert_eq!(j["audit_db"], cell);
    let pgpass = dir.join(".pgpass");
    std::fs::write(&pgpass, format!("127.0.0.1:{}:fleet:cell:{}\n", pg.port, pgcluster::CELL_PW)).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&pgpass, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    ok_json(&somac_run(dir, &cell).output().unwrap());
    ok_json(&inspect(dir, &cell).output().unwrap());
    check_trail(dir, &cell, &[], stops);
    // The owner's tampering is named.
    pg.psql("fleet", "UPDATE blocks SET text = 'G0 X0' WHERE seq = (SELECT MAX(seq) FROM blocks)").unwrap();
    let seq = pg.psql("fleet", "SELECT MAX(seq) FROM blocks").unwrap();
    let o = bin(dir).args(["audit", "verify", "--db", &cell, "--json"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["first_broken"]["seq"].to_string(), seq, "{v}");
}

/// `somac run` on PostgreSQL with the server killed in the middle of the run and started again:
/// the run goes on (its records spooled, the spool named on stderr, sent when the server is
/// back), every stop is stored exactly once and the chain verifies.
#[test]
fn somac_run_survives_a_postgres_outage() {
    let Some(pg) = pgcluster::Cluster::start() else { return };
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let o = bin(dir)
        .args(["simulate", "somac", "--out", "cell", "--seed", "4", "--holes-per-row", "400"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let o = bin(dir)
        .args(["audit", "migrate", "--db", &pg.url("owner", "fleet")])
        .env("PGPASSWORD", pgcluster::OWNER_PW)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let child = somac_run(dir, &pg.url("cell", "fleet"))
        .env("PGPASSWORD", pgcluster::CELL_PW)
        .env("TRUEPOS_AUDIT_RETRY_S", "0.2")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the run has stored some stops, then kill the server.
    let t0 = std::time::Instant::now();
    let count = || pg.psql("fleet", "SELECT COUNT(*) FROM stops").ok().and_then(|s| s.parse::<i64>().ok());
    while count().unwrap_or(0) < 20 {
        assert!(t0.elapsed().as_secs() < 120, "the run stored no stops");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    pg.crash();
    let before = t0.elapsed();
    std::thread::sleep(std::time::Duration::from_millis(800));
    pg.restart();
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    let j = ok_json(&out);
    let stops = j["stops"].as_array().unwrap().len() as i64;
    assert!(err.contains("unreachable") && err.contains("truepos-audit-spool-"), "{err}");
    assert!(err.contains("is back") && err.contains("spooled records sent"), "{err}");
    let spool =
        err.split_whitespace().find(|w| w.contains("truepos-audit-spool-")).unwrap().trim_end_matches(',');
    assert!(!Path::new(spool).exists(), "spool removed: {spool}");
    assert_eq!(pg.psql("fleet", "SELECT COUNT(*) FROM stops").unwrap(), stops.to_string(), "each stop once");
    assert_eq!(pg.psql("fleet", "SELECT COUNT(DISTINCT line) FROM stops").unwrap(), stops.to_string());
    let o = bin(dir)
        .args(["audit", "verify", "--db", &pg.url("cell", "fleet"), "--json"])
        .env("PGPASSWORD", pgcluster::CELL_PW)
        .output()
        .unwrap();
    let v = ok_json(&o);
    assert_eq!(v["ok"], true, "{v}");
    eprintln!(
        "somac run on PostgreSQL: server killed {:.1} s into the run, back 0.8 s later; {stops} of {stops} stops stored once, chain intact",
        before.as_secs_f64()
    );
}
