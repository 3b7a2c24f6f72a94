//! Acquisition: probing a reference sphere through any [`ProbingMachine`] (`truepos probe
//! sphere`, and the point collection of head-offset calibration where the machine has the axes).
//!
//! [`probe_sphere`] distributes the points over the upper hemisphere of the nominal sphere
//! ([`hemisphere_directions`]: one at the pole, the others on a golden-angle spiral of equal
//! area down to [`MAX_POLAR_DEG`] from the pole), and reaches each one safely: up to the safe
//! height (the nominal top of the tip-centre sphere plus twice the clearance), across at that
//! height, down to the start point, which lies `clearance` outside the nominal surface along the
//! surface normal; then one probing move along the inward normal that gives up `clearance`
//! beyond the nominal surface, and back up. A vertical line above a start point on the upper
//! hemisphere only gets farther from the centre, so the descent keeps the clearance from the
//! nominal sphere. The nominal centre must therefore be known to better than the clearance
//! (otherwise a probe misses, or trips during a positioning move: both are errors naming the
//! move, with the machine retracted).
//!
//! [`probe_sphere_about`] does the same with "up" along another direction (the tool axis of a
//! five-axis machine whose positions turn with its table; `truepos kinematics calibrate`).
//!
//! [`acquire_head_offset`] repeats this at several head (B) and table (C) orientations, where
//! the machine has those axes, and [`points_csv`] writes the head-offset points file
//! (`truepos head-offset acquire`; [`readings`] gives the same readings in memory); a machine
//! without them is refused before it moves.
//!
//! The latched tip centres are fitted with the least-squares sphere (`truepos_fit::sphere`,
//! orthogonal distances); the sphere's radius is the fitted radius minus the tip radius.

use thiserror::Error;
use truepos_device::{DeviceError, DeviceInfo, ProbeRequest, ProbingMachine};
use truepos_fit::FitError;
use truepos_math::{Point3, Vector3};

/// The lowest probing point, as the angle from the pole (deg): points near the equator would
/// approach horizontally and leave the stem of a reference sphere no room.
pub const MAX_POLAR_DEG: f64 = 80.0;

/// The largest length a probing request may state (mm): 100 000 mm = 100 m, beyond the
/// travel of any machine tool or CMM. A sphere diameter, clearance, tip diameter or centre
/// coordinate above it cannot be reached by a machine: refused before the machine is opened,
/// naming the option and this limit (a `--diameter-mm 1e308` otherwise overflowed the safe
/// height and failed later as a machine error).
pub const MAX_LENGTH_MM: f64 = truepos_device::MAX_LENGTH_MM;

/// What to probe and how.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereProbing {
    /// Nominal centre (machine frame, mm).
    pub near_mm: Point3,
    /// Nominal sphere diameter (mm).
    pub diameter_mm: f64,
    /// Number of points (≥ 5: four determine a sphere and leave nothing to check it).
    pub points: usize,
    /// Probing feed (mm/s).
    pub feed_mm_s: f64,
    /// Distance from the nominal surface at which each probing move starts, and beyond which
    /// it gives up (mm).
    pub clearance_mm: f64,
    /// Stylus tip radius (mm).
    pub tip_radius_mm: f64,
}

/// A probed and fitted sphere.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbedSphere {
    /// Centre of the sphere in machine coordinates, mm.
    pub center_mm: Point3,
    /// Radius of the sphere: fitted tip-centre sphere minus the tip radius.
    pub radius_mm: f64,
    /// RMS orthogonal residual of the fit, mm.
    pub rms_mm: f64,
    /// Largest absolute orthogonal residual of the fit, mm.
    pub max_abs_residual_mm: f64,
    /// Standard uncertainties of the centre from the fit covariance, mm.
    pub center_uncertainty_mm: Vector3,
    /// Standard uncertainty of the radius from the fit covariance, mm.
    pub radius_uncertainty_mm: f64,
    /// The latched tip centres, in probing order.
    pub points: Vec<Point3>,
    /// The machine the points came from.
    pub device: DeviceInfo,
}

impl ProbedSphere {
    /// The probed sphere as the JSON of `truepos probe sphere --json` (centre, radius, diameter,
    /// residuals, every contact point, standard uncertainties).
    pub fn to_json(&self) -> serde_json::Value {
        let v3 = |v: &nalgebra::Vector3<f64>| serde_json::json!([v.x, v.y, v.z]);
        serde_json::json!({
            "center_mm": v3(&self.center_mm.coords),
            "radius_mm": self.radius_mm,
            "diameter_mm": 2.0 * self.radius_mm,
            "rms_mm": self.rms_mm,
            "max_abs_residual_mm": self.max_abs_residual_mm,
            "n_points": self.points.len(),
            "points": self.points.iter().map(|p| v3(&p.coords)).collect::<Vec<_>>(),
            "center_uncertainty_mm": v3(&self.center_uncertainty_mm),
            "radius_uncertainty_mm": self.radius_uncertainty_mm,
        })
    }
}

/// Why probing the reference sphere failed.
#[derive(Debug, Error)]
pub enum AcquireError {
    /// The request cannot be carried out as given.
    #[error("invalid sphere probing: {0}")]
    Plan(String),
    /// The machine failed (the machine has been left retracted where it could move).
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// The points do not determine a sphere.
    #[error("sphere fit of the probed points: {0}")]
    Fit(#[from] FitError),
    /// The points file could not be written.
    #[error(transparent)]
    Output(#[from] truepos_io::atomic::OutputError),
}

/// `n` unit directions over the upper hemisphere: the pole first, then a golden-angle spiral of
/// equal area down to `max_polar` (rad) from the pole.
pub fn hemisphere_directions(n: usize, max_polar: f64) -> Vec<Vector3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let zmin = max_polar.cos();
    (0..n)
        .map(|i| {
            if i == 0 {
                return Vector3::z();
            }
            // Equal-area steps in z from just below the pole to the lowest ring.
            let f = i as f64 / (n - 1).max(1) as f64;
            let z = 1.0 - f * (1.0 - zmin);
            let rho = (1.0 - z * z).max(0.0).sqrt();
            let phi = i as f64 * golden;
            Vector3::new(rho * phi.cos(), rho * phi.sin(), z)
        })
        .collect()
}

impl SphereProbing {
    /// Check the request (before any machine moves).
    pub fn check(&self) -> Result<(), AcquireError> {
        let bad = |m: &str| Err(AcquireError::Plan(m.to_string()));
        if !self.near_mm.iter().all(|v| v.is_finite()) {
            return bad("the nominal centre is not finite");
        }
        if !(self.diameter_mm.is_finite() && self.diameter_mm > 0.0) {
            return bad("the diameter must be a positive number (mm)");
        }
        let too_large = |what: &str, v: f64| {
            // 1e308 as written, not as 309 digits.
            let v = if v.abs() < 1e9 { format!("{v}") } else { format!("{v:e}") };
            Err(AcquireError::Plan(format!(
                "{what} {v} mm is above {MAX_LENGTH_MM} mm (100 m), the physical limit: no machine tool or CMM travels that far"
            )))
        };
        if let Some(v) = self.near_mm.iter().find(|v| v.abs() > MAX_LENGTH_MM) {
            return too_large("a coordinate of the nominal centre (--near)", *v);
        }
        if self.diameter_mm > MAX_LENGTH_MM {
            return too_large("the sphere diameter (--diameter-mm)", self.diameter_mm);
        }
        if self.clearance_mm > MAX_LENGTH_MM {
            return too_large("the clearance (--clearance-mm)", self.clearance_mm);
        }
        if 2.0 * self.tip_radius_mm > MAX_LENGTH_MM {
            return too_large("the tip diameter (--tip-diameter-mm)", 2.0 * self.tip_radius_mm);
        }
        if !(5..=10_000).contains(&self.points) {
            return bad("the number of points must be between 5 and 10000 (four determine a sphere and leave nothing to check it)");
        }
        if let Some(why) = truepos_device::probing_feed_problem(self.feed_mm_s * 60.0) {
            return Err(AcquireError::Plan(why));
        }
        if !(self.clearance_mm.is_finite() && self.clearance_mm > 0.0) {
            return bad("the clearance must be a positive number (mm)");
        }
        if !(self.tip_radius_mm.is_finite() && self.tip_radius_mm >= 0.0) {
            return bad("the tip diameter must be a number ≥ 0 (mm)");
        }
        Ok(())
    }

    /// Height of the clearance moves (mm).
    pub fn safe_z_mm(&self) -> f64 {
        self.near_mm.z + 0.5 * self.diameter_mm + self.tip_radius_mm + 2.0 * self.clearance_mm
    }

    /// The probing requests, in order.
    pub fn requests(&self) -> Vec<ProbeRequest> {
        let r = 0.5 * self.diameter_mm;
        hemisphere_directions(self.points, MAX_POLAR_DEG.to_radians())
            .into_iter()
            .map(|d| {
                ProbeRequest::with_clearance(
                    self.near_mm + d * r,
                    d,
                    self.tip_radius_mm,
                    self.clearance_mm,
                    self.feed_mm_s,
                )
            })
            .collect()
    }
}

/// Probe the sphere as [`SphereProbing`] says and fit it. The machine ends at the safe height
/// above the last point; on a failure it is left where the failing move left it (a probing move
/// without contact: back at its start point, clear of the sphere) and then raised to the safe
/// height where it can be.
pub fn probe_sphere<M: ProbingMachine + ?Sized>(
    m: &mut M,
    plan: &SphereProbing,
) -> Result<ProbedSphere, AcquireError> {
    plan.check()?;
    let safe_z = plan.safe_z_mm();
    let mut points = Vec::with_capacity(plan.points);
    let p0 = m.position()?;
    // Up first (never down to the safe height from above: that could reach the sphere).
    let mut at = Point3::new(p0.x, p0.y, p0.z.max(safe_z));
    if at != p0 {
        m.move_to(at)?;
    }
    for req in plan.requests() {
        let start = req.start_mm();
        let above = Point3::new(start.x, start.y, safe_z);
        let run = |m: &mut M, at: &mut Point3| -> Result<Point3, DeviceError> {
            if at.z < safe_z {
                *at = Point3::new(at.x, at.y, safe_z);
                m.move_to(*at)?;
            }
            if (*at - above).norm() > 0.0 {
                m.move_to(above)?;
            }
            m.move_to(start)?;
            *at = start;
            let hit = m.probe(&req)?;
            *at = hit.tip_center_mm + req.approach * req.retract_mm;
            Ok(hit.tip_center_mm)
        };
        match run(m, &mut at) {
            Ok(p) => points.push(p),
            Err(e) => {
                if let DeviceError::NoContact { .. } = e {
                    // Retracted to the start point by the machine: up and clear.
                    let _ = m.move_to(above);
                }
                return Err(e.into());
            }
        }
    }
    m.move_to(Point3::new(at.x, at.y, safe_z))?;
    let fit = truepos_fit::sphere(&points)?;
    Ok(ProbedSphere {
        center_mm: fit.center,
        radius_mm: fit.radius - plan.tip_radius_mm,
        rms_mm: fit.rms,
        max_abs_residual_mm: fit.max_abs_residual,
        center_uncertainty_mm: fit.u_center,
        radius_uncertainty_mm: fit.u_radius,
        points,
        device: m.info(),
    })
}

/// [`probe_sphere`] in a turned frame: the same plan, with "up" (the pole of the probed cap, the
/// direction of the clearance moves) along `programme_from_local`'s third column instead of +Z,
/// and the whole pattern turned with it about the nominal centre. For a five-axis machine with
/// tool-centre-point control, whose positions are in the programme frame that turns with the
/// table, `programme_from_local` is the table's rotation (machine directions in the programme
/// frame): the cap then faces the tool and the pattern is the same in the machine at every
/// orientation. The result is in the programme frame (centre, points); each centre
/// uncertainty is the rotated per-axis uncertainty with the fit's correlations left out.
///
/// `programme_from_local` must be a rotation (orthonormal, determinant +1).
pub fn probe_sphere_about<M: ProbingMachine + ?Sized>(
    m: &mut M,
    plan: &SphereProbing,
    programme_from_local: &nalgebra::Matrix3<f64>,
) -> Result<ProbedSphere, AcquireError> {
    plan.check()?;
    let r = programme_from_local;
    let orthonormal = (r.transpose() * r - nalgebra::Matrix3::identity()).abs().max() < 1e-9;
    if !(r.iter().all(|v| v.is_finite()) && orthonormal && r.determinant() > 0.0) {
        return Err(AcquireError::Plan("the probing frame is not a rotation".into()));
    }
    let mut turned = Turned { m, frame: *r, origin: plan.near_mm };
    let s = probe_sphere(&mut turned, plan)?;
    let to_prog = |p: &Point3| turned.to_programme(p);
    let u = s.center_uncertainty_mm;
    let u_prog = Vector3::from_fn(|i, _| (0..3).map(|j| (r[(i, j)] * u[j]).powi(2)).sum::<f64>().sqrt());
    Ok(ProbedSphere {
        center_mm: to_prog(&s.center_mm),
        points: s.points.iter().map(to_prog).collect(),
        center_uncertainty_mm: u_prog,
        ..s
    })
}

/// A machine seen in a frame turned about `origin`: local `q` is programme
/// `origin + frame·(q − origin)`.
struct Turned<'a, M: ?Sized> {
    m: &'a mut M,
    frame: nalgebra::Matrix3<f64>,
    origin: Point3,
}

impl<M: ProbingMachine + ?Sized> Turned<'_, M> {
    fn to_programme(&self, q: &Point3) -> Point3 {
        self.origin + self.frame * (q - self.origin)
    }
    fn to_local(&self, p: &Point3) -> Point3 {
        self.origin + self.frame.transpose() * (p - self.origin)
    }
}

impl<M: ProbingMachine + ?Sized> ProbingMachine for Turned<'_, M> {
    fn info(&self) -> DeviceInfo {
        self.m.info()
    }
    fn position(&mut self) -> Result<Point3, DeviceError> {
        let p = self.m.position()?;
        Ok(self.to_local(&p))
    }
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        let p = self.to_programme(&target_mm);
        self.m.move_to(p)
    }
    fn probe(&mut self, request: &ProbeRequest) -> Result<truepos_device::ProbeHit, DeviceError> {
        let req = ProbeRequest {
            nominal_mm: self.to_programme(&request.nominal_mm),
            approach: self.frame * request.approach,
            ..*request
        };
        let hit = self.m.probe(&req)?;
        Ok(truepos_device::ProbeHit {
            tip_center_mm: self.to_local(&hit.tip_center_mm),
            normal: hit.normal.map(|n| self.frame.transpose() * n),
        })
    }
    fn abort(&mut self) -> Result<(), DeviceError> {
        self.m.abort()
    }
}

impl truepos_math::exit::HasExitClass for AcquireError {
    /// A plan that cannot be carried out (2); an output path per [`truepos_io::atomic::OutputError`];
    /// a machine failure or points that do not fit a sphere (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        match self {
            AcquireError::Plan(_) => ExitClass::Usage,
            AcquireError::Output(o) => truepos_math::exit::HasExitClass::exit_class(o),
            AcquireError::Device(_) | AcquireError::Fit(_) => ExitClass::Device,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_cover_the_upper_cap_with_the_pole_first() {
        let max = MAX_POLAR_DEG.to_radians();
        for n in [5, 12, 25, 100] {
            let d = hemisphere_directions(n, max);
            assert_eq!(d.len(), n);
            assert_eq!(d[0], Vector3::z());
            for v in &d {
                assert!((v.norm() - 1.0).abs() < 1e-12);
                assert!(v.z >= max.cos() - 1e-12, "{v}");
            }
            // The lowest point is on the lowest ring; points are distinct.
            assert!((d[n - 1].z - max.cos()).abs() < 1e-12);
            for i in 0..n {
                for j in 0..i {
                    assert!((d[i] - d[j]).norm() > 1e-3);
                }
            }
        }
    }

    #[test]
    fn plans_are_validated() {
        let ok = SphereProbing {
            near_mm: Point3::origin(),
            diameter_mm: 25.0,
            points: 25,
            feed_mm_s: 1.0,
            clearance_mm: 2.0,
            tip_radius_mm: 1.5,
        };
        assert!(ok.check().is_ok());
        assert!(SphereProbing { points: 4, ..ok }.check().is_err());
        assert!(SphereProbing { diameter_mm: -1.0, ..ok }.check().is_err());
        assert!(SphereProbing { clearance_mm: 0.0, ..ok }.check().is_err());
        assert!(SphereProbing { feed_mm_s: f64::NAN, ..ok }.check().is_err());
        // Absurd lengths: refused naming the option and the 100 m limit; the limit itself passes.
        for (p, opt) in [
            (SphereProbing { diameter_mm: 1e308, ..ok }, "--diameter-mm"),
            (SphereProbing { clearance_mm: 1e6, ..ok }, "--clearance-mm"),
            (SphereProbing { tip_radius_mm: 1e300, ..ok }, "--tip-diameter-mm"),
            (SphereProbing { near_mm: Point3::new(0.0, -2e5, 0.0), ..ok }, "--near"),
        ] {
            let e = p.check().unwrap_err().to_string();
            assert!(e.contains(opt) && e.contains("100000 mm (100 m)"), "{e}");
        }
        assert!(SphereProbing { diameter_mm: MAX_LENGTH_MM, ..ok }.check().is_ok());
        // The physical feed limit: 5000 mm/min accepted, above refused with the reason.
        assert!(SphereProbing { feed_mm_s: 5000.0 / 60.0, ..ok }.check().is_ok());
        let e = SphereProbing { feed_mm_s: 1e9 / 60.0, ..ok }.check().unwrap_err().to_string();
        assert!(e.contains("5000 mm/min") && e.contains("overtravel"), "{e}");
        // Every start point is clearance + tip outside the nominal surface.
        for r in ok.requests() {
            let d = (r.start_mm() - ok.near_mm).norm();
            assert!((d - (12.5 + 1.5 + 2.0)).abs() < 1e-9);
            assert!(r.start_mm().z <= ok.safe_z_mm());
        }
    }
}

/// Head-offset acquisition through a controller: the reference sphere probed at several head
/// (B) and table (C) orientations ([`acquire_head_offset`]), written as the head-offset
/// contract's points file ([`points_csv`]).
///
/// At each orientation the machine positions the NC's head reference point P; the probe tip is
/// at `P + Ry(b)·R`, the sphere (centre `S` at C = 0) at `O + Rz(c)·(S − O)`. So in P
/// coordinates the sphere appears centred at `O + Rz(c)·(S − O) − Ry(b)·R`: the plan probes
/// it there with the nominal offset R, which must therefore be known to better than the
/// clearance (a head drawing's value). The latched points are P positions, exactly the x, y, z
/// of the points file; `truepos head-offset` then finds R from them.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadAcquisition {
    /// The sphere as it sits on the table at C = 0 (nominal centre, diameter) and how to probe
    /// it at every orientation.
    pub sphere: SphereProbing,
    /// The orientations (B, C) in degrees, in order.
    pub orientations: Vec<[f64; 2]>,
    /// The head offset as far as it is known.
    pub nominal_offset_mm: Vector3,
    /// A point of the table's C axis (parallel to Z).
    pub table_center_mm: Point3,
}

/// The sphere probed at one orientation.
#[derive(Debug, Clone, PartialEq)]
pub struct AcquiredOrientation {
    /// Head angle B, degrees.
    pub b_deg: f64,
    /// Table angle C, degrees.
    pub c_deg: f64,
    /// The sphere probed and fitted there.
    pub sphere: ProbedSphere,
}

impl HeadAcquisition {
    /// Check the request (before any machine moves).
    pub fn check(&self) -> Result<(), AcquireError> {
        self.sphere.check()?;
        if self.orientations.is_empty() {
            return Err(AcquireError::Plan("no orientations".into()));
        }
        if self.orientations.iter().flatten().any(|a| !a.is_finite()) {
            return Err(AcquireError::Plan("the orientation angles must be finite".into()));
        }
        // A head swivels at most a quarter turn from vertical (beyond, the stylus points away
        // from the table, as `kinematics` says); a table angle is given within one turn.
        for (k, o) in self.orientations.iter().enumerate() {
            if o[0].abs() > 90.0 || o[1].abs() > 360.0 {
                return Err(AcquireError::Plan(format!(
                    "orientation {} (--orientation {},{}): B must be within ±90° (beyond, the stylus points away from the table) and C within ±360° (one turn of the table)",
                    k + 1,
                    o[0],
                    o[1]
                )));
            }
        }
        if !self.nominal_offset_mm.iter().chain(self.table_center_mm.iter()).all(|v| v.is_finite()) {
            return Err(AcquireError::Plan("the nominal offset and table centre must be finite".into()));
        }
        let far = self
            .nominal_offset_mm
            .iter()
            .map(|v| ("a component of the nominal offset (--nominal-offset-mm)", *v))
            .chain(
                self.table_center_mm
                    .iter()
                    .map(|v| ("a coordinate of the table centre (--table-center-mm)", *v)),
            )
            .find_map(|(what, v)| truepos_device::length_beyond_limit(what, v));
        if let Some(m) = far {
            return Err(AcquireError::Plan(m));
        }
        Ok(())
    }

    /// Refuse, before anything moves, orientations that need an axis the machine does not have.
    pub fn check_axes<M: ProbingMachine + ?Sized>(&self, machine: &M) -> Result<(), AcquireError> {
        let axes = machine.rotary_axes();
        let need_b = self.orientations.iter().any(|o| o[0] != 0.0);
        let need_c = self.orientations.iter().any(|o| o[1] != 0.0);
        let mut missing = vec![];
        if need_b && !axes.head_b {
            missing.push("B (head swivel)");
        }
        if need_c && !axes.table_c {
            missing.push("C (rotary table)");
        }
        if missing.is_empty() {
            return Ok(());
        }
        Err(AcquireError::Device(DeviceError::Rejected {
            address: machine.info().address,
            what: "head-offset acquisition".into(),
            message: format!(
                "the requested orientations need {}, and this machine has {}; a machine without \
                 rotary axes has only B = 0, C = 0, and one orientation determines no head offset",
                missing.join(" and "),
                axes.describe()
            ),
        }))
    }

    /// Where the sphere appears in P coordinates at `(b, c)` degrees with the nominal offset.
    pub fn apparent_center_mm(&self, b_deg: f64, c_deg: f64) -> Point3 {
        let o = self.table_center_mm;
        let s = self.sphere.near_mm;
        o + truepos_math::rz(c_deg.to_radians()) * (s - o)
            - truepos_math::ry(b_deg.to_radians()) * self.nominal_offset_mm
    }

    /// The height (P coordinates) at which the head turns: above the sphere's safe height at
    /// every orientation by twice the offset's length (the tip moves by at most that).
    pub fn turn_z_mm(&self) -> f64 {
        let top = self
            .orientations
            .iter()
            .map(|o| {
                SphereProbing { near_mm: self.apparent_center_mm(o[0], o[1]), ..self.sphere }.safe_z_mm()
            })
            .fold(f64::NEG_INFINITY, f64::max);
        top + 2.0 * self.nominal_offset_mm.norm() + self.sphere.clearance_mm
    }
}

/// Probe the sphere at every orientation: up to the turning height, orient, probe
/// ([`probe_sphere`] around the apparent centre). Orientations the machine cannot reach are
/// refused before anything moves ([`HeadAcquisition::check_axes`]).
pub fn acquire_head_offset<M: ProbingMachine + ?Sized>(
    m: &mut M,
    a: &HeadAcquisition,
) -> Result<Vec<AcquiredOrientation>, AcquireError> {
    a.check()?;
    a.check_axes(m)?;
    let turn_z = a.turn_z_mm();
    let mut out = Vec::with_capacity(a.orientations.len());
    for &[b, c] in &a.orientations {
        let p = m.position()?;
        if p.z < turn_z {
            m.move_to(Point3::new(p.x, p.y, turn_z))?;
        }
        m.orient(b, c)?;
        let plan = SphereProbing { near_mm: a.apparent_center_mm(b, c), ..a.sphere };
        let sphere = probe_sphere(m, &plan)?;
        out.push(AcquiredOrientation { b_deg: b, c_deg: c, sphere });
    }
    let p = m.position()?;
    if p.z < turn_z {
        m.move_to(Point3::new(p.x, p.y, turn_z))?;
    }
    Ok(out)
}

/// The head-offset points file (`b_deg,c_deg,x_mm,y_mm,z_mm,group`, one row per latched point,
/// group = orientation index; numbers in shortest round-trip form).
pub fn points_csv(acquired: &[AcquiredOrientation]) -> String {
    let mut s = String::from("b_deg,c_deg,x_mm,y_mm,z_mm,group\n");
    for (g, o) in acquired.iter().enumerate() {
        for p in &o.sphere.points {
            s += &format!("{},{},{},{},{},{g}\n", o.b_deg, o.c_deg, p.x, p.y, p.z);
        }
    }
    s
}

/// The readings of the points file (what `truepos head-offset --points` reads from it), in
/// memory: one per latched point, angles in rad, group = orientation index.
pub fn readings(acquired: &[AcquiredOrientation]) -> Vec<crate::Reading> {
    acquired
        .iter()
        .enumerate()
        .flat_map(|(g, o)| {
            o.sphere.points.iter().map(move |p| crate::Reading {
                b: o.b_deg.to_radians(),
                c: o.c_deg.to_radians(),
                p: *p,
                dist: None,
                face: None,
                group: Some(g as i64),
            })
        })
        .collect()
}

/// What `truepos head-offset acquire` hands back: the orientations probed, the points file
/// written, and for a virtual machine its truth (head offset, sphere centre at C = 0, radius).
#[derive(Debug, Clone, PartialEq)]
pub struct AcquireReport {
    /// The orientations probed, in order.
    pub acquired: Vec<AcquiredOrientation>,
    /// The points file written.
    pub output: std::path::PathBuf,
    /// The machine probed on.
    pub device: DeviceInfo,
    /// Wall time of the probing, s.
    pub elapsed_s: f64,
    /// The command that computes the offset from the file.
    pub next: String,
    /// For a virtual machine: head offset (mm), sphere centre at C = 0 (mm), sphere radius (mm).
    pub truth: Option<(Vector3, Point3, f64)>,
}

/// Acquire ([`acquire_head_offset`]) and write the points file atomically to `output` (checked
/// before the machine moves). `next` is the head-offset command to suggest.
pub fn acquire_to_file<M: ProbingMachine + ?Sized>(
    m: &mut M,
    a: &HeadAcquisition,
    output: &std::path::Path,
    next: String,
) -> Result<AcquireReport, AcquireError> {
    a.check()?;
    truepos_io::atomic::check_output_path(output)?;
    let t0 = std::time::Instant::now();
    let acquired = acquire_head_offset(m, a)?;
    let elapsed_s = t0.elapsed().as_secs_f64();
    truepos_io::atomic::write_atomic(output, points_csv(&acquired).as_bytes())?;
    Ok(AcquireReport {
        acquired,
        output: output.to_path_buf(),
        device: m.info(),
        elapsed_s,
        next,
        truth: None,
    })
}

impl truepos_io::report::Report for AcquireReport {
    fn to_json(&self) -> serde_json::Value {
        let v3 = |p: &Point3| serde_json::json!([p.x, p.y, p.z]);
        let mut j = serde_json::json!({
            "output": self.output.display().to_string(),
            "n_points": self.acquired.iter().map(|o| o.sphere.points.len()).sum::<usize>(),
            "orientations": self.acquired.iter().map(|o| serde_json::json!({
                "b_deg": o.b_deg,
                "c_deg": o.c_deg,
                "apparent_center_mm": v3(&o.sphere.center_mm),
                "radius_mm": o.sphere.radius_mm,
                "rms_mm": o.sphere.rms_mm,
                "n_points": o.sphere.points.len(),
            })).collect::<Vec<_>>(),
            "controller": { "address": self.device.address, "version": self.device.version },
            "elapsed_s": self.elapsed_s,
            "next": self.next,
        });
        if let Some((off, c, r)) = &self.truth {
            j["virtual_truth"] = serde_json::json!({
                "head_offset_mm": [off.x, off.y, off.z],
                "sphere_center_mm": v3(c),
                "sphere_radius_mm": r,
            });
        }
        j
    }

    fn text(&self) -> String {
        let n: usize = self.acquired.iter().map(|o| o.sphere.points.len()).sum();
        let mut s = format!(
            "head-offset acquisition on {} ({}): {} orientations, {n} points in {:.1} s → {}\n",
            self.device.address,
            self.device.version,
            self.acquired.len(),
            self.elapsed_s,
            self.output.display()
        );
        for o in &self.acquired {
            let c = o.sphere.center_mm;
            s += &format!(
                "  B {:>7.3}° C {:>7.3}°: sphere seen at {:.4} {:.4} {:.4} mm, radius {:.4} mm, rms {:.4} mm\n",
                o.b_deg, o.c_deg, c.x, c.y, c.z, o.sphere.radius_mm, o.sphere.rms_mm
            );
        }
        s += &format!("next: {}\n", self.next);
        if self.acquired.len() < 2 {
            s += "note: one orientation determines no head offset; head-offset will say so\n";
        }
        s
    }

    /// The result is the points file; the text summarises it.
    fn text_on_stderr(&self) -> bool {
        true
    }
}
