//! Small dense linear programs with few variables and many constraints:
//! minimise `cᵀx` subject to `A x ≤ b`, `x ∈ Rᵈ` free, `d ≤ MAXD`.
//!
//! Solved as its dual, `min bᵀy` subject to `Aᵀy = −c`, `y ≥ 0`, by a two-phase revised
//! simplex: the basis is only `d × d` (re-inverted from scratch at every pivot, which costs
//! nothing at this size and keeps rounding from accumulating), and pricing one constraint costs
//! one dot product. In phase 2 the reduced cost of constraint `i` is exactly the primal slack
//! `bᵢ − aᵢᵀx` at the current vertex, so every pivot brings in the most violated constraint
//! (the dual simplex seen from the primal); the simplex multipliers of the optimal basis are the
//! primal solution `x`. Dantzig's rule, with Bland's rule after a run of degenerate pivots so
//! that the method cannot cycle.
//!
//! Entry point: [`minimise`]. The caller scales the problem so that entries are of order 1:
//! the feasibility tolerance is absolute ([`TOL`]).

pub(crate) const MAXD: usize = 8;
/// Absolute tolerance on slacks and pivots, for problems scaled to entries of order 1.
pub(crate) const TOL: f64 = 1e-13;

/// One constraint `aᵀx ≤ b` (the first `d` entries of `a` are used).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Row {
    pub a: [f64; MAXD],
    pub b: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum LpError {
    /// The constraints contradict each other.
    Infeasible,
    /// The objective decreases without bound, or the constraints do not determine `x`.
    Unbounded,
    /// The pivot limit was reached (should not happen; reported rather than looping).
    IterationLimit,
}

type Mat = [[f64; MAXD]; MAXD];

/// Inverse of the leading `d × d` block of `m` by Gauss-Jordan with partial pivoting.
fn invert(m: &Mat, d: usize) -> Option<Mat> {
    let mut a = *m;
    let mut inv = [[0.0; MAXD]; MAXD];
    for (i, row) in inv.iter_mut().enumerate().take(d) {
        row[i] = 1.0;
    }
    for col in 0..d {
        let mut p = col;
        for r in col + 1..d {
            if a[r][col].abs() > a[p][col].abs() {
                p = r;
            }
        }
        if !(a[p][col].abs() > 1e-300) {
            return None;
        }
        a.swap(col, p);
        inv.swap(col, p);
        let piv = 1.0 / a[col][col];
        for k in 0..d {
            a[col][k] *= piv;
            inv[col][k] *= piv;
        }
        for r in 0..d {
            if r != col {
                let f = a[r][col];
                if f != 0.0 {
                    for k in 0..d {
                        a[r][k] -= f * a[col][k];
                        inv[r][k] -= f * inv[col][k];
                    }
                }
            }
        }
    }
    Some(inv)
}

/// Solution of [`minimise`].
#[derive(Clone, Debug)]
pub(crate) struct LpSolution {
    pub x: [f64; MAXD],
    pub objective: f64,
}

/// Minimise `cᵀx` subject to `rows` (`aᵀx ≤ b`), `x ∈ Rᵈ`.
pub(crate) fn minimise(d: usize, c: &[f64], rows: &[Row]) -> Result<LpSolution, LpError> {
    assert!(d <= MAXD && c.len() == d);
    let m = rows.len();
    // Equality rows of the dual: Σ_i y_i a_i = −c. Flip rows so that the right-hand side ≥ 0.
    let mut sign = [1.0; MAXD];
    let mut rhs = [0.0; MAXD];
    for k in 0..d {
        rhs[k] = -c[k];
        if rhs[k] < 0.0 {
            sign[k] = -1.0;
            rhs[k] = -rhs[k];
        }
    }
    // Column j of the dual: j < m a constraint, j ≥ m the artificial for row j − m.
    let col = |j: usize| -> [f64; MAXD] {
        let mut v = [0.0; MAXD];
        if j < m {
            for k in 0..d {
                v[k] = sign[k] * rows[j].a[k];
            }
        } else {
            v[j - m] = 1.0;
        }
        v
    };
    let mut basis: [usize; MAXD] = [0; MAXD];
    for k in 0..d {
        basis[k] = m + k;
    }
    let max_pivots = 50 * (m + d) + 1000;
    let mut pivots = 0;
    let mut degenerate_run = 0;
    for phase in 1..=2 {
        loop {
            pivots += 1;
            if pivots > max_pivots {
                return Err(LpError::IterationLimit);
            }
            let mut bm = [[0.0; MAXD]; MAXD];
            for (k, &j) in basis.iter().enumerate().take(d) {
                let v = col(j);
                for r in 0..d {
                    bm[r][k] = v[r];
                }
            }
            let binv = invert(&bm, d).ok_or(LpError::Unbounded)?;
            // Basic values x_B = B⁻¹ rhs and multipliers π = B⁻ᵀ c_B.
            let mut xb = [0.0; MAXD];
            let mut cb = [0.0; MAXD];
            for r in 0..d {
                xb[r] = (0..d).map(|k| binv[r][k] * rhs[k]).sum::<f64>().max(0.0);
                let j = basis[r];
                cb[r] = if phase == 1 {
                    if j >= m {
                        1.0
                    } else {
                        0.0
                    }
                } else if j >= m {
                    0.0
                } else {
                    rows[j].b
                };
            }
            let mut pi = [0.0; MAXD];
            for k in 0..d {
                pi[k] = (0..d).map(|r| binv[r][k] * cb[r]).sum();
            }
            // The primal point x = S π.
            let mut x = [0.0; MAXD];
            for k in 0..d {
                x[k] = sign[k] * pi[k];
            }
            // Pricing: reduced cost of constraint i.
            let bland = degenerate_run > 2 * d + 10;
            let mut enter = usize::MAX;
            let mut best = -TOL;
            for (i, row) in rows.iter().enumerate() {
                let ax: f64 = (0..d).map(|k| row.a[k] * x[k]).sum();
                let rc = if phase == 1 { -ax } else { row.b - ax };
                let scale = 1.0 + row.b.abs();
                if rc < best * scale {
                    enter = i;
                    if bland {
                        break;
                    }
                    best = rc / scale;
                }
            }
            if phase == 1 {
                for k in 0..d {
                    let j = m + k;
                    if basis[..d].contains(&j) {
                        continue;
                    }
                    let rc = 1.0 - pi[k];
                    if enter == usize::MAX && rc < best {
                        enter = j;
                        best = rc;
                    }
                }
            }
            if enter == usize::MAX {
                if phase == 1 {
                    let art: f64 = (0..d).filter(|&r| basis[r] >= m).map(|r| xb[r]).sum();
                    let scale = 1.0 + rhs[..d].iter().fold(0.0f64, |a, &v| a.max(v));
                    if art > 1e-9 * scale {
                        // The dual is infeasible: the primal is unbounded.
                        return Err(LpError::Unbounded);
                    }
                    // Drive zero-level artificials out of the basis.
                    for r in 0..d {
                        if basis[r] < m {
                            continue;
                        }
                        let mut bestv = 1e-9;
                        let mut q = usize::MAX;
                        for i in 0..m {
                            if basis[..d].contains(&i) {
                                continue;
                            }
                            let v = col(i);
                            let w: f64 = (0..d).map(|k| binv[r][k] * v[k]).sum();
                            if w.abs() > bestv {
                                bestv = w.abs();
                                q = i;
                            }
                        }
                        if q == usize::MAX {
                            // A redundant equality: the constraints do not determine x.
                            return Err(LpError::Unbounded);
                        }
                        basis[r] = q;
                    }
                    degenerate_run = 0;
                    break;
                }
                let objective = (0..d).map(|k| c[k] * x[k]).sum();
                return Ok(LpSolution { x, objective });
            }
            // Ratio test on the entering column.
            let v = col(enter);
            let mut w = [0.0; MAXD];
            for r in 0..d {
                w[r] = (0..d).map(|k| binv[r][k] * v[k]).sum();
            }
            let mut leave = usize::MAX;
            let mut ratio = f64::INFINITY;
            for r in 0..d {
                if w[r] > 1e-11 {
                    let t = xb[r] / w[r];
                    let better = t < ratio - 1e-15
                        || (t <= ratio + 1e-15
                            && leave != usize::MAX
                            && (if bland { basis[r] < basis[leave] } else { w[r] > w[leave] }));
                    if better {
                        ratio = t;
                        leave = r;
                    }
                }
            }
            if leave == usize::MAX {
                // Dual unbounded: the primal constraints contradict each other.
                return Err(LpError::Infeasible);
            }
            if ratio < 1e-14 {
                degenerate_run += 1;
            } else {
                degenerate_run = 0;
            }
            basis[leave] = enter;
        }
    }
    Err(LpError::IterationLimit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(a: &[f64], b: f64) -> Row {
        let mut r = Row { a: [0.0; MAXD], b };
        r.a[..a.len()].copy_from_slice(a);
        r
    }

    #[test]
    fn chebyshev_line_through_three_points() {
        // min t s.t. |y_i − (m x_i + q)| ≤ t for (0,0), (1,1), (2,0): m = 0, q = 0.5, t = 0.5.
        let pts = [(0.0, 0.0), (1.0, 1.0), (2.0, 0.0)];
        let mut rows = vec![];
        for &(x, y) in &pts {
            rows.push(row(&[-x, -1.0, -1.0], -y));
            rows.push(row(&[x, 1.0, -1.0], y));
        }
        let s = minimise(3, &[0.0, 0.0, 1.0], &rows).unwrap();
        assert!((s.x[0]).abs() < 1e-12 && (s.x[1] - 0.5).abs() < 1e-12 && (s.x[2] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn textbook_problem_and_infeasible_unbounded() {
        // max 3x + 5y s.t. x ≤ 4, 2y ≤ 12, 3x + 2y ≤ 18, x, y ≥ 0: optimum (2, 6), 36.
        let rows = vec![
            row(&[1.0, 0.0], 4.0),
            row(&[0.0, 2.0], 12.0),
            row(&[3.0, 2.0], 18.0),
            row(&[-1.0, 0.0], 0.0),
            row(&[0.0, -1.0], 0.0),
        ];
        let s = minimise(2, &[-3.0, -5.0], &rows).unwrap();
        assert!((s.x[0] - 2.0).abs() < 1e-12 && (s.x[1] - 6.0).abs() < 1e-12);
        assert!((s.objective + 36.0).abs() < 1e-10);
        let bad = vec![row(&[1.0], 1.0), row(&[-1.0], -2.0)];
        assert_eq!(minimise(1, &[1.0], &bad).unwrap_err(), LpError::Infeasible);
        let open = vec![row(&[1.0], 1.0)];
        assert_eq!(minimise(1, &[1.0], &open).unwrap_err(), LpError::Unbounded);
    }
}
