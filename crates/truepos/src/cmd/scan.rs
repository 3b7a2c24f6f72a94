//! `truepos scan`: scanning path planning (`plan`) and execution on the virtual CMM (`run`)
//! without stops, with the classic style for comparison; `truepos simulate scan`; the demo
//! section.
//!
//! Files: the features TOML (`[[feature]]` tables and top-level parameters, each overridable by
//! the option of the same name with dashes), the path / point CSVs of the contract, an optional
//! machine TOML, and the scenario's `truth.json` (the true, displaced part) for `--part`.

// Argument docs here are clap's help text, where `[name]` is a TOML table (or an optional CSV
// column), not an intra-doc link: escaping it would change the help the contract names.
#![allow(rustdoc::broken_intra_doc_links)]

use crate::output::{parse_pair, print_json};
use crate::{Classed, Outcome, UsageError};
use anyhow::{Context, Result};
use std::path::PathBuf;
use truepos_io::InputError;
use truepos_math::exit::ExitClass;
use truepos_plant::scanning_cmm::{read_machine_file, run_scan, CmmConfig};
use truepos_scan::execute::ControlParams;
use truepos_scan::file::{read_features, ParamOverrides};
use truepos_scan::{plan, Feature, Params, ScanError, Style};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub action: Action,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Plan the path (no machine): writes t_s,x_mm,y_mm,z_mm,segment,feature,speed_mm_s.
    Plan(PlanArgs),
    /// Plan and execute on the virtual CMM: writes the measured points with deflection and
    /// quality, prints cycle time, stops and per-feature form error.
    Run(RunArgs),
}

/// Options shared by `plan` and `run`; every parameter overrides the file's top-level key of
/// the same name.
#[derive(clap::Args, Debug, Clone)]
pub struct Common {
    /// Features and parameters (TOML: [[feature]] tables, top-level parameters).
    #[arg(long)]
    pub features: PathBuf,
    /// Path style: blended (no stops) or classic (stop, approach along the normal, retract).
    #[arg(long, value_enum, default_value_t = Style::Blended)]
    pub style: Style,
    /// Angle between the approach line and the surface normal, 20 to 60 degrees (default 45).
    #[arg(long, allow_hyphen_values = true)]
    pub approach_angle_deg: Option<f64>,
    /// Scanning speed (default 20 mm/s).
    #[arg(long, value_parser = crate::output::positive)]
    pub scan_speed_mm_s: Option<f64>,
    /// Positioning speed of transfers (default 200 mm/s).
    #[arg(long, value_parser = crate::output::positive)]
    pub move_speed_mm_s: Option<f64>,
    /// Target stylus deflection while scanning (default 0.3 mm).
    #[arg(long, value_parser = crate::output::positive)]
    pub deflection_mm: Option<f64>,
    /// How far the settle path goes past the target deflection (default 0.1 mm).
    #[arg(long, value_parser = crate::output::non_negative)]
    pub overshoot_mm: Option<f64>,
    /// Quality bands on |deflection − target|: A,B (default 0.02,0.05): ≤A → 0, ≤B → 5, else 9.
    #[arg(long, value_parser = parse_pair)]
    pub quality_bands_mm: Option<[f64; 2]>,
    /// Stylus tip radius (default 1.5 mm).
    #[arg(long, value_parser = crate::output::positive)]
    pub tip_radius_mm: Option<f64>,
    /// Clearance from the surface at approach start and release end (default 3 mm).
    #[arg(long, value_parser = crate::output::positive)]
    pub clearance_mm: Option<f64>,
    /// Path acceleration limit (default 1500 mm/s²).
    #[arg(long, value_parser = crate::output::positive)]
    pub accel_mm_s2: Option<f64>,
    /// Path jerk limit (default 20000 mm/s³).
    #[arg(long, value_parser = crate::output::positive)]
    pub jerk_mm_s3: Option<f64>,
    /// Classic style: approach (touch) speed along the normal (default 3 mm/s).
    #[arg(long, value_parser = crate::output::positive)]
    pub touch_speed_mm_s: Option<f64>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct PlanArgs {
    #[command(flatten)]
    pub common: Common,
    /// Path file to write: CSV, or Parquet for a `.parquet` path (same columns; segment and
    /// feature as text).
    #[arg(long)]
    pub output: PathBuf,
    /// Sampling step of the path (s).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 0.001)]
    pub dt_s: f64,
}

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    #[command(flatten)]
    pub common: Common,
    /// Virtual CMM (TOML: [servo] bandwidth_hz, damping, accel_feedforward; [stylus]
    /// natural_freq_hz = [x, y, z], damping_ratio = [x, y, z], restitution, friction;
    /// encoder_noise_um, probe_noise_um, feedback_gain_per_s, contact_threshold_mm).
    /// Default: the built-in CMM (15 Hz servo, 150/200 Hz stylus).
    #[arg(long)]
    pub machine: Option<PathBuf>,
    /// The true part: `truth.json` of `truepos simulate scan` (features matched by id).
    /// Without it the part is exactly nominal.
    #[arg(long)]
    pub part: Option<PathBuf>,
    /// Measured points file to write: CSV, or Parquet for a `.parquet` path (same columns;
    /// segment and feature as text).
    #[arg(long)]
    pub output: PathBuf,
    /// Random seed of the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

// ------------------------------------------------------------------------------------------
// features file: `truepos_scan::file`

/// Read the features file with the command-line overrides; a bad approach angle is a usage error.
fn load(c: &Common) -> Result<(Vec<Feature>, Params)> {
    let overrides = ParamOverrides {
        approach_angle_deg: c.approach_angle_deg,
        scan_speed_mm_s: c.scan_speed_mm_s,
        move_speed_mm_s: c.move_speed_mm_s,
        deflection_mm: c.deflection_mm,
        overshoot_mm: c.overshoot_mm,
        quality_bands_mm: c.quality_bands_mm,
        tip_radius_mm: c.tip_radius_mm,
        clearance_mm: c.clearance_mm,
        accel_mm_s2: c.accel_mm_s2,
        jerk_mm_s3: c.jerk_mm_s3,
        touch_speed_mm_s: c.touch_speed_mm_s,
    };
    Ok(read_features(&c.features, &overrides)?)
}

// ------------------------------------------------------------------------------------------
// commands

pub fn run(a: Args) -> Result<Outcome> {
    match a.action {
        Action::Plan(p) => run_plan(p),
        Action::Run(r) => run_run(r),
    }
}

fn run_plan(a: PlanArgs) -> Result<Outcome> {
    if !(a.dt_s.is_finite() && a.dt_s > 0.0 && a.dt_s <= 0.1) {
        return Err(UsageError(format!("--dt-s {} must be above 0 and at most 0.1 s", a.dt_s)).into());
    }
    let (features, params) = load(&a.common)?;
    let style = a.common.style;
    let pl = plan(&features, &params, style);
    let n = pl.duration() / a.dt_s;
    if !(n.is_finite() && n <= 5.0e7) {
        return Err(UsageError(format!(
            "the path takes {:.3e} s; at --dt-s {} that is more than 5e7 points",
            pl.duration(),
            a.dt_s
        ))
        .into());
    }
    let samples = pl.sample(a.dt_s);
    truepos_scan::file::write_path(&a.output, &pl, &samples, style.name())
        .with_context(|| format!("cannot write {}", a.output.display()))?;
    if a.common.json {
        print_json(&truepos_scan::json::plan(&pl, style, samples.len()))?;
    } else {
        eprintln!(
            "{} style: {} features, planned cycle {:.3} s, {} stops; wrote {} ({} points)",
            style.name(),
            features.len(),
            pl.duration(),
            pl.stops(),
            a.output.display(),
            samples.len()
        );
    }
    Ok(Outcome::Done)
}

fn run_run(a: RunArgs) -> Result<Outcome> {
    let (features, params) = load(&a.common)?;
    let (machine, control) = match &a.machine {
        Some(path) => read_machine_file(path)?,
        None => (CmmConfig::default(), ControlParams::default()),
    };
    let truth = match &a.part {
        Some(p) => truepos_plant::scan_scenario::read_truth(p, &features, &params)?,
        None => features.clone(),
    };
    let style = a.common.style;
    let pl = plan(&features, &params, style);
    let r = run_scan(&pl, &truth, &machine, &control, a.seed).map_err(|e| match e {
        // the surface was not found: a measurement failure
        ScanError::NoContact { .. } => anyhow::Error::new(e),
        // a program the virtual CMM refuses (too long, bad machine): the user's input
        ScanError::Invalid(m) => anyhow::Error::new(InputError::in_file(&a.common.features, m)),
        other => Classed::new(ExitClass::Device, Some("execution failed".into()), other).into(),
    })?;
    truepos_scan::file::write_points(&a.output, &r, &features, &params, style.name())
        .with_context(|| format!("cannot write {}", a.output.display()))?;
    if a.common.json {
        print_json(&truepos_scan::json::run(&r, style))?;
    } else {
        eprint!("{}", truepos_scan::json::text(&r, style, &a.output));
    }
    Ok(Outcome::Done)
}

// ------------------------------------------------------------------------------------------
// simulate

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Writes features.toml (the nominal features and scan parameters) and truth.json (the true,\ndisplaced part: every fifth feature 1.2–1.8 mm off nominal along its normal, alternately\nbefore and beyond). Then: truepos scan run --features DIR/features.toml --part DIR/truth.json ..."
)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// Number of features on the part (bores, bosses, circles on the top plane, lines), 1 to 200.
    #[arg(long, default_value_t = 12, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=200))]
    pub features: usize,
}

pub fn simulate(a: SimArgs) -> Result<Outcome> {
    if a.features == 0 || a.features > 10_000 {
        return Err(UsageError(format!("--features {} must be between 1 and 10000", a.features)).into());
    }
    let w = truepos_plant::scan_scenario::write_scenario(a.common.out_dir()?, a.common.seed, a.features)?;
    eprint!("{}", w.text());
    Ok(Outcome::Done)
}
