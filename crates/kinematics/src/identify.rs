//! Identification of the axis errors from the sphere centres the controller reports at several
//! orientations, and the observability check that runs before any motion.
//!
//! Unknowns `x = (s, θ)`: the sphere centre `s` in the table frame (3) and the axis errors `θ`
//! (4, [`Observable`] order). Observations: the fitted centre at each orientation (3 each).
//! The model `c_i = s + A(B_i, C_i)·θ` ([`design`]) is exact and linear, so one weighted-free
//! linear least-squares solve gives `x`; the normal matrix (7×7) is solved through its symmetric
//! eigen-decomposition.
//!
//! [`check_orientations`] looks at the same normal matrix built from the angles alone: a
//! parameter (a pin, [`PIN_FROM_THETA`]) is *not determined* when a direction of the null space
//! moves it, and *weakly determined* when a unit scatter of the centres moves it by more than
//! [`MAX_AMPLIFICATION`] (angles too close together). Both are refused, naming the parameter.
//!
//! Uncertainty: the centre scatter σ is the larger of the residuals' (`RSS / (3n − 7)`) and the
//! sphere fits' own centre uncertainties (so a lucky small residual with few degrees of freedom
//! does not understate it); the parameters' standard uncertainties are `σ·√diag(g·N⁻¹·gᵀ)`.
//! The machine's other errors (servo, scales, the sphere's own form) are not in it.

use crate::trt::{design, Observable, PIN_FROM_THETA};
use nalgebra::{SMatrix, SVector, SymmetricEigen};
use truepos_math::{Point3, Vector3};

type M7 = SMatrix<f64, 7, 7>;
type V7 = SVector<f64, 7>;

/// A unit scatter of the centres may move no parameter by more than this (refused as weakly
/// determined beyond it: e.g. two B angles 2° apart).
pub const MAX_AMPLIFICATION: f64 = 50.0;

/// Why a set of orientations cannot determine the geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct NotDetermined {
    /// The pins that the orientations cannot determine (or only weakly).
    pub parameters: Vec<String>,
    /// The message: which axis lacks what, and what to add.
    pub message: String,
}

fn normal_matrix(orientations: &[[f64; 2]]) -> M7 {
    let mut n = M7::zeros();
    for o in orientations {
        let j = row_block(o[0].to_radians(), o[1].to_radians());
        n += j.transpose() * j;
    }
    n
}

fn row_block(b: f64, c: f64) -> SMatrix<f64, 3, 7> {
    let mut j = SMatrix::<f64, 3, 7>::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&nalgebra::Matrix3::identity());
    j.fixed_view_mut::<3, 4>(0, 3).copy_from(&design(b, c));
    j
}

/// Pseudo-inverse of a symmetric positive semi-definite matrix and its null space (eigenvectors
/// with eigenvalues below `1e-10 · λ_max`).
fn pinv(n: &M7) -> (M7, Vec<V7>) {
    let eig = SymmetricEigen::new(*n);
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut inv = M7::zeros();
    let mut null = vec![];
    for k in 0..7 {
        let l = eig.eigenvalues[k];
        let v = eig.eigenvectors.column(k).into_owned();
        if lmax <= 0.0 || l <= 1e-10 * lmax {
            null.push(v);
        } else {
            inv += v * v.transpose() / l;
        }
    }
    (inv, null)
}

fn pin_vector(coef: &[f64; 4]) -> V7 {
    V7::from_fn(|i, _| if i >= 3 { coef[i - 3] } else { 0.0 })
}

/// Check that `orientations` (B, C in degrees) determine every parameter; `Err` names the ones
/// they do not and says what to add.
pub fn check_orientations(orientations: &[[f64; 2]]) -> Result<(), NotDetermined> {
    let n = normal_matrix(orientations);
    let (inv, null) = pinv(&n);
    // Which axis errors lie in the null space.
    let theta_free: Vec<Observable> = Observable::ALL
        .iter()
        .enumerate()
        .filter(|(k, _)| null.iter().any(|v| v[3 + k].abs() > 1e-6))
        .map(|(_, o)| *o)
        .collect();
    let mut undetermined = vec![];
    let mut weak = vec![];
    for (name, coef) in PIN_FROM_THETA {
        let g = pin_vector(&coef);
        if null.iter().any(|v| v.dot(&g).abs() > 1e-6) {
            undetermined.push(name.to_string());
        } else {
            let amp = (g.transpose() * inv * g)[(0, 0)].max(0.0).sqrt();
            if amp > MAX_AMPLIFICATION {
                weak.push((name.to_string(), amp));
            }
        }
    }
    if orientations.is_empty() {
        return Err(NotDetermined {
            parameters: PIN_FROM_THETA.iter().map(|p| p.0.to_string()).collect(),
            message: "no orientations: give at least three with --orientation B,C".into(),
        });
    }
    if !undetermined.is_empty() {
        let c_free = theta_free.iter().any(|o| matches!(o, Observable::CAxisX | Observable::CAxisY));
        let b_free = theta_free.iter().any(|o| matches!(o, Observable::BAxisX | Observable::BAxisZ));
        let mut why = vec![];
        if c_free {
            why.push("the C axis's position is not determined: add orientations at two or more C angles (at B = 0, or at one B angle)");
        }
        if b_free {
            why.push("the B axis's position is not determined: add orientations at two or more B angles");
        }
        let free: Vec<&str> = theta_free.iter().map(|o| o.describe()).collect();
        return Err(NotDetermined {
            message: format!(
                "the orientations cannot determine {} ({} free); {}",
                undetermined.join(", "),
                free.join(", "),
                why.join("; ")
            ),
            parameters: undetermined,
        });
    }
    if !weak.is_empty() {
        let list: Vec<String> =
            weak.iter().map(|(n, a)| format!("{n} ({a:.0} µm per µm of centre scatter)")).collect();
        return Err(NotDetermined {
            parameters: weak.into_iter().map(|w| w.0).collect(),
            message: format!(
                "the orientations determine {} only weakly (more than {MAX_AMPLIFICATION:.0} µm per µm): \
                 spread the angles further apart",
                list.join(", ")
            ),
        });
    }
    Ok(())
}

/// One orientation's measured centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Table tilt B of the orientation, degrees.
    pub b_deg: f64,
    /// Table rotation C of the orientation, degrees.
    pub c_deg: f64,
    /// The fitted sphere centre the controller reports (programme frame, mm).
    pub centre_mm: Point3,
    /// The sphere fit's standard uncertainty of that centre, per axis (mm).
    pub centre_uncertainty_mm: Vector3,
}

/// An identified pin change.
#[derive(Debug, Clone, PartialEq)]
pub struct PinChange {
    /// The kinematics module's pin name (`x-rot-point`, ...).
    pub name: String,
    /// Identified true − configured (mm).
    pub change_mm: f64,
    /// Standard uncertainty (mm).
    pub uncertainty_mm: f64,
}

/// The least-squares result.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// Axis errors θ (true − configured, [`Observable`] order), mm.
    pub theta_mm: [f64; 4],
    /// Standard uncertainties of `theta_mm`, same order, mm.
    pub theta_uncertainty_mm: [f64; 4],
    /// The pin changes ([`PIN_FROM_THETA`] order).
    pub pins: Vec<PinChange>,
    /// The sphere centre in the table frame (= the centre at B = C = 0).
    pub sphere_centre_mm: Point3,
    /// Residual of each centre after the fit (mm): what remains once the identified geometry is
    /// in the controller.
    pub residuals_mm: Vec<Vector3>,
    /// RMS of the residual components, mm.
    pub rms_mm: f64,
    /// Centre scatter σ used for the uncertainties, mm.
    pub sigma_mm: f64,
    /// Degrees of freedom of the residuals (3n − 7).
    pub dof: usize,
}

impl Identification {
    /// The largest distance between two centres as they would be with the identified geometry
    /// (the residuals about the fitted sphere centre).
    pub fn spread_after_predicted_mm(&self) -> f64 {
        let pts: Vec<Point3> = self.residuals_mm.iter().map(|r| self.sphere_centre_mm + r).collect();
        max_pairwise(&pts)
    }
}

/// The largest distance between two of `points` (0 for fewer than two).
pub fn max_pairwise(points: &[Point3]) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..points.len() {
        for j in 0..i {
            m = m.max((points[i] - points[j]).norm());
        }
    }
    m
}

/// Identify the axis errors from the observations. The orientations must pass
/// [`check_orientations`].
pub fn identify(obs: &[Observation]) -> Result<Identification, NotDetermined> {
    let orientations: Vec<[f64; 2]> = obs.iter().map(|o| [o.b_deg, o.c_deg]).collect();
    check_orientations(&orientations)?;
    // Centred on the first centre, for conditioning of the right-hand side.
    let origin = obs[0].centre_mm;
    let mut n = M7::zeros();
    let mut rhs = V7::zeros();
    let blocks: Vec<SMatrix<f64, 3, 7>> =
        obs.iter().map(|o| row_block(o.b_deg.to_radians(), o.c_deg.to_radians())).collect();
    for (j, o) in blocks.iter().zip(obs) {
        n += j.transpose() * j;
        rhs += j.transpose() * (o.centre_mm - origin);
    }
    let (inv, _) = pinv(&n);
    let x = inv * rhs;
    let residuals_mm: Vec<Vector3> =
        blocks.iter().zip(obs).map(|(j, o)| (o.centre_mm - origin) - j * x).collect();
    let rss: f64 = residuals_mm.iter().map(|r| r.norm_squared()).sum();
    let m = 3 * obs.len();
    let dof = m.saturating_sub(7);
    let rms = (rss / m as f64).sqrt();
    let fit_var =
        obs.iter().map(|o| o.centre_uncertainty_mm.norm_squared() / 3.0).sum::<f64>() / obs.len() as f64;
    let res_var = if dof > 0 { rss / dof as f64 } else { 0.0 };
    let sigma = res_var.max(fit_var).sqrt();
    let theta_mm = [x[3], x[4], x[5], x[6]];
    let theta_uncertainty_mm = [3, 4, 5, 6].map(|k| sigma * inv[(k, k)].max(0.0).sqrt());
    let pins = PIN_FROM_THETA
        .iter()
        .map(|(name, coef)| {
            let g = pin_vector(coef);
            PinChange {
                name: name.to_string(),
                change_mm: g.dot(&x),
                uncertainty_mm: sigma * (g.transpose() * inv * g)[(0, 0)].max(0.0).sqrt(),
            }
        })
        .collect();
    Ok(Identification {
        theta_mm,
        theta_uncertainty_mm,
        pins,
        sphere_centre_mm: origin + Vector3::new(x[0], x[1], x[2]),
        residuals_mm,
        rms_mm: rms,
        sigma_mm: sigma,
        dof,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trt::{reported_centre, TrtGeometry};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn conf() -> TrtGeometry {
        TrtGeometry {
            x_rot_point: 10.0,
            y_rot_point: -5.0,
            z_rot_point: -20.0,
            x_offset: -20.0,
            z_offset: -15.0,
        }
    }

    fn truth() -> TrtGeometry {
        TrtGeometry {
            x_rot_point: 10.030,
            y_rot_point: -5.020,
            z_rot_point: -20.0,
            x_offset: -19.985,
            z_offset: -15.025,
        }
    }

    const SET: [[f64; 2]; 6] =
        [[0.0, 0.0], [0.0, 120.0], [0.0, 240.0], [45.0, 0.0], [90.0, 120.0], [90.0, 240.0]];

    fn observe(orientations: &[[f64; 2]], noise_mm: f64, seed: u64) -> Vec<Observation> {
        let s = Point3::new(60.0, 25.0, 15.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let nd = Normal::new(0.0, noise_mm.max(1e-300)).unwrap();
        orientations
            .iter()
            .map(|o| {
                let c = reported_centre(&conf(), &truth(), &s, o[0].to_radians(), o[1].to_radians());
                let e = Vector3::from_fn(|_, _| if noise_mm > 0.0 { nd.sample(&mut rng) } else { 0.0 });
                Observation {
                    b_deg: o[0],
                    c_deg: o[1],
                    centre_mm: c + e,
                    centre_uncertainty_mm: Vector3::repeat(noise_mm),
                }
            })
            .collect()
    }

    #[test]
    fn exact_centres_give_the_true_geometry_and_no_spread() {
        let id = identify(&observe(&SET, 0.0, 1)).unwrap();
        let fixed = conf().corrected(&id.theta_mm);
        let (a, b) = (fixed.axes(), truth().axes());
        for k in 0..4 {
            assert!((a[k] - b[k]).abs() < 1e-10, "{k}: {} vs {}", a[k], b[k]);
        }
        assert!((id.sphere_centre_mm - Point3::new(60.0, 25.0, 15.0)).norm() < 1e-10);
        assert!(id.spread_after_predicted_mm() < 1e-10);
        // Pins: x-offset takes the B axis's X change minus the C axis's; z-rot-point untouched.
        let pin = |n: &str| id.pins.iter().find(|p| p.name == n).unwrap().change_mm;
        assert!((pin("x-rot-point") - 0.030).abs() < 1e-10);
        assert!((pin("y-rot-point") + 0.020).abs() < 1e-10);
        assert!((pin("x-offset") - 0.015).abs() < 1e-10);
        assert!((pin("z-offset") + 0.025).abs() < 1e-10);
        let before: Vec<Point3> = observe(&SET, 0.0, 1).iter().map(|o| o.centre_mm).collect();
        assert!(max_pairwise(&before) > 0.08);
    }

    #[test]
    fn noisy_centres_give_the_truth_within_the_stated_uncertainty() {
        // 0.5 µm of centre noise per axis, 200 repetitions: the errors stay within k = 3 of the
        // stated standard uncertainty in ≥ 97 % of cases, and the uncertainty is of the right size.
        let sigma = 0.0005;
        let mut within = 0;
        let mut total = 0;
        let mut mean_u = [0.0; 4];
        for seed in 0..200 {
            let id = identify(&observe(&SET, sigma, seed)).unwrap();
            let truth_theta = {
                let (a, b) = (truth().axes(), conf().axes());
                [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
            };
            for k in 0..4 {
                let e = id.theta_mm[k] - truth_theta[k];
                let u = id.theta_uncertainty_mm[k];
                mean_u[k] += u / 200.0;
                total += 1;
                if e.abs() <= 3.0 * u {
                    within += 1;
                }
            }
        }
        assert!(within as f64 >= 0.97 * total as f64, "{within}/{total}");
        for u in mean_u {
            assert!(u > 0.1 * sigma && u < 5.0 * sigma, "{mean_u:?}");
        }
    }

    #[test]
    fn orientation_sets_that_miss_an_axis_are_refused_naming_the_pins() {
        // Only C turns at B = 0: the B axis is free.
        let e = check_orientations(&[[0.0, 0.0], [0.0, 120.0], [0.0, 240.0]]).unwrap_err();
        assert_eq!(e.parameters, vec!["x-offset", "z-offset"]);
        assert!(e.message.contains("two or more B angles"), "{}", e.message);
        // Only B tilts at C = 0: the C axis is free (and x-offset with it).
        let e = check_orientations(&[[0.0, 0.0], [45.0, 0.0], [90.0, 0.0]]).unwrap_err();
        assert_eq!(e.parameters, vec!["x-rot-point", "y-rot-point", "x-offset"]);
        assert!(e.message.contains("two or more C angles"), "{}", e.message);
        // One orientation, none.
        assert_eq!(check_orientations(&[[30.0, 30.0]]).unwrap_err().parameters.len(), 4);
        assert_eq!(check_orientations(&[]).unwrap_err().parameters.len(), 4);
        // B angles 0.5° apart: determined on paper, weakly in practice.
        let e = check_orientations(&[[0.0, 0.0], [0.0, 120.0], [0.0, 240.0], [0.5, 0.0]]).unwrap_err();
        assert!(e.message.contains("weakly"), "{}", e.message);
        // Good sets pass: the recipe's, and a minimal one.
        check_orientations(&SET).unwrap();
        check_orientations(&[[0.0, 0.0], [0.0, 90.0], [60.0, 0.0]]).unwrap();
        // Two C angles at one tilted B also fix the C axis.
        check_orientations(&[[0.0, 0.0], [45.0, 0.0], [45.0, 180.0]]).unwrap();
    }
}
