//! `truepos head-offset` (calibration from a points file) as a library call: read the readings,
//! check that they can determine what is asked, solve, and return a `Report` (the contract's
//! JSON and the human text) with the observability notes.
//!
//! Entry point: [`calibrate_file`].

use crate::file::{head_error, read_input, Input};
use crate::{solve, HeadOffset, Params, Reference};
use serde_json::Value;
use std::path::Path;
use truepos_io::report::Report;
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};

/// What the user knows about the setup (the file gives the readings).
#[derive(Clone, Debug)]
pub struct Calibration {
    /// The reference object (sphere or vertex).
    pub reference: Reference,
    /// A point of the table's C axis; needed when the readings have several table angles.
    pub table_center_mm: Option<Point3>,
    /// Laser beam tilt (α, β), rad.
    pub tilt: [f64; 2],
    /// Value for offset components the data cannot determine, mm.
    pub prior_offset_mm: Vector3,
    /// Whether the laser beam passes through the head reference point (see `Params::beam_through_reference`).
    pub beam_through_reference: bool,
    /// The stylus tip radius as given (for the JSON), mm.
    pub tip_radius_mm: f64,
    /// The reference sphere's diameter as given, mm.
    pub sphere_diameter_mm: Option<f64>,
}

/// A calibrated head offset with what it was computed from.
pub struct Calibrated {
    /// The adjustment's result.
    pub result: HeadOffset,
    /// The parameters it was computed with.
    pub params: Params,
    /// The readings it was computed from.
    pub input: Input,
    tip_radius_mm: f64,
    sphere_diameter_mm: Option<f64>,
}

impl Calibrated {
    /// What people must know about the result: components taken from the tilt or the prior
    /// because no rotation determines them.
    pub fn notes(&self) -> Vec<String> {
        crate::json::notes(&self.result, &self.params.prior)
    }
}

impl Report for Calibrated {
    fn to_json(&self) -> Value {
        crate::json::result(
            &self.result,
            &self.params,
            self.tip_radius_mm,
            self.sphere_diameter_mm,
            &self.input,
        )
    }

    fn text(&self) -> String {
        crate::json::text(&self.result, self.tip_radius_mm)
    }
}

/// Calibrate the head offset from the readings of `points` (columns `b_deg,c_deg,x_mm,y_mm,z_mm`
/// and optionally `dist_mm`, `face`, `group`). No readings, a laser-head option without
/// `dist_mm`, several table angles without a table centre, or data the adjustment cannot use
/// are input errors naming the file (and line).
pub fn calibrate_file(points: &Path, c: &Calibration) -> Result<Calibrated, InputError> {
    let input = read_input(points, true)?;
    if input.table.n_rows() == 0 {
        let why = "no readings: head-offset needs the reference measured in at least two orientations";
        return Err(InputError::in_file(points, why));
    }
    if c.beam_through_reference && input.table.column("dist_mm").is_none() {
        let why = "--beam-through-reference is for laser heads: the points file needs a dist_mm column";
        return Err(InputError::in_file(points, why));
    }
    let table_turns = input.readings.iter().any(|r| r.c != input.readings[0].c);
    let table_center = match c.table_center_mm {
        Some(t) => t,
        None if table_turns => {
            let why = "the readings have several table angles (c_deg): --table-center-mm X,Y,Z (a point of the C axis) is needed";
            return Err(InputError::in_file(points, why));
        }
        None => Point3::origin(),
    };
    let params = Params {
        reference: c.reference,
        table_center,
        tilt: c.tilt,
        prior: c.prior_offset_mm,
        beam_through_reference: c.beam_through_reference,
    };
    let result = solve(&input.readings, &params).map_err(|e| head_error(&input.table, e))?;
    Ok(Calibrated {
        result,
        params,
        input,
        tip_radius_mm: c.tip_radius_mm,
        sphere_diameter_mm: c.sphere_diameter_mm,
    })
}
