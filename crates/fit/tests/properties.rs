//! Properties of the fits: exact shapes recovered; invariance under rigid motion and under
//! permutation of the data; stated standard uncertainties consistent with the actual scatter
//! over repeated random draws.

use nalgebra::Rotation3;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use truepos_fit::*;
use truepos_math::{any_perpendicular, Point3, Vector3};

/// A unit vector from two uniform numbers.
fn dir(a: f64, b: f64) -> Vector3 {
    let z = 2.0 * a - 1.0;
    let r = (1.0 - z * z).sqrt();
    let phi = std::f64::consts::TAU * b;
    Vector3::new(r * phi.cos(), r * phi.sin(), z)
}

fn frame(w: &Vector3) -> (Vector3, Vector3) {
    let u = any_perpendicular(w);
    (u, w.cross(&u))
}

/// Orthogonal noise along `n` (the surface normal) keeps the truth the least-squares answer to
/// first order; `noise` is its standard deviation.
fn add_noise(p: Point3, n: Vector3, noise: f64, rng: &mut ChaCha8Rng) -> Point3 {
    if noise == 0.0 {
        return p;
    }
    p + n * Normal::new(0.0, noise).unwrap().sample(rng)
}

fn sphere_points(c: Point3, r: f64, n: usize, cap: f64, noise: f64, rng: &mut ChaCha8Rng) -> Vec<Point3> {
    // Directions within `cap` rad of +z (uniform on the cap), then a random orientation.
    let rot = Rotation3::from_scaled_axis(dir(rng.random(), rng.random()) * rng.random::<f64>() * 3.0);
    (0..n)
        .map(|_| {
            let z = 1.0 - rng.random::<f64>() * (1.0 - cap.cos());
            let phi = rng.random::<f64>() * std::f64::consts::TAU;
            let s = (1.0 - z * z).sqrt();
            let d = rot * Vector3::new(s * phi.cos(), s * phi.sin(), z);
            add_noise(c + d * r, d, noise, rng)
        })
        .collect()
}

fn cylinder_points(
    p0: Point3,
    w: Vector3,
    r: f64,
    len: f64,
    n: usize,
    noise: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Point3> {
    let (u, v) = frame(&w);
    (0..n)
        .map(|_| {
            let a = rng.random::<f64>() * std::f64::consts::TAU;
            let d = u * a.cos() + v * a.sin();
            add_noise(p0 + w * (rng.random::<f64>() * len) + d * r, d, noise, rng)
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
/// Points on a cone with apex `apex`, axis `w`, half angle `psi`, between distances t0..t1
/// along the axis from the apex.
fn cone_points(
    apex: Point3,
    w: Vector3,
    psi: f64,
    t0: f64,
    t1: f64,
    n: usize,
    noise: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Point3> {
    let (u, v) = frame(&w);
    (0..n)
        .map(|_| {
            let a = rng.random::<f64>() * std::f64::consts::TAU;
            let t = t0 + rng.random::<f64>() * (t1 - t0);
            let radial = u * a.cos() + v * a.sin();
            let normal = radial * psi.cos() - w * psi.sin();
            add_noise(apex + w * t + radial * (t * psi.tan()), normal, noise, rng)
        })
        .collect()
}

fn circle_points(
    c: Point3,
    w: Vector3,
    r: f64,
    arc: f64,
    n: usize,
    noise: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Point3> {
    let (u, v) = frame(&w);
    (0..n)
        .map(|_| {
            let a = rng.random::<f64>() * arc;
            let d = u * a.cos() + v * a.sin();
            // Radial noise only (out-of-plane noise would be fitted by the plane).
            add_noise(c + d * r, d, noise, rng)
        })
        .collect()
}

fn axis_angle(a: &Vector3, b: &Vector3) -> f64 {
    a.cross(b).norm().atan2(a.dot(b).abs())
}
fn line_dist(p: &Point3, q: &Point3, d: &Vector3) -> f64 {
    let v = p - q;
    (v - d * v.dot(d)).norm()
}

// Tolerances for exact data: the fits converge to a relative step of 1e-14 and the data are
// ~100 mm in size, so 1e-9 mm / 1e-10 rad leave a 1e3 margin over rounding while any
// definition error (algebraic instead of geometric, wrong sign) is far larger.
const EXACT_POS: f64 = 1e-9;
const EXACT_ANG: f64 = 1e-10;

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn exact_spheres_recovered(seed in any::<u64>(), r in 1.0f64..200.0, cap in 0.6f64..3.1, cx in -500.0f64..500.0) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let c = Point3::new(cx, 0.3 * cx, -cx);
        let pts = sphere_points(c, r, 40, cap, 0.0, &mut rng);
        let f = sphere(&pts).unwrap();
        prop_assert!((f.center - c).norm() < EXACT_POS * r.max(1.0) * 10.0, "{} {}", (f.center - c).norm(), r);
        prop_assert!((f.radius - r).abs() < EXACT_POS * r.max(1.0) * 10.0);
        let g = sphere_with_radius(&pts, r).unwrap();
        prop_assert!((g.center - c).norm() < EXACT_POS * r.max(1.0) * 10.0);
        let (lo, hi) = pts.iter().map(|p| (p - f.center).norm()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        prop_assert_eq!(f.form.to_bits(), (hi - lo).to_bits());
    }

    #[test]
    fn exact_cylinders_recovered(seed in any::<u64>(), r in 2.0f64..100.0, len in 5.0f64..200.0, a in 0.0f64..1.0, b in 0.0f64..1.0) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let w = dir(a, b);
        let p0 = Point3::new(100.0, -50.0, 20.0);
        let pts = cylinder_points(p0, w, r, len, 60, 0.0, &mut rng);
        let f = cylinder(&pts).unwrap();
        prop_assert!(axis_angle(&f.axis, &w) < EXACT_ANG * 10.0, "{}", axis_angle(&f.axis, &w));
        prop_assert!(line_dist(&p0, &f.point, &f.axis) < EXACT_POS * 100.0);
        prop_assert!((f.radius - r).abs() < EXACT_POS * 100.0);
    }

    #[test]
    fn exact_cones_recovered(seed in any::<u64>(), psi in 0.1f64..1.2, a in 0.0f64..1.0, b in 0.0f64..1.0) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let w = dir(a, b);
        let apex = Point3::new(-30.0, 12.0, 400.0);
        let pts = cone_points(apex, w, psi, 20.0, 60.0, 60, 0.0, &mut rng);
        let f = cone(&pts).unwrap();
        prop_assert!(f.axis.dot(&w) > 0.0, "cone axis must point towards increasing radius");
        prop_assert!(axis_angle(&f.axis, &w) < EXACT_ANG * 10.0);
        prop_assert!((f.apex_angle - 2.0 * psi).abs() < EXACT_ANG * 10.0);
        // The apex is 20–60 mm from the data: its error is the axis-point error amplified by
        // 1/sin ψ at most ~10×.
        prop_assert!((f.apex - apex).norm() < EXACT_POS * 1000.0, "{}", (f.apex - apex).norm());
    }

    #[test]
    fn exact_circles_planes_lines_recovered(seed in any::<u64>(), r in 1.0f64..300.0, arc in 1.0f64..6.3, a in 0.0f64..1.0, b in 0.0f64..1.0) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let w = dir(a, b);
        let c = Point3::new(7.0, -8.0, 250.0);
        let pts = circle_points(c, w, r, arc, 30, 0.0, &mut rng);
        let f = circle(&pts).unwrap();
        prop_assert!((f.center - c).norm() < EXACT_POS * r * 10.0);
        prop_assert!((f.radius - r).abs() < EXACT_POS * r * 10.0);
        prop_assert!(axis_angle(&f.normal, &w) < EXACT_ANG * 10.0);
        let p = plane(&pts).unwrap();
        prop_assert!(axis_angle(&p.normal, &w) < EXACT_ANG * 10.0);
        prop_assert!(p.distance(&c).abs() < EXACT_POS * r);
        let lp: Vec<Point3> = (0..20).map(|i| c + w * (i as f64 * r / 7.0 - 3.0)).collect();
        let l = line(&lp).unwrap();
        prop_assert!(axis_angle(&l.direction, &w) < EXACT_ANG);
        prop_assert!(line_dist(&c, &l.point, &l.direction) < EXACT_POS * r);
    }

    /// fit(R·P + t) = R·fit(P) + t, and fit(shuffled P) = fit(P). Noisy data (10 µm) so the
    /// minimum is a genuine least-squares one; differences come only from rounding and the
    /// convergence tolerance (1e-14 relative), hence 1e-8 mm / 1e-9 rad.
    #[test]
    fn invariant_under_rigid_motion_and_permutation(seed in any::<u64>(), angle in 0.0f64..3.1, a in 0.0f64..1.0, b in 0.0f64..1.0) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let rot = Rotation3::from_scaled_axis(dir(a, b) * angle);
        let t = Vector3::new(rng.random::<f64>() * 1000.0 - 500.0, 321.0, -77.0);
        let mv = |ps: &[Point3]| -> Vec<Point3> { ps.iter().map(|p| rot * p + t).collect() };
        let shuffle = |ps: &[Point3], rng: &mut ChaCha8Rng| -> Vec<Point3> {
            let mut v = ps.to_vec();
            for i in (1..v.len()).rev() {
                v.swap(i, rng.random_range(0..=i));
            }
            v
        };
        let w = dir(rng.random(), rng.random());
        let (tp, ta) = (1e-8, 1e-9);

        let sp = sphere_points(Point3::new(10.0, 20.0, 30.0), 12.5, 50, 2.0, 0.01, &mut rng);
        let f0 = sphere(&sp).unwrap();
        for f1 in [sphere(&mv(&sp)).unwrap(), { let s = sphere(&shuffle(&sp, &mut rng)).unwrap(); truepos_fit::SphereFit { center: rot * s.center + t, ..s } }] {
            prop_assert!((f1.center - (rot * f0.center + t)).norm() < tp);
            prop_assert!((f1.radius - f0.radius).abs() < tp);
            prop_assert!((f1.u_radius - f0.u_radius).abs() < 1e-6 * f0.u_radius);
        }

        let cp = cylinder_points(Point3::new(5.0, 5.0, 5.0), w, 20.0, 50.0, 80, 0.01, &mut rng);
        let c0 = cylinder(&cp).unwrap();
        let c1 = cylinder(&mv(&cp)).unwrap();
        let c2 = cylinder(&shuffle(&cp, &mut rng)).unwrap();
        prop_assert!(axis_angle(&c1.axis, &(rot * c0.axis)) < ta);
        prop_assert!(line_dist(&(rot * c0.point + t), &c1.point, &c1.axis) < tp);
        prop_assert!((c1.radius - c0.radius).abs() < tp);
        prop_assert!(axis_angle(&c2.axis, &c0.axis) < ta && (c2.radius - c0.radius).abs() < tp);

        let kp = cone_points(Point3::new(0.0, 0.0, 0.0), w, 0.4, 30.0, 80.0, 80, 0.01, &mut rng);
        let k0 = cone(&kp).unwrap();
        let k1 = cone(&mv(&kp)).unwrap();
        let k2 = cone(&shuffle(&kp, &mut rng)).unwrap();
        prop_assert!((k1.axis - rot * k0.axis).norm() < ta);
        prop_assert!((k1.apex - (rot * k0.apex + t)).norm() < tp * 10.0);
        prop_assert!((k1.apex_angle - k0.apex_angle).abs() < ta);
        prop_assert!((k2.axis - k0.axis).norm() < ta && (k2.apex - k0.apex).norm() < tp * 10.0);

        let ci = circle_points(Point3::new(1.0, 2.0, 3.0), w, 30.0, 4.0, 40, 0.01, &mut rng);
        let i0 = circle(&ci).unwrap();
        let i1 = circle(&mv(&ci)).unwrap();
        prop_assert!((i1.center - (rot * i0.center + t)).norm() < tp);
        prop_assert!(axis_angle(&i1.normal, &(rot * i0.normal)) < ta);
        let p0 = plane(&ci).unwrap();
        let p1 = plane(&shuffle(&mv(&ci), &mut rng)).unwrap();
        prop_assert!(axis_angle(&p1.normal, &(rot * p0.normal)) < ta);
        prop_assert!((p1.rms - p0.rms).abs() < tp, "plane rms {} vs {}, normals {:?} {:?}", p1.rms, p0.rms, p0.normal, p1.normal);
    }
}

/// Normalised errors `(estimate − truth)/u` over repeated draws must have an RMS of 1 if the
/// stated standard uncertainty is right. With K = 300 draws the sample RMS of a unit normal
/// variable has a relative standard deviation of 1/√(2K) ≈ 4.1 %; the band 0.8–1.2 is ±4.9σ,
/// so a correct uncertainty fails with probability < 1e-5 (and the seeds are fixed). With σ₀
/// estimated from ~20 degrees of freedom the errors are Student-t, RMS √(ν/(ν−2)) ≈ 1.05, still
/// well inside the band, while an
/// uncertainty off by √(dof) conventions, a missing σ₀ factor or a wrong Jacobian misses it.
fn check_z(name: &str, z: &[f64]) {
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
    eprintln!("{name}: RMS normalised error {rms:.3} over {} draws", z.len());
    assert!((0.8..1.2).contains(&rms), "{name}: RMS of normalised errors {rms}");
}

#[test]
fn stated_uncertainty_matches_scatter() {
    const K: usize = 300;
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let noise = 0.002; // 2 µm, a CMM's probing noise
    let mut zs: [Vec<f64>; 9] = Default::default();
    let w = Vector3::new(0.3, -0.2, 0.93).normalize();
    let (u, _) = frame(&w);
    for _ in 0..K {
        // Sphere: 25 points on a hemisphere of radius 10 mm.
        let c = Point3::new(50.0, -20.0, 10.0);
        let f = sphere(&sphere_points(c, 10.0, 25, 1.6, noise, &mut rng)).unwrap();
        zs[0].push((f.radius - 10.0) / f.u_radius);
        zs[1].push((f.center.x - c.x) / f.u_center.x);
        let g = sphere_with_radius(&sphere_points(c, 10.0, 25, 1.6, noise, &mut rng), 10.0).unwrap();
        zs[2].push((g.center.z - c.z) / g.u_center.z);
        // Cylinder: 40 points, radius 15, length 40.
        let p0 = Point3::new(0.0, 0.0, 0.0);
        let cy = cylinder(&cylinder_points(p0, w, 15.0, 40.0, 40, noise, &mut rng)).unwrap();
        zs[3].push((cy.radius - 15.0) / cy.u_radius);
        // The axis tilt along u: angle component over the root-sum-square of two → ×√2.
        let tilt_u = cy.axis.dot(&u) * cy.axis.dot(&w).signum();
        zs[4].push(tilt_u / (cy.u_axis / 2f64.sqrt()));
        // Cone: half angle 0.3 rad, 50 points.
        let k =
            cone(&cone_points(Point3::new(0.0, 0.0, 0.0), w, 0.3, 20.0, 50.0, 50, noise, &mut rng)).unwrap();
        zs[5].push((k.apex_angle - 0.6) / k.u_apex_angle);
        zs[6].push(k.apex.x / k.u_apex.x);
        // Circle: 20 points over 270°.
        let cc = Point3::new(3.0, 4.0, 5.0);
        let ci = circle(&circle_points(cc, w, 25.0, 4.7, 20, noise, &mut rng)).unwrap();
        zs[7].push((ci.radius - 25.0) / ci.u_radius);
        // Plane: 30 points of a 50 mm square with noise along the normal.
        let (pu, pv) = frame(&w);
        let pts: Vec<Point3> = (0..30)
            .map(|_| {
                let p =
                    Point3::origin() + pu * (rng.random::<f64>() * 50.0) + pv * (rng.random::<f64>() * 50.0);
                add_noise(p, w, noise, &mut rng)
            })
            .collect();
        let pl = plane(&pts).unwrap();
        // The true plane is w·x = 0: the fitted point's distance from it is the offset error.
        zs[8].push(pl.point.coords.dot(&w) / pl.u_offset);
    }
    let names = [
        "sphere radius",
        "sphere centre x",
        "fixed-radius centre z",
        "cylinder radius",
        "cylinder axis tilt",
        "cone apex angle",
        "cone apex x",
        "circle radius",
        "plane offset at centroid",
    ];
    for (n, z) in names.iter().zip(&zs) {
        check_z(n, z);
    }
}

/// Convergence on large noisy data: the sum of squares over 2e5 points carries rounding noise,
/// so a convergence test that is too strict would run to the iteration cap (it did once: 200
/// iterations). Levenberg-Marquardt from the algebraic start converges quadratically: a few
/// iterations, asserted below 20 with margin.
#[test]
fn large_noisy_sphere_converges_quickly() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let c = Point3::new(120.5, -40.25, 310.0);
    let pts = sphere_points(c, 12.7, 200_000, 2.5, 0.002, &mut rng);
    let f = sphere(&pts).unwrap();
    assert!(f.iterations < 20, "{} iterations", f.iterations);
    // 2 µm noise over 2e5 points: centre uncertainty ~1e-5 mm; 6σ bound.
    assert!((f.center - c).norm() < 6.0 * f.u_center.norm(), "{:?}", f.center - c);
    assert!((f.radius - 12.7).abs() < 6.0 * f.u_radius);
    // The form taken from the fit's own residuals is the spread of the distances to the
    // centre, bit for bit.
    let d = pts.iter().map(|p| (p - f.center).norm());
    let (lo, hi) = d.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    assert_eq!(f.form.to_bits(), (hi - lo).to_bits());
    let cy = cylinder(&cylinder_points(
        Point3::origin(),
        Vector3::new(0.1, 0.2, 1.0).normalize(),
        20.0,
        60.0,
        200_000,
        0.002,
        &mut rng,
    ))
    .unwrap();
    assert!(cy.iterations < 20, "{} iterations", cy.iterations);
}
