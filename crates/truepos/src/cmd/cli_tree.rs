//! `truepos __cli-tree` (hidden): the whole command line — every command, subcommand and
//! argument with its help text — as one JSON object on stdout, taken from clap's
//! `CommandFactory`. The CLI test `tests/help_text.rs` walks it and names any argument or
//! command without help; nothing else uses it.
//!
//! Entry point: [`run`].

use crate::output::print_json;
use crate::Outcome;
use serde_json::{json, Value};

/// One command as JSON: `name`, `about`, `args` (`id`, `long`, `positional`, `help`,
/// `long_help`) and `subcommands` (the same, recursively). Clap adds `--help` and `--version`
/// only when a command is built, so they are not listed.
fn tree(c: &clap::Command) -> Value {
    let text = |s: Option<&clap::builder::StyledStr>| s.map(|s| s.to_string());
    json!({
        "name": c.get_name(),
        "hidden": c.is_hide_set(),
        "about": text(c.get_about()),
        "args": c.get_arguments().map(|a| json!({
            "id": a.get_id().as_str(),
            "long": a.get_long(),
            "positional": a.is_positional(),
            "help": text(a.get_help()),
            "long_help": text(a.get_long_help()),
        })).collect::<Vec<_>>(),
        "subcommands": c.get_subcommands().map(tree).collect::<Vec<_>>(),
    })
}

pub fn run() -> anyhow::Result<Outcome> {
    print_json(&tree(&super::command()))?;
    Ok(Outcome::Done)
}
