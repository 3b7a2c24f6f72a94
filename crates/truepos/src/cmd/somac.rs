//! Laser-tracker end-point control commands: `truepos autoscale`, `orient`, `air`, and
//! `somac run` (the measure / compare / correct loop), `somac inspect` (in-spindle probe
//! inspection of the holes, `somac_inspect`).

use crate::output::{emit, print_json};
use crate::{Outcome, UsageError};
use anyhow::Result;
use serde_json::json;
use std::path::PathBuf;
use truepos_math::air::{self, AirConditions, Formula};
use truepos_somac::orient::orient_file;
use truepos_somac::scale::{autoscale_files, Expansion};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: SomacCommand,
}

#[derive(clap::Subcommand, Debug)]
pub enum SomacCommand {
    /// Run a program with the measure / compare / correct loop (virtual gantry and trackers).
    Run(super::somac_run::RunArgs),
    /// In-spindle probe inspection: probe the program's holes (or a hole list) on the same
    /// controller and report each hole's position error and diameter.
    Inspect(super::somac_inspect::InspectArgs),
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Both files: id,x_mm,y_mm,z_mm, matched by id. The scale is the best-fit ratio of measured to\nreference size after removing rotation and translation (similarity fit); two features are\nenough (their distance ratio). Coincident reference or measured features are refused (exit 2)."
)]
pub struct AutoscaleArgs {
    /// Feature positions at the reference temperature (20 °C), e.g. from the drawing.
    #[arg(long)]
    pub reference: PathBuf,
    /// The same features measured now.
    #[arg(long)]
    pub measured: PathBuf,
    /// Coefficient of thermal expansion of the part (ppm/°C), for the cross-check.
    #[arg(long, requires = "temperature_c")]
    pub cte_ppm_per_c: Option<f64>,
    /// Part temperature now (°C), for the cross-check.
    #[arg(long, requires = "cte_ppm_per_c")]
    pub temperature_c: Option<f64>,
    /// Reference temperature of the reference file (°C).
    #[arg(long, default_value_t = 20.0)]
    pub reference_temperature_c: f64,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "At least three targets (id,x_mm,y_mm,z_mm in both files). Only the coordinates that change are\nrewritten; comments, line numbers, other words and spacing are kept byte for byte."
)]
pub struct OrientArgs {
    /// Nominal target positions (the program's frame).
    #[arg(long)]
    pub reference: PathBuf,
    /// Current measured target positions (machine frame).
    #[arg(long)]
    pub measured: PathBuf,
    /// The G-code program to re-orient (its coordinates are in the reference frame).
    #[arg(long)]
    pub program: PathBuf,
    /// Output G-code: the program with its coordinates rewritten in the measured frame.
    #[arg(long)]
    pub output: PathBuf,
    /// Also fit a uniform scale (parts that grew or shrank).
    #[arg(long)]
    pub scale: bool,
    /// Decimals of rewritten coordinates (default 4 in mm programs, 5 in inch programs).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=9))]
    pub decimals: Option<u8>,
    /// Position before the program's first line, in the program's own (reference) coordinates
    /// (mm). Needed when the first motion gives only some axes (e.g. `G0 Z50.`).
    #[arg(long, value_name = "X,Y,Z", value_parser = crate::output::parse_triple, allow_hyphen_values = true)]
    pub start_mm: Option<[f64; 3]>,
    /// Replace arcs whose plane the transform tilts by G1 chords whose largest distance from the
    /// exact transformed arc is at most this (mm). Without it such arcs are refused.
    #[arg(long, value_parser = crate::output::positive, value_name = "MM")]
    pub arc_tolerance_mm: Option<f64>,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Equations as in NIST's Refractive Index of Air Calculator (Stone & Zimmerman). Inputs outside the\nrange where NIST states the equation valid are refused (exit 2): Ciddor 300-1700 nm, -40-100 °C,\n10000-140000 Pa, 0-100 % RH, 0-2000 ppm CO2; Edlén 300-1700 nm, 0-40 °C, 60000-140000 Pa,\n0-100 % RH, CO2 450 ppm only."
)]
pub struct AirArgs {
    /// Air temperature, °C.
    #[arg(long)]
    pub temperature_c: f64,
    /// Air pressure, Pa.
    #[arg(long, value_parser = crate::output::positive)]
    pub pressure_pa: f64,
    /// Relative humidity, %.
    #[arg(long, value_parser = crate::output::non_negative)]
    pub humidity_pct: f64,
    /// CO2 mole fraction (µmol/mol); the modified Edlén equation assumes 450.
    #[arg(long, value_parser = crate::output::non_negative, default_value_t = 450.0)]
    pub co2_ppm: f64,
    /// Vacuum wavelength.
    #[arg(long, value_parser = crate::output::positive, default_value_t = 633.0)]
    pub wavelength_nm: f64,
    /// Equation: ciddor (Ciddor 1996) or edlen (modified Edlén, Birch and Downs 1993/94).
    #[arg(long, value_enum, default_value_t = Formula::Ciddor)]
    pub formula: Formula,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

pub use super::somac_run::{simulate, SimArgs};

pub fn run(a: Args) -> Result<Outcome> {
    match a.command {
        SomacCommand::Run(r) => super::somac_run::run(r),
        SomacCommand::Inspect(i) => super::somac_inspect::run(i),
    }
}

pub fn autoscale(a: AutoscaleArgs) -> Result<Outcome> {
    let expansion = a.cte_ppm_per_c.zip(a.temperature_c).map(|(k, t)| Expansion {
        cte_ppm_per_c: k,
        temperature_c: t,
        reference_temperature_c: a.reference_temperature_c,
    });
    emit(&autoscale_files(&a.reference, &a.measured, expansion)?, a.json)?;
    Ok(Outcome::Done)
}

pub fn orient(a: OrientArgs) -> Result<Outcome> {
    let arc_policy = match a.arc_tolerance_mm {
        None => truepos_gcode::ArcPolicy::Refuse,
        Some(t) if t.is_finite() && t > 0.0 => truepos_gcode::ArcPolicy::Linearize { tolerance_mm: t },
        Some(t) => {
            return Err(UsageError(format!("--arc-tolerance-mm must be a positive number, got {t}")).into())
        }
    };
    let opts = truepos_gcode::TransformOptions { decimals: a.decimals, arc_policy, start_mm: a.start_mm };
    emit(&orient_file(&a.reference, &a.measured, &a.program, &a.output, a.scale, &opts)?, a.json)?;
    Ok(Outcome::Done)
}

pub fn air(a: AirArgs) -> Result<Outcome> {
    let c = AirConditions {
        temperature_c: a.temperature_c,
        pressure_pa: a.pressure_pa,
        humidity_pct: a.humidity_pct,
        co2_ppm: a.co2_ppm,
        wavelength_nm: a.wavelength_nm,
    };
    let f = a.formula;
    let n = air::refractive_index(&c, f)?;
    let name = match f {
        Formula::Ciddor => "ciddor",
        Formula::Edlen => "edlen",
    };
    if a.json {
        print_json(&json!({ "n": n, "formula": name, "n_minus_1_ppm": (n - 1.0) * 1e6 }))?;
    } else {
        println!("n = {n:.15}  ({name}; n − 1 = {:.4} ppm)", (n - 1.0) * 1e6);
    }
    Ok(Outcome::Done)
}
