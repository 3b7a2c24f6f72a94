//! Degenerate data is detected and named: every `FitError` variant from data that provokes it.

use truepos_fit::*;
use truepos_math::Point3;

fn ring(n: usize, r: f64, z: f64) -> Vec<Point3> {
    (0..n)
        .map(|i| {
            let a = i as f64 * std::f64::consts::TAU / n as f64;
            Point3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

#[test]
fn non_finite_points_are_named_by_index() {
    let mut p = ring(10, 5.0, 0.0);
    p.push(Point3::new(0.0, 0.0, 9.0));
    p[4].y = f64::NAN;
    assert_eq!(sphere(&p).unwrap_err(), FitError::NonFinite { index: 4 });
    p[4].y = 1.0;
    p[7].z = f64::INFINITY;
    assert_eq!(plane(&p).unwrap_err(), FitError::NonFinite { index: 7 });
    assert_eq!(cone(&p).unwrap_err(), FitError::NonFinite { index: 7 });
}

#[test]
fn too_few_and_coincident_points() {
    let p = ring(3, 1.0, 0.0);
    assert!(matches!(sphere(&p), Err(FitError::TooFewPoints { needed: 4, got: 3, .. })));
    assert!(matches!(cylinder(&p), Err(FitError::TooFewPoints { needed: 6, .. })));
    assert!(matches!(cone(&ring(6, 1.0, 0.0)), Err(FitError::TooFewPoints { needed: 7, .. })));
    assert!(matches!(line(&[]), Err(FitError::TooFewPoints { got: 0, .. })));
    assert_eq!(line(&[Point3::new(1.0, 2.0, 3.0); 5]).unwrap_err(), FitError::CoincidentPoints);
    assert!(matches!(sphere_with_radius(&ring(8, 1.0, 0.0), -1.0), Err(FitError::InvalidRadius(_))));
}

#[test]
fn collinear_and_coplanar_points() {
    let l: Vec<Point3> = (0..8).map(|i| Point3::new(1.0 + i as f64, 2.0 * i as f64, 3.0)).collect();
    assert_eq!(plane(&l).unwrap_err(), FitError::CollinearPoints { kind: "plane" });
    assert_eq!(circle(&l).unwrap_err(), FitError::CollinearPoints { kind: "circle" });
    assert!(line(&l).is_ok());
    let c = ring(12, 4.0, 2.0);
    assert_eq!(sphere(&c).unwrap_err(), FitError::CoplanarPoints { kind: "sphere" });
    assert_eq!(sphere_with_radius(&c, 5.0).unwrap_err(), FitError::CoplanarPoints { kind: "sphere" });
    assert_eq!(cylinder(&c).unwrap_err(), FitError::CoplanarPoints { kind: "cylinder" });
    assert!(circle(&c).is_ok());
}

#[test]
fn cone_on_a_cylinder_and_cylinder_on_flat_data() {
    // Exact cylinder, three rings: the cone's apex is at infinity.
    let mut cyl = ring(16, 5.0, 0.0);
    cyl.extend(ring(16, 5.0, 10.0));
    cyl.extend(ring(16, 5.0, 20.0));
    assert_eq!(cone(&cyl).unwrap_err(), FitError::ConeIsCylinder);
    let f = cylinder(&cyl).unwrap();
    assert!((f.radius - 5.0).abs() < 1e-12);
    // A noisy plane (deterministic ±1 µm pattern): no significant curvature.
    let flat: Vec<Point3> = (0..400)
        .map(|i| {
            let (x, y) = ((i % 20) as f64 * 5.0, (i / 20) as f64 * 5.0);
            Point3::new(x, y, 1e-3 * ((i * 7919 % 13) as f64 - 6.0) / 6.0)
        })
        .collect();
    assert_eq!(cylinder(&flat).unwrap_err(), FitError::CylinderIsFlat);
}

/// Points on an exact cylinder (radius 5 mm, axis through `c` along a seeded random direction),
/// at seeded random angles and heights over 20 mm.
fn exact_cylinder(seed: u64, n: usize) -> Vec<Point3> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let w = truepos_math::Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize();
    let u = truepos_math::any_perpendicular(&w);
    let v = w.cross(&u);
    let c = Point3::new(
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
    );
    (0..n)
        .map(|_| {
            let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let h: f64 = rng.random_range(-10.0..10.0);
            c + u * (5.0 * a.cos()) + v * (5.0 * a.sin()) + w * h
        })
        .collect()
}

/// A least-squares cylinder through exact data has zero residual: every seeded 6- and 7-point
/// exact cylinder is found (radius 5 mm within 1 µm), never a local minimum (one such set gave
/// r 5.57 mm before the global start).
#[test]
fn small_exact_cylinders_are_found_not_a_local_minimum() {
    let mut wrong = Vec::new();
    for n in [6, 7, 9] {
        for seed in 0..150 {
            let p = exact_cylinder(seed, n);
            match cylinder(&p) {
                Ok(f) if (f.radius - 5.0).abs() < 1e-3 => {}
                Ok(f) => wrong.push(format!("n {n} seed {seed}: r {}", f.radius)),
                Err(FitError::Undetermined { .. }) => {} // named, not silent
                Err(e) => wrong.push(format!("n {n} seed {seed}: {e}")),
            }
        }
    }
    assert!(wrong.is_empty(), "{} wrong: {:?}", wrong.len(), &wrong[..wrong.len().min(20)]);
}

/// The 8 corners of a cube lie exactly on three cylinders (axes along x, y and z, radius √2):
/// the least squares has three equally good answers, so the cylinder is not determined (named,
/// with both answers), never one of them chosen silently.
#[test]
fn equally_good_cylinders_are_not_determined() {
    let mut p = Vec::new();
    for i in 0..8 {
        let s = |b: usize| if i & b == 0 { -1.0 } else { 1.0 };
        p.push(Point3::new(s(1), s(2), s(4)));
    }
    let e = cylinder(&p).unwrap_err();
    assert!(matches!(e, FitError::NotUnique { kind: "cylinder", .. }), "{e}");
    let t = e.to_string();
    assert!(t.contains("not determined") && t.contains("90.000°"), "{t}");
    // Too few: the count and the reason.
    let t = cylinder(&p[..5]).unwrap_err().to_string();
    assert!(t.contains("at least 6 points, 5 given") && t.contains("six cylinders"), "{t}");
    let t = cone(&exact_cylinder(1, 6)).unwrap_err().to_string();
    assert!(t.contains("at least 7 points, 6 given") && t.contains("seventh"), "{t}");
}

/// A guarded size decision needs the diameter's uncertainty: from as many points as the fit
/// has parameters (3 for a circle, 4 for a sphere) it is not determined, and the decision is
/// undecided, not a pass with a zero guard band (hostile audit 2 of issue 31, F7). The simple
/// rule still decides on the value.
#[test]
fn guarded_decisions_without_a_known_uncertainty_are_undecided() {
    use truepos_fit::evaluate::{evaluate, Kind, Method, Spec};
    use truepos_fit::verdict::{DecisionRule, SizeTolerance, Verdict};
    let size = Some(SizeTolerance { nominal: 10.0, lower: -0.01, upper: 0.01 });
    let sphere4 = [
        Point3::new(5.0, 0.0, 0.0),
        Point3::new(-5.0, 0.0, 0.0),
        Point3::new(0.0, 5.0, 0.0),
        Point3::new(0.0, 0.0, 5.0),
    ];
    for (kind, pts) in [(Kind::Circle, ring(3, 5.0, 0.0)), (Kind::Sphere, sphere4.to_vec())] {
        let guarded = Spec { size, form_tolerance: None, rule: DecisionRule::Guarded };
        let e = evaluate(kind, Method::LeastSquares, &pts, &guarded).unwrap();
        assert_eq!(e.diameter_expanded_uncertainty, None, "{kind:?}");
        let d = e.size_decision.unwrap();
        assert_eq!(d.verdict, Verdict::Undecided, "{kind:?}");
        assert!(d.guard_band.is_nan());
        let simple = Spec { rule: DecisionRule::Simple, ..guarded };
        let e = evaluate(kind, Method::LeastSquares, &pts, &simple).unwrap();
        assert_eq!(e.size_decision.unwrap().verdict, Verdict::Pass, "{kind:?}");
    }
    // With one point more the uncertainty is known and the guarded rule decides.
    let e = evaluate(
        Kind::Circle,
        Method::LeastSquares,
        &ring(4, 5.0, 0.0),
        &Spec { size, form_tolerance: None, rule: DecisionRule::Guarded },
    )
    .unwrap();
    assert_eq!(e.size_decision.unwrap().verdict, Verdict::Pass);
}
