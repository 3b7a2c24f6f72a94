//! A throw-away PostgreSQL cluster for tests: `initdb` in a temporary directory (as the
//! unprivileged `postgres` user through `runuser` when the tests run as root), a free loopback
//! port, password (SCRAM) authentication over TCP, trust on its own Unix socket inside the
//! directory. Stopped (immediately) and removed when dropped, also when a test fails.
//! [`Cluster::start`] returns `None` after printing `SKIPPED: …` when PostgreSQL is not
//! installed or cannot start. `fsync` is off except in [`Cluster::start_durable`]. Shared by
//! `crates/audit/tests` and `crates/truepos/tests`.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub struct Cluster {
    dir: tempfile::TempDir,
    data: PathBuf,
    bin: PathBuf,
    pub port: u16,
    /// Run the server and clients as this OS user (when the tests are root).
    run_as: Option<String>,
    /// `fsync` of the server: off unless a test measures throughput. A killed server keeps what
    /// it wrote in the OS page cache, so crash tests hold either way; commits still wait for the
    /// WAL write (`synchronous_commit` stays on).
    fsync: bool,
    /// TLS on (`ssl = on` with `server.crt`/`server.key` in the data directory) and every
    /// connection logged (the log says whether it used TLS).
    tls: bool,
}

pub const OWNER_PW: &str = "owner-pw-7Q";
pub const CELL_PW: &str = "cell-pw-3X";

fn skipped(why: &str) -> Option<Cluster> {
    eprintln!("SKIPPED: PostgreSQL test cluster: {why}");
    None
}

fn find_bin() -> Option<PathBuf> {
    let mut found: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .ok()?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let v: u32 = e.file_name().to_str()?.parse().ok()?;
            let bin = e.path().join("bin");
            bin.join("initdb").exists().then_some((v, bin))
        })
        .collect();
    found.sort();
    found.pop().map(|f| f.1)
}

fn is_root() -> bool {
    Command::new("id").arg("-u").output().is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map(|a| a.port()).unwrap_or(54329)
}

impl Cluster {
    /// Start a cluster with the roles `owner` (owns database `fleet`, creates the schema) and
    /// `cell` (may only SELECT and INSERT what `owner` creates there), passwords [`OWNER_PW`],
    /// [`CELL_PW`].
    pub fn start() -> Option<Cluster> {
        Self::start_with(false)
    }

    /// [`Cluster::start`] with `fsync` on, as a production server (for throughput figures).
    pub fn start_durable() -> Option<Cluster> {
        Self::start_with(true)
    }

    /// [`Cluster::start`] with TLS: `cert_pem` (the server's certificate chain) and `key_pem`
    /// (its private key) are installed in the data directory, `ssl = on`, and connections are
    /// logged ([`Cluster::log`]).
    pub fn start_tls(cert_pem: &str, key_pem: &str) -> Option<Cluster> {
        Self::start_full(false, Some((cert_pem, key_pem)))
    }

    fn start_with(fsync: bool) -> Option<Cluster> {
        Self::start_full(fsync, None)
    }

    fn start_full(fsync: bool, tls: Option<(&str, &str)>) -> Option<Cluster> {
        let Some(bin) = find_bin() else {
            return skipped("no /usr/lib/postgresql/*/bin/initdb (apt-get install postgresql)");
        };
        let run_as = if is_root() {
            if Command::new("id").arg("postgres").output().map(|o| !o.status.success()).unwrap_or(true) {
                return skipped("running as root and there is no OS user 'postgres' to run the server");
            }
            Some("postgres".to_string())
        } else {
            None
        };
        let dir = match tempfile::Builder::new().prefix("truepos-pg-").tempdir() {
            Ok(d) => d,
            Err(e) => return skipped(&format!("no temporary directory: {e}")),
        };
        let data = dir.path().join("pgdata");
        if std::fs::create_dir(&data).is_err() {
            return skipped("cannot create the data directory");
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o755));
            let _ = std::fs::set_permissions(&data, std::fs::Permissions::from_mode(0o700));
        }
        if let Some(u) = &run_as {
            let ok =
                Command::new("chown").arg(format!("{u}:")).arg(&data).status().is_ok_and(|s| s.success());
            if !ok {
                return skipped("cannot chown the data directory to postgres");
            }
        }
        let c = Cluster { dir, data, bin, port: 0, run_as, fsync, tls: tls.is_some() };
        let d = c.data.display().to_string();
        let out = c.run(
            "initdb",
            &[
                "-D",
                &d,
                "-U",
                "postgres",
                "--auth-local=trust",
                "--auth-host=scram-sha-256",
                "-N",
                "-E",
                "UTF8",
            ],
        );
        if !out.as_ref().is_ok_and(|o| o.status.success()) {
            return skipped(&format!("initdb failed: {}", describe(&out)));
        }
        if let Some((cert, key)) = tls {
            let (crt, k) = (c.data.join("server.crt"), c.data.join("server.key"));
            let written = std::fs::write(&crt, cert).and_then(|_| std::fs::write(&k, key));
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                let _ = std::fs::set_permissions(&k, std::fs::Permissions::from_mode(0o600));
            }
            let owned = match &c.run_as {
                Some(u) => Command::new("chown")
                    .arg(format!("{u}:"))
                    .arg(&crt)
                    .arg(&k)
                    .status()
                    .is_ok_and(|s| s.success()),
                None => true,
            };
            if written.is_err() || !owned {
                return skipped("cannot install the server's TLS certificate and key");
            }
        }
        let mut c = c;
        for _ in 0..5 {
            c.port = free_port();
            if c.pg_ctl_start() {
                break;
            }
            c.port = 0;
        }
        if c.port == 0 {
            let log = std::fs::read_to_string(c.data.join("log")).unwrap_or_default();
            return skipped(&format!("the server did not start: {log}"));
        }
        let setup = [
            format!("CREATE ROLE owner LOGIN PASSWORD '{OWNER_PW}'"),
            format!("CREATE ROLE cell LOGIN PASSWORD '{CELL_PW}'"),
            "CREATE DATABASE fleet OWNER owner".to_string(),
        ];
        for sql in &setup {
            if let Err(e) = c.psql("postgres", sql) {
                return skipped(&format!("setup '{sql}' failed: {e}"));
            }
        }
        if let Err(e) = c.psql(
            "fleet",
            "ALTER DEFAULT PRIVILEGES FOR ROLE owner IN SCHEMA public GRANT SELECT, INSERT ON TABLES TO cell",
        ) {
            return skipped(&format!("grants failed: {e}"));
        }
        Some(c)
    }

    fn run(&self, tool: &str, args: &[&str]) -> std::io::Result<Output> {
        let exe = self.bin.join(tool);
        let mut cmd = match &self.run_as {
            Some(u) => {
                let mut c = Command::new("runuser");
                c.arg("-u").arg(u).arg("--").arg(&exe);
                c
            }
            None => Command::new(&exe),
        };
        cmd.args(args).current_dir(self.dir.path()).env_remove("PGPASSWORD").output()
    }

    fn pg_ctl_start(&self) -> bool {
        let d = self.data.display().to_string();
        let log = self.data.join("log").display().to_string();
        let fsync = if self.fsync { "on" } else { "off" };
        let mut opts = format!("-p {} -k {d} -c listen_addresses=127.0.0.1 -c fsync={fsync}", self.port);
        if self.tls {
            opts.push_str(
                " -c ssl=on -c ssl_cert_file=server.crt -c ssl_key_file=server.key -c log_connections=on",
            );
        }
        self.run("pg_ctl", &["-D", &d, "-w", "-t", "30", "-l", &log, "-o", &opts, "start"])
            .is_ok_and(|o| o.status.success())
    }

    /// Start the server again (same port, same data) after [`Cluster::crash`].
    pub fn restart(&self) {
        assert!(self.pg_ctl_start(), "the server did not start again");
    }

    /// Stop the server at once, as a crash does (`pg_ctl -m immediate stop`).
    pub fn crash(&self) {
        let d = self.data.display().to_string();
        let out = self.run("pg_ctl", &["-D", &d, "-m", "immediate", "-w", "stop"]);
        assert!(out.is_ok_and(|o| o.status.success()), "pg_ctl stop failed");
    }

    /// Run SQL as the superuser over the cluster's own socket; stdout (unaligned, tuples only).
    pub fn psql(&self, db: &str, sql: &str) -> Result<String, String> {
        let d = self.data.display().to_string();
        let port = self.port.to_string();
        let out = self
            .run(
                "psql",
                &[
                    "-h",
                    &d,
                    "-p",
                    &port,
                    "-U",
                    "postgres",
                    "-d",
                    db,
                    "-v",
                    "ON_ERROR_STOP=1",
                    "-qAt",
                    "-c",
                    sql,
                ],
            )
            .map_err(|e| e.to_string())?;
        if out.status.success() {
            Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
        } else {
            Err(String::from_utf8_lossy(&out.stderr).trim().to_string())
        }
    }

    /// `postgresql://USER@127.0.0.1:PORT/DB`.
    pub fn url(&self, user: &str, db: &str) -> String {
        format!("postgresql://{user}@127.0.0.1:{}/{db}", self.port)
    }

    /// The server's log so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.data.join("log")).unwrap_or_default()
    }

    pub fn dir(&self) -> &Path {
        self.dir.path()
    }
}

fn describe(o: &std::io::Result<Output>) -> String {
    match o {
        Ok(o) => format!("{} {}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)),
        Err(e) => e.to_string(),
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        if self.port != 0 {
            let d = self.data.display().to_string();
            let _ = self.run("pg_ctl", &["-D", &d, "-m", "immediate", "-w", "stop"]);
        }
    }
}
