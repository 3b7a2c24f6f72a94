//! The audit trail: every block sent, measurement, correction and alarm. The loop reports to
//! an [`AuditSink`]; the binary stores events in SQLite (transactionally, so a crash loses
//! nothing committed). [`MemoryAudit`] keeps them in memory (tests, reports).

use truepos_math::{Point3, Vector3};

/// One auditable event.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A program block sent to the controller.
    Block {
        /// 1-based program line.
        line: usize,
        /// The block as sent.
        text: String,
        /// Time since the start of the run, s.
        time_s: f64,
    },
    /// A tracker measurement at a stop.
    Measurement {
        /// 1-based program line of the stop.
        line: usize,
        /// Correction iteration (0: before any correction).
        iteration: usize,
        /// Commanded position, part frame, mm.
        commanded_mm: Point3,
        /// Measured (fused) position, part frame, mm.
        measured_mm: Point3,
        /// Length of measured − commanded, mm.
        error_mm: f64,
        /// Standard deviation of the readings averaged, mm.
        samples_std_mm: f64,
        /// Time since the start of the run, s.
        time_s: f64,
    },
    /// A correction sent to the controller.
    Correction {
        /// 1-based program line of the stop.
        line: usize,
        /// Correction iteration.
        iteration: usize,
        /// This correction, mm.
        delta_mm: Vector3,
        /// The total offset after it, mm.
        offset_mm: Vector3,
        /// Whether the correction was limited to the largest allowed.
        clipped: bool,
        /// Time since the start of the run, s.
        time_s: f64,
    },
    /// An alarm.
    Alarm {
        /// 1-based program line.
        line: usize,
        /// What kind of alarm.
        kind: crate::run::AlarmKind,
        /// What happened.
        message: String,
        /// What the loop did about it.
        action: String,
        /// Time since the start of the run, s.
        time_s: f64,
    },
    /// A real-time orientation of the part.
    Orientation {
        /// 1-based program line.
        line: usize,
        /// Why it was done.
        reason: String,
        /// The fitted scale (1 without scale).
        scale: f64,
        /// RMS residual of the orientation, mm.
        rms_mm: f64,
        /// Time since the start of the run, s.
        time_s: f64,
    },
    /// The trackers' refractive index changed.
    RefractiveIndex {
        /// 1-based program line.
        line: usize,
        /// The index before.
        old: f64,
        /// The index after.
        new: f64,
        /// Time since the start of the run, s.
        time_s: f64,
    },
    /// The result of a stop.
    StopResult {
        /// 1-based program line of the stop.
        line: usize,
        /// `SUCCESS`, `PARTIAL` or `FAILURE`.
        status: String,
        /// Length of measured − commanded of the last reading, mm.
        final_error_mm: f64,
        /// Correction iterations made.
        iterations: usize,
        /// Time since the start of the run, s.
        time_s: f64,
    },
}

/// Why an audit sink could not store an event (the storage's own error, kept as the cause).
pub type SinkError = Box<dyn std::error::Error + Send + Sync>;

/// Receives events as they happen. `commit` marks the end of a unit of work (a stop).
pub trait AuditSink {
    /// Store one event.
    fn record(&mut self, event: &Event) -> Result<(), SinkError>;
    /// End a unit of work (a stop): what was recorded since the last commit is kept for good.
    fn commit(&mut self) -> Result<(), SinkError> {
        Ok(())
    }
}

/// Events in memory.
#[derive(Debug, Default)]
pub struct MemoryAudit {
    /// The events recorded, in order.
    pub events: Vec<Event>,
}

impl AuditSink for MemoryAudit {
    fn record(&mut self, event: &Event) -> Result<(), SinkError> {
        self.events.push(event.clone());
        Ok(())
    }
}
