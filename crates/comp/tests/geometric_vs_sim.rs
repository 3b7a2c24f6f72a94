//! The first-order compensation model against `truepos-sim`'s exact kinematic chain (finite
//! rotations, written independently by another engineer from docs/conventions.md).

use truepos_comp::{Axis, AxisErrors, AxisTable, Chain, Corrector, GeometricMap, Squareness};
use truepos_math::{Point3, Vector3};
use truepos_sim::errors::{Axis as SAxis, GeometricErrors};
use truepos_sim::machine::{Machine, MachineKind};

/// The comp map holding the simulator's errors sampled every `step` mm.
fn map_of(g: &GeometricErrors, travel: [f64; 3], step: f64) -> GeometricMap {
    let mut m = GeometricMap {
        squareness: Squareness { xy: g.squareness.xy, xz: g.squareness.xz, yz: g.squareness.yz },
        ..Default::default()
    };
    for (sa, ca) in [(SAxis::X, Axis::X), (SAxis::Y, Axis::Y), (SAxis::Z, Axis::Z)] {
        let rows: Vec<_> = g.table(travel, step).into_iter().filter(|r| r.axis == sa).collect();
        let pos: Vec<f64> = rows.iter().map(|r| r.position).collect();
        let e: Vec<AxisErrors> = rows
            .iter()
            .map(|r| AxisErrors {
                pos: r.values[0],
                str1: r.values[1],
                str2: r.values[2],
                pitch: r.values[3],
                yaw: r.values[4],
                roll: r.values[5],
            })
            .collect();
        let t = AxisTable::new(ca, pos, &e).unwrap();
        match ca {
            Axis::X => m.x = Some(t),
            Axis::Y => m.y = Some(t),
            Axis::Z => m.z = Some(t),
        }
    }
    m
}

fn scaled(g: &GeometricErrors, k: f64) -> GeometricErrors {
    let mut g = g.clone();
    for a in &mut g.axes {
        for f in a.linear.iter_mut().chain(a.angular.iter_mut()) {
            *f = f.clone().scaled(k);
        }
    }
    g.squareness.xy *= k;
    g.squareness.xz *= k;
    g.squareness.yz *= k;
    g
}

/// Max |corrected − actual| and max |E| over points on the table nodes (no interpolation error).
fn worst(machine: &Machine, step: f64, tool: Vector3) -> (f64, f64) {
    let mut map = map_of(&machine.chain.errors, machine.travel, step);
    if machine.kind == MachineKind::Gantry {
        map.chain = Chain::GantryXYZ;
    }
    let corr = Corrector { geometric: Some(&map), load: None, probe_offset: tool };
    let (mut dmax, mut emax) = (0.0f64, 0.0f64);
    for i in 0..=10 {
        for j in 0..=10 {
            for k in 0..=8 {
                let axes = Point3::new(100.0 * i as f64, 150.0 * j as f64, 100.0 * k as f64);
                let actual = machine.tip(&axes, &tool);
                let indicated = axes + tool;
                let d = corr.displacement(&indicated).unwrap();
                dmax = dmax.max((indicated + d - actual).norm());
                emax = emax.max((actual - indicated).norm());
                // Same first-order model, two implementations: equal to rounding.
                let b2 = machine.first_order_error(&axes, &tool);
                assert!((b2 - d).norm() < 1e-12, "first-order models differ at {axes}: {b2} vs {d}");
            }
        }
    }
    (dmax, emax)
}

#[test]
fn first_order_model_matches_the_exact_chain_to_second_order() {
    let m = Machine::realistic(MachineKind::BridgeCmm, 11);
    let tool = Vector3::new(30.0, -40.0, -180.0);
    let (d1, e1) = worst(&m, 50.0, tool);
    // Second-order bound: |ε|²·L with |ε| ≲ 2·(3 + 5) µrad and L ≈ 2,100 mm → ≈ 5e-7 mm.
    assert!(e1 > 1e-3, "errors must be visible: {e1}");
    assert!(d1 < 5e-7, "residual {d1} mm");
    // Scaling all 21 parameters by 10 scales the residual by ~100 (purely second order).
    let m10 = Machine::bridge_cmm(scaled(&m.chain.errors, 10.0));
    let (d10, e10) = worst(&m10, 50.0, tool);
    assert!((e10 / e1 - 10.0).abs() < 0.5);
    let ratio = d10 / d1;
    assert!((70.0..130.0).contains(&ratio), "residual ratio {ratio} (d1 {d1}, d10 {d10})");
    eprintln!(
        "max |E| {:.3} µm; first-order residual {:.2e} µm (×10 errors: {:.2e} µm, ratio {ratio:.1})",
        e1 * 1e3,
        d1 * 1e3,
        d10 * 1e3
    );
}

#[test]
fn gantry_chain_matches_to_second_order() {
    // Large gantry (bed → X → Y → Z): ±10 µrad angular errors; over the 1 × 1.5 × 0.8 m region
    // sampled the second-order residual is ≲ (2·20 µrad)²·2,100 mm ≈ 3e-6 mm.
    let m = Machine::realistic(MachineKind::Gantry, 3);
    let (d, e) = worst(&m, 50.0, Vector3::new(0.0, 0.0, -300.0));
    assert!(e > 5e-3 && d < 3e-6, "residual {d} mm, |E| {e} mm");
    eprintln!("gantry: max |E| {:.2} µm, first-order residual {:.2e} µm", e * 1e3, d * 1e3);
}

#[test]
fn inverse_reaches_targets_on_the_exact_chain() {
    let m = Machine::realistic(MachineKind::BridgeCmm, 5);
    let tool = Vector3::new(0.0, 0.0, -150.0);
    // Commanded positions fall between table nodes: sample every 1 mm so that linear
    // interpolation adds at most h²/8·max|f''| ≈ 2 nm (short waves of 20 mm period, ≲ 0.15 µm).
    let map = map_of(&m.chain.errors, m.travel, 1.0);
    let corr = Corrector { geometric: Some(&map), load: None, probe_offset: tool };
    // Targets whose axis positions stay 10 mm inside the travel (the tables end there).
    let targets: Vec<Point3> = (0..=10)
        .flat_map(|i| {
            (0..=6).map(move |k| {
                Point3::new(10.0 + 98.0 * i as f64, 10.0 + 148.0 * i as f64, 10.0 + 120.0 * k as f64) + tool
            })
        })
        .collect();
    let mut cmd = targets.clone();
    let iters = corr.compensate(&mut cmd).unwrap();
    let mut worst = 0.0f64;
    for (t, c) in targets.iter().zip(&cmd) {
        // The model's own residual is below 1 nm …
        assert!((c + corr.displacement(c).unwrap() - t).norm() < 1e-6);
        // … and on the exact machine the tip lands on the target to second order.
        let reached = m.tip(&(c - tool), &tool);
        // (second order ≲ 0.5 nm plus interpolation ≲ 2 nm: 1e-5 mm leaves margin, and is 300×
        // below the errors being compensated).
        worst = worst.max((reached - t).norm());
        assert!((reached - t).norm() < 1e-5, "{}", (reached - t).norm());
        // B2's exact inverse agrees to the same order.
        let exact = m.command_for(t, &tool).unwrap();
        assert!(((c - tool) - exact).norm() < 1e-5);
    }
    eprintln!(
        "inverse: {} targets, at most {iters} iterations; exact-chain tip vs target max {:.2e} µm",
        targets.len(),
        worst * 1e3
    );
}
