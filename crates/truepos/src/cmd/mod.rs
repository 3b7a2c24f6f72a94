//! One module per command. Each has an `Args` (clap) and a `run(Args) -> Result<Outcome>`;
//! capability modules also provide `SimArgs` + `simulate` (their `truepos simulate` scenario)
//! and `demo_section` (their part of the demo report).

use crate::Outcome;
use clap::{Parser, Subcommand};

pub mod align;
pub mod audit;
pub mod cli_tree;
pub mod comp;
pub mod demo;
pub mod dmis;
pub mod examples;
pub mod fit;
pub mod head;
pub mod ippdme;
pub mod kinematics;
pub mod latency;
pub mod load;
pub mod probe;
pub mod scan;
pub mod somac;
pub mod somac_inspect;
pub mod somac_run;

/// truepos: calibrate, compensate and control probe-equipped machine tools and CMMs.
///
/// Lengths in mm, times in s, angles in degrees in every file and option. `--json` prints one
/// JSON object on stdout. Exit codes: 0 done, 1 outside tolerance or alarm, 2 bad usage or
/// input, 3 device or internal failure.
#[derive(Parser, Debug)]
#[command(name = "truepos", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Least-squares geometric element fit (ISO 10360-6 / ASME B89.4.10).
    Fit(fit::Args),
    /// Best-fit transform between matched point sets (tracker to machine, etc.).
    Align(align::Args),
    /// Probe/machine system delay calibration.
    Latency(latency::Args),
    /// Measuring-head 3D offset calibration.
    #[command(name = "head-offset")]
    HeadOffset(head::Args),
    /// 21-parameter geometric error map: volumetric error and correction.
    Comp(comp::Args),
    /// Bed deformation under workpiece load: influence maps, load cases, correction.
    Load(load::Args),
    /// Scanning path planning and execution without stops.
    Scan(scan::Args),
    /// Scale factor from reference and measured feature positions (with CTE cross-check).
    Autoscale(somac::AutoscaleArgs),
    /// Re-orient a G-code program through the best-fit transform of measured targets.
    Orient(somac::OrientArgs),
    /// Refractive index of air (Ciddor, modified Edlén).
    Air(somac::AirArgs),
    /// Laser-tracker end-point control of a large NC machine.
    Somac(somac::Args),
    /// Probe on a machine with a touch probe (virtual, LinuxCNC): `truepos probe sphere`.
    Probe(probe::Args),
    /// Rotary axes of a five-axis controller: `truepos kinematics calibrate`.
    Kinematics(kinematics::Args),
    /// Write a virtual-cell data set (and its truth.json) for one capability.
    Simulate(SimulateArgs),
    /// Run every capability end to end on the virtual cell and write a report.
    Demo(demo::Args),
    /// I++ DME: the virtual CMM as an I++ DME server (`truepos ippdme serve`).
    Ippdme(ippdme::Args),
    /// The audit trail (SQLite or shared PostgreSQL): list, show and export runs, verify the hash chain.
    Audit(audit::Args),
    /// DMIS part programs on a CMM (I++ DME or the virtual CMM): `truepos dmis run`.
    Dmis(dmis::Args),
    /// The command line as JSON (every command and argument with its help), for the tests.
    #[command(name = "__cli-tree", hide = true)]
    CliTree,
}

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    #[command(subcommand)]
    pub scenario: Scenario,
}

#[derive(Subcommand, Debug)]
pub enum Scenario {
    /// Probe and machine streams for system-delay calibration.
    Latency(latency::SimArgs),
    /// Reference-object measurements for head-offset calibration.
    #[command(name = "head-offset")]
    HeadOffset(head::SimArgs),
    /// A CMM bed loaded by a heavy part, measuring a ball plate.
    Load(load::SimArgs),
    /// A part with bores, bosses and planes to scan.
    Scan(scan::SimArgs),
    /// A wing-spar drilling program on the virtual gantry with trackers.
    Somac(somac::SimArgs),
    /// A bridge CMM's geometric error map (x, y, z tables, squareness) and measured points.
    Comp(comp::SimArgs),
}

/// Options every `truepos simulate` scenario takes.
#[derive(clap::Args, Debug, Clone)]
pub struct SimCommon {
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: std::path::PathBuf,
    /// Random seed: the same seed gives the same files.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl SimCommon {
    /// `--out`, checked before anything is generated: a directory, or a path where none is
    /// yet (it is created). An existing file or anything else is bad usage naming the path.
    pub fn out_dir(&self) -> Result<&std::path::Path, crate::UsageError> {
        let out = self.out.as_path();
        match std::fs::metadata(out) {
            Ok(m) if !m.is_dir() => Err(crate::UsageError(format!(
                "--out {}: exists and is not a directory (simulate writes its data set into a directory, created if missing)",
                out.display()
            ))),
            _ => Ok(out),
        }
    }
}

/// The command line as parsed: [`Cli`]'s with negative numbers accepted as the value of every
/// option that takes one (`--diameter-mm -25` reaches the option's range check, which says
/// "must be positive", instead of clap's "unexpected argument '-2'").
pub fn command() -> clap::Command {
    fn numbers(c: clap::Command) -> clap::Command {
        let c = c.mut_args(|a| {
            if a.get_action().takes_values() && !a.is_positional() {
                a.allow_negative_numbers(true)
            } else {
                a
            }
        });
        let subs: Vec<String> = c.get_subcommands().map(|s| s.get_name().to_string()).collect();
        subs.iter().fold(c, |c, n| c.mut_subcommand(n, numbers))
    }
    use clap::CommandFactory;
    numbers(Cli::command())
}

pub fn run(cli: Cli) -> anyhow::Result<Outcome> {
    match cli.command {
        Command::Fit(a) => fit::run(a),
        Command::Align(a) => align::run(a),
        Command::Latency(a) => latency::run(a),
        Command::HeadOffset(a) => head::run(a),
        Command::Comp(a) => comp::run(a),
        Command::Load(a) => load::run(a),
        Command::Scan(a) => scan::run(a),
        Command::Autoscale(a) => somac::autoscale(a),
        Command::Orient(a) => somac::orient(a),
        Command::Air(a) => somac::air(a),
        Command::Somac(a) => somac::run(a),
        Command::Probe(a) => probe::run(a),
        Command::Kinematics(a) => kinematics::run(a),
        Command::Simulate(s) => match s.scenario {
            Scenario::Latency(a) => latency::simulate(a),
            Scenario::HeadOffset(a) => head::simulate(a),
            Scenario::Load(a) => load::simulate(a),
            Scenario::Scan(a) => scan::simulate(a),
            Scenario::Somac(a) => somac::simulate(a),
            Scenario::Comp(a) => comp::simulate(a),
        },
        Command::Demo(a) => demo::run(a),
        Command::Ippdme(a) => ippdme::run(a),
        Command::Audit(a) => audit::run(a),
        Command::Dmis(a) => dmis::run(a),
        Command::CliTree => cli_tree::run(),
    }
}
