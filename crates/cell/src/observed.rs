//! A real controller observed by the virtual cell: [`Observed`] drives a real NC (LinuxCNC) and
//! makes the virtual plant follow the real machine's *actual* position, so the virtual trackers
//! measure where the real controller really put the axes, seen through the virtual machine's
//! structure (geometric errors, thermal growth, the tool offset) and the virtual part.
//!
//! Every block, correction and recovery move goes to the real controller; afterwards its actual
//! position (`ProbingMachine::position`, the controlled point) is read and the virtual
//! controller is moved there (it carries no correction offset of its own: the real controller's
//! offset is the one in force). Time is the virtual cell's clock (the virtual trackers sample,
//! settle and drift on it); [`Observed::wait`] lets virtual time pass without holding the real
//! machine. The real wall-clock time of every controller call is kept for reports.
//!
//! Entry points: [`Observed::new`]`(real, virtual_controller)`; [`run_observed`]: the
//! end-point control loop (`truepos somac run --controller …`) on a real controller with the
//! virtual gantry cell's trackers, with the truth of every hole, the wall-clock time of every
//! stop, and a controller failure recorded in the audit trail (alarm `controller_fault`, the
//! stop in progress FAILURE) before it is returned.

use std::collections::BTreeMap;
use std::time::Instant;
use truepos_device::{Controller, DeviceError, ProbingMachine};
use truepos_math::{Point3, Vector3};
use truepos_plant::gantry::{CellConfig, VirtualCell};
use truepos_somac::audit::{AuditSink, Event, SinkError};
use truepos_somac::run::{AlarmKind, RunError};
use truepos_somac::{run_program, Params, RunReport};

/// A real controller whose actual position the virtual cell follows.
pub struct Observed<R, V> {
    real: R,
    virt: V,
    started: Instant,
    /// Wall-clock seconds spent in the real controller, and the number of moves sent.
    pub real_busy_s: f64,
    /// Moves sent to the real controller.
    pub moves: usize,
    /// The program line of the last block sent.
    pub line: usize,
}

impl<R: Controller + ProbingMachine, V: Controller> Observed<R, V> {
    /// Observe `real` with the virtual controller `virt` following its actual position.
    pub fn new(real: R, virt: V) -> Self {
        Observed { real, virt, started: Instant::now(), real_busy_s: 0.0, moves: 0, line: 0 }
    }

    /// The real controller.
    pub fn real(&mut self) -> &mut R {
        &mut self.real
    }

    /// The real controller, giving up the observer.
    pub fn into_real(self) -> R {
        self.real
    }

    /// Wall-clock seconds since [`Observed::new`].
    pub fn wall_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    fn follow(&mut self) -> Result<(), DeviceError> {
        let actual = self.real.position()?;
        self.virt.move_to(actual)
    }

    fn timed<T>(&mut self, f: impl FnOnce(&mut R) -> Result<T, DeviceError>) -> Result<T, DeviceError> {
        let t = Instant::now();
        let r = f(&mut self.real);
        self.real_busy_s += t.elapsed().as_secs_f64();
        r
    }
}

impl<R: Controller + ProbingMachine, V: Controller> Controller for Observed<R, V> {
    fn send_block(&mut self, line: usize, text: &str, target_mm: Option<Point3>) -> Result<(), DeviceError> {
        self.line = line;
        self.timed(|r| Controller::send_block(r, line, text, target_mm))?;
        // The virtual plant's line bookkeeping (which hole is drilled at which line).
        self.virt.send_block(line, text, None)?;
        if target_mm.is_some() {
            self.moves += 1;
            self.follow()?;
        }
        Ok(())
    }

    fn correct(&mut self, delta_mm: Vector3) -> Result<(), DeviceError> {
        self.timed(|r| r.correct(delta_mm))?;
        self.moves += 1;
        self.follow()
    }

    fn offset(&self) -> Vector3 {
        self.real.offset()
    }

    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        self.timed(|r| Controller::move_to(r, target_mm))?;
        self.moves += 1;
        self.follow()
    }

    fn wait(&mut self, seconds: f64) {
        self.virt.wait(seconds);
    }

    fn now_s(&self) -> f64 {
        self.virt.now_s()
    }
}

/// Forwards events and notes the wall-clock time of every stop result.
struct Timing<'a> {
    inner: &'a mut dyn AuditSink,
    t0: Instant,
    stops: Vec<(usize, f64)>,
}

impl AuditSink for Timing<'_> {
    fn record(&mut self, event: &Event) -> Result<(), SinkError> {
        if let Event::StopResult { line, .. } = event {
            self.stops.push((*line, self.t0.elapsed().as_secs_f64()));
        }
        self.inner.record(event)
    }
    fn commit(&mut self) -> Result<(), SinkError> {
        self.inner.commit()
    }
}

/// A run of the loop on a real controller observed by the virtual cell.
pub struct ObservedRun {
    /// The loop's report.
    pub report: RunReport,
    /// True hole errors (mm) per measurement line: where the real controller's actual position
    /// put the drill point through the virtual structure, against the virtual part's hole.
    pub true_errors: Vec<(usize, f64)>,
    /// Wall-clock seconds of each stop (from the previous stop's end, or the start).
    pub stop_wall_s: Vec<(usize, f64)>,
    /// Wall-clock seconds of the whole run.
    pub wall_s: f64,
    /// Virtual-cell time of the run (s).
    pub duration_s: f64,
    /// The machine's volume diagonal, mm.
    pub diagonal_mm: f64,
    /// Moves sent to the real controller.
    pub moves: usize,
}

/// What [`run_observed`] returns when the controller failed: the error, after the audit trail
/// has recorded it; the line it happened at and the stop marked FAILURE.
#[derive(Debug)]
pub struct Aborted {
    /// Why the run stopped.
    pub error: RunError,
    /// 1-based program line where it happened.
    pub line: usize,
    /// The stop marked FAILURE, if one was under way.
    pub stop_line: Option<usize>,
}

/// Run `program_text` on `real` with the virtual gantry cell `cfg` (part `targets`) observing
/// it. A controller failure aborts the run at once (no further motion): the audit trail gets an
/// alarm `controller_fault` with the controller's message and a FAILURE for the stop in progress
/// (the measurement line at or after the failing line), then the error is returned.
pub fn run_observed<R: Controller + ProbingMachine>(
    program_text: &str,
    cfg: CellConfig,
    targets: Vec<(String, Point3)>,
    params: &Params,
    real: R,
    sink: &mut dyn AuditSink,
) -> Result<ObservedRun, Aborted> {
    let fail = |error: RunError| Aborted { error, line: 0, stop_line: None };
    let program = truepos_gcode::Program::parse(program_text);
    let cell = VirtualCell::new(cfg, targets);
    let mut trackers = cell.align_trackers().map_err(|e| {
        fail(RunError::Device(DeviceError::Tracker(
            0,
            format!("aligning the trackers on the machine targets: {e}"),
        )))
    })?;
    let mut ctl = Observed::new(real, cell.controller());
    let mut sensors = cell.sensors();
    let holes: BTreeMap<usize, Point3> = program
        .blocks()
        .iter()
        .filter(|b| b.target_mm.is_some() && b.has_keyword(&params.keyword))
        .filter_map(|b| b.target_mm.map(|t| (b.line + 1, t)))
        .collect();
    let t0 = Instant::now();
    let mut timing = Timing { inner: sink, t0, stops: vec![] };
    let result = run_program(&program, &mut ctl, &mut trackers, &mut sensors, params, &mut timing);
    let report = match result {
        Ok(r) => r,
        Err(error @ RunError::Device(_)) => {
            let line = ctl.line;
            let stop_line = holes.range(line..).next().map(|(l, _)| *l);
            let message = error.to_string();
            let now = ctl.now_s();
            let sink = timing.inner;
            let _ = sink.record(&Event::Alarm {
                line,
                kind: AlarmKind::ControllerFault,
                message,
                action: "run aborted: no further motion".into(),
                time_s: now,
            });
            if let Some(l) = stop_line {
                let _ = sink.record(&Event::StopResult {
                    line: l,
                    status: "FAILURE".into(),
                    final_error_mm: f64::NAN,
                    iterations: 0,
                    time_s: now,
                });
            }
            let _ = sink.commit();
            return Err(Aborted { error, line, stop_line });
        }
        Err(e) => return Err(fail(e)),
    };
    let mut last = 0.0;
    let stop_wall_s = timing
        .stops
        .iter()
        .map(|(l, t)| {
            let d = t - last;
            last = *t;
            (*l, d)
        })
        .collect();
    Ok(ObservedRun {
        report,
        true_errors: cell.hole_errors(&holes),
        stop_wall_s,
        wall_s: t0.elapsed().as_secs_f64(),
        duration_s: cell.time_s(),
        diagonal_mm: cell.diagonal_mm(),
        moves: ctl.moves,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_device::{DeviceInfo, ProbeHit, ProbeRequest};

    /// A "real" controller whose axes end 10 µm short in X of every commanded position.
    #[derive(Default)]
    struct Real {
        cmd: Point3,
        offset: Vector3,
        fail: bool,
    }
    impl Controller for Real {
        fn send_block(&mut self, _: usize, _: &str, t: Option<Point3>) -> Result<(), DeviceError> {
            if self.fail {
                return Err(DeviceError::NotReady { address: "real".into(), reason: "e-stop".into() });
            }
            if let Some(t) = t {
                self.cmd = t + self.offset;
            }
            Ok(())
        }
        fn correct(&mut self, d: Vector3) -> Result<(), DeviceError> {
            self.offset += d;
            self.cmd += d;
            Ok(())
        }
        fn offset(&self) -> Vector3 {
            self.offset
        }
        fn move_to(&mut self, t: Point3) -> Result<(), DeviceError> {
            self.cmd = t + self.offset;
            Ok(())
        }
        fn wait(&mut self, _: f64) {}
        fn now_s(&self) -> f64 {
            0.0
        }
    }
    impl ProbingMachine for Real {
        fn info(&self) -> DeviceInfo {
            DeviceInfo { address: "real".into(), version: "1".into() }
        }
        fn position(&mut self) -> Result<Point3, DeviceError> {
            Ok(self.cmd - Vector3::new(0.01, 0.0, 0.0))
        }
        fn move_to(&mut self, t: Point3) -> Result<(), DeviceError> {
            self.cmd = t;
            Ok(())
        }
        fn probe(&mut self, _: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
            unreachable!()
        }
        fn abort(&mut self) -> Result<(), DeviceError> {
            Ok(())
        }
    }

    /// Records what the virtual plant was told.
    #[derive(Default)]
    struct Virt {
        lines: Vec<usize>,
        at: Vec<Point3>,
        t: f64,
    }
    impl Controller for Virt {
        fn send_block(&mut self, line: usize, _: &str, t: Option<Point3>) -> Result<(), DeviceError> {
            assert!(t.is_none(), "the virtual plant only follows");
            self.lines.push(line);
            Ok(())
        }
        fn correct(&mut self, _: Vector3) -> Result<(), DeviceError> {
            panic!("the virtual plant carries no offset")
        }
        fn offset(&self) -> Vector3 {
            Vector3::zeros()
        }
        fn move_to(&mut self, t: Point3) -> Result<(), DeviceError> {
            self.at.push(t);
            Ok(())
        }
        fn wait(&mut self, s: f64) {
            self.t += s;
        }
        fn now_s(&self) -> f64 {
            self.t
        }
    }

    #[test]
    fn the_virtual_plant_follows_the_real_actual_position() {
        let mut o = Observed::new(Real::default(), Virt::default());
        o.send_block(3, "G0 X1", Some(Point3::new(1.0, 2.0, 3.0))).unwrap();
        o.send_block(4, "M3", None).unwrap();
        o.correct(Vector3::new(0.01, 0.0, 0.0)).unwrap();
        assert_eq!(o.offset(), Vector3::new(0.01, 0.0, 0.0));
        o.wait(2.5);
        assert_eq!(o.now_s(), 2.5);
        assert_eq!(o.virt.lines, vec![3, 4]);
        assert_eq!(o.virt.at.len(), 2);
        assert!((o.virt.at[0] - Point3::new(0.99, 2.0, 3.0)).norm() < 1e-12);
        assert!((o.virt.at[1] - Point3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        assert_eq!((o.moves, o.line), (2, 4));
        // A real failure propagates and the virtual plant does not move.
        o.real().fail = true;
        assert!(o.send_block(5, "G0 X2", Some(Point3::new(2.0, 2.0, 3.0))).is_err());
        assert_eq!(o.virt.at.len(), 2);
    }
}
