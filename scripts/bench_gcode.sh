#!/usr/bin/env bash
# Whole-process timing of `truepos orient` (parse + rewrite of a G-code program through a
# best-fit transform) against pygcode on the same files. Installs pygcode in a throw-away
# virtual environment; never run by CI.
#
#   scripts/bench_gcode.sh [LINES]      (default 1,000,000; pygcode runs on min(LINES, 100,000))
set -euo pipefail
cd "$(dirname "$0")/.."
LINES=${1:-1000000}
PY_LINES=$(( LINES < 100000 ? LINES : 100000 ))
WORK=${TMPDIR:-/tmp}/truepos-bench-gcode
VENV=${TMPDIR:-/tmp}/truepos-bench-gcode-venv
mkdir -p "$WORK"
cargo build --release --quiet
BIN=$PWD/target/release/truepos
if [ ! -x "$VENV/bin/python" ]; then python3 -m venv "$VENV"; fi
"$VENV/bin/pip" install --quiet pygcode >/dev/null

python3 - "$WORK" "$LINES" "$PY_LINES" <<'PY'
import sys, os
work, n, m = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
def prog(k):
    out = ["%", "O1000 (WING SPAR)", "G21 G90 G17", "G0 X0 Y0 Z50"]
    for i in range(k):
        x = (i % 1000) * 12.5; y = (i // 1000) * 4.0
        c = " (MSG,Measure SOMaC)" if i % 50 == 0 else ""
        out.append(f"N{i+10} G1 X{x:.3f} Y{y:.3f} F2000{c}" if c else f"N{i+10} G1 X{x:.3f} Y{y:.3f}")
    out += ["M30", "%"]
    return "\n".join(out) + "\n"
open(os.path.join(work, "big.nc"), "w").write(prog(n))
open(os.path.join(work, "small.nc"), "w").write(prog(m))
open(os.path.join(work, "nominal.csv"), "w").write("id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,10000,0,0\nT3,0,4000,0\nT4,10000,4000,30\n")
# measured = Rz(0.002 rad) · nominal + (1.5, -0.7, 0.2), scale 1.0001
import math
c, s, k = math.cos(0.002), math.sin(0.002), 1.0001
rows = ["id,x_mm,y_mm,z_mm"]
for tid, (x, y, z) in [("T1", (0, 0, 0)), ("T2", (10000, 0, 0)), ("T3", (0, 4000, 0)), ("T4", (10000, 4000, 30))]:
    rows.append(f"{tid},{k*(c*x - s*y) + 1.5!r},{k*(s*x + c*y) - 0.7!r},{k*z + 0.2!r}")
open(os.path.join(work, "measured.csv"), "w").write("\n".join(rows) + "\n")
PY

cat > "$WORK/pygcode_orient.py" <<'PY'
# The same rewrite with pygcode: parse every line, transform X/Y/Z of motion words, print.
import sys, math
from pygcode import Line
src, dst = sys.argv[1], sys.argv[2]
c, s, k = math.cos(0.002), math.sin(0.002), 1.0001
x = y = z = 0.0
with open(src) as f, open(dst, "w") as g:
    for text in f:
        line = Line(text.rstrip("\n"))
        words = {w.letter: w for w in line.block.words if w.letter in "XYZ"}
        if words:
            x = words["X"].value if "X" in words else x
            y = words["Y"].value if "Y" in words else y
            z = words["Z"].value if "Z" in words else z
            for w in line.block.words:
                if w.letter == "X": w.value = k * (c * x - s * y) + 1.5
                if w.letter == "Y": w.value = k * (s * x + c * y) - 0.7
                if w.letter == "Z": w.value = k * z + 0.2
        g.write(str(line) + "\n")
PY

t() { local s e; s=$(date +%s.%N); "$@" >/dev/null 2>&1; e=$(date +%s.%N); python3 -c "print(f'{$e-$s:.3f}')"; }
echo "lines: truepos $LINES, pygcode $PY_LINES"
for r in 1 2 3; do
  tb=$(t "$BIN" orient --reference "$WORK/nominal.csv" --measured "$WORK/measured.csv" --program "$WORK/big.nc" --output "$WORK/big_out.nc" --scale)
  ts=$(t "$BIN" orient --reference "$WORK/nominal.csv" --measured "$WORK/measured.csv" --program "$WORK/small.nc" --output "$WORK/small_out.nc" --scale)
  echo "run $r: truepos orient ${LINES} lines ${tb} s; ${PY_LINES} lines ${ts} s"
done
tp=$(t "$VENV/bin/python" "$WORK/pygcode_orient.py" "$WORK/small.nc" "$WORK/small_py.nc")
echo "pygcode ${PY_LINES} lines: ${tp} s"
python3 -c "
ts=float('$ts'); tp=float('$tp'); tb=float('$tb')
print(f'ratio on {$PY_LINES} lines: pygcode/truepos = {tp/ts:.0f}x; truepos {int($LINES)/tb/1e6:.2f} M lines/s, pygcode {int($PY_LINES)/tp/1e3:.1f} k lines/s')"
