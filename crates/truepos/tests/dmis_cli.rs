//! `truepos dmis run` as a process: the NIST example on the virtual CMM (output file, JSON,
//! progress), the same through `truepos ippdme serve`, `--dry-run`, a malformed program (exit 2
//! naming file, line and column, no output file), an unknown sensor (exit 2, nothing moved), a
//! probing without surface (exit 3 naming the line, no output file), a tolerance out (exit 1).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn truepos() -> Command {
    Command::new(env!("CARGO_BIN_EXE_truepos"))
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn copy_example(dir: &Path) -> (PathBuf, PathBuf) {
    let prog = dir.join("simple_in.dms");
    let part = dir.join("part.toml");
    std::fs::copy(repo().join("data/dmis/simple_in.dms"), &prog).unwrap();
    std::fs::copy(repo().join("data/dmis/simple_part.toml"), &part).unwrap();
    (prog, part)
}

#[test]
fn the_nist_example_runs_on_the_virtual_cmm() {
    let dir = tempfile::tempdir().unwrap();
    let (prog, part) = copy_example(dir.path());
    let out = truepos()
        .current_dir(dir.path())
        .args(["dmis", "run"])
        .arg(&prog)
        .arg("--part")
        .arg(&part)
        .args(["--sensor", "PROBE6=Probe1", "--json"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("dmis: line 23: MEAS/CIRCLE,F(A_CIRCLE): 4 points"), "{stderr}");
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["n_points"], 4);
    let f = &j["features"][0];
    assert_eq!(f["label"], "A_CIRCLE");
    assert_eq!(f["type"], "CIRCLE");
    assert!((f["diameter_mm"].as_f64().unwrap() - 50.0).abs() < 0.01, "{f}");
    assert!((f["center_mm"][0].as_f64().unwrap() - 50.0).abs() < 0.01, "{f}");
    // No DEVICE in the program: the results go beside it.
    let results = std::fs::read_to_string(dir.path().join("simple_in_output.dms")).unwrap();
    assert!(results.starts_with("FILNAM/'IPP SIMPLE DMIS output'\nUNITS/MM,ANGDEC\nD(START)=DATSET/MCS\nOUTPUT/FA(A_CIRCLE)\nFA(A_CIRCLE) = FEAT/CIRCLE, INNER, CART,  $\n  "), "{results}");
    assert!(results.ends_with("ENDFIL\n"));
}

#[test]
fn the_nist_example_runs_through_an_ippdme_server_process() {
    let dir = tempfile::tempdir().unwrap();
    let (prog, part) = copy_example(dir.path());
    let (mut server, addr) = common::ippdme_server(dir.path(), &part, &[]);
    common::home_cmm(&addr, None);
    let results = dir.path().join("results.dms");
    let out = truepos()
        .current_dir(dir.path())
        .args(["dmis", "run"])
        .arg(&prog)
        .args(["--controller", &format!("ippdme://{addr}"), "--sensor", "PROBE6=Probe1", "--output"])
        .arg(&results)
        .output()
        .unwrap();
    let _ = server.kill();
    let _ = server.wait();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read_to_string(&results).unwrap().contains("FA(A_CIRCLE) = FEAT/CIRCLE, INNER, CART"));
}

#[test]
fn dry_run_lists_the_motions_without_a_machine() {
    let dir = tempfile::tempdir().unwrap();
    let out = truepos()
        .current_dir(dir.path())
        .args(["dmis", "run", "--dry-run"])
        .arg(repo().join("data/dmis/simple_in.dms"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(text.lines().filter(|l| l.starts_with("PTMEAS")).count(), 4, "{text}");
    assert!(text.lines().next().unwrap().starts_with("GOTO (50.0000, 50.0000, 175.0000)"), "{text}");
}

#[test]
fn refusals_have_their_exit_codes_and_leave_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let (prog, part) = copy_example(dir.path());
    let run = |prog: &Path, extra: &[&str]| {
        truepos()
            .current_dir(dir.path())
            .args(["dmis", "run"])
            .arg(prog)
            .arg("--part")
            .arg(&part)
            .args(extra)
            .output()
            .unwrap()
    };
    // Malformed: exit 2 with file:line:col.
    let bad = dir.path().join("bad.dms");
    std::fs::write(
        &bad,
        std::fs::read_to_string(&prog).unwrap().replace("PTMEAS/CART, 25.0", "PTMEAS/CART, 25.0.0"),
    )
    .unwrap();
    let out = run(&bad, &["--sensor", "PROBE6=Probe1"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("bad.dms:26:"), "{stderr}");
    assert!(!dir.path().join("bad_output.dms").exists());
    // A sensor the CMM has no tool for: exit 2 before any motion.
    let out = run(&prog, &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("simple_in.dms:12:") && stderr.contains("--sensor PROBE6=TOOL"), "{stderr}");
    assert!(!stderr.contains("MEAS/"), "{stderr}");
    // The empty tool, NoTool, cannot measure: exit 2 before any motion (hostile audit 2 of
    // issue 31, F26: found at the first MEAS, after the moves, exit 3).
    let out = run(&prog, &["--sensor", "PROBE6=NoTool"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("simple_in.dms:12:") && stderr.contains("NoTool, I++ DME's empty tool"),
        "{stderr}"
    );
    // No surface: exit 3 naming the PTMEAS line; no results file.
    let lost = dir.path().join("lost.dms");
    std::fs::write(
        &lost,
        std::fs::read_to_string(&prog).unwrap().replace("PTMEAS/CART, 75.0", "PTMEAS/CART, 60.0"),
    )
    .unwrap();
    let out = run(&lost, &["--sensor", "PROBE6=Probe1"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("lost.dms:25:") && stderr.contains("without contact"), "{stderr}");
    assert!(!dir.path().join("lost_output.dms").exists());
    // A tolerance out: exit 1, results written.
    let tight = dir.path().join("tight.dms");
    std::fs::write(
        &tight,
        std::fs::read_to_string(&prog)
            .unwrap()
            .replace("OUTPUT/FA(A_CIRCLE)", "T(D)=TOL/DIAM,-0.00001,0.00001\nOUTPUT/FA(A_CIRCLE),TA(D)"),
    )
    .unwrap();
    let out = run(&tight, &["--sensor", "PROBE6=Probe1"]);
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    let results = std::fs::read_to_string(dir.path().join("tight_output.dms")).unwrap();
    assert!(results.contains("TA(D) = TOL/DIAM, ") && results.contains(", OUTOL"), "{results}");
}

/// A run is recorded in the audit trail given by `--db`: the controller, every actual feature's
/// values and every tolerance with its limits and verdict, the end status; the chain verifies.
/// A dry run records nothing.
#[test]
fn a_run_is_recorded_in_the_audit_trail() {
    let dir = tempfile::tempdir().unwrap();
    let (example, part) = copy_example(dir.path());
    // The example with a diameter tolerance (±0.1 mm: in).
    let prog = dir.path().join("tol.dms");
    let text = std::fs::read_to_string(&example).unwrap();
    std::fs::write(
        &prog,
        text.replace("OUTPUT/FA(A_CIRCLE)", "T(D)=TOL/DIAM,-0.1,0.1\nOUTPUT/FA(A_CIRCLE),TA(D)"),
    )
    .unwrap();
    let db = dir.path().join("trail.sqlite");
    let run_program = |prog: &Path, extra: &[&str]| {
        truepos()
            .current_dir(dir.path())
            .args(["dmis", "run"])
            .arg(prog)
            .arg("--part")
            .arg(&part)
            .args(["--sensor", "PROBE6=Probe1", "--json", "--db"])
            .arg(&db)
            .args(extra)
            .output()
            .unwrap()
    };
    let run = |extra: &[&str]| run_program(&prog, extra);
    let o = run(&["--dry-run"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!db.exists(), "a dry run records nothing");
    let o = run(&[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("audit trail appended to"), "{stderr}");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let show = truepos()
        .current_dir(dir.path())
        .args(["audit", "show", "1", "--json", "--db"])
        .arg(&db)
        .output()
        .unwrap();
    assert!(show.status.success(), "{}", String::from_utf8_lossy(&show.stderr));
    let s: serde_json::Value = serde_json::from_slice(&show.stdout).unwrap();
    assert_eq!(s["run"]["status"], "SUCCESS");
    assert_eq!(s["run"]["note"], "dmis run");
    assert!(s["run"]["controller"].as_str().unwrap().starts_with("ippdme://127.0.0.1"), "{}", s["run"]);
    let results = s["results"].as_array().unwrap();
    // Every tolerance of the JSON is in the trail with its value, limits and verdict.
    let tols = j["tolerances"].as_array().unwrap();
    assert!(!tols.is_empty());
    for t in tols {
        let r = results
            .iter()
            .find(|r| r["fields"]["kind"] == "tolerance" && r["fields"]["label"] == t["label"])
            .unwrap_or_else(|| panic!("tolerance {} not recorded", t["label"]));
        let f = &r["fields"];
        assert_eq!(f["verdict"], t["verdict"]);
        if let Some(v) = t["value_mm"].as_f64() {
            assert_eq!(f["value"].as_f64().unwrap(), v);
            assert_eq!(f["lower_limit"].as_f64().unwrap(), t["limits_mm"][0].as_f64().unwrap());
            assert_eq!(f["unit"], "mm");
        }
    }
    // Every actual feature's centre or point is there, x y z, as the JSON gives it.
    for f in j["features"].as_array().unwrap().iter().filter(|f| f["actual"] == true) {
        let p = f.get("center_mm").or_else(|| f.get("point_mm")).or_else(|| f.get("apex_mm")).unwrap();
        for (k, q) in ["x", "y", "z"].iter().enumerate() {
            let r = results
                .iter()
                .find(|r| r["fields"]["label"] == f["label"] && r["fields"]["quantity"] == *q)
                .unwrap_or_else(|| panic!("{} {q} not recorded", f["label"]));
            assert_eq!(r["fields"]["value"].as_f64().unwrap(), p[k].as_f64().unwrap());
        }
    }
    // A tolerance out: exit 1, the run ends FAILURE with the reason, the verdict recorded.
    let tight = dir.path().join("tight.dms");
    std::fs::write(
        &tight,
        text.replace("OUTPUT/FA(A_CIRCLE)", "T(D)=TOL/DIAM,-0.00001,0.00001\nOUTPUT/FA(A_CIRCLE),TA(D)"),
    )
    .unwrap();
    assert_eq!(run_program(&tight, &[]).status.code(), Some(1));
    let show = truepos()
        .current_dir(dir.path())
        .args(["audit", "show", "2", "--json", "--db"])
        .arg(&db)
        .output()
        .unwrap();
    let s: serde_json::Value = serde_json::from_slice(&show.stdout).unwrap();
    assert_eq!(s["run"]["status"], "FAILURE");
    assert!(s["run"]["message"].as_str().unwrap().contains("OUTOL"), "{}", s["run"]);
    assert!(s["results"].as_array().unwrap().iter().any(|r| r["fields"]["verdict"] == "OUTOL"));
    let v = truepos().current_dir(dir.path()).args(["audit", "verify", "--db"]).arg(&db).output().unwrap();
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stderr));
}

/// A run ended by SIGINT sends no motion after the one in progress, writes no results file, is
/// closed in the audit trail as ABORTED with the signal named, and exits 130.
#[test]
fn a_run_interrupted_by_sigint_is_closed_as_aborted() {
    let dir = tempfile::tempdir().unwrap();
    let (example, part) = copy_example(dir.path());
    // The example's circle measured with 20,000 points: long enough to be interrupted.
    let text = std::fs::read_to_string(&example).unwrap();
    let n = 20_000;
    let mut pts = String::new();
    for k in 0..n {
        let a = k as f64 / n as f64 * std::f64::consts::TAU;
        pts.push_str(&format!(
            "PTMEAS/CART, {:.6}, {:.6}, 40.0, {:.6}, {:.6}, 0.0\n",
            50.0 + 25.0 * a.cos(),
            50.0 + 25.0 * a.sin(),
            -a.cos(),
            -a.sin()
        ));
    }
    let start = text.find("MEAS/CIRCLE,F(A_CIRCLE),4").unwrap();
    let end = text.find("GOTO/ 50.0, 50.0, 40.0\nENDMES").unwrap();
    let long = format!(
        "{}MEAS/CIRCLE,F(A_CIRCLE),{n}\nGOTO/ 50.0, 50.0, 40.0\n{pts}{}",
        &text[..start],
        &text[end..]
    );
    let prog = dir.path().join("long.dms");
    std::fs::write(&prog, long).unwrap();
    let db = dir.path().join("trail.sqlite");
    let child = truepos()
        .current_dir(dir.path())
        .args(["dmis", "run"])
        .arg(&prog)
        .arg("--part")
        .arg(&part)
        .args(["--sensor", "PROBE6=Probe1", "--db"])
        .arg(&db)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the run row exists (the program was checked, the run started), then interrupt.
    let t0 = std::time::Instant::now();
    while !db.exists() && t0.elapsed().as_secs() < 30 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    std::thread::sleep(std::time::Duration::from_millis(100));
    let _ = Command::new("kill").args(["-INT", &child.id().to_string()]).status();
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let show = truepos()
        .current_dir(dir.path())
        .args(["audit", "show", "1", "--json", "--db"])
        .arg(&db)
        .output()
        .unwrap();
    let s: serde_json::Value = serde_json::from_slice(&show.stdout).unwrap();
    if out.status.code() == Some(0) {
        eprintln!("note: the run ended before SIGINT arrived");
        assert_eq!(s["run"]["status"], "SUCCESS");
        return;
    }
    eprintln!("{}", err.lines().last().unwrap_or(""));
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert_eq!(s["run"]["status"], "ABORTED", "{err}");
    assert!(s["run"]["message"].as_str().unwrap().contains("SIGINT"), "{}", s["run"]);
    assert!(s["run"]["ended_at"].is_string());
    assert!(err.contains("ABORTED") && err.contains("no results file"), "{err}");
    assert!(!dir.path().join("long_output.dms").exists());
    let v = truepos().current_dir(dir.path()).args(["audit", "verify", "--db"]).arg(&db).output().unwrap();
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stderr));
}

/// One I++ DME command of a session, for comparison: its name and its numbers (the tool name
/// kept for ChangeTool), from a `.prg` line (`00180 PtMeas(X(75.0), …)`) or a server log line.
fn command_of(call: &str) -> (String, Vec<f64>, String) {
    let call = call.trim();
    let name = call.split('(').next().unwrap_or("").to_string();
    let args = &call[name.len()..];
    let quoted = args.split('"').nth(1).unwrap_or("").to_string();
    // Numbers outside quoted strings (a tool name's digits are not arguments).
    let unquoted: String = args.split('"').step_by(2).collect();
    let mut nums = Vec::new();
    let mut cur = String::new();
    for ch in unquoted.chars().chain(std::iter::once(' ')) {
        if ch.is_ascii_digit() || ch == '.' || ch == '-' || ch == '+' {
            cur.push(ch);
        } else {
            if let Ok(v) = cur.parse::<f64>() {
                nums.push(v);
            }
            cur.clear();
        }
    }
    (name, nums, quoted)
}

/// The NIST example through `truepos ippdme serve`: the motions, probings and tool change our
/// client sends (read back from the server's log) are the ones of the I++ DME session a real
/// client produced for the same program (`data/dmis/simple.prg`): the same GoTo targets and
/// PtMeas points and directions in the same order, the tool change (PROBE6 mapped to the CMM's
/// tool), the approach/search/retract distances of SNSET, and FEDRAT/POSVEL's 1.8 m/min as
/// the GoTo speed (30 mm/s).
#[test]
fn the_nist_example_sends_the_commands_of_the_nist_session() {
    let dir = tempfile::tempdir().unwrap();
    let (prog, part) = copy_example(dir.path());
    let log = dir.path().join("session.log");
    let (mut server, addr) = common::ippdme_server(dir.path(), &part, &["--log".as_ref(), log.as_os_str()]);
    // The operator homes the machine (truepos never does), as the NIST session's Home().
    common::home_cmm(&addr, None);
    let out = truepos()
        .current_dir(dir.path())
        .args(["dmis", "run"])
        .arg(&prog)
        .args(["--controller", &format!("ippdme://{addr}"), "--sensor", "PROBE6=Probe1"])
        .output()
        .unwrap();
    let _ = server.kill();
    let _ = server.wait();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&log).unwrap();
    // The run's session: the client lines after the second StartSession.
    let sent: Vec<&str> = text.lines().filter_map(|l| l.split_once(" < ").map(|x| x.1)).collect();
    let start = sent.iter().rposition(|l| l.ends_with("StartSession()")).unwrap();
    let ours: Vec<(String, Vec<f64>, String)> =
        sent[start..].iter().map(|l| command_of(l.split_once(' ').map_or(*l, |x| x.1))).collect();
    let nist_text = std::fs::read_to_string(repo().join("data/dmis/simple.prg")).unwrap();
    let nist: Vec<(String, Vec<f64>, String)> = nist_text
        .lines()
        .filter(|l| l.len() > 6 && l.as_bytes()[0].is_ascii_digit())
        .map(|l| command_of(&l[6..]))
        .collect();
    let moves = |s: &[(String, Vec<f64>, String)]| -> Vec<(String, Vec<f64>)> {
        s.iter()
            .filter(|c| ["GoTo", "PtMeas", "ChangeTool"].contains(&c.0.as_str()))
            .map(|c| (c.0.clone(), c.1.clone()))
            .collect()
    };
    let (a, b) = (moves(&ours), moves(&nist));
    assert_eq!(a.len(), b.len(), "ours {a:?}\nNIST {b:?}");
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.0, y.0, "ours {a:?}\nNIST {b:?}");
        assert_eq!(x.1.len(), y.1.len(), "{x:?} vs {y:?}");
        for (u, v) in x.1.iter().zip(&y.1) {
            assert!((u - v).abs() < 1e-9, "{x:?} vs {y:?}");
        }
    }
    // The tool: the session's reference tool, ours the CMM's tool PROBE6 is mapped to.
    let tool = |s: &[(String, Vec<f64>, String)]| s.iter().find(|c| c.0 == "ChangeTool").map(|c| c.2.clone());
    assert_eq!((tool(&nist).as_deref(), tool(&ours).as_deref()), (Some("RefTool"), Some("Probe1")));
    // The properties set before the first PtMeas: approach, search, retract 10 mm; GoTo speed 30.
    let props = |s: &[(String, Vec<f64>, String)], raw: &[String]| {
        let first = s.iter().position(|c| c.0 == "PtMeas").unwrap();
        let set: Vec<&String> = raw[..first].iter().filter(|l| l.contains("SetProp")).collect();
        let value = |key: &str| {
            set.iter().find_map(|l| {
                let i = l.find(key)? + key.len();
                let rest = &l[i..];
                let rest = rest.strip_prefix(".Act").unwrap_or(rest);
                rest.trim_start_matches('(').split(')').next()?.parse::<f64>().ok()
            })
        };
        ["PtMeasPar.Approach", "PtMeasPar.Search", "PtMeasPar.Retract", "GoToPar.Speed"].map(value)
    };
    let raw_ours: Vec<String> = sent[start..].iter().map(|l| l.to_string()).collect();
    let raw_nist: Vec<String> = nist_text
        .lines()
        .filter(|l| l.len() > 6 && l.as_bytes()[0].is_ascii_digit())
        .map(|l| l.to_string())
        .collect();
    assert_eq!(props(&nist, &raw_nist), [Some(10.0), Some(10.0), Some(10.0), Some(30.0)]);
    assert_eq!(props(&ours, &raw_ours), props(&nist, &raw_nist), "{raw_ours:#?}");
}

// ---------------------------------------------------------------------------------------------
// --qif: the QIF 3 results document of a run

/// xmllint against the official QIF 3.0 schemas (`data/schemas/qif3`), as the QIF tests of
/// `truepos fit` do: `Some(valid)`, or `None` with a loud SKIPPED line without xmllint.
fn xmllint_qif(path: &Path) -> Option<bool> {
    let xsd = repo().join("data/schemas/qif3/QIFApplications/QIFDocument.xsd");
    assert!(xsd.is_file(), "QIF schemas missing at {}", xsd.display());
    match Command::new("xmllint").args(["--noout", "--nonet", "--schema"]).arg(&xsd).arg(path).output() {
        Ok(o) => {
            if !o.status.success() {
                eprintln!("{}", String::from_utf8_lossy(&o.stderr));
            }
            Some(o.status.success())
        }
        Err(e) => {
            eprintln!("SKIPPED: xmllint not available ({e}); install libxml2-utils: the QIF document is NOT schema-validated");
            None
        }
    }
}

fn el<'a, 'i>(n: roxmltree::Node<'a, 'i>, name: &str) -> Option<roxmltree::Node<'a, 'i>> {
    n.children().find(|c| c.is_element() && c.tag_name().name() == name)
}

fn nums(n: roxmltree::Node) -> Vec<f64> {
    n.text().unwrap_or("").split_whitespace().map(|t| t.parse().unwrap()).collect()
}

fn num(n: roxmltree::Node, name: &str) -> f64 {
    nums(el(n, name).unwrap_or_else(|| panic!("no <{name}> in <{}>", n.tag_name().name())))[0]
}

fn json_vec(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

/// Every actual feature and every tolerance of the JSON `j` is in the QIF document `xml` with
/// the same values, and the document's references hold: characteristic measurement → item →
/// nominal → definition, measurement → the feature measurements of the tolerance's features,
/// position and orientation definitions → a datum reference frame of the program's datums.
/// Returns the number of characteristics checked.
fn check_qif_against_json(xml: &str, j: &serde_json::Value, datums: &[(&str, &[&str])]) -> usize {
    let doc = roxmltree::Document::parse(xml).unwrap();
    let qif = Qif { doc: &doc };
    // Features, in output order.
    let feats = qif.elements_ending("FeatureMeasurement");
    let jf: Vec<&serde_json::Value> =
        j["features"].as_array().unwrap().iter().filter(|f| f["actual"] == true).collect();
    assert_eq!(feats.len(), jf.len(), "one feature measurement per actual feature of the JSON");
    for (q, f) in feats.iter().zip(&jf) {
        check_feature(*q, f);
    }
    // Characteristics, in order.
    let meas = qif.elements_ending("CharacteristicMeasurement");
    let jt = j["tolerances"].as_array().unwrap();
    assert_eq!(meas.len(), jt.len(), "one characteristic per tolerance");
    for (m, t) in meas.iter().zip(jt) {
        qif.check_characteristic(*m, t, datums);
    }
    let overall =
        doc.descendants().find(|n| n.tag_name().name() == "InspectionStatusEnum").unwrap().text().unwrap();
    let want = if meas.is_empty() {
        "NOT_CALCULATED"
    } else if j["verdict"] == "INTOL" {
        "PASS"
    } else {
        "FAIL"
    };
    assert_eq!(overall, want);
    meas.len()
}

/// A QIF value and its JSON counterpart agree (relative 1e-9).
fn same(a: f64, b: f64, what: &str) {
    assert!((a - b).abs() <= 1e-9 * (1.0 + b.abs()), "{what}: QIF {a} vs JSON {b}")
}

/// The QIF feature kind of a DMIS feature type of the JSON.
fn qif_feature_kind(ty: &str) -> &'static str {
    match ty {
        "POINT" => "Point",
        "PLANE" => "Plane",
        "LINE" => "Line",
        "CIRCLE" => "Circle",
        "CYLNDR" => "Cylinder",
        "SPHERE" => "Sphere",
        "CONE" => "Cone",
        t => panic!("type {t}"),
    }
}

/// The QIF characteristic of a DMIS tolerance kind of the JSON.
fn qif_characteristic(kind: &str) -> &'static str {
    match kind {
        "FLAT" => "Flatness",
        "STRGHT" => "Straightness",
        "CIRLTY" => "Circularity",
        "CYLCTY" => "Cylindricity",
        "DIAM" => "Diameter",
        "RAD" => "Radius",
        "POS" => "Position",
        "PERP" => "Perpendicularity",
        "PARLEL" => "Parallelism",
        "ANGLB" => "AngleBetween",
        "DISTB" => "DistanceBetween",
        k => panic!("kind {k}"),
    }
}

/// The feature measurement `q` is the JSON's actual feature `f`: name, kind, number of points,
/// location, direction, diameter, and the uncertainties the JSON has.
fn check_feature(q: roxmltree::Node, f: &serde_json::Value) {
    let label = f["label"].as_str().unwrap();
    assert_eq!(el(q, "FeatureName").unwrap().text(), Some(label));
    let kind = qif_feature_kind(f["type"].as_str().unwrap());
    assert_eq!(q.tag_name().name(), format!("{kind}FeatureMeasurement"), "{label}");
    let n_points = el(q, "Attributes").and_then(|a| el(a, "AttributeI1")).unwrap();
    assert_eq!(n_points.attribute("name"), Some("n_points"));
    assert_eq!(
        n_points.attribute("value").unwrap().parse::<u64>().unwrap(),
        f["n_points"].as_u64().unwrap(),
        "{label}"
    );
    let (loc, dir) = match kind {
        "Cylinder" | "Cone" => {
            let ax = el(q, "Axis").unwrap();
            (el(ax, "AxisPoint").unwrap(), el(ax, "Direction"))
        }
        "Line" => (el(q, "Location").unwrap(), el(q, "Direction")),
        _ => (el(q, "Location").unwrap(), el(q, "Normal")),
    };
    let jloc = f.get("center_mm").or(f.get("point_mm")).or(f.get("apex_mm")).unwrap();
    for (a, b) in nums(loc).iter().zip(json_vec(jloc)) {
        same(*a, b, label);
    }
    let jdir = f.get("normal").or(f.get("axis")).or(f.get("direction"));
    assert_eq!(dir.is_some(), jdir.is_some(), "{label}: direction");
    if let (Some(d), Some(jd)) = (dir, jdir) {
        for (a, b) in nums(d).iter().zip(json_vec(jd)) {
            same(*a, b, label);
        }
    }
    if let Some(dia) = f.get("diameter_mm") {
        same(num(q, "Diameter"), dia.as_f64().unwrap(), label);
    }
    check_feature_uncertainty(q, loc, f, label);
}

/// The uncertainties (k = 1) of the JSON feature `f` where it has them are those of the
/// feature measurement `q` (location `loc`, diameter).
fn check_feature_uncertainty(q: roxmltree::Node, loc: roxmltree::Node, f: &serde_json::Value, label: &str) {
    let key = if f.get("center_mm").is_some() {
        "center_mm"
    } else if f.get("apex_mm").is_some() {
        "apex_mm"
    } else {
        "point_mm"
    };
    if let Some(u) = f["uncertainty"][key].as_array() {
        for (axis, ju) in ["x", "y", "z"].iter().zip(u) {
            let qa = loc.attribute(format!("{axis}CombinedUncertainty").as_str());
            match ju.as_f64() {
                Some(v) => same(qa.unwrap().parse().unwrap(), v.abs(), label),
                None => assert!(qa.is_none(), "{label}: no uncertainty in the JSON, none in the QIF"),
            }
        }
    }
    if let Some(u) = f["uncertainty"]["diameter_mm"].as_f64() {
        same(
            el(q, "Diameter").unwrap().attribute("combinedUncertainty").unwrap().parse().unwrap(),
            u.abs(),
            label,
        );
    }
}

/// The QIF document under test, for following its id references.
struct Qif<'a, 'i> {
    /// The parsed document.
    doc: &'a roxmltree::Document<'i>,
}

impl<'a, 'i> Qif<'a, 'i> {
    /// The element with the id `id` (there must be one).
    fn by_id(&self, id: &str) -> roxmltree::Node<'a, 'i> {
        self.doc
            .descendants()
            .find(|n| n.attribute("id") == Some(id))
            .unwrap_or_else(|| panic!("no element with id {id}"))
    }

    /// The elements whose names end with `suffix`, in document order.
    fn elements_ending(&self, suffix: &str) -> Vec<roxmltree::Node<'a, 'i>> {
        self.doc.descendants().filter(|n| n.is_element() && n.tag_name().name().ends_with(suffix)).collect()
    }

    /// The `FeatureName` of the feature measurement with the id `id`.
    fn feature_name(&self, id: &str) -> String {
        el(self.by_id(id), "FeatureName").unwrap().text().unwrap().to_string()
    }

    /// The characteristic measurement `m` is the JSON's tolerance `t`: its chain (item →
    /// nominal → definition) of the tolerance's kind, status, features, values, uncertainty
    /// and, for the tolerances `datums` names, the datums of its reference frame.
    fn check_characteristic(&self, m: roxmltree::Node, t: &serde_json::Value, datums: &[(&str, &[&str])]) {
        let label = t["label"].as_str().unwrap();
        let kind = t["kind"].as_str().unwrap();
        let item = self.by_id(el(m, "CharacteristicItemId").unwrap().text().unwrap());
        assert_eq!(el(item, "Name").unwrap().text(), Some(label));
        let nominal = self.by_id(el(item, "CharacteristicNominalId").unwrap().text().unwrap());
        let def = self.by_id(el(nominal, "CharacteristicDefinitionId").unwrap().text().unwrap());
        let stem = m.tag_name().name().trim_end_matches("CharacteristicMeasurement");
        for n in [item, nominal, def] {
            assert!(
                n.tag_name().name().starts_with(stem),
                "{label}: {} in a {stem} chain",
                n.tag_name().name()
            );
        }
        assert_eq!(stem, qif_characteristic(kind), "{label}");
        let status = el(el(m, "Status").unwrap(), "CharacteristicStatusEnum").unwrap().text().unwrap();
        assert_eq!(status, if t["verdict"] == "INTOL" { "PASS" } else { "FAIL" }, "{label}");
        // The features it was evaluated on.
        let ids: Vec<String> = el(m, "FeatureMeasurementIds")
            .unwrap()
            .children()
            .filter(|c| c.is_element())
            .map(|c| self.feature_name(c.text().unwrap()))
            .collect();
        let jnames: Vec<String> =
            t["features"].as_array().unwrap().iter().map(|x| x.as_str().unwrap().to_string()).collect();
        assert_eq!(ids, jnames, "{label}");
        check_characteristic_values(m, nominal, def, t);
        if let Some(u) = t["uncertainty_mm"].as_f64().or(t["uncertainty_deg"].as_f64()) {
            same(
                el(m, "Value").unwrap().attribute("combinedUncertainty").unwrap().parse().unwrap(),
                u,
                label,
            );
        }
        // Datums: the frame's datum labels in precedence order.
        if let Some((_, want)) = datums.iter().find(|(l, _)| *l == label) {
            let drf = self.by_id(el(def, "DatumReferenceFrameId").unwrap().text().unwrap());
            let got: Vec<String> = drf
                .descendants()
                .filter(|n| n.tag_name().name() == "DatumDefinitionId")
                .map(|n| el(self.by_id(n.text().unwrap()), "DatumLabel").unwrap().text().unwrap().to_string())
                .collect();
            assert_eq!(got, *want, "{label}: datums");
        }
    }
}

/// The value of the characteristic measurement `m` and the limits of its nominal and
/// definition are the JSON tolerance `t`'s (DMIS reports a size's deviation, QIF the size).
fn check_characteristic_values(
    m: roxmltree::Node,
    nominal: roxmltree::Node,
    def: roxmltree::Node,
    t: &serde_json::Value,
) {
    let label = t["label"].as_str().unwrap();
    let kind = t["kind"].as_str().unwrap();
    let value = num(m, "Value");
    match kind {
        "DIAM" | "RAD" | "DISTB" => {
            let target = num(nominal, "TargetValue");
            let tol = el(def, "Tolerance").unwrap();
            let (lo, hi) = (num(tol, "MinValue"), num(tol, "MaxValue"));
            let lim = json_vec(&t["limits_mm"]);
            let v = t["value_mm"].as_f64().unwrap();
            if kind == "DISTB" {
                same(value, v, label);
                same(target + lo, lim[0], label);
                same(target + hi, lim[1], label);
            } else {
                // DMIS reports the deviation from nominal; QIF the actual size.
                same(value - target, v, label);
                same(lo, lim[0], label);
                same(hi, lim[1], label);
            }
        }
        "ANGLB" => {
            let target = num(nominal, "TargetValue");
            let tol = el(def, "Tolerance").unwrap();
            let lim = json_vec(&t["limits_deg"]);
            same(value, t["value_deg"].as_f64().unwrap(), label);
            same(target + num(tol, "MinValue"), lim[0], label);
            same(target + num(tol, "MaxValue"), lim[1], label);
        }
        _ => {
            same(value, t["value_mm"].as_f64().unwrap(), label);
            same(num(def, "ToleranceValue"), json_vec(&t["limits_mm"])[1], label);
        }
    }
}

#[test]
fn qif_results_of_the_nist_example_validate_and_match_the_json() {
    let dir = tempfile::tempdir().unwrap();
    let (example, part) = copy_example(dir.path());
    // The example as it is (one circle, no tolerance), then with a diameter tolerance.
    let prog = dir.path().join("tol.dms");
    let text = std::fs::read_to_string(&example).unwrap();
    std::fs::write(
        &prog,
        text.replace("OUTPUT/FA(A_CIRCLE)", "T(D)=TOL/DIAM,-0.1,0.1\nOUTPUT/FA(A_CIRCLE),TA(D)"),
    )
    .unwrap();
    for (p, n_tol) in [(&example, 0), (&prog, 1)] {
        let q = dir.path().join("out.qif");
        let out = truepos()
            .current_dir(dir.path())
            .args(["dmis", "run"])
            .arg(p)
            .arg("--part")
            .arg(&part)
            .args(["--sensor", "PROBE6=Probe1", "--json", "--qif"])
            .arg(&q)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{stderr}");
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let xml = std::fs::read_to_string(&q).unwrap();
        if let Some(ok) = xmllint_qif(&q) {
            assert!(ok, "the QIF document does not validate:\n{xml}");
        }
        assert_eq!(check_qif_against_json(&xml, &j, &[]), n_tol);
        assert!(xml.contains("<FeatureName>A_CIRCLE</FeatureName>"), "{xml}");
    }
}

/// The richer program (datums, constructions, every tolerance kind, coordinate systems; one
/// tolerance out): every feature and tolerance of the JSON is in the QIF with its values,
/// the datums of POS and PERP form their frames; the document validates.
#[test]
fn qif_results_of_a_program_with_every_tolerance_kind() {
    let dir = tempfile::tempdir().unwrap();
    let programs = repo().join("crates/dmis/tests/programs");
    let prog = dir.path().join("full.dms");
    let part = dir.path().join("full_part.toml");
    std::fs::copy(programs.join("full.dms"), &prog).unwrap();
    std::fs::copy(programs.join("full_part.toml"), &part).unwrap();
    let q = dir.path().join("full.qif");
    let out = truepos()
        .current_dir(dir.path())
        .args(["dmis", "run"])
        .arg(&prog)
        .arg("--part")
        .arg(&part)
        .args(["--sensor", "P1=Probe1", "--json", "--qif"])
        .arg(&q)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    // T(TIGHT) is out: exit 1, both files written.
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let xml = std::fs::read_to_string(&q).unwrap();
    if let Some(ok) = xmllint_qif(&q) {
        assert!(ok, "the QIF document does not validate:\n{xml}");
    }
    let abc: &[&str] = &["A", "B", "C"];
    let n = check_qif_against_json(&xml, &j, &[("POS2", abc), ("PIN", abc), ("PE", &["A"])]);
    assert_eq!(n, 11, "every TA of the program");
    for kind in [
        "Flatness",
        "Diameter",
        "Cylindricity",
        "Perpendicularity",
        "Circularity",
        "Position",
        "DistanceBetween",
        "AngleBetween",
    ] {
        assert!(xml.contains(&format!("<{kind}CharacteristicDefinition ")), "{kind}");
    }
    assert!(xml.contains("<PointFeatureMeasurement ") && xml.contains("<LineFeatureMeasurement "));
}

/// `--qif` refusals: with `--dry-run`, onto the results file, in a missing directory (exit 2,
/// nothing moved, no file); a program that fails on the machine (exit 3) writes no QIF either.
#[test]
fn qif_refusals_leave_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let (prog, part) = copy_example(dir.path());
    let run = |prog: &Path, extra: &[&str]| {
        truepos()
            .current_dir(dir.path())
            .args(["dmis", "run"])
            .arg(prog)
            .args(["--part"])
            .arg(&part)
            .args(["--sensor", "PROBE6=Probe1"])
            .args(extra)
            .output()
            .unwrap()
    };
    let q = dir.path().join("r.qif");
    let qs = q.to_str().unwrap();
    for extra in [
        vec!["--dry-run", "--qif", qs],
        vec!["--output", qs, "--qif", qs],
        vec!["--qif", "no/such/dir/r.qif"],
    ] {
        let o = run(&prog, &extra);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(!stderr.contains("MEAS/"), "nothing moved: {stderr}");
        assert!(!q.exists() && !dir.path().join("simple_in_output.dms").exists(), "{extra:?}");
    }
    let lost = dir.path().join("lost.dms");
    std::fs::write(
        &lost,
        std::fs::read_to_string(&prog).unwrap().replace("PTMEAS/CART, 75.0", "PTMEAS/CART, 60.0"),
    )
    .unwrap();
    let o = run(&lost, &["--qif", qs]);
    assert_eq!(o.status.code(), Some(3), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!q.exists());
}
