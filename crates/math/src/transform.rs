//! Similarity transforms between coordinate frames.
//!
//! A transform mapping coordinates in frame B to frame A is named `a_from_b` and applies as
//! `p_a = s · R · p_b + t`. Composition reads left to right like the names:
//! `a_from_c = a_from_b * b_from_c`.

use crate::types::{Matrix3, Point3, Vector3};
use std::ops::Mul;

/// `p_a = scale · rotation · p_b + translation`, with `rotation` a proper rotation matrix and
/// `scale > 0`. Rigid transforms have `scale == 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform3 {
    /// Uniform scale factor `s` (1 for a rigid transform), dimensionless.
    pub scale: f64,
    /// Rotation matrix `R` from frame B axes to frame A axes.
    pub rotation: Matrix3,
    /// Translation `t`: the origin of frame B expressed in frame A, mm.
    pub translation: Vector3,
}

impl Default for Transform3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Transform3 {
    /// The transform that maps every point to itself.
    pub fn identity() -> Self {
        Self { scale: 1.0, rotation: Matrix3::identity(), translation: Vector3::zeros() }
    }

    /// A rigid transform (scale 1) from a rotation matrix and a translation in mm.
    pub fn rigid(rotation: Matrix3, translation: Vector3) -> Self {
        Self { scale: 1.0, rotation, translation }
    }

    /// A similarity transform from its scale, rotation matrix and translation in mm.
    pub fn new(scale: f64, rotation: Matrix3, translation: Vector3) -> Self {
        Self { scale, rotation, translation }
    }

    /// Apply to a point (rotation, scale and translation).
    #[inline]
    pub fn apply(&self, p: &Point3) -> Point3 {
        Point3::from(self.scale * (self.rotation * p.coords) + self.translation)
    }

    /// Apply to a displacement (rotation and scale, no translation).
    #[inline]
    pub fn apply_vector(&self, v: &Vector3) -> Vector3 {
        self.scale * (self.rotation * v)
    }

    /// The inverse transform: if `self` is `a_from_b`, the result is `b_from_a`.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        let inv_s = 1.0 / self.scale;
        Self { scale: inv_s, rotation: rt, translation: -(inv_s * (rt * self.translation)) }
    }

    /// Rotation angle (rad) of the rotation part, in [0, π].
    pub fn rotation_angle(&self) -> f64 {
        ((self.rotation.trace() - 1.0) * 0.5).clamp(-1.0, 1.0).acos()
    }
}

impl Mul for Transform3 {
    type Output = Transform3;
    /// `a_from_b * b_from_c = a_from_c`.
    fn mul(self, rhs: Transform3) -> Transform3 {
        Transform3 {
            scale: self.scale * rhs.scale,
            rotation: self.rotation * rhs.rotation,
            translation: self.scale * (self.rotation * rhs.translation) + self.translation,
        }
    }
}

impl Mul<Point3> for Transform3 {
    type Output = Point3;
    fn mul(self, p: Point3) -> Point3 {
        self.apply(&p)
    }
}

impl Mul<&Point3> for &Transform3 {
    type Output = Point3;
    fn mul(self, p: &Point3) -> Point3 {
        self.apply(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{rx, ry, rz};
    use proptest::prelude::*;

    fn arb_transform() -> impl Strategy<Value = Transform3> {
        (-3.2f64..3.2, -1.5f64..1.5, -3.2f64..3.2, 0.5f64..2.0, prop::array::uniform3(-1000.0f64..1000.0))
            .prop_map(|(a, b, c, s, t)| {
                Transform3::new(s, rz(c) * ry(b) * rx(a), Vector3::new(t[0], t[1], t[2]))
            })
    }

    proptest! {
        #[test]
        fn compose_then_apply_equals_apply_twice(
            a_from_b in arb_transform(), b_from_c in arb_transform(),
            p in prop::array::uniform3(-1000.0f64..1000.0),
        ) {
            let p_c = Point3::new(p[0], p[1], p[2]);
            let a_from_c = a_from_b * b_from_c;
            let direct = a_from_c.apply(&p_c);
            let twice = a_from_b.apply(&b_from_c.apply(&p_c));
            prop_assert!((direct - twice).norm() < 1e-9);
        }

        #[test]
        fn inverse_round_trips(a_from_b in arb_transform(), p in prop::array::uniform3(-1000.0f64..1000.0)) {
            let p_b = Point3::new(p[0], p[1], p[2]);
            let b_from_a = a_from_b.inverse();
            prop_assert!((b_from_a.apply(&a_from_b.apply(&p_b)) - p_b).norm() < 1e-9);
            let id = a_from_b * b_from_a;
            prop_assert!((id.rotation - Matrix3::identity()).norm() < 1e-12);
            prop_assert!(id.translation.norm() < 1e-9);
            prop_assert!((id.scale - 1.0).abs() < 1e-14);
        }

        #[test]
        fn composition_is_associative(x in arb_transform(), y in arb_transform(), z in arb_transform()) {
            let l = (x * y) * z;
            let r = x * (y * z);
            prop_assert!((l.rotation - r.rotation).norm() < 1e-12);
            prop_assert!((l.translation - r.translation).norm() < 1e-8);
            prop_assert!((l.scale - r.scale).abs() < 1e-12);
        }
    }
}
