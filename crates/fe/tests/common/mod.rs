//! Shared analytic references for the plate tests: Navier double-series solutions of the simply
//! supported rectangular plate (Kirchhoff, and Mindlin for "hard" simple supports).
#![allow(dead_code)]

use std::f64::consts::PI;

use truepos_fe::{Bed, Supports};

pub fn ss_bed(a: f64, b: f64, h: f64) -> Bed {
    Bed {
        size_x: a,
        size_y: b,
        thickness: h,
        youngs_modulus: 2.1e5,
        poisson: 0.3,
        supports: Supports::SimplySupportedEdges,
    }
}

/// Kirchhoff deflection (positive in the load direction) of a simply supported a × b plate of
/// rigidity `d` under a point load `p` at (xi, eta), at (x, y), by Navier's double series
/// (Timoshenko & Woinowsky-Krieger, Theory of Plates and Shells, 2nd ed., §30, eq. (133)–(134)
/// with the load of §31 concentrated at (ξ, η)):
///   w = 4P/(π⁴ a b D) Σ_m Σ_n sin(mπξ/a) sin(nπη/b) sin(mπx/a) sin(nπy/b) / (m²/a² + n²/b²)²,
/// summed over m, n = 1..=terms. The terms fall as 1/(m²+n²)², so the truncated tail is
/// O(1/terms²) relative; callers check convergence by doubling `terms`.
pub fn navier_point_kirchhoff(
    a: f64,
    b: f64,
    d: f64,
    p: f64,
    load: (f64, f64),
    at: (f64, f64),
    terms: usize,
) -> f64 {
    let sx: Vec<f64> =
        (1..=terms).map(|m| (m as f64 * PI * load.0 / a).sin() * (m as f64 * PI * at.0 / a).sin()).collect();
    let sy: Vec<f64> =
        (1..=terms).map(|n| (n as f64 * PI * load.1 / b).sin() * (n as f64 * PI * at.1 / b).sin()).collect();
    let mut sum = 0.0;
    for (mi, sxm) in sx.iter().enumerate() {
        let m2 = ((mi + 1) as f64 / a).powi(2);
        let mut row = 0.0;
        for (ni, syn) in sy.iter().enumerate() {
            let k = m2 + ((ni + 1) as f64 / b).powi(2);
            row += syn / (k * k);
        }
        sum += sxm * row;
    }
    4.0 * p / (PI.powi(4) * a * b * d) * sum
}

/// Uniform load q on a simply supported a × b plate: the Navier series of the Kirchhoff
/// deflection w_K and of the moment sum ℳ = (Mxx + Myy)/(1 + ν) at (x, y)
/// (Timoshenko & Woinowsky-Krieger §28: q = Σ 16q/(π² m n) sin sin over odd m, n;
/// D ∇⁴w_K = q gives w_mn = q_mn/(D α⁴), and ∇²ℳ = −q gives ℳ_mn = q_mn/α², with
/// α² = (mπ/a)² + (nπ/b)²). Returns (w_K, ℳ_K).
pub fn navier_uniform(a: f64, b: f64, d: f64, q: f64, at: (f64, f64), terms: usize) -> (f64, f64) {
    let (mut w, mut mm) = (0.0, 0.0);
    for m in (1..=terms).step_by(2) {
        for n in (1..=terms).step_by(2) {
            let (mf, nf) = (m as f64, n as f64);
            let qmn = 16.0 * q / (PI * PI * mf * nf);
            let s = (mf * PI * at.0 / a).sin() * (nf * PI * at.1 / b).sin();
            let alpha2 = (mf * PI / a).powi(2) + (nf * PI / b).powi(2);
            w += qmn * s / (d * alpha2 * alpha2);
            mm += qmn * s / alpha2;
        }
    }
    (w, mm)
}

/// Bessel function J1 (Numerical Recipes, 2nd ed., §6.5 `bessj1`: rational approximation for
/// |x| < 8, Hankel asymptotic form with polynomial corrections beyond; absolute error < 1e-8).
pub fn bessel_j1(x: f64) -> f64 {
    let ax = x.abs();
    if ax < 8.0 {
        let y = x * x;
        let a1 = x
            * (72362614232.0
                + y * (-7895059235.0
                    + y * (242396853.1 + y * (-2972611.439 + y * (15704.48260 + y * (-30.16036606))))));
        let a2 = 144725228442.0
            + y * (2300535178.0 + y * (18583304.74 + y * (99447.43394 + y * (376.9991397 + y))));
        a1 / a2
    } else {
        let z = 8.0 / ax;
        let y = z * z;
        let xx = ax - 3.0 * std::f64::consts::FRAC_PI_4;
        let a1 =
            1.0 + y * (0.183105e-2 + y * (-0.3516396496e-4 + y * (0.2457520174e-5 + y * (-0.240337019e-6))));
        let a2 = 0.04687499995
            + y * (-0.2002690873e-3 + y * (0.8449199096e-5 + y * (-0.88228987e-6 + y * 0.105787412e-6)));
        let ans = (std::f64::consts::FRAC_2_PI / ax).sqrt() * (xx.cos() * a1 - z * xx.sin() * a2);
        if x < 0.0 {
            -ans
        } else {
            ans
        }
    }
}

/// Mindlin-Reissner deflection (positive in the load direction) of a HARD simply supported
/// a × b plate under a force `p` spread uniformly over a disc of radius `r` centred at
/// `load`, by the Navier series. Each Fourier mode sin(mπx/a) sin(nπy/b) is an exact
/// solution of the Mindlin equations with hard simple supports, with
///   w_mn = q_mn (1/(D k⁴) + 1/(κGh k²)),  k² = (mπ/a)² + (nπ/b)²
/// (the Mindlin/Kirchhoff relation of Wang, Reddy & Lee 2000 mode by mode), and the load's
/// coefficient is q_mn = 4P/(ab) sin(mπξ/a) sin(nπη/b) · 2 J1(k r)/(k r), because
/// sin(αx) sin(βy) = ½[cos(αx − βy) − cos(αx + βy)] and the mean of cos(k·x) over a disc of
/// radius r centred at x₀ is cos(k·x₀) · 2 J1(|k| r)/(|k| r).
#[allow(clippy::too_many_arguments)]
pub fn navier_disc_mindlin(
    a: f64,
    b: f64,
    d: f64,
    kgh: f64,
    p: f64,
    load: (f64, f64),
    r: f64,
    at: (f64, f64),
    terms: usize,
) -> f64 {
    let sx: Vec<f64> =
        (1..=terms).map(|m| (m as f64 * PI * load.0 / a).sin() * (m as f64 * PI * at.0 / a).sin()).collect();
    let sy: Vec<f64> =
        (1..=terms).map(|n| (n as f64 * PI * load.1 / b).sin() * (n as f64 * PI * at.1 / b).sin()).collect();
    let mut sum = 0.0;
    for (mi, sxm) in sx.iter().enumerate() {
        let am2 = ((mi + 1) as f64 * PI / a).powi(2);
        for (ni, syn) in sy.iter().enumerate() {
            let k2 = am2 + ((ni + 1) as f64 * PI / b).powi(2);
            let kr = k2.sqrt() * r;
            let disc = if kr > 0.0 { 2.0 * bessel_j1(kr) / kr } else { 1.0 };
            sum += sxm * syn * disc * (1.0 / (d * k2 * k2) + 1.0 / (kgh * k2));
        }
    }
    4.0 * p / (a * b) * sum
}
