//! The errors of the virtual plant's scenarios, data-set writers and demo sections: one enum that
//! keeps every cause (`#[from]`/`#[source]`), so that the binary can tell a bad user input (a
//! `--out` that cannot be written, a malformed cell file: exit 2) from a failure (exit 3) by
//! [`CellError::is_user_input`].
//!
//! Entry points: [`CellError`], [`Result`], [`Context`] (adds what was being done to any error).

use std::error::Error as StdError;
use std::path::PathBuf;
use truepos_io::atomic::OutputError;
use truepos_io::InputError;

/// What went wrong in the virtual plant.
#[derive(Debug, thiserror::Error)]
pub enum CellError {
    /// A file the user gave is malformed (file, line, column).
    #[error(transparent)]
    Input(#[from] InputError),
    /// An output file could not be written (a bad path is the user's; a failed write is not).
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A directory or file operation on `path` failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The directory or file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// Writing a stream failed.
    #[error(transparent)]
    Write(#[from] std::io::Error),
    /// A JSON value could not be serialised.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A TOML value could not be serialised.
    #[error(transparent)]
    Toml(#[from] toml::ser::Error),
    /// The report could not be drawn or written (`truepos-report`).
    #[error(transparent)]
    Report(#[from] truepos_report::ReportError),
    /// A task-specific uncertainty could not be computed (`truepos-vcmm`).
    #[error(transparent)]
    Vcmm(#[from] truepos_vcmm::VcmmError),
    /// A scenario asked for something it cannot be (sizes, counts): the message says what.
    #[error("{0}")]
    Invalid(String),
    /// A step of the plant failed (a protocol exchange, a device): the message says which.
    #[error("{0}")]
    Failed(String),
    /// An error of a library the plant drives (simulator, capability, device), with what the
    /// plant was doing.
    #[error("{context}")]
    Context {
        /// What the plant was doing.
        context: String,
        /// The library's error.
        #[source]
        source: Box<dyn StdError + Send + Sync + 'static>,
    },
}

/// The plant's result type.
pub type Result<T, E = CellError> = std::result::Result<T, E>;

impl CellError {
    /// True when the cause is the user's input (a malformed file, an output path that cannot be
    /// written): exit code 2 in the binary. Anything else is a failure (3).
    pub fn is_user_input(&self) -> bool {
        match self {
            CellError::Input(_) | CellError::Invalid(_) => true,
            CellError::Output(o) => o.is_path(),
            CellError::Report(r) => r.is_user_input(),
            CellError::Vcmm(v) => v.is_user_input(),
            // The path is the user's choice (`--out`): one that cannot be a directory or file.
            CellError::Io { source, .. } => {
                use std::io::ErrorKind as K;
                matches!(
                    source.kind(),
                    K::NotFound | K::PermissionDenied | K::AlreadyExists | K::NotADirectory | K::IsADirectory
                )
            }
            CellError::Context { source, .. } => {
                let mut e: Option<&(dyn StdError + 'static)> = Some(source.as_ref());
                while let Some(c) = e {
                    if c.is::<InputError>() {
                        return true;
                    }
                    if let Some(cell) = c.downcast_ref::<CellError>() {
                        return cell.is_user_input();
                    }
                    if let Some(o) = c.downcast_ref::<OutputError>() {
                        return o.is_path();
                    }
                    if let Some(r) = c.downcast_ref::<truepos_report::ReportError>() {
                        return r.is_user_input();
                    }
                    if let Some(v) = c.downcast_ref::<truepos_vcmm::VcmmError>() {
                        return v.is_user_input();
                    }
                    e = c.source();
                }
                false
            }
            _ => false,
        }
    }

    /// A directory or file operation on `path` that failed.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CellError::Io { path: path.into(), source }
    }
}

/// Errors of the libraries the plant drives, each kept as the source of a [`CellError::Context`]
/// that names the library's task.
macro_rules! library_errors {
    ($($t:ty => $what:literal,)*) => {
        $(impl From<$t> for CellError {
            fn from(e: $t) -> Self {
                CellError::Context { context: $what.into(), source: Box::new(e) }
            }
        })*
    };
}

library_errors! {
    truepos_fit::FitError => "fitting",
    truepos_math::bestfit::BestFitError => "best-fit transform",
    truepos_math::air::AirError => "refractive index of air",
    truepos_sim::scenario::head_offset::HeadOffsetError => "head-offset simulation",
    truepos_sim::scenario::latency::LatencyError => "latency simulation",
    truepos_head::HeadError => "head-offset calibration",
    truepos_comp::fe_map::FeMapError => "plate FE influence map",
    truepos_comp::statics::StaticsError => "statics of the resting points",
    truepos_comp::influence::NotCovered => "influence map",
    truepos_comp::CompError => "compensation",
    truepos_comp::geometric::MapError => "geometric map",
    truepos_somac::run::RunError => "end-point control run",
    truepos_device::DeviceError => "device",
}

/// Adds what the plant was doing to an error of a library it drives.
pub trait Context<T> {
    /// The error, if any, with `what` (what the plant was doing) as its context.
    fn context(self, what: impl Into<String>) -> Result<T>;
}

impl<T, E: StdError + Send + Sync + 'static> Context<T> for std::result::Result<T, E> {
    fn context(self, what: impl Into<String>) -> Result<T> {
        self.map_err(|e| CellError::Context { context: what.into(), source: Box::new(e) })
    }
}

impl truepos_math::exit::HasExitClass for CellError {
    /// [`CellError::is_user_input`]: the user's input (2), else a failure (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        if self.is_user_input() {
            ExitClass::Input
        } else {
            ExitClass::Internal
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cause survives the context, and a user's input error is found through it.
    #[test]
    fn context_keeps_the_cause_and_classifies_input() {
        let r: std::result::Result<(), InputError> = Err(InputError::new("bad"));
        let e = r.context("reading the cell file").unwrap_err();
        assert_eq!(e.to_string(), "reading the cell file");
        assert_eq!(e.source().map(|s| s.to_string()).as_deref(), Some("bad"));
        assert!(e.is_user_input());
        let r: std::result::Result<(), std::fmt::Error> = Err(std::fmt::Error);
        assert!(!r.context("plot").unwrap_err().is_user_input());
        assert!(CellError::Invalid("--mass-kg".into()).is_user_input());
    }
}
