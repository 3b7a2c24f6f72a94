//! Typed I++ DME commands: [`Command::from_call`] checks a parsed [`Call`] against the
//! command's signature (argument count and kind, allowed keys, no duplicates) and returns the
//! typed command or the error the server answers with ([`CommandError`]).
//!
//! [`Command::to_call_string`] formats the commands a client sends.

use crate::protocol::{fmt_num, Arg, Call, ErrorCode, Tag};

/// A reportable quantity (`X()`, `Tool.A()`, `IJK()`, …).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Key {
    /// `X()`: X of the tool centre, mm.
    X,
    /// `Y()`: Y of the tool centre, mm.
    Y,
    /// `Z()`: Z of the tool centre, mm.
    Z,
    /// `R()`: the rotary table's angle, degrees.
    R,
    /// `Tool.A()`: the tool's first angle, degrees.
    ToolA,
    /// `Tool.B()`: the tool's second angle, degrees.
    ToolB,
    /// `Tool.C()`: the tool's third angle, degrees.
    ToolC,
    /// `IJK()`: the surface normal at a probed point.
    Ijk,
    /// `ER()`: the effective tip radius, mm.
    Er,
    /// `Q()`: the quality of a point, 0 (good) to 100 (bad).
    Q,
}

impl Key {
    /// The key's spelling in the protocol (`X`, `Tool.A`, `IJK`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Key::X => "X",
            Key::Y => "Y",
            Key::Z => "Z",
            Key::R => "R",
            Key::ToolA => "Tool.A",
            Key::ToolB => "Tool.B",
            Key::ToolC => "Tool.C",
            Key::Ijk => "IJK",
            Key::Er => "ER",
            Key::Q => "Q",
        }
    }
    fn from_name(s: &str) -> Option<Key> {
        Some(match s {
            "X" => Key::X,
            "Y" => Key::Y,
            "Z" => Key::Z,
            "R" => Key::R,
            "Tool.A" => Key::ToolA,
            "Tool.B" => Key::ToolB,
            "Tool.C" => Key::ToolC,
            "IJK" => Key::Ijk,
            "ER" => Key::Er,
            "Q" => Key::Q,
            _ => return None,
        })
    }
}

/// Coordinate systems selectable with `SetCoordSystem`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Csy {
    /// The machine's own coordinate system.
    MachineCsy,
    /// The machine coordinate system moved by `MoveableMachineCsy`.
    MoveableMachineCsy,
    /// The coordinate system shared by several arms.
    MultipleArmCsy,
    /// The part coordinate system.
    PartCsy,
}

impl Csy {
    /// The name as the protocol spells it.
    pub fn name(self) -> &'static str {
        match self {
            Csy::MachineCsy => "MachineCsy",
            Csy::MoveableMachineCsy => "MoveableMachineCsy",
            Csy::MultipleArmCsy => "MultipleArmCsy",
            Csy::PartCsy => "PartCsy",
        }
    }
}

/// Largest origin component accepted by `SetCsyTransformation`, mm (1 km, far beyond any CMM's
/// volume): a larger one, or a non-finite one, is refused with error 0504 (argument out of
/// range) and the transformation stays as it was. Positions in such a system would not fit the
/// protocol's 16 digits.
pub const MAX_CSY_TRANSLATION_MM: f64 = 1e6;

/// Largest Euler angle magnitude accepted by `SetCsyTransformation`, degrees (non-finite ones
/// are refused too).
pub const MAX_CSY_ANGLE_DEG: f64 = 1e6;

/// Transformations settable with `SetCsyTransformation`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CsyTransform {
    /// From the part coordinate system to the machine's.
    PartCsy,
    /// The frame the jog display shows.
    JogDisplayCsy,
    /// The frame jog moves are along.
    JogMoveCsy,
    /// The sensor's frame.
    SensorCsy,
    /// The movable machine coordinate system's transformation.
    MoveableMachineCsy,
    /// The multiple-arm coordinate system's transformation.
    MultipleArmCsy,
}

impl CsyTransform {
    /// Every transformation, in the order the server stores them.
    pub const ALL: [CsyTransform; 6] = [
        CsyTransform::PartCsy,
        CsyTransform::JogDisplayCsy,
        CsyTransform::JogMoveCsy,
        CsyTransform::SensorCsy,
        CsyTransform::MoveableMachineCsy,
        CsyTransform::MultipleArmCsy,
    ];
    /// The name as the protocol spells it.
    pub fn name(self) -> &'static str {
        match self {
            CsyTransform::PartCsy => "PartCsy",
            CsyTransform::JogDisplayCsy => "JogDisplayCsy",
            CsyTransform::JogMoveCsy => "JogMoveCsy",
            CsyTransform::SensorCsy => "SensorCsy",
            CsyTransform::MoveableMachineCsy => "MoveableMachineCsy",
            CsyTransform::MultipleArmCsy => "MultipleArmCsy",
        }
    }
    /// Position in [`CsyTransform::ALL`].
    pub fn index(self) -> usize {
        CsyTransform::ALL.iter().position(|c| *c == self).unwrap_or(0)
    }
}

/// Which tool a property path starts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ToolRef {
    /// `Tool`: the mounted tool.
    Tool,
    /// `FoundTool`: the tool selected by `FindTool`.
    FoundTool,
}

/// A motion parameter block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParBlock {
    /// `GoToPar`: parameters of moves.
    GoToPar,
    /// `PtMeasPar`: parameters of probing.
    PtMeasPar,
}

/// A parameter inside a block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// `Speed`, mm/s.
    Speed,
    /// `Accel`, mm/s².
    Accel,
    /// `Approach`: approach distance before a probed point, mm.
    Approach,
    /// `Retract`: retract distance after a probed point, mm.
    Retract,
    /// `Search`: search distance beyond a probed point, mm.
    Search,
}

impl Param {
    /// The name as the protocol spells it.
    pub fn name(self) -> &'static str {
        match self {
            Param::Speed => "Speed",
            Param::Accel => "Accel",
            Param::Approach => "Approach",
            Param::Retract => "Retract",
            Param::Search => "Search",
        }
    }
    /// The parameters a block has.
    pub fn of(block: ParBlock) -> &'static [Param] {
        match block {
            ParBlock::GoToPar => &[Param::Speed, Param::Accel],
            ParBlock::PtMeasPar => {
                &[Param::Speed, Param::Accel, Param::Approach, Param::Retract, Param::Search]
            }
        }
    }
}

/// `Act`, `Def`, `Max`, `Min` of a parameter (a bare parameter means `Act`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// The value in effect.
    Act,
    /// The default value.
    Def,
    /// The largest allowed value.
    Max,
    /// The smallest allowed value.
    Min,
}

impl Field {
    /// The four fields in protocol order.
    pub const ALL: [Field; 4] = [Field::Act, Field::Def, Field::Max, Field::Min];
    /// The name as the protocol spells it.
    pub fn name(self) -> &'static str {
        match self {
            Field::Act => "Act",
            Field::Def => "Def",
            Field::Max => "Max",
            Field::Min => "Min",
        }
    }
}

/// A tool property below `Tool` or `FoundTool`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropItem {
    /// `Tool()` itself (EnumProp only).
    Root,
    /// `Name()`: the tool's name.
    Name,
    /// `Id()`: the tool's id.
    Id,
    /// `AvrRadius()`: the tool's average tip radius, mm.
    AvrRadius,
    /// `Alignment()`: the tool's direction.
    Alignment,
    /// `CollisionVolume()`: the tool's collision volume.
    CollisionVolume,
    /// `Tool.GoToPar()` (EnumProp only).
    Block(ParBlock),
    /// `Tool.GoToPar.Speed()` or `Tool.GoToPar.Speed.Max()`; `field` is `None` for the bare form.
    Value(ParBlock, Param, Option<Field>),
}

/// A property path such as `Tool.PtMeasPar.Speed.Max`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PropPath {
    /// `Tool` or `FoundTool`.
    pub tool: ToolRef,
    /// The property below it.
    pub item: PropItem,
}

impl PropPath {
    /// The dotted name as written in answers.
    pub fn dotted(&self) -> String {
        let root = match self.tool {
            ToolRef::Tool => "Tool",
            ToolRef::FoundTool => "FoundTool",
        };
        let block = |b: ParBlock| match b {
            ParBlock::GoToPar => "GoToPar",
            ParBlock::PtMeasPar => "PtMeasPar",
        };
        match self.item {
            PropItem::Root => root.to_string(),
            PropItem::Name => format!("{root}.Name"),
            PropItem::Id => format!("{root}.Id"),
            PropItem::AvrRadius => format!("{root}.AvrRadius"),
            PropItem::Alignment => format!("{root}.Alignment"),
            PropItem::CollisionVolume => format!("{root}.CollisionVolume"),
            PropItem::Block(b) => format!("{root}.{}", block(b)),
            PropItem::Value(b, p, None) => format!("{root}.{}.{}", block(b), p.name()),
            PropItem::Value(b, p, Some(f)) => format!("{root}.{}.{}.{}", block(b), p.name(), f.name()),
        }
    }

    fn parse(name: &str) -> Option<PropPath> {
        let parts: Vec<&str> = name.split('.').collect();
        let tool = match parts[0] {
            "Tool" => ToolRef::Tool,
            "FoundTool" => ToolRef::FoundTool,
            _ => return None,
        };
        let block = |s: &str| match s {
            "GoToPar" => Some(ParBlock::GoToPar),
            "PtMeasPar" => Some(ParBlock::PtMeasPar),
            _ => None,
        };
        let item = match parts.len() {
            1 => PropItem::Root,
            2 => match parts[1] {
                "Name" => PropItem::Name,
                "Id" => PropItem::Id,
                "AvrRadius" => PropItem::AvrRadius,
                "Alignment" if tool == ToolRef::Tool => PropItem::Alignment,
                "CollisionVolume" => PropItem::CollisionVolume,
                s => PropItem::Block(block(s)?),
            },
            3 | 4 => {
                let b = block(parts[1])?;
                let p = *Param::of(b).iter().find(|p| p.name() == parts[2])?;
                let f = if parts.len() == 4 {
                    Some(*Field::ALL.iter().find(|f| f.name() == parts[3])?)
                } else {
                    None
                };
                PropItem::Value(b, p, f)
            }
            _ => return None,
        };
        Some(PropPath { tool, item })
    }
}

/// Unknown-contour scans (the 1.4 argument lists the NIST suite uses, and 1.4.3's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnknownScan {
    /// In a plane, ending on a sphere.
    InPlaneEndIsSphere,
    /// In a plane, ending on a plane.
    InPlaneEndIsPlane,
    /// In a plane, ending on a cylinder.
    InPlaneEndIsCyl,
    /// On a cylinder, ending on a sphere.
    InCylEndIsSphere,
    /// On a cylinder, ending on a plane.
    InCylEndIsPlane,
}

/// A parsed and checked command.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// `StartSession()`: begin a session (resets the session's state).
    StartSession,
    /// `EndSession()`: end the session.
    EndSession,
    /// `GetDMEVersion()`: report the protocol version the server implements.
    GetDMEVersion,
    /// `GetMachineClass()`: report the machine class (`CartCMM`).
    GetMachineClass,
    /// `GetErrStatusE()`: report whether the server is in error state (fast queue).
    GetErrStatusE,
    /// `GetXtdErrStatus()`: report the error state with the pending errors.
    GetXtdErrStatus,
    /// `GetErrorInfo(n)`: describe error number `n`.
    GetErrorInfo(u16),
    /// `ClearAllErrors()`: leave error state.
    ClearAllErrors,
    /// `AbortE()`: abort every queued and running command (fast queue).
    AbortE,
    /// `Home()`: reference the machine's axes.
    Home,
    /// `IsHomed()`: report whether the machine is referenced.
    IsHomed,
    /// `EnableUser()`: let the operator move the machine (jog).
    EnableUser,
    /// `DisableUser()`: stop the operator moving the machine.
    DisableUser,
    /// `IsUserEnabled()`: report whether the operator may move the machine.
    IsUserEnabled,
    /// `Get(keys)`: report the current position and tool angles named by `keys`.
    Get(Vec<Key>),
    /// Target coordinates in the active csy (missing axes: `None`); tool angles are accepted and
    /// ignored (fixed stylus).
    GoTo {
        /// Target X in the active csy, mm (`None`: keep).
        x: Option<f64>,
        /// Target Y in the active csy, mm (`None`: keep).
        y: Option<f64>,
        /// Target Z in the active csy, mm (`None`: keep).
        z: Option<f64>,
    },
    /// `PtMeas(...)`: probe one point, approaching the nominal point along the nominal normal.
    PtMeas {
        /// Nominal point X in the active csy, mm.
        x: Option<f64>,
        /// Nominal point Y in the active csy, mm.
        y: Option<f64>,
        /// Nominal point Z in the active csy, mm.
        z: Option<f64>,
        /// Nominal surface normal (approach against it); `None`: from the current position.
        ijk: Option<[f64; 3]>,
    },
    /// `OnPtMeasReport(keys)`: what each `PtMeas` reports.
    OnPtMeasReport(Vec<Key>),
    /// `OnScanReport(keys)`: what each scanned point reports.
    OnScanReport(Vec<Key>),
    /// `OnMoveReportE(...)`: start a daemon reporting the position while the machine moves.
    OnMoveReportE {
        /// Report at least every this many seconds, s.
        time_s: Option<f64>,
        /// Report after moving at least this distance, mm.
        dis_mm: Option<f64>,
        /// What each report holds.
        keys: Vec<Key>,
    },
    /// `StopDaemon(tag)`: stop the daemon started by the command with `tag`.
    StopDaemon(Tag),
    /// `StopAllDaemons()`: stop every daemon.
    StopAllDaemons,
    /// `ChangeTool(name)`: change to the named tool.
    ChangeTool(String),
    /// `SetTool(name)`: declare the named tool mounted, without moving.
    SetTool(String),
    /// `FindTool(name)`: select the named tool as `FoundTool` for property queries.
    FindTool(String),
    /// `EnumTools()`: list the machine's tools.
    EnumTools,
    /// `GetChangeToolAction(name)`: report what changing to the named tool would do.
    GetChangeToolAction(String),
    /// `GetProp(paths)`: report tool properties.
    GetProp(Vec<PropPath>),
    /// `GetPropE(paths)`: report tool properties (fast queue).
    GetPropE(Vec<PropPath>),
    /// `SetProp(path(value), ...)`: set tool properties.
    SetProp(Vec<(PropPath, f64)>),
    /// `EnumProp(path)`: list the properties below `path`.
    EnumProp(PropPath),
    /// `EnumAllProp(path)`: list every property below `path`, recursively.
    EnumAllProp(PropPath),
    /// `GetCoordSystem()`: report the active coordinate system.
    GetCoordSystem,
    /// `SetCoordSystem(csy)`: make `csy` the active coordinate system.
    SetCoordSystem(Csy),
    /// `GetCsyTransformation(csy)`: report a coordinate system's transformation.
    GetCsyTransformation(CsyTransform),
    /// `SetCsyTransformation(csy, x, y, z, θ, ψ, φ)`: set a coordinate system's origin (mm) and Euler angles (deg).
    SetCsyTransformation(CsyTransform, [f64; 6]),
    /// `ScanOnCircleHint(displacement, form)`: expected deviations of the next circle scan.
    ScanOnCircleHint {
        /// Expected displacement of the circle from nominal, mm.
        displacement: f64,
        /// Expected form deviation, mm.
        form: f64,
    },
    /// Centre, start point, plane normal, delta (deg), surface angle (deg), step (deg).
    ScanOnCircle {
        /// Circle centre in the active csy, mm.
        center: [f64; 3],
        /// Start point on the circle in the active csy, mm.
        start: [f64; 3],
        /// Normal of the circle's plane.
        normal: [f64; 3],
        /// Angle to scan, degrees (signed).
        delta_deg: f64,
        /// Surface angle (0: a bore/shaft wall; 90: a plane face), degrees.
        sfa_deg: f64,
        /// Angular step between reported points, degrees.
        step_deg: f64,
    },
    /// `ScanOnLineHint(angle, form)`: expected deviations of the next line scan.
    ScanOnLineHint {
        /// Expected angle between the line and the scanned surface, degrees.
        angle: f64,
        /// Expected form deviation, mm.
        form: f64,
    },
    /// Start, end, surface normal, step (mm).
    ScanOnLine {
        /// Start point in the active csy, mm.
        start: [f64; 3],
        /// End point in the active csy, mm.
        end: [f64; 3],
        /// Surface normal along the line.
        normal: [f64; 3],
        /// Distance between reported points, mm.
        step_mm: f64,
    },
    /// `ScanUnknownHint(radius)`: the smallest radius of curvature to expect in the next
    /// unknown-contour scan, mm.
    ScanUnknownHint(f64),
    /// Lock axes (`X`, `Y`, `Z`, `R`, `A`, `B`, `C`, `Phi`): locked axes do not move.
    LockAxis(Vec<String>),
    /// Align the tool within `alpha` degrees of a direction (and the second axis within `beta`).
    AlignTool {
        /// The direction to align the tool with (active csy).
        dir: [f64; 3],
        /// Tolerance on the alignment, degrees.
        alpha_deg: f64,
        /// A second direction and its tolerance (degrees), for a second axis.
        second: Option<([f64; 3], f64)>,
    },
    /// `ReQualify()`: re-qualify the current tool.
    ReQualify,
    /// `ScanUnknown...(...)`: scan an unknown contour, with the variant's argument list.
    ScanUnknown(UnknownScan, Vec<f64>),
    /// Rotary table (specification 12.1): turn the table so that the part direction `part`
    /// (active csy) points, projected into the table plane, along the machine direction
    /// `machine`, within `alpha_deg` (0: no check); the second pair is for a second rotary axis.
    AlignPart {
        /// The part direction to turn (active csy).
        part: [f64; 3],
        /// The machine direction it should point along.
        machine: [f64; 3],
        /// Tolerance on the alignment, degrees (0: no check).
        alpha_deg: f64,
        /// Part direction, machine direction and tolerance (degrees) for a second rotary axis.
        second: Option<([f64; 3], [f64; 3], f64)>,
    },
    /// Form tester (13.1): move the part so that a circle centre lies on the rotation axis when
    /// it is `limit` mm or more away from it.
    CenterPart {
        /// A point on the circle's axis (its centre), active csy, mm.
        point: [f64; 3],
        /// Offset from the rotation axis at or above which the part is moved, mm.
        limit: f64,
    },
    /// Form tester (13.2): tilt the part so that a direction is parallel to the rotation axis
    /// when it deviates by `limit` mm or more over 100 mm.
    TiltPart {
        /// The direction to make parallel to the rotation axis (active csy).
        dir: [f64; 3],
        /// Deviation over 100 mm at or above which the part is tilted, mm.
        limit: f64,
    },
    /// Form tester (13.3): tilt and centre the part so that two circle centres lie on the axis.
    TiltCenterPart {
        /// The first circle centre (active csy), mm.
        first: [f64; 3],
        /// The second circle centre (active csy), mm.
        second: [f64; 3],
        /// Offset at or above which the part is moved, mm.
        limit: f64,
    },
}

/// Why a call is not a valid command.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CommandError {
    /// The specification's error the server answers with.
    pub code: ErrorCode,
    /// What is wrong with the call, for the error's text.
    pub message: String,
}

fn err(code: ErrorCode, message: impl Into<String>) -> CommandError {
    CommandError { code, message: message.into() }
}

fn incorrect(message: impl Into<String>) -> CommandError {
    err(ErrorCode::INCORRECT_ARGUMENTS, message)
}

fn no_args(c: &Call) -> Result<(), CommandError> {
    if c.args.is_empty() {
        Ok(())
    } else {
        Err(incorrect(format!("{} takes no arguments", c.name)))
    }
}

fn numbers(c: &Call, n: &[usize]) -> Result<Vec<f64>, CommandError> {
    if !n.contains(&c.args.len()) {
        return Err(incorrect(format!("{} takes {:?} arguments, got {}", c.name, n, c.args.len())));
    }
    c.args
        .iter()
        .map(|a| match a {
            Arg::Number(v) => Ok(*v),
            other => Err(err(ErrorCode::BAD_ARGUMENT, format!("{}: {other} is not a number", c.name))),
        })
        .collect()
}

fn one_string(c: &Call) -> Result<String, CommandError> {
    match c.args.as_slice() {
        [Arg::Str(s)] if !s.is_empty() => Ok(s.clone()),
        [Arg::Str(_)] => Err(incorrect(format!("{}: empty tool name", c.name))),
        [_] => Err(err(ErrorCode::BAD_ARGUMENT, format!("{} takes a tool name in quotes", c.name))),
        _ => Err(incorrect(format!("{} takes one tool name", c.name))),
    }
}

fn empty_call(a: &Arg, what: &str) -> Result<String, CommandError> {
    match a {
        Arg::Call(c) if c.args.is_empty() => Ok(c.name.clone()),
        other => Err(incorrect(format!("{what}: expected Name(), got {other}"))),
    }
}

fn keys(c: &Call, allowed: &[Key], min: usize) -> Result<Vec<Key>, CommandError> {
    let mut out = Vec::new();
    for a in &c.args {
        let name = empty_call(a, &c.name)?;
        let k = Key::from_name(&name).filter(|k| allowed.contains(k)).ok_or_else(|| {
            err(ErrorCode::BAD_PROPERTY, format!("{}: {name}() is not allowed here", c.name))
        })?;
        if out.contains(&k) {
            return Err(incorrect(format!("{}: {name}() twice", c.name)));
        }
        out.push(k);
    }
    if out.len() < min {
        return Err(incorrect(format!("{} needs at least {min} argument(s)", c.name)));
    }
    Ok(out)
}

const POS_KEYS: [Key; 7] = [Key::X, Key::Y, Key::Z, Key::R, Key::ToolA, Key::ToolB, Key::ToolC];

fn vec3(v: &[f64]) -> [f64; 3] {
    [v[0], v[1], v[2]]
}

/// One group's call parser: `Ok(None)` when the call is not in its group.
type CallParser = fn(&Call) -> Result<Option<Command>, CommandError>;

impl Command {
    /// Check a parsed call and build the typed command. `tag` is the command's tag (commands
    /// whose name ends in `E` must use an event tag, all others a command tag).
    pub fn from_call(tag: Tag, c: &Call) -> Result<Command, CommandError> {
        let fast = c.name.ends_with('E');
        if KNOWN.contains(&c.name.as_str()) && fast != tag.is_event() {
            return Err(err(
                ErrorCode::ILLEGAL_TAG,
                if fast {
                    format!("{} needs an event tag (E0001-E9999)", c.name)
                } else {
                    format!("{} needs a command tag", c.name)
                },
            ));
        }
        if tag == Tag::Command(0) || tag == Tag::Event(0) {
            return Err(err(ErrorCode::ILLEGAL_TAG, "tags 00000 and E0000 are reserved"));
        }
        let groups: [CallParser; 7] = [
            Self::no_arg_call,
            Self::session_call,
            Self::motion_call,
            Self::tool_call,
            Self::csy_call,
            Self::part_call,
            Self::scan_call,
        ];
        for parse in groups {
            if let Some(cmd) = parse(c)? {
                return Ok(cmd);
            }
        }
        Err(err(ErrorCode::UNSUPPORTED_COMMAND, format!("unknown command {}", c.name)))
    }

    /// Commands without arguments. `Ok(None)` when `c` is not one of them.
    fn no_arg_call(c: &Call) -> Result<Option<Command>, CommandError> {
        let cmd = match c.name.as_str() {
            "StartSession" => no_args(c).map(|_| Command::StartSession)?,
            "EndSession" => no_args(c).map(|_| Command::EndSession)?,
            "GetDMEVersion" => no_args(c).map(|_| Command::GetDMEVersion)?,
            "GetMachineClass" => no_args(c).map(|_| Command::GetMachineClass)?,
            "GetErrStatusE" => no_args(c).map(|_| Command::GetErrStatusE)?,
            "GetXtdErrStatus" => no_args(c).map(|_| Command::GetXtdErrStatus)?,
            "ClearAllErrors" => no_args(c).map(|_| Command::ClearAllErrors)?,
            "AbortE" => no_args(c).map(|_| Command::AbortE)?,
            "Home" => no_args(c).map(|_| Command::Home)?,
            "IsHomed" => no_args(c).map(|_| Command::IsHomed)?,
            "EnableUser" => no_args(c).map(|_| Command::EnableUser)?,
            "DisableUser" => no_args(c).map(|_| Command::DisableUser)?,
            "IsUserEnabled" => no_args(c).map(|_| Command::IsUserEnabled)?,
            "EnumTools" => no_args(c).map(|_| Command::EnumTools)?,
            "StopAllDaemons" => no_args(c).map(|_| Command::StopAllDaemons)?,
            "GetCoordSystem" => no_args(c).map(|_| Command::GetCoordSystem)?,
            "ReQualify" => no_args(c).map(|_| Command::ReQualify)?,
            _ => return Ok(None),
        };
        Ok(Some(cmd))
    }

    /// Error information, report formats and the move-report daemon. `Ok(None)` when `c` is not one of them.
    fn session_call(c: &Call) -> Result<Option<Command>, CommandError> {
        let cmd = match c.name.as_str() {
            "GetErrorInfo" => {
                let v = numbers(c, &[1])?[0];
                if v.fract() != 0.0 || !(0.0..=9999.0).contains(&v) {
                    return Err(err(ErrorCode::BAD_ARGUMENT, "GetErrorInfo takes an error number 0000-9999"));
                }
                Command::GetErrorInfo(v as u16)
            }
            "OnPtMeasReport" => {
                let mut allowed = POS_KEYS.to_vec();
                allowed.extend([Key::Ijk, Key::Er]);
                Command::OnPtMeasReport(keys(c, &allowed, 1)?)
            }
            "OnScanReport" => {
                let mut allowed = POS_KEYS.to_vec();
                allowed.extend([Key::Ijk, Key::Er, Key::Q]);
                Command::OnScanReport(keys(c, &allowed, 1)?)
            }
            "OnMoveReportE" => Command::parse_move_report(c)?,
            "StopDaemon" => match c.args.as_slice() {
                [Arg::Ident(t)] => match Tag::parse(t) {
                    Some(tag @ Tag::Event(n)) if n > 0 => Command::StopDaemon(tag),
                    _ => {
                        return Err(err(
                            ErrorCode::BAD_ARGUMENT,
                            format!("StopDaemon: {t} is not an event tag"),
                        ))
                    }
                },
                [_] => return Err(err(ErrorCode::BAD_ARGUMENT, "StopDaemon takes an event tag")),
                _ => return Err(incorrect("StopDaemon takes one event tag")),
            },
            _ => return Ok(None),
        };
        Ok(Some(cmd))
    }

    /// Position queries, moves, single points and axis locks. `Ok(None)` when `c` is not one of them.
    fn motion_call(c: &Call) -> Result<Option<Command>, CommandError> {
        let cmd = match c.name.as_str() {
            "Get" => Command::Get(keys(c, &POS_KEYS, 1)?),
            "GoTo" | "PtMeas" => Command::parse_motion(c)?,
            "LockAxis" => {
                let mut axes = Vec::new();
                for a in &c.args {
                    let name = empty_call(a, "LockAxis")?;
                    if !["X", "Y", "Z", "R", "A", "B", "C", "Phi"].contains(&name.as_str()) {
                        return Err(err(
                            ErrorCode::BAD_PROPERTY,
                            format!("LockAxis: {name}() is not an axis"),
                        ));
                    }
                    if axes.contains(&name) {
                        return Err(incorrect(format!("LockAxis: {name}() twice")));
                    }
                    axes.push(name);
                }
                if axes.is_empty() {
                    return Err(incorrect("LockAxis needs at least one axis"));
                }
                Command::LockAxis(axes)
            }
            _ => return Ok(None),
        };
        Ok(Some(cmd))
    }

    /// Tool selection, tool properties and tool alignment. `Ok(None)` when `c` is not one of them.
    fn tool_call(c: &Call) -> Result<Option<Command>, CommandError> {
        let cmd = match c.name.as_str() {
            "ChangeTool" => Command::ChangeTool(one_string(c)?),
            "SetTool" => Command::SetTool(one_string(c)?),
            "FindTool" => Command::FindTool(one_string(c)?),
            "GetChangeToolAction" => Command::GetChangeToolAction(one_string(c)?),
            "GetProp" | "GetPropE" => {
                if c.args.is_empty() {
                    return Err(incorrect(format!("{} needs at least one property", c.name)));
                }
                let mut paths = Vec::new();
                for a in &c.args {
                    let name = empty_call(a, &c.name)?;
                    let p = PropPath::parse(&name)
                        .filter(|p| !matches!(p.item, PropItem::Root | PropItem::Block(_)))
                        .ok_or_else(|| {
                            err(ErrorCode::BAD_PROPERTY, format!("{}: unknown property {name}", c.name))
                        })?;
                    paths.push(p);
                }
                if c.name == "GetProp" {
                    Command::GetProp(paths)
                } else {
                    Command::GetPropE(paths)
                }
            }
            "SetProp" => {
                if c.args.is_empty() {
                    return Err(incorrect("SetProp needs at least one property"));
                }
                let mut out = Vec::new();
                for a in &c.args {
                    let Arg::Call(inner) = a else {
                        return Err(incorrect(format!("SetProp: expected Property(value), got {a}")));
                    };
                    let p = PropPath::parse(&inner.name).ok_or_else(|| {
                        err(ErrorCode::BAD_PROPERTY, format!("SetProp: unknown property {}", inner.name))
                    })?;
                    let PropItem::Value(_, _, field) = p.item else {
                        return Err(err(
                            ErrorCode::BAD_PROPERTY,
                            format!("SetProp: {} cannot be set", inner.name),
                        ));
                    };
                    if matches!(field, Some(Field::Max) | Some(Field::Min) | Some(Field::Def)) {
                        return Err(err(
                            ErrorCode::BAD_PROPERTY,
                            format!("SetProp: {} is read-only", inner.name),
                        ));
                    }
                    let v = numbers(inner, &[1])?[0];
                    out.push((p, v));
                }
                Command::SetProp(out)
            }
            "EnumProp" | "EnumAllProp" => {
                let [a] = c.args.as_slice() else {
                    return Err(incorrect(format!("{} takes one property", c.name)));
                };
                let name = empty_call(a, &c.name)?;
                let p = PropPath::parse(&name)
                    .filter(|p| {
                        matches!(p.item, PropItem::Root | PropItem::Block(_) | PropItem::Value(_, _, _))
                    })
                    .ok_or_else(|| {
                        err(ErrorCode::BAD_PROPERTY, format!("{}: {name} has no properties", c.name))
                    })?;
                if c.name == "EnumProp" {
                    Command::EnumProp(p)
                } else {
                    Command::EnumAllProp(p)
                }
            }
            "AlignTool" => {
                let v = numbers(c, &[4, 8])?;
                let norm_ok = |k: usize| {
                    ((v[k] * v[k] + v[k + 1] * v[k + 1] + v[k + 2] * v[k + 2]).sqrt() - 1.0).abs() < 1e-6
                };
                if !norm_ok(0) || (v.len() == 8 && !norm_ok(3)) {
                    return Err(incorrect("AlignTool: the direction vectors must be normalized"));
                }
                if v.len() == 4 {
                    Command::AlignTool { dir: vec3(&v[0..3]), alpha_deg: v[3], second: None }
                } else {
                    Command::AlignTool {
                        dir: vec3(&v[0..3]),
                        alpha_deg: v[6],
                        second: Some((vec3(&v[3..6]), v[7])),
                    }
                }
            }
            _ => return Ok(None),
        };
        Ok(Some(cmd))
    }

    /// Coordinate systems and their transformations. `Ok(None)` when `c` is not one of them.
    fn csy_call(c: &Call) -> Result<Option<Command>, CommandError> {
        let cmd = match c.name.as_str() {
            "SetCoordSystem" => match c.args.as_slice() {
                [Arg::Ident(s)] => Command::SetCoordSystem(match s.as_str() {
                    "MachineCsy" => Csy::MachineCsy,
                    "MoveableMachineCsy" => Csy::MoveableMachineCsy,
                    "MultipleArmCsy" => Csy::MultipleArmCsy,
                    "PartCsy" => Csy::PartCsy,
                    _ => {
                        return Err(err(ErrorCode::BAD_ARGUMENT, format!("SetCoordSystem: unknown csy {s}")))
                    }
                }),
                _ => return Err(incorrect("SetCoordSystem takes one coordinate system")),
            },
            "GetCsyTransformation" | "SetCsyTransformation" => {
                let Some(Arg::Ident(s)) = c.args.first() else {
                    return Err(incorrect(format!("{} needs a coordinate system first", c.name)));
                };
                let t = *CsyTransform::ALL.iter().find(|t| t.name() == s).ok_or_else(|| {
                    err(ErrorCode::BAD_ARGUMENT, format!("{}: unknown transformation {s}", c.name))
                })?;
                if c.name == "GetCsyTransformation" {
                    if c.args.len() != 1 {
                        return Err(incorrect("GetCsyTransformation takes one argument"));
                    }
                    Command::GetCsyTransformation(t)
                } else {
                    let rest = Call { name: c.name.clone(), args: c.args[1..].to_vec() };
                    let v = numbers(&rest, &[6])?;
                    if let Some(x) =
                        v[..3].iter().find(|x| !x.is_finite() || x.abs() > MAX_CSY_TRANSLATION_MM)
                    {
                        return Err(err(
                            ErrorCode::ARGUMENT_OUT_OF_RANGE,
                            format!(
                                "SetCsyTransformation: origin {x} mm is out of range (at most ±{MAX_CSY_TRANSLATION_MM:e} mm)"
                            ),
                        ));
                    }
                    if let Some(a) = v[3..].iter().find(|a| !a.is_finite() || a.abs() > MAX_CSY_ANGLE_DEG) {
                        return Err(err(
                            ErrorCode::ARGUMENT_OUT_OF_RANGE,
                            format!(
                                "SetCsyTransformation: angle {a}° is out of range (at most ±{MAX_CSY_ANGLE_DEG:e}°)"
                            ),
                        ));
                    }
                    if !(0.0..=180.0).contains(&v[3]) {
                        return Err(err(ErrorCode::THETA_OUT_OF_RANGE, "Theta must be 0..180 degrees"));
                    }
                    Command::SetCsyTransformation(t, [v[0], v[1], v[2], v[3], v[4], v[5]])
                }
            }
            _ => return Ok(None),
        };
        Ok(Some(cmd))
    }

    /// Part alignment on the rotary table. `Ok(None)` when `c` is not one of them.
    fn part_call(c: &Call) -> Result<Option<Command>, CommandError> {
        let cmd = match c.name.as_str() {
            "AlignPart" => {
                let v = numbers(c, &[7, 14])?;
                if v.len() == 7 {
                    Command::AlignPart {
                        part: vec3(&v[0..3]),
                        machine: vec3(&v[3..6]),
                        alpha_deg: v[6],
                        second: None,
                    }
                } else {
                    Command::AlignPart {
                        part: vec3(&v[0..3]),
                        machine: vec3(&v[3..6]),
                        alpha_deg: v[12],
                        second: Some((vec3(&v[6..9]), vec3(&v[9..12]), v[13])),
                    }
                }
            }
            "CenterPart" => {
                let v = numbers(c, &[4])?;
                Command::CenterPart { point: vec3(&v[0..3]), limit: v[3] }
            }
            "TiltPart" => {
                let v = numbers(c, &[4])?;
                Command::TiltPart { dir: vec3(&v[0..3]), limit: v[3] }
            }
            "TiltCenterPart" => {
                let v = numbers(c, &[7])?;
                Command::TiltCenterPart { first: vec3(&v[0..3]), second: vec3(&v[3..6]), limit: v[6] }
            }
            _ => return Ok(None),
        };
        Ok(Some(cmd))
    }

    /// Scan hints and scans. `Ok(None)` when `c` is not one of them.
    fn scan_call(c: &Call) -> Result<Option<Command>, CommandError> {
        let cmd = match c.name.as_str() {
            "ScanOnCircleHint" => {
                let v = numbers(c, &[2])?;
                Command::ScanOnCircleHint { displacement: v[0], form: v[1] }
            }
            "ScanOnLineHint" => {
                let v = numbers(c, &[2])?;
                Command::ScanOnLineHint { angle: v[0], form: v[1] }
            }
            "ScanUnknownHint" => {
                let v = numbers(c, &[1])?[0];
                if v <= 0.0 {
                    return Err(err(
                        ErrorCode::ARGUMENT_OUT_OF_RANGE,
                        "ScanUnknownHint: the radius must be > 0",
                    ));
                }
                Command::ScanUnknownHint(v)
            }
            "ScanOnCircle" => {
                let v = numbers(c, &[12])?;
                if v[11] <= 0.0 {
                    return Err(err(ErrorCode::ARGUMENT_OUT_OF_RANGE, "ScanOnCircle: StepW must be > 0"));
                }
                Command::ScanOnCircle {
                    center: vec3(&v[0..3]),
                    start: vec3(&v[3..6]),
                    normal: vec3(&v[6..9]),
                    delta_deg: v[9],
                    sfa_deg: v[10],
                    step_deg: v[11],
                }
            }
            "ScanOnLine" => {
                let v = numbers(c, &[10])?;
                if v[9] <= 0.0 {
                    return Err(err(ErrorCode::ARGUMENT_OUT_OF_RANGE, "ScanOnLine: StepW must be > 0"));
                }
                Command::ScanOnLine {
                    start: vec3(&v[0..3]),
                    end: vec3(&v[3..6]),
                    normal: vec3(&v[6..9]),
                    step_mm: v[9],
                }
            }
            "ScanInPlaneEndIsSphere" => {
                Command::ScanUnknown(UnknownScan::InPlaneEndIsSphere, numbers(c, &[17, 21])?)
            }
            "ScanInPlaneEndIsPlane" => {
                Command::ScanUnknown(UnknownScan::InPlaneEndIsPlane, numbers(c, &[20, 23])?)
            }
            "ScanInPlaneEndIsCyl" => {
                Command::ScanUnknown(UnknownScan::InPlaneEndIsCyl, numbers(c, &[21, 24])?)
            }
            "ScanInCylEndIsSphere" => {
                Command::ScanUnknown(UnknownScan::InCylEndIsSphere, numbers(c, &[23, 24])?)
            }
            "ScanInCylEndIsPlane" => Command::ScanUnknown(UnknownScan::InCylEndIsPlane, numbers(c, &[26])?),
            _ => return Ok(None),
        };
        Ok(Some(cmd))
    }

    fn parse_move_report(c: &Call) -> Result<Command, CommandError> {
        let (mut time_s, mut dis_mm, mut ks) = (None, None, Vec::new());
        for a in &c.args {
            let Arg::Call(inner) = a else {
                return Err(incorrect(format!("OnMoveReportE: expected Name(..), got {a}")));
            };
            match inner.name.as_str() {
                "Time" | "Dis" => {
                    let v = numbers(inner, &[1])
                        .map_err(|e| incorrect(format!("OnMoveReportE: {}", e.message)))?[0];
                    let slot = if inner.name == "Time" { &mut time_s } else { &mut dis_mm };
                    if slot.is_some() {
                        return Err(incorrect(format!("OnMoveReportE: {} twice", inner.name)));
                    }
                    if inner.name == "Time" && v < 0.1 {
                        return Err(err(
                            ErrorCode::BAD_PROPERTY,
                            "OnMoveReportE: Time must be at least 0.1 s",
                        ));
                    }
                    if inner.name == "Dis" && v <= 0.0 {
                        return Err(err(ErrorCode::BAD_PROPERTY, "OnMoveReportE: Dis must be positive"));
                    }
                    *slot = Some(v);
                }
                name => {
                    if !inner.args.is_empty() {
                        return Err(incorrect(format!("OnMoveReportE: {name}() takes no value")));
                    }
                    let k = Key::from_name(name).filter(|k| POS_KEYS.contains(k)).ok_or_else(|| {
                        err(ErrorCode::BAD_PROPERTY, format!("OnMoveReportE: {name}() not allowed"))
                    })?;
                    if ks.contains(&k) {
                        return Err(incorrect(format!("OnMoveReportE: {name}() twice")));
                    }
                    ks.push(k);
                }
            }
        }
        Ok(Command::OnMoveReportE { time_s, dis_mm, keys: ks })
    }

    fn parse_motion(c: &Call) -> Result<Command, CommandError> {
        let is_ptmeas = c.name == "PtMeas";
        let (mut x, mut y, mut z, mut ijk) = (None, None, None, None);
        let mut angles = Vec::new();
        if c.args.is_empty() {
            return Err(incorrect(format!("{} needs at least one coordinate", c.name)));
        }
        for a in &c.args {
            let Arg::Call(inner) = a else {
                return Err(incorrect(format!("{}: expected X(..), Y(..), Z(..), got {a}", c.name)));
            };
            let name = inner.name.as_str();
            match name {
                "X" | "Y" | "Z" => {
                    let v = numbers(inner, &[1])?[0];
                    let slot = match name {
                        "X" => &mut x,
                        "Y" => &mut y,
                        _ => &mut z,
                    };
                    if slot.is_some() {
                        return Err(incorrect(format!("{}: {name} twice", c.name)));
                    }
                    *slot = Some(v);
                }
                "IJK" if is_ptmeas => {
                    let v = numbers(inner, &[3])?;
                    if ijk.is_some() {
                        return Err(incorrect("PtMeas: IJK twice"));
                    }
                    ijk = Some(vec3(&v));
                }
                "Tool.A" | "Tool.B" | "Tool.C" if !is_ptmeas => {
                    numbers(inner, &[1])?;
                    if angles.contains(&name) {
                        return Err(incorrect(format!("GoTo: {name} twice")));
                    }
                    angles.push(name);
                }
                _ => return Err(err(ErrorCode::BAD_ARGUMENT, format!("{}: {name}(..) not allowed", c.name))),
            }
        }
        if is_ptmeas {
            if x.is_none() && y.is_none() && z.is_none() {
                return Err(incorrect("PtMeas: IJK without any coordinate is not allowed"));
            }
            Ok(Command::PtMeas { x, y, z, ijk })
        } else {
            Ok(Command::GoTo { x, y, z })
        }
    }

    /// The command text a client sends (without tag), for the commands the client uses.
    pub fn to_call_string(&self) -> String {
        let coords = |x: &Option<f64>, y: &Option<f64>, z: &Option<f64>| {
            let mut parts = Vec::new();
            for (n, v) in [("X", x), ("Y", y), ("Z", z)] {
                if let Some(v) = v {
                    parts.push(format!("{n}({})", fmt_num(*v)));
                }
            }
            parts
        };
        let list = |ks: &[Key]| ks.iter().map(|k| format!("{}()", k.name())).collect::<Vec<_>>().join(", ");
        match self {
            Command::GoTo { x, y, z } => format!("GoTo({})", coords(x, y, z).join(", ")),
            Command::PtMeas { x, y, z, ijk } => {
                let mut parts = coords(x, y, z);
                if let Some([i, j, k]) = ijk {
                    parts.push(format!("IJK({}, {}, {})", fmt_num(*i), fmt_num(*j), fmt_num(*k)));
                }
                format!("PtMeas({})", parts.join(", "))
            }
            Command::Get(ks) => format!("Get({})", list(ks)),
            Command::OnPtMeasReport(ks) => format!("OnPtMeasReport({})", list(ks)),
            Command::OnScanReport(ks) => format!("OnScanReport({})", list(ks)),
            Command::ChangeTool(t) => format!("ChangeTool(\"{t}\")"),
            Command::SetTool(t) => format!("SetTool(\"{t}\")"),
            Command::FindTool(t) => format!("FindTool(\"{t}\")"),
            Command::SetCoordSystem(c) => format!("SetCoordSystem({})", c.name()),
            Command::GetProp(ps) => {
                format!(
                    "GetProp({})",
                    ps.iter().map(|p| format!("{}()", p.dotted())).collect::<Vec<_>>().join(", ")
                )
            }
            Command::SetProp(ps) => format!(
                "SetProp({})",
                ps.iter()
                    .map(|(p, v)| format!("{}({})", p.dotted(), fmt_num(*v)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Command::ScanOnCircle { center, start, normal, delta_deg, sfa_deg, step_deg } => {
                let mut v: Vec<f64> = center.iter().chain(start).chain(normal).copied().collect();
                v.extend([*delta_deg, *sfa_deg, *step_deg]);
                format!("ScanOnCircle({})", v.iter().map(|x| fmt_num(*x)).collect::<Vec<_>>().join(", "))
            }
            Command::ScanOnLine { start, end, normal, step_mm } => {
                let mut v: Vec<f64> = start.iter().chain(end).chain(normal).copied().collect();
                v.push(*step_mm);
                format!("ScanOnLine({})", v.iter().map(|x| fmt_num(*x)).collect::<Vec<_>>().join(", "))
            }
            Command::StartSession => "StartSession()".into(),
            Command::EndSession => "EndSession()".into(),
            Command::GetDMEVersion => "GetDMEVersion()".into(),
            Command::ClearAllErrors => "ClearAllErrors()".into(),
            Command::AbortE => "AbortE()".into(),
            Command::Home => "Home()".into(),
            Command::IsHomed => "IsHomed()".into(),
            Command::GetErrStatusE => "GetErrStatusE()".into(),
            other => format!("{other:?}"),
        }
    }
}

/// Every command name the server knows (others are answered with 0501).
pub const KNOWN: &[&str] = &[
    "StartSession",
    "EndSession",
    "GetDMEVersion",
    "GetMachineClass",
    "GetErrStatusE",
    "GetXtdErrStatus",
    "GetErrorInfo",
    "ClearAllErrors",
    "AbortE",
    "Home",
    "IsHomed",
    "EnableUser",
    "DisableUser",
    "IsUserEnabled",
    "Get",
    "GoTo",
    "PtMeas",
    "OnPtMeasReport",
    "OnScanReport",
    "OnMoveReportE",
    "StopDaemon",
    "StopAllDaemons",
    "ChangeTool",
    "SetTool",
    "FindTool",
    "EnumTools",
    "GetChangeToolAction",
    "GetProp",
    "GetPropE",
    "SetProp",
    "EnumProp",
    "EnumAllProp",
    "GetCoordSystem",
    "SetCoordSystem",
    "GetCsyTransformation",
    "SetCsyTransformation",
    "ScanOnCircleHint",
    "ScanOnCircle",
    "ScanOnLineHint",
    "ScanOnLine",
    "ScanUnknownHint",
    "ReQualify",
    "LockAxis",
    "AlignTool",
    "ScanInPlaneEndIsSphere",
    "ScanInPlaneEndIsPlane",
    "ScanInPlaneEndIsCyl",
    "ScanInCylEndIsSphere",
    "ScanInCylEndIsPlane",
    "AlignPart",
    "CenterPart",
    "TiltPart",
    "TiltCenterPart",
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::parse_line;

    fn cmd(line: &str) -> Result<Command, CommandError> {
        let (t, c) = parse_line(line.as_bytes()).unwrap();
        Command::from_call(t, &c)
    }

    #[test]
    fn typed_commands() {
        assert_eq!(
            cmd("00080 PtMeas(X(1), IJK(0,0,1), Z(3))").unwrap(),
            Command::PtMeas { x: Some(1.0), y: None, z: Some(3.0), ijk: Some([0.0, 0.0, 1.0]) }
        );
        assert_eq!(cmd("00010 Get(X(), Tool.A())").unwrap(), Command::Get(vec![Key::X, Key::ToolA]));
        let Command::GetProp(p) = cmd("00340 GetProp(Tool.PtMeasPar.Accel.Max())").unwrap() else { panic!() };
        assert_eq!(p[0].dotted(), "Tool.PtMeasPar.Accel.Max");
        assert!(matches!(
            cmd("E0490 OnMoveReportE(Time(1), Dis(10), X(), Y())"),
            Ok(Command::OnMoveReportE { .. })
        ));
    }

    #[test]
    fn signature_errors() {
        for (line, num) in [
            ("E0101 AbortE(3)", 502u16),
            ("01401 Get(X)", 502),
            ("01405 Get(X(), X())", 502),
            ("01408 Get(Tool())", 510),
            ("01413 Get(Q())", 510),
            ("01902 GetErrorInfo(2.7)", 509),
            ("02209 GetProp(Tool.PtMeasPar.Accel.Max)", 502),
            ("02205 GetProp(FoundTool.Alignment())", 510),
            ("02504 GoTo(X(4), X(4))", 502),
            ("02511 GoTo(Q(3))", 509),
            ("E3012 OnMoveReportE(Time(1), Dis(10), X(), Y(), Dis(8))", 502),
            ("E3001 OnMoveReportE(Time(0.09))", 510),
            ("03311 PtMeas(IJK(3,2,2))", 502),
            ("04502 SetCoordSystem(JogMoveCsy)", 509),
            ("04604 SetCsyTransformation(PartCsy, 1, 1, 1, 200, 180, 180)", 1007),
            ("04605 SetCsyTransformation(PartCsy, 1e300, 0, 0, 0, 0, 0)", 504),
            ("04606 SetCsyTransformation(PartCsy, 0, -1e15, 0, 0, 0, 0)", 504),
            ("04608 SetCsyTransformation(PartCsy, 0, 0, 0, 0, 1e300, 0)", 504),
            ("04708 SetProp(FoundTool.PtMeasPar.Accel.Max(3))", 510),
            ("05102 StopDaemon(05101)", 509),
            ("05402 AbortE()", 1),
            ("E5403 GoTo(X(0.1))", 1),
            ("05601 CmdName()", 501),
            ("04403 ScanUnknownHint(-1)", 504),
        ] {
            assert_eq!(cmd(line).unwrap_err().code.number, num, "{line}");
        }
    }
}
