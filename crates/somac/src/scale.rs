//! The scale factor of a part from its targets: reference (nominal) positions against measured
//! ones, by a similarity best fit, with the standard uncertainty of the scale from the residual
//! scatter ([`fit_scale`]). Used by the loop's auto-scaling and by `truepos autoscale`
//! ([`autoscale_files`], with the scale expected from thermal expansion, [`Expansion`]).

use serde_json::{json, Value};
use std::path::Path;
use truepos_io::points::read_matched;
use truepos_io::report::Report;
use truepos_io::InputError;
use truepos_math::bestfit::{self, BestFitError};
use truepos_math::stats::COVERAGE_FACTOR;
use truepos_math::{Point3, Transform3};

/// Scale factor of the measured points relative to the reference ones, with its standard
/// uncertainty from the residual scatter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleFit {
    /// The fitted scale (measured / nominal), dimensionless.
    pub scale: f64,
    /// Standard uncertainty of `scale` (1σ, dimensionless).
    pub u_scale: f64,
    /// RMS of the 3D residuals (mm).
    pub rms_mm: f64,
    /// Number of matched points.
    pub n: usize,
}

impl ScaleFit {
    /// The fit for people (`truepos autoscale`): scale in ppm with its standard uncertainty, the
    /// scale `expected` from the CTE and temperature with the discrepancy, and the residual.
    pub fn text(&self, expected: Option<f64>) -> String {
        let mut out = format!(
            "scale            {:.9}  ({:+.2} ppm, u = {:.2} ppm)\n",
            self.scale,
            (self.scale - 1.0) * 1e6,
            self.u_scale * 1e6
        );
        if let Some(e) = expected {
            out += &format!("expected (CTE)   {e:.9}\n");
            out += &format!("discrepancy      {:+.2} ppm\n", (self.scale / e - 1.0) * 1e6);
        }
        out += &format!("rms residual     {:.4} mm over {} features\n", self.rms_mm, self.n);
        out
    }
}

/// Fit `measured = s·R·reference + t` and the scale's uncertainty. Two points are enough (the
/// scale is then their distance ratio); coincident reference or measured points are refused.
///
/// The residual standard deviation per coordinate is `σ = sqrt(SSR / (3n − p))` with p = 7
/// parameters (3 rotation, 3 translation, scale), or 6 when the points lie on a line (the turn
/// about it is not determined); the scale multiplies every reference vector from the centroid,
/// so its least-squares standard uncertainty is `σ / sqrt(Σ |p_i − c|²)`. With no redundancy
/// (two points) the scatter is unknown and `u_scale` is NaN.
pub fn fit_scale(reference: &[Point3], measured: &[Point3]) -> Result<(ScaleFit, Transform3), BestFitError> {
    let f = bestfit::scale_fit(reference, measured, None)?;
    let t = f.transform;
    let res = bestfit::residuals(&t, reference, measured);
    let ssr: f64 = res.iter().map(|r| r.norm_squared()).sum();
    let n = reference.len();
    let params = if f.rotation_determined { 7 } else { 6 };
    let sigma = if 3 * n > params { (ssr / (3 * n - params) as f64).sqrt() } else { f64::NAN };
    let c = truepos_math::centroid(reference);
    let spread: f64 = reference.iter().map(|p| (p - c).norm_squared()).sum();
    let u_scale = sigma / spread.sqrt();
    Ok((ScaleFit { scale: t.scale, u_scale, rms_mm: (ssr / n as f64).sqrt(), n }, t))
}

/// The part's thermal expansion: the scale expected at `temperature_c`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expansion {
    /// Coefficient of thermal expansion of the part, ppm/°C.
    pub cte_ppm_per_c: f64,
    /// The part's temperature, °C.
    pub temperature_c: f64,
    /// Temperature of the reference positions (usually 20 °C).
    pub reference_temperature_c: f64,
}

impl Expansion {
    /// `1 + CTE · (T − T_ref)`; non-finite inputs are an input error.
    pub fn expected_scale(&self) -> Result<f64, InputError> {
        let Expansion { cte_ppm_per_c: k, temperature_c: t, reference_temperature_c: t0 } = *self;
        if !(k.is_finite() && t.is_finite() && t0.is_finite()) {
            return Err(InputError::new("the CTE and the temperatures must be finite numbers"));
        }
        Ok(1.0 + k * 1e-6 * (t - t0))
    }
}

/// The result of `truepos autoscale`: the fitted scale and, with an [`Expansion`], the scale
/// expected from it.
#[derive(Clone, Copy, Debug)]
pub struct Autoscale {
    /// The scale fitted to the targets.
    pub fit: ScaleFit,
    /// The scale expected from the part's temperature, when known.
    pub expected: Option<f64>,
}

impl Report for Autoscale {
    fn to_json(&self) -> Value {
        let f = &self.fit;
        let u = f.u_scale.is_finite().then_some(f.u_scale);
        json!({
            "scale": f.scale,
            "scale_uncertainty": u,
            "coverage_factor": COVERAGE_FACTOR,
            "expanded_uncertainty": {"scale": u.map(|u| COVERAGE_FACTOR * u)},
            "scale_ppm": (f.scale - 1.0) * 1e6,
            "expected_scale": self.expected,
            "discrepancy_ppm": self.expected.map(|e| (f.scale / e - 1.0) * 1e6),
            "rms_mm": f.rms_mm,
            "n_points": f.n,
        })
    }

    fn text(&self) -> String {
        self.fit.text(self.expected)
    }
}

/// Fit the scale of the features of `measured` against `reference` (`id,x_mm,y_mm,z_mm`,
/// matched by id, at least two).
pub fn autoscale_files(
    reference: &Path,
    measured: &Path,
    expansion: Option<Expansion>,
) -> Result<Autoscale, InputError> {
    let expected = expansion.map(|e| e.expected_scale()).transpose()?;
    let (_, _, mt) = read_matched(reference, measured, 2, "a scale (two give their distance ratio)")?;
    let (fit, _) = fit_scale(&mt.from, &mt.to)
        .map_err(|e| InputError::in_file(measured, format!("cannot fit a scale: {e}")))?;
    Ok(Autoscale { fit, expected })
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

    /// The example: two features 100.0 mm apart measured 100.1 mm apart (and turned,
    /// and moved) give the scale 1.001; identical measured points are refused.
    #[test]
    fn two_features_give_their_distance_ratio() {
        let reference = [Point3::new(0.0, 0.0, 0.0), Point3::new(100.0, 0.0, 0.0)];
        let measured = [Point3::new(10.0, 20.0, 5.0), Point3::new(10.0, 120.1, 5.0)];
        let (f, _) = fit_scale(&reference, &measured).unwrap();
        assert!((f.scale - 1.001).abs() < 1e-12, "{}", f.scale);
        assert!(f.u_scale.is_nan(), "no redundancy: no uncertainty from the scatter");
        let same = [Point3::new(1.0, 1.0, 1.0); 3];
        let three = [Point3::new(0.0, 0.0, 0.0), Point3::new(100.0, 0.0, 0.0), Point3::new(0.0, 50.0, 0.0)];
        assert!(matches!(fit_scale(&three, &same), Err(BestFitError::Coincident { .. })));
        assert!(matches!(fit_scale(&same, &three), Err(BestFitError::Coincident { .. })));
    }
}
