//! Artefacts with exact contact geometry: spheres, planes, parallel plates, cuboids, pyramids
//! (any convex polyhedron), capped cylinders, and parts with bores, bosses and planes.
//!
//! Every artefact answers one question exactly: for a point `p`, the nearest point of its
//! material surface, the outward unit normal there, and the signed distance (positive outside
//! the material). For a stylus tip of radius `r` centred at `c`, [`tip_contact`] gives the gap
//! `distance(c) − r` (negative = interference) and the tip-centre position that just touches
//! (`point + r·normal`): the stylus-centre surface is the artefact surface offset by `r`.
//! Outside a convex artefact, the normal at an edge or vertex is the direction from the nearest
//! point to `p`, which is the true contact normal of a ball touching the edge.
//!
//! Entry points: the [`Artefact`] trait (`closest`, `distance`), [`SurfacePoint`],
//! [`tip_contact`] / [`TipContact`], and the shapes [`Sphere`], [`Plane`], [`Plates`] (the gap
//! between two parallel faces), [`ConvexPolyhedron`] ([`ConvexPolyhedron::cuboid`],
//! [`ConvexPolyhedron::pyramid`]), [`Cylinder`] (solid, capped) and [`Part`] (block ∪ bosses −
//! bores). All are exact except [`Part`], which is exact wherever one feature is nearest and its
//! nearest point lies on the part's boundary (everywhere except within the query distance of an
//! intersection edge between features), and a conservative bound there.

use truepos_math::{Matrix3, Point3, Vector3};

use crate::noise::{check_positive, ParamError};

/// The nearest surface point of an artefact to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Signed distance from the surface (mm), positive outside the material.
    pub distance: f64,
    /// The nearest surface point.
    pub point: Point3,
    /// Outward unit normal of the material at the contact (for a point outside: (p − point)/|p − point|).
    pub normal: Vector3,
}

/// Something a stylus can touch.
pub trait Artefact: Send + Sync + std::fmt::Debug {
    /// The nearest surface point to `p`.
    fn closest(&self, p: &Point3) -> SurfacePoint;
    /// Signed distance of `p` from the surface (positive outside).
    fn distance(&self, p: &Point3) -> f64 {
        self.closest(p).distance
    }
}

/// Contact of a spherical stylus tip with an artefact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipContact {
    /// `distance(centre) − r`: negative when the tip interferes with the material.
    pub gap: f64,
    /// Contact point on the artefact surface.
    pub point: Point3,
    /// Outward normal at the contact.
    pub normal: Vector3,
    /// Tip centre that just touches at `point` (`point + r·normal`).
    pub touching_centre: Point3,
}

/// Contact of a tip of radius `tip_radius` centred at `centre` with `artefact`.
pub fn tip_contact(artefact: &dyn Artefact, centre: &Point3, tip_radius: f64) -> TipContact {
    let s = artefact.closest(centre);
    TipContact {
        gap: s.distance - tip_radius,
        point: s.point,
        normal: s.normal,
        touching_centre: s.point + s.normal * tip_radius,
    }
}

/// Any unit vector perpendicular to `n`.
fn perpendicular(n: &Vector3) -> Vector3 {
    let a = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    n.cross(&a).normalize()
}

fn unit(name: &'static str, v: Vector3) -> Result<Vector3, ParamError> {
    let n = v.norm();
    check_positive(name, n)?;
    Ok(v / n)
}

/// A solid sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre, mm.
    pub centre: Point3,
    /// Radius, mm.
    pub radius: f64,
}

impl Sphere {
    /// A sphere; the radius must be positive and finite (mm).
    pub fn new(centre: Point3, radius: f64) -> Result<Self, ParamError> {
        check_positive("sphere radius", radius)?;
        Ok(Sphere { centre, radius })
    }
}

impl Artefact for Sphere {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let d = p - self.centre;
        let len = d.norm();
        let normal = if len > 0.0 { d / len } else { Vector3::z() };
        SurfacePoint { distance: len - self.radius, point: self.centre + normal * self.radius, normal }
    }
}

/// A half-space: material behind the plane through `point` with outward `normal`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// A point of the plane, mm.
    pub point: Point3,
    /// Unit outward normal (out of the material).
    pub normal: Vector3,
}

impl Plane {
    /// A half-space; `normal` is normalised (it must not be zero).
    pub fn new(point: Point3, normal: Vector3) -> Result<Self, ParamError> {
        Ok(Plane { point, normal: unit("plane normal", normal)? })
    }
}

impl Artefact for Plane {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let d = (p - self.point).dot(&self.normal);
        SurfacePoint { distance: d, point: p - self.normal * d, normal: self.normal }
    }
}

/// Two parallel plates facing each other: material on both sides of the free slab
/// `|(p − mid)·axis| < gap/2`. Face 1 at `mid − axis·gap/2` has outward normal `+axis`, face 2
/// at `mid + axis·gap/2` has `−axis`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plates {
    /// The point midway between the faces, mm.
    pub mid: Point3,
    /// Unit axis across the gap.
    pub axis: Vector3,
    /// Distance between the faces, mm.
    pub gap: f64,
}

impl Plates {
    /// Two plates; `axis` is normalised and the gap must be positive (mm).
    pub fn new(mid: Point3, axis: Vector3, gap: f64) -> Result<Self, ParamError> {
        check_positive("plate gap", gap)?;
        Ok(Plates { mid, axis: unit("plate axis", axis)?, gap })
    }
}

impl Artefact for Plates {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let s = (p - self.mid).dot(&self.axis);
        let h = 0.5 * self.gap;
        let (d1, d2) = (s + h, h - s);
        if d1 <= d2 {
            SurfacePoint { distance: d1, point: p - self.axis * d1, normal: self.axis }
        } else {
            SurfacePoint { distance: d2, point: p + self.axis * d2, normal: -self.axis }
        }
    }
}

/// A planar convex face: vertices counter-clockwise seen from outside.
#[derive(Debug, Clone, PartialEq)]
struct Face {
    vertices: Vec<Point3>,
    normal: Vector3,
    offset: f64,
}

/// A convex polyhedron given by its faces.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvexPolyhedron {
    faces: Vec<Face>,
}

impl ConvexPolyhedron {
    /// From faces, each a list of ≥ 3 coplanar vertices counter-clockwise seen from outside.
    pub fn from_faces(faces: &[Vec<Point3>]) -> Result<Self, ParamError> {
        let mut out = Vec::with_capacity(faces.len());
        for f in faces {
            if f.len() < 3 {
                return Err(ParamError::Invalid {
                    name: "face vertex count",
                    requirement: ">= 3",
                    value: f.len() as f64,
                });
            }
            let mut n = Vector3::zeros();
            for i in 0..f.len() {
                let (a, b) = (f[i].coords, f[(i + 1) % f.len()].coords);
                n += a.cross(&b);
            }
            let normal = unit("face area", n)?;
            out.push(Face { vertices: f.clone(), normal, offset: normal.dot(&f[0].coords) });
        }
        if out.len() < 4 {
            return Err(ParamError::Invalid {
                name: "face count",
                requirement: ">= 4",
                value: out.len() as f64,
            });
        }
        Ok(ConvexPolyhedron { faces: out })
    }

    /// A cuboid: centre, half extents along its own axes, orientation `rotation` (columns are its
    /// axes in the machine frame).
    pub fn cuboid(centre: Point3, half: Vector3, rotation: Matrix3) -> Result<Self, ParamError> {
        for h in half.iter() {
            check_positive("cuboid half extent", *h)?;
        }
        let v = |sx: f64, sy: f64, sz: f64| {
            centre + rotation * Vector3::new(sx * half.x, sy * half.y, sz * half.z)
        };
        let faces = vec![
            vec![v(1., -1., -1.), v(1., 1., -1.), v(1., 1., 1.), v(1., -1., 1.)],
            vec![v(-1., -1., -1.), v(-1., -1., 1.), v(-1., 1., 1.), v(-1., 1., -1.)],
            vec![v(-1., 1., -1.), v(-1., 1., 1.), v(1., 1., 1.), v(1., 1., -1.)],
            vec![v(-1., -1., -1.), v(1., -1., -1.), v(1., -1., 1.), v(-1., -1., 1.)],
            vec![v(-1., -1., 1.), v(1., -1., 1.), v(1., 1., 1.), v(-1., 1., 1.)],
            vec![v(-1., -1., -1.), v(-1., 1., -1.), v(1., 1., -1.), v(1., -1., -1.)],
        ];
        Self::from_faces(&faces)
    }

    /// A square pyramid: base centre, base half width, height, orientation (its local +Z, the
    /// apex direction, is `rotation`'s third column).
    pub fn pyramid(
        base_centre: Point3,
        half_width: f64,
        height: f64,
        rotation: Matrix3,
    ) -> Result<Self, ParamError> {
        check_positive("pyramid half width", half_width)?;
        check_positive("pyramid height", height)?;
        let v = |x: f64, y: f64, z: f64| base_centre + rotation * Vector3::new(x, y, z);
        let w = half_width;
        let (b0, b1, b2, b3) = (v(-w, -w, 0.), v(w, -w, 0.), v(w, w, 0.), v(-w, w, 0.));
        let apex = v(0., 0., height);
        let faces = vec![
            vec![b0, b3, b2, b1],
            vec![b0, b1, apex],
            vec![b1, b2, apex],
            vec![b2, b3, apex],
            vec![b3, b0, apex],
        ];
        Self::from_faces(&faces)
    }
}

fn closest_on_segment(p: &Point3, a: &Point3, b: &Point3) -> Point3 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let t = if l2 > 0.0 { ((p - a).dot(&ab) / l2).clamp(0.0, 1.0) } else { 0.0 };
    a + ab * t
}

impl Artefact for ConvexPolyhedron {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        // Inside: the nearest face plane is exact for a convex body.
        let (imax, dmax) = self
            .faces
            .iter()
            .enumerate()
            .map(|(i, f)| (i, f.normal.dot(&p.coords) - f.offset))
            .fold((0, f64::NEG_INFINITY), |acc, x| if x.1 > acc.1 { x } else { acc });
        if dmax <= 0.0 {
            let n = self.faces[imax].normal;
            return SurfacePoint { distance: dmax, point: p - n * dmax, normal: n };
        }
        // Outside: nearest point over the faces (only faces whose plane sees p can hold it).
        let mut best = (f64::INFINITY, *p);
        for f in &self.faces {
            let d = f.normal.dot(&p.coords) - f.offset;
            if d <= 0.0 {
                continue;
            }
            let q = p - f.normal * d;
            let m = f.vertices.len();
            let inside = (0..m).all(|i| {
                (f.vertices[(i + 1) % m] - f.vertices[i]).cross(&(q - f.vertices[i])).dot(&f.normal) >= 0.0
            });
            let c = if inside {
                q
            } else {
                (0..m)
                    .map(|i| closest_on_segment(p, &f.vertices[i], &f.vertices[(i + 1) % m]))
                    .min_by(|a, b| (p - a).norm_squared().total_cmp(&(p - b).norm_squared()))
                    .unwrap_or(q)
            };
            let dist = (p - c).norm();
            if dist < best.0 {
                best = (dist, c);
            }
        }
        let (dist, c) = best;
        let normal = if dist > 0.0 { (p - c) / dist } else { self.faces[imax].normal };
        SurfacePoint { distance: dist, point: c, normal }
    }
}

/// A solid capped cylinder: axis through `centre` (the middle of its length) along `axis`,
/// `radius`, `length`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    /// Centre of the cylinder (middle of its length), mm.
    pub centre: Point3,
    /// Unit axis.
    pub axis: Vector3,
    /// Radius, mm.
    pub radius: f64,
    /// Length along the axis, mm.
    pub length: f64,
}

impl Cylinder {
    /// A cylinder; `axis` is normalised, radius and length must be positive (mm).
    pub fn new(centre: Point3, axis: Vector3, radius: f64, length: f64) -> Result<Self, ParamError> {
        check_positive("cylinder radius", radius)?;
        check_positive("cylinder length", length)?;
        Ok(Cylinder { centre, axis: unit("cylinder axis", axis)?, radius, length })
    }
}

impl Artefact for Cylinder {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let d = p - self.centre;
        let a = d.dot(&self.axis);
        let rad = d - self.axis * a;
        let rr = rad.norm();
        let er = if rr > 1e-300 { rad / rr } else { perpendicular(&self.axis) };
        let h = 0.5 * self.length;
        let (dr, da) = (rr - self.radius, a.abs() - h);
        let sa = if a >= 0.0 { 1.0 } else { -1.0 };
        if dr <= 0.0 && da <= 0.0 {
            return if dr > da {
                SurfacePoint {
                    distance: dr,
                    point: self.centre + self.axis * a + er * self.radius,
                    normal: er,
                }
            } else {
                SurfacePoint {
                    distance: da,
                    point: self.centre + self.axis * (sa * h) + rad,
                    normal: self.axis * sa,
                }
            };
        }
        let q = self.centre + self.axis * a.clamp(-h, h) + er * rr.min(self.radius);
        let dist = (p - q).norm();
        let normal = if dr > 0.0 && da > 0.0 {
            (p - q) / dist
        } else if dr > 0.0 {
            er
        } else {
            self.axis * sa
        };
        SurfacePoint { distance: dist, point: q, normal }
    }
}

/// A part: a block with bosses (solid cylinders) added and bores (cylindrical holes) removed.
/// Planes are the block's faces.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// The block the part is made from.
    pub block: ConvexPolyhedron,
    /// Cylinders added to the block.
    pub bosses: Vec<Cylinder>,
    /// Cylinders removed from the block.
    pub bores: Vec<Cylinder>,
}

impl Artefact for Part {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let mut best = self.block.closest(p);
        for b in &self.bosses {
            let s = b.closest(p);
            if s.distance < best.distance {
                best = s;
            }
        }
        for h in &self.bores {
            let s = h.closest(p);
            // Material minus hole: distance max(d_material, −d_hole), normal into the hole.
            if -s.distance > best.distance {
                best = SurfacePoint { distance: -s.distance, point: s.point, normal: -s.normal };
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn check_consistent(a: &dyn Artefact, p: &Point3) {
        let s = a.closest(p);
        // The reported distance is the distance to the reported point, signed.
        assert!(((p - s.point).norm() - s.distance.abs()).abs() < 1e-9, "{s:?}");
        assert!((s.normal.norm() - 1.0).abs() < 1e-12);
        // p = point + distance·normal.
        assert!((s.point + s.normal * s.distance - p).norm() < 1e-9, "{p} {s:?}");
    }

    #[test]
    fn shapes_give_exact_known_distances() {
        let sp = Sphere::new(Point3::new(1.0, 2.0, 3.0), 12.5).unwrap();
        assert!((sp.distance(&Point3::new(1.0, 2.0, 20.0)) - 4.5).abs() < 1e-12);
        let pl = Plates::new(Point3::origin(), Vector3::x(), 20.0).unwrap();
        let s = pl.closest(&Point3::new(8.0, 5.0, 1.0));
        assert!((s.distance - 2.0).abs() < 1e-12 && s.normal == -Vector3::x());
        let cub =
            ConvexPolyhedron::cuboid(Point3::origin(), Vector3::new(1.0, 2.0, 3.0), Matrix3::identity())
                .unwrap();
        assert!((cub.distance(&Point3::new(4.0, 6.0, 0.0)) - 5.0).abs() < 1e-12); // edge: 3-4-5
        assert!((cub.distance(&Point3::new(0.5, 0.0, 0.0)) + 0.5).abs() < 1e-12);
        let py = ConvexPolyhedron::pyramid(Point3::origin(), 1.0, 1.0, Matrix3::identity()).unwrap();
        // Apex region: straight above the apex the nearest point is the apex.
        assert!((py.distance(&Point3::new(0.0, 0.0, 3.0)) - 2.0).abs() < 1e-12);
        // Side face x + z = 1: distance of (2, 0, 1) is |2 + 1 − 1|/√2.
        assert!((py.distance(&Point3::new(2.0, 0.0, 1.0)) - 2.0 / 2f64.sqrt()).abs() < 1e-12);
        let cyl = Cylinder::new(Point3::origin(), Vector3::z(), 5.0, 10.0).unwrap();
        assert!((cyl.distance(&Point3::new(8.0, 0.0, 9.0)) - 5.0).abs() < 1e-12);
        let part = Part {
            block: ConvexPolyhedron::cuboid(
                Point3::origin(),
                Vector3::new(50.0, 50.0, 10.0),
                Matrix3::identity(),
            )
            .unwrap(),
            bosses: vec![Cylinder::new(Point3::new(20.0, 20.0, 15.0), Vector3::z(), 5.0, 10.0).unwrap()],
            bores: vec![Cylinder::new(Point3::new(-20.0, 0.0, 0.0), Vector3::z(), 6.0, 30.0).unwrap()],
        };
        // In the bore, 2 mm from its axis: 4 mm from the wall, normal pointing to the axis.
        let s = part.closest(&Point3::new(-18.0, 0.0, 0.0));
        assert!((s.distance - 4.0).abs() < 1e-12 && (s.normal + Vector3::x()).norm() < 1e-12);
        // Beside the boss, above the block: 3 mm from the boss wall.
        assert!((part.distance(&Point3::new(28.0, 20.0, 15.0)) - 3.0).abs() < 1e-12);
        let tc = tip_contact(&sp, &Point3::new(1.0, 2.0, 16.0), 1.0);
        assert!(
            (tc.gap + 0.5).abs() < 1e-12 && (tc.touching_centre - Point3::new(1.0, 2.0, 16.5)).norm() < 1e-12
        );
    }

    proptest! {
        #[test]
        fn closest_points_are_consistent(x in -20.0..20.0f64, y in -20.0..20.0f64, z in -20.0..20.0f64) {
            let p = Point3::new(x, y, z);
            let r = truepos_math::rz(0.3) * truepos_math::rx(0.2);
            check_consistent(&Sphere::new(Point3::new(1.0, 0.0, 0.0), 7.0).unwrap(), &p);
            check_consistent(&Plates::new(Point3::origin(), Vector3::new(1.0, 1.0, 0.0), 8.0).unwrap(), &p);
            check_consistent(&ConvexPolyhedron::cuboid(Point3::origin(), Vector3::new(3.0, 4.0, 5.0), r).unwrap(), &p);
            check_consistent(&ConvexPolyhedron::pyramid(Point3::origin(), 6.0, 8.0, r).unwrap(), &p);
            check_consistent(&Cylinder::new(Point3::origin(), Vector3::new(0.0, 1.0, 1.0), 4.0, 9.0).unwrap(), &p);
            // Exactness outside a convex body: no point of a dense surface sample is nearer.
            let cub = ConvexPolyhedron::cuboid(Point3::origin(), Vector3::new(3.0, 4.0, 5.0), r).unwrap();
            let s = cub.closest(&p);
            if s.distance > 0.0 {
                for i in 0..=10 { for j in 0..=10 {
                    let (u, v) = (-1.0 + 0.2 * i as f64, -1.0 + 0.2 * j as f64);
                    for q in [Vector3::new(1.0, u, v), Vector3::new(u, 1.0, v), Vector3::new(u, v, 1.0),
                              Vector3::new(-1.0, u, v), Vector3::new(u, -1.0, v), Vector3::new(u, v, -1.0)] {
                        let sp = Point3::from(r * Vector3::new(3.0 * q.x, 4.0 * q.y, 5.0 * q.z));
                        prop_assert!((p - sp).norm() >= s.distance - 1e-9);
                    }
                }}
            }
        }
    }
}
