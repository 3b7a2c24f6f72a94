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
//! ## Uncertainty of the map (first-order propagation)
//!
//! A table may carry the standard uncertainties (k = 1) of its node values
//! ([`AxisTable::with_uncertainty`]), squareness its own ([`GeometricMap::squareness_u`]).
//! [`GeometricMap::error_u`] then also returns the variance of each coordinate of `E`, by linear
//! propagation through the model above with the 21 components independent of each other:
//! - an interpolated component `c(a) = (1 − f)·c_i + f·c_{i+1}` has
//!   `u²(c) = ((1 − f)·u_i + f·u_{i+1})² + u_int²`: the nodes' uncertainties taken as fully
//!   correlated with their neighbours' (what the dominant terms of a laser calibration — the
//!   wavelength, the material temperature, the alignment — are; independent noise would give
//!   `(1 − f)²·u_i² + f²·u_{i+1}²`, up to √2 less mid-interval, so this side is the safe one
//!   and never states less than a node's own `u`), and `u_int = f(1 − f)/2 · κ_i` is the
//!   linear interpolation error of a component of curvature `κ_i/h²` (`κ_i`: the larger second
//!   difference `c_{j−1} − 2c_j + c_{j+1}` of the interval's two ends, less its expected noise
//!   part `u_{j−1}² + 4u_j² + u_{j+1}²` in quadrature). It is zero at the nodes and largest,
//!   `κ/8`, mid-interval. It assumes the table resolves the error (a step of at most a quarter of
//!   the shortest period): a periodic error shorter than that aliases and no table can show it;
//! - a linear component adds its variance to its own coordinate; a rotation `ε` carried with
//!   lever arm `r` (`ε × r`) adds `u²(ε_y)·r_z² + u²(ε_z)·r_y²` to x (and cyclically): the Abbe
//!   terms, with the probe offset in `r`;
//! - squareness adds `u²(xz)·z²` to x and `u²(xy)·x² + u²(yz)·z²` to y.
//!
//! Second-order terms (products of two small errors) are below a nanometre and left out.
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
    /// Positioning error along the axis, mm.
    pub pos: f64,
    /// Straightness in the first perpendicular direction, mm.
    pub str1: f64,
    /// Straightness in the second perpendicular direction, mm.
    pub str2: f64,
    /// Pitch, rad.
    pub pitch: f64,
    /// Yaw, rad.
    pub yaw: f64,
    /// Roll, rad.
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
    /// An axis's positions are not a valid grid.
    #[error("axis {axis}: {source}")]
    Grid {
        /// The axis.
        axis: &'static str,
        /// What is wrong with the positions.
        source: GridError,
    },
    /// An axis has a different number of positions and error rows.
    #[error("axis {axis}: {positions} positions but {values} error rows")]
    Length {
        /// The axis.
        axis: &'static str,
        /// Number of positions.
        positions: usize,
        /// Number of error rows.
        values: usize,
    },
    /// A component error is not finite.
    #[error("axis {axis}: a component error is not finite at position {position} mm")]
    NotFinite {
        /// The axis.
        axis: &'static str,
        /// The position, mm.
        position: f64,
    },
    /// A standard uncertainty is negative or not finite.
    #[error("axis {axis}: a standard uncertainty is negative or not finite at position {position} mm")]
    BadUncertainty {
        /// The axis.
        axis: &'static str,
        /// The position, mm.
        position: f64,
    },
}

/// A position outside the range a table covers.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("{what} = {value} mm is outside the mapped range [{min}, {max}] mm")]
pub struct OutOfRange {
    /// The coordinate (`x`, `y`, `z`).
    pub what: &'static str,
    /// Its value, mm.
    pub value: f64,
    /// The start of the mapped range, mm.
    pub min: f64,
    /// The end of the mapped range, mm.
    pub max: f64,
}

/// One axis's error table: positions and, per position, `[δx, δy, δz, εx, εy, εz]` in machine
/// coordinates (mm, rad).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisTable {
    /// The axis the table describes.
    pub axis: Axis,
    grid: Grid1,
    nodes: Vec<[f64; 6]>,
    /// Per node, in machine coordinates like `nodes`: the standard uncertainty of the node value
    /// (first six) and the squared curvature term `κ²` of the interval that starts there (last
    /// six).
    unc: Option<Vec<[f64; 12]>>,
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
        Ok(Self { axis, grid, nodes, unc: None })
    }

    /// The same table with the standard uncertainties (k = 1, mm and rad, the axis's own naming)
    /// of its node values, one per position. Negative or non-finite values are refused.
    pub fn with_uncertainty(mut self, u: &[AxisErrors]) -> Result<Self, MapError> {
        let n = self.nodes.len();
        if u.len() != n {
            return Err(MapError::Length { axis: self.axis.name(), positions: n, values: u.len() });
        }
        let mut var = Vec::with_capacity(n);
        for (p, e) in self.grid.values().iter().zip(u) {
            let (d, r) = e.to_machine(self.axis);
            let v = [d[0], d[1], d[2], r[0], r[1], r[2]];
            if v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                return Err(MapError::BadUncertainty { axis: self.axis.name(), position: *p });
            }
            var.push(v.map(|x| x * x));
        }
        // κ_j² at each interior node: the squared second difference less its expected noise.
        let kappa2 = |j: usize, k: usize| -> f64 {
            if j == 0 || j + 1 >= n {
                return 0.0;
            }
            let c = |i: usize| self.nodes[i][k];
            let d2 = c(j - 1) - 2.0 * c(j) + c(j + 1);
            let noise = var[j - 1][k] + 4.0 * var[j][k] + var[j + 1][k];
            (d2 * d2 - noise).max(0.0)
        };
        let mut unc = Vec::with_capacity(n);
        for i in 0..n {
            let mut row = [0.0; 12];
            for k in 0..6 {
                row[k] = var[i][k].sqrt();
            }
            for k in 0..6 {
                // The interval [i, i+1]: the larger curvature of its two ends; an end node of the
                // table borrows its neighbour's.
                let ends = [i.max(1).min(n.saturating_sub(2)), (i + 1).min(n.saturating_sub(2)).max(1)];
                row[6 + k] = ends.iter().map(|&j| kappa2(j, k)).fold(0.0, f64::max);
            }
            unc.push(row);
        }
        self.unc = Some(unc);
        Ok(self)
    }

    /// Whether the table carries the uncertainties of its values.
    pub fn has_uncertainty(&self) -> bool {
        self.unc.is_some()
    }

    /// The mapped positions along the axis, mm.
    pub fn positions(&self) -> &[f64] {
        self.grid.values()
    }
    /// Whether the positions are equally spaced.
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

    /// `(δ, ε)` at `a` like [`AxisTable::at`], and their variances `[δx, δy, δz, εx, εy, εz]`
    /// (mm², rad²; zero without uncertainties): the nodes' propagated plus the interpolation's.
    #[inline]
    pub fn at_u(&self, a: f64, clamp: bool) -> Result<(Vector3, Vector3, [f64; 6]), OutOfRange> {
        let (i, f) = self.grid.locate(a, clamp).ok_or(OutOfRange {
            what: self.axis.name(),
            value: a,
            min: self.grid.first(),
            max: self.grid.last(),
        })?;
        let n0 = &self.nodes[i];
        let n1 = self.nodes.get(i + 1).unwrap_or(n0);
        let l = |k: usize| n0[k] + f * (n1[k] - n0[k]);
        let mut var = [0.0; 6];
        if let Some(u) = &self.unc {
            let u0 = &u[i];
            let u1 = u.get(i + 1).unwrap_or(u0);
            let wi = 0.25 * (f * (1.0 - f)) * (f * (1.0 - f));
            for k in 0..6 {
                let sd = u0[k] + f * (u1[k] - u0[k]);
                var[k] = sd * sd + wi * u0[6 + k];
            }
        }
        Ok((Vector3::new(l(0), l(1), l(2)), Vector3::new(l(3), l(4), l(5)), var))
    }
}

/// The three squareness errors (rad). Positive: the angle between the positive axes is < 90°.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Squareness {
    /// Between X and Y, rad.
    pub xy: f64,
    /// Between X and Z, rad.
    pub xz: f64,
    /// Between Y and Z, rad.
    pub yz: f64,
}

/// Kinematic chain of the machine (which axis carries which); `--chain bridge|gantry` on the
/// command line, where the variants' documentation is the help for each value.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Chain {
    /// Bridge CMM: bed → Y → X → Z → tool.
    #[default]
    #[cfg_attr(feature = "clap", value(name = "bridge"))]
    BridgeYXZ,
    /// Large gantry: bed → X → Y → Z → tool.
    #[cfg_attr(feature = "clap", value(name = "gantry"))]
    GantryXYZ,
}

/// The 21-parameter map. A missing axis table means that axis has no errors (any position).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GeometricMap {
    /// The X axis table, if mapped.
    pub x: Option<AxisTable>,
    /// The Y axis table, if mapped.
    pub y: Option<AxisTable>,
    /// The Z axis table, if mapped.
    pub z: Option<AxisTable>,
    /// The squareness errors, rad.
    pub squareness: Squareness,
    /// Standard uncertainties (k = 1, rad) of the squareness errors, when known.
    pub squareness_u: Option<Squareness>,
    /// Which axis carries which.
    pub chain: Chain,
    /// Hold end values outside a table's range instead of refusing.
    pub clamp: bool,
}

/// Variance added to `E` by a rotation of variances `v` (about x, y, z) with lever arm `r`.
#[inline]
fn cross_var(v: &[f64; 6], r: &Vector3) -> Vector3 {
    let (x2, y2, z2) = (r.x * r.x, r.y * r.y, r.z * r.z);
    Vector3::new(v[4] * z2 + v[5] * y2, v[5] * x2 + v[3] * z2, v[3] * y2 + v[4] * x2)
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

    /// Why the map's uncertainty is not known (`None`: every table and the squareness carry
    /// theirs, and [`GeometricMap::error_u`] propagates them).
    pub fn uncertainty_unknown(&self) -> Option<String> {
        let missing: Vec<&str> = [("x", &self.x), ("y", &self.y), ("z", &self.z)]
            .into_iter()
            .filter(|(_, t)| !t.as_ref().is_some_and(AxisTable::has_uncertainty))
            .map(|(n, _)| n)
            .collect();
        if !missing.is_empty() {
            return Some(format!(
                "the map's {} table{} no standard-uncertainty columns (u_pos_um, u_str1_um, u_str2_um, u_pitch_urad, u_yaw_urad, u_roll_urad)",
                missing.join(", "),
                if missing.len() > 1 { "s have" } else { " has" }
            ));
        }
        if self.squareness_u.is_none() {
            return Some(
                "the squareness carries no standard uncertainties (u_xy_urad, u_xz_urad, u_yz_urad beside the values; a map without a squareness file has none)"
                    .into(),
            );
        }
        None
    }

    /// [`GeometricMap::error`] and the variance of each coordinate of `E` (mm²) from the map's
    /// uncertainties (module docs); components without uncertainties contribute nothing.
    #[inline]
    pub fn error_u(&self, p: &Point3, t: &Vector3) -> Result<(Vector3, Vector3), OutOfRange> {
        let axis_u = |tab: &Option<AxisTable>, a: f64| match tab {
            Some(tab) => tab.at_u(a, self.clamp),
            None => Ok((Vector3::zeros(), Vector3::zeros(), [0.0; 6])),
        };
        let (dx, ex, vx) = axis_u(&self.x, p.x)?;
        let (dy, ey, vy) = axis_u(&self.y, p.y)?;
        let (dz, ez, vz) = axis_u(&self.z, p.z)?;
        let xv = Vector3::new(p.x, 0.0, 0.0);
        let yv = Vector3::new(0.0, p.y, 0.0);
        let zt = Vector3::new(0.0, 0.0, p.z) + t;
        let s = &self.squareness;
        let sq = Vector3::new(s.xz * p.z, s.xy * p.x + s.yz * p.z, 0.0);
        let lin = |v: &[f64; 6]| Vector3::new(v[0], v[1], v[2]);
        let (e, mut var) = match self.chain {
            Chain::BridgeYXZ => {
                let (ry, rx) = (xv + zt, zt);
                (
                    dy + ey.cross(&ry) + dx + ex.cross(&rx),
                    lin(&vy) + cross_var(&vy, &ry) + lin(&vx) + cross_var(&vx, &rx),
                )
            }
            Chain::GantryXYZ => {
                let (rx, ry) = (yv + zt, zt);
                (
                    dx + ex.cross(&rx) + dy + ey.cross(&ry),
                    lin(&vx) + cross_var(&vx, &rx) + lin(&vy) + cross_var(&vy, &ry),
                )
            }
        };
        var += lin(&vz) + cross_var(&vz, t);
        if let Some(su) = &self.squareness_u {
            let (x2, z2) = (p.x * p.x, p.z * p.z);
            var += Vector3::new(su.xz * su.xz * z2, su.xy * su.xy * x2 + su.yz * su.yz * z2, 0.0);
        }
        Ok((e + dz + ez.cross(t) + sq, var))
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

    /// A table of 11 nodes (every 100 mm) with the components of `f` and the uncertainties `u`.
    fn table_u(axis: Axis, f: impl Fn(f64) -> AxisErrors, u: AxisErrors) -> AxisTable {
        let pos: Vec<f64> = (0..=10).map(|i| 100.0 * i as f64).collect();
        let e: Vec<AxisErrors> = pos.iter().map(|&p| f(p)).collect();
        AxisTable::new(axis, pos, &e).unwrap().with_uncertainty(&[u; 11]).unwrap()
    }

    #[test]
    fn propagated_variance_equals_the_sum_of_squared_sensitivities() {
        // At table nodes the variance is exactly Σ (∂E/∂c · u_c)²; E is linear in every
        // component, so each sensitivity is the change of E when that one component (at every
        // node) moves by its u. Checks the Abbe lever arms of both chains independently.
        let u = AxisErrors { pos: 1e-4, str1: 2e-4, str2: 3e-4, pitch: 1e-6, yaw: 2e-6, roll: 3e-6 };
        let su = Squareness { xy: 4e-7, xz: 5e-7, yz: 6e-7 };
        let p = Point3::new(300.0, 700.0, 200.0);
        let t = Vector3::new(15.0, -25.0, -120.0);
        for chain in [Chain::BridgeYXZ, Chain::GantryXYZ] {
            let base = |bump: Option<(usize, usize)>, sq: Squareness| {
                let mk = |ax: usize, axis: Axis| {
                    let mut e = AxisErrors::default();
                    if let Some((a, k)) = bump {
                        if a == ax {
                            let v = [u.pos, u.str1, u.str2, u.pitch, u.yaw, u.roll][k];
                            match k {
                                0 => e.pos = v,
                                1 => e.str1 = v,
                                2 => e.str2 = v,
                                3 => e.pitch = v,
                                4 => e.yaw = v,
                                _ => e.roll = v,
                            }
                        }
                    }
                    table_u(axis, move |_| e, u)
                };
                GeometricMap {
                    x: Some(mk(0, Axis::X)),
                    y: Some(mk(1, Axis::Y)),
                    z: Some(mk(2, Axis::Z)),
                    squareness: sq,
                    squareness_u: Some(su),
                    chain,
                    clamp: false,
                }
            };
            let mut var = Vector3::zeros();
            for a in 0..3 {
                for k in 0..6 {
                    let d = base(Some((a, k)), Squareness::default()).error(&p, &t).unwrap();
                    var += d.component_mul(&d);
                }
            }
            for sq in [
                Squareness { xy: su.xy, ..Default::default() },
                Squareness { xz: su.xz, ..Default::default() },
                Squareness { yz: su.yz, ..Default::default() },
            ] {
                let d = base(None, sq).error(&p, &t).unwrap();
                var += d.component_mul(&d);
            }
            let (_, v) = base(None, Squareness::default()).error_u(&p, &t).unwrap();
            assert!((v - var).norm() < 1e-12 * var.norm(), "{chain:?}: {v} vs {var}");
            assert!(base(None, Squareness::default()).uncertainty_unknown().is_none());
        }
    }

    #[test]
    fn interpolation_term_covers_the_linear_interpolation_error() {
        // pos = k·a² sampled every 100 mm, nearly exact values: mid-interval the linear
        // interpolation is off by k·h²/4 and the curvature term states exactly that (κ = 2k·h²,
        // u_int = κ/8); at a node it is zero.
        let k = 1e-8;
        let tiny = AxisErrors { pos: 1e-12, ..Default::default() };
        let t = table_u(Axis::X, |a| AxisErrors { pos: k * a * a, ..Default::default() }, tiny);
        let (d, _, v) = t.at_u(150.0, false).unwrap();
        let err = (d.x - k * 150.0 * 150.0).abs();
        assert!((err - k * 1e4 / 4.0).abs() < 1e-15);
        assert!((v[0].sqrt() - err).abs() < 1e-9 * err, "{} vs {err}", v[0].sqrt());
        let (_, _, v) = t.at_u(300.0, false).unwrap();
        assert!((v[0].sqrt() - 1e-12).abs() < 1e-15);
        // A map without uncertainties says so; a negative u is refused.
        let plain = GeometricMap { x: Some(table(Axis::X, |_| AxisErrors::default())), ..Default::default() };
        assert!(plain.uncertainty_unknown().unwrap().contains("u_pos_um"));
        let bad = AxisErrors { yaw: -1.0, ..Default::default() };
        assert!(table(Axis::Y, |_| AxisErrors::default()).with_uncertainty(&[bad; 11]).is_err());
    }
}
