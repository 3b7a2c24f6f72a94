//! What a CMM behind the I++ DME server must do: the [`Cmm`] trait.
//!
//! Everything here is in the machine frame, millimetres, tip-centre positions. The server does the
//! protocol, the coordinate systems, the tool table and the PtMeas/scan geometry of the
//! specification; the machine moves, reports contacts and follows surfaces.

use thiserror::Error;
use truepos_math::{Matrix3, Point3, Vector3};

/// A failure inside the machine, mapped by the server to the specification's error numbers.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MachineError {
    /// The move would leave the machine volume (1008).
    #[error("target outside the machine volume")]
    OutOfVolume,
    /// The stylus touched the part during a positioning move (1001); the machine stopped at
    /// `stopped_mm`.
    #[error("the stylus touched the part during a positioning move at {stopped_mm:?}")]
    IllegalTouch {
        /// Where the machine stopped, machine frame, mm.
        stopped_mm: Point3,
    },
    /// The part would leave the machine volume (a part move or a table turn, 1008); the
    /// message says which solid and why. The part stays where it was.
    #[error("{0}")]
    PartOutOfVolume(String),
    /// Any other machine failure (1011).
    #[error("the machine cannot move: {0}")]
    Unable(String),
}

/// A contact of the stylus ball with the material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Tip-centre position at the contact.
    pub tip_center_mm: Point3,
    /// Unit surface normal at the contact (out of the material).
    pub normal: Vector3,
}

/// A scan path the machine follows in contact, with the surface found by a first probing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScanPath {
    /// Circle about `axis` through `center`: the tip centre keeps contact while the start contact
    /// is rotated about the axis by angles `0, step, 2·step, …` up to `delta` (rad, signed).
    Circle {
        /// A point on the axis, mm.
        center: Point3,
        /// Unit axis.
        axis: Vector3,
        /// Angle to scan, rad (signed).
        delta_rad: f64,
        /// Angle between points, rad.
        step_rad: f64,
    },
    /// Straight line in the plane through the start contact spanned by `direction` and the start
    /// normal; points every `step_mm` until `length_mm` from the start contact.
    Line {
        /// Unit direction of the line.
        direction: Vector3,
        /// Length to scan, mm.
        length_mm: f64,
        /// Distance between points, mm.
        step_mm: f64,
    },
    /// Unknown contour (specification 11.3): from the start contact along the surface, the tip
    /// centre staying on `guide`, first towards `toward`, a point every `step_mm` of tip-centre
    /// travel, until `stop` is met (evaluated on the surface points, tip centre − r·normal; the
    /// point where it is met is the last) or `max_length_mm` is travelled (an error). How the
    /// machine follows the contour (planned or stepped) is its own; [`Cmm::take_note`] may say.
    Contour {
        /// The surface the tip centre stays on.
        guide: Guide,
        /// The first direction of travel.
        toward: Vector3,
        /// Tip-centre travel between points, mm.
        step_mm: f64,
        /// When the scan ends.
        stop: Stop,
        /// Longest travel before the scan fails, mm.
        max_length_mm: f64,
    },
}

/// The surface the tip centre stays on during an unknown-contour scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Guide {
    /// The plane through the start contact with this unit normal.
    Plane {
        /// Unit normal of the plane.
        normal: Vector3,
    },
    /// The cylinder about this axis through the start contact.
    Cylinder {
        /// A point on the axis, mm.
        point: Point3,
        /// Unit axis.
        axis: Vector3,
    },
}

/// When an unknown-contour scan ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stop {
    /// At the `count`-th entry into the sphere, where the distance to its centre is minimal
    /// (a start inside the sphere must leave it first).
    Sphere {
        /// Centre, mm.
        center: Point3,
        /// Radius, mm.
        radius: f64,
        /// Which entry ends the scan (1: the first).
        count: u32,
    },
    /// At the `count`-th crossing of the plane, checked once `arm_mm` has been travelled.
    Plane {
        /// A point of the plane, mm.
        point: Point3,
        /// Unit normal.
        normal: Vector3,
        /// Which crossing ends the scan (1: the first).
        count: u32,
        /// Travel before crossings count, mm.
        arm_mm: f64,
    },
    /// At the `count`-th crossing of the cylinder's surface (a start inside must leave first).
    Cylinder {
        /// A point on the axis, mm.
        point: Point3,
        /// Unit axis.
        axis: Vector3,
        /// Radius, mm.
        radius: f64,
        /// Which crossing ends the scan (1: the first).
        count: u32,
    },
}

/// One scanned point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanPoint {
    /// Tip-centre position, machine frame, mm.
    pub tip_center_mm: Point3,
    /// Unit surface normal at the point, out of the material.
    pub normal: Vector3,
    /// Quality 0 (good) … 100 (bad), as in the specification's `Q()`.
    pub quality: f64,
}

/// A coordinate measuring machine behind the protocol.
pub trait Cmm: Send {
    /// One line describing the machine (for logs and `GetXtdErrStatus`).
    fn describe(&self) -> String;
    /// The reachable box of tip-centre positions (min, max corners).
    fn volume(&self) -> (Point3, Point3);
    /// Home the axes; returns the tip-centre position after homing.
    fn home(&mut self) -> Result<Point3, MachineError>;
    /// Where the tip centre is.
    fn position(&self) -> Point3;
    /// A positioning move with a ball of `tip_radius_mm` (0 for a tool that cannot touch). A touch
    /// of the part on the way stops the machine and is [`MachineError::IllegalTouch`].
    fn move_to(&mut self, target_mm: Point3, tip_radius_mm: f64) -> Result<(), MachineError>;
    /// A probing move of the tip centre from `from_mm` to `to_mm` (straight line): the first
    /// touch of the ball on the material is latched and the machine stops there. `None` if the
    /// move ends without contact (the machine is then at `to_mm`). `nominal_mm` and
    /// `nominal_normal` are the nominal surface point and the probing direction reversed (a
    /// machine without a part model touches the ideal plane through them).
    fn probe(
        &mut self,
        from_mm: Point3,
        to_mm: Point3,
        tip_radius_mm: f64,
        nominal_mm: Point3,
        nominal_normal: Vector3,
    ) -> Result<Option<Contact>, MachineError>;
    /// Follow `path` in contact from `start` (a contact found by probing); the points are
    /// appended to `out` (the first is at the start contact). Stops early, without error, where
    /// the surface ends.
    fn scan(
        &mut self,
        start: Contact,
        path: &ScanPath,
        tip_radius_mm: f64,
        out: &mut Vec<ScanPoint>,
    ) -> Result<(), MachineError>;
    /// Refuse a scan the machine will not run (too many points, too long a path, too much
    /// machine time) before anything moves. The server calls it with the nominal start contact
    /// (the nominal surface point offset by the tip radius along the nominal normal) before the
    /// first probing of the scan; [`Cmm::scan`] may still refuse on the measured start contact.
    /// Default: every scan is accepted.
    fn check_scan(
        &self,
        _nominal_start: Contact,
        _path: &ScanPath,
        _tip_radius_mm: f64,
    ) -> Result<(), MachineError> {
        Ok(())
    }
    /// Stop all motion now (client gone, AbortE). Moves are instant on the virtual machine, so
    /// this only has to leave it in a defined, stopped state.
    fn stop(&mut self);
    /// A note about the last command for the session log (e.g. how a scan was executed), taken
    /// once. Default: none.
    fn take_note(&mut self) -> Option<String> {
        None
    }
    /// The rotary table, if the machine has one: a point on its axis and the axis' unit
    /// direction (machine frame). `None`: a `CartCMM` (the default).
    fn rotary_axis(&self) -> Option<(Point3, Vector3)> {
        None
    }
    /// The rotary table's angle (rad, counter-clockwise about its axis), 0 without a table.
    fn table_angle(&self) -> f64 {
        0.0
    }
    /// Turn the rotary table to `angle_rad` (the part on it turns with it). A turn the machine
    /// refuses leaves the table and the part where they were.
    fn set_table_angle(&mut self, _angle_rad: f64) -> Result<(), MachineError> {
        Err(MachineError::Unable("this CMM has no rotary table".into()))
    }
    /// Move the part on the machine rigidly (form-tester centring and tilting, specification
    /// 13.1–13.3): rotate it by `rotation` (a rotation matrix, machine frame) about `about`, then
    /// shift it by `shift`. A move the machine refuses (e.g. one that would take the part out of
    /// its volume) leaves the part where it was.
    fn move_part(&mut self, _rotation: Matrix3, _about: Point3, _shift: Vector3) -> Result<(), MachineError> {
        Err(MachineError::Unable("this CMM cannot move the part".into()))
    }
}
