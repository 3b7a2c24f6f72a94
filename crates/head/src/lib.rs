//! # truepos-head
//!
//! Measuring-head 3D offset calibration (`truepos head-offset`, capability 2 of the product
//! spec). Plain data in, numbers with uncertainties and observability out; the points file is
//! read by [`crate::file`].
//!
//! Model (contract, `shared/spec/interface.md`, "Head offset"): `R` is the offset in the head
//! frame at `b = 0`; the measuring reference point is `Q = P + Ry(b)·R` (P: the NC's head
//! reference point). A laser head reports the surface at `Q + dist·Ry(b)·u`,
//! `u = unit(tan α, tan β, −1)`. The table turns about the line through `O` parallel to Z: a
//! point fixed to the table at `c = 0` position `A` is at `O + Rz(c)·(A − O)`. A touch probe
//! measures stylus-centre positions (the sphere of radius sphere + tip).
//!
//! Entry points:
//! - [`solve`]: one combined least-squares adjustment over any mix of head (B) and table (C)
//!   orientations. Unknowns: the offset `R`, the reference point at `c = 0` (sphere centre or
//!   vertex), the radius if not fixed, and for vertex references the face normals. Observations:
//!   orthogonal distances of every point to the sphere / its face plane, expressed in table
//!   coordinates. Started from the closed-form apparent-centre solution ([`init`]), so it does not
//!   depend on where the reference is or how large the offset is. Components of `R` that the data
//!   cannot determine (null space of the column-scaled normal matrix) are held at the prior and
//!   reported as not observable.
//! - [`task::calibrate_file`]: `truepos head-offset` as a library call (a `Report` back).
//! - [`file::read_input`]: the points file as [`Reading`]s.
//! - [`surface_point`] / [`beam_direction`]: the contract's forward model, used by
//!   `truepos head-offset apply`.
//! - [`acquire::probe_sphere`]: collect the points by probing a reference sphere through any
//!   `truepos_device::ProbingMachine` (the virtual machine tool, LinuxCNC, a CMM).
//!
//! The classical methods are special cases of the one adjustment: head swivel only determines
//! the offset components in the XZ plane (Y is not observable); table rotation only determines X
//! and Y (the triangle of apparent centres about the known table centre; Z is not observable);
//! any mix of both determines all three.

#![forbid(unsafe_code)]

pub mod acquire;
pub mod file;
pub mod init;
pub mod json;
pub mod task;

use init::{algebraic_sphere, intersect_planes, linear_solve, plane_fit, Apparent};
use std::collections::BTreeMap;
use thiserror::Error;
use truepos_math::lsq::{self, LsqError, LsqOptions, Residuals};
use truepos_math::{any_perpendicular, ry, rz, DMatrix, Matrix3, Point3, Vector3};

/// One reading: head angle `b`, table angle `c` (rad), the NC's head reference point `p`, and
/// optionally a laser distance, a face id (vertex references) and an orientation group id.
#[derive(Clone, Debug, PartialEq)]
pub struct Reading {
    /// Head swivel angle B about Y, rad.
    pub b: f64,
    /// Table angle C about Z, rad.
    pub c: f64,
    /// The NC's head reference point P in machine coordinates, mm.
    pub p: Point3,
    /// Laser distance reading along the beam, mm (laser heads only).
    pub dist: Option<f64>,
    /// Index of the face the point was probed on (vertex references).
    pub face: Option<i64>,
    /// Index of the orientation group the reading belongs to.
    pub group: Option<i64>,
}

/// The reference object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reference {
    /// A sphere; `radius` fixes the radius of the measured surface (for a touch probe: sphere
    /// radius + tip radius, the sphere of stylus-centre positions).
    Sphere {
        /// Fixed radius of the measured surface, mm (`None`: fitted).
        radius: Option<f64>,
    },
    /// A vertex: pyramid apex or cuboid corner, the common point of the measured faces (convex).
    /// `tip_radius`: a touch probe's stylus centre runs on the faces moved out by it (0 for a
    /// laser head).
    Vertex {
        /// Stylus tip radius, mm (0 for a laser head).
        tip_radius: f64,
    },
}

/// Everything the adjustment needs besides the readings.
#[derive(Clone, Debug)]
pub struct Params {
    /// The reference object (sphere or vertex).
    pub reference: Reference,
    /// A point on the table's rotation axis (parallel to Z).
    pub table_center: Point3,
    /// Laser beam tilt `(α, β)` in rad (ignored without `dist`).
    pub tilt: [f64; 2],
    /// Value used for offset components the data cannot determine.
    pub prior: Vector3,
    /// Laser heads ("laser tilt" method): the beam passes through the head reference point P, so
    /// R is parallel to the beam direction u. Offset components no rotation reaches then follow
    /// from the tilt and the measured components (`R_j = s·u_j`, `s` the least-squares length of
    /// the measured part along u). Only an assumption about the head makes this possible: the
    /// data alone never determines such a component.
    pub beam_through_reference: bool,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            reference: Reference::Sphere { radius: None },
            table_center: Point3::origin(),
            tilt: [0.0, 0.0],
            prior: Vector3::zeros(),
            beam_through_reference: false,
        }
    }
}

/// One orientation of the data (readings with the same group, B and C).
#[derive(Clone, Debug)]
pub struct Orientation {
    /// Head angle B, rad.
    pub b: f64,
    /// Table angle C, rad.
    pub c: f64,
    /// The orientation group index, when the file has a `group` column.
    pub group: Option<i64>,
    /// Number of readings in this orientation.
    pub n_points: usize,
    /// Apparent reference point in raw coordinates (closed-form, per-orientation fit).
    pub apparent: Point3,
}

/// The result of the adjustment.
#[derive(Clone, Debug)]
pub struct HeadOffset {
    /// The offset R (mm); components that are not observable hold the prior.
    pub offset: Vector3,
    /// Which components of the offset (X, Y, Z) the rotations determine.
    pub observable: [bool; 3],
    /// Components that come from the laser beam tilt (`Params::beam_through_reference`), not
    /// from the rotations.
    pub from_tilt: [bool; 3],
    /// Standard uncertainty of each observable component (mm); `None` if not observable.
    pub u_offset: [Option<f64>; 3],
    /// Sphere centre or vertex, in table coordinates at `c = 0` (= machine coordinates there).
    pub reference_point: Point3,
    /// Standard uncertainties of `reference_point`, mm.
    pub u_reference_point: Vector3,
    /// Components of the reference point the data gives only together with an unobservable
    /// offset component (they follow the prior).
    pub reference_depends_on_prior: [bool; 3],
    /// Fitted (or fixed) radius of the measured sphere surface.
    pub radius: Option<f64>,
    /// Standard uncertainty of `radius`, mm (`None` when fixed or absent).
    pub u_radius: Option<f64>,
    /// Face normals of a vertex reference (table frame at `c = 0`), by face id.
    pub face_normals: Vec<(i64, Vector3)>,
    /// Root mean square of the orthogonal distances (mm).
    pub rms: f64,
    /// Largest absolute orthogonal distance, mm.
    pub max_abs_residual: f64,
    /// Number of readings used.
    pub n_points: usize,
    /// The orientations found in the data, in order of first appearance.
    pub orientations: Vec<Orientation>,
    /// The closed-form (apparent-centre) offset the adjustment started from.
    pub closed_form_offset: Vector3,
    /// Condition number of the column-scaled normal matrix at the solution.
    pub condition: f64,
    /// Iterations of the least-squares adjustment.
    pub iterations: usize,
    /// Whether the adjustment converged before its iteration limit.
    pub converged: bool,
    /// Orthogonal distance of each reading to the fitted reference (mm), in input order.
    pub residuals: Vec<f64>,
}

/// Why a head offset cannot be computed from the readings.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum HeadError {
    /// The file has no readings.
    #[error("no readings: the offset needs the reference measured in at least two orientations")]
    NoData,
    /// Every reading is at one orientation (`n` readings at B, C in degrees).
    #[error(
        "all {n} readings were taken in one orientation (b = {b_deg}°, c = {c_deg}°): the offset needs the \
         reference measured in at least two orientations (swivel the head in B and/or turn the table in C \
         between the measurements)"
    )]
    OneOrientation {
        /// Number of readings.
        n: usize,
        /// Head angle B, degrees.
        b_deg: f64,
        /// Table angle C, degrees.
        c_deg: f64,
    },
    /// An orientation has fewer readings than its fit needs.
    #[error(
        "orientation b = {b_deg}°, c = {c_deg}° has {got} readings: {needed} are needed per orientation \
         ({what})"
    )]
    OrientationTooFew {
        /// Head angle B, degrees.
        b_deg: f64,
        /// Table angle C, degrees.
        c_deg: f64,
        /// Readings in the orientation.
        got: usize,
        /// Readings needed.
        needed: usize,
        /// What they are needed for.
        what: &'static str,
    },
    /// Fewer readings than unknowns overall.
    #[error("{got} readings for {needed} unknowns: at least {needed} readings are needed")]
    TooFewPoints {
        /// Readings given.
        got: usize,
        /// Readings needed.
        needed: usize,
    },
    /// An orientation's points do not determine its reference point (what is wrong).
    #[error("orientation b = {b_deg}°, c = {c_deg}°: {what}")]
    Degenerate {
        /// Head angle B, degrees.
        b_deg: f64,
        /// Table angle C, degrees.
        c_deg: f64,
        /// What is wrong.
        what: String,
    },
    /// Fewer than two orientations with at least three probed faces (vertex references).
    #[error(
        "only {got} orientation(s) show at least 3 faces: a vertex reference needs at least two \
         orientations in each of which at least 3 faces (3 points each) are probed"
    )]
    TooFewVertexOrientations {
        /// Orientations with three faces or more.
        got: usize,
    },
    /// A reading without a face id for a vertex reference (its 0-based index).
    #[error(
        "a reading without a face id: a vertex reference needs the 'face' column (the face each point was \
         probed on; reading index {index})"
    )]
    MissingFace {
        /// 0-based index of the reading.
        index: usize,
    },
    /// A laser reading with a beam tilt of 85° or more (its 0-based index).
    #[error("a laser reading (dist) needs beam tilt angles below 85° (reading index {index})")]
    BadTilt {
        /// 0-based index of the reading.
        index: usize,
    },
    /// A reading with a NaN or infinite value (its 0-based index).
    #[error("a value is not finite (reading index {index})")]
    NotFinite {
        /// 0-based index of the reading.
        index: usize,
    },
    /// A fixed radius that is not finite and positive (mm).
    #[error("the radius must be positive and finite, got {0} mm")]
    BadRadius(f64),
    /// No two orientations differ in B or C, so no offset component is observable.
    #[error(
        "the orientations do not determine any component of the offset: the reference must be measured \
         in at least two orientations that differ in the head swivel B or the table angle C (modulo 360°)"
    )]
    NothingObservable,
    /// The least-squares adjustment failed.
    #[error("the adjustment failed: {0}")]
    Lsq(#[from] LsqError),
}

/// Unit beam direction `unit(tan α, tan β, −1)` in the head frame at `b = 0`.
pub fn beam_direction(tilt: [f64; 2]) -> Vector3 {
    Vector3::new(tilt[0].tan(), tilt[1].tan(), -1.0).normalize()
}

/// The measured point of one reading in machine coordinates: `Q = P + Ry(b)·R`, plus
/// `dist·Ry(b)·u` for a laser reading.
pub fn surface_point(p: &Point3, b: f64, offset: &Vector3, dist: Option<f64>, beam: &Vector3) -> Point3 {
    let v = offset + beam * dist.unwrap_or(0.0);
    p + ry(b) * v
}

/// Machine coordinates at table angle `c` to table coordinates at `c = 0`.
pub fn machine_to_table(x: &Point3, c: f64, o: &Point3) -> Point3 {
    o + rz(-c) * (x - o)
}

/// Per reading, precomputed: `X(R) = x0 + m·R` in table coordinates.
struct Pre {
    x0: Point3,
    m: Matrix3,
}

/// Eigenvalues of the column-scaled normal matrix below this fraction of the largest are a
/// null space (exact rank defects come out at rounding level, ~1e-16; a swivel of 0.01° between
/// orientations still gives ~3e-8).
const NULL_TOL: f64 = 1e-10;

enum Kind {
    Sphere { fixed_radius: Option<f64> },
    Vertex { faces: Vec<(Vector3, Vector3, Vector3)>, face_of: Vec<usize>, tip: f64 },
}

struct Problem<'a> {
    pre: &'a [Pre],
    free: Vec<usize>,
    prior: Vector3,
    kind: &'a Kind,
}

impl Problem<'_> {
    fn offset(&self, p: &[f64]) -> Vector3 {
        let mut r = self.prior;
        for (k, &j) in self.free.iter().enumerate() {
            r[j] = p[k];
        }
        r
    }
    fn nr(&self) -> usize {
        self.free.len()
    }
}

fn face_normal(n0: &Vector3, e1: &Vector3, e2: &Vector3, a: f64, b: f64) -> (Vector3, f64) {
    let v = n0 + e1 * a + e2 * b;
    let l = v.norm();
    (v / l, l)
}

impl Residuals for Problem<'_> {
    fn n_params(&self) -> usize {
        let base = self.nr() + 3;
        match self.kind {
            Kind::Sphere { fixed_radius } => base + usize::from(fixed_radius.is_none()),
            Kind::Vertex { faces, .. } => base + 2 * faces.len(),
        }
    }
    fn n_residuals(&self) -> usize {
        self.pre.len()
    }
    fn eval(&self, p: &[f64], i: usize, jac: &mut [f64]) -> f64 {
        let nr = self.nr();
        let r = self.offset(p);
        let pre = &self.pre[i];
        let x = pre.x0 + pre.m * r;
        let a = Point3::new(p[nr], p[nr + 1], p[nr + 2]);
        match self.kind {
            Kind::Sphere { fixed_radius } => {
                let d = x - a;
                let len = d.norm();
                let e = if len > 0.0 { d / len } else { Vector3::z() };
                let g = pre.m.transpose() * e;
                for (k, &j) in self.free.iter().enumerate() {
                    jac[k] = g[j];
                }
                jac[nr] = -e.x;
                jac[nr + 1] = -e.y;
                jac[nr + 2] = -e.z;
                let rad = match fixed_radius {
                    Some(v) => *v,
                    None => {
                        jac[nr + 3] = -1.0;
                        p[nr + 3]
                    }
                };
                len - rad
            }
            Kind::Vertex { faces, face_of, tip } => {
                let f = face_of[i];
                let (n0, e1, e2) = &faces[f];
                let (pa, pb) = (p[nr + 3 + 2 * f], p[nr + 4 + 2 * f]);
                let (n, l) = face_normal(n0, e1, e2, pa, pb);
                let d = x - a;
                let g = pre.m.transpose() * n;
                for (k, &j) in self.free.iter().enumerate() {
                    jac[k] = g[j];
                }
                jac[nr] = -n.x;
                jac[nr + 1] = -n.y;
                jac[nr + 2] = -n.z;
                // d n / d a = (e1 − n (n·e1)) / |v|, likewise for b.
                let dna = (e1 - n * n.dot(e1)) / l;
                let dnb = (e2 - n * n.dot(e2)) / l;
                jac[nr + 3 + 2 * f] = dna.dot(&d);
                jac[nr + 4 + 2 * f] = dnb.dot(&d);
                n.dot(&d) - tip
            }
        }
    }
}

/// Offset components in the null space of the column-scaled normal matrix (`(j, col)`: `R_j` is
/// parameter `col`).
fn unobservable(jtj: &DMatrix, r_cols: &[(usize, usize)]) -> [bool; 3] {
    let flags = null_flags(jtj, &r_cols.iter().map(|c| c.1).collect::<Vec<_>>());
    let mut out = [false; 3];
    for (&(j, _), f) in r_cols.iter().zip(flags) {
        out[j] = f;
    }
    out
}

/// For each parameter column in `cols`: does a null direction of the column-scaled normal matrix
/// have a noticeable share on it (or is the column all zero)?
fn null_flags(jtj: &DMatrix, cols: &[usize]) -> Vec<bool> {
    truepos_math::lsq::null_space_flags(jtj, cols, NULL_TOL, 1e-4)
}

fn deg(x: f64) -> f64 {
    let d = x.to_degrees();
    (d * 1e6).round() / 1e6
}

/// Determine the head offset from readings of a reference object in several orientations.
///
/// The steps: check the input (`check_input`); group the readings into orientations
/// (`orientations_of`); the closed-form reference point of every orientation
/// (`closed_form`); the model (`model_of`); which offset components the data determines
/// (`observability`); the combined adjustment; for laser heads whose beam passes through the
/// reference point, the components the rotations cannot reach (`complete_from_beam`); the
/// result ([`HeadOffset`]).
pub fn solve(readings: &[Reading], params: &Params) -> Result<HeadOffset, HeadError> {
    let beam = beam_direction(params.tilt);
    check_input(readings, params, &beam)?;
    // Raw points without the offset: P' = P + Ry(b)·dist·u (the offset enters as + Ry(b)·R).
    let raw: Vec<Point3> =
        readings.iter().map(|r| surface_point(&r.p, r.b, &Vector3::zeros(), r.dist, &beam)).collect();
    let groups = orientations_of(readings)?;
    let vertex_tip = match params.reference {
        Reference::Vertex { tip_radius } if tip_radius.is_finite() && tip_radius >= 0.0 => tip_radius,
        Reference::Vertex { tip_radius } => return Err(HeadError::BadRadius(tip_radius)),
        Reference::Sphere { .. } => 0.0,
    };
    let cf = closed_form(readings, &raw, &groups, &params.reference, vertex_tip)?;
    let (kind, radius0) = model_of(readings, params, &cf, vertex_tip)?;
    let o = params.table_center;
    let pre: Vec<Pre> = readings
        .iter()
        .zip(&raw)
        .map(|(r, x)| Pre { x0: machine_to_table(x, r.c, &o), m: rz(-r.c) * ry(r.b) })
        .collect();
    let obs = observability(&pre, &cf.apparent, &kind, radius0, params)?;

    // The combined adjustment over the observable components.
    let free: Vec<usize> = (0..3).filter(|&j| obs.observable[j]).collect();
    let (a0, r0) =
        linear_solve(&cf.apparent, &o, obs.observable, &params.prior).ok_or(HeadError::NothingObservable)?;
    let problem = Problem { pre: &pre, free: free.clone(), prior: params.prior, kind: &kind };
    let x0 = start_params(&free, &r0, &a0, &kind, radius0);
    let opt = LsqOptions { rank_tol: NULL_TOL, ..LsqOptions::default() };
    let res = lsq::solve(&problem, &x0, &opt)?;
    let nr = free.len();
    let mut solution = Solution {
        offset: problem.offset(&res.params),
        u_offset: [None; 3],
        reference_point: Point3::new(res.params[nr], res.params[nr + 1], res.params[nr + 2]),
        observable: obs.observable,
        reference_depends_on_prior: obs.reference_depends_on_prior,
        from_tilt: [false; 3],
    };
    for (k, &j) in free.iter().enumerate() {
        solution.u_offset[j] = Some(res.std_dev(k));
    }
    let laser = readings.iter().any(|r| r.dist.is_some());
    if params.beam_through_reference && laser && free.len() < 3 {
        complete_from_beam(&mut solution, &free, &beam, &res.covariance);
    }

    let u_reference_point = Vector3::new(res.std_dev(nr), res.std_dev(nr + 1), res.std_dev(nr + 2));
    let (radius, u_radius) = match &kind {
        Kind::Sphere { fixed_radius: Some(r) } => (Some(*r), None),
        Kind::Sphere { fixed_radius: None } => (Some(res.params[nr + 3]), Some(res.std_dev(nr + 3))),
        Kind::Vertex { .. } => (None, None),
    };
    let face_normals = match &kind {
        Kind::Vertex { faces, .. } => faces
            .iter()
            .enumerate()
            .map(|(f, (n0, e1, e2))| {
                (
                    cf.face_ids[f],
                    face_normal(n0, e1, e2, res.params[nr + 3 + 2 * f], res.params[nr + 4 + 2 * f]).0,
                )
            })
            .collect(),
        Kind::Sphere { .. } => Vec::new(),
    };
    let mut jac = vec![0.0; problem.n_params()];
    let residuals: Vec<f64> = (0..pre.len()).map(|i| problem.eval(&res.params, i, &mut jac)).collect();
    let n = residuals.len() as f64;
    let rms = (residuals.iter().map(|r| r * r).sum::<f64>() / n).sqrt();
    let max_abs_residual = residuals.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    Ok(HeadOffset {
        offset: solution.offset,
        observable: solution.observable,
        from_tilt: solution.from_tilt,
        u_offset: solution.u_offset,
        reference_point: solution.reference_point,
        u_reference_point,
        reference_depends_on_prior: solution.reference_depends_on_prior,
        radius,
        u_radius,
        face_normals,
        rms,
        max_abs_residual,
        n_points: readings.len(),
        orientations: cf.orientations,
        closed_form_offset: r0,
        condition: res.condition,
        iterations: res.iterations,
        converged: res.converged,
        residuals,
    })
}

/// Every reading finite, laser readings with a usable beam tilt, a fixed sphere radius positive.
fn check_input(readings: &[Reading], params: &Params, beam: &Vector3) -> Result<(), HeadError> {
    if readings.is_empty() {
        return Err(HeadError::NoData);
    }
    for (i, r) in readings.iter().enumerate() {
        let finite = r.b.is_finite() && r.c.is_finite() && r.p.coords.iter().all(|v| v.is_finite());
        if !finite || r.dist.is_some_and(|d| !d.is_finite()) {
            return Err(HeadError::NotFinite { index: i });
        }
        if r.dist.is_some()
            && !(beam.iter().all(|v| v.is_finite())
                && params.tilt.iter().all(|t| t.abs() < 85f64.to_radians()))
        {
            return Err(HeadError::BadTilt { index: i });
        }
    }
    if let Reference::Sphere { radius: Some(rad) } = params.reference {
        if !(rad > 0.0 && rad.is_finite()) {
            return Err(HeadError::BadRadius(rad));
        }
    }
    Ok(())
}

/// An orientation's key: group id, B and C (angles compared to 1e-9 rad).
type OrientationKey = (Option<i64>, i64, i64);

/// The readings grouped by orientation (same group id, B and C); at least two distinct angle
/// pairs are needed.
fn orientations_of(readings: &[Reading]) -> Result<BTreeMap<OrientationKey, Vec<usize>>, HeadError> {
    let key = |r: &Reading| (r.group, (r.b * 1e9).round() as i64, (r.c * 1e9).round() as i64);
    let mut groups: BTreeMap<OrientationKey, Vec<usize>> = BTreeMap::new();
    for (i, r) in readings.iter().enumerate() {
        groups.entry(key(r)).or_default().push(i);
    }
    let distinct_angles: std::collections::BTreeSet<(i64, i64)> = groups.keys().map(|k| (k.1, k.2)).collect();
    if distinct_angles.len() < 2 {
        let r = &readings[0];
        return Err(HeadError::OneOrientation { n: readings.len(), b_deg: deg(r.b), c_deg: deg(r.c) });
    }
    Ok(groups)
}

/// The closed-form reference points of the orientations, and what the model needs from them.
struct ClosedForm {
    /// Apparent reference point per orientation that determines one.
    apparent: Vec<Apparent>,
    orientations: Vec<Orientation>,
    /// Fitted sphere radius per orientation (sphere references).
    radii: Vec<f64>,
    /// Face ids in order of appearance, with the sum of their outward normals in table
    /// coordinates (vertex references).
    face_ids: Vec<i64>,
    face_normals_sum: Vec<Vector3>,
}

/// The closed-form reference point of every orientation: the algebraic sphere centre, or the
/// intersection of the fitted face planes moved out by the tip radius (orientations that see
/// fewer than three faces give none).
fn closed_form(
    readings: &[Reading],
    raw: &[Point3],
    groups: &BTreeMap<OrientationKey, Vec<usize>>,
    reference: &Reference,
    vertex_tip: f64,
) -> Result<ClosedForm, HeadError> {
    let mut cf = ClosedForm {
        apparent: Vec::new(),
        orientations: Vec::new(),
        radii: Vec::new(),
        face_ids: Vec::new(),
        face_normals_sum: Vec::new(),
    };
    for idx in groups.values() {
        let r0 = &readings[idx[0]];
        let point = match reference {
            Reference::Sphere { .. } => {
                let pts: Vec<Point3> = idx.iter().map(|&i| raw[i]).collect();
                let (c, rad) = sphere_centre(&pts, r0)?;
                cf.radii.push(rad);
                Some(c)
            }
            Reference::Vertex { .. } => vertex_point(readings, raw, idx, vertex_tip, &mut cf)?,
        };
        let Some(point) = point else {
            continue;
        };
        cf.apparent.push(Apparent { b: r0.b, c: r0.c, point });
        cf.orientations.push(Orientation {
            b: r0.b,
            c: r0.c,
            group: r0.group,
            n_points: idx.len(),
            apparent: point,
        });
    }
    if cf.apparent.len() < 2 {
        return Err(HeadError::TooFewVertexOrientations { got: cf.apparent.len() });
    }
    Ok(cf)
}

/// The algebraic sphere through one orientation's points: centre and radius.
fn sphere_centre(pts: &[Point3], r0: &Reading) -> Result<(Point3, f64), HeadError> {
    let (bd, cd) = (deg(r0.b), deg(r0.c));
    if pts.len() < 4 {
        return Err(HeadError::OrientationTooFew {
            b_deg: bd,
            c_deg: cd,
            got: pts.len(),
            needed: 4,
            what: "a sphere fit needs at least 4 points, spread over the sphere",
        });
    }
    algebraic_sphere(pts).ok_or_else(|| HeadError::Degenerate {
        b_deg: bd,
        c_deg: cd,
        what: "the points do not determine a sphere (coplanar or collinear): probe the sphere from more directions"
            .into(),
    })
}

/// One orientation of a vertex reference: fit its face planes, orient their normals outwards
/// (accumulating them per face in `cf`), and intersect the planes moved out by the tip radius
/// when at least three faces are seen.
fn vertex_point(
    readings: &[Reading],
    raw: &[Point3],
    idx: &[usize],
    vertex_tip: f64,
    cf: &mut ClosedForm,
) -> Result<Option<Point3>, HeadError> {
    let r0 = &readings[idx[0]];
    let (bd, cd) = (deg(r0.b), deg(r0.c));
    let mut by_face: BTreeMap<i64, Vec<Point3>> = BTreeMap::new();
    for &i in idx {
        let f = readings[i].face.ok_or(HeadError::MissingFace { index: i })?;
        by_face.entry(f).or_default().push(raw[i]);
    }
    let mut planes: Vec<(i64, Vector3, Point3)> = Vec::new();
    for (f, fp) in &by_face {
        let Some((n, m)) = plane_fit(fp) else {
            return Err(HeadError::Degenerate {
                b_deg: bd,
                c_deg: cd,
                what: format!(
                    "face {f} has {} points that do not span a plane: each face needs at least 3 points, not on \
                     one line",
                    fp.len()
                ),
            });
        };
        planes.push((*f, n, m));
    }
    // Outward normals: at a convex vertex the other faces lie on the inner side.
    for plane in planes.iter_mut() {
        let (f, n, m) = *plane;
        let mut side = 0.0;
        for (g, gp) in &by_face {
            if *g != f {
                side += gp.iter().map(|x| n.dot(&(x - m))).sum::<f64>();
            }
        }
        let nt = rz(-r0.c) * n;
        let known = cf.face_ids.iter().position(|x| *x == f);
        let flip = if side != 0.0 {
            side > 0.0
        } else if let Some(k) = known {
            cf.face_normals_sum[k].dot(&nt) < 0.0
        } else {
            // One face only: it faces the head.
            n.dot(&(ry(r0.b) * Vector3::z())) < 0.0
        };
        let (n, nt) = if flip { (-n, -nt) } else { (n, nt) };
        plane.1 = n;
        match known {
            Some(k) => cf.face_normals_sum[k] += nt,
            None => {
                cf.face_ids.push(f);
                cf.face_normals_sum.push(nt);
            }
        }
    }
    if planes.len() < 3 {
        return Ok(None);
    }
    // The stylus centre runs on the faces moved out by the tip radius.
    let moved: Vec<(Vector3, Point3)> = planes.iter().map(|(_, n, m)| (*n, m - n * vertex_tip)).collect();
    Ok(intersect_planes(&moved, 1e-3))
}

/// The adjustment's model and the starting radius of a sphere (the mean of the orientations'
/// radii when it is not fixed); enough readings for its unknowns.
fn model_of(
    readings: &[Reading],
    params: &Params,
    cf: &ClosedForm,
    vertex_tip: f64,
) -> Result<(Kind, Option<f64>), HeadError> {
    let kind = match params.reference {
        Reference::Sphere { radius } => Kind::Sphere { fixed_radius: radius },
        Reference::Vertex { .. } => {
            let faces = cf
                .face_normals_sum
                .iter()
                .map(|s| {
                    let n0 = s.normalize();
                    let e1 = any_perpendicular(&n0);
                    let e2 = n0.cross(&e1);
                    (n0, e1, e2)
                })
                .collect();
            let face_of = readings
                .iter()
                .map(|r| r.face.and_then(|f| cf.face_ids.iter().position(|x| *x == f)).unwrap_or(0))
                .collect();
            Kind::Vertex { faces, face_of, tip: vertex_tip }
        }
    };
    let radius0 = match params.reference {
        Reference::Sphere { radius: Some(r) } => Some(r),
        Reference::Sphere { radius: None } => Some(cf.radii.iter().sum::<f64>() / cf.radii.len() as f64),
        Reference::Vertex { .. } => None,
    };
    let n_unknowns_all = 3
        + 3
        + match &kind {
            Kind::Sphere { fixed_radius } => usize::from(fixed_radius.is_none()),
            Kind::Vertex { faces, .. } => 2 * faces.len(),
        };
    if readings.len() < n_unknowns_all {
        return Err(HeadError::TooFewPoints { got: readings.len(), needed: n_unknowns_all });
    }
    Ok((kind, radius0))
}

/// The adjustment's start vector: the free offset components, the reference point, then the
/// radius (free sphere) or the face-normal corrections (vertex, zero).
fn start_params(free: &[usize], r: &Vector3, a: &Point3, kind: &Kind, radius0: Option<f64>) -> Vec<f64> {
    let mut p: Vec<f64> = free.iter().map(|&j| r[j]).collect();
    p.extend_from_slice(a.coords.as_slice());
    match kind {
        Kind::Sphere { fixed_radius: None } => p.push(radius0.unwrap_or(1.0)),
        Kind::Sphere { .. } => {}
        Kind::Vertex { faces, .. } => p.extend(std::iter::repeat_n(0.0, 2 * faces.len())),
    }
    p
}

/// Which offset components (and which reference-point components) the data determines.
struct Observability {
    observable: [bool; 3],
    reference_depends_on_prior: [bool; 3],
}

/// Observability from the null space of the full adjustment's normal matrix, linearised at a
/// closed-form start (with the components the linear model cannot see held at the prior).
fn observability(
    pre: &[Pre],
    apparent: &[Apparent],
    kind: &Kind,
    radius0: Option<f64>,
    params: &Params,
) -> Result<Observability, HeadError> {
    let all = [0usize, 1, 2];
    let un = unobservable(&init::linear_normal(apparent), &[(0, 3), (1, 4), (2, 5)]);
    let (a_min, r_min) =
        linear_solve(apparent, &params.table_center, [!un[0], !un[1], !un[2]], &params.prior)
            .ok_or(HeadError::NothingObservable)?;
    let probe = Problem { pre, free: all.to_vec(), prior: params.prior, kind };
    let ne = lsq::normal_equations(&probe, &start_params(&all, &r_min, &a_min, kind, radius0), usize::MAX);
    let un = unobservable(&ne.jtj, &[(0, 0), (1, 1), (2, 2)]);
    let a_null = null_flags(&ne.jtj, &[3, 4, 5]);
    let observable = [!un[0], !un[1], !un[2]];
    if !observable.iter().any(|o| *o) {
        return Err(HeadError::NothingObservable);
    }
    Ok(Observability { observable, reference_depends_on_prior: [a_null[0], a_null[1], a_null[2]] })
}

/// The adjusted offset and reference point with their flags.
struct Solution {
    offset: Vector3,
    u_offset: [Option<f64>; 3],
    reference_point: Point3,
    observable: [bool; 3],
    reference_depends_on_prior: [bool; 3],
    from_tilt: [bool; 3],
}

/// Laser heads whose beam passes through the reference point: `R = s·u`, with `s` from the
/// measured components (`s = Σ u_k R_k / Σ u_k²`, k measured) and its variance from their
/// covariance; the components no rotation reaches follow, flagged `from_tilt`.
fn complete_from_beam(sol: &mut Solution, free: &[usize], beam: &Vector3, covariance: &DMatrix) {
    let su2: f64 = free.iter().map(|&j| beam[j] * beam[j]).sum();
    if su2 <= 1e-6 {
        return;
    }
    let g: Vec<f64> = free.iter().map(|&j| beam[j] / su2).collect();
    let s: f64 = free.iter().zip(&g).map(|(&j, gk)| gk * sol.offset[j]).sum();
    let mut var_s = 0.0;
    for (k, gk) in g.iter().enumerate() {
        for (l, gl) in g.iter().enumerate() {
            var_s += gk * gl * covariance[(k, l)];
        }
    }
    for j in 0..3 {
        if !sol.observable[j] {
            let derived = s * beam[j];
            // What the data fixes along a rotation axis is A_j − R_j: move A with R.
            if sol.reference_depends_on_prior[j] {
                sol.reference_point[j] += derived - sol.offset[j];
                sol.reference_depends_on_prior[j] = false;
            }
            sol.offset[j] = derived;
            sol.u_offset[j] = Some(beam[j].abs() * var_s.max(0.0).sqrt());
            sol.observable[j] = true;
            sol.from_tilt[j] = true;
        }
    }
}

#[cfg(test)]
mod tests;
