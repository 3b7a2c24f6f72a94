//! User parameters of the end-point control loop and the alarm set points.

/// Parameters of [`crate::run::run_program`]. Lengths in mm, temperatures in °C, angles in µrad.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Text that marks a measurement block when it occurs in a comment (case-insensitive).
    pub keyword: String,
    /// A stop succeeds when the 3D error is at most this.
    pub threshold_mm: f64,
    /// Correction moves per stop at most.
    pub max_iterations: usize,
    /// No single correction move is longer than this (longer ones are clipped and alarmed).
    pub max_single_correction_mm: f64,
    /// The accumulated correction offset for a part never exceeds this.
    pub max_total_correction_mm: f64,
    /// Repeated tracker samples per reading.
    pub samples: usize,
    /// A reading is stable when the standard deviation of its samples is at most this on every axis.
    pub stable_std_mm: f64,
    /// Attempts to get a stable reading before the stop fails.
    pub stable_attempts: usize,
    /// Dwell after every move before the first reading (s): lets the structure settle.
    pub dwell_s: f64,
    /// Wait between unstable attempts (s).
    pub settle_wait_s: f64,
    /// Lowest temperature the run accepts, °C.
    pub temperature_min_c: f64,
    /// Highest temperature the run accepts, °C.
    pub temperature_max_c: f64,
    /// Temperature change since the last orientation that forces a new orientation.
    pub temperature_change_max_c: f64,
    /// Differential inclination change (any inclinometer) that forces a new orientation.
    pub inclination_limit_urad: f64,
    /// Re-scale when the part temperature has moved by this since the last scale.
    pub autoscale_step_c: f64,
    /// Update the trackers' refractive index when it has changed by more than this.
    pub refractive_update_ppm: f64,
    /// Coefficient of thermal expansion of the part (ppm/°C) for the auto-scaling cross-check.
    pub part_cte_ppm_per_c: f64,
    /// Re-orient on the part targets every this many measurement stops (0: only when forced).
    pub orient_every: usize,
    /// Fit a scale in the real-time orientation.
    pub orient_with_scale: bool,
    /// What to do when a tracker's beam breaks.
    pub beam_recovery: BeamRecovery,
    /// Send corrections (false: measure and report only, the machine's native accuracy).
    pub correct: bool,
    /// Orient the program on the part targets (initially, on alarms, on temperature steps).
    pub orient: bool,
    /// The machine's travel (mm, machine frame): `(min, max)` per axis. No commanded position and
    /// no corrected position may leave it: a block outside stops the run, a correction that
    /// would leave it is refused (alarm `travel_limit`). `None`: not checked.
    pub travel_mm: Option<([f64; 3], [f64; 3])>,
}

/// What to do when the beam is broken at a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BeamRecovery {
    /// Wait for the operator to bring the reflector back into the beam.
    Manual,
    /// Point the tracker at the measurement position and wait (absolute-distance trackers only).
    LookAhead,
    /// Return the machine to the last measured point, reacquire, come back.
    LookBack,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            keyword: "(MSG,Measure SOMaC)".into(),
            threshold_mm: 0.025,
            max_iterations: 4,
            max_single_correction_mm: 2.0,
            max_total_correction_mm: 5.0,
            samples: 5,
            stable_std_mm: 0.030,
            stable_attempts: 8,
            settle_wait_s: 0.5,
            dwell_s: 1.0,
            temperature_min_c: 10.0,
            temperature_max_c: 35.0,
            temperature_change_max_c: 3.0,
            inclination_limit_urad: 50.0,
            autoscale_step_c: 2.0,
            refractive_update_ppm: 0.5,
            part_cte_ppm_per_c: 23.0,
            orient_every: 0,
            orient_with_scale: true,
            beam_recovery: BeamRecovery::LookAhead,
            correct: true,
            orient: true,
            travel_mm: None,
        }
    }
}

/// Largest accepted `samples` (tracker samples per reading).
pub const MAX_SAMPLES: usize = 1000;
/// Largest accepted `max_iterations` (correction moves per stop).
pub const MAX_ITERATIONS: usize = 100;
/// Largest accepted `stable_attempts`.
pub const MAX_ATTEMPTS: usize = 1000;
/// Largest accepted `orient_every` (measurement stops).
pub const MAX_ORIENT_EVERY: usize = 1_000_000;

impl Params {
    /// Whether `p` (mm, machine frame) is within the travel (always, when none is given).
    pub fn within_travel(&self, p: &truepos_math::Point3) -> bool {
        match self.travel_mm {
            None => true,
            Some((lo, hi)) => (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k]),
        }
    }

    /// Check the parameters make sense; the message names the offending one.
    pub fn validate(&self) -> Result<(), String> {
        let pos = [
            ("threshold_mm", self.threshold_mm),
            ("max_single_correction_mm", self.max_single_correction_mm),
            ("max_total_correction_mm", self.max_total_correction_mm),
            ("stable_std_mm", self.stable_std_mm),
            ("autoscale_step_c", self.autoscale_step_c),
            ("refractive_update_ppm", self.refractive_update_ppm),
            ("inclination_limit_urad", self.inclination_limit_urad),
            ("temperature_change_max_c", self.temperature_change_max_c),
        ];
        for (n, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{n} must be a positive number, got {v}"));
            }
        }
        if self.samples < 2 {
            return Err("samples must be at least 2 (stability needs a spread)".into());
        }
        if self.max_iterations == 0 || self.stable_attempts == 0 {
            return Err("max_iterations and stable_attempts must be at least 1".into());
        }
        // Documented limits of the counts: beyond them a value is a typo, and a run would
        // never end (or allocate without bound).
        for (n, v, max) in [
            ("samples", self.samples, MAX_SAMPLES),
            ("max_iterations", self.max_iterations, MAX_ITERATIONS),
            ("stable_attempts", self.stable_attempts, MAX_ATTEMPTS),
            ("orient_every", self.orient_every, MAX_ORIENT_EVERY),
        ] {
            if v > max {
                return Err(format!("{n} must be at most {max}, got {v}"));
            }
        }
        for (n, v) in [("dwell_s", self.dwell_s), ("settle_wait_s", self.settle_wait_s)] {
            if !(v.is_finite() && (0.0..=3600.0).contains(&v)) {
                return Err(format!("{n} must be between 0 and 3600 s, got {v}"));
            }
        }
        if !self.part_cte_ppm_per_c.is_finite() || self.part_cte_ppm_per_c.abs() > 1000.0 {
            return Err(format!(
                "part_cte_ppm_per_c must be a finite number within ±1000, got {}",
                self.part_cte_ppm_per_c
            ));
        }
        if !(-50.0..=100.0).contains(&self.temperature_min_c)
            || !(-50.0..=100.0).contains(&self.temperature_max_c)
        {
            return Err("temperature_min_c and temperature_max_c must lie within -50 to 100 °C".into());
        }
        if let Some((lo, hi)) = self.travel_mm {
            if !(0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] < hi[k]) {
                return Err(format!("travel must have finite min < max on every axis, got {lo:?} .. {hi:?}"));
            }
        }
        if self.keyword.trim().is_empty() {
            return Err("keyword must not be empty (it marks the measurement blocks)".into());
        }
        if self.temperature_min_c.is_nan()
            || self.temperature_max_c.is_nan()
            || self.temperature_min_c >= self.temperature_max_c
        {
            return Err("temperature_min_c must be below temperature_max_c".into());
        }
        if self.max_single_correction_mm > self.max_total_correction_mm {
            return Err("max_single_correction_mm cannot exceed max_total_correction_mm".into());
        }
        Ok(())
    }
}
