//! The part file of `truepos ippdme serve --part PART.toml` and the machine file's `[ippdme]`
//! section: typed, unknown keys refused, errors naming file, line and key.
//!
//! Part file (machine frame, mm): the material is the union of
//! `[[sphere]] center_mm, diameter_mm`, `[[plane]] point_mm, normal` (the half-space below the
//! normal) and `[[cylinder]] point_mm, axis, diameter_mm, side = "outside"` (a pin), minus the
//! `[[cylinder]] ... side = "inside"` (bores, which remove material: a bore in a plate is a
//! `[[plane]]` and an inside `[[cylinder]]`); each with an optional `id`. Cylinders are infinite.
//!
//! Machine file: `[ippdme] volume_min_mm, volume_max_mm` (default ±1000 mm),
//! `[[ippdme.tool]] name, tip_diameter_mm`. Other top-level tables are left to other readers.
//!
//! Entry points: [`Part::from_toml`], [`Part::load`], [`MachineConfig::from_toml`],
//! [`MachineConfig::load`].

use serde::Deserialize;
use std::path::Path;
use thiserror::Error;
use truepos_math::{Point3, Vector3};

/// A bad part or machine file.
#[derive(Debug, Error)]
pub enum PartError {
    #[error("{file}: cannot read: {source}")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}:{line}:{column}: {message}")]
    Syntax { file: String, line: usize, column: usize, message: String },
    #[error("{file}: {key}: {message}")]
    Value { file: String, key: String, message: String },
}

impl PartError {
    /// The 1-based line of the error, when known.
    pub fn line(&self) -> Option<usize> {
        match self {
            PartError::Syntax { line, .. } => Some(*line),
            _ => None,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPart {
    #[serde(default)]
    sphere: Vec<RawSphere>,
    #[serde(default)]
    plane: Vec<RawPlane>,
    #[serde(default)]
    cylinder: Vec<RawCylinder>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSphere {
    id: Option<String>,
    center_mm: [f64; 3],
    diameter_mm: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlane {
    id: Option<String>,
    point_mm: [f64; 3],
    normal: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCylinder {
    id: Option<String>,
    point_mm: [f64; 3],
    axis: [f64; 3],
    diameter_mm: f64,
    side: CylinderSide,
}

/// A cylinder is a pin (material inside) or a bore (material outside).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CylinderSide {
    Outside,
    Inside,
}

/// One solid of the part.
#[derive(Debug, Clone, PartialEq)]
pub enum Solid {
    Sphere {
        center: Point3,
        radius: f64,
    },
    /// Material where `(p − point)·normal ≤ 0`; `normal` is a unit vector.
    HalfSpace {
        point: Point3,
        normal: Vector3,
    },
    /// Infinite cylinder; `axis` is a unit vector. `Outside`: a pin (material inside the
    /// cylinder); `Inside`: a bore (removes the material inside it from the other solids).
    Cylinder {
        point: Point3,
        axis: Vector3,
        radius: f64,
        side: CylinderSide,
    },
}

/// The part: the union of its spheres, half-spaces and pins, minus its bores.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Part {
    pub solids: Vec<(Option<String>, Solid)>,
}

fn syntax(file: &str, text: &str, e: &toml::de::Error) -> PartError {
    let (line, column) = match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map(|k| k + 1).unwrap_or(0) + 1;
            (line, column)
        }
        None => (0, 0),
    };
    PartError::Syntax { file: file.to_string(), line, column, message: e.message().to_string() }
}

fn finite3(file: &str, key: &str, v: [f64; 3]) -> Result<Vector3, PartError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vector3::new(v[0], v[1], v[2]))
    } else {
        Err(PartError::Value { file: file.into(), key: key.into(), message: "not a finite number".into() })
    }
}

fn unit(file: &str, key: &str, v: [f64; 3]) -> Result<Vector3, PartError> {
    let v = finite3(file, key, v)?;
    let n = v.norm();
    if n < 1e-12 {
        return Err(PartError::Value {
            file: file.into(),
            key: key.into(),
            message: "zero-length vector".into(),
        });
    }
    Ok(v / n)
}

fn positive(file: &str, key: &str, v: f64) -> Result<f64, PartError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(PartError::Value {
            file: file.into(),
            key: key.into(),
            message: format!("must be a positive number, got {v}"),
        })
    }
}

impl Part {
    /// Parse a part file's text; `file` names it in errors.
    pub fn from_toml(file: &str, text: &str) -> Result<Part, PartError> {
        let raw: RawPart = toml::from_str(text).map_err(|e| syntax(file, text, &e))?;
        let mut solids = Vec::new();
        for (k, s) in raw.sphere.into_iter().enumerate() {
            let key = format!("sphere[{k}]");
            let c = finite3(file, &format!("{key}.center_mm"), s.center_mm)?;
            let d = positive(file, &format!("{key}.diameter_mm"), s.diameter_mm)?;
            solids.push((s.id, Solid::Sphere { center: Point3::from(c), radius: d / 2.0 }));
        }
        for (k, s) in raw.plane.into_iter().enumerate() {
            let key = format!("plane[{k}]");
            let p = finite3(file, &format!("{key}.point_mm"), s.point_mm)?;
            let n = unit(file, &format!("{key}.normal"), s.normal)?;
            solids.push((s.id, Solid::HalfSpace { point: Point3::from(p), normal: n }));
        }
        for (k, s) in raw.cylinder.into_iter().enumerate() {
            let key = format!("cylinder[{k}]");
            let p = finite3(file, &format!("{key}.point_mm"), s.point_mm)?;
            let a = unit(file, &format!("{key}.axis"), s.axis)?;
            let d = positive(file, &format!("{key}.diameter_mm"), s.diameter_mm)?;
            solids.push((
                s.id,
                Solid::Cylinder { point: Point3::from(p), axis: a, radius: d / 2.0, side: s.side },
            ));
        }
        Ok(Part { solids })
    }

    /// Read and parse a part file.
    pub fn load(path: &Path) -> Result<Part, PartError> {
        let file = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| PartError::Read { file: file.clone(), source })?;
        Part::from_toml(&file, &text)
    }
}

/// An extra tool of the machine file.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolConfig {
    pub name: String,
    pub tip_diameter_mm: f64,
}

/// The `[ippdme]` section of the machine file.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineConfig {
    pub volume_min_mm: Point3,
    pub volume_max_mm: Point3,
    pub tools: Vec<ToolConfig>,
}

impl Default for MachineConfig {
    fn default() -> Self {
        MachineConfig {
            volume_min_mm: Point3::new(-1000.0, -1000.0, -1000.0),
            volume_max_mm: Point3::new(1000.0, 1000.0, 1000.0),
            tools: Vec::new(),
        }
    }
}

#[derive(Debug, Deserialize)]
struct RawMachine {
    ippdme: Option<RawIppdme>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIppdme {
    volume_min_mm: Option<[f64; 3]>,
    volume_max_mm: Option<[f64; 3]>,
    #[serde(default)]
    tool: Vec<RawTool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTool {
    name: String,
    tip_diameter_mm: f64,
}

/// Names the server reserves.
pub const RESERVED_TOOLS: [&str; 5] = ["RefTool", "NoTool", "Probe1", "BaseTool", "UnDefTool"];

impl MachineConfig {
    pub fn from_toml(file: &str, text: &str) -> Result<MachineConfig, PartError> {
        let raw: RawMachine = toml::from_str(text).map_err(|e| syntax(file, text, &e))?;
        let mut cfg = MachineConfig::default();
        let Some(ipp) = raw.ippdme else { return Ok(cfg) };
        if let Some(v) = ipp.volume_min_mm {
            cfg.volume_min_mm = Point3::from(finite3(file, "ippdme.volume_min_mm", v)?);
        }
        if let Some(v) = ipp.volume_max_mm {
            cfg.volume_max_mm = Point3::from(finite3(file, "ippdme.volume_max_mm", v)?);
        }
        for k in 0..3 {
            if cfg.volume_min_mm[k] >= cfg.volume_max_mm[k] {
                return Err(PartError::Value {
                    file: file.into(),
                    key: "ippdme.volume_max_mm".into(),
                    message: "every component must exceed volume_min_mm's".into(),
                });
            }
        }
        for (k, t) in ipp.tool.into_iter().enumerate() {
            let key = format!("ippdme.tool[{k}]");
            if t.name.is_empty() || !t.name.bytes().all(|b| b.is_ascii_graphic() && b != b'"') {
                return Err(PartError::Value {
                    file: file.into(),
                    key: format!("{key}.name"),
                    message: "must be printable ASCII without quotes or blanks".into(),
                });
            }
            if RESERVED_TOOLS.contains(&t.name.as_str()) || cfg.tools.iter().any(|x| x.name == t.name) {
                return Err(PartError::Value {
                    file: file.into(),
                    key: format!("{key}.name"),
                    message: format!("{} is reserved or defined twice", t.name),
                });
            }
            let d = positive(file, &format!("{key}.tip_diameter_mm"), t.tip_diameter_mm)?;
            cfg.tools.push(ToolConfig { name: t.name, tip_diameter_mm: d });
        }
        Ok(cfg)
    }

    pub fn load(path: &Path) -> Result<MachineConfig, PartError> {
        let file = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| PartError::Read { file: file.clone(), source })?;
        MachineConfig::from_toml(&file, &text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_part() {
        let p = Part::from_toml(
            "p.toml",
            "[[sphere]]\nid = \"ref\"\ncenter_mm = [0, 0, 10]\ndiameter_mm = 25\n\n[[plane]]\npoint_mm = [0,0,0]\nnormal = [0,0,2]\n\n[[cylinder]]\npoint_mm=[50,0,0]\naxis=[0,0,1]\ndiameter_mm=10\nside=\"inside\"\n",
        )
        .unwrap();
        assert_eq!(p.solids.len(), 3);
        assert_eq!(p.solids[0].1, Solid::Sphere { center: Point3::new(0.0, 0.0, 10.0), radius: 12.5 });
        assert!(matches!(p.solids[1].1, Solid::HalfSpace { normal, .. } if normal == Vector3::z()));
    }

    #[test]
    fn errors_name_file_line_and_key() {
        let e =
            Part::from_toml("p.toml", "[[sphere]]\ncenter_mm = [0, 0, 10]\ndiameter_mm = 25\ncolour = 3\n")
                .unwrap_err();
        let s = e.to_string();
        assert!(s.starts_with("p.toml:4:"), "{s}");
        assert!(s.contains("colour"), "{s}");
        let e =
            Part::from_toml("p.toml", "[[sphere]]\ncenter_mm = [0, 0, 10]\ndiameter_mm = -2\n").unwrap_err();
        assert!(e.to_string().contains("sphere[0].diameter_mm"), "{e}");
        let e =
            MachineConfig::from_toml("m.toml", "[ippdme]\nvolume_min_mm=[0,0,0]\nvolume_max_mm=[1,1,-1]\n")
                .unwrap_err();
        assert!(e.to_string().contains("volume_max_mm"), "{e}");
        let m = MachineConfig::from_toml(
            "m.toml",
            "[machine]\nx=1\n[[ippdme.tool]]\nname=\"Star1\"\ntip_diameter_mm=2\n",
        )
        .unwrap();
        assert_eq!(m.tools[0].name, "Star1");
    }
}
