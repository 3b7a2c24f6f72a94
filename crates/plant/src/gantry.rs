//! The virtual large gantry cell behind the `truepos-device` traits: a 12 m × 4 m × 2 m gantry
//! (the simulator's exact kinematic chain with geometric errors and thermal growth of its
//! scales), a part (a wing spar) placed with a misalignment and expanding with its temperature,
//! end-effector vibration after every move (so a reading taken too early is unstable), laser
//! trackers (the simulator's [`truepos_sim::tracker::Tracker`]: MPE noise model, refractive
//! index true vs assumed, obstructed lines of sight) with random beam interruptions and lost
//! reflectors, inclinometers, and a tracker that can be bumped (its pose changes: the
//! inclinometers see it).
//!
//! Entry points: [`CellConfig`] (everything a scenario varies; `Default` is the demo cell),
//! [`VirtualCell::new`] (the shared world), [`VirtualCell::controller`],
//! [`VirtualCell::sensors`], [`VirtualCell::align_trackers`],
//! [`VirtualCell::hole_errors`] (truth: drilled position against the warm part's true hole).

use rand::Rng;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;
use truepos_device::{Cell, Controller, DeviceError, Inclinations, Tracker, TrackerFault};
use truepos_math::air::{refractive_index, AirConditions, Formula};
use truepos_math::types::{rx, rz};
use truepos_math::{Point3, Transform3, Vector3};
use truepos_sim::errors::{ErrorMagnitudes, GeometricErrors};
use truepos_sim::machine::Machine;
use truepos_sim::noise::{self, SimRng};
use truepos_sim::thermal::{Part, Step, TemperatureHistory, ThermalModel};
use truepos_sim::tracker::BeamBreak;
use truepos_somac::run::TrackerSetup;

/// An axis-aligned box (machine frame) that blocks a tracker's line of sight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstruction {
    /// Lower corner, machine frame, mm.
    pub min: [f64; 3],
    /// Upper corner, machine frame, mm.
    pub max: [f64; 3],
}

/// One laser tracker of the cell: where it stands, how it is turned, what it can do.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Tracker head position in the machine frame (mm).
    pub position_mm: [f64; 3],
    /// Rotation of the tracker frame about Z relative to the machine (deg).
    pub yaw_deg: f64,
    /// Absolute distance meter (can reacquire by pointing: look-ahead recovery).
    pub adm: bool,
    /// Boxes blocking this tracker's line of sight.
    pub obstructions: Vec<Obstruction>,
}

/// Everything a scenario of the virtual gantry cell varies; `Default` is the demo cell.
#[derive(Debug, Clone, PartialEq)]
pub struct CellConfig {
    /// Seed of every random draw of the cell.
    pub seed: u64,
    /// Multiplier on the gantry class's geometric error magnitudes (a worn machine > 1).
    pub error_scale: f64,
    /// Shop air temperature over time (°C).
    pub air_temperature: TemperatureHistory,
    /// Air pressure at the start, Pa.
    pub pressure_pa: f64,
    /// Pressure drift (Pa/h).
    pub pressure_drift_pa_per_h: f64,
    /// Relative humidity, %.
    pub humidity_pct: f64,
    /// Part CTE (1/K) and thermal time constant (s).
    pub part_cte: f64,
    /// Part thermal time constant, s.
    pub part_tau_s: f64,
    /// Actual placement of the part relative to its nominal (program) placement:
    /// rotation about Z (µrad) and translation (mm).
    pub placement_rz_urad: f64,
    /// Translation of the actual placement, mm.
    pub placement_mm: [f64; 3],
    /// Reflector (drill point) offset from the ram reference point (mm, ram frame).
    pub tool_offset_mm: [f64; 3],
    /// End-effector vibration after a move: amplitude (mm), frequency (Hz), decay time (s).
    pub vibration_mm: f64,
    /// End-effector vibration frequency, Hz.
    pub vibration_hz: f64,
    /// End-effector vibration decay time, s.
    pub vibration_tau_s: f64,
    /// Speed of the machine's moves, mm/s.
    pub move_speed_mm_s: f64,
    /// Time between tracker samples (s).
    pub sample_interval_s: f64,
    /// The laser trackers.
    pub trackers: Vec<TrackerConfig>,
    /// Tracker angular and distance noise: MPE ±(a + b·d) taken as 2σ (mm, mm/m).
    pub tracker_mpe_a_mm: f64,
    /// Tracker MPE, per-distance part b, mm/m.
    pub tracker_mpe_b_mm_per_m: f64,
    /// Probability that someone walks through the beam at a reading.
    pub beam_interrupt_probability: f64,
    /// A tracker is bumped at this time (s): (time, tracker, tilt µrad).
    pub tracker_bump: Option<(f64, usize, f64)>,
}

impl Default for CellConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            error_scale: 3.0,
            air_temperature: TemperatureHistory {
                base: 23.5,
                drift: 1.5 / 3600.0,
                steps: vec![Step { time: 1500.0, delta: 0.8 }],
                cycle_amplitude: 0.3,
                cycle_period: 1800.0,
                cycle_phase: 0.0,
            },
            pressure_pa: 100_800.0,
            pressure_drift_pa_per_h: -600.0,
            humidity_pct: 45.0,
            part_cte: 23.0e-6,
            part_tau_s: 1200.0,
            placement_rz_urad: 150.0,
            placement_mm: [1.2, -0.8, 0.3],
            tool_offset_mm: [0.0, 0.0, -350.0],
            vibration_mm: 0.05,
            vibration_hz: 6.0,
            vibration_tau_s: 0.35,
            move_speed_mm_s: 300.0,
            sample_interval_s: 0.02,
            trackers: vec![
                TrackerConfig {
                    position_mm: [3000.0, -3000.0, 1200.0],
                    yaw_deg: 30.0,
                    adm: true,
                    obstructions: vec![Obstruction {
                        min: [5200.0, -2500.0, -500.0],
                        max: [5600.0, -1000.0, 3000.0],
                    }],
                },
                TrackerConfig {
                    position_mm: [9000.0, -3000.0, 1200.0],
                    yaw_deg: -20.0,
                    adm: true,
                    obstructions: vec![],
                },
            ],
            tracker_mpe_a_mm: 0.015,
            tracker_mpe_b_mm_per_m: 0.006,
            beam_interrupt_probability: 0.002,
            tracker_bump: Some((900.0, 1, 120.0)),
        }
    }
}

struct TrackerState {
    /// The simulator's tracker: true pose (changes when bumped), MPE noise model, refractive
    /// index (true and assumed), obstructions.
    sim: truepos_sim::tracker::Tracker,
    adm: bool,
    /// Lost the reflector after a beam break, until reacquired.
    lost: bool,
    bumped: bool,
    tilt_urad: f64,
}

/// The shared simulated world.
pub struct World {
    cfg: CellConfig,
    t: f64,
    machine: Machine,
    thermal: ThermalModel,
    part: Part,
    /// actual_from_nominal placement of the part.
    placement: Transform3,
    tool: Vector3,
    axes: Point3,
    offset: Vector3,
    last_move_end: f64,
    vib_dir: Vector3,
    rng: SimRng,
    trackers: Vec<TrackerState>,
    current_line: usize,
    /// Per program line: time and static actual reflector position after its last motion.
    line_states: BTreeMap<usize, (f64, Point3)>,
    machine_targets: Vec<(String, Point3)>,
    part_targets: Vec<(String, Point3)>,
}

impl World {
    fn growth_at(&self, t: f64) -> [f64; 3] {
        self.thermal.axis_growth(t)
    }

    /// Static (settled) actual reflector position.
    fn reflector_static(&mut self) -> Point3 {
        self.machine.chain.growth = self.growth_at(self.t);
        self.machine.tip(&self.axes, &self.tool)
    }

    fn reflector_now(&mut self) -> Point3 {
        let dt = (self.t - self.last_move_end).max(0.0);
        let a = self.cfg.vibration_mm
            * (-dt / self.cfg.vibration_tau_s).exp()
            * (std::f64::consts::TAU * self.cfg.vibration_hz * dt).sin();
        self.reflector_static() + a * self.vib_dir
    }

    fn air(&self) -> AirConditions {
        AirConditions {
            temperature_c: self.cfg.air_temperature.at(self.t),
            pressure_pa: self.cfg.pressure_pa + self.cfg.pressure_drift_pa_per_h * self.t / 3600.0,
            humidity_pct: self.cfg.humidity_pct,
            co2_ppm: 450.0,
            wavelength_nm: 633.0,
        }
    }

    fn n_true(&self) -> f64 {
        refractive_index(&self.air(), Formula::Ciddor).unwrap_or(1.00027)
    }

    fn apply_bump(&mut self) {
        if let Some((tb, k, tilt)) = self.cfg.tracker_bump {
            if self.t >= tb && k < self.trackers.len() && !self.trackers[k].bumped {
                let tr = &mut self.trackers[k];
                // Tilt about the tracker's own X axis, through its head.
                let m_from_t = tr.sim.cell_from_tracker;
                tr.sim.cell_from_tracker = m_from_t * Transform3::rigid(rx(tilt * 1e-6), Vector3::zeros());
                tr.bumped = true;
                tr.tilt_urad = tilt;
            }
        }
    }

    fn line_of_sight(&self, k: usize, p: &Point3) -> bool {
        let tr = &self.trackers[k].sim;
        let a = tr.position();
        !tr.beam_breaks.iter().any(|b| b.blocks(&a, p, self.t))
    }

    /// A noisy reading of the machine-frame point `p` by tracker `k` (tracker frame), with the
    /// simulator's MPE model and the true refractive index of the air now.
    fn observe(&mut self, k: usize, p: &Point3) -> Point3 {
        let n = self.n_true();
        let t = self.t;
        let tr = &mut self.trackers[k].sim;
        tr.n_true = n;
        match tr.measure(p, t, &mut self.rng) {
            Ok(r) => r.to_tracker_point(),
            // Callers check the line of sight first; out of range cannot happen in the cell.
            Err(_) => tr.cell_from_tracker.inverse().apply(p),
        }
    }

    /// Tracker `k`'s readings of static nests at the given machine-frame positions (those in
    /// its line of sight), each the mean of many readings.
    fn measure_nests(&mut self, k: usize, nests: &[(String, Point3)]) -> Vec<(String, Point3)> {
        let mut out = vec![];
        for (id, p) in nests {
            if self.line_of_sight(k, p) {
                let mut acc = Vector3::zeros();
                for _ in 0..NEST_READINGS {
                    acc += self.observe(k, p).coords;
                }
                out.push((id.clone(), Point3::from(acc / NEST_READINGS as f64)));
            }
        }
        out
    }

    /// 3D standard uncertainty of one reading at distance `d_mm`.
    fn sigma(&self, k: usize, d_mm: f64) -> f64 {
        let tr = &self.trackers[k].sim;
        let (st, sd) = (tr.sigma_transverse(d_mm), tr.sigma_distance(d_mm));
        (2.0 * st * st + sd * sd).sqrt()
    }
}

/// The virtual cell: one world shared by the controller, the trackers and the sensors.
#[derive(Clone)]
pub struct VirtualCell {
    world: Rc<RefCell<World>>,
}

impl VirtualCell {
    /// Build the cell. `part_targets` and `holes` are nominal (program-frame) positions.
    pub fn new(cfg: CellConfig, part_targets: Vec<(String, Point3)>) -> VirtualCell {
        let mut rng = noise::stream(cfg.seed, 11);
        let mut mags = ErrorMagnitudes::gantry();
        mags.positioning *= cfg.error_scale;
        mags.straightness *= cfg.error_scale;
        mags.angular *= cfg.error_scale;
        mags.squareness *= cfg.error_scale;
        let errors = GeometricErrors::realistic(&mut rng, &mags);
        let machine = Machine::gantry(errors);
        let thermal = ThermalModel::steel(cfg.air_temperature.clone());
        let part = Part {
            cte: cfg.part_cte,
            fixed: Point3::new(0.0, 0.0, 0.0),
            air: cfg.air_temperature.clone(),
            tau: cfg.part_tau_s,
        };
        let placement = Transform3::rigid(rz(cfg.placement_rz_urad * 1e-6), Vector3::from(cfg.placement_mm));
        let trackers = cfg
            .trackers
            .iter()
            .map(|tc| {
                // machine_from_tracker: origin at the head, rotated by yaw about Z.
                let m_from_t = Transform3::rigid(rz(tc.yaw_deg.to_radians()), Vector3::from(tc.position_mm));
                let mut sim = truepos_sim::tracker::Tracker::new(m_from_t);
                sim.mpe_const = cfg.tracker_mpe_a_mm;
                sim.mpe_per_length = cfg.tracker_mpe_b_mm_per_m * 1e-3;
                sim.distance_mpe_const = cfg.tracker_mpe_a_mm;
                sim.distance_mpe_per_length = cfg.tracker_mpe_b_mm_per_m * 1e-3;
                // The MPE bounds the 3D point error (as ~2σ): σ per component = MPE / (2√3).
                sim.sigma_fraction = 0.5 / 3f64.sqrt();
                sim.beam_breaks = tc
                    .obstructions
                    .iter()
                    .map(|o| BeamBreak::Box { min: Point3::from(o.min), max: Point3::from(o.max) })
                    .collect();
                TrackerState { sim, adm: tc.adm, lost: false, bumped: false, tilt_urad: 0.0 }
            })
            .collect();
        let t = machine.travel;
        let machine_targets: Vec<(String, Point3)> = (0..8)
            .map(|i| {
                let x = if i % 4 < 2 { 200.0 } else { t[0] - 200.0 };
                let y = if i % 2 == 0 { -200.0 } else { t[1] + 200.0 };
                let z = if i < 4 { -300.0 } else { 100.0 };
                (format!("M{i}"), Point3::new(x + 37.0 * i as f64, y, z))
            })
            .collect();
        let vib_dir = Vector3::new(1.0, 0.6, 0.25).normalize();
        let tool = Vector3::from(cfg.tool_offset_mm);
        let world = World {
            cfg,
            t: 0.0,
            machine,
            thermal,
            part,
            placement,
            tool,
            axes: Point3::new(100.0, 100.0, 1500.0),
            offset: Vector3::zeros(),
            last_move_end: -100.0,
            vib_dir,
            rng,
            trackers,
            current_line: 0,
            line_states: BTreeMap::new(),
            machine_targets,
            part_targets,
        };
        VirtualCell { world: Rc::new(RefCell::new(world)) }
    }

    /// The cell's CNC controller (the machine the loop commands).
    pub fn controller(&self) -> VirtualController {
        VirtualController { world: self.world.clone() }
    }

    /// The cell's sensors (air, temperatures, inclinometers, targets).
    pub fn sensors(&self) -> VirtualSensors {
        VirtualSensors { world: self.world.clone() }
    }

    /// Trackers aligned to the machine on its reference targets (three-dimensional best fit),
    /// after setting their refractive index from the cell's air sensors, as an operator does.
    /// Fails when a tracker sees fewer than three non-collinear reference targets.
    pub fn align_trackers(
        &self,
    ) -> Result<Vec<TrackerSetup<VirtualTracker>>, truepos_math::bestfit::BestFitError> {
        let n_air = {
            let w = self.world.borrow();
            w.n_true()
        };
        for t in self.world.borrow_mut().trackers.iter_mut() {
            t.sim.n_assumed = n_air;
        }
        let n = self.world.borrow().trackers.len();
        let mut sensors = self.sensors();
        (0..n)
            .map(|k| {
                let seen = sensors.measure_machine_targets(k);
                let refs = sensors.machine_targets();
                let m = truepos_somac::run::machine_from_tracker(&seen, &refs)?;
                Ok(TrackerSetup {
                    tracker: VirtualTracker { world: self.world.clone(), k },
                    machine_from_tracker: m,
                })
            })
            .collect()
    }

    /// True 3D error (mm) of the drilled position at each given program line: the settled
    /// reflector position after the line's last motion against the true position of the hole
    /// (nominal `holes[line]` on the placed part at its temperature at that time).
    pub fn hole_errors(&self, holes: &BTreeMap<usize, Point3>) -> Vec<(usize, f64)> {
        let w = self.world.borrow();
        holes
            .iter()
            .filter_map(|(line, nominal)| {
                let (t, actual) = w.line_states.get(line)?;
                let truth = w.placement.apply(&w.part.position(nominal, *t));
                Some((*line, (actual - truth).norm()))
            })
            .collect()
    }

    /// The machine's travel diagonal (mm), for capability in ppm.
    pub fn diagonal_mm(&self) -> f64 {
        let t = self.world.borrow().machine.travel;
        (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt()
    }

    /// The cell's simulated time since the start, s.
    pub fn time_s(&self) -> f64 {
        self.world.borrow().t
    }
}

/// The virtual gantry's CNC controller (a view of the shared cell).
pub struct VirtualController {
    world: Rc<RefCell<World>>,
}

impl VirtualController {
    fn go(&mut self, target: Point3) {
        let mut w = self.world.borrow_mut();
        let axes = target + w.offset - w.tool;
        let dist = (axes - w.axes).norm();
        w.t += dist / w.cfg.move_speed_mm_s + if dist > 0.0 { 0.6 } else { 0.0 };
        w.axes = axes;
        if dist > 0.0 {
            w.last_move_end = w.t;
        }
        w.apply_bump();
        let line = w.current_line;
        let p = w.reflector_static();
        let t = w.t;
        w.line_states.insert(line, (t, p));
    }
}

impl Controller for VirtualController {
    fn send_block(&mut self, line: usize, _text: &str, target_mm: Option<Point3>) -> Result<(), DeviceError> {
        self.world.borrow_mut().current_line = line;
        match target_mm {
            Some(p) => self.go(p),
            None => self.world.borrow_mut().t += 0.01,
        }
        Ok(())
    }

    fn correct(&mut self, delta_mm: Vector3) -> Result<(), DeviceError> {
        if !delta_mm.iter().all(|v| v.is_finite()) {
            return Err(DeviceError::Rejected {
                address: "virtual".into(),
                what: "correction move".into(),
                message: "correction is not finite".into(),
            });
        }
        let mut w = self.world.borrow_mut();
        w.offset += delta_mm;
        w.axes += delta_mm;
        w.t += delta_mm.norm() / 20.0 + 0.4;
        w.last_move_end = w.t;
        w.apply_bump();
        let line = w.current_line;
        let p = w.reflector_static();
        let t = w.t;
        w.line_states.insert(line, (t, p));
        Ok(())
    }

    fn offset(&self) -> Vector3 {
        self.world.borrow().offset
    }

    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        self.go(target_mm);
        Ok(())
    }

    fn wait(&mut self, seconds: f64) {
        let mut w = self.world.borrow_mut();
        w.t += seconds.max(0.0);
        w.apply_bump();
    }

    fn now_s(&self) -> f64 {
        self.world.borrow().t
    }
}

/// One virtual laser tracker of the cell (a view of the shared cell).
pub struct VirtualTracker {
    world: Rc<RefCell<World>>,
    k: usize,
}

impl Tracker for VirtualTracker {
    fn measure(&mut self) -> Result<Point3, TrackerFault> {
        let mut w = self.world.borrow_mut();
        let dt = w.cfg.sample_interval_s;
        w.t += dt;
        let k = self.k;
        if w.trackers[k].lost {
            return Err(TrackerFault::Lost);
        }
        let p = w.reflector_now();
        let q = w.cfg.beam_interrupt_probability;
        if !w.line_of_sight(k, &p) || w.rng.random::<f64>() < q {
            w.trackers[k].lost = true;
            return Err(TrackerFault::BeamBroken);
        }
        Ok(w.observe(k, &p))
    }

    fn point_at(&mut self, p: Point3) -> Result<(), TrackerFault> {
        let mut w = self.world.borrow_mut();
        let k = self.k;
        if !w.trackers[k].adm {
            return Err(TrackerFault::Lost);
        }
        let actual = w.reflector_static();
        let aimed = w.trackers[k].sim.cell_from_tracker.apply(&p);
        if (aimed - actual).norm() < 5.0 && w.line_of_sight(k, &actual) {
            w.trackers[k].lost = false;
            Ok(())
        } else {
            Err(TrackerFault::BeamBroken)
        }
    }

    fn has_adm(&self) -> bool {
        self.world.borrow().trackers[self.k].adm
    }

    fn set_refractive_index(&mut self, n: f64) {
        self.world.borrow_mut().trackers[self.k].sim.n_assumed = n;
    }

    fn refractive_index(&self) -> f64 {
        self.world.borrow().trackers[self.k].sim.n_assumed
    }

    fn sigma_mm(&self, p: &Point3) -> f64 {
        self.world.borrow().sigma(self.k, p.coords.norm())
    }
}

/// Readings averaged on a static target nest (part or machine reference).
const NEST_READINGS: usize = 100;

/// The virtual cell's sensors and targets (a view of the shared cell).
pub struct VirtualSensors {
    world: Rc<RefCell<World>>,
}

impl Cell for VirtualSensors {
    fn temperature_c(&mut self) -> f64 {
        let w = self.world.borrow();
        w.part.temperature(w.t)
    }

    fn air(&mut self) -> AirConditions {
        self.world.borrow().air()
    }

    fn inclinations(&mut self) -> Inclinations {
        let mut w = self.world.borrow_mut();
        let noise = [noise::gaussian(&mut w.rng, 1.0), noise::gaussian(&mut w.rng, 1.0)];
        let tilt = w.trackers.iter().map(|t| t.tilt_urad).fold(0.0, f64::max);
        Inclinations { machine: noise, part: [0.0, 0.0], tracker: [tilt, 0.0] }
    }

    fn measure_part_targets(&mut self, k: usize) -> Vec<(String, Point3)> {
        let mut w = self.world.borrow_mut();
        let t = w.t;
        let actual: Vec<(String, Point3)> = w
            .part_targets
            .iter()
            .map(|(id, nominal)| (id.clone(), w.placement.apply(&w.part.position(nominal, t))))
            .collect();
        let out = w.measure_nests(k, &actual);
        w.t += 20.0;
        out
    }

    fn part_nominal(&self) -> Vec<(String, Point3)> {
        self.world.borrow().part_targets.clone()
    }

    fn measure_machine_targets(&mut self, k: usize) -> Vec<(String, Point3)> {
        let mut w = self.world.borrow_mut();
        let targets = w.machine_targets.clone();
        let out = w.measure_nests(k, &targets);
        w.t += 30.0;
        out
    }

    fn machine_targets(&self) -> Vec<(String, Point3)> {
        self.world.borrow().machine_targets.clone()
    }

    fn operator_restores_beam(&mut self, k: usize) {
        let mut w = self.world.borrow_mut();
        let p = w.reflector_static();
        if w.line_of_sight(k, &p) {
            w.trackers[k].lost = false;
        }
    }
}
