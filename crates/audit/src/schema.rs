//! The schema: numbered migrations in portable SQL (`{int}`, `{real}`, `{pk}` rendered per
//! [`Dialect`]), the record tables and their columns ([`SPECS`]), and [`migrate`], which creates
//! or migrates forward in one exclusive transaction and refuses, unchanged, a database that is
//! someone else's or newer than this build.
//!
//! Version 4 adds the hash chain: every record row carries `seq` (its place in the database's
//! one chain), `record_id` (unique, chosen by the writer: resending is idempotent), `prev_hash`
//! and `hash`. Run rows become append-only too: `run_starts` (the old `runs` table), with the
//! controller and the end of a run as records of their own (`run_controllers`, `run_ends`), and
//! `runs` a view of all three with the columns it always had. Version 5 adds `results`: one
//! row per reported quantity of any measuring command (a DMIS program's features and
//! tolerances, a calibration's parameters) with its unit, expanded uncertainty, limits and
//! verdict.

use crate::backend::{Backend, BackendError, Dialect, Value};
use crate::AuditError;

/// Numbered migrations.
pub const MIGRATIONS: &[(i64, &str)] = &[
    (
        1,
        "CREATE TABLE runs (
        id {pk},
        started_at TEXT NOT NULL,
        program TEXT NOT NULL,
        note TEXT
    );
    CREATE TABLE blocks (
        run_id {int} NOT NULL REFERENCES runs(id),
        line {int} NOT NULL,
        text TEXT NOT NULL,
        time_s {real} NOT NULL
    );
    CREATE TABLE measurements (
        run_id {int} NOT NULL REFERENCES runs(id),
        line {int} NOT NULL,
        iteration {int} NOT NULL,
        commanded_x_mm {real} NOT NULL, commanded_y_mm {real} NOT NULL, commanded_z_mm {real} NOT NULL,
        measured_x_mm {real} NOT NULL, measured_y_mm {real} NOT NULL, measured_z_mm {real} NOT NULL,
        error_mm {real} NOT NULL,
        samples_std_mm {real} NOT NULL,
        time_s {real} NOT NULL
    );
    CREATE TABLE corrections (
        run_id {int} NOT NULL REFERENCES runs(id),
        line {int} NOT NULL,
        iteration {int} NOT NULL,
        dx_mm {real} NOT NULL, dy_mm {real} NOT NULL, dz_mm {real} NOT NULL,
        offset_x_mm {real} NOT NULL, offset_y_mm {real} NOT NULL, offset_z_mm {real} NOT NULL,
        clipped {int} NOT NULL,
        time_s {real} NOT NULL
    );
    CREATE TABLE alarms (
        run_id {int} NOT NULL REFERENCES runs(id),
        line {int} NOT NULL,
        kind TEXT NOT NULL,
        message TEXT NOT NULL,
        action TEXT NOT NULL,
        time_s {real} NOT NULL
    );
    CREATE TABLE orientations (
        run_id {int} NOT NULL REFERENCES runs(id),
        line {int} NOT NULL,
        reason TEXT NOT NULL,
        scale {real} NOT NULL,
        rms_mm {real} NOT NULL,
        time_s {real} NOT NULL
    );
    CREATE TABLE refractive_index_updates (
        run_id {int} NOT NULL REFERENCES runs(id),
        line {int} NOT NULL,
        n_old {real} NOT NULL,
        n_new {real} NOT NULL,
        time_s {real} NOT NULL
    );
    CREATE TABLE stops (
        run_id {int} NOT NULL REFERENCES runs(id),
        line {int} NOT NULL,
        status TEXT NOT NULL,
        final_error_mm {real},
        iterations {int} NOT NULL,
        time_s {real} NOT NULL
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
    (
        4,
        // The hash chain; append-only runs; hole inspections. The chain columns of every
        // record table are added by `chain_columns` below (same SQL for each table).
        "ALTER TABLE runs RENAME TO run_starts;
    ALTER TABLE run_starts ADD COLUMN uid TEXT;
    CREATE TABLE run_controllers (
        run_id {int} NOT NULL REFERENCES run_starts(id),
        controller TEXT NOT NULL,
        controller_version TEXT NOT NULL,
        at TEXT NOT NULL
    );
    CREATE TABLE run_ends (
        run_id {int} NOT NULL REFERENCES run_starts(id),
        ended_at TEXT NOT NULL,
        status TEXT NOT NULL,
        message TEXT
    );
    CREATE TABLE inspections (
        run_id {int} NOT NULL REFERENCES run_starts(id),
        hole TEXT NOT NULL,
        line {int},
        nominal_x_mm {real} NOT NULL, nominal_y_mm {real} NOT NULL, nominal_z_mm {real} NOT NULL,
        measured_x_mm {real} NOT NULL, measured_y_mm {real} NOT NULL, measured_z_mm {real} NOT NULL,
        error_x_mm {real} NOT NULL, error_y_mm {real} NOT NULL,
        position_error_mm {real} NOT NULL,
        nominal_diameter_mm {real} NOT NULL,
        diameter_mm {real} NOT NULL,
        diameter_error_mm {real} NOT NULL,
        roundness_mm {real} NOT NULL,
        points {int} NOT NULL,
        elapsed_s {real} NOT NULL
    );
    {chain}
    CREATE VIEW runs AS SELECT s.id AS id, s.uid AS uid, s.started_at AS started_at, s.program AS program,
        s.note AS note,
        COALESCE((SELECT c.controller FROM run_controllers c WHERE c.run_id = s.id ORDER BY c.seq DESC LIMIT 1),
            s.controller) AS controller,
        COALESCE((SELECT c.controller_version FROM run_controllers c WHERE c.run_id = s.id
            ORDER BY c.seq DESC LIMIT 1), s.controller_version) AS controller_version,
        COALESCE((SELECT e.ended_at FROM run_ends e WHERE e.run_id = s.id ORDER BY e.seq DESC LIMIT 1),
            s.ended_at) AS ended_at,
        COALESCE((SELECT e.status FROM run_ends e WHERE e.run_id = s.id ORDER BY e.seq DESC LIMIT 1),
            s.status) AS status,
        COALESCE((SELECT e.message FROM run_ends e WHERE e.run_id = s.id ORDER BY e.seq DESC LIMIT 1),
            s.message) AS message
        FROM run_starts s;",
    ),
    (
        5,
        // Results of any measuring command, one row per reported quantity: a DMIS program's
        // feature values and tolerances (`dmis run`), a calibration's parameters. Chained as
        // every record table.
        "CREATE TABLE results (
        run_id {int} NOT NULL REFERENCES run_starts(id),
        line {int},
        kind TEXT NOT NULL,
        label TEXT NOT NULL,
        feature TEXT,
        quantity TEXT NOT NULL,
        value {real},
        unit TEXT NOT NULL,
        expanded_uncertainty {real},
        lower_limit {real},
        upper_limit {real},
        verdict TEXT
    );
    {chain}",
    ),
];

/// The schema version this build writes.
pub fn known_version() -> i64 {
    MIGRATIONS.last().map_or(0, |m| m.0)
}

/// Every base table any version creates (a database with another table is someone else's).
pub const TABLES: &[&str] = &[
    "schema_migrations",
    "runs",
    "run_starts",
    "run_controllers",
    "run_ends",
    "blocks",
    "measurements",
    "corrections",
    "alarms",
    "orientations",
    "refractive_index_updates",
    "stops",
    "inspections",
    "results",
];

/// The kind of a column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// An integer column.
    Int,
    /// A floating-point column.
    Real,
    /// A text column.
    Text,
}

/// A record table: its name and its own columns (the chain columns `seq`, `record_id`,
/// `prev_hash`, `hash` follow them in every table).
#[derive(Debug)]
pub struct Spec {
    /// The table's name.
    pub table: &'static str,
    /// The data columns (name, kind), in order.
    pub columns: &'static [(&'static str, Kind)],
    /// The schema version that created the table (its chain columns come with it).
    pub since: i64,
}

use Kind::{Int, Real, Text};

/// The record tables, in the order `show` and `export` list their counts.
pub const SPECS: &[Spec] = &[
    Spec {
        table: "run_starts",
        since: 4,
        columns: &[("id", Int), ("uid", Text), ("started_at", Text), ("program", Text), ("note", Text)],
    },
    Spec {
        table: "run_controllers",
        since: 4,
        columns: &[("run_id", Int), ("controller", Text), ("controller_version", Text), ("at", Text)],
    },
    Spec {
        table: "blocks",
        since: 4,
        columns: &[("run_id", Int), ("line", Int), ("text", Text), ("time_s", Real)],
    },
    Spec {
        table: "measurements",
        since: 4,
        columns: &[
            ("run_id", Int),
            ("line", Int),
            ("iteration", Int),
            ("commanded_x_mm", Real),
            ("commanded_y_mm", Real),
            ("commanded_z_mm", Real),
            ("measured_x_mm", Real),
            ("measured_y_mm", Real),
            ("measured_z_mm", Real),
            ("error_mm", Real),
            ("samples_std_mm", Real),
            ("time_s", Real),
        ],
    },
    Spec {
        table: "corrections",
        since: 4,
        columns: &[
            ("run_id", Int),
            ("line", Int),
            ("iteration", Int),
            ("dx_mm", Real),
            ("dy_mm", Real),
            ("dz_mm", Real),
            ("offset_x_mm", Real),
            ("offset_y_mm", Real),
            ("offset_z_mm", Real),
            ("clipped", Int),
            ("time_s", Real),
        ],
    },
    Spec {
        table: "alarms",
        since: 4,
        columns: &[
            ("run_id", Int),
            ("line", Int),
            ("kind", Text),
            ("message", Text),
            ("action", Text),
            ("time_s", Real),
        ],
    },
    Spec {
        table: "orientations",
        since: 4,
        columns: &[
            ("run_id", Int),
            ("line", Int),
            ("reason", Text),
            ("scale", Real),
            ("rms_mm", Real),
            ("time_s", Real),
        ],
    },
    Spec {
        table: "refractive_index_updates",
        since: 4,
        columns: &[("run_id", Int), ("line", Int), ("n_old", Real), ("n_new", Real), ("time_s", Real)],
    },
    Spec {
        table: "stops",
        since: 4,
        columns: &[
            ("run_id", Int),
            ("line", Int),
            ("status", Text),
            ("final_error_mm", Real),
            ("iterations", Int),
            ("time_s", Real),
        ],
    },
    Spec {
        table: "inspections",
        since: 4,
        columns: &[
            ("run_id", Int),
            ("hole", Text),
            ("line", Int),
            ("nominal_x_mm", Real),
            ("nominal_y_mm", Real),
            ("nominal_z_mm", Real),
            ("measured_x_mm", Real),
            ("measured_y_mm", Real),
            ("measured_z_mm", Real),
            ("error_x_mm", Real),
            ("error_y_mm", Real),
            ("position_error_mm", Real),
            ("nominal_diameter_mm", Real),
            ("diameter_mm", Real),
            ("diameter_error_mm", Real),
            ("roundness_mm", Real),
            ("points", Int),
            ("elapsed_s", Real),
        ],
    },
    Spec {
        table: "results",
        since: 5,
        columns: &[
            ("run_id", Int),
            ("line", Int),
            ("kind", Text),
            ("label", Text),
            ("feature", Text),
            ("quantity", Text),
            ("value", Real),
            ("unit", Text),
            ("expanded_uncertainty", Real),
            ("lower_limit", Real),
            ("upper_limit", Real),
            ("verdict", Text),
        ],
    },
    Spec {
        table: "run_ends",
        since: 4,
        columns: &[("run_id", Int), ("ended_at", Text), ("status", Text), ("message", Text)],
    },
];

/// The spec of a record table.
pub fn spec(table: &str) -> Option<&'static Spec> {
    SPECS.iter().find(|s| s.table == table)
}

/// The chain columns and their indexes for the record tables created by schema `version`.
fn chain_columns(version: i64) -> String {
    let mut s = String::new();
    for sp in SPECS.iter().filter(|sp| sp.since == version) {
        let t = sp.table;
        for c in ["seq {int}", "record_id TEXT", "prev_hash TEXT", "hash TEXT"] {
            s.push_str(&format!("ALTER TABLE {t} ADD COLUMN {c};\n"));
        }
        s.push_str(&format!("CREATE UNIQUE INDEX {t}_seq ON {t} (seq);\n"));
        s.push_str(&format!("CREATE UNIQUE INDEX {t}_record_id ON {t} (record_id);\n"));
        if t != "run_starts" {
            s.push_str(&format!("CREATE INDEX {t}_run ON {t} (run_id);\n"));
        }
    }
    s
}

/// The SQL of migration `version` for dialect `d` (`{chain}`: the chain columns of the tables
/// it creates).
pub(crate) fn render(d: Dialect, version: i64, sql: &str) -> String {
    d.render(&sql.replace("{chain}", &chain_columns(version)))
}

/// Create or migrate the schema forward, in one exclusive transaction (concurrent openers
/// apply each migration exactly once). Refuses, with nothing changed, a database with tables
/// truepos does not create or a schema newer than this build. Nothing is written when the
/// schema is current (a role without CREATE may open it).
pub fn migrate(b: &mut dyn Backend, shown: &str, applied_at: &str) -> Result<(), AuditError> {
    let dbe = |e: BackendError| AuditError::db(shown, e);
    let foreign = |why: String| AuditError::Foreign { path: shown.to_string(), why };
    b.begin_exclusive().map_err(dbe)?;
    let r = (|| -> Result<(), AuditError> {
        let tables = b.tables().map_err(dbe)?;
        if let Some(t) = tables.iter().find(|t| !TABLES.contains(&t.as_str())) {
            return Err(foreign(format!("it has a table '{t}' that truepos does not create")));
        }
        let known = known_version();
        let found = if tables.is_empty() {
            b.execute_batch(&b.dialect().render(
                "CREATE TABLE schema_migrations (version {int} PRIMARY KEY, applied_at TEXT NOT NULL);",
            ))
            .map_err(|e| create_refused(shown, e))?;
            0
        } else if !tables.iter().any(|t| t == "schema_migrations") {
            return Err(foreign("it has no schema_migrations table".into()));
        } else {
            let rows = b
                .query("SELECT MAX(version) FROM schema_migrations", &[])
                .map_err(|e| foreign(format!("its schema_migrations is not truepos's ({e})")))?;
            match rows.first().and_then(|r| r.first()) {
                Some(Value::Int(v)) => *v,
                Some(Value::Null) | None => 0,
                Some(other) => {
                    return Err(foreign(format!(
                        "its schema_migrations holds {other:?}, not version numbers"
                    )))
                }
            }
        };
        if found > known {
            return Err(AuditError::Newer { path: shown.to_string(), found, known });
        }
        for (v, sql) in MIGRATIONS.iter().filter(|m| m.0 > found) {
            let d = b.dialect();
            b.execute_batch(&render(d, *v, sql)).map_err(|e| create_refused(shown, e))?;
            b.execute(
                "INSERT INTO schema_migrations (version, applied_at) VALUES ($1, $2)",
                &[Value::Int(*v), Value::text(applied_at)],
            )
            .map_err(dbe)?;
        }
        Ok(())
    })();
    match r {
        Ok(()) => b.commit().map_err(dbe),
        Err(e) => {
            b.rollback();
            Err(e)
        }
    }
}

/// A migration the role may not run: say who must.
fn create_refused(shown: &str, e: BackendError) -> AuditError {
    if e.message.contains("permission denied") || e.message.contains("must be owner") {
        AuditError::db(
            shown,
            BackendError {
                message: format!(
                    "{}: this role may not create or migrate the audit schema; run `truepos audit migrate \
                     --db {shown}` once as the schema owner (docs/audit.md)",
                    e.message
                ),
                lost: e.lost,
            },
        )
    } else {
        AuditError::db(shown, e)
    }
}
