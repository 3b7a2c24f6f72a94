//! Criterion benches of the hot paths: sphere, plane and cylinder fits on 1e5 and 1e6 noisy
//! points (the fit alone, data in memory); minimum-zone plane, circle, sphere and cylinder on
//! 1e4 and 1e5 points. Figures: docs/performance-fit.md.

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use truepos_math::{Point3, Vector3};

fn unit(rng: &mut ChaCha8Rng) -> Vector3 {
    loop {
        let v = Vector3::new(
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

fn noise(rng: &mut ChaCha8Rng) -> f64 {
    (rng.random::<f64>() - 0.5) * 0.004
}

fn sphere_pts(n: usize) -> Vec<Point3> {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let c = Point3::new(120.5, -40.25, 310.0);
    (0..n).map(|_| c + unit(&mut rng) * (12.7 + noise(&mut rng))).collect()
}

fn plane_pts(n: usize) -> Vec<Point3> {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    (0..n)
        .map(|_| {
            Point3::new(rng.random::<f64>() * 500.0, rng.random::<f64>() * 300.0, 10.0 + noise(&mut rng))
        })
        .collect()
}

fn cylinder_pts(n: usize) -> Vec<Point3> {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    (0..n)
        .map(|_| {
            let a = rng.random::<f64>() * std::f64::consts::TAU;
            let r = 25.0 + noise(&mut rng);
            Point3::new(r * a.cos() + 5.0, r * a.sin() - 3.0, rng.random::<f64>() * 80.0)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    for n in [100_000usize, 1_000_000] {
        g.throughput(Throughput::Elements(n as u64));
        let s = sphere_pts(n);
        g.bench_with_input(BenchmarkId::new("sphere", n), &s, |b, p| {
            b.iter(|| truepos_fit::sphere(p).unwrap())
        });
        let p = plane_pts(n);
        g.bench_with_input(BenchmarkId::new("plane", n), &p, |b, p| {
            b.iter(|| truepos_fit::plane(p).unwrap())
        });
        let cy = cylinder_pts(n);
        g.bench_with_input(BenchmarkId::new("cylinder", n), &cy, |b, p| {
            b.iter(|| truepos_fit::cylinder(p).unwrap())
        });
    }
    g.finish();
}

fn circle_pts(n: usize) -> Vec<Point3> {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    (0..n)
        .map(|_| {
            let a = rng.random::<f64>() * std::f64::consts::TAU;
            let r = 25.0 + noise(&mut rng) + 0.002 * (3.0 * a).sin();
            Point3::new(r * a.cos() + 5.0, r * a.sin() - 3.0, 7.0)
        })
        .collect()
}

/// Minimum-zone (Chebyshev) fits: plane, circle, sphere, cylinder, 1e4 and 1e5 points.
fn bench_minzone(c: &mut Criterion) {
    use truepos_fit::minzone::{self, Criterion as Crit};
    let mut g = c.benchmark_group("minzone");
    g.sample_size(10);
    for n in [10_000usize, 100_000] {
        g.throughput(Throughput::Elements(n as u64));
        let p = plane_pts(n);
        g.bench_with_input(BenchmarkId::new("plane", n), &p, |b, p| {
            b.iter(|| minzone::plane_zone(p).unwrap())
        });
        let ci = circle_pts(n);
        g.bench_with_input(BenchmarkId::new("circle", n), &ci, |b, p| {
            b.iter(|| minzone::circle_fit(p, Crit::MinimumZone).unwrap())
        });
        let s = sphere_pts(n);
        g.bench_with_input(BenchmarkId::new("sphere", n), &s, |b, p| {
            b.iter(|| minzone::sphere_fit(p, Crit::MinimumZone).unwrap())
        });
        let cy = cylinder_pts(n);
        g.bench_with_input(BenchmarkId::new("cylinder", n), &cy, |b, p| {
            b.iter(|| minzone::cylinder_fit(p, Crit::MinimumZone).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench, bench_minzone);
criterion_main!(benches);
