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
    /// Classic settle: longest wait for the deflection to settle, s.
    pub max_settle_wait: f64,
    /// Duration of the blend between a segment's end and the next one's start, s.
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
    /// Time since the start of the run, s.
    pub t: f64,
    /// Measured tip centre (machine scale + probe deflection).
    pub position: Point3,
    /// Commanded probe position.
    pub commanded: Point3,
    /// |measured deflection|.
    pub deflection: f64,
    /// Planned deflection at this instant.
    pub target: f64,
    /// The kind of segment the sample is on.
    pub segment: SegmentKind,
    /// Index of the feature the sample belongs to.
    pub feature: usize,
    /// Quality code of the sample: 0, 5 or 9 (see `Params::quality_bands`).
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
    /// The feature's id.
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
    /// Time of contact, s.
    pub contact_t: f64,
    /// Time the scan segment started, s.
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
    /// Number of samples on the scan segment.
    pub scan_points: usize,
    /// Share of scan points with quality 0.
    pub quality0_share: f64,
}

/// Result of [`execute`].
#[derive(Clone, Debug)]
pub struct Run {
    /// Every sample, in time order.
    pub points: Vec<Point>,
    /// Per feature, in plan order.
    pub features: Vec<FeatureRun>,
    /// Duration of the whole run, s.
    pub cycle_time: f64,
    /// Number of times the machine stood still between the first and the last feature.
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
///
/// Each control tick: `Exec::enter` the current segment, `Exec::command` the tip centre,
/// the machine follows and measures (`Exec::record`), then either the first contact of an
/// approach re-plans the feature (`Exec::touch`) or the plan advances (`Exec::advance`).
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
    let dt = machine.control_period_s();
    if !(dt.is_finite() && dt > 0.0) {
        return Err(ScanError::Parameter("control_dt_s", dt));
    }
    let nf = plan.features.len();
    let first = plan.segments[0].eval(0.0, &plan.features[plan.segments[0].feature], p.tip_radius);
    machine.begin(first.position, p.tip_radius)?;
    let max_ticks = ((plan.duration()
        + nf as f64
            * (control.max_settle_wait + 2.0 * control.search_limit / p.touch_speed.min(p.scan_speed))
        + 10.0)
        / dt) as usize;
    let mut ex = Exec::new(plan, control, dt);
    for _tick in 0..max_ticks {
        ex.enter();
        let (c, n, target, speed) = ex.command();
        let seg = &plan.segments[ex.i];
        let touchable = seg.kind != SegmentKind::Transfer;
        let sample =
            machine.follow(&ScanCommand { tip_center_mm: c, feature: touchable.then_some(seg.feature) })?;
        ex.t += dt;
        let defl = ex.record(sample.scale_mm, sample.deflection_mm, c, target, speed);
        let in_approach =
            seg.kind == SegmentKind::Approach && seg.contact_time.is_some() && !ex.contacted[seg.feature];
        if in_approach && defl > control.contact_threshold {
            ex.touch(c, n, sample.scale_mm + sample.deflection_mm);
            continue;
        }
        if ex.advance(n, defl, target, in_approach)? {
            break;
        }
    }
    if ex.i < plan.segments.len() {
        return Err(ScanError::Invalid("execution did not finish (internal time limit)".into()));
    }
    if ex.halt_pending {
        if let Some(last) = ex.points.last_mut() {
            last.halted = true;
        }
    }
    let cycle_time = ex.t;
    let stops = count_stops(&ex.points);
    let features = summarise(plan, &ex.points, &ex.shift, &ex.contact_t)?;
    Ok(Run { points: ex.points, features, cycle_time, stops })
}

/// The state of a running [`execute`].
struct Exec<'a> {
    plan: &'a Plan,
    control: &'a ControlParams,
    /// Control period (s).
    dt: f64,
    /// Current segment and the time into it (s).
    i: usize,
    tau: f64,
    mode: Mode,
    /// The current feature's correction along its normal (mm).
    e_n: f64,
    blend: Blend,
    last_n: Vector3,
    settled_for: f64,
    /// Machine time (s).
    t: f64,
    entered: usize,
    halt_pending: bool,
    points: Vec<Point>,
    contacted: Vec<bool>,
    shift: Vec<f64>,
    contact_t: Vec<f64>,
}

impl<'a> Exec<'a> {
    fn new(plan: &'a Plan, control: &'a ControlParams, dt: f64) -> Exec<'a> {
        let nf = plan.features.len();
        let est = (plan.duration() / dt * 1.1) as usize + 16;
        Exec {
            plan,
            control,
            dt,
            i: 0,
            tau: 0.0,
            mode: Mode::Plan,
            e_n: 0.0,
            blend: Blend { o0: Vector3::zeros(), tb: 0.0, dur: 1.0 },
            last_n: Vector3::z(),
            settled_for: 0.0,
            t: 0.0,
            entered: usize::MAX,
            halt_pending: false,
            points: Vec::with_capacity(est),
            contacted: vec![false; nf],
            shift: vec![0.0; nf],
            contact_t: vec![f64::NAN; nf],
        }
    }

    /// On entering a segment: a transfer takes over the feature's correction as a blend that
    /// fades during it.
    fn enter(&mut self) {
        if self.entered == self.i {
            return;
        }
        self.entered = self.i;
        let seg = &self.plan.segments[self.i];
        if seg.kind == SegmentKind::Transfer && (self.e_n != 0.0 || self.blend.o0.norm() > 0.0) {
            let o = self.blend.at(self.t) + self.last_n * self.e_n;
            self.e_n = 0.0;
            self.blend = Blend { o0: o, tb: self.t, dur: seg.duration().clamp(0.05, 0.3) };
        }
        self.settled_for = 0.0;
    }

    /// The commanded tip centre, the surface normal, the target deflection and the path speed.
    fn command(&mut self) -> (Point3, Vector3, f64, f64) {
        let seg = &self.plan.segments[self.i];
        let f = &self.plan.features[seg.feature];
        let (base, n, target, speed) = match &self.mode {
            Mode::Plan => {
                let c = seg.eval(self.tau, f, self.plan.params.tip_radius);
                (c.position, c.normal.unwrap_or(self.last_n), c.deflection, c.speed)
            }
            Mode::Bend { p, n0, speed, .. } => (*p, *n0, 0.0, *speed),
        };
        self.last_n = n;
        (base + n * self.e_n + self.blend.at(self.t), n, target, speed)
    }

    /// Store the tick's measured point; its deflection (mm).
    fn record(&mut self, xm: Point3, qm: Vector3, c: Point3, target: f64, speed: f64) -> f64 {
        let seg = &self.plan.segments[self.i];
        let defl = qm.norm();
        self.points.push(Point {
            t: self.t,
            position: xm + qm,
            commanded: c,
            deflection: defl,
            target,
            segment: seg.kind,
            feature: seg.feature,
            quality: quality(defl - target, self.plan.params.quality_bands),
            speed,
            halted: speed <= 1e-9 || self.halt_pending,
        });
        self.halt_pending = false;
        defl
    }

    /// The first contact of an approach at commanded `c` (normal `n`), the measured tip centre
    /// `measured`: the feature's surface offset is found and the plan continues from the
    /// contact, the jump blended out.
    fn touch(&mut self, c: Point3, n: Vector3, measured: Point3) {
        let (plan, control, dt) = (self.plan, self.control, self.dt);
        let p = &plan.params;
        let seg = &plan.segments[self.i];
        let fi = seg.feature;
        let f = &plan.features[fi];
        let nseg = plan.segments.len();
        self.contacted[fi] = true;
        self.contact_t[fi] = self.t;
        let tc = seg.contact_time.unwrap_or(0.0);
        let (ni, nt) = if tc >= seg.duration() - 1e-12 { (self.i + 1, 0.0) } else { (self.i, tc) };
        let nseg_ = &plan.segments[ni.min(nseg - 1)];
        let b = nseg_.eval(nt, f, p.tip_radius);
        let nb = b.normal.unwrap_or(n);
        let o_now = c - b.position;
        // the measured tip centre touches the true surface: the surface's offset from the
        // nominal one along the normal there is the tip centre's distance minus the radius
        self.e_n = f.signed_distance(&measured).0 - p.tip_radius;
        self.shift[fi] = self.e_n;
        // blend the remaining jump out within `blend_time`; when the command is ahead of
        // the plan (late contact) the fade runs against the motion, so it is slowed until
        // it takes at most 3/8 of the path speed (smoothstep peak rate 1.5·|o|/T) and the
        // command never stops
        let o0 = o_now - nb * self.e_n;
        let ahead = nseg_.eval(nt + 1e-3, f, p.tip_radius).position - b.position;
        let v = b.speed.max(p.touch_speed.min(p.scan_speed));
        let dur = if o0.dot(&ahead) > 0.0 {
            control.blend_time.max(4.0 * o0.norm() / v)
        } else {
            control.blend_time
        };
        self.blend = Blend { o0, tb: self.t, dur };
        self.mode = Mode::Plan;
        self.i = ni.min(nseg - 1);
        // advance by this tick so the commanded speed does not stall
        self.tau = nt + dt;
        self.last_n = nb;
    }

    /// Feedback on the deflection, then the next tick's place on the plan (or in the search
    /// bend after an approach that found nothing). `Ok(true)` when the plan is done.
    fn advance(&mut self, n: Vector3, defl: f64, target: f64, in_approach: bool) -> Result<bool, ScanError> {
        let (plan, control, dt) = (self.plan, self.control, self.dt);
        let p = &plan.params;
        let seg = &plan.segments[self.i];
        let f = &plan.features[seg.feature];
        if seg.feedback && self.tau >= seg.feedback_after && matches!(self.mode, Mode::Plan) {
            self.e_n += control.feedback_gain * (defl - target) * dt;
        }
        match &mut self.mode {
            Mode::Bend { p: bp, dir0, n0, tb, travel, speed } => {
                *tb += dt;
                let d = *dir0 + (-*n0 - *dir0) * (1.0 - (-*tb / control.bend_time).exp());
                let d = if d.norm() > 1e-12 { d.normalize() } else { -*n0 };
                *bp += d * (*speed * dt);
                *travel += *speed * dt;
                if *travel > control.search_limit {
                    return Err(ScanError::NoContact { id: f.id.clone(), limit: control.search_limit });
                }
                Ok(false)
            }
            Mode::Plan => {
                self.tau += dt;
                if seg.wait_settled {
                    if (defl - p.deflection).abs() < 0.5 * p.quality_bands[0] {
                        self.settled_for += dt;
                    } else {
                        self.settled_for = 0.0;
                    }
                    if self.settled_for >= control.settle_dwell || self.tau >= control.max_settle_wait {
                        self.tau = 0.0;
                        self.i += 1;
                        self.halt_pending = true;
                    }
                } else if self.tau >= seg.duration() {
                    if in_approach {
                        self.start_bend(n);
                    } else {
                        self.halt_pending |= seg.end_speed() <= 1e-9
                            || plan.segments.get(self.i + 1).is_some_and(|n| n.start_speed() <= 1e-9);
                        self.tau -= seg.duration();
                        self.i += 1;
                    }
                }
                Ok(self.i >= plan.segments.len())
            }
        }
    }

    /// An approach that ended without contact: bend towards the surface and search on.
    fn start_bend(&mut self, n: Vector3) {
        let plan = self.plan;
        let p = &plan.params;
        let seg = &plan.segments[self.i];
        let f = &plan.features[seg.feature];
        let (dir0, n0) = match (&seg.geom, seg.plane) {
            (Geom::Line { a, b }, Some((_, n0))) => ((b - a).normalize(), n0),
            _ => (-n, n),
        };
        let speed = if plan.style == Style::Blended { p.scan_speed } else { p.touch_speed };
        // carry the part of the tick beyond the approach end into the bend
        let end = seg.eval(seg.duration(), f, p.tip_radius).position
            + n * self.e_n
            + dir0 * (speed * (self.tau - seg.duration()));
        self.mode = Mode::Bend { p: end, dir0, n0, tb: 0.0, travel: 0.0, speed };
        self.e_n = 0.0;
        self.halt_pending |= seg.end_speed() <= 1e-9;
    }
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
