//! A virtual machine tool with a spindle touch probe and reference spheres on its table, behind
//! [`ProbingMachine`] — what `truepos probe sphere --controller virtual` and head-offset
//! acquisition run on, and the twin of the simulated LinuxCNC of the integration tests.
//!
//! The stylus is the simulator's touch-trigger probe ([`truepos_sim::touch::TouchProbe`]: ball
//! radius, pre-travel and lobing), the contacts are exact ([`truepos_sim::artefact::Sphere`]).
//! Like a CNC, the controller samples the probe input once per servo period and latches the
//! axis positions at the first sample after the trigger: the latched point lies up to one
//! servo step (`feed · period`, at a random phase) past the trigger, plus the axes' position
//! noise. After the latch the machine retracts along the approach direction. A positioning
//! move that touches anything stops at the trigger and is an error, as on a CNC ("probe tripped
//! during non-probe move").
//!
//! With rotary axes (`rotary`: a B swivel head, a C table) the machine is the head-offset
//! contract's: positions are the NC's head reference point P, the tip centre is at
//! `P + Ry(b)·R` (`head_offset_mm`), and what is on the table at `A` (C = 0) is at
//! `O + Rz(c)·(A − O)` (`table_center_mm`).
//!
//! [`VirtualMachineTool::five_axis`] is a five-axis machine of another kind: a B tilting table
//! carrying a C rotary table (LinuxCNC's `xyzbc-trt-kins`) with tool-centre-point control, whose
//! positions are in the programme frame; its controller is configured with a geometry tens of
//! µm off the true one, so the sphere appears displaced at B, C ≠ 0 by exactly the closed form
//! of `truepos_kinematics::trt::reported_centre`. Its kinematics parameters can be read and
//! written (at B = C = 0), like a real controller's.
//!
//! Besides spheres, the table can carry plates with bores ([`truepos_sim::artefact::Part`]), the
//! holes that in-spindle inspection probes ([`MachineToolConfig::with_holes`]).
//!
//! Entry points: [`MachineToolConfig`] (`Default`: a 25 mm sphere at (120, 45, 30) and a 3 mm
//! ball), [`MachineToolConfig::near`], [`MachineToolConfig::with_holes`],
//! [`VirtualMachineTool::new`], [`VirtualMachineTool::truth`].

use truepos_device::{
    DeviceError, DeviceInfo, KinematicsParameter, ProbeHit, ProbeRequest, ProbingMachine, RotaryAxes,
    RotaryKinematics,
};
use truepos_kinematics::trt::{reported_centre, TrtGeometry};
use truepos_math::{ry, rz, Matrix3};
use truepos_math::{Point3, Vector3};
use truepos_sim::artefact::{Artefact, ConvexPolyhedron, Cylinder, Part, Sphere, SurfacePoint};
/// The error of a virtual machine tool's parameters ([`VirtualMachineTool::new`]).
pub use truepos_sim::noise::ParamError;
use truepos_sim::noise::{self, SimRng};
use truepos_sim::touch::TouchProbe;

const ADDRESS: &str = "virtual";

/// The virtual machine tool.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineToolConfig {
    /// Seed of the noise.
    pub seed: u64,
    /// Reference spheres: centre (machine frame, mm) and radius (mm).
    pub spheres: Vec<(Point3, f64)>,
    /// Plates with bores (blocks minus cylindrical holes).
    pub parts: Vec<Part>,
    /// The real stylus ball radius (the radius a request gives is only the plan's).
    pub tip_radius_mm: f64,
    /// Touch-trigger pre-travel, mm.
    pub pretravel_mm: f64,
    /// Amplitude of the pre-travel's 3-lobe variation, mm.
    pub lobing_mm: f64,
    /// Servo period (s): the probe input's sampling.
    pub servo_period_s: f64,
    /// Standard deviation of each latched axis position (mm).
    pub position_sigma_mm: f64,
    /// Travel limits (machine frame, mm).
    pub travel_min_mm: Point3,
    /// Upper travel limits (machine frame, mm).
    pub travel_max_mm: Point3,
    /// Where the tip centre is at start.
    pub start_mm: Point3,
    /// Rotary axes the machine has (default none).
    pub rotary: RotaryAxes,
    /// The head offset R: tip centre = P + Ry(b)·R, with P the position the machine reports
    /// (default zero: P is the tip centre).
    pub head_offset_mm: Vector3,
    /// A point of the table's C axis (parallel to Z).
    pub table_center_mm: Point3,
}

impl Default for MachineToolConfig {
    fn default() -> Self {
        MachineToolConfig {
            seed: 1,
            spheres: vec![(Point3::new(120.0, 45.0, 30.0), 12.5)],
            parts: vec![],
            tip_radius_mm: 1.5,
            pretravel_mm: 0.0005,
            lobing_mm: 0.0,
            servo_period_s: 0.001,
            position_sigma_mm: 0.0001,
            travel_min_mm: Point3::new(-500.0, -500.0, -300.0),
            travel_max_mm: Point3::new(1000.0, 800.0, 500.0),
            start_mm: Point3::new(0.0, 0.0, 100.0),
            rotary: RotaryAxes::default(),
            head_offset_mm: Vector3::zeros(),
            table_center_mm: Point3::origin(),
        }
    }
}

impl MachineToolConfig {
    /// A machine whose one reference sphere is set up near a nominal one (centre, radius) as a
    /// real setup would be: displaced by a seeded error of σ = 0.1 mm per axis, its radius a few
    /// µm off nominal; the stylus ball has the nominal tip radius; the machine starts 50 mm above
    /// the sphere with ±500 mm of travel around it.
    pub fn near(seed: u64, centre: Point3, radius: f64, tip_radius: f64) -> MachineToolConfig {
        let mut rng = noise::stream(seed, 77);
        let d = noise::gaussian3(&mut rng, 0.1);
        let dr = noise::gaussian(&mut rng, 0.002);
        MachineToolConfig {
            seed,
            spheres: vec![(centre + d, radius + dr)],
            tip_radius_mm: tip_radius,
            travel_min_mm: centre - Vector3::repeat(radius + 500.0),
            travel_max_mm: centre + Vector3::repeat(radius + 500.0),
            start_mm: centre + Vector3::new(0.0, 0.0, radius + tip_radius + 50.0),
            ..MachineToolConfig::default()
        }
    }
}

/// The truth of [`MachineToolConfig::for_head_offset`]: the head offset the machine really
/// has, and the sphere (centre at C = 0, radius) on its table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadOffsetTruth {
    /// The head offset R, mm.
    pub offset_mm: Vector3,
    /// Sphere centre at C = 0, machine frame, mm.
    pub sphere_centre_mm: Point3,
    /// Sphere radius, mm.
    pub sphere_radius_mm: f64,
}

impl MachineToolConfig {
    /// A machine tool with a B head and a C table for head-offset acquisition `acq`: the sphere
    /// set up near its nominal place ([`MachineToolConfig::near`]), the head offset off its
    /// nominal by a seeded error of σ = 0.2 mm per axis, the C axis through the acquisition's
    /// table centre, travel widened by the offset and the sphere's distance from that axis, and
    /// the tip starting 50 mm above the sphere at B = 0.
    pub fn for_head_offset(
        seed: u64,
        acq: &truepos_head::acquire::HeadAcquisition,
    ) -> (MachineToolConfig, HeadOffsetTruth) {
        let (near, r, tip) = (acq.sphere.near_mm, 0.5 * acq.sphere.diameter_mm, acq.sphere.tip_radius_mm);
        let cfg = MachineToolConfig::near(seed, near, r, tip);
        let offset = acq.nominal_offset_mm + seeded_offset_error(seed, 0.2);
        let (c, radius) = cfg.spheres[0];
        let truth = HeadOffsetTruth { offset_mm: offset, sphere_centre_mm: c, sphere_radius_mm: radius };
        (MachineToolConfig::with_head_offset(seed, acq, &truth), truth)
    }

    /// A machine tool with a B head and a C table for head-offset acquisition `acq` whose head
    /// offset and sphere are `truth` (the noise, latch phase and position noise of `seed`).
    pub fn with_head_offset(
        seed: u64,
        acq: &truepos_head::acquire::HeadAcquisition,
        truth: &HeadOffsetTruth,
    ) -> MachineToolConfig {
        let (near, r, tip) = (acq.sphere.near_mm, 0.5 * acq.sphere.diameter_mm, acq.sphere.tip_radius_mm);
        let mut cfg = MachineToolConfig::near(seed, near, r, tip);
        cfg.spheres = vec![(truth.sphere_centre_mm, truth.sphere_radius_mm)];
        let offset = truth.offset_mm;
        let reach = offset.norm() + (near - acq.table_center_mm).norm();
        cfg.rotary = RotaryAxes { head_b: true, table_c: true };
        cfg.head_offset_mm = offset;
        cfg.table_center_mm = acq.table_center_mm;
        cfg.travel_min_mm -= Vector3::repeat(reach);
        cfg.travel_max_mm += Vector3::repeat(reach);
        cfg.start_mm = near + Vector3::new(0.0, 0.0, r + tip + 50.0) - offset;
        cfg
    }
}

/// A seeded error of σ per axis (e.g. how far a virtual head offset is from its nominal).
pub fn seeded_offset_error(seed: u64, sigma_mm: f64) -> Vector3 {
    noise::gaussian3(&mut noise::stream(seed, 79), sigma_mm)
}

/// A bore of [`MachineToolConfig::with_holes`] as it really is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueHole {
    /// Centre of the hole's top (mm).
    pub top_mm: Point3,
    /// Diameter, mm.
    pub diameter_mm: f64,
}

impl MachineToolConfig {
    /// A machine with the given holes (nominal top centre, nominal diameter) as a real part has
    /// them: each bore displaced by a seeded error of σ = 20 µm in X and Y, its diameter
    /// σ = 5 µm off nominal, in a 30 mm thick plate (one per hole-top height, covering the holes
    /// with a margin) whose top is at the hole tops. No sphere; the stylus ball has
    /// `tip_radius`; the machine starts 50 mm above the first hole. Plates of different heights
    /// that overlap in X and Y are refused (one would fill the other's holes).
    pub fn with_holes(
        seed: u64,
        holes: &[(Point3, f64)],
        tip_radius: f64,
    ) -> Result<(MachineToolConfig, Vec<TrueHole>), String> {
        let Some(first) = holes.first() else { return Err("no holes".into()) };
        let mut rng = noise::stream(seed, 78);
        let truth: Vec<TrueHole> = holes
            .iter()
            .map(|(c, d)| {
                let e = noise::gaussian3(&mut rng, 0.02);
                let dd = noise::gaussian(&mut rng, 0.005);
                TrueHole { top_mm: Point3::new(c.x + e.x, c.y + e.y, c.z), diameter_mm: d + dd }
            })
            .collect();
        // One plate per hole-top height (to 1 µm).
        let mut levels: Vec<f64> = vec![];
        for t in &truth {
            if !levels.iter().any(|z| (z - t.top_mm.z).abs() < 1e-3) {
                levels.push(t.top_mm.z);
            }
        }
        let thickness = 30.0;
        let mut parts = vec![];
        let mut rects: Vec<(f64, f64, f64, f64)> = vec![];
        for z in levels {
            let mine: Vec<&TrueHole> = truth.iter().filter(|t| (t.top_mm.z - z).abs() < 1e-3).collect();
            let margin = mine.iter().map(|t| t.diameter_mm).fold(0.0, f64::max) + 10.0;
            let lo = |f: fn(&Point3) -> f64| {
                mine.iter().map(|t| f(&t.top_mm)).fold(f64::INFINITY, f64::min) - margin
            };
            let hi = |f: fn(&Point3) -> f64| {
                mine.iter().map(|t| f(&t.top_mm)).fold(f64::NEG_INFINITY, f64::max) + margin
            };
            let r = (lo(|p| p.x), hi(|p| p.x), lo(|p| p.y), hi(|p| p.y));
            if rects.iter().any(|q| r.0 < q.1 && q.0 < r.1 && r.2 < q.3 && q.2 < r.3) {
                return Err(format!(
                    "holes at different heights (top z {z} mm and another) are too close in X and Y for one plate each"
                ));
            }
            rects.push(r);
            let block = ConvexPolyhedron::cuboid(
                Point3::new(0.5 * (r.0 + r.1), 0.5 * (r.2 + r.3), z - 0.5 * thickness),
                Vector3::new(0.5 * (r.1 - r.0), 0.5 * (r.3 - r.2), 0.5 * thickness),
                truepos_math::Matrix3::identity(),
            )
            .map_err(|e| e.to_string())?;
            let bores = mine
                .iter()
                .map(|t| {
                    // Through the plate and beyond both faces.
                    Cylinder::new(
                        Point3::new(t.top_mm.x, t.top_mm.y, z - 0.5 * thickness),
                        Vector3::z(),
                        0.5 * t.diameter_mm,
                        thickness + 20.0,
                    )
                })
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| e.to_string())?;
            parts.push(Part { block, bosses: vec![], bores });
        }
        let (lo, hi) = holes.iter().fold(
            (Point3::from(Vector3::repeat(f64::INFINITY)), Point3::from(Vector3::repeat(f64::NEG_INFINITY))),
            |(lo, hi), (c, _)| (lo.inf(c), hi.sup(c)),
        );
        let cfg = MachineToolConfig {
            seed,
            spheres: vec![],
            parts,
            tip_radius_mm: tip_radius,
            travel_min_mm: lo - Vector3::repeat(500.0),
            travel_max_mm: hi + Vector3::repeat(500.0),
            start_mm: first.0 + Vector3::new(0.0, 0.0, 50.0),
            ..MachineToolConfig::default()
        };
        Ok((cfg, truth))
    }
}

/// An artefact on the table as the reported position P sees it: the tip is at
/// `P + shift` (the rotated head offset), the table turned by `turn` about the axis through `o`.
#[derive(Debug, Clone, Copy)]
struct Placed<'a> {
    inner: &'a dyn Artefact,
    shift: Vector3,
    turn: Matrix3,
    o: Point3,
}

impl Artefact for Placed<'_> {
    fn closest(&self, p: &Point3) -> SurfacePoint {
        // Into the table frame at C = 0, and the answer back.
        let q = self.o + self.turn.transpose() * (p + self.shift - self.o);
        let s = self.inner.closest(&q);
        SurfacePoint {
            distance: s.distance,
            point: self.o + self.turn * (s.point - self.o) - self.shift,
            normal: self.turn * s.normal,
        }
    }
}

/// The virtual machine tool behind [`ProbingMachine`].
#[derive(Debug)]
pub struct VirtualMachineTool {
    cfg: MachineToolConfig,
    spheres: Vec<Sphere>,
    probe: TouchProbe,
    rng: SimRng,
    pos: Point3,
    /// Head and table angles (rad).
    b: f64,
    c: f64,
    /// Probing moves made (for tests and reports).
    pub probings: usize,
    /// A five-axis table-tilting machine with TCP ([`VirtualMachineTool::five_axis`]).
    trt: Option<TrtState>,
}

/// The virtual xyzbc-trt machine's two geometries and its angles in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TrtState {
    configured: TrtGeometry,
    truth: TrtGeometry,
    b_deg: f64,
    c_deg: f64,
}

/// The truth of [`VirtualMachineTool::five_axis`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrtTruth {
    /// The geometry the virtual controller is configured with at the start.
    pub configured: TrtGeometry,
    /// The machine's true geometry.
    pub truth: TrtGeometry,
    /// The sphere on the table (centre in the table frame, radius).
    pub sphere_centre_mm: Point3,
    /// Sphere radius, mm.
    pub sphere_radius_mm: f64,
}

fn fmt_point(p: &Point3) -> String {
    format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z)
}

impl VirtualMachineTool {
    /// The virtual machine tool of `cfg` (its spheres and parts checked).
    pub fn new(cfg: MachineToolConfig) -> Result<VirtualMachineTool, ParamError> {
        let spheres = cfg.spheres.iter().map(|(c, r)| Sphere::new(*c, *r)).collect::<Result<Vec<_>, _>>()?;
        let probe = TouchProbe::new(cfg.tip_radius_mm, cfg.pretravel_mm, cfg.lobing_mm)?;
        noise::check_positive("servo period", cfg.servo_period_s)?;
        noise::check_nonneg("position sigma", cfg.position_sigma_mm)?;
        let rng = noise::stream(cfg.seed, 31);
        let pos = cfg.start_mm;
        Ok(VirtualMachineTool { cfg, spheres, probe, rng, pos, b: 0.0, c: 0.0, probings: 0, trt: None })
    }

    /// A five-axis machine tool with a B tilting table carrying a C rotary table and
    /// tool-centre-point control, LinuxCNC's `xyzbc-trt-kins` (`truepos kinematics calibrate
    /// --controller virtual`): positions are in the programme frame, which turns with the table;
    /// `orient` keeps the tip fixed in it. The controller is configured with the geometry of
    /// the LinuxCNC recipe (C axis through (10, −5), B axis at x −10, z −35 mm); the true
    /// geometry differs from it by a seeded error of σ = 30 µm in each of the four observable
    /// numbers (the C axis's x, y, the B axis's x, z). The sphere is set up near its nominal
    /// centre as [`MachineToolConfig::near`] does; the tip starts 60 mm above it.
    pub fn five_axis(
        seed: u64,
        centre: Point3,
        radius: f64,
        tip_radius: f64,
    ) -> Result<(VirtualMachineTool, TrtTruth), ParamError> {
        let configured = TrtGeometry {
            x_rot_point: 10.0,
            y_rot_point: -5.0,
            z_rot_point: -20.0,
            x_offset: -20.0,
            z_offset: -15.0,
        };
        let mut rng = noise::stream(seed, 83);
        let e: Vec<f64> = (0..4).map(|_| noise::gaussian(&mut rng, 0.030)).collect();
        let truth = configured.corrected(&[e[0], e[1], e[2], e[3]]);
        let mut cfg = MachineToolConfig::near(seed, centre, radius, tip_radius);
        cfg.start_mm = centre + Vector3::new(0.0, 0.0, 60.0);
        cfg.rotary = RotaryAxes { head_b: false, table_c: true };
        let (c, r) = cfg.spheres[0];
        let mut m = VirtualMachineTool::new(cfg)?;
        m.trt = Some(TrtState { configured, truth, b_deg: 0.0, c_deg: 0.0 });
        Ok((m, TrtTruth { configured, truth, sphere_centre_mm: c, sphere_radius_mm: r }))
    }

    /// A five-axis machine as [`VirtualMachineTool::five_axis`] with given geometries: the
    /// controller configured with `configured`, the machine truly `truth`, the sphere exactly at
    /// `centre` (table frame) with `radius` — what a task-specific simulation of a calibration
    /// needs. The latch, pre-travel and noise are the virtual machine tool's (seeded by `seed`)
    /// after `edit` has had its say (a model's own latch).
    pub fn five_axis_exact(
        seed: u64,
        configured: TrtGeometry,
        truth: TrtGeometry,
        centre: Point3,
        radius: f64,
        tip_radius: f64,
        edit: impl FnOnce(&mut MachineToolConfig),
    ) -> Result<VirtualMachineTool, ParamError> {
        let mut cfg = MachineToolConfig::near(seed, centre, radius, tip_radius);
        edit(&mut cfg);
        cfg.spheres = vec![(centre, radius)];
        cfg.start_mm = centre + Vector3::new(0.0, 0.0, 60.0);
        cfg.rotary = RotaryAxes { head_b: false, table_c: true };
        let mut m = VirtualMachineTool::new(cfg)?;
        m.trt = Some(TrtState { configured, truth, b_deg: 0.0, c_deg: 0.0 });
        Ok(m)
    }

    /// The reference spheres (truth).
    pub fn truth(&self) -> &[Sphere] {
        &self.spheres
    }

    /// The configuration the machine was built with.
    pub fn config(&self) -> &MachineToolConfig {
        &self.cfg
    }

    /// Everything on the table, as seen by the position the machine reports (P) at the current
    /// head and table angles.
    fn artefacts(&self) -> impl Iterator<Item = Placed<'_>> {
        let (shift, turn, o) = match &self.trt {
            // With TCP the table frame is the programme frame, up to the translation by which the
            // configured geometry misplaces it (zero at B = C = 0).
            Some(t) => {
                let o = self.cfg.table_center_mm;
                let seen = reported_centre(&t.configured, &t.truth, &o, self.b, self.c);
                (o - seen, Matrix3::identity(), o)
            }
            None => (ry(self.b) * self.cfg.head_offset_mm, rz(self.c), self.cfg.table_center_mm),
        };
        self.spheres
            .iter()
            .map(|s| s as &dyn Artefact)
            .chain(self.cfg.parts.iter().map(|p| p as &dyn Artefact))
            .map(move |inner| Placed { inner, shift, turn, o })
    }

    /// First trigger on the straight move from `from` along unit `u` within `len`.
    ///
    /// The probe's own search steps a fraction of its pre-travel at a time, far too fine for a
    /// long positioning move: first sphere-trace (step by the clearance between the ball and
    /// the nearest material, a lower bound of the distance for every artefact here) until the
    /// ball is within a few µm of something, then let the probe search from there.
    fn first_trigger(&self, from: &Point3, u: &Vector3, len: f64) -> Option<f64> {
        let margin = self.cfg.pretravel_mm + self.cfg.lobing_mm.abs() + 0.002;
        let r = self.cfg.tip_radius_mm;
        let mut s0 = 0.0;
        for _ in 0..1_000_000 {
            let p = from + u * s0;
            let gap = self.artefacts().map(|a| a.distance(&p) - r).fold(f64::INFINITY, f64::min);
            if gap <= margin || s0 >= len {
                break;
            }
            s0 += gap - 0.5 * margin;
        }
        if s0 >= len {
            return None;
        }
        let start = from + u * s0;
        self.artefacts()
            .filter_map(|a| self.probe.probe_along(&a, &start, u, len - s0))
            .map(|t| s0 + t.travel_mm)
            .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))))
    }

    fn in_travel(&self, p: &Point3) -> bool {
        (0..3).all(|i| p[i] >= self.cfg.travel_min_mm[i] && p[i] <= self.cfg.travel_max_mm[i])
    }

    fn check_target(&self, p: &Point3, what: &str) -> Result<(), DeviceError> {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(DeviceError::Rejected {
                address: ADDRESS.into(),
                what: what.into(),
                message: "the target is not finite".into(),
            });
        }
        if !self.in_travel(p) {
            return Err(DeviceError::Rejected {
                address: ADDRESS.into(),
                what: what.into(),
                message: format!(
                    "the target is outside the travel {} … {}",
                    fmt_point(&self.cfg.travel_min_mm),
                    fmt_point(&self.cfg.travel_max_mm)
                ),
            });
        }
        Ok(())
    }

    fn position_noise(&mut self) -> Vector3 {
        noise::gaussian3(&mut self.rng, self.cfg.position_sigma_mm)
    }
}

impl ProbingMachine for VirtualMachineTool {
    fn info(&self) -> DeviceInfo {
        DeviceInfo {
            address: ADDRESS.into(),
            version: format!(
                "truepos virtual machine tool (touch probe: {} mm ball, {} µm pre-travel; {} ms servo latch)",
                2.0 * self.cfg.tip_radius_mm,
                self.cfg.pretravel_mm * 1e3,
                self.cfg.servo_period_s * 1e3
            ),
        }
    }

    fn position(&mut self) -> Result<Point3, DeviceError> {
        Ok(self.pos)
    }

    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        let what = format!("positioning move to {}", fmt_point(&target_mm));
        self.check_target(&target_mm, &what)?;
        let d = target_mm - self.pos;
        let len = d.norm();
        if len == 0.0 {
            return Ok(());
        }
        let u = d / len;
        if let Some(s) = self.first_trigger(&self.pos, &u, len) {
            self.pos += u * s;
            return Err(DeviceError::Controller {
                address: ADDRESS.into(),
                what,
                message: format!("probe tripped during a positioning move, at {}", fmt_point(&self.pos)),
            });
        }
        self.pos = target_mm;
        Ok(())
    }

    fn probe(&mut self, r: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        let start = r.start_mm();
        let end = r.end_mm();
        let what = format!("probing move from {} to {}", fmt_point(&start), fmt_point(&end));
        let ok = r.feed_mm_s.is_finite()
            && r.feed_mm_s > 0.0
            && r.retract_mm.is_finite()
            && r.retract_mm >= 0.0
            && (r.approach.norm() - 1.0).abs() < 1e-9;
        if !ok {
            return Err(DeviceError::Rejected {
                address: ADDRESS.into(),
                what,
                message: "feed must be > 0, retract ≥ 0 and the approach a unit vector".into(),
            });
        }
        self.check_target(&end, &what)?;
        self.move_to(start)?;
        self.probings += 1;
        let d = end - start;
        let len = d.norm();
        if len == 0.0 {
            return Err(DeviceError::Rejected { address: ADDRESS.into(), what, message: "no travel".into() });
        }
        let u = d / len;
        let Some(s_trigger) = self.first_trigger(&start, &u, len) else {
            // To the end of the move, then back to the start.
            self.pos = start;
            return Err(DeviceError::NoContact { address: ADDRESS.into(), what });
        };
        // The first servo sample at or after the trigger, at a random sampling phase.
        let step = r.feed_mm_s * self.cfg.servo_period_s;
        let s_latch = (s_trigger + step * noise::uniform(&mut self.rng, 0.0, 1.0)).min(len);
        let latched = start + u * s_latch + self.position_noise();
        // After braking, the machine retracts along the approach direction from the latch.
        self.pos = latched + r.approach * r.retract_mm;
        Ok(ProbeHit { tip_center_mm: latched, normal: None })
    }

    fn abort(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }

    fn rotary_axes(&self) -> RotaryAxes {
        self.cfg.rotary
    }

    fn rotary_kinematics(&self) -> Option<RotaryKinematics> {
        self.trt
            .map(|_| RotaryKinematics { model: "xyzbc-trt".into(), module: "virtual xyzbc-trt-kins".into() })
    }

    fn orientation(&mut self) -> Result<(f64, f64), DeviceError> {
        Ok(match &self.trt {
            Some(t) => (t.b_deg, t.c_deg),
            None => (self.b.to_degrees(), self.c.to_degrees()),
        })
    }

    fn kinematics_parameters(&mut self) -> Result<Vec<KinematicsParameter>, DeviceError> {
        match &self.trt {
            Some(t) => Ok(t.configured.parameters()),
            None => Err(DeviceError::Rejected {
                address: ADDRESS.into(),
                what: "reading the kinematics parameters".into(),
                message: "this virtual machine has no five-axis kinematics".into(),
            }),
        }
    }

    /// Only at B = C = 0, as on a real controller.
    fn set_kinematics_parameters(&mut self, values: &[KinematicsParameter]) -> Result<(), DeviceError> {
        let what = "writing the kinematics parameters";
        let reject =
            |message: String| DeviceError::Rejected { address: ADDRESS.into(), what: what.into(), message };
        let Some(t) = self.trt.as_mut() else {
            return Err(reject("this virtual machine has no five-axis kinematics".into()));
        };
        if t.b_deg != 0.0 || t.c_deg != 0.0 {
            return Err(reject(format!(
                "the table is at B = {} C = {}: the geometry may be changed only at B = C = 0",
                t.b_deg, t.c_deg
            )));
        }
        let mut v = t.configured.values();
        for p in values {
            let k = truepos_kinematics::trt::PINS
                .iter()
                .position(|n| *n == p.name)
                .filter(|_| p.value_mm.is_finite())
                .ok_or_else(|| {
                    reject(format!("`{}` = {} is not a geometry pin value", p.name, p.value_mm))
                })?;
            v[k] = p.value_mm;
        }
        t.configured = TrtGeometry::from_values(v);
        Ok(())
    }

    /// Turns the axes at once; a ball that ends up in the material is an error (the angles are
    /// then left as they were).
    fn orient(&mut self, b_deg: f64, c_deg: f64) -> Result<(), DeviceError> {
        let what = format!("orienting the head to B = {b_deg}°, C = {c_deg}°");
        let reject =
            |message: String| DeviceError::Rejected { address: ADDRESS.into(), what: what.clone(), message };
        if !(b_deg.is_finite() && c_deg.is_finite()) {
            return Err(reject("the angles must be finite".into()));
        }
        if b_deg != 0.0 && !self.cfg.rotary.head_b && self.trt.is_none() {
            return Err(reject(format!("this machine has no B axis ({})", self.cfg.rotary.describe())));
        }
        if c_deg != 0.0 && !self.cfg.rotary.table_c {
            return Err(reject(format!("this machine has no C axis ({})", self.cfg.rotary.describe())));
        }
        if self.trt.is_some() && b_deg.abs() > 120.0 {
            return Err(reject(format!("B = {b_deg}° is beyond the B axis's travel (±120°)")));
        }
        let (b0, c0) = (self.b, self.c);
        (self.b, self.c) = (b_deg.to_radians(), c_deg.to_radians());
        if let Some(t) = self.trt.as_mut() {
            (t.b_deg, t.c_deg) = (b_deg, c_deg);
        }
        let r = self.cfg.tip_radius_mm;
        if self.artefacts().any(|a| a.distance(&self.pos) - r <= 0.0) {
            (self.b, self.c) = (b0, c0);
            if let Some(t) = self.trt.as_mut() {
                (t.b_deg, t.c_deg) = (b0.to_degrees(), c0.to_degrees());
            }
            return Err(DeviceError::Controller {
                address: ADDRESS.into(),
                what,
                message: format!("the probe would collide at {}: move it clear first", fmt_point(&self.pos)),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn machine() -> VirtualMachineTool {
        VirtualMachineTool::new(MachineToolConfig::default()).unwrap()
    }

    #[test]
    fn latches_within_one_servo_step_past_the_trigger() {
        let mut m = machine();
        let c = Point3::new(120.0, 45.0, 30.0);
        for feed_mm_min in [50.0, 200.0, 1000.0] {
            let r = ProbeRequest {
                nominal_mm: c + Vector3::z() * 12.5,
                approach: Vector3::z(),
                tip_radius_mm: 1.5,
                approach_mm: 1.0,
                search_mm: 1.0,
                retract_mm: 1.0,
                feed_mm_s: feed_mm_min / 60.0,
            };
            m.move_to(r.start_mm()).unwrap();
            let hit = m.probe(&r).unwrap();
            // Trigger at 14 mm + pre-travel from the centre; latch up to one servo step and
            // the position noise (5σ) further in.
            let depth = 14.0 - (hit.tip_center_mm - c).norm();
            let step = feed_mm_min / 60.0 * 1e-3;
            assert!(depth >= 0.0005 - 5e-4 && depth <= 0.0005 + step + 5e-4, "{depth}");
            assert!((m.position().unwrap() - (hit.tip_center_mm + Vector3::z())).norm() < 1e-12);
        }
    }

    #[test]
    fn a_miss_is_no_contact_back_at_the_start_and_a_collision_is_an_error() {
        let mut m = machine();
        let r = ProbeRequest {
            nominal_mm: Point3::new(0.0, 0.0, 0.0),
            approach: Vector3::z(),
            tip_radius_mm: 1.5,
            approach_mm: 1.0,
            search_mm: 1.0,
            retract_mm: 1.0,
            feed_mm_s: 1.0,
        };
        match m.probe(&r) {
            Err(DeviceError::NoContact { address, .. }) => assert_eq!(address, "virtual"),
            other => panic!("{other:?}"),
        }
        assert_eq!(m.position().unwrap(), r.start_mm());
        // Straight through the sphere.
        m.move_to(Point3::new(120.0, 45.0, 60.0)).unwrap();
        let e = m.move_to(Point3::new(120.0, 45.0, 0.0)).unwrap_err();
        assert!(e.to_string().contains("probe tripped"), "{e}");
        assert!((m.position().unwrap().z - (44.0 - 0.0005)).abs() < 1e-6);
        assert!(m.move_to(Point3::new(5000.0, 0.0, 0.0)).is_err());
    }

    #[test]
    fn plates_of_different_heights_that_overlap_are_refused() {
        let a = (Point3::new(0.0, 0.0, 0.0), 10.0);
        let b = (Point3::new(30.0, 0.0, -5.0), 10.0);
        assert!(MachineToolConfig::with_holes(1, &[a, b], 1.5).unwrap_err().contains("too close"));
        let far = (Point3::new(300.0, 0.0, -5.0), 10.0);
        let (cfg, truth) = MachineToolConfig::with_holes(1, &[a, far], 1.5).unwrap();
        assert_eq!((cfg.parts.len(), truth.len()), (2, 2));
        assert_eq!(truth[1].top_mm.z, -5.0);
    }

    #[test]
    fn orienting_needs_the_axes_and_a_clear_probe() {
        let mut m = machine();
        let e = m.orient(90.0, 0.0).unwrap_err();
        assert!(matches!(e, DeviceError::Rejected { .. }) && e.to_string().contains("no B axis"), "{e}");
        let cfg = MachineToolConfig {
            rotary: RotaryAxes { head_b: true, table_c: true },
            head_offset_mm: Vector3::new(0.0, 0.0, -30.0),
            // P 20 mm above the sphere's top: the tip (30 mm below P at B = 0) is inside it.
            start_mm: Point3::new(120.0, 45.0, 30.0 + 12.5 + 20.0),
            ..MachineToolConfig::default()
        };
        let mut m = VirtualMachineTool::new(cfg).unwrap();
        m.orient(180.0, 0.0).unwrap(); // tip 30 mm above P: clear
        let e = m.orient(0.0, 0.0).unwrap_err();
        assert!(matches!(e, DeviceError::Controller { .. }) && e.to_string().contains("collide"), "{e}");
        // Still at B = 180°: moving P down 10 mm keeps the tip clear.
        m.move_to(Point3::new(120.0, 45.0, 52.5)).unwrap();
    }
}
