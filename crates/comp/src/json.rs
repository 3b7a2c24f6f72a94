//! The JSON and the human text of `truepos load curves`: the portal's pitch and roll along its
//! travel under a load case, with the forces on the resting points.
//!
//! Entry points: [`curves`], [`curves_text`].

use crate::files::LoadCase;
use crate::influence::PortalCurves;
use serde_json::{json, Value};
use std::fmt::Write;

/// The curves as the contract's JSON (µrad; forces in N, points in mm).
pub fn curves(c: &PortalCurves, case: &LoadCase) -> Value {
    json!({
        "portal_y_mm": c.y(),
        "pitch_urad": c.pitch.iter().map(|v| v * 1e6).collect::<Vec<_>>(),
        "roll_urad": c.roll.iter().map(|v| v * 1e6).collect::<Vec<_>>(),
        "forces_n": case.loads.iter().map(|l| l.2).collect::<Vec<_>>(),
        "rest_points_mm": case.loads.iter().map(|l| [l.0, l.1]).collect::<Vec<_>>(),
        "weight_n": case.weight_n,
        "cog_mm": case.cog,
        "explicit_forces": case.explicit,
    })
}

/// The curves for people: the forces, then a table of portal y, pitch and roll.
pub fn curves_text(c: &PortalCurves, case: &LoadCase) -> String {
    let mut out = String::from("forces (N):\n");
    for l in &case.loads {
        let _ = writeln!(out, "  ({:.1}, {:.1}) mm  {:.3}", l.0, l.1, l.2);
    }
    let _ = writeln!(out, "{:>12} {:>12} {:>12}", "portal_y_mm", "pitch_urad", "roll_urad");
    for ((y, p), r) in c.y().iter().zip(&c.pitch).zip(&c.roll) {
        let _ = writeln!(out, "{y:12.3} {:12.4} {:12.4}", p * 1e6, r * 1e6);
    }
    out
}
