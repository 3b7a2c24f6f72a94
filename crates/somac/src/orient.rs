//! `truepos orient` as a library call: rewrite a G-code program through the best-fit transform
//! from the part's reference targets to where they were measured, streamed in constant memory
//! into an atomic output (nothing is left at the output unless the whole program was rewritten).
//!
//! Entry point: [`orient_file`], returning an [`Oriented`] (a `Report`). The rewriting itself is
//! `truepos_gcode::transform_stream`; this module reads the targets, fits, and names the file,
//! line and column of every error.

use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use truepos_gcode::{StreamError, TransformOptions};
use truepos_io::atomic::{AtomicFile, OutputError};
use truepos_io::points::read_matched;
use truepos_io::report::Report;
use truepos_io::stream::RewriteError;
use truepos_io::InputError;
use truepos_math::bestfit::{self, BestFitOptions};
use truepos_math::Transform3;

/// A program rewritten into the measured frame.
#[derive(Clone, Debug)]
pub struct Oriented {
    /// The transform from the program's reference frame to the measured frame (mm).
    pub measured_from_reference: Transform3,
    /// The ids of the targets used.
    pub ids: Vec<String>,
    /// Residual length per target, mm.
    pub residuals_mm: Vec<f64>,
    /// Lines of the program.
    pub lines: usize,
    /// The rewritten program's file.
    pub output: PathBuf,
}

impl Report for Oriented {
    fn to_json(&self) -> Value {
        let t = &self.measured_from_reference;
        let r = t.rotation;
        json!({
            "n_targets": self.ids.len(),
            "rotation": (0..3).map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]).collect::<Vec<_>>(),
            "translation_mm": <[f64; 3]>::from(t.translation),
            "scale": t.scale,
            "rms_mm": truepos_math::stats::rms(&self.residuals_mm),
            "residuals": self.ids.iter().zip(&self.residuals_mm)
                .map(|(id, r)| json!({"id": id, "residual_mm": r})).collect::<Vec<_>>(),
            "lines": self.lines,
        })
    }

    fn text(&self) -> String {
        format!(
            "oriented {} lines through the fit of {} targets (rms {:.4} mm) → {}\n",
            self.lines,
            self.ids.len(),
            truepos_math::stats::rms(&self.residuals_mm),
            self.output.display()
        )
    }

    fn text_on_stderr(&self) -> bool {
        true
    }
}

/// Fit `measured_from_reference` on the targets of the two files (`id,x_mm,y_mm,z_mm`, at least
/// three common ids; `scale`: similarity fit) and rewrite `program` into `output`.
pub fn orient_file(
    reference: &Path,
    measured: &Path,
    program: &Path,
    output: &Path,
    scale: bool,
    opts: &TransformOptions,
) -> Result<Oriented, RewriteError> {
    let (_, _, mt) = read_matched(reference, measured, 3, "orientation")?;
    let t = bestfit::best_fit(&mt.from, &mt.to, None, BestFitOptions { with_scale: scale })
        .map_err(|e| InputError::in_file(measured, format!("cannot orient: {e}")))?;
    // Bounded input (size limit, line length, no binary data).
    let input = truepos_io::limits::open_text(program, "G-code")?;
    let mut file = AtomicFile::create(output)?;
    let summary = truepos_gcode::transform_stream(input, &mut file, &t, opts).map_err(|e| match e {
        StreamError::Gcode(e) => InputError::at(program, e.line(), Some(e.column()), e.detail()).into(),
        StreamError::Read(e) => truepos_io::limits::read_error(program, e).into(),
        StreamError::Write(source) => {
            RewriteError::Output(OutputError::Io { path: output.to_path_buf(), source })
        }
    })?;
    file.commit()?;
    let residuals_mm = bestfit::residuals(&t, &mt.from, &mt.to).iter().map(|r| r.norm()).collect();
    Ok(Oriented {
        measured_from_reference: t,
        ids: mt.ids,
        residuals_mm,
        lines: summary.lines,
        output: output.to_path_buf(),
    })
}
