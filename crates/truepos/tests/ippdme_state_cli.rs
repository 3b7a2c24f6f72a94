//! `truepos ippdme serve` as a process under hostile clients (issue 31, round 3), on 127.0.0.1:
//! `--write-timeout-s` drops a client that stops reading and serves the next; an idle client
//! keeps its session; a bad timeout is exit 2; a log that cannot be written any more (a regular
//! file at the process's file-size limit) is reported once on stderr and the server keeps serving.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const PART: &str = "[[plane]]\nid = \"table\"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n";

/// A running server: the child, its address and the rest of its stderr, line by line.
struct Serve {
    child: Child,
    addr: String,
    stderr: mpsc::Receiver<String>,
}

impl Serve {
    /// Start `cmd` (a `truepos ippdme serve --port 0 …` command line) and wait for its
    /// listening line.
    fn start(mut cmd: Command) -> Serve {
        let mut child = cmd.stderr(Stdio::piped()).spawn().unwrap();
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut first = String::new();
        err.read_line(&mut first).unwrap();
        let addr = first
            .trim()
            .strip_prefix("ippdme: listening on ")
            .unwrap_or_else(|| panic!("no listening line: {first}"))
            .to_string();
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for l in err.lines() {
                let Ok(l) = l else { break };
                if tx.send(l).is_err() {
                    break;
                }
            }
        });
        Serve { child, addr, stderr: rx }
    }
    /// SIGTERM; the exit code and the stderr lines after the listening line.
    fn stop(mut self) -> (Option<i32>, Vec<String>) {
        let st = Command::new("kill").args(["-TERM", &self.child.id().to_string()]).status().unwrap();
        assert!(st.success());
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            assert!(t0.elapsed() < Duration::from_secs(20), "no exit after SIGTERM");
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut lines = Vec::new();
        while let Ok(l) = self.stderr.recv_timeout(Duration::from_secs(2)) {
            lines.push(l);
        }
        (status.code(), lines)
    }
}

fn serve_cmd(dir: &std::path::Path, extra: &[&str]) -> Command {
    let part = common::write(dir, "part.toml", PART);
    let mut cmd = common::bin();
    cmd.current_dir(dir).args(["ippdme", "serve", "--port", "0", "--part"]).arg(part).args(extra);
    cmd
}

/// Connect; `Err(line)` if the server refuses at once (another client holds it), otherwise the
/// connection (nothing is sent before the refusal could arrive).
fn try_connect(addr: &str) -> Result<(BufReader<TcpStream>, TcpStream), String> {
    let s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(300))).unwrap();
    let w = s.try_clone().unwrap();
    let mut r = BufReader::new(s);
    let mut first = String::new();
    match r.read_line(&mut first) {
        Ok(_) => Err(first.trim_end().to_string()),
        Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
            w.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
            Ok((r, w))
        }
        Err(e) => Err(e.to_string()),
    }
}

/// Send `lines` and read the answers up to the last line's `%`.
fn transact(r: &mut BufReader<TcpStream>, w: &mut TcpStream, lines: &[&str]) -> Vec<String> {
    let mut text = String::new();
    for l in lines {
        text.push_str(l);
        text.push_str("\r\n");
    }
    w.write_all(text.as_bytes()).unwrap();
    let end = format!("{} %", &lines[lines.len() - 1][..5]);
    let mut out = Vec::new();
    loop {
        let mut s = String::new();
        assert!(r.read_line(&mut s).unwrap() > 0, "closed after {out:?}");
        let l = s.trim_end().to_string();
        let done = l == end;
        out.push(l);
        if done {
            return out;
        }
    }
}

/// A client pipelines 20 000 `EnumAllProp(Tool())` (about 1.5 KB of answers each, 30 MB in all)
/// and never reads: with `--write-timeout-s 0.5` the server drops it and serves the next client,
/// and its log says why.
#[test]
fn serve_drops_a_client_that_stops_reading_and_serves_the_next() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("session.log");
    let srv =
        Serve::start(serve_cmd(dir.path(), &["--write-timeout-s", "0.5", "--log", log.to_str().unwrap()]));
    let a = TcpStream::connect(&srv.addr).unwrap();
    let mut aw = a.try_clone().unwrap();
    let writer = std::thread::spawn(move || {
        let mut text = String::from("00001 StartSession()\r\n");
        for k in 2..20_002 {
            text.push_str(&format!("{:05} EnumAllProp(Tool())\r\n", k % 100_000));
        }
        // The server stops reading once it is blocked on its answers, then drops A: this write
        // may fail part-way, which is the point.
        let _ = aw.write_all(text.as_bytes());
    });
    let t0 = Instant::now();
    let mut refusals = 0;
    let (served_at, mut r, mut w) = loop {
        assert!(t0.elapsed() < Duration::from_secs(60), "the non-reading client was never dropped");
        match try_connect(&srv.addr) {
            Ok((r, w)) => break (t0.elapsed(), r, w),
            Err(line) => {
                assert_eq!(line, "E0000 ! Error(2, 0008, \"Connect\", \"Protocol error\")");
                refusals += 1;
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    };
    let out =
        transact(&mut r, &mut w, &["00001 StartSession()", "00002 GetDMEVersion()", "00003 EndSession()"]);
    assert!(out.contains(&"00002 # DMEVersion(\"1.4.3\")".to_string()), "{out:?}");
    eprintln!(
        "ippdme serve --write-timeout-s 0.5: non-reading client dropped, next served after {:.0} ms ({refusals} refusals)",
        served_at.as_secs_f64() * 1e3
    );
    assert!(refusals >= 1, "the first client was never holding the connection");
    assert!(served_at >= Duration::from_millis(500), "{served_at:?}");
    assert!(served_at < Duration::from_secs(30), "{served_at:?}");
    // A got less than its 30 MB before the close.
    a.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut got = 0usize;
    let mut buf = vec![0u8; 1 << 16];
    let mut ar = &a;
    while let Ok(n) = ar.read(&mut buf) {
        if n == 0 {
            break;
        }
        got += n;
    }
    let _ = writer.join();
    assert!(got < 25_000_000, "{got} bytes");
    drop((r, w));
    let (code, _) = srv.stop();
    assert_eq!(code, Some(0));
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(
        text.contains("write error: the client took no answers for 0.500 s (write timeout)"),
        "{}",
        &text[text.len().saturating_sub(2000)..]
    );
}

/// A client that sends nothing for three times the write timeout keeps its session.
#[test]
fn serve_keeps_an_idle_client_beyond_the_write_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let srv = Serve::start(serve_cmd(dir.path(), &["--write-timeout-s", "0.5"]));
    let (mut r, mut w) = try_connect(&srv.addr).unwrap();
    transact(&mut r, &mut w, &["00001 StartSession()", "00002 Home()"]);
    std::thread::sleep(Duration::from_millis(1500));
    let out = transact(&mut r, &mut w, &["00003 IsHomed()", "00004 EndSession()"]);
    assert!(out.contains(&"00003 # IsHomed(1)".to_string()), "{out:?}");
    drop((r, w));
    assert_eq!(srv.stop().0, Some(0));
}

#[test]
fn serve_refuses_a_write_timeout_that_is_not_a_duration() {
    let dir = tempfile::tempdir().unwrap();
    for bad in ["0", "-1", "NaN", "inf", "1e9"] {
        let out = serve_cmd(dir.path(), &["--write-timeout-s", bad]).output().unwrap();
        common::expect_input_error(&out, &["--write-timeout-s", "between 0.001 and 86400"]);
    }
}

/// The log is a regular file, but the process may write at most 4 blocks (`ulimit -f`, the
/// file-size limit: writes beyond fail with EFBIG, as on a full disk). The first failure is
/// reported once on stderr naming the file; the server keeps serving every command; the log
/// holds what was written before.
#[test]
fn serve_reports_a_log_that_can_no_longer_be_written_and_keeps_serving() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("session.log");
    let inner = serve_cmd(dir.path(), &["--log", log.to_str().unwrap()]);
    // The same command line under sh with SIGXFSZ ignored (so that the write fails instead of
    // killing the process) and the file-size limit set; exec keeps the pid.
    let mut cmd = Command::new("sh");
    cmd.current_dir(dir.path())
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 4 || exit 99; exec \"$0\" \"$@\"")
        .arg(inner.get_program())
        .args(inner.get_args());
    let srv = Serve::start(cmd);
    let (mut r, mut w) = try_connect(&srv.addr).unwrap();
    let mut lines = vec!["00001 StartSession()".to_string()];
    for k in 2..300 {
        lines.push(format!("{k:05} GetDMEVersion()"));
    }
    lines.push("00300 EndSession()".to_string());
    for chunk in lines.chunks(50) {
        let refs: Vec<&str> = chunk.iter().map(String::as_str).collect();
        let out = transact(&mut r, &mut w, &refs);
        let answered = out.iter().filter(|l| l.ends_with(" %")).count();
        assert_eq!(answered, chunk.len(), "{out:?}");
    }
    drop((r, w));
    let (code, err) = srv.stop();
    assert_eq!(code, Some(0), "{err:?}");
    let reports: Vec<&String> = err.iter().filter(|l| l.contains("cannot write the session log")).collect();
    assert_eq!(reports.len(), 1, "{err:?}");
    assert!(reports[0].contains(&format!("--log {}", log.display())), "{}", reports[0]);
    assert!(reports[0].contains("File too large"), "{}", reports[0]);
    assert!(reports[0].contains("logging stopped") && reports[0].contains("keeps serving"), "{}", reports[0]);
    let size = std::fs::metadata(&log).unwrap().len();
    // At most the limit (4 blocks of 512 or 1024 bytes), and not empty: it was written until full.
    assert!(size > 0 && size <= 4096, "{size}");
    eprintln!("log stopped at {size} bytes: {}", reports[0]);
}
