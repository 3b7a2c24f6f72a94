//! The `load` scenario: a bridge CMM whose granite bed carries a heavy die.
//!
//! Entry points: [`LoadConfig`] (bed, portal, part, measurement; [`Default`] is the 2,000 kg
//! die on three pads) and [`simulate`] → [`LoadData`] (indicated points with noise and the
//! truth).
//!
//! Physics (independent of `truepos-comp`, which must undo it):
//! - the die's weight goes to its three pads by exact statics (forces and moments balance);
//! - the bed deflects as a Mindlin plate on its support pads (`truepos-fe`), meshed FINER than a
//!   compensation map would be (`sim_element_size`), so the correction is not checked against
//!   its own discretisation;
//! - the die rests rigidly on the deflected pads: its measured features move with the plane
//!   through the three pad deflections (this is where the part really is: truth);
//! - the portal rides on bearings `bearing_span` apart along Y on both rails; rigid, it takes
//!   the mean tilt of its four bearings: about +X `α = (ū_front − ū_back)/span` (front = +Y),
//!   about +Y `β = −(ū_rail2 − ū_rail1)/(x2 − x1)`, about the pivot
//!   `o = ((x1+x2)/2, y, rail_height)`. Its scales are unchanged, so when the machine indicates
//!   `p` the tip is exactly at `o + R(α, β)·(p − o)` (finite rotation);
//! - the indicated coordinates of each true point are found by inverting that relation
//!   (fixed-point, to 1e-12 mm), then probing noise (Gaussian, `noise_sigma` per axis) is added.
//!
//! The portal's common vertical sink (mean of its bearing deflections) is reported in the truth
//! (`portal_sink`) but not applied to the points: the contract's load model corrects pitch and
//! roll only, and this scenario tests that model.

use crate::noise::{gaussian3, stream};
use serde::Serialize;
use truepos_fe::{Bed, FeError, MeshOptions, PlateModel, Supports};
use truepos_math::{Point3, Rotation3, Vector3};

/// Everything that defines the scenario (mm, N, kg, MPa).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadConfig {
    /// The bed plate on its supports.
    pub bed: Bed,
    /// X of the two rails, mm.
    pub rail_x: [f64; 2],
    /// Height of the rails above the bed, mm.
    pub rail_height: f64,
    /// Distance between a carriage's bearings along Y, mm.
    pub bearing_span: f64,
    /// The portal's travel in Y (start, end), mm.
    pub y_range: [f64; 2],
    /// Step of the portal positions in Y, mm.
    pub y_step: f64,
    /// Spacing of the unit-load grid, mm.
    pub grid_spacing: f64,
    /// Unit load of the influence map, N.
    pub unit_load_n: f64,
    /// Element size the compensation map should use (written to bed.toml).
    pub map_element_size: f64,
    /// Element size of the simulator's own (truth) model: finer.
    pub sim_element_size: f64,
    /// Mass of the load, kg.
    pub mass_kg: f64,
    /// Centre of gravity (x, y), mm.
    pub cog: [f64; 2],
    /// Exactly three pads.
    pub rests: [[f64; 2]; 3],
    /// Measured points on the die, design coordinates before the bed deflects.
    pub design_points: Vec<Point3>,
    /// Probing noise, standard deviation per axis (mm).
    pub noise_sigma: f64,
}

/// Standard gravity (m/s²) for mass → weight.
pub const G: f64 = 9.80665;

impl Default for LoadConfig {
    fn default() -> Self {
        // Granite table 2,500 × 1,600 × 200 mm on four pads; rails near the long edges on raised
        // guideways (50 mm); portal bearings 400 mm apart. A 2,000 kg die on three pads,
        // off-centre, measured on a 9 × 7 grid at two heights (its top and a step).
        let mut pts = Vec::new();
        for &z in &[600.0, 250.0] {
            for j in 0..7 {
                for i in 0..9 {
                    pts.push(Point3::new(850.0 + 110.0 * i as f64, 480.0 + 110.0 * j as f64, z));
                }
            }
        }
        Self {
            bed: Bed {
                size_x: 2500.0,
                size_y: 1600.0,
                thickness: 200.0,
                youngs_modulus: 50_000.0,
                poisson: 0.2,
                supports: Supports::Points {
                    xy: vec![[350.0, 250.0], [2150.0, 250.0], [2150.0, 1350.0], [350.0, 1350.0]],
                    stiffness_n_per_mm: None,
                },
            },
            rail_x: [100.0, 2400.0],
            rail_height: 50.0,
            bearing_span: 400.0,
            y_range: [250.0, 1350.0],
            y_step: 50.0,
            grid_spacing: 100.0,
            unit_load_n: 1000.0,
            map_element_size: 25.0,
            sim_element_size: 12.5,
            mass_kg: 2000.0,
            cog: [1260.0, 760.0],
            rests: [[850.0, 450.0], [1750.0, 520.0], [1200.0, 1180.0]],
            design_points: pts,
            noise_sigma: 0.3e-3,
        }
    }
}

/// Why the scenario cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LoadScenarioError {
    /// The plate model failed.
    #[error("plate model: {0}")]
    Fe(#[from] FeError),
    /// The pads cannot carry the load (the forces, N).
    #[error("the three pads are collinear or the centre of gravity is outside them (forces {0:?} N)")]
    Statics([f64; 3]),
    /// A point is off the bed or outside the portal travel (which).
    #[error("a bearing or measured point is off the bed / outside the portal travel: {0}")]
    Geometry(String),
}

/// The scenario's output: what a CMM would report, and the truth.
#[derive(Debug, Clone, Serialize)]
pub struct LoadData {
    /// Weight of the load, N.
    pub weight_n: f64,
    /// Forces on the three pads (N, downwards).
    pub forces_n: [f64; 3],
    /// Where the measured points really are (on the deflected bed).
    pub true_points: Vec<Point3>,
    /// Indicated coordinates without noise.
    pub indicated_exact: Vec<Point3>,
    /// Indicated coordinates as measured (with noise): the points file.
    pub indicated: Vec<Point3>,
    /// Portal positions (mm) and the portal's pitch/roll there (rad): its physical rotations
    /// about +X and +Y (right-hand rule), the contract's sign.
    pub portal_y: Vec<f64>,
    /// Portal pitch at each position, rad.
    pub pitch: Vec<f64>,
    /// Portal roll at each position, rad.
    pub roll: Vec<f64>,
    /// Mean deflection of the portal's four bearings (mm, positive up), not applied.
    pub portal_sink: Vec<f64>,
    /// Deflection of the bed on a grid (for plots): `uz[j][i]` at (`grid_x[i]`, `grid_y[j]`).
    pub grid_x: Vec<f64>,
    /// Y of the grid rows, mm.
    pub grid_y: Vec<f64>,
    /// Bed deflection on the grid, mm, positive up.
    pub uz: Vec<Vec<f64>>,
    /// Deflection under each pad (mm).
    pub rest_uz: [f64; 3],
}

/// Exact statics of three pads: `[1 1 1; x; y] F = W [1; cx; cy]`.
pub fn three_pad_forces(weight: f64, cog: [f64; 2], r: &[[f64; 2]; 3]) -> Option<[f64; 3]> {
    let m = nalgebra::Matrix3::new(1.0, 1.0, 1.0, r[0][0], r[1][0], r[2][0], r[0][1], r[1][1], r[2][1]);
    let f = m.lu().solve(&nalgebra::Vector3::new(weight, weight * cog[0], weight * cog[1]))?;
    Some([f[0], f[1], f[2]])
}

/// Physical tilt `(α, β)` (rad) and mean sink of the portal at `y` on the deflection `uz`.
fn portal_tilt(uz: &dyn Fn(f64, f64) -> f64, c: &LoadConfig, y: f64) -> (f64, f64, f64) {
    let h = 0.5 * c.bearing_span;
    let [x1, x2] = c.rail_x;
    let (b1, f1, b2, f2) = (uz(x1, y - h), uz(x1, y + h), uz(x2, y - h), uz(x2, y + h));
    let alpha = 0.5 * ((f1 - b1) + (f2 - b2)) / c.bearing_span;
    let beta = -(0.5 * (b2 + f2) - 0.5 * (b1 + f1)) / (x2 - x1);
    (alpha, beta, 0.25 * (b1 + f1 + b2 + f2))
}

/// Build the data set.
pub fn simulate(c: &LoadConfig, seed: u64) -> Result<LoadData, LoadScenarioError> {
    let weight = c.mass_kg * G;
    let forces = three_pad_forces(weight, c.cog, &c.rests)
        .filter(|f| f.iter().all(|v| *v > 0.0))
        .ok_or(LoadScenarioError::Statics([f64::NAN; 3]))?;
    let plate = PlateModel::new(&c.bed, &MeshOptions::with_element_size(c.sim_element_size))?;
    let loads: Vec<(f64, f64, f64)> = c.rests.iter().zip(forces).map(|(r, f)| (r[0], r[1], f)).collect();
    let d = plate.solve(&loads)?;
    let uz = |x: f64, y: f64| d.uz(x, y);
    let h = 0.5 * c.bearing_span;
    if c.y_range[0] - h < 0.0 || c.y_range[1] + h > c.bed.size_y {
        return Err(LoadScenarioError::Geometry("bearings leave the bed".into()));
    }
    // The die rests rigidly on its pads: plane w = c0 + c1 x + c2 y through the pad deflections.
    let rest_uz = [
        uz(c.rests[0][0], c.rests[0][1]),
        uz(c.rests[1][0], c.rests[1][1]),
        uz(c.rests[2][0], c.rests[2][1]),
    ];
    let m = nalgebra::Matrix3::new(
        1.0,
        c.rests[0][0],
        c.rests[0][1],
        1.0,
        c.rests[1][0],
        c.rests[1][1],
        1.0,
        c.rests[2][0],
        c.rests[2][1],
    );
    let w = m.lu().solve(&nalgebra::Vector3::from(rest_uz)).ok_or(LoadScenarioError::Statics(forces))?;
    let true_points: Vec<Point3> = c
        .design_points
        .iter()
        .map(|p| {
            // Small rigid rotation (c2 about +X, −c1 about +Y) about the pad plane z = 0, plus sink.
            p + Vector3::new(-w[1] * p.z, -w[2] * p.z, w[0] + w[1] * p.x + w[2] * p.y)
        })
        .collect();
    let pivot = |y: f64| Point3::new(0.5 * (c.rail_x[0] + c.rail_x[1]), y, c.rail_height);
    let mut indicated_exact = Vec::with_capacity(true_points.len());
    for t in &true_points {
        if !(c.y_range[0]..=c.y_range[1]).contains(&t.y) {
            return Err(LoadScenarioError::Geometry(format!(
                "point y = {} mm outside the portal travel",
                t.y
            )));
        }
        // Tip = o + R (p − o)  ⇒  p = o + Rᵀ (tip − o), with o and R at the portal position p.y.
        let mut p = *t;
        for _ in 0..100 {
            let (a, b, _) = portal_tilt(&uz, c, p.y);
            let o = pivot(p.y);
            let r = Rotation3::new(Vector3::new(a, b, 0.0));
            let next = o + r.inverse() * (t - o);
            let step = (next - p).norm();
            p = next;
            if step < 1e-12 {
                break;
            }
        }
        indicated_exact.push(p);
    }
    let mut rng = stream(seed, 31);
    let indicated = indicated_exact.iter().map(|p| p + gaussian3(&mut rng, c.noise_sigma)).collect();
    let mut portal_y = Vec::new();
    let mut y = c.y_range[0];
    while y <= c.y_range[1] + 1e-9 {
        portal_y.push(y.min(c.y_range[1]));
        y += c.y_step;
    }
    let (mut pitch, mut roll, mut sink) = (vec![], vec![], vec![]);
    for &y in &portal_y {
        let (a, b, s) = portal_tilt(&uz, c, y);
        pitch.push(a);
        roll.push(b);
        sink.push(s);
    }
    let grid_x: Vec<f64> = (0..=50).map(|i| c.bed.size_x * i as f64 / 50.0).collect();
    let grid_y: Vec<f64> = (0..=32).map(|j| c.bed.size_y * j as f64 / 32.0).collect();
    let uz_grid = grid_y.iter().map(|&y| grid_x.iter().map(|&x| uz(x, y)).collect()).collect();
    Ok(LoadData {
        weight_n: weight,
        forces_n: forces,
        true_points,
        indicated_exact,
        indicated,
        portal_y,
        pitch,
        roll,
        portal_sink: sink,
        grid_x,
        grid_y,
        uz: uz_grid,
        rest_uz,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statics_balance_and_indicated_points_invert_the_tilt() {
        let c = LoadConfig::default();
        let f = three_pad_forces(1000.0, c.cog, &c.rests).unwrap();
        let s: f64 = f.iter().sum();
        let mx: f64 = f.iter().zip(&c.rests).map(|(f, r)| f * (r[0] - c.cog[0])).sum();
        let my: f64 = f.iter().zip(&c.rests).map(|(f, r)| f * (r[1] - c.cog[1])).sum();
        assert!((s - 1000.0).abs() < 1e-9 && mx.abs() < 1e-7 && my.abs() < 1e-7);
        // A coarse truth mesh keeps the test fast; the relations checked hold for any mesh.
        let c = LoadConfig { sim_element_size: 50.0, ..LoadConfig::default() };
        let d = simulate(&c, 3).unwrap();
        let plate = PlateModel::new(&c.bed, &MeshOptions::with_element_size(50.0)).unwrap();
        let loads: Vec<(f64, f64, f64)> =
            c.rests.iter().zip(d.forces_n).map(|(r, f)| (r[0], r[1], f)).collect();
        let defl = plate.solve(&loads).unwrap();
        let uz = |x: f64, y: f64| defl.uz(x, y);
        let mut noise = Vec::new();
        for ((p, t), n) in d.indicated_exact.iter().zip(&d.true_points).zip(&d.indicated) {
            // The tip of the tilted portal at the indicated position is the true point.
            let (a, b, _) = portal_tilt(&uz, &c, p.y);
            let o = Point3::new(0.5 * (c.rail_x[0] + c.rail_x[1]), p.y, c.rail_height);
            let tip = o + Rotation3::new(Vector3::new(a, b, 0.0)) * (p - o);
            assert!((tip - t).norm() < 1e-10, "{}", (tip - t).norm());
            noise.extend((n - p).iter().copied());
        }
        // The die sinks: every true point is below its design position.
        assert!(d.true_points.iter().zip(&c.design_points).all(|(t, p)| t.z < p.z));
        // Probing noise has the configured σ (378 draws: ±15 % is > 4 standard errors).
        let sd = (noise.iter().map(|v| v * v).sum::<f64>() / noise.len() as f64).sqrt();
        assert!((sd / c.noise_sigma - 1.0).abs() < 0.15, "noise σ {sd}");
    }
}
