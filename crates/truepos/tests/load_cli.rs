//! `truepos load` and `truepos simulate load` through the built binary: the virtual CMM end to
//! end, hand-made imported maps against hand calculations, plate theory, and bad input.

mod common;
use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

fn ok_json(out: &Output) -> Value {
    assert_eq!(out.status.code(), Some(0), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    (header, lines.map(|l| l.split(',').map(String::from).collect()).collect())
}

#[test]
fn virtual_cmm_load_error_removed_by_95_percent() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path().join("sim");
    let out = run(&["simulate", "load", "--out", s(&dir), "--seed", "4"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let (bed, load, points, map, corrected) = (
        dir.join("bed.toml"),
        dir.join("load.toml"),
        dir.join("points.csv"),
        dir.join("map.csv"),
        dir.join("corrected.csv"),
    );
    ok_json(&run(&["load", "map", "--bed", s(&bed), "--output", s(&map), "--json"]));
    let j = ok_json(&run(&[
        "load",
        "correct",
        "--map",
        s(&map),
        "--load",
        s(&load),
        "--bed",
        s(&bed),
        "--points",
        s(&points),
        "--output",
        s(&corrected),
        "--json",
    ]));
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    // Forces from statics (exact three-point solution) equal the simulator's.
    for (a, b) in f64s(&j["forces_n"]).iter().zip(f64s(&truth["forces_n"])) {
        assert!((a - b).abs() < 1e-6 * b, "{a} vs {b}");
    }
    let (h, rows) = csv_rows(&corrected);
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    let (ix, iy, iz, iid) = (col("x_mm"), col("y_mm"), col("z_mm"), col("id"));
    let tp = truth["true_points_mm"].as_array().unwrap();
    let err = truth["error_um"].as_array().unwrap();
    let noise = truth["noise_um"].as_array().unwrap();
    let ids = truth["ids"].as_array().unwrap();
    let (mut sb, mut sa, mut mb, mut ma) = (0.0, 0.0, 0.0f64, 0.0f64);
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r[iid], ids[k].as_str().unwrap(), "ids passed through in order");
        let c = [r[ix].parse::<f64>().unwrap(), r[iy].parse::<f64>().unwrap(), r[iz].parse::<f64>().unwrap()];
        let t = f64s(&tp[k]);
        let e = f64s(&err[k]);
        let n = f64s(&noise[k]);
        // Load-induced error after correction: corrected − true − probing noise (the noise is
        // not load-induced; no correction can remove it).
        let after: f64 = (0..3).map(|i| ((c[i] - t[i]) * 1e3 - n[i]).powi(2)).sum::<f64>().sqrt();
        let before: f64 = e.iter().map(|v| v * v).sum::<f64>().sqrt();
        sb += before * before;
        sa += after * after;
        mb = mb.max(before);
        ma = ma.max(after);
    }
    let n = rows.len() as f64;
    let (rb, ra) = ((sb / n).sqrt(), (sa / n).sqrt());
    eprintln!("virtual CMM: load-induced error before rms {rb:.3} µm max {mb:.3} µm; after rms {ra:.4} µm max {ma:.4} µm ({:.2} % removed)", 100.0 * (1.0 - ra / rb));
    assert!(rb > 1.0, "the scenario must have µm-size errors (rms {rb} µm)");
    assert!(ra <= 0.05 * rb && ma <= 0.05 * mb);
}

/// A hand-made imported map: 2 × 2 load nodes (0/1000 mm), portal y 0/500/1000.
/// pitch = 1 + 10 i + 100 j + 1000 k µrad, roll = 2 + 20 i − 50 j + 300 k µrad per 1000 N.
fn hand_map(dir: &Path) -> PathBuf {
    let mut t = String::from("# from an outside FE package\n# unit_load_n = 1000\nroll_urad,pitch_urad,portal_y_mm,load_y_mm,load_x_mm\n");
    for (i, x) in [0.0, 1000.0].iter().enumerate() {
        for (j, y) in [0.0, 1000.0].iter().enumerate() {
            for (k, py) in [0.0, 500.0, 1000.0].iter().enumerate() {
                let (i, j, k) = (i as f64, j as f64, k as f64);
                t.push_str(&format!(
                    "{},{},{py},{y},{x}\n",
                    2.0 + 20.0 * i - 50.0 * j + 300.0 * k,
                    1.0 + 10.0 * i + 100.0 * j + 1000.0 * k
                ));
            }
        }
    }
    write(dir, "map.csv", &t)
}

const BED: &str = "[portal]\nrail_x_mm = [0, 1000]\nrail_height_mm = 100\nbearing_span_mm = 200\ny_range_mm = [0, 1000]\ny_step_mm = 500\n";

#[test]
fn imported_map_superposition_and_correction_match_hand_calculation() {
    let d = tempfile::tempdir().unwrap();
    let map = hand_map(d.path());
    // Explicit forces: 2000 N at (250, 750), 500 N at (1000, 0).
    let load = write(
        d.path(),
        "load.toml",
        "[[rest]]\nx_mm = 250\ny_mm = 750\nforce_n = 2000\n[[rest]]\nx_mm = 1000\ny_mm = 0\nforce_n = 500\n",
    );
    let j = ok_json(&run(&["load", "curves", "--map", s(&map), "--load", s(&load), "--json"]));
    // By hand: load 1 (fx .25, fy .75) pitch 1 + 2.5 + 75 + 1000k, × 2; load 2 (i = 1, j = 0)
    // pitch 11 + 1000k, × 0.5 → 162.5 + 2500k. Roll: (2 + 5 − 37.5 + 300k)·2 + (22 + 300k)·0.5
    // = −50 + 750k.
    assert_eq!(f64s(&j["portal_y_mm"]), vec![0.0, 500.0, 1000.0]);
    for (k, (p, r)) in f64s(&j["pitch_urad"]).iter().zip(f64s(&j["roll_urad"])).enumerate() {
        let k = k as f64;
        // Rounding of a few sums of doubles: 1e-9 µrad.
        assert!((p - (162.5 + 2500.0 * k)).abs() < 1e-9, "{p}");
        assert!((r - (-50.0 + 750.0 * k)).abs() < 1e-9, "{r}");
    }
    assert_eq!(f64s(&j["forces_n"]), vec![2000.0, 500.0]);
    // Correction of p = (800, 250, 400) with o = (500, 250, 100): θ at y = 250 (halfway between
    // nodes 0 and 1): pitch 1412.5, roll 325 µrad; e = (θy·dz, −θx·dz, −θy·dx) with dx = dz = 300
    // → (97.5, −423.75, −97.5) µm; the applied correction is +e (contract: physical rotations,
    // corrected point p + e).
    let bed = write(d.path(), "bed.toml", BED);
    let pts = write(d.path(), "pts.csv", "id,z_mm,x_mm,y_mm,note\nA,400,800,250,\"keep, me\"\n");
    let outp = d.path().join("out.csv");
    ok_json(&run(&[
        "load",
        "correct",
        "--map",
        s(&map),
        "--load",
        s(&load),
        "--bed",
        s(&bed),
        "--points",
        s(&pts),
        "--output",
        s(&outp),
        "--json",
    ]));
    let text = std::fs::read_to_string(&outp).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "id,z_mm,x_mm,y_mm,note,dx_um,dy_um,dz_um");
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(row[0], "A");
    assert_eq!(&row[4..6], &["\"keep", " me\""], "quoted pass-through column kept");
    let v: Vec<f64> =
        [row[1], row[2], row[3], row[6], row[7], row[8]].iter().map(|x| x.parse().unwrap()).collect();
    let want = [400.0 - 0.0975, 800.0 + 0.0975, 250.0 - 0.42375, 97.5, -423.75, -97.5];
    for (a, b) in v.iter().zip(want) {
        assert!((a - b).abs() < 1e-9, "{v:?} vs {want:?}");
    }
    // Statics from mass/CoG: three points, by hand 5500/2500/2000 N (see the statics unit test).
    let load3 = write(
        d.path(),
        "load3.toml",
        "weight_n = 10000\ncog_mm = [250, 100]\nrest_points_mm = [[0, 0], [1000, 0], [0, 500]]\n",
    );
    let j = ok_json(&run(&["load", "curves", "--map", s(&map), "--load", s(&load3), "--json"]));
    for (a, b) in f64s(&j["forces_n"]).iter().zip([5500.0, 2500.0, 2000.0]) {
        assert!((a - b).abs() < 1e-9);
    }
}

#[test]
fn bad_load_cases_maps_and_beds_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let map = hand_map(d.path());
    let bed = write(d.path(), "bed.toml", BED);
    let curves = |load: &Path| run(&["load", "curves", "--map", s(&map), "--load", s(load), "--json"]);
    let l = write(
        d.path(),
        "outside.toml",
        "mass_kg = 500\ncog_mm = [-100, 100]\nrest_points_mm = [[0, 0], [1000, 0], [0, 500]]\n",
    );
    expect_input_error(&curves(&l), &["outside.toml", "tension"]);
    let l = write(
        d.path(),
        "two.toml",
        "mass_kg = 500\ncog_mm = [300, 100]\nrest_points_mm = [[0, 0], [1000, 0]]\n",
    );
    expect_input_error(&curves(&l), &["two.toml", "cannot carry"]);
    let l = write(d.path(), "neg.toml", "[[rest]]\nx_mm = 1\ny_mm = 1\nforce_n = -5\n");
    expect_input_error(&curves(&l), &["neg.toml", "negative"]);
    let l = write(
        d.path(),
        "off.toml",
        "mass_kg = 500\ncog_mm = [600, 500]\nrest_points_mm = [[200, 200], [1200, 500], [200, 800]]\n",
    );
    expect_input_error(&curves(&l), &["off.toml", "does not cover"]);
    // Loads beyond any table (hostile audit 2 of issue 31, F23: 1e300 kg gave 3e300 N forces).
    for (name, text, needles) in [
        (
            "heavy.toml",
            "mass_kg = 1e300\ncog_mm = [300, 100]\nrest_points_mm = [[0, 0], [1000, 0], [0, 500]]\n",
            ["heavy.toml:1:", "above 1000000 kg"],
        ),
        (
            "heavy_n.toml",
            "weight_n = 1e12\ncog_mm = [300, 100]\nrest_points_mm = [[0, 0], [1000, 0], [0, 500]]\n",
            ["heavy_n.toml:1:", "above 9806650 N"],
        ),
        (
            "heavy_rest.toml",
            "[[rest]]\nx_mm = 1\ny_mm = 1\nforce_n = 1e9\n",
            ["heavy_rest.toml:4:", "above 9806650 N"],
        ),
    ] {
        let l = write(d.path(), name, text);
        expect_input_error(&curves(&l), &needles);
    }
    // A point whose portal position is outside the map's portal range: line named, no output.
    let l =
        write(d.path(), "ok.toml", "weight_n = 1000\ncog_mm = [500, 500]\nrest_points_mm = [[500, 500]]\n");
    let pts = write(d.path(), "pts.csv", "x_mm,y_mm,z_mm\n1,2,3\n1,1500,3\n");
    let outp = d.path().join("never.csv");
    let o = run(&[
        "load",
        "correct",
        "--map",
        s(&map),
        "--load",
        s(&l),
        "--bed",
        s(&bed),
        "--points",
        s(&pts),
        "--output",
        s(&outp),
    ]);
    expect_input_error(&o, &["pts.csv:3", "portal y"]);
    assert!(!outp.exists());
    // Maps: no unit-load comment; an incomplete grid.
    let text = std::fs::read_to_string(&map).unwrap();
    let m = write(d.path(), "nounit.csv", text.replace("# unit_load_n = 1000\n", ""));
    expect_input_error(
        &run(&["load", "curves", "--map", s(&m), "--load", s(&l)]),
        &["nounit.csv", "unit_load_n"],
    );
    let m = write(
        d.path(),
        "holes.csv",
        text.lines().take(text.lines().count() - 1).collect::<Vec<_>>().join("\n"),
    );
    expect_input_error(
        &run(&["load", "curves", "--map", s(&m), "--load", s(&l)]),
        &["holes.csv", "complete grid"],
    );
    // A singular FE model: two supports cannot hold the plate.
    let b = write(d.path(), "two_pads.toml", format!("[bed]\nsize_x_mm = 1000\nsize_y_mm = 1000\nthickness_mm = 100\nyoungs_modulus_mpa = 50000\npoisson = 0.2\nsupports_mm = [[100, 100], [900, 900]]\n{}", BED.replace("y_range_mm = [0, 1000]", "y_range_mm = [200, 800]")));
    let outp = d.path().join("map_never.csv");
    expect_input_error(
        &run(&["load", "map", "--bed", s(&b), "--output", s(&outp)]),
        &["two_pads.toml", "singular"],
    );
    assert!(!outp.exists());
}

#[test]
fn deflection_matches_navier_plate_theory() {
    // Thin (t/a = 1/100) simply supported steel plate, 1 kN at the centre: Kirchhoff-Navier
    // series; Mindlin's shear term is ~1e-3 of the deflection at these distances from the load.
    let d = tempfile::tempdir().unwrap();
    let bed = write(d.path(), "ss.toml", "[bed]\nsize_x_mm = 1000\nsize_y_mm = 1000\nthickness_mm = 10\nyoungs_modulus_mpa = 200000\npoisson = 0.3\nsupports = \"simply-supported-edges\"\n");
    let load =
        write(d.path(), "c.toml", "weight_n = 1000\ncog_mm = [500, 500]\nrest_points_mm = [[500, 500]]\n");
    let at = write(d.path(), "at.csv", "x_mm,y_mm\n250,500\n500,250\n750,750\n100,900\n");
    let j = ok_json(&run(&[
        "load",
        "deflection",
        "--bed",
        s(&bed),
        "--load",
        s(&load),
        "--at",
        s(&at),
        "--json",
    ]));
    let uz = f64s(&j["uz_mm"]);
    let dflex = 200000.0 * 1000.0 / (12.0 * (1.0 - 0.09));
    let pi = std::f64::consts::PI;
    let navier = |x: f64, y: f64| {
        let mut w = 0.0;
        for m in 1..400 {
            for n in 1..400 {
                let (m, n) = (m as f64, n as f64);
                let s = (m * pi * 0.5).sin() * (n * pi * 0.5).sin();
                if s == 0.0 {
                    continue;
                }
                w += s * (m * pi * x / 1000.0).sin() * (n * pi * y / 1000.0).sin()
                    / ((m / 1000.0).powi(2) + (n / 1000.0).powi(2)).powi(2);
            }
        }
        4.0 * 1000.0 / (pi.powi(4) * dflex * 1e6) * w
    };
    for (u, (x, y)) in uz.iter().zip([(250.0, 500.0), (500.0, 250.0), (750.0, 750.0), (100.0, 900.0)]) {
        let w = navier(x, y);
        // FE (MITC4, automatic mesh) vs series: 2 % (discretisation + shear).
        assert!((u + w).abs() < 0.02 * w, "({x}, {y}): uz {u} vs −{w}");
    }
}

#[test]
fn combined_geometric_and_load_correction_is_the_sum_of_both() {
    let d = tempfile::tempdir().unwrap();
    let map = hand_map(d.path());
    let bed = write(d.path(), "bed.toml", BED);
    let load =
        write(d.path(), "l.toml", "weight_n = 1000\ncog_mm = [500, 500]\nrest_points_mm = [[500, 500]]\n");
    // Geometric map: Y pitch 10 µrad, X positioning 1 µm / 100 mm (hand values in comp_cli.rs).
    let mut g = String::from("axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad\n");
    for i in 0..=10 {
        let p = 100.0 * i as f64;
        g.push_str(&format!("x,{p},{},0,0,0,0,0\ny,{p},0,0,0,10,0,0\nz,{p},0,0,0,0,0,0\n", p / 100.0));
    }
    let gm = write(d.path(), "geo.csv", &g);
    let pts = write(d.path(), "p.csv", "x_mm,y_mm,z_mm\n250,500,300\n700,120,650\n");
    let read = |p: &Path| -> Vec<Vec<f64>> {
        let (_, rows) = csv_rows(p);
        rows.iter().map(|r| r[3..6].iter().map(|v| v.parse().unwrap()).collect()).collect()
    };
    let (a, b, c) = (d.path().join("load.csv"), d.path().join("geo_out.csv"), d.path().join("both.csv"));
    ok_json(&run(&[
        "load",
        "correct",
        "--map",
        s(&map),
        "--load",
        s(&load),
        "--bed",
        s(&bed),
        "--points",
        s(&pts),
        "--output",
        s(&a),
        "--json",
    ]));
    let o = run(&["comp", "correct", "--map", s(&gm), "--points", s(&pts), "--output", s(&b)]);
    assert_eq!(o.status.code(), Some(0));
    ok_json(&run(&[
        "load",
        "correct",
        "--map",
        s(&map),
        "--load",
        s(&load),
        "--bed",
        s(&bed),
        "--points",
        s(&pts),
        "--output",
        s(&c),
        "--geometric-map",
        s(&gm),
        "--json",
    ]));
    for ((x, y), z) in read(&a).iter().zip(read(&b)).zip(read(&c)) {
        for i in 0..3 {
            // Both corrections are evaluated at the indicated point and added: exact sum.
            assert!((x[i] + y[i] - z[i]).abs() < 1e-9, "{x:?} + {y:?} vs {z:?}");
        }
        assert!(
            x.iter().any(|v| v.abs() > 1.0) && y.iter().any(|v| v.abs() > 1.0),
            "both corrections are visible"
        );
    }
}
