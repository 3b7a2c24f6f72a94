//! Piecewise-linear interpolation on sorted abscissae.
//!
//! Entry points: [`linear`] (one value of a table `x → y`, extended linearly outside it),
//! [`linear_sorted`] (many sorted query points in one pass) and [`locate`] (index of the
//! interval holding `x`, by binary search).

/// Index `i` with `xs[i] <= x < xs[i+1]` (clamped to `0..=len-2`). `xs` sorted, `len >= 2`.
#[inline]
pub fn locate(xs: &[f64], x: f64) -> usize {
    let i = xs.partition_point(|&v| v <= x);
    i.saturating_sub(1).min(xs.len().saturating_sub(2))
}

/// Linear interpolation of `ys` over strictly increasing `xs` at `x`. Outside the table the end
/// segments are extended linearly. Needs `xs.len() >= 2` (returns `ys[0]` for a single value).
#[inline]
pub fn linear(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    if xs.len() < 2 {
        return ys.first().copied().unwrap_or(f64::NAN);
    }
    let i = locate(xs, x);
    let t = (x - xs[i]) / (xs[i + 1] - xs[i]);
    ys[i] + t * (ys[i + 1] - ys[i])
}

/// Interpolate a whole series `ys(xs)` at the sorted query abscissae `q` in one merge pass
/// (O(n + m), no binary searches). Queries outside `xs` extrapolate linearly.
pub fn linear_sorted(xs: &[f64], ys: &[f64], q: &[f64], out: &mut Vec<f64>) {
    out.clear();
    out.reserve(q.len());
    if xs.len() < 2 {
        out.extend(q.iter().map(|_| ys.first().copied().unwrap_or(f64::NAN)));
        return;
    }
    let mut i = 0;
    for &x in q {
        while i + 2 < xs.len() && xs[i + 1] <= x {
            i += 1;
        }
        let t = (x - xs[i]) / (xs[i + 1] - xs[i]);
        out.push(ys[i] + t * (ys[i + 1] - ys[i]));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_and_extrapolates_linear_data_exactly() {
        let xs = [0.0, 1.0, 3.0, 4.0];
        let ys: Vec<f64> = xs.iter().map(|x| 2.0 * x - 1.0).collect();
        for x in [-1.0, 0.0, 0.5, 2.0, 3.999, 4.0, 7.0] {
            assert!((linear(&xs, &ys, x) - (2.0 * x - 1.0)).abs() < 1e-12);
        }
        let q = [-1.0, 0.25, 2.5, 3.5, 9.0];
        let mut out = Vec::new();
        linear_sorted(&xs, &ys, &q, &mut out);
        for (x, y) in q.iter().zip(&out) {
            assert!((y - (2.0 * x - 1.0)).abs() < 1e-12);
        }
    }
}
