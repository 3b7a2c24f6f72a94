//! # truepos-qif
//!
//! QIF 3.0 (ISO 23952:2020) for fitted features: [`write_results`] turns one measured feature
//! (and, when tolerances are given, its diameter and form characteristics with status) into a
//! QIF document that validates against the official QIF 3.0 schemas; [`read_plan`] takes a
//! nominal diameter, its tolerance and a form tolerance from a QIF plan or model document;
//! [`write_program_results`] writes the results of a whole inspection program (every feature
//! and every tolerance of a `truepos dmis run`, with datum reference frames; module `program`).
//!
//! What the export holds:
//! - `FileUnits`: millimetres as the primary linear unit, degrees as the angular unit (every
//!   number in the document is in these units).
//! - `Results/MeasurementResultsSet/MeasurementResults/MeasuredFeatures`: one
//!   `XxxFeatureMeasurement` (Line, Plane, Circle, Sphere, Cylinder, Cone) with the fitted
//!   location, direction (normal, axis), diameter, full apex angle and form, the substitute
//!   feature algorithm (`LEASTSQUARES`, `MINMAX` for minimum zone, `MAXINSCRIBED`,
//!   `MINCIRCUMSCRIBED`), and the standard uncertainties (k = 1) in the schema's
//!   `combinedUncertainty` attributes (per component for points and vectors).
//! - With a size tolerance: a `DiameterCharacteristic` definition (limit deviations), nominal
//!   (target value), item and measurement (actual value, status) that refers to the feature
//!   measurement. With a form tolerance: the kind's form characteristic (straightness,
//!   flatness, circularity, sphericity, cylindricity, conicity) likewise. Status `PASS`,
//!   `FAIL`, or `INDETERMINATE` for an undecided guarded decision; the measurement results'
//!   inspection status is `PASS`, `FAIL` or `UNKNOWN` accordingly.
//!
//! What the import reads ([`read_plan`]): the linear unit (`FileUnits`, converted to mm), the
//! one `DiameterCharacteristicDefinition` with a `Tolerance` (deviations, or limits when
//! `DefinedAsLimit` is true) and its nominal's `TargetValue`, and the tolerance value of a form
//! characteristic. It does not read feature nominals (location, orientation), datums,
//! positional or profile tolerances, limits-and-fits codes, dual values, or several diameter
//! characteristics in one file; these are refused or ignored as [`PlanError`] and
//! [`Plan::ignored`] say.
//!
//! Numbers are written in plain decimal notation (`xs:decimal` has no exponent) with the
//! shortest representation that reads back to the same `f64`.

#![forbid(unsafe_code)]

use std::fmt::Write as _;
use thiserror::Error;

/// The element kinds truepos fits: the one definition, [`truepos_fit::evaluate::Kind`], under
/// the name this crate has always used.
pub use truepos_fit::evaluate::Kind as FeatureKind;

/// The QIF name of the kind's feature (`Line`, `Plane`, ...), the prefix of its
/// `...FeatureMeasurement` element.
fn qif_name(kind: FeatureKind) -> &'static str {
    match kind {
        FeatureKind::Line => "Line",
        FeatureKind::Plane => "Plane",
        FeatureKind::Circle => "Circle",
        FeatureKind::Sphere => "Sphere",
        FeatureKind::Cylinder => "Cylinder",
        FeatureKind::Cone => "Cone",
    }
}

/// The QIF form characteristic of a kind (`Straightness`, `Flatness`, `Circularity`,
/// `Sphericity`, `Cylindricity`, `Conicity`), the prefix of its `...Characteristic...` elements.
pub fn form_characteristic(kind: FeatureKind) -> &'static str {
    match kind {
        FeatureKind::Line => "Straightness",
        FeatureKind::Plane => "Flatness",
        FeatureKind::Circle => "Circularity",
        FeatureKind::Sphere => "Sphericity",
        FeatureKind::Cylinder => "Cylindricity",
        FeatureKind::Cone => "Conicity",
    }
}

/// The substitute feature algorithm (association criterion).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Algorithm {
    /// Least squares (QIF `LEASTSQUARES`).
    LeastSquares,
    /// Minimum zone, Chebyshev (QIF `MINMAX`).
    MinimumZone,
    /// Maximum inscribed (QIF `MAXINSCRIBED`).
    MaximumInscribed,
    /// Minimum circumscribed (QIF `MINCIRCUMSCRIBED`).
    MinimumCircumscribed,
}

impl Algorithm {
    fn qif(self) -> &'static str {
        match self {
            Algorithm::LeastSquares => "LEASTSQUARES",
            Algorithm::MinimumZone => "MINMAX",
            Algorithm::MaximumInscribed => "MAXINSCRIBED",
            Algorithm::MinimumCircumscribed => "MINCIRCUMSCRIBED",
        }
    }
}

/// Conformance status of a characteristic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Conforms (QIF `PASS`).
    Pass,
    /// Does not conform (QIF `FAIL`).
    Fail,
    /// Neither conformance nor non-conformance proven (ISO 14253-1 guarded rule).
    Undecided,
}

impl Status {
    fn characteristic(self) -> &'static str {
        match self {
            Status::Pass => "PASS",
            Status::Fail => "FAIL",
            Status::Undecided => "INDETERMINATE",
        }
    }
}

/// A value with an optional standard uncertainty (k = 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Value<T> {
    /// The value, in the unit of the field that holds it.
    pub value: T,
    /// Its standard uncertainty (k = 1), same unit; `None` when not known.
    pub uncertainty: Option<T>,
}

impl<T> Value<T> {
    /// A value with its standard uncertainty, if any.
    pub fn new(value: T, uncertainty: Option<T>) -> Self {
        Value { value, uncertainty }
    }
}

/// One measured (fitted) feature. Lengths in mm, angles in degrees.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredFeature {
    /// The element kind (selects the `...FeatureMeasurement` element).
    pub kind: FeatureKind,
    /// Feature name (written as `FeatureName`).
    pub name: String,
    /// The association criterion the feature was fitted by.
    pub algorithm: Algorithm,
    /// Line, plane: a point on it; circle, sphere: the centre; cylinder, cone: a point on the
    /// axis (for a cone, the apex).
    pub location: Value<[f64; 3]>,
    /// Line: direction; plane, circle: normal; cylinder, cone: axis; sphere: none.
    pub direction: Option<Value<[f64; 3]>>,
    /// Circle, sphere, cylinder: diameter.
    pub diameter: Option<Value<f64>>,
    /// Cone: full apex angle, degrees.
    pub full_angle_deg: Option<Value<f64>>,
    /// Form deviation (zone width about the reported feature), mm.
    pub form: f64,
}

/// The diameter characteristic: nominal, limit deviations, actual value and status.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiameterCharacteristic {
    /// Nominal diameter, mm.
    pub nominal: f64,
    /// Lower deviation from the nominal (signed, ≤ `upper`), mm.
    pub lower: f64,
    /// Upper deviation from the nominal (signed, ≥ `lower`), mm.
    pub upper: f64,
    /// Measured diameter with its standard uncertainty, mm.
    pub actual: Value<f64>,
    /// Conformance of the measured diameter.
    pub status: Status,
}

/// The form characteristic of the feature's kind: tolerance, actual value and status.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FormCharacteristic {
    /// Form tolerance (zone width), mm.
    pub tolerance: f64,
    /// Measured form (zone width), mm.
    pub actual: f64,
    /// Conformance of the measured form.
    pub status: Status,
}

/// Everything one results document holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Results {
    /// The measured feature.
    pub feature: MeasuredFeature,
    /// The diameter characteristic, when a size tolerance was given.
    pub diameter: Option<DiameterCharacteristic>,
    /// The form characteristic, when a form tolerance was given.
    pub form: Option<FormCharacteristic>,
    /// Written as the application's name in the header (e.g. "truepos 0.1.0").
    pub application: String,
}

/// Why a results document cannot be written.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum WriteError {
    /// A value to write is NaN or infinite (which value).
    #[error("{what} is not a finite number")]
    NotFinite {
        /// Which value.
        what: &'static str,
    },
    /// A diameter characteristic for a kind without a diameter (the kind).
    #[error("a diameter characteristic needs a feature with a diameter (not a {0:?})")]
    NoDiameter(FeatureKind),
    /// An inconsistent program result ([`write_program_results`]).
    #[error("invalid {what}")]
    Invalid {
        /// Which part of the results is inconsistent.
        what: &'static str,
    },
}

/// Most digits an `xs:decimal` may have for common validators (libxml2 accepts 24; the
/// standard asks every processor for at least 18).
const MAX_DIGITS: usize = 24;

/// A number as `xs:decimal`: plain notation, the shortest digits that read back to the same
/// `f64`, or — when that needs more than [`MAX_DIGITS`] digits (values below ~1e-8 written
/// with all their leading zeros) — rounded to 24 decimal places, an absolute error below
/// 1e-24 of the unit.
fn dec(v: f64) -> String {
    // Rust's `Display` for f64 never uses an exponent; "-0" becomes "0".
    if v == 0.0 {
        return "0".into();
    }
    let s = format!("{v}");
    let digits =
        s.trim_start_matches('-').trim_start_matches('0').chars().filter(char::is_ascii_digit).count();
    if digits <= MAX_DIGITS {
        return s;
    }
    let int_digits =
        s.trim_start_matches('-').split('.').next().map_or(0, |i| i.trim_start_matches('0').len());
    let frac = MAX_DIGITS.saturating_sub(int_digits);
    let r = format!("{v:.frac$}");
    let r = if r.contains('.') { r.trim_end_matches('0').trim_end_matches('.').to_string() } else { r };
    if r.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        "0".into()
    } else {
        r
    }
}

fn check(v: f64, what: &'static str) -> Result<(), WriteError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(WriteError::NotFinite { what })
    }
}

fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => o.push(' '),
            c => o.push(c),
        }
    }
    o
}

/// A QIF `xs:token` (no leading, trailing or repeated whitespace).
fn token(s: &str) -> String {
    let t = s.split_whitespace().collect::<Vec<_>>().join(" ");
    escape(if t.is_empty() { "feature" } else { &t })
}

fn vec3(v: &[f64; 3]) -> String {
    format!("{} {} {}", dec(v[0]), dec(v[1]), dec(v[2]))
}

fn vec_unc(u: &Option<[f64; 3]>) -> String {
    match u {
        Some(u) => format!(
            " xCombinedUncertainty=\"{}\" yCombinedUncertainty=\"{}\" zCombinedUncertainty=\"{}\"",
            dec(u[0].abs()),
            dec(u[1].abs()),
            dec(u[2].abs())
        ),
        None => String::new(),
    }
}

fn scalar_unc(u: &Option<f64>) -> String {
    match u {
        Some(u) => format!(" combinedUncertainty=\"{}\"", dec(u.abs())),
        None => String::new(),
    }
}

/// A deterministic QPId (UUID version 4 layout) from the document's content: the same
/// results give the same identifier, different results different ones.
fn qpid(content: &str) -> String {
    let h = |seed: u64| {
        let mut x: u64 = 0xcbf2_9ce4_8422_2325 ^ seed;
        for b in content.bytes() {
            x ^= b as u64;
            x = x.wrapping_mul(0x0000_0100_0000_01b3);
        }
        x
    };
    let (a, b) = (h(0x9e37_79b9_7f4a_7c15), h(0x6a09_e667_f3bc_c908));
    let hi = (a & 0xffff_ffff_ffff_0fff) | 0x4000;
    let lo = (b & 0x3fff_ffff_ffff_ffff) | 0x8000_0000_0000_0000;
    format!(
        "{:08x}-{:04x}-{:04x}-{:04x}-{:012x}",
        hi >> 32,
        (hi >> 16) & 0xffff,
        hi & 0xffff,
        lo >> 48,
        lo & 0xffff_ffff_ffff
    )
}

/// The QIF 3.0 document for `r`: every value checked, the characteristics (definition,
/// nominal, item, measurement) numbered after the standard (1), the results (2) and the feature
/// measurement (3), then the document assembled around them.
pub fn write_results(r: &Results) -> Result<String, WriteError> {
    check_values(r)?;
    let f = &r.feature;
    let alg = format!(
        "<SubstituteFeatureAlgorithm><SubstituteFeatureAlgorithmEnum>{}</SubstituteFeatureAlgorithmEnum></SubstituteFeatureAlgorithm>",
        f.algorithm.qif()
    );
    let mut chars = Characteristics { next: 4, ..Default::default() };
    if let Some(d) = &r.diameter {
        chars.add_diameter(d, &f.name, &alg);
    }
    if let Some(fc) = &r.form {
        chars.add_form(fc, f, &alg);
    }
    let body = feature_measurement(f, &alg);
    Ok(document(r, &chars, &body))
}

/// Ids of the standard, the measurement results and the feature measurement.
const STD_ID: usize = 1;
const RES_ID: usize = 2;
const FEAT_ID: usize = 3;

/// Every number that goes into the document is finite, and a diameter characteristic belongs
/// to a feature with a diameter.
fn check_values(r: &Results) -> Result<(), WriteError> {
    let f = &r.feature;
    for v in f.location.value.iter().chain(f.location.uncertainty.iter().flatten()) {
        check(*v, "the feature location")?;
    }
    if let Some(d) = &f.direction {
        for v in d.value.iter().chain(d.uncertainty.iter().flatten()) {
            check(*v, "the feature direction")?;
        }
    }
    for (v, what) in [
        (f.diameter.map(|d| d.value), "the diameter"),
        (f.diameter.and_then(|d| d.uncertainty), "the diameter's uncertainty"),
        (f.full_angle_deg.map(|d| d.value), "the apex angle"),
        (f.full_angle_deg.and_then(|d| d.uncertainty), "the apex angle's uncertainty"),
        (Some(f.form), "the form"),
    ] {
        if let Some(v) = v {
            check(v, what)?;
        }
    }
    if let Some(d) = &r.diameter {
        if !f.kind.has_size() {
            return Err(WriteError::NoDiameter(f.kind));
        }
        for v in [d.nominal, d.lower, d.upper, d.actual.value] {
            check(v, "the diameter characteristic")?;
        }
    }
    if let Some(fc) = &r.form {
        check(fc.tolerance, "the form tolerance")?;
        check(fc.actual, "the form value")?;
    }
    Ok(())
}

/// The characteristics of a document, each as four elements (definition, nominal, item,
/// measurement) with consecutive ids, and their statuses.
#[derive(Default)]
struct Characteristics {
    next: usize,
    count: usize,
    defs: String,
    noms: String,
    items: String,
    meas: String,
    statuses: Vec<Status>,
}

impl Characteristics {
    /// Ids for the next characteristic's definition, nominal, item and measurement.
    fn ids(&mut self) -> (usize, usize, usize, usize) {
        let n = self.next;
        self.next += 4;
        self.count += 1;
        (n, n + 1, n + 2, n + 3)
    }

    fn add_diameter(&mut self, d: &DiameterCharacteristic, name: &str, alg: &str) {
        let (def, nom, item, m) = self.ids();
        let _ = write!(
            self.defs,
            "      <DiameterCharacteristicDefinition id=\"{def}\">\n        <Tolerance><MaxValue>{}</MaxValue><MinValue>{}</MinValue><DefinedAsLimit>false</DefinedAsLimit></Tolerance>\n      </DiameterCharacteristicDefinition>\n",
            dec(d.upper),
            dec(d.lower)
        );
        let _ = write!(
            self.noms,
            "      <DiameterCharacteristicNominal id=\"{nom}\">\n        <CharacteristicDefinitionId>{def}</CharacteristicDefinitionId>\n        <TargetValue>{}</TargetValue>\n      </DiameterCharacteristicNominal>\n",
            dec(d.nominal)
        );
        let _ = write!(
            self.items,
            "      <DiameterCharacteristicItem id=\"{item}\">\n        <Name>{} diameter</Name>\n        {alg}\n        <CharacteristicNominalId>{nom}</CharacteristicNominalId>\n      </DiameterCharacteristicItem>\n",
            token(name)
        );
        let _ = write!(
            self.meas,
            "            <DiameterCharacteristicMeasurement id=\"{m}\">\n              <Status><CharacteristicStatusEnum>{}</CharacteristicStatusEnum></Status>\n              <CharacteristicItemId>{item}</CharacteristicItemId>\n              <FeatureMeasurementIds n=\"1\"><Id>{FEAT_ID}</Id></FeatureMeasurementIds>\n              <Value{}>{}</Value>\n            </DiameterCharacteristicMeasurement>\n",
            d.status.characteristic(),
            scalar_unc(&d.actual.uncertainty),
            dec(d.actual.value)
        );
        self.statuses.push(d.status);
    }

    fn add_form(&mut self, fc: &FormCharacteristic, f: &MeasuredFeature, alg: &str) {
        let t = form_characteristic(f.kind);
        let (def, nom, item, m) = self.ids();
        let zone = if f.kind == FeatureKind::Line {
            "\n        <ZoneShape><DiametricalZone/></ZoneShape>"
        } else {
            ""
        };
        let _ = write!(
            self.defs,
            "      <{t}CharacteristicDefinition id=\"{def}\">\n        <ToleranceValue>{}</ToleranceValue>{zone}\n      </{t}CharacteristicDefinition>\n",
            dec(fc.tolerance)
        );
        let _ = write!(
            self.noms,
            "      <{t}CharacteristicNominal id=\"{nom}\">\n        <CharacteristicDefinitionId>{def}</CharacteristicDefinitionId>\n      </{t}CharacteristicNominal>\n"
        );
        let _ = write!(
            self.items,
            "      <{t}CharacteristicItem id=\"{item}\">\n        <Name>{} form</Name>\n        {alg}\n        <CharacteristicNominalId>{nom}</CharacteristicNominalId>\n      </{t}CharacteristicItem>\n",
            token(&f.name)
        );
        let _ = write!(
            self.meas,
            "            <{t}CharacteristicMeasurement id=\"{m}\">\n              <Status><CharacteristicStatusEnum>{}</CharacteristicStatusEnum></Status>\n              <CharacteristicItemId>{item}</CharacteristicItemId>\n              <FeatureMeasurementIds n=\"1\"><Id>{FEAT_ID}</Id></FeatureMeasurementIds>\n              <Value>{}</Value>\n            </{t}CharacteristicMeasurement>\n",
            fc.status.characteristic(),
            dec(fc.actual)
        );
        self.statuses.push(fc.status);
    }

    /// The measurement results' inspection status: FAIL if any fails, UNKNOWN if any is
    /// undecided, NOT_CALCULATED without characteristics, else PASS.
    fn inspection(&self) -> &'static str {
        inspection_status(&self.statuses)
    }
}

/// The inspection status of measurement results whose characteristics have `statuses`: FAIL if
/// any fails, UNKNOWN if any is undecided, NOT_CALCULATED without characteristics, else PASS.
fn inspection_status(statuses: &[Status]) -> &'static str {
    if statuses.contains(&Status::Fail) {
        "FAIL"
    } else if statuses.contains(&Status::Undecided) {
        "UNKNOWN"
    } else if statuses.is_empty() {
        "NOT_CALCULATED"
    } else {
        "PASS"
    }
}

/// The `XxxFeatureMeasurement` element: name, algorithm, the kind's geometry with its
/// uncertainties, and the form.
fn feature_measurement(f: &MeasuredFeature, alg: &str) -> String {
    let mut body = String::new();
    let k = qif_name(f.kind);
    let _ = writeln!(body, "          <{k}FeatureMeasurement id=\"{FEAT_ID}\">");
    let _ = writeln!(body, "            <FeatureName>{}</FeatureName>", token(&f.name));
    let _ = writeln!(body, "            {alg}");
    let loc = format!("{}>{}", vec_unc(&f.location.uncertainty), vec3(&f.location.value));
    let dir = f.direction.as_ref().map(|d| format!("{}>{}", vec_unc(&d.uncertainty), vec3(&d.value)));
    let dia = f.diameter.map(|d| format!("{}>{}", scalar_unc(&d.uncertainty), dec(d.value)));
    let mut push = |name: &str, v: &Option<String>| {
        if let Some(v) = v {
            let _ = writeln!(body, "            <{name}{v}</{name}>");
        }
    };
    match f.kind {
        FeatureKind::Line => {
            push("Location", &Some(loc));
            push("Direction", &dir);
        }
        FeatureKind::Plane => {
            push("Location", &Some(loc));
            push("Normal", &dir);
        }
        FeatureKind::Circle => {
            push("Location", &Some(loc));
            push("Normal", &dir);
            push("Diameter", &dia);
        }
        FeatureKind::Sphere => {
            push("Location", &Some(loc));
            push("Diameter", &dia);
        }
        FeatureKind::Cylinder | FeatureKind::Cone => {
            let _ = writeln!(body, "            <Axis>");
            let _ = writeln!(body, "              <AxisPoint{loc}</AxisPoint>");
            if let Some(d) = &dir {
                let _ = writeln!(body, "              <Direction{d}</Direction>");
            }
            let _ = writeln!(body, "            </Axis>");
            if f.kind == FeatureKind::Cylinder {
                if let Some(d) = &dia {
                    let _ = writeln!(body, "            <Diameter{d}</Diameter>");
                }
            } else if let Some(a) = &f.full_angle_deg {
                let _ = writeln!(
                    body,
                    "            <FullAngle{}>{}</FullAngle>",
                    scalar_unc(&a.uncertainty),
                    dec(a.value)
                );
            }
        }
    }
    let _ = writeln!(body, "            <Form>{}</Form>", dec(f.form));
    let _ = writeln!(body, "          </{k}FeatureMeasurement>");
    body
}

/// Millimetres and degrees (every number of a document is in these units).
const FILE_UNITS: &str = "  <FileUnits>\n    <PrimaryUnits>\n      <AngularUnit><SIUnitName>radian</SIUnitName><UnitName>degree</UnitName><UnitConversion><Factor>0.017453292519943295</Factor></UnitConversion></AngularUnit>\n      <LinearUnit><SIUnitName>meter</SIUnitName><UnitName>mm</UnitName><UnitConversion><Factor>0.001</Factor></UnitConversion></LinearUnit>\n    </PrimaryUnits>\n  </FileUnits>\n";

/// The whole document: header, standard, units, the characteristics, the results around the
/// feature measurement `body`, and the QPId (a digest of the content).
fn document(r: &Results, chars: &Characteristics, body: &str) -> String {
    let mut doc = String::new();
    let _ = writeln!(
        doc,
        "  <Header>\n    <Application>\n      <Name>{}</Name>\n    </Application>\n  </Header>",
        escape(&r.application)
    );
    standards_and_units(&mut doc);
    let n = chars.count;
    if n > 0 {
        let Characteristics { defs, noms, items, .. } = chars;
        let _ = write!(
            doc,
            "  <Characteristics>\n    <FormalStandardId>{STD_ID}</FormalStandardId>\n    <CharacteristicDefinitions n=\"{n}\">\n{defs}    </CharacteristicDefinitions>\n    <CharacteristicNominals n=\"{n}\">\n{noms}    </CharacteristicNominals>\n    <CharacteristicItems n=\"{n}\">\n{items}    </CharacteristicItems>\n  </Characteristics>\n"
        );
    }
    let _ = write!(
        doc,
        "  <Results>\n    <MeasurementResultsSet n=\"1\">\n      <MeasurementResults id=\"{RES_ID}\">\n        <MeasuredFeatures n=\"1\">\n{body}        </MeasuredFeatures>\n"
    );
    if n > 0 {
        let _ = write!(
            doc,
            "        <MeasuredCharacteristics>\n          <CharacteristicMeasurements n=\"{n}\">\n{}          </CharacteristicMeasurements>\n        </MeasuredCharacteristics>\n",
            chars.meas
        );
    }
    let _ = write!(
        doc,
        "        <InspectionStatus><InspectionStatusEnum>{}</InspectionStatusEnum></InspectionStatus>\n      </MeasurementResults>\n    </MeasurementResultsSet>\n  </Results>\n",
        chars.inspection()
    );
    envelope(&doc, chars.next - 1)
}

/// The standard (ISO 1101:2017, id [`STD_ID`]) and the file units (mm, degrees), after the
/// header of either document.
fn standards_and_units(doc: &mut String) {
    let _ = writeln!(
        doc,
        "  <StandardsDefinitions n=\"1\">\n    <Standard id=\"{STD_ID}\">\n      <Organization><StandardsOrganizationEnum>ISO</StandardsOrganizationEnum></Organization>\n      <Designator>1101</Designator>\n      <Year>2017</Year>\n    </Standard>\n  </StandardsDefinitions>"
    );
    doc.push_str(FILE_UNITS);
}

/// The `<QIFDocument>` around the content `doc`: the XML declaration, the root with its
/// namespace, schema location and `idMax`, and the QPId (a digest of the content).
fn envelope(doc: &str, id_max: usize) -> String {
    let id = qpid(doc);
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<QIFDocument xmlns=\"http://qifstandards.org/xsd/qif3\" xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xsi:schemaLocation=\"http://qifstandards.org/xsd/qif3 ../QIFApplications/QIFDocument.xsd\" versionQIF=\"3.0.0\" idMax=\"{id_max}\">\n  <QPId>{id}</QPId>\n{doc}</QIFDocument>\n"
    )
}

// ---------------------------------------------------------------------------------------------
// Reading a plan / model

/// What [`read_plan`] found, in mm.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Plan {
    /// Nominal diameter and its lower/upper deviation.
    pub diameter: Option<(f64, f64, f64)>,
    /// Form tolerance of the requested kind.
    pub form_tolerance: Option<f64>,
    /// Length unit of the file, as its `UnitName` says (`mm` when the file declares none).
    pub unit: String,
    /// Elements present in the file that are not used (each named once).
    pub ignored: Vec<String>,
}

/// Why a plan cannot be read.
#[derive(Debug, Error)]
pub enum PlanError {
    /// The text is not well-formed XML.
    #[error("not well-formed XML: {0}")]
    Xml(#[from] roxmltree::Error),
    /// A problem at a place in the document (1-based line and column, and what is wrong).
    #[error("line {line}, column {column}: {why}")]
    At {
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// What is wrong.
        why: String,
    },
    /// The root element is not `<QIFDocument>` (its name).
    #[error("the root element is <{0}>, not a QIF document <QIFDocument>")]
    NotQif(String),
    /// A `<QIFDocument>` in another namespace than QIF 3's (QIF 2, or none of QIF's).
    #[error("the root element <QIFDocument> is in the namespace '{0}', not QIF 3's ('http://qifstandards.org/xsd/qif3'){hint}", hint = if .0.contains("qif2") { ": QIF 2 documents are not read (convert the plan to QIF 3)" } else { "" })]
    WrongNamespace(String),
    /// Nesting deeper than the bound of `truepos_io::xml`.
    #[error("{0}")]
    TooDeep(#[from] truepos_io::xml::TooDeep),
    /// The plan uses something this reader does not read (what, as a sentence).
    #[error("{0}")]
    Unsupported(String),
}

const QIF_NS: &str = "http://qifstandards.org/xsd/qif3";

fn child<'a, 'i>(n: roxmltree::Node<'a, 'i>, name: &str) -> Option<roxmltree::Node<'a, 'i>> {
    n.children().find(|c| c.is_element() && c.tag_name().name() == name)
}

/// The one child element `name` of `n`, if any; a second one is refused at its place (a reader
/// that took the first would silently ignore it).
fn one_child<'a, 'i>(
    doc: &roxmltree::Document,
    n: roxmltree::Node<'a, 'i>,
    name: &str,
) -> Result<Option<roxmltree::Node<'a, 'i>>, PlanError> {
    let mut found = n.children().filter(|c| c.is_element() && c.tag_name().name() == name);
    let first = found.next();
    if let (Some(first), Some(second)) = (first, found.next()) {
        let line = doc.text_pos_at(first.range().start).row;
        return Err(at(
            doc,
            second,
            format!(
                "a second <{name}> in <{}> (the first is on line {line}): truepos would read only the first",
                n.tag_name().name()
            ),
        ));
    }
    Ok(first)
}

fn elems<'a, 'i>(parent: Option<roxmltree::Node<'a, 'i>>, name: &str) -> Vec<roxmltree::Node<'a, 'i>> {
    parent
        .map(|p| p.children().filter(|c| c.is_element() && c.tag_name().name() == name).collect())
        .unwrap_or_default()
}

fn at(doc: &roxmltree::Document, n: roxmltree::Node, why: String) -> PlanError {
    let p = doc.text_pos_at(n.range().start);
    PlanError::At { line: p.row, column: p.col, why }
}

fn number(doc: &roxmltree::Document, n: roxmltree::Node, scale: f64) -> Result<f64, PlanError> {
    let t = n.text().unwrap_or("").trim();
    match t.parse::<f64>() {
        // The product is checked too: a finite value times the unit's factor can overflow to
        // infinity, which would be a tolerance of ±∞.
        Ok(v) if v.is_finite() && (v * scale).is_finite() => Ok(v * scale),
        Ok(v) if v.is_finite() => {
            Err(at(doc, n, format!("<{}> {t} is out of range once converted to mm", n.tag_name().name())))
        }
        _ => Err(at(doc, n, format!("<{}> is not a number: '{t}'", n.tag_name().name()))),
    }
}

/// Read the nominal diameter with its tolerance and the form tolerance of `kind` from a QIF
/// plan or model document (`text`).
///
/// The text is checked against the XML bounds of `truepos_io::xml` first (nesting depth, node
/// count). Read a file with `truepos_io::xml::read_xml` (size, binary data, depth).
pub fn read_plan(text: &str, kind: FeatureKind) -> Result<Plan, PlanError> {
    truepos_io::xml::check_depth(text)?;
    let opt = roxmltree::ParsingOptions { allow_dtd: false, nodes_limit: truepos_io::xml::MAX_XML_NODES };
    let doc = roxmltree::Document::parse_with_options(text, opt)?;
    let root = qif_root(&doc)?;
    let mut plan = Plan { unit: "mm".into(), ..Default::default() };
    let mut scale = 1.0;
    if let Some((factor, name)) = linear_unit(&doc, root)? {
        scale = factor;
        plan.unit = name;
    }
    let Some(chars) = child(root, "Characteristics") else {
        return Err(PlanError::Unsupported("the QIF document has no <Characteristics>".into()));
    };
    let defs = one_child(&doc, chars, "CharacteristicDefinitions")?;
    let noms = one_child(&doc, chars, "CharacteristicNominals")?;
    let reader = PlanReader { doc: &doc, scale };
    plan.diameter = reader.diameter(defs, noms)?;
    let form_name = format!("{}CharacteristicDefinition", form_characteristic(kind));
    plan.form_tolerance = reader.form_tolerance(defs, kind, &form_name)?;
    plan.ignored = not_read(defs, &form_name);
    if plan.diameter.is_none() && plan.form_tolerance.is_none() {
        return Err(PlanError::Unsupported(format!(
            "the QIF document has neither a diameter characteristic nor a {} characteristic",
            form_characteristic(kind).to_lowercase()
        )));
    }
    Ok(plan)
}

/// The root `<QIFDocument>` of a QIF 3 document with at most one `<Characteristics>` block (a
/// second one would be silently ignored).
fn qif_root<'a, 'i>(doc: &'a roxmltree::Document<'i>) -> Result<roxmltree::Node<'a, 'i>, PlanError> {
    let root = doc.root_element();
    if root.tag_name().name() != "QIFDocument" {
        return Err(PlanError::NotQif(root.tag_name().name().to_string()));
    }
    if let Some(ns) = root.tag_name().namespace().filter(|n| *n != QIF_NS) {
        return Err(PlanError::WrongNamespace(ns.to_string()));
    }
    let blocks: Vec<_> = elems(Some(root), "Characteristics");
    if let Some(second) = blocks.get(1) {
        return Err(at(
            doc,
            *second,
            "a second <Characteristics> block (a QIF document has at most one; truepos would read only the first)".into(),
        ));
    }
    Ok(root)
}

/// The file's linear unit: its factor to mm and its name as the file gives it (`None` when the
/// file declares no linear unit, i.e. mm).
fn linear_unit(doc: &roxmltree::Document, root: roxmltree::Node) -> Result<Option<(f64, String)>, PlanError> {
    let mut lu = one_child(doc, root, "FileUnits")?;
    for name in ["PrimaryUnits", "LinearUnit"] {
        lu = match lu {
            Some(n) => one_child(doc, n, name)?,
            None => None,
        };
    }
    let Some(lu) = lu else {
        return Ok(None);
    };
    let name = child(lu, "UnitName").and_then(|n| n.text()).unwrap_or("").trim().to_string();
    let scale = match child(lu, "UnitConversion").and_then(|c| child(c, "Factor")) {
        Some(f) => number(doc, f, 1000.0)?,
        None => match name.to_ascii_lowercase().as_str() {
            "mm" | "millimeter" | "millimetre" => 1.0,
            "inch" | "in" => 25.4,
            "m" | "meter" | "metre" => 1000.0,
            _ => {
                return Err(at(
                    doc,
                    lu,
                    format!("unknown linear unit '{name}' without a UnitConversion factor"),
                ))
            }
        },
    };
    if scale.is_nan() || scale <= 0.0 {
        return Err(at(doc, lu, "the linear unit's conversion factor is not positive".into()));
    }
    Ok(Some((scale, name)))
}

/// The characteristic definitions other than the diameter and the form `form_name`, each named
/// once as not read.
fn not_read(defs: Option<roxmltree::Node>, form_name: &str) -> Vec<String> {
    let mut ignored = Vec::new();
    if let Some(d) = defs {
        for c in d.children().filter(|c| c.is_element()) {
            let n = c.tag_name().name();
            if n != "DiameterCharacteristicDefinition" && n != form_name {
                let s = format!("{n} (not read)");
                if !ignored.contains(&s) {
                    ignored.push(s);
                }
            }
        }
    }
    ignored
}

/// A plan's characteristics being read: the document (for the places in errors) and the factor
/// from its linear unit to mm.
struct PlanReader<'a, 'i> {
    /// The parsed plan.
    doc: &'a roxmltree::Document<'i>,
    /// Millimetres per unit of the file.
    scale: f64,
}

impl<'i> PlanReader<'_, 'i> {
    /// The error `why` at the element `n`.
    fn at(&self, n: roxmltree::Node, why: &str) -> PlanError {
        at(self.doc, n, why.to_string())
    }

    /// The length in the element `n`, in mm.
    fn length(&self, n: roxmltree::Node) -> Result<f64, PlanError> {
        number(self.doc, n, self.scale)
    }

    /// The one diameter characteristic (nominal, lower and upper deviation, mm) of the
    /// definitions `defs` with its nominal among `noms`, if there is one.
    fn diameter(
        &self,
        defs: Option<roxmltree::Node<'_, 'i>>,
        noms: Option<roxmltree::Node<'_, 'i>>,
    ) -> Result<Option<(f64, f64, f64)>, PlanError> {
        let dia: Vec<_> = elems(defs, "DiameterCharacteristicDefinition");
        if dia.len() > 1 {
            return Err(PlanError::Unsupported(format!(
                "the QIF document has {} diameter characteristics; truepos fit reads exactly one",
                dia.len()
            )));
        }
        let Some(d) = dia.first() else {
            return Ok(None);
        };
        let id = d.attribute("id").unwrap_or("");
        let tol = self.tolerance(*d)?;
        let max = child(tol, "MaxValue").map(|n| self.length(n)).transpose()?;
        let min = child(tol, "MinValue").map(|n| self.length(n)).transpose()?;
        let limit = self.defined_as_limit(tol)?;
        let target = self.target(noms, id)?;
        let (Some(max), Some(min)) = (max, min) else {
            return Err(
                self.at(tol, "a one-sided diameter tolerance (only MaxValue or MinValue) is not supported")
            );
        };
        if limit == Some(true) {
            return self.limits_of_size(tol, min, max, target).map(Some);
        }
        let Some(nominal) = target else {
            let referred = elems(noms, "DiameterCharacteristicNominal").into_iter().any(|n| {
                child(n, "CharacteristicDefinitionId").and_then(|c| c.text()).map(str::trim) == Some(id)
            });
            let why = if referred {
                "the diameter characteristic's nominal has no <TargetValue> (needed with deviations)"
                    .to_string()
            } else {
                format!(
                    "no <DiameterCharacteristicNominal> refers to the diameter characteristic '{id}' (by its <CharacteristicDefinitionId>): the nominal diameter is needed with deviations"
                )
            };
            return Err(self.at(*d, &why));
        };
        Ok(Some((nominal, min, max)))
    }

    /// The `<Tolerance>` of the diameter definition `d`, given in place (not by reference).
    fn tolerance<'a>(&self, d: roxmltree::Node<'a, 'i>) -> Result<roxmltree::Node<'a, 'i>, PlanError> {
        let Some(tol) = child(d, "Tolerance") else {
            return Err(self.at(
                d,
                "the diameter characteristic has no <Tolerance> (limits-and-fits codes and non-toleranced characteristics are not supported)",
            ));
        };
        if child(tol, "DefinitionId").is_some() {
            return Err(self.at(tol, "a tolerance given by reference (DefinitionId) is not supported"));
        }
        Ok(tol)
    }

    /// The tolerance's `<DefinedAsLimit>` (an xsd:boolean), if it has one.
    fn defined_as_limit(&self, tol: roxmltree::Node) -> Result<Option<bool>, PlanError> {
        let Some(n) = child(tol, "DefinedAsLimit") else {
            return Ok(None);
        };
        match n.text().unwrap_or("").trim() {
            "true" | "1" => Ok(Some(true)),
            "false" | "0" => Ok(Some(false)),
            t => Err(at(
                self.doc,
                n,
                format!("<DefinedAsLimit> is '{t}', not an xsd:boolean (true, false, 1 or 0)"),
            )),
        }
    }

    /// The `TargetValue` (mm) of the one nominal among `noms` of the diameter definition `id`,
    /// if it has a nominal with one; a second nominal is ambiguous.
    fn target(&self, noms: Option<roxmltree::Node<'_, 'i>>, id: &str) -> Result<Option<f64>, PlanError> {
        let nominals: Vec<_> = elems(noms, "DiameterCharacteristicNominal")
            .into_iter()
            .filter(|n| {
                child(*n, "CharacteristicDefinitionId").and_then(|c| c.text()).map(str::trim) == Some(id)
            })
            .collect();
        if let Some(second) = nominals.get(1) {
            let first = self.doc.text_pos_at(nominals[0].range().start);
            return Err(at(
                self.doc,
                *second,
                format!(
                    "a second nominal for the diameter characteristic '{id}' (the first is on line {}): the nominal is ambiguous",
                    first.row
                ),
            ));
        }
        nominals.first().and_then(|n| child(*n, "TargetValue")).map(|n| self.length(n)).transpose()
    }

    /// Limits of size `min`, `max` of the tolerance `tol` as nominal and deviations: the
    /// nominal is the target when given, else the mid-limit (halves first: the sum of two large
    /// limits can overflow).
    fn limits_of_size(
        &self,
        tol: roxmltree::Node,
        min: f64,
        max: f64,
        target: Option<f64>,
    ) -> Result<(f64, f64, f64), PlanError> {
        let nominal = target.unwrap_or(0.5 * min + 0.5 * max);
        let triple = (nominal, min - nominal, max - nominal);
        if !(triple.1.is_finite() && triple.2.is_finite()) {
            return Err(
                self.at(tol, "the limits of size are too far from the nominal (deviations out of range)")
            );
        }
        Ok(triple)
    }

    /// The tolerance value (mm) of the one form characteristic `form_name` of `kind` among the
    /// definitions `defs`, if there is one.
    fn form_tolerance(
        &self,
        defs: Option<roxmltree::Node>,
        kind: FeatureKind,
        form_name: &str,
    ) -> Result<Option<f64>, PlanError> {
        let forms = elems(defs, form_name);
        if forms.len() > 1 {
            return Err(PlanError::Unsupported(format!(
                "the QIF document has {} {} characteristics; truepos fit reads at most one",
                forms.len(),
                form_characteristic(kind).to_lowercase()
            )));
        }
        let Some(f) = forms.first() else {
            return Ok(None);
        };
        let Some(tv) = child(*f, "ToleranceValue") else {
            return Err(self.at(
                *f,
                "the form characteristic has no <ToleranceValue> (per-unit zones are not supported)",
            ));
        };
        self.length(tv).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diameter plan (20 mm, −0.001/+0.006) with circularity, as the fuzz seed has it.
    const PLAN: &str = include_str!("../../../fuzz/seeds/qif_plan/circle_mm_deviations.qif");

    /// A second block of definitions, nominals or units was silently ignored (hostile audit 2
    /// of issue 31, F11, F12): each is refused at its place, naming the first; a nominal that
    /// refers to no definition says so (F13) instead of "no <TargetValue>".
    #[test]
    fn second_blocks_are_refused_and_orphan_nominals_named() {
        let ok = read_plan(PLAN, FeatureKind::Circle).unwrap();
        assert_eq!(ok.diameter, Some((20.0, -0.001, 0.006)));
        let defs = "    <CharacteristicDefinitions n=\"1\">\n      <DiameterCharacteristicDefinition id=\"2\"><Tolerance><MaxValue>0.5</MaxValue><MinValue>-0.5</MinValue></Tolerance></DiameterCharacteristicDefinition>\n    </CharacteristicDefinitions>\n";
        let noms = "    <CharacteristicNominals n=\"1\">\n      <DiameterCharacteristicNominal id=\"7\"><CharacteristicDefinitionId>2</CharacteristicDefinitionId><TargetValue>7</TargetValue></DiameterCharacteristicNominal>\n    </CharacteristicNominals>\n";
        let units = "  <FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>inch</UnitName><UnitConversion><Factor>0.0254</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits>\n";
        for (extra, after, name) in [
            (defs, "  </Characteristics>", "CharacteristicDefinitions"),
            (noms, "  </Characteristics>", "CharacteristicNominals"),
            (units, "  <Characteristics>", "FileUnits"),
        ] {
            let text = PLAN.replacen(after, &format!("{extra}{after}"), 1);
            let e = read_plan(&text, FeatureKind::Circle).unwrap_err().to_string();
            assert!(e.contains(&format!("a second <{name}>")) && e.contains("the first is on line"), "{e}");
            assert!(e.starts_with("line "), "{e}");
        }
        let inner = PLAN.replace("<LinearUnit>", "<LinearUnit><SIUnitName>meter</SIUnitName><UnitName>inch</UnitName><UnitConversion><Factor>0.0254</Factor></UnitConversion></LinearUnit><LinearUnit>");
        let e = read_plan(&inner, FeatureKind::Circle).unwrap_err().to_string();
        assert!(e.contains("a second <LinearUnit> in <PrimaryUnits>"), "{e}");
        let orphan = PLAN.replace("<CharacteristicDefinitionId>2<", "<CharacteristicDefinitionId>9<");
        let e = read_plan(&orphan, FeatureKind::Circle).unwrap_err().to_string();
        assert!(
            e.contains("no <DiameterCharacteristicNominal> refers to the diameter characteristic '2'"),
            "{e}"
        );
    }

    #[test]
    fn decimals_have_no_exponent_and_round_trip() {
        for v in [1e-12, 123456.789e10, -0.1, 0.30000000000000004, 1234.5678901234567, -9.87654321e-7] {
            let s = dec(v);
            assert!(!s.contains('e') && !s.contains('E'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap(), v);
        }
        // Tiny values: at most 24 digits, absolute error below 1e-24.
        for v in [6.14195912794905e-17, -1.3e-30, 5e-324, 1.234567890123456e-9] {
            let s = dec(v);
            let digits = s.chars().filter(char::is_ascii_digit).count();
            assert!(digits <= 25 && !s.contains('e'), "{s}");
            assert!((s.parse::<f64>().unwrap() - v).abs() < 1e-24, "{s}");
        }
        assert_eq!(dec(-0.0), "0");
    }

    #[test]
    fn qpid_has_the_uuid_pattern() {
        let q = qpid("x");
        assert_eq!(q.len(), 36);
        let parts: Vec<_> = q.split('-').map(str::len).collect();
        assert_eq!(parts, vec![8, 4, 4, 4, 12]);
        assert_ne!(qpid("a"), qpid("b"));
    }
}

// ---------------------------------------------------------------------------------------------
// From a truepos fit

mod from_fit {
    use super::*;
    use truepos_fit::evaluate::{Evaluation, Kind, Method, Spec};
    use truepos_fit::verdict::{check_form_tolerance, DecisionRule, SizeTolerance, Verdict};
    use truepos_math::Vector3;

    /// The tolerance specification of a plan for a feature of `kind`, with notes for people:
    /// the plan's ignored elements, and a diameter characteristic given for a feature without a
    /// size (not used). A tolerance the evaluation cannot use is an error (its text).
    pub fn plan_spec(plan: &Plan, kind: Kind, rule: DecisionRule) -> Result<(Spec, Vec<String>), String> {
        let mut notes = plan.ignored.clone();
        let size = match plan.diameter {
            Some((n, lo, hi)) if kind.has_size() => {
                Some(SizeTolerance::new(n, lo, hi).map_err(|e| e.to_string())?)
            }
            Some(_) => {
                notes.push(format!(
                    "the diameter characteristic does not apply to a {} and is not used",
                    kind.name()
                ));
                None
            }
            None => None,
        };
        let form_tolerance =
            plan.form_tolerance.map(check_form_tolerance).transpose().map_err(|e| e.to_string())?;
        Ok((Spec { size, form_tolerance, rule }, notes))
    }

    fn arr(v: &Vector3) -> [f64; 3] {
        [v.x, v.y, v.z]
    }

    fn status(v: Verdict) -> Status {
        match v {
            Verdict::Pass => Status::Pass,
            Verdict::Fail => Status::Fail,
            Verdict::Undecided => Status::Undecided,
        }
    }

    /// The QIF results of a truepos evaluation (feature name `name`, e.g. the input file's
    /// stem). Uncertainties are the standard uncertainties (k = 1) of a least-squares fit.
    pub fn results_from_evaluation(e: &Evaluation, name: &str, application: &str) -> Results {
        let kind = e.kind;
        let algorithm = match e.method {
            Method::LeastSquares => Algorithm::LeastSquares,
            Method::MinimumZone => Algorithm::MinimumZone,
            Method::MaximumInscribed => Algorithm::MaximumInscribed,
            Method::MinimumCircumscribed => Algorithm::MinimumCircumscribed,
        };
        let u = e.uncertainty.as_ref();
        let (loc, loc_u) = match e.kind {
            Kind::Circle | Kind::Sphere => (e.center, u.and_then(|u| u.center)),
            Kind::Cone => (e.apex, u.and_then(|u| u.apex)),
            _ => (e.point, u.and_then(|u| u.point)),
        };
        let (dir, dir_u) = match e.kind {
            Kind::Line => (e.direction, u.and_then(|u| u.direction)),
            Kind::Plane | Kind::Circle => (e.normal, u.and_then(|u| u.normal)),
            Kind::Cylinder | Kind::Cone => (e.axis, u.and_then(|u| u.axis)),
            Kind::Sphere => (None, None),
        };
        let diameter = e.radius.map(|r| Value::new(2.0 * r, u.and_then(|u| u.radius).map(|ur| 2.0 * ur)));
        let feature = MeasuredFeature {
            kind,
            name: name.to_string(),
            algorithm,
            location: Value::new(loc.map(|p| [p.x, p.y, p.z]).unwrap_or([0.0; 3]), loc_u.map(|v| arr(&v))),
            direction: dir.map(|d| Value::new(arr(&d), dir_u.map(|v| arr(&v)))),
            diameter: if kind.has_size() { diameter } else { None },
            full_angle_deg: e
                .apex_angle
                .map(|a| Value::new(a.to_degrees(), u.and_then(|u| u.apex_angle).map(f64::to_degrees))),
            form: e.form,
        };
        let diameter = match (&e.size_decision, diameter) {
            (Some(d), Some(actual)) => Some(DiameterCharacteristic {
                nominal: d.tolerance.nominal,
                lower: d.tolerance.lower,
                upper: d.tolerance.upper,
                actual,
                status: status(d.verdict),
            }),
            _ => None,
        };
        let form = e.form_decision.map(|f| FormCharacteristic {
            tolerance: f.tolerance,
            actual: e.form,
            status: status(f.verdict),
        });
        Results { feature, diameter, form, application: application.to_string() }
    }
}

pub use from_fit::{plan_spec, results_from_evaluation};

mod program;
pub use program::{
    write_program_results, CharacteristicKind, ProgramResults, ResultCharacteristic, ResultFeature,
    ResultKind, Tolerance,
};
