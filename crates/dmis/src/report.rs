//! Results of a run: the DMIS output file's lines (`FA(label)=FEAT/…`, `TA(label)=TOL/…`, in the
//! program's units) and the contract's JSON.
//!
//! Entry points: [`feat_line`], [`tol_line`], [`json`](fn@json), [`qif`] (the QIF 3 results
//! document of `--qif`, written by `truepos_qif::write_program_results`).

use crate::ast::{AngleUnit, FeatType, LengthUnit, Side};
use crate::exec::{FeatureResult, Geom, RunResult, TolResult};
use crate::model::{mm_per, rad_per, Feature};
use serde_json::{json, Value};

fn n5(v: f64) -> String {
    // Five decimals as the NIST output file; no "-0.00000".
    let s = format!("{v:.5}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// `FA(label) = FEAT/…` with the values of `g` (part frame, mm) in `length`/`angle` units,
/// continued over two lines as DMIS output files write it.
pub fn feat_line(label: &str, f: &Feature, g: &Geom, length: LengthUnit, angle: AngleUnit) -> String {
    let l = |v: f64| n5(v / mm_per(length));
    let side = |s: Option<Side>| s.map(|s| format!("{s}, ")).unwrap_or_default();
    let xyz = |p: &[f64; 3]| format!("{}, {}, {}", l(p[0]), l(p[1]), l(p[2]));
    let ijk = |v: &[f64; 3]| format!("{}, {}, {}", n5(v[0]), n5(v[1]), n5(v[2]));
    let a = |p: &truepos_math::Point3| [p.x, p.y, p.z];
    let b = |v: &truepos_math::Vector3| [v.x, v.y, v.z];
    let (head, values) = match g {
        Geom::Point { p, n } => ("POINT, CART".to_string(), format!("{}, {}", xyz(&a(p)), ijk(&b(n)))),
        Geom::Plane { p, n } => ("PLANE, CART".to_string(), format!("{}, {}", xyz(&a(p)), ijk(&b(n)))),
        Geom::Line { p, dir } => {
            ("LINE, UNBND, CART".to_string(), format!("{}, {}", xyz(&a(p)), ijk(&b(dir))))
        }
        Geom::Circle { c, n, r } => (
            format!("CIRCLE, {}CART", side(f.side)),
            format!("{}, {}, {}", xyz(&a(c)), ijk(&b(n)), l(2.0 * r)),
        ),
        Geom::Cylinder { p, axis, r } => (
            format!("CYLNDR, {}CART", side(f.side)),
            format!("{}, {}, {}", xyz(&a(p)), ijk(&b(axis)), l(2.0 * r)),
        ),
        Geom::Sphere { c, r } => {
            (format!("SPHERE, {}CART", side(f.side)), format!("{}, {}", xyz(&a(c)), l(2.0 * r)))
        }
        Geom::Cone { apex, axis, half_angle } => (
            format!("CONE, {}CART", side(f.side)),
            format!("{}, {}, {}", xyz(&a(apex)), ijk(&b(axis)), n5(2.0 * half_angle / rad_per(angle))),
        ),
    };
    format!("{label} = FEAT/{head},  $\n  {values}")
}

/// `TA(label) = TOL/<kind>, <value>, INTOL|OUTOL` in the program's units.
pub fn tol_line(t: &TolResult, length: LengthUnit, angle: AngleUnit) -> String {
    let v = if t.angular { t.value / rad_per(angle) } else { t.value / mm_per(length) };
    format!("TA({}) = TOL/{}, {}, {}", t.label, t.kind, n5(v), if t.in_tolerance { "INTOL" } else { "OUTOL" })
}

fn arr(v: &truepos_math::Vector3) -> Value {
    json!([v.x, v.y, v.z])
}

fn feature_json(f: &FeatureResult) -> Value {
    let mut o = json!({
        "label": f.label,
        "type": f.ftype.word(),
        "actual": f.actual,
        "n_points": f.n_points,
    });
    let m = o.as_object_mut().expect("object");
    if let Some(s) = f.side {
        m.insert("side".into(), json!(s.word()));
    }
    match &f.geom {
        Geom::Point { p, n } | Geom::Plane { p, n } => {
            m.insert("point_mm".into(), arr(&p.coords));
            m.insert("normal".into(), arr(n));
        }
        Geom::Line { p, dir } => {
            m.insert("point_mm".into(), arr(&p.coords));
            m.insert("direction".into(), arr(dir));
        }
        Geom::Circle { c, n, r } => {
            m.insert("center_mm".into(), arr(&c.coords));
            m.insert("normal".into(), arr(n));
            m.insert("diameter_mm".into(), json!(2.0 * r));
        }
        Geom::Cylinder { p, axis, r } => {
            m.insert("point_mm".into(), arr(&p.coords));
            m.insert("axis".into(), arr(axis));
            m.insert("diameter_mm".into(), json!(2.0 * r));
        }
        Geom::Sphere { c, r } => {
            m.insert("center_mm".into(), arr(&c.coords));
            m.insert("diameter_mm".into(), json!(2.0 * r));
        }
        Geom::Cone { apex, axis, half_angle } => {
            m.insert("apex_mm".into(), arr(&apex.coords));
            m.insert("axis".into(), arr(axis));
            m.insert("apex_angle_deg".into(), json!(2.0 * half_angle.to_degrees()));
        }
    }
    m.insert("u_position_mm".into(), json!(f.u_position_mm));
    if matches!(f.ftype, FeatType::Circle | FeatType::Cylndr | FeatType::Sphere) {
        m.insert("u_diameter_mm".into(), json!(f.u_diameter_mm));
    }
    o
}

fn tol_json(t: &TolResult) -> Value {
    let verdict = if t.in_tolerance { "INTOL" } else { "OUTOL" };
    if t.angular {
        json!({
            "label": t.label,
            "feature": t.features.first(),
            "features": t.features,
            "kind": t.kind,
            "value_mm": null,
            "limits_mm": null,
            "value_deg": t.value.to_degrees(),
            "limits_deg": [t.limits.0.to_degrees(), t.limits.1.to_degrees()],
            "verdict": verdict,
        })
    } else {
        json!({
            "label": t.label,
            "feature": t.features.first(),
            "features": t.features,
            "kind": t.kind,
            "value_mm": t.value,
            "limits_mm": [t.limits.0, t.limits.1],
            "verdict": verdict,
        })
    }
}

/// The contract's JSON of a run.
pub fn json(program: &str, r: &RunResult, output_file: Option<&str>) -> Value {
    json!({
        "program": program,
        "machine": { "address": r.machine.address, "version": r.machine.version },
        "features": r.features.iter().map(feature_json).collect::<Vec<_>>(),
        "tolerances": r.tolerances.iter().map(tol_json).collect::<Vec<_>>(),
        "n_points": r.n_points,
        "elapsed_s": r.elapsed_s,
        "output": output_file,
        "verdict": if r.any_out_of_tolerance() { "OUTOL" } else { "INTOL" },
    })
}

/// One reported quantity of a run, as an audit trail stores it: a feature's location and size
/// (with U, k = 2, where the fit gives one) or a tolerance's actual value, limits and verdict.
/// Lengths in mm, angles in rad.
#[derive(Debug, Clone, PartialEq)]
pub struct Quantity {
    /// `feature` or `tolerance`.
    pub kind: &'static str,
    /// The feature's or tolerance's label name.
    pub label: String,
    /// A feature's type (`CIRCLE`, …) or the feature(s) a tolerance applies to.
    pub feature: String,
    /// `x`, `y`, `z`, `diameter`, `apex_angle`, or the tolerance kind.
    pub quantity: String,
    /// The value, in `unit`.
    pub value: f64,
    /// `mm` or `rad`.
    pub unit: &'static str,
    /// Expanded uncertainty (k = 2) of the value, in `unit`, where known.
    pub expanded_uncertainty: Option<f64>,
    /// The tolerance limits, in `unit`, for a tolerance.
    pub limits: Option<(f64, f64)>,
    /// `INTOL` or `OUTOL`, for a tolerance.
    pub verdict: Option<&'static str>,
}

/// Every quantity of a run in report order: each actual feature's location (x, y, z) and size,
/// then each tolerance, with the expanded uncertainty (k = 2) `u` gives (task-specific or the
/// fits' own; none where it gives none).
pub fn quantities(r: &RunResult, u: &crate::uncertainty::Uncertainty) -> Vec<Quantity> {
    let k = truepos_math::stats::COVERAGE_FACTOR;
    let finite = |v: f64| v.is_finite().then_some(v);
    let mut out = Vec::new();
    for (f, fu) in r.features.iter().zip(&u.features).filter(|(f, _)| f.actual) {
        let q = |quantity: &str, value: f64, unit: &'static str, u: Option<f64>| Quantity {
            kind: "feature",
            label: f.label.clone(),
            feature: f.ftype.word().to_string(),
            quantity: quantity.to_string(),
            value,
            unit,
            expanded_uncertainty: u.map(|u| k * u),
            limits: None,
            verdict: None,
        };
        let p = f.geom.position();
        let up = fu.as_ref().map(|u| u.position_mm);
        for (i, (name, v)) in [("x", p.x), ("y", p.y), ("z", p.z)].into_iter().enumerate() {
            out.push(q(name, v, "mm", up.and_then(|u| finite(u[i]))));
        }
        match f.geom {
            Geom::Circle { r, .. } | Geom::Cylinder { r, .. } | Geom::Sphere { r, .. } => out.push(q(
                "diameter",
                2.0 * r,
                "mm",
                fu.as_ref().and_then(|u| u.diameter_mm).and_then(finite),
            )),
            Geom::Cone { half_angle, .. } => out.push(q(
                "apex_angle",
                2.0 * half_angle,
                "rad",
                fu.as_ref().and_then(|u| u.angle_rad).and_then(finite),
            )),
            _ => {}
        }
    }
    for (t, tu) in r.tolerances.iter().zip(&u.tolerances) {
        out.push(Quantity {
            kind: "tolerance",
            label: t.label.clone(),
            feature: t.features.join(","),
            quantity: t.kind.to_string(),
            value: t.value,
            unit: if t.angular { "rad" } else { "mm" },
            expanded_uncertainty: tu.and_then(finite).map(|u| k * u),
            limits: Some(t.limits),
            verdict: Some(if t.in_tolerance { "INTOL" } else { "OUTOL" }),
        });
    }
    out
}

fn finite3(v: &truepos_math::Vector3) -> Option<[f64; 3]> {
    v.iter().all(|x| x.is_finite()).then(|| [v.x, v.y, v.z])
}

/// The QIF 3 results of a run (`truepos dmis run --qif`): every actual feature of the output
/// (in the coordinate system active at its `OUTPUT`, as in the output file) with its values,
/// the standard uncertainties (k = 1) `u` gives and its number of points, and every evaluated
/// tolerance as a characteristic referring to the feature results of its `OUTPUT` and, for
/// POS, PERP and PARLEL, to its datums. Dimensional characteristics (DIAM, RAD, DISTB, ANGLB)
/// carry their nominal and deviations, and the actual size, distance or angle as the value
/// (nominal + the deviation DMIS reports for DIAM and RAD). Angles in degrees.
pub fn qif(
    program: &str,
    r: &RunResult,
    u: &crate::uncertainty::Uncertainty,
    application: &str,
) -> truepos_qif::ProgramResults {
    use truepos_qif::{
        CharacteristicKind as K, ResultCharacteristic, ResultFeature, ResultKind, Status, Tolerance,
        Value as V,
    };
    let mut index = vec![None; r.features.len()];
    let mut features = Vec::new();
    for (k, (f, fu)) in r.features.iter().zip(&u.features).enumerate().filter(|(_, (f, _))| f.actual) {
        let fu = fu.as_ref();
        let fin = |v: Option<f64>| v.filter(|x| x.is_finite());
        let pos_u = fu.and_then(|u| finite3(&u.position_mm));
        let dir_u = fu.and_then(|u| u.direction.as_ref()).and_then(finite3);
        let a = |p: &truepos_math::Point3| [p.x, p.y, p.z];
        let b = |v: &truepos_math::Vector3| [v.x, v.y, v.z];
        let kind = match f.geom {
            Geom::Point { .. } => ResultKind::Point,
            Geom::Plane { .. } => ResultKind::Plane,
            Geom::Line { .. } => ResultKind::Line,
            Geom::Circle { .. } => ResultKind::Circle,
            Geom::Cylinder { .. } => ResultKind::Cylinder,
            Geom::Sphere { .. } => ResultKind::Sphere,
            Geom::Cone { .. } => ResultKind::Cone,
        };
        let diameter = f.geom.radius().map(|r| V::new(2.0 * r, fin(fu.and_then(|u| u.diameter_mm))));
        let full_angle_deg = match f.geom {
            Geom::Cone { half_angle, .. } => Some(V::new(
                2.0 * half_angle.to_degrees(),
                fin(fu.and_then(|u| u.angle_rad)).map(f64::to_degrees),
            )),
            _ => None,
        };
        index[k] = Some(features.len());
        features.push(ResultFeature {
            label: f.label.clone(),
            kind,
            location: V::new(a(&f.geom.position()), pos_u),
            direction: f.geom.direction().map(|d| V::new(b(&d), dir_u)),
            diameter,
            full_angle_deg,
            fitted: f.n_points > 0,
            n_points: f.n_points,
        });
    }
    let characteristics = r
        .tolerances
        .iter()
        .zip(&u.tolerances)
        .map(|(t, tu)| {
            let tu = tu.filter(|x| x.is_finite());
            let first_is_plane =
                t.feature_results.first().is_some_and(|k| matches!(r.features[*k].geom, Geom::Plane { .. }));
            let zone = Tolerance::Zone(t.limits.1);
            let nominal = t.nominal.unwrap_or(0.0);
            let deg = |v: f64| v.to_degrees();
            let (kind, tolerance, value, unc) = match t.kind {
                "FLAT" => (K::Flatness, zone, t.value, tu),
                "STRGHT" => (K::Straightness, zone, t.value, tu),
                "CIRLTY" => (K::Circularity, zone, t.value, tu),
                "CYLCTY" => (K::Cylindricity, zone, t.value, tu),
                "POS" => (K::Position { three_d: t.three_d }, zone, t.value, tu),
                "PERP" => (K::Perpendicularity { axis: !first_is_plane }, zone, t.value, tu),
                "PARLEL" => (K::Parallelism { axis: !first_is_plane }, zone, t.value, tu),
                "DIAM" | "RAD" => (
                    if t.kind == "DIAM" { K::Diameter } else { K::Radius },
                    Tolerance::Limits { nominal, lower: t.limits.0, upper: t.limits.1 },
                    nominal + t.value,
                    tu,
                ),
                "ANGLB" => (
                    K::AngleBetween,
                    Tolerance::Limits {
                        nominal: deg(nominal),
                        lower: deg(t.limits.0 - nominal),
                        upper: deg(t.limits.1 - nominal),
                    },
                    deg(t.value),
                    tu.map(deg),
                ),
                // DISTB (the last kind of `model::TolKind`).
                _ => (
                    K::DistanceBetween,
                    Tolerance::Limits { nominal, lower: t.limits.0 - nominal, upper: t.limits.1 - nominal },
                    t.value,
                    tu,
                ),
            };
            // DISTB measured along one direction: the axis it names, else a plane's normal (as
            // `evaluate` measures it); otherwise point to point in 3D.
            let plane_normal = t.feature_results.iter().find_map(|k| match r.features[*k].geom {
                Geom::Plane { n, .. } => Some([n.x, n.y, n.z]),
                _ => None,
            });
            let analysis_vector = (t.kind == "DISTB")
                .then(|| {
                    t.distb_axis
                        .map(|k| std::array::from_fn(|i| f64::from(u8::from(i == k))))
                        .or(plane_normal)
                })
                .flatten();
            ResultCharacteristic {
                analysis_vector,
                label: t.label.clone(),
                kind,
                tolerance,
                value: V::new(value, unc),
                datums: t.datums.clone(),
                features: t.feature_results.iter().filter_map(|k| index[*k]).collect(),
                status: if t.in_tolerance { Status::Pass } else { Status::Fail },
            }
        })
        .collect();
    truepos_qif::ProgramResults {
        program: program.to_string(),
        application: application.to_string(),
        features,
        characteristics,
    }
}
