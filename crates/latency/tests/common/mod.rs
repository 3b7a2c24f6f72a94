//! A small, independent stream generator for the tests: exact frictionless-stylus geometry
//! (the stylus centre is pushed back onto the stylus-centre surface, the deflection is the
//! push), trapezoidal motion, per-axis machine capture delays, white encoder and probe noise.
//! Independent of `truepos-sim` so that the algorithms are checked against two simulators.
#![allow(dead_code, clippy::too_many_arguments)]

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use truepos_math::{Point3, Vector3};

#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// Stylus-centre sphere (outer): centre, radius.
    Sphere(Point3, f64),
    /// Inner stylus-centre sphere/ring (the probe inside): centre, radius.
    Ring(Point3, f64),
    /// Plane through a point with the outward normal (pointing to where the probe is).
    Plane(Point3, Vector3),
}

impl Shape {
    /// Deflection (stylus centre − body) for a body at `m`.
    pub fn deflection(&self, m: &Point3) -> Vector3 {
        match *self {
            Shape::Sphere(c, r) => {
                let w = m - c;
                let d = w.norm();
                if d < r {
                    w / d * (r - d)
                } else {
                    Vector3::zeros()
                }
            }
            Shape::Ring(c, r) => {
                let w = m - c;
                let d = w.norm();
                if d > r {
                    -w / d * (d - r)
                } else {
                    Vector3::zeros()
                }
            }
            Shape::Plane(p, n) => {
                let pen = (p - m).dot(&n);
                if pen > 0.0 {
                    n * pen
                } else {
                    Vector3::zeros()
                }
            }
        }
    }
}

/// Position along a leg of length `l` with a trapezoidal speed profile (speed `v`, acceleration
/// `a`) at time `t` after its start; and the leg's duration.
pub fn leg(t: f64, l: f64, v: f64, a: f64) -> (f64, f64) {
    let ta = v / a;
    let (ta, vm) = if a * ta * ta > l { ((l / a).sqrt(), (l * a).sqrt()) } else { (ta, v) };
    let da = 0.5 * a * ta * ta;
    let tc = (l - 2.0 * da) / vm;
    let total = 2.0 * ta + tc;
    let s = if t <= 0.0 {
        0.0
    } else if t < ta {
        0.5 * a * t * t
    } else if t < ta + tc {
        da + vm * (t - ta)
    } else if t < total {
        let r = total - t;
        l - 0.5 * a * r * r
    } else {
        l
    };
    (s, total)
}

/// One touch: the body moves from `start` along `dir` (unit) by `length` and back, at `speed`.
#[derive(Clone, Copy, Debug)]
pub struct Touch {
    pub shape: Shape,
    pub start: Point3,
    pub dir: Vector3,
    pub length: f64,
    pub speed: f64,
}

/// A touch aimed at surface normal `n` of a shape through its point `q` (on the stylus-centre
/// surface), travelling along `dir` (default −n), to peak penetration `depth` along `n`.
pub fn touch_at(shape: Shape, q: Point3, n: Vector3, dir: Option<Vector3>, depth: f64, speed: f64) -> Touch {
    let dir = dir.unwrap_or(-n).normalize();
    let cosang = -dir.dot(&n);
    let standoff = 1.0; // mm along the travel direction before contact
    let start = q - dir * standoff;
    Touch { shape, start, dir, length: standoff + depth / cosang, speed }
}

pub const ACCEL: f64 = 8000.0; // mm/s² (0.8 g: reaches 40 mm/s within 0.1 mm)
pub const DWELL: f64 = 0.02; // s at rest before and after each touch

pub struct Data {
    pub mt: Vec<f64>,
    pub m: Vec<[f64; 3]>,
    pub pt: Vec<f64>,
    pub p: Vec<[f64; 3]>,
}

impl Data {
    pub fn streams(&self) -> truepos_latency::Streams<'_> {
        truepos_latency::Streams { machine_t: &self.mt, machine: &self.m, probe_t: &self.pt, probe: &self.p }
    }
}

#[derive(Clone, Copy, Debug)]
pub struct Capture {
    pub machine_rate: f64,
    pub probe_rate: f64,
    /// Machine capture delay per axis (s): the machine sample stamped T holds the position of T − D.
    pub delay: [f64; 3],
    pub sigma_machine: f64,
    pub sigma_probe: f64,
    pub seed: u64,
}

impl Capture {
    pub fn realistic(delay: f64, seed: u64) -> Self {
        Capture {
            machine_rate: 4000.0,
            probe_rate: 10_000.0,
            delay: [delay; 3],
            sigma_machine: 1e-3,
            sigma_probe: 3e-4,
            seed,
        }
    }
}

/// Sample a body trajectory `body(t)` (with the shape active at `t`) over `[0, t_end]`.
pub fn sample(cap: &Capture, t_end: f64, body: impl Fn(f64) -> (Point3, Shape)) -> Data {
    let mut rng = ChaCha8Rng::seed_from_u64(cap.seed);
    let nm = Normal::new(0.0, cap.sigma_machine.max(1e-300)).unwrap();
    let np = Normal::new(0.0, cap.sigma_probe.max(1e-300)).unwrap();
    let noise_m = cap.sigma_machine > 0.0;
    let noise_p = cap.sigma_probe > 0.0;
    let mt: Vec<f64> =
        (0..(t_end * cap.machine_rate) as usize).map(|i| i as f64 / cap.machine_rate).collect();
    let m = mt
        .iter()
        .map(|&t| {
            let mut v = [0.0; 3];
            for (k, x) in v.iter_mut().enumerate() {
                *x = body(t - cap.delay[k]).0[k] + if noise_m { nm.sample(&mut rng) } else { 0.0 };
            }
            v
        })
        .collect();
    // The probe clock starts slightly offset (different rates and phases).
    let pt: Vec<f64> =
        (0..(t_end * cap.probe_rate) as usize).map(|i| 3.3e-5 + i as f64 / cap.probe_rate).collect();
    let p = pt
        .iter()
        .map(|&t| {
            let (b, s) = body(t);
            let d = s.deflection(&b);
            let mut v = [d.x, d.y, d.z];
            if noise_p {
                for x in &mut v {
                    *x += np.sample(&mut rng);
                }
            }
            v
        })
        .collect();
    Data { mt, m, pt, p }
}

/// Streams of a sequence of touches.
pub fn touches(cap: &Capture, list: &[Touch]) -> Data {
    let mut starts = Vec::new();
    let mut t = 0.05;
    for tc in list {
        let (_, d) = leg(0.0, tc.length, tc.speed, ACCEL);
        starts.push(t);
        t += 2.0 * DWELL + 2.0 * d;
    }
    let t_end = t + 0.05;
    let list = list.to_vec();
    sample(cap, t_end, move |t| {
        let k = starts.partition_point(|&s| s <= t).saturating_sub(1);
        let tc = &list[k];
        let (_, d) = leg(0.0, tc.length, tc.speed, ACCEL);
        let tau = t - starts[k] - DWELL;
        let s = if tau <= d {
            leg(tau, tc.length, tc.speed, ACCEL).0
        } else {
            tc.length - leg(tau - d, tc.length, tc.speed, ACCEL).0
        };
        (tc.start + tc.dir * s, tc.shape)
    })
}

/// The classic five touches on a stylus-centre sphere: ±X, ±Y, +Z.
pub fn five_point(c: Point3, rc: f64, speed: f64, depth: f64) -> Vec<Touch> {
    let s = Shape::Sphere(c, rc);
    [Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y(), Vector3::z()]
        .iter()
        .map(|n| touch_at(s, c + n * rc, *n, None, depth, speed))
        .collect()
}

/// Circle scan: the body circles centre `c` (in XY) at tangential `speed` for `turns`; its
/// radius switches between `rc − d1` and `rc − d2` at the given angles (radians, increasing,
/// within one turn), with smooth cosine ramps of `ramp` radians.
pub fn circle_scan(
    cap: &Capture,
    c: Point3,
    rc: f64,
    speed: f64,
    d1: f64,
    d2: f64,
    switches: &[f64],
    ramp: f64,
    turns: f64,
) -> Data {
    let shape = Shape::Sphere(c, rc);
    let lead = 0.05;
    let t_end = lead + turns * 2.0 * std::f64::consts::PI * rc / speed + 0.05;
    let sw = switches.to_vec();
    sample(cap, t_end, move |t| {
        let tau = t - lead;
        let th = tau * speed / rc;
        let frac = th.rem_euclid(2.0 * std::f64::consts::PI);
        // Level toggles at each switch; ramps are cosine blends.
        let mut level = 0.0;
        for (i, &s) in sw.iter().enumerate() {
            let target = if i % 2 == 0 { 1.0 } else { 0.0 };
            let x = ((frac - s) / ramp).clamp(0.0, 1.0);
            let blend = 0.5 - 0.5 * (std::f64::consts::PI * x).cos();
            level = level + (target - level) * blend;
        }
        let pen = d1 + (d2 - d1) * level;
        // Smooth entry from 0.5 mm outside the surface over the first 30 ms.
        let entry = ((t - lead + 0.03) / 0.03).clamp(0.0, 1.0);
        let pen = -0.5 + (pen + 0.5) * (0.5 - 0.5 * (std::f64::consts::PI * entry).cos());
        let r = rc - pen;
        (Point3::new(c.x + r * th.cos(), c.y + r * th.sin(), c.z), shape)
    })
}
