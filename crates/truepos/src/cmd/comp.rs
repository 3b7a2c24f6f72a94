//! `truepos comp`: the 21-parameter geometric error map (ISO 230-1): volumetric error at points,
//! correction of measured points and compensation of commanded positions.
//!
//! Map file: CSV `axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad`, rows
//! of one axis in any order (sorted here; a repeated position is an error). Squareness:
//! `--squareness FILE`, TOML `[squareness] xy_urad, xz_urad, yz_urad` or CSV with those columns
//! and one row. Optional standard-uncertainty columns `u_*` beside the values (map and
//! squareness) are propagated to `u_x_um,u_y_um,u_z_um` of the corrected points. Component
//! definitions, rotation axes and the propagation: `truepos_comp::geometric` and the `--help`
//! text below.

use crate::output::{emit, parse_triple};
use crate::Outcome;
use anyhow::Result;
use std::path::PathBuf;
use truepos_comp::stream::Mode;
use truepos_comp::{task, Chain};
use truepos_io::num::NumFormat;
use truepos_math::Vector3;

pub const COMPONENTS_HELP: &str = "\
Map components (errors of motion, actual − nominal; µm and µrad in files):
  axis  pos_um  str1_um  str2_um  roll_urad  pitch_urad  yaw_urad
  x     δx      δy       δz       about X    about Y     about Z
  y     δy      δz       δx       about Y    about X     about Z
  z     δz      δx       δy       about Z    about X     about Y
Rotations are right-handed about the machine axes. Squareness (µrad, positive = the angle
between the positive axes is smaller than 90°): xy adds (0, xy·x, 0), xz adds (xz·z, 0, 0),
yz adds (0, yz·z, 0).
First-order volumetric error, bridge CMM (bed → Y → X → Z → tool, the default):
  E = δY + εY × (x_vec + z_vec + t) + δX + εX × (z_vec + t) + δZ + εZ × t + squareness
  (gantry, bed → X → Y → Z: X and Y swap roles), t = --probe-offset-mm (ram frame),
  x_vec = (x,0,0), z_vec = (0,0,z) the axis positions.
Points are indicated tip coordinates (axis positions + t); the tables are read at the axis
positions a = p − t. A measured point p is corrected to p + E(p − t); with --commanded the file
holds target tip positions T and the output the tip positions c to command, c + E(c − t) = T
(fixed-point iteration, converged below 1 nm; non-convergence is reported).
Tables are interpolated linearly; positions outside a table are an error unless --clamp.
Uncertainty: the map may carry the standard uncertainty (k = 1) of each value beside it,
columns u_pos_um,u_str1_um,u_str2_um,u_pitch_urad,u_yaw_urad,u_roll_urad (all six or none),
and the squareness u_xy_urad,u_xz_urad,u_yz_urad (same TOML table or CSV). With both, the
output gains u_x_um,u_y_um,u_z_um (k = 1) per point: first-order propagation through E above
(components independent; the Abbe lever arms and the probe offset included; a node's u
interpolated linearly; plus the linear interpolation's own error, f(1 − f)/2 × the table's
second difference less its noise, zero at the nodes), and the JSON gives uncertainty_method
\"map-propagation\", coverage_factor 2 and the largest and median expanded U per coordinate.
Without them the output is unchanged and the map's uncertainty is said unknown (stderr, JSON
uncertainty_method \"unknown\").";

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Map columns axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad. Rotation axes:\nX: roll about X, pitch about Y, yaw about Z; Y: roll about Y, pitch about X, yaw about Z;\nZ: roll about Z, pitch about X, yaw about Y. Details: truepos comp correct --help"
)]
#[command(long_about = COMPONENTS_HELP)]
pub struct Args {
    #[command(subcommand)]
    pub command: Sub,
}

#[derive(clap::Subcommand, Debug)]
pub enum Sub {
    /// Correct measured points (or compensate targets with --commanded); adds dx_um,dy_um,dz_um
    /// (and u_x_um,u_y_um,u_z_um when the map states its uncertainty).
    #[command(long_about = COMPONENTS_HELP)]
    Correct(CorrectArgs),
    /// Volumetric error E(p − t; t) at the tip points of a file (JSON error_um per point, or --output CSV).
    #[command(long_about = COMPONENTS_HELP)]
    Error(ErrorArgs),
}

/// Options that describe the map.
#[derive(clap::Args, Debug, Clone)]
pub struct MapArgs {
    /// Geometric error map (CSV: axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad,
    /// optionally u_pos_um,u_str1_um,u_str2_um,u_pitch_urad,u_yaw_urad,u_roll_urad: standard uncertainties).
    #[arg(long)]
    pub map: PathBuf,
    /// Squareness: TOML `[squareness] xy_urad, xz_urad, yz_urad` (optionally u_xy_urad, u_xz_urad,
    /// u_yz_urad), or CSV with those columns (one row).
    #[arg(long)]
    pub squareness: Option<PathBuf>,
    /// Probe/tool offset in the ram frame, mm.
    #[arg(long, value_parser = parse_triple, default_value = "0,0,0")]
    pub probe_offset_mm: [f64; 3],
    /// Kinematic chain.
    #[arg(long, value_enum, default_value_t = Chain::BridgeYXZ)]
    pub chain: Chain,
    /// Hold the end values outside a table's range instead of refusing such points.
    #[arg(long)]
    pub clamp: bool,
}

#[derive(clap::Args, Debug)]
pub struct CorrectArgs {
    #[command(flatten)]
    pub map: MapArgs,
    /// Points (x_mm,y_mm,z_mm and any other columns, passed through): CSV, or Parquet
    /// (`.parquet`) or E57 (`.e57`) by the extension.
    #[arg(long)]
    pub points: PathBuf,
    /// Output: the input with corrected x_mm,y_mm,z_mm and dx_um,dy_um,dz_um added (and
    /// u_x_um,u_y_um,u_z_um, k = 1, when the map and squareness carry u-columns); Parquet
    /// for a `.parquet` path, else CSV. Streamed in constant memory. In a Parquet output,
    /// a Parquet input keeps its column types and a CSV input's other columns are numbers
    /// where every value in the file is a number, else text (text for a CSV read from a pipe).
    #[arg(long)]
    pub output: PathBuf,
    /// The points are targets: write commanded positions c with c + E(c) = T.
    #[arg(long)]
    pub commanded: bool,
    /// Write numbers with this many decimals (default: as many as the input's coordinates carry,
    /// at least 6 (1 nm), e.g. 7 for 379.1898195; the shortest round-trip text when they carry
    /// more than 9 or an exponent, and for Parquet or E57 input).
    #[arg(long)]
    pub decimals: Option<u8>,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct ErrorArgs {
    #[command(flatten)]
    pub map: MapArgs,
    /// Points (x_mm,y_mm,z_mm).
    #[arg(long)]
    pub at: PathBuf,
    /// Write x_mm,y_mm,z_mm,ex_um,ey_um,ez_um instead of printing: Parquet for a `.parquet`
    /// path, else CSV.
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

impl MapArgs {
    /// The map files and options of the command line.
    pub fn files(&self) -> task::MapFiles {
        task::MapFiles {
            map: self.map.clone(),
            squareness: self.squareness.clone(),
            chain: self.chain,
            clamp: self.clamp,
        }
    }

    fn probe_offset(&self) -> Vector3 {
        Vector3::from(self.probe_offset_mm)
    }
}

pub fn run(a: Args) -> Result<Outcome> {
    match a.command {
        Sub::Correct(a) => {
            let map = a.map.files().read()?;
            let fmt = match a.decimals {
                Some(_) => NumFormat::from_decimals(a.decimals).map_err(crate::UsageError)?,
                None => truepos_io::csv::input_precision(&a.points, &["x_mm", "y_mm", "z_mm"]),
            };
            let mode = if a.commanded { Mode::Commanded } else { Mode::Measured };
            let done = task::correct(&map, a.map.probe_offset(), &a.points, &a.output, mode, fmt)?;
            if a.json {
                // Said on stderr with --json too (the text, which carries it, is not printed then).
                if let Some(w) = done.uncertainty_warning() {
                    eprintln!("{w}");
                }
                if let Some(n) = done.dropped_note() {
                    eprintln!("{n}");
                }
            }
            emit(&done, a.json)?
        }
        Sub::Error(a) => {
            let map = a.map.files().read()?;
            emit(&task::errors_at(&map, a.map.probe_offset(), &a.at, a.output.as_deref())?, a.json)?
        }
    }
    Ok(Outcome::Done)
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Writes map.csv (axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad and\ntheir standard uncertainties u_*: the x, y and z tables of a virtual bridge CMM as a simulated\ncalibration with known noise delivers them, every 5 mm), squareness.toml (with u_*), points.csv\n(indicated probe-tip points, id,x_mm,y_mm,z_mm) and truth.json (true_points_mm, probe offset),\nand prints the `truepos comp correct` command that corrects the points (with u_x_um,u_y_um,u_z_um)."
)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
}

/// `truepos simulate comp`: the geometric-map data set with its truth.
pub fn simulate(a: SimArgs) -> Result<Outcome> {
    let w = truepos_cell::scenarios::part::write_comp_dataset(a.common.out_dir()?, a.common.seed)?;
    eprint!("{}", w.text(&a.common.out));
    Ok(Outcome::Done)
}
