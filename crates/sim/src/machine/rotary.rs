//! The rotary axes of the vertical machining centre, exactly as the contract models them
//! (`shared/spec/interface.md`, "Head offset").
//!
//! - B-axis swivel head about machine Y: the head's measuring reference point is
//!   `Q = P + Ry(b)·R`, with `P` the head's reference point whose coordinates the NC reports and
//!   `R` the head offset in the head frame at `b = 0` ([`head_point`], [`head_reference`]).
//! - C-axis rotary table about the line through the table centre `O` parallel to Z: a point fixed
//!   to the table at `c = 0` position `A` is at `O + Rz(c)·(A − O)` at table angle `c`
//!   ([`RotaryTable::to_machine`]; [`RotaryTable::to_table`] undoes it).
//!
//! Optional location errors of the two rotary axes (ISO 230-7 style, [`RotaryAxisErrors`]):
//! the real B axis does not pass through `P` or is not parallel to Y, the real C axis is offset
//! from the nominal table centre or tilted. With zero errors [`head_point_with`] and
//! [`RotaryTable::to_machine_with`] are exactly the contract model.
//!
//! Angles in rad, lengths in mm.

use truepos_math::types::{rx, ry, rz, Point3, Vector3};

/// Location errors of the B (head) and C (table) axes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RotaryAxisErrors {
    /// The real B axis passes through `P + b_offset` (mm; the y component has no effect).
    pub b_offset: Vector3,
    /// Tilt of the real B axis from +Y: small rotations about X and about Z (rad).
    pub b_tilt: [f64; 2],
    /// The real C axis passes through `table centre + c_offset` (mm; z has no effect).
    pub c_offset: Vector3,
    /// Tilt of the real C axis from +Z: small rotations about X and about Y (rad).
    pub c_tilt: [f64; 2],
}

impl RotaryAxisErrors {
    /// Real B axis direction.
    pub fn b_axis(&self) -> Vector3 {
        rz(self.b_tilt[1]) * rx(self.b_tilt[0]) * Vector3::y()
    }

    /// Real C axis direction.
    pub fn c_axis(&self) -> Vector3 {
        ry(self.c_tilt[1]) * rx(self.c_tilt[0]) * Vector3::z()
    }
}

fn rotation_about(axis: &Vector3, angle: f64) -> truepos_math::types::Matrix3 {
    nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(*axis), angle).into_inner()
}

/// [`head_point`] with B-axis location errors: the offset turns about the real B axis through
/// `P + b_offset`: `Q = P + e + Rot(k_B, b)·(R − e)`.
pub fn head_point_with(p: &Point3, b: f64, offset: &Vector3, e: &RotaryAxisErrors) -> Point3 {
    p + e.b_offset + rotation_about(&e.b_axis(), b) * (offset - e.b_offset)
}

/// Inverse of [`head_point_with`]: `P = Q − e − Rot(k_B, b)·(R − e)`.
pub fn head_reference_with(q: &Point3, b: f64, offset: &Vector3, e: &RotaryAxisErrors) -> Point3 {
    q - e.b_offset - rotation_about(&e.b_axis(), b) * (offset - e.b_offset)
}

/// The measuring reference point `Q = P + Ry(b)·R` of a head with offset `offset` (= R) swivelled
/// by `b` when the NC reports `p`.
pub fn head_point(p: &Point3, b: f64, offset: &Vector3) -> Point3 {
    p + ry(b) * offset
}

/// Inverse of [`head_point`]: the NC-reported head reference point `P = Q − Ry(b)·R`.
pub fn head_reference(q: &Point3, b: f64, offset: &Vector3) -> Point3 {
    q - ry(b) * offset
}

/// A C-axis rotary table turning about the line through `centre` parallel to Z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotaryTable {
    /// A point of the rotation axis (mm, machine coordinates).
    pub centre: Point3,
}

impl RotaryTable {
    /// Where the table point that is at `a` for `c = 0` is at table angle `c`:
    /// `O + Rz(c)·(A − O)`.
    pub fn to_machine(&self, a: &Point3, c: f64) -> Point3 {
        self.centre + rz(c) * (a - self.centre)
    }

    /// Undo the table rotation: the `c = 0` position of the table point that is at `x` at angle
    /// `c`: `O + Rz(−c)·(X − O)`.
    pub fn to_table(&self, x: &Point3, c: f64) -> Point3 {
        self.centre + rz(-c) * (x - self.centre)
    }

    /// [`RotaryTable::to_machine`] with C-axis location errors: rotation about the real axis
    /// through `centre + c_offset`.
    pub fn to_machine_with(&self, a: &Point3, c: f64, e: &RotaryAxisErrors) -> Point3 {
        let o = self.centre + e.c_offset;
        o + rotation_about(&e.c_axis(), c) * (a - o)
    }

    /// A direction fixed to the table at table angle `c`, with C-axis location errors.
    pub fn rotate_vector_with(&self, v: &Vector3, c: f64, e: &RotaryAxisErrors) -> Vector3 {
        rotation_about(&e.c_axis(), c) * v
    }

    /// A direction fixed to the table, at table angle `c`.
    pub fn rotate_vector(&self, v: &Vector3, c: f64) -> Vector3 {
        rz(c) * v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotary_location_errors_by_hand() {
        let zero = RotaryAxisErrors::default();
        let p = Point3::new(10.0, 20.0, 30.0);
        let r = Vector3::new(5.0, -3.0, -100.0);
        assert!((head_point_with(&p, 0.8, &r, &zero) - head_point(&p, 0.8, &r)).norm() < 1e-12);
        let t = RotaryTable { centre: Point3::new(100.0, 50.0, 0.0) };
        let a = Point3::new(160.0, 70.0, 40.0);
        assert!((t.to_machine_with(&a, 1.3, &zero) - t.to_machine(&a, 1.3)).norm() < 1e-12);
        // C axis offset by e = (0.01, 0, 0): at c = 180° the point is 2e away from the contract's.
        let e = RotaryAxisErrors { c_offset: Vector3::new(0.01, 0.0, 0.0), ..zero };
        let d = t.to_machine_with(&a, std::f64::consts::PI, &e) - t.to_machine(&a, std::f64::consts::PI);
        assert!((d - Vector3::new(0.02, 0.0, 0.0)).norm() < 1e-12);
        // B pivot 0.1 mm below P along Z: at b = 90° the head point moves by e − Ry(90°)·e =
        // (0,0,−0.1) − (−0.1,0,0) = (0.1, 0, −0.1).
        let e = RotaryAxisErrors { b_offset: Vector3::new(0.0, 0.0, -0.1), ..zero };
        let h = std::f64::consts::FRAC_PI_2;
        let d = head_point_with(&p, h, &r, &e) - head_point(&p, h, &r);
        assert!((d - Vector3::new(0.1, 0.0, -0.1)).norm() < 1e-12);
        let q = head_point_with(&p, h, &r, &e);
        assert!((head_reference_with(&q, h, &r, &e) - p).norm() < 1e-12);
    }

    #[test]
    fn head_and_table_round_trip_and_hand_values() {
        // b = 90°: Ry maps +Z to +X, so R = (0,0,−100) puts Q 100 mm along −X from P.
        let q = head_point(
            &Point3::new(10.0, 20.0, 30.0),
            std::f64::consts::FRAC_PI_2,
            &Vector3::new(0.0, 0.0, -100.0),
        );
        assert!((q - Point3::new(-90.0, 20.0, 30.0)).norm() < 1e-12);
        let p = head_reference(&q, std::f64::consts::FRAC_PI_2, &Vector3::new(0.0, 0.0, -100.0));
        assert!((p - Point3::new(10.0, 20.0, 30.0)).norm() < 1e-12);
        // Table centre (100, 0, 0); point (150, 0, 5) turned by 90° goes to (100, 50, 5).
        let t = RotaryTable { centre: Point3::new(100.0, 0.0, 7.0) };
        let x = t.to_machine(&Point3::new(150.0, 0.0, 5.0), std::f64::consts::FRAC_PI_2);
        assert!((x - Point3::new(100.0, 50.0, 5.0)).norm() < 1e-12);
        assert!((t.to_table(&x, std::f64::consts::FRAC_PI_2) - Point3::new(150.0, 0.0, 5.0)).norm() < 1e-12);
    }
}
