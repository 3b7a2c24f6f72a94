//! Features to scan (circles inside bores, outside bosses, on planes; straight lines) and the
//! scan parameters, with validation.
//!
//! Entry points: [`Feature`], [`Geometry`], [`Side`], [`Params`], [`validate`]. A validated
//! feature answers [`Feature::point`] (the stylus-tip-centre position at parameter `u` and
//! offset `h` from the surface along its outward normal), [`Feature::normal`],
//! [`Feature::tangent`] (unit, in the scan direction) and [`Feature::signed_distance`] (from a
//! point to the material surface, positive on the free side). For circles `u` is the angle from
//! the start (rad, growing in the scan direction); for lines it is the distance from the start.

use crate::ScanError;
use truepos_math::{Point3, Vector3};

/// Which surface a circle scan runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Inside a bore: the material is outside the circle.
    Inside,
    /// Outside a boss: the material is inside the circle.
    Outside,
    /// On a plane whose outward normal is the circle's axis.
    Plane,
}

/// The nominal geometry of one feature.
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// A circular arc.
    Circle {
        /// Centre, machine frame, mm.
        center: Point3,
        /// Unit axis; positive sweep turns counter-clockwise seen from its + end.
        axis: Vector3,
        /// Radius, mm.
        radius: f64,
        /// Inside (a bore) or outside (a boss).
        side: Side,
        /// Start angle (rad) from the reference direction (see [`Feature::basis`]).
        start: f64,
        /// Signed sweep (rad).
        sweep: f64,
    },
    /// A straight line on a surface.
    Line {
        /// Start point, machine frame, mm.
        start: Point3,
        /// End point, machine frame, mm.
        end: Point3,
        /// Unit outward normal of the material surface.
        normal: Vector3,
    },
}

/// One feature of the program.
#[derive(Clone, Debug, PartialEq)]
pub struct Feature {
    /// The feature's id in the features file.
    pub id: String,
    /// Its nominal geometry.
    pub geometry: Geometry,
}

/// Scan parameters (internal units: mm, rad, s).
#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    /// Angle between the approach line and the surface normal (20°..60°).
    pub approach_angle: f64,
    /// Path speed while scanning, mm/s.
    pub scan_speed: f64,
    /// Path speed of transfers, mm/s.
    pub move_speed: f64,
    /// Target stylus deflection while scanning.
    pub deflection: f64,
    /// How far past the target deflection the settle path goes.
    pub overshoot: f64,
    /// Quality bands on |deflection − target|: within `[0]` → 0, within `[1]` → 5, else 9.
    pub quality_bands: [f64; 2],
    /// Stylus tip (ball) radius.
    pub tip_radius: f64,
    /// Normal clearance of approach start / release end from the surface.
    pub clearance: f64,
    /// Least tangential length of the settle path (mm).
    pub settle_length: f64,
    /// Least duration of the settle path at scanning speed (s): the settle path is at least
    /// `settle_time · scan_speed` long, so the transient has time to die out at any speed.
    pub settle_time: f64,
    /// Path acceleration limit (mm/s²): the magnitude of the acceleration vector, tangential and
    /// centripetal together, on every positioning move.
    pub accel: f64,
    /// Path jerk limit (mm/s³, the magnitude of the jerk vector) on every positioning move.
    /// Default [`DEFAULT_JERK`].
    pub jerk: f64,
    /// Classic style: speed of the approach along the normal (touch/search speed).
    pub touch_speed: f64,
    /// Classic style: wait at the pre-hit point for the machine to settle.
    pub prehit_dwell: f64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            approach_angle: 45f64.to_radians(),
            scan_speed: 20.0,
            move_speed: 200.0,
            deflection: 0.3,
            overshoot: 0.1,
            quality_bands: [0.02, 0.05],
            tip_radius: 1.5,
            clearance: 3.0,
            settle_length: 3.0,
            settle_time: 0.15,
            accel: 1500.0,
            jerk: DEFAULT_JERK,
            touch_speed: 3.0,
            prehit_dwell: 0.3,
        }
    }
}

/// Default jerk limit: 20 m/s³ (20 000 mm/s³), so the default 1.5 m/s² acceleration is reached
/// in 75 ms — a gentle value for a bridge CMM; files written before the key existed get it.
pub const DEFAULT_JERK: f64 = 20_000.0;

/// Largest centripetal acceleration of a circle scan as a share of `accel_mm_s2`.
pub const MAX_SCAN_ACCEL_SHARE: f64 = 0.6;
/// Largest centripetal jerk (v³/r²) of a circle scan as a share of `jerk_mm_s3`.
pub const MAX_SCAN_JERK_SHARE: f64 = 0.25;

/// Tolerance on |axis| − 1 and |normal| − 1.
pub const UNIT_TOL: f64 = 1e-6;

/// Check the parameters and every feature; the first problem is returned, naming the feature.
pub fn validate(features: &[Feature], p: &Params) -> Result<(), ScanError> {
    let deg = p.approach_angle.to_degrees();
    if !(20.0 - 1e-9..=60.0 + 1e-9).contains(&deg) || !deg.is_finite() {
        return Err(ScanError::ApproachAngle(deg));
    }
    let pos = |name: &'static str, v: f64| -> Result<(), ScanError> {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(ScanError::Parameter(name, v))
        }
    };
    pos("scan_speed_mm_s", p.scan_speed)?;
    pos("move_speed_mm_s", p.move_speed)?;
    pos("deflection_mm", p.deflection)?;
    pos("tip_radius_mm", p.tip_radius)?;
    pos("clearance_mm", p.clearance)?;
    pos("settle_mm", p.settle_length)?;
    pos("settle_s", p.settle_time)?;
    pos("accel_mm_s2", p.accel)?;
    pos("jerk_mm_s3", p.jerk)?;
    pos("touch_speed_mm_s", p.touch_speed)?;
    if !(p.overshoot.is_finite() && p.overshoot >= 0.0) {
        return Err(ScanError::Parameter("overshoot_mm", p.overshoot));
    }
    if !(p.prehit_dwell.is_finite() && p.prehit_dwell >= 0.0) {
        return Err(ScanError::Parameter("prehit_dwell_s", p.prehit_dwell));
    }
    let [b1, b2] = p.quality_bands;
    if !(b1.is_finite() && b2.is_finite() && b1 > 0.0 && b2 > b1) {
        return Err(ScanError::Bands(b1, b2));
    }
    if p.move_speed < p.scan_speed {
        return Err(ScanError::Invalid(format!(
            "move_speed_mm_s ({}) is below scan_speed_mm_s ({})",
            p.move_speed, p.scan_speed
        )));
    }
    if features.is_empty() {
        return Err(ScanError::Invalid("no [[feature]] to scan".into()));
    }
    for f in features {
        f.check(p)?;
    }
    Ok(())
}

/// Largest coordinate or radius accepted (mm): 1 km.
pub const MAX_COORD: f64 = 1.0e6;

fn finite3(v: &Vector3) -> bool {
    v.iter().all(|c| c.is_finite() && c.abs() <= MAX_COORD)
}

impl Feature {
    /// Geometric sanity of one feature.
    pub fn check(&self, p: &Params) -> Result<(), ScanError> {
        let bad = |why: String| ScanError::Feature { id: self.id.clone(), why };
        match &self.geometry {
            Geometry::Circle { center, axis, radius, side, start, sweep } => {
                if !finite3(&center.coords)
                    || !finite3(axis)
                    || !radius.is_finite()
                    || radius.abs() > MAX_COORD
                    || !start.is_finite()
                    || !sweep.is_finite()
                {
                    return Err(bad("a value is not a finite number of at most 1e6".into()));
                }
                if (axis.norm() - 1.0).abs() > UNIT_TOL {
                    return Err(bad(format!("axis has length {:.6}; it must be a unit vector", axis.norm())));
                }
                if *radius <= 0.0 {
                    return Err(bad(format!("radius_mm is {radius}; a circle needs a radius above zero")));
                }
                if sweep.abs() < 1e-9 {
                    return Err(bad("sweep_deg is zero".into()));
                }
                if sweep.abs() > 4.0 * std::f64::consts::PI {
                    return Err(bad("sweep_deg is beyond ±720°".into()));
                }
                if *side == Side::Inside && *radius <= p.tip_radius + p.deflection {
                    return Err(bad(format!(
                        "bore radius {radius} mm is not larger than the tip radius {} mm",
                        p.tip_radius
                    )));
                }
                if *side == Side::Inside && *radius <= p.tip_radius + p.clearance {
                    return Err(bad(format!(
                        "bore radius {radius} mm is not larger than tip_radius_mm + clearance_mm ({} mm): \
                         the approach would start and the release end beyond the bore's axis",
                        p.tip_radius + p.clearance
                    )));
                }
                // the scan runs at constant speed on a circle of this radius: its centripetal
                // acceleration and jerk must leave room within the limits for the bends that join
                // it (the planner's own share of the limits for constant-curvature moves)
                let r = self.metric(p.tip_radius - p.deflection);
                let (v, k) = (p.scan_speed, 1.0 / r.max(1e-9));
                let (acc, jerk) = (v * v * k, v.powi(3) * k * k);
                if acc > MAX_SCAN_ACCEL_SHARE * p.accel || jerk > MAX_SCAN_JERK_SHARE * p.jerk {
                    return Err(bad(format!(
                        "scan_speed_mm_s {v} is too fast for this circle: on its {r:.3} mm scan path \
                         the centripetal acceleration is {acc:.0} mm/s² (at most {:.0}, 60 % of \
                         accel_mm_s2) and the jerk {jerk:.0} mm/s³ (at most {:.0}, 25 % of \
                         jerk_mm_s3); lower the scan speed",
                        MAX_SCAN_ACCEL_SHARE * p.accel,
                        MAX_SCAN_JERK_SHARE * p.jerk
                    )));
                }
            }
            Geometry::Line { start, end, normal } => {
                if !finite3(&start.coords) || !finite3(&end.coords) || !finite3(normal) {
                    return Err(bad("a value is not a finite number of at most 1e6".into()));
                }
                let d = end - start;
                if d.norm() < 1e-9 {
                    return Err(bad("start_mm and end_mm coincide: a line needs a length above zero".into()));
                }
                if (normal.norm() - 1.0).abs() > UNIT_TOL {
                    return Err(bad(format!(
                        "normal has length {:.6}; it must be a unit vector",
                        normal.norm()
                    )));
                }
                if (d.normalize().dot(normal)).abs() > 1e-6 {
                    return Err(bad("normal is not perpendicular to the line".into()));
                }
            }
        }
        Ok(())
    }

    /// Orthonormal basis (u, v) of a circle's plane: u is the projection of +X (or +Y when the
    /// axis is close to X) onto the plane; v = axis × u. Angles are measured from u towards v.
    pub fn basis(axis: &Vector3) -> (Vector3, Vector3) {
        let e = if axis.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
        let u = (e - axis * axis.dot(&e)).normalize();
        (u, axis.cross(&u))
    }

    /// Length of the scan parameter range (rad for circles, mm for lines; always positive).
    pub fn extent(&self) -> f64 {
        match &self.geometry {
            Geometry::Circle { sweep, .. } => sweep.abs(),
            Geometry::Line { start, end, .. } => (end - start).norm(),
        }
    }

    /// Surface-arc length per unit of `u` at offset `h` (mm per rad for circles, 1 for lines).
    pub fn metric(&self, h: f64) -> f64 {
        match &self.geometry {
            Geometry::Circle { radius, side, .. } => match side {
                Side::Inside => radius - h,
                Side::Outside => radius + h,
                Side::Plane => *radius,
            },
            Geometry::Line { .. } => 1.0,
        }
    }

    /// Radial unit vector of a circle at parameter `u` (and the tangent in the scan direction).
    fn circle_frame(&self, u: f64) -> Option<(Vector3, Vector3)> {
        if let Geometry::Circle { axis, start, sweep, .. } = &self.geometry {
            let (bu, bv) = Self::basis(axis);
            let s = sweep.signum();
            let a = start + s * u;
            let r = bu * a.cos() + bv * a.sin();
            let t = (-bu * a.sin() + bv * a.cos()) * s;
            Some((r, t))
        } else {
            None
        }
    }

    /// Outward (free-side) unit normal of the surface at `u`.
    pub fn normal(&self, u: f64) -> Vector3 {
        match &self.geometry {
            Geometry::Circle { axis, side, .. } => {
                let (r, _) = self.circle_frame(u).unwrap_or((Vector3::x(), Vector3::y()));
                match side {
                    Side::Inside => -r,
                    Side::Outside => r,
                    Side::Plane => *axis,
                }
            }
            Geometry::Line { normal, .. } => *normal,
        }
    }

    /// Unit tangent in the scan direction at `u`.
    pub fn tangent(&self, u: f64) -> Vector3 {
        match &self.geometry {
            Geometry::Circle { .. } => self.circle_frame(u).map(|(_, t)| t).unwrap_or(Vector3::x()),
            Geometry::Line { start, end, .. } => (end - start).normalize(),
        }
    }

    /// Tip-centre position at parameter `u` and offset `h` from the surface along the outward
    /// normal (`h = tip radius − deflection` while scanning).
    pub fn point(&self, u: f64, h: f64) -> Point3 {
        match &self.geometry {
            Geometry::Circle { center, radius, axis, side, .. } => {
                let (r, _) = self.circle_frame(u).unwrap_or((Vector3::x(), Vector3::y()));
                // the normal of [`Feature::normal`], from the same frame
                let n = match side {
                    Side::Inside => -r,
                    Side::Outside => r,
                    Side::Plane => *axis,
                };
                center + r * *radius + n * h
            }
            Geometry::Line { start, end, normal } => start + (end - start).normalize() * u + normal * h,
        }
    }

    /// Signed distance from `p` to the (unbounded) surface, positive on the free side, with the
    /// outward normal at the nearest surface point.
    pub fn signed_distance(&self, p: &Point3) -> (f64, Vector3) {
        match &self.geometry {
            Geometry::Circle { center, axis, radius, side, .. } => {
                let d = p - center;
                let along = axis.dot(&d);
                match side {
                    Side::Plane => (along, *axis),
                    _ => {
                        let radial = d - axis * along;
                        let rho = radial.norm();
                        let r = if rho > 1e-12 { radial / rho } else { Self::basis(axis).0 };
                        if *side == Side::Inside {
                            (radius - rho, -r)
                        } else {
                            (rho - radius, r)
                        }
                    }
                }
            }
            Geometry::Line { start, normal, .. } => ((p - start).dot(normal), *normal),
        }
    }
}
