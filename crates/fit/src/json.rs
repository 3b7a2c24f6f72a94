//! The JSON of `truepos fit --json` (the interface contract's fit object): the element, its
//! residuals and form, standard and expanded uncertainties with the coverage factor, and the
//! characteristics with their verdicts. One definition, used by the binary and the demo.
//!
//! Entry points: [`evaluation`], [`text`] (the same for people, as `truepos fit` prints it).

use crate::evaluate::{Evaluation, Method, Uncertainty, COVERAGE_FACTOR};
use crate::verdict::DecisionRule;
use nalgebra::Vector3;
use serde_json::{json, Map, Value};
use std::fmt::Write;

fn v3(v: Vector3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

/// The element's geometry into `m` under the contract's names (only what the kind has): points
/// and vectors as `[x, y, z]`, the radius in mm, the apex angle in degrees. Used for the element
/// and for its uncertainties, which have the same shape.
fn put_geometry(
    m: &mut Map<String, Value>,
    vectors: [(&str, Option<Vector3<f64>>); 6],
    radius: Option<f64>,
    apex_angle: Option<f64>,
) {
    for (k, v) in vectors {
        if let Some(v) = v {
            m.insert(k.into(), v3(v));
        }
    }
    if let Some(r) = radius {
        m.insert("radius_mm".into(), json!(r));
    }
    if let Some(a) = apex_angle {
        m.insert("apex_angle_deg".into(), json!(a.to_degrees()));
    }
}

fn uncertainty_json(u: &Uncertainty) -> Value {
    let mut m = Map::new();
    let vectors = [
        ("point_mm", u.point),
        ("center_mm", u.center),
        ("apex_mm", u.apex),
        ("direction", u.direction),
        ("normal", u.normal),
        ("axis", u.axis),
    ];
    put_geometry(&mut m, vectors, u.radius, u.apex_angle);
    Value::Object(m)
}

/// The evaluation as the JSON object of the interface contract (`truepos fit --json`).
pub fn evaluation(e: &Evaluation) -> Value {
    let mut m = Map::new();
    m.insert("kind".into(), json!(e.kind.name()));
    m.insert("method".into(), json!(e.method.name()));
    m.insert("n_points".into(), json!(e.n_points));
    let vectors = [
        ("point_mm", e.point.map(|p| p.coords)),
        ("center_mm", e.center.map(|p| p.coords)),
        ("apex_mm", e.apex.map(|p| p.coords)),
        ("direction", e.direction),
        ("normal", e.normal),
        ("axis", e.axis),
    ];
    put_geometry(&mut m, vectors, e.radius, e.apex_angle);
    m.insert("rms_mm".into(), json!(e.rms));
    m.insert("max_abs_residual_mm".into(), json!(e.max_abs_residual));
    m.insert("form_mm".into(), json!(e.form));
    if let Some((i, o)) = e.zone_radii {
        m.insert("inner_radius_mm".into(), json!(i));
        m.insert("outer_radius_mm".into(), json!(o));
    }
    for (k, v) in &e.extras {
        if e.uncertainty.is_none() && k.contains("uncertainty") {
            continue;
        }
        m.insert((*k).into(), if *k == "iterations" { json!(*v as u64) } else { json!(v) });
    }
    if let Some(u) = &e.uncertainty {
        // Earlier field names, kept: per-component vectors of the centre and apex.
        if let Some(c) = u.center {
            m.insert("center_uncertainty_mm".into(), json!(v3(c)));
        }
        if let Some(a) = u.apex {
            m.insert("apex_uncertainty_mm".into(), json!(v3(a)));
        }
        if let Some(a) = u.apex_angle {
            m.insert("apex_angle_uncertainty_deg".into(), json!(a.to_degrees()));
        }
        m.insert("uncertainty".into(), uncertainty_json(u));
        m.insert("coverage_factor".into(), json!(COVERAGE_FACTOR));
        m.insert("expanded_uncertainty".into(), uncertainty_json(&u.scaled(COVERAGE_FACTOR)));
    } else if e.method == Method::LeastSquares {
        m.insert(
            "uncertainty_note".into(),
            json!("not determined: as many residuals as parameters (n − p = 0), the fit is exact whatever the noise"),
        );
    }
    let mut chars = Vec::new();
    if let Some(d) = &e.size_decision {
        let mut c = json!({
            "characteristic": "diameter",
            "nominal_mm": d.tolerance.nominal,
            "lower_deviation_mm": d.tolerance.lower,
            "upper_deviation_mm": d.tolerance.upper,
            "actual_mm": e.radius.map_or(d.tolerance.nominal + d.deviation, |r| 2.0 * r),
            "deviation_mm": d.deviation,
            "decision_rule": d.rule.name(),
            "verdict": d.verdict.name(),
        });
        if d.rule == DecisionRule::Guarded && d.guard_band.is_finite() {
            c["guard_band_mm"] = json!(d.guard_band);
            c["guard_band_source"] = json!("least-squares expanded uncertainty of the diameter, k = 2");
        } else if d.rule == DecisionRule::Guarded {
            c["guard_band_mm"] = serde_json::Value::Null;
            c["guard_band_source"] = json!(
                "not determined: the diameter's uncertainty needs more points than the fit has parameters; a guarded decision is undecided"
            );
        }
        chars.push(c);
    }
    if let Some(f) = &e.form_decision {
        chars.push(json!({
            "characteristic": "form",
            "tolerance_mm": f.tolerance,
            "actual_mm": e.form,
            "decision_rule": "simple",
            "verdict": f.verdict.name(),
        }));
    }
    if let Some(v) = e.verdict {
        m.insert("characteristics".into(), Value::Array(chars));
        m.insert("verdict".into(), json!(v.name()));
    }
    Value::Object(m)
}

/// One line into the text (writing to a `String` cannot fail).
macro_rules! w {
    ($($t:tt)*) => {{
        let _ = writeln!($($t)*);
    }};
}

fn fmt3(v: &Value) -> String {
    match v.as_array() {
        Some(a) => {
            a.iter().map(|x| format!("{:.6}", x.as_f64().unwrap_or(f64::NAN))).collect::<Vec<_>>().join(", ")
        }
        None => String::new(),
    }
}

/// An uncertainty in fixed notation with two significant digits (`0.00000024`, `0.00030`,
/// `1.2`), so that a small one is never shown as zero; an exact zero is `0`.
pub fn fmt_uncertainty(u: f64) -> String {
    if !u.is_finite() {
        return format!("{u}");
    }
    if u == 0.0 {
        return "0".into();
    }
    let decimals = (1 - u.abs().log10().floor() as i32).clamp(0, 20) as usize;
    format!("{u:.decimals$}")
}

/// The fit object of [`evaluation`] for people: geometry first, then residuals and form, then
/// expanded uncertainties (k stated) and the characteristics with their verdicts.
pub fn text(v: &Value) -> String {
    let mut out = String::new();
    // Human output: geometry first, then residuals and form, then uncertainties.
    let order = [
        ("center_mm", "centre", "mm"),
        ("point_mm", "point", "mm"),
        ("apex_mm", "apex", "mm"),
        ("direction", "direction", ""),
        ("normal", "normal", ""),
        ("axis", "axis", ""),
        ("radius_mm", "radius", "mm"),
        ("inner_radius_mm", "inner radius", "mm"),
        ("outer_radius_mm", "outer radius", "mm"),
        ("apex_angle_deg", "apex angle", "°"),
        ("surface_distance_mm", "surface distance", "mm"),
        ("rms_mm", "rms residual", "mm"),
        ("max_abs_residual_mm", "max |residual|", "mm"),
        ("form_mm", "form", "mm"),
    ];
    for (key, label, unit) in order {
        match v.get(key) {
            Some(x) if x.is_array() => w!(out, "  {label:<22} {}  {unit}", fmt3(x)),
            Some(x) => w!(out, "  {label:<22} {:.9}  {unit}", x.as_f64().unwrap_or(f64::NAN)),
            None => {}
        }
    }
    if let Some(u) = v.get("expanded_uncertainty").and_then(|u| u.as_object()) {
        w!(out, "  expanded uncertainties (k = {COVERAGE_FACTOR}):");
        for (k, x) in u {
            // The quantity's label and unit as above (`U(centre)`, mm), two significant digits.
            let (label, unit) = order
                .iter()
                .find(|(key, ..)| key == k)
                .map(|(_, l, u)| (l.to_string(), *u))
                .unwrap_or_else(|| (k.clone(), ""));
            let shown = match x.as_array() {
                Some(a) => a
                    .iter()
                    .map(|c| fmt_uncertainty(c.as_f64().unwrap_or(f64::NAN)))
                    .collect::<Vec<_>>()
                    .join(", "),
                None => fmt_uncertainty(x.as_f64().unwrap_or(f64::NAN)),
            };
            let unit = if unit.is_empty() { "(unit vector components)" } else { unit };
            w!(out, "    {:<21} {shown}  {unit}", format!("U({label})"));
        }
    }
    if let Some(cs) = v.get("characteristics").and_then(|c| c.as_array()) {
        for c in cs {
            w!(
                out,
                "  {:<9} actual {:.6} mm: {}",
                c["characteristic"].as_str().unwrap_or(""),
                c["actual_mm"].as_f64().unwrap_or(f64::NAN),
                c["verdict"].as_str().unwrap_or("")
            );
        }
        w!(out, "  verdict: {}", v["verdict"].as_str().unwrap_or(""));
    }
    out
}

#[cfg(test)]
mod uncertainty_text_tests {
    use super::fmt_uncertainty;

    #[test]
    fn small_uncertainties_keep_two_significant_digits() {
        assert_eq!(fmt_uncertainty(2.36e-7), "0.00000024");
        assert_eq!(fmt_uncertainty(0.000298), "0.00030");
        assert_eq!(fmt_uncertainty(1.234), "1.2");
        assert_eq!(fmt_uncertainty(25.0), "25");
        assert_eq!(fmt_uncertainty(0.0), "0");
    }
}
