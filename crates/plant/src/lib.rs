//! # truepos-plant — the virtual plant
//!
//! The simulated machines that stand in for real hardware, behind the traits of
//! `truepos-device` (and the I++ DME server's `Cmm`), built on the physics models of
//! `truepos-sim`. Capability crates never depend on this crate (except in tests); the demo and
//! its scenarios are `truepos-cell`, the task-specific uncertainty by simulation `truepos-vcmm`.
//!
//! Entry points:
//! - [`gantry`]: the virtual large gantry with laser trackers (end-point control, `somac`).
//! - [`probing`]: the virtual machine tool with a spindle probe (a `ProbingMachine`), and
//!   [`probing::VirtualMachineTool::five_axis`].
//! - [`scanning_cmm`]: the virtual scanning CMM ([`scanning_cmm::VirtualCmm`], a
//!   `truepos_device::ScanningMachine`) and [`scanning_cmm::run_scan`].
//! - [`cmm`]: the touch-probe CMM behind `truepos ippdme serve` ([`cmm::IppdmeCmm`], a
//!   `truepos_ippdme::Cmm`), [`cmm::bind_virtual`] and [`cmm::serve_loopback`].
//! - [`scan_scenario`]: the `scan` scenario's part (nominal and true features as `truepos-scan`
//!   features) and its data set (`features.toml`, `truth.json`).

#![forbid(unsafe_code)]

pub mod cmm;
pub mod gantry;
pub mod probing;
pub mod scan_scenario;
pub mod scanning_cmm;
