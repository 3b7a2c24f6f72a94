//! Positioning moves keep the machine's velocity, acceleration and jerk limits — the transfers
//! between features (and their joins to the release before and the approach after) in the
//! blended style, every move of the classic style — for random feature layouts, bends and
//! limits. Checked on the planned path itself by finite differences of positions sampled on one
//! uniform clock, independent of how the planner built and timed it.

use proptest::prelude::*;
use truepos_math::{Point3, Vector3};
use truepos_scan::plan::Plan;
use truepos_scan::{plan, validate, Feature, Geometry, Params, SegmentKind, Side, Style};

/// Largest speed, |acceleration| and |jerk| (mm/s, mm/s², mm/s³) by finite differences at time
/// step `dt` over every difference stencil that touches a checked segment: transfers in the
/// blended style (so the joins to the release and the approach are in), everything in the
/// classic style (its moves join at rest).
fn maxima(pl: &Plan, dt: f64) -> (f64, f64, f64) {
    let (v, a, j, _) = maxima_at(pl, dt);
    (v, a, j)
}

/// [`maxima`] with the time and segment index where the jerk is largest.
fn maxima_at(pl: &Plan, dt: f64) -> (f64, f64, f64, (f64, usize)) {
    let m = by_kind(pl, dt);
    let checked: Vec<&Max> = m
        .iter()
        .filter(|(k, _)| pl.style == Style::Classic || *k == SegmentKind::Transfer)
        .map(|(_, m)| m)
        .collect();
    let v = checked.iter().map(|m| m.v).fold(0.0, f64::max);
    let a = checked.iter().map(|m| m.a.0).fold(0.0, f64::max);
    let j = checked.iter().map(|m| m.j.0).fold(0.0, f64::max);
    let at = checked.iter().find(|m| m.j.0 == j).map_or((0.0, 0), |m| (m.j.1, m.j.2));
    (v, a, j, at)
}

/// Largest speed, and |acceleration| and |jerk| with the time and segment where they occur.
#[derive(Clone, Copy, Debug, Default)]
struct Max {
    v: f64,
    a: (f64, f64, usize),
    j: (f64, f64, usize),
}

/// [`Max`] of every segment kind over the stencils that touch a segment of that kind (a join
/// counts for both kinds it joins).
fn by_kind(pl: &Plan, dt: f64) -> Vec<(SegmentKind, Max)> {
    let tip = pl.params.tip_radius;
    let total = pl.duration();
    let n = (total / dt).floor() as usize;
    let mut pos = Vec::with_capacity(n + 1);
    let mut seg = 0;
    let mut segs = Vec::with_capacity(n + 1);
    for k in 0..=n {
        let t = k as f64 * dt;
        while seg + 1 < pl.segments.len() && pl.starts[seg + 1] <= t {
            seg += 1;
        }
        let s = &pl.segments[seg];
        pos.push(s.eval(t - pl.starts[seg], &pl.features[s.feature], tip).position);
        segs.push(seg);
    }
    let kinds = [
        SegmentKind::Transfer,
        SegmentKind::Approach,
        SegmentKind::Settle,
        SegmentKind::Scan,
        SegmentKind::Release,
    ];
    let mut out: Vec<(SegmentKind, Max)> = kinds.iter().map(|&k| (k, Max::default())).collect();
    for k in 0..pos.len().saturating_sub(3) {
        let (p0, p1, p2, p3) = (pos[k].coords, pos[k + 1].coords, pos[k + 2].coords, pos[k + 3].coords);
        let v = (p1 - p0).norm() / dt;
        let a = (p2 - p1 * 2.0 + p0).norm() / (dt * dt);
        let j = (p3 - p2 * 3.0 + p1 * 3.0 - p0).norm() / (dt * dt * dt);
        let t = (k + 1) as f64 * dt;
        for (kind, m) in out.iter_mut() {
            if !(k..k + 4).any(|i| pl.segments[segs[i]].kind == *kind) {
                continue;
            }
            m.v = m.v.max(v);
            if a > m.a.0 {
                m.a = (a, t, segs[k + 1]);
            }
            if j > m.j.0 {
                m.j = (j, t, segs[k + 1]);
            }
        }
    }
    out
}

/// A finite difference of order k divided by dtᵏ is a weighted mean of the k-th derivative over
/// the stencil (a B-spline kernel), so on an exact trajectory it never exceeds that derivative's
/// largest value: the 1 % only absorbs rounding and the curvature at the release→transfer join,
/// which the planner matches from differences of the release (relative error ~1e-4).
fn check(pl: &Plan, p: &Params, dt: f64) -> Result<(), TestCaseError> {
    let (v, a, j) = maxima(pl, dt);
    let style = pl.style;
    if a > p.accel * 1.01 || j > p.jerk * 1.01 {
        for (k, m) in by_kind(pl, dt) {
            eprintln!("{style:?} {k:?}: {m:?}");
        }
    }
    prop_assert!(v <= p.move_speed * 1.01, "{style:?}: speed {v} > {}", p.move_speed);
    prop_assert!(a <= p.accel * 1.01, "{style:?}: acceleration {a} > {}", p.accel);
    prop_assert!(j <= p.jerk * 1.01, "{style:?}: jerk {j} > {}", p.jerk);
    Ok(())
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
            geometry: Geometry::Line { start: at, end: at + d * 3.0 * size, normal: axis },
        }
    }
}

/// 1 to 5 features (bores, bosses, face circles, lines) with random axes, sizes, start angles
/// and sweeps of either sign, within a 100 mm cube: close neighbours facing any way make the
/// sharp bends.
fn layout() -> impl Strategy<Value = Vec<Feature>> {
    let one = (
        0usize..4,
        prop::array::uniform3(-50.0..50.0f64),
        (-1.0..1.0f64, -1.0..1.0f64, 0.2..1.0f64),
        4.0..25.0f64,
        -3.2..3.2f64,
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

/// Random limits: acceleration 0.3–5 m/s², jerk 2–200 m/s³, positioning speed 50–500 mm/s,
/// scanning speed 5–50 mm/s, approach angle 20°–60°.
fn limits() -> impl Strategy<Value = Params> {
    (300.0..5000.0f64, 2_000.0..200_000.0f64, 50.0..500.0f64, 5.0..50.0f64, 20.0..60.0f64).prop_map(
        |(accel, jerk, move_speed, scan_speed, deg)| Params {
            accel,
            jerk,
            move_speed,
            scan_speed,
            approach_angle: deg.to_radians(),
            ..Params::default()
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn moves_respect_speed_acceleration_and_jerk(fs in layout(), p in limits()) {
        prop_assume!(validate(&fs, &p).is_ok());
        for style in [Style::Blended, Style::Classic] {
            let pl = plan(&fs, &p, style);
            // 0.5 ms: finer than any S-curve phase at these limits (a/j ≥ 1.5 ms)
            check(&pl, &p, 5e-4)?;
        }
    }
}

/// The case of the report: the 8-feature test program (`scenario(11, 8)`, 40 mm/s scanning),
/// whose transfers reached 6.3 m/s² against the 1.5 m/s² limit in two sharp bends.
#[test]
fn sharp_bends_of_the_eight_feature_program() {
    let s = truepos_plant::scan_scenario::scenario(11, 8);
    let (fs, _, p) = truepos_plant::scan_scenario::program(&s);
    validate(&fs, &p).unwrap();
    for style in [Style::Blended, Style::Classic] {
        let pl = plan(&fs, &p, style);
        let (v, a, j, (t, k)) = maxima_at(&pl, 2e-4);
        let seg = &pl.segments[k];
        eprintln!(
            "{style:?}: max v {v:.1} mm/s, |a| {a:.1} mm/s², |j| {j:.0} mm/s³ (at {t:.4} s, segment {k} {:?}, {:.4} s after its start, {:.4} s long)",
            seg.kind,
            t - pl.starts[k],
            seg.duration()
        );
        // see `check` for the 1 %
        assert!(v <= p.move_speed * 1.01, "{style:?} v {v}");
        assert!(a <= p.accel * 1.01, "{style:?} a {a}");
        assert!(j <= p.jerk * 1.01, "{style:?} j {j}");
    }
    assert_eq!(plan(&fs, &p, Style::Blended).stops(), 0);
}

/// Two bores side by side scanned in opposite directions: the transfer is a U-turn.
#[test]
fn u_turn_between_neighbouring_bores() {
    let z = Vector3::z();
    let fs = vec![
        Feature { id: "a".into(), ..feature(0, Point3::new(0.0, 0.0, 0.0), z, 8.0, 0.0, 6.0) },
        Feature { id: "b".into(), ..feature(0, Point3::new(20.0, 0.0, 0.0), z, 8.0, 3.1, -6.0) },
        Feature { id: "c".into(), ..feature(3, Point3::new(10.0, 25.0, 0.0), -z, 6.0, 1.0, 0.0) },
    ];
    let p = Params::default();
    validate(&fs, &p).unwrap();
    for style in [Style::Blended, Style::Classic] {
        let pl = plan(&fs, &p, style);
        let (v, a, j) = maxima(&pl, 2e-4);
        eprintln!("{style:?} U-turn: max v {v:.1} mm/s, |a| {a:.1} mm/s², |j| {j:.0} mm/s³");
        assert!(v <= p.move_speed * 1.01 && a <= p.accel * 1.01 && j <= p.jerk * 1.01, "{v} {a} {j}");
    }
}

/// The check can fail: the same programs planned at twice the acceleration and jerk limits (and
/// twice the positioning speed) break the original limits in the check, for both styles.
#[test]
fn the_check_catches_a_plan_above_the_limits() {
    let s = truepos_plant::scan_scenario::scenario(11, 4);
    let (fs, _, p) = truepos_plant::scan_scenario::program(&s);
    let loose =
        Params { accel: 2.0 * p.accel, jerk: 2.0 * p.jerk, move_speed: 2.0 * p.move_speed, ..p.clone() };
    for style in [Style::Blended, Style::Classic] {
        assert!(check(&plan(&fs, &p, style), &p, 5e-4).is_ok(), "{style:?} at its own limits");
        let r = check(&plan(&fs, &loose, style), &p, 5e-4);
        assert!(r.is_err(), "{style:?}: a plan at twice the limits passed the check");
    }
}

/// Every segment kind of the blended style on the 8-feature program: approach, settle, scan and
/// release run at scanning speed on the surface, and the settle path bends the motion from the
/// approach line into the surface within the penetration `deflection + overshoot`.
#[test]
#[ignore = "known gap: the settle and release bends exceed the limits at 40 mm/s (docs/performance-scan.md)"]
fn every_blended_segment_keeps_the_limits() {
    let s = truepos_plant::scan_scenario::scenario(11, 8);
    let (fs, _, p) = truepos_plant::scan_scenario::program(&s);
    let pl = plan(&fs, &p, Style::Blended);
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for (k, m) in by_kind(&pl, 2e-4) {
        eprintln!(
            "{k:?}: max v {:.1} mm/s, |a| {:.0} mm/s² (at {:.4} s), |j| {:.0} mm/s³ (at {:.4} s)",
            m.v, m.a.0, m.a.1, m.j.0, m.j.1
        );
        worst = (worst.0.max(m.v), worst.1.max(m.a.0), worst.2.max(m.j.0));
    }
    // see `check` for the 1 %
    assert!(
        worst.0 <= p.move_speed * 1.01 && worst.1 <= p.accel * 1.01 && worst.2 <= p.jerk * 1.01,
        "{worst:?}"
    );
}

/// The stored proptest case that broke the acceleration limit (5.0 vs 4.1 m/s²): a bore, then a
/// line, scanned at 46.5 mm/s with a low jerk limit (14 m/s³) at a 20° approach.
#[test]
fn bore_then_line_at_high_scan_speed_and_low_jerk() {
    let z = Vector3::z();
    let fs = vec![
        Feature {
            id: "f0".into(),
            geometry: Geometry::Circle {
                center: Point3::new(42.32731732521271, -28.84798800303543, 17.747238745265605),
                axis: z,
                radius: 9.326779010507353,
                side: Side::Inside,
                start: 0.0,
                sweep: 5.802800755181947,
            },
        },
        Feature {
            id: "f1".into(),
            geometry: Geometry::Line {
                start: Point3::new(32.72334316653007, -28.787454419442536, 23.48161078345263),
                end: Point3::new(21.88231535477807, -25.25607776594899, 27.22346793144483),
                normal: Vector3::new(0.32626900522420815, 0.0, 0.9452769627098745),
            },
        },
    ];
    let p = Params {
        approach_angle: 0.3490658503988659,
        scan_speed: 46.53284097979764,
        move_speed: 50.0,
        accel: 4142.081579453729,
        jerk: 14356.5290755361,
        ..Params::default()
    };
    report_and_check(&fs, &p);
}

/// A small bore scanned over half a radian at 38 mm/s (3.4 m/s², 43 m/s³): the stop after its
/// release (a stored proptest case).
#[test]
fn stop_after_a_small_bore() {
    let fs = vec![Feature {
        id: "f0".into(),
        geometry: Geometry::Circle {
            center: Point3::origin(),
            axis: Vector3::z(),
            radius: 5.355506820638347,
            side: Side::Inside,
            start: 0.0,
            sweep: 0.5,
        },
    }];
    let p = Params {
        approach_angle: 0.8701117926700492,
        scan_speed: 38.20477225885898,
        move_speed: 50.0,
        accel: 3410.8607086807283,
        jerk: 42939.9217216702,
        ..Params::default()
    };
    report_and_check(&fs, &p);
}

/// Print the segments and the measured maxima of both styles, then [`check`] them.
fn report_and_check(fs: &[Feature], p: &Params) {
    validate(fs, p).unwrap();
    for style in [Style::Blended, Style::Classic] {
        let pl = plan(fs, p, style);
        for (k, s) in pl.segments.iter().enumerate() {
            eprintln!(
                "{k} {:?} start {:.4} dur {:.4} v0 {:.1} v1 {:.1}",
                s.kind,
                pl.starts[k],
                s.duration(),
                s.start_speed(),
                s.end_speed()
            );
        }
        let (v, a, j, (t, k)) = maxima_at(&pl, 2e-4);
        eprintln!(
            "{style:?}: max v {v:.1} mm/s, |a| {a:.1} mm/s², |j| {j:.0} mm/s³ (at {t:.4} s, segment {k})"
        );
        for (kind, m) in by_kind(&pl, 2e-4) {
            eprintln!("  {kind:?}: {m:?}");
        }
        // see `check` for the 1 %
        check(&pl, p, 5e-4).unwrap();
    }
}
