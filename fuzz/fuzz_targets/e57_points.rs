//! Fuzz target: E57 point clouds (`truepos_io::e57_file`, the `e57` crate underneath) on arbitrary
//! bytes, through the two entry points the CLI uses: `points::read_points` (fit) and
//! `csv::Table::read` (every other command that takes points). Either the points (all finite, in
//! mm) or an input error that names the file — never a panic, a hang or an unbounded allocation.
//! The readers take paths (chosen by the `.e57` extension), so each input is written to one
//! scratch file in the temporary directory first.
//!
//! Every 1024-byte E57 page ends in a CRC-32C of its first 1020 bytes, so almost every mutation
//! of a real file would stop at the first checksum. The input is therefore zero-padded to whole
//! pages and every page's checksum recomputed before it is written: the mutations reach the
//! header, the XML section and the binary (bit-packed) sections. (A wrong checksum is one error
//! path, covered by the `e57_file` unit tests.)
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("truepos-fuzz-{}.e57", std::process::id())))
}

const PAGE: usize = 1024;

/// CRC-32C (Castagnoli), as E57 pages carry it.
fn crc32c(data: &[u8]) -> u32 {
    static TABLE: OnceLock<[u32; 256]> = OnceLock::new();
    let t = TABLE.get_or_init(|| {
        let mut t = [0_u32; 256];
        for (i, e) in t.iter_mut().enumerate() {
            let mut v = i as u32;
            for _ in 0..8 {
                v = if v & 1 == 0 { v >> 1 } else { (v >> 1) ^ 0x82F6_3B78 };
            }
            *e = v;
        }
        t
    });
    !data.iter().fold(!0_u32, |c, &b| t[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8))
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    let mut bytes = data.to_vec();
    bytes.resize(data.len().div_ceil(PAGE) * PAGE, 0);
    for page in bytes.chunks_exact_mut(PAGE) {
        let crc = crc32c(&page[..PAGE - 4]);
        page[PAGE - 4..].copy_from_slice(&crc.to_be_bytes());
    }
    if std::fs::write(path, &bytes).is_err() {
        return;
    }
    let name = path.display().to_string();
    match truepos_io::points::read_points(path) {
        Ok(set) => {
            assert!(set.points.iter().all(|p| p.x.is_finite() && p.y.is_finite() && p.z.is_finite()));
            assert!(set.ids.is_none());
            // The same file as a table: the same points as x_mm,y_mm,z_mm, the same count skipped.
            let t = truepos_io::csv::Table::read(path).expect("a readable E57 reads as a table");
            assert_eq!((t.n_rows(), t.skipped_invalid), (set.points.len(), set.skipped_invalid));
            let xyz = t.f64_rows(&["x_mm", "y_mm", "z_mm"]).expect("finite columns");
            for (r, p) in xyz.iter().zip(&set.points) {
                assert_eq!(r, &[p.x, p.y, p.z]);
            }
        }
        Err(e) => {
            assert!(e.to_string().starts_with(&format!("{name}:")), "E57 error without the file: {e}");
        }
    }
});
