//! `truepos align`: the best-fit transform between two point files matched by `id`.
//!
//! `to = scale · rotation · from + translation`, by weighted least squares (SVD with the
//! reflection guard) or the three-point method. Used to relate a laser tracker's frame to the
//! machine frame (`--from tracker.csv --to machine.csv` gives `machine_from_tracker`).

use crate::output::{print_json, v3};
use crate::report::{self, Report};
use crate::{Outcome, UsageError};
use anyhow::Result;
use serde_json::json;
use std::collections::HashMap;
use std::path::PathBuf;
use truepos_io::csv::Table;
use truepos_io::InputError;
use truepos_math::bestfit::{self, BestFitOptions};
use truepos_math::{Point3, Transform3};

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
    #[arg(long, value_enum, default_value_t = Method::BestFit)]
    pub method: Method,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Points of a file with their ids (ids required, unique).
pub struct IdPoints {
    pub ids: Vec<String>,
    pub points: Vec<Point3>,
    pub table: Table,
}

pub fn read_id_points(path: &PathBuf) -> Result<IdPoints, InputError> {
    let table = Table::read(path)?;
    let xyz = table.f64_columns(&["x_mm", "y_mm", "z_mm"])?;
    let ids = table.str_column("id")?;
    let mut seen = HashMap::new();
    for (i, id) in ids.iter().enumerate() {
        if id.trim().is_empty() {
            return Err(InputError::at(
                path,
                table.line_number(i),
                table.column("id").map(|c| c + 1),
                "empty id: every point needs an id to be matched",
            ));
        }
        if let Some(prev) = seen.insert(id.clone(), i) {
            return Err(InputError::at(
                path,
                table.line_number(i),
                table.column("id").map(|c| c + 1),
                format!("duplicate id '{id}' (also on line {})", table.line_number(prev)),
            ));
        }
    }
    let points = xyz.chunks_exact(3).map(|c| Point3::new(c[0], c[1], c[2])).collect();
    Ok(IdPoints { ids, points, table })
}

/// Pairs of points matched by id, in the order of `from`.
pub struct Matched {
    pub ids: Vec<String>,
    pub from: Vec<Point3>,
    pub to: Vec<Point3>,
    pub from_rows: Vec<usize>,
    pub to_rows: Vec<usize>,
}

pub fn match_by_id(from: &IdPoints, to: &IdPoints) -> Matched {
    let index: HashMap<&str, usize> = to.ids.iter().enumerate().map(|(i, s)| (s.as_str(), i)).collect();
    let mut m = Matched { ids: vec![], from: vec![], to: vec![], from_rows: vec![], to_rows: vec![] };
    for (i, id) in from.ids.iter().enumerate() {
        if let Some(&j) = index.get(id.as_str()) {
            m.ids.push(id.clone());
            m.from.push(from.points[i]);
            m.to.push(to.points[j]);
            m.from_rows.push(i);
            m.to_rows.push(j);
        }
    }
    m
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
    let from = read_id_points(&a.from)?;
    let to = read_id_points(&a.to)?;
    let m = match_by_id(&from, &to);
    if m.ids.len() < 3 {
        return Err(InputError::in_file(
            &a.to,
            format!(
                "only {} ids are common to {} and {}; at least 3 are needed",
                m.ids.len(),
                a.from.display(),
                a.to.display()
            ),
        )
        .into());
    }
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

/// Demo: align a simulated tracker frame to the machine frame.
pub fn demo_section(report: &mut Report) -> Result<()> {
    use truepos_math::types::{rx, ry, rz};
    use truepos_math::Vector3;
    // A tracker 3 m from the machine origin, rotated; 8 reflector positions; 10 µm noise.
    let truth = Transform3::rigid(rz(0.7) * ry(0.01) * rx(-0.02), Vector3::new(3000.0, -1200.0, 150.0));
    let machine: Vec<Point3> = (0..8)
        .map(|i| {
            Point3::new(
                if i & 1 == 0 { 0.0 } else { 4000.0 },
                if i & 2 == 0 { 0.0 } else { 2000.0 },
                if i & 4 == 0 { 0.0 } else { 800.0 },
            )
        })
        .collect();
    let tracker_from_machine = truth.inverse();
    // Deterministic "noise" with ~10 µm amplitude.
    let tracker: Vec<Point3> = machine
        .iter()
        .enumerate()
        .map(|(i, p)| {
            tracker_from_machine.apply(p)
                + Vector3::new(
                    ((i * 7) % 5) as f64 - 2.0,
                    ((i * 3) % 5) as f64 - 2.0,
                    ((i * 11) % 5) as f64 - 2.0,
                ) * 0.005
        })
        .collect();
    let est = bestfit::best_fit(&tracker, &machine, None, BestFitOptions::default())?;
    let rows: Vec<Vec<String>> = machine
        .iter()
        .zip(&tracker)
        .enumerate()
        .map(|(i, (m, t))| {
            vec![
                format!("P{i}"),
                format!("{:.1}, {:.1}, {:.1}", m.x, m.y, m.z),
                format!("{:.4}", (est.apply(t) - m).norm() * 1000.0),
            ]
        })
        .collect();
    let html = format!(
        "<p>Machine from tracker by weighted least squares (SVD, reflection guard) over 8 reflector positions with ±10 µm noise. Rotation error {:.2} µrad, translation error {:.2} µm.</p>{}",
        (est.rotation.transpose() * truth.rotation).rotation_angle_from_matrix() * 1e6,
        (est.translation - truth.translation).norm() * 1000.0,
        report::table(&["point", "machine (mm)", "residual (µm)"], &rows)
    );
    report.add("align", "Tracker-to-machine alignment", html);
    Ok(())
}

trait AngleOf {
    fn rotation_angle_from_matrix(&self) -> f64;
}
impl AngleOf for truepos_math::Matrix3 {
    fn rotation_angle_from_matrix(&self) -> f64 {
        ((self.trace() - 1.0) * 0.5).clamp(-1.0, 1.0).acos()
    }
}
