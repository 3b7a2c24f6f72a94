//! The audit trail: every block sent, measurement, correction and alarm. The loop reports to
//! an [`AuditSink`]; the binary stores events in SQLite (transactionally, so a crash loses
//! nothing committed). [`MemoryAudit`] keeps them in memory (tests, reports).

use truepos_math::{Point3, Vector3};

/// One auditable event.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    Block {
        line: usize,
        text: String,
        time_s: f64,
    },
    Measurement {
        line: usize,
        iteration: usize,
        commanded_mm: Point3,
        measured_mm: Point3,
        error_mm: f64,
        samples_std_mm: f64,
        time_s: f64,
    },
    Correction {
        line: usize,
        iteration: usize,
        delta_mm: Vector3,
        offset_mm: Vector3,
        clipped: bool,
        time_s: f64,
    },
    Alarm {
        line: usize,
        kind: crate::run::AlarmKind,
        message: String,
        action: String,
        time_s: f64,
    },
    Orientation {
        line: usize,
        reason: String,
        scale: f64,
        rms_mm: f64,
        time_s: f64,
    },
    RefractiveIndex {
        line: usize,
        old: f64,
        new: f64,
        time_s: f64,
    },
    StopResult {
        line: usize,
        status: String,
        final_error_mm: f64,
        iterations: usize,
        time_s: f64,
    },
}

/// Why an audit sink could not store an event (the storage's own error, kept as the cause).
pub type SinkError = Box<dyn std::error::Error + Send + Sync>;

/// Receives events as they happen. `commit` marks the end of a unit of work (a stop).
pub trait AuditSink {
    fn record(&mut self, event: &Event) -> Result<(), SinkError>;
    fn commit(&mut self) -> Result<(), SinkError> {
        Ok(())
    }
}

/// Events in memory.
#[derive(Debug, Default)]
pub struct MemoryAudit {
    pub events: Vec<Event>,
}

impl AuditSink for MemoryAudit {
    fn record(&mut self, event: &Event) -> Result<(), SinkError> {
        self.events.push(event.clone());
        Ok(())
    }
}
