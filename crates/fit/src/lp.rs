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

/// Minimise `cᵀx` subject to `rows` (`aᵀx ≤ b`), `x ∈ Rᵈ`: the revised simplex method on the
/// dual (equality rows Σ yᵢ aᵢ = −c, y ≥ 0; phase 1 with one artificial per row, phase 2 on
/// the constraints' right-hand sides), Bland's rule after a run of degenerate pivots.
pub(crate) fn minimise(d: usize, c: &[f64], rows: &[Row]) -> Result<LpSolution, LpError> {
    assert!(d <= MAXD && c.len() == d);
    let mut dual = Dual::new(d, c, rows);
    let max_pivots = 50 * (rows.len() + d) + 1000;
    let mut pivots = 0;
    let mut degenerate_run = 0;
    for phase in [Phase::One, Phase::Two] {
        loop {
            pivots += 1;
            if pivots > max_pivots {
                return Err(LpError::IterationLimit);
            }
            let it = dual.iterate(phase)?;
            let bland = degenerate_run > 2 * d + 10;
            let Some(enter) = dual.price(phase, &it, bland) else {
                if phase == Phase::One {
                    dual.end_phase_one(&it)?;
                    degenerate_run = 0;
                    break;
                }
                let objective = (0..d).map(|k| c[k] * it.x[k]).sum();
                return Ok(LpSolution { x: it.x, objective });
            };
            let (leave, ratio) = dual.ratio_test(enter, &it, bland)?;
            degenerate_run = if ratio < 1e-14 { degenerate_run + 1 } else { 0 };
            dual.basis[leave] = enter;
        }
    }
    Err(LpError::IterationLimit)
}

/// The two phases of the simplex method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Find a feasible basis of the dual (minimise the artificials).
    One,
    /// Optimise from it.
    Two,
}

/// The dual problem of [`minimise`]: column j < m is constraint j, j ≥ m the artificial of row
/// j − m; rows flipped so that the right-hand side is ≥ 0.
struct Dual<'a> {
    d: usize,
    m: usize,
    rows: &'a [Row],
    sign: [f64; MAXD],
    rhs: [f64; MAXD],
    basis: [usize; MAXD],
}

/// One iteration's factorisation: B⁻¹, the basic values x_B = B⁻¹ rhs, the multipliers
/// π = B⁻ᵀ c_B and the primal point x = S π.
struct Iterate {
    binv: [[f64; MAXD]; MAXD],
    xb: [f64; MAXD],
    pi: [f64; MAXD],
    x: [f64; MAXD],
}

impl<'a> Dual<'a> {
    fn new(d: usize, c: &[f64], rows: &'a [Row]) -> Dual<'a> {
        let mut sign = [1.0; MAXD];
        let mut rhs = [0.0; MAXD];
        for k in 0..d {
            rhs[k] = -c[k];
            if rhs[k] < 0.0 {
                sign[k] = -1.0;
                rhs[k] = -rhs[k];
            }
        }
        let m = rows.len();
        let mut basis: [usize; MAXD] = [0; MAXD];
        for (k, b) in basis.iter_mut().enumerate().take(d) {
            *b = m + k;
        }
        Dual { d, m, rows, sign, rhs, basis }
    }

    /// Column `j` of the dual's equality rows.
    fn col(&self, j: usize) -> [f64; MAXD] {
        let mut v = [0.0; MAXD];
        if j < self.m {
            for k in 0..self.d {
                v[k] = self.sign[k] * self.rows[j].a[k];
            }
        } else {
            v[j - self.m] = 1.0;
        }
        v
    }

    /// Factor the current basis (a singular basis: the constraints do not bound x).
    fn iterate(&self, phase: Phase) -> Result<Iterate, LpError> {
        let (d, m) = (self.d, self.m);
        let mut bm = [[0.0; MAXD]; MAXD];
        for (k, &j) in self.basis.iter().enumerate().take(d) {
            let v = self.col(j);
            for r in 0..d {
                bm[r][k] = v[r];
            }
        }
        let binv = invert(&bm, d).ok_or(LpError::Unbounded)?;
        let mut xb = [0.0; MAXD];
        let mut cb = [0.0; MAXD];
        for r in 0..d {
            xb[r] = (0..d).map(|k| binv[r][k] * self.rhs[k]).sum::<f64>().max(0.0);
            let j = self.basis[r];
            cb[r] = match (phase, j >= m) {
                (Phase::One, true) => 1.0,
                (Phase::One, false) | (Phase::Two, true) => 0.0,
                (Phase::Two, false) => self.rows[j].b,
            };
        }
        let mut pi = [0.0; MAXD];
        let mut x = [0.0; MAXD];
        for k in 0..d {
            pi[k] = (0..d).map(|r| binv[r][k] * cb[r]).sum();
            x[k] = self.sign[k] * pi[k];
        }
        Ok(Iterate { binv, xb, pi, x })
    }

    /// The entering column: the most negative scaled reduced cost (the first negative under
    /// Bland's rule); in phase 1 also a non-basic artificial. `None` at the optimum.
    fn price(&self, phase: Phase, it: &Iterate, bland: bool) -> Option<usize> {
        let d = self.d;
        let mut enter = None;
        let mut best = -TOL;
        for (i, row) in self.rows.iter().enumerate() {
            let ax: f64 = (0..d).map(|k| row.a[k] * it.x[k]).sum();
            let rc = if phase == Phase::One { -ax } else { row.b - ax };
            let scale = 1.0 + row.b.abs();
            if rc < best * scale {
                enter = Some(i);
                if bland {
                    break;
                }
                best = rc / scale;
            }
        }
        if phase == Phase::One {
            for k in 0..d {
                let j = self.m + k;
                if self.basis[..d].contains(&j) {
                    continue;
                }
                let rc = 1.0 - it.pi[k];
                if enter.is_none() && rc < best {
                    enter = Some(j);
                    best = rc;
                }
            }
        }
        enter
    }

    /// At the end of phase 1: an artificial left above zero means the dual is infeasible (the
    /// primal unbounded); zero-level artificials are driven out of the basis (none can go: a
    /// redundant equality, x not determined).
    fn end_phase_one(&mut self, it: &Iterate) -> Result<(), LpError> {
        let (d, m) = (self.d, self.m);
        let art: f64 = (0..d).filter(|&r| self.basis[r] >= m).map(|r| it.xb[r]).sum();
        let scale = 1.0 + self.rhs[..d].iter().fold(0.0f64, |a, &v| a.max(v));
        if art > 1e-9 * scale {
            return Err(LpError::Unbounded);
        }
        for r in 0..d {
            if self.basis[r] < m {
                continue;
            }
            let mut bestv = 1e-9;
            let mut q = None;
            for i in 0..m {
                if self.basis[..d].contains(&i) {
                    continue;
                }
                let v = self.col(i);
                let w: f64 = (0..d).map(|k| it.binv[r][k] * v[k]).sum();
                if w.abs() > bestv {
                    bestv = w.abs();
                    q = Some(i);
                }
            }
            self.basis[r] = q.ok_or(LpError::Unbounded)?;
        }
        Ok(())
    }

    /// The leaving row for column `enter` and its step (no positive entry: the dual is
    /// unbounded, the primal constraints contradict each other).
    fn ratio_test(&self, enter: usize, it: &Iterate, bland: bool) -> Result<(usize, f64), LpError> {
        let d = self.d;
        let v = self.col(enter);
        let mut leave: Option<usize> = None;
        let mut ratio = f64::INFINITY;
        let mut w = [0.0; MAXD];
        for r in 0..d {
            w[r] = (0..d).map(|k| it.binv[r][k] * v[k]).sum();
        }
        for r in 0..d {
            if w[r] > 1e-11 {
                let t = it.xb[r] / w[r];
                let better = t < ratio - 1e-15
                    || (t <= ratio + 1e-15
                        && leave.is_some_and(|l| {
                            if bland {
                                self.basis[r] < self.basis[l]
                            } else {
                                w[r] > w[l]
                            }
                        }));
                if better {
                    ratio = t;
                    leave = Some(r);
                }
            }
        }
        leave.map(|l| (l, ratio)).ok_or(LpError::Infeasible)
    }
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
