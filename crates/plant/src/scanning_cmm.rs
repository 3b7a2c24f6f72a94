//! The virtual scanning CMM behind [`truepos_device::ScanningMachine`]: servo dynamics of the
//! machine axes, a 3D spring-mass-damper stylus with contact and friction on the true (displaced)
//! part, encoder and probe noise.
//!
//! Entry points: [`CmmConfig`] (the plant: servo, stylus, noise, rates; `Default` is a bridge CMM
//! with a 15 Hz position loop), [`VirtualCmm::new`] with the true features, and [`run_scan`]
//! (plan → virtual CMM → `truepos_scan::execute::Run`, what the CLI, tests and demo call).
//!
//! The physics is integrated at `physics_dt_s` inside each control period. The stylus is
//! `truepos_sim::stylus::Stylus` against the surface of the feature being measured (transfers
//! touch nothing: their paths are collision-free by construction). The servo is the error model
//! of `truepos_sim::motion::Servo` (`ë + 2ζωė + ω²e = (1 − k_a)c̈`), integrated on line because
//! the command is not known in advance (it depends on the probe feedback and on where contact is
//! made).

use serde::Deserialize;
use std::path::Path;
use std::sync::Arc;
use truepos_device::{DeviceError, DeviceInfo, ScanCommand, ScanSample, ScanningMachine};
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};
use truepos_scan::execute::{ControlParams, Run};
use truepos_scan::{Feature, Plan, ScanError};
use truepos_sim::artefact::{Artefact, SurfacePoint};
use truepos_sim::motion::{Servo, State};
use truepos_sim::noise::{self, SimRng};
use truepos_sim::stylus::{Stylus, StylusParams};

const ADDRESS: &str = "virtual";

/// A true feature as an artefact for the stylus model: its unbounded surface (exact nearest
/// point for planes and cylinders).
#[derive(Debug)]
struct Surface(Feature);

impl Artefact for Surface {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        let (distance, normal) = self.0.signed_distance(p);
        SurfacePoint { distance, point: p - normal * distance, normal }
    }
}

/// Nothing to touch (transfers are collision-free by assumption).
#[derive(Debug)]
struct Clear;

impl Artefact for Clear {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        SurfacePoint { distance: 1e9, point: p - Vector3::z() * 1e9, normal: Vector3::z() }
    }
}

/// The virtual CMM's plant.
#[derive(Clone, Debug, PartialEq)]
pub struct CmmConfig {
    /// The servo loop of each axis.
    pub servo: Servo,
    /// Stylus dynamics and contact (`truepos_sim::stylus`); its tip radius is replaced by the
    /// one [`ScanningMachine::begin`] asks for.
    pub stylus: StylusParams,
    /// Standard deviation of the scale reading per axis (mm).
    pub encoder_noise_mm: f64,
    /// Standard deviation of the probe's deflection reading per axis (mm).
    pub probe_noise_mm: f64,
    /// Control period (s).
    pub control_dt_s: f64,
    /// Integration step of the physics (s), at most the control period.
    pub physics_dt_s: f64,
}

impl Default for CmmConfig {
    /// A bridge CMM position loop of 15 Hz, ζ = 0.6, 50 % acceleration feed-forward.
    fn default() -> Self {
        CmmConfig {
            servo: Servo { bandwidth_hz: 15.0, damping: 0.6, accel_feedforward: 0.5 },
            stylus: StylusParams::default(),
            encoder_noise_mm: 0.1e-3,
            probe_noise_mm: 0.2e-3,
            control_dt_s: 1e-3,
            physics_dt_s: 1e-4,
        }
    }
}

impl CmmConfig {
    /// Every parameter finite and in range; the error names the file key.
    pub fn check(&self) -> Result<(), ScanError> {
        self.stylus.validate().map_err(|e| ScanError::Invalid(format!("stylus: {e}")))?;
        let pos = [
            ("servo.bandwidth_hz", self.servo.bandwidth_hz),
            ("servo.damping", self.servo.damping),
            ("control_dt_s", self.control_dt_s),
            ("physics_dt_s", self.physics_dt_s),
        ];
        for (n, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(ScanError::Parameter(n, v));
            }
        }
        let nonneg = [("encoder_noise_mm", self.encoder_noise_mm), ("probe_noise_mm", self.probe_noise_mm)];
        for (n, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ScanError::Parameter(n, v));
            }
        }
        if !(0.0..=1.0).contains(&self.servo.accel_feedforward) {
            return Err(ScanError::Parameter("servo.accel_feedforward", self.servo.accel_feedforward));
        }
        if self.physics_dt_s > self.control_dt_s {
            return Err(ScanError::Invalid("physics_dt_s must not exceed control_dt_s".into()));
        }
        Ok(())
    }
}

/// Motion state between control periods.
struct Motion {
    stylus: Stylus,
    /// Following error per axis and its rate.
    e: Vector3,
    ed: Vector3,
    body_prev: State,
    /// The last two commands (for the command's velocity and acceleration over a period).
    c_prev: Point3,
    c_prev2: Point3,
}

/// The virtual CMM measuring a true part (one surface per planned feature, same order).
pub struct VirtualCmm {
    config: CmmConfig,
    truth: Vec<Arc<dyn Artefact>>,
    rng_encoder: SimRng,
    rng_probe: SimRng,
    motion: Option<Motion>,
}

impl VirtualCmm {
    /// A CMM measuring `truth`, its noise deterministic for `seed`.
    pub fn new(config: CmmConfig, truth: Vec<Feature>, seed: u64) -> Result<Self, ScanError> {
        let truth = truth.into_iter().map(|f| Arc::new(Surface(f)) as Arc<dyn Artefact>).collect();
        Self::with_surfaces(config, truth, seed)
    }

    /// A CMM whose feature `k` touches the artefact `truth[k]` (any surface: the I++ DME
    /// server's part, displaced by the machine's geometric errors).
    pub fn with_surfaces(
        config: CmmConfig,
        truth: Vec<Arc<dyn Artefact>>,
        seed: u64,
    ) -> Result<Self, ScanError> {
        config.check()?;
        Ok(VirtualCmm {
            config,
            truth,
            rng_encoder: noise::stream(seed, 1),
            rng_probe: noise::stream(seed, 2),
            motion: None,
        })
    }

    fn nsub(&self) -> usize {
        (self.config.control_dt_s / self.config.physics_dt_s).ceil().max(1.0) as usize
    }

    fn rejected(what: &str, message: String) -> DeviceError {
        DeviceError::Rejected { address: ADDRESS.into(), what: what.into(), message }
    }
}

impl ScanningMachine for VirtualCmm {
    fn info(&self) -> DeviceInfo {
        DeviceInfo {
            address: ADDRESS.into(),
            version: format!(
                "virtual CMM ({} Hz servo, ζ {})",
                self.config.servo.bandwidth_hz, self.config.servo.damping
            ),
        }
    }

    fn control_period_s(&self) -> f64 {
        self.config.control_dt_s
    }

    fn begin(&mut self, start_mm: Point3, tip_radius_mm: f64) -> Result<(), DeviceError> {
        let h = self.config.control_dt_s / self.nsub() as f64;
        let stylus = Stylus::new(StylusParams { tip_radius_mm, ..self.config.stylus }, h)
            .map_err(|e| Self::rejected("stylus", e.to_string()))?;
        self.motion = Some(Motion {
            stylus,
            e: Vector3::zeros(),
            ed: Vector3::zeros(),
            body_prev: State::rest(start_mm),
            c_prev: start_mm,
            c_prev2: start_mm,
        });
        Ok(())
    }

    fn follow(&mut self, command: &ScanCommand) -> Result<ScanSample, DeviceError> {
        let nsub = self.nsub();
        let dt = self.config.control_dt_s;
        let h = dt / nsub as f64;
        let w = 2.0 * std::f64::consts::PI * self.config.servo.bandwidth_hz;
        let (w2, two_zw, gain) =
            (w * w, 2.0 * self.config.servo.damping * w, 1.0 - self.config.servo.accel_feedforward);
        let surface = match command.feature {
            Some(k) => Some(self.truth.get(k).cloned().ok_or_else(|| {
                Self::rejected("scan", format!("feature {k} of a part with {} features", self.truth.len()))
            })?),
            None => None,
        };
        let art: &dyn Artefact = match &surface {
            Some(s) => s.as_ref(),
            None => &Clear,
        };
        let m = self.motion.as_mut().ok_or_else(|| Self::rejected("scan", "follow before begin".into()))?;
        let c = command.tip_center_mm;
        // the command ramps from the previous one to `c` over the period
        let cv = (c - m.c_prev) / dt;
        let ca = (c - m.c_prev * 2.0 + m.c_prev2.coords) / (dt * dt);
        for k in 0..nsub {
            let ck = m.c_prev + (c - m.c_prev) * ((k + 1) as f64 / nsub as f64);
            let edd = ca * gain - m.ed * two_zw - m.e * w2;
            m.ed += edd * h;
            m.e += m.ed * h;
            let body = State { p: ck - m.e, v: cv - m.ed, a: ca - edd };
            m.stylus.step(&m.body_prev, &body, art);
            m.body_prev = body;
        }
        let q = m.stylus.deflection();
        m.c_prev2 = m.c_prev;
        m.c_prev = c;
        let x = c - m.e;
        let qm = q + noise::gaussian3(&mut self.rng_probe, self.config.probe_noise_mm);
        let xm = x + noise::gaussian3(&mut self.rng_encoder, self.config.encoder_noise_mm);
        Ok(ScanSample { scale_mm: xm, deflection_mm: qm })
    }
}

/// Execute `plan` on a virtual CMM measuring `truth` (one true feature per planned feature, same
/// order). Deterministic for a seed.
pub fn run_scan(
    plan: &Plan,
    truth: &[Feature],
    cmm: &CmmConfig,
    control: &ControlParams,
    seed: u64,
) -> Result<Run, ScanError> {
    if truth.len() != plan.features.len() {
        return Err(ScanError::Invalid(format!(
            "{} true features for {} planned",
            truth.len(),
            plan.features.len()
        )));
    }
    let mut machine = VirtualCmm::new(cmm.clone(), truth.to_vec(), seed)?;
    truepos_scan::execute::execute(plan, &mut machine, control)
}

/// The machine file of `truepos scan run --machine` (TOML, every key optional):
/// `[servo] bandwidth_hz, damping, accel_feedforward`; `[stylus] natural_freq_hz = [x, y, z],
/// damping_ratio = [x, y, z], restitution, friction`; `encoder_noise_um`, `probe_noise_um`,
/// `feedback_gain_per_s`, `contact_threshold_mm`.
#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields)]
pub struct MachineFile {
    /// The `[servo]` table.
    pub servo: Option<ServoSection>,
    /// The `[stylus]` table.
    pub stylus: Option<StylusSection>,
    /// Standard deviation of the scale readings, µm.
    pub encoder_noise_um: Option<f64>,
    /// Standard deviation of the deflection readings, µm.
    pub probe_noise_um: Option<f64>,
    /// Observer gain of the scanning control, 1/s.
    pub feedback_gain_per_s: Option<f64>,
    /// Deflection that counts as contact, mm.
    pub contact_threshold_mm: Option<f64>,
}

/// `[servo]` of a [`MachineFile`].
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct ServoSection {
    /// Bandwidth of the position loop, Hz.
    pub bandwidth_hz: Option<f64>,
    /// Damping ratio of the position loop.
    pub damping: Option<f64>,
    /// Acceleration feed-forward factor (0 to 1).
    pub accel_feedforward: Option<f64>,
}

/// `[stylus]` of a [`MachineFile`].
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct StylusSection {
    /// Natural frequency of the stylus per axis, Hz.
    pub natural_freq_hz: Option<[f64; 3]>,
    /// Damping ratio of the stylus per axis.
    pub damping_ratio: Option<[f64; 3]>,
    /// Coefficient of restitution of a contact.
    pub restitution: Option<f64>,
    /// Coefficient of friction of a contact.
    pub friction: Option<f64>,
}

impl MachineFile {
    /// The default CMM and scanning control with the file's keys applied (µm → mm).
    pub fn apply(&self) -> (CmmConfig, ControlParams) {
        let mut m = CmmConfig::default();
        let mut c = ControlParams::default();
        if let Some(s) = &self.servo {
            let d = m.servo;
            m.servo = Servo {
                bandwidth_hz: s.bandwidth_hz.unwrap_or(d.bandwidth_hz),
                damping: s.damping.unwrap_or(d.damping),
                accel_feedforward: s.accel_feedforward.unwrap_or(d.accel_feedforward),
            };
        }
        if let Some(s) = &self.stylus {
            let d = m.stylus;
            m.stylus = StylusParams {
                natural_freq_hz: s.natural_freq_hz.unwrap_or(d.natural_freq_hz),
                damping_ratio: s.damping_ratio.unwrap_or(d.damping_ratio),
                restitution: s.restitution.unwrap_or(d.restitution),
                friction: s.friction.unwrap_or(d.friction),
                ..d
            };
        }
        if let Some(v) = self.encoder_noise_um {
            m.encoder_noise_mm = v * 1e-3;
        }
        if let Some(v) = self.probe_noise_um {
            m.probe_noise_mm = v * 1e-3;
        }
        if let Some(v) = self.feedback_gain_per_s {
            c.feedback_gain = v;
        }
        if let Some(v) = self.contact_threshold_mm {
            c.contact_threshold = v;
        }
        (m, c)
    }
}

/// Read and check a [`MachineFile`]: syntax errors and unknown keys name the file, line and
/// column; out-of-range values name the file and the key.
pub fn read_machine_file(path: &Path) -> Result<(CmmConfig, ControlParams), InputError> {
    let (file, doc): (MachineFile, _) = truepos_io::config::read_toml_doc(path)?;
    let (m, c) = file.apply();
    m.check().map_err(|e| doc.locate_error(InputError::in_file(path, e.to_string())))?;
    c.check().map_err(|e| doc.locate_error(InputError::in_file(path, e.to_string())))?;
    Ok((m, c))
}
