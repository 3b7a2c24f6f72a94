//! The I++ DME client: a CMM as a [`ProbingMachine`] (`--controller ippdme://HOST:PORT`).
//!
//! Entry points: [`connect`] (parse the URL, connect, start a session, check the machine) and
//! [`IppClient`]. Every wait has a timeout; every failure is a [`DeviceError`] naming the
//! address and the command. Positions are exchanged in the machine coordinate system
//! (`SetCoordSystem(MachineCsy)` at connect); the probe request's approach, search and retract
//! distances and feed are set as the active tool's `PtMeasPar` before each `PtMeas`, so the
//! server's PtMeas geometry is exactly [`ProbeRequest`]'s.
//!
//! truepos never homes the machine: a machine that is not homed is [`DeviceError::NotReady`].

use crate::command::{Command, Field, Key, ParBlock, Param, PropItem, PropPath, ToolRef};
use crate::protocol::{parse_data_items, Body, Response, Tag};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};
use truepos_device::{DeviceError, DeviceInfo, ProbeHit, ProbeRequest, ProbingMachine, RotaryAxes, ToolInfo};
use truepos_math::{Point3, Vector3};

/// Default I++ DME port.
pub const DEFAULT_PORT: u16 = 1294;

/// Timeouts of the client.
#[derive(Debug, Clone, Copy)]
pub struct Timeouts {
    /// How long to wait for the TCP connection and the server's greeting.
    pub connect: Duration,
    /// For commands that do not move.
    pub command: Duration,
    /// For moves and probing (a real CMM moves slowly).
    pub motion: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Timeouts {
            connect: Duration::from_secs(5),
            command: Duration::from_secs(10),
            motion: Duration::from_secs(120),
        }
    }
}

/// The host and port of an `ippdme://HOST[:PORT]` address.
pub fn parse_url(url: &str) -> Result<(String, u16), DeviceError> {
    let bad = |m: &str| DeviceError::Connect { address: url.to_string(), message: m.to_string() };
    let rest = url.strip_prefix("ippdme://").ok_or_else(|| bad("the address must start with ippdme://"))?;
    let rest = rest.trim_end_matches('/');
    if rest.is_empty() {
        return Err(bad("no host"));
    }
    let (host, port) = match rest.rsplit_once(':') {
        Some((h, p)) if !h.is_empty() && !h.ends_with(':') => {
            (h.to_string(), p.parse::<u16>().map_err(|_| bad(&format!("bad port {p:?}")))?)
        }
        _ => (rest.to_string(), DEFAULT_PORT),
    };
    let host = host.trim_start_matches('[').trim_end_matches(']').to_string();
    Ok((host, port))
}

/// A connected I++ DME session.
pub struct IppClient {
    address: String,
    reader: BufReader<TcpStream>,
    writer: TcpStream,
    next_tag: u32,
    next_event: u32,
    timeouts: Timeouts,
    version: String,
    tool_name: String,
    tip_radius_mm: f64,
    /// PtMeasPar values last set: approach, search, retract, speed.
    ptmeas_set: Option<[f64; 4]>,
    in_session: bool,
    /// The CMM reported a rotary table (`GetMachineClass`).
    rotary_table: bool,
}

/// Connect to `ippdme://HOST:PORT` with the default timeouts.
pub fn connect(url: &str) -> Result<IppClient, DeviceError> {
    IppClient::connect(url, Timeouts::default())
}

fn contains_error(lines: &[Response]) -> Option<(u8, u16, String)> {
    lines.iter().find_map(|r| match &r.body {
        Body::Error { severity, number, method, text } => {
            Some((*severity, *number, format!("Error({severity}, {number:04}, \"{method}\", \"{text}\")")))
        }
        _ => None,
    })
}

impl IppClient {
    /// Connect to `tcp://HOST:PORT` and start a session, with `timeouts`.
    pub fn connect(url: &str, timeouts: Timeouts) -> Result<IppClient, DeviceError> {
        let (host, port) = parse_url(url)?;
        let address = format!("ippdme://{host}:{port}");
        let conn = |m: String| DeviceError::Connect { address: address.clone(), message: m };
        let addrs: Vec<_> = (host.as_str(), port)
            .to_socket_addrs()
            .map_err(|e| conn(format!("cannot resolve {host}: {e}")))?
            .collect();
        let mut last = None;
        let mut stream = None;
        for a in addrs {
            match TcpStream::connect_timeout(&a, timeouts.connect) {
                Ok(s) => {
                    stream = Some(s);
                    break;
                }
                Err(e) => last = Some(e),
            }
        }
        let stream =
            stream.ok_or_else(|| conn(last.map(|e| e.to_string()).unwrap_or_else(|| "no address".into())))?;
        let _ = stream.set_nodelay(true);
        stream.set_write_timeout(Some(timeouts.command)).map_err(|e| conn(e.to_string()))?;
        let writer = stream.try_clone().map_err(|e| conn(e.to_string()))?;
        let mut c = IppClient {
            address,
            reader: BufReader::new(stream),
            writer,
            next_tag: 1,
            next_event: 1,
            timeouts,
            version: String::new(),
            tool_name: String::new(),
            tip_radius_mm: 0.0,
            ptmeas_set: None,
            in_session: false,
            rotary_table: false,
        };
        c.transact_raw(&Command::StartSession.to_call_string(), "starting the session", false).map_err(
            |e| match e {
                DeviceError::Controller { address, message, .. }
                | DeviceError::Protocol { address, message, .. } => DeviceError::NotReady {
                    address,
                    reason: format!("the server refused the session: {message}"),
                },
                other => other,
            },
        )?;
        c.in_session = true;
        let v = c.transact_raw("GetDMEVersion()", "reading the DME version", false)?;
        c.version = v
            .first()
            .and_then(|d| d.split('"').nth(1))
            .map(|s| format!("I++ DME {s}"))
            .unwrap_or_else(|| "I++ DME (version not reported)".into());
        let class = c.transact("GetMachineClass()", "reading the machine class")?;
        c.rotary_table = class.first().is_some_and(|d| d.contains("CartCMMWithRotaryTable"));
        let homed = c.transact("IsHomed()", "asking whether the machine is homed")?;
        if !homed.first().is_some_and(|d| d.replace(' ', "").contains("IsHomed(1)")) {
            return Err(DeviceError::NotReady {
                address: c.address.clone(),
                reason: "the machine is not homed (truepos never homes a machine itself)".into(),
            });
        }
        c.transact(
            &Command::SetCoordSystem(crate::command::Csy::MachineCsy).to_call_string(),
            "selecting MachineCsy",
        )?;
        c.transact(
            &Command::OnPtMeasReport(vec![Key::X, Key::Y, Key::Z, Key::Ijk, Key::Er]).to_call_string(),
            "setting the PtMeas report format",
        )?;
        let name = c.transact("GetProp(Tool.Name())", "reading the active tool")?;
        c.tool_name = name.first().and_then(|d| d.split('"').nth(1)).unwrap_or("?").to_string();
        let r = c.transact("GetProp(Tool.AvrRadius())", "reading the tool radius").ok();
        c.tip_radius_mm = r
            .and_then(|d| d.first().and_then(|s| parse_data_items(s).ok()))
            .and_then(|items| items.first().and_then(|(_, v)| v.first().copied()))
            .unwrap_or(0.0);
        Ok(c)
    }

    /// The address (`ippdme://HOST:PORT`).
    pub fn address(&self) -> &str {
        &self.address
    }

    /// The active tool's name and tip radius (mm) as the server reported them.
    pub fn tool(&self) -> (&str, f64) {
        (&self.tool_name, self.tip_radius_mm)
    }

    fn lost(&self, what: &str, e: impl ToString) -> DeviceError {
        DeviceError::ConnectionLost {
            address: self.address.clone(),
            what: what.to_string(),
            message: e.to_string(),
        }
    }

    fn send(&mut self, tag: Tag, text: &str, what: &str) -> Result<(), DeviceError> {
        let line = format!("{tag} {text}\r\n");
        self.writer.write_all(line.as_bytes()).map_err(|e| self.lost(what, e))
    }

    /// Read answers for `tag` until its `%` (other tags' lines, e.g. events, are skipped).
    fn collect(&mut self, tag: Tag, what: &str, timeout: Duration) -> Result<Vec<Response>, DeviceError> {
        let deadline = Instant::now() + timeout;
        let mut got = Vec::new();
        let mut line = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(DeviceError::Timeout {
                    address: self.address.clone(),
                    what: what.to_string(),
                    seconds: timeout.as_secs_f64(),
                });
            }
            self.reader.get_ref().set_read_timeout(Some(left)).map_err(|e| self.lost(what, e))?;
            line.clear();
            // Bounded: a line longer than 1 MiB from the server is a protocol error.
            let n = match (&mut self.reader).take(1 << 20).read_until(b'\n', &mut line) {
                Ok(n) => n,
                Err(e)
                    if e.kind() == std::io::ErrorKind::WouldBlock
                        || e.kind() == std::io::ErrorKind::TimedOut =>
                {
                    return Err(DeviceError::Timeout {
                        address: self.address.clone(),
                        what: what.to_string(),
                        seconds: timeout.as_secs_f64(),
                    })
                }
                Err(e) => return Err(self.lost(what, e)),
            };
            if n == 0 {
                return Err(self.lost(what, "the server closed the connection"));
            }
            if line.last() != Some(&b'\n') {
                return Err(DeviceError::Protocol {
                    address: self.address.clone(),
                    what: what.into(),
                    message: "answer line too long".into(),
                });
            }
            let text = String::from_utf8_lossy(&line);
            let r = Response::parse(&text).map_err(|m| DeviceError::Protocol {
                address: self.address.clone(),
                what: what.to_string(),
                message: m,
            })?;
            if r.tag == Tag::SERVER_EVENT {
                if let Body::Error { number, .. } = &r.body {
                    // The server speaks for the connection (refusal, buffer full): fatal.
                    let msg = text.trim().to_string();
                    if *number == 8 || *number == 0 {
                        return Err(DeviceError::Controller {
                            address: self.address.clone(),
                            what: what.into(),
                            message: msg,
                        });
                    }
                }
                continue;
            }
            if r.tag != tag {
                continue;
            }
            let done = matches!(r.body, Body::Complete);
            got.push(r);
            if done {
                return Ok(got);
            }
        }
    }

    fn transact_raw(&mut self, text: &str, what: &str, motion: bool) -> Result<Vec<String>, DeviceError> {
        let tag = if text.starts_with("AbortE")
            || text.starts_with("GetErrStatusE")
            || text.starts_with("GetPropE")
        {
            let t = Tag::Event(self.next_event);
            self.next_event = self.next_event % 9999 + 1;
            t
        } else {
            let t = Tag::Command(self.next_tag);
            self.next_tag = self.next_tag % 99999 + 1;
            t
        };
        self.send(tag, text, what)?;
        let timeout = if motion { self.timeouts.motion } else { self.timeouts.command };
        let answers = self.collect(tag, what, timeout)?;
        if !matches!(answers.first().map(|r| &r.body), Some(Body::Ack)) {
            return Err(DeviceError::Protocol {
                address: self.address.clone(),
                what: what.into(),
                message: "the first answer was not the acknowledge '&'".into(),
            });
        }
        if let Some((severity, number, msg)) = contains_error(&answers) {
            if severity >= 2 && number != 514 {
                // Leave the server usable for the next command.
                let _ = self.clear_errors();
            }
            if number == 1006 {
                return Err(DeviceError::NoContact { address: self.address.clone(), what: what.into() });
            }
            return Err(DeviceError::Controller {
                address: self.address.clone(),
                what: what.into(),
                message: msg,
            });
        }
        Ok(answers
            .into_iter()
            .filter_map(|r| if let Body::Data(d) = r.body { Some(d) } else { None })
            .collect())
    }

    fn transact(&mut self, text: &str, what: &str) -> Result<Vec<String>, DeviceError> {
        self.transact_raw(text, what, false)
    }

    fn clear_errors(&mut self) -> Result<(), DeviceError> {
        let tag = Tag::Command(self.next_tag);
        self.next_tag = self.next_tag % 99999 + 1;
        self.send(tag, "ClearAllErrors()", "clearing errors")?;
        let t = self.timeouts.command;
        self.collect(tag, "clearing errors", t).map(|_| ())
    }

    fn xyz(&self, data: &[String], what: &str) -> Result<(Point3, Option<Vector3>), DeviceError> {
        let bad = |m: String| DeviceError::Protocol {
            address: self.address.clone(),
            what: what.into(),
            message: m,
        };
        let d = data.first().ok_or_else(|| bad("no data in the answer".into()))?;
        let items = parse_data_items(d).map_err(bad)?;
        let get = |k: &str| items.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
        let one = |k: &str| -> Result<f64, DeviceError> {
            get(k).and_then(|v| v.first().copied()).ok_or_else(|| bad(format!("{k}() missing in {d:?}")))
        };
        let p = Point3::new(one("X")?, one("Y")?, one("Z")?);
        let n = get("IJK").filter(|v| v.len() == 3).map(|v| Vector3::new(v[0], v[1], v[2]));
        Ok((p, n))
    }

    /// Run a scan command (`ScanOnCircle(..)`, `ScanOnLine(..)`) with the report format
    /// `X(), Y(), Z(), IJK()`; returns tip centres and normals (machine frame).
    pub fn scan(&mut self, cmd: &Command) -> Result<Vec<(Point3, Vector3)>, DeviceError> {
        self.transact(
            &Command::OnScanReport(vec![Key::X, Key::Y, Key::Z, Key::Ijk]).to_call_string(),
            "setting the scan report format",
        )?;
        let data = self.transact_raw(&cmd.to_call_string(), "scanning", true)?;
        let mut out = Vec::new();
        for d in data {
            let v: Result<Vec<f64>, _> = d.split(',').map(|s| s.trim().parse::<f64>()).collect();
            let v = v.map_err(|e| DeviceError::Protocol {
                address: self.address.clone(),
                what: "scanning".into(),
                message: e.to_string(),
            })?;
            if v.len() % 6 != 0 {
                return Err(DeviceError::Protocol {
                    address: self.address.clone(),
                    what: "scanning".into(),
                    message: format!("{} values is not a whole number of points", v.len()),
                });
            }
            for c in v.chunks(6) {
                out.push((Point3::new(c[0], c[1], c[2]), Vector3::new(c[3], c[4], c[5])));
            }
        }
        Ok(out)
    }

    fn set_ptmeas(&mut self, req: &ProbeRequest) -> Result<(), DeviceError> {
        let want = [req.approach_mm, req.search_mm, req.retract_mm, req.feed_mm_s];
        if self.ptmeas_set == Some(want) {
            return Ok(());
        }
        let p = |param| PropPath {
            tool: ToolRef::Tool,
            item: PropItem::Value(ParBlock::PtMeasPar, param, Some(Field::Act)),
        };
        let cmd = Command::SetProp(vec![
            (p(Param::Approach), req.approach_mm),
            (p(Param::Search), req.search_mm),
            (p(Param::Retract), req.retract_mm),
            (p(Param::Speed), req.feed_mm_s),
        ]);
        self.transact(&cmd.to_call_string(), "setting the PtMeas parameters")?;
        self.ptmeas_set = Some(want);
        Ok(())
    }
}

impl ProbingMachine for IppClient {
    fn info(&self) -> DeviceInfo {
        DeviceInfo { address: self.address.clone(), version: self.version.clone() }
    }

    fn position(&mut self) -> Result<Point3, DeviceError> {
        let d = self.transact("Get(X(), Y(), Z())", "reading the position")?;
        Ok(self.xyz(&d, "reading the position")?.0)
    }

    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        if !(target_mm.x.is_finite() && target_mm.y.is_finite() && target_mm.z.is_finite()) {
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what: "GoTo".into(),
                message: "target not finite".into(),
            });
        }
        let cmd = Command::GoTo { x: Some(target_mm.x), y: Some(target_mm.y), z: Some(target_mm.z) };
        let what = format!("GoTo({:.4}, {:.4}, {:.4})", target_mm.x, target_mm.y, target_mm.z);
        self.transact_raw(&cmd.to_call_string(), &what, true).map(|_| ())
    }

    /// `SetProp(Tool.GoToPar.Speed.Act(v))`: the speed of the following GoTo moves.
    fn set_move_speed(&mut self, mm_s: f64) -> Result<(), DeviceError> {
        if !(mm_s.is_finite() && mm_s > 0.0) {
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what: "setting the positioning speed".into(),
                message: format!("{mm_s} mm/s is not a positive speed"),
            });
        }
        let path = PropPath {
            tool: ToolRef::Tool,
            item: PropItem::Value(ParBlock::GoToPar, Param::Speed, Some(Field::Act)),
        };
        let cmd = Command::SetProp(vec![(path, mm_s)]);
        self.transact(&cmd.to_call_string(), "setting the positioning speed").map(|_| ())
    }

    fn probe(&mut self, req: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        let n = req.approach;
        let what = format!(
            "PtMeas at ({:.4}, {:.4}, {:.4}) along ({:.3}, {:.3}, {:.3})",
            req.nominal_mm.x, req.nominal_mm.y, req.nominal_mm.z, n.x, n.y, n.z
        );
        if n.norm().is_nan()
            || n.norm() <= 1e-9
            || ![req.approach_mm, req.search_mm, req.retract_mm, req.feed_mm_s].iter().all(|v| v.is_finite())
        {
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what,
                message: "bad probe request".into(),
            });
        }
        if (req.tip_radius_mm - self.tip_radius_mm).abs() > 1e-6 {
            // The server probes with its own tool; the geometry then differs by the radius difference.
            return Err(DeviceError::Rejected {
                address: self.address.clone(),
                what,
                message: format!(
                    "the request's tip radius {} mm differs from the active tool {} ({} mm)",
                    req.tip_radius_mm, self.tool_name, self.tip_radius_mm
                ),
            });
        }
        self.set_ptmeas(req)?;
        let cmd = Command::PtMeas {
            x: Some(req.nominal_mm.x),
            y: Some(req.nominal_mm.y),
            z: Some(req.nominal_mm.z),
            ijk: Some([n.x, n.y, n.z]),
        };
        let d = self.transact_raw(&cmd.to_call_string(), &what, true)?;
        let (p, normal) = self.xyz(&d, &what)?;
        Ok(ProbeHit { tip_center_mm: p, normal })
    }

    /// A CMM with a rotary table (`GetMachineClass` answers `CartCMMWithRotaryTable`) turns its
    /// table (C); no CMM of this client swivels its stylus (B).
    fn rotary_axes(&self) -> RotaryAxes {
        RotaryAxes { head_b: false, table_c: self.rotary_table }
    }

    /// Turn the table to `c_deg` (B must be 0): the table's angle is read with `Get(R())` and the
    /// table turned by the difference with `AlignPart` (the machine X axis as the part vector,
    /// turned by the difference about Z as the machine vector) — the specification's only command
    /// that turns a rotary table.
    fn orient(&mut self, b_deg: f64, c_deg: f64) -> Result<(), DeviceError> {
        let refuse = |m: &str| DeviceError::Rejected {
            address: self.address.clone(),
            what: format!("orienting to B = {b_deg}°, C = {c_deg}°"),
            message: m.into(),
        };
        if !(b_deg.is_finite() && c_deg.is_finite()) {
            return Err(refuse("angles not finite"));
        }
        if b_deg != 0.0 {
            return Err(refuse("this CMM has no swivelling head (B)"));
        }
        if !self.rotary_table {
            return if c_deg == 0.0 { Ok(()) } else { Err(refuse("this CMM has no rotary table (C)")) };
        }
        let what = "reading the table angle";
        let d = self.transact("Get(R())", what)?;
        let bad = |m: String| DeviceError::Protocol {
            address: self.address.clone(),
            what: what.into(),
            message: m,
        };
        let items = parse_data_items(d.first().ok_or_else(|| bad("no data".into()))?).map_err(bad)?;
        let now =
            items.iter().find(|(k, _)| k == "R").and_then(|(_, v)| v.first().copied()).ok_or_else(|| {
                DeviceError::Protocol {
                    address: self.address.clone(),
                    what: what.into(),
                    message: format!("no R() in {d:?}"),
                }
            })?;
        let turn = (c_deg - now).to_radians();
        if turn.abs() < 1e-12 {
            return Ok(());
        }
        let (s, c) = turn.sin_cos();
        let cmd = format!(
            "AlignPart(1, 0, 0, {}, {}, 0, 0)",
            crate::protocol::fmt_num(c),
            crate::protocol::fmt_num(s)
        );
        self.transact_raw(&cmd, &format!("turning the table to C = {c_deg}°"), true).map(|_| ())
    }

    fn abort(&mut self) -> Result<(), DeviceError> {
        self.transact_raw("AbortE()", "aborting", false)?;
        self.clear_errors()
    }

    /// The server's tool table (`EnumTools`).
    fn tool_names(&mut self) -> Result<Vec<String>, DeviceError> {
        let d = self.transact("EnumTools()", "listing the tools")?;
        Ok(d.iter().map(|l| l.trim().trim_matches('"').to_string()).collect())
    }

    /// `ChangeTool(name)`, then the tool's name and radius as the server reports them. The
    /// PtMeas parameters belong to the tool: they are set again before the next probing.
    fn select_tool(&mut self, name: &str) -> Result<ToolInfo, DeviceError> {
        let what = format!("changing the tool to {name}");
        self.transact_raw(&Command::ChangeTool(name.to_string()).to_call_string(), &what, true)?;
        self.ptmeas_set = None;
        let d = self.transact("GetProp(Tool.Name())", "reading the active tool")?;
        self.tool_name = d.first().and_then(|d| d.split('"').nth(1)).unwrap_or(name).to_string();
        let r = self.transact("GetProp(Tool.AvrRadius())", "reading the tool radius")?;
        self.tip_radius_mm = r
            .first()
            .and_then(|s| parse_data_items(s).ok())
            .and_then(|items| items.first().and_then(|(_, v)| v.first().copied()))
            .ok_or_else(|| DeviceError::Protocol {
                address: self.address.clone(),
                what: "reading the tool radius".into(),
                message: format!("no radius in {r:?}"),
            })?;
        Ok(ToolInfo { name: self.tool_name.clone(), tip_radius_mm: self.tip_radius_mm })
    }
}

impl Drop for IppClient {
    fn drop(&mut self) {
        if self.in_session {
            let tag = Tag::Command(self.next_tag);
            if self.send(tag, "EndSession()", "ending the session").is_ok() {
                let _ = self.collect(tag, "ending the session", Duration::from_secs(2));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        assert_eq!(parse_url("ippdme://127.0.0.1:5000").unwrap(), ("127.0.0.1".into(), 5000));
        assert_eq!(parse_url("ippdme://cmm.local").unwrap(), ("cmm.local".into(), 1294));
        assert!(parse_url("http://x").is_err());
        assert!(parse_url("ippdme://h:notaport").is_err());
        assert!(parse_url("ippdme://").is_err());
    }

    #[test]
    fn unreachable_server_names_the_address_within_seconds() {
        // A port nobody listens on (bound then dropped).
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = l.local_addr().unwrap().port();
        drop(l);
        let t0 = Instant::now();
        let e = connect(&format!("ippdme://127.0.0.1:{port}")).err().unwrap();
        assert!(t0.elapsed() < Duration::from_secs(6));
        assert!(e.to_string().contains(&format!("ippdme://127.0.0.1:{port}")), "{e}");
    }
}
