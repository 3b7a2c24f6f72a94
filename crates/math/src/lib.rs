//! # truepos-math
//!
//! The pure-math floor of truepos: no I/O, no file formats, no machine models. Everything here is
//! in the one internal unit system (mm, rad, s) as `f64`.
//!
//! Entry points:
//! - [`types`]: the nalgebra aliases the whole workspace uses (`Point3` for positions,
//!   `Vector3` for displacements and directions; never mix them).
//! - [`transform::Transform3`]: a similarity transform `p_a = s·R·p_b + t`, named `a_from_b`
//!   at every use site, with composition and inversion.
//! - [`bestfit`]: weighted rigid / similarity best fit (SVD with the reflection guard) and the
//!   three-point method.
//! - [`lsq`]: a dense Gauss-Newton / Levenberg-Marquardt solver for problems with few parameters
//!   and many residuals, streaming the normal equations (no Jacobian storage), with covariance
//!   and rank/observability diagnostics.
//! - [`stats`]: mean/standard deviation, weighted straight-line regression with standard
//!   uncertainties.
//! - [`interp`]: piecewise-linear interpolation on sorted abscissae.
//! - [`air`]: refractive index of air (Ciddor, modified Edlén) as NIST computes it.
//! - [`exit`]: [`exit::ExitClass`], the kind of failure each library error says it is (the
//!   binary turns it into the exit code).
//! - [`decimal`]: the exact fast path from decimal text to `f64` that every number reader shares.
//! - [`fixed`]: fixed-point decimal text of a scaled integer, and a libm-free `round`, that every
//!   fixed-decimal writer shares.
//! - [`text`]: where a text's lines end in a carriage return alone (every line reader asks).

#![forbid(unsafe_code)]

pub mod air;
pub mod bestfit;
pub mod decimal;
pub mod exit;
pub mod fixed;
pub mod interp;
pub mod lsq;
pub mod stats;
pub mod text;
pub mod time;
pub mod transform;
pub mod types;

pub use transform::Transform3;
pub use types::*;
