#!/usr/bin/env bash
# Whole-process timing: `truepos fit sphere` (release) vs numpy+scipy least_squares and
# scikit-spatial Sphere.best_fit on the same 1,000,000-point noisy sphere CSV.
# Installs numpy, scipy and scikit-spatial into a virtual environment under /tmp. Never run by CI.
# Usage: scripts/bench_fit.sh [N_POINTS] [REPETITIONS]
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-1000000}
REPS=${2:-5}
VENV=${TRUEPOS_BENCH_VENV:-/tmp/truepos-bench-venv}
WORK=${TRUEPOS_BENCH_DIR:-/tmp/truepos-bench}
mkdir -p "$WORK"
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet numpy scipy scikit-spatial
fi
cargo build --release -p truepos
FILE="$WORK/sphere_${N}.csv"
if [ ! -f "$FILE" ]; then
    "$VENV/bin/python" scripts/bench_fit.py gen "$FILE" "$N"
fi
echo "data: $FILE ($(du -h "$FILE" | cut -f1), $N points); $(nproc) cores; $REPS repetitions"
# Warm the page cache so every tool reads from memory.
cat "$FILE" > /dev/null
"$VENV/bin/python" scripts/bench_fit.py time "$(pwd)/target/release/truepos" "$FILE" "$REPS"
