//! The part file of `truepos ippdme serve --part PART.toml` and the machine file's `[ippdme]`
//! section: typed, unknown keys refused, errors naming file, line and key.
//!
//! Part file (machine frame, mm): the material is the union of
//! `[[sphere]] center_mm, diameter_mm`, `[[plane]] point_mm, normal` (the half-space below the
//! normal) and `[[cylinder]] point_mm, axis, diameter_mm, side = "outside"` (a pin), minus the
//! `[[cylinder]] ... side = "inside"` (bores, which remove material: a bore in a plate is a
//! `[[plane]]` and an inside `[[cylinder]]`); each with an optional `id`.
//!
//! Bounded solids (a real test part):
//! - `[[block]] min_mm, max_mm`: a rectangular block, the intersection of the six half-spaces of
//!   its faces (file axes);
//! - `[[prism]] vertices_mm, height_mm`: a convex polygon (at least three vertices in one
//!   plane, in order) extruded along its plane's normal (the side of the vertices' right-hand
//!   order) by `height_mm`: the intersection of its side and end half-spaces;
//! - `[[cylinder]] ... ends_mm = [a, b]`: a finite cylinder between the planes normal to its
//!   axis at `a` and `b` along it from `point_mm` (a < b). A finite pin has end faces; a finite
//!   bore removes the material between them, so its end at `a` is the bore's floor (its other
//!   end should lie beyond the face it opens through). Without `ends_mm` cylinders are infinite
//!   (the files of earlier versions).
//!
//! Edges and corners of bounded solids are sharp: a probe passing beside a finite pin misses
//! it, and a ball touching an edge touches it at the edge (normal from the edge to the ball's
//! centre), not on an extended face.
//!
//! Machine file: `[ippdme] volume_min_mm, volume_max_mm` (default ±1000 mm),
//! `[[ippdme.tool]] name, tip_diameter_mm`, `rotary_table` (default true: a table turning about
//! machine Z through `rotary_table_centre_mm`, default the origin), and `[ippdme.model]`, the error models of the virtual
//! CMM ([`ModelConfig`]; every key optional, the defaults are a realistic bridge CMM with a
//! touch-trigger probe). Other top-level tables are left to other readers.
//!
//! Entry points: [`Part::from_toml`], [`Part::load`], [`MachineConfig::from_toml`],
//! [`MachineConfig::load`].

use serde::Deserialize;
use std::path::Path;
use thiserror::Error;
use truepos_math::{Point3, Vector3};

/// A bad part or machine file.
#[derive(Debug, Error)]
pub enum PartError {
    /// The file cannot be read.
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The file, as named in the message.
        file: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML (file, 1-based line and column, message).
    #[error("{file}:{line}:{column}: {message}")]
    Syntax {
        /// The file, as named in the message.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A key has an unusable value (file, key, message).
    #[error("{file}: {key}: {message}")]
    Value {
        /// The file, as named in the message.
        file: String,
        /// The key.
        key: String,
        /// What is wrong with its value.
        message: String,
    },
}

impl PartError {
    /// The 1-based line of the error, when known.
    pub fn line(&self) -> Option<usize> {
        match self {
            PartError::Syntax { line, .. } => Some(*line),
            _ => None,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPart {
    #[serde(default)]
    sphere: Vec<RawSphere>,
    #[serde(default)]
    plane: Vec<RawPlane>,
    #[serde(default)]
    cylinder: Vec<RawCylinder>,
    #[serde(default)]
    block: Vec<RawBlock>,
    #[serde(default)]
    prism: Vec<RawPrism>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBlock {
    id: Option<String>,
    min_mm: [f64; 3],
    max_mm: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPrism {
    id: Option<String>,
    vertices_mm: Vec<[f64; 3]>,
    height_mm: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSphere {
    id: Option<String>,
    center_mm: [f64; 3],
    diameter_mm: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlane {
    id: Option<String>,
    point_mm: [f64; 3],
    normal: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCylinder {
    id: Option<String>,
    point_mm: [f64; 3],
    axis: [f64; 3],
    diameter_mm: f64,
    side: CylinderSide,
    ends_mm: Option<[f64; 2]>,
}

/// A cylinder is a pin (material inside) or a bore (material outside).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CylinderSide {
    /// A pin: material inside the cylinder.
    Outside,
    /// A bore: the cylinder removes material from the other solids.
    Inside,
}

/// One solid of the part.
#[derive(Debug, Clone, PartialEq)]
pub enum Solid {
    /// A solid sphere.
    Sphere {
        /// Centre, part frame, mm.
        center: Point3,
        /// Radius, mm.
        radius: f64,
    },
    /// Material where `(p − point)·normal ≤ 0`; `normal` is a unit vector.
    HalfSpace {
        /// A point on the bounding plane, part frame, mm.
        point: Point3,
        /// Unit normal of the plane, out of the material.
        normal: Vector3,
    },
    /// Cylinder; `axis` is a unit vector. `Outside`: a pin (material inside the cylinder);
    /// `Inside`: a bore (removes the material inside it from the other solids). `ends`: the
    /// positions along the axis from `point` of its end planes (`None`: infinite).
    Cylinder {
        /// A point on the axis, part frame, mm.
        point: Point3,
        /// Unit axis direction.
        axis: Vector3,
        /// Radius, mm.
        radius: f64,
        /// Pin or bore.
        side: CylinderSide,
        /// Axial extent `(a, b)` from `point` along `axis` (mm): a finite pin, or a bore with
        /// its floor at `a`; `None` for an infinite cylinder.
        ends: Option<(f64, f64)>,
    },
    /// A convex prism: the polygon `polygon` (counter-clockwise in the `(u, v)` plane through
    /// `origin`) extruded along `w = u × v` from 0 to `height`. `u`, `v`, `w` orthonormal.
    /// A block is a prism with a rectangle.
    Prism {
        /// The polygon plane's origin, part/machine frame (mm).
        origin: Point3,
        /// First in-plane axis (unit).
        u: Vector3,
        /// Second in-plane axis (unit).
        v: Vector3,
        /// Extrusion direction, `u × v` (unit).
        w: Vector3,
        /// The convex polygon's corners `(u, v)` (mm), counter-clockwise.
        polygon: Vec<[f64; 2]>,
        /// Extrusion length along `w` (mm).
        height: f64,
    },
}

impl Solid {
    /// Signed distance of `p` to the solid (negative inside; for a bore, of `p` to the free
    /// cylinder it cuts, negative inside it). Exact for every kind (edges and corners
    /// included), so that a ball of radius r at `c` overlaps the solid exactly when
    /// `distance(c) < r`.
    pub fn distance(&self, p: &Point3) -> f64 {
        match self {
            Solid::Sphere { center, radius } => (p - center).norm() - radius,
            Solid::HalfSpace { point, normal } => (p - point).dot(normal),
            Solid::Cylinder { point, axis, radius, ends, .. } => {
                let rel = p - point;
                let along = rel.dot(axis);
                let radial = (rel - axis * along).norm() - radius;
                match ends {
                    None => radial,
                    Some((a, b)) => {
                        let axial = (a - along).max(along - b);
                        extrude(radial, axial)
                    }
                }
            }
            Solid::Prism { origin, u, v, w, polygon, height } => {
                let rel = p - origin;
                let q = [rel.dot(u), rel.dot(v)];
                let h = rel.dot(w);
                extrude(polygon_distance(polygon, q), (-h).max(h - height))
            }
        }
    }

    /// The outward normal of the solid's surface nearest `p` (for a bore: pointing into the
    /// free cylinder, the material's outward normal): at an edge or corner the direction from
    /// it to `p`.
    pub fn outward(&self, p: &Point3) -> Vector3 {
        match self {
            Solid::Sphere { center, .. } => (p - center).try_normalize(1e-15).unwrap_or_else(Vector3::z),
            Solid::HalfSpace { normal, .. } => *normal,
            Solid::Cylinder { point, axis, radius, side, ends } => {
                let rel = p - point;
                let along = rel.dot(axis);
                let radial_v = rel - axis * along;
                let radial_dir = radial_v.try_normalize(1e-15).unwrap_or_else(|| any_perpendicular(axis));
                let rd = radial_v.norm() - radius;
                let (n_side, n_end, axial) = match ends {
                    None => (radial_dir, Vector3::zeros(), f64::NEG_INFINITY),
                    Some((a, b)) => {
                        let (axial, n_end) =
                            if a - along > along - b { (a - along, -axis) } else { (along - b, *axis) };
                        (radial_dir, n_end, axial)
                    }
                };
                let n = match side {
                    CylinderSide::Outside if rd > 0.0 && axial > 0.0 => {
                        (radial_dir * rd + n_end * axial).normalize()
                    }
                    _ if axial > rd => n_end,
                    _ => n_side,
                };
                match side {
                    CylinderSide::Outside => n,
                    CylinderSide::Inside => -n,
                }
            }
            Solid::Prism { origin, u, v, w, polygon, height } => {
                let rel = p - origin;
                let q = [rel.dot(u), rel.dot(v)];
                let h = rel.dot(w);
                let (d2, g2) = polygon_gradient(polygon, q);
                let (axial, n_end) = if -h > h - height { (-h, -w) } else { (h - height, *w) };
                let n_side = u * g2[0] + v * g2[1];
                if d2 > 0.0 && axial > 0.0 {
                    (n_side * d2 + n_end * axial).normalize()
                } else if axial > d2 {
                    n_end
                } else {
                    n_side
                }
            }
        }
    }
}

/// The exact signed distance of an extrusion from the signed distances across (`d`) and along
/// (`a`) it.
fn extrude(d: f64, a: f64) -> f64 {
    if d > 0.0 && a > 0.0 {
        d.hypot(a)
    } else {
        d.max(a)
    }
}

/// A unit vector perpendicular to `n` (unit).
fn any_perpendicular(n: &Vector3) -> Vector3 {
    let a = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    n.cross(&a).normalize()
}

/// Signed distance of `q` to a convex polygon (counter-clockwise): negative inside.
fn polygon_distance(poly: &[[f64; 2]], q: [f64; 2]) -> f64 {
    polygon_gradient(poly, q).0
}

/// Signed distance of `q` to a convex polygon (counter-clockwise) and the unit direction of
/// its increase (outside: from the nearest boundary point to `q`; inside: the nearest edge's
/// outward normal).
fn polygon_gradient(poly: &[[f64; 2]], q: [f64; 2]) -> (f64, [f64; 2]) {
    let n = poly.len();
    let mut inside = true;
    let mut best_in = (f64::NEG_INFINITY, [0.0, 1.0]);
    let mut best_out = (f64::INFINITY, [0.0, 1.0]);
    for k in 0..n {
        let (a, b) = (poly[k], poly[(k + 1) % n]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let len = e[0].hypot(e[1]);
        let out_n = [e[1] / len, -e[0] / len];
        let rel = [q[0] - a[0], q[1] - a[1]];
        let side = rel[0] * out_n[0] + rel[1] * out_n[1];
        if side > 0.0 {
            inside = false;
        }
        if side > best_in.0 {
            best_in = (side, out_n);
        }
        // Distance to the segment.
        let t = ((rel[0] * e[0] + rel[1] * e[1]) / (len * len)).clamp(0.0, 1.0);
        let d = [rel[0] - t * e[0], rel[1] - t * e[1]];
        let dist = d[0].hypot(d[1]);
        if dist < best_out.0 {
            let dir = if dist > 1e-15 { [d[0] / dist, d[1] / dist] } else { out_n };
            best_out = (dist, dir);
        }
    }
    if inside {
        best_in
    } else {
        best_out
    }
}

/// The part: the union of its spheres, half-spaces and pins, minus its bores.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Part {
    /// The solids with their optional ids, in file order.
    pub solids: Vec<(Option<String>, Solid)>,
}

fn syntax(file: &str, text: &str, e: &toml::de::Error) -> PartError {
    let (line, column) = match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map(|k| k + 1).unwrap_or(0) + 1;
            (line, column)
        }
        None => (0, 0),
    };
    PartError::Syntax { file: file.to_string(), line, column, message: e.message().to_string() }
}

fn finite3(file: &str, key: &str, v: [f64; 3]) -> Result<Vector3, PartError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vector3::new(v[0], v[1], v[2]))
    } else {
        Err(PartError::Value { file: file.into(), key: key.into(), message: "not a finite number".into() })
    }
}

fn unit(file: &str, key: &str, v: [f64; 3]) -> Result<Vector3, PartError> {
    let v = finite3(file, key, v)?;
    let n = v.norm();
    if n < 1e-12 {
        return Err(PartError::Value {
            file: file.into(),
            key: key.into(),
            message: "zero-length vector".into(),
        });
    }
    Ok(v / n)
}

fn positive(file: &str, key: &str, v: f64) -> Result<f64, PartError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(PartError::Value {
            file: file.into(),
            key: key.into(),
            message: format!("must be a positive number, got {v}"),
        })
    }
}

/// A prism from its base polygon's vertices (in order, one plane, convex) and its height along
/// the normal of their right-hand order.
fn prism(file: &str, key: &str, vertices: &[[f64; 3]], height: f64) -> Result<Solid, PartError> {
    let bad =
        |message: String| PartError::Value { file: file.into(), key: format!("{key}.vertices_mm"), message };
    if vertices.len() < 3 {
        return Err(bad(format!("a polygon needs at least 3 vertices, got {}", vertices.len())));
    }
    let mut pts = Vec::with_capacity(vertices.len());
    for v in vertices {
        pts.push(Point3::from(finite3(file, &format!("{key}.vertices_mm"), *v)?));
    }
    // Newell's normal: the polygon's plane and orientation.
    let mut nn = Vector3::zeros();
    for k in 0..pts.len() {
        let (a, b) = (pts[k], pts[(k + 1) % pts.len()]);
        nn += Vector3::new((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    let Some(w) = nn.try_normalize(1e-12) else {
        return Err(bad("the vertices enclose no area".into()));
    };
    let origin = pts[0];
    let size = pts.iter().map(|p| (p - origin).norm()).fold(0.0, f64::max);
    if pts.iter().any(|p| (p - origin).dot(&w).abs() > 1e-9 * size.max(1.0)) {
        return Err(bad("the vertices are not in one plane".into()));
    }
    let u = (pts[1] - origin).try_normalize(1e-12).ok_or_else(|| bad("two vertices coincide".into()))?;
    let v = w.cross(&u);
    let polygon: Vec<[f64; 2]> = pts.iter().map(|p| [(p - origin).dot(&u), (p - origin).dot(&v)]).collect();
    let n = polygon.len();
    for k in 0..n {
        let (a, b, c) = (polygon[k], polygon[(k + 1) % n], polygon[(k + 2) % n]);
        let cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
        let l1 = (b[0] - a[0]).hypot(b[1] - a[1]);
        let l2 = (c[0] - b[0]).hypot(c[1] - b[1]);
        if l1 < 1e-9 || l2 < 1e-9 || cross <= 1e-12 * l1 * l2 {
            return Err(bad(format!(
                "the polygon is not convex with distinct vertices (at vertex {})",
                (k + 1) % n + 1
            )));
        }
    }
    Ok(Solid::Prism { origin, u, v, w, polygon, height })
}

impl Part {
    /// Parse a part file's text; `file` names it in errors.
    pub fn from_toml(file: &str, text: &str) -> Result<Part, PartError> {
        let raw: RawPart = toml::from_str(text).map_err(|e| syntax(file, text, &e))?;
        let mut solids = Vec::new();
        for (k, s) in raw.sphere.into_iter().enumerate() {
            let key = format!("sphere[{k}]");
            let c = finite3(file, &format!("{key}.center_mm"), s.center_mm)?;
            let d = positive(file, &format!("{key}.diameter_mm"), s.diameter_mm)?;
            solids.push((s.id, Solid::Sphere { center: Point3::from(c), radius: d / 2.0 }));
        }
        for (k, s) in raw.plane.into_iter().enumerate() {
            let key = format!("plane[{k}]");
            let p = finite3(file, &format!("{key}.point_mm"), s.point_mm)?;
            let n = unit(file, &format!("{key}.normal"), s.normal)?;
            solids.push((s.id, Solid::HalfSpace { point: Point3::from(p), normal: n }));
        }
        for (k, s) in raw.cylinder.into_iter().enumerate() {
            let key = format!("cylinder[{k}]");
            let p = finite3(file, &format!("{key}.point_mm"), s.point_mm)?;
            let a = unit(file, &format!("{key}.axis"), s.axis)?;
            let d = positive(file, &format!("{key}.diameter_mm"), s.diameter_mm)?;
            let ends = match s.ends_mm {
                None => None,
                Some([lo, hi]) if lo.is_finite() && hi.is_finite() && lo < hi => Some((lo, hi)),
                Some(_) => {
                    return Err(PartError::Value {
                        file: file.into(),
                        key: format!("{key}.ends_mm"),
                        message: "must be two finite positions along the axis, the first below the second"
                            .into(),
                    })
                }
            };
            solids.push((
                s.id,
                Solid::Cylinder { point: Point3::from(p), axis: a, radius: d / 2.0, side: s.side, ends },
            ));
        }
        for (k, b) in raw.block.into_iter().enumerate() {
            let key = format!("block[{k}]");
            let lo = finite3(file, &format!("{key}.min_mm"), b.min_mm)?;
            let hi = finite3(file, &format!("{key}.max_mm"), b.max_mm)?;
            if (0..3).any(|i| lo[i] >= hi[i]) {
                return Err(PartError::Value {
                    file: file.into(),
                    key: format!("{key}.max_mm"),
                    message: "every component must exceed min_mm's".into(),
                });
            }
            let e = hi - lo;
            solids.push((
                b.id,
                Solid::Prism {
                    origin: Point3::from(lo),
                    u: Vector3::x(),
                    v: Vector3::y(),
                    w: Vector3::z(),
                    polygon: vec![[0.0, 0.0], [e.x, 0.0], [e.x, e.y], [0.0, e.y]],
                    height: e.z,
                },
            ));
        }
        for (k, p) in raw.prism.into_iter().enumerate() {
            let key = format!("prism[{k}]");
            let h = positive(file, &format!("{key}.height_mm"), p.height_mm)?;
            let solid = prism(file, &key, &p.vertices_mm, h)?;
            solids.push((p.id, solid));
        }
        Ok(Part { solids })
    }

    /// Read and parse a part file.
    pub fn load(path: &Path) -> Result<Part, PartError> {
        let file = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| PartError::Read { file: file.clone(), source })?;
        Part::from_toml(&file, &text)
    }
}

/// An extra tool of the machine file.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolConfig {
    /// The tool's name (not one of [`RESERVED_TOOLS`]).
    pub name: String,
    /// Diameter of the tool's tip, mm.
    pub tip_diameter_mm: f64,
}

/// The error models of the virtual CMM behind the server (`[ippdme.model]`), plain numbers: the
/// machine that uses them (`truepos_plant::cmm`) builds the models of `truepos-sim` from them.
///
/// Keys (all optional): `seed` (noise and error map, default 1), `geometric_errors`
/// (`"bridge_cmm"`: a seeded realistic ISO 230-1 map of a bridge CMM stretched over the volume,
/// or `"none"`), `geometric_error_scale` (factor on that map, default 1), `stylus_length_mm`
/// (Abbe arm of the angular errors, default 50), `pretravel_um` (touch-trigger pre-travel including
/// the stylus bending up to the trigger force, default 8; 0 = none), `lobing_um` (its 3-lobe
/// variation, default 0.5), `pretravel_compensated` (the probe calibration removes the mean
/// pre-travel, default true), `probe_noise_um` (σ per axis of a touch, default 0.25),
/// `encoder_noise_um` / `scan_probe_noise_um` (σ of the scale and deflection readings while
/// scanning, default 0.1 / 0.2), `servo_bandwidth_hz` (position loop, default 15),
/// `scan_speed_mm_s` (default 20), `scan_deflection_mm` (target deflection, default 0.3).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelConfig {
    /// Seed of the noise and of the error map.
    pub seed: u64,
    /// Whether the machine has the seeded geometric error map of a bridge CMM.
    pub geometric_errors: bool,
    /// Factor on the geometric error map.
    pub geometric_error_scale: f64,
    /// Abbe arm of the angular errors, mm.
    pub stylus_length_mm: f64,
    /// Touch-trigger pre-travel including the stylus bending, mm.
    pub pretravel_mm: f64,
    /// Amplitude of the pre-travel's 3-lobe variation, mm.
    pub lobing_mm: f64,
    /// Whether the probe calibration removes the mean pre-travel.
    pub pretravel_compensated: bool,
    /// Standard deviation of a touch per axis, mm.
    pub probe_noise_mm: f64,
    /// Standard deviation of the scale readings while scanning, mm.
    pub encoder_noise_mm: f64,
    /// Standard deviation of the deflection readings while scanning, mm.
    pub scan_probe_noise_mm: f64,
    /// Bandwidth of the position loop, Hz.
    pub servo_bandwidth_hz: f64,
    /// Scanning speed, mm/s.
    pub scan_speed_mm_s: f64,
    /// Target probe deflection while scanning, mm.
    pub scan_deflection_mm: f64,
}

impl Default for ModelConfig {
    fn default() -> Self {
        ModelConfig {
            seed: 1,
            geometric_errors: true,
            geometric_error_scale: 1.0,
            stylus_length_mm: 50.0,
            pretravel_mm: 8e-3,
            lobing_mm: 0.5e-3,
            pretravel_compensated: true,
            probe_noise_mm: 0.25e-3,
            encoder_noise_mm: 0.1e-3,
            scan_probe_noise_mm: 0.2e-3,
            servo_bandwidth_hz: 15.0,
            scan_speed_mm_s: 20.0,
            scan_deflection_mm: 0.3,
        }
    }
}

impl ModelConfig {
    /// The ideal machine: no geometric errors, no pre-travel, no noise (scans still run through
    /// the scanning planner with servo and stylus dynamics).
    pub fn ideal() -> ModelConfig {
        ModelConfig {
            geometric_errors: false,
            pretravel_mm: 0.0,
            lobing_mm: 0.0,
            probe_noise_mm: 0.0,
            encoder_noise_mm: 0.0,
            scan_probe_noise_mm: 0.0,
            ..ModelConfig::default()
        }
    }

    /// The realistic machine without any random noise (geometric errors and pre-travel kept).
    pub fn without_noise(mut self) -> ModelConfig {
        self.probe_noise_mm = 0.0;
        self.encoder_noise_mm = 0.0;
        self.scan_probe_noise_mm = 0.0;
        self
    }
}

/// The `[ippdme]` section of the machine file.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineConfig {
    /// Lower corner of the machine's volume, machine frame, mm.
    pub volume_min_mm: Point3,
    /// Upper corner of the machine's volume, machine frame, mm.
    pub volume_max_mm: Point3,
    /// The extra tools of the file.
    pub tools: Vec<ToolConfig>,
    /// The error models of the virtual CMM.
    pub model: ModelConfig,
    /// The rotary table's axis point (axis parallel to machine Z), `None` without a table
    /// (`rotary_table = false`). Default: a table turning about the Z axis through the origin.
    pub rotary_table: Option<Point3>,
}

impl Default for MachineConfig {
    fn default() -> Self {
        MachineConfig {
            volume_min_mm: Point3::new(-1000.0, -1000.0, -1000.0),
            volume_max_mm: Point3::new(1000.0, 1000.0, 1000.0),
            tools: Vec::new(),
            model: ModelConfig::default(),
            rotary_table: Some(Point3::origin()),
        }
    }
}

impl MachineConfig {
    /// The default volume and tools on the ideal machine ([`ModelConfig::ideal`]).
    pub fn ideal() -> MachineConfig {
        MachineConfig { model: ModelConfig::ideal(), ..MachineConfig::default() }
    }
}

#[derive(Debug, Deserialize)]
struct RawMachine {
    ippdme: Option<RawIppdme>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIppdme {
    volume_min_mm: Option<[f64; 3]>,
    volume_max_mm: Option<[f64; 3]>,
    #[serde(default)]
    tool: Vec<RawTool>,
    model: Option<RawModel>,
    rotary_table: Option<bool>,
    rotary_table_centre_mm: Option<[f64; 3]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModel {
    seed: Option<u64>,
    geometric_errors: Option<GeometricKind>,
    geometric_error_scale: Option<f64>,
    stylus_length_mm: Option<f64>,
    pretravel_um: Option<f64>,
    lobing_um: Option<f64>,
    pretravel_compensated: Option<bool>,
    probe_noise_um: Option<f64>,
    encoder_noise_um: Option<f64>,
    scan_probe_noise_um: Option<f64>,
    servo_bandwidth_hz: Option<f64>,
    scan_speed_mm_s: Option<f64>,
    scan_deflection_mm: Option<f64>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum GeometricKind {
    BridgeCmm,
    None,
}

fn nonneg(file: &str, key: &str, v: f64) -> Result<f64, PartError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(PartError::Value {
            file: file.into(),
            key: key.into(),
            message: format!("must be a finite number ≥ 0, got {v}"),
        })
    }
}

impl RawModel {
    fn apply(self, file: &str, m: &mut ModelConfig) -> Result<(), PartError> {
        let k = |n: &str| format!("ippdme.model.{n}");
        if let Some(v) = self.seed {
            m.seed = v;
        }
        if let Some(v) = self.geometric_errors {
            m.geometric_errors = matches!(v, GeometricKind::BridgeCmm);
        }
        if let Some(v) = self.geometric_error_scale {
            m.geometric_error_scale = nonneg(file, &k("geometric_error_scale"), v)?;
        }
        if let Some(v) = self.stylus_length_mm {
            m.stylus_length_mm = nonneg(file, &k("stylus_length_mm"), v)?;
        }
        if let Some(v) = self.pretravel_um {
            m.pretravel_mm = nonneg(file, &k("pretravel_um"), v)? * 1e-3;
        }
        if let Some(v) = self.lobing_um {
            m.lobing_mm = nonneg(file, &k("lobing_um"), v)? * 1e-3;
        }
        if let Some(v) = self.pretravel_compensated {
            m.pretravel_compensated = v;
        }
        if let Some(v) = self.probe_noise_um {
            m.probe_noise_mm = nonneg(file, &k("probe_noise_um"), v)? * 1e-3;
        }
        if let Some(v) = self.encoder_noise_um {
            m.encoder_noise_mm = nonneg(file, &k("encoder_noise_um"), v)? * 1e-3;
        }
        if let Some(v) = self.scan_probe_noise_um {
            m.scan_probe_noise_mm = nonneg(file, &k("scan_probe_noise_um"), v)? * 1e-3;
        }
        if let Some(v) = self.servo_bandwidth_hz {
            m.servo_bandwidth_hz = positive(file, &k("servo_bandwidth_hz"), v)?;
        }
        if let Some(v) = self.scan_speed_mm_s {
            m.scan_speed_mm_s = positive(file, &k("scan_speed_mm_s"), v)?;
        }
        if let Some(v) = self.scan_deflection_mm {
            m.scan_deflection_mm = positive(file, &k("scan_deflection_mm"), v)?;
        }
        if m.pretravel_mm > 0.0 && m.lobing_mm >= m.pretravel_mm || m.pretravel_mm == 0.0 && m.lobing_mm > 0.0
        {
            return Err(PartError::Value {
                file: file.into(),
                key: k("lobing_um"),
                message: "must be smaller than pretravel_um".into(),
            });
        }
        Ok(())
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTool {
    name: String,
    tip_diameter_mm: f64,
}

/// Names the server reserves.
pub const RESERVED_TOOLS: [&str; 5] = ["RefTool", "NoTool", "Probe1", "BaseTool", "UnDefTool"];

impl MachineConfig {
    /// The machine configuration from the text of machine file `file` (named in errors).
    pub fn from_toml(file: &str, text: &str) -> Result<MachineConfig, PartError> {
        let raw: RawMachine = toml::from_str(text).map_err(|e| syntax(file, text, &e))?;
        let mut cfg = MachineConfig::default();
        let Some(ipp) = raw.ippdme else { return Ok(cfg) };
        if let Some(v) = ipp.volume_min_mm {
            cfg.volume_min_mm = Point3::from(finite3(file, "ippdme.volume_min_mm", v)?);
        }
        if let Some(v) = ipp.volume_max_mm {
            cfg.volume_max_mm = Point3::from(finite3(file, "ippdme.volume_max_mm", v)?);
        }
        for k in 0..3 {
            if cfg.volume_min_mm[k] >= cfg.volume_max_mm[k] {
                return Err(PartError::Value {
                    file: file.into(),
                    key: "ippdme.volume_max_mm".into(),
                    message: "every component must exceed volume_min_mm's".into(),
                });
            }
        }
        if let Some(m) = ipp.model {
            m.apply(file, &mut cfg.model)?;
        }
        if let Some(c) = ipp.rotary_table_centre_mm {
            cfg.rotary_table = Some(Point3::from(finite3(file, "ippdme.rotary_table_centre_mm", c)?));
        }
        if ipp.rotary_table == Some(false) {
            cfg.rotary_table = None;
        }
        for (k, t) in ipp.tool.into_iter().enumerate() {
            let key = format!("ippdme.tool[{k}]");
            if t.name.is_empty() || !t.name.bytes().all(|b| b.is_ascii_graphic() && b != b'"') {
                return Err(PartError::Value {
                    file: file.into(),
                    key: format!("{key}.name"),
                    message: "must be printable ASCII without quotes or blanks".into(),
                });
            }
            if RESERVED_TOOLS.contains(&t.name.as_str()) || cfg.tools.iter().any(|x| x.name == t.name) {
                return Err(PartError::Value {
                    file: file.into(),
                    key: format!("{key}.name"),
                    message: format!("{} is reserved or defined twice", t.name),
                });
            }
            let d = positive(file, &format!("{key}.tip_diameter_mm"), t.tip_diameter_mm)?;
            cfg.tools.push(ToolConfig { name: t.name, tip_diameter_mm: d });
        }
        Ok(cfg)
    }

    /// Read the machine configuration from a file.
    pub fn load(path: &Path) -> Result<MachineConfig, PartError> {
        let file = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| PartError::Read { file: file.clone(), source })?;
        MachineConfig::from_toml(&file, &text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_part() {
        let p = Part::from_toml(
            "p.toml",
            "[[sphere]]\nid = \"ref\"\ncenter_mm = [0, 0, 10]\ndiameter_mm = 25\n\n[[plane]]\npoint_mm = [0,0,0]\nnormal = [0,0,2]\n\n[[cylinder]]\npoint_mm=[50,0,0]\naxis=[0,0,1]\ndiameter_mm=10\nside=\"inside\"\n",
        )
        .unwrap();
        assert_eq!(p.solids.len(), 3);
        assert_eq!(p.solids[0].1, Solid::Sphere { center: Point3::new(0.0, 0.0, 10.0), radius: 12.5 });
        assert!(matches!(p.solids[1].1, Solid::HalfSpace { normal, .. } if normal == Vector3::z()));
    }

    #[test]
    fn errors_name_file_line_and_key() {
        let e =
            Part::from_toml("p.toml", "[[sphere]]\ncenter_mm = [0, 0, 10]\ndiameter_mm = 25\ncolour = 3\n")
                .unwrap_err();
        let s = e.to_string();
        assert!(s.starts_with("p.toml:4:"), "{s}");
        assert!(s.contains("colour"), "{s}");
        let e =
            Part::from_toml("p.toml", "[[sphere]]\ncenter_mm = [0, 0, 10]\ndiameter_mm = -2\n").unwrap_err();
        assert!(e.to_string().contains("sphere[0].diameter_mm"), "{e}");
        let e =
            MachineConfig::from_toml("m.toml", "[ippdme]\nvolume_min_mm=[0,0,0]\nvolume_max_mm=[1,1,-1]\n")
                .unwrap_err();
        assert!(e.to_string().contains("volume_max_mm"), "{e}");
        let m = MachineConfig::from_toml(
            "m.toml",
            "[machine]\nx=1\n[[ippdme.tool]]\nname=\"Star1\"\ntip_diameter_mm=2\n",
        )
        .unwrap();
        assert_eq!(m.tools[0].name, "Star1");
        assert_eq!(m.model, ModelConfig::default());
        let m = MachineConfig::from_toml(
            "m.toml",
            "[ippdme.model]\nseed = 7\ngeometric_errors = \"none\"\nprobe_noise_um = 0.5\n",
        )
        .unwrap();
        assert_eq!(m.model.seed, 7);
        assert!(!m.model.geometric_errors);
        assert!((m.model.probe_noise_mm - 0.5e-3).abs() < 1e-15);
        let e = MachineConfig::from_toml("m.toml", "[ippdme.model]\nseed = 7\n\nprobe_noize_um = 0.5\n")
            .unwrap_err();
        assert!(e.to_string().starts_with("m.toml:4:"), "{e}");
        assert!(e.to_string().contains("probe_noize_um"), "{e}");
        let e = MachineConfig::from_toml("m.toml", "[ippdme.model]\nlobing_um = 20\n").unwrap_err();
        assert!(e.to_string().contains("ippdme.model.lobing_um"), "{e}");
        let e = MachineConfig::from_toml("m.toml", "[ippdme.model]\nprobe_noise_um = -1\n").unwrap_err();
        assert!(e.to_string().contains("ippdme.model.probe_noise_um"), "{e}");
    }
}
