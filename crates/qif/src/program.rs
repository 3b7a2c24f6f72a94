//! QIF 3.0 results of a whole inspection program (`truepos dmis run --qif`): every measured or
//! constructed feature and every evaluated tolerance of a run in one document.
//!
//! What the document holds (entry point [`write_program_results`]):
//! - `DatumDefinitions` (one per datum label the tolerances name) and `DatumReferenceFrames`
//!   (one per distinct ordered list of datums: primary, secondary, tertiary; `SimpleDatum`s of
//!   the actual datum features, material modifier `NONE`).
//! - `Characteristics`: for each tolerance a definition, a nominal and an item, with ids that
//!   chain (item → nominal → definition); position and orientation definitions refer to their
//!   datum reference frame.
//! - `Results/MeasurementResultsSet/MeasurementResults`: one `XxxFeatureMeasurement` per feature
//!   result (point, line, plane, circle, sphere, cylinder, cone) with its actual values and
//!   standard uncertainties (k = 1, `combinedUncertainty` attributes) and its number of points
//!   (the user attribute `n_points`, `AttributeI1`); one `XxxCharacteristicMeasurement` per
//!   tolerance with its actual value, status (`PASS`/`FAIL`) and the ids of the feature
//!   measurements it was evaluated on; the overall inspection status.
//!
//! DMIS tolerances map to QIF characteristics as follows (lengths mm, angles degrees):
//!
//! | kind | QIF | definition | nominal | measured `Value` |
//! |---|---|---|---|---|
//! | `Form` (FLAT, STRGHT, CIRLTY, CYLCTY) | Flatness, Straightness, Circularity, Cylindricity | `ToleranceValue` | — | zone width |
//! | `Diameter`, `Radius`, `DistanceBetween` | Diameter, Radius, DistanceBetween | `Tolerance` (deviations) | `TargetValue` | actual size / distance |
//! | `AngleBetween` | AngleBetween | `Tolerance` (deviations, °) | `TargetValue` (°) | actual angle (°) |
//! | `Position` | Position (`DiametricalZone`, 2D, or `SphericalZone`, 3D; `REGARDLESS`) | `ToleranceValue`, DRF | — | zone diameter |
//! | `Perpendicularity`, `Parallelism` | the same (`PlanarZone` for planes, `DiametricalZone` for axes) | `ToleranceValue`, DRF | — | zone width |

use super::{check, dec, escape, scalar_unc, token, vec3, vec_unc, Status, Value, WriteError, STD_ID};
use std::fmt::Write as _;

/// The geometry kinds of a feature result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResultKind {
    /// A point (its location; the nominal's direction where it has one).
    Point,
    /// A line: a point on it and its direction.
    Line,
    /// A plane: a point on it and its normal.
    Plane,
    /// A circle: centre, normal and diameter.
    Circle,
    /// A sphere: centre and diameter.
    Sphere,
    /// A cylinder: a point on the axis, the axis and the diameter.
    Cylinder,
    /// A cone: apex, axis and full apex angle.
    Cone,
}

impl ResultKind {
    fn qif(self) -> &'static str {
        match self {
            ResultKind::Point => "Point",
            ResultKind::Line => "Line",
            ResultKind::Plane => "Plane",
            ResultKind::Circle => "Circle",
            ResultKind::Sphere => "Sphere",
            ResultKind::Cylinder => "Cylinder",
            ResultKind::Cone => "Cone",
        }
    }
}

/// One feature result (lengths mm, angles degrees, in the coordinate system the program
/// reported it in).
#[derive(Clone, Debug, PartialEq)]
pub struct ResultFeature {
    /// The program's label (written as `FeatureName`).
    pub label: String,
    /// The feature's geometry kind.
    pub kind: ResultKind,
    /// Point, line, plane: a point on it; circle, sphere: the centre; cylinder: a point on the
    /// axis; cone: the apex.
    pub location: Value<[f64; 3]>,
    /// Point, plane, circle: normal; line: direction; cylinder, cone: axis; sphere: none.
    pub direction: Option<Value<[f64; 3]>>,
    /// Circle, sphere, cylinder.
    pub diameter: Option<Value<f64>>,
    /// Cone: the full apex angle (degrees).
    pub full_angle_deg: Option<Value<f64>>,
    /// Least-squares fit of probed points (`true`) or constructed from other features.
    pub fitted: bool,
    /// Points behind the feature (0 for a constructed feature).
    pub n_points: usize,
}

/// The kind of a characteristic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CharacteristicKind {
    /// Flatness of a plane (minimum-zone width, mm).
    Flatness,
    /// Straightness of a line (zone width, mm).
    Straightness,
    /// Circularity (roundness) of a circle (zone width, mm).
    Circularity,
    /// Cylindricity of a cylinder (zone width, mm).
    Cylindricity,
    /// Diameter of a circle, sphere or cylinder (mm, with limits).
    Diameter,
    /// Radius of a circle, sphere or cylinder (mm, with limits).
    Radius,
    /// Distance between two features (mm, with limits).
    DistanceBetween,
    /// Angle between two features (degrees, with limits).
    AngleBetween,
    /// Position; `three_d`: a spherical zone, else a diametrical zone across the axis.
    Position {
        /// A spherical (3D) zone rather than a diametrical one.
        three_d: bool,
    },
    /// Perpendicularity to the datums.
    Perpendicularity {
        /// The toleranced feature is an axis or line (diametrical zone), else a plane.
        axis: bool,
    },
    /// Parallelism to the datums.
    Parallelism {
        /// The toleranced feature is an axis or line (diametrical zone), else a plane.
        axis: bool,
    },
}

impl CharacteristicKind {
    fn qif(self) -> &'static str {
        match self {
            CharacteristicKind::Flatness => "Flatness",
            CharacteristicKind::Straightness => "Straightness",
            CharacteristicKind::Circularity => "Circularity",
            CharacteristicKind::Cylindricity => "Cylindricity",
            CharacteristicKind::Diameter => "Diameter",
            CharacteristicKind::Radius => "Radius",
            CharacteristicKind::DistanceBetween => "DistanceBetween",
            CharacteristicKind::AngleBetween => "AngleBetween",
            CharacteristicKind::Position { .. } => "Position",
            CharacteristicKind::Perpendicularity { .. } => "Perpendicularity",
            CharacteristicKind::Parallelism { .. } => "Parallelism",
        }
    }
    /// Whether the characteristic has a nominal with limit deviations (else a tolerance zone).
    pub fn dimensional(self) -> bool {
        matches!(
            self,
            CharacteristicKind::Diameter
                | CharacteristicKind::Radius
                | CharacteristicKind::DistanceBetween
                | CharacteristicKind::AngleBetween
        )
    }
    /// Whether the characteristic is judged in a datum reference frame.
    pub fn has_datums(self) -> bool {
        matches!(
            self,
            CharacteristicKind::Position { .. }
                | CharacteristicKind::Perpendicularity { .. }
                | CharacteristicKind::Parallelism { .. }
        )
    }
}

/// The tolerance of a characteristic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tolerance {
    /// Form, position, orientation: the width (or diameter) of the zone.
    Zone(f64),
    /// Size, distance, angle: the nominal and the lower and upper deviations from it.
    Limits {
        /// The nominal value (mm or degrees).
        nominal: f64,
        /// The lower limit deviation from the nominal (signed, mm or degrees).
        lower: f64,
        /// The upper limit deviation from the nominal (signed, mm or degrees).
        upper: f64,
    },
}

/// One evaluated tolerance (lengths mm, angles degrees).
#[derive(Clone, Debug, PartialEq)]
pub struct ResultCharacteristic {
    /// The program's tolerance label (written as the item's `Name`).
    pub label: String,
    /// What is toleranced.
    pub kind: CharacteristicKind,
    /// The tolerance zone or the limits.
    pub tolerance: Tolerance,
    /// The actual value: the zone for form, position and orientation; the actual size,
    /// distance or angle (not its deviation) for the dimensional kinds.
    pub value: Value<f64>,
    /// Datum labels in order of precedence (position and orientation; at most three).
    pub datums: Vec<String>,
    /// Indices into [`ProgramResults::features`] of the features it was evaluated on.
    pub features: Vec<usize>,
    /// The verdict (in or out of tolerance).
    pub status: Status,
    /// A distance measured along one direction (unit vector in the coordinate system of the
    /// values): written as `AnalysisVector` with `ONEDIMENSIONAL`; `None`: point to point in
    /// 3D (`THREEDIMENSIONAL`). Only for [`CharacteristicKind::DistanceBetween`].
    pub analysis_vector: Option<[f64; 3]>,
}

/// Everything a program's results document holds.
#[derive(Clone, Debug, PartialEq)]
pub struct ProgramResults {
    /// The program (file name), written as the header's description.
    pub program: String,
    /// Written as the application's name in the header (e.g. "truepos 0.1.0").
    pub application: String,
    /// Every actual output feature, in output order.
    pub features: Vec<ResultFeature>,
    /// Every evaluated tolerance, in output order.
    pub characteristics: Vec<ResultCharacteristic>,
}

/// Why a program's results cannot be written (beyond [`WriteError`]).
fn invalid(what: &'static str) -> WriteError {
    WriteError::Invalid { what }
}

fn check_value(v: &Value<f64>, what: &'static str) -> Result<(), WriteError> {
    check(v.value, what)?;
    if let Some(u) = v.uncertainty {
        check(u, what)?;
    }
    Ok(())
}

fn check_vec(v: &Value<[f64; 3]>, what: &'static str) -> Result<(), WriteError> {
    for x in v.value.iter().chain(v.uncertainty.iter().flatten()) {
        check(*x, what)?;
    }
    Ok(())
}

/// Every number finite, every reference to a feature in range, datum labels usable as QIF
/// `NMTOKEN`s, at most three datums.
fn check_program(r: &ProgramResults) -> Result<(), WriteError> {
    for f in &r.features {
        check_vec(&f.location, "a feature's location")?;
        if let Some(d) = &f.direction {
            check_vec(d, "a feature's direction")?;
        }
        if let Some(d) = &f.diameter {
            check_value(d, "a feature's diameter")?;
        }
        if let Some(a) = &f.full_angle_deg {
            check_value(a, "a cone's apex angle")?;
        }
    }
    for c in &r.characteristics {
        check_value(&c.value, "a characteristic's value")?;
        match c.tolerance {
            Tolerance::Zone(z) => check(z, "a tolerance zone")?,
            Tolerance::Limits { nominal, lower, upper } => {
                for v in [nominal, lower, upper] {
                    check(v, "a tolerance's nominal or limits")?;
                }
            }
        }
        if c.kind.dimensional() != matches!(c.tolerance, Tolerance::Limits { .. }) {
            return Err(invalid(
                "a characteristic's tolerance (limits for sizes, distances and angles; a zone otherwise)",
            ));
        }
        if c.features.is_empty() || c.features.iter().any(|k| *k >= r.features.len()) {
            return Err(invalid("a characteristic's features (none, or not among the features)"));
        }
        if c.datums.len() > 3 {
            return Err(invalid("a characteristic's datums (at most three)"));
        }
        for d in &c.datums {
            if d.is_empty() || !d.chars().all(|ch| ch.is_alphanumeric() || "._-:".contains(ch)) {
                return Err(invalid("a datum label (letters, digits, '.', '_', '-', ':')"));
            }
        }
    }
    Ok(())
}

/// The `XxxFeatureMeasurement` of one feature result.
fn feature_xml(out: &mut String, f: &ResultFeature, id: usize) {
    let k = f.kind.qif();
    let _ = writeln!(out, "          <{k}FeatureMeasurement id=\"{id}\">");
    let _ = writeln!(
        out,
        "            <Attributes n=\"1\"><AttributeI1 name=\"n_points\" value=\"{}\"/></Attributes>",
        f.n_points
    );
    let _ = writeln!(out, "            <FeatureName>{}</FeatureName>", token(&f.label));
    if f.fitted && f.kind != ResultKind::Point {
        let _ = writeln!(
            out,
            "            <SubstituteFeatureAlgorithm><SubstituteFeatureAlgorithmEnum>LEASTSQUARES</SubstituteFeatureAlgorithmEnum></SubstituteFeatureAlgorithm>"
        );
    }
    let loc = format!("{}>{}", vec_unc(&f.location.uncertainty), vec3(&f.location.value));
    let dir = f.direction.as_ref().map(|d| format!("{}>{}", vec_unc(&d.uncertainty), vec3(&d.value)));
    let dia = f.diameter.map(|d| format!("{}>{}", scalar_unc(&d.uncertainty), dec(d.value)));
    fn push(out: &mut String, name: &str, v: &Option<String>) {
        if let Some(v) = v {
            let _ = writeln!(out, "            <{name}{v}</{name}>");
        }
    }
    match f.kind {
        ResultKind::Point | ResultKind::Plane => {
            push(out, "Location", &Some(loc));
            push(out, "Normal", &dir);
        }
        ResultKind::Line => {
            push(out, "Location", &Some(loc));
            push(out, "Direction", &dir);
        }
        ResultKind::Circle => {
            push(out, "Location", &Some(loc));
            push(out, "Normal", &dir);
            push(out, "Diameter", &dia);
        }
        ResultKind::Sphere => {
            push(out, "Location", &Some(loc));
            push(out, "Diameter", &dia);
        }
        ResultKind::Cylinder | ResultKind::Cone => {
            let _ = writeln!(out, "            <Axis>");
            let _ = writeln!(out, "              <AxisPoint{loc}</AxisPoint>");
            if let Some(d) = &dir {
                let _ = writeln!(out, "              <Direction{d}</Direction>");
            }
            let _ = writeln!(out, "            </Axis>");
            if f.kind == ResultKind::Cylinder {
                push(out, "Diameter", &dia);
            } else if let Some(a) = &f.full_angle_deg {
                let _ = writeln!(
                    out,
                    "            <FullAngle{}>{}</FullAngle>",
                    scalar_unc(&a.uncertainty),
                    dec(a.value)
                );
            }
        }
    }
    let _ = writeln!(out, "          </{k}FeatureMeasurement>");
}

const PRECEDENCE: [&str; 3] = ["PRIMARY", "SECONDARY", "TERTIARY"];

/// The QIF 3.0 results document of a whole program. Ids: the standard 1, the measurement
/// results 2, then the datum definitions, the datum reference frames, the feature
/// measurements, and four per characteristic (definition, nominal, item, measurement).
pub fn write_program_results(r: &ProgramResults) -> Result<String, WriteError> {
    check_program(r)?;
    let mut ids = Ids { next: super::RES_ID + 1 };
    let datums = Datums::of(r, &mut ids);
    let feature_ids: Vec<usize> = r.features.iter().map(|_| ids.take()).collect();
    let mut chars = CharacteristicLists::default();
    for c in &r.characteristics {
        chars.add(c, &mut ids, datums.frame_of(c), &feature_ids);
    }
    let mut doc = String::new();
    header_xml(&mut doc, r);
    super::standards_and_units(&mut doc);
    datums.write(&mut doc);
    chars.write_characteristics(&mut doc);
    results_xml(&mut doc, r, &feature_ids, &chars);
    Ok(super::envelope(&doc, ids.max()))
}

/// The element ids of a program's document, handed out in document order.
struct Ids {
    /// The next id to hand out.
    next: usize,
}

impl Ids {
    /// The next free id.
    fn take(&mut self) -> usize {
        let id = self.next;
        self.next += 1;
        id
    }

    /// The largest id handed out (the document's `idMax`).
    fn max(&self) -> usize {
        self.next - 1
    }
}

/// The datums the tolerances name: one definition per label and one reference frame per
/// distinct ordered list (in order of first use), with their ids.
struct Datums<'a> {
    /// Datum labels, each once.
    labels: Vec<&'a str>,
    /// The id of each label's `DatumDefinition`.
    label_ids: Vec<usize>,
    /// Ordered datum lists (primary, secondary, tertiary), each once.
    frames: Vec<&'a [String]>,
    /// The id of each list's `DatumReferenceFrame`.
    frame_ids: Vec<usize>,
}

impl<'a> Datums<'a> {
    /// Collect the labels and frames of the characteristics judged in a datum reference frame
    /// and give them ids (labels first, then frames).
    fn of(r: &'a ProgramResults, ids: &mut Ids) -> Self {
        let mut labels: Vec<&str> = Vec::new();
        let mut frames: Vec<&[String]> = Vec::new();
        for c in r.characteristics.iter().filter(|c| c.kind.has_datums() && !c.datums.is_empty()) {
            for d in &c.datums {
                if !labels.contains(&d.as_str()) {
                    labels.push(d);
                }
            }
            if !frames.contains(&c.datums.as_slice()) {
                frames.push(&c.datums);
            }
        }
        let label_ids = labels.iter().map(|_| ids.take()).collect();
        let frame_ids = frames.iter().map(|_| ids.take()).collect();
        Datums { labels, label_ids, frames, frame_ids }
    }

    /// The id of the reference frame a characteristic is judged in, if any.
    fn frame_of(&self, c: &ResultCharacteristic) -> Option<usize> {
        (c.kind.has_datums() && !c.datums.is_empty())
            .then(|| self.frames.iter().position(|f| *f == c.datums.as_slice()).map(|k| self.frame_ids[k]))
            .flatten()
    }

    /// `DatumDefinitions` and `DatumReferenceFrames` (nothing when no tolerance names a datum).
    fn write(&self, doc: &mut String) {
        if self.labels.is_empty() {
            return;
        }
        let _ = writeln!(doc, "  <DatumDefinitions n=\"{}\">", self.labels.len());
        for (l, id) in self.labels.iter().zip(&self.label_ids) {
            let _ = writeln!(
                doc,
                "    <DatumDefinition id=\"{id}\"><DatumLabel>{}</DatumLabel></DatumDefinition>",
                escape(l)
            );
        }
        let _ = writeln!(doc, "  </DatumDefinitions>");
        let _ = writeln!(doc, "  <DatumReferenceFrames n=\"{}\">", self.frames.len());
        for (f, id) in self.frames.iter().zip(&self.frame_ids) {
            let _ = writeln!(doc, "    <DatumReferenceFrame id=\"{id}\">\n      <Datums n=\"{}\">", f.len());
            for (k, d) in f.iter().enumerate() {
                let def =
                    self.labels.iter().position(|l| *l == d.as_str()).map(|i| self.label_ids[i]).unwrap_or(0);
                let _ = writeln!(
                    doc,
                    "        <Datum><SimpleDatum><DatumDefinitionId>{def}</DatumDefinitionId><MaterialModifier>NONE</MaterialModifier><ReferencedComponent>ACTUAL</ReferencedComponent></SimpleDatum><Precedence><PrecedenceEnum>{}</PrecedenceEnum></Precedence></Datum>",
                    PRECEDENCE[k.min(2)]
                );
            }
            let _ = writeln!(doc, "      </Datums>\n    </DatumReferenceFrame>");
        }
        let _ = writeln!(doc, "  </DatumReferenceFrames>");
    }
}

/// The characteristics' elements, one list per section of the document, built one
/// characteristic at a time.
#[derive(Default)]
struct CharacteristicLists {
    /// The `XxxCharacteristicDefinition`s.
    defs: String,
    /// The `XxxCharacteristicNominal`s.
    noms: String,
    /// The `XxxCharacteristicItem`s.
    items: String,
    /// The `XxxCharacteristicMeasurement`s.
    meas: String,
    /// Each characteristic's verdict, for the inspection status (one per characteristic).
    statuses: Vec<Status>,
}

impl CharacteristicLists {
    /// Add one characteristic: its definition (in the frame `drf`, if any), nominal, item and
    /// measurement (referring to the features' measurement ids), with four fresh ids.
    fn add(&mut self, c: &ResultCharacteristic, ids: &mut Ids, drf: Option<usize>, feature_ids: &[usize]) {
        let (def, nom, item, m) = (ids.take(), ids.take(), ids.take(), ids.take());
        let t = c.kind.qif();
        let body = definition_body(c, drf);
        let _ = writeln!(
            self.defs,
            "      <{t}CharacteristicDefinition id=\"{def}\">\n{body}\n      </{t}CharacteristicDefinition>"
        );
        let target = nominal_body(c);
        let _ = writeln!(
            self.noms,
            "      <{t}CharacteristicNominal id=\"{nom}\">\n        <CharacteristicDefinitionId>{def}</CharacteristicDefinitionId>{target}\n      </{t}CharacteristicNominal>"
        );
        let _ = writeln!(
            self.items,
            "      <{t}CharacteristicItem id=\"{item}\">\n        <Name>{}</Name>\n        <CharacteristicNominalId>{nom}</CharacteristicNominalId>\n      </{t}CharacteristicItem>",
            token(&c.label)
        );
        let ids: Vec<String> = c.features.iter().map(|k| format!("<Id>{}</Id>", feature_ids[*k])).collect();
        let unc = scalar_unc(&c.value.uncertainty);
        let _ = writeln!(
            self.meas,
            "            <{t}CharacteristicMeasurement id=\"{m}\">\n              <Status><CharacteristicStatusEnum>{}</CharacteristicStatusEnum></Status>\n              <CharacteristicItemId>{item}</CharacteristicItemId>\n              <FeatureMeasurementIds n=\"{}\">{}</FeatureMeasurementIds>\n              <Value{unc}>{}</Value>\n            </{t}CharacteristicMeasurement>",
            c.status.characteristic(),
            ids.len(),
            ids.join(""),
            dec(c.value.value)
        );
        self.statuses.push(c.status);
    }

    /// The `Characteristics` section: definitions, nominals and items (nothing without
    /// characteristics).
    fn write_characteristics(&self, doc: &mut String) {
        let n = self.statuses.len();
        if n > 0 {
            let CharacteristicLists { defs, noms, items, .. } = self;
            let _ = write!(
                doc,
                "  <Characteristics>\n    <FormalStandardId>{STD_ID}</FormalStandardId>\n    <CharacteristicDefinitions n=\"{n}\">\n{defs}    </CharacteristicDefinitions>\n    <CharacteristicNominals n=\"{n}\">\n{noms}    </CharacteristicNominals>\n    <CharacteristicItems n=\"{n}\">\n{items}    </CharacteristicItems>\n  </Characteristics>\n"
            );
        }
    }
}

/// The body of a characteristic's definition: the limit deviations, or the zone (with the
/// frame `drf`, material condition and zone shape for position and orientation).
fn definition_body(c: &ResultCharacteristic, drf: Option<usize>) -> String {
    let drf_xml = drf
        .map(|id| format!("\n        <DatumReferenceFrameId>{id}</DatumReferenceFrameId>"))
        .unwrap_or_default();
    match (c.kind, c.tolerance) {
        (_, Tolerance::Limits { lower, upper, .. }) => format!(
            "        <Tolerance><MaxValue>{}</MaxValue><MinValue>{}</MinValue><DefinedAsLimit>false</DefinedAsLimit></Tolerance>",
            dec(upper),
            dec(lower)
        ),
        (CharacteristicKind::Position { three_d }, Tolerance::Zone(z)) => format!(
            "        <ToleranceValue>{}</ToleranceValue>{drf_xml}\n        <MaterialCondition>REGARDLESS</MaterialCondition>\n        <ZoneShape>{}</ZoneShape>",
            dec(z),
            if three_d {
                "<SphericalZone/>"
            } else {
                "<DiametricalZone><Dimensionality>TWODIMENSIONAL</Dimensionality></DiametricalZone>"
            }
        ),
        (
            CharacteristicKind::Perpendicularity { axis } | CharacteristicKind::Parallelism { axis },
            Tolerance::Zone(z),
        ) => format!(
            "        <ToleranceValue>{}</ToleranceValue>{drf_xml}\n        <MaterialCondition>NONE</MaterialCondition>\n        <ZoneShape>{}</ZoneShape>",
            dec(z),
            if axis { "<DiametricalZone/>" } else { "<PlanarZone/>" }
        ),
        (_, Tolerance::Zone(z)) => format!("        <ToleranceValue>{}</ToleranceValue>", dec(z)),
    }
}

/// What a characteristic's nominal holds after its definition's id: the target value of the
/// dimensional kinds, and the analysis mode (and vector) the schema requires of the
/// between-characteristics.
fn nominal_body(c: &ResultCharacteristic) -> String {
    let target = match c.tolerance {
        Tolerance::Limits { nominal, .. } => {
            format!("\n        <TargetValue>{}</TargetValue>", dec(nominal))
        }
        Tolerance::Zone(_) => String::new(),
    };
    match (c.kind, c.analysis_vector) {
        (CharacteristicKind::DistanceBetween, Some(v)) => format!(
            "{target}\n        <AnalysisVector>{}</AnalysisVector>\n        <AnalysisMode>ONEDIMENSIONAL</AnalysisMode>",
            vec3(&v)
        ),
        (CharacteristicKind::DistanceBetween | CharacteristicKind::AngleBetween, _) => {
            format!("{target}\n        <AnalysisMode>THREEDIMENSIONAL</AnalysisMode>")
        }
        _ => target,
    }
}

/// The header: the application and the program as the description.
fn header_xml(doc: &mut String, r: &ProgramResults) {
    let _ = writeln!(
        doc,
        "  <Header>\n    <Application>\n      <Name>{}</Name>\n    </Application>\n    <Description>{}</Description>\n  </Header>",
        escape(&r.application),
        escape(&format!("inspection program {}", r.program))
    );
}

/// The `Results` section: the feature measurements (ids `feature_ids`), the characteristic
/// measurements and the overall inspection status.
fn results_xml(doc: &mut String, r: &ProgramResults, feature_ids: &[usize], chars: &CharacteristicLists) {
    let mut features = String::new();
    for (f, id) in r.features.iter().zip(feature_ids) {
        feature_xml(&mut features, f, *id);
    }
    let _ = write!(
        doc,
        "  <Results>\n    <MeasurementResultsSet n=\"1\">\n      <MeasurementResults id=\"{}\">\n",
        super::RES_ID
    );
    if !r.features.is_empty() {
        let _ = write!(
            doc,
            "        <MeasuredFeatures n=\"{}\">\n{features}        </MeasuredFeatures>\n",
            r.features.len()
        );
    }
    let n = chars.statuses.len();
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
        super::inspection_status(&chars.statuses)
    );
}
