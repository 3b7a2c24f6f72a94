//! The `head-offset` scenario: a measuring head with an unknown 3D offset R on a machine with a
//! B-axis swivel head and/or a C-axis rotary table measures a reference object (sphere, pyramid
//! apex, cuboid corner) from several orientations. Pure: returns rows and truth; the binary
//! writes `points.csv` (`b_deg,c_deg,x_mm,y_mm,z_mm[,dist_mm][,face],group`) and `truth.json`.
//!
//! Model (exactly the contract's, `shared/spec/interface.md`, "Head offset"; see
//! [`crate::machine::rotary`]): the NC reports the head's reference point `P`; the measuring
//! reference point is `Q = P + Ry(b)·R`; a laser head's surface point is `Q + dist·Ry(b)·u` with
//! `u = unit(tan α, tan β, −1)`; a table point at `A` for `c = 0` is at `O + Rz(c)·(A − O)`.
//! A touch probe's `Q` is the stylus-tip centre, so touch rows lie on the sphere of radius
//! `sphere radius + tip radius` (or on the face planes moved out by the tip radius).
//!
//! How a row is made: pick the object's surface point `S` the head sees in this orientation
//! (spread at random over a cap facing the head for a sphere, over the visible faces for a vertex
//! reference), then
//! - touch probe: `Q = S + r_tip·n + e·n` (`n` the outward normal, `e` the probing noise,
//!   N(0, σ) along the approach direction); `P = Q − Ry(b)·R`;
//! - laser head: a true distance `d` uniform in 80 % of the measuring range, `Q = S − d·w`
//!   (`w = Ry(b)·u`), `P = Q − Ry(b)·R`; `dist` is the exact ray intersection from `Q` (which
//!   returns `d`) plus N(0, σ) noise.
//!
//! Entry points: [`HeadOffsetConfig`] (with [`HeadOffsetConfig::preset`] for the [`Variant`]s
//! swivel / table / both / laser / pyramid / cuboid, and [`HeadOffsetConfig::randomized`]: the
//! object anywhere on the table, R anywhere in ±300 mm), [`simulate`] → [`HeadOffsetData`]
//! (`rows`: [`HeadOffsetRow`]; `truth`: [`HeadOffsetTruth`]), and [`observable_components`]
//! (which components of R a set of orientations determines).
//!
//! Defaults: 36 points per orientation over a 60° half-angle cap, 0.5 µm noise (1σ), a Ø 25 mm
//! sphere off the table centre, a touch probe with a 1.5 mm tip radius, R = (42.5, −18.3, −165.2) mm.

use rand::Rng;
use serde::Serialize;
use truepos_math::types::{ry, rz, Matrix3, Point3, Vector3};

use crate::laser::{LaserHead, Surface};
use crate::machine::rotary::{head_point_with, head_reference, RotaryTable};

/// Largest number of rows a configuration may ask for (guards the CLI against runaway sizes).
pub const MAX_ROWS: usize = 1_000_000;

/// Invalid configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HeadOffsetError {
    /// A number is out of its valid range or not finite.
    #[error("invalid head-offset scenario setting {name}: {reason}")]
    Invalid {
        /// The setting.
        name: &'static str,
        /// Why it is invalid.
        reason: String,
    },
    /// A face of the vertex reference is never visible to the head.
    #[error(
        "face {face} of the reference object is visible from none of the orientations; add B or C angles"
    )]
    FaceNeverVisible {
        /// The face's id.
        face: usize,
    },
    /// The laser head cannot reach the reference in some orientation.
    #[error("the laser beam cannot measure the reference object in orientation b = {b_deg}°, c = {c_deg}°")]
    LaserCannotReach {
        /// Head angle B of the orientation, degrees.
        b_deg: f64,
        /// Table angle C of the orientation, degrees.
        c_deg: f64,
    },
}

/// The measuring head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Head {
    /// Touch-trigger probe; `Q` is the stylus-tip centre.
    TouchProbe {
        /// Stylus tip radius, mm.
        tip_radius: f64,
    },
    /// Laser distance head (tilt, measuring range; the noise is the scenario's `noise`).
    Laser {
        /// Beam tilt (α, β), rad.
        tilt: [f64; 2],
        /// Measuring range, mm.
        range: f64,
    },
}

/// The reference object, given at its `c = 0` position on the table (machine coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reference {
    /// Sphere.
    Sphere {
        /// Centre at c = 0, machine frame, mm.
        centre: Point3,
        /// Radius, mm.
        radius: f64,
    },
    /// Regular pyramid standing on the table, apex up: `faces` (3..=8) faces, each inclined by
    /// `slope` (rad) from horizontal, the first face's outward normal at azimuth `yaw`; points are
    /// sampled at horizontal distances `inner..outer` (mm) from the apex.
    Pyramid {
        /// Apex at c = 0, machine frame, mm.
        apex: Point3,
        /// Number of faces, 3 to 8.
        faces: usize,
        /// Inclination of each face from horizontal, rad.
        slope: f64,
        /// Azimuth of the first face's outward normal, rad.
        yaw: f64,
        /// Nearest horizontal distance of a point from the apex, mm.
        inner: f64,
        /// Farthest horizontal distance of a point from the apex, mm.
        outer: f64,
    },
    /// Top corner of a cuboid lying flat, turned by `yaw` about Z; faces: 0 top (+Z), 1 the side
    /// with outward normal `Rz(yaw)·X`, 2 the side with `Rz(yaw)·Y`; points at `inner..outer`
    /// (mm) from the edges through the vertex.
    CuboidCorner {
        /// The corner at c = 0, machine frame, mm.
        vertex: Point3,
        /// Rotation of the cuboid about Z, rad.
        yaw: f64,
        /// Nearest distance of a point from the edges, mm.
        inner: f64,
        /// Farthest distance of a point from the edges, mm.
        outer: f64,
    },
}

/// The data set variants of `truepos simulate head-offset --variant …` (with the `clap` feature,
/// each value's command-line help is the shorter text of its `value(help)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Variant {
    /// Touch probe, sphere from B = 0°, 45°, 90°.
    #[cfg_attr(
        feature = "clap",
        value(help = "Touch probe, sphere from B = 0°, 45°, 90° (Y not observable)")
    )]
    Swivel,
    /// Touch probe, sphere at C = 0°, 90°, 180°, 270° about the known table centre.
    #[cfg_attr(
        feature = "clap",
        value(help = "Touch probe, sphere at C = 0°, 90°, 180°, 270° (Z not observable)")
    )]
    Table,
    /// Touch probe, B ∈ {0°, 90°} × C ∈ {0°, 120°, 240°}.
    Both,
    /// Laser head with beam tilt (2.0°, −1.5°), 10 mm range, B ∈ {0°, 60°} × C ∈ {0°, 120°, 240°}.
    #[cfg_attr(feature = "clap", value(help = "Laser head with beam tilt (2°, −1.5°)"))]
    Laser,
    /// Touch probe on a 4-sided pyramid (45° faces), B ∈ {0°, 45°} × C ∈ {0°, 90°}.
    #[cfg_attr(feature = "clap", value(help = "Touch probe on a 4-sided pyramid apex"))]
    Pyramid,
    /// Touch probe on a cuboid corner, B ∈ {0°, 45°} × C ∈ {0°, 90°}.
    #[cfg_attr(feature = "clap", value(help = "Touch probe on a cuboid corner"))]
    Cuboid,
}

impl Variant {
    /// All variants.
    pub const ALL: [Variant; 6] =
        [Variant::Swivel, Variant::Table, Variant::Both, Variant::Laser, Variant::Pyramid, Variant::Cuboid];

    /// Name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Swivel => "swivel",
            Variant::Table => "table",
            Variant::Both => "both",
            Variant::Laser => "laser",
            Variant::Pyramid => "pyramid",
            Variant::Cuboid => "cuboid",
        }
    }

    /// Parse a command-line name.
    pub fn from_name(s: &str) -> Option<Variant> {
        Variant::ALL.into_iter().find(|v| v.name() == s)
    }
}

/// Scenario configuration. Angles in rad, lengths in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadOffsetConfig {
    /// RNG seed (same seed → same data set).
    pub seed: u64,
    /// The true head offset R (head frame at b = 0).
    pub offset: Vector3,
    /// Head swivel angles B.
    pub b_angles: Vec<f64>,
    /// Table angles C. The orientations are all pairs (b, c); `group` numbers them b-major.
    pub c_angles: Vec<f64>,
    /// A point of the C axis (the table centre).
    pub table_centre: Point3,
    /// The measuring head.
    pub head: Head,
    /// The reference object at c = 0.
    pub reference: Reference,
    /// Points per orientation (≥ 4 for a sphere; for a vertex at least one per visible face).
    pub points_per_orientation: usize,
    /// Half angle of the sphere cap facing the head over which points spread (rad, < 90°).
    pub cap_half_angle: f64,
    /// Measuring noise, standard deviation (mm): along the normal (touch) or on `dist` (laser).
    pub noise: f64,
    /// A machine with geometric errors (and thermal growth) whose NC reports the axis positions:
    /// the rows' P are then the axis positions that put the erroneous machine's head point on
    /// the surface (`Machine::head_point(P, b, R) = Q`), so the contract model with the true R is
    /// off by the machine's volumetric error; its [`crate::machine::RotaryAxisErrors`] move the
    /// real B and C axes (the table turns about `table_centre + c_offset`). `None` (presets): the ideal contract machine. Its
    /// own rotary table is ignored; [`HeadOffsetConfig::table_centre`] is used.
    pub machine: Option<crate::machine::Machine>,
}

impl Default for HeadOffsetConfig {
    fn default() -> Self {
        HeadOffsetConfig::preset(Variant::Both, 1)
    }
}

const DEG: f64 = std::f64::consts::PI / 180.0;

fn degs(v: &[f64]) -> Vec<f64> {
    v.iter().map(|d| d * DEG).collect()
}

impl HeadOffsetConfig {
    /// The preset configuration of a variant (see [`Variant`]).
    pub fn preset(variant: Variant, seed: u64) -> HeadOffsetConfig {
        let sphere = Reference::Sphere { centre: Point3::new(612.4, 287.9, 105.0), radius: 12.5 };
        let touch = Head::TouchProbe { tip_radius: 1.5 };
        let mut cfg = HeadOffsetConfig {
            seed,
            offset: Vector3::new(42.5, -18.3, -165.2),
            b_angles: vec![0.0],
            c_angles: vec![0.0],
            table_centre: Point3::new(500.0, 250.0, 0.0),
            head: touch,
            reference: sphere,
            points_per_orientation: 36,
            cap_half_angle: 60.0 * DEG,
            noise: 0.5e-3,
            machine: None,
        };
        match variant {
            Variant::Swivel => cfg.b_angles = degs(&[0.0, 45.0, 90.0]),
            Variant::Table => cfg.c_angles = degs(&[0.0, 90.0, 180.0, 270.0]),
            Variant::Both => {
                cfg.b_angles = degs(&[0.0, 90.0]);
                cfg.c_angles = degs(&[0.0, 120.0, 240.0]);
            }
            Variant::Laser => {
                cfg.head = Head::Laser { tilt: [2.0 * DEG, -1.5 * DEG], range: 10.0 };
                cfg.b_angles = degs(&[0.0, 60.0]);
                cfg.c_angles = degs(&[0.0, 120.0, 240.0]);
                cfg.cap_half_angle = 45.0 * DEG;
            }
            Variant::Pyramid => {
                cfg.reference = Reference::Pyramid {
                    apex: Point3::new(580.0, 310.0, 60.0),
                    faces: 4,
                    slope: 45.0 * DEG,
                    yaw: 15.0 * DEG,
                    inner: 3.0,
                    outer: 20.0,
                };
                cfg.b_angles = degs(&[0.0, 45.0]);
                cfg.c_angles = degs(&[0.0, 90.0]);
                cfg.points_per_orientation = 40;
            }
            Variant::Cuboid => {
                cfg.reference = Reference::CuboidCorner {
                    vertex: Point3::new(590.0, 300.0, 50.0),
                    yaw: 30.0 * DEG,
                    inner: 2.0,
                    outer: 25.0,
                };
                cfg.b_angles = degs(&[0.0, 45.0]);
                cfg.c_angles = degs(&[0.0, 90.0]);
                cfg.points_per_orientation = 36;
            }
        }
        cfg
    }
}

impl HeadOffsetConfig {
    /// The preset of `variant` with the reference object placed at random anywhere on a Ø 600 mm
    /// table (50–200 mm above it), a random offset R with each component in ±300 mm, and for a
    /// laser head random tilts within ±5°; all drawn from `seed` (the data's noise too).
    pub fn randomized(variant: Variant, seed: u64) -> HeadOffsetConfig {
        let mut cfg = HeadOffsetConfig::preset(variant, seed);
        // A separate stream so the placement does not share numbers with the measurement noise.
        let mut rng = crate::noise::stream(seed, 0x4845_4144);
        let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.random::<f64>();
        cfg.offset = Vector3::new(u(-300.0, 300.0), u(-300.0, 300.0), u(-300.0, 300.0));
        let (r, phi) = (300.0 * u(0.0, 1.0).sqrt(), u(0.0, std::f64::consts::TAU));
        let spot = cfg.table_centre + Vector3::new(r * phi.cos(), r * phi.sin(), u(50.0, 200.0));
        let yaw = u(0.0, std::f64::consts::TAU);
        cfg.reference = match cfg.reference {
            Reference::Sphere { .. } => Reference::Sphere { centre: spot, radius: u(5.0, 25.0) },
            Reference::Pyramid { faces, slope, inner, outer, .. } => {
                Reference::Pyramid { apex: spot, faces, slope, yaw, inner, outer }
            }
            Reference::CuboidCorner { inner, outer, .. } => {
                Reference::CuboidCorner { vertex: spot, yaw, inner, outer }
            }
        };
        cfg.head = match cfg.head {
            Head::TouchProbe { .. } => Head::TouchProbe { tip_radius: u(0.5, 2.5) },
            Head::Laser { range, .. } => {
                Head::Laser { tilt: [u(-5.0, 5.0) * DEG, u(-5.0, 5.0) * DEG], range }
            }
        };
        cfg
    }
}

/// One row of `points.csv`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HeadOffsetRow {
    /// Head swivel (degrees, as in the file).
    pub b_deg: f64,
    /// Table angle (degrees).
    pub c_deg: f64,
    /// Raw machine coordinates of the head's reference point P reported by the NC (mm).
    pub x_mm: f64,
    /// Y of P, mm.
    pub y_mm: f64,
    /// Z of P, mm.
    pub z_mm: f64,
    /// Laser distance reading (mm), laser head only.
    pub dist_mm: Option<f64>,
    /// Face id, vertex references only.
    pub face: Option<usize>,
    /// Orientation id (index of the (b, c) pair, b-major).
    pub group: usize,
}

/// One face of a vertex reference, at c = 0.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FaceTruth {
    /// The face id of the rows.
    pub id: usize,
    /// Outward unit normal.
    pub normal: [f64; 3],
    /// Number of rows on this face.
    pub n_points: usize,
}

/// What a calibration should recover (`truth.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeadOffsetTruth {
    /// Whether the rows come from a machine with geometric errors (see
    /// [`HeadOffsetConfig::machine`]); then the contract model is exact only to that error.
    pub machine_errors: bool,
    /// The reference object (`sphere`, `pyramid`, `cuboid`).
    pub variant_reference: &'static str,
    /// R (mm).
    pub offset_mm: [f64; 3],
    /// Which components of R the orientations determine (rigid geometry; see
    /// [`observable_components`]).
    pub observable: [bool; 3],
    /// Sphere centre or vertex at c = 0 (mm).
    pub reference_point_mm: [f64; 3],
    /// Sphere radius (mm).
    pub sphere_radius_mm: Option<f64>,
    /// Touch-probe tip radius (mm).
    pub tip_radius_mm: Option<f64>,
    /// Radius of the sphere the rows' Q points lie on (sphere radius + tip radius for a touch
    /// probe; the sphere radius for a laser head).
    pub fitted_radius_mm: Option<f64>,
    /// A point of the table's C axis, mm.
    pub table_center_mm: [f64; 3],
    /// Laser beam tilt α, β (degrees).
    pub tilt_deg: Option<[f64; 2]>,
    /// Laser beam direction u in the head frame at b = 0.
    pub beam_direction: Option<[f64; 3]>,
    /// The head angles B of the orientations, degrees.
    pub b_deg: Vec<f64>,
    /// The table angles C of the orientations, degrees.
    pub c_deg: Vec<f64>,
    /// The faces of a vertex reference.
    pub faces: Vec<FaceTruth>,
    /// Standard deviation of the simulated noise, µm.
    pub noise_um: f64,
    /// Number of rows.
    pub n_points: usize,
    /// Seed of the noise.
    pub seed: u64,
}

/// The data set.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadOffsetData {
    /// The rows of `points.csv`.
    pub rows: Vec<HeadOffsetRow>,
    /// What a calibration should recover.
    pub truth: HeadOffsetTruth,
}

fn invalid(name: &'static str, reason: impl Into<String>) -> HeadOffsetError {
    HeadOffsetError::Invalid { name, reason: reason.into() }
}

fn finite_pt(name: &'static str, p: &Point3) -> Result<(), HeadOffsetError> {
    if p.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(invalid(name, "not finite"))
    }
}

fn positive(name: &'static str, v: f64) -> Result<(), HeadOffsetError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(name, format!("{v} must be positive and finite")))
    }
}

impl HeadOffsetConfig {
    fn validate(&self) -> Result<(), HeadOffsetError> {
        if !self.offset.iter().all(|v| v.is_finite()) {
            return Err(invalid("offset", "not finite"));
        }
        finite_pt("table_centre", &self.table_centre)?;
        if self.b_angles.is_empty() || self.c_angles.is_empty() {
            return Err(invalid("angles", "need at least one B and one C angle"));
        }
        if !self.b_angles.iter().chain(&self.c_angles).all(|a| a.is_finite()) {
            return Err(invalid("angles", "not finite"));
        }
        let n_orient = self.b_angles.len().saturating_mul(self.c_angles.len());
        if self.points_per_orientation == 0 {
            return Err(invalid("points_per_orientation", "must be at least 1"));
        }
        if n_orient.saturating_mul(self.points_per_orientation) > MAX_ROWS {
            return Err(invalid("points_per_orientation", format!("more than {MAX_ROWS} rows")));
        }
        if !(self.cap_half_angle.is_finite() && self.cap_half_angle > 0.0 && self.cap_half_angle < 89.0 * DEG)
        {
            return Err(invalid("cap_half_angle", "must be in (0°, 89°)"));
        }
        if !(self.noise.is_finite() && self.noise >= 0.0) {
            return Err(invalid("noise", "must be ≥ 0 and finite"));
        }
        match self.head {
            Head::TouchProbe { tip_radius } => {
                if !(tip_radius.is_finite() && tip_radius >= 0.0) {
                    return Err(invalid("tip_radius", "must be ≥ 0 and finite"));
                }
            }
            Head::Laser { tilt, range } => {
                positive("range", range)?;
                if !tilt.iter().all(|t| t.is_finite() && t.abs() < 80.0 * DEG) {
                    return Err(invalid("tilt", "tilt angles must be finite and below 80°"));
                }
            }
        }
        match self.reference {
            Reference::Sphere { centre, radius } => {
                finite_pt("sphere centre", &centre)?;
                positive("sphere radius", radius)?;
            }
            Reference::Pyramid { apex, faces, slope, yaw, inner, outer } => {
                finite_pt("apex", &apex)?;
                if !(3..=8).contains(&faces) {
                    return Err(invalid("faces", "a pyramid has 3 to 8 faces"));
                }
                if !(slope.is_finite() && slope > 5.0 * DEG && slope < 85.0 * DEG) {
                    return Err(invalid("slope", "must be in (5°, 85°)"));
                }
                if !yaw.is_finite() {
                    return Err(invalid("yaw", "not finite"));
                }
                positive("inner", inner)?;
                if !(outer.is_finite() && outer > inner) {
                    return Err(invalid("outer", "must exceed inner"));
                }
            }
            Reference::CuboidCorner { vertex, yaw, inner, outer } => {
                finite_pt("vertex", &vertex)?;
                if !yaw.is_finite() {
                    return Err(invalid("yaw", "not finite"));
                }
                positive("inner", inner)?;
                if !(outer.is_finite() && outer > inner) {
                    return Err(invalid("outer", "must exceed inner"));
                }
            }
        }
        Ok(())
    }
}

/// Face planes of a vertex reference at c = 0: (outward normal, sampler of a point on the face
/// from two uniforms).
struct Faces {
    normals: Vec<Vector3>,
    kind: Reference,
}

impl Faces {
    fn new(reference: Reference) -> Option<Faces> {
        let normals = match reference {
            Reference::Sphere { .. } => return None,
            Reference::Pyramid { faces, slope, yaw, .. } => (0..faces)
                .map(|k| {
                    let phi = yaw + std::f64::consts::TAU * k as f64 / faces as f64;
                    Vector3::new(slope.sin() * phi.cos(), slope.sin() * phi.sin(), slope.cos())
                })
                .collect(),
            Reference::CuboidCorner { yaw, .. } => {
                let r = rz(yaw);
                vec![Vector3::z(), r * Vector3::x(), r * Vector3::y()]
            }
        };
        Some(Faces { normals, kind: reference })
    }

    /// Point on face `k` (c = 0) for uniforms `u1, u2 ∈ [0, 1)`.
    fn sample(&self, k: usize, u1: f64, u2: f64) -> Point3 {
        match self.kind {
            Reference::Pyramid { apex, faces, slope, yaw, inner, outer } => {
                let phik = yaw + std::f64::consts::TAU * k as f64 / faces as f64;
                // Stay 15 % of the sector away from the edges.
                let half = 0.85 * std::f64::consts::PI / faces as f64;
                let phi = phik + (2.0 * u1 - 1.0) * half;
                let rho = inner + (outer - inner) * u2;
                let (hx, hy) = (rho * phi.cos(), rho * phi.sin());
                let z = -slope.tan() * (phik.cos() * hx + phik.sin() * hy);
                apex + Vector3::new(hx, hy, z)
            }
            Reference::CuboidCorner { vertex, yaw, inner, outer } => {
                let r = rz(yaw);
                let (e1, e2, e3) = (r * Vector3::x(), r * Vector3::y(), Vector3::z());
                let a = inner + (outer - inner) * u1;
                let b = inner + (outer - inner) * u2;
                match k {
                    0 => vertex - a * e1 - b * e2,
                    1 => vertex - a * e2 - b * e3,
                    _ => vertex - a * e1 - b * e3,
                }
            }
            Reference::Sphere { .. } => unreachable!("Faces is never built for a sphere"),
        }
    }
}

/// Unit vector in a cap of half angle `half` about unit `axis`, uniform in area.
fn cap_direction<R: Rng + ?Sized>(rng: &mut R, axis: &Vector3, half: f64) -> Vector3 {
    let cos_t = 1.0 - rng.random::<f64>() * (1.0 - half.cos());
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = rng.random::<f64>() * std::f64::consts::TAU;
    // Orthonormal basis around the axis.
    let helper = if axis.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let e1 = axis.cross(&helper).normalize();
    let e2 = axis.cross(&e1);
    (axis * cos_t + e1 * (sin_t * phi.cos()) + e2 * (sin_t * phi.sin())).normalize()
}

/// Which components of R a set of orientations determines when the reference object's position is
/// unknown: after undoing the table rotation the apparent reference point of orientation (b, c)
/// is `A − Rz(−c)·Ry(b)·R`, so R is determined up to the null space of the differences
/// `Rz(−c_i)·Ry(b_i) − Rz(−c_0)·Ry(b_0)`; component j is observable when every null vector has a
/// zero j-component.
pub fn observable_components(orientations: &[(f64, f64)]) -> [bool; 3] {
    let Some(&(b0, c0)) = orientations.first() else {
        return [false; 3];
    };
    let m0 = rz(-c0) * ry(b0);
    let mut ntn = Matrix3::zeros();
    for &(b, c) in &orientations[1..] {
        let d = rz(-c) * ry(b) - m0;
        ntn += d.transpose() * d;
    }
    let eig = ntn.symmetric_eigen();
    let scale = eig.eigenvalues.iter().fold(0.0f64, |a, &v| a.max(v.abs())).max(1e-300);
    let mut obs = [true; 3];
    for i in 0..3 {
        if eig.eigenvalues[i] <= 1e-10 * scale.max(1.0) {
            let v = eig.eigenvectors.column(i);
            for (j, o) in obs.iter_mut().enumerate() {
                if v[j].abs() > 1e-6 {
                    *o = false;
                }
            }
        }
    }
    obs
}

/// Build the data set.
pub fn simulate(cfg: &HeadOffsetConfig) -> Result<HeadOffsetData, HeadOffsetError> {
    cfg.validate()?;
    let mut rng = crate::noise::rng(cfg.seed);
    let table = RotaryTable { centre: cfg.table_centre };
    // Rotary-axis location errors of the machine, if any (zero: the contract model).
    let rot_err = cfg.machine.as_ref().map(|m| m.rotary_errors).unwrap_or_default();
    let origin = Point3::origin();
    let faces = Faces::new(cfg.reference);
    let n_faces = faces.as_ref().map_or(0, |f| f.normals.len());
    let mut face_counts = vec![0usize; n_faces];
    let laser = match cfg.head {
        Head::Laser { tilt, range } => Some(LaserHead { tilt, range, noise: cfg.noise }),
        Head::TouchProbe { .. } => None,
    };
    let tip = match cfg.head {
        Head::TouchProbe { tip_radius } => tip_radius,
        Head::Laser { .. } => 0.0,
    };
    let orientations: Vec<(f64, f64)> =
        cfg.b_angles.iter().flat_map(|&b| cfg.c_angles.iter().map(move |&c| (b, c))).collect();
    let mut rows = Vec::with_capacity(orientations.len() * cfg.points_per_orientation);

    for (group, &(b, c)) in orientations.iter().enumerate() {
        // Direction from the surface towards the head: against the probe axis / beam.
        let toward_head = match &laser {
            Some(l) => -l.beam_direction(b),
            None => ry(b) * Vector3::z(),
        };
        // Visible faces in this orientation (normals at table angle c).
        let visible: Vec<usize> = match &faces {
            None => Vec::new(),
            Some(f) => (0..n_faces)
                .filter(|&k| {
                    let n = table.rotate_vector_with(&f.normals[k], c, &rot_err);
                    let cos_inc = n.dot(&toward_head);
                    // A touch probe reaches faces up to slightly past perpendicular to its axis
                    // (stylus side contact); a laser needs ≤ 70° incidence.
                    if laser.is_some() {
                        cos_inc > 20.0f64.to_radians().sin()
                    } else {
                        cos_inc > -0.05
                    }
                })
                .collect(),
        };
        if faces.is_some() && visible.is_empty() {
            continue;
        }
        let mut attempts = 0usize;
        let mut made = 0usize;
        while made < cfg.points_per_orientation {
            attempts += 1;
            if attempts > 100 * cfg.points_per_orientation + 100 {
                return Err(HeadOffsetError::LaserCannotReach { b_deg: b / DEG, c_deg: c / DEG });
            }
            // Surface point S, outward normal n, surface (for the laser), face id.
            let (s, n, surface, face) = match (&faces, cfg.reference) {
                (None, Reference::Sphere { centre, radius }) => {
                    let ctr = table.to_machine_with(&centre, c, &rot_err);
                    let n = cap_direction(&mut rng, &toward_head, cfg.cap_half_angle);
                    (ctr + radius * n, n, Surface::Sphere { centre: ctr, radius }, None)
                }
                (Some(f), _) => {
                    let k = visible[made % visible.len()];
                    let (u1, u2) = (rng.random::<f64>(), rng.random::<f64>());
                    let p = table.to_machine_with(&f.sample(k, u1, u2), c, &rot_err);
                    let n = table.rotate_vector_with(&f.normals[k], c, &rot_err);
                    (p, n, Surface::Plane { point: p, normal: n }, Some(k))
                }
                (None, _) => unreachable!("faces exist for every non-sphere reference"),
            };
            let (q, dist) = match &laser {
                Some(l) => {
                    let w = l.beam_direction(b);
                    let d = (rng.random::<f64>() - 0.5) * 0.8 * l.range;
                    let q = s - d * w;
                    // The exact ray intersection from the focus must return d; it fails only if
                    // the beam meets another part of the object first (not possible for a sphere
                    // cap facing the beam or a single face), which we skip.
                    match l.reading(&q, b, &surface, &mut rng) {
                        Ok(reading) => (q, Some(reading)),
                        Err(_) => continue,
                    }
                }
                None => {
                    let e = crate::noise::gaussian(&mut rng, cfg.noise);
                    (s + (tip + e) * n, None)
                }
            };
            let p = match &cfg.machine {
                None => head_reference(&q, b, &cfg.offset),
                Some(m) => {
                    match m.command_for(&q, &(head_point_with(&origin, b, &cfg.offset, &rot_err) - origin)) {
                        Some(p) => p,
                        None => return Err(invalid("machine", "geometric errors too large to invert")),
                    }
                }
            };
            if let Some(k) = face {
                face_counts[k] += 1;
            }
            rows.push(HeadOffsetRow {
                b_deg: b / DEG,
                c_deg: c / DEG,
                x_mm: p.x,
                y_mm: p.y,
                z_mm: p.z,
                dist_mm: dist,
                face,
                group,
            });
            made += 1;
        }
    }
    if let Some(k) = face_counts.iter().position(|&n| n == 0) {
        return Err(HeadOffsetError::FaceNeverVisible { face: k });
    }

    let truth = truth_of(cfg, &orientations, laser, tip, faces, &face_counts, rows.len());
    Ok(HeadOffsetData { rows, truth })
}

/// What the data set was made from (`truth.json`).
fn truth_of(
    cfg: &HeadOffsetConfig,
    orientations: &[(f64, f64)],
    laser: Option<LaserHead>,
    tip: f64,
    faces: Option<Faces>,
    face_counts: &[usize],
    n_points: usize,
) -> HeadOffsetTruth {
    let (reference_point, sphere_radius, kind) = match cfg.reference {
        Reference::Sphere { centre, radius } => (centre, Some(radius), "sphere"),
        Reference::Pyramid { apex, .. } => (apex, None, "vertex"),
        Reference::CuboidCorner { vertex, .. } => (vertex, None, "vertex"),
    };
    HeadOffsetTruth {
        machine_errors: cfg.machine.is_some(),
        variant_reference: kind,
        offset_mm: cfg.offset.into(),
        observable: observable_components(orientations),
        reference_point_mm: reference_point.coords.into(),
        sphere_radius_mm: sphere_radius,
        tip_radius_mm: laser.is_none().then_some(tip),
        fitted_radius_mm: sphere_radius.map(|r| r + tip),
        table_center_mm: cfg.table_centre.coords.into(),
        tilt_deg: laser.map(|l| [l.tilt[0] / DEG, l.tilt[1] / DEG]),
        beam_direction: laser.map(|l| l.beam_direction_head().into()),
        b_deg: cfg.b_angles.iter().map(|b| b / DEG).collect(),
        c_deg: cfg.c_angles.iter().map(|c| c / DEG).collect(),
        faces: faces
            .map(|f| {
                f.normals
                    .iter()
                    .enumerate()
                    .map(|(id, n)| FaceTruth { id, normal: (*n).into(), n_points: face_counts[id] })
                    .collect()
            })
            .unwrap_or_default(),
        noise_um: cfg.noise * 1e3,
        n_points,
        seed: cfg.seed,
    }
}

impl truepos_math::exit::HasExitClass for HeadOffsetError {
    /// A scenario setting that cannot be simulated is bad usage (exit 2).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        truepos_math::exit::ExitClass::Usage
    }
}
