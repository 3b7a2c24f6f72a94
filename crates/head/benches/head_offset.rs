//! Criterion benches of the head-offset adjustment on the virtual cell's data sets: the preset
//! `both` variant (216 readings, 6 orientations), the pyramid vertex (160 readings, 4 faces) and
//! a dense sphere data set (6 orientations × 5 000 readings).

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use truepos_head::{solve, Params, Reading, Reference};
use truepos_math::{Point3, Vector3};
use truepos_sim::scenario::head_offset::{simulate, HeadOffsetConfig, Variant};

fn data(variant: Variant, per: Option<usize>) -> (Vec<Reading>, Params) {
    let mut cfg = HeadOffsetConfig::preset(variant, 1);
    if let Some(n) = per {
        cfg.points_per_orientation = n;
    }
    let d = simulate(&cfg).expect("preset configurations are valid");
    let readings = d
        .rows
        .iter()
        .map(|r| Reading {
            b: r.b_deg.to_radians(),
            c: r.c_deg.to_radians(),
            p: Point3::new(r.x_mm, r.y_mm, r.z_mm),
            dist: r.dist_mm,
            face: r.face.map(|f| f as i64),
            group: Some(r.group as i64),
        })
        .collect();
    let reference = if d.truth.variant_reference == "sphere" {
        Reference::Sphere { radius: None }
    } else {
        Reference::Vertex { tip_radius: d.truth.tip_radius_mm.unwrap_or(0.0) }
    };
    let setup = Params {
        reference,
        table_center: Point3::from(d.truth.table_center_mm),
        tilt: [0.0, 0.0],
        prior: Vector3::zeros(),
        beam_through_reference: false,
    };
    (readings, setup)
}

fn bench(c: &mut Criterion) {
    for (name, variant, per) in [
        ("both_216", Variant::Both, None),
        ("pyramid_160", Variant::Pyramid, None),
        ("both_30000", Variant::Both, Some(5000)),
    ] {
        let (readings, setup) = data(variant, per);
        c.bench_function(&format!("head_offset/{name}"), |b| b.iter(|| solve(black_box(&readings), &setup)));
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
