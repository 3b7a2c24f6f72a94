//! The master clock and data capture: sampling a continuous-time signal at a channel's own rate,
//! with its own capture latency and noise.
//!
//! Every stream of the virtual cell is time-stamped against one master clock (time in s). A
//! channel samples at stamps `k / rate_hz` (jitter-free, `k` integer), and the value stamped `τ`
//! is the true signal at `τ − latency_s`: **the stamp of a sample is its true time plus the
//! channel's capture latency.** Two channels with latencies `L_m` (machine) and `L_p` (probe)
//! therefore show the system delay `L_m − L_p` of the interface contract: the stylus centre at
//! probe stamp `t` is `machine_position(t + L_m − L_p) + deflection(t)`.
//!
//! Entry points:
//! - [`Capture`]: one channel (`rate_hz`, `latency_s`); [`Capture::stamps`],
//!   [`Capture::true_time`], [`Capture::sample`] (any value type),
//!   [`Capture::sample_vector`] (3-vector with Gaussian noise per component).
//! - [`AxisCapture`]: a machine position channel whose three axes have different latencies
//!   ([`AxisCapture::sample_point`]).
//! - [`MasterClock`]: the span of a run and its stamp grid helpers.

use crate::noise::{check_finite, check_nonneg, check_positive, gaussian3, ParamError, SimRng};
use truepos_math::{Point3, Vector3};

/// The span of a simulated run on the master clock (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MasterClock {
    /// Start of the run, s.
    pub start_s: f64,
    /// End of the run, s.
    pub end_s: f64,
}

impl MasterClock {
    /// A clock span `[start_s, end_s]`.
    pub fn new(start_s: f64, end_s: f64) -> Result<Self, ParamError> {
        check_finite("clock start", start_s)?;
        check_finite("clock end", end_s)?;
        if end_s < start_s {
            return Err(ParamError::Invalid { name: "clock end", requirement: ">= start", value: end_s });
        }
        Ok(MasterClock { start_s, end_s })
    }

    /// Duration (s).
    pub fn duration_s(&self) -> f64 {
        self.end_s - self.start_s
    }
}

/// One capture channel: rate and latency on the master clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capture {
    /// Sampling rate, Hz.
    pub rate_hz: f64,
    /// Capture latency (s): a sample stamped `τ` holds the signal at true time `τ − latency_s`.
    pub latency_s: f64,
}

impl Capture {
    /// A channel; the rate must be positive, the latency finite (either sign is accepted).
    pub fn new(rate_hz: f64, latency_s: f64) -> Result<Self, ParamError> {
        check_positive("sample rate", rate_hz)?;
        check_finite("capture latency", latency_s)?;
        Ok(Capture { rate_hz, latency_s })
    }

    /// Sample period (s).
    pub fn period_s(&self) -> f64 {
        1.0 / self.rate_hz
    }

    /// Index range `k` of the stamps `k / rate_hz` inside `[clock.start_s, clock.end_s]`.
    pub fn index_range(&self, clock: &MasterClock) -> std::ops::RangeInclusive<i64> {
        let k0 = (clock.start_s * self.rate_hz - 1e-9).ceil() as i64;
        let k1 = (clock.end_s * self.rate_hz + 1e-9).floor() as i64;
        k0..=k1
    }

    /// The stamp of sample `k`.
    #[inline]
    pub fn stamp(&self, k: i64) -> f64 {
        k as f64 / self.rate_hz
    }

    /// All stamps in the clock span, in order.
    pub fn stamps(&self, clock: &MasterClock) -> impl Iterator<Item = f64> + '_ {
        let rate = self.rate_hz;
        self.index_range(clock).map(move |k| k as f64 / rate)
    }

    /// The true time of the sample stamped `stamp_s`.
    #[inline]
    pub fn true_time(&self, stamp_s: f64) -> f64 {
        stamp_s - self.latency_s
    }

    /// `(stamp, f(true_time))` for every stamp in the span.
    pub fn sample<T>(&self, clock: &MasterClock, mut f: impl FnMut(f64) -> T) -> Vec<(f64, T)> {
        self.stamps(clock).map(|s| (s, f(s - self.latency_s))).collect()
    }

    /// `(stamp, f(true_time) + noise)`, the noise Gaussian with `sigma` per component.
    pub fn sample_vector(
        &self,
        clock: &MasterClock,
        sigma: f64,
        rng: &mut SimRng,
        mut f: impl FnMut(f64) -> Vector3,
    ) -> Result<Vec<(f64, Vector3)>, ParamError> {
        check_nonneg("noise sigma", sigma)?;
        Ok(self.stamps(clock).map(|s| (s, f(s - self.latency_s) + gaussian3(rng, sigma))).collect())
    }
}

/// A position channel whose X, Y, Z readings have their own capture latencies (an NC that
/// forms each axis position separately).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisCapture {
    /// Sampling rate, Hz.
    pub rate_hz: f64,
    /// Capture latency of each axis (X, Y, Z), s.
    pub latency_s: [f64; 3],
}

impl AxisCapture {
    /// A channel; rate positive, latencies finite.
    pub fn new(rate_hz: f64, latency_s: [f64; 3]) -> Result<Self, ParamError> {
        check_positive("sample rate", rate_hz)?;
        for l in latency_s {
            check_finite("capture latency", l)?;
        }
        Ok(AxisCapture { rate_hz, latency_s })
    }

    /// The same latency on all axes.
    pub fn uniform(capture: Capture) -> Self {
        AxisCapture { rate_hz: capture.rate_hz, latency_s: [capture.latency_s; 3] }
    }

    /// `(stamp, p + noise)` where axis `i` of `p` is axis `i` of `f(stamp − latency_s[i])`.
    /// `f` is called once per sample when the latencies are equal, three times otherwise.
    pub fn sample_point(
        &self,
        clock: &MasterClock,
        sigma: f64,
        rng: &mut SimRng,
        mut f: impl FnMut(f64) -> Point3,
    ) -> Result<Vec<(f64, Point3)>, ParamError> {
        check_nonneg("noise sigma", sigma)?;
        let ch = Capture { rate_hz: self.rate_hz, latency_s: 0.0 };
        let [lx, ly, lz] = self.latency_s;
        let equal = lx == ly && ly == lz;
        Ok(ch
            .stamps(clock)
            .map(|s| {
                let p = if equal { f(s - lx) } else { Point3::new(f(s - lx).x, f(s - ly).y, f(s - lz).z) };
                (s, p + gaussian3(rng, sigma))
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::rng;

    #[test]
    fn stamps_are_on_the_grid_and_values_are_delayed_by_the_latency() {
        let clock = MasterClock::new(0.0, 1.0).unwrap();
        let ch = Capture::new(1000.0, 0.004).unwrap();
        let s = ch.sample(&clock, |t| 2.0 * t);
        assert_eq!(s.len(), 1001);
        for (k, (stamp, v)) in s.iter().enumerate() {
            assert_eq!(*stamp, k as f64 / 1000.0);
            assert!((v - 2.0 * (stamp - 0.004)).abs() < 1e-12);
        }
    }

    #[test]
    fn per_axis_latencies_apply_per_axis() {
        let clock = MasterClock::new(0.0, 0.1).unwrap();
        let ch = AxisCapture::new(100.0, [0.001, 0.002, 0.003]).unwrap();
        let s = ch.sample_point(&clock, 0.0, &mut rng(1), |t| Point3::new(t, 10.0 * t, 100.0 * t)).unwrap();
        for (stamp, p) in s {
            assert!((p.x - (stamp - 0.001)).abs() < 1e-12);
            assert!((p.y - 10.0 * (stamp - 0.002)).abs() < 1e-12);
            assert!((p.z - 100.0 * (stamp - 0.003)).abs() < 1e-12);
        }
        assert!(Capture::new(0.0, 0.0).is_err());
        assert!(Capture::new(10.0, f64::INFINITY).is_err());
    }
}
