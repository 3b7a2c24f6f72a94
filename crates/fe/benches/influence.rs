//! Criterion benches of the bed model: build (mesh, assembly, sparse Cholesky) and the full
//! influence map of a 2 m × 1.5 m granite bed (336 unit loads every 100 mm), at the automatic
//! element size (25 mm). Figures in docs/performance-fe.md.

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
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

fn cases() -> Vec<[(f64, f64, f64); 1]> {
    (0..=20).flat_map(|i| (0..=15).map(move |j| [(i as f64 * 100.0, j as f64 * 100.0, 1000.0)])).collect()
}

fn bench(c: &mut Criterion) {
    let bed = bed();
    let mesh = MeshOptions::default();
    let mut g = c.benchmark_group("fe");
    g.sample_size(10);
    g.bench_function("build_2000x1500_h25", |b| b.iter(|| PlateModel::new(&bed, &mesh).expect("valid bed")));
    let cases = cases();
    g.bench_function("influence_map_336_loads_h25", |b| {
        b.iter(|| {
            let model = PlateModel::new(&bed, &mesh).expect("valid bed");
            let fields = model.solve_many(&cases).expect("loads on the bed");
            fields.iter().map(|d| d.uz(100.0, 750.0)).sum::<f64>()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
