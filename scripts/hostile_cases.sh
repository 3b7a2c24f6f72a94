#!/usr/bin/env bash
# Hostile inputs of issue 14, by group, against one truepos binary: one TSV line per case with
# group, case, exit code, first line of stderr (100 chars), seconds and peak RSS (kB).
# Usage: scripts/hostile_cases.sh path/to/truepos > cases.tsv   (inputs go to a temp dir)
# Each case is cut off after TIMEOUT seconds (default 20; exit 124 in the table).
set -u
T=$(realpath "${1:?usage: hostile_cases.sh TRUEPOS_BINARY}")
D=$(mktemp -d)
trap 'rm -rf "$D"' EXIT
cd "$D"

# Inputs (small; the size cases use /dev/zero and one 10 MB line).
printf 'x_mm,y_mm,z_mm\n0,0,0\n1,1,1\n2,2,2\n3,3,3\n4,4,4\n' > collinear.csv
printf 'x_mm,y_mm,z_mm\n1,2,3\n1,2,3\n1,2,3\n1,2,3\n' > same.csv
printf 'id,x_mm,y_mm,z_mm,w\nA,0,0,0,0\nB,100,0,0,0\nC,0,100,0,0\nD,0,0,100,0\n' > from_w.csv
printf 'id,x_mm,y_mm,z_mm,w\nA,1,0,0,0\nB,101,0,0,0\nC,1,100,0,0\nD,1,0,100,0\n' > to_w.csv
printf 'id,x_mm,y_mm,z_mm\nA,5,5,5\nB,5,5,5\nC,5,5,5\n' > identical.csv
printf 'id,x_mm,y_mm,z_mm\n,0,0,0\nB,100,0,0\nC,0,100,0\n' > emptyid.csv
printf 'id,x_mm,y_mm,z_mm\nA,0,0,0\nA,100,0,0\nC,0,100,0\n' > dupid.csv
printf 'id,x_mm,y_mm,z_mm\nA,0,0,0\nB,100,0,0\nC,0,100,0\n' > ref3.csv
printf 'id,x_mm,y_mm,z_mm\nA,0,0,0\nB,100,0,0\n' > ref2.csv
printf 'id,x_mm,y_mm,z_mm\nA,0,0,0\nB,100.1,0,0\n' > meas2.csv
printf 'id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1000,0,0\nT3,0,1000,0\n' > tref.csv
printf 'id,x_mm,y_mm,z_mm\nT1,1,0,0\nT2,1001,0,0\nT3,1,1000,0\n' > tmeas.csv
printf 'G0 X\n' > g_x.nc; printf 'G0 Xabc\n' > g_xabc.nc; printf 'G0 XNaN\n' > g_nan.nc
printf 'G0 X1e999\n' > g_big.nc; printf '#1=5\nG0 X#1 Y[#1*2] Z1\n' > g_param.nc
printf 'N10 G90\nN20 G0 Z50.\nN30 G1 X10 Y10 F100\n' > g_zonly.nc
printf 'G18\nG0 X0 Y0 Z0\nG2 X10 Z0 I5 K0 F100\n' > g_arc.nc
printf '(a (b) X99) ; tail\nG0 X1 Y2 Z3\n' > g_nested.nc
head -c 10485760 /dev/zero | tr '\0' '1' > longline.csv
printf 'b_deg,c_deg,x_mm,y_mm,z_mm\n0,0,1,2,3\n' > head.csv
python3 - <<'PY'
import sqlite3
c = sqlite3.connect("foreign.sqlite"); c.execute("create table customers(id integer, name text)"); c.commit(); c.close()
PY
cp foreign.sqlite foreign.orig

run() { # group, case, command...
  local g=$1 c=$2; shift 2
  local t0=$(date +%s.%N)
  /usr/bin/time -f %M -o rss.txt timeout "${TIMEOUT:-20}" "$@" > out.txt 2> err.txt
  local rc=$?
  local t1=$(date +%s.%N)
  local msg=$(grep -v '^[0-9]*$' err.txt | head -n1 | tr '\t' ' ' | cut -c1-100)
  printf '%s\t%s\t%s\t%s\t%.2f\t%s\n' "$g" "$c" "$rc" "$msg" "$(echo "$t1 - $t0" | bc)" "$(tail -n1 rss.txt)"
}

printf 'group\tcase\texit\tmessage\tseconds\tpeak_rss_kb\n'
for f in g_x g_xabc g_nan g_big; do run gcode "orient word without a valid number ($f)" "$T" orient --program $f.nc --reference tref.csv --measured tmeas.csv --output o.nc; done
run gcode "orient parameters and expressions" "$T" orient --program g_param.nc --reference tref.csv --measured tmeas.csv --output o.nc
run gcode "orient nested and ; comments kept" "$T" orient --program g_nested.nc --reference tref.csv --measured tmeas.csv --output o.nc
run gcode "orient first motion Z only, no --start-mm" "$T" orient --program g_zonly.nc --reference tref.csv --measured tmeas.csv --output o.nc
run gcode "orient G18 arc, translation only (plane stays parallel)" "$T" orient --program g_arc.nc --reference tref.csv --measured tmeas.csv --output o.nc
run sizes "fit sphere /dev/zero" "$T" fit sphere /dev/zero
run sizes "fit sphere one 10 MB line" "$T" fit sphere longline.csv
run sizes "simulate somac --holes-per-row 1e9" "$T" simulate somac --out sim --holes-per-row 1000000000
run degenerate "fit plane collinear" "$T" fit plane collinear.csv --json
run degenerate "fit line identical points" "$T" fit line same.csv --json
run degenerate "fit circle collinear" "$T" fit circle collinear.csv --json
run degenerate "align all weights zero" "$T" align --from from_w.csv --to to_w.csv --weights w
run degenerate "align identical from points" "$T" align --from identical.csv --to ref3.csv
run degenerate "align empty id" "$T" align --from emptyid.csv --to ref3.csv
run degenerate "align duplicated id" "$T" align --from dupid.csv --to ref3.csv
run degenerate "autoscale identical points" "$T" autoscale --reference identical.csv --measured identical.csv
run autoscale "autoscale two features (100 -> 100.1 mm)" "$T" autoscale --reference ref2.csv --measured meas2.csv --json
run ranges "air wavelength 0.633 nm" "$T" air --temperature-c 20 --pressure-pa 101325 --humidity-pct 50 --wavelength-nm 0.633
run ranges "air pressure 1e12 Pa" "$T" air --temperature-c 20 --pressure-pa 1e12 --humidity-pct 50
run ranges "air humidity 150 %" "$T" air --temperature-c 20 --pressure-pa 101325 --humidity-pct 150
run ranges "air -300 C" "$T" air --temperature-c=-300 --pressure-pa 101325 --humidity-pct 50
run outputs "output in a missing directory" "$T" head-offset apply --offset-mm 0,0,-100 --points head.csv --output nodir/out.csv
run outputs "output is a directory" "$T" head-offset apply --offset-mm 0,0,-100 --points head.csv --output .
run outputs "closed pipe (--json | head -c 10)" bash -c "set -o pipefail; '$T' fit line collinear.csv --json | head -c 10 > /dev/null"
"$T" simulate somac --out cellsim > /dev/null 2>&1
run audit "foreign SQLite file as --db" "$T" somac run --program cellsim/program.nc --cell cellsim/cell.toml --db foreign.sqlite
cmp -s foreign.sqlite foreign.orig && printf 'audit\tforeign database left byte-identical\t0\tyes\t0\t\n' || printf 'audit\tforeign database left byte-identical\t1\tNO: modified\t0\t\n'
