//! The `somac` scenario: a wing-spar drilling program on the virtual large gantry with laser
//! trackers ([`truepos_plant::gantry`]), its cell file (`cell.toml`), the run on the virtual cell with the
//! true hole errors, the data set with its `truth.json`, and the demo section.
//!
//! Entry points: [`read_cell_file`] / [`CellFile`] (the cell file: virtual gantry, trackers,
//! part targets and the loop's `[loop]` parameters), [`scenario`], [`run_virtual`],
//! [`write_scenario`], [`demo_section`].

use crate::error::{CellError, Result};
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::collections::BTreeMap;
use std::path::Path;
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};
use truepos_plant::gantry::{CellConfig, Obstruction, TrackerConfig, VirtualCell};
use truepos_report::{self as report, Report, Series};
use truepos_sim::scenario::somac::{spar, SparConfig};
use truepos_sim::thermal::{Step, TemperatureHistory};
use truepos_somac::audit::{AuditSink, MemoryAudit};
use truepos_somac::params::BeamRecovery;
use truepos_somac::stats::{capability_ppm, hole_stats, HoleStats};
use truepos_somac::{run_program, Params, RunReport};

/// The `[air]` table of the cell file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AirFile {
    /// Air temperature at the start, °C.
    pub temperature_c: f64,
    /// Linear temperature drift, °C/h.
    #[serde(default)]
    pub drift_c_per_h: f64,
    /// Step changes (time s, change °C).
    #[serde(default)]
    pub steps: Vec<[f64; 2]>,
    /// Amplitude of the temperature cycle, °C.
    #[serde(default)]
    pub cycle_amplitude_c: f64,
    /// Period of the temperature cycle, s.
    #[serde(default = "default_period")]
    pub cycle_period_s: f64,
    /// Air pressure at the start, Pa.
    pub pressure_pa: f64,
    /// Pressure drift, Pa/h.
    #[serde(default)]
    pub pressure_drift_pa_per_h: f64,
    /// Relative humidity, %.
    pub humidity_pct: f64,
}

fn default_period() -> f64 {
    3600.0
}

/// One `[[part.target]]` nest: id and nominal position.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetFile {
    /// The target's id.
    pub id: String,
    /// Nominal X, program frame, mm.
    pub x_mm: f64,
    /// Nominal Y, program frame, mm.
    pub y_mm: f64,
    /// Nominal Z, program frame, mm.
    pub z_mm: f64,
}

/// The `[part]` table: expansion, placement and target nests.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartFile {
    /// Coefficient of thermal expansion, ppm/°C.
    pub cte_ppm_per_c: f64,
    /// Thermal time constant, s.
    pub tau_s: f64,
    /// Actual placement's rotation about Z relative to nominal, µrad.
    pub placement_rz_urad: f64,
    /// Actual placement's translation relative to nominal, mm.
    pub placement_mm: [f64; 3],
    /// The part's target nests.
    pub target: Vec<TargetFile>,
}

/// One `[[tracker]]` table.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerFile {
    /// Tracker head position, machine frame, mm.
    pub position_mm: [f64; 3],
    /// Rotation of the tracker frame about Z, degrees.
    pub yaw_deg: f64,
    /// Whether the tracker has an absolute distance meter.
    pub adm: bool,
    /// Boxes (lower, upper corner, mm) blocking the line of sight.
    #[serde(default)]
    pub obstructions: Vec<[[f64; 3]; 2]>,
}

/// The `[loop]` table: every loop parameter, optional (absent: the default of [`Params`]).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoopFile {
    /// Text that marks a measurement block in a comment.
    pub keyword: Option<String>,
    /// A stop succeeds when the 3D error is at most this, mm.
    pub threshold_mm: Option<f64>,
    /// Correction moves per stop at most.
    pub max_iterations: Option<usize>,
    /// Longest single correction move, mm.
    pub max_single_correction_mm: Option<f64>,
    /// Largest accumulated correction offset, mm.
    pub max_total_correction_mm: Option<f64>,
    /// Tracker samples per reading.
    pub samples: Option<usize>,
    /// Largest sample standard deviation of a stable reading, mm.
    pub stable_std_mm: Option<f64>,
    /// Attempts at a stable reading before the stop fails.
    pub stable_attempts: Option<usize>,
    /// Dwell after every move before the first reading, s.
    pub dwell_s: Option<f64>,
    /// Lowest temperature the run accepts, °C.
    pub temperature_min_c: Option<f64>,
    /// Highest temperature the run accepts, °C.
    pub temperature_max_c: Option<f64>,
    /// Temperature change that forces a new orientation, °C.
    pub temperature_change_max_c: Option<f64>,
    /// Inclination change that forces a new orientation, µrad.
    pub inclination_limit_urad: Option<f64>,
    /// Part temperature change that triggers a re-scale, °C.
    pub autoscale_step_c: Option<f64>,
    /// Refractive index change that triggers an update, ppm.
    pub refractive_update_ppm: Option<f64>,
    /// Re-orient every this many measurement stops (0: only when forced).
    pub orient_every: Option<usize>,
    /// "manual", "look-ahead" or "look-back".
    pub beam_recovery: Option<String>,
}

/// Named target positions.
pub type Targets = Vec<(String, Point3)>;

/// The cell file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellFile {
    /// Seed of every random draw of the cell.
    pub seed: u64,
    /// Multiplier on the gantry's geometric error magnitudes.
    pub error_scale: f64,
    /// Reflector offset from the ram reference point, ram frame, mm.
    pub tool_offset_mm: [f64; 3],
    /// End-effector vibration amplitude after a move, mm.
    pub vibration_mm: f64,
    /// Probability that someone walks through a beam at a reading.
    pub beam_interrupt_probability: f64,
    /// [time_s, tracker index, tilt_urad]
    pub tracker_bump: Option<[f64; 3]>,
    /// The `[air]` table.
    pub air: AirFile,
    /// The `[part]` table.
    pub part: PartFile,
    /// The `[[tracker]]` tables.
    pub tracker: Vec<TrackerFile>,
    /// The `[loop]` table: the loop parameters.
    #[serde(default, rename = "loop")]
    pub loop_: LoopFile,
    /// The machine's travel (mm, machine frame); optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine: Option<MachineFile>,
}

/// `[machine] travel_min_mm = [x, y, z], travel_max_mm = [x, y, z]`: no commanded or corrected
/// position may leave this box.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineFile {
    /// Lower corner of the travel, machine frame, mm.
    pub travel_min_mm: [f64; 3],
    /// Upper corner of the travel, machine frame, mm.
    pub travel_max_mm: [f64; 3],
}

/// Largest coordinate magnitude accepted anywhere in a cell file (mm): 100 m.
pub const MAX_COORDINATE_MM: f64 = 1e5;

impl CellFile {
    /// Check every field's range; the message names the key.
    fn check(&self) -> Result<(), String> {
        let fin = |name: &str, v: f64| -> Result<(), String> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(format!("{name} must be a finite number, got {v}"))
            }
        };
        let range = |name: &str, v: f64, lo: f64, hi: f64| -> Result<(), String> {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(format!("{name} must be between {lo} and {hi}, got {v}"))
            }
        };
        let coord = |name: &str, p: &[f64; 3]| -> Result<(), String> {
            for v in p {
                range(name, *v, -MAX_COORDINATE_MM, MAX_COORDINATE_MM)?;
            }
            Ok(())
        };
        range("error_scale", self.error_scale, 0.0, 100.0)?;
        range("vibration_mm", self.vibration_mm, 0.0, 10.0)?;
        range("beam_interrupt_probability", self.beam_interrupt_probability, 0.0, 1.0)?;
        coord("tool_offset_mm", &self.tool_offset_mm)?;
        if let Some(b) = self.tracker_bump {
            range("tracker_bump time_s", b[0], 0.0, 1e7)?;
            let k = b[1];
            if !(k.fract() == 0.0 && k >= 0.0 && (k as usize) < self.tracker.len()) {
                return Err(format!(
                    "tracker_bump tracker index {k} is not one of the {} trackers",
                    self.tracker.len()
                ));
            }
            range("tracker_bump tilt_urad", b[2], -1e5, 1e5)?;
        }
        // The air: within the range where the refractive index equation holds (Ciddor, NIST).
        range("[air] temperature_c", self.air.temperature_c, -40.0, 100.0)?;
        range("[air] pressure_pa", self.air.pressure_pa, 10_000.0, 140_000.0)?;
        range("[air] humidity_pct", self.air.humidity_pct, 0.0, 100.0)?;
        fin("[air] drift_c_per_h", self.air.drift_c_per_h)?;
        fin("[air] pressure_drift_pa_per_h", self.air.pressure_drift_pa_per_h)?;
        range("[air] cycle_amplitude_c", self.air.cycle_amplitude_c, 0.0, 50.0)?;
        range("[air] cycle_period_s", self.air.cycle_period_s, 1e-3, 1e7)?;
        for s in &self.air.steps {
            range("[air] steps time_s", s[0], 0.0, 1e7)?;
            range("[air] steps delta_c", s[1], -100.0, 100.0)?;
        }
        range("[part] cte_ppm_per_c", self.part.cte_ppm_per_c, -1000.0, 1000.0)?;
        range("[part] tau_s", self.part.tau_s, 1e-3, 1e7)?;
        range("[part] placement_rz_urad", self.part.placement_rz_urad, -1e6, 1e6)?;
        coord("[part] placement_mm", &self.part.placement_mm)?;
        let mut seen = std::collections::HashSet::new();
        for t in &self.part.target {
            if t.id.trim().is_empty() {
                return Err("[[part.target]] id must not be empty".into());
            }
            if !seen.insert(t.id.as_str()) {
                return Err(format!("[[part.target]] id '{}' appears twice", t.id));
            }
            coord(&format!("[[part.target]] '{}' position", t.id), &[t.x_mm, t.y_mm, t.z_mm])?;
        }
        for (k, t) in self.tracker.iter().enumerate() {
            coord(&format!("[[tracker]] {k} position_mm"), &t.position_mm)?;
            range(&format!("[[tracker]] {k} yaw_deg"), t.yaw_deg, -360.0, 360.0)?;
            for o in &t.obstructions {
                coord(&format!("[[tracker]] {k} obstruction"), &o[0])?;
                coord(&format!("[[tracker]] {k} obstruction"), &o[1])?;
                if !(0..3).all(|i| o[0][i] <= o[1][i]) {
                    return Err(format!("[[tracker]] {k} obstruction: min must not exceed max"));
                }
            }
        }
        if let Some(m) = &self.machine {
            coord("[machine] travel_min_mm", &m.travel_min_mm)?;
            coord("[machine] travel_max_mm", &m.travel_max_mm)?;
            if !(0..3).all(|i| m.travel_min_mm[i] < m.travel_max_mm[i]) {
                return Err("[machine] travel_min_mm must be below travel_max_mm on every axis".into());
            }
        }
        Ok(())
    }
}

impl CellFile {
    /// The cell file of a cell configuration, its part targets and loop parameters.
    pub fn from_config(c: &CellConfig, targets: &[(String, Point3)], params: &Params) -> CellFile {
        CellFile {
            seed: c.seed,
            error_scale: c.error_scale,
            tool_offset_mm: c.tool_offset_mm,
            vibration_mm: c.vibration_mm,
            beam_interrupt_probability: c.beam_interrupt_probability,
            tracker_bump: c.tracker_bump.map(|(t, k, a)| [t, k as f64, a]),
            air: AirFile {
                temperature_c: c.air_temperature.base,
                drift_c_per_h: c.air_temperature.drift * 3600.0,
                steps: c.air_temperature.steps.iter().map(|s| [s.time, s.delta]).collect(),
                cycle_amplitude_c: c.air_temperature.cycle_amplitude,
                cycle_period_s: c.air_temperature.cycle_period,
                pressure_pa: c.pressure_pa,
                pressure_drift_pa_per_h: c.pressure_drift_pa_per_h,
                humidity_pct: c.humidity_pct,
            },
            part: PartFile {
                cte_ppm_per_c: c.part_cte * 1e6,
                tau_s: c.part_tau_s,
                placement_rz_urad: c.placement_rz_urad,
                placement_mm: c.placement_mm,
                target: targets
                    .iter()
                    .map(|(id, p)| TargetFile { id: id.clone(), x_mm: p.x, y_mm: p.y, z_mm: p.z })
                    .collect(),
            },
            tracker: c
                .trackers
                .iter()
                .map(|t| TrackerFile {
                    position_mm: t.position_mm,
                    yaw_deg: t.yaw_deg,
                    adm: t.adm,
                    obstructions: t.obstructions.iter().map(|o| [o.min, o.max]).collect(),
                })
                .collect(),
            loop_: LoopFile {
                autoscale_step_c: Some(params.autoscale_step_c),
                threshold_mm: Some(params.threshold_mm),
                max_iterations: Some(params.max_iterations),
                samples: Some(params.samples),
                ..Default::default()
            },
            machine: params.travel_mm.map(|(lo, hi)| MachineFile { travel_min_mm: lo, travel_max_mm: hi }),
        }
    }

    /// The cell configuration, part targets and loop parameters of the file at `path` (named in
    /// errors), checked.
    pub fn to_config(&self, path: &Path) -> Result<(CellConfig, Targets, Params), InputError> {
        let bad = |m: String| InputError::in_file(path, m);
        self.check().map_err(bad)?;
        if self.tracker.is_empty() {
            return Err(bad("the cell needs at least one [[tracker]]".into()));
        }
        if self.part.target.len() < 3 {
            return Err(bad(format!(
                "real-time orientation needs at least 3 part targets, the cell has {}",
                self.part.target.len()
            )));
        }
        let d = CellConfig::default();
        let c = CellConfig {
            seed: self.seed,
            error_scale: self.error_scale,
            air_temperature: TemperatureHistory {
                base: self.air.temperature_c,
                drift: self.air.drift_c_per_h / 3600.0,
                steps: self.air.steps.iter().map(|s| Step { time: s[0], delta: s[1] }).collect(),
                cycle_amplitude: self.air.cycle_amplitude_c,
                cycle_period: self.air.cycle_period_s,
                cycle_phase: 0.0,
            },
            pressure_pa: self.air.pressure_pa,
            pressure_drift_pa_per_h: self.air.pressure_drift_pa_per_h,
            humidity_pct: self.air.humidity_pct,
            part_cte: self.part.cte_ppm_per_c * 1e-6,
            part_tau_s: self.part.tau_s,
            placement_rz_urad: self.part.placement_rz_urad,
            placement_mm: self.part.placement_mm,
            tool_offset_mm: self.tool_offset_mm,
            vibration_mm: self.vibration_mm,
            beam_interrupt_probability: self.beam_interrupt_probability,
            tracker_bump: self.tracker_bump.map(|b| (b[0], b[1] as usize, b[2])),
            trackers: self
                .tracker
                .iter()
                .map(|t| TrackerConfig {
                    position_mm: t.position_mm,
                    yaw_deg: t.yaw_deg,
                    adm: t.adm,
                    obstructions: t
                        .obstructions
                        .iter()
                        .map(|o| Obstruction { min: o[0], max: o[1] })
                        .collect(),
                })
                .collect(),
            ..d
        };
        let targets =
            self.part.target.iter().map(|t| (t.id.clone(), Point3::new(t.x_mm, t.y_mm, t.z_mm))).collect();
        let l = &self.loop_;
        let p0 = Params::default();
        let params = Params {
            keyword: l.keyword.clone().unwrap_or(p0.keyword.clone()),
            threshold_mm: l.threshold_mm.unwrap_or(p0.threshold_mm),
            max_iterations: l.max_iterations.unwrap_or(p0.max_iterations),
            max_single_correction_mm: l.max_single_correction_mm.unwrap_or(p0.max_single_correction_mm),
            max_total_correction_mm: l.max_total_correction_mm.unwrap_or(p0.max_total_correction_mm),
            samples: l.samples.unwrap_or(p0.samples),
            stable_std_mm: l.stable_std_mm.unwrap_or(p0.stable_std_mm),
            stable_attempts: l.stable_attempts.unwrap_or(p0.stable_attempts),
            dwell_s: l.dwell_s.unwrap_or(p0.dwell_s),
            temperature_min_c: l.temperature_min_c.unwrap_or(p0.temperature_min_c),
            temperature_max_c: l.temperature_max_c.unwrap_or(p0.temperature_max_c),
            temperature_change_max_c: l.temperature_change_max_c.unwrap_or(p0.temperature_change_max_c),
            inclination_limit_urad: l.inclination_limit_urad.unwrap_or(p0.inclination_limit_urad),
            autoscale_step_c: l.autoscale_step_c.unwrap_or(p0.autoscale_step_c),
            refractive_update_ppm: l.refractive_update_ppm.unwrap_or(p0.refractive_update_ppm),
            part_cte_ppm_per_c: self.part.cte_ppm_per_c,
            orient_every: l.orient_every.unwrap_or(p0.orient_every),
            travel_mm: self.machine.as_ref().map(|m| (m.travel_min_mm, m.travel_max_mm)),
            beam_recovery: match l.beam_recovery.as_deref() {
                None => p0.beam_recovery,
                Some("manual") => BeamRecovery::Manual,
                Some("look-ahead") => BeamRecovery::LookAhead,
                Some("look-back") => BeamRecovery::LookBack,
                Some(o) => {
                    return Err(bad(format!(
                        "[loop] beam_recovery must be manual, look-ahead or look-back, got '{o}'"
                    )))
                }
            },
            ..p0
        };
        params.validate().map_err(|m| bad(format!("[loop] {m}")))?;
        Ok((c, targets, params))
    }
}

/// The demo/scenario cell: the default virtual cell, with the loop tuned for an aluminium spar.
pub fn scenario(seed: u64, holes_per_row: usize) -> (CellConfig, truepos_sim::scenario::somac::Spar, Params) {
    let sp = spar(&SparConfig { holes_per_row, ..Default::default() });
    let cfg = CellConfig { seed, ..CellConfig::default() };
    // Aluminium (23 ppm/°C): re-scale every 0.1 °C so the stale scale stays below ~12 µm at 5 m.
    let params = Params {
        autoscale_step_c: 0.1,
        threshold_mm: 0.015,
        max_iterations: 6,
        samples: 10,
        ..Params::default()
    };
    (cfg, sp, params)
}

/// Result of one run on the virtual cell.
pub struct VirtualRun {
    /// The loop's report.
    pub report: RunReport,
    /// True hole errors (mm) per measurement line.
    pub true_errors: Vec<(usize, f64)>,
    /// The machine's volume diagonal, mm.
    pub diagonal_mm: f64,
    /// Simulated duration of the run, s.
    pub duration_s: f64,
}

impl VirtualRun {
    /// Hole statistics of the run: as measured by the trackers (final errors of the stops) and
    /// as the virtual cell's truth has them.
    pub fn stats(&self) -> (HoleStats, HoleStats) {
        let measured: Vec<f64> = self
            .report
            .stops
            .iter()
            .filter(|s| s.final_error_mm.is_finite())
            .map(|s| s.final_error_mm)
            .collect();
        let truth: Vec<f64> = self.true_errors.iter().map(|e| e.1).collect();
        (hole_stats(&measured), hole_stats(&truth))
    }

    /// The run for people (`truepos somac run`): stops and alarms, measured and true hole errors.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let (hs, ts) = self.stats();
        let n_ok =
            self.report.stops.iter().filter(|s| s.status == truepos_somac::run::StopStatus::Success).count();
        let _ = writeln!(
            out,
            "{} stops: {n_ok} SUCCESS; {} alarms; measured error mean {:.4} σ {:.4} max {:.4} mm",
            self.report.stops.len(),
            self.report.alarms.len(),
            hs.mean_error_mm,
            hs.std_error_mm,
            hs.max_error_mm
        );
        let _ = writeln!(
            out,
            "true hole error (virtual cell): mean {:.4} σ {:.4} max {:.4} mm ({:.1} ppm of the diagonal)",
            ts.mean_error_mm,
            ts.std_error_mm,
            ts.max_error_mm,
            capability_ppm(ts.max_error_mm, self.diagonal_mm)
        );
        out
    }

    /// The run as the JSON of `truepos somac run --json` (stops, alarms, measured and true hole
    /// statistics, capability in ppm of the diagonal, the audit database it was recorded in).
    pub fn to_json(&self, audit_db: &Path) -> serde_json::Value {
        let v3 = |v: Vector3| json!([v.x, v.y, v.z]);
        let (hs, ts) = self.stats();
        let true_by_line: BTreeMap<usize, f64> = self.true_errors.iter().copied().collect();
        json!({
            "stops": self.report.stops.iter().map(|s| json!({
                "true_error_mm": true_by_line.get(&s.line),
                "line": s.line,
                "commanded_mm": v3(s.commanded_mm.coords),
                "measured_mm": s.measured_mm.map(|m| v3(m.coords)),
                "corrections": s.corrections.iter().map(|c| v3(*c)).collect::<Vec<_>>(),
                "iterations": s.iterations,
                "final_error_mm": if s.final_error_mm.is_finite() { json!(s.final_error_mm) } else { json!(null) },
                "status": s.status.as_str(),
                "message": s.message,
            })).collect::<Vec<_>>(),
            "alarms": self.report.alarms.iter().map(|al| json!({"line": al.line, "kind": al.kind.as_str(), "message": al.message, "action": al.action})).collect::<Vec<_>>(),
            "halted": self.report.halted,
            "mean_error_mm": hs.mean_error_mm,
            "std_error_mm": hs.std_error_mm,
            "max_error_mm": hs.max_error_mm,
            "capability_ppm": capability_ppm(hs.max_error_mm, self.diagonal_mm),
            "true_mean_error_mm": ts.mean_error_mm,
            "true_std_error_mm": ts.std_error_mm,
            "true_max_error_mm": ts.max_error_mm,
            "true_capability_ppm": capability_ppm(ts.max_error_mm, self.diagonal_mm),
            "orientations": self.report.orientations,
            "refractive_index_updates": self.report.refractive_updates,
            "duration_s": self.duration_s,
            "audit_db": audit_db.display().to_string(),
        })
    }
}

/// Run `program_text` through the control loop on a virtual cell of `cfg`, recording to `sink`.
pub fn run_virtual(
    program_text: &str,
    cfg: CellConfig,
    targets: Vec<(String, Point3)>,
    params: &Params,
    sink: &mut dyn AuditSink,
) -> Result<VirtualRun, truepos_somac::run::RunError> {
    let program = truepos_gcode::Program::parse(program_text);
    let cell = VirtualCell::new(cfg, targets);
    let mut trackers = cell.align_trackers().map_err(|e| {
        truepos_somac::device::DeviceError::Tracker(
            0,
            format!("aligning the trackers on the machine targets: {e}"),
        )
    })?;
    let mut ctl = cell.controller();
    let mut sensors = cell.sensors();
    let report = run_program(&program, &mut ctl, &mut trackers, &mut sensors, params, sink)?;
    // Holes: the nominal (program-frame) positions of the measurement blocks.
    let holes: BTreeMap<usize, Point3> = program
        .blocks()
        .iter()
        .filter(|b| b.target_mm.is_some() && b.has_keyword(&params.keyword))
        .filter_map(|b| b.target_mm.map(|t| (b.line + 1, t)))
        .collect();
    let true_errors = cell.hole_errors(&holes);
    Ok(VirtualRun { report, true_errors, diagonal_mm: cell.diagonal_mm(), duration_s: cell.time_s() })
}

/// Demo: the spar with and without correction.
pub fn demo_section(report: &mut Report) -> Result<()> {
    let (cfg, sp, params) = scenario(1, 150);
    let cfg_bump = cfg.tracker_bump;
    let native = Params { correct: false, orient: false, ..params.clone() };
    let r0 = run_virtual(&sp.program, cfg.clone(), sp.targets.clone(), &native, &mut MemoryAudit::default())?;
    let mut audit = MemoryAudit::default();
    let r1 = run_virtual(&sp.program, cfg, sp.targets.clone(), &params, &mut audit)?;
    let e0: Vec<f64> = r0.true_errors.iter().map(|e| e.1 * 1000.0).collect();
    let e1: Vec<f64> = r1.true_errors.iter().map(|e| e.1 * 1000.0).collect();
    let (s0, s1) = (hole_stats(&e0), hole_stats(&e1));
    let rows = vec![
        vec![
            "without correction".into(),
            format!("{:.1}", s0.mean_error_mm),
            format!("{:.1}", s0.std_error_mm),
            format!("{:.1}", s0.max_error_mm),
            format!("{:.1}", capability_ppm(s0.max_error_mm / 1000.0, r0.diagonal_mm)),
        ],
        vec![
            "with truepos end-point control".into(),
            format!("{:.1}", s1.mean_error_mm),
            format!("{:.1}", s1.std_error_mm),
            format!("{:.1}", s1.max_error_mm),
            format!("{:.1}", capability_ppm(s1.max_error_mm / 1000.0, r1.diagonal_mm)),
        ],
    ];
    // Each histogram on its own data range (the corrected errors would fill two bins of the
    // uncorrected range), both with the tolerance drawn.
    let tol_um = 50.0;
    let tol_label = format!("tolerance {tol_um:.0} µm");
    let tol_mark = [report::Mark { label: &tol_label, value: tol_um }];
    let hist0 = report::histogram(
        "True hole position error without correction",
        "error (µm)",
        &[("without correction", &e0)],
        40,
        None,
        &tol_mark,
    )?;
    let hist1 = report::histogram(
        "True hole position error with correction",
        "error (µm)",
        &[("with truepos end-point control", &e1)],
        40,
        None,
        &tol_mark,
    )?;
    // Corrections over time: the offset in force (what the machine's own error amounts to at
    // that place and time) and each correction move sent.
    let (mut offset, mut moves) = (vec![], vec![]);
    for e in &audit.events {
        if let truepos_somac::audit::Event::Correction { delta_mm, offset_mm, time_s, .. } = e {
            offset.push((time_s / 60.0, offset_mm.norm() * 1000.0));
            moves.push((time_s / 60.0, delta_mm.norm() * 1000.0));
        }
    }
    let plot = report::xy_plot(
        "Corrections over time",
        "time (min)",
        "µm",
        &[Series::points("|offset in force|", offset), Series::points("|correction move|", moves)],
    )?;
    // One row per alarm and line: the loop raises the same alarm at every retry on a line; the
    // count says how often.
    let mut alarms: Vec<Vec<String>> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    for a in &r1.report.alarms {
        let row = vec![a.line.to_string(), a.kind.as_str().to_string(), a.message.clone(), a.action.clone()];
        match alarms.iter().position(|r| *r == row) {
            Some(i) => counts[i] += 1,
            None => {
                alarms.push(row);
                counts.push(1);
            }
        }
    }
    for (r, n) in alarms.iter_mut().zip(&counts) {
        r.push(n.to_string());
    }
    // The bumped tracker: say when it happened and that no correction came from its readings.
    let bump_note = match (cfg_bump, r1.report.alarms.iter().find(|a| a.kind.as_str() == "inclination")) {
        (Some((t, k, tilt)), Some(a)) => format!(
            "Tracker {} is bumped ({tilt:.0} µrad) at {:.1} min: its inclinometer shows it at line {}, the readings taken with it are discarded before any correction is sent, the trackers are re-aligned on the machine targets and the part re-oriented, and the stop is measured again.",
            k + 1,
            t / 60.0,
            a.line
        ),
        (Some((t, k, _)), None) => format!("Tracker {} is bumped at {:.1} min; no inclination alarm fired.", k + 1, t / 60.0),
        _ => String::new(),
    };
    let run_verdict = r1.report.verdict();
    report.verdict(report::Verdict {
        section: "somac".into(),
        capability: "End-point control (SOMaC)".into(),
        measured: format!("true 3D position error of {} drilled holes", e1.len()),
        truth: format!(
            "hole positions on the warm part in the simulator (uncorrected: mean {:.0} µm, max {:.0} µm)",
            s0.mean_error_mm, s0.max_error_mm
        ),
        result: format!(
            "mean {:.1} µm, σ {:.1} µm, max {:.1} µm; the run's own verdict: {} ({})",
            s1.mean_error_mm,
            s1.std_error_mm,
            s1.max_error_mm,
            run_verdict.verdict.as_str(),
            run_verdict.reasons.join("; ")
        ),
        uncertainty: format!(
            "U = {:.1} µm (k = 2) spread of one hole (2σ over holes); trackers MPE ±(15 µm + 6 µm/m)",
            2.0 * s1.std_error_mm
        ),
        tolerance_text: format!("every hole within {tol_um:.0} µm (tracker MPE at ~5 m: 45 µm); every stop SUCCESS; the tracker bump the demo injects detected by an inclination alarm (so `truepos somac run` on this cell ends with verdict `alarm`, exit 1: a person reviews a run with an alarm)"),
        ..report::Verdict::judged(
            report::Judgement::new(s1.max_error_mm, 2.0 * s1.std_error_mm, tol_um, "µm", report::DecisionRule::Simple)
                .require(
                    run_verdict.verdict != truepos_somac::run::RunOutcome::Fail,
                    format!("the run failed: {}", run_verdict.reasons.join("; ")),
                )
                .require(
                    cfg_bump.is_none() || r1.report.alarms.iter().any(|a| a.kind.as_str() == "inclination"),
                    "the injected tracker bump raised no inclination alarm",
                ),
        )
    });
    let html = format!(
        "<p>A {}-hole wing-spar drilling program on the virtual 12 m × 4 m × 2 m gantry (geometric errors, thermal growth of the scales, part misplaced by ~1.4 mm and 150 µrad, aluminium part warming during the run), two laser trackers with MPE ±(15 µm + 6 µm/m), beam breaks and a tracker bumped mid-run. Errors are true 3D distances between the drilled position and the hole on the warm part.</p>{}{}{}{}<p>In the corrections plot, “|offset in force|” is the accumulated correction at each stop that needed one: what the gantry's own geometric and thermal error amounts to at that place and time after the program was oriented on the part targets (a few hundred µm on this machine). “|correction move|” is each move sent (tens of µm, the loop's threshold is {:.0} µm). {}</p><h3>Alarms</h3>{}<p>{} orientations, {} refractive-index updates.</p>",
        sp.holes.len(),
        report::table(&["run", "mean (µm)", "σ (µm)", "max (µm)", "capability (ppm of diagonal)"], &rows),
        hist0,
        hist1,
        plot,
        params.threshold_mm * 1000.0,
        bump_note,
        report::table(&["line", "kind", "message", "action", "times"], &alarms),
        r1.report.orientations,
        r1.report.refractive_updates,
    );
    report.add("somac", "Laser-tracker end-point control of a large gantry", html);
    Ok(())
}

/// Read a cell file (`cell.toml`): the virtual cell, the part's targets and the loop
/// parameters. Unknown keys and bad values name the file (and line and column where TOML
/// parsing finds them).
pub fn read_cell_file(path: &Path) -> Result<(CellConfig, Targets, Params), InputError> {
    let (file, doc): (CellFile, _) = truepos_io::config::read_toml_doc(path)?;
    file.to_config(path).map_err(|e| doc.locate_error(e))
}

/// What [`write_scenario`] wrote.
pub struct Written {
    /// Number of holes in the program.
    pub holes: usize,
    /// Mean true hole error of the program run as written: no orientation, no correction (mm).
    pub native_mean_error_mm: f64,
    /// Mean true hole error with the orientation through the part targets but no correction
    /// loop, as `somac run --no-correct` runs it (mm).
    pub oriented_only_mean_error_mm: f64,
    /// Number of trackers in the cell.
    pub trackers: usize,
}

impl Written {
    /// What `truepos simulate somac` prints: the scenario, the true error without end-point
    /// control (native and oriented only), the command to run and how to compare.
    pub fn text(&self, dir: &Path) -> String {
        let dir = dir.display();
        format!(
            "somac scenario: a {}-hole wing-spar program on the virtual 12 m gantry with {} laser trackers → {dir}/program.nc, cell.toml (commented), truth.json\n\
             true mean hole error without end-point control: {:.3} mm as written (native), {:.3} mm oriented on the part targets but not corrected\n\
             next: truepos somac run --program {dir}/program.nc --cell {dir}/cell.toml --db {dir}/audit.sqlite\n  \
             (compare: add --no-correct for the oriented-only figure, --no-correct --no-orient for the native one)\n",
            self.holes, self.trackers, self.native_mean_error_mm, self.oriented_only_mean_error_mm
        )
    }
}

/// Write `program.nc`, `cell.toml` and `truth.json` (the holes, the part placement and the
/// native error of this cell: the same run without corrections) into `dir`.
pub fn write_scenario(dir: &Path, seed: u64, holes_per_row: usize) -> Result<Written> {
    let (cfg, sp, params) = scenario(seed, holes_per_row);
    std::fs::create_dir_all(dir).map_err(|e| CellError::io(dir, e))?;
    let cell = CellFile::from_config(&cfg, &sp.targets, &params);
    let toml = annotate_cell_toml(&toml::to_string_pretty(&cell)?);
    truepos_io::atomic::write_atomic(dir.join("program.nc"), sp.program.as_bytes())?;
    truepos_io::atomic::write_atomic(dir.join("cell.toml"), toml.as_bytes())?;
    let native = Params { correct: false, orient: false, ..params.clone() };
    let vr = run_virtual(&sp.program, cfg.clone(), sp.targets.clone(), &native, &mut MemoryAudit::default())?;
    let e: Vec<f64> = vr.true_errors.iter().map(|x| x.1).collect();
    let ns = hole_stats(&e);
    // What `somac run --no-correct` does: the program is still oriented through the measured
    // part targets (placement, thermal scale), only the per-hole correction loop is off.
    let oriented = Params { correct: false, ..params.clone() };
    let vo =
        run_virtual(&sp.program, cfg.clone(), sp.targets.clone(), &oriented, &mut MemoryAudit::default())?;
    let eo: Vec<f64> = vo.true_errors.iter().map(|x| x.1).collect();
    let os = hole_stats(&eo);
    let v3 = |p: &Point3| [p.x, p.y, p.z];
    let truth = json!({
        "holes": sp.holes.iter().map(|(l, p)| json!({"line": l, "nominal_mm": v3(p)})).collect::<Vec<_>>(),
        "part_targets": sp.targets.iter().map(|(id, p)| json!({"id": id, "nominal_mm": v3(p)})).collect::<Vec<_>>(),
        "placement_rz_urad": cfg.placement_rz_urad,
        "placement_mm": cfg.placement_mm,
        "part_cte_ppm_per_c": cfg.part_cte * 1e6,
        "native_mean_error_mm": ns.mean_error_mm,
        "native_max_error_mm": ns.max_error_mm,
        "oriented_only_mean_error_mm": os.mean_error_mm,
        "oriented_only_max_error_mm": os.max_error_mm,
        "note": "native_*: true hole errors of the program run as written (no orientation, no correction: `somac run --no-correct --no-orient`); oriented_only_*: the program oriented through the measured part targets but without the correction loop (`somac run --no-correct`)",
    });
    truepos_io::atomic::write_atomic(
        dir.join("truth.json"),
        serde_json::to_string_pretty(&truth)?.as_bytes(),
    )?;
    Ok(Written {
        holes: sp.holes.len(),
        native_mean_error_mm: ns.mean_error_mm,
        oriented_only_mean_error_mm: os.mean_error_mm,
        trackers: cfg.trackers.len(),
    })
}

/// Comments for the keys of `cell.toml`: `(table, key, comment)`; table "" is the top level,
/// key "" comments the table header itself (first occurrence only).
const CELL_COMMENTS: &[(&str, &str, &str)] = &[
    ("", "seed", "random seed of the virtual cell (tracker noise, beam breaks, vibration)"),
    (
        "",
        "error_scale",
        "multiplier on the virtual gantry's geometric errors (1 = as built; a worn machine > 1)",
    ),
    ("", "tool_offset_mm", "reflector (drill point) offset from the ram reference point, ram frame (mm)"),
    ("", "vibration_mm", "end-effector vibration amplitude after a move (mm)"),
    (
        "",
        "beam_interrupt_probability",
        "probability that someone walks through a tracker beam at a reading (0 to 1)",
    ),
    ("", "tracker_bump", "a tracker is bumped: [time_s, tracker index, tilt_urad]"),
    ("air", "", "shop air around the trackers (refractive index, part temperature)"),
    ("air", "temperature_c", "air temperature at the start (°C)"),
    ("air", "drift_c_per_h", "linear temperature drift (°C per hour)"),
    ("air", "steps", "sudden temperature changes: [time_s, delta_c] (a door opened)"),
    ("air", "cycle_amplitude_c", "amplitude of a periodic temperature cycle (°C; air conditioning)"),
    ("air", "cycle_period_s", "period of that cycle (s)"),
    ("air", "pressure_pa", "air pressure (Pa)"),
    ("air", "pressure_drift_pa_per_h", "pressure drift (Pa per hour)"),
    ("air", "humidity_pct", "relative humidity (%)"),
    ("part", "", "the part: material, how it is really placed, its targets"),
    ("part", "cte_ppm_per_c", "coefficient of thermal expansion (ppm/°C; aluminium 23)"),
    ("part", "tau_s", "thermal time constant of the part following the air (s)"),
    (
        "part",
        "placement_rz_urad",
        "actual placement against the program's nominal one: rotation about Z (µrad)",
    ),
    ("part", "placement_mm", "and translation (mm)"),
    ("part.target", "", "tracker targets on the part, nominal positions in the program frame (mm)"),
    ("tracker", "", "one laser tracker (MPE ±(15 µm + 6 µm/m))"),
    ("tracker", "position_mm", "tracker head position in the machine frame (mm)"),
    ("tracker", "yaw_deg", "rotation of the tracker frame about Z against the machine (degrees)"),
    (
        "tracker",
        "adm",
        "absolute distance meter: can reacquire a broken beam by pointing (look-ahead recovery)",
    ),
    (
        "tracker",
        "obstructions",
        "boxes that block the beam: [[min_x, min_y, min_z], [max_x, max_y, max_z]] (mm)",
    ),
    ("loop", "", "the measure / compare / correct loop (every key optional; truepos somac run --help)"),
    ("loop", "keyword", "comment text that marks a measurement block in the program"),
    ("loop", "threshold_mm", "a stop succeeds when its 3D error is at most this (mm)"),
    ("loop", "max_iterations", "correction moves per stop at most"),
    ("loop", "max_single_correction_mm", "largest single correction move (mm)"),
    ("loop", "max_total_correction_mm", "largest accumulated correction offset (mm)"),
    ("loop", "samples", "repeated tracker samples per reading"),
    ("loop", "autoscale_step_c", "re-scale the part when its temperature has moved by this (°C)"),
    ("machine", "", "the machine's travel: no commanded or corrected position may leave this box"),
    ("machine", "travel_min_mm", "lower corner, machine frame (mm)"),
    ("machine", "travel_max_mm", "upper corner, machine frame (mm)"),
];

/// `cell.toml` as written by [`write_scenario`], with a `#` comment (meaning and unit) above
/// every key and table it knows (`CELL_COMMENTS`).
pub fn annotate_cell_toml(text: &str) -> String {
    let mut out = String::from(
        "# truepos cell file: the virtual large gantry, its laser trackers, the part and the loop.\n\
         # Written by `truepos simulate somac`; read by `truepos somac run --cell`. Lengths mm, angles as named.\n",
    );
    let mut table = String::new();
    let mut seen_tables = std::collections::HashSet::new();
    let mut seen_keys = std::collections::HashSet::new();
    for line in text.lines() {
        let t = line.trim();
        let header = t.strip_prefix("[[").and_then(|r| r.strip_suffix("]]")).or_else(|| {
            t.strip_prefix('[')
                .and_then(|r| r.strip_suffix(']'))
                .filter(|r| !r.contains(',') && !r.is_empty())
        });
        if let Some(h) =
            header.filter(|h| h.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.'))
        {
            table = h.trim().to_string();
            if seen_tables.insert(table.clone()) {
                if let Some(c) = CELL_COMMENTS.iter().find(|c| c.0 == table && c.1.is_empty()) {
                    if !out.ends_with("\n\n") {
                        out.push('\n');
                    }
                    out.push_str(&format!("# {}\n", c.2));
                }
            }
        } else if let Some((key, _)) = t.split_once(" = ") {
            let key = key.trim();
            if seen_keys.insert((table.clone(), key.to_string())) {
                if let Some(c) = CELL_COMMENTS.iter().find(|c| c.0 == table && c.1 == key) {
                    out.push_str(&format!("# {}\n", c.2));
                }
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> CellFile {
        let (cfg, sp, params) = scenario(7, 2);
        CellFile::from_config(&cfg, &sp.targets, &params)
    }

    /// The cases: each is refused naming the key.
    #[test]
    fn cell_file_values_are_checked() {
        let p = Path::new("cell.toml");
        file().to_config(p).unwrap();
        type Mutation = Box<dyn Fn(&mut CellFile)>;
        let cases: Vec<(Mutation, &str)> = vec![
            (Box::new(|f| f.part.target[1].id = f.part.target[0].id.clone()), "appears twice"),
            (Box::new(|f| f.beam_interrupt_probability = 2.0), "beam_interrupt_probability"),
            (Box::new(|f| f.vibration_mm = -0.1), "vibration_mm"),
            (Box::new(|f| f.part.target[0].x_mm = 1e12), "position"),
            (Box::new(|f| f.air.temperature_c = -300.0), "temperature_c"),
            (Box::new(|f| f.air.humidity_pct = 150.0), "humidity_pct"),
            (Box::new(|f| f.part.target[0].id = " ".into()), "empty"),
            (Box::new(|f| f.tracker_bump = Some([1.0, 9.0, 10.0])), "tracker_bump"),
            (
                Box::new(|f| {
                    f.machine = Some(MachineFile { travel_min_mm: [0.0; 3], travel_max_mm: [1.0, 1.0, -1.0] })
                }),
                "travel",
            ),
            (Box::new(|f| f.loop_.samples = Some(1_000_000_000)), "samples"),
        ];
        for (mutate, needle) in cases {
            let mut f = file();
            mutate(&mut f);
            let e = f.to_config(p).expect_err(needle).to_string();
            assert!(e.contains(needle) && e.contains("cell.toml"), "{needle}: {e}");
        }
    }

    /// The written cell file is commented and still reads back to the same cell.
    #[test]
    fn annotated_cell_file_reads_back() {
        let f = file();
        let text = annotate_cell_toml(&toml::to_string_pretty(&f).unwrap());
        for needle in [
            "# probability that someone walks",
            "# air pressure (Pa)",
            "# tracker head position",
            "# a stop succeeds",
        ] {
            assert!(text.contains(needle), "{needle} missing in:\n{text}");
        }
        // Array-of-tables headers are commented once, not per target.
        assert_eq!(text.matches("# tracker targets on the part").count(), 1, "{text}");
        let back: CellFile = toml::from_str(&text).unwrap();
        assert_eq!(toml::to_string_pretty(&back).unwrap(), toml::to_string_pretty(&f).unwrap());
    }

    /// A travel box that excludes the program's holes: the run stops at the first block outside
    /// it with a `travel_limit` alarm instead of moving there.
    #[test]
    fn blocks_outside_the_travel_stop_the_run() {
        let (cfg, sp, mut params) = scenario(7, 2);
        params.travel_mm = Some(([-1e4, -1e4, -1e4], [1e4, 1e4, -5e3]));
        let vr =
            run_virtual(&sp.program, cfg, sp.targets.clone(), &params, &mut MemoryAudit::default()).unwrap();
        assert!(vr.report.halted);
        assert!(vr.report.alarms.iter().any(|a| a.kind.as_str() == "travel_limit"), "{:?}", vr.report.alarms);
        assert!(vr.report.stops.is_empty());
    }
}
