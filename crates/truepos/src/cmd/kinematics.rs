//! `truepos kinematics calibrate`: the rotary axes of a five-axis controller identified by
//! probing a reference sphere on its table at several orientations, and written back with
//! `--apply`. Parses the options, checks them (and the orientations' observability) before
//! opening the controller, opens it (the virtual xyzbc-trt machine, or LinuxCNC with its
//! kinematics module found through halcmd), calls `truepos_kinematics::calibrate`, prints.

use crate::output::{emit, parse_pair, parse_triple};
use crate::{ClassExt, Outcome, UsageError};
use anyhow::Result;
use std::path::PathBuf;
use truepos_device::ProbingMachine;
use truepos_head::acquire::SphereProbing;
use truepos_kinematics::acquire::KinematicsProbing;
use truepos_kinematics::task::default_verify_orientations;
use truepos_kinematics::{CalibrateRequest, Model};
use truepos_math::Point3;
use truepos_plant::probing::VirtualMachineTool;

#[derive(clap::Args, Debug)]
#[command(
    after_help = "On LinuxCNC (one line):\n  truepos kinematics calibrate --controller linuxcncrsh://127.0.0.1:5007 --model xyzbc-trt --near=60,25,15 --diameter-mm 25 --tip-diameter-mm 2 --orientation 0,0 --orientation 0,120 --orientation 0,240 --orientation 45,0 --orientation 90,120 --orientation 90,240 --apply --verify --json"
)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Identify the rotary axes' geometry from a sphere probed at several orientations; write
    /// it into the running controller with --apply.
    Calibrate(CalibrateArgs),
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "On LinuxCNC (one line):\n  truepos kinematics calibrate --controller linuxcncrsh://127.0.0.1:5007 --model xyzbc-trt --near=60,25,15 --diameter-mm 25 --tip-diameter-mm 2 --orientation 0,0 --orientation 0,120 --orientation 0,240 --orientation 45,0 --orientation 90,120 --orientation 90,240 --apply --verify --json

The sphere sits on the rotary table; --near is its nominal centre in the programme frame (the
table frame at B = C = 0), known to better than the clearance. The controller must run its
five-axis kinematics with tool-centre-point control (LinuxCNC: xyzbc-trt-kins, switchkins type
0), be on, homed and idle; truepos never releases an e-stop or switches a machine on.

At each orientation the sphere is probed over the cap that faces the tool, as `probe sphere`
does. Between orientations the probe goes out along the tool axis to --turn-distance-mm from the
sphere, over to the top, the axes turn there (the tip stays put in the table frame), and it
comes back along the new tool axis. The machine ends at B = C = 0 above the sphere.

Four numbers are observable: the C axis's X, Y (x-rot-point, y-rot-point) and the B axis's X, Z
(x-rot-point + x-offset, z-rot-point + z-offset); the Z change goes into z-offset. Orientations
that cannot determine one of them (no two C angles, no two B angles): exit 2 before any motion.

Without --apply nothing is written (dry run). --apply writes the identified values into the
running controller at B = C = 0 (LinuxCNC: halcmd setp on the controller's host, as the user
that runs LinuxCNC) and prints the INI/HAL lines that make it permanent. --verify then probes
again at other orientations and reports how well the centres agree.

Exit codes: 0 done; 2 bad options, orientations that cannot determine the geometry, or --model
maxkins (its forward and inverse kinematics disagree in LinuxCNC 2.9); 3 controller faults."
)]
pub struct CalibrateArgs {
    /// `virtual` (a built-in xyzbc-trt machine whose true geometry is tens of µm off its
    /// configured one) or `linuxcncrsh://HOST:PORT[?password=…]` on this host.
    #[arg(long, default_value = "virtual")]
    pub controller: String,
    /// The kinematics: `xyzbc-trt` (LinuxCNC's xyzbc-trt-kins: a B tilting table carrying a C
    /// rotary table). `maxkins` is refused.
    #[arg(long)]
    pub model: String,
    /// Nominal sphere centre X,Y,Z (mm, programme frame); negative values as `--near=-1,2,3`.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub near: [f64; 3],
    /// Nominal sphere diameter (mm).
    #[arg(long)]
    pub diameter_mm: f64,
    /// An orientation B,C (degrees, |B| ≤ 90); repeat for each. Negative values as
    /// `--orientation=-45,0`.
    #[arg(long = "orientation", value_parser = parse_pair, allow_hyphen_values = true, required = true)]
    pub orientations: Vec<[f64; 2]>,
    /// Points per orientation (≥ 5).
    #[arg(long, default_value_t = 9)]
    pub points: usize,
    /// Probing feed (mm/min).
    #[arg(long, default_value_t = 50.0)]
    pub feed_mm_min: f64,
    /// Distance from the nominal surface where each probing move starts and beyond which it
    /// gives up (mm).
    #[arg(long, default_value_t = 2.0)]
    pub clearance_mm: f64,
    /// Stylus ball diameter (mm).
    #[arg(long, default_value_t = 0.0)]
    pub tip_diameter_mm: f64,
    /// Distance from the sphere's centre at which the axes turn (mm).
    #[arg(long, default_value_t = 60.0)]
    pub turn_distance_mm: f64,
    /// Write the identified geometry into the running controller (at B = C = 0).
    #[arg(long)]
    pub apply: bool,
    /// After --apply, probe again at other orientations and report the centres' agreement.
    #[arg(long)]
    pub verify: bool,
    /// The verification orientations B,C (default: 0,0; 0,60; B/2,180; B,300; B/2,30 with B the
    /// largest calibration tilt).
    #[arg(long = "verify-orientation", value_parser = parse_pair, allow_hyphen_values = true)]
    pub verify_orientations: Vec<[f64; 2]>,
    /// Write the latched points (b_deg,c_deg,x_mm,y_mm,z_mm,group; programme frame) here.
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Seed of the virtual machine (its true geometry and where its sphere is).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub machine_model: super::probe::ModelArgs,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
    /// Record the calibration in an audit trail (SQLite FILE or postgresql://USER@HOST:PORT/DB):
    /// one run with the controller, each parameter's configured and identified value (before and
    /// after), and whether it was applied.
    #[arg(long, value_name = "FILE|URL")]
    pub db: Option<String>,
}

pub fn run(a: Args) -> Result<Outcome> {
    match a.what {
        What::Calibrate(c) => calibrate(c),
    }
}

fn calibrate(a: CalibrateArgs) -> Result<Outcome> {
    let model = Model::parse(&a.model)?;
    if !a.verify && !a.verify_orientations.is_empty() {
        return Err(UsageError("--verify-orientation needs --verify".into()).into());
    }
    let verify = a.verify.then(|| {
        if a.verify_orientations.is_empty() {
            default_verify_orientations(&a.orientations)
        } else {
            a.verify_orientations.clone()
        }
    });
    let req = CalibrateRequest {
        model,
        probing: KinematicsProbing {
            sphere: SphereProbing {
                near_mm: Point3::from(a.near),
                diameter_mm: a.diameter_mm,
                points: a.points,
                feed_mm_s: a.feed_mm_min / 60.0,
                clearance_mm: a.clearance_mm,
                tip_radius_mm: 0.5 * a.tip_diameter_mm,
            },
            orientations: a.orientations.clone(),
            turn_distance_mm: a.turn_distance_mm,
        },
        apply: a.apply,
        verify,
        output: a.output.clone(),
    };
    // Options and observability before a controller is opened (and anything moves).
    req.check()?;
    let db = a.db.as_deref().map(super::audit::parse_db).transpose()?;
    let error_model = a.machine_model.read()?;
    let (mut machine, truth): (Box<dyn ProbingMachine>, _) = if a.controller == "virtual" {
        let (m, t) = VirtualMachineTool::five_axis(
            a.seed,
            Point3::from(a.near),
            0.5 * a.diameter_mm,
            0.5 * a.tip_diameter_mm,
        )
        .usage_in("virtual machine")?;
        (Box::new(m), Some(t))
    } else if a.controller.starts_with(truepos_linuxcnc::url::SCHEME) {
        let address = truepos_linuxcnc::Address::parse(&a.controller)?;
        let options = truepos_linuxcnc::Options { joints: 5, ..truepos_linuxcnc::Options::default() };
        let mut m = truepos_linuxcnc::LinuxCnc::open_address(&address, options)?;
        m.attach_kinematics()?;
        (Box::new(m), None)
    } else {
        return Err(UsageError(format!(
            "--controller `{}`: expected `virtual` or `linuxcncrsh://HOST:PORT[?password=…]`",
            a.controller
        ))
        .into());
    };
    // Progress on stderr (stdout carries only the result).
    let mut report = truepos_kinematics::calibrate(machine.as_mut(), &req, |s| eprintln!("{s}"))?;
    match &error_model {
        Some(m) => {
            // Task-specific: the same calibration simulated on machines drawn from the model.
            let t = truepos_cell::uncertainty::kinematics_uncertainty(
                m,
                &req.probing,
                &report,
                a.machine_model.monte_carlo(),
            )?;
            for ((p, u), big_u) in report.parameters.iter_mut().zip(&t.u_mm).zip(&t.expanded_mm) {
                p.uncertainty_mm = *u;
                p.expanded_mm = Some(*big_u);
            }
            report.uncertainty = truepos_kinematics::UncertaintyBasis {
                method: "task-specific".into(),
                monte_carlo_runs: t.runs,
                basis: format!(
                    "{}; the calibration simulated on five-axis machines with the identified geometry, servo latch, pre-travel and noise; U = the 95 % interval of the simulated deviations ({:.2} s)",
                    t.basis, t.elapsed_s
                ),
            };
        }
        None => eprintln!("{}", super::probe::NO_MODEL_WARNING),
    }
    if let Some(t) = truth {
        report.truth = Some((t.truth, t.sphere_centre_mm));
    }
    match &db {
        Some(db) => record(db, &report)?,
        None if report.applied => eprintln!(
            "note: no --db: the change written into the controller is not recorded in an audit trail"
        ),
        None => {}
    }
    emit(&report, a.json)?;
    Ok(Outcome::Done)
}

/// The calibration as one audit-trail run: the controller, two `results` records per parameter
/// (`configured` = before, `identified` = after with its expanded uncertainty; the verdict says
/// whether it was written into the controller), and the outcome as the run's message.
fn record(db: &truepos_audit::Db, report: &truepos_kinematics::CalibrationReport) -> Result<()> {
    let now = truepos_audit::now_utc();
    let mut audit =
        truepos_audit::Audit::open_noted(db, "kinematics calibrate", Some("kinematics calibrate"), &now)?;
    audit.set_controller(&report.device.address, &report.device.version)?;
    let written = if report.applied { "written" } else { "dry run" };
    for p in &report.parameters {
        for (quantity, value, u, verdict) in [
            ("configured", p.configured_mm, None, None),
            ("identified", p.identified_mm, Some(p.expanded()), Some(written)),
        ] {
            audit.record_result(&truepos_audit::ResultRecord {
                line: None,
                kind: "parameter".into(),
                label: p.name.clone(),
                feature: Some(report.model.name().into()),
                quantity: quantity.into(),
                value,
                unit: "mm".into(),
                expanded_uncertainty: u,
                limits: None,
                verdict: verdict.map(str::to_string),
            });
        }
    }
    audit.flush()?;
    let message = format!(
        "{}; centre spread {:.4} mm before, {:.4} mm predicted after",
        if report.applied { "applied" } else { "dry run" },
        report.spread_before_mm,
        report.identification.spread_after_predicted_mm()
    );
    audit.finish("SUCCESS", Some(&message), &truepos_audit::now_utc())?;
    eprintln!("calibration recorded in {} (run {})", db.display(), audit.run_id());
    Ok(())
}
