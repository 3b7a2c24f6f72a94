//! `truepos load`: bed deformation under workpiece load — influence maps from the plate FE model
//! (or imported), load cases by statics, superposition, and correction of measured points; plus
//! the `load` scenario of `truepos simulate` and the demo section.
//!
//! Files (contract): `bed.toml` (`[bed]`, `[portal]`, `[grid]`), `load.toml` (`mass_kg` or
//! `weight_n`, `cog_mm`, `rest_points_mm` or `[[rest]] x_mm, y_mm, force_n`), the influence map
//! CSV (`load_x_mm,load_y_mm,portal_y_mm,pitch_urad,roll_urad`, `# unit_load_n = …`).
//! Physics and the sign of pitch/roll: `truepos_comp::load`.

use crate::cmd::comp::{batch_error, load_map, rms_max_um, table_points, write_corrected, ChainArg, MapArgs};
use crate::output::{parse_triple, print_json, progress};
use crate::report::{self, Report, Series};
use crate::Outcome;
use anyhow::{Context, Result};
use serde::Deserialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use truepos_comp::fe_map::{self, BedModel, LoadGrid};
use truepos_comp::influence::{InfluenceError, InfluenceMap, InfluenceRow};
use truepos_comp::statics;
use truepos_comp::{Corrector, LoadCorrection, Portal, PortalCurves};
use truepos_fe::{Bed, MeshOptions, Supports};
use truepos_io::atomic::{write_atomic, AtomicFile};
use truepos_io::csv::{CsvWriter, Table};
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};

const SIGN_HELP: &str = "\
Pitch and roll are the portal's physical rotations (µrad, right-hand rule) about +X and +Y, as an
outside FE package reports them: a measured point p at portal position y is corrected to p + e,
e = (pitch, roll, 0) × (p − o), o = ((x1 + x2)/2, y, rail_height_mm) (the tilted portal carries
the tip by e). From the bed deflection: pitch_urad = 1e6·(uz_front − uz_back)/bearing_span
(front = +Y bearing, mean of both rails), roll_urad = 1e6·(uz_rail1 − uz_rail2)/(x2 − x1) (uz
positive up; mean of the two bearings on each rail). A load ahead of the portal tips it forward:
negative pitch. Imported maps are used as they come. The portal's common vertical sink is not
part of the model.

Load case: mass_kg (× 9.80665) or weight_n, cog_mm, rest_points_mm: forces by statics (exact
for three points; the minimum-norm balanced distribution for more). A distribution that needs
tension (centre of gravity outside the support polygon) or that cannot balance (fewer than
three points not carrying the CoG) is an input error. Explicit [[rest]] forces are used as given;
they must not be negative, and if weight or cog_mm are also given they must agree (0.1 %, 1 mm).
Resting points outside the map's load grid, or measured points outside its portal-Y range, are
input errors (the map does not cover the part).";

#[derive(clap::Args, Debug)]
#[command(long_about = SIGN_HELP, after_help = "Examples:\n  truepos load map --bed bed.toml --output map.csv\n  truepos load curves --map map.csv --load load.toml --json\n  truepos load correct --map map.csv --load load.toml --bed bed.toml --points meas.csv --output corrected.csv\n  truepos load deflection --bed bed.toml --load load.toml --at points.csv --json\n\nPitch is about +X, roll about +Y: the portal's physical rotations (right-hand rule), so that\np + (pitch, roll, 0) × (p − o) corrects a measured point (a load ahead of the portal: negative pitch).\nDetails, statics and coverage rules: truepos load correct --help")]
pub struct Args {
    #[command(subcommand)]
    pub command: Sub,
}

#[derive(clap::Subcommand, Debug)]
pub enum Sub {
    /// Influence map from the plate FE model: pitch/roll per unit load against portal Y.
    #[command(long_about = SIGN_HELP, after_help = "Example:\n  truepos load map --bed bed.toml --output map.csv")]
    Map(MapCmd),
    /// Correct measured points for the load case (adds dx_um,dy_um,dz_um).
    #[command(long_about = SIGN_HELP, after_help = "Example:\n  truepos load correct --map map.csv --load load.toml --bed bed.toml --points meas.csv --output corrected.csv")]
    Correct(CorrectCmd),
    /// Pitch and roll curves of the load case, and the forces on the resting points.
    #[command(long_about = SIGN_HELP, after_help = "Example:\n  truepos load curves --map map.csv --load load.toml --json")]
    Curves(CurvesCmd),
    /// Bed deflection uz (mm, positive up) of the load case at given x_mm,y_mm points.
    #[command(
        after_help = "Example:\n  truepos load deflection --bed bed.toml --load load.toml --at points.csv --json"
    )]
    Deflection(DeflectionCmd),
}

#[derive(clap::Args, Debug)]
pub struct MapCmd {
    /// Bed model (TOML: [bed], [portal], [grid]).
    #[arg(long)]
    pub bed: PathBuf,
    /// Output influence map CSV.
    #[arg(long)]
    pub output: PathBuf,
    /// FE element size (mm); default: [bed] element_size_mm, else automatic.
    #[arg(long)]
    pub element_size_mm: Option<f64>,
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct CorrectCmd {
    /// Influence map CSV (from `truepos load map` or an outside FE package).
    #[arg(long)]
    pub map: PathBuf,
    /// Load case TOML.
    #[arg(long)]
    pub load: PathBuf,
    /// Bed TOML ([portal] gives the rails and their height).
    #[arg(long)]
    pub bed: PathBuf,
    /// Measured points (x_mm,y_mm,z_mm; other columns passed through).
    #[arg(long)]
    pub points: PathBuf,
    #[arg(long)]
    pub output: PathBuf,
    /// Also apply a 21-parameter geometric map (combined correction p + E(p) + e(p)).
    #[arg(long)]
    pub geometric_map: Option<PathBuf>,
    /// Squareness for --geometric-map (TOML or CSV).
    #[arg(long, requires = "geometric_map")]
    pub squareness: Option<PathBuf>,
    /// Probe offset for --geometric-map (ram frame, mm).
    #[arg(long, value_parser = parse_triple, default_value = "0,0,0")]
    pub probe_offset_mm: [f64; 3],
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct CurvesCmd {
    #[arg(long)]
    pub map: PathBuf,
    #[arg(long)]
    pub load: PathBuf,
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct DeflectionCmd {
    #[arg(long)]
    pub bed: PathBuf,
    #[arg(long)]
    pub load: PathBuf,
    /// Points (x_mm,y_mm).
    #[arg(long)]
    pub at: PathBuf,
    /// FE element size (mm); default: [bed] element_size_mm, else automatic.
    #[arg(long)]
    pub element_size_mm: Option<f64>,
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Example:\n  truepos simulate load --out data/load --seed 1\n  truepos load map --bed data/load/bed.toml --output data/load/map.csv\n  truepos load correct --map data/load/map.csv --load data/load/load.toml --bed data/load/bed.toml --points data/load/points.csv --output corrected.csv"
)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// Mass of the die (kg).
    #[arg(long, default_value_t = 2000.0)]
    pub mass_kg: f64,
    /// Probing noise, standard deviation per axis (µm).
    #[arg(long, default_value_t = 0.3)]
    pub noise_um: f64,
}

// ---------------------------------------------------------------------------------------------
// Files

#[derive(Deserialize, Debug)]
struct BedFile {
    bed: Option<BedToml>,
    portal: Option<PortalToml>,
    #[serde(default)]
    grid: GridToml,
}

#[derive(Deserialize, Debug)]
struct BedToml {
    size_x_mm: f64,
    size_y_mm: f64,
    thickness_mm: f64,
    youngs_modulus_mpa: f64,
    poisson: f64,
    supports_mm: Option<Vec<[f64; 2]>>,
    supports: Option<String>,
    support_stiffness_n_per_mm: Option<f64>,
    element_size_mm: Option<f64>,
}

#[derive(Deserialize, Debug)]
struct PortalToml {
    rail_x_mm: [f64; 2],
    rail_height_mm: f64,
    bearing_span_mm: f64,
    y_range_mm: [f64; 2],
    y_step_mm: f64,
}

#[derive(Deserialize, Debug)]
struct GridToml {
    #[serde(default = "d_spacing")]
    spacing_mm: f64,
    #[serde(default = "d_unit")]
    unit_load_n: f64,
}
fn d_spacing() -> f64 {
    100.0
}
fn d_unit() -> f64 {
    1000.0
}
impl Default for GridToml {
    fn default() -> Self {
        Self { spacing_mm: d_spacing(), unit_load_n: d_unit() }
    }
}

struct BedInfo {
    bed: Option<(Bed, Option<f64>)>,
    portal: Option<Portal>,
    grid: LoadGrid,
}

fn read_bed(path: &Path) -> Result<BedInfo, InputError> {
    let f: BedFile = truepos_io::config::read_toml(path)?;
    let bed = match f.bed {
        None => None,
        Some(b) => {
            let supports = match (&b.supports_mm, b.supports.as_deref()) {
                (Some(_), Some(_)) => return Err(InputError::in_file(path, "[bed]: give either supports_mm or supports, not both")),
                (Some(xy), None) => Supports::Points { xy: xy.clone(), stiffness_n_per_mm: b.support_stiffness_n_per_mm },
                (None, Some("simply-supported-edges")) => Supports::SimplySupportedEdges,
                (None, Some(other)) => return Err(InputError::in_file(path, format!("[bed] supports = \"{other}\": the only keyword is \"simply-supported-edges\" (or give supports_mm)"))),
                (None, None) => return Err(InputError::in_file(path, "[bed]: supports_mm = [[x, y], ...] (or supports = \"simply-supported-edges\") is required")),
            };
            Some((
                Bed {
                    size_x: b.size_x_mm,
                    size_y: b.size_y_mm,
                    thickness: b.thickness_mm,
                    youngs_modulus: b.youngs_modulus_mpa,
                    poisson: b.poisson,
                    supports,
                },
                b.element_size_mm,
            ))
        }
    };
    let portal = f.portal.map(|p| Portal {
        rail_x: p.rail_x_mm,
        rail_height: p.rail_height_mm,
        bearing_span: p.bearing_span_mm,
        y_range: p.y_range_mm,
        y_step: p.y_step_mm,
    });
    if let Some(p) = &portal {
        p.validate().map_err(|e| InputError::in_file(path, format!("[portal]: {e}")))?;
    }
    Ok(BedInfo {
        bed,
        portal,
        grid: LoadGrid { spacing: f.grid.spacing_mm, unit_load_n: f.grid.unit_load_n },
    })
}

#[derive(Deserialize, Debug)]
struct LoadToml {
    mass_kg: Option<f64>,
    weight_n: Option<f64>,
    cog_mm: Option<[f64; 2]>,
    rest_points_mm: Option<Vec<[f64; 2]>>,
    rest: Option<Vec<RestToml>>,
}

#[derive(Deserialize, Debug)]
struct RestToml {
    x_mm: f64,
    y_mm: f64,
    force_n: f64,
}

/// A resolved load case: point loads `(x, y, F)` (F downwards, N), weight and CoG.
pub struct LoadCase {
    pub loads: Vec<(f64, f64, f64)>,
    pub weight_n: f64,
    pub cog: [f64; 2],
    pub explicit: bool,
}

/// Standard gravity for `mass_kg`.
const G: f64 = 9.80665;

fn read_load(path: &Path) -> Result<LoadCase, InputError> {
    let f: LoadToml = truepos_io::config::read_toml(path)?;
    let err = |m: String| InputError::in_file(path, m);
    let weight = match (f.mass_kg, f.weight_n) {
        (Some(m), None) => Some(m * G),
        (None, Some(w)) => Some(w),
        (Some(m), Some(w)) => {
            if (m * G - w).abs() > 1e-3 * w.abs() {
                return Err(err(format!(
                    "mass_kg = {m} (weight {:.3} N) and weight_n = {w} disagree; give one",
                    m * G
                )));
            }
            Some(w)
        }
        (None, None) => None,
    };
    match (f.rest_points_mm, f.rest) {
        (Some(_), Some(_)) => {
            Err(err("give either rest_points_mm or [[rest]] entries with forces, not both".into()))
        }
        (None, None) => {
            Err(err("no resting points: give rest_points_mm = [[x, y], ...] or [[rest]] x_mm, y_mm, force_n"
                .into()))
        }
        (Some(r), None) => {
            let w =
                weight.ok_or_else(|| err("mass_kg or weight_n is required with rest_points_mm".into()))?;
            let c = f.cog_mm.ok_or_else(|| err("cog_mm = [x, y] is required with rest_points_mm".into()))?;
            let forces = statics::distribute(w, c, &r).map_err(|e| err(e.to_string()))?;
            Ok(LoadCase {
                loads: r.iter().zip(&forces).map(|(p, f)| (p[0], p[1], *f)).collect(),
                weight_n: w,
                cog: c,
                explicit: false,
            })
        }
        (None, Some(rest)) => {
            let loads: Vec<(f64, f64, f64)> = rest.iter().map(|r| (r.x_mm, r.y_mm, r.force_n)).collect();
            let (w, c) = statics::check_explicit(&loads, weight, f.cog_mm).map_err(|e| err(e.to_string()))?;
            Ok(LoadCase { loads, weight_n: w, cog: c, explicit: true })
        }
    }
}

/// Read an influence map CSV (errors with file, line, column).
pub fn read_influence(path: &Path) -> Result<InfluenceMap, InputError> {
    let t = Table::read(path)?;
    let unit = t
        .comments
        .iter()
        .find_map(|c| {
            let (k, v) = c.split_once('=')?;
            (k.trim() == "unit_load_n").then(|| v.trim().to_string())
        })
        .ok_or_else(|| {
            InputError::in_file(path, "missing the comment line '# unit_load_n = <N>' before the header")
        })?;
    let unit: f64 = unit.parse().ok().filter(|v: &f64| v.is_finite() && *v > 0.0).ok_or_else(|| {
        InputError::in_file(path, format!("unit_load_n = '{unit}' is not a positive number"))
    })?;
    let v = t.f64_columns(&["load_x_mm", "load_y_mm", "portal_y_mm", "pitch_urad", "roll_urad"])?;
    let rows: Vec<InfluenceRow> = v
        .chunks_exact(5)
        .map(|r| InfluenceRow {
            load_x: r[0],
            load_y: r[1],
            portal_y: r[2],
            pitch: r[3] * 1e-6,
            roll: r[4] * 1e-6,
        })
        .collect();
    InfluenceMap::from_rows(unit, &rows).map_err(|e| match e {
        InfluenceError::Duplicate { row, .. } | InfluenceError::NotFinite { row } => {
            InputError::at(path, t.line_number(row), None, e.to_string())
        }
        _ => InputError::in_file(path, e.to_string()),
    })
}

fn write_influence(map: &InfluenceMap, out: &Path, note: &str) -> Result<()> {
    let mut f = AtomicFile::create(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut w = CsvWriter::new(&mut f);
    w.comment(&format!("unit_load_n = {}", map.unit_load_n))?;
    w.comment(note)?;
    w.comment("pitch about +X, roll about +Y, µrad per unit load; sign: see `truepos load --help`")?;
    w.header(&["load_x_mm", "load_y_mm", "portal_y_mm", "pitch_urad", "roll_urad"])?;
    for r in map.rows() {
        w.row_f64(&[r.load_x, r.load_y, r.portal_y, r.pitch * 1e6, r.roll * 1e6])?;
    }
    f.commit().with_context(|| format!("cannot write {}", out.display()))?;
    Ok(())
}

fn superpose(
    map: &InfluenceMap,
    case: &LoadCase,
    map_path: &Path,
    load_path: &Path,
) -> Result<PortalCurves, InputError> {
    map.superpose(&case.loads)
        .map_err(|e| InputError::in_file(load_path, format!("{e} ({})", map_path.display())))
}

fn mesh_for(cli: Option<f64>, file: Option<f64>) -> Result<MeshOptions, crate::UsageError> {
    let s = cli.or(file).unwrap_or(0.0);
    if !(s.is_finite() && s >= 0.0) {
        return Err(crate::UsageError(format!("element size must be a positive number of mm (got {s})")));
    }
    Ok(MeshOptions::with_element_size(s))
}

// ---------------------------------------------------------------------------------------------
// Commands

pub fn run(a: Args) -> Result<Outcome> {
    match a.command {
        Sub::Map(m) => map_cmd(m),
        Sub::Correct(c) => correct_cmd(c),
        Sub::Curves(c) => curves_cmd(c),
        Sub::Deflection(d) => deflection_cmd(d),
    }
}

fn model_of(path: &Path, info: BedInfo) -> Result<(BedModel, Option<f64>), InputError> {
    let (bed, es) = info.bed.ok_or_else(|| InputError::in_file(path, "[bed] section is required"))?;
    let portal = info.portal.ok_or_else(|| InputError::in_file(path, "[portal] section is required"))?;
    Ok((BedModel { bed, portal, grid: info.grid }, es))
}

fn map_cmd(a: MapCmd) -> Result<Outcome> {
    let info = read_bed(&a.bed)?;
    let (model, es) = model_of(&a.bed, info)?;
    let mesh = mesh_for(a.element_size_mm, es)?;
    let (xs, ys) = fe_map::load_grid(&model).map_err(|e| InputError::in_file(&a.bed, e.to_string()))?;
    let n = xs.len() * ys.len();
    let pb = progress(n as u64, "influence map");
    let t0 = std::time::Instant::now();
    let map = fe_map::influence_map(&model, &mesh, &|k| pb.set_position(k as u64))
        .map_err(|e| InputError::in_file(&a.bed, e.to_string()))?;
    pb.finish_and_clear();
    write_influence(
        &map,
        &a.output,
        &format!(
            "plate FE of {} (element size {})",
            a.bed.display(),
            if mesh.element_size > 0.0 { format!("{} mm", mesh.element_size) } else { "automatic".into() }
        ),
    )?;
    let secs = t0.elapsed().as_secs_f64();
    if a.json {
        print_json(&json!({
            "output": a.output.display().to_string(),
            "n_loads": n,
            "n_portal_positions": map.portal_y().len(),
            "unit_load_n": map.unit_load_n,
            "seconds": secs,
        }))?;
    } else {
        eprintln!(
            "{n} unit loads × {} portal positions in {secs:.1} s → {}",
            map.portal_y().len(),
            a.output.display()
        );
    }
    Ok(Outcome::Done)
}

fn correct_cmd(a: CorrectCmd) -> Result<Outcome> {
    let map = read_influence(&a.map)?;
    let case = read_load(&a.load)?;
    let info = read_bed(&a.bed)?;
    let portal = info.portal.ok_or_else(|| {
        InputError::in_file(&a.bed, "[portal] section (rail_x_mm, rail_height_mm, …) is required")
    })?;
    let curves = superpose(&map, &case, &a.map, &a.load)?;
    let lc = LoadCorrection::new(curves, &portal);
    let geo = match &a.geometric_map {
        Some(m) => Some(load_map(&MapArgs {
            map: m.clone(),
            squareness: a.squareness.clone(),
            probe_offset_mm: a.probe_offset_mm,
            chain: ChainArg::Bridge,
            clamp: false,
        })?),
        None => None,
    };
    let [ox, oy, oz] = a.probe_offset_mm;
    let corr = Corrector { geometric: geo.as_ref(), load: Some(&lc), probe_offset: Vector3::new(ox, oy, oz) };
    let t = Table::read(&a.points)?;
    let mut pts = table_points(&t)?;
    let mut d = vec![Vector3::zeros(); pts.len()];
    corr.correct_measured(&mut pts, Some(&mut d)).map_err(|e| {
        let mut ie = batch_error(&t, e);
        ie.message.push_str(&format!(
            " (the influence map {} covers portal y only over this range)",
            a.map.display()
        ));
        ie
    })?;
    write_corrected(&t, &pts, &d, &a.output)?;
    let (rms, max) = rms_max_um(&d);
    if a.json {
        print_json(&json!({
            "n_points": pts.len(),
            "output": a.output.display().to_string(),
            "forces_n": case.loads.iter().map(|l| l.2).collect::<Vec<_>>(),
            "weight_n": case.weight_n,
            "rms_correction_um": rms,
            "max_correction_um": max,
        }))?;
    } else {
        eprintln!(
            "{} points corrected; correction rms {rms:.3} µm, max {max:.3} µm → {}",
            pts.len(),
            a.output.display()
        );
    }
    Ok(Outcome::Done)
}

fn curves_cmd(a: CurvesCmd) -> Result<Outcome> {
    let map = read_influence(&a.map)?;
    let case = read_load(&a.load)?;
    let c = superpose(&map, &case, &a.map, &a.load)?;
    if a.json {
        print_json(&json!({
            "portal_y_mm": c.y(),
            "pitch_urad": c.pitch.iter().map(|v| v * 1e6).collect::<Vec<_>>(),
            "roll_urad": c.roll.iter().map(|v| v * 1e6).collect::<Vec<_>>(),
            "forces_n": case.loads.iter().map(|l| l.2).collect::<Vec<_>>(),
            "rest_points_mm": case.loads.iter().map(|l| [l.0, l.1]).collect::<Vec<_>>(),
            "weight_n": case.weight_n,
            "cog_mm": case.cog,
            "explicit_forces": case.explicit,
        }))?;
    } else {
        println!("forces (N):");
        for l in &case.loads {
            println!("  ({:.1}, {:.1}) mm  {:.3}", l.0, l.1, l.2);
        }
        println!("{:>12} {:>12} {:>12}", "portal_y_mm", "pitch_urad", "roll_urad");
        for ((y, p), r) in c.y().iter().zip(&c.pitch).zip(&c.roll) {
            println!("{y:12.3} {:12.4} {:12.4}", p * 1e6, r * 1e6);
        }
    }
    Ok(Outcome::Done)
}

fn deflection_cmd(a: DeflectionCmd) -> Result<Outcome> {
    let info = read_bed(&a.bed)?;
    let (bed, es) = info.bed.ok_or_else(|| InputError::in_file(&a.bed, "[bed] section is required"))?;
    let case = read_load(&a.load)?;
    let mesh = mesh_for(a.element_size_mm, es)?;
    let t = Table::read(&a.at)?;
    let xy = t.f64_columns(&["x_mm", "y_mm"])?;
    let at: Vec<[f64; 2]> = xy.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
    let uz = fe_map::deflection_at(&bed, &mesh, &case.loads, &at).map_err(|e| match e {
        truepos_fe::FeError::InvalidLoad { .. } => InputError::in_file(&a.load, format!("{e}")),
        _ => InputError::in_file(&a.bed, format!("plate model: {e}")),
    })?;
    let mut out = Vec::with_capacity(uz.len());
    for (i, u) in uz.iter().enumerate() {
        out.push(u.ok_or_else(|| {
            InputError::at(
                &a.at,
                t.line_number(i),
                None,
                format!("point ({}, {}) mm is outside the bed", at[i][0], at[i][1]),
            )
        })?);
    }
    if a.json {
        print_json(&json!({ "uz_mm": out, "forces_n": case.loads.iter().map(|l| l.2).collect::<Vec<_>>() }))?;
    } else {
        for (p, u) in at.iter().zip(&out) {
            println!("{:.3} {:.3}  uz {:+.6} mm", p[0], p[1], u);
        }
    }
    Ok(Outcome::Done)
}

// ---------------------------------------------------------------------------------------------
// Simulation and demo

use truepos_sim::scenario::load::{simulate as sim_load, LoadConfig, LoadData};

fn bed_toml(c: &LoadConfig) -> String {
    let supports = match &c.bed.supports {
        Supports::Points { xy, .. } => format!(
            "supports_mm = [{}]",
            xy.iter().map(|p| format!("[{}, {}]", p[0], p[1])).collect::<Vec<_>>().join(", ")
        ),
        Supports::SimplySupportedEdges => "supports = \"simply-supported-edges\"".into(),
    };
    format!(
        "# Virtual bridge CMM: granite bed on its pads, portal rails (truepos simulate load)\n[bed]\nsize_x_mm = {}\nsize_y_mm = {}\nthickness_mm = {}\nyoungs_modulus_mpa = {}\npoisson = {}\n{supports}\nelement_size_mm = {}\n\n[portal]\nrail_x_mm = [{}, {}]\nrail_height_mm = {}\nbearing_span_mm = {}\ny_range_mm = [{}, {}]\ny_step_mm = {}\n\n[grid]\nspacing_mm = {}\nunit_load_n = {}\n",
        c.bed.size_x, c.bed.size_y, c.bed.thickness, c.bed.youngs_modulus, c.bed.poisson, c.map_element_size, c.rail_x[0], c.rail_x[1], c.rail_height, c.bearing_span, c.y_range[0], c.y_range[1], c.y_step, c.grid_spacing, c.unit_load_n
    )
}

fn load_toml(c: &LoadConfig) -> String {
    format!(
        "# A die on three pads (truepos simulate load)\nmass_kg = {}\ncog_mm = [{}, {}]\nrest_points_mm = [{}]\n",
        c.mass_kg,
        c.cog[0],
        c.cog[1],
        c.rests.iter().map(|p| format!("[{}, {}]", p[0], p[1])).collect::<Vec<_>>().join(", ")
    )
}

fn write_scenario(dir: &Path, seed: u64, mass_kg: f64, noise_um: f64) -> Result<(LoadConfig, LoadData)> {
    if !(mass_kg.is_finite() && mass_kg > 0.0 && noise_um.is_finite() && noise_um >= 0.0) {
        return Err(crate::UsageError(format!(
            "--mass-kg must be positive and --noise-um non-negative (got {mass_kg}, {noise_um})"
        ))
        .into());
    }
    let cfg = LoadConfig { mass_kg, noise_sigma: noise_um * 1e-3, ..LoadConfig::default() };
    let data = sim_load(&cfg, seed).map_err(|e| crate::DeviceError(format!("load scenario: {e}")))?;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    write_atomic(dir.join("bed.toml"), bed_toml(&cfg).as_bytes())?;
    write_atomic(dir.join("load.toml"), load_toml(&cfg).as_bytes())?;
    let mut f = AtomicFile::create(dir.join("points.csv"))?;
    {
        let mut w = CsvWriter::new(&mut f);
        w.comment(&format!(
            "indicated coordinates on the loaded virtual CMM, seed {seed}, probing noise {} µm per axis",
            cfg.noise_sigma * 1e3
        ))?;
        w.header(&["id", "x_mm", "y_mm", "z_mm"])?;
        for (i, p) in data.indicated.iter().enumerate() {
            w.field_str(&format!("P{}", i + 1))?;
            w.row_f64(&[p.x, p.y, p.z])?;
        }
    }
    f.commit()?;
    let um = |v: &[f64]| v.iter().map(|x| x * 1e6).collect::<Vec<_>>();
    let truth = json!({
        "scenario": "load",
        "seed": seed,
        "weight_n": data.weight_n,
        "forces_n": data.forces_n,
        "rest_points_mm": cfg.rests,
        "ids": (1..=data.indicated.len()).map(|i| format!("P{i}")).collect::<Vec<_>>(),
        "true_points_mm": data.true_points.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
        "error_um": data.indicated_exact.iter().zip(&data.true_points).map(|(i, t)| [(i.x - t.x) * 1e3, (i.y - t.y) * 1e3, (i.z - t.z) * 1e3]).collect::<Vec<_>>(),
        "noise_um": data.indicated.iter().zip(&data.indicated_exact).map(|(n, e)| [(n.x - e.x) * 1e3, (n.y - e.y) * 1e3, (n.z - e.z) * 1e3]).collect::<Vec<_>>(),
        "noise_sigma_um": cfg.noise_sigma * 1e3,
        "portal_y_mm": data.portal_y,
        "pitch_urad": um(&data.pitch),
        "roll_urad": um(&data.roll),
        "portal_sink_um": data.portal_sink.iter().map(|v| v * 1e3).collect::<Vec<_>>(),
        "rest_uz_um": data.rest_uz.iter().map(|v| v * 1e3).collect::<Vec<_>>(),
        "sim_element_size_mm": cfg.sim_element_size,
        "map_element_size_mm": cfg.map_element_size,
        "notes": "error_um = indicated (noise-free) − true; pitch/roll in truepos-comp's sign (rotation of the bed seen from the portal = −physical tilt); portal_sink is not applied to the points",
    });
    write_atomic(dir.join("truth.json"), serde_json::to_string_pretty(&truth)?.as_bytes())?;
    Ok((cfg, data))
}

pub fn simulate(a: SimArgs) -> Result<Outcome> {
    let (_, data) = write_scenario(&a.common.out, a.common.seed, a.mass_kg, a.noise_um)?;
    eprintln!(
        "load scenario: {} points, forces {:?} N → {}",
        data.indicated.len(),
        data.forces_n.map(|f| (f * 10.0).round() / 10.0),
        a.common.out.display()
    );
    Ok(Outcome::Done)
}

/// This capability's section of the demo report.
pub fn demo_section(report: &mut Report) -> Result<()> {
    let dir = report.dir.join("load");
    let (cfg, data) = write_scenario(&dir, 1, 2000.0, 0.3)?;
    let portal = Portal {
        rail_x: cfg.rail_x,
        rail_height: cfg.rail_height,
        bearing_span: cfg.bearing_span,
        y_range: cfg.y_range,
        y_step: cfg.y_step,
    };
    let model = BedModel {
        bed: cfg.bed.clone(),
        portal,
        grid: LoadGrid { spacing: cfg.grid_spacing, unit_load_n: cfg.unit_load_n },
    };
    let t0 = std::time::Instant::now();
    let map = fe_map::influence_map(&model, &MeshOptions::with_element_size(cfg.map_element_size), &|_| {})?;
    let t_map = t0.elapsed().as_secs_f64();
    write_influence(&map, &dir.join("map.csv"), "plate FE of bed.toml")?;
    let forces = statics::distribute(cfg.mass_kg * G, cfg.cog, &cfg.rests)?;
    let loads: Vec<(f64, f64, f64)> = cfg.rests.iter().zip(&forces).map(|(r, f)| (r[0], r[1], *f)).collect();
    let curves = map.superpose(&loads)?;
    let lc = LoadCorrection::new(curves.clone(), &portal);
    let corr = Corrector { geometric: None, load: Some(&lc), probe_offset: Vector3::zeros() };
    let mut corrected: Vec<Point3> = data.indicated.clone();
    corr.correct_measured(&mut corrected, None)?;
    let err =
        |a: &[Point3]| -> Vec<Vector3> { a.iter().zip(&data.true_points).map(|(p, t)| p - t).collect() };
    let before = err(&data.indicated_exact);
    let after_load: Vec<Point3> = corrected
        .iter()
        .zip(&data.indicated)
        .zip(&data.indicated_exact)
        .map(|((c, n), e)| c - (n - e))
        .collect();
    let after = err(&after_load);
    let (rb, mb) = rms_max_um(&before);
    let (ra, ma) = rms_max_um(&after);
    let (rn0, mn0) = rms_max_um(&err(&data.indicated));
    let (rn, mn) = rms_max_um(&err(&corrected));
    let heat = report::heatmap(
        "Bed deflection uz under the die",
        &data.grid_x,
        &data.grid_y,
        &data.uz.iter().map(|r| r.iter().map(|v| v * 1e3).collect()).collect::<Vec<Vec<f64>>>(),
        "µm",
    )?;
    let curve_plot = report::xy_plot(
        "Portal pitch and roll along Y",
        "portal y (mm)",
        "µrad",
        &[
            Series::line(
                "pitch (map, superposed)",
                curves.y().iter().zip(&curves.pitch).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
            Series::points(
                "pitch (truth, fine FE)",
                data.portal_y.iter().zip(&data.pitch).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
            Series::line(
                "roll (map, superposed)",
                curves.y().iter().zip(&curves.roll).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
            Series::points(
                "roll (truth, fine FE)",
                data.portal_y.iter().zip(&data.roll).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
        ],
    )?;
    let rows = vec![
        vec![
            "load-induced error (noise excluded)".into(),
            format!("{rb:.3}"),
            format!("{mb:.3}"),
            format!("{ra:.4}"),
            format!("{ma:.4}"),
            format!("{:.2} %", 100.0 * (1.0 - ra / rb)),
        ],
        vec![
            format!("measured − true (incl. {:.1} µm probing noise)", cfg.noise_sigma * 1e3),
            format!("{rn0:.3}"),
            format!("{mn0:.3}"),
            format!("{rn:.3}"),
            format!("{mn:.3}"),
            format!("{:.2} %", 100.0 * (1.0 - rn / rn0)),
        ],
    ];
    let force_rows: Vec<Vec<String>> = cfg
        .rests
        .iter()
        .zip(&forces)
        .zip(&data.forces_n)
        .map(|((r, f), t)| vec![format!("({:.0}, {:.0})", r[0], r[1]), format!("{f:.2}"), format!("{t:.2}")])
        .collect();
    let html = format!(
        "<p>A {} kg die on three pads on a {}×{}×{} mm granite bed (four support pads). The influence map ({} unit loads of {} N on a {} mm grid × {} portal positions, FE element {} mm) took {t_map:.1} s; the simulator's truth uses a {} mm mesh. {} points measured at two heights with {} µm probing noise.</p>{}{}<p>Forces on the pads by statics:</p>{}<p>Errors of the measured points against truth (µm):</p>{}",
        cfg.mass_kg, cfg.bed.size_x, cfg.bed.size_y, cfg.bed.thickness,
        map.load_x().len() * map.load_y().len(), cfg.unit_load_n, cfg.grid_spacing, map.portal_y().len(), cfg.map_element_size, cfg.sim_element_size,
        data.indicated.len(), cfg.noise_sigma * 1e3,
        heat, curve_plot,
        report::table(&["pad (mm)", "truepos (N)", "truth (N)"], &force_rows),
        report::table(&["", "RMS before", "max before", "RMS after", "max after", "removed"], &rows),
    );
    report.add("load", "Bed deformation under load", html);
    Ok(())
}
