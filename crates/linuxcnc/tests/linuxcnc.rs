//! Integration tests against a real LinuxCNC 2.9 (simulated machine, virtual reference sphere on
//! the probe input: `tests/lcnc/`), started headless by `truepos_linuxcnc::harness`. Every test
//! starts its own LinuxCNC and stops it at the end (also on a panic); the harness's lock runs
//! them one after the other. Without LinuxCNC (or the unprivileged user it runs as) each test
//! prints `SKIPPED: …` on stderr and returns.

use std::net::TcpListener;
use std::time::{Duration, Instant};
use truepos_device::{DeviceError, ProbingMachine};
use truepos_head::acquire::{probe_sphere, AcquireError, SphereProbing};
use truepos_linuxcnc::harness::{SimLinuxCnc, SphereTruth};
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
