//! Jerk-limited motions planned in velocity space: the blended style's transfers and its final
//! stop.
//!
//! Entry points: [`Motion`] (a trajectory of phases of constant jerk *vector*, evaluated at a
//! time), [`transfer`] (from a moving state to a moving state), [`stop`] (from a moving state to
//! rest).
//!
//! Why velocity space: a transfer leaves the release at scanning speed and enters the next
//! approach at scanning speed, usually in very different directions. Shaping the *path* first
//! (a curve) and timing it afterwards couples the tangential and the centripetal acceleration
//! and jerk, and the curve must be long where the speed is high. Here the *velocity vector* moves
//! on straight lines: from the start velocity to a cruise velocity `V`, constant for a while,
//! then to the end velocity, each change a one-dimensional S-curve (phases of constant jerk,
//! from zero to zero acceleration) along the fixed direction of that change. The acceleration
//! and jerk vectors are then the S-curve's scalar acceleration and jerk times a fixed unit
//! vector, so `|a| ≤ A` and `|j| ≤ J` hold exactly, by construction, with no curvature to sample;
//! the speed never exceeds the largest of the three velocities (a convex path in velocity space).
//! The position follows by integration (a symmetric S-curve change of Δ over τ moves
//! `v_start·τ + Δ·τ/2`), so the cruise velocity solves `D = (v₀ + V)·τ₁/2 + V·T + (V + v₁)·τ₃/2`:
//! for a cruise speed `w` its direction is a fixed point (`V ∥ D − v₀τ₁/2 − v₁τ₃/2`), and the
//! fastest admissible `w ≤ vmax` (cruise time `T ≥ 0`) is found by a descending scan and a
//! bisection. A start with non-zero acceleration (the curvature at the end of a release) first
//! ramps that acceleration to zero at the jerk limit.
//!
//! The time taken is close to a straight rest-to-rest move over the same distance: the velocity
//! change out of the release into the cruise is only a little larger than from rest.

use truepos_math::{Point3, Vector3};

/// One phase: start time, and position, velocity, acceleration at its start; constant jerk.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Phase {
    t: f64,
    p: Point3,
    v: Vector3,
    a: Vector3,
    j: Vector3,
}

/// A trajectory of phases of constant jerk vector (mm, s).
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// The phases in time order; the last one has zero duration and holds the end state.
    phases: Vec<Phase>,
}

/// Position, velocity, acceleration and jerk at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    /// Position, mm.
    pub p: Point3,
    /// Velocity, mm/s.
    pub v: Vector3,
    /// Acceleration, mm/s².
    pub a: Vector3,
    /// Jerk, mm/s³.
    pub j: Vector3,
}

impl Motion {
    fn new(p: Point3, v: Vector3, a: Vector3) -> Motion {
        Motion { phases: vec![Phase { t: 0.0, p, v, a, j: Vector3::zeros() }] }
    }

    /// Appends a phase of duration `dt` with constant jerk `j`.
    fn push(&mut self, dt: f64, j: Vector3) {
        if dt <= 0.0 {
            return;
        }
        let last = self.phases.len() - 1;
        self.phases[last].j = j;
        let s = self.phases[last];
        let e = Self::advance(&s, dt);
        self.phases.push(Phase { t: s.t + dt, p: e.p, v: e.v, a: e.a, j: Vector3::zeros() });
    }

    fn advance(s: &Phase, tau: f64) -> State {
        let (t2, t3) = (tau * tau, tau * tau * tau);
        State {
            p: s.p + s.v * tau + s.a * (0.5 * t2) + s.j * (t3 / 6.0),
            v: s.v + s.a * tau + s.j * (0.5 * t2),
            a: s.a + s.j * tau,
            j: s.j,
        }
    }

    /// A one-dimensional S-curve speed change of `delta` along the unit vector `u`.
    fn change(&mut self, delta: f64, u: Vector3, lim: Limits) {
        for (dt, jk) in s_curve(delta, lim) {
            self.push(dt, u * jk);
        }
    }

    /// Duration of the motion, s.
    pub fn duration(&self) -> f64 {
        self.phases.last().map_or(0.0, |s| s.t)
    }

    /// The state at time `t` (clamped to the motion).
    pub fn state(&self, t: f64) -> State {
        let t = t.clamp(0.0, self.duration());
        let n = self.phases.len();
        let i = self.phases.partition_point(|s| s.t <= t).clamp(1, n) - 1;
        let s = &self.phases[i];
        Self::advance(s, t - s.t)
    }

    /// The state at the start.
    pub fn start(&self) -> State {
        self.state(0.0)
    }

    /// The state at the end.
    pub fn end(&self) -> State {
        self.state(self.duration())
    }

    /// Phase boundaries (times), for samplers that must not step over a jerk switch.
    pub fn switches(&self) -> impl Iterator<Item = f64> + '_ {
        self.phases.iter().map(|s| s.t)
    }
}

/// Speed, acceleration and jerk limits of a motion (mm/s, mm/s², mm/s³).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Speed limit, mm/s.
    pub v: f64,
    /// Acceleration limit, mm/s².
    pub a: f64,
    /// Jerk limit, mm/s³.
    pub j: f64,
}

/// Duration of a symmetric S-curve speed change of `d ≥ 0`, from zero to zero acceleration.
fn tau(d: f64, lim: Limits) -> f64 {
    if d <= 0.0 {
        0.0
    } else if d >= lim.a * lim.a / lim.j {
        d / lim.a + lim.a / lim.j
    } else {
        2.0 * (d / lim.j).sqrt()
    }
}

/// Phases (duration, jerk) of that change.
fn s_curve(d: f64, lim: Limits) -> Vec<(f64, f64)> {
    if d <= 0.0 {
        vec![]
    } else if d >= lim.a * lim.a / lim.j {
        let r = lim.a / lim.j;
        vec![(r, lim.j), (d / lim.a - r, 0.0), (r, -lim.j)]
    } else {
        let r = (d / lim.j).sqrt();
        vec![(r, lim.j), (r, -lim.j)]
    }
}

/// Distance from the origin of the segment `[x, y]` in velocity space (the least speed while
/// the velocity moves from `x` to `y` on a straight line).
fn least_speed(x: Vector3, y: Vector3) -> f64 {
    let d = y - x;
    let dd = d.norm_squared();
    if dd <= 0.0 {
        return x.norm();
    }
    let s = (-x.dot(&d) / dd).clamp(0.0, 1.0);
    (x + d * s).norm()
}

/// How the velocity turns at one end of the cruise: straight from the end velocity to the
/// cruise, or through a midway velocity at the end's speed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Turn {
    Straight,
    /// On the bisector of the two directions.
    Bisector,
    /// Perpendicular to the end velocity, towards this (fixed) side: for turns within 30° of a
    /// reversal, where the bisector would swing with every small change of the cruise direction.
    Side(Vector3),
}

impl Turn {
    /// The turn at the end moving along `end` for a move whose chord is `chord`: through a midway
    /// velocity when the end direction and the chord are more than 90° apart.
    fn for_end(end: Vector3, chord: Vector3, hint: Vector3) -> Turn {
        let (Some(e), Some(c)) = (end.try_normalize(1e-12), chord.try_normalize(1e-12)) else {
            return Turn::Straight;
        };
        if e.dot(&c) >= 0.0 {
            return Turn::Straight;
        }
        if (e + c).norm() >= 0.5 {
            return Turn::Bisector;
        }
        [chord, hint, Vector3::z(), Vector3::x()]
            .into_iter()
            .map(|h| h - e * h.dot(&e))
            .find(|p| p.norm() > 1e-6)
            .map_or(Turn::Straight, |p| Turn::Side(p.normalize()))
    }

    /// The midway velocity between `x` and `y` at speed `s`, if any.
    fn midway(self, x: Vector3, y: Vector3, s: f64) -> Option<Option<Vector3>> {
        match self {
            Turn::Straight => Some(None),
            Turn::Bisector => {
                Some(Some((x.try_normalize(1e-12)? + y.try_normalize(1e-12)?).try_normalize(1e-9)? * s))
            }
            Turn::Side(d) => Some(Some(d * s)),
        }
    }
}

/// The velocities the motion passes through for a cruise velocity `vc`: from the start `u0`
/// through `vc` to the end `v1`, with a midway velocity at either end where `turns` say so (so
/// the speed does not dip towards zero in a reversal).
fn corners(u0: Vector3, vc: Vector3, v1: Vector3, turns: (Turn, Turn)) -> Option<Vec<Vector3>> {
    let mut c = vec![u0];
    c.extend(turns.0.midway(u0, vc, u0.norm())?);
    c.push(vc);
    c.extend(turns.1.midway(vc, v1, v1.norm())?);
    c.push(v1);
    Some(c)
}

/// A candidate: the velocity corners, the index of the cruise among them, its duration and the
/// total duration.
struct Candidate {
    corners: Vec<Vector3>,
    cruise: usize,
    tc: f64,
    total: f64,
}

/// The motion through `corners(u0, w·dir, v1)` that covers `d`, for cruise speed `w`: the
/// direction is a fixed point (`V ∥ d − the displacements of the changes that do not scale with
/// V`); `None` when it does not converge, the cruise time would be negative, or the speed dips
/// below `floor`.
fn cruise(
    d: Vector3,
    (u0, v1): (Vector3, Vector3),
    w: f64,
    lim: Limits,
    floor: f64,
    turns: (Turn, Turn),
) -> Option<Candidate> {
    let mut dir = if d.norm() > 1e-12 { d.normalize() } else { (u0 + v1).try_normalize(1e-12)? };
    for k in 0..200 {
        let c = corners(u0, dir * w, v1, turns)?;
        let ic = c.iter().position(|x| *x == dir * w)?;
        // displacement of each change (x → y over τ): (x + y)·τ/2; the cruise's share of its two
        // neighbouring changes is w·dir·τ/2 each, moved to the left-hand side
        let mut q = d;
        let mut tch = 0.0;
        let mut t_adj = 0.0;
        for (i, pair) in c.windows(2).enumerate() {
            let t = tau((pair[1] - pair[0]).norm(), lim);
            tch += t;
            if i + 1 == ic {
                q -= pair[0] * (0.5 * t);
                t_adj += t;
            } else if i == ic {
                q -= pair[1] * (0.5 * t);
                t_adj += t;
            } else {
                q -= (pair[0] + pair[1]) * (0.5 * t);
            }
        }
        let qn = q.norm();
        if qn <= 1e-12 {
            return None;
        }
        let next = q / qn;
        if (next - dir).norm() <= 1e-13 {
            let tc = qn / w - 0.5 * t_adj;
            let slow = c.windows(2).map(|p| least_speed(p[0], p[1])).fold(f64::INFINITY, f64::min);
            return (tc >= 0.0 && slow >= floor).then_some(Candidate {
                corners: c,
                cruise: ic,
                tc,
                total: tch + tc,
            });
        }
        // damped after a while (an oscillating fixed point at low cruise speeds)
        dir = if k < 50 { next } else { (dir + next).try_normalize(1e-12)? };
    }
    None
}

/// The fastest candidate over cruise speeds from `lim.v` down to `lo`: the first admissible
/// one of a descending scan, refined by bisection towards the edge of admissibility.
fn fastest(
    d: Vector3,
    ends: (Vector3, Vector3),
    lim: Limits,
    floor: f64,
    turns: (Turn, Turn),
) -> Option<Candidate> {
    let lo = floor.max(1e-3 * lim.v);
    let ok = |w: f64| cruise(d, ends, w, lim, floor, turns);
    let mut above: Option<f64> = None;
    let mut w = lim.v;
    let mut found = None;
    while w >= lo {
        if let Some(c) = ok(w) {
            found = Some((w, c));
            break;
        }
        above = Some(w);
        w *= 0.9;
    }
    let (mut wl, mut best) = found?;
    if let Some(mut wh) = above {
        for _ in 0..40 {
            let wm = 0.5 * (wl + wh);
            match ok(wm) {
                Some(c) => {
                    if c.total <= best.total {
                        best = c;
                    }
                    wl = wm;
                }
                None => wh = wm,
            }
        }
    }
    Some(best)
}

/// The jerk-limited transfer from position `p0` with velocity `v0` and acceleration `a0` to
/// position `p1` with velocity `v1` (and zero acceleration), keeping `|v| ≤ lim.v` (`|v0|`,
/// `|v1|` ≤ `lim.v` assumed), `|a| ≤ lim.a`, `|j| ≤ lim.j` exactly, and the speed at least
/// `floor` throughout (never a standstill). The velocity goes straight to the cruise velocity
/// and straight on to `v1`; where that would dip below `floor` (a reversal), around the origin
/// through a midway velocity (`corners`). `None` when no motion of this family keeps the
/// floor (for example a reversal on the spot); the caller then needs another shape.
pub fn transfer(
    (p0, v0, a0): (Point3, Vector3, Vector3),
    (p1, v1): (Point3, Vector3),
    lim: Limits,
    floor: f64,
) -> Option<Motion> {
    if !(lim.a > 0.0 && lim.j > 0.0 && lim.v > 0.0) || a0.norm() > lim.a * (1.0 + 1e-9) {
        return None;
    }
    let mut m = Motion::new(p0, v0, a0);
    // ramp the start acceleration to zero at the jerk limit
    let an = a0.norm();
    if an > 0.0 {
        m.push(an / lim.j, -a0 * (lim.j / an));
    }
    let s = m.end();
    let (q0, u0) = (s.p, s.v);
    if u0.norm() > lim.v * (1.0 + 1e-9) {
        return None;
    }
    let d = p1 - q0;
    let straight = (Turn::Straight, Turn::Straight);
    let c = fastest(d, (u0, v1), lim, floor, straight).or_else(|| {
        // through midway velocities where an end turns back against the chord: the fastest
        // of those combinations that keeps the floor
        let (t0, t1) = (Turn::for_end(u0, d, v1), Turn::for_end(-v1, -d, -u0));
        [(t0, Turn::Straight), (Turn::Straight, t1), (t0, t1)]
            .into_iter()
            .filter(|t| *t != straight)
            .filter_map(|t| fastest(d, (u0, v1), lim, floor, t))
            .min_by(|a, b| a.total.total_cmp(&b.total))
    })?;
    for (i, pair) in c.corners.windows(2).enumerate() {
        let dv = pair[1] - pair[0];
        if dv.norm() > 0.0 {
            m.change(dv.norm(), dv.normalize(), lim);
        }
        if i + 1 == c.cruise {
            m.push(c.tc, Vector3::zeros());
        }
    }
    // the closed-form displacement lands on `p1` up to rounding
    let e = m.end();
    ((e.p - p1).norm() <= 1e-7 * (1.0 + d.norm()) && (e.v - v1).norm() <= 1e-7 * (1.0 + v1.norm()))
        .then_some(m)
}

/// Straight to rest from position `p0`, velocity `v0`, acceleration `a0`: the acceleration
/// ramped to zero at the jerk limit, then an S-curve down to zero speed along the velocity.
pub fn stop((p0, v0, a0): (Point3, Vector3, Vector3), lim: Limits) -> Motion {
    let mut m = Motion::new(p0, v0, a0);
    let an = a0.norm();
    if an > 0.0 {
        m.push(an / lim.j, -a0 * (lim.j / an));
    }
    let v = m.end().v;
    if v.norm() > 0.0 {
        m.change(v.norm(), -v.normalize(), lim);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIM: Limits = Limits { v: 200.0, a: 1500.0, j: 20_000.0 };

    /// Largest |v|, |a|, |j| by finite differences of the positions at `dt`.
    fn measured(m: &Motion, dt: f64) -> (f64, f64, f64) {
        // inside the motion only (it is clamped at its end, where the end velocity goes on)
        let n = (m.duration() / dt).floor() as usize;
        let p: Vec<Point3> = (0..=n).map(|k| m.state(k as f64 * dt).p).collect();
        let (mut v, mut a, mut j) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..p.len().saturating_sub(3) {
            v = v.max((p[k + 1] - p[k]).norm() / dt);
            a = a.max((p[k + 2].coords - p[k + 1].coords * 2.0 + p[k].coords).norm() / (dt * dt));
            let d3 = p[k + 3].coords - p[k + 2].coords * 3.0 + p[k + 1].coords * 3.0 - p[k].coords;
            j = j.max(d3.norm() / (dt * dt * dt));
        }
        (v, a, j)
    }

    #[test]
    fn a_transfer_out_of_a_curved_release_lands_on_its_end_state_within_the_limits() {
        let v0 = Vector3::new(40.0, 0.0, 0.0);
        let a0 = Vector3::new(0.0, 160.0, 0.0); // 40 mm/s on a 10 mm radius
        let p1 = Point3::new(-30.0, 70.0, 12.0);
        let v1 = Vector3::new(0.0, -28.28, -28.28);
        let m = transfer((Point3::origin(), v0, a0), (p1, v1), LIM, 2.0).unwrap();
        let e = m.end();
        // closed form: rounding only
        assert!((e.p - p1).norm() < 1e-9, "{:?}", e.p);
        assert!((e.v - v1).norm() < 1e-9 && e.a.norm() < 1e-9);
        let s = m.start();
        assert!((s.v - v0).norm() < 1e-12 && (s.a - a0).norm() < 1e-12);
        // finite differences at 0.1 ms: within the limits (+0.5 % for the difference stencils
        // straddling a jerk switch)
        let (v, a, j) = measured(&m, 1e-4);
        assert!(v <= LIM.v * 1.005 && a <= LIM.a * 1.005 && j <= LIM.j * 1.005, "{v} {a} {j}");
        // and it uses them: the cruise reaches the top speed on a 77 mm move
        assert!(v > 0.99 * LIM.v, "{v}");
        // close to a rest-to-rest straight move over the chord (0.626 s for 77.1 mm): the
        // velocity changes out of 40 mm/s in another direction cost little
        let d = p1.coords.norm();
        let rr = 2.0 * tau(LIM.v, LIM) + (d - LIM.v * tau(LIM.v, LIM)) / LIM.v;
        assert!(m.duration() < rr + 0.08, "{} vs {rr}", m.duration());
    }

    #[test]
    fn short_transfers_cruise_below_the_top_speed_and_keep_moving() {
        let v0 = Vector3::new(20.0, 0.0, 0.0);
        let v1 = Vector3::new(-20.0, 0.0, 0.0);
        let p1 = Point3::new(0.0, 3.0, 0.0);
        let m = transfer((Point3::origin(), v0, Vector3::zeros()), (p1, v1), LIM, 1.0).unwrap();
        assert!((m.end().p - p1).norm() < 1e-9);
        let n = 2000;
        let least =
            (0..=n).map(|k| m.state(m.duration() * k as f64 / n as f64).v.norm()).fold(f64::MAX, f64::min);
        assert!(least >= 1.0 - 1e-9, "{least}");
        let (v, a, j) = measured(&m, 1e-4);
        assert!(v < LIM.v && a <= LIM.a * 1.005 && j <= LIM.j * 1.005, "{v} {a} {j}");
    }

    #[test]
    fn a_reversal_goes_around_and_keeps_its_speed_floor() {
        // arrive at 160° from the way out, 30 mm away: straight velocity changes would dip to
        // 40·sin 20° ≈ 13.7 mm/s or less; with a floor of 20 mm/s the velocity goes around
        let v0 = Vector3::new(40.0, 0.0, 0.0);
        let v1 = Vector3::new(-40.0 * 160f64.to_radians().cos().abs(), 40.0 * 160f64.to_radians().sin(), 0.0);
        let p1 = Point3::new(-10.0, 30.0, 0.0);
        let m = transfer((Point3::origin(), v0, Vector3::zeros()), (p1, v1), LIM, 20.0).unwrap();
        assert!((m.end().p - p1).norm() < 1e-9 && (m.end().v - v1).norm() < 1e-9);
        let n = 4000;
        let least =
            (0..=n).map(|k| m.state(m.duration() * k as f64 / n as f64).v.norm()).fold(f64::MAX, f64::min);
        assert!(least >= 20.0 * (1.0 - 1e-9), "{least}");
        let (_, a, j) = measured(&m, 1e-4);
        assert!(a <= LIM.a * 1.005 && j <= LIM.j * 1.005, "{a} {j}");
    }

    #[test]
    fn a_reversal_on_the_spot_is_refused() {
        let v0 = Vector3::new(20.0, 0.0, 0.0);
        assert!(
            transfer((Point3::origin(), v0, Vector3::zeros()), (Point3::origin(), v0), LIM, 1.0).is_none()
        );
    }

    #[test]
    fn the_stop_is_straight_and_at_rest() {
        let m = stop((Point3::origin(), Vector3::new(0.0, 40.0, 0.0), Vector3::new(160.0, 0.0, 0.0)), LIM);
        let e = m.end();
        assert!(e.v.norm() < 1e-9 && e.a.norm() < 1e-9);
        let (_, a, j) = measured(&m, 1e-4);
        assert!(a <= LIM.a * 1.005 && j <= LIM.j * 1.005, "{a} {j}");
    }
}
