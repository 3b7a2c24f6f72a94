//! `truepos ippdme serve`: the virtual CMM behind an I++ DME server (contract "CMM protocol").
//! Thin: the work is in `truepos_plant::cmm` and `truepos_ippdme::server`.

use crate::{ClassExt, Outcome};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: IppCommand,
}

#[derive(clap::Subcommand, Debug)]
pub enum IppCommand {
    /// Serve the virtual CMM over I++ DME 1.4.3 (TCP, one client at a time) until SIGINT/SIGTERM.
    ///
    /// The part file (TOML, machine mm) is the union of `[[sphere]] center_mm, diameter_mm`,
    /// `[[plane]] point_mm, normal` (half-space below the normal) and `[[cylinder]] point_mm,
    /// axis, diameter_mm, side = "outside"` (pins), minus `side = "inside"` cylinders (bores).
    /// Bounded solids: `[[block]] min_mm, max_mm`, `[[prism]] vertices_mm, height_mm` (a convex
    /// polygon extruded), `ends_mm = [a, b]` on a cylinder (finite pin; bore with its floor at a).
    /// Without `--part` every probe touches the ideal plane through its nominal point. The
    /// machine file's `[ippdme] volume_min_mm, volume_max_mm` (default ±1000) and `[[ippdme.tool]]
    /// name, tip_diameter_mm` add to the tools `RefTool`, `NoTool`, `Probe1` (3 mm ball). Moves are
    /// instant. `--log` appends every line received (`<`) and sent (`>`) with its UTC time.
    #[command(
        after_help = "Exit codes: 0 after SIGINT/SIGTERM, 2 bad option or part/machine file, 3 port in use."
    )]
    Serve(ServeArgs),
}

#[derive(clap::Args, Debug)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    pub bind: String,
    /// TCP port (I++ DME's is 1294; 0 picks a free one).
    #[arg(long, default_value_t = 1294)]
    pub port: u16,
    /// Part file (TOML): the material the probe touches.
    #[arg(long)]
    pub part: Option<PathBuf>,
    /// Machine file (TOML) with an `[ippdme]` section: volume and extra tools.
    #[arg(long)]
    pub machine: Option<PathBuf>,
    /// Append the session log to this file. The first failed write (full disk, file-size
    /// limit) is reported on stderr; logging then stops and the server keeps serving.
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Drop a client that does not take each 64 KiB of its answers within this many seconds
    /// (a client that stops reading cannot hold the only connection). Reading has no timeout:
    /// an idle client keeps its session.
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    pub write_timeout_s: f64,
}

pub fn run(args: Args) -> anyhow::Result<Outcome> {
    let IppCommand::Serve(a) = args.command;
    use truepos_plant::cmm::{bind_virtual, ServeOptions};
    if let Some(log) = &a.log {
        // The log is appended to for the server's life: only a regular file (or a new one), never
        // a device (a full one would lose every line silently), a FIFO, a symlink, or one of
        // the server's own input files (the log would corrupt the part or machine file).
        for input in a.part.iter().chain(&a.machine) {
            truepos_io::atomic::note_input(input);
        }
        truepos_io::atomic::check_output_path(log).map_err(|e| crate::UsageError(format!("--log: {e}")))?;
    }
    if !(a.write_timeout_s.is_finite() && (0.001..=86_400.0).contains(&a.write_timeout_s)) {
        return Err(crate::UsageError(format!(
            "--write-timeout-s: {} is not a number of seconds between 0.001 and 86400",
            a.write_timeout_s
        ))
        .into());
    }
    let opts = ServeOptions {
        bind: a.bind,
        port: a.port,
        part: a.part,
        machine: a.machine,
        log: a.log,
        write_timeout: std::time::Duration::from_secs_f64(a.write_timeout_s),
    };
    let server = bind_virtual(&opts)?;
    let addr = server.local_addr().device()?;
    let stop = truepos_ippdme::server::stop_on_signals();
    eprintln!("ippdme: listening on {addr}");
    server.run(stop).device_in(format!("ippdme server on {addr}"))?;
    Ok(Outcome::Done)
}
