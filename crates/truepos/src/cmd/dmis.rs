//! `truepos dmis run`: a DMIS part program on a CMM through I++ DME or on the virtual CMM
//! (contract "DMIS part programs"). Thin: the work is in `truepos_dmis` (read, check, run,
//! results) and `truepos_plant::cmm::serve_loopback` (the virtual CMM).

use crate::{Outcome, UsageError};
use anyhow::Result;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use truepos_dmis::exec::{self, DryRun, RunOptions};

#[derive(clap::Args, Debug)]
#[command(
    after_help = "A real CMM through I++ DME: truepos dmis run part.dms --controller ippdme://HOST:1294 --sensor PROBE6=Probe1"
)]
pub struct Args {
    #[command(subcommand)]
    pub command: DmisCommand,
}

#[derive(clap::Subcommand, Debug)]
pub enum DmisCommand {
    /// Run a DMIS (ISO 22093) part program: the prismatic subset of docs/dmis.md.
    ///
    /// The whole program is read and checked before the first motion: anything outside the subset
    /// or inconsistent is exit 2 naming file, line and column. Progress (one line per MEAS) on
    /// stderr. The results file is a DMIS output file (FA(label)=FEAT/… with the actual values,
    /// TA(label)=TOL/…,value,INTOL|OUTOL). With --qif the same results as a QIF 3 results document
    /// (features with uncertainties and point counts, tolerances as characteristics with their
    /// datums; docs/dmis.md).
    #[command(
        after_help = "A real CMM through I++ DME:\n  truepos dmis run part.dms --controller ippdme://HOST:1294 --sensor PROBE6=Probe1\n\nWith --machine-model FILE every actual feature's values and every tolerance's value get a\ntask-specific uncertainty: the program (its PTMEAS points and directions, datums, constructions)\nrun again on ≥ 200 machines drawn from the model, each touching the perfect features where this\nrun found them. The verdict stays DMIS's (INTOL/OUTOL on the value); U is reported beside it.\n  truepos dmis run part.dms --part part.toml --machine-model cmm.toml --json\n\nExit codes: 0 done, 1 a tolerance OUTOL, 2 bad program or option (nothing moved), 3 machine failure (the program line named, the machine retracted)."
    )]
    Run(RunArgs),
}

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// The DMIS program.
    pub program: PathBuf,
    /// `virtual` (the built-in virtual CMM with --part) or `ippdme://HOST:PORT`.
    #[arg(long, default_value = "virtual")]
    pub controller: String,
    /// Part file of the virtual CMM (as `truepos ippdme serve --part`).
    #[arg(long)]
    pub part: Option<PathBuf>,
    /// Machine file of the virtual CMM (as `truepos ippdme serve --machine`).
    #[arg(long)]
    pub machine: Option<PathBuf>,
    /// Map a DMIS sensor to a tool of the CMM: `--sensor PROBE6=Probe1` (repeatable). Default:
    /// the tool of the same name.
    #[arg(long = "sensor", value_name = "LABEL=TOOL")]
    pub sensors: Vec<String>,
    /// The results file (default: the file the program's DEVICE/OPEN names, beside the program,
    /// else PROGRAM_output.dms).
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Also write the results as a QIF 3 results document (ISO 23952): every actual feature
    /// (values, standard uncertainties, number of points) and every tolerance as a
    /// characteristic (tolerance, nominal, actual value, PASS/FAIL) referring to its features
    /// and datums; mm and degrees. Written atomically with the results file, never on error.
    #[arg(long, value_name = "OUT.qif")]
    pub qif: Option<PathBuf>,
    /// List the motions without a machine (every probing touches its nominal point); no file.
    #[arg(long)]
    pub dry_run: bool,
    /// Audit trail: a SQLite file (created if missing) or postgresql://USER@HOST:PORT/DB; the run
    /// is recorded (note `dmis run`) with the controller, every actual feature's values and every
    /// tolerance's value, limits and verdict (with U), and how it ended. Not with --dry-run.
    #[arg(long, default_value = "somac-audit.sqlite")]
    pub db: String,
    #[command(flatten)]
    pub model: super::probe::ModelArgs,
    /// Print the results as one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `truepos dmis run`: read and check the program, run it (or list its motions), then the
/// uncertainties, the audit trail, the results files and the report, in that order.
pub fn run(args: Args) -> Result<Outcome> {
    let DmisCommand::Run(a) = args.command;
    let opts = RunOptions { sensors: sensors(&a.sensors)? };
    let plan = truepos_dmis::task::load(&a.program)?;
    // The machine model is read and checked before anything moves.
    let model = if a.dry_run { None } else { a.model.read()? };
    let mut progress = |l: &str| eprintln!("dmis: {l}");
    if a.dry_run && a.qif.is_some() {
        return Err(UsageError("--qif writes the results of a run: not with --dry-run".into()).into());
    }
    if a.dry_run {
        return dry_run(&plan, &opts, a.json, &mut progress);
    }
    // The virtual CMM's part and machine files are inputs too: no output (--output, --qif, a
    // DEVICE/STOR file) may replace them. They are read when the CMM starts, after these checks.
    for p in [&a.part, &a.machine].into_iter().flatten() {
        truepos_io::atomic::note_input(p);
    }
    let out = results_path(&a, &plan)?;
    // The virtual CMM lives as long as the run.
    let (url, _virtual) = controller(&a)?;
    let db = super::audit::parse_db(&a.db)?;
    // SIGINT/SIGTERM: no motion after the current one, the run closed as ABORTED, exit 128 + n.
    truepos_io::atomic::defer_interrupts();
    let mut audit = truepos_audit::Audit::open_noted(
        &db,
        &a.program.display().to_string(),
        Some("dmis run"),
        &truepos_audit::now_utc(),
    )?;
    let r = run_program(&plan, &url, &opts, &mut progress);
    if let Some(sig) = truepos_io::atomic::interrupted() {
        abort(&mut audit, &db, sig);
    }
    // Task-specific uncertainty (the same program on machines drawn from the model), then the
    // results with their U into the audit trail.
    let done = r.and_then(|r| {
        let m = Measured::new(r, model.as_ref(), &plan, &opts, a.model.monte_carlo())?;
        record(&mut audit, &m.r, &m.u)?;
        Ok(m)
    });
    close_audit(&mut audit, &done)?;
    let m = done?;
    write_results(&a, &plan, &m, &out)?;
    eprintln!("dmis: audit trail appended to {} (run {})", db.display(), audit.run_id());
    if a.json {
        print_json_results(&plan, &m, &out)?;
    } else {
        print_summary(&m, &out);
    }
    Ok(if m.r.any_out_of_tolerance() { Outcome::OutOfTolerance } else { Outcome::Done })
}

/// The `--sensor LABEL=TOOL` mappings, labels upper-cased (a malformed one is bad usage).
fn sensors(args: &[String]) -> Result<HashMap<String, String>> {
    let mut sensors = HashMap::new();
    for s in args {
        let Some((l, t)) = s.split_once('=').filter(|(l, t)| !l.trim().is_empty() && !t.trim().is_empty())
        else {
            return Err(UsageError(format!("--sensor {s:?}: expected LABEL=TOOL, e.g. PROBE6=Probe1")).into());
        };
        sensors.insert(l.trim().to_ascii_uppercase(), t.trim().to_string());
    }
    Ok(sensors)
}

/// `--dry-run`: the program's motions without a machine (every probing touches its nominal
/// point), as lines or in the JSON; no file.
fn dry_run(
    plan: &truepos_dmis::model::Plan,
    opts: &RunOptions,
    json: bool,
    progress: &mut dyn FnMut(&str),
) -> Result<Outcome> {
    let mut m = DryRun::new(plan, opts);
    let r = exec::run(plan, &mut m, opts, progress)?;
    if json {
        let mut j = truepos_dmis::report::json(&plan.file, &r, None);
        j["motions"] = serde_json::json!(r.motions);
        crate::output::print_json(&j)?;
    } else {
        for m in &r.motions {
            println!("{m}");
        }
    }
    Ok(Outcome::Done)
}

/// The results file, checked writable before anything moves; `--qif` is checked too and must
/// be another file.
fn results_path(a: &RunArgs, plan: &truepos_dmis::model::Plan) -> Result<PathBuf> {
    let out = truepos_dmis::task::output_path(plan, &a.program, a.output.as_deref());
    truepos_io::atomic::check_output_path(&out)?;
    if let Some(q) = &a.qif {
        truepos_io::atomic::check_output_path(q)?;
        if q == &out {
            return Err(UsageError(format!(
                "--qif {}: the same file as the results file; give the QIF document its own name",
                q.display()
            ))
            .into());
        }
    }
    Ok(out)
}

/// The I++ DME address to run on, and the virtual CMM serving it with `--controller virtual`
/// (it serves as long as the caller keeps it).
fn controller(a: &RunArgs) -> Result<(String, Option<truepos_plant::cmm::LoopbackCmm>)> {
    if a.controller == "virtual" {
        let cmm = truepos_plant::cmm::serve_loopback(a.part.as_deref(), a.machine.as_deref())?;
        Ok((cmm.url.clone(), Some(cmm)))
    } else if a.controller.starts_with("ippdme://") {
        if a.part.is_some() || a.machine.is_some() {
            return Err(UsageError(
                "--part and --machine describe the virtual CMM: only with --controller virtual".into(),
            )
            .into());
        }
        Ok((a.controller.clone(), None))
    } else {
        Err(UsageError(format!(
            "--controller `{}`: expected `virtual` or `ippdme://HOST:PORT`",
            a.controller
        ))
        .into())
    }
}

/// After SIGINT/SIGTERM `sig`: close the run as ABORTED, say so, and exit 128 + n (no results
/// file).
fn abort(audit: &mut truepos_audit::Audit, db: &truepos_audit::Db, sig: i32) -> ! {
    let name = truepos_io::atomic::signal_name(sig);
    let at = truepos_audit::now_utc();
    let _ = audit.finish("ABORTED", Some(&format!("aborted: interrupted by {name} at {at}")), &at);
    eprintln!(
        "dmis: aborted by {name}: no results file; the run is closed as ABORTED in {} (run {})",
        db.display(),
        audit.run_id()
    );
    truepos_io::atomic::exit_interrupted(sig)
}

/// A finished run with its uncertainties.
struct Measured {
    /// What the run measured and evaluated.
    r: exec::RunResult,
    /// The task-specific uncertainty and the simulation behind it (with a machine model).
    task: Option<truepos_cell::uncertainty::DmisUncertainty>,
    /// The standard uncertainties reported: the task-specific ones, else the fits' scatter.
    u: truepos_dmis::uncertainty::Uncertainty,
}

impl Measured {
    /// The run `r` with the task-specific uncertainty of `model` (the same program on machines
    /// drawn from it), or without a model the fits' scatter and a warning.
    fn new(
        r: exec::RunResult,
        model: Option<&truepos_vcmm::MachineModel>,
        plan: &truepos_dmis::model::Plan,
        opts: &RunOptions,
        mc: truepos_vcmm::MonteCarlo,
    ) -> Result<Measured> {
        let task = match model {
            Some(m) => Some(truepos_cell::uncertainty::dmis_uncertainty(m, plan, opts, &r, mc)?),
            None => {
                eprintln!("{}", super::probe::NO_MODEL_WARNING);
                None
            }
        };
        let u = match &task {
            Some(t) => t.uncertainty.clone(),
            None => truepos_dmis::uncertainty::Uncertainty::fit_residuals(&r),
        };
        Ok(Measured { r, task, u })
    }
}

/// Close the audit trail's run: SUCCESS, FAILURE (a tolerance OUTOL) or ERROR with the error.
fn close_audit(audit: &mut truepos_audit::Audit, done: &Result<Measured>) -> Result<()> {
    let (status, message) = match done {
        Ok(m) if m.r.any_out_of_tolerance() => ("FAILURE", Some("a tolerance is out (OUTOL)".to_string())),
        Ok(_) => ("SUCCESS", None),
        Err(e) => ("ERROR", Some(format!("{e:#}"))),
    };
    audit.finish(status, message.as_deref(), &truepos_audit::now_utc())?;
    Ok(())
}

/// Write the results file `out` and, with `--qif`, the QIF results document. Both are made
/// before either is written: an error leaves no file.
fn write_results(a: &RunArgs, plan: &truepos_dmis::model::Plan, m: &Measured, out: &Path) -> Result<()> {
    let text = m.r.output.join("\n") + "\n";
    let qif = match &a.qif {
        Some(q) => {
            let doc = truepos_dmis::report::qif(
                &plan.file,
                &m.r,
                &m.u,
                concat!("truepos ", env!("CARGO_PKG_VERSION")),
            );
            let xml = truepos_qif::write_program_results(&doc)
                .map_err(|e| anyhow::anyhow!("{}: cannot write the QIF results: {e}", q.display()))?;
            Some((q, xml))
        }
        None => None,
    };
    truepos_io::atomic::write_atomic(out, text.as_bytes())?;
    if let Some((q, xml)) = &qif {
        truepos_io::atomic::write_atomic(q, xml.as_bytes())?;
        eprintln!("dmis: QIF results in {}", q.display());
    }
    Ok(())
}

/// `--json`: the results as one JSON object on stdout, with the expanded uncertainties and how
/// they were found.
fn print_json_results(plan: &truepos_dmis::model::Plan, m: &Measured, out: &Path) -> Result<()> {
    let k = truepos_math::stats::COVERAGE_FACTOR;
    let mut j = truepos_dmis::report::json(&plan.file, &m.r, Some(&out.display().to_string()));
    m.u.add_to_json(&m.r, &mut j, k);
    j["coverage_factor"] = serde_json::json!(k);
    match &m.task {
        Some(t) => {
            j["uncertainty_method"] = serde_json::json!("task-specific");
            j["monte_carlo_runs"] = serde_json::json!(t.spread.runs);
            j["uncertainty_basis"] = serde_json::json!(t.spread.basis);
            j["monte_carlo_s"] = serde_json::json!(t.spread.elapsed_s);
        }
        None => {
            j["uncertainty_method"] = serde_json::json!("fit-residuals");
            j["monte_carlo_runs"] = serde_json::json!(0);
            j["uncertainty_basis"] = serde_json::json!(
                "scatter of each fit's residuals only (machine errors not included; none for directions and tolerances)"
            );
        }
    }
    crate::output::print_json(&j)
}

/// Without `--json`: every tolerance with its U, how the uncertainty was found, and the
/// summary, on stderr.
fn print_summary(m: &Measured, out: &Path) {
    let k = truepos_math::stats::COVERAGE_FACTOR;
    for (t, ut) in m.r.tolerances.iter().zip(&m.u.tolerances) {
        let beside = match ut {
            Some(v) if t.angular => format!(" (U = {:.4}°, k = {k})", (k * v).to_degrees()),
            Some(v) => format!(" (U = {:.4} mm, k = {k})", k * v),
            None => " (U not known without --machine-model)".to_string(),
        };
        eprintln!(
            "dmis: {}{beside}",
            truepos_dmis::report::tol_line(
                t,
                truepos_dmis::ast::LengthUnit::Mm,
                truepos_dmis::ast::AngleUnit::AngDec
            )
        );
    }
    if let Some(t) = &m.task {
        eprintln!(
            "dmis: uncertainty: task-specific, {} machine realisations in {:.2} s ({})",
            t.spread.runs, t.spread.elapsed_s, t.spread.basis
        );
    }
    eprintln!("dmis: {} points, {:.2} s; results in {}", m.r.n_points, m.r.elapsed_s, out.display());
}

/// Connect and run the program; no motion after SIGINT/SIGTERM.
fn run_program(
    plan: &truepos_dmis::model::Plan,
    url: &str,
    opts: &RunOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<exec::RunResult> {
    let mut client = truepos_ippdme::client::connect(url)?;
    let stop = || {
        truepos_io::atomic::interrupted()
            .map(|s| format!("interrupted by {}", truepos_io::atomic::signal_name(s)))
    };
    let mut machine = truepos_device::Stoppable::new(&mut client, &stop);
    Ok(exec::run(plan, &mut machine, opts, progress)?)
}

/// Record the controller and every reported quantity with its expanded uncertainty.
fn record(
    audit: &mut truepos_audit::Audit,
    r: &exec::RunResult,
    u: &truepos_dmis::uncertainty::Uncertainty,
) -> Result<()> {
    audit.set_controller(&r.machine.address, &r.machine.version)?;
    for q in truepos_dmis::report::quantities(r, u) {
        audit.record_result(&truepos_audit::ResultRecord {
            line: None,
            kind: q.kind.into(),
            label: q.label,
            feature: Some(q.feature),
            quantity: q.quantity,
            value: q.value,
            unit: q.unit.into(),
            expanded_uncertainty: q.expanded_uncertainty,
            limits: q.limits,
            verdict: q.verdict.map(str::to_string),
        });
    }
    audit.flush()?;
    Ok(())
}
