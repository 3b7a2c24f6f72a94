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
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Number of points corrected.
    pub n_points: usize,
    /// Points of an E57 input dropped because the file marks them invalid (0 for other inputs).
    pub dropped_invalid: usize,
    /// Points of an E57 input dropped for a NaN or infinite coordinate (0 for other inputs).
    pub dropped_nonfinite: usize,
    /// Root mean square length of the corrections, µm.
    pub rms_um: f64,
    /// Largest length of the corrections, µm.
    pub max_um: f64,
    /// Largest number of fixed-point iterations (commanded positions only).
    pub iterations: usize,
    /// The propagated uncertainty of the corrected points, or why it is unknown.
    pub uncertainty: Result<UncertaintyStats, String>,
}

/// Coverage factor of the expanded uncertainties reported.
pub const COVERAGE_FACTOR: f64 = 2.0;

/// Expanded uncertainties (k = [`COVERAGE_FACTOR`]) of the corrected coordinates over a file.
#[derive(Clone, Debug, PartialEq)]
pub struct UncertaintyStats {
    /// Largest `U` of x, y and z, µm.
    pub max_um: [f64; 3],
    /// Median `U` of x, y and z, µm, from a logarithmic histogram (within 1.2 %; a streamed file
    /// is not held in memory to sort).
    pub median_um: [f64; 3],
}

/// Histogram bins per decade and the decades covered (1e-4 µm to 1e6 µm).
const BINS_PER_DECADE: f64 = 100.0;
const LOG_MIN: f64 = -4.0;
const N_BINS: usize = 1000;

/// Per-coordinate histograms of `U` and their maxima (one per piece, merged in file order).
struct UHist {
    counts: Vec<[u32; 3]>,
    max: [f64; 3],
}

impl UHist {
    fn new() -> UHist {
        UHist { counts: vec![[0; 3]; N_BINS], max: [0.0; 3] }
    }

    #[inline]
    fn add(&mut self, u: [f64; 3]) {
        for (k, &v) in u.iter().enumerate() {
            let b = if v > 0.0 {
                ((v.log10() - LOG_MIN) * BINS_PER_DECADE).clamp(0.0, (N_BINS - 1) as f64) as usize
            } else {
                0
            };
            self.counts[b][k] += 1;
            self.max[k] = self.max[k].max(v);
        }
    }

    fn merge(&mut self, o: &UHist) {
        for (a, b) in self.counts.iter_mut().zip(&o.counts) {
            for k in 0..3 {
                a[k] += b[k];
            }
        }
        for k in 0..3 {
            self.max[k] = self.max[k].max(o.max[k]);
        }
    }

    fn stats(&self, n: usize) -> UncertaintyStats {
        let mut median = [0.0; 3];
        for (k, m) in median.iter_mut().enumerate() {
            let half = n.div_ceil(2) as u64;
            let mut seen = 0u64;
            for (b, c) in self.counts.iter().enumerate() {
                seen += u64::from(c[k]);
                if seen >= half && n > 0 {
                    // The bin's geometric centre, never above the largest value.
                    *m = 10f64.powf((b as f64 + 0.5) / BINS_PER_DECADE + LOG_MIN).min(self.max[k]);
                    break;
                }
            }
        }
        UncertaintyStats { max_um: self.max, median_um: median }
    }
}

/// Correct the points of `input` into `output`: the input's columns with `x_mm,y_mm,z_mm`
/// corrected and `dx_um,dy_um,dz_um` (the correction) replaced or appended. When the corrector's
/// uncertainty is known ([`Corrector::uncertainty_unknown`]), `u_x_um,u_y_um,u_z_um` too: the
/// standard uncertainty (k = 1) of each corrected coordinate, propagated from the map; else the
/// output is exactly what it was without them. A refused point is an input error on its line,
/// with `hint` appended to the message.
pub fn correct_file(
    corr: &Corrector,
    input: &Path,
    output: &Path,
    mode: Mode,
    fmt: NumFormat,
    hint: &str,
) -> Result<Summary, RewriteError> {
    match corr.uncertainty_unknown() {
        None => run(
            corr,
            input,
            output,
            mode,
            fmt,
            hint,
            ["dx_um", "dy_um", "dz_um", "u_x_um", "u_y_um", "u_z_um"],
        ),
        Some(why) => {
            let mut s = run(corr, input, output, mode, fmt, hint, ["dx_um", "dy_um", "dz_um"])?;
            s.uncertainty = Err(why);
            Ok(s)
        }
    }
}

/// [`correct_file`] with `N` = 3 (the correction) or 6 (and its standard uncertainty) columns.
fn run<const N: usize>(
    corr: &Corrector,
    input: &Path,
    output: &Path,
    mode: Mode,
    fmt: NumFormat,
    hint: &str,
    extra: [&str; N],
) -> Result<Summary, RewriteError> {
    let (mut sum_sq, mut max, mut iterations) = (0.0f64, 0.0f64, 0usize);
    let mut hist = (N == 6).then(UHist::new);
    // Per piece: the sum of squared correction lengths, the largest length, the most iterations
    // and, with uncertainties, their histogram.
    let piece = |_first: usize, pts: &mut [truepos_math::Point3], ex: &mut [[f64; N]]| {
        let refused = |e: CompError| (e.index(), format!("{e}{hint}"));
        let mut its = 0;
        let mut h = None;
        match mode {
            Mode::Commanded => {
                let targets = pts.to_vec();
                its = corr.compensate(pts).map_err(refused)?;
                for ((c, t), e) in pts.iter().zip(&targets).zip(ex.iter_mut()) {
                    let v = c - t;
                    e[..3].copy_from_slice(&[v.x * 1e3, v.y * 1e3, v.z * 1e3]);
                }
                if N == 6 {
                    // Where the machine goes: c + E_true(c) = T + (E_true − E_map)(c).
                    for (k, (c, e)) in pts.iter().zip(ex.iter_mut()).enumerate() {
                        let (_, var) = corr
                            .displacement_u(c)
                            .map_err(|source| refused(CompError::OutOfRange { index: k, source }))?;
                        e[3..].copy_from_slice(&[var.x.sqrt() * 1e3, var.y.sqrt() * 1e3, var.z.sqrt() * 1e3]);
                    }
                }
            }
            Mode::Measured if N == 6 => {
                for (k, (p, e)) in pts.iter_mut().zip(ex.iter_mut()).enumerate() {
                    let (d, var) = corr
                        .displacement_u(p)
                        .map_err(|source| refused(CompError::OutOfRange { index: k, source }))?;
                    *p += d;
                    e.copy_from_slice(&[
                        d.x * 1e3,
                        d.y * 1e3,
                        d.z * 1e3,
                        var.x.sqrt() * 1e3,
                        var.y.sqrt() * 1e3,
                        var.z.sqrt() * 1e3,
                    ]);
                }
            }
            Mode::Measured => {
                let mut d = vec![Vector3::zeros(); pts.len()];
                corr.correct_measured(pts, Some(&mut d)).map_err(refused)?;
                for (v, e) in d.iter().zip(ex.iter_mut()) {
                    e[..3].copy_from_slice(&[v.x * 1e3, v.y * 1e3, v.z * 1e3]);
                }
            }
        }
        let (mut s2, mut m) = (0.0f64, 0.0f64);
        for e in ex.iter() {
            let n2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
            s2 += n2;
            m = m.max(n2.sqrt());
        }
        if N == 6 {
            let mut hh = UHist::new();
            for e in ex.iter() {
                hh.add([COVERAGE_FACTOR * e[3], COVERAGE_FACTOR * e[4], COVERAGE_FACTOR * e[5]]);
            }
            h = Some(hh);
        }
        Ok((s2, m, its, h))
    };
    let summary = rewrite_points(
        input,
        output,
        extra,
        fmt,
        piece,
        |(s2, m, its, h): (f64, f64, usize, Option<UHist>)| {
            sum_sq += s2;
            max = max.max(m);
            iterations = iterations.max(its);
            if let (Some(a), Some(b)) = (hist.as_mut(), h.as_ref()) {
                a.merge(b);
            }
        },
    )?;
    let n = summary.n_points;
    let rms_um = if n == 0 { 0.0 } else { (sum_sq / n as f64).sqrt() };
    let uncertainty = match &hist {
        Some(h) => Ok(h.stats(n)),
        None => Err(String::new()),
    };
    Ok(Summary {
        n_points: n,
        dropped_invalid: summary.skipped_invalid,
        dropped_nonfinite: summary.skipped_nonfinite,
        rms_um,
        max_um: max,
        iterations,
        uncertainty,
    })
}
