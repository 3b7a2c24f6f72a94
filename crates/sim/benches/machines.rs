//! Benches of the machine models and the head-offset scenario: exact kinematic chain, first-order
//! error, command inversion, tracker reading, a full head-offset data set.
//! Run: `cargo bench -p truepos-sim --bench machines`.

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use truepos_math::types::{Point3, Vector3};
use truepos_math::Transform3;
use truepos_sim::machine::{Machine, MachineKind};
use truepos_sim::scenario::head_offset::{simulate, HeadOffsetConfig, Variant};
use truepos_sim::tracker::Tracker;

fn machines(c: &mut Criterion) {
    let g = Machine::realistic(MachineKind::Gantry, 1);
    let a = Point3::new(6123.0, 2345.0, 1234.0);
    let t = Vector3::new(0.0, 0.0, -250.0);
    c.bench_function("gantry exact tip", |b| b.iter(|| g.tip(black_box(&a), black_box(&t))));
    c.bench_function("gantry first-order error", |b| {
        b.iter(|| g.first_order_error(black_box(&a), black_box(&t)))
    });
    let target = g.tip(&a, &t);
    c.bench_function("gantry command_for", |b| b.iter(|| g.command_for(black_box(&target), black_box(&t))));
    let tr = Tracker::new(Transform3::identity());
    let mut rng = truepos_sim::noise::rng(1);
    c.bench_function("tracker measure", |b| b.iter(|| tr.measure(black_box(&target), 0.0, &mut rng)));
    let cfg = HeadOffsetConfig::preset(Variant::Both, 1);
    c.bench_function("head-offset both (216 rows)", |b| b.iter(|| simulate(black_box(&cfg))));
}

criterion_group!(benches, machines);
criterion_main!(benches);
