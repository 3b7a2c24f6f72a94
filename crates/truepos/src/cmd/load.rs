//! `truepos load`: bed deformation under workpiece load — influence maps from the plate FE model
//! (or imported), load cases by statics, superposition, and correction of measured points; plus
//! the `load` scenario of `truepos simulate` and the demo section.
//!
//! Files (contract): `bed.toml` (`[bed]`, `[portal]`, `[grid]`), `load.toml` (`mass_kg` or
//! `weight_n`, `cog_mm`, `rest_points_mm` or `[[rest]] x_mm, y_mm, force_n`), the influence map
//! CSV (`load_x_mm,load_y_mm,portal_y_mm,pitch_urad,roll_urad`, `# unit_load_n = …`).
//! Physics and the sign of pitch/roll: `truepos_comp::load`.

// Argument docs here are clap's help text, where `[name]` is a TOML table (or an optional CSV
// column), not an intra-doc link: escaping it would change the help the contract names.
#![allow(rustdoc::broken_intra_doc_links)]

use crate::output::{emit, parse_triple, progress};
use crate::Outcome;
use anyhow::Result;
use std::path::PathBuf;
use truepos_comp::{task, Chain};
use truepos_io::num::NumFormat;
use truepos_math::Vector3;

const SIGN_HELP: &str = "\
Pitch and roll are the portal's physical rotations (µrad, right-hand rule) about +X and +Y, as an
outside FE package reports them: a measured point p at portal position y is corrected to p + e,
e = (pitch, roll, 0) × (p − o), o = ((x1 + x2)/2, y, rail_height_mm) (the tilted portal carries
the tip by e). From the bed deflection: pitch_urad = 1e6·(uz_front − uz_back)/bearing_span
(front = +Y bearing, mean of both rails), roll_urad = 1e6·(uz_rail1 − uz_rail2)/(x2 − x1) (uz
positive up; mean of the two bearings on each rail). A load ahead of the portal tips it forward:
negative pitch. Imported maps are used as they come. The portal's common vertical sink is not
part of the model.

Load case: mass_kg (× 9.80665) or weight_n, cog_mm, rest_points_mm: forces by statics (exact
for three points; the minimum-norm balanced distribution for more). A distribution that needs
tension (centre of gravity outside the support polygon) or that cannot balance (fewer than
three points not carrying the CoG) is an input error. Explicit [[rest]] forces are used as given;
they must not be negative, and if weight or cog_mm are also given they must agree (0.1 %, 1 mm).
Resting points outside the map's load grid, or measured points outside its portal-Y range, are
input errors (the map does not cover the part).";

#[derive(clap::Args, Debug)]
#[command(long_about = SIGN_HELP, after_help = "Pitch is about +X, roll about +Y: the portal's physical rotations (right-hand rule), so that\np + (pitch, roll, 0) × (p − o) corrects a measured point (a load ahead of the portal: negative pitch).\nDetails, statics and coverage rules: truepos load correct --help")]
pub struct Args {
    #[command(subcommand)]
    pub command: Sub,
}

#[derive(clap::Subcommand, Debug)]
pub enum Sub {
    /// Influence map from the plate FE model: pitch/roll per unit load against portal Y.
    #[command(long_about = SIGN_HELP)]
    Map(MapCmd),
    /// Correct measured points for the load case (adds dx_um,dy_um,dz_um).
    #[command(long_about = SIGN_HELP)]
    Correct(CorrectCmd),
    /// Pitch and roll curves of the load case, and the forces on the resting points.
    #[command(long_about = SIGN_HELP)]
    Curves(CurvesCmd),
    /// Bed deflection uz (mm, positive up) of the load case at given x_mm,y_mm points.
    Deflection(DeflectionCmd),
}

#[derive(clap::Args, Debug)]
pub struct MapCmd {
    /// Bed model (TOML: [bed], [portal], [grid]).
    #[arg(long)]
    pub bed: PathBuf,
    /// Output influence map CSV.
    #[arg(long)]
    pub output: PathBuf,
    /// FE element size (mm); default: [bed] element_size_mm, else automatic.
    #[arg(long, value_parser = crate::output::positive)]
    pub element_size_mm: Option<f64>,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct CorrectCmd {
    /// Influence map CSV (from `truepos load map` or an outside FE package).
    #[arg(long)]
    pub map: PathBuf,
    /// Load case TOML.
    #[arg(long)]
    pub load: PathBuf,
    /// Bed TOML ([portal] gives the rails and their height).
    #[arg(long)]
    pub bed: PathBuf,
    /// Measured points (x_mm,y_mm,z_mm; other columns passed through): CSV, or Parquet
    /// (`.parquet`) or E57 (`.e57`) by the extension.
    #[arg(long)]
    pub points: PathBuf,
    /// Output: the points corrected, with dx_um,dy_um,dz_um (the correction applied) added;
    /// Parquet for a `.parquet` path, else CSV. Streamed in constant memory. In a Parquet
    /// output, a Parquet input keeps its column types and a CSV input's other columns are
    /// numbers where every value in the file is a number, else text (text for a CSV read from
    /// a pipe).
    #[arg(long)]
    pub output: PathBuf,
    /// Also apply a 21-parameter geometric map (combined correction p + E(p) + e(p)).
    #[arg(long)]
    pub geometric_map: Option<PathBuf>,
    /// Squareness for --geometric-map (TOML or CSV).
    #[arg(long, requires = "geometric_map")]
    pub squareness: Option<PathBuf>,
    /// Probe offset for --geometric-map (ram frame, mm).
    #[arg(long, value_parser = parse_triple, default_value = "0,0,0")]
    pub probe_offset_mm: [f64; 3],
    /// Write numbers with this many decimals (default: as many as the input's coordinates carry,
    /// at least 6 (1 nm), e.g. 7 for 379.1898195; the shortest round-trip text when they carry
    /// more than 9 or an exponent, and for Parquet or E57 input).
    #[arg(long)]
    pub decimals: Option<u8>,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct CurvesCmd {
    /// Influence map CSV (written by `truepos load map`).
    #[arg(long)]
    pub map: PathBuf,
    /// Load case TOML: mass_kg or weight_n, cog_mm, rest_points_mm (or [[rest]] with forces).
    #[arg(long)]
    pub load: PathBuf,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct DeflectionCmd {
    /// Bed model TOML: [bed] size, thickness, material, supports.
    #[arg(long)]
    pub bed: PathBuf,
    /// Load case TOML: mass_kg or weight_n, cog_mm, rest_points_mm (or [[rest]] with forces).
    #[arg(long)]
    pub load: PathBuf,
    /// Points (x_mm,y_mm).
    #[arg(long)]
    pub at: PathBuf,
    /// FE element size (mm); default: [bed] element_size_mm, else automatic.
    #[arg(long, value_parser = crate::output::positive)]
    pub element_size_mm: Option<f64>,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// Mass of the die (kg).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 2000.0)]
    pub mass_kg: f64,
    /// Probing noise, standard deviation per axis (µm).
    #[arg(long, value_parser = crate::output::non_negative, default_value_t = 0.3)]
    pub noise_um: f64,
}

// ---------------------------------------------------------------------------------------------
// Commands: `truepos_comp::task`

pub fn run(a: Args) -> Result<Outcome> {
    match a.command {
        Sub::Map(a) => {
            let pb = progress(0, "influence map");
            let r = task::influence_map(&a.bed, &a.output, a.element_size_mm, &|k, n| {
                pb.set_length(n as u64);
                pb.set_position(k as u64)
            });
            pb.finish_and_clear();
            emit(&r?, a.json)?
        }
        Sub::Correct(a) => {
            let geometric = match &a.geometric_map {
                Some(m) => Some(map_files(m, &a.squareness).read()?),
                None => None,
            };
            let fmt = match a.decimals {
                Some(_) => NumFormat::from_decimals(a.decimals).map_err(crate::UsageError)?,
                None => truepos_io::csv::input_precision(&a.points, &["x_mm", "y_mm", "z_mm"]),
            };
            let r = task::load_correct(
                &a.map,
                &a.load,
                &a.bed,
                geometric.as_ref(),
                Vector3::from(a.probe_offset_mm),
                &a.points,
                &a.output,
                fmt,
            )?;
            if a.json {
                if let Some(n) = r.dropped_note() {
                    eprintln!("{n}");
                }
            }
            emit(&r, a.json)?
        }
        Sub::Curves(a) => emit(&task::curves(&a.map, &a.load)?, a.json)?,
        Sub::Deflection(a) => emit(&task::deflection(&a.bed, &a.load, &a.at, a.element_size_mm)?, a.json)?,
    }
    Ok(Outcome::Done)
}

/// The geometric map of `load correct --geometric-map` (bridge chain, no clamping).
fn map_files(map: &std::path::Path, squareness: &Option<PathBuf>) -> task::MapFiles {
    task::MapFiles {
        map: map.to_path_buf(),
        squareness: squareness.clone(),
        chain: Chain::BridgeYXZ,
        clamp: false,
    }
}

// ---------------------------------------------------------------------------------------------
// Simulation and demo

pub fn simulate(a: SimArgs) -> Result<Outcome> {
    let (out, seed) = (a.common.out_dir()?, a.common.seed);
    let (_, data) = truepos_cell::scenarios::load::write_scenario(out, seed, a.mass_kg, a.noise_um)?;
    eprint!("{}", truepos_cell::scenarios::load::written_text(out, a.mass_kg, a.noise_um, &data));
    Ok(Outcome::Done)
}
