//! `truepos scan`: scanning path planning (`plan`) and execution on the virtual CMM (`run`)
//! without stops, with the classic style for comparison; `truepos simulate scan`; the demo
//! section.
//!
//! Files: the features TOML (`[[feature]]` tables and top-level parameters, each overridable by
//! the option of the same name with dashes), the path / point CSVs of the contract, an optional
//! machine TOML, and the scenario's `truth.json` (the true, displaced part) for `--part`.

use crate::output::{parse_pair, print_json};
use crate::report::{self, Report, Series};
use crate::{DeviceError, Outcome, UsageError};
use anyhow::{Context, Result};
use serde::Deserialize;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};
use truepos_io::atomic::AtomicFile;
use truepos_io::csv::CsvWriter;
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};
use truepos_scan::execute::{execute, Machine, Run as ScanRun};
use truepos_scan::{plan, validate, Feature, Geometry, Params, Plan, ScanError, SegmentKind, Side, Style};
use truepos_sim::motion::Servo;
use truepos_sim::stylus::StylusParams;

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  truepos simulate scan --out data/scan --seed 1\n  truepos scan plan --features data/scan/features.toml --output path.csv\n  truepos scan run --features data/scan/features.toml --part data/scan/truth.json --output points.csv --json\n  truepos scan run --features data/scan/features.toml --style classic --output classic.csv --json"
)]
pub struct Args {
    #[command(subcommand)]
    pub action: Action,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Plan the path (no machine): writes t_s,x_mm,y_mm,z_mm,segment,feature,speed_mm_s.
    #[command(
        after_help = "Example:\n  truepos scan plan --features data/scan/features.toml --output path.csv --style blended"
    )]
    Plan(PlanArgs),
    /// Plan and execute on the virtual CMM: writes the measured points with deflection and
    /// quality, prints cycle time, stops and per-feature form error.
    #[command(
        after_help = "Example:\n  truepos scan run --features data/scan/features.toml --part data/scan/truth.json --output points.csv --json"
    )]
    Run(RunArgs),
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum StyleArg {
    /// Approach at an angle at scanning speed, settle path, scan, release, straight on: no stops.
    Blended,
    /// Pre-hit point on the normal, stop, approach along the normal, search, scan, stop, retract.
    Classic,
}

impl From<StyleArg> for Style {
    fn from(s: StyleArg) -> Style {
        match s {
            StyleArg::Blended => Style::Blended,
            StyleArg::Classic => Style::Classic,
        }
    }
}

/// Options shared by `plan` and `run`; every parameter overrides the file's top-level key of
/// the same name.
#[derive(clap::Args, Debug, Clone)]
pub struct Common {
    /// Features and parameters (TOML: [[feature]] tables, top-level parameters).
    #[arg(long)]
    pub features: PathBuf,
    #[arg(long, value_enum, default_value_t = StyleArg::Blended)]
    pub style: StyleArg,
    /// Angle between the approach line and the surface normal, 20 to 60 degrees (default 45).
    #[arg(long, allow_hyphen_values = true)]
    pub approach_angle_deg: Option<f64>,
    /// Scanning speed (default 20 mm/s).
    #[arg(long)]
    pub scan_speed_mm_s: Option<f64>,
    /// Positioning speed of transfers (default 200 mm/s).
    #[arg(long)]
    pub move_speed_mm_s: Option<f64>,
    /// Target stylus deflection while scanning (default 0.3 mm).
    #[arg(long)]
    pub deflection_mm: Option<f64>,
    /// How far the settle path goes past the target deflection (default 0.1 mm).
    #[arg(long)]
    pub overshoot_mm: Option<f64>,
    /// Quality bands on |deflection − target|: A,B (default 0.02,0.05): ≤A → 0, ≤B → 5, else 9.
    #[arg(long, value_parser = parse_pair)]
    pub quality_bands_mm: Option<[f64; 2]>,
    /// Stylus tip radius (default 1.5 mm).
    #[arg(long)]
    pub tip_radius_mm: Option<f64>,
    /// Clearance from the surface at approach start and release end (default 3 mm).
    #[arg(long)]
    pub clearance_mm: Option<f64>,
    /// Path acceleration limit (default 1500 mm/s²).
    #[arg(long)]
    pub accel_mm_s2: Option<f64>,
    /// Classic style: approach (touch) speed along the normal (default 3 mm/s).
    #[arg(long)]
    pub touch_speed_mm_s: Option<f64>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct PlanArgs {
    #[command(flatten)]
    pub common: Common,
    /// Path CSV to write.
    #[arg(long)]
    pub output: PathBuf,
    /// Sampling step of the path (s).
    #[arg(long, default_value_t = 0.001)]
    pub dt_s: f64,
}

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    #[command(flatten)]
    pub common: Common,
    /// Virtual CMM (TOML: [servo] bandwidth_hz, damping, accel_feedforward; [stylus]
    /// natural_freq_hz = [x, y, z], damping_ratio = [x, y, z], restitution, friction;
    /// encoder_noise_um, probe_noise_um, feedback_gain_per_s, contact_threshold_mm).
    /// Default: the built-in CMM (15 Hz servo, 150/200 Hz stylus).
    #[arg(long)]
    pub machine: Option<PathBuf>,
    /// The true part: `truth.json` of `truepos simulate scan` (features matched by id).
    /// Without it the part is exactly nominal.
    #[arg(long)]
    pub part: Option<PathBuf>,
    /// Measured points CSV to write.
    #[arg(long)]
    pub output: PathBuf,
    /// Random seed of the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

// ------------------------------------------------------------------------------------------
// features file

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct FeaturesFile {
    approach_angle_deg: Option<f64>,
    scan_speed_mm_s: Option<f64>,
    move_speed_mm_s: Option<f64>,
    deflection_mm: Option<f64>,
    overshoot_mm: Option<f64>,
    quality_bands_mm: Option<[f64; 2]>,
    tip_radius_mm: Option<f64>,
    clearance_mm: Option<f64>,
    accel_mm_s2: Option<f64>,
    touch_speed_mm_s: Option<f64>,
    #[serde(default)]
    feature: Vec<FeatureToml>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct FeatureToml {
    id: String,
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

/// Read the features file, apply the command-line overrides, validate.
fn load(c: &Common) -> Result<(Vec<Feature>, Params)> {
    let text = std::fs::read_to_string(&c.features)
        .map_err(|e| InputError::in_file(&c.features, format!("cannot read: {e}")))?;
    let file: FeaturesFile = truepos_io::config::parse_toml(&c.features, &text)?;
    let path = &c.features;
    let mut features = Vec::with_capacity(file.feature.len());
    let mut seen = std::collections::HashSet::new();
    for f in &file.feature {
        let err = |m: String| feature_error(path, &text, &f.id, format!("feature '{}': {m}", f.id));
        if !seen.insert(f.id.clone()) {
            return Err(err("duplicate id".into()).into());
        }
        let need3 = |v: Option<[f64; 3]>, name: &str| v.ok_or_else(|| err(format!("missing {name}")));
        let geometry = match f.kind.as_str() {
            "circle" => {
                let side = match f.side.as_deref() {
                    Some("inside") => Side::Inside,
                    Some("outside") => Side::Outside,
                    Some("plane") => Side::Plane,
                    Some(s) => {
                        return Err(err(format!("side '{s}' is not one of inside, outside, plane")).into())
                    }
                    None => return Err(err("missing side (inside, outside or plane)".into()).into()),
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
            k => return Err(err(format!("kind '{k}' is not one of circle, line")).into()),
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
        touch_speed: pick(c.touch_speed_mm_s, file.touch_speed_mm_s, d.touch_speed),
        ..d
    };
    match validate(&features, &params) {
        Ok(()) => Ok((features, params)),
        Err(ScanError::Feature { id, why }) => {
            Err(feature_error(path, &text, &id, format!("feature '{id}': {why}")).into())
        }
        Err(e @ ScanError::ApproachAngle(_)) => Err(UsageError(e.to_string()).into()),
        Err(e) => Err(InputError::in_file(path, e.to_string()).into()),
    }
}

// ------------------------------------------------------------------------------------------
// machine file

#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields)]
struct MachineToml {
    servo: Option<ServoToml>,
    stylus: Option<StylusToml>,
    encoder_noise_um: Option<f64>,
    probe_noise_um: Option<f64>,
    feedback_gain_per_s: Option<f64>,
    contact_threshold_mm: Option<f64>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct ServoToml {
    bandwidth_hz: Option<f64>,
    damping: Option<f64>,
    accel_feedforward: Option<f64>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct StylusToml {
    natural_freq_hz: Option<[f64; 3]>,
    damping_ratio: Option<[f64; 3]>,
    restitution: Option<f64>,
    friction: Option<f64>,
}

fn load_machine(path: Option<&PathBuf>) -> Result<Machine> {
    let mut m = Machine::default();
    let Some(path) = path else { return Ok(m) };
    let t: MachineToml = truepos_io::config::read_toml(path)?;
    if let Some(s) = t.servo {
        let d = m.servo;
        m.servo = Servo {
            bandwidth_hz: s.bandwidth_hz.unwrap_or(d.bandwidth_hz),
            damping: s.damping.unwrap_or(d.damping),
            accel_feedforward: s.accel_feedforward.unwrap_or(d.accel_feedforward),
        };
    }
    if let Some(s) = t.stylus {
        let d = m.stylus;
        m.stylus = StylusParams {
            natural_freq_hz: s.natural_freq_hz.unwrap_or(d.natural_freq_hz),
            damping_ratio: s.damping_ratio.unwrap_or(d.damping_ratio),
            restitution: s.restitution.unwrap_or(d.restitution),
            friction: s.friction.unwrap_or(d.friction),
            ..d
        };
    }
    if let Some(v) = t.encoder_noise_um {
        m.encoder_noise = v * 1e-3;
    }
    if let Some(v) = t.probe_noise_um {
        m.probe_noise = v * 1e-3;
    }
    if let Some(v) = t.feedback_gain_per_s {
        m.feedback_gain = v;
    }
    if let Some(v) = t.contact_threshold_mm {
        m.contact_threshold = v;
    }
    m.check().map_err(|e| InputError::in_file(path, e.to_string()))?;
    Ok(m)
}

// ------------------------------------------------------------------------------------------
// the true part (truth.json of the scenario)

fn geometry_json(g: &Geometry) -> serde_json::Value {
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
struct TruthFile {
    features: Vec<TruthFeature>,
}
#[derive(Deserialize)]
struct TruthFeature {
    id: String,
    actual: FeatureGeomJson,
}
#[derive(Deserialize)]
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

fn load_part(path: &Path, nominal: &[Feature], params: &Params) -> Result<Vec<Feature>> {
    let bytes = std::fs::read(path).map_err(|e| InputError::in_file(path, format!("cannot read: {e}")))?;
    let t: TruthFile = serde_json::from_slice(&bytes).map_err(|e| {
        InputError::at(path, e.line(), Some(e.column()), format!("not a scan truth.json: {e}"))
    })?;
    let mut out = Vec::with_capacity(nominal.len());
    for f in nominal {
        let Some(tf) = t.features.iter().find(|x| x.id == f.id) else {
            return Err(InputError::in_file(path, format!("no true geometry for feature '{}'", f.id)).into());
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
                    _ => return Err(bad().into()),
                },
                start: g.start_deg.unwrap_or(0.0).to_radians(),
                sweep: g.sweep_deg.unwrap_or(360.0).to_radians(),
            },
            "line" => Geometry::Line {
                start: p3(g.start_mm.ok_or_else(bad)?),
                end: p3(g.end_mm.ok_or_else(bad)?),
                normal: v3(g.normal.ok_or_else(bad)?),
            },
            _ => return Err(bad().into()),
        };
        let tf = Feature { id: f.id.clone(), geometry };
        tf.check(params).map_err(|e| InputError::in_file(path, format!("true geometry: {e}")))?;
        if std::mem::discriminant(&tf.geometry) != std::mem::discriminant(&f.geometry) {
            return Err(InputError::in_file(
                path,
                format!("feature '{}': true and nominal kinds differ", f.id),
            )
            .into());
        }
        out.push(tf);
    }
    Ok(out)
}

// ------------------------------------------------------------------------------------------
// commands

pub fn run(a: Args) -> Result<Outcome> {
    match a.action {
        Action::Plan(p) => run_plan(p),
        Action::Run(r) => run_run(r),
    }
}

fn style_name(s: Style) -> &'static str {
    match s {
        Style::Blended => "blended",
        Style::Classic => "classic",
    }
}

fn run_plan(a: PlanArgs) -> Result<Outcome> {
    if !(a.dt_s.is_finite() && a.dt_s > 0.0 && a.dt_s <= 0.1) {
        return Err(UsageError(format!("--dt-s {} must be above 0 and at most 0.1 s", a.dt_s)).into());
    }
    let (features, params) = load(&a.common)?;
    let style: Style = a.common.style.into();
    let pl = plan(&features, &params, style);
    let n = pl.duration() / a.dt_s;
    if !(n.is_finite() && n <= 5.0e7) {
        return Err(UsageError(format!(
            "the path takes {:.3e} s; at --dt-s {} that is more than 5e7 points",
            pl.duration(),
            a.dt_s
        ))
        .into());
    }
    let samples = pl.sample(a.dt_s);
    let mut f =
        AtomicFile::create(&a.output).with_context(|| format!("cannot create {}", a.output.display()))?;
    {
        let mut w = CsvWriter::new(std::io::BufWriter::new(&mut f));
        w.comment(&format!(
            "truepos scan plan, style {}: commanded probe (tip centre) path",
            style_name(style)
        ))?;
        w.header(&["t_s", "x_mm", "y_mm", "z_mm", "segment", "feature", "speed_mm_s"])?;
        for s in &samples {
            let seg = &pl.segments[s.segment];
            w.field_f64(s.t)?;
            w.field_f64(s.position.x)?;
            w.field_f64(s.position.y)?;
            w.field_f64(s.position.z)?;
            w.field_str(seg.kind.as_str())?;
            w.field_str(&features[seg.feature].id)?;
            w.field_f64(s.speed)?;
            w.end_row()?;
        }
        w.into_inner().flush()?;
    }
    f.commit().with_context(|| format!("cannot write {}", a.output.display()))?;
    let per = plan_feature_times(&pl);
    if a.common.json {
        print_json(&json!({
            "style": style_name(style),
            "cycle_time_s": pl.duration(),
            "stops": pl.stops(),
            "n_points": samples.len(),
            "features": per.iter().map(|(id, t)| json!({"id": id, "time_s": t})).collect::<Vec<_>>(),
        }))?;
    } else {
        eprintln!(
            "{} style: {} features, planned cycle {:.3} s, {} stops; wrote {} ({} points)",
            style_name(style),
            features.len(),
            pl.duration(),
            pl.stops(),
            a.output.display(),
            samples.len()
        );
    }
    Ok(Outcome::Done)
}

/// Planned time of each feature from its approach start to its release end.
fn plan_feature_times(pl: &Plan) -> Vec<(String, f64)> {
    pl.features
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
            for (s, &t) in pl.segments.iter().zip(&pl.starts) {
                if s.feature == k && s.kind != SegmentKind::Transfer {
                    a = a.min(t);
                    b = b.max(t + s.duration());
                }
            }
            (f.id.clone(), b - a)
        })
        .collect()
}

fn run_run(a: RunArgs) -> Result<Outcome> {
    let (features, params) = load(&a.common)?;
    let machine = load_machine(a.machine.as_ref())?;
    let truth = match &a.part {
        Some(p) => load_part(p, &features, &params)?,
        None => features.clone(),
    };
    let style: Style = a.common.style.into();
    let pl = plan(&features, &params, style);
    let r = execute(&pl, &truth, &machine, a.seed).map_err(|e| match e {
        // the surface was not found: a measurement failure
        ScanError::NoContact { .. } => anyhow::Error::new(DeviceError(e.to_string())),
        // a program the virtual CMM refuses (too long, bad machine): the user's input
        ScanError::Invalid(m) => anyhow::Error::new(InputError::in_file(&a.common.features, m)),
        other => anyhow::Error::new(DeviceError(format!("execution failed: {other}"))),
    })?;
    let mut f =
        AtomicFile::create(&a.output).with_context(|| format!("cannot create {}", a.output.display()))?;
    {
        let mut w = CsvWriter::new(std::io::BufWriter::new(&mut f));
        w.comment(&format!(
            "truepos scan run, style {}: measured tip centre (scale + probe deflection); quality 0/5/9 from |deflection - target| in bands {} / {} mm",
            style_name(style),
            params.quality_bands[0],
            params.quality_bands[1]
        ))?;
        w.header(&[
            "t_s",
            "x_mm",
            "y_mm",
            "z_mm",
            "segment",
            "feature",
            "deflection_mm",
            "quality",
            "target_deflection_mm",
        ])?;
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
    f.commit().with_context(|| format!("cannot write {}", a.output.display()))?;
    if a.common.json {
        print_json(&run_json(&r, style))?;
    } else {
        eprintln!(
            "{} style: cycle {:.3} s, {} stops, {} points written to {}",
            style_name(style),
            r.cycle_time,
            r.stops,
            r.points.len(),
            a.output.display()
        );
        for f in &r.features {
            eprintln!(
                "  {:12} {:7.3} s  form {:>7} µm  shift {:+8.3} mm  scan-start vibration {:6.2} µm rms",
                f.id,
                f.time,
                match &f.form_note {
                    None => format!("{:.2}", f.form_error * 1e3),
                    Some(_) => "-".to_string(),
                },
                f.contact_shift,
                f.vibration_rms * 1e3
            );
        }
    }
    Ok(Outcome::Done)
}

fn run_json(r: &ScanRun, style: Style) -> serde_json::Value {
    json!({
        "style": style_name(style),
        "cycle_time_s": r.cycle_time,
        "stops": r.stops,
        "n_points": r.points.len(),
        "form_error_method": "least-squares element of the scan segment (truepos-fit: 3D circle for bores and bosses, plane for circles on a plane, line for lines), peak-to-valley of the residuals",
        "features": r.features.iter().map(|f| json!({
            "id": f.id,
            "time_s": f.time,
            "form_error_mm": if f.form_error.is_finite() { json!(f.form_error) } else { serde_json::Value::Null },
            "form_error_note": f.form_note,
            "contact_shift_mm": f.contact_shift,
            "vibration_rms_mm": f.vibration_rms,
            "vibration_peak_mm": f.vibration_peak,
            "settle_time_s": f.settle_time,
            "contact_to_scan_s": f.ready_time,
            "scan_points": f.scan_points,
            "quality0_share": f.quality0_share,
        })).collect::<Vec<_>>(),
    })
}

// ------------------------------------------------------------------------------------------
// simulate

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  truepos simulate scan --out data/scan --seed 1 --features 12\n\nWrites features.toml (the nominal features and scan parameters) and truth.json (the true,\ndisplaced part: every fifth feature 1.2–1.8 mm off nominal along its normal, alternately\nbefore and beyond). Then: truepos scan run --features DIR/features.toml --part DIR/truth.json ..."
)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// Number of features on the part (bores, bosses, circles on the top plane, lines), 1 to 200.
    #[arg(long, default_value_t = 12, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=200))]
    pub features: usize,
}

fn toml_features(s: &truepos_sim::scenario::scan::ScanScenario) -> String {
    use truepos_sim::scenario::scan::ScanGeometry;
    let f3 = |v: [f64; 3]| format!("[{}, {}, {}]", v[0], v[1], v[2]);
    let mut t = String::new();
    t.push_str("# truepos simulate scan: nominal features and scan parameters\n");
    t.push_str(&format!("approach_angle_deg = {}\n", s.approach_angle_deg));
    t.push_str(&format!("scan_speed_mm_s = {}\n", s.scan_speed_mm_s));
    t.push_str(&format!("move_speed_mm_s = {}\n", s.move_speed_mm_s));
    t.push_str(&format!("deflection_mm = {}\n", s.deflection_mm));
    t.push_str(&format!("overshoot_mm = {}\n", s.overshoot_mm));
    t.push_str(&format!("quality_bands_mm = [{}, {}]\n", s.quality_bands_mm[0], s.quality_bands_mm[1]));
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

pub fn simulate(a: SimArgs) -> Result<Outcome> {
    if a.features == 0 || a.features > 10_000 {
        return Err(UsageError(format!("--features {} must be between 1 and 10000", a.features)).into());
    }
    let s = truepos_sim::scenario::scan::scenario(a.common.seed, a.features);
    let dir = &a.common.out;
    std::fs::create_dir_all(dir)
        .map_err(|e| InputError::in_file(dir, format!("cannot create the output directory: {e}")))?;
    let features_path = dir.join("features.toml");
    truepos_io::atomic::write_atomic(&features_path, toml_features(&s).as_bytes())?;
    let truth = json!({
        "scenario": "scan",
        "seed": a.common.seed,
        "note": "actual: the true geometry the probe meets; normal_offset_mm: displacement of the true surface along the outward normal at the scan start (+: before the nominal contact point)",
        "features": s.features.iter().map(|f| {
            let nominal = truepos_scan::scenario::feature(&f.id, &f.nominal);
            let actual = truepos_scan::scenario::feature(&f.id, &f.actual);
            json!({
                "id": f.id,
                "nominal": geometry_json(&nominal.geometry),
                "actual": geometry_json(&actual.geometry),
                "normal_offset_mm": f.normal_offset_mm,
            })
        }).collect::<Vec<_>>(),
    });
    let mut text = serde_json::to_string_pretty(&truth)?;
    text.push('\n');
    let truth_path = dir.join("truth.json");
    truepos_io::atomic::write_atomic(&truth_path, text.as_bytes())?;
    eprintln!(
        "wrote {} and {} ({} features)",
        features_path.display(),
        truth_path.display(),
        s.features.len()
    );
    eprintln!(
        "scan with: truepos scan run --features {} --part {} --output points.csv --json",
        features_path.display(),
        truth_path.display()
    );
    Ok(Outcome::Done)
}

// ------------------------------------------------------------------------------------------
// demo

/// This capability's section of the demo report: the same features scanned the blended and the
/// classic way on the virtual CMM, side by side.
pub fn demo_section(report: &mut Report) -> Result<()> {
    let s = truepos_sim::scenario::scan::scenario(1, 12);
    let (nominal, truth, params) = truepos_scan::scenario::program(&s);
    validate(&nominal, &params).map_err(|e| anyhow::anyhow!("demo features: {e}"))?;
    let machine = Machine::default();
    let pb = plan(&nominal, &params, Style::Blended);
    let pc = plan(&nominal, &params, Style::Classic);
    let rb = execute(&pb, &truth, &machine, 1).map_err(|e| anyhow::anyhow!("blended run: {e}"))?;
    let rc = execute(&pc, &truth, &machine, 1).map_err(|e| anyhow::anyhow!("classic run: {e}"))?;

    // path plots (XY of the boss `boss1` with its incoming transfer), coloured by segment
    let kinds = [
        SegmentKind::Transfer,
        SegmentKind::Approach,
        SegmentKind::Settle,
        SegmentKind::Scan,
        SegmentKind::Release,
    ];
    let path_plot = |pl: &Plan, title: &str| -> Result<String> {
        let samples = pl.sample(0.002);
        let series: Vec<Series> = kinds
            .iter()
            .map(|k| {
                let pts = samples
                    .iter()
                    .filter(|q| pl.segments[q.segment].kind == *k && pl.segments[q.segment].feature == 1)
                    .map(|q| (q.position.x, q.position.y))
                    .collect();
                Series::points(k.as_str(), pts)
            })
            .collect();
        report::xy_plot(title, "x (mm)", "y (mm)", &series)
    };
    let plot_b = path_plot(&pb, "Blended path around boss1 (XY), by segment")?;
    let plot_c = path_plot(&pc, "Classic path around boss1 (XY), by segment")?;

    // deflection against time around the first contact on feature 1 (a boss), both styles
    let defl = |r: &ScanRun, label: &str| -> Series {
        let f = &r.features[1];
        let pts = r
            .points
            .iter()
            .filter(|q| q.feature == 1 && q.t >= f.contact_t - 0.02 && q.t <= f.scan_start_t + 0.15)
            .map(|q| (q.t - f.contact_t, q.deflection))
            .collect();
        Series::line(label, pts)
    };
    let plot_d = report::xy_plot(
        "Deflection from first contact into the scan (boss1)",
        "time from contact (s)",
        "deflection (mm)",
        &[defl(&rb, "blended"), defl(&rc, "classic")],
    )?;

    let mean = |r: &ScanRun, g: fn(&truepos_scan::execute::FeatureRun) -> f64| {
        r.features.iter().map(g).sum::<f64>() / r.features.len() as f64
    };
    let maxf = |r: &ScanRun| r.features.iter().map(|f| f.form_error).fold(0.0, f64::max);
    let row = |name: &str, r: &ScanRun| {
        vec![
            name.to_string(),
            format!("{:.2}", r.cycle_time),
            r.stops.to_string(),
            format!("{:.2}", mean(r, |f| f.vibration_rms) * 1e3),
            format!("{:.2}", mean(r, |f| f.vibration_peak) * 1e3),
            format!("{:.3}", mean(r, |f| f.ready_time)),
            format!("{:.2}", mean(r, |f| f.form_error) * 1e3),
            format!("{:.2}", maxf(r) * 1e3),
        ]
    };
    let table = report::table(
        &[
            "style",
            "cycle time (s)",
            "stops",
            "scan-start vibration, rms (µm)",
            "scan-start vibration, peak (µm)",
            "contact → scan (s)",
            "form error, mean (µm)",
            "form error, max (µm)",
        ],
        &[row("blended", &rb), row("classic", &rc)],
    );
    let shifts: Vec<Vec<String>> = rb
        .features
        .iter()
        .zip(&s.features)
        .filter(|(_, t)| t.normal_offset_mm.abs() > 1.0)
        .map(|(f, t)| {
            vec![
                f.id.clone(),
                format!("{:+.3}", t.normal_offset_mm),
                format!("{:+.3}", f.contact_shift),
                format!("{:.2}", f.form_error * 1e3),
            ]
        })
        .collect();
    let shift_table = report::table(
        &["feature", "true offset (mm)", "path shift at contact (mm)", "form error (µm)"],
        &shifts,
    );
    let html = format!(
        "<p>{} features (bores, bosses, circles on the top plane, lines) of a part whose every fifth feature is 1.2–1.8 mm off nominal, scanned at {} mm/s with {} mm deflection on the virtual CMM (15 Hz servo; 150 Hz stylus with restitution and Coulomb friction), the blended and the classic way. Cycle time saving of the blended style: <b>{:.1} %</b>. Vibration at scan start: deviation of the deflection from its target over the first 50 ms of the scan. Form error: peak-to-valley of the residuals of the least-squares element fitted to the scan segment (the true features are perfect, so this is what noise and dynamics leave).</p>\n{}\n{}\n{}\n{}\n<p>Missed surfaces (blended): the path shift where contact was made against the true offset.</p>\n{}",
        nominal.len(),
        params.scan_speed,
        params.deflection,
        100.0 * (1.0 - rb.cycle_time / rc.cycle_time),
        table,
        plot_b,
        plot_c,
        plot_d,
        shift_table
    );
    report.add("scan", "Scanning without stops: blended vs classic", html);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_section_compares_both_styles() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = Report::new(dir.path());
        demo_section(&mut r).unwrap();
        let html = std::fs::read_to_string(r.write().unwrap()).unwrap();

        assert!(html.contains("Scanning without stops"));
        assert!(html.contains("blended") && html.contains("classic"));
        assert!(html.matches("<svg").count() >= 3, "path plots and deflection plot");
    }

    #[test]
    fn id_line_finds_the_feature() {
        let t = "a = 1\n[[feature]]\nid = \"x1\"\n[[feature]]\n  id = 'y'\n";
        assert_eq!(id_line(t, "x1"), Some(3));
        assert_eq!(id_line(t, "y"), Some(5));
        assert_eq!(id_line(t, "z"), None);
    }
}
