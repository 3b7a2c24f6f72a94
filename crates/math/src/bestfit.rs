//! Best-fit transforms between matched point sets.
//!
//! Entry points: [`best_fit`] (weighted least squares, rigid or similarity, by the SVD of the
//! 3×3 cross-covariance with the reflection guard — Kabsch/Umeyama), [`three_point`] (the classic
//! 3-2-1 construction: first point is the origin, first→second the primary direction, the third
//! fixes the plane), [`scale_fit`] (the similarity scale alone, which two points determine), and
//! [`residuals`].
//!
//! Only nalgebra's fixed-size 3×3 SVD is used (its dynamic SVD is wrong on some inputs).

use crate::transform::Transform3;
use crate::types::{Matrix3, Point3, Vector3};
use thiserror::Error;

/// Why a point-set best fit cannot be computed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum BestFitError {
    /// The two point sets have different lengths (first, second).
    #[error("the point sets have different lengths ({0} and {1})")]
    LengthMismatch(usize, usize),
    /// Fewer points than the fit needs.
    #[error("{needed} points are needed, {got} given")]
    TooFewPoints {
        /// Points the fit needs.
        needed: usize,
        /// Points given.
        got: usize,
    },
    /// A weight is negative or not finite, or the weights sum to zero.
    #[error("weights must be finite and non-negative, with a positive sum")]
    BadWeights,
    /// Every weight is zero: no point takes part (a degenerate fit, not a bad number).
    #[error("all {0} weights are zero: no point takes part in the fit, so nothing determines it (degenerate); give the points that count a positive weight")]
    ZeroWeights(usize),
    /// The points lie on one line, so the rotation about it is undetermined.
    #[error("the points are collinear: the rotation about their line is undetermined")]
    Collinear,
    /// All points of one set coincide, so there is nothing to orient.
    #[error("all {which} points coincide (with non-zero weight): nothing to fit a {what} to")]
    Coincident {
        /// Which set (`from` or `to`).
        which: &'static str,
        /// What was being fitted.
        what: &'static str,
    },
    /// A coordinate is NaN or infinite.
    #[error("a coordinate is not a finite number")]
    NotFinite,
    /// nalgebra's singular value decomposition did not converge.
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
/// `weights`: `None` for equal weights. Needs at least three non-collinear points (with
/// non-zero weight).
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
    let core = fit_core(from, to, weights, options.with_scale, "transform")?;
    if core.rank_from < 2 {
        return Err(BestFitError::Collinear);
    }
    // Identical target points: the rotation is not determined (any one fits equally badly) and
    // the scale would be 0; refused as degenerate, like coincident reference points.
    if core.to_coincide {
        return Err(BestFitError::Coincident { which: "target (to)", what: "transform" });
    }
    Ok(core.transform)
}

/// The similarity scale of [`scale_fit`], with what the data determine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScaleFit {
    /// Best-fit ratio of `to` size to `from` size.
    pub scale: f64,
    /// A best-fit similarity transform with that scale. When the points are collinear (two
    /// points, or a row of features) the rotation about their line is arbitrary.
    pub transform: Transform3,
    /// Whether the `from` points span more than a line (so the rotation is determined).
    pub rotation_determined: bool,
}

/// The best-fit uniform scale between matched point sets (similarity fit, rotation and
/// translation removed). Two points are enough: their distance ratio. Refuses coincident `from`
/// or `to` points (no size to compare).
pub fn scale_fit(from: &[Point3], to: &[Point3], weights: Option<&[f64]>) -> Result<ScaleFit, BestFitError> {
    if from.len() != to.len() {
        return Err(BestFitError::LengthMismatch(from.len(), to.len()));
    }
    if from.len() < 2 {
        return Err(BestFitError::TooFewPoints { needed: 2, got: from.len() });
    }
    let core = fit_core(from, to, weights, true, "scale")?;
    if core.var_to <= 0.0 || core.transform.scale <= 0.0 || !core.transform.scale.is_finite() {
        return Err(BestFitError::Coincident { which: "measured (to)", what: "scale" });
    }
    Ok(ScaleFit {
        scale: core.transform.scale,
        transform: core.transform,
        rotation_determined: core.rank_from >= 2,
    })
}

struct Core {
    transform: Transform3,
    /// Rank of the weighted spread of `from` (0, 1 collinear, 2 planar, 3).
    rank_from: usize,
    var_to: f64,
    /// All weighted `to` points coincide (to ~1e-13 of their size).
    to_coincide: bool,
}

fn fit_core(
    from: &[Point3],
    to: &[Point3],
    weights: Option<&[f64]>,
    with_scale: bool,
    what: &'static str,
) -> Result<Core, BestFitError> {
    if let Some(w) = weights {
        if w.len() != from.len() {
            return Err(BestFitError::LengthMismatch(from.len(), w.len()));
        }
        if w.iter().any(|x| !x.is_finite() || *x < 0.0) {
            return Err(BestFitError::BadWeights);
        }
    }
    if from.iter().chain(to).any(|p| !p.coords.iter().all(|c| c.is_finite())) {
        return Err(BestFitError::NotFinite);
    }
    let w = |i: usize| weights.map_or(1.0, |w| w[i]);
    let wsum: f64 = (0..from.len()).map(w).sum();
    if wsum == 0.0 {
        return Err(BestFitError::ZeroWeights(from.len()));
    }
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
    let mut var_to = 0.0;
    let mut spread = Matrix3::zeros();
    for i in 0..from.len() {
        let a = from[i].coords - cf;
        let b = to[i].coords - ct;
        h += w(i) * b * a.transpose();
        var_from += w(i) * a.norm_squared();
        var_to += w(i) * b.norm_squared();
        spread += w(i) * a * a.transpose();
    }
    // Rank of the spread of `from`: coincident (0), collinear (1), or more.
    let eig = spread.symmetric_eigen();
    let mut ev = [eig.eigenvalues[0], eig.eigenvalues[1], eig.eigenvalues[2]];
    ev.sort_by(|a, b| b.total_cmp(a));
    // Relative to the coordinates' magnitude: points equal to ~1e-13 of their size coincide.
    let size2 = from.iter().map(|p| p.coords.norm_squared()).fold(0.0, f64::max) * wsum;
    if ev[0] <= size2 * 1e-26 || var_from <= 0.0 {
        return Err(BestFitError::Coincident { which: "reference (from)", what });
    }
    let rank_from = if ev[1] <= ev[0] * 1e-20 { 1 } else { 2 };
    // The same test for `to`: all weighted target points at one place (to ~1e-13 of their size).
    let size2_to = to.iter().map(|p| p.coords.norm_squared()).fold(0.0, f64::max) * wsum;
    let to_coincide = var_to.partial_cmp(&(size2_to * 1e-26)) != Some(std::cmp::Ordering::Greater);
    let svd = h.svd(true, true);
    let (u, vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Err(BestFitError::SvdFailed),
    };
    let d = (u * vt).determinant().signum();
    let dm = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d));
    let rotation = u * dm * vt;
    let scale = if with_scale {
        let sv = svd.singular_values;
        (sv[0] + sv[1] + d * sv[2]) / var_from
    } else {
        1.0
    };
    let translation = ct - scale * (rotation * cf);
    Ok(Core { transform: Transform3 { scale, rotation, translation }, rank_from, var_to, to_coincide })
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

    /// Two features: the scale is their distance ratio (100.0 mm apart, measured 100.1 mm →
    /// 1.001), whatever the rotation and translation; more collinear points give the least-squares
    /// ratio Σ|b|·|a| / Σ|a|² about the centroids (worked by hand below).
    #[test]
    fn scale_from_two_and_collinear_points() {
        let from = cloud(&[[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]]);
        let t = Transform3::new(1.001, rz(0.4) * rx(0.2), Vector3::new(5.0, -3.0, 2.0));
        let to: Vec<Point3> = from.iter().map(|p| t.apply(p)).collect();
        let f = scale_fit(&from, &to, None).unwrap();
        assert!((f.scale - 1.001).abs() < 1e-14, "{}", f.scale);
        assert!(!f.rotation_determined);
        for (a, b) in from.iter().zip(&to) {
            assert!((f.transform.apply(a) - b).norm() < 1e-9);
        }
        // Three collinear points at 0, 100, 300 measured at 0, 100.1, 300.2 (not a pure scale):
        // about the centroids a = (-133.33, -33.33, 166.67), b = (-133.43, -33.33, 166.77);
        // s = Σ a·b / Σ a² (signs agree along the line).
        let from = cloud(&[[0.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 300.0, 0.0]]);
        let to = cloud(&[[1.0, 0.0, 0.0], [1.0, 100.1, 0.0], [1.0, 300.2, 0.0]]);
        let a = [-400.0 / 3.0, -100.0 / 3.0, 500.0 / 3.0];
        let cb = 400.3 / 3.0;
        let b = [-cb, 100.1 - cb, 300.2 - cb];
        let s: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() / a.iter().map(|x| x * x).sum::<f64>();
        let f = scale_fit(&from, &to, None).unwrap();
        assert!((f.scale - s).abs() < 1e-13, "{} vs {s}", f.scale);
    }

    #[test]
    fn degenerate_inputs_are_named() {
        let same = cloud(&[[10.0, 20.0, 30.0], [10.0, 20.0, 30.0], [10.0, 20.0, 30.0]]);
        let good = cloud(&[[0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 100.0, 0.0]]);
        let e = scale_fit(&same, &good, None).unwrap_err();
        assert!(matches!(e, BestFitError::Coincident { .. }), "{e}");
        assert!(e.to_string().contains("reference"), "{e}");
        let e = scale_fit(&good, &same, None).unwrap_err();
        assert!(e.to_string().contains("measured"), "{e}");
        let e = best_fit(&same, &good, None, Default::default()).unwrap_err();
        assert!(matches!(e, BestFitError::Coincident { .. }), "{e}");
        let e = best_fit(&good, &good, Some(&[0.0, 0.0, 0.0]), Default::default()).unwrap_err();
        assert_eq!(e, BestFitError::ZeroWeights(3));
        assert!(
            e.to_string().contains("all 3 weights are zero") && e.to_string().contains("degenerate"),
            "{e}"
        );
        assert_eq!(
            best_fit(&good, &good, Some(&[1.0, -1.0, 1.0]), Default::default()),
            Err(BestFitError::BadWeights)
        );
        // Identical target points, rigid or with scale: refused, naming the target points.
        for with_scale in [false, true] {
            let e = best_fit(&good, &same, None, BestFitOptions { with_scale }).unwrap_err();
            assert_eq!(e, BestFitError::Coincident { which: "target (to)", what: "transform" });
            assert!(e.to_string().contains("all target (to) points coincide"), "{e}");
        }
        // Only one point with weight: all weighted points coincide.
        assert!(matches!(
            best_fit(&good, &good, Some(&[1.0, 0.0, 0.0]), Default::default()),
            Err(BestFitError::Coincident { .. })
        ));
        let nan = cloud(&[[f64::NAN, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 100.0, 0.0]]);
        assert_eq!(best_fit(&nan, &good, None, Default::default()), Err(BestFitError::NotFinite));
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
