//! Math aliases used across truepos (in the manner of parry's `math` module).
//!
//! Positions are [`Point3`]; displacements, directions and normals are [`Vector3`]. A point minus
//! a point is a vector; a point plus a vector is a point. Units are mm, rad, s.

/// The scalar type of all computations (double precision).
pub type Real = f64;
/// A position in 3D space, mm unless stated otherwise.
pub type Point3 = nalgebra::Point3<f64>;
/// A position in a plane, mm unless stated otherwise.
pub type Point2 = nalgebra::Point2<f64>;
/// A displacement or direction in 3D space (not translated by transforms).
pub type Vector3 = nalgebra::Vector3<f64>;
/// A displacement or direction in a plane.
pub type Vector2 = nalgebra::Vector2<f64>;
/// A 3×3 matrix (rotations, covariances, inertia tensors).
pub type Matrix3 = nalgebra::Matrix3<f64>;
/// A 3D vector of unit length (a direction or surface normal).
pub type UnitVector3 = nalgebra::Unit<nalgebra::Vector3<f64>>;
/// A proper rotation in 3D space.
pub type Rotation3 = nalgebra::Rotation3<f64>;
/// A dynamically sized matrix (Jacobians, normal matrices, covariances).
pub type DMatrix = nalgebra::DMatrix<f64>;
/// A dynamically sized column vector (parameters, residuals).
pub type DVector = nalgebra::DVector<f64>;

/// Rotation about +X by `a` (rad), right-hand rule.
pub fn rx(a: f64) -> Matrix3 {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

/// Rotation about +Y by `b` (rad), right-hand rule.
pub fn ry(b: f64) -> Matrix3 {
    let (s, c) = b.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

/// Rotation about +Z by `c` (rad), right-hand rule.
pub fn rz(c: f64) -> Matrix3 {
    let (s, co) = c.sin_cos();
    Matrix3::new(co, -s, 0.0, s, co, 0.0, 0.0, 0.0, 1.0)
}

/// Centroid of a non-empty slice of points (returns the origin for an empty slice).
pub fn centroid(points: &[Point3]) -> Point3 {
    if points.is_empty() {
        return Point3::origin();
    }
    // Two-level summation keeps the rounding error small for millions of points.
    let mut sum = Vector3::zeros();
    for chunk in points.chunks(4096) {
        let mut s = Vector3::zeros();
        for p in chunk {
            s += p.coords;
        }
        sum += s;
    }
    Point3::from(sum / points.len() as f64)
}

/// Any unit vector perpendicular to `n` (which must be non-zero).
pub fn any_perpendicular(n: &Vector3) -> Vector3 {
    let a = if n.x.abs() <= n.y.abs() && n.x.abs() <= n.z.abs() {
        Vector3::x()
    } else if n.y.abs() <= n.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    n.cross(&a).normalize()
}

/// A linear machine axis (the one definition; `truepos-sim` and `truepos-comp` re-export it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// The X axis (index 0).
    X = 0,
    /// The Y axis (index 1).
    Y = 1,
    /// The Z axis (index 2).
    Z = 2,
}

impl Axis {
    /// X, Y, Z.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// 0, 1, 2.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Lower-case name as in the map file's `axis` column.
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self.index()]
    }

    /// Machine-axis index of the angular components `[pitch, yaw, roll]` of this axis.
    pub fn angular_axes(self) -> [usize; 3] {
        match self {
            Axis::X => [1, 2, 0],
            Axis::Y => [0, 2, 1],
            Axis::Z => [0, 1, 2],
        }
    }

    /// Machine-axis index of the linear components `[pos, str1, str2]` of this axis.
    pub fn linear_axes(self) -> [usize; 3] {
        let a = self.index();
        [a, (a + 1) % 3, (a + 2) % 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_follow_right_hand_rule() {
        // +90° about Z takes +X to +Y; about X takes +Y to +Z; about Y takes +Z to +X.
        let q = std::f64::consts::FRAC_PI_2;
        assert!((rz(q) * Vector3::x() - Vector3::y()).norm() < 1e-15);
        assert!((rx(q) * Vector3::y() - Vector3::z()).norm() < 1e-15);
        assert!((ry(q) * Vector3::z() - Vector3::x()).norm() < 1e-15);
    }

    #[test]
    fn perpendicular_is_unit_and_orthogonal() {
        for n in [Vector3::x(), Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.0, 0.0, -5.0)] {
            let p = any_perpendicular(&n);
            assert!((p.norm() - 1.0).abs() < 1e-15);
            assert!(p.dot(&n).abs() < 1e-12);
        }
    }
}
