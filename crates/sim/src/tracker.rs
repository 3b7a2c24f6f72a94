//! Laser tracker and inclinometers of the cell.
//!
//! A [`Tracker`] stands at a pose in the cell (`cell_from_tracker`) and measures a reflector
//! (SMR) in spherical coordinates: azimuth about its vertical axis (from its +X towards +Y),
//! elevation above its horizontal plane, and distance.
//!
//! Error model:
//! - **MPE** `±(a + b·L)` of a coordinate, default `a = 15 µm`, `b = 6 µm/m` (the usual
//!   ASME B89.4.19 / ISO 10360-10 style statement of a tracker). We treat the MPE as about 2σ
//!   ([`Tracker::sigma_fraction`] = 0.5): the transverse position noise has σ_t(L) = 0.5·(a + b·L)
//!   in each of the two directions across the beam (the angle noise is σ_t/L in elevation and
//!   σ_t/(L·cos el) in azimuth), and the distance noise has σ_d(L) = 0.5·(a_d + b_d·L) with its
//!   own MPE (default the same numbers).
//! - **Refractive index**: the interferometer/ADM measures the optical path `n_true·D`; the
//!   tracker divides by the index it assumes, so it reports `D·n_true/n_assumed`
//!   ([`Tracker::n_true`], [`Tracker::n_assumed`]; computing n from the weather, Ciddor/Edlén,
//!   is done elsewhere).
//! - **Beam breaks** ([`BeamBreak`]): time intervals in which the beam is interrupted, and
//!   obstacles (spheres, axis-aligned boxes in cell coordinates) that block the line of sight;
//!   a reading then fails with [`TrackerError::BeamBroken`].
//! - **Stability**: [`Tracker::measure_repeated`] samples a (possibly moving or vibrating, see
//!   [`VibratingTarget`]) target at a rate; [`spread`] gives the 3D standard deviation and the
//!   largest deviation from the mean, so a vibrating target shows a larger spread.
//!
//! [`Inclinometer`]: a two-axis tilt sensor (on the machine, the part or the tracker) reading the
//! true tilt of its body plus bias, linear drift and noise.
//!
//! Entry points: [`Tracker::new`], [`Tracker::measure`], [`Tracker::measure_exact`],
//! [`SphericalReading::to_tracker_point`], [`Tracker::reading_to_cell`],
//! [`Tracker::measure_repeated`], [`spread`], [`Inclinometer::reading`].
//! Units: mm, rad, s.

use rand::Rng;
use truepos_math::types::{Point3, Vector3};
use truepos_math::Transform3;

use crate::noise::gaussian;

/// Why a tracker reading failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum TrackerError {
    /// The beam is interrupted (time window or obstacle).
    #[error("beam broken at t = {time_s} s")]
    BeamBroken {
        /// Time of the reading, s.
        time_s: f64,
    },
    /// The target is at the tracker's own position or beyond its range.
    #[error("target out of range ({distance_mm} mm)")]
    OutOfRange {
        /// Distance of the target, mm.
        distance_mm: f64,
    },
}

/// A cause of a beam break.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BeamBreak {
    /// The beam is interrupted from `start` to `end` (s).
    Interval {
        /// Start, s.
        start: f64,
        /// End, s.
        end: f64,
    },
    /// A sphere in cell coordinates blocking the line of sight.
    Sphere {
        /// Centre, cell frame, mm.
        centre: Point3,
        /// Radius, mm.
        radius: f64,
    },
    /// An axis-aligned box in cell coordinates blocking the line of sight.
    Box {
        /// Lower corner, cell frame, mm.
        min: Point3,
        /// Upper corner, cell frame, mm.
        max: Point3,
    },
}

impl BeamBreak {
    /// Whether this breaks the beam from `from` to `to` at time `t`.
    pub fn blocks(&self, from: &Point3, to: &Point3, t: f64) -> bool {
        match *self {
            BeamBreak::Interval { start, end } => t >= start && t <= end,
            BeamBreak::Sphere { centre, radius } => {
                let d = to - from;
                let len2 = d.norm_squared();
                if len2 == 0.0 {
                    return false;
                }
                let s = ((centre - from).dot(&d) / len2).clamp(0.0, 1.0);
                (from + s * d - centre).norm() < radius
            }
            BeamBreak::Box { min, max } => {
                // Slab test on the segment.
                let d = to - from;
                let (mut t0, mut t1) = (0.0f64, 1.0f64);
                for i in 0..3 {
                    if d[i].abs() < 1e-300 {
                        if from[i] < min[i] || from[i] > max[i] {
                            return false;
                        }
                    } else {
                        let a = (min[i] - from[i]) / d[i];
                        let b = (max[i] - from[i]) / d[i];
                        t0 = t0.max(a.min(b));
                        t1 = t1.min(a.max(b));
                        if t0 > t1 {
                            return false;
                        }
                    }
                }
                true
            }
        }
    }
}

/// One tracker reading: spherical coordinates in the tracker frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphericalReading {
    /// Time of the reading, s.
    pub time: f64,
    /// Azimuth about the tracker's +Z, from +X towards +Y (rad).
    pub azimuth: f64,
    /// Elevation above the tracker's XY plane (rad).
    pub elevation: f64,
    /// Distance (mm), as reported (with the assumed refractive index).
    pub distance: f64,
}

impl SphericalReading {
    /// The point the reading describes, in the tracker frame.
    pub fn to_tracker_point(&self) -> Point3 {
        let (se, ce) = self.elevation.sin_cos();
        let (sa, ca) = self.azimuth.sin_cos();
        Point3::new(self.distance * ce * ca, self.distance * ce * sa, self.distance * se)
    }

    /// Spherical coordinates of a tracker-frame point (exact, no errors).
    pub fn from_tracker_point(p: &Point3, time: f64) -> SphericalReading {
        let horiz = p.x.hypot(p.y);
        SphericalReading {
            time,
            azimuth: p.y.atan2(p.x),
            elevation: p.z.atan2(horiz),
            distance: p.coords.norm(),
        }
    }
}

/// A laser tracker at a pose in the cell.
#[derive(Debug, Clone, PartialEq)]
pub struct Tracker {
    /// Pose: tracker frame → cell frame.
    pub cell_from_tracker: Transform3,
    /// Transverse MPE, constant part, mm.
    pub mpe_const: f64,
    /// Transverse MPE per length, mm/mm.
    pub mpe_per_length: f64,
    /// Distance MPE, constant part, mm.
    pub distance_mpe_const: f64,
    /// Distance MPE per length, mm/mm.
    pub distance_mpe_per_length: f64,
    /// σ = fraction · MPE (0.5: the MPE read as ~2σ).
    pub sigma_fraction: f64,
    /// True refractive index of the air along the beam.
    pub n_true: f64,
    /// Index the tracker assumes.
    pub n_assumed: f64,
    /// Largest measurable distance (mm).
    pub max_range: f64,
    /// Time windows in which the beam is interrupted.
    pub beam_breaks: Vec<BeamBreak>,
}

impl Tracker {
    /// A tracker at `cell_from_tracker` with the default error model: MPE ±(15 µm + 6 µm/m) for
    /// both the transverse and the distance error, σ = MPE/2, n_true = n_assumed = 1.00027,
    /// 40 m range, no beam breaks.
    pub fn new(cell_from_tracker: Transform3) -> Tracker {
        Tracker {
            cell_from_tracker,
            mpe_const: 15e-3,
            mpe_per_length: 6e-6,
            distance_mpe_const: 15e-3,
            distance_mpe_per_length: 6e-6,
            sigma_fraction: 0.5,
            n_true: 1.00027,
            n_assumed: 1.00027,
            max_range: 40_000.0,
            beam_breaks: Vec::new(),
        }
    }

    /// Transverse standard deviation at distance `l` (mm).
    pub fn sigma_transverse(&self, l: f64) -> f64 {
        self.sigma_fraction * (self.mpe_const + self.mpe_per_length * l)
    }

    /// Distance standard deviation at distance `l` (mm).
    pub fn sigma_distance(&self, l: f64) -> f64 {
        self.sigma_fraction * (self.distance_mpe_const + self.distance_mpe_per_length * l)
    }

    /// The tracker's position in the cell.
    pub fn position(&self) -> Point3 {
        self.cell_from_tracker.apply(&Point3::origin())
    }

    fn geometric(&self, target_cell: &Point3, t: f64) -> Result<Point3, TrackerError> {
        let from = self.position();
        if self.beam_breaks.iter().any(|b| b.blocks(&from, target_cell, t)) {
            return Err(TrackerError::BeamBroken { time_s: t });
        }
        let p = self.cell_from_tracker.inverse().apply(target_cell);
        let d = p.coords.norm();
        if !(d > 1e-6 && d <= self.max_range) {
            return Err(TrackerError::OutOfRange { distance_mm: d });
        }
        Ok(p)
    }

    /// Noise-free reading of a target at `target_cell` at time `t` (still scaled by the
    /// refractive-index mismatch and subject to beam breaks).
    pub fn measure_exact(&self, target_cell: &Point3, t: f64) -> Result<SphericalReading, TrackerError> {
        let p = self.geometric(target_cell, t)?;
        let mut r = SphericalReading::from_tracker_point(&p, t);
        r.distance *= self.n_true / self.n_assumed;
        Ok(r)
    }

    /// Reading with angular and distance noise of the MPE model.
    pub fn measure<R: Rng + ?Sized>(
        &self,
        target_cell: &Point3,
        t: f64,
        rng: &mut R,
    ) -> Result<SphericalReading, TrackerError> {
        let mut r = self.measure_exact(target_cell, t)?;
        let l = r.distance;
        let st = self.sigma_transverse(l);
        r.elevation += gaussian(rng, st / l);
        r.azimuth += gaussian(rng, st / (l * r.elevation.cos().abs().max(1e-6)));
        r.distance += gaussian(rng, self.sigma_distance(l));
        Ok(r)
    }

    /// The cell-frame point of a reading.
    pub fn reading_to_cell(&self, r: &SphericalReading) -> Point3 {
        self.cell_from_tracker.apply(&r.to_tracker_point())
    }

    /// `n` readings of a target whose cell position at time `t` is `target(t)`, at times
    /// `t0, t0 + dt, …` (failed readings are kept as errors).
    pub fn measure_repeated<R: Rng + ?Sized, F: Fn(f64) -> Point3>(
        &self,
        target: F,
        t0: f64,
        dt: f64,
        n: usize,
        rng: &mut R,
    ) -> Vec<Result<SphericalReading, TrackerError>> {
        (0..n)
            .map(|i| {
                let t = t0 + i as f64 * dt;
                self.measure(&target(t), t, rng)
            })
            .collect()
    }
}

/// A target vibrating (sinusoidally) about a centre: `centre + amplitude·sin(2π f t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VibratingTarget {
    /// Centre of the vibration, mm.
    pub centre: Point3,
    /// Amplitude vector (mm).
    pub amplitude: Vector3,
    /// Frequency (Hz).
    pub frequency: f64,
    /// Phase, rad.
    pub phase: f64,
}

impl VibratingTarget {
    /// Position at time `t`.
    pub fn position(&self, t: f64) -> Point3 {
        self.centre + self.amplitude * (std::f64::consts::TAU * self.frequency * t + self.phase).sin()
    }
}

/// Stability of repeated readings: (3D standard deviation about the mean, largest distance from
/// the mean), over the successful readings converted to points by `to_point`; `None` with fewer
/// than two.
pub fn spread(points: &[Point3]) -> Option<(f64, f64)> {
    if points.len() < 2 {
        return None;
    }
    let mean = truepos_math::types::centroid(points);
    let ss: f64 = points.iter().map(|p| (p - mean).norm_squared()).sum();
    let max = points.iter().map(|p| (p - mean).norm()).fold(0.0, f64::max);
    Some(((ss / (points.len() - 1) as f64).sqrt(), max))
}

/// A two-axis inclinometer on a body (machine, part or tracker): reads the body's tilt about X
/// and Y plus a bias, a linear drift and white noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inclinometer {
    /// Bias (rad) of the two readings.
    pub bias: [f64; 2],
    /// Drift (rad/s) of the two readings.
    pub drift: [f64; 2],
    /// Noise σ (rad).
    pub noise: f64,
}

impl Default for Inclinometer {
    /// A precision electronic level: no bias, 0.5 µrad/h drift, 1 µrad noise.
    fn default() -> Self {
        let d = 0.5e-6 / 3600.0;
        Inclinometer { bias: [0.0; 2], drift: [d, -d], noise: 1e-6 }
    }
}

impl Inclinometer {
    /// Reading at time `t` for a body whose true tilt (about X, about Y; rad) is `tilt`.
    pub fn reading<R: Rng + ?Sized>(&self, tilt: [f64; 2], t: f64, rng: &mut R) -> [f64; 2] {
        [0, 1].map(|i| tilt[i] + self.bias[i] + self.drift[i] * t + gaussian(rng, self.noise))
    }

    /// Noise-free reading.
    pub fn reading_exact(&self, tilt: [f64; 2], t: f64) -> [f64; 2] {
        [0, 1].map(|i| tilt[i] + self.bias[i] + self.drift[i] * t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::rng;
    use truepos_math::types::rz;

    fn pose() -> Transform3 {
        Transform3::rigid(rz(0.3), Vector3::new(1000.0, -2000.0, 500.0))
    }

    #[test]
    fn exact_reading_round_trips() {
        let tr = Tracker::new(pose());
        let target = Point3::new(6000.0, 1500.0, 1800.0);
        let r = tr.measure_exact(&target, 0.0).unwrap();
        assert!((tr.reading_to_cell(&r) - target).norm() < 1e-9);
        // Hand: distance is the Euclidean distance from the tracker position.
        assert!((r.distance - (target - Point3::new(1000.0, -2000.0, 500.0)).norm()).abs() < 1e-9);
    }

    #[test]
    fn refractive_index_mismatch_scales_distance() {
        let mut tr = Tracker::new(pose());
        tr.n_true = 1.000271;
        tr.n_assumed = 1.000250;
        let target = Point3::new(11000.0, -2000.0, 500.0); // 10 m along the tracker's rotated X
        let r = tr.measure_exact(&target, 0.0).unwrap();
        // 10 000 mm · (1.000271/1.000250 − 1) = 0.20995 mm.
        assert!((r.distance - 10_000.0 - 10_000.0 * (1.000271 / 1.000250 - 1.0)).abs() < 1e-9);
        assert!((r.distance - 10_000.21).abs() < 1e-3);
    }

    #[test]
    fn noise_follows_the_mpe_model() {
        let tr = Tracker::new(pose());
        let target = tr.cell_from_tracker.apply(&Point3::new(3000.0, 4000.0, 0.0)); // 5 m
        let mut g = rng(9);
        let n = 4000;
        let pts: Vec<Point3> =
            (0..n).map(|i| tr.reading_to_cell(&tr.measure(&target, i as f64, &mut g).unwrap())).collect();
        // σ per direction = (15 + 6·5)/2 = 22.5 µm; 3D σ = √3·22.5 = 39.0 µm. Sampling error of a
        // standard deviation at n = 4000 is ~1.1 %; allow 5 %.
        let (s, _) = spread(&pts).unwrap();
        assert!((s - 3f64.sqrt() * 22.5e-3).abs() < 0.05 * 39e-3, "spread {s}");
        // The MPE is exceeded by a coordinate about 5 % of the time (2σ).
        let along: Vec<f64> =
            pts.iter().map(|p| (p - target).dot(&(target - tr.position()).normalize())).collect();
        let frac = along.iter().filter(|d| d.abs() > 45e-3).count() as f64 / n as f64;
        assert!(frac > 0.03 && frac < 0.07, "fraction beyond MPE {frac}");
    }

    #[test]
    fn beam_breaks_fail_readings() {
        let mut tr = Tracker::new(Transform3::identity());
        tr.beam_breaks = vec![
            BeamBreak::Interval { start: 1.0, end: 2.0 },
            BeamBreak::Sphere { centre: Point3::new(2000.0, 0.0, 0.0), radius: 50.0 },
            BeamBreak::Box { min: Point3::new(500.0, 900.0, -10.0), max: Point3::new(600.0, 1100.0, 10.0) },
        ];
        let ok = Point3::new(3000.0, 500.0, 0.0);
        assert!(tr.measure_exact(&ok, 0.5).is_ok());
        assert!(matches!(tr.measure_exact(&ok, 1.5), Err(TrackerError::BeamBroken { .. })));
        // Behind the sphere on the X axis.
        assert!(tr.measure_exact(&Point3::new(3000.0, 0.0, 0.0), 0.0).is_err());
        // In front of the sphere: fine.
        assert!(tr.measure_exact(&Point3::new(1500.0, 0.0, 0.0), 0.0).is_ok());
        // Through the box: the line to (1100, 2000, 0) passes (550, 1000, 0).
        assert!(tr.measure_exact(&Point3::new(1100.0, 2000.0, 0.0), 0.0).is_err());
    }

    #[test]
    fn a_vibrating_target_spreads_more() {
        let tr = Tracker::new(pose());
        let c = tr.cell_from_tracker.apply(&Point3::new(4000.0, 0.0, 300.0));
        let mut g = rng(3);
        let to_pts = |v: Vec<Result<SphericalReading, TrackerError>>| -> Vec<Point3> {
            v.into_iter().map(|r| tr.reading_to_cell(&r.unwrap())).collect()
        };
        let still = to_pts(tr.measure_repeated(|_| c, 0.0, 0.01, 500, &mut g));
        let vib =
            VibratingTarget { centre: c, amplitude: Vector3::new(0.0, 0.0, 0.1), frequency: 7.3, phase: 0.0 };
        let moving = to_pts(tr.measure_repeated(|t| vib.position(t), 0.0, 0.01, 500, &mut g));
        let (s0, _) = spread(&still).unwrap();
        let (s1, _) = spread(&moving).unwrap();
        // Still: √3·(15+24)/2 ≈ 34 µm; a 0.1 mm sine adds 0.1/√2 ≈ 71 µm rms in z: ≈ 78 µm.
        assert!(s1 > 1.8 * s0, "still {s0}, vibrating {s1}");
    }

    #[test]
    fn inclinometer_bias_drift_noise() {
        let inc = Inclinometer { bias: [2e-6, -1e-6], drift: [1e-9, 0.0], noise: 1e-6 };
        let mut g = rng(5);
        let n = 2000;
        let mean0: f64 = (0..n).map(|_| inc.reading([10e-6, 0.0], 1000.0, &mut g)[0]).sum::<f64>() / n as f64;
        // 10 + 2 + 1 µrad; mean of 2000 draws has σ 0.022 µrad.
        assert!((mean0 - 13e-6).abs() < 0.1e-6, "{mean0}");
        let r = inc.reading_exact([0.0, 5e-6], 0.0);
        assert!((r[0] - 2e-6).abs() < 1e-18 && (r[1] - 4e-6).abs() < 1e-18);
    }
}
