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
//! Angles in rad, lengths in mm.

use truepos_math::types::{ry, rz, Point3, Vector3};

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

    /// A direction fixed to the table, at table angle `c`.
    pub fn rotate_vector(&self, v: &Vector3, c: f64) -> Vector3 {
        rz(c) * v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
