//! # truepos — the command-line binary
//!
//! The top of the workspace: parses the command line (clap), runs one command, maps the outcome
//! to the exit codes of the interface contract (`0` done, `1` out of tolerance or alarm, `2` bad
//! usage or input, `3` device or internal failure), and prints errors once, on stderr.
//!
//! Entry points: [`cmd`] (one module per command, each with `Args` and `run`), [`output`] (JSON on
//! stdout, progress bars on a terminal stderr), [`report`] (the demo report and its SVG plots).

mod cmd;
#[allow(dead_code)] // helpers used as capabilities land
mod output;
#[allow(dead_code)]
mod report;

use clap::Parser;
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

/// Exit code for an error: 2 when any cause is bad input or usage, otherwise 3.
fn exit_code(err: &anyhow::Error) -> u8 {
    for cause in err.chain() {
        if cause.is::<truepos_io::InputError>() || cause.is::<UsageError>() {
            return 2;
        }
        if cause.is::<DeviceError>() {
            return 3;
        }
    }
    3
}

fn main() -> ExitCode {
    let cli = match cmd::Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // --help and --version print to stdout and exit 0; usage errors exit 2.
            let _ = e.print();
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
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(exit_code(&e))
        }
    }
}
