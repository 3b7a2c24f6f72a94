//! Exit classes: what kind of failure an error is, said once by the error's own type.
//!
//! Every library error type of truepos implements [`HasExitClass`]; the binary walks an error's
//! cause chain and the first cause that has a class chooses the process exit code
//! ([`ExitClass::code`], the interface contract's "exit codes"). The type lives in this crate
//! only because every other crate depends on it; it carries no I/O and no machine knowledge.

/// The kind of outcome behind an exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ExitClass {
    /// The work was done but the result is outside a tolerance, or an alarm fired (exit 1).
    Verdict,
    /// A bad option or a bad combination of options, an output path that cannot be used (exit 2).
    Usage,
    /// A malformed or impossible input file (exit 2; the message names file, line and column).
    Input,
    /// A device failed or refused: a machine, a controller, a tracker, the audit trail (exit 3).
    Device,
    /// Anything else that is not the user's doing (exit 3).
    Internal,
    /// SIGINT (exit 130 = 128 + 2; other signals exit 128 + their number).
    Interrupted,
}

impl ExitClass {
    /// The process exit code of the class.
    pub const fn code(self) -> u8 {
        match self {
            ExitClass::Verdict => 1,
            ExitClass::Usage | ExitClass::Input => 2,
            ExitClass::Device | ExitClass::Internal => 3,
            ExitClass::Interrupted => 130,
        }
    }

    /// True for the classes that are the user's to fix (exit 2).
    pub const fn is_user(self) -> bool {
        matches!(self, ExitClass::Usage | ExitClass::Input)
    }
}

/// An error that knows its [`ExitClass`].
pub trait HasExitClass {
    /// What kind of failure this is.
    fn exit_class(&self) -> ExitClass;
}

impl HasExitClass for crate::air::AirError {
    /// Air conditions out of range are the user's numbers.
    fn exit_class(&self) -> ExitClass {
        ExitClass::Usage
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_follow_the_contract() {
        assert_eq!(ExitClass::Verdict.code(), 1);
        assert_eq!(ExitClass::Usage.code(), 2);
        assert_eq!(ExitClass::Input.code(), 2);
        assert_eq!(ExitClass::Device.code(), 3);
        assert_eq!(ExitClass::Internal.code(), 3);
        assert_eq!(ExitClass::Interrupted.code(), 130);
        assert!(ExitClass::Input.is_user() && !ExitClass::Device.is_user());
    }
}
