//! [`LinuxCnc`]: a LinuxCNC 2.9 machine driven through one linuxcncrsh session, behind
//! [`ProbingMachine`] and [`Controller`].
//!
//! Opening a session: `hello`, `set echo off`, `set verbose on`, `set enable`, `set set_wait
//! done` (every `set` then returns when the command is done), then the readiness checks: out of
//! e-stop, machine on, every axis joint homed, no program running. truepos never releases an
//! e-stop, switches the machine on or homes it: a machine that is not ready is
//! [`DeviceError::NotReady`] naming what is missing. It then selects MDI mode, `G21 G90 G94`,
//! reads the controller's version (`#<_vmajor>`, `#<_vminor>`) and the translation between
//! the coordinates MDI words are read in and machine coordinates (`abs_cmd_pos −
//! rel_cmd_pos`: work offsets, G92, tool length), so every position truepos sees and sends is in
//! machine coordinates.
//!
//! Every MDI line is followed by `get error` until `ERROR OK` (linuxcncrsh acknowledges MDI lines
//! that then fail, and queues the messages); any message is [`DeviceError::Controller`] with
//! the controller's own words. After every move, `abs_cmd_pos` must equal the commanded
//! position (a feed hold, abort or e-stop that ended it early is an error, not a silent short
//! move). Probing is `G38.2`; the latched point is read back with `(debug,TAG #5061 #5062
//! #5063 #5070)` and `get operator_display`, with a fresh tag per point (after a failed probe
//! the parameters and the display still hold the previous point). Every wait has a deadline.

use crate::hal::{agrees, Hal};
use crate::session::Session;
use crate::url::{Address, AddressError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use truepos_device::{
    Controller, DeviceError, DeviceInfo, KinematicsParameter, ProbeHit, ProbeRequest, ProbingMachine,
    RotaryAxes, RotaryKinematics,
};
use truepos_math::{Point3, Vector3};

/// Tunables of a session. `Default` suits a machine tool with a spindle probe.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Connecting and the greeting.
    pub connect_timeout: Duration,
    /// Commands that do not move the machine.
    pub answer_timeout: Duration,
    /// Margin added to the expected duration of every move.
    pub move_margin: Duration,
    /// Feed of [`ProbingMachine::move_to`] positioning moves (G1), mm/min.
    pub positioning_feed_mm_min: f64,
    /// The slowest rapid (G0) speed assumed for timeouts (mm/s).
    pub slowest_rapid_mm_s: f64,
    /// How many joints must be homed (the machine's linear axes).
    pub joints: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            connect_timeout: Duration::from_secs(4),
            answer_timeout: Duration::from_secs(5),
            move_margin: Duration::from_secs(10),
            positioning_feed_mm_min: 3000.0,
            slowest_rapid_mm_s: 10.0,
            joints: 3,
        }
    }
}

/// Tolerance on the commanded end position of a move (linuxcncrsh prints 6 decimals).
const POSITION_TOL_MM: f64 = 2e-6;

/// A LinuxCNC machine through linuxcncrsh.
pub struct LinuxCnc {
    session: Session,
    address: String,
    version: String,
    options: Options,
    /// machine = program + this (work offsets, G92, tool length: a translation).
    machine_minus_program: Vector3,
    nonce: u32,
    tags: u64,
    /// End-point control: the correction offset and the last commanded machine position.
    offset: Vector3,
    commanded: Option<Point3>,
    t0: Instant,
    /// The controller's host (for halcmd, which works only there).
    host: String,
    /// A five-axis kinematics module found by [`LinuxCnc::attach_kinematics`], and halcmd.
    kinematics: Option<(RotaryKinematics, Hal)>,
}

/// The geometry pins of `xyzbc-trt-kins` truepos reads and may write (tool-offset is read only).
const TRT_PINS: [&str; 5] = ["x-rot-point", "y-rot-point", "z-rot-point", "x-offset", "z-offset"];

fn fmt_mm(v: f64) -> String {
    let s = format!("{v:.6}");
    if s == "-0.000000" {
        "0.000000".into()
    } else {
        s
    }
}

fn fmt_point(p: &Point3) -> String {
    format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z)
}

impl LinuxCnc {
    /// Open `linuxcncrsh://HOST:PORT[?password=…]` with default options.
    pub fn open(url: &str) -> Result<LinuxCnc, DeviceError> {
        let address = Address::parse(url).map_err(|e: AddressError| DeviceError::Connect {
            address: url.split('?').next().unwrap_or(url).to_string(),
            message: e.to_string(),
        })?;
        LinuxCnc::open_address(&address, Options::default())
    }

    /// Open a session and check that the machine is ready (see the module docs).
    pub fn open_address(address: &Address, options: Options) -> Result<LinuxCnc, DeviceError> {
        let name = address.to_string();
        let mut session = Session::connect(&name, &address.socket_address(), options.connect_timeout)?;
        let greet = session.command(
            &format!("hello {} truepos 1.1", address.password),
            "greeting (hello)",
            options.connect_timeout,
        )?;
        if !greet.starts_with("HELLO ACK") {
            return Err(DeviceError::Connect {
                address: name,
                message: if greet.starts_with("HELLO NAK") {
                    "linuxcncrsh refused the connect password (HELLO NAK)".into()
                } else {
                    format!("not a linuxcncrsh greeting: `{greet}`")
                },
            });
        }
        let protocol = greet.trim_start_matches("HELLO ACK").trim().to_string();
        // `set echo off` is itself echoed once; `set verbose on` then acknowledges every set.
        session.send("set echo off", "setting echo off")?;
        session.send("set verbose on", "setting verbose on")?;
        let deadline = Instant::now() + options.answer_timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let l = session.read_line("setting verbose on", left)?;
            if l == "SET VERBOSE ACK" {
                break;
            }
            if !l.eq_ignore_ascii_case("set echo off") && !l.eq_ignore_ascii_case("set verbose on") {
                return Err(DeviceError::Protocol {
                    address: name,
                    what: "setting verbose on".into(),
                    message: format!("unexpected answer `{l}`"),
                });
            }
        }
        let nonce = (SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.subsec_nanos()).unwrap_or(0)
            ^ std::process::id().rotate_left(16))
            & 0x00ff_ffff;
        let mut m = LinuxCnc {
            session,
            address: name,
            version: String::new(),
            options,
            machine_minus_program: Vector3::zeros(),
            nonce,
            tags: 0,
            offset: Vector3::zeros(),
            commanded: None,
            t0: Instant::now(),
            host: address.host.clone(),
            kinematics: None,
        };
        let enable = format!("set enable {}", address.enable_password);
        if !m.set(&enable, "enable", "enabling commands", m.options.answer_timeout)? {
            return Err(DeviceError::Connect {
                address: m.address.clone(),
                message: "linuxcncrsh refused the enable password (SET ENABLE NAK)".into(),
            });
        }
        m.set_ack("set set_wait done", "set_wait", "selecting wait-until-done")?;
        m.check_ready("opening the session")?;
        m.set_ack("set mode mdi", "mode", "selecting MDI mode")?;
        m.mdi("G21 G90 G94", "selecting mm, absolute, feed per minute", m.options.answer_timeout)?;
        let v = m.debug_values("TV", "#<_vmajor> #<_vminor>", 2, "reading the version")?;
        m.version = format!("LinuxCNC {}.{} (linuxcncrsh {protocol})", trim_number(v[0]), trim_number(v[1]));
        let abs = m.get_vec3("abs_cmd_pos", "reading the commanded position")?;
        let rel = m.get_vec3("rel_cmd_pos", "reading the commanded position")?;
        m.machine_minus_program = abs - rel;
        m.commanded = Some(Point3::from(abs));
        m.t0 = Instant::now();
        Ok(m)
    }

    /// The address (without passwords).
    pub fn address(&self) -> &str {
        &self.address
    }

    /// The controller's version as it reports it.
    pub fn version(&self) -> &str {
        &self.version
    }

    /// Translation from MDI (program) coordinates to machine coordinates found at opening.
    pub fn machine_minus_program(&self) -> Vector3 {
        self.machine_minus_program
    }

    fn protocol(&self, what: &str, message: String) -> DeviceError {
        DeviceError::Protocol { address: self.address.clone(), what: what.into(), message }
    }

    /// `set …` → whether ACK. `name` is the command word as linuxcncrsh echoes it.
    fn set(&mut self, line: &str, name: &str, what: &str, timeout: Duration) -> Result<bool, DeviceError> {
        let a = self.session.command(line, what, timeout)?;
        let ack = format!("SET {} ACK", name.to_ascii_uppercase());
        let nak = format!("SET {} NAK", name.to_ascii_uppercase());
        if a == ack {
            Ok(true)
        } else if a == nak {
            Ok(false)
        } else {
            Err(self.protocol(what, format!("`{line}` answered `{a}`")))
        }
    }

    fn set_ack(&mut self, line: &str, name: &str, what: &str) -> Result<(), DeviceError> {
        if self.set(line, name, what, self.options.answer_timeout)? {
            Ok(())
        } else {
            let msgs = self.drain_errors(what)?;
            Err(DeviceError::Controller {
                address: self.address.clone(),
                what: what.into(),
                message: if msgs.is_empty() {
                    format!("`{line}` was refused (NAK)")
                } else {
                    msgs.join("; ")
                },
            })
        }
    }

    /// `get name` → the answer's words after the name.
    fn get(&mut self, name: &str, what: &str) -> Result<Vec<String>, DeviceError> {
        let a = self.session.command(&format!("get {name}"), what, self.options.answer_timeout)?;
        let upper = name.to_ascii_uppercase();
        match a.split_once(' ') {
            Some((head, rest)) if head == upper => Ok(rest.split_whitespace().map(str::to_string).collect()),
            None if a == upper => Ok(vec![]),
            _ => Err(self.protocol(what, format!("`get {name}` answered `{a}`"))),
        }
    }

    fn get_vec3(&mut self, name: &str, what: &str) -> Result<Vector3, DeviceError> {
        let w = self.get(name, what)?;
        let v: Vec<f64> = w.iter().take(3).filter_map(|s| s.parse::<f64>().ok()).collect();
        if v.len() < 3 || !v.iter().all(|x| x.is_finite()) {
            return Err(self.protocol(what, format!("`get {name}` answered `{}`", w.join(" "))));
        }
        Ok(Vector3::new(v[0], v[1], v[2]))
    }

    /// Every queued error message (`get error` until `ERROR OK`).
    fn drain_errors(&mut self, what: &str) -> Result<Vec<String>, DeviceError> {
        let mut out = vec![];
        for _ in 0..32 {
            let a = self.session.command("get error", what, self.options.answer_timeout)?;
            let msg = a.strip_prefix("ERROR").map(str::trim).ok_or_else(|| DeviceError::Protocol {
                address: self.address.clone(),
                what: what.into(),
                message: format!("`get error` answered `{a}`"),
            })?;
            if msg == "OK" {
                return Ok(out);
            }
            out.push(msg.to_string());
        }
        Ok(out)
    }

    /// Send one MDI line, wait until it is done (within `timeout`), and surface every error.
    fn mdi(&mut self, line: &str, what: &str, timeout: Duration) -> Result<(), DeviceError> {
        let ack = match self.set(&format!("set mdi {line}"), "mdi", what, timeout) {
            Ok(a) => a,
            Err(e @ DeviceError::Timeout { .. }) => {
                // Stop the machine before reporting: the move is still under way.
                let _ = self.session.resync_with_abort(self.options.answer_timeout);
                return Err(e);
            }
            Err(e) => return Err(e),
        };
        let mut msgs = self.drain_errors(what)?;
        if !ack && msgs.is_empty() {
            // The message of a refused line may arrive a moment after the NAK.
            std::thread::sleep(Duration::from_millis(150));
            msgs = self.drain_errors(what)?;
        }
        if msgs.iter().any(|m| m.contains("without making contact")) {
            return Err(DeviceError::NoContact { address: self.address.clone(), what: what.into() });
        }
        if !msgs.is_empty() || !ack {
            let state = self.not_ready_reason();
            let message = match (msgs.is_empty(), state) {
                (false, Some(state)) => format!("{} ({state})", msgs.join("; ")),
                (false, None) => msgs.join("; "),
                (true, Some(state)) => format!("MDI `{line}` was refused (NAK): {state}"),
                (true, None) => format!(
                    "MDI `{line}` was refused (NAK) without a message (has another linuxcncrsh session \
                     taken the enable?)"
                ),
            };
            return Err(DeviceError::Controller {
                address: self.address.clone(),
                what: what.into(),
                message,
            });
        }
        Ok(())
    }

    /// What keeps the machine from moving, if anything (best effort, for error messages).
    fn not_ready_reason(&mut self) -> Option<String> {
        if self.session.is_out_of_step() {
            return None;
        }
        let estop = self.get("estop", "reading the e-stop state").ok()?;
        if estop.first().map(String::as_str) != Some("OFF") {
            return Some("the machine is in e-stop".into());
        }
        let on = self.get("machine", "reading the machine state").ok()?;
        if on.first().map(String::as_str) != Some("ON") {
            return Some("the machine is off".into());
        }
        None
    }

    /// Out of e-stop, machine on, joints homed, no program running.
    pub fn check_ready(&mut self, when: &str) -> Result<(), DeviceError> {
        let not_ready =
            |address: &str, reason: String| DeviceError::NotReady { address: address.into(), reason };
        let estop = self.get("estop", when)?;
        if estop.first().map(String::as_str) != Some("OFF") {
            return Err(not_ready(
                &self.address,
                "the machine is in e-stop (truepos never releases an e-stop: release it at the machine)"
                    .into(),
            ));
        }
        let on = self.get("machine", when)?;
        if on.first().map(String::as_str) != Some("ON") {
            return Err(not_ready(
                &self.address,
                "the machine is off (truepos never switches a machine on: switch it on at the machine)"
                    .into(),
            ));
        }
        let homed = self.get("joint_homed", when)?;
        let n = self.options.joints;
        if homed.len() < n || homed.iter().take(n).any(|h| h != "YES") {
            let missing: Vec<String> = (0..n)
                .filter(|&j| homed.get(j).map(String::as_str) != Some("YES"))
                .map(|j| j.to_string())
                .collect();
            return Err(not_ready(
                &self.address,
                format!("joint(s) {} not homed (home the machine first)", missing.join(", ")),
            ));
        }
        let status = self.get("program_status", when)?;
        if status.first().map(String::as_str) != Some("IDLE") {
            return Err(not_ready(
                &self.address,
                format!("a program is {} (the machine must be idle)", status.join(" ").to_lowercase()),
            ));
        }
        Ok(())
    }

    /// Evaluate `exprs` with `(debug,TAG …)` and read them back from the operator display.
    fn debug_values(
        &mut self,
        prefix: &str,
        exprs: &str,
        n: usize,
        what: &str,
    ) -> Result<Vec<f64>, DeviceError> {
        self.tags += 1;
        let tag = format!("{prefix}{:06X}N{}", self.nonce, self.tags);
        self.mdi(&format!("(debug,{tag} {exprs})"), what, self.options.answer_timeout)?;
        let w = self.get("operator_display", what)?;
        if w.first().map(String::as_str) != Some(tag.as_str()) {
            return Err(self.protocol(
                what,
                format!("the operator display shows `{}`, not the values tagged {tag}", w.join(" ")),
            ));
        }
        let v: Vec<f64> = w[1..].iter().filter_map(|s| s.parse::<f64>().ok()).collect();
        if v.len() != n || !v.iter().all(|x| x.is_finite()) {
            return Err(self.protocol(what, format!("the operator display shows `{}`", w.join(" "))));
        }
        Ok(v)
    }

    fn to_program(&self, p: &Point3) -> Point3 {
        p - self.machine_minus_program
    }

    fn timeout_for(&self, dist_mm: f64, speed_mm_s: f64) -> Duration {
        let t = if speed_mm_s > 0.0 { dist_mm / speed_mm_s } else { 0.0 };
        Duration::from_secs_f64(t.clamp(0.0, 24.0 * 3600.0) * 1.5) + self.options.move_margin
    }

    /// A straight move to `target` (machine coordinates): G0 (`feed_mm_min` None) or G1.
    fn go(&mut self, target: &Point3, feed_mm_min: Option<f64>, what: &str) -> Result<(), DeviceError> {
        if !target.iter().all(|v| v.is_finite()) {
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what: what.into(),
                message: "the target is not finite".into(),
            });
        }
        let from = match self.commanded {
            Some(p) => p,
            None => Point3::from(self.get_vec3("abs_cmd_pos", what)?),
        };
        let dist = (target - from).norm();
        if dist == 0.0 && self.commanded.is_some() {
            return Ok(());
        }
        let q = self.to_program(target);
        let (line, speed) = match feed_mm_min {
            Some(f) => (format!("G1 X{} Y{} Z{} F{:.3}", fmt_mm(q.x), fmt_mm(q.y), fmt_mm(q.z), f), f / 60.0),
            None => (
                format!("G0 X{} Y{} Z{}", fmt_mm(q.x), fmt_mm(q.y), fmt_mm(q.z)),
                self.options.slowest_rapid_mm_s,
            ),
        };
        // Whatever happens now, the last commanded position is unknown until read back.
        self.commanded = None;
        self.mdi(&line, what, self.timeout_for(dist, speed))?;
        let at = Point3::from(self.get_vec3("abs_cmd_pos", what)?);
        if (at - target).norm() > POSITION_TOL_MM.max(1e-9 * target.coords.norm()) {
            let reason = self.not_ready_reason().map(|r| format!(" ({r})")).unwrap_or_default();
            return Err(DeviceError::Controller {
                address: self.address.clone(),
                what: what.into(),
                message: format!(
                    "the move ended at {} instead of {}{reason}",
                    fmt_point(&at),
                    fmt_point(target)
                ),
            });
        }
        self.commanded = Some(*target);
        Ok(())
    }

    /// Where the machine was commanded to last (machine coordinates), read from the
    /// controller when unknown.
    pub fn commanded_position(&mut self) -> Result<Point3, DeviceError> {
        match self.commanded {
            Some(p) => Ok(p),
            None => Ok(Point3::from(self.get_vec3("abs_cmd_pos", "reading the commanded position")?)),
        }
    }
}

impl LinuxCnc {
    /// Find the controller's five-axis kinematics through halcmd on its host (see
    /// [`crate::hal`]): `xyzbc-trt-kins` with tool-centre-point control selected
    /// (`motion.switchkins-type` 0) makes this machine a five-axis one behind
    /// [`ProbingMachine::rotary_kinematics`]; `maxkins` is reported as such (truepos refuses to
    /// calibrate it); anything else leaves it a 3-axis machine (`Ok(None)`).
    pub fn attach_kinematics(&mut self) -> Result<Option<RotaryKinematics>, DeviceError> {
        let hal = Hal::for_controller(&self.address, &self.host)?;
        let comps = hal.components()?;
        let module = ["xyzbc-trt-kins", "maxkins"].into_iter().find(|m| comps.iter().any(|c| c == m));
        let Some(module) = module else { return Ok(None) };
        if module == "xyzbc-trt-kins" {
            let kins_type = hal.getp("motion.switchkins-type").unwrap_or(0.0);
            if kins_type != 0.0 {
                return Err(DeviceError::NotReady {
                    address: self.address.clone(),
                    reason: format!(
                        "motion.switchkins-type is {kins_type}: the identity kinematics is selected; select \
                         xyzbc-trt (type 0, tool-centre-point) first"
                    ),
                });
            }
        }
        let k = RotaryKinematics {
            model: if module == "xyzbc-trt-kins" { "xyzbc-trt" } else { "maxkins" }.into(),
            module: module.into(),
        };
        self.kinematics = Some((k.clone(), hal));
        Ok(Some(k))
    }

    /// The six axis values of `abs_cmd_pos` or `abs_act_pos` (x y z a b c).
    fn get_axes(&mut self, name: &str, what: &str) -> Result<[f64; 6], DeviceError> {
        let w = self.get(name, what)?;
        let v: Vec<f64> = w.iter().take(6).filter_map(|s| s.parse::<f64>().ok()).collect();
        if v.len() < 6 || !v.iter().all(|x| x.is_finite()) {
            return Err(self.protocol(what, format!("`get {name}` answered `{}`", w.join(" "))));
        }
        Ok([v[0], v[1], v[2], v[3], v[4], v[5]])
    }

    fn hal(&self, what: &str) -> Result<&Hal, DeviceError> {
        self.kinematics.as_ref().map(|k| &k.1).ok_or_else(|| DeviceError::Rejected {
            address: self.address.clone(),
            what: what.into(),
            message: "no five-axis kinematics module was found on this controller".into(),
        })
    }
}

fn trim_number(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

fn check_request(address: &str, r: &ProbeRequest) -> Result<(), DeviceError> {
    let bad = |message: &str| DeviceError::Rejected {
        address: address.into(),
        what: "probe request".into(),
        message: message.into(),
    };
    let finite = r.nominal_mm.iter().chain(r.approach.iter()).all(|v| v.is_finite())
        && [r.tip_radius_mm, r.approach_mm, r.search_mm, r.retract_mm, r.feed_mm_s]
            .iter()
            .all(|v| v.is_finite());
    if !finite {
        return Err(bad("a value is not finite"));
    }
    if (r.approach.norm() - 1.0).abs() > 1e-9 {
        return Err(bad("the approach direction is not a unit vector"));
    }
    if r.feed_mm_s <= 0.0
        || r.search_mm <= 0.0
        || r.approach_mm < 0.0
        || r.retract_mm < 0.0
        || r.tip_radius_mm < 0.0
    {
        return Err(bad("feed and search must be > 0; approach, retract and tip radius ≥ 0"));
    }
    if r.approach_mm + r.search_mm <= 0.0 {
        return Err(bad("the probing move has no length"));
    }
    Ok(())
}

impl ProbingMachine for LinuxCnc {
    fn info(&self) -> DeviceInfo {
        DeviceInfo { address: self.address.clone(), version: self.version.clone() }
    }

    fn position(&mut self) -> Result<Point3, DeviceError> {
        Ok(Point3::from(self.get_vec3("abs_act_pos", "reading the actual position")?))
    }

    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        let what = format!("positioning move to {}", fmt_point(&target_mm));
        let f = self.options.positioning_feed_mm_min;
        self.go(&target_mm, Some(f), &what)
    }

    fn probe(&mut self, r: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        check_request(&self.address, r)?;
        let start = r.start_mm();
        let end = r.end_mm();
        ProbingMachine::move_to(self, start)?;
        let f = r.feed_mm_s * 60.0;
        let what = format!("G38.2 probing move from {} to {} at F{f:.1}", fmt_point(&start), fmt_point(&end));
        let q = self.to_program(&end);
        let line = format!("G38.2 X{} Y{} Z{} F{f:.3}", fmt_mm(q.x), fmt_mm(q.y), fmt_mm(q.z));
        self.commanded = None;
        let timeout = self.timeout_for((end - start).norm(), r.feed_mm_s);
        match self.mdi(&line, &what, timeout) {
            Ok(()) => {}
            Err(e @ DeviceError::NoContact { .. }) => {
                // Leave the machine retracted at the start point.
                let back = format!("retract to {} after the probe move without contact", fmt_point(&start));
                let pf = self.options.positioning_feed_mm_min;
                self.go(&start, Some(pf), &back)?;
                return Err(e);
            }
            Err(e) => return Err(e),
        }
        let v = self.debug_values("TP", "#5061 #5062 #5063 #5070", 4, &what)?;
        if v[3] != 1.0 {
            return Err(self.protocol(&what, format!("the probe result flag #5070 is {} after G38.2", v[3])));
        }
        let hit = Point3::new(v[0], v[1], v[2]) + self.machine_minus_program;
        // Sanity: the latched point lies on the probing segment.
        let seg = end - start;
        let s = (hit - start).dot(&seg) / seg.norm_squared();
        let off_line = ((hit - start) - seg * s).norm();
        if !(-1e-6..=1.0 + 1e-6).contains(&s) || off_line > 1e-4 {
            return Err(self.protocol(
                &what,
                format!("the latched point {} is not on the probing move", fmt_point(&hit)),
            ));
        }
        let retract = hit + r.approach * r.retract_mm;
        let pf = self.options.positioning_feed_mm_min;
        self.go(&retract, Some(pf), &format!("retract after {what}"))?;
        Ok(ProbeHit { tip_center_mm: hit, normal: None })
    }

    fn abort(&mut self) -> Result<(), DeviceError> {
        self.commanded = None;
        if self.session.is_out_of_step() {
            return self.session.resync_with_abort(self.options.answer_timeout);
        }
        self.set_ack("set abort", "abort", "aborting")
    }

    fn rotary_axes(&self) -> RotaryAxes {
        match &self.kinematics {
            // B tilts the table, not a head: only C is what the head-offset contract calls an axis.
            Some((k, _)) if k.model == "xyzbc-trt" => RotaryAxes { head_b: false, table_c: true },
            _ => RotaryAxes::default(),
        }
    }

    fn rotary_kinematics(&self) -> Option<RotaryKinematics> {
        self.kinematics.as_ref().map(|k| k.0.clone())
    }

    fn orientation(&mut self) -> Result<(f64, f64), DeviceError> {
        if self.kinematics.is_none() {
            return Ok((0.0, 0.0));
        }
        let v = self.get_axes("abs_cmd_pos", "reading the rotary axes")?;
        Ok((v[4], v[5]))
    }

    /// `G0 B C` with X, Y, Z unchanged: with tool-centre-point control the tip stays where it is
    /// in the programme frame while the table turns. Checks that B and C arrived and the tip
    /// stayed.
    fn orient(&mut self, b_deg: f64, c_deg: f64) -> Result<(), DeviceError> {
        let what = format!("turning the table to B = {b_deg}°, C = {c_deg}°");
        if self.kinematics.is_none() {
            if b_deg == 0.0 && c_deg == 0.0 {
                return Ok(());
            }
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what,
                message: "no five-axis kinematics is attached to this session (a 3-axis machine)".into(),
            });
        }
        if !(b_deg.is_finite() && c_deg.is_finite()) {
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what,
                message: "the angles are not finite".into(),
            });
        }
        let before = self.get_axes("abs_cmd_pos", &what)?;
        let turn = (b_deg - before[4]).abs().max((c_deg - before[5]).abs());
        // Rapid angular moves: assume at least 10°/s for the deadline.
        let timeout = Duration::from_secs_f64(turn / 10.0 * 1.5) + self.options.move_margin;
        self.commanded = None;
        self.mdi(&format!("G0 B{} C{}", fmt_mm(b_deg), fmt_mm(c_deg)), &what, timeout)?;
        let after = self.get_axes("abs_cmd_pos", &what)?;
        let moved = (0..3).map(|i| (after[i] - before[i]).abs()).fold(0.0, f64::max);
        if (after[4] - b_deg).abs() > 1e-6 || (after[5] - c_deg).abs() > 1e-6 || moved > POSITION_TOL_MM {
            return Err(DeviceError::Controller {
                address: self.address.clone(),
                what,
                message: format!(
                    "the move ended at X {:.4} Y {:.4} Z {:.4} B {:.4} C {:.4} (started at X {:.4} Y {:.4} Z {:.4})",
                    after[0], after[1], after[2], after[4], after[5], before[0], before[1], before[2]
                ),
            });
        }
        self.commanded = Some(Point3::new(after[0], after[1], after[2]));
        Ok(())
    }

    /// The geometry pins of the kinematics module and `tool-offset`, through halcmd.
    fn kinematics_parameters(&mut self) -> Result<Vec<KinematicsParameter>, DeviceError> {
        let hal = self.hal("reading the kinematics parameters")?.clone();
        let module = self.kinematics.as_ref().map(|k| k.0.module.clone()).unwrap_or_default();
        let mut out = vec![];
        for pin in TRT_PINS.iter().chain(&["tool-offset"]) {
            let v = hal.getp(&format!("{module}.{pin}"))?;
            out.push(KinematicsParameter { name: pin.to_string(), value_mm: v });
        }
        Ok(out)
    }

    /// Writes the pins (or the signals they are linked to) with halcmd, only with the machine
    /// idle at B = C = 0, where the geometry moves no joint; reads them back and checks that the
    /// position did not move.
    fn set_kinematics_parameters(&mut self, values: &[KinematicsParameter]) -> Result<(), DeviceError> {
        let what = "writing the kinematics parameters";
        let hal = self.hal(what)?.clone();
        let module = self.kinematics.as_ref().map(|k| k.0.module.clone()).unwrap_or_default();
        let rejected = |address: &str, message: String| DeviceError::Rejected {
            address: address.to_string(),
            what: what.into(),
            message,
        };
        for v in values {
            if !TRT_PINS.contains(&v.name.as_str()) || !v.value_mm.is_finite() {
                return Err(rejected(
                    &self.address,
                    format!("`{}` = {} is not a geometry pin value of {module}", v.name, v.value_mm),
                ));
            }
        }
        self.check_ready(what)?;
        let cmd = self.get_axes("abs_cmd_pos", what)?;
        let act = self.get_axes("abs_act_pos", what)?;
        if cmd[4].abs() > 1e-9 || cmd[5].abs() > 1e-9 || act[4].abs() > 1e-6 || act[5].abs() > 1e-6 {
            return Err(rejected(
                &self.address,
                format!(
                    "the table is at B = {} C = {}: the geometry may be changed only at B = C = 0",
                    act[4], act[5]
                ),
            ));
        }
        for v in values {
            let pin = format!("{module}.{}", v.name);
            hal.set(&pin, v.value_mm)?;
            let read = hal.getp(&pin)?;
            if !agrees(read, v.value_mm) {
                return Err(DeviceError::Controller {
                    address: self.address.clone(),
                    what: what.into(),
                    message: format!("{pin} reads {read} after writing {}", v.value_mm),
                });
            }
        }
        let after = self.get_axes("abs_act_pos", what)?;
        let moved = (0..6).map(|i| (after[i] - act[i]).abs()).fold(0.0, f64::max);
        if moved > 1e-6 {
            return Err(DeviceError::Controller {
                address: self.address.clone(),
                what: what.into(),
                message: format!("the position moved by {moved} while the geometry was written"),
            });
        }
        Ok(())
    }
}

impl Controller for LinuxCnc {
    /// Moves the block's target plus the correction offset with one MDI `G0` (LinuxCNC does
    /// the motion; truepos's own interpreter has found the target). Blocks without a target
    /// are not sent: their other words (spindle, subprograms, M-codes) belong to the machine's
    /// own program, not to the measuring loop.
    fn send_block(&mut self, line: usize, text: &str, target_mm: Option<Point3>) -> Result<(), DeviceError> {
        if let Some(t) = target_mm {
            let target = t + self.offset;
            let what = format!("program line {line} `{}`: move to {}", text.trim(), fmt_point(&target));
            self.go(&target, None, &what)?;
        }
        Ok(())
    }

    fn correct(&mut self, delta_mm: Vector3) -> Result<(), DeviceError> {
        if !delta_mm.iter().all(|v| v.is_finite()) {
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what: "correction move".into(),
                message: "correction is not finite".into(),
            });
        }
        let from = self.commanded_position()?;
        let target = from + delta_mm;
        let what = format!(
            "correction move by ({:.4}, {:.4}, {:.4}) mm to {}",
            delta_mm.x,
            delta_mm.y,
            delta_mm.z,
            fmt_point(&target)
        );
        self.go(&target, None, &what)?;
        self.offset += delta_mm;
        Ok(())
    }

    fn offset(&self) -> Vector3 {
        self.offset
    }

    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        let target = target_mm + self.offset;
        let what = format!("recovery move to {}", fmt_point(&target));
        self.go(&target, None, &what)
    }

    fn wait(&mut self, seconds: f64) {
        if seconds.is_finite() && seconds > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(seconds.min(3600.0)));
        }
    }

    fn now_s(&self) -> f64 {
        self.t0.elapsed().as_secs_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_for_gcode_have_six_decimals_and_no_negative_zero() {
        assert_eq!(fmt_mm(-0.0000001), "0.000000");
        assert_eq!(fmt_mm(12.3456789), "12.345679");
        assert_eq!(trim_number(2.9), "2.9");
        assert_eq!(trim_number(0.0), "0");
    }

    #[test]
    fn probe_requests_are_checked() {
        let ok = ProbeRequest {
            nominal_mm: Point3::new(0.0, 0.0, 10.0),
            approach: Vector3::z(),
            tip_radius_mm: 1.5,
            approach_mm: 2.0,
            search_mm: 2.0,
            retract_mm: 1.0,
            feed_mm_s: 1.0,
        };
        assert!(check_request("a", &ok).is_ok());
        assert!(check_request("a", &ProbeRequest { approach: Vector3::new(0.0, 0.0, 2.0), ..ok }).is_err());
        assert!(check_request("a", &ProbeRequest { feed_mm_s: 0.0, ..ok }).is_err());
        assert!(check_request("a", &ProbeRequest { search_mm: f64::NAN, ..ok }).is_err());
    }
}
