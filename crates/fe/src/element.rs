//! The MITC4 Mindlin-Reissner plate element on a rectangle (the structured mesh has only
//! axis-aligned rectangles, for which the covariant MITC4 shear interpolation reduces to the
//! Cartesian one used here).
//!
//! Kinematics (w positive in the load direction, i.e. DOWNWARDS, inside this crate): the
//! in-plane displacements are u = −z ψx, v = −z ψy, so that in the thin (Kirchhoff) limit
//! ψx = ∂w/∂x, ψy = ∂w/∂y. Curvatures κ = (∂ψx/∂x, ∂ψy/∂y, ∂ψx/∂y + ∂ψy/∂x), transverse shear
//! strains γ = (∂w/∂x − ψx, ∂w/∂y − ψy). Strain energy
//! ½∫ κᵀ D_b κ dA + ½∫ κ_s G h γᵀγ dA with D_b = D [[1, ν, 0], [ν, 1, 0], [0, 0, (1−ν)/2]].
//!
//! Why MITC4 (Bathe & Dvorkin, Int. J. Numer. Meth. Eng. 21 (1985) 367–383): with bilinear
//! w and ψ the exact shear energy locks as h/L → 0 (the element cannot represent γ = 0 with
//! non-zero curvature). MITC4 samples γx at the mid-points of the edges η = ±1 and γy at the
//! mid-points of the edges ξ = ±1 and interpolates them linearly across the element; the
//! resulting element passes the patch test, has no spurious zero-energy modes (unlike one-point
//! reduced shear integration, whose hourglass modes appear on point-supported plates), and
//! converges to Kirchhoff theory in the thin limit (tested at h/a = 1e-3).
//!
//! Entry point: [`stiffness`] (12 × 12, DOF order per node `[w, ψx, ψy]`, nodes in the local
//! order (−1,−1), (1,−1), (1,1), (−1,1)); [`shape`] for interpolation.

// Small dense matrix algebra reads most clearly with explicit indices.
#![allow(clippy::needless_range_loop)]

/// Local node coordinates (ξi, ηi).
pub const NODES: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Bilinear shape functions N_i(ξ, η).
pub fn shape(xi: f64, eta: f64) -> [f64; 4] {
    let mut n = [0.0; 4];
    for (k, p) in NODES.iter().enumerate() {
        n[k] = 0.25 * (1.0 + xi * p[0]) * (1.0 + eta * p[1]);
    }
    n
}

/// Derivatives (∂N/∂ξ, ∂N/∂η) at (ξ, η).
pub fn shape_derivatives(xi: f64, eta: f64) -> [[f64; 2]; 4] {
    let mut d = [[0.0; 2]; 4];
    for (k, p) in NODES.iter().enumerate() {
        d[k] = [0.25 * p[0] * (1.0 + eta * p[1]), 0.25 * p[1] * (1.0 + xi * p[0])];
    }
    d
}

/// Material constants of the plate.
#[derive(Debug, Clone, Copy)]
pub struct PlateMaterial {
    /// Flexural rigidity D, N·mm.
    pub d: f64,
    /// Poisson ratio.
    pub nu: f64,
    /// Shear rigidity κ G h, N/mm.
    pub shear: f64,
}

/// Direct (unassumed) shear strain rows at (ξ, η) for an element of size `lx` × `ly`:
/// `(γx row, γy row)`, each 12 long.
fn shear_rows(lx: f64, ly: f64, xi: f64, eta: f64) -> ([f64; 12], [f64; 12]) {
    let n = shape(xi, eta);
    let d = shape_derivatives(xi, eta);
    let mut gx = [0.0; 12];
    let mut gy = [0.0; 12];
    for k in 0..4 {
        gx[3 * k] = d[k][0] * 2.0 / lx;
        gx[3 * k + 1] = -n[k];
        gy[3 * k] = d[k][1] * 2.0 / ly;
        gy[3 * k + 2] = -n[k];
    }
    (gx, gy)
}

/// Stiffness matrix (12 × 12, row-major) of an `lx` × `ly` rectangular MITC4 element.
pub fn stiffness(lx: f64, ly: f64, m: &PlateMaterial) -> [[f64; 12]; 12] {
    let g = 1.0 / 3f64.sqrt();
    let jac = 0.25 * lx * ly; // dA = (lx/2)(ly/2) dξ dη
    let db = [[m.d, m.nu * m.d, 0.0], [m.nu * m.d, m.d, 0.0], [0.0, 0.0, 0.5 * (1.0 - m.nu) * m.d]];
    // MITC4 tying points: γx at (0, ∓1), γy at (∓1, 0).
    let (gx_c, _) = shear_rows(lx, ly, 0.0, -1.0);
    let (gx_a, _) = shear_rows(lx, ly, 0.0, 1.0);
    let (_, gy_d) = shear_rows(lx, ly, -1.0, 0.0);
    let (_, gy_b) = shear_rows(lx, ly, 1.0, 0.0);
    let mut k = [[0.0; 12]; 12];
    for &xi in &[-g, g] {
        for &eta in &[-g, g] {
            // Bending.
            let d = shape_derivatives(xi, eta);
            let mut b = [[0.0; 12]; 3];
            for n in 0..4 {
                let dx = d[n][0] * 2.0 / lx;
                let dy = d[n][1] * 2.0 / ly;
                b[0][3 * n + 1] = dx;
                b[1][3 * n + 2] = dy;
                b[2][3 * n + 1] = dy;
                b[2][3 * n + 2] = dx;
            }
            let mut dbb = [[0.0; 12]; 3];
            for r in 0..3 {
                for c in 0..12 {
                    dbb[r][c] = (0..3).map(|s| db[r][s] * b[s][c]).sum();
                }
            }
            // Assumed shear strains.
            let mut bs = [[0.0; 12]; 2];
            for c in 0..12 {
                bs[0][c] = 0.5 * (1.0 - eta) * gx_c[c] + 0.5 * (1.0 + eta) * gx_a[c];
                bs[1][c] = 0.5 * (1.0 - xi) * gy_d[c] + 0.5 * (1.0 + xi) * gy_b[c];
            }
            for r in 0..12 {
                for c in 0..12 {
                    let bend: f64 = (0..3).map(|s| b[s][r] * dbb[s][c]).sum();
                    let shear = m.shear * (bs[0][r] * bs[0][c] + bs[1][r] * bs[1][c]);
                    k[r][c] += (bend + shear) * jac;
                }
            }
        }
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mat() -> PlateMaterial {
        PlateMaterial { d: 1.0e6, nu: 0.3, shear: 5.0e4 }
    }

    /// The element must be symmetric and have exactly three zero-energy modes (rigid-body w,
    /// and the two rigid rotations w = x·θ with ψx = θ): MITC4 has no spurious modes.
    #[test]
    fn rigid_body_modes_and_rank() {
        let (lx, ly) = (30.0, 20.0);
        let k = stiffness(lx, ly, &mat());
        for r in 0..12 {
            for c in 0..12 {
                assert!((k[r][c] - k[c][r]).abs() <= 1e-9 * k[r][r].abs().max(1.0));
            }
        }
        // Rigid modes: w = a + b x + c y, ψx = b, ψy = c.
        for (a, b, c) in [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)] {
            let mut u = [0.0; 12];
            for (n, p) in NODES.iter().enumerate() {
                let (x, y) = (p[0] * lx / 2.0, p[1] * ly / 2.0);
                u[3 * n] = a + b * x + c * y;
                u[3 * n + 1] = b;
                u[3 * n + 2] = c;
            }
            for row in &k {
                let f: f64 = row.iter().zip(&u).map(|(k, u)| k * u).sum();
                // Forces of a rigid mode vanish to round-off of entries of size ~1e6·30.
                assert!(f.abs() < 1e-6, "rigid mode force {f}");
            }
        }
        // Rank 9: eigenvalues via nalgebra's symmetric eigen (fixed-size, safe).
        let m = nalgebra::SMatrix::<f64, 12, 12>::from_fn(|r, c| k[r][c]);
        let ev = m.symmetric_eigen().eigenvalues;
        let max = ev.iter().cloned().fold(0.0, f64::max);
        let zero = ev.iter().filter(|e| e.abs() < 1e-10 * max).count();
        assert_eq!(zero, 3, "eigenvalues {ev:?}");
    }
}
