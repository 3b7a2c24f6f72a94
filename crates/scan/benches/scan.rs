//! Planning and simulating a 100-feature program (blended style) on the virtual CMM.
//! Run: `cargo bench -p truepos-scan --bench scan`. Figures: docs/performance-scan.md.

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use truepos_plant::scanning_cmm::{run_scan, CmmConfig};
use truepos_scan::execute::ControlParams;
use truepos_scan::{plan, validate, Style};

fn bench(c: &mut Criterion) {
    let scenario = truepos_plant::scan_scenario::scenario(7, 100);
    let (features, truth, params) = truepos_plant::scan_scenario::program(&scenario);
    validate(&features, &params).expect("valid program");
    let machine = CmmConfig::default();
    let mut g = c.benchmark_group("scan");
    g.sample_size(10);
    g.bench_function("plan_100_features", |b| b.iter(|| plan(&features, &params, Style::Blended)));
    g.bench_function("plan_and_simulate_100_features", |b| {
        b.iter(|| {
            let p = plan(&features, &params, Style::Blended);
            run_scan(&p, &truth, &machine, &ControlParams::default(), 1).expect("runs")
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
