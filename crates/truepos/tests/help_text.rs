//! Every argument of every command has help text: walks the whole clap tree (`truepos
//! __cli-tree`, taken from `Cli::command()`), all subcommands recursively, and names each
//! argument (other than clap's own --help/--version, which it adds itself) or command whose
//! help is missing or blank.

mod common;

use serde_json::Value;

fn blank(v: &Value) -> bool {
    !matches!(v.as_str(), Some(s) if !s.trim().is_empty())
}

/// Collect `path --arg` (or `path <ARG>`) for every argument without help, and `path` for every
/// visible command without an about line.
fn walk(cmd: &Value, path: &str, missing: &mut Vec<String>, n_args: &mut usize) {
    let name = cmd["name"].as_str().unwrap_or("?");
    let here = if path.is_empty() { name.to_string() } else { format!("{path} {name}") };
    if !path.is_empty() && !cmd["hidden"].as_bool().unwrap_or(false) && blank(&cmd["about"]) {
        missing.push(format!("{here} (command without an about line)"));
    }
    for a in cmd["args"].as_array().into_iter().flatten() {
        let id = a["id"].as_str().unwrap_or("?");
        if id == "help" || id == "version" {
            continue;
        }
        *n_args += 1;
        if blank(&a["help"]) && blank(&a["long_help"]) {
            let shown = match a["long"].as_str() {
                Some(l) => format!("--{l}"),
                None => format!("<{id}>"),
            };
            missing.push(format!("{here} {shown}"));
        }
    }
    for s in cmd["subcommands"].as_array().into_iter().flatten() {
        walk(s, &here, missing, n_args);
    }
}

#[test]
fn every_argument_has_help_text() {
    let out = common::bin().arg("__cli-tree").output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let tree: Value = serde_json::from_slice(&out.stdout).unwrap();
    let (mut missing, mut n_args) = (Vec::new(), 0);
    walk(&tree, "", &mut missing, &mut n_args);
    // The tree really was walked: the command line has well over a hundred arguments.
    assert!(n_args > 100, "only {n_args} arguments found: the walk is broken");
    assert!(
        missing.is_empty(),
        "{} argument(s)/command(s) without help:\n  {}",
        missing.len(),
        missing.join("\n  ")
    );
}

/// The walk does find a blank: a command line built here with one undocumented argument.
#[test]
fn the_walk_finds_a_blank_help() {
    let tree = serde_json::json!({"name": "t", "about": "x", "args": [
        {"id": "a", "long": "a", "help": "documented", "long_help": null},
        {"id": "b", "long": "b", "help": null, "long_help": null},
        {"id": "help", "long": "help", "help": null, "long_help": null}],
        "subcommands": [{"name": "sub", "about": null, "hidden": false, "args": [], "subcommands": []}]});
    let (mut missing, mut n) = (Vec::new(), 0);
    walk(&tree, "", &mut missing, &mut n);
    assert_eq!(missing, vec!["t --b".to_string(), "t sub (command without an about line)".to_string()]);
    assert_eq!(n, 2);
}
