//! Task-specific uncertainty by simulation of `dmis run` and `kinematics calibrate`: the Monte
//! Carlo of `truepos-vcmm` (its [`MachineModel`], [`simulate`], [`monte_carlo`],
//! [`ErrorOverlay`]) over a capability's own task, replayed on simulated machines. Here, in the
//! application crate, because it joins two capabilities (DMIS, kinematics) with the plant;
//! `truepos-vcmm` keeps its dependencies within issue 33's nine (docs/uncertainty.md).
//!
//! Entry points: [`dmis_uncertainty`] (`dmis run --machine-model`), [`kinematics_uncertainty`]
//! (`kinematics calibrate --machine-model`).

use truepos_vcmm::{monte_carlo, simulate, ErrorOverlay, MachineModel, MonteCarlo, PointErrors, Spread};
use truepos_vcmm::{Result, VcmmError};

/// The task-specific uncertainty of a DMIS run (`dmis run --machine-model`).
#[derive(Debug, Clone)]
pub struct DmisUncertainty {
    /// Standard uncertainties per output feature and tolerance.
    pub uncertainty: truepos_dmis::uncertainty::Uncertainty,
    /// The simulation behind them (RMS deviations in the layout of
    /// [`truepos_dmis::uncertainty::parameters`]).
    pub spread: Spread,
}

/// The task-specific uncertainty of every result of the DMIS run `measured` of `plan`: the same
/// program (its PTMEAS points, directions, SNSET distances, datums and constructions) run again
/// on `mc.runs` machines drawn from `model`, each touching the perfect features where the run
/// found them ([`truepos_dmis::uncertainty::Replay`] with the realisation's errors,
/// [`ErrorOverlay`]); u = the RMS deviation of each result from the perfect run's, combined in
/// quadrature with the measured fits' scatter beyond the simulated machines' (the part's form
/// error and effects outside the model; [`truepos_dmis::uncertainty::fit_scatter`]).
pub fn dmis_uncertainty(
    model: &MachineModel,
    plan: &truepos_dmis::model::Plan,
    opts: &truepos_dmis::exec::RunOptions,
    measured: &truepos_dmis::exec::RunResult,
    mc: MonteCarlo,
) -> Result<DmisUncertainty> {
    use truepos_dmis::exec;
    use truepos_dmis::uncertainty::{fit_scatter, parameters, Replay, Uncertainty};
    let fail = |e: exec::RunError| {
        VcmmError::Failed(format!("task-specific uncertainty: the program on a simulated machine: {e}"))
    };
    let perfect = exec::run(plan, &mut Replay::new(measured), opts, &mut |_| {}).map_err(fail)?;
    let p0 = parameters(&perfect);
    let spread = simulate(model, mc, |errors| {
        let mut m = ErrorOverlay { inner: Replay::new(measured), errors };
        let r = exec::run(plan, &mut m, opts, &mut |_| {}).map_err(fail)?;
        let p = parameters(&r);
        let scatter = fit_scatter(&r);
        if p.len() != p0.len() || scatter.len() != p0.len() {
            return Err(VcmmError::Failed(
                "task-specific uncertainty: a simulated run gave other results than the perfect one".into(),
            ));
        }
        // Deviations, then this machine's fit scatter (its RMS over the machines is the scatter
        // the model explains).
        Ok(p.iter().zip(&p0).map(|(a, b)| a - b).chain(scatter).collect())
    })?;
    let n = p0.len();
    let mut spread = spread;
    let typical = spread.rms.split_off(n);
    spread.mean.truncate(n);
    // The measurement's own fit scatter is a cross-check (see truepos_vcmm's docs): only its
    // part beyond the simulated machines' is added in quadrature.
    let observed = fit_scatter(measured);
    let u: Vec<f64> = spread
        .rms
        .iter()
        .zip(observed.iter().zip(&typical))
        .map(|(sim, (obs, typ))| sim.hypot((obs * obs - typ * typ).max(0.0).sqrt()))
        .collect();
    let uncertainty = Uncertainty::from_parameters(measured, &u);
    Ok(DmisUncertainty { uncertainty, spread })
}

/// The task-specific uncertainty of the rotary-axis geometry `truepos kinematics calibrate`
/// identified (`report`, measured with `probing`): the same calibration (orientations, probing
/// pattern, feed, clearance, turn distance; a dry run) on `mc.runs` five-axis machines per basis
/// of the model whose controller holds the configured geometry and whose true geometry is the
/// identified one, the sphere where it was found, each with the machine tool's servo latch,
/// pre-travel and position noise ([`truepos_plant::probing::VirtualMachineTool::five_axis_exact`]) and
/// the model's errors on every contact ([`ErrorOverlay`]; the error field is evaluated at the
/// programme-frame contact, an approximation for a table that turns).
///
/// Per parameter (`report.parameters` order): u = the RMS deviation of the identified value
/// from the truth, U = the 95th percentile of |deviation| (JCGM 101's coverage interval: the
/// deviations are far from normal — bounded latch and map errors — and k = 2 on their RMS
/// covered 100 % of 400 comparisons), each at least the identification's own (fit) value.
pub fn kinematics_uncertainty(
    model: &MachineModel,
    probing: &truepos_kinematics::acquire::KinematicsProbing,
    report: &truepos_kinematics::CalibrationReport,
    mc: MonteCarlo,
) -> Result<KinematicsUncertainty> {
    use truepos_kinematics::{calibrate, CalibrateRequest};
    use truepos_plant::probing::VirtualMachineTool;
    let t0 = std::time::Instant::now();
    let radii: Vec<f64> = report.acquired.iter().map(|o| o.sphere.radius_mm).collect();
    let radius = radii.iter().sum::<f64>() / radii.len().max(1) as f64;
    if radius.is_nan() || radius <= 0.0 {
        return Err(VcmmError::Invalid("the calibration has no sphere radius to simulate".into()));
    }
    let req = CalibrateRequest {
        model: report.model,
        probing: probing.clone(),
        apply: false,
        verify: None,
        output: None,
    };
    let centre = report.identification.sphere_centre_mm;
    let n = report.parameters.len();
    let (mut u, mut big_u) = (vec![0.0_f64; n], vec![0.0_f64; n]);
    for basis in model.bases() {
        let runs = monte_carlo(mc, |seed| {
            let errors = PointErrors::draw(basis, seed);
            let inner = VirtualMachineTool::five_axis_exact(
                errors.seed(),
                report.configured,
                report.identified,
                centre,
                radius,
                probing.sphere.tip_radius_mm,
                |cfg| model.machine_tool.apply(cfg),
            )
            .map_err(|e| VcmmError::Invalid(e.to_string()))?;
            let mut m = ErrorOverlay { inner, errors };
            let r = calibrate(&mut m, &req, |_| {}).map_err(|e| {
                VcmmError::Failed(format!("task-specific uncertainty: a simulated calibration failed ({e})"))
            })?;
            Ok(r.parameters
                .iter()
                .zip(&report.parameters)
                .map(|(a, b)| a.identified_mm - b.identified_mm)
                .collect::<Vec<f64>>())
        })?;
        for k in 0..n {
            let mut dev: Vec<f64> = runs.iter().map(|r| r[k]).collect();
            if dev.iter().any(|v| !v.is_finite()) {
                return Err(VcmmError::Failed(
                    "task-specific uncertainty: a simulated calibration gave no value".into(),
                ));
            }
            let rms = (dev.iter().map(|v| v * v).sum::<f64>() / dev.len() as f64).sqrt();
            dev.iter_mut().for_each(|v| *v = v.abs());
            dev.sort_by(f64::total_cmp);
            let q95 = dev[((0.95 * dev.len() as f64).ceil() as usize).clamp(1, dev.len()) - 1];
            u[k] = u[k].max(rms);
            big_u[k] = big_u[k].max(q95);
        }
    }
    let k2 = truepos_math::stats::COVERAGE_FACTOR;
    for (k, p) in report.parameters.iter().enumerate() {
        u[k] = u[k].max(p.uncertainty_mm);
        big_u[k] = big_u[k].max(k2 * p.uncertainty_mm);
    }
    Ok(KinematicsUncertainty {
        u_mm: u,
        expanded_mm: big_u,
        runs: mc.runs,
        basis: model.basis(),
        elapsed_s: t0.elapsed().as_secs_f64(),
    })
}

/// What [`kinematics_uncertainty`] found, per parameter in the report's order.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicsUncertainty {
    /// Standard uncertainty (mm).
    pub u_mm: Vec<f64>,
    /// Expanded uncertainty for 95 % coverage (mm).
    pub expanded_mm: Vec<f64>,
    /// Realisations per basis.
    pub runs: usize,
    /// What the model was (for the output).
    pub basis: String,
    /// Wall time of the simulation (s).
    pub elapsed_s: f64,
}
