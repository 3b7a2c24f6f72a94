//! Kinematic chains against hand calculations and against the first-order model of
//! docs/conventions.md.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use truepos_math::types::{ry, rz, Point3, Vector3};
use truepos_sim::errors::{Axis, ErrorFn, GeometricErrors};
use truepos_sim::machine::{head_point, Machine, MachineKind, RotaryTable};

fn random_axes(rng: &mut ChaCha8Rng, m: &Machine) -> Point3 {
    Point3::new(
        rng.random::<f64>() * m.travel[0],
        rng.random::<f64>() * m.travel[1],
        rng.random::<f64>() * m.travel[2],
    )
}

fn scaled(g: &GeometricErrors, k: f64) -> GeometricErrors {
    let mut g = g.clone();
    for ax in &mut g.axes {
        for f in ax.linear.iter_mut().chain(ax.angular.iter_mut()) {
            *f = f.clone().scaled(k);
        }
    }
    g.squareness.xy *= k;
    g.squareness.xz *= k;
    g.squareness.yz *= k;
    g
}

const KINDS: [MachineKind; 3] = [MachineKind::BridgeCmm, MachineKind::Vmc, MachineKind::Gantry];

#[test]
fn zero_errors_give_nominal_positions() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for kind in KINDS {
        let mut m = Machine::realistic(kind, 3);
        m.chain.errors = GeometricErrors::zero();
        for _ in 0..100 {
            let a = random_axes(&mut rng, &m);
            let t = Vector3::new(30.0, -20.0, -150.0);
            // Only rounding of ~1e4 mm sums: 1e-11 mm.
            assert!((m.tip(&a, &t) - m.nominal_tip(&a, &t)).norm() < 1e-11);
            assert!(m.first_order_error(&a, &t).norm() == 0.0);
        }
    }
}

#[test]
fn exact_chain_agrees_with_first_order_to_second_order() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for kind in KINDS {
        let m = Machine::realistic(kind, 11);
        let t = Vector3::new(25.0, 40.0, -180.0);
        let mut worst_ratio: f64 = 0.0;
        for _ in 0..200 {
            let a = random_axes(&mut rng, &m);
            let e1 = m.first_order_error(&a, &t);
            let exact = m.tip(&a, &t) - m.nominal_tip(&a, &t);
            let d = (exact - e1).norm();
            // Explicit bound on the second-order remainder: products of a rotation with a
            // translation error (Σ|ε|·Σ|δ|) and of two rotations, or the ½ε² of one, with the lever
            // (Σ|ε|²·(L + Σ|δ|)), L = |axes| + |t|.
            let g = &m.chain.errors;
            let eps: f64 = Axis::ALL.iter().map(|&ax| g.rotation(ax, a[ax.index()]).norm()).sum();
            let tr: f64 = Axis::ALL
                .iter()
                .map(|&ax| (g.linear(ax, a[ax.index()]) + g.squareness_term(ax, a[ax.index()])).norm())
                .sum();
            let bound = eps * tr + eps * eps * (a.coords.norm() + t.norm() + tr);
            assert!(d <= bound, "{kind:?}: remainder {d} above the bound {bound}");
            // And it is far below the first-order error itself (µm to tens of µm): < 1e-4 of it
            // wherever the error is not accidentally tiny.
            if e1.norm() > 1e-3 {
                assert!(d < 1e-4 * e1.norm(), "{kind:?}: remainder {d} vs error {}", e1.norm());
            }
            worst_ratio = worst_ratio.max(d / e1.norm().max(1e-12));
            // Remainder is second order: scaling every error by 10 scales it by ~100 (100 ± 1 % once
            // the third-order terms, 1e-5 relative smaller, are negligible).
            let mut m10 = m.clone();
            m10.chain.errors = scaled(&m.chain.errors, 10.0);
            let d10 = (m10.tip(&a, &t) - m10.nominal_tip(&a, &t) - m10.first_order_error(&a, &t)).norm();
            if d > 1e-9 {
                let ratio = d10 / d;
                assert!((ratio - 100.0).abs() < 1.0, "{kind:?}: ratio {ratio}");
            }
        }
        eprintln!("{kind:?}: worst |exact − first order| / |E| = {worst_ratio:.2e}");
    }
}

#[test]
fn a_pure_pitch_produces_the_abbe_error_by_hand() {
    // Bridge CMM, X-axis pitch (rotation about Y) of 10 µrad, constant; everything else zero.
    let eps = 10e-6;
    let mut g = GeometricErrors::zero();
    g.axes[Axis::X.index()].angular[0] = ErrorFn::constant(eps);
    let m = Machine::bridge_cmm(g);
    // Ram at z = 300 mm, stylus 200 mm long downwards: the lever below the X carriage is
    // (0, 0, 300 − 200) = 100 mm (z_vec + t). Rotating (0,0,100) about +Y by ε gives
    // (100·sin ε, 0, 100·cos ε): Abbe error Δx = 100·sin ε = 1.0 µm, Δz = −100·(1 − cos ε) = −5e-9 mm.
    let a = Point3::new(400.0, 700.0, 300.0);
    let t = Vector3::new(0.0, 0.0, -200.0);
    let d = m.tip(&a, &t) - m.nominal_tip(&a, &t);
    assert!((d.x - 100.0 * eps.sin()).abs() < 1e-13, "dx {}", d.x);
    assert!(d.y.abs() < 1e-13);
    assert!((d.z + 100.0 * (1.0 - eps.cos())).abs() < 1e-13);
    assert!((d.x - 1.0e-3).abs() < 1e-12);

    // Gantry, Y-axis pitch (about X) of −20 µrad: lever z + t_z = 1500 − 300 = 1200 mm;
    // rotating (0,0,1200) about +X by ε gives (0, −1200·sin ε, 1200·cos ε): Δy = +24 µm.
    let eps = -20e-6;
    let mut g = GeometricErrors::zero();
    g.axes[Axis::Y.index()].angular[0] = ErrorFn::constant(eps);
    let m = Machine::gantry(g);
    let a = Point3::new(8000.0, 2000.0, 1500.0);
    let t = Vector3::new(0.0, 0.0, -300.0);
    let d = m.tip(&a, &t) - m.nominal_tip(&a, &t);
    assert!((d.y - 24e-3).abs() < 1e-10, "dy {}", d.y);
    assert!(d.x.abs() < 1e-13);
}

#[test]
fn squareness_and_positioning_by_hand() {
    let mut g = GeometricErrors::zero();
    g.squareness.xy = 5e-6;
    g.squareness.xz = -3e-6;
    g.squareness.yz = 2e-6;
    g.axes[Axis::Y.index()].linear[0] = ErrorFn::linear(4e-6); // 4 µm/m positioning along Y
    let m = Machine::bridge_cmm(g);
    let a = Point3::new(800.0, 1000.0, 500.0);
    let d = m.tip(&a, &Vector3::zeros()) - m.nominal_tip(&a, &Vector3::zeros());
    // x: xz·z = −1.5 µm; y: xy·x + yz·z + 4e-6·y = 4 + 1 + 4 = 9 µm; z: 0.
    assert!((d.x + 1.5e-3).abs() < 1e-12);
    assert!((d.y - 9e-3).abs() < 1e-12);
    assert!(d.z.abs() < 1e-12);
}

#[test]
fn thermal_growth_scales_the_axes() {
    // Steel-like scale 11.5e-6/K, 2 K warm: 23 µm/m on X from the scale origin at x = 0.
    let m = Machine::bridge_cmm(GeometricErrors::zero()).with_growth([23e-6, 0.0, 0.0], [0.0; 3]);
    let a = Point3::new(1000.0, 10.0, 10.0);
    let d = m.tip(&a, &Vector3::zeros()) - m.nominal_tip(&a, &Vector3::zeros());
    assert!((d.x - 23e-3).abs() < 1e-12 && d.y.abs() < 1e-15 && d.z.abs() < 1e-15);
}

#[test]
fn machine_follows_a_thermal_history() {
    use truepos_sim::thermal::{Step, TemperatureHistory, ThermalModel};
    // Air at 20 °C, +3 K step at t = 0+ (1 s); steel scales with a 1800 s lag fixed at x = 0.
    let air = TemperatureHistory {
        steps: vec![Step { time: 1.0, delta: 3.0 }],
        ..TemperatureHistory::constant(20.0)
    };
    let model = ThermalModel::steel(air);
    let a = Point3::new(1000.0, 0.0, 0.0);
    let dx = |t: f64| {
        let m = Machine::bridge_cmm(GeometricErrors::zero()).at_time(&model, t);
        (m.tip(&a, &Vector3::zeros()) - a).x
    };
    // Before the step: 20 °C, no growth. One time constant later: 11.5e-6·3·(1 − e⁻¹)·1000 mm.
    assert!(dx(0.5).abs() < 1e-15);
    let want = 11.5e-6 * 3.0 * (1.0 - (-1.0f64).exp()) * 1000.0;
    assert!((dx(1801.0) - want).abs() < 1e-12, "{} vs {want}", dx(1801.0));
}

#[test]
fn commanded_positions_put_the_tool_on_target() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for kind in KINDS {
        let m = Machine::realistic(kind, 5);
        let t = Vector3::new(0.0, 0.0, -120.0);
        for _ in 0..50 {
            let target = random_axes(&mut rng, &m) + t;
            let c = m.command_for(&target, &t).unwrap();
            assert!((m.tip(&c, &t) - target).norm() < 1e-9);
        }
    }
}

#[test]
fn vmc_without_errors_is_the_contract_model() {
    let mut m = Machine::realistic(MachineKind::Vmc, 6);
    m.chain.errors = GeometricErrors::zero();
    let table: RotaryTable = m.table.unwrap();
    let r = Vector3::new(40.0, -15.0, -160.0);
    let p = Point3::new(300.0, 200.0, 350.0);
    for (b, c) in [(0.0, 0.0), (0.7, 1.1), (-1.2, 3.0)] {
        let q = m.head_point(&p, b, &r);
        assert!((q - head_point(&p, b, &r)).norm() < 1e-12);
        assert!((q - (p + ry(b) * r)).norm() < 1e-12);
        let on_table = m.head_point_on_table(&p, b, c, &r);
        let o = table.centre;
        assert!((on_table - (o + rz(-c) * (q - o))).norm() < 1e-12);
    }
    // With errors the head point moves by the volumetric error of the swivelled offset.
    let m = Machine::realistic(MachineKind::Vmc, 6);
    let q = m.head_point(&p, 0.5, &r);
    let e = m.first_order_error(&p, &(ry(0.5) * r));
    assert!((q - (p + ry(0.5) * r) - e).norm() < 1e-5 * e.norm().max(1e-3));
    assert!(e.norm() > 1e-4, "realistic VMC errors are µm-level: {}", e.norm());
}

#[test]
fn realistic_gantry_errors_are_tens_of_micrometres() {
    let m = Machine::realistic(MachineKind::Gantry, 7);
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let mut worst: f64 = 0.0;
    for _ in 0..500 {
        let a = random_axes(&mut rng, &m);
        worst = worst.max((m.tip(&a, &Vector3::zeros()) - m.nominal_tip(&a, &Vector3::zeros())).norm());
    }
    // Positioning ±40 µm, straightness ±25 µm, 10 µrad over metres: worst 20–500 µm.
    assert!(worst > 20e-3 && worst < 0.5, "worst {worst}");
}

mod properties {
    use super::*;
    use proptest::prelude::*;
    use truepos_sim::laser::{ray_plane, ray_sphere};

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Commanding then moving lands on the target for any realistic machine, position, tool.
        #[test]
        fn command_inverts_the_chain(seed in 0u64..1000, fx in 0.0..1.0f64, fy in 0.0..1.0f64,
                                     fz in 0.0..1.0f64, tz in -400.0..0.0f64, kind in 0usize..3) {
            let m = Machine::realistic(KINDS[kind], seed);
            let a = Point3::new(fx * m.travel[0], fy * m.travel[1], fz * m.travel[2]);
            let t = Vector3::new(10.0, -5.0, tz);
            let target = a + t;
            let c = m.command_for(&target, &t).unwrap();
            prop_assert!((m.tip(&c, &t) - target).norm() < 1e-9);
        }

        /// The laser's exact ray intersections lie on the surface.
        #[test]
        fn ray_hits_lie_on_the_surface(ox in -50.0..50.0f64, oy in -50.0..50.0f64, oz in 30.0..80.0f64,
                                       dx in -0.3..0.3f64, dy in -0.3..0.3f64, r in 5.0..20.0f64) {
            let o = Point3::new(ox * 0.1, oy * 0.1, oz);
            let d = Vector3::new(dx, dy, -1.0).normalize();
            let c = Point3::new(0.0, 0.0, 0.0);
            if let Some(t) = ray_sphere(&o, &d, &c, r) {
                prop_assert!(((o + t * d) - c).norm() - r < 1e-9);
                prop_assert!(((o + t * d) - c).norm() - r > -1e-9);
                // Entering point: the outward normal faces the beam.
                prop_assert!(((o + t * d) - c).dot(&d) <= 1e-9);
            }
            let n = Vector3::new(0.1, -0.2, 1.0).normalize();
            let t = ray_plane(&o, &d, &c, &n).unwrap();
            prop_assert!(n.dot(&((o + t * d) - c)).abs() < 1e-9);
        }
    }
}
