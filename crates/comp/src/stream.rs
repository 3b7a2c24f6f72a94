//! Points corrected through the maps as a stream: a point CSV (or Parquet) file read chunk by
//! chunk, each chunk corrected (measured points) or compensated (commanded positions) and written
//! with its correction, in constant memory with reading, correcting and writing overlapped
//! (`truepos_io::stream::rewrite_points`). What `truepos comp correct` and `truepos load correct`
//! run.
//!
//! Entry point: [`correct_file`].

use crate::{CompError, Corrector};
use std::path::Path;
use truepos_io::num::NumFormat;
use truepos_io::stream::{rewrite_points, RewriteError};
use truepos_math::Vector3;

/// What the points of the file are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Measured points: corrected to where they truly are.
    Measured,
    /// Commanded positions: compensated so that the machine truly reaches them.
    Commanded,
}

/// Summary of a streamed correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub n_points: usize,
    /// Root mean square and largest length of the corrections, µm.
    pub rms_um: f64,
    pub max_um: f64,
    /// Largest number of fixed-point iterations (commanded positions only).
    pub iterations: usize,
}

/// Correct the points of `input` into `output`: the input's columns with `x_mm,y_mm,z_mm`
/// corrected and `dx_um,dy_um,dz_um` (the correction) replaced or appended. A refused point is an
/// input error on its line, with `hint` appended to the message.
pub fn correct_file(
    corr: &Corrector,
    input: &Path,
    output: &Path,
    mode: Mode,
    fmt: NumFormat,
    hint: &str,
) -> Result<Summary, RewriteError> {
    let (mut sum_sq, mut max, mut iterations) = (0.0f64, 0.0f64, 0usize);
    // Per piece: the sum of squared correction lengths, the largest length, the most iterations.
    let piece = |_: usize, pts: &mut [truepos_math::Point3], ex: &mut [[f64; 3]]| {
        let refused = |e: CompError| (e.index(), format!("{e}{hint}"));
        let mut its = 0;
        match mode {
            Mode::Commanded => {
                let targets = pts.to_vec();
                its = corr.compensate(pts).map_err(refused)?;
                for ((c, t), e) in pts.iter().zip(&targets).zip(ex.iter_mut()) {
                    let v = c - t;
                    *e = [v.x * 1e3, v.y * 1e3, v.z * 1e3];
                }
            }
            Mode::Measured => {
                let mut d = vec![Vector3::zeros(); pts.len()];
                corr.correct_measured(pts, Some(&mut d)).map_err(refused)?;
                for (v, e) in d.iter().zip(ex.iter_mut()) {
                    *e = [v.x * 1e3, v.y * 1e3, v.z * 1e3];
                }
            }
        }
        let (mut s2, mut m) = (0.0f64, 0.0f64);
        for e in ex.iter() {
            let n2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
            s2 += n2;
            m = m.max(n2.sqrt());
        }
        Ok((s2, m, its))
    };
    let summary = rewrite_points(input, output, ["dx_um", "dy_um", "dz_um"], fmt, piece, |(s2, m, its)| {
        sum_sq += s2;
        max = max.max(m);
        iterations = iterations.max(its);
    })?;
    let n = summary.n_points;
    let rms_um = if n == 0 { 0.0 } else { (sum_sq / n as f64).sqrt() };
    Ok(Summary { n_points: n, rms_um, max_um: max, iterations })
}
