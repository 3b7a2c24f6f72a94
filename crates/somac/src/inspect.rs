//! In-spindle probe inspection (`truepos somac inspect`): after the holes of a program are
//! made, the same machine, with a touch probe in the spindle, probes each hole and reports its
//! position error and diameter — the machine accepts its own part, as a CMM would.
//!
//! A hole is its nominal top centre (machine frame, mm: where the program's measurement block
//! puts the tool, [`holes_from_program`], or a row of a hole list) and its nominal diameter.
//! [`inspect`] visits the holes in order through any [`ProbingMachine`] (the virtual machine tool,
//! LinuxCNC with G38.2, a CMM through I++ DME): up to the safe height, across above the hole's
//! nominal centre, straight down to the probing depth below the top, then `points` single-point
//! probings on the bore wall at equal angles — each starting `clearance` inside the nominal
//! wall and moving radially outwards at most `clearance` beyond it — back to the centre and up.
//! Every move stays inside the nominal bore less the clearance, so a hole whose real centre is
//! off by less than the clearance is probed without collision; a larger error is a probe move
//! without contact or a trip during a positioning move (both errors naming the move, the
//! machine retracted).
//!
//! The holes come from a program file ([`read_program_holes`]) or a hole list
//! ([`read_hole_list`]).
//!
//! The latched tip centres of a hole are fitted with the least-squares circle
//! (`truepos_fit::circle`); the hole's diameter is the fitted tip-centre circle's plus the tip
//! diameter. The position error is the measured centre minus the nominal one in XY (the hole
//! axis is taken along Z); `true_position_mm` is twice its length (the diameter of the
//! ASME Y14.5 / ISO 1101 position zone the centre lies on).

use std::path::Path;
use std::time::Instant;
use thiserror::Error;
use truepos_device::{DeviceError, DeviceInfo, ProbeRequest, ProbingMachine};
use truepos_fit::FitError;
use truepos_gcode::Program;
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};

use crate::stats::{hole_stats, HoleStats};

/// A hole to inspect.
#[derive(Debug, Clone, PartialEq)]
pub struct Hole {
    /// Its name (a hole list's id, or `L<line>` for a program block).
    pub id: String,
    /// The program line (1-based) of the block that made it, if it came from a program.
    pub line: Option<usize>,
    /// Nominal centre of the hole's top (machine frame, mm).
    pub nominal_mm: Point3,
    /// Nominal diameter (mm).
    pub diameter_mm: f64,
}

/// How to probe the holes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InspectPlan {
    /// Probing depth below each hole's top (mm).
    pub depth_mm: f64,
    /// Points per hole (≥ 4: three determine a circle and leave nothing to check it).
    pub points: usize,
    /// Probing feed (mm/s).
    pub feed_mm_s: f64,
    /// Distance from the nominal wall where each probing move starts, and beyond which it gives
    /// up (mm).
    pub clearance_mm: f64,
    /// Stylus tip radius (mm).
    pub tip_radius_mm: f64,
    /// Height above the highest hole top at which the machine travels between holes (mm).
    pub safe_height_mm: f64,
    /// Angle of the first point, from +X towards +Y (deg).
    pub start_angle_deg: f64,
}

impl Default for InspectPlan {
    fn default() -> Self {
        InspectPlan {
            depth_mm: 3.0,
            points: 8,
            feed_mm_s: 50.0 / 60.0,
            clearance_mm: 0.5,
            tip_radius_mm: 0.0,
            safe_height_mm: 5.0,
            start_angle_deg: 0.0,
        }
    }
}

/// Why an inspection of holes failed.
#[derive(Debug, Error)]
pub enum InspectError {
    /// The request cannot be carried out as given (nothing has moved).
    #[error("invalid inspection: {0}")]
    Plan(String),
    /// The machine failed at a hole (the machine is left where the device error says).
    #[error("hole {hole}: {error}")]
    Device {
        /// The hole's id.
        hole: String,
        /// What the machine said.
        error: DeviceError,
    },
    /// The points of a hole do not determine a circle.
    #[error("hole {hole}: circle fit of the probed points: {error}")]
    Fit {
        /// The hole's id.
        hole: String,
        /// Why the fit failed.
        error: FitError,
    },
}

/// One inspected hole.
#[derive(Debug, Clone, PartialEq)]
pub struct HoleResult {
    /// The hole as planned.
    pub hole: Hole,
    /// Measured centre at the probing depth (mm).
    pub measured_mm: Point3,
    /// Measured minus nominal centre, X and Y (mm).
    pub error_xy_mm: [f64; 2],
    /// Length of `error_xy_mm` (mm).
    pub position_error_mm: f64,
    /// Measured diameter: fitted tip-centre circle plus the tip diameter (mm).
    pub diameter_mm: f64,
    /// Measured minus nominal diameter (mm).
    pub diameter_error_mm: f64,
    /// Roundness (max − min radial residual) of the fit, mm.
    pub roundness_mm: f64,
    /// RMS residual of the circle fit, mm.
    pub rms_mm: f64,
    /// Standard uncertainties of the centre (X, Y) from the fit, mm.
    pub center_uncertainty_mm: [f64; 2],
    /// Standard uncertainty of the diameter from the fit, mm.
    pub diameter_uncertainty_mm: f64,
    /// The latched tip centres.
    pub points: Vec<Point3>,
    /// Wall-clock time spent on this hole, including the moves to it (s).
    pub elapsed_s: f64,
}

impl HoleResult {
    /// `true_position_mm`: twice the position error (the diameter of the position zone).
    pub fn true_position_mm(&self) -> f64 {
        2.0 * self.position_error_mm
    }
}

/// The inspection of a set of holes.
#[derive(Debug, Clone, PartialEq)]
pub struct Inspection {
    /// Every hole, in plan order.
    pub holes: Vec<HoleResult>,
    /// Statistics of the position errors (mm).
    pub stats: HoleStats,
    /// The plan that was run.
    pub plan: InspectPlan,
    /// The machine it ran on.
    pub device: DeviceInfo,
    /// Wall time of the inspection, s.
    pub elapsed_s: f64,
}

/// The holes of a program: every motion block with the measurement keyword comment and a
/// complete target; the target is the hole's top centre.
pub fn holes_from_program(program: &Program, keyword: &str, diameter_mm: f64) -> Vec<Hole> {
    program
        .blocks()
        .iter()
        .filter(|b| b.has_keyword(keyword))
        .filter_map(|b| {
            b.target_mm.map(|t| Hole {
                id: format!("L{}", b.line + 1),
                line: Some(b.line + 1),
                nominal_mm: t,
                diameter_mm,
            })
        })
        .collect()
}

/// The holes of a G-code program file ([`holes_from_program`]); a program that does not parse,
/// or has no hole, is an input error naming the file (and line and column).
pub fn read_program_holes(path: &Path, keyword: &str, diameter_mm: f64) -> Result<Vec<Hole>, InputError> {
    let text = truepos_io::limits::read_string(path, "G-code")?;
    let program = Program::parse(&text);
    program.check().map_err(|e| InputError::at(path, e.line(), Some(e.column()), e.detail()))?;
    let holes = holes_from_program(&program, keyword, diameter_mm);
    if holes.is_empty() {
        let why =
            format!("no hole: no motion block with a complete target has the keyword comment '{keyword}'");
        return Err(InputError::in_file(path, why));
    }
    Ok(holes)
}

/// A hole list (`id,x_mm,y_mm,z_mm` and an optional `diameter_mm` column; `diameter_mm` is used
/// where the column is absent). An empty list, a missing diameter or one that is not positive is
/// an input error naming the file (and line and column).
pub fn read_hole_list(path: &Path, diameter_mm: Option<f64>) -> Result<Vec<Hole>, InputError> {
    let pts = truepos_io::points::read_id_points(path)?;
    let column = pts.table.column("diameter_mm");
    let diameters = match column {
        Some(_) => pts.table.f64_columns(&["diameter_mm"])?,
        None => {
            let d = diameter_mm
                .ok_or_else(|| InputError::in_file(path, "no diameter_mm column: give --diameter-mm"))?;
            vec![d; pts.ids.len()]
        }
    };
    if pts.ids.is_empty() {
        return Err(InputError::in_file(path, "no holes in the list"));
    }
    let mut holes = Vec::with_capacity(pts.ids.len());
    for (i, ((id, p), d)) in pts.ids.iter().zip(&pts.points).zip(diameters).enumerate() {
        if !(d.is_finite() && d > 0.0) {
            let why = format!("hole {id}: the diameter must be > 0, got {d}");
            return Err(InputError::at(path, pts.table.line_number(i), column.map(|c| c + 1), why));
        }
        for (k, axis) in ["x_mm", "y_mm", "z_mm"].into_iter().enumerate() {
            if let Some(why) = truepos_device::length_beyond_limit(&format!("hole {id}: {axis}"), p[k]) {
                let col = pts.table.column(axis).map(|c| c + 1);
                return Err(InputError::at(path, pts.table.line_number(i), col, why));
            }
        }
        if let Some(why) = truepos_device::length_beyond_limit(&format!("hole {id}: diameter_mm"), d) {
            return Err(InputError::at(path, pts.table.line_number(i), column.map(|c| c + 1), why));
        }
        holes.push(Hole { id: id.clone(), line: None, nominal_mm: *p, diameter_mm: d });
    }
    Ok(holes)
}

/// Most single points per hole: a circle needs 3 and a few dozen characterise roundness; at
/// a second per touch 10 000 already take hours per hole (and the request is allocated before
/// any motion).
pub const MAX_POINTS_PER_HOLE: usize = 10_000;

impl InspectPlan {
    /// Check the plan against the holes (before any machine moves).
    pub fn check(&self, holes: &[Hole]) -> Result<(), InspectError> {
        let bad = |m: String| Err(InspectError::Plan(m));
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if holes.is_empty() {
            return bad("no holes to inspect".into());
        }
        if !(4..=MAX_POINTS_PER_HOLE).contains(&self.points) {
            return bad(format!(
                "between 4 and {MAX_POINTS_PER_HOLE} points per hole are needed, got {} (three determine a circle and leave nothing to check it; {MAX_POINTS_PER_HOLE} single points already take hours per hole)",
                self.points
            ));
        }
        if let Some(why) = truepos_device::probing_feed_problem(self.feed_mm_s * 60.0) {
            return bad(why);
        }
        for (name, v) in [
            ("--depth-mm", self.depth_mm),
            ("--clearance-mm", self.clearance_mm),
            ("--safe-height-mm", self.safe_height_mm),
        ] {
            if !pos(v) {
                return bad(format!("{name} must be finite and > 0, got {v}"));
            }
            if let Some(m) = truepos_device::length_beyond_limit(name, v) {
                return bad(m);
            }
        }
        if !(self.tip_radius_mm.is_finite() && self.tip_radius_mm >= 0.0) {
            return bad(format!("the tip diameter must be finite and ≥ 0, got {}", 2.0 * self.tip_radius_mm));
        }
        if !self.start_angle_deg.is_finite() {
            return bad("the start angle must be finite".into());
        }
        for h in holes {
            if !h.nominal_mm.iter().all(|v| v.is_finite()) || !pos(h.diameter_mm) {
                return bad(format!("hole {}: position and diameter must be finite, diameter > 0", h.id));
            }
            // The tip travels inside the nominal bore less the clearance, with room to spare.
            let room = 0.5 * h.diameter_mm - self.tip_radius_mm - self.clearance_mm;
            if room <= 0.0 {
                return bad(format!(
                    "hole {}: a {} mm hole leaves no room for a {} mm tip with {} mm clearance",
                    h.id,
                    h.diameter_mm,
                    2.0 * self.tip_radius_mm,
                    self.clearance_mm
                ));
            }
        }
        Ok(())
    }

    /// The travel height: highest hole top plus the safe height.
    pub fn safe_z_mm(&self, holes: &[Hole]) -> f64 {
        holes.iter().map(|h| h.nominal_mm.z).fold(f64::NEG_INFINITY, f64::max) + self.safe_height_mm
    }

    /// The probing requests of one hole (at the probing depth, equal angles from the start angle).
    pub fn requests(&self, hole: &Hole) -> Vec<ProbeRequest> {
        let c = hole.nominal_mm - Vector3::z() * self.depth_mm;
        let r = 0.5 * hole.diameter_mm;
        (0..self.points)
            .map(|k| {
                let a =
                    self.start_angle_deg.to_radians() + std::f64::consts::TAU * k as f64 / self.points as f64;
                let e = Vector3::new(a.cos(), a.sin(), 0.0);
                // Out of the material: towards the hole's axis; the retract ends where the move
                // started (inside the bore, clear of the wall).
                ProbeRequest::with_clearance(
                    c + e * r,
                    -e,
                    self.tip_radius_mm,
                    self.clearance_mm,
                    self.feed_mm_s,
                )
            })
            .collect()
    }
}

/// Probe every hole in order and fit it. On a device failure the machine is sent up to the
/// safe height (best effort) before the error is returned.
pub fn inspect(
    machine: &mut dyn ProbingMachine,
    holes: &[Hole],
    plan: &InspectPlan,
) -> Result<Inspection, InspectError> {
    plan.check(holes)?;
    let t_all = Instant::now();
    let safe_z = plan.safe_z_mm(holes);
    let device = machine.info();
    let mut out = Vec::with_capacity(holes.len());
    for h in holes {
        let t = Instant::now();
        let dev = |error: DeviceError| InspectError::Device { hole: h.id.clone(), error };
        let points = match probe_hole(machine, h, plan, safe_z) {
            Ok(p) => p,
            Err(e) => {
                // Leave the machine clear of the part where it can still move.
                if let Ok(p) = machine.position() {
                    let _ = machine.move_to(Point3::new(p.x, p.y, p.z.max(safe_z)));
                }
                return Err(dev(e));
            }
        };
        let fit =
            truepos_fit::circle(&points).map_err(|error| InspectError::Fit { hole: h.id.clone(), error })?;
        let nominal_at_depth = h.nominal_mm - Vector3::z() * plan.depth_mm;
        let d = fit.center - nominal_at_depth;
        let diameter = 2.0 * (fit.radius + plan.tip_radius_mm);
        out.push(HoleResult {
            hole: h.clone(),
            measured_mm: fit.center,
            error_xy_mm: [d.x, d.y],
            position_error_mm: d.x.hypot(d.y),
            diameter_mm: diameter,
            diameter_error_mm: diameter - h.diameter_mm,
            roundness_mm: fit.form,
            rms_mm: fit.radial_rms,
            center_uncertainty_mm: [fit.u_center.x, fit.u_center.y],
            diameter_uncertainty_mm: 2.0 * fit.u_radius,
            points,
            elapsed_s: t.elapsed().as_secs_f64(),
        });
    }
    let errors: Vec<f64> = out.iter().map(|r| r.position_error_mm).collect();
    Ok(Inspection {
        stats: hole_stats(&errors),
        holes: out,
        plan: *plan,
        device,
        elapsed_s: t_all.elapsed().as_secs_f64(),
    })
}

fn probe_hole(
    m: &mut dyn ProbingMachine,
    h: &Hole,
    plan: &InspectPlan,
    safe_z: f64,
) -> Result<Vec<Point3>, DeviceError> {
    let here = m.position()?;
    if here.z < safe_z {
        m.move_to(Point3::new(here.x, here.y, safe_z))?;
    }
    let top = h.nominal_mm;
    let axis = Point3::new(top.x, top.y, top.z - plan.depth_mm);
    m.move_to(Point3::new(top.x, top.y, safe_z))?;
    m.move_to(axis)?;
    let mut points = Vec::with_capacity(plan.points);
    for r in plan.requests(h) {
        points.push(m.probe(&r)?.tip_center_mm);
    }
    m.move_to(axis)?;
    m.move_to(Point3::new(top.x, top.y, safe_z))?;
    Ok(points)
}

/// What `truepos somac inspect` prints: the inspection, the position tolerance it was judged
/// against, and for a virtual machine the truth of its holes (top centre, diameter).
#[derive(Debug, Clone, PartialEq)]
pub struct InspectReport {
    /// The inspection.
    pub inspection: Inspection,
    /// The position tolerance the holes are judged against, mm.
    pub tolerance_mm: Option<f64>,
    /// For a virtual machine: each hole's true top centre and diameter, mm.
    pub truth: Option<Vec<(Point3, f64)>>,
    /// How the holes' uncertainties were found: (`task-specific` or `fit-residuals`, Monte Carlo
    /// runs, basis). The holes' `center_uncertainty_mm` / `diameter_uncertainty_mm` hold them.
    pub uncertainty: (String, usize, String),
}

impl InspectReport {
    /// Ids of the holes whose position error exceeds the tolerance.
    pub fn out_of_tolerance(&self) -> Vec<&str> {
        match self.tolerance_mm {
            Some(t) => self
                .inspection
                .holes
                .iter()
                .filter(|h| h.position_error_mm > t)
                .map(|h| h.hole.id.as_str())
                .collect(),
            None => vec![],
        }
    }
}

impl truepos_io::report::Report for InspectReport {
    fn to_json(&self) -> serde_json::Value {
        let mut j = self.inspection.to_json();
        let k = truepos_math::stats::COVERAGE_FACTOR;
        j["uncertainty_method"] = serde_json::json!(self.uncertainty.0);
        j["monte_carlo_runs"] = serde_json::json!(self.uncertainty.1);
        j["uncertainty_basis"] = serde_json::json!(self.uncertainty.2);
        j["coverage_factor"] = serde_json::json!(k);
        if let Some(holes) = j["holes"].as_array_mut() {
            for (h, r) in holes.iter_mut().zip(&self.inspection.holes) {
                h["expanded_uncertainty"] = serde_json::json!({
                    "center_xy_mm": [k * r.center_uncertainty_mm[0], k * r.center_uncertainty_mm[1]],
                    "diameter_mm": k * r.diameter_uncertainty_mm,
                });
            }
        }
        if let Some(t) = self.tolerance_mm {
            j["tolerance_mm"] = serde_json::json!(t);
            j["out_of_tolerance"] = serde_json::json!(self.out_of_tolerance());
        }
        if let Some(truth) = &self.truth {
            j["virtual_truth"] = truth
                .iter()
                .zip(&self.inspection.holes)
                .map(|((top, d), h)| serde_json::json!({ "id": h.hole.id, "top_mm": [top.x, top.y, top.z], "diameter_mm": d }))
                .collect();
        }
        j
    }

    fn text(&self) -> String {
        let mut s = self.inspection.text();
        if let Some(t) = self.tolerance_mm {
            let over = self.out_of_tolerance();
            let n = self.inspection.holes.len();
            if over.is_empty() {
                s += &format!("all {n} holes within the position tolerance {t} mm\n");
            } else {
                s += &format!(
                    "{} of {n} holes beyond the position tolerance {t} mm: {}\n",
                    over.len(),
                    over.join(", ")
                );
            }
        }
        s
    }
}

/// JSON of `truepos somac inspect --json` (every length in mm, as the contract's other objects).
impl Inspection {
    /// The inspection as the JSON of `truepos somac inspect --json` (lengths in mm).
    pub fn to_json(&self) -> serde_json::Value {
        let v3 = |p: &Point3| serde_json::json!([p.x, p.y, p.z]);
        serde_json::json!({
            "holes": self.holes.iter().map(|r| serde_json::json!({
                "id": r.hole.id,
                "line": r.hole.line,
                "nominal_mm": v3(&r.hole.nominal_mm),
                "nominal_diameter_mm": r.hole.diameter_mm,
                "measured_mm": v3(&r.measured_mm),
                "error_xy_mm": r.error_xy_mm,
                "position_error_mm": r.position_error_mm,
                "true_position_mm": r.true_position_mm(),
                "diameter_mm": r.diameter_mm,
                "diameter_error_mm": r.diameter_error_mm,
                "roundness_mm": r.roundness_mm,
                "rms_mm": r.rms_mm,
                "center_uncertainty_mm": r.center_uncertainty_mm,
                "diameter_uncertainty_mm": r.diameter_uncertainty_mm,
                "n_points": r.points.len(),
                "points": r.points.iter().map(v3).collect::<Vec<_>>(),
                "elapsed_s": r.elapsed_s,
            })).collect::<Vec<_>>(),
            "n_holes": self.stats.n,
            "mean_error_mm": self.stats.mean_error_mm,
            "std_error_mm": self.stats.std_error_mm,
            "max_error_mm": self.stats.max_error_mm,
            "depth_mm": self.plan.depth_mm,
            "points_per_hole": self.plan.points,
            "feed_mm_min": self.plan.feed_mm_s * 60.0,
            "clearance_mm": self.plan.clearance_mm,
            "tip_diameter_mm": 2.0 * self.plan.tip_radius_mm,
            "controller": { "address": self.device.address, "version": self.device.version },
            "elapsed_s": self.elapsed_s,
        })
    }

    /// The same for people: one line per hole, then the statistics.
    pub fn text(&self) -> String {
        let mut s = format!(
            "inspection on {} ({}): {} holes, {} points each at {} mm depth, F{:.0}, in {:.1} s\n",
            self.device.address,
            self.device.version,
            self.holes.len(),
            self.plan.points,
            self.plan.depth_mm,
            self.plan.feed_mm_s * 60.0,
            self.elapsed_s
        );
        s += "  hole        dx µm    dy µm   pos µm   diam mm    Δdiam µm  round µm   time s\n";
        for r in &self.holes {
            s += &format!(
                "  {:<9} {:>8.1} {:>8.1} {:>8.1} {:>9.4} {:>10.1} {:>9.1} {:>8.2}\n",
                r.hole.id,
                r.error_xy_mm[0] * 1e3,
                r.error_xy_mm[1] * 1e3,
                r.position_error_mm * 1e3,
                r.diameter_mm,
                r.diameter_error_mm * 1e3,
                r.roundness_mm * 1e3,
                r.elapsed_s
            );
        }
        s += &format!(
            "  position error: mean {:.1} µm, std {:.1} µm, max {:.1} µm\n",
            self.stats.mean_error_mm * 1e3,
            self.stats.std_error_mm * 1e3,
            self.stats.max_error_mm * 1e3
        );
        s
    }
}

impl truepos_math::exit::HasExitClass for InspectError {
    /// A plan that cannot be carried out (2, nothing moved); a machine or fit failure (3).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        use truepos_math::exit::ExitClass;
        match self {
            InspectError::Plan(_) => ExitClass::Usage,
            InspectError::Device { .. } | InspectError::Fit { .. } => ExitClass::Device,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hole(d: f64) -> Hole {
        Hole { id: "H1".into(), line: None, nominal_mm: Point3::new(10.0, 20.0, 0.0), diameter_mm: d }
    }

    #[test]
    fn requests_start_inside_the_bore_and_end_beyond_the_wall() {
        let plan = InspectPlan { tip_radius_mm: 1.5, points: 4, ..InspectPlan::default() };
        let h = hole(10.0);
        plan.check(std::slice::from_ref(&h)).unwrap();
        let axis = Point3::new(10.0, 20.0, -3.0);
        for r in plan.requests(&h) {
            // Tip centre from 5 − 1.5 − 0.5 = 3 mm to 5 − 1.5 + 0.5 = 4 mm from the axis.
            assert!(((r.start_mm() - axis).norm() - 3.0).abs() < 1e-12);
            assert!(((r.end_mm() - axis).norm() - 4.0).abs() < 1e-12);
            assert_eq!(r.start_mm().z, -3.0);
        }
    }

    #[test]
    fn plans_that_cannot_work_are_refused_before_moving() {
        let p = InspectPlan { tip_radius_mm: 1.5, ..InspectPlan::default() };
        assert!(p.check(&[hole(4.0)]).is_err()); // 2 − 1.5 − 0.5 = 0: no room
        assert!(p.check(&[hole(4.1)]).is_ok());
        assert!(p.check(&[]).is_err());
        assert!(InspectPlan { points: 3, ..p }.check(&[hole(10.0)]).is_err());
        assert!(InspectPlan { points: MAX_POINTS_PER_HOLE, ..p }.check(&[hole(10.0)]).is_ok());
        assert!(InspectPlan { points: MAX_POINTS_PER_HOLE + 1, ..p }.check(&[hole(10.0)]).is_err());
        assert!(InspectPlan { feed_mm_s: 5001.0 / 60.0, ..p }.check(&[hole(10.0)]).is_err());
        assert!(InspectPlan { feed_mm_s: 0.0, ..p }.check(&[hole(10.0)]).is_err());
        assert!(InspectPlan { depth_mm: f64::NAN, ..p }.check(&[hole(10.0)]).is_err());
    }

    #[test]
    fn holes_come_from_the_measurement_blocks() {
        let prog = Program::parse(
            "G21 G90\nG0 X1 Y2 Z10\nG1 Z5 (MSG,Measure SOMaC)\nG0 Z10\nG0 X4 Y2\nG1 Z4 (MSG,Measure SOMaC)\n",
        );
        let h = holes_from_program(&prog, "Measure SOMaC", 6.0);
        assert_eq!(h.len(), 2);
        assert_eq!(h[0].line, Some(3));
        assert_eq!(h[0].nominal_mm, Point3::new(1.0, 2.0, 5.0));
        assert_eq!(h[1].nominal_mm, Point3::new(4.0, 2.0, 4.0));
        assert_eq!(h[1].id, "L6");
    }
}
