//! `truepos fit` (being built; see ARCHITECTURE.md).

use crate::report::Report;
use crate::{DeviceError, Outcome};

#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<Outcome> {
    Err(DeviceError("not available yet".into()).into())
}

/// The fitting section of the demo report (NIST data sets against their certified fits).
pub fn demo_section(_report: &mut Report) -> anyhow::Result<()> {
    Ok(())
}
