//! Machines as kinematic chains with ISO 230-1 geometric errors ([`crate::errors`]) and thermal
//! scale growth ([`crate::thermal`]).
//!
//! - **Bridge CMM** ([`Machine::bridge_cmm`]): the portal runs along Y on two rails on the bed,
//!   the X carriage along the bridge, the Z ram in the carriage; chain bed → Y → X → Z → probe.
//!   Envelope 1000 × 1500 × 800 mm.
//! - **Vertical machining centre** ([`Machine::vmc`]): chain bed → Y → X → Z (the same
//!   per-axis error definitions), plus a B-axis swivel head about machine Y and a C-axis rotary
//!   table about Z through the table centre, exactly the contract's model
//!   ([`rotary`]: `Q = P + Ry(b)·R`; a table point at `A` for `c = 0` is at `O + Rz(c)·(A − O)`).
//!   [`Machine::head_point`] evaluates the head's measuring point with geometric errors and the
//!   head offset carried through the chain; [`Machine::head_point_on_table`] returns it in the
//!   table frame at `c = 0`. Envelope 800 × 500 × 500 mm.
//! - **Large gantry** ([`Machine::gantry`]): X on the bed rails, Y on the cross-beam, Z ram; chain
//!   bed → X → Y → Z. Envelope 12 000 × 4000 × 2000 mm.
//!
//! Common entry points: [`Machine::realistic`] (a machine of a kind with a seeded realistic error
//! map), [`Machine::tip`] (exact actual tool/tip position), [`Machine::nominal_tip`],
//! [`Machine::first_order_error`], [`Machine::command_for`], [`Machine::with_growth`] /
//! [`Machine::at_time`] (thermal growth); the chain
//! itself is [`chain::SerialChain`].

pub mod chain;
pub mod rotary;

use truepos_math::types::{Point3, Vector3};

pub use chain::SerialChain;
pub use rotary::{
    head_point, head_point_with, head_reference, head_reference_with, RotaryAxisErrors, RotaryTable,
};

use crate::errors::{Axis, ErrorMagnitudes, GeometricErrors};

/// The kinds of machine the virtual cell has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MachineKind {
    /// A bridge CMM.
    BridgeCmm,
    /// A vertical machining centre with a C-axis table.
    Vmc,
    /// A large gantry.
    Gantry,
}

impl MachineKind {
    /// Chain order from the bed to the tool.
    pub fn chain_order(self) -> [Axis; 3] {
        match self {
            MachineKind::BridgeCmm | MachineKind::Vmc => [Axis::Y, Axis::X, Axis::Z],
            MachineKind::Gantry => [Axis::X, Axis::Y, Axis::Z],
        }
    }

    /// Realistic error magnitudes and travels of the kind.
    pub fn magnitudes(self) -> ErrorMagnitudes {
        match self {
            MachineKind::BridgeCmm => ErrorMagnitudes::cmm(),
            MachineKind::Vmc => ErrorMagnitudes::vmc(),
            MachineKind::Gantry => ErrorMagnitudes::gantry(),
        }
    }
}

/// A three-axis machine (with rotary axes for the VMC).
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// What kind of machine it is.
    pub kind: MachineKind,
    /// Axis travels (mm); axis positions run from 0 to the travel.
    pub travel: [f64; 3],
    /// The axes with their errors, from the bed outwards.
    pub chain: SerialChain,
    /// The C-axis rotary table (VMC only).
    pub table: Option<RotaryTable>,
    /// Location errors of the B and C axes (VMC; zero by default).
    pub rotary_errors: RotaryAxisErrors,
}

impl Machine {
    fn with_kind(kind: MachineKind, errors: GeometricErrors) -> Machine {
        Machine {
            kind,
            travel: kind.magnitudes().travel,
            chain: SerialChain::new(kind.chain_order(), errors),
            table: None,
            rotary_errors: RotaryAxisErrors::default(),
        }
    }

    /// Bridge CMM with the given errors.
    pub fn bridge_cmm(errors: GeometricErrors) -> Machine {
        Machine::with_kind(MachineKind::BridgeCmm, errors)
    }

    /// Vertical machining centre with the given errors and the C table turning about the vertical
    /// line through `table_centre`.
    pub fn vmc(errors: GeometricErrors, table_centre: Point3) -> Machine {
        let mut m = Machine::with_kind(MachineKind::Vmc, errors);
        m.table = Some(RotaryTable { centre: table_centre });
        m
    }

    /// Large gantry with the given errors.
    pub fn gantry(errors: GeometricErrors) -> Machine {
        Machine::with_kind(MachineKind::Gantry, errors)
    }

    /// A machine of `kind` with a realistic error map drawn from `seed` (VMC table centre at the
    /// middle of the X/Y travel, z = 0).
    pub fn realistic(kind: MachineKind, seed: u64) -> Machine {
        let mut rng = crate::noise::rng(seed);
        let errors = GeometricErrors::realistic(&mut rng, &kind.magnitudes());
        match kind {
            MachineKind::BridgeCmm => Machine::bridge_cmm(errors),
            MachineKind::Vmc => {
                let t = kind.magnitudes().travel;
                Machine::vmc(errors, Point3::new(0.5 * t[0], 0.5 * t[1], 0.0))
            }
            MachineKind::Gantry => Machine::gantry(errors),
        }
    }

    /// The same machine with thermal scale growth (see [`crate::thermal::ThermalModel`]).
    pub fn with_growth(mut self, growth: [f64; 3], origin: [f64; 3]) -> Machine {
        self.chain.growth = growth;
        self.chain.growth_origin = origin;
        self
    }

    /// The same machine at time `t` of a thermal model: scale growth
    /// [`crate::thermal::ThermalModel::axis_growth`] about the model's scale origins.
    pub fn at_time(self, thermal: &crate::thermal::ThermalModel, t: f64) -> Machine {
        self.with_growth(thermal.axis_growth(t), thermal.origin)
    }

    /// Whether the axis positions are inside the travel (with `margin` mm to spare).
    pub fn in_envelope(&self, axes: &Point3, margin: f64) -> bool {
        (0..3).all(|i| axes[i] >= -margin && axes[i] <= self.travel[i] + margin)
    }

    /// Exact actual tool/tip position (machine coordinates) for axis positions `axes` and tool
    /// offset `tool` (ram frame).
    pub fn tip(&self, axes: &Point3, tool: &Vector3) -> Point3 {
        self.chain.actual(axes, tool)
    }

    /// Nominal tool/tip position `axes + tool`.
    pub fn nominal_tip(&self, axes: &Point3, tool: &Vector3) -> Point3 {
        SerialChain::nominal(axes, tool)
    }

    /// First-order volumetric error of conventions.md.
    pub fn first_order_error(&self, axes: &Point3, tool: &Vector3) -> Vector3 {
        self.chain.first_order_error(axes, tool)
    }

    /// Axis positions that put the tool exactly on `target` (see [`SerialChain::command_for`]).
    pub fn command_for(&self, target: &Point3, tool: &Vector3) -> Option<Point3> {
        self.chain.command_for(target, tool)
    }

    /// VMC head: the actual measuring reference point in machine coordinates when the NC reports
    /// the head reference point at `axes`, the head is swivelled by `b` and has offset `offset`
    /// (head frame at b = 0). With zero errors this is the contract's `P + Ry(b)·R`.
    /// B-axis location errors ([`Machine::rotary_errors`]) turn the offset about the real axis.
    pub fn head_point(&self, axes: &Point3, b: f64, offset: &Vector3) -> Point3 {
        let p0 = Point3::origin();
        let tool = head_point_with(&p0, b, offset, &self.rotary_errors) - p0;
        self.chain.actual(axes, &tool)
    }

    /// VMC head and table: the head's measuring point expressed at its `c = 0` table position
    /// (`O + Rz(−c)·(Q − O)`), i.e. in the coordinates of a part fixed to the table. Without a
    /// table (not a VMC) this equals [`Machine::head_point`].
    pub fn head_point_on_table(&self, axes: &Point3, b: f64, c: f64, offset: &Vector3) -> Point3 {
        let q = self.head_point(axes, b, offset);
        match &self.table {
            Some(t) => {
                // Undo the real table rotation: about the real axis through centre + c_offset.
                let e = &self.rotary_errors;
                let o = t.centre + e.c_offset;
                let back =
                    nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(e.c_axis()), -c);
                o + back * (q - o)
            }
            None => q,
        }
    }
}
