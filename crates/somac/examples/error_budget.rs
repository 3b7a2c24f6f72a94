//! The loop's error budget on the virtual gantry (docs/performance-somac.md): the spar run with
//! one error source removed at a time — tracker noise, air temperature changes, beam
//! interrupts, obstructions — and the hole errors each leaves. It prints; the checks are in
//! `tests/virtual_gantry.rs`.
//!
//! Run: `cargo run --release -p truepos-somac --example error_budget`

#[path = "../tests/support/mod.rs"]
mod support;

use support::{run, spar_params};
use truepos_plant::gantry::CellConfig;
use truepos_somac::stats::hole_stats;

fn main() {
    let base = CellConfig::default();
    let flat = truepos_sim::thermal::TemperatureHistory::constant(23.5);
    for (name, cfg) in [
        ("default", base.clone()),
        (
            "no tracker noise",
            CellConfig { tracker_mpe_a_mm: 0.0, tracker_mpe_b_mm_per_m: 0.0, ..base.clone() },
        ),
        ("constant air temperature", CellConfig { air_temperature: flat.clone(), ..base.clone() }),
        ("no interrupts", CellConfig { beam_interrupt_probability: 0.0, ..base.clone() }),
        (
            "no obstructions",
            CellConfig {
                trackers: base
                    .trackers
                    .iter()
                    .cloned()
                    .map(|mut t| {
                        t.obstructions.clear();
                        t
                    })
                    .collect(),
                ..base.clone()
            },
        ),
        (
            "no noise, constant temp",
            CellConfig {
                tracker_mpe_a_mm: 0.0,
                tracker_mpe_b_mm_per_m: 0.0,
                air_temperature: flat,
                ..base.clone()
            },
        ),
    ] {
        let (r, e, _) = run(cfg, &spar_params(), 150);
        let s = hole_stats(&e);
        eprintln!(
            "{name}: mean {:.4} σ {:.4} max {:.4} orientations {}",
            s.mean_error_mm, s.std_error_mm, s.max_error_mm, r.orientations
        );
        for (st, err) in r.stops.iter().zip(&e) {
            if *err > 0.05 {
                eprintln!(
                    "   line {} {:?} true {:.4} final {:.4} iters {} {:?}",
                    st.line, st.status, err, st.final_error_mm, st.iterations, st.message
                );
            }
        }
        eprintln!("   alarms {:?}", r.alarms.iter().map(|a| (a.line, a.kind.as_str())).collect::<Vec<_>>());
    }
}
