//! Thermal behaviour of the cell: temperatures over time (drifts, steps, daily cycles), the
//! lagged response of a structure or part, axis growth (scale errors ∝ CTE·ΔT of the scales or
//! the structure carrying them) and part expansion relative to 20 °C (ISO 1).
//!
//! Entry points: [`TemperatureHistory`] ([`TemperatureHistory::at`] for air, and
//! [`TemperatureHistory::lagged`] — the exact first-order-lag response of a body with time
//! constant τ), [`ThermalModel`] ([`ThermalModel::axis_growth`] gives the `growth` array of
//! [`crate::machine::Machine::with_growth`]), [`expand_part`] / [`Part`] (part expansion about a
//! fixing point), and [`cte`] (typical coefficients, 1/K).
//!
//! Units: °C, s, mm, 1/K.

use truepos_math::types::Point3;

/// The reference temperature of dimensional metrology (ISO 1), °C.
pub const REFERENCE_TEMPERATURE: f64 = 20.0;

/// Typical coefficients of thermal expansion (1/K).
pub mod cte {
    /// Steel (structure, steel scales).
    pub const STEEL: f64 = 11.5e-6;
    /// Grey cast iron.
    pub const CAST_IRON: f64 = 10.5e-6;
    /// Aluminium alloy.
    pub const ALUMINIUM: f64 = 23.0e-6;
    /// Granite.
    pub const GRANITE: f64 = 6.0e-6;
    /// Glass-ceramic scale (Zerodur-like).
    pub const ZERODUR: f64 = 0.05e-6;
    /// Glass scale.
    pub const GLASS: f64 = 8.5e-6;
    /// Invar.
    pub const INVAR: f64 = 1.2e-6;
}

/// A step change of temperature at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Time of the step (s).
    pub time: f64,
    /// Change (K).
    pub delta: f64,
}

/// Temperature over time: `base + drift·t + Σ steps + amplitude·sin(2π t/period + phase)`.
#[derive(Debug, Clone, PartialEq)]
pub struct TemperatureHistory {
    /// Temperature at t = 0 (°C).
    pub base: f64,
    /// Linear drift (K/s).
    pub drift: f64,
    /// Step changes.
    pub steps: Vec<Step>,
    /// Cycle amplitude (K), period (s) and phase (rad); amplitude 0 for none.
    pub cycle_amplitude: f64,
    /// Cycle period, s.
    pub cycle_period: f64,
    /// Cycle phase, rad.
    pub cycle_phase: f64,
}

impl TemperatureHistory {
    /// A constant temperature.
    pub fn constant(t: f64) -> TemperatureHistory {
        TemperatureHistory {
            base: t,
            drift: 0.0,
            steps: Vec::new(),
            cycle_amplitude: 0.0,
            cycle_period: 86_400.0,
            cycle_phase: 0.0,
        }
    }

    /// A typical workshop: 21.5 °C at t = 0, +0.3 K/h drift, a ±1 K daily cycle.
    pub fn workshop() -> TemperatureHistory {
        TemperatureHistory {
            base: 21.5,
            drift: 0.3 / 3600.0,
            steps: Vec::new(),
            cycle_amplitude: 1.0,
            cycle_period: 86_400.0,
            cycle_phase: 0.0,
        }
    }

    /// Temperature at time `t` (s).
    pub fn at(&self, t: f64) -> f64 {
        let mut v = self.base + self.drift * t;
        for s in &self.steps {
            if t >= s.time {
                v += s.delta;
            }
        }
        if self.cycle_amplitude != 0.0 && self.cycle_period > 0.0 {
            let w = std::f64::consts::TAU / self.cycle_period;
            v += self.cycle_amplitude * (w * t + self.cycle_phase).sin();
        }
        v
    }

    /// Temperature of a body following this (air) temperature with a first-order lag of time
    /// constant `tau` (s), `τ·dT_b/dt = T_air − T_b`, starting at `T_b(0) = at(0)`. Exact closed
    /// form for every term (drift, steps, cycle with its transient). `tau ≤ 0` gives [`Self::at`].
    pub fn lagged(&self, t: f64, tau: f64) -> f64 {
        if tau <= 0.0 || t <= 0.0 {
            return self.at(t);
        }
        let decay = |s: f64| (-s / tau).exp();
        // The base is steady; each other term's response is added with its own transient.
        let mut v = self.base;
        // Drift d·t: response d·(t − τ(1 − e^{−t/τ})).
        v += self.drift * (t - tau * (1.0 - decay(t)));
        for s in &self.steps {
            if s.time <= 0.0 {
                // A step at or before t = 0 is already in the initial condition: at(0) includes it.
                v += s.delta;
            } else if t >= s.time {
                v += s.delta * (1.0 - decay(t - s.time));
            }
        }
        if self.cycle_amplitude != 0.0 && self.cycle_period > 0.0 {
            // Input A·sin(ωt + φ) with the body starting at A·sin φ: the solution is
            // A/(1+ω²τ²)·[sin(ωt+φ) − ωτ·cos(ωt+φ)] + C·e^{−t/τ}, with C fixed by y(0) = A sin φ.
            let w = std::f64::consts::TAU / self.cycle_period;
            let a = self.cycle_amplitude;
            let wt = w * tau;
            let k = a / (1.0 + wt * wt);
            let phi = self.cycle_phase;
            let steady = |x: f64| k * ((w * x + phi).sin() - wt * (w * x + phi).cos());
            let c = a * phi.sin() - steady(0.0);
            v += steady(t) + c * decay(t);
        }
        v
    }
}

/// Thermal model of a three-axis machine: each axis's scale (or the structure that carries it)
/// has a CTE and follows a temperature history with a lag; its growth is `CTE·(T − 20 °C)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalModel {
    /// CTE of each axis's scale/structure (1/K), indexed X, Y, Z.
    pub scale_cte: [f64; 3],
    /// Temperature history of the air around each axis.
    pub air: [TemperatureHistory; 3],
    /// Time constant of each scale/structure (s).
    pub tau: [f64; 3],
    /// Scale origin (fixed point) of each axis, mm.
    pub origin: [f64; 3],
}

impl ThermalModel {
    /// Steel scales/structure (11.5e-6/K) in the same air history, 30 min lag, fixed at 0.
    pub fn steel(air: TemperatureHistory) -> ThermalModel {
        ThermalModel {
            scale_cte: [cte::STEEL; 3],
            air: [air.clone(), air.clone(), air],
            tau: [1800.0; 3],
            origin: [0.0; 3],
        }
    }

    /// Scale temperatures at time `t` (°C).
    pub fn scale_temperature(&self, t: f64) -> [f64; 3] {
        [0, 1, 2].map(|i| self.air[i].lagged(t, self.tau[i]))
    }

    /// Axis growth (dimensionless scale error `CTE·(T − 20 °C)`) at time `t`, for
    /// [`crate::machine::Machine::with_growth`] together with [`ThermalModel::origin`].
    pub fn axis_growth(&self, t: f64) -> [f64; 3] {
        let temps = self.scale_temperature(t);
        [0, 1, 2].map(|i| self.scale_cte[i] * (temps[i] - REFERENCE_TEMPERATURE))
    }
}

/// Position of a part point at temperature `temp`, given its position `p20` at 20 °C, for a
/// part with expansion coefficient `cte` fixed (clamped) at `fixed`: `fixed + (1 + cte·ΔT)·(p20 −
/// fixed)`.
pub fn expand_part(p20: &Point3, fixed: &Point3, cte: f64, temp: f64) -> Point3 {
    fixed + (1.0 + cte * (temp - REFERENCE_TEMPERATURE)) * (p20 - fixed)
}

/// A workpiece that expands with its temperature about its fixing point.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// Coefficient of thermal expansion, 1/K.
    pub cte: f64,
    /// Point that stays put (clamp / datum), mm.
    pub fixed: Point3,
    /// The air temperature the part follows.
    pub air: TemperatureHistory,
    /// Part time constant (s).
    pub tau: f64,
}

impl Part {
    /// Part temperature at time `t` (°C).
    pub fn temperature(&self, t: f64) -> f64 {
        self.air.lagged(t, self.tau)
    }

    /// Where the point that is at `p20` at 20 °C is at time `t`.
    pub fn position(&self, p20: &Point3, t: f64) -> Point3 {
        expand_part(p20, &self.fixed, self.cte, self.temperature(t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Forward-Euler reference for the lag ODE with a fine step.
    fn euler(h: &TemperatureHistory, t_end: f64, tau: f64) -> f64 {
        let n = 200_000;
        let dt = t_end / n as f64;
        let mut y = h.at(0.0);
        for i in 0..n {
            let t = i as f64 * dt;
            // Midpoint (RK2) for accuracy.
            let k1 = (h.at(t) - y) / tau;
            let k2 = (h.at(t + 0.5 * dt) - (y + 0.5 * dt * k1)) / tau;
            y += dt * k2;
        }
        y
    }

    #[test]
    fn lagged_matches_the_ode() {
        let h = TemperatureHistory {
            base: 21.0,
            drift: 1.0 / 3600.0,
            steps: vec![Step { time: 1000.0, delta: -0.8 }],
            cycle_amplitude: 0.7,
            cycle_period: 7200.0,
            cycle_phase: 0.4,
        };
        for t_end in [500.0, 2500.0, 9000.0] {
            let exact = h.lagged(t_end, 900.0);
            let num = euler(&h, t_end, 900.0);
            // RK2 with dt ≤ 0.045 s: error ≪ 1e-6 K except the step's one-sample jump
            // (≤ 0.8 K·dt/τ ≈ 4e-5 K).
            assert!((exact - num).abs() < 1e-4, "t {t_end}: {exact} vs {num}");
        }
        // A step response reaches 63.2 % after one time constant.
        let s = TemperatureHistory {
            steps: vec![Step { time: 10.0, delta: 1.0 }],
            ..TemperatureHistory::constant(20.0)
        };
        assert!((s.lagged(10.0 + 600.0, 600.0) - 20.0 - (1.0 - (-1.0f64).exp())).abs() < 1e-12);
    }

    #[test]
    fn growth_and_part_expansion_by_hand() {
        let m = ThermalModel::steel(TemperatureHistory::constant(22.0));
        // Long after t = 0 the scale is at 22 °C: 11.5e-6 · 2 = 23e-6 (23 µm per metre).
        let g = m.axis_growth(1e6);
        assert!((g[0] - 23e-6).abs() < 1e-15);
        // Aluminium 500 mm part at 25 °C fixed at one end grows 23e-6·5·500 = 57.5 µm.
        let p = expand_part(&Point3::new(500.0, 0.0, 0.0), &Point3::origin(), cte::ALUMINIUM, 25.0);
        assert!((p.x - 500.0575).abs() < 1e-12);
    }
}
