//! E57 point clouds (ASTM E2807, what laser scanners and trackers export) as point files, chosen
//! by the `.e57` extension, read with the `e57` crate.
//!
//! - [`read_e57`]: every scan (E57 "data3D") of the file, concatenated in file order, in the
//!   file's common frame (each scan's pose applied), in **mm** (E57 stores metres: converted
//!   here, at the edge). Scans recorded in spherical coordinates (range, azimuth, elevation) are
//!   converted to Cartesian ones by the `e57` crate. Points whose coordinates are not valid
//!   (`cartesianInvalidState` 1 = direction only, 2 = invalid; or the spherical equivalents),
//!   or not finite numbers once in mm, are skipped and counted. A file that is not a readable E57 is an input error naming it (and
//!   the scan, when one is broken).
//! - [`E57Source`]: the same points in batches, in constant memory (the `e57` crate reads the
//!   binary sections packet by packet): what the streamed point rewrite
//!   ([`crate::stream::rewrite_points`]) reads.
//! - [`write_e57`]: points in mm as one Cartesian scan of doubles, written atomically (for
//!   tests and exchange).
//!
//! Where E57 points reach the rest of truepos: [`crate::points::read_points`] (fit),
//! [`crate::csv::Table::read`] (columns `x_mm,y_mm,z_mm`) and, streamed,
//! [`crate::stream::rewrite_points`] (`comp correct`, `load correct`).

use crate::atomic::OutputError;
use crate::InputError;
use e57::{CartesianCoordinate, E57Reader, E57Writer, Record, RecordValue};
use std::path::Path;
use truepos_math::Point3;

/// Millimetres per metre.
const MM_PER_M: f64 = 1000.0;

/// The points of an E57 file.
#[derive(Debug, Clone, PartialEq)]
pub struct E57Points {
    /// Valid points of every scan, in mm, in file order.
    pub points: Vec<Point3>,
    /// Points skipped because their coordinates are marked invalid (or direction only).
    pub skipped_invalid: usize,
    /// Scans (point clouds) in the file.
    pub scans: usize,
}

/// Whether `path` is chosen as E57 (by its extension, any case).
pub fn is_e57(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("e57"))
}

fn e57_err(path: &Path, e: impl std::fmt::Display) -> InputError {
    InputError::in_file(path, format!("not a readable E57 file: {e}"))
}

/// Read every scan of an E57 file (see the module docs).
pub fn read_e57(path: &Path) -> Result<E57Points, InputError> {
    let mut points = Vec::new();
    let (skipped_invalid, scans) = E57Source::open(path)?.for_each_batch(usize::MAX, |b| {
        if points.is_empty() {
            points = b;
        } else {
            points.extend_from_slice(&b);
        }
        true
    })?;
    Ok(E57Points { points, skipped_invalid, scans })
}

/// An E57 file opened, its XML read and its point counts checked, ready to be read scan by scan
/// in batches ([`for_each_batch`](Self::for_each_batch)): the `e57` crate reads the binary
/// sections packet by packet, so memory holds one batch whatever the file's size.
pub struct E57Source {
    path: std::path::PathBuf,
    reader: E57Reader<std::io::BufReader<std::fs::File>>,
    clouds: Vec<e57::PointCloud>,
    announced: u64,
}

impl E57Source {
    /// Open `path` and check what can be checked before reading points.
    pub fn open(path: &Path) -> Result<Self, InputError> {
        let file =
            std::fs::File::open(path).map_err(|e| InputError::in_file(path, format!("cannot read: {e}")))?;
        crate::atomic::note_input(path);
        let meta = file.metadata().map_err(|e| InputError::in_file(path, format!("cannot read: {e}")))?;
        if meta.is_dir() {
            return Err(InputError::in_file(path, "is a directory, not a file"));
        }
        crate::limits::check_file_size(path, &meta)?;
        let reader = E57Reader::new(std::io::BufReader::new(file)).map_err(|e| e57_err(path, e))?;
        let clouds = reader.pointclouds();
        // The point counts come from the file's XML: bounded before anything is allocated or
        // read. Every stored point takes at least one bit of the file, so a file of S bytes
        // holds at most 8·S points; more announced is a broken (or hostile) file, refused
        // instead of a reservation or a read loop of billions of points from a few kilobytes.
        let announced = clouds.iter().fold(0_u64, |n, c| n.saturating_add(c.records));
        let most = meta.len().saturating_mul(8);
        if announced > most {
            return Err(e57_err(
                path,
                format!(
                    "its scans announce {announced} points, more than a file of {} bytes can hold",
                    meta.len()
                ),
            ));
        }
        Ok(Self { path: path.to_path_buf(), reader, clouds, announced })
    }

    /// Read every scan in file order and hand the valid points (mm, in the file's common frame)
    /// to `sink` in batches of `batch` points (the last one shorter; none for a file without
    /// points). Reading stops, without an error, when `sink` returns `false`. Returns the points
    /// skipped as invalid and the number of scans.
    pub fn for_each_batch(
        mut self,
        batch: usize,
        mut sink: impl FnMut(Vec<Point3>) -> bool,
    ) -> Result<(usize, usize), InputError> {
        let path = self.path.as_path();
        let cap = usize::try_from(self.announced).unwrap_or(0).min(1 << 20).min(batch);
        let mut points = Vec::with_capacity(cap);
        let mut skipped_invalid = 0;
        for (k, pc) in self.clouds.iter().enumerate() {
            let name = pc.name.clone().or_else(|| pc.guid.clone()).unwrap_or_default();
            let scan = |e: &dyn std::fmt::Display| e57_err(path, format!("scan {} ('{name}'): {e}", k + 1));
            if !pc.has_cartesian() && !pc.has_spherical() {
                return Err(scan(&"it has neither Cartesian nor spherical coordinates"));
            }
            let mut it = self.reader.pointcloud_simple(pc).map_err(|e| scan(&e))?;
            // Defaults of the simple reader, stated: the scan's pose is applied (points in the
            // file's common frame) and spherical coordinates are converted to Cartesian ones.
            it.apply_pose(true);
            it.spherical_to_cartesian(true);
            for p in it {
                let p = p.map_err(|e| scan(&e))?;
                // Finite in mm, not only in metres: beyond ±1.8e305 m the conversion overflows
                // to infinity (found by the `e57_points` fuzz target), and an infinite point
                // would go into the fit. Such points are skipped and counted like the ones
                // marked invalid.
                match p.cartesian {
                    CartesianCoordinate::Valid { x, y, z } => {
                        let q = Point3::new(x * MM_PER_M, y * MM_PER_M, z * MM_PER_M);
                        if q.x.is_finite() && q.y.is_finite() && q.z.is_finite() {
                            points.push(q);
                            if points.len() == batch
                                && !sink(std::mem::replace(&mut points, Vec::with_capacity(cap)))
                            {
                                return Ok((skipped_invalid, self.clouds.len()));
                            }
                        } else {
                            skipped_invalid += 1;
                        }
                    }
                    _ => skipped_invalid += 1,
                }
            }
        }
        if !points.is_empty() {
            sink(points);
        }
        Ok((skipped_invalid, self.clouds.len()))
    }
}

/// Write `points_mm` as an E57 file with one Cartesian scan (doubles, metres), atomically.
pub fn write_e57(path: &Path, points_mm: &[Point3]) -> Result<(), OutputError> {
    let io = |e: e57::Error| OutputError::Io { path: path.to_path_buf(), source: std::io::Error::other(e) };
    let mut buf = std::io::Cursor::new(Vec::with_capacity(points_mm.len() * 26 + 4096));
    {
        let mut w = E57Writer::new(&mut buf, "truepos-e57").map_err(io)?;
        let proto = vec![Record::CARTESIAN_X_F64, Record::CARTESIAN_Y_F64, Record::CARTESIAN_Z_F64];
        let mut pc = w.add_pointcloud("truepos-scan-1", proto).map_err(io)?;
        for p in points_mm {
            pc.add_point(vec![
                RecordValue::Double(p.x / MM_PER_M),
                RecordValue::Double(p.y / MM_PER_M),
                RecordValue::Double(p.z / MM_PER_M),
            ])
            .map_err(io)?;
        }
        pc.finalize().map_err(io)?;
        w.finalize().map_err(io)?;
    }
    crate::atomic::write_atomic(path, &buf.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use e57::{Quaternion, RecordDataType, RecordName, Transform, Translation};

    /// Three scans: Cartesian with a pose (a turn of 90° about Z and a shift), spherical, and
    /// Cartesian with invalid points; read back concatenated, in mm, in the common frame.
    #[test]
    fn scans_are_concatenated_in_mm_with_poses_spherical_and_invalid_points() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("scan.e57");
        {
            let mut w = E57Writer::from_file(&path, "test-guid").unwrap();
            let cart = vec![Record::CARTESIAN_X_F64, Record::CARTESIAN_Y_F64, Record::CARTESIAN_Z_F64];
            let mut pc = w.add_pointcloud("a", cart.clone()).unwrap();
            // Rotation of 90° about Z: q = (cos 45°, 0, 0, sin 45°); then (1, 2, 3) m.
            let h = std::f64::consts::FRAC_1_SQRT_2;
            pc.set_transform(Some(Transform {
                rotation: Quaternion { w: h, x: 0.0, y: 0.0, z: h },
                translation: Translation { x: 1.0, y: 2.0, z: 3.0 },
            }));
            for v in [[0.1, 0.0, 0.0], [0.0, 0.2, 0.5]] {
                pc.add_point(v.iter().map(|&x| RecordValue::Double(x)).collect()).unwrap();
            }
            pc.finalize().unwrap();
            let sph = vec![
                Record::SPHERICAL_RANGE_F64,
                Record::SPHERICAL_AZIMUTH_F64,
                Record::SPHERICAL_ELEVATION_F64,
            ];
            let mut pc = w.add_pointcloud("b", sph).unwrap();
            // Range 2 m, azimuth 90°, elevation 0 → (0, 2, 0) m; elevation 90° → (0, 0, 2) m.
            let q = std::f64::consts::FRAC_PI_2;
            for v in [[2.0, q, 0.0], [2.0, 0.0, q]] {
                pc.add_point(v.iter().map(|&x| RecordValue::Double(x)).collect()).unwrap();
            }
            pc.finalize().unwrap();
            let mut with_state = cart;
            with_state.push(Record {
                name: RecordName::CartesianInvalidState,
                data_type: RecordDataType::Integer { min: 0, max: 2 },
            });
            let mut pc = w.add_pointcloud("c", with_state).unwrap();
            for (v, state) in
                [([0.5, 0.25, 0.125], 0), ([9.0, 9.0, 9.0], 2), ([1.0, 0.0, 0.0], 1), ([-0.001, 0.0, 0.0], 0)]
            {
                let mut vals: Vec<RecordValue> = v.iter().map(|&x| RecordValue::Double(x)).collect();
                vals.push(RecordValue::Integer(state));
                pc.add_point(vals).unwrap();
            }
            pc.finalize().unwrap();
            w.finalize().unwrap();
        }
        let r = read_e57(&path).unwrap();
        assert_eq!((r.scans, r.skipped_invalid), (3, 2));
        let want = [
            [1000.0, 2100.0, 3000.0],
            [800.0, 2000.0, 3500.0],
            [0.0, 2000.0, 0.0],
            [0.0, 0.0, 2000.0],
            [500.0, 250.0, 125.0],
            [-1.0, 0.0, 0.0],
        ];
        assert_eq!(r.points.len(), want.len());
        for (p, w) in r.points.iter().zip(want) {
            // Quaternion and trigonometric round-off on metre values: far below 1e-9 mm.
            assert!((p - Point3::from(w)).norm() < 1e-9, "{p} vs {w:?}");
        }
        // Read as a table (every command but fit): the same points, the same count skipped.
        let t = crate::csv::Table::read(&path).unwrap();
        assert_eq!((t.n_rows(), t.skipped_invalid), (want.len(), 2));
    }

    #[test]
    fn written_points_read_back_and_corrupt_files_are_named() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("pts.E57");
        assert!(is_e57(&path));
        let pts: Vec<Point3> =
            (0..1000).map(|i| Point3::new(i as f64 * 0.37, -(i as f64) / 3.0, 12.5)).collect();
        write_e57(&path, &pts).unwrap();
        let r = read_e57(&path).unwrap();
        assert_eq!((r.scans, r.skipped_invalid, r.points.len()), (1, 0, pts.len()));
        for (a, b) in r.points.iter().zip(&pts) {
            // mm → m → mm: at most an ulp or two of a few hundred mm.
            assert!((a - b).norm() < 1e-12, "{a} vs {b}");
        }
        let mut bytes = std::fs::read(&path).unwrap();
        let bad = d.path().join("bad.e57");
        let n = bytes.len();
        bytes[n / 2..].iter_mut().for_each(|b| *b = !*b);
        std::fs::write(&bad, &bytes).unwrap();
        let e = read_e57(&bad).unwrap_err();
        assert!(e.to_string().starts_with(&format!("{}: ", bad.display())), "{e}");
        std::fs::write(&bad, b"x_mm,y_mm,z_mm\n1,2,3\n").unwrap();
        assert!(read_e57(&bad).unwrap_err().to_string().contains("not a readable E57 file"));
    }
}

/// Files broken on purpose: the XML of a valid file edited, the pages' checksums recomputed.
#[cfg(test)]
mod hostile {
    use super::*;

    const PAGE: usize = 1024;

    /// CRC-32C (Castagnoli), as E57 pages carry it (big-endian).
    fn crc32c(data: &[u8]) -> u32 {
        !data.iter().fold(!0_u32, |mut c, &b| {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 == 0 { c >> 1 } else { (c >> 1) ^ 0x82F6_3B78 };
            }
            c
        })
    }

    /// A file of `points` with `edit` applied to its XML section (the last thing in the file).
    fn edited(path: &Path, points: usize, edit: impl Fn(&str) -> String) {
        let pts: Vec<Point3> = (0..points).map(|i| Point3::new(i as f64, 1.0, 2.0)).collect();
        // The previous file was read by this process: an output onto an input is refused, so
        // it goes first.
        let _ = std::fs::remove_file(path);
        write_e57(path, &pts).unwrap();
        let phys = std::fs::read(path).unwrap();
        let u64_at = |o: usize| u64::from_le_bytes(phys[o..o + 8].try_into().unwrap());
        let (xml_phys, xml_len) = (u64_at(24) as usize, u64_at(32) as usize);
        let mut logical: Vec<u8> = phys.chunks(PAGE).flat_map(|p| p[..PAGE - 4].to_vec()).collect();
        let xml_at = xml_phys - xml_phys / PAGE * 4;
        let xml = String::from_utf8(logical[xml_at..xml_at + xml_len].to_vec()).unwrap();
        let new_xml = edit(&xml);
        assert_ne!(new_xml, xml, "the edit changes nothing");
        logical.truncate(xml_at);
        logical.extend_from_slice(new_xml.as_bytes());
        logical[32..40].copy_from_slice(&(new_xml.len() as u64).to_le_bytes());
        logical.resize(logical.len().div_ceil(PAGE - 4) * (PAGE - 4), 0);
        let phys_len = (logical.len() / (PAGE - 4) * PAGE) as u64;
        logical[16..24].copy_from_slice(&phys_len.to_le_bytes());
        let mut out = Vec::with_capacity(phys_len as usize);
        for chunk in logical.chunks(PAGE - 4) {
            out.extend_from_slice(chunk);
            out.extend_from_slice(&crc32c(chunk).to_be_bytes());
        }
        std::fs::write(path, out).unwrap();
    }

    #[test]
    fn the_page_tooling_reproduces_a_valid_file() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("same.e57");
        edited(&path, 10, |x| x.replace("recordCount=\"10\"", "recordCount=\"9\""));
        let r = read_e57(&path).unwrap();
        assert_eq!(r.points.len(), 9);
    }

    /// Coordinates finite in metres but not in mm (the ×1000 overflows): skipped and counted,
    /// never an infinite point.
    #[test]
    fn coordinates_that_overflow_in_mm_are_skipped() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("far.e57");
        {
            let mut w = E57Writer::from_file(&path, "far").unwrap();
            let cart = vec![Record::CARTESIAN_X_F64, Record::CARTESIAN_Y_F64, Record::CARTESIAN_Z_F64];
            let mut pc = w.add_pointcloud("far", cart).unwrap();
            for v in [[1.0, 2.0, 3.0], [1e306, 0.0, 0.0], [0.0, -1e306, 0.0], [4.0, 5.0, 6.0]] {
                pc.add_point(v.iter().map(|&x| RecordValue::Double(x)).collect()).unwrap();
            }
            pc.finalize().unwrap();
            w.finalize().unwrap();
        }
        let r = read_e57(&path).unwrap();
        assert_eq!(r.skipped_invalid, 2);
        assert_eq!(r.points, vec![Point3::new(1000.0, 2000.0, 3000.0), Point3::new(4000.0, 5000.0, 6000.0)]);
    }

    /// A point count far beyond what the file can hold (the XML says 10^12 points, or two scans
    /// whose counts overflow a u64 when added) is refused before anything is reserved or read.
    #[test]
    fn announced_point_counts_are_bounded_by_the_file_size() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("huge.e57");
        edited(&path, 10, |x| x.replace("recordCount=\"10\"", "recordCount=\"1000000000000\""));
        let e = read_e57(&path).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: not a readable E57 file: ", path.display())), "{e}");
        assert!(e.contains("announce 1000000000000 points"), "{e}");
        // Two scans of 2^63 points each: the sum saturates, it does not wrap to 0.
        edited(&path, 10, |x| {
            let start = x.find("<vectorChild").unwrap();
            let end = x.rfind("</vectorChild>").unwrap() + "</vectorChild>".len();
            let scan = x[start..end].replace("recordCount=\"10\"", "recordCount=\"9223372036854775808\"");
            format!("{}{scan}{scan}{}", &x[..start], &x[end..])
        });
        let e = read_e57(&path).unwrap_err().to_string();
        assert!(e.contains("announce 18446744073709551615 points"), "{e}");
    }
}
