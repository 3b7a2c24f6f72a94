//! The figures behind docs/performance-fe.md: the timing of the full influence map of a
//! 2 m × 1.5 m bed (21 × 16 = 336 unit loads every 100 mm) and the mesh-size convergence study.
//! It prints; the checks of the plate model are in `tests/`.
//!
//! Run: `cargo run -p truepos-fe --release --example influence_figures`

use std::time::Instant;

use truepos_fe::{Bed, MeshOptions, PlateModel, Supports};

fn bed() -> Bed {
    Bed {
        size_x: 2000.0,
        size_y: 1500.0,
        thickness: 250.0,
        youngs_modulus: 5.0e4,
        poisson: 0.2,
        supports: Supports::Points {
            xy: vec![[200.0, 150.0], [1800.0, 150.0], [200.0, 1350.0], [1800.0, 1350.0]],
            stiffness_n_per_mm: None,
        },
    }
}

fn unit_cases() -> Vec<[(f64, f64, f64); 1]> {
    let mut cases = Vec::new();
    for i in 0..=20 {
        for j in 0..=15 {
            cases.push([(i as f64 * 100.0, j as f64 * 100.0, 1000.0)]);
        }
    }
    cases
}

/// Rail read-out of one field: uz along two rails (x = 100 and 1900) every 100 mm.
fn rail_readout(d: &truepos_fe::Deflection) -> Vec<f64> {
    let mut v = Vec::new();
    for x in [100.0, 1900.0] {
        for j in 0..=15 {
            v.push(d.uz(x, j as f64 * 100.0));
        }
    }
    v
}

fn influence_map_timing() {
    let cases = unit_cases();
    assert_eq!(cases.len(), 336);
    for h in [50.0, 25.0, 12.5] {
        let t0 = Instant::now();
        let model = PlateModel::new(&bed(), &MeshOptions::with_element_size(h)).unwrap();
        let t1 = Instant::now();
        let fields = model.solve_many(&cases).unwrap();
        let readout: f64 = fields.iter().map(|d| rail_readout(d).iter().sum::<f64>()).sum();
        let t2 = Instant::now();
        eprintln!(
            "h = {h} mm: {} nodes, {} equations; build+factorise {:.3} s, 336 solves + read-out {:.3} s, total {:.3} s (checksum {readout:.6e})",
            model.mesh().n_nodes(),
            model.n_equations(),
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t2 - t0).as_secs_f64()
        );
        assert!((t2 - t0).as_secs_f64() < 60.0);
    }
}

/// Convergence of the influence-map quantities (rail deflections and the rail slope over a
/// 100 mm base, what the portal's pitch/roll are made of) with the element size; reference:
/// Richardson extrapolation (order 2) of the two finest meshes.
fn mesh_convergence_study() {
    let loads =
        [(500.0, 400.0), (1000.0, 800.0), (1700.0, 1200.0), (100.0, 700.0), (0.0, 700.0), (1000.0, 1500.0)];
    let sizes = [100.0, 50.0, 25.0, 12.5, 6.25];
    let mut out: Vec<Vec<f64>> = Vec::new();
    for &h in &sizes {
        let t0 = Instant::now();
        let model = PlateModel::new(&bed(), &MeshOptions::with_element_size(h)).unwrap();
        let cases: Vec<[(f64, f64, f64); 1]> = loads.iter().map(|l| [(l.0, l.1, 1000.0)]).collect();
        let fields = model.solve_many(&cases).unwrap();
        let v: Vec<f64> = fields.iter().flat_map(rail_readout).collect();
        eprintln!("h = {h}: {} equations, {:.2} s", model.n_equations(), t0.elapsed().as_secs_f64());
        out.push(v);
    }
    let n = out.len();
    let reference: Vec<f64> = out[n - 1].iter().zip(&out[n - 2]).map(|(f, c)| f + (f - c) / 3.0).collect();
    let max_ref = reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // Slopes along the rails over 100 mm.
    let slopes = |v: &[f64]| -> Vec<f64> {
        let mut s = Vec::new();
        for c in v.chunks(16) {
            for w in c.windows(2) {
                s.push((w[1] - w[0]) / 100.0);
            }
        }
        s
    };
    let sref = slopes(&reference);
    let max_sref = sref.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (h, v) in sizes.iter().zip(&out) {
        let e = v.iter().zip(&reference).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let s = slopes(v);
        let es = s.iter().zip(&sref).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        eprintln!(
            "h = {h:6.2} mm: max |uz err| {:.3e} of max |uz| {max_ref:.3e} ({:.3} %), max slope err {:.3} % of max slope",
            e,
            100.0 * e / max_ref,
            100.0 * es / max_sref
        );
    }
}

fn main() {
    influence_map_timing();
    mesh_convergence_study();
}
