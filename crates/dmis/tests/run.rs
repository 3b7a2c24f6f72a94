//! Programs checked and run: the NIST example on the dry-run machine and on the virtual CMM
//! behind I++ DME (its true bore known), a program with datums, constructions and every
//! tolerance kind, and refusals before any motion.

use std::collections::HashMap;
use std::path::PathBuf;
use truepos_dmis::exec::{run, DryRun, Geom, RunError, RunOptions};
use truepos_dmis::model::check;
use truepos_dmis::{parse, ErrorKind};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn plan_of(rel: &str) -> truepos_dmis::model::Plan {
    let text = std::fs::read_to_string(repo().join(rel)).unwrap();
    check(&parse(rel, &text).unwrap()).unwrap()
}

fn sensors(pairs: &[(&str, &str)]) -> RunOptions {
    RunOptions {
        sensors: pairs.iter().map(|(a, b)| (a.to_string(), b.to_string())).collect::<HashMap<_, _>>(),
    }
}

#[test]
fn the_nist_example_dry_runs_to_its_output() {
    let plan = plan_of("data/dmis/simple_in.dms");
    assert_eq!(plan.n_probes, 4);
    let opts = RunOptions::default();
    let mut m = DryRun::new(&plan, &opts);
    let r = run(&plan, &mut m, &opts, &mut |_| {}).unwrap();
    let out = r.output.join("\n");
    assert!(out.contains("FA(A_CIRCLE) = FEAT/CIRCLE, INNER, CART,  $\n  50.00000, 50.00000, 40.00000, 0.00000, 0.00000, 1.00000, 50.00000"), "{out}");
    assert!(
        out.starts_with("FILNAM/'IPP SIMPLE DMIS output'\nUNITS/MM,ANGDEC\nD(START)=DATSET/MCS\n"),
        "{out}"
    );
    assert!(out.ends_with("OUTPUT/FA(A_CIRCLE)\nFA(A_CIRCLE) = FEAT/CIRCLE, INNER, CART,  $\n  50.00000, 50.00000, 40.00000, 0.00000, 0.00000, 1.00000, 50.00000\nENDFIL"), "{out}");
    // The motions of simple.prg: GoTo 175, the tool, 75, FEDRAT/POSVEL (1.8 m/min = 30 mm/s),
    // 40, four PtMeas, GoTo 40, 100.
    let kinds: Vec<&str> = r.motions.iter().filter_map(|m| m.split(' ').next()).collect();
    assert_eq!(
        kinds,
        ["GOTO", "line", "GOTO", "line", "GOTO", "PTMEAS", "PTMEAS", "PTMEAS", "PTMEAS", "GOTO", "GOTO"]
    );
    assert_eq!(r.motions[3], "line 19: positioning speed 30 mm/s");
    assert!(
        r.motions[5].starts_with("PTMEAS (75.0000, 50.0000, 40.0000) along (-1.0000, 0.0000, 0.0000)"),
        "{:?}",
        r.motions
    );
}

#[test]
fn the_nist_example_runs_on_the_virtual_cmm_through_ippdme() {
    let cmm =
        truepos_plant::cmm::serve_loopback(Some(&repo().join("data/dmis/simple_part.toml")), None).unwrap();
    let mut client = truepos_ippdme::connect(&cmm.url).unwrap();
    let plan = plan_of("data/dmis/simple_in.dms");
    let moves = || cmm.handle.shared.with_machine(|m| (m.counters.moves, m.counters.probes));
    let before = moves();
    // PROBE6 is not a tool of the CMM: refused before anything moves.
    let e = run(&plan, &mut client, &RunOptions::default(), &mut |_| {}).unwrap_err();
    match &e {
        RunError::Input(d) => {
            assert_eq!((d.pos.line, d.kind), (12, ErrorKind::Semantic));
            assert!(d.message.contains("--sensor PROBE6=TOOL") && d.message.contains("Probe1"), "{d}");
        }
        other => panic!("{other}"),
    }
    assert_eq!(moves(), before);
    let mut lines = Vec::new();
    let r = run(&plan, &mut client, &sensors(&[("PROBE6", "Probe1")]), &mut |l| lines.push(l.to_string()))
        .unwrap();
    assert_eq!(r.n_points, 4);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].starts_with("line 23: MEAS/CIRCLE,F(A_CIRCLE): 4 points"), "{lines:?}");
    let f = &r.features[0];
    let Geom::Circle { c, n, r: radius } = &f.geom else { panic!("{f:?}") };
    // The realistic virtual CMM (geometric errors of a few µm, probing noise): centre and
    // diameter within 10 µm of the true bore.
    assert!((c.x - 50.0).abs() < 0.01 && (c.y - 50.0).abs() < 0.01 && (c.z - 40.0).abs() < 0.01, "{c:?}");
    assert!((2.0 * radius - 50.0).abs() < 0.01, "{radius}");
    assert!((n.z - 1.0).abs() < 1e-9);
    assert!(r.output.iter().any(|l| l.starts_with("FA(A_CIRCLE) = FEAT/CIRCLE, INNER, CART")));
}

fn tol<'a>(r: &'a truepos_dmis::exec::RunResult, label: &str) -> &'a truepos_dmis::exec::TolResult {
    r.tolerances.iter().find(|t| t.label == label).unwrap_or_else(|| panic!("no TA({label})"))
}

#[test]
fn datums_constructions_and_every_tolerance_on_the_virtual_cmm() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/programs");
    let cmm = truepos_plant::cmm::serve_loopback(Some(&dir.join("full_part.toml")), None).unwrap();
    let mut client = truepos_ippdme::connect(&cmm.url).unwrap();
    let plan = plan_of("crates/dmis/tests/programs/full.dms");
    let r = run(&plan, &mut client, &sensors(&[("P1", "Probe1")]), &mut |_| {}).unwrap();
    assert_eq!(r.n_points, 25);
    // Truth (machine frame): top z = 40, bores at (30, 30) and (130, 30) Ø20, pin (80, 80) Ø12,
    // sphere (80, 150, 60) Ø25. Part frame: origin (30, 30, 40), X along +x. The realistic
    // virtual CMM errs by a few µm: 10 µm bounds.
    let feat =
        |label: &str, k: usize| r.features.iter().filter(|f| f.label == label).nth(k).unwrap().geom.clone();
    let Geom::Circle { c, r: rad, .. } = feat("PIN", 0) else { panic!() };
    assert!((c.x - 50.0).abs() < 0.01 && (c.y - 50.0).abs() < 0.01 && (c.z - 10.0).abs() < 0.01, "{c:?}");
    assert!((2.0 * rad - 12.0).abs() < 0.01, "{rad}");
    let Geom::Point { p, .. } = feat("MID", 0) else { panic!() };
    assert!((p - truepos_math::Point3::new(50.0, 0.0, 0.0)).norm() < 0.01, "{p:?}");
    let Geom::Sphere { c, r: rad } = feat("SPH", 0) else { panic!() };
    assert!((c - truepos_math::Point3::new(50.0, 120.0, 20.0)).norm() < 0.01, "{c:?}");
    assert!((2.0 * rad - 25.0).abs() < 0.01, "{rad}");
    let Geom::Cylinder { axis, r: rad, .. } = feat("B1", 0) else { panic!() };
    assert!((axis.z - 1.0).abs() < 1e-4 && (2.0 * rad - 20.0).abs() < 0.01, "{axis:?} {rad}");
    // C2 in the part frame (twice), then after ROTATE/ZAXIS,90, after TRANS/XORIG,FA(PIN),
    // after RECALL.
    let centres: Vec<truepos_math::Point3> = (0..5)
        .map(|k| match feat("C2", k) {
            Geom::Circle { c, .. } => c,
            g => panic!("{g:?}"),
        })
        .collect();
    for (got, want) in centres.iter().zip([
        [100.0, 0.0, -5.0],
        [100.0, 0.0, -5.0],
        [0.0, -100.0, -5.0],
        [-50.0, -100.0, -5.0],
        [100.0, 0.0, -5.0],
    ]) {
        assert!((got - truepos_math::Point3::from(want)).norm() < 0.01, "{got:?} vs {want:?}");
    }
    // Tolerances: form of exact solids is the machine's error only (µm); positions and sizes
    // within their zones; the ±0.1 µm diameter is out.
    for (label, lo, hi) in [
        ("FL", 0.0, 0.01),
        ("DB1", -0.01, 0.01),
        ("CY", 0.0, 0.01),
        ("PE", 0.0, 0.01),
        ("RO", 0.0, 0.01),
        ("POS2", 0.0, 0.02),
        ("DI", 99.99, 100.01),
        ("SP", -0.01, 0.01),
        ("PIN", 0.0, 0.02),
    ] {
        let t = tol(&r, label);
        assert!(t.value >= lo && t.value <= hi, "{label}: {}", t.value);
        assert!(t.in_tolerance, "{label}: {t:?}");
    }
    let an = tol(&r, "AN");
    assert!(an.angular && (an.value.to_degrees() - 90.0).abs() < 0.01 && an.in_tolerance, "{an:?}");
    assert!(!tol(&r, "TIGHT").in_tolerance);
    assert!(r.any_out_of_tolerance());
    let out = r.output.join("\n");
    assert!(out.contains("D(PART)=DATSET/DAT(A),ZDIR,ZORIG,DAT(B),XDIR,DAT(C),XORIG,YORIG"), "{out}");
    assert!(out.contains("T(FL)=TOL/FLAT,0.02\nTA(FL) = TOL/FLAT, 0.00"), "{out}");
    assert!(out.contains("TA(TIGHT) = TOL/DIAM, ") && out.contains(", OUTOL"), "{out}");
    assert!(out.contains("TEXT/OUTFIL,'end of the tests'\nENDFIL"), "{out}");
    // The JSON of the contract.
    let j = truepos_dmis::report::json("full.dms", &r, Some("full_output.dms"));
    assert_eq!(j["n_points"], 25);
    let pin = j["tolerances"].as_array().unwrap().iter().find(|t| t["label"] == "PIN").unwrap();
    assert_eq!(pin["kind"], "POS");
    assert_eq!(pin["feature"], "PIN");
    assert_eq!(pin["verdict"], "INTOL");
    assert_eq!(pin["limits_mm"][1], 0.05);
}

#[test]
fn a_probing_without_surface_stops_at_its_line_with_the_machine_retracted() {
    // The bore's wall is at x = 75; a first point nominal at x = 60 searches 10 mm past it (the
    // program's SNSET/SEARCH) and finds nothing.
    let text = std::fs::read_to_string(repo().join("data/dmis/simple_in.dms"))
        .unwrap()
        .replace("PTMEAS/CART, 75.0, 50.0, 40.0", "PTMEAS/CART, 60.0, 50.0, 40.0");
    let plan = check(&parse("moved.dms", &text).unwrap()).unwrap();
    let cmm =
        truepos_plant::cmm::serve_loopback(Some(&repo().join("data/dmis/simple_part.toml")), None).unwrap();
    let mut client = truepos_ippdme::connect(&cmm.url).unwrap();
    let e = run(&plan, &mut client, &sensors(&[("PROBE6", "Probe1")]), &mut |_| {}).unwrap_err();
    match &e {
        RunError::Device { line, source, .. } => {
            assert_eq!(*line, 25);
            assert!(matches!(source, truepos_device::DeviceError::NoContact { .. }), "{source}");
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().starts_with("moved.dms:25: "), "{e}");
    // Back at the start of the failed probing: the approach distance (10) and the tip radius
    // (1.5) before the nominal point.
    let at = cmm.handle.shared.with_machine(|m| truepos_ippdme::Cmm::position(m));
    assert!((at.x - (60.0 - 10.0 - 1.5)).abs() < 1e-3 && (at.y - 50.0).abs() < 1e-6, "{at:?}");
}

/// The test block (`tests/programs/block_part.toml`: a block with datum faces, a through bore,
/// a blind bore with its floor, a finite pin and a sphere) measured by `block.dms` on the ideal
/// virtual CMM (`ideal_machine.toml`: exact contacts): every feature and every tolerance equals
/// the part's truth, in the part frame of the datums A (top), B (back), C (right), to 1 µm.
#[test]
fn the_test_block_measures_to_its_truth_on_the_ideal_machine() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/programs");
    let cmm = truepos_plant::cmm::serve_loopback(
        Some(&dir.join("block_part.toml")),
        Some(&dir.join("ideal_machine.toml")),
    )
    .unwrap();
    let mut client = truepos_ippdme::connect(&cmm.url).unwrap();
    let plan = plan_of("crates/dmis/tests/programs/block.dms");
    let r = run(&plan, &mut client, &sensors(&[("P1", "Probe1")]), &mut |_| {}).unwrap();
    assert_eq!(r.n_points, 4 + 4 + 4 + 8 + 4 + 3 + 4 + 5);
    let um = 1e-3;
    let feat = |label: &str| r.features.iter().find(|f| f.label == label).unwrap().geom.clone();
    let near = |got: truepos_math::Point3, want: [f64; 3], what: &str| {
        let e = (got - truepos_math::Point3::from(want)).norm();
        eprintln!("{what}: {e:.2e} mm from the truth");
        assert!(e < um, "{what}: {got:?} vs {want:?}");
    };
    // Truth (part frame = machine − (160, 100, 40)).
    let Geom::Plane { p, n } = feat("TOP") else { panic!() };
    assert!(p.z.abs() < um && (n - truepos_math::Vector3::z()).norm() < 1e-6, "{p:?} {n:?}");
    let Geom::Cylinder { p, axis, r: rad } = feat("B1") else { panic!() };
    near(truepos_math::Point3::new(p.x, p.y, 0.0), [-120.0, -50.0, 0.0], "B1 axis");
    assert!(
        (axis - truepos_math::Vector3::z()).norm() < 1e-6 && (2.0 * rad - 20.0).abs() < um,
        "{axis:?} {rad}"
    );
    let Geom::Circle { c, r: rad, .. } = feat("B2") else { panic!() };
    near(c, [-40.0, -50.0, -10.0], "B2 centre");
    assert!((2.0 * rad - 16.0).abs() < um, "{rad}");
    let Geom::Plane { p, n } = feat("FLOOR") else { panic!() };
    assert!((p.z + 25.0).abs() < um && (n - truepos_math::Vector3::z()).norm() < 1e-6, "{p:?} {n:?}");
    let Geom::Circle { c, r: rad, .. } = feat("PIN") else { panic!() };
    near(c, [-80.0, -75.0, 10.0], "pin centre");
    assert!((2.0 * rad - 10.0).abs() < um, "{rad}");
    let Geom::Sphere { c, r: rad } = feat("SPH") else { panic!() };
    near(c, [-80.0, -20.0, 5.0], "sphere centre");
    assert!((2.0 * rad - 20.0).abs() < um, "{rad}");
    let Geom::Point { p, .. } = feat("P1") else { panic!() };
    near(p, [-120.0, -50.0, 0.0], "B1 axis on datum A");
    // Tolerances: form, orientation and position of a perfect part are zero; sizes and
    // distances their nominal.
    for (label, want) in [
        ("FL", 0.0),
        ("DB1", 0.0),
        ("PE", 0.0),
        ("PA", 0.0),
        ("PB2", 0.0),
        ("PSP", 0.0),
        ("PPIN", 0.0),
        ("DEP", 25.0),
        ("D12", 80.0),
    ] {
        let t = tol(&r, label);
        assert!((t.value - want).abs() < um, "T({label}) = {} vs {want}", t.value);
        assert!(t.in_tolerance, "T({label})");
    }
    assert_eq!(tol(&r, "PB2").datums, ["A", "B", "C"]);
    assert_eq!(tol(&r, "DEP").nominal, Some(25.0));
    assert!(!r.any_out_of_tolerance());
}
