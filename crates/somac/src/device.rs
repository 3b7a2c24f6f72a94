//! The devices the loop talks to. A real installation implements these over its controller's
//! interface and its trackers' SDKs; [`crate::virtual_cell`] implements them on the simulator.

use thiserror::Error;
use truepos_math::air::AirConditions;
use truepos_math::{Point3, Vector3};

#[derive(Debug, Error, Clone, PartialEq)]
pub enum DeviceError {
    #[error("controller: {0}")]
    Controller(String),
    #[error("tracker {0}: {1}")]
    Tracker(usize, String),
}

/// Why a tracker reading failed.
#[derive(Debug, Error, Clone, Copy, PartialEq, Eq)]
pub enum TrackerFault {
    #[error("beam broken (no line of sight to the reflector)")]
    BeamBroken,
    #[error("the tracker lost the reflector and needs it brought back")]
    Lost,
}

/// An NC controller fed one block at a time.
pub trait Controller {
    /// Execute one block; returns when the machine has come to its commanded stop.
    /// `target_mm` is the block's commanded end position (program frame = machine frame) if
    /// it moves. The controller adds its external correction offset to every target.
    fn send_block(&mut self, line: usize, text: &str, target_mm: Option<Point3>) -> Result<(), DeviceError>;
    /// An incremental correction move, which also shifts the external offset by `delta_mm`.
    fn correct(&mut self, delta_mm: Vector3) -> Result<(), DeviceError>;
    /// The external correction offset now in force.
    fn offset(&self) -> Vector3;
    /// Move to a commanded position (plus offset), for look-back recovery.
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError>;
    /// Let time pass (waiting for the machine to settle, for an operator, …).
    fn wait(&mut self, seconds: f64);
    /// Time since the start of the run (s).
    fn now_s(&self) -> f64;
}

/// A laser tracker measuring the end effector's reflector.
pub trait Tracker {
    /// One reading of the reflector (tracker frame, mm).
    fn measure(&mut self) -> Result<Point3, TrackerFault>;
    /// Point the beam at a position (tracker frame) and lock on when the reflector arrives.
    /// Only absolute-distance (ADM) trackers can reacquire this way.
    fn point_at(&mut self, p: Point3) -> Result<(), TrackerFault>;
    fn has_adm(&self) -> bool;
    /// Set the refractive index the tracker uses for its distances.
    fn set_refractive_index(&mut self, n: f64);
    fn refractive_index(&self) -> f64;
    /// Standard uncertainty (mm) of a reading at `p` (tracker frame), for fusion weights.
    fn sigma_mm(&self, p: &Point3) -> f64;
}

/// Differential inclinometer readings (µrad, two tilt components each).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Inclinations {
    pub machine: [f64; 2],
    pub part: [f64; 2],
    pub tracker: [f64; 2],
}

impl Inclinations {
    /// The largest change of any component relative to `base`.
    pub fn max_change(&self, base: &Inclinations) -> f64 {
        let mut m = 0.0f64;
        for (a, b) in [(self.machine, base.machine), (self.part, base.part), (self.tracker, base.tracker)] {
            for k in 0..2 {
                m = m.max((a[k] - b[k]).abs());
            }
        }
        m
    }
}

/// The rest of the cell: sensors and the targets the trackers measure directly.
pub trait Cell {
    /// Part temperature (°C).
    fn temperature_c(&mut self) -> f64;
    fn air(&mut self) -> AirConditions;
    fn inclinations(&mut self) -> Inclinations;
    /// Tracker `k`'s readings of the part's targets (id, tracker frame) — for real-time
    /// orientation and auto-scaling. Nominal positions are in [`Cell::part_nominal`].
    fn measure_part_targets(&mut self, k: usize) -> Vec<(String, Point3)>;
    /// Nominal positions of the part's targets at the reference temperature (program frame).
    fn part_nominal(&self) -> Vec<(String, Point3)>;
    /// Tracker `k`'s readings of the machine's reference targets (tracker frame), and their
    /// calibrated machine-frame positions — for (re-)aligning the tracker to the machine.
    fn measure_machine_targets(&mut self, k: usize) -> Vec<(String, Point3)>;
    fn machine_targets(&self) -> Vec<(String, Point3)>;
    /// An operator brings the reflector back into the beam (manual recovery).
    fn operator_restores_beam(&mut self, k: usize);
}
