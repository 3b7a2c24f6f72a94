#!/usr/bin/env python3
"""Workspace dependencies per crate (issue 33's "no library crate on more than nine").

Reads every `crates/*/Cargo.toml` and counts, per package, the truepos crates among its normal
`[dependencies]` (dev- and build-dependencies are listed apart and not counted). A package is an
application when it has a binary target (`src/main.rs` or `[[bin]]`) or is named in APPLICATIONS
below (the demo crate `truepos-cell`, documented in ARCHITECTURE.md as the application layer
beside the binary); the limit applies to library crates only.

Usage:
    scripts/workspace_deps.py              # Markdown table, most dependencies first
    scripts/workspace_deps.py --limit 9    # the same, and exit 1 if a library crate is over 9
"""
import argparse
import os
import sys
import tomllib

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
APPLICATIONS = {"truepos-cell"}


def crates():
    base = os.path.join(ROOT, "crates")
    for name in sorted(os.listdir(base)):
        path = os.path.join(base, name, "Cargo.toml")
        if os.path.isfile(path):
            with open(path, "rb") as f:
                yield os.path.join(base, name), tomllib.load(f)


def workspace(table):
    return sorted(k for k in table if k.startswith("truepos-"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--limit", type=int, help="fail when a library crate has more workspace deps")
    args = ap.parse_args()
    rows = []
    for dir_, toml in crates():
        pkg = toml["package"]["name"]
        normal = workspace(toml.get("dependencies", {}))
        dev = workspace(toml.get("dev-dependencies", {}))
        app = (
            pkg in APPLICATIONS
            or os.path.isfile(os.path.join(dir_, "src", "main.rs"))
            or bool(toml.get("bin"))
        )
        rows.append((pkg, "application" if app else "library", normal, dev))
    rows.sort(key=lambda r: (-len(r[2]), r[0]))
    print("| crate | kind | workspace deps | normal dependencies | dev-dependencies |")
    print("|---|---|---:|---|---|")
    short = lambda names: ", ".join(n.removeprefix("truepos-") for n in names) or "—"
    for pkg, kind, normal, dev in rows:
        print(f"| {pkg} | {kind} | {len(normal)} | {short(normal)} | {short(dev)} |")
    if args.limit is not None:
        over = [r for r in rows if r[1] == "library" and len(r[2]) > args.limit]
        for pkg, _, normal, _ in over:
            print(f"{pkg}: {len(normal)} workspace dependencies > {args.limit}", file=sys.stderr)
        return 1 if over else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
