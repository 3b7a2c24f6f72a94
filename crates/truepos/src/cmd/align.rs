//! `truepos align`: the best-fit transform between two point files matched by `id`.
//!
//! `to = scale · rotation · from + translation`, by weighted least squares (SVD with the
//! reflection guard) or the three-point method. Used to relate a laser tracker's frame to the
//! machine frame (`--from tracker.csv --to machine.csv` gives `machine_from_tracker`).

use crate::output::{print_json, v3};
use crate::{Outcome, UsageError};
use anyhow::Result;
use serde_json::json;
use std::path::PathBuf;
use truepos_io::points::{read_matched, Matched};
use truepos_io::InputError;
use truepos_math::bestfit::{self, BestFitOptions};
use truepos_math::Transform3;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Least squares over all matched points (at least three, not collinear).
    BestFit,
    /// The first three matched points (in `--from` order): 3-2-1 construction.
    ThreePoint,
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  truepos align --from tracker.csv --to machine.csv --json\n\nBoth files have columns id,x_mm,y_mm,z_mm; points are matched by id. The result maps\n`from` coordinates to `to` coordinates: to = scale · rotation · from + translation."
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
    #[arg(long, value_enum, default_value_t = Method::BestFit)]
    pub method: Method,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Fit `to_from_from` with the options of the command line.
pub fn fit_transform(
    m: &Matched,
    weights: Option<&[f64]>,
    scale: bool,
    method: Method,
    file: &PathBuf,
) -> Result<Transform3, InputError> {
    let r = match method {
        Method::BestFit => bestfit::best_fit(&m.from, &m.to, weights, BestFitOptions { with_scale: scale }),
        Method::ThreePoint => bestfit::three_point(&m.from, &m.to, scale),
    };
    r.map_err(|e| {
        InputError::in_file(file, format!("cannot align the {} points matched by id: {e}", m.ids.len()))
    })
}

pub fn run(a: Args) -> Result<Outcome> {
    let (from, to, m) = read_matched(&a.from, &a.to, 3, "a rigid alignment")?;
    let weights = match &a.weights {
        None => None,
        Some(col) => {
            let (src, rows) = if to.table.column(col).is_some() {
                (&to.table, &m.to_rows)
            } else if from.table.column(col).is_some() {
                (&from.table, &m.from_rows)
            } else {
                return Err(UsageError(format!(
                    "weight column '{col}' is in neither {} nor {}",
                    a.to.display(),
                    a.from.display()
                ))
                .into());
            };
            let all = src.f64_column(col)?;
            for (i, w) in all.iter().enumerate() {
                if *w < 0.0 {
                    return Err(InputError::at(
                        &src.path,
                        src.line_number(i),
                        src.column(col).map(|c| c + 1),
                        "negative weight",
                    )
                    .into());
                }
            }
            Some(rows.iter().map(|&r| all[r]).collect::<Vec<f64>>())
        }
    };
    let t = fit_transform(&m, weights.as_deref(), a.scale, a.method, &a.to)?;
    let res = bestfit::residuals(&t, &m.from, &m.to);
    let norms: Vec<f64> = res.iter().map(|r| r.norm()).collect();
    let rms = truepos_math::stats::rms(&norms);
    if a.json {
        let r = t.rotation;
        print_json(&json!({
            "method": match a.method { Method::BestFit => "best-fit", Method::ThreePoint => "three-point" },
            "n_points": m.ids.len(),
            "rotation": [[r[(0,0)], r[(0,1)], r[(0,2)]], [r[(1,0)], r[(1,1)], r[(1,2)]], [r[(2,0)], r[(2,1)], r[(2,2)]]],
            "translation_mm": v3(t.translation),
            "scale": t.scale,
            "rotation_angle_deg": t.rotation_angle().to_degrees(),
            "rms_mm": rms,
            "max_residual_mm": truepos_math::stats::max_abs(&norms),
            "residuals": m.ids.iter().zip(&res).map(|(id, r)| json!({"id": id, "residual_mm": r.norm(), "residual_vector_mm": v3(*r)})).collect::<Vec<_>>(),
        }))?;
    } else {
        println!("to = scale · rotation · from + translation  ({} points)", m.ids.len());
        println!("scale        {:.9}", t.scale);
        for i in 0..3 {
            println!(
                "rotation     {:+.12} {:+.12} {:+.12}",
                t.rotation[(i, 0)],
                t.rotation[(i, 1)],
                t.rotation[(i, 2)]
            );
        }
        println!("translation  {:.6} {:.6} {:.6} mm", t.translation.x, t.translation.y, t.translation.z);
        println!("rms residual {:.6} mm", rms);
        for (id, n) in m.ids.iter().zip(&norms) {
            println!("  {id:>12}  {n:.6} mm");
        }
    }
    Ok(Outcome::Done)
}
