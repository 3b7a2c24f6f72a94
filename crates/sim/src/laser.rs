//! Laser distance head: a non-contact head that focuses a beam and reports the signed distance of
//! the surface from its focus point along the beam.
//!
//! Model (the contract's, `shared/spec/interface.md`, "Head offset"): the focus point is the
//! head's measuring reference point `Q`; the beam direction in the head frame at `b = 0` is
//! `u = unit(tan α, tan β, −1)` for the tilt angles `α, β`; with the head swivelled by `b` about
//! machine Y the beam runs along `w = Ry(b)·u`, and the surface point is `Q + dist·w`. A reading
//! exists only when the surface crossing lies inside the measuring range `|dist| ≤ range/2` and the
//! beam meets the surface from outside (its front side).
//!
//! Entry points: [`LaserHead`] ([`LaserHead::beam_direction`], [`LaserHead::reading_exact`],
//! [`LaserHead::reading`]), the exact ray intersections [`ray_sphere`] and [`ray_plane`], and the
//! [`Surface`] enum.

use rand::Rng;
use truepos_math::types::{ry, Point3, Vector3};

/// A surface a laser beam (or a probe) can meet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Surface {
    /// Sphere with centre and radius (mm).
    Sphere {
        /// Centre, mm.
        centre: Point3,
        /// Radius, mm.
        radius: f64,
    },
    /// Plane through `point` with outward unit `normal` (the material is on the `−normal` side).
    Plane {
        /// A point of the plane, mm.
        point: Point3,
        /// Unit outward normal.
        normal: Vector3,
    },
}

/// Why a laser head gives no reading.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LaserError {
    /// The beam line misses the surface, or meets only its back side.
    #[error("the laser beam does not meet the surface")]
    Miss,
    /// The surface crossing is outside the measuring range.
    #[error("surface at {dist_mm:.3} mm from the focus, outside the measuring range ±{half_range_mm:.3} mm")]
    OutOfRange {
        /// Distance of the crossing from the focus, mm.
        dist_mm: f64,
        /// Half the measuring range, mm.
        half_range_mm: f64,
    },
}

/// Signed parameter `t` of the point where the line `origin + t·dir` (unit `dir`) enters the
/// sphere (the smaller root: the beam arrives from `t = −∞`), or `None` if the line misses it.
/// Exact (closed form, with the cancellation-free quadratic root).
pub fn ray_sphere(origin: &Point3, dir: &Vector3, centre: &Point3, radius: f64) -> Option<f64> {
    let oc = origin - centre;
    let half_b = oc.dot(dir);
    let c = oc.norm_squared() - radius * radius;
    let disc = half_b * half_b - c;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    // Roots -half_b ± sq; compute the far one without cancellation and the near one from the
    // product c = t1·t2 when that is stable.
    let q = -half_b - sq.copysign(half_b);
    if q == 0.0 {
        return Some(0.0);
    }
    let (r1, r2) = (q, c / q);
    Some(r1.min(r2))
}

/// Signed parameter `t` where the line `origin + t·dir` meets the plane's front side (the beam
/// travels against the outward normal), or `None` if the beam is parallel or hits the back side.
pub fn ray_plane(origin: &Point3, dir: &Vector3, point: &Point3, normal: &Vector3) -> Option<f64> {
    let den = dir.dot(normal);
    if den.is_nan() || den >= -1e-12 {
        return None;
    }
    Some((point - origin).dot(normal) / den)
}

/// Distance along the beam line to `surface` (see [`ray_sphere`], [`ray_plane`]).
pub fn ray_surface(origin: &Point3, dir: &Vector3, surface: &Surface) -> Option<f64> {
    match surface {
        Surface::Sphere { centre, radius } => ray_sphere(origin, dir, centre, *radius),
        Surface::Plane { point, normal } => ray_plane(origin, dir, point, normal),
    }
}

/// A laser distance head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserHead {
    /// Beam tilt angles `α` (in the XZ plane) and `β` (in the YZ plane), rad.
    pub tilt: [f64; 2],
    /// Full measuring range (mm), symmetric about the focus: readings exist for `|dist| ≤ range/2`.
    pub range: f64,
    /// Distance noise, standard deviation (mm).
    pub noise: f64,
}

impl Default for LaserHead {
    /// Untilted beam, 10 mm range, 0.5 µm noise.
    fn default() -> Self {
        LaserHead { tilt: [0.0, 0.0], range: 10.0, noise: 0.5e-3 }
    }
}

impl LaserHead {
    /// Beam direction in the head frame at `b = 0`: `unit(tan α, tan β, −1)`.
    pub fn beam_direction_head(&self) -> Vector3 {
        Vector3::new(self.tilt[0].tan(), self.tilt[1].tan(), -1.0).normalize()
    }

    /// Beam direction in machine coordinates with the head swivelled by `b` (rad) about Y.
    pub fn beam_direction(&self, b: f64) -> Vector3 {
        ry(b) * self.beam_direction_head()
    }

    /// Exact (noise-free) reading of the head with focus `focus` and swivel `b` on `surface`.
    pub fn reading_exact(&self, focus: &Point3, b: f64, surface: &Surface) -> Result<f64, LaserError> {
        let w = self.beam_direction(b);
        let t = ray_surface(focus, &w, surface).ok_or(LaserError::Miss)?;
        let half = 0.5 * self.range;
        if t.abs() > half {
            return Err(LaserError::OutOfRange { dist_mm: t, half_range_mm: half });
        }
        Ok(t)
    }

    /// Reading with Gaussian distance noise of standard deviation [`LaserHead::noise`].
    pub fn reading<R: Rng + ?Sized>(
        &self,
        focus: &Point3,
        b: f64,
        surface: &Surface,
        rng: &mut R,
    ) -> Result<f64, LaserError> {
        let t = self.reading_exact(focus, b, surface)?;
        Ok(t + crate::noise::gaussian(rng, self.noise))
    }

    /// The surface point the contract model assigns to a reading: `focus + dist·Ry(b)·u`.
    pub fn surface_point(&self, focus: &Point3, b: f64, dist: f64) -> Point3 {
        focus + dist * self.beam_direction(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_entering_root_is_the_near_side() {
        // Beam along −Z from (0,0,100) onto a unit sphere at the origin: enters at z = 1, t = 99.
        let t = ray_sphere(&Point3::new(0.0, 0.0, 100.0), &-Vector3::z(), &Point3::origin(), 1.0);
        assert!((t.unwrap() - 99.0).abs() < 1e-12);
        // Off-axis by 0.6: enters at z = 0.8.
        let t = ray_sphere(&Point3::new(0.6, 0.0, 5.0), &-Vector3::z(), &Point3::origin(), 1.0);
        assert!((t.unwrap() - 4.2).abs() < 1e-12);
        // Miss.
        assert!(ray_sphere(&Point3::new(1.5, 0.0, 5.0), &-Vector3::z(), &Point3::origin(), 1.0).is_none());
    }

    #[test]
    fn plane_front_side_only() {
        let n = Vector3::z();
        let t = ray_plane(&Point3::new(3.0, 4.0, 2.0), &-Vector3::z(), &Point3::origin(), &n);
        assert_eq!(t, Some(2.0));
        assert!(ray_plane(&Point3::new(3.0, 4.0, 2.0), &Vector3::z(), &Point3::origin(), &n).is_none());
    }

    #[test]
    fn range_and_tilt() {
        let head = LaserHead { tilt: [0.1, -0.05], range: 4.0, noise: 0.0 };
        let u = head.beam_direction_head();
        assert!((u.x / -u.z - 0.1f64.tan()).abs() < 1e-15);
        assert!((u.y / -u.z + 0.05f64.tan()).abs() < 1e-15);
        let plane = Surface::Plane { point: Point3::origin(), normal: Vector3::z() };
        let d = head.reading_exact(&Point3::new(0.0, 0.0, 1.5), 0.0, &plane).unwrap();
        // Vertical drop 1.5 along a beam with direction cosine −u.z.
        assert!((d - 1.5 / -u.z).abs() < 1e-12);
        let p = head.surface_point(&Point3::new(0.0, 0.0, 1.5), 0.0, d);
        assert!(p.z.abs() < 1e-12);
        assert!(matches!(
            head.reading_exact(&Point3::new(0.0, 0.0, 2.5), 0.0, &plane),
            Err(LaserError::OutOfRange { .. })
        ));
    }
}
