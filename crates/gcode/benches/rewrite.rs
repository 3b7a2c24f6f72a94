//! Parse and rewrite a million-line drilling program through a small rotation + translation.

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use truepos_gcode::{Program, TransformOptions};
use truepos_math::types::rz;
use truepos_math::{Transform3, Vector3};

pub fn million_line_program() -> String {
    let mut s = String::with_capacity(40_000_000);
    s.push_str("%\nO1000 (WING SPAR)\nG21 G90 G17\nG0 X0 Y0 Z50\n");
    for i in 0..1_000_000u32 {
        let x = (i % 1000) as f64 * 12.5;
        let y = (i / 1000) as f64 * 4.0;
        if i % 50 == 0 {
            s.push_str(&format!("N{} G1 X{x:.3} Y{y:.3} F2000 (MSG,Measure SOMaC)\n", i + 10));
        } else {
            s.push_str(&format!("N{} G1 X{x:.3} Y{y:.3}\n", i + 10));
        }
    }
    s.push_str("M30\n%\n");
    s
}

fn bench(c: &mut Criterion) {
    let src = million_line_program();
    let t = Transform3::new(1.0001, rz(0.002), Vector3::new(1.5, -0.7, 0.2));
    let mut g = c.benchmark_group("gcode");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(src.len() as u64));
    g.bench_function("parse_1M_lines", |b| b.iter(|| Program::parse(&src)));
    g.bench_function("parse_and_rewrite_1M_lines", |b| {
        b.iter(|| Program::parse(&src).transform(&t, &TransformOptions::default()).map(|s| s.len()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
