//! What the virtual-gantry tests and the error-budget example share: one run of the loop on
//! the aluminium spar, and the loop settings for it.

use std::collections::BTreeMap;
use truepos_gcode::Program;
use truepos_math::Point3;
use truepos_plant::gantry::{CellConfig, VirtualCell};
use truepos_sim::scenario::somac::{spar, SparConfig};
use truepos_somac::audit::MemoryAudit;
use truepos_somac::{run_program, Params, RunReport};

/// Run the loop on a spar with `holes_per_row` holes per row: the report, each hole's true
/// error (mm) and the audit events.
pub fn run(cfg: CellConfig, params: &Params, holes_per_row: usize) -> (RunReport, Vec<f64>, MemoryAudit) {
    let sp = spar(&SparConfig { holes_per_row, ..Default::default() });
    let cell = VirtualCell::new(cfg, sp.targets.clone());
    let mut trackers = cell.align_trackers().unwrap();
    let mut ctl = cell.controller();
    let mut sensors = cell.sensors();
    let mut audit = MemoryAudit::default();
    let program = Program::parse(&sp.program);
    let report = run_program(&program, &mut ctl, &mut trackers, &mut sensors, params, &mut audit).unwrap();
    let holes: BTreeMap<usize, Point3> = sp.holes.iter().copied().collect();
    let errors = cell.hole_errors(&holes).into_iter().map(|e| e.1).collect();
    (report, errors, audit)
}

/// The loop settings for the aluminium spar: re-scale every 0.1 °C so the stale scale stays
/// below 23 ppm/°C · 0.1 °C · 5 m ≈ 12 µm at the ends; ten samples per reading (σ ≈ 4 µm per
/// axis fused) and a 15 µm threshold.
pub fn spar_params() -> Params {
    Params {
        autoscale_step_c: 0.1,
        threshold_mm: 0.015,
        max_iterations: 6,
        samples: 10,
        ..Default::default()
    }
}
