//! The combined correction (geometric map + load) applied to many points: the hot path.
//!
//! Entry points: [`Corrector`] with [`Corrector::displacement`] (corrected − indicated at one
//! point), [`Corrector::correct_measured`] (in place, parallel), [`Corrector::compensate`]
//! (commanded positions by fixed-point inversion, parallel) and [`CompError`].
//!
//! Points are indicated **tip** coordinates (the machine's axis positions plus the probe offset
//! `t`, what a CMM reports); the map's tables are read at the axis positions `a = p − t`. A
//! measured point `p` becomes `p + E(p − t; t) − e(p)` (geometric error `E` of
//! `docs/conventions.md`, load error `e` of [`crate::load`], both at the indicated point; their
//! interaction is second order). A target
//! `T` is commanded at `c` with `c + E(c) − e(c) = T`, by `c ← T − (E(c) − e(c))` until the step
//! is below 1 nm (the map's slopes are µm/mm, so the iteration contracts by ~10⁻⁵ per step);
//! a map that does not contract (slopes near 1) is reported, never silently accepted.
//!
//! Performance: no allocation per point, O(1) table lookups on uniform grids (binary search
//! otherwise), rayon over chunks of 4096 points; errors carry the index of the first bad point.

use crate::geometric::{GeometricMap, OutOfRange};
use crate::load::LoadCorrection;
use rayon::prelude::*;
use truepos_math::{Point3, Vector3};

/// Convergence threshold of the inverse (mm): 1 nm.
pub const INVERSE_TOL_MM: f64 = 1e-6;
/// Iteration limit of the inverse.
pub const INVERSE_MAX_ITER: usize = 50;

/// Errors of a batch correction.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompError {
    /// A point is outside the map's range.
    #[error("point {index}: {source}")]
    OutOfRange {
        /// 0-based index of the point.
        index: usize,
        /// Which coordinate is out of which range.
        source: OutOfRange,
    },
    /// The inverse correction of a commanded position did not converge.
    #[error("point {index}: the inverse did not converge below 1 nm in {iterations} iterations (last step {last_step_mm:.3e} mm); the map is not a small correction there")]
    NoConvergence {
        /// 0-based index of the point.
        index: usize,
        /// Iterations tried.
        iterations: usize,
        /// Length of the last fixed-point step, mm.
        last_step_mm: f64,
    },
}

impl CompError {
    /// 0-based index of the point the error is about.
    pub fn index(&self) -> usize {
        match self {
            CompError::OutOfRange { index, .. } | CompError::NoConvergence { index, .. } => *index,
        }
    }
}

/// Geometric map and/or load correction with the probe offset.
#[derive(Debug, Clone, Copy)]
pub struct Corrector<'a> {
    /// The geometric error map, if any.
    pub geometric: Option<&'a GeometricMap>,
    /// The load correction, if any.
    pub load: Option<&'a LoadCorrection>,
    /// Probe/tool offset in the ram frame (mm).
    pub probe_offset: Vector3,
}

const CHUNK: usize = 4096;

impl<'a> Corrector<'a> {
    /// The volumetric error at each point; the first point outside the map's range is an
    /// [`CompError::OutOfRange`] with its index.
    pub fn displacements(&self, points: &[Point3]) -> Result<Vec<Vector3>, CompError> {
        points
            .iter()
            .enumerate()
            .map(|(index, p)| self.displacement(p).map_err(|source| CompError::OutOfRange { index, source }))
            .collect()
    }

    /// `corrected − p` at indicated tip point `p`: `E(p − t; t) + e(p)`.
    #[inline]
    pub fn displacement(&self, p: &Point3) -> Result<Vector3, OutOfRange> {
        let mut d = Vector3::zeros();
        if let Some(g) = self.geometric {
            d += g.error(&(p - self.probe_offset), &self.probe_offset)?;
        }
        if let Some(l) = self.load {
            d += l.error(p)?;
        }
        Ok(d)
    }

    /// [`Corrector::displacement`] and the variance of each of its coordinates (mm²) from the
    /// geometric map's uncertainties ([`GeometricMap::error_u`]); the load correction carries
    /// none (callers check [`Corrector::uncertainty_unknown`] first).
    #[inline]
    pub fn displacement_u(&self, p: &Point3) -> Result<(Vector3, Vector3), OutOfRange> {
        let (mut d, mut v) = (Vector3::zeros(), Vector3::zeros());
        if let Some(g) = self.geometric {
            (d, v) = g.error_u(&(p - self.probe_offset), &self.probe_offset)?;
        }
        if let Some(l) = self.load {
            d += l.error(p)?;
        }
        Ok((d, v))
    }

    /// Why the correction's uncertainty is not known (`None`: a geometric map with its
    /// uncertainties and no load correction, whose uncertainty is not modelled).
    pub fn uncertainty_unknown(&self) -> Option<String> {
        if self.load.is_some() {
            return Some("the load correction carries no uncertainty model".into());
        }
        match self.geometric {
            Some(g) => g.uncertainty_unknown(),
            None => Some("no geometric map".into()),
        }
    }

    /// Correct measured points in place; `corrections` (same length, if given) receives the
    /// displacement applied to each. On error nothing meaningful is left in `points`.
    pub fn correct_measured(
        &self,
        points: &mut [Point3],
        corrections: Option<&mut [Vector3]>,
    ) -> Result<(), CompError> {
        let run = |(ci, (pts, mut cor)): (usize, (&mut [Point3], Option<&mut [Vector3]>))| -> Result<(), CompError> {
            for (k, p) in pts.iter_mut().enumerate() {
                let d = self.displacement(p).map_err(|source| CompError::OutOfRange { index: ci * CHUNK + k, source })?;
                *p += d;
                if let Some(c) = cor.as_deref_mut() {
                    c[k] = d;
                }
            }
            Ok(())
        };
        let results: Vec<Result<(), CompError>> = match corrections {
            Some(c) => {
                assert_eq!(c.len(), points.len(), "corrections must have one entry per point");
                points
                    .par_chunks_mut(CHUNK)
                    .zip(c.par_chunks_mut(CHUNK))
                    .map(|(p, c)| (p, Some(c)))
                    .enumerate()
                    .map(run)
                    .collect()
            }
            None => points.par_chunks_mut(CHUNK).map(|p| (p, None)).enumerate().map(run).collect(),
        };
        first_error(results)
    }

    /// Commanded position for one target and the number of iterations used.
    pub fn command_for(&self, target: &Point3) -> Result<(Point3, usize), InverseFail> {
        let mut c = *target;
        let mut step = f64::INFINITY;
        for it in 1..=INVERSE_MAX_ITER {
            let d = self.displacement(&c).map_err(InverseFail::Range)?;
            let next = target - d;
            step = (next - c).norm();
            c = next;
            if step < INVERSE_TOL_MM {
                // One more evaluation confirms the residual `c + D(c) − T` is below 1 nm too.
                let d = self.displacement(&c).map_err(InverseFail::Range)?;
                if (c + d - target).norm() < INVERSE_TOL_MM {
                    return Ok((c, it));
                }
            }
        }
        Err(InverseFail::NoConvergence { iterations: INVERSE_MAX_ITER, last_step_mm: step })
    }

    /// Replace targets by commanded positions in place. Returns the largest iteration count.
    pub fn compensate(&self, targets: &mut [Point3]) -> Result<usize, CompError> {
        let results: Vec<Result<usize, CompError>> = targets
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(ci, pts)| {
                let mut worst = 0;
                for (k, p) in pts.iter_mut().enumerate() {
                    let index = ci * CHUNK + k;
                    let (c, it) = self.command_for(p).map_err(|f| match f {
                        InverseFail::Range(source) => CompError::OutOfRange { index, source },
                        InverseFail::NoConvergence { iterations, last_step_mm } => {
                            CompError::NoConvergence { index, iterations, last_step_mm }
                        }
                    })?;
                    *p = c;
                    worst = worst.max(it);
                }
                Ok(worst)
            })
            .collect();
        let mut worst = 0;
        let mut errors = Vec::new();
        for r in results {
            match r {
                Ok(w) => worst = worst.max(w),
                Err(e) => errors.push(e),
            }
        }
        errors.into_iter().min_by_key(CompError::index).map_or(Ok(worst), Err)
    }
}

/// Why one inverse failed.
#[derive(Debug, Clone, PartialEq)]
pub enum InverseFail {
    /// A position left the map's range.
    Range(OutOfRange),
    /// The fixed-point iteration did not converge.
    NoConvergence {
        /// Iterations tried.
        iterations: usize,
        /// Length of the last step, mm.
        last_step_mm: f64,
    },
}

fn first_error(results: Vec<Result<(), CompError>>) -> Result<(), CompError> {
    results.into_iter().filter_map(Result::err).min_by_key(CompError::index).map_or(Ok(()), Err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometric::{Axis, AxisErrors, AxisTable};

    fn smooth_map() -> GeometricMap {
        let pos: Vec<f64> = (0..=20).map(|i| 50.0 * i as f64).collect();
        let mk = |axis, s: f64| {
            let e: Vec<AxisErrors> = pos
                .iter()
                .map(|&p| {
                    let u = p / 1000.0;
                    AxisErrors {
                        pos: s * 5e-3 * u,
                        str1: s * 2e-3 * (u * 6.0).sin(),
                        str2: -s * 1e-3 * u * u,
                        pitch: s * 8e-6 * (u * 3.0).cos(),
                        yaw: -s * 4e-6 * u,
                        roll: s * 3e-6 * (u * 5.0).sin(),
                    }
                })
                .collect();
            AxisTable::new(axis, pos.clone(), &e).unwrap()
        };
        GeometricMap {
            x: Some(mk(Axis::X, 1.0)),
            y: Some(mk(Axis::Y, -0.7)),
            z: Some(mk(Axis::Z, 0.5)),
            ..Default::default()
        }
    }

    #[test]
    fn inverse_converges_below_a_nanometre() {
        let g = smooth_map();
        let c =
            Corrector { geometric: Some(&g), load: None, probe_offset: Vector3::new(10.0, -20.0, -150.0) };
        let targets: Vec<Point3> = (0..500)
            .map(|i| {
                Point3::new(
                    20.0 + (i * 37 % 970) as f64,
                    5.0 + (i * 53 % 970) as f64,
                    100.0 + (i * 71 % 700) as f64,
                )
            })
            .collect();
        let mut cmd = targets.clone();
        let worst = c.compensate(&mut cmd).unwrap();
        assert!(worst <= 5, "contraction ~1e-5 per step: a few iterations ({worst})");
        for (t, k) in targets.iter().zip(&cmd) {
            let reached = k + c.displacement(k).unwrap();
            assert!((reached - t).norm() < 1e-6, "{}", (reached - t).norm());
        }
    }

    #[test]
    fn steep_map_reports_non_convergence_and_range_errors_name_the_point() {
        // Positioning error E = 1.05·x (slope > 1): c ← T − E(c) oscillates with growing
        // amplitude (×1.05 per step, ~11× in 50 steps, so it stays inside the table's range).
        let pos = vec![-1e5, 1e5];
        let e = [
            AxisErrors { pos: -1.05e5, ..Default::default() },
            AxisErrors { pos: 1.05e5, ..Default::default() },
        ];
        let g = GeometricMap { x: Some(AxisTable::new(Axis::X, pos, &e).unwrap()), ..Default::default() };
        let c = Corrector { geometric: Some(&g), load: None, probe_offset: Vector3::zeros() };
        let mut t = vec![Point3::new(500.0, 0.0, 0.0)];
        assert!(matches!(c.compensate(&mut t), Err(CompError::NoConvergence { index: 0, .. })));
        let g = smooth_map();
        let c = Corrector { geometric: Some(&g), load: None, probe_offset: Vector3::zeros() };
        let mut pts = vec![Point3::new(1.0, 1.0, 1.0); 10_000];
        pts[9000].y = 1200.0;
        pts[5000].z = -1.0;
        let e = c.correct_measured(&mut pts, None).unwrap_err();
        assert_eq!(e.index(), 5000);
    }

    #[test]
    fn parallel_equals_serial() {
        let g = smooth_map();
        let c = Corrector { geometric: Some(&g), load: None, probe_offset: Vector3::new(0.0, 0.0, -100.0) };
        let pts: Vec<Point3> = (0..20_000)
            .map(|i| Point3::new((i % 1000) as f64, (i / 20) as f64, (i % 7) as f64 * 100.0))
            .collect();
        let mut a = pts.clone();
        let mut cor = vec![Vector3::zeros(); pts.len()];
        c.correct_measured(&mut a, Some(&mut cor)).unwrap();
        for i in (0..pts.len()).step_by(97) {
            let d = c.displacement(&pts[i]).unwrap();
            assert_eq!(a[i], pts[i] + d);
            assert_eq!(cor[i], d);
        }
    }
}
