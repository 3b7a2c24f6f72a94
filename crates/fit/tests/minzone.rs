//! Chebyshev fits against independent truth:
//! - an exhaustive search over all support sets (small n): the minimum-zone plane's normal is
//!   the normal of three points or the common normal of two point pairs (face–vertex or
//!   edge–edge contact of the two planes); the minimum-zone circle's centre is a circumcentre of
//!   three points or the intersection of two perpendicular bisectors; the circumscribed
//!   circle's a circumcentre or a midpoint; the inscribed circle's an empty circumcircle; the
//!   sphere's likewise one dimension up. The search is global; the SLP is started from the
//!   least-squares element. Widths must agree to 1e-9 mm on parts of ~10–50 mm: the SLP stops
//!   when the linear model predicts less than 1e-15 of the extent, the search is exact up to
//!   rounding (~1e-14 mm), so 1e-9 leaves margin yet catches a wrong vertex (differences of
//!   µm) by orders of magnitude.
//! - known answers: points on two concentric circles (spheres, coaxial cylinders) give the
//!   radii difference exactly; two parallel planes their distance; a line's points on a
//!   cylinder its diameter.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use truepos_fit::minzone::{self, Criterion};
use truepos_fit::FitError;
use truepos_math::{Point3, Vector3};

const TOL: f64 = 1e-9;

fn width(points: &[Point3], n: &Vector3) -> f64 {
    let n = n.normalize();
    let (lo, hi) = points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let d = p.coords.dot(&n);
        (lo.min(d), hi.max(d))
    });
    hi - lo
}

/// Global minimum-zone width of a point set by exhaustive search of support configurations.
fn brute_plane(p: &[Point3]) -> f64 {
    let n = p.len();
    let mut best = f64::INFINITY;
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let nn = (p[j] - p[i]).cross(&(p[k] - p[i]));
                if nn.norm() > 1e-12 {
                    best = best.min(width(p, &nn));
                }
            }
        }
    }
    let pairs: Vec<(usize, usize)> = (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).collect();
    for a in 0..pairs.len() {
        for b in a + 1..pairs.len() {
            let (i, j) = pairs[a];
            let (k, l) = pairs[b];
            let nn = (p[j] - p[i]).cross(&(p[l] - p[k]));
            if nn.norm() > 1e-12 {
                best = best.min(width(p, &nn));
            }
        }
    }
    best
}

fn circumcentre2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<[f64; 2]> {
    let d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]));
    if d.abs() < 1e-12 {
        return None;
    }
    let (a2, b2, c2) = (a[0] * a[0] + a[1] * a[1], b[0] * b[0] + b[1] * b[1], c[0] * c[0] + c[1] * c[1]);
    Some([
        (a2 * (b[1] - c[1]) + b2 * (c[1] - a[1]) + c2 * (a[1] - b[1])) / d,
        (a2 * (c[0] - b[0]) + b2 * (a[0] - c[0]) + c2 * (b[0] - a[0])) / d,
    ])
}

/// Intersection of the perpendicular bisectors of (a, b) and (c, d).
fn bisectors2(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> Option<[f64; 2]> {
    // (b − a)·x = (|b|² − |a|²)/2, (d − c)·x = (|d|² − |c|²)/2
    let (u, v) = ([b[0] - a[0], b[1] - a[1]], [d[0] - c[0], d[1] - c[1]]);
    let r1 = 0.5 * (b[0] * b[0] + b[1] * b[1] - a[0] * a[0] - a[1] * a[1]);
    let r2 = 0.5 * (d[0] * d[0] + d[1] * d[1] - c[0] * c[0] - c[1] * c[1]);
    let det = u[0] * v[1] - u[1] * v[0];
    if det.abs() < 1e-12 {
        return None;
    }
    Some([(r1 * v[1] - r2 * u[1]) / det, (u[0] * r2 - v[0] * r1) / det])
}

fn range2(p: &[[f64; 2]], c: [f64; 2]) -> (f64, f64) {
    p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
        let r = (q[0] - c[0]).hypot(q[1] - c[1]);
        (lo.min(r), hi.max(r))
    })
}

fn inside_hull2(p: &[[f64; 2]], c: [f64; 2]) -> bool {
    // Inside the convex hull iff no direction has every point on one side of c: check the
    // angular gaps around c.
    let mut a: Vec<f64> = p.iter().map(|q| (q[1] - c[1]).atan2(q[0] - c[0])).collect();
    a.sort_by(f64::total_cmp);
    let mut gap = a[0] + std::f64::consts::TAU - a[a.len() - 1];
    for w in a.windows(2) {
        gap = gap.max(w[1] - w[0]);
    }
    gap < std::f64::consts::PI
}

/// (minimum zone width, inscribed radius, circumscribed radius) of 2D points by exhaustive
/// search over support sets.
fn brute_circle(p: &[[f64; 2]]) -> (f64, f64, f64) {
    let n = p.len();
    let (mut mz, mut mic, mut mcc) = (f64::INFINITY, 0.0f64, f64::INFINITY);
    let try_c = |c: [f64; 2], mz: &mut f64, mic: &mut f64, mcc: &mut f64| {
        let (lo, hi) = range2(p, c);
        *mz = mz.min(hi - lo);
        *mcc = mcc.min(hi);
        if inside_hull2(p, c) {
            *mic = mic.max(lo);
        }
    };
    for i in 0..n {
        for j in i + 1..n {
            try_c([(p[i][0] + p[j][0]) / 2.0, (p[i][1] + p[j][1]) / 2.0], &mut mz, &mut mic, &mut mcc);
            for k in j + 1..n {
                if let Some(c) = circumcentre2(p[i], p[j], p[k]) {
                    try_c(c, &mut mz, &mut mic, &mut mcc);
                }
            }
        }
    }
    let pairs: Vec<(usize, usize)> = (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).collect();
    for a in 0..pairs.len() {
        for b in a + 1..pairs.len() {
            if let Some(c) = bisectors2(p[pairs[a].0], p[pairs[a].1], p[pairs[b].0], p[pairs[b].1]) {
                let (lo, hi) = range2(p, c);
                mz = mz.min(hi - lo);
            }
        }
    }
    (mz, mic, mcc)
}

/// Centre equidistant from the points `s` (2 to 4 of them) and lying in their affine hull.
fn equidistant_centre(s: &[Point3]) -> Option<Point3> {
    // c = s0 + Σ λ_k (s_k − s0), with (s_k − s0)·(c − s0) = |s_k − s0|²/2.
    let m = s.len() - 1;
    let e: Vec<Vector3> = s[1..].iter().map(|q| q - s[0]).collect();
    let mut a = nalgebra::DMatrix::<f64>::zeros(m, m);
    let mut b = nalgebra::DVector::<f64>::zeros(m);
    for i in 0..m {
        for j in 0..m {
            a[(i, j)] = e[i].dot(&e[j]);
        }
        b[i] = 0.5 * e[i].norm_squared();
    }
    let lam = a.lu().solve(&b)?;
    let c = s[0] + (0..m).fold(Vector3::zeros(), |acc, k| acc + e[k] * lam[k]);
    c.coords.iter().all(|v| v.is_finite()).then_some(c)
}

fn range3(p: &[Point3], c: &Point3) -> (f64, f64) {
    p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
        let r = (q - c).norm();
        (lo.min(r), hi.max(r))
    })
}

/// Sphere (minimum zone width, circumscribed radius) by exhaustive search.
fn brute_sphere(p: &[Point3]) -> (f64, f64) {
    let n = p.len();
    let (mut mz, mut mcc) = (f64::INFINITY, f64::INFINITY);
    let idx = |k: usize| -> Vec<Vec<usize>> {
        let mut out = vec![];
        let mut cur = vec![];
        fn rec(start: usize, n: usize, k: usize, cur: &mut Vec<usize>, out: &mut Vec<Vec<usize>>) {
            if cur.len() == k {
                out.push(cur.clone());
                return;
            }
            for i in start..n {
                cur.push(i);
                rec(i + 1, n, k, cur, out);
                cur.pop();
            }
        }
        rec(0, n, k, &mut cur, &mut out);
        out
    };
    for k in 2..=4 {
        for s in idx(k) {
            let pts: Vec<Point3> = s.iter().map(|&i| p[i]).collect();
            if let Some(c) = equidistant_centre(&pts) {
                let (lo, hi) = range3(p, &c);
                mcc = mcc.min(hi);
                if k == 4 {
                    mz = mz.min(hi - lo);
                }
            }
        }
    }
    // 3 + 2: on the axis of the circumcircle of three, equidistant from two others.
    for t in idx(3) {
        let (a, b, c) = (p[t[0]], p[t[1]], p[t[2]]);
        let Some(o) = equidistant_centre(&[a, b, c]) else { continue };
        let ax = (b - a).cross(&(c - a));
        if ax.norm() < 1e-12 {
            continue;
        }
        for i in 0..n {
            for j in i + 1..n {
                if t.contains(&i) || t.contains(&j) {
                    continue;
                }
                // |o + s ax − p_i|² = |o + s ax − p_j|²: linear in s.
                let (pi, pj) = (p[i], p[j]);
                let den = 2.0 * ax.dot(&(pj - pi));
                if den.abs() < 1e-12 {
                    continue;
                }
                let num =
                    (pj.coords.norm_squared() - pi.coords.norm_squared()) - 2.0 * o.coords.dot(&(pj - pi));
                let cc = o + ax * (num / den);
                let (lo, hi) = range3(p, &cc);
                mz = mz.min(hi - lo);
            }
        }
    }
    (mz, mcc)
}

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A tilted, offset plane with form deviations of ±`dev`.
fn plane_set(seed: u64, n: usize, dev: f64) -> Vec<Point3> {
    let mut r = rng(seed);
    let nrm = Vector3::new(r.random::<f64>() - 0.5, r.random::<f64>() - 0.5, 2.0).normalize();
    let u = truepos_math::any_perpendicular(&nrm);
    let v = nrm.cross(&u);
    let o = Point3::new(r.random::<f64>() * 100.0, -50.0, 20.0);
    (0..n)
        .map(|_| {
            o + u * (r.random::<f64>() * 40.0)
                + v * (r.random::<f64>() * 25.0)
                + nrm * (dev * (2.0 * r.random::<f64>() - 1.0))
        })
        .collect()
}

fn circle_set(seed: u64, n: usize, radius: f64, dev: f64) -> Vec<[f64; 2]> {
    let mut r = rng(seed);
    let c = [r.random::<f64>() * 10.0, r.random::<f64>() * 10.0];
    (0..n)
        .map(|i| {
            let a = (i as f64 + 0.3 * r.random::<f64>()) * std::f64::consts::TAU / n as f64;
            let rr = radius + dev * (2.0 * r.random::<f64>() - 1.0) + 0.5 * dev * (3.0 * a).cos();
            [c[0] + rr * a.cos(), c[1] + rr * a.sin()]
        })
        .collect()
}

#[test]
fn minimum_zone_plane_matches_exhaustive_search() {
    let mut worst = 0.0f64;
    for seed in 0..12 {
        let p = plane_set(seed, 14, 0.01 * (1.0 + seed as f64));
        let z = minzone::plane_zone(&p).unwrap();
        let b = brute_plane(&p);
        worst = worst.max((z.form - b).abs());
        assert!((z.form - b).abs() < TOL, "seed {seed}: {} vs {b}", z.form);
        // The reported plane holds every point within ±form/2.
        for q in &p {
            assert!(((q - z.point).dot(&z.normal)).abs() <= z.form / 2.0 + 1e-12);
        }
    }
    eprintln!("minimum-zone plane vs exhaustive search, 12 sets: worst |Δ width| = {worst:.2e} mm");
}

#[test]
fn circle_criteria_match_exhaustive_search() {
    let (mut w_mz, mut w_mic, mut w_mcc) = (0.0f64, 0.0f64, 0.0f64);
    for seed in 0..12 {
        let q = circle_set(100 + seed, 12, 10.0 + seed as f64, 0.02);
        // Embed in a tilted plane in 3D.
        let nrm = Vector3::new(0.3, -0.2, 1.0).normalize();
        let u = truepos_math::any_perpendicular(&nrm);
        let v = nrm.cross(&u);
        let o = Point3::new(5.0, 7.0, -3.0);
        let p: Vec<Point3> = q.iter().map(|a| o + u * a[0] + v * a[1]).collect();
        let (mz, mic, mcc) = brute_circle(&q);
        let z = minzone::circle_fit(&p, Criterion::MinimumZone).unwrap();
        let i = minzone::circle_fit(&p, Criterion::MaximumInscribed).unwrap();
        let c = minzone::circle_fit(&p, Criterion::MinimumCircumscribed).unwrap();
        w_mz = w_mz.max((z.form - mz).abs());
        w_mic = w_mic.max((i.radius - mic).abs());
        w_mcc = w_mcc.max((c.radius - mcc).abs());
        assert!((z.form - mz).abs() < TOL, "seed {seed}: zone {} vs {mz}", z.form);
        assert!((i.radius - mic).abs() < TOL, "seed {seed}: inscribed {} vs {mic}", i.radius);
        assert!((c.radius - mcc).abs() < TOL, "seed {seed}: circumscribed {} vs {mcc}", c.radius);
        assert!((z.radius - 0.5 * (z.inner_radius + z.outer_radius)).abs() < 1e-12);
    }
    eprintln!(
        "circle vs exhaustive search, 12 sets: worst |Δ| zone {w_mz:.2e}, inscribed {w_mic:.2e}, circumscribed {w_mcc:.2e} mm"
    );
}

#[test]
fn sphere_criteria_match_exhaustive_search() {
    let (mut w_mz, mut w_mcc) = (0.0f64, 0.0f64);
    for seed in 0..10 {
        let mut r = rng(200 + seed);
        let c = Point3::new(r.random::<f64>() * 20.0, 3.0, -4.0);
        let p: Vec<Point3> = (0..11)
            .map(|_| {
                let d = Vector3::new(
                    2.0 * r.random::<f64>() - 1.0,
                    2.0 * r.random::<f64>() - 1.0,
                    r.random::<f64>() - 0.3,
                )
                .normalize();
                c + d * (12.5 + 0.02 * (2.0 * r.random::<f64>() - 1.0))
            })
            .collect();
        let (mz, mcc) = brute_sphere(&p);
        let z = minzone::sphere_fit(&p, Criterion::MinimumZone).unwrap();
        let o = minzone::sphere_fit(&p, Criterion::MinimumCircumscribed).unwrap();
        w_mz = w_mz.max((z.form - mz).abs());
        w_mcc = w_mcc.max((o.radius - mcc).abs());
        assert!((z.form - mz).abs() < TOL, "seed {seed}: zone {} vs {mz}", z.form);
        assert!((o.radius - mcc).abs() < TOL, "seed {seed}: circumscribed {} vs {mcc}", o.radius);
    }
    eprintln!(
        "sphere vs exhaustive search, 10 sets: worst |Δ| zone {w_mz:.2e}, circumscribed {w_mcc:.2e} mm"
    );
}

#[test]
fn known_answers() {
    // Two parallel planes 0.05 apart.
    let mut r = rng(7);
    let n = Vector3::new(0.1, 0.2, 1.0).normalize();
    let u = truepos_math::any_perpendicular(&n);
    let v = n.cross(&u);
    let p: Vec<Point3> = (0..200)
        .map(|i| {
            Point3::new(1.0, 2.0, 3.0)
                + u * (r.random::<f64>() * 80.0)
                + v * (r.random::<f64>() * 30.0)
                + n * if i % 2 == 0 { 0.0 } else { 0.05 }
        })
        .collect();
    let z = minzone::plane_zone(&p).unwrap();
    assert!((z.form - 0.05).abs() < 1e-12, "{}", z.form);
    assert!(z.normal.cross(&n).norm() < 1e-12);

    // Points on two coaxial cylinders of radii 8 and 8.02 (axis tilted), 3 heights.
    let ax = Vector3::new(0.2, -0.1, 1.0).normalize();
    let a = truepos_math::any_perpendicular(&ax);
    let b = ax.cross(&a);
    let o = Point3::new(-3.0, 4.0, 10.0);
    let mut cyl = vec![];
    for k in 0..3 {
        for i in 0..24 {
            let t = i as f64 * std::f64::consts::TAU / 24.0 + 0.1 * k as f64;
            let rr = if (i + k) % 2 == 0 { 8.0 } else { 8.02 };
            cyl.push(o + ax * (10.0 * k as f64) + (a * t.cos() + b * t.sin()) * rr);
        }
    }
    let z = minzone::cylinder_fit(&cyl, Criterion::MinimumZone).unwrap();
    assert!((z.form - 0.02).abs() < 1e-10, "{}", z.form);
    assert!((z.radius - 8.01).abs() < 1e-10);
    let i = minzone::cylinder_fit(&cyl, Criterion::MaximumInscribed).unwrap();
    assert!((i.radius - 8.0).abs() < 1e-10, "{}", i.radius);
    let c = minzone::cylinder_fit(&cyl, Criterion::MinimumCircumscribed).unwrap();
    assert!((c.radius - 8.02).abs() < 1e-10, "{}", c.radius);

    // Two concentric spheres.
    let mut sph = vec![];
    for i in 0..60 {
        let d = Vector3::new((i as f64 * 0.7).cos(), (i as f64 * 1.3).sin(), ((i % 7) as f64 - 3.0) / 3.5)
            .normalize();
        sph.push(Point3::new(1.0, -1.0, 2.0) + d * if i % 2 == 0 { 25.0 } else { 25.004 });
    }
    let z = minzone::sphere_fit(&sph, Criterion::MinimumZone).unwrap();
    assert!((z.form - 0.004).abs() < 1e-11, "{}", z.form);

    // A line's points on a cylinder of radius 0.01 around it: form = 0.02 (diameter).
    let d = Vector3::new(1.0, 1.0, 0.3).normalize();
    let e = truepos_math::any_perpendicular(&d);
    let f = d.cross(&e);
    let line: Vec<Point3> = (0..50)
        .map(|i| {
            let t = i as f64 * 1.7;
            Point3::new(2.0, 3.0, 4.0) + d * t + (e * (t * 1.3).cos() + f * (t * 1.3).sin()) * 0.01
        })
        .collect();
    let z = minzone::line_zone(&line).unwrap();
    assert!((z.form - 0.02).abs() < 1e-10, "{}", z.form);
    assert!(z.direction.cross(&d).norm() < 1e-9);
}

#[test]
fn open_data_has_no_inscribed_element() {
    // A 60° arc: the inscribed circle is unbounded.
    let arc: Vec<Point3> = (0..30)
        .map(|i| {
            let a = i as f64 * std::f64::consts::PI / 3.0 / 29.0;
            Point3::new(10.0 * a.cos(), 10.0 * a.sin(), 0.0)
        })
        .collect();
    assert!(matches!(
        minzone::circle_fit(&arc, Criterion::MaximumInscribed),
        Err(FitError::InscribedUnbounded { .. })
    ));
    let z = minzone::circle_fit(&arc, Criterion::MinimumZone).unwrap();
    assert!(z.form < 1e-9 && (z.radius - 10.0).abs() < 1e-9);
}

/// Timings for the report (release profile: `cargo test --release -p truepos-fit --test
/// minzone -- --ignored --nocapture`). The criterion bench has the same cases.
#[test]
#[ignore = "timing figures, run by hand"]
fn timings_10k_100k() {
    for n in [10_000usize, 100_000] {
        let p = plane_set(1, n, 0.005);
        let t = std::time::Instant::now();
        let _ = truepos_fit::plane(&p).unwrap();
        eprintln!("ls plane n={n}: {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
        let t = std::time::Instant::now();
        let z = minzone::plane_zone(&p).unwrap();
        eprintln!(
            "plane   n={n}: {:.1} ms, form {:.6} mm, {} steps",
            t.elapsed().as_secs_f64() * 1e3,
            z.form,
            z.iterations
        );
        let q: Vec<Point3> =
            circle_set(2, n, 25.0, 0.005).iter().map(|a| Point3::new(a[0], a[1], 0.0)).collect();
        let t = std::time::Instant::now();
        let z = minzone::circle_fit(&q, Criterion::MinimumZone).unwrap();
        eprintln!(
            "circle  n={n}: {:.1} ms, form {:.6} mm, {} steps",
            t.elapsed().as_secs_f64() * 1e3,
            z.form,
            z.iterations
        );
    }
}

mod invariants {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// The minimum zone is never wider than the least-squares element's zone; the inscribed
        /// radius ≤ the zone's inner radius … ≤ the circumscribed radius; the reported zones
        /// hold every point.
        #[test]
        fn zone_orderings(seed in 0u64..10_000, n in 8usize..60, dev in 1e-4f64..0.05) {
            let q: Vec<Point3> = circle_set(seed, n, 20.0, dev).iter().map(|a| Point3::new(a[0], a[1], 1.0)).collect();
            let ls = truepos_fit::circle(&q).unwrap();
            let z = minzone::circle_fit(&q, Criterion::MinimumZone).unwrap();
            let i = minzone::circle_fit(&q, Criterion::MaximumInscribed).unwrap();
            let o = minzone::circle_fit(&q, Criterion::MinimumCircumscribed).unwrap();
            prop_assert!(z.form <= ls.form + 1e-12);
            prop_assert!(i.radius <= ls.radius + 1e-12 && ls.radius <= o.radius + 1e-12);
            prop_assert!(i.form >= z.form - 1e-12 && o.form >= z.form - 1e-12);
            for p in &q {
                let r = (p - o.center).norm();
                prop_assert!(r <= o.radius + 1e-12);
                prop_assert!((p - i.center).norm() >= i.radius - 1e-12);
            }
            let p = plane_set(seed, n, dev);
            let lsp = truepos_fit::plane(&p).unwrap();
            let zp = minzone::plane_zone(&p).unwrap();
            prop_assert!(zp.form <= lsp.form + 1e-12);
        }
    }
}
