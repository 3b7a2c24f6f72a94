//! The storage behind the audit trail: a small [`Backend`] trait (statements, queries,
//! transactions) implemented for SQLite ([`crate::sqlite`]) and PostgreSQL ([`crate::pg`]).
//! Everything above it — schema, migrations, the hash chain, the spool, the readers — is written
//! once against this trait, so both databases hold the same records.
//!
//! Statements use `$1, $2, …` placeholders, in order, each once (the SQLite backend rewrites
//! them to `?1, ?2, …`). Values are [`Value`]s: NULL, 64-bit integer, double, text.

/// One SQL value, as both databases store it.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// SQL NULL.
    Null,
    /// A 64-bit integer (`INTEGER`, `BIGINT`).
    Int(i64),
    /// A double (`REAL`, `DOUBLE PRECISION`).
    Real(f64),
    /// UTF-8 text (`TEXT`).
    Text(String),
}

impl Value {
    /// A real as stored: `-0.0` becomes `0.0` and NaN becomes NULL (SQLite stores both that
    /// way), so what is hashed is what either database gives back.
    pub fn real(x: f64) -> Value {
        if x.is_nan() {
            Value::Null
        } else if x == 0.0 {
            Value::Real(0.0)
        } else {
            Value::Real(x)
        }
    }

    /// A text value.
    pub fn text(s: impl Into<String>) -> Value {
        Value::Text(s.into())
    }

    /// A text value, or NULL for `None`.
    pub fn opt_text(s: Option<&str>) -> Value {
        s.map_or(Value::Null, |s| Value::Text(s.to_string()))
    }

    /// The integer, if the value is one.
    pub fn as_i64(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            _ => None,
        }
    }

    /// The text, if the value is text.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            Value::Text(s) => Some(s),
            _ => None,
        }
    }

    /// As JSON (reals as numbers, NULL as null).
    pub fn to_json(&self) -> serde_json::Value {
        match self {
            Value::Null => serde_json::Value::Null,
            Value::Int(i) => (*i).into(),
            Value::Real(x) => serde_json::Number::from_f64(*x).map_or(serde_json::Value::Null, Into::into),
            Value::Text(s) => s.clone().into(),
        }
    }

    /// As a CSV field (empty for NULL; reals in the shortest form that reads back exactly).
    pub fn to_field(&self) -> String {
        match self {
            Value::Null => String::new(),
            Value::Int(i) => i.to_string(),
            Value::Real(x) => format!("{x:?}"),
            Value::Text(s) => s.clone(),
        }
    }
}

/// A failure of the database: `lost` when the connection is gone (the server stopped, the
/// network failed), which the writer answers by spooling; otherwise a real error.
#[derive(Debug, Clone)]
pub struct BackendError {
    /// The database's or driver's message.
    pub message: String,
    /// Whether the connection was lost (the writer then spools the records).
    pub lost: bool,
}

impl std::fmt::Display for BackendError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for BackendError {}

impl From<rusqlite::Error> for BackendError {
    fn from(e: rusqlite::Error) -> Self {
        BackendError { message: e.to_string(), lost: false }
    }
}

/// SQL dialect: the few type names the migrations spell differently.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dialect {
    /// SQLite's spelling.
    Sqlite,
    /// PostgreSQL's spelling.
    Postgres,
}

impl Dialect {
    /// Render a migration: `{int}` 64-bit integer, `{real}` double, `{pk}` integer primary key.
    pub fn render(self, sql: &str) -> String {
        let (int, real, pk) = match self {
            Dialect::Sqlite => ("INTEGER", "REAL", "INTEGER PRIMARY KEY"),
            Dialect::Postgres => ("BIGINT", "DOUBLE PRECISION", "BIGINT PRIMARY KEY"),
        };
        sql.replace("{int}", int).replace("{real}", real).replace("{pk}", pk)
    }
}

/// What the record logic needs from a database.
pub trait Backend: Send {
    /// The SQL dialect of the database.
    fn dialect(&self) -> Dialect;
    /// Several statements without parameters (migrations).
    fn execute_batch(&mut self, sql: &str) -> Result<(), BackendError>;
    /// One statement; the number of rows changed.
    fn execute(&mut self, sql: &str, params: &[Value]) -> Result<u64, BackendError>;
    /// One query; every row as values.
    fn query(&mut self, sql: &str, params: &[Value]) -> Result<Vec<Vec<Value>>, BackendError>;
    /// Start a transaction that excludes every other writer until commit (SQLite
    /// `BEGIN IMMEDIATE`; PostgreSQL a transaction-scoped advisory lock): migrations and chain
    /// appends run one at a time, so each sees the chain's true head.
    fn begin_exclusive(&mut self) -> Result<(), BackendError>;
    /// Commit the transaction begun by [`Backend::begin_exclusive`].
    fn commit(&mut self) -> Result<(), BackendError>;
    /// Roll back (errors ignored: a lost connection rolls back by itself).
    fn rollback(&mut self);
    /// The names of the base tables in the schema.
    fn tables(&mut self) -> Result<Vec<String>, BackendError>;
    /// Connect again after a lost connection.
    fn reconnect(&mut self) -> Result<(), BackendError>;
}

/// Run `f` in an exclusive transaction: commit on success, roll back on error.
pub fn exclusive<T, E: From<BackendError>>(
    b: &mut dyn Backend,
    f: impl FnOnce(&mut dyn Backend) -> Result<T, E>,
) -> Result<T, E> {
    b.begin_exclusive()?;
    match f(b) {
        Ok(v) => {
            b.commit()?;
            Ok(v)
        }
        Err(e) => {
            b.rollback();
            Err(e)
        }
    }
}
