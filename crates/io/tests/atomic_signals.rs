//! Temporary output files are removed when the process is interrupted (SIGINT, SIGTERM), and a
//! file over the size limit is refused from its size, before it is read.
//!
//! The child process is this test binary itself, re-run with `TRUEPOS_TEST_CHILD` set: it
//! creates an `AtomicFile`, writes to it, says "ready" and waits to be killed.

use std::io::{BufRead, Write};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn child_holding_an_output() {
    let Ok(dir) = std::env::var("TRUEPOS_TEST_CHILD") else { return };
    let mut f = truepos_io::atomic::AtomicFile::create(Path::new(&dir).join("out.csv")).unwrap();
    f.write_all(&vec![b'x'; 3 << 20]).unwrap();
    f.flush().unwrap();
    println!("ready");
    std::io::stdout().flush().unwrap();
    std::thread::sleep(Duration::from_secs(30));
    f.commit().unwrap();
}

fn interrupted_child_leaves_nothing(signal: &str) {
    if !Path::new("/bin/kill").exists() && !Path::new("/usr/bin/kill").exists() {
        eprintln!("SKIPPED: no kill command to send {signal}");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child_holding_an_output", "--nocapture", "--test-threads=1"])
        .env("TRUEPOS_TEST_CHILD", dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    while !line.contains("ready") {
        line.clear();
        assert!(out.read_line(&mut line).unwrap() > 0, "child ended before it was ready");
    }
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names.len(), 1);
    assert!(names[0].to_string_lossy().starts_with(".out.csv.tmp-"), "{names:?}");
    let status = Command::new("kill").args([signal, &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let t = Instant::now();
    let st = child.wait().unwrap();
    assert!(t.elapsed() < Duration::from_secs(10));
    assert!(!st.success());
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "left behind after {signal}: {left:?}");
}

#[test]
fn sigint_removes_temporary_files() {
    if std::env::var("TRUEPOS_TEST_CHILD").is_ok() {
        return;
    }
    interrupted_child_leaves_nothing("-INT");
}

#[test]
fn sigterm_removes_temporary_files() {
    if std::env::var("TRUEPOS_TEST_CHILD").is_ok() {
        return;
    }
    interrupted_child_leaves_nothing("-TERM");
}

#[test]
fn oversized_files_are_refused_before_reading() {
    if std::env::var("TRUEPOS_TEST_CHILD").is_ok() {
        return;
    }
    // A sparse 3 GB file: refused from its size at once (no 3 GB read). The limit is the default.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.csv");
    let f = std::fs::File::create(&p).unwrap();
    f.set_len(3_000_000_000).unwrap();
    let t = Instant::now();
    let e = truepos_io::csv::Table::read(&p).unwrap_err();
    assert!(e.to_string().contains("3.0 GB") && e.to_string().contains("at most"), "{e}");
    let e = truepos_io::stream::CsvStream::open(&p).err().unwrap();
    assert!(e.to_string().contains("3.0 GB"), "{e}");
    let e = truepos_io::limits::read_text(&p, "G-code").unwrap_err();
    assert!(e.to_string().contains("3.0 GB"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(2));
}

#[test]
fn remove_all_temporaries_clears_live_files() {
    if std::env::var("TRUEPOS_TEST_CHILD").is_ok() {
        return;
    }
    // The only test of this binary that creates files in this process.
    let dir = tempfile::tempdir().unwrap();
    let f = truepos_io::atomic::AtomicFile::create(dir.path().join("a.csv")).unwrap();
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    assert_eq!(truepos_io::atomic::remove_all_temporaries(), 1);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    drop(f);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}
