//! A simulated LinuxCNC for tests: [`SimLinuxCnc::start`] copies the test configuration
//! (`tests/lcnc/`: a 3-axis machine with an ideal servo loop, a 1 ms servo period and, on the
//! probe input, a virtual reference sphere ([`SphereTruth`]) and a plate with four bores
//! ([`PlateTruth`])) into a temporary directory owned by an unprivileged user
//! (LinuxCNC refuses to run as root; `TRUEPOS_LINUXCNC_USER`, default `lcnc`), picks a free
//! loopback port for linuxcncrsh, starts `linuxcnc` headless in its own session and waits for
//! linuxcncrsh to greet. [`SimLinuxCnc::arm`] does what an operator does at the machine (release
//! the e-stop, switch on, home) — truepos itself never does.
//!
//! Only one LinuxCNC can run on a machine (a second start kills the first): every
//! [`SimLinuxCnc`] holds, for its lifetime, a process-wide mutex and a cross-process
//! [`MachineLock`] (an exclusive `flock` on `truepos-linuxcnc.lock` in the system temp
//! directory), so test binaries that cargo runs in parallel start LinuxCNC one after the other;
//! the lock is released when the holder ends, even when it is killed. Dropping a [`SimLinuxCnc`]
//! (also on a panic) stops LinuxCNC: SIGTERM to its `linuxcncrsh` (the `linuxcnc` script then runs its own
//! cleanup), then SIGTERM/SIGKILL to the process group it was started in.
//!
//! When LinuxCNC is not installed or cannot start, [`SimLinuxCnc::start`] returns
//! [`Unavailable`] with the reason: tests print `SKIPPED: …` and return.

use std::fs;
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};
use truepos_math::Point3;

const INI: &str = include_str!("../tests/lcnc/truepos_sim.ini");
const HAL: &str = include_str!("../tests/lcnc/truepos_sim.hal");
const TBL: &str = include_str!("../tests/lcnc/sim_mm.tbl");
const INI5: &str = include_str!("../tests/lcnc5/xyzbc_sphere.ini");
const HAL5: &str = include_str!("../tests/lcnc5/xyzbc_sphere.hal");

/// Where `halcompile --install` puts the five-axis truth component.
pub const SPHERE5_MODULE: &str = "/usr/lib/linuxcnc/modules/sphere5.so";

static ONE_LINUXCNC: Mutex<()> = Mutex::new(());

/// How long [`SimLinuxCnc::start`] waits for another test process's LinuxCNC to finish.
pub const LOCK_WAIT: Duration = Duration::from_secs(1200);

/// The cross-process lock file every [`SimLinuxCnc`] holds while its LinuxCNC runs.
pub fn lock_path() -> PathBuf {
    std::env::temp_dir().join("truepos-linuxcnc.lock")
}

/// An exclusive advisory lock (`flock(LOCK_EX)`) on a file, held until dropped. The kernel
/// releases it when the holder's file is closed, also when the process dies, so a killed test
/// never leaves it behind.
#[derive(Debug)]
pub struct MachineLock {
    _file: fs::File,
    path: PathBuf,
}

impl MachineLock {
    /// Take the lock on `path` (created if missing, readable and writable by everyone so that
    /// test runs as different users share it), polling every 50 ms for at most `timeout`.
    /// `on_wait` is called once if the lock is busy at the first attempt.
    pub fn acquire(path: &Path, timeout: Duration, on_wait: impl FnOnce()) -> Result<MachineLock, String> {
        use std::os::unix::fs::OpenOptionsExt;
        use std::os::unix::io::AsRawFd;
        let file = fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .mode(0o666)
            .open(path)
            .map_err(|e| format!("cannot open the lock file {}: {e}", path.display()))?;
        // The mode above is filtered by the umask: widen it (best effort; the owner may differ).
        let _ = fs::set_permissions(path, std::os::unix::fs::PermissionsExt::from_mode(0o666));
        let t = Instant::now();
        let mut on_wait = Some(on_wait);
        loop {
            // SAFETY: flock on a file descriptor this function owns (open for its lifetime).
            let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
            if r == 0 {
                return Ok(MachineLock { _file: file, path: path.to_path_buf() });
            }
            let err = std::io::Error::last_os_error();
            if err.raw_os_error() != Some(libc::EWOULDBLOCK) && err.raw_os_error() != Some(libc::EINTR) {
                return Err(format!("cannot lock {}: {err}", path.display()));
            }
            if let Some(f) = on_wait.take() {
                f();
            }
            if t.elapsed() >= timeout {
                return Err(format!(
                    "{} is still locked by another process after {:.0} s",
                    path.display(),
                    timeout.as_secs_f64()
                ));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The path of the lock file held.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Why the simulated LinuxCNC is not available (the test is skipped, loudly).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Unavailable(pub String);

impl std::fmt::Display for Unavailable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// The virtual reference sphere wired to the probe input (the HAL truth).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereTruth {
    /// Centre of the sphere in machine coordinates, mm.
    pub center_mm: Point3,
    /// Radius of the sphere, mm.
    pub radius_mm: f64,
    /// The probe trips when the tip centre is within `radius + tip_radius` of the centre.
    pub tip_radius_mm: f64,
}

impl Default for SphereTruth {
    /// A 25 mm sphere at (120, 45, 30) probed with a 3 mm ball.
    fn default() -> Self {
        SphereTruth { center_mm: Point3::new(120.0, 45.0, 30.0), radius_mm: 12.5, tip_radius_mm: 1.5 }
    }
}

/// One vertical through bore of the virtual plate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoreTruth {
    /// Axis position X, Y (mm).
    pub center_xy_mm: [f64; 2],
    /// Bore diameter, mm.
    pub diameter_mm: f64,
}

/// The virtual plate with four bores wired to the probe input (the HAL truth): the probe trips
/// while the tip centre is inside the plate's box grown by the tip radius and not within
/// `radius − tip radius` of a bore's axis. The HAL model has exactly four bores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateTruth {
    /// The plate's X extent (min, max), mm.
    pub x_mm: [f64; 2],
    /// The plate's Y extent (min, max), mm.
    pub y_mm: [f64; 2],
    /// The plate's Z extent (bottom, top), mm.
    pub z_mm: [f64; 2],
    /// The four bores through the plate.
    pub bores: [BoreTruth; 4],
}

impl Default for PlateTruth {
    /// A 30 mm plate at X 200…320, Y −150…−50, top at Z 0 (clear of the sphere, of the machine's
    /// home at the origin and of the somac test program's moves), with four nominally 10 mm
    /// bores a few µm to tens of µm off the round nominal positions (230, −120), (260, −120),
    /// (290, −80), (230, −80).
    fn default() -> Self {
        let b = |x: f64, y: f64, d: f64| BoreTruth { center_xy_mm: [x, y], diameter_mm: d };
        PlateTruth {
            x_mm: [200.0, 320.0],
            y_mm: [-150.0, -50.0],
            z_mm: [-30.0, 0.0],
            bores: [
                b(230.012, -119.991, 10.0),
                b(260.0, -120.015, 10.012),
                b(290.008, -80.0, 9.99),
                b(229.985, -80.01, 10.004),
            ],
        }
    }
}

/// The five-axis test machine (`tests/lcnc5/`, the verified recipe's configuration): LinuxCNC's
/// `xyzbc-trt-kins` (a B tilting table carrying a C rotary table) configured with one geometry,
/// while the probe input comes from the `sphere5` realtime component, which computes the tip in
/// the table frame with the *true* geometry and trips inside a sphere fixed on the table.
/// Geometry arrays are in the pin order x-rot-point, y-rot-point, z-rot-point, x-offset,
/// z-offset (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FiveAxisTruth {
    /// What the controller's kinematics pins are set to at start-up.
    pub configured: [f64; 5],
    /// The machine's true geometry (only the truth component knows it).
    pub truth: [f64; 5],
    /// The sphere's centre in the (true) table frame, mm.
    pub sphere_center_mm: Point3,
    /// Radius of the sphere, mm.
    pub radius_mm: f64,
    /// Radius of the stylus tip, mm.
    pub tip_radius_mm: f64,
}

impl Default for FiveAxisTruth {
    /// The recipe's machine: C axis off by (+30, −20) µm, B axis by x +45 µm, z −25 µm; a
    /// 25 mm sphere at (60, 25, 15) probed with a 2 mm ball.
    fn default() -> Self {
        FiveAxisTruth {
            configured: [10.0, -5.0, -20.0, -20.0, -15.0],
            truth: [10.030, -5.020, -20.0, -19.985, -15.025],
            sphere_center_mm: Point3::new(60.0, 25.0, 15.0),
            radius_mm: 12.5,
            tip_radius_mm: 1.0,
        }
    }
}

/// Set `key = value` in `[section]` only.
fn set_section_key(text: &str, section: &str, key: &str, value: &str) -> String {
    let mut current = String::new();
    text.lines()
        .map(|l| {
            let t = l.trim();
            if t.starts_with('[') && t.ends_with(']') {
                current = t.to_string();
            }
            if current == section && t.starts_with(key) && t[key.len()..].trim_start().starts_with('=') {
                format!("{key} = {value}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

/// A running simulated LinuxCNC (stopped on drop).
pub struct SimLinuxCnc {
    child: Option<Child>,
    dir: PathBuf,
    port: u16,
    sphere: SphereTruth,
    plate: PlateTruth,
    five: Option<FiveAxisTruth>,
    /// The user and the runuser program when running as root.
    run_as: Option<(String, PathBuf)>,
    // Dropped after `Drop::drop` has stopped LinuxCNC: fields drop in declaration order, the
    // cross-process lock before the in-process mutex.
    _machine_lock: MachineLock,
    _exclusive: MutexGuard<'static, ()>,
}

fn find_program(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(
            ["/usr/local/sbin", "/usr/local/bin", "/usr/sbin", "/usr/bin", "/sbin", "/bin"]
                .map(PathBuf::from),
        )
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

fn my_uid() -> Option<u32> {
    let s = fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("Uid:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn id_of(user: &str, flag: &str) -> Option<u32> {
    let out = Command::new("id").args([flag, user]).output().ok()?;
    if !out.status.success() {
        return None;
    }
    String::from_utf8_lossy(&out.stdout).trim().parse().ok()
}

/// Processes of session `sid`: (pid, command name).
fn session_processes(sid: u32) -> Vec<(u32, String)> {
    let mut out = vec![];
    let Ok(rd) = fs::read_dir("/proc") else { return out };
    for e in rd.flatten() {
        let Some(pid) = e.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else { continue };
        let Ok(stat) = fs::read_to_string(e.path().join("stat")) else { continue };
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else { continue };
        let comm = stat[open + 1..close].to_string();
        let fields: Vec<&str> = stat[close + 1..].split_whitespace().collect();
        // state ppid pgrp session …
        if fields.get(3).and_then(|s| s.parse::<u32>().ok()) == Some(sid) {
            out.push((pid, comm));
        }
    }
    out
}

fn signal(target: &str, sig: &str) {
    let _ =
        Command::new("kill").args([sig, "--", target]).stdout(Stdio::null()).stderr(Stdio::null()).status();
}

fn any_process_named(name: &str) -> bool {
    let Ok(rd) = fs::read_dir("/proc") else { return false };
    rd.flatten().any(|e| fs::read_to_string(e.path().join("comm")).map(|c| c.trim() == name).unwrap_or(false))
}

/// Stop LinuxCNCs left by a test process that was killed before it could stop them (their
/// configuration directory names a process id that no longer exists): SIGTERM to their
/// `linuxcncrsh`, found by that directory in its command line.
fn reap_orphans() {
    let Ok(rd) = fs::read_dir("/proc") else { return };
    let marker = format!("{}/truepos-lcnc-", std::env::temp_dir().display());
    let mut reaped = false;
    for e in rd.flatten() {
        let Some(pid) = e.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else { continue };
        if fs::read_to_string(e.path().join("comm")).map(|c| c.trim() != "linuxcncrsh").unwrap_or(true) {
            continue;
        }
        let Ok(cmdline) = fs::read(e.path().join("cmdline")) else { continue };
        let cmdline = String::from_utf8_lossy(&cmdline).replace('\0', " ");
        let Some(at) = cmdline.find(&marker) else { continue };
        let owner: String = cmdline[at + marker.len()..].chars().take_while(|c| c.is_ascii_digit()).collect();
        if owner.is_empty() || Path::new("/proc").join(&owner).exists() {
            continue;
        }
        eprintln!("harness: stopping a LinuxCNC left by the killed test process {owner} (linuxcncrsh {pid})");
        signal(&pid.to_string(), "-TERM");
        reaped = true;
    }
    if reaped {
        let t = Instant::now();
        while any_process_named("linuxcnc") && t.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

fn set_key(text: &str, key: &str, value: &str) -> String {
    text.lines()
        .map(|l| {
            let t = l.trim_start();
            if t.starts_with(key) && t[key.len()..].trim_start().starts_with('=') {
                format!("{key} = {value}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

fn tail(path: &Path, n: usize) -> String {
    let s = fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// A plain linuxcncrsh client for the harness's operator actions.
struct Operator {
    reader: BufReader<TcpStream>,
    writer: TcpStream,
}

impl Operator {
    fn connect(port: u16, timeout: Duration) -> Result<Operator, String> {
        let s =
            TcpStream::connect_timeout(&([127, 0, 0, 1], port).into(), timeout).map_err(|e| e.to_string())?;
        s.set_read_timeout(Some(timeout)).map_err(|e| e.to_string())?;
        let writer = s.try_clone().map_err(|e| e.to_string())?;
        let mut op = Operator { reader: BufReader::new(s), writer };
        let hello = op.cmd("hello EMC truepos-test-operator 1.1")?;
        if !hello.starts_with("HELLO ACK") {
            return Err(format!("greeting answered `{hello}`"));
        }
        op.send("set echo off")?;
        op.send("set verbose on")?;
        loop {
            if op.line()? == "SET VERBOSE ACK" {
                break;
            }
        }
        op.expect("set enable EMCTOO", "SET ENABLE ACK")?;
        Ok(op)
    }

    fn send(&mut self, l: &str) -> Result<(), String> {
        self.writer.write_all(format!("{l}\r\n").as_bytes()).map_err(|e| e.to_string())
    }

    fn line(&mut self) -> Result<String, String> {
        loop {
            let mut s = String::new();
            if self.reader.read_line(&mut s).map_err(|e| e.to_string())? == 0 {
                return Err("connection closed".into());
            }
            let t = s.trim();
            if !t.is_empty() {
                return Ok(t.to_string());
            }
        }
    }

    fn cmd(&mut self, l: &str) -> Result<String, String> {
        self.send(l)?;
        self.line()
    }

    fn expect(&mut self, l: &str, answer: &str) -> Result<(), String> {
        let a = self.cmd(l)?;
        if a == answer {
            Ok(())
        } else {
            Err(format!("`{l}` answered `{a}`"))
        }
    }
}

impl SimLinuxCnc {
    /// Start LinuxCNC with the test configuration and the given sphere; waits (≤ 30 s) until
    /// linuxcncrsh greets. Blocks while another [`SimLinuxCnc`] of this process, or of another
    /// process ([`MachineLock`] on [`lock_path`], at most [`LOCK_WAIT`]), runs.
    pub fn start(sphere: SphereTruth) -> Result<SimLinuxCnc, Unavailable> {
        SimLinuxCnc::start_with(sphere, PlateTruth::default())
    }

    /// [`SimLinuxCnc::start`] with another plate (the tip radius is the sphere's).
    pub fn start_with(sphere: SphereTruth, plate: PlateTruth) -> Result<SimLinuxCnc, Unavailable> {
        SimLinuxCnc::start_inner(sphere, plate, None)
    }

    /// Start the five-axis test machine ([`FiveAxisTruth`]). Needs the `sphere5` component
    /// installed ([`SPHERE5_MODULE`]: `halcompile --install tests/lcnc5/sphere5.comp` as root,
    /// from linuxcnc-uspace-dev); without it, [`Unavailable`] says so.
    pub fn start_five_axis(five: FiveAxisTruth) -> Result<SimLinuxCnc, Unavailable> {
        if !Path::new(SPHERE5_MODULE).is_file() {
            return Err(Unavailable(format!(
                "the five-axis truth component is not installed ({SPHERE5_MODULE}): as root, with \
                 linuxcnc-uspace-dev, `halcompile --install crates/linuxcnc/tests/lcnc5/sphere5.comp`"
            )));
        }
        let sphere = SphereTruth {
            center_mm: five.sphere_center_mm,
            radius_mm: five.radius_mm,
            tip_radius_mm: five.tip_radius_mm,
        };
        SimLinuxCnc::start_inner(sphere, PlateTruth::default(), Some(five))
    }

    fn start_inner(
        sphere: SphereTruth,
        plate: PlateTruth,
        five: Option<FiveAxisTruth>,
    ) -> Result<SimLinuxCnc, Unavailable> {
        let guard = ONE_LINUXCNC.lock().unwrap_or_else(|p| p.into_inner());
        let un = |s: String| Unavailable(s);
        let linuxcnc = find_program("linuxcnc")
            .ok_or_else(|| un("LinuxCNC is not installed (apt-get install linuxcnc-uspace)".into()))?;
        let setsid = find_program("setsid").ok_or_else(|| un("setsid (util-linux) not found".into()))?;
        let uid = my_uid().ok_or_else(|| un("cannot read this process's uid".into()))?;
        let run_as = if uid == 0 {
            let user = std::env::var("TRUEPOS_LINUXCNC_USER").unwrap_or_else(|_| "lcnc".into());
            let (Some(u), Some(g)) = (id_of(&user, "-u"), id_of(&user, "-g")) else {
                return Err(un(format!(
                    "running as root and the user `{user}` to run LinuxCNC does not exist (useradd -m {user})"
                )));
            };
            let runuser =
                find_program("runuser").ok_or_else(|| un("runuser (util-linux) not found".into()))?;
            Some((user, u, g, runuser))
        } else {
            None
        };
        let path = lock_path();
        let machine_lock = MachineLock::acquire(&path, LOCK_WAIT, || {
            eprintln!(
                "harness: another test process runs LinuxCNC ({} is locked): waiting for it",
                path.display()
            )
        })
        .map_err(un)?;
        reap_orphans();
        // Another LinuxCNC (not ours) would be killed by our start: wait for it, then give up.
        let lock = std::env::temp_dir().join("linuxcnc.lock");
        let t = Instant::now();
        while lock.exists() && any_process_named("linuxcnc") {
            if t.elapsed() > Duration::from_secs(30) {
                return Err(un(format!("another LinuxCNC is running on this machine ({})", lock.display())));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .map(|a| a.port())
            .map_err(|e| un(format!("no free port: {e}")))?;
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        let dir = std::env::temp_dir().join(format!("truepos-lcnc-{}-{nanos}", std::process::id()));
        let write = |name: &str, text: &str| fs::write(dir.join(name), text);
        let c = sphere.center_mm;
        let mut ini = set_key(INI, "DISPLAY", &format!("linuxcncrsh --port {port}"));
        for (k, v) in [
            ("OFFSET_X", -c.x),
            ("OFFSET_Y", -c.y),
            ("OFFSET_Z", -c.z),
            ("TRIP_RADIUS", sphere.radius_mm + sphere.tip_radius_mm),
        ] {
            ini = set_key(&ini, k, &format!("{v}"));
        }
        let tip = sphere.tip_radius_mm;
        let mut plate_keys = vec![
            ("TRIP_X_MIN".to_string(), plate.x_mm[0] - tip),
            ("TRIP_X_MAX".to_string(), plate.x_mm[1] + tip),
            ("TRIP_Y_MIN".to_string(), plate.y_mm[0] - tip),
            ("TRIP_Y_MAX".to_string(), plate.y_mm[1] + tip),
            ("TRIP_Z_MIN".to_string(), plate.z_mm[0] - tip),
            ("TRIP_Z_MAX".to_string(), plate.z_mm[1] + tip),
        ];
        for (i, b) in plate.bores.iter().enumerate() {
            plate_keys.push((format!("BORE{i}_OFFSET_X"), -b.center_xy_mm[0]));
            plate_keys.push((format!("BORE{i}_OFFSET_Y"), -b.center_xy_mm[1]));
            plate_keys.push((format!("BORE{i}_FREE_RADIUS"), 0.5 * b.diameter_mm - tip));
        }
        for (k, v) in plate_keys {
            ini = set_key(&ini, &k, &format!("{v}"));
        }
        let (ini_name, ini, hal_name, hal) = match &five {
            None => ("truepos_sim.ini", ini, "truepos_sim.hal", HAL),
            Some(f) => {
                let mut ini =
                    set_section_key(INI5, "[DISPLAY]", "DISPLAY", &format!("linuxcncrsh --port {port}"));
                for (k, key) in
                    ["X_ROT_POINT", "Y_ROT_POINT", "Z_ROT_POINT", "X_OFFSET", "Z_OFFSET"].iter().enumerate()
                {
                    ini = set_section_key(&ini, "[KINS]", key, &format!("{:.6}", f.configured[k]));
                    ini = set_section_key(&ini, "[TRUTH]", key, &format!("{:.6}", f.truth[k]));
                }
                let c = f.sphere_center_mm;
                for (key, v) in [
                    ("SPHERE_X", c.x),
                    ("SPHERE_Y", c.y),
                    ("SPHERE_Z", c.z),
                    ("RADIUS", f.radius_mm + f.tip_radius_mm),
                ] {
                    ini = set_section_key(&ini, "[TRUTH]", key, &format!("{v:.6}"));
                }
                ("xyzbc_sphere.ini", ini, "xyzbc_sphere.hal", HAL5)
            }
        };
        fs::create_dir_all(&dir)
            .and_then(|_| write(ini_name, &ini))
            .and_then(|_| write(hal_name, hal))
            .and_then(|_| write("sim_mm.tbl", TBL))
            .and_then(|_| write("sim_mm.var", ""))
            .map_err(|e| un(format!("cannot write the configuration in {}: {e}", dir.display())))?;
        if let Some((_, u, g, _)) = &run_as {
            for e in fs::read_dir(&dir).map_err(|e| un(e.to_string()))?.flatten() {
                let _ = std::os::unix::fs::chown(e.path(), Some(*u), Some(*g));
            }
            std::os::unix::fs::chown(&dir, Some(*u), Some(*g)).map_err(|e| un(format!("chown: {e}")))?;
        }
        let log = fs::File::create(dir.join("linuxcnc-output.txt")).map_err(|e| un(e.to_string()))?;
        let log2 = log.try_clone().map_err(|e| un(e.to_string()))?;
        let ini_path = dir.join(ini_name);
        let mut cmd = Command::new(setsid);
        if let Some((user, _, _, runuser)) = &run_as {
            cmd.arg(runuser).args(["-u", user, "--"]);
        }
        cmd.arg(&linuxcnc).arg(&ini_path);
        cmd.current_dir(&dir)
            .env_remove("DISPLAY")
            .env("PATH", "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin")
            .stdin(Stdio::null())
            .stdout(Stdio::from(log))
            .stderr(Stdio::from(log2));
        let child = cmd.spawn().map_err(|e| un(format!("cannot start linuxcnc: {e}")))?;
        let run_as = run_as.map(|(user, _, _, runuser)| (user, runuser));
        let mut sim = SimLinuxCnc {
            child: Some(child),
            dir,
            port,
            sphere,
            plate,
            five,
            run_as,
            _machine_lock: machine_lock,
            _exclusive: guard,
        };
        sim.wait_for_greeting()?;
        Ok(sim)
    }

    fn wait_for_greeting(&mut self) -> Result<(), Unavailable> {
        let t = Instant::now();
        let mut last = String::new();
        while t.elapsed() < Duration::from_secs(30) {
            if let Some(c) = self.child.as_mut() {
                if let Ok(Some(status)) = c.try_wait() {
                    let home_log = Path::new("/home")
                        .join(std::env::var("TRUEPOS_LINUXCNC_USER").unwrap_or_else(|_| "lcnc".into()))
                        .join("linuxcnc_print.txt");
                    let why = format!(
                        "LinuxCNC exited at start-up ({status}): {}\n{}",
                        tail(&self.dir.join("linuxcnc-output.txt"), 10),
                        tail(&home_log, 10)
                    );
                    self.child = None;
                    return Err(Unavailable(why));
                }
            }
            match Operator::connect(self.port, Duration::from_secs(2)) {
                Ok(_) => return Ok(()),
                Err(e) => last = e,
            }
            std::thread::sleep(Duration::from_millis(150));
        }
        Err(Unavailable(format!("linuxcncrsh did not greet within 30 s on port {}: {last}", self.port)))
    }

    /// `linuxcncrsh://127.0.0.1:PORT`.
    pub fn url(&self) -> String {
        format!("linuxcncrsh://127.0.0.1:{}", self.port)
    }

    /// The TCP port linuxcncrsh listens on (localhost).
    pub fn port(&self) -> u16 {
        self.port
    }

    /// The virtual reference sphere of this simulator (the truth to compare with).
    pub fn sphere(&self) -> SphereTruth {
        self.sphere
    }

    /// The virtual plate with bores of this simulator (the truth to compare with).
    pub fn plate(&self) -> PlateTruth {
        self.plate
    }

    /// The five-axis machine's truth, when it is the five-axis test machine.
    pub fn five_axis(&self) -> Option<FiveAxisTruth> {
        self.five
    }

    /// The operator's part: release the e-stop, switch on, home every joint where it stands,
    /// MDI mode.
    pub fn arm(&self) -> Result<(), String> {
        let mut op = Operator::connect(self.port, Duration::from_secs(5))?;
        op.expect("set set_wait done", "SET SET_WAIT ACK")?;
        op.expect("set estop off", "SET ESTOP ACK")?;
        op.expect("set machine on", "SET MACHINE ACK")?;
        op.expect("set mode manual", "SET MODE ACK")?;
        op.expect("set home -1", "SET HOME ACK")?;
        let t = Instant::now();
        loop {
            let h = op.cmd("get joint_homed")?;
            let joints = if self.five.is_some() { 5 } else { 3 };
            if h.split_whitespace().skip(1).take(joints).filter(|w| *w == "YES").count() == joints {
                break;
            }
            if t.elapsed() > Duration::from_secs(10) {
                return Err(format!("not homed after 10 s: {h}"));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        op.expect("set mode mdi", "SET MODE ACK")?;
        Ok(())
    }

    /// The operator presses the e-stop button (a HAL pin in the e-stop chain, set with
    /// `halcmd`; a second linuxcncrsh session would take the enable from truepos's session).
    pub fn press_estop(&self) -> Result<(), String> {
        self.halcmd(&["setp", "estop_button.in1", "0"])
    }

    /// Run `halcmd ARGS` as the user LinuxCNC runs as.
    pub fn halcmd(&self, args: &[&str]) -> Result<(), String> {
        let halcmd = find_program("halcmd").ok_or("halcmd not found")?;
        let mut cmd = match &self.run_as {
            Some((user, runuser)) => {
                let mut c = Command::new(runuser);
                c.args(["-u", user, "--"]).arg(&halcmd);
                c
            }
            None => Command::new(&halcmd),
        };
        let out = cmd.args(args).current_dir(&self.dir).output().map_err(|e| e.to_string())?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!("halcmd {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim()))
        }
    }

    /// An MDI line from the operator's session (e.g. to put the machine somewhere).
    pub fn operator_mdi(&self, line: &str) -> Result<(), String> {
        let mut op = Operator::connect(self.port, Duration::from_secs(30))?;
        op.expect("set set_wait done", "SET SET_WAIT ACK")?;
        op.expect(&format!("set mdi {line}"), "SET MDI ACK")?;
        let e = op.cmd("get error")?;
        if e == "ERROR OK" {
            Ok(())
        } else {
            Err(e)
        }
    }

    /// Stop LinuxCNC (also done on drop).
    pub fn stop(&mut self) {
        let Some(mut child) = self.child.take() else { return };
        let sid = child.id();
        for (pid, comm) in session_processes(sid) {
            if comm == "linuxcncrsh" {
                signal(&pid.to_string(), "-TERM");
            }
        }
        let t = Instant::now();
        let mut done = false;
        while t.elapsed() < Duration::from_secs(15) {
            if let Ok(Some(_)) = child.try_wait() {
                done = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        if !done {
            signal(&format!("-{sid}"), "-TERM");
            std::thread::sleep(Duration::from_secs(2));
            signal(&format!("-{sid}"), "-KILL");
            let _ = child.wait();
        }
        // Leftovers of our session (none after a clean exit).
        if !session_processes(sid).is_empty() {
            signal(&format!("-{sid}"), "-KILL");
        }
        let _ = fs::remove_dir_all(&self.dir);
    }
}

impl Drop for SimLinuxCnc {
    fn drop(&mut self) {
        self.stop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ini_keys_are_rewritten_in_place() {
        let t = set_key("[A]\nDISPLAY = x\nDISPLAY_X = 3\nOFFSET_X = 1\n", "DISPLAY", "linuxcncrsh --port 9");
        assert_eq!(t, "[A]\nDISPLAY = linuxcncrsh --port 9\nDISPLAY_X = 3\nOFFSET_X = 1\n");
        assert!(INI.contains("TRIP_RADIUS") && HAL.contains("motion.probe-input") && TBL.starts_with("T1"));
    }

    #[test]
    fn every_ini_value_the_hal_reads_exists_and_the_harness_rewrites_it() {
        let mut n = 0;
        for section in ["[PROBE_SPHERE]", "[PROBE_PLATE]"] {
            for (at, _) in HAL.match_indices(section) {
                let key: String = HAL[at + section.len()..]
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if key.is_empty() {
                    continue; // the section named in a comment
                }
                assert!(
                    INI.lines().any(|l| l.starts_with(&format!("{key} = "))),
                    "{section}{key} not in the INI"
                );
                // The harness rewrites it: a changed value shows up.
                assert_ne!(set_key(INI, &key, "12345.5"), INI, "{key}");
                n += 1;
            }
        }
        // 4 sphere values; 6 box limits and 3 values per bore.
        assert_eq!(n, 4 + 6 + 4 * 3);
    }

    /// Not a test on its own: the other process of the lock tests (run by them with
    /// `TRUEPOS_TEST_LOCK_HOLD` set; without it, it returns at once).
    #[test]
    fn lock_holder_child() {
        let Some(path) = std::env::var_os("TRUEPOS_TEST_LOCK_HOLD") else { return };
        let path = PathBuf::from(path);
        let lock = MachineLock::acquire(&path, Duration::from_secs(30), || {}).unwrap();
        fs::write(path.with_extension("held"), "").unwrap();
        std::thread::sleep(Duration::from_millis(1500));
        fs::write(path.with_extension("releasing"), "").unwrap();
        drop(lock);
    }

    fn spawn_holder(path: &Path) -> Child {
        Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "harness::tests::lock_holder_child", "--nocapture", "--test-threads=1"])
            .env("TRUEPOS_TEST_LOCK_HOLD", path)
            .stdout(Stdio::null())
            .spawn()
            .unwrap()
    }

    fn wait_for(file: &Path) {
        let t = Instant::now();
        while !file.exists() {
            assert!(t.elapsed() < Duration::from_secs(30), "the other process never took the lock");
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    #[test]
    fn a_second_process_waits_for_the_lock_until_the_first_releases_it() {
        let dir = std::env::temp_dir().join(format!("truepos-lock-test-{}-a", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("lcnc.lock");
        let mut child = spawn_holder(&path);
        wait_for(&path.with_extension("held"));
        // Busy: a short attempt fails and says so.
        let e = MachineLock::acquire(&path, Duration::from_millis(200), || {}).unwrap_err();
        assert!(e.contains("still locked"), "{e}");
        // A patient one waits until the other process has released it.
        let t = Instant::now();
        let mut waited = false;
        let lock = MachineLock::acquire(&path, Duration::from_secs(30), || waited = true).unwrap();
        let secs = t.elapsed().as_secs_f64();
        assert!(waited);
        assert!(path.with_extension("releasing").exists(), "lock granted while the other process held it");
        // The holder keeps it 1.5 s after signalling; 0.2 s of it already spent above.
        assert!(secs > 0.5, "waited only {secs} s");
        eprintln!("lock test: second process waited {secs:.2} s for the first to release the lock");
        drop(lock);
        assert!(child.wait().unwrap().success());
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_killed_holder_releases_the_lock() {
        let dir = std::env::temp_dir().join(format!("truepos-lock-test-{}-b", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("lcnc.lock");
        let mut child = spawn_holder(&path);
        wait_for(&path.with_extension("held"));
        assert!(MachineLock::acquire(&path, Duration::from_millis(100), || {}).is_err());
        child.kill().unwrap();
        child.wait().unwrap();
        let t = Instant::now();
        let lock = MachineLock::acquire(&path, Duration::from_secs(5), || {}).unwrap();
        assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
        assert!(!path.with_extension("releasing").exists());
        drop(lock);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn threads_contending_for_the_lock_are_never_inside_together() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        use std::sync::Arc;
        let dir = std::env::temp_dir().join(format!("truepos-lock-test-{}-c", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("lcnc.lock");
        let inside = Arc::new(AtomicUsize::new(0));
        let max = Arc::new(AtomicUsize::new(0));
        let hs: Vec<_> = (0..4)
            .map(|_| {
                let (path, inside, max) = (path.clone(), inside.clone(), max.clone());
                std::thread::spawn(move || {
                    for _ in 0..3 {
                        let _l = MachineLock::acquire(&path, Duration::from_secs(30), || {}).unwrap();
                        let n = inside.fetch_add(1, Ordering::SeqCst) + 1;
                        max.fetch_max(n, Ordering::SeqCst);
                        std::thread::sleep(Duration::from_millis(20));
                        inside.fetch_sub(1, Ordering::SeqCst);
                    }
                })
            })
            .collect();
        for h in hs {
            h.join().unwrap();
        }
        assert_eq!(max.load(Ordering::SeqCst), 1);
        let _ = fs::remove_dir_all(&dir);
    }
}
