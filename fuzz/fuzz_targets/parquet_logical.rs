//! Fuzz target: Parquet columns with logical (and legacy converted) types, structure-aware. The
//! input chooses, per column, a physical type (INT32, INT64), an annotation (none; `INTEGER`
//! of 8–64 bits, signed or not; `UINT_8`…`UINT_64`, `INT_8`…`INT_64`; `DECIMAL(p, s)` of any
//! scale the annotation allows; `DATE`, `TIME`, `TIMESTAMP`, `TIME_MILLIS`) and the values; the
//! file is written with the `parquet` crate (plain or dictionary pages, one or two row groups,
//! optional columns with a null or not) and read back
//! through `truepos_io::parquet_file::read_columns`, what every command reading a `.parquet`
//! file runs.
//!
//! Checked against an independent reading of the same values: an unsigned annotation gives the
//! unsigned value; a decimal gives the stored integer times 10^−scale, bit for bit the
//! correctly rounded decimal (Rust's own parser on "{v}e-{scale}") when the integer is below
//! 2^53, within 2 ulp above; dates, times and timestamps are refused naming the column; a scale
//! outside 0..=22 is refused; a null is refused naming the column and its row. Never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use parquet::data_type::{Int32Type, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};
use truepos_io::parquet_file::{read_columns, ColumnData};

/// What the target expects of a column.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    Plain,
    Unsigned,
    Decimal(i32),
    /// Refused, the message naming this.
    Refused(&'static str),
}

/// Annotation `k` of an INT32 (or INT64) column: its schema text and what is expected of it.
/// Schemas `parquet` does not accept (an annotation on the wrong physical type) end the run.
fn annotation(k: u8, scale: u8, prec: u8, int64: bool) -> (String, Expect) {
    let bits = if int64 { 64 } else { 32 };
    match k % 13 {
        0 => (String::new(), Expect::Plain),
        1 => (format!("(INTEGER({bits},true))"), Expect::Plain),
        2 => (format!("(INTEGER({bits},false))"), Expect::Unsigned),
        3 => ((if int64 { "(UINT_64)" } else { "(UINT_32)" }).into(), Expect::Unsigned),
        4 => ((if int64 { "(INT_64)" } else { "(INT_32)" }).into(), Expect::Plain),
        5 => ("(INTEGER(16,false))".into(), Expect::Unsigned),
        6 | 7 => {
            // DECIMAL(precision, scale): precision 1..=9 (INT32) or 1..=18 (INT64), scale ≤ it.
            let max_p = if int64 { 18 } else { 9 };
            let p = 1 + prec % max_p;
            let s = scale % (p + 1);
            (format!("(DECIMAL({p},{s}))"), Expect::Decimal(i32::from(s)))
        }
        8 if !int64 => ("(DATE)".into(), Expect::Refused("Date")),
        9 => (
            (if int64 { "(TIME(MICROS,true))" } else { "(TIME(MILLIS,true))" }).into(),
            Expect::Refused("Time"),
        ),
        10 if int64 => ("(TIMESTAMP(MILLIS,true))".into(), Expect::Refused("Timestamp")),
        11 if !int64 => ("(TIME_MILLIS)".into(), Expect::Refused("TIME_MILLIS")),
        _ => ("(INTEGER(8,true))".into(), Expect::Plain),
    }
}

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| {
        std::env::temp_dir().join(format!("truepos-fuzz-logical-{}.parquet", std::process::id()))
    })
}

struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }
    fn i64(&mut self) -> i64 {
        let mut v = [0u8; 8];
        for b in v.iter_mut() {
            *b = self.u8();
        }
        i64::from_le_bytes(v)
    }
}

/// The independent value of stored integer `v` under `e`: what the column must hold.
fn expected(v: i64, int64: bool, e: Expect) -> f64 {
    match e {
        Expect::Unsigned if int64 => v as u64 as f64,
        Expect::Unsigned => v as i32 as u32 as f64,
        Expect::Decimal(s) => format!("{v}e-{s}").parse::<f64>().unwrap_or(f64::NAN),
        _ => v as f64,
    }
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let n_cols = 1 + usize::from(b.u8() % 3);
    let rows = usize::from(b.u8() % 8);
    let flags = b.u8();
    let (dictionary, two_groups, optional, nulls) =
        (flags & 1 != 0, flags & 2 != 0, flags & 4 != 0, flags & 8 != 0);
    let mut fields = Vec::new();
    let mut cols = Vec::new();
    for c in 0..n_cols {
        let int64 = b.u8() & 1 != 0;
        let (k, scale, prec) = (b.u8(), b.u8(), b.u8());
        let (ann, e) = annotation(k, scale, prec, int64);
        let values: Vec<i64> = (0..rows)
            .map(|_| {
                let v = b.i64();
                if int64 {
                    v
                } else {
                    i64::from(v as i32)
                }
            })
            .collect();
        fields.push(format!(
            "{} {} c{c} {ann};",
            if optional { "optional" } else { "required" },
            if int64 { "int64" } else { "int32" }
        ));
        cols.push((int64, e, values));
    }
    let schema = format!("message m {{ {} }}", fields.join(" "));
    let Ok(schema) = parquet::schema::parser::parse_message_type(&schema) else { return };
    let props = WriterProperties::builder().set_dictionary_enabled(dictionary).build();
    let path = scratch();
    let Ok(file) = std::fs::File::create(path) else { return };
    let Ok(mut w) = SerializedFileWriter::new(file, Arc::new(schema), Arc::new(props)) else { return };
    // The null (if any): the last row of the first column.
    let null_at = (optional && nulls && rows > 0).then(|| rows - 1);
    let groups: Vec<(usize, usize)> =
        if two_groups && rows > 1 { vec![(0, rows / 2), (rows / 2, rows)] } else { vec![(0, rows)] };
    for (a, z) in &groups {
        let Ok(mut rg) = w.next_row_group() else { return };
        let mut c = 0;
        while let Ok(Some(mut col)) = rg.next_column() {
            let (int64, _, values) = &cols[c];
            let defs: Vec<i16> = (*a..*z).map(|r| if c == 0 && Some(r) == null_at { 0 } else { 1 }).collect();
            let vals: Vec<i64> =
                (*a..*z).filter(|&r| !(c == 0 && Some(r) == null_at)).map(|r| values[r]).collect();
            let defs = optional.then_some(&defs[..]);
            let ok = if *int64 {
                col.typed::<Int64Type>().write_batch(&vals, defs, None).is_ok()
            } else {
                let v32: Vec<i32> = vals.iter().map(|&v| v as i32).collect();
                col.typed::<Int32Type>().write_batch(&v32, defs, None).is_ok()
            };
            if !ok || col.close().is_err() {
                return;
            }
            c += 1;
        }
        if rg.close().is_err() {
            return;
        }
    }
    if w.close().is_err() {
        return;
    }
    let name = path.display().to_string();
    match read_columns(path) {
        Ok(got) => {
            assert!(
                cols.iter().all(|(_, e, _)| !matches!(e, Expect::Refused(_))),
                "a refused type was read: {cols:?}"
            );
            assert!(null_at.is_none(), "a null was read as a value");
            for (c, (int64, e, values)) in cols.iter().enumerate() {
                let Some(ColumnData::F64(v)) = got.data.get(c) else { panic!("column c{c} missing or text") };
                assert_eq!(v.len(), rows);
                for (r, (&x, &stored)) in v.iter().zip(values).enumerate() {
                    let want = expected(stored, *int64, *e);
                    let exact = stored.unsigned_abs() < (1 << 53) || !matches!(e, Expect::Decimal(_));
                    if exact {
                        assert_eq!(
                            x.to_bits(),
                            want.to_bits(),
                            "c{c} row {r}: {stored} as {e:?}: {x} vs {want}"
                        );
                    } else {
                        let ulp = f64::from_bits(want.abs().to_bits() + 1) - want.abs();
                        assert!(
                            (x - want).abs() <= 2.0 * ulp,
                            "c{c} row {r}: {stored} as {e:?}: {x} vs {want}"
                        );
                    }
                }
            }
        }
        Err(err) => {
            let s = err.to_string();
            assert!(s.starts_with(&format!("{name}:")), "error without the file: {s}");
            let refused = cols.iter().enumerate().find_map(|(c, (_, e, _))| match e {
                Expect::Refused(what) => Some((c, *what)),
                _ => None,
            });
            match (refused, null_at) {
                (Some((c, what)), _) => {
                    assert!(s.contains(&format!("column 'c{c}'")) && s.contains(what), "{s}")
                }
                (None, Some(r)) => {
                    assert!(
                        s.contains("column 'c0'")
                            && s.contains(&format!("row {}", r + 1))
                            && s.contains("null"),
                        "{s}"
                    )
                }
                (None, None) => panic!("a valid file was refused: {s} ({cols:?})"),
            }
        }
    }
});
