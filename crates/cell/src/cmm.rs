//! The virtual CMM behind `truepos ippdme serve`: a bridge CMM with instant moves, a spherical
//! stylus and a part made of exact solids (the part file of `truepos-ippdme`: union of spheres,
//! half-spaces, pins and bores).
//!
//! Contacts are exact: a probing move of the ball centre along a segment latches the first
//! parameter at which the ball touches any solid (the ball-centre surface is the part's surface
//! offset by the tip radius, which for a union is the union of the offset solids), and the normal
//! there. Without a part, every probing touches the ideal plane through the nominal point, normal
//! to the probing direction (contract). Positioning moves that would touch the part stop at the
//! touch and fail (`MachineError::IllegalTouch`).
//!
//! Scanning follows the path of the I++ DME scan commands in contact: each point is probed
//! exactly on the actual surface along the nominal normal of the path at that point (the circle's
//! cone shell rotated about its axis, or the line's plane), so a scan of a true circle returns
//! points on it to floating-point precision. Moves are instant (contract), so the dynamic
//! execution of `truepos-scan` (servo, stylus dynamics, blended stop-free paths in time) is not
//! involved here; the geometric result is the same for an ideal machine.
//!
//! Entry point: [`IppdmeCmm::new`]; it implements [`truepos_ippdme::Cmm`].

use truepos_ippdme::part::{CylinderSide, Part, Solid};
use truepos_ippdme::{Cmm, Contact, Guide, MachineConfig, MachineError, ScanPath, ScanPoint, Stop};
use truepos_math::{Point3, Vector3};

/// Contacts closer than this (mm) to the start of a move count as "already touching".
const TOUCH_EPS: f64 = 1e-9;

/// The virtual CMM.
#[derive(Debug, Clone)]
pub struct IppdmeCmm {
    part: Option<Part>,
    volume: (Point3, Point3),
    position: Point3,
    /// Number of probing moves, positioning moves and scan points so far (for tests).
    pub counters: Counters,
}

/// What the machine did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    pub moves: u64,
    pub probes: u64,
    pub scan_points: u64,
    pub stops: u64,
}

impl IppdmeCmm {
    /// A machine with the volume of `config` and optionally a part. It starts un-homed at its
    /// home position.
    pub fn new(config: &MachineConfig, part: Option<Part>) -> IppdmeCmm {
        let (lo, hi) = (config.volume_min_mm, config.volume_max_mm);
        IppdmeCmm { part, volume: (lo, hi), position: home_of(lo, hi), counters: Counters::default() }
    }

    pub fn part(&self) -> Option<&Part> {
        self.part.as_ref()
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

/// The home position: centred in X and Y, a tenth of the Z travel below its top.
fn home_of(lo: Point3, hi: Point3) -> Point3 {
    Point3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z - 0.1 * (hi.z - lo.z))
}

/// Signed gap of a ball of radius `r` at `c` to one solid's surface (negative: overlapping; for
/// a bore: negative when strictly inside its free cylinder, i.e. clear of its wall).
fn gap(s: &Solid, c: &Point3, r: f64) -> f64 {
    match s {
        Solid::Sphere { center, radius } => (c - center).norm() - radius - r,
        Solid::HalfSpace { point, normal } => (c - point).dot(normal) - r,
        Solid::Cylinder { point, axis, radius, side } => {
            let rel = c - point;
            let dist = (rel - axis * rel.dot(axis)).norm();
            match side {
                CylinderSide::Outside => dist - radius - r,
                CylinderSide::Inside => dist - (radius - r),
            }
        }
    }
}

/// The material's outward normal of one solid at (the projection of) `c`.
fn outward(s: &Solid, c: &Point3) -> Vector3 {
    match s {
        Solid::Sphere { center, .. } => (c - center).try_normalize(1e-15).unwrap_or_else(Vector3::z),
        Solid::HalfSpace { normal, .. } => *normal,
        Solid::Cylinder { point, axis, side, .. } => {
            let rel = c - point;
            let radial =
                (rel - axis * rel.dot(axis)).try_normalize(1e-15).unwrap_or_else(|| perpendicular(axis));
            match side {
                CylinderSide::Outside => radial,
                CylinderSide::Inside => -radial,
            }
        }
    }
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
        Solid::Cylinder { point, axis, radius, side } => {
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

fn rotate(v: &Vector3, axis: &Vector3, angle: f64) -> Vector3 {
    let (s, c) = angle.sin_cos();
    v * c + axis.cross(v) * s + axis * axis.dot(v) * (1.0 - c)
}

impl Cmm for IppdmeCmm {
    fn describe(&self) -> String {
        let solids = self.part.as_ref().map(|p| p.solids.len()).unwrap_or(0);
        format!("truepos virtual CMM (exact contacts, instant moves, {solids} part solids)")
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
        if let Some((t, n)) = self.first_contact(&self.position, &target_mm, tip_radius_mm) {
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
        let c = match &self.part {
            Some(_) => self.probe_exact(&from_mm, &to_mm, tip_radius_mm),
            None => {
                // The ideal plane through the nominal point, normal to the probing direction:
                // the ball centre touches it where the move reaches the plane offset by r
                // (nominal + r·n when the move runs along the normal).
                let n = nominal_normal
                    .try_normalize(1e-15)
                    .ok_or_else(|| MachineError::Unable("zero probing direction".into()))?;
                // The segment meets the plane offset by r at fraction t.
                let touch = nominal_mm + n * tip_radius_mm;
                let d = to_mm - from_mm;
                let dn = d.dot(&n);
                let t = if dn.abs() > 1e-300 { (touch - from_mm).dot(&n) / dn } else { f64::NAN };
                (0.0..=1.0).contains(&t).then(|| Contact { tip_center_mm: from_mm + d * t, normal: n })
            }
        };
        self.position = c.map(|c| c.tip_center_mm).unwrap_or(to_mm);
        Ok(c)
    }

    fn scan(
        &mut self,
        start: Contact,
        path: &ScanPath,
        tip_radius_mm: f64,
        out: &mut Vec<ScanPoint>,
    ) -> Result<(), MachineError> {
        let window = 2.0 + tip_radius_mm;
        let mut push = |me: &mut Self, q: Point3, n: Vector3| -> bool {
            let c = if me.part.is_none() {
                Some(Contact { tip_center_mm: q, normal: n })
            } else {
                me.probe_exact(&(q + n * window), &(q - n * window), tip_radius_mm)
            };
            match c {
                Some(c) => {
                    me.position = c.tip_center_mm;
                    me.counters.scan_points += 1;
                    out.push(ScanPoint { tip_center_mm: c.tip_center_mm, normal: c.normal, quality: 0.0 });
                    true
                }
                None => false,
            }
        };
        match *path {
            ScanPath::Circle { center, axis, delta_rad, step_rad } => {
                let axis =
                    axis.try_normalize(1e-15).ok_or_else(|| MachineError::Unable("zero scan axis".into()))?;
                let n_steps = ((delta_rad.abs() / step_rad.max(1e-9)).round() as usize).max(1);
                let arm = start.tip_center_mm - center;
                for k in 0..=n_steps {
                    let ang = delta_rad * k as f64 / n_steps as f64;
                    let q = center + rotate(&arm, &axis, ang);
                    let n = rotate(&start.normal, &axis, ang);
                    if !push(self, q, n) {
                        break;
                    }
                }
            }
            ScanPath::Contour { guide, toward, step_mm, stop, max_length_mm } => {
                return self.follow(
                    start,
                    &guide,
                    &toward,
                    step_mm,
                    &stop,
                    max_length_mm,
                    tip_radius_mm,
                    out,
                );
            }
            ScanPath::Line { direction, length_mm, step_mm } => {
                let n_steps = ((length_mm / step_mm.max(1e-9)).round() as usize).max(1);
                for k in 0..=n_steps {
                    let q = start.tip_center_mm + direction * (length_mm * k as f64 / n_steps as f64);
                    if !push(self, q, start.normal) {
                        break;
                    }
                }
            }
        }
        Ok(())
    }

    fn stop(&mut self) {
        self.counters.stops += 1;
    }
}

/// Options of `truepos ippdme serve`.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    pub bind: String,
    pub port: u16,
    pub part: Option<std::path::PathBuf>,
    pub machine: Option<std::path::PathBuf>,
    pub log: Option<std::path::PathBuf>,
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A bad part or machine file (exit 2).
    #[error(transparent)]
    Input(#[from] truepos_ippdme::PartError),
    /// The log file cannot be opened (exit 2).
    #[error("{path}: cannot open the log: {source}")]
    Log {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The address cannot be bound, e.g. the port is in use (exit 3).
    #[error("cannot listen on {address}: {source}")]
    Bind {
        address: String,
        #[source]
        source: std::io::Error,
    },
}

/// Build the virtual CMM from the files and bind the I++ DME server (not yet accepting).
pub fn bind_virtual(opts: &ServeOptions) -> Result<truepos_ippdme::Server<IppdmeCmm>, ServeError> {
    let config = match &opts.machine {
        Some(p) => MachineConfig::load(p)?,
        None => MachineConfig::default(),
    };
    let part = opts.part.as_deref().map(Part::load).transpose()?;
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
        .map_err(|source| ServeError::Bind { address, source })
}
