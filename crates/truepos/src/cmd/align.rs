//! `truepos align`: the best-fit transform between two point files matched by `id`
//! (`truepos_somac::align`; `--from tracker.csv --to machine.csv` gives `machine_from_tracker`).

use crate::output::emit;
use crate::Outcome;
use anyhow::Result;
use std::path::PathBuf;
use truepos_somac::align;

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Both files have columns id,x_mm,y_mm,z_mm; points are matched by id. The result maps\n`from` coordinates to `to` coordinates: to = scale · rotation · from + translation."
)]
pub struct Args {
    /// Points in the source frame (columns id,x_mm,y_mm,z_mm).
    #[arg(long)]
    pub from: PathBuf,
    /// The same points (same ids) in the target frame.
    #[arg(long)]
    pub to: PathBuf,
    /// Also fit a uniform scale factor (similarity transform).
    #[arg(long)]
    pub scale: bool,
    /// Name of a column of weights (looked up in --to, then in --from).
    #[arg(long)]
    pub weights: Option<String>,
    /// How the transform is found: least squares over all matched points, or the first three (3-2-1).
    #[arg(long, value_enum, default_value_t = align::Method::BestFit)]
    pub method: align::Method,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> Result<Outcome> {
    let o = align::AlignOptions { scale: a.scale, weights: a.weights.as_deref(), method: a.method };
    emit(&align::align_files(&a.from, &a.to, o)?, a.json)?;
    Ok(Outcome::Done)
}
