//! # truepos-audit — the audit trail in SQLite
//!
//! Every block sent, measurement, correction, alarm, orientation and refractive-index update of
//! an end-point control run, stored in an embedded SQLite database. Events are kept in memory
//! during a measurement stop and written in one transaction at its end ([`AuditSink::commit`]),
//! so a crash loses nothing that was committed and never leaves half a stop, and the write lock
//! is held only for the milliseconds of that transaction.
//!
//! Several runs may share one database at once: a busy timeout makes writers wait for each other,
//! the migrations run in one `BEGIN IMMEDIATE` transaction that re-reads the schema version, and
//! every run row records its start, end and final status ([`SqliteAudit::finish`]). Timestamps
//! are ISO 8601 UTC ([`now_utc`]). A file that is not a truepos audit database (not SQLite, or
//! SQLite with other tables), or one whose schema is newer than this build knows, is refused
//! before anything is written to it: it stays byte for byte as it was.
//!
//! The schema uses only portable SQL (INTEGER, REAL, TEXT; no SQLite-specific types or
//! functions) and numbered migrations in `schema_migrations`, so the same migrations run on
//! PostgreSQL when shared plants need it.
//!
//! Entry points: [`SqliteAudit::open`], [`SqliteAudit::finish`], [`MIGRATIONS`],
//! [`SqliteAudit::count`], [`now_utc`].

use rusqlite::{params, Connection, OpenFlags};
use std::path::Path;
use std::time::Duration;
use thiserror::Error;
use truepos_somac::audit::{AuditSink, Event, SinkError};

#[derive(Debug, Error)]
pub enum AuditError {
    #[error("audit database: {0}")]
    Sql(#[from] rusqlite::Error),
    /// The file is not a truepos audit database; it was not modified.
    #[error("{path} is not a truepos audit database ({why}); it was left unchanged")]
    Foreign { path: String, why: String },
    /// The schema is newer than this build; the file was not modified.
    #[error(
        "{path} has audit schema version {found}, newer than this truepos knows ({known}); it was left \
         unchanged (use a newer truepos)"
    )]
    Newer { path: String, found: i64, known: i64 },
    #[error("timestamp '{0}' is not ISO 8601 UTC (YYYY-MM-DDTHH:MM:SS[.fff]Z)")]
    BadTimestamp(String),
}

/// How long a writer waits for another one before giving up.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(60);

/// The tables the migrations create (a database with any other table is someone else's).
pub const TABLES: &[&str] = &[
    "schema_migrations",
    "runs",
    "blocks",
    "measurements",
    "corrections",
    "alarms",
    "orientations",
    "refractive_index_updates",
    "stops",
];

/// The current time as ISO 8601 UTC with milliseconds, e.g. `2026-11-24T01:02:03.456Z`.
pub fn now_utc() -> String {
    let d = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    iso8601_utc(d.as_secs() as i64, d.subsec_millis())
}

/// `secs` since the Unix epoch as ISO 8601 UTC with milliseconds.
pub fn iso8601_utc(secs: i64, millis: u32) -> String {
    truepos_math::time::UtcDateTime::from_unix(secs).iso8601_millis(millis)
}

/// Whether `s` is ISO 8601 UTC: `YYYY-MM-DDTHH:MM:SS`, optional fraction, `Z`.
pub fn is_iso8601_utc(s: &str) -> bool {
    let b = s.as_bytes();
    let digits = |r: std::ops::Range<usize>| b.get(r).is_some_and(|x| x.iter().all(u8::is_ascii_digit));
    if b.len() < 20 || !b.ends_with(b"Z") {
        return false;
    }
    let fixed = digits(0..4)
        && b[4] == b'-'
        && digits(5..7)
        && b[7] == b'-'
        && digits(8..10)
        && b[10] == b'T'
        && digits(11..13)
        && b[13] == b':'
        && digits(14..16)
        && b[16] == b':'
        && digits(17..19);
    let frac = &b[19..b.len() - 1];
    let frac_ok =
        frac.is_empty() || (frac.len() >= 2 && frac[0] == b'.' && frac[1..].iter().all(u8::is_ascii_digit));
    let n = |r: std::ops::Range<usize>| s[r].parse::<u32>().unwrap_or(99);
    fixed
        && frac_ok
        && (1..=12).contains(&n(5..7))
        && (1..=31).contains(&n(8..10))
        && n(11..13) < 24
        && n(14..16) < 60
        && n(17..19) < 61
}

/// Numbered, portable migrations.
pub const MIGRATIONS: &[(i64, &str)] = &[
    (
        1,
        "CREATE TABLE runs (
        id INTEGER PRIMARY KEY,
        started_at TEXT NOT NULL,
        program TEXT NOT NULL,
        note TEXT
    );
    CREATE TABLE blocks (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        line INTEGER NOT NULL,
        text TEXT NOT NULL,
        time_s REAL NOT NULL
    );
    CREATE TABLE measurements (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        line INTEGER NOT NULL,
        iteration INTEGER NOT NULL,
        commanded_x_mm REAL NOT NULL, commanded_y_mm REAL NOT NULL, commanded_z_mm REAL NOT NULL,
        measured_x_mm REAL NOT NULL, measured_y_mm REAL NOT NULL, measured_z_mm REAL NOT NULL,
        error_mm REAL NOT NULL,
        samples_std_mm REAL NOT NULL,
        time_s REAL NOT NULL
    );
    CREATE TABLE corrections (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        line INTEGER NOT NULL,
        iteration INTEGER NOT NULL,
        dx_mm REAL NOT NULL, dy_mm REAL NOT NULL, dz_mm REAL NOT NULL,
        offset_x_mm REAL NOT NULL, offset_y_mm REAL NOT NULL, offset_z_mm REAL NOT NULL,
        clipped INTEGER NOT NULL,
        time_s REAL NOT NULL
    );
    CREATE TABLE alarms (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        line INTEGER NOT NULL,
        kind TEXT NOT NULL,
        message TEXT NOT NULL,
        action TEXT NOT NULL,
        time_s REAL NOT NULL
    );
    CREATE TABLE orientations (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        line INTEGER NOT NULL,
        reason TEXT NOT NULL,
        scale REAL NOT NULL,
        rms_mm REAL NOT NULL,
        time_s REAL NOT NULL
    );
    CREATE TABLE refractive_index_updates (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        line INTEGER NOT NULL,
        n_old REAL NOT NULL,
        n_new REAL NOT NULL,
        time_s REAL NOT NULL
    );
    CREATE TABLE stops (
        run_id INTEGER NOT NULL REFERENCES runs(id),
        line INTEGER NOT NULL,
        status TEXT NOT NULL,
        final_error_mm REAL,
        iterations INTEGER NOT NULL,
        time_s REAL NOT NULL
    );",
    ),
    (
        2,
        // The controller a run drove (address and version as it reports them).
        "ALTER TABLE runs ADD COLUMN controller TEXT;
         ALTER TABLE runs ADD COLUMN controller_version TEXT;",
    ),
    (
        3,
        // How each run ended: its end time, final status and message.
        "ALTER TABLE runs ADD COLUMN ended_at TEXT;
    ALTER TABLE runs ADD COLUMN status TEXT;
    ALTER TABLE runs ADD COLUMN message TEXT;",
    ),
];

/// An audit trail in a SQLite file.
pub struct SqliteAudit {
    conn: Connection,
    run_id: i64,
    /// Events of the current stop, written at [`AuditSink::commit`].
    pending: Vec<Event>,
    finished: bool,
}

/// Refuse, without writing anything, a file that is not ours or is newer than this build.
fn inspect(path: &Path) -> Result<(), AuditError> {
    let shown = path.display().to_string();
    let foreign = |why: String| AuditError::Foreign { path: shown.clone(), why };
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => return Err(foreign("it is a directory".into())),
        Ok(m) if m.len() == 0 => return Ok(()),
        Ok(_) => {}
        Err(_) => return Ok(()), // created below
    }
    let mut header = [0u8; 16];
    {
        use std::io::Read;
        let mut f = std::fs::File::open(path).map_err(|e| foreign(format!("cannot read it: {e}")))?;
        let n = f.read(&mut header).map_err(|e| foreign(format!("cannot read it: {e}")))?;
        if n < 16 || &header != b"SQLite format 3\0" {
            return Err(foreign("it is not an SQLite database".into()));
        }
    }
    let conn =
        Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX)
            .map_err(|e| foreign(format!("cannot open it read-only: {e}")))?;
    conn.busy_timeout(BUSY_TIMEOUT)?;
    let tables: Vec<String> = {
        let mut st = conn
            .prepare("SELECT name FROM sqlite_master WHERE type = 'table'")
            .map_err(|e| foreign(format!("cannot read its schema: {e}")))?;
        let rows = st.query_map([], |r| r.get::<_, String>(0))?;
        rows.collect::<Result<_, _>>()?
    };
    if tables.is_empty() {
        return Ok(());
    }
    if let Some(t) = tables.iter().find(|t| !TABLES.contains(&t.as_str())) {
        return Err(foreign(format!("it has a table '{t}' that truepos does not create")));
    }
    if !tables.iter().any(|t| t == "schema_migrations") {
        return Err(foreign("it has no schema_migrations table".into()));
    }
    let found: Option<i64> =
        conn.query_row("SELECT MAX(version) FROM schema_migrations", [], |r| r.get(0))?;
    let known = MIGRATIONS.last().map_or(0, |m| m.0);
    if let Some(found) = found.filter(|f| *f > known) {
        return Err(AuditError::Newer { path: shown, found, known });
    }
    Ok(())
}

impl SqliteAudit {
    /// Open (or create) the database, run pending migrations, and start a new run.
    /// `started_at` must be ISO 8601 UTC (see [`now_utc`]).
    pub fn open(path: impl AsRef<Path>, program: &str, started_at: &str) -> Result<Self, AuditError> {
        let path = path.as_ref();
        if !is_iso8601_utc(started_at) {
            return Err(AuditError::BadTimestamp(started_at.into()));
        }
        inspect(path)?;
        let conn = Connection::open(path)?;
        conn.busy_timeout(BUSY_TIMEOUT)?;
        // Write-ahead log: a commit is one append and fsync; a crashed process loses nothing
        // committed, and readers never block the loop. Switching needs a moment alone with the
        // file, which the busy timeout gives.
        retry_busy(|| conn.pragma_update(None, "journal_mode", "WAL"))?;
        conn.pragma_update(None, "synchronous", "FULL")?;
        migrate(&conn, path, started_at)?;
        conn.execute(
            "INSERT INTO runs (started_at, program, status) VALUES (?1, ?2, 'running')",
            params![started_at, program],
        )?;
        let run_id = conn.last_insert_rowid();
        Ok(Self { conn, run_id, pending: Vec::new(), finished: false })
    }

    /// Commit what is pending and record the run's end time and final status (for example
    /// `SUCCESS`, `FAILURE`, `ERROR`) with an optional message.
    pub fn finish(&mut self, status: &str, message: Option<&str>, ended_at: &str) -> Result<(), AuditError> {
        if !is_iso8601_utc(ended_at) {
            return Err(AuditError::BadTimestamp(ended_at.into()));
        }
        self.flush()?;
        self.conn.execute(
            "UPDATE runs SET ended_at = ?1, status = ?2, message = ?3 WHERE id = ?4",
            params![ended_at, status, message, self.run_id],
        )?;
        self.finished = true;
        Ok(())
    }

    /// Record the controller this run drives: its address and version.
    pub fn set_controller(&mut self, address: &str, version: &str) -> Result<(), AuditError> {
        self.conn.execute(
            "UPDATE runs SET controller = ?1, controller_version = ?2 WHERE id = ?3",
            params![address, version, self.run_id],
        )?;
        Ok(())
    }

    /// The controller recorded for this run (address, version).
    pub fn controller(&self) -> Result<(Option<String>, Option<String>), AuditError> {
        Ok(self.conn.query_row(
            "SELECT controller, controller_version FROM runs WHERE id = ?1",
            params![self.run_id],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )?)
    }

    /// Whether [`SqliteAudit::finish`] has been called.
    pub fn is_finished(&self) -> bool {
        self.finished
    }

    pub fn run_id(&self) -> i64 {
        self.run_id
    }

    /// Committed rows of `table` for this run.
    pub fn count(&self, table: &str) -> Result<i64, AuditError> {
        let allowed = [
            "blocks",
            "measurements",
            "corrections",
            "alarms",
            "orientations",
            "refractive_index_updates",
            "stops",
        ];
        let t = allowed.iter().find(|a| **a == table).copied().unwrap_or("stops");
        Ok(self.conn.query_row(
            &format!("SELECT COUNT(*) FROM {t} WHERE run_id = ?1"),
            params![self.run_id],
            |r| r.get(0),
        )?)
    }

    /// Write the pending events in one immediate transaction.
    fn flush(&mut self) -> Result<(), rusqlite::Error> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let events = std::mem::take(&mut self.pending);
        retry_busy(|| self.conn.execute_batch("BEGIN IMMEDIATE"))?;
        let r = events.iter().try_for_each(|e| self.insert(e));
        match r {
            Ok(()) => self.conn.execute_batch("COMMIT"),
            Err(e) => {
                let _ = self.conn.execute_batch("ROLLBACK");
                Err(e)
            }
        }
    }

    fn insert(&self, e: &Event) -> Result<(), rusqlite::Error> {
        let id = self.run_id;
        match e {
            Event::Block { line, text, time_s } => {
                self.conn.execute(
                    "INSERT INTO blocks VALUES (?1, ?2, ?3, ?4)",
                    params![id, *line as i64, text, time_s],
                )?;
            }
            Event::Measurement {
                line,
                iteration,
                commanded_mm: c,
                measured_mm: m,
                error_mm,
                samples_std_mm,
                time_s,
            } => {
                self.conn.execute(
                    "INSERT INTO measurements VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
                    params![
                        id,
                        *line as i64,
                        *iteration as i64,
                        c.x,
                        c.y,
                        c.z,
                        m.x,
                        m.y,
                        m.z,
                        error_mm,
                        samples_std_mm,
                        time_s
                    ],
                )?;
            }
            Event::Correction { line, iteration, delta_mm: d, offset_mm: o, clipped, time_s } => {
                self.conn.execute(
                    "INSERT INTO corrections VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
                    params![
                        id,
                        *line as i64,
                        *iteration as i64,
                        d.x,
                        d.y,
                        d.z,
                        o.x,
                        o.y,
                        o.z,
                        *clipped as i64,
                        time_s
                    ],
                )?;
            }
            Event::Alarm { line, kind, message, action, time_s } => {
                self.conn.execute(
                    "INSERT INTO alarms VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                    params![id, *line as i64, kind.as_str(), message, action, time_s],
                )?;
            }
            Event::Orientation { line, reason, scale, rms_mm, time_s } => {
                self.conn.execute(
                    "INSERT INTO orientations VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                    params![id, *line as i64, reason, scale, rms_mm, time_s],
                )?;
            }
            Event::RefractiveIndex { line, old, new, time_s } => {
                self.conn.execute(
                    "INSERT INTO refractive_index_updates VALUES (?1, ?2, ?3, ?4, ?5)",
                    params![id, *line as i64, old, new, time_s],
                )?;
            }
            Event::StopResult { line, status, final_error_mm, iterations, time_s } => {
                let fe = final_error_mm.is_finite().then_some(*final_error_mm);
                self.conn.execute(
                    "INSERT INTO stops VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                    params![id, *line as i64, status, fe, *iterations as i64, time_s],
                )?;
            }
        }
        Ok(())
    }
}

impl AuditSink for SqliteAudit {
    fn record(&mut self, event: &Event) -> Result<(), SinkError> {
        self.pending.push(event.clone());
        Ok(())
    }

    fn commit(&mut self) -> Result<(), SinkError> {
        Ok(self.flush()?)
    }
}

/// Retry `f` while the database is busy (some lock upgrades report busy without waiting in the
/// busy handler), up to [`BUSY_TIMEOUT`].
fn retry_busy<T>(mut f: impl FnMut() -> Result<T, rusqlite::Error>) -> Result<T, rusqlite::Error> {
    let t0 = std::time::Instant::now();
    loop {
        match f() {
            Err(rusqlite::Error::SqliteFailure(e, _))
                if matches!(
                    e.code,
                    rusqlite::ErrorCode::DatabaseBusy | rusqlite::ErrorCode::DatabaseLocked
                ) && t0.elapsed() < BUSY_TIMEOUT =>
            {
                std::thread::sleep(Duration::from_millis(5));
            }
            r => return r,
        }
    }
}

/// Run the pending migrations in one immediate transaction (so concurrent openers apply each
/// exactly once), refusing a schema newer than this build.
fn migrate(conn: &Connection, path: &Path, applied_at: &str) -> Result<(), AuditError> {
    retry_busy(|| conn.execute_batch("BEGIN IMMEDIATE"))?;
    let r = (|| -> Result<(), AuditError> {
        conn.execute_batch(
            "CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL);",
        )?;
        let found: Option<i64> =
            conn.query_row("SELECT MAX(version) FROM schema_migrations", [], |r| r.get(0))?;
        let found = found.unwrap_or(0);
        let known = MIGRATIONS.last().map_or(0, |m| m.0);
        if found > known {
            return Err(AuditError::Newer { path: path.display().to_string(), found, known });
        }
        for (v, sql) in MIGRATIONS.iter().filter(|m| m.0 > found) {
            conn.execute_batch(sql)?;
            conn.execute(
                "INSERT INTO schema_migrations (version, applied_at) VALUES (?1, ?2)",
                params![v, applied_at],
            )?;
        }
        Ok(())
    })();
    match r {
        Ok(()) => {
            conn.execute_batch("COMMIT")?;
            Ok(())
        }
        Err(e) => {
            let _ = conn.execute_batch("ROLLBACK");
            Err(e)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_somac::audit::Event;

    #[test]
    fn committed_events_survive_a_crash_uncommitted_do_not() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("audit.sqlite");
        {
            let mut a = SqliteAudit::open(&path, "spar.nc", "2026-11-22T00:00:00Z").unwrap();
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
            // Closed without commit, as when the process dies in the middle of a stop: SQLite
            // rolls the open transaction back.
            drop(a);
        }
        let a = SqliteAudit::open(&path, "spar.nc", "2026-11-22T00:01:00Z").unwrap();
        let conn = &a.conn;
        let blocks: i64 = conn.query_row("SELECT COUNT(*) FROM blocks", [], |r| r.get(0)).unwrap();
        let alarms: i64 = conn.query_row("SELECT COUNT(*) FROM alarms", [], |r| r.get(0)).unwrap();
        assert_eq!((blocks, alarms), (1, 1));
        // Migrations ran once; the second open started run 2.
        let migs: i64 = conn.query_row("SELECT COUNT(*) FROM schema_migrations", [], |r| r.get(0)).unwrap();
        assert_eq!(migs, MIGRATIONS.len() as i64);
        assert_eq!(a.run_id(), 2);
        // The controller of a run (migration 2).
        let mut a = a;
        assert_eq!(a.controller().unwrap(), (None, None));
        a.set_controller("linuxcncrsh://127.0.0.1:5007", "LinuxCNC 2.9.0").unwrap();
        assert_eq!(
            a.controller().unwrap(),
            (Some("linuxcncrsh://127.0.0.1:5007".to_string()), Some("LinuxCNC 2.9.0".to_string()))
        );
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

    fn stop(a: &mut SqliteAudit, line: usize) {
        a.record(&Event::Block { line, text: format!("G1 X{line}"), time_s: line as f64 }).unwrap();
        a.record(&Event::StopResult {
            line,
            status: "SUCCESS".into(),
            final_error_mm: 0.01,
            iterations: 1,
            time_s: line as f64,
        })
        .unwrap();
        a.commit().unwrap();
    }

    /// Eight runs at once on one new database: every run opens (one applies the migrations, the
    /// others see them), writes all its stops, and records its end and status.
    #[test]
    fn eight_concurrent_runs_all_complete() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shared.sqlite");
        let barrier = std::sync::Arc::new(std::sync::Barrier::new(8));
        let handles: Vec<_> = (0..8)
            .map(|k| {
                let path = path.clone();
                let barrier = barrier.clone();
                std::thread::spawn(move || -> Result<i64, String> {
                    barrier.wait();
                    let mut a = SqliteAudit::open(&path, &format!("p{k}.nc"), &now_utc())
                        .map_err(|e| e.to_string())?;
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
        let started: String =
            c.query_row("SELECT started_at FROM runs WHERE id = 1", [], |r| r.get(0)).unwrap();
        assert!(is_iso8601_utc(&started), "{started}");
    }

    /// Foreign files and newer schemas are refused before anything is written.
    #[test]
    fn foreign_and_newer_databases_are_left_byte_identical() {
        let dir = tempfile::tempdir().unwrap();
        let text = dir.path().join("notes.sqlite");
        std::fs::write(&text, "not a database\n").unwrap();
        let foreign = dir.path().join("parts.sqlite");
        {
            let c = Connection::open(&foreign).unwrap();
            c.execute_batch(
                "CREATE TABLE parts (id INTEGER, name TEXT); INSERT INTO parts VALUES (1, 'spar');",
            )
            .unwrap();
        }
        let rails = dir.path().join("rails.sqlite");
        {
            let c = Connection::open(&rails).unwrap();
            c.execute_batch(
                "CREATE TABLE schema_migrations (version TEXT); CREATE TABLE users (id INTEGER);",
            )
            .unwrap();
        }
        let newer = dir.path().join("newer.sqlite");
        {
            let mut a = SqliteAudit::open(&newer, "p.nc", &now_utc()).unwrap();
            a.finish("SUCCESS", None, &now_utc()).unwrap();
            a.conn.execute("INSERT INTO schema_migrations VALUES (99, '2030-01-01T00:00:00Z')", []).unwrap();
        }
        for (p, what) in
            [(&text, "not an SQLite"), (&foreign, "parts"), (&rails, "users"), (&newer, "version 99")]
        {
            let before = std::fs::read(p).unwrap();
            let e = SqliteAudit::open(p, "p.nc", &now_utc()).err().expect("refused");
            assert!(e.to_string().contains(what), "{e}");
            assert_eq!(std::fs::read(p).unwrap(), before, "{}", p.display());
        }
        // A directory is refused too; a bad timestamp is refused before the file is touched.
        assert!(SqliteAudit::open(dir.path(), "p.nc", &now_utc()).is_err());
        let fresh = dir.path().join("fresh.sqlite");
        assert!(matches!(
            SqliteAudit::open(&fresh, "p.nc", "SystemTime { tv_sec: 1 }"),
            Err(AuditError::BadTimestamp(_))
        ));
        assert!(!fresh.exists());
    }

    /// A version-1 database gains the run end and status columns; its old rows stay.
    #[test]
    fn version_1_database_is_migrated() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v1.sqlite");
        {
            let c = Connection::open(&path).unwrap();
            c.execute_batch(
                "CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL);",
            )
            .unwrap();
            c.execute_batch(MIGRATIONS[0].1).unwrap();
            c.execute("INSERT INTO schema_migrations VALUES (1, '2026-01-01T00:00:00Z')", []).unwrap();
            c.execute("INSERT INTO runs (started_at, program) VALUES ('2026-01-01T00:00:00Z', 'old.nc')", [])
                .unwrap();
        }
        let mut a = SqliteAudit::open(&path, "new.nc", &now_utc()).unwrap();
        assert_eq!(a.run_id(), 2);
        a.finish("FAILURE", Some("alarm"), &now_utc()).unwrap();
        let st: String = a.conn.query_row("SELECT status FROM runs WHERE id = 2", [], |r| r.get(0)).unwrap();
        assert_eq!(st, "FAILURE");
    }
}
