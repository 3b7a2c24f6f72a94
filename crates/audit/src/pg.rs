//! The PostgreSQL [`Backend`] (the synchronous `postgres` client) and its address:
//! `postgresql://USER@HOST[:PORT][/DB][?sslmode=MODE&sslrootcert=FILE&connect_timeout=S&application_name=N]`.
//!
//! The password is never part of the address: it comes from `PGPASSWORD` or the password file
//! (`PGPASSFILE`, default `~/.pgpass`, lines `host:port:database:user:password` with `*`
//! wildcards, ignored when group or others can read it, as libpq does). An address with a
//! password is refused ([`PgTarget::parse`]) and the password is never printed. TLS follows
//! libpq's `sslmode` (`disable`, `allow`/`prefer` — the default —, `require`, `verify-ca`,
//! `verify-full`; see [`crate::pg_tls`]): `require` and stronger never fall back to clear text.
//!
//! Writers serialise on a transaction-scoped advisory lock ([`LOCK_KEY`]), which needs no
//! privilege, so a role that may only INSERT and SELECT can append to the chain.

use crate::backend::{Backend, BackendError, Dialect, Value};
use crate::pg_tls::{SslMode, TlsSettings};
use postgres::types::{to_sql_checked, IsNull, ToSql, Type};
use postgres::{Client, NoTls, Statement};
use std::collections::HashMap;
use std::time::Duration;

/// The advisory lock every truepos writer takes for migrations and chain appends.
pub const LOCK_KEY: i64 = 0x0074_7275_6570_6f73; // "truepos"

/// A PostgreSQL address, its password resolved (never displayed).
#[derive(Clone)]
pub struct PgTarget {
    /// Database role (user name).
    pub user: String,
    /// Server host name or address.
    pub host: String,
    /// Server TCP port (default 5432).
    pub port: u16,
    /// Database name.
    pub dbname: String,
    /// How long to wait for a connection.
    pub connect_timeout: Duration,
    /// `application_name` reported to the server.
    pub application_name: String,
    /// `sslmode` and, for the verifying modes, the trusted authorities.
    pub tls: TlsSettings,
    password: Option<String>,
}

impl std::fmt::Debug for PgTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.display())
    }
}

fn pct_decode(s: &str) -> Result<String, String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let h = s.get(i + 1..i + 3).and_then(|h| u8::from_str_radix(h, 16).ok());
            out.push(h.ok_or_else(|| format!("bad percent escape at byte {i}"))?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| "not UTF-8 after percent decoding".to_string())
}

impl PgTarget {
    /// Parse a `postgresql://` (or `postgres://`) address; `env` gives environment variables
    /// (`PGPASSWORD`, `PGPASSFILE`, `HOME`). Errors never contain a password.
    pub fn parse(url: &str, env: &dyn Fn(&str) -> Option<String>) -> Result<PgTarget, String> {
        let rest = url
            .strip_prefix("postgresql://")
            .or_else(|| url.strip_prefix("postgres://"))
            .ok_or("a PostgreSQL address starts with postgresql://")?;
        let (rest, query) = match rest.split_once('?') {
            Some((r, q)) => (r, Some(q)),
            None => (rest, None),
        };
        let (authority, path) = match rest.split_once('/') {
            Some((a, p)) => (a, p),
            None => (rest, ""),
        };
        let (userinfo, hostport) = match authority.rsplit_once('@') {
            Some((u, h)) => (u, h),
            None => return Err("the address needs a user: postgresql://USER@HOST:PORT/DB".into()),
        };
        if userinfo.contains(':') {
            return Err("a password in the address is refused (it would show in process lists and \
                        shell history): give it in PGPASSWORD or ~/.pgpass"
                .into());
        }
        let user = pct_decode(userinfo).map_err(|e| format!("user: {e}"))?;
        if user.is_empty() {
            return Err("the address needs a user: postgresql://USER@HOST:PORT/DB".into());
        }
        let (host, port) = if let Some(h) = hostport.strip_prefix('[') {
            let (h, p) = h.split_once(']').ok_or("unclosed [ in the host")?;
            (h.to_string(), p.strip_prefix(':'))
        } else {
            match hostport.rsplit_once(':') {
                Some((h, p)) => (h.to_string(), Some(p)),
                None => (hostport.to_string(), None),
            }
        };
        if host.is_empty() {
            return Err("the address needs a host: postgresql://USER@HOST:PORT/DB".into());
        }
        let port = match port {
            None | Some("") => 5432,
            Some(p) => {
                p.parse::<u16>().ok().filter(|p| *p > 0).ok_or(format!("port '{p}' is not 1 to 65535"))?
            }
        };
        let dbname = if path.is_empty() {
            user.clone()
        } else {
            pct_decode(path).map_err(|e| format!("database: {e}"))?
        };
        let mut t = PgTarget {
            user,
            host,
            port,
            dbname,
            connect_timeout: Duration::from_secs(5),
            application_name: "truepos".into(),
            tls: TlsSettings::new(SslMode::Prefer, None, None)?,
            password: None,
        };
        let (mut ssl_mode, mut root_cert) = (SslMode::Prefer, None);
        for kv in query.unwrap_or("").split('&').filter(|s| !s.is_empty()) {
            let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
            match k {
                "sslmode" => ssl_mode = SslMode::parse(v)?,
                "sslrootcert" => {
                    root_cert = Some(std::path::PathBuf::from(
                        pct_decode(v).map_err(|e| format!("sslrootcert: {e}"))?,
                    ))
                }
                "connect_timeout" => {
                    let s: u64 =
                        v.parse().map_err(|_| format!("connect_timeout '{v}' is not whole seconds"))?;
                    t.connect_timeout = Duration::from_secs(s.max(1));
                }
                "application_name" => {
                    t.application_name = pct_decode(v).map_err(|e| format!("application_name: {e}"))?
                }
                "password" => {
                    return Err(
                        "a password in the address is refused: give it in PGPASSWORD or ~/.pgpass".into()
                    )
                }
                other => {
                    return Err(format!(
                    "unknown parameter '{other}' (sslmode, sslrootcert, connect_timeout, application_name)"
                ))
                }
            }
        }
        let home = env("HOME").map(std::path::PathBuf::from);
        t.tls = TlsSettings::new(ssl_mode, root_cert, home.as_deref())?;
        t.password = env("PGPASSWORD").filter(|p| !p.is_empty()).or_else(|| t.password_from_file(env));
        Ok(t)
    }

    /// The address as given, without any secret (`sslmode` shown when it is not the default).
    pub fn display(&self) -> String {
        let host = if self.host.contains(':') { format!("[{}]", self.host) } else { self.host.clone() };
        let mut s = format!("postgresql://{}@{}:{}/{}", self.user, host, self.port, self.dbname);
        if self.tls.mode != SslMode::Prefer {
            s.push_str(&format!("?sslmode={}", self.tls.mode.name()));
        }
        s
    }

    /// Open a connection as `sslmode` says.
    pub fn connect(&self) -> Result<Client, postgres::Error> {
        let mut c = self.config();
        c.ssl_mode(self.tls.mode.client_mode());
        match self.tls.connector() {
            Some(tls) => c.connect(tls),
            None => c.connect(NoTls),
        }
    }

    /// Whether a password was found (environment or password file).
    pub fn has_password(&self) -> bool {
        self.password.is_some()
    }

    /// The first matching line of the password file.
    fn password_from_file(&self, env: &dyn Fn(&str) -> Option<String>) -> Option<String> {
        let path = env("PGPASSFILE")
            .map(std::path::PathBuf::from)
            .or_else(|| env("HOME").map(|h| std::path::Path::new(&h).join(".pgpass")))?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let m = std::fs::metadata(&path).ok()?;
            if m.permissions().mode() & 0o077 != 0 {
                return None; // libpq ignores a password file others can read
            }
        }
        let text = std::fs::read_to_string(&path).ok()?;
        let port = self.port.to_string();
        for line in text.lines() {
            if line.starts_with('#') || line.trim().is_empty() {
                continue;
            }
            let f = split_pgpass(line);
            if f.len() < 5 {
                continue;
            }
            let m = |field: &str, want: &str| field == "*" || field == want;
            if m(&f[0], &self.host) && m(&f[1], &port) && m(&f[2], &self.dbname) && m(&f[3], &self.user) {
                return Some(f[4..].join(":"));
            }
        }
        None
    }

    fn config(&self) -> postgres::Config {
        let mut c = postgres::Config::new();
        c.user(&self.user)
            .host(&self.host)
            .port(self.port)
            .dbname(&self.dbname)
            .connect_timeout(self.connect_timeout)
            // A server that vanishes without closing the connection (power, network) is noticed
            // within seconds, not after the kernel's TCP timeouts: the run then spools.
            .keepalives(true)
            .keepalives_idle(Duration::from_secs(5))
            .keepalives_interval(Duration::from_secs(2))
            .keepalives_retries(3)
            .tcp_user_timeout(Duration::from_secs(15))
            .application_name(&self.application_name);
        if let Some(p) = &self.password {
            c.password(p);
        }
        c
    }
}

/// Fields of a password-file line: `:` separates, `\` escapes.
fn split_pgpass(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut field = String::new();
    let mut esc = false;
    for ch in line.chars() {
        if esc {
            field.push(ch);
            esc = false;
        } else if ch == '\\' {
            esc = true;
        } else if ch == ':' && out.len() < 4 {
            out.push(std::mem::take(&mut field));
        } else {
            field.push(ch);
        }
    }
    out.push(field);
    out
}

/// The audit trail on PostgreSQL: one connection with its prepared statements.
pub struct PgBackend {
    target: PgTarget,
    client: Option<Client>,
    statements: HashMap<String, Statement>,
}

fn lost(message: String) -> BackendError {
    BackendError { message, lost: true }
}

/// Classify a client error: no SQLSTATE (I/O, closed connection) or a connection-class or
/// shutdown SQLSTATE means the connection is gone.
fn classify(e: postgres::Error, target: &PgTarget) -> BackendError {
    let gone = match e.code() {
        None => true,
        Some(c) => {
            let c = c.code();
            c.starts_with("08") || c.starts_with("57P")
        }
    };
    let mut message = match e.as_db_error() {
        Some(d) => format!("{}: {}", d.severity(), d.message()),
        None => {
            let mut m = e.to_string();
            let mut src = std::error::Error::source(&e);
            while let Some(s) = src {
                let t = s.to_string();
                if !m.contains(&t) {
                    m = format!("{m}: {t}");
                }
                src = s.source();
            }
            m
        }
    };
    if message.contains("password") && !target.has_password() {
        message.push_str(" (no password was found: set PGPASSWORD or add a line to ~/.pgpass)");
    }
    BackendError { message, lost: gone }
}

impl PgBackend {
    /// Connect to `target` (TLS as its `sslmode` says).
    pub fn connect(target: &PgTarget) -> Result<Self, BackendError> {
        let mut b = PgBackend { target: target.clone(), client: None, statements: HashMap::new() };
        b.reconnect()?;
        Ok(b)
    }

    fn client(&mut self) -> Result<&mut Client, BackendError> {
        match self.client.as_mut() {
            Some(c) if !c.is_closed() => Ok(self.client.as_mut().expect("checked")),
            _ => Err(lost(format!("the connection to {} is closed", self.target.display()))),
        }
    }

    fn statement(&mut self, sql: &str) -> Result<Statement, BackendError> {
        if let Some(s) = self.statements.get(sql) {
            return Ok(s.clone());
        }
        let target = self.target.clone();
        let st = self.client()?.prepare(sql).map_err(|e| classify(e, &target))?;
        self.statements.insert(sql.to_string(), st.clone());
        Ok(st)
    }

    fn on_error(&mut self, e: postgres::Error) -> BackendError {
        let e = classify(e, &self.target);
        if e.lost {
            self.client = None;
            self.statements.clear();
        }
        e
    }
}

impl ToSql for Value {
    fn to_sql(
        &self,
        ty: &Type,
        out: &mut bytes::BytesMut,
    ) -> Result<IsNull, Box<dyn std::error::Error + Sync + Send>> {
        match self {
            Value::Null => Ok(IsNull::Yes),
            Value::Int(i) => match *ty {
                Type::INT4 => i32::try_from(*i)?.to_sql(ty, out),
                Type::INT2 => i16::try_from(*i)?.to_sql(ty, out),
                Type::FLOAT8 => (*i as f64).to_sql(ty, out),
                _ => i.to_sql(ty, out),
            },
            Value::Real(x) => match *ty {
                Type::FLOAT4 => (*x as f32).to_sql(ty, out),
                _ => x.to_sql(ty, out),
            },
            Value::Text(s) => s.as_str().to_sql(ty, out),
        }
    }

    fn accepts(_: &Type) -> bool {
        true
    }

    to_sql_checked!();
}

fn from_row(row: &postgres::Row) -> Result<Vec<Value>, postgres::Error> {
    let mut out = Vec::with_capacity(row.len());
    for (i, c) in row.columns().iter().enumerate() {
        let v = match *c.type_() {
            Type::INT8 => row.try_get::<_, Option<i64>>(i)?.map(Value::Int),
            Type::INT4 => row.try_get::<_, Option<i32>>(i)?.map(|x| Value::Int(x.into())),
            Type::INT2 => row.try_get::<_, Option<i16>>(i)?.map(|x| Value::Int(x.into())),
            Type::FLOAT8 => row.try_get::<_, Option<f64>>(i)?.map(Value::Real),
            Type::FLOAT4 => row.try_get::<_, Option<f32>>(i)?.map(|x| Value::Real(x.into())),
            Type::BOOL => row.try_get::<_, Option<bool>>(i)?.map(|x| Value::Int(x.into())),
            _ => row.try_get::<_, Option<String>>(i)?.map(Value::Text),
        };
        out.push(v.unwrap_or(Value::Null));
    }
    Ok(out)
}

impl Backend for PgBackend {
    fn dialect(&self) -> Dialect {
        Dialect::Postgres
    }

    fn execute_batch(&mut self, sql: &str) -> Result<(), BackendError> {
        let r = self.client()?.batch_execute(sql);
        r.map_err(|e| self.on_error(e))
    }

    fn execute(&mut self, sql: &str, params: &[Value]) -> Result<u64, BackendError> {
        let st = self.statement(sql)?;
        let p: Vec<&(dyn ToSql + Sync)> = params.iter().map(|v| v as &(dyn ToSql + Sync)).collect();
        let r = self.client()?.execute(&st, &p);
        r.map_err(|e| self.on_error(e))
    }

    fn query(&mut self, sql: &str, params: &[Value]) -> Result<Vec<Vec<Value>>, BackendError> {
        let st = self.statement(sql)?;
        let p: Vec<&(dyn ToSql + Sync)> = params.iter().map(|v| v as &(dyn ToSql + Sync)).collect();
        let r = self.client()?.query(&st, &p).and_then(|rows| rows.iter().map(from_row).collect());
        r.map_err(|e| self.on_error(e))
    }

    fn begin_exclusive(&mut self) -> Result<(), BackendError> {
        self.execute_batch(&format!("BEGIN; SELECT pg_advisory_xact_lock({LOCK_KEY});"))
    }

    fn commit(&mut self) -> Result<(), BackendError> {
        self.execute_batch("COMMIT")
    }

    fn rollback(&mut self) {
        let _ = self.execute_batch("ROLLBACK");
    }

    fn tables(&mut self) -> Result<Vec<String>, BackendError> {
        let rows = self.query(
            "SELECT c.relname::text FROM pg_catalog.pg_class c \
             JOIN pg_catalog.pg_namespace n ON n.oid = c.relnamespace \
             WHERE n.nspname = current_schema() AND c.relkind IN ('r', 'p')",
            &[],
        )?;
        Ok(rows.into_iter().filter_map(|r| r.into_iter().next()?.as_str().map(str::to_string)).collect())
    }

    fn reconnect(&mut self) -> Result<(), BackendError> {
        self.client = None;
        self.statements.clear();
        let c = self.target.connect().map_err(|e| classify(e, &self.target))?;
        self.client = Some(c);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| vars.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
    }

    #[test]
    fn addresses_parse_and_passwords_are_refused_unprinted() {
        let t = PgTarget::parse("postgresql://cell@10.0.0.5:5433/fleet", &env(&[])).unwrap();
        assert_eq!(
            (t.user.as_str(), t.host.as_str(), t.port, t.dbname.as_str()),
            ("cell", "10.0.0.5", 5433, "fleet")
        );
        assert!(!t.has_password());
        let t = PgTarget::parse("postgres://cell@db", &env(&[("PGPASSWORD", "s3cret")])).unwrap();
        assert_eq!((t.port, t.dbname.as_str()), (5432, "cell"));
        assert!(t.has_password());
        assert!(!format!("{t:?}").contains("s3cret"));
        assert_eq!(t.display(), "postgresql://cell@db:5432/cell");
        let t = PgTarget::parse("postgresql://cell@[::1]:6000/f?sslmode=prefer&connect_timeout=2", &env(&[]))
            .unwrap();
        assert_eq!((t.host.as_str(), t.port, t.connect_timeout.as_secs()), ("::1", 6000, 2));
        for (bad, what) in [
            ("postgresql://cell:hunter2@db/fleet", "password"),
            ("postgresql://cell@db/fleet?password=hunter2", "password"),
            ("postgresql://db/fleet", "user"),
            ("postgresql://cell@db:99999/fleet", "port"),
            ("postgresql://cell@db/fleet?sslmode=on", "verify-full"),
            (
                "postgresql://cell@db/fleet?sslmode=verify-full&sslrootcert=/nonexistent/ca.pem",
                "/nonexistent/ca.pem",
            ),
            ("postgresql://cell@db/fleet?foo=1", "unknown parameter"),
        ] {
            let e = PgTarget::parse(bad, &env(&[])).expect_err(bad);
            assert!(e.contains(what), "{bad}: {e}");
            assert!(!e.contains("hunter2"), "{e}");
        }
    }

    #[test]
    fn password_file_lines_match_with_wildcards_and_escapes() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("pgpass");
        std::fs::write(&f, "# comment\nother:*:*:*:nope\n127.0.0.1:*:fleet:cell:pa\\:ss:word\n").unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o600)).unwrap();
        }
        let p = f.display().to_string();
        let t =
            PgTarget::parse("postgresql://cell@127.0.0.1:5999/fleet", &env(&[("PGPASSFILE", &p)])).unwrap();
        assert_eq!(t.password.as_deref(), Some("pa:ss:word"));
        let t =
            PgTarget::parse("postgresql://cell@127.0.0.1:5999/other", &env(&[("PGPASSFILE", &p)])).unwrap();
        assert!(!t.has_password());
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o644)).unwrap();
            let t = PgTarget::parse("postgresql://cell@127.0.0.1:5999/fleet", &env(&[("PGPASSFILE", &p)]))
                .unwrap();
            assert!(!t.has_password(), "a password file others can read is ignored");
        }
    }
}
