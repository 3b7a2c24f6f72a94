//! Point supports: equilibrium, statics of three pads, load over a pad, symmetry,
//! reciprocity, elastic pads, and rejection of singular or invalid models.

use truepos_fe::{Bed, FeError, MeshOptions, ModelOptions, PlateModel, Supports};

/// A granite bed: 2000 × 1500 × 250 mm, E = 50 GPa, ν = 0.2.
fn granite(supports: Supports) -> Bed {
    Bed { size_x: 2000.0, size_y: 1500.0, thickness: 250.0, youngs_modulus: 5.0e4, poisson: 0.2, supports }
}

fn rigid(xy: &[[f64; 2]]) -> Supports {
    Supports::Points { xy: xy.to_vec(), stiffness_n_per_mm: None }
}

const MESH: MeshOptions = MeshOptions { element_size: 50.0 };

/// Three rigid pads make the bed statically determinate: the reactions follow from force and
/// moment balance alone, whatever the plate's stiffness. The FE reactions must match the
/// statics to round-off (1e-9 relative: the reactions come from K·u − f with K entries ~1e10
/// and a Cholesky solve of a well-conditioned system).
#[test]
fn three_pads_reactions_match_statics() {
    let pads = [[200.0, 150.0], [1800.0, 300.0], [900.0, 1350.0]];
    let model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let loads = [(500.0, 500.0, 3000.0), (1430.0, 1010.0, 1200.0), (1234.5, 222.2, 700.0)];
    let def = model.solve(&loads).unwrap();
    // Statics: Σ R_k (1, x_k, y_k) = Σ F (1, x, y).
    let total: f64 = loads.iter().map(|l| l.2).sum();
    let mx: f64 = loads.iter().map(|l| l.0 * l.2).sum();
    let my: f64 = loads.iter().map(|l| l.1 * l.2).sum();
    let m = nalgebra::Matrix3::from_fn(|r, c| match r {
        0 => 1.0,
        1 => pads[c][0],
        _ => pads[c][1],
    });
    let r = m.lu().solve(&nalgebra::Vector3::new(total, mx, my)).unwrap();
    for k in 0..3 {
        assert!(
            (def.reactions()[k] - r[k]).abs() < 1e-9 * total,
            "pad {k}: FE {} vs statics {}",
            def.reactions()[k],
            r[k]
        );
    }
    assert!((def.total_reaction() - total).abs() < 1e-9 * total);
}

/// Six pads (statically indeterminate): reactions still sum to the load and balance its moments.
#[test]
fn six_pads_equilibrium() {
    let pads = [
        [150.0, 150.0],
        [1000.0, 150.0],
        [1850.0, 150.0],
        [150.0, 1350.0],
        [1000.0, 1350.0],
        [1850.0, 1350.0],
    ];
    let model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let loads = [(700.0, 900.0, 5000.0), (1620.0, 410.0, 2500.0)];
    let def = model.solve(&loads).unwrap();
    let total: f64 = loads.iter().map(|l| l.2).sum();
    let sum: f64 = def.reactions().iter().sum();
    assert!((sum - total).abs() < 1e-9 * total, "{sum} vs {total}");
    let mx: f64 = loads.iter().map(|l| l.0 * l.2).sum();
    let rx: f64 = def.reactions().iter().zip(&pads).map(|(r, p)| r * p[0]).sum();
    assert!((mx - rx).abs() < 1e-9 * mx);
    // The loaded bed sags between the pads.
    assert!(def.uz(700.0, 900.0) < 0.0);
}

/// A load directly over a rigid pad goes straight into the pad: no deflection anywhere
/// (exactly zero in the model up to round-off, against ~µm for the same load mid-span).
#[test]
fn load_over_pad_gives_no_deflection() {
    let pads = [[150.0, 150.0], [1850.0, 150.0], [150.0, 1350.0], [1850.0, 1350.0]];
    let model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let on_pad = model.solve(&[(1850.0, 150.0, 10_000.0)]).unwrap();
    let mid = model.solve(&[(1000.0, 750.0, 10_000.0)]).unwrap();
    let scale = mid.uz(1000.0, 750.0).abs();
    assert!(scale > 1e-4, "mid-span deflection {scale} mm implausibly small");
    for n in 0..model.mesh().n_nodes() {
        assert!(on_pad.nodal_uz(n).abs() < 1e-9 * scale);
    }
    assert!((on_pad.reactions()[1] - 10_000.0).abs() < 1e-6);
}

/// Symmetric pads and a central load give a field symmetric about both mid-lines; Maxwell-Betti
/// reciprocity (uz at B from a load at A equals uz at A from the same load at B) holds for any
/// pads. Tolerances: round-off of the solve, 1e-9 of the peak deflection.
#[test]
fn symmetry_and_reciprocity() {
    let pads = [[200.0, 200.0], [1800.0, 200.0], [200.0, 1300.0], [1800.0, 1300.0]];
    let model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let def = model.solve(&[(1000.0, 750.0, 1000.0)]).unwrap();
    let peak = def.uz(1000.0, 750.0).abs();
    for &(x, y) in &[(100.0, 100.0), (430.0, 610.0), (975.0, 20.0), (1333.0, 1111.0)] {
        let u = def.uz(x, y);
        assert!((u - def.uz(2000.0 - x, y)).abs() < 1e-9 * peak);
        assert!((u - def.uz(x, 1500.0 - y)).abs() < 1e-9 * peak);
        assert!((u - def.uz(2000.0 - x, 1500.0 - y)).abs() < 1e-9 * peak);
    }
    for r in def.reactions() {
        assert!((r - 250.0).abs() < 1e-9 * 1000.0);
    }
    // Reciprocity holds for the point-load operator (the load is distributed and the deflection
    // read with the same shape functions); with load patches it holds for patch means instead.
    let point = ModelOptions { load_patch_diameter: Some(0.0), pad_diameter: None };
    let model = PlateModel::with_options(&granite(rigid(&pads)), &MESH, &point).unwrap();
    let (a, b) = ((450.0, 900.0), (1537.0, 311.0));
    let from_a = model.solve(&[(a.0, a.1, 1000.0)]).unwrap();
    let from_b = model.solve(&[(b.0, b.1, 1000.0)]).unwrap();
    assert!((from_a.uz(b.0, b.1) - from_b.uz(a.0, a.1)).abs() < 1e-9 * peak);
}

/// Four elastic pads of stiffness k symmetric about the load: each carries P/4 by symmetry, so
/// each pad compresses by exactly P/(4k), whatever the plate.
#[test]
fn elastic_pads_compress_by_their_share() {
    let k = 2.0e5;
    let pads = vec![[200.0, 200.0], [1800.0, 200.0], [200.0, 1300.0], [1800.0, 1300.0]];
    let bed = granite(Supports::Points { xy: pads.clone(), stiffness_n_per_mm: Some(k) });
    let model = PlateModel::new(&bed, &MESH).unwrap();
    let p = 8000.0;
    let def = model.solve(&[(1000.0, 750.0, p)]).unwrap();
    for r in def.reactions() {
        assert!((r - p / 4.0).abs() < 1e-9 * p);
    }
    assert!((def.total_reaction() - p).abs() < 1e-9 * p);
    // The same bed on rigid pads deflects less by the pad compression at the centre, i.e. the
    // elastic field is the rigid one plus the rigid-body drop P/(4k) (exact here by symmetry).
    let rigid_model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let r = rigid_model.solve(&[(1000.0, 750.0, p)]).unwrap();
    for &(x, y) in &[(200.0, 200.0), (700.0, 500.0), (1000.0, 750.0), (1990.0, 10.0)] {
        let diff = def.uz(x, y) - r.uz(x, y);
        assert!((diff + p / (4.0 * k)).abs() < 1e-6 * p / (4.0 * k), "diff {diff}");
    }
}

/// solve_many gives the same fields as solve, case by case.
#[test]
fn solve_many_matches_solve() {
    let pads = [[150.0, 150.0], [1850.0, 150.0], [1000.0, 1350.0]];
    let model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let cases: Vec<Vec<(f64, f64, f64)>> =
        (0..37).map(|i| vec![(50.0 * i as f64 + 3.0, 30.0 * i as f64 + 7.0, 1000.0)]).collect();
    let many = model.solve_many(&cases).unwrap();
    assert_eq!(many.len(), cases.len());
    for (case, d) in cases.iter().zip(&many) {
        let one = model.solve(case).unwrap();
        for &(x, y) in &[(100.0, 100.0), (1000.0, 700.0), (1900.0, 1400.0)] {
            assert!((one.uz(x, y) - d.uz(x, y)).abs() <= 1e-12 * one.uz(x, y).abs().max(1e-9));
        }
    }
}

#[test]
fn singular_and_invalid_models_are_rejected() {
    let two = granite(rigid(&[[100.0, 100.0], [1900.0, 1400.0]]));
    assert!(matches!(PlateModel::new(&two, &MESH), Err(FeError::Singular(_))));
    let collinear = granite(rigid(&[[100.0, 100.0], [1000.0, 550.0], [1900.0, 1000.0]]));
    assert!(matches!(PlateModel::new(&collinear, &MESH), Err(FeError::Singular(_))));
    let coincident = granite(rigid(&[[100.0, 100.0], [100.0, 100.0], [100.0, 100.0]]));
    assert!(matches!(PlateModel::new(&coincident, &MESH), Err(FeError::Singular(_))));
    let springs_collinear = granite(Supports::Points {
        xy: vec![[0.0, 750.0], [1000.0, 750.0], [2000.0, 750.0], [500.0, 750.0]],
        stiffness_n_per_mm: Some(1e5),
    });
    assert!(matches!(PlateModel::new(&springs_collinear, &MESH), Err(FeError::Singular(_))));
    let zero_spring = granite(Supports::Points {
        xy: vec![[0.0, 0.0], [2000.0, 0.0], [0.0, 1500.0]],
        stiffness_n_per_mm: Some(0.0),
    });
    assert!(matches!(PlateModel::new(&zero_spring, &MESH), Err(FeError::Singular(_))));
    let outside = granite(rigid(&[[0.0, 0.0], [2100.0, 0.0], [0.0, 1500.0]]));
    assert!(matches!(PlateModel::new(&outside, &MESH), Err(FeError::SupportOutsideBed { .. })));
    let nan = granite(rigid(&[[0.0, 0.0], [f64::NAN, 0.0], [0.0, 1500.0]]));
    assert!(matches!(PlateModel::new(&nan, &MESH), Err(FeError::SupportOutsideBed { .. })));
    let ok_pads = [[0.0, 0.0], [2000.0, 0.0], [0.0, 1500.0]];
    for (name, mut bed) in [
        ("thickness", granite(rigid(&ok_pads))),
        ("poisson", granite(rigid(&ok_pads))),
        ("size_x", granite(rigid(&ok_pads))),
    ] {
        match name {
            "thickness" => bed.thickness = -1.0,
            "poisson" => bed.poisson = 0.5,
            _ => bed.size_x = f64::INFINITY,
        }
        assert!(matches!(PlateModel::new(&bed, &MESH), Err(FeError::InvalidParameter { .. })));
    }
    let bed = granite(rigid(&ok_pads));
    assert!(matches!(
        PlateModel::new(&bed, &MeshOptions { element_size: -5.0 }),
        Err(FeError::InvalidParameter { .. })
    ));
    assert!(matches!(
        PlateModel::new(&bed, &MeshOptions { element_size: 1e-3 }),
        Err(FeError::MeshTooLarge { .. })
    ));
    let model = PlateModel::new(&bed, &MeshOptions::default()).unwrap();
    assert!(matches!(model.solve(&[(-10.0, 5.0, 1.0)]), Err(FeError::InvalidLoad { index: 0, .. })));
    assert!(matches!(
        model.solve(&[(10.0, 5.0, 1.0), (10.0, 5.0, f64::NAN)]),
        Err(FeError::InvalidLoad { index: 1, .. })
    ));
    let def = model.solve(&[(10.0, 5.0, 1.0)]).unwrap();
    assert!(def.uz(-1.0, 0.0).is_nan() && def.try_uz(2000.5, 0.0).is_none());
}

/// Pads and loads on edges and corners: the footprints are squeezed so each resultant stays at
/// its nominal point, hence the three-pad statics still hold exactly (1e-9, round-off).
#[test]
fn edge_pads_and_edge_loads_keep_statics() {
    let pads = [[0.0, 0.0], [2000.0, 700.0], [600.0, 1500.0]];
    let model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let loads = [(0.0, 900.0, 1000.0), (1300.0, 0.0, 2000.0), (2000.0, 1500.0, 500.0), (60.0, 40.0, 800.0)];
    let def = model.solve(&loads).unwrap();
    let total: f64 = loads.iter().map(|l| l.2).sum();
    let mx: f64 = loads.iter().map(|l| l.0 * l.2).sum();
    let my: f64 = loads.iter().map(|l| l.1 * l.2).sum();
    let m = nalgebra::Matrix3::from_fn(|r, c| match r {
        0 => 1.0,
        1 => pads[c][0],
        _ => pads[c][1],
    });
    let r = m.lu().solve(&nalgebra::Vector3::new(total, mx, my)).unwrap();
    for k in 0..3 {
        assert!((def.reactions()[k] - r[k]).abs() < 1e-9 * total, "pad {k}");
    }
}

/// Linearity and statics on random load sets (property test): solve(A ∪ B) = solve(A) +
/// solve(B), and three-pad reactions equal the statics, for loads anywhere on the bed.
#[test]
fn superposition_and_statics_property() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, TestRunner};
    let pads = [[300.0, 200.0], [1700.0, 250.0], [1000.0, 1400.0]];
    let model = PlateModel::new(&granite(rigid(&pads)), &MESH).unwrap();
    let load = (0.0..=2000.0f64, 0.0..=1500.0f64, -5000.0..5000.0f64);
    let mut runner = TestRunner::new(Config { cases: 24, ..Config::default() });
    runner
        .run(&(prop::collection::vec(load.clone(), 1..4), prop::collection::vec(load, 1..4)), |(a, b)| {
            let both: Vec<_> = a.iter().chain(&b).copied().collect();
            let (da, db, dab) =
                (model.solve(&a).unwrap(), model.solve(&b).unwrap(), model.solve(&both).unwrap());
            let scale: f64 = both.iter().map(|l| l.2.abs()).sum::<f64>().max(1.0);
            for &(x, y) in &[(10.0, 10.0), (777.0, 333.0), (1990.0, 1490.0), (1000.0, 750.0)] {
                let lin = dab.uz(x, y) - da.uz(x, y) - db.uz(x, y);
                // Deflections are ~1e-6 mm/N: round-off of the solve ~1e-15 relative.
                prop_assert!(lin.abs() < 1e-15 * scale);
            }
            let total: f64 = both.iter().map(|l| l.2).sum();
            let rsum: f64 = dab.reactions().iter().sum();
            prop_assert!((rsum - total).abs() < 1e-9 * scale);
            Ok(())
        })
        .unwrap();
}

/// Statically indeterminate elastic support: a (nearly) rigid plate on five equal springs
/// settles as a rigid body, w_i = a + b x_i + c y_i, so the reactions k·w_i follow from force and
/// moment balance alone. The bed is made 1e4 times stiffer than granite so its own bending is
/// ~1e-6 of the spring compression; tolerance 1e-4 of the load.
#[test]
fn stiff_plate_on_springs_settles_rigidly() {
    let pads = vec![[100.0, 100.0], [1900.0, 200.0], [1800.0, 1400.0], [300.0, 1300.0], [1000.0, 800.0]];
    let k = 1.0e3;
    let mut bed = granite(Supports::Points { xy: pads.clone(), stiffness_n_per_mm: Some(k) });
    bed.youngs_modulus *= 1e4;
    let model = PlateModel::new(&bed, &MESH).unwrap();
    let loads = [(500.0, 600.0, 4000.0), (1600.0, 1100.0, 2500.0)];
    let def = model.solve(&loads).unwrap();
    // Σ k (a + b x_i + c y_i) (1, x_i, y_i) = Σ F (1, x, y).
    let mut n = nalgebra::Matrix3::zeros();
    for p in &pads {
        let v = nalgebra::Vector3::new(1.0, p[0], p[1]);
        n += k * v * v.transpose();
    }
    let total: f64 = loads.iter().map(|l| l.2).sum();
    let rhs = nalgebra::Vector3::new(
        total,
        loads.iter().map(|l| l.0 * l.2).sum(),
        loads.iter().map(|l| l.1 * l.2).sum(),
    );
    let abc = n.lu().solve(&rhs).unwrap();
    for (p, r) in pads.iter().zip(def.reactions()) {
        let expected = k * (abc[0] + abc[1] * p[0] + abc[2] * p[1]);
        assert!((r - expected).abs() < 1e-4 * total, "FE {r} vs rigid-body {expected}");
    }
}

/// A narrow plate strip on four corner pads under uniform pressure behaves as a simply
/// supported Timoshenko beam: linear plate theory gives a free-edged strip in bending the
/// beam stiffness E·b h³/12 exactly (the anticlastic solution w ∝ x² − ν y², so no 1/(1 − ν²)),
/// hence w_mid = 5 Q L⁴/(384 E I) + Q L²/(8 κ G b h) with Q = q b (Timoshenko beam, κ = 5/6).
/// Tolerance 1 %: the strip's ends are held at the corners only, not along the end edges, so
/// the end sections sag and twist locally (an effect of order (b/L)² ≈ 1 % here), plus the
/// 25 mm mesh error (~0.1 %).
#[test]
fn narrow_strip_on_corner_pads_matches_timoshenko_beam() {
    let (l, b, h) = (2000.0, 200.0, 100.0);
    let bed = Bed {
        size_x: l,
        size_y: b,
        thickness: h,
        youngs_modulus: 2.1e5,
        poisson: 0.3,
        supports: Supports::Points {
            xy: vec![[0.0, 0.0], [l, 0.0], [0.0, b], [l, b]],
            stiffness_n_per_mm: None,
        },
    };
    let model = PlateModel::new(&bed, &MeshOptions::with_element_size(25.0)).unwrap();
    let q = 0.01; // N/mm²
    let def = model.solve_pressure(q, &[]).unwrap();
    let w_mid = -(0..=8).map(|j| def.uz(l / 2.0, j as f64 * 25.0)).sum::<f64>() / 9.0;
    let e = bed.youngs_modulus;
    let g = e / (2.0 * (1.0 + bed.poisson));
    let i = b * h.powi(3) / 12.0;
    let qb = q * b;
    let beam = 5.0 * qb * l.powi(4) / (384.0 * e * i) + qb * l * l / (8.0 * (5.0 / 6.0) * g * b * h);
    let err = (w_mid - beam) / beam;
    eprintln!("strip: FE {w_mid:.6e}, Timoshenko beam {beam:.6e}, rel err {err:.2e}");
    assert!(err.abs() < 0.01, "rel err {err}");
}
