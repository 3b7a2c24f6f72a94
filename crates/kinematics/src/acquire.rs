//! The sphere probed at several orientations of a five-axis machine with tool-centre-point
//! control ([`acquire`]), through any [`ProbingMachine`] whose [`ProbingMachine::rotary_kinematics`]
//! is `xyzbc-trt`: the virtual one in `truepos-cell`, LinuxCNC in `truepos-linuxcnc`.
//!
//! Positions are in the programme frame (the table frame, which turns with B and C), and the
//! tool axis there is `a(B, C)` ([`tool_axis`]). At each orientation the sphere is probed as
//! `truepos probe sphere` does, with its cap and clearance moves turned to face the tool
//! ([`probe_sphere_about`] with the table's rotation).
//!
//! Orientation changes follow a path that never comes near the sphere, with `s` the nominal
//! centre and `T` the turn distance ([`KinematicsProbing::turn_distance_mm`]):
//! 1. out along the current tool axis to `s + T·a_old` (straight out of a probing position; from
//!    an unknown start: first up along the tool axis to height `T` above `s`, then across),
//! 2. along the great circle of radius `T` about `s` to `s + T·Z` (chords of ≤ 15°: they stay
//!    ≥ `T·cos 7.5°` from `s`),
//! 3. `orient(B, C)` there: with TCP the tip stays put in the table frame while the table turns;
//!    the tool, which points along `a` with `a·Z = cos B ≥ 0` for |B| ≤ 90°, never points back
//!    towards the sphere, so no part of it on its axis comes nearer than `T`,
//! 4. along the great circle to `s + T·a_new`, then the probing of the next cap.
//!
//! After the last orientation the machine goes back to B = C = 0 by the same path and stays at
//! `s + T·Z`.

use crate::trt::{programme_from_machine, tool_axis, MODULE};
use thiserror::Error;
use truepos_device::{DeviceError, ProbingMachine};
use truepos_head::acquire::{probe_sphere_about, AcquireError, AcquiredOrientation, SphereProbing};
use truepos_math::{Point3, Vector3};

/// Largest step of the great-circle moves (rad).
const ARC_STEP: f64 = 15.0 * std::f64::consts::PI / 180.0;

/// What to probe, where, and how far away to turn.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicsProbing {
    /// The sphere: `near_mm` is its nominal centre in the programme frame (the table frame at
    /// B = C = 0, where it is also the machine frame).
    pub sphere: SphereProbing,
    /// (B, C) in degrees, in probing order.
    pub orientations: Vec<[f64; 2]>,
    /// Distance from the nominal centre at which the axes turn (mm).
    pub turn_distance_mm: f64,
}

/// Why a probing plan (the orientations to visit) is not usable.
#[derive(Debug, Error)]
pub enum PlanError {
    /// The plan is invalid (why, as a sentence).
    #[error("{0}")]
    Invalid(String),
}

impl KinematicsProbing {
    /// Check the request before anything moves.
    pub fn check(&self) -> Result<(), PlanError> {
        let bad = |m: String| Err(PlanError::Invalid(m));
        if let Err(e) = self.sphere.check() {
            return bad(e.to_string());
        }
        for o in &self.orientations {
            if !(o[0].is_finite() && o[1].is_finite()) {
                return bad("orientation angles must be finite numbers (degrees)".into());
            }
            if o[0].abs() > 90.0 {
                return bad(format!(
                    "B = {}°: |B| must be at most 90° (beyond, the probed cap faces the table and the sphere's stem)",
                    o[0]
                ));
            }
        }
        let reach =
            0.5 * self.sphere.diameter_mm + self.sphere.tip_radius_mm + 2.0 * self.sphere.clearance_mm;
        let t = self.turn_distance_mm;
        if let Some(m) = truepos_device::length_beyond_limit("the turn distance (--turn-distance-mm)", t) {
            return bad(m);
        }
        if !(t.is_finite() && t >= 1.5 * reach) {
            return bad(format!(
                "the turn distance {t} mm must be at least 1.5 × (sphere radius + tip radius + 2 × clearance) = {:.3} mm",
                1.5 * reach
            ));
        }
        Ok(())
    }
}

/// Refuse a machine that is not an `xyzbc-trt` five-axis machine with TCP.
pub fn check_machine<M: ProbingMachine + ?Sized>(m: &M, model: &str) -> Result<(), DeviceError> {
    match m.rotary_kinematics() {
        Some(k) if k.model == model => Ok(()),
        Some(k) => Err(DeviceError::Rejected {
            address: m.info().address,
            what: format!("calibrating the {model} kinematics"),
            message: format!("the controller runs {} ({}), not {model} ({MODULE})", k.module, k.model),
        }),
        None => Err(DeviceError::Rejected {
            address: m.info().address,
            what: format!("calibrating the {model} kinematics"),
            message: "the controller reports no five-axis kinematics with tool-centre-point control \
                      (a 3-axis machine, or its kinematics module is not one truepos knows)"
                .into(),
        }),
    }
}

/// Where the tool is relative to the nominal centre, and the moves between those places.
struct Path {
    s: Point3,
    turn: f64,
}

impl Path {
    /// From wherever the machine is (at the given orientation) to `s + T·a`: up along the tool
    /// axis to height ≥ T, across at that height, down along the axis to T.
    fn out<M: ProbingMachine + ?Sized>(&self, m: &mut M, a: &Vector3) -> Result<(), DeviceError> {
        let p0 = m.position()?;
        let h0 = (p0 - self.s).dot(a);
        let target = self.s + a * self.turn;
        if (p0 - target).norm() < 1e-9 {
            return Ok(());
        }
        let h = h0.max(self.turn);
        let up = p0 + a * (h - h0);
        if (up - p0).norm() > 0.0 {
            m.move_to(up)?;
        }
        let across = self.s + a * h;
        if (across - up).norm() > 0.0 {
            m.move_to(across)?;
        }
        if (target - across).norm() > 0.0 {
            m.move_to(target)?;
        }
        Ok(())
    }

    /// Along the great circle of radius T from direction `from` to `to` (both unit).
    fn arc<M: ProbingMachine + ?Sized>(
        &self,
        m: &mut M,
        from: &Vector3,
        to: &Vector3,
    ) -> Result<(), DeviceError> {
        let angle = from.dot(to).clamp(-1.0, 1.0).acos();
        if angle < 1e-12 {
            return Ok(());
        }
        // A rotation axis perpendicular to both (any, for opposite directions).
        let axis = {
            let c = from.cross(to);
            if c.norm() > 1e-9 {
                c.normalize()
            } else {
                truepos_math::any_perpendicular(from)
            }
        };
        let n = (angle / ARC_STEP).ceil().max(1.0) as usize;
        for k in 1..=n {
            let rot = nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Unit::new_unchecked(axis),
                angle * k as f64 / n as f64,
            );
            let d = if k == n { *to } else { rot * from };
            m.move_to(self.s + d * self.turn)?;
        }
        Ok(())
    }

    /// From `s + T·a(b0, c0)` to `s + T·a(b, c)` through `s + T·Z`, turning the axes there.
    fn reorient<M: ProbingMachine + ?Sized>(
        &self,
        m: &mut M,
        from: (f64, f64),
        to: (f64, f64),
    ) -> Result<(), DeviceError> {
        if from == to {
            return Ok(());
        }
        let a0 = tool_axis(from.0.to_radians(), from.1.to_radians());
        let a1 = tool_axis(to.0.to_radians(), to.1.to_radians());
        self.arc(m, &a0, &Vector3::z())?;
        m.orient(to.0, to.1)?;
        self.arc(m, &Vector3::z(), &a1)
    }
}

/// Probe the sphere at every orientation (see the module docs for the path) and return the
/// fitted spheres in the programme frame. The machine must already have passed
/// [`check_machine`]; it ends at B = C = 0, `T` above the nominal centre.
pub fn acquire<M: ProbingMachine + ?Sized>(
    m: &mut M,
    plan: &KinematicsProbing,
    mut on_orientation: impl FnMut(usize, &AcquiredOrientation),
) -> Result<Vec<AcquiredOrientation>, AcquireError> {
    plan.check().map_err(|e| AcquireError::Plan(e.to_string()))?;
    let path = Path { s: plan.sphere.near_mm, turn: plan.turn_distance_mm };
    let mut at = m.orientation()?;
    path.out(m, &tool_axis(at.0.to_radians(), at.1.to_radians()))?;
    let mut out = Vec::with_capacity(plan.orientations.len());
    for (k, &[b, c]) in plan.orientations.iter().enumerate() {
        path.reorient(m, at, (b, c))?;
        at = (b, c);
        let frame = programme_from_machine(b.to_radians(), c.to_radians());
        let sphere = probe_sphere_about(m, &plan.sphere, &frame)?;
        path.out(m, &tool_axis(b.to_radians(), c.to_radians()))?;
        let o = AcquiredOrientation { b_deg: b, c_deg: c, sphere };
        on_orientation(k, &o);
        out.push(o);
    }
    path.reorient(m, at, (0.0, 0.0))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan() -> KinematicsProbing {
        KinematicsProbing {
            sphere: SphereProbing {
                near_mm: Point3::new(60.0, 25.0, 15.0),
                diameter_mm: 25.0,
                points: 9,
                feed_mm_s: 50.0 / 60.0,
                clearance_mm: 0.5,
                tip_radius_mm: 1.0,
            },
            orientations: vec![[0.0, 0.0], [45.0, 120.0]],
            turn_distance_mm: 60.0,
        }
    }

    #[test]
    fn plans_are_checked() {
        assert!(plan().check().is_ok());
        let e = KinematicsProbing { orientations: vec![[95.0, 0.0]], ..plan() }.check().unwrap_err();
        assert!(e.to_string().contains("90°"), "{e}");
        let e = KinematicsProbing { turn_distance_mm: 15.0, ..plan() }.check().unwrap_err();
        assert!(e.to_string().contains("turn distance"), "{e}");
        assert!(KinematicsProbing { orientations: vec![[f64::NAN, 0.0]], ..plan() }.check().is_err());
    }
}
