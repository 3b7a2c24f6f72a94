//! `truepos somac run` and `truepos simulate somac`: the end-point control loop on the virtual
//! large gantry, its cell file, audit trail and report section.
//!
//! The cell file (`cell.toml`) describes the virtual cell (written by `truepos simulate somac`)
//! and the loop parameters (`[loop]`, every field optional). A real controller and trackers plug
//! in behind the same traits (`truepos_somac::device`).

// Argument docs here are clap's help text, where `[name]` is a TOML table (or an optional CSV
// column), not an intra-doc link: escaping it would change the help the contract names.
#![allow(rustdoc::broken_intra_doc_links)]

use crate::output::print_json;
use crate::{ClassExt, Outcome, UsageError};
use anyhow::Result;
use serde_json::json;
use std::path::PathBuf;
use truepos_cell::scenarios::somac::{read_cell_file, run_virtual, write_scenario};
use truepos_io::InputError;

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Verdict (JSON `verdict`, `reasons`; the audit run's status says the same):\n  pass   every stop SUCCESS and no alarm: exit 0, status SUCCESS\n  alarm  every stop SUCCESS but an alarm fired, recovered or not (an inclination or\n         temperature alarm means the trackers or the part moved: a person must review\n         the run before the part is accepted, so the contract's exit code is 1): exit 1,\n         status ALARM\n  fail   a stop is not SUCCESS or the run halted: exit 1, status FAILURE\nAn automatically recovered beam break is listed in `reasons` and alone does not change\nthe verdict."
)]
pub struct RunArgs {
    /// The G-code program; measurement blocks carry the loop's keyword comment ([loop] keyword, default `(MSG,Measure SOMaC)`).
    #[arg(long)]
    pub program: PathBuf,
    /// The cell: virtual gantry, trackers, part targets, loop parameters.
    #[arg(long)]
    pub cell: PathBuf,
    /// Audit trail: a SQLite file (created if missing) or postgresql://USER@HOST:PORT/DB shared
    /// by a fleet (password from PGPASSWORD or ~/.pgpass); every run is appended to it (its
    /// start, controller and end, one record per block, measurement, stop, alarm and correction,
    /// hash-chained). It is printed at the end of the run; `truepos audit` reads it.
    #[arg(long, default_value = "somac-audit.sqlite")]
    pub db: String,
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
    let text = truepos_io::limits::read_string(&a.program, "G-code")?;
    let program = truepos_gcode::Program::parse(&text);
    program.check().map_err(|e| InputError::at(&a.program, e.line(), Some(e.column()), e.detail()))?;
    if !program.blocks().iter().any(|b| b.has_keyword(&params.keyword) && b.target_mm.is_some()) {
        return Err(InputError::in_file(
            &a.program,
            format!("no measurement block: no motion block has the keyword comment '{}'", params.keyword),
        )
        .into());
    }
    let db = super::audit::parse_db(&a.db)?;
    let mut audit =
        truepos_audit::Audit::open(&db, &a.program.display().to_string(), &truepos_audit::now_utc())?;
    // SIGINT/SIGTERM: the loop stops at its next event and the run is closed as ABORTED.
    truepos_io::atomic::defer_interrupts();
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
    if let Some(sig) = truepos_io::atomic::interrupted() {
        let name = truepos_io::atomic::signal_name(sig);
        let at = truepos_audit::now_utc();
        let _ = audit.finish("ABORTED", Some(&format!("aborted: interrupted by {name} at {at}")), &at);
        eprintln!(
            "aborted by {name}: the run is closed as ABORTED in {} (run {})",
            db.display(),
            audit.run_id()
        );
        truepos_io::atomic::exit_interrupted(sig);
    }
    // The run row records its end and final status, whatever happened.
    let (status, message) = match &vr {
        Ok(v) => {
            let rv = v.report.verdict();
            (rv.verdict.audit_status(), Some(format!("{}: {}", rv.verdict.as_str(), rv.reasons.join("; "))))
        }
        Err(e) => ("ERROR", Some(format!("{e:#}"))),
    };
    audit.finish(status, message.as_deref(), &truepos_audit::now_utc())?;
    let vr = vr.map_err(|e| match e.downcast::<truepos_somac::run::RunError>() {
        Ok(truepos_somac::run::RunError::Program { line, message }) => {
            InputError::at(&a.program, line, None, message).into()
        }
        Ok(other) => anyhow::Error::from(other),
        Err(e) => e,
    })?;
    let out = vr.to_json(std::path::Path::new(&db.display()));
    let mut out = out;
    let rv = vr.report.verdict();
    out["verdict"] = json!(rv.verdict.as_str());
    out["reasons"] = json!(rv.reasons);
    out["status"] = json!(rv.verdict.audit_status());
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
    eprintln!("verdict: {} — {}", rv.verdict.as_str(), rv.reasons.join("; "));
    eprintln!(
        "audit trail appended to {} (run {}; --db FILE|postgresql://… to choose another)",
        db.display(),
        audit.run_id()
    );
    Ok(if vr.report.failed() { Outcome::OutOfTolerance } else { Outcome::Done })
}

/// `somac run --controller linuxcncrsh://…`: LinuxCNC moves the axes, the virtual cell's
/// trackers observe its actual position (`truepos_cell::observed`). Returns the run as the
/// virtual one is reported, plus the controller and wall-clock times per stop.
fn run_on_controller(
    a: &RunArgs,
    text: &str,
    cfg: truepos_plant::gantry::CellConfig,
    targets: Vec<(String, truepos_math::Point3)>,
    params: &truepos_somac::Params,
    audit: &mut truepos_audit::Audit,
) -> Result<(truepos_cell::scenarios::somac::VirtualRun, serde_json::Value)> {
    use truepos_device::ProbingMachine;
    use truepos_somac::run::RunError;
    // Hook: further controllers (e.g. other NCs) are opened here.
    let address = truepos_linuxcnc::Address::parse(&a.controller).usage_in("--controller (or `virtual`)")?;
    let ctl = truepos_linuxcnc::LinuxCnc::open_address(&address, truepos_linuxcnc::Options::default())?;
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
            other => crate::Classed::new(
                truepos_math::exit::ExitClass::Device,
                Some(format!(
                    "the run was aborted at line {} (no further motion){}; audit trail {}",
                    ab.line,
                    ab.stop_line.map(|l| format!(", stop at line {l} marked FAILURE")).unwrap_or_default(),
                    a.db
                )),
                other,
            )
            .into(),
        }),
    }
}

pub fn simulate(a: SimArgs) -> Result<Outcome> {
    if a.holes_per_row == 0 {
        return Err(UsageError("--holes-per-row must be at least 1".into()).into());
    }
    let w = write_scenario(a.common.out_dir()?, a.common.seed, a.holes_per_row)?;
    eprint!("{}", w.text(&a.common.out));
    Ok(Outcome::Done)
}
