//! The values every enum option of the command line accepts, as the contract
//! (`interface.md`) and the help name them, in their order. The options take the libraries' own
//! enums (`clap::ValueEnum` behind each library's `clap` feature), so a renamed or reordered
//! library variant would silently change the command line; this test names the values instead.
//!
//! Each case gives clap a value that is not one of them and reads the possible values from its
//! refusal (exit 2, "[possible values: …]"), then runs the command with every listed value far
//! enough to see that clap accepts it (a refusal of the value itself would name it as invalid).

mod common;

/// One enum option: the command line up to the value, and the values in order.
struct Case {
    args: &'static [&'static str],
    /// Arguments after the value (positional ones the command needs to get past clap).
    after: &'static [&'static str],
    values: &'static [&'static str],
}

const CASES: &[Case] = &[
    // `truepos fit <line|plane|circle|sphere|cylinder|cone> <points>`
    Case {
        args: &["fit"],
        after: &["points.csv"],
        values: &["line", "plane", "circle", "sphere", "cylinder", "cone"],
    },
    // `--method ls|minimum-zone|mic|mcc`
    Case {
        args: &["fit", "circle", "points.csv", "--method"],
        after: &[],
        values: &["ls", "minimum-zone", "mic", "mcc"],
    },
    // `--decision-rule simple|guarded`
    Case {
        args: &["fit", "circle", "points.csv", "--decision-rule"],
        after: &[],
        values: &["simple", "guarded"],
    },
    // `truepos latency --method auto|artefact|speeds|scan|inout`
    Case {
        args: &["latency", "--machine", "m.csv", "--probe", "p.csv", "--method"],
        after: &[],
        values: &["auto", "artefact", "speeds", "scan", "inout"],
    },
    // `truepos scan plan ... [--style blended|classic]`
    Case {
        args: &["scan", "plan", "--features", "f.toml", "--output", "o.csv", "--style"],
        after: &[],
        values: &["blended", "classic"],
    },
    // `truepos align ... [--method three-point|best-fit]` (help order: best-fit first)
    Case {
        args: &["align", "--from", "a.csv", "--to", "b.csv", "--method"],
        after: &[],
        values: &["best-fit", "three-point"],
    },
    // `truepos air ... [--formula ciddor|edlen]`
    Case {
        args: &[
            "air",
            "--temperature-c",
            "20",
            "--pressure-pa",
            "101325",
            "--humidity-pct",
            "50",
            "--formula",
        ],
        after: &[],
        values: &["ciddor", "edlen"],
    },
    // `truepos comp correct --map FILE ... --chain bridge|gantry`
    Case {
        args: &["comp", "correct", "--map", "m.csv", "--points", "p.csv", "--output", "o.csv", "--chain"],
        after: &[],
        values: &["bridge", "gantry"],
    },
    // `truepos simulate head-offset --variant …`
    Case {
        args: &["simulate", "head-offset", "--variant"],
        after: &[],
        values: &["swivel", "table", "both", "laser", "pyramid", "cuboid"],
    },
];

#[test]
fn enum_options_accept_exactly_the_contract_values() {
    let dir = tempfile::tempdir().unwrap();
    for case in CASES {
        let shown = case.args.join(" ");
        // An impossible value: clap refuses it and lists the possible ones.
        let out = common::bin()
            .current_dir(dir.path())
            .args(case.args)
            .arg("not-a-value")
            .args(case.after)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{shown} not-a-value: {err}");
        let list = err
            .split("[possible values: ")
            .nth(1)
            .and_then(|s| s.split(']').next())
            .unwrap_or_else(|| panic!("{shown}: no possible values in: {err}"));
        let got: Vec<&str> = list.split(", ").collect();
        assert_eq!(got, case.values, "{shown}");
        // Every value gets past clap: whatever fails afterwards (missing files) is not the value.
        for v in case.values {
            let out = common::bin()
                .current_dir(dir.path())
                .args(case.args)
                .arg(v)
                .args(case.after)
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!err.contains("invalid value"), "{shown} {v} refused by clap: {err}");
        }
    }
}
