//! The commands of `truepos latency` as library calls: read the two stream files, estimate (or
//! apply) the delay, and return a `Report` (the contract's JSON and the human text).
//!
//! Entry points: [`estimate_files`] (`truepos latency`), [`apply_files`] (`truepos latency
//! apply`). Errors about a stream name its file and line ([`crate::file::input_error`]).

use crate::file::{input_error, read_streams, write_centres};
use crate::{Estimate, Options, Streams};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use truepos_io::atomic::OutputError;
use truepos_io::report::Report;
use truepos_io::stream::RewriteError;
use truepos_io::InputError;

/// The machine stream's value columns.
pub const MACHINE_COLUMNS: [&str; 3] = ["x_mm", "y_mm", "z_mm"];
/// The probe stream's value columns.
pub const PROBE_COLUMNS: [&str; 3] = ["a_mm", "b_mm", "c_mm"];

/// An estimate with the options it was made with.
pub struct Estimated {
    /// The estimate.
    pub estimate: Estimate,
    /// The options the estimate was computed with (method, known size, tip radius, ...).
    pub options: Options,
}

impl Report for Estimated {
    fn to_json(&self) -> Value {
        crate::json::estimate(&self.estimate, &self.options)
    }

    fn text(&self) -> String {
        crate::text::estimate(&self.estimate, &self.options)
    }
}

/// `truepos latency`: the system delay from the machine stream (`t_s,x_mm,y_mm,z_mm`) and the
/// probe stream (`t_s,a_mm,b_mm,c_mm`). The estimate's warnings are in `estimate.warnings`.
pub fn estimate_files(machine: &Path, probe: &Path, options: Options) -> Result<Estimated, InputError> {
    let (m, p) = read_streams(machine, probe, false)?;
    let s = Streams { machine_t: &m.t, machine: &m.v, probe_t: &p.t, probe: &p.v };
    let estimate = crate::estimate(&s, &options).map_err(|e| input_error(e, &m, &p))?;
    Ok(Estimated { estimate, options })
}

/// The stylus centres written by [`apply_files`].
pub struct Applied {
    /// The delay applied to the machine stamps, s.
    pub delay_s: f64,
    /// Number of stylus centres written.
    pub n_points: usize,
    /// Probe rows whose shifted time the machine data does not cover.
    pub n_skipped: usize,
    /// The output file written.
    pub output: PathBuf,
}

impl Report for Applied {
    fn to_json(&self) -> Value {
        json!({"delay_s": self.delay_s, "n_points": self.n_points, "n_skipped": self.n_skipped,
               "output": self.output.display().to_string()})
    }

    fn text(&self) -> String {
        let mut out = String::new();
        if self.n_skipped > 0 {
            out += &format!(
                "warning: {} probe row(s) skipped: the machine data does not cover t + delay there\n",
                self.n_skipped
            );
        }
        out + &format!("{} stylus-centre positions written to {}\n", self.n_points, self.output.display())
    }

    fn text_on_stderr(&self) -> bool {
        true
    }
}

/// `truepos latency apply`: the stylus-centre positions of the probe rows with the machine
/// position read at `t + delay_s`, written to `output`. No covered row at all is an input error.
pub fn apply_files(
    machine: &Path,
    probe: &Path,
    delay_s: f64,
    output: &Path,
) -> Result<Applied, RewriteError> {
    if !delay_s.is_finite() {
        return Err(InputError::new("the delay must be a finite number of seconds").into());
    }
    // The probe file's other columns are copied to the output: keep its table.
    let (m, p) = read_streams(machine, probe, true)?;
    let s = Streams { machine_t: &m.t, machine: &m.v, probe_t: &p.t, probe: &p.v };
    s.check().map_err(|e| input_error(e, &m, &p))?;
    let mut out = Vec::new();
    crate::apply(&s, delay_s, &mut out);
    let n_points = out.iter().filter(|c| !c[0].is_nan()).count();
    if n_points == 0 {
        let what = format!(
            "the machine data ({}) covers none of the probe time stamps shifted by {delay_s} s",
            machine.display()
        );
        return Err(InputError::in_file(probe, what).into());
    }
    write_centres(output, delay_s, &p, &out).map_err(|e| OutputError::from_io(output, e))?;
    Ok(Applied { delay_s, n_points, n_skipped: out.len() - n_points, output: output.to_path_buf() })
}
