//! # truepos-kinematics — the rotary axes of five-axis controllers
//!
//! A five-axis controller with tool-centre-point control turns every programme position with
//! its rotary axes, using the geometry its kinematics module is configured with: where the C
//! axis is, where the B axis is. When that geometry is wrong by tens of µm, a point fixed on the
//! table is reported at different places at different orientations. This crate measures that —
//! a reference sphere on the table probed at several orientations — identifies the true
//! geometry, and writes it back into the running controller (`truepos kinematics calibrate`).
//!
//! Entry points:
//! - [`trt`]: the `xyzbc-trt` model (LinuxCNC's `xyzbc-trt-kins`): forward and inverse
//!   kinematics, the closed form of where the controller reports a table-fixed sphere, its
//!   derivative in the four observable numbers.
//! - [`identify`]: the observability check of a set of orientations (before any motion) and the
//!   linear least-squares identification with uncertainties from the residuals.
//! - [`acquire`]: the sphere probed at each orientation through any
//!   `truepos_device::ProbingMachine` with `rotary_kinematics`, on a collision-free path.
//! - [`task`]: the whole command (check, read the configured geometry, acquire, identify,
//!   apply, verify) and its report.
//!
//! Sees machines only through `truepos-device`; the virtual five-axis machine is in
//! `truepos-cell`, LinuxCNC in `truepos-linuxcnc`. Internal units mm and rad; options and
//! files in degrees.

#![forbid(unsafe_code)]

pub mod acquire;
pub mod identify;
pub mod task;
pub mod trt;

pub use task::{calibrate, CalibrateRequest, CalibrationReport, KinematicsError, Model, UncertaintyBasis};
