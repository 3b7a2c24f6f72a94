//! First and second moments of a point cloud in one or two passes: centroid, scatter matrix and
//! its eigen-decomposition (principal axes), the algebraic (Kåsa) sphere normal equations, and
//! the degeneracy tests every fit starts with (finite, enough points, not coincident,
//! collinear or coplanar).

use crate::FitError;
use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;
use truepos_math::{Matrix3, Point3, Vector3};

const CHUNK: usize = 16 * 1024;
const PARALLEL_ABOVE: usize = 32 * 1024;

/// Ratio of standard deviations (smallest over largest principal spread) below which a point
/// cloud counts as lower-dimensional. Points printed with 5 decimals on a 100 mm part are still
/// three-dimensional above 1e-7; exactly collinear/coplanar data computed in floating point
/// sits near 1e-15. 1e-9 separates the two with margin on both sides.
pub const DEGENERATE_RATIO: f64 = 1e-9;

/// Spread ratio above which the eigenvalues alone decide the dimension (their rounding floor is
/// ~1e-8 in this ratio, the square root of the relative rounding of an eigenvalue).
pub const RESOLVED_RATIO: f64 = 1e-6;

/// Moments of a point set about its centroid.
#[derive(Clone, Debug)]
pub struct Moments {
    /// Number of points.
    pub n: usize,
    /// Centroid (mean position) of the points, mm.
    pub centroid: Point3,
    /// `Σ (p − c)(p − c)ᵀ`.
    pub scatter: Matrix3,
    /// Eigenvalues of `scatter`, ascending.
    pub eigenvalues: Vector3,
    /// Unit eigenvectors matching `eigenvalues` (columns).
    pub eigenvectors: Matrix3,
    /// `Σ (p − c)|p − c|²`, mm³: with `sum_sq` and `sum_sq2`, the algebraic sphere sums.
    pub sq3: Vector3,
    /// `Σ |p − c|²`, mm².
    pub sum_sq: f64,
    /// `Σ |p − c|⁴`, mm⁴.
    pub sum_sq2: f64,
}

/// The largest coordinate magnitude a fit accepts, mm: 10¹² mm (a million km, beyond any
/// measured coordinate, geocentric ones in mm included). Far larger values are a unit or
/// format error, and the fit's sums of squares and fourth powers of coordinate differences
/// overflow from about 10⁷⁵ mm (10¹⁵⁴ for squares), which made distinct points at 10²⁰⁰ read as
/// coinciding; refused with the point and this limit ([`FitError::CoordinateTooLarge`]).
pub const MAX_COORDINATE_MM: f64 = 1e12;

/// The first point with a coordinate beyond [`MAX_COORDINATE_MM`], as an error.
fn check_magnitude(points: &[Point3]) -> Result<(), FitError> {
    let big = |p: &&Point3| p.coords.amax() > MAX_COORDINATE_MM;
    match points.iter().enumerate().find(|(_, p)| big(p)) {
        Some((index, p)) => Err(FitError::CoordinateTooLarge { index, magnitude: p.coords.amax() }),
        None => Ok(()),
    }
}

fn check_finite(points: &[Point3]) -> Result<(), FitError> {
    let bad = if points.len() > PARALLEL_ABOVE {
        points.par_iter().position_first(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    } else {
        points.iter().position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    };
    match bad {
        Some(index) => Err(FitError::NonFinite { index }),
        None => Ok(()),
    }
}

fn centroid(points: &[Point3]) -> Point3 {
    let sum = |c: &[Point3]| c.iter().fold(Vector3::zeros(), |s, p| s + p.coords);
    let s = if points.len() > PARALLEL_ABOVE {
        // Added in chunk order, whatever the threads do: the same digits on every run.
        let parts: Vec<Vector3> = points.par_chunks(CHUNK).map(sum).collect();
        parts.into_iter().fold(Vector3::zeros(), |a, b| a + b)
    } else {
        points.chunks(4096).map(sum).fold(Vector3::zeros(), |a, b| a + b)
    };
    Point3::from(s / points.len() as f64)
}

#[derive(Clone, Copy)]
struct Sums {
    xx: [f64; 6],
    sq3: [f64; 3],
    sq: f64,
    sq2: f64,
    first: [f64; 3],
    /// Largest coordinate magnitude seen.
    amax: f64,
}

impl Sums {
    fn zero() -> Self {
        Sums { xx: [0.0; 6], sq3: [0.0; 3], sq: 0.0, sq2: 0.0, first: [0.0; 3], amax: 0.0 }
    }
    fn add(mut self, o: Sums) -> Sums {
        for k in 0..6 {
            self.xx[k] += o.xx[k];
        }
        for k in 0..3 {
            self.sq3[k] += o.sq3[k];
            self.first[k] += o.first[k];
        }
        self.sq += o.sq;
        self.sq2 += o.sq2;
        self.amax = self.amax.max(o.amax);
        self
    }
}

fn sums(points: &[Point3], c: &Point3) -> Sums {
    let mut s = Sums::zero();
    for p in points {
        let (x, y, z) = (p.x - c.x, p.y - c.y, p.z - c.z);
        let q = x * x + y * y + z * z;
        s.xx[0] += x * x;
        s.xx[1] += x * y;
        s.xx[2] += x * z;
        s.xx[3] += y * y;
        s.xx[4] += y * z;
        s.xx[5] += z * z;
        s.sq3[0] += x * q;
        s.sq3[1] += y * q;
        s.sq3[2] += z * q;
        s.sq += q;
        s.sq2 += q * q;
        s.first[0] += x;
        s.first[1] += y;
        s.first[2] += z;
        s.amax = s.amax.max(p.x.abs()).max(p.y.abs()).max(p.z.abs());
    }
    s
}

impl Moments {
    /// Check finiteness and compute the moments (two passes over the points).
    pub fn of(points: &[Point3]) -> Result<Moments, FitError> {
        if points.is_empty() {
            return Err(FitError::TooFewPoints { kind: "point set", needed: 1, got: 0 });
        }
        let c0 = centroid(points);
        // One pass fewer on good data: a non-finite coordinate makes the sum non-finite, and
        // only then is the offending point searched for. (Finite points whose sum overflows
        // are reported as the first point, as no coordinate is usable at that magnitude.)
        if !(c0.x.is_finite() && c0.y.is_finite() && c0.z.is_finite()) {
            check_finite(points)?;
            check_magnitude(points)?;
            return Err(FitError::NonFinite { index: 0 });
        }
        let s = if points.len() > PARALLEL_ABOVE {
            let parts: Vec<Sums> = points.par_chunks(CHUNK).map(|ch| sums(ch, &c0)).collect();
            parts.into_iter().fold(Sums::zero(), Sums::add)
        } else {
            sums(points, &c0)
        };
        if s.amax > MAX_COORDINATE_MM {
            check_magnitude(points)?;
        }
        // Correct the centroid by the residual mean (compensates rounding in the first pass).
        let n = points.len() as f64;
        let d = Vector3::new(s.first[0], s.first[1], s.first[2]) / n;
        let centroid = c0 + d;
        let scatter =
            Matrix3::new(s.xx[0], s.xx[1], s.xx[2], s.xx[1], s.xx[3], s.xx[4], s.xx[2], s.xx[4], s.xx[5])
                - d * d.transpose() * n;
        let eig = scatter.symmetric_eigen();
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        let eigenvalues =
            Vector3::new(eig.eigenvalues[idx[0]], eig.eigenvalues[idx[1]], eig.eigenvalues[idx[2]])
                .map(|v| v.max(0.0));
        let eigenvectors = Matrix3::from_columns(&[
            eig.eigenvectors.column(idx[0]).into_owned(),
            eig.eigenvectors.column(idx[1]).into_owned(),
            eig.eigenvectors.column(idx[2]).into_owned(),
        ]);
        Ok(Moments {
            n: points.len(),
            centroid,
            scatter,
            eigenvalues,
            eigenvectors,
            sq3: Vector3::new(s.sq3[0], s.sq3[1], s.sq3[2]),
            sum_sq: s.sq,
            sum_sq2: s.sq2,
        })
    }

    /// Principal axis `k` (0 = least spread, 2 = most).
    pub fn axis(&self, k: usize) -> Vector3 {
        self.eigenvectors.column(k).into_owned()
    }

    /// RMS distance of the points from their centroid (the data's scale), mm.
    pub fn extent(&self) -> f64 {
        (self.eigenvalues.sum() / self.n as f64).sqrt()
    }

    /// Moments of `points` for a fit of `kind`: checks the count first (so an empty set is
    /// "too few points"), then finiteness and the dimension (see [`require`](Self::require)),
    /// confirmed on the points themselves when the eigenvalues cannot tell.
    pub fn for_fit(
        points: &[Point3],
        kind: &'static str,
        needed: usize,
        dimension: usize,
    ) -> Result<Moments, FitError> {
        if points.len() < needed {
            return Err(FitError::TooFewPoints { kind, needed, got: points.len() });
        }
        let m = Moments::of(points)?;
        m.require_direct(points, kind, dimension)?;
        Ok(m)
    }

    /// Refuse point sets that cannot determine an element of `kind` with `needed` points and the
    /// given dimension (1 = must not be collinear, 2 = must not be coplanar), by the
    /// eigenvalues. An eigenvalue carries an absolute rounding error of ~1e-16 of the largest
    /// one, so a spread ratio below ~1e-8 is not resolved here: [`for_fit`](Self::for_fit)
    /// then measures the distances from the principal line or plane point by point.
    pub fn require(&self, kind: &'static str, needed: usize, dimension: usize) -> Result<(), FitError> {
        if self.n < needed {
            return Err(FitError::TooFewPoints { kind, needed, got: self.n });
        }
        let scale = self.centroid.coords.amax().max(self.extent());
        let max = self.eigenvalues[2].sqrt();
        if !(max > 1e-13 * scale) {
            return Err(FitError::CoincidentPoints);
        }
        if dimension >= 1 && !(self.eigenvalues[1].sqrt() > DEGENERATE_RATIO * max) {
            return Err(FitError::CollinearPoints { kind });
        }
        if dimension >= 2 && !(self.eigenvalues[0].sqrt() > DEGENERATE_RATIO * max) {
            return Err(FitError::CoplanarPoints { kind });
        }
        Ok(())
    }

    /// The dimension test on the points themselves, where the eigenvalues are too close to
    /// their rounding floor to decide (spread ratio below [`RESOLVED_RATIO`]): the largest
    /// distance from the centroid (coincident), from the principal line (collinear) and from the
    /// principal plane (coplanar), against [`DEGENERATE_RATIO`] of the largest extent along the
    /// principal axis plus the rounding of the coordinates (1e-13 of their magnitude).
    fn require_direct(
        &self,
        points: &[Point3],
        kind: &'static str,
        dimension: usize,
    ) -> Result<(), FitError> {
        let max = self.eigenvalues[2].sqrt();
        let scale = self.centroid.coords.amax().max(self.extent());
        let check_point = !(max > RESOLVED_RATIO * scale);
        let r1 = self.eigenvalues[1].sqrt() / max;
        let r0 = self.eigenvalues[0].sqrt() / max;
        let check_line = dimension >= 1 && !(r1 >= RESOLVED_RATIO);
        let check_plane = dimension >= 2 && !(r0 >= RESOLVED_RATIO);
        if !(check_point || check_line || check_plane) {
            return Ok(());
        }
        let c = self.centroid;
        let (a0, a2) = (self.axis(0), self.axis(2));
        let fold = |acc: [f64; 4], p: &Point3| {
            let d = p - c;
            let along = d.dot(&a2);
            let perp = (d - a2 * along).norm();
            [acc[0].max(d.norm()), acc[1].max(along.abs()), acc[2].max(perp), acc[3].max(d.dot(&a0).abs())]
        };
        let m = if points.len() > PARALLEL_ABOVE {
            points
                .par_iter()
                .fold(|| [0.0; 4], fold)
                .reduce(|| [0.0; 4], |a, b| [a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2]), a[3].max(b[3])])
        } else {
            points.iter().fold([0.0; 4], fold)
        };
        let rounding = 1e-13 * self.centroid.coords.abs().max().max(m[0]);
        if !(m[0] > rounding) {
            return Err(FitError::CoincidentPoints);
        }
        if check_line && !(m[2] > DEGENERATE_RATIO * m[1] + rounding) {
            return Err(FitError::CollinearPoints { kind });
        }
        if check_plane && !(m[3] > DEGENERATE_RATIO * m[1] + rounding) {
            return Err(FitError::CoplanarPoints { kind });
        }
        Ok(())
    }

    /// Algebraic (Kåsa) sphere through the moments: minimises `Σ (|p − c|² − R²)²`.
    /// Returns centre and radius, or `None` when the linear system is singular.
    pub fn algebraic_sphere(&self) -> Option<(Point3, f64)> {
        // Unknowns (a, b, c, e) with |q|² = 2 a·q + e, q = p − centroid (Σq = 0).
        let n = self.n as f64;
        let mut m = Matrix4::zeros();
        let mut rhs = Vector4::zeros();
        for i in 0..3 {
            for j in 0..3 {
                m[(i, j)] = 4.0 * self.scatter[(i, j)];
            }
            rhs[i] = 2.0 * self.sq3[i];
        }
        m[(3, 3)] = n;
        rhs[3] = self.sum_sq;
        let sol = m.cholesky()?.solve(&rhs);
        let a = Vector3::new(sol[0], sol[1], sol[2]);
        let r2 = sol[3] + a.norm_squared();
        (r2 > 0.0 && r2.is_finite()).then(|| (self.centroid + a, r2.sqrt()))
    }
}
