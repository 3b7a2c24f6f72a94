//! Figures for the report: the head-offset adjustment on every variant of the simulator's
//! scenario over 20 seeds — errors against the truth, uncertainties, the honesty of the
//! uncertainty (rms of error/u, ≈ 1 when the covariance is right) and the solve time.
//!
//! `cargo run --release -p truepos-head --example head_offset_figures`
//! (the assertions are in `tests/virtual_cell.rs`; this prints, it does not check).

#[path = "../tests/support/mod.rs"]
mod support;

use support::{readings, setup};
use truepos_head::solve;
use truepos_math::Vector3;
use truepos_sim::scenario::head_offset::{simulate, HeadOffsetConfig, Variant};

/// Largest error over the observable components (mm).
fn worst_error(variant: Variant, seed: u64) -> f64 {
    let cfg = HeadOffsetConfig::preset(variant, seed);
    let d = simulate(&cfg).expect("preset scenario");
    let r = solve(&readings(&d), &setup(&cfg, &d, false)).expect("solvable preset");
    let truth = Vector3::from(d.truth.offset_mm);
    (0..3).filter(|&j| r.observable[j]).map(|j| (r.offset[j] - truth[j]).abs()).fold(0.0, f64::max)
}

fn main() {
    for v in Variant::ALL {
        let all: Vec<f64> = (1..=20).map(|seed| worst_error(v, seed)).collect();
        let worst = all.iter().copied().fold(0.0, f64::max);
        let mut z2 = 0.0;
        let mut nz = 0;
        for seed in 1..=20 {
            let cfg = HeadOffsetConfig::preset(v, seed);
            let d = simulate(&cfg).expect("preset scenario");
            let r = solve(&readings(&d), &setup(&cfg, &d, false)).expect("solvable preset");
            for j in 0..3 {
                if let Some(u) = r.u_offset[j] {
                    z2 += ((r.offset[j] - d.truth.offset_mm[j]) / u).powi(2);
                    nz += 1;
                }
            }
        }
        let cfg = HeadOffsetConfig::preset(v, 1);
        let d = simulate(&cfg).expect("preset scenario");
        let t0 = std::time::Instant::now();
        let r = solve(&readings(&d), &setup(&cfg, &d, false)).expect("solvable preset");
        let dt = t0.elapsed();
        let truth = Vector3::from(d.truth.offset_mm);
        println!(
            "{:8} n={:4} obs={:?} err_um=[{}] u_um=[{}] rms_um={:.3} iters={} time={:?} worst20_um={:.3} over1um={} rms(err/u)={:.2}",
            v.name(),
            r.n_points,
            r.observable,
            (0..3).map(|j| format!("{:+.3}", (r.offset[j] - truth[j]) * 1e3)).collect::<Vec<_>>().join(","),
            (0..3).map(|j| r.u_offset[j].map_or("-".into(), |u| format!("{:.3}", u * 1e3))).collect::<Vec<_>>().join(","),
            r.rms * 1e3,
            r.iterations,
            dt,
            worst * 1e3,
            all.iter().filter(|e| **e > 1e-3).count(),
            (z2 / nz as f64).sqrt()
        );
    }
}
