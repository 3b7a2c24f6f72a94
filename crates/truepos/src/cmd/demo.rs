//! `truepos demo`: every capability end to end on the virtual cell, written as a report
//! (`index.html` with tables and SVG plots) that a person reads.

use crate::Outcome;
use std::path::PathBuf;
use truepos_report::Report;

#[derive(clap::Args, Debug)]
#[command(
    long_about = "Run every capability end to end on the virtual cell (fitting on the NIST reference data) and compare each result with the simulator's truth.\n\nWrites into --out:\n  index.html    the report: header (version, UTC time, seed, machines, environment, command line), overall verdict, one summary row per capability, one section per capability with tables and plots (self-contained, no network), including the real interfaces: the I++ DME section starts the virtual CMM's I++ DME server on 127.0.0.1 (an ephemeral port) while it runs, and the controller section probes through the same trait as LinuxCNC (LinuxCNC itself is not started)\n  summary.json  the same as data: header, verdicts, every table\n  load/         the influence map of the bed-load section (map.csv)\n\nProgress: one line per capability with its time on stderr. Reruns are byte-identical except the generation time; set SOURCE_DATE_EPOCH (Unix seconds) to fix it too."
)]
pub struct Args {
    /// Report directory (data sets of each capability go in subdirectories).
    #[arg(long, default_value = "demo")]
    pub out: PathBuf,
}

/// The report directory, created if missing, checked writable before any work: a bad `--out`
/// (a file, a read-only place) fails at once, not after the sections have run.
fn check_out_dir(dir: &std::path::Path) -> Result<(), crate::UsageError> {
    let bad = |why: String| crate::UsageError(format!("--out {}: {why}", dir.display()));
    if dir.exists() && !dir.is_dir() {
        return Err(bad("exists and is not a directory".into()));
    }
    std::fs::create_dir_all(dir).map_err(|e| bad(format!("cannot create the directory: {e}")))?;
    tempfile_probe(dir).map_err(|e| bad(format!("cannot write into the directory: {e}")))
}

/// Create and remove a file in `dir` (the test that it is writable).
fn tempfile_probe(dir: &std::path::Path) -> std::io::Result<()> {
    let p = dir.join(format!(".truepos-write-test-{}", std::process::id()));
    std::fs::write(&p, b"")?;
    std::fs::remove_file(&p)
}

pub fn run(a: Args) -> anyhow::Result<Outcome> {
    check_out_dir(&a.out)?;
    let mut report = Report::new(&a.out);
    // Generation time: SOURCE_DATE_EPOCH (reproducible builds convention) when set, else now.
    let now = match std::env::var("SOURCE_DATE_EPOCH") {
        Ok(v) => v.trim().parse::<i64>().map_err(|_| {
            crate::UsageError(format!("SOURCE_DATE_EPOCH must be Unix seconds (an integer), got {v:?}"))
        })?,
        Err(_) => std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs() as i64)
            .unwrap_or(0),
    };
    report.header = truepos_report::Header {
        version: format!("{} (build {})", env!("CARGO_PKG_VERSION"), env!("TRUEPOS_BUILD_COMMIT")),
        generated_unix_s: now,
        command_line: std::env::args().collect::<Vec<_>>().join(" "),
        seed: truepos_cell::scenarios::part::SEED,
        machine: "virtual bridge CMM (bed load, geometric map), virtual scanning CMM, virtual VMC with swivel head, virtual 12 m × 4 m × 2 m gantry with two laser trackers, latency test cell".into(),
        environment: "air 20 °C, 101 325 Pa, 50 % RH, 450 ppm CO₂ (reference conditions); the gantry's part warms during its run and the autoscale part is 4 °C above 20 °C".into(),
    };
    let sections = truepos_cell::demo::sections();
    let n = sections.len();
    let pb = crate::output::progress(n as u64, "demo");
    let t_all = std::time::Instant::now();
    for (i, (name, f)) in sections.into_iter().enumerate() {
        pb.set_message(name.to_string());
        let t0 = std::time::Instant::now();
        f(&mut report).map_err(|e| anyhow::Error::from(e).context(format!("demo section '{name}'")))?;
        // One line per capability (above the bar on a terminal; plain lines otherwise).
        pb.suspend(|| eprintln!("[{}/{n}] {name:<18} {:6.2} s", i + 1, t0.elapsed().as_secs_f64()));
        pb.inc(1);
    }
    pb.finish_and_clear();
    eprintln!(
        "all {n} sections in {:.1} s; overall: {}",
        t_all.elapsed().as_secs_f64(),
        match report.overall() {
            truepos_report::Overall::Pass => "PASS".to_string(),
            truepos_report::Overall::Fail => "FAIL".to_string(),
            truepos_report::Overall::Incomplete => {
                let open: Vec<String> = report
                    .verdicts()
                    .iter()
                    .filter(|v| !matches!(v.verdict, truepos_report::Outcome::Pass))
                    .map(|v| format!("{} {}", v.capability, v.verdict.word()))
                    .collect();
                format!("INCOMPLETE ({})", open.join(", "))
            }
        }
    );
    let path = report.write()?;
    eprintln!("report written to {}", path.display());
    // Exit 0 only when every capability passed (contract: summary.json verdicts).
    Ok(if report.overall_pass() { Outcome::Done } else { Outcome::OutOfTolerance })
}
