//! Every method on the virtual cell (`truepos-sim`, engineer B1's physics: servo following
//! error, stylus spring-mass-damper with friction and restitution, exact artefact contacts,
//! separate capture latencies, encoders 1 µm, probe 0.3 µm, 1 kHz streams) against its truth,
//! for positive and negative delays.
//!
//! Tolerances (contract): |error| < 10 µs for the touch methods, < 20 µs for the scan, and
//! |error| < 3 stated standard uncertainties. Repeats are set so the stated uncertainty is a
//! few µs (a calibration repeats its pattern to average the encoder noise: at 1 kHz one
//! five-point set at 10 mm/s gives u ≈ 20 µs, 48 sets ≈ 3 µs).

use truepos_latency::{estimate, KnownSize, Method, Options, Streams};
use truepos_sim::scenario::latency::{self as scen, ArtefactTruth, Config, Variant};

struct Owned {
    mt: Vec<f64>,
    m: Vec<[f64; 3]>,
    pt: Vec<f64>,
    p: Vec<[f64; 3]>,
}

fn owned(d: &scen::Dataset) -> Owned {
    Owned {
        mt: d.machine.iter().map(|x| x.0).collect(),
        m: d.machine.iter().map(|x| [x.1.x, x.1.y, x.1.z]).collect(),
        pt: d.probe.iter().map(|x| x.0).collect(),
        p: d.probe.iter().map(|x| [x.1.x, x.1.y, x.1.z]).collect(),
    }
}

fn config(variant: Variant, delay: f64, seed: u64, repeats: usize) -> Config {
    let mut c = Config::preset(variant);
    c.seed = seed;
    c.repeats = repeats;
    if let Some(ax) = &mut c.axis_latency_s {
        // Keep the per-axis spread, shift the mean delay.
        let mean = ax.iter().sum::<f64>() / 3.0 - c.probe_latency_s;
        for l in ax.iter_mut() {
            *l += delay - mean;
        }
    }
    c.machine_latency_s = c.probe_latency_s + delay;
    c
}

fn run(variant: Variant, method: Method, delay: f64, seed: u64, repeats: usize, tol: f64) {
    let mut c = config(variant, delay, seed, repeats);
    if variant == Variant::Speeds {
        // At 1 kHz a 40 mm/s retract leaves 4–5 samples in the extrapolation band and its size
        // comes out about 0.8 µm small (≈ +9 µs on the delay); at 2 kHz the bias is 0.35 µm.
        c.machine_rate_hz = 2000.0;
        c.probe_rate_hz = 2000.0;
    }
    let d = scen::simulate(&c).expect("scenario");
    let o = owned(&d);
    let s = Streams { machine_t: &o.mt, machine: &o.m, probe_t: &o.pt, probe: &o.p };
    let known = match (method, d.truth.artefact) {
        (Method::Artefact, ArtefactTruth::Sphere { diameter_mm, .. }) => {
            Some(KnownSize::SphereDiameter(diameter_mm))
        }
        (Method::Artefact, ArtefactTruth::Plates { gap_mm, .. }) => Some(KnownSize::Gap(gap_mm)),
        _ => None,
    };
    let opt = Options { method, known_size: known, tip_radius: d.truth.tip_radius_mm, ..Options::default() };
    let e = estimate(&s, &opt).unwrap_or_else(|err| panic!("{variant:?} {delay}: {err}"));
    let err = e.delay - d.truth.delay_s;
    eprintln!(
        "{:10} {:8} truth {:9.2} µs  got {:9.2} µs  u {:6.2} µs  error {:+7.2} µs  ({} contacts) {:?}",
        variant.name(),
        e.method().name(),
        d.truth.delay_s * 1e6,
        e.delay * 1e6,
        e.u_delay * 1e6,
        err * 1e6,
        e.n_contacts,
        e.warnings
    );
    assert!(err.abs() < tol, "{variant:?}: error {err:e} s beyond {tol:e} s");
    assert!(err.abs() < 3.0 * e.u_delay, "{variant:?}: error {err:e} s beyond 3 u = {:e} s", 3.0 * e.u_delay);
    if let Some(s0) = e.static_size() {
        if method == Method::Speeds {
            // Static size from the intercept: within a few µm of the artefact (u ≈ 1 µm).
            assert!(
                (s0 - d.truth.static_size_mm).abs() < 5e-3,
                "static size {s0} vs {}",
                d.truth.static_size_mm
            );
        }
    }
}

#[test]
fn sphere_artefact() {
    run(Variant::Sphere, Method::Artefact, 2.5e-3, 1, 48, 10e-6);
    run(Variant::Sphere, Method::Artefact, -1.5e-3, 2, 48, 10e-6);
}

/// The plates repeat identical moves, so every touch is sampled at the same phase. The run used
/// to end at the first sample whose noisy deflection fell below the threshold, which kept only
/// the near-threshold samples with upward noise: the zero-deflection instant came late on every
/// retract and the delay −6.6 ± 1.1 µs off (8 seeds, probe noise alone; −9 / −10 µs here against
/// u ≈ 3 µs). The descent now runs on to half the threshold and the fit selects on its fitted
/// curve: 12 seeds give +1.7 ± 0.7 µs, scatter 2.6 µs against a stated 2.8 µs.
#[test]
fn plates_artefact() {
    run(Variant::Plates, Method::Artefact, 2.5e-3, 3, 96, 10e-6);
    run(Variant::Plates, Method::Artefact, -1.5e-3, 4, 96, 10e-6);
}

#[test]
fn speeds() {
    run(Variant::Speeds, Method::Speeds, 2.5e-3, 5, 32, 10e-6);
    run(Variant::Speeds, Method::Speeds, -1.5e-3, 6, 32, 10e-6);
}

#[test]
fn scan() {
    run(Variant::Scan, Method::Scan, 2.5e-3, 7, 6, 20e-6);
    run(Variant::Scan, Method::Scan, -1.5e-3, 8, 6, 20e-6);
}

#[test]
fn inout() {
    run(Variant::InOut, Method::Inout, 2.5e-3, 9, 48, 10e-6);
    run(Variant::InOut, Method::Inout, -1.5e-3, 10, 48, 10e-6);
}

#[test]
fn multi_rate_and_oblique() {
    run(Variant::MultiRate, Method::Artefact, 2.5e-3, 11, 48, 10e-6);
    run(Variant::Oblique, Method::Artefact, -1.5e-3, 12, 48, 10e-6);
    // Seed 20 once kept a single +Z touch (the others turned too far under friction to count as
    // touches): 192 normals in the XY plane and one up were classified a circle, and the delay
    // came out 3.7 ms off with u = 7.5 ms.
    run(Variant::Oblique, Method::Artefact, 2.5e-3, 20, 48, 10e-6);
}

#[test]
fn auto_picks_a_method() {
    run(Variant::Speeds, Method::Auto, 1.0e-3, 13, 32, 10e-6);
    run(Variant::Scan, Method::Auto, -0.5e-3, 14, 6, 20e-6);
}

/// The scan at 1 kHz for several fractional parts of the delay in machine samples (the
/// interpolation phase of every sample changes with it), positive and negative. Interpolating
/// the noisy machine stream made the error depend on that phase (a weighted profile whose noise
/// term swings with it: sd 13 µs at 3.1 ms against a stated u of 6 µs over 12 seeds); the
/// profile now combines on the machine clock and interpolates the quieter probe.
#[test]
fn scan_fractional_delays() {
    for (k, d) in
        [2.9e-3, 3.0e-3, 3.1e-3, 3.25e-3, 3.5e-3, -2.9e-3, -3.1e-3, -3.25e-3, -3.5e-3].into_iter().enumerate()
    {
        run(Variant::Scan, Method::Scan, d, 3 + k as u64, 6, 20e-6);
    }
}
