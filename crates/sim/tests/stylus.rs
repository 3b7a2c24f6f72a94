//! Stylus dynamics against analytic solutions: free ringing after a step release (frequency and
//! damping per axis), bounce and exact settling on impact, Coulomb drag while sliding, and the
//! inertial deflection under body acceleration.

use std::f64::consts::PI;

use truepos_math::{Point3, Vector3};
use truepos_sim::artefact::Plane;
use truepos_sim::motion::{Limits, Motion, State, Trajectory};
use truepos_sim::stylus::{simulate, Stylus, StylusParams};

fn params() -> StylusParams {
    StylusParams {
        tip_radius_mm: 1.0,
        natural_freq_hz: [90.0, 130.0, 200.0],
        damping_ratio: [0.02, 0.05, 0.1],
        restitution: 0.5,
        friction: 0.2,
        dynamic: true,
    }
}

/// Zero crossings (linearly interpolated) of a sampled signal, rising ones only.
fn rising_crossings(x: &[f64], dt: f64) -> Vec<f64> {
    (1..x.len())
        .filter(|&k| x[k - 1] < 0.0 && x[k] >= 0.0)
        .map(|k| (k - 1) as f64 * dt + dt * x[k - 1] / (x[k - 1] - x[k]))
        .collect()
}

/// Positive peak values, refined by a parabola through the three samples around each maximum.
fn peaks(x: &[f64]) -> Vec<f64> {
    (1..x.len() - 1)
        .filter(|&k| x[k] > 0.0 && x[k] >= x[k - 1] && x[k] > x[k + 1])
        .map(|k| {
            let (a, b, c) = (x[k - 1], x[k], x[k + 1]);
            let den = a - 2.0 * b + c;
            if den == 0.0 {
                b
            } else {
                b - 0.25 * (a - c) * (a - c) / den
            }
        })
        .collect()
}

#[test]
fn a_step_release_rings_at_the_natural_frequency_and_decays_at_the_damping_ratio() {
    let p = params();
    let dt = 1e-5;
    let body = State::rest(Point3::origin());
    for axis in 0..3 {
        let mut n = Vector3::zeros();
        n[axis] = 1.0;
        // Tip pressed 0.2 mm by a surface with outward normal +axis (deflection along +n).
        let pressing = Plane::new(Point3::from(n * (0.2 - p.tip_radius_mm)), n).unwrap();
        let gone = Plane::new(Point3::from(n * -1000.0), n).unwrap();
        let mut st = Stylus::new(p, dt).unwrap();
        st.set_state(n * 0.2, Vector3::zeros(), true);
        for _ in 0..100 {
            st.step(&body, &body, &pressing);
        }
        assert!((st.deflection() - n * 0.2).norm() < 1e-15, "held: {}", st.deflection());
        // The step: the surface disappears; the stylus rings freely.
        let mut x = Vec::new();
        for _ in 0..60_000 {
            st.step(&body, &body, &gone);
            let d = st.deflection();
            // Axes are decoupled without contact: the other two stay exactly at rest.
            assert!((d - n * d[axis]).norm() == 0.0);
            x.push(d[axis]);
        }
        let w = 2.0 * PI * p.natural_freq_hz[axis];
        let z = p.damping_ratio[axis];
        // Frequency: mean period between the first and last rising zero crossing. The
        // integration is exact (matrix exponential), and linear interpolation of a crossing
        // errs by O(ζω·dt²) in time — a relative error < 1e-6 in the mean period over ≥ 10
        // periods. Tolerance 1e-4.
        let zc = rising_crossings(&x, dt);
        assert!(zc.len() > 10, "axis {axis}: {} crossings", zc.len());
        let period = (zc[zc.len() - 1] - zc[0]) / (zc.len() - 1) as f64;
        let wd = w * (1.0 - z * z).sqrt();
        assert!((2.0 * PI / period / wd - 1.0).abs() < 1e-4, "axis {axis}: {} vs {wd}", 2.0 * PI / period);
        // Damping: logarithmic decrement over N periods, δ = ln(x₀/x_N)/N, ζ = δ/√(4π² + δ²)
        // (exact for a linear oscillator: successive peaks are a damped period apart and
        // their ratio is exp(ζω·T_d)). Parabolic peak refinement errs by O((ω·dt)⁴) relative
        // ≈ 3e-7; peaks are taken while above 1 % of the start. Tolerance 0.1 %.
        let pk: Vec<f64> = peaks(&x).into_iter().take_while(|v| *v > 0.002).collect();
        let nper = pk.len() - 1;
        assert!(nper >= 5, "axis {axis}: {nper}");
        let delta = (pk[0] / pk[nper]).ln() / nper as f64;
        let zeta = delta / (4.0 * PI * PI + delta * delta).sqrt();
        assert!((zeta / z - 1.0).abs() < 1e-3, "axis {axis}: ζ {zeta} vs {z}");
    }
}

#[test]
fn an_impact_bounces_then_settles_exactly_on_the_surface() {
    let p = params();
    // Body moves down at 20 mm/s towards a plane z = 0 (tip radius 1) and stops with 0.15 mm
    // of interference (body at z = 0.85).
    let mut tr = Trajectory::new(0.0, Point3::new(0.0, 0.0, 3.0));
    tr.line_to(Point3::new(0.0, 0.0, 0.85), &Limits::accel(20.0, 5000.0)).unwrap();
    tr.dwell(0.5).unwrap();
    let plane = Plane::new(Point3::origin(), Vector3::z()).unwrap();
    let dt = 1e-4;
    let n = (tr.end_s() / dt) as usize;
    let out = simulate(&p, &tr, &plane, 0.0, dt, n, 4).unwrap();
    // Bounces: contact begins, is lost (restitution 0.5), and is regained at least once.
    let first = out.iter().position(|s| s.1).unwrap();
    let lost = out[first..].iter().position(|s| !s.1).map(|k| k + first).expect("no bounce");
    assert!(out[lost..].iter().any(|s| s.1), "never came back");
    // While in contact, the tip is exactly on the surface: centre z = tip radius.
    for (k, (d, c)) in out.iter().enumerate() {
        if *c {
            let body = tr.state(k as f64 * dt).p;
            assert!(((body + d).z - 1.0).abs() < 1e-12);
        }
    }
    // Settled (last 0.1 s): deflection = interference along +n, exactly.
    for (d, c) in &out[n - 1000..] {
        assert!(*c && (d - Vector3::new(0.0, 0.0, 0.15)).norm() < 1e-12, "{d}");
    }
}

#[test]
fn sliding_drags_the_tip_back_by_the_coulomb_friction() {
    let p = params();
    let plane = Plane::new(Point3::new(0.0, 0.0, -0.8), Vector3::z()).unwrap();
    // Body pressed 0.2 mm into the plane, sliding at 5 mm/s along +X.
    let mut tr = Trajectory::new(0.0, Point3::origin());
    tr.cruise_to(Point3::new(5.0, 0.0, 0.0), 5.0).unwrap();
    let dt = 1e-6;
    let mut st = Stylus::new(p, dt).unwrap();
    st.set_state(Vector3::new(0.0, 0.0, 0.2), Vector3::zeros(), true);
    let mut prev = tr.state(0.0);
    for k in 1..=600_000 {
        let next = tr.state(k as f64 * dt);
        st.step(&prev, &next, &plane);
        prev = next;
    }
    // Steady sliding: the tip moves with the body (no damping force), so the lateral spring
    // force balances friction: ω_x²·d_x = −μ·ω_z²·d_z. The time stepping resolves the friction
    // impulse per step, exact to O(ω·dt) = 1e-3 relative; after 0.6 s (≈ 34 damping times of
    // the X axis) the transient is gone. Tolerance 0.5 %.
    let (wx, wz) = (p.natural_freq_hz[0], p.natural_freq_hz[2]);
    let expect = -p.friction * (wz / wx).powi(2) * 0.2;
    let d = st.deflection();
    assert!((d.x / expect - 1.0).abs() < 5e-3, "{} vs {expect}", d.x);
    assert!((d.z - 0.2).abs() < 1e-12 && d.y.abs() < 1e-15);
}

#[test]
fn body_acceleration_deflects_a_free_stylus_by_a_over_omega_squared() {
    let p = params();
    // Constant body acceleration (the free stylus lags): steady d = −a/ω² per axis.
    let a = Vector3::new(1000.0, -2000.0, 500.0);
    let far = Plane::new(Point3::new(0.0, 0.0, -1e6), Vector3::z()).unwrap();
    let dt = 1e-5;
    let mut st = Stylus::new(p, dt).unwrap();
    let state = |t: f64| State { p: Point3::from(a * (0.5 * t * t)), v: a * t, a };
    let mut prev = state(0.0);
    for k in 1..=300_000 {
        let next = state(k as f64 * dt);
        st.step(&prev, &next, &far);
        prev = next;
    }
    // After 3 s even the least damped axis (ζω = 11.3 /s) has decayed by e^-34: exact to
    // round-off; tolerance 1e-9 relative.
    for i in 0..3 {
        let w = 2.0 * PI * p.natural_freq_hz[i];
        let expect = -a[i] / (w * w);
        assert!((st.deflection()[i] / expect - 1.0).abs() < 1e-9, "axis {i}");
    }
}
