//! ISO 230-1 rigid-body geometric errors: 18 position-dependent component errors (6 per linear
//! axis) plus 3 squareness errors, as smooth functions, following `docs/conventions.md` exactly.
//!
//! Conventions (errors of motion, actual − nominal, mm and rad):
//! - linear components of axis A, in file order `pos, str1, str2`: positioning along A, then
//!   straightness along the next two axes in x→y→z→x order, i.e. component k is along machine
//!   axis `(A + k) mod 3` ([`GeometricErrors::linear`]);
//! - angular components in file order `pitch, yaw, roll`, a small rotation vector about machine
//!   X, Y, Z: X axis roll→X, pitch→Y, yaw→Z; Y axis roll→Y, pitch→X, yaw→Z; Z axis roll→Z,
//!   pitch→X, yaw→Y ([`GeometricErrors::rotation`]);
//! - squareness `xy` (X travel (1, xy, 0)), `xz` (Z travel (xz, 0, 1)), `yz` (Z travel (0, yz, 1)),
//!   positive when the angle between the positive axes is below 90° ([`Squareness`]).
//!
//! Each component is an [`ErrorFn`]: a low-order polynomial in the normalised position plus a
//! few sinusoids (long-wave guideway form, short-wave screw/scale periodic error).
//! [`GeometricErrors::realistic`] draws a realistic set for a machine size class
//! ([`ErrorMagnitudes::cmm`], [`ErrorMagnitudes::vmc`], [`ErrorMagnitudes::gantry`]);
//! [`GeometricErrors::sample`] / [`GeometricErrors::table`] turn it into the map table a data
//! set's truth holds (position → `[pos, str1, str2, pitch, yaw, roll]`); the exact and
//! first-order kinematic chains that use it live in [`crate::machine`].

use rand::Rng;
pub use truepos_math::types::Axis;
use truepos_math::types::{Matrix3, Vector3};

/// One sinusoid: `amplitude · sin(2π·a/period + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wave {
    /// Amplitude, in the unit of the error (mm or rad).
    pub amplitude: f64,
    /// Period (mm), > 0.
    pub period: f64,
    /// Phase, rad.
    pub phase: f64,
}

/// A smooth component error `f(a) = Σ poly[k]·(a/length)^k + Σ waves` of axis position `a` (mm).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ErrorFn {
    /// Normalising length (mm), usually the axis travel; > 0 when `poly` has non-constant terms.
    pub length: f64,
    /// Polynomial coefficients in powers of `a/length` (units of the error: mm or rad).
    pub poly: Vec<f64>,
    /// Sinusoids added to the polynomial.
    pub waves: Vec<Wave>,
}

impl ErrorFn {
    /// The zero function.
    pub fn zero() -> ErrorFn {
        ErrorFn { length: 1.0, poly: Vec::new(), waves: Vec::new() }
    }

    /// A linear function `slope · a` (slope per mm).
    pub fn linear(slope: f64) -> ErrorFn {
        ErrorFn { length: 1.0, poly: vec![0.0, slope], waves: Vec::new() }
    }

    /// A constant.
    pub fn constant(v: f64) -> ErrorFn {
        ErrorFn { length: 1.0, poly: vec![v], waves: Vec::new() }
    }

    /// Value at position `a` (mm).
    pub fn eval(&self, a: f64) -> f64 {
        let s = if self.length != 0.0 { a / self.length } else { 0.0 };
        let mut v = 0.0;
        for c in self.poly.iter().rev() {
            v = v * s + c;
        }
        for w in &self.waves {
            v += w.amplitude * (std::f64::consts::TAU * a / w.period + w.phase).sin();
        }
        v
    }

    /// Derivative at `a` (per mm).
    pub fn derivative(&self, a: f64) -> f64 {
        let s = if self.length != 0.0 { a / self.length } else { 0.0 };
        let mut d = 0.0;
        for (k, c) in self.poly.iter().enumerate().skip(1).rev() {
            d = d * s + k as f64 * c;
        }
        d /= if self.length != 0.0 { self.length } else { 1.0 };
        for w in &self.waves {
            let k = std::f64::consts::TAU / w.period;
            d += w.amplitude * k * (k * a + w.phase).cos();
        }
        d
    }

    /// Scale the function by `k`.
    pub fn scaled(mut self, k: f64) -> ErrorFn {
        for c in &mut self.poly {
            *c *= k;
        }
        for w in &mut self.waves {
            w.amplitude *= k;
        }
        self
    }

    /// A random smooth function of peak size about `amplitude` over `0..length`: zero at 0, a
    /// cubic (form), one long wave (period length/3..length) and one short wave (period
    /// `short_period`, 5 % amplitude: screw or scale periodic error).
    pub fn random<R: Rng + ?Sized>(rng: &mut R, length: f64, amplitude: f64, short_period: f64) -> ErrorFn {
        let mut u = || 2.0 * rng.random::<f64>() - 1.0;
        let c1 = 0.6 * amplitude * u();
        let c2 = 0.5 * amplitude * u();
        let c3 = 0.3 * amplitude * u();
        let a_long = 0.25 * amplitude * u();
        let p_long = length * (0.33 + 0.67 * (0.5 + 0.5 * u()));
        let ph_long = std::f64::consts::PI * u();
        let a_short = 0.05 * amplitude * u();
        let ph_short = std::f64::consts::PI * u();
        let mut f = ErrorFn {
            length,
            poly: vec![0.0, c1, c2, c3],
            waves: vec![
                Wave { amplitude: a_long, period: p_long, phase: ph_long },
                Wave { amplitude: a_short, period: short_period, phase: ph_short },
            ],
        };
        // Zero at the axis origin (the reference mark): remove the waves' value at 0.
        let v0 = f.eval(0.0);
        f.poly[0] = -v0;
        f
    }
}

/// The six component error functions of one linear axis (the model; `truepos_comp::AxisErrors` is
/// the six values at one position, as a map table holds them).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AxisErrorFns {
    /// `[pos, str1, str2]` (mm), see [`Axis::linear_axes`].
    pub linear: [ErrorFn; 3],
    /// `[pitch, yaw, roll]` (rad), see [`Axis::angular_axes`].
    pub angular: [ErrorFn; 3],
}

impl AxisErrorFns {
    /// All six components zero.
    pub fn zero() -> AxisErrorFns {
        AxisErrorFns {
            linear: [ErrorFn::zero(), ErrorFn::zero(), ErrorFn::zero()],
            angular: [ErrorFn::zero(), ErrorFn::zero(), ErrorFn::zero()],
        }
    }

    /// `[pos, str1, str2, pitch, yaw, roll]` at `a` (mm, rad).
    pub fn components(&self, a: f64) -> [f64; 6] {
        [
            self.linear[0].eval(a),
            self.linear[1].eval(a),
            self.linear[2].eval(a),
            self.angular[0].eval(a),
            self.angular[1].eval(a),
            self.angular[2].eval(a),
        ]
    }
}

/// Squareness errors (rad), conventions.md sign.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Squareness {
    /// Between X and Y, rad.
    pub xy: f64,
    /// Between X and Z, rad.
    pub xz: f64,
    /// Between Y and Z, rad.
    pub yz: f64,
}

/// Size classes of geometric errors (peak values over the travel; mm and rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorMagnitudes {
    /// Axis travels (mm).
    pub travel: [f64; 3],
    /// Peak positioning error, mm.
    pub positioning: f64,
    /// Peak straightness error, mm.
    pub straightness: f64,
    /// Peak angular error, rad.
    pub angular: f64,
    /// Squareness error, rad.
    pub squareness: f64,
    /// Short-wave period (mm): screw lead or scale period.
    pub short_period: f64,
}

impl ErrorMagnitudes {
    /// Bridge CMM, 1000 × 1500 × 800 mm: ±3 µm positioning, ±1.5 µm straightness, ±3 µrad
    /// angular, ±5 µrad squareness.
    pub fn cmm() -> Self {
        ErrorMagnitudes {
            travel: [1000.0, 1500.0, 800.0],
            positioning: 3e-3,
            straightness: 1.5e-3,
            angular: 3e-6,
            squareness: 5e-6,
            short_period: 20.0,
        }
    }
    /// Vertical machining centre, 800 × 500 × 500 mm: ±8 µm, ±4 µm, ±8 µrad, ±10 µrad.
    pub fn vmc() -> Self {
        ErrorMagnitudes {
            travel: [800.0, 500.0, 500.0],
            positioning: 8e-3,
            straightness: 4e-3,
            angular: 8e-6,
            squareness: 10e-6,
            short_period: 10.0,
        }
    }
    /// Large gantry, 12 m × 4 m × 2 m: ±40 µm positioning, ±25 µm straightness, ±10 µrad
    /// angular, ±10 µrad squareness.
    pub fn gantry() -> Self {
        ErrorMagnitudes {
            travel: [12000.0, 4000.0, 2000.0],
            positioning: 40e-3,
            straightness: 25e-3,
            angular: 10e-6,
            squareness: 10e-6,
            short_period: 50.0,
        }
    }
}

/// The 21 geometric error parameters of a three-axis machine.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GeometricErrors {
    /// Indexed by [`Axis::index`].
    pub axes: [AxisErrorFns; 3],
    /// The squareness errors.
    pub squareness: Squareness,
}

impl GeometricErrors {
    /// All 21 parameters zero (the nominal machine).
    pub fn zero() -> GeometricErrors {
        GeometricErrors {
            axes: [AxisErrorFns::zero(), AxisErrorFns::zero(), AxisErrorFns::zero()],
            squareness: Squareness::default(),
        }
    }

    /// A random realistic set of the given size class.
    pub fn realistic<R: Rng + ?Sized>(rng: &mut R, m: &ErrorMagnitudes) -> GeometricErrors {
        let mut axes = [AxisErrorFns::zero(), AxisErrorFns::zero(), AxisErrorFns::zero()];
        for (i, ax) in axes.iter_mut().enumerate() {
            let l = m.travel[i];
            ax.linear = [
                ErrorFn::random(rng, l, m.positioning, m.short_period),
                ErrorFn::random(rng, l, m.straightness, m.short_period),
                ErrorFn::random(rng, l, m.straightness, m.short_period),
            ];
            ax.angular = [
                ErrorFn::random(rng, l, m.angular, m.short_period),
                ErrorFn::random(rng, l, m.angular, m.short_period),
                ErrorFn::random(rng, l, m.angular, m.short_period),
            ];
        }
        let mut u = || (2.0 * rng.random::<f64>() - 1.0) * m.squareness;
        let squareness = Squareness { xy: u(), xz: u(), yz: u() };
        GeometricErrors { axes, squareness }
    }

    /// The component errors of `axis`.
    pub fn axis(&self, axis: Axis) -> &AxisErrorFns {
        &self.axes[axis.index()]
    }

    /// Linear error vector `δ_A(a)` in machine coordinates (mm).
    pub fn linear(&self, axis: Axis, a: f64) -> Vector3 {
        let e = self.axis(axis);
        let mut v = Vector3::zeros();
        for (k, &m) in axis.linear_axes().iter().enumerate() {
            v[m] = e.linear[k].eval(a);
        }
        v
    }

    /// Angular error rotation vector `ε_A(a)` about machine X, Y, Z (rad).
    pub fn rotation(&self, axis: Axis, a: f64) -> Vector3 {
        let e = self.axis(axis);
        let mut v = Vector3::zeros();
        for (k, &m) in axis.angular_axes().iter().enumerate() {
            v[m] = e.angular[k].eval(a);
        }
        v
    }

    /// Squareness translation carried by `axis` at position `a`: X adds `(0, xy·x, 0)`, Z adds
    /// `(xz·z, yz·z, 0)`, Y nothing.
    pub fn squareness_term(&self, axis: Axis, a: f64) -> Vector3 {
        let s = &self.squareness;
        match axis {
            Axis::X => Vector3::new(0.0, s.xy * a, 0.0),
            Axis::Y => Vector3::zeros(),
            Axis::Z => Vector3::new(s.xz * a, s.yz * a, 0.0),
        }
    }

    /// Sample `axis` at `positions`: rows `[pos, str1, str2, pitch, yaw, roll]` (mm, rad).
    pub fn sample(&self, axis: Axis, positions: &[f64]) -> Vec<[f64; 6]> {
        let e = self.axis(axis);
        positions.iter().map(|&a| e.components(a)).collect()
    }

    /// The full map as a table: for each axis, positions `0, step, …, travel` (the last one exactly
    /// `travel`) and their six components. Empty if `step ≤ 0`, a travel is negative or not
    /// finite, or an axis would need more than 1e7 rows.
    pub fn table(&self, travel: [f64; 3], step: f64) -> Vec<MapRow> {
        let mut rows = Vec::new();
        if step.is_nan() || step <= 0.0 {
            return rows;
        }
        // Refuse absurd requests (non-finite or negative travel, more than 1e7 rows per axis).
        if travel.iter().any(|t| !t.is_finite() || *t < 0.0 || t / step > 1e7) {
            return rows;
        }
        for axis in Axis::ALL {
            let t = travel[axis.index()];
            let n = (t / step).ceil().max(1.0) as usize;
            for i in 0..=n {
                let a = (i as f64 * step).min(t);
                rows.push(MapRow { axis, position: a, values: self.axis(axis).components(a) });
            }
        }
        rows
    }
}

/// One row of a sampled map: `values = [pos, str1, str2, pitch, yaw, roll]` in mm and rad (the
/// file wants µm and µrad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapRow {
    /// The axis.
    pub axis: Axis,
    /// Position along the axis, mm.
    pub position: f64,
    /// Positioning, two straightnesses (mm), pitch, yaw, roll (rad).
    pub values: [f64; 6],
}

/// Exact rotation matrix of the rotation vector `v` (Rodrigues), not its first-order `I + [v]×`.
pub fn rotation_matrix(v: &Vector3) -> Matrix3 {
    nalgebra::Rotation3::new(*v).into_inner()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn component_mapping_follows_conventions() {
        let mut g = GeometricErrors::zero();
        // Y axis: pos→y, str1→z, str2→x; roll→Y, pitch→X, yaw→Z.
        g.axes[1].linear = [ErrorFn::constant(1.0), ErrorFn::constant(2.0), ErrorFn::constant(3.0)];
        g.axes[1].angular = [ErrorFn::constant(10.0), ErrorFn::constant(20.0), ErrorFn::constant(30.0)];
        assert_eq!(g.linear(Axis::Y, 5.0), Vector3::new(3.0, 1.0, 2.0));
        assert_eq!(g.rotation(Axis::Y, 5.0), Vector3::new(10.0, 30.0, 20.0));
        // X axis: roll→X, pitch→Y, yaw→Z.
        g.axes[0].angular = [ErrorFn::constant(1.0), ErrorFn::constant(2.0), ErrorFn::constant(3.0)];
        assert_eq!(g.rotation(Axis::X, 0.0), Vector3::new(3.0, 1.0, 2.0));
        // Z axis: roll→Z, pitch→X, yaw→Y; pos→z, str1→x, str2→y.
        g.axes[2].angular = [ErrorFn::constant(1.0), ErrorFn::constant(2.0), ErrorFn::constant(3.0)];
        g.axes[2].linear = [ErrorFn::constant(1.0), ErrorFn::constant(2.0), ErrorFn::constant(3.0)];
        assert_eq!(g.rotation(Axis::Z, 0.0), Vector3::new(1.0, 2.0, 3.0));
        assert_eq!(g.linear(Axis::Z, 0.0), Vector3::new(2.0, 3.0, 1.0));
    }

    #[test]
    fn realistic_magnitudes_and_zero_at_origin() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let m = ErrorMagnitudes::gantry();
        let g = GeometricErrors::realistic(&mut rng, &m);
        for axis in Axis::ALL {
            let t = m.travel[axis.index()];
            let pos: Vec<f64> = (0..=200).map(|i| t * i as f64 / 200.0).collect();
            let s = g.sample(axis, &pos);
            assert!(s[0].iter().all(|v| v.abs() < 1e-15), "zero at the reference mark");
            // Sum of the term bounds: 0.6+0.5+0.3+2·0.25+2·0.05 = 2.0 × amplitude.
            for row in &s {
                for (k, v) in row.iter().enumerate() {
                    let amp = match k {
                        0 => m.positioning,
                        1 | 2 => m.straightness,
                        _ => m.angular,
                    };
                    assert!(v.abs() <= 2.0 * amp + 1e-18);
                }
            }
        }
    }

    #[test]
    fn derivative_matches_finite_difference() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let f = ErrorFn::random(&mut rng, 1000.0, 1e-3, 20.0);
        for a in [0.0, 123.0, 777.7] {
            let h = 1e-3;
            let fd = (f.eval(a + h) - f.eval(a - h)) / (2.0 * h);
            // Central difference error ~ h²·f'''/6, f''' ≲ 1e-3·(2π/20)³ ≈ 3e-5 → ~5e-12.
            assert!((fd - f.derivative(a)).abs() < 1e-10, "{fd} vs {}", f.derivative(a));
        }
    }

    #[test]
    fn table_ends_at_travel() {
        let g = GeometricErrors::zero();
        let rows = g.table([100.0, 50.0, 30.0], 20.0);
        let x: Vec<f64> = rows.iter().filter(|r| r.axis == Axis::X).map(|r| r.position).collect();
        assert_eq!(x, vec![0.0, 20.0, 40.0, 60.0, 80.0, 100.0]);
        let z: Vec<f64> = rows.iter().filter(|r| r.axis == Axis::Z).map(|r| r.position).collect();
        assert_eq!(z, vec![0.0, 20.0, 30.0]);
    }
}
