//! Best-fit transforms between matched point sets.
//!
//! Entry points: [`best_fit`] (weighted least squares, rigid or similarity, by the SVD of the
//! 3×3 cross-covariance with the reflection guard — Kabsch/Umeyama), [`three_point`] (the classic
//! 3-2-1 construction: first point is the origin, first→second the primary direction, the third
//! fixes the plane), and [`residuals`].
//!
//! Only nalgebra's fixed-size 3×3 SVD is used (its dynamic SVD is wrong on some inputs).

use crate::transform::Transform3;
use crate::types::{Matrix3, Point3, Vector3};
use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum BestFitError {
    #[error("the point sets have different lengths ({0} and {1})")]
    LengthMismatch(usize, usize),
    #[error("{needed} points are needed, {got} given")]
    TooFewPoints { needed: usize, got: usize },
    #[error("weights must be finite and non-negative, with a positive sum")]
    BadWeights,
    #[error("the points are collinear (or coincide): the rotation about their line is undetermined")]
    Collinear,
    #[error("the singular value decomposition did not converge")]
    SvdFailed,
}

/// Options of [`best_fit`].
#[derive(Clone, Copy, Debug, Default)]
pub struct BestFitOptions {
    /// Also estimate a uniform scale (similarity transform).
    pub with_scale: bool,
}

/// Weighted least-squares transform `to_from_from` minimising `Σ wᵢ |to_i − T(from_i)|²`.
///
/// `weights`: `None` for equal weights. Needs at least three non-collinear points.
pub fn best_fit(
    from: &[Point3],
    to: &[Point3],
    weights: Option<&[f64]>,
    options: BestFitOptions,
) -> Result<Transform3, BestFitError> {
    if from.len() != to.len() {
        return Err(BestFitError::LengthMismatch(from.len(), to.len()));
    }
    if from.len() < 3 {
        return Err(BestFitError::TooFewPoints { needed: 3, got: from.len() });
    }
    if let Some(w) = weights {
        if w.len() != from.len() {
            return Err(BestFitError::LengthMismatch(from.len(), w.len()));
        }
        if w.iter().any(|x| !x.is_finite() || *x < 0.0) {
            return Err(BestFitError::BadWeights);
        }
    }
    let w = |i: usize| weights.map_or(1.0, |w| w[i]);
    let wsum: f64 = (0..from.len()).map(w).sum();
    if wsum <= 0.0 || !wsum.is_finite() {
        return Err(BestFitError::BadWeights);
    }
    let mut cf = Vector3::zeros();
    let mut ct = Vector3::zeros();
    for i in 0..from.len() {
        cf += w(i) * from[i].coords;
        ct += w(i) * to[i].coords;
    }
    cf /= wsum;
    ct /= wsum;
    let mut h = Matrix3::zeros();
    let mut var_from = 0.0;
    for i in 0..from.len() {
        let a = from[i].coords - cf;
        let b = to[i].coords - ct;
        h += w(i) * b * a.transpose();
        var_from += w(i) * a.norm_squared();
    }
    // Collinearity: the spread of `from` must have rank >= 2.
    let spread = {
        let mut c = Matrix3::zeros();
        for (i, p) in from.iter().enumerate() {
            let a = p.coords - cf;
            c += w(i) * a * a.transpose();
        }
        c
    };
    let eig = spread.symmetric_eigen();
    let mut ev = [eig.eigenvalues[0], eig.eigenvalues[1], eig.eigenvalues[2]];
    ev.sort_by(|a, b| b.total_cmp(a));
    if ev[0] <= 0.0 || ev[1] <= ev[0] * 1e-20 {
        return Err(BestFitError::Collinear);
    }
    let svd = h.svd(true, true);
    let (u, vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Err(BestFitError::SvdFailed),
    };
    let d = (u * vt).determinant().signum();
    let dm = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d));
    let rotation = u * dm * vt;
    let scale = if options.with_scale {
        let sv = svd.singular_values;
        (sv[0] + sv[1] + d * sv[2]) / var_from
    } else {
        1.0
    };
    let translation = ct - scale * (rotation * cf);
    Ok(Transform3 { scale, rotation, translation })
}

/// The three-point (3-2-1) transform: `to[0]` is matched exactly, the direction `from[0]→from[1]`
/// is mapped onto `to[0]→to[1]`, and the plane of the three points onto the other plane.
/// With `with_scale`, the scale is the ratio of the perimeters of the two triangles.
pub fn three_point(from: &[Point3], to: &[Point3], with_scale: bool) -> Result<Transform3, BestFitError> {
    if from.len() != to.len() {
        return Err(BestFitError::LengthMismatch(from.len(), to.len()));
    }
    if from.len() < 3 {
        return Err(BestFitError::TooFewPoints { needed: 3, got: from.len() });
    }
    let frame = |p: &[Point3]| -> Result<Matrix3, BestFitError> {
        let x = p[1] - p[0];
        let v = p[2] - p[0];
        let z = x.cross(&v);
        let scale = x.norm() * v.norm();
        if x.norm() == 0.0 || z.norm() <= 1e-12 * scale {
            return Err(BestFitError::Collinear);
        }
        let x = x.normalize();
        let z = z.normalize();
        let y = z.cross(&x);
        Ok(Matrix3::from_columns(&[x, y, z]))
    };
    let ff = frame(from)?;
    let ft = frame(to)?;
    let rotation = ft * ff.transpose();
    let scale = if with_scale {
        let per = |p: &[Point3]| (p[1] - p[0]).norm() + (p[2] - p[1]).norm() + (p[0] - p[2]).norm();
        per(to) / per(from)
    } else {
        1.0
    };
    let translation = to[0].coords - scale * (rotation * from[0].coords);
    Ok(Transform3 { scale, rotation, translation })
}

/// Residual vectors `to_i − T(from_i)`.
pub fn residuals(t: &Transform3, from: &[Point3], to: &[Point3]) -> Vec<Vector3> {
    from.iter().zip(to).map(|(f, p)| p - t.apply(f)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{rx, ry, rz};
    use proptest::prelude::*;

    fn cloud(seed: &[[f64; 3]]) -> Vec<Point3> {
        seed.iter().map(|p| Point3::new(p[0], p[1], p[2])).collect()
    }

    proptest! {
        #[test]
        fn recovers_known_similarity(
            a in -3.1f64..3.1, b in -1.5f64..1.5, c in -3.1f64..3.1,
            s in 0.9f64..1.1,
            t in prop::array::uniform3(-5000.0f64..5000.0),
            pts in prop::collection::vec(prop::array::uniform3(-2000.0f64..2000.0), 4..40),
        ) {
            let from = cloud(&pts);
            // Skip (practically impossible) degenerate clouds.
            prop_assume!(best_fit(&from, &from, None, BestFitOptions::default()).is_ok());
            let truth = Transform3::new(s, rz(c) * ry(b) * rx(a), Vector3::new(t[0], t[1], t[2]));
            let to: Vec<Point3> = from.iter().map(|p| truth.apply(p)).collect();
            let est = best_fit(&from, &to, None, BestFitOptions { with_scale: true }).unwrap();
            for (f, p) in from.iter().zip(&to) {
                prop_assert!((est.apply(f) - p).norm() < 1e-9, "residual {}", (est.apply(f) - p).norm());
            }
            prop_assert!((est.scale - s).abs() < 1e-12);
            let rigid_truth = Transform3 { scale: 1.0, ..truth };
            let to_rigid: Vec<Point3> = from.iter().map(|p| rigid_truth.apply(p)).collect();
            let w: Vec<f64> = (0..from.len()).map(|i| 1.0 + i as f64).collect();
            let est = best_fit(&from, &to_rigid, Some(&w), BestFitOptions::default()).unwrap();
            for (f, p) in from.iter().zip(&to_rigid) {
                prop_assert!((est.apply(f) - p).norm() < 1e-9);
            }
            prop_assert!(est.rotation.determinant() > 0.0);
        }

        #[test]
        fn three_point_matches_exact_data(
            a in -3.1f64..3.1, b in -1.5f64..1.5, c in -3.1f64..3.1,
            t in prop::array::uniform3(-5000.0f64..5000.0),
        ) {
            let from = cloud(&[[0.0, 0.0, 0.0], [1000.0, 10.0, 0.0], [100.0, 800.0, 50.0], [500.0, 500.0, 500.0]]);
            let truth = Transform3::rigid(rz(c) * ry(b) * rx(a), Vector3::new(t[0], t[1], t[2]));
            let to: Vec<Point3> = from.iter().map(|p| truth.apply(p)).collect();
            let est = three_point(&from, &to, false).unwrap();
            for (f, p) in from.iter().zip(&to) {
                prop_assert!((est.apply(f) - p).norm() < 1e-9);
            }
        }
    }

    #[test]
    fn reflection_is_never_returned() {
        // A mirrored planar set: the best proper rotation, not the reflection.
        let from = cloud(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        let to: Vec<Point3> = from.iter().map(|p| Point3::new(-p.x, p.y, p.z)).collect();
        let t = best_fit(&from, &to, None, BestFitOptions::default()).unwrap();
        assert!((t.rotation.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn collinear_and_short_inputs_are_named() {
        let line = cloud(&[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]);
        assert_eq!(best_fit(&line, &line, None, Default::default()), Err(BestFitError::Collinear));
        assert_eq!(three_point(&line, &line, false), Err(BestFitError::Collinear));
        assert!(matches!(
            best_fit(&line[..2], &line[..2], None, Default::default()),
            Err(BestFitError::TooFewPoints { .. })
        ));
    }
}
