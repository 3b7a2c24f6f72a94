//! The scale factor of a part from its targets: reference (nominal) positions against measured
//! ones, by a similarity best fit, with the standard uncertainty of the scale from the residual
//! scatter ([`fit_scale`]). Used by `truepos autoscale` and the loop's auto-scaling.

use truepos_math::bestfit::{self, BestFitError, BestFitOptions};
use truepos_math::{Point3, Transform3};

/// Scale factor of the measured points relative to the reference ones, with its standard
/// uncertainty from the residual scatter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleFit {
    pub scale: f64,
    /// Standard uncertainty of `scale` (1σ, dimensionless).
    pub u_scale: f64,
    /// RMS of the 3D residuals (mm).
    pub rms_mm: f64,
    /// Number of matched points.
    pub n: usize,
}

/// Fit `measured = s·R·reference + t` and the scale's uncertainty.
///
/// The residual standard deviation per coordinate is `σ = sqrt(SSR / (3n − 7))` (7 parameters:
/// 3 rotation, 3 translation, scale); the scale multiplies every reference vector from the
/// centroid, so its least-squares standard uncertainty is `σ / sqrt(Σ |p_i − c|²)`.
pub fn fit_scale(reference: &[Point3], measured: &[Point3]) -> Result<(ScaleFit, Transform3), BestFitError> {
    let t = bestfit::best_fit(reference, measured, None, BestFitOptions { with_scale: true })?;
    let res = bestfit::residuals(&t, reference, measured);
    let ssr: f64 = res.iter().map(|r| r.norm_squared()).sum();
    let n = reference.len();
    let dof = (3 * n).saturating_sub(7).max(1) as f64;
    let sigma = (ssr / dof).sqrt();
    let c = truepos_math::centroid(reference);
    let spread: f64 = reference.iter().map(|p| (p - c).norm_squared()).sum();
    let u_scale = sigma / spread.sqrt();
    Ok((ScaleFit { scale: t.scale, u_scale, rms_mm: (ssr / n as f64).sqrt(), n }, t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_math::Vector3;

    /// An exact scale of 1 + 50 ppm is recovered to rounding, and the uncertainty of a fit
    /// without noise is (numerically) zero.
    #[test]
    fn recovers_an_exact_scale() {
        let reference: Vec<Point3> = (0..8)
            .map(|i| {
                Point3::new(
                    if i & 1 == 0 { 0.0 } else { 5000.0 },
                    if i & 2 == 0 { 0.0 } else { 1000.0 },
                    if i & 4 == 0 { 0.0 } else { 300.0 },
                )
            })
            .collect();
        let s = 1.0 + 50e-6;
        let measured: Vec<Point3> =
            reference.iter().map(|p| Point3::from(p.coords * s) + Vector3::new(1.0, 2.0, 3.0)).collect();
        let (f, _) = fit_scale(&reference, &measured).unwrap();
        assert!((f.scale - s).abs() < 1e-12, "{}", f.scale);
        assert!(f.u_scale < 1e-12 && f.rms_mm < 1e-9);
        assert_eq!(f.n, 8);
    }
}
