//! truepos-fe: a finite-element model of a machine bed (granite or cast-iron plate) on its
//! support pads, used to build influence maps of bed deflection under workpiece loads.
//!
//! Theory: thick (Mindlin-Reissner) plates, because machine beds are 200–400 mm thick and the
//! transverse shear deformation is a few per cent of the bending deflection. Elements: the
//! 4-node MITC4 quadrilateral (Bathe & Dvorkin 1985) — bilinear `w`, `ψx`, `ψy` with the
//! transverse shear strains interpolated from the edge mid-points ("tying points"), which removes
//! shear locking without the spurious zero-energy modes of uniformly reduced integration and
//! without the over-soft behaviour of selective-reduced integration on coarse meshes. See
//! [`element`] for the details.
//!
//! Entry points (the contract of `docs/conventions.md`, "Plate FE API"):
//! - [`Bed`], [`Supports`], [`MeshOptions`]: the model description;
//! - [`PlateModel::new`]: meshes, assembles and factorises (sparse Cholesky, faer) ONCE;
//! - [`PlateModel::solve`] / [`PlateModel::solve_many`] / [`PlateModel::solve_pressure`]:
//!   load cases, reusing the factorisation;
//! - [`Deflection::uz`], [`Deflection::slope`], [`Deflection::reactions`]: results.
//!
//! Forces and pads act over a disc of diameter = thickness on the mid-surface by default
//! ([`ModelOptions`]): Mindlin theory gives an infinite deflection under a true point force, so
//! without this the results would not converge with mesh refinement (docs/performance-fe.md).
//!
//! Units: mm, N, N/mm² (MPa). Loads are `(x, y, force_n)` with force positive DOWNWARDS (a
//! weight); the deflection `uz` is positive UP. The bed origin is the corner (0, 0); bed
//! coordinates are machine X, Y.

#![forbid(unsafe_code)]

pub mod element;
pub mod mesh;
mod model;

pub use mesh::Mesh;
pub use model::{Deflection, ModelOptions, PlateModel};

/// Shear correction factor of the Mindlin-Reissner plate (Reissner's 5/6).
pub const SHEAR_CORRECTION: f64 = 5.0 / 6.0;

/// Errors of the plate model. All user-caused problems are reported here; nothing panics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeError {
    /// A bed parameter is out of range (non-finite, non-positive, Poisson ratio outside
    /// (-1, 0.5)).
    #[error("invalid bed parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        reason: &'static str,
    },
    /// A support point lies outside the bed or is not finite.
    #[error("support {index} at ({x}, {y}) mm lies outside the bed (0..{size_x}, 0..{size_y}) mm")]
    SupportOutsideBed {
        /// 0-based index of the support.
        index: usize,
        /// Its X, mm.
        x: f64,
        /// Its Y, mm.
        y: f64,
        /// Bed size along X, mm.
        size_x: f64,
        /// Bed size along Y, mm.
        size_y: f64,
    },
    /// The supports cannot restrain the rigid-body motion of the plate (fewer than three
    /// non-collinear support points, or non-positive spring stiffness).
    #[error("singular model: {0}")]
    Singular(String),
    /// A load point lies outside the bed or a load is not finite.
    #[error("load {index} at ({x}, {y}) mm with force {force} N lies outside the bed or is not finite")]
    InvalidLoad {
        /// 0-based index of the load.
        index: usize,
        /// Its X, mm.
        x: f64,
        /// Its Y, mm.
        y: f64,
        /// Its force, N.
        force: f64,
    },
    /// The requested mesh would be too large (element size too small for the bed).
    #[error("mesh too large: {nodes} nodes (limit {limit}); increase the element size")]
    MeshTooLarge {
        /// Nodes the mesh would have.
        nodes: usize,
        /// Most nodes allowed.
        limit: usize,
    },
    /// The sparse factorisation failed (numerically singular or out of memory).
    #[error("sparse factorisation failed: {0}")]
    Factorisation(String),
}

/// How the bed is supported.
#[derive(Debug, Clone, PartialEq)]
pub enum Supports {
    /// Point supports on pads at `xy` (mm, bed coordinates). `stiffness_n_per_mm = None`:
    /// rigid pads (the vertical deflection is constrained to zero at the pad); `Some(k)`:
    /// elastic pads, each a vertical spring of stiffness `k` N/mm. Either way at least three
    /// non-collinear pads are needed. The mesh lines are put through every pad; each pad acts
    /// on the mean deflection over a disc of diameter = thickness around it (see
    /// [`ModelOptions`]), a rigid pad holding that mean exactly at zero.
    Points {
        /// Pad positions (x, y), bed coordinates, mm.
        xy: Vec<[f64; 2]>,
        /// Stiffness of each pad, N/mm (`None`: rigid).
        stiffness_n_per_mm: Option<f64>,
    },
    /// All four edges "hard" simply supported: w = 0 and the rotation about the edge normal
    /// (the tangential rotation) = 0, the bending moment normal to the edge free. This is the
    /// support for which the Navier solutions and the Wang-Reddy-Lee Mindlin/Kirchhoff relation
    /// hold exactly (no boundary layer); it is meant for checks against plate theory.
    SimplySupportedEdges,
}

/// The machine bed: a rectangular plate of uniform thickness.
#[derive(Debug, Clone, PartialEq)]
pub struct Bed {
    /// Extent along machine X, mm.
    pub size_x: f64,
    /// Extent along machine Y, mm.
    pub size_y: f64,
    /// Plate thickness, mm.
    pub thickness: f64,
    /// Young's modulus, N/mm² (granite ≈ 4.5e4–6e4, cast iron ≈ 1.1e5–1.3e5).
    pub youngs_modulus: f64,
    /// Poisson ratio (granite ≈ 0.1–0.25, cast iron ≈ 0.26).
    pub poisson: f64,
    /// Supports.
    pub supports: Supports,
}

impl Bed {
    /// Plate bending stiffness D = E h³ / (12 (1 − ν²)), N·mm.
    pub fn flexural_rigidity(&self) -> f64 {
        self.youngs_modulus * self.thickness.powi(3) / (12.0 * (1.0 - self.poisson * self.poisson))
    }

    /// Transverse shear stiffness κ G h with κ = 5/6, N/mm.
    pub fn shear_rigidity(&self) -> f64 {
        SHEAR_CORRECTION * self.youngs_modulus / (2.0 * (1.0 + self.poisson)) * self.thickness
    }
}

/// Meshing options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshOptions {
    /// Target element edge length in mm. `0.0` (the [`Default`]) selects it automatically:
    /// the largest of 1, 2, 2.5, 5 × 10^k not above max(size_x, size_y) / 64 (25 mm for a 2 m
    /// bed; see docs/performance-fe.md for the convergence study behind this choice). Mesh lines
    /// are at multiples of the element size from the origin, plus lines through every support
    /// pad and the far edges, so load grids in multiples of the element size fall on nodes.
    pub element_size: f64,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions { element_size: 0.0 }
    }
}

impl MeshOptions {
    /// Mesh with the given target element size (mm).
    pub fn with_element_size(element_size: f64) -> Self {
        MeshOptions { element_size }
    }
}
