//! The touch methods: known artefact size, several speeds, single point in and out, and the
//! per-axis variants.
//!
//! Entry points: [`artefact`], [`speeds`], [`inout`], [`speed_groups`], [`per_axis_speeds`].

use crate::contact::Contact;
use crate::geom::{self, DelayMode, Feature, FitSpec};
use crate::stream::Streams;
use crate::LatencyError;
use truepos_math::Vector3;

/// A delay with its standard uncertainty and the per-method details.
#[derive(Clone, Debug, Default)]
pub struct TouchResult {
    /// The fitted delay, s.
    pub delay: f64,
    /// Standard uncertainty of the delay, s.
    pub u_delay: f64,
    /// RMS residual of the fit, mm.
    pub rms: f64,
    /// Signed stylus-centre static size (speeds method; the known size for artefact).
    pub static_size: Option<f64>,
    /// Standard uncertainty of `static_size`, mm.
    pub u_static_size: Option<f64>,
    /// (mean speed mm/s, signed stylus-centre size mm) per speed group.
    pub per_speed: Vec<(f64, f64)>,
    /// Separate delays per axis, when the per-axis fit was run.
    pub per_axis: Option<PerAxis>,
    /// Notes for people about the data or the result.
    pub warnings: Vec<String>,
}

/// Separate delays for X, Y, Z (`None` where the data cannot determine one).
#[derive(Clone, Debug, Default)]
pub struct PerAxis {
    /// Delay of X, Y, Z, s (`None` where not observable).
    pub delay: [Option<f64>; 3],
    /// Standard uncertainty of each axis delay, s.
    pub u_delay: [Option<f64>; 3],
}

/// Axes whose delays differ by more than this many combined standard uncertainties have
/// different delays (3 u: a false alarm in ~0.3 % of cases for normal errors).
pub const AXES_DIFFER_K: f64 = 3.0;

impl PerAxis {
    /// The pair of determined axes that differ most relative to their combined standard
    /// uncertainty: `(|Δdelay|, u(Δdelay))` in s, or `None` with fewer than two axes determined.
    pub fn largest_difference(&self) -> Option<(f64, f64)> {
        let obs: Vec<(f64, f64)> = (0..3).filter_map(|k| Some((self.delay[k]?, self.u_delay[k]?))).collect();
        obs.iter()
            .enumerate()
            .flat_map(|(i, a)| obs[i + 1..].iter().map(move |b| ((a.0 - b.0).abs(), a.1.hypot(b.1))))
            .max_by(|x, y| (x.0 / x.1).total_cmp(&(y.0 / y.1)))
    }
}

/// Known size: fit the feature with its known (signed, stylus-centre) size and the delay.
pub fn artefact(
    feature: Feature,
    contacts: &[Contact],
    size: f64,
    per_axis: bool,
) -> Result<TouchResult, LatencyError> {
    let spec = FitSpec { size: Some(size), fixed_delay: [0.0; 3], delay: DelayMode::Common };
    let f = geom::fit(feature, contacts, spec)?;
    let mut out = TouchResult {
        delay: f.delay[0],
        u_delay: f.u_delay[0],
        rms: f.rms,
        static_size: Some(size),
        ..Default::default()
    };
    let speeds: Vec<f64> = contacts.iter().map(|c| c.speed()).collect();
    let (lo, hi) = speeds.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    if hi > 1.1 * lo {
        out.warnings.push(format!(
            "contact speeds range from {lo:.3} to {hi:.3} mm/s; each point is corrected with its own velocity"
        ));
    }
    if f.dof == 0 {
        out.warnings
            .push("no redundant contacts: the uncertainty comes from the extrapolation noise alone".into());
    }
    if per_axis {
        let mask = geom::axes_with_opposite_pairs(contacts);
        let mut pa = PerAxis::default();
        if mask.iter().any(|&b| b) {
            let spec =
                FitSpec { size: Some(size), fixed_delay: [f.delay[0]; 3], delay: DelayMode::PerAxis(mask) };
            let g = geom::fit(feature, contacts, spec)?;
            for (k, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
                pa.delay[k] = Some(g.delay[k]);
                pa.u_delay[k] = Some(g.u_delay[k]);
            }
        }
        for (k, name) in ["X", "Y", "Z"].iter().enumerate() {
            if !mask[k] {
                out.warnings
                    .push(format!("no opposite contacts along {name}: its own delay is not observable"));
            }
        }
        out.per_axis = Some(pa);
    }
    Ok(out)
}

/// Group contacts by speed: sorted speeds split where one is more than 10 % above the last.
pub fn speed_groups(contacts: &[Contact]) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..contacts.len()).collect();
    order.sort_by(|&a, &b| contacts[a].speed().total_cmp(&contacts[b].speed()));
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut last = f64::NAN;
    for i in order {
        let s = contacts[i].speed();
        if groups.is_empty() || s > 1.1 * last {
            groups.push(Vec::new());
        }
        if let Some(g) = groups.last_mut() {
            g.push(i);
        }
        last = s;
    }
    groups
}

/// Weighted straight line `y = a + b·x` with standard uncertainties from the stated weights,
/// inflated by the Birge ratio when the scatter exceeds them: (a, b, u_a, u_b, birge).
pub fn weighted_line(x: &[f64], y: &[f64], u: &[f64]) -> Option<(f64, f64, f64, f64, f64)> {
    let n = x.len();
    if n < 2 {
        return None;
    }
    let w: Vec<f64> = u.iter().map(|u| 1.0 / (u * u).max(1e-300)).collect();
    let sw: f64 = w.iter().sum();
    let mx = x.iter().zip(&w).map(|(x, w)| x * w).sum::<f64>() / sw;
    let my = y.iter().zip(&w).map(|(y, w)| y * w).sum::<f64>() / sw;
    let sxx: f64 = x.iter().zip(&w).map(|(x, w)| w * (x - mx).powi(2)).sum();
    if !(sxx > 0.0) {
        return None;
    }
    let sxy: f64 = (0..n).map(|i| w[i] * (x[i] - mx) * (y[i] - my)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let chi2: f64 = (0..n).map(|i| w[i] * (y[i] - a - b * x[i]).powi(2)).sum();
    let birge = if n > 2 { (chi2 / (n - 2) as f64).sqrt() } else { 1.0 };
    let k = birge.max(1.0);
    Some((a, b, k * (1.0 / sw + mx * mx / sxx).sqrt(), k * (1.0 / sxx).sqrt(), birge))
}

/// Several speeds, size unknown: the size of each speed group is linear in the speed; its
/// gradient gives the delay and its intercept the static size.
///
/// For each group `g` the fitted (signed, stylus-centre) size obeys `S_g = S₀ − w_g·D` with
/// `w_g = ∂S/∂D` of the corrected points (`2·speed` for retract on an outer feature; the sign
/// follows the direction of travel). A weighted line of `S_g` against `w_g` gives `D = −slope`
/// and `S₀ = intercept`.
pub fn speeds(feature: Feature, contacts: &[Contact], per_axis: bool) -> Result<TouchResult, LatencyError> {
    let groups = speed_groups(contacts);
    if groups.len() < 2 {
        let s = contacts.iter().map(|c| c.speed()).sum::<f64>() / contacts.len().max(1) as f64;
        return Err(LatencyError::SingleSpeed(s));
    }
    let mut out = TouchResult::default();
    let (mut xs, mut ys, mut us) = (vec![], vec![], vec![]);
    let eps = 1e-4;
    let mut rms2 = 0.0;
    let mut n_rms = 0.0;
    for g in &groups {
        let cs: Vec<Contact> = g.iter().map(|&i| contacts[i].clone()).collect();
        let sp = cs.iter().map(|c| c.speed()).sum::<f64>() / cs.len() as f64;
        let spec0 = FitSpec { size: None, fixed_delay: [0.0; 3], delay: DelayMode::None };
        let f0 = match geom::fit(feature, &cs, spec0) {
            Ok(f) => f,
            Err(e) => {
                out.warnings.push(format!("speed {sp:.3} mm/s ({} contacts) skipped: {e}", cs.len()));
                continue;
            }
        };
        let f1 = geom::fit(feature, &cs, FitSpec { fixed_delay: [eps; 3], ..spec0 })?;
        let w = (f1.size - f0.size) / eps;
        // A size from an exact fit has no scatter of its own: use the stated point uncertainty.
        let u = f0.u_size.max(1e-9);
        xs.push(w);
        ys.push(f0.size);
        us.push(u);
        rms2 += f0.rms * f0.rms * cs.len() as f64;
        n_rms += cs.len() as f64;
        out.per_speed.push((sp, f0.size));
    }
    if xs.len() < 2 {
        return Err(LatencyError::SingleSpeed(out.per_speed.first().map_or(0.0, |p| p.0)));
    }
    let (mut a, mut b, mut ua, mut ub, _) = weighted_line(&xs, &ys, &us)
        .ok_or_else(|| LatencyError::Underdetermined("the speed groups do not differ in speed".into()))?;
    // One speed group whose size departs from the line by more than 3 of its own standard
    // uncertainties (and 3 of the line's scatter) does not follow the linear model (e.g. the
    // servo has not settled at that speed): leave it out, with a warning, when ≥ 4 groups remain.
    if xs.len() >= 5 {
        let worst = (0..xs.len())
            .map(|i| (i, ((ys[i] - a - b * xs[i]) / us[i]).abs()))
            .max_by(|p, q| p.1.total_cmp(&q.1));
        if let Some((i, z)) = worst {
            if z > 3.0 {
                let (mut x2, mut y2, mut u2) = (xs.clone(), ys.clone(), us.clone());
                x2.remove(i);
                y2.remove(i);
                u2.remove(i);
                if let Some(f) = weighted_line(&x2, &y2, &u2) {
                    let zi = ((ys[i] - f.0 - f.1 * xs[i]) / us[i]).abs();
                    if zi > 3.0 {
                        out.warnings.push(format!(
                            "speed {:.3} mm/s left out: its size departs from the size-speed line by {:.1} standard uncertainties",
                            out.per_speed[i].0, zi
                        ));
                        (a, b, ua, ub) = (f.0, f.1, f.2, f.3);
                    }
                }
            }
        }
    }
    out.delay = -b;
    out.u_delay = ub;
    out.static_size = Some(a);
    out.u_static_size = Some(ua);
    out.rms = (rms2 / n_rms.max(1.0)).sqrt();
    if xs.len() == 2 {
        out.warnings.push("only two speeds: the uncertainty cannot be checked against the scatter".into());
    }
    if per_axis {
        out.per_axis = Some(per_axis_speeds(contacts, &mut out.warnings));
    }
    Ok(out)
}

/// Per-axis delays from contacts repeated at the same surface points at several speeds: the
/// apparent position along the normal of each point is `a_g − Σ_k D_k·v_k·n_k`; centring within
/// each point group leaves a linear least-squares problem in `D_x, D_y, D_z`.
pub fn per_axis_speeds(contacts: &[Contact], warnings: &mut Vec<String>) -> PerAxis {
    // Group by normal direction (within 15°).
    let cos = 15f64.to_radians().cos();
    let mut groups: Vec<(Vector3, Vec<usize>)> = Vec::new();
    for (i, c) in contacts.iter().enumerate() {
        match groups.iter_mut().find(|g| g.0.dot(&c.normal) > cos) {
            Some(g) => g.1.push(i),
            None => groups.push((c.normal, vec![i])),
        }
    }
    let mut ata = truepos_math::Matrix3::zeros();
    let mut atb = Vector3::zeros();
    let mut rows: Vec<(Vector3, f64, f64)> = Vec::new();
    for (n, g) in &groups {
        if g.len() < 2 {
            continue;
        }
        let w: Vec<f64> = g.iter().map(|&i| 1.0 / contacts[i].u_point.powi(2)).collect();
        let sw: f64 = w.iter().sum();
        let xs: Vec<Vector3> = g.iter().map(|&i| contacts[i].velocity.component_mul(n)).collect();
        let ys: Vec<f64> = g.iter().map(|&i| n.dot(&contacts[i].point.coords)).collect();
        let mx = xs.iter().zip(&w).map(|(x, w)| x * *w).sum::<Vector3>() / sw;
        let my = ys.iter().zip(&w).map(|(y, w)| y * w).sum::<f64>() / sw;
        for k in 0..g.len() {
            // y − ȳ = −(x − x̄)·D
            let a = -(xs[k] - mx);
            let b = ys[k] - my;
            ata += a * a.transpose() * w[k];
            atb += a * b * w[k];
            rows.push((a, b, w[k]));
        }
    }
    let mut pa = PerAxis::default();
    let max_diag = (0..3).map(|k| ata[(k, k)]).fold(0.0f64, f64::max);
    let mask: Vec<bool> = (0..3).map(|k| ata[(k, k)] > 1e-6 * max_diag && max_diag > 0.0).collect();
    let idx: Vec<usize> = (0..3).filter(|&k| mask[k]).collect();
    let names = ["X", "Y", "Z"];
    for k in 0..3 {
        if !mask[k] {
            warnings.push(format!(
                "no contacts moving along {} at several speeds: its own delay is not observable",
                names[k]
            ));
        }
    }
    if idx.is_empty() {
        return pa;
    }
    let m = idx.len();
    let sub = nalgebra::DMatrix::from_fn(m, m, |a, b| ata[(idx[a], idx[b])]);
    let rhs = nalgebra::DVector::from_fn(m, |a, _| atb[idx[a]]);
    let Some(chol) = sub.clone().cholesky() else {
        warnings.push("per-axis delays: the normal equations are singular".into());
        return pa;
    };
    let d = chol.solve(&rhs);
    let inv = chol.inverse();
    let dof = rows.len() as f64 - (groups.iter().filter(|g| g.1.len() >= 2).count() + m) as f64;
    let chi2: f64 = rows
        .iter()
        .map(|(a, b, w)| {
            let pred: f64 = (0..m).map(|j| a[idx[j]] * d[j]).sum();
            w * (b - pred).powi(2)
        })
        .sum();
    let k = if dof > 0.0 { (chi2 / dof).sqrt().max(1.0) } else { 1.0 };
    for (j, &ax) in idx.iter().enumerate() {
        pa.delay[ax] = Some(d[j]);
        pa.u_delay[ax] = Some(inv[(j, j)].max(0.0).sqrt() * k);
    }
    pa
}

/// Line through the samples `(t, y)` as (value at mean time, slope, mean time, u_value, u_slope).
fn flank(tx: &[(f64, f64)]) -> Option<(f64, f64, f64, f64, f64)> {
    let n = tx.len();
    if n < 3 {
        return None;
    }
    let nf = n as f64;
    let mt = tx.iter().map(|p| p.0).sum::<f64>() / nf;
    let my = tx.iter().map(|p| p.1).sum::<f64>() / nf;
    let stt: f64 = tx.iter().map(|p| (p.0 - mt).powi(2)).sum();
    if !(stt > 0.0) {
        return None;
    }
    let b = tx.iter().map(|p| (p.0 - mt) * (p.1 - my)).sum::<f64>() / stt;
    let ssr: f64 = tx.iter().map(|p| (p.1 - my - b * (p.0 - mt)).powi(2)).sum();
    let s2 = ssr / (nf - 2.0).max(1.0);
    Some((my, b, mt, (s2 / nf).sqrt(), (s2 / stt).sqrt()))
}

/// Time at which a flank line reaches `level`, with its standard uncertainty.
fn crossing(f: (f64, f64, f64, f64, f64), level: f64) -> (f64, f64) {
    let (a, b, mt, ua, ub) = f;
    let dt = (level - a) / b;
    (mt + dt, (ua * ua + dt * dt * ub * ub).sqrt() / b.abs())
}

/// Midpoint time of a peaked signal `(t, depth)` with its uncertainty: lines through the
/// rising and falling flanks between 30 % and 70 % of `height` below the peak, crossed at 50 %.
fn midpoint(tx: &[(f64, f64)], peak_value: f64, height: f64) -> Option<(f64, f64, f64, f64)> {
    let ip = tx.iter().enumerate().max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?.0;
    let band = |v: f64| {
        let below = peak_value - v;
        below >= 0.3 * height && below <= 0.7 * height
    };
    let rise: Vec<(f64, f64)> = tx[..=ip].iter().copied().filter(|p| band(p.1)).collect();
    let fall: Vec<(f64, f64)> = tx[ip..].iter().copied().filter(|p| band(p.1)).collect();
    let (fr, ff) = (flank(&rise)?, flank(&fall)?);
    let level = peak_value - 0.5 * height;
    let (t1, u1) = crossing(fr, level);
    let (t2, u2) = crossing(ff, level);
    Some((0.5 * (t1 + t2), 0.5 * (u1 * u1 + u2 * u2).sqrt(), fr.1, ff.1))
}

/// Single point in and out: for each contact, the time between the extremum of the machine
/// position along the normal and the extremum of the deflection (each located sub-sample as
/// the midpoint of its two flanks); contacts combined by weighted mean. Returns also the
/// per-contact delays (s) with their uncertainties.
pub fn inout(
    s: &Streams,
    contacts: &[Contact],
    per_axis: bool,
) -> Result<(TouchResult, Vec<(f64, f64)>), LatencyError> {
    let mut out = TouchResult::default();
    let mut each = Vec::new();
    let mut axis_of = Vec::new();
    for c in contacts {
        let n = c.normal;
        let tp: Vec<(f64, f64)> = (c.start..c.end)
            .map(|j| {
                let d = s.probe[j];
                (s.probe_t[j], d[0] * n.x + d[1] * n.y + d[2] * n.z)
            })
            .collect();
        let h = c.peak_deflection;
        let Some((mid_p, u_p, rp, fp)) = midpoint(&tp, h, h) else { continue };
        // Machine: depth −(m·n) over a window twice the contact's duration around it.
        let (t0, t1) = (s.probe_t[c.start], s.probe_t[c.end - 1]);
        let span = t1 - t0;
        let i0 = s.machine_t.partition_point(|&t| t < t0 - span);
        let i1 = s.machine_t.partition_point(|&t| t <= t1 + span);
        let tm: Vec<(f64, f64)> = (i0..i1)
            .map(|i| {
                let m = s.machine[i];
                (s.machine_t[i], -(m[0] * n.x + m[1] * n.y + m[2] * n.z))
            })
            .collect();
        let Some(peak_m) = tm.iter().map(|p| p.1).max_by(f64::total_cmp) else { continue };
        let Some((mid_m, u_m, rm, fm)) = midpoint(&tm, peak_m, h) else { continue };
        if (rp.abs() - fp.abs()).abs() > 0.05 * rp.abs().max(fp.abs())
            || (rm.abs() - fm.abs()).abs() > 0.05 * rm.abs().max(fm.abs())
        {
            out.warnings.push(format!(
                "contact at t = {:.4} s: approach and retract speeds differ by more than 5 %; the in-out midpoint is biased",
                c.t_peak
            ));
        }
        each.push((mid_m - mid_p, (u_m * u_m + u_p * u_p).sqrt()));
        axis_of.push(n.iamax());
    }
    if each.is_empty() {
        return Err(LatencyError::Underdetermined(
            "no contact has clean in and out flanks (30–70 % of the peak deflection) for the in-out method"
                .into(),
        ));
    }
    let (d, u, birge) = weighted_mean(&each);
    out.delay = d;
    out.u_delay = u;
    out.rms = 0.0;
    if each.len() > 1 && birge > 2.0 {
        out.warnings
            .push(format!("the contacts' delays scatter {birge:.1}× more than their stated uncertainties"));
    }
    if per_axis {
        let mut pa = PerAxis::default();
        for k in 0..3 {
            let sel: Vec<(f64, f64)> =
                each.iter().zip(&axis_of).filter(|(_, &a)| a == k).map(|(e, _)| *e).collect();
            if sel.is_empty() {
                out.warnings.push(format!(
                    "no in-out contact along {}: its own delay is not observable",
                    ["X", "Y", "Z"][k]
                ));
                continue;
            }
            let (dk, uk, _) = weighted_mean(&sel);
            pa.delay[k] = Some(dk);
            pa.u_delay[k] = Some(uk);
        }
        out.per_axis = Some(pa);
    }
    Ok((out, each))
}

/// Weighted mean of `(value, u)` with its uncertainty (inflated by the Birge ratio when the
/// scatter exceeds the stated uncertainties) and the Birge ratio.
pub fn weighted_mean(v: &[(f64, f64)]) -> (f64, f64, f64) {
    let w: Vec<f64> = v.iter().map(|(_, u)| 1.0 / (u * u).max(1e-30)).collect();
    let sw: f64 = w.iter().sum();
    let m = v.iter().zip(&w).map(|((x, _), w)| x * w).sum::<f64>() / sw;
    let birge = if v.len() > 1 {
        (v.iter().zip(&w).map(|((x, _), w)| w * (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    } else {
        1.0
    };
    (m, (1.0 / sw).sqrt() * birge.max(1.0), birge)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The most significant pair wins (not the largest raw difference); one axis is not a pair.
    #[test]
    fn largest_difference_is_the_most_significant_pair() {
        let pa = PerAxis {
            delay: [Some(10e-6), Some(14e-6), Some(30e-6)],
            u_delay: [Some(1e-6), Some(1e-6), Some(20e-6)],
        };
        let (d, u) = pa.largest_difference().unwrap();
        assert!((d - 4e-6).abs() < 1e-15 && (u - 2f64.sqrt() * 1e-6).abs() < 1e-15, "{d} {u}");
        let one = PerAxis { delay: [Some(1e-6), None, None], u_delay: [Some(1e-7), None, None] };
        assert!(one.largest_difference().is_none());
    }
}
