//! Planner properties against geometry computed independently of the planner.

use truepos_math::{Point3, Vector3};
use truepos_scan::plan::Geom;
use truepos_scan::{plan, validate, Feature, Geometry, Params, ScanError, SegmentKind, Side, Style};

fn program(n: usize) -> (Vec<Feature>, Params) {
    let s = truepos_plant::scan_scenario::scenario(11, n);
    let (nom, _, p) = truepos_plant::scan_scenario::program(&s);
    (nom, p)
}

#[test]
fn approach_lines_make_the_requested_angle_with_the_normal() {
    let (features, mut p) = program(12);
    for deg in [20.0, 33.0, 45.0, 60.0] {
        p.approach_angle = f64::to_radians(deg);
        validate(&features, &p).unwrap();
        let pl = plan(&features, &p, Style::Blended);
        let ap = pl.approaches();
        assert_eq!(ap.len(), features.len());
        for (k, (dir, n)) in ap.iter().enumerate() {
            // the angle between the reversed approach direction and the outward normal
            let ang = (-dir.dot(n)).clamp(-1.0, 1.0).acos().to_degrees();
            // requirement: within 1°; the construction is exact, so 1e-6° would do
            assert!((ang - deg).abs() < 1.0, "feature {k}: {ang}° vs {deg}°");
            // and it moves in the scan direction: positive tangential component along the
            // feature's tangent at the contact point (independently: the settle start)
            let st = &pl.segments.iter().filter(|s| s.kind == SegmentKind::Settle).nth(k).unwrap();
            if let Geom::Along { u0, .. } = st.geom {
                let t = features[k].tangent(u0);
                assert!(dir.dot(&t) > 0.3, "approach not in the scan direction");
            }
        }
    }
}

#[test]
fn blended_never_stops_between_first_approach_and_last_release() {
    let (features, p) = program(16);
    let pl = plan(&features, &p, Style::Blended);
    assert_eq!(pl.stops(), 0);
    let (a, b) = pl.window();
    let samples = pl.sample(1e-3);
    let mut min_v = f64::INFINITY;
    for s in samples.iter().filter(|s| s.t >= a && s.t <= b) {
        min_v = min_v.min(s.speed);
    }
    // never near a standstill: transfers slow down in tight bends (lateral acceleration
    // limit) but never below half the scanning speed
    assert!(min_v >= 0.5 * p.scan_speed * (1.0 - 1e-9), "min speed {min_v}");
    // positions continuous: no jump larger than what the top speed allows in one step
    for w in samples.windows(2) {
        let d = (w[1].position - w[0].position).norm();
        assert!(d <= p.move_speed * (w[1].t - w[0].t) * 1.05 + 1e-9, "jump {d} at t={}", w[0].t);
    }
}

fn dir_at(samples: &[truepos_scan::plan::PathSample], k: usize, back: bool) -> Vector3 {
    let (a, b) = if back {
        (samples[k - 2].position, samples[k - 1].position)
    } else {
        (samples[k].position, samples[k + 1].position)
    };
    (b - a).normalize()
}

#[test]
fn blended_path_has_no_sharp_corners() {
    let (features, p) = program(8);
    let pl = plan(&features, &p, Style::Blended);
    let samples = pl.sample(2e-4);
    // at every segment boundary the direction of motion turns by less than 3° over 0.4 ms
    // (the largest turn rate on the path is the 8 mm bore at 20 mm/s: 2.5 rad/s → 0.06°/0.4 ms,
    // and the tightest transfer Bézier turns well below 3° there)
    for k in 2..samples.len() - 2 {
        if samples[k].segment != samples[k - 1].segment {
            let d0 = dir_at(&samples, k, true);
            let d1 = dir_at(&samples, k, false);
            let ang = d0.dot(&d1).clamp(-1.0, 1.0).acos().to_degrees();
            let kinds = (pl.segments[samples[k - 1].segment].kind, pl.segments[samples[k].segment].kind);
            assert!(ang < 3.0, "corner of {ang}° between {kinds:?} at t={}", samples[k].t);
        }
    }
}

#[test]
fn classic_stops_at_every_prehit_point() {
    let (features, p) = program(8);
    let pl = plan(&features, &p, Style::Classic);
    // pre-hit points: on the normal at the scan start, `clearance` away from the touching tip
    for (k, f) in features.iter().enumerate() {
        let pre: Point3 = f.point(0.0, p.tip_radius + p.clearance);
        let hold = pl
            .segments
            .iter()
            .find(|s| {
                s.feature == k && matches!(s.geom, Geom::Hold { .. }) && s.kind == SegmentKind::Approach
            })
            .unwrap();
        match hold.geom {
            Geom::Hold { p: h } => assert!((h - pre).norm() < 1e-9),
            _ => unreachable!(),
        }
        assert!(hold.duration() >= p.prehit_dwell);
    }
    let samples = pl.sample(1e-3);
    for (k, f) in features.iter().enumerate() {
        let pre = f.point(0.0, p.tip_radius + p.clearance);
        let near: Vec<_> = samples.iter().filter(|s| (s.position - pre).norm() < 1e-9).collect();
        assert!(!near.is_empty(), "feature {k}: pre-hit never reached");
        assert!(near.iter().all(|s| s.speed.abs() < 1e-9), "feature {k}: moving through the pre-hit point");
    }
    // pre-hit arrival, the stop at the deflection, end of scan, end of retract
    assert_eq!(pl.stops(), 4 * features.len());
}

fn circle(id: &str, radius: f64, axis: Vector3, side: Side) -> Feature {
    Feature {
        id: id.into(),
        geometry: Geometry::Circle { center: Point3::origin(), axis, radius, side, start: 0.0, sweep: 6.0 },
    }
}

#[test]
fn bad_input_is_rejected_with_a_named_reason() {
    let p = Params::default();
    let good = circle("b1", 10.0, Vector3::z(), Side::Inside);
    validate(std::slice::from_ref(&good), &p).unwrap();
    for deg in [19.9, 60.1, -45.0, f64::NAN] {
        let q = Params { approach_angle: f64::to_radians(deg), ..p.clone() };
        assert!(
            matches!(validate(std::slice::from_ref(&good), &q), Err(ScanError::ApproachAngle(_))),
            "{deg}"
        );
    }
    let zero_r = circle("c0", 0.0, Vector3::z(), Side::Outside);
    let e = validate(&[zero_r], &p).unwrap_err().to_string();
    assert!(e.contains("c0") && e.contains("radius"), "{e}");
    let bad_axis = circle("ax", 10.0, Vector3::new(0.0, 0.0, 1.1), Side::Outside);
    let e = validate(&[bad_axis], &p).unwrap_err().to_string();
    assert!(e.contains("ax") && e.contains("unit vector"), "{e}");
    let zero_line = Feature {
        id: "l0".into(),
        geometry: Geometry::Line {
            start: Point3::new(1.0, 2.0, 3.0),
            end: Point3::new(1.0, 2.0, 3.0),
            normal: Vector3::z(),
        },
    };
    let e = validate(&[zero_line], &p).unwrap_err().to_string();
    assert!(e.contains("l0") && e.contains("length"), "{e}");
}

#[test]
fn scan_segment_follows_the_nominal_surface_at_the_target_deflection() {
    let (features, p) = program(8);
    let pl = plan(&features, &p, Style::Blended);
    for s in pl.segments.iter().filter(|s| s.kind == SegmentKind::Scan) {
        let f = &features[s.feature];
        for k in 0..=20 {
            let c = s.eval(s.duration() * k as f64 / 20.0, f, p.tip_radius);
            // independent check: signed distance of the commanded tip centre from the surface
            let (d, _) = f.signed_distance(&c.position);
            assert!((d - (p.tip_radius - p.deflection)).abs() < 1e-9);
            assert!((c.speed - p.scan_speed).abs() < 1e-9);
        }
    }
}

mod props {
    use super::*;
    use proptest::prelude::*;

    fn feature_strategy() -> impl Strategy<Value = Feature> {
        let axis =
            (-1.0..1.0f64, -1.0..1.0f64, 0.2..1.0f64).prop_map(|(x, y, z)| Vector3::new(x, y, z).normalize());
        let circle =
            (axis.clone(), 8.0..40.0f64, 0usize..3, -3.0..3.0f64, prop_oneof![0.5..6.3f64, -6.3..-0.5f64])
                .prop_map(|(axis, radius, side, start, sweep)| Feature {
                    id: "c".into(),
                    geometry: Geometry::Circle {
                        center: Point3::new(10.0, -20.0, 5.0),
                        axis,
                        radius,
                        side: [Side::Inside, Side::Outside, Side::Plane][side],
                        start,
                        sweep,
                    },
                });
        let line = (axis, 5.0..80.0f64, -3.0..3.0f64).prop_map(|(n, len, a)| {
            let (u, v) = Feature::basis(&n);
            let d = u * a.cos() + v * a.sin();
            Feature {
                id: "l".into(),
                geometry: Geometry::Line {
                    start: Point3::new(1.0, 2.0, 3.0),
                    end: Point3::new(1.0, 2.0, 3.0) + d * len,
                    normal: n,
                },
            }
        });
        prop_oneof![circle, line]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn any_valid_program_plans_without_stops_at_the_requested_angle(
            fs in proptest::collection::vec(feature_strategy(), 1..5),
            deg in 20.0..60.0f64,
        ) {
            let features: Vec<Feature> = fs.into_iter().enumerate().map(|(i, mut f)| { f.id = format!("f{i}"); f }).collect();
            let p = Params { approach_angle: deg.to_radians(), ..Params::default() };
            prop_assume!(validate(&features, &p).is_ok());
            let pl = plan(&features, &p, Style::Blended);
            prop_assert_eq!(pl.stops(), 0);
            for (dir, n) in pl.approaches() {
                let ang = (-dir.dot(&n)).clamp(-1.0, 1.0).acos().to_degrees();
                prop_assert!((ang - deg).abs() < 1e-6);
            }
            let (a, b) = pl.window();
            for s in pl.sample(5e-3).iter().filter(|s| s.t >= a && s.t <= b) {
                // never a stop; below half the scanning speed only in a transfer no shape can
                // take faster within the acceleration and jerk limits (e.g. a reversal between
                // two crossing face circles), down to 1 % (see `transfer` in plan.rs)
                prop_assert!(s.speed >= 0.01 * p.scan_speed * (1.0 - 1e-9));
                prop_assert!(s.position.coords.iter().all(|c| c.is_finite()));
            }
            let pc = plan(&features, &p, Style::Classic);
            prop_assert_eq!(pc.stops(), 4 * features.len());
        }
    }
}

#[test]
fn a_circle_too_tight_for_the_scan_speed_is_refused() {
    let p = Params { scan_speed: 48.0, accel: 300.0, jerk: 2000.0, ..Params::default() };
    // 5 mm bore: scan path radius 5 − 1.5 + 0.3 = 3.8 mm, 48²/3.8 = 606 mm/s² > 0.6 · 300
    let e = validate(&[circle("b0", 5.0, Vector3::z(), Side::Inside)], &p).unwrap_err().to_string();
    assert!(e.contains("b0") && e.contains("scan_speed_mm_s") && e.contains("centripetal"), "{e}");
    // the same bore at 10 mm/s: 26 mm/s² and 69 mm/s³, within both shares
    let slow = Params { scan_speed: 10.0, ..p.clone() };
    validate(&[circle("b0", 5.0, Vector3::z(), Side::Inside)], &slow).unwrap();
    // a 4 mm bore: the approach would start (3 mm clearance from the 1.5 mm tip) past its axis
    let e = validate(&[circle("b0", 4.0, Vector3::z(), Side::Inside)], &slow).unwrap_err().to_string();
    assert!(e.contains("b0") && e.contains("clearance_mm"), "{e}");
}
