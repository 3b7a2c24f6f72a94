//! Demo sections for the capabilities without a scenario of their own: the geometric error map
//! correction (`comp`), the part's scale from its targets (`autoscale`), re-orientation of a
//! program through measured targets (`orient`) and the refractive index of air (`air`). Each
//! runs the library on simulated data (or published reference values) and judges the result
//! against the truth with a stated tolerance.
//!
//! Entry points: [`comp_section`], [`autoscale_section`], [`orient_section`], [`air_section`];
//! [`write_comp_dataset`] (the `truepos simulate comp` data set, from [`comp_data`]).

use crate::error::{CellError, Result};
use truepos_report::{self as report, DecisionRule, Judgement, Report, Verdict};

/// Expanded uncertainty (in 10⁻⁹) of comparing n with NIST's printed values: the printed values'
/// rounding is the tolerance itself; double-precision evaluation adds far less than this bound.
const AIR_COMPARISON_U_PPB: f64 = 0.001;
use rand::Rng;
use std::f64::consts::FRAC_1_SQRT_2;
use std::path::{Path, PathBuf};
use truepos_comp::{AxisErrors, AxisTable, Chain, Corrector, GeometricMap, Squareness};
use truepos_io::atomic::{write_atomic, AtomicFile};
use truepos_io::csv::CsvWriter;
use truepos_math::bestfit::{self, BestFitOptions};
use truepos_math::types::{rx, ry, rz, Axis};
use truepos_math::{Point3, Transform3, Vector3};
use truepos_sim::errors::{ErrorMagnitudes, GeometricErrors};
use truepos_sim::machine::chain::SerialChain;
use truepos_sim::noise;

/// Seed of every simulated data set in these sections.
pub const SEED: u64 = 1;

/// Standard uncertainties (k = 1) of the simulated calibration of the `comp` data set, per
/// component `[pos, str1, str2, pitch, yaw, roll]` (mm, rad): what a laser-interferometer and
/// electronic-level calibration of a CMM states (0.05 µm positioning, 0.1 µm straightness,
/// 0.05 µrad pitch and yaw, 0.1 µrad roll). The map's values carry exactly this error: half its
/// variance common to all the nodes of a component (the calibration's systematic part), half
/// independent from node to node.
pub const COMP_CAL_U: [f64; 6] = [0.05e-3, 0.1e-3, 0.1e-3, 0.05e-6, 0.05e-6, 0.1e-6];
/// Standard uncertainty (k = 1, rad) of each calibrated squareness error (0.2 µrad: a ball plate
/// or square in three positions).
pub const COMP_CAL_U_SQUARENESS: f64 = 0.2e-6;

/// The geometric-map data set: a bridge CMM's simulated errors, its map as a calibration delivers
/// it (sampled every 5 mm, a quarter of the shortest periodic error's period, each value with
/// the calibration's noise of [`COMP_CAL_U`], stated in the map's uncertainty columns) and 400
/// points measured with a probe 150 mm below the ram with their true positions (the simulator's
/// exact kinematic chain).
pub struct CompData {
    /// The error magnitudes of the simulated machine.
    pub mags: ErrorMagnitudes,
    /// The simulated machine's true geometric errors.
    pub errors: GeometricErrors,
    /// Map step (mm).
    pub step: f64,
    /// The calibrated map, as the compensation reads it.
    pub map: GeometricMap,
    /// The calibrated map's rows per axis: positions (mm) and `[pos, str1, str2, pitch, yaw,
    /// roll]` (mm, rad), noise included.
    pub rows: [(Vec<f64>, Vec<[f64; 6]>); 3],
    /// The calibrated squareness (rad), noise included.
    pub squareness: Squareness,
    /// Probe offset in the ram frame (mm).
    pub tool: Vector3,
    /// Indicated tip points (axis positions + tool), as the CMM reports them.
    pub indicated: Vec<Point3>,
    /// True tip points.
    pub actual: Vec<Point3>,
}

/// The `comp` data set of a seed (the demo uses [`SEED`]).
pub fn comp_data(seed: u64) -> Result<CompData> {
    let mags = ErrorMagnitudes::cmm();
    let mut rng = noise::stream(seed, 31);
    let mut cal = noise::stream(seed, 32);
    let errors = GeometricErrors::realistic(&mut rng, &mags);
    let chain = SerialChain::new([Axis::Y, Axis::X, Axis::Z], errors.clone());
    let step = 5.0;
    let mut map = GeometricMap { chain: Chain::BridgeYXZ, ..GeometricMap::default() };
    let u = COMP_CAL_U;
    let u_row = AxisErrors { pos: u[0], str1: u[1], str2: u[2], pitch: u[3], yaw: u[4], roll: u[5] };
    let mut rows: [(Vec<f64>, Vec<[f64; 6]>); 3] = Default::default();
    for axis in Axis::ALL {
        let t = mags.travel[axis.index()];
        let n = (t / step).ceil() as usize;
        let pos: Vec<f64> = (0..=n).map(|i| (i as f64 * step).min(t)).collect();
        // Half the variance shared by every node of a component (the calibration's systematic
        // part: wavelength, material temperature, zero of the level), half each node's own.
        let shared: [f64; 6] = std::array::from_fn(|k| noise::gaussian(&mut cal, u[k] * FRAC_1_SQRT_2));
        let vals: Vec<[f64; 6]> = errors
            .sample(axis, &pos)
            .iter()
            .map(|v| {
                std::array::from_fn(|k| v[k] + shared[k] + noise::gaussian(&mut cal, u[k] * FRAC_1_SQRT_2))
            })
            .collect();
        let e: Vec<AxisErrors> = vals
            .iter()
            .map(|v| AxisErrors { pos: v[0], str1: v[1], str2: v[2], pitch: v[3], yaw: v[4], roll: v[5] })
            .collect();
        let table = AxisTable::new(axis, pos.clone(), &e)?.with_uncertainty(&vec![u_row; pos.len()])?;
        match axis {
            Axis::X => map.x = Some(table),
            Axis::Y => map.y = Some(table),
            Axis::Z => map.z = Some(table),
        }
        rows[axis.index()] = (pos, vals);
    }
    let us = COMP_CAL_U_SQUARENESS;
    let squareness = Squareness {
        xy: errors.squareness.xy + noise::gaussian(&mut cal, us),
        xz: errors.squareness.xz + noise::gaussian(&mut cal, us),
        yz: errors.squareness.yz + noise::gaussian(&mut cal, us),
    };
    map.squareness = squareness;
    map.squareness_u = Some(Squareness { xy: us, xz: us, yz: us });
    let tool = Vector3::new(0.0, 0.0, -150.0);
    // 400 random axis positions inside the travel; the indicated tip point is axes + tool.
    let axes: Vec<Point3> = (0..400)
        .map(|_| {
            Point3::new(
                rng.random_range(0.0..mags.travel[0]),
                rng.random_range(0.0..mags.travel[1]),
                rng.random_range(0.0..mags.travel[2]),
            )
        })
        .collect();
    let actual: Vec<Point3> = axes.iter().map(|a| chain.actual(a, &tool)).collect();
    let indicated: Vec<Point3> = axes.iter().map(|a| a + tool).collect();
    Ok(CompData { mags, errors, step, map, rows, squareness, tool, indicated, actual })
}

/// What [`write_comp_dataset`] wrote.
pub struct CompWritten {
    /// The map file written.
    pub map: PathBuf,
    /// The squareness file written.
    pub squareness: PathBuf,
    /// The points file written.
    pub points: PathBuf,
    /// The truth file written.
    pub truth: PathBuf,
    /// The command line that corrects the points.
    pub command: String,
    /// Number of points.
    pub n_points: usize,
    /// Map rows per axis (x, y, z).
    pub rows: [usize; 3],
    /// RMS and max 3D error of the uncorrected points (µm).
    pub rms_um: f64,
    /// Largest 3D error of the uncorrected points, µm.
    pub max_um: f64,
}

impl CompWritten {
    /// What `truepos simulate comp` prints: the data set, the command and what to compare.
    pub fn text(&self, dir: &Path) -> String {
        format!(
            "comp scenario: bridge CMM map with {} x, {} y and {} z rows and their standard uncertainties, squareness, {} points (uncorrected 3D error RMS {:.2} µm, max {:.2} µm) → {}\nnext: {}\nthen compare corrected.csv with true_points_mm in {} (expect each coordinate within ±2 u of the truth, u_x_um,u_y_um,u_z_um of the output, in about 95 % of cases)\n",
            self.rows[0], self.rows[1], self.rows[2], self.n_points, self.rms_um, self.max_um,
            dir.display(), self.command, self.truth.display()
        )
    }
}

/// Write the `comp` data set (`truepos simulate comp`) into `dir`: `map.csv` (the contract's map
/// columns, one table per axis), `squareness.toml`, `points.csv` (indicated tip points with ids)
/// and `truth.json` (the true points, the probe offset, the chain), every file commented.
pub fn write_comp_dataset(dir: &Path, seed: u64) -> Result<CompWritten> {
    let d = comp_data(seed)?;
    std::fs::create_dir_all(dir).map_err(|e| CellError::io(dir, e))?;
    let (map_p, sq_p, pts_p, truth_p) =
        (dir.join("map.csv"), dir.join("squareness.toml"), dir.join("points.csv"), dir.join("truth.json"));
    let t = d.tool;
    let command = format!(
        "truepos comp correct --map {} --squareness {} --points {} --output {} --probe-offset-mm {},{},{}",
        map_p.display(),
        sq_p.display(),
        pts_p.display(),
        dir.join("corrected.csv").display(),
        t.x,
        t.y,
        t.z
    );
    let rows = write_comp_map(&map_p, &d, seed, &command)?;
    write_comp_squareness(&sq_p, &d, seed)?;
    write_comp_points(&pts_p, &d, seed)?;
    let err: Vec<f64> = d.indicated.iter().zip(&d.actual).map(|(i, a)| (i - a).norm() * 1e3).collect();
    let (rms_um, max_um) = (truepos_math::stats::rms(&err), err.iter().copied().fold(0.0_f64, f64::max));
    let truth = serde_json::json!({
        "scenario": "comp",
        "seed": seed,
        "chain": "bridge (bed → Y → X → Z → tool)",
        "travel_mm": d.mags.travel,
        "map_step_mm": d.step,
        "probe_offset_mm": [t.x, t.y, t.z],
        "squareness_urad": {
            "xy": d.errors.squareness.xy * 1e6,
            "xz": d.errors.squareness.xz * 1e6,
            "yz": d.errors.squareness.yz * 1e6
        },
        "calibration_standard_uncertainty": {
            "pos_um": COMP_CAL_U[0] * 1e3, "str1_um": COMP_CAL_U[1] * 1e3, "str2_um": COMP_CAL_U[2] * 1e3,
            "pitch_urad": COMP_CAL_U[3] * 1e6, "yaw_urad": COMP_CAL_U[4] * 1e6, "roll_urad": COMP_CAL_U[5] * 1e6,
            "squareness_urad": COMP_CAL_U_SQUARENESS * 1e6
        },
        "ids": (1..=d.actual.len()).map(|i| format!("P{i}")).collect::<Vec<_>>(),
        "true_points_mm": d.actual.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
        "uncorrected_rms_error_um": rms_um,
        "uncorrected_max_error_um": max_um,
        "command": command,
        "note": "true_points_mm: the probe tip on the simulator's exact (non-linearised) kinematic chain; squareness_urad: the true squareness (squareness.toml holds the calibrated one). The map carries its calibration's noise, stated in its u_* columns: a corrected point lies within its ±2·u (u_x_um, u_y_um, u_z_um of the output) of the truth in about 95 % of coordinates",
    });
    let mut text = serde_json::to_string_pretty(&truth)?;
    text.push('\n');
    write_atomic(&truth_p, text.as_bytes())?;
    Ok(CompWritten {
        map: map_p,
        squareness: sq_p,
        points: pts_p,
        truth: truth_p,
        command,
        n_points: d.indicated.len(),
        rows,
        rms_um,
        max_um,
    })
}

/// `map.csv` of the `comp` data set: the calibrated map with its u_* columns, one table per
/// axis; returns the rows written per axis.
fn write_comp_map(map_p: &Path, d: &CompData, seed: u64, command: &str) -> Result<[usize; 3]> {
    let mut rows = [0usize; 3];
    let mut f = AtomicFile::create(map_p)?;
    {
        // 0.01 nm and 0.01 nrad: exact for any use, and no 1e-19 noise at the tables' zero.
        let mut w =
            CsvWriter::new(std::io::BufWriter::new(&mut f)).with_format(truepos_io::num::NumFormat::Fixed(5));
        for c in [
            format!("Geometric error map of a virtual bridge CMM (truepos simulate comp, seed {seed}), as a simulated calibration delivers it: sampled every {} mm, each value with the calibration's noise.", d.step),
            "Errors of motion, actual − nominal, one table per axis (rows with axis = x, y, z), at the axis position position_mm (mm).".into(),
            "pos_um: positioning error along the axis itself (µm); str1_um, str2_um: straightness along the next two axes in x→y→z→x order (µm).".into(),
            "pitch_urad, yaw_urad, roll_urad: angular errors (µrad, right-handed): X: roll about X, pitch about Y, yaw about Z; Y: roll about Y, pitch about X, yaw about Z; Z: roll about Z, pitch about X, yaw about Y.".into(),
            "u_*: the standard uncertainty (k = 1) of each value, the calibration's noise; truepos comp correct propagates them to u_x_um,u_y_um,u_z_um.".into(),
            "Squareness: squareness.toml. Chain: bed → Y → X → Z → tool (bridge, the default of truepos comp).".into(),
            format!("Correct the points with: {command}"),
        ] {
            w.comment(&c)?;
        }
        w.header(&[
            "axis",
            "position_mm",
            "pos_um",
            "str1_um",
            "str2_um",
            "pitch_urad",
            "yaw_urad",
            "roll_urad",
            "u_pos_um",
            "u_str1_um",
            "u_str2_um",
            "u_pitch_urad",
            "u_yaw_urad",
            "u_roll_urad",
        ])?;
        let u = COMP_CAL_U;
        for (k, (pos, vals)) in d.rows.iter().enumerate() {
            for (p, v) in pos.iter().zip(vals) {
                w.field_str(["x", "y", "z"][k])?;
                w.row_f64(&[
                    *p,
                    v[0] * 1e3,
                    v[1] * 1e3,
                    v[2] * 1e3,
                    v[3] * 1e6,
                    v[4] * 1e6,
                    v[5] * 1e6,
                    u[0] * 1e3,
                    u[1] * 1e3,
                    u[2] * 1e3,
                    u[3] * 1e6,
                    u[4] * 1e6,
                    u[5] * 1e6,
                ])?;
                rows[k] += 1;
            }
        }
        std::io::Write::flush(&mut w.into_inner())?;
    }
    f.commit()?;
    Ok(rows)
}

/// `squareness.toml` of the `comp` data set (the calibrated squareness, µrad, with its u).
fn write_comp_squareness(sq_p: &Path, d: &CompData, seed: u64) -> Result<()> {
    let sq = &d.squareness;
    let us = COMP_CAL_U_SQUARENESS * 1e6;
    write_atomic(
        sq_p,
        format!(
            "# Squareness errors of the virtual bridge CMM (truepos simulate comp, seed {seed}), µrad, as calibrated.\n\
             # Positive = the angle between the positive axes is smaller than 90°; xy adds (0, xy·x, 0),\n\
             # xz adds (xz·z, 0, 0), yz adds (0, yz·z, 0) to the volumetric error.\n\
             # u_*: standard uncertainty (k = 1) of each, the calibration's noise.\n\
             [squareness]\n\
             # between X and Y (µrad)\nxy_urad = {}\nu_xy_urad = {us}\n\
             # between X and Z (µrad)\nxz_urad = {}\nu_xz_urad = {us}\n\
             # between Y and Z (µrad)\nyz_urad = {}\nu_yz_urad = {us}\n",
            sq.xy * 1e6,
            sq.xz * 1e6,
            sq.yz * 1e6
        )
        .as_bytes(),
    )?;
    Ok(())
}

/// `points.csv` of the `comp` data set: the indicated probe-tip points with their ids.
fn write_comp_points(pts_p: &Path, d: &CompData, seed: u64) -> Result<()> {
    let t = d.tool;
    let mut f = AtomicFile::create(pts_p)?;
    {
        // 7 decimals: 0.1 nm, far below the probing noise; outputs keep this precision.
        let mut w =
            CsvWriter::new(std::io::BufWriter::new(&mut f)).with_format(truepos_io::num::NumFormat::Fixed(7));
        w.comment(&format!(
            "{} points measured on the virtual bridge CMM (seed {seed}): x_mm,y_mm,z_mm are the indicated probe-tip coordinates (mm), probe {},{},{} mm from the ram.",
            d.indicated.len(), t.x, t.y, t.z
        ))?;
        w.comment("Their true positions are true_points_mm in truth.json (same order, same ids).")?;
        w.header(&["id", "x_mm", "y_mm", "z_mm"])?;
        for (i, p) in d.indicated.iter().enumerate() {
            w.field_str(&format!("P{}", i + 1))?;
            w.row_f64(&[p.x, p.y, p.z])?;
        }
        std::io::Write::flush(&mut w.into_inner())?;
    }
    f.commit()?;
    Ok(())
}

/// The `comp` data set's points corrected through its calibrated map, against the truth.
pub struct CompCheck {
    /// 3D error of each point before and after correction (µm).
    pub before_um: Vec<f64>,
    /// 3D error of each point after correction, µm.
    pub after_um: Vec<f64>,
    /// Per point and coordinate: the residual `corrected − true` and its expanded uncertainty
    /// (k = 2) propagated from the map's uncertainties (µm).
    pub residual_um: Vec<[f64; 3]>,
    /// Expanded uncertainty (k = 2) of each residual coordinate, µm.
    pub expanded_u_um: Vec<[f64; 3]>,
}

impl CompCheck {
    /// Fraction of coordinates whose residual lies within ±U.
    pub fn coverage(&self) -> f64 {
        let n = 3 * self.residual_um.len();
        let inside = self
            .residual_um
            .iter()
            .zip(&self.expanded_u_um)
            .flat_map(|(r, u)| (0..3).map(move |k| r[k].abs() <= u[k]))
            .filter(|&b| b)
            .count();
        inside as f64 / n.max(1) as f64
    }

    /// Median of |residual| / U over all coordinates.
    pub fn median_ratio(&self) -> f64 {
        let mut r: Vec<f64> = self
            .residual_um
            .iter()
            .zip(&self.expanded_u_um)
            .flat_map(|(r, u)| (0..3).map(move |k| r[k].abs() / u[k]))
            .collect();
        r.sort_by(f64::total_cmp);
        r.get(r.len() / 2).copied().unwrap_or(f64::NAN)
    }

    /// The largest |residual| of any coordinate (µm), and the U of that coordinate.
    pub fn worst(&self) -> (f64, f64) {
        let mut w = (0.0, 0.0);
        for (r, u) in self.residual_um.iter().zip(&self.expanded_u_um) {
            for k in 0..3 {
                if r[k].abs() > w.0 {
                    w = (r[k].abs(), u[k]);
                }
            }
        }
        w
    }
}

/// Correct the points of `d` through its map with the propagated uncertainty and compare them
/// with the truth.
pub fn comp_check(d: &CompData) -> Result<CompCheck> {
    let corr = Corrector { geometric: Some(&d.map), load: None, probe_offset: d.tool };
    let n = d.indicated.len();
    let (mut before_um, mut after_um) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let (mut residual_um, mut expanded_u_um) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for (p, t) in d.indicated.iter().zip(&d.actual) {
        let (disp, var) = corr.displacement_u(p).map_err(|e| CellError::Failed(format!("comp: {e}")))?;
        let r = (p + disp - t) * 1e3;
        before_um.push((p - t).norm() * 1e3);
        after_um.push(r.norm());
        residual_um.push([r.x, r.y, r.z]);
        expanded_u_um.push([2e3 * var.x.sqrt(), 2e3 * var.y.sqrt(), 2e3 * var.z.sqrt()]);
    }
    Ok(CompCheck { before_um, after_um, residual_um, expanded_u_um })
}

/// Tolerance of the demo's corrected points (µm per coordinate): what a laser-calibrated CMM map
/// is held to after correction.
pub const COMP_TOL_UM: f64 = 1.0;

/// Demo: a bridge CMM with realistic geometric errors; its 21-parameter map as a calibration
/// delivers it (every 5 mm, with the calibration's noise and its stated uncertainty), measured
/// points corrected with the map and compared with the exact (non-linearised) kinematic chain of
/// the simulator; the corrected points' uncertainty propagated from the map's.
pub fn comp_section(report: &mut Report) -> Result<()> {
    let d = comp_data(SEED)?;
    let c = comp_check(&d)?;
    let (mags, errors, step) = (&d.mags, &d.errors, d.step);
    let stats = |v: &[f64]| (truepos_math::stats::rms(v), v.iter().copied().fold(0.0_f64, f64::max));
    let (rb, mb) = stats(&c.before_um);
    let (ra, ma) = stats(&c.after_um);
    let (worst, u_worst) = c.worst();
    let u_max = c.expanded_u_um.iter().flatten().copied().fold(0.0_f64, f64::max);
    let (coverage, ratio) = (c.coverage(), c.median_ratio());
    let tol_um = COMP_TOL_UM;
    report.verdict(Verdict {
        section: "comp".into(),
        capability: "Geometric map correction (comp)".into(),
        measured: "400 points in the working volume of a bridge CMM, probe 150 mm below the ram".into(),
        truth: format!(
            "exact rigid-body kinematic chain of the simulator (uncorrected: RMS {rb:.2} µm, max {mb:.2} µm)"
        ),
        result: format!(
            "after correction: RMS {ra:.3} µm (3D), largest coordinate residual {worst:.3} µm; {:.1} % of the 1200 coordinates within their ±U (median |residual|/U {ratio:.2})",
            100.0 * coverage
        ),
        uncertainty: format!(
            "U (k = 2) of each corrected coordinate propagated from the map's stated calibration uncertainties (u_* columns: 0.05 µm positioning, 0.1 µm straightness, 0.05/0.05/0.1 µrad pitch/yaw/roll, 0.2 µrad squareness) through the 21-parameter model with its Abbe lever arms, plus the linear interpolation's: U = {u_worst:.3} µm at the largest residual, at most {u_max:.3} µm"
        ),
        tolerance_text: format!(
            "every corrected coordinate within {tol_um} µm of the truth (U: the largest of the 1200; the coverage of U itself is proven over 100 maps in crates/cell/tests/comp_coverage.rs)"
        ),
        ..Verdict::judged(Judgement::new(worst, u_max, tol_um, "µm", DecisionRule::Simple))
    });
    // Two histograms, each on its own range: after correction the errors are a hundred times
    // smaller and would fill one bin of the uncorrected range. After correction the histogram
    // is of what is judged, each coordinate's |residual|; the tolerance is drawn on both (a 3D
    // error below it puts every coordinate below it) and the largest U beside it.
    let tol_label = format!("tolerance {tol_um} µm per coordinate");
    let u_label = format!("largest U (k = 2) {u_max:.3} µm");
    let tol_mark = [report::Mark { label: &tol_label, value: tol_um }];
    let hist_before = report::histogram(
        "3D error of the points before map correction",
        "3D error (µm)",
        &[("before correction", &c.before_um)],
        40,
        None,
        &tol_mark,
    )?;
    let coords: Vec<f64> = c.residual_um.iter().flat_map(|r| r.map(f64::abs)).collect();
    let hist_after = report::histogram(
        "Coordinate residuals after map correction",
        "|corrected − true| per coordinate (µm)",
        &[("after correction (x, y, z)", &coords)],
        40,
        None,
        &[tol_mark[0], report::Mark { label: &u_label, value: u_max }],
    )?;
    let hist = format!("{hist_before}{hist_after}");
    let rows = vec![
        vec!["before correction".into(), format!("{rb:.2}"), format!("{mb:.2}")],
        vec!["after correction".into(), format!("{ra:.3}"), format!("{ma:.3}")],
    ];
    let html = format!(
        "<p>A bridge CMM ({} × {} × {} mm travel, chain bed → Y → X → Z) with realistic geometric errors drawn by the simulator (seed {SEED}): 18 component errors as smooth polynomials plus short-wave periodic errors, 3 squareness errors (xy {:.1}, xz {:.1}, yz {:.1} µrad). The map truepos uses is what a simulated calibration delivers: the errors sampled every {step} mm, each value with the calibration's noise, whose standard uncertainty the map states in its u_* columns. The corrected points' uncertainty is propagated from those through the model (first order, with the Abbe lever arms and the probe offset, plus the linear interpolation's). The truth is the exact chain with full rotation matrices, which the first-order map model only approximates. Reproduce: <code>truepos simulate comp --out DIR</code>, then the printed <code>truepos comp correct</code> command (its output has u_x_um,u_y_um,u_z_um).</p>{}{}",
        mags.travel[0], mags.travel[1], mags.travel[2],
        errors.squareness.xy * 1e6, errors.squareness.xz * 1e6, errors.squareness.yz * 1e6,
        report::table(&["points", "RMS 3D error (µm)", "max 3D error (µm)"], &rows),
        hist
    );
    report.add("comp", "Geometric error map correction", html);
    Ok(())
}

/// Reference targets of a 10 m × 3 m part (mm) and the same part measured warm, moved and
/// rotated, with 10 µm (σ per axis) tracker noise.
fn part_targets(rng: &mut impl Rng) -> (Vec<Point3>, Vec<Point3>, Transform3, f64) {
    let reference: Vec<Point3> = (0..12)
        .map(|i| {
            Point3::new(
                (i % 6) as f64 * 2000.0,
                (i / 6) as f64 * 3000.0,
                if i % 3 == 0 { 150.0 } else { 0.0 },
            )
        })
        .collect();
    // Aluminium (23.1 ppm/°C) at 24 °C against a 20 °C reference.
    let scale = 1.0 + 23.1e-6 * 4.0;
    let placement = Transform3 {
        scale,
        ..Transform3::rigid(rz(0.002) * ry(1e-4) * rx(-2e-4), Vector3::new(1500.0, 400.0, 820.0))
    };
    let sigma = 0.010;
    let measured = reference
        .iter()
        .map(|p| {
            placement.apply(p)
                + Vector3::new(
                    noise::gaussian(rng, sigma),
                    noise::gaussian(rng, sigma),
                    noise::gaussian(rng, sigma),
                )
        })
        .collect();
    (reference, measured, placement, sigma)
}

/// Demo: the part's scale factor from 12 targets against the true thermal scale.
pub fn autoscale_section(report: &mut Report) -> Result<()> {
    let mut rng = noise::stream(SEED, 32);
    let (reference, measured, truth, sigma) = part_targets(&mut rng);
    let (f, _) = truepos_somac::scale::fit_scale(&reference, &measured)?;
    let err_ppm = (f.scale - truth.scale) * 1e6;
    let u_ppm = f.u_scale * 1e6;
    // Tolerance: |error| ≤ 2u (k = 2), and u itself must show the 10 µm noise over the 10 m
    // part is resolved to better than 2 ppm.
    let pass = err_ppm.abs() <= 2.0 * u_ppm && u_ppm < 2.0;
    report.verdict(Verdict {
        section: "autoscale".into(),
        capability: "Part scale (autoscale)".into(),
        measured: format!("scale factor of a 10 m × 3 m aluminium part from {} targets", f.n),
        truth: format!("{:.9} (23.1 ppm/°C × 4 °C = {:+.1} ppm)", truth.scale, (truth.scale - 1.0) * 1e6),
        result: format!("{:.9} ({:+.2} ppm; error {err_ppm:+.2} ppm)", f.scale, (f.scale - 1.0) * 1e6),
        uncertainty: format!("U = {:.2} ppm (k = 2)", 2.0 * u_ppm),
        tolerance_text: "|error| ≤ 4 ppm, with U < 4 ppm".into(),
        ..Verdict::judged(
            Judgement::new(err_ppm, 2.0 * u_ppm, 4.0, "ppm", DecisionRule::Simple)
                .require(pass, "|error| > U"),
        )
    });
    let html = format!(
        "<p>Twelve targets of a part measured 4 °C warm, moved and rotated, with {:.0} µm tracker noise per axis (seed {SEED}). truepos fits measured = s·R·reference + t and reports s with its uncertainty from the residuals (RMS {:.1} µm). Reproduce: <code>truepos autoscale --reference reference.csv --measured measured.csv --cte-ppm-per-c 23.1 --temperature-c 24</code>.</p>{}",
        sigma * 1e3,
        f.rms_mm * 1e3,
        report::table(
            &["source", "scale", "ppm", "U (ppm, k = 2)"],
            &[
                vec!["truth".into(), format!("{:.9}", truth.scale), format!("{:+.2}", (truth.scale - 1.0) * 1e6), "—".into()],
                vec!["truepos".into(), format!("{:.9}", f.scale), format!("{:+.2}", (f.scale - 1.0) * 1e6), format!("{:.2}", 2.0 * u_ppm)],
            ],
        )
    );
    report.add("autoscale", "Part scale from its targets (autoscale)", html);
    Ok(())
}

/// Demo: the part's placement from its targets (rigid fit), applied to program positions,
/// against the true placement.
pub fn orient_section(report: &mut Report) -> Result<()> {
    let mut rng = noise::stream(SEED, 33);
    let (reference, measured, truth, sigma) = part_targets(&mut rng);
    let est = bestfit::best_fit(&reference, &measured, None, BestFitOptions { with_scale: true })?;
    // Program positions: holes along the part.
    let holes: Vec<Point3> = (0..21).map(|i| Point3::new(i as f64 * 500.0, 1500.0, 0.0)).collect();
    let dev: Vec<f64> = holes.iter().map(|p| (est.apply(p) - truth.apply(p)).norm() * 1e3).collect();
    let max = dev.iter().copied().fold(0.0_f64, f64::max);
    let rms = truepos_math::stats::rms(&dev);
    // Tolerance: 12 targets with σ = 10 µm per axis: the fitted position at a hole inside the
    // target pattern is known to about σ·√(7/12)·√3 ≈ 13 µm (1σ, 3D); 30 µm is about 2σ.
    let tol = 30.0;
    let orient_u_um = 2.0 * sigma * 1e3 * (7.0_f64 / 12.0).sqrt() * 3.0_f64.sqrt();
    report.verdict(Verdict {
        section: "orient".into(),
        capability: "Program re-orientation (orient)".into(),
        measured: format!("placement of the part from {} targets, applied to {} program positions", reference.len(), holes.len()),
        truth: "the simulator's placement (rotation 2 mrad about Z, small tilts, moved 1.5 m, 0.4 m, 0.82 m; scaled)".into(),
        result: format!("oriented positions off the truth by RMS {rms:.1} µm, max {max:.1} µm"),
        uncertainty: format!("U ≈ {orient_u_um:.0} µm (k = 2) at a position, from the {:.0} µm target noise", sigma * 1e3),
        tolerance_text: format!("every position within {tol:.0} µm"),
        ..Verdict::judged(Judgement::new(max, orient_u_um, tol, "µm", DecisionRule::Simple))
    });
    let html = format!(
        "<p>The program of the part (21 holes along y = 1500 mm) is carried through the best-fit transform of the measured targets (same data as autoscale, with scale). Reproduce: <code>truepos orient --reference reference.csv --measured measured.csv --program part.nc --output oriented.nc --scale</code>.</p>{}",
        report::table(
            &["quantity", "RMS (µm)", "max (µm)"],
            &[vec!["oriented − true position".into(), format!("{rms:.1}"), format!("{max:.1}")]]
        )
    );
    report.add("orient", "Re-orientation through measured targets (orient)", html);
    Ok(())
}

/// Demo: refractive index of air against NIST's published calculator values.
pub fn air_section(report: &mut Report) -> Result<()> {
    use truepos_math::air::{refractive_index, AirConditions, Formula};
    // NIST Engineering Metrology Toolbox (Ciddor), 20 °C, 101 325 Pa, 50 % RH, 450 ppm CO2,
    // printed to 9 decimals.
    let cases = [(633.0, 1.000271373), (500.0, 1.000273781), (1000.987, 1.000269038)];
    let mut rows = Vec::new();
    let mut worst = 0.0_f64;
    for (wl, truth) in cases {
        let c = AirConditions {
            temperature_c: 20.0,
            pressure_pa: 101_325.0,
            humidity_pct: 50.0,
            co2_ppm: 450.0,
            wavelength_nm: wl,
        };
        let n = refractive_index(&c, Formula::Ciddor)?;
        let d = (n - truth) * 1e9;
        worst = worst.max(d.abs());
        rows.push(vec![format!("{wl}"), format!("{truth:.9}"), format!("{n:.9}"), format!("{d:+.2}")]);
    }
    report.verdict(Verdict {
        section: "air".into(),
        capability: "Refractive index of air (air)".into(),
        measured: "n (Ciddor) at 20 °C, 101 325 Pa, 50 % RH, 450 ppm CO₂, three wavelengths".into(),
        truth: "NIST online calculator values, printed to 1 × 10⁻⁹".into(),
        result: format!("worst |n − n_NIST| = {worst:.2} × 10⁻⁹"),
        uncertainty: format!("U = {AIR_COMPARISON_U_PPB} × 10⁻⁹ (k = 2) of the comparison: the NIST values' rounding to 10⁻⁹ is inside the tolerance, and double-precision evaluation adds < 10⁻¹⁵ (the Ciddor equation's own 2 × 10⁻⁸ is the same in both and cancels)"),
        tolerance_text: "|n − n_NIST| ≤ 0.5 × 10⁻⁹ (half the last printed digit)".into(),
        ..Verdict::judged(Judgement::new(worst, AIR_COMPARISON_U_PPB, 0.5, "1e-9", DecisionRule::Simple))
    });
    let html = format!(
        "<p>The Ciddor equation as implemented by truepos against values printed by NIST's calculator. Reproduce: <code>truepos air --temperature-c 20 --pressure-pa 101325 --humidity-pct 50 --wavelength-nm 633</code>.</p>{}",
        report::table(&["wavelength (nm)", "NIST", "truepos", "difference (10⁻⁹)"], &rows)
    );
    report.add("air", "Refractive index of air", html);
    Ok(())
}
