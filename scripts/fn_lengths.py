#!/usr/bin/env python3
"""Function lengths across the workspace's Rust sources (issue 33's figure).

Counts, for every `fn` with a body in `crates/**/*.rs`, the lines from the line holding `fn`
to the line holding the body's closing brace (inclusive). Strings, char literals, raw strings
and comments are skipped when matching braces. Nested functions and closures count in their
parent and are also listed on their own when they are `fn`s.

Usage:
    scripts/fn_lengths.py                 # summary: functions over 100, 150, 200 lines
    scripts/fn_lengths.py --list 150      # every function over 150 lines, longest first
    scripts/fn_lengths.py --list 100 --exclude-tests
`--exclude-tests` leaves out `tests/`, `benches/`, `examples/` and `#[cfg(test)] mod tests`
blocks (detected as a `mod tests` after `#[cfg(test)]`).
"""
import argparse
import os
import re
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


def strip(src):
    """Replace comments and the contents of string/char literals with spaces (keeps newlines)."""
    out = []
    i, n = 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif (c == "r" or src.startswith("br", i)) and re.match(r"b?r#*\"", src[i:]) and (
            i == 0 or not (src[i - 1].isalnum() or src[i - 1] == "_")
        ):
            m = re.match(r"(b?r)(#*)\"", src[i:])
            end = '"' + m.group(2)
            j = src.find(end, i + len(m.group(0)))
            j = n if j < 0 else j + len(end)
            out.append(re.sub(r"[^\n]", " ", src[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            out.append(re.sub(r"[^\n]", " ", src[i : j + 1]))
            i = j + 1
        elif c == "'":
            # char literal ('x', '\n', '\u{..}') vs lifetime ('a)
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", src[i:])
            if m:
                out.append(" " * len(m.group(0)))
                i += len(m.group(0))
            else:
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


FN_RE = re.compile(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)")


def functions(path, exclude_tests):
    with open(path, encoding="utf-8") as f:
        src = strip(f.read())
    line_of = [0] * (len(src) + 1)
    ln = 1
    for k, ch in enumerate(src):
        line_of[k] = ln
        if ch == "\n":
            ln += 1
    line_of[len(src)] = ln
    # test-module spans to exclude
    skip = []
    if exclude_tests:
        for m in re.finditer(r"#\[cfg\(test\)\]\s*(pub\s+)?mod\s+\w+\s*\{", src):
            end = match_brace(src, m.end() - 1)
            skip.append((m.start(), end))
    for m in FN_RE.finditer(src):
        if any(a <= m.start() < b for a, b in skip):
            continue
        # find the body: first '{' or ';' at paren/angle depth 0 after the signature
        j, depth = m.end(), 0
        while j < len(src):
            ch = src[j]
            if ch in "([":
                depth += 1
            elif ch in ")]":
                depth -= 1
            elif depth == 0 and ch in "{;":
                break
            j += 1
        if j >= len(src) or src[j] == ";":
            continue
        end = match_brace(src, j)
        yield m.group(1), line_of[m.start()], line_of[end] - line_of[m.start()] + 1


def match_brace(src, j):
    depth = 0
    for k in range(j, len(src)):
        if src[k] == "{":
            depth += 1
        elif src[k] == "}":
            depth -= 1
            if depth == 0:
                return k
    return len(src)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--list", type=int, default=None, help="list functions longer than N lines")
    ap.add_argument("--exclude-tests", action="store_true")
    a = ap.parse_args()
    rows = []
    for base, dirs, files in os.walk(os.path.join(ROOT, "crates")):
        dirs[:] = [d for d in dirs if d not in ("target", "node_modules")]
        rel = os.path.relpath(base, ROOT)
        parts = rel.split(os.sep)
        if a.exclude_tests and any(p in ("tests", "benches", "examples") for p in parts):
            continue
        for fn in files:
            if fn.endswith(".rs"):
                p = os.path.join(base, fn)
                for name, line, length in functions(p, a.exclude_tests):
                    rows.append((length, os.path.relpath(p, ROOT), line, name))
    rows.sort(reverse=True)
    if a.list is not None:
        for length, p, line, name in rows:
            if length > a.list:
                print(f"{length:5d}  {p}:{line}  {name}")
        return
    print(f"functions: {len(rows)}")
    for t in (100, 150, 200):
        print(f"over {t} lines: {sum(1 for r in rows if r[0] > t)}")


if __name__ == "__main__":
    sys.exit(main())
