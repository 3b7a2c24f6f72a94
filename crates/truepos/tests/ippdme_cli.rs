//! `truepos ippdme serve` as a process: listening line, a full session with the log, SIGTERM →
//! exit 0, bad part file → exit 2 naming file and line, port in use → exit 3.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn truepos() -> Command {
    Command::new(env!("CARGO_BIN_EXE_truepos"))
}

#[test]
fn serve_runs_a_session_logs_it_and_ends_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [0, 0, 0]\ndiameter_mm = 20\n").unwrap();
    let log = dir.path().join("ippdme.log");
    let mut child = truepos()
        .args(["ippdme", "serve", "--port", "0", "--part"])
        .arg(&part)
        .arg("--log")
        .arg(&log)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut first = String::new();
    err.read_line(&mut first).unwrap();
    let addr =
        first.trim().strip_prefix("ippdme: listening on ").unwrap_or_else(|| panic!("{first}")).to_string();
    let s = TcpStream::connect(&addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    w.write_all(b"00001 StartSession()\r\n00002 Home()\r\n00003 ChangeTool(\"Probe1\")\r\n00004 PtMeas(X(0), Y(0), Z(10), IJK(0,0,1))\r\n00005 EndSession()\r\n").unwrap();
    let mut lines = Vec::new();
    while lines.last().is_none_or(|l: &String| l != "00005 %") {
        let mut l = String::new();
        assert!(r.read_line(&mut l).unwrap() > 0, "{lines:?}");
        lines.push(l.trim_end().to_string());
    }
    assert!(lines.contains(&"00004 # X(0.000000), Y(0.000000), Z(11.500000)".to_string()), "{lines:?}");
    drop((w, r));
    // SIGTERM: exit 0.
    unsafe_kill(child.id());
    let t0 = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "no exit after SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(status.code(), Some(0));
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.contains(" < 00004 PtMeas(X(0), Y(0), Z(10), IJK(0,0,1))"), "{text}");
    assert!(text.contains(" > 00004 # X(0.000000), Y(0.000000), Z(11.500000)"), "{text}");
}

fn unsafe_kill(pid: u32) {
    let st = Command::new("kill").args(["-TERM", &pid.to_string()]).status().unwrap();
    assert!(st.success());
}

#[test]
fn bad_part_file_is_exit_2_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.toml");
    std::fs::write(&part, "[[sphere]]\ncenter_mm = [0, 0, 0]\ndiameter_mm = 20\nradius = 3\n").unwrap();
    let out = truepos().args(["ippdme", "serve", "--port", "0", "--part"]).arg(&part).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("part.toml:4:"), "{err}");
}

#[test]
fn port_in_use_is_exit_3() {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = l.local_addr().unwrap().port().to_string();
    let out = truepos().args(["ippdme", "serve", "--port", &port]).output().unwrap();
    assert_eq!(out.status.code(), Some(3), "{}", String::from_utf8_lossy(&out.stderr));
}
