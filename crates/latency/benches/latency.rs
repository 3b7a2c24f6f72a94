//! Criterion benches of the hot paths: the whole touch calibration (checks, interpolation,
//! segmentation, extrapolation, sphere fit) on a million-sample pair of streams, the
//! interpolation pass alone, and the scan method.
//!
//! Run: `cargo bench -p truepos-latency` (figures in docs/performance-latency.md).

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use truepos_latency::{estimate, stream, KnownSize, Options};
use truepos_math::Point3;

#[path = "../tests/common/mod.rs"]
mod common;
use common::*;

fn million() -> Data {
    // 10 kHz machine and probe for 100 s: 1.0 M samples each; 5-point sets at 20 mm/s.
    let cap = Capture { machine_rate: 10_000.0, probe_rate: 10_000.0, ..Capture::realistic(2.5e-3, 1) };
    let set = five_point(Point3::new(0.0, 0.0, 0.0), 12.5, 20.0, 0.3);
    // One touch takes about 0.17 s: 140 sets of five cover the 100 s.
    let list: Vec<Touch> = (0..140).flat_map(|_| set.iter().copied()).collect();
    let mut d = touches(&cap, &list);
    assert!(d.pt.len() >= 1_000_000 && d.mt.len() >= 1_000_000, "{} samples", d.pt.len());
    d.pt.truncate(1_000_000);
    d.p.truncate(1_000_000);
    d.mt.truncate(1_000_000);
    d.m.truncate(1_000_000);
    d
}

fn benches(c: &mut Criterion) {
    let d = million();
    eprintln!("streams: {} machine, {} probe samples", d.mt.len(), d.pt.len());
    let opt = Options { known_size: Some(KnownSize::SphereDiameter(25.0)), ..Options::default() };
    let e = estimate(&d.streams(), &opt).expect("estimate");
    eprintln!("{} contacts, delay {:.3} µs ± {:.3} µs", e.n_contacts, e.delay * 1e6, e.u_delay * 1e6);
    let mut g = c.benchmark_group("latency");
    g.sample_size(10);
    g.bench_function("artefact_1M_pair", |b| {
        b.iter(|| estimate(black_box(&d.streams()), &opt).unwrap().delay)
    });
    let mut out = Vec::new();
    g.bench_function("interpolate_1M", |b| {
        b.iter(|| {
            stream::machine_at(&d.mt, &d.m, &d.pt, 2.5e-3, &mut out);
            out.len()
        })
    });
    // Scan: 4 revolutions of a 12.5 mm circle at 20 mm/s, 10 kHz: ~160 k samples per stream.
    let cap = Capture { machine_rate: 10_000.0, probe_rate: 10_000.0, ..Capture::realistic(2.5e-3, 2) };
    let s = circle_scan(&cap, Point3::origin(), 12.5, 20.0, 0.1, 0.25, &[0.5, 1.6, 3.0, 5.2], 0.12, 4.0);
    eprintln!("scan: {} probe samples", s.pt.len());
    g.bench_function("scan_160k_pair", |b| {
        b.iter(|| estimate(black_box(&s.streams()), &Options::default()).unwrap().delay)
    });
    g.finish();
}

criterion_group!(latency, benches);
criterion_main!(latency);
