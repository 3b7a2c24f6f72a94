//! Bench: simulate a ≥ 60 s latency run with both streams at 10 kHz (stylus integrated at
//! 40 kHz, servo on, noise on). Target: well under a second.

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use truepos_sim::scenario::latency::{simulate, Config, Variant};

fn sixty_second_config() -> Config {
    let mut cfg = Config::preset(Variant::Sphere);
    cfg.machine_rate_hz = 10_000.0;
    cfg.probe_rate_hz = 10_000.0;
    let one = simulate(&Config { repeats: 1, ..cfg.clone() }).expect("valid config").truth.duration_s;
    cfg.repeats = (60.0 / one).ceil() as usize;
    cfg
}

fn bench(c: &mut Criterion) {
    let cfg = sixty_second_config();
    let ds = simulate(&cfg).expect("valid config");
    eprintln!(
        "latency run: {:.1} s simulated, {} machine + {} probe samples, {} contacts",
        ds.truth.duration_s,
        ds.machine.len(),
        ds.probe.len(),
        ds.truth.contacts.len()
    );
    let mut g = c.benchmark_group("latency_sim");
    g.sample_size(10);
    g.bench_function("sphere_60s_10kHz", |b| b.iter(|| simulate(&cfg).expect("valid config")));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
