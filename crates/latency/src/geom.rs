//! The artefact seen through the contacts: which feature the normals describe (a pair of
//! parallel faces, a circle, a sphere), its size, and the joint least-squares fit of the
//! feature with the system delay(s).
//!
//! Every contact's surface point is corrected as `point + diag(D)·velocity` (the contract's sign
//! convention: the machine data at stamp `t + D` is the position at probe stamp `t`). Residuals
//! are orthogonal distances weighted by each point's standard uncertainty, so the covariance
//! `(JᵀWJ)⁻¹`, inflated by the Birge ratio when the scatter exceeds it, is the uncertainty.
//!
//! Entry points: [`Feature::classify`], [`fit`] ([`FitSpec`] says what is known and what is
//! fitted), [`FeatureFit`].

use crate::contact::Contact;
use crate::LatencyError;
use truepos_math::lsq::{self, LsqOptions, Residuals};
use truepos_math::{Matrix3, Point3, Vector3};

/// The shape the contact normals describe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feature {
    /// Two parallel faces with normals ±`axis` (plates, a gauge block, ±X of a sphere).
    Pair {
        /// Unit axis of the pair.
        axis: Vector3,
    },
    /// Normals in one plane (normal `normal`, in-plane basis `e1`, `e2`): a circle.
    Circle {
        /// Unit normal of the plane.
        normal: Vector3,
        /// First in-plane unit vector.
        e1: Vector3,
        /// Second in-plane unit vector.
        e2: Vector3,
    },
    /// Normals spanning 3D: a sphere.
    Sphere,
}

impl Feature {
    /// Classify from the scatter matrix `Σ n nᵀ` (eigenvalues `λ1 ≥ λ2 ≥ λ3`) of the distinct
    /// contact directions (normals within 15° of each other form one direction, counted once):
    /// one direction (`λ2 < 5 %`) → pair; a plane (`λ3 < 5 %`) → circle; otherwise sphere.
    /// Counting directions rather than contacts keeps a direction probed less often than the
    /// others (one +Z touch among 192 in the XY plane) from being taken for scatter around a
    /// circle, whose fit would then put that point 14 mm off.
    pub fn classify(normals: &[Vector3]) -> Result<Feature, LatencyError> {
        if normals.len() < 2 {
            return Err(LatencyError::Underdetermined(format!(
                "{} contact(s) found; at least two are needed",
                normals.len()
            )));
        }
        let cos = 15f64.to_radians().cos();
        let mut dirs: Vec<(Vector3, Vector3)> = Vec::new(); // (first normal, sum)
        for q in normals {
            match dirs.iter_mut().find(|d| d.0.dot(q) > cos) {
                Some(d) => d.1 += q,
                None => dirs.push((*q, *q)),
            }
        }
        let mut m = Matrix3::zeros();
        for (_, sum) in &dirs {
            let u = sum.normalize();
            m += u * u.transpose();
        }
        let n = dirs.len() as f64;
        let e = m.symmetric_eigen();
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| e.eigenvalues[b].total_cmp(&e.eigenvalues[a]));
        let lam: Vec<f64> = idx.iter().map(|&i| e.eigenvalues[i] / n).collect();
        let vec = |k: usize| -> Vector3 { e.eigenvectors.column(idx[k]).into_owned() };
        if lam[1] < 0.05 {
            let axis = vec(0);
            let pos = normals.iter().filter(|q| q.dot(&axis) > 0.0).count();
            if pos == 0 || pos == normals.len() {
                return Err(LatencyError::Underdetermined(
                    "all contacts face the same way: no opposite pair to measure a size".into(),
                ));
            }
            return Ok(Feature::Pair { axis });
        }
        if lam[2] < 0.05 {
            let normal = vec(2);
            let e1 = vec(0);
            let e2 = normal.cross(&e1);
            return Ok(Feature::Circle { normal, e1, e2 });
        }
        Ok(Feature::Sphere)
    }

    /// The feature's name in the JSON output and messages.
    pub fn name(&self) -> &'static str {
        match self {
            Feature::Pair { .. } => "pair of parallel faces",
            Feature::Circle { .. } => "circle",
            Feature::Sphere => "sphere",
        }
    }
}

/// What the joint fit knows and estimates.
#[derive(Clone, Copy, Debug)]
pub struct FitSpec {
    /// Known stylus-centre size (signed: + for an outer feature (sphere, block), − for an inner
    /// one (gap, ring)); `None` to fit it.
    pub size: Option<f64>,
    /// Delay applied to the axes that are not fitted (s).
    pub fixed_delay: [f64; 3],
    /// Which delays are fitted: `Common` (one for all axes), `PerAxis(mask)`, or `None`.
    pub delay: DelayMode,
}

/// Which delays a feature fit estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DelayMode {
    /// No delay: every axis keeps its fixed delay.
    None,
    /// One delay common to all axes.
    Common,
    /// One delay per axis, for the axes marked `true` (X, Y, Z).
    PerAxis([bool; 3]),
}

impl DelayMode {
    fn n(&self) -> usize {
        match self {
            DelayMode::None => 0,
            DelayMode::Common => 1,
            DelayMode::PerAxis(m) => m.iter().filter(|&&b| b).count(),
        }
    }
}

/// Result of [`fit`].
#[derive(Clone, Debug)]
pub struct FeatureFit {
    /// Signed stylus-centre size: diameter (+ outer, − inner) or face distance.
    pub size: f64,
    /// Standard uncertainty of `size`, mm.
    pub u_size: f64,
    /// Delay per axis (the fixed value where not fitted).
    pub delay: [f64; 3],
    /// Standard uncertainty per axis (NaN where not fitted).
    pub u_delay: [f64; 3],
    /// Centre (circle, sphere) in machine coordinates.
    pub center: Option<Point3>,
    /// RMS orthogonal residual (mm).
    pub rms: f64,
    /// Birge ratio √(χ²/dof) of the weighted residuals (1 when no degrees of freedom).
    pub birge: f64,
    /// Degrees of freedom of the fit (residuals minus parameters).
    pub dof: usize,
}

struct Problem<'a> {
    feature: Feature,
    contacts: &'a [Contact],
    spec: FitSpec,
    /// Orientation of the pair axis (group A has n·axis > 0).
    axis: Vector3,
}

impl Problem<'_> {
    fn n_geom(&self) -> usize {
        let base = match self.feature {
            Feature::Pair { .. } => 1,
            Feature::Circle { .. } => 2,
            Feature::Sphere => 3,
        };
        base + usize::from(self.spec.size.is_none())
    }
    fn delays(&self, p: &[f64]) -> [f64; 3] {
        let g = self.n_geom();
        match self.spec.delay {
            DelayMode::None => self.spec.fixed_delay,
            DelayMode::Common => [p[g]; 3],
            DelayMode::PerAxis(mask) => {
                let mut d = self.spec.fixed_delay;
                let mut j = g;
                for k in 0..3 {
                    if mask[k] {
                        d[k] = p[j];
                        j += 1;
                    }
                }
                d
            }
        }
    }
    /// Residual (mm, unweighted) and its gradient with respect to the corrected point.
    fn raw(&self, p: &[f64], q: &Point3, c: &Contact) -> (f64, Vector3, [f64; 4]) {
        // Returns (residual, ∂r/∂q, ∂r/∂geometry params).
        let mut dg = [0.0; 4];
        match self.feature {
            Feature::Pair { .. } => {
                let s = self.spec.size.unwrap_or_else(|| p[1]);
                let x = self.axis.dot(&q.coords);
                if c.normal.dot(&self.axis) > 0.0 {
                    dg[0] = -1.0;
                    (x - p[0], self.axis, dg)
                } else {
                    dg[0] = -1.0;
                    dg[1] = 1.0;
                    (x - (p[0] - s), self.axis, dg)
                }
            }
            Feature::Circle { e1, e2, .. } => {
                let r = self.spec.size.map_or_else(|| p[2], |s| s.abs() / 2.0);
                let (u, v) = (e1.dot(&q.coords) - p[0], e2.dot(&q.coords) - p[1]);
                let d = (u * u + v * v).sqrt().max(1e-300);
                dg[0] = -u / d;
                dg[1] = -v / d;
                dg[2] = -1.0;
                (d - r, e1 * (u / d) + e2 * (v / d), dg)
            }
            Feature::Sphere => {
                let r = self.spec.size.map_or_else(|| p[3], |s| s.abs() / 2.0);
                let w = q.coords - Vector3::new(p[0], p[1], p[2]);
                let d = w.norm().max(1e-300);
                let g = w / d;
                dg[0] = -g.x;
                dg[1] = -g.y;
                dg[2] = -g.z;
                dg[3] = -1.0;
                (d - r, g, dg)
            }
        }
    }
}

impl Residuals for Problem<'_> {
    fn n_params(&self) -> usize {
        self.n_geom() + self.spec.delay.n()
    }
    fn n_residuals(&self) -> usize {
        self.contacts.len()
    }
    fn eval(&self, p: &[f64], i: usize, jac: &mut [f64]) -> f64 {
        let c = &self.contacts[i];
        let d = self.delays(p);
        let q = c.corrected(d);
        let (r, dq, dg) = self.raw(p, &q, c);
        let w = 1.0 / c.u_point;
        let g = self.n_geom();
        for j in 0..g {
            // dg holds the derivatives of the geometry parameters that exist (fixed size drops
            // the last one).
            jac[j] = dg[j] * w;
        }
        let v = c.velocity;
        match self.spec.delay {
            DelayMode::None => {}
            DelayMode::Common => jac[g] = dq.dot(&v) * w,
            DelayMode::PerAxis(mask) => {
                let mut j = g;
                for k in 0..3 {
                    if mask[k] {
                        jac[j] = dq[k] * v[k] * w;
                        j += 1;
                    }
                }
            }
        }
        r * w
    }
}

/// Algebraic (Kåsa) starting values: circle in the (e1, e2) plane or sphere.
fn start_values(feature: Feature, pts: &[Point3]) -> Result<Vec<f64>, LatencyError> {
    match feature {
        Feature::Pair { .. } => Ok(vec![]),
        Feature::Circle { e1, e2, .. } => {
            let mut m = Matrix3::zeros();
            let mut r = Vector3::zeros();
            for p in pts {
                let (u, v) = (e1.dot(&p.coords), e2.dot(&p.coords));
                let row = Vector3::new(u, v, 1.0);
                m += row * row.transpose();
                r += row * (u * u + v * v);
            }
            let s = m
                .try_inverse()
                .ok_or_else(|| LatencyError::Degenerate("the points do not define a circle".into()))?
                * r;
            let (a, b) = (s[0] / 2.0, s[1] / 2.0);
            Ok(vec![a, b, (s[2] + a * a + b * b).max(0.0).sqrt()])
        }
        Feature::Sphere => {
            let mut m = nalgebra::Matrix4::<f64>::zeros();
            let mut r = nalgebra::Vector4::<f64>::zeros();
            for p in pts {
                let row = nalgebra::Vector4::new(p.x, p.y, p.z, 1.0);
                m += row * row.transpose();
                r += row * p.coords.norm_squared();
            }
            let s = m
                .try_inverse()
                .ok_or_else(|| LatencyError::Degenerate("the points do not define a sphere".into()))?
                * r;
            let c = Vector3::new(s[0], s[1], s[2]) / 2.0;
            Ok(vec![c.x, c.y, c.z, (s[3] + c.norm_squared()).max(0.0).sqrt()])
        }
    }
}

/// Whether the contacts enclose the centre from outside (outer feature) or inside (inner).
fn outer_sign(feature: Feature, contacts: &[Contact], axis: &Vector3, center: Option<Point3>) -> f64 {
    let s: f64 = match (feature, center) {
        (Feature::Pair { .. }, _) => {
            // Outer when the faces whose normals point +axis lie at larger axis coordinate.
            let (mut a, mut na, mut b, mut nb) = (0.0, 0.0, 0.0, 0.0);
            for c in contacts {
                if c.normal.dot(axis) > 0.0 {
                    a += axis.dot(&c.point.coords);
                    na += 1.0;
                } else {
                    b += axis.dot(&c.point.coords);
                    nb += 1.0;
                }
            }
            a / na - b / nb
        }
        (_, Some(c0)) => contacts.iter().map(|c| c.normal.dot(&(c.point - c0))).sum(),
        _ => 1.0,
    };
    if s >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

/// Fit the feature (and the delays `spec.delay`) to the contacts.
pub fn fit(feature: Feature, contacts: &[Contact], spec: FitSpec) -> Result<FeatureFit, LatencyError> {
    let axis = match feature {
        Feature::Pair { axis } => axis,
        _ => Vector3::z(),
    };
    let pts: Vec<Point3> = contacts.iter().map(|c| c.corrected(spec.fixed_delay)).collect();
    let mut x0 = start_values(feature, &pts)?;
    let mut center = None;
    match feature {
        Feature::Pair { .. } => {
            let (mut a, mut na, mut b, mut nb) = (0.0, 0.0, 0.0, 0.0);
            for (c, p) in contacts.iter().zip(&pts) {
                if c.normal.dot(&axis) > 0.0 {
                    a += axis.dot(&p.coords);
                    na += 1.0;
                } else {
                    b += axis.dot(&p.coords);
                    nb += 1.0;
                }
            }
            x0.push(a / na);
            if spec.size.is_none() {
                x0.push(a / na - b / nb);
            }
        }
        Feature::Circle { e1, e2, normal } => {
            let h = pts.iter().map(|p| normal.dot(&p.coords)).sum::<f64>() / pts.len() as f64;
            center = Some(Point3::from(e1 * x0[0] + e2 * x0[1] + normal * h));
            if spec.size.is_some() {
                x0.pop();
            }
        }
        Feature::Sphere => {
            center = Some(Point3::new(x0[0], x0[1], x0[2]));
            if spec.size.is_some() {
                x0.pop();
            }
        }
    }
    let sign = outer_sign(feature, contacts, &axis, center);
    if let Some(s) = spec.size {
        if s * sign < 0.0 {
            return Err(LatencyError::Degenerate(format!(
                "the known size is for an {} feature but the contacts describe an {} one",
                if s > 0.0 { "outer" } else { "inner" },
                if sign > 0.0 { "outer" } else { "inner" }
            )));
        }
    }
    match spec.delay {
        DelayMode::None => {}
        DelayMode::Common => x0.push(spec.fixed_delay[0]),
        DelayMode::PerAxis(mask) => {
            for (k, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
                x0.push(spec.fixed_delay[k]);
            }
        }
    }
    let prob = Problem { feature, contacts, spec, axis };
    let np = prob.n_params();
    if contacts.len() < np {
        return Err(LatencyError::Underdetermined(format!(
            "{} contacts cannot determine the {} unknowns of a {} fit",
            contacts.len(),
            np,
            feature.name()
        )));
    }
    let mut scale = vec![1.0; np];
    for s in scale.iter_mut().skip(prob.n_geom()) {
        *s = 1e-3;
    }
    let opt = LsqOptions { x_tol: 1e-12, x_scale: Some(scale), ..LsqOptions::default() };
    let r = lsq::solve(&prob, &x0, &opt)
        .map_err(|e| LatencyError::Degenerate(format!("{} fit: {e}", feature.name())))?;
    if r.rank < np {
        return Err(LatencyError::Underdetermined(format!(
            "the contacts do not determine every unknown of the {} fit (rank {} of {})",
            feature.name(),
            r.rank,
            np
        )));
    }
    let dof = contacts.len() - np;
    let birge = if dof > 0 { (r.ssr / dof as f64).sqrt() } else { 1.0 };
    let inv = lsq::spd_pinv(&r.normal_matrix, 1e-12);
    let k = birge.max(1.0);
    let u = |j: usize| inv[(j, j)].max(0.0).sqrt() * k;
    let p = &r.params;
    let (size, u_size) = match (feature, spec.size) {
        (_, Some(s)) => (s, 0.0),
        (Feature::Pair { .. }, None) => (p[1], u(1)),
        (Feature::Circle { .. }, None) => (2.0 * p[2] * sign, 2.0 * u(2)),
        (Feature::Sphere, None) => (2.0 * p[3] * sign, 2.0 * u(3)),
    };
    let center = match feature {
        Feature::Pair { .. } => None,
        Feature::Circle { e1, e2, normal } => {
            let h = pts.iter().map(|q| normal.dot(&q.coords)).sum::<f64>() / pts.len() as f64;
            Some(Point3::from(e1 * p[0] + e2 * p[1] + normal * h))
        }
        Feature::Sphere => Some(Point3::new(p[0], p[1], p[2])),
    };
    let delay = prob.delays(p);
    let mut u_delay = [f64::NAN; 3];
    let g = prob.n_geom();
    match spec.delay {
        DelayMode::None => {}
        DelayMode::Common => u_delay = [u(g); 3],
        DelayMode::PerAxis(mask) => {
            let mut j = g;
            for k in 0..3 {
                if mask[k] {
                    u_delay[k] = u(j);
                    j += 1;
                }
            }
        }
    }
    // Unweighted RMS orthogonal residual.
    let mut ss = 0.0;
    let mut jac = vec![0.0; np];
    for (i, c) in contacts.iter().enumerate() {
        let rr = prob.eval(p, i, &mut jac) * c.u_point;
        ss += rr * rr;
    }
    Ok(FeatureFit {
        size,
        u_size,
        delay,
        u_delay,
        center,
        rms: (ss / contacts.len() as f64).sqrt(),
        birge,
        dof,
    })
}

/// Whether the contacts describe an outer feature (sphere, block: normals point away from the
/// centre) rather than an inner one (ring, gap).
pub fn is_outer(feature: Feature, contacts: &[Contact]) -> Result<bool, LatencyError> {
    let pts: Vec<Point3> = contacts.iter().map(|c| c.point).collect();
    let axis = match feature {
        Feature::Pair { axis } => axis,
        _ => Vector3::z(),
    };
    let center = match feature {
        Feature::Pair { .. } => None,
        Feature::Circle { e1, e2, .. } => {
            let x = start_values(feature, &pts)?;
            Some(Point3::from(e1 * x[0] + e2 * x[1]))
        }
        Feature::Sphere => {
            let x = start_values(feature, &pts)?;
            Some(Point3::new(x[0], x[1], x[2]))
        }
    };
    // For a circle the centre lacks its out-of-plane coordinate; normals are in-plane, so the
    // dot products are unaffected.
    Ok(outer_sign(feature, contacts, &axis, center) > 0.0)
}

/// Which axes have opposite contacts (normal components beyond ±0.5) and motion along them,
/// i.e. whose own delay a known-size fit can determine.
pub fn axes_with_opposite_pairs(contacts: &[Contact]) -> [bool; 3] {
    let mut m = [false; 3];
    for (k, mk) in m.iter_mut().enumerate() {
        let pos = contacts.iter().any(|c| c.normal[k] > 0.5 && c.velocity[k].abs() > 1e-6);
        let neg = contacts.iter().any(|c| c.normal[k] < -0.5 && c.velocity[k].abs() > 1e-6);
        *mk = pos && neg;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classification_counts_directions_not_contacts() {
        let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
        let mut normals = Vec::new();
        for _ in 0..48 {
            normals.extend([x, -x, y, -y]);
        }
        assert!(matches!(Feature::classify(&normals), Ok(Feature::Circle { .. })));
        // One touch on top makes the data three-dimensional: a sphere, not a circle with an
        // outlier 14 mm inside it.
        normals.push(z);
        assert_eq!(Feature::classify(&normals), Ok(Feature::Sphere));
        // Many touches on ±X and one on +Y leave a circle; ±X alone a pair.
        let mut pair: Vec<Vector3> = (0..40).map(|k| if k % 2 == 0 { x } else { -x }).collect();
        match Feature::classify(&pair) {
            Ok(Feature::Pair { axis }) => assert!(axis.x.abs() > 1.0 - 1e-12),
            other => panic!("{other:?}"),
        }
        pair.push(y);
        assert!(matches!(Feature::classify(&pair), Ok(Feature::Circle { .. })));
        // Normals a few degrees apart (friction, noise) are one direction.
        let tilt = Vector3::new(1.0, 0.05, 0.0).normalize();
        let near: Vec<Vector3> = (0..40).map(|k| if k % 2 == 0 { tilt } else { -x }).collect();
        assert!(matches!(Feature::classify(&near), Ok(Feature::Pair { .. })));
    }
}
