//! The fitting section of the demo: every NIST algorithm-testing data set (ASME B89.4.10 /
//! ISO 10360-6, shipped in the repository's `data/nist-fit` and embedded in the binary) fitted by
//! `truepos-fit` and compared with NIST's certified least-squares result. It needs the reference
//! data rather than the virtual plant, but it is one of the demo's evaluations, so it lives with
//! the others.
//!
//! Entry points: [`NIST_SETS`] (the data sets, compiled in, so an installed binary runs this
//! section from any directory), [`nist_table`] (the comparison, also used by tests),
//! [`nist_table_dir`] (the same on a folder laid out like `data/nist-fit`), [`demo_section`].

use crate::error::Result;
use std::path::{Path, PathBuf};
use truepos_fit::evaluate::Kind;
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};
use truepos_report::{self as report, Report};

/// One NIST data set as shipped: its folder under `data/nist-fit`, its name, the `.ds` points
/// file and the `.fit` certified values.
pub struct NistSet {
    /// The element kind.
    pub kind: Kind,
    /// Its folder under `data/nist-fit`.
    pub folder: &'static str,
    /// The data set's name.
    pub name: &'static str,
    /// The `.ds` points file's bytes.
    pub ds: &'static [u8],
    /// The `.fit` file's text (the certified values).
    pub fit: &'static str,
}

macro_rules! nist_set {
    ($kind:expr, $folder:literal, $name:literal) => {
        NistSet {
            kind: $kind,
            folder: $folder,
            name: $name,
            ds: include_bytes!(concat!("../../../../data/nist-fit/", $folder, "/", $name, ".ds")),
            fit: include_str!(concat!("../../../../data/nist-fit/", $folder, "/", $name, ".fit")),
        }
    };
}

/// Every data set of `data/nist-fit`, in folder order (line, plane, circle, sphere, cylinder,
/// cone) and by name within a folder. A test checks that this list and the folder agree.
pub const NIST_SETS: &[NistSet] = &[
    nist_set!(Kind::Line, "Line3d", "lin3"),
    nist_set!(Kind::Plane, "Plane", "pla22"),
    nist_set!(Kind::Plane, "Plane", "pla7"),
    nist_set!(Kind::Circle, "Circle3d", "cir10"),
    nist_set!(Kind::Circle, "Circle3d", "cir20"),
    nist_set!(Kind::Circle, "Circle3d", "cir5"),
    nist_set!(Kind::Sphere, "Sphere", "sph14"),
    nist_set!(Kind::Sphere, "Sphere", "sph22"),
    nist_set!(Kind::Sphere, "Sphere", "sph5"),
    nist_set!(Kind::Cylinder, "Cylinder", "cyl21"),
    nist_set!(Kind::Cone, "Cone", "con17"),
];

/// The folders of `data/nist-fit` and the element each holds.
pub const NIST_FOLDERS: [(&str, Kind); 6] = [
    ("Line3d", Kind::Line),
    ("Plane", Kind::Plane),
    ("Circle3d", Kind::Circle),
    ("Sphere", Kind::Sphere),
    ("Cylinder", Kind::Cylinder),
    ("Cone", Kind::Cone),
];

/// One NIST data set fitted and compared with its certified result.
pub struct NistRow {
    /// The element kind.
    pub kind: Kind,
    /// The data set's name.
    pub name: String,
    /// Largest position/size deviation, mm.
    pub position_dev_mm: f64,
    /// Largest orientation deviation, rad.
    pub angle_dev_rad: f64,
}

fn axis_angle(a: &Vector3, b: &Vector3) -> f64 {
    a.cross(b).norm().atan2(a.dot(b).abs())
}
fn line_dist(p: &Point3, q: &Point3, d: &Vector3) -> f64 {
    let v = p - q;
    (v - d * v.dot(d)).norm()
}

/// Fit every embedded NIST data set ([`NIST_SETS`]) and compare with its certified values as
/// the data's README says (lines and axes by angle and point-to-line distance, cones at the axis
/// point, sizes as diameters).
pub fn nist_table() -> Result<Vec<NistRow>> {
    NIST_SETS
        .iter()
        .map(|s| {
            let ds = PathBuf::from(format!("data/nist-fit/{}/{}.ds", s.folder, s.name));
            let pts = truepos_io::points::parse_ds(&ds, s.ds)?;
            compare(s.kind, s.name, &pts, &ds.with_extension("fit"), s.fit)
        })
        .collect()
}

/// [`nist_table`] on a folder laid out like `data/nist-fit` (one sub-folder per element, `.ds`
/// and `.fit` pairs), read at run time.
pub fn nist_table_dir(dir: &Path) -> Result<Vec<NistRow>> {
    let mut rows = Vec::new();
    for (folder, kind) in NIST_FOLDERS {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join(folder))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "ds"))
            .collect();
        files.sort();
        for ds in files {
            let pts = truepos_io::points::read_ds(&ds)?;
            let fit_path = ds.with_extension("fit");
            let text = std::fs::read_to_string(&fit_path)?;
            let name = ds.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            rows.push(compare(kind, &name, &pts, &fit_path, &text)?);
        }
    }
    Ok(rows)
}

/// Fit `pts` as `kind` and compare with the certified values in `fit_text` (from `fit_path`).
fn compare(kind: Kind, name: &str, pts: &[Point3], fit_path: &Path, fit_text: &str) -> Result<NistRow> {
    let c: Vec<f64> = fit_text
        .split_whitespace()
        .map(|t| t.parse::<f64>().map_err(|_| InputError::in_file(fit_path, format!("not a number: '{t}'"))))
        .collect::<Result<_, _>>()?;
    let need = match kind {
        Kind::Sphere => 4,
        Kind::Line | Kind::Plane => 6,
        Kind::Circle | Kind::Cylinder => 7,
        Kind::Cone => 8,
    };
    if c.len() < need {
        return Err(
            InputError::in_file(fit_path, format!("expected {need} values, found {}", c.len())).into()
        );
    }
    let p = Point3::new(c[0], c[1], c[2]);
    let (pos, ang) = match kind {
        Kind::Sphere => {
            let f = truepos_fit::sphere(pts)?;
            ((f.center - p).norm().max((2.0 * f.radius - c[3]).abs()), 0.0)
        }
        _ => {
            let d = Vector3::new(c[3], c[4], c[5]).normalize();
            match kind {
                Kind::Line => {
                    let f = truepos_fit::line(pts)?;
                    (line_dist(&p, &f.point, &f.direction), axis_angle(&f.direction, &d))
                }
                Kind::Plane => {
                    let f = truepos_fit::plane(pts)?;
                    (f.distance(&p).abs(), axis_angle(&f.normal, &d))
                }
                Kind::Circle => {
                    let f = truepos_fit::circle(pts)?;
                    ((f.center - p).norm().max((2.0 * f.radius - c[6]).abs()), axis_angle(&f.normal, &d))
                }
                Kind::Cylinder => {
                    let f = truepos_fit::cylinder(pts)?;
                    (
                        line_dist(&p, &f.point, &f.axis).max((2.0 * f.radius - c[6]).abs()),
                        axis_angle(&f.axis, &d),
                    )
                }
                _ => {
                    let f = truepos_fit::cone(pts)?;
                    let t = (p - f.point).dot(&f.axis);
                    let pos = line_dist(&p, &f.point, &f.axis).max((f.surface_distance_at(t) - c[6]).abs());
                    let signed = f.axis.cross(&d).norm().atan2(f.axis.dot(&d));
                    (pos, signed.max((f.apex_angle - c[7].to_radians()).abs()))
                }
            }
        }
    };
    Ok(NistRow { kind, name: name.to_string(), position_dev_mm: pos, angle_dev_rad: ang })
}

/// Acceptance limit of the project on the position/size deviation from the certified fit, mm
/// (1 nm; PTB's ISO 10360-6 limits are 100× looser).
pub const NIST_POS_TOL_MM: f64 = 1e-6;
/// Acceptance limit of the project on the orientation deviation from the certified fit, rad
/// (10 nrad).
pub const NIST_ANG_TOL_RAD: f64 = 1e-8;

/// Expanded uncertainty (nm) of a comparison with NIST's certified values: a bound on the
/// double-precision rounding of the fit and on the certified values' printed digits.
const NIST_COMPARISON_U_NM: f64 = 0.001;

/// The fitting section of the demo report (NIST data sets against their certified fits).
pub fn demo_section(report: &mut Report) -> Result<()> {
    let rows = nist_table()?;
    if rows.is_empty() {
        let reason = "no NIST reference data set is compiled into this build";
        report.verdict(report::Verdict::skipped("fit", "Fitting", reason));
        report.add(
            "fit",
            "Least-squares fitting against NIST reference data",
            format!("<p>Not run: {reason}.</p>"),
        );
        return Ok(());
    }
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let ok = r.position_dev_mm < NIST_POS_TOL_MM && r.angle_dev_rad < NIST_ANG_TOL_RAD;
            vec![
                r.name.clone(),
                r.kind.name().to_string(),
                // Picometres and picoradians: the deviations are far below a nanometre, and
                // fixed decimals read naturally (no `0.00e0`).
                format!("{:.2}", r.position_dev_mm * 1e9),
                format!("{:.2}", r.angle_dev_rad * 1e12),
                if ok { "pass".into() } else { "FAIL".into() },
            ]
        })
        .collect();
    let html = format!(
        "<p>Every NIST algorithm-testing data set (ASME B89.4.10 / ISO 10360-6) fitted by truepos and compared with NIST's certified least-squares fit: largest deviation in position or size (diameters; lines and axes by point-to-line distance; cones at NIST's axis point and its distance to the surface) and in orientation. Limits: 1 nm and 10 nrad (PTB's acceptance limits are 100 nm and 100 nrad).</p>{}",
        report::table(&["data set", "element", "position/size deviation (pm)", "orientation deviation (prad)", "result"], &cells)
    );
    let all_pass =
        rows.iter().all(|r| r.position_dev_mm < NIST_POS_TOL_MM && r.angle_dev_rad < NIST_ANG_TOL_RAD);
    let worst_pos = rows.iter().map(|r| r.position_dev_mm).fold(0.0, f64::max);
    let worst_ang = rows.iter().map(|r| r.angle_dev_rad).fold(0.0, f64::max);
    report.verdict(report::Verdict {
        section: "fit".into(),
        capability: "Fitting".into(),
        measured: format!(
            "{} NIST reference data sets (line, plane, circle, sphere, cylinder, cone)",
            rows.len()
        ),
        truth: "NIST's certified least-squares fits".into(),
        result: format!(
            "worst deviation {:.2} pm in position/size, {:.2} prad in orientation",
            worst_pos * 1e9,
            worst_ang * 1e12
        ),
        uncertainty: format!(
            "U = {NIST_COMPARISON_U_NM} nm (k = 2): the comparison's own, a bound on double-precision rounding over coordinates up to 10³ mm and on the certified values' 18 printed digits"
        ),
        tolerance_text: "1 nm and 10 nrad (100× tighter than PTB's acceptance limits)".into(),
        ..report::Verdict::judged(
            report::Judgement::new(worst_pos * 1e6, NIST_COMPARISON_U_NM, NIST_POS_TOL_MM * 1e6, "nm", report::DecisionRule::Guarded)
                .require(!rows.is_empty(), "no data set was fitted")
                .require(all_pass, "a data set outside 1 nm or 10 nrad")
                .require(worst_ang < NIST_ANG_TOL_RAD, format!("orientation deviation {:.3} nrad > 10 nrad", worst_ang * 1e9)),
        )
    });
    report.add("fit", "Least-squares fitting against NIST reference data", html);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The demo's NIST table covers every data set of `data/nist-fit` (the embedded list and
    /// the folder agree, so a set added to one and not the other fails), the embedded sets are
    /// the files byte for byte (same results as reading the folder), and every one passes the
    /// project's limits (the library's own tests check the same sets independently in
    /// crates/fit/tests/nist.rs).
    #[test]
    fn nist_table_covers_every_set_and_passes() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/nist-fit");
        let mut on_disk = Vec::new();
        for (folder, _) in NIST_FOLDERS {
            let mut names: Vec<String> = std::fs::read_dir(dir.join(folder))
                .unwrap_or_else(|e| panic!("{}: {e}", dir.join(folder).display()))
                .map(|e| e.unwrap().path())
                .filter(|p| p.extension().is_some_and(|x| x == "ds"))
                .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
                .collect();
            names.sort();
            on_disk.extend(names.into_iter().map(|n| format!("{folder}/{n}")));
        }
        let embedded: Vec<String> = NIST_SETS.iter().map(|s| format!("{}/{}", s.folder, s.name)).collect();
        assert_eq!(embedded, on_disk, "NIST_SETS and data/nist-fit differ");
        assert!(embedded.len() >= 11);
        let rows = nist_table().unwrap();
        let from_dir = nist_table_dir(&dir).unwrap();
        assert_eq!(rows.len(), from_dir.len());
        for (r, d) in rows.iter().zip(&from_dir) {
            assert_eq!(
                (&r.name, r.position_dev_mm, r.angle_dev_rad),
                (&d.name, d.position_dev_mm, d.angle_dev_rad)
            );
            assert!(r.position_dev_mm < NIST_POS_TOL_MM && r.angle_dev_rad < NIST_ANG_TOL_RAD, "{}", r.name);
        }
        let mut report = Report::new(std::env::temp_dir().join("truepos-fit-demo-test"));
        demo_section(&mut report).unwrap();
    }
}
