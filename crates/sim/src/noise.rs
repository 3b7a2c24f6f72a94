//! Seeded, deterministic random numbers and measurement noise for the virtual cell.
//!
//! Every simulated data set is a pure function of its configuration and a `u64` seed: the same
//! seed gives bit-identical output on every platform (ChaCha is portable and fully specified).
//! Independent noise sources (encoder, probe, …) draw from separate ChaCha *streams* of the
//! same seed, so adding samples to one stream never changes the numbers of another.
//!
//! Entry points:
//! - [`rng`] / [`stream`]: a [`SimRng`] from a seed (and a stream id).
//! - [`gaussian`], [`gaussian3`], [`uniform`]: draws with a given standard deviation / range.
//! - [`Gaussian`]: a noise source bundling its own RNG and σ (`sample`, `sample3`).
//! - [`ParamError`] and the `check_*` helpers: validation of physical parameters shared by the
//!   probing-physics modules (every constructor rejects non-finite or out-of-range values).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha12Rng;
use rand_distr::StandardNormal;
use truepos_math::Vector3;

/// The random number generator of the virtual cell (ChaCha12, portable and deterministic).
pub type SimRng = ChaCha12Rng;

/// A generator seeded from `seed` (stream 0).
pub fn rng(seed: u64) -> SimRng {
    ChaCha12Rng::seed_from_u64(seed)
}

/// A generator seeded from `seed` on the independent ChaCha stream `stream_id`.
pub fn stream(seed: u64, stream_id: u64) -> SimRng {
    let mut r = rng(seed);
    r.set_stream(stream_id);
    r
}

/// A zero-mean Gaussian draw with standard deviation `sigma` (mm, s, … as given). `sigma == 0`
/// returns exactly 0 without consuming randomness.
#[inline]
pub fn gaussian<R: Rng + ?Sized>(rng: &mut R, sigma: f64) -> f64 {
    if sigma == 0.0 {
        0.0
    } else {
        let z: f64 = rng.sample(StandardNormal);
        sigma * z
    }
}

/// Three independent zero-mean Gaussian components with standard deviation `sigma` each.
#[inline]
pub fn gaussian3<R: Rng + ?Sized>(rng: &mut R, sigma: f64) -> Vector3 {
    Vector3::new(gaussian(rng, sigma), gaussian(rng, sigma), gaussian(rng, sigma))
}

/// A uniform draw in `[lo, hi)`.
#[inline]
pub fn uniform<R: Rng + ?Sized>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// A Gaussian noise source: its own generator and standard deviation.
#[derive(Debug, Clone)]
pub struct Gaussian {
    rng: SimRng,
    sigma: f64,
}

impl Gaussian {
    /// Noise with standard deviation `sigma` (≥ 0, finite) drawn from `stream(seed, stream_id)`.
    pub fn new(seed: u64, stream_id: u64, sigma: f64) -> Result<Self, ParamError> {
        check_nonneg("noise sigma", sigma)?;
        Ok(Gaussian { rng: stream(seed, stream_id), sigma })
    }

    /// Standard deviation.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// One draw.
    #[inline]
    pub fn sample(&mut self) -> f64 {
        gaussian(&mut self.rng, self.sigma)
    }

    /// Three independent draws.
    #[inline]
    pub fn sample3(&mut self) -> Vector3 {
        gaussian3(&mut self.rng, self.sigma)
    }
}

/// An invalid physical parameter given to a simulator component.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// A parameter does not meet its requirement.
    #[error("{name} must be {requirement}, got {value}")]
    Invalid {
        /// The parameter.
        name: &'static str,
        /// What it must be.
        requirement: &'static str,
        /// The value given.
        value: f64,
    },
}

/// `value` must be finite and > 0.
pub fn check_positive(name: &'static str, value: f64) -> Result<f64, ParamError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ParamError::Invalid { name, requirement: "finite and > 0", value })
    }
}

/// `value` must be finite and ≥ 0.
pub fn check_nonneg(name: &'static str, value: f64) -> Result<f64, ParamError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(ParamError::Invalid { name, requirement: "finite and >= 0", value })
    }
}

/// `value` must be finite.
pub fn check_finite(name: &'static str, value: f64) -> Result<f64, ParamError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ParamError::Invalid { name, requirement: "finite", value })
    }
}

/// `value` must lie in `[lo, hi]`.
pub fn check_range(name: &'static str, value: f64, lo: f64, hi: f64) -> Result<f64, ParamError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(ParamError::Invalid { name, requirement: "within its allowed range", value })
    }
}

impl truepos_math::exit::HasExitClass for ParamError {
    /// A model parameter out of range is the user's setting (exit 2).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        truepos_math::exit::ExitClass::Usage
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_numbers_and_streams_differ() {
        let a: Vec<f64> = (0..5).map(|_| gaussian(&mut rng(7), 1.0)).collect();
        let mut r1 = rng(7);
        let mut r2 = rng(7);
        let x: Vec<f64> = (0..100).map(|_| gaussian(&mut r1, 1.0)).collect();
        let y: Vec<f64> = (0..100).map(|_| gaussian(&mut r2, 1.0)).collect();
        assert_eq!(x, y);
        assert_eq!(a[0], x[0]);
        let z: Vec<f64> = {
            let mut s = stream(7, 1);
            (0..100).map(|_| gaussian(&mut s, 1.0)).collect()
        };
        assert_ne!(x, z);
    }

    #[test]
    fn gaussian_has_the_requested_sigma() {
        // n = 200 000 draws: the sample σ has relative standard error 1/sqrt(2n) = 0.16 %;
        // the mean has standard error σ/sqrt(n) = 0.0022σ. 5 % and 0.02σ are > 9 standard errors.
        let mut g = Gaussian::new(3, 0, 0.3).unwrap();
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| g.sample()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        assert!(mean.abs() < 0.02 * 0.3, "mean {mean}");
        assert!((sd / 0.3 - 1.0).abs() < 0.05, "sd {sd}");
        assert!(Gaussian::new(3, 0, -1.0).is_err());
        assert!(Gaussian::new(3, 0, f64::NAN).is_err());
    }
}
