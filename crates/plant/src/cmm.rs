//! The virtual CMM behind `truepos ippdme serve`: the cell's bridge CMM with its error models
//! (instant moves), a touch-trigger probe, a scanning probe driven by the blended scanning
//! planner, and a part made of exact solids (the part file of `truepos-ippdme`: union of spheres,
//! half-spaces, pins and bores).
//!
//! **Error models** (configured by the machine file's `[ippdme.model]`,
//! [`truepos_ippdme::ModelConfig`]; one implementation each, from `truepos-sim`):
//! - geometric: the ISO 230-1 map of a realistic bridge CMM (`truepos_sim::machine::Machine`,
//!   seeded), its axis travels stretched over the server's volume, evaluated for a stylus of
//!   `stylus_length_mm` below the ram. The tip is at `actual(p) = p + E(p)` when the scales read
//!   `p`; every contact happens at the actual position and is reported at the scale reading, so
//!   the residual geometric error (a few µm) is in the reported points as on a real CMM.
//! - touch-trigger probe (`truepos_sim::touch::TouchProbe`): the probe triggers once the
//!   stylus deflection (pre-travel, which includes the stylus bending up to the trigger force)
//!   reaches `pretravel + lobing·cos 3φ`; the machine reports the scale position at the trigger.
//!   The probe calibration (`pretravel_compensated`) removes the mean pre-travel along the
//!   contact normal (the effective tip radius), so the lobing remains.
//! - probing noise (`truepos_sim::noise`, seeded streams): Gaussian, σ per axis, on every touch.
//! - scanning: `ScanOnCircle`/`ScanOnLine` (and their hint variants) are planned by the blended,
//!   stop-free planner of `truepos-scan` and executed on the servo/stylus dynamics of
//!   [`crate::scanning_cmm::VirtualCmm`] against the part (displaced by `E`), with its encoder
//!   and deflection noise; the points reported are the measured tip centres at the requested
//!   step. Unknown-contour scans (11.3, the `ScanIn…` family) go the same way wherever the
//!   surface under them is a line or circle the planner can plan (`contour`: a plane face,
//!   a pin, a bore or a sphere cut in a line or a circle), ending where the stop criterion is
//!   met on the planned path; elsewhere (an ellipse, a helix, a path across several faces) they
//!   step along the surface with exact contacts plus the touch noise, and say so in the log.
//!
//! With [`truepos_ippdme::ModelConfig::ideal`] contacts are exact: a probing move of the ball
//! centre along a segment latches the first parameter at which the ball touches any solid (the
//! ball-centre surface is the part's surface offset by the tip radius, which for a union is the
//! union of the offset solids), and the normal there. Without a part, every probing touches the
//! ideal plane through the nominal point, normal to the probing direction (contract).
//! Positioning moves that would touch the part stop at the touch and fail
//! (`MachineError::IllegalTouch`).
//!
//! Entry point: [`IppdmeCmm::new`]; it implements [`truepos_ippdme::Cmm`].

use std::sync::Arc;
use truepos_ippdme::part::{CylinderSide, Part, Solid};
use truepos_ippdme::{
    Cmm, Contact, Guide, MachineConfig, MachineError, ModelConfig, ScanPath, ScanPoint, Stop,
};
use truepos_math::{rz, Matrix3, Point3, Vector3};
use truepos_scan::execute::ControlParams;
use truepos_scan::{Feature, Geometry, Params, SegmentKind, Side, Style};
use truepos_sim::artefact::{Artefact, SurfacePoint};
use truepos_sim::machine::{Machine, MachineKind};
use truepos_sim::noise::{self, SimRng};
use truepos_sim::touch::TouchProbe;

use crate::scanning_cmm::{CmmConfig, VirtualCmm};

mod contour;

/// Most points one scan may return (bounds the memory of a session).
const MAX_SCAN_POINTS: usize = 1_000_000;
/// Most machine time (s) one scan may take (bounds the simulation's work per command).
const MAX_SCAN_TIME_S: f64 = 300.0;
/// Largest sweep of one circle scan (rad): two turns, the planner's limit.
const MAX_SCAN_SWEEP_RAD: f64 = 4.0 * std::f64::consts::PI;

/// How far (mm along the surface) a scan runs beyond its last requested point.
const OVERSCAN_MM: f64 = 0.5;

/// Contacts closer than this (mm) to the start of a move count as "already touching".
const TOUCH_EPS: f64 = 1e-9;

/// The geometric error field of the machine: `E(p)`, actual − nominal tip position when the
/// scales read `p`.
#[derive(Debug, Clone)]
pub struct ErrorField {
    machine: Machine,
    lo: Point3,
    hi: Point3,
    tool: Vector3,
    scale: f64,
}

impl ErrorField {
    /// The seeded realistic bridge CMM of `truepos-sim`, its travels stretched over `lo..hi`.
    pub fn bridge_cmm(model: &ModelConfig, lo: Point3, hi: Point3) -> ErrorField {
        ErrorField {
            machine: Machine::realistic(MachineKind::BridgeCmm, model.seed),
            lo,
            hi,
            tool: Vector3::new(0.0, 0.0, -model.stylus_length_mm),
            scale: model.geometric_error_scale,
        }
    }

    /// `E(p)` (mm): the error of the chain at the axis positions of `p` (clamped to the travel).
    pub fn at(&self, p: &Point3) -> Vector3 {
        let t = self.machine.travel;
        let axes = Point3::new(
            ((p.x - self.lo.x) / (self.hi.x - self.lo.x)).clamp(0.0, 1.0) * t[0],
            ((p.y - self.lo.y) / (self.hi.y - self.lo.y)).clamp(0.0, 1.0) * t[1],
            ((p.z - self.lo.z) / (self.hi.z - self.lo.z)).clamp(0.0, 1.0) * t[2],
        );
        (self.machine.tip(&axes, &self.tool) - self.machine.nominal_tip(&axes, &self.tool)) * self.scale
    }
}

/// The error models of the machine, built from [`ModelConfig`].
#[derive(Debug, Clone)]
struct Models {
    config: ModelConfig,
    errors: Option<Arc<ErrorField>>,
    probe: Option<TouchProbe>,
    rng_touch: SimRng,
    /// Scans so far (each scan's dynamic noise is drawn from its own seeded stream).
    scans: u64,
    /// Stylus deflection left by the last trigger (mm): the body stopped past the contact by
    /// the pre-travel, so the next move may start with the ball that far "in" the material.
    deflected_mm: f64,
}

/// The virtual CMM.
#[derive(Debug, Clone)]
pub struct IppdmeCmm {
    /// The part where it is now (its file's solids moved by `mount` and the table).
    part: Option<Arc<Part>>,
    /// The part as its file describes it.
    part_file: Option<Arc<Part>>,
    /// The rotary table: its axis point (axis parallel to Z), `None` for a CartCMM.
    table: Option<Point3>,
    table_angle: f64,
    /// How the part sits on the table at angle 0: file coordinates `a` ↦ `R·a + t`.
    mount: (Matrix3, Vector3),
    volume: (Point3, Point3),
    position: Point3,
    models: Models,
    /// How the last unknown-contour scan ran (for the session log).
    note: Option<String>,
    /// Number of probing moves, positioning moves and scan points so far (for tests).
    pub counters: Counters,
}

/// What the machine did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Positioning moves made.
    pub moves: u64,
    /// Points probed.
    pub probes: u64,
    /// Points scanned.
    pub scan_points: u64,
    /// Times the machine stopped on an abort or error.
    pub stops: u64,
}

impl IppdmeCmm {
    /// A machine with the volume and error models of `config` and optionally a part. It starts
    /// un-homed at its home position. The error models are deterministic for the model's seed.
    pub fn new(config: &MachineConfig, part: Option<Part>) -> IppdmeCmm {
        let (lo, hi) = (config.volume_min_mm, config.volume_max_mm);
        let m = &config.model;
        let errors = (m.geometric_errors && m.geometric_error_scale > 0.0)
            .then(|| Arc::new(ErrorField::bridge_cmm(m, lo, hi)));
        // Pre-travel 0 is an ideal probe; the machine file checks lobing < pre-travel.
        let probe = TouchProbe::new(0.0, m.pretravel_mm, m.lobing_mm).ok();
        IppdmeCmm {
            part: part.clone().map(Arc::new),
            part_file: part.map(Arc::new),
            table: config.rotary_table,
            table_angle: 0.0,
            mount: (Matrix3::identity(), Vector3::zeros()),
            volume: (lo, hi),
            position: home_of(lo, hi),
            models: Models {
                config: m.clone(),
                errors,
                probe,
                rng_touch: noise::stream(m.seed, 11),
                scans: 0,
                deflected_mm: 0.0,
            },
            note: None,
            counters: Counters::default(),
        }
    }

    /// The part where it is now (moved by the rotary table and by `move_part`).
    pub fn part(&self) -> Option<&Part> {
        self.part.as_deref()
    }

    /// The part's file solids posed by the mount `(R, t)` (file coordinates `a` ↦ `R·a + t` on
    /// the table at angle 0) and the table angle (rad); `None` without a part.
    fn posed(&self, table_angle: f64, mount: (Matrix3, Vector3)) -> Option<Part> {
        let file = self.part_file.as_ref()?;
        let o = self.table.unwrap_or_else(Point3::origin);
        let rt = rz(table_angle);
        let (rm, tm) = mount;
        let point = |a: &Point3| o + rt * (rm * a.coords + tm - o.coords);
        let dir = |v: &Vector3| rt * (rm * v);
        let solids = file
            .solids
            .iter()
            .map(|(id, s)| {
                let s = match s {
                    Solid::Sphere { center, radius } => {
                        Solid::Sphere { center: point(center), radius: *radius }
                    }
                    Solid::HalfSpace { point: p, normal } => {
                        Solid::HalfSpace { point: point(p), normal: dir(normal) }
                    }
                    Solid::Cylinder { point: p, axis, radius, side, ends } => Solid::Cylinder {
                        point: point(p),
                        axis: dir(axis),
                        radius: *radius,
                        side: *side,
                        ends: *ends,
                    },
                    Solid::Prism { origin, u, v, w, polygon, height } => Solid::Prism {
                        origin: point(origin),
                        u: dir(u),
                        v: dir(v),
                        w: dir(w),
                        polygon: polygon.clone(),
                        height: *height,
                    },
                };
                (id.clone(), s)
            })
            .collect();
        Some(Part { solids })
    }

    /// Refuse a new pose of the part that takes a solid which reaches into the machine volume
    /// now out of it (or makes a number non-finite): the part would be out of reach for the
    /// server's life. `what` names the command.
    fn check_pose(&self, new: &Part, what: &str) -> Result<(), MachineError> {
        let Some(now) = &self.part else { return Ok(()) };
        for (k, ((id, before), (_, after))) in now.solids.iter().zip(&new.solids).enumerate() {
            if meets_box(before, &self.volume) && !meets_box(after, &self.volume) {
                let name = match id {
                    Some(id) => format!("solid '{id}'"),
                    None => format!("solid {} of the part file", k + 1),
                };
                return Err(MachineError::PartOutOfVolume(format!(
                    "{what} would move {name} out of the machine volume {:?}..{:?} mm; refused and the part left where it is",
                    self.volume.0.coords.as_slice(),
                    self.volume.1.coords.as_slice()
                )));
            }
        }
        Ok(())
    }

    /// The error models' configuration.
    pub fn model(&self) -> &ModelConfig {
        &self.models.config
    }

    /// Where the tip actually is when the scales read `p`.
    pub fn actual(&self, p: &Point3) -> Point3 {
        match &self.models.errors {
            Some(e) => p + e.at(p),
            None => *p,
        }
    }

    /// Touch noise (σ per axis of the model).
    fn touch_noise(&mut self) -> Vector3 {
        let s = self.models.config.probe_noise_mm;
        if s > 0.0 {
            noise::gaussian3(&mut self.models.rng_touch, s)
        } else {
            Vector3::zeros()
        }
    }

    /// Whether a ball of radius `r` centred at `c` overlaps the material (touching is not
    /// overlapping: penetration below 1 nm is ignored).
    pub fn collides(&self, c: &Point3, r: f64) -> bool {
        let Some(part) = &self.part else { return false };
        let mut overlaps = false;
        for (_, s) in &part.solids {
            match s {
                Solid::Cylinder { side: CylinderSide::Inside, .. } => {
                    if gap(s, c, r) <= TOUCH_EPS {
                        // Inside the bore's free cylinder (touching its wall included): the bore
                        // removes all material the ball could reach.
                        return false;
                    }
                }
                _ => overlaps |= gap(s, c, r) < -TOUCH_EPS,
            }
        }
        overlaps
    }

    /// First contact of a ball of radius `r` moving from `a` to `b`: (fraction along the move,
    /// contact normal out of the material). A ball that already touches at `a` has contact at 0
    /// only if the move goes into the material.
    pub fn first_contact(&self, a: &Point3, b: &Point3, r: f64) -> Option<(f64, Vector3)> {
        let part = self.part.as_ref()?;
        let d = b - a;
        // Every parameter where the ball crosses the boundary of one solid's offset.
        let mut events = vec![0.0, 1.0];
        for (_, s) in &part.solids {
            crossings(s, a, &d, r, &mut events);
        }
        events.retain(|t| (0.0..=1.0).contains(t));
        events.sort_by(|x, y| x.total_cmp(y));
        events.dedup();
        for w in events.windows(2) {
            let (t0, t1) = (w[0], w[1]);
            if t1 - t0 < 1e-15 {
                continue;
            }
            if self.collides(&(a + d * (0.5 * (t0 + t1))), r) {
                let c = a + d * t0;
                return Some((t0, self.normal_at(&c, r, &d)));
            }
        }
        None
    }

    /// The surface normal where a ball at `c` touches (the solid whose offset surface passes
    /// through `c`; among several, the one the move `d` enters most directly).
    fn normal_at(&self, c: &Point3, r: f64, d: &Vector3) -> Vector3 {
        let mut best: Option<(f64, Vector3)> = None;
        if let Some(part) = &self.part {
            for (_, s) in &part.solids {
                let g = gap(s, c, r).abs();
                if g > 1e-6 {
                    continue;
                }
                let n = outward(s, c);
                let score = n.dot(d);
                if best.is_none_or(|(b, _)| score < b) {
                    best = Some((score, n));
                }
            }
        }
        best.map(|(_, n)| n).unwrap_or_else(|| -d.try_normalize(1e-15).unwrap_or_else(Vector3::z))
    }

    fn probe_exact(&self, from: &Point3, to: &Point3, r: f64) -> Option<Contact> {
        let (t, n) = self.first_contact(from, to, r)?;
        Some(Contact { tip_center_mm: from + (to - from) * t, normal: n })
    }
}

/// Progress of a stop criterion along a scan.
struct StopState {
    crossings: u32,
    inside: Option<bool>,
    left_once: bool,
    last_distance: f64,
    travelled: f64,
}

impl StopState {
    /// Feed the next surface point; true when the scan ends at this point (inclusive).
    fn update(&mut self, stop: &Stop, p: &Point3, step: f64) -> bool {
        self.travelled += step;
        match *stop {
            Stop::Sphere { center, radius, count } => {
                let dist = (p - center).norm();
                let inside = dist <= radius;
                let was = self.inside.replace(inside);
                if was.is_none() {
                    self.left_once = !inside;
                } else if !inside {
                    self.left_once = true;
                } else if was == Some(false) && self.left_once {
                    self.crossings += 1;
                }
                let done = inside && self.crossings >= count && dist > self.last_distance;
                self.last_distance = dist;
                done
            }
            Stop::Plane { point, normal, count, arm_mm } => {
                let side = (p - point).dot(&normal) > 0.0;
                let was = self.inside.replace(side);
                if self.travelled > arm_mm && was.is_some_and(|w| w != side) {
                    self.crossings += 1;
                }
                self.crossings >= count
            }
            Stop::Cylinder { point, axis, radius, count } => {
                let rel = p - point;
                let inside = (rel - axis * rel.dot(&axis)).norm() <= radius;
                let was = self.inside.replace(inside);
                if was.is_some_and(|w| w != inside) {
                    self.crossings += 1;
                }
                self.crossings >= count
            }
        }
    }
}

impl IppdmeCmm {
    /// Unknown-contour following: step along the surface, tip centre on the guide, probing each
    /// point along the last surface normal (projected into the guide's tangent plane).
    fn follow(
        &mut self,
        start: Contact,
        guide: &Guide,
        toward: &Vector3,
        step: f64,
        stop: &Stop,
        max_length_mm: f64,
        r: f64,
        out: &mut Vec<ScanPoint>,
    ) -> Result<(), MachineError> {
        let guide_normal = |c: &Point3| -> Vector3 {
            match guide {
                Guide::Plane { normal } => normal.normalize(),
                Guide::Cylinder { point, axis } => {
                    let rel = c - point;
                    (rel - axis * rel.dot(axis)).try_normalize(1e-12).unwrap_or_else(|| perpendicular(axis))
                }
            }
        };
        let on_guide = |q: Point3| -> Point3 {
            match guide {
                Guide::Plane { normal } => {
                    let n = normal.normalize();
                    q - n * (q - start.tip_center_mm).dot(&n)
                }
                Guide::Cylinder { point, axis } => {
                    let a = axis.normalize();
                    let rho = {
                        let rel = start.tip_center_mm - point;
                        (rel - a * rel.dot(&a)).norm()
                    };
                    let rel = q - point;
                    let radial = rel - a * rel.dot(&a);
                    match radial.try_normalize(1e-12) {
                        Some(u) => point + a * rel.dot(&a) + u * rho,
                        None => q,
                    }
                }
            }
        };
        // Orthonormalise `v` against the surface normal and the guide normal.
        let tangent = |v: &Vector3, n: &Vector3, g: &Vector3| -> Option<Vector3> {
            let g2 = (g - n * n.dot(g)).try_normalize(1e-9);
            let mut t = v - n * n.dot(v);
            if let Some(g2) = g2 {
                t -= g2 * g2.dot(&t);
            }
            t.try_normalize(1e-9)
        };
        let mut c = start;
        let mut dir = *toward;
        let mut st = StopState {
            crossings: 0,
            inside: None,
            left_once: false,
            last_distance: f64::INFINITY,
            travelled: 0.0,
        };
        st.update(stop, &(c.tip_center_mm - c.normal * r), 0.0);
        self.counters.scan_points += 1;
        out.push(ScanPoint { tip_center_mm: c.tip_center_mm, normal: c.normal, quality: 0.0 });
        let (lo, hi) = self.volume;
        let mut travelled = 0.0;
        while travelled < max_length_mm {
            let g = guide_normal(&c.tip_center_mm);
            let t = tangent(&dir, &c.normal, &g)
                .ok_or_else(|| MachineError::Unable("the scan direction is undefined".into()))?;
            let q = on_guide(c.tip_center_mm + t * step);
            if (0..3).any(|k| q[k] < lo[k] || q[k] > hi[k]) {
                return Err(MachineError::OutOfVolume);
            }
            let n_probe = {
                let g = guide_normal(&q);
                (c.normal - g * g.dot(&c.normal)).try_normalize(1e-9).unwrap_or(c.normal)
            };
            let next = if self.part.is_none() {
                // The ideal plane of the start contact.
                let d = (q - start.tip_center_mm).dot(&start.normal);
                Some(Contact { tip_center_mm: q - start.normal * d, normal: start.normal })
            } else {
                let w = 2.0 * step + 1.0;
                self.probe_exact(&(q + n_probe * w), &(q - n_probe * w), r)
            };
            let Some(nc) = next else {
                return Err(MachineError::Unable(format!(
                    "lost the surface after {} points (no contact within {:.3} mm of the path)",
                    out.len(),
                    2.0 * step + 1.0
                )));
            };
            let moved = (nc.tip_center_mm - c.tip_center_mm).norm();
            if moved < 1e-9 {
                return Err(MachineError::Unable("the scan does not advance (concave corner)".into()));
            }
            travelled += moved;
            dir = nc.tip_center_mm - c.tip_center_mm;
            c = nc;
            self.position = c.tip_center_mm;
            self.counters.scan_points += 1;
            out.push(ScanPoint { tip_center_mm: c.tip_center_mm, normal: c.normal, quality: 0.0 });
            if st.update(stop, &(c.tip_center_mm - c.normal * r), moved) {
                return Ok(());
            }
        }
        Err(MachineError::Unable(format!(
            "the stop criterion was not met within {max_length_mm:.0} mm of scanning"
        )))
    }
}

/// Whether solid `s` reaches into the box `(lo, hi)`: a sphere overlaps it, a half-space's
/// plane cuts it (or touches it), a cylinder's axis passes through the box grown by its radius,
/// a prism's bounding box overlaps it. False for any non-finite number.
fn meets_box(s: &Solid, (lo, hi): &(Point3, Point3)) -> bool {
    match s {
        Solid::Sphere { center, radius } => {
            let closest = Point3::new(
                center.x.clamp(lo.x, hi.x),
                center.y.clamp(lo.y, hi.y),
                center.z.clamp(lo.z, hi.z),
            );
            (center - closest).norm() <= *radius
        }
        Solid::HalfSpace { point, normal } => {
            let (mut below, mut above) = (false, false);
            for k in 0..8 {
                let corner = Point3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                );
                let h = (corner - point).dot(normal);
                below |= h <= 0.0;
                above |= h >= 0.0;
            }
            below && above
        }
        Solid::Cylinder { point, axis, radius, .. } => {
            // Slabs of the grown box along the infinite axis line.
            let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
            for k in 0..3 {
                let (a, b) = (lo[k] - radius, hi[k] + radius);
                if !(point[k].is_finite() && axis[k].is_finite()) {
                    return false;
                }
                if axis[k].abs() < 1e-12 {
                    if point[k] < a || point[k] > b {
                        return false;
                    }
                } else {
                    let (u, v) = ((a - point[k]) / axis[k], (b - point[k]) / axis[k]);
                    t0 = t0.max(u.min(v));
                    t1 = t1.min(u.max(v));
                }
            }
            t0 <= t1
        }
        Solid::Prism { origin, u, v, w, polygon, height } => {
            // Its bounding box (of the polygon's corners at both ends) overlaps the box.
            let mut bb = (Point3::from([f64::INFINITY; 3]), Point3::from([f64::NEG_INFINITY; 3]));
            for [a, b] in polygon {
                for h in [0.0, *height] {
                    let p = origin + u * *a + v * *b + w * h;
                    if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                        return false;
                    }
                    bb = (bb.0.inf(&p), bb.1.sup(&p));
                }
            }
            (0..3).all(|k| bb.0[k] <= hi[k] && bb.1[k] >= lo[k])
        }
    }
}

/// The home position: centred in X and Y, a tenth of the Z travel below its top.
fn home_of(lo: Point3, hi: Point3) -> Point3 {
    Point3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z - 0.1 * (hi.z - lo.z))
}

/// Signed gap of a ball of radius `r` at `c` to one solid's surface (negative: overlapping; for
/// a bore: negative when strictly inside its free cylinder shrunk by the ball, i.e. clear of its
/// wall and floor). Exact at edges and corners of bounded solids; convex along any line.
fn gap(s: &Solid, c: &Point3, r: f64) -> f64 {
    match s {
        Solid::Cylinder { point, axis, radius, side: CylinderSide::Inside, ends } => {
            let rel = c - point;
            let along = rel.dot(axis);
            let radial = (rel - axis * along).norm() - (radius - r);
            match ends {
                None => radial,
                Some((a, b)) => radial.max(a + r - along).max(along - (b - r)),
            }
        }
        _ => s.distance(c) - r,
    }
}

/// The material's outward normal of one solid at (the projection of) `c`.
fn outward(s: &Solid, c: &Point3) -> Vector3 {
    s.outward(c)
}

fn perpendicular(n: &Vector3) -> Vector3 {
    let a = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    n.cross(&a).normalize()
}

/// Roots of |p + t·d|² = R² (both), appended to `out`.
fn circle_roots(p: &Vector3, d: &Vector3, radius: f64, out: &mut Vec<f64>) {
    let a = d.dot(d);
    if a < 1e-30 || radius <= 0.0 {
        return;
    }
    let b = p.dot(d);
    let c = p.dot(p) - radius * radius;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return;
    }
    let q = disc.sqrt();
    out.push((-b - q) / a);
    out.push((-b + q) / a);
}

/// Parameters where a ball of radius `r` moving from `a` by `d` crosses the offset surface of `s`.
fn crossings(s: &Solid, a: &Point3, d: &Vector3, r: f64, out: &mut Vec<f64>) {
    match s {
        Solid::Sphere { center, radius } => circle_roots(&(a - center), d, radius + r, out),
        Solid::HalfSpace { point, normal } => {
            let dn = d.dot(normal);
            if dn.abs() > 1e-300 {
                out.push(-((a - point).dot(normal) - r) / dn);
            }
        }
        Solid::Cylinder { ends: Some(_), .. } | Solid::Prism { .. } => convex_crossings(s, a, d, r, out),
        Solid::Cylinder { point, axis, radius, side, ends: None } => {
            let rel = a - point;
            let p = rel - axis * rel.dot(axis);
            let dp = d - axis * d.dot(axis);
            let big = match side {
                CylinderSide::Outside => radius + r,
                CylinderSide::Inside => radius - r,
            };
            circle_roots(&p, &dp, big, out);
        }
    }
}

/// Where a ball of radius `r` moving from `a` by `d` (t in [0, 1]) enters and leaves a bounded
/// solid's offset (or a finite bore's free region): `gap` is convex along the line, so its
/// minimum is found by golden-section search and each root by bisection on either side.
fn convex_crossings(s: &Solid, a: &Point3, d: &Vector3, r: f64, out: &mut Vec<f64>) {
    if d.norm() < 1e-15 {
        return;
    }
    let f = |t: f64| gap(s, &(a + d * t), r);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut lo, mut hi) = (0.0, 1.0);
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..80 {
        if f1 < f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
    }
    let tm = 0.5 * (lo + hi);
    let (t_min, f_min) = [(0.0, f(0.0)), (tm, f(tm)), (1.0, f(1.0))]
        .into_iter()
        .fold((tm, f64::INFINITY), |b, x| if x.1 < b.1 { x } else { b });
    if f_min > 0.0 {
        return;
    }
    let root = |mut outside: f64, mut inside: f64| {
        for _ in 0..200 {
            let m = 0.5 * (outside + inside);
            if m == outside || m == inside {
                break;
            }
            if f(m) > 0.0 {
                outside = m;
            } else {
                inside = m;
            }
        }
        outside
    };
    if f(0.0) > 0.0 {
        out.push(root(0.0, t_min));
    }
    if f(1.0) > 0.0 {
        out.push(root(1.0, t_min));
    }
}

/// The part's surface for the stylus model: signed distance of the union of its solids minus its
/// bores (constructive-solid-geometry distance: exact near a single face), displaced by the
/// machine's geometric errors so that the machine, working in scale coordinates, touches where
/// the actual tip meets the part.
#[derive(Debug)]
struct PartSurface {
    part: Arc<Part>,
    errors: Option<Arc<ErrorField>>,
}

/// Signed distance of `p` to the part's surface (positive outside the material) and the outward
/// normal there: union of the solids minus the bores, exact near a single face.
fn part_distance(part: &Part, p: &Point3) -> (f64, Vector3) {
    let mut best = (f64::INFINITY, Vector3::z());
    for (_, s) in &part.solids {
        if !matches!(s, Solid::Cylinder { side: CylinderSide::Inside, .. }) {
            let d = gap(s, p, 0.0);
            if d < best.0 {
                best = (d, outward(s, p));
            }
        }
    }
    for (_, s) in &part.solids {
        if matches!(s, Solid::Cylinder { side: CylinderSide::Inside, .. }) {
            // Inside the free cylinder `gap` is negative: the material's distance is −gap.
            let d = -gap(s, p, 0.0);
            if d > best.0 {
                best = (d, outward(s, p));
            }
        }
    }
    if !best.0.is_finite() {
        best.0 = 1e9;
    }
    best
}

impl Artefact for PartSurface {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let e = self.errors.as_ref().map(|e| e.at(p)).unwrap_or_else(Vector3::zeros);
        let (distance, normal) = part_distance(&self.part, &(p + e));
        SurfacePoint { distance, point: p - normal * distance, normal }
    }
}

/// A nominal scan feature as the true surface (no part: the ideal surface through the start).
#[derive(Debug)]
struct Nominal(Feature);

impl Artefact for Nominal {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let (distance, normal) = self.0.signed_distance(p);
        SurfacePoint { distance, point: p - normal * distance, normal }
    }
}

impl IppdmeCmm {
    /// First contact of a probing or positioning move, as the fraction of the move in scale
    /// coordinates: found on the straight segment between the actual positions of its ends,
    /// then refined on the actual (slightly curved: the short-wave errors bend a 6 mm move by
    /// a few tenths of a µm) path `actual(from + t·(to − from))`.
    fn contact_on_move(&self, from: &Point3, to: &Point3, r: f64) -> Option<(f64, Vector3)> {
        let (mut t, mut n) = self.first_contact(&self.actual(from), &self.actual(to), r)?;
        let (Some(part), Some(_)) = (&self.part, &self.models.errors) else { return Some((t, n)) };
        let d = to - from;
        let gap_at = |t: f64| part_distance(part, &self.actual(&(from + d * t))).0 - r;
        let len = d.norm();
        if len <= 0.0 {
            return Some((t, n));
        }
        // Secant steps on the gap along the actual path (its slope is −|d|·cos of the approach).
        let h = 1e-4 / len;
        for _ in 0..4 {
            let g = gap_at(t);
            if g.abs() < 1e-10 {
                break;
            }
            let slope = (gap_at(t + h) - g) / h;
            if slope.abs() < 1e-12 {
                break;
            }
            t = (t - g / slope).clamp(0.0, 1.0);
        }
        n = part_distance(part, &self.actual(&(from + d * t))).1;
        Some((t, n))
    }

    /// The planner's parameters for a scan with a tip of radius `r`.
    fn scan_params(&self, r: f64) -> Params {
        let m = &self.models.config;
        Params {
            tip_radius: r,
            scan_speed: m.scan_speed_mm_s,
            deflection: m.scan_deflection_mm,
            overshoot: (m.scan_deflection_mm / 3.0).min(0.1),
            ..Params::default()
        }
    }

    /// Whether the planner can plan `feature` and the machine runs it within
    /// [`MAX_SCAN_TIME_S`]; the planner's parameters if so.
    fn check_planned(&self, feature: &Feature, r: f64) -> Result<Params, MachineError> {
        let params = self.scan_params(r);
        // The planner plans at most two turns; a two-turn ScanOnCircle runs its overscan beyond
        // them (every requested point lies within the two turns), so that excess is not refused.
        let mut checked = feature.clone();
        if let Geometry::Circle { sweep, radius, .. } = &mut checked.geometry {
            if sweep.abs() <= MAX_SCAN_SWEEP_RAD + OVERSCAN_MM / *radius * (1.0 + 1e-9) {
                *sweep = sweep.clamp(-MAX_SCAN_SWEEP_RAD, MAX_SCAN_SWEEP_RAD);
            }
        }
        truepos_scan::validate(std::slice::from_ref(&checked), &params)
            .map_err(|e| MachineError::Unable(format!("scan: {e}")))?;
        let length = feature.extent() * feature.metric(r - params.deflection);
        let seconds = length / params.scan_speed;
        // NaN (a non-finite path) is refused too.
        if seconds.is_nan() || seconds > MAX_SCAN_TIME_S {
            return Err(MachineError::Unable(format!(
                "scan: {length:.0} mm of tip-centre path at {} mm/s is {seconds:.0} s of machine time; the limit is {MAX_SCAN_TIME_S} s per scan ({:.0} mm at this speed)",
                params.scan_speed,
                MAX_SCAN_TIME_S * params.scan_speed
            )));
        }
        Ok(params)
    }

    /// Execute a circle or line scan with the blended planner on the scanning dynamics; the
    /// points at the requested parameters `targets` (rad or mm from the start) are appended.
    fn scan_planned(
        &mut self,
        feature: Feature,
        targets: &[f64],
        r: f64,
        out: &mut Vec<ScanPoint>,
    ) -> Result<(), MachineError> {
        let m = self.models.config.clone();
        let params = self.check_planned(&feature, r)?;
        let surface: Arc<dyn Artefact> = match &self.part {
            Some(p) => Arc::new(PartSurface { part: p.clone(), errors: self.models.errors.clone() }),
            None => Arc::new(Nominal(feature.clone())),
        };
        let plan = truepos_scan::plan(std::slice::from_ref(&feature), &params, Style::Blended);
        let cmm = CmmConfig {
            servo: truepos_sim::motion::Servo {
                bandwidth_hz: m.servo_bandwidth_hz,
                ..CmmConfig::default().servo
            },
            encoder_noise_mm: m.encoder_noise_mm,
            probe_noise_mm: m.scan_probe_noise_mm,
            ..CmmConfig::default()
        };
        self.models.scans += 1;
        let seed = m.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(self.models.scans);
        let mut machine = VirtualCmm::with_surfaces(cmm, vec![surface.clone()], seed)
            .map_err(|e| MachineError::Unable(format!("scan: {e}")))?;
        let run = truepos_scan::execute::execute(&plan, &mut machine, &ControlParams::default())
            .map_err(|e| MachineError::Unable(format!("scan: {e}")))?;
        // The scan segment's samples with their parameter along the feature.
        let samples: Vec<(f64, &truepos_scan::execute::Point)> = {
            let mut v = Vec::new();
            let mut unwrap = 0.0;
            let mut prev: Option<f64> = None;
            for p in run.points.iter().filter(|p| p.segment == SegmentKind::Scan && p.feature == 0) {
                let u = feature_param(&feature, &p.position);
                let u = match prev {
                    // Circles: unwrap the angle along the scan.
                    Some(q) if matches!(feature.geometry, Geometry::Circle { .. }) => {
                        let mut d = u + unwrap - q;
                        while d > std::f64::consts::PI {
                            unwrap -= 2.0 * std::f64::consts::PI;
                            d -= 2.0 * std::f64::consts::PI;
                        }
                        while d < -std::f64::consts::PI {
                            unwrap += 2.0 * std::f64::consts::PI;
                            d += 2.0 * std::f64::consts::PI;
                        }
                        q + d
                    }
                    _ => u,
                };
                prev = Some(u);
                v.push((u, p));
            }
            v
        };
        if samples.is_empty() {
            return Err(MachineError::Unable("scan: no point was measured in contact".into()));
        }
        // Each requested point is interpolated between the two measured samples around its
        // parameter (the control loop samples at 1 kHz; a step finer than the sample spacing
        // would otherwise repeat samples); outside the scanned range the end sample is used.
        let mut k = 0;
        for &t in targets {
            while k + 2 < samples.len() && samples[k + 1].0 < t {
                k += 1;
            }
            let (ua, a) = samples[k];
            let (pos, quality) = match samples.get(k + 1) {
                Some(&(ub, b)) if ub > ua => {
                    let w = ((t - ua) / (ub - ua)).clamp(0.0, 1.0);
                    (a.position + (b.position - a.position) * w, a.quality.max(b.quality))
                }
                _ => (a.position, a.quality),
            };
            let n = surface.closest(&pos).normal;
            self.counters.scan_points += 1;
            out.push(ScanPoint { tip_center_mm: pos, normal: n, quality: 10.0 * f64::from(quality) });
        }
        if let Some(last) = run.points.last() {
            self.position = last.commanded;
        }
        Ok(())
    }
}

/// A circle or line scan with its size known before it runs.
struct SizedScan {
    /// The feature the planner plans (with the overscan).
    feature: Feature,
    /// Number of steps between the requested points.
    n_steps: usize,
    /// The requested range of the scan parameter (rad for circles, mm for lines).
    span: f64,
}

/// The planned feature and size of a circle or line scan from the contact `start` (`None` for an
/// unknown contour, whose length is found while following it); refuses more than
/// [`MAX_SCAN_POINTS`] points and a circle's sweep beyond [`MAX_SCAN_SWEEP_RAD`].
fn sized_scan(start: &Contact, path: &ScanPath, r: f64) -> Result<Option<SizedScan>, MachineError> {
    let s0 = start.tip_center_mm - start.normal * r;
    match *path {
        ScanPath::Circle { center, axis, delta_rad, step_rad } => {
            let mut axis =
                axis.try_normalize(1e-15).ok_or_else(|| MachineError::Unable("zero scan axis".into()))?;
            if delta_rad.is_nan() || delta_rad.abs() > MAX_SCAN_SWEEP_RAD * (1.0 + 1e-12) {
                return Err(MachineError::Unable(format!(
                    "scan: |delta| = {:.3} deg is beyond the limit of 720 deg (two turns) per ScanOnCircle",
                    delta_rad.abs().to_degrees()
                )));
            }
            let mut delta = delta_rad.clamp(-MAX_SCAN_SWEEP_RAD, MAX_SCAN_SWEEP_RAD);
            let n_steps = steps(delta.abs() / step_rad.max(1e-12))?;
            let c = center + axis * (s0 - center).dot(&axis);
            let radial = s0 - c;
            let radius = radial.norm();
            let side = if start.normal.dot(&axis).abs() > 0.9 {
                if start.normal.dot(&axis) < 0.0 {
                    // The plane's outward normal is the feature's axis: turn it over and keep
                    // the sense of rotation.
                    axis = -axis;
                    delta = -delta;
                }
                Side::Plane
            } else if start.normal.dot(&radial) > 0.0 {
                Side::Outside
            } else {
                Side::Inside
            };
            if radius.is_nan() || radius < 1e-6 {
                return Err(MachineError::Unable("the scan circle has no radius".into()));
            }
            let (u, v) = Feature::basis(&axis);
            let feature = Feature {
                id: "ScanOnCircle".into(),
                geometry: Geometry::Circle {
                    center: c,
                    axis,
                    radius,
                    side,
                    start: radial.dot(&v).atan2(radial.dot(&u)),
                    // Overscan by 0.5 mm of arc (beyond 720° too): the planner's scan segment
                    // hands over to the release a few samples before its nominal end, and the
                    // last requested point must lie inside the scanned range.
                    sweep: (delta.abs() + OVERSCAN_MM / radius) * delta.signum(),
                },
            };
            Ok(Some(SizedScan { feature, n_steps, span: delta.abs() }))
        }
        ScanPath::Line { direction, length_mm, step_mm } => {
            let dir = (direction - start.normal * start.normal.dot(&direction))
                .try_normalize(1e-9)
                .ok_or_else(|| MachineError::Unable("the scan line runs along the normal".into()))?;
            let n_steps = steps(length_mm / step_mm.max(1e-12))?;
            let feature = Feature {
                id: "ScanOnLine".into(),
                geometry: Geometry::Line {
                    start: s0,
                    end: s0 + dir * (length_mm + OVERSCAN_MM),
                    normal: start.normal,
                },
            };
            Ok(Some(SizedScan { feature, n_steps, span: length_mm }))
        }
        ScanPath::Contour { step_mm, max_length_mm, .. } => {
            steps(max_length_mm / step_mm.max(1e-12))?;
            Ok(None)
        }
    }
}

/// The number of steps of a scan (at least 1), at most [`MAX_SCAN_POINTS`] − 1.
fn steps(ratio: f64) -> Result<usize, MachineError> {
    let n = ratio.round().max(1.0);
    if n >= MAX_SCAN_POINTS as f64 {
        return Err(MachineError::Unable(format!(
            "scan: {n:.0} steps; at most {} points per scan",
            MAX_SCAN_POINTS
        )));
    }
    Ok(n as usize)
}

/// The scan parameter of a measured tip centre: the angle from the start (rad, in the sweep's
/// sense) for circles, the distance along the line for lines.
fn feature_param(f: &Feature, p: &Point3) -> f64 {
    match &f.geometry {
        Geometry::Circle { center, axis, start, sweep, .. } => {
            let (u, v) = Feature::basis(axis);
            let d = p - center;
            let a = d.dot(&v).atan2(d.dot(&u));
            let mut x = (a - start) * sweep.signum();
            x = x.rem_euclid(2.0 * std::f64::consts::PI);
            if x > 1.5 * std::f64::consts::PI {
                x -= 2.0 * std::f64::consts::PI;
            }
            x
        }
        Geometry::Line { start, end, .. } => (p - start).dot(&(end - start).normalize()),
    }
}

impl Cmm for IppdmeCmm {
    fn describe(&self) -> String {
        let solids = self.part.as_ref().map(|p| p.solids.len()).unwrap_or(0);
        let m = &self.models.config;
        format!(
            "truepos virtual CMM (instant moves, {solids} part solids, geometric errors {}, pre-travel {:.1} µm, lobing {:.1} µm, touch noise {:.2} µm, scans on the blended planner)",
            if self.models.errors.is_some() { "on" } else { "off" },
            m.pretravel_mm * 1e3,
            m.lobing_mm * 1e3,
            m.probe_noise_mm * 1e3
        )
    }

    fn volume(&self) -> (Point3, Point3) {
        self.volume
    }

    fn home(&mut self) -> Result<Point3, MachineError> {
        self.position = home_of(self.volume.0, self.volume.1);
        self.counters.moves += 1;
        Ok(self.position)
    }

    fn position(&self) -> Point3 {
        self.position
    }

    fn move_to(&mut self, target_mm: Point3, tip_radius_mm: f64) -> Result<(), MachineError> {
        let (lo, hi) = self.volume;
        if (0..3).any(|k| !(target_mm[k] >= lo[k] - 1e-9 && target_mm[k] <= hi[k] + 1e-9)) {
            return Err(MachineError::OutOfVolume);
        }
        self.counters.moves += 1;
        // Leaving a trigger position: the deflected stylus springs back as the move starts.
        let r = (tip_radius_mm - std::mem::take(&mut self.models.deflected_mm)).max(0.0);
        if let Some((t, n)) = self.contact_on_move(&self.position, &target_mm, r) {
            // Stop at the touch, backed off by 1 µm along the normal.
            let stopped = self.position + (target_mm - self.position) * t + n * 1e-3;
            self.position = stopped;
            return Err(MachineError::IllegalTouch { stopped_mm: stopped });
        }
        self.position = target_mm;
        Ok(())
    }

    fn probe(
        &mut self,
        from_mm: Point3,
        to_mm: Point3,
        tip_radius_mm: f64,
        nominal_mm: Point3,
        nominal_normal: Vector3,
    ) -> Result<Option<Contact>, MachineError> {
        self.counters.probes += 1;
        let (a, b) = (self.actual(&from_mm), self.actual(&to_mm));
        let hit = match &self.part {
            Some(_) => self.contact_on_move(&from_mm, &to_mm, tip_radius_mm),
            None => {
                // The ideal plane through the nominal point, normal to the probing direction:
                // the ball centre touches it where the actual move reaches the plane offset by r.
                let n = nominal_normal
                    .try_normalize(1e-15)
                    .ok_or_else(|| MachineError::Unable("zero probing direction".into()))?;
                let touch = nominal_mm + n * tip_radius_mm;
                let d = b - a;
                let dn = d.dot(&n);
                let t = if dn.abs() > 1e-300 { (touch - a).dot(&n) / dn } else { f64::NAN };
                (0.0..=1.0).contains(&t).then_some((t, n))
            }
        };
        self.models.deflected_mm = 0.0;
        let Some((t, n)) = hit else {
            self.position = to_mm;
            return Ok(None);
        };
        let d = to_mm - from_mm;
        let len = d.norm();
        // The probe triggers when the deflection along the normal reaches the pre-travel: the
        // machine runs on by pretravel / cos(angle between the move and the normal).
        let (over, mean) = match &self.models.probe {
            Some(p) if len > 0.0 => {
                let cos = (-(d / len).dot(&n)).max(0.05);
                (p.pretravel(&n) / cos, p.pretravel_mm)
            }
            _ => (0.0, 0.0),
        };
        let t_trig = if len > 0.0 { t + over / len } else { t };
        if t_trig > 1.0 {
            // The move ended before the deflection reached the trigger.
            self.position = to_mm;
            return Ok(None);
        }
        let trigger = from_mm + d * t_trig;
        self.position = trigger;
        self.models.deflected_mm = if over > 0.0 { over + 1e-6 } else { 0.0 };
        let mut reported = trigger;
        if self.models.config.pretravel_compensated {
            reported += n * mean;
        }
        reported += self.touch_noise();
        Ok(Some(Contact { tip_center_mm: reported, normal: n }))
    }

    fn scan(
        &mut self,
        start: Contact,
        path: &ScanPath,
        tip_radius_mm: f64,
        out: &mut Vec<ScanPoint>,
    ) -> Result<(), MachineError> {
        let r = tip_radius_mm;
        match *path {
            ScanPath::Circle { .. } | ScanPath::Line { .. } => {
                let sized = sized_scan(&start, path, r)?
                    .ok_or_else(|| MachineError::Unable("scan: not a circle or a line".into()))?;
                // The planned feature is checked (planner limits, machine time) before the
                // requested parameters are allocated.
                self.check_planned(&sized.feature, r)?;
                let targets: Vec<f64> =
                    (0..=sized.n_steps).map(|k| sized.span * k as f64 / sized.n_steps as f64).collect();
                self.scan_planned(sized.feature, &targets, r, out)
            }
            ScanPath::Contour { guide, toward, step_mm, stop, max_length_mm } => {
                steps(max_length_mm / step_mm.max(1e-12))?;
                let why = match self.contour_route(&start, &guide, &toward, r)? {
                    contour::Route::Planned(feature, what) => {
                        match self.contour_end(&feature, &stop, step_mm, max_length_mm, r)? {
                            Ok((feature, end)) => {
                                let metric = feature.metric(r);
                                let n_steps = steps(end * metric / step_mm.max(1e-12))?;
                                let du = step_mm / metric;
                                let mut targets: Vec<f64> = (0..=n_steps)
                                    .map(|k| k as f64 * du)
                                    .take_while(|u| *u < end - 0.01 * du)
                                    .collect();
                                // The end point itself (grid points within 1 % of a step
                                // before it are left out).
                                targets.push(end);
                                let first = out.len();
                                match self.scan_planned(feature, &targets, r, out) {
                                    Ok(()) => {
                                        self.note = Some(format!(
                                            "unknown contour planned as {what} (blended planner on the scanning dynamics): {} points, {:.3} mm to the stop",
                                            targets.len(),
                                            end * metric
                                        ));
                                        return Ok(());
                                    }
                                    Err(e) => {
                                        // E.g. a bore too narrow for the planner: step instead.
                                        out.truncate(first);
                                        format!("the planned scan ({what}) failed: {e}")
                                    }
                                }
                            }
                            Err(why) => why,
                        }
                    }
                    contour::Route::Stepped(why) => why,
                };
                self.note = Some(format!(
                    "unknown contour stepped along the surface (exact contacts plus touch noise): {why}"
                ));
                let first = out.len();
                self.follow(start, &guide, &toward, step_mm, &stop, max_length_mm, tip_radius_mm, out)?;
                for p in &mut out[first..] {
                    let e = self.touch_noise();
                    p.tip_center_mm += e;
                }
                Ok(())
            }
        }
    }

    fn check_scan(
        &self,
        nominal_start: Contact,
        path: &ScanPath,
        tip_radius_mm: f64,
    ) -> Result<(), MachineError> {
        match sized_scan(&nominal_start, path, tip_radius_mm)? {
            Some(sized) => self.check_planned(&sized.feature, tip_radius_mm).map(|_| ()),
            None => Ok(()),
        }
    }

    fn stop(&mut self) {
        self.counters.stops += 1;
    }

    fn take_note(&mut self) -> Option<String> {
        self.note.take()
    }

    fn rotary_axis(&self) -> Option<(Point3, Vector3)> {
        self.table.map(|o| (o, Vector3::z()))
    }

    fn table_angle(&self) -> f64 {
        self.table_angle
    }

    fn set_table_angle(&mut self, angle_rad: f64) -> Result<(), MachineError> {
        if self.table.is_none() {
            return Err(MachineError::Unable("this CMM has no rotary table".into()));
        }
        if !angle_rad.is_finite() {
            return Err(MachineError::Unable(format!("table angle {angle_rad}")));
        }
        // The table turns by the shortest way to the angle, kept in (−180°, 180°].
        let mut a = angle_rad.rem_euclid(2.0 * std::f64::consts::PI);
        if a > std::f64::consts::PI {
            a -= 2.0 * std::f64::consts::PI;
        }
        if let Some(p) = self.posed(a, self.mount) {
            self.check_pose(&p, "turning the table")?;
            self.part = Some(Arc::new(p));
        }
        self.table_angle = a;
        self.counters.moves += 1;
        Ok(())
    }

    fn move_part(&mut self, rotation: Matrix3, about: Point3, shift: Vector3) -> Result<(), MachineError> {
        // In the table frame at angle 0: x0 ↦ O + Rz(−c)·(b + Q·(O + Rz(c)·(x0 − O) − b) + s − O).
        let o = self.table.unwrap_or_else(Point3::origin);
        let (rc, rci) = (rz(self.table_angle), rz(-self.table_angle));
        let f = |x0: Vector3| -> Vector3 {
            let x = o.coords + rc * (x0 - o.coords);
            let moved = about.coords + rotation * (x - about.coords) + shift;
            o.coords + rci * (moved - o.coords)
        };
        let (rm, tm) = self.mount;
        let mount = (rci * rotation * rc * rm, f(tm));
        if !(mount.0.iter().chain(mount.1.iter()).all(|x| x.is_finite())) {
            return Err(MachineError::PartOutOfVolume(
                "moving the part: a non-finite rotation or shift; refused and the part left where it is"
                    .into(),
            ));
        }
        if let Some(p) = self.posed(self.table_angle, mount) {
            self.check_pose(&p, "moving the part")?;
            self.part = Some(Arc::new(p));
        }
        self.mount = mount;
        self.counters.moves += 1;
        Ok(())
    }
}

/// Options of `truepos ippdme serve`.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Address to listen on.
    pub bind: String,
    /// TCP port to listen on (0: any free port).
    pub port: u16,
    /// The part file (TOML) the virtual CMM measures.
    pub part: Option<std::path::PathBuf>,
    /// The machine file (TOML) of the virtual CMM.
    pub machine: Option<std::path::PathBuf>,
    /// The protocol log file, if any.
    pub log: Option<std::path::PathBuf>,
    /// Drop a client that does not take each 64 KiB of its answers within this time
    /// ([`truepos_ippdme::server::DEFAULT_WRITE_TIMEOUT`], 10 s).
    pub write_timeout: std::time::Duration,
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A bad part or machine file (exit 2).
    #[error(transparent)]
    Input(#[from] truepos_ippdme::PartError),
    /// A part or machine file that cannot be read as a bounded text file: too large, binary
    /// data, a directory, a missing file (exit 2).
    #[error(transparent)]
    File(#[from] truepos_io::InputError),
    /// The log file cannot be opened (exit 2).
    #[error("{path}: cannot open the log: {source}")]
    Log {
        /// The log file.
        path: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The address cannot be bound, e.g. the port is in use (exit 3).
    #[error("cannot listen on {address}: {source}")]
    Bind {
        /// The address and port.
        address: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
}

/// Build the virtual CMM from the files and bind the I++ DME server (not yet accepting).
pub fn bind_virtual(opts: &ServeOptions) -> Result<truepos_ippdme::Server<IppdmeCmm>, ServeError> {
    // Through the bounded reader of configuration files (size limit, binary data refused at
    // once), which also records them as inputs: no output of the command may replace them.
    let config = match &opts.machine {
        Some(p) => {
            let text = truepos_io::limits::read_config_string(p, "TOML")?;
            MachineConfig::from_toml(&p.display().to_string(), &text)?
        }
        None => MachineConfig::default(),
    };
    let part = match &opts.part {
        Some(p) => {
            let text = truepos_io::limits::read_config_string(p, "TOML")?;
            Some(Part::from_toml(&p.display().to_string(), &text)?)
        }
        None => None,
    };
    let log = match &opts.log {
        Some(p) => Some(
            truepos_ippdme::server::Log::open(p)
                .map_err(|source| ServeError::Log { path: p.display().to_string(), source })?,
        ),
        None => None,
    };
    let address = if opts.bind.contains(':') {
        format!("[{}]:{}", opts.bind, opts.port)
    } else {
        format!("{}:{}", opts.bind, opts.port)
    };
    truepos_ippdme::Server::bind(&address, IppdmeCmm::new(&config, part), &config, log)
        .map(|s| s.with_write_timeout(opts.write_timeout))
        .map_err(|source| ServeError::Bind { address, source })
}

/// The virtual CMM served for one client program on an ephemeral loopback port, homed as an
/// operator would before the program runs (`truepos dmis run --controller virtual`). The server
/// stops when the handle is dropped.
pub struct LoopbackCmm {
    /// The running server.
    pub handle: truepos_ippdme::server::ServerHandle<IppdmeCmm>,
    /// `ippdme://127.0.0.1:PORT`.
    pub url: String,
}

/// Build the virtual CMM from the files (as `truepos ippdme serve`), serve it on
/// `127.0.0.1:0` and home it.
pub fn serve_loopback(
    part: Option<&std::path::Path>,
    machine: Option<&std::path::Path>,
) -> Result<LoopbackCmm, ServeError> {
    let opts = ServeOptions {
        bind: "127.0.0.1".into(),
        port: 0,
        part: part.map(|p| p.to_path_buf()),
        machine: machine.map(|p| p.to_path_buf()),
        log: None,
        write_timeout: truepos_ippdme::server::DEFAULT_WRITE_TIMEOUT,
    };
    let server = bind_virtual(&opts)?;
    let address = "127.0.0.1:0".to_string();
    let mut session = truepos_ippdme::server::Session::new(server.shared());
    let mut out = Vec::new();
    for line in ["00001 StartSession()", "00002 Home()", "00003 EndSession()"] {
        let _ = session.handle_line(line.as_bytes(), &mut out);
    }
    if let Some(bad) = out.iter().map(|r| r.format()).find(|l| l.contains(" ! ")) {
        return Err(ServeError::Bind {
            address,
            source: std::io::Error::other(format!("homing refused: {bad}")),
        });
    }
    let handle = server.spawn().map_err(|source| ServeError::Bind { address: address.clone(), source })?;
    let url = format!("ippdme://{}", handle.addr);
    Ok(LoopbackCmm { handle, url })
}

impl truepos_math::exit::HasExitClass for ServeError {
    /// A bad part, machine or log file is the user's (2); an address that cannot be bound is not (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        match self {
            ServeError::Input(_) | ServeError::File(_) | ServeError::Log { .. } => ExitClass::Input,
            ServeError::Bind { .. } => ExitClass::Device,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scans_are_bounded_in_points_and_machine_time() {
        let part = Part::from_toml("p", "[[plane]]\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n").unwrap();
        let mut m = IppdmeCmm::new(&MachineConfig::default(), Some(part));
        let start = Contact { tip_center_mm: Point3::new(800.0, 0.0, 1.5), normal: Vector3::z() };
        let mut out = Vec::new();
        // Two turns of a 1.6 m circle: 10 km at 20 mm/s.
        let long = ScanPath::Circle {
            center: Point3::origin(),
            axis: Vector3::z(),
            delta_rad: 4.0 * std::f64::consts::PI,
            step_rad: 0.01,
        };
        let e = m.scan(start, &long, 1.5, &mut out).unwrap_err();
        assert!(e.to_string().contains("machine time"), "{e}");
        let fine = ScanPath::Line { direction: Vector3::x(), length_mm: 10.0, step_mm: 1e-9 };
        let e = m.scan(start, &fine, 1.5, &mut out).unwrap_err();
        assert!(e.to_string().contains("points per scan"), "{e}");
        assert!(out.is_empty());
        // Within the bounds: a 10 mm line in 1 mm steps on the plane, 11 points at z ≈ r.
        let ok = ScanPath::Line { direction: Vector3::x(), length_mm: 10.0, step_mm: 1.0 };
        m.scan(start, &ok, 1.5, &mut out).unwrap();
        assert_eq!(out.len(), 11);
        // The realistic machine: within 10 µm of the true plane (geometric map and noise).
        assert!(out.iter().all(|p| (p.tip_center_mm.z - 1.5).abs() < 10e-3), "{out:?}");
    }

    /// The ideal machine on `part`: exact contacts.
    fn ideal(part: &str) -> IppdmeCmm {
        IppdmeCmm::new(&MachineConfig::ideal(), Some(Part::from_toml("p", part).unwrap()))
    }

    const BLOCK: &str = "[[block]]\nmin_mm = [0, 0, 0]\nmax_mm = [100, 60, 40]\n";

    /// Contacts on a block's faces, edges and corners, computed by hand: a face gives the
    /// face's normal at r from it; an edge is not a face (the ball touches the edge, its normal
    /// from the edge to the ball's centre); beside the block the probe misses.
    #[test]
    fn a_block_is_touched_on_its_faces_and_edges_only() {
        let m = ideal(BLOCK);
        let r = 1.5;
        // Top face, straight down.
        let (t, n) =
            m.first_contact(&Point3::new(50.0, 30.0, 50.0), &Point3::new(50.0, 30.0, 30.0), r).unwrap();
        assert!((50.0 - 20.0 * t - (40.0 + r)).abs() < 1e-9 && (n - Vector3::z()).norm() < 1e-12, "{t} {n}");
        // Down 1 mm outside the edge x = 100: the ball meets the edge at height
        // 40 + sqrt(r² − 1²), normal (1, 0, h)/r.
        let (t, n) =
            m.first_contact(&Point3::new(101.0, 30.0, 50.0), &Point3::new(101.0, 30.0, 30.0), r).unwrap();
        let h = (r * r - 1.0f64).sqrt();
        assert!((50.0 - 20.0 * t - (40.0 + h)).abs() < 1e-9, "{t}");
        assert!((n - Vector3::new(1.0, 0.0, h) / r).norm() < 1e-9, "{n}");
        // Down 2 mm outside: misses (a half-space top face would have been touched).
        assert!(m
            .first_contact(&Point3::new(102.0, 30.0, 50.0), &Point3::new(102.0, 30.0, 30.0), r)
            .is_none());
        // Along −x at z = 41 towards the corner edge (x = 100, z = 40): touches the edge.
        let (t, n) =
            m.first_contact(&Point3::new(110.0, 30.0, 41.0), &Point3::new(90.0, 30.0, 41.0), r).unwrap();
        let x = 110.0 - 20.0 * t;
        assert!((x - (100.0 + (r * r - 1.0f64).sqrt())).abs() < 1e-9, "{x}");
        assert!(n.x > 0.0 && n.z > 0.0 && (n.norm() - 1.0).abs() < 1e-12, "{n}");
        // Side face x = 0 from outside.
        let (t, n) =
            m.first_contact(&Point3::new(-10.0, 30.0, 20.0), &Point3::new(10.0, 30.0, 20.0), r).unwrap();
        assert!((-10.0 + 20.0 * t + r).abs() < 1e-9 && (n + Vector3::x()).norm() < 1e-12, "{t} {n}");
        // Inside the block's volume there is no free space to start from.
        assert!(m.collides(&Point3::new(50.0, 30.0, 20.0), r));
        assert!(!m.collides(&Point3::new(50.0, 30.0, 41.6), r));
    }

    /// A finite pin: touched on its side and on its end face; a probe passing beside it above
    /// its end misses it (an infinite pin would stop it).
    #[test]
    fn a_finite_pin_has_an_end_face_and_can_be_passed() {
        let pin = "[[cylinder]]\npoint_mm = [0, 0, 0]\naxis = [0, 0, 1]\ndiameter_mm = 10\nside = \"outside\"\nends_mm = [0, 20]\n";
        let infinite =
            "[[cylinder]]\npoint_mm = [0, 0, 0]\naxis = [0, 0, 1]\ndiameter_mm = 10\nside = \"outside\"\n";
        let (m, inf) = (ideal(pin), ideal(infinite));
        let r = 1.5;
        let (a, b) = (Point3::new(-20.0, 0.0, 22.0), Point3::new(20.0, 0.0, 22.0));
        assert!(m.first_contact(&a, &b, r).is_none(), "above the end at 22 > 20 + r: no contact");
        assert!(inf.first_contact(&a, &b, r).is_some());
        // Side at z = 10.
        let (t, n) =
            m.first_contact(&Point3::new(-20.0, 0.0, 10.0), &Point3::new(0.0, 0.0, 10.0), r).unwrap();
        assert!((-20.0 + 20.0 * t + 5.0 + r).abs() < 1e-9 && (n + Vector3::x()).norm() < 1e-9, "{t} {n}");
        // End face from above, 2 mm off the axis.
        let (t, n) = m.first_contact(&Point3::new(2.0, 0.0, 30.0), &Point3::new(2.0, 0.0, 10.0), r).unwrap();
        assert!((30.0 - 20.0 * t - (20.0 + r)).abs() < 1e-9 && (n - Vector3::z()).norm() < 1e-12, "{t} {n}");
    }

    /// A blind bore in a block: its wall and its floor are touched where they are; below the
    /// floor there is material, beside the bore the block's top.
    #[test]
    fn a_blind_bore_has_a_wall_and_a_floor() {
        let part = format!(
            "{BLOCK}[[cylinder]]\npoint_mm = [50, 30, 0]\naxis = [0, 0, 1]\ndiameter_mm = 16\nside = \"inside\"\nends_mm = [15, 60]\n"
        );
        let m = ideal(&part);
        let r = 1.5;
        // Floor, 3 mm off the axis.
        let (t, n) =
            m.first_contact(&Point3::new(53.0, 30.0, 30.0), &Point3::new(53.0, 30.0, 10.0), r).unwrap();
        assert!((30.0 - 20.0 * t - (15.0 + r)).abs() < 1e-9 && (n - Vector3::z()).norm() < 1e-12, "{t} {n}");
        // Wall at z = 25, towards +x.
        let (t, n) =
            m.first_contact(&Point3::new(50.0, 30.0, 25.0), &Point3::new(60.0, 30.0, 25.0), r).unwrap();
        assert!((50.0 + 10.0 * t - (58.0 - r)).abs() < 1e-9 && (n + Vector3::x()).norm() < 1e-9, "{t} {n}");
        // Down beside the bore: the block's top.
        let (t, _) =
            m.first_contact(&Point3::new(70.0, 30.0, 50.0), &Point3::new(70.0, 30.0, 30.0), r).unwrap();
        assert!((50.0 - 20.0 * t - (40.0 + r)).abs() < 1e-9, "{t}");
    }

    /// A triangular prism: its sloped side is a face with the normal of the hand computation.
    #[test]
    fn a_prism_has_its_faces() {
        let m = ideal("[[prism]]\nvertices_mm = [[0, 0, 0], [40, 0, 0], [0, 30, 0]]\nheight_mm = 10\n");
        let r = 1.0;
        // The hypotenuse from (40, 0) to (0, 30): outward normal (3, 4)/5; probe along −normal
        // through the edge's midpoint (20, 15) at z = 5.
        let nrm = Vector3::new(0.6, 0.8, 0.0);
        let mid = Point3::new(20.0, 15.0, 5.0);
        let (t, n) = m.first_contact(&(mid + nrm * 10.0), &(mid - nrm * 5.0), r).unwrap();
        assert!((10.0 - 15.0 * t - r).abs() < 1e-9 && (n - nrm).norm() < 1e-9, "{t} {n}");
        // The end face z = 10 and the base z = 0.
        let (t, n) = m.first_contact(&Point3::new(5.0, 5.0, 20.0), &Point3::new(5.0, 5.0, 5.0), r).unwrap();
        assert!((20.0 - 15.0 * t - 11.0).abs() < 1e-9 && (n - Vector3::z()).norm() < 1e-12, "{t} {n}");
        let (_, n) = m.first_contact(&Point3::new(5.0, 5.0, -10.0), &Point3::new(5.0, 5.0, 5.0), r).unwrap();
        assert!((n + Vector3::z()).norm() < 1e-12, "{n}");
    }
}
