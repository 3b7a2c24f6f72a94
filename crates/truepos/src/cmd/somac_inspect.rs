//! `truepos somac inspect`: the in-spindle probe inspection mode of end-point control. After the
//! holes of a program are made, the same controller probes each one with the spindle probe
//! (single points on the bore wall at a depth, least-squares circle) and reports every hole's
//! position error and diameter. The holes come from the program's measurement blocks
//! (`--program`) or from a hole list (`--holes`); the procedure is
//! `truepos_somac::inspect::inspect`, through the same `--controller` URLs as `probe sphere`.

// Argument docs here are clap's help text, where `[name]` is a TOML table (or an optional CSV
// column), not an intra-doc link: escaping it would change the help the contract names.
#![allow(rustdoc::broken_intra_doc_links)]

use crate::{ClassExt, Outcome, UsageError};
use anyhow::Result;
use std::path::PathBuf;
use truepos_math::Point3;
use truepos_plant::probing::{MachineToolConfig, VirtualMachineTool};
use truepos_somac::inspect::{inspect, read_hole_list, read_program_holes, Hole, InspectPlan, InspectReport};

#[derive(clap::Args, Debug)]
#[command(
    after_help = "A hole is the nominal centre of its top (machine frame, mm): the target of each program block\nwith the measurement keyword comment (--program), or a row of --holes (id,x_mm,y_mm,z_mm and an\noptional diameter_mm column). Each hole is probed at --depth-mm below its top with --points\nsingle-point probings on the bore wall (G38.2 on LinuxCNC, PtMeas on I++ DME), each starting\n--clearance-mm inside the nominal wall; the machine travels between holes at --safe-height-mm\nabove the highest top. The machine must be on, homed and idle (truepos never releases an\ne-stop). Reported per hole: measured centre, position error (X, Y and its length),\ntrue position (twice the length), diameter and its error, roundness, time.\nExit 3 naming the hole, the address and the move when the controller fails or a probe move\nends without contact (the machine is sent up to the safe height); exit 1 when --tolerance-mm is\ngiven and a hole's position error exceeds it.\n\nWith --controller virtual the holes are bored in a plate on the virtual machine tool, each off\nits nominal by a seeded error (σ = 20 µm per axis, 5 µm on the diameter); the JSON then has\nthe truth per hole (virtual_truth)."
)]
pub struct InspectArgs {
    /// `virtual` (the built-in virtual machine tool), `linuxcncrsh://HOST:PORT[?password=…]`,
    /// `ippdme://HOST:PORT`.
    #[arg(long, default_value = "virtual")]
    pub controller: String,
    /// The program whose holes to inspect (its measurement blocks' targets).
    #[arg(long, conflicts_with = "holes", required_unless_present = "holes")]
    pub program: Option<PathBuf>,
    /// A hole list: CSV id,x_mm,y_mm,z_mm[,diameter_mm] (hole top centres).
    #[arg(long)]
    pub holes: Option<PathBuf>,
    /// Nominal hole diameter (mm); required unless the hole list has a diameter_mm column.
    #[arg(long, value_parser = crate::output::positive)]
    pub diameter_mm: Option<f64>,
    /// The measurement keyword comment that marks the program's hole blocks.
    #[arg(long, default_value = "(MSG,Measure SOMaC)")]
    pub keyword: String,
    /// Probing depth below each hole's top (mm).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 3.0)]
    pub depth_mm: f64,
    /// Points per hole (4 to 10000), at equal angles.
    #[arg(long, default_value_t = 8)]
    pub points: usize,
    /// Probing feed (mm/min, at most 5000: faster, a touch probe cannot stop within its overtravel).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 50.0)]
    pub feed_mm_min: f64,
    /// Distance from the nominal wall where each probing move starts and beyond which it gives
    /// up (mm): the hole positions must be known to better than this.
    #[arg(long, value_parser = crate::output::positive, default_value_t = 0.5)]
    pub clearance_mm: f64,
    /// Stylus ball diameter (mm).
    #[arg(long, value_parser = crate::output::non_negative, default_value_t = 0.0)]
    pub tip_diameter_mm: f64,
    /// Travel height above the highest hole top (mm).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 5.0)]
    pub safe_height_mm: f64,
    /// Position tolerance (mm, length of the XY error): exit 1 when a hole exceeds it.
    #[arg(long, value_parser = crate::output::positive)]
    pub tolerance_mm: Option<f64>,
    /// Seed of the virtual machine (where its holes really are).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Audit trail: a SQLite file (created if missing) or postgresql://USER@HOST:PORT/DB; the
    /// inspection is recorded as a run (note `somac inspect`) with one record per hole.
    #[arg(long, default_value = "somac-audit.sqlite")]
    pub db: String,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub model: super::probe::ModelArgs,
}

fn read_holes(a: &InspectArgs) -> Result<Vec<Hole>> {
    Ok(match (&a.program, &a.holes) {
        (Some(path), _) => {
            let d = a.diameter_mm.ok_or_else(|| UsageError("--program needs --diameter-mm".into()))?;
            read_program_holes(path, &a.keyword, d)?
        }
        (None, Some(path)) => read_hole_list(path, a.diameter_mm)?,
        (None, None) => return Err(UsageError("give --program or --holes".into()).into()),
    })
}

pub fn run(a: InspectArgs) -> Result<Outcome> {
    let holes = read_holes(&a)?;
    let plan = InspectPlan {
        depth_mm: a.depth_mm,
        points: a.points,
        feed_mm_s: a.feed_mm_min / 60.0,
        clearance_mm: a.clearance_mm,
        tip_radius_mm: 0.5 * a.tip_diameter_mm,
        safe_height_mm: a.safe_height_mm,
        start_angle_deg: 0.0,
    };
    if let Some(t) = a.tolerance_mm {
        if !(t.is_finite() && t > 0.0) {
            return Err(UsageError(format!("--tolerance-mm must be > 0, got {t}")).into());
        }
    }
    // Check everything before touching a machine.
    plan.check(&holes)?;
    let model = a.model.read()?;
    let db = super::audit::parse_db(&a.db)?;
    let source = a.program.as_ref().or(a.holes.as_ref()).map(|p| p.display().to_string()).unwrap_or_default();
    let mut audit =
        truepos_audit::Audit::open_noted(&db, &source, Some("somac inspect"), &truepos_audit::now_utc())?;
    let r = inspect_and_record(&a, &holes, &plan, model.as_ref(), &mut audit);
    let (status, message) = match &r {
        Ok(rep) if !rep.out_of_tolerance().is_empty() => ("FAILURE", None),
        Ok(_) => ("SUCCESS", None),
        Err(e) => ("ERROR", Some(format!("{e:#}"))),
    };
    audit.finish(status, message.as_deref(), &truepos_audit::now_utc())?;
    let report = r?;
    crate::output::emit(&report, a.json)?;
    eprintln!("audit trail appended to {} (run {})", db.display(), audit.run_id());
    let over = report.out_of_tolerance();
    Ok(if over.is_empty() { Outcome::Done } else { Outcome::OutOfTolerance })
}

/// Open the machine, inspect, and record the device and every hole in the audit trail.
fn inspect_and_record(
    a: &InspectArgs,
    holes: &[Hole],
    plan: &InspectPlan,
    model: Option<&truepos_vcmm::MachineModel>,
    audit: &mut truepos_audit::Audit,
) -> Result<InspectReport> {
    let mut truth = None;
    let mut machine: Box<dyn truepos_device::ProbingMachine> = if a.controller == "virtual" {
        let nominal: Vec<(Point3, f64)> = holes.iter().map(|h| (h.nominal_mm, h.diameter_mm)).collect();
        let (cfg, t) = MachineToolConfig::with_holes(a.seed, &nominal, plan.tip_radius_mm)
            .map_err(|e| UsageError(format!("virtual machine: {e}")))?; // a String, not an error
        truth = Some(t);
        Box::new(VirtualMachineTool::new(cfg).usage_in("virtual machine")?)
    } else {
        super::probe::open_probing_machine(&a.controller, None, a.seed)?.machine
    };
    let mut r = inspect(machine.as_mut(), holes, plan)?;
    let uncertainty = match model {
        Some(m) => {
            let u = truepos_vcmm::inspection_uncertainty(m, plan, &r, a.model.monte_carlo())?;
            for (h, u) in r.holes.iter_mut().zip(&u) {
                h.center_uncertainty_mm = u.center_xy_mm;
                h.diameter_uncertainty_mm = u.diameter_mm;
            }
            ("task-specific".to_string(), a.model.monte_carlo_runs, m.basis())
        }
        None => {
            eprintln!("{}", super::probe::NO_MODEL_WARNING);
            (
                "fit-residuals".to_string(),
                0,
                "scatter of each hole's circle fit only (machine errors not included)".to_string(),
            )
        }
    };
    audit.set_controller(&r.device.address, &r.device.version)?;
    for h in &r.holes {
        audit.record_inspection(h);
    }
    audit.flush()?;
    Ok(InspectReport {
        inspection: r,
        tolerance_mm: a.tolerance_mm,
        truth: truth.map(|t| t.iter().map(|t| (t.top_mm, t.diameter_mm)).collect()),
        uncertainty,
    })
}
