//! Chebyshev (minimum-zone) fits and the maximum-inscribed / minimum-circumscribed elements:
//! form by the definitions of ISO 1101 / ISO 12780–12781, ISO 12181, ISO 12180.
//!
//! Entry points: [`line_zone`] (straightness: the smallest cylinder holding every point),
//! [`plane_zone`] (flatness), [`circle_fit`], [`sphere_fit`], [`cylinder_fit`] with a
//! [`Criterion`] (minimum zone, maximum inscribed, minimum circumscribed). Every result has the
//! feature, the zone's inner and outer radius (or the two planes' offsets) and `form`, the zone
//! width about the reported feature.
//!
//! Method: sequential linear programming with a trust region. At the current feature the
//! orthogonal residuals are linearised in a local step (a shift of the centre or axis point, a
//! tilt of the normal or axis, expressed in a frame rebuilt at every step), and the linear
//! Chebyshev problem (`min t − s` with `s ≤ rᵢ + Jᵢδ ≤ t`; `min t` for circumscribed and line
//! zones; `max s` for inscribed) with the box `|δⱼ| ≤ Δ` is solved exactly by the crate's private `lp` module.
//! A step is accepted when the exact (nonlinear) objective decreases; the box grows or shrinks
//! with the agreement between predicted and actual decrease. At convergence the linearised
//! problem has its optimum at δ = 0, which is the first-order optimality condition of the exact
//! problem: the result is a vertex solution held by `k + 2` contact points, exact to rounding.
//! Only constraints that can be active inside the box are given to the LP (a point whose
//! residual cannot reach the current extreme within `Σ|Jᵢⱼ|Δ` is left out; this is exact), so
//! each LP has a few dozen rows near convergence whatever the number of points.
//!
//! The problems are not convex (except the circumscribed circle and sphere): the iteration
//! starts from the least-squares element and finds the zone nearest to it, which is the global
//! one for measured form (deviations small against the size). The tests check this against an
//! exhaustive search over all support sets.
//!
//! Circles follow the contract: the plane is the least-squares plane of the points, the
//! residuals are the in-plane radial deviations of the points projected into it.

use crate::lp::{self, Row, MAXD};
use crate::moments::Moments;
use crate::{canonical as canonical_dir, FitError};
use truepos_math::{any_perpendicular, Point3, Vector3};

/// Which Chebyshev element to compute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Criterion {
    /// Minimum zone: the two concentric (coaxial, parallel) surfaces closest together that
    /// hold every point.
    MinimumZone,
    /// Maximum inscribed: the largest element with every point on or outside it.
    MaximumInscribed,
    /// Minimum circumscribed: the smallest element with every point on or inside it.
    MinimumCircumscribed,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Objective {
    /// min (max r − min r)
    Zone,
    /// min max r
    Outer,
    /// max min r
    Inner,
}

impl From<Criterion> for Objective {
    fn from(c: Criterion) -> Self {
        match c {
            Criterion::MinimumZone => Objective::Zone,
            Criterion::MaximumInscribed => Objective::Inner,
            Criterion::MinimumCircumscribed => Objective::Outer,
        }
    }
}

/// A model: residual of a (scaled, centred) point at a state, and its gradient with respect
/// to the local step.
trait Cheb {
    type State: Clone;
    fn k(&self) -> usize;
    fn eval(&self, s: &Self::State, q: &Point3, j: &mut [f64; 4]) -> f64;
    fn apply(&self, s: &Self::State, d: &[f64]) -> Self::State;
    /// How far the state has moved from the start (scaled units), to detect a runaway
    /// inscribed element (open data).
    fn moved(&self, s0: &Self::State, s: &Self::State) -> f64;
}

struct Outcome<S> {
    state: S,
    lo: f64,
    hi: f64,
    iterations: usize,
}

/// Iteration cap for the trust-region loop (convergence takes 5–30 steps).
const MAX_STEPS: usize = 500;

fn objective(o: Objective, lo: f64, hi: f64) -> f64 {
    match o {
        Objective::Zone => hi - lo,
        Objective::Outer => hi,
        Objective::Inner => -lo,
    }
}

fn range<M: Cheb>(m: &M, s: &M::State, q: &[Point3]) -> (f64, f64) {
    let mut j = [0.0; 4];
    q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let r = m.eval(s, p, &mut j);
        (lo.min(r), hi.max(r))
    })
}

/// Why the Chebyshev iteration failed (mapped to a [`FitError`] by the callers).
enum ChebFail {
    /// The inscribed element grows without bound (the points do not surround it).
    Unbounded,
    NotConverged,
}

fn solve<M: Cheb>(
    m: &M,
    o: Objective,
    q: &[Point3],
    s0: M::State,
    runaway: f64,
) -> Result<Outcome<M::State>, ChebFail> {
    let k = m.k();
    let (upper, lower) = match o {
        Objective::Zone => (true, true),
        Objective::Outer => (true, false),
        Objective::Inner => (false, true),
    };
    let nv = k + upper as usize + lower as usize;
    let ti = k;
    let si = k + upper as usize;
    let mut c = [0.0; MAXD];
    if upper {
        c[ti] = 1.0;
    }
    if lower {
        c[si] = -1.0;
    }
    let mut s = s0.clone();
    let (mut lo, mut hi) = range(m, &s, q);
    let mut f = objective(o, lo, hi);
    // Start with a box of the order of the zone (or of the residual spread).
    let mut delta = (0.1 * (hi - lo)).clamp(1e-9, 0.1);
    let mut res: Vec<(f64, [f64; 4])> = Vec::with_capacity(q.len());
    let (mut up, mut down): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    let mut fresh = true;
    for it in 1..=MAX_STEPS {
        if fresh {
            res.clear();
            res.extend(q.iter().map(|p| {
                let mut j = [0.0; 4];
                let r = m.eval(&s, p, &mut j);
                (r, j)
            }));
            fresh = false;
        }
        // Exact filter: point i can bound t (s) inside the box only if its residual can reach
        // the largest lower bound (smallest upper bound) of the extreme residual.
        let g = |j: &[f64; 4]| delta * j[..k].iter().map(|v| v.abs()).sum::<f64>();
        let (mut top, mut bot) = (f64::NEG_INFINITY, f64::INFINITY);
        for (r, j) in &res {
            let gi = g(j);
            top = top.max(r - gi);
            bot = bot.min(r + gi);
        }
        up.clear();
        down.clear();
        for (i, (r, j)) in res.iter().enumerate() {
            let gi = g(j);
            if upper && r + gi >= top {
                up.push(i);
            }
            if lower && r - gi <= bot {
                down.push(i);
            }
        }
        let row = |i: usize, is_up: bool| -> Row {
            let (r, j) = &res[i];
            let mut a = [0.0; MAXD];
            if is_up {
                a[..k].copy_from_slice(&j[..k]);
                a[ti] = -1.0;
                Row { a, b: -r }
            } else {
                for t in 0..k {
                    a[t] = -j[t];
                }
                a[si] = 1.0;
                Row { a, b: *r }
            }
        };
        let sol = solve_lp(nv, &c[..nv], k, delta, &up, &down, row).map_err(|_| ChebFail::NotConverged)?;
        let pred = f - sol.objective;
        let step = &sol.x[..k];
        let size = step.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        // Converged: the linear model predicts no decrease (to rounding of the scaled
        // residuals, ~1e-16) or the step is below rounding.
        if pred <= 1e-15 || size < 1e-15 {
            return Ok(Outcome { state: s, lo, hi, iterations: it });
        }
        let sn = m.apply(&s, step);
        let (lo_n, hi_n) = range(m, &sn, q);
        let fn_ = objective(o, lo_n, hi_n);
        if fn_ < f {
            let rho = (f - fn_) / pred;
            s = sn;
            lo = lo_n;
            hi = hi_n;
            f = fn_;
            fresh = true;
            if rho > 0.75 && size > 0.99 * delta {
                delta *= 2.0;
            } else if rho < 0.25 {
                delta *= 0.5;
            }
            if m.moved(&s0, &s) > runaway {
                return Err(ChebFail::Unbounded);
            }
        } else {
            delta = 0.25 * size;
            if delta < 1e-16 {
                return Ok(Outcome { state: s, lo, hi, iterations: it });
            }
        }
    }
    Err(ChebFail::NotConverged)
}

/// The linearised Chebyshev LP: rows `row(i, true)` for `i` in `up` (bounding the upper
/// extreme), `row(i, false)` for `i` in `lo`, and the box `|δⱼ| ≤ delta`, solved by constraint
/// generation: a working set of the box and, of each kind, the rows with the smallest
/// right-hand side (the extreme residuals, tightest at δ = 0); then the most violated of the
/// others are added until none is violated. The optimum of a subset that satisfies every row
/// is the optimum of the whole LP, so this is exact; each simplex has a few dozen rows however
/// many points there are, and no row is built for a point that never enters.
fn solve_lp(
    nv: usize,
    c: &[f64],
    k: usize,
    delta: f64,
    up: &[usize],
    lo: &[usize],
    row: impl Fn(usize, bool) -> Row,
) -> Result<lp::LpSolution, lp::LpError> {
    const START: usize = 16;
    const ADD: usize = 16;
    let mut work: Vec<Row> = Vec::new();
    for t in 0..k {
        let mut a = [0.0; MAXD];
        a[t] = 1.0;
        work.push(Row { a, b: delta });
        a[t] = -1.0;
        work.push(Row { a, b: delta });
    }
    let mut in_up = vec![false; up.len()];
    let mut in_lo = vec![false; lo.len()];
    for (list, flags, is_up) in [(up, &mut in_up, true), (lo, &mut in_lo, false)] {
        let mut idx: Vec<usize> = (0..list.len()).collect();
        if idx.len() > START {
            idx.select_nth_unstable_by(START, |&a, &b| {
                row(list[a], is_up).b.total_cmp(&row(list[b], is_up).b)
            });
            idx.truncate(START);
        }
        for p in idx {
            flags[p] = true;
            work.push(row(list[p], is_up));
        }
    }
    loop {
        let sol = lp::minimise(nv, c, &work)?;
        let mut viol: Vec<(f64, usize, bool)> = Vec::new();
        for (list, flags, is_up) in [(up, &in_up, true), (lo, &in_lo, false)] {
            for (p, &i) in list.iter().enumerate() {
                if flags[p] {
                    continue;
                }
                let r = row(i, is_up);
                let ax: f64 = (0..nv).map(|t| r.a[t] * sol.x[t]).sum();
                let v = ax - r.b;
                if v > lp::TOL * (1.0 + r.b.abs()) {
                    viol.push((v, p, is_up));
                }
            }
        }
        if viol.is_empty() {
            return Ok(sol);
        }
        if viol.len() > ADD {
            viol.select_nth_unstable_by(ADD, |a, b| b.0.total_cmp(&a.0));
            viol.truncate(ADD);
        }
        for (_, p, is_up) in viol {
            if is_up {
                in_up[p] = true;
                work.push(row(up[p], true));
            } else {
                in_lo[p] = true;
                work.push(row(lo[p], false));
            }
        }
    }
}

/// Points centred on the centroid and divided by the extent (entries of order 1 for the LP).
fn scaled(points: &[Point3], m: &Moments) -> (Vec<Point3>, f64) {
    let l = m.extent().max(1e-300);
    (points.iter().map(|p| Point3::from((p - m.centroid) / l)).collect(), l)
}

fn fail(kind: &'static str, e: ChebFail) -> FitError {
    match e {
        ChebFail::Unbounded => FitError::InscribedUnbounded { kind },
        ChebFail::NotConverged => FitError::Undetermined { kind },
    }
}

// ---------------------------------------------------------------------------------------------
// Plane

struct PlaneModel;
#[derive(Clone)]
struct Basis {
    u: Vector3,
    v: Vector3,
    n: Vector3,
}
impl Basis {
    fn new(n: Vector3) -> Basis {
        let n = n.normalize();
        let u = any_perpendicular(&n);
        Basis { u, v: n.cross(&u), n }
    }
    fn tilted(&self, a: f64, b: f64) -> Basis {
        let n = (self.n + self.u * a + self.v * b).normalize();
        let u = (self.u - n * self.u.dot(&n)).normalize();
        Basis { u, v: n.cross(&u), n }
    }
}
impl Cheb for PlaneModel {
    type State = Basis;
    fn k(&self) -> usize {
        2
    }
    #[inline]
    fn eval(&self, s: &Basis, q: &Point3, j: &mut [f64; 4]) -> f64 {
        j[0] = q.coords.dot(&s.u);
        j[1] = q.coords.dot(&s.v);
        q.coords.dot(&s.n)
    }
    fn apply(&self, s: &Basis, d: &[f64]) -> Basis {
        s.tilted(d[0], d[1])
    }
    fn moved(&self, _: &Basis, _: &Basis) -> f64 {
        0.0
    }
}

/// Minimum-zone plane (flatness).
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneZone {
    /// The centroid projected onto the mid-plane of the zone.
    pub point: Point3,
    /// Unit normal (sign: largest component positive).
    pub normal: Vector3,
    /// Width of the zone (distance between the two parallel planes), mm.
    pub form: f64,
    /// RMS orthogonal distance from the mid-plane, mm.
    pub rms: f64,
    /// Largest absolute orthogonal distance from the mid-plane (half the zone width), mm.
    pub max_abs_residual: f64,
    /// Number of points.
    pub n_points: usize,
    /// Iterations of the Chebyshev solver.
    pub iterations: usize,
}

/// Minimum-zone plane: the two parallel planes closest together that hold every point.
pub fn plane_zone(points: &[Point3]) -> Result<PlaneZone, FitError> {
    let ls = crate::plane(points)?;
    let m = Moments::of(points)?;
    let (q, l) = scaled(points, &m);
    let out = solve(&PlaneModel, Objective::Zone, &q, Basis::new(ls.normal), f64::INFINITY)
        .map_err(|e| fail("plane", e))?;
    let normal = canonical_dir(out.state.n);
    let sign = if normal.dot(&out.state.n) < 0.0 { -1.0 } else { 1.0 };
    let mid = 0.5 * (out.lo + out.hi) * l;
    let point = m.centroid + out.state.n * mid;
    let (ssr, max_abs) = crate::ssr_max(points, |p| (p - point).dot(&normal) * sign);
    Ok(PlaneZone {
        point,
        normal,
        form: (out.hi - out.lo) * l,
        rms: (ssr / points.len() as f64).sqrt(),
        max_abs_residual: max_abs,
        n_points: points.len(),
        iterations: out.iterations,
    })
}

// ---------------------------------------------------------------------------------------------
// Line, cylinder: distance from an axis

#[derive(Clone)]
struct Axis {
    o: Point3,
    b: Basis,
}
struct AxisModel;
impl Cheb for AxisModel {
    type State = Axis;
    fn k(&self) -> usize {
        4
    }
    #[inline]
    fn eval(&self, s: &Axis, q: &Point3, j: &mut [f64; 4]) -> f64 {
        let d = q - s.o;
        let (x, y, z) = (d.dot(&s.b.u), d.dot(&s.b.v), d.dot(&s.b.n));
        let rho = x.hypot(y);
        if rho > 1e-300 {
            let (cx, cy) = (x / rho, y / rho);
            *j = [-cx, -cy, -cx * z, -cy * z];
        } else {
            *j = [0.0; 4];
        }
        rho
    }
    fn apply(&self, s: &Axis, d: &[f64]) -> Axis {
        let o = s.o + s.b.u * d[0] + s.b.v * d[1];
        let b = s.b.tilted(d[2], d[3]);
        // Keep the origin at the axis point nearest the centroid (the scaled origin).
        let t = (-o.coords).dot(&b.n);
        Axis { o: o + b.n * t, b }
    }
    fn moved(&self, s0: &Axis, s: &Axis) -> f64 {
        (s.o - s0.o).norm()
    }
}

/// Minimum-zone line (straightness in space): the smallest cylinder holding every point.
#[derive(Clone, Debug, PartialEq)]
pub struct LineZone {
    /// The point on the axis nearest the centroid.
    pub point: Point3,
    /// Unit direction (sign: largest component positive).
    pub direction: Vector3,
    /// Diameter of the smallest cylinder holding every point, mm.
    pub form: f64,
    /// RMS distance from the line, mm.
    pub rms: f64,
    /// Largest distance from the line (the cylinder's radius), mm.
    pub max_abs_residual: f64,
    /// Number of points.
    pub n_points: usize,
    /// Iterations of the Chebyshev solver.
    pub iterations: usize,
}

/// Minimum-zone line: the axis of the smallest cylinder that holds every point.
pub fn line_zone(points: &[Point3]) -> Result<LineZone, FitError> {
    let ls = crate::line(points)?;
    let m = Moments::of(points)?;
    let (q, l) = scaled(points, &m);
    let s0 = Axis { o: Point3::origin(), b: Basis::new(ls.direction) };
    let out = solve(&AxisModel, Objective::Outer, &q, s0, f64::INFINITY).map_err(|e| fail("line", e))?;
    let point = m.centroid + out.state.o.coords * l;
    let direction = canonical_dir(out.state.b.n);
    let (ssr, max_abs) = crate::ssr_max(points, |p| {
        let v = p - point;
        (v - direction * v.dot(&direction)).norm()
    });
    Ok(LineZone {
        point,
        direction,
        form: 2.0 * out.hi * l,
        rms: (ssr / points.len() as f64).sqrt(),
        max_abs_residual: max_abs,
        n_points: points.len(),
        iterations: out.iterations,
    })
}

/// A Chebyshev cylinder (minimum zone, maximum inscribed or minimum circumscribed).
#[derive(Clone, Debug, PartialEq)]
pub struct CylinderZone {
    /// Which Chebyshev criterion this cylinder satisfies.
    pub criterion: Criterion,
    /// The point on the axis nearest the centroid.
    pub point: Point3,
    /// Unit axis (sign: largest component positive).
    pub axis: Vector3,
    /// Minimum zone: the mean of the two zone radii; inscribed/circumscribed: that radius, mm.
    pub radius: f64,
    /// Smallest distance of a point from the axis, mm.
    pub inner_radius: f64,
    /// Largest distance of a point from the axis, mm.
    pub outer_radius: f64,
    /// Cylindricity about this axis: `outer_radius − inner_radius`, mm.
    pub form: f64,
    /// RMS of `distance − radius`, mm.
    pub rms: f64,
    /// Largest absolute value of `distance − radius`, mm.
    pub max_abs_residual: f64,
    /// Number of points.
    pub n_points: usize,
    /// Iterations of the Chebyshev solver.
    pub iterations: usize,
}

/// Chebyshev cylinder by `criterion`, started from the least-squares cylinder.
pub fn cylinder_fit(points: &[Point3], criterion: Criterion) -> Result<CylinderZone, FitError> {
    let ls = crate::cylinder(points)?;
    cylinder_fit_from(points, criterion, (ls.point, ls.axis, ls.radius))
}

/// [`cylinder_fit`] from a given least-squares cylinder `(point, axis, radius)` instead of the
/// free least-squares fit: for a caller that knows which cylinder the points are (a nominal
/// feature's axis chose it), where the points alone may not decide (8 points on two levels of a
/// bore also lie on a cylinder across them).
pub fn cylinder_fit_from(
    points: &[Point3],
    criterion: Criterion,
    (ls_point, ls_axis, ls_radius): (Point3, Vector3, f64),
) -> Result<CylinderZone, FitError> {
    let m = Moments::of(points)?;
    let (q, l) = scaled(points, &m);
    let s0 = Axis { o: Point3::from((ls_point - m.centroid) / l), b: Basis::new(ls_axis) };
    let out = solve(&AxisModel, criterion.into(), &q, s0, ls_radius / l).map_err(|e| fail("cylinder", e))?;
    let point = m.centroid + out.state.o.coords * l;
    let axis = canonical_dir(out.state.b.n);
    let (inner, outer) = (out.lo * l, out.hi * l);
    let radius = pick_radius(criterion, inner, outer);
    let (ssr, max_abs) = crate::ssr_max(points, |p| {
        let v = p - point;
        (v - axis * v.dot(&axis)).norm() - radius
    });
    Ok(CylinderZone {
        criterion,
        point,
        axis,
        radius,
        inner_radius: inner,
        outer_radius: outer,
        form: outer - inner,
        rms: (ssr / points.len() as f64).sqrt(),
        max_abs_residual: max_abs,
        n_points: points.len(),
        iterations: out.iterations,
    })
}

fn pick_radius(c: Criterion, inner: f64, outer: f64) -> f64 {
    match c {
        Criterion::MinimumZone => 0.5 * (inner + outer),
        Criterion::MaximumInscribed => inner,
        Criterion::MinimumCircumscribed => outer,
    }
}

// ---------------------------------------------------------------------------------------------
// Circle, sphere: distance from a centre

struct CentreModel {
    k: usize,
}
impl Cheb for CentreModel {
    type State = Point3;
    fn k(&self) -> usize {
        self.k
    }
    #[inline]
    fn eval(&self, c: &Point3, q: &Point3, j: &mut [f64; 4]) -> f64 {
        let d = q - c;
        let r = d.norm();
        if r > 1e-300 {
            *j = [-d.x / r, -d.y / r, -d.z / r, 0.0];
        } else {
            *j = [0.0; 4];
        }
        r
    }
    fn apply(&self, c: &Point3, d: &[f64]) -> Point3 {
        let mut n = *c;
        for t in 0..self.k {
            n[t] += d[t];
        }
        n
    }
    fn moved(&self, s0: &Point3, s: &Point3) -> f64 {
        (s - s0).norm()
    }
}

/// A Chebyshev sphere or circle.
#[derive(Clone, Debug, PartialEq)]
pub struct RoundZone {
    /// Which Chebyshev criterion this sphere or circle satisfies.
    pub criterion: Criterion,
    /// Centre, in the frame of the points, mm.
    pub center: Point3,
    /// Circles: the unit normal of the least-squares plane; spheres: zero.
    pub normal: Vector3,
    /// Minimum zone: the mean of the two zone radii; inscribed/circumscribed: that radius, mm.
    pub radius: f64,
    /// Smallest distance of a point from the centre (in-plane for circles), mm.
    pub inner_radius: f64,
    /// Largest distance of a point from the centre (in-plane for circles), mm.
    pub outer_radius: f64,
    /// Roundness / sphericity about this centre: `outer_radius − inner_radius`, mm.
    pub form: f64,
    /// RMS of `distance − radius` (in-plane for circles), mm.
    pub rms: f64,
    /// Largest absolute value of `distance − radius`, mm.
    pub max_abs_residual: f64,
    /// Number of points.
    pub n_points: usize,
    /// Iterations of the Chebyshev solver.
    pub iterations: usize,
}

fn round_result(
    criterion: Criterion,
    center: Point3,
    normal: Vector3,
    dists: impl Iterator<Item = f64>,
    out: &Outcome<Point3>,
    l: f64,
) -> RoundZone {
    let (inner, outer) = (out.lo * l, out.hi * l);
    let radius = pick_radius(criterion, inner, outer);
    let (mut ssr, mut max_abs, mut n) = (0.0, 0.0f64, 0usize);
    for d in dists {
        let r = d - radius;
        ssr += r * r;
        max_abs = max_abs.max(r.abs());
        n += 1;
    }
    RoundZone {
        criterion,
        center,
        normal,
        radius,
        inner_radius: inner,
        outer_radius: outer,
        form: outer - inner,
        rms: (ssr / n.max(1) as f64).sqrt(),
        max_abs_residual: max_abs,
        n_points: n,
        iterations: out.iterations,
    }
}

/// Chebyshev sphere by `criterion`, started from the least-squares sphere.
pub fn sphere_fit(points: &[Point3], criterion: Criterion) -> Result<RoundZone, FitError> {
    let ls = crate::sphere(points)?;
    let m = Moments::of(points)?;
    let (q, l) = scaled(points, &m);
    let c0 = Point3::from((ls.center - m.centroid) / l);
    let out = solve(&CentreModel { k: 3 }, criterion.into(), &q, c0, ls.radius / l)
        .map_err(|e| fail("sphere", e))?;
    let center = m.centroid + out.state.coords * l;
    let dists = points.iter().map(|p| (p - center).norm());
    Ok(round_result(criterion, center, Vector3::zeros(), dists, &out, l))
}

/// Chebyshev circle by `criterion` in the least-squares plane of the points (the points are
/// projected into it), started from the least-squares circle.
pub fn circle_fit(points: &[Point3], criterion: Criterion) -> Result<RoundZone, FitError> {
    let ls = crate::circle(points)?;
    let m = Moments::of(points)?;
    let l = m.extent().max(1e-300);
    let (u, v) = (m.axis(2), m.axis(1));
    let q: Vec<Point3> = points
        .iter()
        .map(|p| {
            let d = p - m.centroid;
            Point3::new(d.dot(&u) / l, d.dot(&v) / l, 0.0)
        })
        .collect();
    let dc = ls.center - m.centroid;
    let c0 = Point3::new(dc.dot(&u) / l, dc.dot(&v) / l, 0.0);
    let out = solve(&CentreModel { k: 2 }, criterion.into(), &q, c0, ls.radius / l)
        .map_err(|e| fail("circle", e))?;
    let c2 = out.state;
    let center = m.centroid + (u * c2.x + v * c2.y) * l;
    let dists = q.iter().map(|p| (p - c2).norm() * l);
    Ok(round_result(criterion, center, ls.normal, dists, &out, l))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(n: usize, r: f64, phase: f64) -> Vec<Point3> {
        (0..n)
            .map(|i| {
                let a = phase + i as f64 * std::f64::consts::TAU / n as f64;
                Point3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect()
    }

    #[test]
    fn two_concentric_circles_give_the_radius_difference() {
        let mut p = ring(36, 10.0, 0.0);
        p.extend(ring(36, 10.01, 0.05));
        let shift = Vector3::new(3.0, -2.0, 7.0);
        let p: Vec<Point3> = p.iter().map(|q| q + shift).collect();
        let z = circle_fit(&p, Criterion::MinimumZone).unwrap();
        assert!((z.form - 0.01).abs() < 1e-12, "{}", z.form);
        assert!((z.radius - 10.005).abs() < 1e-12);
        assert!((z.center - Point3::from(shift)).norm() < 1e-12);
        let i = circle_fit(&p, Criterion::MaximumInscribed).unwrap();
        assert!((i.radius - 10.0).abs() < 1e-12);
        let o = circle_fit(&p, Criterion::MinimumCircumscribed).unwrap();
        assert!((o.radius - 10.01).abs() < 1e-12);
    }

    #[test]
    fn open_arc_has_no_inscribed_circle() {
        let p: Vec<Point3> =
            (0..20).map(|i| Point3::new((i as f64 * 0.05).cos(), (i as f64 * 0.05).sin(), 0.0)).collect();
        assert!(matches!(
            circle_fit(&p, Criterion::MaximumInscribed),
            Err(FitError::InscribedUnbounded { .. })
        ));
        assert!(circle_fit(&p, Criterion::MinimumCircumscribed).is_ok());
    }
}
