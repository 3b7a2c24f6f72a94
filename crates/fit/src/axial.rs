//! Cylinder and cone: least-squares elements with an axis.
//!
//! Parametrisation (Forbes, NPL DITC 140/89): at every iteration the data is re-expressed in a
//! frame whose origin is the current axis point nearest the centroid and whose z is the current
//! axis; the step is `(x0, y0, a, b, …)`: a shift of the axis point in the frame's xy-plane and a
//! tilt of the axis to `(a, b, 1)`. The Jacobian is evaluated at the step's origin, where it is
//! simple and well conditioned; the frame is rebuilt after each accepted step.
//!
//! Cone residual (orthogonal distance, valid on both sides of the surface):
//! `d = ρ·cos ψ − z·sin ψ − s`, with `ρ` the distance from the axis, `z` the coordinate along the
//! axis from the axis point, `ψ` the half apex angle and `s` the orthogonal distance from the
//! axis point to the surface (NIST's cone parameter).
//!
//! Starting values: for each candidate axis direction (the three principal axes and 64
//! directions spread evenly over the hemisphere) an algebraic fit of `x² + y² = 2ax + 2by + e
//! (+ f z + g z²)` to a subsample of at most 2000 points — exact for a cylinder (cone) whose axis
//! is the candidate — scored by the geometric residual; the best few are refined with all points
//! and the lowest sum of squares wins.

use crate::engine::{covariance, minimise, Model};
use crate::moments::Moments;
use crate::{FitError, MAX_ITERATIONS, RCOND};
use nalgebra::{SMatrix, SVector};
use truepos_math::{any_perpendicular, Matrix3, Point3, Vector3};

/// Least-squares cylinder.
#[derive(Clone, Debug, PartialEq)]
pub struct CylinderFit {
    /// The point on the axis nearest the centroid.
    pub point: Point3,
    /// Unit axis direction (sign: largest component positive).
    pub axis: Vector3,
    /// Radius of the cylinder, mm.
    pub radius: f64,
    /// RMS orthogonal distance of the points from the cylinder surface, mm.
    pub rms: f64,
    /// Largest absolute orthogonal residual, mm.
    pub max_abs_residual: f64,
    /// Number of points fitted.
    pub n_points: usize,
    /// Standard uncertainty of `point` perpendicular to the axis (root-sum-square), mm.
    pub u_point: f64,
    /// Standard uncertainty of the axis direction (root-sum-square of two tilts), rad.
    pub u_axis: f64,
    /// Standard uncertainty of the radius, mm.
    pub u_radius: f64,
    /// Gauss-Newton iterations the fit took.
    pub iterations: usize,
    /// Covariance of `point` (perpendicular to the axis), mm².
    pub point_covariance: Matrix3,
    /// Covariance of the unit axis vector's components.
    pub axis_covariance: Matrix3,
    /// Cylindricity about this cylinder: largest minus smallest distance from the axis, mm.
    pub form: f64,
}

/// Least-squares cone.
#[derive(Clone, Debug, PartialEq)]
pub struct ConeFit {
    /// The apex (vertex) of the cone, in the frame of the points, mm.
    pub apex: Point3,
    /// Unit axis direction from the apex towards increasing radius.
    pub axis: Vector3,
    /// Full apex angle, rad.
    pub apex_angle: f64,
    /// The point on the axis nearest the centroid (where the data is).
    pub point: Point3,
    /// Orthogonal distance from `point` to the cone surface, mm.
    pub surface_distance: f64,
    /// RMS signed orthogonal distance of the points from the cone surface, mm.
    pub rms: f64,
    /// Largest absolute orthogonal residual, mm.
    pub max_abs_residual: f64,
    /// Number of points fitted.
    pub n_points: usize,
    /// Standard uncertainties of the apex coordinates, mm (large for small apex angles).
    pub u_apex: Vector3,
    /// Standard uncertainty of `point` perpendicular to the axis (root-sum-square), mm.
    pub u_point: f64,
    /// Standard uncertainty of the axis direction (root-sum-square of two tilts), rad.
    pub u_axis: f64,
    /// Standard uncertainty of the full apex angle, rad.
    pub u_apex_angle: f64,
    /// Standard uncertainty of `surface_distance`, mm.
    pub u_surface_distance: f64,
    /// Gauss-Newton iterations the fit took.
    pub iterations: usize,
    /// Covariance of the apex, mm².
    pub apex_covariance: Matrix3,
    /// Covariance of the unit axis vector's components.
    pub axis_covariance: Matrix3,
    /// Conicity about this cone: largest minus smallest signed orthogonal residual, mm.
    pub form: f64,
}

/// `E C Eᵀ` for the 2×2 block of `cov` at (`k`, `k`) with `E = [u v]`.
fn lift(cov: &SMatrix<f64, 5, 5>, k: usize, u: &Vector3, v: &Vector3) -> Matrix3 {
    let e = nalgebra::Matrix3x2::from_columns(&[*u, *v]);
    let c = nalgebra::Matrix2::new(cov[(k, k)], cov[(k, k + 1)], cov[(k + 1, k)], cov[(k + 1, k + 1)]);
    e * c * e.transpose()
}

/// A frame on the current axis: origin on the axis, rows of `r` are (u, v, axis).
#[derive(Clone, Debug)]
struct Frame {
    o: Point3,
    r: Matrix3,
}

impl Frame {
    fn new(o: Point3, axis: Vector3) -> Frame {
        let w = axis.normalize();
        let u = any_perpendicular(&w);
        let v = w.cross(&u);
        Frame { o, r: Matrix3::from_rows(&[u.transpose(), v.transpose(), w.transpose()]) }
    }
    fn u(&self) -> Vector3 {
        self.r.row(0).transpose()
    }
    fn v(&self) -> Vector3 {
        self.r.row(1).transpose()
    }
    fn w(&self) -> Vector3 {
        self.r.row(2).transpose()
    }
    #[inline(always)]
    fn local(&self, p: &Point3) -> Vector3 {
        self.r * (p - self.o)
    }
    /// The frame after the step (x0, y0, a, b), its origin moved along the new axis to the
    /// point nearest `centre`; returns the frame and how far the origin moved along the axis.
    fn stepped(&self, d0: f64, d1: f64, a: f64, b: f64, centre: &Point3) -> (Frame, f64) {
        let (u, v, w) = (self.u(), self.v(), self.w());
        let o = self.o + u * d0 + v * d1;
        let wn = (w + u * a + v * b).normalize();
        let t = (centre - o).dot(&wn);
        let un = (u - wn * u.dot(&wn)).normalize();
        let vn = wn.cross(&un);
        (Frame { o: o + wn * t, r: Matrix3::from_rows(&[un.transpose(), vn.transpose(), wn.transpose()]) }, t)
    }
}

struct CylModel {
    centre: Point3,
    scale: f64,
}
impl Model<5> for CylModel {
    type State = (Frame, f64);
    #[inline(always)]
    fn residual(&self, s: &(Frame, f64), p: &Point3, j: &mut [f64; 5]) -> f64 {
        let q = s.0.local(p);
        let rho = (q.x * q.x + q.y * q.y).sqrt();
        let (cx, cy) = (q.x / rho, q.y / rho);
        j[0] = -cx;
        j[1] = -cy;
        j[2] = -cx * q.z;
        j[3] = -cy * q.z;
        j[4] = -1.0;
        rho - s.1
    }
    fn apply(&self, s: &(Frame, f64), d: &SVector<f64, 5>) -> (Frame, f64) {
        (s.0.stepped(d[0], d[1], d[2], d[3], &self.centre).0, s.1 + d[4])
    }
    fn step_size(&self, d: &SVector<f64, 5>) -> f64 {
        (d[0].abs().max(d[1].abs()).max(d[4].abs()) / self.scale).max(d[2].abs()).max(d[3].abs())
    }
}

struct ConeModel {
    centre: Point3,
    scale: f64,
}
/// State: frame, half apex angle ψ, surface distance s.
type ConeState = (Frame, f64, f64);
impl Model<6> for ConeModel {
    type State = ConeState;
    #[inline(always)]
    fn residual(&self, s: &ConeState, p: &Point3, j: &mut [f64; 6]) -> f64 {
        let q = s.0.local(p);
        let rho = (q.x * q.x + q.y * q.y).sqrt();
        let (sn, cs) = s.1.sin_cos();
        let (cx, cy) = (q.x / rho, q.y / rho);
        j[0] = -cx * cs;
        j[1] = -cy * cs;
        j[2] = -cs * cx * q.z - sn * q.x;
        j[3] = -cs * cy * q.z - sn * q.y;
        j[4] = -rho * sn - q.z * cs;
        j[5] = -1.0;
        rho * cs - q.z * sn - s.2
    }
    fn apply(&self, s: &ConeState, d: &SVector<f64, 6>) -> ConeState {
        let (f, t) = s.0.stepped(d[0], d[1], d[2], d[3], &self.centre);
        let psi = s.1 + d[4];
        // Moving the axis point by t along the axis changes the surface distance by t·sin ψ.
        (f, psi, s.2 + d[5] + t * psi.sin())
    }
    fn step_size(&self, d: &SVector<f64, 6>) -> f64 {
        let pos = d[0].abs().max(d[1].abs()).max(d[5].abs()) / self.scale;
        pos.max(d[2].abs()).max(d[3].abs()).max(d[4].abs())
    }
}

/// Candidate axis directions: principal axes first, then an even spread over the hemisphere
/// (Fibonacci lattice), so that no axis orientation is more than ~15° from a candidate.
fn candidate_axes(m: &Moments, n: usize) -> Vec<Vector3> {
    let mut v = vec![m.axis(2), m.axis(1), m.axis(0)];
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..n {
        let z = 1.0 - (i as f64 + 0.5) / n as f64; // (0, 1]: upper hemisphere
        let r = (1.0 - z * z).sqrt();
        let phi = golden * i as f64;
        v.push(Vector3::new(r * phi.cos(), r * phi.sin(), z));
    }
    v
}

/// At most `k` points spread over the data (every `n/k`-th).
fn subsample(points: &[Point3], k: usize) -> Vec<Point3> {
    if points.len() <= k {
        return points.to_vec();
    }
    let step = points.len() as f64 / k as f64;
    (0..k).map(|i| points[(i as f64 * step) as usize]).collect()
}

/// Algebraic start along `axis`: fits `x²+y² = 2ax + 2by + e [+ f z + g z²]` in a frame at the
/// centroid. Returns (axis point, half angle ψ, surface distance s) with ψ = 0 for a cylinder.
fn algebraic_axial(
    sub: &[Point3],
    centre: &Point3,
    axis: &Vector3,
    cone: bool,
) -> Option<(Point3, f64, f64)> {
    let f = Frame::new(*centre, *axis);
    let k = if cone { 5 } else { 3 };
    let mut ata = nalgebra::DMatrix::<f64>::zeros(k, k);
    let mut atb = nalgebra::DVector::<f64>::zeros(k);
    let mut row = [0.0; 5];
    for p in sub {
        let q = f.local(p);
        row[0] = 2.0 * q.x;
        row[1] = 2.0 * q.y;
        row[2] = 1.0;
        row[3] = q.z;
        row[4] = q.z * q.z;
        let rhs = q.x * q.x + q.y * q.y;
        for a in 0..k {
            atb[a] += row[a] * rhs;
            for b in 0..k {
                ata[(a, b)] += row[a] * row[b];
            }
        }
    }
    let sol = ata.cholesky()?.solve(&atb);
    let (a, b, e) = (sol[0], sol[1], sol[2]);
    let r0 = (e + a * a + b * b).max(0.0).sqrt();
    let (psi, s) = if cone {
        let slope = sol[4].max(0.0).sqrt().copysign(sol[3]);
        let psi = slope.atan();
        (psi, r0 * psi.cos())
    } else {
        (0.0, r0)
    };
    let o = f.o + f.u() * a + f.v() * b;
    (r0 > 0.0 && psi.is_finite()).then_some((o, psi, s))
}

fn score(sub: &[Point3], o: &Point3, axis: &Vector3, psi: f64, s: f64) -> f64 {
    let f = Frame::new(*o, *axis);
    let (sn, cs) = psi.sin_cos();
    sub.iter()
        .map(|p| {
            let q = f.local(p);
            let d = q.x.hypot(q.y) * cs - q.z * sn - s;
            d * d
        })
        .sum()
}

/// Point count up to which every start is refined (the global search of small data sets, where
/// local minima are common: one 6-point exact cylinder converged to r 5.57 mm instead of 5 from
/// the best three starts). 400 axis directions (≤ 7° from any axis) refined on ≤ 200 points
/// cost less than one start on 100 000 points.
const GLOBAL_SEARCH_POINTS: usize = 200;

/// Best starting values `(axis point, axis, ψ, s)`, best first: on small data sets (at most
/// [`GLOBAL_SEARCH_POINTS`]) from 400 axis directions and all of them, else from 64 and the
/// best `keep`.
fn starts(points: &[Point3], m: &Moments, cone: bool, keep: usize) -> Vec<(Point3, Vector3, f64, f64, f64)> {
    let sub = subsample(points, 2000);
    let small = points.len() <= GLOBAL_SEARCH_POINTS;
    let (dirs, keep) = if small { (400, usize::MAX) } else { (64, keep) };
    let mut c: Vec<(Point3, Vector3, f64, f64, f64)> = candidate_axes(m, dirs)
        .into_iter()
        .filter_map(|w| {
            let (o, psi, s) = algebraic_axial(&sub, &m.centroid, &w, cone)?;
            let sc = score(&sub, &o, &w, psi, s);
            sc.is_finite().then_some((o, w, psi, s, sc))
        })
        .collect();
    c.sort_by(|a, b| a.4.total_cmp(&b.4));
    c.truncate(keep);
    c
}

fn canonical(v: Vector3) -> Vector3 {
    if v[v.iamax()] < 0.0 {
        -v
    } else {
        v
    }
}

/// Fewest points for a cylinder: it has 5 parameters, and up to six different cylinders pass
/// exactly through 5 points in general position (Bottema and Veldkamp), so a sixth point is
/// needed to decide between them (and to leave a residual that checks the fit).
pub const MIN_CYLINDER_POINTS: usize = 6;

/// Fewest points for a cone: it has 6 parameters, and several cones pass exactly through 6
/// points in general position, so a seventh is needed to decide between them.
pub const MIN_CONE_POINTS: usize = 7;

/// A converged local minimum of one start: its sum of squares, size (radius or full apex
/// angle) and axis.
struct Minimum {
    ssr: f64,
    size: f64,
    axis: Vector3,
}

/// The check that the least-squares answer is the answer: among the local minima found from
/// every start, none other than the best may fit as well (a sum of squares within one residual
/// variance, `ssr / (n − p)`, of the best) while describing a different element (its size or
/// axis more than three standard uncertainties, and more than 1e-7 relative or rad, away: the
/// convergence of one start is far tighter). Otherwise
/// the data does not determine the element: two answers fit it equally well.
#[allow(clippy::too_many_arguments)]
fn unique(
    kind: &'static str,
    size_name: &str,
    minima: &[Minimum],
    n: usize,
    p: usize,
    (size, u_size): (f64, f64),
    (axis, u_axis): (Vector3, f64),
    size_scale: f64,
) -> Result<(), FitError> {
    let best = minima.iter().map(|m| m.ssr).fold(f64::INFINITY, f64::min);
    let dof = n.saturating_sub(p).max(1) as f64;
    let within = best + best / dof;
    for m in minima {
        if m.ssr > within {
            continue;
        }
        let d_size = (m.size - size).abs();
        let angle = m.axis.cross(&axis).norm().atan2(m.axis.dot(&axis).abs());
        let other_size = d_size > 3.0 * u_size && d_size > 1e-7 * size_scale.max(size);
        let other_axis = angle > 3.0 * u_axis && angle > 1e-7;
        if other_size || other_axis {
            return Err(FitError::NotUnique {
                kind,
                detail: format!(
                    "two {kind}s fit the {n} points equally well ({size_name} {} and {}, axes {:.3}° apart; sums of squares {:.3e} and {:.3e} mm²); measure more points",
                    fmt_size(size),
                    fmt_size(m.size),
                    angle.to_degrees(),
                    best,
                    m.ssr
                ),
            });
        }
    }
    Ok(())
}

fn fmt_size(v: f64) -> String {
    format!("{v:.6}")
}

/// Least-squares cylinder (orthogonal distance).
pub fn cylinder(points: &[Point3]) -> Result<CylinderFit, FitError> {
    let m = Moments::for_fit(points, "cylinder", MIN_CYLINDER_POINTS, 2)?;
    let model = CylModel { centre: m.centroid, scale: m.extent() };
    let mut best: Option<crate::engine::Solution<5, (Frame, f64)>> = None;
    let mut minima: Vec<Minimum> = Vec::new();
    for (o, w, _, s, _) in starts(points, &m, false, 3) {
        let (f, _) = Frame::new(o, w).stepped(0.0, 0.0, 0.0, 0.0, &m.centroid);
        if let Some(sol) = minimise(&model, (f, s), points, MAX_ITERATIONS) {
            minima.push(Minimum { ssr: sol.acc.ssr, size: sol.state.1.abs(), axis: sol.state.0.w() });
            if best.as_ref().is_none_or(|b| sol.acc.ssr < b.acc.ssr) {
                best = Some(sol);
            }
        }
    }
    let sol = best.ok_or(FitError::Undetermined { kind: "cylinder" })?;
    let (frame, radius) = &sol.state;
    let radius = radius.abs();
    let extent = m.extent();
    let cov = covariance(&sol.acc, points.len(), RCOND);
    let Some(cov) = cov else {
        return Err(if radius > 100.0 * extent {
            FitError::CylinderIsFlat
        } else {
            FitError::Undetermined { kind: "cylinder" }
        });
    };
    let ur = cov[(4, 4)].max(0.0).sqrt();
    // Flat data: the curvature 1/R is not significantly different from zero (|κ| ≤ 3 u(κ),
    // u(κ) = u(R)/R², i.e. u(R) ≥ R/3), or the radius is a million times the data's extent.
    if 3.0 * ur >= radius || radius > 1e6 * extent {
        return Err(FitError::CylinderIsFlat);
    }
    let ua = (cov[(2, 2)] + cov[(3, 3)]).max(0.0).sqrt();
    unique("cylinder", "radius", &minima, points.len(), 5, (radius, ur), (frame.w(), ua), extent)?;
    let n = points.len();
    let (u, v) = (frame.u(), frame.v());
    let (lo, hi) = crate::extremes(points, |p| {
        let q = frame.local(p);
        q.x.hypot(q.y)
    });
    Ok(CylinderFit {
        point_covariance: lift(&cov, 0, &u, &v),
        axis_covariance: lift(&cov, 2, &u, &v),
        form: hi - lo,
        point: frame.o,
        axis: canonical(frame.w()),
        radius,
        rms: (sol.acc.ssr / n as f64).sqrt(),
        max_abs_residual: sol.acc.max_abs,
        n_points: n,
        u_point: (cov[(0, 0)] + cov[(1, 1)]).max(0.0).sqrt(),
        u_axis: (cov[(2, 2)] + cov[(3, 3)]).max(0.0).sqrt(),
        u_radius: ur,
        iterations: sol.iterations,
    })
}

/// Least-squares cone (orthogonal distance).
pub fn cone(points: &[Point3]) -> Result<ConeFit, FitError> {
    let m = Moments::for_fit(points, "cone", MIN_CONE_POINTS, 2)?;
    let extent = m.extent();
    let model = ConeModel { centre: m.centroid, scale: extent };
    let mut best: Option<crate::engine::Solution<6, ConeState>> = None;
    let mut minima: Vec<Minimum> = Vec::new();
    for (o, w, psi, s, _) in starts(points, &m, true, 4) {
        let (f, t) = Frame::new(o, w).stepped(0.0, 0.0, 0.0, 0.0, &m.centroid);
        let sol = minimise(&model, (f, psi, s + t * psi.sin()), points, MAX_ITERATIONS).and_then(|sol| {
            // ψ is found modulo π ((ψ + π, s) is the cone (ψ, −s)): a minimum outside
            // (−π/2, π/2] is the same cone, converged again from its canonical state so that
            // its covariance belongs to the parameters reported.
            let (f, psi, s) = sol.state.clone();
            let k = (psi / std::f64::consts::PI).round();
            if k == 0.0 {
                return Some(sol);
            }
            let s = if k.rem_euclid(2.0) == 1.0 { -s } else { s };
            minimise(&model, (f, psi - k * std::f64::consts::PI, s), points, MAX_ITERATIONS)
        });
        if let Some(sol) = sol {
            minima.push(Minimum { ssr: sol.acc.ssr, size: 2.0 * sol.state.1.abs(), axis: sol.state.0.w() });
            if best.as_ref().is_none_or(|b| sol.acc.ssr < b.acc.ssr) {
                best = Some(sol);
            }
        }
    }
    let sol = best.ok_or(FitError::Undetermined { kind: "cone" })?;
    let (frame, psi, s) = sol.state.clone();
    // Orient the axis towards increasing radius (ψ > 0); the residual is invariant under
    // (axis, ψ) → (−axis, −ψ), and the covariance's signs flip with the parameters.
    let (w, psi) = if psi < 0.0 { (-frame.w(), -psi) } else { (frame.w(), psi) };
    let cov = covariance(&sol.acc, points.len(), RCOND);
    let upsi = cov.as_ref().map(|c| c[(4, 4)].max(0.0).sqrt());
    let apex_dist = s / psi.sin();
    // A cone whose half angle is not significantly different from 0 is a cylinder: apex at
    // infinity. Also when ψ is below 1e-9 rad (exact cylinder data) or the apex is a million
    // data extents away.
    if psi < 1e-9 || upsi.is_none_or(|u| psi <= 3.0 * u) || !(apex_dist.abs() < 1e6 * extent) {
        return Err(FitError::ConeIsCylinder);
    }
    let cov = cov.ok_or(FitError::Undetermined { kind: "cone" })?;
    let ua = (cov[(2, 2)] + cov[(3, 3)]).max(0.0).sqrt();
    let upsi = 2.0 * cov[(4, 4)].max(0.0).sqrt();
    unique("cone", "apex angle", &minima, points.len(), 6, (2.0 * psi, upsi), (frame.w(), ua), 1.0)?;
    let apex = frame.o - w * apex_dist;
    // Apex = o + δ0 u + δ1 v − (w + δ2 u + δ3 v)·s/sin ψ in the fit's own parameters.
    let (u, v, wf) = (frame.u(), frame.v(), frame.w());
    let psi_f = sol.state.1;
    let big = sol.state.2 / psi_f.sin();
    let mut jac = SMatrix::<f64, 3, 6>::zeros();
    jac.set_column(0, &u);
    jac.set_column(1, &v);
    jac.set_column(2, &(-u * big));
    jac.set_column(3, &(-v * big));
    jac.set_column(4, &(wf * (sol.state.2 * psi_f.cos() / psi_f.sin().powi(2))));
    jac.set_column(5, &(-wf / psi_f.sin()));
    let ca = jac * cov * jac.transpose();
    let n = points.len();
    let cov5 = cov.fixed_view::<5, 5>(0, 0).into_owned();
    let (sn, cs) = psi_f.sin_cos();
    let s_f = sol.state.2;
    let (lo, hi) = crate::extremes(points, |p| {
        let q = frame.local(p);
        q.x.hypot(q.y) * cs - q.z * sn - s_f
    });
    Ok(ConeFit {
        apex_covariance: ca,
        axis_covariance: lift(&cov5, 2, &u, &v),
        form: hi - lo,
        apex,
        axis: w,
        apex_angle: 2.0 * psi,
        point: frame.o,
        surface_distance: s,
        rms: (sol.acc.ssr / n as f64).sqrt(),
        max_abs_residual: sol.acc.max_abs,
        n_points: n,
        u_apex: Vector3::new(ca[(0, 0)], ca[(1, 1)], ca[(2, 2)]).map(|x| x.max(0.0).sqrt()),
        u_point: (cov[(0, 0)] + cov[(1, 1)]).max(0.0).sqrt(),
        u_axis: (cov[(2, 2)] + cov[(3, 3)]).max(0.0).sqrt(),
        u_apex_angle: 2.0 * cov[(4, 4)].max(0.0).sqrt(),
        u_surface_distance: cov[(5, 5)].max(0.0).sqrt(),
        iterations: sol.iterations,
    })
}

impl ConeFit {
    /// Orthogonal distance from a point on the axis at signed position `t` (along `axis` from
    /// `point`) to the surface.
    pub fn surface_distance_at(&self, t: f64) -> f64 {
        self.surface_distance + t * (self.apex_angle / 2.0).sin()
    }
}
