//! `truepos demo`: every capability end to end on the virtual cell, written as a report
//! (`index.html` with tables and SVG plots) that a person reads.

use crate::Outcome;
use std::path::PathBuf;
use truepos_cell::demo::SectionFn;
use truepos_cell::report::Report;

#[derive(clap::Args, Debug)]
#[command(after_help = "Example:\n  truepos demo --out demo   # then open demo/index.html")]
pub struct Args {
    /// Report directory (data sets of each capability go in subdirectories).
    #[arg(long, default_value = "demo")]
    pub out: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<Outcome> {
    let mut report = Report::new(&a.out);
    let mut sections: Vec<(&str, SectionFn)> = vec![("fitting", super::fit::demo_section)];
    sections.extend(truepos_cell::demo::sections());
    let pb = crate::output::progress(sections.len() as u64, "demo");
    for (name, f) in sections {
        pb.set_message(name.to_string());
        let t0 = std::time::Instant::now();
        f(&mut report).map_err(|e| e.context(format!("demo section '{name}'")))?;
        tracing::info!("demo section {name}: {:.2} s", t0.elapsed().as_secs_f64());
        pb.inc(1);
    }
    pb.finish_and_clear();
    let path = report.write()?;
    eprintln!("report written to {}", path.display());
    Ok(Outcome::Done)
}
