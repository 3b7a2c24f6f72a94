//! Fuzz target: the QIF plan reader as `truepos fit --qif-plan` uses it: `truepos_qif::read_plan`
//! on the text for every feature kind, then `truepos_qif::plan_spec` (the tolerance the
//! evaluation gets) with both decision rules. Either a plan whose numbers are all finite (mm)
//! and a spec, or an error — never a panic. An error with a position has line and column ≥ 1.
//! (The CLI reads the file with `read_to_string`: bytes that are not UTF-8 never reach the reader.)
#![no_main]

use libfuzzer_sys::fuzz_target;
use truepos_fit::evaluate::Kind;
use truepos_fit::verdict::DecisionRule;
use truepos_qif::{plan_spec, read_plan, PlanError};

const KINDS: [Kind; 6] = [Kind::Line, Kind::Plane, Kind::Circle, Kind::Sphere, Kind::Cylinder, Kind::Cone];

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    for kind in KINDS {
        match read_plan(text, kind.into()) {
            Ok(plan) => {
                if let Some((n, lo, hi)) = plan.diameter {
                    assert!(n.is_finite() && lo.is_finite() && hi.is_finite(), "{plan:?}");
                }
                if let Some(t) = plan.form_tolerance {
                    assert!(t.is_finite(), "{plan:?}");
                }
                for rule in [DecisionRule::Simple, DecisionRule::Guarded] {
                    let _ = plan_spec(&plan, kind, rule);
                }
            }
            Err(PlanError::At { line, column, .. }) => assert!(line >= 1 && column >= 1),
            Err(_) => {}
        }
    }
});
