//! # truepos-cell — the virtual plant
//!
//! Everything simulated that stands in for real hardware lives here, behind the traits of
//! `truepos-device`: the virtual machines (gantry with trackers, CMM, machine tool with a
//! spindle probe), the scenarios that write data sets with their `truth.json`, and the demo's
//! evaluations against truth. Capability crates never depend on this crate (except in tests).

pub mod cmm;
