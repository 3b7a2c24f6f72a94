//! `truepos kinematics calibrate` as a library call: [`CalibrateRequest::check`] (before a
//! controller is opened: the plan and the observability of the orientations), then
//! [`calibrate`] (the configured geometry read from the controller, the sphere probed at every
//! orientation, the identification, and with `apply` the identified geometry written into the
//! running controller at B = C = 0 and, with `verify`, the sphere probed again at other
//! orientations). The result is a [`CalibrationReport`] (the contract's JSON and text).

use crate::acquire::{acquire, check_machine, KinematicsProbing};
use crate::identify::{check_orientations, identify, max_pairwise, Identification, Observation};
use crate::trt::{TrtGeometry, INI_KEYS, MODULE, PINS, PIN_FROM_THETA};
use std::path::PathBuf;
use thiserror::Error;
use truepos_device::{DeviceError, DeviceInfo, KinematicsParameter, ProbingMachine};
use truepos_head::acquire::{AcquireError, AcquiredOrientation};
use truepos_math::stats::COVERAGE_FACTOR;
use truepos_math::Point3;

/// The models `--model` knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// LinuxCNC's `xyzbc-trt-kins`: a B tilting table carrying a C rotary table.
    XyzbcTrt,
}

/// Why `maxkins` is refused (the recipe's measurement on LinuxCNC 2.9).
pub const MAXKINS_REFUSAL: &str =
    "maxkins is refused: in LinuxCNC 2.9 (and upstream master) its forward and \
inverse kinematics disagree when B ≠ 0 and C ≠ 0 — the inverse turns the head's B offset with C, the forward \
adds it unturned — so a probe latched at a combined B/C orientation is off by 2·L·sin B·sin(C/2), tens of mm \
for a usual pivot length; it also has a single geometry pin and its C axis fixed at X0 Y0. Run a kinematics \
whose forward and inverse agree (xyzbc-trt-kins)";

impl Model {
    /// The model called `name` on the command line (`xyzbc-trt`); `maxkins` and unknown names are refused.
    pub fn parse(name: &str) -> Result<Model, KinematicsError> {
        match name {
            "xyzbc-trt" | "xyzbc-trt-kins" => Ok(Model::XyzbcTrt),
            "maxkins" => Err(KinematicsError::Usage(format!("--model maxkins: {MAXKINS_REFUSAL}"))),
            other => Err(KinematicsError::Usage(format!(
                "--model `{other}`: truepos knows `xyzbc-trt` (LinuxCNC's xyzbc-trt-kins)"
            ))),
        }
    }

    /// The model's name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Model::XyzbcTrt => "xyzbc-trt",
        }
    }
}

/// Why a kinematics calibration failed; [`KinematicsError::is_user_input`] sorts exit 2 from 3.
#[derive(Debug, Error)]
pub enum KinematicsError {
    /// Bad options or plan (exit 2).
    #[error("{0}")]
    Usage(String),
    /// The orientations cannot determine a parameter (exit 2, before any motion).
    #[error("{0}")]
    NotDetermined(String),
    /// The machine failed or refused (exit 3).
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// Probing failed (exit 3; a plan error is exit 2).
    #[error(transparent)]
    Acquire(#[from] AcquireError),
    /// The points file could not be written.
    #[error(transparent)]
    Output(#[from] truepos_io::atomic::OutputError),
}

impl KinematicsError {
    /// Whether the user's input is the cause (exit 2) rather than the machine (exit 3).
    pub fn is_user_input(&self) -> bool {
        match self {
            KinematicsError::Usage(_) | KinematicsError::NotDetermined(_) => true,
            KinematicsError::Acquire(AcquireError::Plan(_)) => true,
            KinematicsError::Output(o) => o.is_path(),
            _ => false,
        }
    }
}

/// Everything `truepos kinematics calibrate` is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateRequest {
    /// The machine's kinematics model.
    pub model: Model,
    /// How the reference sphere is probed at each orientation.
    pub probing: KinematicsProbing,
    /// Write the identified geometry into the running controller.
    pub apply: bool,
    /// After applying, probe again at these orientations and report the spread.
    pub verify: Option<Vec<[f64; 2]>>,
    /// The latched points (`b_deg,c_deg,x_mm,y_mm,z_mm,group`).
    pub output: Option<PathBuf>,
}

impl CalibrateRequest {
    /// Everything that can be checked before a controller is opened.
    pub fn check(&self) -> Result<(), KinematicsError> {
        self.probing.check().map_err(|e| KinematicsError::Usage(e.to_string()))?;
        if let Err(e) = check_orientations(&self.probing.orientations) {
            return Err(KinematicsError::NotDetermined(e.message));
        }
        if let Some(v) = &self.verify {
            if !self.apply {
                return Err(KinematicsError::Usage(
                    "--verify checks the applied geometry: it needs --apply".into(),
                ));
            }
            let p = KinematicsProbing { orientations: v.clone(), ..self.probing.clone() };
            p.check().map_err(|e| KinematicsError::Usage(format!("verification: {e}")))?;
            if v.len() < 2 {
                return Err(KinematicsError::Usage("verification needs at least two orientations".into()));
            }
        }
        if let Some(o) = &self.output {
            truepos_io::atomic::check_output_path(o)?;
        }
        Ok(())
    }
}

/// The default verification orientations for a calibration whose largest |B| is `b_max`
/// (sign as used): B = C = 0 and four others at C angles the calibration set rarely uses.
pub fn default_verify_orientations(calibration: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let b_max = calibration.iter().map(|o| o[0]).fold(0.0, |m: f64, b| if b.abs() > m.abs() { b } else { m });
    vec![[0.0, 0.0], [0.0, 60.0], [0.5 * b_max, 180.0], [b_max, 300.0], [0.5 * b_max, 30.0]]
}

/// One identified parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterResult {
    /// The kinematics module's pin name (`x-rot-point`, ...).
    pub name: String,
    /// The value the controller was configured with, mm.
    pub configured_mm: f64,
    /// The identified value, mm.
    pub identified_mm: f64,
    /// Standard uncertainty (k = 1).
    pub uncertainty_mm: f64,
    /// Expanded uncertainty for about 95 % coverage where a simulation gives its distribution
    /// (task-specific: the 95th percentile of the simulated |deviation|, JCGM 101); `None`: k·u
    /// with k = 2.
    pub expanded_mm: Option<f64>,
}

impl ParameterResult {
    /// U: the simulation's 95 % interval half-width, else k·u (k = 2).
    pub fn expanded(&self) -> f64 {
        self.expanded_mm.unwrap_or(COVERAGE_FACTOR * self.uncertainty_mm)
    }
}

/// The re-probing after the write-back.
#[derive(Debug, Clone, PartialEq)]
pub struct Verification {
    /// The sphere centres measured at the orientations after the write-back.
    pub acquired: Vec<AcquiredOrientation>,
    /// Largest distance between two centres, mm.
    pub spread_mm: f64,
    /// Largest distance of a centre from their mean, mm.
    pub max_from_mean_mm: f64,
}

/// What [`calibrate`] hands back.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationReport {
    /// The kinematics model calibrated.
    pub model: Model,
    /// The geometry the controller had before the calibration, mm.
    pub configured: TrtGeometry,
    /// The identified (true) geometry, mm.
    pub identified: TrtGeometry,
    /// Each identified pin with its configured value and uncertainty.
    pub parameters: Vec<ParameterResult>,
    /// The sphere centres measured at the calibration orientations.
    pub acquired: Vec<AcquiredOrientation>,
    /// The least-squares identification (axis errors, residuals, statistics).
    pub identification: Identification,
    /// Largest distance between two measured centres before the write-back, mm.
    pub spread_before_mm: f64,
    /// Whether the identified geometry was written into the controller.
    pub applied: bool,
    /// The re-probing after the write-back, when it was done.
    pub verification: Option<Verification>,
    /// The controller the calibration ran on.
    pub device: DeviceInfo,
    /// Wall time of the probing at the calibration orientations (s), and per orientation.
    pub acquisition_s: f64,
    /// The points file written, if one was asked for.
    pub output: Option<PathBuf>,
    /// For a virtual machine: its true geometry and sphere centre (set by the caller).
    pub truth: Option<(TrtGeometry, Point3)>,
    /// How the parameters' uncertainties were found: `fit-residuals` (the identification's
    /// own, what [`calibrate`] gives) or `task-specific` (set by the caller after a simulation
    /// on the machine's model), with the realisations and what the model was.
    pub uncertainty: UncertaintyBasis,
}

/// The basis of a calibration's stated uncertainties.
#[derive(Debug, Clone, PartialEq)]
pub struct UncertaintyBasis {
    /// `fit-residuals` or `task-specific`.
    pub method: String,
    /// Monte Carlo realisations behind task-specific uncertainties (0 for `fit-residuals`).
    pub monte_carlo_runs: usize,
    /// What the uncertainties rest on, as a sentence for the report.
    pub basis: String,
}

impl Default for UncertaintyBasis {
    fn default() -> Self {
        UncertaintyBasis {
            method: "fit-residuals".into(),
            monte_carlo_runs: 0,
            basis: "the scatter of the sphere centres about the identified model (the machine's other errors are not included)".into(),
        }
    }
}

fn fmt6(v: f64) -> String {
    let s = format!("{v:.6}");
    if s == "-0.000000" {
        "0.000000".into()
    } else {
        s
    }
}

/// Round to 1 nm (what is written and printed).
fn nm(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

impl CalibrationReport {
    /// The centres as measured.
    pub fn centres(&self) -> Vec<Point3> {
        self.acquired.iter().map(|o| o.sphere.center_mm).collect()
    }

    /// The HAL lines that set the identified values (for a HAL file).
    pub fn hal_lines(&self) -> Vec<String> {
        self.parameters
            .iter()
            .map(|p| format!("setp {MODULE}.{} {}", p.name, fmt6(p.identified_mm)))
            .collect()
    }

    /// The INI lines that make the change permanent: the recipe's `[KINS]` keys, which the HAL
    /// file passes to the pins (`setp xyzbc-trt-kins.x-rot-point [KINS]X_ROT_POINT`).
    pub fn ini_lines(&self) -> Vec<String> {
        let mut v = vec!["[KINS]".to_string()];
        for p in &self.parameters {
            if let Some(k) = PINS.iter().position(|n| *n == p.name) {
                v.push(format!("{} = {}", INI_KEYS[k], fmt6(p.identified_mm)));
            }
        }
        v
    }

    /// Mean probing time per calibration orientation, s.
    pub fn time_per_orientation_s(&self) -> f64 {
        self.acquisition_s / self.acquired.len().max(1) as f64
    }
}

fn verification(acquired: Vec<AcquiredOrientation>) -> Verification {
    let c: Vec<Point3> = acquired.iter().map(|o| o.sphere.center_mm).collect();
    let mean = truepos_math::centroid(&c);
    let max_from_mean_mm = c.iter().map(|p| (p - mean).norm()).fold(0.0, f64::max);
    Verification { spread_mm: max_pairwise(&c), max_from_mean_mm, acquired }
}

/// The points file: `b_deg,c_deg,x_mm,y_mm,z_mm,group` (programme frame).
pub fn points_csv(acquired: &[AcquiredOrientation]) -> String {
    truepos_head::acquire::points_csv(acquired)
}

/// Run the calibration on `m` (see the module docs). `progress(k, n, what)` is told about each
/// orientation probed.
pub fn calibrate<M: ProbingMachine + ?Sized>(
    m: &mut M,
    req: &CalibrateRequest,
    mut progress: impl FnMut(&str),
) -> Result<CalibrationReport, KinematicsError> {
    req.check()?;
    check_machine(m, req.model.name())?;
    let params = m.kinematics_parameters()?;
    let configured = TrtGeometry::from_parameters(&params).map_err(|e| DeviceError::Protocol {
        address: m.info().address,
        what: "reading the kinematics parameters".into(),
        message: e,
    })?;
    let n = req.probing.orientations.len();
    let t0 = std::time::Instant::now();
    let acquired = acquire(m, &req.probing, |k, o| {
        progress(&format!(
            "orientation {}/{n}: B {}° C {}°: centre {:.4} {:.4} {:.4} mm ({:.1} s)",
            k + 1,
            o.b_deg,
            o.c_deg,
            o.sphere.center_mm.x,
            o.sphere.center_mm.y,
            o.sphere.center_mm.z,
            t0.elapsed().as_secs_f64()
        ))
    })?;
    let acquisition_s = t0.elapsed().as_secs_f64();
    if let Some(path) = &req.output {
        truepos_io::atomic::write_atomic(path, points_csv(&acquired).as_bytes())?;
    }
    let obs: Vec<Observation> = acquired
        .iter()
        .map(|o| Observation {
            b_deg: o.b_deg,
            c_deg: o.c_deg,
            centre_mm: o.sphere.center_mm,
            centre_uncertainty_mm: o.sphere.center_uncertainty_mm,
        })
        .collect();
    let id = identify(&obs).map_err(|e| KinematicsError::NotDetermined(e.message))?;
    let corrected = configured.corrected(&id.theta_mm);
    let identified = TrtGeometry::from_values(corrected.values().map(nm));
    let parameters: Vec<ParameterResult> = PIN_FROM_THETA
        .iter()
        .zip(&id.pins)
        .map(|((name, _), pin)| {
            let k = PINS.iter().position(|p| p == name).unwrap_or(0);
            ParameterResult {
                name: name.to_string(),
                configured_mm: configured.values()[k],
                identified_mm: identified.values()[k],
                uncertainty_mm: pin.uncertainty_mm,
                expanded_mm: None,
            }
        })
        .collect();
    let spread_before_mm = max_pairwise(&obs.iter().map(|o| o.centre_mm).collect::<Vec<_>>());
    let mut applied = false;
    let mut verification_result = None;
    if req.apply {
        let values: Vec<KinematicsParameter> = parameters
            .iter()
            .map(|p| KinematicsParameter { name: p.name.clone(), value_mm: p.identified_mm })
            .collect();
        progress("writing the identified geometry into the controller (at B = C = 0)");
        m.set_kinematics_parameters(&values)?;
        applied = true;
        if let Some(v) = &req.verify {
            let plan = KinematicsProbing { orientations: v.clone(), ..req.probing.clone() };
            let nv = v.len();
            let t1 = std::time::Instant::now();
            let again = acquire(m, &plan, |k, o| {
                progress(&format!(
                    "verification {}/{nv}: B {}° C {}°: centre {:.4} {:.4} {:.4} mm ({:.1} s)",
                    k + 1,
                    o.b_deg,
                    o.c_deg,
                    o.sphere.center_mm.x,
                    o.sphere.center_mm.y,
                    o.sphere.center_mm.z,
                    t1.elapsed().as_secs_f64()
                ))
            })?;
            verification_result = Some(verification(again));
        }
    }
    Ok(CalibrationReport {
        model: req.model,
        configured,
        identified,
        parameters,
        acquired,
        identification: id,
        spread_before_mm,
        applied,
        verification: verification_result,
        device: m.info(),
        acquisition_s,
        output: req.output.clone(),
        truth: None,
        uncertainty: UncertaintyBasis::default(),
    })
}

fn v3(p: &Point3) -> serde_json::Value {
    serde_json::json!([p.x, p.y, p.z])
}

impl truepos_io::report::Report for CalibrationReport {
    fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let id = &self.identification;
        let mut j = json!({
            "model": self.model.name(),
            "module": MODULE,
            "parameters": self.parameters.iter().map(|p| json!({
                "name": p.name,
                "configured": p.configured_mm,
                "identified": p.identified_mm,
                "change": p.identified_mm - p.configured_mm,
                "uncertainty": p.uncertainty_mm,
                "expanded_uncertainty": p.expanded(),
                "coverage_factor": p.expanded() / p.uncertainty_mm,
            })).collect::<Vec<_>>(),
            "unchanged": [{
                "name": "z-rot-point",
                "configured": self.configured.z_rot_point,
                "reason": "only z-rot-point + z-offset is observable; the change goes into z-offset",
            }],
            "centres_mm": self.centres().iter().map(v3).collect::<Vec<_>>(),
            "orientations": self.acquired.iter().zip(&id.residuals_mm).map(|(o, r)| json!({
                "b_deg": o.b_deg,
                "c_deg": o.c_deg,
                "center_mm": v3(&o.sphere.center_mm),
                "radius_mm": o.sphere.radius_mm,
                "rms_mm": o.sphere.rms_mm,
                "n_points": o.sphere.points.len(),
                "residual_mm": [r.x, r.y, r.z],
            })).collect::<Vec<_>>(),
            "sphere_center_mm": v3(&id.sphere_centre_mm),
            "spread_before_mm": self.spread_before_mm,
            "spread_after_predicted_mm": id.spread_after_predicted_mm(),
            "residual_rms_mm": id.rms_mm,
            "centre_sigma_mm": id.sigma_mm,
            "degrees_of_freedom": id.dof,
            "applied": self.applied,
            "ini_lines": self.ini_lines(),
            "hal_lines": self.hal_lines(),
            "coverage_factor": COVERAGE_FACTOR,
            "uncertainty_method": self.uncertainty.method,
            "monte_carlo_runs": self.uncertainty.monte_carlo_runs,
            "uncertainty_basis": self.uncertainty.basis,
            "controller": { "address": self.device.address, "version": self.device.version },
            "acquisition_s": self.acquisition_s,
            "time_per_orientation_s": self.time_per_orientation_s(),
            "output": self.output.as_ref().map(|p| p.display().to_string()),
            "verify": self.verification.as_ref().map(|v| json!({
                "orientations": v.acquired.iter().map(|o| json!({
                    "b_deg": o.b_deg,
                    "c_deg": o.c_deg,
                    "center_mm": v3(&o.sphere.center_mm),
                    "radius_mm": o.sphere.radius_mm,
                    "rms_mm": o.sphere.rms_mm,
                })).collect::<Vec<_>>(),
                "centres_mm": v.acquired.iter().map(|o| v3(&o.sphere.center_mm)).collect::<Vec<_>>(),
                "spread_mm": v.spread_mm,
                "max_from_mean_mm": v.max_from_mean_mm,
            })),
        });
        if let Some((g, s)) = &self.truth {
            j["virtual_truth"] = json!({
                "parameters": PINS.iter().zip(g.values()).map(|(n, v)| json!({"name": n, "value": v})).collect::<Vec<_>>(),
                "sphere_center_mm": v3(s),
            });
        }
        j
    }

    fn text(&self) -> String {
        let id = &self.identification;
        let mut s = format!(
            "{} kinematics ({MODULE}) on {} ({}): {} orientations in {:.1} s ({:.1} s each)\n",
            self.model.name(),
            self.device.address,
            self.device.version,
            self.acquired.len(),
            self.acquisition_s,
            self.time_per_orientation_s()
        );
        for (o, r) in self.acquired.iter().zip(&id.residuals_mm) {
            let c = o.sphere.center_mm;
            s += &format!(
                "  B {:>7.3}° C {:>8.3}°: centre {:.4} {:.4} {:.4} mm, rms {:.4} mm, residual {:.1} µm\n",
                o.b_deg,
                o.c_deg,
                c.x,
                c.y,
                c.z,
                o.sphere.rms_mm,
                r.norm() * 1e3
            );
        }
        s += &format!(
            "centre spread {:.1} µm as configured, {:.1} µm predicted with the identified geometry\n",
            self.spread_before_mm * 1e3,
            id.spread_after_predicted_mm() * 1e3
        );
        s += &format!(
            "{:<12} {:>14} {:>14} {:>10} {:>12}\n",
            "parameter", "configured mm", "identified mm", "change µm", "U (k=2) µm"
        );
        for p in &self.parameters {
            s += &format!(
                "{:<12} {:>14.6} {:>14.6} {:>10.1} {:>12.1}\n",
                p.name,
                p.configured_mm,
                p.identified_mm,
                (p.identified_mm - p.configured_mm) * 1e3,
                p.expanded() * 1e3
            );
        }
        s += "z-rot-point is not observable on its own: its share of the Z change is in z-offset\n";
        s += &format!(
            "uncertainty: {} ({}{})\n",
            self.uncertainty.method,
            self.uncertainty.basis,
            if self.uncertainty.monte_carlo_runs > 0 {
                format!(", {} machine realisations", self.uncertainty.monte_carlo_runs)
            } else {
                String::new()
            }
        );
        if self.applied {
            s += "applied: the identified values are in the running controller (until it restarts)\n";
        } else {
            s += "dry run: nothing was written (--apply writes the values into the running controller)\n";
        }
        s += "to make it permanent, in the INI file (if the HAL file sets the pins from these keys):\n";
        for l in self.ini_lines() {
            s += &format!("  {l}\n");
        }
        s += "or in the HAL file:\n";
        for l in self.hal_lines() {
            s += &format!("  {l}\n");
        }
        if let Some(v) = &self.verification {
            s += &format!(
                "verification at {} other orientations: centre spread {:.1} µm (largest from the mean {:.1} µm)\n",
                v.acquired.len(),
                v.spread_mm * 1e3,
                v.max_from_mean_mm * 1e3
            );
        }
        if let Some((g, c)) = &self.truth {
            let (a, b) = (self.identified.axes(), g.axes());
            s += &format!(
                "virtual truth: axes identified − true = C x {:.2} y {:.2}, B x {:.2} z {:.2} µm; sphere {:.4} {:.4} {:.4} mm\n",
                (a[0] - b[0]) * 1e3,
                (a[1] - b[1]) * 1e3,
                (a[2] - b[2]) * 1e3,
                (a[3] - b[3]) * 1e3,
                c.x,
                c.y,
                c.z
            );
        }
        s
    }
}

impl truepos_math::exit::HasExitClass for KinematicsError {
    /// [`KinematicsError::is_user_input`]: the user's (2), else the machine's (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        if self.is_user_input() {
            ExitClass::Usage
        } else {
            ExitClass::Device
        }
    }
}
