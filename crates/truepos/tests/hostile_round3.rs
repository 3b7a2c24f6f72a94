//! Hostile inputs of the third hardening round (issue 31), through the binary: QIF plans that
//! are too deep, too large or ambiguous; probing requests that would measure nothing; outputs
//! that would destroy what they replace; unclear refusals. Every case: exit 2 (or 3 for a
//! device), the file, line or field and the limit named, nothing written.

mod common;

use common::{bin, expect_input_error, write};

const CIRCLE: &str =
    "x_mm,y_mm,z_mm\n1,0,0\n0,1,0\n-1,0,0\n0,-1,0\n0.7071067811865476,0.7071067811865476,0\n";

#[test]
fn qif_plans_are_bounded_and_depth_limited() {
    let d = tempfile::tempdir().unwrap();
    let pts = write(d.path(), "c.csv", CIRCLE);
    let n = 50_000;
    let deep = write(
        d.path(),
        "deep.qif",
        format!(
            "<QIFDocument xmlns=\"http://qifstandards.org/xsd/qif3\">\n{}{}</QIFDocument>",
            "<a>".repeat(n),
            "</a>".repeat(n)
        ),
    );
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif-plan").arg(&deep).output().unwrap();
    expect_input_error(&out, &["deep.qif:2:", "nested more than 256"]);
    if std::path::Path::new("/dev/zero").exists() {
        let t = std::time::Instant::now();
        let out = bin().args(["fit", "circle"]).arg(&pts).args(["--qif-plan", "/dev/zero"]).output().unwrap();
        expect_input_error(&out, &["/dev/zero", "binary data"]);
        assert!(t.elapsed().as_secs_f64() < 10.0);
    } else {
        eprintln!("SKIPPED: no /dev/zero on this system");
    }
    let qif2 = write(
        d.path(),
        "old.qif",
        "<QIFDocument xmlns=\"http://qifstandards.org/xsd/qif2\"><Characteristics/></QIFDocument>",
    );
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif-plan").arg(&qif2).output().unwrap();
    expect_input_error(&out, &["old.qif", "QIF 2", "qif2"]);
}

#[test]
fn probing_feeds_and_counts_have_physical_limits() {
    let out = bin()
        .args(["probe", "sphere", "--near=0,0,0", "--diameter-mm", "25", "--feed-mm-min", "1e9"])
        .output()
        .unwrap();
    expect_input_error(&out, &["1000000000 mm/min", "5000 mm/min", "overtravel"]);
    let d = tempfile::tempdir().unwrap();
    let holes = write(d.path(), "holes.csv", "id,x_mm,y_mm,z_mm\nA,10,20,0\n");
    for (opt, val, needle) in
        [("--feed-mm-min", "1e9", "5000 mm/min"), ("--points", "1000000000", "between 4 and 10000")]
    {
        let out = bin()
            .args(["somac", "inspect", "--diameter-mm", "6", "--holes"])
            .arg(&holes)
            .args([opt, val, "--db"])
            .arg(d.path().join("a.sqlite"))
            .output()
            .unwrap();
        expect_input_error(&out, &[needle]);
    }
    // The limit itself is accepted.
    let out = bin()
        .args([
            "probe",
            "sphere",
            "--near=0,0,0",
            "--diameter-mm",
            "25",
            "--feed-mm-min",
            "5000",
            "--points",
            "6",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
}

/// Outputs replace only regular files that are not the command's own inputs: the input named
/// as the output, a symlink, a FIFO, a character device are refused (exit 2), left as they were.
#[cfg(unix)]
#[test]
fn outputs_never_destroy_what_they_replace() {
    let d = tempfile::tempdir().unwrap();
    let pts = write(d.path(), "c.csv", CIRCLE);
    // The input as its own output, named another way.
    let same = d.path().join(".").join("c.csv");
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif").arg(&same).output().unwrap();
    expect_input_error(&out, &["same file as the input", "c.csv"]);
    assert_eq!(std::fs::read_to_string(&pts).unwrap(), CIRCLE);
    let target = write(d.path(), "t.qif", "keep");
    let link = d.path().join("l.qif");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif").arg(&link).output().unwrap();
    expect_input_error(&out, &["l.qif", "symbolic link"]);
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    let fifo = d.path().join("f.qif");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()));
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif").arg(&fifo).output().unwrap();
    expect_input_error(&out, &["f.qif", "FIFO"]);
    let out = bin().args(["fit", "circle"]).arg(&pts).args(["--qif", "/dev/null"]).output().unwrap();
    expect_input_error(&out, &["/dev/null", "character device"]);
    // ippdme serve --log onto its own part file, or onto a full device: refused before serving.
    let part = write(d.path(), "part.toml", "# part\n");
    let out = bin()
        .args(["ippdme", "serve", "--port", "0", "--part"])
        .arg(&part)
        .arg("--log")
        .arg(d.path().join(".").join("part.toml"))
        .output()
        .unwrap();
    expect_input_error(&out, &["--log", "same file as the input", "part.toml"]);
    assert_eq!(std::fs::read_to_string(&part).unwrap(), "# part\n");
    let out = bin().args(["ippdme", "serve", "--port", "0", "--log", "/dev/full"]).output().unwrap();
    expect_input_error(&out, &["--log", "/dev/full", "character device"]);
}

/// Parquet fixtures written by pyarrow (`crates/io/tests/pyarrow/make_fixtures.py`): points on
/// the sphere of centre (1, 2, 3) mm and radius 10 mm, pages with CRC-32s; the same, GZIP.
const CRC_POINTS: &[u8] = include_bytes!("../../io/tests/pyarrow/crc_points.parquet");
const GZIP_POINTS: &[u8] = include_bytes!("../../io/tests/pyarrow/gzip_points.parquet");

/// A page whose CRC-32 does not match its bytes is refused naming the file and the column, by
/// `fit` and by the streamed `comp correct` (no output left); a codec truepos does not decode
/// is named plainly.
#[test]
fn corrupted_pages_and_unsupported_codecs_are_refused_with_their_column() {
    let d = tempfile::tempdir().unwrap();
    let good = write(d.path(), "crc.parquet", CRC_POINTS);
    let out = bin().args(["fit", "sphere", "--json"]).arg(&good).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let c: Vec<f64> = v["center_mm"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    // Five exact points of the sphere: centre and radius to round-off.
    assert!((c[0] - 1.0).abs() < 1e-9 && (c[1] - 2.0).abs() < 1e-9 && (c[2] - 3.0).abs() < 1e-9, "{c:?}");
    assert!((v["radius_mm"].as_f64().unwrap() - 10.0).abs() < 1e-9, "{v}");
    // One bit of x_mm's −9 flipped (−9.000000000000002: a plausible value, fitted without the
    // checksum).
    let mut bytes = CRC_POINTS.to_vec();
    let x: Vec<u8> = [11.0_f64, -9.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    let at = bytes.windows(16).position(|w| w == x.as_slice()).unwrap();
    bytes[at + 8] ^= 1;
    let bad = write(d.path(), "flipped.parquet", &bytes);
    let out = bin().args(["fit", "sphere"]).arg(&bad).output().unwrap();
    expect_input_error(&out, &["flipped.parquet", "column 'x_mm'", "CRC-32", "corrupted"]);
    let map = write(
        d.path(),
        "map.csv",
        "axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad\nx,-100,0,0,0,0,0,0\nx,100,0,0,0,0,0,0\ny,-100,0,0,0,0,0,0\ny,100,0,0,0,0,0,0\nz,-100,0,0,0,0,0,0\nz,100,0,0,0,0,0,0\n",
    );
    for input in [&good, &bad] {
        let output = d.path().join("corrected.csv");
        let out = bin()
            .args(["comp", "correct", "--map"])
            .arg(&map)
            .arg("--points")
            .arg(input)
            .arg("--output")
            .arg(&output)
            .output()
            .unwrap();
        if input == &good {
            assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
            std::fs::remove_file(&output).unwrap();
        } else {
            expect_input_error(&out, &["flipped.parquet", "column 'x_mm'", "CRC-32"]);
            assert!(!output.exists());
        }
    }
    let gz = write(d.path(), "gz.parquet", GZIP_POINTS);
    let out = bin().args(["fit", "sphere"]).arg(&gz).output().unwrap();
    expect_input_error(&out, &["gz.parquet", "compression GZIP is not supported; use Snappy"]);
}

/// One Cartesian scan of doubles (m) named `name`, with `pose` and the points `pts` and their
/// invalid states.
fn e57_scan(path: &std::path::Path, name: &str, pose: Option<e57::Transform>, pts: &[([f64; 3], i64)]) {
    use e57::{Record, RecordDataType, RecordName, RecordValue};
    let mut w = e57::E57Writer::from_file(path, "hostile").unwrap();
    let mut proto = vec![Record::CARTESIAN_X_F64, Record::CARTESIAN_Y_F64, Record::CARTESIAN_Z_F64];
    proto.push(Record {
        name: RecordName::CartesianInvalidState,
        data_type: RecordDataType::Integer { min: 0, max: 2 },
    });
    let mut pc = w.add_pointcloud(name, proto).unwrap();
    pc.set_transform(pose);
    for (v, state) in pts {
        let mut vals: Vec<RecordValue> = v.iter().map(|&x| RecordValue::Double(x)).collect();
        vals.push(RecordValue::Integer(*state));
        pc.add_point(vals).unwrap();
    }
    pc.finalize().unwrap();
    w.finalize().unwrap();
}

/// E57: a pose whose quaternion is not a unit one is refused naming the scan, the field and the
/// tolerance; NaN/inf points are named as such, apart from the points the file marks invalid;
/// `comp correct` says how many points it dropped, on stderr and in its JSON.
#[test]
fn e57_poses_and_dropped_points_are_named() {
    let d = tempfile::tempdir().unwrap();
    let sphere: Vec<([f64; 3], i64)> = [
        [0.011, 0.002, 0.003],
        [-0.009, 0.002, 0.003],
        [0.001, 0.012, 0.003],
        [0.001, -0.008, 0.003],
        [0.001, 0.002, 0.013],
        [0.001, 0.002, -0.007],
    ]
    .into_iter()
    .map(|p| (p, 0))
    .collect();
    let tilted = e57::Transform {
        rotation: e57::Quaternion { w: 1.0, x: 0.01, y: 0.0, z: 0.0 },
        translation: Default::default(),
    };
    let path = d.path().join("tilted.e57");
    e57_scan(&path, "scan-a", Some(tilted), &sphere);
    let out = bin().args(["fit", "sphere"]).arg(&path).output().unwrap();
    expect_input_error(
        &out,
        &["tilted.e57", "scan 1 ('scan-a')", "pose/rotation", "norm 1.0000499", "within 1e-6"],
    );
    // NaN, infinity and a point marked invalid: the sphere is fitted from the rest, and the
    // note names each kind.
    let mut pts = sphere.clone();
    pts.extend([([f64::NAN, 0.0, 0.0], 0), ([0.0, f64::NEG_INFINITY, 0.0], 0), ([0.5, 0.5, 0.5], 2)]);
    let path = d.path().join("holes.e57");
    e57_scan(&path, "scan-b", None, &pts);
    let out = bin().args(["fit", "sphere", "--json"]).arg(&path).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("1 points marked invalid in the file were skipped"), "{err}");
    assert!(err.contains("2 points with a NaN or infinite coordinate were skipped"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!((v["radius_mm"].as_f64().unwrap() - 10.0).abs() < 1e-9, "{v}");
    let map = write(
        d.path(),
        "map.csv",
        "axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad\nx,-100,0,0,0,0,0,0\nx,100,0,0,0,0,0,0\ny,-100,0,0,0,0,0,0\ny,100,0,0,0,0,0,0\nz,-100,0,0,0,0,0,0\nz,100,0,0,0,0,0,0\n",
    );
    let output = d.path().join("c.csv");
    let out = bin()
        .args(["comp", "correct", "--json", "--map"])
        .arg(&map)
        .arg("--points")
        .arg(&path)
        .arg("--output")
        .arg(&output)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("3 points of the E57 input dropped (not in the output): 1 marked invalid in the file, 2 with a NaN or infinite coordinate"),
        "{err}"
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((j["n_points"].as_u64(), j["dropped_invalid_points"].as_u64()), (Some(6), Some(1)));
    assert_eq!(j["dropped_nonfinite_points"].as_u64(), Some(2));
    assert_eq!(truepos_io::csv::Table::read(&output).unwrap().n_rows(), 6);
}

/// Sizes and magnitudes beyond the physical ones, and degenerate requests: exit 2 naming the
/// option or quantity and the limit (before: exit 3 from the machine, "all points coincide",
/// a generic weight message, "must be above absolute zero").
#[test]
fn absurd_sizes_and_degenerate_requests_name_the_limit() {
    for (opt, val) in [("--diameter-mm", "1e308"), ("--clearance-mm", "1e9"), ("--tip-diameter-mm", "1e300")]
    {
        let mut args = vec!["probe", "sphere", "--near=0,0,0", opt, val];
        if opt != "--diameter-mm" {
            args.extend(["--diameter-mm", "25"]);
        }
        let out = bin().args(&args).output().unwrap();
        expect_input_error(&out, &[opt, "100000 mm (100 m)", "physical limit"]);
    }
    let out = bin().args(["probe", "sphere", "--near=0,0,1e200", "--diameter-mm", "25"]).output().unwrap();
    expect_input_error(&out, &["--near", "100000 mm"]);
    let d = tempfile::tempdir().unwrap();
    // Distinct points at 1e200 mm: named by the coordinate magnitude limit, not as coinciding.
    let far = write(
        d.path(),
        "far.csv",
        "x_mm,y_mm,z_mm\n1e200,0,0\n0,1e200,0\n-1e200,0,0\n0,-1e200,0\n0,0,1e200\n",
    );
    for kind in ["sphere", "line", "plane", "circle"] {
        let out = bin().args(["fit", kind]).arg(&far).output().unwrap();
        expect_input_error(&out, &["far.csv", "magnitude 1e200 mm", "coordinate magnitude limit of 1e12 mm"]);
    }
    // align: all weights zero; identical target points.
    let good = write(d.path(), "g.csv", "id,x_mm,y_mm,z_mm,w\nA,0,0,0,0\nB,100,0,0,0\nC,0,100,0,0\n");
    let out = bin()
        .args(["align", "--from"])
        .arg(&good)
        .arg("--to")
        .arg(&good)
        .args(["--weights", "w"])
        .output()
        .unwrap();
    expect_input_error(&out, &["all 3 weights are zero", "degenerate"]);
    let same = write(d.path(), "same.csv", "id,x_mm,y_mm,z_mm\nA,5,5,5\nB,5,5,5\nC,5,5,5\n");
    let out = bin().args(["align", "--from"]).arg(&good).arg("--to").arg(&same).output().unwrap();
    expect_input_error(&out, &["same.csv", "all target (to) points coincide"]);
    // air below absolute zero: the range of the equation is named too.
    let out = bin()
        .args(["air", "--temperature-c=-300", "--pressure-pa", "101325", "--humidity-pct", "50"])
        .output()
        .unwrap();
    expect_input_error(&out, &["-300 °C", "absolute zero", "-40 to 100 °C"]);
}

/// CR-only line ends (classic Mac OS): named as such where a reader sees one line, not as the
/// missing column or the long line that follows from it.
#[test]
fn cr_only_line_ends_are_named() {
    let d = tempfile::tempdir().unwrap();
    let map = write(
        d.path(),
        "map.csv",
        "axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad\nx,-100,0,0,0,0,0,0\nx,100,0,0,0,0,0,0\ny,-100,0,0,0,0,0,0\ny,100,0,0,0,0,0,0\nz,-100,0,0,0,0,0,0\nz,100,0,0,0,0,0,0\n",
    );
    let correct = |pts: &std::path::Path, output: &std::path::Path| {
        bin()
            .args(["comp", "correct", "--map"])
            .arg(&map)
            .arg("--points")
            .arg(pts)
            .arg("--output")
            .arg(output)
            .output()
            .unwrap()
    };
    let output = d.path().join("out.csv");
    let mac = write(d.path(), "mac.csv", "id,x_mm,y_mm,z_mm\rP1,1,2,3\rP2,4,5,6\r");
    let out = correct(&mac, &output);
    expect_input_error(&out, &["mac.csv:1", "CR-only line ends", "tr '\\r' '\\n'"]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("missing required column"));
    assert!(!output.exists());
    // Over a megabyte without a line feed: CR-only line ends, not a line too long.
    let mut big = String::from("id,x_mm,y_mm,z_mm\r");
    let mut i = 0;
    while big.len() < 1_200_000 {
        big.push_str(&format!("P{i},{i}.5,2,3\r"));
        i += 1;
    }
    let big = write(d.path(), "bigmac.csv", big);
    let out = correct(&big, &output);
    expect_input_error(&out, &["bigmac.csv:1:1", "CR-only line ends"]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("longer than"));
    assert!(!output.exists());
}

/// The NIST example program and part (data/dmis), copied into `dir`.
fn dmis_example(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/dmis");
    let prog = dir.join("prog.dms");
    let part = dir.join("part.toml");
    std::fs::copy(data.join("simple_in.dms"), &prog).unwrap();
    std::fs::copy(data.join("simple_part.toml"), &part).unwrap();
    (prog, part)
}

/// F14: `dmis run` never writes over the virtual CMM's part or machine file, whether named by
/// --output, --qif or the program's own DEVICE/STOR; refused before anything moves.
#[test]
fn dmis_run_outputs_never_replace_the_part_or_machine_file() {
    let d = tempfile::tempdir().unwrap();
    let (prog, part) = dmis_example(d.path());
    let part_text = std::fs::read_to_string(&part).unwrap();
    let machine = write(
        d.path(),
        "cmm.toml",
        "[ippdme]\nvolume_min_mm = [-500, -500, -500]\nvolume_max_mm = [500, 500, 500]\n",
    );
    let db = d.path().join("a.sqlite");
    let run = |extra: &[&std::ffi::OsStr], prog: &std::path::Path| {
        bin()
            .current_dir(d.path())
            .args(["dmis", "run"])
            .arg(prog)
            .args(["--sensor", "PROBE6=Probe1", "--part"])
            .arg(&part)
            .arg("--machine")
            .arg(&machine)
            .arg("--db")
            .arg(&db)
            .args(extra)
            .output()
            .unwrap()
    };
    let same_part = d.path().join(".").join("part.toml");
    let out = run(&["--output".as_ref(), same_part.as_os_str()], &prog);
    expect_input_error(&out, &["part.toml", "same file as the input"]);
    let out = run(&["--output".as_ref(), "r.dms".as_ref(), "--qif".as_ref(), part.as_os_str()], &prog);
    expect_input_error(&out, &["part.toml", "same file as the input"]);
    let out = run(&["--output".as_ref(), machine.as_os_str()], &prog);
    expect_input_error(&out, &["cmm.toml", "same file as the input"]);
    let text = std::fs::read_to_string(&prog)
        .unwrap()
        .replace("ENDFIL", "DID(D1)=DEVICE/STOR,'part.toml'\nOPEN/DID(D1),DIRECT,OUTPUT,OVERWR\nENDFIL");
    let stor = write(d.path(), "stor.dms", text);
    let out = run(&[], &stor);
    expect_input_error(&out, &["part.toml", "same file as the input"]);
    assert_eq!(std::fs::read_to_string(&part).unwrap(), part_text);
    assert!(std::fs::read_to_string(&machine).unwrap().starts_with("[ippdme]"));
    assert!(!d.path().join("r.dms").exists());
}

/// F4: the virtual CMM's part and machine files go through the bounded reader of configuration
/// files: a sparse 3 GB file, /dev/zero, /dev/urandom refused at once (exit 2, file named).
#[cfg(unix)]
#[test]
fn virtual_cmm_files_are_read_within_the_configuration_limit() {
    let d = tempfile::tempdir().unwrap();
    let (prog, part) = dmis_example(d.path());
    let sparse = d.path().join("sparse.toml");
    std::fs::File::create(&sparse).unwrap().set_len(3 << 30).unwrap();
    let dmis = |opt: &str, file: &std::path::Path| {
        let t = std::time::Instant::now();
        let (part_file, machine) = if opt == "--part" { (file, None) } else { (part.as_path(), Some(file)) };
        let mut cmd = bin();
        cmd.current_dir(d.path())
            .args(["dmis", "run"])
            .arg(&prog)
            .args(["--sensor", "PROBE6=Probe1", "--part"])
            .arg(part_file);
        if let Some(m) = machine {
            cmd.arg("--machine").arg(m);
        }
        let out = cmd.arg("--db").arg(d.path().join("a.sqlite")).output().unwrap();
        assert!(t.elapsed().as_secs_f64() < 10.0);
        out
    };
    let out = dmis("--part", &sparse);
    expect_input_error(
        &out,
        &["sparse.toml", "3.2 GB", "configuration files of at most 67.1 MB", "TRUEPOS_MAX_CONFIG_MB"],
    );
    let out = dmis("--machine", &sparse);
    expect_input_error(&out, &["sparse.toml", "configuration files of at most"]);
    for dev in ["/dev/zero", "/dev/urandom"] {
        if !std::path::Path::new(dev).exists() {
            eprintln!("SKIPPED: no {dev} on this system");
            continue;
        }
        let out = dmis("--machine", std::path::Path::new(dev));
        expect_input_error(&out, &[dev, "binary data"]);
        let t = std::time::Instant::now();
        let out = bin().args(["ippdme", "serve", "--port", "0", "--part", dev]).output().unwrap();
        expect_input_error(&out, &[dev, "binary data"]);
        assert!(t.elapsed().as_secs_f64() < 10.0);
    }
    // A configuration file over a lowered limit names it.
    let out = bin()
        .env("TRUEPOS_MAX_CONFIG_MB", "1")
        .args(["ippdme", "serve", "--port", "0", "--machine"])
        .arg(&sparse)
        .output()
        .unwrap();
    expect_input_error(&out, &["sparse.toml", "at most 1.0 MB", "TRUEPOS_MAX_CONFIG_MB"]);
}

/// F2: an element with more attributes than the XML bound is refused at once, naming its line
/// and column and the limit (150 000 attributes took 17 s in the parser).
#[test]
fn an_xml_element_with_too_many_attributes_is_refused_at_once() {
    let d = tempfile::tempdir().unwrap();
    let pts = write(d.path(), "c.csv", CIRCLE);
    let attrs: String = (0..150_000).map(|i| format!(" a{i}=\"1\"")).collect();
    let qif = write(
        d.path(),
        "ma.qif",
        format!("<QIFDocument xmlns=\"http://qifstandards.org/xsd/qif3\">\n  <a{attrs}/></QIFDocument>"),
    );
    let t = std::time::Instant::now();
    let out = bin().args(["fit", "circle"]).arg(&pts).arg("--qif-plan").arg(&qif).output().unwrap();
    expect_input_error(&out, &["ma.qif:2:3", "more than 1024 attributes"]);
    assert!(t.elapsed().as_secs_f64() < 5.0);
}

/// F5: Parquet (and E57) on a FIFO or a character device: named as needing a regular file,
/// not "No such device".
#[cfg(unix)]
#[test]
fn parquet_on_a_fifo_or_device_needs_a_regular_file() {
    let d = tempfile::tempdir().unwrap();
    let dev = d.path().join("r.parquet");
    std::os::unix::fs::symlink("/dev/null", &dev).unwrap();
    let out = bin().args(["fit", "sphere"]).arg(&dev).output().unwrap();
    expect_input_error(&out, &["r.parquet", "character device", "Parquet file", "regular file"]);
    // A FIFO without a writer: refused before opening (which would block).
    let fifo = d.path().join("f.parquet");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()));
    let out = bin().args(["fit", "sphere"]).arg(&fifo).output().unwrap();
    expect_input_error(&out, &["f.parquet", "FIFO", "regular file"]);
}

/// F15: `simulate … --out` naming an existing file: exit 2 naming it and what is expected.
#[test]
fn simulate_out_must_be_a_directory() {
    let d = tempfile::tempdir().unwrap();
    let f = write(d.path(), "vfile", "keep");
    for sim in ["scan", "load", "comp"] {
        let out = bin().args(["simulate", sim, "--out"]).arg(&f).output().unwrap();
        expect_input_error(&out, &["--out", "vfile", "not a directory"]);
    }
    assert_eq!(std::fs::read_to_string(&f).unwrap(), "keep");
}

/// F17: `--db` on a FIFO or a character device: exit 2 naming the path, nothing opened.
#[cfg(unix)]
#[test]
fn the_audit_trail_must_be_a_regular_file() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("ofifo");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()));
    let holes = write(d.path(), "holes.csv", "id,x_mm,y_mm,z_mm\nA,10,20,0\n");
    let out = bin()
        .args(["somac", "inspect", "--diameter-mm", "6", "--holes"])
        .arg(&holes)
        .arg("--db")
        .arg(&fifo)
        .output()
        .unwrap();
    expect_input_error(&out, &["ofifo", "FIFO", "regular file"]);
    for dev in ["/dev/full", "/dev/urandom"] {
        if !std::path::Path::new(dev).exists() {
            eprintln!("SKIPPED: no {dev}");
            continue;
        }
        let out = bin().args(["audit", "list", "--db", dev]).output().unwrap();
        expect_input_error(&out, &[dev, "character device", "regular file"]);
    }
}

/// F9: absurd lengths are refused before the machine is opened, naming the option or the file
/// field and the 100 m limit.
#[test]
fn absurd_lengths_are_refused_with_the_physical_limit() {
    let d = tempfile::tempdir().unwrap();
    let holes = write(d.path(), "holes.csv", "id,x_mm,y_mm,z_mm\nA,10,20,0\n");
    let db = d.path().join("a.sqlite");
    let out = bin()
        .args(["somac", "inspect", "--diameter-mm", "6", "--depth-mm", "1e9", "--holes"])
        .arg(&holes)
        .arg("--db")
        .arg(&db)
        .output()
        .unwrap();
    expect_input_error(&out, &["--depth-mm", "1e9 mm", "100 m"]);
    let far = write(d.path(), "hfar.csv", "id,x_mm,y_mm,z_mm\nA,10,20,0\nB,1e300,0,0\n");
    let out = bin()
        .args(["somac", "inspect", "--diameter-mm", "6", "--holes"])
        .arg(&far)
        .arg("--db")
        .arg(&db)
        .output()
        .unwrap();
    expect_input_error(&out, &["hfar.csv:3:2", "hole B: x_mm", "1e300 mm", "100 m"]);
    let out = bin()
        .args(["kinematics", "calibrate", "--model", "xyzbc-trt", "--near=60,25,15", "--diameter-mm", "25"])
        .args(["--turn-distance-mm", "1e12"])
        .args(["0,0", "0,120", "0,240", "45,0", "90,120", "90,240"].iter().flat_map(|o| ["--orientation", o]))
        .output()
        .unwrap();
    expect_input_error(&out, &["--turn-distance-mm", "1e12 mm", "100 m"]);
    let ha = d.path().join("ha.csv");
    for (opt, orient) in [("--nominal-offset-mm", "90,0"), ("--table-center-mm", "0,90")] {
        let out = bin()
            .args(["head-offset", "acquire", "--near=0,0,0", "--diameter-mm", "25"])
            .args(["--orientation", "0,0", "--orientation", orient, opt, "1e300,0,0", "--output"])
            .arg(&ha)
            .output()
            .unwrap();
        expect_input_error(&out, &[opt, "1e300 mm", "100 m"]);
        assert!(!ha.exists());
    }
    // F10: a head swivel of 1e9° was accepted and written as b_deg; F8: a feed of 1e-300
    // mm/min probed (F0 on a controller).
    let out = bin()
        .args(["head-offset", "acquire", "--near=0,0,0", "--diameter-mm", "25"])
        .args(["--orientation", "1e9,0", "--orientation", "0,0", "--output"])
        .arg(&ha)
        .output()
        .unwrap();
    expect_input_error(&out, &["orientation 1", "B must be within ±90°"]);
    assert!(!ha.exists());
    let out = bin()
        .args(["probe", "sphere", "--near=0,0,0", "--diameter-mm", "25", "--points", "6"])
        .args(["--feed-mm-min", "1e-300"])
        .output()
        .unwrap();
    expect_input_error(&out, &["1e-300 mm/min is below 1 mm/min"]);
}

// Findings of the second hostile audit (scripts/hostile_round3.sh; docs/hardening.md): G-code
// expressions that overflowed the stack and CR-only line ends that made a program one block.

const TREF: &str = "id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1000,0,0\nT3,0,1000,0\n";
const TMEAS: &str = "id,x_mm,y_mm,z_mm\nT1,1,0,0\nT2,1001,0,0\nT3,1,1000,0\n";

/// Nothing but `keep` in `dir` (no output, no temporary file).
fn only(dir: &std::path::Path, keep: &[&str]) {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut want: Vec<String> = keep.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(names, want);
}

/// F1: a 10,000-term expression, 7,000 nested brackets or 20,000 signs in one word overflowed
/// the reader thread's stack (exit 134, a temporary file left); now exit 2 at the word's place
/// with the limit, and nothing written.
#[test]
fn huge_gcode_expressions_are_refused_not_crashed() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "tref.csv", TREF);
    write(d.path(), "tmeas.csv", TMEAS);
    let cases = [
        ("flat.nc", format!("X[{}1]", "1+".repeat(10_000))),
        ("deep.nc", format!("X{}1{}", "[".repeat(7000), "]".repeat(7000))),
        ("signs.nc", format!("X[{}1]", "-".repeat(20_000))),
    ];
    for (name, word) in &cases {
        write(d.path(), name, format!("G90\nG0 {word} Y0 Z0\n"));
    }
    for (name, _) in &cases {
        let out = bin()
            .current_dir(d.path())
            .args(["orient", "--reference", "tref.csv", "--measured", "tmeas.csv", "--program", name])
            .args(["--output", "o.nc"])
            .output()
            .unwrap();
        expect_input_error(&out, &[&format!("{name}:2:4"), "more than 1000 values and operators"]);
        assert!(String::from_utf8_lossy(&out.stderr).len() < 2000, "the message quotes all of it");
        only(d.path(), &["tref.csv", "tmeas.csv", "flat.nc", "deep.nc", "signs.nc"]);
    }
    // The same in a parameter setting of a somac program (the main thread's parser).
    let prog = write(d.path(), "set.nc", format!("#1=[{}1]\nG0 X#1 Y0 Z0\n", "1+".repeat(200_000)));
    let out = bin()
        .args(["somac", "inspect", "--diameter-mm", "6", "--program"])
        .arg(&prog)
        .arg("--db")
        .arg(d.path().join("s.sqlite"))
        .output()
        .unwrap();
    expect_input_error(&out, &["set.nc:1:", "more than 1000 values and operators"]);
}

/// F19, F20: lines ending in a carriage return alone (classic Mac OS) read as one block: orient
/// wrote a wrong program with exit 0 (the first motion took the last X), somac inspect found
/// one hole of four. Now exit 2 naming CR-only line ends at the first one, nothing written.
#[test]
fn cr_only_gcode_is_refused_at_its_first_carriage_return() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "tref.csv", TREF);
    write(d.path(), "tmeas.csv", TMEAS);
    write(d.path(), "mac.nc", "G90\rG0 X1 Y2 Z3\rG1 X10 Y10 Z0 F100\r");
    let out = bin()
        .current_dir(d.path())
        .args(["orient", "--reference", "tref.csv", "--measured", "tmeas.csv", "--program", "mac.nc"])
        .args(["--output", "o.nc"])
        .output()
        .unwrap();
    expect_input_error(&out, &["mac.nc:1:4", "CR-only line ends", "LF or CRLF"]);
    only(d.path(), &["tref.csv", "tmeas.csv", "mac.nc"]);
    // A comment swallowing the rest of a CR-only program is caught too.
    write(d.path(), "macc.nc", "G90 ; set up\rG0 X1 Y2 Z3\r");
    let out = bin()
        .current_dir(d.path())
        .args(["orient", "--reference", "tref.csv", "--measured", "tmeas.csv", "--program", "macc.nc"])
        .args(["--output", "o.nc"])
        .output()
        .unwrap();
    expect_input_error(&out, &["macc.nc:1:", "CR-only line ends"]);
    // somac inspect on a simulated cell's program with its LF turned into CR.
    let out = bin().args(["simulate", "somac", "--out"]).arg(d.path().join("cell")).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let prog = std::fs::read(d.path().join("cell/program.nc")).unwrap();
    let mac: Vec<u8> = prog.iter().map(|&c| if c == b'\n' { b'\r' } else { c }).collect();
    let macp = write(d.path(), "macsomac.nc", mac);
    let out = bin()
        .args(["somac", "inspect", "--diameter-mm", "6", "--program"])
        .arg(&macp)
        .arg("--db")
        .arg(d.path().join("m.sqlite"))
        .output()
        .unwrap();
    expect_input_error(&out, &["macsomac.nc:1:", "CR-only line ends"]);
}
