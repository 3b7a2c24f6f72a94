//! End to end on the virtual CMM (`truepos-sim`'s `load` scenario): the influence map from a
//! coarser FE mesh, statics, superposition and the contract's correction must remove at least
//! 95 % of the load-induced error of the measured points.

use truepos_comp::fe_map::{influence_map, BedModel, LoadGrid};
use truepos_comp::statics::distribute;
use truepos_comp::{Corrector, LoadCorrection, Portal};
use truepos_fe::MeshOptions;
use truepos_math::{Point3, Vector3};
use truepos_sim::scenario::load::{simulate, LoadConfig, G};

fn rms_max(v: &[Vector3]) -> (f64, f64) {
    let n = v.len() as f64;
    let rms = (v.iter().map(|e| e.norm_squared()).sum::<f64>() / n).sqrt();
    (rms, v.iter().map(|e| e.norm()).fold(0.0, f64::max))
}

#[test]
fn load_correction_removes_95_percent_on_the_virtual_cmm() {
    let cfg = LoadConfig::default();
    let data = simulate(&cfg, 7).unwrap();
    let portal = Portal {
        rail_x: cfg.rail_x,
        rail_height: cfg.rail_height,
        bearing_span: cfg.bearing_span,
        y_range: cfg.y_range,
        y_step: cfg.y_step,
    };
    let model = BedModel {
        bed: cfg.bed.clone(),
        portal,
        grid: LoadGrid { spacing: cfg.grid_spacing, unit_load_n: cfg.unit_load_n },
    };
    let t0 = std::time::Instant::now();
    let map = influence_map(&model, &MeshOptions::with_element_size(cfg.map_element_size), &|_| {}).unwrap();
    let t_map = t0.elapsed().as_secs_f64();
    let forces = distribute(cfg.mass_kg * G, cfg.cog, &cfg.rests).unwrap();
    for (a, b) in forces.iter().zip(data.forces_n) {
        assert!((a - b).abs() < 1e-6 * b, "statics: comp {a} vs sim {b}");
    }
    let loads: Vec<(f64, f64, f64)> = cfg.rests.iter().zip(&forces).map(|(r, f)| (r[0], r[1], *f)).collect();
    let curves = map.superpose(&loads).unwrap();
    let lc = LoadCorrection::new(curves, &portal);
    let corr = Corrector { geometric: None, load: Some(&lc), probe_offset: Vector3::zeros() };
    // Load-induced error before: indicated (noise-free) − true. After: corrected − true, with the
    // correction computed from the noisy indicated points and the noise itself (not load-induced,
    // no correction can remove it) subtracted.
    let mut corrected: Vec<Point3> = data.indicated.clone();
    corr.correct_measured(&mut corrected, None).unwrap();
    let before: Vec<Vector3> =
        data.indicated_exact.iter().zip(&data.true_points).map(|(i, t)| i - t).collect();
    let after: Vec<Vector3> = corrected
        .iter()
        .zip(&data.indicated)
        .zip(data.indicated_exact.iter().zip(&data.true_points))
        .map(|((c, n), (e, t))| (c - (n - e)) - t)
        .collect();
    let with_noise: Vec<Vector3> = corrected.iter().zip(&data.true_points).map(|(c, t)| c - t).collect();
    let (rb, mb) = rms_max(&before);
    let (ra, ma) = rms_max(&after);
    let (rn, mn) = rms_max(&with_noise);
    eprintln!(
        "load error before: rms {:.3} µm max {:.3} µm; after: rms {:.4} µm max {:.4} µm ({:.2} % removed); incl. noise: rms {:.3} max {:.3} µm; map {} cases in {t_map:.1} s",
        rb * 1e3, mb * 1e3, ra * 1e3, ma * 1e3, 100.0 * (1.0 - ra / rb), rn * 1e3, mn * 1e3, map.load_x().len() * map.load_y().len()
    );
    for (k, y) in data.portal_y.iter().enumerate().step_by(4) {
        let (p, r) = lc.curves.at(*y).unwrap();
        eprintln!(
            "y {y:7.1}  pitch {:8.4} (true {:8.4})  roll {:8.4} (true {:8.4}) µrad",
            p * 1e6,
            data.pitch[k] * 1e6,
            r * 1e6,
            data.roll[k] * 1e6
        );
    }
    assert!(rb > 1e-3, "the scenario must produce a visible error (rms {rb} mm)");
    assert!(ra < 0.05 * rb && ma < 0.05 * mb, "≥ 95 % reduction required");
}
