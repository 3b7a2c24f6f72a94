//! The assembled and factorised plate model, and the deflection fields it produces.
//!
//! Entry points: [`PlateModel::new`] (validate, mesh, assemble into a faer sparse matrix,
//! sparse Cholesky LLᵀ once), [`PlateModel::solve`], [`PlateModel::solve_many`] (batches, in
//! parallel with rayon, several right-hand sides per triangular sweep),
//! [`PlateModel::solve_pressure`], and [`Deflection`] (`uz`, `slope`, `reactions`).
//!
//! Boundary conditions are imposed by elimination: constrained DOFs are dropped from the
//! system; the rows of the full stiffness matrix at constrained deflection DOFs are kept to
//! recover the support reactions. Elastic pads add their stiffness to the diagonal.

use std::sync::Arc;

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use rayon::prelude::*;

use crate::element::{self, PlateMaterial};
use crate::mesh::{automatic_element_size, Mesh};
use crate::{Bed, FeError, MeshOptions, Supports};

const FREE_NONE: usize = usize::MAX;

/// A support pad mapped onto the mesh: the consistent nodal weights (summing to 1) of a uniform
/// distribution over its footprint; the pad acts on the weighted mean deflection `cᵀw`.
#[derive(Debug, Clone)]
struct Pad {
    weights: Vec<(usize, f64)>,
    stiffness: Option<f64>,
    /// Index of this pad's rigid constraint (coincident rigid pads share one), if rigid.
    constraint: Option<usize>,
}

/// Exact rigid-pad constraints cᵀw = 0, imposed on the spring-supported system K_s by the
/// Schur complement: u = u₀ − Z λ, S λ = Cᵀu₀, with Z = K_s⁻¹C and S = CᵀZ.
#[derive(Debug)]
struct RigidPads {
    /// Weight vectors c (equation numbering), one per constraint.
    c: Vec<Vec<(usize, f64)>>,
    /// Z = K_s⁻¹ C, n_eq × m.
    z: Mat<f64>,
    /// Cholesky factor of S = CᵀZ.
    s_chol: nalgebra::Cholesky<f64, nalgebra::Dyn>,
}

/// Options of the model beyond the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModelOptions {
    /// Diameter (mm) of the disc over which each point load is spread on the mid-surface.
    /// `None` (default): the plate thickness — a force on the top surface spreads at 45°
    /// through the half-thickness. `Some(0.0)`: a true point load (consistent nodal loads of
    /// the point itself). See [`PlateModel::with_options`] for why.
    pub load_patch_diameter: Option<f64>,
    /// Diameter (mm) of the support pads' footprint; `None` (default): the plate thickness;
    /// `Some(0.0)`: a support at the single node.
    pub pad_diameter: Option<f64>,
}

/// A bed model meshed, assembled and factorised once; solve any number of load cases with it.
#[derive(Debug)]
pub struct PlateModel {
    bed: Bed,
    mesh: Arc<Mesh>,
    /// DOF (3 per node: w, ψx, ψy) → equation number, or `FREE_NONE` if constrained.
    eq: Vec<usize>,
    n_eq: usize,
    llt: Llt<usize, f64>,
    pads: Vec<Pad>,
    rigid: Option<RigidPads>,
    load_radius: f64,
    /// For every constrained deflection DOF: (dof, row of the full stiffness matrix as
    /// (dof, value) pairs), to recover reactions.
    reaction_rows: Vec<(usize, Vec<(usize, f64)>)>,
}

/// The deflection field of one load case.
#[derive(Debug, Clone)]
pub struct Deflection {
    mesh: Arc<Mesh>,
    /// Full DOF vector (w positive DOWN, ψ), 3 per node.
    u: Vec<f64>,
    /// Upward reaction of each support pad (N), in the order of `Supports::Points::xy`.
    reactions: Vec<f64>,
    /// Sum of all upward support reactions (pads or edges), N.
    total_reaction: f64,
}

fn check_positive(name: &'static str, value: f64) -> Result<(), FeError> {
    if !value.is_finite() || value <= 0.0 {
        return Err(FeError::InvalidParameter { name, value, reason: "must be finite and > 0" });
    }
    Ok(())
}

fn validate(bed: &Bed) -> Result<(), FeError> {
    check_positive("size_x", bed.size_x)?;
    check_positive("size_y", bed.size_y)?;
    check_positive("thickness", bed.thickness)?;
    check_positive("youngs_modulus", bed.youngs_modulus)?;
    if !bed.poisson.is_finite() || bed.poisson <= -1.0 || bed.poisson >= 0.5 {
        return Err(FeError::InvalidParameter {
            name: "poisson",
            value: bed.poisson,
            reason: "must lie in (-1, 0.5)",
        });
    }
    if let Supports::Points { xy, stiffness_n_per_mm } = &bed.supports {
        let tol = 1e-9 * bed.size_x.max(bed.size_y);
        for (index, p) in xy.iter().enumerate() {
            let (x, y) = (p[0], p[1]);
            let inside = x.is_finite()
                && y.is_finite()
                && x >= -tol
                && y >= -tol
                && x <= bed.size_x + tol
                && y <= bed.size_y + tol;
            if !inside {
                return Err(FeError::SupportOutsideBed {
                    index,
                    x,
                    y,
                    size_x: bed.size_x,
                    size_y: bed.size_y,
                });
            }
        }
        if let Some(k) = stiffness_n_per_mm {
            if !k.is_finite() || *k <= 0.0 {
                return Err(FeError::Singular(format!(
                    "pad stiffness {k} N/mm must be finite and > 0 (use None for rigid pads)"
                )));
            }
        }
        // At least three non-collinear pads: the smaller principal spread of the pad
        // positions must be non-negligible against the bed size.
        if xy.len() < 3 {
            return Err(FeError::Singular(format!(
                "{} support pad(s): at least three non-collinear pads are needed to hold the bed",
                xy.len()
            )));
        }
        let n = xy.len() as f64;
        let (mx, my) = (xy.iter().map(|p| p[0]).sum::<f64>() / n, xy.iter().map(|p| p[1]).sum::<f64>() / n);
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for p in xy {
            let (dx, dy) = (p[0] - mx, p[1] - my);
            sxx += dx * dx;
            syy += dy * dy;
            sxy += dx * dy;
        }
        let tr = sxx + syy;
        let lmin = 0.5 * (tr - ((sxx - syy).powi(2) + 4.0 * sxy * sxy).sqrt());
        let scale = bed.size_x.max(bed.size_y);
        if lmin.max(0.0).sqrt() <= 1e-6 * scale {
            return Err(FeError::Singular(
                "all support pads lie on one line: the bed could rotate about it".into(),
            ));
        }
    }
    Ok(())
}

/// Consistent nodal weights (summing to 1) of a unit force spread uniformly over a disc of
/// radius `r` centred at (x, y). Near an edge the disc is squeezed into an ellipse whose
/// semi-axis across that edge is the distance to it, so the resultant stays exactly at (x, y)
/// (on an edge the patch becomes a short line load along the edge, which still has a finite
/// Mindlin deflection; only at a corner does it degenerate to a point). The patch is sampled
/// with a symmetric midpoint grid (spacing ≤ element size / 3), each sample distributed with
/// the bilinear shape functions of its element; bilinear interpolation reproduces linear
/// fields, so the weights' first moments equal (x, y) exactly.
fn patch_weights(mesh: &Mesh, x: f64, y: f64, r: f64, h: f64) -> Option<Vec<(usize, f64)>> {
    let size_x = *mesh.xs.last()?;
    let size_y = *mesh.ys.last()?;
    let rx = r.min(x).min(size_x - x).max(0.0);
    let ry = r.min(y).min(size_y - y).max(0.0);
    let mut samples: Vec<(f64, f64)> = Vec::new();
    if rx.max(ry) > 1e-9 * size_x.max(size_y) {
        let n = ((rx.max(ry) / (h / 3.0)).ceil() as usize).clamp(4, 64);
        for i in 0..2 * n {
            for j in 0..2 * n {
                let u = (i as f64 - n as f64 + 0.5) / n as f64;
                let v = (j as f64 - n as f64 + 0.5) / n as f64;
                if u * u + v * v <= 1.0 {
                    samples.push((x + u * rx, y + v * ry));
                }
            }
        }
    }
    if samples.is_empty() {
        samples.push((x, y));
    }
    let wt = 1.0 / samples.len() as f64;
    let mut acc: Vec<(usize, f64)> = Vec::with_capacity(4 * samples.len());
    for (sx, sy) in samples {
        let loc = mesh.locate(sx, sy)?;
        let n = element::shape(loc.xi, loc.eta);
        for (k, node) in mesh.element_nodes(loc.i, loc.j).into_iter().enumerate() {
            if n[k] != 0.0 {
                acc.push((node, wt * n[k]));
            }
        }
    }
    acc.sort_unstable_by_key(|a| a.0);
    let mut out: Vec<(usize, f64)> = Vec::with_capacity(acc.len() / 2);
    for (node, w) in acc {
        match out.last_mut() {
            Some(o) if o.0 == node => o.1 += w,
            _ => out.push((node, w)),
        }
    }
    Some(out)
}

fn diameter(name: &'static str, value: Option<f64>, default: f64) -> Result<f64, FeError> {
    match value {
        None => Ok(default),
        Some(d) if d.is_finite() && d >= 0.0 => Ok(d),
        Some(d) => Err(FeError::InvalidParameter { name, value: d, reason: "must be finite and >= 0" }),
    }
}

/// Equation numbers of the degrees of freedom (3 per node: w, ψx, ψy): `FREE_NONE` for a
/// constrained one (simply supported edges), and the reaction row of each constrained w.
struct Dofs {
    eq: Vec<usize>,
    n_eq: usize,
    reaction_index: Vec<usize>,
    n_reactions: usize,
}

impl Dofs {
    fn number(bed: &Bed, mesh: &Mesh) -> Result<Dofs, FeError> {
        let n_dof = 3 * mesh.n_nodes();
        let mut constrained = vec![false; n_dof];
        if let Supports::SimplySupportedEdges = bed.supports {
            // Hard simple support: w = 0 and the tangential rotation = 0 on each edge.
            let (nx, ny) = (mesh.nx(), mesh.ny());
            for j in 0..ny {
                for i in 0..nx {
                    let n = mesh.node_index(i, j);
                    if i == 0 || i == nx - 1 {
                        constrained[3 * n] = true;
                        constrained[3 * n + 2] = true; // ψy along the edge x = const
                    }
                    if j == 0 || j == ny - 1 {
                        constrained[3 * n] = true;
                        constrained[3 * n + 1] = true; // ψx along the edge y = const
                    }
                }
            }
        }
        let mut eq = vec![FREE_NONE; n_dof];
        let mut n_eq = 0;
        for d in 0..n_dof {
            if !constrained[d] {
                eq[d] = n_eq;
                n_eq += 1;
            }
        }
        if n_eq == 0 {
            return Err(FeError::Singular("no free degrees of freedom".into()));
        }
        let mut reaction_index = vec![FREE_NONE; n_dof];
        let mut n_reactions = 0;
        for d in (0..n_dof).step_by(3) {
            if constrained[d] {
                reaction_index[d] = n_reactions;
                n_reactions += 1;
            }
        }
        Ok(Dofs { eq, n_eq, reaction_index, n_reactions })
    }
}

/// The pads with their footprint weights; rigid pads get a constraint each (coincident ones
/// share). Returns the pads and the number of rigid constraints.
fn pads(
    bed: &Bed,
    mesh: &Mesh,
    pad_xy: &[[f64; 2]],
    pad_radius: f64,
    h: f64,
) -> Result<(Vec<Pad>, usize), FeError> {
    let mut pads: Vec<Pad> = Vec::new();
    let mut constraint_centres: Vec<[f64; 2]> = Vec::new();
    if let Supports::Points { stiffness_n_per_mm, .. } = &bed.supports {
        let tol = 1e-6 * bed.size_x.max(bed.size_y);
        for p in pad_xy {
            let weights = patch_weights(mesh, p[0], p[1], pad_radius, h).ok_or_else(|| {
                FeError::Singular(format!("internal: pad ({}, {}) not on the mesh", p[0], p[1]))
            })?;
            let constraint = if stiffness_n_per_mm.is_none() {
                let found = constraint_centres
                    .iter()
                    .position(|c| (c[0] - p[0]).abs() <= tol && (c[1] - p[1]).abs() <= tol);
                Some(found.unwrap_or_else(|| {
                    constraint_centres.push(*p);
                    constraint_centres.len() - 1
                }))
            } else {
                None
            };
            pads.push(Pad { weights, stiffness: *stiffness_n_per_mm, constraint });
        }
    }
    Ok((pads, constraint_centres.len()))
}

/// A reaction row: the constrained w and its (dof, stiffness) entries.
type ReactionRow = (usize, Vec<(usize, f64)>);

/// Assembly: the upper triangle of the free-free block as (row, col, value) entries (element
/// stiffnesses and the pad springs, `k_aux` for rigid pads), and the rows of the constrained
/// w for the reactions (entries not yet merged).
fn assemble(
    mesh: &Mesh,
    material: &PlateMaterial,
    dofs: &Dofs,
    pads: &[Pad],
    k_aux: f64,
) -> (Vec<(usize, usize, f64)>, Vec<ReactionRow>) {
    let (eq, reaction_index) = (&dofs.eq, &dofs.reaction_index);
    let mut reaction_rows: Vec<ReactionRow> = Vec::with_capacity(dofs.n_reactions);
    for (d, &r) in reaction_index.iter().enumerate() {
        if r != FREE_NONE {
            reaction_rows.push((d, Vec::new()));
        }
    }
    let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(mesh.n_elements() * 78);
    for j in 0..mesh.ny() - 1 {
        for i in 0..mesh.nx() - 1 {
            let lx = mesh.xs[i + 1] - mesh.xs[i];
            let ly = mesh.ys[j + 1] - mesh.ys[j];
            let ke = element::stiffness(lx, ly, material);
            let nodes = mesh.element_nodes(i, j);
            let el_dofs: [usize; 12] = std::array::from_fn(|k| 3 * nodes[k / 3] + k % 3);
            for r in 0..12 {
                let (dr, er) = (el_dofs[r], eq[el_dofs[r]]);
                for c in 0..12 {
                    let dc = el_dofs[c];
                    let ec = eq[dc];
                    if er != FREE_NONE && ec != FREE_NONE && er <= ec {
                        entries.push((er, ec, ke[r][c]));
                    }
                    if reaction_index[dr] != FREE_NONE {
                        reaction_rows[reaction_index[dr]].1.push((dc, ke[r][c]));
                    }
                }
            }
        }
    }
    for pad in pads {
        let k = pad.stiffness.unwrap_or(k_aux);
        for &(na, wa) in &pad.weights {
            for &(nb, wb) in &pad.weights {
                let (ea, eb) = (eq[3 * na], eq[3 * nb]);
                if ea <= eb {
                    entries.push((ea, eb, k * wa * wb));
                }
            }
        }
    }
    (entries, reaction_rows)
}

/// The sparse Cholesky factor of the assembled entries (duplicates summed).
fn factorise(mut entries: Vec<(usize, usize, f64)>, n_eq: usize) -> Result<Llt<usize, f64>, FeError> {
    // Merge duplicates (sorted by column then row).
    entries.sort_unstable_by_key(|&(r, c, _)| (c, r));
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::with_capacity(entries.len() / 3);
    for (r, c, v) in entries {
        match triplets.last_mut() {
            Some(t) if t.row == r && t.col == c => t.val += v,
            _ => triplets.push(Triplet::new(r, c, v)),
        }
    }
    let k = SparseColMat::<usize, f64>::try_new_from_triplets(n_eq, n_eq, &triplets)
        .map_err(|e| FeError::Factorisation(format!("{e:?}")))?;
    k.sp_cholesky(Side::Upper).map_err(|e| match e {
        faer::sparse::linalg::LltError::Numeric(_) => FeError::Singular(
            "the stiffness matrix is not positive definite: the supports cannot hold the bed".into(),
        ),
        other => FeError::Factorisation(format!("{other:?}")),
    })
}

/// Sort (dof, value) entries by dof and sum the duplicates.
fn merge_sorted(row: &mut Vec<(usize, f64)>) {
    row.sort_unstable_by_key(|&(d, _)| d);
    let mut merged: Vec<(usize, f64)> = Vec::with_capacity(row.len());
    for &(d, v) in row.iter() {
        match merged.last_mut() {
            Some(m) if m.0 == d => m.1 += v,
            _ => merged.push((d, v)),
        }
    }
    *row = merged;
}

/// Rigid pads: Z = K_s⁻¹ C and the Cholesky factor of S = CᵀZ (none without rigid pads).
fn rigid_pads(
    pads: &[Pad],
    m: usize,
    dofs: &Dofs,
    llt: &Llt<usize, f64>,
) -> Result<Option<RigidPads>, FeError> {
    if m == 0 {
        return Ok(None);
    }
    let mut c: Vec<Vec<(usize, f64)>> = vec![Vec::new(); m];
    for pad in pads {
        if let Some(ci) = pad.constraint {
            if c[ci].is_empty() {
                c[ci] = pad.weights.iter().map(|&(n, w)| (dofs.eq[3 * n], w)).collect();
            }
        }
    }
    let mut z = Mat::<f64>::zeros(dofs.n_eq, m);
    for (ci, cv) in c.iter().enumerate() {
        for &(e, w) in cv {
            z[(e, ci)] = w;
        }
    }
    llt.solve_in_place(z.as_mut());
    let s = nalgebra::DMatrix::from_fn(m, m, |a, b| c[a].iter().map(|&(e, w)| w * z[(e, b)]).sum());
    let s = 0.5 * (&s + s.transpose());
    let s_chol = nalgebra::Cholesky::new(s)
        .ok_or_else(|| FeError::Singular("the rigid pads' constraints are dependent".into()))?;
    Ok(Some(RigidPads { c, z, s_chol }))
}

impl PlateModel {
    /// Validate the bed, mesh it, assemble the stiffness matrix and factorise it (sparse
    /// Cholesky), with the default [`ModelOptions`] (loads and pads spread over a disc of
    /// diameter = thickness). Fails with [`FeError`] on invalid parameters, pads outside the
    /// bed, or supports that cannot hold the bed (fewer than three non-collinear pads).
    pub fn new(bed: &Bed, mesh_options: &MeshOptions) -> Result<PlateModel, FeError> {
        Self::with_options(bed, mesh_options, &ModelOptions::default())
    }

    /// [`PlateModel::new`] with explicit [`ModelOptions`].
    ///
    /// Why loads and pads are spread over a footprint: in Mindlin-Reissner theory the
    /// deflection under a concentrated force is logarithmically infinite (the shear part
    /// w_s = P/(2π κGh)·ln(1/r)), so a true point load or a rigid point support makes the
    /// local deflection grow without bound as the mesh is refined (by P/(2π κGh)·ln 2 per
    /// halving, ~3e-5 mm for 1 kN on a 250 mm granite bed — the size of the whole influence
    /// signal). Real forces act through a contact area and reach the mid-surface spread at
    /// ~45° over the half-thickness, so each force is applied as a uniform pressure on a disc
    /// of diameter = thickness by default, and each pad acts on the mean deflection over such a
    /// disc. The results then converge at the element's O(h²) rate.
    ///
    /// Rigid pads are imposed exactly (constraint cᵀw = 0 on the pad's mean deflection, through
    /// a Schur complement on top of auxiliary springs; see `RigidPads`), elastic pads as
    /// springs on that mean deflection.
    pub fn with_options(
        bed: &Bed,
        mesh_options: &MeshOptions,
        options: &ModelOptions,
    ) -> Result<PlateModel, FeError> {
        validate(bed)?;
        let h = if mesh_options.element_size == 0.0 {
            automatic_element_size(bed.size_x.max(bed.size_y))
        } else {
            check_positive("element_size", mesh_options.element_size)?;
            mesh_options.element_size
        };
        let load_radius = 0.5 * diameter("load_patch_diameter", options.load_patch_diameter, bed.thickness)?;
        let pad_radius = 0.5 * diameter("pad_diameter", options.pad_diameter, bed.thickness)?;
        let pad_xy: Vec<[f64; 2]> = match &bed.supports {
            Supports::Points { xy, .. } => {
                xy.iter().map(|p| [p[0].clamp(0.0, bed.size_x), p[1].clamp(0.0, bed.size_y)]).collect()
            }
            Supports::SimplySupportedEdges => Vec::new(),
        };
        let mesh = Mesh::build(bed.size_x, bed.size_y, h, &pad_xy)?;
        let dofs = Dofs::number(bed, &mesh)?;
        let material =
            PlateMaterial { d: bed.flexural_rigidity(), nu: bed.poisson, shear: bed.shear_rigidity() };
        let (pads, n_constraints) = pads(bed, &mesh, &pad_xy, pad_radius, h)?;
        // Auxiliary spring of rigid pads (its force vanishes once the constraint holds; it only
        // makes K_s positive definite): of the order of the plate's own point stiffness.
        let k_aux = 16.0 * material.d / (bed.size_x * bed.size_y);
        let (entries, mut reaction_rows) = assemble(&mesh, &material, &dofs, &pads, k_aux);
        let llt = factorise(entries, dofs.n_eq)?;
        for row in &mut reaction_rows {
            merge_sorted(&mut row.1);
        }
        let rigid = rigid_pads(&pads, n_constraints, &dofs, &llt)?;
        let Dofs { eq, n_eq, .. } = dofs;
        Ok(PlateModel {
            bed: bed.clone(),
            mesh: Arc::new(mesh),
            eq,
            n_eq,
            llt,
            pads,
            rigid,
            load_radius,
            reaction_rows,
        })
    }

    /// The bed this model was built from.
    pub fn bed(&self) -> &Bed {
        &self.bed
    }

    /// The mesh.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Number of free degrees of freedom (size of the factorised system).
    pub fn n_equations(&self) -> usize {
        self.n_eq
    }

    /// Target element size used (mm).
    fn element_size(&self) -> f64 {
        let m = &self.mesh;
        let dx = m.xs.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        let dy = m.ys.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        dx.max(dy)
    }

    /// Consistent nodal load vector (full DOF numbering) of point loads: each force is spread
    /// over its load patch (see [`ModelOptions`]) and distributed to the deflection DOFs with the
    /// elements' bilinear shape functions (work-equivalent loads).
    fn load_vector(&self, loads: &[(f64, f64, f64)], f: &mut [f64]) -> Result<(), FeError> {
        let h = self.element_size();
        for (index, &(x, y, force)) in loads.iter().enumerate() {
            let bad = FeError::InvalidLoad { index, x, y, force };
            if !force.is_finite() {
                return Err(bad);
            }
            self.mesh.locate(x, y).ok_or(bad.clone())?;
            let size_x = self.bed.size_x;
            let size_y = self.bed.size_y;
            let (xc, yc) = (x.clamp(0.0, size_x), y.clamp(0.0, size_y));
            let weights = patch_weights(&self.mesh, xc, yc, self.load_radius, h).ok_or(bad)?;
            for (node, w) in weights {
                f[3 * node] += force * w;
            }
        }
        Ok(())
    }

    /// Solve one load case: point loads `(x, y, force_n)`, force positive DOWNWARDS.
    pub fn solve(&self, loads: &[(f64, f64, f64)]) -> Result<Deflection, FeError> {
        let mut f = vec![0.0; self.eq.len()];
        self.load_vector(loads, &mut f)?;
        Ok(self.solve_load_vectors(vec![f]).pop().expect("one case in, one out"))
    }

    /// Uniform pressure `p` (N/mm², positive downwards) over the whole bed, plus optional
    /// point loads. Consistent nodal loads p·lx·ly/4 per element node.
    pub fn solve_pressure(&self, pressure: f64, loads: &[(f64, f64, f64)]) -> Result<Deflection, FeError> {
        if !pressure.is_finite() {
            return Err(FeError::InvalidParameter {
                name: "pressure",
                value: pressure,
                reason: "must be finite",
            });
        }
        let mut f = vec![0.0; self.eq.len()];
        let m = &self.mesh;
        for j in 0..m.ny() - 1 {
            for i in 0..m.nx() - 1 {
                let q = pressure * (m.xs[i + 1] - m.xs[i]) * (m.ys[j + 1] - m.ys[j]) / 4.0;
                for n in m.element_nodes(i, j) {
                    f[3 * n] += q;
                }
            }
        }
        self.load_vector(loads, &mut f)?;
        Ok(self.solve_load_vectors(vec![f]).pop().expect("one case in, one out"))
    }

    /// Solve many load cases (each a list of point loads) with the one factorisation, in
    /// parallel (rayon) and several right-hand sides per triangular sweep.
    pub fn solve_many<L: AsRef<[(f64, f64, f64)]> + Sync>(
        &self,
        cases: &[L],
    ) -> Result<Vec<Deflection>, FeError> {
        const BLOCK: usize = 16;
        let blocks: Vec<Result<Vec<Deflection>, FeError>> = cases
            .par_chunks(BLOCK)
            .map(|chunk| {
                let mut fs = Vec::with_capacity(chunk.len());
                for case in chunk {
                    let mut f = vec![0.0; self.eq.len()];
                    self.load_vector(case.as_ref(), &mut f)?;
                    fs.push(f);
                }
                Ok(self.solve_load_vectors(fs))
            })
            .collect();
        let mut out = Vec::with_capacity(cases.len());
        for b in blocks {
            out.extend(b?);
        }
        Ok(out)
    }

    /// Solve for full-numbering load vectors, returning the deflections with reactions.
    fn solve_load_vectors(&self, fs: Vec<Vec<f64>>) -> Vec<Deflection> {
        let mut rhs = Mat::<f64>::zeros(self.n_eq, fs.len());
        for (c, f) in fs.iter().enumerate() {
            for (d, &e) in self.eq.iter().enumerate() {
                if e != FREE_NONE {
                    rhs[(e, c)] = f[d];
                }
            }
        }
        self.llt.solve_in_place(rhs.as_mut());
        fs.into_iter()
            .enumerate()
            .map(|(c, f)| {
                // Rigid pads: λ = S⁻¹ Cᵀ u₀, u = u₀ − Z λ; λ are the pads' upward reactions.
                let lambda = self.rigid.as_ref().map(|rp| {
                    let g = nalgebra::DVector::from_iterator(
                        rp.c.len(),
                        rp.c.iter().map(|cv| cv.iter().map(|&(e, w)| w * rhs[(e, c)]).sum::<f64>()),
                    );
                    rp.s_chol.solve(&g)
                });
                let u: Vec<f64> = self
                    .eq
                    .iter()
                    .map(|&e| {
                        if e == FREE_NONE {
                            return 0.0;
                        }
                        let mut v = rhs[(e, c)];
                        if let (Some(rp), Some(l)) = (&self.rigid, &lambda) {
                            for k in 0..l.len() {
                                v -= rp.z[(e, k)] * l[k];
                            }
                        }
                        v
                    })
                    .collect();
                self.deflection(u, &f, lambda.as_ref())
            })
            .collect()
    }

    fn deflection(&self, u: Vec<f64>, f: &[f64], lambda: Option<&nalgebra::DVector<f64>>) -> Deflection {
        // Upward reactions at eliminated deflection DOFs (edges): r_up = f − (K u).
        let mut total = 0.0;
        for (d, row) in &self.reaction_rows {
            let ku: f64 = row.iter().map(|&(j, v)| v * u[j]).sum();
            total += f[*d] - ku;
        }
        // Pads: rigid ones carry their constraint's λ (shared equally among coincident pads),
        // elastic ones k·cᵀw.
        let mut reactions = Vec::with_capacity(self.pads.len());
        for pad in &self.pads {
            let mean_w: f64 = pad.weights.iter().map(|&(n, w)| w * u[3 * n]).sum();
            let r = match (pad.constraint, lambda) {
                (Some(ci), Some(l)) => {
                    let share = self.pads.iter().filter(|p| p.constraint == Some(ci)).count();
                    l[ci] / share as f64
                }
                _ => pad.stiffness.unwrap_or(0.0) * mean_w,
            };
            total += r;
            reactions.push(r);
        }
        Deflection { mesh: Arc::clone(&self.mesh), u, reactions, total_reaction: total }
    }
}

impl Deflection {
    /// Vertical deflection at (x, y), mm, positive UP, interpolated with the element's bilinear
    /// shape functions. NaN if (x, y) is outside the bed or not finite (use
    /// [`Deflection::try_uz`] to get `None` instead).
    pub fn uz(&self, x: f64, y: f64) -> f64 {
        self.try_uz(x, y).unwrap_or(f64::NAN)
    }

    /// [`Deflection::uz`], `None` outside the bed.
    pub fn try_uz(&self, x: f64, y: f64) -> Option<f64> {
        let loc = self.mesh.locate(x, y)?;
        let n = element::shape(loc.xi, loc.eta);
        let nodes = self.mesh.element_nodes(loc.i, loc.j);
        Some(-(0..4).map(|k| n[k] * self.u[3 * nodes[k]]).sum::<f64>())
    }

    /// Slope of the bed (rad) at (x, y): (∂uz/∂x, ∂uz/∂y) taken from the interpolated rotation
    /// of the plate's normal (continuous across elements; equals the slope of the mid-surface
    /// up to the transverse shear strain). NaN outside the bed.
    pub fn slope(&self, x: f64, y: f64) -> [f64; 2] {
        let Some(loc) = self.mesh.locate(x, y) else { return [f64::NAN; 2] };
        let n = element::shape(loc.xi, loc.eta);
        let nodes = self.mesh.element_nodes(loc.i, loc.j);
        let sx: f64 = (0..4).map(|k| n[k] * self.u[3 * nodes[k] + 1]).sum();
        let sy: f64 = (0..4).map(|k| n[k] * self.u[3 * nodes[k] + 2]).sum();
        [-sx, -sy]
    }

    /// Nodal deflection (mm, positive up) of node `n` of the mesh; NaN if out of range.
    pub fn nodal_uz(&self, n: usize) -> f64 {
        self.u.get(3 * n).map_or(f64::NAN, |w| -w)
    }

    /// Upward reaction (N) of each support pad, in the order of `Supports::Points::xy`
    /// (empty for simply supported edges).
    pub fn reactions(&self) -> &[f64] {
        &self.reactions
    }

    /// Sum of all upward support reactions (pads or edge supports), N. Equals the total
    /// applied load by equilibrium.
    pub fn total_reaction(&self) -> f64 {
        self.total_reaction
    }

    /// The mesh the field lives on.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }
}
