//! # truepos-cell — the virtual plant
//!
//! Everything simulated that stands in for real hardware lives here, behind the traits of
//! `truepos-device`: the virtual machines (gantry with trackers, CMM, machine tool with a
//! spindle probe), the scenarios that write data sets with their `truth.json`, and the demo's
//! evaluations against truth. Capability crates never depend on this crate (except in tests).
//!
//! Entry points:
//! - [`gantry`]: the virtual large gantry with laser trackers (end-point control, `somac`).
//! - [`scanning_cmm`]: the virtual scanning CMM ([`scanning_cmm::VirtualCmm`], a
//!   `truepos_device::ScanningMachine`) and [`scanning_cmm::run_scan`].
//! - [`scenarios`]: one module per capability: the data set of its `truepos simulate` scenario
//!   (with `truth.json`) and its section of the demo report.
//! - [`demo`]: the demo's sections in order; [`report`]: the report (`index.html` with SVG
//!   plots, `summary.json`).
//! - [`probing`]: the virtual machine tool with a spindle probe (a `ProbingMachine`);
//!   [`observed`]: a real controller whose actual position the virtual cell follows.
//! - [`scan_scenario`]: the simulator's `scan` scenario as `truepos-scan` features.
//! - [`cmm`]: the touch-probe CMM behind `truepos ippdme serve` ([`cmm::IppdmeCmm`], a
//!   `truepos_ippdme::Cmm`) and [`cmm::bind_virtual`].

#![forbid(unsafe_code)]

pub mod cmm;
pub mod demo;
pub mod error;
pub mod gantry;
pub mod observed;
pub mod probing;
pub mod report;
pub mod scan_scenario;
pub mod scanning_cmm;
pub mod scenarios;
pub mod vcmm;

pub use error::{CellError, Context};
