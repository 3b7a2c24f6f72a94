//! # truepos-audit — the audit trail in SQLite
//!
//! Every block sent, measurement, correction, alarm, orientation and refractive-index update of
//! an end-point control run, stored in an embedded SQLite database. Events are written inside a
//! transaction that is committed at the end of every measurement stop ([`AuditSink::commit`]),
//! so a crash loses nothing that was committed and never leaves half a stop.
//!
//! The schema uses only portable SQL (INTEGER, REAL, TEXT; no SQLite-specific types or
//! functions) and numbered migrations in `schema_migrations`, so the same migrations run on
//! PostgreSQL when shared plants need it.
//!
//! Entry points: [`SqliteAudit::open`], [`MIGRATIONS`], [`SqliteAudit::count`].

use rusqlite::{params, Connection};
use std::path::Path;
use thiserror::Error;
use truepos_somac::audit::{AuditSink, Event, SinkError};

#[derive(Debug, Error)]
pub enum AuditError {
    #[error("audit database: {0}")]
    Sql(#[from] rusqlite::Error),
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
];

/// An audit trail in a SQLite file.
pub struct SqliteAudit {
    conn: Connection,
    run_id: i64,
    in_tx: bool,
}

impl SqliteAudit {
    /// Open (or create) the database, run pending migrations, and start a new run.
    pub fn open(path: impl AsRef<Path>, program: &str, started_at: &str) -> Result<Self, AuditError> {
        let conn = Connection::open(path)?;
        // Write-ahead log: a commit is one append and fsync; a crashed process loses nothing
        // committed, and readers never block the loop.
        conn.pragma_update(None, "journal_mode", "WAL")?;
        conn.pragma_update(None, "synchronous", "FULL")?;
        conn.execute_batch("CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL);")?;
        for (v, sql) in MIGRATIONS {
            let done: i64 = conn.query_row(
                "SELECT COUNT(*) FROM schema_migrations WHERE version = ?1",
                params![v],
                |r| r.get(0),
            )?;
            if done == 0 {
                let tx = conn.unchecked_transaction()?;
                tx.execute_batch(sql)?;
                tx.execute(
                    "INSERT INTO schema_migrations (version, applied_at) VALUES (?1, ?2)",
                    params![v, started_at],
                )?;
                tx.commit()?;
            }
        }
        conn.execute("INSERT INTO runs (started_at, program) VALUES (?1, ?2)", params![started_at, program])?;
        let run_id = conn.last_insert_rowid();
        Ok(Self { conn, run_id, in_tx: false })
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

    pub fn run_id(&self) -> i64 {
        self.run_id
    }

    /// Rows of `table` for this run (committed or not).
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

    fn begin(&mut self) -> Result<(), rusqlite::Error> {
        if !self.in_tx {
            self.conn.execute_batch("BEGIN")?;
            self.in_tx = true;
        }
        Ok(())
    }

    fn insert(&mut self, e: &Event) -> Result<(), rusqlite::Error> {
        self.begin()?;
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
        Ok(self.insert(event)?)
    }

    fn commit(&mut self) -> Result<(), SinkError> {
        if self.in_tx {
            self.conn.execute_batch("COMMIT")?;
            self.in_tx = false;
        }
        Ok(())
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
}
