//! The demo: every capability end to end on the virtual cell, compared with the truth, written
//! as a report (`index.html` with tables and SVG plots, and `summary.json` with every table as
//! data).
//!
//! Entry points: [`sections`] (the demo's sections in report order, each a function adding its
//! part to a [`Report`]).

use crate::scenarios;
use truepos_report::Report;

/// One section of the demo report.
pub type SectionFn = fn(&mut Report) -> crate::error::Result<()>;

/// The demo's sections, in report order, with their names (fitting on the NIST reference data
/// first, then the virtual cell's capabilities).
pub fn sections() -> Vec<(&'static str, SectionFn)> {
    vec![
        ("fitting", scenarios::nist::demo_section as SectionFn),
        ("alignment", scenarios::align::demo_section),
        ("system delay", scenarios::latency::demo_section),
        ("head offset", scenarios::head::demo_section),
        ("bed load", scenarios::load::demo_section),
        ("scanning", scenarios::scan::demo_section),
        ("end-point control", scenarios::somac::demo_section),
        ("geometric map", scenarios::part::comp_section),
        ("autoscale", scenarios::part::autoscale_section),
        ("orient", scenarios::part::orient_section),
        ("air", scenarios::part::air_section),
        ("I++ DME", scenarios::interfaces::ippdme_section),
        ("controller", scenarios::interfaces::controller_section),
    ]
}
