//! # truepos-cell — the demo application
//!
//! The application layer beside the binary: it joins every capability to the virtual plant
//! (`truepos-plant`), the task-specific uncertainty (`truepos-vcmm`) and the report
//! (`truepos-report`), as `truepos demo` and `truepos simulate` need. Being an application, it
//! may depend on every crate (issue 33's limit of nine workspace crates is for library crates);
//! nothing but the binary depends on it.
//!
//! Entry points:
//! - [`scenarios`]: one module per capability: the data set of its `truepos simulate` scenario
//!   (with `truth.json`) and its section of the demo report.
//! - [`demo`]: the demo's sections in order (the report itself is `truepos_report`).
//! - [`observed`]: a real controller whose actual position the virtual gantry cell follows
//!   (`truepos somac run` on a real controller).
//! - [`uncertainty`]: the task-specific uncertainty of `dmis run` and `kinematics calibrate`
//!   (the Monte Carlo of `truepos-vcmm` over those capabilities' tasks).
//! - [`CellError`]: the errors of all of them, with whether the user's input is the cause.

#![forbid(unsafe_code)]

pub mod demo;
pub mod error;
pub mod observed;
pub mod scenarios;
pub mod uncertainty;

pub use error::{CellError, Context};
