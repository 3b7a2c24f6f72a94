//! Time-stamped streams: validation and interpolation of the machine stream onto the probe clock.
//!
//! Entry points: [`Streams`] (borrowed machine and probe data), [`check_stream`],
//! [`Streams::check`] (sorted, no duplicates, finite, overlapping) and [`machine_at`] (machine
//! position at shifted probe stamps, one merge pass, no allocation per sample).

use crate::LatencyError;

/// Which stream an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Which {
    /// The machine position stream.
    Machine,
    /// The probe deflection stream.
    Probe,
}

impl std::fmt::Display for Which {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Which::Machine => "machine",
            Which::Probe => "probe",
        })
    }
}

/// Machine positions (mm) and probe deflections (mm) with their time stamps (s) on the master
/// clock. `machine[i]` is the encoder position at `machine_t[i]`; `probe[j]` the deflection
/// (a, b, c) along the machine axes at `probe_t[j]`.
#[derive(Clone, Copy, Debug)]
pub struct Streams<'a> {
    /// Machine time stamps, s.
    pub machine_t: &'a [f64],
    /// Machine positions x, y, z at `machine_t`, mm.
    pub machine: &'a [[f64; 3]],
    /// Probe time stamps, s.
    pub probe_t: &'a [f64],
    /// Stylus deflections a, b, c at `probe_t`, mm.
    pub probe: &'a [[f64; 3]],
}

/// Check one stream: at least two samples, finite values, strictly increasing time stamps.
/// Errors carry the 0-based sample index.
pub fn check_stream(which: Which, t: &[f64], v: &[[f64; 3]]) -> Result<(), LatencyError> {
    if t.len() != v.len() {
        return Err(LatencyError::LengthMismatch { which, times: t.len(), values: v.len() });
    }
    if t.len() < 2 {
        return Err(LatencyError::TooShort { which, n: t.len() });
    }
    for i in 0..t.len() {
        if !t[i].is_finite() || !v[i].iter().all(|x| x.is_finite()) {
            return Err(LatencyError::NotFinite { which, index: i });
        }
        if i > 0 {
            if t[i] == t[i - 1] {
                return Err(LatencyError::DuplicateStamp { which, index: i, t: t[i] });
            }
            if t[i] < t[i - 1] {
                return Err(LatencyError::NotIncreasing { which, index: i, t: t[i], previous: t[i - 1] });
            }
        }
    }
    Ok(())
}

impl Streams<'_> {
    /// Validate both streams and that their time ranges overlap.
    pub fn check(&self) -> Result<(), LatencyError> {
        check_stream(Which::Machine, self.machine_t, self.machine)?;
        check_stream(Which::Probe, self.probe_t, self.probe)?;
        let (m0, m1) = (self.machine_t[0], self.machine_t[self.machine_t.len() - 1]);
        let (p0, p1) = (self.probe_t[0], self.probe_t[self.probe_t.len() - 1]);
        if m1 <= p0 || p1 <= m0 {
            return Err(LatencyError::NoOverlap { machine: (m0, m1), probe: (p0, p1) });
        }
        Ok(())
    }

    /// Typical sample interval of the machine stream (median-free: span / (n − 1)).
    pub fn machine_dt(&self) -> f64 {
        let n = self.machine_t.len();
        (self.machine_t[n - 1] - self.machine_t[0]) / (n - 1) as f64
    }

    /// Typical sample interval of the probe stream.
    pub fn probe_dt(&self) -> f64 {
        let n = self.probe_t.len();
        (self.probe_t[n - 1] - self.probe_t[0]) / (n - 1) as f64
    }
}

/// Machine position interpolated linearly at `probe_t[j] + shift` for every probe stamp, in one
/// merge pass (both sorted). Stamps outside the machine's time range give NaN (no
/// extrapolation). `out` is cleared and refilled (reuse it to avoid allocation).
pub fn machine_at(
    machine_t: &[f64],
    machine: &[[f64; 3]],
    probe_t: &[f64],
    shift: f64,
    out: &mut Vec<[f64; 3]>,
) {
    out.clear();
    out.reserve(probe_t.len());
    let n = machine_t.len();
    if n < 2 {
        out.extend(probe_t.iter().map(|_| [f64::NAN; 3]));
        return;
    }
    let (t0, t1) = (machine_t[0], machine_t[n - 1]);
    let mut i = 0usize;
    for &tp in probe_t {
        let t = tp + shift;
        if !(t >= t0 && t <= t1) {
            out.push([f64::NAN; 3]);
            continue;
        }
        while i + 2 < n && machine_t[i + 1] <= t {
            i += 1;
        }
        let (a, b) = (machine[i], machine[i + 1]);
        let w = (t - machine_t[i]) / (machine_t[i + 1] - machine_t[i]);
        out.push([a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2])]);
    }
}

/// Machine position and velocity (finite difference of the bracketing samples) at time `t`
/// by binary search; `None` outside the machine's time range.
#[inline]
pub fn machine_pos_vel(machine_t: &[f64], machine: &[[f64; 3]], t: f64) -> Option<([f64; 3], [f64; 3])> {
    let n = machine_t.len();
    if n < 2 || !(t >= machine_t[0] && t <= machine_t[n - 1]) {
        return None;
    }
    let i = machine_t.partition_point(|&v| v <= t).saturating_sub(1).min(n - 2);
    let h = machine_t[i + 1] - machine_t[i];
    let w = (t - machine_t[i]) / h;
    let (a, b) = (machine[i], machine[i + 1]);
    let mut p = [0.0; 3];
    let mut v = [0.0; 3];
    for k in 0..3 {
        p[k] = a[k] + w * (b[k] - a[k]);
        v[k] = (b[k] - a[k]) / h;
    }
    Some((p, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_of_a_ramp_is_exact_at_any_rate_and_shift() {
        // Machine at 1 kHz moving x = 10·t + 1; probe at 3.7 kHz. Linear data interpolate exactly.
        let mt: Vec<f64> = (0..1000).map(|i| i as f64 * 1e-3).collect();
        let m: Vec<[f64; 3]> = mt.iter().map(|t| [10.0 * t + 1.0, -2.0 * t, 0.5]).collect();
        let pt: Vec<f64> = (0..3000).map(|i| 0.01 + i as f64 / 3700.0).collect();
        let mut out = Vec::new();
        machine_at(&mt, &m, &pt, 1.234e-4, &mut out);
        for (t, p) in pt.iter().zip(&out) {
            let tt = t + 1.234e-4;
            assert!((p[0] - (10.0 * tt + 1.0)).abs() < 1e-12);
            assert!((p[1] + 2.0 * tt).abs() < 1e-12);
        }
        let (p, v) = machine_pos_vel(&mt, &m, 0.5004).unwrap();
        assert!((p[0] - 6.004).abs() < 1e-12 && (v[0] - 10.0).abs() < 1e-9);
        // Outside the machine range: NaN, never extrapolated.
        machine_at(&mt, &m, &[-1.0, 5.0], 0.0, &mut out);
        assert!(out.iter().all(|p| p[0].is_nan()));
    }

    #[test]
    fn checks_find_unsorted_duplicate_nonfinite_and_disjoint() {
        let v = [[0.0; 3]; 4];
        assert!(matches!(
            check_stream(Which::Probe, &[0.0, 1.0, 0.5, 2.0], &v),
            Err(LatencyError::NotIncreasing { index: 2, .. })
        ));
        assert!(matches!(
            check_stream(Which::Probe, &[0.0, 1.0, 1.0, 2.0], &v),
            Err(LatencyError::DuplicateStamp { index: 2, .. })
        ));
        let mut bad = v;
        bad[3][1] = f64::NAN;
        assert!(matches!(
            check_stream(Which::Machine, &[0.0, 1.0, 2.0, 3.0], &bad),
            Err(LatencyError::NotFinite { index: 3, .. })
        ));
        let s = Streams {
            machine_t: &[0.0, 1.0, 2.0, 3.0],
            machine: &v,
            probe_t: &[4.0, 5.0, 6.0, 7.0],
            probe: &v,
        };
        assert!(matches!(s.check(), Err(LatencyError::NoOverlap { .. })));
    }
}
