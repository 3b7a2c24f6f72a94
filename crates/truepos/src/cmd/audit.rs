//! `truepos audit list | show RUN | export RUN --format json|csv | verify | migrate | push SPOOL`:
//! read the audit trail that `somac run` and `somac inspect` write (SQLite file or
//! `postgresql://USER@HOST:PORT/DB`), check its hash chain, create or migrate its schema as its
//! owner, and send a spool left by a run that ended while the database was away. The work is in
//! `truepos_audit` ([`truepos_audit::Trail`], [`truepos_audit::push_spool`]).

use crate::output::print_json;
use crate::{ClassExt, Outcome, UsageError};
use anyhow::Result;
use serde_json::json;
use std::path::PathBuf;
use truepos_audit::{Db, RunSummary, Trail};

#[derive(clap::Args, Debug)]
#[command(
    after_help = "A fleet's shared trail: PGPASSWORD=… truepos audit verify --db postgresql://cell@db.plant:5432/fleet\n\nThe password of a postgresql:// database comes from PGPASSWORD or ~/.pgpass, never the\naddress. `verify` exits 1 naming the first record whose hash chain is broken (changed,\ninserted or deleted); note the head it prints to detect a later truncation."
)]
pub struct Args {
    #[command(subcommand)]
    pub command: AuditCommand,
}

/// Where the trail is (shared by every subcommand).
#[derive(clap::Args, Debug, Clone)]
pub struct DbArg {
    /// The audit trail: a SQLite file or postgresql://USER@HOST:PORT/DB.
    #[arg(long, default_value = "somac-audit.sqlite")]
    pub db: String,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Subcommand, Debug)]
pub enum AuditCommand {
    /// Every run: id, uid, program, start, end, status, controller.
    List(DbArg),
    /// One run (by id or uid): its summary, record counts, stops, alarms, inspected holes and
    /// results (features and tolerances of `dmis run`).
    Show {
        /// Run id or uid.
        run: String,
        #[command(flatten)]
        db: DbArg,
    },
    /// Every record of a run with its chain columns, as JSON or CSV on stdout.
    Export {
        /// Run id or uid.
        run: String,
        /// json (one object: run and records) or csv (one row per record).
        #[arg(long, value_parser = ["json", "csv"])]
        format: String,
        /// The audit trail: a SQLite file or postgresql://USER@HOST:PORT/DB.
        #[arg(long, default_value = "somac-audit.sqlite")]
        db: String,
    },
    /// Recompute the hash chain; exit 1 naming the first broken record.
    Verify {
        #[command(flatten)]
        db: DbArg,
        /// A head printed by an earlier verify (SEQ:HASH), kept elsewhere: that record must still
        /// be there unchanged (detects records deleted at the end of the chain).
        #[arg(long, value_name = "SEQ:HASH")]
        head: Option<String>,
    },
    /// Create or migrate the schema (run once as the schema owner; cells then only insert and read).
    Migrate(DbArg),
    /// Send a spool left by a run that ended while the database was unreachable.
    Push {
        /// The spool file the run named (truepos-audit-spool-*.sqlite).
        spool: PathBuf,
        /// The database to send to (default: the one the spool names).
        #[arg(long)]
        db: Option<String>,
        /// Print one JSON object on stdout (human text goes to stderr).
        #[arg(long)]
        json: bool,
    },
}

/// Parse `--db` (a bad address is bad usage; the value is never echoed: it may hold a password).
pub fn parse_db(s: &str) -> Result<Db> {
    Db::parse(s).usage().map_err(Into::into)
}

fn open(db: &str) -> Result<Trail> {
    let db = parse_db(db)?;
    Ok(Trail::open(&db)?)
}

fn opt(s: &Option<String>) -> &str {
    s.as_deref().unwrap_or("-")
}

fn run_line(r: &RunSummary) -> String {
    format!(
        "{:>5}  {:<8}  {:<24}  {:<24}  {:<8}  {}  {}",
        r.id,
        opt(&r.status),
        r.started_at,
        opt(&r.ended_at),
        r.uid.as_deref().map_or("-", |u| &u[..8.min(u.len())]),
        r.program,
        opt(&r.controller)
    )
}

pub fn run(a: Args) -> Result<Outcome> {
    match &a.command {
        AuditCommand::List(d) => list(d),
        AuditCommand::Show { run, db } => show(run, db),
        AuditCommand::Export { run, format, db } => export(run, format, db),
        AuditCommand::Verify { db, head } => verify(db, head.as_deref()),
        AuditCommand::Migrate(d) => migrate(d),
        AuditCommand::Push { spool, db, json } => push(spool, db.as_deref(), *json),
    }
}

/// `audit list`: every run.
fn list(d: &DbArg) -> Result<Outcome> {
    let mut t = open(&d.db)?;
    let runs = t.runs()?;
    if d.json {
        print_json(
            &json!({ "db": t.display(), "runs": runs.iter().map(RunSummary::to_json).collect::<Vec<_>>() }),
        )?;
    } else {
        println!(
            "{:>5}  {:<8}  {:<24}  {:<24}  {:<8}  program  controller",
            "run", "status", "started", "ended", "uid"
        );
        for r in &runs {
            println!("{}", run_line(r));
        }
        eprintln!("{} runs in {}", runs.len(), t.display());
    }
    Ok(Outcome::Done)
}

/// `audit show RUN`: one run with its records.
fn show(run: &str, db: &DbArg) -> Result<Outcome> {
    let mut t = open(&db.db)?;
    let r = t.run(run)?;
    let counts = t.counts(r.id)?;
    let records = t.records(r.id)?;
    let pick =
        |table: &str| records.iter().filter(|x| x.table == table).map(|x| x.to_json()).collect::<Vec<_>>();
    if db.json {
        let c: serde_json::Map<String, serde_json::Value> =
            counts.iter().map(|(k, n)| (k.to_string(), (*n).into())).collect();
        print_json(&json!({
            "db": t.display(), "run": r.to_json(), "counts": c,
            "stops": pick("stops"), "alarms": pick("alarms"), "inspections": pick("inspections"),
            "results": pick("results"),
        }))?;
    } else {
        println!("run {} ({})  {}", r.id, opt(&r.uid), r.program);
        println!("  started {}  ended {}  status {}", r.started_at, opt(&r.ended_at), opt(&r.status));
        if let Some(m) = &r.message {
            println!("  message {m}");
        }
        println!("  controller {} {}", opt(&r.controller), opt(&r.controller_version));
        let c: Vec<String> = counts.iter().filter(|c| c.1 > 0).map(|(k, n)| format!("{k} {n}")).collect();
        println!("  records: {}", if c.is_empty() { "none".into() } else { c.join(", ") });
        for s in records.iter().filter(|x| x.table == "stops") {
            let g = |c: &str| s.get(c).map(|v| v.to_field()).unwrap_or_default();
            println!(
                "  stop line {:>5}  {:<8}  final error {} mm  iterations {}",
                g("line"),
                g("status"),
                g("final_error_mm"),
                g("iterations")
            );
        }
        for s in records.iter().filter(|x| x.table == "alarms") {
            let g = |c: &str| s.get(c).map(|v| v.to_field()).unwrap_or_default();
            println!("  alarm line {:>5}  {}: {} ({})", g("line"), g("kind"), g("message"), g("action"));
        }
        for s in records.iter().filter(|x| x.table == "results") {
            let g = |c: &str| s.get(c).map(|v| v.to_field()).unwrap_or_default();
            let u = g("expanded_uncertainty");
            let lim = g("lower_limit");
            println!(
                "  {} {} {} {} {}{}{}{}",
                g("kind"),
                g("label"),
                g("quantity"),
                g("value"),
                g("unit"),
                if u.is_empty() { String::new() } else { format!(" (U = {u})") },
                if lim.is_empty() {
                    String::new()
                } else {
                    format!(" limits {lim} … {}", g("upper_limit"))
                },
                s.get("verdict").and_then(|v| v.as_str()).map(|v| format!(" {v}")).unwrap_or_default()
            );
        }
        for s in records.iter().filter(|x| x.table == "inspections") {
            let g = |c: &str| s.get(c).map(|v| v.to_field()).unwrap_or_default();
            println!(
                "  hole {}  position error {} mm  diameter {} mm",
                g("hole"),
                g("position_error_mm"),
                g("diameter_mm")
            );
        }
    }
    Ok(Outcome::Done)
}

/// `audit export RUN --format json|csv`.
fn export(run: &str, format: &str, db: &str) -> Result<Outcome> {
    let mut t = open(db)?;
    let r = t.run(run)?;
    let records = t.records(r.id)?;
    if format == "csv" {
        use std::io::Write;
        let mut out = std::io::stdout().lock();
        out.write_all(truepos_audit::records_csv(&records).as_bytes())?;
        out.flush()?;
    } else {
        print_json(&json!({
            "db": t.display(), "run": r.to_json(),
            "records": records.iter().map(|x| x.to_json()).collect::<Vec<_>>(),
        }))?;
    }
    eprintln!("run {}: {} records exported", r.id, records.len());
    Ok(Outcome::Done)
}

/// `audit verify [--head SEQ:HASH]`: exit 1 (out of tolerance) when the chain is broken.
fn verify(d: &DbArg, head: Option<&str>) -> Result<Outcome> {
    let anchor = match head {
        None => None,
        Some(h) => {
            let bad = || UsageError(format!("--head '{h}' is not SEQ:HASH (as `audit verify` prints it)"));
            let (seq, hash) = h.split_once(':').ok_or_else(bad)?;
            let seq: i64 = seq.parse().map_err(|_| bad())?;
            if hash.len() != 64 || !hash.bytes().all(|c| c.is_ascii_hexdigit()) {
                return Err(bad().into());
            }
            Some((seq, hash.to_ascii_lowercase()))
        }
    };
    let mut t = open(&d.db)?;
    let v = match &anchor {
        Some((seq, hash)) => t.verify_against(*seq, hash)?,
        None => t.verify()?,
    };
    let broken = v
        .first_broken
        .as_ref()
        .map(|b| json!({ "seq": b.seq, "table": b.table, "record_id": b.record_id, "problem": b.problem }));
    if d.json {
        print_json(&json!({
            "db": t.display(), "ok": v.first_broken.is_none(), "records": v.records,
            "legacy_records": v.legacy_records,
            "head": { "seq": v.head.0, "hash": v.head.1 }, "first_broken": broken,
        }))?;
    } else {
        match &v.first_broken {
            None => println!(
                "ok: {} records, chain intact; head {}:{} (keep it: --head checks it later)",
                v.records, v.head.0, v.head.1
            ),
            Some(b) => {
                println!("BROKEN at record seq {} ({} {}): {}", b.seq, b.table, b.record_id, b.problem)
            }
        }
        if v.legacy_records > 0 {
            eprintln!(
                "note: {} rows predate the hash chain (schema < 4) and cannot be verified",
                v.legacy_records
            );
        }
    }
    if v.first_broken.is_some() {
        return Ok(Outcome::OutOfTolerance);
    }
    Ok(Outcome::Done)
}

/// `audit migrate`: create or migrate the schema.
fn migrate(d: &DbArg) -> Result<Outcome> {
    let t = open_or_create(&d.db)?;
    let v = truepos_audit::MIGRATIONS.last().map_or(0, |m| m.0);
    if d.json {
        print_json(&json!({ "db": t, "schema_version": v }))?;
    } else {
        println!("{t}: audit schema version {v}");
    }
    Ok(Outcome::Done)
}

/// `audit push SPOOL`: send a spool to its database.
fn push(spool: &std::path::Path, db: Option<&str>, as_json: bool) -> Result<Outcome> {
    let db = db.map(parse_db).transpose()?;
    let (db, sent) = truepos_audit::push_spool(spool, db.as_ref())?;
    if as_json {
        print_json(&json!({ "db": db.display(), "spool": spool.display().to_string(), "sent": sent }))?;
    } else {
        println!("{sent} records sent from {} to {}; spool removed", spool.display(), db.display());
    }
    Ok(Outcome::Done)
}

/// `migrate` creates a missing SQLite file (the other subcommands never do).
fn open_or_create(s: &str) -> Result<String> {
    let db = parse_db(s)?;
    if let Db::Sqlite(p) = &db {
        if !p.exists() {
            drop(truepos_audit::Db::Sqlite(p.clone()).connect(true)?);
        }
    }
    Ok(Trail::open(&db)?.display().to_string())
}
