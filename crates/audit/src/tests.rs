//! Unit tests on SQLite (no server): transactions, concurrency, refusals, migrations, the hash
//! chain against tampering, idempotent resends, and the spool behind a backend that loses its
//! connection on demand. The same logic on a real PostgreSQL: `tests/postgres.rs`.

use super::*;
use crate::backend::{BackendError, Dialect};
use rusqlite::Connection;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use truepos_somac::audit::Event;

fn sqlite(path: &Path) -> Db {
    Db::Sqlite(path.to_path_buf())
}

fn stop(a: &mut Audit, line: usize) {
    a.record(&Event::Block { line, text: format!("G1 X{line}"), time_s: line as f64 }).unwrap();
    a.record(&Event::StopResult {
        line,
        status: "SUCCESS".into(),
        final_error_mm: 0.01 + line as f64 * 1e-3,
        iterations: 1,
        time_s: line as f64 + 0.5,
    })
    .unwrap();
    a.commit().unwrap();
}

#[test]
fn committed_events_survive_a_crash_uncommitted_do_not() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("audit.sqlite");
    {
        let mut a = Audit::open(&path, "spar.nc", "2026-11-22T00:00:00Z").unwrap();
        a.record(&Event::Block { line: 1, text: "G0 X0".into(), time_s: 0.0 }).unwrap();
        a.record(&Event::Alarm {
            line: 1,
            kind: truepos_somac::run::AlarmKind::BeamBreak,
            message: "m".into(),
            action: "a".into(),
            time_s: 0.1,
        })
        .unwrap();
        a.commit().unwrap();
        a.record(&Event::Block { line: 2, text: "G0 X1".into(), time_s: 0.2 }).unwrap();
        // Dropped without commit, as when the process dies in the middle of a stop.
        drop(a);
    }
    let mut a = Audit::open(&path, "spar.nc", "2026-11-22T00:01:00Z").unwrap();
    let c = Connection::open(&path).unwrap();
    let q = |sql: &str| -> i64 { c.query_row(sql, [], |r| r.get(0)).unwrap() };
    assert_eq!((q("SELECT COUNT(*) FROM blocks"), q("SELECT COUNT(*) FROM alarms")), (1, 1));
    assert_eq!(q("SELECT COUNT(*) FROM schema_migrations"), MIGRATIONS.len() as i64);
    assert_eq!(a.run_id(), 2);
    assert_eq!(a.controller().unwrap(), (None, None));
    a.set_controller("linuxcncrsh://127.0.0.1:5007", "LinuxCNC 2.9.0").unwrap();
    assert_eq!(
        a.controller().unwrap(),
        (Some("linuxcncrsh://127.0.0.1:5007".to_string()), Some("LinuxCNC 2.9.0".to_string()))
    );
    // Run 1 never finished: no end record, no status.
    let st: Option<String> = c.query_row("SELECT status FROM runs WHERE id = 1", [], |r| r.get(0)).unwrap();
    assert_eq!(st, None);
    let v = Trail::open(&sqlite(&path)).unwrap().verify().unwrap();
    assert!(v.first_broken.is_none(), "{v:?}");
    // run 1 start, block, alarm, run 2 start, controller.
    assert_eq!((v.records, v.legacy_records), (5, 0));
}

#[test]
fn iso8601_utc_of_known_instants() {
    assert_eq!(iso8601_utc(0, 0), "1970-01-01T00:00:00.000Z");
    assert_eq!(iso8601_utc(951_782_400, 5), "2000-02-29T00:00:00.005Z");
    assert_eq!(iso8601_utc(1_700_000_000, 123), "2023-11-14T22:13:20.123Z");
    assert_eq!(iso8601_utc(-1, 0), "1969-12-31T23:59:59.000Z");
    assert!(is_iso8601_utc(&now_utc()));
    assert!(is_iso8601_utc("2026-11-22T00:00:00Z"));
    for bad in [
        "SystemTime { tv_sec: 1, tv_nsec: 2 }",
        "2026-11-22 00:00:00Z",
        "2026-13-01T00:00:00Z",
        "2026-11-22T00:00:00",
    ] {
        assert!(!is_iso8601_utc(bad), "{bad}");
    }
}

/// Eight runs at once on one new database: every run opens (one applies the migrations, the
/// others see them), writes all its stops, and records its end and status; the chain holds.
#[test]
fn eight_concurrent_runs_all_complete() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.sqlite");
    let barrier = Arc::new(std::sync::Barrier::new(8));
    let handles: Vec<_> = (0..8)
        .map(|k| {
            let path = path.clone();
            let barrier = barrier.clone();
            std::thread::spawn(move || -> Result<i64, String> {
                barrier.wait();
                let mut a = Audit::open(&path, &format!("p{k}.nc"), &now_utc()).map_err(|e| e.to_string())?;
                for line in 0..25 {
                    stop(&mut a, line);
                }
                a.finish("SUCCESS", None, &now_utc()).map_err(|e| e.to_string())?;
                Ok(a.run_id())
            })
        })
        .collect();
    let mut ids: Vec<i64> = handles.into_iter().map(|h| h.join().unwrap().unwrap()).collect();
    ids.sort();
    assert_eq!(ids, (1..=8).collect::<Vec<i64>>());
    let c = Connection::open(&path).unwrap();
    let q = |sql: &str| -> i64 { c.query_row(sql, [], |r| r.get(0)).unwrap() };
    assert_eq!(q("SELECT COUNT(*) FROM runs"), 8);
    assert_eq!(q("SELECT COUNT(*) FROM runs WHERE status = 'SUCCESS' AND ended_at IS NOT NULL"), 8);
    assert_eq!(q("SELECT COUNT(*) FROM schema_migrations"), MIGRATIONS.len() as i64);
    for id in 1..=8 {
        assert_eq!(q(&format!("SELECT COUNT(*) FROM blocks WHERE run_id = {id}")), 25);
        assert_eq!(q(&format!("SELECT COUNT(*) FROM stops WHERE run_id = {id}")), 25);
    }
    let started: String = c.query_row("SELECT started_at FROM runs WHERE id = 1", [], |r| r.get(0)).unwrap();
    assert!(is_iso8601_utc(&started), "{started}");
    let v = Trail::open(&sqlite(&path)).unwrap().verify().unwrap();
    assert!(v.first_broken.is_none(), "{v:?}");
    assert_eq!(v.records, 8 * (1 + 50 + 1));
}

/// Foreign files and newer schemas are refused before anything is written.
#[test]
fn foreign_and_newer_databases_are_left_byte_identical() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.sqlite");
    std::fs::write(&text, "not a database\n").unwrap();
    let foreign = dir.path().join("parts.sqlite");
    Connection::open(&foreign)
        .unwrap()
        .execute_batch("CREATE TABLE parts (id INTEGER, name TEXT); INSERT INTO parts VALUES (1, 'spar');")
        .unwrap();
    let rails = dir.path().join("rails.sqlite");
    Connection::open(&rails)
        .unwrap()
        .execute_batch("CREATE TABLE schema_migrations (version TEXT); CREATE TABLE users (id INTEGER);")
        .unwrap();
    let newer = dir.path().join("newer.sqlite");
    {
        let mut a = Audit::open(&newer, "p.nc", &now_utc()).unwrap();
        a.finish("SUCCESS", None, &now_utc()).unwrap();
    }
    Connection::open(&newer)
        .unwrap()
        .execute("INSERT INTO schema_migrations VALUES (99, '2030-01-01T00:00:00Z')", [])
        .unwrap();
    for (p, what) in
        [(&text, "not an SQLite"), (&foreign, "parts"), (&rails, "users"), (&newer, "version 99")]
    {
        let before = std::fs::read(p).unwrap();
        let e = Audit::open(p, "p.nc", &now_utc()).err().expect("refused");
        assert!(e.to_string().contains(what), "{e}");
        assert!(e.is_usage());
        let e = Trail::open(&sqlite(p)).err().expect("refused");
        assert!(e.to_string().contains(what), "{e}");
        assert_eq!(std::fs::read(p).unwrap(), before, "{}", p.display());
    }
    // A directory is refused too; a bad timestamp is refused before the file is touched.
    assert!(Audit::open(dir.path(), "p.nc", &now_utc()).is_err());
    let fresh = dir.path().join("fresh.sqlite");
    assert!(matches!(
        Audit::open(&fresh, "p.nc", "SystemTime { tv_sec: 1 }"),
        Err(AuditError::BadTimestamp(_))
    ));
    assert!(!fresh.exists());
    // Reading a trail that does not exist creates nothing.
    assert!(matches!(Trail::open(&sqlite(&fresh)), Err(AuditError::Missing(_))));
    assert!(!fresh.exists());
}

/// Version-1 and version-3 databases gain the chain; their old rows stay, readable, counted as
/// records from before the chain.
#[test]
fn old_databases_are_migrated_and_their_rows_kept() {
    let dir = tempfile::tempdir().unwrap();
    for upto in [1usize, 3] {
        let path = dir.path().join(format!("v{upto}.sqlite"));
        {
            let c = Connection::open(&path).unwrap();
            c.execute_batch(
                "CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL);",
            )
            .unwrap();
            for (v, sql) in &MIGRATIONS[..upto] {
                c.execute_batch(&Dialect::Sqlite.render(sql)).unwrap();
                c.execute("INSERT INTO schema_migrations VALUES (?1, '2026-01-01T00:00:00Z')", [v]).unwrap();
            }
            c.execute("INSERT INTO runs (started_at, program) VALUES ('2026-01-01T00:00:00Z', 'old.nc')", [])
                .unwrap();
            c.execute("INSERT INTO stops VALUES (1, 7, 'SUCCESS', 0.002, 1, 3.5)", []).unwrap();
            if upto == 3 {
                c.execute(
                    "UPDATE runs SET status = 'SUCCESS', ended_at = '2026-01-01T00:10:00Z' WHERE id = 1",
                    [],
                )
                .unwrap();
            }
        }
        let mut a = Audit::open(&path, "new.nc", &now_utc()).unwrap();
        assert_eq!(a.run_id(), 2);
        stop(&mut a, 1);
        a.finish("FAILURE", Some("alarm"), &now_utc()).unwrap();
        let mut t = Trail::open(&sqlite(&path)).unwrap();
        let runs = t.runs().unwrap();
        assert_eq!(runs.len(), 2);
        assert_eq!(runs[0].program, "old.nc");
        assert_eq!(runs[0].status.as_deref(), if upto == 3 { Some("SUCCESS") } else { None });
        assert_eq!((runs[1].status.as_deref(), runs[1].message.as_deref()), (Some("FAILURE"), Some("alarm")));
        assert_eq!(t.counts(1).unwrap().iter().find(|c| c.0 == "stops").unwrap().1, 1);
        let v = t.verify().unwrap();
        assert!(v.first_broken.is_none(), "{v:?}");
        assert_eq!(
            (v.records, v.legacy_records),
            (4, 2),
            "run 2: start, block, stop, end; run 1 + its stop before"
        );
    }
}

/// A version 4 trail (before `results`) is migrated to the current version: its records stay
/// in the chain, results are recorded and read back, and the chain verifies.
#[test]
fn a_version_4_trail_gains_results_and_keeps_its_chain() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v4.sqlite");
    {
        let c = Connection::open(&path).unwrap();
        c.execute_batch(
            "CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL);",
        )
        .unwrap();
        for (v, sql) in MIGRATIONS.iter().filter(|m| m.0 <= 4) {
            c.execute_batch(&crate::schema::render(Dialect::Sqlite, *v, sql)).unwrap();
            c.execute("INSERT INTO schema_migrations VALUES (?1, '2026-01-01T00:00:00Z')", [v]).unwrap();
        }
        assert!(c.prepare("SELECT * FROM results").is_err(), "version 4 has no results table");
    }
    let mut a = Audit::open(&path, "part.dms", &now_utc()).unwrap();
    a.record_result(&ResultRecord {
        line: Some(12),
        kind: "tolerance".into(),
        label: "T_DIAM1".into(),
        feature: Some("F_CIR1".into()),
        quantity: "DIAM".into(),
        value: 0.004,
        unit: "mm".into(),
        expanded_uncertainty: Some(0.0012),
        limits: Some((-0.01, 0.01)),
        verdict: Some("INTOL".into()),
    });
    a.finish("SUCCESS", None, &now_utc()).unwrap();
    let mut t = Trail::open(&sqlite(&path)).unwrap();
    let recs = t.records(a.run_id()).unwrap();
    let r = recs.iter().find(|r| r.table == "results").expect("a results record");
    assert!(r.values.contains(&Value::text("T_DIAM1")) && r.values.contains(&Value::Real(0.0012)), "{r:?}");
    assert!(t.verify().unwrap().first_broken.is_none());
    // Changing a recorded result breaks the chain at that record.
    Connection::open(&path).unwrap().execute_batch("UPDATE results SET value = 0.003").unwrap();
    let b = Trail::open(&sqlite(&path)).unwrap().verify().unwrap().first_broken.expect("detected");
    assert_eq!(b.table, "results", "{b:?}");
}

fn tamper(path: &Path, sql: &str) -> Option<Break> {
    Connection::open(path).unwrap().execute_batch(sql).unwrap();
    Trail::open(&sqlite(path)).unwrap().verify().unwrap().first_broken
}

/// A changed value, a deleted record, an inserted record, a record moved to another run and a
/// record taken out of the chain are each named by `verify`.
#[test]
fn the_chain_names_the_first_changed_deleted_or_inserted_record() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("good.sqlite");
    for k in 0..2 {
        let mut a = Audit::open(&src, &format!("p{k}.nc"), &now_utc()).unwrap();
        for line in 0..3 {
            stop(&mut a, line);
        }
        a.finish("SUCCESS", None, &now_utc()).unwrap();
    }
    let v = Trail::open(&sqlite(&src)).unwrap().verify().unwrap();
    assert!(v.first_broken.is_none());
    assert_eq!(v.records, 2 * (1 + 6 + 1));
    assert_eq!(v.head.0, 16);
    // Record seqs: run 1 start 1, blocks/stops 2..7, end 8; run 2 start 9, … end 16.
    let cases: &[(&str, i64, &str)] = &[
        ("UPDATE stops SET final_error_mm = 0.001 WHERE seq = 5", 5, "content"),
        ("UPDATE blocks SET text = 'G1 X9' WHERE seq = 2", 2, "content"),
        ("UPDATE stops SET run_id = 2 WHERE seq = 3", 3, "content"),
        ("UPDATE run_ends SET status = 'SUCCESS ' WHERE seq = 8", 8, "content"),
        ("DELETE FROM blocks WHERE seq = 4", 5, "missing"),
        (
            "INSERT INTO alarms SELECT run_id, line, 'x', 'y', 'z', time_s, 6, 'fake', prev_hash, hash FROM blocks WHERE seq = 6",
            6,
            "second record",
        ),
        ("UPDATE blocks SET seq = NULL WHERE seq = 14", 15, "missing"),
        ("UPDATE stops SET seq = NULL, record_id = record_id WHERE seq = 15", 16, "missing"),
    ];
    for (i, (sql, seq, what)) in cases.iter().enumerate() {
        let p = dir.path().join(format!("t{i}.sqlite"));
        std::fs::copy(&src, &p).unwrap();
        let b = tamper(&p, sql).unwrap_or_else(|| panic!("not detected: {sql}"));
        assert_eq!(b.seq, *seq, "{sql}: {b:?}");
        assert!(b.problem.contains(what), "{sql}: {b:?}");
    }
    // Records deleted at the end: only a head kept elsewhere tells.
    let p = dir.path().join("truncated.sqlite");
    std::fs::copy(&src, &p).unwrap();
    assert!(tamper(&p, "DELETE FROM run_ends WHERE seq = 16; DELETE FROM stops WHERE seq = 15").is_none());
    let mut t = Trail::open(&sqlite(&p)).unwrap();
    let b = t.verify_against(v.head.0, &v.head.1).unwrap().first_broken.expect("detected with the head");
    assert!(b.problem.contains("chain ends at 14"), "{b:?}");
    let ok = Trail::open(&sqlite(&src)).unwrap().verify_against(8, &v.head.1).unwrap();
    assert!(ok.first_broken.unwrap().problem.contains("rewritten"));
    let ok = Trail::open(&sqlite(&src)).unwrap().verify_against(v.head.0, &v.head.1).unwrap();
    assert!(ok.first_broken.is_none());
    // Taking the last record out of the chain while keeping its id.
    let p = dir.path().join("tail.sqlite");
    std::fs::copy(&src, &p).unwrap();
    let b = tamper(&p, "UPDATE run_ends SET seq = NULL WHERE seq = 16").expect("detected");
    assert!(b.problem.contains("lost its seq"), "{b:?}");
}

/// A batch sent twice (its acknowledgement lost) is stored once.
#[test]
fn a_resent_batch_is_stored_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.sqlite");
    let mut a = Audit::open(&path, "p.nc", &now_utc()).unwrap();
    let batch = vec![a.make("blocks", vec![Value::Int(1), Value::text("G1"), Value::real(0.5)])];
    let mut b = sqlite(&path).connect(false).unwrap();
    assert!(chain::append(b.as_mut(), &batch).unwrap());
    assert!(!chain::append(b.as_mut(), &batch).unwrap());
    assert_eq!(a.count("blocks").unwrap(), 1);
}

/// A SQLite backend whose connection can be made to fail, as a PostgreSQL server going away
/// does (`down`), or to lose the acknowledgement of a commit that did happen (`lose_ack`).
struct Flaky {
    inner: Box<dyn Backend>,
    down: Arc<AtomicBool>,
    lose_ack: Arc<AtomicBool>,
}

fn gone() -> BackendError {
    BackendError { message: "server closed the connection unexpectedly".into(), lost: true }
}

impl Backend for Flaky {
    fn dialect(&self) -> Dialect {
        self.inner.dialect()
    }
    fn execute_batch(&mut self, sql: &str) -> Result<(), BackendError> {
        if self.down.load(Ordering::SeqCst) {
            return Err(gone());
        }
        self.inner.execute_batch(sql)
    }
    fn execute(&mut self, sql: &str, p: &[Value]) -> Result<u64, BackendError> {
        if self.down.load(Ordering::SeqCst) {
            return Err(gone());
        }
        self.inner.execute(sql, p)
    }
    fn query(&mut self, sql: &str, p: &[Value]) -> Result<Vec<Vec<Value>>, BackendError> {
        if self.down.load(Ordering::SeqCst) {
            return Err(gone());
        }
        self.inner.query(sql, p)
    }
    fn begin_exclusive(&mut self) -> Result<(), BackendError> {
        if self.down.load(Ordering::SeqCst) {
            return Err(gone());
        }
        self.inner.begin_exclusive()
    }
    fn commit(&mut self) -> Result<(), BackendError> {
        if self.down.load(Ordering::SeqCst) {
            self.inner.rollback();
            return Err(gone());
        }
        self.inner.commit()?;
        if self.lose_ack.swap(false, Ordering::SeqCst) {
            return Err(gone());
        }
        Ok(())
    }
    fn rollback(&mut self) {
        self.inner.rollback()
    }
    fn tables(&mut self) -> Result<Vec<String>, BackendError> {
        if self.down.load(Ordering::SeqCst) {
            return Err(gone());
        }
        self.inner.tables()
    }
    fn reconnect(&mut self) -> Result<(), BackendError> {
        if self.down.load(Ordering::SeqCst) {
            return Err(gone());
        }
        Ok(())
    }
}

/// The database goes away in the middle of a run and comes back: the records are spooled
/// (the spool named in a notice), sent when it is back, each exactly once, the chain intact;
/// a lost acknowledgement does not duplicate a batch.
#[test]
fn an_outage_is_spooled_and_sent_exactly_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.sqlite");
    let down = Arc::new(AtomicBool::new(false));
    let lose_ack = Arc::new(AtomicBool::new(false));
    let flaky =
        Flaky { inner: sqlite(&path).connect(true).unwrap(), down: down.clone(), lose_ack: lose_ack.clone() };
    let mut a =
        Audit::open_backend(Box::new(flaky), path.display().to_string(), "p.nc", None, &now_utc()).unwrap();
    let notices = Arc::new(Mutex::new(Vec::<String>::new()));
    let n2 = notices.clone();
    a.set_notify(move |m| n2.lock().unwrap().push(m.to_string()));
    a.set_spool_dir(dir.path());
    a.set_retry(Duration::ZERO, Duration::from_millis(300));
    for line in 0..3 {
        stop(&mut a, line);
    }
    lose_ack.store(true, Ordering::SeqCst);
    stop(&mut a, 3); // stored, but the writer hears it was not: spooled too
    let spool = a.spool_path().expect("spooling").to_path_buf();
    assert!(spool.starts_with(dir.path()) && spool.exists());
    assert!(notices.lock().unwrap()[0].contains(&spool.display().to_string()), "{notices:?}");
    down.store(true, Ordering::SeqCst);
    for line in 4..8 {
        stop(&mut a, line);
    }
    assert!(a.spool_path().is_some());
    down.store(false, Ordering::SeqCst);
    for line in 8..10 {
        stop(&mut a, line);
    }
    assert!(a.spool_path().is_none(), "sent once the database is back");
    assert!(!spool.exists());
    assert!(notices.lock().unwrap()[1].contains("is back"), "{notices:?}");
    a.finish("SUCCESS", None, &now_utc()).unwrap();
    let mut t = Trail::open(&sqlite(&path)).unwrap();
    let counts = t.counts(1).unwrap();
    assert_eq!(counts.iter().find(|c| c.0 == "stops").unwrap().1, 10);
    assert_eq!(counts.iter().find(|c| c.0 == "blocks").unwrap().1, 10);
    let recs = t.records(1).unwrap();
    let lines: Vec<i64> = recs
        .iter()
        .filter(|r| r.table == "stops")
        .map(|r| r.get("line").unwrap().as_i64().unwrap())
        .collect();
    assert_eq!(lines, (0..10).collect::<Vec<_>>(), "in order");
    let v = t.verify().unwrap();
    assert!(v.first_broken.is_none(), "{v:?}");
    assert_eq!(v.records, 1 + 20 + 1);
}

/// The run ends while the database is still away: the error names the spool; `push_spool`
/// sends it later, once.
#[test]
fn a_run_ending_during_an_outage_leaves_a_spool_to_push() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.sqlite");
    let down = Arc::new(AtomicBool::new(false));
    let flaky = Flaky {
        inner: sqlite(&path).connect(true).unwrap(),
        down: down.clone(),
        lose_ack: Arc::new(AtomicBool::new(false)),
    };
    let mut a =
        Audit::open_backend(Box::new(flaky), path.display().to_string(), "p.nc", None, &now_utc()).unwrap();
    a.set_notify(|_| {});
    a.set_spool_dir(dir.path());
    a.set_retry(Duration::from_millis(50), Duration::from_millis(200));
    stop(&mut a, 0);
    down.store(true, Ordering::SeqCst);
    stop(&mut a, 1);
    let e = a.finish("SUCCESS", None, &now_utc()).expect_err("unsent");
    let AuditError::Unsent { spool, records, .. } = &e else { panic!("{e}") };
    assert_eq!(*records, 3, "block, stop, end");
    assert!(!e.is_usage());
    let spool = PathBuf::from(spool);
    assert!(spool.exists());
    drop(a);
    let (_, sent) = push_spool(&spool, None).unwrap();
    assert_eq!(sent, 3);
    assert!(!spool.exists());
    let mut t = Trail::open(&sqlite(&path)).unwrap();
    assert_eq!(t.run("1").unwrap().status.as_deref(), Some("SUCCESS"));
    assert!(t.verify().unwrap().first_broken.is_none());
    // A spool that cannot be written stops the run: the commit fails.
    let down = Arc::new(AtomicBool::new(false));
    let flaky = Flaky {
        inner: sqlite(&path).connect(true).unwrap(),
        down: down.clone(),
        lose_ack: Arc::new(AtomicBool::new(false)),
    };
    let mut a =
        Audit::open_backend(Box::new(flaky), path.display().to_string(), "p.nc", None, &now_utc()).unwrap();
    a.set_notify(|_| {});
    a.set_spool_dir(dir.path().join("no/such/dir"));
    down.store(true, Ordering::SeqCst);
    a.record(&Event::Block { line: 1, text: "G1".into(), time_s: 0.0 }).unwrap();
    let e = a.commit().expect_err("cannot keep");
    assert!(e.to_string().contains("cannot be kept"), "{e}");
}

#[test]
fn export_csv_quotes_and_keeps_exact_reals() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.sqlite");
    let mut a = Audit::open(&path, "p, \"q\".nc", &now_utc()).unwrap();
    a.record(&Event::Block { line: 3, text: "G1 X1,5".into(), time_s: 0.1 + 0.2 }).unwrap();
    a.commit().unwrap();
    let mut t = Trail::open(&sqlite(&path)).unwrap();
    let csv = records_csv(&t.records(1).unwrap());
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("seq,table,record_id,prev_hash,hash,id,uid,started_at,program,note,run_id"));
    assert_eq!(lines.len(), 3);
    assert!(lines[1].contains(",\"p, \"\"q\"\".nc\","), "{}", lines[1]);
    assert!(lines[2].contains(",\"G1 X1,5\",0.30000000000000004"), "{}", lines[2]);
}

#[test]
fn addresses_choose_the_backend() {
    assert!(matches!(Db::parse("somac-audit.sqlite").unwrap(), Db::Sqlite(_)));
    assert!(matches!(Db::parse_with("postgresql://c@h:1/d", &|_| None).unwrap(), Db::Postgres(_)));
    let e = Db::parse_with("postgresql://c:pw@h/d", &|_| None).unwrap_err();
    assert!(e.is_usage() && !e.to_string().contains("pw@"), "{e}");
    assert!(Db::parse("mysql://h/d").unwrap_err().is_usage());
}
