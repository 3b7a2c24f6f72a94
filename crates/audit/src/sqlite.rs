//! The SQLite [`Backend`]: one file, write-ahead log, `synchronous = FULL`, a busy timeout so
//! that several processes share it. [`inspect`] refuses, before anything is written, a file that
//! is not a truepos audit database or whose schema is newer than this build.

use crate::backend::{Backend, BackendError, Dialect, Value};
use crate::schema::{known_version, TABLES};
use crate::AuditError;
use rusqlite::{Connection, OpenFlags};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How long a writer waits for another one before giving up.
pub const BUSY_TIMEOUT: Duration = Duration::from_secs(60);

/// The audit trail in a SQLite file.
pub struct SqliteBackend {
    conn: Connection,
    path: PathBuf,
}

impl SqliteBackend {
    /// Open (creating it when `create`) after [`inspect`] found nothing foreign.
    pub fn open(path: &Path, create: bool) -> Result<Self, AuditError> {
        if !create && !path.exists() {
            return Err(AuditError::Missing(path.display().to_string()));
        }
        inspect(path)?;
        let conn = Connection::open(path).map_err(|e| AuditError::db(path.display(), e.into()))?;
        let b = Self { conn, path: path.to_path_buf() };
        b.setup().map_err(|e| AuditError::db(path.display(), e))?;
        Ok(b)
    }

    fn setup(&self) -> Result<(), BackendError> {
        self.conn.busy_timeout(BUSY_TIMEOUT)?;
        // Write-ahead log: a commit is one append and fsync; a crashed process loses nothing
        // committed, and readers never block the writers. Switching needs a moment alone with
        // the file, which the busy timeout gives.
        retry_busy(|| self.conn.pragma_update(None, "journal_mode", "WAL"))?;
        self.conn.pragma_update(None, "synchronous", "FULL")?;
        Ok(())
    }

    /// The database file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// `$1, $2, …` → `?1, ?2, …`.
fn sql(s: &str) -> String {
    s.replace('$', "?")
}

fn to_sqlite(v: &Value) -> rusqlite::types::Value {
    match v {
        Value::Null => rusqlite::types::Value::Null,
        Value::Int(i) => rusqlite::types::Value::Integer(*i),
        Value::Real(x) => rusqlite::types::Value::Real(*x),
        Value::Text(s) => rusqlite::types::Value::Text(s.clone()),
    }
}

impl Backend for SqliteBackend {
    fn dialect(&self) -> Dialect {
        Dialect::Sqlite
    }

    fn execute_batch(&mut self, s: &str) -> Result<(), BackendError> {
        Ok(self.conn.execute_batch(s)?)
    }

    fn execute(&mut self, s: &str, params: &[Value]) -> Result<u64, BackendError> {
        let mut st = self.conn.prepare_cached(&sql(s))?;
        let p: Vec<rusqlite::types::Value> = params.iter().map(to_sqlite).collect();
        Ok(st.execute(rusqlite::params_from_iter(p))? as u64)
    }

    fn query(&mut self, s: &str, params: &[Value]) -> Result<Vec<Vec<Value>>, BackendError> {
        let mut st = self.conn.prepare_cached(&sql(s))?;
        let n = st.column_count();
        let p: Vec<rusqlite::types::Value> = params.iter().map(to_sqlite).collect();
        let mut rows = st.query(rusqlite::params_from_iter(p))?;
        let mut out = Vec::new();
        while let Some(r) = rows.next()? {
            let mut row = Vec::with_capacity(n);
            for i in 0..n {
                use rusqlite::types::ValueRef;
                row.push(match r.get_ref(i)? {
                    ValueRef::Null => Value::Null,
                    ValueRef::Integer(i) => Value::Int(i),
                    ValueRef::Real(x) => Value::Real(x),
                    ValueRef::Text(t) => Value::Text(String::from_utf8_lossy(t).into_owned()),
                    ValueRef::Blob(b) => Value::Text(String::from_utf8_lossy(b).into_owned()),
                });
            }
            out.push(row);
        }
        Ok(out)
    }

    fn begin_exclusive(&mut self) -> Result<(), BackendError> {
        Ok(retry_busy(|| self.conn.execute_batch("BEGIN IMMEDIATE"))?)
    }

    fn commit(&mut self) -> Result<(), BackendError> {
        Ok(self.conn.execute_batch("COMMIT")?)
    }

    fn rollback(&mut self) {
        let _ = self.conn.execute_batch("ROLLBACK");
    }

    fn tables(&mut self) -> Result<Vec<String>, BackendError> {
        let rows = self.query("SELECT name FROM sqlite_master WHERE type = 'table'", &[])?;
        Ok(rows.into_iter().filter_map(|r| r.into_iter().next()?.as_str().map(str::to_string)).collect())
    }

    fn reconnect(&mut self) -> Result<(), BackendError> {
        Ok(())
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

/// What a path that is neither a regular file nor a directory is, for messages.
fn kind_of(m: &std::fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let ft = m.file_type();
        if ft.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    let _ = m;
    "not a regular file"
}

/// Refuse, without writing anything, a file that is not ours or is newer than this build, and
/// a path that is not a regular file (a FIFO, a device).
pub fn inspect(path: &Path) -> Result<(), AuditError> {
    let shown = path.display().to_string();
    let foreign = |why: String| AuditError::Foreign { path: shown.clone(), why };
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => return Err(foreign("it is a directory".into())),
        Ok(m) if !m.is_file() => return Err(AuditError::NotRegular { path: shown, kind: kind_of(&m) }),
        Ok(m) if m.len() == 0 => return Ok(()),
        Ok(_) => {}
        Err(_) => return Ok(()), // created by the caller
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
    let dbe = |e: rusqlite::Error| AuditError::db(path.display(), e.into());
    conn.busy_timeout(BUSY_TIMEOUT).map_err(dbe)?;
    let tables: Vec<String> = {
        let mut st = conn
            .prepare("SELECT name FROM sqlite_master WHERE type = 'table'")
            .map_err(|e| foreign(format!("cannot read its schema: {e}")))?;
        let rows = st.query_map([], |r| r.get::<_, String>(0)).map_err(dbe)?;
        rows.collect::<Result<_, _>>().map_err(dbe)?
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
    let found: Option<i64> = conn
        .query_row("SELECT MAX(version) FROM schema_migrations", [], |r| r.get(0))
        .map_err(|e| foreign(format!("its schema_migrations is not truepos's: {e}")))?;
    let known = known_version();
    if let Some(found) = found.filter(|f| *f > known) {
        return Err(AuditError::Newer { path: shown, found, known });
    }
    Ok(())
}
