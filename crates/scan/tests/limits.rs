//! Transfers keep the machine's velocity, acceleration and jerk limits, even in the sharp turns
//! between features that lie close together or face opposite ways: checked on the planned path
//! itself by finite differences of positions (independent of how the planner built it).

use proptest::prelude::*;
use truepos_math::{Point3, Vector3};
use truepos_scan::plan::Plan;
use truepos_scan::{plan, validate, Feature, Geometry, Params, SegmentKind, Side, Style};

/// Finite-difference speed, acceleration and jerk magnitudes over every stencil of positions
/// that lies inside one transfer (for v and a: that touches a transfer), at time step `dt`.
fn transfer_maxima(pl: &Plan, dt: f64) -> (f64, f64, f64) {
    let tip = pl.params.tip_radius;
    let (mut vm, mut am, mut jm) = (0.0f64, 0.0f64, 0.0f64);
    // Sample the whole plan on one uniform clock, remembering which segment each sample is in.
    let total = pl.duration();
    let n = (total / dt).floor() as usize;
    let mut pos = Vec::with_capacity(n + 1);
    let mut kind = Vec::with_capacity(n + 1);
    let mut seg = 0;
    for k in 0..=n {
        let t = k as f64 * dt;
        while seg + 1 < pl.segments.len() && pl.starts[seg + 1] <= t {
            seg += 1;
        }
        let s = &pl.segments[seg];
        let c = s.eval(t - pl.starts[seg], &pl.features[s.feature], tip);
        pos.push(c.position);
        kind.push((seg, s.kind == SegmentKind::Transfer));
    }
    for k in 0..pos.len().saturating_sub(3) {
        let any = (k..k + 3).any(|i| kind[i].1);
        let inside = (k..k + 4).all(|i| kind[i].1 && kind[i].0 == kind[k].0);
        if any {
            let v = (pos[k + 1] - pos[k]).norm() / dt;
            let a = (pos[k + 2].coords - 2.0 * pos[k + 1].coords + pos[k].coords).norm() / (dt * dt);
            vm = vm.max(v);
            am = am.max(a);
        }
        if inside {
            let j = (pos[k + 3].coords - 3.0 * pos[k + 2].coords + 3.0 * pos[k + 1].coords - pos[k].coords)
                .norm()
                / (dt * dt * dt);
            jm = jm.max(j);
        }
    }
    (vm, am, jm)
}

fn feature(kind: usize, at: Point3, axis: Vector3, size: f64, start: f64, sweep: f64) -> Feature {
    if kind < 3 {
        Feature {
            id: String::new(),
            geometry: Geometry::Circle {
                center: at,
                axis,
                radius: size,
                side: [Side::Inside, Side::Outside, Side::Plane][kind],
                start,
                sweep,
            },
        }
    } else {
        let (u, v) = Feature::basis(&axis);
        let d = u * start.cos() + v * start.sin();
        Feature {
            id: String::new(),
            geometry: Geometry::Line { start: at, end: at + d * 5.0 * size, normal: axis },
        }
    }
}

fn layout() -> impl Strategy<Value = Vec<Feature>> {
    let one = (
        0usize..4,
        prop::array::uniform3(-60.0..60.0f64),
        (-1.0..1.0f64, -1.0..1.0f64, 0.2..1.0f64),
        6.0..30.0f64,
        -3.0..3.0f64,
        prop_oneof![0.5..6.3f64, -6.3..-0.5f64],
    )
        .prop_map(|(k, c, (x, y, z), size, start, sweep)| {
            feature(k, Point3::new(c[0], c[1], c[2]), Vector3::new(x, y, z).normalize(), size, start, sweep)
        });
    prop::collection::vec(one, 1..6).prop_map(|fs| {
        fs.into_iter()
            .enumerate()
            .map(|(i, mut f)| {
                f.id = format!("f{i}");
                f
            })
            .collect()
    })
}

/// Tolerances: finite differences at 0.5 ms on piecewise-cubic motion reproduce speed and
/// acceleration to well under 1 % and average the jerk over the stencil (never above its
/// largest value); the planner keeps a 10 % margin, so 1 % (v, a) and 2 % (j) over the limits
/// would already be a violation.
fn check(pl: &Plan, p: &Params) -> Result<(), TestCaseError> {
    let (v, a, j) = transfer_maxima(pl, 5e-4);
    prop_assert!(v <= p.move_speed * 1.01, "speed {v} > {}", p.move_speed);
    prop_assert!(a <= p.accel * 1.01, "acceleration {a} > {}", p.accel);
    prop_assert!(j <= p.jerk * 1.02, "jerk {j} > {}", p.jerk);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn transfers_respect_speed_acceleration_and_jerk(fs in layout(), deg in 20.0..60.0f64, fast in any::<bool>()) {
        let mut p = Params { approach_angle: deg.to_radians(), ..Params::default() };
        if fast {
            p.move_speed = 400.0;
            p.scan_speed = 40.0;
        }
        prop_assume!(validate(&fs, &p).is_ok());
        for style in [Style::Blended, Style::Classic] {
            let pl = plan(&fs, &p, style);
            check(&pl, &p)?;
        }
    }
}

/// The case of the report: two bores side by side scanned in opposite directions (a U-turn of
/// the transfer), where the old planner reached 6.3 m/s² against a 1.5 m/s² limit.
#[test]
fn sharp_u_turn_between_neighbouring_bores() {
    let z = Vector3::z();
    let fs = vec![
        Feature { id: "a".into(), ..feature(0, Point3::new(0.0, 0.0, 0.0), z, 8.0, 0.0, 6.0) },
        Feature { id: "b".into(), ..feature(0, Point3::new(20.0, 0.0, 0.0), z, 8.0, 3.1, -6.0) },
        Feature { id: "c".into(), ..feature(3, Point3::new(10.0, 25.0, 0.0), -z, 6.0, 1.0, 0.0) },
    ];
    let p = Params::default();
    validate(&fs, &p).unwrap();
    let pl = plan(&fs, &p, Style::Blended);
    let (v, a, j) = transfer_maxima(&pl, 5e-4);
    eprintln!("U-turn transfers: max v {v:.1} mm/s, a {a:.1} mm/s², j {j:.0} mm/s³");
    assert!(v <= p.move_speed * 1.01 && a <= p.accel * 1.01 && j <= p.jerk * 1.02, "{v} {a} {j}");
    assert_eq!(pl.stops(), 0);
}
