//! The local spool: batches of records that could not reach the database, kept in a small
//! SQLite file (`synchronous = FULL`: a batch is on disk before the run goes on) until they are
//! sent, in order, each batch once ([`crate::chain::append`] skips a batch already stored).
//! The file names the database it belongs to; `truepos audit push` sends a spool left by a run
//! that ended while the database was still away.

use crate::backend::{Backend, Value};
use crate::chain::{append, Record};
use crate::schema::spec;
use crate::AuditError;
use rusqlite::{params, Connection};
use std::path::{Path, PathBuf};

/// The local spool file of records waiting for the database.
pub struct Spool {
    conn: Connection,
    path: PathBuf,
}

fn enc(v: &Value) -> serde_json::Value {
    match v {
        Value::Null => serde_json::Value::Null,
        Value::Int(i) => serde_json::json!({ "i": i }),
        // Bits, so the value sent is the value hashed, exactly.
        Value::Real(x) => serde_json::json!({ "r": format!("{:016x}", x.to_bits()) }),
        Value::Text(s) => serde_json::Value::String(s.clone()),
    }
}

fn dec(v: &serde_json::Value) -> Option<Value> {
    Some(match v {
        serde_json::Value::Null => Value::Null,
        serde_json::Value::String(s) => Value::Text(s.clone()),
        serde_json::Value::Object(o) => {
            if let Some(i) = o.get("i") {
                Value::Int(i.as_i64()?)
            } else {
                Value::Real(f64::from_bits(u64::from_str_radix(o.get("r")?.as_str()?, 16).ok()?))
            }
        }
        _ => return None,
    })
}

impl Spool {
    /// Create (or reopen) the spool file for the database `db`.
    pub fn create(path: &Path, db: &str) -> Result<Spool, AuditError> {
        let err = |e: rusqlite::Error| AuditError::Spool(format!("{}: {e}", path.display()));
        let conn = Connection::open(path).map_err(err)?;
        conn.pragma_update(None, "synchronous", "FULL").map_err(err)?;
        conn.execute_batch(
            "CREATE TABLE IF NOT EXISTS spool_meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
             CREATE TABLE IF NOT EXISTS spool (batch INTEGER NOT NULL, pos INTEGER NOT NULL,
                 tbl TEXT NOT NULL, record_id TEXT NOT NULL, vals TEXT NOT NULL, PRIMARY KEY (batch, pos));",
        )
        .map_err(err)?;
        conn.execute("INSERT OR IGNORE INTO spool_meta VALUES ('db', ?1)", params![db]).map_err(err)?;
        Ok(Spool { conn, path: path.to_path_buf() })
    }

    /// Open an existing spool file (for `truepos audit push`); returns it and its database.
    pub fn open(path: &Path) -> Result<(Spool, String), AuditError> {
        if !path.is_file() {
            return Err(AuditError::Missing(path.display().to_string()));
        }
        let err = |e: rusqlite::Error| AuditError::Spool(format!("{}: {e}", path.display()));
        let conn = Connection::open(path).map_err(err)?;
        let db: String = conn
            .query_row("SELECT value FROM spool_meta WHERE key = 'db'", [], |r| r.get(0))
            .map_err(|e| AuditError::Foreign {
                path: path.display().to_string(),
                why: format!("not a spool: {e}"),
            })?;
        Ok((Spool { conn, path: path.to_path_buf() }, db))
    }

    /// The spool file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Keep one batch (durably, before returning).
    pub fn push(&mut self, batch: &[Record]) -> Result<(), AuditError> {
        let err = |e: rusqlite::Error| AuditError::Spool(format!("{}: {e}", self.path.display()));
        let tx = self.conn.transaction().map_err(err)?;
        let n: i64 =
            tx.query_row("SELECT COALESCE(MAX(batch), 0) + 1 FROM spool", [], |r| r.get(0)).map_err(err)?;
        for (pos, r) in batch.iter().enumerate() {
            let vals = serde_json::Value::Array(r.values.iter().map(enc).collect()).to_string();
            tx.execute(
                "INSERT INTO spool VALUES (?1, ?2, ?3, ?4, ?5)",
                params![n, pos as i64, r.table, r.record_id, vals],
            )
            .map_err(err)?;
        }
        tx.commit().map_err(err)
    }

    /// Batches waiting.
    pub fn batches(&self) -> Result<i64, AuditError> {
        self.conn
            .query_row("SELECT COUNT(DISTINCT batch) FROM spool", [], |r| r.get(0))
            .map_err(|e| AuditError::Spool(format!("{}: {e}", self.path.display())))
    }

    /// Records waiting.
    pub fn records(&self) -> Result<i64, AuditError> {
        self.conn
            .query_row("SELECT COUNT(*) FROM spool", [], |r| r.get(0))
            .map_err(|e| AuditError::Spool(format!("{}: {e}", self.path.display())))
    }

    fn first_batch(&self) -> Result<Option<(i64, Vec<Record>)>, AuditError> {
        let bad = |why: String| AuditError::Spool(format!("{}: {why}", self.path.display()));
        let err = |e: rusqlite::Error| bad(e.to_string());
        let Some(n) = self
            .conn
            .query_row("SELECT MIN(batch) FROM spool", [], |r| r.get::<_, Option<i64>>(0))
            .map_err(err)?
        else {
            return Ok(None);
        };
        let mut st = self
            .conn
            .prepare("SELECT tbl, record_id, vals FROM spool WHERE batch = ?1 ORDER BY pos")
            .map_err(err)?;
        let rows = st
            .query_map(params![n], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?, r.get::<_, String>(2)?))
            })
            .map_err(err)?;
        let mut batch = Vec::new();
        for row in rows {
            let (tbl, record_id, vals) = row.map_err(err)?;
            let sp = spec(&tbl).ok_or_else(|| bad(format!("unknown table {tbl}")))?;
            let v: serde_json::Value = serde_json::from_str(&vals).map_err(|e| bad(e.to_string()))?;
            let values: Option<Vec<Value>> =
                v.as_array().map(|a| a.iter().map(dec).collect()).unwrap_or(None);
            let values = values
                .filter(|v| v.len() == sp.columns.len())
                .ok_or_else(|| bad(format!("bad record {record_id}")))?;
            batch.push(Record { table: sp.table, record_id, values });
        }
        Ok(Some((n, batch)))
    }

    /// Send every batch, oldest first; each is removed once stored. Stops at the first failure
    /// (the rest stays). Returns the records sent.
    pub fn drain(&mut self, b: &mut dyn Backend, shown: &str) -> Result<i64, AuditError> {
        let mut sent = 0;
        while let Some((n, batch)) = self.first_batch()? {
            append(b, &batch).map_err(|e| AuditError::db(shown, e))?;
            self.conn
                .execute("DELETE FROM spool WHERE batch = ?1", params![n])
                .map_err(|e| AuditError::Spool(format!("{}: {e}", self.path.display())))?;
            sent += batch.len() as i64;
        }
        Ok(sent)
    }

    /// Remove the (empty) spool file.
    pub fn remove(self) -> Result<(), AuditError> {
        let path = self.path.clone();
        drop(self.conn);
        for suffix in ["", "-journal", "-wal", "-shm"] {
            let p = PathBuf::from(format!("{}{suffix}", path.display()));
            if p.exists() {
                std::fs::remove_file(&p).map_err(|e| AuditError::Spool(format!("{}: {e}", p.display())))?;
            }
        }
        Ok(())
    }
}
