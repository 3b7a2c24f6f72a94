//! The executor: a checked [`Plan`] run on any [`ProbingMachine`].
//!
//! Coordinates: the plan's numbers are part coordinates of the coordinate system active at each
//! step ([`Frame`]: `p_machine = o + R·p_part`); `DATSET`, `TRANS`, `ROTATE`, `RECALL` change it.
//! Nominal features take the frame active at their `FEAT`; actual features are kept in the
//! machine frame and reported in the frame active at their `OUTPUT`.
//!
//! Probing: each `PTMEAS` is one [`ProbeRequest`] (approach, search and retract distances of
//! `SNSET`, the measuring feed of `FEDRAT/MESVEL`), with the tip radius the machine reports for
//! the selected tool; the contact point is the reported tip centre minus the radius along the
//! reported surface normal (the approach direction when the machine reports none), unless
//! `PRCOMP/OFF`. A `PTMEAS` without direction takes the nominal feature's surface normal at the
//! point. After `ENDMES` the feature is the least-squares fit of its points (circles in the
//! plane of their nominal, directions signed like the nominal); form tolerances are minimum zone.
//!
//! Failures: a probing without contact or any controller error stops the run with
//! [`RunError::Device`] naming the program line; the machine is stopped and moved back to where
//! the failed probing started (best effort). A sensor the machine has no tool for is refused
//! before the first motion ([`RunError::Input`]).
//!
//! Entry points: [`run`], [`DryRun`] (a machine that moves nowhere and touches every nominal
//! point: `--dry-run`).

use crate::ast::{
    AngleUnit, DatsetWord, DistAxis, FeatType, FeedKind, LengthUnit, Side, Statement, TextKind, Tol,
};
use crate::error::{DmisError, ErrorKind, Pos};
use crate::model::*;
use std::collections::HashMap;
use std::time::Instant;
use thiserror::Error;
use truepos_device::{DeviceError, DeviceInfo, ProbeHit, ProbeRequest, ProbingMachine, ToolInfo};
use truepos_fit::minzone::{self, Criterion};
use truepos_math::{Matrix3, Point3, Vector3};

/// Why a run stopped.
#[derive(Debug, Error)]
pub enum RunError {
    /// The program cannot run on this machine (a sensor without a tool): nothing moved (exit 2).
    #[error(transparent)]
    Input(#[from] DmisError),
    /// The machine failed at a program line (exit 3).
    #[error("{file}:{line}: {source}")]
    Device {
        /// The program's file name.
        file: String,
        /// 1-based program line.
        line: u32,
        /// What the machine said.
        #[source]
        source: DeviceError,
    },
    /// The measured points do not define the feature (collinear points for a circle, …) (exit 3).
    #[error("{file}:{line}: {message}")]
    Evaluation {
        /// The program's file name.
        file: String,
        /// 1-based program line.
        line: u32,
        /// What is wrong.
        message: String,
    },
}

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// DMIS sensor name (upper-case) → the machine's tool name (`--sensor PROBE6=Probe1`).
    pub sensors: HashMap<String, String>,
}

/// A coordinate system: part axes (columns of `r`) and origin `o` in the machine frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Rotation: the part axes as columns, in machine coordinates.
    pub r: Matrix3,
    /// The part origin in machine coordinates, mm.
    pub o: Vector3,
}

impl Frame {
    /// The machine coordinate system itself.
    pub fn machine() -> Frame {
        Frame { r: Matrix3::identity(), o: Vector3::zeros() }
    }
    /// A point from part to machine coordinates, mm.
    pub fn to_machine(&self, p: &Point3) -> Point3 {
        Point3::from(self.o + self.r * p.coords)
    }
    /// A direction from part to machine coordinates.
    pub fn dir_to_machine(&self, v: &Vector3) -> Vector3 {
        self.r * v
    }
    /// A point from machine to part coordinates, mm.
    pub fn to_part(&self, p: &Point3) -> Point3 {
        Point3::from(self.r.transpose() * (p.coords - self.o))
    }
    /// A direction from machine to part coordinates.
    pub fn dir_to_part(&self, v: &Vector3) -> Vector3 {
        self.r.transpose() * v
    }
    fn axis(&self, k: usize) -> Vector3 {
        self.r.column(k).into_owned()
    }
}

/// A feature's geometry in the machine frame (mm, rad).
#[derive(Debug, Clone, PartialEq)]
pub enum Geom {
    /// A point on a surface.
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
        /// A point of the line, mm.
        p: Point3,
        /// The unit direction.
        dir: Vector3,
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
    },
    /// A sphere.
    Sphere {
        /// The centre, mm.
        c: Point3,
        /// The radius, mm.
        r: f64,
    },
    /// A cone.
    Cone {
        /// The apex, mm.
        apex: Point3,
        /// The unit axis, from the apex into the cone.
        axis: Vector3,
        /// Half the included angle, rad.
        half_angle: f64,
    },
}

impl Geom {
    /// The location of the feature (point, centre, axis point, apex, plane point).
    pub fn position(&self) -> Point3 {
        match self {
            Geom::Point { p, .. }
            | Geom::Plane { p, .. }
            | Geom::Line { p, .. }
            | Geom::Cylinder { p, .. } => *p,
            Geom::Circle { c, .. } | Geom::Sphere { c, .. } => *c,
            Geom::Cone { apex, .. } => *apex,
        }
    }
    /// The direction (normal or axis), if the feature has one.
    pub fn direction(&self) -> Option<Vector3> {
        match self {
            Geom::Point { n, .. } | Geom::Plane { n, .. } | Geom::Circle { n, .. } => Some(*n),
            Geom::Line { dir, .. } => Some(*dir),
            Geom::Cylinder { axis, .. } | Geom::Cone { axis, .. } => Some(*axis),
            Geom::Sphere { .. } => None,
        }
    }
    /// The point of the feature's surface nearest `q` (a point and a line: `q` moved onto the
    /// plane through the point / onto the line).
    pub fn project(&self, q: &Point3) -> Point3 {
        let radial = |c: &Point3, axis: &Vector3, r: f64| {
            let v = q - c;
            let along = axis * v.dot(axis);
            let rad = v - along;
            match rad.try_normalize(1e-12) {
                Some(u) => c + along + u * r,
                None => *q,
            }
        };
        match self {
            Geom::Point { p, n } | Geom::Plane { p, n } => q - n * (q - p).dot(n),
            Geom::Line { p, dir } => p + dir * (q - p).dot(dir),
            Geom::Circle { c, n, r } => radial(c, n, *r),
            Geom::Cylinder { p, axis, r } => radial(p, axis, *r),
            Geom::Sphere { c, r } => match (q - c).try_normalize(1e-12) {
                Some(u) => c + u * *r,
                None => *q,
            },
            Geom::Cone { apex, axis, half_angle } => {
                let v = q - apex;
                let rad = v - axis * v.dot(axis);
                match rad.try_normalize(1e-12) {
                    Some(u) => {
                        let g = axis * half_angle.cos() + u * half_angle.sin();
                        apex + g * v.dot(&g).max(0.0)
                    }
                    None => *q,
                }
            }
        }
    }
    /// Radius of round features.
    pub fn radius(&self) -> Option<f64> {
        match self {
            Geom::Circle { r, .. } | Geom::Cylinder { r, .. } | Geom::Sphere { r, .. } => Some(*r),
            _ => None,
        }
    }
    fn in_frame(nom: &Nominal, f: &Frame) -> Geom {
        let p = |q: &Point3| f.to_machine(q);
        let d = |v: &Vector3| f.dir_to_machine(v);
        match nom {
            Nominal::Point { p: q, n } => Geom::Point { p: p(q), n: d(n) },
            Nominal::Plane { p: q, n } => Geom::Plane { p: p(q), n: d(n) },
            Nominal::Line { p: q, dir, .. } => Geom::Line { p: p(q), dir: d(dir) },
            Nominal::Circle { c, n, r } => Geom::Circle { c: p(c), n: d(n), r: *r },
            Nominal::Cylinder { p: q, axis, r, .. } => Geom::Cylinder { p: p(q), axis: d(axis), r: *r },
            Nominal::Sphere { c, r } => Geom::Sphere { c: p(c), r: *r },
            Nominal::Cone { apex, axis, half_angle } => {
                Geom::Cone { apex: p(apex), axis: d(axis), half_angle: *half_angle }
            }
        }
    }
    /// The surface normal (out of the material) of a nominal feature at a point near it.
    fn normal_at(&self, q: &Point3, side: Option<Side>) -> Option<Vector3> {
        let out = if side == Some(Side::Inner) { -1.0 } else { 1.0 };
        let radial = |c: &Point3, axis: &Vector3| {
            let v = q - c;
            let v = v - axis * v.dot(axis);
            (v.norm() > 1e-9).then(|| v / v.norm() * out)
        };
        match self {
            Geom::Point { n, .. } | Geom::Plane { n, .. } => Some(*n),
            Geom::Line { .. } => None,
            Geom::Circle { c, n, .. } => radial(c, n),
            Geom::Cylinder { p, axis, .. } => radial(p, axis),
            Geom::Sphere { c, .. } => {
                let v = q - c;
                (v.norm() > 1e-9).then(|| v / v.norm() * out)
            }
            Geom::Cone { apex, axis, half_angle } => {
                let v = q - apex;
                let radial = v - axis * v.dot(axis);
                if radial.norm() < 1e-9 {
                    return None;
                }
                let n = radial / radial.norm() * half_angle.cos() - axis * half_angle.sin();
                Some(n * out)
            }
        }
    }
}

/// An actual feature: geometry (machine frame), its surface points and standard uncertainties.
#[derive(Debug, Clone, PartialEq)]
pub struct Actual {
    /// The fitted geometry, machine frame.
    pub geom: Geom,
    /// The compensated surface points, machine frame, mm.
    pub points: Vec<Point3>,
    /// Standard uncertainty of the position (mm), where a fit gives it.
    pub u_position_mm: Option<f64>,
    /// Standard uncertainty of the diameter (mm), for round features.
    pub u_diameter_mm: Option<f64>,
}

/// One output feature.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureResult {
    /// The feature's label name.
    pub label: String,
    /// The feature type.
    pub ftype: FeatType,
    /// Inner or outer, for features that have a side.
    pub side: Option<Side>,
    /// In the coordinate system active at the OUTPUT (mm, rad).
    pub geom: Geom,
    /// Standard uncertainty of the position, mm, where known.
    pub u_position_mm: Option<f64>,
    /// Standard uncertainty of the diameter, mm, for round features.
    pub u_diameter_mm: Option<f64>,
    /// Number of points measured (0 for a constructed feature).
    pub n_points: usize,
    /// Whether measured or constructed (`FA`) rather than only nominal.
    pub actual: bool,
}

/// One evaluated tolerance.
#[derive(Debug, Clone, PartialEq)]
pub struct TolResult {
    /// The tolerance's label name.
    pub label: String,
    /// The labels of the features it applies to.
    pub features: Vec<String>,
    /// The tolerance's minor word (`DIAM`, `POS`, ...).
    pub kind: &'static str,
    /// The actual value: mm, or rad for ANGLB.
    pub value: f64,
    /// The limits the value is judged against (mm, or rad for ANGLB).
    pub limits: (f64, f64),
    /// Whether the value and limits are angles (rad) rather than lengths (mm).
    pub angular: bool,
    /// Whether the value is within the limits.
    pub in_tolerance: bool,
    /// For a value that is the length of a vector (POS: twice the position deviation; PERP and
    /// PARLEL of an axis: its extent across or along the datum), that vector (machine frame,
    /// mm): a simulation judges the vector, whose truth may be zero, not its length.
    pub vector: Option<Vector3>,
    /// The nominal the limits are taken about (mm, or rad for ANGLB): DIAM the nominal
    /// diameter, RAD the nominal radius, DISTB the nominal distance, ANGLB the nominal angle.
    /// `None` for form, position and orientation tolerances (their nominal is zero).
    pub nominal: Option<f64>,
    /// The datums named by the tolerance in order of precedence (POS, PERP, PARLEL), as written
    /// in the program (`A` for `DAT(A)`, the feature's name for `FA(x)`).
    pub datums: Vec<String>,
    /// Indices into [`RunResult::features`] of the actual features of the same `OUTPUT` the
    /// tolerance was evaluated on, in the order of [`TolResult::features`].
    pub feature_results: Vec<usize>,
    /// `POS,3D` (a spherical zone about the nominal point); false for every other tolerance.
    pub three_d: bool,
    /// `DISTB` along an axis of the current coordinate system (`XAXIS` 0, `YAXIS` 1, `ZAXIS`
    /// 2); `None` for every other tolerance and for `DISTB` without one (`PT2PT`).
    pub distb_axis: Option<usize>,
}

/// One probing of a run: which feature, the compensated contact point and the probing
/// direction (machine frame), and where the perfect feature (the fit) has that point.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeRecord {
    /// Index of the feature probed (in the plan's features).
    pub feature: usize,
    /// The compensated contact point, machine frame, mm.
    pub point_mm: Point3,
    /// The unit probing direction, machine frame.
    pub approach: Vector3,
    /// The point moved onto the fitted feature (its form error removed): what a perfect part
    /// placed where this one was found would give.
    pub perfect_mm: Point3,
}

/// What a run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// The machine the program ran on.
    pub machine: DeviceInfo,
    /// The features output by `OUTPUT`, in order.
    pub features: Vec<FeatureResult>,
    /// The tolerances output by `OUTPUT`, in order.
    pub tolerances: Vec<TolResult>,
    /// Number of points probed.
    pub n_points: usize,
    /// Wall time of the run, s.
    pub elapsed_s: f64,
    /// The DMIS output file, line by line.
    pub output: Vec<String>,
    /// Motions in order (what `--dry-run` lists).
    pub motions: Vec<String>,
    /// Every probing in order ([`Replay`](crate::uncertainty::Replay) runs the plan again on the
    /// perfect features).
    pub probes: Vec<ProbeRecord>,
    /// The tools selected (name, tip radius mm), as the machine reported them.
    pub tools: Vec<ToolInfo>,
}

impl RunResult {
    /// Any tolerance out (exit 1).
    pub fn any_out_of_tolerance(&self) -> bool {
        self.tolerances.iter().any(|t| !t.in_tolerance)
    }
}

struct Exec<'a> {
    plan: &'a Plan,
    frame: Frame,
    saved: HashMap<String, Frame>,
    nominal: Vec<Option<Geom>>,
    /// The frame each nominal was defined in.
    def_frame: Vec<Option<Frame>>,
    actual: Vec<Option<Actual>>,
    tip_radius: Option<f64>,
    approach: f64,
    search: f64,
    retract: f64,
    feed: f64,
    compensate: bool,
    length: LengthUnit,
    angle: AngleUnit,
    out: Vec<String>,
    motions: Vec<String>,
    features: Vec<FeatureResult>,
    tolerances: Vec<TolResult>,
    n_points: usize,
    /// Where the tip centre was last sent (machine frame), if known.
    at: Option<Point3>,
    probes: Vec<ProbeRecord>,
    tools: Vec<ToolInfo>,
}

fn fmt_xyz(p: &Point3) -> String {
    format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z)
}

/// Run `plan` on `machine`. `progress` gets one line per `MEAS` (and the texts of `TEXT/OPER`).
pub fn run(
    plan: &Plan,
    machine: &mut dyn ProbingMachine,
    opts: &RunOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<RunResult, RunError> {
    let t0 = Instant::now();
    let tool_of = tools_of_sensors(plan, machine, opts)?;
    let mut ex = Exec::new(plan);
    ex.out.push(format!(
        "FILNAM/'{}'",
        plan.filnam.clone().unwrap_or_else(|| plan.title.clone()).replace('\'', "''")
    ));
    for step in &plan.steps {
        ex.step(machine, step, &tool_of, progress)?;
    }
    ex.out.push("ENDFIL".into());
    Ok(RunResult {
        machine: machine.info(),
        features: ex.features,
        tolerances: ex.tolerances,
        n_points: ex.n_points,
        elapsed_s: t0.elapsed().as_secs_f64(),
        output: ex.out,
        motions: ex.motions,
        probes: ex.probes,
        tools: ex.tools,
    })
}

/// The machine's tool for each sensor of the plan (by `--sensor`, else the sensor's name),
/// checked before any motion: a selected sensor needs a tool the machine lists, and every
/// `--sensor` must name a sensor of the program.
fn tools_of_sensors(
    plan: &Plan,
    machine: &mut dyn ProbingMachine,
    opts: &RunOptions,
) -> Result<Vec<String>, RunError> {
    let listed = machine.tool_names().map_err(|e| RunError::Device {
        file: plan.file.clone(),
        line: plan.steps.first().map_or(1, |s| s.pos.line),
        source: e,
    })?;
    let mut tool_of: Vec<String> = Vec::new();
    for s in &plan.sensors {
        let tool = opts.sensors.get(&s.name.to_ascii_uppercase()).cloned().unwrap_or_else(|| s.name.clone());
        let used = plan
            .steps
            .iter()
            .any(|st| matches!(st.op, Op::SelectSensor(k) if plan.sensors[k].name == s.name));
        if used && !listed.is_empty() && !listed.iter().any(|t| t == &tool) {
            return Err(RunError::Input(DmisError::new(
                &plan.file,
                s.pos,
                ErrorKind::Semantic,
                format!(
                    "the CMM has no tool {tool} for the sensor S({}) (its tools: {}); map it with --sensor {}=TOOL",
                    s.name,
                    listed.join(", "),
                    s.name
                ),
            )));
        }
        // I++ DME's `NoTool` is the empty tool (no probe mounted): listed, but it cannot
        // measure, and the server would only say so at the first PtMeas, after the moves.
        if used && tool.eq_ignore_ascii_case("NoTool") {
            return Err(RunError::Input(DmisError::new(
                &plan.file,
                s.pos,
                ErrorKind::Semantic,
                format!(
                    "the sensor S({}) is mapped to NoTool, I++ DME's empty tool (no probe mounted), which cannot measure; map it to a probe with --sensor {}=TOOL (the CMM's tools: {})",
                    s.name,
                    s.name,
                    listed.join(", ")
                ),
            )));
        }
        tool_of.push(tool);
    }
    for key in opts.sensors.keys() {
        if !plan.sensors.iter().any(|s| s.name.eq_ignore_ascii_case(key)) {
            return Err(RunError::Input(DmisError::new(
                &plan.file,
                Pos::new(1, 1),
                ErrorKind::Semantic,
                format!("--sensor {key}=…: the program defines no sensor S({key})"),
            )));
        }
    }
    Ok(tool_of)
}

/// The steps: one at a time, the motions, coordinate systems and settings they change.
impl<'a> Exec<'a> {
    /// An executor at the start of `plan`: machine coordinates, mm and degrees, the default
    /// probing distances and feed, compensation on.
    fn new(plan: &'a Plan) -> Exec<'a> {
        Exec {
            plan,
            frame: Frame::machine(),
            saved: HashMap::new(),
            nominal: vec![None; plan.features.len()],
            def_frame: vec![None; plan.features.len()],
            actual: vec![None; plan.features.len()],
            tip_radius: None,
            approach: 2.0,
            search: 4.0,
            retract: 2.0,
            feed: 5.0,
            compensate: true,
            length: LengthUnit::Mm,
            angle: AngleUnit::AngDec,
            out: Vec::new(),
            motions: Vec::new(),
            features: Vec::new(),
            tolerances: Vec::new(),
            n_points: 0,
            at: None,
            probes: Vec::new(),
            tools: Vec::new(),
        }
    }

    /// One step of the plan; `tool_of` names the machine's tool of each sensor.
    fn step(
        &mut self,
        machine: &mut dyn ProbingMachine,
        step: &Step,
        tool_of: &[String],
        progress: &mut dyn FnMut(&str),
    ) -> Result<(), RunError> {
        let plan = self.plan;
        let line = step.pos.line;
        let dev = |e: DeviceError| RunError::Device { file: plan.file.clone(), line, source: e };
        if let Some(e) = &step.echo {
            self.out.push(e.clone());
        }
        match &step.op {
            Op::Goto(p) => {
                let q = self.frame.to_machine(p);
                self.goto(machine, q).map_err(dev)?;
            }
            Op::GotoIncr(v) => self.goto_incr(machine, v).map_err(dev)?,
            Op::Feed { kind, mm_s } => match (kind, mm_s) {
                (FeedKind::MesVel, Some(v)) => self.feed = *v,
                (FeedKind::PosVel, Some(v)) => {
                    machine.set_move_speed(*v).map_err(dev)?;
                    self.motions.push(format!("line {line}: positioning speed {v} mm/s"));
                }
                _ => {}
            },
            Op::Approach(v) => self.approach = *v,
            Op::Search(v) => self.search = *v,
            Op::Retract(v) => self.retract = *v,
            Op::Compensation(on) => self.compensate = *on,
            Op::SelectSensor(k) => self.select_sensor(machine, &tool_of[*k], line).map_err(dev)?,
            Op::Define(k) => {
                self.nominal[*k] = Some(Geom::in_frame(&plan.features[*k].nominal, &self.frame));
                self.def_frame[*k] = Some(self.frame);
            }
            Op::Measure { feature, moves } => {
                let t = Instant::now();
                self.measure(machine, *feature, moves, step.pos)?;
                let f = &plan.features[*feature];
                progress(&format!(
                    "line {line}: MEAS/{},F({}): {} points in {:.2} s",
                    f.ftype,
                    f.name,
                    moves.iter().filter(|m| matches!(m.0, Move::Probe { .. })).count(),
                    t.elapsed().as_secs_f64()
                ));
            }
            Op::Construct { feature, method } => self.construct(*feature, method, line)?,
            Op::Datset { name, def } => {
                self.datset(def, line)?;
                self.save_frame(name);
            }
            Op::Trans { name, items } => self.trans(name.as_deref(), items),
            Op::Rotate { name, axis, by } => self.rotate(name.as_deref(), *axis, by, line)?,
            Op::Save(n) => self.save_frame(n),
            Op::Recall(n) => {
                if let Some(f) = self.saved.get(&n.to_ascii_uppercase()) {
                    self.frame = *f;
                }
            }
            Op::Units { length, angle } => {
                self.length = *length;
                self.angle = *angle;
            }
            Op::Output(items) => self.output(items, line)?,
            Op::Text { kind, text } => match kind {
                TextKind::Outfil => self.out.push(format!("TEXT/OUTFIL,'{}'", text.replace('\'', "''"))),
                _ => progress(&format!("line {line}: TEXT/{kind}: {text}")),
            },
        }
        Ok(())
    }

    /// `GOTO/INCR`: from where the tip was last sent (or where the machine says it is).
    fn goto_incr(&mut self, m: &mut dyn ProbingMachine, v: &Vector3) -> Result<(), DeviceError> {
        let from = match self.at {
            Some(a) => a,
            None => m.position()?,
        };
        let q = from + self.frame.dir_to_machine(v);
        self.goto(m, q)
    }

    /// `SNSLCT`: the machine's `tool`, its tip radius and where the tip is now unknown.
    fn select_sensor(
        &mut self,
        m: &mut dyn ProbingMachine,
        tool: &str,
        line: u32,
    ) -> Result<(), DeviceError> {
        let info = m.select_tool(tool)?;
        self.motions.push(format!("line {line}: tool {} (tip radius {} mm)", info.name, info.tip_radius_mm));
        self.tip_radius = Some(info.tip_radius_mm);
        self.at = None;
        if !self.tools.iter().any(|t| t.name == info.name) {
            self.tools.push(info);
        }
        Ok(())
    }

    /// Keeps the active coordinate system under `name` (for `RECALL`).
    fn save_frame(&mut self, name: &str) {
        self.saved.insert(name.to_ascii_uppercase(), self.frame);
    }

    /// `TRANS`: each origin moved along its axis to a value or a feature's position.
    fn trans(&mut self, name: Option<&str>, items: &[(usize, TransTo)]) {
        for (axis, to) in items {
            let e = self.frame.axis(*axis);
            let v = match to {
                TransTo::Value(v) => *v,
                TransTo::Feature(k) => e.dot(&(self.actual_geom(*k).position().coords - self.frame.o)),
            };
            self.frame.o += e * v;
        }
        if let Some(n) = name {
            self.save_frame(n);
        }
    }

    /// `ROTATE` about `axis` by an angle, or until a feature's direction is the target axis.
    fn rotate(&mut self, name: Option<&str>, axis: usize, by: &RotateTo, line: u32) -> Result<(), RunError> {
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        let (ei, ej, ek) = (self.frame.axis(i), self.frame.axis(j), self.frame.axis(axis));
        let theta = match by {
            RotateTo::Angle(a) => *a,
            RotateTo::Feature(k, target) => {
                let d = self.actual_geom(*k).direction().unwrap_or(ek);
                let (x, y) = (d.dot(&ei), d.dot(&ej));
                if x.hypot(y) < 1e-9 {
                    return Err(self.eval_err(
                        line,
                        format!(
                            "ROTATE: F({})'s direction lies along the rotation axis",
                            self.plan.features[*k].name
                        ),
                    ));
                }
                let phi = y.atan2(x);
                if *target == i {
                    phi
                } else {
                    phi - std::f64::consts::FRAC_PI_2
                }
            }
        };
        let (s, c) = theta.sin_cos();
        let ni = ei * c + ej * s;
        let nj = -ei * s + ej * c;
        self.frame.r.set_column(i, &ni);
        self.frame.r.set_column(j, &nj);
        if let Some(n) = name {
            self.save_frame(n);
        }
        Ok(())
    }
}

impl Exec<'_> {
    fn eval_err(&self, line: u32, m: impl Into<String>) -> RunError {
        RunError::Evaluation { file: self.plan.file.clone(), line, message: m.into() }
    }

    fn goto(&mut self, m: &mut dyn ProbingMachine, q: Point3) -> Result<(), DeviceError> {
        self.motions.push(format!("GOTO {}", fmt_xyz(&q)));
        m.move_to(q)?;
        self.at = Some(q);
        Ok(())
    }

    fn actual_geom(&self, k: usize) -> Geom {
        match &self.actual[k] {
            Some(a) => a.geom.clone(),
            // The checker guarantees actuals where they are used; the nominal is a safe stand-in.
            None => self.nominal[k].clone().unwrap_or(Geom::Point { p: Point3::origin(), n: Vector3::z() }),
        }
    }

    fn measure(
        &mut self,
        m: &mut dyn ProbingMachine,
        k: usize,
        moves: &[(Move, Pos)],
        mpos: Pos,
    ) -> Result<(), RunError> {
        let plan = self.plan;
        let feat = &plan.features[k];
        let nominal = self.nominal_geom(k);
        let r = self.tip_radius.unwrap_or(0.0);
        let mut points = Vec::new();
        let mut approaches = Vec::new();
        for (mv, pos) in moves {
            let line = pos.line;
            let dev = |e: DeviceError| RunError::Device { file: plan.file.clone(), line, source: e };
            match mv {
                Move::Goto(p) => {
                    let q = self.frame.to_machine(p);
                    self.goto(m, q).map_err(dev)?;
                }
                Move::GotoIncr(v) => self.goto_incr(m, v).map_err(dev)?,
                Move::Probe { p, dir } => {
                    let q = self.frame.to_machine(p);
                    let n = match dir {
                        Some(d) => self.frame.dir_to_machine(d),
                        None => nominal.normal_at(&q, feat.side).ok_or_else(|| {
                            self.eval_err(
                                line,
                                format!(
                                    "PTMEAS: no surface normal of F({}) at this point; give the direction",
                                    feat.name
                                ),
                            )
                        })?,
                    };
                    let req = ProbeRequest {
                        nominal_mm: q,
                        approach: n,
                        tip_radius_mm: r,
                        approach_mm: self.approach,
                        search_mm: self.search,
                        retract_mm: self.retract,
                        feed_mm_s: self.feed,
                    };
                    self.motions.push(format!(
                        "PTMEAS {} along ({:.4}, {:.4}, {:.4})",
                        fmt_xyz(&q),
                        n.x,
                        n.y,
                        n.z
                    ));
                    let hit = match m.probe(&req) {
                        Ok(h) => h,
                        Err(e) => {
                            if !matches!(e, DeviceError::NoContact { .. }) {
                                let _ = m.abort();
                                let _ = m.move_to(req.start_mm());
                            }
                            return Err(dev(e));
                        }
                    };
                    self.at = None;
                    let normal = hit.normal.filter(|v| v.norm() > 0.5).map(|v| v / v.norm()).unwrap_or(n);
                    let s = if self.compensate { hit.tip_center_mm - normal * r } else { hit.tip_center_mm };
                    points.push(s);
                    approaches.push(n);
                }
            }
        }
        self.n_points += points.len();
        let a = fit_feature(feat.ftype, &nominal, points)
            .map_err(|e| self.eval_err(mpos.line, format!("F({}): {e}", feat.name)))?;
        for (q, n) in a.points.iter().zip(approaches) {
            self.probes.push(ProbeRecord {
                feature: k,
                point_mm: *q,
                approach: n,
                perfect_mm: a.geom.project(q),
            });
        }
        self.actual[k] = Some(a);
        Ok(())
    }

    fn construct(&mut self, k: usize, method: &Construction, line: u32) -> Result<(), RunError> {
        let feat = &self.plan.features[k];
        let nominal = self.nominal_geom(k);
        let err = |m: String| RunError::Evaluation {
            file: self.plan.file.clone(),
            line,
            message: format!("CONST F({}): {m}", feat.name),
        };
        let a = match method {
            Construction::Bf(ks) => {
                let pts: Vec<Point3> = ks.iter().map(|k| self.actual_geom(*k).position()).collect();
                let mut a = fit_feature(feat.ftype, &nominal, pts).map_err(err)?;
                if let (Geom::Line { dir, .. }, Some(first), Some(last)) =
                    (&mut a.geom, ks.first(), ks.last())
                {
                    let along = self.actual_geom(*last).position() - self.actual_geom(*first).position();
                    if dir.dot(&along) < 0.0 {
                        *dir = -*dir;
                    }
                }
                a
            }
            Construction::Intof(x, y) => {
                let (gx, gy) = (self.actual_geom(*x), self.actual_geom(*y));
                let g = intersect(&gx, &gy)
                    .ok_or_else(|| err("the features do not intersect (parallel)".into()))?;
                Actual {
                    geom: orient_like(g, &nominal),
                    points: vec![],
                    u_position_mm: None,
                    u_diameter_mm: None,
                }
            }
            Construction::Projct(x, y) => {
                let (gx, gy) = (self.actual_geom(*x), self.actual_geom(*y));
                let Geom::Plane { p: pp, n: pn } = gy else { return Err(err("not onto a plane".into())) };
                let proj = |q: Point3| q - pn * (q - pp).dot(&pn);
                let g = match gx {
                    Geom::Circle { c, r, .. } => Geom::Circle { c: proj(c), n: pn, r },
                    Geom::Line { p, dir } => {
                        let d = dir - pn * dir.dot(&pn);
                        if d.norm() < 1e-9 {
                            return Err(err("the line is perpendicular to the plane".into()));
                        }
                        Geom::Line { p: proj(p), dir: d / d.norm() }
                    }
                    other => Geom::Point { p: proj(other.position()), n: pn },
                };
                Actual {
                    geom: orient_like(g, &nominal),
                    points: vec![],
                    u_position_mm: None,
                    u_diameter_mm: None,
                }
            }
            Construction::Midpt(x, y) => {
                let (px, py) = (self.actual_geom(*x).position(), self.actual_geom(*y).position());
                let n = nominal.direction().unwrap_or(Vector3::z());
                Actual {
                    geom: Geom::Point { p: Point3::from((px.coords + py.coords) / 2.0), n },
                    points: vec![],
                    u_position_mm: None,
                    u_diameter_mm: None,
                }
            }
        };
        self.actual[k] = Some(a);
        Ok(())
    }

    fn datset(&mut self, def: &DatsetOp, line: u32) -> Result<(), RunError> {
        let ds = match def {
            DatsetOp::Mcs => {
                self.frame = Frame::machine();
                return Ok(());
            }
            DatsetOp::Datums(ds) => ds,
        };
        let cur = self.frame;
        let mut dirs: Vec<(usize, Vector3)> = Vec::new();
        for (k, ws) in ds {
            for w in ws {
                let ax = match w {
                    DatsetWord::XDir => 0,
                    DatsetWord::YDir => 1,
                    DatsetWord::ZDir => 2,
                    _ => continue,
                };
                let d = self.actual_geom(*k).direction().unwrap_or(Vector3::z());
                dirs.push((ax, d / d.norm()));
            }
        }
        let mut r = cur.r;
        if !dirs.is_empty() {
            let (k1, v1) = dirs[0];
            let (k2, v2) = match dirs.get(1) {
                Some(&(k2, v)) => (k2, v),
                None => {
                    let k2 = (k1 + 1) % 3;
                    let c = cur.axis(k2);
                    if (c - v1 * c.dot(&v1)).norm() > 1e-6 {
                        (k2, c)
                    } else {
                        let k2 = (k1 + 2) % 3;
                        (k2, cur.axis(k2))
                    }
                }
            };
            let u2 = v2 - v1 * v2.dot(&v1);
            if u2.norm() < 1e-9 {
                return Err(self.eval_err(line, "DATSET: the two datum directions are parallel"));
            }
            let u2 = u2 / u2.norm();
            let k3 = 3 - k1 - k2;
            let mut e = [Vector3::zeros(); 3];
            e[k1] = v1;
            e[k2] = u2;
            e[k3] = e[(k3 + 1) % 3].cross(&e[(k3 + 2) % 3]);
            r = Matrix3::from_columns(&e);
        }
        let mut o = cur.o;
        for (k, ws) in ds {
            for w in ws {
                let ax = match w {
                    DatsetWord::XOrig => 0,
                    DatsetWord::YOrig => 1,
                    DatsetWord::ZOrig => 2,
                    _ => continue,
                };
                let e = r.column(ax).into_owned();
                let p = self.actual_geom(*k).position();
                o += e * e.dot(&(p.coords - o));
            }
        }
        self.frame = Frame { r, o };
        Ok(())
    }

    fn output(&mut self, items: &[OutputItem], line: u32) -> Result<(), RunError> {
        let plan = self.plan;
        let labels: Vec<String> = items
            .iter()
            .map(|it| match it {
                OutputItem::Feature { feature, actual } => {
                    format!("{}({})", if *actual { "FA" } else { "F" }, plan.features[*feature].name)
                }
                OutputItem::Tolerance { tolerance, actual, .. } => {
                    format!("{}({})", if *actual { "TA" } else { "T" }, plan.tolerances[*tolerance].name)
                }
            })
            .collect();
        self.out.push(format!("OUTPUT/{}", labels.join(",")));
        for it in items {
            match it {
                OutputItem::Feature { feature, actual } => {
                    let f = &plan.features[*feature];
                    let (g, a) = if *actual {
                        let a =
                            self.actual[*feature].clone().ok_or_else(|| self.eval_err(line, "no actual"))?;
                        (a.geom.clone(), Some(a))
                    } else {
                        (self.nominal_geom(*feature), None)
                    };
                    let part = self.to_part_geom(&g);
                    self.out.push(crate::report::feat_line(
                        &format!("{}({})", if *actual { "FA" } else { "F" }, f.name),
                        f,
                        &part,
                        self.length,
                        self.angle,
                    ));
                    self.features.push(FeatureResult {
                        label: f.name.clone(),
                        ftype: f.ftype,
                        side: f.side,
                        geom: part,
                        u_position_mm: a.as_ref().and_then(|a| a.u_position_mm),
                        u_diameter_mm: a.as_ref().and_then(|a| a.u_diameter_mm),
                        n_points: a.as_ref().map(|a| a.points.len()).unwrap_or(0),
                        actual: *actual,
                    });
                }
                OutputItem::Tolerance { tolerance, features, actual } => {
                    let t = &plan.tolerances[*tolerance];
                    self.out.push(t.statement.to_string());
                    if !*actual {
                        continue;
                    }
                    let r = self.evaluate(t, features, line)?;
                    self.out.push(crate::report::tol_line(&r, self.length, self.angle));
                    self.tolerances.push(r);
                }
            }
        }
        Ok(())
    }

    fn to_part_geom(&self, g: &Geom) -> Geom {
        let f = &self.frame;
        let p = |q: &Point3| f.to_part(q);
        let d = |v: &Vector3| f.dir_to_part(v);
        match g {
            Geom::Point { p: q, n } => Geom::Point { p: p(q), n: d(n) },
            Geom::Plane { p: q, n } => Geom::Plane { p: p(q), n: d(n) },
            Geom::Line { p: q, dir } => Geom::Line { p: p(q), dir: d(dir) },
            Geom::Circle { c, n, r } => Geom::Circle { c: p(c), n: d(n), r: *r },
            Geom::Cylinder { p: q, axis, r } => Geom::Cylinder { p: p(q), axis: d(axis), r: *r },
            Geom::Sphere { c, r } => Geom::Sphere { c: p(c), r: *r },
            Geom::Cone { apex, axis, half_angle } => {
                Geom::Cone { apex: p(apex), axis: d(axis), half_angle: *half_angle }
            }
        }
    }

    /// A tolerance evaluated on the actual features `fs`: its value, limits and verdict, with what
    /// the report and a simulation need besides.
    fn evaluate(&self, t: &Tolerance, fs: &[usize], line: u32) -> Result<TolResult, RunError> {
        let plan = self.plan;
        let names: Vec<String> = fs.iter().map(|k| plan.features[*k].name.clone()).collect();
        let within = |v: f64, z: f64| v <= z;
        let mut vector = None;
        let (value, limits, ok, angular) = match &t.kind {
            TolKind::Flat(z) | TolKind::Strght(z) | TolKind::Cirlty(z) | TolKind::Cylcty(z) => {
                let v = self.form_value(t, fs[0], line)?;
                (v, (0.0, *z), within(v, *z), false)
            }
            TolKind::Diam { lo, hi } | TolKind::Rad { lo, hi } => {
                let f = if matches!(t.kind, TolKind::Diam { .. }) { 2.0 } else { 1.0 };
                let ra = self.actual_at(fs[0], line)?.geom.radius().unwrap_or(0.0);
                let rn = self.nominal_geom(fs[0]).radius().unwrap_or(0.0);
                let v = f * (ra - rn);
                (v, (*lo, *hi), v >= *lo && v <= *hi, false)
            }
            TolKind::Pos { three_d, zone } => {
                let d = self.position_deviation(fs[0], *three_d, line)?;
                let v = 2.0 * d.norm();
                vector = Some(d * 2.0);
                (v, (0.0, *zone), within(v, *zone), false)
            }
            TolKind::Perp { zone, datum } | TolKind::Parlel { zone, datum } => {
                let (v, w) = self.orientation_value(t, fs[0], *datum, line)?;
                vector = w;
                (v, (0.0, *zone), within(v, *zone), false)
            }
            TolKind::Anglb { angle, lo, hi } => {
                let da = self.actual_at(fs[0], line)?.geom.direction().unwrap_or(Vector3::z());
                let db = self.actual_at(fs[1], line)?.geom.direction().unwrap_or(Vector3::z());
                let v = (da.dot(&db) / (da.norm() * db.norm())).clamp(-1.0, 1.0).acos();
                (v, (angle + lo, angle + hi), v >= angle + lo && v <= angle + hi, true)
            }
            TolKind::Distb { dist, lo, hi, axis } => {
                let v = self.distance_value(fs, *axis, line)?;
                (v, (dist + lo, dist + hi), v >= dist + lo && v <= dist + hi, false)
            }
        };
        let nominal = match &t.kind {
            TolKind::Diam { .. } => self.nominal_geom(fs[0]).radius().map(|r| 2.0 * r),
            TolKind::Rad { .. } => self.nominal_geom(fs[0]).radius(),
            TolKind::Anglb { angle, .. } => Some(*angle),
            TolKind::Distb { dist, .. } => Some(*dist),
            _ => None,
        };
        // The feature results of this OUTPUT: the latest actual output of each feature.
        let feature_results = names
            .iter()
            .filter_map(|n| self.features.iter().rposition(|f| f.actual && f.label == *n))
            .collect();
        Ok(TolResult {
            label: t.name.clone(),
            features: names,
            kind: t.statement_word(),
            value,
            limits,
            angular,
            in_tolerance: ok,
            vector,
            nominal,
            datums: tolerance_datums(t),
            feature_results,
            three_d: matches!(t.kind, TolKind::Pos { three_d: true, .. }),
            distb_axis: match &t.kind {
                TolKind::Distb { axis: Some(DistAxis::XAxis), .. } => Some(0),
                TolKind::Distb { axis: Some(DistAxis::YAxis), .. } => Some(1),
                TolKind::Distb { axis: Some(DistAxis::ZAxis), .. } => Some(2),
                _ => None,
            },
        })
    }

    /// The actual feature `k` (a copy), which the checker guarantees by the time it is used.
    fn actual_at(&self, k: usize, line: u32) -> Result<Actual, RunError> {
        self.actual[k].clone().ok_or_else(|| self.eval_err(line, "no actual"))
    }

    /// The nominal feature `k` in the machine frame (in the active frame if not defined yet).
    fn nominal_geom(&self, k: usize) -> Geom {
        self.nominal[k].clone().unwrap_or_else(|| Geom::in_frame(&self.plan.features[k].nominal, &self.frame))
    }

    /// The minimum-zone form error (FLAT, STRGHT, CIRLTY, CYLCTY) of the actual feature `k`, mm.
    fn form_value(&self, t: &Tolerance, k: usize, line: u32) -> Result<f64, RunError> {
        let fe = |e: truepos_fit::FitError| self.eval_err(line, format!("T({}): {e}", t.name));
        let act = self.actual_at(k, line)?;
        Ok(match &t.kind {
            TolKind::Flat(_) => minzone::plane_zone(&act.points).map_err(fe)?.form,
            TolKind::Strght(_) => {
                let pts = match &self.plan.features[k].nominal {
                    Nominal::Line { plane: Some(pn), .. } => {
                        let n = self.nominal_frame_dir(k, pn);
                        let c = act.geom.position();
                        act.points.iter().map(|q| q - n * (q - c).dot(&n)).collect()
                    }
                    _ => act.points.clone(),
                };
                if pts.len() < 3 {
                    0.0
                } else {
                    minzone::line_zone(&pts).map_err(fe)?.form
                }
            }
            TolKind::Cirlty(_) => minzone::circle_fit(&act.points, Criterion::MinimumZone).map_err(fe)?.form,
            // CYLCTY, from the feature's own fit (its nominal axis chose the cylinder): the points
            // alone may fit another cylinder equally well.
            _ => {
                match &act.geom {
                    Geom::Cylinder { p, axis, r } => {
                        minzone::cylinder_fit_from(&act.points, Criterion::MinimumZone, (*p, *axis, *r))
                    }
                    _ => minzone::cylinder_fit(&act.points, Criterion::MinimumZone),
                }
                .map_err(fe)?
                .form
            }
        })
    }

    /// POS: the actual feature `k`'s deviation from its nominal position (an axis: where it
    /// passes the nominal point), across the nominal direction unless `three_d`; mm.
    fn position_deviation(&self, k: usize, three_d: bool, line: u32) -> Result<Vector3, RunError> {
        let (ga, gn) = (self.actual_at(k, line)?.geom, self.nominal_geom(k));
        let pn = gn.position();
        let mut d = match (&ga, gn.direction()) {
            (Geom::Cylinder { p, axis, .. }, _) => {
                let q = p + axis * (pn - p).dot(axis);
                q - pn
            }
            _ => ga.position() - pn,
        };
        if !three_d {
            if let Some(ax) = gn.direction() {
                d -= ax * d.dot(&ax);
            }
        }
        Ok(d)
    }

    /// PERP or PARLEL of the actual feature `k` to the feature `datum`: the zone width (mm) and,
    /// for an axis, the vector whose length it is.
    fn orientation_value(
        &self,
        t: &Tolerance,
        k: usize,
        datum: usize,
        line: u32,
    ) -> Result<(f64, Option<Vector3>), RunError> {
        let perp = matches!(t.kind, TolKind::Perp { .. });
        let act = self.actual_at(k, line)?;
        let dg = self.actual_geom(datum);
        let d = dg.direction().unwrap_or(Vector3::z());
        let d = d / d.norm();
        let datum_is_plane = matches!(dg, Geom::Plane { .. });
        Ok(match &act.geom {
            Geom::Plane { n, .. } => {
                // Zone: two planes; their normal is d or n made perpendicular to d.
                let use_d = perp != datum_is_plane;
                let u = if use_d {
                    d
                } else {
                    let u = n - d * n.dot(&d);
                    if u.norm() < 1e-9 {
                        return Err(self.eval_err(
                            line,
                            format!("T({}): the plane is parallel to its datum's direction", t.name),
                        ));
                    }
                    u / u.norm()
                };
                (range(&act.points, &u), None)
            }
            g => {
                let ax = g.direction().unwrap_or(Vector3::z());
                let (lo, hi) = extent(&act.points, &ax);
                let s = ax * (hi - lo);
                let along = d * s.dot(&d);
                let across = s - along;
                let w = if perp == datum_is_plane { across } else { along };
                (w.norm(), Some(w))
            }
        })
    }

    /// DISTB between the actual features `fs[0]` and `fs[1]`: along a plane's normal, an axis of
    /// the active coordinate system, or point to point; mm.
    fn distance_value(&self, fs: &[usize], axis: Option<DistAxis>, line: u32) -> Result<f64, RunError> {
        let (ga, gb) = (self.actual_at(fs[0], line)?.geom, self.actual_at(fs[1], line)?.geom);
        let delta = gb.position() - ga.position();
        Ok(match (&ga, &gb, axis) {
            (Geom::Plane { n, .. }, _, None | Some(DistAxis::Pt2Pt))
            | (_, Geom::Plane { n, .. }, None | Some(DistAxis::Pt2Pt)) => delta.dot(n).abs(),
            (_, _, Some(DistAxis::XAxis)) => delta.dot(&self.frame.axis(0)).abs(),
            (_, _, Some(DistAxis::YAxis)) => delta.dot(&self.frame.axis(1)).abs(),
            (_, _, Some(DistAxis::ZAxis)) => delta.dot(&self.frame.axis(2)).abs(),
            _ => delta.norm(),
        })
    }

    /// A nominal's direction (given in the part frame active at its FEAT) in the machine frame.
    fn nominal_frame_dir(&self, k: usize, v: &Vector3) -> Vector3 {
        self.def_frame[k].unwrap_or(self.frame).dir_to_machine(v)
    }
}

/// The datums a tolerance names in order of precedence (POS, PERP, PARLEL), as written.
fn tolerance_datums(t: &Tolerance) -> Vec<String> {
    match &t.statement {
        Statement::Tol { tol: Tol::Pos { datums, .. }, .. } => {
            datums.iter().map(|d| d.name.clone()).collect()
        }
        Statement::Tol { tol: Tol::Perp { datum, .. } | Tol::Parlel { datum, .. }, .. } => {
            vec![datum.name.clone()]
        }
        _ => Vec::new(),
    }
}

fn extent(points: &[Point3], u: &Vector3) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for p in points {
        let s = p.coords.dot(u);
        lo = lo.min(s);
        hi = hi.max(s);
    }
    if points.is_empty() {
        (0.0, 0.0)
    } else {
        (lo, hi)
    }
}

fn range(points: &[Point3], u: &Vector3) -> f64 {
    let (lo, hi) = extent(points, u);
    hi - lo
}

fn orient(v: Vector3, like: Option<Vector3>) -> Vector3 {
    match like {
        Some(n) if v.dot(&n) < 0.0 => -v,
        _ => v,
    }
}

fn orient_like(g: Geom, nominal: &Geom) -> Geom {
    let like = nominal.direction();
    match g {
        Geom::Point { p, n } => Geom::Point { p, n: orient(n, like) },
        Geom::Plane { p, n } => Geom::Plane { p, n: orient(n, like) },
        Geom::Line { p, dir } => Geom::Line { p, dir: orient(dir, like) },
        Geom::Circle { c, n, r } => Geom::Circle { c, n: orient(n, like), r },
        Geom::Cylinder { p, axis, r } => Geom::Cylinder { p, axis: orient(axis, like), r },
        other => other,
    }
}

fn line_plane(p: Point3, d: Vector3, pp: Point3, pn: Vector3) -> Option<Point3> {
    let den = d.dot(&pn);
    if den.abs() < 1e-9 {
        return None;
    }
    Some(p + d * ((pp - p).dot(&pn) / den))
}

/// Intersection of two actual features (the combinations the checker allows).
fn intersect(a: &Geom, b: &Geom) -> Option<Geom> {
    match (a, b) {
        (Geom::Line { p, dir }, Geom::Plane { p: pp, n })
        | (Geom::Plane { p: pp, n }, Geom::Line { p, dir })
        | (Geom::Cylinder { p, axis: dir, .. }, Geom::Plane { p: pp, n })
        | (Geom::Plane { p: pp, n }, Geom::Cylinder { p, axis: dir, .. }) => {
            line_plane(*p, *dir, *pp, *n).map(|q| Geom::Point { p: q, n: *n })
        }
        (Geom::Line { p: p1, dir: d1 }, Geom::Line { p: p2, dir: d2 }) => {
            // Midpoint of the shortest segment between the lines.
            let w = p1 - p2;
            let (a11, a12, a22) = (d1.dot(d1), d1.dot(d2), d2.dot(d2));
            let den = a11 * a22 - a12 * a12;
            if den.abs() < 1e-12 {
                return None;
            }
            let (b1, b2) = (d1.dot(&w), d2.dot(&w));
            let s = (a12 * b2 - a22 * b1) / den;
            let t = (a11 * b2 - a12 * b1) / den;
            let q = Point3::from(((p1 + d1 * s).coords + (p2 + d2 * t).coords) / 2.0);
            let n = d1.cross(d2);
            Some(Geom::Point { p: q, n: n / n.norm() })
        }
        (Geom::Plane { p: p1, n: n1 }, Geom::Plane { p: p2, n: n2 }) => {
            let dir = n1.cross(n2);
            if dir.norm() < 1e-9 {
                return None;
            }
            let dir = dir / dir.norm();
            // The point of the line nearest the first plane's point.
            let m = Matrix3::from_rows(&[n1.transpose(), n2.transpose(), dir.transpose()]);
            let rhs = Vector3::new(n1.dot(&p1.coords), n2.dot(&p2.coords), dir.dot(&p1.coords));
            let q = m.lu().solve(&rhs)?;
            Some(Geom::Line { p: Point3::from(q), dir })
        }
        _ => None,
    }
}

/// The least-squares feature of `points` (machine frame), signed like `nominal`.
pub fn fit_feature(t: FeatType, nominal: &Geom, points: Vec<Point3>) -> Result<Actual, String> {
    let like = nominal.direction();
    let e = |e: truepos_fit::FitError| e.to_string();
    let (geom, up, ud) = match t {
        FeatType::Point => {
            let n = points.len() as f64;
            let c = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
            (Geom::Point { p: Point3::from(c), n: like.unwrap_or(Vector3::z()) }, None, None)
        }
        FeatType::Plane => {
            let f = truepos_fit::plane(&points).map_err(e)?;
            (Geom::Plane { p: f.point, n: orient(f.normal, like) }, Some(f.u_offset), None)
        }
        FeatType::Line => {
            if points.len() == 2 {
                let d = points[1] - points[0];
                if d.norm() < 1e-9 {
                    return Err("the two points of the line coincide".into());
                }
                (Geom::Line { p: points[0], dir: orient(d / d.norm(), like) }, None, None)
            } else {
                let f = truepos_fit::line(&points).map_err(e)?;
                (Geom::Line { p: f.point, dir: orient(f.direction, like) }, Some(f.u_point), None)
            }
        }
        FeatType::Circle => {
            // In the plane of the nominal, through the points' mean height.
            let n = like.unwrap_or(Vector3::z());
            let m = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / points.len() as f64;
            let h = m.dot(&n);
            let proj: Vec<Point3> = points.iter().map(|p| p - n * (p.coords.dot(&n) - h)).collect();
            let f = truepos_fit::circle(&proj).map_err(e)?;
            let u = f.u_center.norm();
            (Geom::Circle { c: f.center, n, r: f.radius }, Some(u), Some(2.0 * f.u_radius))
        }
        FeatType::Cylndr => {
            let (p, axis, r, up, ur) = cylinder_from_nominal(nominal, &points)?;
            (Geom::Cylinder { p, axis: orient(axis, like), r }, Some(up), Some(2.0 * ur))
        }
        FeatType::Sphere => {
            let f = truepos_fit::sphere(&points).map_err(e)?;
            (Geom::Sphere { c: f.center, r: f.radius }, Some(f.u_center.norm()), Some(2.0 * f.u_radius))
        }
        FeatType::Cone => {
            let f = truepos_fit::cone(&points).map_err(e)?;
            (
                Geom::Cone { apex: f.apex, axis: f.axis, half_angle: f.apex_angle / 2.0 },
                Some(f.u_apex.norm()),
                None,
            )
        }
    };
    Ok(Actual { geom, points, u_position_mm: up, u_diameter_mm: ud })
}

/// A machine that moves nowhere: every probing touches its nominal point exactly (tip centre at
/// nominal + radius along the approach). `--dry-run` runs the plan on it and lists the motions.
#[derive(Debug, Clone)]
pub struct DryRun {
    at: Point3,
    radius: f64,
    /// Tip radii of tools by name (the program's `SNSDEF` diameters).
    pub tools: HashMap<String, f64>,
}

impl DryRun {
    /// A dry-run machine for `plan` with the options of the run.
    pub fn new(plan: &Plan, opts: &RunOptions) -> DryRun {
        let tools = plan
            .sensors
            .iter()
            .map(|s| {
                let name =
                    opts.sensors.get(&s.name.to_ascii_uppercase()).cloned().unwrap_or_else(|| s.name.clone());
                (name, s.tip_diameter_mm / 2.0)
            })
            .collect();
        DryRun { at: Point3::origin(), radius: 0.0, tools }
    }
}

impl ProbingMachine for DryRun {
    fn info(&self) -> DeviceInfo {
        DeviceInfo { address: "dry-run".into(), version: "no machine: nominal points".into() }
    }
    fn position(&mut self) -> Result<Point3, DeviceError> {
        Ok(self.at)
    }
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        self.at = target_mm;
        Ok(())
    }
    fn probe(&mut self, r: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        let tip = r.nominal_mm + r.approach * self.radius;
        self.at = tip + r.approach * r.retract_mm;
        Ok(ProbeHit { tip_center_mm: tip, normal: Some(r.approach) })
    }
    fn abort(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }
    fn tool_names(&mut self) -> Result<Vec<String>, DeviceError> {
        Ok(self.tools.keys().cloned().collect())
    }
    fn select_tool(&mut self, name: &str) -> Result<ToolInfo, DeviceError> {
        self.radius = self.tools.get(name).copied().unwrap_or(0.0);
        Ok(ToolInfo { name: name.to_string(), tip_radius_mm: self.radius })
    }
}

/// The least-squares cylinder started from the nominal (axis, radius). Points taken on two
/// levels at the same angles lie on several cylinders (four points a level at 0°, 90°, 180°,
/// 270° lie as well on a cylinder about a diagonal); the nominal picks the one the program means.
/// Returns axis point, unit axis, radius and the standard uncertainties of point and radius.
fn cylinder_from_nominal(
    nominal: &Geom,
    points: &[Point3],
) -> Result<(Point3, Vector3, f64, f64, f64), String> {
    use truepos_math::lsq::{solve, LsqOptions, Residuals};
    let Geom::Cylinder { p: p0, axis: a0, r: r0 } = nominal else {
        return Err("not a cylinder".into());
    };
    let n = points.len() as f64;
    let centroid = Point3::from(points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n);
    let a0 = a0 / a0.norm();
    let c0 = p0 + a0 * (centroid - p0).dot(&a0);
    let u = a0.cross(&if a0.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() });
    let u = u / u.norm();
    let v = a0.cross(&u);
    struct Cyl<'a> {
        pts: &'a [Point3],
        c0: Point3,
        a0: Vector3,
        u: Vector3,
        v: Vector3,
    }
    impl Cyl<'_> {
        fn geom(&self, x: &[f64]) -> (Point3, Vector3) {
            let o = self.c0 + self.u * x[0] + self.v * x[1];
            let a = self.a0 + self.u * x[2] + self.v * x[3];
            (o, a / a.norm())
        }
        fn res(&self, x: &[f64], i: usize) -> f64 {
            let (o, a) = self.geom(x);
            (self.pts[i] - o).cross(&a).norm() - x[4]
        }
    }
    impl Residuals for Cyl<'_> {
        fn n_params(&self) -> usize {
            5
        }
        fn n_residuals(&self) -> usize {
            self.pts.len()
        }
        fn eval(&self, x: &[f64], i: usize, jac: &mut [f64]) -> f64 {
            let r = self.res(x, i);
            let mut y = x.to_vec();
            for j in 0..5 {
                let h = 1e-7 * (1.0 + x[j].abs());
                y[j] = x[j] + h;
                let rp = self.res(&y, i);
                y[j] = x[j] - h;
                let rm = self.res(&y, i);
                y[j] = x[j];
                jac[j] = (rp - rm) / (2.0 * h);
            }
            r
        }
    }
    let prob = Cyl { pts: points, c0, a0, u, v };
    let sol = solve(&prob, &[0.0, 0.0, 0.0, 0.0, *r0], &LsqOptions::default())
        .map_err(|e| format!("cylinder: {e}"))?;
    if sol.rank < 5 {
        return Err("cylinder: the points do not determine the cylinder".into());
    }
    let (o, a) = prob.geom(&sol.params);
    let up = (sol.covariance[(0, 0)] + sol.covariance[(1, 1)]).max(0.0).sqrt();
    Ok((o, a, sol.params[4].abs(), up, sol.std_dev(4)))
}

impl truepos_math::exit::HasExitClass for RunError {
    /// A program that cannot run here is input (2); a machine or evaluation failure is not (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        match self {
            RunError::Input(_) => ExitClass::Input,
            _ => ExitClass::Device,
        }
    }
}
