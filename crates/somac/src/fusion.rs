//! Weighted fusion of several trackers' readings of one point (machine frame), each weighted by
//! the inverse variance of its uncertainty model (which grows with distance and reflects the
//! geometry), with the fused standard uncertainty.

use truepos_math::{Point3, Vector3};

/// A reading in the machine frame with its standard uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// The position, machine frame, mm.
    pub p: Point3,
    /// Its standard uncertainty, mm.
    pub sigma_mm: f64,
}

/// Inverse-variance weighted mean and its standard uncertainty. `None` for no readings.
pub fn fuse(readings: &[Reading]) -> Option<Reading> {
    let mut wsum = 0.0;
    let mut acc = Vector3::zeros();
    for r in readings {
        let w = 1.0 / (r.sigma_mm * r.sigma_mm).max(1e-18);
        wsum += w;
        acc += w * r.p.coords;
    }
    (wsum > 0.0).then(|| Reading { p: Point3::from(acc / wsum), sigma_mm: (1.0 / wsum).sqrt() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_variance_weights() {
        // Hand calculation: σ 1 and 2 → weights 1 and 1/4 → mean (0·1 + 5·0.25)/1.25 = 1, σ = sqrt(1/1.25).
        let f = fuse(&[
            Reading { p: Point3::new(0.0, 0.0, 0.0), sigma_mm: 1.0 },
            Reading { p: Point3::new(5.0, 0.0, 0.0), sigma_mm: 2.0 },
        ])
        .unwrap();
        assert!((f.p.x - 1.0).abs() < 1e-15);
        assert!((f.sigma_mm - (1.0f64 / 1.25).sqrt()).abs() < 1e-15);
        assert!(fuse(&[]).is_none());
    }
}
