//! # truepos-fit
//!
//! Least-squares (Gaussian, orthogonal-distance) geometric elements as ISO 10360-6 and ASME
//! B89.4.10 define them, with the standard uncertainties of their parameters from the fit
//! covariance `σ₀²(JᵀJ)⁻¹`, `σ₀² = SSR/(n − p)`.
//!
//! Entry points: [`line()`], [`plane`], [`circle`] (3D reference definition: least-squares plane,
//! then the least-squares 2D circle of the points projected into it), [`sphere`],
//! [`sphere_with_radius`], [`cylinder`], [`cone`]. Each returns its `XxxFit` or a [`FitError`]
//! naming why the data cannot determine the element (too few points, coincident, collinear,
//! coplanar, a cone that is a cylinder, a cylinder on flat data, non-finite values).
//!
//! Method: line and plane are closed-form (principal axes of the scatter matrix, fixed 3×3
//! symmetric eigen-decomposition). The others start from values that need no luck (algebraic
//! Kåsa sphere/circle fits; for cylinder and cone an algebraic fit along every principal axis and
//! a coarse grid of directions over the hemisphere, best kept) and refine them by
//! Levenberg-Marquardt (the private `engine` module) in a local frame re-expressed at every iteration (the
//! current axis is z), which keeps the normal equations well conditioned. One iteration is one
//! parallel, allocation-free pass over the points.

#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]
// Negated comparisons are deliberate: `!(x > t)` also rejects NaN. Index loops over small
// fixed-size matrices read better than iterator chains.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

mod axial;
mod engine;
pub mod evaluate;
pub mod json;
mod lp;
pub mod minzone;
pub mod moments;
pub mod verdict;

pub use axial::{cone, cylinder, ConeFit, CylinderFit, MIN_CONE_POINTS, MIN_CYLINDER_POINTS};

use engine::{covariance, minimise, Model, BLOCK};
use moments::Moments;
use nalgebra::{SVector, Vector2};
use thiserror::Error;
use truepos_math::{Matrix3, Point3, Vector3};

/// Why a fit cannot be computed from the given points.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FitError {
    /// Fewer points than the kind needs (kind, needed, given).
    #[error("a {kind} fit needs at least {needed} points, {got} given ({why})", why = min_points_reason(kind))]
    TooFewPoints {
        /// The element kind.
        kind: &'static str,
        /// Points the kind needs.
        needed: usize,
        /// Points given.
        got: usize,
    },
    /// Several elements fit the points equally well (distinct local minima of the least
    /// squares): the answer is not determined.
    #[error("the {kind} is not determined: {detail}")]
    NotUnique {
        /// The element kind.
        kind: &'static str,
        /// The competing solutions, as a sentence.
        detail: String,
    },
    /// A point has a NaN or infinite coordinate (its 0-based index).
    #[error("point {index} (0-based) has a coordinate that is not a finite number")]
    NonFinite {
        /// 0-based index of the point.
        index: usize,
    },
    /// A coordinate beyond [`moments::MAX_COORDINATE_MM`] (the fit's sums would overflow, or
    /// lose every digit, long before the points coincide).
    #[error(
        "point {index} (0-based) has a coordinate of magnitude {magnitude:e} mm, beyond the coordinate magnitude limit of 1e12 mm (a million km): no measured coordinate is that large (a unit or format error?), and the fit's sums of squares overflow there"
    )]
    CoordinateTooLarge {
        /// 0-based index of the point.
        index: usize,
        /// The largest coordinate magnitude of that point (mm).
        magnitude: f64,
    },
    /// Every point is at the same place.
    #[error("all points coincide: no element is determined")]
    CoincidentPoints,
    /// The points lie on one line, which does not determine the kind.
    #[error("the points are collinear: a {kind} is not determined")]
    CollinearPoints {
        /// The element kind.
        kind: &'static str,
    },
    /// The points lie in one plane, which does not determine the kind.
    #[error("the points are coplanar: a {kind} is not determined")]
    CoplanarPoints {
        /// The element kind.
        kind: &'static str,
    },
    /// The cone's apex angle is not significantly different from zero.
    #[error("the cone is a cylinder: its apex angle is not significantly different from 0 (apex at infinity); fit a cylinder")]
    ConeIsCylinder,
    /// The cylinder's curvature is not significantly different from zero.
    #[error("the data is flat (a plane or a line), not a cylinder: its curvature is not significantly different from 0")]
    CylinderIsFlat,
    /// A fixed radius that is not finite and positive (the value, mm).
    #[error("invalid fixed radius {0} mm (must be finite and positive)")]
    InvalidRadius(f64),
    /// The normal equations are singular: the data does not determine the element.
    #[error("the data does not determine the {kind}: the normal equations are singular")]
    Undetermined {
        /// The element kind.
        kind: &'static str,
    },
    /// The points do not surround a maximum inscribed element (an open arc or cap).
    #[error("no bounded maximum inscribed {kind}: the points do not surround it (an open arc or cap)")]
    InscribedUnbounded {
        /// The element kind.
        kind: &'static str,
    },
}

/// Why a fit of `kind` needs its minimum number of points (the message of
/// [`FitError::TooFewPoints`]).
pub fn min_points_reason(kind: &str) -> &'static str {
    match kind {
        "line" => "two distinct points determine a line",
        "plane" => "three points not on a line determine a plane",
        "circle" => "three points not on a line determine a circle",
        "sphere" => "four points not in a plane determine a sphere",
        "cylinder" => "a cylinder has 5 parameters and up to six cylinders pass through 5 points: a sixth decides between them",
        "cone" => "a cone has 6 parameters and several cones pass through 6 points: a seventh decides between them",
        _ => "fewer points do not determine it",
    }
}

/// Iteration cap for Levenberg-Marquardt (convergence takes 3–15 iterations on real data).
const MAX_ITERATIONS: usize = 200;
/// Reciprocal condition of the column-scaled normal matrix below which parameters are not
/// determined (double precision leaves ~1e-16; a factor 1e4 margin for the accumulation).
const RCOND: f64 = 1e-12;

/// Root-sum-square standard uncertainty of a tilt described by two orthogonal angles (rad).
fn rss(a: f64, b: f64) -> f64 {
    (a.max(0.0) + b.max(0.0)).sqrt()
}

fn sqrt_diag(m: &Matrix3) -> Vector3 {
    Vector3::new(m[(0, 0)].max(0.0).sqrt(), m[(1, 1)].max(0.0).sqrt(), m[(2, 2)].max(0.0).sqrt())
}

// ---------------------------------------------------------------------------------------------
// Line

/// Least-squares 3D line.
#[derive(Clone, Debug, PartialEq)]
pub struct LineFit {
    /// The point on the line nearest the centroid (the centroid itself).
    pub point: Point3,
    /// Unit direction (sign: largest component positive).
    pub direction: Vector3,
    /// RMS orthogonal distance, mm.
    pub rms: f64,
    /// Largest absolute orthogonal distance from the line, mm.
    pub max_abs_residual: f64,
    /// Number of points fitted.
    pub n_points: usize,
    /// Standard uncertainty of `point` perpendicular to the line (root-sum-square of the two
    /// perpendicular components), mm.
    pub u_point: f64,
    /// Standard uncertainty of the direction (root-sum-square of two tilt angles), rad.
    pub u_direction: f64,
    /// Covariance of `point` (perpendicular to the line), mm².
    pub point_covariance: Matrix3,
    /// Covariance of the unit `direction` vector's components (perpendicular to it).
    pub direction_covariance: Matrix3,
    /// Diameter of the cylindrical zone about the line that holds every point (2 × the largest
    /// distance), mm.
    pub form: f64,
}

/// Make the largest-magnitude component of a direction positive (a stable sign convention).
fn canonical(v: Vector3) -> Vector3 {
    if v[v.iamax()] < 0.0 {
        -v
    } else {
        v
    }
}

/// Least-squares line (orthogonal distance).
pub fn line(points: &[Point3]) -> Result<LineFit, FitError> {
    let m = Moments::for_fit(points, "line", 2, 0)?;
    let dir = canonical(m.axis(2));
    let n = points.len();
    let (ssr, max_abs) = ssr_max(points, |p| {
        let v = p - m.centroid;
        (v - dir * v.dot(&dir)).norm()
    });
    // Two residual components per point, four parameters (two offsets, two tilts).
    // σ̂² = SSR/(n − p) with n the number of residual components (2 per point).
    let dof = (2 * n) as f64 - 4.0;
    let s2 = if dof > 0.0 { ssr / dof } else { 0.0 };
    // Both perpendicular offsets have variance σ̂²/n, both tilts σ̂²/Σt² (t along the line).
    let perp = Matrix3::identity() - dir * dir.transpose();
    Ok(LineFit {
        point: m.centroid,
        direction: dir,
        rms: (ssr / n as f64).sqrt(),
        max_abs_residual: max_abs,
        n_points: n,
        u_point: (2.0 * s2 / n as f64).sqrt(),
        u_direction: (2.0 * s2 / m.eigenvalues[2]).sqrt(),
        point_covariance: perp * (s2 / n as f64),
        direction_covariance: perp * (s2 / m.eigenvalues[2]),
        form: 2.0 * max_abs,
    })
}

/// Sum of squares and largest absolute value of `f` over the points (one parallel pass). The
/// sum of squares is computed from the residuals, not from eigenvalues: an eigenvalue near zero
/// carries an absolute error of ~1e-16 of the largest one, which would put a floor of
/// ~1e-8·extent under the RMS of nearly exact data.
pub(crate) fn ssr_max(points: &[Point3], f: impl Fn(&Point3) -> f64 + Sync) -> (f64, f64) {
    use rayon::prelude::*;
    let fold = |(s, m): (f64, f64), p: &Point3| {
        let r = f(p);
        (s + r * r, m.max(r.abs()))
    };
    if points.len() > 32 * 1024 {
        // Fixed chunks summed in chunk order: the same digits on every run (rayon's adaptive
        // fold would add in an order that depends on thread timing).
        let parts: Vec<(f64, f64)> =
            points.par_chunks(16 * 1024).map(|c| c.iter().fold((0.0, 0.0), fold)).collect();
        parts.into_iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1.max(b.1)))
    } else {
        points.iter().fold((0.0, 0.0), fold)
    }
}

/// Smallest and largest value of `f` over the points (one parallel pass).
pub(crate) fn extremes(points: &[Point3], f: impl Fn(&Point3) -> f64 + Sync) -> (f64, f64) {
    use rayon::prelude::*;
    let fold = |(lo, hi): (f64, f64), p: &Point3| {
        let r = f(p);
        (lo.min(r), hi.max(r))
    };
    let id = (f64::INFINITY, f64::NEG_INFINITY);
    if points.len() > 32 * 1024 {
        points.par_iter().fold(|| id, fold).reduce(|| id, |a, b| (a.0.min(b.0), a.1.max(b.1)))
    } else {
        points.iter().fold(id, fold)
    }
}

// ---------------------------------------------------------------------------------------------
// Plane

/// Least-squares plane.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneFit {
    /// The centroid (which lies on the least-squares plane).
    pub point: Point3,
    /// Unit normal (sign: largest component positive).
    pub normal: Vector3,
    /// RMS orthogonal distance from the plane, mm.
    pub rms: f64,
    /// Largest absolute orthogonal distance from the plane, mm.
    pub max_abs_residual: f64,
    /// Number of points fitted.
    pub n_points: usize,
    /// Standard uncertainty of the plane's position along its normal at `point`, mm.
    pub u_offset: f64,
    /// Standard uncertainty of the normal (root-sum-square of two tilt angles), rad.
    pub u_normal: f64,
    /// Covariance of `point` (along the normal: the plane's offset), mm².
    pub point_covariance: Matrix3,
    /// Covariance of the unit normal's components.
    pub normal_covariance: Matrix3,
    /// Flatness about this plane: largest minus smallest signed distance, mm.
    pub form: f64,
}

impl PlaneFit {
    /// Signed distance of `p` from the plane (positive on the side the normal points to).
    pub fn distance(&self, p: &Point3) -> f64 {
        (p - self.point).dot(&self.normal)
    }
}

fn plane_from_moments(points: &[Point3], m: &Moments) -> PlaneFit {
    let normal = canonical(m.axis(0));
    let n = points.len();
    let c = m.centroid;
    let (ssr, max_abs) = ssr_max(points, |p| (p - c).dot(&normal));
    let (lo, hi) = extremes(points, |p| (p - c).dot(&normal));
    let dof = n as f64 - 3.0;
    let s2 = if dof > 0.0 { ssr / dof } else { 0.0 };
    let (e1, e2) = (m.axis(1), m.axis(2));
    PlaneFit {
        point_covariance: normal * normal.transpose() * (s2 / n as f64),
        normal_covariance: e1 * e1.transpose() * (s2 / m.eigenvalues[1])
            + e2 * e2.transpose() * (s2 / m.eigenvalues[2]),
        form: hi - lo,
        point: c,
        normal,
        rms: (ssr / n as f64).sqrt(),
        max_abs_residual: max_abs,
        n_points: n,
        u_offset: (s2 / n as f64).sqrt(),
        u_normal: rss(s2 / m.eigenvalues[1], s2 / m.eigenvalues[2]),
    }
}

/// Least-squares plane (orthogonal distance).
pub fn plane(points: &[Point3]) -> Result<PlaneFit, FitError> {
    let m = Moments::for_fit(points, "plane", 3, 1)?;
    Ok(plane_from_moments(points, &m))
}

// ---------------------------------------------------------------------------------------------
// Sphere

/// Least-squares sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereFit {
    /// Centre of the sphere, in the frame of the points, mm.
    pub center: Point3,
    /// Radius of the sphere (the fixed radius when one was given), mm.
    pub radius: f64,
    /// RMS of the orthogonal residuals `|p − c| − r`, mm.
    pub rms: f64,
    /// Largest absolute orthogonal residual, mm.
    pub max_abs_residual: f64,
    /// Number of points fitted.
    pub n_points: usize,
    /// Standard uncertainties of the centre coordinates, mm.
    pub u_center: Vector3,
    /// Covariance of the centre, mm².
    pub center_covariance: Matrix3,
    /// Standard uncertainty of the radius, mm (0 when the radius was fixed).
    pub u_radius: f64,
    /// Gauss-Newton iterations the fit took.
    pub iterations: usize,
    /// Sphericity about this sphere: largest minus smallest `|p − c|`, mm.
    pub form: f64,
}

struct SphereModel {
    scale: f64,
}
impl Model<4> for SphereModel {
    type State = (Point3, f64);
    #[inline(always)]
    fn residual(&self, s: &(Point3, f64), p: &Point3, j: &mut [f64; 4]) -> f64 {
        let (dx, dy, dz) = (p.x - s.0.x, p.y - s.0.y, p.z - s.0.z);
        let d = (dx * dx + dy * dy + dz * dz).sqrt();
        let inv = 1.0 / d;
        j[0] = -dx * inv;
        j[1] = -dy * inv;
        j[2] = -dz * inv;
        j[3] = -1.0;
        d - s.1
    }
    #[inline(always)]
    fn residuals_block(
        &self,
        s: &(Point3, f64),
        pts: &[Point3],
        r: &mut [f64; BLOCK],
        j: &mut [[f64; 4]; BLOCK],
    ) {
        // Structure of arrays over the block so that sqrt and 1/x run two (or four) points per
        // instruction: the divider, not memory, bounds the per-point loop otherwise.
        let (mut dx, mut dy, mut dz, mut q) = ([0.0; BLOCK], [0.0; BLOCK], [0.0; BLOCK], [1.0; BLOCK]);
        for (k, p) in pts.iter().enumerate() {
            dx[k] = p.x - s.0.x;
            dy[k] = p.y - s.0.y;
            dz[k] = p.z - s.0.z;
            q[k] = dx[k] * dx[k] + dy[k] * dy[k] + dz[k] * dz[k];
        }
        let mut d = [0.0; BLOCK];
        let mut inv = [0.0; BLOCK];
        for k in 0..BLOCK {
            d[k] = q[k].sqrt();
            inv[k] = 1.0 / d[k];
        }
        for k in 0..pts.len() {
            j[k] = [-dx[k] * inv[k], -dy[k] * inv[k], -dz[k] * inv[k], -1.0];
            r[k] = d[k] - s.1;
        }
    }
    fn apply(&self, s: &(Point3, f64), d: &SVector<f64, 4>) -> (Point3, f64) {
        (s.0 + Vector3::new(d[0], d[1], d[2]), s.1 + d[3])
    }
    fn step_size(&self, d: &SVector<f64, 4>) -> f64 {
        d.amax() / self.scale
    }
}

struct FixedSphereModel(f64, f64);
impl Model<3> for FixedSphereModel {
    type State = Point3;
    #[inline(always)]
    fn residual(&self, s: &Point3, p: &Point3, j: &mut [f64; 3]) -> f64 {
        let (dx, dy, dz) = (p.x - s.x, p.y - s.y, p.z - s.z);
        let d = (dx * dx + dy * dy + dz * dz).sqrt();
        let inv = 1.0 / d;
        j[0] = -dx * inv;
        j[1] = -dy * inv;
        j[2] = -dz * inv;
        d - self.0
    }
    fn apply(&self, s: &Point3, d: &SVector<f64, 3>) -> Point3 {
        s + d
    }
    fn step_size(&self, d: &SVector<f64, 3>) -> f64 {
        d.amax() / self.1
    }
}

/// Least-squares sphere (orthogonal distance), from the algebraic (Kåsa) start.
pub fn sphere(points: &[Point3]) -> Result<SphereFit, FitError> {
    let m = Moments::for_fit(points, "sphere", 4, 2)?;
    let (c0, r0) = m.algebraic_sphere().ok_or(FitError::Undetermined { kind: "sphere" })?;
    let model = SphereModel { scale: m.extent() };
    let sol = minimise(&model, (c0, r0), points, MAX_ITERATIONS)
        .ok_or(FitError::Undetermined { kind: "sphere" })?;
    let (center, radius) = sol.state;
    let cov = covariance(&sol.acc, points.len(), RCOND).ok_or(FitError::Undetermined { kind: "sphere" })?;
    let center_covariance = cov.fixed_view::<3, 3>(0, 0).into_owned();
    let n = points.len();
    // The form from the last accumulation's residuals `d − r` (d = |p − c|), without another
    // pass, when every `d − r` was exact (Sterbenz: r/2 ≤ d ≤ 2r), so that
    // `(d_max − r) − (d_min − r)` is `d_max − d_min` rounded once, bit for bit the form of the
    // distances themselves; else the pass over the distances.
    let (lo_r, hi_r) = (sol.acc.min_r, sol.acc.max_r);
    let form = if radius > 0.0 && lo_r >= -0.5 * radius && hi_r <= radius {
        hi_r - lo_r
    } else {
        let (lo, hi) = extremes(points, |p| (p - center).norm());
        hi - lo
    };
    Ok(SphereFit {
        form,
        center,
        radius: radius.abs(),
        rms: (sol.acc.ssr / n as f64).sqrt(),
        max_abs_residual: sol.acc.max_abs,
        n_points: n,
        u_center: sqrt_diag(&center_covariance),
        center_covariance,
        u_radius: cov[(3, 3)].max(0.0).sqrt(),
        iterations: sol.iterations,
    })
}

/// Least-squares sphere of known radius (only the centre is fitted), e.g. a calibrated
/// reference sphere. The points must not be coplanar (a circle of points lies on two mirror
/// spheres of the same radius).
pub fn sphere_with_radius(points: &[Point3], radius: f64) -> Result<SphereFit, FitError> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(FitError::InvalidRadius(radius));
    }
    // Four points: any three are coplanar, and coplanar points leave a mirror ambiguity.
    let m = Moments::for_fit(points, "sphere", 4, 2)?;
    // Start: the free algebraic sphere's centre, moved along the line from the centroid so the
    // mean distance matches the fixed radius.
    let c0 = match m.algebraic_sphere() {
        Some((c, _)) => c,
        None => m.centroid,
    };
    let model = FixedSphereModel(radius, m.extent());
    let sol =
        minimise(&model, c0, points, MAX_ITERATIONS).ok_or(FitError::Undetermined { kind: "sphere" })?;
    let center = sol.state;
    let cov = covariance(&sol.acc, points.len(), RCOND).ok_or(FitError::Undetermined { kind: "sphere" })?;
    let n = points.len();
    let (lo, hi) = extremes(points, |p| (p - center).norm());
    Ok(SphereFit {
        form: hi - lo,
        center,
        radius,
        rms: (sol.acc.ssr / n as f64).sqrt(),
        max_abs_residual: sol.acc.max_abs,
        n_points: n,
        u_center: sqrt_diag(&cov),
        center_covariance: cov,
        u_radius: 0.0,
        iterations: sol.iterations,
    })
}

// ---------------------------------------------------------------------------------------------
// Circle (3D)

/// Least-squares 3D circle (ISO 10360-6 reference definition).
#[derive(Clone, Debug, PartialEq)]
pub struct CircleFit {
    /// Centre of the circle, in the frame of the points, mm.
    pub center: Point3,
    /// Unit normal of the least-squares plane (sign: largest component positive).
    pub normal: Vector3,
    /// Radius of the circle, mm.
    pub radius: f64,
    /// RMS of the 3D distance of the points from the circle, mm.
    pub rms: f64,
    /// Largest absolute 3D distance of a point from the circle, mm.
    pub max_abs_residual: f64,
    /// RMS of the in-plane radial residuals (what the 2D circle fit minimises), mm.
    pub radial_rms: f64,
    /// RMS distance from the plane, mm.
    pub plane_rms: f64,
    /// Number of points fitted.
    pub n_points: usize,
    /// Standard uncertainties of the centre coordinates, mm.
    pub u_center: Vector3,
    /// Standard uncertainty of the radius, mm.
    pub u_radius: f64,
    /// Standard uncertainty of the normal (root-sum-square of two tilt angles), rad.
    pub u_normal: f64,
    /// Gauss-Newton iterations of the in-plane circle fit.
    pub iterations: usize,
    /// Covariance of the centre, including the least-squares plane's offset and tilt, mm².
    pub center_covariance: Matrix3,
    /// Covariance of the unit normal's components (from the plane).
    pub normal_covariance: Matrix3,
    /// Roundness about this circle: largest minus smallest in-plane radial residual of the
    /// points projected into the least-squares plane, mm.
    pub form: f64,
}

struct CircleModel {
    scale: f64,
}
impl Model<3> for CircleModel {
    type State = (Vector2<f64>, f64);
    #[inline(always)]
    fn residual(&self, s: &(Vector2<f64>, f64), p: &Point3, j: &mut [f64; 3]) -> f64 {
        let (dx, dy) = (p.x - s.0.x, p.y - s.0.y);
        let d = (dx * dx + dy * dy).sqrt();
        j[0] = -dx / d;
        j[1] = -dy / d;
        j[2] = -1.0;
        d - s.1
    }
    fn apply(&self, s: &(Vector2<f64>, f64), d: &SVector<f64, 3>) -> (Vector2<f64>, f64) {
        (s.0 + Vector2::new(d[0], d[1]), s.1 + d[2])
    }
    fn step_size(&self, d: &SVector<f64, 3>) -> f64 {
        d.amax() / self.scale
    }
}

/// Algebraic (Kåsa) circle of 2D points stored as `(u, v, 0)` and centred: `(centre, radius)`.
fn kasa_2d(q: &[Point3]) -> Option<(Vector2<f64>, f64)> {
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut rhs = Vector3::zeros();
    for p in q {
        let row = Vector3::new(2.0 * p.x, 2.0 * p.y, 1.0);
        let s = p.x * p.x + p.y * p.y;
        m += row * row.transpose();
        rhs += row * s;
    }
    let sol = m.cholesky()?.solve(&rhs);
    let r2 = sol[2] + sol[0] * sol[0] + sol[1] * sol[1];
    (r2 > 0.0 && r2.is_finite()).then(|| (Vector2::new(sol[0], sol[1]), r2.sqrt()))
}

/// Least-squares 3D circle: the least-squares plane, then the least-squares circle of the
/// points projected into it.
pub fn circle(points: &[Point3]) -> Result<CircleFit, FitError> {
    let m = Moments::for_fit(points, "circle", 3, 1)?;
    let pl = plane_from_moments(points, &m);
    let (u, v, n) = (m.axis(2), m.axis(1), pl.normal);
    let c = m.centroid;
    let q: Vec<Point3> = points.iter().map(|p| Point3::new((p - c).dot(&u), (p - c).dot(&v), 0.0)).collect();
    let start = kasa_2d(&q).ok_or(FitError::CollinearPoints { kind: "circle" })?;
    let sol = minimise(&CircleModel { scale: m.extent() }, start, &q, MAX_ITERATIONS)
        .ok_or(FitError::Undetermined { kind: "circle" })?;
    let (c2, radius) = sol.state;
    let cov = covariance(&sol.acc, points.len(), RCOND).ok_or(FitError::Undetermined { kind: "circle" })?;
    let center = c + u * c2.x + v * c2.y;
    // Centre covariance: in-plane from the circle fit, along the normal from the plane offset.
    let e = nalgebra::Matrix3x2::from_columns(&[u, v]);
    let c_in = cov.fixed_view::<2, 2>(0, 0).into_owned();
    // Along the normal: the plane's offset at the centroid, plus its two tilts (about the
    // principal axes u, v through the centroid) carried over the in-plane lever arm c2.
    let s2p = pl.u_offset.powi(2) * points.len() as f64;
    let var_n =
        pl.u_offset.powi(2) + c2.x * c2.x * s2p / m.eigenvalues[2] + c2.y * c2.y * s2p / m.eigenvalues[1];
    let cc = e * c_in * e.transpose() + n * n.transpose() * var_n;
    let nn = points.len();
    let mut ssr3 = 0.0;
    let mut max3 = 0.0f64;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (p, qq) in points.iter().zip(&q) {
        let h = (p - c).dot(&n);
        let rr = (qq.x - c2.x).hypot(qq.y - c2.y) - radius;
        lo = lo.min(rr);
        hi = hi.max(rr);
        let d2 = h * h + rr * rr;
        ssr3 += d2;
        max3 = max3.max(d2.sqrt());
    }
    Ok(CircleFit {
        center,
        normal: n,
        radius: radius.abs(),
        rms: (ssr3 / nn as f64).sqrt(),
        max_abs_residual: max3,
        radial_rms: (sol.acc.ssr / nn as f64).sqrt(),
        plane_rms: pl.rms,
        n_points: nn,
        u_center: sqrt_diag(&cc),
        u_radius: cov[(2, 2)].max(0.0).sqrt(),
        u_normal: pl.u_normal,
        iterations: sol.iterations,
        center_covariance: cc,
        normal_covariance: pl.normal_covariance,
        form: hi - lo,
    })
}
