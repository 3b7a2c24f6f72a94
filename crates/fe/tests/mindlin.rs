//! Thick plates against the Mindlin reference (Wang, Reddy & Lee), and absence of shear locking.

mod common;

use common::{navier_uniform, ss_bed};
use truepos_fe::{MeshOptions, PlateModel, SHEAR_CORRECTION};

/// Centre deflection of a hard simply supported square plate under uniform load q.
///
/// Reference: Wang, Reddy & Lee, "Shear Deformable Beams and Plates: Relationships with
/// Classical Solutions" (Elsevier 2000), ch. 7: for simply supported polygonal plates
/// w_M = w_K + ℳ_K / (κ G h), ℳ = (Mxx + Myy)/(1 + ν) the moment sum of the Kirchhoff plate.
/// Derivation of the centre values for the square: D∇²∇²w_K = q and, since
/// ℳ = −D∇²w_K, ∇²ℳ_K = −q with ℳ_K = 0 on the edges (w = 0 and M_n = 0 there). Both follow
/// from the Navier series (see `common::navier_uniform`); the classical coefficients are
/// w_K = 0.00406235 q a⁴/D (Timoshenko & Woinowsky-Krieger, Table 8) and
/// ℳ_K = 0.0736713 q a² (the Prandtl membrane/torsion value of the square), which the series
/// must reproduce. Hence w_M(centre) = (0.00406235 a²/D + 0.0736713/(κ G h)) q a².
fn centre_reference(a: f64, h: f64) -> (f64, f64) {
    let bed = ss_bed(a, a, h);
    let d = bed.flexural_rigidity();
    let q = 1.0;
    let (wk, mk) = navier_uniform(a, a, d, q, (a / 2.0, a / 2.0), 401);
    // The series reproduces the classical coefficients (to their published digits).
    assert!((wk * d / (q * a.powi(4)) - 0.00406235).abs() < 2e-8);
    assert!((mk / (q * a * a) - 0.0736713).abs() < 2e-7);
    let kgh = SHEAR_CORRECTION * bed.youngs_modulus / (2.0 * (1.0 + bed.poisson)) * h;
    (wk, wk + mk / kgh)
}

fn fe_centre(a: f64, h: f64, element: f64) -> f64 {
    let model = PlateModel::new(&ss_bed(a, a, h), &MeshOptions::with_element_size(element)).unwrap();
    let def = model.solve_pressure(1.0, &[]).unwrap();
    // Equilibrium: edge reactions carry q a².
    assert!((def.total_reaction() - a * a).abs() < 1e-6 * a * a);
    -def.uz(a / 2.0, a / 2.0)
}

/// h/a = 0.1 and 0.2: the shear term is 5.2 % and 21 % of the deflection, so agreement to
/// 0.5 % proves the shear deformation is modelled (a Kirchhoff element would miss by 5–17 %).
/// 0.5 %: the 25 mm (a/40) mesh's discretisation error, O((a/40)²) ≈ 0.1–0.3 % for MITC4 here.
#[test]
fn thick_square_plate_uniform_load_matches_mindlin() {
    let a = 1000.0;
    for h in [100.0, 200.0] {
        let (wk, wm) = centre_reference(a, h);
        let fe = fe_centre(a, h, 25.0);
        let err = (fe - wm) / wm;
        eprintln!("h/a = {}: FE {fe:.6e}, Mindlin {wm:.6e} (Kirchhoff {wk:.6e}), rel err {err:.2e}", h / a);
        assert!(err.abs() < 5e-3, "h/a {}: rel err {err}", h / a);
        assert!((fe - wk) / wk > 0.04, "shear deformation missing");
    }
}

/// h/a = 1e-3: the shear term is 3e-6 of the bending deflection, so the plate must match
/// Kirchhoff; a locking element would be orders of magnitude too stiff. 0.5 % as above.
#[test]
fn no_shear_locking_in_thin_limit() {
    let a = 1000.0;
    let (wk, wm) = centre_reference(a, 1.0);
    assert!((wm - wk) / wk < 1e-5);
    for element in [50.0, 25.0] {
        let fe = fe_centre(a, 1.0, element);
        let err = (fe - wk) / wk;
        eprintln!("thin h/a = 1e-3, element {element}: rel err vs Kirchhoff {err:.2e}");
        assert!(err.abs() < 5e-3, "rel err {err}");
    }
}

/// The NR J1 approximation against its power series Σ (−1)^k (x/2)^{2k+1}/(k!(k+1)!) where the
/// series is accurate in f64 (x ≤ 12: largest term ~1e4, round-off ~1e-12).
#[test]
fn bessel_j1_matches_power_series() {
    for &x in &[0.3, 1.0, 2.5, 5.0, 7.9, 8.1, 10.0, 12.0] {
        let mut term = x / 2.0;
        let mut sum = term;
        for k in 1..60 {
            term *= -(x / 2.0) * (x / 2.0) / (k as f64 * (k + 1) as f64);
            sum += term;
        }
        assert!((common::bessel_j1(x) - sum).abs() < 2e-8, "x {x}: {} vs {sum}", common::bessel_j1(x));
    }
}

/// Thick plate (h/a = 0.2) under a 1 kN force spread over a disc of diameter h (the model's
/// default load patch), hard simply supported: FE against the Mindlin Navier series, at the
/// load centre (where the shear part is ~30 % of the deflection) and elsewhere. Tolerance 0.5 %:
/// the 25 mm mesh resolves the 200 mm disc with 8 elements across (O(h²) ≈ 0.3 %), plus the
/// staircase sampling of the disc boundary.
#[test]
fn thick_plate_patch_load_matches_mindlin_navier() {
    let (a, b, h, p) = (1000.0, 800.0, 200.0, 1000.0);
    let bed = ss_bed(a, b, h);
    let (d, kgh) = (bed.flexural_rigidity(), bed.shear_rigidity());
    let model = PlateModel::new(&bed, &MeshOptions::with_element_size(25.0)).unwrap();
    let load = (400.0, 450.0);
    let def = model.solve(&[(load.0, load.1, p)]).unwrap();
    let r = h / 2.0;
    let c1 = common::navier_disc_mindlin(a, b, d, kgh, p, load, r, load, 500);
    let c2 = common::navier_disc_mindlin(a, b, d, kgh, p, load, r, load, 1000);
    assert!(((c1 - c2) / c2).abs() < 2e-4, "series not converged: {c1} vs {c2}");
    let mut worst: f64 = 0.0;
    for &at in &[load, (450.0, 450.0), (250.0, 300.0), (700.0, 600.0), (800.0, 200.0)] {
        let reference = common::navier_disc_mindlin(a, b, d, kgh, p, load, r, at, 1000);
        let kirchhoff = common::navier_disc_mindlin(a, b, d, f64::INFINITY, p, load, r, at, 1000);
        let fe = -def.uz(at.0, at.1);
        let err = (fe - reference) / reference;
        worst = worst.max(err.abs());
        eprintln!(
            "at {at:?}: FE {fe:.5e}, Mindlin {reference:.5e}, Kirchhoff {kirchhoff:.5e}, rel err {err:.2e}"
        );
        assert!(err.abs() < 0.005, "at {at:?}: rel err {err}");
    }
    eprintln!("thick patch load: worst rel err {worst:.2e}");
}
