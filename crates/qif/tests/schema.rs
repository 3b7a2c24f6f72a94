//! Every kind's QIF export validates against the official QIF 3.0 schemas with xmllint (the
//! schemas' `xs:key`/`xs:keyref` included, so a dangling id fails too), with and without
//! tolerances, for every method that applies; the values read back equal the evaluation's;
//! a plan written by hand is read back (deviations, limits, inches).
//!
//! xmllint comes from the Debian package libxml2-utils; without it the validation prints a loud
//! `SKIPPED:` line and the rest of the checks still run.

use std::path::PathBuf;
use std::process::Command;
use truepos_fit::evaluate::{evaluate, Kind, Method, Spec};
use truepos_fit::verdict::{DecisionRule, SizeTolerance};
use truepos_math::{Point3, Vector3};
use truepos_qif::{read_plan, results_from_evaluation, write_results, FeatureKind};

fn schema() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/schemas/qif3/QIFApplications/QIFDocument.xsd")
}

/// `Some(true)` all valid, `Some(false)` some invalid (with xmllint's messages printed), `None`
/// skipped. One xmllint run for all files: loading the schema set is most of the time.
fn xmllint(paths: &[PathBuf]) -> Option<bool> {
    let xsd = schema();
    assert!(xsd.is_file(), "QIF schemas missing at {} (they ship in data/schemas)", xsd.display());
    match Command::new("xmllint").args(["--noout", "--nonet", "--schema"]).arg(&xsd).args(paths).output() {
        Ok(o) => {
            if !o.status.success() {
                eprintln!("{}", String::from_utf8_lossy(&o.stderr));
            }
            Some(o.status.success())
        }
        Err(e) => {
            eprintln!("SKIPPED: xmllint not available ({e}); install libxml2-utils");
            None
        }
    }
}

fn ring(c: Point3, axis: Vector3, r: f64, n: usize, z: f64, wobble: f64) -> Vec<Point3> {
    let w = axis.normalize();
    let u = truepos_math::any_perpendicular(&w);
    let v = w.cross(&u);
    (0..n)
        .map(|i| {
            let a = i as f64 * std::f64::consts::TAU / n as f64;
            c + w * z
                + (u * a.cos() + v * a.sin())
                    * (r + wobble * (3.0 * a).sin() + 0.3 * wobble * (7.0 * a).cos())
        })
        .collect()
}

fn data(kind: Kind) -> Vec<Point3> {
    let ax = Vector3::new(0.1, -0.2, 1.0);
    let c = Point3::new(10.0, 20.0, 30.0);
    match kind {
        Kind::Line => (0..30)
            .map(|i| {
                Point3::new(
                    i as f64,
                    0.5 * i as f64 + 0.001 * (i as f64).sin(),
                    2.0 + 0.001 * (i as f64 * 1.7).cos(),
                )
            })
            .collect(),
        Kind::Plane => (0..50)
            .map(|i| {
                Point3::new((i % 10) as f64 * 5.0, (i / 10) as f64 * 5.0, 0.002 * ((i * 7 % 11) as f64 - 5.0))
            })
            .collect(),
        Kind::Circle => ring(c, ax, 10.0, 40, 0.0, 0.002),
        Kind::Sphere => (0..60)
            .map(|i| {
                let z = 1.0 - 1.6 * (i as f64 + 0.5) / 60.0;
                let r = (1.0 - z * z).sqrt();
                let phi = i as f64 * 2.4;
                c + Vector3::new(r * phi.cos(), r * phi.sin(), z) * (12.0 + 0.001 * (5.0 * phi).sin())
            })
            .collect(),
        Kind::Cylinder => (0..4).flat_map(|k| ring(c, ax, 8.0, 16, 10.0 * k as f64, 0.002)).collect(),
        Kind::Cone => {
            (0..4).flat_map(|k| ring(c, ax, 5.0 + 3.0 * k as f64, 16, 6.0 * k as f64, 0.001)).collect()
        }
    }
}

fn text_of(doc: &roxmltree::Document, name: &str) -> Option<String> {
    doc.descendants().find(|n| n.has_tag_name(name)).and_then(|n| n.text()).map(|t| t.trim().to_string())
}

fn nums(s: &str) -> Vec<f64> {
    s.split_whitespace().map(|t| t.parse().unwrap()).collect()
}

#[test]
fn every_kind_and_method_validates_and_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = vec![];
    let kinds = [Kind::Line, Kind::Plane, Kind::Circle, Kind::Sphere, Kind::Cylinder, Kind::Cone];
    for kind in kinds {
        let pts = data(kind);
        let methods: &[Method] = match kind {
            Kind::Cone => &[Method::LeastSquares],
            Kind::Line | Kind::Plane => &[Method::LeastSquares, Method::MinimumZone],
            _ => &[
                Method::LeastSquares,
                Method::MinimumZone,
                Method::MaximumInscribed,
                Method::MinimumCircumscribed,
            ],
        };
        for &m in methods {
            for with_tol in [false, true] {
                let mut spec = Spec { rule: DecisionRule::Guarded, ..Spec::default() };
                if with_tol {
                    spec.form_tolerance = Some(0.003);
                    if kind.has_size() {
                        let e0 = evaluate(kind, Method::LeastSquares, &pts, &Spec::default()).unwrap();
                        let d = 2.0 * e0.radius.unwrap();
                        spec.size = Some(SizeTolerance::new(d.round(), -0.001, 0.006).unwrap());
                    }
                }
                let e = evaluate(kind, m, &pts, &spec).unwrap();
                let r = results_from_evaluation(&e, "feature 1", "truepos test");
                let xml = write_results(&r).unwrap();
                let path = dir.path().join(format!("{}-{}-{with_tol}.qif", kind.name(), m.name()));
                std::fs::write(&path, &xml).unwrap();
                files.push(path);
                // Values read back.
                let doc = roxmltree::Document::parse(&xml).unwrap();
                assert_eq!(text_of(&doc, "UnitName").as_deref(), Some("degree"));
                assert!(xml.contains("<LinearUnit><SIUnitName>meter</SIUnitName><UnitName>mm</UnitName>"));
                let loc = text_of(&doc, "Location").or_else(|| text_of(&doc, "AxisPoint")).unwrap();
                let want = match kind {
                    Kind::Circle | Kind::Sphere => e.center.unwrap(),
                    Kind::Cone => e.apex.unwrap(),
                    _ => e.point.unwrap(),
                };
                let got = nums(&loc);
                for k in 0..3 {
                    assert!((got[k] - want[k]).abs() <= 1e-9, "{kind:?} location");
                }
                if let Some(r) = e.radius {
                    let d: f64 = text_of(&doc, "Diameter").unwrap().parse().unwrap();
                    assert!((d - 2.0 * r).abs() <= 1e-9);
                }
                let form: f64 = text_of(&doc, "Form").unwrap().parse().unwrap();
                assert!((form - e.form).abs() <= 1e-9);
                if with_tol {
                    let status =
                        doc.descendants().filter(|n| n.has_tag_name("CharacteristicStatusEnum")).count();
                    assert_eq!(status, if kind.has_size() { 2 } else { 1 });
                    if kind.has_size() {
                        assert!(xml.contains("<DiameterCharacteristicMeasurement"));
                        assert!(xml.contains("<TargetValue>"));
                    }
                } else {
                    assert!(!xml.contains("Characteristic"));
                }
                if m == Method::LeastSquares {
                    assert!(xml.contains("ombinedUncertainty=\""), "{xml}");
                }
            }
        }
    }
    match xmllint(&files) {
        Some(true) => {
            eprintln!("xmllint: all {} QIF exports validate against the QIF 3.0 schemas", files.len())
        }
        Some(false) => panic!("some QIF exports do not validate (xmllint's messages above)"),
        None => {}
    }
}

#[test]
fn plans_are_read_with_units_and_limits() {
    let plan = |unit: &str, factor: &str, tol: &str, form: &str| {
        format!(
            r#"<?xml version="1.0"?>
<QIFDocument xmlns="http://qifstandards.org/xsd/qif3" versionQIF="3.0.0" idMax="9">
  <QPId>0b7c1f2e-1234-4abc-8def-0123456789ab</QPId>
  <FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>{unit}</UnitName><UnitConversion><Factor>{factor}</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits>
  <Characteristics>
    <FormalStandardId>1</FormalStandardId>
    <CharacteristicDefinitions n="2">
      <DiameterCharacteristicDefinition id="2">{tol}</DiameterCharacteristicDefinition>
      {form}
      <PositionCharacteristicDefinition id="8"><ToleranceValue>0.1</ToleranceValue></PositionCharacteristicDefinition>
    </CharacteristicDefinitions>
    <CharacteristicNominals n="1">
      <DiameterCharacteristicNominal id="3"><CharacteristicDefinitionId>2</CharacteristicDefinitionId><TargetValue>20</TargetValue></DiameterCharacteristicNominal>
    </CharacteristicNominals>
  </Characteristics>
</QIFDocument>"#
        )
    };
    let dev = "<Tolerance><MaxValue>0.006</MaxValue><MinValue>-0.001</MinValue><DefinedAsLimit>false</DefinedAsLimit></Tolerance>";
    let circ = r#"<CircularityCharacteristicDefinition id="5"><ToleranceValue>0.004</ToleranceValue></CircularityCharacteristicDefinition>"#;
    let p = read_plan(&plan("mm", "0.001", dev, circ), FeatureKind::Circle).unwrap();
    let (n, lo, hi) = p.diameter.unwrap();
    assert!((n - 20.0).abs() < 1e-12 && (lo + 0.001).abs() < 1e-12 && (hi - 0.006).abs() < 1e-12);
    assert!((p.form_tolerance.unwrap() - 0.004).abs() < 1e-12);
    assert!(p.ignored.iter().any(|s| s.contains("Position")));
    // Limits of size in inches.
    let lim = "<Tolerance><MaxValue>0.8</MaxValue><MinValue>0.7</MinValue><DefinedAsLimit>true</DefinedAsLimit></Tolerance>";
    let p = read_plan(&plan("inch", "0.0254", lim, ""), FeatureKind::Cylinder).unwrap();
    let (n, lo, hi) = p.diameter.unwrap();
    assert!((n - 508.0).abs() < 1e-9, "{n}");
    assert!((n + lo - 17.78).abs() < 1e-9 && (n + hi - 20.32).abs() < 1e-9);
    // Not supported: said clearly.
    let e = read_plan(&plan("mm", "0.001", "<NonTolerance>MEASURED</NonTolerance>", ""), FeatureKind::Circle)
        .unwrap_err();
    assert!(e.to_string().contains("no <Tolerance>"), "{e}");
    let e = read_plan("<a/>", FeatureKind::Circle).unwrap_err();
    assert!(e.to_string().contains("not a QIF document"), "{e}");
    let e = read_plan("<QIFDocument", FeatureKind::Circle).unwrap_err();
    assert!(e.to_string().contains("XML"), "{e}");
}

/// Numbers that are finite in the file but overflow once converted to mm (a huge unit factor, a
/// huge value in metres, limits of size whose midpoint or deviations overflow) are refused with
/// their place, never read as a tolerance of ±∞.
#[test]
fn numbers_that_overflow_in_mm_are_refused_with_their_place() {
    let doc = |factor: &str, max: &str, min: &str, limit: &str, target: &str| {
        format!(
            r#"<QIFDocument xmlns="http://qifstandards.org/xsd/qif3">
<FileUnits><PrimaryUnits><LinearUnit><UnitName>u</UnitName><UnitConversion><Factor>{factor}</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits>
<Characteristics><CharacteristicDefinitions>
<DiameterCharacteristicDefinition id="2"><Tolerance><MaxValue>{max}</MaxValue><MinValue>{min}</MinValue><DefinedAsLimit>{limit}</DefinedAsLimit></Tolerance></DiameterCharacteristicDefinition>
</CharacteristicDefinitions><CharacteristicNominals>
<DiameterCharacteristicNominal id="3"><CharacteristicDefinitionId>2</CharacteristicDefinitionId>{target}</DiameterCharacteristicNominal>
</CharacteristicNominals></Characteristics></QIFDocument>"#
        )
    };
    let t20 = "<TargetValue>20</TargetValue>";
    // Factor 1e306 m → 1e309 mm per unit: infinite.
    let e = read_plan(&doc("1e306", "0.1", "-0.1", "false", t20), FeatureKind::Circle).unwrap_err();
    assert!(e.to_string().starts_with("line 2, column ") && e.to_string().contains("Factor"), "{e}");
    // Metres: 1e306 m is finite, 1e309 mm is not.
    let e = read_plan(&doc("1", "1e306", "-0.1", "false", t20), FeatureKind::Circle).unwrap_err();
    assert!(e.to_string().contains("line 4") && e.to_string().contains("MaxValue"), "{e}");
    // Limits of size in mm whose sum overflows: the mid-limit is still finite (1e308), but the
    // deviations from a 0-based nominal overflow.
    let p = read_plan(&doc("0.001", "1.5e308", "1e308", "true", ""), FeatureKind::Circle).unwrap();
    let (n, lo, hi) = p.diameter.unwrap();
    assert!(n.is_finite() && lo.is_finite() && hi.is_finite(), "{n} {lo} {hi}");
    let e = read_plan(
        &doc("0.001", "1.7e308", "-1.7e308", "true", "<TargetValue>1.7e308</TargetValue>"),
        FeatureKind::Circle,
    )
    .unwrap_err();
    assert!(e.to_string().contains("line 4") && e.to_string().contains("out of range"), "{e}");
}

/// A plan whose meaning is ambiguous is refused with the element's line, never read one way
/// silently: a `DefinedAsLimit` outside xsd:boolean, two nominals for one definition, a second
/// characteristics block; a QIF 2 document and a plan nested deeper than the XML bound are
/// named as such (the deep one used to overflow the stack).
#[test]
fn ambiguous_plans_are_refused_with_their_line() {
    let doc = |limit: &str, noms: &str, extra: &str| {
        format!(
            r#"<QIFDocument xmlns="http://qifstandards.org/xsd/qif3">
<Characteristics><CharacteristicDefinitions>
<DiameterCharacteristicDefinition id="2"><Tolerance><MaxValue>20.1</MaxValue><MinValue>19.9</MinValue><DefinedAsLimit>{limit}</DefinedAsLimit></Tolerance></DiameterCharacteristicDefinition>
</CharacteristicDefinitions><CharacteristicNominals>
<DiameterCharacteristicNominal id="3"><CharacteristicDefinitionId>2</CharacteristicDefinitionId><TargetValue>20</TargetValue></DiameterCharacteristicNominal>
{noms}</CharacteristicNominals></Characteristics>
{extra}</QIFDocument>"#
        )
    };
    for ok in ["true", " 1 ", "false", "0"] {
        let p = read_plan(&doc(ok, "", ""), FeatureKind::Circle).unwrap();
        let (n, lo, hi) = p.diameter.unwrap();
        if ok.trim() == "true" || ok.trim() == "1" {
            assert!((n - 20.0).abs() < 1e-12 && (lo + 0.1).abs() < 1e-9 && (hi - 0.1).abs() < 1e-9);
        } else {
            assert!((lo - 19.9).abs() < 1e-12 && (hi - 20.1).abs() < 1e-12);
        }
    }
    for bad in ["yes", "True", "TRUE", "2", ""] {
        let e = read_plan(&doc(bad, "", ""), FeatureKind::Circle).unwrap_err().to_string();
        assert!(
            e.starts_with("line 3,") && e.contains("DefinedAsLimit") && e.contains("xsd:boolean"),
            "{bad}: {e}"
        );
    }
    let second = r#"<DiameterCharacteristicNominal id="4"><CharacteristicDefinitionId>2</CharacteristicDefinitionId><TargetValue>25</TargetValue></DiameterCharacteristicNominal>
"#;
    let e = read_plan(&doc("false", second, ""), FeatureKind::Circle).unwrap_err().to_string();
    assert!(e.starts_with("line 6,") && e.contains("second nominal") && e.contains("line 5"), "{e}");
    let e =
        read_plan(&doc("false", "", "<Characteristics/>\n"), FeatureKind::Circle).unwrap_err().to_string();
    assert!(e.starts_with("line 7,") && e.contains("second <Characteristics>"), "{e}");
    let qif2 = doc("false", "", "").replace("xsd/qif3", "xsd/qif2");
    let e = read_plan(&qif2, FeatureKind::Circle).unwrap_err().to_string();
    assert!(
        e.contains("qif2") && e.contains("QIF 2") && !e.contains("not a QIF document <QIFDocument>"),
        "{e}"
    );
    let n = 50_000;
    let deep = doc("false", "", &format!("{}{}", "<a>".repeat(n), "</a>".repeat(n)));
    let e = read_plan(&deep, FeatureKind::Circle).unwrap_err().to_string();
    assert!(e.starts_with("line 7,") && e.contains("nested more than 256"), "{e}");
}
