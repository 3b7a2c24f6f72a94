//! The head-offset scenario against the contract model: applying `Q = P + Ry(b)·R` (plus
//! `dist·Ry(b)·u` for a laser) with the TRUE offset and undoing the table rotation puts every row on
//! the true sphere / the true faces to noise level; a wrong offset does not, not even with a
//! freely fitted sphere.

use nalgebra::{Matrix4, Vector4};
use truepos_math::types::{ry, rz, Point3, Vector3};
use truepos_sim::scenario::head_offset::{
    simulate, Head, HeadOffsetConfig, HeadOffsetData, HeadOffsetRow, Reference, Variant,
};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The contract model: the c = 0 table position of the measured point of a row for offset `r`.
fn contract_point(row: &HeadOffsetRow, r: &Vector3, cfg: &HeadOffsetConfig) -> Point3 {
    let b = row.b_deg * DEG;
    let c = row.c_deg * DEG;
    let p = Point3::new(row.x_mm, row.y_mm, row.z_mm);
    let mut q = p + ry(b) * r;
    if let Head::Laser { tilt, .. } = cfg.head {
        let u = Vector3::new(tilt[0].tan(), tilt[1].tan(), -1.0).normalize();
        q += row.dist_mm.expect("laser rows carry dist_mm") * (ry(b) * u);
    }
    let o = cfg.table_centre;
    o + rz(-c) * (q - o)
}

/// Signed residuals of the rows against the truth geometry for offset `r`.
fn residuals(data: &HeadOffsetData, cfg: &HeadOffsetConfig, r: &Vector3) -> Vec<f64> {
    let t = &data.truth;
    data.rows
        .iter()
        .map(|row| {
            let a = contract_point(row, r, cfg);
            let v = Point3::from(t.reference_point_mm);
            match row.face {
                None => (a - v).norm() - t.fitted_radius_mm.unwrap(),
                Some(k) => {
                    let n = Vector3::from(t.faces[k].normal);
                    n.dot(&(a - v)) - t.tip_radius_mm.unwrap_or(0.0)
                }
            }
        })
        .collect()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |a, x| a.max(x.abs()))
}

/// Free-centre, free-radius geometric sphere fit (Gauss–Newton from the centroid); returns RMS.
fn free_sphere_rms(pts: &[Point3]) -> f64 {
    let n = pts.len() as f64;
    let mut c = pts.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let mut r = pts.iter().map(|p| (p.coords - c).norm()).sum::<f64>() / n;
    // Centroid of a cap is inside the sphere; move outwards along the mean direction first.
    for _ in 0..200 {
        let mut jtj = Matrix4::zeros();
        let mut jtr = Vector4::zeros();
        for p in pts {
            let d = p.coords - c;
            let dist = d.norm();
            let res = dist - r;
            let u = d / dist;
            let j = Vector4::new(-u.x, -u.y, -u.z, -1.0);
            jtj += j * j.transpose();
            jtr += j * res;
        }
        let step = jtj.lu().solve(&(-jtr)).unwrap();
        c += Vector3::new(step[0], step[1], step[2]);
        r += step[3];
        if step.norm() < 1e-12 {
            break;
        }
    }
    let res: Vec<f64> = pts.iter().map(|p| (p.coords - c).norm() - r).collect();
    rms(&res)
}

#[test]
fn deterministic_for_a_seed() {
    for v in Variant::ALL {
        let cfg = HeadOffsetConfig::preset(v, 7);
        let a = simulate(&cfg).unwrap();
        let b = simulate(&cfg).unwrap();
        assert_eq!(a, b, "{}", v.name());
        let c = simulate(&HeadOffsetConfig::preset(v, 8)).unwrap();
        assert_ne!(a.rows, c.rows, "{}: another seed gives other points", v.name());
    }
}

#[test]
fn noise_free_rows_are_exact_under_the_true_offset() {
    for v in Variant::ALL {
        let mut cfg = HeadOffsetConfig::preset(v, 3);
        cfg.noise = 0.0;
        let data = simulate(&cfg).unwrap();
        let res = residuals(&data, &cfg, &cfg.offset);
        // Only floating-point rounding of ~1000 mm coordinates: 1e-12 relative → ~1e-9 mm.
        assert!(max_abs(&res) < 1e-9, "{}: max residual {} mm", v.name(), max_abs(&res));
        // Realistic sizes: 36–40 points per orientation, one row per point.
        let n_orient = cfg.b_angles.len() * cfg.c_angles.len();
        assert_eq!(data.rows.len(), n_orient * cfg.points_per_orientation, "{}", v.name());
        assert_eq!(data.truth.n_points, data.rows.len());
    }
}

#[test]
fn noisy_rows_sit_on_the_truth_at_noise_level_and_wrong_offsets_do_not() {
    for v in Variant::ALL {
        let cfg = HeadOffsetConfig::preset(v, 11);
        let data = simulate(&cfg).unwrap();
        let res = residuals(&data, &cfg, &cfg.offset);
        let sigma = cfg.noise;
        // The residual along the normal is the N(0, σ) noise itself (touch), or the distance noise
        // times the cosine of the incidence angle (laser, cos ≥ cos 45°–70°), so RMS ∈ [0.3σ, 1.3σ]
        // for n ≥ 144 (sampling scatter of an RMS at n = 144 is ~6 %).
        let r = rms(&res);
        assert!(r < 1.3 * sigma && r > 0.3 * sigma, "{}: rms {r}", v.name());
        // Max |N(0,1)| over ≤ 240 draws stays below 5 with probability > 0.9998.
        assert!(max_abs(&res) < 5.0 * sigma, "{}: max {}", v.name(), max_abs(&res));

        // A 50 µm error of R along each observable component leaves residuals ≫ noise.
        for j in 0..3 {
            if !data.truth.observable[j] {
                continue;
            }
            let mut wrong = cfg.offset;
            wrong[j] += 0.05;
            let bad = residuals(&data, &cfg, &wrong);
            assert!(max_abs(&bad) > 20.0 * sigma, "{} comp {j}: max {}", v.name(), max_abs(&bad));
        }
    }
}

#[test]
fn a_wrong_offset_is_not_absorbed_by_a_free_sphere_fit() {
    let cfg = HeadOffsetConfig::preset(Variant::Both, 5);
    let data = simulate(&cfg).unwrap();
    let fit = |r: &Vector3| {
        let pts: Vec<Point3> = data.rows.iter().map(|row| contract_point(row, r, &cfg)).collect();
        free_sphere_rms(&pts)
    };
    // With the truth: the free fit's RMS is the noise (0.5 µm) minus 4 of 216 degrees of freedom.
    let good = fit(&cfg.offset);
    assert!(good < 1.3 * cfg.noise && good > 0.5 * cfg.noise, "good {good}");
    // 50 µm wrong in x: the six groups' centres disagree by up to 2·50 µm; a free fit cannot
    // absorb that (RMS ≫ 10 µm would be typical; assert a safe 10σ).
    let wrong = cfg.offset + Vector3::new(0.05, 0.0, 0.0);
    let bad = fit(&wrong);
    assert!(bad > 10.0 * cfg.noise, "bad {bad}");
}

#[test]
fn observability_truth_matches_the_orientations() {
    let obs = |v| simulate(&HeadOffsetConfig::preset(v, 1)).unwrap().truth.observable;
    // B about Y moves x and z of R; C about Z moves x and y; both: all three.
    assert_eq!(obs(Variant::Swivel), [true, false, true]);
    assert_eq!(obs(Variant::Table), [true, true, false]);
    assert_eq!(obs(Variant::Both), [true, true, true]);
}

#[test]
fn points_spread_over_a_cap_facing_the_head() {
    let cfg = HeadOffsetConfig::preset(Variant::Swivel, 2);
    let data = simulate(&cfg).unwrap();
    let Reference::Sphere { centre, radius } = cfg.reference else { panic!() };
    let tip = 1.5;
    for row in &data.rows {
        let b = row.b_deg * DEG;
        let q = Point3::new(row.x_mm, row.y_mm, row.z_mm) + ry(b) * cfg.offset;
        let n = (q - centre) / (radius + tip);
        // Normal within 60° (+ noise) of the direction to the head, Ry(b)·Z.
        let cosang = n.dot(&(ry(b) * Vector3::z()));
        assert!(cosang > (60.0 * DEG).cos() - 1e-3, "cos {cosang}");
    }
    // Rows of the raw P are far from the sphere (the offset is ~170 mm): the raw data alone is not
    // the sphere.
    let p0 = &data.rows[0];
    let d = (Point3::new(p0.x_mm, p0.y_mm, p0.z_mm) - centre).norm();
    assert!(d > 100.0, "raw P is {d} mm from the centre");
}

#[test]
fn vertex_faces_are_tagged_and_all_seen() {
    for v in [Variant::Pyramid, Variant::Cuboid] {
        let data = simulate(&HeadOffsetConfig::preset(v, 4)).unwrap();
        let n_faces = data.truth.faces.len();
        assert!(n_faces >= 3);
        for f in &data.truth.faces {
            let count = data.rows.iter().filter(|r| r.face == Some(f.id)).count();
            assert_eq!(count, f.n_points);
            assert!(count >= 10, "{}: face {} has {count} points", v.name(), f.id);
        }
    }
}

#[test]
fn laser_offsets_up_to_300_mm_and_bad_settings_are_refused() {
    let mut cfg = HeadOffsetConfig::preset(Variant::Laser, 9);
    cfg.offset = Vector3::new(-300.0, 250.0, -300.0);
    cfg.noise = 0.0;
    let data = simulate(&cfg).unwrap();
    assert!(max_abs(&residuals(&data, &cfg, &cfg.offset)) < 1e-9);
    assert!(data.rows.iter().all(|r| r.dist_mm.unwrap().abs() <= 5.0));

    let mut bad = HeadOffsetConfig::preset(Variant::Both, 1);
    bad.noise = f64::NAN;
    assert!(simulate(&bad).is_err());
    let mut bad = HeadOffsetConfig::preset(Variant::Both, 1);
    bad.b_angles.clear();
    assert!(simulate(&bad).is_err());
    let mut bad = HeadOffsetConfig::preset(Variant::Cuboid, 1);
    bad.b_angles = vec![0.0];
    bad.c_angles = vec![0.0];
    bad.head = Head::Laser { tilt: [0.0, 0.0], range: 10.0 };
    // A vertical beam never sees the cuboid's vertical faces.
    assert!(simulate(&bad).is_err());
}

#[test]
fn randomized_placements_and_offsets_stay_exact() {
    // Sphere/vertex anywhere on the table, R in ±300 mm, random tilts and tip radii: the contract
    // model with the true R still reproduces the truth exactly without noise, and to noise level
    // with it (same bounds as above).
    for seed in 0..20 {
        for v in Variant::ALL {
            let mut cfg = HeadOffsetConfig::randomized(v, seed);
            assert!(cfg.offset.iter().all(|c| c.abs() <= 300.0));
            let data = match simulate(&cfg) {
                Ok(d) => d,
                Err(e) => panic!("{} seed {seed}: {e}", v.name()),
            };
            let res = residuals(&data, &cfg, &cfg.offset);
            // ~26 000 normal draws in all: P(any |z| > 5.5) ≈ 26 000 · 3.8e-8 ≈ 1e-3.
            assert!(max_abs(&res) < 5.5 * cfg.noise, "{} seed {seed}: {}", v.name(), max_abs(&res));
            cfg.noise = 0.0;
            let data = simulate(&cfg).unwrap();
            assert!(max_abs(&residuals(&data, &cfg, &cfg.offset)) < 1e-9);
        }
    }
}

#[test]
fn a_machine_with_geometric_errors_shows_through_at_the_micrometre_level() {
    use truepos_sim::machine::{Machine, MachineKind};
    let mut cfg = HeadOffsetConfig::preset(Variant::Both, 12);
    cfg.noise = 0.0;
    let ideal = simulate(&cfg).unwrap();
    cfg.machine = Some(Machine::realistic(MachineKind::Vmc, 3));
    let real = simulate(&cfg).unwrap();
    assert!(real.truth.machine_errors);
    // Same seed: same surface points, but the NC reports other axis positions: they differ by
    // the volumetric error (realistic VMC: µm to tens of µm).
    let dp = ideal
        .rows
        .iter()
        .zip(&real.rows)
        .map(|(a, b)| (Vector3::new(a.x_mm - b.x_mm, a.y_mm - b.y_mm, a.z_mm - b.z_mm)).norm())
        .fold(0.0, f64::max);
    assert!(dp > 1e-3 && dp < 0.1, "largest change of P {dp}");
    // Against the truth the contract model is off by the error's variation over the data: above
    // the noise-free 1e-9 but below the whole error.
    let res = residuals(&real, &cfg, &cfg.offset);
    assert!(max_abs(&res) > 1e-6 && max_abs(&res) < dp + 1e-9, "{}", max_abs(&res));
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn any_f64() -> impl Strategy<Value = f64> {
        prop_oneof![-1e6..1e6f64, Just(0.0), Just(f64::NAN), Just(f64::INFINITY), Just(-1e300), Just(1e-300)]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        /// Any configuration either simulates or is refused with an error: never a panic, never
        /// a non-finite coordinate in an accepted data set of sane size.
        #[test]
        fn no_panic_on_any_config(v in 0usize..6, seed in any::<u64>(), ox in any_f64(), b in any_f64(),
                                  c in any_f64(), n in 0usize..60, noise in any_f64(), cap in any_f64(),
                                  radius in any_f64(), tip in any_f64()) {
            let mut cfg = HeadOffsetConfig::preset(Variant::ALL[v], seed);
            cfg.offset.x = ox;
            cfg.b_angles.push(b);
            cfg.c_angles.push(c);
            cfg.points_per_orientation = n;
            cfg.noise = noise;
            cfg.cap_half_angle = cap;
            if let Reference::Sphere { centre, .. } = cfg.reference {
                cfg.reference = Reference::Sphere { centre, radius };
            }
            if let Head::TouchProbe { .. } = cfg.head {
                cfg.head = Head::TouchProbe { tip_radius: tip };
            }
            if let Ok(d) = simulate(&cfg) {
                if ox.abs() < 1e100 && radius.abs() < 1e100 && noise.abs() < 1e100 {
                    prop_assert!(d.rows.iter().all(|r| r.x_mm.is_finite() && r.y_mm.is_finite() && r.z_mm.is_finite()));
                }
            }
        }
    }
}

#[test]
fn a_c_axis_location_error_breaks_the_contract_by_twice_the_offset() {
    use truepos_sim::errors::GeometricErrors;
    use truepos_sim::machine::{Machine, RotaryAxisErrors};
    let mut cfg = HeadOffsetConfig::preset(Variant::Table, 2);
    cfg.noise = 0.0;
    let mut m = Machine::vmc(GeometricErrors::zero(), cfg.table_centre);
    m.rotary_errors = RotaryAxisErrors { c_offset: Vector3::new(0.01, 0.0, 0.0), ..Default::default() };
    cfg.machine = Some(m);
    let data = simulate(&cfg).unwrap();
    // Rows at c = 0 still fit exactly; at c = 180° the sphere is 2·10 µm off along x, so the
    // signed residuals reach about ±20 µm·cos(angle to x) over the 60° cap.
    let res = residuals(&data, &cfg, &cfg.offset);
    let at = |c: f64| -> f64 {
        max_abs(
            &data.rows.iter().zip(&res).filter(|(r, _)| r.c_deg == c).map(|(_, e)| *e).collect::<Vec<_>>(),
        )
    };
    assert!(at(0.0) < 1e-9, "{}", at(0.0));
    assert!(at(180.0) > 0.015 && at(180.0) <= 0.02 + 1e-9, "{}", at(180.0));
}
