//! The scan method: a continuous scan of a circle or sphere whose path switches between two
//! radii (so the deflection steps several times). With the wrong time shift the combined
//! points `machine(t + D) + deflection(t)` show radial spikes at each step; the delay is the
//! shift that minimises the form error.
//!
//! The shift is found in two stages: a bracket over `±max_delay` on a decimated subset
//! (Kåsa fit inside, only to find the basin), then Brent's method on the profile sum of squared
//! radial errors over every in-contact sample (a Gauss-Newton geometric circle/sphere fit inside
//! each evaluation): sub-sample precision without differentiating noisy machine data. The
//! curvature of the profile at the minimum gives the standard uncertainty.
//!
//! Entry points: [`scan_delay`], [`ScanResult`], [`radial_errors`].

use crate::stream::{machine_pos_vel, Streams};
use crate::LatencyError;
use truepos_math::lsq::Residuals;
use truepos_math::{Matrix3, Point3, Vector3};

/// The scanned form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Form {
    /// A circle in the plane through `origin` with basis `e1`, `e2`.
    Circle {
        /// A point of the circle's plane (machine frame, mm).
        origin: Point3,
        /// First unit vector of the plane.
        e1: Vector3,
        /// Second unit vector of the plane.
        e2: Vector3,
    },
    /// A sphere (points over its surface).
    Sphere,
}

/// Result of the scan method.
#[derive(Clone, Debug)]
pub struct ScanResult {
    /// The fitted delay, s.
    pub delay: f64,
    /// Standard uncertainty of the delay, s.
    pub u_delay: f64,
    /// The scanned form (circle plane or sphere).
    pub form: Form,
    /// Centre and radius of the stylus-centre circle or sphere.
    pub center: Point3,
    /// Radius of the stylus-centre circle or sphere, mm.
    pub radius: f64,
    /// RMS radial error of the combined points without shift and with the fitted shift (mm).
    pub rms_before: f64,
    /// RMS radial error with the fitted shift, mm.
    pub rms_after: f64,
    /// Probe sample indices used.
    pub samples: Vec<usize>,
    /// Number of deflection steps (direction changes of the radial motion) seen.
    pub n_steps: usize,
}

struct ScanProblem<'a> {
    s: &'a Streams<'a>,
    idx: &'a [usize],
    form: Form,
}

impl ScanProblem<'_> {
    fn point(&self, i: usize, shift: f64) -> Option<(Vector3, Vector3)> {
        let j = self.idx[i];
        let (m, v) = machine_pos_vel(self.s.machine_t, self.s.machine, self.s.probe_t[j] + shift)?;
        let d = self.s.probe[j];
        Some((Vector3::new(m[0] + d[0], m[1] + d[1], m[2] + d[2]), Vector3::new(v[0], v[1], v[2])))
    }
}

impl Residuals for ScanProblem<'_> {
    fn n_params(&self) -> usize {
        match self.form {
            Form::Circle { .. } => 4,
            Form::Sphere => 5,
        }
    }
    fn n_residuals(&self) -> usize {
        self.idx.len()
    }
    fn eval(&self, p: &[f64], i: usize, jac: &mut [f64]) -> f64 {
        let shift = p[p.len() - 1];
        let Some((q, v)) = self.point(i, shift) else {
            // Outside the machine's time range: no information (zero residual and gradient).
            jac.iter_mut().for_each(|j| *j = 0.0);
            return 0.0;
        };
        match self.form {
            Form::Circle { origin, e1, e2 } => {
                let w = q - origin.coords;
                let (u, vv) = (e1.dot(&w) - p[0], e2.dot(&w) - p[1]);
                let d = (u * u + vv * vv).sqrt().max(1e-300);
                jac[0] = -u / d;
                jac[1] = -vv / d;
                jac[2] = -1.0;
                jac[3] = (e1 * (u / d) + e2 * (vv / d)).dot(&v);
                d - p[2]
            }
            Form::Sphere => {
                let w = q - Vector3::new(p[0], p[1], p[2]);
                let d = w.norm().max(1e-300);
                let g = w / d;
                jac[0] = -g.x;
                jac[1] = -g.y;
                jac[2] = -g.z;
                jac[3] = -1.0;
                jac[4] = g.dot(&v);
                d - p[3]
            }
        }
    }
}

/// Kåsa fit of the combined points at `shift` over `sub` (indices into `prob.idx`): returns the
/// geometric parameters (circle a, b, R or sphere cx, cy, cz, R) and the RMS radial error.
fn kasa(prob: &ScanProblem, sub: &[usize], shift: f64) -> Option<(Vec<f64>, f64)> {
    let mut pts = Vec::with_capacity(sub.len());
    for &i in sub {
        if let Some((q, _)) = prob.point(i, shift) {
            pts.push(q);
        }
    }
    if pts.len() < 5 {
        return None;
    }
    let p = match prob.form {
        Form::Circle { origin, e1, e2 } => {
            let mut m = Matrix3::zeros();
            let mut r = Vector3::zeros();
            for q in &pts {
                let w = q - origin.coords;
                let (u, v) = (e1.dot(&w), e2.dot(&w));
                let row = Vector3::new(u, v, 1.0);
                m += row * row.transpose();
                r += row * (u * u + v * v);
            }
            let s = m.try_inverse()? * r;
            let (a, b) = (s[0] / 2.0, s[1] / 2.0);
            vec![a, b, (s[2] + a * a + b * b).max(0.0).sqrt()]
        }
        Form::Sphere => {
            let mut m = nalgebra::Matrix4::<f64>::zeros();
            let mut r = nalgebra::Vector4::<f64>::zeros();
            for q in &pts {
                let row = nalgebra::Vector4::new(q.x, q.y, q.z, 1.0);
                m += row * row.transpose();
                r += row * q.norm_squared();
            }
            let s = m.try_inverse()? * r;
            let c = Vector3::new(s[0], s[1], s[2]) / 2.0;
            vec![c.x, c.y, c.z, (s[3] + c.norm_squared()).max(0.0).sqrt()]
        }
    };
    let mut pp = p.clone();
    pp.push(shift);
    let mut jac = vec![0.0; pp.len()];
    let mut ss = 0.0;
    for &i in sub {
        let r = prob.eval(&pp, i, &mut jac);
        ss += r * r;
    }
    Some((p, (ss / sub.len() as f64).sqrt()))
}

/// Count the steps of the deflection magnitude between its low and high levels (hysteresis at
/// the 25 % and 75 % points between the 10th and 90th percentiles).
fn count_steps(s: &Streams, idx: &[usize], threshold: f64) -> usize {
    let mut mags: Vec<f64> = idx
        .iter()
        .map(|&j| {
            let d = s.probe[j];
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        })
        .collect();
    let series = mags.clone();
    mags.sort_by(f64::total_cmp);
    let q = |f: f64| mags[((mags.len() - 1) as f64 * f) as usize];
    let (p10, p90) = (q(0.1), q(0.9));
    if p90 - p10 < 2.0 * threshold {
        return 0;
    }
    let (lo, hi) = (p10 + 0.25 * (p90 - p10), p10 + 0.75 * (p90 - p10));
    let mut state = 0i8;
    let mut steps = 0;
    for m in series {
        let ns = if m < lo {
            -1
        } else if m > hi {
            1
        } else {
            state
        };
        if ns != state && state != 0 {
            steps += 1;
        }
        state = ns;
    }
    steps
}

/// Probe samples in contact within runs whose deflection direction turns (the scan).
pub fn scan_samples(s: &Streams, threshold: f64, min_turn: f64) -> Vec<usize> {
    let mut idx = Vec::new();
    for (a, b) in crate::contact::find_runs(s.probe, threshold, 20) {
        let Some(n) = crate::contact::run_normal(s.probe, a, b) else { continue };
        if crate::contact::run_turn(s.probe, a, b, &n) >= min_turn {
            idx.extend(a..b);
        }
    }
    idx
}

/// The form of the scan from its combined points at zero shift: a circle in their plane when
/// they are flat (smallest spread < 2 % of the largest), else a sphere.
fn scan_form(s: &Streams, idx: &[usize]) -> Result<Form, LatencyError> {
    let mut pts = Vec::with_capacity(idx.len());
    for &j in idx {
        if let Some((m, _)) = machine_pos_vel(s.machine_t, s.machine, s.probe_t[j]) {
            let d = s.probe[j];
            pts.push(Vector3::new(m[0] + d[0], m[1] + d[1], m[2] + d[2]));
        }
    }
    if pts.len() < 50 {
        return Err(LatencyError::NoOverlap {
            machine: (s.machine_t[0], s.machine_t[s.machine_t.len() - 1]),
            probe: (s.probe_t[0], s.probe_t[s.probe_t.len() - 1]),
        });
    }
    let c = pts.iter().sum::<Vector3>() / pts.len() as f64;
    let mut cov = Matrix3::zeros();
    for p in &pts {
        cov += (p - c) * (p - c).transpose();
    }
    let e = cov.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| e.eigenvalues[b].total_cmp(&e.eigenvalues[a]));
    let lam = |k: usize| e.eigenvalues[order[k]].max(0.0);
    Ok(if lam(2).sqrt() < 0.02 * lam(0).sqrt() {
        let e1: Vector3 = e.eigenvectors.column(order[0]).into_owned();
        let nrm: Vector3 = e.eigenvectors.column(order[2]).into_owned();
        Form::Circle { origin: Point3::from(c), e1, e2: nrm.cross(&e1) }
    } else {
        Form::Sphere
    })
}

/// The machine samples whose stamp shifted by `shift` stays inside one contact run of `idx`
/// (`margin` s from its ends): stage 2's fixed sample set on the machine clock.
fn machine_clock_samples(s: &Streams, idx: &[usize], margin: f64, shift: f64) -> Vec<usize> {
    let mut on_machine = Vec::new();
    let mut r0 = 0;
    for r in 1..=idx.len() {
        if r == idx.len() || idx[r] != idx[r - 1] + 1 {
            let (ta, tb) = (s.probe_t[idx[r0]] + margin, s.probe_t[idx[r - 1]] - margin);
            let i0 = s.machine_t.partition_point(|&t| t - shift < ta);
            let i1 = s.machine_t.partition_point(|&t| t - shift <= tb);
            on_machine.extend(i0..i1.max(i0));
            r0 = r;
        }
    }
    on_machine
}

/// Delay from a scan. `max_delay` bounds the search (s).
pub fn scan_delay(s: &Streams, threshold: f64, max_delay: f64) -> Result<ScanResult, LatencyError> {
    let idx = scan_samples(s, threshold, 0.5);
    if idx.len() < 50 {
        return Err(LatencyError::NoContact(format!(
            "no scan found: no contact run longer than 20 samples whose deflection direction turns (threshold {threshold} mm)"
        )));
    }
    let n_steps = count_steps(s, &idx, threshold);
    if n_steps < 2 {
        return Err(LatencyError::Underdetermined(format!(
            "the scan has {n_steps} deflection step(s): without direction changes of the radial motion the delay is not observable (switch the path between two radii several times)"
        )));
    }
    let form = scan_form(s, &idx)?;
    let prob = ScanProblem { s, idx: &idx, form };
    // Noise of each stream (robust, from second differences): interpolating noisy machine
    // samples at fraction w has a variance that swings with the shift (period: one machine
    // sample) and would pull an unweighted minimum towards half-sample shifts. Each combined
    // point is weighted by its own variance.
    let t_lo = s.probe_t[idx[0]] - max_delay;
    let t_hi = s.probe_t[idx[idx.len() - 1]] + max_delay;
    let m0 = s.machine_t.partition_point(|&t| t < t_lo);
    let m1 = s.machine_t.partition_point(|&t| t <= t_hi);
    let sig_m2 = noise_variance(&s.machine[m0..m1]);
    let sig_p2 = noise_variance(&idx.iter().map(|&j| s.probe[j]).collect::<Vec<_>>());
    let floor = 1e-14; // (0.1 nm)²: noise-free data still gets finite weights
                       // Starting geometry: algebraic fit at zero shift.
    let all: Vec<usize> = (0..idx.len()).collect();
    let (g0, rms0) = kasa(&prob, &all, 0.0)
        .ok_or_else(|| LatencyError::Degenerate("the scan points do not define a circle or sphere".into()))?;
    let _ = rms0;
    // Stage 1: bracket the basin on a decimated subset (weighted profile, as stage 2).
    let step = (idx.len() / 5_000).max(1);
    let sub: Vec<usize> = (0..idx.len()).step_by(step).collect();
    let n_grid = 200;
    let h_grid = 2.0 * max_delay / n_grid as f64;
    let mut coarse = Profile::new(&prob, sub, g0.clone(), sig_m2.max(floor), sig_p2.max(floor));
    let mut best = (f64::INFINITY, 0.0, g0.clone());
    for g in 0..=n_grid {
        let shift = -max_delay + h_grid * g as f64;
        let f = coarse.ssr(shift);
        if f < best.0 {
            best = (f, shift, coarse.geom.clone());
        }
    }
    if !best.0.is_finite() {
        return Err(LatencyError::Degenerate("the scan points do not define a circle or sphere".into()));
    }
    // Stage 2: Brent's method on the weighted profile sum of squares f(D) = min over the form
    // of Σ w·radial², with a Gauss-Newton geometric fit inside, over every in-contact sample.
    let mut prof = Profile::new(&prob, all, g0, sig_m2.max(floor), sig_p2.max(floor));
    let f_before = prof.ssr(0.0);
    let rms_before = prof.rms();
    let _ = f_before;
    prof.geom = best.2.clone();
    // Stage 2 combines on the machine clock: each machine sample with the deflection
    // interpolated at its stamp minus the shift (the same model: the stylus centre at machine
    // stamp T is machine(T) + deflection(T − D)). The machine samples then enter unchanged at
    // every shift, and only the quieter probe (0.3 µm against 1 µm) is interpolated: the swing
    // of the interpolated noise with the fractional part of the shift in samples — which pulls
    // the minimum towards whole- or half-sample shifts unless the weights cancel it exactly —
    // shrinks by the ratio of the variances. The sample set is fixed once (all machine stamps
    // whose shifted time stays inside one contact run over the whole bracket), so the profile
    // is continuous.
    let margin = h_grid + 2.0 * s.machine_dt().max(s.probe_dt());
    let on_machine = machine_clock_samples(s, &idx, margin, best.1);
    if on_machine.len() >= 50 {
        // Take the clock on which the profile is smoother (see [`roughness`]): on equal clocks
        // every point has the same interpolation phase and the noisier machine should not be
        // interpolated; a much faster probe clock spreads the machine's phases instead.
        let probe_points: Vec<f64> = idx.iter().map(|&j| s.probe_t[j] + best.1).collect();
        let machine_points: Vec<f64> = on_machine.iter().map(|&i| s.machine_t[i] - best.1).collect();
        let a = roughness(&probe_points, s.machine_t, sig_p2.max(floor), sig_m2.max(floor));
        let b = roughness(&machine_points, s.probe_t, sig_m2.max(floor), sig_p2.max(floor));
        if b < a {
            prof.machine_samples = Some(on_machine);
        }
    }
    let (a, b) = (best.1 - h_grid, best.1 + h_grid);
    let tol = 1e-8;
    let (delay, f0) = brent(|d| prof.ssr(d), a, b, tol);
    let rms_after = {
        prof.ssr(delay);
        prof.rms()
    };
    let geom = prof.geom.clone();
    // Curvature of the profile at the minimum gives the standard uncertainty:
    // f(D) ≈ f₀ + k·(D − D̂)², var(D̂) = σ₀² / k, σ₀² = f₀ / (n − p).
    let h = (0.2 * s.machine_dt()).max(1e-6);
    let (fp, fm) = (prof.ssr(delay + h), prof.ssr(delay - h));
    let k = (fp + fm - 2.0 * f0) / (2.0 * h * h);
    let np = geom.len() + 1;
    let n = prof.buf.len();
    if !(k > 0.0) || n <= np {
        return Err(LatencyError::Underdetermined(
            "the form error does not change with the shift: the scan does not determine the delay".into(),
        ));
    }
    let sigma2 = f0 / (n - np) as f64;
    // Interpolated machine values are correlated when the machine samples more slowly than the
    // probe: count independent machine samples only.
    // The same holds for interpolated probe values on the machine clock.
    let ratio = if prof.machine_samples.is_some() {
        (s.probe_dt() / s.machine_dt()).max(1.0)
    } else {
        (s.machine_dt() / s.probe_dt()).max(1.0)
    };
    let u_delay = (sigma2 / k).sqrt() * ratio.sqrt();
    let p = &geom;
    let (center, radius) = match form {
        Form::Circle { origin, e1, e2 } => (origin + e1 * p[0] + e2 * p[1], p[2]),
        Form::Sphere => (Point3::new(p[0], p[1], p[2]), p[3]),
    };
    Ok(ScanResult { delay, u_delay, form, center, radius, rms_before, rms_after, samples: idx, n_steps })
}

/// Radial error (mm) of each scan sample `(t_s, error)` for a shift: the distance of the
/// combined point from the fitted centre minus the radius (for plots before/after).
pub fn radial_errors(s: &Streams, r: &ScanResult, shift: f64) -> Vec<(f64, f64)> {
    let prob = ScanProblem { s, idx: &r.samples, form: r.form };
    let geom: Vec<f64> = match r.form {
        Form::Circle { origin, e1, e2 } => {
            let w = r.center - origin;
            vec![e1.dot(&w), e2.dot(&w), r.radius]
        }
        Form::Sphere => vec![r.center.x, r.center.y, r.center.z, r.radius],
    };
    let sub: Vec<usize> = (0..r.samples.len()).collect();
    // Refit the form at this shift so that "before" is the best form without the correction.
    let geom = kasa(&prob, &sub, shift).map(|g| g.0).unwrap_or(geom);
    let mut p = geom;
    p.push(shift);
    let mut jac = vec![0.0; p.len()];
    (0..r.samples.len()).map(|i| (s.probe_t[r.samples[i]], prob.eval(&p, i, &mut jac))).collect()
}

/// How rough the profile is when the points `fixed + interpolated(t + shift)` are formed at the
/// times `t` (already shifted) by linear interpolation on the clock `grid` (noise variances
/// `sig_f2` of the fixed, `sig_i2` of the interpolated stream). Each time the shift carries a
/// group of points with one interpolation phase across a sample of `grid`, the profile's slope
/// jumps by a random amount ∝ √(group)·σᵢ/Δt·σ (the second difference of the interpolated noise);
/// against the profile's curvature ∝ N/σ² this moves the minimum by about
/// `σᵢ·σ / (Δt·√(N·phases))`, which is returned (relative units; smaller is better).
fn roughness(t: &[f64], grid: &[f64], sig_f2: f64, sig_i2: f64) -> f64 {
    let n = grid.len();
    if n < 2 || t.is_empty() {
        return f64::INFINITY;
    }
    let dt = (grid[n - 1] - grid[0]) / (n - 1) as f64;
    const BINS: usize = 64;
    let mut hist = [0usize; BINS];
    let mut var = 0.0;
    for &x in t {
        let i = grid.partition_point(|&g| g <= x).clamp(1, n - 1) - 1;
        let w = ((x - grid[i]) / (grid[i + 1] - grid[i])).clamp(0.0, 1.0);
        hist[((w * BINS as f64) as usize).min(BINS - 1)] += 1;
        var += sig_f2 + sig_i2 * (w * w + (1.0 - w) * (1.0 - w));
    }
    let nt = t.len() as f64;
    let phases = hist.iter().filter(|&&c| c as f64 >= 0.01 * nt).count().max(1) as f64;
    sig_i2.sqrt() * (var / nt).sqrt() / (dt * (nt * phases).sqrt())
}

/// The profile objective: combined points at a shift (one merge pass into a reused buffer) and
/// a Gauss-Newton fit of the form, warm-started from the previous one.
struct Profile<'a> {
    prob: &'a ScanProblem<'a>,
    /// Indices into `prob.idx` used.
    sub: Vec<usize>,
    geom: Vec<f64>,
    sig_m2: f64,
    sig_p2: f64,
    /// Combined points and their weights at the last shift.
    buf: Vec<(Vector3, f64)>,
    /// Unweighted sum of squares at the last evaluation.
    last_ss: f64,
    /// When set, combine on the machine clock: these machine samples with the deflection
    /// interpolated at their stamp minus the shift (instead of `sub` on the probe clock).
    machine_samples: Option<Vec<usize>>,
}

/// Robust noise variance per component of a sampled 3-vector signal from its second
/// differences: `median(Δ²)² / 0.4549 / 6` averaged over the components (white noise; smooth
/// motion contributes nothing at these rates).
fn noise_variance(v: &[[f64; 3]]) -> f64 {
    if v.len() < 5 {
        return 0.0;
    }
    let mut acc = 0.0;
    for k in 0..3 {
        let mut d2: Vec<f64> = v.windows(3).map(|w| (w[2][k] - 2.0 * w[1][k] + w[0][k]).powi(2)).collect();
        let mid = d2.len() / 2;
        let (_, med, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
        acc += *med / 0.4549 / 6.0;
    }
    acc / 3.0
}

impl<'a> Profile<'a> {
    fn new(prob: &'a ScanProblem<'a>, sub: Vec<usize>, geom: Vec<f64>, sig_m2: f64, sig_p2: f64) -> Self {
        let n = sub.len();
        Profile {
            prob,
            sub,
            geom,
            sig_m2,
            sig_p2,
            buf: Vec::with_capacity(n),
            last_ss: 0.0,
            machine_samples: None,
        }
    }

    fn rms(&self) -> f64 {
        (self.last_ss / self.buf.len().max(1) as f64).sqrt()
    }

    fn points(&mut self, shift: f64) {
        let s = self.prob.s;
        let (mt, m) = (s.machine_t, s.machine);
        self.buf.clear();
        if let Some(ms) = &self.machine_samples {
            let (pt, p) = (s.probe_t, s.probe);
            let n = pt.len();
            let mut j = 0usize;
            for &i in ms {
                let t = mt[i] - shift;
                if !(t >= pt[0] && t <= pt[n - 1]) {
                    continue;
                }
                while j + 2 < n && pt[j + 1] <= t {
                    j += 1;
                }
                let w = (t - pt[j]) / (pt[j + 1] - pt[j]);
                let (a, b, q) = (p[j], p[j + 1], m[i]);
                let var = self.sig_m2 + self.sig_p2 * (w * w + (1.0 - w) * (1.0 - w));
                self.buf.push((
                    Vector3::new(
                        q[0] + a[0] + w * (b[0] - a[0]),
                        q[1] + a[1] + w * (b[1] - a[1]),
                        q[2] + a[2] + w * (b[2] - a[2]),
                    ),
                    1.0 / var,
                ));
            }
            return;
        }
        let n = mt.len();
        let mut i = 0usize;
        for &k in &self.sub {
            let j = self.prob.idx[k];
            let t = s.probe_t[j] + shift;
            if !(t >= mt[0] && t <= mt[n - 1]) {
                continue;
            }
            while i + 2 < n && mt[i + 1] <= t {
                i += 1;
            }
            let w = (t - mt[i]) / (mt[i + 1] - mt[i]);
            let (a, b) = (m[i], m[i + 1]);
            let d = s.probe[j];
            let var = self.sig_p2 + self.sig_m2 * (w * w + (1.0 - w) * (1.0 - w));
            self.buf.push((
                Vector3::new(
                    a[0] + w * (b[0] - a[0]) + d[0],
                    a[1] + w * (b[1] - a[1]) + d[1],
                    a[2] + w * (b[2] - a[2]) + d[2],
                ),
                1.0 / var,
            ));
        }
    }

    /// Weighted sum of squared radial errors at `shift` after a weighted geometric fit of the
    /// form (warm-started from the previous one).
    fn ssr(&mut self, shift: f64) -> f64 {
        self.points(shift);
        if self.buf.len() < 10 {
            return f64::INFINITY;
        }
        let mut g = self.geom.clone();
        let mut last = f64::INFINITY;
        let mut last_ss = 0.0;
        for _ in 0..30 {
            let (ssr, ss, step) = match self.prob.form {
                Form::Circle { origin, e1, e2 } => {
                    let mut a = Matrix3::zeros();
                    let mut r = Vector3::zeros();
                    let (mut sw, mut ss) = (0.0, 0.0);
                    for (q, wt) in &self.buf {
                        let w = q - origin.coords;
                        let (u, v) = (e1.dot(&w) - g[0], e2.dot(&w) - g[1]);
                        let d = (u * u + v * v).sqrt().max(1e-300);
                        let res = d - g[2];
                        let jr = Vector3::new(-u / d, -v / d, -1.0);
                        a += jr * jr.transpose() * *wt;
                        r += jr * (res * wt);
                        sw += wt * res * res;
                        ss += res * res;
                    }
                    let st = a.try_inverse().map(|inv| -(inv * r));
                    (sw, ss, st.map(|v| vec![v[0], v[1], v[2]]))
                }
                Form::Sphere => {
                    let mut a = nalgebra::Matrix4::<f64>::zeros();
                    let mut r = nalgebra::Vector4::<f64>::zeros();
                    let (mut sw, mut ss) = (0.0, 0.0);
                    for (q, wt) in &self.buf {
                        let w = q - Vector3::new(g[0], g[1], g[2]);
                        let d = w.norm().max(1e-300);
                        let res = d - g[3];
                        let jr = nalgebra::Vector4::new(-w.x / d, -w.y / d, -w.z / d, -1.0);
                        a += jr * jr.transpose() * *wt;
                        r += jr * (res * wt);
                        sw += wt * res * res;
                        ss += res * res;
                    }
                    let st = a.try_inverse().map(|inv| -(inv * r));
                    (sw, ss, st.map(|v| vec![v[0], v[1], v[2], v[3]]))
                }
            };
            let Some(step) = step else { return ssr };
            last = ssr;
            last_ss = ss;
            // Converged when the step is below a picometre: the sum of squares at `g` is final.
            if step.iter().all(|x| x.abs() < 1e-9) {
                break;
            }
            for (x, d) in g.iter_mut().zip(&step) {
                *x += d;
            }
        }
        self.geom = g;
        self.last_ss = last_ss;
        last
    }
}

/// Brent's minimisation of `f` on `[a, b]` (parabolic interpolation with golden-section
/// safeguards) to absolute tolerance `tol`: returns (argmin, min).
pub fn brent(mut f: impl FnMut(f64) -> f64, a: f64, b: f64, tol: f64) -> (f64, f64) {
    const CG: f64 = 0.381_966_011_250_105_1;
    let (mut a, mut b) = (a.min(b), a.max(b));
    let mut x = a + CG * (b - a);
    let (mut w, mut v) = (x, x);
    let mut fx = f(x);
    let (mut fw, mut fv) = (fx, fx);
    let (mut d, mut e) = (0.0f64, 0.0f64);
    for _ in 0..200 {
        let xm = 0.5 * (a + b);
        let tol1 = tol + 1e-10 * x.abs();
        let tol2 = 2.0 * tol1;
        if (x - xm).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            let r = (x - w) * (fx - fv);
            let mut q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            let etemp = e;
            e = d;
            if p.abs() < (0.5 * q * etemp).abs() && p > q * (a - x) && p < q * (b - x) {
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = if xm >= x { tol1 } else { -tol1 };
                }
                golden = false;
            }
        }
        if golden {
            e = if x >= xm { a - x } else { b - x };
            d = CG * e;
        }
        let u = if d.abs() >= tol1 { x + d } else { x + if d >= 0.0 { tol1 } else { -tol1 } };
        let fu = f(u);
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            v = w;
            fv = fw;
            w = x;
            fw = fx;
            x = u;
            fx = fu;
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                v = w;
                fv = fw;
                w = u;
                fw = fu;
            } else if fu <= fv || v == x || v == w {
                v = u;
                fv = fu;
            }
        }
    }
    (x, fx)
}

#[cfg(test)]
mod tests {
    use super::brent;

    #[test]
    fn brent_finds_the_minimum_of_a_parabola_and_a_quartic() {
        let (x, f) = brent(|x| (x - 0.3).powi(2) + 1.0, -1.0, 2.0, 1e-10);
        assert!((x - 0.3).abs() < 1e-8 && (f - 1.0).abs() < 1e-14);
        let (x, _) = brent(|x| (x + 1.2345e-3).powi(4) + 2.0 * (x + 1.2345e-3).powi(2), -0.01, 0.01, 1e-12);
        assert!((x + 1.2345e-3).abs() < 1e-9, "{x}");
    }
}
