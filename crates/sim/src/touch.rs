//! Touch-trigger probe: the probe triggers when the stylus deflection exceeds its pre-travel, which
//! may vary with the direction of deflection (lobing of a kinematic three-point seat).
//!
//! Entry points: [`TouchProbe`] (`pretravel` for a direction, `triggered` for a deflection),
//! [`TouchProbe::first_trigger`] (first sample of a deflection stream that triggers, with the
//! crossing time interpolated), and [`TouchProbe::probe_along`] (exact body position and tip
//! contact at the trigger when the body moves along a straight line towards an artefact, for a
//! stiff stylus whose deflection equals the interference along the contact normal).

use truepos_math::{Point3, Vector3};

use crate::artefact::{tip_contact, Artefact, TipContact};
use crate::noise::{check_nonneg, check_positive, ParamError};

/// A touch-trigger probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TouchProbe {
    /// Tip radius (mm).
    pub tip_radius_mm: f64,
    /// Mean pre-travel (mm): the deflection at which it triggers.
    pub pretravel_mm: f64,
    /// Lobing amplitude (mm): pre-travel varies as `pretravel + lobing·cos(3φ)` with the azimuth
    /// `φ` of the deflection in the probe's XY plane (0 for a lobing-free probe).
    pub lobing_mm: f64,
}

/// A trigger found in a deflection stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trigger {
    /// Index of the first sample over the threshold.
    pub index: usize,
    /// Time of the threshold crossing, interpolated between that sample and the previous (s).
    pub t_s: f64,
}

/// A trigger found along a straight probing move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineTrigger {
    /// Body position at the trigger.
    pub body: Point3,
    /// Travel from the start to the trigger (mm).
    pub travel_mm: f64,
    /// Contact of the tip at the trigger.
    pub contact: TipContact,
}

impl TouchProbe {
    /// A probe; radius, pre-travel ≥ 0, `|lobing| < pretravel`.
    pub fn new(tip_radius_mm: f64, pretravel_mm: f64, lobing_mm: f64) -> Result<Self, ParamError> {
        check_nonneg("tip radius", tip_radius_mm)?;
        check_positive("pre-travel", pretravel_mm)?;
        check_nonneg("lobing", lobing_mm.abs())?;
        if lobing_mm.abs() >= pretravel_mm {
            return Err(ParamError::Invalid {
                name: "lobing",
                requirement: "smaller than the pre-travel",
                value: lobing_mm,
            });
        }
        Ok(TouchProbe { tip_radius_mm, pretravel_mm, lobing_mm })
    }

    /// Pre-travel for a deflection direction `dir` (need not be unit).
    pub fn pretravel(&self, dir: &Vector3) -> f64 {
        if self.lobing_mm == 0.0 || (dir.x == 0.0 && dir.y == 0.0) {
            return self.pretravel_mm;
        }
        self.pretravel_mm + self.lobing_mm * (3.0 * dir.y.atan2(dir.x)).cos()
    }

    /// Whether a deflection triggers the probe.
    pub fn triggered(&self, deflection: &Vector3) -> bool {
        let m = deflection.norm();
        m > 0.0 && m >= self.pretravel(deflection)
    }

    /// First trigger in a stream of `(t_s, deflection)`.
    pub fn first_trigger(&self, samples: &[(f64, Vector3)]) -> Option<Trigger> {
        let k = samples.iter().position(|(_, d)| self.triggered(d))?;
        if k == 0 {
            return Some(Trigger { index: 0, t_s: samples[0].0 });
        }
        let (t0, d0) = samples[k - 1];
        let (t1, d1) = samples[k];
        let thr = self.pretravel(&d1);
        let (m0, m1) = (d0.norm(), d1.norm());
        let f = if m1 > m0 { ((thr - m0) / (m1 - m0)).clamp(0.0, 1.0) } else { 1.0 };
        Some(Trigger { index: k, t_s: t0 + f * (t1 - t0) })
    }

    /// Move the body from `start` along `dir` by at most `max_travel_mm`; the trigger is where the
    /// tip's interference with `artefact` reaches the pre-travel for the contact normal. Found by
    /// marching in steps of a quarter of the pre-travel and bisecting to 1e-12 mm.
    pub fn probe_along(
        &self,
        artefact: &dyn Artefact,
        start: &Point3,
        dir: &Vector3,
        max_travel_mm: f64,
    ) -> Option<LineTrigger> {
        let len = dir.norm();
        if len.is_nan() || len <= 0.0 || !max_travel_mm.is_finite() {
            return None;
        }
        let u = dir / len;
        let excess = |s: f64| {
            let c = tip_contact(artefact, &(start + u * s), self.tip_radius_mm);
            -c.gap - self.pretravel(&c.normal)
        };
        let step = 0.25 * (self.pretravel_mm - self.lobing_mm.abs());
        let mut s0 = 0.0;
        if excess(0.0) >= 0.0 {
            return None; // already triggered at the start
        }
        while s0 < max_travel_mm {
            let s1 = (s0 + step).min(max_travel_mm);
            if excess(s1) >= 0.0 {
                let (mut lo, mut hi) = (s0, s1);
                while hi - lo > 1e-12 {
                    let mid = 0.5 * (lo + hi);
                    if excess(mid) >= 0.0 {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                let body = start + u * hi;
                return Some(LineTrigger {
                    body,
                    travel_mm: hi,
                    contact: tip_contact(artefact, &body, self.tip_radius_mm),
                });
            }
            s0 = s1;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::artefact::Sphere;

    #[test]
    fn triggers_after_the_pretravel_along_the_normal() {
        let sp = Sphere::new(Point3::origin(), 10.0).unwrap();
        let probe = TouchProbe::new(1.0, 0.01, 0.0).unwrap();
        let t = probe
            .probe_along(&sp, &Point3::new(20.0, 0.0, 0.0), &Vector3::new(-1.0, 0.0, 0.0), 50.0)
            .unwrap();
        // Contact at body x = 11, trigger 0.01 mm further in.
        assert!((t.body.x - 10.99).abs() < 1e-9, "{}", t.body);
        // Lobing: pre-travel 0.01 + 0.002 cos 3φ; along +X φ = 0.
        let lob = TouchProbe::new(1.0, 0.01, 0.002).unwrap();
        let t =
            lob.probe_along(&sp, &Point3::new(20.0, 0.0, 0.0), &Vector3::new(-1.0, 0.0, 0.0), 50.0).unwrap();
        assert!((t.body.x - 10.988).abs() < 1e-9, "{}", t.body);
        let s: Vec<(f64, Vector3)> =
            (0..10).map(|k| (k as f64, Vector3::new(0.004 * k as f64, 0.0, 0.0))).collect();
        let tr = probe.first_trigger(&s).unwrap();
        assert_eq!(tr.index, 3);
        assert!((tr.t_s - 2.5).abs() < 1e-9);
        assert!(TouchProbe::new(1.0, 0.01, 0.02).is_err());
    }
}
