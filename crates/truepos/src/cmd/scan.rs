//! `truepos scan` (being built; see ARCHITECTURE.md).

use crate::report::Report;
use crate::{DeviceError, Outcome};

#[derive(clap::Args, Debug)]
pub struct Args {}

#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
}

pub fn run(_args: Args) -> anyhow::Result<Outcome> {
    Err(DeviceError("not available yet".into()).into())
}

pub fn simulate(_args: SimArgs) -> anyhow::Result<Outcome> {
    Err(DeviceError("not available yet".into()).into())
}

/// This capability's section of the demo report.
pub fn demo_section(_report: &mut Report) -> anyhow::Result<()> {
    Ok(())
}
