//! The `latency` scenario: a scanning probe on a machine touches an artefact at known speeds while
//! the machine-position stream and the probe-deflection stream are captured on one master clock,
//! each with its own capture latency, rate and noise. Pure: returns a [`Dataset`]; the binary
//! writes `machine.csv` (`t_s,x_mm,y_mm,z_mm`), `probe.csv` (`t_s,a_mm,b_mm,c_mm`) and
//! `truth.json`.
//!
//! **Truth and sign convention** (interface contract, "System delay"): a channel stamps a sample
//! with its true time plus its capture latency ([`crate::capture`]), so
//! `delay_s = machine latency − probe latency`, and the stylus centre at probe stamp `t` is
//! `machine_position(t + delay_s) + deflection(t)`. With per-axis machine latencies, axis `i`
//! has delay `per_axis_delay_s[i]` and `delay_s` is their mean.
//!
//! **Physics.** The commanded body path ([`crate::motion::Trajectory`]) goes through a servo with
//! following error ([`crate::motion::ServoMotion`]); the stylus is a spring-mass-damper with
//! contact, restitution and friction ([`crate::stylus`]), integrated at ≥ 40 kHz on sub-steps of
//! the probe's sample grid; the artefact contact is exact ([`crate::artefact`]). Each contact:
//! from a stand-off point the body moves along the approach direction at the contact speed `v`
//! (reached before the contact), into the surface until the normal deflection reaches
//! `max_deflection_mm`, dwells, and retracts at the same speed, so that during the constant-speed
//! retract the deflection falls linearly with body position (extrapolation to zero deflection
//! gives the contact point). In free air the body accelerates at `accel_mm_s2` (transfers are
//! also jerk-limited), so the inertial deflection of the stylus stays near `a/ω²` ≈ 1 µm, well
//! below contact-detection thresholds; inside a contact the deceleration to the deepest point
//! and the acceleration away from it are `contact_accel_mm_s2`, raised where needed so each
//! takes at most a quarter of the in-contact travel: `a ≥ 2v²/travel`. After the release the stylus rings with amplitude
//! ≈ `v/ω` (physical; it follows the contact immediately).
//!
//! Entry points: [`Variant`] (sphere, plates, speeds, scan, in-out, per-axis, multi-rate,
//! oblique), [`Config::preset`] (realistic defaults for a variant; every field may then be
//! changed), [`simulate`] → [`Dataset`] (`machine`, `probe`, `probe_in_contact`, `truth`:
//! [`Truth`] with [`ArtefactTruth`] and the [`ContactTruth`] list).

use serde::Serialize;
use truepos_math::{Point3, Vector3};

use crate::artefact::{Artefact, Plates, Sphere};
use crate::capture::{AxisCapture, Capture, MasterClock};
use crate::motion::{Limits, Motion, Profile, Servo, ServoMotion, State, Trajectory};
use crate::noise::{gaussian3, stream, ParamError};
use crate::stylus::{self, StylusParams};

/// Largest number of samples per stream a configuration may ask for.
pub const MAX_SAMPLES: f64 = 50_000_000.0;

/// Invalid configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LatencyError {
    /// A setting is invalid.
    #[error("invalid latency scenario setting {name}: {reason}")]
    Invalid {
        /// The setting.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// A model parameter is invalid.
    #[error(transparent)]
    Param(#[from] ParamError),
}

fn invalid(name: &'static str, reason: impl Into<String>) -> LatencyError {
    LatencyError::Invalid { name, reason: reason.into() }
}

/// What the data set exercises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Variant {
    /// Five points (±X, ±Y, +Z) on a sphere of known diameter at one speed.
    Sphere,
    /// Both inner faces of a pair of parallel plates of known gap at one speed.
    Plates,
    /// The five sphere points at each of several speeds (size treated as unknown).
    Speeds,
    /// Continuous scan around the sphere's equator, the path switching between two radii at
    /// sections of different angular length.
    Scan,
    /// One point (+X of the sphere), driven in and out.
    #[serde(rename = "inout")]
    InOut,
    /// The five sphere points with a different capture latency per machine axis.
    PerAxis,
    /// The five sphere points with the streams at different rates (machine 1 kHz, probe 4 kHz).
    MultiRate,
    /// The five sphere points approached at an angle to the surface normal.
    Oblique,
}

impl Variant {
    /// Every variant.
    pub const ALL: [Variant; 8] = [
        Variant::Sphere,
        Variant::Plates,
        Variant::Speeds,
        Variant::Scan,
        Variant::InOut,
        Variant::PerAxis,
        Variant::MultiRate,
        Variant::Oblique,
    ];

    /// Its command-line name.
    pub fn name(&self) -> &'static str {
        match self {
            Variant::Sphere => "sphere",
            Variant::Plates => "plates",
            Variant::Speeds => "speeds",
            Variant::Scan => "scan",
            Variant::InOut => "inout",
            Variant::PerAxis => "per-axis",
            Variant::MultiRate => "multi-rate",
            Variant::Oblique => "oblique",
        }
    }

    /// Parse a command-line name.
    pub fn parse(s: &str) -> Option<Variant> {
        Variant::ALL.into_iter().find(|v| v.name() == s)
    }
}

/// Everything a user may vary (mm, s, Hz; angles in degrees as named).
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Which data set to make.
    pub variant: Variant,
    /// Seed of the noise.
    pub seed: u64,
    /// Machine position sampling rate, Hz.
    pub machine_rate_hz: f64,
    /// Probe deflection sampling rate, Hz.
    pub probe_rate_hz: f64,
    /// Machine position capture latency (s), all axes.
    pub machine_latency_s: f64,
    /// Per-axis machine latencies (s); overrides `machine_latency_s` when set.
    pub axis_latency_s: Option<[f64; 3]>,
    /// Probe deflection capture latency (s).
    pub probe_latency_s: f64,
    /// Encoder noise, 1σ per axis (mm).
    pub encoder_noise_mm: f64,
    /// Probe noise, 1σ per component (mm).
    pub probe_noise_mm: f64,
    /// Stylus (tip radius, dynamics, restitution, friction).
    pub stylus: StylusParams,
    /// Internal stylus integration rate, at least (Hz).
    pub stylus_rate_hz: f64,
    /// Servo following-error model; `None` for perfect tracking.
    pub servo: Option<Servo>,
    /// Centre of the reference sphere, mm.
    pub sphere_centre_mm: Point3,
    /// Diameter of the reference sphere, mm.
    pub sphere_diameter_mm: f64,
    /// Middle of the plate gap; the faces are at ±gap/2 along X.
    pub plates_mid_mm: Point3,
    /// Gap between the plates, mm.
    pub plate_gap_mm: f64,
    /// Contact speed (mm/s) of the single-speed variants and of the scan.
    pub speed_mm_s: f64,
    /// Contact speeds of the `speeds` variant (mm/s).
    pub speeds_mm_s: Vec<f64>,
    /// Normal deflection at the deepest point of a contact (mm).
    pub max_deflection_mm: f64,
    /// Distance from the touching position at which a contact move starts (mm); raised where
    /// needed so the contact speed is reached before the contact.
    pub standoff_mm: f64,
    /// Acceleration of the moves in free air (mm/s²). Inside a contact the deceleration to the
    /// deepest point and the acceleration away from it are raised where needed (see the module
    /// docs).
    pub accel_mm_s2: f64,
    /// Least acceleration inside a contact (mm/s²): deceleration to the deepest point and
    /// acceleration away from it (raised further where needed, see the module docs).
    pub contact_accel_mm_s2: f64,
    /// Jerk limit of the rest-to-rest transfer moves and of the scan's approach and retract
    /// (mm/s³); `None` for trapezoidal moves.
    pub jerk_mm_s3: Option<f64>,
    /// Speed of the transfer moves, mm/s.
    pub transfer_speed_mm_s: f64,
    /// Dwell at the deepest point of a contact (s).
    pub dwell_s: f64,
    /// Angle between the approach direction and the surface normal (`oblique`), degrees.
    pub approach_angle_deg: f64,
    /// How many times the contact pattern (or scan revolution) is repeated.
    pub repeats: usize,
    /// The two deflections of the scan path (mm): the path radius is `R + r − deflection`.
    pub scan_deflections_mm: [f64; 2],
    /// Angular lengths of the scan sections of one revolution (deg, summing to 360); the
    /// deflection alternates between the two levels from section to section.
    pub scan_sections_deg: Vec<f64>,
    /// Angular length of each raised-cosine switch between the two radii (deg).
    pub scan_transition_deg: f64,
}

impl Default for Config {
    fn default() -> Self {
        Config::preset(Variant::Sphere)
    }
}

impl Config {
    /// Realistic defaults for a variant: 1 kHz streams (probe 4 kHz for `multi-rate`), machine
    /// latency 4 ms, probe latency 1.5 ms (delay +2.5 ms; per-axis 4 / 2.5 / 1 ms machine
    /// latencies for `per-axis`), encoder noise 1 µm, probe noise 0.3 µm, stylus dynamics on,
    /// servo on, 1000 mm/s² and 10 000 mm/s³ in free air, 2000 mm/s² in contact, transfers at
    /// 50 mm/s, Ø 25 mm
    /// sphere, 20 mm plate gap, 2 mm tip radius, 10 mm/s (speeds 5, 10, 20,
    /// 30, 40 mm/s), 0.3 mm maximum deflection, 20 ms dwell at the deepest point (none for
    /// `inout`), 30° approach angle for `oblique`.
    pub fn preset(variant: Variant) -> Self {
        let mut c = Config {
            variant,
            seed: 1,
            machine_rate_hz: 1000.0,
            probe_rate_hz: 1000.0,
            machine_latency_s: 0.004,
            axis_latency_s: None,
            probe_latency_s: 0.0015,
            encoder_noise_mm: 0.001,
            probe_noise_mm: 0.0003,
            stylus: StylusParams::default(),
            stylus_rate_hz: 40_000.0,
            servo: Some(Servo::default()),
            sphere_centre_mm: Point3::new(250.0, 150.0, 80.0),
            sphere_diameter_mm: 25.0,
            plates_mid_mm: Point3::new(300.0, 200.0, 60.0),
            plate_gap_mm: 20.0,
            speed_mm_s: 10.0,
            speeds_mm_s: vec![5.0, 10.0, 20.0, 30.0, 40.0],
            max_deflection_mm: 0.3,
            standoff_mm: 1.0,
            accel_mm_s2: 1000.0,
            contact_accel_mm_s2: 2000.0,
            jerk_mm_s3: Some(10_000.0),
            transfer_speed_mm_s: 50.0,
            dwell_s: 0.02,
            approach_angle_deg: 0.0,
            repeats: 1,
            scan_deflections_mm: [0.1, 0.3],
            scan_sections_deg: vec![40.0, 75.0, 25.0, 90.0, 55.0, 75.0],
            scan_transition_deg: 4.0,
        };
        match variant {
            Variant::PerAxis => c.axis_latency_s = Some([0.004, 0.0025, 0.001]),
            Variant::MultiRate => c.probe_rate_hz = 4000.0,
            Variant::Oblique => c.approach_angle_deg = 30.0,
            // No dwell at the deepest point: the extremum of both streams is then sharp.
            Variant::InOut => c.dwell_s = 0.0,
            _ => {}
        }
        c
    }

    /// Machine capture latency per axis (s).
    pub fn machine_latencies(&self) -> [f64; 3] {
        self.axis_latency_s.unwrap_or([self.machine_latency_s; 3])
    }

    fn validate(&self) -> Result<(), LatencyError> {
        use crate::noise::{check_finite, check_nonneg, check_positive};
        check_positive("machine rate", self.machine_rate_hz)?;
        check_positive("probe rate", self.probe_rate_hz)?;
        for l in self.machine_latencies() {
            check_finite("machine latency", l)?;
        }
        check_finite("probe latency", self.probe_latency_s)?;
        check_nonneg("encoder noise", self.encoder_noise_mm)?;
        check_nonneg("probe noise", self.probe_noise_mm)?;
        self.stylus.validate()?;
        check_positive("stylus rate", self.stylus_rate_hz)?;
        if self.stylus_rate_hz > 1e7 {
            return Err(invalid("stylus rate", "must be at most 10 MHz"));
        }
        check_positive("sphere diameter", self.sphere_diameter_mm)?;
        check_positive("plate gap", self.plate_gap_mm)?;
        check_positive("speed", self.speed_mm_s)?;
        for s in &self.speeds_mm_s {
            check_positive("speeds", *s)?;
        }
        check_positive("max deflection", self.max_deflection_mm)?;
        check_nonneg("standoff", self.standoff_mm)?;
        check_positive("acceleration", self.accel_mm_s2)?;
        check_positive("contact acceleration", self.contact_accel_mm_s2)?;
        if let Some(j) = self.jerk_mm_s3 {
            check_positive("jerk", j)?;
        }
        check_positive("transfer speed", self.transfer_speed_mm_s)?;
        check_nonneg("dwell", self.dwell_s)?;
        for p in [self.sphere_centre_mm, self.plates_mid_mm] {
            for c in p.iter() {
                check_finite("artefact position", *c)?;
            }
        }
        if !(self.approach_angle_deg.is_finite() && self.approach_angle_deg.abs() <= 75.0) {
            return Err(invalid("approach angle", "must be within ±75° of the surface normal"));
        }
        if self.repeats == 0 || self.repeats > 100_000 {
            return Err(invalid("repeats", "must be between 1 and 100000"));
        }
        if self.variant == Variant::Speeds && self.speeds_mm_s.is_empty() {
            return Err(invalid("speeds", "needs at least one speed"));
        }
        let r_centre = 0.5 * self.sphere_diameter_mm + self.stylus.tip_radius_mm;
        for d in self.scan_deflections_mm {
            check_positive("scan deflection", d)?;
            if d >= 0.5 * r_centre {
                return Err(invalid("scan deflection", "must be well below the stylus-centre radius"));
            }
        }
        if self.variant == Variant::Scan {
            let sum: f64 = self.scan_sections_deg.iter().sum();
            if self.scan_sections_deg.len() < 2
                || self.scan_sections_deg.iter().any(|s| !(s.is_finite() && *s > 0.0))
            {
                return Err(invalid("scan sections", "need at least two positive angular lengths"));
            }
            if (sum - 360.0).abs() > 1e-6 {
                return Err(invalid("scan sections", format!("must sum to 360°, got {sum}°")));
            }
            let tr = self.scan_transition_deg;
            if !(tr.is_finite() && tr > 0.0 && self.scan_sections_deg.iter().all(|s| *s > tr)) {
                return Err(invalid("scan transition", "must be positive and shorter than every section"));
            }
        }
        if self.variant == Variant::Plates {
            let room = 0.5 * self.plate_gap_mm - self.stylus.tip_radius_mm;
            if room <= self.max_deflection_mm + 0.1 {
                return Err(invalid("plate gap", "leaves no room for the stylus tip between the plates"));
            }
        }
        Ok(())
    }
}

/// The artefact of the run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ArtefactTruth {
    /// A sphere.
    Sphere {
        /// Centre, mm.
        centre_mm: [f64; 3],
        /// Diameter, mm.
        diameter_mm: f64,
    },
    /// Faces at `mid ∓ axis·gap/2`.
    Plates {
        /// Middle of the gap, mm.
        mid_mm: [f64; 3],
        /// Unit axis across the gap.
        axis: [f64; 3],
        /// Gap, mm.
        gap_mm: f64,
    },
}

/// One contact (or one scan) of the run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactTruth {
    /// `+X`, `-Y`, `+Z`, `face1`, `face2`, `scan`.
    pub label: String,
    /// Contact speed, mm/s.
    pub speed_mm_s: f64,
    /// Contact point on the artefact surface (for a scan: the start point).
    pub surface_point_mm: [f64; 3],
    /// Outward surface normal there.
    pub normal: [f64; 3],
    /// Body (stylus-centre) position at the first touch: `surface point + r·normal`.
    pub touching_centre_mm: [f64; 3],
    /// Unit direction of body travel on approach.
    pub approach_direction: [f64; 3],
    /// True-time window of the contact move (s): start of the approach at the stand-off point,
    /// end of the retract back there.
    pub t_start_s: f64,
    /// End of the retract, true time, s.
    pub t_end_s: f64,
}

/// The known truth of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Truth {
    /// The data set's variant.
    pub variant: Variant,
    /// Seed of the noise.
    pub seed: u64,
    /// Machine − probe capture latency (s); the mean of the per-axis values.
    pub delay_s: f64,
    /// Machine − probe capture latency per axis, s.
    pub per_axis_delay_s: [f64; 3],
    /// Machine position capture latency per axis, s.
    pub machine_latency_s: [f64; 3],
    /// Probe capture latency, s.
    pub probe_latency_s: f64,
    /// Machine sampling rate, Hz.
    pub machine_rate_hz: f64,
    /// Probe sampling rate, Hz.
    pub probe_rate_hz: f64,
    /// Standard deviation of the encoder noise, mm.
    pub encoder_noise_mm: f64,
    /// Standard deviation of the probe noise, mm.
    pub probe_noise_mm: f64,
    /// The artefact probed.
    pub artefact: ArtefactTruth,
    /// Stylus tip radius, mm.
    pub tip_radius_mm: f64,
    /// The artefact's size: sphere diameter or plate gap (mm).
    pub static_size_mm: f64,
    /// The size of the stylus-centre surface: `D + 2r` (sphere) or `gap − 2r` (plates).
    pub stylus_centre_size_mm: f64,
    /// Distinct contact speeds in order of use (mm/s).
    pub speeds_mm_s: Vec<f64>,
    /// Largest deflection of the run, mm.
    pub max_deflection_mm: f64,
    /// Duration of the run, s.
    pub duration_s: f64,
    /// Every contact (or scan), in order.
    pub contacts: Vec<ContactTruth>,
}

/// A simulated data set.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// `(t_s, body position)` as the machine reports it.
    pub machine: Vec<(f64, Point3)>,
    /// `(t_s, deflection a, b, c)` as the probe reports it.
    pub probe: Vec<(f64, Vector3)>,
    /// Per probe sample: whether the tip truly touched the surface in the stylus sub-step ending
    /// at that instant (then the stylus centre lies exactly on the stylus-centre surface; a
    /// bounce that leaves the surface before the sample is not flagged). Not written to the
    /// contract files; for tests and plots.
    pub probe_in_contact: Vec<bool>,
    /// The known truth of the run.
    pub truth: Truth,
}

fn arr(p: &Vector3) -> [f64; 3] {
    [p.x, p.y, p.z]
}

/// One planned contact: surface point, outward normal, approach direction, speed, label.
struct Plan {
    label: &'static str,
    surface: Point3,
    normal: Vector3,
    approach: Vector3,
    speed: f64,
}

fn sphere_plans(cfg: &Config, speeds: &[f64]) -> Vec<Plan> {
    let r = 0.5 * cfg.sphere_diameter_mm;
    let c = cfg.sphere_centre_mm;
    let alpha = cfg.approach_angle_deg.to_radians();
    let dirs: [(&'static str, Vector3); 5] = [
        ("+X", Vector3::x()),
        ("-X", -Vector3::x()),
        ("+Y", Vector3::y()),
        ("-Y", -Vector3::y()),
        ("+Z", Vector3::z()),
    ];
    let mut out = Vec::new();
    for &v in speeds {
        for (label, n) in dirs {
            // Tilt the approach in a tangent direction (horizontal for the side points, +X for +Z).
            let t = if n.z.abs() > 0.5 { Vector3::x() } else { n.cross(&Vector3::z()) };
            let approach = -n * alpha.cos() + t * alpha.sin();
            out.push(Plan { label, surface: c + n * r, normal: n, approach, speed: v });
        }
    }
    out
}

/// Safe rest-to-rest route between two points outside a sphere: radially out to a clearance
/// sphere, along it (steps ≤ 30°, via the top) and radially in.
fn sphere_route(centre: &Point3, clear_radius: f64, from: &Point3, to: &Point3) -> Vec<Point3> {
    let d0 = (from - centre).normalize();
    let d1 = (to - centre).normalize();
    let mut pts = vec![centre + d0 * clear_radius];
    let leg = |a: Vector3, b: Vector3, pts: &mut Vec<Point3>| {
        let ang = a.dot(&b).clamp(-1.0, 1.0).acos();
        let n = (ang / 30f64.to_radians()).ceil().max(1.0) as usize;
        for k in 1..=n {
            let f = k as f64 / n as f64;
            // Slerp (a and b are never antipodal: each leg has +Z at one end and the points
            // are never straight below the centre).
            let s = ang.sin();
            let dir =
                if s < 1e-9 { b } else { a * (((1.0 - f) * ang).sin() / s) + b * ((f * ang).sin() / s) };
            pts.push(centre + dir.normalize() * clear_radius);
        }
    };
    if d0.dot(&d1) < 0.99 {
        leg(d0, Vector3::z(), &mut pts);
        leg(Vector3::z(), d1, &mut pts);
    } else {
        leg(d0, d1, &mut pts);
    }
    pts.push(*to);
    pts.dedup_by(|a, b| (*a - *b).norm() < 1e-9);
    pts
}

/// Run the scenario: the trajectory of every touch (or the scan), the two sampled streams, and
/// the truth beside them.
pub fn simulate(cfg: &Config) -> Result<Dataset, LatencyError> {
    cfg.validate()?;
    let r_tip = cfg.stylus.tip_radius_mm;
    let sphere = Sphere::new(cfg.sphere_centre_mm, 0.5 * cfg.sphere_diameter_mm)?;
    let plates = Plates::new(cfg.plates_mid_mm, Vector3::x(), cfg.plate_gap_mm)?;
    let on_plates = cfg.variant == Variant::Plates;
    let artefact: &dyn Artefact = if on_plates { &plates } else { &sphere };
    let clear_radius = 1.1 * (sphere.radius + r_tip) + 5.0;
    let transfer = Limits { v_max: cfg.transfer_speed_mm_s, a_max: cfg.accel_mm_s2, j_max: cfg.jerk_mm_s3 };

    let lead = 0.1;
    let home = if on_plates { cfg.plates_mid_mm } else { cfg.sphere_centre_mm + Vector3::z() * clear_radius };
    let mut tr = Trajectory::new(0.0, home);
    tr.dwell(lead)?;
    let mut contacts = Vec::new();
    let mut speeds_used: Vec<f64> = Vec::new();
    if cfg.variant == Variant::Scan {
        build_scan(cfg, &mut tr, &sphere, r_tip, clear_radius, &transfer, &mut contacts)?;
        speeds_used.push(cfg.speed_mm_s);
    } else {
        let route = Route { on_plates, home, clear_radius, transfer };
        let plans = touch_plans(cfg);
        build_touches(cfg, &mut tr, &plans, &route, &mut contacts, &mut speeds_used)?;
    }
    tr.dwell(lead)?;
    // Refuse runaway sizes before any large allocation (the servo adds < 1 s of settling).
    let t_est = tr.end_s() + 1.0;
    for rate in [cfg.machine_rate_hz, cfg.probe_rate_hz] {
        if t_est * rate > MAX_SAMPLES {
            return Err(invalid("duration × rate", format!("{:.0} samples is too many", t_est * rate)));
        }
    }
    let motion: Box<dyn Motion> = match &cfg.servo {
        Some(s) => Box::new(ServoMotion::new(tr, s, 2e-4)?),
        None => Box::new(tr),
    };
    let t_end = motion.end_s();
    let (machine, probe, probe_in_contact) = sample_streams(cfg, &*motion, artefact)?;
    let (artefact, static_size_mm, stylus_centre_size_mm) = if on_plates {
        let truth = ArtefactTruth::Plates {
            mid_mm: arr(&plates.mid.coords),
            axis: arr(&plates.axis),
            gap_mm: plates.gap,
        };
        (truth, plates.gap, plates.gap - 2.0 * r_tip)
    } else {
        let truth = ArtefactTruth::Sphere {
            centre_mm: arr(&sphere.centre.coords),
            diameter_mm: cfg.sphere_diameter_mm,
        };
        (truth, cfg.sphere_diameter_mm, cfg.sphere_diameter_mm + 2.0 * r_tip)
    };
    let lat_m = cfg.machine_latencies();
    let lat_p = cfg.probe_latency_s;
    let per_axis = [lat_m[0] - lat_p, lat_m[1] - lat_p, lat_m[2] - lat_p];
    let truth = Truth {
        variant: cfg.variant,
        seed: cfg.seed,
        delay_s: per_axis.iter().sum::<f64>() / 3.0,
        per_axis_delay_s: per_axis,
        machine_latency_s: lat_m,
        probe_latency_s: lat_p,
        machine_rate_hz: cfg.machine_rate_hz,
        probe_rate_hz: cfg.probe_rate_hz,
        encoder_noise_mm: cfg.encoder_noise_mm,
        probe_noise_mm: cfg.probe_noise_mm,
        artefact,
        tip_radius_mm: r_tip,
        static_size_mm,
        stylus_centre_size_mm,
        speeds_mm_s: speeds_used,
        max_deflection_mm: cfg.max_deflection_mm,
        duration_s: t_end,
        contacts,
    };
    Ok(Dataset { machine, probe, probe_in_contact, truth })
}

/// The touches of a touch variant, `cfg.repeats` times over.
fn touch_plans(cfg: &Config) -> Vec<Plan> {
    let mut plans = Vec::new();
    for _ in 0..cfg.repeats {
        match cfg.variant {
            Variant::Plates => {
                let (m, h) = (cfg.plates_mid_mm, 0.5 * cfg.plate_gap_mm);
                let v = cfg.speed_mm_s;
                let x = Vector3::x();
                plans.push(Plan { label: "face2", surface: m + x * h, normal: -x, approach: x, speed: v });
                plans.push(Plan { label: "face1", surface: m - x * h, normal: x, approach: -x, speed: v });
            }
            Variant::InOut => {
                let mut p = sphere_plans(cfg, &[cfg.speed_mm_s]);
                p.truncate(1);
                plans.extend(p);
            }
            Variant::Speeds => plans.extend(sphere_plans(cfg, &cfg.speeds_mm_s)),
            _ => plans.extend(sphere_plans(cfg, &[cfg.speed_mm_s])),
        }
    }
    plans
}

/// How the probe travels between touches: straight between the plates, around the sphere on
/// its clearance sphere.
struct Route {
    on_plates: bool,
    home: Point3,
    clear_radius: f64,
    transfer: Limits,
}

impl Route {
    fn travel(&self, cfg: &Config, tr: &mut Trajectory, to: Point3) -> Result<(), LatencyError> {
        if self.on_plates {
            tr.line_to(to, &self.transfer)?;
        } else {
            let route = sphere_route(&cfg.sphere_centre_mm, self.clear_radius, &tr.position(), &to);
            tr.polyline(&route, &self.transfer)?;
        }
        Ok(())
    }
}

/// Append every touch of `plans` to `tr` (free-air run-up, touch at speed, stop at the deepest
/// point, dwell, leave at speed) and back home; the truth of each contact and the speeds used.
fn build_touches(
    cfg: &Config,
    tr: &mut Trajectory,
    plans: &[Plan],
    route: &Route,
    contacts: &mut Vec<ContactTruth>,
    speeds_used: &mut Vec<f64>,
) -> Result<(), LatencyError> {
    let r_tip = cfg.stylus.tip_radius_mm;
    for plan in plans {
        let cos_in = -plan.approach.dot(&plan.normal);
        if cos_in < 0.2 {
            return Err(invalid("approach angle", "too grazing for a contact"));
        }
        let v = plan.speed;
        let travel_in = cfg.max_deflection_mm / cos_in;
        let a_c = cfg.contact_accel_mm_s2.max(2.0 * v * v / travel_in);
        let lim_free = Limits { v_max: v, a_max: cfg.accel_mm_s2, j_max: None };
        let lim_in = Limits { v_max: v, a_max: a_c, j_max: None };
        // Reach v in free air (and let the servo and the stylus settle for 20 ms) before
        // the touch.
        let standoff = cfg.standoff_mm.max(1.5 * v * v / (2.0 * cfg.accel_mm_s2) + 0.02 * v);
        let touching = plan.surface + plan.normal * r_tip;
        let start = touching - plan.approach * standoff;
        let deepest = touching + plan.approach * travel_in;
        route.travel(cfg, tr, start)?;
        let t_start = tr.end_s();
        // In: accelerate in free air, touch at v, stop at the deepest point.
        tr.line_speeds(touching, 0.0, v, &lim_free)?;
        tr.line_speeds(deepest, v, 0.0, &lim_in)?;
        tr.dwell(cfg.dwell_s)?;
        // Out: accelerate to v while in contact, leave at v, stop in free air.
        tr.line_speeds(touching, 0.0, v, &lim_in)?;
        tr.line_speeds(start, v, 0.0, &lim_free)?;
        let t_end = tr.end_s();
        if !speeds_used.contains(&v) {
            speeds_used.push(v);
        }
        contacts.push(ContactTruth {
            label: plan.label.to_string(),
            speed_mm_s: v,
            surface_point_mm: arr(&plan.surface.coords),
            normal: arr(&plan.normal),
            touching_centre_mm: arr(&touching.coords),
            approach_direction: arr(&plan.approach),
            t_start_s: t_start,
            t_end_s: t_end,
        });
    }
    route.travel(cfg, tr, route.home)
}

/// A machine stream (position samples) and a probe stream (deflection samples with their
/// in-contact flags), computed side by side (they are independent).
type Streams = (Vec<(f64, Point3)>, Vec<(f64, Vector3)>, Vec<bool>);

/// Sample `motion` as the machine's axes and the probe see it (latencies, rates, noise).
fn sample_streams(
    cfg: &Config,
    motion: &dyn Motion,
    artefact: &dyn Artefact,
) -> Result<Streams, LatencyError> {
    let clock = MasterClock::new(0.0, motion.end_s())?;
    let machine_capture = AxisCapture::new(cfg.machine_rate_hz, cfg.machine_latencies())?;
    let pc = Capture::new(cfg.probe_rate_hz, cfg.probe_latency_s)?;
    let (machine, probe_side) = rayon::join(
        || {
            let mut rng_m = stream(cfg.seed, 1);
            machine_capture.sample_point(&clock, cfg.encoder_noise_mm, &mut rng_m, |t| motion.state(t).p)
        },
        || -> Result<_, ParamError> {
            // The stylus is integrated on the probe's true-time grid.
            let range = pc.index_range(&clock);
            let (k0, k1) = (*range.start(), *range.end());
            let n = (k1 - k0 + 1).max(0) as usize;
            let substeps = (cfg.stylus_rate_hz / cfg.probe_rate_hz).ceil().max(1.0) as usize;
            let t_first = pc.true_time(pc.stamp(k0));
            let defl = stylus::simulate(&cfg.stylus, motion, artefact, t_first, pc.period_s(), n, substeps)?;
            let mut rng_p = stream(cfg.seed, 2);
            let mut probe = Vec::with_capacity(n);
            let mut in_contact = Vec::with_capacity(n);
            for (i, (d, c)) in defl.into_iter().enumerate() {
                probe.push((pc.stamp(k0 + i as i64), d + gaussian3(&mut rng_p, cfg.probe_noise_mm)));
                in_contact.push(c);
            }
            Ok((probe, in_contact))
        },
    );
    let (probe, in_contact) = probe_side?;
    Ok((machine?, probe, in_contact))
}

/// Deflection level switches of the scan: `(θ_centre, δ_before, δ_after)`.
fn scan_switches(cfg: &Config) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    let mut theta = 0.0;
    let mut k = 0usize;
    for _ in 0..cfg.repeats {
        for s in &cfg.scan_sections_deg {
            theta += s.to_radians();
            let before = cfg.scan_deflections_mm[k % 2];
            let after = cfg.scan_deflections_mm[(k + 1) % 2];
            out.push((theta, before, after));
            k += 1;
        }
    }
    out.pop(); // no switch at the very end of the sweep
    out
}

/// Deflection δ(θ) of the scan path and its first two derivatives.
fn scan_deflection(switches: &[(f64, f64, f64)], first: f64, w: f64, theta: f64) -> (f64, f64, f64) {
    // The switch whose window holds θ (windows do not overlap: sections are longer than w).
    let i = switches.partition_point(|s| s.0 + 0.5 * w < theta);
    let level = if i == 0 { first } else { switches[i - 1].2 };
    match switches.get(i) {
        Some(&(tc, a, b)) if theta > tc - 0.5 * w => {
            let s = (theta - tc + 0.5 * w) / w;
            let pi = std::f64::consts::PI;
            let (sn, cs) = (pi * s).sin_cos();
            (
                a + (b - a) * 0.5 * (1.0 - cs),
                (b - a) * pi * sn / (2.0 * w),
                (b - a) * pi * pi * cs / (2.0 * w * w),
            )
        }
        _ => (level, 0.0, 0.0),
    }
}

fn build_scan(
    cfg: &Config,
    tr: &mut Trajectory,
    sphere: &Sphere,
    r_tip: f64,
    clear_radius: f64,
    transfer: &Limits,
    contacts: &mut Vec<ContactTruth>,
) -> Result<(), LatencyError> {
    let c = sphere.centre;
    let r_c = sphere.radius + r_tip;
    let v = cfg.speed_mm_s;
    let first = cfg.scan_deflections_mm[0];
    let start_pt = c + Vector3::x() * (r_c + cfg.standoff_mm.max(1.0));
    let route = sphere_route(&c, clear_radius, &tr.position(), &start_pt);
    tr.polyline(&route, transfer)?;
    // Radial approach into the first path radius at the scan speed.
    let lim_in = Limits { v_max: v, a_max: cfg.accel_mm_s2, j_max: cfg.jerk_mm_s3 };
    let t_start = tr.end_s();
    // (Rest-to-rest: the radial approach stops on the first path radius before the sweep.)
    tr.line_to(c + Vector3::x() * (r_c - first), &lim_in)?;
    tr.dwell(cfg.dwell_s)?;
    let switches = scan_switches(cfg);
    let w = cfg.scan_transition_deg.to_radians();
    let sweep = 2.0 * std::f64::consts::PI * cfg.repeats as f64;
    let rho_mean = r_c - 0.5 * (cfg.scan_deflections_mm[0] + cfg.scan_deflections_mm[1]);
    let ang = Limits {
        v_max: v / rho_mean,
        a_max: cfg.accel_mm_s2 / rho_mean,
        j_max: cfg.jerk_mm_s3.map(|j| j / rho_mean),
    };
    let prof = Profile::new(sweep, &ang)?;
    let path = move |u: f64| {
        let (th, thd, thdd) = prof.eval(u);
        let (dl, dl1, dl2) = scan_deflection(&switches, first, w, th);
        let (rho, rho1, rho2) = (r_c - dl, -dl1, -dl2);
        let (sn, cs) = th.sin_cos();
        let er = Vector3::new(cs, sn, 0.0);
        let et = Vector3::new(-sn, cs, 0.0);
        State {
            p: c + er * rho,
            v: er * (rho1 * thd) + et * (rho * thd),
            a: er * (rho2 * thd * thd + rho1 * thdd - rho * thd * thd)
                + et * (2.0 * rho1 * thd * thd + rho * thdd),
        }
    };
    tr.custom(prof.duration(), path)?;
    tr.dwell(cfg.dwell_s)?;
    tr.line_to(start_pt, &lim_in)?;
    let t_end = tr.end_s();
    let route = sphere_route(&c, clear_radius, &start_pt, &(c + Vector3::z() * clear_radius));
    tr.polyline(&route, transfer)?;
    contacts.push(ContactTruth {
        label: "scan".to_string(),
        speed_mm_s: v,
        surface_point_mm: arr(&(c + Vector3::x() * sphere.radius).coords),
        normal: [1.0, 0.0, 0.0],
        touching_centre_mm: arr(&(c + Vector3::x() * r_c).coords),
        approach_direction: [-1.0, 0.0, 0.0],
        t_start_s: t_start,
        t_end_s: t_end,
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_data_and_different_seed_different_noise() {
        let mut cfg = Config::preset(Variant::InOut);
        cfg.speed_mm_s = 20.0;
        let a = simulate(&cfg).unwrap();
        let b = simulate(&cfg).unwrap();
        assert_eq!(a, b);
        cfg.seed = 2;
        let c = simulate(&cfg).unwrap();
        assert_eq!(a.machine.len(), c.machine.len());
        assert_ne!(a.machine[10].1, c.machine[10].1);
        assert!((a.truth.delay_s - 0.0025).abs() < 1e-15);
    }

    #[test]
    fn scan_path_deflection_switches_smoothly() {
        let cfg = Config::preset(Variant::Scan);
        let sw = scan_switches(&cfg);
        assert_eq!(sw.len(), 5);
        let w = cfg.scan_transition_deg.to_radians();
        let h = 1e-7;
        for k in 1..5000 {
            let th = 2.0 * std::f64::consts::PI * k as f64 / 5000.0;
            let (d, d1, _) = scan_deflection(&sw, 0.1, w, th);
            assert!((0.1 - 1e-12..=0.3 + 1e-12).contains(&d));
            let num =
                (scan_deflection(&sw, 0.1, w, th + h).0 - scan_deflection(&sw, 0.1, w, th - h).0) / (2.0 * h);
            assert!((num - d1).abs() < 1e-5, "{th}: {num} vs {d1}");
        }
        assert!(simulate(&Config { scan_sections_deg: vec![100.0, 100.0], ..cfg.clone() }).is_err());
    }

    #[test]
    fn bad_settings_are_refused() {
        let ok = Config::default();
        assert!(simulate(&Config { probe_rate_hz: 0.0, ..ok.clone() }).is_err());
        assert!(simulate(&Config { encoder_noise_mm: f64::NAN, ..ok.clone() }).is_err());
        assert!(simulate(&Config { repeats: 0, ..ok.clone() }).is_err());
        assert!(simulate(&Config { probe_rate_hz: 1e9, ..ok.clone() }).is_err());
        assert!(simulate(&Config { variant: Variant::Plates, plate_gap_mm: 4.0, ..ok.clone() }).is_err());
        assert!(simulate(&Config { approach_angle_deg: 89.0, ..ok }).is_err());
    }
}
