//! One linuxcncrsh TCP session: send a line, read answer lines, every read with a deadline.
//!
//! linuxcncrsh answers `set` commands (with verbose on) with one line `SET <CMD> ACK|NAK` and
//! `get` commands with one line `<NAME> values…`; lines end in `\n\r`, so leading/trailing
//! whitespace is stripped and empty lines are skipped. After a timeout the late answer may still
//! arrive: the session is then out of step and refuses further commands until
//! [`Session::resync_with_abort`] has re-synchronised it.
//!
//! Entry points: [`Session::connect`], [`Session::command`], [`Session::read_line`].

use std::io::{BufRead, BufReader, ErrorKind, Write};
use std::net::{Shutdown, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};
use truepos_device::DeviceError;

pub(crate) struct Session {
    address: String,
    writer: TcpStream,
    reader: BufReader<TcpStream>,
    /// A command timed out: answers may be out of step.
    out_of_step: bool,
}

impl Session {
    /// Open the TCP connection within `timeout`.
    pub fn connect(address: &str, socket_address: &str, timeout: Duration) -> Result<Session, DeviceError> {
        let connect_err = |message: String| DeviceError::Connect { address: address.to_string(), message };
        let addrs: Vec<_> = socket_address
            .to_socket_addrs()
            .map_err(|e| connect_err(format!("cannot resolve {socket_address}: {e}")))?
            .collect();
        let mut last = None;
        for a in &addrs {
            match TcpStream::connect_timeout(a, timeout) {
                Ok(s) => {
                    let _ = s.set_nodelay(true);
                    let writer = s.try_clone().map_err(|e| connect_err(e.to_string()))?;
                    s.set_write_timeout(Some(timeout)).map_err(|e| connect_err(e.to_string()))?;
                    return Ok(Session {
                        address: address.to_string(),
                        writer,
                        reader: BufReader::new(s),
                        out_of_step: false,
                    });
                }
                Err(e) => last = Some(e),
            }
        }
        Err(connect_err(match last {
            Some(e) if e.kind() == ErrorKind::ConnectionRefused => {
                "connection refused (is LinuxCNC running with linuxcncrsh on this port?)".into()
            }
            Some(e) if e.kind() == ErrorKind::TimedOut || e.kind() == ErrorKind::WouldBlock => {
                format!("no connection within {:.0} s", timeout.as_secs_f64())
            }
            Some(e) => e.to_string(),
            None => format!("{socket_address} resolves to no address"),
        }))
    }

    fn lost(&self, what: &str, message: String) -> DeviceError {
        DeviceError::ConnectionLost { address: self.address.clone(), what: what.to_string(), message }
    }

    /// Send one command line.
    pub fn send(&mut self, line: &str, what: &str) -> Result<(), DeviceError> {
        if self.out_of_step {
            return Err(DeviceError::Protocol {
                address: self.address.clone(),
                what: what.to_string(),
                message: "the session is out of step after an earlier timeout; reconnect".into(),
            });
        }
        let mut buf = Vec::with_capacity(line.len() + 2);
        buf.extend_from_slice(line.as_bytes());
        buf.extend_from_slice(b"\r\n");
        self.writer.write_all(&buf).map_err(|e| self.lost(what, e.to_string()))
    }

    /// The next non-empty line, trimmed, within `timeout`.
    pub fn read_line(&mut self, what: &str, timeout: Duration) -> Result<String, DeviceError> {
        let deadline = Instant::now() + timeout;
        // Bytes of a line read before a read timeout stay here for the next attempt.
        let mut raw = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                self.out_of_step = true;
                return Err(DeviceError::Timeout {
                    address: self.address.clone(),
                    what: what.to_string(),
                    seconds: timeout.as_secs_f64(),
                });
            }
            self.reader
                .get_ref()
                .set_read_timeout(Some(left.max(Duration::from_millis(1))))
                .map_err(|e| self.lost(what, e.to_string()))?;
            match self.reader.read_until(b'\n', &mut raw) {
                Ok(0) => return Err(self.lost(what, "the controller closed the connection".into())),
                Ok(_) => {
                    if raw.last() != Some(&b'\n') {
                        // A partial line followed by EOF.
                        return Err(self.lost(what, "the controller closed the connection".into()));
                    }
                    let t = String::from_utf8_lossy(&raw).trim().to_string();
                    raw.clear();
                    if !t.is_empty() {
                        return Ok(t);
                    }
                }
                // The deadline check at the top of the loop reports the timeout.
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(self.lost(what, e.to_string())),
            }
        }
    }

    /// Send `line` and read its one-line answer.
    pub fn command(&mut self, line: &str, what: &str, timeout: Duration) -> Result<String, DeviceError> {
        self.send(line, what)?;
        self.read_line(what, timeout)
    }

    /// After a timeout: send `set abort` and skip every line until its `SET ABORT ACK|NAK`.
    pub fn resync_with_abort(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.out_of_step = false;
        self.send("set abort", "aborting")?;
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let l = self.read_line("aborting", left)?;
            if l.starts_with("SET ABORT ") {
                return Ok(());
            }
        }
    }

    /// Whether a command timed out and the answers may belong to earlier commands (until [`Self::resync_with_abort`]).
    pub fn is_out_of_step(&self) -> bool {
        self.out_of_step
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.writer.write_all(b"quit\r\n");
        let _ = self.writer.shutdown(Shutdown::Both);
    }
}
