//! Influence maps from the plate finite-element model of `truepos-fe`.
//!
//! Entry points: [`BedModel`] (bed, portal, load grid), [`load_grid`] (the unit-load nodes),
//! [`influence_map`] (one FE solve per unit load, all with one factorisation, in parallel),
//! [`deflection_at`] (the bed deflection of a load case at given points).
//!
//! For every unit load on the grid the plate is solved and the portal's pitch and roll are read
//! at each portal position with [`crate::load::portal_rotation`] (deflection difference across
//! the bearing span along Y per rail, averaged, and the difference between the rails over their
//! spacing; sign convention in [`crate::load`]).

use crate::influence::{InfluenceError, InfluenceMap};
use crate::load::{portal_rotation, Portal, PortalError};
use truepos_fe::{Bed, FeError, MeshOptions, PlateModel};

/// The unit-load grid: nodes `spacing` apart from the bed corner, over the whole bed (the far
/// edges are added when the size is not a multiple of the spacing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadGrid {
    /// Distance between load nodes, mm.
    pub spacing: f64,
    /// The unit load applied at each node, N.
    pub unit_load_n: f64,
}

impl Default for LoadGrid {
    fn default() -> Self {
        Self { spacing: 100.0, unit_load_n: 1000.0 }
    }
}

/// A bed on its supports with the portal's rails on it.
#[derive(Debug, Clone, PartialEq)]
pub struct BedModel {
    /// The bed plate on its supports.
    pub bed: Bed,
    /// The portal and its rails.
    pub portal: Portal,
    /// The unit-load grid.
    pub grid: LoadGrid,
}

/// Errors of the FE influence map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeMapError {
    /// The plate model failed.
    #[error("plate model: {0}")]
    Fe(#[from] FeError),
    /// The portal is invalid.
    #[error("portal: {0}")]
    Portal(#[from] PortalError),
    /// The portal's rails are not on the bed (why).
    #[error("the portal does not fit on the bed: {0}")]
    PortalOffBed(String),
    /// The grid's spacing (mm) or unit load (N) is not usable.
    #[error("grid: spacing_mm and unit_load_n must be positive, at most 1,000 nodes per bed side (got {0} mm, {1} N)")]
    Grid(f64, f64),
    /// The influence map could not be built.
    #[error("influence map: {0}")]
    Map(#[from] InfluenceError),
}

/// Grid positions along one bed side.
pub fn grid_positions(size: f64, spacing: f64) -> Vec<f64> {
    let n = (size / spacing + 1e-9).floor() as usize;
    let mut v: Vec<f64> = (0..=n).map(|i| (i as f64 * spacing).min(size)).collect();
    if size - v[v.len() - 1] > 1e-9 * spacing {
        v.push(size);
    }
    v
}

/// The unit-load nodes `(x, y)` of the model, x-major (all y for the first x, …).
pub fn load_grid(model: &BedModel) -> Result<(Vec<f64>, Vec<f64>), FeMapError> {
    let g = model.grid;
    if !(g.spacing.is_finite() && g.spacing > 0.0 && g.unit_load_n.is_finite() && g.unit_load_n > 0.0) {
        return Err(FeMapError::Grid(g.spacing, g.unit_load_n));
    }
    if !(model.bed.size_x.is_finite()
        && model.bed.size_x > 0.0
        && model.bed.size_y.is_finite()
        && model.bed.size_y > 0.0)
    {
        return Err(FeError::InvalidParameter {
            name: "size",
            value: model.bed.size_x.min(model.bed.size_y),
            reason: "must be positive and finite",
        }
        .into());
    }
    // At most 1,000 nodes per side (10⁶ FE solves): a finer grid is a typo, not a map.
    if model.bed.size_x / g.spacing > 1000.0 || model.bed.size_y / g.spacing > 1000.0 {
        return Err(FeMapError::Grid(g.spacing, g.unit_load_n));
    }
    Ok((grid_positions(model.bed.size_x, g.spacing), grid_positions(model.bed.size_y, g.spacing)))
}

/// Check that rails and bearings stay on the bed over the portal's travel.
pub fn check_portal(model: &BedModel) -> Result<(), FeMapError> {
    let p = &model.portal;
    p.validate()?;
    let (sx, sy) = (model.bed.size_x, model.bed.size_y);
    for x in p.rail_x {
        if !(0.0..=sx).contains(&x) {
            return Err(FeMapError::PortalOffBed(format!(
                "rail at x = {x} mm is outside the bed (0..{sx} mm)"
            )));
        }
    }
    let h = 0.5 * p.bearing_span;
    if p.y_range[0] - h < 0.0 || p.y_range[1] + h > sy {
        return Err(FeMapError::PortalOffBed(format!(
            "with the bearings ±{h} mm about the portal position, y_range_mm = [{}, {}] needs the bed to span {}..{} mm in y (it spans 0..{sy} mm)",
            p.y_range[0],
            p.y_range[1],
            p.y_range[0] - h,
            p.y_range[1] + h
        )));
    }
    Ok(())
}

/// The influence map of the model: for each unit load, pitch and roll at every portal position.
/// `progress(k)` is called with the number of load cases done (from any thread).
pub fn influence_map(
    model: &BedModel,
    mesh: &MeshOptions,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<InfluenceMap, FeMapError> {
    check_portal(model)?;
    let (xs, ys) = load_grid(model)?;
    let plate = PlateModel::new(&model.bed, mesh)?;
    let py = model.portal.positions();
    let unit = model.grid.unit_load_n;
    let cases: Vec<[(f64, f64, f64); 1]> =
        xs.iter().flat_map(|&x| ys.iter().map(move |&y| [(x, y, unit)])).collect();
    let np = py.len();
    let mut pitch = Vec::with_capacity(cases.len() * np);
    let mut roll = Vec::with_capacity(cases.len() * np);
    // Batches bound the memory held in deflection fields (one full field per case).
    const BATCH: usize = 64;
    for (b, batch) in cases.chunks(BATCH).enumerate() {
        let defl = plate.solve_many(batch)?;
        for d in &defl {
            for &y in &py {
                let (p, r) = portal_rotation(|x, y| d.uz(x, y), &model.portal, y);
                pitch.push(p);
                roll.push(r);
            }
        }
        progress((b * BATCH + batch.len()).min(cases.len()));
    }
    Ok(InfluenceMap::from_grid(unit, xs, ys, py, pitch, roll)?)
}

/// Deflection `uz` (mm, positive up) at `at` under point loads `(x, y, F)` (F downwards, N).
pub fn deflection_at(
    bed: &Bed,
    mesh: &MeshOptions,
    loads: &[(f64, f64, f64)],
    at: &[[f64; 2]],
) -> Result<Vec<Option<f64>>, FeError> {
    let plate = PlateModel::new(bed, mesh)?;
    let d = plate.solve(loads)?;
    Ok(at.iter().map(|p| d.try_uz(p[0], p[1])).collect())
}
