//! The 21-parameter geometric error map (ISO 230-1 rigid-body model) and its first-order
//! volumetric error, as fixed in `docs/conventions.md`.
//!
//! Entry points: [`AxisTable`] (one axis's six component errors against position), [`Squareness`],
//! [`GeometricMap`] with [`GeometricMap::error`] (`E(p; t) = actual − nominal`).
//!
//! ## Components and rotation axes
//!
//! All components are errors of motion (actual − nominal) of the carriage, mm and rad here
//! (µm and µrad in files). Linear errors `pos`, `str1`, `str2` are along the axis itself and the
//! next two axes in x→y→z→x order. Angular errors are small rotations (right-hand rule) about the
//! machine axes:
//!
//! | axis | pos | str1 | str2 | roll | pitch | yaw |
//! |---|---|---|---|---|---|---|
//! | X | δx | δy | δz | about X | about Y | about Z |
//! | Y | δy | δz | δx | about Y | about X | about Z |
//! | Z | δz | δx | δy | about Z | about X | about Y |
//!
//! Squareness (positive = the angle between the two positive axes is smaller than 90°), carried
//! by the moving axis: `xy` adds `(0, xy·x, 0)`, `xz` adds `(xz·z, 0, 0)`, `yz` adds `(0, yz·z, 0)`.
//!
//! ## First-order model
//!
//! Bridge CMM, chain bed → Y → X → Z → tool (the default):
//! `E = δY + εY × (x_vec + z_vec + t) + δX + εX × (z_vec + t) + δZ + εZ × t + squareness`,
//! with `x_vec = (x,0,0)`, `z_vec = (0,0,z)` and `t` the probe offset in the ram frame.
//! Large gantry, chain bed → X → Y → Z: the same with the roles of X and Y swapped
//! (`E = δX + εX × (y_vec + z_vec + t) + δY + εY × (z_vec + t) + δZ + εZ × t + squareness`).
//!
//! Tables are interpolated piecewise-linearly (continuous, no overshoot between calibration
//! positions, exact at them — what a laser-interferometer map supports; a spline would invent
//! curvature the data does not have). Outside a table's range the map either refuses
//! ([`OutOfRange`]) or, with `clamp`, holds the end values.

use crate::grid1::{Grid1, GridError};
pub use truepos_math::types::Axis;
use truepos_math::{Point3, Vector3};

/// The six component errors of one axis at one position, in the axis's own naming (mm, rad).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AxisErrors {
    pub pos: f64,
    pub str1: f64,
    pub str2: f64,
    pub pitch: f64,
    pub yaw: f64,
    pub roll: f64,
}

impl AxisErrors {
    /// Linear error vector `δ` and rotation vector `ε` in machine X, Y, Z.
    pub fn to_machine(&self, axis: Axis) -> ([f64; 3], [f64; 3]) {
        match axis {
            Axis::X => ([self.pos, self.str1, self.str2], [self.roll, self.pitch, self.yaw]),
            Axis::Y => ([self.str2, self.pos, self.str1], [self.pitch, self.roll, self.yaw]),
            Axis::Z => ([self.str1, self.str2, self.pos], [self.pitch, self.yaw, self.roll]),
        }
    }
}

/// Errors of the map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    #[error("axis {axis}: {source}")]
    Grid { axis: &'static str, source: GridError },
    #[error("axis {axis}: {positions} positions but {values} error rows")]
    Length { axis: &'static str, positions: usize, values: usize },
    #[error("axis {axis}: a component error is not finite at position {position} mm")]
    NotFinite { axis: &'static str, position: f64 },
}

/// A position outside the range a table covers.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("{what} = {value} mm is outside the mapped range [{min}, {max}] mm")]
pub struct OutOfRange {
    pub what: &'static str,
    pub value: f64,
    pub min: f64,
    pub max: f64,
}

/// One axis's error table: positions and, per position, `[δx, δy, δz, εx, εy, εz]` in machine
/// coordinates (mm, rad).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisTable {
    pub axis: Axis,
    grid: Grid1,
    nodes: Vec<[f64; 6]>,
}

impl AxisTable {
    /// A table from strictly increasing positions (mm) and the component errors there.
    pub fn new(axis: Axis, positions: Vec<f64>, errors: &[AxisErrors]) -> Result<Self, MapError> {
        if positions.len() != errors.len() {
            return Err(MapError::Length {
                axis: axis.name(),
                positions: positions.len(),
                values: errors.len(),
            });
        }
        let mut nodes = Vec::with_capacity(errors.len());
        for (p, e) in positions.iter().zip(errors) {
            let (d, r) = e.to_machine(axis);
            let n = [d[0], d[1], d[2], r[0], r[1], r[2]];
            if n.iter().any(|v| !v.is_finite()) {
                return Err(MapError::NotFinite { axis: axis.name(), position: *p });
            }
            nodes.push(n);
        }
        let grid = Grid1::new(positions).map_err(|source| MapError::Grid { axis: axis.name(), source })?;
        Ok(Self { axis, grid, nodes })
    }

    pub fn positions(&self) -> &[f64] {
        self.grid.values()
    }
    pub fn is_uniform(&self) -> bool {
        self.grid.is_uniform()
    }

    /// `(δ, ε)` in machine coordinates at position `a`, linearly interpolated.
    #[inline]
    pub fn at(&self, a: f64, clamp: bool) -> Result<(Vector3, Vector3), OutOfRange> {
        let (i, f) = self.grid.locate(a, clamp).ok_or(OutOfRange {
            what: self.axis.name(),
            value: a,
            min: self.grid.first(),
            max: self.grid.last(),
        })?;
        let n0 = &self.nodes[i];
        let n1 = self.nodes.get(i + 1).unwrap_or(n0);
        let l = |k: usize| n0[k] + f * (n1[k] - n0[k]);
        Ok((Vector3::new(l(0), l(1), l(2)), Vector3::new(l(3), l(4), l(5))))
    }
}

/// The three squareness errors (rad). Positive: the angle between the positive axes is < 90°.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Squareness {
    pub xy: f64,
    pub xz: f64,
    pub yz: f64,
}

/// Kinematic chain of the machine (which axis carries which).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Chain {
    /// Bridge CMM: bed → Y → X → Z → tool.
    #[default]
    BridgeYXZ,
    /// Large gantry: bed → X → Y → Z → tool.
    GantryXYZ,
}

/// The 21-parameter map. A missing axis table means that axis has no errors (any position).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GeometricMap {
    pub x: Option<AxisTable>,
    pub y: Option<AxisTable>,
    pub z: Option<AxisTable>,
    pub squareness: Squareness,
    pub chain: Chain,
    /// Hold end values outside a table's range instead of refusing.
    pub clamp: bool,
}

#[inline]
fn axis_at(t: &Option<AxisTable>, a: f64, clamp: bool) -> Result<(Vector3, Vector3), OutOfRange> {
    match t {
        Some(t) => t.at(a, clamp),
        None => Ok((Vector3::zeros(), Vector3::zeros())),
    }
}

impl GeometricMap {
    /// First-order volumetric error `E(p; t) = actual − nominal` (mm) at nominal (indicated)
    /// position `p` with probe offset `t` (ram frame, mm).
    #[inline]
    pub fn error(&self, p: &Point3, t: &Vector3) -> Result<Vector3, OutOfRange> {
        let (dx, ex) = axis_at(&self.x, p.x, self.clamp)?;
        let (dy, ey) = axis_at(&self.y, p.y, self.clamp)?;
        let (dz, ez) = axis_at(&self.z, p.z, self.clamp)?;
        let xv = Vector3::new(p.x, 0.0, 0.0);
        let yv = Vector3::new(0.0, p.y, 0.0);
        let zt = Vector3::new(0.0, 0.0, p.z) + t;
        let s = &self.squareness;
        let sq = Vector3::new(s.xz * p.z, s.xy * p.x + s.yz * p.z, 0.0);
        let chain = match self.chain {
            Chain::BridgeYXZ => dy + ey.cross(&(xv + zt)) + dx + ex.cross(&zt),
            Chain::GantryXYZ => dx + ex.cross(&(yv + zt)) + dy + ey.cross(&zt),
        };
        Ok(chain + dz + ez.cross(t) + sq)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(axis: Axis, f: impl Fn(f64) -> AxisErrors) -> AxisTable {
        let pos: Vec<f64> = (0..=10).map(|i| 100.0 * i as f64).collect();
        let e: Vec<AxisErrors> = pos.iter().map(|&p| f(p)).collect();
        AxisTable::new(axis, pos, &e).unwrap()
    }

    #[test]
    fn component_naming_maps_to_machine_axes() {
        // One non-zero component at a time: each must land on the documented machine axis.
        let e = AxisErrors { pos: 1.0, str1: 2.0, str2: 3.0, pitch: 4.0, yaw: 5.0, roll: 6.0 };
        assert_eq!(e.to_machine(Axis::X), ([1.0, 2.0, 3.0], [6.0, 4.0, 5.0]));
        assert_eq!(e.to_machine(Axis::Y), ([3.0, 1.0, 2.0], [4.0, 6.0, 5.0]));
        assert_eq!(e.to_machine(Axis::Z), ([2.0, 3.0, 1.0], [4.0, 5.0, 6.0]));
    }

    #[test]
    fn hand_computed_abbe_terms() {
        // Y pitch (about X) of 10 µrad at y = 500 with the tip at z = 300 and offset t = (0,0,-100):
        // εY × (x_vec + z_vec + t) = (1e-5,0,0) × (x, 0, 200) = (0, -2e-3, 0) mm (independent of x).
        let map = GeometricMap {
            y: Some(table(Axis::Y, |_| AxisErrors { pitch: 10e-6, ..Default::default() })),
            ..Default::default()
        };
        let e = map.error(&Point3::new(250.0, 500.0, 300.0), &Vector3::new(0.0, 0.0, -100.0)).unwrap();
        assert!((e - Vector3::new(0.0, -2e-3, 0.0)).norm() < 1e-15, "{e}");
        // X yaw (about Z) 5 µrad carried by X: εX × (z_vec + t) with t = (20, 0, 0): (0, 1e-4, 0).
        let map = GeometricMap {
            x: Some(table(Axis::X, |_| AxisErrors { yaw: 5e-6, ..Default::default() })),
            ..Default::default()
        };
        let e = map.error(&Point3::new(250.0, 500.0, 300.0), &Vector3::new(20.0, 0.0, 0.0)).unwrap();
        assert!((e - Vector3::new(0.0, 1e-4, 0.0)).norm() < 1e-15, "{e}");
        // Squareness xy = 2 µrad at x = 400: +0.8 µm in y.
        let map =
            GeometricMap { squareness: Squareness { xy: 2e-6, ..Default::default() }, ..Default::default() };
        let e = map.error(&Point3::new(400.0, 0.0, 0.0), &Vector3::zeros()).unwrap();
        assert!((e.y - 0.8e-3).abs() < 1e-15);
    }

    #[test]
    fn interpolation_is_linear_and_range_checked() {
        let t = table(Axis::X, |p| AxisErrors { pos: 1e-6 * p * p, ..Default::default() });
        let (d, _) = t.at(150.0, false).unwrap();
        // Linear between 100 (0.01) and 200 (0.04): 0.025.
        assert!((d.x - 0.025).abs() < 1e-15);
        assert!(t.at(1000.5, false).is_err());
        assert_eq!(t.at(1000.5, true).unwrap().0.x, 1.0);
        assert!(AxisTable::new(Axis::Y, vec![0.0, 1.0], &[AxisErrors::default()]).is_err());
        assert!(AxisTable::new(Axis::Y, vec![0.0], &[AxisErrors { pos: f64::NAN, ..Default::default() }])
            .is_err());
    }
}
