//! The semantic model: a parsed program checked as a whole before anything moves, and turned
//! into a [`Plan`] in internal units (mm, rad; unit vectors normalised).
//!
//! What is checked (each refusal names file, line and column): the program starts with
//! `DMISMN`/`DMISMD` and ends with `ENDFIL`; units (`ANGDMS` is refused); sensors defined
//! (`SNSDEF`) before they are selected, and selected before `MEAS`; features defined (`FEAT`)
//! before they are measured, constructed or output, with the matching type, their vectors not
//! zero and sizes positive; `MEAS` blocks hold only `GOTO` and `PTMEAS`, as many points as
//! announced and at least as many as the fit needs; constructions from features that exist by
//! then, of types the construction can combine; datums defined from measured features; `DATSET`
//! axes and origins each set once, two directions at most on different axes; `TRANS`, `ROTATE`,
//! `SAVE`, `RECALL` on known coordinate systems; tolerances with positive zones, applied by
//! `OUTPUT` to actual features of a type they apply to (two features for `ANGLB`, `DISTB`);
//! `POS` with `MMC`/`LMC` (bonus tolerance) refused; datums named by `POS` must be those the
//! active coordinate system was set from; devices defined before they are opened.
//!
//! Entry point: [`check`].

use crate::ast::*;
use crate::error::{DmisError, ErrorKind, Pos};
use crate::parse::{Program, Stmt};
use std::collections::HashMap;
use truepos_math::{Point3, Vector3};

/// A nominal feature in mm (and rad), in the coordinate system active where it was defined.
#[derive(Debug, Clone, PartialEq)]
pub enum Nominal {
    /// A surface point.
    Point {
        /// The point, mm.
        p: Point3,
        /// The unit surface normal.
        n: Vector3,
    },
    /// A plane.
    Plane {
        /// A point of the plane, mm.
        p: Point3,
        /// The unit normal.
        n: Vector3,
    },
    /// A line.
    Line {
        /// A point of the line (the start of a bounded one), mm.
        p: Point3,
        /// The unit direction.
        dir: Vector3,
        /// The unit normal of the plane the line lies in, when given.
        plane: Option<Vector3>,
        /// Length of a bounded line, mm.
        length: Option<f64>,
    },
    /// A circle.
    Circle {
        /// The centre, mm.
        c: Point3,
        /// The unit normal of its plane.
        n: Vector3,
        /// The radius, mm.
        r: f64,
    },
    /// A cylinder.
    Cylinder {
        /// A point on the axis, mm.
        p: Point3,
        /// The unit axis.
        axis: Vector3,
        /// The radius, mm.
        r: f64,
        /// Length along the axis, mm, when given.
        length: Option<f64>,
    },
    /// A sphere.
    Sphere {
        /// The centre, mm.
        c: Point3,
        /// The radius, mm.
        r: f64,
    },
    /// Apex, unit axis from the apex into the cone, half of the included angle (rad).
    Cone {
        /// The apex, mm.
        apex: Point3,
        /// The unit axis, from the apex into the cone.
        axis: Vector3,
        /// Half the included angle, rad.
        half_angle: f64,
    },
}

/// A feature of the program.
#[derive(Debug, Clone, PartialEq)]
pub struct Feature {
    /// The label's name as written.
    pub name: String,
    /// The feature type.
    pub ftype: FeatType,
    /// Inner or outer, for features that have a side.
    pub side: Option<Side>,
    /// The nominal geometry.
    pub nominal: Nominal,
    /// Where the feature is defined in the program.
    pub pos: Pos,
}

/// A sensor (`SNSDEF`).
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// The sensor's label name as written.
    pub name: String,
    /// The tip diameter, mm.
    pub tip_diameter_mm: f64,
    /// Where the sensor is defined in the program.
    pub pos: Pos,
}

/// A tolerance in internal units.
#[derive(Debug, Clone, PartialEq)]
pub enum TolKind {
    /// Flatness zone, mm.
    Flat(f64),
    /// Straightness zone, mm.
    Strght(f64),
    /// Circularity zone, mm.
    Cirlty(f64),
    /// Cylindricity zone, mm.
    Cylcty(f64),
    /// Diameter deviations from nominal.
    Diam {
        /// Lower deviation, mm.
        lo: f64,
        /// Upper deviation, mm.
        hi: f64,
    },
    /// Radius deviations from nominal.
    Rad {
        /// Lower deviation, mm.
        lo: f64,
        /// Upper deviation, mm.
        hi: f64,
    },
    /// Position.
    Pos {
        /// A spherical (3D) rather than a cylindrical (2D) zone.
        three_d: bool,
        /// Zone diameter, mm.
        zone: f64,
    },
    /// Zone and the datum feature.
    Perp {
        /// Zone width, mm.
        zone: f64,
        /// Index of the datum feature.
        datum: usize,
    },
    /// Parallelism: zone and the datum feature.
    Parlel {
        /// Zone width, mm.
        zone: f64,
        /// Index of the datum feature.
        datum: usize,
    },
    /// Nominal angle and deviations (rad).
    Anglb {
        /// Nominal angle, rad.
        angle: f64,
        /// Lower deviation, rad.
        lo: f64,
        /// Upper deviation, rad.
        hi: f64,
    },
    /// Distance between two features.
    Distb {
        /// Nominal distance, mm.
        dist: f64,
        /// Lower deviation, mm.
        lo: f64,
        /// Upper deviation, mm.
        hi: f64,
        /// The direction measured along (`None`: point to point).
        axis: Option<DistAxis>,
    },
}

impl TolKind {
    /// How many features the tolerance relates (1, or 2 for ANGLB and DISTB).
    pub fn n_features(&self) -> usize {
        match self {
            TolKind::Anglb { .. } | TolKind::Distb { .. } => 2,
            _ => 1,
        }
    }
}

/// A tolerance (`TOL`).
#[derive(Debug, Clone, PartialEq)]
pub struct Tolerance {
    /// The tolerance's label name as written.
    pub name: String,
    /// The tolerance in internal units.
    pub kind: TolKind,
    /// The statement as written (echoed in the output file, in the program's units).
    pub statement: Statement,
    /// Where the tolerance is defined in the program.
    pub pos: Pos,
}

/// One motion inside `MEAS` (part coordinates of the active coordinate system, mm).
#[derive(Debug, Clone, PartialEq)]
pub enum Move {
    /// `GOTO` to a point, mm.
    Goto(Point3),
    /// `GOTO/INCR` by a displacement, mm.
    GotoIncr(Vector3),
    /// A point to probe and its approach direction (out of the material); `None`: from the
    /// nominal feature.
    Probe {
        /// The nominal point, mm.
        p: Point3,
        /// The unit approach direction, when the program gives one.
        dir: Option<Vector3>,
    },
}

/// How a feature is constructed (indices of features).
#[derive(Debug, Clone, PartialEq)]
pub enum Construction {
    /// Best fit through the points of these features.
    Bf(Vec<usize>),
    /// Intersection of two features.
    Intof(usize, usize),
    /// The first feature projected onto the second (a plane).
    Projct(usize, usize),
    /// The point midway between two features' positions.
    Midpt(usize, usize),
}

/// `DATSET` in indices of features.
#[derive(Debug, Clone, PartialEq)]
pub enum DatsetOp {
    /// The machine coordinate system.
    Mcs,
    /// Datum features with the axis and origin words each sets.
    Datums(Vec<(usize, Vec<DatsetWord>)>),
}

/// One item of `OUTPUT`.
#[derive(Debug, Clone, PartialEq)]
pub enum OutputItem {
    /// A feature's actual (`FA`) or nominal (`F`) values.
    Feature {
        /// Index of the feature.
        feature: usize,
        /// Actual (`FA`) rather than nominal (`F`).
        actual: bool,
    },
    /// A tolerance evaluated on the output's features (`TA`), or only echoed (`T`).
    Tolerance {
        /// Index of the tolerance.
        tolerance: usize,
        /// Indices of the features it is evaluated on.
        features: Vec<usize>,
        /// Evaluated (`TA`) rather than only echoed (`T`).
        actual: bool,
    },
}

/// One step of the plan.
#[derive(Debug, Clone, PartialEq)]
pub enum Op {
    /// `GOTO` to a point (active part coordinates), mm.
    Goto(Point3),
    /// `GOTO/INCR` by a displacement, mm.
    GotoIncr(Vector3),
    /// Feed of `FEDRAT` (mm/s; `None`: the machine's default).
    Feed {
        /// Which speed.
        kind: FeedKind,
        /// The speed, mm/s.
        mm_s: Option<f64>,
    },
    /// `SNSET/APPRCH`, mm.
    Approach(f64),
    /// `SNSET/SEARCH`, mm.
    Search(f64),
    /// `SNSET/RETRCT`, mm.
    Retract(f64),
    /// `PRCOMP`: compensate probed points by the tip radius.
    Compensation(bool),
    /// `SNSLCT`: index of the sensor.
    SelectSensor(usize),
    /// `FEAT`: the nominal takes the active coordinate system.
    Define(usize),
    /// `MEAS … ENDMES`, each motion with its statement's position.
    Measure {
        /// Index of the feature measured.
        feature: usize,
        /// The motions and probings, in order.
        moves: Vec<(Move, Pos)>,
    },
    /// `CONST`: construct a feature.
    Construct {
        /// Index of the constructed feature.
        feature: usize,
        /// How it is constructed.
        method: Construction,
    },
    /// `DATSET`: a coordinate system from datums.
    Datset {
        /// The coordinate system's label name.
        name: String,
        /// How it is built.
        def: DatsetOp,
    },
    /// `TRANS`: origins along axes 0..3 to a value (mm) or a feature's position.
    Trans {
        /// The new coordinate system's label name, when assigned.
        name: Option<String>,
        /// Axis index and target of each origin moved.
        items: Vec<(usize, TransTo)>,
    },
    /// `ROTATE` about axis 0..3.
    Rotate {
        /// The new coordinate system's label name, when assigned.
        name: Option<String>,
        /// The axis index rotated about.
        axis: usize,
        /// An angle or a feature's direction.
        by: RotateTo,
    },
    /// `SAVE`: keep the active coordinate system under this name.
    Save(String),
    /// `RECALL`: make the saved coordinate system of this name active.
    Recall(String),
    /// `UNITS` (what the output file is written in from here on).
    Units {
        /// The length unit.
        length: LengthUnit,
        /// The angle unit.
        angle: AngleUnit,
    },
    /// `OUTPUT`: report features and tolerances.
    Output(Vec<OutputItem>),
    /// `TEXT`: a message.
    Text {
        /// Where it goes.
        kind: TextKind,
        /// The text.
        text: String,
    },
}

/// Where `TRANS` moves an origin.
#[derive(Debug, Clone, PartialEq)]
pub enum TransTo {
    /// A value, mm.
    Value(f64),
    /// The position of the feature with this index.
    Feature(usize),
}

/// What `ROTATE` turns by.
#[derive(Debug, Clone, PartialEq)]
pub enum RotateTo {
    /// An angle, rad.
    Angle(f64),
    /// The feature's direction becomes this axis (0..3).
    Feature(usize, usize),
}

/// A step with where it comes from.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// What the step does.
    pub op: Op,
    /// Where its statement is in the program.
    pub pos: Pos,
    /// The statement in canonical DMIS where the output file repeats it (`UNITS`, `DATSET`,
    /// `TRANS`, `ROTATE`, `SAVE`, `RECALL`).
    pub echo: Option<String>,
}

/// A checked program, ready to run.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The program's file name, as reported in errors.
    pub file: String,
    /// The title of `DMISMN`.
    pub title: String,
    /// The name of `FILNAM`, when given.
    pub filnam: Option<String>,
    /// Every feature of the program, indexed by the steps.
    pub features: Vec<Feature>,
    /// Every sensor of the program, indexed by the steps.
    pub sensors: Vec<Sensor>,
    /// Every tolerance of the program, indexed by the steps.
    pub tolerances: Vec<Tolerance>,
    /// The steps, in program order.
    pub steps: Vec<Step>,
    /// The file named by the `DEVICE/STOR` that is opened for `OUTPUT`, as written.
    pub output_file: Option<String>,
    /// Number of points the plan probes (the `PTMEAS` statements it runs).
    pub n_probes: usize,
}

/// Length unit → mm.
pub fn mm_per(u: LengthUnit) -> f64 {
    match u {
        LengthUnit::Mm => 1.0,
        LengthUnit::Cm => 10.0,
        LengthUnit::M => 1000.0,
        LengthUnit::Inch => 25.4,
        LengthUnit::Feet => 304.8,
    }
}

/// Angle unit → rad (ANGDMS is refused by [`check`]).
pub fn rad_per(u: AngleUnit) -> f64 {
    match u {
        AngleUnit::AngDec => std::f64::consts::PI / 180.0,
        AngleUnit::AngRad | AngleUnit::AngDms => 1.0,
    }
}

/// Fewest points a feature type can be fitted from.
pub fn min_points(t: FeatType) -> usize {
    match t {
        FeatType::Point => 1,
        FeatType::Line => 2,
        FeatType::Plane | FeatType::Circle => 3,
        FeatType::Sphere => 4,
        FeatType::Cylndr => 5,
        FeatType::Cone => 6,
    }
}

fn has_direction(t: FeatType) -> bool {
    matches!(t, FeatType::Plane | FeatType::Line | FeatType::Cylndr | FeatType::Cone | FeatType::Circle)
}

fn point_like(t: FeatType) -> bool {
    matches!(t, FeatType::Point | FeatType::Circle | FeatType::Sphere)
}

/// A `MEAS` being read.
struct OpenMeas {
    /// Index of the feature measured.
    feature: usize,
    /// The number of points the `MEAS` announces.
    n: u32,
    /// Where the `MEAS` is.
    pos: Pos,
    /// The motions and probings so far, each with its statement's position.
    moves: Vec<(Move, Pos)>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Have {
    /// Defined by FEAT only.
    Nominal,
    /// Measured or constructed; `points`: has measured points (form can be evaluated).
    Actual { points: bool },
}

struct Checker<'a> {
    file: &'a str,
    length: LengthUnit,
    angle: AngleUnit,
    plan: Plan,
    feat: HashMap<String, (usize, Have)>,
    sensors: HashMap<String, usize>,
    selected: bool,
    datums: HashMap<String, usize>,
    csys: HashMap<String, Option<Vec<usize>>>,
    /// Datum features the active coordinate system was set from (`None`: MCS or not by datums).
    active_datums: Option<Vec<usize>>,
    tols: HashMap<String, usize>,
    devices: HashMap<String, (DeviceKind, Option<String>, bool)>,
    /// The `MEAS` whose `ENDMES` has not come yet.
    meas: Option<OpenMeas>,
    /// Whether `ENDFIL` has come.
    ended: bool,
}

impl Checker<'_> {
    fn err(&self, pos: Pos, kind: ErrorKind, m: impl Into<String>) -> DmisError {
        DmisError::new(self.file, pos, kind, m)
    }
    fn sem(&self, pos: Pos, m: impl Into<String>) -> DmisError {
        self.err(pos, ErrorKind::Semantic, m)
    }
    fn len(&self, v: f64) -> f64 {
        v * mm_per(self.length)
    }
    fn pt(&self, v: &Xyz) -> Point3 {
        Point3::new(self.len(v[0]), self.len(v[1]), self.len(v[2]))
    }
    fn unit(&self, v: &Xyz, pos: Pos, what: &str) -> Result<Vector3, DmisError> {
        let u = Vector3::new(v[0], v[1], v[2]);
        let n = u.norm();
        if !(n.is_finite() && n > 1e-12) {
            return Err(self.sem(pos, format!("{what} ({}, {}, {}) has no direction", v[0], v[1], v[2])));
        }
        Ok(u / n)
    }
    fn positive(&self, v: f64, pos: Pos, what: &str) -> Result<f64, DmisError> {
        if v > 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(self.sem(pos, format!("{what} must be positive, not {v}")))
        }
    }
    fn finite_mm(&self, v: f64, pos: Pos) -> Result<f64, DmisError> {
        let x = self.len(v);
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.sem(pos, format!("{v} is out of range in mm")))
        }
    }
    fn finite_pt(&self, v: &Xyz, st: &Stmt, first_arg: usize) -> Result<Point3, DmisError> {
        for k in 0..3 {
            self.finite_mm(v[k], st.arg(first_arg + k))?;
        }
        Ok(self.pt(v))
    }
    /// A feature by label: its index, type and state.
    fn feature(&self, l: &Label, pos: Pos) -> Result<(usize, Have), DmisError> {
        self.feat.get(&l.key()).copied().ok_or_else(|| {
            self.sem(pos, format!("F({}) is not defined (FEAT) before this statement", l.name))
        })
    }
    /// A feature that must have actual values by now.
    fn actual(&self, l: &Label, pos: Pos) -> Result<(usize, bool), DmisError> {
        match self.feature(l, pos)? {
            (k, Have::Actual { points }) => Ok((k, points)),
            (_, Have::Nominal) => Err(self.sem(
                pos,
                format!(
                    "FA({}) has not been measured (MEAS) or constructed (CONST) before this statement",
                    l.name
                ),
            )),
        }
    }
    fn ftype(&self, k: usize) -> FeatType {
        self.plan.features[k].ftype
    }
    fn datum(&self, l: &Label, pos: Pos) -> Result<usize, DmisError> {
        match l.kind {
            LabelKind::Fa | LabelKind::F => Ok(self.actual(l, pos)?.0),
            _ => self.datums.get(&l.key()).copied().ok_or_else(|| {
                self.sem(pos, format!("the datum {l} is not defined (DATDEF) before this statement"))
            }),
        }
    }
}

/// Check a program as a whole and build its plan. Nothing outside the subset, nothing malformed
/// and nothing inconsistent passes: the first problem is returned with its place.
pub fn check(program: &Program) -> Result<Plan, DmisError> {
    let mut c = Checker::new(&program.file);
    let sts = &program.statements;
    let Some(first) = sts.first() else {
        return Err(c.sem(Pos::new(1, 1), "the program is empty (a part program starts with DMISMN)"));
    };
    match &first.statement {
        Statement::Dmismn { title, .. } | Statement::Dmismd { title, .. } => c.plan.title = title.clone(),
        other => {
            return Err(c.sem(first.pos, format!("a part program starts with DMISMN, not {}", other.major())))
        }
    }
    for st in &sts[1..] {
        c.statement(st)?;
    }
    if let Some(m) = &c.meas {
        return Err(c.sem(m.pos, "MEAS without ENDMES"));
    }
    if !c.ended {
        let last = sts.last().map(|s| s.pos).unwrap_or_default();
        return Err(c.sem(last, "the program has no ENDFIL"));
    }
    Ok(c.plan)
}

/// The statements: one checker per statement kind, each adding its step to the plan.
impl<'a> Checker<'a> {
    /// A checker at the start of the program in `file` (mm, degrees).
    fn new(file: &'a str) -> Checker<'a> {
        Checker {
            file,
            length: LengthUnit::Mm,
            angle: AngleUnit::AngDec,
            plan: Plan {
                file: file.to_string(),
                title: String::new(),
                filnam: None,
                features: Vec::new(),
                sensors: Vec::new(),
                tolerances: Vec::new(),
                steps: Vec::new(),
                output_file: None,
                n_probes: 0,
            },
            feat: HashMap::new(),
            sensors: HashMap::new(),
            selected: false,
            datums: HashMap::new(),
            csys: HashMap::new(),
            active_datums: None,
            tols: HashMap::new(),
            devices: HashMap::new(),
            meas: None,
            ended: false,
        }
    }

    /// Appends a step made by the statement at `pos`.
    fn push(&mut self, op: Op, pos: Pos) {
        self.plan.steps.push(Step { op, pos, echo: None });
    }

    /// One statement after the first: inside a `MEAS` block or outside it.
    fn statement(&mut self, st: &Stmt) -> Result<(), DmisError> {
        if self.ended {
            return Err(self.sem(st.pos, "statement after ENDFIL"));
        }
        if let Some(m) = self.meas.take() {
            return self.in_meas(m, st);
        }
        let n_steps = self.plan.steps.len();
        self.outside_meas(st)?;
        // The output file repeats these statements where their step is.
        if self.plan.steps.len() > n_steps
            && matches!(
                st.statement,
                Statement::Units { .. }
                    | Statement::Datset { .. }
                    | Statement::Trans { .. }
                    | Statement::Rotate { .. }
                    | Statement::Save(_)
                    | Statement::Recall(_)
            )
        {
            if let Some(s) = self.plan.steps.last_mut() {
                s.echo = Some(st.statement.to_string());
            }
        }
        Ok(())
    }

    /// A statement between `MEAS` and `ENDMES`: a motion or probing of `m`, or its end.
    fn in_meas(&mut self, mut m: OpenMeas, st: &Stmt) -> Result<(), DmisError> {
        let pos = st.pos;
        let mv = match &st.statement {
            Statement::Goto(Goto::Abs(p)) => Move::Goto(self.finite_pt(p, st, 0)?),
            Statement::Goto(Goto::Incr { dist, dir }) => {
                let d = self.finite_mm(*dist, st.arg(1))?;
                let u = self.unit(dir, st.arg(2), "the direction")?;
                Move::GotoIncr(u * d)
            }
            Statement::Ptmeas { p, n: dir } => {
                let q = self.finite_pt(p, st, 1)?;
                let d = match dir {
                    Some(d) => Some(self.unit(d, st.arg(4), "the approach direction")?),
                    None => None,
                };
                Move::Probe { p: q, dir: d }
            }
            Statement::Endmes => return self.check_endmes(m, pos),
            other => {
                return Err(self.sem(
                    pos,
                    format!(
                        "{} is not allowed between MEAS (line {}) and ENDMES (only GOTO and PTMEAS)",
                        other.major(),
                        m.pos.line
                    ),
                ))
            }
        };
        m.moves.push((mv, pos));
        self.meas = Some(m);
        Ok(())
    }

    /// `ENDMES` at `pos`: `m` has the points it announced, enough for its fit; its step.
    fn check_endmes(&mut self, m: OpenMeas, pos: Pos) -> Result<(), DmisError> {
        let probes = m.moves.iter().filter(|m| matches!(m.0, Move::Probe { .. })).count();
        let ft = self.ftype(m.feature);
        if probes != m.n as usize {
            return Err(self.sem(
                pos,
                format!("the MEAS at line {} announces {} points but measures {probes}", m.pos.line, m.n),
            ));
        }
        if probes < min_points(ft) {
            return Err(self.sem(
                m.pos,
                format!("a {ft} needs at least {} points, this MEAS has {probes}", min_points(ft)),
            ));
        }
        self.plan.n_probes += probes;
        let name = self.plan.features[m.feature].name.to_ascii_uppercase();
        self.feat.insert(name, (m.feature, Have::Actual { points: true }));
        // The step is located at its MEAS (progress and errors name that line).
        self.push(Op::Measure { feature: m.feature, moves: m.moves }, m.pos);
        Ok(())
    }

    /// A statement outside `MEAS` blocks: dispatches to its checker.
    fn outside_meas(&mut self, st: &Stmt) -> Result<(), DmisError> {
        let pos = st.pos;
        match &st.statement {
            Statement::Dmismn { .. } | Statement::Dmismd { .. } => {
                return Err(self.sem(pos, format!("{} may only be the first statement", st.statement.major())))
            }
            Statement::Endfil => self.ended = true,
            Statement::Filnam { name, .. } => self.plan.filnam = Some(name.clone()),
            Statement::Units { length, angle, .. } => self.check_units(st, *length, *angle)?,
            Statement::Disply(_) | Statement::Snsmnt { .. } => {}
            Statement::Prcomp(on) => self.push(Op::Compensation(*on), pos),
            Statement::Mode(ws) => self.check_mode(st, ws)?,
            Statement::Fedrat { kind, unit, value } => self.check_fedrat(st, *kind, *unit, *value)?,
            Statement::Snset(s) => self.check_snset(st, s)?,
            Statement::Snsdef { label, dir, diam, .. } => self.check_snsdef(st, label, dir, *diam)?,
            Statement::Snslct(l) => self.check_snslct(st, l)?,
            Statement::Goto(Goto::Abs(p)) => {
                let q = self.finite_pt(p, st, 0)?;
                self.push(Op::Goto(q), pos);
            }
            Statement::Goto(Goto::Incr { dist, dir }) => {
                let d = self.finite_mm(*dist, st.arg(1))?;
                let u = self.unit(dir, st.arg(2), "the direction")?;
                self.push(Op::GotoIncr(u * d), pos);
            }
            Statement::Feat { label, geom } => self.check_feat(st, label, geom)?,
            Statement::Meas { ftype, feature, n } => self.check_meas(st, *ftype, feature, *n)?,
            Statement::Endmes => return Err(self.sem(pos, "ENDMES without MEAS")),
            Statement::Ptmeas { .. } => return Err(self.sem(pos, "PTMEAS outside MEAS … ENDMES")),
            Statement::Const { ftype, feature, method } => self.check_const(st, *ftype, feature, method)?,
            Statement::Datdef { datum, feature, .. } => {
                // The feature is the first argument in both forms.
                let (k, _) = self.actual(feature, st.arg(0))?;
                self.datums.insert(datum.key(), k);
            }
            Statement::Datset { label, def } => self.check_datset(st, label, def)?,
            Statement::Trans { label, items } => self.check_trans(st, label.as_ref(), items)?,
            Statement::Rotate { label, axis, by } => self.check_rotate(st, label.as_ref(), *axis, by)?,
            Statement::Save(l) => {
                self.csys.insert(l.key(), self.active_datums.clone());
                self.push(Op::Save(l.name.clone()), pos);
            }
            Statement::Recall(l) => self.check_recall(st, l)?,
            Statement::Tol { label, tol } => self.check_tol(st, label, tol)?,
            Statement::Output(ls) => {
                let items = output(self, ls, st)?;
                self.push(Op::Output(items), pos);
            }
            Statement::Text { kind, text } => self.check_text(st, *kind, text)?,
            Statement::Device { label, kind, file } => {
                self.devices.insert(label.key(), (*kind, file.clone(), false));
            }
            Statement::Open { device, words } => self.check_open(st, device, words)?,
            Statement::Close { device, .. } => self.check_close(st, device)?,
        }
        Ok(())
    }

    /// `UNITS`: the units of the statements that follow (`ANGDMS` refused).
    fn check_units(&mut self, st: &Stmt, length: LengthUnit, angle: AngleUnit) -> Result<(), DmisError> {
        if angle == AngleUnit::AngDms {
            return Err(self.err(
                st.arg(1),
                ErrorKind::Unsupported,
                "UNITS: ANGDMS is not supported (ANGDEC, ANGRAD)",
            ));
        }
        self.length = length;
        self.angle = angle;
        self.push(Op::Units { length, angle }, st.pos);
        Ok(())
    }

    /// `MODE`: automatic or programmed (manual measurement refused).
    fn check_mode(&self, st: &Stmt, ws: &[ModeWord]) -> Result<(), DmisError> {
        if !ws.iter().any(|w| matches!(w, ModeWord::Auto | ModeWord::Prog)) {
            return Err(self.err(
                st.arg(0),
                ErrorKind::Unsupported,
                "MODE/MAN (manual measurement) is not supported: truepos runs programs automatically",
            ));
        }
        Ok(())
    }

    /// `FEDRAT`: a positive speed, converted to mm/s (a percentage in (0, 100]).
    fn check_fedrat(
        &mut self,
        st: &Stmt,
        kind: FeedKind,
        unit: FeedUnit,
        value: Option<f64>,
    ) -> Result<(), DmisError> {
        let mm_s = match (unit, value) {
            (FeedUnit::Mpm, Some(v)) => Some(self.positive(v, st.arg(2), "the speed")? * 1000.0 / 60.0),
            (FeedUnit::Mmps, Some(v)) => Some(self.positive(v, st.arg(2), "the speed")?),
            (FeedUnit::Ipm, Some(v)) => Some(self.positive(v, st.arg(2), "the speed")? * 25.4 / 60.0),
            (FeedUnit::Ips, Some(v)) => Some(self.positive(v, st.arg(2), "the speed")? * 25.4),
            (FeedUnit::Pcent, Some(v)) => {
                if !(v > 0.0 && v <= 100.0) {
                    return Err(self.sem(st.arg(2), format!("a speed in percent is in (0, 100], not {v}")));
                }
                None
            }
            _ => None,
        };
        self.push(Op::Feed { kind, mm_s }, st.pos);
        Ok(())
    }

    /// `SNSET`: approach, retract and search distances (the others are only checked).
    fn check_snset(&mut self, st: &Stmt, s: &Snset) -> Result<(), DmisError> {
        match s {
            Snset::Apprch(v) | Snset::Retrct(v) | Snset::Search(v) => {
                let mm = self.finite_mm(*v, st.arg(1))?;
                let ok = if matches!(s, Snset::Search(_)) { mm > 0.0 } else { mm >= 0.0 };
                if !ok {
                    return Err(self.sem(st.arg(1), format!("SNSET: the distance must be positive, not {v}")));
                }
                self.push(
                    match s {
                        Snset::Apprch(_) => Op::Approach(mm),
                        Snset::Retrct(_) => Op::Retract(mm),
                        _ => Op::Search(mm),
                    },
                    st.pos,
                );
            }
            Snset::Depth(v) | Snset::Clrsrf(None, v) => {
                self.finite_mm(*v, st.arg(1))?;
            }
            Snset::Clrsrf(Some(l), v) => {
                self.feature(l, st.arg(1))?;
                self.finite_mm(*v, st.arg(2))?;
            }
            Snset::ClrsrfOff => {}
        }
        Ok(())
    }

    /// `SNSDEF`: a new sensor with a direction and a positive tip diameter.
    fn check_snsdef(&mut self, st: &Stmt, label: &Label, dir: &Xyz, diam: f64) -> Result<(), DmisError> {
        self.unit(dir, st.arg(6), "the probe direction")?;
        let d = self.len(self.positive(diam, st.arg(9), "the tip diameter")?);
        if let Some(k) = self.sensors.get(&label.key()) {
            return Err(self.sem(
                st.label_pos,
                format!("{label} is already defined at line {}", self.plan.sensors[*k].pos.line),
            ));
        }
        self.sensors.insert(label.key(), self.plan.sensors.len());
        self.plan.sensors.push(Sensor { name: label.name.clone(), tip_diameter_mm: d, pos: st.pos });
        Ok(())
    }

    /// `SNSLCT`: a sensor defined before.
    fn check_snslct(&mut self, st: &Stmt, l: &Label) -> Result<(), DmisError> {
        let Some(k) = self.sensors.get(&l.key()).copied() else {
            return Err(self.sem(
                st.arg(0),
                format!("the sensor S({}) is not defined (SNSDEF) before this statement", l.name),
            ));
        };
        self.selected = true;
        self.push(Op::SelectSensor(k), st.pos);
        Ok(())
    }

    /// `F(l)=FEAT`: a new nominal feature in internal units.
    fn check_feat(&mut self, st: &Stmt, label: &Label, geom: &FeatGeom) -> Result<(), DmisError> {
        if label.kind == LabelKind::Fa {
            return Err(self
                .sem(st.label_pos, "FA(…)=FEAT is a result (output file) statement, not part of a program"));
        }
        if let Some((k, _)) = self.feat.get(&label.key()) {
            return Err(self.sem(
                st.label_pos,
                format!("{label} is already defined at line {}", self.plan.features[*k].pos.line),
            ));
        }
        let (side, nominal) = nominal(self, geom, st)?;
        let k = self.plan.features.len();
        self.plan.features.push(Feature {
            name: label.name.clone(),
            ftype: geom.feat_type(),
            side,
            nominal,
            pos: st.pos,
        });
        self.feat.insert(label.key(), (k, Have::Nominal));
        self.push(Op::Define(k), st.pos);
        Ok(())
    }

    /// `MEAS`: opens the block of a defined feature of its type, with a sensor selected.
    fn check_meas(&mut self, st: &Stmt, ftype: FeatType, feature: &Label, n: u32) -> Result<(), DmisError> {
        let (k, _) = self.feature(feature, st.arg(1))?;
        if self.ftype(k) != ftype {
            return Err(
                self.sem(st.arg(0), format!("MEAS/{ftype} of {feature}, which is a {}", self.ftype(k)))
            );
        }
        if !self.selected {
            return Err(self.sem(st.pos, "no sensor is selected (SNSLCT) before this MEAS"));
        }
        self.meas = Some(OpenMeas { feature: k, n, pos: st.pos, moves: Vec::new() });
        Ok(())
    }

    /// `CONST`: a defined feature of its type, constructed from features that exist by now.
    fn check_const(
        &mut self,
        st: &Stmt,
        ftype: FeatType,
        feature: &Label,
        method: &ConstMethod,
    ) -> Result<(), DmisError> {
        let (k, _) = self.feature(feature, st.arg(1))?;
        if self.ftype(k) != ftype {
            return Err(
                self.sem(st.arg(0), format!("CONST/{ftype} of {feature}, which is a {}", self.ftype(k)))
            );
        }
        let (m, points) = construction(self, ftype, method, st)?;
        self.feat.insert(feature.key(), (k, Have::Actual { points }));
        self.push(Op::Construct { feature: k, method: m }, st.pos);
        Ok(())
    }

    /// `DATSET`: the machine coordinate system, or one from datums.
    fn check_datset(&mut self, st: &Stmt, label: &Label, def: &Datset) -> Result<(), DmisError> {
        let op = match def {
            Datset::Mcs => {
                self.active_datums = None;
                DatsetOp::Mcs
            }
            Datset::Datums(ds) => {
                let out = self.datset_datums(st, ds)?;
                self.active_datums = Some(out.iter().map(|(k, _)| *k).collect());
                DatsetOp::Datums(out)
            }
        };
        self.csys.insert(label.key(), self.active_datums.clone());
        self.push(Op::Datset { name: label.name.clone(), def: op }, st.pos);
        Ok(())
    }

    /// The datums of `DATSET`: defined, each axis and origin set once, two directions at most.
    fn datset_datums(
        &self,
        st: &Stmt,
        ds: &[(Label, Vec<DatsetWord>)],
    ) -> Result<Vec<(usize, Vec<DatsetWord>)>, DmisError> {
        let mut seen: Vec<DatsetWord> = Vec::new();
        let mut dirs: Vec<DatsetWord> = Vec::new();
        let mut out = Vec::new();
        let mut argk = 0;
        for (l, ws) in ds {
            let lpos = st.arg(argk);
            let k = self.datum(l, lpos)?;
            let t = self.ftype(k);
            for (j, w) in ws.iter().enumerate() {
                let wpos = st.arg(argk + 1 + j);
                if seen.contains(w) {
                    return Err(self.sem(wpos, format!("DATSET: {w} is set twice")));
                }
                seen.push(*w);
                if matches!(w, DatsetWord::XDir | DatsetWord::YDir | DatsetWord::ZDir) {
                    if !has_direction(t) {
                        return Err(self.sem(wpos, format!("DATSET: a {t} has no direction for {w}")));
                    }
                    dirs.push(*w);
                }
            }
            argk += 1 + ws.len();
            out.push((k, ws.clone()));
        }
        if dirs.len() > 2 {
            return Err(self.sem(st.pos, "DATSET: at most two directions (the third follows)"));
        }
        Ok(out)
    }

    /// `TRANS`: each origin set once, to a value or an actual feature's position.
    fn check_trans(
        &mut self,
        st: &Stmt,
        label: Option<&Label>,
        items: &[(Origin, TransBy)],
    ) -> Result<(), DmisError> {
        let mut seen = Vec::new();
        let mut out = Vec::new();
        for (j, (o, by)) in items.iter().enumerate() {
            let axis = match o {
                Origin::XOrig => 0,
                Origin::YOrig => 1,
                Origin::ZOrig => 2,
            };
            if seen.contains(&axis) {
                return Err(self.sem(st.arg(2 * j), format!("TRANS: {o} is set twice")));
            }
            seen.push(axis);
            out.push((
                axis,
                match by {
                    TransBy::Value(v) => TransTo::Value(self.finite_mm(*v, st.arg(2 * j + 1))?),
                    TransBy::Feature(l) => TransTo::Feature(self.actual(l, st.arg(2 * j + 1))?.0),
                },
            ));
        }
        if let Some(l) = label {
            self.csys.insert(l.key(), self.active_datums.clone());
        }
        self.push(Op::Trans { name: label.map(|l| l.name.clone()), items: out }, st.pos);
        Ok(())
    }

    /// `ROTATE`: by an angle, or so that an actual feature's direction becomes another axis.
    fn check_rotate(
        &mut self,
        st: &Stmt,
        label: Option<&Label>,
        axis: RotAxis,
        by: &RotateBy,
    ) -> Result<(), DmisError> {
        let ax = match axis {
            RotAxis::XAxis => 0,
            RotAxis::YAxis => 1,
            RotAxis::ZAxis => 2,
        };
        let by = match by {
            RotateBy::Angle(a) => {
                let r = a * rad_per(self.angle);
                if !r.is_finite() {
                    return Err(self.sem(st.arg(1), "the angle is out of range"));
                }
                RotateTo::Angle(r)
            }
            RotateBy::Feature(l, d) => {
                let (k, _) = self.actual(l, st.arg(1))?;
                if !has_direction(self.ftype(k)) {
                    return Err(self.sem(st.arg(1), format!("ROTATE: a {} has no direction", self.ftype(k))));
                }
                let dk = match d {
                    AxisDir::XDir => 0,
                    AxisDir::YDir => 1,
                    AxisDir::ZDir => 2,
                };
                if dk == ax {
                    return Err(
                        self.sem(st.arg(2), format!("ROTATE/{axis}: {d} lies along the rotation axis"))
                    );
                }
                RotateTo::Feature(k, dk)
            }
        };
        if let Some(l) = label {
            self.csys.insert(l.key(), self.active_datums.clone());
        }
        self.push(Op::Rotate { name: label.map(|l| l.name.clone()), axis: ax, by }, st.pos);
        Ok(())
    }

    /// `RECALL`: a coordinate system defined or saved before.
    fn check_recall(&mut self, st: &Stmt, l: &Label) -> Result<(), DmisError> {
        match self.csys.get(&l.key()) {
            Some(d) => {
                self.active_datums = d.clone();
                self.push(Op::Recall(l.name.clone()), st.pos);
                Ok(())
            }
            None => Err(self.sem(
                st.arg(0),
                format!(
                    "the coordinate system {} is neither defined (DATSET, TRANS, ROTATE) nor saved \
                     (SAVE) before this statement",
                    l.name
                ),
            )),
        }
    }

    /// `T(l)=TOL`: a new tolerance in internal units.
    fn check_tol(&mut self, st: &Stmt, label: &Label, tol: &Tol) -> Result<(), DmisError> {
        if let Some(k) = self.tols.get(&label.key()) {
            return Err(self.sem(
                st.label_pos,
                format!("{label} is already defined at line {}", self.plan.tolerances[*k].pos.line),
            ));
        }
        let kind = tolerance(self, tol, st)?;
        self.tols.insert(label.key(), self.plan.tolerances.len());
        self.plan.tolerances.push(Tolerance {
            name: label.name.clone(),
            kind,
            statement: st.statement.clone(),
            pos: st.pos,
        });
        Ok(())
    }

    /// `TEXT`: a message (operator input refused).
    fn check_text(&mut self, st: &Stmt, kind: TextKind, text: &str) -> Result<(), DmisError> {
        if kind == TextKind::Query {
            return Err(self.err(
                st.arg(0),
                ErrorKind::Unsupported,
                "TEXT/QUERY (operator input) is not supported",
            ));
        }
        self.push(Op::Text { kind, text: text.to_string() }, st.pos);
        Ok(())
    }

    /// `OPEN`: a device defined before; a storage device opened for output is the output file.
    fn check_open(&mut self, st: &Stmt, device: &Label, words: &[String]) -> Result<(), DmisError> {
        let Some(d) = self.devices.get(&device.key()).cloned() else {
            return Err(
                self.sem(st.arg(0), format!("{device} is not defined (DEVICE) before this statement"))
            );
        };
        if words.iter().any(|w| w == "OUTPUT") && d.0 == DeviceKind::Stor {
            match &d.1 {
                Some(f) if !is_plain_file_name(f) => {
                    return Err(self.err(
                        st.arg(0),
                        ErrorKind::Unsupported,
                        format!(
                            "{device} names '{f}', not a plain file name: the output file goes beside the program (a name without a folder; --output writes elsewhere)"
                        ),
                    ))
                }
                Some(f) if self.plan.output_file.is_none() => self.plan.output_file = Some(f.clone()),
                Some(_) => {
                    return Err(self.err(
                        st.arg(0),
                        ErrorKind::Unsupported,
                        "a second output file: truepos writes one output file",
                    ))
                }
                None => return Err(self.sem(st.arg(0), format!("{device} names no file"))),
            }
        }
        self.devices.insert(device.key(), (d.0, d.1, true));
        Ok(())
    }

    /// `CLOSE`: a device that is open.
    fn check_close(&self, st: &Stmt, device: &Label) -> Result<(), DmisError> {
        match self.devices.get(&device.key()) {
            Some((_, _, true)) => Ok(()),
            Some(_) => Err(self.sem(st.arg(0), format!("{device} is not open"))),
            None => {
                Err(self.sem(st.arg(0), format!("{device} is not defined (DEVICE) before this statement")))
            }
        }
    }
}

fn nominal(c: &Checker, g: &FeatGeom, st: &Stmt) -> Result<(Option<Side>, Nominal), DmisError> {
    // Argument indices: 0 type, then (side), CART, numbers.
    let a = |k: usize| st.arg(k);
    Ok(match g {
        FeatGeom::Point { p, n } => {
            (None, Nominal::Point { p: c.finite_pt(p, st, 2)?, n: c.unit(n, a(5), "the normal")? })
        }
        FeatGeom::Plane { p, n } => {
            (None, Nominal::Plane { p: c.finite_pt(p, st, 2)?, n: c.unit(n, a(5), "the normal")? })
        }
        FeatGeom::LineUnbnd { p, dir, plane } => (
            None,
            Nominal::Line {
                p: c.finite_pt(p, st, 3)?,
                dir: c.unit(dir, a(6), "the direction")?,
                plane: plane.as_ref().map(|v| c.unit(v, a(9), "the plane normal")).transpose()?,
                length: None,
            },
        ),
        FeatGeom::LineBnd { p1, p2, plane } => {
            let q1 = c.finite_pt(p1, st, 3)?;
            let q2 = c.finite_pt(p2, st, 6)?;
            let d = q2 - q1;
            if d.norm() < 1e-9 {
                return Err(c.sem(a(6), "the bounded line's end points coincide"));
            }
            (
                None,
                Nominal::Line {
                    p: q1,
                    dir: d / d.norm(),
                    plane: plane.as_ref().map(|v| c.unit(v, a(9), "the plane normal")).transpose()?,
                    length: Some(d.norm()),
                },
            )
        }
        FeatGeom::Circle { side, c: cc, n, diam } => (
            Some(*side),
            Nominal::Circle {
                c: c.finite_pt(cc, st, 3)?,
                n: c.unit(n, a(6), "the normal")?,
                r: c.len(c.positive(*diam, a(9), "the diameter")?) / 2.0,
            },
        ),
        FeatGeom::Cylndr { side, p, axis, diam, length } => (
            Some(*side),
            Nominal::Cylinder {
                p: c.finite_pt(p, st, 3)?,
                axis: c.unit(axis, a(6), "the axis")?,
                r: c.len(c.positive(*diam, a(9), "the diameter")?) / 2.0,
                length: length.map(|l| c.positive(l, a(10), "the length").map(|l| c.len(l))).transpose()?,
            },
        ),
        FeatGeom::Sphere { side, c: cc, n, diam } => {
            let dk = if n.is_some() { 9 } else { 6 };
            if let Some(n) = n {
                c.unit(n, a(6), "the direction")?;
            }
            (
                Some(*side),
                Nominal::Sphere {
                    c: c.finite_pt(cc, st, 3)?,
                    r: c.len(c.positive(*diam, a(dk), "the diameter")?) / 2.0,
                },
            )
        }
        FeatGeom::Cone { side, apex, axis, angle } => {
            let full = angle * rad_per(c.angle);
            if !(full > 0.0 && full < std::f64::consts::PI) {
                return Err(c.sem(
                    a(9),
                    format!("the cone's included angle must be between 0 and 180°, not {angle}"),
                ));
            }
            (
                Some(*side),
                Nominal::Cone {
                    apex: c.finite_pt(apex, st, 3)?,
                    axis: c.unit(axis, a(6), "the axis")?,
                    half_angle: full / 2.0,
                },
            )
        }
    })
}

fn construction(
    c: &Checker,
    t: FeatType,
    m: &ConstMethod,
    st: &Stmt,
) -> Result<(Construction, bool), DmisError> {
    let bad = |pos: Pos, what: String| {
        c.err(pos, ErrorKind::Unsupported, format!("CONST/{t},…,{what} is not supported"))
    };
    Ok(match m {
        ConstMethod::Bf(ls) => {
            let need = match t {
                FeatType::Line => 2,
                FeatType::Plane | FeatType::Circle => 3,
                FeatType::Sphere => 4,
                _ => return Err(bad(st.arg(2), "BF".into())),
            };
            let mut ks = Vec::new();
            for (j, l) in ls.iter().enumerate() {
                let (k, _) = c.actual(l, st.arg(3 + j))?;
                if !point_like(c.ftype(k)) {
                    return Err(c.sem(
                        st.arg(3 + j),
                        format!(
                            "BF takes the positions of points, circles and spheres, not of a {}",
                            c.ftype(k)
                        ),
                    ));
                }
                ks.push(k);
            }
            if ks.len() < need {
                return Err(c.sem(
                    st.arg(2),
                    format!("a best-fit {t} needs at least {need} features, not {}", ks.len()),
                ));
            }
            (Construction::Bf(ks), true)
        }
        ConstMethod::Intof(a, b) | ConstMethod::Projct(a, b) | ConstMethod::Midpt(a, b) => {
            let (ka, _) = c.actual(a, st.arg(3))?;
            let (kb, _) = c.actual(b, st.arg(4))?;
            let (ta, tb) = (c.ftype(ka), c.ftype(kb));
            use FeatType as F;
            let (word, ok) = match m {
                ConstMethod::Intof(..) => (
                    "INTOF",
                    match t {
                        F::Point => matches!(
                            (ta, tb),
                            (F::Line, F::Line)
                                | (F::Line, F::Plane)
                                | (F::Plane, F::Line)
                                | (F::Cylndr, F::Plane)
                                | (F::Plane, F::Cylndr)
                        ),
                        F::Line => (ta, tb) == (F::Plane, F::Plane),
                        _ => false,
                    },
                ),
                ConstMethod::Projct(..) => (
                    "PROJCT",
                    tb == F::Plane
                        && match t {
                            F::Point => point_like(ta) || ta == F::Cylndr,
                            F::Circle => ta == F::Circle,
                            F::Line => ta == F::Line,
                            _ => false,
                        },
                ),
                _ => ("MIDPT", t == F::Point && point_like(ta) && point_like(tb)),
            };
            if !ok {
                return Err(bad(st.arg(2), format!("{word},{ta},{tb}")));
            }
            let m = match m {
                ConstMethod::Intof(..) => Construction::Intof(ka, kb),
                ConstMethod::Projct(..) => Construction::Projct(ka, kb),
                _ => Construction::Midpt(ka, kb),
            };
            (m, false)
        }
    })
}

fn tolerance(c: &Checker, t: &Tol, st: &Stmt) -> Result<TolKind, DmisError> {
    let zone = |v: f64, k: usize| c.positive(v, st.arg(k), "the tolerance zone").map(|v| c.len(v));
    let range = |lo: f64, hi: f64, k: usize, f: f64| -> Result<(f64, f64), DmisError> {
        if lo > hi || lo.is_nan() || hi.is_nan() {
            return Err(c.sem(st.arg(k), format!("the lower deviation {lo} is above the upper {hi}")));
        }
        Ok((lo * f, hi * f))
    };
    let lf = mm_per(c.length);
    Ok(match t {
        Tol::Flat(v) => TolKind::Flat(zone(*v, 1)?),
        Tol::Strght(v) => TolKind::Strght(zone(*v, 1)?),
        Tol::Cirlty(v) => TolKind::Cirlty(zone(*v, 1)?),
        Tol::Cylcty(v) => TolKind::Cylcty(zone(*v, 1)?),
        Tol::Diam { lo, hi } => {
            let (lo, hi) = range(*lo, *hi, 1, lf)?;
            TolKind::Diam { lo, hi }
        }
        Tol::Rad { lo, hi } => {
            let (lo, hi) = range(*lo, *hi, 1, lf)?;
            TolKind::Rad { lo, hi }
        }
        Tol::Pos { three_d, zone: z, cond, datums } => {
            if *cond != MatCond::Rfs {
                return Err(c.err(
                    st.arg(3),
                    ErrorKind::Unsupported,
                    format!("TOL/POS with {cond} (bonus tolerance) is not supported: RFS only"),
                ));
            }
            for (j, d) in datums.iter().enumerate() {
                c.datum(d, st.arg(4 + j))?;
            }
            TolKind::Pos { three_d: *three_d, zone: zone(*z, 2)? }
        }
        Tol::Perp { zone: z, datum } | Tol::Parlel { zone: z, datum } => {
            let k = c.datum(datum, st.arg(2))?;
            if !has_direction(c.ftype(k)) {
                return Err(
                    c.sem(st.arg(2), format!("the datum is a {}, which has no direction", c.ftype(k)))
                );
            }
            let zone = zone(*z, 1)?;
            if matches!(t, Tol::Perp { .. }) {
                TolKind::Perp { zone, datum: k }
            } else {
                TolKind::Parlel { zone, datum: k }
            }
        }
        Tol::Anglb { angle, lo, hi } => {
            let f = rad_per(c.angle);
            let (lo, hi) = range(*lo, *hi, 2, f)?;
            TolKind::Anglb { angle: angle * f, lo, hi }
        }
        Tol::Distb { dist, lo, hi, axis } => {
            let (lo, hi) = range(*lo, *hi, 3, lf)?;
            TolKind::Distb { dist: c.len(*dist), lo, hi, axis: *axis }
        }
    })
}

fn output(c: &Checker, ls: &[Label], st: &Stmt) -> Result<Vec<OutputItem>, DmisError> {
    let mut items = Vec::new();
    let mut feats: Vec<(usize, bool, bool)> = Vec::new();
    let mut j = 0;
    while j < ls.len() && matches!(ls[j].kind, LabelKind::Fa | LabelKind::F) {
        let l = &ls[j];
        let pos = st.arg(j);
        if l.kind == LabelKind::Fa {
            let (k, points) = c.actual(l, pos)?;
            feats.push((k, true, points));
            items.push(OutputItem::Feature { feature: k, actual: true });
        } else {
            let (k, _) = c.feature(l, pos)?;
            feats.push((k, false, false));
            items.push(OutputItem::Feature { feature: k, actual: false });
        }
        j += 1;
    }
    for (jj, l) in ls.iter().enumerate().skip(j) {
        let pos = st.arg(jj);
        if matches!(l.kind, LabelKind::Fa | LabelKind::F) {
            return Err(c.sem(pos, "OUTPUT lists features first, then tolerances"));
        }
        let Some(&k) = c.tols.get(&l.key()) else {
            return Err(c.sem(
                pos,
                format!("the tolerance T({}) is not defined (TOL) before this statement", l.name),
            ));
        };
        if l.kind == LabelKind::T {
            items.push(OutputItem::Tolerance { tolerance: k, features: vec![], actual: false });
            continue;
        }
        let tol = &c.plan.tolerances[k];
        let need = tol.kind.n_features();
        if feats.len() != need {
            return Err(c.sem(
                pos,
                format!(
                    "TA({}) ({}) applies to {need} feature(s), this OUTPUT lists {}",
                    l.name,
                    tol.statement_word(),
                    feats.len()
                ),
            ));
        }
        for (fi, (f, actual, points)) in feats.iter().enumerate() {
            let t = c.ftype(*f);
            let fpos = st.arg(fi);
            if !actual {
                return Err(
                    c.sem(fpos, format!("TA({}) is evaluated on actual features: FA(…), not F(…)", l.name))
                );
            }
            if !applies_to(&tol.kind, t) {
                return Err(c.sem(
                    fpos,
                    format!("TA({}) ({}) does not apply to a {t}", l.name, tol.statement_word()),
                ));
            }
            let form = matches!(
                tol.kind,
                TolKind::Flat(_)
                    | TolKind::Strght(_)
                    | TolKind::Cirlty(_)
                    | TolKind::Cylcty(_)
                    | TolKind::Perp { .. }
                    | TolKind::Parlel { .. }
            );
            if form && !points {
                return Err(c.sem(
                    fpos,
                    format!(
                        "TA({}) needs measured points, and this feature was constructed without any",
                        l.name
                    ),
                ));
            }
        }
        pos_datums_active(c, l, tol, pos)?;
        items.push(OutputItem::Tolerance {
            tolerance: k,
            features: feats.iter().map(|f| f.0).collect(),
            actual: true,
        });
    }
    Ok(items)
}

/// Whether a tolerance of `kind` applies to a feature of type `t`.
fn applies_to(kind: &TolKind, t: FeatType) -> bool {
    use FeatType as F;
    match kind {
        TolKind::Flat(_) => t == F::Plane,
        TolKind::Strght(_) => t == F::Line,
        TolKind::Cirlty(_) => t == F::Circle,
        TolKind::Cylcty(_) => t == F::Cylndr,
        TolKind::Diam { .. } | TolKind::Rad { .. } => matches!(t, F::Circle | F::Cylndr | F::Sphere),
        TolKind::Pos { three_d, .. } => {
            matches!(t, F::Point | F::Circle | F::Cylndr) || (*three_d && t == F::Sphere)
        }
        TolKind::Perp { .. } | TolKind::Parlel { .. } => {
            matches!(t, F::Plane | F::Line | F::Cylndr | F::Cone)
        }
        TolKind::Anglb { .. } => has_direction(t),
        TolKind::Distb { .. } => point_like(t) || matches!(t, F::Plane | F::Cylndr),
    }
}

/// `TA(l)` of a `POS` that names datums (`OUTPUT` at `pos`): the active coordinate system must
/// have been set from those datums, first and in order.
fn pos_datums_active(c: &Checker, l: &Label, tol: &Tolerance, pos: Pos) -> Result<(), DmisError> {
    if let (TolKind::Pos { .. }, Statement::Tol { tol: Tol::Pos { datums, .. }, .. }) =
        (&tol.kind, &tol.statement)
    {
        if !datums.is_empty() {
            let want: Vec<usize> = datums.iter().filter_map(|d| c.datum(d, pos).ok()).collect();
            let active = c.active_datums.clone().unwrap_or_default();
            if active.len() < want.len() || active[..want.len()] != want[..] {
                return Err(c.sem(
                    pos,
                    format!(
                        "TA({}) refers to datums that the active coordinate system was not set from \
                         (DATSET with those datums first): position is reported in the active \
                         coordinate system",
                        l.name
                    ),
                ));
            }
        }
    }
    Ok(())
}

impl Tolerance {
    /// The tolerance kind's DMIS word (`FLAT`, `POS`, …).
    pub fn statement_word(&self) -> &'static str {
        match &self.statement {
            Statement::Tol { tol, .. } => tol.word(),
            _ => "TOL",
        }
    }
}

/// A file name with no folder in it (no `/` or `\\`, not `.` or `..`, not empty): what a
/// `DEVICE/STOR` output may name, so that the results stay beside the program.
fn is_plain_file_name(f: &str) -> bool {
    let f = f.trim();
    !f.is_empty() && f != "." && f != ".." && !f.contains(['/', '\\']) && !f.contains('\0')
}
