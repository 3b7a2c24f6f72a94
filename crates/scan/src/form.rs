//! Form error of a scanned feature from its scan-segment points: the least-squares element of
//! `truepos-fit` (3D circle for bores and bosses, plane for a circle scanned on a plane, line for
//! a line scan), then the peak-to-valley of the residuals (radial for circles, along the plane
//! normal, along the nominal surface normal for lines).
//!
//! Entry point: [`form_error`].

use crate::feature::{Feature, Geometry, Side};
use crate::ScanError;
use truepos_math::Point3;

/// Fewest scan points accepted for a form evaluation.
pub const MIN_POINTS: usize = 8;

fn pv(it: impl Iterator<Item = f64>) -> f64 {
    let (lo, hi) = it.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    if hi >= lo {
        hi - lo
    } else {
        0.0
    }
}

/// Peak-to-valley of the least-squares residuals (mm).
pub fn form_error(f: &Feature, pts: &[Point3]) -> Result<f64, ScanError> {
    if pts.len() < MIN_POINTS {
        return Err(ScanError::TooFewPoints { id: f.id.clone(), n: pts.len() });
    }
    let fit_err = |e: truepos_fit::FitError| ScanError::Fit { id: f.id.clone(), why: e.to_string() };
    Ok(match &f.geometry {
        Geometry::Circle { side: Side::Plane, .. } => {
            let pl = truepos_fit::plane(pts).map_err(fit_err)?;
            pv(pts.iter().map(|p| pl.distance(p)))
        }
        Geometry::Circle { .. } => {
            let c = truepos_fit::circle(pts).map_err(fit_err)?;
            pv(pts.iter().map(|p| {
                let d = p - c.center;
                let h = d.dot(&c.normal);
                (d - c.normal * h).norm() - c.radius
            }))
        }
        Geometry::Line { normal, .. } => {
            let l = truepos_fit::line(pts).map_err(fit_err)?;
            pv(pts.iter().map(|p| {
                let d = p - l.point;
                (d - l.direction * d.dot(&l.direction)).dot(normal)
            }))
        }
    })
}
