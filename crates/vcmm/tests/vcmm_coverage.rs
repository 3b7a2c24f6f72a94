//! Proof of coverage of the task-specific uncertainty (ISO/TS 15530-4): machines drawn from the
//! virtual CMM's error model (the model of `truepos ippdme serve`, each machine its own `seed`)
//! measure a Ø 25 mm sphere of known position with `probe sphere`'s strategy; the expanded
//! uncertainty (k = 2) from `--machine-model` must contain the truth in 95 % (90–99 %) of the
//! comparisons, and must not be inflated (median |error|/U ≥ 0.15).
//!
//! The always-on test draws 60 machines (240 comparisons); the `--ignored` one 200 machines
//! (800 comparisons), the figures of docs/uncertainty.md.

use std::path::Path;
use truepos_head::acquire::{probe_sphere, SphereProbing};
use truepos_ippdme::part::{Part, Solid};
use truepos_ippdme::MachineConfig;
use truepos_math::{Point3, Vector3};
use truepos_vcmm::{sphere_uncertainty, MachineModel, MonteCarlo, SimulatedCmm};

/// A measurement on machine `seed` of the model: (errors of cx, cy, cz, r) and their U (k = 2).
fn measure(model: &MachineModel, seed: u64, truth: Point3, radius: f64) -> ([f64; 4], [f64; 4]) {
    let mut cfg: MachineConfig = model.cmm.clone().expect("an error model");
    cfg.model.seed = seed;
    let part = Part { solids: vec![(None, Solid::Sphere { center: truth, radius })] };
    // The user's nominal centre is 0.3 mm off the true one, as a sphere set up by hand is.
    let plan = SphereProbing {
        near_mm: truth + Vector3::new(0.2, -0.15, 0.16),
        diameter_mm: 2.0 * radius,
        points: 25,
        feed_mm_s: 50.0 / 60.0,
        clearance_mm: 2.0,
        tip_radius_mm: 1.5,
    };
    let mut machine = SimulatedCmm::new(&cfg, Some(part), plan.tip_radius_mm);
    let s = probe_sphere(&mut machine, &plan).expect("probe the sphere");
    let u = sphere_uncertainty(
        model,
        &plan,
        s.center_mm,
        s.radius_mm,
        s.center_uncertainty_mm,
        s.radius_uncertainty_mm,
        MonteCarlo::default(),
    )
    .expect("uncertainty");
    let e = s.center_mm - truth;
    (
        [e.x, e.y, e.z, s.radius_mm - radius],
        [2.0 * u.center_mm.x, 2.0 * u.center_mm.y, 2.0 * u.center_mm.z, 2.0 * u.radius_mm],
    )
}

fn coverage(machines: u64, model_text: &str) -> (f64, f64, usize) {
    let model = MachineModel::from_toml(Path::new("model.toml"), model_text).expect("model");
    let spheres = [(Point3::new(120.0, 45.0, 30.0), 12.5), (Point3::new(-310.0, 260.0, -120.0), 12.5)];
    let mut inside = 0;
    let mut ratios = Vec::new();
    for seed in 1..=machines {
        let (c, r) = spheres[(seed % 2) as usize];
        let (err, big_u) = measure(&model, 1000 + seed, c, r);
        for k in 0..4 {
            if err[k].abs() <= big_u[k] {
                inside += 1;
            }
            ratios.push(err[k].abs() / big_u[k]);
        }
    }
    ratios.sort_by(f64::total_cmp);
    let n = ratios.len();
    (inside as f64 / n as f64, ratios[n / 2], n)
}

const DEFAULT_MODEL: &str = "[ippdme.model]\n";

fn check(label: &str, machines: u64, model: &str) {
    let t0 = std::time::Instant::now();
    let (cov, median, n) = coverage(machines, model);
    eprintln!(
        "coverage {label}: {:.1} % of {n} comparisons within ±U, median |error|/U = {median:.2} ({machines} machines, {:.1} s)",
        100.0 * cov,
        t0.elapsed().as_secs_f64()
    );
    assert!((0.90..=0.99).contains(&cov), "{label}: coverage {cov} outside 90–99 %");
    assert!(median >= 0.15, "{label}: U inflated: median |error|/U = {median}");
}

#[test]
fn task_specific_uncertainty_covers_the_truth_on_the_default_cmm() {
    check("default virtual CMM", 60, DEFAULT_MODEL);
}

#[test]
#[ignore = "200 machines × 200 realisations: the figures of docs/uncertainty.md"]
fn task_specific_uncertainty_covers_the_truth_200_machines() {
    check("default virtual CMM", 200, DEFAULT_MODEL);
    check(
        "CMM with twice the geometric errors",
        200,
        "[ippdme.model]\ngeometric_error_scale = 2\nprobe_noise_um = 0.5\n",
    );
}

/// Without the machine's errors (the fit's scatter alone) the coverage is far below 95 %: the
/// reason for the task-specific method (the issue measured 36 % through the server).
#[test]
fn fit_residual_uncertainty_alone_does_not_cover() {
    let model = MachineModel::from_toml(Path::new("m.toml"), DEFAULT_MODEL).unwrap();
    let mut inside = 0;
    let mut n = 0;
    for seed in 1..=20u64 {
        let mut cfg = model.cmm.clone().unwrap();
        cfg.model.seed = 5000 + seed;
        let truth = Point3::new(120.0, 45.0, 30.0);
        let part = Part { solids: vec![(None, Solid::Sphere { center: truth, radius: 12.5 })] };
        let plan = SphereProbing {
            near_mm: truth,
            diameter_mm: 25.0,
            points: 25,
            feed_mm_s: 1.0,
            clearance_mm: 2.0,
            tip_radius_mm: 1.5,
        };
        let mut m = SimulatedCmm::new(&cfg, Some(part), 1.5);
        let s = probe_sphere(&mut m, &plan).unwrap();
        let e = s.center_mm - truth;
        for k in 0..3 {
            n += 1;
            inside += usize::from(e[k].abs() <= 2.0 * s.center_uncertainty_mm[k]);
        }
        n += 1;
        inside += usize::from((s.radius_mm - 12.5).abs() <= 2.0 * s.radius_uncertainty_mm);
    }
    let cov = inside as f64 / n as f64;
    eprintln!("fit residuals alone: {:.0} % of {n} within ±U", 100.0 * cov);
    assert!(cov < 0.8, "the fit's scatter alone covered {cov}: the machine model adds nothing?");
}

#[test]
fn iso10360_datasheet_gives_an_uncertainty_that_grows_with_the_mpe() {
    let truth = Point3::new(0.0, 0.0, 0.0);
    let plan = SphereProbing {
        near_mm: truth,
        diameter_mm: 25.0,
        points: 25,
        feed_mm_s: 1.0,
        clearance_mm: 2.0,
        tip_radius_mm: 1.5,
    };
    let u_of = |text: &str| {
        let m = MachineModel::from_toml(Path::new("iso.toml"), text).unwrap();
        sphere_uncertainty(&m, &plan, truth, 12.5, Vector3::zeros(), 0.0, MonteCarlo::default()).unwrap()
    };
    let small = u_of("[iso10360]\nmpe_e_um = [1.5, 333]\nmpe_p_um = 1.5\n");
    let large = u_of("[iso10360]\nmpe_e_um = [3, 150]\nmpe_p_um = 4\n");
    assert!(small.center_mm.max() > 0.0 && small.radius_mm > 0.0);
    assert!(large.radius_mm > 2.0 * small.radius_mm, "{small:?} {large:?}");
    // A probing error uniform within ±P/2 on 25 points: the radius' u is of order P/(2√3·√25)…
    // and below P/2 (the largest single-point error).
    assert!(small.radius_mm < 0.75e-3, "{}", small.radius_mm);
    assert!(small.basis.contains("ISO 10360"));
}

#[test]
fn machine_model_files_are_checked() {
    let bad = |text: &str, needle: &str| {
        let e = MachineModel::from_toml(Path::new("m.toml"), text).unwrap_err();
        assert!(e.is_user_input(), "{e}");
        assert!(e.to_string().contains(needle), "{e} does not name {needle}");
    };
    bad("", "names no machine model");
    bad("[iso10360]\nmpe_e_um = [1.5, 333]\n", "mpe_p_um");
    bad("[iso10360]\nmpe_e_um = [1.5, 0]\nmpe_p_um = 2\n", "K");
    bad("[iso10360]\nmpe_e_um = [1.5, 300]\nmpe_p_um = 2\nextra = 1\n", "extra");
    bad("[ippdme.model]\nprobe_noize_um = 1\n", "probe_noize_um");
    bad("[ippdme]\nvolume_min_mm = [0, 0, 0]\n", "[ippdme.model]");
    bad("[other]\n", "other");
    let both = MachineModel::from_toml(
        Path::new("m.toml"),
        "[ippdme.model]\nseed = 4\n[iso10360]\nmpe_e_um = [1.5, 333]\nmpe_p_um = 1.5\n",
    )
    .unwrap();
    assert!(both.cmm.is_some() && both.iso10360.is_some());
}

#[test]
fn the_uncertainty_is_deterministic() {
    let m = MachineModel::from_toml(Path::new("m.toml"), DEFAULT_MODEL).unwrap();
    let plan = SphereProbing {
        near_mm: Point3::new(10.0, -5.0, 20.0),
        diameter_mm: 25.0,
        points: 25,
        feed_mm_s: 1.0,
        clearance_mm: 2.0,
        tip_radius_mm: 1.5,
    };
    let go = || {
        sphere_uncertainty(&m, &plan, plan.near_mm, 12.5, Vector3::zeros(), 0.0, MonteCarlo::default())
            .unwrap()
    };
    let (a, b) = (go(), go());
    assert_eq!(a.center_mm, b.center_mm);
    assert_eq!(a.radius_mm, b.radius_mm);
    assert_eq!(a.runs, 200);
}

/// `somac inspect` on machines drawn from the default CMM model: three Ø 20 mm bores in a plate,
/// 8 points each; the task-specific U of each hole's X, Y and diameter covers the true bore.
#[test]
fn inspection_uncertainty_covers_the_truth() {
    use truepos_ippdme::part::CylinderSide;
    use truepos_somac::inspect::{inspect, Hole, InspectPlan};
    let model = MachineModel::from_toml(Path::new("m.toml"), DEFAULT_MODEL).unwrap();
    let tops =
        [Point3::new(100.0, 50.0, 0.0), Point3::new(-250.0, 180.0, 0.0), Point3::new(300.0, -320.0, 0.0)];
    let plan = InspectPlan {
        depth_mm: 5.0,
        points: 8,
        feed_mm_s: 1.0,
        clearance_mm: 1.5,
        tip_radius_mm: 1.5,
        safe_height_mm: 10.0,
        start_angle_deg: 0.0,
    };
    let (mut inside, mut n, mut ratios) = (0, 0, Vec::new());
    for seed in 1..=30u64 {
        let mut cfg = model.cmm.clone().unwrap();
        cfg.model.seed = 7000 + seed;
        // The real bores: 30–60 µm off nominal, diameters 20 ± 0.01.
        let truth: Vec<(Point3, f64)> = tops
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let f = (seed as f64 * 0.37 + i as f64).sin();
                (Point3::new(t.x + 0.04 * f, t.y - 0.03 * f, t.z), 20.0 + 0.01 * f)
            })
            .collect();
        let mut solids = vec![(None, Solid::HalfSpace { point: Point3::origin(), normal: Vector3::z() })];
        for (c, d) in &truth {
            solids.push((
                None,
                Solid::Cylinder {
                    point: *c,
                    axis: Vector3::z(),
                    radius: 0.5 * d,
                    side: CylinderSide::Inside,
                    ends: None,
                },
            ));
        }
        let holes: Vec<Hole> = tops
            .iter()
            .enumerate()
            .map(|(i, t)| Hole { id: format!("H{i}"), line: None, nominal_mm: *t, diameter_mm: 20.0 })
            .collect();
        let mut m = SimulatedCmm::new(&cfg, Some(Part { solids }), plan.tip_radius_mm);
        let got = inspect(&mut m, &holes, &plan).unwrap();
        let u = truepos_vcmm::inspection_uncertainty(&model, &plan, &got, MonteCarlo::default()).unwrap();
        for ((r, u), (c, d)) in got.holes.iter().zip(&u).zip(&truth) {
            let errs = [
                (r.measured_mm.x - c.x, 2.0 * u.center_xy_mm[0]),
                (r.measured_mm.y - c.y, 2.0 * u.center_xy_mm[1]),
                (r.diameter_mm - d, 2.0 * u.diameter_mm),
            ];
            for (e, big_u) in errs {
                n += 1;
                inside += usize::from(e.abs() <= big_u);
                ratios.push(e.abs() / big_u);
            }
        }
    }
    ratios.sort_by(f64::total_cmp);
    let cov = inside as f64 / n as f64;
    let median = ratios[n / 2];
    eprintln!(
        "somac inspect: {:.1} % of {n} comparisons within ±U, median |error|/U = {median:.2}",
        100.0 * cov
    );
    assert!((0.90..=0.99).contains(&cov), "coverage {cov}");
    assert!(median >= 0.15, "inflated: {median}");
}
