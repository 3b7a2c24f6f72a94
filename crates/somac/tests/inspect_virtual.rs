//! In-spindle inspection on the virtual machine tool: hole positions and diameters against the
//! plate's truth, and a hole too far off its nominal refused with the machine retracted.

use truepos_device::{DeviceError, ProbingMachine};
use truepos_math::Point3;
use truepos_plant::probing::{MachineToolConfig, VirtualMachineTool};
use truepos_somac::inspect::{inspect, Hole, InspectError, InspectPlan};

fn holes() -> Vec<Hole> {
    (0..6)
        .map(|i| Hole {
            id: format!("H{i}"),
            line: None,
            nominal_mm: Point3::new(100.0 + 40.0 * (i % 3) as f64, 50.0 + 40.0 * (i / 3) as f64, 10.0),
            diameter_mm: 10.0,
        })
        .collect()
}

#[test]
fn measured_holes_match_the_virtual_plate_within_the_latch_error() {
    let holes = holes();
    let nominal: Vec<(Point3, f64)> = holes.iter().map(|h| (h.nominal_mm, h.diameter_mm)).collect();
    for (seed, feed_mm_min) in [(1, 50.0), (2, 200.0)] {
        let (cfg, truth) = MachineToolConfig::with_holes(seed, &nominal, 1.5).unwrap();
        let (pretravel, sigma, period) = (cfg.pretravel_mm, cfg.position_sigma_mm, cfg.servo_period_s);
        let mut m = VirtualMachineTool::new(cfg).unwrap();
        let plan =
            InspectPlan { tip_radius_mm: 1.5, feed_mm_s: feed_mm_min / 60.0, ..InspectPlan::default() };
        let r = inspect(&mut m, &holes, &plan).unwrap();
        let step = plan.feed_mm_s * period;
        for (h, t) in r.holes.iter().zip(&truth) {
            let ce = ((h.measured_mm.x - t.top_mm.x).hypot(h.measured_mm.y - t.top_mm.y)) * 1e3;
            let de = (h.diameter_mm - t.diameter_mm) * 1e3;
            eprintln!("F{feed_mm_min} {}: centre error {ce:.3} µm, diameter error {de:.3} µm", h.hole.id);
            // Each latch lies 0 … one servo step past the trigger (outwards), plus σ = 0.1 µm of
            // position noise: the centre moves by at most about one step (+ 4σ).
            assert!(ce < (step + 4.0 * sigma) * 1e3, "centre error {ce} µm");
            // The diameter reads large by twice the pre-travel plus 0 … 2 steps (± 4σ).
            assert!(de > (2.0 * pretravel - 4.0 * sigma) * 1e3, "diameter error {de} µm");
            assert!(de < (2.0 * (pretravel + step) + 4.0 * sigma) * 1e3, "diameter error {de} µm");
            // The probing height, up to the axes' position noise (σ per latched point).
            assert!((h.measured_mm.z - (t.top_mm.z - plan.depth_mm)).abs() < 4.0 * sigma);
            // The reported error is measured minus nominal (the truth is 20 µm-ish off nominal).
            let nominal_err = (t.top_mm.x - h.hole.nominal_mm.x).hypot(t.top_mm.y - h.hole.nominal_mm.y);
            assert!((h.position_error_mm - nominal_err).abs() * 1e3 < (step + 4.0 * sigma) * 1e3);
        }
        assert_eq!(m.probings, holes.len() * plan.points);
        // Ends above the holes at the safe height.
        assert!((m.position().unwrap().z - plan.safe_z_mm(&holes)).abs() < 1e-9);
    }
}

#[test]
fn a_hole_off_by_more_than_the_clearance_fails_naming_it_with_the_machine_up() {
    let mut holes = holes();
    let nominal: Vec<(Point3, f64)> = holes.iter().map(|h| (h.nominal_mm, h.diameter_mm)).collect();
    let (cfg, _) = MachineToolConfig::with_holes(3, &nominal, 1.5).unwrap();
    let mut m = VirtualMachineTool::new(cfg).unwrap();
    // The list says hole H2 is 1.2 mm from where it is: more than the 0.5 mm clearance.
    holes[2].nominal_mm.x += 1.2;
    let plan = InspectPlan { tip_radius_mm: 1.5, ..InspectPlan::default() };
    match inspect(&mut m, &holes, &plan) {
        Err(InspectError::Device { hole, error }) => {
            assert_eq!(hole, "H2");
            assert!(
                matches!(error, DeviceError::NoContact { .. } | DeviceError::Controller { .. }),
                "{error}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!((m.position().unwrap().z - plan.safe_z_mm(&holes)).abs() < 1e-9);
}
