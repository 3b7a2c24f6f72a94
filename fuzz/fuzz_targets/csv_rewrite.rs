//! Fuzz target: the streamed point rewrite (`truepos_io::stream::rewrite_points`, what `comp
//! correct` and `load correct` run: reader thread, row index, split-and-parse, pass-through,
//! formatting) never panics and agrees with the general CSV reader: it succeeds exactly when
//! the general reader parses every row's x_mm,y_mm,z_mm, then writes every row with x moved by
//! one and every other column's text kept (column names with a comma, a quote or a byte-order mark are refused);
//! otherwise its error names the file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use truepos_io::csv::Table;
use truepos_io::stream::rewrite_points;

fuzz_target!(|data: &[u8]| {
    // One directory per fuzzing process (in memory where there is /dev/shm), reused per input.
    let base = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm" } else { "/tmp" };
    let dir = std::path::PathBuf::from(format!("{base}/truepos-fuzz-rewrite-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary directory");
    let inp = dir.join("in.csv");
    let out = dir.join("out.csv");
    let _ = std::fs::remove_file(&out);
    std::fs::write(&inp, data).expect("write input");
    let general = Table::from_bytes(&inp, data.to_vec()).and_then(|t| t.f64_rows(&["x_mm", "y_mm", "z_mm"]).map(|v| (t, v)));
    let r = rewrite_points(
        &inp,
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
    // Column names holding a comma or a quote are refused by the rewrite (they could not be
    // written back unchanged).
    let unwritable = general.as_ref().is_ok_and(|(t, _)| t.header.iter().any(|n| n.contains([',', '"', '\u{feff}'])));
    if unwritable {
        assert!(r.is_err(), "a column name with a comma or quote was accepted");
        assert!(!out.exists(), "no output after an error");
        return;
    }
    match (general, r) {
        (Ok((t, v)), Ok(sum)) => {
            assert_eq!(sum.n_points, v.len());
            let o = Table::read(&out).expect("the output reads back");
            let x = o.f64_column("x_mm").expect("x_mm");
            assert!(x.iter().zip(&v).all(|(a, b)| a.to_bits() == (b[0] + 1.0).to_bits()));
            for name in &t.header {
                if !["x_mm", "y_mm", "z_mm", "dx_um", "dy_um", "dz_um"].contains(&name.as_str()) {
                    assert_eq!(t.str_column(name).ok(), o.str_column(name).ok(), "{name}");
                }
            }
        }
        (Err(_), Err(e)) => {
            assert!(!out.exists(), "no output after an error");
            if let truepos_io::stream::RewriteError::Input(e) = e {
                assert!(e.file.is_some());
            }
        }
        (g, r) => panic!("general reader {:?} but rewrite {:?}", g.map(|(_, v)| v.len()), r.map(|s| s.n_points)),
    }
});
