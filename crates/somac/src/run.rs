//! The measure / compare / correct loop ([`run_program`]).
//!
//! For every block of the program (fed one at a time): check the alarms at measurement blocks
//! (temperature range → stop; temperature change or inclination change → new orientation; the
//! part temperature moved by the auto-scale step → re-scale), update the trackers' refractive
//! index when it has drifted, send the block, and at keyword blocks: wait for a stable reading
//! (repeated samples within the standard-deviation limit; beam breaks recovered as configured),
//! fuse the trackers, compare with the commanded position, and correct incrementally until the
//! error is within the threshold or the iteration limit is reached. No correction move is longer
//! than the single limit and the accumulated offset never exceeds the total limit (a clip raises
//! an alarm). Each stop ends SUCCESS (within threshold), PARTIAL (measured and corrected but not
//! within threshold: iterations exhausted or a limit reached) or FAILURE (no stable reading, beam
//! not recovered, or the run halted).

use crate::audit::{AuditSink, Event};
use crate::device::{Cell, Controller, DeviceError, Inclinations, Tracker};
use crate::fusion::{fuse, Reading};
use crate::params::{BeamRecovery, Params};
use thiserror::Error;
use truepos_gcode::{Program, TransformOptions};
use truepos_math::air::{refractive_index, Formula};
use truepos_math::bestfit::{best_fit, BestFitOptions};
use truepos_math::{Point3, Transform3, Vector3};

pub use truepos_device::TrackerSetup;

/// The outcome of one stop of the control loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopStatus {
    /// The stop reached its tolerance.
    Success,
    /// The stop was corrected but did not reach its tolerance.
    Partial,
    /// The stop could not be measured or corrected.
    Failure,
}

impl StopStatus {
    /// The status as the audit trail and JSON spell it (`SUCCESS`, `PARTIAL`, `FAILURE`).
    pub fn as_str(self) -> &'static str {
        match self {
            StopStatus::Success => "SUCCESS",
            StopStatus::Partial => "PARTIAL",
            StopStatus::Failure => "FAILURE",
        }
    }
}

/// What happened at one stop of the control loop.
#[derive(Debug, Clone, PartialEq)]
pub struct StopReport {
    /// 1-based program line.
    pub line: usize,
    /// Commanded position (machine frame, after orientation), without the correction offset.
    pub commanded_mm: Point3,
    /// Last fused reading, if any.
    pub measured_mm: Option<Point3>,
    /// The corrections sent, in order, mm.
    pub corrections: Vec<Vector3>,
    /// Correction iterations made.
    pub iterations: usize,
    /// |measured − commanded| of the last reading (NaN when there was none).
    pub final_error_mm: f64,
    /// The outcome.
    pub status: StopStatus,
    /// Why, when not a success.
    pub message: Option<String>,
}

/// What an alarm is about. Its string form ([`AlarmKind::as_str`]) is the `kind` of the JSON
/// output and of the audit trail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AlarmKind {
    /// The part temperature left its allowed range: the run stops.
    TemperatureRange,
    /// The part temperature changed by more than the limit since the last orientation: re-orient.
    TemperatureChange,
    /// The inclinometers moved by more than the limit: re-align the trackers and re-orient.
    Inclination,
    /// The scale from the part targets disagrees with the part's CTE and temperature.
    ScaleDiscrepancy,
    /// Real-time orientation on the part targets failed.
    OrientationFailed,
    /// Re-aligning a tracker on the machine targets failed.
    AlignmentFailed,
    /// No tracker sees the reflector; recovered automatically or by the operator (the stop's
    /// status says whether a reading came back).
    BeamBreak,
    /// No stable reading at a measurement stop.
    NoReading,
    /// A correction move was clipped to the single-correction limit.
    MaxSingleCorrection,
    /// The accumulated correction reached the total limit.
    MaxTotalCorrection,
    /// A commanded or corrected position would leave the machine's travel.
    TravelLimit,
    /// The controller failed (e-stop, lost connection, an error it reports): the run is aborted
    /// and the stop in progress marked FAILURE.
    ControllerFault,
}

impl AlarmKind {
    /// Every kind.
    pub const ALL: [AlarmKind; 12] = [
        AlarmKind::TemperatureRange,
        AlarmKind::TemperatureChange,
        AlarmKind::Inclination,
        AlarmKind::ScaleDiscrepancy,
        AlarmKind::OrientationFailed,
        AlarmKind::AlignmentFailed,
        AlarmKind::BeamBreak,
        AlarmKind::NoReading,
        AlarmKind::MaxSingleCorrection,
        AlarmKind::MaxTotalCorrection,
        AlarmKind::TravelLimit,
        AlarmKind::ControllerFault,
    ];

    /// The name in the JSON output and the audit trail (`temperature_range`, `beam_break`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            AlarmKind::TemperatureRange => "temperature_range",
            AlarmKind::TemperatureChange => "temperature_change",
            AlarmKind::Inclination => "inclination",
            AlarmKind::ScaleDiscrepancy => "scale_discrepancy",
            AlarmKind::OrientationFailed => "orientation_failed",
            AlarmKind::AlignmentFailed => "alignment_failed",
            AlarmKind::BeamBreak => "beam_break",
            AlarmKind::NoReading => "no_reading",
            AlarmKind::MaxSingleCorrection => "max_single_correction",
            AlarmKind::MaxTotalCorrection => "max_total_correction",
            AlarmKind::TravelLimit => "travel_limit",
            AlarmKind::ControllerFault => "controller_fault",
        }
    }

    /// The kind of a name from [`AlarmKind::as_str`].
    pub fn parse(name: &str) -> Option<AlarmKind> {
        AlarmKind::ALL.into_iter().find(|k| k.as_str() == name)
    }

    /// Whether the alarm makes the run's outcome "alarm fired" (exit code 1). A beam break does
    /// not: it is recovered (automatically or by the operator) and a stop that got no reading
    /// back is marked FAILURE on its own.
    pub fn fails_run(self) -> bool {
        self != AlarmKind::BeamBreak
    }
}

impl std::fmt::Display for AlarmKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// An alarm raised during a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Alarm {
    /// 1-based program line.
    pub line: usize,
    /// What kind of alarm.
    pub kind: AlarmKind,
    /// What happened.
    pub message: String,
    /// What the loop did about it.
    pub action: String,
}

/// What a run of the control loop did.
#[derive(Debug, Clone, PartialEq)]
pub struct RunReport {
    /// Every stop, in program order.
    pub stops: Vec<StopReport>,
    /// Every alarm, in order.
    pub alarms: Vec<Alarm>,
    /// The run stopped before the end of the program (a stop alarm).
    pub halted: bool,
    /// Number of real-time orientations.
    pub orientations: usize,
    /// Number of refractive index updates.
    pub refractive_updates: usize,
    /// The last orientation: part frame to machine frame (mm).
    pub machine_from_part: Transform3,
    /// Number of program blocks sent.
    pub blocks_sent: usize,
}

impl RunReport {
    /// The run did not do its job: it halted, a stop did not succeed, or an alarm that fails a
    /// run fired (exit code 1).
    pub fn failed(&self) -> bool {
        self.verdict().verdict != RunOutcome::Pass
    }

    /// The run's verdict with every reason: `fail` when it halted or a stop is not SUCCESS;
    /// `alarm` when every stop succeeded but an alarm that needs a person's review fired
    /// (recovered or not: the contract's "an alarm fired", exit code 1); `pass` otherwise. Every
    /// alarm is a reason, recovered beam breaks too (they alone do not change the verdict).
    pub fn verdict(&self) -> RunVerdict {
        let mut reasons = Vec::new();
        if self.halted {
            reasons.push("the run halted before the end of the program".to_string());
        }
        for s in self.stops.iter().filter(|s| s.status != StopStatus::Success) {
            reasons.push(format!(
                "line {}: stop {}{}",
                s.line,
                s.status.as_str(),
                s.message.as_deref().map(|m| format!(" ({m})")).unwrap_or_default()
            ));
        }
        let bad_stops = !reasons.is_empty();
        for a in &self.alarms {
            reasons.push(format!(
                "line {}: {} alarm — {} ({}){}",
                a.line,
                a.kind.as_str(),
                a.message,
                a.action,
                if a.kind.fails_run() { "" } else { "; recovered, does not fail the run" }
            ));
        }
        let alarm = self.alarms.iter().any(|a| a.kind.fails_run());
        let verdict = if bad_stops {
            RunOutcome::Fail
        } else if alarm {
            RunOutcome::Alarm
        } else {
            RunOutcome::Pass
        };
        if reasons.is_empty() {
            reasons.push(format!("all {} stops SUCCESS, no alarm", self.stops.len()));
        }
        RunVerdict { verdict, reasons }
    }
}

/// The outcome of a run ([`RunReport::verdict`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunOutcome {
    /// Every stop SUCCESS, no alarm that needs review: exit code 0, audit status SUCCESS.
    Pass,
    /// Every stop SUCCESS, but an alarm fired (e.g. an inclination alarm, recovered by
    /// re-aligning): exit code 1, audit status ALARM.
    Alarm,
    /// The run halted or a stop is not SUCCESS: exit code 1, audit status FAILURE.
    Fail,
}

impl RunOutcome {
    /// The JSON `verdict`: `pass`, `alarm` or `fail`.
    pub fn as_str(self) -> &'static str {
        match self {
            RunOutcome::Pass => "pass",
            RunOutcome::Alarm => "alarm",
            RunOutcome::Fail => "fail",
        }
    }

    /// The audit trail's final run status for this outcome.
    pub fn audit_status(self) -> &'static str {
        match self {
            RunOutcome::Pass => "SUCCESS",
            RunOutcome::Alarm => "ALARM",
            RunOutcome::Fail => "FAILURE",
        }
    }
}

/// A run's verdict and its reasons (never empty).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunVerdict {
    /// The verdict.
    pub verdict: RunOutcome,
    /// Why, as sentences.
    pub reasons: Vec<String>,
}

/// Why a run of the control loop could not go on.
#[derive(Debug, Error)]
pub enum RunError {
    /// The parameters are invalid (why).
    #[error("invalid parameters: {0}")]
    Params(String),
    /// The controller or a tracker failed.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// A program line cannot be run.
    #[error("line {line}: {message}")]
    Program {
        /// 1-based program line.
        line: usize,
        /// Why.
        message: String,
    },
    /// The audit trail could not store an event (its storage's error is the source).
    #[error("audit trail")]
    Audit(#[source] crate::audit::SinkError),
}

/// The loop's devices, settings and audit trail, with its state: what every step of
/// [`run_program`] works on.
struct Loop<'a, C, T, E> {
    /// The program as given (part coordinates); [`State::program`] is its oriented version.
    original: &'a Program,
    ctl: &'a mut C,
    trackers: &'a mut [TrackerSetup<T>],
    cell: &'a mut E,
    params: &'a Params,
    sink: &'a mut dyn AuditSink,
    st: State,
}

/// What changes during a run.
struct State {
    machine_from_part: Transform3,
    program: Program,
    /// Per line of `program`: the commanded target (mm) and whether it is a measurement stop.
    targets: Vec<(Option<Point3>, bool)>,
    temp_orient: f64,
    temp_scale: f64,
    incl_base: Inclinations,
    n_air: f64,
    last_measured: Option<(Point3, Point3)>,
    report: RunReport,
}

/// Run `program` (in part coordinates) on the controller with the trackers.
pub fn run_program<C: Controller, T: Tracker, E: Cell>(
    program: &Program,
    ctl: &mut C,
    trackers: &mut [TrackerSetup<T>],
    cell: &mut E,
    params: &Params,
    sink: &mut dyn AuditSink,
) -> Result<RunReport, RunError> {
    params.validate().map_err(RunError::Params)?;
    if trackers.is_empty() {
        return Err(RunError::Params("at least one tracker is needed".into()));
    }
    program.check().map_err(|e| RunError::Program { line: e.line(), message: e.detail() })?;
    let t0 = cell.temperature_c();
    let n0 = refractive_index(&cell.air(), Formula::Ciddor).map_err(|e| RunError::Params(e.to_string()))?;
    for t in trackers.iter_mut() {
        t.tracker.set_refractive_index(n0);
    }
    let st = State {
        machine_from_part: Transform3::identity(),
        program: program.clone(),
        targets: index_targets(program, &params.keyword),
        temp_orient: t0,
        temp_scale: t0,
        incl_base: cell.inclinations(),
        n_air: n0,
        last_measured: None,
        report: RunReport {
            stops: vec![],
            alarms: vec![],
            halted: false,
            orientations: 0,
            refractive_updates: 0,
            machine_from_part: Transform3::identity(),
            blocks_sent: 0,
        },
    };
    Loop { original: program, ctl, trackers, cell, params, sink, st }.run()
}

impl<C: Controller, T: Tracker, E: Cell> Loop<'_, C, T, E> {
    /// Record an event in the audit trail.
    fn audit(&mut self, e: Event) -> Result<(), RunError> {
        self.sink.record(&e).map_err(RunError::Audit)
    }

    /// The program, block by block, with the checks at every measurement stop.
    fn run(mut self) -> Result<RunReport, RunError> {
        if self.params.orient && self.cell.part_nominal().len() >= 3 {
            self.orient(0, "initial orientation")?;
        }
        let mut n_stops = 0usize;
        for i in 0..self.st.program.lines.len() {
            let line = i + 1;
            let is_stop = self.st.targets[i].1;
            if is_stop {
                // Alarms and environment, checked at every measurement stop.
                let temp = self.cell.temperature_c();
                if temp < self.params.temperature_min_c || temp > self.params.temperature_max_c {
                    self.alarm(
                        line,
                        AlarmKind::TemperatureRange,
                        format!(
                            "part temperature {temp:.2} °C outside {}–{} °C",
                            self.params.temperature_min_c, self.params.temperature_max_c
                        ),
                        "stop",
                    )?;
                    self.st.report.halted = true;
                    break;
                }
                let realigned = self.check_inclination(line, "")?;
                if realigned {
                    // Re-aligned and re-oriented just now.
                } else if (temp - self.st.temp_orient).abs() > self.params.temperature_change_max_c {
                    let message = format!(
                        "temperature changed by {:.2} °C since the last orientation (limit {})",
                        temp - self.st.temp_orient,
                        self.params.temperature_change_max_c
                    );
                    self.alarm(line, AlarmKind::TemperatureChange, message, "re-orient")?;
                    self.orient(line, "temperature change")?;
                } else if (temp - self.st.temp_scale).abs() >= self.params.autoscale_step_c {
                    self.orient(line, "auto-scale (temperature step)")?;
                } else if self.params.orient_every > 0
                    && n_stops > 0
                    && n_stops.is_multiple_of(self.params.orient_every)
                {
                    self.orient(line, "periodic orientation")?;
                }
                let n_new = refractive_index(&self.cell.air(), Formula::Ciddor)
                    .map_err(|e| RunError::Params(e.to_string()))?;
                if ((n_new - self.st.n_air) / self.st.n_air).abs() * 1e6 > self.params.refractive_update_ppm {
                    self.audit(Event::RefractiveIndex {
                        line,
                        old: self.st.n_air,
                        new: n_new,
                        time_s: self.ctl.now_s(),
                    })?;
                    for t in self.trackers.iter_mut() {
                        t.tracker.set_refractive_index(n_new);
                    }
                    self.st.n_air = n_new;
                    self.st.report.refractive_updates += 1;
                }
            }
            // The program may have been re-transformed: take the block again.
            let target = self.st.targets[i].0;
            if let Some(t) = target.filter(|t| !self.params.within_travel(&(t + self.ctl.offset()))) {
                self.alarm(
                    line,
                    AlarmKind::TravelLimit,
                    format!(
                        "the block commands ({:.3}, {:.3}, {:.3}) mm, outside the machine's travel",
                        t.x, t.y, t.z
                    ),
                    "stop",
                )?;
                self.st.report.halted = true;
                break;
            }
            self.ctl.send_block(line, self.st.program.line_text(i), target)?;
            self.st.report.blocks_sent += 1;
            self.audit(Event::Block {
                line,
                text: self.st.program.line_text(i).to_string(),
                time_s: self.ctl.now_s(),
            })?;
            if is_stop {
                let mut commanded = target.unwrap_or_else(Point3::origin);
                let mut stop = self.measure_stop(line, commanded)?;
                // An inclinometer that moved during the stop invalidates its readings: re-align,
                // re-orient, go to the (re-oriented) position and measure the stop again.
                if self.check_inclination(line, " during the stop")? {
                    commanded = self.st.targets[i].0.unwrap_or(commanded);
                    self.ctl.move_to(commanded)?;
                    stop = self.measure_stop(line, commanded)?;
                }
                self.audit(Event::StopResult {
                    line,
                    status: stop.status.as_str().into(),
                    final_error_mm: stop.final_error_mm,
                    iterations: stop.iterations,
                    time_s: self.ctl.now_s(),
                })?;
                self.sink.commit().map_err(RunError::Audit)?;
                self.st.report.stops.push(stop);
                n_stops += 1;
            }
        }
        self.sink.commit().map_err(RunError::Audit)?;
        self.st.report.machine_from_part = self.st.machine_from_part;
        Ok(self.st.report)
    }

    /// If an inclinometer moved beyond the limit since the last orientation: alarm, re-align the
    /// trackers on the machine targets, re-orient the part. Returns whether it did.
    fn check_inclination(&mut self, line: usize, when: &str) -> Result<bool, RunError> {
        let incl = self.cell.inclinations();
        let dincl = incl.max_change(&self.st.incl_base);
        if dincl <= self.params.inclination_limit_urad {
            return Ok(false);
        }
        self.alarm(
            line,
            AlarmKind::Inclination,
            format!(
                "inclination changed by {dincl:.1} µrad{when} (limit {})",
                self.params.inclination_limit_urad
            ),
            "re-align trackers and re-orient",
        )?;
        self.realign(line)?;
        self.st.incl_base = incl;
        self.orient(line, "inclination change")?;
        Ok(true)
    }

    /// Raise an alarm of `kind` at `line`.
    fn alarm(&mut self, line: usize, kind: AlarmKind, message: String, action: &str) -> Result<(), RunError> {
        self.raise(Alarm { line, kind, message, action: action.into() })
    }

    fn raise(&mut self, a: Alarm) -> Result<(), RunError> {
        self.audit(Event::Alarm {
            line: a.line,
            kind: a.kind,
            message: a.message.clone(),
            action: a.action.clone(),
            time_s: self.ctl.now_s(),
        })?;
        self.st.report.alarms.push(a);
        Ok(())
    }

    /// Real-time orientation (and scale) of the part from its targets; re-transforms the program.
    fn orient(&mut self, line: usize, reason: &str) -> Result<(), RunError> {
        if !self.params.orient {
            return Ok(());
        }
        let nominal = self.cell.part_nominal();
        let mut from = vec![];
        let mut to = vec![];
        // Each tracker measures the targets it sees; each target is fused over those trackers.
        let seen: Vec<Vec<(String, Point3)>> =
            (0..self.trackers.len()).map(|k| self.cell.measure_part_targets(k)).collect();
        for (id, p_nom) in &nominal {
            let mut rs = vec![];
            for (k, t) in self.trackers.iter().enumerate() {
                if let Some((_, p)) = seen[k].iter().find(|(i, _)| i == id) {
                    rs.push(Reading { p: t.machine_from_tracker.apply(p), sigma_mm: t.tracker.sigma_mm(p) });
                }
            }
            if let Some(f) = fuse(&rs) {
                from.push(*p_nom);
                to.push(f.p);
            }
        }
        let temp = self.cell.temperature_c();
        let fit = best_fit(&from, &to, None, BestFitOptions { with_scale: self.params.orient_with_scale });
        match fit {
            Ok(t) => {
                let res: Vec<f64> = from.iter().zip(&to).map(|(f, p)| (t.apply(f) - p).norm()).collect();
                let rms = truepos_math::stats::rms(&res);
                let expected = 1.0 + self.params.part_cte_ppm_per_c * 1e-6 * (temp - 20.0);
                let disc_ppm = (t.scale / expected - 1.0) * 1e6;
                if self.params.orient_with_scale && disc_ppm.abs() > 100.0 {
                    self.alarm(
                        line,
                        AlarmKind::ScaleDiscrepancy,
                        format!(
                            "fitted scale {:.6} differs from the CTE expectation {:.6} by {disc_ppm:.0} ppm",
                            t.scale, expected
                        ),
                        "continue (check the part temperature and CTE)",
                    )?;
                }
                self.st.machine_from_part = t;
                self.st.program = Program::parse(
                    &self
                        .original
                        .transform(&t, &TransformOptions::default())
                        .map_err(|e| RunError::Program { line: e.line(), message: e.detail() })?,
                );
                self.st.targets = index_targets(&self.st.program, &self.params.keyword);
                self.st.temp_orient = temp;
                self.st.temp_scale = temp;
                self.st.report.orientations += 1;
                self.audit(Event::Orientation {
                    line,
                    reason: reason.into(),
                    scale: t.scale,
                    rms_mm: rms,
                    time_s: self.ctl.now_s(),
                })?;
            }
            Err(e) => {
                self.alarm(
                    line,
                    AlarmKind::OrientationFailed,
                    format!("{reason}: {} targets measured: {e}", to.len()),
                    "keep the previous orientation",
                )?;
            }
        }
        Ok(())
    }

    /// Re-align every tracker to the machine from the machine's reference targets.
    fn realign(&mut self, line: usize) -> Result<(), RunError> {
        let reference = self.cell.machine_targets();
        for k in 0..self.trackers.len() {
            let seen = self.cell.measure_machine_targets(k);
            match machine_from_tracker(&seen, &reference) {
                Ok(m) => self.trackers[k].machine_from_tracker = m,
                Err(e) => {
                    self.alarm(
                        line,
                        AlarmKind::AlignmentFailed,
                        format!("tracker {k}: {e}"),
                        "keep the previous alignment",
                    )?;
                }
            }
        }
        Ok(())
    }

    /// One stable, fused reading (machine frame) and the largest sample standard deviation.
    fn read(&mut self, line: usize, commanded: Point3) -> Result<Result<(Point3, f64), String>, RunError> {
        self.ctl.wait(self.params.dwell_s);
        let mut recoveries = 0;
        let mut attempt = 0;
        while attempt < self.params.stable_attempts {
            let mut readings = vec![];
            let mut worst_std = 0.0f64;
            let mut any = false;
            let mut unstable = false;
            let mut lost = vec![];
            for (k, t) in self.trackers.iter_mut().enumerate() {
                let mut samples = Vec::with_capacity(self.params.samples);
                for _ in 0..self.params.samples {
                    match t.tracker.measure() {
                        Ok(p) => samples.push(p),
                        Err(_) => {
                            samples.clear();
                            break;
                        }
                    }
                }
                if samples.len() < self.params.samples {
                    lost.push(k);
                    continue;
                }
                any = true;
                let n = samples.len() as f64;
                let mean = samples.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
                let mut var = Vector3::zeros();
                for p in &samples {
                    let d = p.coords - mean;
                    var += d.component_mul(&d);
                }
                let std = (var / (n - 1.0)).map(f64::sqrt).max();
                worst_std = worst_std.max(std);
                if std > self.params.stable_std_mm {
                    unstable = true;
                    continue;
                }
                let p_t = Point3::from(mean);
                readings.push(Reading {
                    p: t.machine_from_tracker.apply(&p_t),
                    sigma_mm: t.tracker.sigma_mm(&p_t) / n.sqrt(),
                });
            }
            if !any {
                // Every beam broken: recover as configured.
                recoveries += 1;
                if recoveries > 4 {
                    return Ok(Err("beam broken on every tracker and not recovered".into()));
                }
                if recoveries == 4 && self.params.beam_recovery != BeamRecovery::Manual {
                    // The automatic strategy failed three times: call the operator.
                    self.alarm(
                        line,
                        AlarmKind::BeamBreak,
                        "automatic recovery failed".into(),
                        "manual recovery",
                    )?;
                    for k in 0..self.trackers.len() {
                        self.cell.operator_restores_beam(k);
                    }
                    self.ctl.wait(30.0);
                    continue;
                }
                self.alarm(
                    line,
                    AlarmKind::BeamBreak,
                    "no tracker sees the reflector".into(),
                    &match self.params.beam_recovery {
                        BeamRecovery::LookAhead if !self.trackers.iter().any(|t| t.tracker.has_adm()) => {
                            "manual recovery (look-ahead needs an absolute distance meter)".into()
                        }
                        s => format!("{s:?} recovery").to_lowercase(),
                    },
                )?;
                self.recover(commanded)?;
                continue;
            }
            if !readings.is_empty() && !unstable {
                let f = fuse(&readings).map(|r| r.p).unwrap_or(commanded);
                // Trackers that lost the beam while others measured: reacquire by pointing (ADM).
                for k in lost {
                    let t = &mut self.trackers[k];
                    if t.tracker.has_adm() {
                        let p = t.machine_from_tracker.inverse().apply(&f);
                        let _ = t.tracker.point_at(p);
                    }
                }
                return Ok(Ok((f, worst_std)));
            }
            if !readings.is_empty() && readings.len() == self.trackers.len() {
                let f = fuse(&readings).map(|r| r.p).unwrap_or(commanded);
                return Ok(Ok((f, worst_std)));
            }
            attempt += 1;
            self.ctl.wait(self.params.settle_wait_s);
        }
        Ok(Err(format!(
            "the reading never became stable within {} attempts (σ limit {} mm)",
            self.params.stable_attempts, self.params.stable_std_mm
        )))
    }

    fn recover(&mut self, commanded: Point3) -> Result<(), RunError> {
        let target = commanded + self.ctl.offset();
        for (k, t) in self.trackers.iter_mut().enumerate() {
            let tracker_from_machine = t.machine_from_tracker.inverse();
            let strategy = match self.params.beam_recovery {
                BeamRecovery::LookAhead if !t.tracker.has_adm() => BeamRecovery::Manual,
                s => s,
            };
            match strategy {
                BeamRecovery::Manual => {
                    self.cell.operator_restores_beam(k);
                    self.ctl.wait(30.0);
                }
                BeamRecovery::LookAhead => {
                    let _ = t.tracker.point_at(tracker_from_machine.apply(&target));
                }
                BeamRecovery::LookBack => {
                    if let Some((cmd, measured)) = self.st.last_measured {
                        self.ctl.move_to(cmd)?;
                        let _ = t.tracker.point_at(tracker_from_machine.apply(&measured));
                        self.ctl.move_to(commanded)?;
                    } else {
                        self.cell.operator_restores_beam(k);
                        self.ctl.wait(30.0);
                    }
                }
            }
        }
        Ok(())
    }

    fn measure_stop(&mut self, line: usize, commanded: Point3) -> Result<StopReport, RunError> {
        let mut stop = StopReport {
            line,
            commanded_mm: commanded,
            measured_mm: None,
            corrections: vec![],
            iterations: 0,
            final_error_mm: f64::NAN,
            status: StopStatus::Failure,
            message: None,
        };
        let mut limited = false;
        loop {
            let (m, std) = match self.read(line, commanded)? {
                Ok(r) => r,
                Err(msg) => {
                    self.alarm(line, AlarmKind::NoReading, msg.clone(), "stop marked FAILURE")?;
                    stop.message = Some(msg);
                    stop.status = StopStatus::Failure;
                    return Ok(stop);
                }
            };
            let e = m - commanded;
            stop.measured_mm = Some(m);
            stop.final_error_mm = e.norm();
            self.audit(Event::Measurement {
                line,
                iteration: stop.iterations,
                commanded_mm: commanded,
                measured_mm: m,
                error_mm: e.norm(),
                samples_std_mm: std,
                time_s: self.ctl.now_s(),
            })?;
            if e.norm() <= self.params.threshold_mm {
                self.st.last_measured = Some((commanded, m));
                stop.status = StopStatus::Success;
                return Ok(stop);
            }
            if !self.params.correct {
                self.st.last_measured = Some((commanded, m));
                stop.status = StopStatus::Partial;
                stop.message = Some("corrections disabled".into());
                return Ok(stop);
            }
            if stop.iterations >= self.params.max_iterations || limited {
                stop.status = StopStatus::Partial;
                stop.message = Some(if limited {
                    "correction limited".into()
                } else {
                    "iteration limit reached".into()
                });
                return Ok(stop);
            }
            // A tracker that moved since the last alignment (an inclinometer says so) made this
            // reading wrong: send no correction from it. The caller re-aligns the trackers,
            // re-orients and measures the stop again (a bumped tracker at 5 m tilted by 120 µrad
            // would otherwise send a 0.6 mm correction and then have to undo it).
            if self.cell.inclinations().max_change(&self.st.incl_base) > self.params.inclination_limit_urad {
                stop.status = StopStatus::Partial;
                stop.message =
                    Some("a tracker moved during the stop: reading discarded, no correction sent".into());
                return Ok(stop);
            }
            // The correction: −e, clipped to the single limit and to the total limit.
            let mut delta = -e;
            let mut clipped = false;
            if delta.norm() > self.params.max_single_correction_mm {
                delta *= self.params.max_single_correction_mm / delta.norm();
                clipped = true;
                self.alarm(
                    line,
                    AlarmKind::MaxSingleCorrection,
                    format!(
                        "correction of {:.3} mm clipped to {} mm",
                        e.norm(),
                        self.params.max_single_correction_mm
                    ),
                    "clip",
                )?;
            }
            let offset = self.ctl.offset();
            let new_offset = offset + delta;
            if new_offset.norm() > self.params.max_total_correction_mm {
                // Largest step along delta that keeps |offset + s·delta| within the limit.
                let (a2, b, c) = (
                    delta.norm_squared(),
                    2.0 * offset.dot(&delta),
                    offset.norm_squared() - self.params.max_total_correction_mm.powi(2),
                );
                let disc = (b * b - 4.0 * a2 * c).max(0.0);
                let s = ((-b + disc.sqrt()) / (2.0 * a2)).clamp(0.0, 1.0);
                delta *= s * (1.0 - 1e-12);
                clipped = true;
                limited = true;
                self.alarm(
                    line,
                    AlarmKind::MaxTotalCorrection,
                    format!(
                        "the total correction would reach {:.3} mm (limit {} mm)",
                        new_offset.norm(),
                        self.params.max_total_correction_mm
                    ),
                    "limit and mark PARTIAL",
                )?;
            }
            if delta.norm() == 0.0 {
                stop.status = StopStatus::Partial;
                stop.message = Some("no correction possible within the total limit".into());
                return Ok(stop);
            }
            let corrected = commanded + self.ctl.offset() + delta;
            if !self.params.within_travel(&corrected) {
                self.alarm(
                    line,
                    AlarmKind::TravelLimit,
                    format!(
                        "the corrected position ({:.3}, {:.3}, {:.3}) mm would leave the machine's travel",
                        corrected.x, corrected.y, corrected.z
                    ),
                    "refuse the correction and mark PARTIAL",
                )?;
                stop.status = StopStatus::Partial;
                stop.message = Some("correction would leave the machine's travel".into());
                return Ok(stop);
            }
            self.ctl.correct(delta)?;
            stop.iterations += 1;
            stop.corrections.push(delta);
            self.audit(Event::Correction {
                line,
                iteration: stop.iterations,
                delta_mm: delta,
                offset_mm: self.ctl.offset(),
                clipped,
                time_s: self.ctl.now_s(),
            })?;
        }
    }
}

/// `machine_from_tracker` from a tracker's readings of reference targets (tracker frame) and
/// their calibrated machine-frame positions, matched by id (rigid best fit).
pub fn machine_from_tracker(
    seen: &[(String, Point3)],
    reference: &[(String, Point3)],
) -> Result<Transform3, truepos_math::bestfit::BestFitError> {
    let (mut from, mut to) = (vec![], vec![]);
    for (id, p) in seen {
        if let Some((_, q)) = reference.iter().find(|(i, _)| i == id) {
            from.push(*p);
            to.push(*q);
        }
    }
    best_fit(&from, &to, None, BestFitOptions::default())
}

/// Per line: the commanded target (mm) and whether the line is a measurement stop.
fn index_targets(p: &Program, keyword: &str) -> Vec<(Option<Point3>, bool)> {
    p.blocks().iter().map(|b| (b.target_mm, b.target_mm.is_some() && b.has_keyword(keyword))).collect()
}

impl truepos_math::exit::HasExitClass for RunError {
    /// Bad parameters or program (2); the machine or the audit trail failed (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        match self {
            RunError::Params(_) => ExitClass::Usage,
            RunError::Program { .. } => ExitClass::Input,
            RunError::Device(_) | RunError::Audit(_) => ExitClass::Device,
        }
    }
}
