//! Fuzz target: Parquet point and stream files (`truepos_io::parquet_file::read_columns`, arrow-rs
//! `parquet` underneath) on arbitrary bytes, through the two entry points the CLI uses:
//! `csv::Table::read` (streams, maps, every command reading columns) and `points::read_points`
//! (fit). Either columns of equal length with finite numbers, or an input error that names the
//! file — never a panic, a hang or an unbounded allocation. Streams have no reader of their own:
//! a `.parquet` stream (`t_s`, …) is read by `Table::read` like any other column file.
//! The readers take paths (chosen by the `.parquet` extension), so each input is written to one
//! scratch file in the temporary directory first.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("truepos-fuzz-{}.parquet", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    if std::fs::write(path, data).is_err() {
        return;
    }
    let name = path.display().to_string();
    let named = |e: &dyn std::fmt::Display| {
        let s = e.to_string();
        assert!(s.starts_with(&format!("{name}: ")), "Parquet error without the file: {s}");
    };
    match truepos_io::csv::Table::read(path) {
        Ok(t) => {
            assert!(t.check_rectangular().is_ok());
            for h in t.header.clone() {
                match t.f64_column(&h) {
                    Ok(v) => assert!(v.len() == t.n_rows() && v.iter().all(|x| x.is_finite())),
                    Err(e) => named(&e),
                }
                let _ = t.str_column(&h);
            }
            match truepos_io::points::read_points(path) {
                Ok(set) => {
                    assert_eq!(set.points.len(), t.n_rows());
                    assert!(set.points.iter().all(|p| p.x.is_finite() && p.y.is_finite() && p.z.is_finite()));
                    if let Some(ids) = set.ids {
                        assert_eq!(ids.len(), set.points.len());
                    }
                }
                Err(e) => named(&e),
            }
        }
        Err(e) => named(&e),
    }
});
