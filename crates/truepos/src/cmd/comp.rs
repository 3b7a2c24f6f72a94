//! `truepos comp` (being built; see ARCHITECTURE.md).

use crate::{DeviceError, Outcome};

#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<Outcome> {
    Err(DeviceError("not available yet".into()).into())
}
