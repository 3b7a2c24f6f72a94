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

/// A support pad mapped onto the mesh.
#[derive(Debug, Clone)]
struct Pad {
    node: usize,
    stiffness: Option<f64>,
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

impl PlateModel {
    /// Validate the bed, mesh it, assemble the stiffness matrix and factorise it (sparse
    /// Cholesky). Fails with [`FeError`] on invalid parameters, pads outside the bed, or supports
    /// that cannot hold the bed (fewer than three non-collinear pads).
    pub fn new(bed: &Bed, mesh_options: &MeshOptions) -> Result<PlateModel, FeError> {
        validate(bed)?;
        let h = if mesh_options.element_size == 0.0 {
            automatic_element_size(bed.size_x.max(bed.size_y))
        } else {
            check_positive("element_size", mesh_options.element_size)?;
            mesh_options.element_size
        };
        let pad_xy: Vec<[f64; 2]> = match &bed.supports {
            Supports::Points { xy, .. } => {
                xy.iter().map(|p| [p[0].clamp(0.0, bed.size_x), p[1].clamp(0.0, bed.size_y)]).collect()
            }
            Supports::SimplySupportedEdges => Vec::new(),
        };
        let mesh = Mesh::build(bed.size_x, bed.size_y, h, &pad_xy)?;
        let n_dof = 3 * mesh.n_nodes();

        // Constraints and pads.
        let mut constrained = vec![false; n_dof];
        let mut pads = Vec::new();
        match &bed.supports {
            Supports::Points { stiffness_n_per_mm, .. } => {
                let tol = 1e-6 * bed.size_x.max(bed.size_y);
                for p in &pad_xy {
                    let node = mesh.node_at(p[0], p[1], tol).ok_or_else(|| {
                        FeError::Singular(format!("internal: pad ({}, {}) not on a node", p[0], p[1]))
                    })?;
                    if stiffness_n_per_mm.is_none() {
                        constrained[3 * node] = true;
                    }
                    pads.push(Pad { node, stiffness: *stiffness_n_per_mm });
                }
            }
            Supports::SimplySupportedEdges => {
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
        }
        let mut eq = vec![FREE_NONE; n_dof];
        let mut n_eq = 0;
        for d in 0..n_dof {
            if !constrained[d] {
                eq[d] = n_eq;
                n_eq += 1;
            }
        }
        let mut reaction_index = vec![FREE_NONE; n_dof];
        let mut reaction_rows: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
        for d in (0..n_dof).step_by(3) {
            if constrained[d] {
                reaction_index[d] = reaction_rows.len();
                reaction_rows.push((d, Vec::new()));
            }
        }

        // Assembly: upper triangle of the free-free block, as (row, col, value) entries.
        let material =
            PlateMaterial { d: bed.flexural_rigidity(), nu: bed.poisson, shear: bed.shear_rigidity() };
        let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(mesh.n_elements() * 78);
        for j in 0..mesh.ny() - 1 {
            for i in 0..mesh.nx() - 1 {
                let lx = mesh.xs[i + 1] - mesh.xs[i];
                let ly = mesh.ys[j + 1] - mesh.ys[j];
                let ke = element::stiffness(lx, ly, &material);
                let nodes = mesh.element_nodes(i, j);
                let dofs: [usize; 12] = std::array::from_fn(|k| 3 * nodes[k / 3] + k % 3);
                for r in 0..12 {
                    let (dr, er) = (dofs[r], eq[dofs[r]]);
                    for c in 0..12 {
                        let dc = dofs[c];
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
        for pad in &pads {
            if let Some(k) = pad.stiffness {
                let e = eq[3 * pad.node];
                entries.push((e, e, k));
            }
        }
        if n_eq == 0 {
            return Err(FeError::Singular("no free degrees of freedom".into()));
        }
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
        let llt = k.sp_cholesky(Side::Upper).map_err(|e| match e {
            faer::sparse::linalg::LltError::Numeric(_) => FeError::Singular(
                "the stiffness matrix is not positive definite: the supports cannot hold the bed".into(),
            ),
            other => FeError::Factorisation(format!("{other:?}")),
        })?;
        for row in &mut reaction_rows {
            row.1.sort_unstable_by_key(|&(d, _)| d);
            let mut merged: Vec<(usize, f64)> = Vec::with_capacity(row.1.len());
            for &(d, v) in &row.1 {
                match merged.last_mut() {
                    Some(m) if m.0 == d => m.1 += v,
                    _ => merged.push((d, v)),
                }
            }
            row.1 = merged;
        }
        Ok(PlateModel { bed: bed.clone(), mesh: Arc::new(mesh), eq, n_eq, llt, pads, reaction_rows })
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

    /// Consistent nodal load vector (full DOF numbering) of point loads: each force is
    /// distributed to the deflection DOFs of the four nodes of the element holding it with the
    /// element's bilinear shape functions (the work-equivalent loads).
    fn load_vector(&self, loads: &[(f64, f64, f64)], f: &mut [f64]) -> Result<(), FeError> {
        for (index, &(x, y, force)) in loads.iter().enumerate() {
            let bad = FeError::InvalidLoad { index, x, y, force };
            if !force.is_finite() {
                return Err(bad);
            }
            let loc = self.mesh.locate(x, y).ok_or(bad)?;
            let n = element::shape(loc.xi, loc.eta);
            let nodes = self.mesh.element_nodes(loc.i, loc.j);
            for k in 0..4 {
                f[3 * nodes[k]] += force * n[k];
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
                let u: Vec<f64> =
                    self.eq.iter().map(|&e| if e != FREE_NONE { rhs[(e, c)] } else { 0.0 }).collect();
                self.deflection(u, &f)
            })
            .collect()
    }

    fn deflection(&self, u: Vec<f64>, f: &[f64]) -> Deflection {
        // Upward reactions at constrained deflection DOFs: r_up = f − (K u).
        let mut node_reaction = std::collections::HashMap::new();
        let mut total = 0.0;
        for (d, row) in &self.reaction_rows {
            let ku: f64 = row.iter().map(|&(j, v)| v * u[j]).sum();
            let r = f[*d] - ku;
            total += r;
            node_reaction.insert(d / 3, r);
        }
        // Pads: rigid share their node's reaction equally among coincident pads; springs k·w.
        let mut reactions = Vec::with_capacity(self.pads.len());
        for pad in &self.pads {
            match pad.stiffness {
                None => {
                    let share = self.pads.iter().filter(|p| p.node == pad.node).count() as f64;
                    reactions.push(node_reaction.get(&pad.node).copied().unwrap_or(0.0) / share);
                }
                Some(k) => {
                    let r = k * u[3 * pad.node];
                    total += r;
                    reactions.push(r);
                }
            }
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
