//! Dense nonlinear least squares for few parameters and many residuals.
//!
//! [`solve`] runs Levenberg-Marquardt (Marquardt's diagonal scaling) on a [`Residuals`] problem.
//! The normal equations `JᵀJ`, `Jᵀr` are accumulated row by row in parallel chunks (rayon), so
//! the Jacobian is never stored: memory is O(n²) whatever the number of residuals, and a pass
//! over millions of points is memory-bound. The result carries the covariance
//! `σ₀²·(JᵀJ)⁻¹`, with `σ₀² = SSR/(m−n)`, and the numerical rank of the column-scaled normal
//! matrix, so callers can refuse to report what the data does not determine.

use crate::types::{DMatrix, DVector};
use rayon::prelude::*;
use thiserror::Error;

/// A least-squares problem: residuals `r_i(p)` and their gradients.
pub trait Residuals: Sync {
    /// Number of parameters `n`.
    fn n_params(&self) -> usize;
    /// Number of residuals `m`.
    fn n_residuals(&self) -> usize;
    /// Residual `i` at `params`; writes `∂r_i/∂p_j` into `jac[j]` (`jac.len() == n_params`).
    fn eval(&self, params: &[f64], i: usize, jac: &mut [f64]) -> f64;
    /// Apply a step. The default is `params + delta`; override for manifold parameters.
    fn step(&self, params: &[f64], delta: &[f64]) -> Vec<f64> {
        params.iter().zip(delta).map(|(p, d)| p + d).collect()
    }
}

/// Stopping and rank criteria for the Levenberg-Marquardt solver [`solve`].
#[derive(Clone, Debug)]
pub struct LsqOptions {
    /// Iterations after which the solver stops, converged or not.
    pub max_iterations: usize,
    /// Converged when every step component is below `x_tol · (|p_j| + x_scale_j)`.
    pub x_tol: f64,
    /// Per-parameter scale used with `x_tol` (defaults to 1 for each).
    pub x_scale: Option<Vec<f64>>,
    /// Relative threshold on the eigenvalues of the scaled normal matrix for the rank.
    pub rank_tol: f64,
    /// Residual count above which accumulation runs in parallel.
    pub parallel_threshold: usize,
}

impl Default for LsqOptions {
    fn default() -> Self {
        Self { max_iterations: 200, x_tol: 1e-13, x_scale: None, rank_tol: 1e-12, parallel_threshold: 20_000 }
    }
}

/// Why a least-squares problem cannot be solved.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LsqError {
    /// Fewer residuals than parameters: the problem is underdetermined.
    #[error("{needed} residuals are needed for {params} parameters, {got} given")]
    TooFewResiduals {
        /// Residuals needed.
        needed: usize,
        /// Number of parameters.
        params: usize,
        /// Residuals given.
        got: usize,
    },
    /// A residual or gradient is NaN or infinite at the starting parameters.
    #[error("a residual or its gradient is not finite at the starting point")]
    NotFinite,
    /// The normal matrix has no usable rank: no parameter is determined.
    #[error("the normal equations are singular: the data does not determine all parameters")]
    Singular,
}

/// The solution of a least-squares problem with its statistics.
#[derive(Clone, Debug)]
pub struct LsqResult {
    /// The parameter vector at the solution, in the problem's own units.
    pub params: Vec<f64>,
    /// Sum of squared residuals at the solution.
    pub ssr: f64,
    /// `sqrt(ssr / (m − n))`, the a-posteriori standard deviation of unit weight.
    pub sigma0: f64,
    /// `σ₀² (JᵀJ)⁺` (pseudo-inverse on the determined subspace).
    pub covariance: DMatrix,
    /// `JᵀJ` at the solution.
    pub normal_matrix: DMatrix,
    /// Numerical rank of the column-scaled normal matrix.
    pub rank: usize,
    /// Ratio of largest to smallest eigenvalue of the column-scaled normal matrix (∞ if singular).
    pub condition: f64,
    /// Iterations taken.
    pub iterations: usize,
    /// Whether the step criterion of [`LsqOptions::x_tol`] was met before the iteration limit.
    pub converged: bool,
    /// Number of residuals `m` (the degrees of freedom are `m − rank`).
    pub n_residuals: usize,
}

impl LsqResult {
    /// Standard uncertainty of parameter `j` (square root of the covariance diagonal).
    pub fn std_dev(&self, j: usize) -> f64 {
        self.covariance[(j, j)].max(0.0).sqrt()
    }
}

/// Accumulated normal equations at one parameter vector.
pub struct Normal {
    /// `JᵀJ`, the normal matrix.
    pub jtj: DMatrix,
    /// `Jᵀr`, the right-hand side (gradient of half the sum of squares).
    pub jtr: DVector,
    /// Sum of squared residuals at the parameter vector.
    pub ssr: f64,
    /// False when a residual or gradient was NaN or infinite (the sums are then meaningless).
    pub finite: bool,
}

/// Accumulate `JᵀJ`, `Jᵀr` and the sum of squares at `params`.
pub fn normal_equations<P: Residuals>(problem: &P, params: &[f64], parallel_threshold: usize) -> Normal {
    let n = problem.n_params();
    let m = problem.n_residuals();
    let chunk = |range: std::ops::Range<usize>| {
        let mut jtj = vec![0.0; n * n];
        let mut jtr = vec![0.0; n];
        let mut ssr = 0.0;
        let mut finite = true;
        let mut row = vec![0.0; n];
        for i in range {
            row.iter_mut().for_each(|x| *x = 0.0);
            let r = problem.eval(params, i, &mut row);
            if !r.is_finite() || row.iter().any(|x| !x.is_finite()) {
                finite = false;
                continue;
            }
            ssr += r * r;
            for a in 0..n {
                let ra = row[a];
                jtr[a] += ra * r;
                for b in 0..=a {
                    jtj[a * n + b] += ra * row[b];
                }
            }
        }
        (jtj, jtr, ssr, finite)
    };
    let merge = |mut x: (Vec<f64>, Vec<f64>, f64, bool), y: (Vec<f64>, Vec<f64>, f64, bool)| {
        x.0.iter_mut().zip(&y.0).for_each(|(a, b)| *a += b);
        x.1.iter_mut().zip(&y.1).for_each(|(a, b)| *a += b);
        (x.0, x.1, x.2 + y.2, x.3 && y.3)
    };
    let (jtj, jtr, ssr, finite) = if m >= parallel_threshold {
        let block = 8192;
        (0..m.div_ceil(block))
            .into_par_iter()
            .map(|k| chunk(k * block..((k + 1) * block).min(m)))
            .reduce(|| (vec![0.0; n * n], vec![0.0; n], 0.0, true), merge)
    } else {
        chunk(0..m)
    };
    let mut jtj = DMatrix::from_row_slice(n, n, &jtj);
    for a in 0..n {
        for b in 0..a {
            jtj[(b, a)] = jtj[(a, b)];
        }
    }
    Normal { jtj, jtr: DVector::from_vec(jtr), ssr, finite }
}

/// The normal matrix with its columns scaled to unit diagonal (`S = D·JᵀJ·D`,
/// `D = diag(1/√(JᵀJ)ᵢᵢ)`, 0 for an all-zero column) and the eigen-decomposition of `S`. Scaling
/// makes ranks and null spaces independent of the parameters' units.
pub struct ScaledEigen {
    /// The scale factors `Dᵢᵢ`.
    pub d: Vec<f64>,
    /// Eigenvalues of `S`, ascending.
    pub eigenvalues: DVector,
    /// Columns are the eigenvectors of `S`.
    pub eigenvectors: DMatrix,
    /// The largest eigenvalue of `S` (the reference for relative rank tests).
    pub max: f64,
}

/// Scale `JᵀJ` to unit diagonal and decompose it (see [`ScaledEigen`]).
pub fn scaled_eigen(jtj: &DMatrix) -> ScaledEigen {
    let n = jtj.nrows();
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let v = jtj[(i, i)];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let mut s = jtj.clone();
    for a in 0..n {
        for b in 0..n {
            s[(a, b)] *= d[a] * d[b];
        }
    }
    let eig = s.symmetric_eigen();
    let max = eig.eigenvalues.iter().cloned().fold(0.0f64, f64::max);
    ScaledEigen { d, eigenvalues: eig.eigenvalues, eigenvectors: eig.eigenvectors, max }
}

/// Rank and condition of the normal matrix after scaling its columns to unit diagonal.
pub fn scaled_rank(jtj: &DMatrix, rank_tol: f64) -> (usize, f64) {
    let e = scaled_eigen(jtj);
    let min = e.eigenvalues.iter().cloned().fold(f64::INFINITY, f64::min);
    let rank = e.eigenvalues.iter().filter(|&&v| v > rank_tol * e.max.max(f64::MIN_POSITIVE)).count();
    let cond = if min > 0.0 { e.max / min } else { f64::INFINITY };
    (rank, cond)
}

/// For each parameter column in `cols`: whether a null direction of the column-scaled normal
/// matrix (eigenvalue ≤ `null_tol · max`) has a share above `share` (squared component) on it,
/// or the column is all zero — i.e. the data cannot determine that parameter.
pub fn null_space_flags(jtj: &DMatrix, cols: &[usize], null_tol: f64, share: f64) -> Vec<bool> {
    let e = scaled_eigen(jtj);
    let mut out = vec![false; cols.len()];
    for k in 0..jtj.nrows() {
        if e.eigenvalues[k] <= null_tol * e.max {
            for (o, &col) in out.iter_mut().zip(cols) {
                if e.eigenvectors[(col, k)].powi(2) > share {
                    *o = true;
                }
            }
        }
    }
    for (o, &col) in out.iter_mut().zip(cols) {
        if e.d[col] == 0.0 {
            *o = true;
        }
    }
    out
}

/// Pseudo-inverse of a symmetric positive semi-definite matrix through column scaling and
/// its eigen-decomposition, dropping eigenvalues below `rank_tol · max`.
pub fn spd_pinv(jtj: &DMatrix, rank_tol: f64) -> DMatrix {
    let n = jtj.nrows();
    let e = scaled_eigen(jtj);
    let mut inv = DMatrix::zeros(n, n);
    for k in 0..n {
        let v = e.eigenvalues[k];
        if v > rank_tol * e.max && v > 0.0 {
            let c = e.eigenvectors.column(k);
            inv += (c * c.transpose()) / v;
        }
    }
    for a in 0..n {
        for b in 0..n {
            inv[(a, b)] *= e.d[a] * e.d[b];
        }
    }
    inv
}

/// Levenberg-Marquardt from `x0`.
pub fn solve<P: Residuals>(problem: &P, x0: &[f64], opt: &LsqOptions) -> Result<LsqResult, LsqError> {
    let n = problem.n_params();
    let m = problem.n_residuals();
    if m < n {
        return Err(LsqError::TooFewResiduals { needed: n, params: n, got: m });
    }
    let mut x = x0.to_vec();
    let mut ne = normal_equations(problem, &x, opt.parallel_threshold);
    if !ne.finite {
        return Err(LsqError::NotFinite);
    }
    let mut lambda = 1e-6;
    let mut converged = false;
    let mut iterations = 0;
    let scale = |j: usize| opt.x_scale.as_ref().map_or(1.0, |s| s[j]);
    while iterations < opt.max_iterations {
        iterations += 1;
        let mut accepted = false;
        for _ in 0..40 {
            let mut a = ne.jtj.clone();
            for j in 0..n {
                let dj = ne.jtj[(j, j)].max(1e-300);
                a[(j, j)] += lambda * dj;
            }
            let Some(chol) = a.cholesky() else {
                lambda = (lambda * 10.0).max(1e-12);
                continue;
            };
            let delta = chol.solve(&(-&ne.jtr));
            let xn = problem.step(&x, delta.as_slice());
            let nn = normal_equations(problem, &xn, opt.parallel_threshold);
            if nn.finite && nn.ssr <= ne.ssr {
                let small = (0..n).all(|j| delta[j].abs() <= opt.x_tol * (x[j].abs() + scale(j)));
                let no_gain = ne.ssr - nn.ssr <= 1e-15 * ne.ssr;
                x = xn;
                ne = nn;
                lambda = (lambda / 10.0).max(1e-15);
                accepted = true;
                if small || (no_gain && lambda <= 1e-9) {
                    converged = true;
                }
                break;
            }
            lambda *= 10.0;
            if lambda > 1e20 {
                break;
            }
        }
        if converged {
            break;
        }
        if !accepted {
            // No step decreases the sum of squares: we sit at the minimum to rounding.
            converged = true;
            break;
        }
    }
    let (rank, condition) = scaled_rank(&ne.jtj, opt.rank_tol);
    let dof = (m as f64 - n as f64).max(1.0);
    let sigma0 = (ne.ssr / dof).sqrt();
    let covariance = spd_pinv(&ne.jtj, opt.rank_tol) * (sigma0 * sigma0);
    Ok(LsqResult {
        params: x,
        ssr: ne.ssr,
        sigma0,
        covariance,
        normal_matrix: ne.jtj,
        rank,
        condition,
        iterations,
        converged,
        n_residuals: m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exponential decay y = a·exp(−b·t): a classic LM check with an exact solution.
    struct Decay {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl Residuals for Decay {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.t.len()
        }
        fn eval(&self, p: &[f64], i: usize, jac: &mut [f64]) -> f64 {
            let e = (-p[1] * self.t[i]).exp();
            jac[0] = e;
            jac[1] = -p[0] * self.t[i] * e;
            p[0] * e - self.y[i]
        }
    }

    #[test]
    fn recovers_exact_parameters_and_zero_residual() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y = t.iter().map(|t| 3.0 * (-0.7 * t).exp()).collect();
        let r = solve(&Decay { t, y }, &[1.0, 0.1], &LsqOptions::default()).unwrap();
        assert!(r.converged);
        assert!((r.params[0] - 3.0).abs() < 1e-12, "{:?}", r.params);
        assert!((r.params[1] - 0.7).abs() < 1e-12);
        assert_eq!(r.rank, 2);
    }

    /// Straight-line fit: the covariance must equal the textbook formula.
    struct Line {
        x: Vec<f64>,
        y: Vec<f64>,
    }
    impl Residuals for Line {
        fn n_params(&self) -> usize {
            2
        }
        fn n_residuals(&self) -> usize {
            self.x.len()
        }
        fn eval(&self, p: &[f64], i: usize, jac: &mut [f64]) -> f64 {
            jac[0] = 1.0;
            jac[1] = self.x[i];
            p[0] + p[1] * self.x[i] - self.y[i]
        }
    }

    #[test]
    fn covariance_matches_textbook_regression() {
        let x: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let noise = [0.1, -0.2, 0.05, 0.0, 0.3, -0.1, -0.05, 0.2, -0.3, 0.1];
        let y: Vec<f64> = x.iter().zip(noise).map(|(x, e)| 1.0 + 2.0 * x + e).collect();
        let r = solve(&Line { x: x.clone(), y: y.clone() }, &[0.0, 0.0], &LsqOptions::default()).unwrap();
        let n = x.len() as f64;
        let mx = x.iter().sum::<f64>() / n;
        let sxx: f64 = x.iter().map(|x| (x - mx).powi(2)).sum();
        let s2 = r.ssr / (n - 2.0);
        assert!((r.std_dev(1) - (s2 / sxx).sqrt()).abs() < 1e-12);
        assert!((r.std_dev(0) - (s2 * (1.0 / n + mx * mx / sxx)).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn rank_deficiency_is_reported() {
        // Two identical columns: p0 + p1 is determined, the split is not.
        struct Dup;
        impl Residuals for Dup {
            fn n_params(&self) -> usize {
                2
            }
            fn n_residuals(&self) -> usize {
                5
            }
            fn eval(&self, p: &[f64], i: usize, jac: &mut [f64]) -> f64 {
                jac[0] = 1.0;
                jac[1] = 1.0;
                p[0] + p[1] - i as f64
            }
        }
        let r = solve(&Dup, &[0.0, 0.0], &LsqOptions::default()).unwrap();
        assert_eq!(r.rank, 1);
        assert!(r.condition.is_infinite() || r.condition > 1e12);
    }
}
