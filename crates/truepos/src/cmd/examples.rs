//! The examples of every command, printed after clap's help verbatim: clap re-wraps all help
//! text to the terminal's width (`wrap_help`), which broke long commands in the middle; these
//! lines are never wrapped, so each pastes as it is. One command per line.
//!
//! They are a runnable tour: the `truepos simulate …` examples write the data sets the others
//! read (`latency/`, `latency-speeds/`, `head/`, `head-both/`, `comp/`, `load/`, `scan/`,
//! `spar/`), and a few small files are
//! named as a user would have them (`points.csv`, `hole.csv`, `tracker.csv`, …).
//! `tests/help_examples.rs` runs every example of every `--help` on such data, so they cannot
//! rot.
//!
//! Entry points: [`examples`] (by command path), [`help_path`] (the command a `--help` command
//! line asks about).

/// The examples of the command at `path` (subcommand names from the top, `[]` for `truepos`
/// itself).
pub fn examples(path: &[&str]) -> &'static [&'static str] {
    match path {
        [] => &["truepos demo --out demo", "truepos fit sphere points.csv --json"],
        ["fit"] => &[
            "truepos fit sphere points.csv --json",
            "truepos fit cylinder bore.ds --method minimum-zone --form-tolerance-mm 0.005",
            "truepos fit circle hole.csv --nominal-diameter-mm 20 --tolerance-mm=-0.001,0.006 --decision-rule guarded --qif hole.qif",
            "truepos fit circle hole.csv --qif-plan hole.qif --qif results.qif",
        ],
        ["align"] => &["truepos align --from tracker.csv --to machine.csv --json"],
        ["latency"] => &[
            "truepos latency --machine latency/machine.csv --probe latency/probe.csv --sphere-diameter-mm 25 --tip-radius-mm 2 --json",
            "truepos latency --machine latency-speeds/machine.csv --probe latency-speeds/probe.csv --method speeds --per-axis",
            "truepos latency apply --delay-s 0.0025 --machine latency/machine.csv --probe latency/probe.csv --output latency/centres.csv",
        ],
        ["latency", "apply"] => &[
            "truepos latency apply --delay-s 0.0025 --machine latency/machine.csv --probe latency/probe.csv --output latency/centres.csv",
        ],
        ["latency", "probe"] => &[
            "truepos latency probe --near=120,45,30 --diameter-mm 25 --tip-diameter-mm 3 --feeds-mm-min 60,120,240,480 --json",
        ],
        ["head-offset"] => &[
            "truepos head-offset --points head/points.csv --table-center-mm 500,250,0 --json",
            "truepos head-offset --points head/points.csv --sphere-diameter-mm 25 --tip-radius-mm 1.5 --table-center-mm 500,250,0",
            "truepos head-offset apply --offset-mm 42.5,-18.3,-165.2 --points head/points.csv --output head/machine.csv",
        ],
        ["head-offset", "apply"] => &[
            "truepos head-offset apply --offset-mm 42.5,-18.3,-165.2 --points head/points.csv --output head/machine.csv",
        ],
        ["head-offset", "acquire"] => &[
            "truepos head-offset acquire --near=600,250,30 --diameter-mm 25 --tip-diameter-mm 3 --orientation 0,0 --orientation 0,120 --orientation 0,240 --orientation 90,0 --orientation 90,120 --orientation 90,240 --nominal-offset-mm=42,-18,-165 --table-center-mm 500,250,0 --output head/acquired.csv",
            "truepos head-offset --points head/acquired.csv --table-center-mm 500,250,0 --json",
        ],
        ["comp"] => &[
            "truepos comp correct --map comp/map.csv --squareness comp/squareness.toml --points comp/points.csv --output comp/corrected.csv --probe-offset-mm 0,0,-150",
            "truepos comp correct --map comp/map.csv --squareness comp/squareness.toml --points comp/points.csv --output comp/commanded.csv --probe-offset-mm 0,0,-150 --commanded",
            "truepos comp error --map comp/map.csv --at comp/points.csv --probe-offset-mm 0,0,-150 --json",
        ],
        ["comp", "correct"] => &[
            "truepos comp correct --map comp/map.csv --squareness comp/squareness.toml --points comp/points.csv --output comp/corrected.csv --probe-offset-mm 0,0,-150",
        ],
        ["comp", "error"] => &["truepos comp error --map comp/map.csv --at comp/points.csv --probe-offset-mm 0,0,-150 --json"],
        ["load"] => &[
            "truepos load map --bed load/bed.toml --output load/map.csv",
            "truepos load curves --map load/map.csv --load load/load.toml --json",
            "truepos load correct --map load/map.csv --load load/load.toml --bed load/bed.toml --points load/points.csv --output load/corrected.csv",
            "truepos load deflection --bed load/bed.toml --load load/load.toml --at load/points.csv --json",
        ],
        ["load", "map"] => &["truepos load map --bed load/bed.toml --output load/map.csv"],
        ["load", "correct"] => &[
            "truepos load correct --map load/map.csv --load load/load.toml --bed load/bed.toml --points load/points.csv --output load/corrected.csv",
        ],
        ["load", "curves"] => &["truepos load curves --map load/map.csv --load load/load.toml --json"],
        ["load", "deflection"] => {
            &["truepos load deflection --bed load/bed.toml --load load/load.toml --at load/points.csv --json"]
        }
        ["scan"] => &[
            "truepos scan plan --features scan/features.toml --output scan/path.csv",
            "truepos scan run --features scan/features.toml --part scan/truth.json --output scan/points.csv --json",
            "truepos scan run --features scan/features.toml --style classic --output scan/classic.csv --json",
        ],
        ["scan", "plan"] => &["truepos scan plan --features scan/features.toml --output scan/path.csv --style blended"],
        ["scan", "run"] => &[
            "truepos scan run --features scan/features.toml --part scan/truth.json --output scan/points.csv --json",
        ],
        ["autoscale"] => &[
            "truepos autoscale --reference balls_20C.csv --measured balls_now.csv --cte-ppm-per-c 23.6 --temperature-c 24.1 --json",
        ],
        ["orient"] => &[
            "truepos orient --reference targets_nominal.csv --measured targets_now.csv --program spar/program.nc --output spar/oriented.nc --scale",
        ],
        ["air"] => &["truepos air --temperature-c 20 --pressure-pa 101325 --humidity-pct 50 --json"],
        ["somac"] | ["somac", "run"] => &[
            "truepos somac run --program spar/program.nc --cell spar/cell.toml --db spar/audit.sqlite --json",
        ],
        ["somac", "inspect"] => &["truepos somac inspect --program spar/program.nc --diameter-mm 8 --tip-diameter-mm 3 --json"],
        ["probe"] | ["probe", "sphere"] => &["truepos probe sphere --near=120,45,30 --diameter-mm 25 --tip-diameter-mm 3 --json"],
        ["simulate"] => &[
            "truepos simulate latency --out latency",
            "truepos simulate head-offset --out head",
            "truepos simulate comp --out comp",
            "truepos simulate load --out load",
            "truepos simulate scan --out scan",
            "truepos simulate somac --out spar",
        ],
        ["simulate", "latency"] => &["truepos simulate latency --out latency-speeds --seed 1 --variant speeds --delay-s=-0.0012"],
        ["simulate", "head-offset"] => &["truepos simulate head-offset --out head-both --seed 1 --variant both"],
        ["simulate", "comp"] => &["truepos simulate comp --out comp --seed 1"],
        ["simulate", "load"] => &["truepos simulate load --out load --seed 1"],
        ["simulate", "scan"] => &["truepos simulate scan --out scan --seed 1 --features 12"],
        ["simulate", "somac"] => &["truepos simulate somac --out spar --seed 1"],
        ["demo"] => &["truepos demo --out demo"],
        ["audit"] => &[
            "truepos somac run --program spar/program.nc --cell spar/cell.toml --db spar/audit.sqlite --json",
            "truepos audit list --db spar/audit.sqlite",
            "truepos audit verify --db spar/audit.sqlite --json",
        ],
        ["audit", "list"] => &["truepos audit list --db spar/audit.sqlite --json"],
        ["audit", "show"] => &["truepos audit show 1 --db spar/audit.sqlite"],
        ["audit", "export"] => &["truepos audit export 1 --format csv --db spar/audit.sqlite"],
        ["audit", "verify"] => &["truepos audit verify --db spar/audit.sqlite"],
        ["audit", "migrate"] => &["truepos audit migrate --db spar/audit.sqlite"],
        ["audit", "push"] => &["truepos audit push truepos-audit-spool-0.sqlite --db spar/audit.sqlite"],
        ["dmis"] | ["dmis", "run"] => &[
            "truepos dmis run simple_in.dms --part simple_part.toml --sensor PROBE6=Probe1 --json",
            "truepos dmis run simple_in.dms --part simple_part.toml --sensor PROBE6=Probe1 --dry-run",
        ],
        ["kinematics"] | ["kinematics", "calibrate"] => &[
            "truepos kinematics calibrate --model xyzbc-trt --near=60,25,15 --diameter-mm 25 --tip-diameter-mm 2 --clearance-mm 1 --orientation 0,0 --orientation 0,120 --orientation 0,240 --orientation 45,0 --orientation 90,120 --orientation 90,240 --apply --verify --json",
        ],
        ["ippdme"] | ["ippdme", "serve"] => &["truepos ippdme serve --bind 127.0.0.1 --port 1294 --log ippdme.log"],
        _ => &[],
    }
}

/// The command path a command line asks help about (`truepos load map --help` → `["load",
/// "map"]`, also `truepos help load map`): the subcommand names in order, skipping options
/// and their values.
pub fn help_path(root: &clap::Command, args: &[String]) -> Vec<String> {
    let mut cmd = root;
    let mut path = Vec::new();
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        i += 1;
        if a == "--" {
            break;
        }
        if let Some(long) = a.strip_prefix("--") {
            // An option that takes a value given as the next word: skip that word.
            let takes = cmd
                .get_arguments()
                .find(|x| x.get_long() == Some(long))
                .is_some_and(|x| x.get_action().takes_values());
            if takes && !long.contains('=') {
                i += 1;
            }
            continue;
        }
        if a.starts_with('-') {
            continue;
        }
        if a == "help" && cmd.find_subcommand("help").is_none() {
            continue;
        }
        match cmd.find_subcommand(a) {
            Some(sub) => {
                path.push(sub.get_name().to_string());
                cmd = sub;
            }
            None => break,
        }
    }
    path
}

/// The examples block printed after the help of `path` (empty when it has none).
pub fn block(path: &[String]) -> String {
    let p: Vec<&str> = path.iter().map(String::as_str).collect();
    let ex = examples(&p);
    if ex.is_empty() {
        return String::new();
    }
    let mut s = String::from(if ex.len() == 1 { "\nExample:\n" } else { "\nExamples:\n" });
    for e in ex {
        s.push_str("  ");
        s.push_str(e);
        s.push('\n');
    }
    s
}
