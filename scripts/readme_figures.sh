#!/usr/bin/env bash
# The figures the README's five-minute tour quotes, from one run of the tour's commands (in a
# temporary directory). Paste them into README.md's comments after a change that moves them;
# crates/truepos/tests/readme_tour.rs fails when the README and these outputs disagree beyond
# the README's last printed digit.
#
# Usage (from the repository root): scripts/readme_figures.sh [path/to/truepos]
# (default: target/release/truepos, built if missing). Needs jq.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="${1:-$root/target/release/truepos}"
[ -x "$bin" ] || (cd "$root" && cargo build --release -p truepos)
t="$(mktemp -d)"
trap 'rm -rf "$t"' EXIT
cd "$t"
q() { "$bin" "$@" 2>/dev/null; }

q simulate latency --out tour/latency >/dev/null
q latency --machine tour/latency/machine.csv --probe tour/latency/probe.csv --sphere-diameter-mm 25 \
  --tip-radius-mm 2 --json | jq -r '"latency: delay \(.delay_s * 1e6 * 10 | round / 10) µs ± \(.uncertainty_s * 1e6 * 10 | round / 10) µs"'

q simulate head-offset --out tour/head >/dev/null
q head-offset --points tour/head/points.csv --table-center-mm 500,250,0 --tip-radius-mm 1.5 --json >head.json
jq -r --slurpfile t tour/head/truth.json \
  '[.offset_mm, $t[0].offset_mm] | transpose | map((.[0] - .[1]) | fabs) | max * 1e4 | round / 10 | "head-offset: found to \(.) µm"' head.json

q simulate comp --out tour/comp >/dev/null
q comp correct --map tour/comp/map.csv --squareness tour/comp/squareness.toml --points tour/comp/points.csv \
  --output tour/comp/corrected.csv --probe-offset-mm 0,0,-150
echo "comp: corrected $(grep -v '^#' tour/comp/corrected.csv | sed -n 2p | cut -d, -f1-4)"
echo "comp: truth $(jq -c '.true_points_mm[0] | map(. * 1e7 | round / 1e7)' tour/comp/truth.json)"

q simulate load --out tour/load >/dev/null
q load map --bed tour/load/bed.toml --output tour/load/map.csv
q load correct --map tour/load/map.csv --load tour/load/load.toml --bed tour/load/bed.toml \
  --points tour/load/points.csv --output tour/load/corrected.csv
echo "load: corrected $(grep -v '^#' tour/load/corrected.csv | sed -n 2p | cut -d, -f1-4)"
echo "load: truth $(jq -c '.true_points_mm[0] | map(. * 1e7 | round / 1e7)' tour/load/truth.json)"

q simulate scan --out tour/scan >/dev/null
q scan run --features tour/scan/features.toml --part tour/scan/truth.json --output tour/scan/points.csv --json \
  | jq -r '"scan: cycle \(.cycle_time_s * 100 | round / 100) s, \(.stops) stops"'
grep -v '^#' tour/scan/points.csv | awk -F, 'NR==1 || ($6=="bore0" && $5=="scan")' >tour/scan/bore0.csv
q fit circle tour/scan/bore0.csv --json | jq -r '"scan: bore0 radius \(.radius_mm * 1e6 | round / 1e6) mm (stylus centres)"'
jq -r '"scan: bore0 true radius \(.features[0].actual.radius_mm * 1e6 | round / 1e6) mm"' tour/scan/truth.json

q simulate somac --out tour/somac >/dev/null
q somac run --program tour/somac/program.nc --cell tour/somac/cell.toml --db tour/somac/audit.sqlite --json \
  | jq -r '"somac: \(.true_mean_error_mm * 1e4 | round / 1e4) mean, \(.true_max_error_mm * 1e4 | round / 1e4) max (mm)"' || true
jq -r '"somac: native mean error \(.native_mean_error_mm * 1e3 | round / 1e3) mm"' tour/somac/truth.json
