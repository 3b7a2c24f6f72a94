//! `calibrate` on the virtual xyzbc-trt machine of `truepos-cell` (its true geometry known):
//! identification within µm of the truth, the write-back, the verification, and the refusals.

use truepos_device::{DeviceError, KinematicsParameter, ProbingMachine};
use truepos_head::acquire::SphereProbing;
use truepos_kinematics::acquire::KinematicsProbing;
use truepos_kinematics::{calibrate, CalibrateRequest, KinematicsError, Model};
use truepos_math::Point3;
use truepos_plant::probing::{MachineToolConfig, VirtualMachineTool};

fn request(orientations: Vec<[f64; 2]>, apply: bool, verify: Option<Vec<[f64; 2]>>) -> CalibrateRequest {
    CalibrateRequest {
        model: Model::XyzbcTrt,
        probing: KinematicsProbing {
            sphere: SphereProbing {
                near_mm: Point3::new(60.0, 25.0, 15.0),
                diameter_mm: 25.0,
                points: 9,
                feed_mm_s: 50.0 / 60.0,
                clearance_mm: 1.0,
                tip_radius_mm: 1.5,
            },
            orientations,
            turn_distance_mm: 60.0,
        },
        apply,
        verify,
        output: None,
    }
}

const SET: [[f64; 2]; 6] =
    [[0.0, 0.0], [0.0, 120.0], [0.0, 240.0], [45.0, 0.0], [90.0, 120.0], [90.0, 240.0]];

#[test]
fn identifies_applies_and_verifies_on_the_virtual_machine() {
    for seed in [1, 2, 3] {
        let (mut m, truth) =
            VirtualMachineTool::five_axis(seed, Point3::new(60.0, 25.0, 15.0), 12.5, 1.5).unwrap();
        let verify = vec![[0.0, 60.0], [30.0, 180.0], [60.0, 300.0], [90.0, 30.0]];
        let r = calibrate(&mut m, &request(SET.to_vec(), true, Some(verify)), |_| {}).unwrap();
        assert_eq!(r.configured, truth.configured);
        let (id, tr) = (r.identified.axes(), truth.truth.axes());
        let err: Vec<f64> = (0..4).map(|k| (id[k] - tr[k]) * 1e3).collect();
        let before = r.spread_before_mm * 1e3;
        let after = r.verification.as_ref().unwrap().spread_mm * 1e3;
        eprintln!("virtual seed {seed}: axes error {err:.2?} µm; spread {before:.1} → {after:.2} µm");
        // The virtual probe: 0.1 µm position noise, latch within one servo step (0.83 µm).
        for (k, e) in err.iter().enumerate() {
            assert!(e.abs() < 2.0, "axis {k}: {e} µm");
            // Within k = 3 of the stated uncertainty (or 0.5 µm: the latch is not random noise).
            let u = r.parameters.iter().map(|p| p.uncertainty_mm).fold(0.0, f64::max) * 1e3;
            assert!(e.abs() < (3.0 * u).max(0.5), "axis {k}: {e} µm vs u {u} µm");
        }
        assert!(before > 20.0, "{before}");
        assert!(after < 2.0, "{after}");
        assert!(r.applied);
        // The controller now holds the identified values; the machine is back at B = C = 0.
        let now = m.kinematics_parameters().unwrap();
        assert_eq!(truepos_kinematics::trt::TrtGeometry::from_parameters(&now).unwrap(), r.identified);
        assert_eq!(m.orientation().unwrap(), (0.0, 0.0));
        // The text and JSON carry the contract's fields.
        let j = truepos_io::report::Report::to_json(&r);
        for k in [
            "model",
            "parameters",
            "centres_mm",
            "spread_before_mm",
            "spread_after_predicted_mm",
            "applied",
            "coverage_factor",
        ] {
            assert!(j.get(k).is_some(), "{k}");
        }
        assert_eq!(j["parameters"].as_array().unwrap().len(), 4);
    }
}

#[test]
fn a_dry_run_writes_nothing() {
    let (mut m, truth) = VirtualMachineTool::five_axis(4, Point3::new(60.0, 25.0, 15.0), 12.5, 1.5).unwrap();
    let r = calibrate(&mut m, &request(SET[..4].to_vec(), false, None), |_| {}).unwrap();
    assert!(!r.applied);
    let now = m.kinematics_parameters().unwrap();
    assert_eq!(truepos_kinematics::trt::TrtGeometry::from_parameters(&now).unwrap(), truth.configured);
}

#[test]
fn refusals_come_before_any_motion() {
    // Orientations that cannot determine the B axis.
    let (mut m, _) = VirtualMachineTool::five_axis(1, Point3::new(60.0, 25.0, 15.0), 12.5, 1.5).unwrap();
    let p0 = m.position().unwrap();
    let e = calibrate(&mut m, &request(vec![[0.0, 0.0], [0.0, 90.0], [0.0, 180.0]], false, None), |_| {})
        .unwrap_err();
    assert!(matches!(e, KinematicsError::NotDetermined(_)) && e.is_user_input(), "{e}");
    assert!(e.to_string().contains("x-offset, z-offset"), "{e}");
    assert_eq!(m.position().unwrap(), p0);
    // A 3-axis machine.
    let mut three = VirtualMachineTool::new(MachineToolConfig::default()).unwrap();
    let e = calibrate(&mut three, &request(SET.to_vec(), false, None), |_| {}).unwrap_err();
    assert!(matches!(e, KinematicsError::Device(DeviceError::Rejected { .. })) && !e.is_user_input(), "{e}");
    // maxkins and unknown models.
    let e = Model::parse("maxkins").unwrap_err();
    assert!(e.is_user_input() && e.to_string().contains("forward and inverse"), "{e}");
    assert!(Model::parse("xyzac-trt").is_err());
    // Verify without apply.
    let e = request(SET.to_vec(), false, Some(vec![[0.0, 0.0], [30.0, 30.0]])).check().unwrap_err();
    assert!(e.to_string().contains("--apply"), "{e}");
    // The geometry is written only at B = C = 0.
    m.move_to(Point3::new(60.0, 25.0, 80.0)).unwrap();
    m.orient(30.0, 0.0).unwrap();
    let e = m
        .set_kinematics_parameters(&[KinematicsParameter { name: "x-rot-point".into(), value_mm: 10.01 }])
        .unwrap_err();
    assert!(e.to_string().contains("B = C = 0"), "{e}");
}
