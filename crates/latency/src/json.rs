//! The JSON of `truepos latency --json` (the interface contract's latency object): the delay with
//! its standard and expanded uncertainty (k stated), the options it was estimated with, and each
//! method's own evidence (sizes per speed, per-axis delays, scan residuals, per-contact delays).
//!
//! Entry point: [`estimate`].

use crate::{Estimate, Options};
use serde_json::{json, Value};
use truepos_math::stats::COVERAGE_FACTOR;

/// The JSON object of an estimate (contract fields plus details).
pub fn estimate(e: &Estimate, opt: &Options) -> Value {
    let mut v = json!({
        "method": e.method().name(),
        "delay_s": e.delay,
        "uncertainty_s": e.u_delay,
        "n_contacts": e.n_contacts,
        "rms_mm": e.rms,
        "residual_delay_s": e.residual_delay,
        "already_corrected_s": opt.already_corrected,
        "threshold_mm": opt.threshold,
        "tip_radius_mm": opt.tip_radius,
        "warnings": e.warnings,
    });
    let o = v.as_object_mut().expect("json object");
    // Expanded uncertainties with their coverage factor, as every command states them.
    let k = COVERAGE_FACTOR;
    let mut expanded = json!({"delay_s": k * e.u_delay});
    if let Some(u) = e.u_static_size() {
        expanded["static_size_mm"] = json!(k * u);
    }
    o.insert("coverage_factor".into(), json!(k));
    o.insert("expanded_uncertainty".into(), expanded);
    if let Some(f) = e.feature() {
        o.insert("feature".into(), json!(f));
    }
    if let Some(s) = e.static_size() {
        o.insert("static_size_mm".into(), json!(s));
    }
    if let Some(u) = e.u_static_size() {
        o.insert("static_size_uncertainty_mm".into(), json!(u));
    }
    if !e.per_speed().is_empty() {
        o.insert(
            "per_speed".into(),
            json!(e
                .per_speed()
                .iter()
                .map(|(s, z)| json!({"speed_mm_s": s, "size_mm": z}))
                .collect::<Vec<_>>()),
        );
    }
    if let Some(pa) = e.per_axis() {
        o.insert("per_axis_delay_s".into(), json!(pa.delay));
        o.insert("per_axis_uncertainty_s".into(), json!(pa.u_delay));
    }
    if let Some(sc) = e.scan() {
        o.insert("scan_rms_before_mm".into(), json!(sc.rms_before));
        o.insert("scan_rms_after_mm".into(), json!(sc.rms_after));
        o.insert("scan_steps".into(), json!(sc.n_steps));
        o.insert("scan_radius_mm".into(), json!(sc.radius));
    }
    if !e.inout_each().is_empty() {
        o.insert("per_contact_delay_s".into(), json!(e.inout_each().iter().map(|p| p.0).collect::<Vec<_>>()));
    }
    v
}
