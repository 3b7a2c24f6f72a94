//! # truepos-vcmm — task-specific measurement uncertainty by simulation
//!
//! Task-specific measurement uncertainty by simulation (ISO/TS 15530-4, the "virtual CMM";
//! JCGM 101 Monte Carlo): what `--machine-model FILE` adds to the commands that measure through a
//! controller.
//!
//! The user does not know the errors of *their* machine, only the class it belongs to: its error
//! model (the keys of the virtual CMM's `[ippdme.model]`: a geometric map of that class and size,
//! probe pre-travel residual and lobing, noise) or its ISO 10360 datasheet (`[iso10360] mpe_e_um
//! = [A, K]`, `mpe_p_um = P`). The uncertainty of a measurement is then the spread of its result
//! over machines of that class, each measuring a perfect feature at the measured place with the
//! same strategy:
//!
//! 1. for r = 1..R (R ≥ [`MIN_RUNS`], seeded, in parallel): draw a machine from the model (a new
//!    geometric map, probe lobing and pre-travel residual, a new noise stream), run the *same*
//!    probing code ([`truepos_head::acquire::probe_sphere`]) against a perfect sphere at the
//!    measured centre and radius, fit, and record the deviations of the fitted parameters from
//!    the perfect ones;
//! 2. u of each parameter = the root mean square of those deviations (their spread plus the bias
//!    the model predicts, which is not corrected);
//! 3. the measurement's own fit scatter is a cross-check, not a second noise term (the noise is in
//!    the simulation already): only the part of it beyond what the simulated machines show (the
//!    median of their fit uncertainties) is added in quadrature — form error of the artefact or
//!    effects the model does not contain;
//! 4. U = k·u with k = [`truepos_math::stats::COVERAGE_FACTOR`].
//!
//! With the ISO 10360 datasheet only, each realisation has per-axis scale errors uniform within
//! ±1/K µm/mm and squareness errors uniform within ±1/K µrad·10³ (so that a length along any axis
//! or diagonal stays within MPE_E's length term), and a probing error along the surface normal
//! uniform within ±P/2 per point (a form range within MPE_P) — the usual conservative
//! assumptions (uniform within ±MPE). The output says which basis was used.
//!
//! Entry points: [`MachineModel`] (read the file), [`sphere_uncertainty`] (a probed sphere),
//! [`inspection_uncertainty`] (`somac inspect`), [`head_offset_uncertainty`] (`head-offset
//! acquire`),
//! [`SimulatedCmm`] (one realisation behind the [`ProbingMachine`] trait). The common parts:
//! [`monte_carlo`] (the one parallel, seeded loop), [`simulate`] (it, over every basis of the
//! model, summarised as a [`Spread`]), [`PointErrors`] (one realisation as errors of probed
//! points) and [`ErrorOverlay`] (those errors added to another machine's contacts). The same
//! loop over `dmis run` (the program replayed on the perfect features) and `kinematics
//! calibrate` is `truepos_cell::uncertainty`, which joins those capabilities to it.

#![forbid(unsafe_code)]

mod error;

use rayon::prelude::*;
use std::path::Path;
use truepos_device::{DeviceError, DeviceInfo, ProbeHit, ProbeRequest, ProbingMachine};
use truepos_head::acquire::{probe_sphere, SphereProbing};
use truepos_ippdme::part::{Part, Solid};
use truepos_ippdme::{Cmm, MachineConfig};
use truepos_math::{Matrix3, Point3, Vector3};
use truepos_sim::noise;

pub use error::{Result, VcmmError};
use truepos_plant::cmm::IppdmeCmm;

/// The fewest machine realisations a task-specific uncertainty is computed from.
pub const MIN_RUNS: usize = 200;

/// The base seed of the realisations (fixed: the same measurement gets the same uncertainty).
pub const DEFAULT_SEED: u64 = 0x1553_0004;

/// Most realisations (bounds the work of one command).
pub const MAX_RUNS: usize = 100_000;

/// An ISO 10360 datasheet: MPE_E = A + L/K µm (L in mm) and MPE_P.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Iso10360 {
    /// A of MPE_E (µm).
    pub mpe_e_a_um: f64,
    /// K of MPE_E (mm/µm).
    pub mpe_e_k: f64,
    /// MPE_P (µm): the range of a sphere's residuals the probing may produce.
    pub mpe_p_um: f64,
}

/// What is known of the machine's errors (`--machine-model FILE`).
#[derive(Debug, Clone)]
pub struct MachineModel {
    /// The file it was read from (for messages and the JSON).
    pub source: String,
    /// The virtual CMM's error model (`[ippdme.model]`, and the `[ippdme]` volume the map is
    /// stretched over); its seed is not used.
    pub cmm: Option<MachineConfig>,
    /// The ISO 10360 datasheet.
    pub iso10360: Option<Iso10360>,
    /// What a machine tool's controller adds when it measures (`[machine_tool]`; defaults: the
    /// virtual machine tool's, a LinuxCNC servo thread of 1 ms).
    pub machine_tool: MachineToolLatch,
}

/// A machine tool's probing beyond the model's errors: its probe input is sampled once per servo
/// period (the latched position lies up to one servo step, feed × period, past the trigger), the
/// probe's pre-travel, and the noise of each latched axis (`[machine_tool] servo_period_ms,
/// pretravel_um, position_sigma_um`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MachineToolLatch {
    /// Servo period (the probe input's sampling), s.
    pub servo_period_s: f64,
    /// Touch-trigger pre-travel, mm.
    pub pretravel_mm: f64,
    /// Standard deviation of each latched axis position, mm.
    pub position_sigma_mm: f64,
}

impl Default for MachineToolLatch {
    fn default() -> Self {
        let d = truepos_plant::probing::MachineToolConfig::default();
        MachineToolLatch {
            servo_period_s: d.servo_period_s,
            pretravel_mm: d.pretravel_mm,
            position_sigma_mm: d.position_sigma_mm,
        }
    }
}

impl MachineToolLatch {
    /// Give a virtual machine tool this latch.
    pub fn apply(&self, cfg: &mut truepos_plant::probing::MachineToolConfig) {
        cfg.servo_period_s = self.servo_period_s;
        cfg.pretravel_mm = self.pretravel_mm;
        cfg.position_sigma_mm = self.position_sigma_mm;
    }
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    ippdme: Option<toml::Table>,
    iso10360: Option<RawIso>,
    machine_tool: Option<RawMachineTool>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMachineTool {
    servo_period_ms: Option<f64>,
    pretravel_um: Option<f64>,
    position_sigma_um: Option<f64>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIso {
    mpe_e_um: [f64; 2],
    mpe_p_um: f64,
}

impl MachineModel {
    /// Read a machine-model file (bounded read; every error names the file, and the line where
    /// there is one).
    pub fn read(path: &Path) -> Result<MachineModel> {
        let text = truepos_io::limits::read_config_string(path, "TOML")?;
        MachineModel::from_toml(path, &text)
    }

    /// Parse the text of a machine-model file that came from `path`.
    pub fn from_toml(path: &Path, text: &str) -> Result<MachineModel> {
        let file = path.display().to_string();
        let raw: RawFile = truepos_io::config::parse_toml(path, text)?;
        let cmm = match &raw.ippdme {
            Some(t) => {
                if !t.contains_key("model") {
                    return Err(VcmmError::Invalid(format!(
                        "{file}: [ippdme] has no [ippdme.model] table (the machine's error model)"
                    )));
                }
                Some(MachineConfig::from_toml(&file, text).map_err(|e| VcmmError::Invalid(e.to_string()))?)
            }
            None => None,
        };
        let iso10360 = match raw.iso10360 {
            Some(r) => {
                let [a, k] = r.mpe_e_um;
                let bad = |key: &str, what: &str| {
                    Err(VcmmError::Invalid(format!("{file}: iso10360.{key}: {what}")))
                };
                if !(a.is_finite() && a > 0.0) {
                    return bad("mpe_e_um", "A (µm) must be a positive number");
                }
                if !(k.is_finite() && k > 0.0) {
                    return bad("mpe_e_um", "K (mm/µm, MPE_E = A + L/K) must be a positive number");
                }
                if !(r.mpe_p_um.is_finite() && r.mpe_p_um > 0.0) {
                    return bad("mpe_p_um", "must be a positive number (µm)");
                }
                Some(Iso10360 { mpe_e_a_um: a, mpe_e_k: k, mpe_p_um: r.mpe_p_um })
            }
            None => None,
        };
        let mut machine_tool = MachineToolLatch::default();
        if let Some(t) = raw.machine_tool {
            let check = |key: &str, v: Option<f64>, lo: f64, hi: f64, unit: &str| -> Result<Option<f64>> {
                match v {
                    Some(x) if !(x.is_finite() && x >= lo && x <= hi) => Err(VcmmError::Invalid(format!(
                        "{file}: machine_tool.{key}: {x} is outside {lo}–{hi} {unit}"
                    ))),
                    other => Ok(other),
                }
            };
            // A servo period from 10 µs (a fast FPGA latch) to 10 ms (a slow PLC scan).
            if let Some(ms) = check("servo_period_ms", t.servo_period_ms, 0.01, 10.0, "ms")? {
                machine_tool.servo_period_s = ms * 1e-3;
            }
            if let Some(um) = check("pretravel_um", t.pretravel_um, 0.0, 100.0, "µm")? {
                machine_tool.pretravel_mm = um * 1e-3;
            }
            if let Some(um) = check("position_sigma_um", t.position_sigma_um, 0.0, 100.0, "µm")? {
                machine_tool.position_sigma_mm = um * 1e-3;
            }
        }
        if cmm.is_none() && iso10360.is_none() {
            return Err(VcmmError::Invalid(format!(
                "{file}: names no machine model: expected [ippdme.model] (an error model) and/or [iso10360] (mpe_e_um = [A, K], mpe_p_um)"
            )));
        }
        Ok(MachineModel { source: file, cmm, iso10360, machine_tool })
    }

    /// One line saying what the uncertainty is based on.
    pub fn basis(&self) -> String {
        let mut parts = Vec::new();
        if let Some(c) = &self.cmm {
            let m = &c.model;
            parts.push(format!(
                "error model of {} ({} geometric map ×{}, pre-travel {} µm {}compensated, lobing {} µm, probing noise σ {} µm)",
                self.source,
                if m.geometric_errors { "bridge-CMM" } else { "no" },
                m.geometric_error_scale,
                m.pretravel_mm * 1e3,
                if m.pretravel_compensated { "" } else { "not " },
                m.lobing_mm * 1e3,
                m.probe_noise_mm * 1e3
            ));
        }
        if let Some(i) = &self.iso10360 {
            parts.push(format!(
                "ISO 10360 datasheet of {} (MPE_E = {} + L/{} µm, MPE_P = {} µm; uniform within ±MPE)",
                self.source, i.mpe_e_a_um, i.mpe_e_k, i.mpe_p_um
            ));
        }
        parts.join("; ")
    }
}

/// How many realisations, from which seed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MonteCarlo {
    /// Realisations to simulate.
    pub runs: usize,
    /// Seed of the first realisation.
    pub seed: u64,
}

impl Default for MonteCarlo {
    fn default() -> Self {
        MonteCarlo { runs: MIN_RUNS, seed: DEFAULT_SEED }
    }
}

impl MonteCarlo {
    fn check(&self) -> Result<()> {
        if !(MIN_RUNS..=MAX_RUNS).contains(&self.runs) {
            return Err(VcmmError::Invalid(format!(
                "Monte Carlo runs must be between {MIN_RUNS} and {MAX_RUNS}, got {}",
                self.runs
            )));
        }
        Ok(())
    }

    /// The seed of realisation `r` (SplitMix64 of the base seed and r: independent streams).
    fn seed_of(&self, r: usize) -> u64 {
        let mut z = self.seed ^ (r as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// The task-specific uncertainty of a probed sphere.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereUncertainty {
    /// Standard uncertainty of each centre coordinate (mm).
    pub center_mm: Vector3,
    /// Standard uncertainty of the radius (mm).
    pub radius_mm: f64,
    /// The simulation's part: RMS deviation over the realisations (centre, radius; mm).
    pub simulated_center_mm: Vector3,
    /// RMS deviation of the simulated radius, mm.
    pub simulated_radius_mm: f64,
    /// Mean deviation over the realisations (the bias the model predicts; mm), included in u.
    pub bias_center_mm: Vector3,
    /// Mean deviation of the simulated radius, mm.
    pub bias_radius_mm: f64,
    /// The measurement's own fit scatter beyond the simulated machines' (mm, 0 when within).
    pub excess_center_mm: Vector3,
    /// The measurement's radius scatter beyond the simulated machines', mm.
    pub excess_radius_mm: f64,
    /// Realisations run.
    pub runs: usize,
    /// What the model was (for the output).
    pub basis: String,
    /// Wall time of the simulation (s).
    pub elapsed_s: f64,
}

/// One simulated sphere measurement: deviations of centre and radius from the perfect sphere,
/// and the fit's own standard uncertainties.
#[derive(Debug, Clone, Copy)]
struct Trial {
    dc: Vector3,
    dr: f64,
    uc: Vector3,
    ur: f64,
}

/// The task-specific uncertainty of a sphere measured as `plan` says, whose fit gave `center`,
/// `radius` (the sphere's, tip radius removed) and the fit-residual standard uncertainties
/// `fit_u_center`, `fit_u_radius`.
pub fn sphere_uncertainty(
    model: &MachineModel,
    plan: &SphereProbing,
    center: Point3,
    radius: f64,
    fit_u_center: Vector3,
    fit_u_radius: f64,
    mc: MonteCarlo,
) -> Result<SphereUncertainty> {
    check_sphere_task(mc, plan, center, radius)?;
    let t0 = std::time::Instant::now();
    // The simulation probes the perfect sphere where it was found, with the same plan.
    let sim_plan = *plan;
    let mut per_model: Vec<Vec<Trial>> = Vec::new();
    if let Some(cfg) = &model.cmm {
        let make = |seed: u64| {
            let mut cfg = cfg.clone();
            cfg.model.seed = seed;
            let part = Part { solids: vec![(None, Solid::Sphere { center, radius })] };
            SimulatedCmm::new(&cfg, Some(part), sim_plan.tip_radius_mm)
        };
        per_model.push(trials_on(&make, &sim_plan, center, radius, mc)?);
    }
    if let Some(iso) = &model.iso10360 {
        per_model.push(monte_carlo(mc, |seed| iso_trial(iso, &sim_plan, center, radius, seed))?);
    }
    // Each model gives a u per parameter; with both, the larger (they describe the same machine).
    let mut best: Option<SphereUncertainty> = None;
    for trials in &per_model {
        let u = summarise(trials, fit_u_center, fit_u_radius);
        best = Some(match best {
            None => u,
            Some(b) => larger(b, u),
        });
    }
    let mut out = best.ok_or_else(|| VcmmError::Invalid("the machine model names no model".into()))?;
    out.runs = mc.runs;
    out.basis = model.basis();
    out.elapsed_s = t0.elapsed().as_secs_f64();
    Ok(out)
}

/// The checks every sphere simulation makes before it runs: the Monte Carlo settings, the plan,
/// and a finite measured sphere.
fn check_sphere_task(mc: MonteCarlo, plan: &SphereProbing, center: Point3, radius: f64) -> Result<()> {
    mc.check()?;
    plan.check().map_err(|e| VcmmError::Invalid(e.to_string()))?;
    if !(center.iter().all(|v| v.is_finite()) && radius.is_finite() && radius > 0.0) {
        return Err(VcmmError::Invalid("the measured sphere is not finite".into()));
    }
    Ok(())
}

/// Two bases' uncertainties of the same sphere: per parameter the larger u (they describe the
/// same machine), the larger simulated spread and excess, the bias of larger magnitude.
fn larger(b: SphereUncertainty, u: SphereUncertainty) -> SphereUncertainty {
    let bigger = |x: f64, y: f64| if x.abs() >= y.abs() { x } else { y };
    SphereUncertainty {
        center_mm: b.center_mm.zip_map(&u.center_mm, f64::max),
        radius_mm: b.radius_mm.max(u.radius_mm),
        simulated_center_mm: b.simulated_center_mm.zip_map(&u.simulated_center_mm, f64::max),
        simulated_radius_mm: b.simulated_radius_mm.max(u.simulated_radius_mm),
        bias_center_mm: b.bias_center_mm.zip_map(&u.bias_center_mm, bigger),
        bias_radius_mm: bigger(b.bias_radius_mm, u.bias_radius_mm),
        excess_center_mm: b.excess_center_mm.zip_map(&u.excess_center_mm, f64::max),
        excess_radius_mm: b.excess_radius_mm.max(u.excess_radius_mm),
        ..b
    }
}

fn summarise(trials: &[Trial], fit_u_center: Vector3, fit_u_radius: f64) -> SphereUncertainty {
    let n = trials.len() as f64;
    let mut mean_c = Vector3::zeros();
    let mut mean_r = 0.0;
    let mut ms_c = Vector3::zeros();
    let mut ms_r = 0.0;
    for t in trials {
        mean_c += t.dc;
        mean_r += t.dr;
        ms_c += t.dc.component_mul(&t.dc);
        ms_r += t.dr * t.dr;
    }
    mean_c /= n;
    mean_r /= n;
    let rms_c = (ms_c / n).map(f64::sqrt);
    let rms_r = (ms_r / n).sqrt();
    // Typical fit scatter of the simulated machines (median per parameter).
    let median = |mut v: Vec<f64>| -> f64 {
        v.sort_by(f64::total_cmp);
        let m = v.len() / 2;
        if v.len() % 2 == 1 {
            v[m]
        } else {
            0.5 * (v[m - 1] + v[m])
        }
    };
    let typical_uc = Vector3::from_fn(|k, _| median(trials.iter().map(|t| t.uc[k]).collect()));
    let typical_ur = median(trials.iter().map(|t| t.ur).collect());
    let excess = |obs: f64, typ: f64| (obs * obs - typ * typ).max(0.0).sqrt();
    let excess_c = fit_u_center.zip_map(&typical_uc, excess);
    let excess_r = excess(fit_u_radius, typical_ur);
    SphereUncertainty {
        center_mm: rms_c.zip_map(&excess_c, f64::hypot),
        radius_mm: rms_r.hypot(excess_r),
        simulated_center_mm: rms_c,
        simulated_radius_mm: rms_r,
        bias_center_mm: mean_c,
        bias_radius_mm: mean_r,
        excess_center_mm: excess_c,
        excess_radius_mm: excess_r,
        runs: trials.len(),
        basis: String::new(),
        elapsed_s: 0.0,
    }
}

/// The sphere measured as `plan` says on `mc.runs` machines made by `make(seed)`, each with the
/// perfect sphere (`center`, `radius`) on it.
fn trials_on<M, F>(
    make: &F,
    plan: &SphereProbing,
    center: Point3,
    radius: f64,
    mc: MonteCarlo,
) -> Result<Vec<Trial>>
where
    M: ProbingMachine,
    F: Fn(u64) -> M + Sync,
{
    monte_carlo(mc, |seed| {
        let mut m = make(seed);
        let s = probe_sphere(&mut m, plan).map_err(|e| {
                VcmmError::Failed(format!(
                    "task-specific uncertainty: a simulated machine could not measure the sphere ({e}); the model's errors are larger than the clearance"
                ))
            })?;
        Ok(Trial {
            dc: s.center_mm - center,
            dr: s.radius_mm - radius,
            uc: s.center_uncertainty_mm,
            ur: s.radius_uncertainty_mm,
        })
    })
}

/// The task-specific uncertainty of a sphere measured as `plan` says on a machine of which
/// `make(seed)` builds realisations with the perfect sphere (`center`, `radius`) on them — e.g.
/// the virtual machine tool, whose servo latch, pre-travel and noise are its model. `basis`
/// names the model for the output.
pub fn sphere_uncertainty_on<M, F>(
    make: F,
    basis: &str,
    plan: &SphereProbing,
    center: Point3,
    radius: f64,
    fit_u_center: Vector3,
    fit_u_radius: f64,
    mc: MonteCarlo,
) -> Result<SphereUncertainty>
where
    M: ProbingMachine,
    F: Fn(u64) -> M + Sync,
{
    mc.check()?;
    let t0 = std::time::Instant::now();
    let trials = trials_on(&make, plan, center, radius, mc)?;
    let mut u = summarise(&trials, fit_u_center, fit_u_radius);
    u.basis = basis.to_string();
    u.elapsed_s = t0.elapsed().as_secs_f64();
    Ok(u)
}

/// The task-specific uncertainty of a sphere probed on a machine tool (LinuxCNC, the virtual
/// machine tool): the same probing of the perfect sphere where it was found, on realisations of
/// the virtual machine tool with the model's `[machine_tool]` latch (servo period, pre-travel,
/// position noise) and each basis's errors on every contact ([`ErrorOverlay`]); u per parameter
/// as [`sphere_uncertainty`], the larger over the bases.
pub fn sphere_uncertainty_machine_tool(
    model: &MachineModel,
    plan: &SphereProbing,
    center: Point3,
    radius: f64,
    fit_u_center: Vector3,
    fit_u_radius: f64,
    mc: MonteCarlo,
) -> Result<SphereUncertainty> {
    use truepos_plant::probing::{MachineToolConfig, VirtualMachineTool};
    check_sphere_task(mc, plan, center, radius)?;
    let t0 = std::time::Instant::now();
    let mut best: Option<SphereUncertainty> = None;
    for basis in model.bases() {
        let make = |seed: u64| {
            let mut cfg = MachineToolConfig::near(seed, center, radius, plan.tip_radius_mm);
            cfg.spheres = vec![(center, radius)];
            model.machine_tool.apply(&mut cfg);
            let inner = VirtualMachineTool::new(cfg).expect("a checked plan and a finite sphere");
            ErrorOverlay { inner, errors: PointErrors::draw(basis, seed) }
        };
        let u = summarise(&trials_on(&make, plan, center, radius, mc)?, fit_u_center, fit_u_radius);
        best = Some(match best {
            None => u,
            Some(b) => larger(b, u),
        });
    }
    let mut out = best.ok_or_else(|| VcmmError::Invalid("the machine model names no model".into()))?;
    let l = model.machine_tool;
    out.runs = mc.runs;
    out.basis = format!(
        "{}; on a machine tool: probe input latched every {} ms (up to feed × period past the trigger), pre-travel {} µm, position noise σ {} µm",
        model.basis(),
        l.servo_period_s * 1e3,
        l.pretravel_mm * 1e3,
        l.position_sigma_mm * 1e3
    );
    out.elapsed_s = t0.elapsed().as_secs_f64();
    Ok(out)
}

/// One realisation of the ISO 10360 datasheet measuring the perfect sphere: the tip centres the
/// plan's probing directions find on it, moved by the realisation's linear errors about the
/// sphere's centre and by a uniform probing error along the normal.
fn iso_trial(iso: &Iso10360, plan: &SphereProbing, center: Point3, radius: f64, seed: u64) -> Result<Trial> {
    use rand::Rng;
    let mut rng = noise::rng(seed);
    let rel = 1e-3 / iso.mpe_e_k; // µm per mm → relative
    let mut u = |h: f64| rng.random_range(-h..=h);
    let scale = Vector3::new(u(rel), u(rel), u(rel));
    let (sxy, sxz, syz) = (u(rel), u(rel), u(rel));
    // Linear error matrix: scale on the diagonal, squareness as shear.
    let lin = Matrix3::new(scale.x, sxy, sxz, 0.0, scale.y, syz, 0.0, 0.0, scale.z);
    let half_p = 0.5 * iso.mpe_p_um * 1e-3;
    let r_tip = radius + plan.tip_radius_mm;
    // The linear error is taken about the measured centre's distance from the probing start of
    // the sphere: a length L measured across the sphere errs by ≈ L·ε.
    let points: Vec<Point3> = plan
        .requests()
        .iter()
        .map(|req| {
            let d = req.approach;
            let p = center + d * r_tip;
            let e = lin * (p - center) + d * u(half_p);
            p + e
        })
        .collect();
    let f =
        truepos_fit::sphere(&points).map_err(|e| VcmmError::Failed(format!("ISO 10360 simulation: {e}")))?;
    Ok(Trial { dc: f.center - center, dr: f.radius - r_tip, uc: f.u_center, ur: f.u_radius })
}

/// One realisation of the virtual CMM's error model behind [`ProbingMachine`]: probing moves run
/// as the I++ DME server's PtMeas cycle (start, search to the end, latch, retract) on an
/// [`IppdmeCmm`], in process.
pub struct SimulatedCmm {
    cmm: IppdmeCmm,
    tip_radius_mm: f64,
}

impl SimulatedCmm {
    /// The machine of `config` (its model's seed picks the realisation) with `part` on it,
    /// carrying a stylus ball of `tip_radius_mm` (positioning moves keep it off the part).
    pub fn new(config: &MachineConfig, part: Option<Part>, tip_radius_mm: f64) -> SimulatedCmm {
        SimulatedCmm { cmm: IppdmeCmm::new(config, part), tip_radius_mm }
    }
}

const SIM_ADDRESS: &str = "simulated CMM";

impl ProbingMachine for SimulatedCmm {
    fn info(&self) -> DeviceInfo {
        DeviceInfo { address: SIM_ADDRESS.into(), version: self.cmm.describe() }
    }

    fn position(&mut self) -> Result<Point3, DeviceError> {
        Ok(self.cmm.position())
    }

    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        self.cmm.move_to(target_mm, self.tip_radius_mm).map_err(|e| DeviceError::Controller {
            address: SIM_ADDRESS.into(),
            what: format!("move to {target_mm:?}"),
            message: e.to_string(),
        })
    }

    fn probe(&mut self, req: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        let what = || format!("probing at {:?}", req.nominal_mm);
        let err = |e: truepos_ippdme::MachineError| DeviceError::Controller {
            address: SIM_ADDRESS.into(),
            what: what(),
            message: e.to_string(),
        };
        let (start, end) = (req.start_mm(), req.end_mm());
        let r = req.tip_radius_mm;
        self.cmm.move_to(start, r).map_err(err)?;
        match self.cmm.probe(start, end, r, req.nominal_mm, req.approach).map_err(err)? {
            Some(c) => {
                self.cmm.move_to(c.tip_center_mm + req.approach * req.retract_mm, r).map_err(err)?;
                Ok(ProbeHit { tip_center_mm: c.tip_center_mm, normal: Some(c.normal) })
            }
            None => {
                let _ = self.cmm.move_to(start, r);
                Err(DeviceError::NoContact { address: SIM_ADDRESS.into(), what: what() })
            }
        }
    }

    fn abort(&mut self) -> Result<(), DeviceError> {
        self.cmm.stop();
        Ok(())
    }
}

/// The task-specific uncertainty of one inspected hole (`somac inspect`), standard (k = 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoleUncertainty {
    /// Of the measured centre's X and Y (mm).
    pub center_xy_mm: [f64; 2],
    /// Of the measured diameter (mm).
    pub diameter_mm: f64,
}

/// The task-specific uncertainty of every hole of an inspection: the same plan simulated on
/// `mc.runs` realisations of the machine model with perfect bores (in a plate whose top is the
/// holes' top) at the measured centres and diameters.
pub fn inspection_uncertainty(
    model: &MachineModel,
    plan: &truepos_somac::inspect::InspectPlan,
    measured: &truepos_somac::inspect::Inspection,
    mc: MonteCarlo,
) -> Result<Vec<HoleUncertainty>> {
    use truepos_ippdme::part::CylinderSide;
    use truepos_somac::inspect::{inspect, Hole};
    mc.check()?;
    let holes: Vec<Hole> = measured.holes.iter().map(|r| r.hole.clone()).collect();
    let n = holes.len();
    // Perfect bores where they were found: centre at the probing depth, measured diameter.
    let perfect: Vec<(Point3, f64)> = measured.holes.iter().map(|r| (r.measured_mm, r.diameter_mm)).collect();
    let top = holes.iter().map(|h| h.nominal_mm.z).fold(f64::NEG_INFINITY, f64::max);
    // Per model: per run, per hole (dx, dy, dd).
    let mut per_model: Vec<Vec<Vec<[f64; 3]>>> = Vec::new();
    let deviations = |m: &truepos_somac::inspect::Inspection| -> Vec<[f64; 3]> {
        m.holes
            .iter()
            .zip(&perfect)
            .map(|(r, (c, d))| [r.measured_mm.x - c.x, r.measured_mm.y - c.y, r.diameter_mm - d])
            .collect()
    };
    if let Some(cfg) = &model.cmm {
        let mut solids =
            vec![(None, Solid::HalfSpace { point: Point3::new(0.0, 0.0, top), normal: Vector3::z() })];
        for (c, d) in &perfect {
            solids.push((
                None,
                Solid::Cylinder {
                    point: *c,
                    axis: Vector3::z(),
                    radius: 0.5 * d,
                    side: CylinderSide::Inside,
                    ends: None,
                },
            ));
        }
        let part = Part { solids };
        let runs = monte_carlo(mc, |seed| {
            let mut cfg = cfg.clone();
            cfg.model.seed = seed;
            let mut m = SimulatedCmm::new(&cfg, Some(part.clone()), plan.tip_radius_mm);
            let got = inspect(&mut m, &holes, plan).map_err(|e| {
                VcmmError::Failed(format!(
                    "task-specific uncertainty: a simulated machine could not inspect the holes ({e})"
                ))
            })?;
            Ok(deviations(&got))
        })?;
        per_model.push(runs);
    }
    if let Some(iso) = &model.iso10360 {
        per_model.push(monte_carlo(mc, |seed| iso_holes(iso, plan, &holes, &perfect, seed))?);
    }
    if per_model.is_empty() {
        return Err(VcmmError::Invalid("the machine model names no model".into()));
    }
    let mut out = vec![HoleUncertainty { center_xy_mm: [0.0; 2], diameter_mm: 0.0 }; n];
    for runs in &per_model {
        for (h, o) in out.iter_mut().enumerate() {
            let rms =
                |k: usize| (runs.iter().map(|r| r[h][k] * r[h][k]).sum::<f64>() / runs.len() as f64).sqrt();
            let fit = &measured.holes[h];
            // The measurement's own fit scatter is a cross-check (see the module docs): kept only
            // where it exceeds the simulation (then added in quadrature).
            let u = [
                rms(0).max(fit.center_uncertainty_mm[0]),
                rms(1).max(fit.center_uncertainty_mm[1]),
                rms(2).max(fit.diameter_uncertainty_mm),
            ];
            o.center_xy_mm = [o.center_xy_mm[0].max(u[0]), o.center_xy_mm[1].max(u[1])];
            o.diameter_mm = o.diameter_mm.max(u[2]);
        }
    }
    Ok(out)
}

/// One realisation of the ISO 10360 datasheet inspecting perfect bores (see [`iso_trial`]).
fn iso_holes(
    iso: &Iso10360,
    plan: &truepos_somac::inspect::InspectPlan,
    holes: &[truepos_somac::inspect::Hole],
    perfect: &[(Point3, f64)],
    seed: u64,
) -> Result<Vec<[f64; 3]>> {
    use rand::Rng;
    let mut rng = noise::rng(seed);
    let rel = 1e-3 / iso.mpe_e_k;
    let mut u = |h: f64| rng.random_range(-h..=h);
    let lin = Matrix3::new(u(rel), u(rel), u(rel), 0.0, u(rel), u(rel), 0.0, 0.0, u(rel));
    let half_p = 0.5 * iso.mpe_p_um * 1e-3;
    let origin = perfect.first().map_or(Point3::origin(), |p| p.0);
    holes
        .iter()
        .zip(perfect)
        .map(|(h, (c, d))| {
            let r_tip = 0.5 * d - plan.tip_radius_mm;
            let points: Vec<Point3> = plan
                .requests(h)
                .iter()
                .map(|req| {
                    // The probing moves outwards (−approach) onto the bore wall.
                    let e = -req.approach;
                    let p = c + e * r_tip;
                    p + lin * (p - origin) + e * u(half_p)
                })
                .collect();
            let f = truepos_fit::circle(&points)
                .map_err(|e| VcmmError::Failed(format!("ISO 10360 simulation: {e}")))?;
            Ok([f.center.x - c.x, f.center.y - c.y, 2.0 * (f.radius + plan.tip_radius_mm) - d])
        })
        .collect()
}

/// Run `trial` on `mc.runs` machine realisations in parallel; realisation r always gets the seed
/// `mc.seed_of(r)`, so the result does not depend on the threads (deterministic). The one Monte
/// Carlo loop of this module: every task-specific uncertainty goes through it.
pub fn monte_carlo<T, F>(mc: MonteCarlo, trial: F) -> Result<Vec<T>>
where
    T: Send,
    F: Fn(u64) -> Result<T> + Sync,
{
    mc.check()?;
    (0..mc.runs).into_par_iter().map(|r| trial(mc.seed_of(r))).collect()
}

/// One of the bases a machine-model file gives (a file may give both).
#[derive(Debug, Clone, Copy)]
pub enum Basis<'a> {
    /// The virtual CMM's error model (`[ippdme.model]`).
    ErrorModel(&'a MachineConfig),
    /// The ISO 10360 datasheet (`[iso10360]`).
    Iso10360(&'a Iso10360),
}

impl MachineModel {
    /// The bases of the file, each simulated on its own (with both, the larger u is kept: they
    /// describe the same machine).
    pub fn bases(&self) -> Vec<Basis<'_>> {
        let mut b = Vec::new();
        if let Some(c) = &self.cmm {
            b.push(Basis::ErrorModel(c));
        }
        if let Some(i) = &self.iso10360 {
            b.push(Basis::Iso10360(i));
        }
        b
    }
}

/// One machine drawn from one basis of the model, as the errors it adds to reported tip
/// centres: for the error model, the geometric map's error at the point (the scales read
/// `p − E(p)` where the tip touches at `p`), the probe's pre-travel left after its calibration
/// along the contact normal (lobing, or all of it uncompensated) and the touch noise; for the ISO
/// 10360 datasheet, linear scale and squareness errors about the first point probed and a uniform
/// probing error along the normal (as [`sphere_uncertainty`] draws them).
#[derive(Debug, Clone)]
pub struct PointErrors {
    kind: PointKind,
    rng: noise::SimRng,
    origin: Option<Point3>,
    seed: u64,
}

#[derive(Debug, Clone)]
enum PointKind {
    ErrorModel {
        field: Option<Box<truepos_plant::cmm::ErrorField>>,
        probe: Option<truepos_sim::touch::TouchProbe>,
        compensated: bool,
        sigma_mm: f64,
    },
    Iso {
        lin: Matrix3,
        half_p_mm: f64,
    },
}

impl PointErrors {
    /// The machine of realisation `seed` of `basis`.
    pub fn draw(basis: Basis<'_>, seed: u64) -> PointErrors {
        use rand::Rng;
        match basis {
            Basis::ErrorModel(cfg) => {
                let mut m = cfg.model.clone();
                m.seed = seed;
                let field = (m.geometric_errors && m.geometric_error_scale > 0.0).then(|| {
                    Box::new(truepos_plant::cmm::ErrorField::bridge_cmm(
                        &m,
                        cfg.volume_min_mm,
                        cfg.volume_max_mm,
                    ))
                });
                let probe = truepos_sim::touch::TouchProbe::new(0.0, m.pretravel_mm, m.lobing_mm).ok();
                PointErrors {
                    kind: PointKind::ErrorModel {
                        field,
                        probe,
                        compensated: m.pretravel_compensated,
                        sigma_mm: m.probe_noise_mm,
                    },
                    rng: noise::stream(seed, 11),
                    origin: None,
                    seed,
                }
            }
            Basis::Iso10360(iso) => {
                let mut rng = noise::rng(seed);
                let rel = 1e-3 / iso.mpe_e_k;
                let mut u = |h: f64| rng.random_range(-h..=h);
                let lin = Matrix3::new(u(rel), u(rel), u(rel), 0.0, u(rel), u(rel), 0.0, 0.0, u(rel));
                PointErrors {
                    kind: PointKind::Iso { lin, half_p_mm: 0.5 * iso.mpe_p_um * 1e-3 },
                    rng: noise::stream(seed, 12),
                    origin: None,
                    seed,
                }
            }
        }
    }

    /// The realisation's seed (for the other random parts of the same simulated machine).
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The error of the tip centre this machine reports for a contact at `p` with the outward
    /// surface normal `n` (unit).
    pub fn at(&mut self, p: &Point3, n: &Vector3) -> Vector3 {
        use rand::Rng;
        let origin = *self.origin.get_or_insert(*p);
        match &self.kind {
            PointKind::ErrorModel { field, probe, compensated, sigma_mm } => {
                let mut e = Vector3::zeros();
                if let Some(f) = field {
                    e -= f.at(p);
                }
                if let Some(pr) = probe {
                    let left = pr.pretravel(n) - if *compensated { pr.pretravel_mm } else { 0.0 };
                    e -= n * left;
                }
                if *sigma_mm > 0.0 {
                    e += noise::gaussian3(&mut self.rng, *sigma_mm);
                }
                e
            }
            PointKind::Iso { lin, half_p_mm } => {
                let h = *half_p_mm;
                lin * (p - origin) + n * self.rng.random_range(-h..=h)
            }
        }
    }
}

/// A machine that reports what `inner` touches with a realisation's errors ([`PointErrors`])
/// added to every probed tip centre: a perfect machine (or a machine tool's own model) made one
/// machine of the class the model describes.
pub struct ErrorOverlay<M> {
    /// The machine whose points are moved.
    pub inner: M,
    /// The errors added to every probed tip centre.
    pub errors: PointErrors,
}

impl<M: ProbingMachine> ProbingMachine for ErrorOverlay<M> {
    fn info(&self) -> DeviceInfo {
        self.inner.info()
    }
    fn position(&mut self) -> Result<Point3, DeviceError> {
        self.inner.position()
    }
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        self.inner.move_to(target_mm)
    }
    fn probe(&mut self, req: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        let mut hit = self.inner.probe(req)?;
        let n = hit.normal.filter(|v| v.norm() > 0.5).map_or(req.approach, |v| v.normalize());
        hit.tip_center_mm += self.errors.at(&hit.tip_center_mm, &n);
        Ok(hit)
    }
    fn abort(&mut self) -> Result<(), DeviceError> {
        self.inner.abort()
    }
    fn tool_names(&mut self) -> Result<Vec<String>, DeviceError> {
        self.inner.tool_names()
    }
    fn select_tool(&mut self, name: &str) -> Result<truepos_device::ToolInfo, DeviceError> {
        self.inner.select_tool(name)
    }
    fn rotary_axes(&self) -> truepos_device::RotaryAxes {
        self.inner.rotary_axes()
    }
    fn orient(&mut self, b_deg: f64, c_deg: f64) -> Result<(), DeviceError> {
        self.inner.orient(b_deg, c_deg)
    }
    fn orientation(&mut self) -> Result<(f64, f64), DeviceError> {
        self.inner.orientation()
    }
    fn set_move_speed(&mut self, mm_s: f64) -> Result<(), DeviceError> {
        self.inner.set_move_speed(mm_s)
    }
    fn rotary_kinematics(&self) -> Option<truepos_device::RotaryKinematics> {
        self.inner.rotary_kinematics()
    }
    fn kinematics_parameters(&mut self) -> Result<Vec<truepos_device::KinematicsParameter>, DeviceError> {
        self.inner.kinematics_parameters()
    }
    fn set_kinematics_parameters(
        &mut self,
        values: &[truepos_device::KinematicsParameter],
    ) -> Result<(), DeviceError> {
        self.inner.set_kinematics_parameters(values)
    }
}

/// The spread of a measurement's results over machines drawn from a model: per result
/// parameter, the root mean square deviation from the perfect result (the standard uncertainty
/// the simulation gives, bias included) and the mean deviation (the bias).
#[derive(Debug, Clone, PartialEq)]
pub struct Spread {
    /// RMS deviation per quantity (the standard uncertainty, bias included).
    pub rms: Vec<f64>,
    /// Mean deviation per quantity (the bias).
    pub mean: Vec<f64>,
    /// Realisations per basis.
    pub runs: usize,
    /// What the model was (for the output).
    pub basis: String,
    /// Wall time of the simulation (s).
    pub elapsed_s: f64,
}

/// The task-specific spread of any measurement: `trial` measures the perfect object with the
/// measurement's own strategy on the machine a [`PointErrors`] realisation describes and returns
/// its result parameters' deviations from the perfect ones. Run on `mc.runs` realisations of
/// every basis of `model` ([`monte_carlo`]); with both bases the larger spread per parameter.
pub fn simulate<F>(model: &MachineModel, mc: MonteCarlo, trial: F) -> Result<Spread>
where
    F: Fn(PointErrors) -> Result<Vec<f64>> + Sync,
{
    let t0 = std::time::Instant::now();
    let mut out: Option<Spread> = None;
    for basis in model.bases() {
        let runs = monte_carlo(mc, |seed| trial(PointErrors::draw(basis, seed)))?;
        let s = spread_of(&runs)?;
        out = Some(match out {
            None => s,
            Some(b) => Spread {
                rms: b.rms.iter().zip(&s.rms).map(|(x, y)| x.max(*y)).collect(),
                mean: b
                    .mean
                    .iter()
                    .zip(&s.mean)
                    .map(|(x, y)| if x.abs() >= y.abs() { *x } else { *y })
                    .collect(),
                ..b
            },
        });
    }
    let mut s = out.ok_or_else(|| VcmmError::Invalid("the machine model names no model".into()))?;
    s.runs = mc.runs;
    s.basis = model.basis();
    s.elapsed_s = t0.elapsed().as_secs_f64();
    Ok(s)
}

/// RMS and mean per parameter of deviation vectors (all of one length).
pub fn spread_of(runs: &[Vec<f64>]) -> Result<Spread> {
    let n = runs.first().map_or(0, Vec::len);
    if runs.is_empty() || runs.iter().any(|r| r.len() != n || r.iter().any(|v| !v.is_finite())) {
        return Err(VcmmError::Failed(
            "task-specific uncertainty: the simulated measurements did not give comparable results".into(),
        ));
    }
    let m = runs.len() as f64;
    let mean = (0..n).map(|k| runs.iter().map(|r| r[k]).sum::<f64>() / m).collect();
    let rms = (0..n).map(|k| (runs.iter().map(|r| r[k] * r[k]).sum::<f64>() / m).sqrt()).collect();
    Ok(Spread { rms, mean, runs: runs.len(), basis: String::new(), elapsed_s: 0.0 })
}

/// The task-specific uncertainty of a head offset acquired through a controller.
#[derive(Debug, Clone)]
pub struct HeadOffsetUncertainty {
    /// Standard uncertainty of each component of the offset (mm); `None` where the orientations
    /// do not determine it.
    pub offset_mm: [Option<f64>; 3],
    /// The simulation behind them (offset X, Y, Z; then the sphere centre X, Y, Z).
    pub spread: Spread,
}

/// What the simulated machines of a head-offset acquisition are besides the model's errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AcquiringMachine {
    /// A machine tool (LinuxCNC, the virtual machine tool): its probe input latched once per
    /// servo period (up to one servo step, feed × 1 ms, past the trigger), 0.5 µm pre-travel and
    /// 0.1 µm position noise, as the virtual machine tool's model.
    MachineTool,
    /// A CMM (I++ DME): contacts latched at the trigger; only the model's errors.
    Cmm,
}

/// The task-specific uncertainty of the head offset `measured` found (with `params`) from the
/// acquisition `acq`: the same acquisition (orientations, probing pattern, feed, clearance) run
/// on `mc.runs` machines drawn from `model` ([`ErrorOverlay`] on the virtual machine tool
/// carrying the measured offset and the sphere where it was found; for a machine tool with its
/// servo latch), the offset found from each as `truepos head-offset` finds it, u = the RMS
/// deviation from the measured one. Unobservable components stay unobservable (`None`).
pub fn head_offset_uncertainty(
    model: &MachineModel,
    acq: &truepos_head::acquire::HeadAcquisition,
    params: &truepos_head::Params,
    measured: &truepos_head::HeadOffset,
    machine: AcquiringMachine,
    mc: MonteCarlo,
) -> Result<HeadOffsetUncertainty> {
    use truepos_head::acquire::{acquire_head_offset, readings};
    use truepos_plant::probing::{HeadOffsetTruth, MachineToolConfig, VirtualMachineTool};
    acq.check().map_err(|e| VcmmError::Invalid(e.to_string()))?;
    let radius =
        measured.radius.map(|r| r - acq.sphere.tip_radius_mm).filter(|r| *r > 0.0).ok_or_else(|| {
            VcmmError::Invalid("the measured head offset has no positive sphere radius to simulate".into())
        })?;
    let truth = HeadOffsetTruth {
        offset_mm: measured.offset,
        sphere_centre_mm: measured.reference_point,
        sphere_radius_mm: radius,
    };
    let spread = simulate(model, mc, |errors| {
        let mut cfg = MachineToolConfig::with_head_offset(errors.seed(), acq, &truth);
        model.machine_tool.apply(&mut cfg);
        if machine == AcquiringMachine::Cmm {
            cfg.servo_period_s = 1e-9;
            cfg.position_sigma_mm = 0.0;
            cfg.pretravel_mm = 1e-9;
        }
        let inner = VirtualMachineTool::new(cfg).map_err(|e| VcmmError::Invalid(e.to_string()))?;
        let mut m = ErrorOverlay { inner, errors };
        let got = acquire_head_offset(&mut m, acq).map_err(|e| {
            VcmmError::Failed(format!(
                "task-specific uncertainty: a simulated machine could not acquire the sphere ({e})"
            ))
        })?;
        let r = truepos_head::solve(&readings(&got), params).map_err(|e| {
            VcmmError::Failed(format!(
                "task-specific uncertainty: a simulated acquisition gave no offset ({e})"
            ))
        })?;
        let d = r.offset - measured.offset;
        let c = r.reference_point - measured.reference_point;
        Ok(vec![d.x, d.y, d.z, c.x, c.y, c.z])
    })?;
    let offset_mm = std::array::from_fn(|k| measured.observable[k].then_some(spread.rms[k]));
    Ok(HeadOffsetUncertainty { offset_mm, spread })
}
