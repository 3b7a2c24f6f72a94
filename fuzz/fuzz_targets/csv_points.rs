//! Fuzz target: the direct point and stream readers (`truepos_io::points::read_points`, what
//! `truepos fit` runs, and `csv::Table::read_stream_direct`, what `truepos latency` runs: rows
//! parsed straight from the text, plain rows by delimiter blocks and SSSE3 number conversion
//! where the CPU has it) never panic and agree with the general CSV reader bit for bit: the same
//! points (and ids) or stream values when it parses every row, else the same error (file, line,
//! column, message).
#![no_main]

use libfuzzer_sys::fuzz_target;
use truepos_io::csv::Table;

fuzz_target!(|data: &[u8]| {
    // One directory per fuzzing process (in memory where there is /dev/shm), reused per input.
    let base = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm" } else { "/tmp" };
    let dir = std::path::PathBuf::from(format!("{base}/truepos-fuzz-points-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary directory");
    let inp = dir.join("in.csv");
    std::fs::write(&inp, data).expect("write input");
    let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();

    let general = Table::from_bytes(&inp, data.to_vec());
    let want = general.as_ref().map_err(|e| e.to_string()).and_then(|t| {
        let p = t.f64_rows(&["x_mm", "y_mm", "z_mm"]).map_err(|e| e.to_string())?;
        let ids = match t.column("id") {
            Some(_) => Some(t.str_column("id").map_err(|e| e.to_string())?),
            None => None,
        };
        Ok((bits(&p), ids))
    });
    let got = truepos_io::points::read_points(&inp).map(|s| {
        let p: Vec<[f64; 3]> = s.points.iter().map(|q| [q.x, q.y, q.z]).collect();
        (bits(&p), s.ids)
    });
    match (&want, &got) {
        (Ok(w), Ok(g)) => assert_eq!(w, g, "points differ"),
        (Err(w), Err(g)) => {
            assert!(g.file.is_some());
            assert_eq!(w, &g.to_string(), "errors differ");
        }
        _ => panic!("general {:?} but direct {:?}", want.as_ref().map(|w| w.0.len()), got.as_ref().map(|g| g.0.len())),
    }

    // Streams: t_s and three values per row.
    let names = ["t_s", "x_mm", "y_mm", "z_mm"];
    match Table::read_stream_direct(&inp, &names) {
        Ok(Ok((t, v))) => {
            let g = general.as_ref().expect("the direct stream read a file the general reader refuses");
            let gt = g.f64_column("t_s").expect("general t_s");
            let gv = g.f64_rows(&["x_mm", "y_mm", "z_mm"]).expect("general values");
            assert_eq!(t.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), gt.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
            assert_eq!(bits(&v), bits(&gv));
        }
        Ok(Err(table)) => {
            // Not the plain case: the table is the general reader's.
            let g = general.as_ref().expect("a table from a file the general reader refuses");
            assert_eq!(table.header, g.header);
            assert_eq!(table.n_rows(), g.n_rows());
        }
        Err(e) => {
            assert!(e.file.is_some());
            assert_eq!(Some(e.to_string()), general.as_ref().err().map(|e| e.to_string()));
        }
    }
});
