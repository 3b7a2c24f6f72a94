//! The `scan` scenario: a part with bores, bosses, planes and straight edges on the plane to be
//! scanned on the virtual CMM, as `truepos-scan` features: the nominal ones (what
//! `features.toml` describes) and the true, displaced ones (what the probe meets; written to
//! `truth.json`), for `truepos simulate scan`, the demo, and the tests and benches of
//! `truepos-scan`. (One module: the part, its features and its files were three modules in two
//! crates, with a copy of the feature types in `truepos-sim`.)
//!
//! Every feature is displaced a little from nominal (manufacturing scatter: centres
//! ~N(0, 30 µm), radii ~N(0, 10 µm), planes ~N(0, 20 µm)); every fifth feature is displaced by
//! 1.2–1.8 mm along its surface normal, in alternating directions, so that both missed-surface
//! cases (surface before and beyond the nominal contact point) occur.
//!
//! Entry points: [`scenario`] (`seed`, number of features), [`program`] (nominal features, true
//! features and parameters of a scenario), [`write_scenario`] (`features.toml` and
//! `truth.json`), [`read_truth`] (the true part of a `truth.json`).

use serde::Deserialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};
use truepos_scan::{Feature, Geometry, Params, Side};
use truepos_sim::noise;

/// One feature: nominal and true geometry (internal units: mm, rad).
#[derive(Clone, Debug, PartialEq)]
pub struct ScanFeature {
    /// The feature's id in `features.toml`.
    pub id: String,
    /// The drawing's geometry (what the planner plans on).
    pub nominal: Geometry,
    /// The part's true geometry (what the virtual CMM touches).
    pub actual: Geometry,
    /// Displacement of the true surface along the outward normal at the scan start (mm; +:
    /// the surface lies before the nominal contact point).
    pub normal_offset_mm: f64,
}

/// The data set: the features and the scan parameters of `features.toml` (mm, mm/s, degrees).
#[derive(Clone, Debug, PartialEq)]
pub struct ScanScenario {
    /// The features, nominal and true.
    pub features: Vec<ScanFeature>,
    /// Approach angle to the surface (degrees).
    pub approach_angle_deg: f64,
    /// Path speed while scanning (mm/s).
    pub scan_speed_mm_s: f64,
    /// Path speed of transfers (mm/s).
    pub move_speed_mm_s: f64,
    /// Target probe deflection while scanning (mm).
    pub deflection_mm: f64,
    /// Scan overrun past the closing point (mm).
    pub overshoot_mm: f64,
    /// Quality bands of the deflection error `[good, fair]` (mm).
    pub quality_bands_mm: [f64; 2],
}

/// A circle of the part (`start_deg`, `sweep_deg` in degrees as the scenario draws them).
fn circle(center: Point3, radius: f64, side: Side, start_deg: f64, sweep_deg: f64) -> Geometry {
    Geometry::Circle {
        center,
        axis: Vector3::z(),
        radius,
        side,
        start: start_deg.to_radians(),
        sweep: sweep_deg.to_radians(),
    }
}

/// Build the part: `n` features on a 60 mm grid, cycling bore, boss, circle on the top plane,
/// line on the top plane.
pub fn scenario(seed: u64, n: usize) -> ScanScenario {
    let mut rng = noise::stream(seed, 0x5ca7);
    let mut features = Vec::with_capacity(n);
    for k in 0..n {
        let (gx, gy) = ((k % 8) as f64, (k / 8) as f64);
        let c = Point3::new(60.0 + 60.0 * gx, 60.0 + 60.0 * gy, 0.0);
        let big = if k % 5 == 4 {
            let mag = noise::uniform(&mut rng, 1.2, 1.8);
            if (k / 5) % 2 == 0 {
                mag
            } else {
                -mag
            }
        } else {
            0.0
        };
        let dc = Vector3::new(noise::gaussian(&mut rng, 0.03), noise::gaussian(&mut rng, 0.03), 0.0);
        let dr = noise::gaussian(&mut rng, 0.01);
        let dz = noise::gaussian(&mut rng, 0.02);
        let start_deg = noise::uniform(&mut rng, 0.0, 360.0).round();
        let z = Vector3::z();
        let (id, nominal, actual, off) = match k % 4 {
            0 => {
                let r = 8.0 + (k % 3) as f64 * 2.0;
                let at = c + Vector3::new(0.0, 0.0, -5.0);
                let nom = circle(at, r, Side::Inside, start_deg, 360.0);
                // a bore: the surface is before the nominal point when the radius is smaller
                let act = circle(at + dc, r + dr - big, Side::Inside, start_deg, 360.0);
                (format!("bore{k}"), nom, act, big)
            }
            1 => {
                let r = 10.0 + (k % 3) as f64 * 2.5;
                let at = c + Vector3::new(0.0, 0.0, 8.0);
                let nom = circle(at, r, Side::Outside, start_deg, 360.0);
                let act = circle(at + dc, r + dr + big, Side::Outside, start_deg, 360.0);
                (format!("boss{k}"), nom, act, big)
            }
            2 => {
                let nom = circle(c, 12.0, Side::Plane, start_deg, -270.0);
                let act = circle(c + z * (dz + big), 12.0, Side::Plane, start_deg, -270.0);
                (format!("face{k}"), nom, act, dz + big)
            }
            _ => {
                let a = start_deg.to_radians();
                let d = Vector3::new(a.cos(), a.sin(), 0.0) * 20.0;
                let nom = Geometry::Line { start: c - d, end: c + d, normal: z };
                let act =
                    Geometry::Line { start: c - d + z * (dz + big), end: c + d + z * (dz + big), normal: z };
                (format!("line{k}"), nom, act, dz + big)
            }
        };
        features.push(ScanFeature { id, nominal, actual, normal_offset_mm: off });
    }
    ScanScenario {
        features,
        approach_angle_deg: 45.0,
        scan_speed_mm_s: 40.0,
        move_speed_mm_s: 200.0,
        deflection_mm: 0.3,
        overshoot_mm: 0.1,
        quality_bands_mm: [0.02, 0.05],
    }
}

/// (nominal features, true features, parameters) of a scenario.
pub fn program(s: &ScanScenario) -> (Vec<Feature>, Vec<Feature>, Params) {
    let nominal =
        s.features.iter().map(|f| Feature { id: f.id.clone(), geometry: f.nominal.clone() }).collect();
    let truth = s.features.iter().map(|f| Feature { id: f.id.clone(), geometry: f.actual.clone() }).collect();
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
            "side": side_str(*side),
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
    let text = truepos_io::limits::read_config_string(path, "JSON")?;
    let t: TruthFile = serde_json::from_str(&text).map_err(|e| {
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
            Geometry::Circle { center, axis, radius, side, start, sweep } => {
                t.push_str("kind = \"circle\"\n");
                t.push_str(&format!("center_mm = {}\n", f3((*center).into())));
                t.push_str(&format!("axis = {}\n", f3((*axis).into())));
                t.push_str(&format!("radius_mm = {radius}\n"));
                t.push_str(&format!("side = \"{}\"\n", side_str(*side)));
                t.push_str(&format!("start_deg = {}\n", degrees(*start)));
                t.push_str(&format!("sweep_deg = {}\n", degrees(*sweep)));
            }
            Geometry::Line { start, end, normal } => {
                t.push_str("kind = \"line\"\n");
                t.push_str(&format!("start_mm = {}\n", f3((*start).into())));
                t.push_str(&format!("end_mm = {}\n", f3((*end).into())));
                t.push_str(&format!("normal = {}\n", f3((*normal).into())));
            }
        }
    }
    t
}

/// The side as the files write it.
fn side_str(side: Side) -> &'static str {
    match side {
        Side::Inside => "inside",
        Side::Outside => "outside",
        Side::Plane => "plane",
    }
}

/// An angle (rad) in degrees as `features.toml` writes it: rounded to 1e-9° so that the
/// scenario's whole-degree angles come back as written (137, not 137.00000000000003).
fn degrees(rad: f64) -> f64 {
    (rad.to_degrees() * 1e9).round() / 1e9
}

fn p3(a: [f64; 3]) -> Point3 {
    Point3::new(a[0], a[1], a[2])
}

fn v3(a: [f64; 3]) -> Vector3 {
    Vector3::new(a[0], a[1], a[2])
}

/// What [`write_scenario`] wrote.
pub struct Written {
    /// The features file written.
    pub features: PathBuf,
    /// The truth file written.
    pub truth: PathBuf,
    /// Number of features.
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
    let s = scenario(seed, n);
    std::fs::create_dir_all(dir)?;
    let features_path = dir.join("features.toml");
    truepos_io::atomic::write_atomic(&features_path, toml_features(&s).as_bytes())?;
    let truth = json!({
        "scenario": "scan",
        "seed": seed,
        "note": "actual: the true geometry the probe meets; normal_offset_mm: displacement of the true surface along the outward normal at the scan start (+: before the nominal contact point)",
        "features": s.features.iter().map(|f| {
            json!({
                "id": f.id,
                "nominal": geometry_json(&f.nominal),
                "actual": geometry_json(&f.actual),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_displaced_both_ways() {
        let a = scenario(3, 20);
        assert_eq!(a, scenario(3, 20));
        assert_ne!(a, scenario(4, 20));
        // every fifth feature is displaced by 1.2–1.8 mm, alternating sign
        let big: Vec<f64> = a.features.iter().map(|f| f.normal_offset_mm).filter(|o| o.abs() > 1.0).collect();
        assert_eq!(big.len(), 4);
        assert!(big.iter().any(|&o| o > 1.19) && big.iter().any(|&o| o < -1.19));
        assert!(big.iter().all(|o| (1.2..=1.8 + 0.1).contains(&o.abs())));
    }

    /// The features file gives the drawn whole-degree angles exactly, and reads back (through
    /// `truepos-scan`'s reader) as the scenario's nominal features.
    #[test]
    fn features_toml_reads_back_as_the_nominal_features() {
        let s = scenario(5, 8);
        let text = toml_features(&s);
        for f in &s.features {
            if let Geometry::Circle { start, .. } = f.nominal {
                let deg = start.to_degrees().round();
                assert!(text.contains(&format!("start_deg = {deg}\n")), "{deg} in\n{text}");
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("features.toml");
        std::fs::write(&path, &text).unwrap();
        let (nominal, _, params) = program(&s);
        let (read, read_params) =
            truepos_scan::file::read_features(&path, &truepos_scan::file::ParamOverrides::default()).unwrap();
        assert_eq!(read.len(), nominal.len());
        for (a, b) in read.iter().zip(&nominal) {
            assert_eq!(a.id, b.id);
            match (&a.geometry, &b.geometry) {
                (
                    Geometry::Circle { center: c1, radius: r1, start: s1, sweep: w1, side: d1, .. },
                    Geometry::Circle { center: c2, radius: r2, start: s2, sweep: w2, side: d2, .. },
                ) => {
                    // 1e-12: the text round trip of the same f64 values (and 1e-9° of rounding).
                    assert!((c1 - c2).norm() < 1e-12 && (r1 - r2).abs() < 1e-12 && d1 == d2);
                    assert!((s1 - s2).abs() < 1e-12 && (w1 - w2).abs() < 1e-12);
                }
                (Geometry::Line { start: a1, end: e1, .. }, Geometry::Line { start: a2, end: e2, .. }) => {
                    assert!((a1 - a2).norm() < 1e-12 && (e1 - e2).norm() < 1e-12);
                }
                _ => panic!("feature {}: kinds differ", a.id),
            }
        }
        assert!((read_params.approach_angle - params.approach_angle).abs() < 1e-12);
        assert_eq!(read_params.scan_speed, params.scan_speed);
    }
}
