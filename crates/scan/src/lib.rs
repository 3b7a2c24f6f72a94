//! # truepos-scan — scanning path control for CMMs without stops
//!
//! Plans scans of circles (inside bores, outside bosses, on planes) and lines in two styles:
//! **blended** (transfer at positioning speed along corner-free paths, a straight approach at
//! 20°–60° to the surface normal entered at scanning speed, a settle path that overshoots the
//! target deflection and decreases gradually to it, the scan with probe feedback, a continuous
//! release, and straight on to the next approach: the commanded speed never reaches zero between
//! the first approach and the last release) and **classic** (pre-hit point on the normal, stop,
//! normal approach, search to the deflection, scan, stop, retract), and executes them on the
//! scanning machine (`truepos_device::ScanningMachine`; the virtual CMM with servo and stylus
//! dynamics is `truepos_plant::scanning_cmm`), missed surfaces handled both ways.
//!
//! Entry points:
//! - [`feature`]: [`Feature`], [`Params`], [`validate`].
//! - [`plan`](mod@plan): [`plan::plan`] with [`Style`] → [`Plan`] (segments, sampling, stops).
//! - [`execute`]: [`execute::execute`] on a scanning machine with [`execute::ControlParams`] →
//!   points tagged by segment/feature with deflection and quality, per-feature form error, cycle
//!   time.
//! - [`crate::file`]: the features file ([`file::read_features`]).
//! - [`form`]: form error (peak-to-valley of least-squares residuals, via `truepos-fit`).

#![forbid(unsafe_code)]

pub mod execute;
pub mod feature;
pub mod file;
pub mod form;
pub mod json;
pub mod motion;
pub mod plan;

pub use feature::{validate, Feature, Geometry, Params, Side};
pub use plan::{plan, Plan, SegmentKind, Style};

/// Errors of planning and execution.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum ScanError {
    /// The approach angle is outside 20 to 60 degrees (the value).
    #[error("approach_angle_deg is {0}; it must be between 20 and 60 degrees")]
    ApproachAngle(f64),
    /// A parameter is not finite and positive (name, value).
    #[error("{0} is {1}; it must be a finite number above zero")]
    Parameter(&'static str, f64),
    /// The quality bands are not two positive increasing numbers (mm).
    #[error("quality_bands_mm [{0}, {1}] must be two positive numbers in increasing order")]
    Bands(f64, f64),
    /// A feature is invalid.
    #[error("feature '{id}': {why}")]
    Feature {
        /// The feature's id.
        id: String,
        /// What is wrong.
        why: String,
    },
    /// No contact within the search limit.
    #[error("feature '{id}': no contact within {limit} mm beyond the nominal contact point")]
    NoContact {
        /// The feature's id.
        id: String,
        /// The search limit beyond the nominal contact point, mm.
        limit: f64,
    },
    /// Too few scan points for a form evaluation.
    #[error("feature '{id}': only {n} scan points, too few for a form evaluation")]
    TooFewPoints {
        /// The feature's id.
        id: String,
        /// Scan points obtained.
        n: usize,
    },
    /// The form fit failed.
    #[error("feature '{id}': form fit failed: {why}")]
    Fit {
        /// The feature's id.
        id: String,
        /// Why.
        why: String,
    },
    /// Invalid input (the message).
    #[error("{0}")]
    Invalid(String),
    /// The scanning machine failed or refused a command.
    #[error(transparent)]
    Device(#[from] truepos_device::DeviceError),
}

impl truepos_math::exit::HasExitClass for ScanError {
    /// Parameters and features that cannot be planned are the user's (2); a surface not found or
    /// a machine failure is a measurement failure (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        match self {
            ScanError::Device(_) | ScanError::NoContact { .. } => ExitClass::Device,
            _ => ExitClass::Usage,
        }
    }
}
