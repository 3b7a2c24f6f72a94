//! Fuzz target: CSV indexing and typed parsing never panic, and every error names the file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use truepos_io::csv::Table;

fuzz_target!(|data: &[u8]| {
    match Table::from_bytes("fuzz.csv", data.to_vec()) {
        Ok(t) => {
            for cols in [&["x_mm", "y_mm", "z_mm"][..], &[], &["x_mm"]] {
                if let Ok(v) = t.f64_columns(cols) {
                    assert_eq!(v.len(), cols.len() * t.n_rows());
                    assert!(v.iter().all(|x| x.is_finite()));
                } else if let Err(e) = t.f64_columns(cols) {
                    assert!(e.file.is_some());
                }
            }
            // Every header column through the typed and text accessors.
            for name in t.header.clone() {
                let _ = t.f64_column(&name);
                let _ = t.str_column(&name);
            }
            let _ = t.check_rectangular();
            for r in 0..t.n_rows().min(16) {
                let _ = t.line_number(r);
                let _ = t.row_text(r);
            }
        }
        Err(e) => assert!(e.file.is_some()),
    }
});
