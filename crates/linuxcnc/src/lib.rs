//! # truepos-linuxcnc — LinuxCNC 2.9 through linuxcncrsh
//!
//! LinuxCNC's `linuxcncrsh` is a line-based TCP interface to its task controller. This crate
//! drives it behind truepos's device traits, so the probing procedures and the end-point
//! control loop that run on the virtual machines run on a real controller unchanged.
//!
//! Entry points:
//! - [`LinuxCnc::open`] (`linuxcncrsh://HOST:PORT[?password=…]`): one session, readiness checks
//!   (out of e-stop, on, homed, idle — truepos never releases an e-stop or switches a machine
//!   on), then [`truepos_device::ProbingMachine`] (G38.2 probing with the latched point read
//!   back) and [`truepos_device::Controller`] (moves and correction moves for `somac`).
//! - [`LinuxCnc::attach_kinematics`]: a five-axis machine (`xyzbc-trt-kins` with
//!   tool-centre-point control): `orient` turns the table with `G0 B C`, and the kinematics
//!   module's geometry pins are read and written through [`hal`] (`halcmd` on the controller's
//!   host, as the user that runs LinuxCNC) for `truepos kinematics calibrate`.
//! - [`url::Address`]: the address and its passwords.
//! - [`harness::SimLinuxCnc`]: a simulated LinuxCNC with a virtual reference sphere on the probe
//!   input, started headless for integration tests.
//!
//! Every failure is a [`truepos_device::DeviceError`] naming the address and, where the
//! controller said something, its own message.

#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]

pub mod hal;
pub mod harness;
mod machine;
mod session;
pub mod url;

pub use machine::{LinuxCnc, Options};
pub use url::Address;
