//! Execution of a [`Plan`] on a scanning machine (`truepos_device::ScanningMachine`, driven at
//! its control rate): the command along the plan, the probe feedback (observer) that holds the
//! target deflection, contact detection and the missed-surface behaviour, quality marks and the
//! per-feature evaluation.
//!
//! Entry points: [`execute`] with a machine and the [`ControlParams`]; it returns a [`Run`]:
//! measured points tagged by segment and feature with deflection and quality mark, per-feature
//! results (time, form error, contact shift, vibration at scan start) and the summary (cycle
//! time, stops). The virtual CMM (servo and stylus dynamics on the true part) is
//! `truepos_plant::scanning_cmm`.
//!
//! Missed surfaces: contact is detected on the approach when the measured deflection exceeds
//! `contact_threshold`. Early contact (surface before the nominal point) moves the plan on to its
//! nominal contact instant and shifts the rest of the feature's path along the surface normal by
//! where contact was made; the tangential part of the jump is blended out smoothly over
//! `blend_time`. Late contact: when the approach reaches the nominal contact point without
//! contact, the path bends along a logarithmic blend (direction `w + (−N − w)(1 − e^{−τ/τ_b})`)
//! towards the nominal surface normal at the same speed until contact (or `search_limit`).

use crate::feature::Params;
use crate::plan::{Geom, Plan, SegmentKind, Style};
use crate::ScanError;
use truepos_device::{ScanCommand, ScanningMachine};
use truepos_math::{Point3, Vector3};

/// The scanning control's own settings (the machine's are its backend's).
#[derive(Clone, Debug, PartialEq)]
pub struct ControlParams {
    /// Observer gain (1/s): normal path correction rate per mm of deflection error.
    pub feedback_gain: f64,
    /// Deflection (mm) that counts as contact on an approach.
    pub contact_threshold: f64,
    /// How far beyond the nominal contact point a late contact is searched (mm).
    pub search_limit: f64,
    /// Classic settle: time the deflection must stay inside half the first band.
    pub settle_dwell: f64,
    pub max_settle_wait: f64,
    pub blend_time: f64,
    /// Time constant of the late-contact bend (s).
    pub bend_time: f64,
}

impl Default for ControlParams {
    fn default() -> Self {
        ControlParams {
            feedback_gain: 60.0,
            contact_threshold: 0.01,
            search_limit: 8.0,
            settle_dwell: 0.05,
            max_settle_wait: 3.0,
            blend_time: 0.1,
            bend_time: 0.05,
        }
    }
}

impl ControlParams {
    /// Every setting finite and in range; the error names the file key.
    pub fn check(&self) -> Result<(), ScanError> {
        let pos = [
            ("contact_threshold_mm", self.contact_threshold),
            ("search_limit_mm", self.search_limit),
            ("blend_time_s", self.blend_time),
            ("bend_time_s", self.bend_time),
        ];
        for (n, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(ScanError::Parameter(n, v));
            }
        }
        let nonneg = [
            ("feedback_gain", self.feedback_gain),
            ("settle_dwell_s", self.settle_dwell),
            ("max_settle_wait_s", self.max_settle_wait),
        ];
        for (n, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ScanError::Parameter(n, v));
            }
        }
        Ok(())
    }
}

/// One measured (and commanded) sample.
#[derive(Clone, Copy, Debug)]
pub struct Point {
    pub t: f64,
    /// Measured tip centre (machine scale + probe deflection).
    pub position: Point3,
    /// Commanded probe position.
    pub commanded: Point3,
    /// |measured deflection|.
    pub deflection: f64,
    /// Planned deflection at this instant.
    pub target: f64,
    pub segment: SegmentKind,
    pub feature: usize,
    pub quality: u8,
    /// Commanded path speed (without the observer's corrections).
    pub speed: f64,
    /// The commanded path speed was zero at some instant of this tick (a hold, or a segment
    /// boundary where the speed profile reaches zero).
    pub halted: bool,
}

/// Per-feature outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureRun {
    pub id: String,
    /// From the start of its approach to the end of its release.
    pub time: f64,
    /// Peak-to-valley of the residuals of the least-squares element fitted to the scan segment.
    /// NaN when the scan segment cannot determine it (see `form_note`).
    pub form_error: f64,
    /// Why the form error is not available (too few scan points, degenerate fit).
    pub form_note: Option<String>,
    /// Shift of the path along the surface normal where contact was made (+: surface before
    /// the nominal point).
    pub contact_shift: f64,
    pub contact_t: f64,
    pub scan_start_t: f64,
    /// RMS of deflection − target over the first 50 ms of the scan.
    pub vibration_rms: f64,
    /// Peak |deflection − target| over the first 50 ms of the scan.
    pub vibration_peak: f64,
    /// From contact until the deflection follows the planned deflection within half the first
    /// quality band for 50 ms.
    pub settle_time: f64,
    /// From contact to the start of the scan segment.
    pub ready_time: f64,
    pub scan_points: usize,
    /// Share of scan points with quality 0.
    pub quality0_share: f64,
}

/// Result of [`execute`].
#[derive(Clone, Debug)]
pub struct Run {
    pub points: Vec<Point>,
    pub features: Vec<FeatureRun>,
    pub cycle_time: f64,
    pub stops: usize,
}

/// Longest program (machine time, s) [`execute`] accepts.
pub const MAX_MACHINE_TIME: f64 = 1.0e5;

/// Quality mark from |deflection − target| and the two bands.
pub fn quality(err: f64, bands: [f64; 2]) -> u8 {
    let e = err.abs();
    if e <= bands[0] {
        0
    } else if e <= bands[1] {
        5
    } else {
        9
    }
}

enum Mode {
    Plan,
    Bend { p: Point3, dir0: Vector3, n0: Vector3, tb: f64, travel: f64, speed: f64 },
}

struct Blend {
    o0: Vector3,
    tb: f64,
    dur: f64,
}

impl Blend {
    fn at(&self, t: f64) -> Vector3 {
        let x = ((t - self.tb) / self.dur).clamp(0.0, 1.0);
        self.o0 * (1.0 - x * x * (3.0 - 2.0 * x))
    }
}

/// Run `plan` on `machine` at its control rate. Deterministic when the machine is.
pub fn execute<M: ScanningMachine + ?Sized>(
    plan: &Plan,
    machine: &mut M,
    control: &ControlParams,
) -> Result<Run, ScanError> {
    control.check()?;
    let dur = plan.duration();
    if !(dur.is_finite() && dur <= MAX_MACHINE_TIME) {
        return Err(ScanError::Invalid(format!(
            "the program takes {dur:.3e} s of machine time; at most {MAX_MACHINE_TIME} s can be simulated"
        )));
    }
    let p: &Params = &plan.params;
    let tip = p.tip_radius;
    let dt = machine.control_period_s();
    if !(dt.is_finite() && dt > 0.0) {
        return Err(ScanError::Parameter("control_dt_s", dt));
    }

    let nseg = plan.segments.len();
    let nf = plan.features.len();
    let est = (plan.duration() / dt * 1.1) as usize + 16;
    let mut points: Vec<Point> = Vec::with_capacity(est);
    let mut contacted = vec![false; nf];
    let mut shift = vec![0.0; nf];
    let mut contact_t = vec![f64::NAN; nf];

    let (mut i, mut tau) = (0usize, 0.0f64);
    let mut mode = Mode::Plan;
    let mut e_n = 0.0;
    let mut blend = Blend { o0: Vector3::zeros(), tb: 0.0, dur: 1.0 };
    let mut last_n = Vector3::z();
    let mut settled_for = 0.0;
    let first = plan.segments[0].eval(0.0, &plan.features[plan.segments[0].feature], tip);
    machine.begin(first.position, tip)?;
    let mut t = 0.0;
    let max_ticks = ((plan.duration()
        + nf as f64
            * (control.max_settle_wait + 2.0 * control.search_limit / p.touch_speed.min(p.scan_speed))
        + 10.0)
        / dt) as usize;
    let mut entered = usize::MAX;
    let mut halt_pending = false;

    for _tick in 0..max_ticks {
        let seg = &plan.segments[i];
        let fi = seg.feature;
        let f = &plan.features[fi];
        if entered != i {
            entered = i;
            if seg.kind == SegmentKind::Transfer && (e_n != 0.0 || blend.o0.norm() > 0.0) {
                // hand the feature's correction over to a blend that fades during the transfer
                let o = blend.at(t) + last_n * e_n;
                e_n = 0.0;
                blend = Blend { o0: o, tb: t, dur: seg.duration().clamp(0.05, 0.3) };
            }
            settled_for = 0.0;
        }
        // 1. command
        let (base, n, target, speed) = match &mode {
            Mode::Plan => {
                let c = seg.eval(tau, f, tip);
                (c.position, c.normal.unwrap_or(last_n), c.deflection, c.speed)
            }
            Mode::Bend { p, n0, speed, .. } => (*p, *n0, 0.0, *speed),
        };
        last_n = n;
        let c = base + n * e_n + blend.at(t);
        // 2. the machine follows the command over the tick and measures
        let touchable = seg.kind != SegmentKind::Transfer;
        let sample = machine.follow(&ScanCommand { tip_center_mm: c, feature: touchable.then_some(fi) })?;
        t += dt;
        // 3. measure
        let (xm, qm) = (sample.scale_mm, sample.deflection_mm);
        let defl = qm.norm();
        points.push(Point {
            t,
            position: xm + qm,
            commanded: c,
            deflection: defl,
            target,
            segment: seg.kind,
            feature: fi,
            quality: quality(defl - target, p.quality_bands),
            speed,
            halted: speed <= 1e-9 || halt_pending,
        });
        halt_pending = false;
        // 4. logic
        let in_approach = seg.kind == SegmentKind::Approach && seg.contact_time.is_some() && !contacted[fi];
        if in_approach && defl > control.contact_threshold {
            contacted[fi] = true;
            contact_t[fi] = t;
            let tc = seg.contact_time.unwrap_or(0.0);
            let (ni, nt) = if tc >= seg.duration() - 1e-12 { (i + 1, 0.0) } else { (i, tc) };
            let nseg_ = &plan.segments[ni.min(nseg - 1)];
            let b = nseg_.eval(nt, f, tip);
            let nb = b.normal.unwrap_or(n);
            let o_now = c - b.position;
            // the measured tip centre touches the true surface: the surface's offset from the
            // nominal one along the normal there is the tip centre's distance minus the radius
            e_n = f.signed_distance(&(xm + qm)).0 - tip;
            shift[fi] = e_n;
            // blend the remaining jump out within `blend_time`; when the command is ahead of
            // the plan (late contact) the fade runs against the motion, so it is slowed until
            // it takes at most 3/8 of the path speed (smoothstep peak rate 1.5·|o|/T) and the
            // command never stops
            let o0 = o_now - nb * e_n;
            let ahead = nseg_.eval(nt + 1e-3, f, tip).position - b.position;
            let v = b.speed.max(p.touch_speed.min(p.scan_speed));
            let dur = if o0.dot(&ahead) > 0.0 {
                control.blend_time.max(4.0 * o0.norm() / v)
            } else {
                control.blend_time
            };
            blend = Blend { o0, tb: t, dur };
            mode = Mode::Plan;
            i = ni.min(nseg - 1);
            // advance by this tick so the commanded speed does not stall
            tau = nt + dt;
            last_n = nb;
            continue;
        }
        if seg.feedback && tau >= seg.feedback_after && matches!(mode, Mode::Plan) {
            e_n += control.feedback_gain * (defl - target) * dt;
        }
        match &mut mode {
            Mode::Bend { p: bp, dir0, n0, tb, travel, speed } => {
                *tb += dt;
                let d = *dir0 + (-*n0 - *dir0) * (1.0 - (-*tb / control.bend_time).exp());
                let d = if d.norm() > 1e-12 { d.normalize() } else { -*n0 };
                *bp += d * (*speed * dt);
                *travel += *speed * dt;
                if *travel > control.search_limit {
                    return Err(ScanError::NoContact { id: f.id.clone(), limit: control.search_limit });
                }
            }
            Mode::Plan => {
                tau += dt;
                if seg.wait_settled {
                    if (defl - p.deflection).abs() < 0.5 * p.quality_bands[0] {
                        settled_for += dt;
                    } else {
                        settled_for = 0.0;
                    }
                    if settled_for >= control.settle_dwell || tau >= control.max_settle_wait {
                        tau = 0.0;
                        i += 1;
                        halt_pending = true;
                    }
                } else if tau >= seg.duration() {
                    if in_approach {
                        let (dir0, n0) = match (&seg.geom, seg.plane) {
                            (Geom::Line { a, b }, Some((_, n0))) => ((b - a).normalize(), n0),
                            _ => (-n, n),
                        };
                        let speed = if plan.style == Style::Blended { p.scan_speed } else { p.touch_speed };
                        // carry the part of the tick beyond the approach end into the bend
                        let end = seg.eval(seg.duration(), f, tip).position
                            + n * e_n
                            + dir0 * (speed * (tau - seg.duration()));
                        mode = Mode::Bend { p: end, dir0, n0, tb: 0.0, travel: 0.0, speed };
                        e_n = 0.0;
                        halt_pending |= seg.end_speed() <= 1e-9;
                    } else {
                        halt_pending |= seg.end_speed() <= 1e-9
                            || plan.segments.get(i + 1).is_some_and(|n| n.start_speed() <= 1e-9);
                        tau -= seg.duration();
                        i += 1;
                    }
                }
                if i >= nseg {
                    break;
                }
            }
        }
    }
    if i < nseg {
        return Err(ScanError::Invalid("execution did not finish (internal time limit)".into()));
    }
    if halt_pending {
        if let Some(last) = points.last_mut() {
            last.halted = true;
        }
    }
    let cycle_time = t;
    let stops = count_stops(&points);
    let features = summarise(plan, &points, &shift, &contact_t)?;
    Ok(Run { points, features, cycle_time, stops })
}

/// Runs of zero commanded path speed between the first approach and the last release.
pub fn count_stops(points: &[Point]) -> usize {
    let a = points.iter().position(|q| q.segment == SegmentKind::Approach);
    let b = points.iter().rposition(|q| q.segment == SegmentKind::Release);
    let (Some(a), Some(b)) = (a, b) else { return 0 };
    let mut n = 0;
    let mut stopped = false;
    for q in &points[a..=b] {
        let z = q.halted;
        if z && !stopped {
            n += 1;
        }
        stopped = z;
    }
    n
}

fn summarise(
    plan: &Plan,
    pts: &[Point],
    shift: &[f64],
    contact_t: &[f64],
) -> Result<Vec<FeatureRun>, ScanError> {
    let p = &plan.params;
    let nf = plan.features.len();
    let mut spans = vec![(usize::MAX, 0usize); nf];
    for (k, q) in pts.iter().enumerate() {
        if q.segment != SegmentKind::Transfer {
            let s = &mut spans[q.feature];
            s.0 = s.0.min(k);
            s.1 = s.1.max(k);
        }
    }
    let mut out = Vec::with_capacity(nf);
    for (fi, f) in plan.features.iter().enumerate() {
        let (a, b) = spans[fi];
        if a == usize::MAX {
            return Err(ScanError::Invalid(format!("feature '{}' was not executed", f.id)));
        }
        let seg = &pts[a..=b];
        let scan: Vec<&Point> = seg.iter().filter(|q| q.segment == SegmentKind::Scan).collect();
        let xyz: Vec<Point3> = scan.iter().map(|q| q.position).collect();
        let (form_error, form_note) = match crate::form::form_error(f, &xyz) {
            Ok(v) => (v, None),
            Err(e) => (f64::NAN, Some(e.to_string())),
        };
        let t0 = scan.first().map_or(f64::NAN, |q| q.t);
        let first: Vec<f64> =
            scan.iter().take_while(|q| q.t < t0 + 0.05).map(|q| q.deflection - p.deflection).collect();
        let vibration_rms = (first.iter().map(|x| x * x).sum::<f64>() / first.len().max(1) as f64).sqrt();
        let vibration_peak = first.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        // settle time: first instant after contact from which 50 ms stay inside band 1
        let tc = contact_t[fi];
        let after: Vec<&Point> = seg
            .iter()
            .filter(|q| {
                q.t >= tc
                    && matches!(q.segment, SegmentKind::Approach | SegmentKind::Settle | SegmentKind::Scan)
            })
            .collect();
        let mut settle_time = f64::NAN;
        let mut run_start: Option<f64> = None;
        for q in &after {
            if (q.deflection - p.deflection).abs() <= p.quality_bands[0] {
                let s = *run_start.get_or_insert(q.t);
                if q.t - s >= 0.05 {
                    settle_time = s - tc;
                    break;
                }
            } else {
                run_start = None;
            }
        }
        let q0 = scan.iter().filter(|q| q.quality == 0).count();
        out.push(FeatureRun {
            id: f.id.clone(),
            time: pts[b].t - pts[a].t,
            form_error,
            form_note,
            contact_shift: shift[fi],
            contact_t: tc,
            scan_start_t: t0,
            vibration_rms,
            vibration_peak,
            settle_time,
            ready_time: t0 - tc,
            scan_points: scan.len(),
            quality0_share: q0 as f64 / scan.len().max(1) as f64,
        });
    }
    Ok(out)
}
