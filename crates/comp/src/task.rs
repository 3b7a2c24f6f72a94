//! The commands of `truepos comp` and `truepos load` as library calls: each reads its files,
//! computes, writes its outputs atomically and returns a [`Report`] (the contract's JSON and the
//! human text). The binary parses arguments, calls one of these and prints.
//!
//! Entry points: [`correct`] (`comp correct`), [`errors_at`] (`comp error`), [`influence_map`]
//! (`load map`), [`load_correct`] (`load correct`), [`curves`] (`load curves`), [`deflection`]
//! (`load deflection`); [`MapFiles::read`] for the geometric map with its squareness file.
//!
//! Errors: input problems are [`InputError`]s naming file, line and column; a task that also
//! writes returns [`RewriteError`] (input or output, the output error telling a bad path from a
//! failed write).

use crate::files::{
    read_bed, read_influence, read_load, read_map, read_squareness_u, write_influence, LoadCase,
};
use crate::stream::{correct_file, Mode, Summary, COVERAGE_FACTOR};
use crate::{fe_map, Chain, CompError, Corrector, GeometricMap, LoadCorrection, PortalCurves};
use serde_json::{json, Value};
use std::fmt::Write;
use std::path::{Path, PathBuf};
use truepos_fe::MeshOptions;
use truepos_io::atomic::OutputError;
use truepos_io::csv::Table;
use truepos_io::num::NumFormat;
use truepos_io::report::Report;
use truepos_io::stream::RewriteError;
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};

/// Where the geometric map comes from and how it is applied.
#[derive(Clone, Debug)]
pub struct MapFiles {
    /// The map CSV (`axis,position_mm,pos_um,…`).
    pub map: PathBuf,
    /// Squareness, TOML or one-row CSV; none: zero.
    pub squareness: Option<PathBuf>,
    /// Which axis carries which.
    pub chain: Chain,
    /// Hold a table's end values outside its range instead of refusing the point.
    pub clamp: bool,
}

impl MapFiles {
    /// The full map: tables, squareness, chain and range policy.
    pub fn read(&self) -> Result<GeometricMap, InputError> {
        let mut map = read_map(&self.map)?;
        if let Some(s) = &self.squareness {
            (map.squareness, map.squareness_u) = read_squareness_u(s)?;
        }
        map.chain = self.chain;
        map.clamp = self.clamp;
        Ok(map)
    }
}

/// A streamed correction done (`comp correct`, `load correct`).
#[derive(Clone, Debug)]
pub struct Corrected {
    /// What the correction did.
    pub summary: Summary,
    /// The output file written.
    pub output: PathBuf,
    /// Measured points or commanded positions.
    pub mode: Mode,
    /// The load case applied (`load correct` only).
    pub load: Option<LoadCase>,
}

impl Corrected {
    /// The note of an E57 input whose points were dropped (marked invalid in the file, or with a
    /// NaN or infinite coordinate): `None` when none was. Printed on stderr with or without
    /// `--json` (whose object carries the counts too).
    pub fn dropped_note(&self) -> Option<String> {
        let s = &self.summary;
        if s.dropped_invalid + s.dropped_nonfinite == 0 {
            return None;
        }
        Some(format!(
            "note: {} points of the E57 input dropped (not in the output): {} marked invalid in the file, {} with a NaN or infinite coordinate",
            s.dropped_invalid + s.dropped_nonfinite,
            s.dropped_invalid,
            s.dropped_nonfinite
        ))
    }

    /// The warning of a `comp correct` whose map states no uncertainty (`None` otherwise).
    pub fn uncertainty_warning(&self) -> Option<String> {
        match (&self.load, &self.summary.uncertainty) {
            (None, Err(why)) => Some(format!(
                "warning: the map's uncertainty is unknown ({why}): the corrected points carry no uncertainty"
            )),
            _ => None,
        }
    }
}

impl Report for Corrected {
    fn to_json(&self) -> Value {
        let s = &self.summary;
        let mut j = json!({
            "n_points": s.n_points,
            "output": self.output.display().to_string(),
            "rms_correction_um": s.rms_um,
            "max_correction_um": s.max_um,
            "dropped_invalid_points": s.dropped_invalid,
            "dropped_nonfinite_points": s.dropped_nonfinite,
        });
        match &self.load {
            Some(case) => {
                j["forces_n"] = json!(case.loads.iter().map(|l| l.2).collect::<Vec<_>>());
                j["weight_n"] = json!(case.weight_n);
            }
            None => {
                j["mode"] = json!(match self.mode {
                    Mode::Commanded => "commanded",
                    Mode::Measured => "measured",
                });
            }
        }
        if self.mode == Mode::Commanded {
            j["max_iterations"] = json!(s.iterations);
        }
        if self.load.is_none() {
            j["coverage_factor"] = json!(COVERAGE_FACTOR);
            match &s.uncertainty {
                Ok(u) => {
                    j["uncertainty_method"] = json!("map-propagation");
                    j["max_expanded_uncertainty_um"] = json!(u.max_um);
                    j["median_expanded_uncertainty_um"] = json!(u.median_um);
                }
                Err(why) => {
                    j["uncertainty_method"] = json!("unknown");
                    j["uncertainty_unknown"] = json!(why);
                }
            }
        }
        j
    }

    fn text(&self) -> String {
        let s = &self.summary;
        let mut t = format!(
            "{} points {}; correction rms {:.3} µm, max {:.3} µm → {}\n",
            s.n_points,
            if self.mode == Mode::Commanded { "compensated" } else { "corrected" },
            s.rms_um,
            s.max_um,
            self.output.display()
        );
        if let Some(n) = self.dropped_note() {
            t.push_str(&n);
            t.push('\n');
        }
        if self.load.is_none() {
            match &s.uncertainty {
                Ok(u) => {
                    let _ = writeln!(
                        t,
                        "uncertainty (map propagation, k = {COVERAGE_FACTOR}): U x/y/z median {:.3}/{:.3}/{:.3} µm, max {:.3}/{:.3}/{:.3} µm (u_x_um,u_y_um,u_z_um in the output are k = 1)",
                        u.median_um[0], u.median_um[1], u.median_um[2], u.max_um[0], u.max_um[1], u.max_um[2]
                    );
                }
                Err(_) => {
                    if let Some(w) = self.uncertainty_warning() {
                        t.push_str(&w);
                        t.push('\n');
                    }
                }
            }
        }
        t
    }

    fn text_on_stderr(&self) -> bool {
        true
    }
}

/// `comp correct`: correct the measured points of `points` (or compensate the targets,
/// [`Mode::Commanded`]) through the geometric map into `output`, streamed.
pub fn correct(
    map: &GeometricMap,
    probe_offset: Vector3,
    points: &Path,
    output: &Path,
    mode: Mode,
    format: NumFormat,
) -> Result<Corrected, RewriteError> {
    let corr = Corrector { geometric: Some(map), load: None, probe_offset };
    let summary = correct_file(&corr, points, output, mode, format, "")?;
    Ok(Corrected { summary, output: output.to_path_buf(), mode, load: None })
}

/// The volumetric error at the points of a file (`comp error`).
#[derive(Clone, Debug)]
pub struct ErrorsAt {
    /// The points, machine frame, mm.
    pub points: Vec<Point3>,
    /// E(p − t; t) at each point, mm.
    pub errors: Vec<Vector3>,
    /// The CSV written, if one was asked for (then the text is empty).
    pub output: Option<PathBuf>,
}

impl Report for ErrorsAt {
    fn to_json(&self) -> Value {
        json!({
            "n_points": self.points.len(),
            "error_um": self.errors.iter().map(|v| [v.x * 1e3, v.y * 1e3, v.z * 1e3]).collect::<Vec<_>>(),
        })
    }

    fn text(&self) -> String {
        let mut out = String::new();
        if self.output.is_none() {
            for (p, v) in self.points.iter().zip(&self.errors) {
                let (x, y, z) = (v.x * 1e3, v.y * 1e3, v.z * 1e3);
                let _ = writeln!(out, "{:.4} {:.4} {:.4}  →  {x:+.4} {y:+.4} {z:+.4} µm", p.x, p.y, p.z);
            }
        }
        out
    }
}

/// `comp error`: the map's error at the tip points of `at` (`x_mm,y_mm,z_mm`), also written as
/// CSV to `output` when given. A point outside the map is an input error on its line.
pub fn errors_at(
    map: &GeometricMap,
    probe_offset: Vector3,
    at: &Path,
    output: Option<&Path>,
) -> Result<ErrorsAt, RewriteError> {
    let t = Table::read(at)?;
    let points = table_points(&t)?;
    let corr = Corrector { geometric: Some(map), load: None, probe_offset };
    let errors = corr.displacements(&points).map_err(|e| batch_error(&t, e))?;
    if let Some(out) = output {
        crate::files::write_errors(out, &points, &errors).map_err(|e| OutputError::from_io(out, e))?;
    }
    Ok(ErrorsAt { points, errors, output: output.map(Path::to_path_buf) })
}

/// Points of a CSV table (`x_mm,y_mm,z_mm`).
pub fn table_points(t: &Table) -> Result<Vec<Point3>, InputError> {
    let v = t.f64_columns(&["x_mm", "y_mm", "z_mm"])?;
    Ok(v.chunks_exact(3).map(|c| Point3::new(c[0], c[1], c[2])).collect())
}

/// A refused point of a batch as an input error on its line.
pub fn batch_error(t: &Table, e: CompError) -> InputError {
    InputError::at(&t.path, t.line_number(e.index()), None, e.to_string())
}

/// The FE mesh: the command line's element size, else the bed file's, else automatic (0).
pub fn mesh_options(element_size_mm: Option<f64>, from_file: Option<f64>) -> Result<MeshOptions, InputError> {
    let s = element_size_mm.or(from_file).unwrap_or(0.0);
    if !(s.is_finite() && s >= 0.0) {
        return Err(InputError::new(format!("element size must be a positive number of mm (got {s})")));
    }
    Ok(MeshOptions::with_element_size(s))
}

/// An influence map computed and written (`load map`).
#[derive(Clone, Debug)]
pub struct MapWritten {
    /// The influence map file written.
    pub output: PathBuf,
    /// Number of load positions.
    pub n_loads: usize,
    /// Number of portal positions.
    pub n_portal_positions: usize,
    /// The unit load, N.
    pub unit_load_n: f64,
    /// Wall time of the computation, s.
    pub seconds: f64,
}

impl Report for MapWritten {
    fn to_json(&self) -> Value {
        json!({
            "output": self.output.display().to_string(),
            "n_loads": self.n_loads,
            "n_portal_positions": self.n_portal_positions,
            "unit_load_n": self.unit_load_n,
            "seconds": self.seconds,
        })
    }

    fn text(&self) -> String {
        format!(
            "{} unit loads × {} portal positions in {:.1} s → {}\n",
            self.n_loads,
            self.n_portal_positions,
            self.seconds,
            self.output.display()
        )
    }

    fn text_on_stderr(&self) -> bool {
        true
    }
}

/// `load map`: the influence map of the bed's plate model, written to `output`.
/// `progress(done, total)` is called as unit loads are solved (from any thread).
pub fn influence_map(
    bed: &Path,
    output: &Path,
    element_size_mm: Option<f64>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<MapWritten, RewriteError> {
    let (model, es) = read_bed(bed)?.into_model(bed)?;
    let mesh = mesh_options(element_size_mm, es)?;
    let (xs, ys) = fe_map::load_grid(&model).map_err(|e| InputError::in_file(bed, e.to_string()))?;
    let n_loads = xs.len() * ys.len();
    let t0 = std::time::Instant::now();
    let map = fe_map::influence_map(&model, &mesh, &|k| progress(k, n_loads))
        .map_err(|e| InputError::in_file(bed, e.to_string()))?;
    let size = if mesh.element_size > 0.0 { format!("{} mm", mesh.element_size) } else { "automatic".into() };
    let note = format!("plate FE of {} (element size {size})", bed.display());
    write_influence(&map, output, &note).map_err(|e| OutputError::from_io(output, e))?;
    Ok(MapWritten {
        output: output.to_path_buf(),
        n_loads,
        n_portal_positions: map.portal_y().len(),
        unit_load_n: map.unit_load_n,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The portal's curves under a load case (`load curves`).
pub struct Curves {
    /// Portal pitch and roll along Y.
    pub curves: PortalCurves,
    /// The resolved load case.
    pub case: LoadCase,
}

impl Report for Curves {
    fn to_json(&self) -> Value {
        crate::json::curves(&self.curves, &self.case)
    }

    fn text(&self) -> String {
        crate::json::curves_text(&self.curves, &self.case)
    }
}

/// `load curves`: pitch and roll along the portal's travel under the load case (the influence
/// map of `map` superposed for the loads of `load`).
pub fn curves(map: &Path, load: &Path) -> Result<Curves, InputError> {
    let m = read_influence(map)?;
    let case = read_load(load)?;
    let curves = m
        .superpose(&case.loads)
        .map_err(|e| InputError::in_file(load, format!("{e} ({})", map.display())))?;
    Ok(Curves { curves, case })
}

/// `load correct`: correct measured points for the load case (and the geometric map, when
/// given) into `output`, streamed. `bed` gives the portal (rails and their height).
#[allow(clippy::too_many_arguments)]
pub fn load_correct(
    map: &Path,
    load: &Path,
    bed: &Path,
    geometric: Option<&GeometricMap>,
    probe_offset: Vector3,
    points: &Path,
    output: &Path,
    format: NumFormat,
) -> Result<Corrected, RewriteError> {
    let Curves { curves, case } = curves(map, load)?;
    let portal = read_bed(bed)?.portal.ok_or_else(|| {
        InputError::in_file(bed, "[portal] section (rail_x_mm, rail_height_mm, …) is required")
    })?;
    let lc = LoadCorrection::new(curves, &portal);
    let corr = Corrector { geometric, load: Some(&lc), probe_offset };
    let hint = format!(" (the influence map {} covers portal y only over this range)", map.display());
    let summary = correct_file(&corr, points, output, Mode::Measured, format, &hint)?;
    Ok(Corrected { summary, output: output.to_path_buf(), mode: Mode::Measured, load: Some(case) })
}

/// The bed's deflection under a load case at given points (`load deflection`).
pub struct Deflection {
    /// The points (x, y), mm.
    pub at: Vec<[f64; 2]>,
    /// uz, mm, positive up.
    pub uz_mm: Vec<f64>,
    /// The resting points' forces, N.
    pub forces_n: Vec<f64>,
}

impl Report for Deflection {
    fn to_json(&self) -> Value {
        json!({ "uz_mm": self.uz_mm, "forces_n": self.forces_n })
    }

    fn text(&self) -> String {
        let mut out = String::new();
        for (p, u) in self.at.iter().zip(&self.uz_mm) {
            let _ = writeln!(out, "{:.3} {:.3}  uz {:+.6} mm", p[0], p[1], u);
        }
        out
    }
}

/// `load deflection`: uz of the bed's plate model under the load case at the `x_mm,y_mm`
/// points of `at`; a point outside the bed is an input error on its line.
pub fn deflection(
    bed: &Path,
    load: &Path,
    at: &Path,
    element_size_mm: Option<f64>,
) -> Result<Deflection, InputError> {
    let (plate, es) =
        read_bed(bed)?.bed.ok_or_else(|| InputError::in_file(bed, "[bed] section is required"))?;
    let case = read_load(load)?;
    let mesh = mesh_options(element_size_mm, es)?;
    let t = Table::read(at)?;
    let xy = t.f64_columns(&["x_mm", "y_mm"])?;
    let points: Vec<[f64; 2]> = xy.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
    let uz = fe_map::deflection_at(&plate, &mesh, &case.loads, &points).map_err(|e| match e {
        truepos_fe::FeError::InvalidLoad { .. } => InputError::in_file(load, format!("{e}")),
        _ => InputError::in_file(bed, format!("plate model: {e}")),
    })?;
    let uz_mm = uz
        .iter()
        .enumerate()
        .map(|(i, u)| {
            u.ok_or_else(|| {
                let [x, y] = points[i];
                InputError::at(at, t.line_number(i), None, format!("point ({x}, {y}) mm is outside the bed"))
            })
        })
        .collect::<Result<Vec<f64>, _>>()?;
    Ok(Deflection { at: points, uz_mm, forces_n: case.loads.iter().map(|l| l.2).collect() })
}
