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
    RunOptions { sensors: pairs.iter().map(|(a, b)| (a.to_string(), b.to_string())).collect::<HashMap<_, _>>() }
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
    assert!(out.starts_with("FILNAM/'IPP SIMPLE DMIS output'\nUNITS/MM,ANGDEC\nD(START)=DATSET/MCS\n"), "{out}");
    assert!(out.ends_with("OUTPUT/FA(A_CIRCLE)\nFA(A_CIRCLE) = FEAT/CIRCLE, INNER, CART,  $\n  50.00000, 50.00000, 40.00000, 0.00000, 0.00000, 1.00000, 50.00000\nENDFIL"), "{out}");
    // The motions of simple.prg: GoTo 175, 75, 40, four PtMeas, GoTo 40, 100.
    let kinds: Vec<&str> = r.motions.iter().filter_map(|m| m.split(' ').next()).collect();
    assert_eq!(kinds, ["GOTO", "line", "GOTO", "GOTO", "PTMEAS", "PTMEAS", "PTMEAS", "PTMEAS", "GOTO", "GOTO"]);
    assert!(r.motions[4].starts_with("PTMEAS (75.0000, 50.0000, 40.0000) along (-1.0000, 0.0000, 0.0000)"), "{:?}", r.motions);
}

#[test]
fn the_nist_example_runs_on_the_virtual_cmm_through_ippdme() {
    let cmm = truepos_cell::cmm::serve_loopback(Some(&repo().join("data/dmis/simple_part.toml")), None).unwrap();
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
    let r = run(&plan, &mut client, &sensors(&[("PROBE6", "Probe1")]), &mut |l| lines.push(l.to_string())).unwrap();
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
