//! `truepos head-offset`: the measuring head's 3D offset R from a reference object (sphere,
//! pyramid apex, cuboid corner) measured in several head (B) and table (C) orientations, and
//! `truepos head-offset apply`, which turns raw head data into points in machine coordinates.
//!
//! Entry points: [`run`] (the calibration and the `apply` subcommand), [`simulate`] (`truepos
//! simulate head-offset`: the virtual cell's data set and its truth), [`demo_section`]. The
//! numerics are in `truepos-head`; this module reads and writes the contract's files.

use crate::output::{parse_pair, parse_triple, print_json};
use crate::{Outcome, UsageError};
use anyhow::{Context, Result};
use std::path::PathBuf;
use truepos_cell::scenarios::head::Variant;
use truepos_head::file::{head_error, read_input};
use truepos_head::{solve, Params, Reference};
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefKind {
    /// A sphere: its centre (least-squares, all orientations together).
    Sphere,
    /// A pyramid apex or cuboid corner: the common point of the fitted face planes (`face` column).
    Vertex,
}

const AFTER_HELP: &str = "\
Examples:
  truepos head-offset --points points.csv --table-center-mm 500,250,0 --json
  truepos head-offset --points touch.csv --sphere-diameter-mm 25 --tip-radius-mm 1.5
  truepos head-offset --points laser.csv --tilt-deg 2,-1.5 --table-center-mm 500,250,0
  truepos head-offset apply --offset-mm 42.5,-18.3,-165.2 --points raw.csv --output machine.csv

Input columns: b_deg,c_deg,x_mm,y_mm,z_mm (x,y,z: the NC's head reference point P), optional
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
    #[arg(long)]
    pub sphere_diameter_mm: Option<f64>,
    /// Touch-probe tip radius (mm): the stylus centre runs on the sphere of radius sphere + tip, or
    /// on the faces moved out by it.
    #[arg(long, default_value_t = 0.0)]
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
#[command(
    after_help = "Example:\n  truepos head-offset apply --offset-mm 42.5,-18.3,-165.2 --points raw.csv --output machine.csv\n\n\
x_mm,y_mm,z_mm of the output are the measured points (Q = P + Ry(b)·R, or the laser surface point\n\
Q + dist·Ry(b)·u when a dist_mm column is present); all other columns pass through unchanged."
)]
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

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimVariant {
    /// Touch probe, sphere from B = 0°, 45°, 90° (Y not observable).
    Swivel,
    /// Touch probe, sphere at C = 0°, 90°, 180°, 270° (Z not observable).
    Table,
    /// Touch probe, B ∈ {0°, 90°} × C ∈ {0°, 120°, 240°}.
    Both,
    /// Laser head with beam tilt (2°, −1.5°).
    Laser,
    /// Touch probe on a 4-sided pyramid apex.
    Pyramid,
    /// Touch probe on a cuboid corner.
    Cuboid,
}

impl SimVariant {
    fn sim(self) -> Variant {
        match self {
            SimVariant::Swivel => Variant::Swivel,
            SimVariant::Table => Variant::Table,
            SimVariant::Both => Variant::Both,
            SimVariant::Laser => Variant::Laser,
            SimVariant::Pyramid => Variant::Pyramid,
            SimVariant::Cuboid => Variant::Cuboid,
        }
    }
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  truepos simulate head-offset --out data/head --seed 1 --variant both\n  truepos head-offset --points data/head/points.csv --table-center-mm 500,250,0 --json"
)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// Which head and reference object, and which B/C orientations are measured.
    #[arg(long, value_enum, default_value_t = SimVariant::Both)]
    pub variant: SimVariant,
}

fn tilt_rad(t: [f64; 2], name: &str) -> Result<[f64; 2], UsageError> {
    if t.iter().any(|a| a.abs() >= 80.0) {
        return Err(UsageError(format!("{name} {},{}: tilt angles must be below 80°", t[0], t[1])));
    }
    Ok([t[0].to_radians(), t[1].to_radians()])
}

pub fn run(args: Args) -> Result<Outcome> {
    if let Some(Action::Apply(a)) = args.action {
        return apply(a);
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
    let tilt = tilt_rad(a.tilt_deg, "--tilt-deg")?;
    let input = read_input(&points, true)?;
    if input.table.n_rows() == 0 {
        return Err(InputError::in_file(
            &points,
            "no readings: head-offset needs the reference measured in at least two orientations",
        )
        .into());
    }
    if a.beam_through_reference && input.table.column("dist_mm").is_none() {
        return Err(UsageError(
            "--beam-through-reference is for laser heads: the points file needs a dist_mm column".into(),
        )
        .into());
    }
    let table_turns = input.readings.iter().any(|r| r.c != input.readings[0].c);
    let table_center =
        match a.table_center_mm {
            Some(t) => Point3::from(t),
            None if table_turns => return Err(UsageError(
                "the readings have several table angles (c_deg): --table-center-mm X,Y,Z (a point of the C \
                 axis) is needed"
                    .into(),
            )
            .into()),
            None => Point3::origin(),
        };
    let reference = match a.reference {
        RefKind::Sphere => {
            Reference::Sphere { radius: a.sphere_diameter_mm.map(|d| 0.5 * d + a.tip_radius_mm) }
        }
        RefKind::Vertex => Reference::Vertex { tip_radius: a.tip_radius_mm },
    };
    let setup = Params {
        reference,
        table_center,
        tilt,
        prior: Vector3::from(a.prior_offset_mm),
        beam_through_reference: a.beam_through_reference,
    };
    let r = solve(&input.readings, &setup).map_err(|e| head_error(&input.table, e))?;
    for note in truepos_head::json::notes(&r, &setup.prior) {
        eprintln!("{note}");
    }
    if a.json {
        print_json(&truepos_head::json::result(&r, &setup, a.tip_radius_mm, a.sphere_diameter_mm, &input))?;
    } else {
        print!("{}", truepos_head::json::text(&r, a.tip_radius_mm));
    }
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

pub fn simulate(args: SimArgs) -> Result<Outcome> {
    let d = truepos_cell::scenarios::head::simulate(args.variant.sim(), args.common.seed)
        .map_err(|e| UsageError(e.to_string()))?;
    // Where the data set cannot be written is the user's choice of --out: an input error.
    let w = truepos_cell::scenarios::head::write_dataset(&args.common.out, &d)
        .map_err(|e| InputError::in_file(&args.common.out, format!("{e:#}")))?;
    eprint!("{}", w.text(d.rows.len()));
    Ok(Outcome::Done)
}
