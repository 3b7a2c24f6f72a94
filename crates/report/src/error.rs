//! The errors of writing the report: an output path that cannot be written (the user's, exit 2)
//! and a failed write or plot (exit 3).
//!
//! Entry points: [`ReportError`], [`Result`].

use truepos_io::atomic::OutputError;

/// What went wrong while drawing or writing the report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// An output file could not be written (a bad path is the user's; a failed write is not).
    #[error(transparent)]
    Output(#[from] OutputError),
    /// Creating the report directory failed.
    #[error(transparent)]
    Write(#[from] std::io::Error),
    /// `summary.json` could not be serialised.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A plot could not be drawn (the SVG backend's message).
    #[error("plot: {0}")]
    Plot(String),
}

/// The report's result type.
pub type Result<T, E = ReportError> = std::result::Result<T, E>;

impl ReportError {
    /// True when the cause is the user's input (an output path that cannot be written): exit
    /// code 2 in the binary. Anything else is a failure (3).
    pub fn is_user_input(&self) -> bool {
        matches!(self, ReportError::Output(o) if o.is_path())
    }
}

impl truepos_math::exit::HasExitClass for ReportError {
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        if self.is_user_input() {
            ExitClass::Input
        } else {
            ExitClass::Internal
        }
    }
}
