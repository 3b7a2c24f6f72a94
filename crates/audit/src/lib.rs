//! # truepos-audit — the audit trail, in SQLite or a shared PostgreSQL
//!
//! Every block sent, measurement, correction, alarm, orientation, refractive-index update and
//! hole inspection of a run, and the run's start, controller and end, stored as records in one
//! database: a SQLite file ([`Db::Sqlite`], the default, no server) or PostgreSQL
//! ([`Db::Postgres`], `postgresql://USER@HOST:PORT/DB`, for a fleet of cells sharing one trail).
//! The record logic is written once over a small [`backend::Backend`] trait; both databases
//! get the same schema ([`schema`]), the same records and the same hashes.
//!
//! * **Transactions.** Events are kept in memory during a measurement stop and appended in one
//!   exclusive transaction at its end ([`AuditSink::commit`]): a crash loses nothing committed
//!   and never leaves half a stop. Many writers (processes, cells) share a database; they take
//!   turns at the chain's head.
//! * **Hash chain.** Every record carries `prev_hash` and `hash` (SHA-256 over its canonical
//!   content, [`chain`]); [`Trail::verify`] names the first changed, inserted or deleted record.
//! * **Schema.** Created and migrated forward on first use ([`schema::migrate`]); a database with
//!   tables truepos does not create, or a newer schema, is refused and left unchanged.
//! * **Outages.** When the connection is lost, batches go to a local SQLite spool ([`spool`],
//!   its path announced through the notice callback) and are sent, in order and exactly once
//!   (writer-chosen record ids), when the database is back; a spool that cannot be written stops
//!   the run (the error reaches the loop). [`Audit::finish`] waits a while for the database and
//!   otherwise reports the spool to send later (`truepos audit push`).
//! * **Least privilege.** Writing needs only INSERT and SELECT (no UPDATE, DELETE or DDL once the
//!   owner has created the schema): the run rows are append-only and `runs` is a view.
//!
//! Entry points: [`Db::parse`], [`Audit::open`] (a run: an [`AuditSink`]), [`Audit::finish`],
//! [`Trail::open`] (list, show, export, verify), [`push_spool`], [`now_utc`].

#![forbid(unsafe_code)]

pub mod backend;
pub mod chain;
pub mod pg;
pub mod pg_tls;
pub mod schema;
pub mod spool;
pub mod sqlite;

pub use backend::{BackendError, Value};
pub use chain::{Break, Stored, Verification};
pub use schema::{MIGRATIONS, TABLES};
pub use sqlite::BUSY_TIMEOUT;

use backend::{exclusive, Backend};
use chain::Record;
use pg::{PgBackend, PgTarget};
use schema::{spec, SPECS};
use spool::Spool;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use thiserror::Error;
use truepos_somac::audit::{AuditSink, Event, SinkError};

/// Why the audit trail cannot be opened, written or read.
#[derive(Debug, Error)]
pub enum AuditError {
    /// The database failed (or could not be reached).
    #[error("audit trail {db}: {source}")]
    Db {
        /// The trail's address.
        db: String,
        /// The database's error.
        #[source]
        source: BackendError,
    },
    /// The database is not a truepos audit database; it was not modified.
    #[error("{path} is not a truepos audit database ({why}); it was left unchanged")]
    Foreign {
        /// The database's address.
        path: String,
        /// Why it is not an audit database.
        why: String,
    },
    /// The SQLite path is not a regular file (a FIFO, a device, a socket); nothing was opened.
    #[error("{path}: cannot be an audit trail: it is {kind}; an audit trail is an SQLite database in a regular file (give a file path)")]
    NotRegular {
        /// The path given.
        path: String,
        /// What is there ("a FIFO (named pipe)", "a character device", …).
        kind: &'static str,
    },
    /// The schema is newer than this build; the database was not modified.
    #[error(
        "{path} has audit schema version {found}, newer than this truepos knows ({known}); it was left \
         unchanged (use a newer truepos)"
    )]
    Newer {
        /// The database's address.
        path: String,
        /// Its schema version.
        found: i64,
        /// The newest version this build knows.
        known: i64,
    },
    /// A timestamp that is not ISO 8601 UTC (the text given).
    #[error("timestamp '{0}' is not ISO 8601 UTC (YYYY-MM-DDTHH:MM:SS[.fff]Z)")]
    BadTimestamp(String),
    /// A `--db` value that is not a usable address (never contains a password).
    #[error("--db: {0}")]
    Address(String),
    /// Reading a trail (or spool) that does not exist.
    #[error("no audit trail at {0}")]
    Missing(String),
    /// The database has no run with that id or uid.
    #[error("audit trail {db}: no run '{run}' (give its id or uid, see `truepos audit list`)")]
    NoSuchRun {
        /// The trail's address.
        db: String,
        /// The run asked for.
        run: String,
    },
    /// The local spool could not keep records: the run must stop.
    #[error("audit spool: {0}; the records of this stop cannot be kept")]
    Spool(String),
    /// The run ended while the database was away: its last records are in the spool.
    #[error(
        "audit trail {db} is unreachable; {records} records of this run are kept in {spool}: send them \
         with `truepos audit push {spool}` when it is back"
    )]
    Unsent {
        /// The trail's address.
        db: String,
        /// The spool file holding the records.
        spool: String,
        /// Number of records in the spool.
        records: i64,
    },
}

impl AuditError {
    pub(crate) fn db(db: impl std::fmt::Display, source: BackendError) -> AuditError {
        AuditError::Db { db: db.to_string(), source }
    }

    /// Bad usage or input (exit 2); everything else is a failure of the trail (exit 3).
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            AuditError::Foreign { .. }
                | AuditError::NotRegular { .. }
                | AuditError::Newer { .. }
                | AuditError::BadTimestamp(_)
                | AuditError::Address(_)
                | AuditError::Missing(_)
                | AuditError::NoSuchRun { .. }
        )
    }
}

/// Where the trail is.
#[derive(Debug, Clone)]
pub enum Db {
    /// A SQLite file.
    Sqlite(PathBuf),
    /// A PostgreSQL database.
    Postgres(PgTarget),
}

impl From<&Path> for Db {
    fn from(p: &Path) -> Db {
        Db::Sqlite(p.to_path_buf())
    }
}

impl From<PathBuf> for Db {
    fn from(p: PathBuf) -> Db {
        Db::Sqlite(p)
    }
}

impl From<&PathBuf> for Db {
    fn from(p: &PathBuf) -> Db {
        Db::Sqlite(p.clone())
    }
}

impl From<&Db> for Db {
    fn from(d: &Db) -> Db {
        d.clone()
    }
}

impl Db {
    /// `postgresql://…` (or `postgres://…`) is PostgreSQL, its password from `PGPASSWORD` or
    /// `~/.pgpass`; anything else is a SQLite file path.
    pub fn parse(s: &str) -> Result<Db, AuditError> {
        Db::parse_with(s, &|k| std::env::var(k).ok())
    }

    /// [`Db::parse`] with the environment given (tests).
    pub fn parse_with(s: &str, env: &dyn Fn(&str) -> Option<String>) -> Result<Db, AuditError> {
        if s.starts_with("postgresql://") || s.starts_with("postgres://") {
            return PgTarget::parse(s, env).map(Db::Postgres).map_err(AuditError::Address);
        }
        if let Some((scheme, _)) = s.split_once("://") {
            if !scheme.is_empty() && scheme.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c)) {
                return Err(AuditError::Address(format!(
                    "'{scheme}://' is not a supported database (a SQLite file path or postgresql://USER@HOST:PORT/DB)"
                )));
            }
        }
        if s.is_empty() {
            return Err(AuditError::Address("empty".into()));
        }
        Ok(Db::Sqlite(PathBuf::from(s)))
    }

    /// The database as shown in messages (never a password).
    pub fn display(&self) -> String {
        match self {
            Db::Sqlite(p) => p.display().to_string(),
            Db::Postgres(t) => t.display(),
        }
    }

    /// Connect (a SQLite file is created when `create`; otherwise it must exist).
    pub fn connect(&self, create: bool) -> Result<Box<dyn Backend>, AuditError> {
        Ok(match self {
            Db::Sqlite(p) => Box::new(sqlite::SqliteBackend::open(p, create)?),
            Db::Postgres(t) => Box::new(PgBackend::connect(t).map_err(|e| AuditError::db(t.display(), e))?),
        })
    }
}

/// A fresh run uid: 32 hex digits from the time, process, a counter and the address space.
fn new_uid() -> String {
    use sha2::{Digest, Sha256};
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    let local = 0u8;
    let mut h = Sha256::new();
    h.update(t.as_nanos().to_le_bytes());
    h.update(std::process::id().to_le_bytes());
    h.update(COUNTER.fetch_add(1, Ordering::Relaxed).to_le_bytes());
    h.update((&local as *const u8 as usize).to_le_bytes());
    h.update(format!("{:?}", std::thread::current().id()).as_bytes());
    if let Ok(host) = std::fs::read_to_string("/proc/sys/kernel/hostname") {
        h.update(host.as_bytes());
    }
    h.finalize().iter().take(16).map(|b| format!("{b:02x}")).collect()
}

/// One run's writer: an [`AuditSink`] whose stops are appended to the chain at each commit.
pub struct Audit {
    backend: Box<dyn Backend>,
    shown: String,
    run_id: i64,
    uid: String,
    next: u64,
    /// Records of the current stop, appended at [`AuditSink::commit`].
    pending: Vec<Record>,
    spool: Option<Spool>,
    spool_dir: PathBuf,
    last_try: Option<Instant>,
    retry_every: Duration,
    finish_wait: Duration,
    finished: bool,
    notify: Box<dyn FnMut(&str) + Send>,
}

/// Seconds from an environment variable.
fn env_secs(name: &str, default: f64) -> Duration {
    let s =
        std::env::var(name).ok().and_then(|v| v.parse::<f64>().ok()).filter(|s| s.is_finite() && *s >= 0.0);
    Duration::from_secs_f64(s.unwrap_or(default))
}

impl Audit {
    /// Open (or create) the trail, run pending migrations, and start a new run (its start
    /// record is in the chain when this returns). `started_at` must be ISO 8601 UTC
    /// ([`now_utc`]). A database that cannot be reached now is an error: no run starts
    /// without its trail.
    ///
    /// Spool directory: `TRUEPOS_AUDIT_SPOOL_DIR` (default the current directory); retry
    /// period while spooling: `TRUEPOS_AUDIT_RETRY_S` (default 5 s); how long
    /// [`Audit::finish`] waits for the database: `TRUEPOS_AUDIT_WAIT_S` (default 60 s).
    pub fn open(db: impl Into<Db>, program: &str, started_at: &str) -> Result<Self, AuditError> {
        Self::open_noted(db, program, None, started_at)
    }

    /// [`Audit::open`] with a note on the run (e.g. `somac inspect`: what kind of run it is).
    pub fn open_noted(
        db: impl Into<Db>,
        program: &str,
        note: Option<&str>,
        started_at: &str,
    ) -> Result<Self, AuditError> {
        let db = db.into();
        if !is_iso8601_utc(started_at) {
            return Err(AuditError::BadTimestamp(started_at.into()));
        }
        let shown = db.display();
        let backend = db.connect(true)?;
        Self::open_backend(backend, shown, program, note, started_at)
    }

    /// [`Audit::open`] on a backend already connected.
    pub fn open_backend(
        mut backend: Box<dyn Backend>,
        shown: String,
        program: &str,
        note: Option<&str>,
        started_at: &str,
    ) -> Result<Self, AuditError> {
        if !is_iso8601_utc(started_at) {
            return Err(AuditError::BadTimestamp(started_at.into()));
        }
        schema::migrate(backend.as_mut(), &shown, started_at)?;
        let uid = new_uid();
        let run_id = exclusive(backend.as_mut(), |b| -> Result<i64, BackendError> {
            let rows = b.query("SELECT COALESCE(MAX(id), 0) + 1 FROM run_starts", &[])?;
            let id = rows.first().and_then(|r| r.first()).and_then(Value::as_i64).unwrap_or(1);
            let start = Record {
                table: "run_starts",
                record_id: format!("{uid}-0"),
                values: vec![
                    Value::Int(id),
                    Value::text(&uid),
                    Value::text(started_at),
                    Value::text(program),
                    Value::opt_text(note),
                ],
            };
            chain::append_in(b, &[start])?;
            Ok(id)
        })
        .map_err(|e| AuditError::db(&shown, e))?;
        Ok(Audit {
            backend,
            shown,
            run_id,
            uid,
            next: 1,
            pending: Vec::new(),
            spool: None,
            spool_dir: std::env::var_os("TRUEPOS_AUDIT_SPOOL_DIR")
                .map_or_else(|| PathBuf::from("."), PathBuf::from),
            last_try: None,
            retry_every: env_secs("TRUEPOS_AUDIT_RETRY_S", 5.0),
            finish_wait: env_secs("TRUEPOS_AUDIT_WAIT_S", 60.0),
            finished: false,
            notify: Box::new(|m| eprintln!("{m}")),
        })
    }

    /// Where spool files go (default: `TRUEPOS_AUDIT_SPOOL_DIR` or the current directory).
    pub fn set_spool_dir(&mut self, dir: impl Into<PathBuf>) {
        self.spool_dir = dir.into();
    }

    /// How often to try the database again while spooling, and how long [`Audit::finish`]
    /// waits for it.
    pub fn set_retry(&mut self, every: Duration, finish_wait: Duration) {
        self.retry_every = every;
        self.finish_wait = finish_wait;
    }

    /// Where notices go (spool started, spool sent); default stderr.
    pub fn set_notify(&mut self, f: impl FnMut(&str) + Send + 'static) {
        self.notify = Box::new(f);
    }

    /// Commit what is pending and record the run's end time and final status (for example
    /// `SUCCESS`, `FAILURE`, `ERROR`, `ABORTED`) with an optional message. When the database
    /// is away, waits for it (see [`Audit::open`]); if it does not come back the records stay in
    /// the spool and [`AuditError::Unsent`] names it.
    pub fn finish(&mut self, status: &str, message: Option<&str>, ended_at: &str) -> Result<(), AuditError> {
        if !is_iso8601_utc(ended_at) {
            return Err(AuditError::BadTimestamp(ended_at.into()));
        }
        let r =
            self.make("run_ends", vec![Value::text(ended_at), Value::text(status), Value::opt_text(message)]);
        self.pending.push(r);
        self.flush()?;
        self.finished = true;
        let t0 = Instant::now();
        while self.spool.is_some() {
            if t0.elapsed() >= self.finish_wait {
                let spool = self.spool.as_ref().expect("checked");
                return Err(AuditError::Unsent {
                    db: self.shown.clone(),
                    spool: spool.path().display().to_string(),
                    records: spool.records().unwrap_or(-1),
                });
            }
            std::thread::sleep(self.retry_every.min(Duration::from_millis(500)));
            self.try_drain(true)?;
        }
        Ok(())
    }

    /// Record the controller this run drives: its address and version.
    pub fn set_controller(&mut self, address: &str, version: &str) -> Result<(), AuditError> {
        let r = self.make(
            "run_controllers",
            vec![Value::text(address), Value::text(version), Value::text(now_utc())],
        );
        self.pending.push(r);
        self.flush()
    }

    /// Record one inspected hole (`somac inspect`); stored at the next commit.
    pub fn record_inspection(&mut self, h: &truepos_somac::inspect::HoleResult) {
        let n = &h.hole.nominal_mm;
        let m = &h.measured_mm;
        let v = vec![
            Value::text(&h.hole.id),
            h.hole.line.map_or(Value::Null, |l| Value::Int(l as i64)),
            Value::real(n.x),
            Value::real(n.y),
            Value::real(n.z),
            Value::real(m.x),
            Value::real(m.y),
            Value::real(m.z),
            Value::real(h.error_xy_mm[0]),
            Value::real(h.error_xy_mm[1]),
            Value::real(h.position_error_mm),
            Value::real(h.hole.diameter_mm),
            Value::real(h.diameter_mm),
            Value::real(h.diameter_error_mm),
            Value::real(h.roundness_mm),
            Value::Int(h.points.len() as i64),
            Value::real(h.elapsed_s),
        ];
        let r = self.make("inspections", v);
        self.pending.push(r);
    }

    /// Record one reported quantity (`results`): stored at the next commit.
    pub fn record_result(&mut self, r: &ResultRecord) {
        let opt = |v: Option<f64>| v.map_or(Value::Null, Value::real);
        let v = vec![
            r.line.map_or(Value::Null, |l| Value::Int(l as i64)),
            Value::text(&r.kind),
            Value::text(&r.label),
            Value::opt_text(r.feature.as_deref()),
            Value::text(&r.quantity),
            Value::real(r.value),
            Value::text(&r.unit),
            opt(r.expanded_uncertainty),
            opt(r.limits.map(|l| l.0)),
            opt(r.limits.map(|l| l.1)),
            Value::opt_text(r.verdict.as_deref()),
        ];
        let rec = self.make("results", v);
        self.pending.push(rec);
    }

    /// The controller recorded for this run (address, version).
    pub fn controller(&mut self) -> Result<(Option<String>, Option<String>), AuditError> {
        let rows = self
            .backend
            .query(
                "SELECT controller, controller_version FROM runs WHERE id = $1",
                &[Value::Int(self.run_id)],
            )
            .map_err(|e| AuditError::db(&self.shown, e))?;
        let row = rows.into_iter().next().unwrap_or_default();
        let s = |i: usize| row.get(i).and_then(Value::as_str).map(str::to_string);
        Ok((s(0), s(1)))
    }

    /// Whether [`Audit::finish`] has been called.
    pub fn is_finished(&self) -> bool {
        self.finished
    }

    /// The run's id (its row in `runs`).
    pub fn run_id(&self) -> i64 {
        self.run_id
    }

    /// The run's unique id (its records' ids start with it).
    pub fn uid(&self) -> &str {
        &self.uid
    }

    /// The spool file, while records wait in it.
    pub fn spool_path(&self) -> Option<&Path> {
        self.spool.as_ref().map(|s| s.path())
    }

    /// Committed rows of `table` for this run (a record table name).
    pub fn count(&mut self, table: &str) -> Result<i64, AuditError> {
        let t = spec(table).filter(|s| s.table != "run_starts").map_or("stops", |s| s.table);
        let rows = self
            .backend
            .query(&format!("SELECT COUNT(*) FROM {t} WHERE run_id = $1"), &[Value::Int(self.run_id)])
            .map_err(|e| AuditError::db(&self.shown, e))?;
        Ok(rows.first().and_then(|r| r.first()).and_then(Value::as_i64).unwrap_or(0))
    }

    /// A record of this run: run id first, then `values`; the next record id.
    fn make(&mut self, table: &'static str, values: Vec<Value>) -> Record {
        let mut v = Vec::with_capacity(values.len() + 1);
        v.push(Value::Int(self.run_id));
        v.extend(values);
        let record_id = format!("{}-{}", self.uid, self.next);
        self.next += 1;
        Record { table, record_id, values: v }
    }

    /// Append the pending records (one batch); spool them if the database is away. The same as
    /// [`AuditSink::commit`], with this crate's error.
    pub fn flush(&mut self) -> Result<(), AuditError> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let batch = std::mem::take(&mut self.pending);
        if self.spool.is_some() {
            self.try_drain(false)?;
        }
        if let Some(spool) = self.spool.as_mut() {
            return spool.push(&batch);
        }
        match chain::append(self.backend.as_mut(), &batch) {
            Ok(_) => Ok(()),
            Err(e) if e.lost => {
                let name = format!("truepos-audit-spool-{}.sqlite", self.uid);
                let path = std::path::absolute(self.spool_dir.join(name))
                    .map_err(|e| AuditError::Spool(format!("{}: {e}", self.spool_dir.display())))?;
                let mut spool = Spool::create(&path, &self.shown)?;
                spool.push(&batch)?;
                (self.notify)(&format!(
                    "audit trail {} unreachable ({e}); records are kept in {} and sent when it is back",
                    self.shown,
                    path.display()
                ));
                self.spool = Some(spool);
                self.last_try = Some(Instant::now());
                Ok(())
            }
            Err(e) => Err(AuditError::db(&self.shown, e)),
        }
    }

    /// Try to send the spool (at most every `retry_every` unless `force`); remove it when empty.
    fn try_drain(&mut self, force: bool) -> Result<(), AuditError> {
        if !force && self.last_try.is_some_and(|t| t.elapsed() < self.retry_every) {
            return Ok(());
        }
        self.last_try = Some(Instant::now());
        let Some(spool) = self.spool.as_mut() else { return Ok(()) };
        if self.backend.reconnect().is_err() {
            return Ok(());
        }
        match spool.drain(self.backend.as_mut(), &self.shown) {
            Ok(sent) => {
                let spool = self.spool.take().expect("checked");
                let path = spool.path().display().to_string();
                spool.remove()?;
                (self.notify)(&format!(
                    "audit trail {} is back: {sent} spooled records sent, {path} removed",
                    self.shown
                ));
                Ok(())
            }
            Err(AuditError::Db { source, .. }) if source.lost => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn record_event(&mut self, e: &Event) {
        let r = match e {
            Event::Block { line, text, time_s } => {
                self.make("blocks", vec![Value::Int(*line as i64), Value::text(text), Value::real(*time_s)])
            }
            Event::Measurement {
                line,
                iteration,
                commanded_mm: c,
                measured_mm: m,
                error_mm,
                samples_std_mm,
                time_s,
            } => self.make(
                "measurements",
                vec![
                    Value::Int(*line as i64),
                    Value::Int(*iteration as i64),
                    Value::real(c.x),
                    Value::real(c.y),
                    Value::real(c.z),
                    Value::real(m.x),
                    Value::real(m.y),
                    Value::real(m.z),
                    Value::real(*error_mm),
                    Value::real(*samples_std_mm),
                    Value::real(*time_s),
                ],
            ),
            Event::Correction { line, iteration, delta_mm: d, offset_mm: o, clipped, time_s } => self.make(
                "corrections",
                vec![
                    Value::Int(*line as i64),
                    Value::Int(*iteration as i64),
                    Value::real(d.x),
                    Value::real(d.y),
                    Value::real(d.z),
                    Value::real(o.x),
                    Value::real(o.y),
                    Value::real(o.z),
                    Value::Int(*clipped as i64),
                    Value::real(*time_s),
                ],
            ),
            Event::Alarm { line, kind, message, action, time_s } => self.make(
                "alarms",
                vec![
                    Value::Int(*line as i64),
                    Value::text(kind.as_str()),
                    Value::text(message),
                    Value::text(action),
                    Value::real(*time_s),
                ],
            ),
            Event::Orientation { line, reason, scale, rms_mm, time_s } => self.make(
                "orientations",
                vec![
                    Value::Int(*line as i64),
                    Value::text(reason),
                    Value::real(*scale),
                    Value::real(*rms_mm),
                    Value::real(*time_s),
                ],
            ),
            Event::RefractiveIndex { line, old, new, time_s } => self.make(
                "refractive_index_updates",
                vec![Value::Int(*line as i64), Value::real(*old), Value::real(*new), Value::real(*time_s)],
            ),
            Event::StopResult { line, status, final_error_mm, iterations, time_s } => self.make(
                "stops",
                vec![
                    Value::Int(*line as i64),
                    Value::text(status),
                    Value::real(*final_error_mm), // non-finite → NULL? see Value::real
                    Value::Int(*iterations as i64),
                    Value::real(*time_s),
                ],
            ),
        };
        self.pending.push(r);
    }
}

impl AuditSink for Audit {
    fn record(&mut self, event: &Event) -> Result<(), SinkError> {
        self.record_event(event);
        // A deferred SIGINT/SIGTERM stops the run at this event (the caller closes the run as
        // ABORTED and ends the process).
        if let Some(sig) = truepos_io::atomic::interrupted() {
            return Err(format!("interrupted by {}", truepos_io::atomic::signal_name(sig)).into());
        }
        Ok(())
    }

    fn commit(&mut self) -> Result<(), SinkError> {
        Ok(self.flush()?)
    }
}

/// The writer under its former name (SQLite was its only backend).
pub type SqliteAudit = Audit;

/// One reported quantity of a measuring command, as [`Audit::record_result`] stores it in
/// `results`: lengths in mm, angles in rad (the unit is recorded with it).
#[derive(Debug, Clone, PartialEq)]
pub struct ResultRecord {
    /// The program line that produced it, where there is one.
    pub line: Option<usize>,
    /// `feature`, `tolerance` or `parameter`.
    pub kind: String,
    /// The label (DMIS `F(…)`/`T(…)` label, parameter name).
    pub label: String,
    /// For a tolerance: the feature(s) it applies to; for a feature: its type.
    pub feature: Option<String>,
    /// What the value is: `x`, `y`, `z`, `diameter`, `apex_angle`, a tolerance kind, …
    pub quantity: String,
    /// The value, in `unit`.
    pub value: f64,
    /// The unit of `value` (`mm`, `rad`, ...).
    pub unit: String,
    /// U (k = 2), where the command states one.
    pub expanded_uncertainty: Option<f64>,
    /// Lower and upper limit the value is judged against.
    pub limits: Option<(f64, f64)>,
    /// The verdict (`INTOL`, `OUTOL`, `pass`, …).
    pub verdict: Option<String>,
}

/// Send a spool left by a run that ended while the database was away (`truepos audit push`).
/// `db` defaults to the database the spool names. Returns the records sent; the spool file is
/// removed once empty.
pub fn push_spool(path: &Path, db: Option<&Db>) -> Result<(Db, i64), AuditError> {
    let (spool, named) = Spool::open(path)?;
    let db = match db {
        Some(d) => d.clone(),
        None => Db::parse(&named)?,
    };
    let shown = db.display();
    let mut backend = db.connect(false)?;
    schema::migrate(backend.as_mut(), &shown, &now_utc())?;
    let mut spool = spool;
    let sent = spool.drain(backend.as_mut(), &shown)?;
    spool.remove()?;
    Ok((db, sent))
}

/// A run as listed.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    /// The run's row id.
    pub id: i64,
    /// The run's unique id, when the writer gave one.
    pub uid: Option<String>,
    /// The program that ran (command or DMIS file).
    pub program: String,
    /// Start time, ISO 8601 UTC.
    pub started_at: String,
    /// End time, ISO 8601 UTC (`None` while running or after a crash).
    pub ended_at: Option<String>,
    /// Final status (`SUCCESS`, `FAILURE`, `ERROR`, `ABORTED`), when the run ended.
    pub status: Option<String>,
    /// The status message, if any.
    pub message: Option<String>,
    /// The controller the run used, if any.
    pub controller: Option<String>,
    /// The controller's version string, if known.
    pub controller_version: Option<String>,
    /// What kind of run it is (`somac inspect`), when the writer said.
    pub note: Option<String>,
}

impl RunSummary {
    /// The run as a JSON object (`truepos audit list --json`).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "id": self.id, "uid": self.uid, "program": self.program, "started_at": self.started_at,
            "ended_at": self.ended_at, "status": self.status, "message": self.message,
            "controller": self.controller, "controller_version": self.controller_version,
            "note": self.note,
        })
    }
}

/// A trail opened to read: list runs, show or export one, verify the chain.
pub struct Trail {
    backend: Box<dyn Backend>,
    shown: String,
}

const RUN_COLUMNS: &str =
    "id, uid, program, started_at, ended_at, status, message, controller, controller_version, note";

fn summary(r: Vec<Value>) -> RunSummary {
    let s = |i: usize| r.get(i).and_then(Value::as_str).map(str::to_string);
    RunSummary {
        id: r.first().and_then(Value::as_i64).unwrap_or(0),
        uid: s(1),
        program: s(2).unwrap_or_default(),
        started_at: s(3).unwrap_or_default(),
        ended_at: s(4),
        status: s(5),
        message: s(6),
        controller: s(7),
        controller_version: s(8),
        note: s(9),
    }
}

impl Trail {
    /// Open an existing trail (a missing SQLite file is an error) and migrate it forward when
    /// it is older than this build (nothing is written when it is current).
    pub fn open(db: &Db) -> Result<Trail, AuditError> {
        let shown = db.display();
        let mut backend = db.connect(false)?;
        schema::migrate(backend.as_mut(), &shown, &now_utc())?;
        Ok(Trail { backend, shown })
    }

    /// The trail's address for messages (never with a password).
    pub fn display(&self) -> &str {
        &self.shown
    }

    fn err(&self) -> impl Fn(BackendError) -> AuditError + '_ {
        move |e| AuditError::db(&self.shown, e)
    }

    /// Every run, oldest first.
    pub fn runs(&mut self) -> Result<Vec<RunSummary>, AuditError> {
        let rows = self.backend.query(&format!("SELECT {RUN_COLUMNS} FROM runs ORDER BY id"), &[]);
        Ok(rows.map_err(self.err())?.into_iter().map(summary).collect())
    }

    /// One run, by id or uid.
    pub fn run(&mut self, key: &str) -> Result<RunSummary, AuditError> {
        let rows = match key.parse::<i64>() {
            Ok(id) => self
                .backend
                .query(&format!("SELECT {RUN_COLUMNS} FROM runs WHERE id = $1"), &[Value::Int(id)]),
            Err(_) => self
                .backend
                .query(&format!("SELECT {RUN_COLUMNS} FROM runs WHERE uid = $1"), &[Value::text(key)]),
        };
        rows.map_err(self.err())?
            .into_iter()
            .next()
            .map(summary)
            .ok_or_else(|| AuditError::NoSuchRun { db: self.shown.clone(), run: key.to_string() })
    }

    /// Rows per record table for a run (including rows from before the chain).
    pub fn counts(&mut self, run_id: i64) -> Result<Vec<(&'static str, i64)>, AuditError> {
        let mut out = Vec::new();
        for sp in SPECS.iter().filter(|s| s.table != "run_starts") {
            let rows = self
                .backend
                .query(&format!("SELECT COUNT(*) FROM {} WHERE run_id = $1", sp.table), &[Value::Int(run_id)])
                .map_err(self.err())?;
            out.push((sp.table, rows.first().and_then(|r| r.first()).and_then(Value::as_i64).unwrap_or(0)));
        }
        Ok(out)
    }

    /// Every chained record of a run, in chain order.
    pub fn records(&mut self, run_id: i64) -> Result<Vec<Stored>, AuditError> {
        let mut all = Vec::new();
        for sp in SPECS {
            all.extend(chain::read_table(self.backend.as_mut(), sp, Some(run_id)).map_err(self.err())?);
        }
        all.sort_by_key(|r| r.seq);
        Ok(all)
    }

    /// Recompute the whole chain ([`chain::verify`]).
    pub fn verify(&mut self) -> Result<Verification, AuditError> {
        chain::verify(self.backend.as_mut(), None).map_err(self.err())
    }

    /// [`Trail::verify`], and the record at a head kept earlier (`seq`, `hash`) must still be
    /// there unchanged (detects records deleted at the end of the chain).
    pub fn verify_against(&mut self, seq: i64, hash: &str) -> Result<Verification, AuditError> {
        chain::verify(self.backend.as_mut(), Some((seq, hash))).map_err(self.err())
    }
}

/// Records as CSV: `seq,table,record_id,prev_hash,hash` and then every column of every record
/// table (empty where a record has no such column).
pub fn records_csv(records: &[Stored]) -> String {
    let mut cols: Vec<&str> = Vec::new();
    for sp in SPECS {
        for (c, _) in sp.columns {
            if !cols.contains(c) {
                cols.push(c);
            }
        }
    }
    let field = |s: &str| {
        if s.contains([',', '"', '\n', '\r']) {
            format!("\"{}\"", s.replace('"', "\"\""))
        } else {
            s.to_string()
        }
    };
    let mut out = String::from("seq,table,record_id,prev_hash,hash");
    for c in &cols {
        out.push(',');
        out.push_str(c);
    }
    out.push('\n');
    for r in records {
        out.push_str(&format!("{},{},{},{},{}", r.seq, r.table, field(&r.record_id), r.prev_hash, r.hash));
        for c in &cols {
            out.push(',');
            if let Some(v) = r.get(c) {
                out.push_str(&field(&v.to_field()));
            }
        }
        out.push('\n');
    }
    out
}

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

#[cfg(test)]
mod tests;

impl truepos_math::exit::HasExitClass for AuditError {
    /// [`AuditError::is_usage`]: bad usage or input (2); a failure of the trail (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        if self.is_usage() {
            ExitClass::Usage
        } else {
            ExitClass::Device
        }
    }
}
