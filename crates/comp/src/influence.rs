//! Influence maps of the bed under load and their superposition for a load case.
//!
//! Entry points: [`InfluenceMap`] (per unit load at each grid node, the portal's pitch and roll
//! against portal Y; built by [`crate::fe_map`] or imported from a CSV of an outside FE
//! package), [`InfluenceMap::superpose`] (the contract's superposition) giving
//! [`PortalCurves`].
//!
//! Superposition (contract): for each resting point k with force F_k at (x_k, y_k), the map is
//! interpolated bilinearly in (load_x, load_y) and linearly in portal_y, scaled by
//! F_k / unit_load_n, and summed. Since all three operations are linear, the curves are summed
//! at the map's own portal-Y nodes and interpolated linearly in Y afterwards — identical to
//! interpolating each term. A resting point outside the load grid is refused
//! ([`NotCovered`]); linear elasticity does not extrapolate safely beyond the mapped bed.

use crate::geometric::OutOfRange;
use crate::grid1::Grid1;

/// One row of an influence map file (mm, rad per `unit_load_n`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InfluenceRow {
    /// X of the unit load, mm.
    pub load_x: f64,
    /// Y of the unit load, mm.
    pub load_y: f64,
    /// Y of the portal, mm.
    pub portal_y: f64,
    /// Portal pitch per unit load, rad.
    pub pitch: f64,
    /// Portal roll per unit load, rad.
    pub roll: f64,
}

/// Why rows do not form a map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InfluenceError {
    /// The unit load is not positive and finite (N).
    #[error("the unit load must be positive and finite (got {0} N)")]
    UnitLoad(f64),
    /// A value of a row is not finite.
    #[error("row {row}: a value is not finite")]
    NotFinite {
        /// 0-based row.
        row: usize,
    },
    #[error(
        "row {row}: duplicate entry for load ({x}, {y}) mm at portal y = {py} mm (first in row {first})"
    )]
    /// Two rows for the same load and portal position.
    Duplicate {
        /// 0-based row of the second.
        row: usize,
        /// 0-based row of the first.
        first: usize,
        /// Load X, mm.
        x: f64,
        /// Load Y, mm.
        y: f64,
        /// Portal Y, mm.
        py: f64,
    },
    /// The rows do not fill the grid of load and portal positions.
    #[error("the map is not a complete grid: {present} of {expected} (load_x × load_y × portal_y) entries are present; missing e.g. load ({x}, {y}) mm at portal y = {py} mm")]
    Incomplete {
        /// Rows present.
        present: usize,
        /// Rows a complete grid has.
        expected: usize,
        /// Load X of a missing entry, mm.
        x: f64,
        /// Load Y of a missing entry, mm.
        y: f64,
        /// Portal Y of a missing entry, mm.
        py: f64,
    },
    /// Fewer than two distinct values of a grid coordinate.
    #[error("the map needs at least two distinct {what} values (got {n})")]
    TooFew {
        /// The coordinate.
        what: &'static str,
        /// Distinct values found.
        n: usize,
    },
}

/// A resting point outside the load grid of the map.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("resting point {index} at ({x}, {y}) mm is outside the influence map's load grid (x {x0}..{x1}, y {y0}..{y1} mm): the map does not cover the part")]
pub struct NotCovered {
    /// 0-based index of the resting point.
    pub index: usize,
    /// Its X, mm.
    pub x: f64,
    /// Its Y, mm.
    pub y: f64,
    /// Start of the load grid in X, mm.
    pub x0: f64,
    /// End of the load grid in X, mm.
    pub x1: f64,
    /// Start of the load grid in Y, mm.
    pub y0: f64,
    /// End of the load grid in Y, mm.
    pub y1: f64,
}

/// Unit-load influence map on a rectilinear grid of load positions.
#[derive(Debug, Clone, PartialEq)]
pub struct InfluenceMap {
    /// The unit load the map is per, N.
    pub unit_load_n: f64,
    load_x: Grid1,
    load_y: Grid1,
    portal_y: Grid1,
    /// `[(ix·ny + iy)·np + ip]`, rad per unit load.
    pitch: Vec<f64>,
    roll: Vec<f64>,
}

fn sorted_unique(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v.dedup();
    v
}

impl InfluenceMap {
    /// A map from its grid axes and values in `[ix][iy][ip]` order.
    pub fn from_grid(
        unit_load_n: f64,
        load_x: Vec<f64>,
        load_y: Vec<f64>,
        portal_y: Vec<f64>,
        pitch: Vec<f64>,
        roll: Vec<f64>,
    ) -> Result<Self, InfluenceError> {
        let mut rows = Vec::with_capacity(pitch.len());
        let n = load_x.len() * load_y.len() * portal_y.len();
        if pitch.len() != n || roll.len() != n {
            return Err(InfluenceError::Incomplete {
                present: pitch.len().min(roll.len()),
                expected: n,
                x: f64::NAN,
                y: f64::NAN,
                py: f64::NAN,
            });
        }
        let mut k = 0;
        for &x in &load_x {
            for &y in &load_y {
                for &py in &portal_y {
                    rows.push(InfluenceRow {
                        load_x: x,
                        load_y: y,
                        portal_y: py,
                        pitch: pitch[k],
                        roll: roll[k],
                    });
                    k += 1;
                }
            }
        }
        Self::from_rows(unit_load_n, &rows)
    }

    /// A map from rows in any order. Every combination of the distinct load_x, load_y and
    /// portal_y values must be present exactly once. Errors name the row index (0-based).
    pub fn from_rows(unit_load_n: f64, rows: &[InfluenceRow]) -> Result<Self, InfluenceError> {
        if !(unit_load_n.is_finite() && unit_load_n > 0.0) {
            return Err(InfluenceError::UnitLoad(unit_load_n));
        }
        for (i, r) in rows.iter().enumerate() {
            if ![r.load_x, r.load_y, r.portal_y, r.pitch, r.roll].iter().all(|v| v.is_finite()) {
                return Err(InfluenceError::NotFinite { row: i });
            }
        }
        let xs = sorted_unique(rows.iter().map(|r| r.load_x).collect());
        let ys = sorted_unique(rows.iter().map(|r| r.load_y).collect());
        let ps = sorted_unique(rows.iter().map(|r| r.portal_y).collect());
        for (what, v) in [("load_x_mm", &xs), ("load_y_mm", &ys), ("portal_y_mm", &ps)] {
            if v.len() < 2 {
                return Err(InfluenceError::TooFew { what, n: v.len() });
            }
        }
        let (nx, ny, np) = (xs.len(), ys.len(), ps.len());
        let n = nx * ny * np;
        let mut owner = vec![usize::MAX; n];
        let mut pitch = vec![0.0; n];
        let mut roll = vec![0.0; n];
        let idx = |v: &[f64], a: f64| v.binary_search_by(|p| p.total_cmp(&a)).unwrap_or(0);
        for (i, r) in rows.iter().enumerate() {
            let k = (idx(&xs, r.load_x) * ny + idx(&ys, r.load_y)) * np + idx(&ps, r.portal_y);
            if owner[k] != usize::MAX {
                return Err(InfluenceError::Duplicate {
                    row: i,
                    first: owner[k],
                    x: r.load_x,
                    y: r.load_y,
                    py: r.portal_y,
                });
            }
            owner[k] = i;
            pitch[k] = r.pitch;
            roll[k] = r.roll;
        }
        if let Some(k) = owner.iter().position(|&o| o == usize::MAX) {
            return Err(InfluenceError::Incomplete {
                present: rows.len(),
                expected: n,
                x: xs[k / (ny * np)],
                y: ys[(k / np) % ny],
                py: ps[k % np],
            });
        }
        let g = |v| Grid1::new(v).map_err(|_| InfluenceError::TooFew { what: "grid", n: 0 });
        Ok(Self { unit_load_n, load_x: g(xs)?, load_y: g(ys)?, portal_y: g(ps)?, pitch, roll })
    }

    /// The load positions in X, mm.
    pub fn load_x(&self) -> &[f64] {
        self.load_x.values()
    }
    /// The load positions in Y, mm.
    pub fn load_y(&self) -> &[f64] {
        self.load_y.values()
    }
    /// The portal positions in Y, mm.
    pub fn portal_y(&self) -> &[f64] {
        self.portal_y.values()
    }

    /// All rows in `[load_x][load_y][portal_y]` order (for writing the file).
    pub fn rows(&self) -> impl Iterator<Item = InfluenceRow> + '_ {
        let (ny, np) = (self.load_y.len(), self.portal_y.len());
        (0..self.pitch.len()).map(move |k| InfluenceRow {
            load_x: self.load_x.values()[k / (ny * np)],
            load_y: self.load_y.values()[(k / np) % ny],
            portal_y: self.portal_y.values()[k % np],
            pitch: self.pitch[k],
            roll: self.roll[k],
        })
    }

    /// Pitch and roll curves (rad) at the map's portal-Y nodes for point loads `(x, y, F)`
    /// (F in N, downwards), by the contract's superposition.
    pub fn superpose(&self, loads: &[(f64, f64, f64)]) -> Result<PortalCurves, NotCovered> {
        let (ny, np) = (self.load_y.len(), self.portal_y.len());
        let mut pitch = vec![0.0; np];
        let mut roll = vec![0.0; np];
        for (index, &(x, y, f)) in loads.iter().enumerate() {
            let nc = NotCovered {
                index,
                x,
                y,
                x0: self.load_x.first(),
                x1: self.load_x.last(),
                y0: self.load_y.first(),
                y1: self.load_y.last(),
            };
            let (ix, fx) = self.load_x.locate(x, false).ok_or(nc)?;
            let (iy, fy) = self.load_y.locate(y, false).ok_or(nc)?;
            let s = f / self.unit_load_n;
            for (dx, wx) in [(0, 1.0 - fx), (1, fx)] {
                for (dy, wy) in [(0, 1.0 - fy), (1, fy)] {
                    let w = wx * wy * s;
                    if wx * wy == 0.0 {
                        continue;
                    }
                    let base = ((ix + dx) * ny + iy + dy) * np;
                    for ip in 0..np {
                        pitch[ip] += w * self.pitch[base + ip];
                        roll[ip] += w * self.roll[base + ip];
                    }
                }
            }
        }
        Ok(PortalCurves { y: self.portal_y.clone(), pitch, roll })
    }
}

/// The portal's pitch (about +X) and roll (about +Y), rad, against portal Y (mm): its physical
/// rotations by the right-hand rule, as [`crate::load`] defines them (the correction is
/// `p + θ × (p − o)`).
#[derive(Debug, Clone, PartialEq)]
pub struct PortalCurves {
    y: Grid1,
    /// Portal pitch at each position, rad.
    pub pitch: Vec<f64>,
    /// Portal roll at each position, rad.
    pub roll: Vec<f64>,
}

impl PortalCurves {
    /// Curves from values at strictly increasing Y positions.
    pub fn new(y: Vec<f64>, pitch: Vec<f64>, roll: Vec<f64>) -> Option<Self> {
        (y.len() == pitch.len() && y.len() == roll.len()).then_some(())?;
        Some(Self { y: Grid1::new(y).ok()?, pitch, roll })
    }
    /// The portal positions in Y, mm.
    pub fn y(&self) -> &[f64] {
        self.y.values()
    }
    /// `(pitch, roll)` at portal position `y`, linear between nodes; outside the range refused.
    #[inline]
    pub fn at(&self, y: f64) -> Result<(f64, f64), OutOfRange> {
        let (i, f) = self.y.locate(y, false).ok_or(OutOfRange {
            what: "portal y",
            value: y,
            min: self.y.first(),
            max: self.y.last(),
        })?;
        let j = (i + 1).min(self.pitch.len() - 1);
        Ok((
            self.pitch[i] + f * (self.pitch[j] - self.pitch[i]),
            self.roll[i] + f * (self.roll[j] - self.roll[i]),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand-made imported map: 2×2 load nodes, 3 portal positions, values chosen so every
    /// interpolation weight is visible in the sum.
    fn hand_map() -> InfluenceMap {
        let mut rows = vec![];
        for (i, &x) in [0.0, 100.0].iter().enumerate() {
            for (j, &y) in [0.0, 200.0].iter().enumerate() {
                for (k, &py) in [0.0, 500.0, 1000.0].iter().enumerate() {
                    // pitch = 1 + 10 i + 100 j + 1000 k (µrad), roll = −pitch.
                    let v = (1.0 + 10.0 * i as f64 + 100.0 * j as f64 + 1000.0 * k as f64) * 1e-6;
                    rows.push(InfluenceRow { load_x: x, load_y: y, portal_y: py, pitch: v, roll: -v });
                }
            }
        }
        rows.reverse(); // any order
        InfluenceMap::from_rows(1000.0, &rows).unwrap()
    }

    #[test]
    fn superposition_matches_hand_calculation() {
        let m = hand_map();
        // Load 2000 N at (25, 150): fx = 0.25, fy = 0.75; bilinear value at portal node k:
        // 1 + 10·0.25 + 100·0.75 + 1000k = 78.5 + 1000k; × 2 (F/unit). Second load 500 N at
        // (100, 0): 1 + 10 + 1000k, × 0.5. Sum at k: 157 + 2000k + 5.5 + 500k = 162.5 + 2500k.
        let c = m.superpose(&[(25.0, 150.0, 2000.0), (100.0, 0.0, 500.0)]).unwrap();
        for k in 0..3 {
            let want = (162.5 + 2500.0 * k as f64) * 1e-6;
            // A few additions of doubles: relative rounding well below 1e-12.
            assert!((c.pitch[k] - want).abs() <= 1e-12 * want, "{k}: {} vs {want}", c.pitch[k]);
            assert!((c.roll[k] + want).abs() <= 1e-12 * want);
        }
        // Linear in portal y: at y = 250 (halfway between nodes 0 and 1): 162.5 + 1250.
        let (p, r) = c.at(250.0).unwrap();
        assert!((p - 1412.5e-6).abs() < 1e-15 && (r + 1412.5e-6).abs() < 1e-15);
        assert!(c.at(1000.1).is_err());
    }

    #[test]
    fn coverage_and_completeness() {
        let m = hand_map();
        let e = m.superpose(&[(50.0, 50.0, 1.0), (100.5, 0.0, 1.0)]).unwrap_err();
        assert_eq!(e.index, 1);
        let mut rows: Vec<InfluenceRow> = m.rows().collect();
        assert_eq!(InfluenceMap::from_rows(1000.0, &rows).unwrap(), m);
        rows.pop();
        assert!(matches!(InfluenceMap::from_rows(1000.0, &rows), Err(InfluenceError::Incomplete { .. })));
        let r0 = rows[0];
        rows.push(r0);
        assert!(matches!(InfluenceMap::from_rows(1000.0, &rows), Err(InfluenceError::Duplicate { .. })));
        assert!(matches!(InfluenceMap::from_rows(0.0, &rows), Err(InfluenceError::UnitLoad(_))));
    }
}
