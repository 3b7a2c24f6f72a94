//! `truepos head-offset`: the measuring head's 3D offset R from a reference object (sphere,
//! pyramid apex, cuboid corner) measured in several head (B) and table (C) orientations, and
//! `truepos head-offset apply`, which turns raw head data into points in machine coordinates.
//!
//! Entry points: [`run`] (the calibration and the `apply` subcommand), [`simulate`] (`truepos
//! simulate head-offset`: the virtual cell's data set and its truth); the demo section is the
//! cell's head scenario's `demo_section`. The
//! numerics are in `truepos-head`; this module reads and writes the contract's files.

// Argument docs here are clap's help text, where `[name]` is a TOML table (or an optional CSV
// column), not an intra-doc link: escaping it would change the help the contract names.
#![allow(rustdoc::broken_intra_doc_links)]

use crate::output::{emit, parse_pair, parse_triple};
use crate::{ClassExt, Outcome, UsageError};
use anyhow::{Context, Result};
use std::path::PathBuf;
use truepos_cell::scenarios::head::Variant;
use truepos_head::file::read_input;
use truepos_head::task::{calibrate_file, Calibration};
use truepos_head::Reference;
use truepos_math::{Point3, Vector3};

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefKind {
    /// A sphere: its centre (least-squares, all orientations together).
    Sphere,
    /// A pyramid apex or cuboid corner: the common point of the fitted face planes (`face` column).
    Vertex,
}

const AFTER_HELP: &str =
    "Input columns: b_deg,c_deg,x_mm,y_mm,z_mm (x,y,z: the NC's head reference point P), optional
dist_mm (laser reading), face (vertex references), group (orientation id).
Model: Q = P + Ry(b)·R; a laser surface point is Q + dist·Ry(b)·u, u = unit(tan α, tan β, −1);
a table point at A for c = 0 is at O + Rz(c)·(A − O), O = --table-center-mm. Head swivel alone
determines R in the XZ plane (Y is not observable), the table alone X and Y (Z is not
observable); a mix of both determines all three. What the data cannot determine is held at
--prior-offset-mm, reported as not observable, with no uncertainty.";

#[derive(clap::Args, Debug)]
#[command(args_conflicts_with_subcommands = true, after_help = AFTER_HELP)]
pub struct Args {
    #[command(subcommand)]
    pub action: Option<Action>,
    #[command(flatten)]
    pub calibrate: CalibrateArgs,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Turn raw head data into measured points in machine coordinates with a known offset.
    Apply(ApplyArgs),
    /// Probe the reference sphere through a controller at several head (B) / table (C)
    /// orientations and write the points file (then `truepos head-offset --points FILE`).
    Acquire(AcquireArgs),
}

#[derive(clap::Args, Debug)]
#[command(after_help = "\
At each orientation (B swivels the head about Y, C turns the table about the axis through\n\
--table-center-mm parallel to Z) the sphere is probed over its upper hemisphere as `truepos probe\n\
sphere` does, around where it appears to the NC: O + Rz(c)·(S − O) − Ry(b)·R with S = --near and\n\
R = --nominal-offset-mm, both of which must be known to better than --clearance-mm. The head turns\n\
at a height clear of the sphere at every orientation. The output has one row per latched point:\n\
b_deg,c_deg,x_mm,y_mm,z_mm (the NC's head reference point P) and group (orientation index).\n\n\
Orientations need the axes: a machine without B or C (the LinuxCNC test machine is XYZ) is\n\
refused before it moves (exit 3, naming the address and the missing axes). One orientation\n\
(--orientation 0,0) can be acquired anywhere, but determines no head offset: head-offset then says\n\
so. --controller virtual is a machine tool with B and C whose sphere and head offset are off the\n\
nominal ones by seeded errors (σ 0.1 mm and 0.2 mm per axis); the JSON has that truth.\n\n\
With two orientations or more the head offset is computed from the points as `truepos head-offset\n\
--points` does (components the orientations do not determine are reported as not observable).\n\
Its uncertainty: with --machine-model FILE task-specific (the same acquisition simulated on ≥ 200\n\
machines drawn from the model, on a machine tool with its 1 ms servo latch; JSON\n\
uncertainty_method \"task-specific\"), else the fit's scatter alone (a warning says so).")]
pub struct AcquireArgs {
    #[command(flatten)]
    pub sphere: super::probe::SphereTarget,
    /// One orientation B,C (degrees); repeat for each, in the order to measure.
    #[arg(long = "orientation", value_parser = parse_pair, allow_hyphen_values = true, required = true)]
    pub orientations: Vec<[f64; 2]>,
    /// The head offset R as far as it is known (X,Y,Z mm, head frame at B = 0).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, default_value = "0,0,0")]
    pub nominal_offset_mm: [f64; 3],
    /// A point of the table's C axis (X,Y,Z mm); needed when C varies.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub table_center_mm: Option<[f64; 3]>,
    /// Points per orientation (≥ 5).
    #[arg(long, default_value_t = 12)]
    pub points: usize,
    /// Probing feed (mm/min).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 50.0)]
    pub feed_mm_min: f64,
    /// The points file to write (atomically).
    #[arg(long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub model: super::probe::ModelArgs,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct CalibrateArgs {
    /// Readings of the reference object (columns b_deg,c_deg,x_mm,y_mm,z_mm[,dist_mm,face,group]).
    #[arg(long)]
    pub points: Option<PathBuf>,
    /// The reference object: a sphere (its centre) or a vertex (the common point of fitted face planes).
    #[arg(long, value_enum, default_value_t = RefKind::Sphere)]
    pub reference: RefKind,
    /// Sphere diameter (mm): fixes the radius (plus --tip-radius-mm for a touch probe).
    #[arg(long, value_parser = crate::output::positive)]
    pub sphere_diameter_mm: Option<f64>,
    /// Touch-probe tip radius (mm): the stylus centre runs on the sphere of radius sphere + tip, or
    /// on the faces moved out by it.
    #[arg(long, value_parser = crate::output::non_negative, default_value_t = 0.0)]
    pub tip_radius_mm: f64,
    /// A point of the rotary table's axis (parallel to Z), X,Y,Z in mm. Needed when C varies.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub table_center_mm: Option<[f64; 3]>,
    /// Laser beam tilt α,β (degrees): u = unit(tan α, tan β, −1).
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true, default_value = "0,0")]
    pub tilt_deg: [f64; 2],
    /// Value held for offset components the data cannot determine (X,Y,Z mm).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true, default_value = "0,0,0")]
    pub prior_offset_mm: [f64; 3],
    /// Laser head whose beam passes through the head reference point (R parallel to the beam):
    /// components no rotation reaches follow from --tilt-deg and the measured components.
    #[arg(long)]
    pub beam_through_reference: bool,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
#[command(after_help = "\
x_mm,y_mm,z_mm of the output are the measured points (Q = P + Ry(b)·R, or the laser surface point\n\
Q + dist·Ry(b)·u when a dist_mm column is present); all other columns pass through unchanged.")]
pub struct ApplyArgs {
    /// The head offset R (X,Y,Z mm, head frame at b = 0).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub offset_mm: [f64; 3],
    /// Raw readings (columns b_deg,x_mm,y_mm,z_mm; optional dist_mm, c_deg; others pass through).
    #[arg(long)]
    pub points: PathBuf,
    /// Output CSV (written atomically).
    #[arg(long)]
    pub output: PathBuf,
    /// Laser beam tilt α,β (degrees).
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true, default_value = "0,0")]
    pub tilt_deg: [f64; 2],
    /// Express the points on the table at c = 0 (undo the table rotation; needs c_deg and
    /// --table-center-mm) instead of in machine coordinates.
    #[arg(long)]
    pub table_frame: bool,
    /// A point of the rotary table's axis (with --table-frame).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub table_center_mm: Option<[f64; 3]>,
}

#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// Which head and reference object, and which B/C orientations are measured.
    #[arg(long, value_enum, default_value_t = Variant::Both)]
    pub variant: Variant,
}

fn tilt_rad(t: [f64; 2], name: &str) -> Result<[f64; 2], UsageError> {
    if t.iter().any(|a| a.abs() >= 80.0) {
        return Err(UsageError(format!("{name} {},{}: tilt angles must be below 80°", t[0], t[1])));
    }
    Ok([t[0].to_radians(), t[1].to_radians()])
}

pub fn run(args: Args) -> Result<Outcome> {
    match args.action {
        Some(Action::Apply(a)) => return apply(a),
        Some(Action::Acquire(a)) => return acquire(a),
        None => {}
    }
    let a = args.calibrate;
    let Some(points) = a.points.clone() else {
        return Err(UsageError(
            "--points FILE is required (readings with columns b_deg,c_deg,x_mm,y_mm,z_mm); see --help".into(),
        )
        .into());
    };
    if let Some(d) = a.sphere_diameter_mm {
        if !(d.is_finite() && d > 0.0) {
            return Err(UsageError(format!("--sphere-diameter-mm {d}: must be positive")).into());
        }
        if a.reference == RefKind::Vertex {
            return Err(UsageError("--sphere-diameter-mm applies to --reference sphere only".into()).into());
        }
    }
    if !(a.tip_radius_mm.is_finite() && a.tip_radius_mm >= 0.0) {
        return Err(UsageError(format!("--tip-radius-mm {}: must be ≥ 0", a.tip_radius_mm)).into());
    }
    let reference = match a.reference {
        RefKind::Sphere => {
            Reference::Sphere { radius: a.sphere_diameter_mm.map(|d| 0.5 * d + a.tip_radius_mm) }
        }
        RefKind::Vertex => Reference::Vertex { tip_radius: a.tip_radius_mm },
    };
    let c = Calibration {
        reference,
        table_center_mm: a.table_center_mm.map(Point3::from),
        tilt: tilt_rad(a.tilt_deg, "--tilt-deg")?,
        prior_offset_mm: Vector3::from(a.prior_offset_mm),
        beam_through_reference: a.beam_through_reference,
        tip_radius_mm: a.tip_radius_mm,
        sphere_diameter_mm: a.sphere_diameter_mm,
    };
    let r = calibrate_file(&points, &c)?;
    for note in r.notes() {
        eprintln!("{note}");
    }
    emit(&r, a.json)?;
    Ok(Outcome::Done)
}

fn apply(a: ApplyArgs) -> Result<Outcome> {
    tilt_rad(a.tilt_deg, "--tilt-deg")?;
    let offset = Vector3::from(a.offset_mm);
    let table_center = match (a.table_frame, a.table_center_mm) {
        (true, None) => return Err(UsageError("--table-frame needs --table-center-mm X,Y,Z".into()).into()),
        (true, t) => t.map(Point3::from),
        (false, _) => None,
    };
    let input = read_input(&a.points, a.table_frame)?;
    truepos_head::file::write_applied(&a.output, &input, &offset, a.tilt_deg, table_center)
        .with_context(|| format!("writing {}", a.output.display()))?;
    eprintln!("wrote {} points to {}", input.readings.len(), a.output.display());
    Ok(Outcome::Done)
}

fn acquire(a: AcquireArgs) -> Result<Outcome> {
    use truepos_head::acquire::{acquire_to_file, HeadAcquisition};
    use truepos_plant::probing::{MachineToolConfig, VirtualMachineTool};
    let c_varies = a.orientations.iter().any(|o| o[1] != 0.0);
    let table_center = match a.table_center_mm {
        Some(t) => Point3::from(t),
        None if c_varies => {
            return Err(UsageError(
                "orientations with C ≠ 0 need --table-center-mm X,Y,Z (a point of the C axis)".into(),
            )
            .into())
        }
        None => Point3::origin(),
    };
    let acq = HeadAcquisition {
        sphere: a.sphere.plan(a.points, a.feed_mm_min),
        orientations: a.orientations.clone(),
        nominal_offset_mm: Vector3::from(a.nominal_offset_mm),
        table_center_mm: table_center,
    };
    acq.check()?;
    let model = a.model.read()?;
    let mut truth = None;
    let mut machine: Box<dyn truepos_device::ProbingMachine> = if a.sphere.controller == "virtual" {
        let (cfg, t) = MachineToolConfig::for_head_offset(a.sphere.seed, &acq);
        truth = Some(t);
        Box::new(VirtualMachineTool::new(cfg).usage_in("virtual machine")?)
    } else {
        super::probe::open_probing_machine(&a.sphere.controller, None, a.sphere.seed)?.machine
    };
    let next = format!(
        "truepos head-offset --points {}{} --tip-radius-mm {}",
        a.output.display(),
        a.table_center_mm
            .map(|t| format!(" --table-center-mm {},{},{}", t[0], t[1], t[2]))
            .unwrap_or_default(),
        acq.sphere.tip_radius_mm
    );
    let mut report = acquire_to_file(machine.as_mut(), &acq, &a.output, next)?;
    report.truth = truth.map(|t| (t.offset_mm, t.sphere_centre_mm, t.sphere_radius_mm));
    let machine_kind = if a.sphere.controller.starts_with("ippdme://") {
        truepos_vcmm::AcquiringMachine::Cmm
    } else {
        truepos_vcmm::AcquiringMachine::MachineTool
    };
    let offset = acquired_offset(&report, &acq, model.as_ref(), machine_kind, &a.model)?;
    if a.json {
        let mut j = truepos_io::report::Report::to_json(&report);
        j["head_offset"] = offset.json;
        j["uncertainty_method"] = serde_json::json!(offset.method);
        j["monte_carlo_runs"] = serde_json::json!(offset.runs);
        crate::output::print_json(&j)?;
    } else {
        eprint!("{}{}", truepos_io::report::Report::text(&report), offset.text);
    }
    Ok(Outcome::Done)
}

/// The head offset of an acquisition with its uncertainty, as JSON and text.
struct AcquiredOffset {
    json: serde_json::Value,
    text: String,
    method: &'static str,
    runs: usize,
}

/// Compute the head offset from the acquired points as `truepos head-offset --points` does, and
/// its uncertainty: task-specific with a machine model, the fit's scatter without (warning).
fn acquired_offset(
    report: &truepos_head::acquire::AcquireReport,
    acq: &truepos_head::acquire::HeadAcquisition,
    model: Option<&truepos_vcmm::MachineModel>,
    machine: truepos_vcmm::AcquiringMachine,
    args: &super::probe::ModelArgs,
) -> Result<AcquiredOffset> {
    use serde_json::json;
    let none = |why: String| AcquiredOffset {
        json: json!({ "offset_mm": null, "note": why }),
        text: String::new(),
        method: "none",
        runs: 0,
    };
    if report.acquired.len() < 2 {
        return Ok(none("one orientation determines no head offset".into()));
    }
    let params = truepos_head::Params {
        reference: truepos_head::Reference::Sphere { radius: None },
        table_center: acq.table_center_mm,
        ..truepos_head::Params::default()
    };
    let r = match truepos_head::solve(&truepos_head::acquire::readings(&report.acquired), &params) {
        Ok(r) => r,
        Err(e) => return Ok(none(format!("the points determine no head offset: {e}"))),
    };
    let task = match model {
        Some(m) => {
            Some(truepos_vcmm::head_offset_uncertainty(m, acq, &params, &r, machine, args.monte_carlo())?)
        }
        None => {
            eprintln!("{}", super::probe::NO_MODEL_WARNING);
            None
        }
    };
    let u: [Option<f64>; 3] = match &task {
        Some(t) => t.offset_mm,
        None => r.u_offset,
    };
    let k = truepos_math::stats::COVERAGE_FACTOR;
    let opt = |v: Option<f64>, s: f64| v.map_or(serde_json::Value::Null, |v| json!(v * s));
    let (method, runs, basis) = match &task {
        Some(t) => ("task-specific", t.spread.runs, t.spread.basis.clone()),
        None => {
            ("fit-residuals", 0, "scatter of the fit's residuals only (machine errors not included)".into())
        }
    };
    let mut j = json!({
        "offset_mm": [r.offset.x, r.offset.y, r.offset.z],
        "observable": r.observable,
        "uncertainty_mm": [opt(u[0], 1.0), opt(u[1], 1.0), opt(u[2], 1.0)],
        "coverage_factor": k,
        "expanded_uncertainty_mm": [opt(u[0], k), opt(u[1], k), opt(u[2], k)],
        "reference_point_mm": [r.reference_point.x, r.reference_point.y, r.reference_point.z],
        "uncertainty_method": method,
        "monte_carlo_runs": runs,
        "uncertainty_basis": basis,
    });
    if let Some(t) = &task {
        j["monte_carlo_s"] = json!(t.spread.elapsed_s);
    }
    let mut text = String::from("head offset (as head-offset --points computes it):\n");
    for (i, axis) in ["X", "Y", "Z"].iter().enumerate() {
        text += &match (r.observable[i], u[i]) {
            (true, Some(v)) => {
                format!("  {axis} {:+.4} mm (U = {:.2} µm, k = {k})\n", r.offset[i], k * v * 1e3)
            }
            (true, None) => format!("  {axis} {:+.4} mm\n", r.offset[i]),
            (false, _) => {
                format!("  {axis} not observable from these orientations (held at {})\n", r.offset[i])
            }
        };
    }
    text += &match &task {
        Some(t) => format!(
            "  uncertainty: task-specific, {} machine realisations in {:.2} s ({})\n",
            t.spread.runs, t.spread.elapsed_s, t.spread.basis
        ),
        None => "  uncertainty: fit residuals only (machine errors not included)\n".into(),
    };
    Ok(AcquiredOffset { json: j, text, method, runs })
}

pub fn simulate(args: SimArgs) -> Result<Outcome> {
    let d = truepos_cell::scenarios::head::simulate(args.variant, args.common.seed)?;
    // Where the data set cannot be written is the user's choice of --out: an input error.
    let w = truepos_cell::scenarios::head::write_dataset(args.common.out_dir()?, &d)
        .map_err(|e| truepos_io::InputError::in_file(&args.common.out, format!("{e:#}")))?;
    eprint!("{}", w.text(d.rows.len()));
    Ok(Outcome::Done)
}
