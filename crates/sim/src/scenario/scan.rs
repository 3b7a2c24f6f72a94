//! The `scan` scenario: a part with bores, bosses, planes and straight edges on the plane to be
//! scanned on the virtual CMM, with its nominal features (what `features.toml` describes) and
//! the true, displaced ones (what the probe meets; written to `truth.json`).
//!
//! Entry point: [`scenario`] (`seed`, number of features). Every feature is displaced a little
//! from nominal (manufacturing scatter: centres ~N(0, 30 µm), radii ~N(0, 10 µm), planes
//! ~N(0, 20 µm)); every fifth feature is displaced by 1.2–1.8 mm along its surface normal, in
//! alternating directions, so that both missed-surface cases (surface before and beyond the
//! nominal contact point) occur.

use crate::noise;
use truepos_math::{Point3, Vector3};

/// Which surface a circle scan runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScanSide {
    /// The inside of a bore.
    Inside,
    /// The outside of a boss.
    Outside,
    /// A plane face.
    Plane,
}

impl ScanSide {
    /// The side as `features.toml` spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            ScanSide::Inside => "inside",
            ScanSide::Outside => "outside",
            ScanSide::Plane => "plane",
        }
    }
}

/// A feature's geometry in the terms of `features.toml` (mm, degrees).
#[derive(Clone, Debug, PartialEq)]
pub enum ScanGeometry {
    /// A circular arc.
    Circle {
        /// Centre, mm.
        center: Point3,
        /// Unit axis.
        axis: Vector3,
        /// Radius, mm.
        radius: f64,
        /// Which surface.
        side: ScanSide,
        /// Start angle, degrees.
        start_deg: f64,
        /// Signed sweep, degrees.
        sweep_deg: f64,
    },
    /// A straight line on a surface.
    Line {
        /// Start, mm.
        start: Point3,
        /// End, mm.
        end: Point3,
        /// Unit outward surface normal.
        normal: Vector3,
    },
}

/// One feature: nominal and true geometry.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanFeature {
    /// The feature's id.
    pub id: String,
    /// Nominal geometry (the features file).
    pub nominal: ScanGeometry,
    /// True geometry (the machine's part).
    pub actual: ScanGeometry,
    /// Displacement of the true surface along the outward normal at the scan start (mm; +:
    /// the surface lies before the nominal contact point).
    pub normal_offset_mm: f64,
}

/// The data set.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanScenario {
    /// The features.
    pub features: Vec<ScanFeature>,
    /// Approach angle, degrees.
    pub approach_angle_deg: f64,
    /// Scanning speed, mm/s.
    pub scan_speed_mm_s: f64,
    /// Transfer speed, mm/s.
    pub move_speed_mm_s: f64,
    /// Target deflection, mm.
    pub deflection_mm: f64,
    /// Settle overshoot, mm.
    pub overshoot_mm: f64,
    /// The two quality bands, mm.
    pub quality_bands_mm: [f64; 2],
}

/// Build the part: `n` features on a 60 mm grid, cycling bore, boss, circle on the top plane,
/// line on the top plane.
pub fn scenario(seed: u64, n: usize) -> ScanScenario {
    let mut rng = noise::stream(seed, 0x5ca7);
    let mut features = Vec::with_capacity(n);
    for k in 0..n {
        let (gx, gy) = ((k % 8) as f64, (k / 8) as f64);
        let c = Point3::new(60.0 + 60.0 * gx, 60.0 + 60.0 * gy, 0.0);
        let big = if k % 5 == 4 {
            let mag = noise::uniform(&mut rng, 1.2, 1.8);
            if (k / 5) % 2 == 0 {
                mag
            } else {
                -mag
            }
        } else {
            0.0
        };
        let dc = Vector3::new(noise::gaussian(&mut rng, 0.03), noise::gaussian(&mut rng, 0.03), 0.0);
        let dr = noise::gaussian(&mut rng, 0.01);
        let dz = noise::gaussian(&mut rng, 0.02);
        let start_deg = noise::uniform(&mut rng, 0.0, 360.0).round();
        let z = Vector3::z();
        let (id, nominal, actual, off) = match k % 4 {
            0 => {
                let r = 8.0 + (k % 3) as f64 * 2.0;
                let nom = ScanGeometry::Circle {
                    center: c + Vector3::new(0.0, 0.0, -5.0),
                    axis: z,
                    radius: r,
                    side: ScanSide::Inside,
                    start_deg,
                    sweep_deg: 360.0,
                };
                // a bore: the surface is before the nominal point when the radius is smaller
                let ra = r + dr - big;
                let act = ScanGeometry::Circle {
                    center: c + Vector3::new(0.0, 0.0, -5.0) + dc,
                    axis: z,
                    radius: ra,
                    side: ScanSide::Inside,
                    start_deg,
                    sweep_deg: 360.0,
                };
                (format!("bore{k}"), nom, act, big)
            }
            1 => {
                let r = 10.0 + (k % 3) as f64 * 2.5;
                let nom = ScanGeometry::Circle {
                    center: c + Vector3::new(0.0, 0.0, 8.0),
                    axis: z,
                    radius: r,
                    side: ScanSide::Outside,
                    start_deg,
                    sweep_deg: 360.0,
                };
                let act = ScanGeometry::Circle {
                    center: c + Vector3::new(0.0, 0.0, 8.0) + dc,
                    axis: z,
                    radius: r + dr + big,
                    side: ScanSide::Outside,
                    start_deg,
                    sweep_deg: 360.0,
                };
                (format!("boss{k}"), nom, act, big)
            }
            2 => {
                let r = 12.0;
                let nom = ScanGeometry::Circle {
                    center: c,
                    axis: z,
                    radius: r,
                    side: ScanSide::Plane,
                    start_deg,
                    sweep_deg: -270.0,
                };
                let act = ScanGeometry::Circle {
                    center: c + z * (dz + big),
                    axis: z,
                    radius: r,
                    side: ScanSide::Plane,
                    start_deg,
                    sweep_deg: -270.0,
                };
                (format!("face{k}"), nom, act, dz + big)
            }
            _ => {
                let a = start_deg.to_radians();
                let d = Vector3::new(a.cos(), a.sin(), 0.0) * 20.0;
                let nom = ScanGeometry::Line { start: c - d, end: c + d, normal: z };
                let act = ScanGeometry::Line {
                    start: c - d + z * (dz + big),
                    end: c + d + z * (dz + big),
                    normal: z,
                };
                (format!("line{k}"), nom, act, dz + big)
            }
        };
        features.push(ScanFeature { id, nominal, actual, normal_offset_mm: off });
    }
    ScanScenario {
        features,
        approach_angle_deg: 45.0,
        scan_speed_mm_s: 40.0,
        move_speed_mm_s: 200.0,
        deflection_mm: 0.3,
        overshoot_mm: 0.1,
        quality_bands_mm: [0.02, 0.05],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_displaced_both_ways() {
        let a = scenario(3, 20);
        assert_eq!(a, scenario(3, 20));
        assert_ne!(a, scenario(4, 20));
        // every fifth feature is displaced by 1.2–1.8 mm, alternating sign
        let big: Vec<f64> = a.features.iter().map(|f| f.normal_offset_mm).filter(|o| o.abs() > 1.0).collect();
        assert_eq!(big.len(), 4);
        assert!(big.iter().any(|&o| o > 1.19) && big.iter().any(|&o| o < -1.19));
        assert!(big.iter().all(|o| (1.2..=1.8 + 0.1).contains(&o.abs())));
    }
}
