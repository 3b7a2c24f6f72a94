//! Task-specific uncertainty through the real interfaces (issue: "uncertainty you can sign"):
//! machines drawn from the virtual CMM's error model are `truepos ippdme serve` processes with
//! different `[ippdme.model] seed`s; `truepos probe sphere --controller ippdme://…
//! --machine-model FILE` measures a Ø 25 mm sphere of known position on each, and the truth must
//! lie within ± `expanded_uncertainty` in about 95 % of the comparisons (centre coordinates and
//! radius). The always-on test uses 20 machines; `--ignored` the 100 of docs/uncertainty.md.

mod common;

use std::path::Path;
use std::process::Command;

fn truepos() -> Command {
    Command::new(env!("CARGO_BIN_EXE_truepos"))
}

/// A server on a free loopback port with `part` and `machine`; homed, Probe1 chosen.
fn server(part: &Path, machine: &Path) -> (std::process::Child, String) {
    let dir = part.parent().unwrap_or(Path::new("."));
    let (child, addr) = common::ippdme_server(dir, part, &["--machine".as_ref(), machine.as_os_str()]);
    common::home_cmm(&addr, Some("Probe1"));
    (child, addr)
}

fn stop(mut child: std::process::Child) {
    let _ = Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
    let _ = child.wait();
}

fn arr(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

struct Tally {
    task_inside: usize,
    fit_inside: usize,
    n: usize,
    ratios: Vec<f64>,
    mc_s: Vec<f64>,
}

fn run_machines(machines: u64) -> Tally {
    let dir = tempfile::tempdir().unwrap();
    let truth = [10.0, -5.0, 20.0];
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [10, -5, 20]\ndiameter_mm = 25\n").unwrap();
    // What the user knows: the class of their machine (the default model), not its seed.
    let model = dir.path().join("model.toml");
    std::fs::write(&model, "[ippdme.model]\n").unwrap();
    let mut t = Tally { task_inside: 0, fit_inside: 0, n: 0, ratios: Vec::new(), mc_s: Vec::new() };
    for seed in 1..=machines {
        let machine = dir.path().join(format!("cmm{seed}.toml"));
        std::fs::write(&machine, format!("[ippdme.model]\nseed = {seed}\n")).unwrap();
        let (child, addr) = server(&part, &machine);
        let probe = |with_model: bool| {
            let mut c = truepos();
            c.args(["probe", "sphere", "--controller", &format!("ippdme://{addr}")]).args([
                "--near=10.2,-5.1,20.1",
                "--diameter-mm",
                "25",
                "--tip-diameter-mm",
                "3",
                "--json",
            ]);
            if with_model {
                c.arg("--machine-model").arg(&model);
            }
            let out = c.output().unwrap();
            assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
            (
                serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap(),
                String::from_utf8_lossy(&out.stderr).to_string(),
            )
        };
        let (task, task_err) = probe(true);
        let (fit, fit_err) = probe(false);
        stop(child);
        assert_eq!(task["uncertainty_method"], "task-specific");
        assert!(task["monte_carlo_runs"].as_u64().unwrap() >= 200);
        assert_eq!(task["coverage_factor"].as_f64(), Some(2.0));
        assert!(!task_err.contains("warning"), "{task_err}");
        assert_eq!(fit["uncertainty_method"], "fit-residuals");
        assert_eq!(fit["monte_carlo_runs"].as_u64(), Some(0));
        assert!(fit_err.contains("warning: no --machine-model"), "{fit_err}");
        t.mc_s.push(task["monte_carlo_s"].as_f64().unwrap());
        for (j, inside) in [(&task, &mut t.task_inside), (&fit, &mut t.fit_inside)] {
            let c = arr(&j["center_mm"]);
            let u = arr(&j["expanded_uncertainty"]["center_mm"]);
            let mut errs: Vec<(f64, f64)> = (0..3).map(|k| (c[k] - truth[k], u[k])).collect();
            errs.push((
                j["radius_mm"].as_f64().unwrap() - 12.5,
                j["expanded_uncertainty"]["radius_mm"].as_f64().unwrap(),
            ));
            for (e, u) in errs {
                *inside += usize::from(e.abs() <= u);
                if std::ptr::eq(j, &task) {
                    t.ratios.push(e.abs() / u);
                }
            }
        }
        t.n += 4;
    }
    t.ratios.sort_by(f64::total_cmp);
    t
}

fn report(t: &Tally) -> (f64, f64, f64) {
    let cov = t.task_inside as f64 / t.n as f64;
    let fit = t.fit_inside as f64 / t.n as f64;
    let median = t.ratios[t.ratios.len() / 2];
    let mut mc = t.mc_s.clone();
    mc.sort_by(f64::total_cmp);
    eprintln!(
        "probe sphere through ippdme://, {} comparisons: task-specific {:.1} % within ±U (median |error|/U {median:.2}), fit residuals alone {:.1} %; Monte Carlo median {:.3} s, max {:.3} s",
        t.n,
        100.0 * cov,
        100.0 * fit,
        mc[mc.len() / 2],
        mc[mc.len() - 1]
    );
    (cov, fit, median)
}

#[test]
fn probe_sphere_task_specific_uncertainty_covers_the_truth_through_ippdme() {
    let t = run_machines(20);
    let (cov, fit, median) = report(&t);
    // 80 comparisons: at 95 % true coverage, fewer than 72 inside (90 %) has probability < 3 %.
    assert!(cov >= 0.9, "coverage {cov}");
    assert!(median >= 0.15, "U inflated: median |error|/U {median}");
    assert!(fit < 0.8, "fit residuals alone covered {fit}");
    assert!(t.mc_s.iter().all(|&s| s < 2.0), "Monte Carlo slower than 2 s: {:?}", t.mc_s);
}

#[test]
#[ignore = "100 server processes: the figure of docs/uncertainty.md"]
fn probe_sphere_task_specific_uncertainty_covers_the_truth_100_machines() {
    let t = run_machines(100);
    let (cov, _, median) = report(&t);
    assert!((0.90..=0.99).contains(&cov), "coverage {cov}");
    assert!(median >= 0.15, "U inflated: median |error|/U {median}");
}

#[test]
fn a_bad_machine_model_is_exit_2_before_any_motion() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.toml");
    std::fs::write(&model, "[iso10360]\nmpe_e_um = [1.5, 333]\nmpe_p = 2\n").unwrap();
    // No server at this address: the model is refused before the controller is opened.
    let out = truepos()
        .args([
            "probe",
            "sphere",
            "--controller",
            "ippdme://127.0.0.1:9",
            "--near=0,0,0",
            "--diameter-mm",
            "25",
        ])
        .arg("--machine-model")
        .arg(&model)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("model.toml") && err.contains("mpe_p"), "{err}");
}

/// `somac inspect --controller ippdme://… --machine-model FILE`: each hole's U is task-specific
/// and covers the part file's bore (3 machines × 2 holes × X, Y, diameter).
#[test]
fn somac_inspect_reports_task_specific_uncertainty_through_ippdme() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(
        &part,
        "[[plane]]\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n\n[[cylinder]]\npoint_mm = [100.02, 49.97, 0]\naxis = [0, 0, 1]\ndiameter_mm = 20.004\nside = \"inside\"\n\n[[cylinder]]\npoint_mm = [-150, 80.03, 0]\naxis = [0, 0, 1]\ndiameter_mm = 19.998\nside = \"inside\"\n",
    )
    .unwrap();
    let holes = dir.path().join("holes.csv");
    std::fs::write(&holes, "id,x_mm,y_mm,z_mm\nA,100,50,0\nB,-150,80,0\n").unwrap();
    let model = dir.path().join("model.toml");
    std::fs::write(&model, "[ippdme.model]\n").unwrap();
    let truth = [(100.02, 49.97, 20.004), (-150.0, 80.03, 19.998)];
    let (mut inside, mut n) = (0, 0);
    for seed in 1..=3 {
        let machine = dir.path().join(format!("cmm{seed}.toml"));
        std::fs::write(&machine, format!("[ippdme.model]\nseed = {}\n", 40 + seed)).unwrap();
        let (child, addr) = server(&part, &machine);
        let out = truepos()
            .current_dir(dir.path())
            .args(["somac", "inspect", "--controller", &format!("ippdme://{addr}"), "--holes"])
            .arg(&holes)
            .args([
                "--diameter-mm",
                "20",
                "--tip-diameter-mm",
                "3",
                "--points",
                "8",
                "--json",
                "--machine-model",
            ])
            .arg(&model)
            .output()
            .unwrap();
        stop(child);
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(j["uncertainty_method"], "task-specific");
        assert!(j["monte_carlo_runs"].as_u64().unwrap() >= 200);
        for (h, (x, y, d)) in j["holes"].as_array().unwrap().iter().zip(truth) {
            let m = arr(&h["measured_mm"]);
            let u = arr(&h["expanded_uncertainty"]["center_xy_mm"]);
            let ud = h["expanded_uncertainty"]["diameter_mm"].as_f64().unwrap();
            for (e, u) in [(m[0] - x, u[0]), (m[1] - y, u[1]), (h["diameter_mm"].as_f64().unwrap() - d, ud)] {
                n += 1;
                inside += usize::from(e.abs() <= u);
                assert!(u > 0.0 && u < 0.02, "U {u}");
            }
        }
    }
    eprintln!("somac inspect through ippdme://: {inside} of {n} within ±U");
    assert!(inside >= n - 2, "{inside} of {n}");
}

/// `dmis run --machine-model` through `truepos ippdme serve` machines with different seeds: every
/// actual feature and tolerance has its U, the truth of the part lies within it (the coverage
/// figures are the in-process test's, crates/cell/tests/vcmm_coverage_dmis_head.rs); without a
/// model, the warning and the fits' scatter.
#[test]
fn dmis_run_reports_task_specific_uncertainty_through_ippdme() {
    let dir = tempfile::tempdir().unwrap();
    let programs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../dmis/tests/programs");
    let program = dir.path().join("full.dms");
    std::fs::copy(programs.join("full.dms"), &program).unwrap();
    let part = programs.join("full_part.toml");
    let model = dir.path().join("model.toml");
    std::fs::write(&model, "[ippdme.model]\n").unwrap();
    let (mut inside, mut n) = (0, 0);
    for seed in 1..=3 {
        let machine = dir.path().join(format!("cmm{seed}.toml"));
        std::fs::write(&machine, format!("[ippdme.model]\nseed = {}\n", 60 + seed)).unwrap();
        let (child, addr) = server(&part, &machine);
        let mut cmd = truepos();
        cmd.current_dir(dir.path()).args(["dmis", "run"]).arg(&program).args([
            "--controller",
            &format!("ippdme://{addr}"),
            "--sensor",
            "P1=Probe1",
            "--json",
        ]);
        if seed < 3 {
            cmd.arg("--machine-model").arg(&model);
        }
        let out = cmd.output().unwrap();
        stop(child);
        let err = String::from_utf8_lossy(&out.stderr);
        // T(TIGHT) (±0.1 µm on a diameter) is OUTOL on any real machine: exit 1.
        assert_eq!(out.status.code(), Some(1), "{err}");
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        if seed == 3 {
            assert!(err.contains("no --machine-model"), "{err}");
            assert_eq!(j["uncertainty_method"], "fit-residuals");
            assert_eq!(j["monte_carlo_runs"], 0);
            assert!(j["tolerances"][0]["expanded_uncertainty_mm"].is_null());
            continue;
        }
        assert!(!err.contains("no --machine-model"), "{err}");
        assert_eq!(j["uncertainty_method"], "task-specific");
        assert!(j["monte_carlo_runs"].as_u64().unwrap() >= 200);
        assert!(j["monte_carlo_s"].as_f64().unwrap() < 10.0);
        let feature = |label: &str| {
            j["features"].as_array().unwrap().iter().find(|f| f["label"] == label).unwrap().clone()
        };
        let pin = feature("PIN");
        let c = arr(&pin["center_mm"]);
        let u = arr(&pin["expanded_uncertainty"]["center_mm"]);
        let ud = pin["expanded_uncertainty"]["diameter_mm"].as_f64().unwrap();
        let sph = feature("SPH");
        let cs = arr(&sph["center_mm"]);
        let us = arr(&sph["expanded_uncertainty"]["center_mm"]);
        let mut checks = vec![
            (c[0] - 50.0, u[0]),
            (c[1] - 50.0, u[1]),
            (pin["diameter_mm"].as_f64().unwrap() - 12.0, ud),
            (cs[0] - 50.0, us[0]),
            (cs[1] - 120.0, us[1]),
            (cs[2] - 20.0, us[2]),
        ];
        for t in j["tolerances"].as_array().unwrap() {
            let truth = match t["label"].as_str().unwrap() {
                "DI" => 100.0,
                "AN" => 90.0,
                _ => 0.0,
            };
            let (v, big_u) = match t["value_mm"].as_f64() {
                Some(v) => (v, t["expanded_uncertainty_mm"].as_f64().unwrap()),
                None => (t["value_deg"].as_f64().unwrap(), t["expanded_uncertainty_deg"].as_f64().unwrap()),
            };
            checks.push((v - truth, big_u));
        }
        for (e, big_u) in checks {
            n += 1;
            inside += usize::from(e.abs() <= big_u);
            assert!(big_u > 0.0 && big_u < 0.05, "U {big_u}");
        }
    }
    eprintln!("dmis run through ippdme://: {inside} of {n} within ±U");
    assert!(inside >= n - 3, "{inside} of {n}");
}

/// `head-offset acquire --machine-model` on the virtual machine tool (its truth in the JSON):
/// the offset with its task-specific U; without a model, the warning and the fit's scatter;
/// a component the orientations do not determine has none.
#[test]
fn head_offset_acquire_reports_task_specific_uncertainty() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.toml");
    std::fs::write(&model, "[ippdme.model]\n").unwrap();
    let run = |seed: u64, orientations: &[&str], with_model: bool| {
        let mut cmd = truepos();
        cmd.current_dir(dir.path()).args([
            "head-offset",
            "acquire",
            "--near=150,20,40",
            "--diameter-mm",
            "25",
            "--tip-diameter-mm",
            "3",
            "--nominal-offset-mm=30,0,-150",
            "--table-center-mm=100,0,0",
            "--seed",
            &seed.to_string(),
            "--output",
            &format!("points{seed}.csv"),
            "--json",
        ]);
        for o in orientations {
            cmd.arg(format!("--orientation={o}"));
        }
        if with_model {
            cmd.arg("--machine-model").arg(&model);
        }
        let out = cmd.output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (j, String::from_utf8_lossy(&out.stderr).to_string())
    };
    let both = ["0,0", "90,0", "0,120", "90,120", "0,240", "90,240"];
    let (mut inside, mut n) = (0, 0);
    for seed in 1..=4 {
        let (j, err) = run(seed, &both, true);
        assert!(!err.contains("no --machine-model"), "{err}");
        assert_eq!(j["uncertainty_method"], "task-specific");
        assert!(j["monte_carlo_runs"].as_u64().unwrap() >= 200);
        let h = &j["head_offset"];
        assert_eq!(h["uncertainty_method"], "task-specific");
        let off = arr(&h["offset_mm"]);
        let big_u = arr(&h["expanded_uncertainty_mm"]);
        let truth = arr(&j["virtual_truth"]["head_offset_mm"]);
        for k in 0..3 {
            n += 1;
            inside += usize::from((off[k] - truth[k]).abs() <= big_u[k]);
            assert!(big_u[k] > 0.0 && big_u[k] < 0.05, "U {big_u:?}");
        }
    }
    eprintln!("head-offset acquire: {inside} of {n} within ±U");
    assert!(inside >= n - 2, "{inside} of {n}");
    // Without a model: the warning, the fit's scatter; B only: Y not observable, no U.
    let (j, err) = run(9, &["0,0", "45,0", "90,0"], false);
    assert!(err.contains("no --machine-model"), "{err}");
    assert_eq!(j["uncertainty_method"], "fit-residuals");
    assert_eq!(j["monte_carlo_runs"], 0);
    assert_eq!(j["head_offset"]["observable"], serde_json::json!([true, false, true]));
    assert!(j["head_offset"]["expanded_uncertainty_mm"][1].is_null());
    assert!(j["head_offset"]["expanded_uncertainty_mm"][0].as_f64().unwrap() > 0.0);
}
