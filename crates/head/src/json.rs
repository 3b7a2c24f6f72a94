//! The JSON of `truepos head-offset --json` (the interface contract's head-offset object): the
//! offset with per-component observability, standard and expanded uncertainties (k stated), the
//! reference point, the orientations and the solver's diagnostics.
//!
//! Entry points: [`result`], [`notes`] (warnings on observability), [`text`] (the same for people, as `truepos head-offset` prints it).

use crate::file::Input;
use crate::{HeadOffset, Params, Reference};
use serde_json::{json, Value};
use std::fmt::Write;
use truepos_math::stats::COVERAGE_FACTOR;

fn v3(v: impl Into<[f64; 3]>) -> Value {
    json!(v.into())
}

/// The calibration result as JSON: `r` solved with `setup`; `tip` the touch-probe tip radius and
/// `diameter` the sphere diameter given by the user (mm), `input` the readings' names.
pub fn result(r: &HeadOffset, setup: &Params, tip: f64, diameter: Option<f64>, input: &Input) -> Value {
    let name = |names: &[String], id: i64| names.get(id as usize).cloned().unwrap_or_default();
    let unc: Vec<Value> = r.u_offset.iter().map(|u| u.map_or(Value::Null, |v| json!(v))).collect();
    let sphere_diameter = match (setup.reference, r.radius) {
        (Reference::Sphere { .. }, Some(rad)) => Some(diameter.unwrap_or(2.0 * (rad - tip))),
        _ => None,
    };
    let k = COVERAGE_FACTOR;
    let expanded = json!({
        "offset_mm": r.u_offset.iter().map(|u| u.map_or(Value::Null, |v| json!(k * v))).collect::<Vec<_>>(),
        "reference_point_mm": v3(r.u_reference_point * k),
        "radius_mm": r.u_radius.map(|u| k * u),
    });
    json!({
        "offset_mm": v3(r.offset),
        "observable": r.observable,
        "coverage_factor": k,
        "expanded_uncertainty": expanded,
        "from_tilt": r.from_tilt,
        "reference_point_depends_on_prior": r.reference_depends_on_prior,
        "uncertainty_mm": unc,
        "reference": match setup.reference { Reference::Sphere { .. } => "sphere", Reference::Vertex { .. } => "vertex" },
        "reference_point_mm": v3(r.reference_point),
        "reference_point_uncertainty_mm": v3(r.u_reference_point),
        "radius_mm": r.radius,
        "radius_uncertainty_mm": r.u_radius,
        "sphere_diameter_mm": sphere_diameter,
        "tip_radius_mm": tip,
        "rms_mm": r.rms,
        "max_residual_mm": r.max_abs_residual,
        "n_points": r.n_points,
        "n_orientations": r.orientations.len(),
        "orientations": r.orientations.iter().map(|o| json!({
            "b_deg": o.b.to_degrees(), "c_deg": o.c.to_degrees(), "group": o.group.map(|g| name(&input.group_names, g)),
            "n_points": o.n_points, "apparent_point_mm": v3(o.apparent),
        })).collect::<Vec<_>>(),
        "face_normals": r.face_normals.iter().map(|(id, n)| json!({"face": name(&input.face_names, *id), "normal": v3(*n)})).collect::<Vec<_>>(),
        "prior_offset_mm": v3(setup.prior),
        "closed_form_offset_mm": v3(r.closed_form_offset),
        "table_center_mm": v3(setup.table_center),
        "tilt_deg": [setup.tilt[0].to_degrees(), setup.tilt[1].to_degrees()],
        "condition": if r.condition.is_finite() { json!(r.condition) } else { Value::Null },
        "iterations": r.iterations,
        "converged": r.converged,
    })
}

/// One line into the text (writing to a `String` cannot fail).
macro_rules! w {
    ($($t:tt)*) => {{
        let _ = writeln!($($t)*);
    }};
}

const AXES: [&str; 3] = ["X", "Y", "Z"];

/// The calibration result for people: each offset component with its standard uncertainty or
/// "not observable", the reference point, the radius, the residuals (`tip`: the touch-probe tip
/// radius, mm).
pub fn text(r: &HeadOffset, tip: f64) -> String {
    let mut out = String::new();
    w!(out, "head offset R ({} points, {} orientations)", r.n_points, r.orientations.len());
    for j in 0..3 {
        match r.u_offset[j] {
            Some(u) => {
                w!(out, "  R{} = {:+.6} mm  ± {:.4} µm (1σ)", AXES[j].to_lowercase(), r.offset[j], u * 1e3)
            }
            None => w!(
                out,
                "  R{} = {:+.6} mm  not observable (prior, not measured)",
                AXES[j].to_lowercase(),
                r.offset[j]
            ),
        }
    }
    let p = r.reference_point;
    w!(out, "reference point at c = 0: {:.6}, {:.6}, {:.6} mm", p.x, p.y, p.z);
    for j in 0..3 {
        if r.reference_depends_on_prior[j] {
            w!(
                out,
                "  (its {} follows the prior offset: only A{} − R{} is measured)",
                AXES[j],
                AXES[j].to_lowercase(),
                AXES[j].to_lowercase()
            );
        }
    }
    if let Some(rad) = r.radius {
        match r.u_radius {
            Some(u) => w!(out, "radius {rad:.6} mm ± {:.4} µm", u * 1e3),
            None => w!(out, "radius {rad:.6} mm (fixed)"),
        }
        if tip > 0.0 {
            w!(out, "sphere diameter {:.6} mm (radius − tip radius {tip} mm, doubled)", 2.0 * (rad - tip));
        }
    }
    w!(out, "rms {:.4} µm, max {:.4} µm", r.rms * 1e3, r.max_abs_residual * 1e3);
    out
}

/// Why offset component `j` (0 = X, 1 = Y, 2 = Z) is not observable, and what to add.
fn why_unobservable(j: usize) -> &'static str {
    match j {
        1 => "a swivel about Y moves no point along Y: turn the table as well",
        2 => "a table turn about Z moves no point along Z: swivel the head as well",
        _ => "add orientations with other B and C angles",
    }
}

/// Notes and warnings on a result for the user: components that come from the beam tilt rather
/// than a rotation, and components the orientations cannot determine (held at `prior`, mm).
pub fn notes(r: &HeadOffset, prior: &truepos_math::Vector3) -> Vec<String> {
    let mut out = Vec::new();
    for j in 0..3 {
        if r.from_tilt[j] {
            out.push(format!(
                "note: offset component {} comes from the beam tilt (R parallel to the beam), not from a rotation",
                AXES[j]
            ));
        }
        if !r.observable[j] {
            out.push(format!(
                "warning: offset component {} is not observable from these orientations ({}); held at the \
                 prior {} mm, not measured",
                AXES[j],
                why_unobservable(j),
                prior[j]
            ));
        }
    }
    out
}
