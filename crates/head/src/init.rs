//! Closed-form starting values for the head-offset adjustment.
//!
//! Per orientation: an algebraic sphere fit ([`algebraic_sphere`]) or the intersection of
//! fitted face planes ([`plane_fit`], [`intersect_planes`]) gives the apparent reference point
//! `C_k` in "raw" coordinates (the head reference point P, before the offset is added). The
//! contract's model makes `C_k − O = Rz(c_k)·(A − O) − Ry(b_k)·R`, linear in the reference point
//! `A` (table frame at `c = 0`) and the offset `R`; [`linear_solve`] solves it by least squares
//! over all orientations with some offset components held at given values. Nothing here needs a
//! starting guess, so the adjustment that follows converges wherever the reference sits.

use nalgebra::{Matrix3, Matrix4, SymmetricEigen, Vector4};
use truepos_math::{centroid, ry, rz, DMatrix, DVector, Point3, Vector3};

/// Algebraic (Kåsa) sphere fit on points centred at their mean: returns (centre, radius), or
/// `None` when the points do not determine a sphere (fewer than 4, coplanar, collinear).
pub fn algebraic_sphere(points: &[Point3]) -> Option<(Point3, f64)> {
    if points.len() < 4 {
        return None;
    }
    let m = centroid(points);
    let mut n = Matrix4::<f64>::zeros();
    let mut rhs = Vector4::<f64>::zeros();
    let mut scale = 0.0f64;
    for p in points {
        scale = scale.max((p - m).norm());
    }
    if scale.is_nan() || scale <= 0.0 || !scale.is_finite() {
        return None;
    }
    for p in points {
        let d = (p - m) / scale;
        let row = Vector4::new(2.0 * d.x, 2.0 * d.y, 2.0 * d.z, 1.0);
        n += row * row.transpose();
        rhs += row * d.norm_squared();
    }
    // Degeneracy check on the column-scaled normal matrix.
    let dg: Vec<f64> = (0..4).map(|i| 1.0 / n[(i, i)].max(1e-300).sqrt()).collect();
    let mut s = n;
    for a in 0..4 {
        for b in 0..4 {
            s[(a, b)] *= dg[a] * dg[b];
        }
    }
    let eig = SymmetricEigen::new(s);
    let max = eig.eigenvalues.max();
    let min = eig.eigenvalues.min();
    if min.is_nan() || min <= 1e-10 * max {
        return None;
    }
    let sol = n.cholesky()?.solve(&rhs);
    let c = Vector3::new(sol[0], sol[1], sol[2]);
    let r2 = sol[3] + c.norm_squared();
    if r2.is_nan() || r2 <= 0.0 {
        return None;
    }
    Some((m + c * scale, r2.sqrt() * scale))
}

/// Total-least-squares plane: (unit normal, centroid, smallest/middle eigenvalue ratio), or `None`
/// for fewer than 3 points or collinear points.
pub fn plane_fit(points: &[Point3]) -> Option<(Vector3, Point3)> {
    if points.len() < 3 {
        return None;
    }
    let m = centroid(points);
    let mut cov = Matrix3::<f64>::zeros();
    for p in points {
        let d = p - m;
        cov += d * d.transpose();
    }
    let eig = SymmetricEigen::new(cov);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let (l0, l1) = (eig.eigenvalues[idx[0]], eig.eigenvalues[idx[1]]);
    if l1.is_nan() || l1 <= 0.0 || l0 > 0.5 * l1 {
        return None;
    }
    let n: Vector3 = eig.eigenvectors.column(idx[0]).into_owned();
    Some((n.normalize(), m))
}

/// Least-squares intersection point of planes `n·x = n·p`, or `None` when the normals do not span
/// space well (smallest eigenvalue of `Σ n nᵀ` below `min_eig`).
pub fn intersect_planes(planes: &[(Vector3, Point3)], min_eig: f64) -> Option<Point3> {
    let mut a = Matrix3::<f64>::zeros();
    let mut b = Vector3::zeros();
    for (n, p) in planes {
        a += n * n.transpose();
        b += n * n.dot(&p.coords);
    }
    let eig = SymmetricEigen::new(a);
    let min = eig.eigenvalues.min();
    if min.is_nan() || min <= min_eig {
        return None;
    }
    a.cholesky().map(|c| Point3::from(c.solve(&b)))
}

/// One orientation's apparent reference point in raw coordinates.
#[derive(Clone, Debug)]
pub struct Apparent {
    /// Head angle B of the orientation, rad.
    pub b: f64,
    /// Table angle C of the orientation, rad.
    pub c: f64,
    /// The apparent reference point (sphere centre or vertex) in raw coordinates, mm.
    pub point: Point3,
}

/// Rows of the linear model for one orientation: `[Rz(c), −Ry(b)]`.
fn rows(b: f64, c: f64) -> (Matrix3<f64>, Matrix3<f64>) {
    (rz(c), -ry(b))
}

/// The 6×6 normal matrix of the linear apparent-centre model (unknowns `A − O`, `R`).
pub fn linear_normal(app: &[Apparent]) -> DMatrix {
    let mut n = DMatrix::zeros(6, 6);
    for a in app {
        let (ma, mr) = rows(a.b, a.c);
        let mut m = DMatrix::zeros(3, 6);
        m.view_mut((0, 0), (3, 3)).copy_from(&ma);
        m.view_mut((0, 3), (3, 3)).copy_from(&mr);
        n += m.transpose() * m;
    }
    n
}

/// Solve `C_k − O = Rz(c_k)(A − O) − Ry(b_k) R` for `A` and the free components of `R`
/// (`free[j]`), holding the others at `prior[j]`. Returns `(A, R)` or `None` if singular.
pub fn linear_solve(
    app: &[Apparent],
    o: &Point3,
    free: [bool; 3],
    prior: &Vector3,
) -> Option<(Point3, Vector3)> {
    let fr: Vec<usize> = (0..3).filter(|&j| free[j]).collect();
    let n = 3 + fr.len();
    let mut ntn = DMatrix::zeros(n, n);
    let mut ntb = DVector::zeros(n);
    for a in app {
        let (ma, mr) = rows(a.b, a.c);
        // Right-hand side with the held components moved over.
        let mut held = Vector3::zeros();
        for j in 0..3 {
            if !free[j] {
                held[j] = prior[j];
            }
        }
        let rhs = (a.point - o) - mr * held;
        let mut m = DMatrix::zeros(3, n);
        m.view_mut((0, 0), (3, 3)).copy_from(&ma);
        for (k, &j) in fr.iter().enumerate() {
            for i in 0..3 {
                m[(i, 3 + k)] = mr[(i, j)];
            }
        }
        ntn += m.transpose() * &m;
        ntb += m.transpose() * DVector::from_column_slice(rhs.as_slice());
    }
    let sol = ntn.cholesky()?.solve(&ntb);
    if sol.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let a = o + Vector3::new(sol[0], sol[1], sol[2]);
    let mut r = *prior;
    for (k, &j) in fr.iter().enumerate() {
        r[j] = sol[3 + k];
    }
    Some((a, r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn algebraic_sphere_is_exact_on_exact_points() {
        let c = Point3::new(120.0, -40.0, 300.0);
        let pts: Vec<Point3> = (0..20)
            .map(|i| {
                let t = i as f64 * 0.37;
                let p = 0.3 + 0.05 * i as f64;
                c + Vector3::new(p.sin() * t.cos(), p.sin() * t.sin(), p.cos()) * 12.5
            })
            .collect();
        let (cc, r) = algebraic_sphere(&pts).unwrap();
        // Exact data: only rounding remains (values of order 1e2 mm → 1e-10 mm is generous).
        assert!((cc - c).norm() < 1e-9, "{cc}");
        assert!((r - 12.5).abs() < 1e-9);
    }

    #[test]
    fn coplanar_points_are_not_a_sphere() {
        let pts: Vec<Point3> = (0..10).map(|i| Point3::new(i as f64, (i * i) as f64, 5.0)).collect();
        assert!(algebraic_sphere(&pts).is_none());
    }

    #[test]
    fn three_planes_meet_at_the_corner() {
        let corner = Point3::new(1.0, 2.0, 3.0);
        let planes = vec![
            (Vector3::x(), corner + Vector3::new(0.0, 5.0, 1.0)),
            (Vector3::y(), corner + Vector3::new(2.0, 0.0, 7.0)),
            (Vector3::z(), corner + Vector3::new(3.0, 1.0, 0.0)),
        ];
        let v = intersect_planes(&planes, 1e-6).unwrap();
        assert!((v - corner).norm() < 1e-12);
    }
}
