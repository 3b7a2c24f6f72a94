//! The parser on the NIST example, on a program with every statement kind, on malformed
//! programs (each error's line and column asserted), and the round trip
//! `parse(print(parse(p))) == parse(p)` as a property over generated statements.

use proptest::prelude::*;
use std::path::PathBuf;
use truepos_dmis::ast::*;
use truepos_dmis::{parse, ErrorKind};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(repo().join(rel)).unwrap()
}

#[test]
fn the_nist_example_parses_to_its_statements() {
    let p = parse("simple_in.dms", &read("data/dmis/simple_in.dms")).unwrap();
    assert_eq!(p.statements.len(), 24);
    let s = p.statements();
    assert_eq!(s[0], &Statement::Dmismn { title: "IPP SIMPLE DMIS program".into(), version: None });
    assert_eq!(s[2], &Statement::Units { length: LengthUnit::Mm, angle: AngleUnit::AngDec, temp: None });
    assert_eq!(
        s[5],
        &Statement::Snsdef {
            label: Label::new(LabelKind::S, "PROBE6"),
            offset: [0.0, 0.0, 30.0],
            dir: [0.0, 0.0, -1.0],
            diam: 4.0
        }
    );
    assert_eq!(s[11], &Statement::Fedrat { kind: FeedKind::PosVel, unit: FeedUnit::Mpm, value: Some(1.8) });
    assert_eq!(
        s[12],
        &Statement::Feat {
            label: Label::new(LabelKind::F, "A_CIRCLE"),
            geom: FeatGeom::Circle {
                side: Side::Inner,
                c: [50.0, 50.0, 40.0],
                n: [0.0, 0.0, 1.0],
                diam: 50.0
            }
        }
    );
    assert_eq!(
        s[13],
        &Statement::Meas { ftype: FeatType::Circle, feature: Label::new(LabelKind::F, "A_CIRCLE"), n: 4 }
    );
    assert_eq!(s[15], &Statement::Ptmeas { p: [75.0, 50.0, 40.0], n: Some([-1.0, 0.0, 0.0]) });
    assert_eq!(s[20], &Statement::Endmes);
    assert_eq!(s[23], &Statement::Endfil);
    // Lines and columns: the statement after four comment lines.
    assert_eq!((p.statements[2].pos.line, p.statements[2].pos.col), (8, 1));
    assert_eq!((p.statements[15].args[1].line, p.statements[15].args[1].col), (25, 14));
}

#[test]
fn the_nist_output_file_parses_with_its_continuation() {
    let p = parse("simple_output.dms", &read("data/dmis/simple_output.dms")).unwrap();
    let s = p.statements();
    assert_eq!(s.len(), 6);
    assert_eq!(
        s[4],
        &Statement::Feat {
            label: Label::new(LabelKind::Fa, "A_CIRCLE"),
            geom: FeatGeom::Circle {
                side: Side::Inner,
                c: [50.0, 50.0, 40.0],
                n: [0.0, 0.0, 1.0],
                diam: 50.0
            }
        }
    );
}

#[test]
fn every_statement_kind_parses_and_prints_back() {
    let text = read("crates/dmis/tests/programs/every_statement.dms");
    let p = parse("every_statement.dms", &text).unwrap();
    let majors: std::collections::BTreeSet<&str> = p.statements().iter().map(|s| s.major()).collect();
    for m in [
        "DMISMN", "FILNAM", "UNITS", "DISPLY", "PRCOMP", "MODE", "FEDRAT", "DEVICE", "OPEN", "SNSDEF",
        "SNSMNT", "SNSLCT", "SNSET", "GOTO", "DATSET", "FEAT", "MEAS", "PTMEAS", "ENDMES", "CONST", "DATDEF",
        "TRANS", "ROTATE", "SAVE", "RECALL", "TOL", "OUTPUT", "TEXT", "CLOSE", "ENDFIL",
    ] {
        assert!(majors.contains(m), "{m} missing");
    }
    // Lower case is the same statement.
    assert_eq!(
        p.statements[1].statement,
        Statement::Filnam { name: "every statement".into(), version: Some(5.2) }
    );
    let printed = p.print();
    let again = parse("printed", &printed).unwrap();
    assert_eq!(again.statements(), p.statements());
    assert_eq!(again.print(), printed);
    // DMISMD files parse too.
    let m = parse("m.dms", "DMISMD/'module',4.0\nENDFIL\n").unwrap();
    assert_eq!(m.statements[0].statement, Statement::Dmismd { title: "module".into(), version: Some(4.0) });
}

/// `(program, line, column, kind, part of the message)`.
const MALFORMED: &[(&str, u32, u32, ErrorKind, &str)] = &[
    ("DMISMN/'x'\nGOTO/1,2\n", 2, 9, ErrorKind::Syntax, "third of three"),
    ("DMISMN/'x'\nGOTO/1,2,3,4\n", 2, 12, ErrorKind::Syntax, "too many"),
    ("DMISMN/'x'\nGOTO/1,,3\n", 2, 8, ErrorKind::Syntax, "argument expected"),
    ("DMISMN/'x'\nGOTO/1,2,\n", 2, 9, ErrorKind::Syntax, "after the last"),
    ("DMISMN/'x'\nGOTO/1 2,3\n", 2, 8, ErrorKind::Syntax, "',' expected"),
    ("DMISMN/'x'\nGOTO 1,2,3\n", 2, 6, ErrorKind::Syntax, "'/' expected"),
    ("DMISMN/'x'\nUNITS/MM,ANGDMX\n", 2, 10, ErrorKind::Unsupported, "ANGDMX"),
    ("DMISMN/'x'\nUNITS/FURLONG,ANGDEC\n", 2, 7, ErrorKind::Unsupported, "FURLONG"),
    ("DMISMN/'x'\nFOO/1\n", 2, 1, ErrorKind::Syntax, "not a DMIS statement"),
    ("DMISMN/'x'\nDECL/GLOBAL,REAL,X\n", 2, 1, ErrorKind::Unsupported, "outside the DMIS subset"),
    ("DMISMN/'x'\nF(C)=FEAT/CIRCLE,INNER,POL,1,2,3,0,0,1,5\n", 2, 24, ErrorKind::Unsupported, "CART"),
    ("DMISMN/'x'\nF(C)=FEAT/TORUS,INNER,CART,1,2,3\n", 2, 11, ErrorKind::Unsupported, "TORUS"),
    ("DMISMN/'x'\nFEAT/CIRCLE,INNER,CART,1,2,3,0,0,1,5\n", 2, 1, ErrorKind::Syntax, "needs a label"),
    ("DMISMN/'x'\nT(C)=FEAT/CIRCLE,INNER,CART,1,2,3,0,0,1,5\n", 2, 1, ErrorKind::Syntax, "F() or FA()"),
    ("DMISMN/'x'\nX(C)=FEAT/CIRCLE,INNER,CART,1,2,3,0,0,1,5\n", 2, 1, ErrorKind::Unsupported, "X()"),
    ("DMISMN/'x'\nMEAS/CIRCLE,F(C),2.5\n", 2, 18, ErrorKind::Syntax, "whole number"),
    ("DMISMN/'x'\nMEAS/CIRCLE,FA(C),4\n", 2, 13, ErrorKind::Syntax, "F() label"),
    ("DMISMN/'x'\nTEXT/OPER,'never closed\n", 2, 11, ErrorKind::Syntax, "apostrophe"),
    ("DMISMN/'x'\nGOTO/1,2,3 $ 4\n", 2, 12, ErrorKind::Syntax, "'$'"),
    ("DMISMN/'x'\nGOTO/1,2,3;\n", 2, 11, ErrorKind::Syntax, "unexpected character"),
    ("DMISMN/'x'\nGOTO/1,2, $\n  3e999\n", 3, 3, ErrorKind::Syntax, "out of range"),
    ("DMISMN/'x'\nGOTO/1,2, $\n\n", 2, 9, ErrorKind::Syntax, "after the last"),
    ("DMISMN/'x'\nF(A B)=FEAT/POINT,CART,0,0,0,0,0,1\n", 2, 4, ErrorKind::Syntax, "label name"),
    ("DMISMN/'x'\nF()=FEAT/POINT,CART,0,0,0,0,0,1\n", 2, 3, ErrorKind::Syntax, "no name"),
    ("DMISMN/'x'\nF(A=FEAT/POINT,CART,0,0,0,0,0,1\n", 2, 4, ErrorKind::Syntax, "label name"),
    ("DMISMN/'x'\nT(P)=TOL/POS,4D,0.1,RFS\n", 2, 14, ErrorKind::Unsupported, "4D"),
    ("DMISMN/'x'\nT(P)=TOL/PROFS,0.1\n", 2, 10, ErrorKind::Unsupported, "PROFS"),
    ("DMISMN/'x'\nT(P)=TOL/DISTB,40,-0.1,0.1\n", 2, 16, ErrorKind::Syntax, "NOMINL"),
    ("DMISMN/'x'\nSNSET/VALUE,1\n", 2, 7, ErrorKind::Unsupported, "VALUE"),
    ("DMISMN/'x'\nS(P)=SNSDEF/PROBE,INDEX,CART,0,0,0\n", 2, 19, ErrorKind::Unsupported, "INDEX"),
    ("DMISMN/'x'\nD(X)=DATSET/DAT(A),ZDIR,DAT(B)\n", 2, 31, ErrorKind::Syntax, "axis or origin"),
    ("DMISMN/'x'\nD(X)=DATSET/DAT(A),WDIR\n", 2, 20, ErrorKind::Unsupported, "WDIR"),
    ("DMISMN/'x'\nCONST/POINT,F(P),TANTO,FA(A),FA(B)\n", 2, 18, ErrorKind::Unsupported, "TANTO"),
    ("DMISMN/'x'\nOUTPUT/\n", 2, 8, ErrorKind::Syntax, "expected at the end"),
    ("DMISMN/'x'\n= GOTO/1,2,3\n", 2, 1, ErrorKind::Syntax, "major word"),
    ("DMISMN/'x'\nGOTO/1,2,3=\n", 2, 11, ErrorKind::Syntax, "',' expected"),
    ("DMISMN/'x'\n+FEAT/1\n", 2, 1, ErrorKind::Syntax, "unexpected character"),
    ("DMISMN/'x'\nGOTO/.,1,2\n", 2, 6, ErrorKind::Syntax, "is not a number"),
];

#[test]
fn malformed_programs_are_refused_at_their_place() {
    for (text, line, col, kind, msg) in MALFORMED {
        let e = parse("bad.dms", text).expect_err(text);
        assert_eq!((e.pos.line, e.pos.col, e.kind), (*line, *col, *kind), "{text:?}: {e}");
        assert!(e.to_string().starts_with(&format!("bad.dms:{line}:{col}: ")), "{e}");
        assert!(e.message.contains(msg), "{text:?}: {e}");
    }
}

#[test]
fn columns_count_characters_not_bytes() {
    let e = parse("u.dms", "TEXT/OPER,'é ü'\nGOTO/1,2,x\n").unwrap_err();
    assert_eq!((e.pos.line, e.pos.col), (2, 10));
    let e = parse("u.dms", "TEXT/OPER,'é ü',X\n").unwrap_err();
    assert_eq!((e.pos.line, e.pos.col), (1, 17));
}

// ---------------------------------------------------------------------------------------------
// Round trip over generated statements.

fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        (-100_000i64..100_000).prop_map(|v| v as f64 / 1000.0),
        prop::num::f64::NORMAL | prop::num::f64::ZERO | prop::num::f64::SUBNORMAL,
        Just(-0.0),
    ]
}
fn xyz() -> impl Strategy<Value = Xyz> {
    [number(), number(), number()]
}
fn name() -> impl Strategy<Value = String> {
    "[A-Za-z0-9_][A-Za-z0-9_.-]{0,15}"
}
fn label(k: LabelKind) -> impl Strategy<Value = Label> {
    name().prop_map(move |n| Label { kind: k, name: n })
}
fn label_of(ks: &'static [LabelKind]) -> impl Strategy<Value = Label> {
    (prop::sample::select(ks), name()).prop_map(|(kind, name)| Label { kind, name })
}
fn text() -> impl Strategy<Value = String> {
    "[ -~]{0,24}"
}
fn pick<T: Copy + std::fmt::Debug + 'static>(all: &'static [T]) -> impl Strategy<Value = T> {
    prop::sample::select(all)
}

fn geom() -> impl Strategy<Value = FeatGeom> {
    prop_oneof![
        (xyz(), xyz()).prop_map(|(p, n)| FeatGeom::Point { p, n }),
        (xyz(), xyz()).prop_map(|(p, n)| FeatGeom::Plane { p, n }),
        (xyz(), xyz(), prop::option::of(xyz())).prop_map(|(p, dir, plane)| FeatGeom::LineUnbnd {
            p,
            dir,
            plane
        }),
        (xyz(), xyz(), prop::option::of(xyz())).prop_map(|(p1, p2, plane)| FeatGeom::LineBnd {
            p1,
            p2,
            plane
        }),
        (pick(Side::ALL), xyz(), xyz(), number()).prop_map(|(side, c, n, diam)| FeatGeom::Circle {
            side,
            c,
            n,
            diam
        }),
        (pick(Side::ALL), xyz(), xyz(), number(), prop::option::of(number()))
            .prop_map(|(side, p, axis, diam, length)| FeatGeom::Cylndr { side, p, axis, diam, length }),
        (pick(Side::ALL), xyz(), prop::option::of(xyz()), number())
            .prop_map(|(side, c, n, diam)| FeatGeom::Sphere { side, c, n, diam }),
        (pick(Side::ALL), xyz(), xyz(), number()).prop_map(|(side, apex, axis, angle)| FeatGeom::Cone {
            side,
            apex,
            axis,
            angle
        }),
    ]
}

fn tol() -> impl Strategy<Value = Tol> {
    const DATS: &[LabelKind] = &[LabelKind::Dat, LabelKind::Da];
    const REFS: &[LabelKind] = &[LabelKind::Dat, LabelKind::Da, LabelKind::Fa, LabelKind::F];
    prop_oneof![
        number().prop_map(Tol::Flat),
        number().prop_map(Tol::Strght),
        number().prop_map(Tol::Cirlty),
        number().prop_map(Tol::Cylcty),
        (number(), number()).prop_map(|(lo, hi)| Tol::Diam { lo, hi }),
        (number(), number()).prop_map(|(lo, hi)| Tol::Rad { lo, hi }),
        (any::<bool>(), number(), pick(MatCond::ALL), prop::collection::vec(label_of(DATS), 0..4))
            .prop_map(|(three_d, zone, cond, datums)| Tol::Pos { three_d, zone, cond, datums }),
        (number(), label_of(REFS)).prop_map(|(zone, datum)| Tol::Perp { zone, datum }),
        (number(), label_of(REFS)).prop_map(|(zone, datum)| Tol::Parlel { zone, datum }),
        (number(), number(), number()).prop_map(|(angle, lo, hi)| Tol::Anglb { angle, lo, hi }),
        (number(), number(), number(), prop::option::of(pick(DistAxis::ALL)))
            .prop_map(|(dist, lo, hi, axis)| Tol::Distb { dist, lo, hi, axis }),
    ]
}

fn statement() -> impl Strategy<Value = Statement> {
    use LabelKind as L;
    const SRC: &[LabelKind] = &[L::Fa, L::F];
    const DATSRC: &[LabelKind] = &[L::Dat, L::Da, L::Fa];
    const OUT: &[LabelKind] = &[L::Fa, L::F, L::Ta, L::T];
    let header = prop_oneof![
        (text(), prop::option::of(number()))
            .prop_map(|(title, version)| Statement::Dmismn { title, version }),
        (text(), prop::option::of(number()))
            .prop_map(|(title, version)| Statement::Dmismd { title, version }),
        (text(), prop::option::of(number())).prop_map(|(name, version)| Statement::Filnam { name, version }),
        Just(Statement::Endfil),
        Just(Statement::Endmes),
        (pick(LengthUnit::ALL), pick(AngleUnit::ALL), prop::option::of(pick(TempUnit::ALL)))
            .prop_map(|(length, angle, temp)| Statement::Units { length, angle, temp }),
        prop::collection::vec(
            prop_oneof![
                prop::sample::select(&["OFF", "TERM", "STOR", "PRINT", "COMM", "DMIS", "V"][..])
                    .prop_map(|w| DisplyItem::Word(w.to_string())),
                label(L::Did).prop_map(DisplyItem::Device),
            ],
            1..5
        )
        .prop_map(Statement::Disply),
        any::<bool>().prop_map(Statement::Prcomp),
        prop::collection::vec(pick(ModeWord::ALL), 1..4).prop_map(Statement::Mode),
        (pick(FeedKind::ALL), pick(FeedUnit::ALL), number()).prop_map(|(kind, unit, v)| Statement::Fedrat {
            kind,
            unit,
            value: (!matches!(unit, FeedUnit::High | FeedUnit::Low | FeedUnit::Defalt)).then_some(v)
        }),
    ];
    let sensors = prop_oneof![
        number().prop_map(|v| Statement::Snset(Snset::Apprch(v))),
        number().prop_map(|v| Statement::Snset(Snset::Retrct(v))),
        number().prop_map(|v| Statement::Snset(Snset::Search(v))),
        number().prop_map(|v| Statement::Snset(Snset::Depth(v))),
        (prop::option::of(label_of(SRC)), number()).prop_map(|(l, v)| Statement::Snset(Snset::Clrsrf(l, v))),
        Just(Statement::Snset(Snset::ClrsrfOff)),
        (label(L::S), xyz(), xyz(), number()).prop_map(|(label, offset, dir, diam)| Statement::Snsdef {
            label,
            offset,
            dir,
            diam
        }),
        label_of(&[L::S, L::Sa]).prop_map(Statement::Snslct),
        (xyz(), xyz(), xyz()).prop_map(|(xvec, zvec, mntlen)| Statement::Snsmnt { xvec, zvec, mntlen }),
        xyz().prop_map(|p| Statement::Goto(Goto::Abs(p))),
        (number(), xyz()).prop_map(|(dist, dir)| Statement::Goto(Goto::Incr { dist, dir })),
        (xyz(), prop::option::of(xyz())).prop_map(|(p, n)| Statement::Ptmeas { p, n }),
    ];
    let features = prop_oneof![
        (label_of(&[L::F, L::Fa]), geom()).prop_map(|(label, geom)| Statement::Feat { label, geom }),
        (pick(FeatType::ALL), label(L::F), 1u32..100_000).prop_map(|(ftype, feature, n)| Statement::Meas {
            ftype,
            feature,
            n
        }),
        (
            pick(FeatType::ALL),
            label(L::F),
            prop_oneof![
                prop::collection::vec(label_of(SRC), 1..6).prop_map(ConstMethod::Bf),
                (label_of(SRC), label_of(SRC)).prop_map(|(a, b)| ConstMethod::Intof(a, b)),
                (label_of(SRC), label_of(SRC)).prop_map(|(a, b)| ConstMethod::Projct(a, b)),
                (label_of(SRC), label_of(SRC)).prop_map(|(a, b)| ConstMethod::Midpt(a, b)),
            ]
        )
            .prop_map(|(ftype, feature, method)| Statement::Const { ftype, feature, method }),
        (label_of(&[L::Dat, L::Da]), label_of(SRC), any::<bool>())
            .prop_map(|(datum, feature, assigned)| Statement::Datdef { datum, feature, assigned }),
        (
            label(L::D),
            prop_oneof![
                Just(Datset::Mcs),
                prop::collection::vec(
                    (label_of(DATSRC), prop::collection::vec(pick(DatsetWord::ALL), 1..4)),
                    1..4
                )
                .prop_map(Datset::Datums)
            ]
        )
            .prop_map(|(label, def)| Statement::Datset { label, def }),
        (
            prop::option::of(label(L::D)),
            prop::collection::vec(
                (
                    pick(Origin::ALL),
                    prop_oneof![number().prop_map(TransBy::Value), label_of(SRC).prop_map(TransBy::Feature)]
                ),
                1..4
            )
        )
            .prop_map(|(label, items)| Statement::Trans { label, items }),
        (
            prop::option::of(label(L::D)),
            pick(RotAxis::ALL),
            prop_oneof![
                number().prop_map(RotateBy::Angle),
                (label_of(SRC), pick(AxisDir::ALL)).prop_map(|(l, d)| RotateBy::Feature(l, d))
            ]
        )
            .prop_map(|(label, axis, by)| Statement::Rotate { label, axis, by }),
        label_of(&[L::D, L::Da]).prop_map(Statement::Save),
        label_of(&[L::D, L::Da]).prop_map(Statement::Recall),
        (label(L::T), tol()).prop_map(|(label, tol)| Statement::Tol { label, tol }),
        prop::collection::vec(label_of(OUT), 1..5).prop_map(Statement::Output),
        (pick(TextKind::ALL), text()).prop_map(|(kind, text)| Statement::Text { kind, text }),
        (label(L::Did), pick(DeviceKind::ALL), prop::option::of(text()))
            .prop_map(|(label, kind, file)| Statement::Device { label, kind, file }),
        (
            label(L::Did),
            prop::collection::vec(
                prop::sample::select(&["DIRECT", "OUTPUT", "OVERWR", "APPEND"][..]).prop_map(String::from),
                0..4
            )
        )
            .prop_map(|(device, words)| Statement::Open { device, words }),
        (
            label(L::Did),
            prop::option::of(prop::sample::select(&["KEEP", "DELETE"][..]).prop_map(String::from))
        )
            .prop_map(|(device, word)| Statement::Close { device, word }),
    ];
    prop_oneof![header, sensors, features]
}

/// The printed statement with blanks after commas, a lower-case major word and continuations:
/// the same statement for DMIS.
fn reformat(s: &str, seed: u64) -> String {
    let mut out = String::new();
    let mut in_text = false;
    let mut k = seed;
    for (i, c) in s.chars().enumerate() {
        k = k.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        if c == '\'' {
            in_text = !in_text;
        }
        if !in_text
            && i < 3
            && c.is_ascii_alphabetic()
            && s.contains('/')
            && !s.starts_with(char::is_lowercase)
        {
            // lower-case the first letters of the major word (not of labels)
            if s[..s.find(['/', '=', '(']).unwrap_or(0)].len() > i {
                out.push(c.to_ascii_lowercase());
                continue;
            }
        }
        out.push(c);
        if !in_text && c == ',' {
            match k >> 61 {
                0 => out.push_str(" $\n   "),
                1 => out.push_str("  "),
                2 => out.push_str(" $ $$ no: a comment\n"),
                _ => {}
            }
        }
    }
    out.replace(" $ $$ no: a comment\n", " $\n")
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn print_parse_round_trip(st in prop::collection::vec(statement(), 1..8), seed in any::<u64>()) {
        let text: String = st.iter().map(|s| format!("{s}\n")).collect();
        let p = parse("gen.dms", &text).map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        let got: Vec<Statement> = p.statements.iter().map(|s| s.statement.clone()).collect();
        prop_assert_eq!(&got, &st);
        // Printing is stable.
        prop_assert_eq!(p.print(), text.clone());
        // Blanks, continuations and case do not change a statement.
        let loose: String = st.iter().map(|s| format!("{}\n", reformat(&s.to_string(), seed))).collect();
        let q = parse("loose.dms", &loose).map_err(|e| TestCaseError::fail(format!("{e}\n{loose}")))?;
        let got2: Vec<Statement> = q.statements.iter().map(|s| s.statement.clone()).collect();
        prop_assert_eq!(&got2, &st);
    }

    #[test]
    fn any_text_parses_or_fails_at_a_place_inside_it(text in "[ -~\n\t$']{0,200}") {
        match parse("any.dms", &text) {
            Ok(p) => {
                let again = parse("again", &p.print()).map_err(|e| TestCaseError::fail(e.to_string()))?;
                prop_assert_eq!(again.statements(), p.statements());
            }
            Err(e) => {
                let lines = text.split('\n').count() as u32;
                prop_assert!(e.pos.line >= 1 && e.pos.line <= lines.max(1) + 1, "{}", e);
                prop_assert!(e.pos.col >= 1, "{}", e);
            }
        }
    }
}
