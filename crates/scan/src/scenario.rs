//! Bridge from the virtual cell's `scan` scenario (`truepos_sim::scenario::scan`) to this
//! crate's features and parameters, for tests, benches and the demo.
//!
//! Entry points: [`feature`] (one geometry), [`program`] (nominal features, true features and
//! parameters of a scenario).

use crate::feature::{Feature, Geometry, Params, Side};
use truepos_sim::scenario::scan::{ScanGeometry, ScanScenario, ScanSide};

/// A scenario geometry as a [`Feature`] (degrees → radians).
pub fn feature(id: &str, g: &ScanGeometry) -> Feature {
    let geometry = match g {
        ScanGeometry::Circle { center, axis, radius, side, start_deg, sweep_deg } => Geometry::Circle {
            center: *center,
            axis: *axis,
            radius: *radius,
            side: match side {
                ScanSide::Inside => Side::Inside,
                ScanSide::Outside => Side::Outside,
                ScanSide::Plane => Side::Plane,
            },
            start: start_deg.to_radians(),
            sweep: sweep_deg.to_radians(),
        },
        ScanGeometry::Line { start, end, normal } => {
            Geometry::Line { start: *start, end: *end, normal: *normal }
        }
    };
    Feature { id: id.to_string(), geometry }
}

/// (nominal features, true features, parameters) of a scenario.
pub fn program(s: &ScanScenario) -> (Vec<Feature>, Vec<Feature>, Params) {
    let nominal = s.features.iter().map(|f| feature(&f.id, &f.nominal)).collect();
    let truth = s.features.iter().map(|f| feature(&f.id, &f.actual)).collect();
    let params = Params {
        approach_angle: s.approach_angle_deg.to_radians(),
        scan_speed: s.scan_speed_mm_s,
        move_speed: s.move_speed_mm_s,
        deflection: s.deflection_mm,
        overshoot: s.overshoot_mm,
        quality_bands: s.quality_bands_mm,
        ..Params::default()
    };
    (nominal, truth, params)
}
