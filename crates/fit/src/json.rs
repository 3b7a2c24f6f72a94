//! The JSON of `truepos fit --json` (the interface contract's fit object): the element, its
//! residuals and form, standard and expanded uncertainties with the coverage factor, and the
//! characteristics with their verdicts. One definition, used by the binary and the demo.
//!
//! Entry point: [`evaluation`].

use crate::evaluate::{Evaluation, Method, Uncertainty, COVERAGE_FACTOR};
use crate::verdict::DecisionRule;
use nalgebra::Vector3;
use serde_json::{json, Map, Value};

fn v3(v: Vector3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

fn uncertainty_json(u: &Uncertainty) -> Value {
    let mut m = Map::new();
    let mut put3 = |k: &str, v: Option<Vector3<f64>>| {
        if let Some(v) = v {
            m.insert(k.into(), json!(v3(v)));
        }
    };
    put3("point_mm", u.point);
    put3("center_mm", u.center);
    put3("apex_mm", u.apex);
    put3("direction", u.direction);
    put3("normal", u.normal);
    put3("axis", u.axis);
    if let Some(r) = u.radius {
        m.insert("radius_mm".into(), json!(r));
    }
    if let Some(a) = u.apex_angle {
        m.insert("apex_angle_deg".into(), json!(a.to_degrees()));
    }
    Value::Object(m)
}

/// The evaluation as the JSON object of the interface contract (`truepos fit --json`).
pub fn evaluation(e: &Evaluation) -> Value {
    let mut m = Map::new();
    m.insert("kind".into(), json!(e.kind.name()));
    m.insert("method".into(), json!(e.method.name()));
    m.insert("n_points".into(), json!(e.n_points));
    let mut put3 = |k: &str, v: Option<Vector3<f64>>| {
        if let Some(v) = v {
            m.insert(k.into(), json!(v3(v)));
        }
    };
    put3("point_mm", e.point.map(|p| p.coords));
    put3("center_mm", e.center.map(|p| p.coords));
    put3("apex_mm", e.apex.map(|p| p.coords));
    put3("direction", e.direction);
    put3("normal", e.normal);
    put3("axis", e.axis);
    if let Some(r) = e.radius {
        m.insert("radius_mm".into(), json!(r));
    }
    if let Some(a) = e.apex_angle {
        m.insert("apex_angle_deg".into(), json!(a.to_degrees()));
    }
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
        if d.rule == DecisionRule::Guarded {
            c["guard_band_mm"] = json!(d.guard_band);
            c["guard_band_source"] = json!("least-squares expanded uncertainty of the diameter, k = 2");
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
