//! Descriptive statistics and straight-line regression with standard uncertainties.
//!
//! Entry points: [`mean`], [`std_dev`], [`rms`], [`LineFit`] via [`fit_line`] (weighted
//! `y = a + b·x` with the standard uncertainties of `a` and `b` from the residual scatter),
//! [`COVERAGE_FACTOR`] (the k of every expanded uncertainty truepos reports).

/// Coverage factor of the expanded uncertainties U = k·u (k = 2: ≈ 95 % coverage for a normal
/// distribution, GUM 6.3). One value for every capability.
pub const COVERAGE_FACTOR: f64 = 2.0;

/// Arithmetic mean (NaN for an empty slice).
pub fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

/// Sample standard deviation (n − 1 in the denominator; 0 for fewer than two values).
pub fn std_dev(x: &[f64]) -> f64 {
    if x.len() < 2 {
        return 0.0;
    }
    let m = mean(x);
    (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (x.len() as f64 - 1.0)).sqrt()
}

/// Root mean square (0 for an empty slice).
pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Largest absolute value (0 for an empty slice).
pub fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// Result of a straight-line regression `y = intercept + slope·x`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineFit {
    /// Value of the line at `x = 0`, in the units of `y`.
    pub intercept: f64,
    /// Gradient `dy/dx`, in units of `y` per unit of `x`.
    pub slope: f64,
    /// Standard uncertainty of the intercept.
    pub u_intercept: f64,
    /// Standard uncertainty of the slope.
    pub u_slope: f64,
    /// Residual standard deviation (n − 2 degrees of freedom; 0 when n == 2).
    pub sigma: f64,
    /// Number of points used.
    pub n: usize,
}

/// Weighted least-squares line. `weights = None` for equal weights. With weights, the
/// uncertainties are scaled by the observed residual scatter (Birge ratio), so the weights
/// need only be relative. Returns `None` for fewer than two distinct `x`.
pub fn fit_line(x: &[f64], y: &[f64], weights: Option<&[f64]>) -> Option<LineFit> {
    let n = x.len().min(y.len());
    if n < 2 {
        return None;
    }
    let w = |i: usize| weights.map_or(1.0, |w| w[i]);
    let sw: f64 = (0..n).map(w).sum();
    let mx = (0..n).map(|i| w(i) * x[i]).sum::<f64>() / sw;
    let my = (0..n).map(|i| w(i) * y[i]).sum::<f64>() / sw;
    let sxx: f64 = (0..n).map(|i| w(i) * (x[i] - mx).powi(2)).sum();
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let sxy: f64 = (0..n).map(|i| w(i) * (x[i] - mx) * (y[i] - my)).sum();
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let ssr: f64 = (0..n).map(|i| w(i) * (y[i] - intercept - slope * x[i]).powi(2)).sum();
    let s2 = if n > 2 { ssr / (n as f64 - 2.0) } else { 0.0 };
    let u_slope = (s2 / sxx).sqrt();
    let u_intercept = (s2 * (1.0 / sw + mx * mx / sxx)).sqrt();
    let sigma = if weights.is_some() { (s2 * n as f64 / sw).sqrt() } else { s2.sqrt() };
    Some(LineFit { intercept, slope, u_intercept, u_slope, sigma, n })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_line_has_zero_uncertainty() {
        let x = [1.0, 2.0, 3.0, 4.0];
        let y = [3.0, 5.0, 7.0, 9.0];
        let f = fit_line(&x, &y, None).unwrap();
        assert!((f.slope - 2.0).abs() < 1e-15 && (f.intercept - 1.0).abs() < 1e-14);
        assert!(f.u_slope < 1e-14);
    }

    #[test]
    fn uncertainty_matches_hand_calculation() {
        // x = 0,1,2; y = 0,2,1 → slope 0.5, intercept 0.5, residuals -0.5, 1, -0.5, SSR 1.5,
        // s² = 1.5, Sxx = 2 → u(slope) = sqrt(0.75).
        let f = fit_line(&[0.0, 1.0, 2.0], &[0.0, 2.0, 1.0], None).unwrap();
        assert!((f.slope - 0.5).abs() < 1e-15);
        assert!((f.u_slope - 0.75f64.sqrt()).abs() < 1e-15);
        assert!((f.u_intercept - (1.5f64 * (1.0 / 3.0 + 0.5)).sqrt()).abs() < 1e-15);
        assert!(fit_line(&[1.0, 1.0], &[0.0, 1.0], None).is_none());
    }

    #[test]
    fn descriptive() {
        assert_eq!(mean(&[1.0, 2.0, 3.0]), 2.0);
        assert_eq!(std_dev(&[1.0, 2.0, 3.0]), 1.0);
        assert!((rms(&[3.0, 4.0]) - 12.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(max_abs(&[-3.0, 2.0]), 3.0);
    }
}
