//! Machines as kinematic chains (being extended: bridge CMM, VMC, large gantry).
//!
//! Entry points: [`rotary`] (the contract's B-head / C-table model).

pub mod rotary;

pub use rotary::{head_point, head_reference, RotaryTable};
