//! Helpers shared by the CLI tests: run the built binary, write input files, check that bad
//! input is refused the contract's way.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `truepos` binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_truepos"))
}

/// Write `contents` to `dir/name` and return the path.
pub fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, contents).unwrap();
    p
}

/// Bad input: exit code 2, nothing on stdout, no panic, and stderr names every needle.
pub fn expect_input_error(out: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {err}");
    assert!(
        out.stdout.is_empty(),
        "stdout must stay empty on error: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    for n in needles {
        assert!(err.contains(n), "expected '{n}' in: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
}

/// `truepos ippdme serve` on a free loopback port with `part` and the `extra` options, run in
/// `dir`; returns the child and the address it printed.
pub fn ippdme_server(dir: &Path, part: &Path, extra: &[&std::ffi::OsStr]) -> (std::process::Child, String) {
    use std::io::BufRead;
    let mut child = bin()
        .current_dir(dir)
        .args(["ippdme", "serve", "--port", "0", "--part"])
        .arg(part)
        .args(extra)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut first = String::new();
    err.read_line(&mut first).unwrap();
    let addr =
        first.trim().strip_prefix("ippdme: listening on ").unwrap_or_else(|| panic!("{first}")).to_string();
    (child, addr)
}

/// What the operator does before truepos may use the CMM at `addr` (truepos never homes a
/// machine itself): one session that homes it and, with `tool`, selects that tool.
pub fn home_cmm(addr: &str, tool: Option<&str>) {
    use std::io::{BufRead, Write};
    let s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = std::io::BufReader::new(s);
    let change = tool.map(|t| format!("00003 ChangeTool(\"{t}\")\r\n")).unwrap_or_default();
    w.write_all(format!("00001 StartSession()\r\n00002 Home()\r\n{change}00004 EndSession()\r\n").as_bytes())
        .unwrap();
    let mut last = String::new();
    while last.trim_end() != "00004 %" {
        last.clear();
        assert!(r.read_line(&mut last).unwrap() > 0, "the server closed the session");
    }
}
