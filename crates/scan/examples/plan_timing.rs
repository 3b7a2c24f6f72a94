//! Planning time and the largest speed, |acceleration| and |jerk| of the planned positioning
//! moves for the test programs (`scenario(11, n)`), both styles:
//! `cargo run --release -p truepos-scan --example plan_timing [n ...]`.

use std::time::Instant;
use truepos_scan::{plan, Style};

fn main() {
    let ns: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ns = if ns.is_empty() { vec![4, 8, 16] } else { ns };
    for n in ns {
        let s = truepos_sim::scenario::scan::scenario(11, n);
        let (fs, _, p) = truepos_cell::scan_scenario::program(&s);
        for style in [Style::Blended, Style::Classic] {
            let t0 = Instant::now();
            let pl = plan(&fs, &p, style);
            let dt = t0.elapsed();
            println!(
                "{n:2} features {:8}: planned in {:8.2} ms, program {:.3} s",
                style.name(),
                dt.as_secs_f64() * 1e3,
                pl.duration()
            );
        }
    }
}
