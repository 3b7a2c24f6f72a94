//! The `load` scenario: a die on three pads on the virtual bridge CMM's granite bed, written as
//! `bed.toml`, `load.toml`, `points.csv` and `truth.json`; and the demo section (influence map,
//! load case, correction against the simulator's fine-mesh truth).
//!
//! Entry points: [`write_scenario`], [`demo_section`].

use crate::error::{CellError, Context, Result};
use serde_json::json;
use std::path::Path;
use truepos_comp::fe_map::{self, BedModel, LoadGrid};
use truepos_comp::files::{rms_max_um, write_influence, G};
use truepos_comp::statics;
use truepos_comp::{Corrector, LoadCorrection, Portal};
use truepos_fe::{MeshOptions, Supports};
use truepos_io::atomic::{write_atomic, AtomicFile};
use truepos_io::csv::CsvWriter;
use truepos_math::{Point3, Vector3};
use truepos_report::{self as report, Report, Series};
use truepos_sim::scenario::load::{simulate as sim_load, LoadConfig, LoadData};

fn bed_toml(c: &LoadConfig) -> String {
    let supports = match &c.bed.supports {
        Supports::Points { xy, .. } => format!(
            "supports_mm = [{}]",
            xy.iter().map(|p| format!("[{}, {}]", p[0], p[1])).collect::<Vec<_>>().join(", ")
        ),
        Supports::SimplySupportedEdges => "supports = \"simply-supported-edges\"".into(),
    };
    format!(
        "# Virtual bridge CMM: granite bed on its pads, portal rails (truepos simulate load).\n\
         # Bed coordinates are machine X, Y (mm); deflection uz is positive upwards.\n\
         [bed]\n\
         # plate size along X and Y, and thickness (mm)\nsize_x_mm = {}\nsize_y_mm = {}\nthickness_mm = {}\n\
         # Young's modulus (MPa) and Poisson's ratio of the granite\nyoungs_modulus_mpa = {}\npoisson = {}\n\
         # support pads under the bed, [x, y] (mm)\n{supports}\n\
         # finite-element size of the influence map (mm)\nelement_size_mm = {}\n\n\
         [portal]\n\
         # X of the two rails the portal runs on (mm), and the height (machine Z) of its pivot on them (mm)\nrail_x_mm = [{}, {}]\nrail_height_mm = {}\n\
         # distance between the portal's bearings along Y (mm)\nbearing_span_mm = {}\n\
         # portal positions at which the map gives pitch and roll: from, to, step (mm)\ny_range_mm = [{}, {}]\ny_step_mm = {}\n\n\
         [grid]\n\
         # spacing of the unit loads of the influence map (mm) and their size (N)\nspacing_mm = {}\nunit_load_n = {}\n",
        c.bed.size_x, c.bed.size_y, c.bed.thickness, c.bed.youngs_modulus, c.bed.poisson, c.map_element_size, c.rail_x[0], c.rail_x[1], c.rail_height, c.bearing_span, c.y_range[0], c.y_range[1], c.y_step, c.grid_spacing, c.unit_load_n
    )
}

fn load_toml(c: &LoadConfig) -> String {
    format!(
        "# A die on three pads (truepos simulate load).\n\
         # mass of the part (kg); its weight is shared among the resting points by statics\nmass_kg = {}\n\
         # centre of gravity, [x, y] in bed (machine) coordinates (mm)\ncog_mm = [{}, {}]\n\
         # where the part rests on the bed, [x, y] (mm)\nrest_points_mm = [{}]\n",
        c.mass_kg,
        c.cog[0],
        c.cog[1],
        c.rests.iter().map(|p| format!("[{}, {}]", p[0], p[1])).collect::<Vec<_>>().join(", ")
    )
}

/// Write the scenario (`bed.toml`, `load.toml`, `points.csv`, `truth.json`) into `dir`; the
/// configuration and the simulated data. `mass_kg` must be positive and `noise_um` non-negative.
pub fn write_scenario(dir: &Path, seed: u64, mass_kg: f64, noise_um: f64) -> Result<(LoadConfig, LoadData)> {
    if !(mass_kg.is_finite() && mass_kg > 0.0 && noise_um.is_finite() && noise_um >= 0.0) {
        return Err(CellError::Invalid(format!(
            "--mass-kg must be positive and --noise-um non-negative (got {mass_kg}, {noise_um})"
        )));
    }
    let cfg = LoadConfig { mass_kg, noise_sigma: noise_um * 1e-3, ..LoadConfig::default() };
    let data = sim_load(&cfg, seed).context("load scenario")?;
    std::fs::create_dir_all(dir).map_err(|e| CellError::io(dir, e))?;
    write_atomic(dir.join("bed.toml"), bed_toml(&cfg).as_bytes())?;
    write_atomic(dir.join("load.toml"), load_toml(&cfg).as_bytes())?;
    let mut f = AtomicFile::create(dir.join("points.csv"))?;
    {
        // 7 decimals: 0.1 nm, far below the probing noise; outputs keep this precision.
        let mut w = CsvWriter::new(&mut f).with_format(truepos_io::num::NumFormat::Fixed(7));
        w.comment(&format!(
            "indicated coordinates on the loaded virtual CMM, seed {seed}, probing noise {} µm per axis",
            cfg.noise_sigma * 1e3
        ))?;
        w.header(&["id", "x_mm", "y_mm", "z_mm"])?;
        for (i, p) in data.indicated.iter().enumerate() {
            w.field_str(&format!("P{}", i + 1))?;
            w.row_f64(&[p.x, p.y, p.z])?;
        }
    }
    f.commit()?;
    let um = |v: &[f64]| v.iter().map(|x| x * 1e6).collect::<Vec<_>>();
    let truth = json!({
        "scenario": "load",
        "seed": seed,
        "weight_n": data.weight_n,
        "forces_n": data.forces_n,
        "rest_points_mm": cfg.rests,
        "ids": (1..=data.indicated.len()).map(|i| format!("P{i}")).collect::<Vec<_>>(),
        "true_points_mm": data.true_points.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
        "error_um": data.indicated_exact.iter().zip(&data.true_points).map(|(i, t)| [(i.x - t.x) * 1e3, (i.y - t.y) * 1e3, (i.z - t.z) * 1e3]).collect::<Vec<_>>(),
        "noise_um": data.indicated.iter().zip(&data.indicated_exact).map(|(n, e)| [(n.x - e.x) * 1e3, (n.y - e.y) * 1e3, (n.z - e.z) * 1e3]).collect::<Vec<_>>(),
        "noise_sigma_um": cfg.noise_sigma * 1e3,
        "portal_y_mm": data.portal_y,
        "pitch_urad": um(&data.pitch),
        "roll_urad": um(&data.roll),
        "portal_sink_um": data.portal_sink.iter().map(|v| v * 1e3).collect::<Vec<_>>(),
        "rest_uz_um": data.rest_uz.iter().map(|v| v * 1e3).collect::<Vec<_>>(),
        "sim_element_size_mm": cfg.sim_element_size,
        "map_element_size_mm": cfg.map_element_size,
        "notes": "error_um = indicated (noise-free) − true; pitch/roll in truepos-comp's sign (rotation of the bed seen from the portal = −physical tilt); portal_sink is not applied to the points",
    });
    write_atomic(dir.join("truth.json"), serde_json::to_string_pretty(&truth)?.as_bytes())?;
    Ok((cfg, data))
}

/// This capability's section of the demo report.
/// Expanded uncertainty (µm) of the load-induced error after correction: both sides are
/// deterministic FE solutions; a bound on the sparse solvers' numerical error.
const LOAD_MODEL_U_UM: f64 = 0.001;

/// The report section of the load scenario: the bed deflection compensated against the truth.
pub fn demo_section(report: &mut Report) -> Result<()> {
    let dir = report.dir.join("load");
    let (cfg, data) = write_scenario(&dir, 1, 2000.0, 0.3)?;
    let portal = Portal {
        rail_x: cfg.rail_x,
        rail_height: cfg.rail_height,
        bearing_span: cfg.bearing_span,
        y_range: cfg.y_range,
        y_step: cfg.y_step,
    };
    let model = BedModel {
        bed: cfg.bed.clone(),
        portal,
        grid: LoadGrid { spacing: cfg.grid_spacing, unit_load_n: cfg.unit_load_n },
    };
    let t0 = std::time::Instant::now();
    let map = fe_map::influence_map(&model, &MeshOptions::with_element_size(cfg.map_element_size), &|_| {})?;
    // Time goes to the log, not the report (reruns stay byte-identical).
    eprintln!("  load: influence map in {:.1} s", t0.elapsed().as_secs_f64());
    write_influence(&map, &dir.join("map.csv"), "plate FE of bed.toml")
        .map_err(|e| CellError::io(dir.join("map.csv"), e))?;
    let forces = statics::distribute(cfg.mass_kg * G, cfg.cog, &cfg.rests)?;
    let loads: Vec<(f64, f64, f64)> = cfg.rests.iter().zip(&forces).map(|(r, f)| (r[0], r[1], *f)).collect();
    let curves = map.superpose(&loads)?;
    let lc = LoadCorrection::new(curves.clone(), &portal);
    let corr = Corrector { geometric: None, load: Some(&lc), probe_offset: Vector3::zeros() };
    let mut corrected: Vec<Point3> = data.indicated.clone();
    corr.correct_measured(&mut corrected, None)?;
    let err =
        |a: &[Point3]| -> Vec<Vector3> { a.iter().zip(&data.true_points).map(|(p, t)| p - t).collect() };
    let before = err(&data.indicated_exact);
    let after_load: Vec<Point3> = corrected
        .iter()
        .zip(&data.indicated)
        .zip(&data.indicated_exact)
        .map(|((c, n), e)| c - (n - e))
        .collect();
    let after = err(&after_load);
    let (rb, mb) = rms_max_um(&before);
    let (ra, ma) = rms_max_um(&after);
    let (rn0, mn0) = rms_max_um(&err(&data.indicated));
    let (rn, mn) = rms_max_um(&err(&corrected));
    let heat = report::heatmap(
        "Bed deflection uz under the die",
        &data.grid_x,
        &data.grid_y,
        &data.uz.iter().map(|r| r.iter().map(|v| v * 1e3).collect()).collect::<Vec<Vec<f64>>>(),
        "µm",
    )?;
    let curve_plot = report::xy_plot(
        "Portal pitch and roll along Y",
        "portal y (mm)",
        "µrad",
        &[
            Series::line(
                "pitch (map, superposed)",
                curves.y().iter().zip(&curves.pitch).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
            Series::points(
                "pitch (truth, fine FE)",
                data.portal_y.iter().zip(&data.pitch).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
            Series::line(
                "roll (map, superposed)",
                curves.y().iter().zip(&curves.roll).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
            Series::points(
                "roll (truth, fine FE)",
                data.portal_y.iter().zip(&data.roll).map(|(y, p)| (*y, p * 1e6)).collect(),
            ),
        ],
    )?;
    let rows = vec![
        vec![
            "load-induced error (noise excluded)".into(),
            format!("{rb:.3}"),
            format!("{mb:.3}"),
            format!("{ra:.4}"),
            format!("{ma:.4}"),
            format!("{:.2} %", 100.0 * (1.0 - ra / rb)),
        ],
        vec![
            format!("measured − true (incl. {:.1} µm probing noise)", cfg.noise_sigma * 1e3),
            format!("{rn0:.3}"),
            format!("{mn0:.3}"),
            format!("{rn:.3}"),
            format!("{mn:.3}"),
            format!("{:.2} %", 100.0 * (1.0 - rn / rn0)),
        ],
    ];
    let force_rows: Vec<Vec<String>> = cfg
        .rests
        .iter()
        .zip(&forces)
        .zip(&data.forces_n)
        .map(|((r, f), t)| vec![format!("({:.0}, {:.0})", r[0], r[1]), format!("{f:.2}"), format!("{t:.2}")])
        .collect();
    let html = format!(
        "<p>A {} kg die on three pads on a {}×{}×{} mm granite bed (four support pads). The influence map ({} unit loads of {} N on a {} mm grid × {} portal positions, FE element {} mm) was computed for this report; the simulator's truth uses a {} mm mesh. {} points measured at two heights with {} µm probing noise.</p>{}{}<p>Forces on the pads by statics:</p>{}<p>Errors of the measured points against truth (µm):</p>{}",
        cfg.mass_kg, cfg.bed.size_x, cfg.bed.size_y, cfg.bed.thickness,
        map.load_x().len() * map.load_y().len(), cfg.unit_load_n, cfg.grid_spacing, map.portal_y().len(), cfg.map_element_size, cfg.sim_element_size,
        data.indicated.len(), cfg.noise_sigma * 1e3,
        heat, curve_plot,
        report::table(&["pad (mm)", "truepos (N)", "truth (N)"], &force_rows),
        report::table(&["errors", "RMS before", "max before", "RMS after", "max after", "removed"], &rows),
    );
    report.verdict(report::Verdict {
        section: "load".into(),
        capability: "Bed load correction".into(),
        measured: format!("{} points on the loaded bed, corrected with the influence map", data.indicated.len()),
        truth: "fine-mesh FE deflection of the simulator (load-induced error before correction: max {mb:.2} µm)".replace("{mb:.2}", &format!("{mb:.2}")),
        result: format!("load-induced error after correction: RMS {ra:.3} µm, max {ma:.3} µm"),
        uncertainty: format!("U = {LOAD_MODEL_U_UM} µm (k = 2) on the load-induced error after correction: map and truth are deterministic FE solutions (the {:.2} µm probing noise of the measured points is excluded from this comparison and shown below), so U bounds the solvers' numerical error", 2.0 * cfg.noise_sigma * 1e3),
        tolerance_text: "max residual ≤ 10 % of the uncorrected max (coarse map mesh against the fine truth mesh)".into(),
        ..report::Verdict::judged(report::Judgement::new(ma, LOAD_MODEL_U_UM, 0.1 * mb, "µm", report::DecisionRule::Simple))
    });
    report.add("load", "Bed deformation under load", html);
    Ok(())
}

/// What `truepos simulate load` prints: the scenario's facts, the commands to run next and
/// what to compare with `truth.json`.
pub fn written_text(dir: &Path, mass_kg: f64, noise_um: f64, data: &LoadData) -> String {
    let mut out = format!(
        "load scenario: a {mass_kg} kg die on three pads on a granite bed (forces {:?} N), {} points measured with {noise_um} µm noise → {}\n",
        data.forces_n.map(|f| (f * 10.0).round() / 10.0),
        data.indicated.len(),
        dir.display()
    );
    for c in suggested_commands(dir) {
        out += &format!("next: {c}\n");
    }
    out + &format!("then compare corrected.csv with true_points_mm in {}\n", dir.join("truth.json").display())
}

/// The commands that correct a `load` data set written to `dir`: the influence map from the
/// bed, then the correction of the points.
pub fn suggested_commands(dir: &Path) -> [String; 2] {
    let f = |n: &str| dir.join(n).display().to_string();
    [
        format!("truepos load map --bed {} --output {}", f("bed.toml"), f("map.csv")),
        format!(
            "truepos load correct --map {} --load {} --bed {} --points {} --output {}",
            f("map.csv"),
            f("load.toml"),
            f("bed.toml"),
            f("points.csv"),
            f("corrected.csv")
        ),
    ]
}
