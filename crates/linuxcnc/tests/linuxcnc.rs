//! Integration tests against a real LinuxCNC 2.9 (simulated machine, virtual reference sphere on
//! the probe input: `tests/lcnc/`), started headless by `truepos_linuxcnc::harness`. Every test
//! starts its own LinuxCNC and stops it at the end (also on a panic); the harness's lock runs
//! them one after the other. Without LinuxCNC (or the unprivileged user it runs as) each test
//! prints `SKIPPED: …` on stderr and returns.

use std::net::TcpListener;
use std::time::{Duration, Instant};
use truepos_device::{DeviceError, ProbingMachine};
use truepos_head::acquire::{probe_sphere, AcquireError, SphereProbing};
use truepos_linuxcnc::harness::{PlateTruth, SimLinuxCnc, SphereTruth};
use truepos_linuxcnc::{Address, LinuxCnc, Options};
use truepos_math::Point3;

fn start() -> Option<SimLinuxCnc> {
    match SimLinuxCnc::start(SphereTruth::default()) {
        Ok(s) => Some(s),
        Err(why) => {
            eprintln!("SKIPPED: LinuxCNC integration test: {why}");
            None
        }
    }
}

fn plan(truth: &SphereTruth, feed_mm_min: f64, points: usize) -> SphereProbing {
    SphereProbing {
        // Nominal centre 0.2 mm off the truth, within the clearance.
        near_mm: truth.center_mm + truepos_math::Vector3::new(0.1, -0.1, 0.1),
        diameter_mm: 2.0 * truth.radius_mm,
        points,
        feed_mm_s: feed_mm_min / 60.0,
        clearance_mm: 0.5,
        tip_radius_mm: truth.tip_radius_mm,
    }
}

#[test]
fn probe_sphere_through_linuxcnc_matches_the_hal_sphere_at_two_feeds() {
    let Some(sim) = start() else { return };
    sim.arm().expect("arming the simulated machine");
    let truth = sim.sphere();
    // Fast positioning between the points (the simulated machine has no inertia to fear).
    let fast = Options { positioning_feed_mm_min: 12000.0, ..Options::default() };
    let mut m = LinuxCnc::open_address(&Address::parse(&sim.url()).unwrap(), fast).expect("open");
    assert!(m.version().starts_with("LinuxCNC 2.9"), "{}", m.version());
    for feed in [50.0, 200.0] {
        let t0 = Instant::now();
        let s = probe_sphere(&mut m, &plan(&truth, feed, 10)).expect("probe sphere");
        let secs = t0.elapsed().as_secs_f64();
        // The servo samples the probe input every 1 ms: the latched point is the first sample
        // inside the trip sphere, up to one servo step (feed × 1 ms) inside it. linuxcncrsh's
        // debug output has 6 decimals: allow 1 nm of rounding.
        let step = feed / 60.0 * 1e-3;
        let trip = truth.radius_mm + truth.tip_radius_mm;
        let radial: Vec<f64> = s.points.iter().map(|p| (p - truth.center_mm).norm() - trip).collect();
        let (lo, hi) = radial.iter().fold((f64::MAX, f64::MIN), |(a, b), &r| (a.min(r), b.max(r)));
        let ce = s.center_mm - truth.center_mm;
        let re = s.radius_mm - truth.radius_mm;
        eprintln!(
            "LinuxCNC probe sphere F{feed}: {} points in {secs:.1} s; centre error ({:.2}, {:.2}, {:.2}) µm |{:.2}| µm; \
             radius error {:.2} µm; per-point radial latch error {:.2} … {:.2} µm (servo step {:.2} µm); rms {:.2} µm",
            s.points.len(),
            ce.x * 1e3,
            ce.y * 1e3,
            ce.z * 1e3,
            ce.norm() * 1e3,
            re * 1e3,
            lo * 1e3,
            hi * 1e3,
            step * 1e3,
            s.rms_mm * 1e3
        );
        for r in &radial {
            assert!(*r <= 1e-6 && *r >= -step - 1e-6, "radial latch error {r} mm outside [-{step}, 0]");
        }
        // Fit: radius low by about step/2, centre within about one step (verified recipe:
        // 2 µm at 50 mm/min, 5 µm at 200 mm/min).
        let tol = if feed <= 50.0 { 0.002 } else { 0.005 };
        assert!(ce.norm() < tol, "centre error {ce}");
        assert!(re <= 1e-6 && re >= -step - 1e-6, "radius error {re}");
        assert!(re.abs() < tol);
    }
    // The machine ends above the sphere at the safe height.
    let p = m.position().unwrap();
    assert!(p.z >= plan(&truth, 50.0, 10).safe_z_mm() - 1e-6, "{p}");
}

/// The HAL plate's bores at their round nominal positions (the truth is µm to tens of µm off).
fn nominal_holes(plate: &PlateTruth) -> Vec<truepos_somac::inspect::Hole> {
    plate
        .bores
        .iter()
        .enumerate()
        .map(|(i, b)| truepos_somac::inspect::Hole {
            id: format!("B{i}"),
            line: None,
            nominal_mm: Point3::new(b.center_xy_mm[0].round(), b.center_xy_mm[1].round(), plate.z_mm[1]),
            diameter_mm: 10.0,
        })
        .collect()
}

#[test]
fn inspect_holes_through_linuxcnc_matches_the_hal_plate_at_two_feeds() {
    use truepos_somac::inspect::{inspect, InspectPlan};
    let Some(sim) = start() else { return };
    sim.arm().expect("arming the simulated machine");
    let (plate, tip) = (sim.plate(), sim.sphere().tip_radius_mm);
    let holes = nominal_holes(&plate);
    let fast = Options { positioning_feed_mm_min: 12000.0, ..Options::default() };
    let mut m = LinuxCnc::open_address(&Address::parse(&sim.url()).unwrap(), fast).expect("open");
    for feed in [50.0, 200.0] {
        let plan = InspectPlan { tip_radius_mm: tip, feed_mm_s: feed / 60.0, ..InspectPlan::default() };
        let r = inspect(&mut m, &holes, &plan).expect("inspect");
        let step = feed / 60.0 * 1e-3;
        for (h, b) in r.holes.iter().zip(&plate.bores) {
            let ce = (h.measured_mm.x - b.center_xy_mm[0]).hypot(h.measured_mm.y - b.center_xy_mm[1]);
            let de = h.diameter_mm - b.diameter_mm;
            eprintln!(
                "LinuxCNC inspect F{feed} {}: position error vs nominal {:.1} µm (truth {:.1} µm); measured vs HAL truth: centre {:.3} µm, diameter {:.3} µm; roundness {:.3} µm; {:.1} s",
                h.hole.id,
                h.position_error_mm * 1e3,
                (b.center_xy_mm[0] - h.hole.nominal_mm.x).hypot(b.center_xy_mm[1] - h.hole.nominal_mm.y) * 1e3,
                ce * 1e3,
                de * 1e3,
                h.roundness_mm * 1e3,
                h.elapsed_s
            );
            // Each latch is the first 1 ms servo sample outside the bore's free circle: 0 … one
            // step (feed × 1 ms) beyond it, radially. With 8 points at 45° the fitted centre moves
            // by at most 0.65 step; allow one step, plus 2 nm for the 6-decimal read-back.
            assert!(ce <= step + 2e-6, "centre error {ce} mm, step {step} mm");
            // The diameter reads large by 0 … 2 steps.
            assert!(de >= -2e-6 && de <= 2.0 * step + 2e-6, "diameter error {de} mm, step {step} mm");
            // All points at the probing depth exactly (no Z motion while probing).
            assert!((h.measured_mm.z - (plate.z_mm[1] - plan.depth_mm)).abs() < 2e-6);
        }
        eprintln!(
            "LinuxCNC inspect F{feed}: {} holes in {:.1} s ({:.1} s per hole, {} points each)",
            r.holes.len(),
            r.elapsed_s,
            r.elapsed_s / r.holes.len() as f64,
            plan.points
        );
    }
}

#[test]
fn inspect_on_linuxcnc_reports_a_hole_far_off_its_nominal_with_the_machine_up() {
    use truepos_somac::inspect::{inspect, InspectError, InspectPlan};
    let Some(sim) = start() else { return };
    sim.arm().unwrap();
    let (plate, tip) = (sim.plate(), sim.sphere().tip_radius_mm);
    let mut holes = nominal_holes(&plate);
    holes[1].nominal_mm.y += 1.0; // 1 mm off: beyond the 0.5 mm clearance
    let fast = Options { positioning_feed_mm_min: 12000.0, ..Options::default() };
    let mut m = LinuxCnc::open_address(&Address::parse(&sim.url()).unwrap(), fast).unwrap();
    let plan = InspectPlan { tip_radius_mm: tip, feed_mm_s: 200.0 / 60.0, ..InspectPlan::default() };
    match inspect(&mut m, &holes, &plan) {
        Err(InspectError::Device { hole, error }) => {
            let s = error.to_string();
            eprintln!("hole far off on LinuxCNC: hole {hole}: {s}");
            assert_eq!(hole, "B1");
            assert!(s.contains(&sim.url()), "{s}");
            assert!(matches!(error, DeviceError::NoContact { .. } | DeviceError::Controller { .. }), "{s}");
        }
        other => panic!("{other:?}"),
    }
    let at = m.position().unwrap();
    assert!((at.z - plan.safe_z_mm(&holes)).abs() < 1e-3, "{at}");
}

#[test]
fn unreachable_controllers_fail_within_ten_seconds_naming_the_address() {
    // Nothing listens: connection refused. Port 1 is privileged, so no test process (nor the
    // LinuxCNC that the other tests here start on a free ephemeral port) can be listening there;
    // a port taken from the ephemeral range and released again could be reused in between.
    let url = "linuxcncrsh://127.0.0.1:1".to_string();
    let t = Instant::now();
    let e = LinuxCnc::open(&url).err().expect("must fail");
    assert!(t.elapsed() < Duration::from_secs(10));
    assert!(matches!(e, DeviceError::Connect { .. }), "{e}");
    assert!(e.to_string().contains(&url), "{e}");
    // Something listens but never answers (a wrong port): a timeout, still within 10 s.
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("linuxcncrsh://127.0.0.1:{}", l.local_addr().unwrap().port());
    let t = Instant::now();
    let e = LinuxCnc::open(&url).err().expect("must fail");
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    assert!(matches!(e, DeviceError::Timeout { .. }), "{e}");
    assert!(e.to_string().contains(&url), "{e}");
}

#[test]
fn refuses_a_machine_in_estop_and_reports_a_probe_without_contact_with_the_machine_retracted() {
    let Some(sim) = start() else { return };
    // Not armed: in e-stop. truepos must say so and not release it.
    let e = LinuxCnc::open(&sim.url()).err().expect("must refuse");
    assert!(matches!(e, DeviceError::NotReady { .. }), "{e}");
    assert!(e.to_string().contains("e-stop") && e.to_string().contains(&sim.url()), "{e}");
    sim.arm().unwrap();
    let truth = sim.sphere();
    let mut m = LinuxCnc::open(&sim.url()).unwrap();
    // The sphere is 3 mm lower than its nominal (clearance 0.5): the pole probe misses.
    let mut p = plan(&truth, 200.0, 6);
    p.near_mm = truth.center_mm + truepos_math::Vector3::new(0.0, 0.0, 3.0);
    let t = Instant::now();
    match probe_sphere(&mut m, &p) {
        Err(AcquireError::Device(e @ DeviceError::NoContact { .. })) => {
            let s = e.to_string();
            eprintln!("no contact: {s} ({:.1} s)", t.elapsed().as_secs_f64());
            assert!(s.contains(&sim.url()) && s.contains("G38.2"), "{s}");
        }
        other => panic!("{other:?}"),
    }
    // Retracted: up at the safe height, outside the sphere.
    let at = m.position().unwrap();
    assert!((at.z - p.safe_z_mm()).abs() < 1e-3, "{at}");
    assert!((at - truth.center_mm).norm() > truth.radius_mm + truth.tip_radius_mm);
    // A positioning move through the sphere: LinuxCNC's own message.
    m.move_to(Point3::new(truth.center_mm.x, truth.center_mm.y, truth.center_mm.z + 20.0)).unwrap();
    let e = m.move_to(truth.center_mm).unwrap_err();
    assert!(matches!(e, DeviceError::Controller { .. }), "{e}");
    assert!(e.to_string().to_lowercase().contains("probe"), "{e}");
    eprintln!("collision: {e}");
}
