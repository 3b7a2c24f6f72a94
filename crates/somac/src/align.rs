//! `truepos align`: the best-fit transform between two point files matched by `id`, as a library
//! call. `to = scale · rotation · from + translation`, by weighted least squares (SVD with the
//! reflection guard, `truepos_math::bestfit`) or the three-point (3-2-1) method. Used to relate
//! a laser tracker's frame to the machine frame: `--from tracker.csv --to machine.csv` gives
//! `machine_from_tracker`.
//!
//! Entry point: [`align_files`], returning an [`Alignment`] (a `Report`: the contract's JSON and
//! the human text).

use serde_json::{json, Value};
use std::fmt::Write;
use std::path::Path;
use truepos_io::points::read_matched;
use truepos_io::report::Report;
use truepos_io::InputError;
use truepos_math::bestfit::{self, BestFitOptions};
use truepos_math::{Transform3, Vector3};

/// How the transform is found (`truepos align --method best-fit|three-point`; the variants'
/// documentation is the command line's help for each value, which names the option `--from`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Method {
    /// Least squares over all matched points (at least three, not collinear).
    BestFit,
    /// The first three matched points (in `from` order): 3-2-1 construction.
    #[cfg_attr(
        feature = "clap",
        value(help = "The first three matched points (in `--from` order): 3-2-1 construction")
    )]
    ThreePoint,
}

impl Method {
    /// The contract's name.
    pub fn name(self) -> &'static str {
        match self {
            Method::BestFit => "best-fit",
            Method::ThreePoint => "three-point",
        }
    }
}

/// What to align and how.
#[derive(Clone, Copy, Debug)]
pub struct AlignOptions<'a> {
    /// Also fit a uniform scale (similarity transform).
    pub scale: bool,
    /// A column of non-negative weights, looked up in `to`, then in `from`.
    pub weights: Option<&'a str>,
    /// How the transform is found.
    pub method: Method,
}

/// The transform `to_from_from` with its residuals.
#[derive(Clone, Debug)]
pub struct Alignment {
    /// How the transform was found.
    pub method: Method,
    /// The transform from the `from` frame to the `to` frame (mm).
    pub to_from_from: Transform3,
    /// The ids of the matched points, in `from` order.
    pub ids: Vec<String>,
    /// `to − transform · from` per matched point, mm.
    pub residuals: Vec<Vector3>,
}

impl Alignment {
    /// Root mean square of the residual lengths, mm.
    pub fn rms_mm(&self) -> f64 {
        truepos_math::stats::rms(&self.norms())
    }

    fn norms(&self) -> Vec<f64> {
        self.residuals.iter().map(|r| r.norm()).collect()
    }
}

impl Report for Alignment {
    fn to_json(&self) -> Value {
        let t = &self.to_from_from;
        let r = t.rotation;
        let norms = self.norms();
        json!({
            "method": self.method.name(),
            "n_points": self.ids.len(),
            "rotation": (0..3).map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]).collect::<Vec<_>>(),
            "translation_mm": <[f64; 3]>::from(t.translation),
            "scale": t.scale,
            "rotation_angle_deg": t.rotation_angle().to_degrees(),
            "rms_mm": self.rms_mm(),
            "max_residual_mm": truepos_math::stats::max_abs(&norms),
            "residuals": self.ids.iter().zip(&self.residuals).map(|(id, r)| json!({
                "id": id, "residual_mm": r.norm(), "residual_vector_mm": <[f64; 3]>::from(*r),
            })).collect::<Vec<_>>(),
        })
    }

    fn text(&self) -> String {
        let t = &self.to_from_from;
        let mut out = format!("to = scale · rotation · from + translation  ({} points)\n", self.ids.len());
        let _ = writeln!(out, "scale        {:.9}", t.scale);
        for i in 0..3 {
            let r = &t.rotation;
            let _ = writeln!(out, "rotation     {:+.12} {:+.12} {:+.12}", r[(i, 0)], r[(i, 1)], r[(i, 2)]);
        }
        let v = t.translation;
        let _ = writeln!(out, "translation  {:.6} {:.6} {:.6} mm", v.x, v.y, v.z);
        let _ = writeln!(out, "rms residual {:.6} mm", self.rms_mm());
        for (id, n) in self.ids.iter().zip(self.norms()) {
            let _ = writeln!(out, "  {id:>12}  {n:.6} mm");
        }
        out
    }
}

/// Align the points of `from` onto those of `to` (columns `id,x_mm,y_mm,z_mm`, matched by id).
/// Fewer than three common ids, a weight column in neither file, a negative weight, or a
/// degenerate configuration (named by `truepos_math::bestfit`) is an input error.
pub fn align_files(from: &Path, to: &Path, o: AlignOptions) -> Result<Alignment, InputError> {
    let (from_pts, to_pts, m) = read_matched(from, to, 3, "a rigid alignment")?;
    let weights = match o.weights {
        None => None,
        Some(col) => {
            let (src, rows) = if to_pts.table.column(col).is_some() {
                (&to_pts.table, &m.to_rows)
            } else if from_pts.table.column(col).is_some() {
                (&from_pts.table, &m.from_rows)
            } else {
                return Err(InputError::new(format!(
                    "weight column '{col}' is in neither {} nor {}",
                    to.display(),
                    from.display()
                )));
            };
            let all = src.f64_column(col)?;
            if let Some(i) = all.iter().position(|w| *w < 0.0) {
                let column = src.column(col).map(|c| c + 1);
                return Err(InputError::at(&src.path, src.line_number(i), column, "negative weight"));
            }
            Some(rows.iter().map(|&r| all[r]).collect::<Vec<f64>>())
        }
    };
    let fitted = match o.method {
        Method::BestFit => {
            bestfit::best_fit(&m.from, &m.to, weights.as_deref(), BestFitOptions { with_scale: o.scale })
        }
        Method::ThreePoint => bestfit::three_point(&m.from, &m.to, o.scale),
    };
    let t = fitted.map_err(|e| {
        InputError::in_file(to, format!("cannot align the {} points matched by id: {e}", m.ids.len()))
    })?;
    let residuals = bestfit::residuals(&t, &m.from, &m.to);
    Ok(Alignment { method: o.method, to_from_from: t, ids: m.ids, residuals })
}
