//! The DMIS side of a run's task-specific uncertainty (ISO/TS 15530-4; the simulation itself is
//! `truepos_cell::uncertainty::dmis_uncertainty`):
//!
//! - [`Replay`]: a machine on which every probing touches the perfect features a run found (each
//!   contact on the plane through the point of the fitted feature, normal to the probing
//!   direction, on the requested probing line). The plan run again on it gives the perfect
//!   result; with a simulated machine's errors added to its contacts, that machine's result.
//! - [`parameters`]: a run's results as one vector — every actual output feature's values
//!   (position, direction, diameter or cone angle) and every tolerance's value, in output order;
//!   [`fit_scatter`]: the fits' own scatter in the same layout.
//! - [`Uncertainty`]: standard uncertainties of that vector put back per feature and tolerance
//!   ([`Uncertainty::from_parameters`]), or the fits' own scatter without a machine model
//!   ([`Uncertainty::fit_residuals`]); [`Uncertainty::add_to_json`] writes them beside the values
//!   of [`crate::report::json`].

use crate::exec::{FeatureResult, Geom, ProbeRecord, RunResult};
use serde_json::{json, Value};
use truepos_device::{DeviceError, DeviceInfo, ProbeHit, ProbeRequest, ProbingMachine, ToolInfo};
use truepos_math::{Point3, Vector3};

const ADDRESS: &str = "replay";

/// A machine that touches the perfect features of a run (see the module docs).
#[derive(Debug, Clone)]
pub struct Replay {
    probes: Vec<ProbeRecord>,
    tools: Vec<ToolInfo>,
    next: usize,
    at: Point3,
}

impl Replay {
    /// A machine replaying the probings of run `r` on its perfect features.
    pub fn new(r: &RunResult) -> Replay {
        Replay { probes: r.probes.clone(), tools: r.tools.clone(), next: 0, at: Point3::origin() }
    }
}

impl ProbingMachine for Replay {
    fn info(&self) -> DeviceInfo {
        DeviceInfo { address: ADDRESS.into(), version: "the perfect features of a run".into() }
    }
    fn position(&mut self) -> Result<Point3, DeviceError> {
        Ok(self.at)
    }
    fn move_to(&mut self, target_mm: Point3) -> Result<(), DeviceError> {
        self.at = target_mm;
        Ok(())
    }
    fn probe(&mut self, req: &ProbeRequest) -> Result<ProbeHit, DeviceError> {
        let Some(rec) = self.probes.get(self.next) else {
            return Err(DeviceError::Rejected {
                address: ADDRESS.into(),
                what: format!("probing at {:?}", req.nominal_mm),
                message: "more probings than the run had".into(),
            });
        };
        self.next += 1;
        let a = req.approach.try_normalize(1e-12).unwrap_or(rec.approach);
        let q = req.nominal_mm;
        let s = q + a * (rec.perfect_mm - q).dot(&a);
        let tip = s + a * req.tip_radius_mm;
        self.at = tip + a * req.retract_mm;
        Ok(ProbeHit { tip_center_mm: tip, normal: Some(a) })
    }
    fn abort(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }
    fn tool_names(&mut self) -> Result<Vec<String>, DeviceError> {
        Ok(self.tools.iter().map(|t| t.name.clone()).collect())
    }
    fn select_tool(&mut self, name: &str) -> Result<ToolInfo, DeviceError> {
        let r = self.tools.iter().find(|t| t.name == name).map_or(0.0, |t| t.tip_radius_mm);
        Ok(ToolInfo { name: name.to_string(), tip_radius_mm: r })
    }
}

/// Which measured values a feature has beyond its position: (a direction, a diameter, a cone
/// angle). A point's and a circle's direction is their nominal's, not measured: none.
fn layout(g: &Geom) -> (bool, bool, bool) {
    match g {
        Geom::Point { .. } => (false, false, false),
        Geom::Plane { .. } | Geom::Line { .. } => (true, false, false),
        Geom::Circle { .. } => (false, true, false),
        Geom::Cylinder { .. } => (true, true, false),
        Geom::Sphere { .. } => (false, true, false),
        Geom::Cone { .. } => (true, false, true),
    }
}

/// A run's results as one vector (mm, unit directions, cone angle in rad, tolerance values in
/// mm or rad): every actual output feature, then every tolerance (the vector of a value that is
/// a vector's length, [`crate::exec::TolResult::vector`]).
pub fn parameters(r: &RunResult) -> Vec<f64> {
    let mut v = Vec::new();
    for f in r.features.iter().filter(|f| f.actual) {
        let g = &f.geom;
        v.extend(g.position().iter());
        let (dir, dia, ang) = layout(g);
        if dir {
            v.extend(g.direction().unwrap_or_else(Vector3::zeros).iter());
        }
        if dia {
            v.push(2.0 * g.radius().unwrap_or(0.0));
        }
        if ang {
            if let Geom::Cone { half_angle, .. } = g {
                v.push(2.0 * half_angle);
            }
        }
    }
    for t in &r.tolerances {
        match &t.vector {
            Some(w) => v.extend(w.iter()),
            None => v.push(t.value),
        }
    }
    v
}

/// The fits' own scatter in the layout of [`parameters`]: each actual feature's position
/// uncertainty for its three coordinates and its diameter's for the diameter (mm; 0 where the
/// fit gives none: constructed features, directions, cone angles and tolerances). The
/// task-specific uncertainty compares it with the simulated machines' to find scatter the model
/// does not contain (form error of the part, effects outside the model).
pub fn fit_scatter(r: &RunResult) -> Vec<f64> {
    let mut v = Vec::new();
    for f in r.features.iter().filter(|f| f.actual) {
        let pos = f.u_position_mm.filter(|u| u.is_finite()).unwrap_or(0.0);
        v.extend([pos; 3]);
        let (dir, dia, ang) = layout(&f.geom);
        if dir {
            v.extend([0.0; 3]);
        }
        if dia {
            v.push(f.u_diameter_mm.filter(|u| u.is_finite()).unwrap_or(0.0));
        }
        if ang {
            v.push(0.0);
        }
    }
    for t in &r.tolerances {
        v.extend(std::iter::repeat_n(0.0, if t.vector.is_some() { 3 } else { 1 }));
    }
    v
}

/// Standard uncertainties of one output feature (k = 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureUncertainty {
    /// Of each coordinate of the position (mm).
    pub position_mm: Vector3,
    /// Of each component of the direction (unit vector), where known.
    pub direction: Option<Vector3>,
    /// Of the diameter (mm).
    pub diameter_mm: Option<f64>,
    /// Of the cone's apex angle (rad).
    pub angle_rad: Option<f64>,
}

/// Standard uncertainties of a run's results, per output feature (`None` for nominal outputs)
/// and per tolerance (`None` where not known).
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// Per feature of the plan, in order.
    pub features: Vec<Option<FeatureUncertainty>>,
    /// Per tolerance of the plan, in order: the standard uncertainty of its value (mm or rad).
    pub tolerances: Vec<Option<f64>>,
}

impl Uncertainty {
    /// From the standard uncertainties of [`parameters`]`(r)` (same layout).
    pub fn from_parameters(r: &RunResult, u: &[f64]) -> Uncertainty {
        let mut it = u.iter().copied();
        let mut next = || it.next().unwrap_or(f64::NAN);
        let mut features = Vec::new();
        for f in &r.features {
            if !f.actual {
                features.push(None);
                continue;
            }
            let (dir, dia, ang) = layout(&f.geom);
            let position_mm = Vector3::new(next(), next(), next());
            let direction = dir.then(|| Vector3::new(next(), next(), next()));
            let diameter_mm = dia.then(&mut next);
            let angle_rad = ang.then(&mut next);
            features.push(Some(FeatureUncertainty { position_mm, direction, diameter_mm, angle_rad }));
        }
        // A length's uncertainty is its vector's (the root sum of squares of the components'):
        // right where the truth is zero, conservative elsewhere.
        let tolerances = r
            .tolerances
            .iter()
            .map(|t| match t.vector {
                Some(_) => Some(Vector3::new(next(), next(), next()).norm()),
                None => Some(next()),
            })
            .collect();
        Uncertainty { features, tolerances }
    }

    /// Without a machine model: each fit's own scatter (the position's as the same number for
    /// every coordinate), nothing for directions and tolerances.
    pub fn fit_residuals(r: &RunResult) -> Uncertainty {
        let features = r
            .features
            .iter()
            .map(|f: &FeatureResult| {
                f.actual.then(|| FeatureUncertainty {
                    position_mm: Vector3::repeat(f.u_position_mm.unwrap_or(f64::NAN)),
                    direction: None,
                    diameter_mm: f.u_diameter_mm,
                    angle_rad: None,
                })
            })
            .collect();
        Uncertainty { features, tolerances: vec![None; r.tolerances.len()] }
    }

    /// Add `uncertainty` and `expanded_uncertainty` (× `k`) to each feature and tolerance of
    /// `j` (the JSON of [`crate::report::json`] for `r`), keyed like the values they belong to.
    pub fn add_to_json(&self, r: &RunResult, j: &mut Value, k: f64) {
        let num = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
        let arr = |v: &Vector3, s: f64| json!([num(v.x * s), num(v.y * s), num(v.z * s)]);
        if let Some(fs) = j.get_mut("features").and_then(Value::as_array_mut) {
            for ((fj, f), u) in fs.iter_mut().zip(&r.features).zip(&self.features) {
                let Some(u) = u else { continue };
                let (pos_key, dir_key) = match f.geom {
                    Geom::Point { .. } | Geom::Plane { .. } => ("point_mm", "normal"),
                    Geom::Line { .. } => ("point_mm", "direction"),
                    Geom::Circle { .. } => ("center_mm", "normal"),
                    Geom::Cylinder { .. } => ("point_mm", "axis"),
                    Geom::Sphere { .. } => ("center_mm", "normal"),
                    Geom::Cone { .. } => ("apex_mm", "axis"),
                };
                let one = |s: f64| {
                    let mut m = serde_json::Map::new();
                    m.insert(pos_key.into(), arr(&u.position_mm, s));
                    if let Some(d) = &u.direction {
                        m.insert(dir_key.into(), arr(d, s));
                    }
                    if let Some(d) = u.diameter_mm {
                        m.insert("diameter_mm".into(), num(d * s));
                    }
                    if let Some(a) = u.angle_rad {
                        m.insert("apex_angle_deg".into(), num(a.to_degrees() * s));
                    }
                    Value::Object(m)
                };
                fj["uncertainty"] = one(1.0);
                fj["expanded_uncertainty"] = one(k);
            }
        }
        if let Some(ts) = j.get_mut("tolerances").and_then(Value::as_array_mut) {
            for ((tj, t), u) in ts.iter_mut().zip(&r.tolerances).zip(&self.tolerances) {
                let (key_u, key_big) = if t.angular {
                    ("uncertainty_deg", "expanded_uncertainty_deg")
                } else {
                    ("uncertainty_mm", "expanded_uncertainty_mm")
                };
                let conv = |v: f64| if t.angular { v.to_degrees() } else { v };
                tj[key_u] = u.map_or(Value::Null, |v| num(conv(v)));
                tj[key_big] = u.map_or(Value::Null, |v| num(conv(k * v)));
            }
        }
    }
}
