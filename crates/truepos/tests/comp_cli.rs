//! `truepos comp` through the built binary: hand-computed corrections, pass-through, the inverse
//! to 1 nm, help text, and bad input.

mod common;
use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Y pitch (about X) 10 µrad everywhere; X positioning 1 µm per 100 mm; all else 0.
fn map_file(dir: &Path) -> PathBuf {
    let mut t = String::from("axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad\n");
    for i in (0..=10).rev() {
        let p = 100.0 * i as f64;
        t.push_str(&format!("x,{p},{},0,0,0,0,0\n", p / 100.0));
        t.push_str(&format!("y,{p},0,0,0,10,0,0\n"));
        t.push_str(&format!("z,{p},0,0,0,0,0,0\n"));
    }
    write(dir, "map.csv", &t)
}

#[test]
fn correction_matches_hand_calculation_and_passes_columns_through() {
    let d = tempfile::tempdir().unwrap();
    let map = map_file(d.path());
    let sq = write(d.path(), "sq.toml", "[squareness]\nxy_urad = 2\n");
    // Tip (250, 500, 300) with probe offset (0, 0, −100): axis positions (250, 500, 400).
    // δX = 2.5 µm along x; εY × (x_vec + z_vec + t) = (1e-5, 0, 0) × (250, 0, 300) = (0, −3, 0) µm;
    // squareness xy·x = 2e-6 · 250 = 0.5 µm along y. Total (2.5, −2.5, 0) µm.
    let pts = write(d.path(), "p.csv", "# measured\nid,x_mm,y_mm,z_mm,temp_c\nP1,250,500,300,20.5\n");
    let outp = d.path().join("c.csv");
    let o = run(&[
        "comp",
        "correct",
        "--map",
        s(&map),
        "--squareness",
        s(&sq),
        "--points",
        s(&pts),
        "--output",
        s(&outp),
        "--probe-offset-mm",
        "0,0,-100",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["n_points"], 1);
    let text = std::fs::read_to_string(&outp).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "id,x_mm,y_mm,z_mm,temp_c,dx_um,dy_um,dz_um");
    let r: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!((r[0], r[4]), ("P1", "20.5"));
    let v: Vec<f64> = [r[1], r[2], r[3], r[5], r[6], r[7]].iter().map(|x| x.parse().unwrap()).collect();
    let want = [250.0025, 499.9975, 300.0, 2.5, -2.5, 0.0];
    for (a, b) in v.iter().zip(want) {
        // Doubles of ~1e3 mm carry ~1e-13 mm rounding; 1e-9 leaves room and still catches any
        // term error (the smallest term is 0.5 µm = 5e-4 mm).
        assert!((a - b).abs() < 1e-9, "{v:?} vs {want:?}");
    }
    // The same squareness as a CSV file.
    let sqc = write(d.path(), "sq.csv", "xy_urad,xz_urad,yz_urad\n2,0,0\n");
    let o = run(&[
        "comp",
        "error",
        "--map",
        s(&map),
        "--squareness",
        s(&sqc),
        "--at",
        s(&pts),
        "--probe-offset-mm",
        "0,0,-100",
        "--json",
    ]);
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    let e: Vec<f64> = j["error_um"][0].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert!((e[0] - 2.5).abs() < 1e-9 && (e[1] + 2.5).abs() < 1e-9 && e[2].abs() < 1e-9, "{e:?}");
}

#[test]
fn commanded_positions_reach_the_target_within_a_nanometre() {
    let d = tempfile::tempdir().unwrap();
    let map = map_file(d.path());
    let targets = write(d.path(), "t.csv", "x_mm,y_mm,z_mm\n100,200,300\n955.5,10,990\n0,1000,0\n");
    let cmd = d.path().join("cmd.csv");
    let o = run(&[
        "comp",
        "correct",
        "--map",
        s(&map),
        "--points",
        s(&targets),
        "--output",
        s(&cmd),
        "--commanded",
        "--clamp",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    // c + E(c) must equal T: evaluate E at the commanded positions with `comp error`.
    let o = run(&["comp", "error", "--map", s(&map), "--at", s(&cmd), "--clamp", "--json"]);
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    let text = std::fs::read_to_string(&cmd).unwrap();
    let t = [[100.0, 200.0, 300.0], [955.5, 10.0, 990.0], [0.0, 1000.0, 0.0]];
    for (k, line) in text.lines().skip(1).enumerate() {
        let c: Vec<f64> = line.split(',').take(3).map(|x| x.parse().unwrap()).collect();
        let e: Vec<f64> = j["error_um"][k].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        for i in 0..3 {
            let reached = c[i] + e[i] * 1e-3;
            assert!((reached - t[k][i]).abs() < 1e-6, "target {k} axis {i}: {reached} vs {}", t[k][i]);
        }
        assert!((c[0] - t[k][0]).abs() > 1e-4 || t[k][0] == 0.0, "a real correction was applied");
    }
}

#[test]
fn help_names_the_rotation_axes() {
    let o = run(&["comp", "correct", "--help"]);
    let h = String::from_utf8_lossy(&o.stdout);
    for n in ["pitch_urad", "about X", "about Y", "about Z", "squareness", "1 nm"] {
        assert!(h.contains(n), "help lacks '{n}':\n{h}");
    }
}

#[test]
fn bad_maps_and_points_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let map = map_file(d.path());
    let pts = write(d.path(), "p.csv", "x_mm,y_mm,z_mm\n1,2,3\n1,2,1200\n");
    let outp = d.path().join("never.csv");
    let correct =
        |m: &Path, p: &Path| run(&["comp", "correct", "--map", s(m), "--points", s(p), "--output", s(&outp)]);
    expect_input_error(&correct(&map, &pts), &["p.csv:3", "z = 1200"]);
    assert!(!outp.exists());
    let text = std::fs::read_to_string(&map).unwrap();
    let m = write(d.path(), "w.csv", text.replacen("\nx,", "\nw,", 1));
    expect_input_error(&correct(&m, &pts), &["w.csv:2", "axis"]);
    let m = write(d.path(), "dup.csv", format!("{text}x,100,0,0,0,0,0,0\n"));
    expect_input_error(&correct(&m, &pts), &["dup.csv", "appears twice"]);
    let m = write(d.path(), "nan.csv", text.replacen(",10,0,0\n", ",nan,0,0\n", 1));
    expect_input_error(&correct(&m, &pts), &["nan.csv:3", "pitch_urad"]);
    let sq = write(d.path(), "sq.toml", "[squareness]\nxy_urad = \"a\"\n");
    let o = run(&[
        "comp",
        "correct",
        "--map",
        s(&map),
        "--squareness",
        s(&sq),
        "--points",
        s(&pts),
        "--output",
        s(&outp),
    ]);
    expect_input_error(&o, &["sq.toml:2"]);
    assert!(!outp.exists());
}

/// Issue 19: `comp correct` reads Parquet and E57 point files and writes Parquet by extension,
/// with the same numbers as the CSV route (the hand-computed case above, and a refused point
/// named by its row).
#[test]
fn correct_reads_and_writes_parquet_and_reads_e57() {
    use truepos_io::parquet_file::{read_columns, write_columns, ColumnData, Columns};
    let d = tempfile::tempdir().unwrap();
    let map = map_file(d.path());
    let correct = |pts: &Path, out: &Path| {
        run(&[
            "comp",
            "correct",
            "--map",
            s(&map),
            "--points",
            s(pts),
            "--output",
            s(out),
            "--probe-offset-mm",
            "0,0,-100",
        ])
    };
    // Written with 10 decimals: a full-precision input, so the CSV output is the shortest
    // round-trip text (as for Parquet and E57 input) and the routes agree bit for bit.
    let pts = write(d.path(), "p.csv", "id,x_mm,y_mm,z_mm\nP1,250.0000000000,500,300\nP2,10.5,20.25,30\n");
    let (out_csv, out_pq) = (d.path().join("c.csv"), d.path().join("c.parquet"));
    for out in [&out_csv, &out_pq] {
        let o = correct(&pts, out);
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let want = truepos_io::csv::Table::read(&out_csv).unwrap();
    let got = read_columns(&out_pq).unwrap();
    assert_eq!(got.names, ["id", "x_mm", "y_mm", "z_mm", "dx_um", "dy_um", "dz_um"]);
    for name in ["x_mm", "y_mm", "dx_um", "dy_um"] {
        // Shortest text reads back bit for bit: the Parquet doubles equal the CSV's exactly.
        assert_eq!(want.f64_column(name).unwrap(), got.f64(&out_pq, name).unwrap(), "{name}");
    }
    assert!((got.f64(&out_pq, "dx_um").unwrap()[0] - 2.5).abs() < 1e-9, "the hand-computed 2.5 µm");
    // Parquet in → CSV out: the same text as CSV in → CSV out.
    let pq_in = d.path().join("p.parquet");
    let cols = Columns {
        names: vec!["id".into(), "x_mm".into(), "y_mm".into(), "z_mm".into()],
        data: vec![
            ColumnData::Str(vec!["P1".into(), "P2".into()]),
            ColumnData::F64(vec![250.0, 10.5]),
            ColumnData::F64(vec![500.0, 20.25]),
            ColumnData::F64(vec![300.0, 30.0]),
        ],
    };
    write_columns(&pq_in, &cols).unwrap();
    let again = d.path().join("again.csv");
    let o = correct(&pq_in, &again);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(&again).unwrap(), std::fs::read_to_string(&out_csv).unwrap());
    // E57 in (metres inside; mm → m → mm moves a coordinate by an ulp or so).
    let e57 = d.path().join("p.e57");
    let p3 = |x, y, z| truepos_math::Point3::new(x, y, z);
    truepos_io::e57_file::write_e57(&e57, &[p3(250.0, 500.0, 300.0), p3(10.5, 20.25, 30.0)]).unwrap();
    let from_e57 = d.path().join("e.csv");
    let o = correct(&e57, &from_e57);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let e = truepos_io::csv::Table::read(&from_e57).unwrap();
    for name in ["x_mm", "y_mm", "z_mm", "dx_um", "dy_um", "dz_um"] {
        let (a, b) = (want.f64_column(name).unwrap(), e.f64_column(name).unwrap());
        // 1e-9 (mm or µm): ulps of ~1e3 mm are 1e-13 mm; a wrong unit would be off by 1e3.
        assert!(a.iter().zip(&b).all(|(a, b)| (a - b).abs() < 1e-9), "{name}: {a:?} {b:?}");
    }
    // A point outside the map in a Parquet file: exit 2 naming the file and the row.
    let far = Columns {
        data: vec![
            cols.data[0].clone(),
            cols.data[1].clone(),
            cols.data[2].clone(),
            ColumnData::F64(vec![300.0, 1200.0]),
        ],
        ..cols
    };
    write_columns(&pq_in, &far).unwrap();
    let gone = d.path().join("gone.parquet");
    expect_input_error(&correct(&pq_in, &gone), &["p.parquet", "row 2"]);
    assert!(!gone.exists());
    // `comp error --output` by extension too: the Parquet file holds the CSV's numbers.
    let errs = |out: &Path| {
        run(&[
            "comp",
            "error",
            "--map",
            s(&map),
            "--at",
            s(&pts),
            "--probe-offset-mm",
            "0,0,-100",
            "--output",
            s(out),
        ])
    };
    let (ec, ep) = (d.path().join("e.csv"), d.path().join("e.parquet"));
    for out in [&ec, &ep] {
        let o = errs(out);
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (a, b) = (truepos_io::csv::Table::read(&ec).unwrap(), read_columns(&ep).unwrap());
    assert_eq!(b.names, a.header);
    for name in ["x_mm", "ex_um", "ey_um"] {
        assert_eq!(a.f64_column(name).unwrap(), b.f64(&ep, name).unwrap(), "{name}");
    }
}

/// The map of [`map_file`] with standard-uncertainty columns: 0.1 µm on X positioning, 1 µrad on
/// Y pitch, 0.2 µm on Z positioning, all else 0.
fn map_file_u(dir: &Path) -> PathBuf {
    let mut t = String::from(
        "axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad,u_pos_um,u_str1_um,u_str2_um,u_pitch_urad,u_yaw_urad,u_roll_urad\n",
    );
    for i in 0..=10 {
        let p = 100.0 * i as f64;
        t.push_str(&format!("x,{p},{},0,0,0,0,0,0.1,0,0,0,0,0\n", p / 100.0));
        t.push_str(&format!("y,{p},0,0,0,10,0,0,0,0,0,1,0,0\n"));
        t.push_str(&format!("z,{p},0,0,0,0,0,0,0.2,0,0,0,0,0\n"));
    }
    write(dir, "map_u.csv", &t)
}

/// Issue 28: the map's u-columns propagate to u_x_um,u_y_um,u_z_um (hand-computed), the JSON
/// states the method; without them the output is unchanged and the uncertainty is said unknown.
#[test]
fn map_uncertainty_propagates_to_the_corrected_points() {
    let d = tempfile::tempdir().unwrap();
    let map = map_file_u(d.path());
    let sq = write(
        d.path(),
        "sq.toml",
        "[squareness]\nxy_urad = 2\nu_xy_urad = 0.5\nu_xz_urad = 0\nu_yz_urad = 0\n",
    );
    let pts =
        write(d.path(), "p.csv", "id,x_mm,y_mm,z_mm,temp_c\nP1,250,500,300,20.5\nP2,200,500,300,20.5\n");
    let outp = d.path().join("c.csv");
    let args = |m: &Path, q: &Path, o: &Path| {
        run(&[
            "comp",
            "correct",
            "--map",
            s(m),
            "--squareness",
            s(q),
            "--points",
            s(&pts),
            "--output",
            s(o),
            "--probe-offset-mm",
            "0,0,-100",
            "--json",
        ])
    };
    let o = args(&map, &sq, &outp);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["uncertainty_method"], "map-propagation");
    assert_eq!(j["coverage_factor"], 2.0);
    let text = std::fs::read_to_string(&outp).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "id,x_mm,y_mm,z_mm,temp_c,dx_um,dy_um,dz_um,u_x_um,u_y_um,u_z_um");
    // P1: axis positions (250, 500, 400). x: X positioning 0.1 µm (linear between equal node
    // u's, and the linear table has no curvature). y: Y pitch (about X) 1 µrad × lever z + t_z =
    // 300 mm = 0.3 µm, squareness xy 0.5 µrad × x 250 mm = 0.125 µm: √(0.09 + 0.015625). z: 0.2.
    // P2 at x = 200: the squareness term 0.1 µm.
    let u = |l: &str| -> Vec<f64> { l.split(',').skip(8).map(|v| v.parse().unwrap()).collect() };
    let expect = [[0.1, (0.09f64 + 0.015625).sqrt(), 0.2], [0.1, (0.09f64 + 0.01).sqrt(), 0.2]];
    for e in expect {
        let got = u(lines.next().unwrap());
        for k in 0..3 {
            assert!((got[k] - e[k]).abs() < 1e-6, "{got:?} vs {e:?}");
        }
    }
    let mx: Vec<f64> =
        j["max_expanded_uncertainty_um"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert!((mx[1] - 2.0 * (0.09f64 + 0.015625).sqrt()).abs() < 1e-9, "{mx:?}");
    // The corrections themselves are those of the map without u-columns, byte for byte.
    let plain = d.path().join("plain.csv");
    let o = args(&map_file(d.path()), &sq, &plain);
    assert_eq!(o.status.code(), Some(0));
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["uncertainty_method"], "unknown");
    assert!(j["uncertainty_unknown"].as_str().unwrap().contains("u_pos_um"), "{j}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("uncertainty is unknown"));
    let p = std::fs::read_to_string(&plain).unwrap();
    assert!(p.starts_with("id,x_mm,y_mm,z_mm,temp_c,dx_um,dy_um,dz_um\n"), "{p}");
    for (a, b) in p.lines().zip(text.lines()).skip(1) {
        assert_eq!(a, b.rsplitn(4, ',').last().unwrap());
    }
    // A map with u-columns but a squareness without them: unknown, said so.
    let sq0 = write(d.path(), "sq0.toml", "[squareness]\nxy_urad = 2\n");
    let o = args(&map, &sq0, &d.path().join("c0.csv"));
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["uncertainty_method"], "unknown");
    assert!(j["uncertainty_unknown"].as_str().unwrap().contains("squareness"), "{j}");
}

/// Issue 28: a partial set of u-columns, a negative u or a partial squareness set is an input
/// error at its file:line:col, and no output is written.
#[test]
fn partial_or_bad_uncertainty_columns_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(map_file_u(d.path())).unwrap();
    let pts = write(d.path(), "p.csv", "x_mm,y_mm,z_mm\n1,2,3\n");
    let outp = d.path().join("never.csv");
    let correct = |m: &Path, extra: &[&str]| {
        let mut a = vec!["comp", "correct", "--map", s(m), "--points", s(&pts), "--output", s(&outp)];
        a.extend_from_slice(extra);
        run(&a)
    };
    // Drop u_roll_urad (the last column): the header names the others, column 9 is u_pos_um.
    let partial: String = text.lines().map(|l| format!("{}\n", l.rsplit_once(',').unwrap().0)).collect();
    let m = write(d.path(), "partial.csv", partial);
    expect_input_error(&correct(&m, &[]), &["partial.csv:1:9", "u_roll_urad", "missing"]);
    assert!(!outp.exists());
    let m = write(d.path(), "neg.csv", text.replacen(",0.1,0,0,0,0,0\n", ",-0.1,0,0,0,0,0\n", 1));
    expect_input_error(&correct(&m, &[]), &["neg.csv:2:9", "u_pos_um"]);
    assert!(!outp.exists());
    let m = write(d.path(), "inf.csv", text.replacen(",0,0,0,1,0,0\n", ",0,0,0,inf,0,0\n", 1));
    expect_input_error(&correct(&m, &[]), &["inf.csv:3:12", "u_pitch_urad"]);
    let good = write(d.path(), "good.csv", &text);
    let sq = write(d.path(), "sq.toml", "[squareness]\nxy_urad = 2\nu_xy_urad = 0.5\n");
    expect_input_error(&correct(&good, &["--squareness", s(&sq)]), &["sq.toml:3", "u_xz_urad"]);
    let sq = write(d.path(), "sq.csv", "xy_urad,xz_urad,yz_urad,u_xy_urad,u_xz_urad\n1,2,3,0.1,0.1\n");
    expect_input_error(&correct(&good, &["--squareness", s(&sq)]), &["sq.csv:1:4", "u_yz_urad"]);
    assert!(!outp.exists());
}
