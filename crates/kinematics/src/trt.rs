//! `xyzbc-trt`: LinuxCNC's `xyzbc-trt-kins`, a B tilting table carrying a C rotary table, and
//! where its controller reports a sphere fixed on the table when the configured geometry differs
//! from the machine's true one.
//!
//! Geometry ([`TrtGeometry`], the module's pins, mm): `r = (x-rot-point, y-rot-point,
//! z-rot-point)`, `d = (x-offset, 0, z-offset)`. At B = 0 the C axis is the vertical line
//! through `(r.x, r.y)`; the B axis is parallel to machine Y through `X = r.x + d.x`,
//! `Z = r.z + d.z`. Positive B and C turn the table right-handed about +Y and +Z. `w` is the
//! programme (table) position, `P` the joint (machine) position of the tool tip:
//!
//! - inverse: `P = r + d + Ry(B)·(Rz(C)·(w − r) − d)` ([`TrtGeometry::inverse`])
//! - forward: `w = r + Rz(−C)·(Ry(−B)·(P − r − d) + d)` ([`TrtGeometry::forward`])
//!
//! A sphere fixed on the table at `s` (true table frame) is reported by a controller configured
//! with `g_conf` on a machine whose true geometry is `g_true` at
//! `c(B, C) = fwd_conf(inv_true(s)) = s − δr + Rz(−C)·(Ry(−B)·(δr + δd) − δd)`,
//! `δ = true − configured` ([`reported_centre`]). It is `s` at B = C = 0 whatever the geometry,
//! and linear in the geometry error. Only `δr.z + δd.z` enters, so four numbers are observable
//! ([`Observable`]): the C axis `(x, y)` and the B axis `(x, z)`. [`design`] is `∂c/∂θ` for
//! `θ = (δ C-axis x, δ C-axis y, δ B-axis x, δ B-axis z)`: `c = s + design(B, C)·θ`, exactly.
//!
//! Provenance: the equations and signs are those of the project's verified LinuxCNC recipe
//! (`notes/linuxcnc-5axis.md`, §4: the forward and inverse agreed with LinuxCNC 2.9's
//! `xyzbc-trt-kins` to print rounding at six poses, and measured centres with the predicted
//! `c(B, C)` to ≤ 0.6 µm).

use nalgebra::Matrix3x4;
use truepos_device::KinematicsParameter;
use truepos_math::{ry, rz, Matrix3, Point3, Vector3};

/// The kinematics module's name in LinuxCNC.
pub const MODULE: &str = "xyzbc-trt-kins";

/// The pins of `xyzbc-trt-kins` that hold the geometry, in [`TrtGeometry`]'s order.
pub const PINS: [&str; 5] = ["x-rot-point", "y-rot-point", "z-rot-point", "x-offset", "z-offset"];

/// The INI keys of the recipe's `[KINS]` section that the HAL file sets the pins from, in
/// [`PINS`]' order.
pub const INI_KEYS: [&str; 5] = ["X_ROT_POINT", "Y_ROT_POINT", "Z_ROT_POINT", "X_OFFSET", "Z_OFFSET"];

/// The geometry of an `xyzbc-trt` machine (mm), as the kinematics module's pins hold it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrtGeometry {
    /// X of the C axis at B = 0 (pin `x-rot-point`), mm.
    pub x_rot_point: f64,
    /// Y of the C axis at B = 0 (pin `y-rot-point`), mm.
    pub y_rot_point: f64,
    /// Z of the rotation point (pin `z-rot-point`), mm.
    pub z_rot_point: f64,
    /// X offset of the B axis from the rotation point (pin `x-offset`), mm.
    pub x_offset: f64,
    /// Z offset of the B axis from the rotation point (pin `z-offset`), mm.
    pub z_offset: f64,
}

impl TrtGeometry {
    /// The C axis point `r`.
    pub fn r(&self) -> Vector3 {
        Vector3::new(self.x_rot_point, self.y_rot_point, self.z_rot_point)
    }

    /// The B axis offset `d` (y-offset is not used by xyzbc).
    pub fn d(&self) -> Vector3 {
        Vector3::new(self.x_offset, 0.0, self.z_offset)
    }

    /// Joint (machine) position of the tip for programme position `w` at B, C (rad).
    pub fn inverse(&self, w: &Point3, b: f64, c: f64) -> Point3 {
        let (r, d) = (self.r(), self.d());
        Point3::from(r + d + ry(b) * (rz(c) * (w.coords - r) - d))
    }

    /// Programme position of the tip at joint position `p` and B, C (rad).
    pub fn forward(&self, p: &Point3, b: f64, c: f64) -> Point3 {
        let (r, d) = (self.r(), self.d());
        Point3::from(r + rz(-c) * (ry(-b) * (p.coords - r - d) + d))
    }

    /// The values in [`PINS`]' order.
    pub fn values(&self) -> [f64; 5] {
        [self.x_rot_point, self.y_rot_point, self.z_rot_point, self.x_offset, self.z_offset]
    }

    /// The geometry from its pin values in [`PINS`] order, mm.
    pub fn from_values(v: [f64; 5]) -> TrtGeometry {
        TrtGeometry {
            x_rot_point: v[0],
            y_rot_point: v[1],
            z_rot_point: v[2],
            x_offset: v[3],
            z_offset: v[4],
        }
    }

    /// As the controller's parameters (pin names).
    pub fn parameters(&self) -> Vec<KinematicsParameter> {
        PINS.iter()
            .zip(self.values())
            .map(|(n, v)| KinematicsParameter { name: n.to_string(), value_mm: v })
            .collect()
    }

    /// From the controller's parameters: every pin of [`PINS`] must be there and finite
    /// (others, such as `tool-offset`, are ignored). `Err` names what is missing.
    pub fn from_parameters(p: &[KinematicsParameter]) -> Result<TrtGeometry, String> {
        let mut v = [0.0; 5];
        for (k, name) in PINS.iter().enumerate() {
            let found = p.iter().find(|q| q.name == *name).ok_or_else(|| format!("no `{name}`"))?;
            if !found.value_mm.is_finite() {
                return Err(format!("`{name}` is not a finite number"));
            }
            v[k] = found.value_mm;
        }
        Ok(TrtGeometry::from_values(v))
    }

    /// The geometry with an identified change `θ` ([`Observable`] order) of the observable
    /// axes: the C axis moves by `(θ0, θ1)`, the B axis by `(θ2, θ3)` in X and Z; z-rot-point
    /// stays, so the Z change goes into z-offset.
    pub fn corrected(&self, theta: &[f64; 4]) -> TrtGeometry {
        TrtGeometry {
            x_rot_point: self.x_rot_point + theta[0],
            y_rot_point: self.y_rot_point + theta[1],
            z_rot_point: self.z_rot_point,
            x_offset: self.x_offset + theta[2] - theta[0],
            z_offset: self.z_offset + theta[3],
        }
    }

    /// The observable numbers: C axis (x, y) and B axis (x, z) (mm).
    pub fn axes(&self) -> [f64; 4] {
        [
            self.x_rot_point,
            self.y_rot_point,
            self.x_rot_point + self.x_offset,
            self.z_rot_point + self.z_offset,
        ]
    }
}

/// Rotation from machine directions to programme (table) directions at B, C (rad):
/// `Rz(−C)·Ry(−B)`. Its third column is the tool axis ([`tool_axis`]).
pub fn programme_from_machine(b: f64, c: f64) -> Matrix3 {
    rz(-c) * ry(-b)
}

/// The tool axis (machine +Z, from the tip towards the spindle) in the programme frame at B, C
/// (rad): `(−cos C·sin B, sin C·sin B, cos B)`.
pub fn tool_axis(b: f64, c: f64) -> Vector3 {
    Vector3::new(-c.cos() * b.sin(), c.sin() * b.sin(), b.cos())
}

/// Where a controller configured with `conf` reports a sphere fixed at `s` on a machine whose
/// true geometry is `truth`, at B, C (rad): the closed form `s − δr + Rz(−C)·(Ry(−B)·(δr + δd)
/// − δd)`.
pub fn reported_centre(conf: &TrtGeometry, truth: &TrtGeometry, s: &Point3, b: f64, c: f64) -> Point3 {
    let dr = truth.r() - conf.r();
    let dd = truth.d() - conf.d();
    s - dr + rz(-c) * (ry(-b) * (dr + dd) - dd)
}

/// The four observable numbers, in the order of `θ` in [`design`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Observable {
    /// The C axis's X (`x-rot-point`).
    CAxisX,
    /// The C axis's Y (`y-rot-point`).
    CAxisY,
    /// The B axis's X (`x-rot-point + x-offset`).
    BAxisX,
    /// The B axis's Z (`z-rot-point + z-offset`).
    BAxisZ,
}

impl Observable {
    /// The four observables in `θ` order.
    pub const ALL: [Observable; 4] =
        [Observable::CAxisX, Observable::CAxisY, Observable::BAxisX, Observable::BAxisZ];

    /// The observable in words, for reports and messages.
    pub fn describe(self) -> &'static str {
        match self {
            Observable::CAxisX => "the C axis's X (x-rot-point)",
            Observable::CAxisY => "the C axis's Y (y-rot-point)",
            Observable::BAxisX => "the B axis's X (x-rot-point + x-offset)",
            Observable::BAxisZ => "the B axis's Z (z-rot-point + z-offset)",
        }
    }
}

/// The identified pins as combinations of `θ`: (pin, coefficients). x-offset changes by the B
/// axis's X change minus the C axis's.
pub const PIN_FROM_THETA: [(&str, [f64; 4]); 4] = [
    ("x-rot-point", [1.0, 0.0, 0.0, 0.0]),
    ("y-rot-point", [0.0, 1.0, 0.0, 0.0]),
    ("x-offset", [-1.0, 0.0, 1.0, 0.0]),
    ("z-offset", [0.0, 0.0, 0.0, 1.0]),
];

/// `∂c/∂θ` at B, C (rad): the reported centre is `c = s + design(B, C)·θ` for the axis errors
/// `θ` ([`Observable`] order, true − configured).
pub fn design(b: f64, c: f64) -> Matrix3x4<f64> {
    let m = rz(-c);
    let n = m * ry(-b);
    let (ex, ey, ez) = (Vector3::x(), Vector3::y(), Vector3::z());
    let cols = [m * ex - ex, n * ey - ey, n * ex - m * ex, n * ez - m * ez];
    Matrix3x4::from_columns(&cols)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn conf() -> TrtGeometry {
        TrtGeometry {
            x_rot_point: 10.0,
            y_rot_point: -5.0,
            z_rot_point: -20.0,
            x_offset: -20.0,
            z_offset: -15.0,
        }
    }
    fn truth() -> TrtGeometry {
        TrtGeometry {
            x_rot_point: 10.030,
            y_rot_point: -5.020,
            z_rot_point: -20.0,
            x_offset: -19.985,
            z_offset: -15.025,
        }
    }

    #[test]
    fn forward_inverts_inverse_and_matches_the_recipes_poses() {
        let g = conf();
        let d = |x: f64| x.to_radians();
        // Poses verified on LinuxCNC 2.9 (notes/linuxcnc-5axis.md §4).
        let w = Point3::new(30.0, -20.0, 60.0);
        let p = g.inverse(&w, 0.0, d(90.0));
        assert!((p - Point3::new(25.0, 15.0, 60.0)).norm() < 1e-9, "{p}");
        let p = g.inverse(&w, d(30.0), 0.0);
        assert!((p - Point3::new(72.1410, -20.0, 27.2724)).norm() < 1e-4, "{p}");
        for (b, c) in [(0.0, 0.0), (45.0, 200.0), (-30.0, 17.0), (90.0, 45.0)] {
            let q = g.forward(&g.inverse(&w, d(b), d(c)), d(b), d(c));
            assert!((q - w).norm() < 1e-12);
        }
        // The tool axis: machine +Z in the programme frame.
        for (b, c) in [(30.0, 0.0), (45.0, 120.0), (90.0, 270.0)] {
            let (b, c) = (d(b), d(c));
            let a = g.forward(&(g.inverse(&w, b, c) + Vector3::z()), b, c) - w;
            assert!((a - tool_axis(b, c)).norm() < 1e-12);
            assert!((programme_from_machine(b, c).column(2) - tool_axis(b, c)).norm() < 1e-15);
        }
    }

    #[test]
    fn the_closed_form_is_forward_configured_of_inverse_true_and_linear_in_the_error() {
        let s = Point3::new(60.0, 25.0, 15.0);
        let (gc, gt) = (conf(), truth());
        let theta = {
            let (a, b) = (gt.axes(), gc.axes());
            [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
        };
        for b in [0.0, 30.0, 45.0, 90.0, -60.0] {
            for c in [0.0, 120.0, 240.0, 33.0] {
                let (b, c) = (f64::to_radians(b), f64::to_radians(c));
                let direct = gc.forward(&gt.inverse(&s, b, c), b, c);
                let closed = reported_centre(&gc, &gt, &s, b, c);
                assert!((direct - closed).norm() < 1e-12, "{direct} {closed}");
                let lin = s + design(b, c) * nalgebra::Vector4::from(theta);
                assert!((lin - closed).norm() < 1e-12);
            }
        }
        // The recipe's measured centres with the wrong pins (µm agreement ≤ 0.6 there).
        let c = reported_centre(&gc, &gt, &s, 45f64.to_radians(), 240f64.to_radians());
        assert!((c - Point3::new(59.9701, 25.0599, 15.0391)).norm() < 1e-4, "{c}");
        // At B = C = 0 the geometry does not matter; correcting by θ removes every error.
        assert!((reported_centre(&gc, &gt, &s, 0.0, 0.0) - s).norm() < 1e-12);
        let fixed = gc.corrected(&theta);
        for (b, c) in [(0.5, 1.0), (1.2, -2.0)] {
            assert!((reported_centre(&fixed, &gt, &s, b, c) - s).norm() < 1e-12);
        }
        // Only the sum z-rot-point + z-offset enters.
        let moved = TrtGeometry { z_rot_point: gt.z_rot_point + 7.0, z_offset: gt.z_offset - 7.0, ..gt };
        assert!(
            (reported_centre(&gc, &moved, &s, 0.7, 2.0) - reported_centre(&gc, &gt, &s, 0.7, 2.0)).norm()
                < 1e-12
        );
    }

    #[test]
    fn parameters_round_trip_and_missing_pins_are_named() {
        let g = truth();
        assert_eq!(TrtGeometry::from_parameters(&g.parameters()).unwrap(), g);
        let mut p = g.parameters();
        p.retain(|q| q.name != "x-offset");
        assert!(TrtGeometry::from_parameters(&p).unwrap_err().contains("x-offset"));
    }
}
