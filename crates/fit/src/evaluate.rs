//! One call from points to a reportable result: the fitted feature by the chosen method, its
//! form, the least-squares uncertainties with the coverage factor, and the verdicts against the
//! given tolerances. This is what `truepos fit` prints and exports.
//!
//! Entry point: [`evaluate`] with a [`Kind`], a [`Method`] and a [`Spec`]; the result is an
//! [`Evaluation`]. Conventions (the interface contract, "Fitting"):
//! - `form` is the largest minus the smallest orthogonal residual about the reported feature
//!   (a line: the diameter of the cylinder about it holding every point, 2 × the largest
//!   distance; a 3D circle: in-plane radial residuals of the points projected into the
//!   least-squares plane). For the minimum zone it is the smallest possible width.
//! - Minimum-zone radius: the mean of the two zone radii; `mic`/`mcc`: the inscribed or
//!   circumscribed radius. `mic`/`mcc` apply to circle, sphere and cylinder; the minimum zone to
//!   line, plane, circle, sphere and cylinder; a cone has the least-squares fit only.
//! - Uncertainties (least-squares fits only): standard uncertainties (k = 1) from
//!   `σ̂²(JᵀJ)⁻¹`, `σ̂² = SSR/(n − p)`, one per vector component; expanded with
//!   [`COVERAGE_FACTOR`]. Guarded size decisions use the least-squares expanded uncertainty of
//!   the diameter (2 U(radius)) for every method.

use crate::minzone::{self, Criterion};
use crate::verdict::{self, DecisionRule, SizeDecision, SizeTolerance, Verdict};
use crate::FitError;
use truepos_math::{Matrix3, Point3, Vector3};

pub use truepos_math::stats::COVERAGE_FACTOR;

/// The geometric element to fit: the one definition of the element kinds, used by the fits,
/// the QIF export (`truepos_qif::FeatureKind`), the cell and, as the `<KIND>` argument of
/// `truepos fit`, the command line (with the `clap` feature). The command line lists the kinds
/// without a description each, so their `clap` help is empty.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Kind {
    /// A straight line in space.
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Line,
    /// A plane.
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Plane,
    /// A circle in space (in its least-squares plane).
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Circle,
    /// A sphere.
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Sphere,
    /// A circular cylinder.
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Cylinder,
    /// A circular cone.
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Cone,
}

impl Kind {
    /// The lower-case name, as the CLI and the JSON output spell it (`line`, `plane`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Kind::Line => "line",
            Kind::Plane => "plane",
            Kind::Circle => "circle",
            Kind::Sphere => "sphere",
            Kind::Cylinder => "cylinder",
            Kind::Cone => "cone",
        }
    }
    /// Circle, sphere and cylinder have a size (diameter).
    pub fn has_size(self) -> bool {
        matches!(self, Kind::Circle | Kind::Sphere | Kind::Cylinder)
    }
}

/// The association criterion that defines the fitted element (`truepos fit --method`; the
/// variants' documentation is the command line's help for each value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Method {
    /// Least squares (Gaussian), with uncertainties.
    #[cfg_attr(feature = "clap", value(name = "ls"))]
    LeastSquares,
    /// Minimum zone (Chebyshev): line, plane, circle, sphere, cylinder.
    MinimumZone,
    /// Maximum inscribed: circle, sphere, cylinder.
    #[cfg_attr(feature = "clap", value(name = "mic"))]
    MaximumInscribed,
    /// Minimum circumscribed: circle, sphere, cylinder.
    #[cfg_attr(feature = "clap", value(name = "mcc"))]
    MinimumCircumscribed,
}

impl Method {
    /// The CLI's name of the method (`ls`, `minimum-zone`, `mic`, `mcc`).
    pub fn name(self) -> &'static str {
        match self {
            Method::LeastSquares => "ls",
            Method::MinimumZone => "minimum-zone",
            Method::MaximumInscribed => "mic",
            Method::MinimumCircumscribed => "mcc",
        }
    }
}

/// Why an evaluation was not started: the request itself is inconsistent (a usage error).
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum SpecError {
    /// The method does not exist for the kind (method name, kind name, reason).
    #[error("--method {method} does not apply to a {kind} ({why})")]
    MethodNotForKind {
        /// The method's name.
        method: &'static str,
        /// The kind's name.
        kind: &'static str,
        /// Why the method does not apply.
        why: &'static str,
    },
    /// A size tolerance given for a kind without a diameter (the kind's name).
    #[error("a size tolerance applies to a circle, sphere or cylinder, not to a {0}")]
    SizeNotForKind(&'static str),
}

/// Tolerances and the decision rule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spec {
    /// Size (diameter) tolerance, for circles, spheres and cylinders.
    pub size: Option<SizeTolerance>,
    /// Form tolerance (zone width), mm.
    pub form_tolerance: Option<f64>,
    /// Decision rule for the size verdict.
    pub rule: DecisionRule,
}

impl Default for Spec {
    fn default() -> Self {
        Spec { size: None, form_tolerance: None, rule: DecisionRule::Simple }
    }
}

/// Check that `method` and `spec` apply to `kind` (before any work).
pub fn check(kind: Kind, method: Method, spec: &Spec) -> Result<(), SpecError> {
    let bad = |why| Err(SpecError::MethodNotForKind { method: method.name(), kind: kind.name(), why });
    match (kind, method) {
        (Kind::Cone, Method::LeastSquares) => {}
        (Kind::Cone, _) => return bad("a cone has the least-squares fit only"),
        (Kind::Line | Kind::Plane, Method::MaximumInscribed | Method::MinimumCircumscribed) => {
            return bad("inscribed and circumscribed elements exist for circles, spheres and cylinders")
        }
        _ => {}
    }
    if spec.size.is_some() && !kind.has_size() {
        return Err(SpecError::SizeNotForKind(kind.name()));
    }
    Ok(())
}

/// Standard uncertainties (k = 1) of the reported parameters, same shapes.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Uncertainty {
    /// Of the line's point, mm.
    pub point: Option<Vector3>,
    /// Of the centre (circle, sphere), mm.
    pub center: Option<Vector3>,
    /// Of the cone's apex, mm.
    pub apex: Option<Vector3>,
    /// Of the line's unit direction components (dimensionless).
    pub direction: Option<Vector3>,
    /// Of the plane's or circle's unit normal components (dimensionless).
    pub normal: Option<Vector3>,
    /// Of the cylinder's or cone's unit axis components (dimensionless).
    pub axis: Option<Vector3>,
    /// Of the radius, mm.
    pub radius: Option<f64>,
    /// Full apex angle, rad.
    pub apex_angle: Option<f64>,
}

impl Uncertainty {
    /// The same uncertainties multiplied by `k`.
    pub fn scaled(&self, k: f64) -> Uncertainty {
        Uncertainty {
            point: self.point.map(|v| v * k),
            center: self.center.map(|v| v * k),
            apex: self.apex.map(|v| v * k),
            direction: self.direction.map(|v| v * k),
            normal: self.normal.map(|v| v * k),
            axis: self.axis.map(|v| v * k),
            radius: self.radius.map(|v| v * k),
            apex_angle: self.apex_angle.map(|v| v * k),
        }
    }
}

/// The form decision (simple rule).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FormDecision {
    /// The form tolerance (zone width) decided against, mm.
    pub tolerance: f64,
    /// Whether the form is within the tolerance.
    pub verdict: Verdict,
}

/// A fitted feature with everything reported about it. Lengths mm, angles rad.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// The element fitted.
    pub kind: Kind,
    /// The association criterion used.
    pub method: Method,
    /// Number of points fitted.
    pub n_points: usize,
    /// Line, plane, cylinder, cone: a point on the element (nearest the centroid), mm.
    pub point: Option<Point3>,
    /// Circle, sphere: the centre, mm.
    pub center: Option<Point3>,
    /// Cone: the apex, mm.
    pub apex: Option<Point3>,
    /// Line: the unit direction.
    pub direction: Option<Vector3>,
    /// Plane, circle: the unit normal.
    pub normal: Option<Vector3>,
    /// Cylinder, cone: the unit axis.
    pub axis: Option<Vector3>,
    /// Circle, sphere, cylinder: the radius, mm.
    pub radius: Option<f64>,
    /// Full apex angle, rad.
    pub apex_angle: Option<f64>,
    /// RMS orthogonal residual, mm.
    pub rms: f64,
    /// Largest absolute orthogonal residual, mm.
    pub max_abs_residual: f64,
    /// Form about the reported element: largest minus smallest orthogonal residual, mm.
    pub form: f64,
    /// Chebyshev circles, spheres, cylinders: the zone's inner and outer radius, mm.
    pub zone_radii: Option<(f64, f64)>,
    /// Standard uncertainties: least-squares fits with more residuals than parameters only.
    pub uncertainty: Option<Uncertainty>,
    /// Least-squares expanded uncertainty of the diameter (used as the guard band).
    pub diameter_expanded_uncertainty: Option<f64>,
    /// Further named scalars of the fit (mm, rad or counts as the name says).
    pub extras: Vec<(&'static str, f64)>,
    /// The size decision, when a size tolerance was given.
    pub size_decision: Option<SizeDecision>,
    /// The form decision, when a form tolerance was given.
    pub form_decision: Option<FormDecision>,
    /// Combined verdict; `None` without tolerances.
    pub verdict: Option<Verdict>,
}

fn std3(m: &Matrix3) -> Vector3 {
    Vector3::new(m[(0, 0)].max(0.0).sqrt(), m[(1, 1)].max(0.0).sqrt(), m[(2, 2)].max(0.0).sqrt())
}

impl Evaluation {
    fn new(kind: Kind, method: Method, n: usize) -> Self {
        Evaluation {
            kind,
            method,
            n_points: n,
            point: None,
            center: None,
            apex: None,
            direction: None,
            normal: None,
            axis: None,
            radius: None,
            apex_angle: None,
            rms: 0.0,
            max_abs_residual: 0.0,
            form: 0.0,
            zone_radii: None,
            uncertainty: None,
            diameter_expanded_uncertainty: None,
            extras: Vec::new(),
            size_decision: None,
            form_decision: None,
            verdict: None,
        }
    }
    /// The expanded uncertainties (k = [`COVERAGE_FACTOR`]).
    pub fn expanded_uncertainty(&self) -> Option<Uncertainty> {
        self.uncertainty.as_ref().map(|u| u.scaled(COVERAGE_FACTOR))
    }
}

fn ls(kind: Kind, points: &[Point3]) -> Result<Evaluation, FitError> {
    let mut e = Evaluation::new(kind, Method::LeastSquares, points.len());
    let mut u = Uncertainty::default();
    match kind {
        Kind::Line => {
            let f = crate::line(points)?;
            e.point = Some(f.point);
            e.direction = Some(f.direction);
            e.rms = f.rms;
            e.max_abs_residual = f.max_abs_residual;
            e.form = f.form;
            u.point = Some(std3(&f.point_covariance));
            u.direction = Some(std3(&f.direction_covariance));
            e.extras =
                vec![("point_uncertainty_mm", f.u_point), ("direction_uncertainty_rad", f.u_direction)];
        }
        Kind::Plane => {
            let f = crate::plane(points)?;
            e.point = Some(f.point);
            e.normal = Some(f.normal);
            e.rms = f.rms;
            e.max_abs_residual = f.max_abs_residual;
            e.form = f.form;
            u.point = Some(std3(&f.point_covariance));
            u.normal = Some(std3(&f.normal_covariance));
            e.extras = vec![("offset_uncertainty_mm", f.u_offset), ("normal_uncertainty_rad", f.u_normal)];
        }
        Kind::Circle => {
            let f = crate::circle(points)?;
            e.center = Some(f.center);
            e.normal = Some(f.normal);
            e.radius = Some(f.radius);
            e.rms = f.rms;
            e.max_abs_residual = f.max_abs_residual;
            e.form = f.form;
            u.center = Some(std3(&f.center_covariance));
            u.normal = Some(std3(&f.normal_covariance));
            u.radius = Some(f.u_radius);
            e.extras = vec![
                ("radial_rms_mm", f.radial_rms),
                ("plane_rms_mm", f.plane_rms),
                ("radius_uncertainty_mm", f.u_radius),
                ("normal_uncertainty_rad", f.u_normal),
                ("iterations", f.iterations as f64),
            ];
        }
        Kind::Sphere => {
            let f = crate::sphere(points)?;
            e.center = Some(f.center);
            e.radius = Some(f.radius);
            e.rms = f.rms;
            e.max_abs_residual = f.max_abs_residual;
            e.form = f.form;
            u.center = Some(f.u_center);
            u.radius = Some(f.u_radius);
            e.extras = vec![("radius_uncertainty_mm", f.u_radius), ("iterations", f.iterations as f64)];
        }
        Kind::Cylinder => {
            let f = crate::cylinder(points)?;
            e.point = Some(f.point);
            e.axis = Some(f.axis);
            e.radius = Some(f.radius);
            e.rms = f.rms;
            e.max_abs_residual = f.max_abs_residual;
            e.form = f.form;
            u.point = Some(std3(&f.point_covariance));
            u.axis = Some(std3(&f.axis_covariance));
            u.radius = Some(f.u_radius);
            e.extras = vec![
                ("point_uncertainty_mm", f.u_point),
                ("axis_uncertainty_rad", f.u_axis),
                ("radius_uncertainty_mm", f.u_radius),
                ("iterations", f.iterations as f64),
            ];
        }
        Kind::Cone => {
            let f = crate::cone(points)?;
            e.apex = Some(f.apex);
            e.point = Some(f.point);
            e.axis = Some(f.axis);
            e.apex_angle = Some(f.apex_angle);
            e.rms = f.rms;
            e.max_abs_residual = f.max_abs_residual;
            e.form = f.form;
            u.apex = Some(std3(&f.apex_covariance));
            u.axis = Some(std3(&f.axis_covariance));
            u.apex_angle = Some(f.u_apex_angle);
            e.extras = vec![
                ("surface_distance_mm", f.surface_distance),
                ("axis_uncertainty_rad", f.u_axis),
                ("point_uncertainty_mm", f.u_point),
                ("surface_distance_uncertainty_mm", f.u_surface_distance),
                ("iterations", f.iterations as f64),
            ];
        }
    }
    // σ̂² = SSR/(n − p) needs n > p: with as many residuals as parameters the fit is exact
    // whatever the noise, and its uncertainty is not determined (not zero).
    let (n, p) = match kind {
        Kind::Line => (2 * points.len(), 4),
        Kind::Plane => (points.len(), 3),
        Kind::Circle => (points.len(), 3),
        Kind::Sphere => (points.len(), 4),
        Kind::Cylinder => (points.len(), 5),
        Kind::Cone => (points.len(), 6),
    };
    if n > p {
        e.diameter_expanded_uncertainty = u.radius.map(|r| 2.0 * COVERAGE_FACTOR * r);
        e.uncertainty = Some(u);
    }
    Ok(e)
}

fn chebyshev(kind: Kind, method: Method, points: &[Point3]) -> Result<Evaluation, FitError> {
    let crit = match method {
        Method::MinimumZone => Criterion::MinimumZone,
        Method::MaximumInscribed => Criterion::MaximumInscribed,
        _ => Criterion::MinimumCircumscribed,
    };
    let mut e = Evaluation::new(kind, method, points.len());
    match kind {
        Kind::Line => {
            let z = minzone::line_zone(points)?;
            e.point = Some(z.point);
            e.direction = Some(z.direction);
            e.rms = z.rms;
            e.max_abs_residual = z.max_abs_residual;
            e.form = z.form;
            e.extras = vec![("iterations", z.iterations as f64)];
        }
        Kind::Plane => {
            let z = minzone::plane_zone(points)?;
            e.point = Some(z.point);
            e.normal = Some(z.normal);
            e.rms = z.rms;
            e.max_abs_residual = z.max_abs_residual;
            e.form = z.form;
            e.extras = vec![("iterations", z.iterations as f64)];
        }
        Kind::Circle | Kind::Sphere => {
            let z = if kind == Kind::Circle {
                minzone::circle_fit(points, crit)?
            } else {
                minzone::sphere_fit(points, crit)?
            };
            e.center = Some(z.center);
            if kind == Kind::Circle {
                e.normal = Some(z.normal);
            }
            e.radius = Some(z.radius);
            e.rms = z.rms;
            e.max_abs_residual = z.max_abs_residual;
            e.form = z.form;
            e.zone_radii = Some((z.inner_radius, z.outer_radius));
            e.extras = vec![("iterations", z.iterations as f64)];
        }
        Kind::Cylinder => {
            let z = minzone::cylinder_fit(points, crit)?;
            e.point = Some(z.point);
            e.axis = Some(z.axis);
            e.radius = Some(z.radius);
            e.rms = z.rms;
            e.max_abs_residual = z.max_abs_residual;
            e.form = z.form;
            e.zone_radii = Some((z.inner_radius, z.outer_radius));
            e.extras = vec![("iterations", z.iterations as f64)];
        }
        Kind::Cone => unreachable!("checked: a cone has the least-squares fit only"),
    }
    Ok(e)
}

/// Why an evaluation failed.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum EvaluateError {
    /// The tolerances or method do not apply to the kind.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// The fit itself failed (degenerate or invalid points).
    #[error(transparent)]
    Fit(#[from] FitError),
}

/// Fit `kind` to `points` by `method`, and decide against `spec`.
pub fn evaluate(
    kind: Kind,
    method: Method,
    points: &[Point3],
    spec: &Spec,
) -> Result<Evaluation, EvaluateError> {
    check(kind, method, spec)?;
    let mut e = if method == Method::LeastSquares {
        ls(kind, points)?
    } else {
        let mut e = chebyshev(kind, method, points)?;
        // The guard band of a guarded size decision: the least-squares uncertainty.
        if spec.size.is_some() && spec.rule == DecisionRule::Guarded {
            e.diameter_expanded_uncertainty = ls(kind, points)?.diameter_expanded_uncertainty;
        }
        e
    };
    let mut verdicts = Vec::new();
    if let (Some(tol), Some(r)) = (spec.size, e.radius) {
        // An uncertainty that is not determined (as many parameters as points: no residual
        // left) is no guard band: a guarded decision can then neither pass nor fail.
        let u = e.diameter_expanded_uncertainty.unwrap_or(f64::NAN);
        let d = verdict::size_verdict(&tol, 2.0 * r, u, spec.rule);
        verdicts.push(d.verdict);
        e.size_decision = Some(d);
    }
    if let Some(t) = spec.form_tolerance {
        let v = verdict::form_verdict(e.form, t);
        verdicts.push(v);
        e.form_decision = Some(FormDecision { tolerance: t, verdict: v });
    }
    e.verdict = verdict::combine(&verdicts);
    Ok(e)
}
