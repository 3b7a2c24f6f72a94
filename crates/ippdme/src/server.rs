//! The I++ DME server: a session state machine ([`Session`]) over any [`Cmm`], and the TCP
//! front end ([`Server`]) that serves one client at a time.
//!
//! Entry points:
//! - [`Server::bind`] then [`Server::run`] (blocking, until the stop flag is set) or
//!   [`Server::spawn`] (background thread, for tests and benches).
//! - [`Session::handle_line`]: one received line → the response lines, without any socket (the
//!   protocol core, fuzzable).
//!
//! Behaviour (contract "CMM protocol: truepos ippdme serve"): answers carry the command's tag,
//! `&` first, `%` last, data `#` and errors `!` between; an unreadable tag gets only an `E0000`
//! error; severity ≥ 2 puts the session in error state until `ClearAllErrors()`; a line over
//! 64 KiB gets `E0000 ! Error(2, 0000, "Read", "Buffer full")` and the connection is closed; a
//! second connection while one is served gets `E0000 ! Error(2, 0008, "Connect", "Protocol
//! error")` and is closed. Homing, the active tool, the tool properties and the coordinate
//! systems belong to the machine and persist across sessions and connections. When a client
//! disconnects the machine is stopped.
//!
//! Coordinate systems: a transformation `(X0, Y0, Z0, Theta, Psi, Phi)` maps machine to csy
//! coordinates as `p_csy = R · p_machine + (X0, Y0, Z0)` with `R` built from the Euler angles as in
//! the specification's appendix A.4.2 (so `(X0, Y0, Z0)` is the machine origin in the csy).

use crate::command::{
    Command, Csy, CsyTransform, Field, Key, ParBlock, Param, PropItem, PropPath, ToolRef, UnknownScan,
};
use crate::machine::{Cmm, Contact, Guide, MachineError, ScanPath, ScanPoint, Stop};
use crate::part::MachineConfig;
use crate::protocol::{fmt_num, parse_line, Body, ErrorCode, LineError, Response, Tag};
use crate::reader::{LineReader, ReadLine};
use std::fmt::Write as _;
use std::io::{self, BufWriter, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use truepos_math::{Matrix3, Point3, Vector3};

/// The specification version this server implements.
pub const DME_VERSION: &str = "1.4.3";

/// Points per `#` line when streaming scans.
const SCAN_POINTS_PER_LINE: usize = 32;

/// Limits and defaults of one motion parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ParamValue {
    act: f64,
    def: f64,
    min: f64,
    max: f64,
}

impl ParamValue {
    const fn new(def: f64, min: f64, max: f64) -> Self {
        ParamValue { act: def, def, min, max }
    }
    fn field(&self, f: Field) -> f64 {
        match f {
            Field::Act => self.act,
            Field::Def => self.def,
            Field::Max => self.max,
            Field::Min => self.min,
        }
    }
}

/// A tool of the tool table.
#[derive(Debug, Clone, PartialEq)]
struct Tool {
    name: String,
    radius_mm: f64,
    can_measure: bool,
    enumerated: bool,
    goto: [ParamValue; 2],
    ptmeas: [ParamValue; 5],
}

impl Tool {
    fn new(name: &str, tip_diameter_mm: f64, can_measure: bool, enumerated: bool) -> Tool {
        Tool {
            name: name.to_string(),
            radius_mm: tip_diameter_mm / 2.0,
            can_measure,
            enumerated,
            // Speed mm/s, Accel mm/s².
            goto: [ParamValue::new(100.0, 1.0, 1000.0), ParamValue::new(500.0, 1.0, 3000.0)],
            // Speed, Accel, Approach, Retract, Search (mm/s, mm/s², mm).
            ptmeas: [
                ParamValue::new(5.0, 0.1, 500.0),
                ParamValue::new(100.0, 1.0, 3000.0),
                ParamValue::new(2.0, 0.0, 100.0),
                ParamValue::new(2.0, -100.0, 100.0),
                ParamValue::new(4.0, 0.01, 100.0),
            ],
        }
    }
    fn param(&self, b: ParBlock, p: Param) -> Option<&ParamValue> {
        let k = Param::of(b).iter().position(|x| *x == p)?;
        match b {
            ParBlock::GoToPar => self.goto.get(k),
            ParBlock::PtMeasPar => self.ptmeas.get(k),
        }
    }
    fn param_mut(&mut self, b: ParBlock, p: Param) -> Option<&mut ParamValue> {
        let k = Param::of(b).iter().position(|x| *x == p)?;
        match b {
            ParBlock::GoToPar => self.goto.get_mut(k),
            ParBlock::PtMeasPar => self.ptmeas.get_mut(k),
        }
    }
    fn ptmeas(&self, p: Param) -> f64 {
        self.param(ParBlock::PtMeasPar, p).map(|v| v.act).unwrap_or(0.0)
    }
}

/// What belongs to the machine and outlives sessions and connections.
struct MachineState<M> {
    machine: M,
    homed: bool,
    tools: Vec<Tool>,
    tool: usize,
    found_tool: Option<usize>,
    csy: Csy,
    transforms: [[f64; 6]; 6],
    /// X, Y, Z locked by `LockAxis` (a property of the active tool; cleared by `ChangeTool`).
    locked: [bool; 3],
}

/// The state shared by all connections: the machine and its persistent settings.
pub struct Shared<M> {
    state: Mutex<MachineState<M>>,
}

impl<M: Cmm> Shared<M> {
    /// The machine with its tool table: `RefTool`, `NoTool`, `Probe1`, then the machine file's
    /// tools (and the reserved, not enumerated `BaseTool`).
    pub fn new(machine: M, config: &MachineConfig) -> Shared<M> {
        let mut tools = vec![
            Tool::new("RefTool", 3.0, true, true),
            Tool::new("NoTool", 0.0, false, true),
            Tool::new("Probe1", 3.0, true, true),
        ];
        for t in &config.tools {
            tools.push(Tool::new(&t.name, t.tip_diameter_mm, true, true));
        }
        tools.push(Tool::new("BaseTool", 0.0, true, false));
        Shared {
            state: Mutex::new(MachineState {
                machine,
                homed: false,
                tools,
                tool: 1,
                found_tool: None,
                csy: Csy::MachineCsy,
                transforms: [[0.0; 6]; 6],
                locked: [false; 3],
            }),
        }
    }

    fn lock(&self) -> MutexGuard<'_, MachineState<M>> {
        // A panic while holding the lock cannot leave the plain data inconsistent in a way that
        // matters more than refusing all further service.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Run `f` on the machine (for tests: truth, positions).
    pub fn with_machine<T>(&self, f: impl FnOnce(&mut M) -> T) -> T {
        f(&mut self.lock().machine)
    }
}

/// The `OnMoveReportE` daemon.
#[derive(Debug, Clone)]
struct MoveDaemon {
    tag: Tag,
    time_s: Option<f64>,
    dis_mm: Option<f64>,
    keys: Vec<Key>,
    last_report: Instant,
    last_pos: Point3,
}

/// One client's session on the shared machine.
pub struct Session<M> {
    shared: Arc<Shared<M>>,
    in_session: bool,
    error_state: bool,
    user_enabled: bool,
    last_error: Option<(ErrorCode, String)>,
    ptmeas_keys: Vec<Key>,
    scan_keys: Vec<Key>,
    daemon: Option<MoveDaemon>,
    /// The detail the next error's text carries (the limit a refused command exceeded).
    detail: Option<String>,
    /// Lines for the log about things that went wrong (bad input, faults).
    pub notes: Vec<String>,
}

/// Result of handling one line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Keep the connection open.
    Continue,
    /// Close the connection after sending the responses.
    Close,
}

type Answer = Result<(), (ErrorCode, String)>;

fn fail<T>(code: ErrorCode, msg: impl Into<String>) -> Result<T, (ErrorCode, String)> {
    Err((code, msg.into()))
}

fn euler_matrix(theta: f64, psi: f64, phi: f64) -> Matrix3 {
    let (s1, c1) = theta.to_radians().sin_cos();
    let (s2, c2) = psi.to_radians().sin_cos();
    let (s3, c3) = phi.to_radians().sin_cos();
    Matrix3::new(
        c2 * c3 - c1 * s2 * s3,
        s2 * c3 + c1 * c2 * s3,
        s1 * s3,
        -c2 * s3 - c1 * s2 * c3,
        -s2 * s3 + c1 * c2 * c3,
        s1 * c3,
        s1 * s2,
        -s1 * c2,
        c1,
    )
}

/// csy_from_machine for the active coordinate system.
fn csy_transform<M>(st: &MachineState<M>) -> (Matrix3, Vector3) {
    let t = match st.csy {
        Csy::MachineCsy => return (Matrix3::identity(), Vector3::zeros()),
        Csy::PartCsy => st.transforms[CsyTransform::PartCsy.index()],
        Csy::MoveableMachineCsy => st.transforms[CsyTransform::MoveableMachineCsy.index()],
        Csy::MultipleArmCsy => st.transforms[CsyTransform::MultipleArmCsy.index()],
    };
    (euler_matrix(t[3], t[4], t[5]), Vector3::new(t[0], t[1], t[2]))
}

fn to_csy<M>(st: &MachineState<M>, p: &Point3) -> Point3 {
    let (r, t) = csy_transform(st);
    Point3::from(r * p.coords + t)
}

fn to_machine<M>(st: &MachineState<M>, p: &Point3) -> Point3 {
    let (r, t) = csy_transform(st);
    Point3::from(r.transpose() * (p.coords - t))
}

fn dir_to_csy<M>(st: &MachineState<M>, v: &Vector3) -> Vector3 {
    csy_transform(st).0 * v
}

fn dir_to_machine<M>(st: &MachineState<M>, v: &Vector3) -> Vector3 {
    csy_transform(st).0.transpose() * v
}

/// The rotary table's angle in degrees (0 without a table).
fn table_deg<M: Cmm>(st: &MachineState<M>) -> f64 {
    st.machine.table_angle().to_degrees()
}

/// Rotation by `angle` (rad) about the unit `axis` (Rodrigues).
fn axis_rotation(axis: &Vector3, angle: f64) -> Matrix3 {
    let (s, c) = angle.sin_cos();
    let k = Matrix3::new(0.0, -axis.z, axis.y, axis.z, 0.0, -axis.x, -axis.y, axis.x, 0.0);
    Matrix3::identity() + k * s + k * k * (1.0 - c)
}

/// The rotation that turns unit `a` onto unit `b` (about `a × b`; a half turn about any
/// perpendicular when they are opposite).
fn rotation_between(a: &Vector3, b: &Vector3) -> Matrix3 {
    let axis = a.cross(b);
    let angle = a.dot(b).clamp(-1.0, 1.0).acos();
    match axis.try_normalize(1e-12) {
        Some(k) => axis_rotation(&k, angle),
        None if a.dot(b) > 0.0 => Matrix3::identity(),
        None => {
            let e = if a.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
            axis_rotation(&a.cross(&e).normalize(), std::f64::consts::PI)
        }
    }
}

/// The rotary table's axis or the specification's error for a machine without one.
fn table_axis<M: Cmm>(st: &MachineState<M>, what: &str) -> Result<(Point3, Vector3), (ErrorCode, String)> {
    st.machine
        .rotary_axis()
        .ok_or((ErrorCode::UNSUPPORTED_COMMAND, format!("{what}: this CMM has no rotary table")))
}

/// Distance of `p` from the line through `o` along unit `a`, and the offset from the line.
fn off_axis(p: &Point3, o: &Point3, a: &Vector3) -> (f64, Vector3) {
    let rel = p - o;
    let radial = rel - a * rel.dot(a);
    (radial.norm(), radial)
}

fn in_volume<M: Cmm>(st: &MachineState<M>, p: &Point3) -> bool {
    let (lo, hi) = st.machine.volume();
    (0..3).all(|k| p[k] >= lo[k] - 1e-9 && p[k] <= hi[k] + 1e-9)
}

fn machine_error(e: MachineError) -> (ErrorCode, String) {
    match e {
        MachineError::OutOfVolume | MachineError::PartOutOfVolume(_) => {
            (ErrorCode::OUT_OF_VOLUME, e.to_string())
        }
        MachineError::IllegalTouch { .. } => (ErrorCode::ILLEGAL_TOUCH, e.to_string()),
        MachineError::Unable(_) => (ErrorCode::UNABLE_TO_MOVE, e.to_string()),
    }
}

/// `v` normalised; `None` for a vector shorter than 1e-12 or with a non-finite component. The
/// largest component is divided out first, so that huge components (1e300) do not overflow.
fn unit(v: [f64; 3]) -> Option<Vector3> {
    let v = Vector3::new(v[0], v[1], v[2]);
    let m = v.amax();
    if !(m.is_finite() && m > 1e-12) {
        return None;
    }
    let w = v / m;
    let n = w.norm();
    (n * m > 1e-12).then(|| w / n)
}

/// `v` normalised, or the specification's error for a vector without length (`what`: the
/// message).
fn direction(v: [f64; 3], what: impl Into<String>) -> Result<Vector3, (ErrorCode, String)> {
    unit(v).ok_or_else(|| (ErrorCode::VECTOR_HAS_NO_NORM, what.into()))
}

/// The error of a scan that would leave the machine volume, unless every point of `points`
/// (machine coordinates) is inside it.
fn scan_in_volume<M: Cmm>(st: &MachineState<M>, points: &[Point3]) -> Answer {
    if points.iter().any(|p| !in_volume(st, p)) {
        return fail(ErrorCode::OUT_OF_VOLUME, "scan outside the machine volume");
    }
    Ok(())
}

/// One point's values in report order.
/// `r_deg` is the rotary table's angle (`R()`, degrees).
#[allow(clippy::too_many_arguments)]
fn report_values(
    keys: &[Key],
    p: &Point3,
    n: &Vector3,
    er: f64,
    q: f64,
    r_deg: f64,
    named: bool,
    out: &mut String,
) {
    for (i, k) in keys.iter().enumerate() {
        if i > 0 {
            out.push_str(if named { ", " } else { "," });
        }
        let vals: &[f64] = match k {
            Key::X => &[p.x],
            Key::Y => &[p.y],
            Key::Z => &[p.z],
            Key::R => &[r_deg],
            Key::ToolA | Key::ToolB | Key::ToolC => &[0.0],
            Key::Ijk => &[n.x, n.y, n.z],
            Key::Er => &[er],
            Key::Q => &[q],
        };
        if named {
            out.push_str(k.name());
            out.push('(');
        }
        for (j, v) in vals.iter().enumerate() {
            if j > 0 {
                out.push_str(if named { ", " } else { "," });
            }
            let _ = write!(out, "{:.6}", if *v == 0.0 { 0.0 } else { *v });
        }
        if named {
            out.push(')');
        }
    }
}

impl<M: Cmm> Session<M> {
    /// A new session on the shared machine.
    pub fn new(shared: Arc<Shared<M>>) -> Session<M> {
        Session {
            shared,
            in_session: false,
            error_state: false,
            user_enabled: false,
            last_error: None,
            ptmeas_keys: vec![Key::X, Key::Y, Key::Z],
            scan_keys: vec![Key::X, Key::Y, Key::Z, Key::Q],
            daemon: None,
            detail: None,
            notes: Vec::new(),
        }
    }

    /// The client went away: stop the machine, end the session.
    pub fn disconnect(&mut self) {
        self.shared.lock().machine.stop();
        self.in_session = false;
        self.daemon = None;
    }

    fn error_response(&mut self, tag: Tag, code: ErrorCode, method: &str, message: &str) -> Response {
        if code.severity >= 2 {
            self.error_state = true;
        }
        self.last_error = Some((code, method.to_string()));
        self.notes.push(format!("{tag}: error {:04} ({}): {message}", code.number, code.text));
        match self.detail.take() {
            Some(d) => Response::error_with_detail(tag, code, method, &d),
            None => Response::error(tag, code, method),
        }
    }

    /// Refuse the command for the machine's reason, which the error's text carries.
    fn refuse_machine<T>(&mut self, e: MachineError) -> Result<T, (ErrorCode, String)> {
        let why = match &e {
            MachineError::Unable(m) | MachineError::PartOutOfVolume(m) => m.clone(),
            other => other.to_string(),
        };
        self.refuse(machine_error(e).0, why)
    }

    /// Refuse the command for a limit: the error's text names it (as does the log).
    fn refuse<T>(&mut self, code: ErrorCode, why: String) -> Result<T, (ErrorCode, String)> {
        self.detail = Some(why.clone());
        Err((code, why))
    }

    /// Handle one received line (without CR LF); the answers are appended to `out`.
    pub fn handle_line(&mut self, line: &[u8], out: &mut Vec<Response>) -> Flow {
        let text = String::from_utf8_lossy(line);
        let method: String = text.get(6..).unwrap_or("").chars().take(80).collect();
        let (tag, call) = match parse_line(line) {
            Ok(x) => x,
            Err(e) => {
                let tag = e.tag();
                let code = e.code();
                let method = match &e {
                    LineError::IllegalTag | LineError::NoSpace => "ParseTag".to_string(),
                    LineError::IllegalChar { .. } => "ReadLine".to_string(),
                    _ => method,
                };
                match e {
                    LineError::IllegalTag | LineError::NoSpace | LineError::IllegalChar { tag: None, .. } => {
                        let r = self.error_response(Tag::SERVER_EVENT, code, &method, &e.describe());
                        out.push(r);
                    }
                    _ => {
                        out.push(Response::ack(tag));
                        let r = self.error_response(tag, code, &method, &e.describe());
                        out.push(r);
                        out.push(Response::complete(tag));
                    }
                }
                return Flow::Continue;
            }
        };
        out.push(Response::ack(tag));
        let method = call.name.clone();
        let cmd = match Command::from_call(tag, &call) {
            Ok(c) => c,
            Err(e) => {
                let r = self.error_response(tag, e.code, &method, &e.message);
                out.push(r);
                out.push(Response::complete(tag));
                return Flow::Continue;
            }
        };
        let mut after = Vec::new();
        let result = self.execute(tag, &cmd, out, &mut after);
        if let Err((code, msg)) = result {
            let r = self.error_response(tag, code, &method, &msg);
            out.push(r);
        }
        out.push(Response::complete(tag));
        out.append(&mut after);
        Flow::Continue
    }

    fn check_homed(&self, st: &MachineState<M>) -> Answer {
        if st.homed {
            Ok(())
        } else {
            fail(ErrorCode::BAD_CONTEXT, "the machine is not homed: Home() first")
        }
    }

    /// The active tool, once the machine is homed and if the tool can measure (else the tool's
    /// name and `cannot`, e.g. "cannot measure").
    fn measuring_tool(&self, st: &MachineState<M>, cannot: &str) -> Result<Tool, (ErrorCode, String)> {
        self.check_homed(st)?;
        let tool = &st.tools[st.tool];
        if !tool.can_measure {
            return fail(ErrorCode::BAD_CONTEXT, format!("{} {cannot}", tool.name));
        }
        Ok(tool.clone())
    }

    /// The rotary table's centre and axis for the part command `what`, once the machine is
    /// homed.
    fn homed_table(
        &self,
        st: &MachineState<M>,
        what: &str,
    ) -> Result<(Point3, Vector3), (ErrorCode, String)> {
        self.check_homed(st)?;
        table_axis(st, what)
    }

    fn execute(
        &mut self,
        tag: Tag,
        cmd: &Command,
        out: &mut Vec<Response>,
        after: &mut Vec<Response>,
    ) -> Answer {
        if !self.in_session && *cmd != Command::StartSession {
            return fail(ErrorCode::BAD_CONTEXT, "no session: StartSession() first");
        }
        let allowed_in_error = matches!(
            cmd,
            Command::ClearAllErrors
                | Command::StartSession
                | Command::GetErrStatusE
                | Command::GetXtdErrStatus
                | Command::GetErrorInfo(_)
                | Command::AbortE
                | Command::EndSession
                | Command::StopDaemon(_)
                | Command::StopAllDaemons
        );
        if self.error_state && !allowed_in_error {
            return fail(ErrorCode::USE_CLEAR_ALL_ERRORS, "the server is in error state");
        }
        let shared = Arc::clone(&self.shared);
        let mut st = shared.lock();
        match cmd {
            Command::StartSession
            | Command::EndSession
            | Command::GetDMEVersion
            | Command::GetMachineClass
            | Command::GetErrStatusE
            | Command::GetXtdErrStatus
            | Command::GetErrorInfo(..)
            | Command::ClearAllErrors
            | Command::AbortE
            | Command::EnableUser
            | Command::DisableUser
            | Command::IsUserEnabled => self.session_command(tag, cmd, &mut st, out),
            Command::OnPtMeasReport(..)
            | Command::OnScanReport(..)
            | Command::OnMoveReportE { .. }
            | Command::StopDaemon(..)
            | Command::StopAllDaemons => self.report_command(tag, cmd, &st, after),
            Command::Home
            | Command::IsHomed
            | Command::Get(..)
            | Command::GoTo { .. }
            | Command::PtMeas { .. }
            | Command::LockAxis(..) => self.motion_command(tag, cmd, &mut st, out),
            Command::ChangeTool(..)
            | Command::SetTool(..)
            | Command::FindTool(..)
            | Command::EnumTools
            | Command::GetChangeToolAction(..)
            | Command::GetProp(..)
            | Command::GetPropE(..)
            | Command::SetProp(..)
            | Command::EnumProp(..)
            | Command::EnumAllProp(..)
            | Command::ReQualify
            | Command::AlignTool { .. } => self.tool_command(tag, cmd, &mut st, out),
            Command::GetCoordSystem
            | Command::SetCoordSystem(..)
            | Command::GetCsyTransformation(..)
            | Command::SetCsyTransformation(..) => self.csy_command(tag, cmd, &mut st, out),
            Command::AlignPart { .. }
            | Command::CenterPart { .. }
            | Command::TiltPart { .. }
            | Command::TiltCenterPart { .. } => self.part_command(tag, cmd, &mut st, out),
            Command::ScanOnCircleHint { .. }
            | Command::ScanOnLineHint { .. }
            | Command::ScanUnknownHint(..)
            | Command::ScanOnCircle { .. }
            | Command::ScanOnLine { .. }
            | Command::ScanUnknown(..) => self.scan_command(tag, cmd, &mut st, out),
        }
    }

    /// Session, error-state and user-enable commands (spec 6.3.1, 6.3.2).
    fn session_command(
        &mut self,
        tag: Tag,
        cmd: &Command,
        st: &mut MachineState<M>,
        out: &mut Vec<Response>,
    ) -> Answer {
        let data = |s: String| Response::data(tag, s);
        match cmd {
            Command::StartSession => {
                if self.in_session {
                    return fail(ErrorCode::ILLEGAL_COMMAND, "a session is already open");
                }
                self.in_session = true;
                self.error_state = false;
                self.user_enabled = false;
                self.ptmeas_keys = vec![Key::X, Key::Y, Key::Z];
                self.scan_keys = vec![Key::X, Key::Y, Key::Z, Key::Q];
                self.daemon = None;
            }
            Command::EndSession => {
                self.in_session = false;
                self.daemon = None;
                self.error_state = false;
            }
            Command::GetDMEVersion => out.push(data(format!("DMEVersion(\"{DME_VERSION}\")"))),
            Command::GetMachineClass => out.push(data(
                if st.machine.rotary_axis().is_some() {
                    "GetMachineClass(CartCMMWithRotaryTable)"
                } else {
                    "GetMachineClass(CartCMM)"
                }
                .into(),
            )),
            Command::GetErrStatusE => out.push(data(format!("ErrStatus({})", self.error_state as u8))),
            Command::GetXtdErrStatus => {
                out.push(data(format!("IsHomed({})", st.homed as u8)));
                out.push(data(format!("IsUserEnabled({})", self.user_enabled as u8)));
                if self.error_state {
                    if let Some((code, m)) = &self.last_error {
                        out.push(data(format!(
                            "Error({}, {:04}, \"{}\", \"{}\")",
                            code.severity,
                            code.number,
                            m.replace('"', "#"),
                            code.text
                        )));
                    }
                }
            }
            Command::GetErrorInfo(n) => match ErrorCode::lookup(*n) {
                Some(c) => out.push(data(format!("\"{}\"", c.text))),
                None => return fail(ErrorCode::ARGUMENT_OUT_OF_RANGE, format!("no error number {n:04}")),
            },
            Command::ClearAllErrors => {
                self.error_state = false;
            }
            Command::AbortE => {
                // Moves are instant: nothing is pending. As the specification asks, the client
                // must send ClearAllErrors() before anything else.
                st.machine.stop();
                self.error_state = true;
                self.last_error = Some((ErrorCode::TRANSACTION_ABORTED, "AbortE".into()));
            }
            Command::EnableUser => self.user_enabled = true,
            Command::DisableUser => self.user_enabled = false,
            Command::IsUserEnabled => out.push(data(format!("IsUserEnabled({})", self.user_enabled as u8))),
            _ => unreachable!("execute routes only session commands here"),
        }
        Ok(())
    }

    /// Report formats and the `OnMoveReportE` daemon.
    fn report_command(
        &mut self,
        tag: Tag,
        cmd: &Command,
        st: &MachineState<M>,
        after: &mut Vec<Response>,
    ) -> Answer {
        match cmd {
            Command::OnPtMeasReport(keys) => self.ptmeas_keys = keys.clone(),
            Command::OnScanReport(keys) => self.scan_keys = keys.clone(),
            Command::OnMoveReportE { time_s, dis_mm, keys } => {
                if self.daemon.is_some() {
                    return fail(
                        ErrorCode::DAEMON_ALREADY_EXISTS,
                        "stop the running OnMoveReportE daemon first",
                    );
                }
                let pos = st.machine.position();
                let d = MoveDaemon {
                    tag,
                    time_s: *time_s,
                    dis_mm: *dis_mm,
                    keys: keys.clone(),
                    last_report: Instant::now(),
                    last_pos: pos,
                };
                // The first report comes right after the daemon started (as the NIST server does).
                if !d.keys.is_empty() {
                    let mut s = String::new();
                    report_values(
                        &d.keys,
                        &to_csy(st, &pos),
                        &Vector3::zeros(),
                        0.0,
                        0.0,
                        table_deg(st),
                        true,
                        &mut s,
                    );
                    after.push(Response::data(tag, s));
                }
                self.daemon = Some(d);
            }
            Command::StopDaemon(t) => match &self.daemon {
                Some(d) if d.tag == *t => self.daemon = None,
                _ => return fail(ErrorCode::DAEMON_DOES_NOT_EXIST, format!("no daemon {t}")),
            },
            Command::StopAllDaemons => {
                if self.daemon.take().is_none() {
                    return fail(ErrorCode::NO_DAEMONS, "no daemon is running");
                }
            }
            _ => unreachable!("execute routes only report commands here"),
        }
        Ok(())
    }

    /// Homing, position queries, moves and single-point measurement.
    fn motion_command(
        &mut self,
        tag: Tag,
        cmd: &Command,
        st: &mut MachineState<M>,
        out: &mut Vec<Response>,
    ) -> Answer {
        let data = |s: String| Response::data(tag, s);
        match cmd {
            Command::Home => {
                st.machine.home().map_err(machine_error)?;
                st.homed = true;
                self.after_move(st, out);
            }
            Command::IsHomed => out.push(data(format!("IsHomed({})", st.homed as u8))),
            Command::Get(keys) => {
                let p = to_csy(st, &st.machine.position());
                let mut s = String::new();
                report_values(keys, &p, &Vector3::zeros(), 0.0, 0.0, table_deg(st), true, &mut s);
                out.push(data(s));
            }
            Command::GoTo { x, y, z } => {
                self.check_homed(st)?;
                let cur = to_csy(st, &st.machine.position());
                let target = Point3::new(x.unwrap_or(cur.x), y.unwrap_or(cur.y), z.unwrap_or(cur.z));
                let mut target_m = to_machine(st, &target);
                // Locked machine axes stay where they are, without an error (spec 13.4).
                let now = st.machine.position();
                for k in 0..3 {
                    if st.locked[k] {
                        target_m[k] = now[k];
                    }
                }
                if !in_volume(st, &target_m) {
                    return fail(
                        ErrorCode::OUT_OF_VOLUME,
                        format!("GoTo target {target_m:?} (machine) outside the volume"),
                    );
                }
                self.user_enabled = false;
                let r = st.tools[st.tool].radius_mm;
                let res = st.machine.move_to(target_m, r);
                self.after_move(st, out);
                res.map_err(machine_error)?;
            }
            Command::PtMeas { x, y, z, ijk } => {
                let tool = self.measuring_tool(st, "cannot measure")?;
                let cur = to_csy(st, &st.machine.position());
                let p = Point3::new(x.unwrap_or(cur.x), y.unwrap_or(cur.y), z.unwrap_or(cur.z));
                let n = direction(ijk.unwrap_or((cur - p).into()), "the probing direction has no length")?;
                let p_m = to_machine(st, &p);
                let n_m = dir_to_machine(st, &n);
                self.user_enabled = false;
                let retract = tool.ptmeas(Param::Retract);
                let contact = ptmeas(st, &tool, p_m, n_m, retract);
                self.after_move(st, out);
                let c = contact?;
                let mut s = String::new();
                let tc = to_csy(st, &c.tip_center_mm);
                let nc = dir_to_csy(st, &c.normal);
                report_values(&self.ptmeas_keys, &tc, &nc, tool.radius_mm, 0.0, table_deg(st), true, &mut s);
                out.push(data(s));
            }
            Command::LockAxis(axes) => {
                for (k, n) in ["X", "Y", "Z"].iter().enumerate() {
                    if axes.iter().any(|a| a == n) {
                        st.locked[k] = true;
                    }
                }
            }
            _ => unreachable!("execute routes only motion commands here"),
        }
        Ok(())
    }

    /// Tool selection, tool properties, qualification and tool alignment.
    fn tool_command(
        &mut self,
        tag: Tag,
        cmd: &Command,
        st: &mut MachineState<M>,
        out: &mut Vec<Response>,
    ) -> Answer {
        let data = |s: String| Response::data(tag, s);
        match cmd {
            Command::ChangeTool(name) | Command::SetTool(name) => {
                // The virtual head carries every tool at the same reference point, so the
                // tip-centre position does not jump on a change (a report is sent anyway, as
                // the specification asks).
                let k = find_tool(st, name)?;
                st.tool = k;
                if matches!(cmd, Command::ChangeTool(_)) {
                    st.locked = [false; 3];
                }
                self.after_move_forced(st, out);
            }
            Command::FindTool(name) => {
                let k = find_tool(st, name)?;
                st.found_tool = Some(k);
            }
            Command::EnumTools => {
                for t in st.tools.iter().filter(|t| t.enumerated) {
                    out.push(data(format!("\"{}\"", t.name)));
                }
            }
            Command::GetChangeToolAction(name) => {
                let k = find_tool(st, name)?;
                let p = to_csy(st, &st.machine.position());
                let action = if k == st.tool { "None" } else { "Switch" };
                out.push(data(format!(
                    "ChangeToolAction({action}, X({}), Y({}), Z({}))",
                    fmt_num(p.x),
                    fmt_num(p.y),
                    fmt_num(p.z)
                )));
            }
            Command::GetProp(paths) | Command::GetPropE(paths) => {
                let mut items = Vec::new();
                for p in paths {
                    let t = resolve_tool(st, p)?;
                    items.push(format!("{}({})", p.dotted(), prop_value(t, p)?));
                }
                out.push(data(items.join(", ")));
            }
            Command::SetProp(items) => {
                for (p, v) in items {
                    let k = match p.tool {
                        ToolRef::Tool => st.tool,
                        ToolRef::FoundTool => {
                            st.found_tool.ok_or((ErrorCode::BAD_CONTEXT, "no FindTool() yet".to_string()))?
                        }
                    };
                    let PropItem::Value(b, param, _) = p.item else {
                        return fail(ErrorCode::BAD_PROPERTY, format!("{} cannot be set", p.dotted()));
                    };
                    let tool = &mut st.tools[k];
                    if b == ParBlock::PtMeasPar && !tool.can_measure {
                        return fail(ErrorCode::BAD_CONTEXT, format!("{} has no PtMeasPar", tool.name));
                    }
                    let pv = tool
                        .param_mut(b, param)
                        .ok_or((ErrorCode::BAD_PROPERTY, format!("unknown property {}", p.dotted())))?;
                    if !(pv.min..=pv.max).contains(v) {
                        return fail(
                            ErrorCode::ARGUMENT_OUT_OF_RANGE,
                            format!("{} = {v} outside {}..{}", p.dotted(), pv.min, pv.max),
                        );
                    }
                    pv.act = *v;
                }
            }
            Command::EnumProp(p) | Command::EnumAllProp(p) => {
                let all = matches!(cmd, Command::EnumAllProp(_));
                let t = resolve_tool(st, p)?;
                for line in enum_props(t, p, all)? {
                    out.push(data(line));
                }
            }
            Command::ReQualify => {
                self.measuring_tool(st, "cannot be qualified")?;
                // The virtual stylus is exact: its qualification is its nominal geometry.
            }
            Command::AlignTool { dir, alpha_deg, second } => {
                self.check_homed(st)?;
                // A fixed vertical stylus: the tool axis is +Z, its second axis +X. Report them if
                // they are within the requested tolerances, otherwise the angle is out of range.
                let within = |v: &[f64; 3], actual: Vector3, tol: f64| {
                    let v = Vector3::new(v[0], v[1], v[2]);
                    v.dot(&actual).clamp(-1.0, 1.0).acos().to_degrees() <= tol.abs() + 1e-9
                };
                if !within(dir, dir_to_csy(st, &Vector3::z()), *alpha_deg)
                    || second.as_ref().is_some_and(|(v, b)| !within(v, dir_to_csy(st, &Vector3::x()), *b))
                {
                    return fail(ErrorCode::ANGLE_OUT_OF_RANGE, "this CMM has a fixed stylus (tool axis +Z)");
                }
                let z = dir_to_csy(st, &Vector3::z());
                let mut s = format!("({}, {}, {}", fmt_num(z.x), fmt_num(z.y), fmt_num(z.z));
                if second.is_some() {
                    let x = dir_to_csy(st, &Vector3::x());
                    let _ = write!(s, ", {}, {}, {}", fmt_num(x.x), fmt_num(x.y), fmt_num(x.z));
                }
                s.push(')');
                out.push(data(s));
            }
            _ => unreachable!("execute routes only tool commands here"),
        }
        Ok(())
    }

    /// Coordinate systems and their transformations.
    fn csy_command(
        &mut self,
        tag: Tag,
        cmd: &Command,
        st: &mut MachineState<M>,
        out: &mut Vec<Response>,
    ) -> Answer {
        let data = |s: String| Response::data(tag, s);
        match cmd {
            Command::GetCoordSystem => out.push(data(format!("CoordSystem({})", st.csy.name()))),
            Command::SetCoordSystem(c) => {
                st.csy = *c;
                self.after_move_forced(st, out);
            }
            Command::GetCsyTransformation(t) => {
                let v = st.transforms[t.index()];
                out.push(data(format!(
                    "GetCsyTransformation({})",
                    v.iter().map(|x| fmt_num(*x)).collect::<Vec<_>>().join(", ")
                )));
            }
            Command::SetCsyTransformation(t, v) => {
                let mut v = *v;
                v[4] = v[4].rem_euclid(360.0);
                v[5] = v[5].rem_euclid(360.0);
                st.transforms[t.index()] = v;
            }
            _ => unreachable!("execute routes only csy commands here"),
        }
        Ok(())
    }

    /// Part alignment on the rotary table (`AlignPart`, `CenterPart`, `TiltPart`, `TiltCenterPart`).
    fn part_command(
        &mut self,
        tag: Tag,
        cmd: &Command,
        st: &mut MachineState<M>,
        out: &mut Vec<Response>,
    ) -> Answer {
        let data = |s: String| Response::data(tag, s);
        match cmd {
            Command::AlignPart { part, machine, alpha_deg, second } => {
                let (_, axis) = self.homed_table(st, "AlignPart")?;
                // Both vectors projected into the table plane; they must not lie along the axis.
                let project = |v: [f64; 3], what: &str| {
                    let no_norm = (
                        ErrorCode::VECTOR_HAS_NO_NORM,
                        format!("AlignPart: the {what} vector has no length or lies along the table axis"),
                    );
                    let v = unit(v).ok_or_else(|| no_norm.clone())?;
                    (v - axis * v.dot(&axis)).try_normalize(1e-9).ok_or(no_norm)
                };
                let p = project(dir_to_machine(st, &Vector3::from(*part)).into(), "part")?;
                let m = project(*machine, "machine")?;
                let turn = p.cross(&m).dot(&axis).atan2(p.dot(&m));
                // Every check before the table turns: the reached direction is known beforehand.
                let reached = axis_rotation(&axis, turn) * p;
                let err_deg = reached.dot(&m).clamp(-1.0, 1.0).acos().to_degrees();
                if *alpha_deg != 0.0 && err_deg > alpha_deg.abs() {
                    return fail(
                        ErrorCode::PART_NOT_ALIGNED,
                        format!("AlignPart: {err_deg:.4}° from the target"),
                    );
                }
                let angle = st.machine.table_angle() + turn;
                if let Err(e) = st.machine.set_table_angle(angle) {
                    return self.refuse_machine(e);
                }
                let mut s =
                    format!("({}, {}, {}", fmt_num(reached.x), fmt_num(reached.y), fmt_num(reached.z));
                if let Some((p2, _, _)) = second {
                    // A single rotary table: the second pair (a second, perpendicular rotary axis)
                    // cannot be acted on; its part vector is reported where the table put it.
                    let v = axis_rotation(&axis, turn) * dir_to_machine(st, &Vector3::from(*p2));
                    let _ = write!(s, ", {}, {}, {}", fmt_num(v.x), fmt_num(v.y), fmt_num(v.z));
                }
                s.push(')');
                out.push(data(s));
            }
            Command::CenterPart { point, limit } => {
                let (o, axis) = self.homed_table(st, "CenterPart")?;
                let p = to_machine(st, &Point3::from(*point));
                if !in_volume(st, &p) {
                    return self.refuse(
                        ErrorCode::OUT_OF_VOLUME,
                        format!(
                            "CenterPart: the centre {:?} (machine) is outside the machine volume",
                            p.coords.as_slice()
                        ),
                    );
                }
                let (d, radial) = off_axis(&p, &o, &axis);
                let moved = d >= *limit;
                if moved {
                    if let Err(e) = st.machine.move_part(Matrix3::identity(), o, -radial) {
                        return self.refuse_machine(e);
                    }
                }
                out.push(data(format!("CenterPart({})", (!moved) as u8)));
            }
            Command::TiltPart { dir, limit } => {
                let (o, axis) = self.homed_table(st, "TiltPart")?;
                let d = direction(*dir, "TiltPart direction")?;
                let mut d = dir_to_machine(st, &d);
                if d.dot(&axis) < 0.0 {
                    d = -d;
                }
                // Deviation over a base length of 100 mm.
                let dev = 100.0 * d.cross(&axis).norm();
                let moved = dev >= *limit;
                if moved {
                    if let Err(e) = st.machine.move_part(rotation_between(&d, &axis), o, Vector3::zeros()) {
                        return self.refuse_machine(e);
                    }
                }
                out.push(data(format!("TiltPart({})", (!moved) as u8)));
            }
            Command::TiltCenterPart { first, second, limit } => {
                let (o, axis) = self.homed_table(st, "TiltCenterPart")?;
                let p1 = to_machine(st, &Point3::from(*first));
                let p2 = to_machine(st, &Point3::from(*second));
                if !in_volume(st, &p1) || !in_volume(st, &p2) {
                    return self.refuse(
                        ErrorCode::OUT_OF_VOLUME,
                        "TiltCenterPart: a centre is outside the machine volume".to_string(),
                    );
                }
                let mut d = (p2 - p1).try_normalize(1e-9).ok_or((
                    ErrorCode::INCORRECT_ARGUMENTS,
                    "TiltCenterPart: the two centres coincide".to_string(),
                ))?;
                if d.dot(&axis) < 0.0 {
                    d = -d;
                }
                let (d1, _) = off_axis(&p1, &o, &axis);
                let (d2, _) = off_axis(&p2, &o, &axis);
                let moved = d1.max(d2) >= *limit;
                if moved {
                    // Tilt about the first centre until the centres' line is parallel to the
                    // axis, then shift the first centre onto the axis.
                    let (_, radial) = off_axis(&p1, &o, &axis);
                    if let Err(e) = st.machine.move_part(rotation_between(&d, &axis), p1, -radial) {
                        return self.refuse_machine(e);
                    }
                }
                out.push(data(format!("TiltCenterPart({})", (!moved) as u8)));
            }
            _ => unreachable!("execute routes only part commands here"),
        }
        Ok(())
    }

    /// Scan hints and the three scans (circle, line, unknown contour).
    fn scan_command(
        &mut self,
        tag: Tag,
        cmd: &Command,
        st: &mut MachineState<M>,
        out: &mut Vec<Response>,
    ) -> Answer {
        match cmd {
            Command::ScanOnCircleHint { displacement, form }
            | Command::ScanOnLineHint { angle: displacement, form } => {
                if *displacement < 0.0 || *form < 0.0 {
                    return fail(ErrorCode::ARGUMENT_OUT_OF_RANGE, "hints must not be negative");
                }
            }
            Command::ScanUnknownHint(_) => {}
            Command::ScanOnCircle { center, start, normal, delta_deg, sfa_deg, step_deg } => {
                let tool = self.measuring_tool(st, "cannot measure")?;
                let axis = direction(*normal, "circle normal")?;
                let c = Point3::from(*center);
                let s = Point3::from(*start);
                let radial = s - c;
                let radius = radial.norm();
                if radius < 1e-9 {
                    return fail(ErrorCode::INCORRECT_ARGUMENTS, "start point on the centre");
                }
                if radial.dot(&axis).abs() > 1e-6 * radius.max(1.0) {
                    return fail(
                        ErrorCode::INCORRECT_ARGUMENTS,
                        "the radius is not perpendicular to the normal",
                    );
                }
                if delta_deg.abs() < 1e-12 {
                    return fail(ErrorCode::INCORRECT_ARGUMENTS, "delta is zero");
                }
                let (c_m, s_m, axis_m) = (to_machine(st, &c), to_machine(st, &s), dir_to_machine(st, &axis));
                scan_in_volume(st, &[c_m, s_m])?;
                let u = (s_m - c_m).normalize();
                let sfa = sfa_deg.to_radians();
                let n0 = (u * sfa.cos() + axis_m * sfa.sin()).normalize();
                let path = ScanPath::Circle {
                    center: c_m,
                    axis: axis_m,
                    delta_rad: delta_deg.to_radians(),
                    step_rad: step_deg.abs().to_radians(),
                };
                self.run_scan(tag, st, &tool, s_m, n0, &path, out)?;
            }
            Command::ScanOnLine { start, end, normal, step_mm } => {
                let tool = self.measuring_tool(st, "cannot measure")?;
                let n = direction(*normal, "surface normal")?;
                let (s, e) = (Point3::from(*start), Point3::from(*end));
                let len = (e - s).norm();
                if len < 1e-9 {
                    return fail(ErrorCode::INCORRECT_ARGUMENTS, "start and end point are the same");
                }
                if (e - s).dot(&n).abs() > 1e-6 * len.max(1.0) {
                    return fail(
                        ErrorCode::INCORRECT_ARGUMENTS,
                        "the normal is not perpendicular to the line",
                    );
                }
                let (s_m, e_m, n_m) = (to_machine(st, &s), to_machine(st, &e), dir_to_machine(st, &n));
                scan_in_volume(st, &[s_m, e_m])?;
                let path = ScanPath::Line { direction: (e_m - s_m) / len, length_mm: len, step_mm: *step_mm };
                self.run_scan(tag, st, &tool, s_m, n_m, &path, out)?;
            }
            Command::ScanUnknown(kind, args) => {
                let u = unknown_scan(*kind, args)?;
                for p in [&u.start, &u.direction_point].into_iter().chain(u.stop_point.as_ref()) {
                    if !in_volume(st, &to_machine(st, p)) {
                        return fail(ErrorCode::OUT_OF_VOLUME, "scan point outside the machine volume");
                    }
                }
                let tool = self.measuring_tool(st, "cannot measure")?;
                // Everything to machine coordinates.
                let pm = |p: &Point3| to_machine(st, p);
                let vm = |v: &Vector3| dir_to_machine(st, v);
                let s_m = pm(&u.start);
                let guide = match u.guide {
                    Guide::Plane { normal } => Guide::Plane { normal: vm(&normal) },
                    Guide::Cylinder { point, axis } => Guide::Cylinder { point: pm(&point), axis: vm(&axis) },
                };
                let stop = match u.stop {
                    Stop::Sphere { center, radius, count } => {
                        Stop::Sphere { center: pm(&center), radius, count }
                    }
                    Stop::Plane { point, normal, count, arm_mm } => {
                        Stop::Plane { point: pm(&point), normal: vm(&normal), count, arm_mm }
                    }
                    Stop::Cylinder { point, axis, radius, count } => {
                        Stop::Cylinder { point: pm(&point), axis: vm(&axis), radius, count }
                    }
                };
                let (lo, hi) = st.machine.volume();
                let path = ScanPath::Contour {
                    guide,
                    toward: pm(&u.direction_point) - s_m,
                    step_mm: u.step_mm,
                    stop,
                    max_length_mm: 4.0 * (hi - lo).norm(),
                };
                let n_m = vm(&u.surface_normal);
                self.run_scan(tag, st, &tool, s_m, n_m, &path, out)?;
            }
            _ => unreachable!("execute routes only scan commands here"),
        }
        Ok(())
    }

    fn run_scan(
        &mut self,
        tag: Tag,
        st: &mut MachineState<M>,
        tool: &Tool,
        start_m: Point3,
        n_m: Vector3,
        path: &ScanPath,
        out: &mut Vec<Response>,
    ) -> Answer {
        self.user_enabled = false;
        if st.locked.iter().any(|l| *l) {
            return fail(
                ErrorCode::UNABLE_TO_MOVE,
                "the virtual CMM cannot scan with a locked axis (ChangeTool unlocks)",
            );
        }
        // Size, length and machine time are checked on the nominal path before anything moves.
        let nominal = Contact { tip_center_mm: start_m + n_m * tool.radius_mm, normal: n_m };
        if let Err(e) = st.machine.check_scan(nominal, path, tool.radius_mm) {
            return self.refuse_machine(e);
        }
        let before = st.machine.position();
        let first = ptmeas(st, tool, start_m, n_m, 0.0);
        let first = match first {
            Ok(c) => c,
            Err(e) => {
                self.after_move(st, out);
                return Err(e);
            }
        };
        let mut pts: Vec<ScanPoint> = Vec::new();
        let res = st.machine.scan(first, path, tool.radius_mm, &mut pts);
        if let Some(note) = st.machine.take_note() {
            self.notes.push(format!("{tag}: {note}"));
        }
        // Leave the surface along the last normal by the PtMeas retract distance.
        if let Some(last) = pts.last() {
            let r = tool.ptmeas(Param::Retract).max(0.0);
            let _ = st.machine.move_to(last.tip_center_mm + last.normal * r, 0.0);
        } else if res.is_err() {
            // Refused at the start it measured (the nominal start passed the check): undo the
            // approach the way it came, to the approach point and to where the command found
            // the machine, so a refused scan leaves the machine where it was.
            let approach = start_m + n_m * (tool.ptmeas(Param::Approach) + tool.radius_mm);
            let _ = st.machine.move_to(approach, 0.0);
            let _ = st.machine.move_to(before, 0.0);
        }
        self.after_move(st, out);
        if let Err(e) = res {
            return self.refuse_machine(e);
        }
        let (r, t) = csy_transform(st);
        let mut line = String::with_capacity(SCAN_POINTS_PER_LINE * 40);
        for chunk in pts.chunks(SCAN_POINTS_PER_LINE) {
            line.clear();
            for (i, p) in chunk.iter().enumerate() {
                if i > 0 {
                    line.push(',');
                }
                let pc = Point3::from(r * p.tip_center_mm.coords + t);
                let nc = r * p.normal;
                report_values(
                    &self.scan_keys,
                    &pc,
                    &nc,
                    tool.radius_mm,
                    p.quality,
                    table_deg(st),
                    false,
                    &mut line,
                );
            }
            out.push(Response::data(tag, line.clone()));
        }
        Ok(())
    }

    /// A report of the move daemon if it is due.
    fn after_move(&mut self, st: &MachineState<M>, out: &mut Vec<Response>) {
        self.report_move(st, out, false);
    }

    fn after_move_forced(&mut self, st: &MachineState<M>, out: &mut Vec<Response>) {
        self.report_move(st, out, true);
    }

    fn report_move(&mut self, st: &MachineState<M>, out: &mut Vec<Response>, forced: bool) {
        let Some(d) = &mut self.daemon else { return };
        let pos = st.machine.position();
        let elapsed = d.last_report.elapsed().as_secs_f64();
        let moved = (pos - d.last_pos).norm();
        // At most 10 reports per second (specification 6.3.2.7).
        if elapsed < 0.1 || (moved == 0.0 && !forced) {
            return;
        }
        let due = forced
            || match (d.time_s, d.dis_mm) {
                (None, None) => true,
                (t, dis) => t.is_some_and(|t| elapsed >= t) || dis.is_some_and(|dd| moved >= dd),
            };
        if !due || d.keys.is_empty() {
            return;
        }
        let mut s = String::new();
        report_values(&d.keys, &to_csy(st, &pos), &Vector3::zeros(), 0.0, 0.0, table_deg(st), true, &mut s);
        out.push(Response::data(d.tag, s));
        d.last_report = Instant::now();
        d.last_pos = pos;
    }
}

/// An unknown-contour scan command, checked (active csy coordinates).
struct UnknownScanArgs {
    start: Point3,
    surface_normal: Vector3,
    direction_point: Point3,
    step_mm: f64,
    guide: Guide,
    stop: Stop,
    stop_point: Option<Point3>,
}

/// Read the argument list of an unknown-contour scan: the layouts of I++ DME 1.4 (the NIST
/// suite's) and of 1.4.3 (which adds the scan-plane normal and the sphere's count `n`).
fn unknown_scan(kind: UnknownScan, a: &[f64]) -> Result<UnknownScanArgs, (ErrorCode, String)> {
    let p3 = |k: usize| Point3::new(a[k], a[k + 1], a[k + 2]);
    let v3 = |k: usize, what: &str| direction([a[k], a[k + 1], a[k + 2]], format!("{what} has no length"));
    let positive = |k: usize, what: &str| {
        if a[k] > 0.0 {
            Ok(a[k])
        } else {
            fail(ErrorCode::INCORRECT_ARGUMENTS, format!("{what} must be positive"))
        }
    };
    let count = |k: usize| {
        if a[k] >= 1.0 && a[k].fract() == 0.0 && a[k] <= 1e6 {
            Ok(a[k] as u32)
        } else {
            fail(ErrorCode::INCORRECT_ARGUMENTS, "the count n must be a whole number ≥ 1")
        }
    };
    // Leading part: in-plane: S, Si, [N], D, StepW; in-cylinder: C, Ci, S, Si, D, StepW.
    let in_cyl = matches!(kind, UnknownScan::InCylEndIsSphere | UnknownScan::InCylEndIsPlane);
    let with_n = match kind {
        UnknownScan::InPlaneEndIsSphere => a.len() == 21,
        UnknownScan::InPlaneEndIsPlane => a.len() == 23,
        UnknownScan::InPlaneEndIsCyl => a.len() == 24,
        _ => false,
    };
    let (start, si, d, step, guide, rest) = if in_cyl {
        let c = p3(0);
        let ci = v3(3, "the cylinder axis")?;
        let s = p3(6);
        let si = v3(9, "the start direction")?;
        let d = p3(12);
        let rel = s - c;
        if (rel - ci * rel.dot(&ci)).norm() < 1e-9 {
            return fail(ErrorCode::INCORRECT_ARGUMENTS, "the start point is on the cylinder axis");
        }
        (s, si, d, positive(15, "StepW")?, Guide::Cylinder { point: c, axis: ci }, 16)
    } else {
        let s = p3(0);
        let si = v3(3, "the start direction")?;
        let (n, k) = if with_n { (Some(v3(6, "the scan-plane normal")?), 9) } else { (None, 6) };
        let d = p3(k);
        let normal = match n {
            Some(n) => n,
            None => si.cross(&(d - s)).try_normalize(1e-12).ok_or((
                ErrorCode::INCORRECT_ARGUMENTS,
                "the direction point is along the start direction".to_string(),
            ))?,
        };
        (s, si, d, positive(k + 3, "StepW")?, Guide::Plane { normal }, k + 4)
    };
    if (d - start).norm() < 1e-9 {
        return fail(ErrorCode::INCORRECT_ARGUMENTS, "the start point equals the direction point");
    }
    let r = rest;
    let (stop, stop_point, end_dir) = match kind {
        UnknownScan::InPlaneEndIsSphere | UnknownScan::InCylEndIsSphere => {
            let has_n = with_n || (in_cyl && a.len() == 24);
            let n = if has_n { count(r + 4)? } else { 1 };
            let e = r + 4 + usize::from(has_n);
            let center = p3(r);
            (Stop::Sphere { center, radius: positive(r + 3, "Dia")? / 2.0, count: n }, Some(center), e)
        }
        UnknownScan::InPlaneEndIsPlane | UnknownScan::InCylEndIsPlane => {
            let normal = v3(r + 3, "the stop-plane normal")?;
            let arm = (d - start).norm();
            (Stop::Plane { point: p3(r), normal, count: count(r + 6)?, arm_mm: arm }, None, r + 7)
        }
        UnknownScan::InPlaneEndIsCyl => {
            let axis = v3(r + 3, "the stop-cylinder axis")?;
            let radius = positive(r + 6, "d")? / 2.0;
            (Stop::Cylinder { point: p3(r), axis, radius, count: count(r + 7)? }, None, r + 8)
        }
    };
    v3(end_dir, "the end direction")?;
    Ok(UnknownScanArgs {
        start,
        surface_normal: si,
        direction_point: d,
        step_mm: step,
        guide,
        stop,
        stop_point,
    })
}

/// The PtMeas cycle in machine coordinates (specification 6.3.2.13): approach point, search to
/// the end of search, latch, retract (`retract < 0`: back to the approach point).
fn ptmeas<M: Cmm>(
    st: &mut MachineState<M>,
    tool: &Tool,
    p: Point3,
    n: Vector3,
    retract: f64,
) -> Result<Contact, (ErrorCode, String)> {
    let r = tool.radius_mm;
    let mut start = p + n * (tool.ptmeas(Param::Approach) + r);
    let mut end = p + n * (r - tool.ptmeas(Param::Search));
    if !in_volume(st, &start) || !in_volume(st, &p) {
        return fail(ErrorCode::OUT_OF_VOLUME, format!("PtMeas approach point {start:?} outside the volume"));
    }
    // Locked axes (LockAxis) do not move: the cycle runs in the unlocked ones.
    let now = st.machine.position();
    let locked = st.locked;
    let keep = |mut q: Point3| {
        for k in 0..3 {
            if locked[k] {
                q[k] = now[k];
            }
        }
        q
    };
    start = keep(start);
    end = keep(end);
    if (end - start).norm() < 1e-9 {
        return fail(ErrorCode::UNABLE_TO_MOVE, "the probing direction lies in the locked axes");
    }
    st.machine.move_to(start, r).map_err(machine_error)?;
    match st.machine.probe(start, end, r, p, n).map_err(machine_error)? {
        Some(c) => {
            let back = keep(if retract >= 0.0 { c.tip_center_mm + n * retract } else { start });
            st.machine.move_to(back, r).map_err(machine_error)?;
            Ok(c)
        }
        None => {
            let _ = st.machine.move_to(start, r);
            fail(ErrorCode::SURFACE_NOT_FOUND, "no contact within the search distance")
        }
    }
}

fn find_tool<M>(st: &MachineState<M>, name: &str) -> Result<usize, (ErrorCode, String)> {
    if name == "UnDefTool" {
        return fail(ErrorCode::TOOL_NOT_DEFINED, "UnDefTool cannot be selected");
    }
    st.tools.iter().position(|t| t.name == name).ok_or((ErrorCode::TOOL_NOT_FOUND, format!("no tool {name}")))
}

fn resolve_tool<'a, M>(st: &'a MachineState<M>, p: &PropPath) -> Result<&'a Tool, (ErrorCode, String)> {
    let k = match p.tool {
        ToolRef::Tool => st.tool,
        ToolRef::FoundTool => {
            st.found_tool.ok_or((ErrorCode::BAD_CONTEXT, "no FindTool() yet".to_string()))?
        }
    };
    let t = &st.tools[k];
    let uses_ptmeas =
        matches!(p.item, PropItem::Block(ParBlock::PtMeasPar) | PropItem::Value(ParBlock::PtMeasPar, _, _));
    if uses_ptmeas && !t.can_measure {
        return fail(ErrorCode::BAD_CONTEXT, format!("{} has no PtMeasPar", t.name));
    }
    Ok(t)
}

fn prop_value(t: &Tool, p: &PropPath) -> Result<String, (ErrorCode, String)> {
    Ok(match p.item {
        PropItem::Name => format!("\"{}\"", t.name),
        PropItem::Id => format!("\"{}\"", t.name),
        PropItem::AvrRadius => fmt_num(t.radius_mm),
        PropItem::Alignment => "0.000000, 0.000000, 1.000000".into(),
        PropItem::CollisionVolume => {
            // The stylus as an oriented box: ball and shank, 50 mm long, above the tip centre.
            let w = (2.0 * t.radius_mm).max(1.0);
            format!("OBB, 0.000000, 0.000000, 25.000000, {w:.6}, {w:.6}, 50.000000, 1,0,0, 0,1,0, 0,0,1")
        }
        PropItem::Value(b, param, f) => {
            let v = t
                .param(b, param)
                .ok_or((ErrorCode::BAD_PROPERTY, format!("unknown property {}", p.dotted())))?;
            fmt_num(v.field(f.unwrap_or(Field::Act)))
        }
        PropItem::Root | PropItem::Block(_) => {
            return fail(ErrorCode::BAD_PROPERTY, format!("{} is not a value", p.dotted()))
        }
    })
}

fn enum_props(t: &Tool, p: &PropPath, all: bool) -> Result<Vec<String>, (ErrorCode, String)> {
    let mut out = Vec::new();
    let block_name = |b: ParBlock| if b == ParBlock::GoToPar { "GoToPar" } else { "PtMeasPar" };
    let param_lines = |out: &mut Vec<String>, b: ParBlock, all: bool| {
        for prm in Param::of(b) {
            out.push(format!("\"{}\", \"Property\"", prm.name()));
            if all {
                for f in Field::ALL {
                    out.push(format!("\"{}\", \"Number\"", f.name()));
                }
            }
        }
    };
    match p.item {
        PropItem::Root => {
            let blocks: &[ParBlock] =
                if t.can_measure { &[ParBlock::GoToPar, ParBlock::PtMeasPar] } else { &[ParBlock::GoToPar] };
            for b in blocks {
                out.push(format!("\"{}\", \"Property\"", block_name(*b)));
                if all {
                    param_lines(&mut out, *b, true);
                }
            }
            out.push("\"Name\", \"String\"".into());
            out.push("\"Id\", \"String\"".into());
            out.push("\"AvrRadius\", \"Number\"".into());
        }
        PropItem::Block(b) => param_lines(&mut out, b, all),
        PropItem::Value(_, _, None) => {
            for f in Field::ALL {
                out.push(format!("\"{}\", \"Number\"", f.name()));
            }
        }
        PropItem::Value(_, _, Some(_)) => {}
        _ => return fail(ErrorCode::BAD_PROPERTY, format!("{} has no properties", p.dotted())),
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Logging

/// Appends `<ISO time> < line` / `> line` to the `--log` file; bytes outside printable ASCII are
/// written as `\xNN`. The log is flushed after every batch of answers.
///
/// **Failure rule**: the first write or flush that fails (a full disk, a file-size limit, an
/// I/O error) is reported once, naming the file and the error (on stderr by default, see
/// [`Log::with_reporter`]); logging then stops for the server's life and the server keeps
/// serving (a running measurement program is not cut off by its log). Lines are never lost
/// silently: the report says from when on the log is incomplete.
pub struct Log {
    out: Mutex<LogState>,
    path: String,
    report: Box<dyn Fn(&str) + Send + Sync>,
}

struct LogState {
    file: BufWriter<std::fs::File>,
    failed: bool,
}

fn iso_now() -> String {
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    truepos_math::time::UtcDateTime::from_unix(now.as_secs() as i64).iso8601_millis(now.subsec_millis())
}

/// `bytes` with everything outside printable ASCII as `\xNN` (and `\` itself as `\x5C`).
pub fn escape_bytes(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len());
    for &b in bytes {
        if (0x20..=0x7e).contains(&b) && b != b'\\' {
            s.push(b as char);
        } else {
            let _ = write!(s, "\\x{b:02X}");
        }
    }
    s
}

impl Log {
    /// Open `path` for appending; a failure later is reported on stderr.
    pub fn open(path: &Path) -> io::Result<Log> {
        Log::with_reporter(path, |m| eprintln!("{m}"))
    }
    /// Open `path` for appending; `report` gets the one message about the first failure.
    pub fn with_reporter(path: &Path, report: impl Fn(&str) + Send + Sync + 'static) -> io::Result<Log> {
        let f = std::fs::OpenOptions::new().create(true).append(true).open(path)?;
        Ok(Log {
            out: Mutex::new(LogState { file: BufWriter::new(f), failed: false }),
            path: path.display().to_string(),
            report: Box::new(report),
        })
    }
    fn lock(&self) -> MutexGuard<'_, LogState> {
        self.out.lock().unwrap_or_else(|e| e.into_inner())
    }
    /// Record the first failure and report it; later calls do nothing.
    fn failed(&self, st: &mut LogState, e: &io::Error) {
        if !st.failed {
            st.failed = true;
            (self.report)(&format!(
                "ippdme: --log {}: cannot write the session log ({e}); logging stopped at {}, the server keeps serving",
                self.path,
                iso_now()
            ));
        }
    }
    fn write(&self, dir: char, bytes: &[u8]) {
        let mut st = self.lock();
        if st.failed {
            return;
        }
        if let Err(e) = writeln!(st.file, "{} {dir} {}", iso_now(), escape_bytes(bytes)) {
            self.failed(&mut st, &e);
        }
    }
    /// A line received from the client.
    pub fn received(&self, bytes: &[u8]) {
        self.write('<', bytes);
    }
    /// A line sent to the client.
    pub fn sent(&self, line: &str) {
        self.write('>', line.as_bytes());
    }
    /// A note about the connection (connect, refusal, disconnect, bad input).
    pub fn note(&self, text: &str) {
        self.write('#', text.as_bytes());
    }
    /// Flush what was logged to the file.
    pub fn flush(&self) {
        let mut st = self.lock();
        if st.failed {
            return;
        }
        if let Err(e) = st.file.flush() {
            self.failed(&mut st, &e);
        }
    }
    /// Whether a write failed (logging has stopped).
    pub fn has_failed(&self) -> bool {
        self.lock().failed
    }
}

// ---------------------------------------------------------------------------------------------
// TCP

/// The TCP server.
pub struct Server<M> {
    listener: TcpListener,
    shared: Arc<Shared<M>>,
    log: Option<Arc<Log>>,
    busy: Arc<AtomicBool>,
    write_timeout: Duration,
}

/// A server running on a background thread.
pub struct ServerHandle<M> {
    /// The address the server listens on.
    pub addr: SocketAddr,
    /// The machine and settings shared with the server's connections.
    pub shared: Arc<Shared<M>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<()>>>,
}

impl<M> ServerHandle<M> {
    /// Stop accepting and wait for the accept loop (a connected client's thread ends when it
    /// disconnects).
    pub fn shutdown(mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl<M> Drop for ServerHandle<M> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl<M: Cmm + 'static> Server<M> {
    /// Bind to `addr` (e.g. `127.0.0.1:1294`; port 0 picks a free one).
    pub fn bind(addr: &str, machine: M, config: &MachineConfig, log: Option<Log>) -> io::Result<Server<M>> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        Ok(Server {
            listener,
            shared: Arc::new(Shared::new(machine, config)),
            log: log.map(Arc::new),
            busy: Arc::new(AtomicBool::new(false)),
            write_timeout: DEFAULT_WRITE_TIMEOUT,
        })
    }

    /// Drop a client that does not take each 64 KiB of its answers within `timeout` (default
    /// [`DEFAULT_WRITE_TIMEOUT`]; at least 1 ms).
    pub fn with_write_timeout(mut self, timeout: Duration) -> Self {
        self.write_timeout = timeout.max(Duration::from_millis(1));
        self
    }

    /// The address the listener is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// The machine and settings shared by the connections.
    pub fn shared(&self) -> Arc<Shared<M>> {
        Arc::clone(&self.shared)
    }

    /// Accept clients until `stop` is set. One client is served at a time; others are refused.
    pub fn run(&self, stop: &AtomicBool) -> io::Result<()> {
        while !stop.load(Ordering::SeqCst) {
            match self.listener.accept() {
                Ok((stream, peer)) => self.accept(stream, peer),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted => {
                    std::thread::sleep(Duration::from_millis(10));
                }
                Err(e)
                    if e.kind() == io::ErrorKind::ConnectionAborted
                        || e.kind() == io::ErrorKind::ConnectionReset => {}
                Err(e) => return Err(e),
            }
        }
        if let Some(l) = &self.log {
            l.flush();
        }
        Ok(())
    }

    /// Run on a background thread.
    pub fn spawn(self) -> io::Result<ServerHandle<M>> {
        let addr = self.local_addr()?;
        let shared = self.shared();
        let stop = Arc::new(AtomicBool::new(false));
        let s2 = Arc::clone(&stop);
        let thread = std::thread::Builder::new().name("ippdme-accept".into()).spawn(move || self.run(&s2))?;
        Ok(ServerHandle { addr, shared, stop, thread: Some(thread) })
    }

    fn accept(&self, stream: TcpStream, peer: SocketAddr) {
        let _ = stream.set_nonblocking(false);
        let _ = stream.set_nodelay(true);
        if self.busy.swap(true, Ordering::SeqCst) {
            let line = Response::error(Tag::SERVER_EVENT, ErrorCode::PROTOCOL_ERROR, "Connect").format();
            if let Some(l) = &self.log {
                l.note(&format!("refused {peer}: another client is connected"));
                l.sent(&line);
                l.flush();
            }
            let mut s = &stream;
            let _ = stream.set_write_timeout(Some(Duration::from_secs(1)));
            let _ = s.write_all(format!("{line}\r\n").as_bytes());
            let _ = stream.shutdown(Shutdown::Both);
            return;
        }
        let shared = Arc::clone(&self.shared);
        let log = self.log.clone();
        let busy = Arc::clone(&self.busy);
        let write_timeout = self.write_timeout;
        let spawned = std::thread::Builder::new().name(format!("ippdme-{peer}")).spawn(move || {
            if let Some(l) = &log {
                l.note(&format!("connected {peer}"));
            }
            let why = serve_connection(stream, shared, log.as_deref(), write_timeout);
            if let Some(l) = &log {
                l.note(&format!("disconnected {peer}: {why}"));
                l.flush();
            }
            busy.store(false, Ordering::SeqCst);
        });
        if spawned.is_err() {
            self.busy.store(false, Ordering::SeqCst);
        }
    }
}

/// How long the server waits for a client to take each 64 KiB of answers before it drops the
/// client (`truepos ippdme serve --write-timeout-s`): a client that stops reading its replies
/// cannot hold the only connection for longer. Reading has no timeout: a client that sends
/// nothing keeps its session (a program may wait for an operator).
pub const DEFAULT_WRITE_TIMEOUT: Duration = Duration::from_secs(10);

/// Bytes of answers sent in one piece, each within the write timeout.
const SEND_CHUNK: usize = 1 << 16;

/// Send `bytes`, each [`SEND_CHUNK`] of them within `timeout` (a deadline per chunk, however the
/// socket splits it): a client that reads nothing, or trickles, fails with `TimedOut`.
fn send_within(stream: &TcpStream, bytes: &[u8], timeout: Duration) -> io::Result<()> {
    let mut s = stream;
    for chunk in bytes.chunks(SEND_CHUNK) {
        let deadline = Instant::now() + timeout;
        let mut rest = chunk;
        while !rest.is_empty() {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    format!("the client took no answers for {:.3} s (write timeout)", timeout.as_secs_f64()),
                ));
            }
            // Zero would mean "no timeout" to the socket.
            stream.set_write_timeout(Some(left.max(Duration::from_millis(1))))?;
            match s.write(rest) {
                Ok(0) => return Err(io::Error::new(io::ErrorKind::WriteZero, "the client closed")),
                Ok(n) => rest = &rest[n..],
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::TimedOut => {}
                Err(e) => return Err(e),
            }
        }
    }
    Ok(())
}

/// Serve one connection until it closes; returns why it ended. Answers are dropped with the
/// client when it does not take them within `write_timeout` ([`DEFAULT_WRITE_TIMEOUT`]).
pub fn serve_connection<M: Cmm>(
    stream: TcpStream,
    shared: Arc<Shared<M>>,
    log: Option<&Log>,
    write_timeout: Duration,
) -> String {
    let Ok(read_half) = stream.try_clone() else { return "cannot clone the socket".into() };
    let mut reader = LineReader::new(read_half);
    let mut pending: Vec<u8> = Vec::with_capacity(SEND_CHUNK);
    let mut session = Session::new(shared);
    let mut out = Vec::new();
    let why = loop {
        let line = match reader.read_line() {
            Ok(ReadLine::Line(l)) => l,
            Ok(ReadLine::Eof) => break "the client closed the connection".to_string(),
            Ok(ReadLine::TooLong) => {
                let r = Response::error(Tag::SERVER_EVENT, ErrorCode::BUFFER_FULL, "Read").format();
                if let Some(l) = log {
                    l.note("a line longer than 64 KiB: closing");
                    l.sent(&r);
                }
                pending.extend_from_slice(format!("{r}\r\n").as_bytes());
                let _ = send_within(&stream, &pending, write_timeout);
                pending.clear();
                drain(reader.get_ref());
                break "line over 64 KiB".to_string();
            }
            Err(e) => break format!("read error: {e}"),
        };
        if let Some(l) = log {
            l.received(&line);
        }
        out.clear();
        let flow = session.handle_line(&line, &mut out);
        if let Some(l) = log {
            for n in session.notes.drain(..) {
                l.note(&n);
            }
        } else {
            session.notes.clear();
        }
        let mut failed = None;
        for r in &out {
            let text = r.format();
            if let Some(l) = log {
                l.sent(&text);
            }
            pending.extend_from_slice(text.as_bytes());
            pending.extend_from_slice(b"\r\n");
            if pending.len() >= SEND_CHUNK {
                if let Err(e) = send_within(&stream, &pending, write_timeout) {
                    failed = Some(e);
                    break;
                }
                pending.clear();
            }
        }
        // Send when the client has nothing more queued (keeps pipelined batches fast).
        if failed.is_none() && !reader.has_buffered_line() {
            if let Err(e) = send_within(&stream, &pending, write_timeout) {
                failed = Some(e);
            }
            pending.clear();
            if let Some(l) = log {
                l.flush();
            }
        }
        if let Some(e) = failed {
            break format!("write error: {e}");
        }
        if flow == Flow::Close {
            break "closed by the server".to_string();
        }
    };
    if !pending.is_empty() {
        let _ = send_within(&stream, &pending, write_timeout);
    }
    session.disconnect();
    let _ = stream.shutdown(Shutdown::Both);
    why
}

/// After refusing a line: stop sending, then read and discard what the client is still sending
/// (at most 8 MiB or 2 s), so the close is a clean FIN and the client gets the error line
/// instead of a reset.
fn drain(stream: &TcpStream) {
    let _ = stream.shutdown(Shutdown::Write);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(300)));
    let t0 = Instant::now();
    let mut buf = [0u8; 16384];
    let mut total = 0usize;
    let mut s = stream;
    while total < 8 << 20 && t0.elapsed() < Duration::from_secs(2) {
        match io::Read::read(&mut s, &mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => total += n,
        }
    }
}

/// Whether an answer line is the end of its transaction.
pub fn is_complete(r: &Response) -> bool {
    matches!(r.body, Body::Complete)
}

// ---------------------------------------------------------------------------------------------
// Signals

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// Install SIGINT and SIGTERM handlers that set the returned flag (pass it to [`Server::run`],
/// which then returns and the process can exit 0).
pub fn stop_on_signals() -> &'static AtomicBool {
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGINT, on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t);
    }
    &STOP
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A machine whose every probe touches the ideal plane (no part).
    struct Flat(Point3);

    impl Cmm for Flat {
        fn describe(&self) -> String {
            "flat".into()
        }
        fn volume(&self) -> (Point3, Point3) {
            (Point3::new(-1000.0, -1000.0, -1000.0), Point3::new(1000.0, 1000.0, 1000.0))
        }
        fn home(&mut self) -> Result<Point3, MachineError> {
            self.0 = Point3::new(0.0, 0.0, 500.0);
            Ok(self.0)
        }
        fn position(&self) -> Point3 {
            self.0
        }
        fn move_to(&mut self, t: Point3, _: f64) -> Result<(), MachineError> {
            self.0 = t;
            Ok(())
        }
        fn probe(
            &mut self,
            _: Point3,
            _: Point3,
            r: f64,
            p: Point3,
            n: Vector3,
        ) -> Result<Option<Contact>, MachineError> {
            self.0 = p + n * r;
            Ok(Some(Contact { tip_center_mm: self.0, normal: n }))
        }
        fn scan(
            &mut self,
            start: Contact,
            _: &ScanPath,
            _: f64,
            out: &mut Vec<ScanPoint>,
        ) -> Result<(), MachineError> {
            out.push(ScanPoint { tip_center_mm: start.tip_center_mm, normal: start.normal, quality: 0.0 });
            Ok(())
        }
        fn stop(&mut self) {}
    }

    fn session() -> Session<Flat> {
        Session::new(Arc::new(Shared::new(Flat(Point3::origin()), &MachineConfig::default())))
    }

    fn run(s: &mut Session<Flat>, line: &str) -> Vec<String> {
        let mut out = Vec::new();
        s.handle_line(line.as_bytes(), &mut out);
        out.iter().map(Response::format).collect()
    }

    #[test]
    fn ptmeas_reports_tip_centre_normal_and_radius_in_the_part_csy() {
        let mut s = session();
        for l in [
            "00001 StartSession()",
            "00002 Home()",
            "00003 ChangeTool(\"Probe1\")",
            "00004 OnPtMeasReport(X(), Y(), Z(), IJK(), ER())",
        ] {
            assert_eq!(run(&mut s, l).len(), 2, "{l}");
        }
        let out = run(&mut s, "00005 PtMeas(X(10), Y(0), Z(0), IJK(0, 0, 2))");
        assert_eq!(
            out[1],
            "00005 # X(10.000000), Y(0.000000), Z(1.500000), IJK(0.000000, 0.000000, 1.000000), ER(1.500000)"
        );
        // Part csy shifted by (1, 2, 3) and turned by Phi = 90° about Z: p_csy = R p + t.
        run(&mut s, "00006 SetCsyTransformation(PartCsy, 1, 2, 3, 0, 0, 90)");
        run(&mut s, "00007 SetCoordSystem(PartCsy)");
        let out = run(&mut s, "00008 Get(X(), Y(), Z())");
        // Machine (10, 0, 3.5) after the retract: R·p = (0, -10, 3.5), + t = (1, -8, 6.5).
        assert_eq!(out[1], "00008 # X(1.000000), Y(-8.000000), Z(6.500000)");
        let out = run(&mut s, "00009 PtMeas(X(1), Y(-8), Z(3), IJK(0, 0, 1))");
        assert!(
            out[1].starts_with(
                "00009 # X(1.000000), Y(-8.000000), Z(4.500000), IJK(0.000000, 0.000000, 1.000000)"
            ),
            "{out:?}"
        );
    }

    #[test]
    fn an_absurd_csy_transformation_is_refused_and_changes_nothing() {
        let mut s = session();
        for l in ["00001 StartSession()", "00002 Home()"] {
            assert_eq!(run(&mut s, l).len(), 2, "{l}");
        }
        run(&mut s, "00003 SetCsyTransformation(PartCsy, 1, 2, 3, 0, 0, 90)");
        for l in [
            "00004 SetCsyTransformation(PartCsy, 1e300, 0, 0, 0, 0, 0)",
            "00004 SetCsyTransformation(PartCsy, 0, 1e15, 0, 0, 0, 0)",
            "00004 SetCsyTransformation(PartCsy, 0, 0, 0, 0, 0, 1e300)",
        ] {
            let out = run(&mut s, l);
            assert!(out.iter().any(|r| r.contains("0504")), "{l}: {out:?}");
            run(&mut s, "00005 ClearAllErrors()");
        }
        let out = run(&mut s, "00006 GetCsyTransformation(PartCsy)");
        assert!(out[1].contains("GetCsyTransformation(1.000000, 2.000000, 3.000000,"), "{out:?}");
        // The limit itself is accepted.
        let out = run(&mut s, "00007 SetCsyTransformation(PartCsy, 1e6, -1e6, 0, 0, 0, 0)");
        assert!(!out.iter().any(|r| r.contains(" ! ")), "{out:?}");
    }

    #[test]
    fn error_state_and_clear() {
        let mut s = session();
        assert!(run(&mut s, "00001 Home()")[1].contains("0508"));
        run(&mut s, "00002 StartSession()");
        let out = run(&mut s, "00003 GoTo(X(1))");
        assert_eq!(out, vec!["00003 &", "00003 ! Error(3, 0508, \"GoTo\", \"Bad context\")", "00003 %"]);
        assert!(run(&mut s, "00004 Home()")[1].contains("0514"));
        assert_eq!(run(&mut s, "E0005 GetErrStatusE()")[1], "E0005 # ErrStatus(1)");
        run(&mut s, "00006 ClearAllErrors()");
        assert_eq!(run(&mut s, "00007 Home()"), vec!["00007 &", "00007 %"]);
        // A warning (severity 1) does not need ClearAllErrors.
        assert!(run(&mut s, "00008 SetProp(Tool.GoToPar.Speed(0.5))")[1].contains("Error(1, 0504"));
        assert_eq!(run(&mut s, "00009 IsHomed()")[1], "00009 # IsHomed(1)");
        assert_eq!(run(&mut s, "00010 GetDMEVersion()")[1], "00010 # DMEVersion(\"1.4.3\")");
        assert_eq!(
            run(&mut s, "00011 EnumTools()")[1..4],
            ["00011 # \"RefTool\"", "00011 # \"NoTool\"", "00011 # \"Probe1\""]
        );
    }

    proptest::proptest! {
        #[test]
        fn every_readable_command_is_framed(line in "[0-9]{5} [A-Za-z]{2,12}\\([-+0-9., \"A-Za-z()]{0,30}\\)") {
            let mut s = session();
            run(&mut s, "00001 StartSession()");
            let out = run(&mut s, &line);
            let tag = &line[..5];
            if tag != "00000" {
                proptest::prop_assert_eq!(out.first().cloned(), Some(format!("{tag} &")));
                proptest::prop_assert_eq!(out.last().cloned(), Some(format!("{tag} %")));
            }
        }
        #[test]
        fn garbage_never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
            let mut s = session();
            run(&mut s, "00001 StartSession()");
            let mut out = Vec::new();
            s.handle_line(&bytes, &mut out);
            proptest::prop_assert!(!out.is_empty());
        }
    }
}
