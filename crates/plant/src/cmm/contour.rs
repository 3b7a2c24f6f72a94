//! Unknown-contour scans (I++ DME 11.3, the `ScanIn…` family) on the blended planner.
//!
//! Where the surface under the scan is one the planner of `truepos-scan` can plan, the scan is a
//! line or circle feature executed like `ScanOnLine`/`ScanOnCircle` on the scanning dynamics:
//!
//! | guide | surface at the start | path |
//! |---|---|---|
//! | scan plane | plane face (not parallel to the scan plane) | line along plane × face |
//! | scan plane | pin or bore whose axis is normal to the plane | circle about the pin's axis |
//! | scan plane | pin or bore whose axis lies in the plane | line along the axis |
//! | scan plane | sphere whose centre lies in the plane | great circle |
//! | scan cylinder | plane face normal to its axis | circle about the scan axis on the face |
//! | scan cylinder | plane face parallel to its axis | line along the axis |
//! | scan cylinder | pin or bore parallel to its axis | line along the axis; coaxial: circle (or line) as the direction point says |
//! | scan cylinder | sphere centred on its axis, start on the equator | the equator |
//!
//! Without a part the surface is the ideal plane of the start contact (as for PtMeas). The end
//! of the scan is computed on the planned path from the stop criterion ([`StopTracker`]:
//! the n-th entry into the stop sphere at its closest point, the n-th crossing of the stop
//! plane once |D − S| has been travelled, the n-th crossing of the stop cylinder), marching in
//! steps of at most 0.05 mm and refining each event to 1e-9 of the step; the points reported
//! are every StepW (tip-centre arc length) from the start and the end point itself. The path is
//! checked against the part up to its end (plus the overscan): a path that leaves the face
//! (an edge, another solid in the way) is not plannable.
//!
//! Anything else (an ellipse, a helix, a small circle of a sphere, a path that crosses onto
//! another face, more than the planner's two turns) is stepped along the surface by
//! `IppdmeCmm::follow`, and the reason goes to the session log.
//!
//! Entry point: [`IppdmeCmm::contour_route`], then [`IppdmeCmm::contour_end`].

use super::{gap, outward, part_distance, IppdmeCmm, MAX_SCAN_TIME_S, OVERSCAN_MM};
use truepos_ippdme::part::{CylinderSide, Part, Solid};
use truepos_ippdme::{Contact, Guide, MachineError, Stop};
use truepos_math::{Point3, Vector3};
use truepos_scan::{Feature, Geometry, Side};

/// How an unknown-contour scan runs.
#[derive(Debug, Clone)]
pub(super) enum Route {
    /// On the planner: the feature (direction and sense set, extent still open: a unit line or
    /// a ±1 rad sweep) and what it is, for the log.
    Planned(Feature, String),
    /// Stepped along the surface, and why.
    Stepped(String),
}

/// Sine of the angle below which two directions count as parallel (or perpendicular).
const DIR_EPS: f64 = 1e-6;
/// A start contact within this of a solid's offset surface is on that solid (mm): far above the
/// machine's µm errors, far below any feature size.
const FACE_TOL_MM: f64 = 0.02;
/// A sphere's centre this close to the scan plane (or to the scan axis, the start this close to
/// its equator), or a cylinder's axis this close to the scan axis, counts as on it (mm): the
/// measured start contact and a client's measured axis are µm off; the planner's deflection
/// takes up the rest.
const POS_TOL_MM: f64 = FACE_TOL_MM;
/// Normals closer than this cosine (about 1.8°) are the same face.
const FACE_COS: f64 = 0.9995;
/// Largest marching step along the planned path (mm of tip-centre travel).
const MARCH_MM: f64 = 0.05;

fn solid_kind(s: &Solid) -> &'static str {
    match s {
        Solid::Sphere { .. } => "sphere",
        Solid::HalfSpace { .. } => "plane face",
        Solid::Cylinder { side: CylinderSide::Outside, .. } => "pin",
        Solid::Cylinder { side: CylinderSide::Inside, .. } => "bore",
        Solid::Prism { .. } => "prism face",
    }
}

/// The face of a bounded solid a contact lies on, as the unbounded solid the planner plans on
/// (a plane, an infinite cylinder); `None` at an edge. Unbounded solids are themselves.
fn face_of(s: &Solid, tip: &Point3, n: &Vector3) -> Option<Solid> {
    match s {
        Solid::Cylinder { point, axis, radius, side, ends: Some((a, b)) } => {
            let lateral =
                Solid::Cylinder { point: *point, axis: *axis, radius: *radius, side: *side, ends: None };
            let radial = outward(&lateral, tip);
            if radial.dot(n) > FACE_COS {
                return Some(lateral);
            }
            let sign = if *side == CylinderSide::Inside { -1.0 } else { 1.0 };
            [(*a, -axis * sign), (*b, axis * sign)]
                .into_iter()
                .find(|(_, m)| m.dot(n) > FACE_COS)
                .map(|(e, m)| Solid::HalfSpace { point: point + axis * e, normal: m })
        }
        Solid::Prism { origin, u, v, w, polygon, height } => {
            let k = polygon.len();
            let mut faces = vec![(*origin, -w), (origin + w * *height, *w)];
            for i in 0..k {
                let (p, q) = (polygon[i], polygon[(i + 1) % k]);
                let e = [q[0] - p[0], q[1] - p[1]];
                let len = e[0].hypot(e[1]);
                faces.push((origin + u * p[0] + v * p[1], u * (e[1] / len) - v * (e[0] / len)));
            }
            faces
                .into_iter()
                .find(|(_, m)| m.dot(n) > FACE_COS)
                .map(|(p, m)| Solid::HalfSpace { point: p, normal: m })
        }
        other => Some(other.clone()),
    }
}

/// The one solid the start contact lies on, with a label for the log.
fn start_solid(part: &Part, tip: &Point3, n: &Vector3, r: f64) -> Result<(String, Solid), String> {
    let mut hits: Vec<(String, Solid)> = Vec::new();
    for (k, (id, s)) in part.solids.iter().enumerate() {
        if gap(s, tip, r).abs() < FACE_TOL_MM && outward(s, tip).dot(n) > FACE_COS {
            let name = match id {
                Some(id) => format!("the {} `{id}`", solid_kind(s)),
                None => format!("the {} (solid {})", solid_kind(s), k + 1),
            };
            let Some(face) = face_of(s, tip, n) else {
                return Err(format!("the start contact is on an edge of {name}"));
            };
            hits.push((name, face));
        }
    }
    match hits.len() {
        1 => Ok(hits.remove(0)),
        0 => Err("no single face of the part under the start contact".into()),
        _ => Err(format!("the start contact is on an edge ({} and {})", hits[0].0, hits[1].0)),
    }
}

/// Whether the planned path at `u` runs on the face it was planned on: the ball at the planned
/// tip centre touches the part (distance r within [`FACE_TOL_MM`]) with the planned normal.
fn on_face(part: &Part, f: &Feature, u: f64, r: f64) -> bool {
    let (d, n) = part_distance(part, &f.point(u, r));
    (d - r).abs() < FACE_TOL_MM && n.dot(&f.normal(u)) > FACE_COS
}

/// The stop criterion followed continuously along a path of surface points `p(u)`.
pub(super) struct StopTracker {
    stop: Stop,
    crossings: u32,
    /// Sphere: the start was outside, or the path has left the sphere since.
    left_once: bool,
}

impl StopTracker {
    pub(super) fn new(stop: &Stop, p0: &Point3) -> StopTracker {
        let left_once = match stop {
            Stop::Sphere { center, radius, .. } => (p0 - center).norm() > *radius,
            _ => true,
        };
        StopTracker { stop: *stop, crossings: 0, left_once }
    }

    /// Advance from `a` to `b` (`b − a` small: at most one event in between); the parameter
    /// where the scan ends if it ends in `(a, b]`. `metric`: tip-centre mm per unit of `u`.
    pub(super) fn advance(&mut self, a: f64, b: f64, p: &dyn Fn(f64) -> Point3, metric: f64) -> Option<f64> {
        match self.stop {
            Stop::Sphere { center, radius, count } => {
                let dist = |u: f64| (p(u) - center).norm();
                let (ina, inb) = (dist(a) <= radius, dist(b) <= radius);
                if !ina && inb && self.left_once {
                    self.crossings += 1;
                    if self.crossings >= count {
                        let entry = bisect(a, b, |u| dist(u) <= radius);
                        return Some(closest_after(entry, b - a, p, &center));
                    }
                }
                if !inb {
                    self.left_once = true;
                }
                None
            }
            Stop::Plane { point, normal, count, arm_mm } => {
                let side = |u: f64| (p(u) - point).dot(&normal) > 0.0;
                if side(a) != side(b) {
                    let sa = side(a);
                    let uc = bisect(a, b, |u| side(u) != sa);
                    if uc * metric > arm_mm {
                        self.crossings += 1;
                        if self.crossings >= count {
                            return Some(uc);
                        }
                    }
                }
                None
            }
            Stop::Cylinder { point, axis, radius, count } => {
                let inside = |u: f64| {
                    let rel = p(u) - point;
                    (rel - axis * rel.dot(&axis)).norm() <= radius
                };
                if inside(a) != inside(b) {
                    let ia = inside(a);
                    let uc = bisect(a, b, |u| inside(u) != ia);
                    self.crossings += 1;
                    if self.crossings >= count {
                        return Some(uc);
                    }
                }
                None
            }
        }
    }
}

/// The first `u` in `(a, b]` where `flipped(u)` holds (`flipped(b)` holds, `flipped(a)` not).
fn bisect(mut a: f64, mut b: f64, flipped: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..80 {
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            break;
        }
        if flipped(m) {
            b = m;
        } else {
            a = m;
        }
    }
    b
}

/// The parameter of the least distance to `center` after `entry` (the distance falls after an
/// entry and must rise again before the path can leave): march in `h` until it stops falling,
/// then bisect on the sign of its slope `(p − c)·p'` (central differences).
fn closest_after(entry: f64, h: f64, p: &dyn Fn(f64) -> Point3, center: &Point3) -> f64 {
    let d = 1e-6 * h;
    let rising = |u: f64| (p(u) - center).dot(&(p(u + d) - p(u - d))) >= 0.0;
    if rising(entry) {
        return entry;
    }
    let mut u = entry;
    // Bounded: an entry is followed by the minimum within the sphere's diameter.
    for _ in 0..100_000_000 {
        if rising(u + h) {
            break;
        }
        u += h;
    }
    bisect(u, u + h, rising)
}

/// The planner's side of a cylinder of the part.
fn planner_side(s: CylinderSide) -> Side {
    match s {
        CylinderSide::Outside => Side::Outside,
        CylinderSide::Inside => Side::Inside,
    }
}

/// The start of an unknown-contour scan while its route is decided: where it touches, which
/// way the direction point says, and what it touches (for the log).
struct RouteStart<'a> {
    /// The start contact's surface normal.
    n: Vector3,
    /// The start contact's tip centre (mm).
    c0: Point3,
    /// The start contact's surface point: the tip centre less the tip radius along `n` (mm).
    s0: Point3,
    /// Towards the direction point: the sense along the path.
    toward: &'a Vector3,
    /// The length of `toward` (the scale below which it has no component along a path).
    tn: f64,
    /// The surface under the start, as the log names it.
    label: String,
}

impl RouteStart<'_> {
    /// The error of a direction point with no component along the only possible path.
    fn undefined() -> MachineError {
        MachineError::Unable("the scan direction is undefined".into())
    }

    /// A planned line from the start along `dir`, in the sense of the direction point.
    fn line(&self, dir: Vector3, what: String) -> Result<Route, MachineError> {
        let dir = dir.normalize();
        let along = self.toward.dot(&dir);
        if along.abs() <= 1e-9 * self.tn {
            return Err(Self::undefined());
        }
        let d = dir * along.signum();
        let feature = Feature {
            id: "ScanIn".into(),
            geometry: Geometry::Line { start: self.s0, end: self.s0 + d, normal: self.n },
        };
        Ok(Route::Planned(feature, what))
    }

    /// A planned circle through the start about the axis through `point` along `axis`, in the
    /// sense of the direction point (stepped if the start lies on the axis).
    fn circle(&self, point: Point3, axis: Vector3, side: Side, what: String) -> Result<Route, MachineError> {
        let mut axis = axis.normalize();
        if side == Side::Plane && axis.dot(&self.n) < 0.0 {
            // The planner's plane circle has the face's outward normal as its axis.
            axis = -axis;
        }
        let c = point + axis * (self.s0 - point).dot(&axis);
        let radial = self.s0 - c;
        let radius = radial.norm();
        if radius < 1e-6 {
            return Ok(Route::Stepped("the start lies on the scan axis".into()));
        }
        let along = self.toward.dot(&axis.cross(&(radial / radius)));
        if along.abs() <= 1e-9 * self.tn {
            return Err(Self::undefined());
        }
        let (bu, bv) = Feature::basis(&axis);
        let feature = Feature {
            id: "ScanIn".into(),
            geometry: Geometry::Circle {
                center: c,
                axis,
                radius,
                side,
                start: radial.dot(&bv).atan2(radial.dot(&bu)),
                sweep: along.signum(),
            },
        };
        Ok(Route::Planned(feature, what))
    }

    /// The route in the scan plane with unit normal `g` over the start's `solid`.
    fn in_scan_plane(&self, g: Vector3, solid: Solid) -> Result<Route, MachineError> {
        let label = &self.label;
        match solid {
            Solid::HalfSpace { normal: m, .. } => {
                let dir = g.cross(&m);
                if dir.norm() < DIR_EPS {
                    return Ok(Route::Stepped(format!("the scan plane is parallel to {label}")));
                }
                self.line(dir, format!("a line on {label}"))
            }
            Solid::Cylinder { point, axis, side, .. } => {
                if g.cross(&axis).norm() < DIR_EPS {
                    self.circle(
                        point,
                        axis,
                        planner_side(side),
                        format!("a circle about the axis of {label}"),
                    )
                } else if g.dot(&axis).abs() < DIR_EPS {
                    self.line(axis, format!("a line along {label}"))
                } else {
                    Ok(Route::Stepped(format!(
                        "the scan plane cuts {label} in an ellipse (the planner plans lines and circles)"
                    )))
                }
            }
            Solid::Sphere { center, .. } => {
                if (center - self.c0).dot(&g).abs() < POS_TOL_MM {
                    self.circle(center, g, Side::Outside, format!("a great circle of {label}"))
                } else {
                    Ok(Route::Stepped(format!(
                        "the scan plane cuts {label} off its centre (the surface normal leaves the plane)"
                    )))
                }
            }
            Solid::Prism { .. } => {
                Ok(Route::Stepped(format!("{label} is not a single face the planner plans on")))
            }
        }
    }

    /// The route on the scan cylinder through `gp` with unit axis `ga` over the start's
    /// `solid`.
    fn on_scan_cylinder(&self, gp: Point3, ga: Vector3, solid: Solid) -> Result<Route, MachineError> {
        let label = &self.label;
        match solid {
            Solid::HalfSpace { normal: m, .. } => {
                if m.cross(&ga).norm() < DIR_EPS {
                    self.circle(gp, ga, Side::Plane, format!("a circle about the scan axis on {label}"))
                } else if m.dot(&ga).abs() < DIR_EPS {
                    self.line(ga, format!("a line along the scan axis on {label}"))
                } else {
                    Ok(Route::Stepped(format!(
                        "the scan cylinder cuts {label} in an ellipse (the planner plans lines and circles)"
                    )))
                }
            }
            Solid::Cylinder { point, axis, side, .. } => self.along_cylinder(gp, ga, point, axis, side),
            Solid::Sphere { center, .. } => {
                let off = center - gp;
                let on_axis = (off - ga * off.dot(&ga)).norm() < POS_TOL_MM;
                if on_axis && (self.c0 - center).dot(&ga).abs() < POS_TOL_MM {
                    self.circle(
                        center,
                        ga,
                        Side::Outside,
                        format!("the equator of {label} about the scan axis"),
                    )
                } else {
                    Ok(Route::Stepped(format!(
                        "the scan cylinder cuts {label} off its equator (the surface normal leaves the cylinder's radial plane)"
                    )))
                }
            }
            Solid::Prism { .. } => {
                Ok(Route::Stepped(format!("{label} is not a single face the planner plans on")))
            }
        }
    }

    /// The route on the scan cylinder (`gp`, unit axis `ga`) over a pin or bore through
    /// `point` along `axis`: a line when parallel; when coaxial, a circle or a line as the
    /// direction point says.
    fn along_cylinder(
        &self,
        gp: Point3,
        ga: Vector3,
        point: Point3,
        axis: Vector3,
        side: CylinderSide,
    ) -> Result<Route, MachineError> {
        let label = &self.label;
        if axis.cross(&ga).norm() >= DIR_EPS {
            return Ok(Route::Stepped(format!(
                "the scan cylinder cuts {label} in a space curve (the planner plans lines and circles)"
            )));
        }
        let off = point - gp;
        if (off - ga * off.dot(&ga)).norm() > POS_TOL_MM {
            return self.line(ga, format!("a line along {label}, parallel to the scan axis"));
        }
        // Coaxial: the tip centre is free on the scan cylinder; the direction point says which
        // way.
        let rel = self.s0 - gp;
        let radial = (rel - ga * rel.dot(&ga)).try_normalize(1e-12).unwrap_or(self.n);
        let (along_axis, around) = (self.toward.dot(&ga), self.toward.dot(&ga.cross(&radial)));
        if along_axis.abs() <= DIR_EPS * self.tn {
            self.circle(
                gp,
                ga,
                planner_side(side),
                format!("a circle on {label}, coaxial with the scan cylinder"),
            )
        } else if around.abs() <= DIR_EPS * self.tn {
            self.line(ga, format!("a line along {label}, coaxial with the scan cylinder"))
        } else {
            Ok(Route::Stepped(format!(
                "a helix on {label}, coaxial with the scan cylinder (the planner plans lines and circles)"
            )))
        }
    }
}

impl IppdmeCmm {
    /// Decide how an unknown-contour scan from `start` runs (see the module's table). An
    /// undefined scan direction (the direction point has no component along the only possible
    /// path) is an error, as in the stepping.
    pub(super) fn contour_route(
        &self,
        start: &Contact,
        guide: &Guide,
        toward: &Vector3,
        r: f64,
    ) -> Result<Route, MachineError> {
        let n = start.normal;
        let c0 = start.tip_center_mm;
        let s0 = c0 - n * r;
        let (label, solid) = match &self.part {
            None => (
                "the ideal plane of the start contact".to_string(),
                Solid::HalfSpace { point: s0, normal: n },
            ),
            Some(p) => match start_solid(p, &c0, &n, r) {
                Ok(x) => x,
                Err(why) => return Ok(Route::Stepped(why)),
            },
        };
        let from = RouteStart { n, c0, s0, toward, tn: toward.norm(), label };
        match *guide {
            Guide::Plane { normal: g } => from.in_scan_plane(g.normalize(), solid),
            Guide::Cylinder { point: gp, axis: ga } => from.on_scan_cylinder(gp, ga.normalize(), solid),
        }
    }

    /// Where a planned contour scan ends: the feature with its extent set (the end plus the
    /// overscan) and the end parameter (mm along a line, rad around a circle). `Ok(Err(why))`
    /// if the path leaves the face first or needs more than the planner's two turns: then it is
    /// stepped. A path that leaves the machine volume before the end is 1008; no end within
    /// `max_length_mm` (or the machine-time bound) is 1011.
    pub(super) fn contour_end(
        &self,
        feature: &Feature,
        stop: &Stop,
        step_mm: f64,
        max_length_mm: f64,
        r: f64,
    ) -> Result<Result<(Feature, f64), String>, MachineError> {
        let metric = feature.metric(r);
        let limit_mm = max_length_mm.min(MAX_SCAN_TIME_S * self.models.config.scan_speed_mm_s);
        let u_max = limit_mm / metric;
        let h = (step_mm / 4.0).min(MARCH_MM) / metric;
        let surface = |u: f64| feature.point(u, 0.0);
        let mut tracker = StopTracker::new(stop, &surface(0.0));
        let (lo, hi) = self.volume;
        let leaves = |u: f64| format!("the path leaves the face after {:.3} mm, before its end", u * metric);
        let mut u = 0.0;
        let end = loop {
            if let Some(part) = &self.part {
                if !on_face(part, feature, u, r) {
                    return Ok(Err(leaves(u)));
                }
            }
            let tip = feature.point(u, r);
            if (0..3).any(|k| tip[k] < lo[k] || tip[k] > hi[k]) {
                return Err(MachineError::OutOfVolume);
            }
            if u >= u_max {
                return Err(MachineError::Unable(format!(
                    "the stop criterion was not met within {limit_mm:.0} mm of scanning"
                )));
            }
            let next = (u + h).min(u_max);
            if let Some(e) = tracker.advance(u, next, &surface, metric) {
                break e;
            }
            u = next;
        };
        // The overscan runs on too: it must stay on the face.
        if let Some(part) = &self.part {
            let over = end + OVERSCAN_MM / metric;
            let k = ((over - u) / h).ceil().max(1.0) as usize;
            if let Some(bad) =
                (0..=k).map(|i| u + (over - u) * i as f64 / k as f64).find(|&x| !on_face(part, feature, x, r))
            {
                return Ok(Err(leaves(bad)));
            }
        }
        let geometry = match &feature.geometry {
            Geometry::Line { start, end: e, normal } => {
                let dir = (e - start).normalize();
                Geometry::Line { start: *start, end: start + dir * (end + OVERSCAN_MM), normal: *normal }
            }
            Geometry::Circle { center, axis, radius, side, start, sweep } => {
                let total = end + OVERSCAN_MM / radius;
                if total > 4.0 * std::f64::consts::PI {
                    return Ok(Err(format!(
                        "the stop is {:.0}° around, beyond the planner's two turns",
                        end.to_degrees()
                    )));
                }
                Geometry::Circle {
                    center: *center,
                    axis: *axis,
                    radius: *radius,
                    side: *side,
                    start: *start,
                    sweep: total * sweep.signum(),
                }
            }
        };
        Ok(Ok((Feature { id: feature.id.clone(), geometry }, end)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line_x() -> impl Fn(f64) -> Point3 {
        |u| Point3::new(u, 0.0, 0.0)
    }

    fn run(stop: Stop, p: &dyn Fn(f64) -> Point3, h: f64, u_max: f64) -> Option<f64> {
        let mut t = StopTracker::new(&stop, &p(0.0));
        let mut u = 0.0;
        while u < u_max {
            if let Some(e) = t.advance(u, u + h, p, 1.0) {
                return Some(e);
            }
            u += h;
        }
        None
    }

    #[test]
    fn stops_on_a_line_are_exact() {
        let p = line_x();
        // Sphere off the line by 0.3: entered, then closest at x = 9.
        let s = Stop::Sphere { center: Point3::new(9.0, 0.3, 0.0), radius: 0.7, count: 1 };
        assert!((run(s, &p, 0.05, 20.0).unwrap() - 9.0).abs() < 1e-9);
        // A start inside must leave first: a line leaves once and never comes back.
        let s = Stop::Sphere { center: Point3::new(0.2, 0.0, 0.0), radius: 0.7, count: 1 };
        assert_eq!(run(s, &p, 0.05, 20.0), None);
        // Plane x = 3.3 crossed after the arm of 2; a crossing before the arm does not count.
        let s =
            Stop::Plane { point: Point3::new(3.3, 0.0, 0.0), normal: -Vector3::x(), count: 1, arm_mm: 2.0 };
        assert!((run(s, &p, 0.05, 20.0).unwrap() - 3.3).abs() < 1e-9);
        let s =
            Stop::Plane { point: Point3::new(1.0, 0.0, 0.0), normal: Vector3::x(), count: 1, arm_mm: 2.0 };
        assert_eq!(run(s, &p, 0.05, 20.0), None);
        // Cylinder about Z at x = 8, radius 0.35: in at 7.65 (1st), out at 8.35 (2nd).
        let c = |count| Stop::Cylinder {
            point: Point3::new(8.0, 0.0, 0.0),
            axis: Vector3::z(),
            radius: 0.35,
            count,
        };
        assert!((run(c(1), &p, 0.05, 20.0).unwrap() - 7.65).abs() < 1e-9);
        assert!((run(c(2), &p, 0.05, 20.0).unwrap() - 8.35).abs() < 1e-9);
        assert_eq!(run(c(3), &p, 0.05, 20.0), None);
    }

    const PART: &str = "[[plane]]\nid = \"table\"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n\n[[cylinder]]\nid = \"pin\"\npoint_mm = [200, -100, 0]\naxis = [0, 0, 1]\ndiameter_mm = 40\nside = \"outside\"\n\n[[cylinder]]\nid = \"bore\"\npoint_mm = [-100, 0, 0]\naxis = [0, 0, 1]\ndiameter_mm = 30\nside = \"inside\"\n\n[[sphere]]\nid = \"ball\"\ncenter_mm = [100, 50, 20]\ndiameter_mm = 25\n";

    /// The route of a scan from the contact at tip centre `tip` with normal `n`: "line", "circle"
    /// or "stepped", with the log text.
    fn route(
        part: Option<&str>,
        tip: [f64; 3],
        n: [f64; 3],
        guide: Guide,
        toward: [f64; 3],
    ) -> (String, String) {
        let part = part.map(|t| Part::from_toml("p", t).unwrap());
        let m = IppdmeCmm::new(&truepos_ippdme::MachineConfig::ideal(), part);
        let start = Contact { tip_center_mm: Point3::from(tip), normal: Vector3::from(n).normalize() };
        match m.contour_route(&start, &guide, &Vector3::from(toward), 1.5) {
            Ok(Route::Planned(f, what)) => {
                let kind = match f.geometry {
                    Geometry::Line { .. } => "line",
                    Geometry::Circle { .. } => "circle",
                };
                (kind.to_string(), what)
            }
            Ok(Route::Stepped(why)) => ("stepped".into(), why),
            Err(e) => ("error".into(), e.to_string()),
        }
    }

    #[test]
    fn every_row_of_the_route_table() {
        let p = Some(PART);
        let plane = |v: [f64; 3]| Guide::Plane { normal: Vector3::from(v).normalize() };
        let cyl = |o: [f64; 3], a: [f64; 3]| Guide::Cylinder {
            point: Point3::from(o),
            axis: Vector3::from(a).normalize(),
        };
        let table = [0.0, -200.0, 1.5];
        let pin = [221.5, -100.0, 10.0];
        let bore = [-86.5, 0.0, -10.0];
        let cases: Vec<(&str, (String, String), &str, &str)> = vec![
            (
                "plane · table",
                route(p, table, [0., 0., 1.], plane([0., 1., 0.]), [1., 0., 0.]),
                "line",
                "line on the plane face `table`",
            ),
            (
                "plane ∥ table",
                route(p, table, [0., 0., 1.], plane([0., 0., 1.]), [1., 0., 0.]),
                "stepped",
                "parallel",
            ),
            (
                "plane ⊥ pin",
                route(p, pin, [1., 0., 0.], plane([0., 0., 1.]), [0., 1., 0.]),
                "circle",
                "circle about the axis of the pin `pin`",
            ),
            (
                "plane ∋ pin axis",
                route(p, pin, [1., 0., 0.], plane([0., 1., 0.]), [0., 0., 1.]),
                "line",
                "line along the pin `pin`",
            ),
            (
                "plane oblique to pin",
                route(p, pin, [1., 0., 0.], plane([0., 1., 1.]), [0., 1., -1.]),
                "stepped",
                "ellipse",
            ),
            (
                "plane ⊥ bore",
                route(p, bore, [-1., 0., 0.], plane([0., 0., 1.]), [0., 1., 0.]),
                "circle",
                "circle about the axis of the bore `bore`",
            ),
            (
                "plane through ball centre",
                route(p, [100., 50., 34.], [0., 0., 1.], plane([0., 1., 0.]), [1., 0., 0.]),
                "circle",
                "great circle of the sphere `ball`",
            ),
            (
                "plane off ball centre",
                route(p, [100., 55.6, 32.84], [0., 0.4, 0.9165], plane([0., 1., 0.]), [1., 0., 0.]),
                "stepped",
                "off its centre",
            ),
            (
                "cylinder ⊥ table",
                route(p, [10., -400., 1.5], [0., 0., 1.], cyl([0., -400., 0.], [0., 0., 1.]), [0., 1., 0.]),
                "circle",
                "circle about the scan axis on the plane face",
            ),
            (
                "cylinder ∥ table",
                route(p, [10., -400., 1.5], [0., 0., 1.], cyl([0., -400., 20.], [1., 0., 0.]), [1., 0., 0.]),
                "line",
                "line along the scan axis on the plane face",
            ),
            (
                "cylinder oblique to table",
                route(p, [10., -400., 1.5], [0., 0., 1.], cyl([0., -400., 0.], [1., 0., 1.]), [0., 1., 0.]),
                "stepped",
                "ellipse",
            ),
            (
                "coaxial bore, around",
                route(p, bore, [-1., 0., 0.], cyl([-100., 0., 0.], [0., 0., 1.]), [0., 1., 0.]),
                "circle",
                "circle on the bore `bore`, coaxial",
            ),
            (
                "coaxial bore, along",
                route(p, bore, [-1., 0., 0.], cyl([-100., 0., 0.], [0., 0., 1.]), [0., 0., -1.]),
                "line",
                "coaxial",
            ),
            (
                "coaxial bore, helix",
                route(p, bore, [-1., 0., 0.], cyl([-100., 0., 0.], [0., 0., 1.]), [0., 1., 1.]),
                "stepped",
                "helix",
            ),
            (
                "pin parallel, off axis",
                route(p, pin, [1., 0., 0.], cyl([300., -100., 0.], [0., 0., 1.]), [0., 0., 1.]),
                "line",
                "parallel to the scan axis",
            ),
            (
                "pin oblique",
                route(p, pin, [1., 0., 0.], cyl([200., -100., 0.], [1., 0., 1.]), [0., 1., 0.]),
                "stepped",
                "space curve",
            ),
            (
                "ball equator",
                route(p, [114., 50., 20.], [1., 0., 0.], cyl([100., 50., 0.], [0., 0., 1.]), [0., 1., 0.]),
                "circle",
                "equator of the sphere `ball`",
            ),
            (
                "ball off equator",
                route(p, [109.9, 50., 29.9], [1., 0., 1.], cyl([100., 50., 0.], [0., 0., 1.]), [0., 1., 0.]),
                "stepped",
                "off its equator",
            ),
            (
                "no part: ideal plane",
                route(None, [0., 0., 1.5], [0., 0., 1.], plane([0., 1., 0.]), [1., 0., 0.]),
                "line",
                "ideal plane",
            ),
            (
                "direction across the only path",
                route(p, table, [0., 0., 1.], plane([0., 1., 0.]), [0., 0., 1.]),
                "error",
                "undefined",
            ),
            (
                "edge: nothing under the start",
                route(p, [0., 0., 30.], [0., 0., 1.], plane([0., 1., 0.]), [1., 0., 0.]),
                "stepped",
                "no single face",
            ),
        ];
        for (name, (kind, what), want, words) in cases {
            assert_eq!(kind, want, "{name}: {what}");
            assert!(what.contains(words), "{name}: {what}");
        }
    }

    #[test]
    fn a_sphere_entered_on_the_second_turn_of_a_circle() {
        // A circle of radius 5 about Z, the stop sphere on it at 90°: count 2 is one turn later.
        let p = |u: f64| Point3::new(5.0 * u.cos(), 5.0 * u.sin(), 0.0);
        let s = |count| Stop::Sphere { center: Point3::new(0.0, 5.0, 0.0), radius: 1.0, count };
        let h = 0.01;
        let first = run(s(1), &p, h, 20.0).unwrap();
        let second = run(s(2), &p, h, 20.0).unwrap();
        assert!((first - std::f64::consts::FRAC_PI_2).abs() < 1e-6, "{first}");
        assert!((second - first - 2.0 * std::f64::consts::PI).abs() < 1e-6, "{second}");
    }
}
