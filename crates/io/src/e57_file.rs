//! E57 point clouds (ASTM E2807, what laser scanners and trackers export) as point files, chosen
//! by the `.e57` extension, read with the `e57` crate.
//!
//! - [`read_e57`]: every scan (E57 "data3D") of the file, concatenated in file order, in the
//!   file's common frame (each scan's pose applied), in **mm** (E57 stores metres: converted
//!   here, at the edge). Scans recorded in spherical coordinates (range, azimuth, elevation) are
//!   converted to Cartesian ones (as the `e57` crate does). Points whose coordinates the file marks
//!   as not valid (`cartesianInvalidState` 1 = direction only, 2 = invalid; or the spherical
//!   equivalents) are skipped and counted ([`E57Points::skipped_invalid`]); so are points with a
//!   NaN or infinite coordinate (in the file, or once in mm and posed), counted apart
//!   ([`E57Points::skipped_nonfinite`]). A file that is not a readable E57 is an input error
//!   naming it (and the scan, when one is broken).
//! - Poses: a scan's rotation must be a unit quaternion. One whose norm is within
//!   [`QUATERNION_NORM_TOLERANCE`] (1e-6) of 1 is normalised (written with too few digits, it
//!   would otherwise scale the scan by |q|², up to 2e-6); any other, or a NaN/infinite component
//!   of the rotation or translation, is refused naming the scan and the field
//!   (`pose/rotation`, `pose/translation`).
//! - [`E57Source`]: the same points in batches, in constant memory (the `e57` crate's raw reader
//!   reads the binary sections packet by packet): what the streamed point rewrite
//!   ([`crate::stream::rewrite_points`]) reads.
//! - [`write_e57`]: points in mm as one Cartesian scan of doubles, written atomically (for
//!   tests and exchange).
//!
//! Where E57 points reach the rest of truepos: [`crate::points::read_points`] (fit),
//! [`crate::csv::Table::read`] (columns `x_mm,y_mm,z_mm`) and, streamed,
//! [`crate::stream::rewrite_points`] (`comp correct`, `load correct`).

use crate::atomic::OutputError;
use crate::InputError;
use e57::{E57Reader, E57Writer, Record, RecordValue};
use std::path::Path;
use truepos_math::{Point3, Vector3};

/// Millimetres per metre.
const MM_PER_M: f64 = 1000.0;

/// How far from 1 the norm of a pose's rotation quaternion may be and still be normalised:
/// | |q| − 1 | ≤ 1e-6. Ten significant digits written for each component leave |q| within
/// about 1e-10 of 1; a norm further off is not a rotation written with round-off but a wrong
/// pose, refused.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-6;

/// The points of an E57 file.
#[derive(Debug, Clone, PartialEq)]
pub struct E57Points {
    /// Valid points of every scan, in mm, in file order.
    pub points: Vec<Point3>,
    /// Points skipped because the file marks their coordinates invalid (or direction only).
    pub skipped_invalid: usize,
    /// Points skipped because a coordinate is NaN or infinite (in the file, or once in mm).
    pub skipped_nonfinite: usize,
    /// Scans (point clouds) in the file.
    pub scans: usize,
}

/// What reading an E57 file skipped, and its scans (see [`E57Points`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct E57Counts {
    /// Points skipped because the file marks them invalid.
    pub skipped_invalid: usize,
    /// Points skipped because a coordinate is NaN or infinite.
    pub skipped_nonfinite: usize,
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
    let c = E57Source::open(path)?.for_each_batch(usize::MAX, |b| {
        if points.is_empty() {
            points = b;
        } else {
            points.extend_from_slice(&b);
        }
        true
    })?;
    Ok(E57Points {
        points,
        skipped_invalid: c.skipped_invalid,
        skipped_nonfinite: c.skipped_nonfinite,
        scans: c.scans,
    })
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
        crate::limits::require_regular(path, "E57")?;
        let file =
            std::fs::File::open(path).map_err(|e| InputError::in_file(path, format!("cannot read: {e}")))?;
        crate::atomic::note_input(path);
        let meta = file.metadata().map_err(|e| InputError::in_file(path, format!("cannot read: {e}")))?;
        if meta.is_dir() {
            return Err(InputError::in_file(path, "is a directory, not a file"));
        }
        crate::limits::check_file_size(path, &meta)?;
        let reader = E57Reader::new(std::io::BufReader::new(file)).map_err(|e| e57_err(path, e))?;
        let mut clouds = reader.pointclouds();
        for (k, pc) in clouds.iter_mut().enumerate() {
            check_pose(pc)
                .map_err(|e| e57_err(path, format!("scan {} ('{}'): {e}", k + 1, scan_name(pc))))?;
        }
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
    /// skipped (marked invalid; NaN or infinite) and the number of scans.
    pub fn for_each_batch(
        mut self,
        batch: usize,
        mut sink: impl FnMut(Vec<Point3>) -> bool,
    ) -> Result<E57Counts, InputError> {
        let path = self.path.as_path();
        let cap = usize::try_from(self.announced).unwrap_or(0).min(1 << 20).min(batch);
        let mut points = Vec::with_capacity(cap);
        let mut counts = E57Counts { scans: self.clouds.len(), ..E57Counts::default() };
        for (k, pc) in self.clouds.iter().enumerate() {
            let name = scan_name(pc);
            let scan = |e: &dyn std::fmt::Display| e57_err(path, format!("scan {} ('{name}'): {e}", k + 1));
            if !pc.has_cartesian() && !pc.has_spherical() {
                return Err(scan(&"it has neither Cartesian nor spherical coordinates"));
            }
            // The raw reader, not the crate's simple one: the simple reader takes a data packet
            // that leaves one of the scan's byte streams empty for the end of the data (the
            // `e57` writer packs only whole bytes until its last packet, e.g. three 2-bit
            // invalid states) and fails with "Cannot read next point because of logic error";
            // the raw reader reads on to the next packet. The point is then made here as the
            // simple reader makes it (see `Layout::point`).
            let layout = Layout::of(pc);
            let pose = Pose::of(pc);
            let it = self.reader.pointcloud_raw(pc).map_err(|e| scan(&e))?;
            for values in it {
                let values = values.map_err(|e| scan(&e))?;
                let p = layout.point(&pc.prototype, &values).map_err(|e| scan(&e))?;
                // Finite in mm, not only in metres: beyond ±1.8e305 m the conversion overflows
                // to infinity (found by the `e57_points` fuzz target), and an infinite point
                // would go into the fit. Such points, and NaN or infinite coordinates in the
                // file, are skipped and counted apart from the ones the file marks invalid.
                match p {
                    Some(m) => {
                        let q = pose.apply(m) * MM_PER_M;
                        let q = Point3::from(q);
                        if q.x.is_finite() && q.y.is_finite() && q.z.is_finite() {
                            points.push(q);
                            if points.len() == batch
                                && !sink(std::mem::replace(&mut points, Vec::with_capacity(cap)))
                            {
                                return Ok(counts);
                            }
                        } else {
                            counts.skipped_nonfinite += 1;
                        }
                    }
                    None => counts.skipped_invalid += 1,
                }
            }
        }
        if !points.is_empty() {
            sink(points);
        }
        Ok(counts)
    }
}

/// Where a scan's coordinates and invalid states are in its records (prototype indices).
struct Layout {
    cartesian: Option<[usize; 3]>,
    cartesian_state: Option<usize>,
    spherical: Option<[usize; 3]>,
    spherical_state: Option<usize>,
}

impl Layout {
    fn of(pc: &e57::PointCloud) -> Self {
        use e57::RecordName as N;
        let at = |n: N| pc.prototype.iter().position(|r| r.name == n);
        let three = |a: N, b: N, c: N| Some([at(a)?, at(b)?, at(c)?]);
        Layout {
            cartesian: three(N::CartesianX, N::CartesianY, N::CartesianZ),
            cartesian_state: at(N::CartesianInvalidState),
            spherical: three(N::SphericalRange, N::SphericalAzimuth, N::SphericalElevation),
            spherical_state: at(N::SphericalInvalidState),
        }
    }

    /// The point of one record in the scan's own frame (m), as the `e57` crate's simple reader
    /// makes it: its Cartesian coordinates when their state is 0 (or absent), else its
    /// spherical ones converted when their state is 0 (x = r cos e cos a, y = r cos e sin a,
    /// z = r sin e); `None` when neither is valid (state 1 = direction only, 2 = invalid).
    fn point(&self, proto: &[e57::Record], v: &[e57::RecordValue]) -> Result<Option<Vector3>, String> {
        let f = |i: usize| v[i].to_f64(&proto[i].data_type).map_err(|e| e.to_string());
        let state = |i: Option<usize>, what: &str| match i {
            None => Ok(0),
            Some(i) => match v[i].to_i64(&proto[i].data_type).map_err(|e| e.to_string())? {
                s @ 0..=2 => Ok(s),
                s => Err(format!("{what} is {s}, not 0 (valid), 1 (direction only) or 2 (invalid)")),
            },
        };
        if let Some([x, y, z]) = self.cartesian {
            if state(self.cartesian_state, "cartesianInvalidState")? == 0 {
                return Ok(Some(Vector3::new(f(x)?, f(y)?, f(z)?)));
            }
        }
        if let Some([r, a, e]) = self.spherical {
            if state(self.spherical_state, "sphericalInvalidState")? == 0 {
                let (r, a, e) = (f(r)?, f(a)?, f(e)?);
                let ce = e.cos();
                return Ok(Some(Vector3::new(r * ce * a.cos(), r * ce * a.sin(), r * e.sin())));
            }
        }
        Ok(None)
    }
}

/// A scan's pose (rotation already normalised by [`check_pose`]) as a matrix and a translation.
struct Pose {
    rotation: truepos_math::Matrix3,
    translation: Vector3,
}

impl Pose {
    fn of(pc: &e57::PointCloud) -> Self {
        let Some(t) = &pc.transform else {
            return Pose { rotation: truepos_math::Matrix3::identity(), translation: Vector3::zeros() };
        };
        // The rotation of the unit quaternion (w, x, y, z), in the form the `e57` crate uses.
        let (w, x, y, z) = (t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z);
        let rotation = truepos_math::Matrix3::new(
            w * w + x * x - y * y - z * z,
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            w * w + y * y - x * x - z * z,
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            w * w + z * z - x * x - y * y,
        );
        let tr = &t.translation;
        Pose { rotation, translation: Vector3::new(tr.x, tr.y, tr.z) }
    }

    fn apply(&self, p: Vector3) -> Vector3 {
        self.rotation * p + self.translation
    }
}

/// The name of a scan for messages (its name, else its GUID).
fn scan_name(pc: &e57::PointCloud) -> String {
    pc.name.clone().or_else(|| pc.guid.clone()).unwrap_or_default()
}

/// Check a scan's pose and normalise its rotation (see the module docs): a quaternion whose
/// norm is within [`QUATERNION_NORM_TOLERANCE`] of 1 is divided by its norm; another norm, or a
/// NaN or infinite component, is refused naming the field.
fn check_pose(pc: &mut e57::PointCloud) -> Result<(), String> {
    let Some(t) = pc.transform.as_mut() else { return Ok(()) };
    let q = &mut t.rotation;
    let comps = [q.w, q.x, q.y, q.z];
    if comps.iter().any(|c| !c.is_finite()) {
        return Err(format!(
            "pose/rotation: the quaternion (w, x, y, z) = ({}, {}, {}, {}) has a NaN or infinite component",
            q.w, q.x, q.y, q.z
        ));
    }
    let norm = comps.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(format!(
            "pose/rotation: the quaternion (w, x, y, z) = ({}, {}, {}, {}) has norm {norm}, not 1: a rotation needs a unit quaternion (a norm within 1e-6 of 1 is normalised, this one is {:.3e} off)",
            q.w,
            q.x,
            q.y,
            q.z,
            (norm - 1.0).abs()
        ));
    }
    for c in [&mut q.w, &mut q.x, &mut q.y, &mut q.z] {
        *c /= norm;
    }
    let tr = &t.translation;
    if ![tr.x, tr.y, tr.z].iter().all(|c| c.is_finite()) {
        return Err(format!(
            "pose/translation: ({}, {}, {}) m has a NaN or infinite component",
            tr.x, tr.y, tr.z
        ));
    }
    Ok(())
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

    /// The two-scan seed of the `e57_points` fuzz target (`fuzz/seeds/e57_points/mixed.e57`,
    /// written by `examples/fuzz_seeds.rs`): singles with intensity, colour and invalid states
    /// under a pose (90° about Z, then (1, 2, 3) m), then spherical doubles. Its valid points
    /// computed here by hand from what the example writes.
    #[test]
    fn the_two_scan_fuzz_seed_reads_as_written() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/e57_points/mixed.e57");
        let r = read_e57(&path).unwrap();
        // Scan 1: (f, −f, 0.5) m, f = i/4, states 0, 1, 2, 0 → points 0 and 3. Rotated by 90°
        // about Z, (x, y) → (−y, x), then shifted. Scan 2: (range, azimuth, elevation) with
        // states 0, 0, 2 → x = r cos e cos a, y = r cos e sin a, z = r sin e.
        let posed = |f: f64| [(f + 1.0) * 1e3, (f + 2.0) * 1e3, 3.5e3];
        let sph = |r: f64, a: f64, e: f64| {
            [r * e.cos() * a.cos() * 1e3, r * e.cos() * a.sin() * 1e3, r * e.sin() * 1e3]
        };
        let want = [posed(0.0), posed(0.75), sph(2.0, 0.5, 0.1), sph(1.0, -1.0, 1.2)];
        assert_eq!((r.scans, r.skipped_invalid, r.skipped_nonfinite), (2, 3, 0));
        assert_eq!(r.points.len(), want.len());
        for (p, w) in r.points.iter().zip(want) {
            // Round-off of the quaternion and the trigonometry on metre values: < 1e-9 mm.
            assert!((p - Point3::from(w)).norm() < 1e-9, "{p} vs {w:?}");
        }
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
    use e57::{Quaternion, Transform, Translation};

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

    /// Coordinates finite in metres but not in mm (the ×1000 overflows): skipped and counted as
    /// non-finite, never an infinite point.
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
        assert_eq!((r.skipped_invalid, r.skipped_nonfinite), (0, 2));
        assert_eq!(r.points, vec![Point3::new(1000.0, 2000.0, 3000.0), Point3::new(4000.0, 5000.0, 6000.0)]);
    }

    /// One Cartesian scan of doubles with `pose` and the points `pts` (m).
    fn posed(path: &Path, pose: Transform, pts: &[[f64; 3]]) {
        let _ = std::fs::remove_file(path);
        let mut w = E57Writer::from_file(path, "posed").unwrap();
        let cart = vec![Record::CARTESIAN_X_F64, Record::CARTESIAN_Y_F64, Record::CARTESIAN_Z_F64];
        let mut pc = w.add_pointcloud("tilted", cart).unwrap();
        pc.set_transform(Some(pose));
        for v in pts {
            pc.add_point(v.iter().map(|&x| RecordValue::Double(x)).collect()).unwrap();
        }
        pc.finalize().unwrap();
        w.finalize().unwrap();
    }

    /// A pose quaternion within 1e-6 of unit norm is normalised (the points are rotated, not
    /// scaled by |q|²); one further off, or with a NaN, is refused naming the scan and the field.
    #[test]
    fn pose_quaternions_are_normalised_or_refused() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("posed.e57");
        let h = std::f64::consts::FRAC_1_SQRT_2;
        // 90° about Z, norm 1 + 9e-7: inside the tolerance. Unnormalised, (1, 0, 0) m would come
        // out at 1 + 1.8e-6 m, 1.8 µm too far: the normalised rotation gives (0, 1000, 0) mm.
        let k = 1.0 + 9e-7;
        let rot = |k: f64| Quaternion { w: h * k, x: 0.0, y: 0.0, z: h * k };
        let zero = Translation { x: 0.0, y: 0.0, z: 0.0 };
        posed(&path, Transform { rotation: rot(k), translation: zero.clone() }, &[[1.0, 0.0, 0.0]]);
        let r = read_e57(&path).unwrap();
        assert_eq!(r.points.len(), 1);
        assert!((r.points[0] - Point3::new(0.0, 1000.0, 0.0)).norm() < 1e-9, "{}", r.points[0]);
        // 1.1e-6 off: refused, naming the scan, the field and the tolerance.
        posed(
            &path,
            Transform { rotation: rot(1.0 + 1.1e-6), translation: zero.clone() },
            &[[1.0, 0.0, 0.0]],
        );
        let e = read_e57(&path).unwrap_err().to_string();
        for n in ["posed.e57", "scan 1 ('tilted')", "pose/rotation", "not 1", "within 1e-6"] {
            assert!(e.contains(n), "{n} in {e}");
        }
        // A quaternion of norm 2 (a common mistake: not a rotation at all).
        posed(&path, Transform { rotation: rot(2.0), translation: zero.clone() }, &[[1.0, 0.0, 0.0]]);
        assert!(read_e57(&path).unwrap_err().to_string().contains("has norm 2"));
        let nan = Translation { x: f64::NAN, y: 0.0, z: 0.0 };
        posed(&path, Transform { rotation: rot(1.0), translation: nan }, &[[1.0, 0.0, 0.0]]);
        let e = read_e57(&path).unwrap_err().to_string();
        assert!(e.contains("pose/translation") && e.contains("NaN"), "{e}");
    }

    /// NaN and infinite coordinates in the file are counted as such, apart from the points the
    /// file marks invalid.
    #[test]
    fn nan_and_infinite_coordinates_are_counted_apart_from_invalid_ones() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("nan.e57");
        {
            let mut w = E57Writer::from_file(&path, "nan").unwrap();
            let mut proto = vec![Record::CARTESIAN_X_F64, Record::CARTESIAN_Y_F64, Record::CARTESIAN_Z_F64];
            proto.push(Record {
                name: e57::RecordName::CartesianInvalidState,
                data_type: e57::RecordDataType::Integer { min: 0, max: 2 },
            });
            let mut pc = w.add_pointcloud("nan", proto).unwrap();
            for (v, state) in [
                ([1.0, 2.0, 3.0], 0),
                ([f64::NAN, 0.0, 0.0], 0),
                ([0.0, f64::INFINITY, 0.0], 0),
                ([9.0, 9.0, 9.0], 2),
                ([4.0, 5.0, 6.0], 0),
            ] {
                let mut vals: Vec<RecordValue> = v.iter().map(|&x| RecordValue::Double(x)).collect();
                vals.push(RecordValue::Integer(state));
                pc.add_point(vals).unwrap();
            }
            pc.finalize().unwrap();
            w.finalize().unwrap();
        }
        let r = read_e57(&path).unwrap();
        assert_eq!((r.skipped_invalid, r.skipped_nonfinite), (1, 2));
        assert_eq!(r.points, vec![Point3::new(1000.0, 2000.0, 3000.0), Point3::new(4000.0, 5000.0, 6000.0)]);
        let t = crate::csv::Table::read(&path).unwrap();
        assert_eq!((t.n_rows(), t.skipped_invalid, t.skipped_nonfinite), (2, 1, 2));
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
