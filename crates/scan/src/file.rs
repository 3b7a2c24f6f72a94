//! The files of `truepos scan`, each defined once: the features file (TOML: `[[feature]]`
//! tables and top-level scan parameters; [`FeaturesFile`], read by [`read_features`] with
//! [`ParamOverrides`], the command line's options of the same names), the planned path CSV
//! ([`write_path`]) and the measured points CSV ([`write_points`]), each as Parquet instead for a
//! `.parquet` path (same column names). Unknown keys are errors;
//! errors name the file, and the line of the feature's `id` where there is one.

use crate::execute::Run;
use crate::feature::{validate, Feature, Geometry, Params, Side};
use crate::plan::{PathSample, Plan};
use crate::ScanError;
use serde::Deserialize;
use std::io::Write;
use std::path::Path;
use truepos_io::atomic::AtomicFile;
use truepos_io::csv::CsvWriter;
use truepos_io::parquet_file::{is_parquet, write_columns, ColumnData, Columns};
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};

/// Why a features file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum FeaturesError {
    /// The file is unreadable, malformed or describes an impossible feature.
    #[error(transparent)]
    Input(#[from] InputError),
    /// A parameter is out of its allowed range (a usage error whether it came from the file or
    /// an override).
    #[error(transparent)]
    Usage(ScanError),
}

/// Values that replace the file's top-level parameters (mm, mm/s, mm/s², degrees).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamOverrides {
    /// Approach angle, degrees.
    pub approach_angle_deg: Option<f64>,
    /// Scanning speed, mm/s.
    pub scan_speed_mm_s: Option<f64>,
    /// Transfer speed, mm/s.
    pub move_speed_mm_s: Option<f64>,
    /// Target deflection, mm.
    pub deflection_mm: Option<f64>,
    /// Settle overshoot, mm.
    pub overshoot_mm: Option<f64>,
    /// The two quality bands, mm.
    pub quality_bands_mm: Option<[f64; 2]>,
    /// Stylus tip radius, mm.
    pub tip_radius_mm: Option<f64>,
    /// Clearance from the surface, mm.
    pub clearance_mm: Option<f64>,
    /// Acceleration limit, mm/s².
    pub accel_mm_s2: Option<f64>,
    /// Jerk limit (mm/s³); absent in older files: [`crate::feature::DEFAULT_JERK`].
    pub jerk_mm_s3: Option<f64>,
    /// Speed of the classic style's approach along the normal, mm/s.
    pub touch_speed_mm_s: Option<f64>,
}

/// The features TOML file: top-level parameters and the `[[feature]]` tables.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct FeaturesFile {
    /// Approach angle, degrees.
    pub approach_angle_deg: Option<f64>,
    /// Scanning speed, mm/s.
    pub scan_speed_mm_s: Option<f64>,
    /// Transfer speed, mm/s.
    pub move_speed_mm_s: Option<f64>,
    /// Target deflection, mm.
    pub deflection_mm: Option<f64>,
    /// Settle overshoot, mm.
    pub overshoot_mm: Option<f64>,
    /// The two quality bands, mm.
    pub quality_bands_mm: Option<[f64; 2]>,
    /// Stylus tip radius, mm.
    pub tip_radius_mm: Option<f64>,
    /// Clearance from the surface, mm.
    pub clearance_mm: Option<f64>,
    accel_mm_s2: Option<f64>,
    /// Optional (default [`crate::feature::DEFAULT_JERK`]), so older files still read.
    jerk_mm_s3: Option<f64>,
    /// Speed of the classic style's approach along the normal, mm/s.
    pub touch_speed_mm_s: Option<f64>,
    /// The `[[feature]]` tables.
    #[serde(default)]
    pub feature: Vec<FeatureToml>,
}

/// One `[[feature]]` table as written (degrees, mm).
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct FeatureToml {
    /// The feature's id.
    pub id: String,
    /// `circle` or `line`.
    pub kind: String,
    /// Circle centre, mm.
    pub center_mm: Option<[f64; 3]>,
    /// Circle axis (unit vector after normalising).
    pub axis: Option<[f64; 3]>,
    /// Circle radius, mm.
    pub radius_mm: Option<f64>,
    /// `inside` or `outside`.
    pub side: Option<String>,
    /// Start angle of the arc, degrees.
    pub start_deg: Option<f64>,
    /// Signed sweep of the arc, degrees.
    pub sweep_deg: Option<f64>,
    /// Line start, mm.
    pub start_mm: Option<[f64; 3]>,
    /// Line end, mm.
    pub end_mm: Option<[f64; 3]>,
    /// Outward surface normal of a line.
    pub normal: Option<[f64; 3]>,
}

/// Line of `id = "<id>"` in the file (for messages), 1-based.
fn id_line(text: &str, id: &str) -> Option<usize> {
    let quoted = [format!("\"{id}\""), format!("'{id}'")];
    text.lines()
        .position(|l| {
            let t = l.trim_start();
            t.starts_with("id") && quoted.iter().any(|q| t.contains(q.as_str()))
        })
        .map(|i| i + 1)
}

fn feature_error(path: &Path, text: &str, id: &str, msg: String) -> InputError {
    match id_line(text, id) {
        Some(line) => InputError::at(path, line, None, msg),
        None => InputError::in_file(path, msg),
    }
}

fn v3(a: [f64; 3]) -> Vector3 {
    Vector3::new(a[0], a[1], a[2])
}

fn p3(a: [f64; 3]) -> Point3 {
    Point3::new(a[0], a[1], a[2])
}

/// Read a features file, apply the overrides (each replaces the file's key of the same name),
/// validate. Errors in a feature name the line of its `id`.
pub fn read_features(path: &Path, c: &ParamOverrides) -> Result<(Vec<Feature>, Params), FeaturesError> {
    let text = truepos_io::limits::read_config_string(path, "TOML")?;
    let file: FeaturesFile = truepos_io::config::parse_toml(path, &text)?;
    let mut features = Vec::with_capacity(file.feature.len());
    let mut seen = std::collections::HashSet::new();
    for f in &file.feature {
        let err = |m: String| -> FeaturesError {
            FeaturesError::Input(feature_error(path, &text, &f.id, format!("feature '{}': {m}", f.id)))
        };
        if !seen.insert(f.id.clone()) {
            return Err(err("duplicate id".into()));
        }
        let need3 = |v: Option<[f64; 3]>, name: &str| v.ok_or_else(|| err(format!("missing {name}")));
        let geometry = match f.kind.as_str() {
            "circle" => {
                let side = match f.side.as_deref() {
                    Some("inside") => Side::Inside,
                    Some("outside") => Side::Outside,
                    Some("plane") => Side::Plane,
                    Some(s) => return Err(err(format!("side '{s}' is not one of inside, outside, plane"))),
                    None => return Err(err("missing side (inside, outside or plane)".into())),
                };
                Geometry::Circle {
                    center: p3(need3(f.center_mm, "center_mm")?),
                    axis: v3(need3(f.axis, "axis")?),
                    radius: f.radius_mm.ok_or_else(|| err("missing radius_mm".into()))?,
                    side,
                    start: f.start_deg.unwrap_or(0.0).to_radians(),
                    sweep: f.sweep_deg.unwrap_or(360.0).to_radians(),
                }
            }
            "line" => Geometry::Line {
                start: p3(need3(f.start_mm, "start_mm")?),
                end: p3(need3(f.end_mm, "end_mm")?),
                normal: v3(need3(f.normal, "normal")?),
            },
            k => return Err(err(format!("kind '{k}' is not one of circle, line"))),
        };
        features.push(Feature { id: f.id.clone(), geometry });
    }
    let d = Params::default();
    let pick = |cli: Option<f64>, file: Option<f64>, def: f64| cli.or(file).unwrap_or(def);
    let angle_deg = pick(c.approach_angle_deg, file.approach_angle_deg, 45.0);
    let params = Params {
        approach_angle: angle_deg.to_radians(),
        scan_speed: pick(c.scan_speed_mm_s, file.scan_speed_mm_s, d.scan_speed),
        move_speed: pick(c.move_speed_mm_s, file.move_speed_mm_s, d.move_speed),
        deflection: pick(c.deflection_mm, file.deflection_mm, d.deflection),
        overshoot: pick(c.overshoot_mm, file.overshoot_mm, d.overshoot),
        quality_bands: c.quality_bands_mm.or(file.quality_bands_mm).unwrap_or(d.quality_bands),
        tip_radius: pick(c.tip_radius_mm, file.tip_radius_mm, d.tip_radius),
        clearance: pick(c.clearance_mm, file.clearance_mm, d.clearance),
        accel: pick(c.accel_mm_s2, file.accel_mm_s2, d.accel),
        jerk: pick(c.jerk_mm_s3, file.jerk_mm_s3, d.jerk),
        touch_speed: pick(c.touch_speed_mm_s, file.touch_speed_mm_s, d.touch_speed),
        ..d
    };
    match validate(&features, &params) {
        Ok(()) => Ok((features, params)),
        Err(ScanError::Feature { id, why }) => {
            Err(feature_error(path, &text, &id, format!("feature '{id}': {why}")).into())
        }
        Err(e @ ScanError::ApproachAngle(_)) => Err(FeaturesError::Usage(e)),
        // A parameter of the file: at its line (a key the file does not have came from an option).
        Err(e @ (ScanError::Parameter(..) | ScanError::Bands(..))) => {
            let key = match e {
                ScanError::Parameter(k, _) => k,
                _ => "quality_bands_mm",
            };
            let doc = truepos_io::config::TomlDoc { path: path.to_path_buf(), text };
            match doc.locate(&[key]) {
                Some(_) => Err(doc.error_at(&[key], e.to_string()).into()),
                None => Err(FeaturesError::Usage(e)),
            }
        }
        Err(e) => Err(InputError::in_file(path, e.to_string()).into()),
    }
}

/// Columns of the planned path file.
const PATH_COLUMNS: [&str; 7] = ["t_s", "x_mm", "y_mm", "z_mm", "segment", "feature", "speed_mm_s"];

/// Columns of the measured points file.
const POINT_COLUMNS: [&str; 9] =
    ["t_s", "x_mm", "y_mm", "z_mm", "segment", "feature", "deflection_mm", "quality", "target_deflection_mm"];

/// Write a planned path as the contract's CSV (`t_s,x_mm,y_mm,z_mm,segment,feature,speed_mm_s`),
/// atomically; `style` names the style in the comment line. A `.parquet` path gets the same
/// columns as Parquet (`segment` and `feature` as text, the others as doubles; no comment line).
pub fn write_path(path: &Path, pl: &Plan, samples: &[PathSample], style: &str) -> std::io::Result<()> {
    if is_parquet(path) {
        let num = |f: &dyn Fn(&PathSample) -> f64| ColumnData::F64(samples.iter().map(f).collect());
        let seg = |s: &PathSample| &pl.segments[s.segment];
        let cols = Columns {
            names: PATH_COLUMNS.map(String::from).to_vec(),
            data: vec![
                num(&|s| s.t),
                num(&|s| s.position.x),
                num(&|s| s.position.y),
                num(&|s| s.position.z),
                ColumnData::Str(samples.iter().map(|s| seg(s).kind.as_str().to_string()).collect()),
                ColumnData::Str(samples.iter().map(|s| pl.features[seg(s).feature].id.clone()).collect()),
                num(&|s| s.speed),
            ],
        };
        return Ok(write_columns(path, &cols)?);
    }
    let mut f = AtomicFile::create(path)?;
    {
        let mut w = CsvWriter::new(std::io::BufWriter::new(&mut f));
        w.comment(&format!("truepos scan plan, style {}: commanded probe (tip centre) path", style))?;
        w.header(&PATH_COLUMNS)?;
        for s in samples {
            let seg = &pl.segments[s.segment];
            w.field_f64(s.t)?;
            w.field_f64(s.position.x)?;
            w.field_f64(s.position.y)?;
            w.field_f64(s.position.z)?;
            w.field_str(seg.kind.as_str())?;
            w.field_str(&pl.features[seg.feature].id)?;
            w.field_f64(s.speed)?;
            w.end_row()?;
        }
        w.into_inner().flush()?;
    }
    Ok(f.commit()?)
}

/// Write measured points as the contract's CSV (`t_s,x_mm,y_mm,z_mm,segment,feature,
/// deflection_mm,quality,target_deflection_mm`), atomically. A `.parquet` path gets the same
/// columns as Parquet (`segment` and `feature` as text, the others, `quality` too, as doubles;
/// no comment line).
pub fn write_points(
    path: &Path,
    r: &Run,
    features: &[Feature],
    params: &Params,
    style: &str,
) -> std::io::Result<()> {
    if is_parquet(path) {
        let num =
            |f: &dyn Fn(&crate::execute::Point) -> f64| ColumnData::F64(r.points.iter().map(f).collect());
        let cols = Columns {
            names: POINT_COLUMNS.map(String::from).to_vec(),
            data: vec![
                num(&|q| q.t),
                num(&|q| q.position.x),
                num(&|q| q.position.y),
                num(&|q| q.position.z),
                ColumnData::Str(r.points.iter().map(|q| q.segment.as_str().to_string()).collect()),
                ColumnData::Str(r.points.iter().map(|q| features[q.feature].id.clone()).collect()),
                num(&|q| q.deflection),
                num(&|q| f64::from(q.quality)),
                num(&|q| q.target),
            ],
        };
        return Ok(write_columns(path, &cols)?);
    }
    let mut f = AtomicFile::create(path)?;
    {
        let mut w = CsvWriter::new(std::io::BufWriter::new(&mut f));
        w.comment(&format!(
            "truepos scan run, style {}: measured tip centre (scale + probe deflection); quality 0/5/9 from |deflection - target| in bands {} / {} mm",
            style,
            params.quality_bands[0],
            params.quality_bands[1]
        ))?;
        w.header(&POINT_COLUMNS)?;
        for q in &r.points {
            w.field_f64(q.t)?;
            w.field_f64(q.position.x)?;
            w.field_f64(q.position.y)?;
            w.field_f64(q.position.z)?;
            w.field_str(q.segment.as_str())?;
            w.field_str(&features[q.feature].id)?;
            w.field_f64(q.deflection)?;
            w.field_str(&q.quality.to_string())?;
            w.field_f64(q.target)?;
            w.end_row()?;
        }
        w.into_inner().flush()?;
    }
    Ok(f.commit()?)
}

impl truepos_math::exit::HasExitClass for FeaturesError {
    /// A bad features file (2) or a parameter out of range (2).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        match self {
            FeaturesError::Input(_) => ExitClass::Input,
            FeaturesError::Usage(_) => ExitClass::Usage,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn id_line_finds_the_feature() {
        let t = "a = 1\n[[feature]]\nid = \"x1\"\n[[feature]]\n  id = 'y'\n";
        assert_eq!(id_line(t, "x1"), Some(3));
        assert_eq!(id_line(t, "y"), Some(5));
        assert_eq!(id_line(t, "z"), None);
    }
}
