//! The errors of the task-specific uncertainty: a machine-model file or a task the simulation
//! cannot take (the user's input, exit 2) and a simulated measurement that failed (exit 3).
//!
//! Entry points: [`VcmmError`], [`Result`].

use truepos_io::InputError;

/// What went wrong while computing a task-specific uncertainty.
#[derive(Debug, thiserror::Error)]
pub enum VcmmError {
    /// The machine-model file is malformed (file, line, column).
    #[error(transparent)]
    Input(#[from] InputError),
    /// The model or the task cannot be simulated as given (the message says what).
    #[error("{0}")]
    Invalid(String),
    /// A simulated measurement failed (the message says which).
    #[error("{0}")]
    Failed(String),
}

/// The result type of the task-specific uncertainty.
pub type Result<T, E = VcmmError> = std::result::Result<T, E>;

impl VcmmError {
    /// True when the cause is the user's input (a malformed machine model, a task that cannot be
    /// simulated): exit code 2 in the binary. A failed simulation is not (3).
    pub fn is_user_input(&self) -> bool {
        matches!(self, VcmmError::Input(_) | VcmmError::Invalid(_))
    }
}

impl truepos_math::exit::HasExitClass for VcmmError {
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        if self.is_user_input() {
            ExitClass::Input
        } else {
            ExitClass::Internal
        }
    }
}
