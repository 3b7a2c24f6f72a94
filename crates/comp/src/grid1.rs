//! Interval lookup on a sorted 1-D grid: O(1) on uniform grids (detected once), binary search
//! otherwise. Used by every table of the crate (axis tables, portal curves, influence grids).
//!
//! Entry point: [`Grid1`] with [`Grid1::locate`] returning the interval index and the fraction.

/// Sorted, strictly increasing abscissae with a fast interval lookup.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid1 {
    xs: Vec<f64>,
    /// `(first, 1/step)` when the grid is uniform to 1e-9 of its span.
    uniform: Option<(f64, f64)>,
}

/// Why a grid cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// No positions.
    #[error("no positions")]
    Empty,
    /// The positions are not finite and strictly increasing.
    #[error("positions must be finite and strictly increasing (position {index}: {value} after {previous})")]
    NotIncreasing {
        /// 0-based index of the offending position.
        index: usize,
        /// Its value.
        value: f64,
        /// The value before it.
        previous: f64,
    },
}

impl Grid1 {
    /// A grid of finite, strictly increasing positions.
    pub fn new(xs: Vec<f64>) -> Result<Self, GridError> {
        if xs.is_empty() {
            return Err(GridError::Empty);
        }
        for i in 0..xs.len() {
            if !xs[i].is_finite() || (i > 0 && xs[i] <= xs[i - 1]) {
                return Err(GridError::NotIncreasing {
                    index: i,
                    value: xs[i],
                    previous: if i > 0 { xs[i - 1] } else { f64::NAN },
                });
            }
        }
        let n = xs.len();
        let uniform = if n >= 2 {
            let span = xs[n - 1] - xs[0];
            let step = span / (n - 1) as f64;
            let tol = 1e-9 * span.abs().max(1.0);
            xs.iter()
                .enumerate()
                .all(|(i, &x)| (x - (xs[0] + i as f64 * step)).abs() <= tol)
                .then_some((xs[0], 1.0 / step))
        } else {
            None
        };
        Ok(Self { xs, uniform })
    }

    /// The positions.
    pub fn values(&self) -> &[f64] {
        &self.xs
    }
    /// Number of positions.
    pub fn len(&self) -> usize {
        self.xs.len()
    }
    /// Whether there are no positions (never, for a grid built by [`Grid1::new`]).
    pub fn is_empty(&self) -> bool {
        self.xs.is_empty()
    }
    /// The first position.
    pub fn first(&self) -> f64 {
        self.xs[0]
    }
    /// The last position.
    pub fn last(&self) -> f64 {
        self.xs[self.xs.len() - 1]
    }
    /// Whether the positions are equally spaced (lookups are then direct).
    pub fn is_uniform(&self) -> bool {
        self.uniform.is_some()
    }

    /// `(i, f)` with `x = xs[i] + f·(xs[i+1] − xs[i])`, `0 ≤ f ≤ 1`, or `None` outside
    /// `[first, last]`. With `clamp`, positions outside are held at the end values. A
    /// single-position grid is constant: `(0, 0)` everywhere.
    #[inline]
    pub fn locate(&self, x: f64, clamp: bool) -> Option<(usize, f64)> {
        let n = self.xs.len();
        if n == 1 {
            return (clamp || x == self.xs[0]).then_some((0, 0.0));
        }
        let (lo, hi) = (self.xs[0], self.xs[n - 1]);
        // NaN fails both comparisons and is rejected below.
        let x = if x >= lo && x <= hi {
            x
        } else if clamp && !x.is_nan() {
            x.clamp(lo, hi)
        } else {
            return None;
        };
        match self.uniform {
            Some((x0, inv)) => {
                // O(1): the fraction comes from the same product, no division.
                let u = (x - x0) * inv;
                let i = (u as usize).min(n - 2);
                Some((i, (u - i as f64).clamp(0.0, 1.0)))
            }
            None => {
                let i = self.xs.partition_point(|&v| v <= x).saturating_sub(1).min(n - 2);
                Some((i, ((x - self.xs[i]) / (self.xs[i + 1] - self.xs[i])).clamp(0.0, 1.0)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_and_nonuniform_agree() {
        let u = Grid1::new((0..11).map(|i| -50.0 + 10.0 * i as f64).collect()).unwrap();
        assert!(u.is_uniform());
        let mut v: Vec<f64> = (0..11).map(|i| -50.0 + 10.0 * i as f64).collect();
        v[3] += 1e-3; // breaks uniformity but keeps the intervals comparable
        let nu = Grid1::new(v.clone()).unwrap();
        assert!(!nu.is_uniform());
        for k in 0..=1000 {
            let x = -50.0 + 0.1 * k as f64;
            let (i, f) = u.locate(x, false).unwrap();
            // Reconstruct x from the interval: exact to rounding.
            assert!((u.values()[i] + f * 10.0 - x).abs() < 1e-9);
            let (j, g) = nu.locate(x, false).unwrap();
            assert!((v[j] + g * (v[j + 1] - v[j]) - x).abs() < 1e-9, "{x}");
        }
        assert_eq!(u.locate(50.0, false), Some((9, 1.0)));
        assert_eq!(u.locate(50.0 + 1e-9, false), None);
        assert_eq!(u.locate(-51.0, true), Some((0, 0.0)));
        assert_eq!(u.locate(f64::NAN, true), None);
    }

    #[test]
    fn rejects_bad_grids() {
        assert_eq!(Grid1::new(vec![]), Err(GridError::Empty));
        assert!(Grid1::new(vec![0.0, 1.0, 1.0]).is_err());
        assert!(Grid1::new(vec![0.0, f64::NAN]).is_err());
        let one = Grid1::new(vec![5.0]).unwrap();
        assert_eq!(one.locate(5.0, false), Some((0, 0.0)));
        assert_eq!(one.locate(6.0, false), None);
    }
}
