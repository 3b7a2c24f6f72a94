//! Automatic segmentation of probe contacts and extrapolation to zero deflection.
//!
//! A contact is a run of probe samples with `|deflection| > threshold`. Its normal is the
//! direction of the deflection (the surface's outward normal, by the contract's sign). The
//! approach phase runs up to the deepest deflection, the retract phase after it.
//!
//! Extrapolation to zero deflection: while the tip rests on a surface point and the body moves
//! at constant speed, the machine position along the normal is linear in the deflection; the
//! intercept at zero deflection is the machine position of contact, free of stylus bending and
//! bounce. The band used is `threshold ≤ δ ≤ f·δ_peak`, `f` shrunk until the machine speed is
//! constant over the band. Retract data is preferred; approach data is the fallback.
//!
//! Entry points: [`find_runs`], [`extract_contacts`], [`Contact`].

use crate::stream::Streams;
use truepos_math::{Point3, Vector3};

/// Which phase of a contact gave its surface point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// The surface point came from the retract (the preferred phase).
    Retract,
    /// The surface point came from the approach (the retract was unusable).
    Approach,
}

/// One touch: where the machine was at zero deflection (uncorrected for the delay), the normal,
/// and the machine velocity while the extrapolated samples were taken.
#[derive(Clone, Debug)]
pub struct Contact {
    /// Probe sample indices `[start, end)` and of the deepest deflection.
    pub start: usize,
    /// Probe sample index of the deepest deflection.
    pub peak: usize,
    /// Probe sample index one past the contact's last sample.
    pub end: usize,
    /// Probe time stamp of the deepest deflection, s.
    pub t_peak: f64,
    /// Unit normal (direction of the deflection).
    pub normal: Vector3,
    /// Deepest deflection along the normal (mm).
    pub peak_deflection: f64,
    /// Machine position at zero deflection, paired by raw time stamps (mm).
    pub point: Point3,
    /// Standard uncertainty of `point` along the normal (mm), from the extrapolation's leverage and
    /// the residual scatter pooled over all contacts.
    pub u_point: f64,
    /// The same surface point from the deflection domain alone (machine position against
    /// deflection over the band, intercept at zero deflection), and its standard uncertainty.
    /// `point` comes from the time domain where it can: the probe's instant of zero deflection
    /// and the machine's own samples around it — more machine samples, and indifferent to the
    /// tip dragging sideways under friction. But the servo may still be settling from the
    /// acceleration away from the surface: the speed then wavers by about 1 % through the band
    /// (30 mm/s on the virtual cell), the quadratics in time bend to it and the point moves by
    /// 0.1 µm, by an amount that depends on the speed. The deflection domain does not see the
    /// motion in time at all (machine position plus deflection is the surface position however
    /// the body moves), so the speeds method, whose gradient a speed-dependent error would bias,
    /// uses this one (see [`crate::estimate`]).
    pub point_defl: Point3,
    /// Standard uncertainty of `point_defl` (root-sum-square of its components), mm.
    pub u_point_defl: f64,
    /// Machine velocity at the zero-deflection instant (mm/s).
    pub velocity: Vector3,
    /// Machine velocity over the approach band (mm/s), when it could be measured.
    pub approach_velocity: Option<Vector3>,
    /// Which phase of the contact gave the surface point.
    pub phase: Phase,
    /// Probe samples used in the extrapolation.
    pub n_used: usize,
}

impl Contact {
    /// Speed of the machine over the extrapolation band (mm/s).
    pub fn speed(&self) -> f64 {
        self.velocity.norm()
    }
    /// Velocity component along the normal (positive: moving away from the surface).
    pub fn normal_speed(&self) -> f64 {
        self.velocity.dot(&self.normal)
    }
    /// The surface point corrected for per-axis delays: `point + diag(d)·velocity`.
    pub fn corrected(&self, d: [f64; 3]) -> Point3 {
        self.point + Vector3::new(d[0] * self.velocity.x, d[1] * self.velocity.y, d[2] * self.velocity.z)
    }
}

/// Runs of probe samples with `|deflection| > threshold`: `[start, end)` index pairs. Runs
/// shorter than `min_len` samples are dropped (noise spikes).
pub fn find_runs(probe: &[[f64; 3]], threshold: f64, min_len: usize) -> Vec<(usize, usize)> {
    let th2 = threshold * threshold;
    let mut runs = Vec::new();
    let mut start = None;
    let mut ringing = false;
    for (i, d) in probe.iter().enumerate() {
        let on = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > th2;
        // A deflection that reverses between two samples without passing below the threshold
        // (the stylus ringing after a release, faster than the sampling) ends the run, and the
        // ringing after it is no run at all: it must not make a touch look like a scan.
        if let (true, Some(s)) = (on, start) {
            let p: &[f64; 3] = &probe[i - 1];
            if p[0] * d[0] + p[1] * d[1] + p[2] * d[2] < 0.0 {
                if i - s >= min_len && !ringing {
                    runs.push((s, i));
                }
                start = Some(i);
                ringing = true;
                continue;
            }
        }
        match (on, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                if i - s >= min_len && !ringing {
                    runs.push((s, i));
                }
                start = None;
                ringing = false;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        if probe.len() - s >= min_len && !ringing {
            runs.push((s, probe.len()));
        }
    }
    runs
}

/// Mean deflection direction of a run (unit), or `None` when it has no direction.
pub fn run_normal(probe: &[[f64; 3]], start: usize, end: usize) -> Option<Vector3> {
    let mut s = Vector3::zeros();
    for d in &probe[start..end] {
        s += Vector3::new(d[0], d[1], d[2]);
    }
    let n = s.norm();
    (n > 0.0).then(|| s / n)
}

/// How far the deflection direction turns within a run: the largest angle (rad) between the
/// run's mean direction and the direction of a sample deflected at least half as far as the
/// deepest one (scans turn, touches do not). The shallow samples are left out: with friction the
/// tip drags sideways as a touch starts and slips the other way as it leaves, so near the
/// threshold an oblique touch's direction swings by 30–40° (measured on the virtual cell's 30°
/// approaches) while its deep part holds within a few degrees.
pub fn run_turn(probe: &[[f64; 3]], start: usize, end: usize, normal: &Vector3) -> f64 {
    let norm = |d: &[f64; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let peak = probe[start..end].iter().map(norm).fold(0.0f64, f64::max);
    let mut min_cos = 1.0f64;
    for d in &probe[start..end] {
        let n = norm(d);
        if n > 0.0 && n >= 0.5 * peak {
            let v = Vector3::new(d[0], d[1], d[2]);
            min_cos = min_cos.min(v.dot(normal) / n);
        }
    }
    min_cos.clamp(-1.0, 1.0).acos()
}

/// Accumulates sums for the small straight-line regressions of the extrapolation (no allocation).
#[derive(Default, Clone, Copy)]
struct Line {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl Line {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        self.sx += x;
        self.sy += y;
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
    }
    /// Standard uncertainty of the intercept per unit residual sigma: √(1/n + x̄²/Sxx).
    fn leverage(&self) -> f64 {
        let mx = self.sx / self.n;
        let sxx = self.sxx - self.n * mx * mx;
        (1.0 / self.n + mx * mx / sxx).sqrt()
    }
    /// (intercept, slope, u_intercept, u_slope, residual sigma)
    fn fit(&self) -> Option<(f64, f64, f64, f64, f64)> {
        if self.n < 3.0 {
            return None;
        }
        let mx = self.sx / self.n;
        let my = self.sy / self.n;
        let sxx = self.sxx - self.n * mx * mx;
        let sxy = self.sxy - self.n * mx * my;
        let syy = self.syy - self.n * my * my;
        if !(sxx > 0.0) {
            return None;
        }
        let b = sxy / sxx;
        let a = my - b * mx;
        let ssr = (syy - b * sxy).max(0.0);
        let s2 = ssr / (self.n - 2.0);
        Some((a, b, (s2 * (1.0 / self.n + mx * mx / sxx)).sqrt(), (s2 / sxx).sqrt(), s2.sqrt()))
    }
}

/// Result of extrapolating one band.
struct Band {
    point: Point3,
    /// Standard uncertainty of the intercept per unit residual sigma (leverage), with the
    /// correlation inflation; the pooled sigma of all contacts multiplies it.
    unit: f64,
    /// Standard uncertainty of the point along the normal from the zero-deflection instant per
    /// unit probe residual sigma; the probe sigma pooled over all contacts multiplies it, and the
    /// product is added in quadrature.
    u_time: f64,
    /// Residual sum of squares and degrees of freedom of the probe's fit of δ(t).
    ssr_p: f64,
    dof_p: f64,
    ssr: f64,
    dof: f64,
    velocity: Vector3,
    n_used: usize,
    /// The same band's deflection-domain point (see [`Contact::point_defl`]).
    defl_domain: DeflDomain,
}

/// A zero-deflection point from the deflection domain: the intercept of machine position
/// against deflection.
#[derive(Clone, Copy, Default)]
struct DeflDomain {
    point: Point3,
    /// Leverage per unit residual sigma (with the correlation inflation).
    unit: f64,
    ssr: f64,
    dof: f64,
}

/// Options of the contact extraction.
#[derive(Clone, Copy, Debug)]
pub struct ContactOptions {
    /// Contact detection threshold on |deflection| (mm).
    pub threshold: f64,
    /// Minimum number of probe samples in an extrapolation band.
    pub min_band: usize,
}

impl Default for ContactOptions {
    fn default() -> Self {
        Self { threshold: 0.005, min_band: 4 }
    }
}

/// Extrapolate machine position against deflection to zero deflection over the samples in
/// `idx` (a contiguous probe index range, in time order) whose deflection along `n` lies in
/// `[lo, hi]`. `mi` is the machine position at the probe stamps.
#[allow(clippy::too_many_arguments)]
fn extrapolate(
    s: &Streams,
    mi: &[[f64; 3]],
    n: &Vector3,
    range: std::ops::Range<usize>,
    lo: f64,
    peak: f64,
    opt: &ContactOptions,
    forward: bool,
) -> Option<Band> {
    // Only the contiguous descent from the peak: after the tip leaves the surface the stylus
    // rings (and on approach it may bounce), and those samples can lie in the band too.
    let defl = |j: usize| {
        let d = s.probe[j];
        d[0] * n.x + d[1] * n.y + d[2] * n.z
    };
    // The descent runs on past the run's end (where the noisy deflection first fell below the
    // threshold) down to half the threshold: a sample whose true deflection is just above `lo`
    // must not be dropped for its noise alone, or the samples kept at the band's shallow end are
    // biased high (upward noise) and the zero-deflection instant with them. The time-domain
    // fit selects on its fitted curve, not on these noisy values.
    let stop_at = 0.5 * lo;
    let range = if forward {
        let stop = (range.start..s.probe.len()).find(|&j| defl(j) < stop_at).unwrap_or(s.probe.len());
        range.start..stop
    } else {
        let first = (0..range.end).rev().find(|&j| defl(j) < stop_at).map_or(0, |j| j + 1);
        first..range.end
    };
    if range.len() < opt.min_band {
        return None;
    }
    let t_ref = s.probe_t[range.start];
    for f in [0.6, 0.5, 0.4, 0.3, 0.2, 0.15] {
        let hi = f * peak;
        if hi <= lo {
            continue;
        }
        let mut pos_vs_defl = [Line::default(); 3];
        let mut along = Line::default();
        let mut pos_vs_t = [Line::default(); 3];
        // Quadratic check of x(t): sums for a 3-parameter fit of x along the normal.
        let mut tq = Vec::new();
        let mut tp = Vec::new();
        let (mut t_first, mut t_last) = (f64::NAN, f64::NAN);
        for j in range.clone() {
            let d = s.probe[j];
            let defl = d[0] * n.x + d[1] * n.y + d[2] * n.z;
            let m = mi[j];
            if !(defl >= lo && defl <= hi) || m[0].is_nan() {
                continue;
            }
            let t = s.probe_t[j] - t_ref;
            if t_first.is_nan() {
                t_first = s.probe_t[j];
            }
            t_last = s.probe_t[j];
            let x = m[0] * n.x + m[1] * n.y + m[2] * n.z;
            for k in 0..3 {
                pos_vs_defl[k].add(defl, m[k]);
                pos_vs_t[k].add(t, m[k]);
            }
            along.add(defl, x);
            tq.push((t, x));
            tp.push((t, defl));
        }
        if (along.n as usize) < opt.min_band {
            continue;
        }
        // Constant speed over the band? Compare a quadratic's velocity change with the speed.
        // The probe (0.3 µm noise) sees a change of speed more sharply than the encoders.
        if !(constant_speed(&tq) && constant_speed(&tp)) && f > 0.15 {
            continue;
        }
        let (ax, bx, _, _, sig) = along.fit()?;
        let mut p = [0.0; 3];
        let mut v = [0.0; 3];
        for k in 0..3 {
            p[k] = pos_vs_defl[k].fit()?.0;
            v[k] = pos_vs_t[k].fit()?.1;
        }
        let n_used = along.n as usize;
        // Preferred: the time domain. The probe gives the instant of zero deflection t₀ (line
        // of δ against t over the band); the machine line x(t) over its whole constant-speed
        // stretch (the band and beyond, where the body keeps moving freely) gives the machine
        // position at t₀. Same model, many more machine samples.
        // The deflection domain: machine position (interpolated at the probe stamps) against
        // deflection. Interpolated values between machine samples are correlated: count only
        // the independent machine samples in the band when the machine is slower than the probe.
        let i0 = s.machine_t.partition_point(|&t| t < t_first);
        let i1 = s.machine_t.partition_point(|&t| t <= t_last);
        let n_machine = (i1.saturating_sub(i0)).max(2) as f64;
        let inflate = (n_used as f64 / n_machine).max(1.0).sqrt();
        let defl_domain = DeflDomain {
            point: Point3::new(p[0], p[1], p[2]),
            unit: along.leverage() * inflate,
            ssr: sig * sig * (along.n - 2.0),
            dof: along.n - 2.0,
        };
        // Preferred: the time domain. The probe gives the instant of zero deflection t₀ (line
        // of δ against t over the band); the machine line x(t) over its whole constant-speed
        // stretch (the band and beyond, where the body keeps moving freely) gives the machine
        // position at t₀. Same model, many more machine samples.
        if let Some(mut b) = time_domain(s, n, range.clone(), lo, hi, ax + bx * hi, forward) {
            b.defl_domain = defl_domain;
            return Some(b);
        }
        // Fallback: the deflection domain alone.
        return Some(Band {
            point: defl_domain.point,
            unit: defl_domain.unit,
            u_time: 0.0,
            ssr_p: 0.0,
            dof_p: 0.0,
            ssr: defl_domain.ssr,
            dof: defl_domain.dof,
            velocity: Vector3::new(v[0], v[1], v[2]),
            n_used,
            defl_domain,
        });
    }
    None
}

/// Fraction of the band's deflection range left out at its deep end in the machine window.
const MARGIN: f64 = 0.25;

/// Accumulated sums for a quadratic `y = c₀ + c₁τ + c₂τ²` (no allocation).
#[derive(Default, Clone, Copy)]
struct Quad {
    m: nalgebra::Matrix3<f64>,
    r: nalgebra::Vector3<f64>,
    yy: f64,
    n: f64,
}

impl Quad {
    fn add(&mut self, t: f64, y: f64) {
        let row = nalgebra::Vector3::new(1.0, t, t * t);
        self.m += row * row.transpose();
        self.r += row * y;
        self.yy += y * y;
        self.n += 1.0;
    }
    /// Coefficients, inverse normal matrix and residual sum of squares.
    fn fit(&self) -> Option<(nalgebra::Vector3<f64>, nalgebra::Matrix3<f64>, f64)> {
        if self.n < 4.0 {
            return None;
        }
        let inv = self.m.try_inverse()?;
        let c = inv * self.r;
        let ssr = (self.yy - c.dot(&self.r)).max(0.0);
        Some((c, inv, ssr))
    }
}

/// The time-domain extrapolation (see [`extrapolate`]): the probe gives the instant `t₀` of zero
/// deflection (quadratic in time over the band); the machine's own samples over the same stretch
/// of positions, extended beyond the contact by the band's length so that `t₀` lies inside,
/// give the machine position at `t₀` (quadratic in time: the servo may still be settling). `x_hi`
/// is the machine position along the normal at the band's deepest deflection; `forward` for
/// retract (the free stretch follows the band in time), backward for approach.
fn time_domain(
    s: &Streams,
    n: &Vector3,
    range: std::ops::Range<usize>,
    lo: f64,
    hi: f64,
    x_hi: f64,
    forward: bool,
) -> Option<Band> {
    let mut dq = Quad::default();
    let (mut t_first, mut t_last) = (f64::NAN, f64::NAN);
    for j in range.clone() {
        let d = s.probe[j];
        let defl = d[0] * n.x + d[1] * n.y + d[2] * n.z;
        if defl >= lo && defl <= hi {
            if t_first.is_nan() {
                t_first = s.probe_t[j];
            }
            t_last = s.probe_t[j];
        }
    }
    if t_first.is_nan() {
        return None;
    }
    let t_ref = 0.5 * (t_first + t_last);
    for j in range.clone() {
        let d = s.probe[j];
        let defl = d[0] * n.x + d[1] * n.y + d[2] * n.z;
        if defl >= lo && defl <= hi {
            dq.add(s.probe_t[j] - t_ref, defl);
        }
    }
    let (c1, _, _) = dq.fit()?;
    // Selecting samples on their noisy deflection truncates the noise at the band's ends and
    // biases the fit: select again on time, where the first fit is inside the band.
    let mut dq = Quad::default();
    for j in range.clone() {
        let t = s.probe_t[j] - t_ref;
        let f = c1[0] + c1[1] * t + c1[2] * t * t;
        if f >= lo && f <= hi {
            let d = s.probe[j];
            dq.add(t, d[0] * n.x + d[1] * n.y + d[2] * n.z);
        }
    }
    let (c, inv_p, ssr_p) = dq.fit()?;
    // Zero of the quadratic nearest the end of the band where δ → 0 (Newton from the line's root).
    let t_end = if forward { t_last - t_ref } else { t_first - t_ref };
    let mut t0 = if c[1] != 0.0 { -c[0] / c[1] } else { t_end };
    for _ in 0..20 {
        let f = c[0] + c[1] * t0 + c[2] * t0 * t0;
        let df = c[1] + 2.0 * c[2] * t0;
        if df == 0.0 {
            return None;
        }
        let step = f / df;
        t0 -= step;
        if step.abs() < 1e-15 {
            break;
        }
    }
    let slope0 = c[1] + 2.0 * c[2] * t0;
    if !t0.is_finite() || (t0 - t_end).abs() > (t_last - t_first).abs() + 0.05 {
        return None;
    }
    let row0 = nalgebra::Vector3::new(1.0, t0, t0 * t0);
    // Per unit probe sigma: the sigma is pooled over all contacts. A per-contact residual sigma
    // (14 degrees of freedom) makes the weights of the joint fit scatter by ±40 % and, where
    // the stylus signal departs a little from the quadratic, correlate with the point's error:
    // on the plates that biased the delay by −7 µs (probe noise alone).
    let u_t0 = (row0.dot(&(inv_p * row0))).max(0.0).sqrt() / slope0.abs();
    // Machine samples on the same side of the machine's own turnaround, from x_hi over twice
    // the band's length along the normal.
    let span = (t_last - t_first).abs().max(1e-6);
    let along = |i: usize| {
        let m = s.machine[i];
        m[0] * n.x + m[1] * n.y + m[2] * n.z
    };
    let c0 = s.machine_t.partition_point(|&t| t < t_first.min(t_last) - span - 0.02);
    let c1 = s.machine_t.partition_point(|&t| t <= t_first.max(t_last) + span + 0.02).min(s.machine_t.len());
    if c1 <= c0 + 4 {
        return None;
    }
    let turn = (c0..c1).min_by(|&i, &j| along(i).total_cmp(&along(j)))?;
    let band_len = (hi - lo).abs();
    // Symmetric about the zero-deflection position x_hi + hi, clear of the turnaround.
    let bottom = x_hi + MARGIN * hi;
    let top = x_hi + (2.0 - MARGIN) * hi;
    let w1 = s.machine_t.partition_point(|&t| t <= t_first.max(t_last) + 10.0 * span + 0.05);
    let w0 = s.machine_t.partition_point(|&t| t < t_first.min(t_last) - 10.0 * span - 0.05);
    let keep = |i: &usize| along(*i) >= bottom && along(*i) <= top;
    let stop = |i: &usize| along(*i) <= top + 0.5 * band_len;
    let idx: Vec<usize> = if forward {
        (turn..w1.max(turn)).take_while(stop).filter(keep).collect()
    } else {
        (w0.min(turn)..=turn).rev().take_while(stop).filter(keep).collect()
    };
    if idx.len() < 5 {
        return None;
    }
    // As for the probe: select on time where a first fit lies in the window, not on noisy x.
    let mut q1 = Quad::default();
    for &i in &idx {
        q1.add(s.machine_t[i] - t_ref, along(i));
    }
    let (g, _, _) = q1.fit()?;
    let (i_lo, i_hi) = (*idx.iter().min()?, *idx.iter().max()?);
    let pad = 3;
    let idx: Vec<usize> = (i_lo.saturating_sub(pad)..(i_hi + pad + 1).min(s.machine_t.len()))
        .filter(|&i| {
            let t = s.machine_t[i] - t_ref;
            let x = g[0] + g[1] * t + g[2] * t * t;
            x >= bottom && x <= top
        })
        .collect();
    if idx.len() < 5 {
        return None;
    }
    let mut q = [Quad::default(); 3];
    let mut qa = Quad::default();
    for &i in &idx {
        let t = s.machine_t[i] - t_ref;
        for (k, qk) in q.iter_mut().enumerate() {
            qk.add(t, s.machine[i][k]);
        }
        qa.add(t, along(i));
    }
    let mut p = [0.0; 3];
    let mut v = [0.0; 3];
    for k in 0..3 {
        let (ck, _, _) = q[k].fit()?;
        p[k] = ck[0] + ck[1] * t0 + ck[2] * t0 * t0;
        v[k] = ck[1] + 2.0 * ck[2] * t0;
    }
    let (_, inv_m, ssr_m) = qa.fit()?;
    let lev = row0.dot(&(inv_m * row0)).max(0.0).sqrt();
    let vn = Vector3::new(v[0], v[1], v[2]).dot(n);
    Some(Band {
        point: Point3::new(p[0], p[1], p[2]),
        unit: lev,
        u_time: u_t0 * vn.abs(),
        ssr_p,
        dof_p: dq.n - 3.0,
        ssr: ssr_m,
        dof: qa.n - 3.0,
        velocity: Vector3::new(v[0], v[1], v[2]),
        n_used: idx.len(),
        defl_domain: DeflDomain::default(),
    })
}

/// True when the position samples `(t, x)` move at constant speed to within 0.5 % (or the
/// change is not significant against the noise).
fn constant_speed(tx: &[(f64, f64)]) -> bool {
    if tx.len() < 6 {
        return true;
    }
    let n = tx.len() as f64;
    let mt = tx.iter().map(|p| p.0).sum::<f64>() / n;
    // Normal equations of x = a + b·τ + c·τ², τ = t − mean.
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut r = nalgebra::Vector3::<f64>::zeros();
    for &(t, x) in tx {
        let u = t - mt;
        let row = nalgebra::Vector3::new(1.0, u, u * u);
        m += row * row.transpose();
        r += row * x;
    }
    let Some(inv) = m.try_inverse() else { return true };
    let c = inv * r;
    let ssr: f64 = tx
        .iter()
        .map(|&(t, x)| {
            let u = t - mt;
            (x - c[0] - c[1] * u - c[2] * u * u).powi(2)
        })
        .sum();
    let s2 = ssr / (n - 3.0).max(1.0);
    let span = tx[tx.len() - 1].0 - tx[0].0;
    let dv = 2.0 * c[2] * span;
    let u_dv = 2.0 * span * (s2 * inv[(2, 2)]).max(0.0).sqrt();
    dv.abs() <= 0.005 * c[1].abs() || dv.abs() <= 2.0 * u_dv
}

/// The deepest sample of a run along `n`: (index, deflection).
fn deepest(probe: &[[f64; 3]], start: usize, end: usize, n: &Vector3) -> (usize, f64) {
    let (mut peak, mut pd) = (start, f64::NEG_INFINITY);
    for (j, d) in probe.iter().enumerate().take(end).skip(start) {
        let v = d[0] * n.x + d[1] * n.y + d[2] * n.z;
        if v > pd {
            pd = v;
            peak = j;
        }
    }
    (peak, pd)
}

/// The surface normal of a touch, free of friction to first order: the mean of the unit
/// deflection directions of the approach and of the retract, each over the samples between the
/// threshold and 60 % of the peak. With friction the tip drags sideways against the motion, one
/// way going in and the other coming out (and holds whatever it had while the machine dwells), so
/// the direction of the whole run leans off the normal (4° for the virtual cell's in-plane 30°
/// approaches, 9° for the vertical one) while the two halves lean off it by about as much on
/// opposite sides. `None` when either half has no sample in that range.
pub fn touch_normal(
    probe: &[[f64; 3]],
    start: usize,
    peak: usize,
    end: usize,
    rough: &Vector3,
    lo: f64,
) -> Option<Vector3> {
    let (_, pd) = deepest(probe, start, end, rough);
    let hi = 0.6 * pd;
    let mean_dir = |r: std::ops::Range<usize>| -> Option<Vector3> {
        let mut acc = Vector3::zeros();
        for d in &probe[r] {
            let v = Vector3::new(d[0], d[1], d[2]);
            let a = v.dot(rough);
            if a >= lo && a <= hi {
                acc += v / v.norm();
            }
        }
        let n = acc.norm();
        (n > 0.0).then(|| acc / n)
    };
    let sum = mean_dir(start..peak)? + mean_dir(peak..end)?;
    let n = sum.norm();
    (n > 0.0).then(|| sum / n)
}

/// Extract every contact (touch) from the streams: segmentation, normal, phases, extrapolation
/// to zero deflection (retract preferred, approach as fallback). `mi` is the machine position
/// at the probe stamps ([`crate::stream::machine_at`] with shift 0 for raw data). Runs whose
/// deflection direction turns by more than `max_turn` rad (scans) are skipped.
pub fn extract_contacts(s: &Streams, mi: &[[f64; 3]], opt: &ContactOptions, max_turn: f64) -> Vec<Contact> {
    let mut out = Vec::new();
    let mut pooled = (0.0, 0.0);
    let mut pooled_p = (0.0, 0.0);
    let mut pooled_d = (0.0, 0.0);
    let mut u_times = Vec::new();
    for (start, end) in find_runs(s.probe, opt.threshold, opt.min_band) {
        let Some(n) = run_normal(s.probe, start, end) else { continue };
        if run_turn(s.probe, start, end, &n) > max_turn {
            continue;
        }
        let lo = opt.threshold;
        let (peak, _) = deepest(s.probe, start, end, &n);
        let n = touch_normal(s.probe, start, peak, end, &n, lo).unwrap_or(n);
        let (peak, pd) = deepest(s.probe, start, end, &n);
        let retract = extrapolate(s, mi, &n, peak..end, lo, pd, opt, true);
        let approach = extrapolate(s, mi, &n, start..peak + 1, lo, pd, opt, false);
        let approach_velocity = approach.as_ref().map(|b| b.velocity);
        let (band, phase) = match (retract, approach) {
            (Some(b), _) => (b, Phase::Retract),
            (None, Some(b)) => (b, Phase::Approach),
            (None, None) => continue,
        };
        pooled.0 += band.ssr;
        pooled.1 += band.dof;
        pooled_d.0 += band.defl_domain.ssr;
        pooled_d.1 += band.defl_domain.dof;
        pooled_p.0 += band.ssr_p;
        pooled_p.1 += band.dof_p;
        u_times.push(band.u_time);
        out.push(Contact {
            start,
            peak,
            end,
            t_peak: s.probe_t[peak],
            normal: n,
            peak_deflection: pd,
            point: band.point,
            u_point: band.unit,
            point_defl: band.defl_domain.point,
            u_point_defl: band.defl_domain.unit,
            velocity: band.velocity,
            approach_velocity,
            phase,
            n_used: band.n_used,
        });
    }
    // The residual scatter of one short band is a poor estimate of the noise: pool it over all
    // contacts (same encoders, same probe), then scale each contact's leverage.
    let sigma = if pooled.1 > 0.0 { (pooled.0 / pooled.1).sqrt() } else { 0.0 };
    // Exact data would give zero uncertainty and infinite weights: floor at 1 nm.
    let sigma = sigma.max(1e-6);
    let sigma_p = if pooled_p.1 > 0.0 { (pooled_p.0 / pooled_p.1).sqrt() } else { 0.0 };
    let sigma_d = if pooled_d.1 > 0.0 { (pooled_d.0 / pooled_d.1).sqrt() } else { 0.0 }.max(1e-6);
    for (c, ut) in out.iter_mut().zip(&u_times) {
        c.u_point = (c.u_point * sigma).hypot(*ut * sigma_p);
        c.u_point_defl *= sigma_d;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stream::machine_at;

    /// A body moving along −x into a plane at x = 0 (outward normal +x), turning round at depth
    /// 0.2 mm and leaving at the same speed; the machine data lags by `delay`.
    type Streams4 = (Vec<f64>, Vec<[f64; 3]>, Vec<f64>, Vec<[f64; 3]>);

    pub(crate) fn touch(delay: f64, speed: f64) -> Streams4 {
        let depth = 0.2;
        let start = 0.5; // body starts 0.5 mm off the surface
        let t_turn = (start + depth) / speed;
        let body = |t: f64| start - speed * (t_turn - (t - t_turn).abs()) * 1.0 - 0.0 * t;
        let body = move |t: f64| if t < 0.0 { start } else { body(t).min(start) };
        let tend = 2.0 * t_turn;
        let mt: Vec<f64> = (0..=(tend * 2000.0) as usize).map(|i| i as f64 / 2000.0).collect();
        // Machine stamp T holds the position of instant T − delay.
        let m: Vec<[f64; 3]> = mt.iter().map(|&t| [body(t - delay), 1.0, 2.0]).collect();
        let pt: Vec<f64> = (0..=(tend * 5000.0) as usize).map(|i| i as f64 / 5000.0).collect();
        let p: Vec<[f64; 3]> = pt.iter().map(|&t| [(-body(t)).max(0.0), 0.0, 0.0]).collect();
        (mt, m, pt, p)
    }

    #[test]
    fn extrapolation_of_exact_ramps_gives_the_delay_shifted_point() {
        // With machine lag D, the retract point (moving away, +x at speed v) appears at −D·v,
        // the approach point at +D·v (exact: both streams are piecewise linear).
        for (delay, speed) in [(0.0, 10.0), (2e-4, 10.0), (-3e-4, 25.0)] {
            let (mt, m, pt, p) = touch(delay, speed);
            let s = Streams { machine_t: &mt, machine: &m, probe_t: &pt, probe: &p };
            let mut mi = Vec::new();
            machine_at(&mt, &m, &pt, 0.0, &mut mi);
            let c = extract_contacts(&s, &mi, &ContactOptions::default(), 0.5);
            assert_eq!(c.len(), 1);
            let c = &c[0];
            assert_eq!(c.phase, Phase::Retract);
            assert!((c.normal - Vector3::x()).norm() < 1e-12);
            assert!((c.velocity.x - speed).abs() < 1e-6, "{:?}", c.velocity);
            // Interpolation of a linear ramp is exact; the tolerance is rounding.
            assert!((c.point.x - (-delay * speed)).abs() < 1e-9, "{} vs {}", c.point.x, -delay * speed);
            assert!((c.point.y - 1.0).abs() < 1e-9 && (c.point.z - 2.0).abs() < 1e-9);
            assert!((c.corrected([delay; 3]).x).abs() < 1e-9);
            assert!((c.approach_velocity.unwrap().x + speed).abs() < 1e-6);
        }
    }

    #[test]
    fn runs_ignore_short_spikes() {
        let mut p = vec![[0.0; 3]; 100];
        p[10] = [0.01, 0.0, 0.0];
        for d in &mut p[40..60] {
            *d = [0.0, -0.02, 0.0];
        }
        assert_eq!(find_runs(&p, 0.005, 3), vec![(40, 60)]);
        assert!((run_normal(&p, 40, 60).unwrap() + Vector3::y()).norm() < 1e-15);
        // A reversal between two samples (ringing after a release) without a sample below the
        // threshold splits the run, so the touch is not taken for a turning scan.
        let mut p = vec![[0.0; 3]; 100];
        for d in &mut p[20..50] {
            *d = [0.02, 0.0, 0.0];
        }
        for d in &mut p[50..56] {
            *d = [-0.008, 0.0, 0.0];
        }
        assert_eq!(find_runs(&p, 0.005, 4), vec![(20, 50)]);
        assert!(run_turn(&p, 20, 50, &Vector3::x()) < 1e-12);
    }
}
