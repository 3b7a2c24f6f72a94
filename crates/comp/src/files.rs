//! The file formats of compensation, each defined once: the geometric map CSV ([`read_map`]),
//! squareness in TOML or CSV ([`read_squareness`]), the bed TOML ([`read_bed`]),
//! the load case TOML ([`read_load`]) and the influence map CSV ([`read_influence`],
//! [`write_influence`]). Unknown keys are errors; every error names the file (and the line and
//! column where there is one) through `truepos_io::InputError`.

use crate::fe_map::{BedModel, LoadGrid};
use crate::geometric::{Axis, AxisErrors, AxisTable, GeometricMap, Squareness};
use crate::influence::{InfluenceError, InfluenceMap, InfluenceRow};
use crate::load::Portal;
use crate::statics;
use serde::Deserialize;
use std::path::Path;
use truepos_fe::{Bed, Supports};
use truepos_io::atomic::AtomicFile;
use truepos_io::csv::{CsvWriter, Table};
use truepos_io::InputError;
use truepos_math::Vector3;

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

/// Write an influence map CSV (atomically): the `unit_load_n` comment, a note, the header and
/// one row per (load, portal position), µrad per unit load.
pub fn write_influence(map: &InfluenceMap, out: &Path, note: &str) -> Result<(), std::io::Error> {
    let mut f = AtomicFile::create(out)?;
    let mut w = CsvWriter::new(&mut f);
    w.comment(&format!("unit_load_n = {}", map.unit_load_n))?;
    w.comment(note)?;
    w.comment("pitch about +X, roll about +Y, µrad per unit load; sign: see `truepos load --help`")?;
    w.header(&["load_x_mm", "load_y_mm", "portal_y_mm", "pitch_urad", "roll_urad"])?;
    for r in map.rows() {
        w.row_f64(&[r.load_x, r.load_y, r.portal_y, r.pitch * 1e6, r.roll * 1e6])?;
    }
    f.commit()?;
    Ok(())
}

/// RMS and maximum norm (µm) of displacements.
pub fn rms_max_um(d: &[Vector3]) -> (f64, f64) {
    if d.is_empty() {
        return (0.0, 0.0);
    }
    let rms = (d.iter().map(|v| v.norm_squared()).sum::<f64>() / d.len() as f64).sqrt();
    (rms * 1e3, d.iter().map(|v| v.norm()).fold(0.0, f64::max) * 1e3)
}

/// The bed TOML file: `[bed]`, `[portal]` and `[grid]`.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct BedFile {
    /// The `[bed]` table.
    pub bed: Option<BedToml>,
    /// The `[portal]` table.
    pub portal: Option<PortalToml>,
    /// The `[grid]` table (defaults when absent).
    #[serde(default)]
    pub grid: GridToml,
}

/// The `[bed]` table: the plate, its material and its supports.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct BedToml {
    /// Bed size along X, mm.
    pub size_x_mm: f64,
    /// Bed size along Y, mm.
    pub size_y_mm: f64,
    /// Plate thickness, mm.
    pub thickness_mm: f64,
    /// Young's modulus, MPa.
    pub youngs_modulus_mpa: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Support positions (x, y), mm.
    pub supports_mm: Option<Vec<[f64; 2]>>,
    /// A named support layout instead of `supports_mm`.
    pub supports: Option<String>,
    /// Stiffness of each support, N/mm (rigid when absent).
    pub support_stiffness_n_per_mm: Option<f64>,
    /// FE element size, mm (automatic when absent).
    pub element_size_mm: Option<f64>,
}

/// The `[portal]` table: the rails and the portal's travel.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct PortalToml {
    /// X of the two rails, mm.
    pub rail_x_mm: [f64; 2],
    /// Height of the rails above the bed, mm.
    pub rail_height_mm: f64,
    /// Distance between a carriage's bearings along Y, mm.
    pub bearing_span_mm: f64,
    /// The portal's travel in Y (start, end), mm.
    pub y_range_mm: [f64; 2],
    /// Step of the portal positions in Y, mm.
    pub y_step_mm: f64,
}

/// The `[grid]` table: the unit-load grid of the influence map.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct GridToml {
    /// Distance between load nodes, mm.
    #[serde(default = "d_spacing")]
    pub spacing_mm: f64,
    /// Unit load per node, N.
    #[serde(default = "d_unit")]
    pub unit_load_n: f64,
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

/// What a bed file describes, checked.
pub struct BedInfo {
    /// The plate and the file's FE element size, if `[bed]` is given.
    pub bed: Option<(Bed, Option<f64>)>,
    /// The portal, if `[portal]` is given.
    pub portal: Option<Portal>,
    /// The unit-load grid.
    pub grid: LoadGrid,
}

/// Read the bed TOML (`[bed]`, `[portal]`, `[grid]`): the one reader of this format. Every value
/// found wrong (a size that is not positive, a pad off the bed, a portal that cannot be) is
/// reported at its line and column.
pub fn read_bed(path: &Path) -> Result<BedInfo, InputError> {
    let (f, doc): (BedFile, _) = truepos_io::config::read_toml_doc(path)?;
    let bed = match f.bed {
        None => None,
        Some(b) => {
            for (key, v) in [
                ("size_x_mm", b.size_x_mm),
                ("size_y_mm", b.size_y_mm),
                ("thickness_mm", b.thickness_mm),
                ("youngs_modulus_mpa", b.youngs_modulus_mpa),
            ] {
                doc.positive(&["bed", key], v)?;
            }
            if !(b.poisson.is_finite() && b.poisson > -1.0 && b.poisson < 0.5) {
                return Err(doc.error_at(
                    &["bed", "poisson"],
                    format!("[bed] poisson = {}: must lie between -1 and 0.5", b.poisson),
                ));
            }
            if let Some(k) = b.support_stiffness_n_per_mm {
                doc.positive(&["bed", "support_stiffness_n_per_mm"], k)?;
            }
            if let Some(e) = b.element_size_mm {
                doc.positive(&["bed", "element_size_mm"], e)?;
            }
            let tol = 1e-9 * b.size_x_mm.max(b.size_y_mm);
            for (i, p) in b.supports_mm.iter().flatten().enumerate() {
                let inside = p.iter().all(|v| v.is_finite())
                    && (-tol..=b.size_x_mm + tol).contains(&p[0])
                    && (-tol..=b.size_y_mm + tol).contains(&p[1]);
                if !inside {
                    return Err(doc.error_at(
                        &["bed", "supports_mm", &i.to_string()],
                        format!(
                            "[bed] supports_mm: pad {} at ({}, {}) mm is off the {} × {} mm bed",
                            i + 1,
                            p[0],
                            p[1],
                            b.size_x_mm,
                            b.size_y_mm
                        ),
                    ));
                }
            }
            let supports = match (&b.supports_mm, b.supports.as_deref()) {
                (Some(_), Some(_)) => return Err(doc.error_at(&["bed", "supports"], "[bed]: give either supports_mm or supports, not both")),
                (Some(xy), None) => Supports::Points { xy: xy.clone(), stiffness_n_per_mm: b.support_stiffness_n_per_mm },
                (None, Some("simply-supported-edges")) => Supports::SimplySupportedEdges,
                (None, Some(other)) => return Err(doc.error_at(&["bed", "supports"], format!("[bed] supports = \"{other}\": the only keyword is \"simply-supported-edges\" (or give supports_mm)"))),
                (None, None) => return Err(doc.error_at(&["bed"], "[bed]: supports_mm = [[x, y], ...] (or supports = \"simply-supported-edges\") is required")),
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
    if let Some(p) = &f.portal {
        doc.positive(&["portal", "bearing_span_mm"], p.bearing_span_mm)?;
        doc.positive(&["portal", "y_step_mm"], p.y_step_mm)?;
    }
    let portal = f.portal.map(|p| Portal {
        rail_x: p.rail_x_mm,
        rail_height: p.rail_height_mm,
        bearing_span: p.bearing_span_mm,
        y_range: p.y_range_mm,
        y_step: p.y_step_mm,
    });
    if let Some(p) = &portal {
        p.validate().map_err(|e| {
            let key = match e {
                crate::load::PortalError::Rails(..) => "rail_x_mm",
                crate::load::PortalError::Span(..) => "bearing_span_mm",
                crate::load::PortalError::Range(..) => "y_range_mm",
                _ => "",
            };
            let keys: &[&str] = if key.is_empty() { &["portal"] } else { &["portal", key] };
            doc.error_at(keys, format!("[portal]: {e}"))
        })?;
    }
    doc.positive(&["grid", "spacing_mm"], f.grid.spacing_mm)?;
    doc.positive(&["grid", "unit_load_n"], f.grid.unit_load_n)?;
    Ok(BedInfo {
        bed,
        portal,
        grid: LoadGrid { spacing: f.grid.spacing_mm, unit_load_n: f.grid.unit_load_n },
    })
}

/// The load case TOML file.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct LoadToml {
    /// Mass of the load, kg (or `weight_n`).
    pub mass_kg: Option<f64>,
    /// Weight of the load, N (or `mass_kg`).
    pub weight_n: Option<f64>,
    /// Centre of gravity (x, y), mm.
    pub cog_mm: Option<[f64; 2]>,
    /// Resting points (x, y), mm; forces from statics.
    pub rest_points_mm: Option<Vec<[f64; 2]>>,
    /// Resting points with explicit forces (`[[rest]]`).
    pub rest: Option<Vec<RestToml>>,
}

/// One `[[rest]]` table: a resting point with its force.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct RestToml {
    /// X of the resting point, mm.
    pub x_mm: f64,
    /// Y of the resting point, mm.
    pub y_mm: f64,
    /// Downward force there, N.
    pub force_n: f64,
}

/// A resolved load case: point loads `(x, y, F)` (F downwards, N), weight and CoG.
#[derive(Clone, Debug)]
pub struct LoadCase {
    /// Point loads (x mm, y mm, downward force N).
    pub loads: Vec<(f64, f64, f64)>,
    /// Total weight, N.
    pub weight_n: f64,
    /// Centre of gravity (x, y), mm.
    pub cog: [f64; 2],
    /// Whether the forces were given (`[[rest]]`) rather than found by statics.
    pub explicit: bool,
}

/// Standard gravity for `mass_kg`.
pub const G: f64 = 9.80665;

/// Heaviest load a load case may hold, kg (1000 t): several times the heaviest workpieces of
/// the largest machine-tool tables; beyond it a number is a unit mistake (grams, newtons
/// given as kilograms) or no number at all, not a load the bed model can mean.
pub const MAX_LOAD_KG: f64 = 1.0e6;

/// The refusal of `key = value` above `limit` (in `unit`).
fn over_limit(key: &str, value: f64, unit: &str, limit: f64) -> String {
    format!(
        "{key} = {value}: above {limit:.0} {unit} (a load of {:.0} t), beyond any machine-tool table; check the unit",
        MAX_LOAD_KG / 1000.0
    )
}

/// Read a load case TOML (`mass_kg`/`weight_n`, `cog_mm`, `rest_points_mm` or `[[rest]]`) and
/// resolve it to point loads.
pub fn read_load(path: &Path) -> Result<LoadCase, InputError> {
    let (f, doc): (LoadToml, _) = truepos_io::config::read_toml_doc(path)?;
    let err = |m: String| InputError::in_file(path, m);
    if let Some(m) = f.mass_kg {
        doc.positive(&["mass_kg"], m)?;
        if m > MAX_LOAD_KG {
            return Err(doc.error_at(&["mass_kg"], over_limit("mass_kg", m, "kg", MAX_LOAD_KG)));
        }
    }
    if let Some(w) = f.weight_n {
        doc.positive(&["weight_n"], w)?;
        if w > MAX_LOAD_KG * G {
            return Err(doc.error_at(&["weight_n"], over_limit("weight_n", w, "N", MAX_LOAD_KG * G)));
        }
    }
    for (i, r) in f.rest.iter().flatten().enumerate() {
        for (k, v) in [("x_mm", r.x_mm), ("y_mm", r.y_mm), ("force_n", r.force_n)] {
            if !v.is_finite() {
                return Err(doc.error_at(
                    &["rest", &i.to_string(), k],
                    format!("[[rest]] #{} {k} is not finite", i + 1),
                ));
            }
            if k == "force_n" && v.abs() > MAX_LOAD_KG * G {
                return Err(doc.error_at(
                    &["rest", &i.to_string(), k],
                    format!("[[rest]] #{} {}", i + 1, over_limit(k, v, "N", MAX_LOAD_KG * G)),
                ));
            }
        }
    }
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

impl BedInfo {
    /// The FE model of a bed file that has both `[bed]` and `[portal]`, and the file's element size.
    pub fn into_model(self, path: &Path) -> Result<(BedModel, Option<f64>), InputError> {
        let info = self;
        let (bed, es) = info.bed.ok_or_else(|| InputError::in_file(path, "[bed] section is required"))?;
        let portal = info.portal.ok_or_else(|| InputError::in_file(path, "[portal] section is required"))?;
        Ok((BedModel { bed, portal, grid: info.grid }, es))
    }
}

/// Read a geometric map CSV (errors with file, line, column).
pub fn read_map(path: &Path) -> Result<GeometricMap, InputError> {
    let t = Table::read(path)?;
    let cols = ["position_mm", "pos_um", "str1_um", "str2_um", "pitch_urad", "yaw_urad", "roll_urad"];
    let v = t.f64_columns(&cols)?;
    let axes = t.str_column("axis")?;
    let acol = t.column("axis").map(|c| c + 1);
    let mut rows: [Vec<(f64, AxisErrors, usize)>; 3] = [vec![], vec![], vec![]];
    for (i, a) in axes.iter().enumerate() {
        let k = match a.trim().to_ascii_lowercase().as_str() {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            other => {
                return Err(InputError::at(
                    path,
                    t.line_number(i),
                    acol,
                    format!("axis must be x, y or z (got '{other}')"),
                )
                .with_column_name("axis"))
            }
        };
        let r = &v[i * 7..i * 7 + 7];
        let e = AxisErrors {
            pos: r[1] * 1e-3,
            str1: r[2] * 1e-3,
            str2: r[3] * 1e-3,
            pitch: r[4] * 1e-6,
            yaw: r[5] * 1e-6,
            roll: r[6] * 1e-6,
        };
        rows[k].push((r[0], e, i));
    }
    let u = read_map_u(&t, path)?;
    let mut map = GeometricMap::default();
    for (k, axis) in [Axis::X, Axis::Y, Axis::Z].into_iter().enumerate() {
        let r = &mut rows[k];
        if r.is_empty() {
            continue;
        }
        r.sort_by(|a, b| a.0.total_cmp(&b.0));
        for w in r.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(InputError::at(
                    path,
                    t.line_number(w[1].2.max(w[0].2)),
                    t.column("position_mm").map(|c| c + 1),
                    format!(
                        "axis {}: position {} mm appears twice (also line {})",
                        axis.name(),
                        w[0].0,
                        t.line_number(w[1].2.min(w[0].2))
                    ),
                ));
            }
        }
        let pos: Vec<f64> = r.iter().map(|x| x.0).collect();
        let e: Vec<AxisErrors> = r.iter().map(|x| x.1).collect();
        let mut table =
            AxisTable::new(axis, pos, &e).map_err(|e| InputError::in_file(path, e.to_string()))?;
        if let Some(u) = &u {
            let ue: Vec<AxisErrors> = r.iter().map(|x| u[x.2]).collect();
            table = table.with_uncertainty(&ue).map_err(|e| InputError::in_file(path, e.to_string()))?;
        }
        match axis {
            Axis::X => map.x = Some(table),
            Axis::Y => map.y = Some(table),
            Axis::Z => map.z = Some(table),
        }
    }
    if map.x.is_none() && map.y.is_none() && map.z.is_none() {
        return Err(InputError::in_file(path, "the map has no rows"));
    }
    // A missing table would silently read as zero errors for that axis: refuse it by name.
    let missing: Vec<&str> = [("x", map.x.is_none()), ("y", map.y.is_none()), ("z", map.z.is_none())]
        .into_iter()
        .filter_map(|(n, m)| m.then_some(n))
        .collect();
    if !missing.is_empty() {
        return Err(InputError::in_file(
            path,
            format!(
                "the {} table{} missing: the map needs rows for every axis (axis column x, y and z; \
                 a table of zeros if that axis really has no errors)",
                missing.join(" and "),
                if missing.len() > 1 { "s are" } else { " is" }
            ),
        )
        .with_column_name("axis"));
    }
    Ok(map)
}

/// The optional standard-uncertainty columns of a map CSV, in the order of the components.
pub const MAP_U_COLUMNS: [&str; 6] =
    ["u_pos_um", "u_str1_um", "u_str2_um", "u_pitch_urad", "u_yaw_urad", "u_roll_urad"];

/// The optional standard-uncertainty columns of a squareness CSV (or keys of its TOML table).
pub const SQUARENESS_U_COLUMNS: [&str; 3] = ["u_xy_urad", "u_xz_urad", "u_yz_urad"];

/// A partial set of optional columns: the error on the header line, at the first present one.
fn partial_set(t: &Table, path: &Path, names: &[&str]) -> Result<bool, InputError> {
    let present: Vec<&str> = names.iter().copied().filter(|n| t.column(n).is_some()).collect();
    if present.is_empty() || present.len() == names.len() {
        return Ok(!present.is_empty());
    }
    let missing: Vec<&str> = names.iter().copied().filter(|n| t.column(n).is_none()).collect();
    Err(InputError::at(
        path,
        t.header_line(),
        t.column(present[0]).map(|c| c + 1),
        format!(
            "standard-uncertainty columns come all together or not at all: {} present, {} missing",
            present.join(", "),
            missing.join(", ")
        ),
    )
    .with_column_name(present[0]))
}

/// Refuse a negative or non-finite standard uncertainty at its line and column.
fn check_u(t: &Table, path: &Path, names: &[&str], v: &[f64]) -> Result<(), InputError> {
    let k = names.len();
    for (i, row) in v.chunks_exact(k).enumerate() {
        for (j, x) in row.iter().enumerate() {
            if !(x.is_finite() && *x >= 0.0) {
                return Err(InputError::at(
                    path,
                    t.line_number(i),
                    t.column(names[j]).map(|c| c + 1),
                    format!("{} = {x}: a standard uncertainty is a finite number ≥ 0", names[j]),
                )
                .with_column_name(names[j]));
            }
        }
    }
    Ok(())
}

/// The map's standard uncertainties per data row (mm, rad), if the file has the columns.
fn read_map_u(t: &Table, path: &Path) -> Result<Option<Vec<AxisErrors>>, InputError> {
    if !partial_set(t, path, &MAP_U_COLUMNS)? {
        return Ok(None);
    }
    let v = t.f64_columns(&MAP_U_COLUMNS)?;
    check_u(t, path, &MAP_U_COLUMNS, &v)?;
    Ok(Some(
        v.chunks_exact(6)
            .map(|r| AxisErrors {
                pos: r[0] * 1e-3,
                str1: r[1] * 1e-3,
                str2: r[2] * 1e-3,
                pitch: r[3] * 1e-6,
                yaw: r[4] * 1e-6,
                roll: r[5] * 1e-6,
            })
            .collect(),
    ))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SqFile {
    squareness: SqToml,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SqToml {
    #[serde(default)]
    xy_urad: f64,
    #[serde(default)]
    xz_urad: f64,
    #[serde(default)]
    yz_urad: f64,
    u_xy_urad: Option<f64>,
    u_xz_urad: Option<f64>,
    u_yz_urad: Option<f64>,
}

/// Read squareness from TOML or CSV (µrad in the file, rad returned).
pub fn read_squareness(path: &Path) -> Result<Squareness, InputError> {
    Ok(read_squareness_u(path)?.0)
}

/// Read squareness and, when the file has them (`u_xy_urad, u_xz_urad, u_yz_urad`, all three or
/// none), its standard uncertainties (k = 1), from TOML or CSV (µrad in the file, rad returned).
pub fn read_squareness_u(path: &Path) -> Result<(Squareness, Option<Squareness>), InputError> {
    let is_toml = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let (xy, xz, yz, u) = if is_toml {
        let (f, doc): (SqFile, _) = truepos_io::config::read_toml_doc(path)?;
        let q = &f.squareness;
        for (k, v) in [("xy_urad", q.xy_urad), ("xz_urad", q.xz_urad), ("yz_urad", q.yz_urad)] {
            if !v.is_finite() {
                return Err(doc.error_at(&["squareness", k], format!("[squareness] {k} is not finite")));
            }
        }
        let uk = [("u_xy_urad", q.u_xy_urad), ("u_xz_urad", q.u_xz_urad), ("u_yz_urad", q.u_yz_urad)];
        let n_some = uk.iter().filter(|(_, v)| v.is_some()).count();
        let u = match n_some {
            0 => None,
            3 => {
                for (k, v) in uk {
                    let v = v.unwrap_or_default();
                    if !(v.is_finite() && v >= 0.0) {
                        return Err(doc.error_at(
                            &["squareness", k],
                            format!("[squareness] {k} = {v}: a standard uncertainty is a finite number ≥ 0"),
                        ));
                    }
                }
                Some([q.u_xy_urad, q.u_xz_urad, q.u_yz_urad].map(Option::unwrap_or_default))
            }
            _ => {
                let (first, _) = uk.iter().find(|(_, v)| v.is_some()).copied().unwrap_or(uk[0]);
                let missing: Vec<&str> = uk.iter().filter(|(_, v)| v.is_none()).map(|(k, _)| *k).collect();
                return Err(doc.error_at(
                    &["squareness", first],
                    format!(
                        "[squareness] standard uncertainties come all together or not at all: {} missing",
                        missing.join(", ")
                    ),
                ));
            }
        };
        (q.xy_urad, q.xz_urad, q.yz_urad, u)
    } else {
        let t = Table::read(path)?;
        let v = t.f64_columns(&["xy_urad", "xz_urad", "yz_urad"])?;
        if t.n_rows() != 1 {
            return Err(InputError::in_file(
                path,
                format!("a squareness CSV has exactly one data row (got {})", t.n_rows()),
            ));
        }
        let u = if partial_set(&t, path, &SQUARENESS_U_COLUMNS)? {
            let u = t.f64_columns(&SQUARENESS_U_COLUMNS)?;
            check_u(&t, path, &SQUARENESS_U_COLUMNS, &u)?;
            Some([u[0], u[1], u[2]])
        } else {
            None
        };
        (v[0], v[1], v[2], u)
    };
    for (n, v) in [("xy_urad", xy), ("xz_urad", xz), ("yz_urad", yz)] {
        if !v.is_finite() {
            return Err(InputError::in_file(path, format!("{n} is not finite")));
        }
    }
    let rad = |[a, b, c]: [f64; 3]| Squareness { xy: a * 1e-6, xz: b * 1e-6, yz: c * 1e-6 };
    Ok((rad([xy, xz, yz]), u.map(rad)))
}

/// Write the volumetric errors at points (`truepos comp error --output`): `x_mm,y_mm,z_mm` and
/// the error `ex_um,ey_um,ez_um`, atomically; as Parquet for a `.parquet` path, else CSV. A bad path rides in the `io::Error` as an
/// `OutputError`.
pub fn write_errors(
    path: &Path,
    points: &[truepos_math::Point3],
    errors: &[truepos_math::Vector3],
) -> std::io::Result<()> {
    if truepos_io::parquet_file::is_parquet(path) {
        use truepos_io::parquet_file::{write_columns, ColumnData, Columns};
        let col = |f: &dyn Fn(usize) -> f64| ColumnData::F64((0..points.len()).map(f).collect());
        let cols = Columns {
            names: ["x_mm", "y_mm", "z_mm", "ex_um", "ey_um", "ez_um"].map(String::from).to_vec(),
            data: vec![
                col(&|i| points[i].x),
                col(&|i| points[i].y),
                col(&|i| points[i].z),
                col(&|i| errors[i].x * 1e3),
                col(&|i| errors[i].y * 1e3),
                col(&|i| errors[i].z * 1e3),
            ],
        };
        return Ok(write_columns(path, &cols)?);
    }
    let mut f = AtomicFile::create(path)?;
    {
        let mut w = CsvWriter::new(&mut f);
        w.header(&["x_mm", "y_mm", "z_mm", "ex_um", "ey_um", "ez_um"])?;
        for (p, v) in points.iter().zip(errors) {
            w.row_f64(&[p.x, p.y, p.z, v.x * 1e3, v.y * 1e3, v.z * 1e3])?;
        }
    }
    f.commit()?;
    Ok(())
}
