//! Demo sections for the real-machine interfaces, run against the virtual plant: the I++ DME
//! server (the virtual CMM on a loopback port, probed through truepos's own I++ DME client,
//! exactly what `truepos probe sphere --controller ippdme://HOST:PORT` does) and the controller
//! trait (the virtual machine tool behind `ProbingMachine`, what `--controller virtual` runs and
//! what `--controller linuxcncrsh://HOST:PORT` runs on LinuxCNC).
//!
//! Entry points: [`ippdme_section`], [`controller_section`].

use crate::error::{CellError, Context, Result};
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};
use truepos_head::acquire::{probe_sphere, ProbedSphere, SphereProbing};
use truepos_ippdme::{MachineConfig, Part, Server};
use truepos_math::{Point3, Vector3};
use truepos_plant::cmm::IppdmeCmm;
use truepos_plant::probing::{MachineToolConfig, VirtualMachineTool};
use truepos_report::{self as report, Report, Verdict};

/// The reference sphere of both sections (machine frame, mm).
const CENTRE: [f64; 3] = [100.0, 50.0, 20.0];
const DIAMETER_MM: f64 = 25.0;

/// Prepare the CMM as an operator would before a client program runs: a session that homes
/// the machine and puts `Probe1` in the spindle (both persist across sessions).
fn prepare(addr: std::net::SocketAddr) -> Result<()> {
    let s = TcpStream::connect(addr).context(format!("connecting to the I++ DME server at {addr}"))?;
    s.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut w = s.try_clone()?;
    w.write_all(
        b"00001 StartSession()\r\n00002 Home()\r\n00003 ChangeTool(\"Probe1\")\r\n00004 EndSession()\r\n",
    )?;
    let mut r = BufReader::new(s);
    let mut line = String::new();
    loop {
        line.clear();
        if r.read_line(&mut line)? == 0 {
            return Err(CellError::Failed(
                "the I++ DME server closed the connection while preparing the machine".into(),
            ));
        }
        let l = line.trim_end();
        if l.contains(" ! ") {
            return Err(CellError::Failed(format!("the I++ DME server refused the preparation: {l}")));
        }
        if l.starts_with("00004") && l[5..].trim() == "%" {
            return Ok(());
        }
    }
}

/// A length in the unit `(name, per mm)` with `dec` decimals and a sign; never "-0.00".
fn signed(v_mm: f64, unit: (&str, f64), dec: usize) -> String {
    let t = format!("{:+.*}", dec, v_mm * unit.1);
    if t[1..].chars().all(|c| c == '0' || c == '.') {
        t[1..].to_string()
    } else {
        t
    }
}

/// Rows of the result table (truth, result, U with k = 2, error) with the errors in `unit`
/// (µm, or nm where the errors are a few nm), and the centre and radius errors (mm).
fn rows(s: &ProbedSphere, centre: Point3, radius: f64, unit: (&str, f64)) -> (Vec<Vec<String>>, f64, f64) {
    let ce = (s.center_mm - centre).norm();
    let re = s.radius_mm - radius;
    let p = |v: &Point3| format!("({:.4}, {:.4}, {:.4})", v.x, v.y, v.z);
    let rows = vec![
        vec![
            "centre (mm)".into(),
            p(&centre),
            p(&s.center_mm),
            format!("{:.2}", 2.0 * s.center_uncertainty_mm.norm() * unit.1),
            format!("{:.2} (3D distance)", ce * unit.1),
        ],
        vec![
            "radius (mm)".into(),
            format!("{:.4}", radius),
            format!("{:.4}", s.radius_mm),
            format!("{:.2}", 2.0 * s.radius_uncertainty_mm * unit.1),
            signed(re, unit, 2),
        ],
    ];
    (rows, ce, re)
}

/// The worst of the centre coordinates and the radius by |error|/U: (error, U), mm, k = 2.
fn worst_component(s: &ProbedSphere, centre: Point3, radius: f64) -> (f64, f64) {
    let k = truepos_math::stats::COVERAGE_FACTOR;
    let e = s.center_mm - centre;
    let mut items: Vec<(f64, f64)> = (0..3).map(|i| (e[i], k * s.center_uncertainty_mm[i])).collect();
    items.push((s.radius_mm - radius, k * s.radius_uncertainty_mm));
    items
        .into_iter()
        .max_by(|a, b| (a.0.abs() / a.1.max(1e-300)).total_cmp(&(b.0.abs() / b.1.max(1e-300))))
        .unwrap_or((f64::NAN, f64::NAN))
}

/// The words of a task-specific sphere uncertainty (k = 2, µm), simulated on `what`.
fn task_u_text(tsu: &truepos_vcmm::SphereUncertainty, what: &str) -> String {
    format!(
        "U = {:.2}, {:.2}, {:.2} µm on the centre coordinates, {:.2} µm on the radius (k = 2; task-specific, ISO/TS 15530-4: the same probing simulated on {} {what})",
        2e3 * tsu.center_mm.x,
        2e3 * tsu.center_mm.y,
        2e3 * tsu.center_mm.z,
        2e3 * tsu.radius_mm,
        tsu.runs
    )
}

/// The verdict fields of the worst component ([`worst_component`], mm) against `tol_um`.
fn worst_verdict((error, u): (f64, f64), tol_um: f64) -> Verdict {
    Verdict::judged(report::Judgement::new(error * 1e3, u * 1e3, tol_um, "µm", report::DecisionRule::Simple))
}

/// The result table in `unit`.
fn result_table(rows: &[Vec<String>], unit: &str) -> String {
    let (u, e) = (format!("U, k = 2 ({unit})"), format!("error ({unit})"));
    report::table(&["quantity", "truth", "measured", &u, &e], rows)
}

const UM: (&str, f64) = ("µm", 1e3);

/// Demo: the virtual CMM as an I++ DME server on 127.0.0.1 (an ephemeral port), a sphere probed
/// through the I++ DME client with the same procedure as `truepos probe sphere`, against the
/// part's true sphere.
pub fn ippdme_section(report: &mut Report) -> Result<()> {
    let config = MachineConfig::default();
    let part_toml = format!(
        "[[sphere]]\nid = \"ref\"\ncenter_mm = [{}, {}, {}]\ndiameter_mm = {DIAMETER_MM}\n\n[[plane]]\nid = \"table\"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n",
        CENTRE[0], CENTRE[1], CENTRE[2]
    );
    let part = Part::from_toml("demo-part.toml", &part_toml).context("the demo's I++ DME part")?;
    let server = Server::bind("127.0.0.1:0", IppdmeCmm::new(&config, Some(part)), &config, None)
        .context("starting the I++ DME server on 127.0.0.1")?
        .spawn()
        .context("starting the I++ DME server thread")?;
    let addr = server.addr;
    prepare(addr)?;
    let url = format!("ippdme://{addr}");
    // The server takes the next session once it has seen the preparing client go.
    let t0 = Instant::now();
    let mut client = loop {
        match truepos_ippdme::connect(&url) {
            Ok(c) => break c,
            Err(e)
                if e.to_string().contains("refused the session")
                    && t0.elapsed() < Duration::from_secs(10) =>
            {
                std::thread::sleep(Duration::from_millis(20))
            }
            Err(e) => return Err(e).context("connecting the I++ DME client"),
        }
    };
    let centre = Point3::new(CENTRE[0], CENTRE[1], CENTRE[2]);
    let radius = 0.5 * DIAMETER_MM;
    let plan = SphereProbing {
        // The nominal centre as a drawing would give it: a few tenths off the real sphere.
        near_mm: centre + Vector3::new(0.3, -0.2, 0.2),
        diameter_mm: DIAMETER_MM,
        points: 25,
        feed_mm_s: 50.0 / 60.0,
        clearance_mm: 2.0,
        tip_radius_mm: 1.5,
    };
    let mut s = probe_sphere(&mut client, &plan).context("probing the sphere through I++ DME")?;
    let version = s.device.version.clone();
    drop(client);
    server.shutdown();
    // Task-specific uncertainty: the server's error-model class (its seed unknown to the user).
    let model = truepos_vcmm::MachineModel {
        source: "the virtual CMM's default [ippdme.model]".into(),
        cmm: Some(MachineConfig::default()),
        iso10360: None,
        machine_tool: truepos_vcmm::MachineToolLatch::default(),
    };
    let tsu = truepos_vcmm::sphere_uncertainty(
        &model,
        &plan,
        s.center_mm,
        s.radius_mm,
        s.center_uncertainty_mm,
        s.radius_uncertainty_mm,
        truepos_vcmm::MonteCarlo::default(),
    )?;
    s.center_uncertainty_mm = tsu.center_mm;
    s.radius_uncertainty_mm = tsu.radius_mm;
    let (rows, ce, re) = rows(&s, centre, radius, UM);
    let judgement = worst_component(&s, centre, radius);
    // The virtual CMM is the realistic default ([ippdme.model]: a bridge CMM's geometric errors
    // of a few µm, compensated pre-travel with 0.5 µm lobing, 0.25 µm touch noise): a 25-point
    // sphere agrees with truth within the MPE class of such a machine, 5 µm.
    let tol_um = 5.0;
    report.verdict(Verdict {
        section: "ippdme".into(),
        capability: "I++ DME client and server".into(),
        measured: format!(
            "a Ø {DIAMETER_MM} mm sphere probed with {} PtMeas through truepos's I++ DME client",
            s.points.len()
        ),
        truth: "the sphere of the virtual CMM's part file".into(),
        result: format!("centre error {:.3} µm, radius error {} µm", ce * 1e3, signed(re, UM, 3)),
        uncertainty: task_u_text(&tsu, &format!("machines drawn from the server's error model, in {:.2} s", tsu.elapsed_s)),
        tolerance_text: format!(
            "each centre coordinate and the radius within {tol_um} µm (the virtual CMM's default error models: geometric errors, pre-travel lobing, touch noise); judged on the worst of the four"
        ),
        ..worst_verdict(judgement, tol_um)
    });
    let _ = (ce, re);
    let html = format!(
        "<p>The virtual CMM runs as an I++ DME server ({version}) on 127.0.0.1 with its default error models (a bridge CMM's geometric errors, a touch-trigger probe's compensated pre-travel with lobing, touch noise), on an ephemeral port, inside the demo, with a part file holding a Ø {DIAMETER_MM} mm sphere at ({}, {}, {}) mm on a table plane. A client session homes the machine and loads <code>Probe1</code> (Ø 3 mm ball), as an operator would; then truepos's I++ DME client connects and runs the sphere procedure of <code>truepos probe sphere</code>: up to the safe height, {} points over the upper hemisphere with <code>PtMeas</code>, each from the nominal centre given {:.2} mm off the real one. The fitted tip-centre sphere minus the ball radius is compared with the part's sphere. The same run against any I++ DME server: <code>truepos ippdme serve --part part.toml</code> in one terminal, <code>truepos probe sphere --controller ippdme://127.0.0.1:1294 --near=100.3,49.8,20.2 --diameter-mm 25 --tip-diameter-mm 3 --json</code> in another.</p>{}",
        CENTRE[0],
        CENTRE[1],
        CENTRE[2],
        s.points.len(),
        (plan.near_mm - centre).norm(),
        result_table(&rows, UM.0),
    );
    report.add("ippdme", "I++ DME: the virtual CMM through the protocol", html);
    Ok(())
}

/// Demo: the sphere procedure on the virtual machine tool through the controller trait
/// (`ProbingMachine`), against its true sphere; LinuxCNC is the same procedure through the same
/// trait and is not started by the demo.
pub fn controller_section(report: &mut Report) -> Result<()> {
    let centre = Point3::new(CENTRE[0], CENTRE[1], CENTRE[2]);
    let tip = 1.5;
    let cfg = MachineToolConfig::near(1, centre, 0.5 * DIAMETER_MM, tip);
    let (true_centre, true_radius) = cfg.spheres[0];
    let mut m = VirtualMachineTool::new(cfg).context("virtual machine tool")?;
    let plan = SphereProbing {
        near_mm: centre,
        diameter_mm: DIAMETER_MM,
        points: 25,
        feed_mm_s: 50.0 / 60.0,
        clearance_mm: 2.0,
        tip_radius_mm: tip,
    };
    let mut s = probe_sphere(&mut m, &plan).context("probing the sphere on the virtual machine tool")?;
    // Task-specific uncertainty: the machine tool's model (servo latch, pre-travel, noise) with
    // the perfect sphere where it was found, on seeded realisations.
    let (c, r) = (s.center_mm, s.radius_mm);
    let make = |seed: u64| {
        let cfg =
            MachineToolConfig { spheres: vec![(c, r)], ..MachineToolConfig::near(seed, centre, r, tip) };
        VirtualMachineTool::new(cfg).expect("the demo's machine tool configuration is valid")
    };
    let tsu = truepos_vcmm::sphere_uncertainty_on(
        make,
        "the virtual machine tool's model (1 ms servo latch, 0.5 µm pre-travel, 0.1 µm noise)",
        &plan,
        c,
        r,
        s.center_uncertainty_mm,
        s.radius_uncertainty_mm,
        truepos_vcmm::MonteCarlo::default(),
    )?;
    s.center_uncertainty_mm = tsu.center_mm;
    s.radius_uncertainty_mm = tsu.radius_mm;
    let (rows, ce, re) = rows(&s, true_centre, true_radius, UM);
    let judgement = worst_component(&s, true_centre, true_radius);
    // At 50 mm/min the 1 ms servo latch puts each point up to 0.83 µm inside, plus 0.5 µm
    // pre-travel and 0.1 µm noise: the radius reads low by about 0.9 µm and the centre is within
    // about one servo step; 1.5 µm bounds both.
    let tol_um = 1.5;
    report.verdict(Verdict {
        section: "controller".into(),
        capability: "Machine-tool controller (probing trait)".into(),
        measured: format!(
            "a Ø {DIAMETER_MM} mm sphere probed with {} G38.2-style moves on the virtual machine tool",
            s.points.len()
        ),
        truth: "the virtual machine's true sphere (set up 0.1 mm σ off nominal)".into(),
        result: format!("centre error {:.2} µm, radius error {} µm", ce * 1e3, signed(re, UM, 2)),
        uncertainty: task_u_text(&tsu, &format!("realisations of {}", tsu.basis)),
        tolerance_text: format!(
            "each centre coordinate and the radius within {tol_um} µm (1 ms servo latch at 50 mm/min, 0.5 µm pre-travel); judged on the worst of the four"
        ),
        ..worst_verdict(judgement, tol_um)
    });
    let html = format!(
        "<p>The sphere procedure of <code>truepos probe sphere</code> on the virtual machine tool through the controller trait (<code>ProbingMachine</code>: position, moves, single-point probing), what <code>--controller virtual</code> runs: a touch probe with 0.5 µm pre-travel, 0.1 µm noise and a 1 ms servo latch, {} points at 50 mm/min over the upper hemisphere of a Ø {DIAMETER_MM} mm sphere set up near its nominal centre. A LinuxCNC run is what <code>truepos probe sphere --controller linuxcncrsh://HOST:PORT --near=X,Y,Z --diameter-mm 25</code> does: the same procedure through the same trait, with G38.2 moves sent over linuxcncrsh and the latched point read back from <code>#5061..#5063</code>, on a machine that is on, homed and idle. The demo does not start LinuxCNC (the LinuxCNC integration tests do, in <code>crates/linuxcnc</code>).</p>{}",
        s.points.len(),
        result_table(&rows, UM.0),
    );
    report.add("controller", "Machine-tool controller: probing through the trait", html);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_never_writes_minus_zero() {
        assert_eq!(signed(-1e-9, UM, 2), "0.00");
        assert_eq!(signed(-0.0012, UM, 2), "-1.20");
        assert_eq!(signed(0.0012, ("nm", 1e6), 1), "+1200.0");
    }

    /// Both sections run (the I++ DME server on a loopback port, the virtual machine tool) and
    /// pass against their truth; the report states that LinuxCNC is not started.
    #[test]
    fn interface_sections_pass_against_truth() {
        let d = tempfile::tempdir().unwrap();
        let mut r = Report::new(d.path());
        ippdme_section(&mut r).unwrap();
        controller_section(&mut r).unwrap();
        let index = r.write().unwrap();
        let html = std::fs::read_to_string(index).unwrap();
        assert!(html.contains("id=\"ippdme\"") && html.contains("id=\"controller\""));
        assert!(html.contains("The demo does not start LinuxCNC"));
        let summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.path().join("summary.json")).unwrap()).unwrap();
        let caps = summary["capabilities"].as_array().unwrap();
        assert_eq!(caps.len(), 2);
        for c in caps {
            assert_eq!(c["verdict"], "pass", "{c}");
        }
        // No port number in the report: reruns stay byte-identical.
        assert_eq!(html.matches("127.0.0.1:").count(), html.matches("127.0.0.1:1294").count());
    }
}
