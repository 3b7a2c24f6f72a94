//! The exit classes of this crate's errors ([`truepos_math::exit::HasExitClass`]).

use crate::atomic::OutputError;
use crate::stream::RewriteError;
use crate::InputError;
use truepos_math::exit::{ExitClass, HasExitClass};

impl HasExitClass for InputError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::Input
    }
}

impl HasExitClass for OutputError {
    /// An output path that cannot be used is the user's choice (2); a failed write is not (3).
    fn exit_class(&self) -> ExitClass {
        if self.is_path() {
            ExitClass::Usage
        } else {
            ExitClass::Internal
        }
    }
}

impl HasExitClass for RewriteError {
    fn exit_class(&self) -> ExitClass {
        match self {
            RewriteError::Input(e) => e.exit_class(),
            RewriteError::Output(e) => e.exit_class(),
        }
    }
}

/// The class of an [`OutputError`] carried inside an `io::Error` by a writer that returns
/// `std::io::Result`, when it is a bad output path (exit 2); `None` otherwise.
pub fn io_exit_class(e: &std::io::Error) -> Option<ExitClass> {
    e.get_ref().and_then(|i| i.downcast_ref::<OutputError>()).filter(|o| o.is_path()).map(|o| o.exit_class())
}
