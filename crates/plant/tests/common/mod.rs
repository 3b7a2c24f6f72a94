//! The raw I++ DME line client the virtual CMM's server tests share (integration tests cannot
//! reach the server crate's own `#[cfg(test)]` helpers).

// Each test binary uses its own part of it.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::Duration;
use truepos_ippdme::ServerHandle;
use truepos_plant::cmm::IppdmeCmm;

/// A raw line client for tests.
pub struct Raw {
    pub r: BufReader<TcpStream>,
    pub w: TcpStream,
}

impl Raw {
    /// Connect to the server of `h` (reads wait at most 60 s: a hung server fails the test).
    pub fn connect(h: &ServerHandle<IppdmeCmm>) -> Raw {
        let s = TcpStream::connect(h.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        Raw { w: s.try_clone().unwrap(), r: BufReader::new(s) }
    }

    /// Send bytes as they are.
    pub fn send_raw(&mut self, bytes: &[u8]) {
        self.w.write_all(bytes).unwrap();
    }

    /// The next line without its line end; `None` when the connection closed.
    pub fn line(&mut self) -> Option<String> {
        let mut s = String::new();
        match self.r.read_line(&mut s) {
            Ok(0) | Err(_) => None,
            Ok(_) => Some(s.trim_end().to_string()),
        }
    }

    /// Send one command and return every line up to and including the tag's `%` (fewer if
    /// the connection closes).
    pub fn cmd(&mut self, line: &str) -> Vec<String> {
        self.send_raw(format!("{line}\r\n").as_bytes());
        let tag = &line[..5];
        let mut out = Vec::new();
        while let Some(l) = self.line() {
            let done = l.starts_with(tag) && l[5..].trim() == "%";
            out.push(l);
            if done {
                break;
            }
        }
        out
    }

    /// [`Raw::cmd`] that must not fail.
    pub fn ok(&mut self, line: &str) -> Vec<String> {
        let out = self.cmd(line);
        assert!(!out.iter().any(|l| l.contains(" ! ")), "{line}: {out:?}");
        out
    }

    /// The command must fail with error `number`; its text must contain every needle. The
    /// error state is cleared afterwards.
    pub fn refused(&mut self, line: &str, number: &str, needles: &[&str]) -> String {
        let out = self.cmd(line);
        let err = out
            .iter()
            .find(|l| l.contains(" ! "))
            .unwrap_or_else(|| panic!("{line} was not refused: {out:?}"))
            .clone();
        assert!(err.contains(&format!(", {number}, ")), "{line}: {err}");
        for n in needles {
            assert!(err.contains(n), "{line}: '{n}' missing in {err}");
        }
        assert!(out.iter().all(|l| !l.contains(" # ")), "{line}: data in a refusal {out:?}");
        self.ok("09999 ClearAllErrors()");
        err
    }

    /// `Get(X(), Y(), Z(), R())` as the server formats it (6 decimals: identical strings mean
    /// the machine did not move).
    pub fn where_(&mut self) -> String {
        self.ok("09998 Get(X(), Y(), Z(), R())")[1].clone()
    }
}
