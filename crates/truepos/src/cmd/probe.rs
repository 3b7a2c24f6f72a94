//! `truepos probe sphere`: probe a reference sphere over its upper hemisphere on a machine with
//! a touch probe and fit it — on the virtual machine tool (`--controller virtual`, the default)
//! or a real controller (`linuxcncrsh://HOST:PORT`, `ippdme://HOST:PORT`). The procedure is
//! `truepos_head::acquire::probe_sphere`; this module only parses options, opens the
//! controller ([`open_probing_machine`]) and prints the result.

use crate::output::{parse_triple, print_json, v3};
use crate::{DeviceError, Outcome, UsageError};
use anyhow::Result;
use serde_json::json;
use truepos_cell::probing::{MachineToolConfig, VirtualMachineTool};
use truepos_device::ProbingMachine;
use truepos_head::acquire::{probe_sphere, AcquireError, SphereProbing};
use truepos_math::Point3;

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
    /// Probing feed (mm/min).
    #[arg(long, value_parser = crate::output::positive, default_value_t = 50.0)]
    pub feed_mm_min: f64,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

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
        let m = VirtualMachineTool::new(cfg).map_err(|e| UsageError(format!("virtual machine: {e}")))?;
        return Ok(Opened { machine: Box::new(m), virtual_truth: truth });
    }
    if url.starts_with(truepos_linuxcnc::url::SCHEME) {
        let address = truepos_linuxcnc::Address::parse(url).map_err(|e| UsageError(e.to_string()))?;
        let m = truepos_linuxcnc::LinuxCnc::open_address(&address, truepos_linuxcnc::Options::default())
            .map_err(|e| DeviceError(e.to_string()))?;
        return Ok(Opened { machine: Box::new(m), virtual_truth: None });
    }
    if url.starts_with("ippdme://") {
        // A CMM through its I++ DME server (`truepos ippdme serve` or a real controller).
        let m = truepos_ippdme::client::connect(url).map_err(|e| DeviceError(e.to_string()))?;
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
    // Check the plan before touching a machine.
    if let Err(e) = plan.check() {
        return Err(UsageError(e.to_string()).into());
    }
    let mut opened = a.sphere.open()?;
    let info = opened.machine.info();
    let t0 = std::time::Instant::now();
    let s = match probe_sphere(opened.machine.as_mut(), &plan) {
        Ok(s) => s,
        Err(AcquireError::Plan(m)) => return Err(UsageError(m).into()),
        Err(e) => return Err(DeviceError(e.to_string()).into()),
    };
    let elapsed = t0.elapsed().as_secs_f64();
    if a.json {
        let mut j = s.to_json();
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
            "  centre  {:.4} {:.4} {:.4} mm  (u = {:.4} {:.4} {:.4})",
            s.center_mm.x,
            s.center_mm.y,
            s.center_mm.z,
            s.center_uncertainty_mm.x,
            s.center_uncertainty_mm.y,
            s.center_uncertainty_mm.z
        );
        println!(
            "  radius  {:.4} mm (u = {:.4}), rms {:.4} mm",
            s.radius_mm, s.radius_uncertainty_mm, s.rms_mm
        );
    }
    Ok(Outcome::Done)
}
