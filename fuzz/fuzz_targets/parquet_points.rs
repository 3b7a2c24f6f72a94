//! Fuzz target: Parquet point and stream files (`truepos_io::parquet_file::read_columns`, arrow-rs
//! `parquet` underneath) on arbitrary bytes, through the two entry points the CLI uses:
//! `csv::Table::read` (streams, maps, every command reading columns) and `points::read_points`
//! (fit). Either columns of equal length with finite numbers, or an input error that names the
//! file — never a panic, a hang or an unbounded allocation. The streamed point rewrite
//! (`stream::rewrite_points`, what `comp correct` runs on a `.parquet` input) is run on the same
//! file: an error names the file and leaves no output. Streams have no reader of their own:
//! a `.parquet` stream (`t_s`, …) is read by `Table::read` like any other column file.
//! The readers take paths (chosen by the `.parquet` extension), so each input is written to one
//! scratch file in the temporary directory first.
//!
//! `read_columns` contains panics of the `parquet` decoder (it asserts on some malformed pages)
//! and turns them into input errors. libFuzzer's panic hook would abort on those before they
//! are caught, so this target lets a panic whose location is inside the `parquet` crate unwind
//! (printing its location once, to see which asserts the inputs reach); any other panic — in
//! truepos, or one that escapes the reader — aborts and is reported as a crash as usual.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::{Mutex, Once, OnceLock};

fn contain_parquet_panics() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        // Decoded values are held to the input limit (8 bytes a number): with the default 2 GiB
        // they could legitimately reach the fuzzer's 2 GB memory limit. 64 MiB keeps a legitimate
        // large decode far below it, so an out-of-memory report means a real unbounded allocation.
        std::env::set_var("TRUEPOS_MAX_INPUT_MB", "64");
        let fuzzer_hook = std::panic::take_hook();
        let seen = Mutex::new(HashSet::new());
        std::panic::set_hook(Box::new(move |info| match info.location() {
            Some(l) if l.file().contains("/parquet-") => {
                if seen.lock().is_ok_and(|mut s| s.insert((l.file().to_string(), l.line()))) {
                    eprintln!("contained parquet panic at {l}: {}", info.payload_as_str().unwrap_or(""));
                }
            }
            _ => fuzzer_hook(info),
        }));
    });
}

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("truepos-fuzz-{}.parquet", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    contain_parquet_panics();
    let path = scratch();
    if std::fs::write(path, data).is_err() {
        return;
    }
    let name = path.display().to_string();
    let named = |e: &dyn std::fmt::Display| {
        let s = e.to_string();
        assert!(s.starts_with(&format!("{name}:")), "Parquet error without the file: {s}");
    };
    let table = truepos_io::csv::Table::read(path);
    rewrite(path, table.as_ref().ok(), &named);
    match table {
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

/// The streamed point rewrite (`comp correct` of a `.parquet` input: `ParquetReader` in
/// batches, pieces, the CSV writer) into CSV: an error names the file and leaves no output;
/// a success on a file the table reader reads too writes every row, x moved by one.
fn rewrite(
    path: &std::path::Path,
    table: Option<&truepos_io::csv::Table>,
    named: &dyn Fn(&dyn std::fmt::Display),
) {
    let out = path.with_extension("out.csv");
    let _ = std::fs::remove_file(&out);
    let r = truepos_io::stream::rewrite_points(
        path,
        &out,
        ["dx_um", "dy_um", "dz_um"],
        Default::default(),
        |_, p, e| {
            for (q, d) in p.iter_mut().zip(e.iter_mut()) {
                q.x += 1.0;
                *d = [1.0, 2.0, 3.0];
            }
            Ok::<(), (usize, String)>(())
        },
        |_| {},
    );
    match r {
        Err(e) => {
            named(&e);
            assert!(!out.exists(), "an output after an error");
        }
        Ok(sum) => {
            // The table reader may refuse what the rewrite reads (its CSV text has limits of its
            // own, e.g. the line length); where it reads the file, the rows agree.
            if let Some(t) = table {
                assert_eq!(sum.n_points, t.n_rows());
                let x = t.f64_column("x_mm").expect("x_mm of a rewritten file");
                let o = truepos_io::csv::Table::read(&out).expect("the output reads back");
                let x2 = o.f64_column("x_mm").expect("x_mm");
                assert!(x.iter().zip(&x2).all(|(a, b)| (a + 1.0).to_bits() == b.to_bits()));
            }
            let _ = std::fs::remove_file(&out);
        }
    }
}
