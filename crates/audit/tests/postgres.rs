//! The audit trail on a real PostgreSQL (a throw-away cluster per test, `pgcluster`): the
//! schema created by its owner and refused to a role that may not create it; a role that can only
//! insert and read; eight cells writing at once; the same records as SQLite; tampering detected;
//! the server killed in the middle of a run and brought back; records per second.
//! Without PostgreSQL installed each test prints `SKIPPED: …` and returns.

mod pgcluster;

use pgcluster::{Cluster, CELL_PW, OWNER_PW};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use truepos_audit::{now_utc, Audit, AuditError, Db, Trail, Value};
use truepos_somac::audit::{AuditSink, Event};

fn db(c: &Cluster, user: &str) -> Db {
    let pw = if user == "owner" { OWNER_PW } else { CELL_PW };
    Db::parse_with(&c.url(user, "fleet"), &|k| (k == "PGPASSWORD").then(|| pw.to_string())).unwrap()
}

fn stop(a: &mut Audit, line: usize) {
    a.record(&Event::Block { line, text: format!("G1 X{line} (MSG,Measure SOMaC)"), time_s: line as f64 })
        .unwrap();
    a.record(&Event::Measurement {
        line,
        iteration: 0,
        commanded_mm: truepos_math::Point3::new(line as f64, 2.5, -0.0),
        measured_mm: truepos_math::Point3::new(line as f64 + 0.013, 2.5 - 1e-9, 0.1 + 0.2),
        error_mm: 0.013,
        samples_std_mm: 1.5e-4,
        time_s: line as f64 + 0.25,
    })
    .unwrap();
    a.record(&Event::StopResult {
        line,
        status: "SUCCESS".into(),
        final_error_mm: if line == 1 { f64::NAN } else { 0.004 },
        iterations: 1,
        time_s: line as f64 + 0.5,
    })
    .unwrap();
    a.commit().unwrap();
}

/// A run's records without what differs between two writes of the same events (uid, record
/// ids, hashes, run ids, timestamps): table and values.
fn content(t: &mut Trail, run: i64) -> Vec<(String, Vec<Value>)> {
    t.records(run)
        .unwrap()
        .into_iter()
        .filter(|r| r.table != "run_starts")
        .map(|r| {
            let vals = r
                .spec()
                .columns
                .iter()
                .zip(&r.values)
                .filter(|(c, _)| !["at", "ended_at", "run_id"].contains(&c.0));
            (r.table.to_string(), vals.map(|(_, v)| v.clone()).collect())
        })
        .collect()
}

#[test]
fn postgres_trail_privileges_concurrency_chain() {
    let Some(c) = Cluster::start() else { return };
    let owner = db(&c, "owner");
    let cell = db(&c, "cell");

    // The cell role may not create the schema: a clear refusal naming the owner's command.
    let e = Audit::open(&cell, "p.nc", &now_utc()).err().expect("no CREATE on public");
    assert!(e.to_string().contains("truepos audit migrate"), "{e}");
    assert!(!e.is_usage());
    assert_eq!(c.psql("fleet", "SELECT COUNT(*) FROM pg_tables WHERE schemaname = 'public'").unwrap(), "0");
    // The owner creates it (as `truepos audit migrate` does).
    Trail::open(&owner).unwrap();
    let tables = c.psql("fleet", "SELECT COUNT(*) FROM pg_tables WHERE schemaname = 'public'").unwrap();
    assert_eq!(
        tables,
        truepos_audit::TABLES.len().saturating_sub(1).to_string(),
        "every table but the runs view"
    );

    // Eight cells at once, as the insert-and-read role.
    let t0 = Instant::now();
    let handles: Vec<_> = (0..8)
        .map(|k| {
            let cell = cell.clone();
            std::thread::spawn(move || -> Result<i64, String> {
                let mut a =
                    Audit::open(&cell, &format!("cell{k}.nc"), &now_utc()).map_err(|e| e.to_string())?;
                a.set_controller("virtual", &format!("cell {k}")).map_err(|e| e.to_string())?;
                for line in 0..20 {
                    stop(&mut a, line);
                }
                a.finish("SUCCESS", None, &now_utc()).map_err(|e| e.to_string())?;
                Ok(a.run_id())
            })
        })
        .collect();
    let mut ids: Vec<i64> = handles.into_iter().map(|h| h.join().unwrap().unwrap()).collect();
    let secs = t0.elapsed().as_secs_f64();
    ids.sort();
    assert_eq!(ids, (1..=8).collect::<Vec<_>>());
    let per_run = 1 + 1 + 20 * 3 + 1;
    eprintln!(
        "postgres: 8 cells at once, {} records in {secs:.2} s ({:.0} records/s)",
        8 * per_run,
        (8 * per_run) as f64 / secs
    );
    let mut t = Trail::open(&cell).unwrap();
    let runs = t.runs().unwrap();
    assert_eq!(runs.len(), 8);
    assert!(runs.iter().all(|r| r.status.as_deref() == Some("SUCCESS") && r.ended_at.is_some()));
    assert!(runs.iter().all(|r| r.controller.as_deref() == Some("virtual")));
    let v = t.verify().unwrap();
    assert!(v.first_broken.is_none(), "{v:?}");
    assert_eq!(v.records, 8 * per_run as i64);

    // Least privilege: the cell role cannot change or remove the trail, nor the schema.
    let mut client = postgres::Config::new()
        .host("127.0.0.1")
        .port(c.port)
        .user("cell")
        .password(CELL_PW)
        .dbname("fleet")
        .connect(postgres::NoTls)
        .unwrap();
    for sql in [
        "UPDATE stops SET final_error_mm = 0 WHERE seq = 5",
        "DELETE FROM stops WHERE seq = 5",
        "DELETE FROM run_ends",
        "TRUNCATE blocks",
        "DROP TABLE measurements",
        "ALTER TABLE stops ADD COLUMN x TEXT",
        "CREATE TABLE t (x int)",
    ] {
        let e = client.batch_execute(sql).err().unwrap_or_else(|| panic!("allowed: {sql}"));
        let msg = e.as_db_error().map(|d| d.message().to_string()).unwrap_or_default();
        assert!(msg.contains("permission denied") || msg.contains("must be owner"), "{sql}: {msg}");
    }
    assert!(client.query_one("SELECT COUNT(*) FROM runs", &[]).is_ok(), "it can read");

    // Same records as SQLite: one run of identical events on both backends.
    let dir = tempfile::tempdir().unwrap();
    let lite = Db::Sqlite(dir.path().join("a.sqlite"));
    let mut contents = Vec::new();
    for d in [&lite, &cell] {
        let mut a = Audit::open(d, "same.nc", "2026-11-28T00:00:00Z").unwrap();
        a.set_controller("virtual", "v").unwrap();
        for line in 0..3 {
            stop(&mut a, line);
        }
        a.finish("FAILURE", Some("alarm, \"quoted\""), "2026-11-28T00:01:00Z").unwrap();
        let run = a.run_id();
        let mut t = Trail::open(d).unwrap();
        contents.push(content(&mut t, run));
        assert!(t.verify().unwrap().first_broken.is_none());
    }
    assert_eq!(contents[0], contents[1]);
    assert!(
        contents[0].iter().any(|(t, v)| t == "stops" && v[2] == Value::Null),
        "NaN stored as NULL on both"
    );

    // Tampering by the owner is named by verify.
    c.psql(
        "fleet",
        "UPDATE measurements SET error_mm = 0.001 WHERE seq = (SELECT MIN(seq) FROM measurements)",
    )
    .unwrap();
    let first_meas = c.psql("fleet", "SELECT MIN(seq) FROM measurements").unwrap();
    let b = Trail::open(&cell).unwrap().verify().unwrap().first_broken.expect("detected");
    assert_eq!(b.seq.to_string(), first_meas);
    assert_eq!(b.table, "measurements");
    assert!(b.problem.contains("content"), "{b:?}");

    // A newer schema is refused and left as it is; so is a database with foreign tables.
    c.psql("fleet", "INSERT INTO schema_migrations VALUES (99, '2030-01-01T00:00:00Z')").unwrap();
    let before = c.psql("fleet", "SELECT COUNT(*) FROM run_starts").unwrap();
    let e = Audit::open(&cell, "p.nc", &now_utc()).err().expect("newer");
    assert!(matches!(e, AuditError::Newer { found: 99, .. }), "{e}");
    assert_eq!(c.psql("fleet", "SELECT COUNT(*) FROM run_starts").unwrap(), before);
    c.psql("postgres", "CREATE DATABASE shop OWNER owner").unwrap();
    c.psql("shop", "CREATE TABLE parts (id int); INSERT INTO parts VALUES (1)").unwrap();
    let shop =
        Db::parse_with(&c.url("owner", "shop"), &|k| (k == "PGPASSWORD").then(|| OWNER_PW.into())).unwrap();
    let e = Audit::open(&shop, "p.nc", &now_utc()).err().expect("foreign");
    assert!(e.to_string().contains("'parts'") && e.is_usage(), "{e}");
    assert_eq!(
        c.psql("shop", "SELECT string_agg(tablename, ',') FROM pg_tables WHERE schemaname = 'public'")
            .unwrap(),
        "parts"
    );

    // A wrong password is a clear error, and never echoes a password.
    let bad =
        Db::parse_with(&c.url("cell", "fleet"), &|k| (k == "PGPASSWORD").then(|| "wrong-pw".into())).unwrap();
    let e = Audit::open(&bad, "p.nc", &now_utc()).err().expect("refused");
    assert!(e.to_string().contains("password") && !e.to_string().contains("wrong-pw"), "{e}");
}

/// Records per second, one writer, one commit per stop of 3 records (`--nocapture` shows it).
fn rate(d: &Db, stops: usize) -> f64 {
    let mut a = Audit::open(d, "rate.nc", &now_utc()).unwrap();
    let t0 = Instant::now();
    for line in 0..stops {
        stop(&mut a, line);
    }
    a.finish("SUCCESS", None, &now_utc()).unwrap();
    (stops * 3 + 1) as f64 / t0.elapsed().as_secs_f64()
}

#[test]
fn postgres_outage_in_the_middle_of_a_run() {
    let Some(c) = Cluster::start_durable() else { return };
    let owner = db(&c, "owner");
    let cell = db(&c, "cell");
    Trail::open(&owner).unwrap();
    let spool_dir = tempfile::tempdir().unwrap();

    let mut a = Audit::open(&cell, "long.nc", &now_utc()).unwrap();
    let notices = Arc::new(Mutex::new(Vec::<String>::new()));
    let n2 = notices.clone();
    a.set_notify(move |m| n2.lock().unwrap().push(m.to_string()));
    a.set_spool_dir(spool_dir.path());
    a.set_retry(Duration::from_millis(100), Duration::from_secs(20));
    for line in 0..5 {
        stop(&mut a, line);
    }
    c.crash();
    for line in 5..10 {
        stop(&mut a, line);
    }
    let spool = a.spool_path().expect("spooling while the server is down").to_path_buf();
    assert!(spool.exists() && spool.starts_with(spool_dir.path()));
    assert!(notices.lock().unwrap()[0].contains(&spool.display().to_string()), "{notices:?}");
    c.restart();
    std::thread::sleep(Duration::from_millis(150));
    for line in 10..15 {
        stop(&mut a, line);
    }
    assert!(a.spool_path().is_none() && !spool.exists(), "{notices:?}");
    a.finish("SUCCESS", None, &now_utc()).unwrap();
    let mut t = Trail::open(&cell).unwrap();
    let counts = t.counts(1).unwrap();
    for table in ["blocks", "measurements", "stops"] {
        assert_eq!(counts.iter().find(|x| x.0 == table).unwrap().1, 15, "{table}: exactly once");
    }
    let lines: Vec<i64> = t
        .records(1)
        .unwrap()
        .iter()
        .filter(|r| r.table == "stops")
        .map(|r| r.get("line").and_then(Value::as_i64).unwrap())
        .collect();
    assert_eq!(lines, (0..15).collect::<Vec<_>>());
    let v = t.verify().unwrap();
    assert!(v.first_broken.is_none(), "{v:?}");
    eprintln!("postgres outage: server killed after stop 4, back before stop 10; 15/15 stops stored once, chain intact");

    // The server is still down when the run ends: the spool is named, pushed later, once.
    let mut a = Audit::open(&cell, "short.nc", &now_utc()).unwrap();
    a.set_notify(|_| {});
    a.set_spool_dir(spool_dir.path());
    a.set_retry(Duration::from_millis(100), Duration::from_millis(500));
    stop(&mut a, 0);
    c.crash();
    stop(&mut a, 1);
    let e = a.finish("ABORTED", Some("signal"), &now_utc()).expect_err("unsent");
    let AuditError::Unsent { spool, records, .. } = e else { panic!("{e}") };
    assert_eq!(records, 4);
    drop(a);
    c.restart();
    let (_, sent) = truepos_audit::push_spool(Path::new(&spool), Some(&cell)).unwrap();
    assert_eq!(sent, 4);
    let mut t = Trail::open(&cell).unwrap();
    let r = t.run("2").unwrap();
    assert_eq!((r.status.as_deref(), r.message.as_deref()), (Some("ABORTED"), Some("signal")));
    assert!(t.verify().unwrap().first_broken.is_none());

    // Records per second, both backends (figures for docs/audit.md).
    let dir = tempfile::tempdir().unwrap();
    let lite = Db::Sqlite(dir.path().join("rate.sqlite"));
    eprintln!(
        "records/s, one writer, one commit per 3-record stop: sqlite {:.0}, postgres {:.0}",
        rate(&lite, 300),
        rate(&cell, 300)
    );
}
