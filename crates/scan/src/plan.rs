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
//! climbs straight to the clearance; the transfer is a quintic Hermite curve that matches the
//! release's end point, direction and curvature at one end and the approach line (zero
//! curvature) at the other, so position, velocity and acceleration are continuous at both joints.
//!
//! Transfers (and every straight move) run on jerk-limited speed profiles ([`Profile::s_curve`]:
//! phases of constant jerk). On a curved transfer the speed is capped from the curve's largest
//! curvature κ, curvature rate κ' and κτ so that the whole motion — tangential and lateral —
//! stays within the limits: `|a| ≤ √(a_t² + v⁴κ²) ≤ accel` and
//! `|j| ≤ |j_t| + v³κ² + 3·v·|a_t|·κ + v³|κ'| + v³|κτ| ≤ jerk` (the Frenet decomposition of
//! the third derivative of the position). The settle path lies *before* the scan start
//! (for a line, on the extension of the line before `start_mm`), so the scan covers the whole
//! requested path.

use crate::feature::{Feature, Params};
use truepos_math::{Point3, Vector3};

/// The segment tags of the contract.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SegmentKind {
    Transfer,
    Approach,
    Settle,
    Scan,
    Release,
}

impl SegmentKind {
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

/// Planning style.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    Blended,
    Classic,
}

/// Commanded penetration (deflection) along a surface-following segment, as a function of the
/// tangential distance `x` (mm) from the segment start.
#[derive(Clone, Debug, PartialEq)]
pub enum Penetration {
    Const(f64),
    /// `s0·x − ½·peak·(x/x1)³` up to `x1` (reaching `peak` with zero slope), then a half cosine
    /// from `peak` down to `end` at `len`.
    Settle {
        s0: f64,
        peak: f64,
        x1: f64,
        end: f64,
        len: f64,
    },
    /// `d − k·x³` up to `xr` (slope −`c` there), then straight with slope −`c`.
    Release {
        d: f64,
        k: f64,
        xr: f64,
        c: f64,
    },
}

impl Penetration {
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
    Line {
        a: Point3,
        b: Point3,
    },
    /// Quintic Hermite: end points, end tangents (dP/dλ) and end second derivatives (d²P/dλ²).
    Quintic {
        p: [Point3; 2],
        m: [Vector3; 2],
        c: [Vector3; 2],
    },
    /// Along the segment's feature from `u0` to `u1` (see [`Feature::point`]); `x_len` is the
    /// tangential length over which the penetration profile is evaluated.
    Along {
        u0: f64,
        u1: f64,
        pen: Penetration,
        x_len: f64,
    },
    /// Standing still.
    Hold {
        p: Point3,
    },
}

/// Speed profile over a length: a trapezoid, or a jerk-limited S-curve (phases of constant jerk).
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// Phases of the S-curve: (start time, s, v, a, jerk) at each phase start; `None` for a
    /// trapezoid.
    table: Option<Vec<[f64; 5]>>,
    pub len: f64,
    pub v0: f64,
    pub v1: f64,
    vp: f64,
    a0: f64,
    a1: f64,
    t0: f64,
    tc: f64,
    t1: f64,
}

impl Profile {
    /// From `v0` to `v1`, cruising at most at `vmax`, accelerating at most at `a` (the limit is
    /// raised only when the length cannot join `v0` and `v1` otherwise).
    pub fn new(len: f64, v0: f64, vmax: f64, v1: f64, a: f64) -> Profile {
        let len = len.max(0.0);
        if len <= 1e-12 {
            return Profile {
                table: None,
                len: 0.0,
                v0,
                v1,
                vp: v0,
                a0: 0.0,
                a1: 0.0,
                t0: 0.0,
                tc: 0.0,
                t1: 0.0,
            };
        }
        let need = (v1 * v1 - v0 * v0).abs() / (2.0 * len);
        let a = a.max(need * (1.0 + 1e-9));
        let mut vp = vmax.max(v0).max(v1);
        let d0 = (vp * vp - v0 * v0) / (2.0 * a);
        let d1 = (vp * vp - v1 * v1) / (2.0 * a);
        if d0 + d1 > len {
            vp = ((2.0 * a * len + v0 * v0 + v1 * v1) / 2.0).sqrt().max(v0).max(v1);
        }
        let d0 = (vp * vp - v0 * v0) / (2.0 * a);
        let d1 = (vp * vp - v1 * v1) / (2.0 * a);
        let dc = (len - d0 - d1).max(0.0);
        let t0 = (vp - v0) / a;
        let t1 = (vp - v1) / a;
        let tc = if vp > 0.0 { dc / vp } else { 0.0 };
        Profile { table: None, len, v0, v1, vp, a0: a, a1: a, t0, tc, t1 }
    }

    /// Jerk-limited profile over `len` from `v0` to `v1` through a cruise speed of at most `vmax`
    /// (the highest the length allows), with |a| ≤ `a` and |jerk| ≤ `j`: every speed change is an
    /// S-curve (jerk ±j, then constant acceleration when the change is large enough, then ∓j),
    /// starting and ending with zero acceleration. When `len` is too short to join `v0` and `v1`
    /// at these limits, both are raised together just enough (as [`Profile::new`] does).
    pub fn s_curve(len: f64, v0: f64, vmax: f64, v1: f64, a: f64, j: f64) -> Profile {
        let len = len.max(0.0);
        if len <= 1e-12 {
            return Profile::new(0.0, v0, vmax, v1, a);
        }
        // (phases (duration, jerk), distance) of a change from va to vb.
        let change = |va: f64, vb: f64, a: f64, j: f64| -> (Vec<(f64, f64)>, f64) {
            let d = (vb - va).abs();
            if d <= 0.0 {
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
        };
        let lo = v0.max(v1);
        let dist = |vp: f64, a: f64, j: f64| change(v0, vp, a, j).1 + change(vp, v1, a, j).1;
        let (mut a, mut j) = (a, j);
        while dist(lo, a, j) > len {
            a *= 1.05;
            j *= 1.05 * 1.05;
        }
        let hi = vmax.max(lo);
        let vp = if dist(hi, a, j) <= len {
            hi
        } else {
            let (mut l, mut h) = (lo, hi);
            for _ in 0..100 {
                let m = 0.5 * (l + h);
                if dist(m, a, j) <= len {
                    l = m;
                } else {
                    h = m;
                }
            }
            l
        };
        let (up, d_up) = change(v0, vp, a, j);
        let (down, d_down) = change(vp, v1, a, j);
        let cruise = if vp > 0.0 { (len - d_up - d_down).max(0.0) / vp } else { 0.0 };
        let mut phases = up;
        if cruise > 0.0 {
            phases.push((cruise, 0.0));
        }
        phases.extend(down);
        // Integrate the phases exactly.
        let mut table = Vec::with_capacity(phases.len() + 1);
        let (mut t, mut x, mut v, mut acc) = (0.0, 0.0, v0, 0.0);
        for (dt, jk) in phases {
            if dt <= 0.0 {
                continue;
            }
            table.push([t, x, v, acc, jk]);
            x += v * dt + 0.5 * acc * dt * dt + jk * dt * dt * dt / 6.0;
            v += acc * dt + 0.5 * jk * dt * dt;
            acc += jk * dt;
            t += dt;
        }
        table.push([t, x, v, 0.0, 0.0]);
        // t0/t1 hold the lengths of the speed changes (for curve checks), tc the cruise time.
        Profile { table: Some(table), len, v0, v1, vp, a0: a, a1: a, t0: d_up, tc: cruise, t1: d_down }
    }

    /// Lengths of the initial and final speed changes of an S-curve (0 for other profiles).
    fn change_lengths(&self) -> (f64, f64) {
        match self.table {
            Some(_) => (self.t0, self.t1),
            None => (0.0, 0.0),
        }
    }

    /// Constant speed.
    pub fn constant(len: f64, v: f64) -> Profile {
        Profile::new(len, v, v, v, 1.0)
    }

    pub fn duration(&self) -> f64 {
        match &self.table {
            Some(tb) => tb.last().map_or(0.0, |r| r[0]),
            None => self.t0 + self.tc + self.t1,
        }
    }

    /// Distance and speed at time `t` from the start.
    pub fn at(&self, t: f64) -> (f64, f64) {
        if self.len == 0.0 {
            return (0.0, self.v0);
        }
        let t = t.clamp(0.0, self.duration());
        if let Some(tb) = &self.table {
            let i = tb.partition_point(|r| r[0] <= t).clamp(1, tb.len()) - 1;
            let [t0, x, v, a, j] = tb[i];
            let tau = t - t0;
            let s = x + v * tau + 0.5 * a * tau * tau + j * tau * tau * tau / 6.0;
            return (s.clamp(0.0, self.len), v + a * tau + 0.5 * j * tau * tau);
        }
        if t < self.t0 {
            (self.v0 * t + 0.5 * self.a0 * t * t, self.v0 + self.a0 * t)
        } else if t < self.t0 + self.tc {
            let d0 = self.v0 * self.t0 + 0.5 * self.a0 * self.t0 * self.t0;
            (d0 + self.vp * (t - self.t0), self.vp)
        } else {
            let d0 = self.v0 * self.t0 + 0.5 * self.a0 * self.t0 * self.t0;
            let dcl = d0 + self.vp * self.tc;
            let r = t - self.t0 - self.tc;
            ((dcl + self.vp * r - 0.5 * self.a1 * r * r).min(self.len), self.vp - self.a1 * r)
        }
    }
}

/// One planned segment.
#[derive(Clone, Debug)]
pub struct Segment {
    pub kind: SegmentKind,
    /// Index of the feature it belongs to (a transfer belongs to the feature it leads to).
    pub feature: usize,
    pub geom: Geom,
    pub profile: Profile,
    /// Duration of a [`Geom::Hold`] (nominal, for the classic settle the executor extends it
    /// until the deflection has settled).
    pub hold: f64,
    /// Probe feedback (observer) on (from local time `feedback_after`).
    pub feedback: bool,
    pub feedback_after: f64,
    /// For approaches: the segment-local time at which the nominal contact point is passed.
    pub contact_time: Option<f64>,
    /// Classic settle: wait until the deflection has settled.
    pub wait_settled: bool,
    /// Surface point and outward normal for segments that are not [`Geom::Along`] (approach
    /// target, classic retract): the target deflection is the penetration of this plane.
    pub plane: Option<(Point3, Vector3)>,
    /// Arc-length table of the carrier: (λ at equal distance steps).
    table: Vec<f64>,
    /// Quintic carriers: arc length at `ARC_N + 1` equal steps of λ (Gauss–Legendre), for the
    /// exact (smooth) inverse λ(s) that a jerk-limited motion needs.
    arc: Vec<f64>,
}

/// What a segment commands at a local time.
#[derive(Clone, Copy, Debug)]
pub struct Command {
    pub position: Point3,
    pub speed: f64,
    /// Outward surface normal (for feedback and missed-surface shifts), if any.
    pub normal: Option<Vector3>,
    /// Planned stylus deflection.
    pub deflection: f64,
}

const TABLE_N: usize = 256;

impl Segment {
    fn new(
        kind: SegmentKind,
        feature: usize,
        geom: Geom,
        f: &Feature,
        tip: f64,
        speeds: (f64, f64, f64),
        limits: (f64, f64),
    ) -> Segment {
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
            table: Vec::new(),
            arc: Vec::new(),
        };
        // arc-length table: cumulative chord lengths at equal λ, inverted to λ at equal s.
        let mut cum = Vec::with_capacity(TABLE_N + 1);
        cum.push(0.0);
        let mut prev = s.carrier(0.0, f, tip);
        for i in 1..=TABLE_N {
            let p = s.carrier(i as f64 / TABLE_N as f64, f, tip);
            cum.push(cum[i - 1] + (p - prev).norm());
            prev = p;
        }
        let mut len = cum[TABLE_N];
        if let Geom::Quintic { p, m, c } = &s.geom {
            let mut arc = Vec::with_capacity(ARC_N + 1);
            arc.push(0.0);
            for k in 0..ARC_N {
                let (l0, l1) = (k as f64 / ARC_N as f64, (k + 1) as f64 / ARC_N as f64);
                arc.push(arc[k] + gauss_length(p, m, c, l0, l1));
            }
            len = arc[ARC_N];
            s.arc = arc;
        }
        let mut table = Vec::with_capacity(TABLE_N + 1);
        let mut j = 0;
        for i in 0..=TABLE_N {
            let target = len * i as f64 / TABLE_N as f64;
            while j < TABLE_N - 1 && cum[j + 1] < target {
                j += 1;
            }
            let span = cum[j + 1] - cum[j];
            let f = if span > 0.0 { ((target - cum[j]) / span).clamp(0.0, 1.0) } else { 0.0 };
            table.push((j as f64 + f) / TABLE_N as f64);
        }
        s.table = table;
        let (accel, jerk) = limits;
        s.profile = match &s.geom {
            Geom::Line { .. } => Profile::s_curve(len, speeds.0, speeds.1, speeds.2, accel, jerk),
            Geom::Quintic { p, m, c } if len > 1e-9 => {
                let sh = curve_shape(p, m, c);
                curve_profile(&sh, speeds.0, speeds.1, speeds.2, accel, jerk).unwrap_or_else(|| {
                    // Even the end speeds exceed the limits somewhere (a near-cusp the tangent
                    // stretching could not open): go through at the end speeds.
                    let (_, _, a_t, j_t) = curve_budget(accel, jerk);
                    Profile::s_curve(len, speeds.0, speeds.0.max(speeds.2), speeds.2, a_t, j_t)
                })
            }
            _ => Profile::new(len, speeds.0, speeds.1, speeds.2, accel),
        };
        s
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
            table: vec![0.0, 1.0],
            arc: Vec::new(),
        }
    }

    /// Position of the carrier at `λ`.
    fn carrier(&self, l: f64, f: &Feature, tip: f64) -> Point3 {
        match &self.geom {
            Geom::Line { a, b } => a + (b - a) * l,
            Geom::Quintic { p, m, c } => quintic(p, m, c, l, 0),
            Geom::Along { u0, u1, pen, x_len } => f.point(u0 + (u1 - u0) * l, tip - pen.at(l * x_len)),
            Geom::Hold { p } => *p,
        }
    }

    pub fn duration(&self) -> f64 {
        match self.geom {
            Geom::Hold { .. } => self.hold,
            _ => self.profile.duration(),
        }
    }

    /// Speed at the end (0 for holds).
    pub fn end_speed(&self) -> f64 {
        match self.geom {
            Geom::Hold { .. } => 0.0,
            _ => self.profile.v1,
        }
    }

    pub fn start_speed(&self) -> f64 {
        match self.geom {
            Geom::Hold { .. } => 0.0,
            _ => self.profile.v0,
        }
    }

    fn lambda(&self, s: f64) -> f64 {
        self.lambda_at(s, self.profile.len)
    }

    fn lambda_at(&self, s: f64, len: f64) -> f64 {
        if len <= 0.0 {
            return 0.0;
        }
        if let (Geom::Quintic { p, m, c }, false) = (&self.geom, self.arc.is_empty()) {
            // Newton on s(λ) = arc[i] + ∫ |P'| from λ_i, started from the linear guess.
            let s = s.clamp(0.0, self.arc[ARC_N]);
            let i = (self.arc.partition_point(|a| *a <= s).clamp(1, ARC_N)) - 1;
            let l0 = i as f64 / ARC_N as f64;
            let span = self.arc[i + 1] - self.arc[i];
            let mut l = if span > 0.0 { l0 + (s - self.arc[i]) / span / ARC_N as f64 } else { l0 };
            for _ in 0..8 {
                let f = self.arc[i] + gauss_length(p, m, c, l0, l) - s;
                let d = quintic(p, m, c, l, 1).coords.norm();
                if d < 1e-12 {
                    break;
                }
                let step = f / d;
                l = (l - step).clamp(l0, (i + 1) as f64 / ARC_N as f64);
                if step.abs() < 1e-15 {
                    break;
                }
            }
            return l;
        }
        let x = (s / len).clamp(0.0, 1.0) * TABLE_N as f64;
        let i = (x.floor() as usize).min(TABLE_N - 1);
        let f = x - i as f64;
        self.table[i] + (self.table[i + 1] - self.table[i]) * f
    }

    /// What the segment commands at local time `t`.
    pub fn eval(&self, t: f64, f: &Feature, tip: f64) -> Command {
        let (s, v) = self.profile.at(t);
        let l = self.lambda(s);
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
}

/// A planned program.
#[derive(Clone, Debug)]
pub struct Plan {
    pub style: Style,
    pub features: Vec<Feature>,
    pub params: Params,
    pub segments: Vec<Segment>,
    /// Start time of each segment.
    pub starts: Vec<f64>,
}

/// One sample of the planned path.
#[derive(Clone, Copy, Debug)]
pub struct PathSample {
    pub t: f64,
    pub position: Point3,
    pub speed: f64,
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

/// Home (start and end) point: above the first feature's scan start on its normal.
pub fn home(features: &[Feature], p: &Params) -> Point3 {
    features[0].point(0.0, p.tip_radius + p.clearance + 10.0)
}

/// Derivative `order` (0–3) of the quintic Hermite curve at `l`.
fn quintic(p: &[Point3; 2], m: &[Vector3; 2], c: &[Vector3; 2], l: f64, order: u8) -> Point3 {
    let (l2, l3) = (l * l, l * l * l);
    let (l4, l5) = (l3 * l, l3 * l2);
    // Basis (value, d/dλ, d²/dλ², d³/dλ³) for p0, m0, c0, c1, m1, p1.
    let w: [f64; 6] = match order {
        0 => [
            1.0 - 10.0 * l3 + 15.0 * l4 - 6.0 * l5,
            l - 6.0 * l3 + 8.0 * l4 - 3.0 * l5,
            0.5 * l2 - 1.5 * l3 + 1.5 * l4 - 0.5 * l5,
            0.5 * l3 - l4 + 0.5 * l5,
            -4.0 * l3 + 7.0 * l4 - 3.0 * l5,
            10.0 * l3 - 15.0 * l4 + 6.0 * l5,
        ],
        1 => [
            -30.0 * l2 + 60.0 * l3 - 30.0 * l4,
            1.0 - 18.0 * l2 + 32.0 * l3 - 15.0 * l4,
            l - 4.5 * l2 + 6.0 * l3 - 2.5 * l4,
            1.5 * l2 - 4.0 * l3 + 2.5 * l4,
            -12.0 * l2 + 28.0 * l3 - 15.0 * l4,
            30.0 * l2 - 60.0 * l3 + 30.0 * l4,
        ],
        2 => [
            -60.0 * l + 180.0 * l2 - 120.0 * l3,
            -36.0 * l + 96.0 * l2 - 60.0 * l3,
            1.0 - 9.0 * l + 18.0 * l2 - 10.0 * l3,
            3.0 * l - 12.0 * l2 + 10.0 * l3,
            -24.0 * l + 84.0 * l2 - 60.0 * l3,
            60.0 * l - 180.0 * l2 + 120.0 * l3,
        ],
        _ => [
            -60.0 + 360.0 * l - 360.0 * l2,
            -36.0 + 192.0 * l - 180.0 * l2,
            -9.0 + 36.0 * l - 30.0 * l2,
            3.0 - 24.0 * l + 30.0 * l2,
            -24.0 + 168.0 * l - 180.0 * l2,
            60.0 - 360.0 * l + 360.0 * l2,
        ],
    };
    let v = p[0].coords * w[0] + m[0] * w[1] + c[0] * w[2] + c[1] * w[3] + m[1] * w[4] + p[1].coords * w[5];
    Point3::from(v)
}

/// Steps of the arc-length table of a quintic carrier.
const ARC_N: usize = 64;

/// Arc length of the quintic between `l0` and `l1` (8-point Gauss–Legendre: the speed |P'| is
/// smooth, so this is exact to rounding on the short intervals used).
fn gauss_length(p: &[Point3; 2], m: &[Vector3; 2], c: &[Vector3; 2], l0: f64, l1: f64) -> f64 {
    const X: [f64; 4] =
        [0.183_434_642_495_649_8, 0.525_532_409_916_329, 0.796_666_477_413_626_7, 0.960_289_856_497_536_3];
    const W: [f64; 4] =
        [0.362_683_783_378_362, 0.313_706_645_877_887_3, 0.222_381_034_453_374_5, 0.101_228_536_290_376_3];
    let (h, mid) = (0.5 * (l1 - l0), 0.5 * (l1 + l0));
    let mut sum = 0.0;
    for (x, w) in X.iter().zip(W) {
        sum += w
            * (quintic(p, m, c, mid - h * x, 1).coords.norm()
                + quintic(p, m, c, mid + h * x, 1).coords.norm());
    }
    sum * h
}

/// The curve's shape along its length: at samples of arc length `s`, the curvature κ (1/mm)
/// and `q = κ² + |dκ/ds| + |κτ|` (1/mm²), the factor of v³ in the jerk.
#[derive(Clone, Debug, Default)]
struct CurveShape {
    s: Vec<f64>,
    kappa: Vec<f64>,
    q: Vec<f64>,
}

impl CurveShape {
    fn len(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// Largest κ and q over `[s0, s1]` (one sample beyond each end, for the sampling).
    fn max_in(&self, s0: f64, s1: f64) -> (f64, f64) {
        let n = self.s.len();
        let i0 = self.s.partition_point(|x| *x < s0).saturating_sub(1);
        let i1 = (self.s.partition_point(|x| *x <= s1) + 1).min(n);
        let mut out = (0.0f64, 0.0f64);
        for k in i0..i1 {
            out.0 = out.0.max(self.kappa[k]);
            out.1 = out.1.max(self.q[k]);
        }
        out
    }
}

fn curve_shape(p: &[Point3; 2], m: &[Vector3; 2], c: &[Vector3; 2]) -> CurveShape {
    const N: usize = 1024;
    let mut sh = CurveShape::default();
    let mut s = 0.0;
    let mut last = quintic(p, m, c, 0.0, 0);
    let mut kt = Vec::with_capacity(N + 1);
    for k in 0..=N {
        let l = k as f64 / N as f64;
        let pos = quintic(p, m, c, l, 0);
        s += (pos - last).norm();
        last = pos;
        let d1 = quintic(p, m, c, l, 1).coords;
        let d2 = quintic(p, m, c, l, 2).coords;
        let d3 = quintic(p, m, c, l, 3).coords;
        let sp = d1.norm();
        let cr = d1.cross(&d2);
        let (kappa, ktau) = if sp < 1e-9 {
            // A cusp: no finite speed limit would do.
            (f64::INFINITY, f64::INFINITY)
        } else {
            (cr.norm() / sp.powi(3), cr.dot(&d3).abs() / sp.powi(6))
        };
        sh.s.push(s);
        sh.kappa.push(kappa);
        kt.push(ktau);
    }
    for k in 0..=N {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(N));
        let ds = sh.s[b] - sh.s[a];
        let dk = if ds > 0.0 { (sh.kappa[b] - sh.kappa[a]).abs() / ds } else { f64::INFINITY };
        sh.q.push(sh.kappa[k] * sh.kappa[k] + dk + kt[k]);
    }
    sh
}

/// Limits used on curves (a 10 % margin covers the sampling of the curve): the total
/// acceleration and jerk allowed, and the tangential acceleration and jerk of speed changes.
fn curve_budget(accel: f64, jerk: f64) -> (f64, f64, f64, f64) {
    let (a_lim, j_lim) = (0.9 * accel, 0.9 * jerk);
    let a_t = a_lim * std::f64::consts::FRAC_1_SQRT_2;
    let j_t = 0.5 * j_lim;
    (a_lim, j_lim, a_t, j_t)
}

/// Whether speed `v` is within the limits on a stretch with largest κ and q, with (`accel_zone`)
/// or without tangential acceleration there:
/// `|a| ≤ √(a_t² + v⁴κ²)`, `|j| ≤ |j_t| + v³·q + 3·v·|a_t|·κ` (Frenet decomposition of the jerk).
fn speed_ok(v: f64, (kappa, q): (f64, f64), accel_zone: bool, accel: f64, jerk: f64) -> bool {
    let (a_lim, j_lim, a_t, j_t) = curve_budget(accel, jerk);
    if !(kappa.is_finite() && q.is_finite()) {
        return v == 0.0;
    }
    let lat = v * v * kappa;
    if accel_zone {
        lat <= a_t && j_t + v.powi(3) * q + 3.0 * v * a_t * kappa <= j_lim
    } else {
        lat <= a_lim && v.powi(3) * q <= j_lim
    }
}

/// The jerk-limited profile along a curve: the highest cruise speed (≤ `vmax`) for which the
/// cruise stretch and the two speed-change stretches (at the reduced tangential limits) keep the
/// total acceleration and jerk within the limits. `None` when even the end speeds cannot.
fn curve_profile(sh: &CurveShape, v0: f64, vmax: f64, v1: f64, accel: f64, jerk: f64) -> Option<Profile> {
    let (_, _, a_t, j_t) = curve_budget(accel, jerk);
    let len = sh.len();
    let lo = v0.max(v1);
    let feasible = |vp: f64| -> Option<Profile> {
        let pr = Profile::s_curve(len, v0, vp, v1, a_t, j_t);
        let (d_up, d_down) = pr.change_lengths();
        let cruise_ok = speed_ok(pr.vp, sh.max_in(d_up, len - d_down), false, accel, jerk);
        let up_ok = d_up <= 0.0 || speed_ok(pr.vp.max(v0), sh.max_in(0.0, d_up), true, accel, jerk);
        let down_ok =
            d_down <= 0.0 || speed_ok(pr.vp.max(v1), sh.max_in(len - d_down, len), true, accel, jerk);
        (cruise_ok && up_ok && down_ok).then_some(pr)
    };
    let hi = vmax.max(lo);
    if let Some(p) = feasible(hi) {
        return Some(p);
    }
    let mut best = feasible(lo)?;
    let (mut l, mut h) = (lo, hi);
    for _ in 0..40 {
        let mid = 0.5 * (l + h);
        match feasible(mid) {
            Some(p) => {
                best = p;
                l = mid;
            }
            None => h = mid,
        }
    }
    Some(best)
}

/// A transfer from `a` (leaving in direction `da` with curvature vector `ka`, 1/mm) to `b`
/// (arriving in direction `db` on a straight line), as a quintic Hermite whose tangent lengths
/// are about the chord (at most 45 mm, so long transfers stay nearly straight), times `stretch`.
fn quintic_between(a: Point3, da: Vector3, ka: Vector3, b: Point3, db: Vector3, stretch: f64) -> Geom {
    let k = (b - a).norm().clamp(1.0, 45.0) * stretch;
    // d²P/dλ² = κ·|dP/dλ|² along the normal at the start (no tangential component).
    Geom::Quintic { p: [a, b], m: [da * k, db * k], c: [ka * (k * k), Vector3::zeros()] }
}

/// The transfer segment from `a` to `b` (see [`quintic_between`]): the tangent lengths grow
/// until the curve's speed cap admits both end speeds (a tight turn between close features).
#[allow(clippy::too_many_arguments)]
fn transfer(
    i: usize,
    f: &Feature,
    p: &Params,
    (a, da, ka): (Point3, Vector3, Vector3),
    (b, db): (Point3, Vector3),
    speeds: (f64, f64, f64),
) -> Segment {
    let mut stretch = 1.0;
    loop {
        let g = quintic_between(a, da, ka, b, db, stretch);
        let ok = match &g {
            Geom::Quintic { p: pp, m, c } => {
                curve_profile(&curve_shape(pp, m, c), speeds.0, speeds.1, speeds.2, p.accel, p.jerk).is_some()
            }
            _ => true,
        };
        if ok || stretch > 8.0 {
            return Segment::new(SegmentKind::Transfer, i, g, f, p.tip_radius, speeds, (p.accel, p.jerk));
        }
        stretch *= 1.25;
    }
}

/// Unit direction and curvature vector (1/mm) at the end of a segment's carrier.
fn end_state(s: &Segment, f: &Feature, tip: f64) -> (Point3, Vector3, Vector3) {
    let e = s.carrier(1.0, f, tip);
    let h = 1e-3;
    let (p0, p1, p2) = (s.carrier(1.0 - 2.0 * h, f, tip), s.carrier(1.0 - h, f, tip), e);
    let d1 = (p2 - p0) / (2.0 * h);
    let d2 = (p2.coords - 2.0 * p1.coords + p0.coords) / (h * h);
    let sp = d1.norm();
    if sp < 1e-12 {
        return (e, Vector3::zeros(), Vector3::zeros());
    }
    let t = d1 / sp;
    // Curvature vector: the part of d²P/dλ² normal to the tangent, over |dP/dλ|².
    let kv = (d2 - t * d2.dot(&t)) / (sp * sp);
    (e, t, kv)
}

fn blended(features: &[Feature], p: &Params) -> Vec<Segment> {
    let tip = p.tip_radius;
    let (ca, sa) = (p.approach_angle.cos(), p.approach_angle.sin());
    let cot = ca / sa;
    let peak = p.deflection + p.overshoot;
    let x1 = 1.5 * peak / cot;
    let settle_len = settle_extension(p);
    let lift = p.clearance;
    let xr = 0.5;
    let k = cot / (3.0 * xr * xr);
    let rel_len = xr + ((p.deflection + lift) - k * xr.powi(3)) / cot;
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
            None => {
                let h = home(features, p);
                let d = (a - h).norm();
                let dir = if d > 1e-9 { (a - h) / d } else { w };
                transfer(i, f, p, (h, dir, Vector3::zeros()), (a, w), (0.0, p.move_speed, v))
            }
            Some(start) => transfer(i, f, p, start, (a, w), (v, p.move_speed, v)),
        };
        segs.push(tr);
        let mut ap = Segment::new(
            SegmentKind::Approach,
            i,
            Geom::Line { a, b: c0 },
            f,
            tip,
            (v, v, v),
            (p.accel, p.jerk),
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
            (v, v, v),
            (p.accel, p.jerk),
        );
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
            (v, v, v),
            (p.accel, p.jerk),
        );
        sc.feedback = true;
        segs.push(sc);
        let pen = Penetration::Release { d: p.deflection, k, xr, c: cot };
        let rl = Segment::new(
            SegmentKind::Release,
            i,
            Geom::Along { u0: ext, u1: ext + rel_len / m, pen, x_len: rel_len },
            f,
            tip,
            (v, v, v),
            (p.accel, p.jerk),
        );
        let end = end_state(&rl, f, tip);
        segs.push(rl);
        prev_end = Some(end);
    }
    // come to rest straight on from the last release
    if let Some((e, de, ke)) = prev_end {
        let f = &features[features.len() - 1];
        // Room for the jerk-limited stop even at the reduced tangential limits of a curve.
        let (a_t, j_t) = (0.6 * p.accel, 0.45 * p.jerk);
        let d = 0.55 * v * (v / a_t + a_t / j_t) + 1e-6;
        segs.push(transfer(features.len() - 1, f, p, (e, de, ke), (e + de * d.max(1.0), de), (v, v, 0.0)));
    }
    segs
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
            segs.push(Segment::new(
                SegmentKind::Transfer,
                i,
                Geom::Line { a: pos, b: pre },
                f,
                tip,
                (0.0, p.move_speed, 0.0),
                (p.accel, p.jerk),
            ));
        }
        segs.push(Segment::hold(SegmentKind::Approach, i, pre, p.prehit_dwell));
        let deep = c0 - n0 * p.deflection;
        let mut ap = Segment::new(
            SegmentKind::Approach,
            i,
            Geom::Line { a: pre, b: deep },
            f,
            tip,
            (0.0, p.touch_speed, 0.0),
            (p.accel, p.jerk),
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
            (0.0, p.scan_speed, 0.0),
            (p.accel, p.jerk),
        );
        sc.feedback = true;
        segs.push(sc);
        let a = f.point(ext, tip - p.deflection);
        let b = f.point(ext, tip + p.clearance);
        let mut rl = Segment::new(
            SegmentKind::Release,
            i,
            Geom::Line { a, b },
            f,
            tip,
            (0.0, p.move_speed, 0.0),
            (p.accel, p.jerk),
        );
        rl.plane = Some((f.point(ext, 0.0), f.normal(ext)));
        segs.push(rl);
        pos = b;
    }
    segs
}

impl Plan {
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
