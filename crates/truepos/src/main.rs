//! # truepos — the command-line binary
//!
//! The top of the workspace: parses the command line (clap), runs one command, maps the outcome
//! to the exit codes of the interface contract (`0` done, `1` out of tolerance or alarm, `2` bad
//! usage or input, `3` device or internal failure), and prints errors once, on stderr.
//!
//! Entry points: [`cmd`] (one module per command, each with `Args` and `run`), [`output`] (JSON on
//! stdout, progress bars on a terminal stderr).

mod cmd;
#[allow(dead_code)] // helpers used as capabilities land
mod output;

use std::process::ExitCode;

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

/// A device or internal failure: exit 3.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct DeviceError(pub String);

/// Exit code for an error: the one place where errors become exit codes. The first cause in the
/// chain that says what kind of failure it is decides: bad input or usage → 2; a device, the
/// audit trail or anything internal → 3.
/// An output path that cannot be written is bad usage too (2).
fn exit_code(err: &anyhow::Error) -> u8 {
    use truepos_scan::ScanError;
    use truepos_somac::run::RunError;
    for cause in err.chain() {
        if cause.is::<truepos_io::InputError>() || cause.is::<UsageError>() {
            return 2;
        }
        if cause.downcast_ref::<truepos_io::atomic::OutputError>().is_some_and(|o| o.is_path()) {
            return 2;
        }
        // Input or output of a task that reads and writes (transparent: its cause is skipped).
        if let Some(e) = cause.downcast_ref::<truepos_io::stream::RewriteError>() {
            return match e {
                truepos_io::stream::RewriteError::Input(_) => 2,
                truepos_io::stream::RewriteError::Output(o) => {
                    if o.is_path() {
                        2
                    } else {
                        3
                    }
                }
            };
        }
        // An output error carried inside an io::Error by a library that returns io::Result.
        if let Some(io) = cause.downcast_ref::<std::io::Error>() {
            if io
                .get_ref()
                .and_then(|i| i.downcast_ref::<truepos_io::atomic::OutputError>())
                .is_some_and(|o| o.is_path())
            {
                return 2;
            }
        }
        if let Some(e) = cause.downcast_ref::<truepos_audit::AuditError>() {
            return if e.is_usage() { 2 } else { 3 };
        }
        if cause.is::<truepos_dmis::DmisError>() {
            return 2;
        }
        if let Some(e) = cause.downcast_ref::<truepos_dmis::exec::RunError>() {
            return match e {
                truepos_dmis::exec::RunError::Input(_) => 2,
                _ => 3,
            };
        }
        if cause.is::<DeviceError>() || cause.is::<truepos_device::DeviceError>() {
            return 3;
        }
        if let Some(e) = cause.downcast_ref::<truepos_cell::CellError>() {
            return if e.is_user_input() { 2 } else { 3 };
        }
        if let Some(e) = cause.downcast_ref::<RunError>() {
            return match e {
                RunError::Params(_) | RunError::Program { .. } => 2,
                RunError::Device(_) | RunError::Audit(_) => 3,
            };
        }
        if let Some(e) = cause.downcast_ref::<ScanError>() {
            return match e {
                ScanError::Device(_) | ScanError::NoContact { .. } => 3,
                _ => 2,
            };
        }
    }
    3
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
        Ok(Outcome::OutOfTolerance) => ExitCode::from(1),
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(exit_code(&e))
        }
    }
}
