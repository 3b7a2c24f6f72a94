//! # truepos-device — how truepos sees machines
//!
//! Capability crates never talk to a simulator or a wire protocol directly: they drive the traits
//! here, and backends implement them — the virtual plant (`truepos-cell`), LinuxCNC through
//! linuxcncrsh (`truepos-linuxcnc`), and CMMs through I++ DME (`truepos-ippdme`).
//!
//! Entry points:
//! - [`ProbingMachine`]: a machine with a touch probe — position, positioning moves, single-point
//!   probing ([`ProbeRequest`] → [`ProbeHit`]), abort. Used by `probe sphere`, head-offset
//!   acquisition and inspection.
//! - [`ScanningMachine`]: a machine with an analogue scanning probe. Servo-rate path following
//!   ([`ScanningMachine::follow`]: one tip-centre command per control period in, encoder position
//!   and probe deflection out) is what truepos's own scanning control drives; whole scans run by
//!   the machine's controller ([`ScanningMachine::scan_on_circle`], [`ScanningMachine::scan_on_line`],
//!   as I++ DME's `ScanOnCircle` / `ScanOnLine`) are the other half, for backends whose
//!   controller scans by itself.
//! - [`Controller`], [`Tracker`], [`Cell`]: the end-point control loop's NC controller fed block by
//!   block, its laser trackers and the rest of the cell's sensors.
//! - [`RotaryKinematics`], [`KinematicsParameter`]: a five-axis controller with tool-centre-point
//!   control and the geometry of its kinematics module, which `truepos kinematics calibrate`
//!   reads, identifies and writes back through [`ProbingMachine`].
//! - [`DeviceError`]: every failure of a device, naming the device's address; the binary maps it
//!   to exit code 3.
//!
//! Frames and units: every position is in the machine frame, millimetres; feeds in mm/s — except
//! on a machine with [`ProbingMachine::rotary_kinematics`], whose positions are in the programme
//! frame that turns with its table.

#![forbid(unsafe_code)]

use thiserror::Error;
use truepos_math::air::AirConditions;
use truepos_math::{Point3, Vector3};

/// A failure of a device. Every variant that concerns a real device names its address
/// (`linuxcncrsh://127.0.0.1:5007`, `ippdme://…`, `virtual`).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum DeviceError {
    /// The device could not be reached (connection refused, no route, …).
    #[error("{address}: cannot connect: {message}")]
    Connect {
        /// The device's address.
        address: String,
        /// The operating system's or library's message.
        message: String,
    },
    /// The device did not answer in time.
    #[error("{address}: no answer within {seconds} s while {what}")]
    Timeout {
        /// The device's address.
        address: String,
        /// What truepos was doing.
        what: String,
        /// How long it waited, s.
        seconds: f64,
    },
    /// The connection broke during a command.
    #[error("{address}: connection lost while {what}: {message}")]
    ConnectionLost {
        /// The device's address.
        address: String,
        /// What truepos was doing.
        what: String,
        /// The operating system's or library's message.
        message: String,
    },
    /// The device is not in a state truepos may use (e-stop, machine off, not homed, busy).
    /// truepos never releases an e-stop or switches a machine on itself.
    #[error("{address}: not ready: {reason}")]
    NotReady {
        /// The device's address.
        address: String,
        /// Why it is not ready.
        reason: String,
    },
    /// The controller reported an error for a command (its own message, verbatim).
    #[error("{address}: {what}: the controller reports: {message}")]
    Controller {
        /// The device's address.
        address: String,
        /// What truepos was doing.
        what: String,
        /// The controller's message, verbatim.
        message: String,
    },
    /// A probing move ended without contact; the machine has been retracted.
    #[error("{address}: {what}: the probe move ended without contact")]
    NoContact {
        /// The device's address.
        address: String,
        /// What truepos was doing.
        what: String,
    },
    /// The device answered something the protocol does not allow.
    #[error("{address}: protocol error while {what}: {message}")]
    Protocol {
        /// The device's address.
        address: String,
        /// What truepos was doing.
        what: String,
        /// What was wrong with the answer.
        message: String,
    },
    /// A request the device cannot carry out (outside its travel, not finite, …).
    #[error("{address}: {what}: {message}")]
    Rejected {
        /// The device's address.
        address: String,
        /// What truepos asked for.
        what: String,
        /// Why it cannot be done.
        message: String,
    },
    /// Tracker `k` failed for a reason other than a beam break.
    #[error("tracker {0}: {1}")]
    Tracker(usize, String),
}

/// What a device is, for reports and the audit trail.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceInfo {
    /// The address it was opened with (`virtual`, `linuxcncrsh://HOST:PORT`, `ippdme://HOST:PORT`).
    pub address: String,
    /// The device's own name and version as it reports them (e.g. `LinuxCNC 2.9.0`,
    /// `I++ DME 1.4.3`), or the virtual machine's description.
    pub version: String,
}

/// Fastest single-point probing feed truepos commands, mm/min (83 mm/s).
///
/// Why: a touch-trigger probe stops the machine after the trigger within its overtravel (a few
/// millimetres of stylus deflection); the distance a machine needs to stop grows with the square
/// of the feed, and probe makers give probing feeds of a few hundred to 3000 mm/min. Above
/// 5000 mm/min the machine overruns the overtravel (breaking the stylus) or the controller
/// reports the end of the move as a touch: the result measures nothing. Requests above this are
/// refused before any motion (exit 2).
pub const MAX_PROBING_FEED_MM_MIN: f64 = 5000.0;

/// Slowest probing feed truepos commands, mm/min. Why: a 10 mm approach at this feed already
/// takes ten minutes per point, and controllers write feeds with three decimals, so a feed
/// below 0.0005 mm/min reaches a LinuxCNC probing move as `F0.000`.
pub const MIN_PROBING_FEED_MM_MIN: f64 = 1.0;

/// Why a probing feed (mm/min) is refused: not a positive number, below
/// [`MIN_PROBING_FEED_MM_MIN`] or above [`MAX_PROBING_FEED_MM_MIN`]; `None` when it is within.
/// Checked before any motion (exit 2).
pub fn probing_feed_problem(feed_mm_min: f64) -> Option<String> {
    // Plain digits for the usual sizes, an exponent for the absurd ones (not 300 zeros).
    let f = feed_mm_min;
    let feed_mm_min =
        if f.abs() >= 1e-3 && f.abs() < 1e16 || f == 0.0 { format!("{f}") } else { format!("{f:e}") };
    if !(f.is_finite() && f > 0.0) {
        return Some(format!("the probing feed must be a positive number, got {feed_mm_min} mm/min"));
    }
    if f > MAX_PROBING_FEED_MM_MIN {
        return Some(format!(
            "the probing feed {feed_mm_min} mm/min is above {MAX_PROBING_FEED_MM_MIN} mm/min: a touch probe cannot stop within its overtravel at that speed, so the points would measure nothing"
        ));
    }
    if f < MIN_PROBING_FEED_MM_MIN {
        return Some(format!(
            "the probing feed {feed_mm_min} mm/min is below {MIN_PROBING_FEED_MM_MIN} mm/min: a 10 mm approach would take over ten minutes per point, and a controller writes such a feed as F0"
        ));
    }
    None
}

/// The largest length or coordinate a probing request may state (mm): 100 000 mm = 100 m,
/// beyond the travel of any machine tool or CMM. Requests beyond it (or not finite) are
/// refused before any motion (exit 2) with [`length_beyond_limit`]'s message.
pub const MAX_LENGTH_MM: f64 = 100_000.0;

/// The message for `what` (the option or file field, e.g. "--depth-mm") of `v` mm when `v` is
/// not finite or its magnitude exceeds [`MAX_LENGTH_MM`]; `None` when it is within.
pub fn length_beyond_limit(what: &str, v: f64) -> Option<String> {
    if v.is_finite() && v.abs() <= MAX_LENGTH_MM {
        return None;
    }
    // 1e308 as written, not as 309 digits.
    let shown = if v.abs() < 1e9 || !v.is_finite() { format!("{v}") } else { format!("{v:e}") };
    Some(format!(
        "{what} {shown} mm is beyond ±{MAX_LENGTH_MM} mm (100 m), the physical limit: no machine tool or CMM travels that far"
    ))
}

/// One single-point probing: touch the surface near `nominal_mm` coming from outside the
/// material along `-approach`.
///
/// The tip centre starts at `nominal_mm + (approach_mm + tip_radius_mm)·approach`, moves along
/// `-approach` at `feed_mm_s` until the probe triggers, at most to
/// `nominal_mm + (tip_radius_mm − search_mm)·approach`, latches, then retracts by `retract_mm`
/// along `approach`. (The same geometry as I++ DME's `PtMeas` with its Approach/Search/Retract
/// properties.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeRequest {
    /// Nominal surface point (machine frame, mm).
    pub nominal_mm: Point3,
    /// Unit vector pointing out of the material at the nominal point.
    pub approach: Vector3,
    /// Radius of the stylus ball (mm).
    pub tip_radius_mm: f64,
    /// Distance between the ball and the nominal surface at the start of the probing move (mm).
    pub approach_mm: f64,
    /// How far beyond the nominal surface the move may go before it ends without contact (mm).
    pub search_mm: f64,
    /// Retract distance along `approach` after the contact (mm).
    pub retract_mm: f64,
    /// Probing feed (mm/s).
    pub feed_mm_s: f64,
}

impl ProbeRequest {
    /// A probing that starts `clearance_mm` before the nominal surface point (along `approach`,
    /// out of the material), searches as far beyond it, and retracts back to its start.
    pub fn with_clearance(
        nominal_mm: Point3,
        approach: Vector3,
        tip_radius_mm: f64,
        clearance_mm: f64,
        feed_mm_s: f64,
    ) -> ProbeRequest {
        ProbeRequest {
            nominal_mm,
            approach,
            tip_radius_mm,
            approach_mm: clearance_mm,
            search_mm: clearance_mm,
            retract_mm: clearance_mm,
            feed_mm_s,
        }
    }

    /// Tip-centre position where the probing move starts.
    pub fn start_mm(&self) -> Point3 {
        self.nominal_mm + self.approach * (self.approach_mm + self.tip_radius_mm)
    }
    /// Tip-centre position where the probing move ends if nothing is touched.
    pub fn end_mm(&self) -> Point3 {
        self.nominal_mm + self.approach * (self.tip_radius_mm - self.search_mm)
    }
}

/// The result of one probing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeHit {
    /// Tip-centre position latched at the contact (machine frame, mm).
    pub tip_center_mm: Point3,
    /// Unit surface normal at the contact, if the device reports one (I++ DME does).
    pub normal: Option<Vector3>,
}

/// A tool (stylus) of a machine as the machine reports it ([`ProbingMachine::select_tool`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ToolInfo {
    /// The machine's name of the tool (as selected).
    pub name: String,
    /// The calibrated tip radius the machine uses (mm).
    pub tip_radius_mm: f64,
}

/// The rotary axes a probing machine orients its head and table with
/// ([`ProbingMachine::rotary_axes`]), as the head-offset contract defines them: B swivels the
/// head about Y, C turns the table about an axis parallel to Z.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RotaryAxes {
    /// Whether the machine has a B axis swivelling the head about Y.
    pub head_b: bool,
    /// Whether the machine has a C axis turning the table about Z.
    pub table_c: bool,
}

impl RotaryAxes {
    /// "B and C", "B", "C" or "none", for messages.
    pub fn describe(&self) -> &'static str {
        match (self.head_b, self.table_c) {
            (true, true) => "B (head) and C (table)",
            (true, false) => "B (head) only",
            (false, true) => "C (table) only",
            (false, false) => "no rotary axes",
        }
    }
}

/// The kinematics of a five-axis machine whose controller turns programme positions with its
/// rotary axes ([`ProbingMachine::rotary_kinematics`]): tool-centre-point control (TCP).
///
/// With TCP, every position the machine reports and takes is in the *programme frame*, which
/// moves with the table (at B = C = 0 it coincides with the machine frame), and
/// [`ProbingMachine::orient`] keeps the tip fixed in that frame while the axes turn. Where the
/// controller believes the table is depends on the geometry its kinematics module is configured
/// with ([`ProbingMachine::kinematics_parameters`]); `truepos-kinematics` identifies it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RotaryKinematics {
    /// truepos's name of the model (`xyzbc-trt`: a B tilting table carrying a C rotary table).
    pub model: String,
    /// The controller's own name of its kinematics module (`xyzbc-trt-kins` in LinuxCNC).
    pub module: String,
}

/// One geometry parameter of a controller's kinematics module (a LinuxCNC kinematics pin), in
/// mm.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicsParameter {
    /// The module's own name of the parameter (`x-rot-point`).
    pub name: String,
    /// The parameter's value, mm.
    pub value_mm: f64,
}

/// A machine with a touch-trigger (or scanning) probe: a CMM, or a machine tool with a
/// spindle probe. Positions are tip-centre positions in the machine frame (mm) — as the NC
/// knows them: with a head whose offset is being calibrated, they are the NC's head reference
/// point P (the head-offset contract's x, y, z), not the physical tip centre.
///
/// Implementations must never release an e-stop or switch a machine on; opening one checks that
/// the machine is on, homed and idle and returns [`DeviceError::NotReady`] otherwise. Every wait
/// has a timeout.
pub trait ProbingMachine {
    /// Address and version, for reports and the audit trail.
    fn info(&self) -> DeviceInfo;
    /// Where the tip centre is now.
    fn position(&mut self) -> Result<Point3, DeviceError>;
    /// A straight positioning move (not probing). A probe trigger during it is an error.
    /// Callers plan their own clearance moves.
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError>;
    /// Probe one point as [`ProbeRequest`] describes. No contact within the search distance is
    /// [`DeviceError::NoContact`], with the machine back at the start point.
    fn probe(&mut self, request: &ProbeRequest) -> Result<ProbeHit, DeviceError>;
    /// Stop all motion now (best effort; also used on the way out of a failure).
    fn abort(&mut self) -> Result<(), DeviceError>;
    /// The speed of the following positioning moves (mm/s), where the machine lets a client set
    /// it (a DMIS `FEDRAT/POSVEL`). Default: the machine keeps its own speed (a positioning
    /// speed changes no measured value).
    fn set_move_speed(&mut self, mm_s: f64) -> Result<(), DeviceError> {
        let _ = mm_s;
        Ok(())
    }
    /// The names of the tools (styli) the machine can select, where it can list them (default:
    /// none listed — the machine has one stylus, or cannot say).
    fn tool_names(&mut self) -> Result<Vec<String>, DeviceError> {
        Ok(Vec::new())
    }
    /// Make the tool `name` active (a tool change where the machine needs one) and return it with
    /// the tip radius the machine uses for it. Default: refused (no tool table).
    fn select_tool(&mut self, name: &str) -> Result<ToolInfo, DeviceError> {
        Err(DeviceError::Rejected {
            address: self.info().address,
            what: format!("selecting the tool {name}"),
            message: "this machine has no tool table".into(),
        })
    }
    /// The rotary axes this machine can orient (default: none, a 3-axis machine).
    fn rotary_axes(&self) -> RotaryAxes {
        RotaryAxes::default()
    }
    /// Swivel the head to `b_deg` and turn the table to `c_deg` (degrees), where the machine has
    /// those axes. The caller first moves the probe clear of everything. The default (no rotary
    /// axes) accepts only B = C = 0, the one orientation a 3-axis machine has.
    fn orient(&mut self, b_deg: f64, c_deg: f64) -> Result<(), DeviceError> {
        if b_deg == 0.0 && c_deg == 0.0 {
            return Ok(());
        }
        Err(DeviceError::Rejected {
            address: self.info().address,
            what: format!("orienting the head to B = {b_deg}°, C = {c_deg}°"),
            message: "this machine has no rotary axes (B, C)".into(),
        })
    }
    /// Where a five-axis machine's controller turns positions with its rotary axes (TCP), its
    /// kinematics ([`RotaryKinematics`]); then positions are in the programme frame, `orient`
    /// keeps the tip fixed in it, and B may tilt the table rather than the head. Default: none
    /// (positions are machine coordinates, as on every machine before).
    fn rotary_kinematics(&self) -> Option<RotaryKinematics> {
        None
    }
    /// The rotary axes' angles now (B, C in degrees). The default knows only machines without
    /// rotary axes (always 0, 0); machines with axes override it.
    fn orientation(&mut self) -> Result<(f64, f64), DeviceError> {
        let axes = self.rotary_axes();
        if !axes.head_b && !axes.table_c && self.rotary_kinematics().is_none() {
            return Ok((0.0, 0.0));
        }
        Err(DeviceError::Rejected {
            address: self.info().address,
            what: "reading the rotary axes' angles".into(),
            message: "this machine does not report them".into(),
        })
    }
    /// The geometry its kinematics module is configured with now, read from the running
    /// controller (default: not available).
    fn kinematics_parameters(&mut self) -> Result<Vec<KinematicsParameter>, DeviceError> {
        Err(DeviceError::Rejected {
            address: self.info().address,
            what: "reading the kinematics parameters".into(),
            message: "this machine's kinematics cannot be read".into(),
        })
    }
    /// Write kinematics parameters into the running controller. Implementations refuse unless
    /// the machine is idle at B = C = 0, where the geometry moves no joint, and read the values
    /// back (default: not available).
    fn set_kinematics_parameters(&mut self, values: &[KinematicsParameter]) -> Result<(), DeviceError> {
        let _ = values;
        Err(DeviceError::Rejected {
            address: self.info().address,
            what: "writing the kinematics parameters".into(),
            message: "this machine's kinematics cannot be written".into(),
        })
    }
}

/// One position command of servo-rate scanning ([`ScanningMachine::follow`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanCommand {
    /// Where the tip centre is to be at the end of the control period (machine frame, mm).
    pub tip_center_mm: Point3,
    /// Index of the feature being measured, `None` on transfers (paths that are collision-free
    /// by construction). A real machine ignores it; the virtual CMM, whose true part is a set of
    /// unbounded feature surfaces, uses it to choose the surface the stylus can touch.
    pub feature: Option<usize>,
}

/// What a scanning machine measured at the end of one control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanSample {
    /// Position of the probe's reference point as the axis scales read it (machine frame, mm).
    pub scale_mm: Point3,
    /// Stylus deflection as the scanning probe measures it (machine frame, mm).
    pub deflection_mm: Vector3,
}

impl ScanSample {
    /// The measured tip centre: scale position plus probe deflection.
    pub fn tip_center_mm(&self) -> Point3 {
        self.scale_mm + self.deflection_mm
    }
}

/// A scan the machine's own controller carries out along a circle (I++ DME `ScanOnCircle`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleScanRequest {
    /// Circle centre (machine frame, mm).
    pub center_mm: Point3,
    /// Nominal surface point where the scan starts (on the circle).
    pub start_mm: Point3,
    /// Unit normal of the circle's plane.
    pub normal: Vector3,
    /// Angle to scan (degrees, signed about `normal`).
    pub delta_deg: f64,
    /// Surface angle: 0 outside (boss), 180 inside (bore), 90/270 on a plane.
    pub surface_angle_deg: f64,
    /// Nominal distance between reported points (mm).
    pub step_mm: f64,
}

/// A scan the machine's own controller carries out along a line (I++ DME `ScanOnLine`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineScanRequest {
    /// Nominal surface point where the scan starts (machine frame, mm).
    pub start_mm: Point3,
    /// Nominal surface point where the scan ends (machine frame, mm).
    pub end_mm: Point3,
    /// Unit surface normal, out of the material.
    pub normal: Vector3,
    /// Nominal distance between reported points (mm).
    pub step_mm: f64,
}

/// A machine with an analogue scanning probe (a CMM, or a machine tool with a scanning spindle
/// probe). Positions are tip-centre positions in the machine frame (mm).
///
/// Two ways to scan, and a backend offers what its controller can do:
/// - servo-rate path following ([`ScanningMachine::begin`] then [`ScanningMachine::follow`] once
///   per control period): truepos plans the path and closes the deflection loop itself (the
///   blended scans of `truepos-scan`). The virtual CMM does this; a real controller needs a
///   streaming position interface at its servo rate (LinuxCNC with a HAL streamer).
/// - controller-run scans ([`ScanningMachine::scan_on_circle`], [`ScanningMachine::scan_on_line`]):
///   the controller plans and scans and reports the points (I++ DME).
///
/// Every method a backend does not offer returns [`DeviceError::Rejected`] (the defaults do).
pub trait ScanningMachine {
    /// Address and version, for reports and the audit trail.
    fn info(&self) -> DeviceInfo;
    /// The control period of [`ScanningMachine::follow`] (s).
    fn control_period_s(&self) -> f64;
    /// Prepare servo-rate following with the tip centre at rest at `start_mm` and a stylus of
    /// `tip_radius_mm` (a real machine checks that its stylus has that radius).
    fn begin(&mut self, start_mm: Point3, tip_radius_mm: f64) -> Result<(), DeviceError> {
        let _ = (start_mm, tip_radius_mm);
        Err(self.unsupported("servo-rate scanning"))
    }
    /// Command the tip centre to `command.tip_center_mm` at the end of the next control period
    /// (the command ramps linearly over the period) and return what the machine measured then.
    fn follow(&mut self, command: &ScanCommand) -> Result<ScanSample, DeviceError> {
        let _ = command;
        Err(self.unsupported("servo-rate scanning"))
    }
    /// Scan along a circle with the controller's own path control; the measured tip centres
    /// with their surface normals.
    fn scan_on_circle(&mut self, request: &CircleScanRequest) -> Result<Vec<ProbeHit>, DeviceError> {
        let _ = request;
        Err(self.unsupported("ScanOnCircle"))
    }
    /// Scan along a line with the controller's own path control.
    fn scan_on_line(&mut self, request: &LineScanRequest) -> Result<Vec<ProbeHit>, DeviceError> {
        let _ = request;
        Err(self.unsupported("ScanOnLine"))
    }
    /// The error every unsupported method returns.
    fn unsupported(&self, what: &str) -> DeviceError {
        DeviceError::Rejected {
            address: self.info().address,
            what: what.to_string(),
            message: "this machine does not support it".to_string(),
        }
    }
}

/// A laser tracker with its alignment to the machine: readings in the tracker frame become
/// machine-frame positions through `machine_from_tracker`.
pub struct TrackerSetup<T> {
    /// The tracker itself (readings in its own frame).
    pub tracker: T,
    /// Transform from the tracker frame to the machine frame (mm).
    pub machine_from_tracker: truepos_math::Transform3,
}

/// Why a tracker reading failed.
#[derive(Debug, Error, Clone, Copy, PartialEq, Eq)]
pub enum TrackerFault {
    /// The beam is interrupted: no line of sight to the reflector.
    #[error("beam broken (no line of sight to the reflector)")]
    BeamBroken,
    /// The tracker lost the reflector; it must be brought back into the beam.
    #[error("the tracker lost the reflector and needs it brought back")]
    Lost,
}

/// An NC controller fed one block at a time.
pub trait Controller {
    /// Execute one block; returns when the machine has come to its commanded stop.
    /// `target_mm` is the block's commanded end position (program frame = machine frame) if
    /// it moves. The controller adds its external correction offset to every target.
    fn send_block(&mut self, line: usize, text: &str, target_mm: Option<Point3>) -> Result<(), DeviceError>;
    /// An incremental correction move, which also shifts the external offset by `delta_mm`.
    fn correct(&mut self, delta_mm: Vector3) -> Result<(), DeviceError>;
    /// The external correction offset now in force.
    fn offset(&self) -> Vector3;
    /// Move to a commanded position (plus offset), for look-back recovery.
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError>;
    /// Let time pass (waiting for the machine to settle, for an operator, …).
    fn wait(&mut self, seconds: f64);
    /// Time since the start of the run (s).
    fn now_s(&self) -> f64;
}

/// A laser tracker measuring the end effector's reflector.
pub trait Tracker {
    /// One reading of the reflector (tracker frame, mm).
    fn measure(&mut self) -> Result<Point3, TrackerFault>;
    /// Point the beam at a position (tracker frame) and lock on when the reflector arrives.
    /// Only absolute-distance (ADM) trackers can reacquire this way.
    fn point_at(&mut self, p: Point3) -> Result<(), TrackerFault>;
    /// Whether the tracker has an absolute distance meter (it can then reacquire by `point_at`).
    fn has_adm(&self) -> bool;
    /// Set the refractive index the tracker uses for its distances.
    fn set_refractive_index(&mut self, n: f64);
    /// The refractive index the tracker uses for its distances.
    fn refractive_index(&self) -> f64;
    /// Standard uncertainty (mm) of a reading at `p` (tracker frame), for fusion weights.
    fn sigma_mm(&self, p: &Point3) -> f64;
}

/// Differential inclinometer readings (µrad, two tilt components each).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Inclinations {
    /// Inclinometer on the machine, two tilt components, µrad.
    pub machine: [f64; 2],
    /// Inclinometer on the part, two tilt components, µrad.
    pub part: [f64; 2],
    /// Inclinometer on the tracker, two tilt components, µrad.
    pub tracker: [f64; 2],
}

impl Inclinations {
    /// The largest change of any component relative to `base`.
    pub fn max_change(&self, base: &Inclinations) -> f64 {
        let mut m = 0.0f64;
        for (a, b) in [(self.machine, base.machine), (self.part, base.part), (self.tracker, base.tracker)] {
            for k in 0..2 {
                m = m.max((a[k] - b[k]).abs());
            }
        }
        m
    }
}

/// The rest of the cell: sensors and the targets the trackers measure directly.
pub trait Cell {
    /// Part temperature (°C).
    fn temperature_c(&mut self) -> f64;
    /// The air's temperature, pressure, humidity and CO2 content now.
    fn air(&mut self) -> AirConditions;
    /// The inclinometers' readings now.
    fn inclinations(&mut self) -> Inclinations;
    /// Tracker `k`'s readings of the part's targets (id, tracker frame) — for real-time
    /// orientation and auto-scaling. Nominal positions are in [`Cell::part_nominal`].
    fn measure_part_targets(&mut self, k: usize) -> Vec<(String, Point3)>;
    /// Nominal positions of the part's targets at the reference temperature (program frame).
    fn part_nominal(&self) -> Vec<(String, Point3)>;
    /// Tracker `k`'s readings of the machine's reference targets (tracker frame) — for
    /// (re-)aligning the tracker to the machine.
    fn measure_machine_targets(&mut self, k: usize) -> Vec<(String, Point3)>;
    /// The calibrated machine-frame positions of the machine's reference targets (mm).
    fn machine_targets(&self) -> Vec<(String, Point3)>;
    /// An operator brings the reflector back into the beam (manual recovery).
    fn operator_restores_beam(&mut self, k: usize);
}

/// A [`ProbingMachine`] that stops commanding motion once `stop` gives a reason (an operator's
/// SIGINT, a deadline): every move, probe, tool change and orientation first asks, and a stop
/// is [`DeviceError::Rejected`] with that reason — the machine is left where its last completed
/// command put it (a probing cycle always ends retracted). Reading the position and `abort`
/// still pass through.
pub struct Stoppable<'a, M: ProbingMachine + ?Sized> {
    inner: &'a mut M,
    stop: &'a dyn Fn() -> Option<String>,
}

impl<'a, M: ProbingMachine + ?Sized> Stoppable<'a, M> {
    /// Wrap `inner` so that every motion first asks `stop` for a reason to refuse.
    pub fn new(inner: &'a mut M, stop: &'a dyn Fn() -> Option<String>) -> Self {
        Stoppable { inner, stop }
    }

    fn check(&self, what: &str) -> Result<(), DeviceError> {
        match (self.stop)() {
            None => Ok(()),
            Some(reason) => Err(DeviceError::Rejected {
                address: self.inner.info().address,
                what: what.to_string(),
                message: format!("{reason}: no further motion"),
            }),
        }
    }
}

impl<M: ProbingMachine + ?Sized> ProbingMachine for Stoppable<'_, M> {
    fn info(&self) -> DeviceInfo {
        self.inner.info()
    }
    fn position(&mut self) -> Result<Point3, DeviceError> {
        self.inner.position()
    }
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        self.check("moving")?;
        self.inner.move_to(target_mm)
    }
    fn probe(&mut self, request: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        self.check("probing")?;
        self.inner.probe(request)
    }
    fn abort(&mut self) -> Result<(), DeviceError> {
        self.inner.abort()
    }
    fn set_move_speed(&mut self, mm_s: f64) -> Result<(), DeviceError> {
        self.inner.set_move_speed(mm_s)
    }
    fn tool_names(&mut self) -> Result<Vec<String>, DeviceError> {
        self.inner.tool_names()
    }
    fn select_tool(&mut self, name: &str) -> Result<ToolInfo, DeviceError> {
        self.check("changing the tool")?;
        self.inner.select_tool(name)
    }
    fn rotary_axes(&self) -> RotaryAxes {
        self.inner.rotary_axes()
    }
    fn orient(&mut self, b_deg: f64, c_deg: f64) -> Result<(), DeviceError> {
        self.check("orienting")?;
        self.inner.orient(b_deg, c_deg)
    }
    fn rotary_kinematics(&self) -> Option<RotaryKinematics> {
        self.inner.rotary_kinematics()
    }
    fn orientation(&mut self) -> Result<(f64, f64), DeviceError> {
        self.inner.orientation()
    }
    fn kinematics_parameters(&mut self) -> Result<Vec<KinematicsParameter>, DeviceError> {
        self.inner.kinematics_parameters()
    }
    fn set_kinematics_parameters(&mut self, values: &[KinematicsParameter]) -> Result<(), DeviceError> {
        self.check("writing the kinematics parameters")?;
        self.inner.set_kinematics_parameters(values)
    }
}

#[cfg(test)]
mod stoppable_tests {
    use super::*;
    use std::cell::Cell;

    /// A machine that counts the moves it was sent.
    struct Counting(usize);
    impl ProbingMachine for Counting {
        fn info(&self) -> DeviceInfo {
            DeviceInfo { address: "test".into(), version: "t".into() }
        }
        fn position(&mut self) -> Result<Point3, DeviceError> {
            Ok(Point3::origin())
        }
        fn move_to(&mut self, _: Point3) -> Result<(), DeviceError> {
            self.0 += 1;
            Ok(())
        }
        fn probe(&mut self, _: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
            unreachable!("not probed in this test")
        }
        fn abort(&mut self) -> Result<(), DeviceError> {
            Ok(())
        }
    }

    #[test]
    fn no_motion_is_sent_after_a_stop() {
        let mut m = Counting(0);
        let stopped = Cell::new(false);
        let stop = || stopped.get().then(|| "interrupted by SIGINT".to_string());
        {
            let mut s = Stoppable::new(&mut m, &stop);
            s.move_to(Point3::origin()).unwrap();
            stopped.set(true);
            let e = s.move_to(Point3::origin()).unwrap_err().to_string();
            assert!(e.contains("interrupted by SIGINT") && e.contains("no further motion"), "{e}");
            assert!(s.position().is_ok() && s.abort().is_ok(), "reading and stopping still pass");
        }
        assert_eq!(m.0, 1);
    }
}

impl truepos_math::exit::HasExitClass for DeviceError {
    /// A device failure (exit 3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        truepos_math::exit::ExitClass::Device
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probe_request_start_and_end_follow_ptmeas_geometry() {
        let r = ProbeRequest {
            nominal_mm: Point3::new(10.0, 0.0, 5.0),
            approach: Vector3::new(0.0, 0.0, 1.0),
            tip_radius_mm: 1.5,
            approach_mm: 2.0,
            search_mm: 4.0,
            retract_mm: 2.0,
            feed_mm_s: 1.0,
        };
        assert_eq!(r.start_mm(), Point3::new(10.0, 0.0, 8.5));
        assert_eq!(r.end_mm(), Point3::new(10.0, 0.0, 2.5));
    }
}
