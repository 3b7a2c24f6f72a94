//! `truepos latency`: the system delay between scanning-probe data and machine position data,
//! `truepos latency apply` (stylus-centre positions for a known delay), the `latency` scenario
//! of `truepos simulate`, and the demo section.
//!
//! Sign convention (interface contract): the stylus centre at probe stamp `t` is
//! `machine(t + delay_s) + deflection(t)`; a positive delay means the machine data lags.
//!
//! Entry points: [`run`], [`simulate`]; the demo section is the cell's latency scenario's
//! `demo_section`. The algorithms are in
//! `truepos-latency`; this module reads the CSV files, maps errors to file/line messages and
//! writes JSON, CSV and the report.

use crate::output::emit;
use crate::{Classed, Outcome, UsageError};
use anyhow::Result;
use std::path::PathBuf;
use truepos_cell::scenarios::latency::{self as latency_scenario, SimRequest};
use truepos_latency::task;
use truepos_latency::{KnownSize, Method, Options};
use truepos_math::exit::ExitClass;

const AFTER_HELP: &str =
    "Files: machine t_s,x_mm,y_mm,z_mm (encoder position of the probe body); probe t_s,a_mm,b_mm,c_mm
(stylus deflection along the machine axes, pointing along the surface's outward normal), one
master clock, any rates. delay_s: the stylus centre at probe stamp t is
machine(t + delay_s) + deflection(t); positive means the machine data lags.

Contacts are segmented where |deflection| > --threshold-mm; each surface point is found by
extrapolating machine position against deflection to zero deflection on the retract (approach
as fallback). With --already-corrected-s D0 the data's machine stamps were already corrected by
D0: residual_delay_s is what the data shows, delay_s = D0 + residual the total.
JSON: method, delay_s, uncertainty_s, n_contacts, static_size_mm, per_speed, per_axis_delay_s
(null where not observable), rms_mm, residual_delay_s, warnings.";

#[derive(clap::Args, Debug)]
#[command(args_conflicts_with_subcommands = true, after_help = AFTER_HELP)]
pub struct Args {
    #[command(subcommand)]
    pub action: Option<Action>,
    /// Machine positions: t_s,x_mm,y_mm,z_mm.
    #[arg(long)]
    pub machine: Option<PathBuf>,
    /// Probe deflections: t_s,a_mm,b_mm,c_mm.
    #[arg(long)]
    pub probe: Option<PathBuf>,
    /// How the delay is found (auto: chosen from the data and the options given).
    #[arg(long, value_enum, default_value_t = Method::Auto)]
    pub method: Method,
    /// Known sphere (or ring) diameter, mm (artefact method).
    #[arg(long, value_parser = crate::output::positive, conflicts_with = "gap_mm")]
    pub sphere_diameter_mm: Option<f64>,
    /// Known distance between two parallel plates, mm (artefact method).
    #[arg(long, value_parser = crate::output::positive)]
    pub gap_mm: Option<f64>,
    /// Stylus tip radius, mm (0: sizes are of the stylus-centre surface).
    #[arg(long, value_parser = crate::output::non_negative, default_value_t = 0.0)]
    pub tip_radius_mm: f64,
    /// Contact detection threshold on |deflection|, mm.
    #[arg(long, value_parser = crate::output::positive, default_value_t = 0.005)]
    pub threshold_mm: f64,
    /// Separate delays for X, Y, Z (from opposite contacts, or points at several speeds, along each axis).
    #[arg(long)]
    pub per_axis: bool,
    /// Search range of the scan method, ± seconds.
    #[arg(long, value_parser = crate::output::positive, default_value_t = 0.05)]
    pub max_delay_s: f64,
    /// Delay already applied to the data (s): report the residual and the total.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub already_corrected_s: f64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Stylus-centre positions machine(t + delay) + deflection(t) at the probe time stamps.
    Apply(ApplyArgs),
    /// The delay through a controller: a reference sphere probed at several feeds, radius
    /// against feed (a late latch makes a sphere probed from outside smaller by feed × delay).
    Probe(ProbeArgs),
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "The sphere is probed over its upper hemisphere at every feed (as `truepos probe sphere` does) and
fitted; the slope of the fitted radius against the feed is minus the delay, with its standard
uncertainty from the sphere fits (scaled up by the line's scatter when that is larger). A
controller that samples its probe input every servo period T latches 0…T late: expect about T/2.
With --controller virtual (servo period 1 ms) the JSON has the virtual machine's true mean
latch delay, 0.5 ms."
)]
pub struct ProbeArgs {
    #[command(flatten)]
    pub sphere: super::probe::SphereTarget,
    /// Probing feeds (mm/min), comma-separated; at least two, the highest ≥ 1.5 × the lowest.
    #[arg(long, value_parser = crate::output::positive, value_delimiter = ',', default_value = "60,120,240,480")]
    pub feeds_mm_min: Vec<f64>,
    /// Points per sphere.
    #[arg(long, default_value_t = 25)]
    pub points: usize,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Writes t_s,x_mm,y_mm,z_mm at every probe stamp whose t + delay the machine data covers, then\nthe probe file's other columns unchanged. Written atomically."
)]
pub struct ApplyArgs {
    /// The system delay (s).
    #[arg(long, allow_hyphen_values = true)]
    pub delay_s: f64,
    /// Machine positions: t_s,x_mm,y_mm,z_mm (encoder position of the probe body).
    #[arg(long)]
    pub machine: PathBuf,
    /// Probe deflections: t_s,a_mm,b_mm,c_mm (along the machine axes).
    #[arg(long)]
    pub probe: PathBuf,
    /// Output: t_s,x_mm,y_mm,z_mm stylus-centre positions at the probe time stamps, then the probe file's other columns; Parquet for a `.parquet` path, else CSV.
    #[arg(long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

fn positive(name: &str, v: f64) -> Result<(), UsageError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(UsageError(format!("{name} must be a positive number, got {v}")))
    }
}

/// The options of the command line as library options (validated).
fn options(a: &Args) -> Result<Options, UsageError> {
    positive("--threshold-mm", a.threshold_mm)?;
    positive("--max-delay-s", a.max_delay_s)?;
    if !(a.tip_radius_mm.is_finite() && a.tip_radius_mm >= 0.0) {
        return Err(UsageError(format!("--tip-radius-mm must be zero or positive, got {}", a.tip_radius_mm)));
    }
    if !a.already_corrected_s.is_finite() {
        return Err(UsageError("--already-corrected-s must be a finite number".into()));
    }
    let known_size = match (a.sphere_diameter_mm, a.gap_mm) {
        (Some(d), _) => {
            positive("--sphere-diameter-mm", d)?;
            Some(KnownSize::SphereDiameter(d))
        }
        (None, Some(g)) => {
            positive("--gap-mm", g)?;
            Some(KnownSize::Gap(g))
        }
        _ => None,
    };
    if a.method == Method::Artefact && known_size.is_none() {
        return Err(UsageError("--method artefact needs --sphere-diameter-mm or --gap-mm".into()));
    }
    Ok(Options {
        method: a.method,
        known_size,
        tip_radius: a.tip_radius_mm,
        threshold: a.threshold_mm,
        per_axis: a.per_axis,
        max_delay: a.max_delay_s,
        already_corrected: a.already_corrected_s,
    })
}

pub fn run(a: Args) -> Result<Outcome> {
    if let Some(Action::Apply(ap)) = a.action {
        if !ap.delay_s.is_finite() {
            return Err(UsageError("--delay-s must be a finite number".into()).into());
        }
        emit(&task::apply_files(&ap.machine, &ap.probe, ap.delay_s, &ap.output)?, ap.json)?;
        return Ok(Outcome::Done);
    }
    if let Some(Action::Probe(p)) = a.action {
        return probe_feeds(p);
    }
    let (Some(machine), Some(probe)) = (a.machine.as_ref(), a.probe.as_ref()) else {
        return Err(UsageError(
            "truepos latency needs --machine FILE and --probe FILE (or the apply subcommand)".into(),
        )
        .into());
    };
    let opts = options(&a)?;
    let pb = crate::output::spinner("system delay: reading the streams, finding the contacts, estimating");
    let r = task::estimate_files(machine, probe, opts);
    pb.finish_and_clear();
    let r = r?;
    for w in &r.estimate.warnings {
        eprintln!("warning: {w}");
    }
    emit(&r, a.json)?;
    Ok(Outcome::Done)
}

/// `truepos latency probe`: the delay by feeds through `--controller`.
fn probe_feeds(a: ProbeArgs) -> Result<Outcome> {
    let plan = a.sphere.plan(a.points, 60.0);
    let feeds: Vec<f64> = a.feeds_mm_min.iter().map(|f| f / 60.0).collect();
    // The sphere's sizes and place before a machine is opened (an absurd --diameter-mm is a
    // usage error naming its limit, not a machine error).
    plan.check()?;
    let mut opened = a.sphere.open()?;
    use truepos_head::acquire::AcquireError;
    let mut r = match truepos_latency::probing::delay_by_feeds(opened.machine.as_mut(), &plan, &feeds) {
        Ok(r) => r,
        Err(e @ AcquireError::Plan(_)) => return Err(e.into()),
        Err(e) => return Err(Classed::new(ExitClass::Device, None, e).into()),
    };
    if opened.virtual_truth.is_some() {
        // The virtual machine tool latches at the first servo sample after the trigger, at a
        // random phase: on average half a servo period late.
        r.virtual_truth_s = Some(0.5 * truepos_plant::probing::MachineToolConfig::default().servo_period_s);
    }
    emit(&r, a.json)?;
    Ok(Outcome::Done)
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Writes machine.csv (t_s,x_mm,y_mm,z_mm), probe.csv (t_s,a_mm,b_mm,c_mm) and truth.json\n(delay_s, per_axis_delay_s, artefact, tip radius, speeds, contacts)."
)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// sphere, plates, speeds, scan, inout, per-axis, multi-rate or oblique.
    #[arg(long, default_value = "sphere")]
    pub variant: String,
    /// System delay (s): machine capture latency minus probe capture latency (default 0.0025).
    #[arg(long, allow_hyphen_values = true)]
    pub delay_s: Option<f64>,
    /// Contact (or scan) speed, mm/s.
    #[arg(long, value_parser = crate::output::positive)]
    pub speed_mm_s: Option<f64>,
    /// Repeats of the contact pattern (or scan revolutions), 1 to 1000 (default: 24; 8 for
    /// speeds, 12 for scan: enough contacts for the 10 µs goal).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1000))]
    pub repeats: Option<usize>,
    /// Machine position stream rate, Hz (default 1000).
    #[arg(long, value_parser = crate::output::positive)]
    pub machine_rate_hz: Option<f64>,
    /// Probe deflection stream rate, Hz (default 1000; 4000 for multi-rate).
    #[arg(long, value_parser = crate::output::positive)]
    pub probe_rate_hz: Option<f64>,
}

pub fn simulate(a: SimArgs) -> Result<Outcome> {
    let request = SimRequest {
        variant: a.variant.clone(),
        seed: a.common.seed,
        delay_s: a.delay_s,
        speed_mm_s: a.speed_mm_s,
        repeats: a.repeats,
        machine_rate_hz: a.machine_rate_hz,
        probe_rate_hz: a.probe_rate_hz,
    };
    let d = latency_scenario::simulate(&request)?;
    latency_scenario::write_dataset(a.common.out_dir()?, &d)?;
    eprint!("{}", latency_scenario::written_text(&a.common.out, &d));
    Ok(Outcome::Done)
}
