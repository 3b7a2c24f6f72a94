//! The demo: every capability end to end on the virtual cell, compared with the truth, written
//! as a report (`index.html` with tables and SVG plots, and `summary.json` with every table as
//! data).
//!
//! Entry points: [`sections`] (the demo's sections in report order, each a function adding its
//! part to a [`Report`]).

use crate::report::Report;
use crate::scenarios;

/// One section of the demo report.
pub type SectionFn = fn(&mut Report) -> anyhow::Result<()>;

/// The virtual cell's sections of the demo, in report order, with their names. (The fitting
/// section, which needs the NIST reference data rather than the virtual cell, is the binary's.)
pub fn sections() -> Vec<(&'static str, SectionFn)> {
    vec![
        ("alignment", scenarios::align::demo_section as SectionFn),
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
