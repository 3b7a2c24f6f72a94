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
    assert!(matches!(cylinder(&p), Err(FitError::TooFewPoints { needed: 5, .. })));
    assert!(matches!(cone(&ring(5, 1.0, 0.0)), Err(FitError::TooFewPoints { needed: 6, .. })));
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
