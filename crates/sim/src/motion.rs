//! Machine motion: commanded trajectories with acceleration- or jerk-limited profiles, and a servo
//! model with following error, so that a commanded stop is not an instant stop.
//!
//! Everything is a [`Motion`]: position, velocity and acceleration of the probe body at any time
//! `t` (s, master clock true time). Before its start a motion rests at its first position; after
//! its end it rests at its last.
//!
//! Entry points:
//! - [`Limits`] (`v_max`, `a_max`, optional `j_max`) and [`Profile`]: a scalar profile of a
//!   given length. [`Profile::new`] is rest-to-rest: without `j_max` the time-optimal trapezoid;
//!   with `j_max` the trapezoid passed through a moving-average filter of length
//!   `a_max / j_max`, which gives the standard jerk-limited S-curve exactly (jerk ≤ `j_max`,
//!   |a| ≤ `a_max`, |v| ≤ `v_max`). [`Profile::with_speeds`] goes from a start speed to an end
//!   speed (acceleration-limited).
//! - [`Trajectory`]: a commanded path built from pieces: [`Trajectory::line_to`] (rest-to-rest
//!   straight move), [`Trajectory::line_speeds`] (straight move between given entry and exit
//!   speeds, e.g. rest → scan speed), [`Trajectory::cruise_to`] (straight, constant speed),
//!   [`Trajectory::arc_cruise`] (circular arc at constant speed), [`Trajectory::arc_to`]
//!   (rest-to-rest circular arc), [`Trajectory::polyline`] (rest-to-rest through points),
//!   [`Trajectory::dwell`], and [`Trajectory::custom`] (any parametric `State` function of local
//!   time, e.g. a scan path). Constant-speed pieces do not ramp: the caller keeps speed and
//!   direction continuous at the joins (a direction change at a join is an instant turn).
//! - [`Servo`] / [`ServoMotion`]: the actual motion of an axis set under a position loop with
//!   velocity feed-forward and partial acceleration feed-forward. Per axis the following error
//!   `e = commanded − actual` obeys `ë + 2ζω ė + ω² e = (1 − k_a) c̈`: zero error at constant
//!   velocity, a lag of `(1 − k_a)·a/ω²` while accelerating, and an overshoot that rings out
//!   after a commanded stop. The error is integrated once, exactly (matrix exponential, forcing
//!   averaged over each step), on a grid of step `dt`, and read back by cubic Hermite
//!   interpolation, so `state(t)` costs one table lookup plus one commanded evaluation.

use std::sync::Arc;

use nalgebra::Matrix2;
use truepos_math::{Point3, Vector3};

use crate::noise::{check_nonneg, check_positive, check_range, ParamError};

/// Position (mm), velocity (mm/s) and acceleration (mm/s²) at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// Position, mm.
    pub p: Point3,
    /// Velocity, mm/s.
    pub v: Vector3,
    /// Acceleration, mm/s².
    pub a: Vector3,
}

impl State {
    /// At rest at `p`.
    pub fn rest(p: Point3) -> Self {
        State { p, v: Vector3::zeros(), a: Vector3::zeros() }
    }
}

/// A motion of the probe body on the master clock.
pub trait Motion: Send + Sync {
    /// The state at true time `t` (s).
    fn state(&self, t: f64) -> State;
    /// Start time (s).
    fn start_s(&self) -> f64;
    /// End time (s): at rest from here on.
    fn end_s(&self) -> f64;
}

/// Kinematic limits of a move (mm/s, mm/s², mm/s³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Speed limit, mm/s.
    pub v_max: f64,
    /// Acceleration limit, mm/s².
    pub a_max: f64,
    /// Jerk limit, mm/s³ (`None`: trapezoidal, unlimited jerk).
    pub j_max: Option<f64>,
}

impl Limits {
    /// Acceleration-limited (trapezoidal) limits.
    pub fn accel(v_max: f64, a_max: f64) -> Self {
        Limits { v_max, a_max, j_max: None }
    }

    /// Jerk-limited (S-curve) limits.
    pub fn jerk(v_max: f64, a_max: f64, j_max: f64) -> Self {
        Limits { v_max, a_max, j_max: Some(j_max) }
    }

    fn validate(&self) -> Result<(), ParamError> {
        check_positive("v_max", self.v_max)?;
        check_positive("a_max", self.a_max)?;
        if let Some(j) = self.j_max {
            check_positive("j_max", j)?;
        }
        Ok(())
    }
}

/// A scalar motion profile over a length (mm or rad): rest-to-rest (trapezoid or S-curve), or
/// acceleration-limited between given start and end speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    len: f64,
    a: f64,
    v0: f64,
    v1: f64,
    vp: f64,
    /// Durations of the acceleration, cruise and deceleration phases (s).
    ta: f64,
    tc: f64,
    td: f64,
    /// Moving-average window (s); 0 for the plain trapezoid.
    tf: f64,
}

impl Profile {
    /// The rest-to-rest profile covering `len ≥ 0` within `limits`.
    pub fn new(len: f64, limits: &Limits) -> Result<Self, ParamError> {
        let mut p = Self::with_speeds(len, 0.0, 0.0, &Limits { j_max: None, ..*limits })?;
        p.tf = limits.j_max.map_or(0.0, |j| limits.a_max / j);
        limits.validate()?;
        Ok(p)
    }

    /// The fastest acceleration-limited profile covering `len` that starts at speed `v0` and
    /// ends at speed `v1` (both ≤ `v_max`; `j_max` is ignored). Fails when `len` is too short to
    /// change speed from `v0` to `v1` at `a_max`.
    pub fn with_speeds(len: f64, v0: f64, v1: f64, limits: &Limits) -> Result<Self, ParamError> {
        check_nonneg("move length", len)?;
        Limits { j_max: None, ..*limits }.validate()?;
        let (vm, a) = (limits.v_max, limits.a_max);
        check_range("start speed", v0, 0.0, vm)?;
        check_range("end speed", v1, 0.0, vm)?;
        if (v1 * v1 - v0 * v0).abs() > 2.0 * a * len * (1.0 + 1e-12) + 1e-15 {
            return Err(ParamError::Invalid {
                name: "move length",
                requirement: "long enough to change speed at the acceleration limit",
                value: len,
            });
        }
        let need = (2.0 * vm * vm - v0 * v0 - v1 * v1) / (2.0 * a);
        let vp =
            if len >= need { vm } else { ((2.0 * a * len + v0 * v0 + v1 * v1) / 2.0).sqrt().max(v0).max(v1) };
        let ta = (vp - v0) / a;
        let td = (vp - v1) / a;
        let d_ramps = (vp * vp - v0 * v0) / (2.0 * a) + (vp * vp - v1 * v1) / (2.0 * a);
        let tc = if vp > 0.0 { ((len - d_ramps) / vp).max(0.0) } else { 0.0 };
        Ok(Profile { len, a, v0, v1, vp, ta, tc, td, tf: 0.0 })
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        self.ta + self.tc + self.td + self.tf
    }

    /// Length (mm or rad).
    pub fn len(&self) -> f64 {
        self.len
    }

    /// Peak speed reached.
    pub fn peak_speed(&self) -> f64 {
        self.vp
    }

    fn t_trap(&self) -> f64 {
        self.ta + self.tc + self.td
    }

    /// Trapezoid: (s, v, a, ∫s dt) at t (the integral is used for rest-to-rest profiles only).
    fn trap(&self, t: f64) -> (f64, f64, f64, f64) {
        let (a, v0, vp) = (self.a, self.v0, self.vp);
        let (ta, tc, td) = (self.ta, self.tc, self.td);
        if t <= 0.0 {
            return (v0 * t, v0, 0.0, 0.5 * v0 * t * t);
        }
        let s1 = v0 * ta + 0.5 * a * ta * ta;
        let i1 = 0.5 * v0 * ta * ta + a * ta * ta * ta / 6.0;
        if t < ta {
            return (v0 * t + 0.5 * a * t * t, v0 + a * t, a, 0.5 * v0 * t * t + a * t * t * t / 6.0);
        }
        let t2 = ta + tc;
        let s2 = s1 + vp * tc;
        let i2 = i1 + s1 * tc + 0.5 * vp * tc * tc;
        if t < t2 {
            let u = t - ta;
            return (s1 + vp * u, vp, 0.0, i1 + s1 * u + 0.5 * vp * u * u);
        }
        let tt = self.t_trap();
        if t < tt {
            let u = t - t2;
            let s = s2 + vp * u - 0.5 * a * u * u;
            return (s, vp - a * u, -a, i2 + s2 * u + 0.5 * vp * u * u - a * u * u * u / 6.0);
        }
        let u = td;
        let i3 = i2 + s2 * u + 0.5 * vp * u * u - a * u * u * u / 6.0;
        let w = t - tt;
        (self.len + self.v1 * w, self.v1, 0.0, i3 + self.len * w + 0.5 * self.v1 * w * w)
    }

    /// (s, ṡ, s̈) at local time `t`.
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        if self.tf <= 0.0 {
            let (s, v, a, _) = self.trap(t);
            return (s, v, a);
        }
        let (s1, v1, _, i1) = self.trap(t);
        let (s0, v0, _, i0) = self.trap(t - self.tf);
        ((i1 - i0) / self.tf, (s1 - s0) / self.tf, (v1 - v0) / self.tf)
    }
}

/// A piece of a commanded trajectory (local time from 0).
#[derive(Clone)]
enum Piece {
    Line { from: Point3, dir: Vector3, profile: Profile },
    Cruise { from: Point3, vel: Vector3 },
    Dwell { at: Point3 },
    Arc { centre: Point3, e1: Vector3, e2: Vector3, radius: f64, sign: f64, profile: Profile },
    Custom(Arc<dyn Fn(f64) -> State + Send + Sync>),
}

impl Piece {
    fn state(&self, u: f64) -> State {
        match self {
            Piece::Line { from, dir, profile } => {
                let (s, v, a) = profile.eval(u);
                State { p: from + dir * s, v: dir * v, a: dir * a }
            }
            Piece::Cruise { from, vel } => State { p: from + vel * u, v: *vel, a: Vector3::zeros() },
            Piece::Dwell { at } => State::rest(*at),
            Piece::Arc { centre, e1, e2, radius, sign, profile } => {
                let (s, v, a) = profile.eval(u);
                let th = sign * s / radius;
                let (sn, cs) = th.sin_cos();
                let radial = e1 * cs + e2 * sn;
                let tangent = (e2 * cs - e1 * sn) * *sign;
                State {
                    p: centre + radial * *radius,
                    v: tangent * v,
                    a: tangent * a - radial * (v * v / radius),
                }
            }
            Piece::Custom(f) => f(u),
        }
    }
}

/// A commanded trajectory: pieces laid end to end in time.
#[derive(Clone)]
pub struct Trajectory {
    start_s: f64,
    starts: Vec<f64>,
    durations: Vec<f64>,
    pieces: Vec<Piece>,
    first: Point3,
    last: State,
}

impl std::fmt::Debug for Trajectory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Trajectory")
            .field("start_s", &self.start_s)
            .field("pieces", &self.pieces.len())
            .field("end_s", &self.end_s())
            .finish()
    }
}

impl Trajectory {
    /// An empty trajectory resting at `start` from time `start_s`.
    pub fn new(start_s: f64, start: Point3) -> Self {
        Trajectory {
            start_s,
            starts: Vec::new(),
            durations: Vec::new(),
            pieces: Vec::new(),
            first: start,
            last: State::rest(start),
        }
    }

    /// Where the trajectory currently ends (position and velocity at its end).
    pub fn end_state(&self) -> State {
        self.last
    }

    /// Current end position.
    pub fn position(&self) -> Point3 {
        self.last.p
    }

    fn push(&mut self, piece: Piece, duration: f64) {
        let t0 = self.end_s();
        self.last = piece.state(duration);
        self.starts.push(t0);
        self.durations.push(duration);
        self.pieces.push(piece);
    }

    /// Rest-to-rest straight move to `to` within `limits`.
    pub fn line_to(&mut self, to: Point3, limits: &Limits) -> Result<&mut Self, ParamError> {
        let d = to - self.last.p;
        let len = d.norm();
        let profile = Profile::new(len, limits)?;
        let dir = if len > 0.0 { d / len } else { Vector3::zeros() };
        let from = self.last.p;
        self.push(Piece::Line { from, dir, profile }, profile.duration());
        // Land exactly on `to` (no round-off drift along long programs).
        self.last = State::rest(to);
        Ok(self)
    }

    /// Straight move to `to` entering at speed `v_start` and leaving at `v_end` along the line
    /// (acceleration-limited, cruising at `limits.v_max` where there is room). Chain these with
    /// [`Trajectory::cruise_to`] for constant-speed paths without stops; the caller keeps the
    /// direction continuous at the joins.
    pub fn line_speeds(
        &mut self,
        to: Point3,
        v_start: f64,
        v_end: f64,
        limits: &Limits,
    ) -> Result<&mut Self, ParamError> {
        let d = to - self.last.p;
        let len = d.norm();
        let profile = Profile::with_speeds(len, v_start, v_end, limits)?;
        let dir = if len > 0.0 { d / len } else { Vector3::zeros() };
        let from = self.last.p;
        self.push(Piece::Line { from, dir, profile }, profile.duration());
        self.last = State { p: to, v: dir * v_end, a: Vector3::zeros() };
        Ok(self)
    }

    /// Straight move to `to` at constant `speed` (no acceleration phase: the velocity jumps at
    /// the joins unless the neighbouring pieces match it).
    pub fn cruise_to(&mut self, to: Point3, speed: f64) -> Result<&mut Self, ParamError> {
        check_positive("cruise speed", speed)?;
        let d = to - self.last.p;
        let len = d.norm();
        let from = self.last.p;
        let vel = if len > 0.0 { d * (speed / len) } else { Vector3::zeros() };
        self.push(Piece::Cruise { from, vel }, len / speed);
        self.last.p = to;
        Ok(self)
    }

    /// Rest-to-rest circular arc about the axis through `centre` along `normal`, turning by
    /// `sweep_rad` (right-hand rule about `normal`) from the current position.
    pub fn arc_to(
        &mut self,
        centre: Point3,
        normal: Vector3,
        sweep_rad: f64,
        limits: &Limits,
    ) -> Result<&mut Self, ParamError> {
        let nn = normal.norm();
        check_positive("arc normal length", nn)?;
        let n = normal / nn;
        let r_vec = self.last.p - centre;
        let radial = r_vec - n * r_vec.dot(&n);
        let radius = check_positive("arc radius", radial.norm())?;
        let e1 = radial / radius;
        let e2 = n.cross(&e1);
        let centre = centre + n * r_vec.dot(&n);
        let profile = Profile::new(sweep_rad.abs() * radius, limits)?;
        let sign = if sweep_rad < 0.0 { -1.0 } else { 1.0 };
        self.push(Piece::Arc { centre, e1, e2, radius, sign, profile }, profile.duration());
        self.last.v = Vector3::zeros();
        self.last.a = Vector3::zeros();
        Ok(self)
    }

    /// Circular arc at constant `speed` about the axis through `centre` along `normal`, turning
    /// by `sweep_rad` (right-hand rule about `normal`) from the current position; centripetal
    /// acceleration `speed²/radius`, no tangential ramps.
    pub fn arc_cruise(
        &mut self,
        centre: Point3,
        normal: Vector3,
        sweep_rad: f64,
        speed: f64,
    ) -> Result<&mut Self, ParamError> {
        check_positive("arc speed", speed)?;
        let nn = normal.norm();
        check_positive("arc normal length", nn)?;
        let n = normal / nn;
        let r_vec = self.last.p - centre;
        let radial = r_vec - n * r_vec.dot(&n);
        let radius = check_positive("arc radius", radial.norm())?;
        let e1 = radial / radius;
        let e2 = n.cross(&e1);
        let centre = centre + n * r_vec.dot(&n);
        let len = sweep_rad.abs() * radius;
        let lim = Limits::accel(speed, 1.0);
        let profile = Profile::with_speeds(len, speed, speed, &lim)?;
        let sign = if sweep_rad < 0.0 { -1.0 } else { 1.0 };
        self.push(Piece::Arc { centre, e1, e2, radius, sign, profile }, profile.duration());
        Ok(self)
    }

    /// Rest-to-rest moves through each point in turn.
    pub fn polyline(&mut self, points: &[Point3], limits: &Limits) -> Result<&mut Self, ParamError> {
        for p in points {
            self.line_to(*p, limits)?;
        }
        Ok(self)
    }

    /// Stay where the trajectory ends for `duration_s`.
    pub fn dwell(&mut self, duration_s: f64) -> Result<&mut Self, ParamError> {
        check_nonneg("dwell", duration_s)?;
        let at = self.last.p;
        self.push(Piece::Dwell { at }, duration_s);
        self.last = State::rest(at);
        Ok(self)
    }

    /// Any parametric piece: `f(u)` for local time `u ∈ [0, duration_s]`. It should start where
    /// the trajectory ends (the caller's responsibility).
    pub fn custom(
        &mut self,
        duration_s: f64,
        f: impl Fn(f64) -> State + Send + Sync + 'static,
    ) -> Result<&mut Self, ParamError> {
        check_nonneg("piece duration", duration_s)?;
        self.push(Piece::Custom(Arc::new(f)), duration_s);
        Ok(self)
    }

    /// Number of pieces.
    pub fn len(&self) -> usize {
        self.pieces.len()
    }

    /// True when no piece was added.
    pub fn is_empty(&self) -> bool {
        self.pieces.is_empty()
    }

    /// Start time of piece `i` (s).
    pub fn piece_start_s(&self, i: usize) -> Option<f64> {
        self.starts.get(i).copied()
    }
}

impl Motion for Trajectory {
    fn state(&self, t: f64) -> State {
        if self.pieces.is_empty() || t <= self.start_s {
            return State::rest(self.first);
        }
        let i = self.starts.partition_point(|&s| s <= t).saturating_sub(1);
        let u = t - self.starts[i];
        if i + 1 == self.pieces.len() && u >= self.durations[i] {
            return State::rest(self.last.p);
        }
        self.pieces[i].state(u.min(self.durations[i]))
    }

    fn start_s(&self) -> f64 {
        self.start_s
    }

    fn end_s(&self) -> f64 {
        self.starts.last().zip(self.durations.last()).map_or(self.start_s, |(s, d)| s + d)
    }
}

/// Position-loop parameters (same on every axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Servo {
    /// Natural frequency of the error dynamics (Hz).
    pub bandwidth_hz: f64,
    /// Damping ratio.
    pub damping: f64,
    /// Acceleration feed-forward fraction `k_a` in `[0, 1]` (1: perfect tracking).
    pub accel_feedforward: f64,
}

impl Default for Servo {
    /// A stiff CMM/machine-tool loop: 60 Hz, ζ = 0.7, 90 % acceleration feed-forward.
    fn default() -> Self {
        Servo { bandwidth_hz: 60.0, damping: 0.7, accel_feedforward: 0.9 }
    }
}

/// The actual motion of a commanded trajectory through a [`Servo`].
pub struct ServoMotion<M: Motion> {
    cmd: M,
    t0: f64,
    dt: f64,
    w2: f64,
    two_zw: f64,
    gain: f64,
    /// (e, ė) per node, per axis.
    table: Vec<[f64; 6]>,
}

impl<M: Motion> ServoMotion<M> {
    /// Integrate the following error of `cmd` on a grid of step `dt_s` (e.g. 1e-4 s), over the
    /// commanded span plus a settling time of `10/(ζω)` (capped at 1 s).
    pub fn new(cmd: M, servo: &Servo, dt_s: f64) -> Result<Self, ParamError> {
        check_positive("servo bandwidth", servo.bandwidth_hz)?;
        check_positive("servo damping", servo.damping)?;
        check_range("acceleration feed-forward", servo.accel_feedforward, 0.0, 1.0)?;
        check_positive("servo step", dt_s)?;
        let w = 2.0 * std::f64::consts::PI * servo.bandwidth_hz;
        let (w2, two_zw) = (w * w, 2.0 * servo.damping * w);
        let gain = 1.0 - servo.accel_feedforward;
        let settle = (10.0 / (servo.damping * w)).min(1.0);
        let t0 = cmd.start_s();
        let n = (((cmd.end_s() + settle - t0) / dt_s).ceil() as usize).max(1) + 1;
        let phi = (Matrix2::new(0.0, 1.0, -w2, -two_zw) * dt_s).exp();
        let mut table = Vec::with_capacity(n);
        let mut e = [[0.0f64; 2]; 3];
        let mut a_prev = cmd.state(t0).a;
        table.push([0.0; 6]);
        for k in 1..n {
            let a_next = cmd.state(t0 + k as f64 * dt_s).a;
            let f = (a_prev + a_next) * (0.5 * gain);
            let mut row = [0.0; 6];
            for i in 0..3 {
                let eq = f[i] / w2;
                let x = e[i][0] - eq;
                let v = e[i][1];
                e[i][0] = phi[(0, 0)] * x + phi[(0, 1)] * v + eq;
                e[i][1] = phi[(1, 0)] * x + phi[(1, 1)] * v;
                row[2 * i] = e[i][0];
                row[2 * i + 1] = e[i][1];
            }
            table.push(row);
            a_prev = a_next;
        }
        Ok(ServoMotion { cmd, t0, dt: dt_s, w2, two_zw, gain, table })
    }

    /// The commanded motion.
    pub fn commanded(&self) -> &M {
        &self.cmd
    }

    /// Following error `commanded − actual` (mm) at `t`, and its rate.
    pub fn following_error(&self, t: f64) -> (Vector3, Vector3) {
        let x = (t - self.t0) / self.dt;
        if x <= 0.0 {
            return (Vector3::zeros(), Vector3::zeros());
        }
        let last = self.table.len() - 1;
        let i = (x.floor() as usize).min(last);
        if i == last {
            let r = &self.table[last];
            return (Vector3::new(r[0], r[2], r[4]), Vector3::new(r[1], r[3], r[5]));
        }
        let s = x - i as f64;
        let (r0, r1) = (&self.table[i], &self.table[i + 1]);
        // Cubic Hermite for e, linear for ė.
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        let mut e = Vector3::zeros();
        let mut ed = Vector3::zeros();
        for k in 0..3 {
            e[k] = h00 * r0[2 * k]
                + h10 * self.dt * r0[2 * k + 1]
                + h01 * r1[2 * k]
                + h11 * self.dt * r1[2 * k + 1];
            ed[k] = r0[2 * k + 1] + s * (r1[2 * k + 1] - r0[2 * k + 1]);
        }
        (e, ed)
    }
}

impl<M: Motion> Motion for ServoMotion<M> {
    fn state(&self, t: f64) -> State {
        let c = self.cmd.state(t);
        let (e, ed) = self.following_error(t);
        let edd = c.a * self.gain - e * self.w2 - ed * self.two_zw;
        State { p: c.p - e, v: c.v - ed, a: c.a - edd }
    }

    fn start_s(&self) -> f64 {
        self.t0
    }

    fn end_s(&self) -> f64 {
        self.t0 + (self.table.len() - 1) as f64 * self.dt
    }
}

impl<M: Motion + ?Sized> Motion for Box<M> {
    fn state(&self, t: f64) -> State {
        (**self).state(t)
    }
    fn start_s(&self) -> f64 {
        (**self).start_s()
    }
    fn end_s(&self) -> f64 {
        (**self).end_s()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_derivatives(m: &dyn Motion, t0: f64, t1: f64, tol_v: f64, tol_a: f64) {
        // Central differences with h = 1e-6 s: truncation error h²/6·(third derivative) is far
        // below the tolerances; where the acceleration jumps (trapezoid) we skip points whose
        // acceleration changes within ±h.
        let h = 1e-6;
        let n = 2000;
        for k in 1..n {
            let t = t0 + (t1 - t0) * k as f64 / n as f64;
            let (a, b, c) = (m.state(t - h), m.state(t), m.state(t + h));
            if (a.a - c.a).norm() > 1e-9 {
                continue;
            }
            let v = (c.p - a.p) / (2.0 * h);
            let acc = (c.v - a.v) / (2.0 * h);
            assert!((v - b.v).norm() < tol_v, "v at {t}: {v} vs {}", b.v);
            assert!((acc - b.a).norm() < tol_a, "a at {t}: {acc} vs {}", b.a);
        }
    }

    #[test]
    fn trapezoid_and_s_curve_respect_limits_and_arrive() {
        for lim in [Limits::accel(50.0, 1000.0), Limits::jerk(50.0, 1000.0, 50_000.0)] {
            for len in [0.0, 0.5, 2.5, 100.0] {
                let p = Profile::new(len, &lim).unwrap();
                let t_end = p.duration();
                let (s, v, a) = p.eval(t_end + 0.1);
                assert!((s - len).abs() < 1e-9 && v.abs() < 1e-9 && a.abs() < 1e-9);
                for k in 0..=1000 {
                    let (_, v, a) = p.eval(t_end * k as f64 / 1000.0);
                    assert!(v <= lim.v_max + 1e-9 && v >= -1e-9);
                    assert!(a.abs() <= lim.a_max + 1e-9);
                }
            }
        }
        // Trapezoid duration: 100 mm at 50 mm/s, 1000 mm/s²: 2·0.05 + (100 − 2.5)/50 = 2.05 s.
        assert!((Profile::new(100.0, &Limits::accel(50.0, 1000.0)).unwrap().duration() - 2.05).abs() < 1e-12);
    }

    #[test]
    fn profiles_between_speeds_join_without_velocity_jumps() {
        let lim = Limits::accel(30.0, 800.0);
        let p = Profile::with_speeds(10.0, 5.0, 20.0, &lim).unwrap();
        let (s, v, _) = p.eval(p.duration());
        assert!((s - 10.0).abs() < 1e-12 && (v - 20.0).abs() < 1e-12);
        assert_eq!(p.eval(0.0).1, 5.0);
        // Too short to go from 0 to 30 mm/s at 800 mm/s²: needs 0.5625 mm.
        assert!(Profile::with_speeds(0.5, 0.0, 30.0, &lim).is_err());
        // Rest → scan speed → constant-speed line → constant-speed arc → rest: continuous velocity.
        let mut tr = Trajectory::new(0.0, Point3::origin());
        tr.line_speeds(Point3::new(5.0, 0.0, 0.0), 0.0, 10.0, &lim).unwrap();
        tr.cruise_to(Point3::new(15.0, 0.0, 0.0), 10.0).unwrap();
        tr.arc_cruise(Point3::new(15.0, 5.0, 0.0), Vector3::z(), std::f64::consts::FRAC_PI_2, 10.0).unwrap();
        let end = tr.position();
        assert!((end - Point3::new(20.0, 5.0, 0.0)).norm() < 1e-12, "{end}");
        tr.line_speeds(Point3::new(20.0, 10.0, 0.0), 10.0, 0.0, &lim).unwrap();
        let t_end = tr.end_s();
        let mut prev = tr.state(0.0).v;
        for k in 1..=20_000 {
            let v = tr.state(t_end * k as f64 / 20_000.0).v;
            // Bounded acceleration: between samples Δt apart the velocity changes by at most
            // max(a_max, v²/r = 20 mm/s²)·Δt (no jumps at the joins).
            assert!((v - prev).norm() <= 800.0 * t_end / 20_000.0 + 1e-9, "jump at {k}");
            prev = v;
        }
        check_derivatives(&tr, 0.0, t_end, 1e-5, 1e-2);
    }

    #[test]
    fn trajectory_states_are_consistent_derivatives() {
        let mut tr = Trajectory::new(0.0, Point3::new(0.0, 0.0, 0.0));
        let lim = Limits::jerk(20.0, 500.0, 20_000.0);
        tr.line_to(Point3::new(10.0, 0.0, 0.0), &lim).unwrap();
        tr.arc_to(Point3::new(0.0, 0.0, 0.0), Vector3::z(), 1.0, &lim).unwrap();
        tr.dwell(0.1).unwrap();
        tr.cruise_to(Point3::new(0.0, 0.0, 5.0), 10.0).unwrap();
        let end = tr.end_s();
        check_derivatives(&tr, 0.0, end, 1e-5, 1e-2);
        // The arc keeps its radius.
        let t_arc = tr.piece_start_s(1).unwrap() + 0.05;
        assert!(((tr.state(t_arc).p - Point3::origin()).norm() - 10.0).abs() < 1e-12);
        assert_eq!(tr.state(end + 1.0).p, Point3::new(0.0, 0.0, 5.0));
    }

    #[test]
    fn servo_lags_by_the_analytic_amount_and_overshoots_a_stop() {
        // Constant acceleration a: steady following error (1 − k_a)·a/ω².
        let a = 2000.0;
        let mut tr = Trajectory::new(0.0, Point3::origin());
        tr.line_to(Point3::new(100.0, 0.0, 0.0), &Limits::accel(400.0, a)).unwrap();
        let servo = Servo { bandwidth_hz: 50.0, damping: 0.7, accel_feedforward: 0.5 };
        let m = ServoMotion::new(tr, &servo, 1e-4).unwrap();
        let w = 2.0 * std::f64::consts::PI * 50.0;
        // After 0.15 s of the 0.2 s acceleration phase the transient has decayed by
        // exp(−ζω·0.15) = 5e-15: the error is the steady value to round-off.
        let (e, _) = m.following_error(0.15);
        assert!((e.x - 0.5 * a / (w * w)).abs() < 1e-9, "{e}");
        // Commanded stop at 100 mm: the actual position overshoots (undamped part of ζ = 0.7).
        let t_stop = m.commanded().end_s();
        let max_x = (0..2000).map(|k| m.state(t_stop + k as f64 * 1e-5).p.x).fold(f64::MIN, f64::max);
        assert!(max_x > 100.0 + 1e-6, "no overshoot: {max_x}");
        assert!((m.state(m.end_s() + 1.0).p.x - 100.0).abs() < 1e-6);
        check_derivatives(&m, 0.0, m.end_s(), 1e-3, 2.0);
    }

    proptest::proptest! {
        #[test]
        fn random_moves_arrive_within_limits(
            pts in proptest::collection::vec((-50.0..50.0f64, -50.0..50.0f64, -50.0..50.0f64), 1..5),
            v in 1.0..100.0f64, a in 100.0..5000.0f64, jerk in proptest::option::of(1e4..1e6f64),
        ) {
            let lim = Limits { v_max: v, a_max: a, j_max: jerk };
            let mut tr = Trajectory::new(0.0, Point3::origin());
            let targets: Vec<Point3> = pts.iter().map(|&(x, y, z)| Point3::new(x, y, z)).collect();
            tr.polyline(&targets, &lim).unwrap();
            let end = tr.end_s();
            // Each vertex is reached at rest at the end of its piece.
            for (i, p) in targets.iter().enumerate() {
                let t = tr.piece_start_s(i).unwrap() + (if i + 1 < targets.len() {
                    tr.piece_start_s(i + 1).unwrap() - tr.piece_start_s(i).unwrap()
                } else { end - tr.piece_start_s(i).unwrap() });
                let st = tr.state(t - 1e-12);
                proptest::prop_assert!((st.p - p).norm() < 1e-6, "vertex {i}: {} vs {p}", st.p);
            }
            for k in 0..=2000 {
                let st = tr.state(end * k as f64 / 2000.0);
                proptest::prop_assert!(st.v.norm() <= v * (1.0 + 1e-9));
                proptest::prop_assert!(st.a.norm() <= a * (1.0 + 1e-9));
            }
        }
    }
}
