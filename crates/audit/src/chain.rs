//! The hash chain. Every record (a row of a [`SPECS`] table) has a place
//! `seq` in the database's single chain (1, 2, 3, … across all tables and runs), a writer-chosen
//! unique `record_id`, the `hash` of the record before it (`prev_hash`, 64 zeros for the first)
//! and its own `hash`:
//!
//! ```text
//! hash = hex(SHA-256(prev_hash ‖ "\n" ‖ canonical))
//! canonical = table ‖ "|seq=" seq ‖ "|record_id=" json(record_id) ‖ ("|" column "=" value)*
//! value = "null" | "i:" decimal | "r:" 16 hex digits of the IEEE-754 bits | "t:" json(text)
//! ```
//!
//! so a changed value, a deleted or inserted record, or a record moved to another run breaks
//! the chain at that record ([`verify`]). A batch is appended in one exclusive transaction
//! ([`append`]); appending a batch whose first record id is already there does nothing, so a
//! batch resent after a lost acknowledgement is stored exactly once.

use crate::backend::{exclusive, Backend, BackendError, Value};
use crate::schema::{spec, Kind, Spec, SPECS};
use sha2::{Digest, Sha256};

/// The `prev_hash` of the first record.
pub const GENESIS: &str = "0000000000000000000000000000000000000000000000000000000000000000";

/// One record to append: its table, writer-chosen id, and values in the spec's column order.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// The table the record goes to.
    pub table: &'static str,
    /// The writer-chosen id, unique in the table (a retried batch is recognised by it).
    pub record_id: String,
    /// The values, in the table spec's column order.
    pub values: Vec<Value>,
}

/// The canonical text of a record at `seq` (what is hashed).
pub fn canonical(
    table: &str,
    seq: i64,
    record_id: &str,
    columns: &[(&str, Kind)],
    values: &[Value],
) -> String {
    let mut s = format!("{table}|seq={seq}|record_id={}", json_str(record_id));
    for ((name, _), v) in columns.iter().zip(values) {
        s.push('|');
        s.push_str(name);
        s.push('=');
        match v {
            Value::Null => s.push_str("null"),
            Value::Int(i) => s.push_str(&format!("i:{i}")),
            Value::Real(x) => s.push_str(&format!("r:{:016x}", x.to_bits())),
            Value::Text(t) => {
                s.push_str("t:");
                s.push_str(&json_str(t));
            }
        }
    }
    s
}

fn json_str(s: &str) -> String {
    serde_json::Value::String(s.to_string()).to_string()
}

/// `hex(SHA-256(prev ‖ "\n" ‖ canonical))`.
pub fn link(prev: &str, canonical: &str) -> String {
    let mut h = Sha256::new();
    h.update(prev.as_bytes());
    h.update(b"\n");
    h.update(canonical.as_bytes());
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The chain's last record: (seq, hash), or (0, [`GENESIS`]) when empty.
pub fn head(b: &mut dyn Backend) -> Result<(i64, String), BackendError> {
    let union = SPECS.iter().map(|s| format!("SELECT MAX(seq) AS m FROM {}", s.table)).collect::<Vec<_>>();
    let rows = b.query(&format!("SELECT MAX(m) FROM ({}) x", union.join(" UNION ALL ")), &[])?;
    let seq = match rows.first().and_then(|r| r.first()) {
        Some(Value::Int(s)) => *s,
        _ => return Ok((0, GENESIS.to_string())),
    };
    let union = SPECS
        .iter()
        .enumerate()
        .map(|(i, s)| format!("SELECT hash FROM {} WHERE seq = ${}", s.table, i + 1))
        .collect::<Vec<_>>();
    let params = vec![Value::Int(seq); SPECS.len()];
    let rows = b.query(&union.join(" UNION ALL "), &params)?;
    let hash = rows
        .first()
        .and_then(|r| r.first())
        .and_then(Value::as_str)
        .map(str::to_string)
        .unwrap_or_else(|| GENESIS.to_string());
    Ok((seq, hash))
}

fn insert_sql(sp: &Spec) -> String {
    let cols: Vec<&str> =
        sp.columns.iter().map(|c| c.0).chain(["seq", "record_id", "prev_hash", "hash"]).collect();
    let marks: Vec<String> = (1..=cols.len()).map(|i| format!("${i}")).collect();
    format!("INSERT INTO {} ({}) VALUES ({})", sp.table, cols.join(", "), marks.join(", "))
}

/// Whether a record id is already stored.
pub fn stored(b: &mut dyn Backend, r: &Record) -> Result<bool, BackendError> {
    let rows = b.query(
        &format!("SELECT COUNT(*) FROM {} WHERE record_id = $1", r.table),
        &[Value::text(&r.record_id)],
    )?;
    Ok(rows.first().and_then(|r| r.first()).and_then(Value::as_i64).unwrap_or(0) > 0)
}

/// Insert `batch` at the head, inside the caller's exclusive transaction. Returns the new head.
pub fn append_in(b: &mut dyn Backend, batch: &[Record]) -> Result<(i64, String), BackendError> {
    let (mut seq, mut prev) = head(b)?;
    for r in batch {
        let sp = spec(r.table)
            .ok_or_else(|| BackendError { message: format!("no table {}", r.table), lost: false })?;
        seq += 1;
        let hash = link(&prev, &canonical(sp.table, seq, &r.record_id, sp.columns, &r.values));
        let mut params = r.values.clone();
        params.extend([Value::Int(seq), Value::text(&r.record_id), Value::text(&prev), Value::text(&hash)]);
        b.execute(&insert_sql(sp), &params)?;
        prev = hash;
    }
    Ok((seq, prev))
}

/// Append a batch in one exclusive transaction; a batch already stored (its first record id is
/// there) is left alone. Returns whether it was written now.
pub fn append(b: &mut dyn Backend, batch: &[Record]) -> Result<bool, BackendError> {
    let Some(first) = batch.first() else { return Ok(false) };
    exclusive(b, |b| -> Result<bool, BackendError> {
        if stored(b, first)? {
            return Ok(false);
        }
        append_in(b, batch)?;
        Ok(true)
    })
}

/// A record read back, with its chain columns.
#[derive(Debug, Clone)]
pub struct Stored {
    /// The table the record is in.
    pub table: &'static str,
    /// Position in the chain (1-based, over all tables).
    pub seq: i64,
    /// The writer-chosen id.
    pub record_id: String,
    /// Hash of the previous record in the chain (hex).
    pub prev_hash: String,
    /// This record's hash (hex), over its values and `prev_hash`.
    pub hash: String,
    /// The values, in the table spec's column order.
    pub values: Vec<Value>,
}

impl Stored {
    /// The column spec of the record's table.
    pub fn spec(&self) -> &'static Spec {
        spec(self.table).expect("read from a spec table")
    }

    /// Value of a column by name.
    pub fn get(&self, column: &str) -> Option<&Value> {
        self.spec().columns.iter().position(|c| c.0 == column).and_then(|i| self.values.get(i))
    }

    /// The record as a JSON object (chain columns and named values).
    pub fn to_json(&self) -> serde_json::Value {
        let fields: serde_json::Map<String, serde_json::Value> = self
            .spec()
            .columns
            .iter()
            .zip(&self.values)
            .map(|((n, _), v)| (n.to_string(), v.to_json()))
            .collect();
        serde_json::json!({
            "seq": self.seq, "table": self.table, "record_id": self.record_id,
            "prev_hash": self.prev_hash, "hash": self.hash, "fields": fields,
        })
    }
}

fn coerce(v: Value, k: Kind) -> Value {
    match (v, k) {
        (Value::Int(i), Kind::Real) => Value::Real(i as f64),
        (v, _) => v,
    }
}

/// Read the chained records of `table` (optionally of one run), in chain order.
pub fn read_table(
    b: &mut dyn Backend,
    sp: &'static Spec,
    run: Option<i64>,
) -> Result<Vec<Stored>, BackendError> {
    let cols: Vec<&str> = sp.columns.iter().map(|c| c.0).collect();
    let run_col = if sp.table == "run_starts" { "id" } else { "run_id" };
    let (filter, params) = match run {
        Some(id) => (format!(" AND {run_col} = $1"), vec![Value::Int(id)]),
        None => (String::new(), vec![]),
    };
    let sql = format!(
        "SELECT {}, seq, record_id, prev_hash, hash FROM {} WHERE seq IS NOT NULL{filter} ORDER BY seq",
        cols.join(", "),
        sp.table
    );
    let n = cols.len();
    let rows = b.query(&sql, &params)?;
    Ok(rows
        .into_iter()
        .map(|mut r| {
            let tail = r.split_off(n);
            let text = |i: usize| tail.get(i).and_then(Value::as_str).unwrap_or("").to_string();
            Stored {
                table: sp.table,
                seq: tail.first().and_then(Value::as_i64).unwrap_or(0),
                record_id: text(1),
                prev_hash: text(2),
                hash: text(3),
                values: r.into_iter().zip(sp.columns).map(|(v, (_, k))| coerce(v, *k)).collect(),
            }
        })
        .collect())
}

/// Rows written before the chain existed (schema < 4): not verifiable, counted.
pub fn legacy_count(b: &mut dyn Backend) -> Result<i64, BackendError> {
    let mut n = 0;
    for sp in SPECS {
        let rows = b.query(
            &format!("SELECT COUNT(*) FROM {} WHERE seq IS NULL AND record_id IS NULL", sp.table),
            &[],
        )?;
        n += rows.first().and_then(|r| r.first()).and_then(Value::as_i64).unwrap_or(0);
    }
    Ok(n)
}

/// The first record where the chain breaks.
#[derive(Debug, Clone, PartialEq)]
pub struct Break {
    /// Chain position of the broken record.
    pub seq: i64,
    /// The table the broken record is in.
    pub table: String,
    /// The broken record's id.
    pub record_id: String,
    /// What is wrong with it, as a sentence.
    pub problem: String,
}

/// The outcome of [`verify`].
#[derive(Debug, Clone)]
pub struct Verification {
    /// Chained records checked.
    pub records: i64,
    /// Rows from before the chain (schema < 4).
    pub legacy_records: i64,
    /// The last record (seq, hash): keep it elsewhere to detect a later truncation.
    pub head: (i64, String),
    /// The first record where the chain breaks, if it does.
    pub first_broken: Option<Break>,
}

/// Recompute the whole chain: every hash from its record's content and the previous hash, the
/// sequence 1, 2, 3, … without gap or repeat. Stops at the first broken record. `anchor`: a
/// head (`seq`, `hash`) printed by an earlier verify and kept elsewhere; it detects what the
/// chain alone cannot, records deleted at its end.
pub fn verify(b: &mut dyn Backend, anchor: Option<(i64, &str)>) -> Result<Verification, BackendError> {
    let mut all = Vec::new();
    for sp in SPECS {
        all.extend(read_table(b, sp, None)?);
    }
    // Rows that lost their place (seq cleared) but kept their id were chained: tampering.
    let mut orphan = None;
    for sp in SPECS {
        let rows = b.query(
            &format!(
                "SELECT record_id FROM {} WHERE seq IS NULL AND record_id IS NOT NULL LIMIT 1",
                sp.table
            ),
            &[],
        )?;
        if let Some(id) = rows.first().and_then(|r| r.first()).and_then(Value::as_str) {
            orphan = Some((sp.table, id.to_string()));
            break;
        }
    }
    all.sort_by_key(|r| r.seq);
    let legacy_records = legacy_count(b)?;
    let mut prev = GENESIS.to_string();
    let mut first_broken = None;
    for (i, r) in all.iter().enumerate() {
        let expect = i as i64 + 1;
        let brk = |problem: String| Break {
            seq: r.seq,
            table: r.table.to_string(),
            record_id: r.record_id.clone(),
            problem,
        };
        let problem = if r.seq < expect {
            Some(format!("a second record with seq {} (a record was inserted)", r.seq))
        } else if r.seq > expect {
            Some(format!(
                "seq jumps from {} to {} (record{} {} missing: deleted)",
                expect - 1,
                r.seq,
                if r.seq - expect > 1 { "s" } else { "" },
                if r.seq - expect > 1 { format!("{expect}..{}", r.seq - 1) } else { expect.to_string() }
            ))
        } else if r.prev_hash != prev {
            Some("prev_hash is not the hash of the record before it (a record was replaced)".to_string())
        } else if link(&prev, &canonical(r.table, r.seq, &r.record_id, r.spec().columns, &r.values)) != r.hash
        {
            Some("its content does not match its hash (the record was changed)".to_string())
        } else {
            None
        };
        if let Some(p) = problem {
            first_broken = Some(brk(p));
            break;
        }
        prev = r.hash.clone();
    }
    if first_broken.is_none() {
        if let Some((table, id)) = orphan {
            first_broken = Some(Break {
                seq: 0,
                table: table.to_string(),
                record_id: id,
                problem: "a chained record has lost its seq (taken out of the chain)".to_string(),
            });
        }
    }
    let head = all.last().map_or((0, GENESIS.to_string()), |r| (r.seq, r.hash.clone()));
    // A head kept elsewhere earlier: the record at its seq must still be there, unchanged.
    if let (None, Some((seq, hash))) = (&first_broken, anchor) {
        let problem = match all.iter().find(|r| r.seq == seq) {
            Some(r) if r.hash == hash => None,
            Some(r) => Some((
                r.table.to_string(),
                r.record_id.clone(),
                format!("the kept head says hash {hash}, the chain has {} (the chain was rewritten)", r.hash),
            )),
            None => Some((
                String::new(),
                String::new(),
                format!(
                    "the kept head is record {seq} but the chain ends at {} (records at its end were deleted)",
                    head.0
                ),
            )),
        };
        if let Some((table, record_id, problem)) = problem {
            first_broken = Some(Break { seq, table, record_id, problem });
        }
    }
    Ok(Verification { records: all.len() as i64, legacy_records, head, first_broken })
}
