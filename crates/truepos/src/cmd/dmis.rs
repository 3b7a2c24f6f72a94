//! `truepos dmis run`: a DMIS part program on a CMM through I++ DME or on the virtual CMM
//! (contract "DMIS part programs"). Thin: the work is in `truepos_dmis` (read, check, run,
//! results) and `truepos_cell::cmm::serve_loopback` (the virtual CMM).

use crate::{Outcome, UsageError};
use anyhow::Result;
use std::collections::HashMap;
use std::path::PathBuf;
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
    /// TA(label)=TOL/…,value,INTOL|OUTOL).
    #[command(
        after_help = "A real CMM through I++ DME:\n  truepos dmis run part.dms --controller ippdme://HOST:1294 --sensor PROBE6=Probe1\n\nExit codes: 0 done, 1 a tolerance OUTOL, 2 bad program or option (nothing moved), 3 machine failure (the program line named, the machine retracted)."
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
    /// List the motions without a machine (every probing touches its nominal point); no file.
    #[arg(long)]
    pub dry_run: bool,
    /// Print the results as one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<Outcome> {
    let DmisCommand::Run(a) = args.command;
    let mut sensors = HashMap::new();
    for s in &a.sensors {
        let Some((l, t)) = s.split_once('=').filter(|(l, t)| !l.trim().is_empty() && !t.trim().is_empty())
        else {
            return Err(UsageError(format!("--sensor {s:?}: expected LABEL=TOOL, e.g. PROBE6=Probe1")).into());
        };
        sensors.insert(l.trim().to_ascii_uppercase(), t.trim().to_string());
    }
    let opts = RunOptions { sensors };
    let plan = truepos_dmis::task::load(&a.program)?;
    let mut progress = |l: &str| eprintln!("dmis: {l}");
    if a.dry_run {
        let mut m = DryRun::new(&plan, &opts);
        let r = exec::run(&plan, &mut m, &opts, &mut progress)?;
        if a.json {
            let mut j = truepos_dmis::report::json(&plan.file, &r, None);
            j["motions"] = serde_json::json!(r.motions);
            crate::output::print_json(&j)?;
        } else {
            for m in &r.motions {
                println!("{m}");
            }
        }
        return Ok(Outcome::Done);
    }
    let out = truepos_dmis::task::output_path(&plan, &a.program, a.output.as_deref());
    truepos_io::atomic::check_output_path(&out)?;
    // The virtual CMM lives as long as the run.
    let mut _virtual = None;
    let url = if a.controller == "virtual" {
        let cmm = truepos_cell::cmm::serve_loopback(a.part.as_deref(), a.machine.as_deref())?;
        let url = cmm.url.clone();
        _virtual = Some(cmm);
        url
    } else if a.controller.starts_with("ippdme://") {
        if a.part.is_some() || a.machine.is_some() {
            return Err(UsageError(
                "--part and --machine describe the virtual CMM: only with --controller virtual".into(),
            )
            .into());
        }
        a.controller.clone()
    } else {
        return Err(UsageError(format!(
            "--controller `{}`: expected `virtual` or `ippdme://HOST:PORT`",
            a.controller
        ))
        .into());
    };
    let mut client = truepos_ippdme::client::connect(&url)?;
    let r = exec::run(&plan, &mut client, &opts, &mut progress)?;
    let text = r.output.join("\n") + "\n";
    truepos_io::atomic::write_atomic(&out, text.as_bytes())?;
    drop(client);
    if a.json {
        crate::output::print_json(&truepos_dmis::report::json(
            &plan.file,
            &r,
            Some(&out.display().to_string()),
        ))?;
    } else {
        for t in &r.tolerances {
            eprintln!(
                "dmis: {}",
                truepos_dmis::report::tol_line(
                    t,
                    truepos_dmis::ast::LengthUnit::Mm,
                    truepos_dmis::ast::AngleUnit::AngDec
                )
            );
        }
        eprintln!("dmis: {} points, {:.2} s; results in {}", r.n_points, r.elapsed_s, out.display());
    }
    Ok(if r.any_out_of_tolerance() { Outcome::OutOfTolerance } else { Outcome::Done })
}
