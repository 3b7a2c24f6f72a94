//! The semantic model: programs that parse but cannot run are refused at their place before
//! anything moves; units are converted; a 100,000-line program is parsed and checked in well
//! under a second.

use std::time::Instant;
use truepos_dmis::model::{check, Nominal, Op};
use truepos_dmis::{parse, ErrorKind};

const HEAD: &str = "DMISMN/'t'\nUNITS/MM,ANGDEC\nS(P)=SNSDEF/PROBE,FIXED,CART,0,0,50,0,0,-1,3\nSNSLCT/S(P)\n";

fn checked(body: &str) -> Result<truepos_dmis::model::Plan, truepos_dmis::DmisError> {
    let text = format!("{HEAD}{body}");
    check(&parse("p.dms", &text).expect("parses"))
}

/// `(body after the 4 header lines, line, column, kind, part of the message)`.
const REFUSED: &[(&str, u32, u32, ErrorKind, &str)] = &[
    ("GOTO/1,2,3\n", 5, 1, ErrorKind::Semantic, "no ENDFIL"),
    ("ENDFIL\nGOTO/1,2,3\n", 6, 1, ErrorKind::Semantic, "after ENDFIL"),
    ("DMISMN/'again'\nENDFIL\n", 5, 1, ErrorKind::Semantic, "first statement"),
    ("UNITS/MM,ANGDMS\nENDFIL\n", 5, 10, ErrorKind::Unsupported, "ANGDMS"),
    ("MODE/MAN\nENDFIL\n", 5, 6, ErrorKind::Unsupported, "MODE/MAN"),
    ("MEAS/CIRCLE,F(C),4\nENDMES\nENDFIL\n", 5, 13, ErrorKind::Semantic, "F(C) is not defined"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nMEAS/PLANE,F(C),3\nENDMES\nENDFIL\n", 6, 6, ErrorKind::Semantic, "which is a CIRCLE"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,0,10\nENDFIL\n", 5, 35, ErrorKind::Semantic, "no direction"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,-10\nENDFIL\n", 5, 41, ErrorKind::Semantic, "positive"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nF(c)=FEAT/POINT,CART,0,0,0,0,0,1\nENDFIL\n", 6, 1, ErrorKind::Semantic, "already defined at line 5"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nMEAS/CIRCLE,F(C),4\nPTMEAS/CART,5,0,0\nPTMEAS/CART,0,5,0\nPTMEAS/CART,-5,0,0\nENDMES\nENDFIL\n", 10, 1, ErrorKind::Semantic, "announces 4 points but measures 3"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nMEAS/CIRCLE,F(C),2\nPTMEAS/CART,5,0,0\nPTMEAS/CART,0,5,0\nENDMES\nENDFIL\n", 6, 1, ErrorKind::Semantic, "at least 3 points"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nMEAS/CIRCLE,F(C),3\nPTMEAS/CART,5,0,0\nTEXT/OPER,'x'\nENDMES\nENDFIL\n", 8, 1, ErrorKind::Semantic, "not allowed between MEAS (line 6)"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nMEAS/CIRCLE,F(C),3\nPTMEAS/CART,5,0,0\n", 6, 1, ErrorKind::Semantic, "MEAS without ENDMES"),
    ("PTMEAS/CART,5,0,0\nENDFIL\n", 5, 1, ErrorKind::Semantic, "outside MEAS"),
    ("ENDMES\nENDFIL\n", 5, 1, ErrorKind::Semantic, "ENDMES without MEAS"),
    ("SNSLCT/S(Q)\nENDFIL\n", 5, 8, ErrorKind::Semantic, "S(Q) is not defined"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nOUTPUT/FA(C)\nENDFIL\n", 6, 8, ErrorKind::Semantic, "has not been measured"),
    ("F(C)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,10\nDAT(A)=DATDEF/FA(C)\nENDFIL\n", 6, 15, ErrorKind::Semantic, "has not been measured"),
    ("D(X)=DATSET/DAT(A),ZDIR\nENDFIL\n", 5, 13, ErrorKind::Semantic, "DAT(A) is not defined"),
    ("RECALL/DA(NOPE)\nENDFIL\n", 5, 8, ErrorKind::Semantic, "neither defined"),
    ("T(P)=TOL/POS,2D,0.1,MMC\nENDFIL\n", 5, 21, ErrorKind::Unsupported, "bonus"),
    ("T(F)=TOL/FLAT,0\nENDFIL\n", 5, 15, ErrorKind::Semantic, "positive"),
    ("T(D)=TOL/DIAM,0.1,-0.1\nENDFIL\n", 5, 15, ErrorKind::Semantic, "above the upper"),
    ("T(D)=TOL/DIAM,-0.1,0.1\nOUTPUT/TA(D)\nENDFIL\n", 6, 8, ErrorKind::Semantic, "applies to 1 feature"),
    ("T(D)=TOL/DIAM,-0.1,0.1\nOUTPUT/TA(X)\nENDFIL\n", 6, 8, ErrorKind::Semantic, "T(X) is not defined"),
    ("F(P)=FEAT/PLANE,CART,0,0,0,0,0,1\nMEAS/PLANE,F(P),3\nPTMEAS/CART,0,0,0\nPTMEAS/CART,1,0,0\nPTMEAS/CART,0,1,0\nENDMES\nT(D)=TOL/DIAM,-0.1,0.1\nOUTPUT/FA(P),TA(D)\nENDFIL\n", 12, 8, ErrorKind::Semantic, "does not apply to a PLANE"),
    ("F(P)=FEAT/PLANE,CART,0,0,0,0,0,1\nMEAS/PLANE,F(P),3\nPTMEAS/CART,0,0,0\nPTMEAS/CART,1,0,0\nPTMEAS/CART,0,1,0\nENDMES\nF(Q)=FEAT/PLANE,CART,0,0,0,0,0,1\nCONST/PLANE,F(Q),BF,FA(P),FA(P),FA(P)\nENDFIL\n", 12, 21, ErrorKind::Semantic, "BF takes the positions"),
    ("F(P)=FEAT/PLANE,CART,0,0,0,0,0,1\nMEAS/PLANE,F(P),3\nPTMEAS/CART,0,0,0\nPTMEAS/CART,1,0,0\nPTMEAS/CART,0,1,0\nENDMES\nF(Q)=FEAT/CIRCLE,INNER,CART,0,0,0,0,0,1,3\nCONST/CIRCLE,F(Q),INTOF,FA(P),FA(P)\nENDFIL\n", 12, 19, ErrorKind::Unsupported, "INTOF,PLANE,PLANE"),
    ("F(P)=FEAT/PLANE,CART,0,0,0,0,0,1\nMEAS/PLANE,F(P),3\nPTMEAS/CART,0,0,0\nPTMEAS/CART,1,0,0\nPTMEAS/CART,0,1,0\nENDMES\nDAT(A)=DATDEF/FA(P)\nD(X)=DATSET/DAT(A),ZDIR,ZORIG,DAT(A),ZORIG\nENDFIL\n", 12, 38, ErrorKind::Semantic, "ZORIG is set twice"),
    ("F(P)=FEAT/PLANE,CART,0,0,0,0,0,1\nMEAS/PLANE,F(P),3\nPTMEAS/CART,0,0,0\nPTMEAS/CART,1,0,0\nPTMEAS/CART,0,1,0\nENDMES\nT(P)=TOL/POS,3D,0.1,RFS,DAT(A)\nENDFIL\n", 11, 25, ErrorKind::Semantic, "DAT(A) is not defined"),
    ("TEXT/QUERY,'how many?'\nENDFIL\n", 5, 6, ErrorKind::Unsupported, "QUERY"),
    ("OPEN/DID(X),DIRECT,OUTPUT\nENDFIL\n", 5, 6, ErrorKind::Semantic, "DID(X) is not defined"),
    ("F(C)=FEAT/CONE,INNER,CART,0,0,0,0,0,1,180\nENDFIL\n", 5, 39, ErrorKind::Semantic, "between 0 and 180"),
];

#[test]
fn inconsistent_programs_are_refused_at_their_place() {
    let mut bad = Vec::new();
    for (body, line, col, kind, msg) in REFUSED {
        match checked(body) {
            Ok(_) => bad.push(format!("{body:?}: accepted")),
            Err(e) => {
                if (e.pos.line, e.pos.col, e.kind) != (*line, *col, *kind) || !e.message.contains(msg) {
                    bad.push(format!("{body:?}: {e} ({:?})", e.kind));
                }
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    let e = check(&parse("e.dms", "").unwrap()).unwrap_err();
    assert!(e.message.contains("empty"));
    let e = check(&parse("e.dms", "GOTO/1,2,3\nENDFIL\n").unwrap()).unwrap_err();
    assert_eq!((e.pos.line, e.pos.col), (1, 1));
}

#[test]
fn inches_and_radians_are_converted() {
    let p = checked(
        "UNITS/INCH,ANGRAD\nF(C)=FEAT/CIRCLE,INNER,CART,1,2,3,0,0,2,0.5\nF(K)=FEAT/CONE,INNER,CART,0,0,0,0,0,1,1\nGOTO/1,0,0\nFEDRAT/MESVEL,IPS,0.1\nROTATE/ZAXIS,0.5\nENDFIL\n",
    )
    .unwrap();
    match &p.features[0].nominal {
        Nominal::Circle { c, n, r } => {
            assert!((c - truepos_math::Point3::new(25.4, 50.8, 76.2)).norm() < 1e-12, "{c:?}");
            assert_eq!(n.z, 1.0);
            assert!((r - 6.35).abs() < 1e-12);
        }
        other => panic!("{other:?}"),
    }
    match &p.features[1].nominal {
        Nominal::Cone { half_angle, .. } => assert!((half_angle - 0.5).abs() < 1e-15),
        other => panic!("{other:?}"),
    }
    let ops: Vec<&Op> = p.steps.iter().map(|s| &s.op).collect();
    assert!(ops.iter().any(|o| matches!(o, Op::Goto(q) if q.x == 25.4)));
    assert!(ops.iter().any(|o| matches!(o, Op::Feed { mm_s: Some(v), .. } if (v - 2.54).abs() < 1e-12)));
    assert!(ops
        .iter()
        .any(|o| matches!(o, Op::Rotate { by: truepos_dmis::model::RotateTo::Angle(a), .. } if *a == 0.5)));
}

#[test]
fn the_full_test_program_checks() {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/programs/full.dms")).unwrap();
    let p = check(&parse("full.dms", &text).unwrap()).unwrap();
    assert_eq!(p.n_probes, 4 + 8 + 4 + 4 + 5);
    assert_eq!(p.output_file.as_deref(), Some("full_output.dms"));
    assert_eq!(p.tolerances.len(), 11);
}

/// A program of `lines` lines: header, then circles with four points each.
pub fn big_program(lines: usize) -> String {
    let mut s = String::with_capacity(lines * 40);
    s.push_str(HEAD);
    let mut n = 4;
    let mut k = 0;
    while n + 8 < lines {
        let (x, y) = ((k % 100) as f64 * 30.0, (k / 100) as f64 * 30.0);
        s.push_str(&format!("F(C{k})=FEAT/CIRCLE,INNER,CART,{x},{y},-5,0,0,1,20\n"));
        s.push_str(&format!("MEAS/CIRCLE,F(C{k}),4\n"));
        s.push_str(&format!("  PTMEAS/CART,{},{y},-5,-1,0,0\n", x + 10.0));
        s.push_str(&format!("  PTMEAS/CART,{x},{}, $\n    -5,0,-1,0\n", y + 10.0));
        s.push_str(&format!("  PTMEAS/CART,{},{y},-5,1.0E0,0,0\n", x - 10.0));
        s.push_str(&format!("  PTMEAS/CART,{x},{},-5,0,1,0\nENDMES\n", y - 10.0));
        s.push_str(&format!("OUTPUT/FA(C{k})\n"));
        n += 9;
        k += 1;
    }
    while n + 1 < lines {
        s.push_str("$$ filler\n");
        n += 1;
    }
    s.push_str("ENDFIL\n");
    s
}

#[test]
fn a_100000_line_program_parses_and_checks_in_well_under_a_second() {
    let text = big_program(100_000);
    assert_eq!(text.lines().count(), 100_000);
    let t = Instant::now();
    let p = parse("big.dms", &text).unwrap();
    let t_parse = t.elapsed().as_secs_f64();
    let plan = check(&p).unwrap();
    let t_all = t.elapsed().as_secs_f64();
    eprintln!("100,000 lines ({} bytes): parse {:.3} s, parse + check {:.3} s", text.len(), t_parse, t_all);
    assert_eq!(plan.n_probes, 4 * plan.features.len());
    // The contract's figure is 1 s (release build); the bound here leaves room for a loaded CI
    // machine running the test profile.
    assert!(t_all < 3.0, "{t_all} s");
}

/// The executor's own cost per PTMEAS (issue 29: under 1 ms): the 100,000-line program's 44,440
/// probings run on the dry-run machine (which answers at once), so the time is the executor's —
/// its bookkeeping, the coordinate systems, the compensation, the fits and the outputs.
#[test]
fn the_executor_costs_well_under_a_millisecond_per_ptmeas() {
    use truepos_dmis::exec::{run, DryRun, RunOptions};
    let plan = check(&parse("big.dms", &big_program(100_000)).unwrap()).unwrap();
    let opts = RunOptions::default();
    let mut machine = DryRun::new(&plan, &opts);
    let t = Instant::now();
    let r = run(&plan, &mut machine, &opts, &mut |_| {}).expect("the program runs");
    let s = t.elapsed().as_secs_f64();
    let n = r.probes.len();
    assert_eq!(n, plan.n_probes);
    let per = s / n as f64;
    eprintln!("executor: {n} PTMEAS in {s:.3} s: {:.1} µs per PTMEAS (fits and outputs included)", per * 1e6);
    // The contract's figure is 1 ms; measured in the tens of µs, so a loaded machine passes too.
    assert!(per < 1e-3, "{per} s per PTMEAS");
}

/// Second hostile audit of issue 31: a `DEVICE/STOR` output that names a folder (F25: it wrote
/// three folders above the program) is refused at the OPEN; `IF/(…)` is named as outside the
/// subset like DO and CALL (F24: "unexpected character '('"); CR-only line ends are named as
/// such at the first one (F21: "',' expected … found the word UNITS").
#[test]
fn output_folders_flow_control_and_cr_only_line_ends_are_named() {
    for (f, ok) in [
        ("out.dms", true),
        ("../../../escaped.dms", false),
        ("/tmp/x.dms", false),
        ("sub/x.dms", false),
        ("..", false),
    ] {
        let r = checked(&format!("DID(O)=DEVICE/STOR,'{f}'\nOPEN/DID(O),DIRECT,OUTPUT,OVERWR\nENDFIL\n"));
        match r {
            Ok(plan) => {
                assert!(ok, "{f} accepted");
                assert_eq!(plan.output_file.as_deref(), Some(f));
            }
            Err(e) => {
                assert!(!ok, "{f}: {e}");
                assert_eq!((e.pos.line, e.pos.col, e.kind), (6, 6, ErrorKind::Unsupported), "{e}");
                assert!(e.to_string().contains("not a plain file name"), "{e}");
            }
        }
    }
    let e = parse("p.dms", &format!("{HEAD}IF/(1 .EQ. 1)\nENDIF\nENDFIL\n")).unwrap_err();
    assert_eq!((e.pos.line, e.pos.col, e.kind), (5, 1, ErrorKind::Unsupported), "{e}");
    assert!(e.to_string().contains("IF is outside the DMIS subset"), "{e}");
    let mac = format!("{HEAD}ENDFIL\n").replace('\n', "\r");
    let e = parse("p.dms", &mac).unwrap_err();
    assert_eq!((e.pos.line, e.pos.col), (1, 11), "{e}");
    assert!(e.to_string().contains("CR-only line ends"), "{e}");
    // CRLF is a line end.
    check(&parse("p.dms", &format!("{HEAD}ENDFIL\n").replace('\n', "\r\n")).unwrap()).unwrap();
}
