//! Statics of a workpiece resting on the bed: how its weight is shared among its resting points.
//!
//! Entry points: [`distribute`] (weight and centre of gravity → forces), [`check_explicit`]
//! (user-given forces → weight and centre of gravity, with balance checks).
//!
//! Balance: `Σ F_k = W`, `Σ F_k (x_k − c_x) = 0`, `Σ F_k (y_k − c_y) = 0`. With three resting
//! points not on one line this has exactly one solution. With more, the minimum-norm solution
//! `F = Aᵀ (A Aᵀ)⁻¹ b` (the contract's choice: the distribution a statically indeterminate
//! support takes when all points are equally stiff and the part is rigid). With collinear points
//! (or fewer than three), a balanced distribution exists only if the centre of gravity lies on
//! their line (segment); otherwise the case is rejected.
//!
//! A negative force would be tension: a part that merely rests cannot pull on the bed, so the
//! part would tip. That happens when the centre of gravity lies outside the support polygon
//! (or, for the minimum-norm distribution of four or more points, when the layout is very
//! uneven); it is rejected as an input error ([`StaticsError::Tension`]) — give the forces
//! explicitly if they are known (load cells).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Why a load case cannot be balanced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StaticsError {
    /// No resting points.
    #[error("no resting points")]
    NoRestPoints,
    /// The weight is not positive and finite (N).
    #[error("the weight must be positive and finite (got {0} N)")]
    BadWeight(f64),
    /// A resting point or the centre of gravity is not finite.
    #[error("a resting point or the centre of gravity is not finite")]
    NotFinite,
    /// The resting points cannot balance the load (collinear or one point off the CoG).
    #[error("the {n} resting point(s) cannot carry the load: the centre of gravity ({cx}, {cy}) mm is not on their line/point, so forces and moments cannot balance (residual moment {moment_nmm:.3e} N·mm); give at least three resting points around the centre of gravity")]
    CannotBalance {
        /// Number of resting points.
        n: usize,
        /// CoG X, mm.
        cx: f64,
        /// CoG Y, mm.
        cy: f64,
        /// The unbalanced moment, N·mm.
        moment_nmm: f64,
    },
    /// A resting point would have to pull.
    #[error("resting point {index} ({x}, {y}) mm would need a tension of {force:.3} N: the centre of gravity is outside the support polygon (or the minimum-norm distribution needs tension); the part cannot rest like this — give the forces explicitly if they are known")]
    Tension {
        /// 0-based index of the point.
        index: usize,
        /// Its X, mm.
        x: f64,
        /// Its Y, mm.
        y: f64,
        /// The (negative) force it would need, N.
        force: f64,
    },
    /// An explicit force is negative.
    #[error("explicit force {index} is negative ({force} N): a resting point cannot pull")]
    NegativeExplicit {
        /// 0-based index of the force.
        index: usize,
        /// The force, N.
        force: f64,
    },
    /// The explicit forces do not sum to the weight.
    #[error("the explicit forces sum to {sum:.3} N but the weight is {weight:.3} N")]
    ExplicitWeight {
        /// Their sum, N.
        sum: f64,
        /// The weight, N.
        weight: f64,
    },
    /// The explicit forces put the CoG elsewhere than the load case says.
    #[error("the explicit forces put the centre of gravity at ({x:.3}, {y:.3}) mm, but the load case says ({cx:.3}, {cy:.3}) mm")]
    ExplicitCog {
        /// CoG X from the forces, mm.
        x: f64,
        /// CoG Y from the forces, mm.
        y: f64,
        /// CoG X of the load case, mm.
        cx: f64,
        /// CoG Y of the load case, mm.
        cy: f64,
    },
}

/// Forces (N, downwards) at `rests` carrying weight `weight_n` with centre of gravity `cog`.
pub fn distribute(weight_n: f64, cog: [f64; 2], rests: &[[f64; 2]]) -> Result<Vec<f64>, StaticsError> {
    if rests.is_empty() {
        return Err(StaticsError::NoRestPoints);
    }
    if !(weight_n.is_finite() && weight_n > 0.0) {
        return Err(StaticsError::BadWeight(weight_n));
    }
    if !(cog[0].is_finite() && cog[1].is_finite()) || rests.iter().flatten().any(|v| !v.is_finite()) {
        return Err(StaticsError::NotFinite);
    }
    // Rows of A: 1, (x − cx)/L, (y − cy)/L; L scales moments to forces for conditioning.
    let l = rests.iter().map(|r| (r[0] - cog[0]).hypot(r[1] - cog[1])).fold(0.0, f64::max).max(1.0);
    let col = |r: &[f64; 2]| Vector3::new(1.0, (r[0] - cog[0]) / l, (r[1] - cog[1]) / l);
    let mut m = Matrix3::zeros();
    for r in rests {
        let a = col(r);
        m += a * a.transpose();
    }
    // Pseudo-inverse of the symmetric 3×3 normal matrix by eigen-decomposition (rank 1..3).
    let eig = SymmetricEigen::new(m);
    let lmax = eig.eigenvalues.amax();
    let b = Vector3::new(1.0, 0.0, 0.0); // per unit weight
    let mut lambda = Vector3::zeros();
    for k in 0..3 {
        let ev = eig.eigenvalues[k];
        if ev > 1e-12 * lmax {
            let v = eig.eigenvectors.column(k);
            lambda += v * (v.dot(&b) / ev);
        }
    }
    let f: Vec<f64> = rests.iter().map(|r| col(r).dot(&lambda)).collect();
    // Balance check: the pseudo-inverse gives the least-squares solution when none is exact.
    let mut res = -b;
    for (r, fk) in rests.iter().zip(&f) {
        res += col(r) * *fk;
    }
    if res.norm() > 1e-9 {
        return Err(StaticsError::CannotBalance {
            n: rests.len(),
            cx: cog[0],
            cy: cog[1],
            moment_nmm: weight_n * l * res.fixed_rows::<2>(1).norm(),
        });
    }
    for (i, (r, fk)) in rests.iter().zip(&f).enumerate() {
        if *fk < -1e-9 {
            return Err(StaticsError::Tension { index: i, x: r[0], y: r[1], force: fk * weight_n });
        }
    }
    Ok(f.iter().map(|fk| fk.max(0.0) * weight_n).collect())
}

/// Check explicit forces `(x, y, F)`: none negative, and, if the load case also states a weight
/// or a centre of gravity, consistent with them (weight to 0.1 %, centre of gravity to 1 mm —
/// what a load-cell reading and a drawing agree to). Returns `(weight, cog)`.
pub fn check_explicit(
    forces: &[(f64, f64, f64)],
    weight_n: Option<f64>,
    cog: Option<[f64; 2]>,
) -> Result<(f64, [f64; 2]), StaticsError> {
    if forces.is_empty() {
        return Err(StaticsError::NoRestPoints);
    }
    for (i, &(x, y, f)) in forces.iter().enumerate() {
        if !(x.is_finite() && y.is_finite() && f.is_finite()) {
            return Err(StaticsError::NotFinite);
        }
        if f < 0.0 {
            return Err(StaticsError::NegativeExplicit { index: i, force: f });
        }
    }
    let sum: f64 = forces.iter().map(|f| f.2).sum();
    if sum <= 0.0 {
        return Err(StaticsError::BadWeight(sum));
    }
    let cx = forces.iter().map(|f| f.0 * f.2).sum::<f64>() / sum;
    let cy = forces.iter().map(|f| f.1 * f.2).sum::<f64>() / sum;
    if let Some(w) = weight_n {
        if (sum - w).abs() > 1e-3 * w.abs() {
            return Err(StaticsError::ExplicitWeight { sum, weight: w });
        }
    }
    if let Some(c) = cog {
        if (cx - c[0]).hypot(cy - c[1]) > 1.0 {
            return Err(StaticsError::ExplicitCog { x: cx, y: cy, cx: c[0], cy: c[1] });
        }
    }
    Ok((sum, [cx, cy]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn balance(w: f64, c: [f64; 2], r: &[[f64; 2]], f: &[f64]) -> (f64, f64, f64) {
        let s: f64 = f.iter().sum();
        let mx: f64 = r.iter().zip(f).map(|(p, f)| f * (p[0] - c[0])).sum();
        let my: f64 = r.iter().zip(f).map(|(p, f)| f * (p[1] - c[1])).sum();
        (s - w, mx, my)
    }

    #[test]
    fn three_points_hand_calculation() {
        // Points (0,0), (1000,0), (0,500); CoG (250, 100), W = 10 kN. By hand: moments about the
        // y axis: F2·1000 = W·250 → F2 = 2500; about the x axis: F3·500 = W·100 → F3 = 2000;
        // F1 = 10000 − 2500 − 2000 = 5500.
        let f = distribute(10_000.0, [250.0, 100.0], &[[0.0, 0.0], [1000.0, 0.0], [0.0, 500.0]]).unwrap();
        for (a, b) in f.iter().zip([5500.0, 2500.0, 2000.0]) {
            assert!((a - b).abs() < 1e-9, "{f:?}");
        }
    }

    #[test]
    fn four_symmetric_points_share_equally_and_min_norm_is_balanced() {
        let r = [[0.0, 0.0], [800.0, 0.0], [800.0, 600.0], [0.0, 600.0]];
        let f = distribute(4000.0, [400.0, 300.0], &r).unwrap();
        for fk in &f {
            assert!((fk - 1000.0).abs() < 1e-9);
        }
        // Off-centre CoG: the minimum-norm solution lies in the row space, F_k = α + β·u_k + γ·v_k
        // with u_k = ±a/2, v_k = ±b/2 about the rectangle's centre; the three balance equations
        // give F_k = W/4 · (1 + 2·ex/a·su + 2·ey/b·sv) (su, sv = ±1). Here a = 800, b = 600,
        // ex = 100, ey = −60.
        let c = [500.0, 240.0];
        let f = distribute(4000.0, c, &r).unwrap();
        let (s, mx, my) = balance(4000.0, c, &r, &f);
        assert!(s.abs() < 1e-9 && mx.abs() < 1e-6 && my.abs() < 1e-6);
        let closed = |u: f64, v: f64| 1000.0 * (1.0 + 2.0 * 100.0 / 800.0 * u + 2.0 * (-60.0) / 600.0 * v);
        let want = [closed(-1.0, -1.0), closed(1.0, -1.0), closed(1.0, 1.0), closed(-1.0, 1.0)];
        for (a, b) in f.iter().zip(want) {
            assert!((a - b).abs() < 1e-9, "{f:?} vs {want:?}");
        }
    }

    #[test]
    fn degenerate_and_tension_cases_are_rejected() {
        // Two points with the CoG on the segment: lever rule.
        let f = distribute(900.0, [300.0, 0.0], &[[0.0, 0.0], [900.0, 0.0]]).unwrap();
        assert!((f[0] - 600.0).abs() < 1e-9 && (f[1] - 300.0).abs() < 1e-9);
        // Two points, CoG off their line: cannot balance.
        assert!(matches!(
            distribute(900.0, [300.0, 10.0], &[[0.0, 0.0], [900.0, 0.0]]),
            Err(StaticsError::CannotBalance { .. })
        ));
        // One point not under the CoG.
        assert!(matches!(
            distribute(900.0, [1.0, 0.0], &[[0.0, 0.0]]),
            Err(StaticsError::CannotBalance { .. })
        ));
        // Three collinear points, CoG off the line.
        assert!(matches!(
            distribute(900.0, [1.0, 5.0], &[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]),
            Err(StaticsError::CannotBalance { .. })
        ));
        // CoG outside the triangle: tension.
        assert!(matches!(
            distribute(900.0, [-100.0, 100.0], &[[0.0, 0.0], [1000.0, 0.0], [0.0, 500.0]]),
            Err(StaticsError::Tension { .. })
        ));
        assert!(distribute(0.0, [0.0, 0.0], &[[0.0, 0.0]]).is_err());
        assert_eq!(distribute(1.0, [0.0, 0.0], &[]), Err(StaticsError::NoRestPoints));
    }

    #[test]
    fn explicit_forces() {
        let (w, c) = check_explicit(
            &[(0.0, 0.0, 5500.0), (1000.0, 0.0, 2500.0), (0.0, 500.0, 2000.0)],
            Some(10_000.0),
            Some([250.0, 100.0]),
        )
        .unwrap();
        assert!((w - 10_000.0).abs() < 1e-9 && (c[0] - 250.0).abs() < 1e-9 && (c[1] - 100.0).abs() < 1e-9);
        assert!(matches!(
            check_explicit(&[(0.0, 0.0, 5500.0), (1000.0, 0.0, 2500.0)], Some(10_000.0), None),
            Err(StaticsError::ExplicitWeight { .. })
        ));
        assert!(matches!(
            check_explicit(&[(0.0, 0.0, 10.0), (1000.0, 0.0, 10.0)], None, Some([0.0, 0.0])),
            Err(StaticsError::ExplicitCog { .. })
        ));
        assert!(matches!(
            check_explicit(&[(0.0, 0.0, -1.0)], None, None),
            Err(StaticsError::NegativeExplicit { .. })
        ));
    }
}

#[cfg(test)]
mod props {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Whatever the layout, an accepted distribution balances forces and moments and has no
        /// tension; a CoG at the centroid of ≥ 3 points on a circle is always accepted.
        #[test]
        fn accepted_distributions_balance(n in 3usize..7, r in 100.0f64..2000.0, phase in 0.0f64..6.0,
                                          cx in -300.0f64..300.0, cy in -300.0f64..300.0, w in 1.0f64..1e5) {
            let pts: Vec<[f64; 2]> = (0..n).map(|k| {
                let a = phase + k as f64 * std::f64::consts::TAU / n as f64;
                [cx + r * a.cos(), cy + r * a.sin()]
            }).collect();
            let f = distribute(w, [cx, cy], &pts).unwrap();
            let s: f64 = f.iter().sum();
            let mx: f64 = pts.iter().zip(&f).map(|(p, f)| f * (p[0] - cx)).sum();
            let my: f64 = pts.iter().zip(&f).map(|(p, f)| f * (p[1] - cy)).sum();
            prop_assert!((s - w).abs() < 1e-9 * w);
            prop_assert!(mx.abs() < 1e-9 * w * r && my.abs() < 1e-9 * w * r);
            prop_assert!(f.iter().all(|v| *v >= 0.0));
        }
    }
}
