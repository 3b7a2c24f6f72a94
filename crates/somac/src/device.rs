//! The devices the loop talks to: re-exported from `truepos-device`, where every backend
//! (virtual cell, LinuxCNC, I++ DME) finds them. `truepos_plant::gantry` implements them on the
//! simulator.

pub use truepos_device::{Cell, Controller, DeviceError, Inclinations, Tracker, TrackerFault, TrackerSetup};
