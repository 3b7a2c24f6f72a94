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
//! climbs straight to the clearance; the transfer is a cubic Bézier tangent to the release at one
//! end and to the next approach at the other (no corners), on a trapezoidal speed profile from
//! scanning speed up to positioning speed and back. The settle path lies *before* the scan start
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
    Bezier([Point3; 4]),
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

/// Speed profile over a length: a trapezoid, or (for curved transfers) a sampled profile that
/// respects a lateral-acceleration speed limit along the curve.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// (t, s, v) samples of a curvature-limited profile; `None` for a trapezoid.
    table: Option<Vec<[f64; 3]>>,
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

    /// Time-optimal profile along a curve sampled at equal distances `ds` with speed limits
    /// `vlim` (one per sample, the first and last replaced by `v0` and `v1`): forward and
    /// backward passes with acceleration `a`, then constant acceleration between samples.
    pub fn limited(ds: f64, vlim: &[f64], v0: f64, v1: f64, a: f64) -> Profile {
        let n = vlim.len();
        if n < 2 || ds <= 0.0 {
            return Profile::new(ds * n.saturating_sub(1) as f64, v0, v0.max(v1), v1, a);
        }
        let mut v: Vec<f64> = vlim.to_vec();
        v[0] = v0;
        v[n - 1] = v1;
        for i in 1..n {
            v[i] = v[i].min((v[i - 1] * v[i - 1] + 2.0 * a * ds).sqrt());
        }
        v[n - 1] = v1;
        for i in (0..n - 1).rev() {
            v[i] = v[i].min((v[i + 1] * v[i + 1] + 2.0 * a * ds).sqrt());
        }
        v[0] = v0;
        let mut table = Vec::with_capacity(n);
        let mut t = 0.0;
        table.push([0.0, 0.0, v[0]]);
        for i in 1..n {
            let vm = (v[i - 1] + v[i]).max(1e-9);
            t += 2.0 * ds / vm;
            table.push([t, ds * i as f64, v[i]]);
        }
        let len = ds * (n - 1) as f64;
        Profile { table: Some(table), len, v0, v1, vp: v0.max(v1), a0: a, a1: a, t0: 0.0, tc: 0.0, t1: 0.0 }
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
            let i = tb.partition_point(|r| r[0] <= t).clamp(1, tb.len() - 1) - 1;
            let (r0, r1) = (tb[i], tb[i + 1]);
            let dt = r1[0] - r0[0];
            let acc = if dt > 0.0 { (r1[2] - r0[2]) / dt } else { 0.0 };
            let tau = t - r0[0];
            return ((r0[1] + r0[2] * tau + 0.5 * acc * tau * tau).min(r1[1]), r0[2] + acc * tau);
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
        accel: f64,
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
        let len = cum[TABLE_N];
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
        s.profile = if matches!(s.geom, Geom::Bezier(_)) && len > 1e-9 {
            // cap the speed where the curve bends: lateral acceleration v²/ρ ≤ accel
            const N: usize = 128;
            let ds = len / N as f64;
            let pts: Vec<Point3> =
                (0..=N).map(|k| s.carrier(s.lambda_at(ds * k as f64, len), f, tip)).collect();
            let mut vlim = vec![speeds.1; N + 1];
            for k in 1..N {
                let (a, b) = (pts[k] - pts[k - 1], pts[k + 1] - pts[k]);
                let (la, lb) = (a.norm(), b.norm());
                if la > 1e-12 && lb > 1e-12 {
                    let turn = (a.dot(&b) / (la * lb)).clamp(-1.0, 1.0).acos();
                    if turn > 1e-12 {
                        let rho = 0.5 * (la + lb) / turn;
                        vlim[k] = vlim[k].min((accel * rho).sqrt());
                    }
                }
            }
            // never below half the slower end speed: a near-cusp must not become a stop
            let floor = 0.5 * speeds.0.max(speeds.2).min(if speeds.0 > 0.0 { speeds.0 } else { speeds.2 });
            for v in vlim.iter_mut() {
                *v = v.max(floor);
            }
            Profile::limited(ds, &vlim, speeds.0, speeds.2, accel)
        } else {
            Profile::new(len, speeds.0, speeds.1, speeds.2, accel)
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
        }
    }

    /// Position of the carrier at `λ`.
    fn carrier(&self, l: f64, f: &Feature, tip: f64) -> Point3 {
        match &self.geom {
            Geom::Line { a, b } => a + (b - a) * l,
            Geom::Bezier([p0, p1, p2, p3]) => {
                let m = 1.0 - l;
                Point3::from(
                    p0.coords * (m * m * m)
                        + p1.coords * (3.0 * m * m * l)
                        + p2.coords * (3.0 * m * l * l)
                        + p3.coords * (l * l * l),
                )
            }
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

    /// Unit direction of motion at the end (or start) of the carrier.
    fn direction(&self, at_end: bool, f: &Feature, tip: f64) -> Vector3 {
        let (a, b) = if at_end { (1.0 - 1e-4, 1.0) } else { (0.0, 1e-4) };
        let d = self.carrier(b, f, tip) - self.carrier(a, f, tip);
        if d.norm() > 1e-12 {
            d.normalize()
        } else {
            Vector3::zeros()
        }
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

fn bezier_between(a: Point3, da: Vector3, b: Point3, db: Vector3) -> Geom {
    // tangent arms of at most 15 mm: long enough for a gentle turn at scanning speed, short
    // enough that long transfers stay nearly straight (no loops)
    let k = ((b - a).norm() / 3.0).min(15.0);
    Geom::Bezier([a, a + da * k, b - db * k, b])
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
    let mut prev_end: Option<(Point3, Vector3)> = None;
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
                let g = bezier_between(h, dir, a, w);
                Segment::new(SegmentKind::Transfer, i, g, f, tip, (0.0, p.move_speed, v), p.accel)
            }
            Some((e, de)) => Segment::new(
                SegmentKind::Transfer,
                i,
                bezier_between(e, de, a, w),
                f,
                tip,
                (v, p.move_speed, v),
                p.accel,
            ),
        };
        segs.push(tr);
        let mut ap =
            Segment::new(SegmentKind::Approach, i, Geom::Line { a, b: c0 }, f, tip, (v, v, v), p.accel);
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
            p.accel,
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
            p.accel,
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
            p.accel,
        );
        let e = rl.carrier(1.0, f, tip);
        let de = rl.direction(true, f, tip);
        segs.push(rl);
        prev_end = Some((e, de));
    }
    // come to rest straight on from the last release
    if let Some((e, de)) = prev_end {
        let f = &features[features.len() - 1];
        let d = v * v / (2.0 * p.accel) + 1e-6;
        segs.push(Segment::new(
            SegmentKind::Transfer,
            features.len() - 1,
            Geom::Line { a: e, b: e + de * d },
            f,
            tip,
            (v, v, 0.0),
            p.accel,
        ));
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
                p.accel,
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
            p.accel,
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
            p.accel,
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
            p.accel,
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
