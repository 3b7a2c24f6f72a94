//! The latency scenario against its own truth, through the interface contract: the stylus
//! centre at probe stamp `t` is `machine_position(t + delay_s) + deflection(t)`, the machine
//! position interpolated linearly in its own stream.

use truepos_math::{Point3, Vector3};
use truepos_sim::scenario::latency::{simulate, ArtefactTruth, Config, Dataset, Variant};

/// Machine position at `t` per the contract, axis `i` delayed by `delays[i]`: linear
/// interpolation in the machine stream.
fn machine_at(ds: &Dataset, t: f64, delays: [f64; 3]) -> Point3 {
    let m = &ds.machine;
    let mut p = Point3::origin();
    for i in 0..3 {
        let tq = t + delays[i];
        let k = m.partition_point(|s| s.0 <= tq).clamp(1, m.len() - 1);
        let (t0, p0) = m[k - 1];
        let (t1, p1) = m[k];
        let f = (tq - t0) / (t1 - t0);
        p[i] = p0[i] + f * (p1[i] - p0[i]);
    }
    p
}

/// Stylus-centre points of the truly-in-contact probe samples.
fn centres(ds: &Dataset, delays: [f64; 3]) -> Vec<(usize, Point3)> {
    let (t_lo, t_hi) = (ds.machine[0].0 + 0.01, ds.machine.last().unwrap().0 - 0.01);
    ds.probe
        .iter()
        .enumerate()
        .filter(|(i, (t, _))| ds.probe_in_contact[*i] && *t > t_lo && *t < t_hi)
        .map(|(i, (t, d))| (i, machine_at(ds, *t, delays) + d))
        .collect()
}

/// Signed distance of a stylus-centre point from the stylus-centre surface of the artefact.
fn residual(ds: &Dataset, c: &Point3) -> f64 {
    let r = ds.truth.tip_radius_mm;
    match ds.truth.artefact {
        ArtefactTruth::Sphere { centre_mm, diameter_mm } => {
            (c - Point3::from(centre_mm)).norm() - (0.5 * diameter_mm + r)
        }
        ArtefactTruth::Plates { mid_mm, axis, gap_mm } => {
            let s = (c - Point3::from(mid_mm)).dot(&Vector3::from(axis));
            (0.5 * gap_mm - r) - s.abs()
        }
    }
}

fn rms_max(ds: &Dataset, delays: [f64; 3]) -> (f64, f64, usize) {
    let pts = centres(ds, delays);
    let res: Vec<f64> = pts.iter().map(|(_, c)| residual(ds, c)).collect();
    let rms = (res.iter().map(|r| r * r).sum::<f64>() / res.len() as f64).sqrt();
    let max = res.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    (rms, max, res.len())
}

fn true_delays(ds: &Dataset) -> [f64; 3] {
    ds.truth.per_axis_delay_s
}

#[test]
fn noise_free_runs_reproduce_the_exact_geometry_in_every_variant() {
    for v in Variant::ALL {
        let mut cfg = Config::preset(v);
        cfg.encoder_noise_mm = 0.0;
        cfg.probe_noise_mm = 0.0;
        // 10 kHz machine stream: linear interpolation of the body position is then wrong by at
        // most a·Δt²/8 = 2000 mm/s² · (1e-4 s)² / 8 = 2.5 nm in the contact moves (servo
        // overshoot adds a few %). The resting tip is projected exactly onto the surface.
        // Tolerance 20 nm.
        cfg.machine_rate_hz = 10_000.0;
        let ds = simulate(&cfg).unwrap();
        let (rms, max, n) = rms_max(&ds, true_delays(&ds));
        assert!(n > 50, "{v:?}: only {n} contact samples");
        assert!(max < 2e-5, "{v:?}: max {max} rms {rms}");
        // Normal approaches: the tip does not slide, so every contact sample's centre is the
        // touching centre itself (deflection = touching centre − body, linear in the body
        // position: extrapolating to zero deflection gives the contact point).
        if matches!(
            v,
            Variant::Sphere | Variant::Plates | Variant::Speeds | Variant::InOut | Variant::MultiRate
        ) {
            for (i, c) in centres(&ds, true_delays(&ds)) {
                let t = ds.probe[i].0;
                let ct = ds
                    .truth
                    .contacts
                    .iter()
                    .find(|k| {
                        t - ds.truth.probe_latency_s >= k.t_start_s
                            && t - ds.truth.probe_latency_s <= k.t_end_s
                    })
                    .expect("contact sample outside every contact window");
                assert!((c - Point3::from(ct.touching_centre_mm)).norm() < 2e-5, "{v:?} {}", ct.label);
            }
        }
    }
}

#[test]
fn true_delay_gives_the_artefact_to_noise_level_and_wrong_delays_do_not() {
    for v in [
        Variant::Sphere,
        Variant::Plates,
        Variant::Speeds,
        Variant::MultiRate,
        Variant::Oblique,
        Variant::Scan,
    ] {
        // Three repeats of the contact pattern, for enough samples to state noise statistics.
        let cfg = Config { repeats: 3, ..Config::preset(v) };
        let ds = simulate(&cfg).unwrap();
        let d = true_delays(&ds);
        let (rms, max, n) = rms_max(&ds, d);
        // Radial noise: encoder 1 µm per axis (interpolated between two samples: 0.71–1 µm)
        // and probe 0.3 µm: σ ≤ 1.05 µm. RMS within 1.2 µm (n > 300 samples: the sample RMS
        // has a relative standard error < 4.1 %, so 1.2 µm is > 3.5 standard errors above σ), and above 0.6 µm (the noise is really there).
        // Max below 6 µm (5.7σ: for n ≈ 10⁴ Gaussian samples the max is ≈ 4σ).
        assert!(n > 300, "{v:?}: {n}");
        assert!(rms < 1.2e-3 && rms > 0.6e-3, "{v:?}: rms {rms}");
        assert!(max < 6e-3, "{v:?}: max {max}");
        if v == Variant::Scan {
            // On the circle a time shift only slides points along it (radial error (vε)²/2ρ,
            // nanometres); the information is in the switches between the two radii, where
            // the body's radial speed peaks at (δ₂ − δ₁)·π/(2w)·v/ρ = 0.2·π/(2·0.070)·10/14.8
            // ≈ 3 mm/s. 5 ms off: ≈ 15 µm at the switches, far above the 6 µm noise maximum.
            for err in [-0.005, 0.005] {
                let (_, max_w, _) = rms_max(&ds, [d[0] + err, d[1] + err, d[2] + err]);
                assert!(max_w > 9e-3, "scan {err}: max {max_w}");
            }
            continue;
        }
        // 1 ms off: the contact speed (≥ 5 mm/s) makes every moving sample 5–10 µm wrong;
        // the RMS over all contact samples (including dwells) more than triples.
        for err in [-0.001, 0.001] {
            let wrong = [d[0] + err, d[1] + err, d[2] + err];
            let (rms_w, _, _) = rms_max(&ds, wrong);
            assert!(rms_w > 3.0 * rms, "{v:?} {err}: {rms_w} vs {rms}");
        }
        // Ignoring the delay altogether (2.5 ms off) is worse still.
        let (rms0, _, _) = rms_max(&ds, [0.0; 3]);
        assert!(rms0 > 5.0 * rms, "{v:?}: {rms0}");
    }
}

#[test]
fn per_axis_delays_need_per_axis_combination() {
    let cfg = Config::preset(Variant::PerAxis);
    let ds = simulate(&cfg).unwrap();
    let d = ds.truth.per_axis_delay_s;
    assert_eq!(d, [0.004 - 0.0015, 0.0025 - 0.0015, 0.001 - 0.0015]);
    let (rms, _, _) = rms_max(&ds, d);
    assert!(rms < 1.2e-3, "{rms}"); // noise level, as above
                                    // One common delay (the mean) is 1–1.5 ms wrong on X and Z: at 10 mm/s ≥ 10 µm on those
                                    // contacts.
    let m = ds.truth.delay_s;
    let (rms_m, _, _) = rms_max(&ds, [m; 3]);
    assert!(rms_m > 3.0 * rms, "{rms_m} vs {rms}");
}

#[test]
fn streams_have_their_rates_and_the_truth_is_complete() {
    let ds = simulate(&Config::preset(Variant::MultiRate)).unwrap();
    let dt_m = ds.machine[1].0 - ds.machine[0].0;
    let dt_p = ds.probe[1].0 - ds.probe[0].0;
    assert!((dt_m - 1e-3).abs() < 1e-12 && (dt_p - 2.5e-4).abs() < 1e-12);
    assert!((ds.probe.len() as f64 / ds.machine.len() as f64 - 4.0).abs() < 0.01);
    let t = &ds.truth;
    assert_eq!(t.contacts.len(), 5);
    assert_eq!(t.static_size_mm, 25.0);
    assert_eq!(t.stylus_centre_size_mm, 29.0);
    let sp = simulate(&Config::preset(Variant::Speeds)).unwrap();
    assert_eq!(sp.truth.speeds_mm_s, vec![5.0, 10.0, 20.0, 30.0, 40.0]);
    assert_eq!(sp.truth.contacts.len(), 25);
    // Each contact reaches the configured maximum deflection (0.3 mm) within the servo
    // overshoot and stylus dynamics (±5 %), and the contact speed is really reached: the
    // largest body speed in the window is the contact speed within 1 %.
    for c in &sp.truth.contacts {
        let peak = sp
            .probe
            .iter()
            .filter(|(t, _)| *t >= c.t_start_s && *t <= c.t_end_s)
            .map(|(_, d)| d.norm())
            .fold(0.0, f64::max);
        assert!((peak - 0.3).abs() < 0.015, "{} at {}: {peak}", c.label, c.speed_mm_s);
    }
}

/// Vertex of the parabola through three equally spaced samples around index `k` (as a
/// fractional index offset from `k`).
fn parabolic_offset(y0: f64, y1: f64, y2: f64) -> f64 {
    let den = y0 - 2.0 * y1 + y2;
    if den == 0.0 {
        0.0
    } else {
        0.5 * (y0 - y2) / den
    }
}

#[test]
fn in_and_out_extrema_are_one_delay_apart_and_negative_delays_work() {
    for (lm, lp) in [(0.004, 0.0015), (0.0005, 0.004)] {
        let cfg = Config {
            machine_latency_s: lm,
            probe_latency_s: lp,
            encoder_noise_mm: 0.0,
            probe_noise_mm: 0.0,
            ..Config::preset(Variant::InOut)
        };
        let ds = simulate(&cfg).unwrap();
        // The +X point: deepest body position = smallest x; largest deflection along +X.
        let ct = &ds.truth.contacts[0];
        let inside = |t: f64, lat: f64| t - lat > ct.t_start_s && t - lat < ct.t_end_s;
        let km = (1..ds.machine.len() - 1)
            .filter(|&k| inside(ds.machine[k].0, lm))
            .min_by(|&a, &b| ds.machine[a].1.x.total_cmp(&ds.machine[b].1.x))
            .unwrap();
        let kp = (1..ds.probe.len() - 1)
            .filter(|&k| inside(ds.probe[k].0, lp))
            .max_by(|&a, &b| ds.probe[a].1.x.total_cmp(&ds.probe[b].1.x))
            .unwrap();
        let dm = 1.0 / cfg.machine_rate_hz;
        let dp = 1.0 / cfg.probe_rate_hz;
        let tm = ds.machine[km].0
            + dm * parabolic_offset(ds.machine[km - 1].1.x, ds.machine[km].1.x, ds.machine[km + 1].1.x);
        let tp = ds.probe[kp].0
            + dp * parabolic_offset(ds.probe[kp - 1].1.x, ds.probe[kp].1.x, ds.probe[kp + 1].1.x);
        // While the tip rests on the surface, deflection = touching centre − body exactly, so
        // both extrema happen at the same true time and are stamped one delay apart. Around
        // the turn the body moves on a parabola (constant deceleration) and the parabolic
        // vertex is exact; the servo's following-error transient adds a small cubic term.
        // Tolerance 50 µs (5 % of a sample period).
        let delay = lm - lp;
        assert!((tm - tp - delay).abs() < 5e-5, "{}: {} vs {delay}", lm, tm - tp);
        // And the contract combination works for either sign.
        let noisy =
            simulate(&Config { encoder_noise_mm: 0.001, probe_noise_mm: 0.0003, repeats: 5, ..cfg }).unwrap();
        let (rms, _, _) = rms_max(&noisy, true_delays(&noisy));
        let (rms0, _, _) = rms_max(&noisy, [0.0; 3]);
        // Noise level as in the test above; 2.5 / 3.5 ms ignored at 10 mm/s: ≥ 25 µm.
        assert!(rms < 1.2e-3 && rms0 > 5.0 * rms, "{rms} {rms0}");
    }
}

#[test]
fn away_from_contacts_the_stylus_barely_deflects() {
    // Free-air moves accelerate at 1000 mm/s² (transfers jerk-limited to 10 000 mm/s³, a ramp
    // of 0.1 s ≫ the 7 ms stylus period, so quasi-static): inertial deflection a/ω² =
    // 1000/(2π·150)² = 1.1 µm on X/Y, 0.6 µm on Z. Outside the contact windows (and 0.1 s after
    // them, when the release ringing has decayed by e^(−ζω·0.1) = 1e-4) it must stay below
    // 2 µm: far below the contract's default contact threshold of 5 µm.
    for v in [Variant::Sphere, Variant::Speeds, Variant::Plates, Variant::Scan] {
        let ds =
            simulate(&Config { encoder_noise_mm: 0.0, probe_noise_mm: 0.0, ..Config::preset(v) }).unwrap();
        let lp = ds.truth.probe_latency_s;
        let mut worst = 0.0f64;
        for (t, d) in &ds.probe {
            let tt = t - lp;
            if ds.truth.contacts.iter().all(|c| tt < c.t_start_s || tt > c.t_end_s + 0.1) {
                worst = worst.max(d.norm());
            }
        }
        assert!(worst < 2e-3 && worst > 1e-4, "{v:?}: {worst}");
    }
}

/// Least-squares time shift ε that best puts the contact samples on the known stylus-centre
/// surface, linearised: r(ε) ≈ r(0) + g·ε with g = ∂r/∂ε (central difference over ±0.1 ms; r
/// is linear in ε up to the body's acceleration, a·ε²/2 = 1e-5 µm). ε̂ = −Σgr/Σg², standard
/// error σ_r/√Σg² with σ_r the post-fit residual RMS. Returns (ε̂, standard error, n).
fn ls_delay_error(ds: &Dataset) -> (f64, f64, usize) {
    let d = true_delays(ds);
    let h = 1e-4;
    let shift = |e: f64| [d[0] + e, d[1] + e, d[2] + e];
    let r0: Vec<f64> = centres(ds, d).iter().map(|(_, c)| residual(ds, c)).collect();
    let rp: Vec<f64> = centres(ds, shift(h)).iter().map(|(_, c)| residual(ds, c)).collect();
    let rm: Vec<f64> = centres(ds, shift(-h)).iter().map(|(_, c)| residual(ds, c)).collect();
    let g: Vec<f64> = rp.iter().zip(&rm).map(|(p, m)| (p - m) / (2.0 * h)).collect();
    let sgg: f64 = g.iter().map(|x| x * x).sum();
    let sgr: f64 = g.iter().zip(&r0).map(|(a, b)| a * b).sum();
    let eps = -sgr / sgg;
    let n = r0.len() as f64;
    let s2 = r0.iter().zip(&g).map(|(r, gg)| (r + gg * eps).powi(2)).sum::<f64>() / (n - 1.0);
    (eps, (s2 / sgg).sqrt(), r0.len())
}

#[test]
fn the_data_determine_the_true_delay_without_bias() {
    for (v, seed, repeats) in [(Variant::Plates, 3, 24), (Variant::Speeds, 5, 8), (Variant::Sphere, 1, 12)] {
        // Noise-free: the only error left is the linear interpolation of the 1 kHz machine
        // stream where the body accelerates (≤ a·Δt²/8 = 0.25 µm at 2000 mm/s², on a small
        // fraction of the samples), worth well under 0.5 µs of delay. (Measured: ≤ 0.09 µs.)
        let clean = Config { seed, repeats, encoder_noise_mm: 0.0, probe_noise_mm: 0.0, ..Config::preset(v) };
        let (eps, _, _) = ls_delay_error(&simulate(&clean).unwrap());
        assert!(eps.abs() < 5e-7, "{v:?}: noise-free delay bias {:.3} µs", eps * 1e6);
        // Noisy: within 4 standard errors, the standard error inflated by √2 because adjacent
        // probe samples share a machine sample through the interpolation (correlation ≤ 0.5,
        // which at most doubles the variance of the sums). Failure probability ≤ 6e-5 per case.
        let ds = simulate(&Config { seed, repeats, ..Config::preset(v) }).unwrap();
        let (eps, se, n) = ls_delay_error(&ds);
        eprintln!("{v:?}: least-squares delay error {:+.3} µs, se {:.3} µs, n {n}", eps * 1e6, se * 1e6);
        assert!(eps.abs() < 4.0 * 2f64.sqrt() * se, "{v:?}: {:.2} µs, se {:.2} µs", eps * 1e6, se * 1e6);
        assert!(se < 2e-6, "{v:?}: standard error {se}");
    }
}
