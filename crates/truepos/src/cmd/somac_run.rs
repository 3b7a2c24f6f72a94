//! `truepos somac run` and `truepos simulate somac`: the end-point control loop on the virtual
//! large gantry, its cell file, audit trail and report section.
//!
//! The cell file (`cell.toml`) describes the virtual cell (written by `truepos simulate somac`)
//! and the loop parameters (`[loop]`, every field optional). A real controller and trackers plug
//! in behind the same traits (`truepos_somac::device`).

use crate::output::print_json;
use crate::{Outcome, UsageError};
use anyhow::{Context, Result};
use serde_json::json;
use std::path::PathBuf;
use truepos_cell::scenarios::somac::{read_cell_file, run_virtual, write_scenario};
use truepos_io::InputError;

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Exit code 1 when a stop is not SUCCESS, the run halted, or an alarm other than an\nautomatically recovered beam break fired."
)]
pub struct RunArgs {
    /// The G-code program; measurement blocks carry the loop's keyword comment ([loop] keyword, default `(MSG,Measure SOMaC)`).
    #[arg(long)]
    pub program: PathBuf,
    /// The cell: virtual gantry, trackers, part targets, loop parameters.
    #[arg(long)]
    pub cell: PathBuf,
    /// Audit trail database (SQLite), created if missing; every run is appended to it (one run
    /// row, one row per stop, alarm and correction). Its path is printed at the end of the run.
    #[arg(long, default_value = "somac-audit.sqlite")]
    pub db: PathBuf,
    /// Measure and report only, never correct. The program is still oriented through the
    /// measured part targets (placement and thermal scale); add --no-orient for the machine's
    /// native accuracy (the figure `truepos simulate somac` prints as "native").
    #[arg(long)]
    pub no_correct: bool,
    /// Do not orient the program through the measured part targets (run it as written).
    #[arg(long)]
    pub no_orient: bool,
    /// The NC: `virtual` (the cell's virtual gantry) or `linuxcncrsh://HOST:PORT[?password=…]`
    /// (LinuxCNC moves the axes; the cell's virtual trackers observe its actual position through
    /// the cell's structural error model).
    #[arg(long, default_value = "virtual")]
    pub controller: String,
    /// Print one JSON object on stdout (human text goes to stderr).
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub common: super::SimCommon,
    /// Holes per row (two rows), 1 to 2000.
    #[arg(long, default_value_t = 150, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=2000))]
    pub holes_per_row: usize,
}

pub fn run(a: RunArgs) -> Result<Outcome> {
    let (cfg, targets, mut params) = read_cell_file(&a.cell)?;
    if a.no_correct {
        params.correct = false;
    }
    if a.no_orient {
        params.orient = false;
    }
    let text = std::fs::read_to_string(&a.program)
        .map_err(|e| InputError::in_file(&a.program, format!("cannot read: {e}")))?;
    let program = truepos_gcode::Program::parse(&text);
    program.check().map_err(|e| InputError::at(&a.program, e.line(), Some(e.column()), e.detail()))?;
    if !program.blocks().iter().any(|b| b.has_keyword(&params.keyword) && b.target_mm.is_some()) {
        return Err(InputError::in_file(
            &a.program,
            format!("no measurement block: no motion block has the keyword comment '{}'", params.keyword),
        )
        .into());
    }
    let mut audit =
        truepos_audit::SqliteAudit::open(&a.db, &a.program.display().to_string(), &truepos_audit::now_utc())
            .map_err(|e| match e {
                truepos_audit::AuditError::Sql(_) => {
                    anyhow::Error::from(e).context(format!("audit trail {}", a.db.display()))
                }
                other => InputError::in_file(&a.db, other.to_string()).into(),
            })?;
    let mut on_controller = None;
    let vr = if a.controller != "virtual" {
        run_on_controller(&a, &text, cfg, targets, &params, &mut audit).map(|(vr, extra)| {
            on_controller = Some(extra);
            vr
        })
    } else {
        audit.set_controller("virtual", "truepos virtual gantry cell")?;
        let pb = crate::output::spinner("somac: running the program on the virtual gantry with the trackers");
        let r = run_virtual(&text, cfg, targets, &params, &mut audit).map_err(anyhow::Error::from);
        pb.finish_and_clear();
        r
    };
    // The run row records its end and final status, whatever happened.
    let (status, message) = match &vr {
        Ok(v) if v.report.failed() => ("FAILURE", None),
        Ok(_) => ("SUCCESS", None),
        Err(e) => ("ERROR", Some(format!("{e:#}"))),
    };
    audit
        .finish(status, message.as_deref(), &truepos_audit::now_utc())
        .with_context(|| format!("audit trail {}", a.db.display()))?;
    let vr = vr.map_err(|e| match e.downcast::<truepos_somac::run::RunError>() {
        Ok(truepos_somac::run::RunError::Program { line, message }) => {
            InputError::at(&a.program, line, None, message).into()
        }
        Ok(truepos_somac::run::RunError::Params(m)) => UsageError(m).into(),
        Ok(other) => anyhow::Error::from(other),
        Err(e) => e,
    })?;
    let out = vr.to_json(&a.db);
    let mut out = out;
    if let Some(extra) = on_controller {
        for (k, v) in extra.as_object().into_iter().flatten() {
            out[k] = v.clone();
        }
    }
    if a.json {
        print_json(&out)?;
    } else {
        print!("{}", vr.text());
        for al in &vr.report.alarms {
            eprintln!("alarm line {}: {} — {} ({})", al.line, al.kind, al.message, al.action);
        }
        match (params.correct, params.orient) {
            (false, true) => eprintln!(
                "note: --no-correct: holes drilled through the orientation on the part targets, without the correction loop; add --no-orient for the program as written (the native error of `truepos simulate somac`)"
            ),
            (false, false) => eprintln!("note: --no-correct --no-orient: the program as written, the machine's native accuracy"),
            (true, false) => eprintln!("note: --no-orient: corrections without orienting the program on the part targets"),
            (true, true) => {}
        }
    }
    eprintln!("audit trail appended to {} (run with --db FILE to choose another)", a.db.display());
    Ok(if vr.report.failed() { Outcome::OutOfTolerance } else { Outcome::Done })
}

/// `somac run --controller linuxcncrsh://…`: LinuxCNC moves the axes, the virtual cell's
/// trackers observe its actual position (`truepos_cell::observed`). Returns the run as the
/// virtual one is reported, plus the controller and wall-clock times per stop.
fn run_on_controller(
    a: &RunArgs,
    text: &str,
    cfg: truepos_cell::gantry::CellConfig,
    targets: Vec<(String, truepos_math::Point3)>,
    params: &truepos_somac::Params,
    audit: &mut truepos_audit::SqliteAudit,
) -> Result<(truepos_cell::scenarios::somac::VirtualRun, serde_json::Value)> {
    use truepos_device::ProbingMachine;
    use truepos_somac::run::RunError;
    // Hook: further controllers (e.g. other NCs) are opened here.
    let address = truepos_linuxcnc::Address::parse(&a.controller)
        .map_err(|e| UsageError(format!("--controller: {e} (or `virtual`)")))?;
    let ctl = truepos_linuxcnc::LinuxCnc::open_address(&address, truepos_linuxcnc::Options::default())
        .map_err(|e| crate::DeviceError(e.to_string()))?;
    let info = ctl.info();
    audit.set_controller(&info.address, &info.version)?;
    match truepos_cell::observed::run_observed(text, cfg, targets, params, ctl, audit) {
        Ok(o) => {
            let extra = json!({
                "controller": { "address": info.address, "version": info.version },
                "stop_wall_s": o.stop_wall_s.iter().map(|(l, t)| json!({"line": l, "wall_s": t})).collect::<Vec<_>>(),
                "wall_s": o.wall_s,
                "controller_moves": o.moves,
            });
            let vr = truepos_cell::scenarios::somac::VirtualRun {
                report: o.report,
                true_errors: o.true_errors,
                diagonal_mm: o.diagonal_mm,
                duration_s: o.duration_s,
            };
            Ok((vr, extra))
        }
        Err(ab) => Err(match ab.error {
            RunError::Program { line, message } => InputError::at(&a.program, line, None, message).into(),
            RunError::Params(m) => UsageError(m).into(),
            other => crate::DeviceError(format!(
                "{other}; the run was aborted at line {} (no further motion){}; audit trail {}",
                ab.line,
                ab.stop_line.map(|l| format!(", stop at line {l} marked FAILURE")).unwrap_or_default(),
                a.db.display()
            ))
            .into(),
        }),
    }
}

pub fn simulate(a: SimArgs) -> Result<Outcome> {
    if a.holes_per_row == 0 {
        return Err(UsageError("--holes-per-row must be at least 1".into()).into());
    }
    let w = write_scenario(&a.common.out, a.common.seed, a.holes_per_row)?;
    eprint!("{}", w.text(&a.common.out));
    Ok(Outcome::Done)
}
