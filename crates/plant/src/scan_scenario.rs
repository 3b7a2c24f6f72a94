//! Bridge from the virtual cell's `scan` scenario (`truepos_sim::scenario::scan`) to
//! `truepos-scan`'s features and parameters, for tests, benches and the demo.
//!
//! Entry points: [`feature`] (one geometry), [`program`] (nominal features, true features and
//! parameters of a scenario), [`write_scenario`] (`features.toml` and `truth.json`),
//! [`read_truth`] (the true part of a `truth.json`).

use serde::Deserialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};
use truepos_scan::{Feature, Geometry, Params, Side};
use truepos_sim::scenario::scan::{ScanGeometry, ScanScenario, ScanSide};

/// A scenario geometry as a [`Feature`] (degrees → radians).
pub fn feature(id: &str, g: &ScanGeometry) -> Feature {
    let geometry = match g {
        ScanGeometry::Circle { center, axis, radius, side, start_deg, sweep_deg } => Geometry::Circle {
            center: *center,
            axis: *axis,
            radius: *radius,
            side: match side {
                ScanSide::Inside => Side::Inside,
                ScanSide::Outside => Side::Outside,
                ScanSide::Plane => Side::Plane,
            },
            start: start_deg.to_radians(),
            sweep: sweep_deg.to_radians(),
        },
        ScanGeometry::Line { start, end, normal } => {
            Geometry::Line { start: *start, end: *end, normal: *normal }
        }
    };
    Feature { id: id.to_string(), geometry }
}

/// (nominal features, true features, parameters) of a scenario.
pub fn program(s: &ScanScenario) -> (Vec<Feature>, Vec<Feature>, Params) {
    let nominal = s.features.iter().map(|f| feature(&f.id, &f.nominal)).collect();
    let truth = s.features.iter().map(|f| feature(&f.id, &f.actual)).collect();
    let params = Params {
        approach_angle: s.approach_angle_deg.to_radians(),
        scan_speed: s.scan_speed_mm_s,
        move_speed: s.move_speed_mm_s,
        deflection: s.deflection_mm,
        overshoot: s.overshoot_mm,
        quality_bands: s.quality_bands_mm,
        ..Params::default()
    };
    (nominal, truth, params)
}

/// A geometry as `truth.json` writes it (degrees, mm).
pub fn geometry_json(g: &Geometry) -> serde_json::Value {
    match g {
        Geometry::Circle { center, axis, radius, side, start, sweep } => json!({
            "kind": "circle",
            "center_mm": [center.x, center.y, center.z],
            "axis": [axis.x, axis.y, axis.z],
            "radius_mm": radius,
            "side": match side { Side::Inside => "inside", Side::Outside => "outside", Side::Plane => "plane" },
            "start_deg": start.to_degrees(),
            "sweep_deg": sweep.to_degrees(),
        }),
        Geometry::Line { start, end, normal } => json!({
            "kind": "line",
            "start_mm": [start.x, start.y, start.z],
            "end_mm": [end.x, end.y, end.z],
            "normal": [normal.x, normal.y, normal.z],
        }),
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TruthFile {
    #[allow(dead_code)]
    scenario: Option<String>,
    #[allow(dead_code)]
    seed: Option<u64>,
    #[allow(dead_code)]
    note: Option<String>,
    features: Vec<TruthFeature>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TruthFeature {
    id: String,
    #[allow(dead_code)]
    nominal: Option<FeatureGeomJson>,
    actual: FeatureGeomJson,
    #[allow(dead_code)]
    normal_offset_mm: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FeatureGeomJson {
    kind: String,
    center_mm: Option<[f64; 3]>,
    axis: Option<[f64; 3]>,
    radius_mm: Option<f64>,
    side: Option<String>,
    start_deg: Option<f64>,
    sweep_deg: Option<f64>,
    start_mm: Option<[f64; 3]>,
    end_mm: Option<[f64; 3]>,
    normal: Option<[f64; 3]>,
}

/// The true part of a scenario's `truth.json` for the nominal features (matched by id): each
/// feature's `actual` geometry, checked against the parameters and the nominal kind.
pub fn read_truth(path: &Path, nominal: &[Feature], params: &Params) -> Result<Vec<Feature>, InputError> {
    let bytes = truepos_io::limits::read_text(path, "JSON")?;
    let t: TruthFile = serde_json::from_slice(&bytes).map_err(|e| {
        InputError::at(path, e.line(), Some(e.column()), format!("not a scan truth.json: {e}"))
    })?;
    let mut out = Vec::with_capacity(nominal.len());
    for f in nominal {
        let Some(tf) = t.features.iter().find(|x| x.id == f.id) else {
            return Err(InputError::in_file(path, format!("no true geometry for feature '{}'", f.id)));
        };
        let g = &tf.actual;
        let bad = || InputError::in_file(path, format!("feature '{}': incomplete true geometry", f.id));
        let geometry = match g.kind.as_str() {
            "circle" => Geometry::Circle {
                center: p3(g.center_mm.ok_or_else(bad)?),
                axis: v3(g.axis.ok_or_else(bad)?),
                radius: g.radius_mm.ok_or_else(bad)?,
                side: match g.side.as_deref() {
                    Some("inside") => Side::Inside,
                    Some("outside") => Side::Outside,
                    Some("plane") => Side::Plane,
                    _ => return Err(bad()),
                },
                start: g.start_deg.unwrap_or(0.0).to_radians(),
                sweep: g.sweep_deg.unwrap_or(360.0).to_radians(),
            },
            "line" => Geometry::Line {
                start: p3(g.start_mm.ok_or_else(bad)?),
                end: p3(g.end_mm.ok_or_else(bad)?),
                normal: v3(g.normal.ok_or_else(bad)?),
            },
            _ => return Err(bad()),
        };
        let tf = Feature { id: f.id.clone(), geometry };
        tf.check(params).map_err(|e| InputError::in_file(path, format!("true geometry: {e}")))?;
        if std::mem::discriminant(&tf.geometry) != std::mem::discriminant(&f.geometry) {
            return Err(InputError::in_file(
                path,
                format!("feature '{}': true and nominal kinds differ", f.id),
            ));
        }
        out.push(tf);
    }
    Ok(out)
}

/// The features TOML of a scenario (nominal geometry and the scan parameters).
pub fn toml_features(s: &ScanScenario) -> String {
    let f3 = |v: [f64; 3]| format!("[{}, {}, {}]", v[0], v[1], v[2]);
    let mut t = String::new();
    t.push_str("# truepos simulate scan: nominal features and scan parameters (mm, mm/s, degrees).\n");
    t.push_str(
        "# Each parameter can be overridden by the option of the same name, e.g. --scan-speed-mm-s 20.\n",
    );
    t.push_str("# angle between the approach line and the surface normal at the contact point (20 to 60°)\n");
    t.push_str(&format!("approach_angle_deg = {}\n", s.approach_angle_deg));
    t.push_str("# speed along the surface while scanning (mm/s)\n");
    t.push_str(&format!("scan_speed_mm_s = {}\n", s.scan_speed_mm_s));
    t.push_str("# speed of the transfer moves between features (mm/s)\n");
    t.push_str(&format!("move_speed_mm_s = {}\n", s.move_speed_mm_s));
    t.push_str("# nominal probe deflection while scanning (mm)\n");
    t.push_str(&format!("deflection_mm = {}\n", s.deflection_mm));
    t.push_str("# how far past the target deflection the settle path goes (mm)\n");
    t.push_str(&format!("overshoot_mm = {}\n", s.overshoot_mm));
    t.push_str("# quality bands on |deflection − target| (mm): within the first → quality 0, the second → 5, else 9\n");
    t.push_str(&format!("quality_bands_mm = [{}, {}]\n", s.quality_bands_mm[0], s.quality_bands_mm[1]));
    t.push_str(
        "\n# Features: kind circle (center_mm, axis, radius_mm, side inside|outside|plane, start_deg,\n",
    );
    t.push_str("# sweep_deg) or line (start_mm, end_mm, normal = outward normal of the material surface).\n");
    for f in &s.features {
        t.push_str("\n[[feature]]\n");
        t.push_str(&format!("id = \"{}\"\n", f.id));
        match &f.nominal {
            ScanGeometry::Circle { center, axis, radius, side, start_deg, sweep_deg } => {
                t.push_str("kind = \"circle\"\n");
                t.push_str(&format!("center_mm = {}\n", f3((*center).into())));
                t.push_str(&format!("axis = {}\n", f3((*axis).into())));
                t.push_str(&format!("radius_mm = {radius}\n"));
                t.push_str(&format!("side = \"{}\"\n", side.as_str()));
                t.push_str(&format!("start_deg = {start_deg}\n"));
                t.push_str(&format!("sweep_deg = {sweep_deg}\n"));
            }
            ScanGeometry::Line { start, end, normal } => {
                t.push_str("kind = \"line\"\n");
                t.push_str(&format!("start_mm = {}\n", f3((*start).into())));
                t.push_str(&format!("end_mm = {}\n", f3((*end).into())));
                t.push_str(&format!("normal = {}\n", f3((*normal).into())));
            }
        }
    }
    t
}

fn p3(a: [f64; 3]) -> Point3 {
    Point3::new(a[0], a[1], a[2])
}

fn v3(a: [f64; 3]) -> Vector3 {
    Vector3::new(a[0], a[1], a[2])
}

/// What [`write_scenario`] wrote.
pub struct Written {
    pub features: PathBuf,
    pub truth: PathBuf,
    pub n_features: usize,
}

impl Written {
    /// What `truepos simulate scan` prints: the files and the command that scans the part.
    pub fn text(&self) -> String {
        // The points go beside the scenario's files, as every other scenario's outputs do.
        let points = self.features.with_file_name("points.csv");
        format!(
            "wrote {} and {} ({} features)\nscan with: truepos scan run --features {} --part {} --output {} --json\n",
            self.features.display(),
            self.truth.display(),
            self.n_features,
            self.features.display(),
            self.truth.display(),
            points.display()
        )
    }
}

/// Write the `scan` scenario of `seed` with `n` features: `features.toml` (nominal) and
/// `truth.json` (nominal and actual geometry of every feature).
pub fn write_scenario(dir: &Path, seed: u64, n: usize) -> std::io::Result<Written> {
    let s = truepos_sim::scenario::scan::scenario(seed, n);
    std::fs::create_dir_all(dir)?;
    let features_path = dir.join("features.toml");
    truepos_io::atomic::write_atomic(&features_path, toml_features(&s).as_bytes())?;
    let truth = json!({
        "scenario": "scan",
        "seed": seed,
        "note": "actual: the true geometry the probe meets; normal_offset_mm: displacement of the true surface along the outward normal at the scan start (+: before the nominal contact point)",
        "features": s.features.iter().map(|f| {
            let nominal = feature(&f.id, &f.nominal);
            let actual = feature(&f.id, &f.actual);
            json!({
                "id": f.id,
                "nominal": geometry_json(&nominal.geometry),
                "actual": geometry_json(&actual.geometry),
                "normal_offset_mm": f.normal_offset_mm,
            })
        }).collect::<Vec<_>>(),
    });
    let mut text = serde_json::to_string_pretty(&truth).map_err(std::io::Error::other)?;
    text.push('\n');
    let truth_path = dir.join("truth.json");
    truepos_io::atomic::write_atomic(&truth_path, text.as_bytes())?;
    Ok(Written { features: features_path, truth: truth_path, n_features: s.features.len() })
}
