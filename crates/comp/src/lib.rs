//! # truepos-comp — geometric error map and bed deformation under load
//!
//! Capability 3 of `shared/spec/product.md` (`truepos comp`, `truepos load`). Computation, plus
//! the typed definitions of its file formats ([`files`]).
//!
//! Entry points:
//! - [`geometric`]: the 21-parameter ISO 230-1 map ([`GeometricMap`], [`AxisTable`]) and the
//!   first-order volumetric error `E(p; t)` of `docs/conventions.md`; its module docs give the
//!   rotation axis of every pitch, yaw and roll.
//! - [`correct`]: the combined correction on many points ([`Corrector`]): measured points
//!   `p + E(p) − e(p)`, commanded positions by iteration to 1 nm; parallel, allocation-free.
//! - [`statics`]: the weight of a part shared among its resting points.
//! - [`influence`]: unit-load influence maps (pitch/roll of the portal against its Y position)
//!   and their superposition for a load case.
//! - [`load`]: the portal, the physics and sign convention of its pitch/roll, and the
//!   contract's correction `p − θ × (p − o)`.
//! - [`fe_map`]: influence maps computed with the plate model of `truepos-fe`.
//! - [`files`]: the influence map CSV (read and write).
//! - [`task`]: the commands of `truepos comp` and `truepos load` as library calls (files in,
//!   outputs written, a `Report` back).
//! - [`grid1`]: O(1)/binary-search interval lookup shared by all tables.

#![forbid(unsafe_code)]

pub mod correct;
pub mod fe_map;
pub mod files;
pub mod geometric;
pub mod grid1;
pub mod influence;
pub mod json;
pub mod load;
pub mod statics;
pub mod stream;
pub mod task;

pub use correct::{CompError, Corrector};
pub use fe_map::{BedModel, LoadGrid};
pub use geometric::{Axis, AxisErrors, AxisTable, Chain, GeometricMap, OutOfRange, Squareness};
pub use influence::{InfluenceMap, InfluenceRow, PortalCurves};
pub use load::{LoadCorrection, Portal};
