//! `truepos probe sphere`: probe a reference sphere over its upper hemisphere on a machine with
//! a touch probe and fit it — on the virtual machine tool (`--controller virtual`, the default)
//! or a real controller (`linuxcncrsh://HOST:PORT`, `ippdme://HOST:PORT`). The procedure is
//! `truepos_head::acquire::probe_sphere`; this module only parses options, opens the
//! controller ([`open_probing_machine`]) and prints the result.

use crate::output::{parse_triple, print_json, v3};
use crate::{ClassExt, Classed, Outcome, UsageError};
use anyhow::Result;
use serde_json::json;
use truepos_device::ProbingMachine;
use truepos_head::acquire::{probe_sphere, AcquireError, SphereProbing};
use truepos_math::exit::ExitClass;
use truepos_math::Point3;
use truepos_plant::probing::{MachineToolConfig, VirtualMachineTool};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Probe a reference sphere (G38.2 on LinuxCNC) over its upper hemisphere and fit it.
    Sphere(SphereArgs),
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "The machine must be on, homed and idle (truepos never releases an e-stop or switches a machine\non). It first rises to the safe height (nominal top + tip radius + 2 × clearance), then visits\neach point from above. The nominal centre must be known to better than the clearance.\nExit code 3 (naming the address and the move) when the controller cannot be reached, reports\nan error, or a probing move ends without contact (the machine is left retracted)."
)]
pub struct SphereArgs {
    #[command(flatten)]
    pub sphere: SphereTarget,
    /// Number of points (≥ 5).
    #[arg(long, default_value_t = 25)]
    pub points: usize,
    /// Probing feed (mm/min, at most 5000: faster, a touch probe cannot stop within its overtravel).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 50.0)]
    pub feed_mm_min: f64,
    #[command(flatten)]
    pub model: ModelArgs,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

/// `--machine-model FILE`: task-specific uncertainty (ISO/TS 15530-4) for commands that measure
/// through a controller.
#[derive(clap::Args, Debug, Clone)]
pub struct ModelArgs {
    /// What is known of the machine's errors (TOML): the keys of the virtual CMM's
    /// `[ippdme.model]` (its geometric map class, probe pre-travel and lobing, noise; the seed is
    /// ignored) and/or `[iso10360] mpe_e_um = [A, K]` (MPE_E = A + L/K µm), `mpe_p_um = P`; for a
    /// machine tool also `[machine_tool] servo_period_ms, pretravel_um, position_sigma_um` (the
    /// probe latch; default 1 ms, 0.5 µm, 0.1 µm).
    /// With it the uncertainty is task-specific: the same probing simulated on machines drawn
    /// from the model. Without it, the fit's scatter alone (a warning says so).
    #[arg(long, value_name = "FILE")]
    pub machine_model: Option<std::path::PathBuf>,
    /// Machine realisations of the task-specific simulation (≥ 200).
    #[arg(long, default_value_t = truepos_vcmm::MIN_RUNS, requires = "machine_model")]
    pub monte_carlo_runs: usize,
}

impl ModelArgs {
    /// The machine model, read (and checked) before any machine moves.
    pub fn read(&self) -> Result<Option<truepos_vcmm::MachineModel>> {
        let Some(path) = &self.machine_model else { return Ok(None) };
        if !(truepos_vcmm::MIN_RUNS..=truepos_vcmm::MAX_RUNS).contains(&self.monte_carlo_runs) {
            return Err(UsageError(format!(
                "--monte-carlo-runs must be between {} and {}, got {}",
                truepos_vcmm::MIN_RUNS,
                truepos_vcmm::MAX_RUNS,
                self.monte_carlo_runs
            ))
            .into());
        }
        Ok(Some(truepos_vcmm::MachineModel::read(path)?))
    }

    /// The Monte Carlo settings.
    pub fn monte_carlo(&self) -> truepos_vcmm::MonteCarlo {
        truepos_vcmm::MonteCarlo { runs: self.monte_carlo_runs, ..Default::default() }
    }
}

/// The warning printed when a measurement's uncertainty leaves the machine's errors out.
pub const NO_MODEL_WARNING: &str = "warning: no --machine-model: the uncertainty is the fit's scatter alone and does not include the machine's own errors (geometric map, probe); give the machine's error model or its ISO 10360 MPEs for a task-specific uncertainty";

/// The options every command that probes a reference sphere through a controller shares
/// (`probe sphere`, `head-offset acquire`, `latency probe`).
#[derive(clap::Args, Debug)]
pub struct SphereTarget {
    /// `virtual` (the built-in virtual machine tool), `linuxcncrsh://HOST:PORT[?password=…]`,
    /// `ippdme://HOST:PORT` (a CMM through its I++ DME server).
    #[arg(long, default_value = "virtual")]
    pub controller: String,
    /// Nominal sphere centre X,Y,Z (mm, machine frame; at C = 0 when the table turns); negative
    /// values as `--near=-1,2,3`.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub near: [f64; 3],
    /// Nominal sphere diameter (mm).
    #[arg(long, value_parser = crate::output::positive)]
    pub diameter_mm: f64,
    /// Distance from the nominal surface where each probing move starts and beyond which it
    /// gives up (mm).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 2.0)]
    pub clearance_mm: f64,
    /// Stylus ball diameter (mm); a reported radius is the tip-centre sphere's minus half this.
    #[arg(long, value_parser = crate::output::non_negative, default_value_t = 0.0)]
    pub tip_diameter_mm: f64,
    /// Seed of the virtual machine (where its sphere really is relative to the nominal one).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl SphereTarget {
    /// The sphere probing with `points` points at `feed_mm_min`.
    pub fn plan(&self, points: usize, feed_mm_min: f64) -> SphereProbing {
        SphereProbing {
            near_mm: Point3::from(self.near),
            diameter_mm: self.diameter_mm,
            points,
            feed_mm_s: feed_mm_min / 60.0,
            clearance_mm: self.clearance_mm,
            tip_radius_mm: 0.5 * self.tip_diameter_mm,
        }
    }

    /// The machine behind `--controller` (the virtual one set up around this sphere).
    pub fn open(&self) -> Result<Opened> {
        let nominal = (Point3::from(self.near), 0.5 * self.diameter_mm, 0.5 * self.tip_diameter_mm);
        open_probing_machine(&self.controller, Some(nominal), self.seed)
    }
}

/// A probing machine opened from a `--controller` URL, with what a report says about it.
pub struct Opened {
    pub machine: Box<dyn ProbingMachine>,
    /// For the virtual machine: its true sphere (centre, radius).
    pub virtual_truth: Option<(Point3, f64)>,
}

/// Open the machine behind `--controller`. `virtual` builds the virtual machine tool with a
/// reference sphere near `nominal` (centre and radius), displaced by a seeded fraction of a
/// millimetre as a real setup would be.
pub fn open_probing_machine(url: &str, nominal: Option<(Point3, f64, f64)>, seed: u64) -> Result<Opened> {
    if url == "virtual" {
        let (cfg, truth) = match nominal {
            Some((c, r, tip)) => {
                let cfg = MachineToolConfig::near(seed, c, r, tip);
                let truth = cfg.spheres.first().copied();
                (cfg, truth)
            }
            None => (MachineToolConfig { seed, ..MachineToolConfig::default() }, None),
        };
        let m = VirtualMachineTool::new(cfg).usage_in("virtual machine")?;
        return Ok(Opened { machine: Box::new(m), virtual_truth: truth });
    }
    if url.starts_with(truepos_linuxcnc::url::SCHEME) {
        let address = truepos_linuxcnc::Address::parse(url)?;
        let m = truepos_linuxcnc::LinuxCnc::open_address(&address, truepos_linuxcnc::Options::default())?;
        return Ok(Opened { machine: Box::new(m), virtual_truth: None });
    }
    if url.starts_with("ippdme://") {
        // A CMM through its I++ DME server (`truepos ippdme serve` or a real controller).
        let m = truepos_ippdme::client::connect(url)?;
        return Ok(Opened { machine: Box::new(m), virtual_truth: None });
    }
    Err(UsageError(format!(
        "--controller `{url}`: expected `virtual`, `linuxcncrsh://HOST:PORT[?password=…]` or `ippdme://HOST:PORT`"
    ))
    .into())
}

pub fn run(a: Args) -> Result<Outcome> {
    match a.what {
        What::Sphere(s) => sphere(s),
    }
}

fn sphere(a: SphereArgs) -> Result<Outcome> {
    let plan = a.sphere.plan(a.points, a.feed_mm_min);
    // Check the plan and the machine model before touching a machine.
    plan.check()?;
    let model = a.model.read()?;
    let mut opened = a.sphere.open()?;
    let info = opened.machine.info();
    let t0 = std::time::Instant::now();
    let s = match probe_sphere(opened.machine.as_mut(), &plan) {
        Ok(s) => s,
        Err(e @ AcquireError::Plan(_)) => return Err(e.into()),
        Err(e) => return Err(Classed::new(ExitClass::Device, None, e).into()),
    };
    let elapsed = t0.elapsed().as_secs_f64();
    let fit_u = (s.center_uncertainty_mm, s.radius_uncertainty_mm);
    // A machine tool (LinuxCNC, the virtual one) latches its probe input once per servo period:
    // its simulation carries that latch; a CMM (I++ DME) latches at the trigger.
    let machine_tool = !a.sphere.controller.starts_with("ippdme://");
    let task = match &model {
        Some(m) if machine_tool => Some(truepos_vcmm::sphere_uncertainty_machine_tool(
            m,
            &plan,
            s.center_mm,
            s.radius_mm,
            fit_u.0,
            fit_u.1,
            a.model.monte_carlo(),
        )?),
        Some(m) => Some(truepos_vcmm::sphere_uncertainty(
            m,
            &plan,
            s.center_mm,
            s.radius_mm,
            fit_u.0,
            fit_u.1,
            a.model.monte_carlo(),
        )?),
        None => {
            eprintln!("{NO_MODEL_WARNING}");
            None
        }
    };
    let (u_c, u_r) = task.as_ref().map_or(fit_u, |t| (t.center_mm, t.radius_mm));
    let k = truepos_math::stats::COVERAGE_FACTOR;
    let mut s = s;
    s.center_uncertainty_mm = u_c;
    s.radius_uncertainty_mm = u_r;
    if a.json {
        let mut j = s.to_json();
        j["uncertainty"] =
            json!({ "center_mm": v3(Point3::from(u_c)), "radius_mm": u_r, "diameter_mm": 2.0 * u_r });
        j["coverage_factor"] = json!(k);
        j["expanded_uncertainty"] = json!({ "center_mm": v3(Point3::from(u_c * k)), "radius_mm": k * u_r, "diameter_mm": 2.0 * k * u_r });
        j["fit_uncertainty"] = json!({ "center_mm": v3(Point3::from(fit_u.0)), "radius_mm": fit_u.1 });
        match &task {
            Some(t) => {
                j["uncertainty_method"] = json!("task-specific");
                j["monte_carlo_runs"] = json!(t.runs);
                j["uncertainty_basis"] = json!(t.basis);
                j["monte_carlo_s"] = json!(t.elapsed_s);
                j["simulated_bias"] =
                    json!({ "center_mm": v3(Point3::from(t.bias_center_mm)), "radius_mm": t.bias_radius_mm });
            }
            None => {
                j["uncertainty_method"] = json!("fit-residuals");
                j["monte_carlo_runs"] = json!(0);
                j["uncertainty_basis"] =
                    json!("scatter of the fit's residuals only (machine errors not included)");
            }
        }
        j["tip_diameter_mm"] = json!(a.sphere.tip_diameter_mm);
        j["feed_mm_min"] = json!(a.feed_mm_min);
        j["clearance_mm"] = json!(a.sphere.clearance_mm);
        j["controller"] = json!({ "address": info.address, "version": info.version });
        j["elapsed_s"] = json!(elapsed);
        if let Some((c, r)) = opened.virtual_truth {
            j["virtual_truth"] = json!({ "center_mm": v3(c), "radius_mm": r });
        }
        print_json(&j)?;
    } else {
        println!(
            "sphere probed on {} ({}), {} points in {elapsed:.1} s",
            info.address,
            info.version,
            s.points.len()
        );
        println!(
            "  centre  {:.4} {:.4} {:.4} mm  (U = {:.2} {:.2} {:.2} µm, k = {k})",
            s.center_mm.x,
            s.center_mm.y,
            s.center_mm.z,
            k * u_c.x * 1e3,
            k * u_c.y * 1e3,
            k * u_c.z * 1e3
        );
        println!(
            "  radius  {:.4} mm (U = {:.2} µm, k = {k}), rms {:.2} µm",
            s.radius_mm,
            k * u_r * 1e3,
            s.rms_mm * 1e3
        );
        match &task {
            Some(t) => {
                println!("  uncertainty: task-specific, {} machine realisations ({})", t.runs, t.basis)
            }
            None => println!("  uncertainty: fit residuals only (machine errors not included)"),
        }
    }
    Ok(Outcome::Done)
}
