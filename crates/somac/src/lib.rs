//! # truepos-somac — laser-tracker end-point control of large NC machines
//!
//! The machine keeps its own controller and encoders; an independent 3D measurement (laser
//! trackers on a reflector at the end effector, taken while the machine is stopped) closes the
//! loop. The program is trickle-fed one block at a time; at every block marked by the keyword
//! (default the comment `(MSG,Measure SOMaC)`) the loop waits for a stable reading, compares it
//! with the commanded position and sends incremental corrections until the error is within the
//! threshold or the iteration limit is reached, within the single- and total-correction limits.
//!
//! Entry points:
//! - [`align::align_files`]: the best-fit transform between two point files (`truepos align`).
//! - [`params::Params`]: the user parameters and alarm set points.
//! - [`device`]: the [`device::Controller`], [`device::Tracker`] and [`device::Cell`] traits a
//!   real installation or the virtual cell implements.
//! - [`run::run_program`]: the measure / compare / correct loop with alarms, real-time
//!   orientation, auto-scaling, refractive-index updates, multi-tracker fusion and beam-break
//!   recovery; it reports every event to an [`audit::AuditSink`].
//! - [`scale`]: the part's scale factor from its targets, with its uncertainty
//!   ([`scale::autoscale_files`]: `truepos autoscale`).
//! - [`orient::orient_file`]: a G-code program rewritten through the fit of measured targets
//!   (`truepos orient`).
//! - [`fusion`]: weighted fusion of several trackers' readings.
//! - [`stats`]: hole true-position statistics and capability in ppm of the diagonal.
//! - [`inspect`]: in-spindle probe inspection of the holes through any `ProbingMachine`
//!   (position error and diameter per hole; `truepos somac inspect`).
//!
//! The virtual large gantry with trackers that implements these traits on the simulator lives
//! in `truepos-cell` (`truepos_plant::gantry`); this crate never depends on the simulator.

#![forbid(unsafe_code)]

pub mod align;
pub mod audit;
pub mod device;
pub mod fusion;
pub mod inspect;
pub mod orient;
pub mod params;
pub mod run;
pub mod scale;
pub mod stats;

pub use params::Params;
pub use run::{run_program, Alarm, AlarmKind, RunReport, StopReport, StopStatus};
