//! Path planning: the blended style (no stops between the first approach and the last release)
//! and the classic style (pre-hit, stop, normal approach, search, scan, stop, retract), as a list
//! of time-parametrised [`Segment`]s.
//!
//! Entry points: [`plan`] (with [`Style`]), [`Plan::sample`] (the path at a fixed time step, for
//! `truepos scan plan`), [`Plan::stops`], [`Segment::eval`] (used by the executor).
//!
//! Geometry of the blended style for one feature (`N` outward normal, `T` scan tangent, `α` the
//! approach angle): the approach is the straight line into the nominal contact point `C0` (tip
//! touching the surface, no deflection) along `w = −cos α N + sin α T`, entered at scanning
//! speed; the settle path runs along the surface in the scan direction with a penetration
//! (commanded deflection) that starts with slope `cot α` (tangent-continuous with the approach),
//! rises to `deflection + overshoot` and falls back to `deflection` along a half cosine; the scan
//! holds `deflection`; the release lifts off with a cubic that reaches slope `−cot α` and then
//! climbs straight to the clearance; the transfer leaves the release with its velocity and
//! acceleration and enters the next approach at scanning speed along it, planned in velocity
//! space by [`crate::motion::transfer`] (the velocity vector moves on straight lines, each change
//! a jerk-limited S-curve, so |v|, |a| and |j| keep `move_speed`, `accel` and `jerk` by
//! construction; a curve-first quintic transfer checked on a dense grid is the fallback where
//! that family has no motion); the program ends with a straight jerk-limited stop. The settle
//! path lies *before* the scan start (for a line, on the extension of the line before
//! `start_mm`), so the scan covers the whole requested path.
//!
//! The classic style runs every positioning move as a rest-to-rest S-curve on a straight line.

use crate::feature::{Feature, Params};
use crate::motion::{self, Limits, Motion};
use truepos_math::{Point3, Vector3};

/// The segment tags of the contract.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SegmentKind {
    /// A move between features, off the surface.
    Transfer,
    /// From the clearance position to first contact.
    Approach,
    /// From contact until the deflection is on target.
    Settle,
    /// The measuring part of the feature.
    Scan,
    /// From the scan's end off the surface.
    Release,
}

impl SegmentKind {
    /// The segment tag as the contract spells it (`transfer`, `approach`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            SegmentKind::Transfer => "transfer",
            SegmentKind::Approach => "approach",
            SegmentKind::Settle => "settle",
            SegmentKind::Scan => "scan",
            SegmentKind::Release => "release",
        }
    }
}

/// Planning style (`truepos scan --style`; the variants' documentation is the command line's
/// help for each value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Style {
    /// Approach at an angle at scanning speed, settle path, scan, release, straight on: no stops.
    Blended,
    /// Pre-hit point on the normal, stop, approach along the normal, search, scan, stop, retract.
    Classic,
}

impl Style {
    /// The name used in files, JSON and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Style::Blended => "blended",
            Style::Classic => "classic",
        }
    }
}

/// Commanded penetration (deflection) along a surface-following segment, as a function of the
/// tangential distance `x` (mm) from the segment start.
#[derive(Clone, Debug, PartialEq)]
pub enum Penetration {
    /// A constant penetration, mm.
    Const(f64),
    /// `s0·x − ½·peak·(x/x1)³` up to `x1` (reaching `peak` with zero slope), then a half cosine
    /// from `peak` down to `end` at `len`.
    Settle {
        /// Initial slope (penetration per tangential mm).
        s0: f64,
        /// Peak penetration, mm.
        peak: f64,
        /// Where the peak is reached, mm.
        x1: f64,
        /// Penetration at the end, mm.
        end: f64,
        /// Length of the profile, mm.
        len: f64,
    },
    /// `d − k·x³` up to `xr` (slope −`c` there), then straight with slope −`c`.
    Release {
        /// Penetration at the start, mm.
        d: f64,
        /// Cubic coefficient, mm⁻².
        k: f64,
        /// End of the cubic part, mm.
        xr: f64,
        /// Slope of the straight part (penetration lost per tangential mm).
        c: f64,
    },
}

impl Penetration {
    /// The penetration at tangential distance `x` from the segment start, mm.
    pub fn at(&self, x: f64) -> f64 {
        match *self {
            Penetration::Const(d) => d,
            Penetration::Settle { s0, peak, x1, end, len } => {
                if x <= x1 {
                    s0 * x - 0.5 * peak * (x / x1).powi(3)
                } else {
                    let f = ((x - x1) / (len - x1)).clamp(0.0, 1.0);
                    end + (peak - end) * 0.5 * (1.0 + (std::f64::consts::PI * f).cos())
                }
            }
            Penetration::Release { d, k, xr, c } => {
                if x <= xr {
                    d - k * x.powi(3)
                } else {
                    d - k * xr.powi(3) - c * (x - xr)
                }
            }
        }
    }
}

/// The geometric carrier of a segment, parametrised by `λ ∈ [0, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub enum Geom {
    /// A straight line from `a` to `b`.
    Line {
        /// Start, machine frame, mm.
        a: Point3,
        /// End, machine frame, mm.
        b: Point3,
    },
    /// Quintic Hermite: end points, end derivatives dP/dλ and end second derivatives d²P/dλ².
    Quintic {
        /// End points, machine frame, mm.
        p: [Point3; 2],
        /// End derivatives dP/dλ, mm.
        m: [Vector3; 2],
        /// End second derivatives d²P/dλ², mm.
        c: [Vector3; 2],
    },
    /// Along the segment's feature from `u0` to `u1` (see [`Feature::point`]); `x_len` is the
    /// tangential length over which the penetration profile is evaluated.
    Along {
        /// Feature parameter at the start.
        u0: f64,
        /// Feature parameter at the end.
        u1: f64,
        /// The commanded penetration along the segment.
        pen: Penetration,
        /// Tangential length the penetration is evaluated over, mm.
        x_len: f64,
    },
    /// Standing still.
    Hold {
        /// Where, machine frame, mm.
        p: Point3,
    },
    /// A motion given directly in time (phases of constant jerk vector; see [`crate::motion`]):
    /// the blended transfers and the final stop. Its duration is the motion's.
    Timed {
        /// The motion.
        motion: Motion,
    },
}

/// Speed profile over a length: phases of constant jerk (an S-curve for every speed change, each
/// change starting and ending with zero acceleration), or a constant speed.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// (start time, s, v, a, jerk) at the start of each phase; the last row is the end state.
    phases: Vec<[f64; 5]>,
    /// Length covered, mm.
    pub len: f64,
    /// Speed at the start, mm/s.
    pub v0: f64,
    /// Speed at the end, mm/s.
    pub v1: f64,
}

/// Distance of the S-curve speed change of [`change`] (without building its phases).
fn change_dist(va: f64, vb: f64, a: f64, j: f64) -> f64 {
    let d = (vb - va).abs();
    if d <= 1e-12 {
        return 0.0;
    }
    let t = if d >= a * a / j { d / a + a / j } else { 2.0 * (d / j).sqrt() };
    0.5 * (va + vb) * t
}

/// Phases (duration, jerk) and distance of an S-curve speed change from `va` to `vb` with
/// |a| ≤ `a`, |jerk| ≤ `j`, from zero acceleration to zero acceleration.
fn change(va: f64, vb: f64, a: f64, j: f64) -> (Vec<(f64, f64)>, f64) {
    let d = (vb - va).abs();
    if d <= 1e-12 {
        return (vec![], 0.0);
    }
    let sg = (vb - va).signum();
    let (ph, t) = if d >= a * a / j {
        (vec![(a / j, sg * j), (d / a - a / j, 0.0), (a / j, -sg * j)], d / a + a / j)
    } else {
        let t1 = (d / j).sqrt();
        (vec![(t1, sg * j), (t1, -sg * j)], 2.0 * t1)
    };
    (ph, 0.5 * (va + vb) * t)
}

impl Profile {
    /// Constant speed `v` over `len` (a zero-length profile when `len` is 0).
    pub fn constant(len: f64, v: f64) -> Profile {
        let len = len.max(0.0);
        let t = if len > 0.0 && v > 0.0 { len / v } else { 0.0 };
        let len = if t > 0.0 { len } else { 0.0 };
        Profile { phases: vec![[0.0, 0.0, v, 0.0, 0.0], [t, len, v, 0.0, 0.0]], len, v0: v, v1: v }
    }

    /// From `v0` through a plateau at exactly `vp` to `v1` (S-curves with |a| ≤ `a`,
    /// |jerk| ≤ `j`); `None` when the changes do not fit in `len`.
    pub fn with_peak(len: f64, v0: f64, vp: f64, v1: f64, a: f64, j: f64) -> Option<Profile> {
        let (up, d_up) = change(v0, vp, a, j);
        let (down, d_down) = change(vp, v1, a, j);
        let rest = len - d_up - d_down;
        if rest < -1e-9 * len.max(1.0) {
            return None;
        }
        let rest = rest.max(0.0);
        if rest > 1e-12 && vp <= 1e-12 {
            return None;
        }
        let mut phases = up;
        if rest > 1e-12 {
            phases.push((rest / vp, 0.0));
        }
        phases.extend(down);
        let mut pr = from_phases(len, v0, v1, &phases);
        // the changes end exactly at `v1` with zero acceleration: the end row says so, free of
        // the integration's rounding
        if let Some(r) = pr.phases.last_mut() {
            r[2] = v1;
            r[3] = 0.0;
        }
        Some(pr)
    }

    /// Jerk-limited profile over `len` from `v0` to `v1` through the highest plateau ≤ `vmax`
    /// that fits (a bisection of 60 steps on closed-form distances). When `len` is too short to
    /// join `v0` and `v1` at these limits, both limits are raised together just enough (the
    /// change's distance scales as 1/s when `a → s·a`, `j → s²·j`; never needed by the
    /// planner's own moves, which are long enough by construction).
    pub fn s_curve(len: f64, v0: f64, vmax: f64, v1: f64, a: f64, j: f64) -> Profile {
        let len = len.max(0.0);
        if len <= 1e-12 {
            return Profile::constant(0.0, v0);
        }
        let (mut a, mut j) = (a, j);
        let need = change_dist(v0, v1, a, j);
        if need > len {
            let s = need / len * (1.0 + 1e-9);
            a *= s;
            j *= s * s;
        }
        let fits = |vp: f64| change_dist(v0, vp, a, j) + change_dist(vp, v1, a, j) <= len;
        let lo = v0.max(v1);
        let hi = vmax.max(lo);
        if fits(hi) {
            if let Some(p) = Profile::with_peak(len, v0, hi, v1, a, j) {
                return p;
            }
        }
        let (mut l, mut h) = (lo, hi);
        for _ in 0..60 {
            let m = 0.5 * (l + h);
            if fits(m) {
                l = m;
            } else {
                h = m;
            }
        }
        // `l > 0` whenever `len > 0` (any small plateau fits), so the plateau is never empty
        Profile::with_peak(len, v0, l, v1, a, j)
            .or_else(|| Profile::with_peak(len, v0, l, v1, a * 1.001, j * 1.002))
            .unwrap_or_else(|| Profile::constant(len, l.max(1e-9)))
    }

    /// Duration of the profile, s.
    pub fn duration(&self) -> f64 {
        self.phases.last().map_or(0.0, |r| r[0])
    }

    /// Distance, speed, tangential acceleration and jerk at time `t` from the start.
    pub fn state(&self, t: f64) -> [f64; 4] {
        if self.len == 0.0 {
            return [0.0, self.v0, 0.0, 0.0];
        }
        let t = t.clamp(0.0, self.duration());
        let n = self.phases.len();
        let i = self.phases.partition_point(|r| r[0] <= t).clamp(1, n) - 1;
        let [t0, x, v, a, j] = self.phases[i];
        let tau = t - t0;
        let s = x + v * tau + 0.5 * a * tau * tau + j * tau * tau * tau / 6.0;
        [s.clamp(0.0, self.len), v + a * tau + 0.5 * j * tau * tau, a + j * tau, j]
    }

    /// Distance and speed at time `t` from the start.
    pub fn at(&self, t: f64) -> (f64, f64) {
        let [s, v, _, _] = self.state(t);
        (s, v)
    }
}

/// One planned segment.
#[derive(Clone, Debug)]
pub struct Segment {
    /// What the segment is for.
    pub kind: SegmentKind,
    /// Index of the feature it belongs to (a transfer belongs to the feature it leads to).
    pub feature: usize,
    /// Its geometric carrier.
    pub geom: Geom,
    /// Its speed profile.
    pub profile: Profile,
    /// Duration of a [`Geom::Hold`] (nominal, for the classic settle the executor extends it
    /// until the deflection has settled).
    pub hold: f64,
    /// Probe feedback (observer) on (from local time `feedback_after`).
    pub feedback: bool,
    /// Segment-local time from which probe feedback is on, s.
    pub feedback_after: f64,
    /// For approaches: the segment-local time at which the nominal contact point is passed.
    pub contact_time: Option<f64>,
    /// Classic settle: wait until the deflection has settled.
    pub wait_settled: bool,
    /// Surface point and outward normal for segments that are not [`Geom::Along`] (approach
    /// target, classic retract): the target deflection is the penetration of this plane.
    pub plane: Option<(Point3, Vector3)>,
    /// Arc length of the carrier at `ARC_N + 1` equal steps of λ (Gauss–Legendre), for the
    /// smooth inverse λ(s); empty for carriers run at a constant rate (lines, constant offsets).
    arc: Vec<f64>,
    /// Carrier length (mm).
    len: f64,
}

/// What a segment commands at a local time.
#[derive(Clone, Copy, Debug)]
pub struct Command {
    /// Commanded position, machine frame, mm.
    pub position: Point3,
    /// Commanded path speed, mm/s.
    pub speed: f64,
    /// Outward surface normal (for feedback and missed-surface shifts), if any.
    pub normal: Option<Vector3>,
    /// Planned stylus deflection.
    pub deflection: f64,
}

/// λ steps of the arc-length table.
const ARC_N: usize = 64;
/// Gauss–Legendre nodes and weights (5 points on [−1, 1]).
const GL: [(f64, f64); 5] = [
    (0.0, 0.568_888_888_888_888_9),
    (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (0.906_179_845_938_664, 0.236_926_885_056_189_1),
    (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
];
/// Arc-length steps of the curvature grid of a curved move.
const GRID_N: usize = 512;
/// Share of the limits the planner's own check allows (the rest absorbs interpolation between
/// its samples and grid points).
const MARGIN: f64 = 0.95;

/// Power-basis coefficients of a quintic Hermite curve.
fn quintic_coeffs(p: &[Point3; 2], m: &[Vector3; 2], c: &[Vector3; 2]) -> [Vector3; 6] {
    let (p0, p1) = (p[0].coords, p[1].coords);
    [
        p0,
        m[0],
        c[0] * 0.5,
        -p0 * 10.0 - m[0] * 6.0 - c[0] * 1.5 + c[1] * 0.5 - m[1] * 4.0 + p1 * 10.0,
        p0 * 15.0 + m[0] * 8.0 + c[0] * 1.5 - c[1] + m[1] * 7.0 - p1 * 15.0,
        -p0 * 6.0 - m[0] * 3.0 - c[0] * 0.5 + c[1] * 0.5 - m[1] * 3.0 + p1 * 6.0,
    ]
}

/// Unit tangent, curvature vector and its arc-length derivative along a curved move, on an
/// equal arc-length grid.
struct CurveGrid {
    ds: f64,
    tan: Vec<Vector3>,
    k: Vec<Vector3>,
    dk: Vec<Vector3>,
}

impl CurveGrid {
    fn at(&self, s: f64) -> (Vector3, Vector3, Vector3) {
        let n = self.tan.len() - 1;
        let x = (s / self.ds).clamp(0.0, n as f64);
        let i = (x.floor() as usize).min(n - 1);
        let f = x - i as f64;
        let lerp = |v: &Vec<Vector3>| v[i] + (v[i + 1] - v[i]) * f;
        (lerp(&self.tan), lerp(&self.k), lerp(&self.dk))
    }

    /// Whether `pr` keeps |v| ≤ `vmax`, |a| ≤ `a` and |jerk| ≤ `j` along the curve (with
    /// [`MARGIN`]): a = a_t·T + v²·K, jerk = j_t·T + 3·v·a_t·K + v³·dK/ds (K the curvature
    /// vector), on a dense time grid that includes every phase boundary.
    fn admits(&self, pr: &Profile, vmax: f64, a: f64, j: f64) -> bool {
        self.violation(pr, vmax, a, j).is_none()
    }

    /// The distance along the curve of the first sample where `pr` breaks a limit.
    fn violation(&self, pr: &Profile, vmax: f64, a: f64, j: f64) -> Option<f64> {
        let dur = pr.duration();
        // 1 ms, or one grid step at the profile's top speed when that is shorter (a fast move
        // passes the curvature's narrow peaks between 1 ms samples)
        let vtop = pr.phases.iter().map(|r| r[2]).fold(pr.v0.max(pr.v1), f64::max);
        let step = if vtop > 0.0 { (self.ds / vtop).min(1e-3) } else { 1e-3 };
        let n = ((dur / step).ceil() as usize).clamp(200, 40_000);
        let mut times: Vec<f64> = (0..=n).map(|k| dur * k as f64 / n as f64).collect();
        for r in &pr.phases {
            times.push(r[0]);
            times.push((r[0] - 1e-9).max(0.0));
        }
        times.sort_by(f64::total_cmp);
        times.into_iter().find_map(|t| {
            let [s, v, at, jt] = pr.state(t);
            let (tn, k, dk) = self.at(s);
            let acc = tn * at + k * (v * v);
            let jerk = tn * jt + k * (3.0 * v * at) + dk * (v * v * v);
            let ok = v <= vmax * (1.0 + 1e-9) && acc.norm() <= MARGIN * a && jerk.norm() <= MARGIN * j;
            (!ok).then_some(s)
        })
    }

    /// Speed cap from the curve alone at grid point `i` (lateral acceleration v²|K| and the
    /// jerk terms v³(|K|² + |dK/ds|) within shares of the limits).
    fn cap(&self, i: usize, a: f64, j: f64) -> f64 {
        let k = self.k[i].norm();
        let q = k * k + self.dk[i].norm();
        let ca = if k > 1e-12 { (0.8 * a / k).sqrt() } else { f64::INFINITY };
        let cj = if q > 1e-12 { (0.4 * j / q).cbrt() } else { f64::INFINITY };
        ca.min(cj)
    }
}

/// The S-curve along a path of constant curvature `k` (1/mm; a circle, or a line with `k = 0`)
/// in closed form. With the unit tangent `T` and normal `N`, `a = a_t·T + v²k·N` and
/// `jerk = (j_t − v³k²)·T + 3·v·a_t·k·N`; the plateau is capped so that `v²k ≤ 0.6·a` and
/// `v³k² ≤ 0.25·j`, and the tangential limits are what is left of [`MARGIN`]·a and
/// [`MARGIN`]·j at that plateau speed (the largest `v` of the move, so they hold throughout):
/// `a_t ≤ √((0.95a)² − (v²k)²)` and `3·v·a_t·k ≤ 0.5·j`, then
/// `j_t ≤ √((0.95j)² − (3·v·a_t·k)²) − v³k²`.
fn circle_profile(len: f64, (v0, vmax, v1): (f64, f64, f64), k: f64, a: f64, j: f64) -> Profile {
    if k <= 1e-12 {
        return Profile::s_curve(len, v0, vmax, v1, a, j);
    }
    let vp = vmax.min((0.6 * a / k).sqrt()).min((0.25 * j / (k * k)).cbrt()).max(v0.max(v1));
    let (am, jm) = (MARGIN * a, MARGIN * j);
    let cent = vp * vp * k;
    let mut at = (am * am - cent * cent).max(0.0).sqrt();
    if vp > 0.0 {
        at = at.min(0.5 * j / (3.0 * vp * k));
    }
    let lat = 3.0 * vp * at * k;
    let jt = ((jm * jm - lat * lat).max(0.0).sqrt() - vp.powi(3) * k * k).max(1e-3 * j);
    Profile::s_curve(len, v0, vp, v1, at.max(1e-3 * a), jt)
}

/// Profiles run one after the other (each ends at the speed the next starts with).
fn concat(parts: &[Profile]) -> Profile {
    let mut rows = Vec::new();
    let (mut t, mut x) = (0.0, 0.0);
    for pr in parts {
        for r in &pr.phases[..pr.phases.len() - 1] {
            rows.push([r[0] + t, r[1] + x, r[2], r[3], r[4]]);
        }
        t += pr.duration();
        x += pr.len;
    }
    let v1 = parts.last().map_or(0.0, |p| p.v1);
    rows.push([t, x, v1, 0.0, 0.0]);
    Profile { phases: rows, len: x, v0: parts.first().map_or(0.0, |p| p.v0), v1 }
}

/// A transfer that turns near its ends and runs nearly straight in between: the first and last
/// share `end` of the length at a bend speed `u`, the middle through the highest plateau that fits
/// (tangential limits 0.8·a, 0.8·j); the highest `u` the full check admits (12 steps down from
/// `vmax`, then 8 bisection steps).
fn three_level(
    g: &CurveGrid,
    len: f64,
    (v0, vmax, v1): (f64, f64, f64),
    vlo: f64,
    (a, j): (f64, f64),
    (end, early): (f64, bool),
) -> Option<Profile> {
    let (at, jt) = (0.8 * a, 0.8 * j);
    let (l1, l2) = (end * len, (1.0 - 2.0 * end) * len);
    // `early`: into the bend speed right away and out of it only at the very end (where the
    // transfer straightens into the approach); otherwise each end part keeps the faster of its
    // two speeds as long as it can
    let build = |u: f64| {
        let ends = if early {
            (Profile::with_peak(l1, v0, u, u, at, jt)?, Profile::with_peak(l1, u, u, v1, at, jt)?)
        } else {
            (Profile::s_curve(l1, v0, u, u, at, jt), Profile::s_curve(l1, u, u, v1, at, jt))
        };
        Some(concat(&[ends.0, Profile::s_curve(l2, u, vmax, u, at, jt), ends.1]))
    };
    let ok = |u: f64| build(u).filter(|pr| g.admits(pr, vmax, a, j));
    let steps = 12;
    let mut prev_bad = None;
    for k in 0..=steps {
        let u = vmax - (vmax - vlo) * k as f64 / steps as f64;
        if let Some(pr) = ok(u) {
            let (mut l, mut best) = (u, pr);
            if let Some(mut h) = prev_bad {
                for _ in 0..8 {
                    let m = 0.5 * (l + h);
                    match ok(m) {
                        Some(p) => {
                            best = p;
                            l = m;
                        }
                        None => h = m,
                    }
                }
            }
            return Some(best);
        }
        prev_bad = Some(u);
    }
    None
}

/// Profile from (duration, jerk) phases starting at `v0` with zero acceleration.
fn from_phases(len: f64, v0: f64, v1: f64, phases: &[(f64, f64)]) -> Profile {
    let mut rows = Vec::with_capacity(phases.len() + 1);
    let (mut t, mut x, mut v, mut acc) = (0.0, 0.0, v0, 0.0);
    for &(dt, jk) in phases {
        if dt <= 0.0 {
            continue;
        }
        rows.push([t, x, v, acc, jk]);
        x += v * dt + 0.5 * acc * dt * dt + jk * dt * dt * dt / 6.0;
        v += acc * dt + 0.5 * jk * dt * dt;
        acc += jk * dt;
        t += dt;
    }
    rows.push([t, x, v, acc, 0.0]);
    Profile { phases: rows, len, v0, v1 }
}

/// A profile of plateaus along a curve: the curve is cut into windows of about 3 mm, each run
/// at one speed no higher than its curvature allows; every change between neighbouring
/// plateaus is an S-curve (tangential limits 0.6·a, 0.5·j, lower if needed) inside the faster window, and a
/// window too short for its changes is slowed until they fit. Where the full check still finds
/// the limits broken, that window's speed is lowered by 15 % and the profile rebuilt.
fn plateau_profile(
    g: &CurveGrid,
    len: f64,
    speeds: (f64, f64, f64),
    floor: f64,
    a: f64,
    j: f64,
) -> Option<Profile> {
    // in a tight turn the tangential acceleration couples into the jerk (3·v·a_t·|K|): gentler
    // speed changes when the bolder ones cannot keep the limits
    [(0.6, 0.5), (0.3, 0.25), (0.12, 0.1), (0.05, 0.04)]
        .into_iter()
        .find_map(|(sa, sj)| plateaus(g, len, speeds, floor, (a, j), (sa * a, sj * j)))
}

fn plateaus(
    g: &CurveGrid,
    len: f64,
    (v0, vmax, v1): (f64, f64, f64),
    floor: f64,
    (a, j): (f64, f64),
    (at, jt): (f64, f64),
) -> Option<Profile> {
    let nw = ((len / 3.0).round() as usize).clamp(1, 64);
    let lw = len / nw as f64;
    let ng = g.k.len() - 1;
    let mut cap: Vec<f64> = (0..nw)
        .map(|w| {
            let i0 = ((w as f64 * lw / g.ds).floor() as usize).saturating_sub(2);
            let i1 = (((w + 1) as f64 * lw / g.ds).ceil() as usize + 2).min(ng);
            (i0..=i1).map(|i| g.cap(i, a, j)).fold(vmax, f64::min).max(floor)
        })
        .collect();
    let dist = |x: f64, y: f64| change_dist(x, y, at, jt);
    for _ in 0..150 {
        let mut w = cap.clone();
        // hosted changes: (in, out) of window i
        let need = |w: &[f64], i: usize, wi: f64| {
            let left = if i == 0 { v0 } else { w[i - 1] };
            let right = if i + 1 == nw { v1 } else { w[i + 1] };
            let din = if left < wi || (i == 0 && left != wi) { dist(left, wi) } else { 0.0 };
            let dout = if right < wi || (i + 1 == nw && right != wi) { dist(wi, right) } else { 0.0 };
            din + dout
        };
        let mut feasible = true;
        for _pass in 0..100 {
            let mut changed = false;
            for i in 0..nw {
                if need(&w, i, w[i]) <= lw * (1.0 - 1e-9) {
                    continue;
                }
                let left = if i == 0 { v0 } else { w[i - 1] };
                let right = if i + 1 == nw { v1 } else { w[i + 1] };
                let mut lo = left.min(right).min(w[i]);
                if need(&w, i, lo) > lw {
                    // only at the ends: the end speed cannot be joined inside one window
                    lo = floor.min(lo);
                    if need(&w, i, lo) > lw {
                        feasible = false;
                        break;
                    }
                }
                let mut hi = w[i];
                for _ in 0..30 {
                    let m = 0.5 * (lo + hi);
                    if need(&w, i, m) <= lw * (1.0 - 1e-9) {
                        lo = m;
                    } else {
                        hi = m;
                    }
                }
                w[i] = lo;
                changed = true;
            }
            if !changed || !feasible {
                break;
            }
        }
        if !feasible {
            return None;
        }
        // assemble the phases
        let mut ph: Vec<(f64, f64)> = Vec::new();
        let mut short: Option<usize> = None;
        for i in 0..nw {
            let left = if i == 0 { v0 } else { w[i - 1] };
            let right = if i + 1 == nw { v1 } else { w[i + 1] };
            let host_in = left < w[i] || (i == 0 && left != w[i]);
            let host_out = right < w[i] || (i + 1 == nw && right != w[i]);
            let (pin, din) = if host_in { change(left, w[i], at, jt) } else { (vec![], 0.0) };
            let (pout, dout) = if host_out { change(w[i], right, at, jt) } else { (vec![], 0.0) };
            ph.extend(pin);
            if lw - din - dout < -1e-9 * lw && short.is_none() {
                short = Some(i);
            }
            let c = (lw - din - dout).max(0.0);
            if c > 0.0 && w[i] > 0.0 {
                ph.push((c / w[i], 0.0));
            }
            ph.extend(pout);
        }
        let pr = from_phases(len, v0, v1, &ph);
        // a window whose changes do not fit (the feasibility passes ran out) counts as a
        // violation there, as does a profile whose phases do not add up to the length
        let end = pr.phases.last().map_or(0.0, |r| r[1]);
        let off = (end - len).abs() > 1e-7 * len.max(1.0);
        let bad = short.map(|i| (i as f64 + 0.5) * lw).or_else(|| off.then_some(0.5 * len));
        match bad.or_else(|| g.violation(&pr, vmax, a, j)) {
            None => return Some(pr),
            Some(sf) => {
                let i = ((sf / lw).floor() as usize).min(nw - 1);
                if w[i] <= floor * (1.0 + 1e-9) {
                    return None;
                }
                // the window of the violation and its neighbours (a change hosted next door)
                for k in i.saturating_sub(1)..=(i + 1).min(nw - 1) {
                    cap[k] = cap[k].min((0.85 * w[i]).max(floor));
                }
            }
        }
    }
    None
}

/// The fastest jerk-limited profile along a curve from `v0` to `v1` whose plateau is at most
/// `vmax` and at least `floor` times the slower non-zero end speed (a tight bend slows the move,
/// it never stops it; the planner asks for half, and less only where no transfer shape allows
/// that), keeping |v|, |a| (tangential and centripetal together) and |jerk| within the
/// limits; tried with several shares of the limits for the tangential part. `None` when no
/// plateau in that range keeps the limits.
fn curve_profile(
    g: &CurveGrid,
    len: f64,
    (v0, vmax, v1): (f64, f64, f64),
    (a, j): (f64, f64),
    floor: f64,
) -> Option<Profile> {
    let slow = match (v0 > 0.0, v1 > 0.0) {
        (true, true) => v0.min(v1),
        (true, false) => v0,
        (false, true) => v1,
        (false, false) => 0.0,
    };
    let vlo = if slow > 0.0 { floor * slow } else { 1e-3 * vmax };
    // windowed plateaus follow the curvature closely but change speed window by window; three
    // levels (bend, straight middle, bend) reach a much higher top speed on a long transfer
    // whose bends are near its ends; one plateau over the whole move suits short transfers:
    // the fastest of them
    let mut best = plateau_profile(g, len, (v0, vmax, v1), vlo, a, j);
    for shape in [(0.12, true), (0.25, true), (0.12, false), (0.25, false)] {
        if let Some(pr) = three_level(g, len, (v0, vmax, v1), vlo, (a, j), shape) {
            if best.as_ref().is_none_or(|b| pr.duration() < b.duration()) {
                best = Some(pr);
            }
        }
    }
    // (with fewer shares of the limits when one of the others already keeps them)
    let shares: &[f64] = if best.is_some() { &[0.9, 0.5] } else { &[0.9, 0.6, 0.3] };
    for &share in shares {
        let (at, jt) = (a * share, j * share);
        let ok = |vp: f64| Profile::with_peak(len, v0, vp, v1, at, jt).filter(|pr| g.admits(pr, vmax, a, j));
        let found = match ok(vmax) {
            Some(pr) => Some(pr),
            None => {
                // the highest admissible plateau: from the lowest one that is admitted
                let steps = 12;
                let mut lo_ok = None;
                let mut hi_bad = vmax;
                for k in 0..=steps {
                    let vp = vlo + (vmax - vlo) * k as f64 / steps as f64;
                    match ok(vp) {
                        Some(pr) => lo_ok = Some((vp, pr)),
                        None if lo_ok.is_some() => {
                            hi_bad = vp;
                            break;
                        }
                        None => {}
                    }
                }
                lo_ok.map(|(mut l, mut pr)| {
                    let mut h = hi_bad;
                    for _ in 0..12 {
                        let m = 0.5 * (l + h);
                        match ok(m) {
                            Some(p) => {
                                pr = p;
                                l = m;
                            }
                            None => h = m,
                        }
                    }
                    pr
                })
            }
        };
        if let Some(pr) = found {
            if best.as_ref().is_none_or(|b| pr.duration() < b.duration()) {
                best = Some(pr);
            }
        }
    }
    best
}

impl Segment {
    /// A segment on `geom` (its arc length measured), still without a speed profile.
    fn new(kind: SegmentKind, feature: usize, geom: Geom, f: &Feature, tip: f64) -> Segment {
        let mut s = Segment {
            kind,
            feature,
            geom,
            profile: Profile::constant(0.0, 0.0),
            hold: 0.0,
            feedback: false,
            feedback_after: 0.0,
            contact_time: None,
            wait_settled: false,
            plane: None,
            arc: Vec::new(),
            len: 0.0,
        };
        match &s.geom {
            Geom::Hold { .. } => {}
            Geom::Timed { motion } => {
                // path length (for reporting; the motion is evaluated in time)
                let n = 256;
                let d = motion.duration();
                s.len = (0..n)
                    .map(|k| {
                        (motion.state(d * (k + 1) as f64 / n as f64).p
                            - motion.state(d * k as f64 / n as f64).p)
                            .norm()
                    })
                    .sum();
            }
            Geom::Line { a, b } => s.len = (b - a).norm(),
            Geom::Along { pen: Penetration::Const(_), .. } => s.len = s.arc_piece(0.0, 1.0, f, tip),
            _ => {
                let mut arc = Vec::with_capacity(ARC_N + 1);
                arc.push(0.0);
                for k in 0..ARC_N {
                    let (l0, l1) = (k as f64 / ARC_N as f64, (k + 1) as f64 / ARC_N as f64);
                    arc.push(arc[k] + s.arc_piece(l0, l1, f, tip));
                }
                s.len = arc[ARC_N];
                s.arc = arc;
            }
        }
        s
    }

    /// The segment run at `speeds` = (start, highest, end) within the limits of `p`: constant
    /// speed, a jerk-limited S-curve on a straight line, or on a curve the fastest S-curve that
    /// keeps the whole acceleration and jerk vectors within the limits.
    fn timed(mut self, f: &Feature, tip: f64, speeds: (f64, f64, f64), p: &Params) -> Segment {
        self.profile = self.profile_for(f, tip, speeds, p).unwrap_or_else(|| {
            // no plateau keeps the limits (a cusp): through at the slower end speed
            Profile::s_curve(self.len, speeds.0, speeds.0.min(speeds.2).max(1e-3), speeds.2, p.accel, p.jerk)
        });
        self
    }

    fn profile_for(&self, f: &Feature, tip: f64, speeds: (f64, f64, f64), p: &Params) -> Option<Profile> {
        self.profile_with_floor(f, tip, speeds, p, 0.5)
    }

    /// [`Segment::profile_for`] with the least plateau speed of a curve as a share of the slower
    /// non-zero end speed (see [`curve_profile`]).
    fn profile_with_floor(
        &self,
        f: &Feature,
        tip: f64,
        (v0, vmax, v1): (f64, f64, f64),
        p: &Params,
        floor: f64,
    ) -> Option<Profile> {
        if matches!(self.geom, Geom::Hold { .. }) || self.len <= 1e-12 {
            return Some(Profile::constant(0.0, v0));
        }
        if v0 == vmax && vmax == v1 {
            return Some(Profile::constant(self.len, v0));
        }
        if matches!(self.geom, Geom::Line { .. }) {
            return Some(Profile::s_curve(self.len, v0, vmax, v1, p.accel, p.jerk));
        }
        if let Geom::Along { pen: Penetration::Const(d), .. } = self.geom {
            let k = match f.geometry {
                crate::Geometry::Circle { .. } => 1.0 / f.metric(tip - d).max(1e-9),
                crate::Geometry::Line { .. } => 0.0,
            };
            return Some(circle_profile(self.len, (v0, vmax, v1), k, p.accel, p.jerk));
        }
        let g = self.grid(f, tip);
        curve_profile(&g, self.len, (v0, vmax, v1), (p.accel, p.jerk), floor)
    }

    /// Tangent, curvature vector and its derivative on [`GRID_N`] equal arc-length steps (finite
    /// differences of the carrier at the smooth λ(s)).
    fn grid(&self, f: &Feature, tip: f64) -> CurveGrid {
        // at most 0.05 mm apart: tight turns between close features are a few mm long
        let n = ((self.len / 0.05).ceil() as usize).clamp(GRID_N, 8 * GRID_N);
        let ds = self.len / n as f64;
        let pts: Vec<Point3> =
            (0..=n).map(|i| self.carrier(self.lambda(ds * i as f64, f, tip), f, tip)).collect();
        let mut tan = Vec::with_capacity(n + 1);
        let mut k = Vec::with_capacity(n + 1);
        for i in 0..=n {
            let (a, b, c) = match i {
                0 => (0, 1, 2),
                i if i == n => (n - 2, n - 1, n),
                i => (i - 1, i, i + 1),
            };
            let d1 = (pts[c] - pts[a]) / (2.0 * ds);
            let d2 = (pts[c].coords - pts[b].coords * 2.0 + pts[a].coords) / (ds * ds);
            let t = if d1.norm() > 1e-12 { d1.normalize() } else { Vector3::zeros() };
            tan.push(t);
            k.push(d2 - t * t.dot(&d2));
        }
        // the three-point stencils at the ends are centred one step inside: extrapolate the
        // curvature to the end points (the joins, where a transfer ends straight), and take
        // one-sided second-order differences there
        k[0] = k[1] * 2.0 - k[2];
        k[n] = k[n - 1] * 2.0 - k[n - 2];
        let dk = (0..=n)
            .map(|i| match i {
                0 => (k[1] * 4.0 - k[0] * 3.0 - k[2]) / (2.0 * ds),
                i if i == n => (k[n] * 3.0 - k[n - 1] * 4.0 + k[n - 2]) / (2.0 * ds),
                i => (k[i + 1] - k[i - 1]) / (2.0 * ds),
            })
            .collect();
        CurveGrid { ds, tan, k, dk }
    }

    /// Whether the carrier run at constant speed `v` keeps the acceleration (v²·|K|) and jerk
    /// (v³·|dK/ds|) limits, with [`MARGIN`], beyond the share `from` of its parameter (plus
    /// three grid steps, clear of a curvature step at `from`).
    fn tail_keeps_limits(&self, f: &Feature, tip: f64, from: f64, v: f64, p: &Params) -> bool {
        let g = self.grid(f, tip);
        let n = g.k.len() - 1;
        let i0 = ((from * n as f64).ceil() as usize + 3).min(n);
        (i0..=n).all(|i| {
            g.k[i].norm() * v * v <= MARGIN * p.accel && g.dk[i].norm() * v.powi(3) <= MARGIN * p.jerk
        })
    }

    fn hold(kind: SegmentKind, feature: usize, p: Point3, duration: f64) -> Segment {
        Segment {
            kind,
            feature,
            geom: Geom::Hold { p },
            profile: Profile::constant(0.0, 0.0),
            hold: duration,
            feedback: false,
            feedback_after: 0.0,
            contact_time: None,
            wait_settled: false,
            plane: None,
            arc: Vec::new(),
            len: 0.0,
        }
    }

    /// Position of the carrier at `λ`.
    fn carrier(&self, l: f64, f: &Feature, tip: f64) -> Point3 {
        match &self.geom {
            Geom::Line { a, b } => a + (b - a) * l,
            Geom::Quintic { p, m, c } => {
                let q = quintic_coeffs(p, m, c);
                Point3::from(q[0] + (q[1] + (q[2] + (q[3] + (q[4] + q[5] * l) * l) * l) * l) * l)
            }
            Geom::Along { u0, u1, pen, x_len } => f.point(u0 + (u1 - u0) * l, tip - pen.at(l * x_len)),
            Geom::Hold { p } => *p,
            Geom::Timed { motion } => motion.state(l * motion.duration()).p,
        }
    }

    /// |dP/dλ| of the carrier.
    fn rate(&self, l: f64, f: &Feature, tip: f64) -> f64 {
        match &self.geom {
            Geom::Quintic { p, m, c } => {
                let q = quintic_coeffs(p, m, c);
                (q[1] + (q[2] * 2.0 + (q[3] * 3.0 + (q[4] * 4.0 + q[5] * (5.0 * l)) * l) * l) * l).norm()
            }
            _ => {
                let h = 1e-6;
                (self.carrier(l + h, f, tip) - self.carrier(l - h, f, tip)).norm() / (2.0 * h)
            }
        }
    }

    /// Arc length between `l0` and `l1` (5-point Gauss–Legendre).
    fn arc_piece(&self, l0: f64, l1: f64, f: &Feature, tip: f64) -> f64 {
        let (m, r) = (0.5 * (l0 + l1), 0.5 * (l1 - l0));
        GL.iter().map(|&(x, w)| w * self.rate(m + r * x, f, tip)).sum::<f64>() * r
    }

    /// Duration of the segment, s.
    pub fn duration(&self) -> f64 {
        match &self.geom {
            Geom::Hold { .. } => self.hold,
            Geom::Timed { motion } => motion.duration(),
            _ => self.profile.duration(),
        }
    }

    /// Speed at the end (0 for holds).
    pub fn end_speed(&self) -> f64 {
        match &self.geom {
            Geom::Hold { .. } => 0.0,
            Geom::Timed { motion } => motion.end().v.norm(),
            _ => self.profile.v1,
        }
    }

    /// Speed at the start, mm/s (0 for holds).
    pub fn start_speed(&self) -> f64 {
        match &self.geom {
            Geom::Hold { .. } => 0.0,
            Geom::Timed { motion } => motion.start().v.norm(),
            _ => self.profile.v0,
        }
    }

    /// λ at arc length `s`: exact for constant-rate carriers, otherwise Newton steps on the
    /// Gauss–Legendre arc length from the table's linear guess (smooth in `s`, so a jerk-limited
    /// speed profile stays jerk-limited in space).
    fn lambda(&self, s: f64, f: &Feature, tip: f64) -> f64 {
        if self.len <= 0.0 {
            return 0.0;
        }
        let s = s.clamp(0.0, self.len);
        if self.arc.is_empty() {
            return s / self.len;
        }
        let k = self.arc.partition_point(|&a| a <= s).clamp(1, ARC_N) - 1;
        let span = self.arc[k + 1] - self.arc[k];
        let mut l = (k as f64 + if span > 0.0 { (s - self.arc[k]) / span } else { 0.0 }) / ARC_N as f64;
        for _ in 0..3 {
            let kk = ((l * ARC_N as f64).floor() as usize).min(ARC_N - 1);
            let at = self.arc[kk] + self.arc_piece(kk as f64 / ARC_N as f64, l, f, tip);
            let r = self.rate(l, f, tip);
            if r <= 1e-12 {
                break;
            }
            l = (l - (at - s) / r).clamp(0.0, 1.0);
        }
        l
    }

    /// What the segment commands at local time `t`.
    pub fn eval(&self, t: f64, f: &Feature, tip: f64) -> Command {
        if let Geom::Timed { motion } = &self.geom {
            let st = motion.state(t);
            return Command { position: st.p, speed: st.v.norm(), normal: None, deflection: 0.0 };
        }
        let (s, v) = self.profile.at(t);
        let l = self.lambda(s, f, tip);
        let position = self.carrier(l, f, tip);
        let (normal, deflection) = match &self.geom {
            Geom::Along { u0, u1, pen, x_len } => {
                (Some(f.normal(u0 + (u1 - u0) * l)), pen.at(l * x_len).max(0.0))
            }
            _ => match self.plane {
                Some((s0, n)) => (Some(n), (tip - (position - s0).dot(&n)).max(0.0)),
                None => (None, 0.0),
            },
        };
        let speed = if matches!(self.geom, Geom::Hold { .. }) { 0.0 } else { v };
        Command { position, speed, normal, deflection }
    }

    /// End point, unit direction of motion and curvature vector (1/mm) at the end of the
    /// carrier (backward differences in arc length).
    fn end_state(&self, f: &Feature, tip: f64) -> (Point3, Vector3, Vector3) {
        let e = self.carrier(1.0, f, tip);
        let h = (self.len * 1e-3).clamp(1e-6, 0.01);
        if self.len < 3.0 * h {
            return (e, Vector3::zeros(), Vector3::zeros());
        }
        let p1 = self.carrier(self.lambda(self.len - h, f, tip), f, tip);
        let p2 = self.carrier(self.lambda(self.len - 2.0 * h, f, tip), f, tip);
        let d1 = (e.coords * 3.0 - p1.coords * 4.0 + p2.coords) / (2.0 * h);
        let d2 = (e.coords - p1.coords * 2.0 + p2.coords) / (h * h);
        if d1.norm() < 1e-12 {
            return (e, Vector3::zeros(), Vector3::zeros());
        }
        let t = d1.normalize();
        (e, t, d2 - t * t.dot(&d2))
    }
}

/// A planned program.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The planning style.
    pub style: Style,
    /// The features, in order.
    pub features: Vec<Feature>,
    /// The scan parameters used.
    pub params: Params,
    /// The segments, in order.
    pub segments: Vec<Segment>,
    /// Start time of each segment.
    pub starts: Vec<f64>,
}

/// One sample of the planned path.
#[derive(Clone, Copy, Debug)]
pub struct PathSample {
    /// Time, s.
    pub t: f64,
    /// Position, machine frame, mm.
    pub position: Point3,
    /// Path speed, mm/s.
    pub speed: f64,
    /// Index of the segment.
    pub segment: usize,
}

/// Plan a program (features and parameters must have passed [`crate::validate`]).
pub fn plan(features: &[Feature], params: &Params, style: Style) -> Plan {
    let segments = match style {
        Style::Blended => blended(features, params),
        Style::Classic => classic(features, params),
    };
    let mut starts = Vec::with_capacity(segments.len());
    let mut t = 0.0;
    for s in &segments {
        starts.push(t);
        t += s.duration();
    }
    Plan { style, features: features.to_vec(), params: params.clone(), segments, starts }
}

/// Home point of the classic style (its start): above the first feature's scan start on its
/// normal. The blended style starts from rest on the extension of its first approach line.
pub fn home(features: &[Feature], p: &Params) -> Point3 {
    features[0].point(0.0, p.tip_radius + p.clearance + 10.0)
}

/// A transfer carrier from `a` (leaving along `da` with curvature vector `ka`, 1/mm) to `b`
/// (arriving along `db` on a straight line, zero curvature): a quintic Hermite with end
/// derivatives of length `k`, so position, direction and curvature — and with them velocity and
/// acceleration — are continuous at both joins.
fn quintic_between(
    a: Point3,
    da: Vector3,
    ka: Vector3,
    b: Point3,
    db: Vector3,
    (k0, k1): (f64, f64),
) -> Geom {
    // d²P/dλ² = κ·|dP/dλ|² along the curvature vector (no tangential part) at the start.
    Geom::Quintic { p: [a, b], m: [da * k0, db * k1], c: [ka * (k0 * k0), Vector3::zeros()] }
}

/// The fastest transfer from `start` = (point, direction, curvature vector) to `end` = (point,
/// direction): quintic carriers with end derivatives of 0.5 to 1.8 chords (a tight turn between
/// close features needs a wider swing, a long transfer a nearly straight one) are each given the
/// fastest profile within the limits ([`curve_profile`]); the shortest in time wins. When none
/// keeps the limits (a U-turn between close neighbours), wider swings up to 6 chords are tried.
/// `Err` holds the best carrier found when none keeps the limits (timed above them).
fn transfer(
    i: usize,
    f: &Feature,
    p: &Params,
    (a, da, ka): (Point3, Vector3, Vector3),
    (b, db): (Point3, Vector3),
    speeds: (f64, f64, f64),
) -> Result<Segment, Box<Segment>> {
    let tip = p.tip_radius;
    let chord = (b - a).norm().max(1.0);
    let mut best: Option<Segment> = None;
    let mut fallback: Option<Segment> = None;
    let mut kinked: Option<(f64, Segment)> = None;
    // at limits too low for the geometry (a tight turn at a low jerk) the bend is taken slower:
    // first down to half the slower end speed, then to a tenth, 1 %, 0.1 %
    'floors: for floor in [0.5, 0.1, 0.01, 0.001] {
        // end-derivative lengths in chords (start, end); the unequal pairs swing wider at one
        // end only (a reversal into an approach that faces back), tried when the equal ones fail
        for (s0, s1) in [
            (0.25f64, 0.25f64),
            (0.5, 0.5),
            (0.8, 0.8),
            (1.2, 1.2),
            (1.8, 1.8),
            (2.7, 2.7),
            (0.5, 2.5),
            (2.5, 0.5),
            (1.0, 4.0),
            (4.0, 1.0),
            (4.0, 4.0),
            (6.0, 6.0),
        ] {
            if s0.max(s1) > 2.0 && best.is_some() {
                break 'floors;
            }
            let seg = Segment::new(
                SegmentKind::Transfer,
                i,
                quintic_between(a, da, ka, b, db, (chord * s0, chord * s1)),
                f,
                tip,
            );
            // a carrier that nearly stalls (|dP/dλ| far below its mean) or bends tighter than
            // 1 mm radius has a kink narrower than the curvature grid resolves: not a candidate
            let kmax = max_curvature(&seg.geom);
            if (0..=256).any(|k| seg.rate(k as f64 / 256.0, f, tip) < 0.1 * seg.len) || kmax > 1.0 {
                // the least kinked one is kept for the case that no candidate keeps the limits
                if kinked.as_ref().is_none_or(|(k, _)| kmax < *k) {
                    kinked = Some((kmax, seg));
                }
                continue;
            }
            match seg.profile_with_floor(f, tip, speeds, p, floor) {
                Some(pr) if best.as_ref().is_none_or(|s| pr.duration() < s.duration()) => {
                    best = Some(Segment { profile: pr, ..seg });
                }
                Some(_) => {}
                None if fallback.is_none() => fallback = Some(seg),
                None => {}
            }
        }
        if best.is_some() {
            break;
        }
    }
    // no candidate keeps the limits (a known gap, see docs/performance-scan.md): the first
    // smooth carrier, else the least kinked one, timed as well as the curve allows
    let fallback = fallback.or(kinked.map(|(_, s)| s));
    best.ok_or_else(|| {
        Box::new(fallback.map(|s| s.timed(f, tip, speeds, p)).unwrap_or_else(|| {
            Segment::new(SegmentKind::Transfer, i, Geom::Line { a, b }, f, tip).timed(f, tip, speeds, p)
        }))
    })
}

/// The transfer as one or three moves. When no single curve from `start` to `end` keeps the
/// limits at the end speeds (a high scanning speed with a low jerk limit: the curvature may grow
/// by at most 0.95·j/v³ per mm, too little for a tight turn), the transfer slows down before it
/// turns: a lead-out that straightens from the release's curvature (a quintic ending straight
/// along the release direction, curvature-continuous at both ends) while slowing to a bend speed
/// `u`, the turn at `u` ([`transfer`]), and a straight lead-in on the approach line's extension
/// back up to the end speed. Bend speeds from half to a twentieth of the start speed, lead-out
/// lengths from one to eight times the least one are tried; the first that keeps the limits is
/// taken. When none does, the single best carrier is returned (timed above the limits). When a
/// single curve keeps the limits, two turns joined by a straight line ([`corner_turns`]) replace
/// it if they are faster.
fn transfer_moves(
    i: usize,
    f: &Feature,
    p: &Params,
    start: (Point3, Vector3, Vector3),
    end: (Point3, Vector3),
    speeds: (f64, f64, f64),
) -> Vec<Segment> {
    let total = |v: &[Segment]| v.iter().map(Segment::duration).sum::<f64>();
    match transfer(i, f, p, start, end, speeds) {
        // slowing down for a sharp turn can also beat a single curve taken at the end speeds
        Ok(s) => match corner_turns(i, f, p, start, end, speeds) {
            Some(v) if total(&v) < s.duration() => v,
            _ => vec![s],
        },
        Err(s) => slow_turn(i, f, p, start, end, speeds, &[0.5, 0.25, 0.1, 0.05], &[1.0, 2.0, 4.0, 8.0])
            .unwrap_or_else(|| vec![*s]),
    }
}

/// A long transfer as two turns joined by a straight line run up to the positioning speed: the
/// first turn from the release into the direction between the two turns, the second from that
/// direction into the approach, each a quintic of [`transfer`] ending (starting) straight at a
/// join speed `u`. Turn legs of 0.15 to 0.3 chords, join speeds of 1.5 and 2 times the faster
/// end speed (at most the positioning speed); the fastest that keeps the limits. Only for
/// chords of 20 mm and more between moving ends.
fn corner_turns(
    i: usize,
    f: &Feature,
    p: &Params,
    start: (Point3, Vector3, Vector3),
    (b, db): (Point3, Vector3),
    (v0, vmax, v1): (f64, f64, f64),
) -> Option<Vec<Segment>> {
    let tip = p.tip_radius;
    let (a, da, _) = start;
    let chord = (b - a).norm();
    if chord < 20.0 || v0 <= 0.0 || v1 <= 0.0 {
        return None;
    }
    let mut best: Option<(f64, Vec<Segment>)> = None;
    for (share, mul) in [(0.15, 2.0), (0.2, 2.0), (0.25, 2.0), (0.3, 2.0), (0.2, 1.5), (0.3, 1.5)] {
        let h = share * chord;
        let (qa, qb) = (a + da * h, b - db * h);
        if (qb - qa).norm() < 2.2 * h {
            continue;
        }
        let dm = (qb - qa).normalize();
        let (p1, p2) = (qa + dm * h, qb - dm * h);
        let u = (mul * v0.max(v1)).min(vmax);
        let Ok(t1) = transfer(i, f, p, start, (p1, dm), (v0, vmax, u)) else {
            continue;
        };
        let Ok(t2) = transfer(i, f, p, (p2, dm, Vector3::zeros()), (b, db), (u, vmax, v1)) else {
            continue;
        };
        let line = Segment::new(SegmentKind::Transfer, i, Geom::Line { a: p1, b: p2 }, f, tip).timed(
            f,
            tip,
            (u, vmax, u),
            p,
        );
        let t = t1.duration() + line.duration() + t2.duration();
        if best.as_ref().is_none_or(|(bt, _)| t < *bt) {
            best = Some((t, vec![t1, line, t2]));
        }
    }
    best.map(|(_, v)| v)
}

/// Lead-out, turn at a bend speed and straight lead-in of [`transfer_moves`]: the first bend
/// speed share (of the start speed) and lead-out length multiple that keep the limits.
#[allow(clippy::too_many_arguments)]
fn slow_turn(
    i: usize,
    f: &Feature,
    p: &Params,
    (a, da, ka): (Point3, Vector3, Vector3),
    (b, db): (Point3, Vector3),
    (v0, vmax, v1): (f64, f64, f64),
    shares: &[f64],
    muls: &[f64],
) -> Option<Vec<Segment>> {
    let tip = p.tip_radius;
    if v0 <= 0.0 || da.norm() < 0.5 || db.norm() < 0.5 {
        return None;
    }
    let straighten = straighten_len(ka, v0, p);
    for &share in shares {
        let u = share * v0;
        let l3 = change_dist(u, v1, p.accel, p.jerk) + 0.5;
        let c = b - db * l3;
        for &mul in muls {
            let l1 = mul * (straighten + change_dist(v0, u, 0.5 * p.accel, 0.5 * p.jerk) + 0.5);
            let m = a + da * l1;
            let out =
                Segment::new(SegmentKind::Transfer, i, quintic_between(a, da, ka, m, da, (l1, l1)), f, tip);
            let Some(pr) = out.profile_with_floor(f, tip, (v0, v0, u), p, 1.0) else {
                continue;
            };
            let Ok(turn) = transfer(i, f, p, (m, da, Vector3::zeros()), (c, db), (u, vmax, u)) else {
                continue;
            };
            let lead_in = Segment::new(SegmentKind::Transfer, i, Geom::Line { a: c, b }, f, tip).timed(
                f,
                tip,
                (u, u.max(v1), v1),
                p,
            );
            return Some(vec![Segment { profile: pr, ..out }, turn, lead_in]);
        }
    }
    None
}

/// Largest curvature (1/mm) of a quintic carrier, from its exact derivatives at 1024 steps of λ
/// (0 for other carriers).
fn max_curvature(g: &Geom) -> f64 {
    let Geom::Quintic { p, m, c } = g else {
        return 0.0;
    };
    let q = quintic_coeffs(p, m, c);
    (0..=1024)
        .map(|k| {
            let l = k as f64 / 1024.0;
            let d1 = q[1] + (q[2] * 2.0 + (q[3] * 3.0 + (q[4] * 4.0 + q[5] * (5.0 * l)) * l) * l) * l;
            let d2 = q[2] * 2.0 + (q[3] * 6.0 + (q[4] * 12.0 + q[5] * (20.0 * l)) * l) * l;
            let r = d1.norm();
            if r > 1e-12 {
                d1.cross(&d2).norm() / r.powi(3)
            } else {
                f64::INFINITY
            }
        })
        .fold(0.0, f64::max)
}

/// Length over which a curvature `k` (1/mm) can fall to zero at speed `v` with the curvature
/// term of the jerk, v³·|dK/ds|, within half the jerk limit, on a quintic Hermite with end
/// derivatives as long as the move (its curvature falls as κ·(1 − 9λ + 18λ² − 10λ³), at most
/// 9 times faster than on average).
fn straighten_len(k: Vector3, v: f64, p: &Params) -> f64 {
    9.0 * k.norm() * v.powi(3) / (0.5 * p.jerk)
}

/// Distance a jerk-limited stop from `v` needs at half the limits (room for the final stop).
fn stop_distance(v: f64, p: &Params) -> f64 {
    let (a, j) = (0.5 * p.accel, 0.5 * p.jerk);
    0.5 * v * (v / a + a / j)
}

fn blended(features: &[Feature], p: &Params) -> Vec<Segment> {
    let tip = p.tip_radius;
    let (ca, sa) = (p.approach_angle.cos(), p.approach_angle.sin());
    let cot = ca / sa;
    let peak = p.deflection + p.overshoot;
    let x1 = 1.5 * peak / cot;
    let settle_len = settle_extension(p);
    let xr = 0.5;
    let k = cot / (3.0 * xr * xr);
    let rel_len = |lift: f64| xr + ((p.deflection + lift) - k * xr.powi(3)) / cot;
    let v = p.scan_speed;
    let mut segs: Vec<Segment> = Vec::new();
    let mut prev_end: Option<(Point3, Vector3, Vector3)> = None;
    for (i, f) in features.iter().enumerate() {
        let m = f.metric(tip - p.deflection).max(1e-9);
        let uc = -settle_len / m;
        let n0 = f.normal(uc);
        let t0 = f.tangent(uc);
        let c0 = f.point(uc, tip);
        let w = -n0 * ca + t0 * sa;
        let a = c0 - w * (p.clearance / ca);
        // transfer into the approach
        let tr = match prev_end {
            // from rest on the approach line's extension, far enough back to reach scanning
            // speed straight on (a curve from rest into the approach would have to be taken
            // at a fraction of the scanning speed at low limits)
            None => {
                let h = a - w * (2.0 * stop_distance(v, p) + 1.0);
                Some(Segment::new(SegmentKind::Transfer, i, Geom::Line { a: h, b: a }, f, tip).timed(
                    f,
                    tip,
                    (0.0, p.move_speed, v),
                    p,
                ))
            }
            Some(start) => {
                segs.extend(velocity_transfer(i, f, p, start, (a, w), v));
                None
            }
        };
        segs.extend(tr);
        let mut ap = Segment::new(SegmentKind::Approach, i, Geom::Line { a, b: c0 }, f, tip).timed(
            f,
            tip,
            (v, v, v),
            p,
        );
        ap.contact_time = Some(ap.duration());
        ap.plane = Some((f.point(uc, 0.0), n0));
        segs.push(ap);
        let pen = Penetration::Settle { s0: cot, peak, x1, end: p.deflection, len: settle_len };
        // The settle starts open loop on the contact point's shift: integrating the deflection
        // error through the transient of the turn (servo lag of the normal deceleration) would
        // wind the observer up and leave an error at the scan start. The feedback comes on once
        // the deflection is past its peak, 30 % into the gradual decrease.
        let mut st = Segment::new(
            SegmentKind::Settle,
            i,
            Geom::Along { u0: uc, u1: 0.0, pen, x_len: settle_len },
            f,
            tip,
        )
        .timed(f, tip, (v, v, v), p);
        st.feedback = true;
        st.feedback_after = (x1 + 0.3 * (settle_len - x1)) / settle_len * st.duration();
        segs.push(st);
        let ext = f.extent();
        let mut sc = Segment::new(
            SegmentKind::Scan,
            i,
            Geom::Along { u0: 0.0, u1: ext, pen: Penetration::Const(p.deflection), x_len: ext * m },
            f,
            tip,
        )
        .timed(f, tip, (v, v, v), p);
        sc.feedback = true;
        segs.push(sc);
        // The release lifts by `clearance`, less where its straight-sloped tail would bend too
        // tightly for the limits at scanning speed (in a small bore the tail spirals towards the
        // axis and its curvature grows without bound): the transfer, checked against the
        // limits, takes over from where the tail still keeps them (at least 0.2 mm off).
        let pen = Penetration::Release { d: p.deflection, k, xr, c: cot };
        let mut lift = p.clearance;
        let rl = loop {
            let len = rel_len(lift);
            let rl = Segment::new(
                SegmentKind::Release,
                i,
                Geom::Along { u0: ext, u1: ext + len / m, pen: pen.clone(), x_len: len },
                f,
                tip,
            )
            .timed(f, tip, (v, v, v), p);
            if lift <= 0.2 || rl.tail_keeps_limits(f, tip, xr / len, v, p) {
                break rl;
            }
            lift = (0.8 * lift).max(0.2);
        };
        let end = rl.end_state(f, tip);
        segs.push(rl);
        prev_end = Some(end);
    }
    // come to rest straight on from the last release (its curvature's acceleration ramped to
    // zero first)
    if let Some((e, de, ke)) = prev_end {
        let last = features.len() - 1;
        let m = motion::stop((e, de * v, ke * (v * v)), limits(p));
        segs.push(Segment::new(SegmentKind::Transfer, last, Geom::Timed { motion: m }, &features[last], tip));
    }
    segs
}

/// The planner's share ([`MARGIN`]) of the positioning limits, for motions planned in time.
fn limits(p: &Params) -> Limits {
    Limits { v: p.move_speed, a: MARGIN * p.accel, j: MARGIN * p.jerk }
}

/// The transfer from a release's end `start` = (point, unit direction, curvature vector) at
/// scanning speed `v` into the approach starting at `b` along `db`: planned in velocity space
/// ([`motion::transfer`], never slower than half the scanning speed); when that family
/// has no motion for the geometry (a reversal on the spot), the curve-first transfer of
/// [`transfer_moves`].
fn velocity_transfer(
    i: usize,
    f: &Feature,
    p: &Params,
    (a, da, ka): (Point3, Vector3, Vector3),
    (b, db): (Point3, Vector3),
    v: f64,
) -> Vec<Segment> {
    match motion::transfer((a, da * v, ka * (v * v)), (b, db * v), limits(p), 0.5 * v) {
        Some(m) => vec![Segment::new(SegmentKind::Transfer, i, Geom::Timed { motion: m }, f, p.tip_radius)],
        None => transfer_moves(i, f, p, (a, da, ka), (b, db), (v, p.move_speed, v)),
    }
}

fn classic(features: &[Feature], p: &Params) -> Vec<Segment> {
    let tip = p.tip_radius;
    let mut segs: Vec<Segment> = Vec::new();
    let mut pos = home(features, p);
    for (i, f) in features.iter().enumerate() {
        let n0 = f.normal(0.0);
        let c0 = f.point(0.0, tip);
        let pre = c0 + n0 * p.clearance;
        if (pre - pos).norm() > 1e-9 {
            segs.push(Segment::new(SegmentKind::Transfer, i, Geom::Line { a: pos, b: pre }, f, tip).timed(
                f,
                tip,
                (0.0, p.move_speed, 0.0),
                p,
            ));
        }
        segs.push(Segment::hold(SegmentKind::Approach, i, pre, p.prehit_dwell));
        let deep = c0 - n0 * p.deflection;
        let mut ap = Segment::new(SegmentKind::Approach, i, Geom::Line { a: pre, b: deep }, f, tip).timed(
            f,
            tip,
            (0.0, p.touch_speed, 0.0),
            p,
        );
        // time at which the nominal contact point is passed
        let target = p.clearance;
        let (mut lo, mut hi) = (0.0, ap.duration());
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if ap.profile.at(mid).0 < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        ap.contact_time = Some(hi);
        ap.plane = Some((f.point(0.0, 0.0), n0));
        segs.push(ap);
        let mut st = Segment::hold(SegmentKind::Settle, i, deep, 0.3);
        st.feedback = true;
        st.wait_settled = true;
        st.plane = Some((f.point(0.0, 0.0), n0));
        segs.push(st);
        let ext = f.extent();
        let m = f.metric(tip - p.deflection).max(1e-9);
        let mut sc = Segment::new(
            SegmentKind::Scan,
            i,
            Geom::Along { u0: 0.0, u1: ext, pen: Penetration::Const(p.deflection), x_len: ext * m },
            f,
            tip,
        )
        .timed(f, tip, (0.0, p.scan_speed, 0.0), p);
        sc.feedback = true;
        segs.push(sc);
        let a = f.point(ext, tip - p.deflection);
        let b = f.point(ext, tip + p.clearance);
        let mut rl = Segment::new(SegmentKind::Release, i, Geom::Line { a, b }, f, tip).timed(
            f,
            tip,
            (0.0, p.move_speed, 0.0),
            p,
        );
        rl.plane = Some((f.point(ext, 0.0), f.normal(ext)));
        segs.push(rl);
        pos = b;
    }
    segs
}

impl Plan {
    /// Duration of the whole plan, s.
    pub fn duration(&self) -> f64 {
        match (self.starts.last(), self.segments.last()) {
            (Some(t), Some(s)) => t + s.duration(),
            _ => 0.0,
        }
    }

    /// Time window from the start of the first approach to the end of the last release.
    pub fn window(&self) -> (f64, f64) {
        let mut a = f64::INFINITY;
        let mut b = f64::NEG_INFINITY;
        for (s, &t) in self.segments.iter().zip(&self.starts) {
            if s.kind == SegmentKind::Approach {
                a = a.min(t);
            }
            if s.kind == SegmentKind::Release {
                b = b.max(t + s.duration());
            }
        }
        (a, b)
    }

    /// Number of times the commanded speed reaches zero in [`Plan::window`] (consecutive zero
    /// instants and holds count once).
    pub fn stops(&self) -> usize {
        let (a, b) = self.window();
        let mut events: Vec<(f64, f64)> = Vec::new(); // zero-speed intervals
        for (s, &t) in self.segments.iter().zip(&self.starts) {
            let d = s.duration();
            if matches!(s.geom, Geom::Hold { .. }) {
                events.push((t, t + d));
            } else {
                if s.start_speed() <= 1e-12 {
                    events.push((t, t));
                }
                if s.end_speed() <= 1e-12 {
                    events.push((t + d, t + d));
                }
            }
        }
        let eps = 1e-9;
        let mut count = 0;
        let mut last_end = f64::NEG_INFINITY;
        for (s, e) in events {
            if e < a - eps || s > b + eps {
                continue;
            }
            if s > last_end + eps {
                count += 1;
            }
            last_end = last_end.max(e);
        }
        count
    }

    /// The commanded path at time step `dt` (every segment's start and end included).
    pub fn sample(&self, dt: f64) -> Vec<PathSample> {
        let mut out = Vec::with_capacity((self.duration() / dt) as usize + 2 * self.segments.len() + 2);
        let tip = self.params.tip_radius;
        for (i, (s, &t0)) in self.segments.iter().zip(&self.starts).enumerate() {
            let f = &self.features[s.feature];
            let d = s.duration();
            let n = ((d / dt).ceil() as usize).max(1);
            let last = i + 1 == self.segments.len();
            let upto = if last { n } else { n - 1 };
            for k in 0..=upto {
                let tl = (k as f64 * dt).min(d);
                let c = s.eval(tl, f, tip);
                out.push(PathSample { t: t0 + tl, position: c.position, speed: c.speed, segment: i });
            }
        }
        out
    }

    /// Approach directions (unit) with the surface normal at their contact point, for checking.
    pub fn approaches(&self) -> Vec<(Vector3, Vector3)> {
        self.segments
            .iter()
            .filter_map(|s| match (&s.geom, s.plane, s.kind) {
                (Geom::Line { a, b }, Some((_, n)), SegmentKind::Approach) => Some(((b - a).normalize(), n)),
                _ => None,
            })
            .collect()
    }
}

/// For a line feature the settle path lies on the line's extension before `start_mm`; this is
/// the distance it extends (mm), for scenario builders that must provide material there.
pub fn settle_extension(p: &Params) -> f64 {
    let cot = p.approach_angle.cos() / p.approach_angle.sin();
    let x1 = 1.5 * (p.deflection + p.overshoot) / cot;
    p.settle_length.max(2.0 * x1).max(p.settle_time * p.scan_speed)
}
