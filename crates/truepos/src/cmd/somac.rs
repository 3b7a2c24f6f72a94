//! `truepos somac`, `autoscale`, `orient`, `air` (being built; see ARCHITECTURE.md).

use crate::report::Report;
use crate::{DeviceError, Outcome};

#[derive(clap::Args, Debug)]
pub struct Args {}
#[derive(clap::Args, Debug)]
pub struct AutoscaleArgs {}
#[derive(clap::Args, Debug)]
pub struct OrientArgs {}
#[derive(clap::Args, Debug)]
pub struct AirArgs {}

#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
}

fn todo() -> anyhow::Result<Outcome> {
    Err(DeviceError("not available yet".into()).into())
}
pub fn run(_a: Args) -> anyhow::Result<Outcome> { todo() }
pub fn autoscale(_a: AutoscaleArgs) -> anyhow::Result<Outcome> { todo() }
pub fn orient(_a: OrientArgs) -> anyhow::Result<Outcome> { todo() }
pub fn air(_a: AirArgs) -> anyhow::Result<Outcome> { todo() }
pub fn simulate(_a: SimArgs) -> anyhow::Result<Outcome> { todo() }

/// This capability's section of the demo report.
pub fn demo_section(_report: &mut Report) -> anyhow::Result<()> {
    Ok(())
}
