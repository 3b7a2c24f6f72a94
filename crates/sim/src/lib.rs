//! # truepos-sim — the virtual cell
//!
//! Produces exactly the data a real cell would, with known truth, so every method can be tried
//! and verified without hardware. Pure computation: it returns data structures; the binary
//! writes them as the files of the interface contract plus `truth.json`.
//!
//! Module map (see each module's docs for its entry points):
//! - probing physics: [`noise`], [`capture`] (master clock, sampling, capture latency),
//!   [`motion`] (acceleration/jerk-limited profiles, servo following error), [`stylus`]
//!   (scanning-probe stylus dynamics), [`touch`] (touch-trigger probe), [`artefact`]
//!   (spheres, plates, pyramids, cuboids, parts with bores/bosses/planes; exact contacts).
//! - machines: [`machine`] (kinematic chains: bridge CMM, VMC with B head and C table,
//!   large gantry), [`errors`] (ISO 230-1 21-parameter geometric errors), [`thermal`],
//!   [`laser`] (laser distance head), [`tracker`] (laser tracker, inclinometers).
//! - [`scenario`]: the data sets of `truepos simulate`.

#![forbid(unsafe_code)]

pub mod artefact;
pub mod capture;
pub mod errors;
pub mod laser;
pub mod machine;
pub mod motion;
pub mod noise;
pub mod scenario;
pub mod stylus;
pub mod thermal;
pub mod touch;
pub mod tracker;
