//! The JSON of `truepos scan plan --json` and `truepos scan run --json` (the interface
//! contract's scan objects): cycle time, stops, and per feature its time, form error, contact
//! shift, vibration and settling.
//!
//! Entry points: [`plan`], [`run`], [`text`] (a run for people), [`feature_times`].

use crate::execute::Run;
use crate::{Plan, SegmentKind, Style};
use serde_json::{json, Value};
use std::fmt::Write;
use std::path::Path;

/// A plan as JSON (`truepos scan plan --json`), `n_points` the samples written.
pub fn plan(pl: &Plan, style: Style, n_points: usize) -> Value {
    json!({
        "style": style.name(),
        "cycle_time_s": pl.duration(),
        "stops": pl.stops(),
        "n_points": n_points,
        "features": feature_times(pl).iter().map(|(id, t)| json!({"id": id, "time_s": t})).collect::<Vec<_>>(),
    })
}

/// A run on a machine as JSON (`truepos scan run --json`).
pub fn run(r: &Run, style: Style) -> Value {
    json!({
        "style": style.name(),
        "cycle_time_s": r.cycle_time,
        "stops": r.stops,
        "n_points": r.points.len(),
        "form_error_method": "least-squares element of the scan segment (truepos-fit: 3D circle for bores and bosses, plane for circles on a plane, line for lines), peak-to-valley of the residuals",
        "features": r.features.iter().map(|f| json!({
            "id": f.id,
            "time_s": f.time,
            "form_error_mm": if f.form_error.is_finite() { json!(f.form_error) } else { Value::Null },
            "form_error_note": f.form_note,
            "contact_shift_mm": f.contact_shift,
            "vibration_rms_mm": f.vibration_rms,
            "vibration_peak_mm": f.vibration_peak,
            "settle_time_s": f.settle_time,
            "contact_to_scan_s": f.ready_time,
            "scan_points": f.scan_points,
            "quality0_share": f.quality0_share,
        })).collect::<Vec<_>>(),
    })
}

/// Planned time of each feature from its approach start to its release end.
pub fn feature_times(pl: &Plan) -> Vec<(String, f64)> {
    pl.features
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
            for (s, &t) in pl.segments.iter().zip(&pl.starts) {
                if s.feature == k && s.kind != SegmentKind::Transfer {
                    a = a.min(t);
                    b = b.max(t + s.duration());
                }
            }
            (f.id.clone(), b - a)
        })
        .collect()
}

/// One line into the text (writing to a `String` cannot fail).
macro_rules! w {
    ($($t:tt)*) => {{
        let _ = writeln!($($t)*);
    }};
}

/// A run for people (`truepos scan run`): cycle time, stops, the points file, and per feature its
/// time, form error, contact shift and scan-start vibration.
pub fn text(r: &Run, style: Style, output: &Path) -> String {
    let mut out = String::new();
    w!(
        out,
        "{} style: cycle {:.3} s, {} stops, {} points written to {}",
        style.name(),
        r.cycle_time,
        r.stops,
        r.points.len(),
        output.display()
    );
    for f in &r.features {
        w!(
            out,
            "  {:12} {:7.3} s  form {:>7} µm  shift {:+8.3} mm  scan-start vibration {:6.2} µm rms",
            f.id,
            f.time,
            match &f.form_note {
                None => format!("{:.2}", f.form_error * 1e3),
                Some(_) => "-".to_string(),
            },
            f.contact_shift,
            f.vibration_rms * 1e3
        );
    }
    out
}
