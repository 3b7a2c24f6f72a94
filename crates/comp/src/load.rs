//! Bed deformation under load: the portal geometry, the physics that turns a bed deflection into
//! the portal's pitch and roll, and the contract's correction of measured points.
//!
//! Entry points: [`Portal`] (rails, height, bearing span, travel), [`portal_rotation`] (pitch and
//! roll at one portal position from any deflection field `uz(x, y)`), [`LoadCorrection`]
//! (pitch/roll curves + pivot → correction of a point).
//!
//! ## Physics and sign convention
//!
//! The portal rides on the two rails at `x = rail_x[0]`, `x = rail_x[1]` (top at
//! `z = rail_height`), on bearings `bearing_span` apart along Y centred on the portal position
//! `y`. The bed deflects by `uz(x, y)` (positive up). The portal, rigid, follows its bearings:
//!
//! - its physical tilt about +X is `α = (ū_front − ū_back) / span` (front = +Y bearing; ū = mean
//!   over the two rails): a positive α lifts the +Y side;
//! - its physical tilt about +Y is `β = −(ū_2 − ū_1) / (x_2 − x_1)` (ū_r = mean of the two
//!   bearings on rail r): a positive β lowers the +X side.
//!
//! The scales on the portal read the same values as before, so the probe tip really is at
//! `p_true ≈ p + (α, β, 0) × (p − o)` when the machine indicates `p`, with the pivot
//! `o = ((x1 + x2)/2, y, rail_height)`. The contract (interface.md, "Geometric map and load")
//! states pitch and roll as these **physical** rotations, `θ = (α, β)` by the right-hand rule
//! about +X and +Y, and corrects with `p + e`, `e = (θx, θy, 0) × (p − o)`: exactly the true
//! point above. A load ahead of the portal (larger Y) sinks its front bearings: the portal tips
//! forward and the pitch is negative; a load near rail 2 (larger X) lowers that rail and the roll
//! is positive. Maps from an outside FE package that reports the physical rotations are used as
//! they come (pitch_urad = 10⁶·(uz_front − uz_back)/span, roll_urad = 10⁶·(uz_rail1 −
//! uz_rail2)/(x2 − x1)).
//!
//! The common vertical sink of the four bearings (`ū`) moves the portal without rotating it; the
//! contract's model has no term for it, and it is not corrected here.

use crate::geometric::OutOfRange;
use crate::influence::PortalCurves;
use truepos_math::{Point3, Vector3};

/// The portal and its travel (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Portal {
    /// X of the two rails, mm.
    pub rail_x: [f64; 2],
    /// Height of the rails above the bed, mm.
    pub rail_height: f64,
    /// Distance between a carriage's bearings along Y, mm.
    pub bearing_span: f64,
    /// The travel in Y (start, end), mm.
    pub y_range: [f64; 2],
    /// Step of the positions in Y, mm.
    pub y_step: f64,
}

/// Why a portal description is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PortalError {
    /// The two rails are at the same X (mm).
    #[error("the two rails must be at different x (rail_x_mm = [{0}, {1}])")]
    Rails(f64, f64),
    /// The bearing span is not positive (mm).
    #[error("bearing_span_mm must be positive (got {0})")]
    Span(f64),
    #[error(
        "y_range_mm must be increasing and y_step_mm positive (y_range_mm = [{0}, {1}], y_step_mm = {2})"
    )]
    /// The Y range is not increasing or the step not positive (start, end, step, mm).
    Range(f64, f64, f64),
    /// A portal value is not finite.
    #[error("a portal value is not finite")]
    NotFinite,
}

impl Portal {
    /// Check that the rails differ, the span is positive, the range increases and every value is finite.
    pub fn validate(&self) -> Result<(), PortalError> {
        let all = [
            self.rail_x[0],
            self.rail_x[1],
            self.rail_height,
            self.bearing_span,
            self.y_range[0],
            self.y_range[1],
            self.y_step,
        ];
        if all.iter().any(|v| !v.is_finite()) {
            return Err(PortalError::NotFinite);
        }
        if self.rail_x[0] == self.rail_x[1] {
            return Err(PortalError::Rails(self.rail_x[0], self.rail_x[1]));
        }
        if self.bearing_span <= 0.0 {
            return Err(PortalError::Span(self.bearing_span));
        }
        // At most 100,000 portal positions: beyond that the step is a typo, not a map.
        if !(self.y_range[1] > self.y_range[0] && self.y_step > 0.0)
            || (self.y_range[1] - self.y_range[0]) / self.y_step > 1e5
        {
            return Err(PortalError::Range(self.y_range[0], self.y_range[1], self.y_step));
        }
        Ok(())
    }

    /// Portal positions `y0, y0 + step, …`, ending exactly at `y1` (the last step may be shorter).
    pub fn positions(&self) -> Vec<f64> {
        let [y0, y1] = self.y_range;
        let n = ((y1 - y0) / self.y_step - 1e-9).floor().max(0.0) as usize;
        let mut v: Vec<f64> = (0..=n).map(|i| y0 + i as f64 * self.y_step).collect();
        if y1 - v[v.len() - 1] > 1e-9 * self.y_step {
            v.push(y1);
        }
        v
    }

    /// The pivot `o` of the contract at portal position `y`.
    pub fn pivot(&self, y: f64) -> Point3 {
        Point3::new(0.5 * (self.rail_x[0] + self.rail_x[1]), y, self.rail_height)
    }
}

/// The portal's physical `(pitch, roll)` (rad, right-hand rule about +X and +Y) at position `y`
/// on a bed deflected by `uz` (mm, positive up).
pub fn portal_rotation(uz: impl Fn(f64, f64) -> f64, portal: &Portal, y: f64) -> (f64, f64) {
    let h = 0.5 * portal.bearing_span;
    let [x1, x2] = portal.rail_x;
    let (b1, f1) = (uz(x1, y - h), uz(x1, y + h));
    let (b2, f2) = (uz(x2, y - h), uz(x2, y + h));
    let pitch = 0.5 * ((f1 - b1) + (f2 - b2)) / portal.bearing_span;
    let roll = (0.5 * (b1 + f1) - 0.5 * (b2 + f2)) / (x2 - x1);
    (pitch, roll)
}

/// The load correction of one load case: pitch/roll curves and the pivot geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadCorrection {
    /// Portal pitch and roll along Y under the load.
    pub curves: PortalCurves,
    /// X midway between the rails (the roll pivot), mm.
    pub rail_center_x: f64,
    /// Height of the rails (the pivot), mm.
    pub rail_height: f64,
}

impl LoadCorrection {
    /// The correction for `curves` on the rails and pivot height of `portal`.
    pub fn new(curves: PortalCurves, portal: &Portal) -> Self {
        Self {
            curves,
            rail_center_x: 0.5 * (portal.rail_x[0] + portal.rail_x[1]),
            rail_height: portal.rail_height,
        }
    }

    /// The contract's error `e = (θx, θy, 0) × (p − o)` at indicated point `p` (portal at `p.y`).
    #[inline]
    pub fn error(&self, p: &Point3) -> Result<Vector3, OutOfRange> {
        let (tx, ty) = self.curves.at(p.y)?;
        let dx = p.x - self.rail_center_x;
        let dz = p.z - self.rail_height;
        // (tx, ty, 0) × (dx, 0, dz)
        Ok(Vector3::new(ty * dz, -tx * dz, -ty * dx))
    }

    /// The corrected point `p + e` (the true position of the tip of the tilted portal).
    pub fn correct(&self, p: &Point3) -> Result<Point3, OutOfRange> {
        Ok(p + self.error(p)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn portal() -> Portal {
        Portal {
            rail_x: [0.0, 2000.0],
            rail_height: 100.0,
            bearing_span: 400.0,
            y_range: [200.0, 1800.0],
            y_step: 300.0,
        }
    }

    #[test]
    fn positions_end_at_the_range() {
        assert_eq!(portal().positions(), vec![200.0, 500.0, 800.0, 1100.0, 1400.0, 1700.0, 1800.0]);
        let p = Portal { y_step: 400.0, ..portal() };
        assert_eq!(p.positions(), vec![200.0, 600.0, 1000.0, 1400.0, 1800.0]);
        assert!(Portal { rail_x: [5.0, 5.0], ..portal() }.validate().is_err());
    }

    #[test]
    fn tilted_bed_gives_exact_rotation_and_correction_undoes_it() {
        // A bed that tilts rigidly: uz = a·x + b·y. The portal follows: physical tilt about +X is
        // α = b (front higher), about +Y is β = −a (+X side higher turns +X towards +Z, a
        // negative rotation about +Y by the right-hand rule). Pitch, roll = (b, −a).
        let (a, b) = (3e-6, -5e-6);
        let (pitch, roll) = portal_rotation(|x, y| a * x + b * y, &portal(), 900.0);
        assert!((pitch - b).abs() < 1e-18 && (roll + a).abs() < 1e-18, "{pitch} {roll}");
        // The tip of the physically tilted portal: p_true = o + R(α, β)(p − o) (exact rotation).
        let pr = portal();
        let curves = PortalCurves::new(vec![0.0, 2000.0], vec![pitch; 2], vec![roll; 2]).unwrap();
        let lc = LoadCorrection::new(curves, &pr);
        let p = Point3::new(1700.0, 900.0, 650.0);
        let o = pr.pivot(p.y);
        let rot = nalgebra::Rotation3::new(Vector3::new(b, -a, 0.0));
        let truth = o + rot * (p - o);
        let corrected = lc.correct(&p).unwrap();
        // Residual is second order: |θ|²·|p − o| ≈ 3.4e-11·1000 mm ≈ 3e-8 mm.
        assert!((corrected - truth).norm() < 1e-7, "{}", (corrected - truth).norm());
        assert!((p - truth).norm() > 1e-3, "the test must have a visible error");
    }

    /// An independent hand calculation of the contract: rails at x = 0 and 2000, height 100,
    /// portal at y = 900, so o = (1000, 900, 100). Pitch −5 µrad, roll −3 µrad (physical).
    /// p = (1700, 900, 650): p − o = (700, 0, 550).
    /// e = (θx, θy, 0) × (dx, dy, dz) = (θy·dz − 0·dy, 0·dx − θx·dz, θx·dy − θy·dx)
    ///   = (−3e-6·550, 5e-6·550, 0 + 3e-6·700) = (−0.00165, 0.00275, 0.0021) mm,
    /// corrected = p + e = (1699.99835, 900.00275, 650.0021).
    #[test]
    fn correction_matches_a_hand_calculation() {
        let curves = PortalCurves::new(vec![0.0, 2000.0], vec![-5e-6; 2], vec![-3e-6; 2]).unwrap();
        let lc = LoadCorrection::new(curves, &portal());
        let c = lc.correct(&Point3::new(1700.0, 900.0, 650.0)).unwrap();
        let want = Point3::new(1699.99835, 900.00275, 650.0021);
        // Decimal inputs, a few operations: agreement to 1e-9 mm.
        assert!((c - want).norm() < 1e-9, "{c} vs {want}");
    }
}
