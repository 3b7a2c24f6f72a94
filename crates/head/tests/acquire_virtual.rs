//! Sphere acquisition (`truepos_head::acquire`) on the virtual machine tool, against its truth.

use truepos_cell::probing::{MachineToolConfig, VirtualMachineTool};
use truepos_device::{DeviceError, ProbingMachine};
use truepos_head::acquire::{probe_sphere, AcquireError, SphereProbing};
use truepos_math::Point3;

fn plan(feed_mm_min: f64) -> SphereProbing {
    SphereProbing {
        // The nominal centre is 0.3 mm off the true one: inside the clearance.
        near_mm: Point3::new(120.2, 44.9, 30.15),
        diameter_mm: 25.0,
        points: 25,
        feed_mm_s: feed_mm_min / 60.0,
        clearance_mm: 2.0,
        tip_radius_mm: 1.5,
    }
}

#[test]
fn finds_the_true_sphere_within_the_servo_latch_error() {
    for (seed, feed) in [(1u64, 50.0), (2, 200.0)] {
        let cfg = MachineToolConfig { seed, ..MachineToolConfig::default() };
        let (c_true, r_true) = cfg.spheres[0];
        let mut m = VirtualMachineTool::new(cfg.clone()).unwrap();
        let s = probe_sphere(&mut m, &plan(feed)).unwrap();
        assert_eq!(s.points.len(), 25);
        assert_eq!(m.probings, 25);
        // Each point latches pre-travel + U(0,1)·step past the contact (step = feed × 1 ms),
        // plus 0.1 µm noise per axis. Over the points the radius therefore reads low by
        // pre-travel + step/2 on average (the spread of U over 25 points moves the mean by
        // ~step/√(12·25) ≈ 0.06 step), and the centre moves by a fraction of a step: allow
        // 0.3 step + 0.3 µm on the radius around that mean and one step + 0.3 µm on the centre.
        let step = feed / 60.0 * cfg.servo_period_s;
        let expected_r = r_true - cfg.pretravel_mm - 0.5 * step;
        assert!(
            (s.radius_mm - expected_r).abs() < 0.3 * step + 3e-4,
            "feed {feed}: radius {} expected {expected_r}",
            s.radius_mm
        );
        let ce = (s.center_mm - c_true).norm();
        assert!(ce < step + 3e-4, "feed {feed}: centre error {ce}");
        assert!(s.rms_mm < step, "rms {}", s.rms_mm);
        // Left at the safe height.
        let p = m.position().unwrap();
        assert!((p.z - plan(feed).safe_z_mm()).abs() < 1e-9, "{p}");
        assert_eq!(s.device.address, "virtual");
    }
}

#[test]
fn a_nominal_centre_off_by_more_than_the_clearance_misses_and_leaves_the_machine_clear() {
    let mut m = VirtualMachineTool::new(MachineToolConfig::default()).unwrap();
    let mut p = plan(200.0);
    p.near_mm.z -= 5.0; // the sphere is 5 mm higher than said: the descent trips the probe
    match probe_sphere(&mut m, &p) {
        Err(AcquireError::Device(DeviceError::Controller { message, .. })) => {
            assert!(message.contains("probe tripped"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    let mut m = VirtualMachineTool::new(MachineToolConfig::default()).unwrap();
    let mut p = plan(200.0);
    p.near_mm.z += 5.0; // 5 mm lower than said: the first probe finds nothing
    match probe_sphere(&mut m, &p) {
        Err(AcquireError::Device(DeviceError::NoContact { what, .. })) => {
            assert!(what.contains("probing move"), "{what}")
        }
        other => panic!("{other:?}"),
    }
    // Raised back to the safe height above the failed point, clear of the sphere.
    let at = m.position().unwrap();
    assert!((at.z - p.safe_z_mm()).abs() < 1e-9);
    let c = MachineToolConfig::default().spheres[0].0;
    assert!((at - c).norm() > 14.0);
}
