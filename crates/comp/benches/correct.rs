//! Hot path: 10 million points through the combined map (21-parameter geometric map on uniform
//! 10 mm tables + load pitch/roll curves), in place, all cores; and 1 million points through the
//! geometric map alone, without and with the propagation of its uncertainty (issue 28).

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rayon::prelude::*;
use truepos_comp::{
    Axis, AxisErrors, AxisTable, Corrector, GeometricMap, LoadCorrection, Portal, PortalCurves, Squareness,
};
use truepos_math::{Point3, Vector3};

fn map() -> GeometricMap {
    let pos: Vec<f64> = (0..=200).map(|i| 10.0 * i as f64).collect();
    let mk = |axis, s: f64| {
        let e: Vec<AxisErrors> = pos
            .iter()
            .map(|&p| {
                let u = p / 2000.0;
                AxisErrors {
                    pos: s * 3e-3 * u,
                    str1: s * 1e-3 * (6.0 * u).sin(),
                    str2: s * 1e-3 * u * u,
                    pitch: s * 3e-6 * (3.0 * u).cos(),
                    yaw: s * 2e-6 * u,
                    roll: s * 1e-6 * (5.0 * u).sin(),
                }
            })
            .collect();
        AxisTable::new(axis, pos.clone(), &e).unwrap()
    };
    GeometricMap {
        x: Some(mk(Axis::X, 1.0)),
        y: Some(mk(Axis::Y, -1.0)),
        z: Some(mk(Axis::Z, 0.5)),
        squareness: Squareness { xy: 3e-6, xz: -2e-6, yz: 1e-6 },
        ..Default::default()
    }
}

fn bench(c: &mut Criterion) {
    let g = map();
    let portal = Portal {
        rail_x: [0.0, 2000.0],
        rail_height: 0.0,
        bearing_span: 400.0,
        y_range: [0.0, 2000.0],
        y_step: 50.0,
    };
    let ys: Vec<f64> = (0..=40).map(|i| 50.0 * i as f64).collect();
    let curves = PortalCurves::new(
        ys.clone(),
        ys.iter().map(|y| 1e-6 * (y / 300.0).sin()).collect(),
        ys.iter().map(|y| 2e-7 * y / 2000.0).collect(),
    )
    .unwrap();
    let lc = LoadCorrection::new(curves, &portal);
    let corr =
        Corrector { geometric: Some(&g), load: Some(&lc), probe_offset: Vector3::new(0.0, 0.0, -100.0) };
    let n = 10_000_000usize;
    let base: Vec<Point3> = (0..n)
        .map(|i| {
            Point3::new((i % 1999) as f64 + 0.3, ((i / 1999) % 1999) as f64 + 0.7, 100.0 + (i % 1700) as f64)
        })
        .collect();
    // Corrected in place repeatedly: each pass moves the points by micrometres only, so they stay
    // inside the tables and every pass does the same work (no 240 MB copy inside the timing).
    let mut pts = base;
    let mut g10 = c.benchmark_group("comp");
    g10.sample_size(10);
    g10.throughput(Throughput::Elements(n as u64));
    g10.bench_function("correct_10M_points_combined_map", |b| {
        b.iter(|| {
            corr.correct_measured(&mut pts, None).unwrap();
        })
    });
    g10.finish();

    // Geometric map alone, 1 M points: the correction (what a map without u-columns runs) and the
    // correction with its propagated variance (a map with u-columns).
    let mut gu = map();
    for t in [&mut gu.x, &mut gu.y, &mut gu.z] {
        let tab = t.take().unwrap();
        let u = vec![
            AxisErrors { pos: 5e-5, str1: 1e-4, str2: 1e-4, pitch: 5e-8, yaw: 5e-8, roll: 1e-7 };
            tab.positions().len()
        ];
        *t = Some(tab.with_uncertainty(&u).unwrap());
    }
    gu.squareness_u = Some(Squareness { xy: 2e-7, xz: 2e-7, yz: 2e-7 });
    let plain = Corrector { geometric: Some(&g), load: None, probe_offset: Vector3::new(0.0, 0.0, -100.0) };
    let with_u = Corrector { geometric: Some(&gu), load: None, probe_offset: Vector3::new(0.0, 0.0, -100.0) };
    let m = 1_000_000usize;
    let mut pts: Vec<Point3> = pts[..m].to_vec();
    let mut var = vec![Vector3::zeros(); m];
    let mut g1 = c.benchmark_group("comp_u");
    g1.sample_size(10);
    g1.throughput(Throughput::Elements(m as u64));
    g1.bench_function("correct_1M_points_geometric", |b| {
        b.iter(|| plain.correct_measured(&mut pts, None).unwrap())
    });
    g1.bench_function("correct_1M_points_geometric_with_u", |b| {
        b.iter(|| {
            pts.par_chunks_mut(4096).zip(var.par_chunks_mut(4096)).for_each(|(p, v)| {
                for (p, v) in p.iter_mut().zip(v.iter_mut()) {
                    let (d, s) = with_u.displacement_u(p).unwrap();
                    *p += d;
                    *v = s;
                }
            })
        })
    });
    g1.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
