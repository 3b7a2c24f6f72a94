//! # truepos — the command-line binary
//!
//! The top of the workspace: parses the command line (clap), runs one command, maps the outcome
//! to the exit codes of the interface contract (`0` done, `1` out of tolerance or alarm, `2` bad
//! usage or input, `3` device or internal failure), and prints errors once, on stderr.
//!
//! Entry points: [`cmd`] (one module per command, each with `Args` and `run`), [`output`] (JSON on
//! stdout, progress bars on a terminal stderr).

#![forbid(unsafe_code)]

mod cmd;
#[allow(dead_code)] // helpers used as capabilities land
mod output;

use std::process::ExitCode;
use truepos_math::exit::{ExitClass, HasExitClass};

/// What a command that finished reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Exit code 0.
    Done,
    /// Exit code 1: the result is outside a tolerance or an alarm fired (the JSON says which).
    OutOfTolerance,
}

/// A usage error found after argument parsing (conflicting or out-of-range options): exit 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// A device or internal failure found by the binary itself: exit 3.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct DeviceError(pub String);

impl HasExitClass for UsageError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::Usage
    }
}

impl HasExitClass for DeviceError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::Device
    }
}

/// A library error whose exit class depends on the call (the same parse error is bad usage for
/// a flag and a failure elsewhere), or whose type has no class: the command says the class, the
/// error stays the source (its chain intact), and an optional context is printed before it.
#[derive(Debug)]
pub struct Classed {
    class: ExitClass,
    context: Option<String>,
    source: Box<dyn std::error::Error + Send + Sync + 'static>,
}

impl Classed {
    /// `source` with exit class `class`, printed after `context` when there is one.
    pub fn new(
        class: ExitClass,
        context: Option<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Classed { class, context, source: Box::new(source) }
    }

    /// [`Classed::new`] for an error that is already boxed.
    pub fn boxed(
        class: ExitClass,
        context: Option<String>,
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    ) -> Self {
        Classed { class, context, source }
    }
}

impl std::fmt::Display for Classed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.context {
            Some(c) => f.write_str(c),
            None => self.source.fmt(f),
        }
    }
}

impl std::error::Error for Classed {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.context {
            // The error is the next link of the chain.
            Some(_) => Some(self.source.as_ref()),
            // Transparent: this link shows the error itself, the chain goes on with its cause.
            None => self.source.source(),
        }
    }
}

impl HasExitClass for Classed {
    fn exit_class(&self) -> ExitClass {
        self.class
    }
}

/// Say the exit class of a library error at the call: `.usage()`, `.device()`, or with a
/// context printed before it, `.usage_in("--flag")`, `.device_in("what was done")`.
pub trait ClassExt<T> {
    /// The error with class `class` and an optional context.
    fn classed(self, class: ExitClass, context: Option<String>) -> Result<T, Classed>;
    /// Bad usage (exit 2).
    fn usage(self) -> Result<T, Classed>
    where
        Self: Sized,
    {
        self.classed(ExitClass::Usage, None)
    }
    /// Bad usage (exit 2), printed as `context: error`.
    fn usage_in(self, context: impl Into<String>) -> Result<T, Classed>
    where
        Self: Sized,
    {
        self.classed(ExitClass::Usage, Some(context.into()))
    }
    /// A device failure (exit 3).
    fn device(self) -> Result<T, Classed>
    where
        Self: Sized,
    {
        self.classed(ExitClass::Device, None)
    }
    /// A device failure (exit 3), printed as `context: error`.
    fn device_in(self, context: impl Into<String>) -> Result<T, Classed>
    where
        Self: Sized,
    {
        self.classed(ExitClass::Device, Some(context.into()))
    }
}

impl<T, E: std::error::Error + Send + Sync + 'static> ClassExt<T> for Result<T, E> {
    fn classed(self, class: ExitClass, context: Option<String>) -> Result<T, Classed> {
        self.map_err(|e| Classed::new(class, context, e))
    }
}

/// The exit class of an error: the one place where errors become exit codes. The first cause in
/// the chain whose type has a class ([`HasExitClass`], said by each library error type) decides;
/// an error no type claims is internal (3).
fn exit_class(err: &anyhow::Error) -> ExitClass {
    err.chain().find_map(class_of).unwrap_or(ExitClass::Internal)
}

/// The class of one cause, when its type has one.
fn class_of(cause: &(dyn std::error::Error + 'static)) -> Option<ExitClass> {
    macro_rules! classes {
        ($($t:ty),* $(,)?) => {
            $(if let Some(e) = cause.downcast_ref::<$t>() {
                return Some(e.exit_class());
            })*
        };
    }
    classes!(
        UsageError,
        DeviceError,
        Classed,
        truepos_math::air::AirError,
        truepos_io::InputError,
        truepos_io::atomic::OutputError,
        truepos_io::stream::RewriteError,
        truepos_device::DeviceError,
        truepos_linuxcnc::url::AddressError,
        truepos_plant::probing::ParamError,
        truepos_cell::scenarios::head::HeadOffsetError,
        truepos_head::acquire::AcquireError,
        truepos_scan::ScanError,
        truepos_scan::file::FeaturesError,
        truepos_somac::run::RunError,
        truepos_somac::inspect::InspectError,
        truepos_kinematics::task::KinematicsError,
        truepos_dmis::DmisError,
        truepos_dmis::exec::RunError,
        truepos_audit::AuditError,
        truepos_cell::CellError,
        truepos_vcmm::VcmmError,
        truepos_report::ReportError,
        truepos_plant::cmm::ServeError,
        truepos_cell::scenarios::latency::SimRequestError,
    );
    // An output error carried inside an io::Error by a library that returns io::Result.
    cause.downcast_ref::<std::io::Error>().and_then(truepos_io::exit::io_exit_class)
}

/// True when the error is a write to a closed pipe (`truepos … --json | head -c 10`): the
/// reader has gone, nothing is wrong with the work, and the process ends quietly.
fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|c| {
        c.downcast_ref::<std::io::Error>().is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
            || c.downcast_ref::<serde_json::Error>()
                .is_some_and(|e| e.io_error_kind() == Some(std::io::ErrorKind::BrokenPipe))
    })
}

/// `println!` panics when stdout is a closed pipe; that panic is the same quiet end.
fn is_broken_pipe_panic(msg: &str) -> bool {
    msg.contains("failed printing to stdout") && (msg.contains("Broken pipe") || msg.contains("os error 32"))
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_default()
}

fn main() -> ExitCode {
    // Silence only the closed-pipe panic of `println!`; every other panic is reported as usual.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !is_broken_pipe_panic(&panic_message(info.payload())) {
            default_hook(info);
        }
    }));
    let code = match std::panic::catch_unwind(real_main) {
        Ok(c) => c,
        Err(p) if is_broken_pipe_panic(&panic_message(p.as_ref())) => ExitCode::SUCCESS,
        Err(_) => ExitCode::from(3),
    };
    // Nothing half-written survives the process (outputs are removed on drop; this also covers
    // any still registered).
    truepos_io::atomic::remove_all_temporaries();
    code
}

fn real_main() -> ExitCode {
    let parsed = cmd::command()
        .try_get_matches()
        .and_then(|m| <cmd::Cli as clap::FromArgMatches>::from_arg_matches(&m));
    let cli = match parsed {
        Ok(c) => c,
        Err(e) => {
            // --help and --version print to stdout and exit 0; usage errors exit 2.
            let _ = e.print();
            if e.kind() == clap::error::ErrorKind::DisplayHelp {
                // The examples, verbatim (clap re-wraps its own text to the terminal).
                let args: Vec<String> = std::env::args().skip(1).collect();
                let path = cmd::examples::help_path(&cmd::command(), &args);
                let block = cmd::examples::block(&path);
                if !block.is_empty() {
                    use std::io::Write;
                    let mut out = std::io::stdout().lock();
                    let _ = out.write_all(block.as_bytes()).and_then(|_| out.flush());
                }
            }
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("TRUEPOS_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .without_time()
        .init();
    match cmd::run(cli) {
        Ok(Outcome::Done) => ExitCode::SUCCESS,
        Ok(Outcome::OutOfTolerance) => ExitCode::from(ExitClass::Verdict.code()),
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(exit_class(&e).code())
        }
    }
}
